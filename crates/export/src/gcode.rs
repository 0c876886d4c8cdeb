//! G-code for a gantry (`.gcode`): the TCP's path in the part frame, in mm.
//!
//! `G21 G90 G94`, then `G0` to the first pose and `G1 X Y Z F` (feed in mm/min from the
//! timeline) to every other pose; the arc-on command (`gcode_arc_on`, default `M3`) after
//! arriving at each arc-on pose, the arc-off command (`gcode_arc_off`, default `M5`) after
//! arriving at each arc-off pose; a wait is `G4 P<seconds>` (LinuxCNC convention) before
//! its zero-length move. A gantry holds the torch vertical: the torch's tilt is not
//! written, and a move that only turns the torch becomes a dwell of its time.
//!
//! From a toolpath alone ([`Program::rapid_travel`]: `waam plan --out` without a robot)
//! the moves with the arc off are `G0` (the toolpath's transit speed is a robot's, a gantry
//! travels at its own rapid), and a wait or turn is its `G4` alone: before the first weld
//! move no feed is set for a zero-length `G1`. With a robot trajectory every move stays
//! `G1` at the validated speed, so the arc strikes when the thermal check assumed.

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
            Move::Linear { .. } if p.rapid_travel && !t.arc_during => {
                let _ = writeln!(s, "G0 {xyz}");
            }
            Move::Linear { speed_mm_s } => {
                let _ = writeln!(s, "G1 {xyz} F{}", num(speed_mm_s * 60.0, 2));
            }
            Move::Turn { duration_s, .. } | Move::Wait { duration_s } if p.rapid_travel => {
                let _ = writeln!(s, "G4 P{}", num(duration_s, 3));
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

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Isometry3;
    use std::f64::consts::TAU;
    use waam_motion::toolpath::{toolpath_of_graph_plan, ProcessSettings, ToolpathFrame};
    use waam_part::{Bead, BeadPart, Deposit, ThermalParams};

    const R: f64 = 33.0;

    /// Rings of radius R on `layers` layers (W 6, H 2.5), 35 nodes each.
    fn rings(layers: u32) -> BeadPart {
        let points: Vec<[f64; 2]> = (0..128)
            .map(|i| {
                let a = TAU * i as f64 / 128.0;
                [R * a.cos(), R * a.sin()]
            })
            .collect();
        let mut beads = Vec::new();
        let mut nodes = Vec::new();
        for layer in 0..layers {
            let bead = Bead {
                layer,
                closed: true,
                points: points.clone(),
            };
            let len = bead.length_mm();
            for i in 0..35 {
                let (from_mm, to_mm) = (len * i as f64 / 35.0, len * (i + 1) as f64 / 35.0);
                let a = TAU * (i as f64 + 0.5) / 35.0;
                nodes.push(Deposit {
                    bead: layer as usize,
                    from_mm,
                    to_mm,
                    layer,
                    centre_mm: [R * a.cos(), R * a.sin(), 2.5 * (layer as f64 + 0.5)],
                    volume_mm3: 6.0 * 2.5 * (to_mm - from_mm),
                    surface_mm2: 1.0,
                    substrate_mm2: 0.0,
                });
            }
            beads.push(bead);
        }
        BeadPart {
            name: "ring".into(),
            max_fragments: 2,
            bead_mm: [6.0, 2.5],
            base_z_mm: 0.0,
            beads,
            nodes,
            contacts: Vec::new(),
            windows: Vec::new(),
            thermal: ThermalParams::default(),
            warnings: Vec::new(),
        }
    }

    fn gcode(part: &BeadPart, fragments: &[Vec<usize>]) -> String {
        let s = ProcessSettings::default();
        let tp = toolpath_of_graph_plan(part, fragments, &s, ToolpathFrame::Part).unwrap();
        let p = Program::from_toolpath("RING", &tp.to_file(), Isometry3::identity()).unwrap();
        write(&p, &CellSettings::default()).text
    }

    /// (G word, [x, y, z], feed) of every move, with the arc's state during it.
    fn moves(text: &str) -> Vec<(String, [f64; 3], Option<f64>, bool)> {
        let mut arc = false;
        let mut out = Vec::new();
        for line in text.lines() {
            match line {
                "M3" => arc = true,
                "M5" => arc = false,
                _ if line.starts_with("G0 ") || line.starts_with("G1 ") => {
                    let word = |c: char| {
                        line.split(' ')
                            .find_map(|w| w.strip_prefix(c))
                            .map(|v| v.parse::<f64>().unwrap())
                    };
                    let xyz = [word('X').unwrap(), word('Y').unwrap(), word('Z').unwrap()];
                    out.push((line[..2].to_string(), xyz, word('F'), arc));
                }
                _ => {}
            }
        }
        out
    }

    #[test]
    fn a_ring_toolpath_alone_is_g_code_on_its_circle() {
        let part = rings(1);
        let text = gcode(&part, &[(0..35).collect()]);
        assert_eq!(text.lines().filter(|l| *l == "M3").count(), 1);
        assert_eq!(text.lines().filter(|l| *l == "M5").count(), 1);
        let all = moves(&text);
        let welds: Vec<_> = all.iter().filter(|m| m.3).collect();
        assert!(welds.len() > 128, "{} weld moves", welds.len());
        let feed = 6.0 / ThermalParams::default().block_time_s * 60.0;
        for (g, [x, y, z], f, _) in &welds {
            assert_eq!(g, "G1");
            assert!((x.hypot(*y) - R).abs() < 0.1, "X{x} Y{y}");
            assert!((z - 2.5).abs() < 1e-9);
            // The weld feed: W per block time (the chords are a little shorter).
            let f = f.expect("a weld move has its feed");
            assert!((f - feed).abs() < 0.01 * feed, "F{f}, {feed}");
        }
        // Everything with the arc off is a rapid.
        assert!(all.iter().filter(|m| !m.3).all(|m| m.0 == "G0"));
        assert!(all.iter().filter(|m| !m.3).count() >= 4);
        // The dwells are G4 alone.
        assert!(
            text.contains("G4 P0.300") && text.contains("G4 P0.500"),
            "{text}"
        );
    }

    #[test]
    fn between_two_passes_the_torch_travels_in_rapids_with_the_arc_off() {
        let part = rings(2);
        let text = gcode(&part, &[(0..35).collect(), (35..70).collect()]);
        let all = moves(&text);
        let lines: Vec<&str> = text.lines().collect();
        let off = lines.iter().position(|l| *l == "M5").unwrap();
        let on = lines.iter().rposition(|l| *l == "M3").unwrap();
        assert!(off < on);
        let between = &lines[off + 1..on];
        assert!(between
            .iter()
            .all(|l| l.starts_with("G0 ") || l.starts_with("G4 ")));
        assert!(between.len() >= 3, "{between:?}");
        // The second pass welds layer 1, on its circle.
        let top: Vec<_> = all
            .iter()
            .filter(|m| m.3 && (m.1[2] - 5.0).abs() < 1e-9)
            .collect();
        assert!(top.len() > 128);
        assert!(top.iter().all(|m| (m.1[0].hypot(m.1[1]) - R).abs() < 0.1));
    }
}
