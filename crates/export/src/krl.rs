//! KUKA KRL (KSS 8.x) with ArcTech.
//!
//! `<NAME>.src`/`.dat` is the main program: it sets the tool and base (the TCP in the
//! flange, the plate frame in the robot's base frame, stored in TOOL_DATA / BASE_DATA of
//! the cell settings' numbers) and calls the part programs `<NAME>_1`, `<NAME>_2`, … (each
//! a `.src` with its `.dat`, at most `max_targets.krl` targets). A part program holds its
//! targets as `E6POS` in its `.dat` (X, Y, Z in mm in the base; A, B, C the Z-Y'-X''
//! angles; S and T from the joint solution, see [`crate::ArmConfig::kuka_status`] and
//! [`crate::ArmConfig::kuka_turn`]) and moves `PTP` to the first target, `LIN` with
//! `$VEL.CP` from the timeline elsewhere.
//!
//! The arc follows the ArcTech 3.x inline forms (KSS 8.3 and later): an `ARCON` fold on
//! the move to each arc-on pose, `ARCSWI` folds on the weld moves, an `ARCOFF` fold on the
//! move to each arc-off pose, each naming its weld data set `WDAT<n>` (the weld schedule
//! number, one per weld speed). Inside each fold is the plain move; the weld parameters of
//! the data set (speed, schedule, wire feed, voltage, current) are listed in the `.dat`
//! for setting up the ArcTech data set on the controller. Dwells are `WAIT SEC`.

use std::fmt::Write as _;

use crate::{mm, num, rpy_deg, Arc, CellSettings, ExportError, File, Format, Move, Program};

