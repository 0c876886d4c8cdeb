//! Writing a [`Part`] as a part file in the shared format (`shared/spec/part-format.md`),
//! so that what `waam voxelize` writes, `waam check` and the planner read back unchanged.

use std::collections::HashMap;
use std::fmt::Write as _;

use crate::ThermalParams;
use crate::{Block, Part, Window};

/// The part as YAML: the `layers` form when the part fills its bounding box reasonably,
/// the `blocks` form when it is sparse (a few far-apart blocks); windows as boxes where a
/// box holds exactly the blocks sharing a window, else block by block; thermal constants
/// that differ from the defaults.
pub fn to_yaml(part: &Part) -> String {
    let mut out = String::new();
    let quoted = serde_json::to_string(&part.name).expect("a string serializes");
    let _ = writeln!(out, "name: {quoted}");
    let _ = writeln!(out, "block_mm: {}", triple(part.block_mm));
    if part.origin_mm != [0.0; 3] {
        let _ = writeln!(out, "origin_mm: {}", triple(part.origin_mm));
    }
    let _ = writeln!(out, "max_fragments: {}", part.max_fragments);
    write_blocks(&mut out, part);
    write_windows(&mut out, part);
    write_thermal(&mut out, &part.thermal);
    out
}

/// A real number that reads back bit for bit (`6.0`, `2.5`, `1e-7`).
pub(crate) fn real(x: f64) -> String {
    format!("{x:?}")
}

fn triple(v: [f64; 3]) -> String {
    format!("[{}, {}, {}]", real(v[0]), real(v[1]), real(v[2]))
}

fn block(b: Block) -> String {
    format!("[{}, {}, {}]", b[0], b[1], b[2])
}

fn write_blocks(out: &mut String, part: &Part) {
    let max = |d: usize| part.blocks().iter().map(|b| b[d]).max().unwrap_or(0);
    let (w, h, layers) = (max(0) as u128 + 1, max(1) as u128 + 1, max(2) as u128 + 1);
    if w * h * layers > 8 * part.len() as u128 + 4096 {
        out.push_str("blocks:\n");
        for chunk in part.blocks().chunks(8) {
            let items: Vec<String> = chunk.iter().map(|&b| block(b)).collect();
            let _ = writeln!(out, "  - {}", items.join("\n  - "));
        }
        return;
    }
    out.push_str("layers:\n");
    let (w, h) = (w as usize, h as usize);
    let mut grid = vec![b'.'; w * h];
    let mut rest = part.blocks();
    for z in 0..layers as i64 {
        // Blocks are sorted by (z, y, x): this layer's are a prefix of the rest.
        let n = rest.iter().take_while(|b| b[2] == z).count();
        grid.fill(b'.');
        for b in &rest[..n] {
            grid[b[1] as usize * w + b[0] as usize] = b'#';
        }
        rest = &rest[n..];
        let _ = writeln!(out, "  - |  # z = {z}");
        for row in grid.chunks(w) {
            let _ = writeln!(out, "    {}", std::str::from_utf8(row).expect("ASCII"));
        }
    }
}

fn write_windows(out: &mut String, part: &Part) {
    if part.windows().is_empty() {
        return;
    }
    out.push_str("t85:\n");
    // Blocks grouped by window, in order of first appearance.
    let mut groups: Vec<(Window, Vec<usize>)> = Vec::new();
    let mut group_of: HashMap<[u64; 2], usize> = HashMap::new();
    for &(i, w) in part.windows() {
        let g = *group_of
            .entry([w.min_s.to_bits(), w.max_s.to_bits()])
            .or_insert_with(|| {
                groups.push((w, Vec::new()));
                groups.len() - 1
            });
        groups[g].1.push(i);
    }
    let entry = |out: &mut String, target: String, w: Window| {
        let _ = writeln!(
            out,
            "  - {{{target}, min_s: {}, max_s: {}}}",
            real(w.min_s),
            real(w.max_s)
        );
    };
    for (w, members) in groups {
        let (lo, hi) = bounding_box(part, &members);
        let inside = |b: &Block| (0..3).all(|d| lo[d] <= b[d] && b[d] <= hi[d]);
        let exact = members.len() > 1
            && part.blocks().iter().filter(|b| inside(b)).count() == members.len();
        if exact {
            entry(
                out,
                format!("box: {{min: {}, max: {}}}", block(lo), block(hi)),
                w,
            );
        } else {
            for i in members {
                entry(out, format!("block: {}", block(part.block(i))), w);
            }
        }
    }
}

