//! Yaskawa INFORM (DX/YRC job files, `.JBI`).
//!
//! The main job `<NAME>.JBI` calls the part jobs `<NAME>_1`, `<NAME>_2`, … in order. Each
//! part job holds at most `max_targets.inform` positions (`C00000`…, 999 by default: the
//! job's position variables are numbered with five digits, and long jobs load slowly on
//! the pendant). Positions are Cartesian (`///RECTAN`) in user frame `user_frame` (the
//! plate frame, to be taught or entered on the controller: the values are in the job's
//! comment) with tool `tool`: X, Y, Z in mm and Rx, Ry, Rz in degrees (fixed axes,
//! R = Rz·Ry·Rx), each preceded by its `///RCONF` (flip, lower arm, back, R ≥ 180°, T ≥ 180°,
//! S ≥ 180°, from the joint solution). `MOVJ` to the first position, `MOVL` with `V=`
//! (mm/s) from the timeline, `VR=` (deg/s) for a move that only turns the torch,
//! `ARCON ASF#(n)` / `ARCOF AEF#(n)` at the arc-on / arc-off positions (n: the weld
//! schedule of the pass's weld speed), `TIMER T=` for dwells.

use std::fmt::Write as _;

use crate::{mm, num, rpy_deg, Arc, CellSettings, ExportError, File, Format, Move, Program};

pub fn write(p: &Program, cell: &CellSettings) -> Result<Vec<File>, ExportError> {
    let chunks = p.chunks(Format::Inform, cell.max_targets.inform)?;
    let weld = p.weld_speeds();
    let name = p.name.to_uppercase();
    let header = |job: &str, npos: usize| {
        format!(
            "/JOB\n//NAME {job}\n//POS\n///NPOS {npos},0,0,0,0,0\n///TOOL {}\n///POSTYPE USER\n///USER {}\n///RECTAN\n",
            cell.tool, cell.user_frame
        )
    };
    let inst = "//INST\n///DATE 2026/01/01 00:00\n///ATTR SC,RW\n///GROUP1 RB1\nNOP\n";
    let mut files = Vec::new();

    let mut m = header(&name, 0);
    m.push_str(inst);
    let [x, y, z] = mm(&p.plate);
    let [rx, ry, rz] = rpy_deg(&p.plate.rotation);
    let _ = writeln!(
        m,
        "'waam-planner export: {} targets, {} weld pass(es), {} part job(s)",
        p.targets.len(),
        p.passes(),
        chunks.len()
    );
    let _ = writeln!(
        m,
        "'user frame {}: plate at X {} Y {} Z {} Rx {} Ry {} Rz {} in the robot base",
        cell.user_frame,
        num(x, 3),
        num(y, 3),
        num(z, 3),
        num(rx, 4),
        num(ry, 4),
        num(rz, 4)
    );
    for (i, v) in weld.iter().enumerate() {
        let _ = writeln!(
            m,
            "'ASF#({n})/AEF#({n}): weld speed {} mm/s, {} A, {} V, wire feed {} m/min",
            num(*v, 2),
            num(cell.current_a, 1),
            num(cell.voltage_v, 1),
            num(cell.wire_feed_m_min, 2),
            n = cell.schedule as usize + i
        );
    }
    for k in 0..chunks.len() {
        let _ = writeln!(m, "CALL JOB:{name}_{}", k + 1);
    }
    m.push_str("END\n");
    files.push(File {
        name: format!("{name}.JBI"),
        text: m,
    });

    for (k, range) in chunks.iter().enumerate() {
        let job = format!("{name}_{}", k + 1);
        let mut s = header(&job, range.len());
        let mut body = String::new();
        let mut rconf = String::new();
        for (c, i) in range.clone().enumerate() {
            let t = &p.targets[i];
            let conf = t.config.as_ref().expect("checked by export");
            let half =
                |j: usize| (conf.joints_deg.get(j).copied().unwrap_or(0.0).abs() >= 180.0) as u8;
            let rc = format!(
                "///RCONF {},{},{},{},{},{},0,0\n",
                conf.wrist_negative as u8,
                conf.elbow_down as u8,
                conf.behind as u8,
                half(3),
                half(5),
                half(0)
            );
            if rc != rconf {
                s.push_str(&rc);
                rconf = rc;
            }
            let [x, y, z] = mm(&t.part);
            let [rx, ry, rz] = rpy_deg(&t.part.rotation);
            let _ = writeln!(
                s,
                "C{c:05}={},{},{},{},{},{}",
                num(x, 3),
                num(y, 3),
                num(z, 3),
                num(rx, 4),
                num(ry, 4),
                num(rz, 4)
            );
            let line = match t.how {
                Move::First => format!("MOVJ C{c:05} VJ=25.00"),
                Move::Linear { speed_mm_s } => format!("MOVL C{c:05} V={}", num(speed_mm_s, 1)),
                Move::Turn { duration_s, deg } => {
                    format!("MOVL C{c:05} VR={}", num(deg / duration_s, 1))
                }
                Move::Wait { duration_s } => {
                    let _ = writeln!(body, "TIMER T={}", num(duration_s, 2));
                    format!("MOVL C{c:05} V=10.0")
                }
            };
            let _ = writeln!(body, "{line}");
            let n = cell.schedule as usize + p.pass_speed_index(&weld, i);
            match t.arc {
                Arc::On => {
                    let _ = writeln!(body, "ARCON ASF#({n})");
                }
                Arc::Off => {
                    let _ = writeln!(body, "ARCOF AEF#({n})");
                }
                Arc::Keep => {}
            }
        }
        s.push_str(inst);
        s.push_str(&body);
        s.push_str("END\n");
        files.push(File {
            name: format!("{job}.JBI"),
            text: s,
        });
    }
    Ok(files)
}