pub fn write(p: &Program, cell: &CellSettings) -> Result<Vec<File>, ExportError> {
    let chunks = p.chunks(Format::Krl, cell.max_targets.krl)?;
    let weld = p.weld_speeds();
    let name = p.name.to_uppercase();
    let mut files = Vec::new();

    let frame = |iso: &nalgebra::Isometry3<f64>| {
        let [x, y, z] = mm(iso);
        let [roll, pitch, yaw] = rpy_deg(&iso.rotation);
        format!(
            "{{X {},Y {},Z {},A {},B {},C {}}}",
            num(x, 3),
            num(y, 3),
            num(z, 3),
            num(yaw, 6),
            num(pitch, 6),
            num(roll, 6)
        )
    };

    let mut src = String::new();
    let _ = writeln!(src, "&ACCESS RVP\n&REL 1\nDEF {name}( )");
    let _ = writeln!(
        src,
        ";waam-planner export: {} targets, {} weld pass(es), {} part program(s)",
        p.targets.len(),
        p.passes(),
        chunks.len()
    );
    let _ = writeln!(src, ";FOLD INI\n  BAS (#INITMOV,0 )\n;ENDFOLD");
    let _ = writeln!(src, "TOOL_DATA[{}] = WAAM_TOOL", cell.tool);
    let _ = writeln!(src, "BASE_DATA[{}] = WAAM_BASE", cell.user_frame);
    let _ = writeln!(src, "$TOOL = TOOL_DATA[{}]", cell.tool);
    let _ = writeln!(src, "$BASE = BASE_DATA[{}]", cell.user_frame);
    let _ = writeln!(src, "$APO.CDIS = 1.0");
    for k in 0..chunks.len() {
        let _ = writeln!(src, "{name}_{}( )", k + 1);
    }
    src.push_str("END\n");
    let mut dat = String::new();
    let _ = writeln!(dat, "&ACCESS RVP\n&REL 1\nDEFDAT {name} PUBLIC");
    let _ = writeln!(dat, ";the TCP in the flange (mm, deg), tool {}", cell.tool);
    let _ = writeln!(dat, "DECL GLOBAL FRAME WAAM_TOOL={}", frame(&p.tcp));
    let _ = writeln!(
        dat,
        ";the plate frame in the robot's base frame {:?} (mm, deg), base {}",
        p.frame, cell.user_frame
    );
    let _ = writeln!(dat, "DECL GLOBAL FRAME WAAM_BASE={}", frame(&p.plate));
    for (i, v) in weld.iter().enumerate() {
        let _ = writeln!(
            dat,
            ";WDAT{}: weld speed {} mm/s, schedule {}, wire feed {} m/min, {} V, {} A",
            cell.schedule as usize + i,
            num(*v, 2),
            cell.schedule as usize + i,
            num(cell.wire_feed_m_min, 2),
            num(cell.voltage_v, 1),
            num(cell.current_a, 1)
        );
    }
    dat.push_str("ENDDAT\n");
    files.push(File {
        name: format!("{name}.src"),
        text: src,
    });
    files.push(File {
        name: format!("{name}.dat"),
        text: dat,
    });

    for (k, range) in chunks.iter().enumerate() {
        let module = format!("{name}_{}", k + 1);
        let mut src = String::new();
        let mut dat = String::new();
        let _ = writeln!(src, "&ACCESS RVP\n&REL 1\nGLOBAL DEF {module}( )");
        let _ = writeln!(dat, "&ACCESS RVP\n&REL 1\nDEFDAT {module} PUBLIC");
        let mut vel = f64::NAN;
        for i in range.clone() {
            let t = &p.targets[i];
            let [x, y, z] = mm(&t.part);
            let [roll, pitch, yaw] = rpy_deg(&t.part.rotation);
            let c = t.config.as_ref().expect("checked by export");
            let axes: Vec<String> = c.joints_deg.iter().map(|q| num(*q, 4)).collect();
            let _ = writeln!(
                dat,
                "DECL E6POS XP{}={{X {},Y {},Z {},A {},B {},C {},S {},T {},E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}} ;axes {}",
                i + 1,
                num(x, 3),
                num(y, 3),
                num(z, 3),
                num(yaw, 6),
                num(pitch, 6),
                num(roll, 6),
                c.kuka_status(),
                c.kuka_turn(),
                axes.join(" ")
            );
            match t.how {
                Move::Wait { duration_s } => {
                    let _ = writeln!(src, "WAIT SEC {}", num(duration_s, 3));
                }
                Move::Linear { speed_mm_s } => {
                    let v = (speed_mm_s * 100.0).round() / 100.0;
                    if v != vel {
                        let _ = writeln!(src, "$VEL.CP = {}", num(v / 1000.0, 5));
                        vel = v;
                    }
                }
                Move::Turn { duration_s, deg } => {
                    let _ = writeln!(src, "$VEL.ORI1 = {}", num(deg / duration_s, 3));
                    let _ = writeln!(src, "$VEL.ORI2 = {}", num(deg / duration_s, 3));
                }
                Move::First => {}
            }
            let next_waits = p
                .targets
                .get(i + 1)
                .is_some_and(|n| matches!(n.how, Move::Wait { .. }));
            let approx = if next_waits || t.arc != Arc::Keep || i + 1 == p.targets.len() {
                ""
            } else {
                " C_DIS"
            };
            let motion = match t.how {
                Move::First => format!("PTP XP{}", i + 1),
                _ => format!("LIN XP{}{approx}", i + 1),
            };
            let wdat = cell.schedule as usize
                + match (t.how, t.arc_during) {
                    (Move::Linear { speed_mm_s }, true) => p.weld_speed_index(&weld, speed_mm_s),
                    _ => p.pass_speed_index(&weld, i),
                };
            let form = match (t.arc, t.arc_during) {
                (Arc::On, _) => Some("ARCON"),
                (Arc::Off, _) => Some("ARCOFF"),
                (Arc::Keep, true) => Some("ARCSWI"),
                (Arc::Keep, false) => None,
            };
            match form {
                Some(form) => {
                    let _ = writeln!(
                        src,
                        ";FOLD {form} WDAT{wdat} LIN P{} CPDAT1 Tool[{}]:WAAM_TOOL Base[{}]:WAAM_BASE ;%{{PE}}",
                        i + 1,
                        cell.tool,
                        cell.user_frame
                    );
                    let _ = writeln!(src, "{motion}");
                    src.push_str(";ENDFOLD\n");
                }
                None => {
                    let _ = writeln!(src, "{motion}");
                }
            }
        }
        src.push_str("END\n");
        dat.push_str("ENDDAT\n");
        files.push(File {
            name: format!("{module}.src"),
            text: src,
        });
        files.push(File {
            name: format!("{module}.dat"),
            text: dat,
        });
    }
    Ok(files)
}