fn bounding_box(part: &Part, members: &[usize]) -> (Block, Block) {
    let mut lo = [i64::MAX; 3];
    let mut hi = [i64::MIN; 3];
    for &i in members {
        let b = part.block(i);
        for d in 0..3 {
            lo[d] = lo[d].min(b[d]);
            hi[d] = hi[d].max(b[d]);
        }
    }
    (lo, hi)
}

pub(crate) fn write_thermal(out: &mut String, t: &ThermalParams) {
    let d = ThermalParams::default();
    let reals = [
        ("ambient_c", t.ambient_c, d.ambient_c),
        ("deposit_c", t.deposit_c, d.deposit_c),
        ("block_time_s", t.block_time_s, d.block_time_s),
        ("transit_time_s", t.transit_time_s, d.transit_time_s),
        ("conduction_per_s", t.conduction_per_s, d.conduction_per_s),
        ("substrate_per_s", t.substrate_per_s, d.substrate_per_s),
        (
            "radiation_per_s_k3",
            t.radiation_per_s_k3,
            d.radiation_per_s_k3,
        ),
        ("max_cooldown_s", t.max_cooldown_s, d.max_cooldown_s),
    ];
    let mut lines: Vec<String> = reals
        .iter()
        .filter(|(_, v, default)| v.to_bits() != default.to_bits())
        .map(|(k, v, _)| format!("  {k}: {}", real(*v)))
        .collect();
    if t.substeps != d.substeps {
        lines.push(format!("  substeps: {}", t.substeps));
    }
    if !lines.is_empty() {
        out.push_str("thermal:\n");
        for line in lines {
            let _ = writeln!(out, "{line}");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn round_trip(text: &str) -> (Part, Part) {
        let part = Part::parse(text).unwrap();
        let again =
            Part::parse(&to_yaml(&part)).unwrap_or_else(|e| panic!("{e}\n{}", to_yaml(&part)));
        (part, again)
    }

    fn assert_same(a: &Part, b: &Part) {
        assert_eq!(a.name, b.name);
        assert_eq!(a.block_mm, b.block_mm);
        assert_eq!(a.origin_mm, b.origin_mm);
        assert_eq!(a.max_fragments, b.max_fragments);
        assert_eq!(a.blocks(), b.blocks());
        assert_eq!(a.windows(), b.windows());
        assert_eq!(a.thermal, b.thermal);
    }

    #[test]
    fn layers_windows_and_thermal_read_back() {
        let (a, b) = round_trip(
            "name: 'odd: name #1'\nblock_mm: [6, 0.1, 1e-7]\norigin_mm: [-1.5, 0, 987654.321]\nmax_fragments: 3\n\
             layers:\n  - |\n    ###\n    #.#\n  - |\n    .\n  - |\n    ..#\n\
             t85:\n  - {box: {min: [0,0,0], max: [2,0,0]}, min_s: 1, max_s: 5}\n  - {block: [2,0,2], min_s: 0.3, max_s: 0.7}\n  - {block: [0,1,0], min_s: 1, max_s: 5}\n\
             thermal: {substeps: 7, radiation_per_s_k3: 3.3e-13}\n",
        );
        assert_same(&a, &b);
        let text = to_yaml(&a);
        assert!(text.contains("layers:"), "{text}");
        // [0,1,0] joins the first box's window, but that box would hold [2,1,0] too.
        assert!(text.contains("block: [0, 1, 0]"), "{text}");
    }

    #[test]
    fn sparse_parts_use_the_blocks_form() {
        let (a, b) = round_trip(
            "name: far\nblock_mm: [1, 1, 1]\nmax_fragments: 1\nblocks: [[0,0,0], [100000, 0, 0], [5, 7, 1]]\n\
             t85: [{box: {min: [0,0,0], max: [100000,0,0]}, min_s: 0, max_s: 9}]\n",
        );
        assert_same(&a, &b);
        assert!(to_yaml(&a).contains("box: {min: [0, 0, 0], max: [100000, 0, 0]}"));
    }
}
