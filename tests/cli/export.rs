//! `waam export` end to end: each format's program parsed back and checked against the
//! motion it came from — one target per toolpath pose at that pose (0.01 mm, 0.01°), arc-on
//! and arc-off pairs at the toolpath's arc switches (one pair per weld pass), speeds and
//! dwells of the trajectory's timeline, and configuration data of the joint solution's
//! branch. RAPID modules go through `rapidchecker`, G-code is replayed by `pygcode`
//! (tests/py/replay_gcode.py); both from the venv of `scripts/export-venv.sh`, which the
//! test script exports as `WAAM_EXPORT_PYTHON`.

use crate::common;
use crate::common::run::run_at_root;

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};
use waam_motion::toolpath::{ProcessSettings, ToolpathFile};
use waam_motion::trajectory::TrajectoryFile;

const URDF: &str = "tests/data/abb_irb1600_12.urdf";

fn ok(out: &Output) -> String {
    let stdout = String::from_utf8_lossy(&out.stdout).to_string();
    assert_eq!(
        out.status.code(),
        Some(0),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

/// The motion of s2-corner (two weld passes) on the ABB arm, written once.
fn motion_dir() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let plan = common::plan_path("s2-corner");
        ok(&run_at_root(&[
            "motion",
            "config/parts/s2-corner.yaml",
            plan.to_str().unwrap(),
            "--robot",
            URDF,
            "--tcp",
            common::ABB_TCP,
            "--out",
            dir.path().to_str().unwrap(),
        ]));
        dir
    })
    .path()
}

/// Exports the motion in `format` into a new directory; extra arguments appended.
fn export(format: &str, extra: &[&str]) -> (tempfile::TempDir, String) {
    let out = tempfile::tempdir().unwrap();
    let mut args = vec![
        "export",
        motion_dir().to_str().unwrap(),
        "--format",
        format,
        "--robot",
        URDF,
        "--tcp",
        common::ABB_TCP,
        "--out",
        out.path().to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let stdout = ok(&run_at_root(&args));
    (out, stdout)
}

fn read(dir: &Path, name: &str) -> String {
    std::fs::read_to_string(dir.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// What the program must say, from the motion files.
struct Expect {
    /// TCP poses in the base link, m.
    base: Vec<Isometry3<f64>>,
    plate: Isometry3<f64>,
    arc: Vec<bool>,
    time: Vec<f64>,
    joints: Vec<Vec<f64>>,
    passes: usize,
}

/// How the TCP gets into pose i.
#[derive(Debug, PartialEq)]
enum Step {
    First,
    Speed(f64),
    Wait(f64),
}

impl Expect {
    fn load() -> Expect {
        let tp: ToolpathFile = serde_yaml::from_str(&read(motion_dir(), "toolpath.yaml")).unwrap();
        let traj: TrajectoryFile =
            serde_yaml::from_str(&read(motion_dir(), "trajectory.yaml")).unwrap();
        assert_eq!(tp.poses.len(), traj.points.len());
        let passes = tp.poses.iter().map(|p| p.fragment).max().unwrap() + 1;
        Expect {
            base: tp.poses.iter().map(|p| p.isometry()).collect(),
            plate: ProcessSettings::default().plate.isometry(),
            arc: tp.poses.iter().map(|p| p.arc_on).collect(),
            time: traj.points.iter().map(|p| p.time_from_start).collect(),
            joints: traj.points.iter().map(|p| p.positions.clone()).collect(),
            passes,
        }
    }

    fn n(&self) -> usize {
        self.base.len()
    }

    fn part(&self, i: usize) -> Isometry3<f64> {
        self.plate.inverse() * self.base[i]
    }

    fn step(&self, i: usize) -> Step {
        if i == 0 {
            return Step::First;
        }
        let dist =
            (self.base[i].translation.vector - self.base[i - 1].translation.vector).norm() * 1e3;
        let dt = self.time[i] - self.time[i - 1];
        let deg = self.base[i]
            .rotation
            .angle_to(&self.base[i - 1].rotation)
            .to_degrees();
        assert!(dist >= 1e-3 || deg < 1e-3, "no turn-only moves here");
        if dist >= 1e-3 {
            Step::Speed(dist / dt)
        } else {
            Step::Wait(dt)
        }
    }

    /// Indices of the poses where the arc switches on and off.
    fn switches(&self) -> (Vec<usize>, Vec<usize>) {
        let mut on = Vec::new();
        let mut off = Vec::new();
        for i in 0..self.n() {
            let before = i > 0 && self.arc[i - 1];
            match (before, self.arc[i]) {
                (false, true) => on.push(i),
                (true, false) => off.push(i),
                _ => {}
            }
        }
        (on, off)
    }

    /// (behind, elbow, wrist negative) of pose i's joint solution: the analytic solver's
    /// shoulder and elbow bits, the sign of joint 5.
    fn branch(&self, i: usize) -> (bool, bool, bool) {
        let robot = common::abb_robot();
        let c = robot.opw().unwrap().configuration(&self.joints[i]);
        (c & 1 != 0, c & 2 != 0, self.joints[i][4] < 0.0)
    }

    fn deg(&self, i: usize, j: usize) -> f64 {
        self.joints[i][j].to_degrees()
    }

    /// Pose i matches `got` (in the part frame) within 0.01 mm and 0.01°.
    fn assert_pose(&self, i: usize, got: &Isometry3<f64>, what: &str) {
        let want = self.part(i);
        let dmm = (got.translation.vector - want.translation.vector).norm() * 1e3;
        let ddeg = got.rotation.angle_to(&want.rotation).to_degrees();
        assert!(
            dmm <= 0.01 && ddeg <= 0.01,
            "{what} target {i}: {dmm:.4} mm / {ddeg:.4} deg off the toolpath pose"
        );
    }
}

/// All numbers in a text (brackets, braces and separators ignored).
fn numbers(text: &str) -> Vec<f64> {
    text.split(|c: char| !(c.is_ascii_digit() || c == '.' || c == '-' || c == '+' || c == 'E'))
        .filter_map(|s| s.parse().ok())
        .collect()
}

fn iso_mm(xyz: &[f64], r: UnitQuaternion<f64>) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(xyz[0] / 1e3, xyz[1] / 1e3, xyz[2] / 1e3),
        r,
    )
}

/// R = Rz(rz)·Ry(ry)·Rx(rx), degrees.
fn zyx(rx: f64, ry: f64, rz: f64) -> UnitQuaternion<f64> {
    UnitQuaternion::from_euler_angles(rx.to_radians(), ry.to_radians(), rz.to_radians())
}

fn python() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("WAAM_EXPORT_PYTHON") {
        return Some(PathBuf::from(p));
    }
    if std::env::var("WAAM_SKIP_PY").as_deref() == Ok("1") {
        eprintln!("WAAM_SKIP_PY=1: skipping the Python check");
        return None;
    }
    panic!(
        "WAAM_EXPORT_PYTHON is not set. Run the tests through scripts/test.sh, or \
         `export WAAM_EXPORT_PYTHON=$(scripts/export-venv.sh | tail -1)` first \
         (or set WAAM_SKIP_PY=1 to skip the Python checks)."
    );
}

