//! The first run: `waam plan` without a part runs the whole chain on the bundled part and
//! robot, writes every output into one new folder and prints a short summary.

use std::path::Path;

use waam_plot::blocks::{GIF_SIZE, HEAT_SIZE, PLAN_SIZE};
use waam_rosbag::Bag;

fn waam_in(dir: &Path, args: &[&str]) -> std::process::Output {
    crate::common::run::waam()
        .args(args)
        .current_dir(dir)
        .env_remove("RUST_LOG")
        .output()
        .unwrap()
}

/// Decodes a PNG: (width, height, RGB(A) bytes, bytes per pixel).
fn decode_png(path: &Path) -> (u32, u32, Vec<u8>, usize) {
    let decoder = png::Decoder::new(std::fs::File::open(path).unwrap());
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    buf.truncate(info.buffer_size());
    (info.width, info.height, buf, info.color_type.samples())
}

/// Distinct colours among the pixels that are not white.
fn drawn_colours(pixels: &[u8], bpp: usize) -> (usize, usize) {
    let mut seen = std::collections::HashSet::new();
    let mut drawn = 0;
    for px in pixels.chunks(bpp) {
        let rgb = [px[0], px[1], px[2]];
        if rgb != [255, 255, 255] {
            drawn += 1;
            seen.insert(rgb);
        }
    }
    (drawn, seen.len())
}

