//! G-code for a gantry (`.gcode`): the TCP's path in the part frame, in mm.
//!
//! `G21 G90 G94`, then `G0` to the first pose and `G1 X Y Z F` (feed in mm/min from the
//! timeline) to every other pose; the arc-on command (`gcode_arc_on`, default `M3`) after
//! arriving at each arc-on pose, the arc-off command (`gcode_arc_off`, default `M5`) after
//! arriving at each arc-off pose; a wait is `G4 P<seconds>` (LinuxCNC convention) before
//! its zero-length move. A gantry holds the torch vertical: the torch's tilt is not
//! written, and a move that only turns the torch becomes a dwell of its time.

use std::fmt::Write as _;

use crate::{mm, num, Arc, CellSettings, File, Move, Program};

pub fn write(p: &Program, cell: &CellSettings) -> File {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "; waam-planner export: {} targets, {} weld pass(es), part frame, mm",
        p.targets.len(),
        p.passes()
    );
    s.push_str("G21 G90 G94\n");
    for t in &p.targets {
        let [x, y, z] = mm(&t.part);
        let xyz = format!("X{} Y{} Z{}", num(x, 3), num(y, 3), num(z, 3));
        match t.how {
            Move::First => {
                let _ = writeln!(s, "G0 {xyz}");
            }
            Move::Linear { speed_mm_s } => {
                let _ = writeln!(s, "G1 {xyz} F{}", num(speed_mm_s * 60.0, 2));
            }
            Move::Turn { duration_s, .. } | Move::Wait { duration_s } => {
                let _ = writeln!(s, "G4 P{}", num(duration_s, 3));
                let _ = writeln!(s, "G1 {xyz}");
            }
        }
        match t.arc {
            Arc::On => {
                let _ = writeln!(s, "{}", cell.gcode_arc_on.trim());
            }
            Arc::Off => {
                let _ = writeln!(s, "{}", cell.gcode_arc_off.trim());
            }
            Arc::Keep => {}
        }
    }
    s.push_str("M2\n");
    File {
        name: format!("{}.gcode", p.name),
        text: s,
    }
}
