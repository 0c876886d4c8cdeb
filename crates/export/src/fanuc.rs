//! Fanuc TP programs in ASCII (`.ls`, Arc Tool).
//!
//! The main program `<NAME>.ls` calls the part programs `<NAME>_1`, … in order; each holds
//! at most `max_targets.fanuc` positions `P[n]` in user frame `user_frame` (the plate frame)
//! with tool `tool`: X, Y, Z in mm, W, P, R in degrees (fixed axes, R = Rz·Ry·Rx) and the
//! configuration string `'F/N U/D T/B, t1, t4, t6'` (wrist flipped, elbow up/down, front/
//! back; the turn numbers of joints 1, 4, 6) from the joint solution. `J P[1] 100% FINE`
//! to the first position, `L P[n] v mm/sec` with the timeline's speed (Fanuc takes whole
//! mm/sec: the nearest, at least 1), `deg/sec` for a move that only turns the torch;
//! `Arc Start[n]` on the move to each arc-on position, `Arc End[n]` on the move to each
//! arc-off position (n: the weld schedule of the pass's weld speed), weld moves at
//! `WELD_SPEED` (the schedule's travel speed — set it to the value in the program's
//! comment; a weld move at another speed switches the schedule with `Arc Start[m]` before
//! it), `WAIT x(sec)` for dwells.

use std::fmt::Write as _;

use crate::{
    mm, num, rpy_deg, Arc, ArmConfig, CellSettings, ExportError, File, Format, Move, Program,
};

pub fn write(p: &Program, cell: &CellSettings) -> Result<Vec<File>, ExportError> {
    let chunks = p.chunks(Format::Fanuc, cell.max_targets.fanuc)?;
    let weld = p.weld_speeds();
    let name = p.name.to_uppercase();
    let mut files = Vec::new();

    let mut lines = vec![format!(
        "! waam-planner: {} targets, {} passes ;",
        p.targets.len(),
        p.passes()
    )];
    for (i, v) in weld.iter().enumerate() {
        lines.push(format!(
            "! Weld Schedule {}: {} mm/s ;",
            cell.schedule as usize + i,
            num(*v, 2)
        ));
        lines.push(format!(
            "! {} A, {} V, {} m/min ;",
            num(cell.current_a, 1),
            num(cell.voltage_v, 1),
            num(cell.wire_feed_m_min, 2)
        ));
    }
    for k in 0..chunks.len() {
        lines.push(format!("CALL {name}_{} ;", k + 1));
    }
    files.push(File {
        name: format!("{name}.ls"),
        text: program(&name, &lines, "", cell),
    });

    for (k, range) in chunks.iter().enumerate() {
        let prog = format!("{name}_{}", k + 1);
        let mut mn = vec![
            format!("UFRAME_NUM={} ;", cell.user_frame),
            format!("UTOOL_NUM={} ;", cell.tool),
        ];
        let mut pos = String::new();
        let mut current = 0;
        for (c, i) in range.clone().enumerate() {
            let t = &p.targets[i];
            let n = c + 1;
            let conf = t.config.as_ref().expect("checked by export");
            let sched = cell.schedule as usize + p.pass_speed_index(&weld, i);
            let term = {
                let next_waits = p
                    .targets
                    .get(i + 1)
                    .is_some_and(|n| matches!(n.how, Move::Wait { .. }));
                if next_waits || t.arc != Arc::Keep || i + 1 == p.targets.len() {
                    "FINE"
                } else {
                    "CNT100"
                }
            };
            let arc = match t.arc {
                Arc::On => {
                    current = sched;
                    format!(" Arc Start[{sched}]")
                }
                Arc::Off => format!(" Arc End[{sched}]"),
                Arc::Keep => String::new(),
            };
            let line = match t.how {
                Move::First => format!("J P[{n}] 100% {term}{arc} ;"),
                Move::Linear { speed_mm_s } if t.arc_during => {
                    // A weld schedule per weld speed: switch (Arc Start) before a move at
                    // another speed than the schedule in use.
                    let want = cell.schedule as usize + p.weld_speed_index(&weld, speed_mm_s);
                    if want != current {
                        mn.push(format!("Arc Start[{want}] ;"));
                        current = want;
                    }
                    format!("L P[{n}] WELD_SPEED {term}{arc} ;")
                }
                Move::Linear { speed_mm_s } => format!(
                    "L P[{n}] {}mm/sec {term}{arc} ;",
                    speed_mm_s.round().max(1.0)
                ),
                Move::Turn { duration_s, deg } => format!(
                    "L P[{n}] {}deg/sec {term}{arc} ;",
                    (deg / duration_s).round().max(1.0)
                ),
                Move::Wait { duration_s } => {
                    mn.push(format!("WAIT {}(sec) ;", num(duration_s, 2)));
                    let speed = if t.arc_during {
                        "WELD_SPEED".to_string()
                    } else {
                        "10mm/sec".to_string()
                    };
                    format!("L P[{n}] {speed} {term}{arc} ;")
                }
            };
            mn.push(line);
            let [x, y, z] = mm(&t.part);
            let [w, pp, r] = rpy_deg(&t.part.rotation);
            let _ = write!(
                pos,
                "P[{n}]{{\n   GP1:\n\tUF : {}, UT : {},\t\tCONFIG : '{}',\n\tX = {} mm,\tY = {} mm,\tZ = {} mm,\n\tW = {} deg,\tP = {} deg,\tR = {} deg\n}};\n",
                cell.user_frame,
                cell.tool,
                config_string(conf),
                num(x, 3),
                num(y, 3),
                num(z, 3),
                num(w, 3),
                num(pp, 3),
                num(r, 3)
            );
        }
        files.push(File {
            name: format!("{prog}.ls"),
            text: program(&prog, &mn, &pos, cell),
        });
    }
    Ok(files)
}

