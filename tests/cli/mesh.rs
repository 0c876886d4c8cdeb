//! `waam voxelize` through the binary: it writes a part file that reads back (the mesh
//! library's own tests: `crates/mesh/tests/mesh.rs`).

use std::path::PathBuf;

use waam_part::writer;
use waam_part::Part;

fn data(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

#[test]
fn waam_voxelize_writes_a_part_file_that_reads_back() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("tube.yaml");
    let status = crate::common::run::waam()
        .args(["-q", "voxelize"])
        .arg(data("tube_binary.stl"))
        .args(["--pitch", "6 6 2.5", "--k", "2", "--name", "tube"])
        .args(["--window", "2 4 0 0 1 3 0 1", "--window", "2 4 3 3 1"])
        .arg("--out")
        .arg(&out)
        .status()
        .unwrap();
    assert!(status.success());
    let text = std::fs::read_to_string(&out).unwrap();
    let part = Part::parse(&text).unwrap();
    let ring = Part::parse(
        &std::fs::read_to_string(
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("config/parts/s3-ring.yaml"),
        )
        .unwrap(),
    )
    .unwrap();
    // The same blocks and windows as s3-ring, so `waam check` treats both alike.
    assert_eq!(part.blocks(), ring.blocks());
    assert_eq!(part.windows(), ring.windows());
    assert_eq!(part.max_fragments, 2);
    assert_eq!(writer::to_yaml(&part), text);

    let run = |args: &[&str]| {
        crate::common::run::waam()
            .args(["-q", "voxelize"])
            .args(args)
            .output()
            .unwrap()
    };
    let open = run(&[data("open_box.stl").to_str().unwrap(), "--pitch", "6 6 2.5"]);
    assert_eq!(open.status.code(), Some(2));
    let err = String::from_utf8_lossy(&open.stderr);
    assert!(err.contains("open mesh: 4 boundary edge(s)"), "{err}");
    let no_pitch = run(&[data("open_box.stl").to_str().unwrap()]);
    assert_eq!(no_pitch.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&no_pitch.stderr).contains("needs --pitch"));
}
