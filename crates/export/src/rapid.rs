//! ABB RAPID (RobotWare 6 with RobotWare Arc).
//!
//! A main module `<NAME>.mod` holds the data — `tooldata` (the TCP in the flange), `wobjdata`
//! (the plate frame in the robot's base frame, user frame programmed), `seamdata` and one
//! `welddata` per weld speed (schedule, voltage, wire feed, current from the cell
//! settings), one `speeddata` per travel speed — and `PROC main()`, which calls the part
//! modules `<NAME>_1.mod`, `<NAME>_2.mod`, … in order. Each part module holds at most
//! `max_targets.rapid` `robtarget`s, cut between passes where possible and else inside a
//! weld, which the next module's `ArcL`s continue (in the work object; `confdata` from the joint
//! solution, see [`crate::ArmConfig::abb_confdata`]) and one procedure: `MoveJ` to the
//! first target, `MoveL` transits, `ArcLStart` to each arc-on pose (fine), `ArcL` along
//! the weld, `ArcLEnd` at each arc-off pose (fine), `WaitTime \InPos` where the timeline
//! waits (after a fine point), `\T` on a move that only turns the torch.

use std::fmt::Write as _;

use crate::{mm, num, Arc, CellSettings, ExportError, File, Format, Move, Program};

/// Writes the main module and the part modules.
pub fn write(p: &Program, cell: &CellSettings) -> Result<Vec<File>, ExportError> {
    let chunks = p.chunks(Format::Rapid, cell.max_targets.rapid)?;
    let weld = p.weld_speeds();
    let travel = travel_speeds(p);
    let tool = "tWaamTorch";
    let wobj = "wobjWaamPlate";
    let mut files = Vec::new();

    let mut m = String::new();
    let _ = writeln!(m, "MODULE {}", p.name);
    let _ = writeln!(
        m,
        "  ! waam-planner export: {} targets, {} weld pass(es), {} part module(s).",
        p.targets.len(),
        p.passes(),
        chunks.len()
    );
    let _ = writeln!(
        m,
        "  ! Targets are in {wobj} (the plate frame in the base frame {:?}).",
        p.frame
    );
    let [tx, ty, tz] = mm(&p.tcp);
    let q = p.tcp.rotation.coords;
    let _ = writeln!(
        m,
        "  PERS tooldata {tool} := [TRUE, [[{}, {}, {}], [{}, {}, {}, {}]], [{}, [0, 0, {}], [1, 0, 0, 0], 0, 0, 0]];",
        num(tx, 3),
        num(ty, 3),
        num(tz, 3),
        num(q.w, 9),
        num(q.x, 9),
        num(q.y, 9),
        num(q.z, 9),
        num(cell.tool_mass_kg.max(0.001), 3),
        num(tz / 2.0, 1)
    );
    let [ux, uy, uz] = mm(&p.plate);
    let u = p.plate.rotation.coords;
    let _ = writeln!(
        m,
        "  PERS wobjdata {wobj} := [FALSE, TRUE, \"\", [[{}, {}, {}], [{}, {}, {}, {}]], [[0, 0, 0], [1, 0, 0, 0]]];",
        num(ux, 3),
        num(uy, 3),
        num(uz, 3),
        num(u.w, 9),
        num(u.x, 9),
        num(u.y, 9),
        num(u.z, 9)
    );
    // seamdata (RobotWare 6 Arc, standard components): purge_time, preflow_time, ign_arc,
    // ign_move_delay, scrape_start, heat_arc, heat_time, cool_time, fill_time, bback_time,
    // rback_time, fill_arc, postflow_time. The dwells are in the program (WaitTime), not here.
    let arc = arcdata(cell, cell.schedule);
    let _ = writeln!(
        m,
        "  PERS seamdata smWaam := [0, {}, {arc}, 0, 0, {arc}, 0, 0, 0, 0, 0, {arc}, {}];",
        num(cell.preflow_s, 2),
        num(cell.postflow_s, 2)
    );
    // welddata: weld_speed (mm/s), org_weld_speed, main_arc, org_arc.
    for (i, v) in weld.iter().enumerate() {
        let arc = arcdata(cell, cell.schedule + i as u32);
        let _ = writeln!(
            m,
            "  PERS welddata wdWaam{} := [{}, 0, {arc}, {arc}];",
            i + 1,
            num(*v, 2)
        );
    }
    for (i, v) in weld.iter().enumerate() {
        let _ = writeln!(
            m,
            "  CONST speeddata vWeld{} := [{}, 500, 5000, 1000];",
            i + 1,
            num(*v, 2)
        );
    }
    for (i, v) in travel.iter().enumerate() {
        let _ = writeln!(
            m,
            "  CONST speeddata vTravel{} := [{}, 500, 5000, 1000];",
            i + 1,
            num(*v, 2)
        );
    }
    m.push('\n');
    m.push_str("  PROC main()\n");
    for k in 0..chunks.len() {
        let _ = writeln!(m, "    {}_{};", p.name, k + 1);
    }
    m.push_str("  ENDPROC\nENDMODULE\n");
    files.push(File {
        name: format!("{}.mod", p.name),
        text: m,
    });

    for (k, range) in chunks.iter().enumerate() {
        let module = format!("{}_{}", p.name, k + 1);
        let mut s = String::new();
        let _ = writeln!(s, "MODULE {module}");
        for i in range.clone() {
            let t = &p.targets[i];
            let [x, y, z] = mm(&t.part);
            let q = t.part.rotation.coords;
            let c = t.config.as_ref().expect("checked by export").abb_confdata();
            let _ = writeln!(
                s,
                "  CONST robtarget pW{} := [[{}, {}, {}], [{}, {}, {}, {}], [{}, {}, {}, {}], [9E+09, 9E+09, 9E+09, 9E+09, 9E+09, 9E+09]];",
                i + 1,
                num(x, 3),
                num(y, 3),
                num(z, 3),
                num(q.w, 9),
                num(q.x, 9),
                num(q.y, 9),
                num(q.z, 9),
                c[0],
                c[1],
                c[2],
                c[3]
            );
        }
        s.push('\n');
        let _ = writeln!(s, "  PROC {module}()");
        for i in range.clone() {
            let t = &p.targets[i];
            if let Move::Wait { duration_s } = t.how {
                let _ = writeln!(s, "    WaitTime \\InPos, {};", num(duration_s, 3));
            }
            // A target before a wait or an arc event is a stop point.
            let next_waits = p
                .targets
                .get(i + 1)
                .is_some_and(|n| matches!(n.how, Move::Wait { .. }));
            let zone = if next_waits || t.arc != Arc::Keep || i + 1 == p.targets.len() {
                "fine"
            } else {
                "z1"
            };
            let target = format!("pW{}", i + 1);
            let (speed, time) = match t.how {
                Move::Linear { speed_mm_s } if t.arc_during => (
                    format!("vWeld{}", p.weld_speed_index(&weld, speed_mm_s) + 1),
                    String::new(),
                ),
                Move::Linear { speed_mm_s } => (
                    format!("vTravel{}", travel_index(&travel, speed_mm_s) + 1),
                    String::new(),
                ),
                Move::Turn { duration_s, .. } => {
                    ("v100".to_string(), format!(" \\T:={}", num(duration_s, 3)))
                }
                Move::First | Move::Wait { .. } => ("v100".to_string(), String::new()),
            };
            // A weld move takes the weld data of its own speed; the others the pass's.
            let wd = match (t.how, t.arc_during) {
                (Move::Linear { speed_mm_s }, true) => p.weld_speed_index(&weld, speed_mm_s),
                _ => p.pass_speed_index(&weld, i),
            };
            let wd = format!("wdWaam{}", wd + 1);
            let line = match (t.how, t.arc, t.arc_during) {
                (Move::First, _, _) => {
                    format!("MoveJ {target}, {speed}, {zone}, {tool} \\WObj:={wobj};")
                }
                (_, Arc::On, _) => format!(
                    "ArcLStart {target}, {speed}{time}, smWaam, {wd}, fine, {tool} \\WObj:={wobj};"
                ),
                (_, Arc::Off, _) => format!(
                    "ArcLEnd {target}, {speed}{time}, smWaam, {wd}, fine, {tool} \\WObj:={wobj};"
                ),
                (_, Arc::Keep, true) => format!(
                    "ArcL {target}, {speed}{time}, smWaam, {wd}, {zone}, {tool} \\WObj:={wobj};"
                ),
                (_, Arc::Keep, false) => {
                    format!("MoveL {target}, {speed}{time}, {zone}, {tool} \\WObj:={wobj};")
                }
            };
            let _ = writeln!(s, "    {line}");
        }
        s.push_str("  ENDPROC\nENDMODULE\n");
        files.push(File {
            name: format!("{module}.mod"),
            text: s,
        });
    }
    Ok(files)
}

/// arcdata (RobotWare 6 Arc, standard components): sched, mode, voltage, wirefeed
/// (m/min), control, current, voltage2, wirefeed2, control2.
fn arcdata(cell: &CellSettings, sched: u32) -> String {
    format!(
        "[{sched}, 0, {}, {}, 0, {}, 0, 0, 0]",
        num(cell.voltage_v, 1),
        num(cell.wire_feed_m_min, 2),
        num(cell.current_a, 1)
    )
}

/// The distinct travel speeds (arc off), mm/s rounded to 0.01, in order of first use.
fn travel_speeds(p: &Program) -> Vec<f64> {
    let mut out: Vec<f64> = Vec::new();
    for t in &p.targets {
        if let (false, Move::Linear { speed_mm_s }) = (t.arc_during, t.how) {
            let v = (speed_mm_s * 100.0).round() / 100.0;
            if !out.iter().any(|s| (s - v).abs() < 1e-9) {
                out.push(v);
            }
        }
    }
    out
}

fn travel_index(speeds: &[f64], v: f64) -> usize {
    let v = (v * 100.0).round() / 100.0;
    speeds
        .iter()
        .position(|s| (s - v).abs() < 1e-9)
        .unwrap_or(0)
}