/// `'F U T, t1, t4, t6'`: flip (N: no flip), elbow up (D: down), front (B: back), and the
/// turn numbers of joints 1, 4 and 6.
pub fn config_string(c: &ArmConfig) -> String {
    let turn = |j: usize| ArmConfig::turn(c.joints_deg.get(j).copied().unwrap_or(0.0));
    format!(
        "{} {} {}, {}, {}, {}",
        if c.wrist_negative { 'F' } else { 'N' },
        if c.elbow_down { 'D' } else { 'U' },
        if c.behind { 'B' } else { 'T' },
        turn(0),
        turn(3),
        turn(5)
    )
}

fn program(name: &str, mn: &[String], pos: &str, cell: &CellSettings) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "/PROG  {name}");
    s.push_str("/ATTR\nOWNER\t\t= MNEDITOR;\nCOMMENT\t\t= \"waam-planner\";\nPROG_SIZE\t= 0;\n");
    s.push_str(
        "CREATE\t\t= DATE 26-01-01  TIME 00:00:00;\nMODIFIED\t= DATE 26-01-01  TIME 00:00:00;\n",
    );
    s.push_str("FILE_NAME\t= ;\nVERSION\t\t= 0;\n");
    let _ = writeln!(s, "LINE_COUNT\t= {};", mn.len());
    s.push_str("MEMORY_SIZE\t= 0;\nPROTECT\t\t= READ_WRITE;\n");
    s.push_str("TCD:  STACK_SIZE\t= 0,\n      TASK_PRIORITY\t= 50,\n      TIME_SLICE\t= 0,\n      BUSY_LAMP_OFF\t= 0,\n      ABORT_REQUEST\t= 0,\n      PAUSE_REQUEST\t= 0;\n");
    s.push_str("DEFAULT_GROUP\t= 1,*,*,*,*;\nCONTROL_CODE\t= 00000000 00000000;\n");
    let _ = writeln!(
        s,
        "/APPL\n  ARC Welding Equipment : {},*,*,*,*;",
        cell.tool.max(1)
    );
    s.push_str("/MN\n");
    for (i, line) in mn.iter().enumerate() {
        let (lead, text) = match line.strip_prefix("J ").or(line.strip_prefix("L ")) {
            Some(_) => ("", line.as_str()),
            None => ("  ", line.as_str()),
        };
        let _ = writeln!(s, "{:>4}:{lead}{text}", i + 1);
    }
    s.push_str("/POS\n");
    s.push_str(pos);
    s.push_str("/END\n");
    s
}