#[test]
fn rapid_targets_arcs_speeds_waits_and_confdata_match_the_motion() {
    let e = Expect::load();
    let (dir, stdout) = export("rapid", &[]);
    assert!(stdout.contains("EXPORT: rapid"), "{stdout}");
    let main = read(dir.path(), "WAAM.mod");
    let part = read(dir.path(), "WAAM_1.mod");
    assert!(
        main.contains("PROC main()") && main.contains("    WAAM_1;"),
        "{main}"
    );
    // The work object is the plate frame.
    let wobj = main.lines().find(|l| l.contains("PERS wobjdata")).unwrap();
    let w = numbers(wobj.split("\"\"").nth(1).unwrap());
    let uframe = iso_mm(
        &w[0..3],
        UnitQuaternion::from_quaternion(Quaternion::new(w[3], w[4], w[5], w[6])),
    );
    assert!((uframe.translation.vector - e.plate.translation.vector).norm() < 1e-6);
    let data = |kind: &str| -> HashMap<String, f64> {
        main.lines()
            .filter(|l| l.contains(kind))
            .map(|l| {
                let name = l
                    .split(kind)
                    .nth(1)
                    .unwrap()
                    .split_whitespace()
                    .next()
                    .unwrap();
                let v = numbers(l.split(":=").nth(1).unwrap())[0];
                (name.to_string(), v)
            })
            .collect()
    };
    let speeds = data("speeddata ");
    let welds = data("welddata ");
    assert!(!welds.is_empty() && !speeds.is_empty());

    // One robtarget per toolpath pose, at the pose, with the branch's confdata.
    let targets: Vec<Vec<f64>> = part
        .lines()
        .filter(|l| l.contains("CONST robtarget"))
        .map(|l| numbers(l.split(":=").nth(1).unwrap()))
        .collect();
    assert_eq!(targets.len(), e.n());
    for (i, t) in targets.iter().enumerate() {
        let r = UnitQuaternion::from_quaternion(Quaternion::new(t[3], t[4], t[5], t[6]));
        e.assert_pose(i, &iso_mm(&t[0..3], r), "RAPID");
        let (behind, elbow, wrist) = e.branch(i);
        let quad = |j: usize| (e.deg(i, j) / 90.0).floor();
        let cfx = 4.0 * behind as u8 as f64 + 2.0 * elbow as u8 as f64 + wrist as u8 as f64;
        assert_eq!(
            t[7..11],
            [quad(0), quad(3), quad(5), cfx],
            "confdata of pW{}",
            i + 1
        );
    }

    // One move per target, in order; arcs, speeds and waits of the timeline.
    let body: Vec<&str> = part
        .lines()
        .map(str::trim)
        .filter(|l| {
            [
                "MoveJ ",
                "MoveL ",
                "ArcLStart ",
                "ArcL ",
                "ArcLEnd ",
                "WaitTime ",
            ]
            .iter()
            .any(|k| l.starts_with(k))
        })
        .collect();
    let (on, off) = e.switches();
    assert_eq!(on.len(), e.passes);
    assert_eq!(off.len(), e.passes);
    let mut i = 0;
    let mut wait = None;
    let (mut starts, mut ends) = (Vec::new(), Vec::new());
    for line in body {
        let words: Vec<&str> = line
            .split([' ', ',', ';'])
            .filter(|w| !w.is_empty())
            .collect();
        if words[0] == "WaitTime" {
            wait = Some(words[2].parse::<f64>().unwrap());
            continue;
        }
        assert_eq!(words[1], format!("pW{}", i + 1), "{line}");
        match words[0] {
            "ArcLStart" => starts.push(i),
            "ArcLEnd" => ends.push(i),
            _ => {}
        }
        match e.step(i) {
            Step::First => assert_eq!(words[0], "MoveJ"),
            Step::Wait(dt) => {
                let w = wait
                    .take()
                    .unwrap_or_else(|| panic!("no WaitTime before {line}"));
                assert!((w - dt).abs() < 6e-4, "{line}: wait {w} s, timeline {dt} s");
            }
            Step::Speed(v) => {
                assert!(wait.is_none(), "a wait before a move: {line}");
                let got = if e.arc[i - 1] {
                    assert!(matches!(words[0], "ArcL" | "ArcLEnd"), "{line}");
                    welds[words[4]]
                } else {
                    assert!(matches!(words[0], "MoveL" | "ArcLStart"), "{line}");
                    speeds[words[2]]
                };
                assert!(
                    (got - v).abs() < 6e-3,
                    "{line}: {got} mm/s, timeline {v} mm/s"
                );
            }
        }
        i += 1;
    }
    assert_eq!(i, e.n());
    assert_eq!((starts, ends), (on, off));
}

