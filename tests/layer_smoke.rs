use waam::layer::{search, Layer, Model, SearchOptions};
#[test]
fn smoke() {
    let path = std::env::var("LAYER").unwrap_or("config/layers/paper-16mm.yaml".into());
    let layer = Layer::from_bytes(&std::fs::read(path).unwrap()).unwrap();
    let model = Model::new(&layer).unwrap();
    eprintln!("mesh nodes {} tris {} nnzL {} monotone {} horizon {} deadheads {}", model.mesh.points.len(), model.mesh.triangles.len(), model.heat.factor_nnz(), model.heat.monotone, model.horizon, model.deadheads);
    let mut rec = Vec::new();
    let t = std::time::Instant::now();
    let mut opts = SearchOptions::default();
    opts.time_limit = Some(std::time::Duration::from_secs(std::env::var("TL").map(|s| s.parse().unwrap()).unwrap_or(20)));
    let r = search(&model, &opts);
    eprintln!("{:?} {:?}", r, r.trail);
    eprintln!("{:?}", t.elapsed());
    let obj = model.simulate(&r.trail, Some(&mut rec));
    let mx = rec.iter().map(|u| u.iter().cloned().fold(0./0., f64::max)).collect::<Vec<_>>();
    eprintln!("obj {obj} max dev per step {:?}", &mx.iter().map(|x| *x as i64).collect::<Vec<_>>());
    let mean = rec.iter().map(|u| (u.iter().sum::<f64>()/u.len() as f64) as i64).collect::<Vec<_>>();
    eprintln!("mean {:?}", mean);
}
#[test]
fn enumerate_all() {
    let path = std::env::var("LAYER").unwrap_or("config/layers/paper-16mm.yaml".into());
    let layer = Layer::from_bytes(&std::fs::read(path).unwrap()).unwrap();
    let model = Model::new(&layer).unwrap();
    let mut opts = SearchOptions::default();
    opts.bound = false;
    opts.symmetry = std::env::var("SYM").is_ok();
    let r = search(&model, &opts);
    eprintln!("ENUM obj {} leaves {} nodes {} secs {}", r.objective, r.leaves, r.nodes_explored, r.seconds);
}
#[test]
fn debug_mono() {
    use waam::layer::fem::Matrices;
    let path = std::env::var("LAYER").unwrap_or("config/layers/honeycomb-12.yaml".into());
    let layer = Layer::from_bytes(&std::fs::read(path).unwrap()).unwrap();
    let model = Model::new(&layer).unwrap();
    let m = Matrices::assemble(&model.mesh, 5.0, 0.5);
    let mut worst = (0.0, 0, 0);
    for (i, j, &v) in m.stiffness.triplet_iter() { if i != j && v > worst.0 { worst = (v, i, j); } }
    eprintln!("worst {:?} pi {:?} pj {:?}", worst, model.mesh.points[worst.1], model.mesh.points[worst.2]);
    eprintln!("syms {}", waam::layer::symmetry::symmetries(&model).len());
}