#[test]
fn first_run_writes_the_whole_chain_into_a_new_folder() {
    let cwd = tempfile::tempdir().unwrap();
    // An earlier run's folder is left alone: this run takes the next name.
    std::fs::create_dir(cwd.path().join("waam-out")).unwrap();
    std::fs::write(cwd.path().join("waam-out/keep.txt"), "mine").unwrap();
    let run = waam_in(cwd.path(), &["plan"]);
    let stdout = String::from_utf8_lossy(&run.stdout);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(0), "{stdout}{stderr}");
    let lines = stdout.lines().count();
    assert!((6..=20).contains(&lines), "{lines} lines:\n{stdout}");
    assert!(stdout.contains("optimal (proven)"), "{stdout}");
    assert!(stdout.contains("wrote waam-out-2/"), "{stdout}");
    assert!(
        stdout.contains("waam replay waam-out-2/recording"),
        "{stdout}"
    );
    assert!(stdout.contains("waam plot waam-out-2"), "{stdout}");
    // No block lists on the terminal.
    assert!(!stdout.contains("fragments:"), "{stdout}");
    // Issue #32: sentences only, no log lines below warnings, no debug structs, and no
    // colour escapes in output that goes to a pipe or a file.
    for text in [&stdout, &stderr] {
        assert!(!text.contains('\x1b'), "escape codes:\n{text}");
        assert!(
            !text.contains(" INFO ") && !text.contains("DEBUG"),
            "{text}"
        );
        assert!(
            !text.contains(" { ") && !text.contains("Violated"),
            "{text}"
        );
    }
    assert_eq!(
        std::fs::read_to_string(cwd.path().join("waam-out/keep.txt")).unwrap(),
        "mine"
    );
    let out = cwd.path().join("waam-out-2");
    for file in [
        "part.yaml",
        "plan.yaml",
        "toolpath.yaml",
        "trajectory.yaml",
        "plan3d.png",
        "heat.png",
        "heat.gif",
        "t85.png",
        "toolpath.png",
        "recording/metadata.yaml",
    ] {
        assert!(out.join(file).is_file(), "{file} missing");
    }
    // The plan is valid and feasible for the part written beside it.
    let check = waam_in(&out, &["check", "part.yaml", "plan.yaml"]);
    assert_eq!(
        check.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&check.stdout)
    );
    // The round part: a ring mesh sliced into beads, welded along its centre line, with
    // its plan valid and feasible on the graph part written beside it, G-code and pictures.
    assert!(stdout.contains("42 nodes in 2 layers"), "{stdout}");
    let ring = out.join("ring");
    for file in [
        "part.yaml",
        "plan.yaml",
        "toolpath.yaml",
        "trajectory.yaml",
        "WAAM.gcode",
        "plan3d.png",
        "toolpath.png",
    ] {
        assert!(ring.join(file).is_file(), "ring/{file} missing");
    }
    let part = std::fs::read_to_string(ring.join("part.yaml")).unwrap();
    assert!(
        waam_part::is_bead_part(&part),
        "ring/part.yaml is no graph part"
    );
    let check = waam_in(&ring, &["check", "part.yaml", "plan.yaml"]);
    let said = String::from_utf8_lossy(&check.stdout);
    assert_eq!(check.status.code(), Some(0), "{said}");
    assert!(
        said.contains("42 nodes") && said.contains("FEASIBLE"),
        "{said}"
    );
    // Every arc-on move of the G-code (part frame, mm) lies on the ring's centre line, r = 20
    // mm: within 0.03 mm on a layer (tests/ros/mesh_beads.py), and on the climb to the next
    // layer, which follows the circle (a straight climb over one 6 mm node would cut a chord
    // 6^2 / (8 * 20) = 0.225 mm inside it).
    let gcode = std::fs::read_to_string(ring.join("WAAM.gcode")).unwrap();
    let (mut arc, mut welded) = (false, 0);
    for line in gcode.lines() {
        arc = match line.split_whitespace().next() {
            Some("M3") => true,
            Some("M5") => false,
            _ => arc,
        };
        let word = |c: char| {
            line.split_whitespace()
                .find_map(|w| w.strip_prefix(c)?.parse::<f64>().ok())
        };
        if let (true, true, Some(x), Some(y)) = (arc, line.starts_with("G1"), word('X'), word('Y'))
        {
            welded += 1;
            let r = x.hypot(y);
            assert!((r - 20.0).abs() < 0.1, "a weld move at r = {r} mm: {line}");
        }
    }
    assert!(welded >= 42, "{welded} weld moves");
    // The recording is readable by our own reader and holds the plan and the motion.
    let bag = Bag::open(&out.join("recording")).unwrap();
    assert!(bag.truncated.is_none());
    assert_eq!(bag.count(waam_messages::topics::WELD_PLAN), 1);
    assert_eq!(bag.count(waam_messages::topics::JOINT_TRAJECTORY), 1);
    // Pictures of the expected size, with something drawn in many colours.
    for (file, size) in [
        ("plan3d.png", PLAN_SIZE),
        ("heat.png", HEAT_SIZE),
        ("t85.png", waam_plot::T85_SIZE),
        ("toolpath.png", waam_plot::TOOLPATH_SIZE),
    ] {
        let (w, h, pixels, bpp) = decode_png(&out.join(file));
        assert_eq!((w, h), size, "{file}");
        let (drawn, colours) = drawn_colours(&pixels, bpp);
        let n = (w * h) as usize;
        assert!(drawn > n / 20, "{file}: {drawn} of {n} pixels drawn");
        assert!(colours > 20, "{file}: {colours} colours");
    }
    // The animation: one frame per stage of the build, the last held, none blank.
    let mut options = gif::DecodeOptions::new();
    options.set_color_output(gif::ColorOutput::RGBA);
    let mut decoder = options
        .read_info(std::fs::File::open(out.join("heat.gif")).unwrap())
        .unwrap();
    assert_eq!((decoder.width() as u32, decoder.height() as u32), GIF_SIZE);
    let mut frames = 0;
    while let Some(frame) = decoder.read_next_frame().unwrap() {
        let (drawn, colours) = drawn_colours(&frame.buffer, 4);
        assert!(
            drawn > 1000 && colours > 10,
            "frame {frames}: {drawn} px, {colours} colours"
        );
        frames += 1;
    }
    assert!(frames >= 10, "{frames} frames");
    // `waam plot DIR` draws the same pictures again from the folder alone.
    let plot = waam_in(cwd.path(), &["plot", "waam-out-2"]);
    let said = String::from_utf8_lossy(&plot.stdout);
    assert_eq!(plot.status.code(), Some(0), "{said}");
    for file in [
        "plan3d.png",
        "heat.png",
        "heat.gif",
        "t85.png",
        "toolpath.png",
    ] {
        assert!(said.contains(file), "{said}");
    }
}

#[test]
fn first_run_never_writes_into_a_non_empty_folder() {
    let cwd = tempfile::tempdir().unwrap();
    std::fs::create_dir(cwd.path().join("mine")).unwrap();
    std::fs::write(cwd.path().join("mine/plan.yaml"), "keep").unwrap();
    let run = waam_in(cwd.path(), &["plan", "--out", "mine"]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
    assert!(stderr.contains("not empty"), "{stderr}");
    assert_eq!(
        std::fs::read_to_string(cwd.path().join("mine/plan.yaml")).unwrap(),
        "keep"
    );
}