#[test]
fn rapid_modules_pass_rapidchecker() {
    let Some(python) = python() else { return };
    let (dir, _) = export("rapid", &[]);
    for name in ["WAAM.mod", "WAAM_1.mod"] {
        assert_rapid_ok(&python, dir.path(), name);
    }
    // And it does find errors: a module with a broken instruction fails.
    let bad = read(dir.path(), "WAAM_1.mod").replacen("MoveJ pW1,", "MoveJ pW1", 1);
    std::fs::write(dir.path().join("bad.mod"), bad).unwrap();
    assert!(!rapidchecker(&python, dir.path(), "bad.mod")
        .status
        .success());
}

/// `rapidchecker` run on the module `name` in `dir`.
fn rapidchecker(python: &Path, dir: &Path, name: &str) -> Output {
    Command::new(python)
        .args(["-m", "rapidchecker"])
        .arg(dir.join(name))
        .current_dir(dir)
        .output()
        .unwrap()
}

/// Asserts that `rapidchecker` finds no error in the module `name` in `dir`.
fn assert_rapid_ok(python: &Path, dir: &Path, name: &str) {
    let out = rapidchecker(python, dir, name);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && text.contains("No RAPID format errors"),
        "{name}: {text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn long_rapid_programs_split_between_passes() {
    let e = Expect::load();
    let cell = tempfile::NamedTempFile::new().unwrap();
    std::fs::write(cell.path(), "max_targets: {rapid: 40}\n").unwrap();
    let (dir, stdout) = export("rapid", &["--cell", cell.path().to_str().unwrap()]);
    assert!(stdout.contains("3 file(s)"), "{stdout}");
    let main = read(dir.path(), "WAAM.mod");
    let calls: Vec<&str> = main
        .lines()
        .map(str::trim)
        .filter(|l| l.starts_with("WAAM_"))
        .collect();
    assert_eq!(calls, ["WAAM_1;", "WAAM_2;"]);
    let mut total = 0;
    for k in 1..=2 {
        let m = read(dir.path(), &format!("WAAM_{k}.mod"));
        let n = m.matches("CONST robtarget").count();
        assert!(n <= 40, "module {k}: {n} targets");
        // A module holds whole passes: every ArcLStart has its ArcLEnd.
        assert_eq!(
            m.matches("ArcLStart ").count(),
            m.matches("ArcLEnd ").count()
        );
        total += n;
    }
    assert_eq!(total, e.n());

    // A pass longer than the limit is refused by KRL, naming the key.
    std::fs::write(cell.path(), "max_targets: {krl: 5}\n").unwrap();
    let out = run_at_root(&[
        "export",
        motion_dir().to_str().unwrap(),
        "--format",
        "krl",
        "--robot",
        URDF,
        "--tcp",
        common::ABB_TCP,
        "--cell",
        cell.path().to_str().unwrap(),
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("max_targets.krl"), "{err}");
}

#[test]
fn rapid_splits_a_pass_longer_than_the_limit_between_procedures() {
    let e = Expect::load();
    let cell = tempfile::NamedTempFile::new().unwrap();
    std::fs::write(cell.path(), "max_targets: {rapid: 5}\n").unwrap();
    let (dir, _) = export("rapid", &["--cell", cell.path().to_str().unwrap()]);
    let main = read(dir.path(), "WAAM.mod");
    let calls: Vec<String> = main
        .lines()
        .map(str::trim)
        .filter(|l| l.starts_with("WAAM_"))
        .map(|l| l.trim_end_matches(';').to_string())
        .collect();
    assert!(calls.len() >= e.n().div_ceil(5), "{calls:?}");
    // The moves of the modules, in the order main calls them, are the whole motion: one
    // weld opened by ArcLStart, continued by ArcL (also across a call), closed by ArcLEnd.
    let (mut moves, mut welding, mut split_inside_weld) = (0, false, false);
    let (mut starts, mut ends) = (Vec::new(), Vec::new());
    for name in &calls {
        let m = read(dir.path(), &format!("{name}.mod"));
        let n = m.matches("CONST robtarget").count();
        assert!((1..=5).contains(&n), "{name}: {n} targets");
        split_inside_weld |= welding;
        for l in m.lines().map(str::trim) {
            match l.split_whitespace().next().unwrap_or("") {
                "ArcLStart" => {
                    assert!(!welding, "{name}: {l}");
                    welding = true;
                    starts.push(moves);
                }
                "ArcL" => assert!(welding, "{name}: ArcL with no weld open: {l}"),
                "ArcLEnd" => {
                    assert!(welding, "{name}: {l}");
                    welding = false;
                    ends.push(moves);
                }
                "MoveL" | "MoveJ" => assert!(!welding, "{name}: a move with the arc on: {l}"),
                _ => continue,
            }
            // Move k goes to target pW(k+1): the targets stay in the motion's order.
            assert!(l.contains(&format!(" pW{},", moves + 1)), "{name}: {l}");
            moves += 1;
        }
    }
    assert!(!welding);
    assert_eq!(moves, e.n());
    assert!(split_inside_weld, "no module boundary falls inside a weld");
    // The arc switches on and off exactly where the motion switches it.
    assert_eq!((starts, ends), e.switches());

    let Some(python) = python() else { return };
    for name in std::iter::once("WAAM".to_string()).chain(calls) {
        assert_rapid_ok(&python, dir.path(), &format!("{name}.mod"));
    }
}

#[test]
fn krl_targets_arcs_speeds_waits_and_status_turn_match_the_motion() {
    let e = Expect::load();
    let (dir, _) = export("krl", &[]);
    let main_dat = read(dir.path(), "WAAM.dat");
    let frame = |line: &str| -> HashMap<String, f64> {
        let inner = line.split('{').nth(1).unwrap().split('}').next().unwrap();
        inner
            .split(',')
            .map(|kv| {
                let mut it = kv.split_whitespace();
                (
                    it.next().unwrap().to_string(),
                    it.next().unwrap().parse().unwrap(),
                )
            })
            .collect()
    };
    let base = frame(main_dat.lines().find(|l| l.contains("WAAM_BASE=")).unwrap());
    assert!((base["X"] - e.plate.translation.x * 1e3).abs() < 1e-3);
    let dat = read(dir.path(), "WAAM_1.dat");
    let pos: Vec<HashMap<String, f64>> = dat
        .lines()
        .filter(|l| l.starts_with("DECL E6POS"))
        .map(frame)
        .collect();
    assert_eq!(pos.len(), e.n());
    for (i, p) in pos.iter().enumerate() {
        let r = zyx(p["C"], p["B"], p["A"]);
        e.assert_pose(i, &iso_mm(&[p["X"], p["Y"], p["Z"]], r), "KRL");
        let (behind, elbow, wrist) = e.branch(i);
        let status = behind as u32 | (elbow as u32) << 1 | (wrist as u32) << 2;
        let turn: u32 = (0..6)
            .filter(|&j| e.joints[i][j] < 0.0)
            .map(|j| 1 << j)
            .sum();
        assert_eq!(
            (p["S"] as u32, p["T"] as u32),
            (status, turn),
            "XP{}",
            i + 1
        );
    }
    let src = read(dir.path(), "WAAM_1.src");
    let (on, off) = e.switches();
    let (mut ons, mut offs) = (Vec::new(), Vec::new());
    let (mut vel, mut wait, mut fold) = (None, None, None);
    let mut i = 0;
    for line in src.lines().map(str::trim) {
        if let Some(v) = line.strip_prefix("$VEL.CP = ") {
            vel = Some(v.parse::<f64>().unwrap() * 1e3);
        } else if let Some(t) = line.strip_prefix("WAIT SEC ") {
            wait = Some(t.parse::<f64>().unwrap());
        } else if let Some(f) = line.strip_prefix(";FOLD ARC") {
            fold = Some(f.split_whitespace().next().unwrap().to_string());
        } else if line.starts_with("PTP XP") || line.starts_with("LIN XP") {
            let name = line.split_whitespace().nth(1).unwrap();
            assert_eq!(name, format!("XP{}", i + 1));
            match fold.take().as_deref() {
                Some("ON") => ons.push(i),
                Some("OFF") => offs.push(i),
                Some("SWI") => assert!(e.arc[i - 1] && e.arc[i], "ARCSWI off the weld at {i}"),
                Some(other) => panic!("unknown fold ARC{other}"),
                None => assert!(
                    !(i > 0 && e.arc[i - 1]),
                    "a weld move without ARCSWI at {i}"
                ),
            }
            match e.step(i) {
                Step::First => assert!(line.starts_with("PTP")),
                Step::Wait(dt) => assert!((wait.take().unwrap() - dt).abs() < 6e-4),
                Step::Speed(v) => {
                    let got = vel.unwrap();
                    assert!((got - v).abs() < 6e-3, "{line}: {got} mm/s, timeline {v}");
                }
            }
            i += 1;
        }
    }
    assert_eq!(i, e.n());
    assert_eq!((ons, offs), (on, off));
    assert_eq!(
        src.matches(";ENDFOLD").count(),
        src.matches(";FOLD ").count()
    );
}

#[test]
fn inform_positions_arcs_speeds_timers_and_rconf_match_the_motion() {
    let e = Expect::load();
    let (dir, _) = export("inform", &[]);
    let main = read(dir.path(), "WAAM.JBI");
    assert!(main.contains("CALL JOB:WAAM_1"));
    let job = read(dir.path(), "WAAM_1.JBI");
    assert!(job.contains(&format!("///NPOS {},0,0,0,0,0", e.n())));
    let mut rconf = Vec::new();
    let mut pos = Vec::new();
    for line in job.lines() {
        if let Some(r) = line.strip_prefix("///RCONF ") {
            rconf = numbers(r);
        } else if line.starts_with('C') && line.contains('=') {
            pos.push((numbers(line.split('=').nth(1).unwrap()), rconf.clone()));
        }
    }
    assert_eq!(pos.len(), e.n());
    for (i, (p, rc)) in pos.iter().enumerate() {
        e.assert_pose(i, &iso_mm(&p[0..3], zyx(p[3], p[4], p[5])), "INFORM");
        let (behind, elbow, wrist) = e.branch(i);
        assert_eq!(
            rc[0..3],
            [wrist as u8 as f64, elbow as u8 as f64, behind as u8 as f64],
            "RCONF of C{i:05}"
        );
    }
    let (on, off) = e.switches();
    let (mut ons, mut offs) = (Vec::new(), Vec::new());
    let mut wait = None;
    let mut i = 0;
    for line in job.split("//INST").nth(1).unwrap().lines() {
        if let Some(t) = line.strip_prefix("TIMER T=") {
            wait = Some(t.parse::<f64>().unwrap());
        } else if line.starts_with("ARCON ASF#(") {
            ons.push(i - 1);
        } else if line.starts_with("ARCOF AEF#(") {
            offs.push(i - 1);
        } else if line.starts_with("MOVJ C") || line.starts_with("MOVL C") {
            assert!(line.contains(&format!("C{i:05}")), "{line}");
            match e.step(i) {
                Step::First => assert!(line.starts_with("MOVJ")),
                Step::Wait(dt) => assert!((wait.take().unwrap() - dt).abs() < 6e-3),
                Step::Speed(v) => {
                    let got: f64 = line.split("V=").nth(1).unwrap().parse().unwrap();
                    assert!((got - v).abs() < 0.06, "{line}: timeline {v} mm/s");
                }
            }
            i += 1;
        }
    }
    assert_eq!(i, e.n());
    assert_eq!((ons, offs), (on, off));
}

#[test]
fn fanuc_positions_arcs_speeds_waits_and_config_match_the_motion() {
    let e = Expect::load();
    let (dir, _) = export("fanuc", &[]);
    let main = read(dir.path(), "WAAM.ls");
    assert!(main.contains("CALL WAAM_1 ;"));
    // The weld schedules' travel speeds, from the main program's comments.
    let schedules: HashMap<u32, f64> = main
        .lines()
        .filter_map(|l| l.split("! Weld Schedule ").nth(1))
        .map(|s| {
            let n = numbers(s);
            (n[0] as u32, n[1])
        })
        .collect();
    let prog = read(dir.path(), "WAAM_1.ls");
    let blocks: Vec<&str> = prog.split("/POS").nth(1).unwrap().split("};").collect();
    let pos: Vec<(String, HashMap<String, f64>)> = blocks
        .iter()
        .filter(|b| b.contains("CONFIG"))
        .map(|b| {
            let config = b.split('\'').nth(1).unwrap().to_string();
            let mut v = HashMap::new();
            for key in ["X", "Y", "Z", "W", "P", "R"] {
                let s = b.split(&format!("\t{key} = ")).nth(1).unwrap();
                v.insert(key.to_string(), numbers(s)[0]);
            }
            (config, v)
        })
        .collect();
    assert_eq!(pos.len(), e.n());
    for (i, (config, v)) in pos.iter().enumerate() {
        e.assert_pose(
            i,
            &iso_mm(&[v["X"], v["Y"], v["Z"]], zyx(v["W"], v["P"], v["R"])),
            "Fanuc",
        );
        let (behind, elbow, wrist) = e.branch(i);
        let turn = |j: usize| ((e.deg(i, j) - 180.0) / 360.0).ceil() as i32;
        let want = format!(
            "{} {} {}, {}, {}, {}",
            if wrist { 'F' } else { 'N' },
            if elbow { 'D' } else { 'U' },
            if behind { 'B' } else { 'T' },
            turn(0),
            turn(3),
            turn(5)
        );
        assert_eq!(config, &want, "P[{}]", i + 1);
    }
    let (on, off) = e.switches();
    let (mut ons, mut offs) = (Vec::new(), Vec::new());
    let (mut wait, mut schedule) = (None, 0);
    let mut i = 0;
    let mn = prog
        .split("/MN")
        .nth(1)
        .unwrap()
        .split("/POS")
        .next()
        .unwrap();
    for line in mn
        .lines()
        .filter_map(|l| l.split_once(':').map(|(_, t)| t.trim()))
    {
        if let Some(t) = line.strip_prefix("WAIT ") {
            wait = Some(numbers(t)[0]);
        } else if let Some(s) = line.strip_prefix("Arc Start[") {
            schedule = numbers(s)[0] as u32;
        } else if line.starts_with("J P[") || line.starts_with("L P[") {
            assert!(
                line.starts_with(&format!("{} P[{}]", &line[..1], i + 1)),
                "{line}"
            );
            if let Some(s) = line.split("Arc Start[").nth(1) {
                schedule = numbers(s)[0] as u32;
                ons.push(i);
            }
            if line.contains("Arc End[") {
                offs.push(i);
            }
            match e.step(i) {
                Step::First => assert!(line.starts_with('J')),
                Step::Wait(dt) => assert!((wait.take().unwrap() - dt).abs() < 6e-3),
                Step::Speed(v) if e.arc[i - 1] => {
                    assert!(line.contains("WELD_SPEED"), "{line}");
                    let got = schedules[&schedule];
                    assert!(
                        (got - v).abs() < 6e-3,
                        "{line}: schedule {schedule} {got} mm/s, timeline {v}"
                    );
                }
                Step::Speed(v) => {
                    let got = numbers(line.split(']').nth(1).unwrap())[0];
                    assert!((got - v).abs() <= 0.5 + 1e-9, "{line}: timeline {v} mm/s");
                }
            }
            i += 1;
        }
    }
    assert_eq!(i, e.n());
    assert_eq!((ons, offs), (on, off));
}

#[test]
fn gcode_replayed_by_pygcode_follows_the_toolpath_with_its_arc_and_timing() {
    let Some(python) = python() else { return };
    let e = Expect::load();
    let (dir, _) = export("gcode", &[]);
    let out = Command::new(&python)
        .arg(common::root().join("tests/py/replay_gcode.py"))
        .arg(dir.path().join("WAAM.gcode"))
        .args(["M3", "M5"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let events: Vec<serde_json::Value> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let mut i = 0;
    let mut wait = None;
    let mut arc_at = Vec::new();
    for ev in &events {
        if let Some(d) = ev.get("dwell") {
            wait = Some(d.as_f64().unwrap());
            continue;
        }
        let xyz: Vec<f64> = ev["xyz"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        let want = e.part(i).translation.vector * 1e3;
        let d = ((xyz[0] - want.x).powi(2) + (xyz[1] - want.y).powi(2) + (xyz[2] - want.z).powi(2))
            .sqrt();
        assert!(d <= 0.01, "move {i}: {d} mm off the toolpath");
        // The arc state while moving into pose i is the toolpath's before it.
        arc_at.push(ev["arc"].as_bool().unwrap());
        match e.step(i) {
            Step::First => assert_eq!(ev["g"], 0),
            Step::Wait(dt) => assert!((wait.take().unwrap() - dt).abs() < 6e-4),
            Step::Speed(v) => {
                let feed = ev["feed"].as_f64().unwrap();
                assert!(
                    (feed - v * 60.0).abs() < 6e-3 * 60.0,
                    "move {i}: F{feed}, timeline {v} mm/s"
                );
            }
        }
        i += 1;
    }
    assert_eq!(i, e.n());
    let want: Vec<bool> = (0..e.n()).map(|i| i > 0 && e.arc[i - 1]).collect();
    assert_eq!(arc_at, want);
    let gcode = read(dir.path(), "WAAM.gcode");
    let count = |cmd: &str| gcode.lines().filter(|l| l.trim() == cmd).count();
    assert_eq!((count("M3"), count("M5")), (e.passes, e.passes));
}

#[test]
fn robot_formats_need_the_robot_and_bad_cells_are_refused() {
    let out = run_at_root(&["export", motion_dir().to_str().unwrap(), "--format", "krl"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("--robot") && err.lines().count() == 1, "{err}");

    // The wrong TCP does not reproduce the toolpath.
    let out = run_at_root(&[
        "export",
        motion_dir().to_str().unwrap(),
        "--format",
        "rapid",
        "--robot",
        URDF,
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("--tcp"), "{err}");

    let cell = tempfile::NamedTempFile::new().unwrap();
    std::fs::write(cell.path(), "voltage: 20\n").unwrap();
    let out = run_at_root(&[
        "export",
        motion_dir().to_str().unwrap(),
        "--format",
        "gcode",
        "--cell",
        cell.path().to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("voltage"), "{err}");

    let out = run_at_root(&["export", "/nonexistent-dir", "--format", "gcode"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("toolpath.yaml"), "{err}");
}

#[test]
fn plan_with_export_writes_the_program_beside_the_motion() {
    let dir = tempfile::tempdir().unwrap();
    let stdout = ok(&run_at_root(&[
        "plan",
        "config/parts/s2-corner.yaml",
        "--robot",
        URDF,
        "--tcp",
        common::ABB_TCP,
        "--out",
        dir.path().to_str().unwrap(),
        "--export",
        "gcode",
        "-q",
    ]));
    assert!(stdout.contains("EXPORT: gcode"), "{stdout}");
    let gcode = read(dir.path(), "WAAM.gcode");
    let tp: ToolpathFile = serde_yaml::from_str(&read(dir.path(), "toolpath.yaml")).unwrap();
    let moves = gcode
        .lines()
        .filter(|l| l.starts_with("G0 ") || l.starts_with("G1 "))
        .count();
    assert_eq!(moves, tp.poses.len());
}

#[test]
fn layer_plan_with_export_writes_an_inform_job_at_the_layer_weld_speed() {
    let dir = tempfile::tempdir().unwrap();
    let stdout = ok(&run_at_root(&[
        "-q",
        "layer",
        "plan",
        "config/layers/paper-16mm.yaml",
        "--robot",
        "urdf/waam_robot.urdf",
        "--out",
        dir.path().to_str().unwrap(),
        "--export",
        "inform",
    ]));
    assert!(stdout.contains("EXPORT: inform"), "{stdout}");
    let tp: ToolpathFile = serde_yaml::from_str(&read(dir.path(), "toolpath.yaml")).unwrap();
    let job = read(dir.path(), "WAAM_1.JBI");
    let positions = job
        .lines()
        .filter(|l| l.starts_with('C') && l.contains('='))
        .count();
    assert_eq!(positions, tp.poses.len());
    // One ARCON/ARCOF pair per arc-on stretch of the trail (deadheading moves are arc off).
    let stretches = tp
        .poses
        .windows(2)
        .filter(|w| !w[0].arc_on && w[1].arc_on)
        .count()
        + tp.poses[0].arc_on as usize;
    assert!(stretches >= 1);
    assert_eq!(job.matches("\nARCON ").count(), stretches);
    assert_eq!(job.matches("\nARCOF ").count(), stretches);
    // The layer is welded at its own weld speed (10 mm/s in the paper's instance).
    let layer =
        std::fs::read_to_string(common::root().join("config/layers/paper-16mm.yaml")).unwrap();
    let speed: f64 = layer
        .lines()
        .find_map(|l| l.trim().strip_prefix("weld_speed_mm_s:"))
        .and_then(|v| v.split('#').next().unwrap().trim().parse().ok())
        .expect("the layer's weld speed");
    let (mut arc, mut after_wait) = (false, false);
    let mut weld_moves = 0;
    for line in job.split("//INST").nth(1).unwrap().lines() {
        if line.starts_with("ARCON") {
            arc = true;
        } else if line.starts_with("ARCOF") {
            arc = false;
        } else if line.starts_with("TIMER") {
            after_wait = true;
        } else if line.starts_with("MOVL") && std::mem::take(&mut after_wait) {
            // The zero-length move after a dwell.
        } else if arc && line.starts_with("MOVL") {
            let v: f64 = line.split("V=").nth(1).unwrap().parse().unwrap();
            assert!((v - speed).abs() < 0.06, "{line}: layer speed {speed}");
            weld_moves += 1;
        }
    }
    assert!(weld_moves > 10, "{weld_moves} weld moves");
}

/// Without a robot, `waam plan --out` writes toolpath.yaml in the part frame (a cube part
/// through its blocks, a graph part sliced from an STL along its beads), and
/// `waam export --format gcode` takes it alone: one G1 at the weld feed per toolpath move
/// with the arc on, G0 with it off; the robot formats ask for the trajectory.
#[test]
fn plan_without_a_robot_is_g_code_in_the_part_frame() {
    for (part, extra) in [
        ("config/parts/s2-corner.yaml", &[][..]),
        ("tests/data/ring_binary.stl", &["--bead", "6 2.5"][..]),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path().to_str().unwrap();
        let mut args = vec!["plan", part];
        args.extend_from_slice(extra);
        args.extend_from_slice(&["--out", d, "-q"]);
        ok(&run_at_root(&args));
        assert!(!dir.path().join("trajectory.yaml").exists());
        let tp: ToolpathFile = serde_yaml::from_str(&read(dir.path(), "toolpath.yaml")).unwrap();
        assert_eq!(tp.frame, "part");
        let stdout = ok(&run_at_root(&["export", d, "--format", "gcode"]));
        assert!(stdout.contains("EXPORT: gcode"), "{stdout}");
        let gcode = read(dir.path(), "WAAM.gcode");
        // The toolpath's moves, in mm as written: (G word, X Y Z).
        let xyz = |p: [f64; 3]| {
            format!(
                "X{:.3} Y{:.3} Z{:.3}",
                p[0] * 1000.0,
                p[1] * 1000.0,
                p[2] * 1000.0
            )
            .replace("-0.000", "0.000")
        };
        let want: Vec<(&str, String)> = tp
            .poses
            .windows(2)
            .filter(|w| {
                let d: f64 = (0..3)
                    .map(|k| (w[1].position[k] - w[0].position[k]).powi(2))
                    .sum();
                d.sqrt() * 1000.0 >= 1e-3
            })
            .map(|w| (if w[0].arc_on { "G1" } else { "G0" }, xyz(w[1].position)))
            .collect();
        let got: Vec<(&str, String)> = gcode
            .lines()
            .skip_while(|l| !l.starts_with("G0 "))
            .skip(1)
            .filter(|l| l.starts_with("G0 ") || l.starts_with("G1 "))
            .map(|l| {
                let coords: Vec<&str> = l.split(' ').skip(1).take(3).collect();
                (&l[..2], coords.join(" "))
            })
            .collect();
        assert_eq!(got, want, "{part}");
        let welds = gcode.lines().filter(|l| l.starts_with("G1 ")).count();
        assert!(
            welds > 0
                && gcode
                    .lines()
                    .all(|l| !l.starts_with("G1 ") || l.contains(" F"))
        );
        let out = run_at_root(&["export", d, "--format", "rapid", "--robot", URDF]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{err}");
        assert!(err.contains("trajectory.yaml"), "{err}");
    }
}

/// A graph part sliced from an STL, planned with the robot: the motion runs along the
/// beads (toolpath and trajectory in the base link, the graph part beside the plan),
/// `waam motion` of the written part and plan makes the same trajectory, and a robot
/// program is exported from it.
#[test]
fn a_graph_part_planned_with_the_robot_is_moved_and_exported() {
    // The project's robot (the one built into the binary).
    const OUR_ROBOT: &str = "urdf/waam_robot.urdf";
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().to_str().unwrap();
    let stdout = ok(&run_at_root(&[
        "plan",
        "tests/data/ring_binary.stl",
        "--bead",
        "6 2.5",
        "-k",
        "2",
        "--robot",
        OUR_ROBOT,
        "--out",
        d,
    ]));
    assert!(stdout.contains("MOTION: "), "{stdout}");
    let tp: ToolpathFile = serde_yaml::from_str(&read(dir.path(), "toolpath.yaml")).unwrap();
    assert_eq!(tp.frame, "base_link");
    let traj = read(dir.path(), "trajectory.yaml");
    // The welded poses lie on the two rings' centre lines (radii about 21 and 27 mm about
    // the part's axis), not on stand-in blocks in a row.
    let plate = ProcessSettings::default().plate.isometry().inverse();
    for p in tp.poses.iter().filter(|p| p.arc_on) {
        let v = plate * nalgebra::Point3::from(p.position) * 1000.0;
        let r = v.x.hypot(v.y);
        assert!(
            (19.0..29.0).contains(&r),
            "a weld pose {r} mm from the axis"
        );
    }
    let again = tempfile::tempdir().unwrap();
    let part = dir.path().join("part.yaml");
    let plan = dir.path().join("plan.yaml");
    ok(&run_at_root(&[
        "motion",
        part.to_str().unwrap(),
        plan.to_str().unwrap(),
        "--robot",
        OUR_ROBOT,
        "--out",
        again.path().to_str().unwrap(),
    ]));
    assert_eq!(read(again.path(), "trajectory.yaml"), traj);
    let stdout = ok(&run_at_root(&[
        "export", d, "--format", "krl", "--robot", OUR_ROBOT,
    ]));
    assert!(stdout.contains("EXPORT: krl"), "{stdout}");
    let src = read(dir.path(), "WAAM_1.src");
    let arcs = src.matches("ARCON ").count();
    assert!(arcs >= 1 && src.matches("ARCOFF ").count() == arcs, "{src}");
}
