//! `waam motion` and `waam plot` end to end, through the binary.

use crate::common;
use crate::common::run::run_at_root;

/// Decodes a PNG: (width, height, RGB(A) pixels as rows of bytes, bytes per pixel).
fn decode(path: &std::path::Path) -> (u32, u32, Vec<u8>, usize) {
    let decoder = png::Decoder::new(std::fs::File::open(path).unwrap());
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    buf.truncate(info.buffer_size());
    let bpp = info.color_type.samples();
    (info.width, info.height, buf, bpp)
}

#[test]
fn motion_then_plot_writes_yaml_and_pictures() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let plan = common::plan_path("ex2-bracket");
    let run = run_at_root(&[
        "motion",
        "config/parts/ex2-bracket.yaml",
        plan.to_str().unwrap(),
        "--robot",
        "tests/data/abb_irb1600_12.urdf",
        "--tcp",
        common::ABB_TCP,
        "--out",
        out,
    ]);
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert_eq!(
        run.status.code(),
        Some(0),
        "{stdout}{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert!(
        stdout.contains("MOTION:") && stdout.contains("113 weld poses at points"),
        "{stdout}"
    );
    assert!(
        dir.path().join("toolpath.yaml").exists() && dir.path().join("trajectory.yaml").exists()
    );

    let run = run_at_root(&[
        "plot",
        out,
        "--part",
        "config/parts/ex2-bracket.yaml",
        "--plan",
        plan.to_str().unwrap(),
    ]);
    assert_eq!(
        run.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    for (file, size) in [
        ("toolpath.png", waam_plot::TOOLPATH_SIZE),
        ("t85.png", waam_plot::T85_SIZE),
    ] {
        let (w, h, pixels, bpp) = decode(&dir.path().join(file));
        assert_eq!((w, h), size, "{file}");
        let px = |i: usize| &pixels[i * bpp..i * bpp + 3];
        let n = (w * h) as usize;
        let drawn = (0..n).filter(|&i| px(i) != [255, 255, 255]).count();
        assert!(drawn > n / 100, "{file}: only {drawn} of {n} pixels drawn");
        if file == "toolpath.png" {
            // Weld moves are drawn pure red.
            let red = (0..n).filter(|&i| px(i) == [255, 0, 0]).count();
            assert!(red > 1000, "{file}: {red} red pixels");
        }
    }
}

#[test]
fn motion_errors_are_answers_not_crashes() {
    let dir = tempfile::tempdir().unwrap();
    let far = dir.path().join("far.yaml");
    std::fs::write(&far, "plate: {position_m: [5.8, 0.0, 0.35]}\n").unwrap();
    let plan = common::plan_path("s1-wall");
    let out = dir.path().join("out");
    let args = [
        "motion",
        "config/parts/s1-wall.yaml",
        plan.to_str().unwrap(),
        "--robot",
        "urdf/waam_robot.urdf",
        "--process",
        far.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    let run = run_at_root(&args);
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert_eq!(run.status.code(), Some(1), "{stdout}");
    assert!(
        stdout.contains("NO MOTION: unreachable: pose 0"),
        "{stdout}"
    );
    assert!(!out.join("trajectory.yaml").exists());

    std::fs::write(&far, "plate: {position_m: [0.8, 0.0]}\n").unwrap();
    let run = run_at_root(&args);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2));
    assert!(stderr.contains("in process settings"), "{stderr}");

    let mut bad_tcp = args.to_vec();
    bad_tcp.retain(|a| *a != "--process" && *a != far.to_str().unwrap());
    bad_tcp.extend(["--tcp", "0 0 0.3"]);
    let run = run_at_root(&bad_tcp);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2));
    assert!(
        stderr.contains("--tcp: expected 6 finite numbers"),
        "{stderr}"
    );

    let run = run_at_root(&[
        "motion",
        "config/parts/s1-wall.yaml",
        plan.to_str().unwrap(),
        "--robot",
        "nowhere.urdf",
        "--out",
        "x",
    ]);
    assert_eq!(run.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&run.stderr).contains("nowhere.urdf"));
}

#[test]
fn plot_draws_a_planned_layer_as_layer_plot_does() {
    use waam_plot::layer::{TEMPERATURE_SIZE, TRAIL_SIZE};
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let layer = "config/layers/paper-16mm.yaml";
    let run = run_at_root(&[
        "-q",
        "layer",
        "plan",
        layer,
        "--robot",
        "urdf/waam_robot.urdf",
        "--out",
        out,
    ]);
    assert_eq!(
        run.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let run = run_at_root(&["plot", out, "--node", "E"]);
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert_eq!(
        run.status.code(),
        Some(0),
        "{stdout}{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let read = |file: &str| std::fs::read(dir.path().join(file)).unwrap();
    for (file, size) in [
        ("toolpath.png", waam_plot::TOOLPATH_SIZE),
        ("trail.png", TRAIL_SIZE),
        ("temperature.png", TEMPERATURE_SIZE),
    ] {
        assert!(stdout.contains(file), "{stdout}");
        let (w, h, pixels, bpp) = decode(&dir.path().join(file));
        assert_eq!((w, h), size, "{file}");
        let n = (w * h) as usize;
        let drawn = (0..n)
            .filter(|&i| pixels[i * bpp..i * bpp + 3] != [255, 255, 255])
            .count();
        assert!(drawn > n / 100, "{file}: only {drawn} of {n} pixels drawn");
    }
    // The same pictures as `waam layer plot`, and --node chooses the curve.
    let (trail, temperature) = (read("trail.png"), read("temperature.png"));
    let run = run_at_root(&["layer", "plot", out, "--node", "E"]);
    assert_eq!(run.status.code(), Some(0));
    assert!(read("trail.png") == trail && read("temperature.png") == temperature);
    let run = run_at_root(&["plot", out, "--node", "A"]);
    assert_eq!(run.status.code(), Some(0));
    assert!(read("trail.png") == trail && read("temperature.png") != temperature);
    // --node needs a layer; a bad node is named.
    let run = run_at_root(&["plot", out, "--node", "Z"]);
    assert_eq!(run.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&run.stderr).contains("--node Z"));
    let empty = tempfile::tempdir().unwrap();
    let run = run_at_root(&["plot", empty.path().to_str().unwrap(), "--node", "E"]);
    assert_eq!(run.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&run.stderr).contains("trail.yaml does not exist"));
}
