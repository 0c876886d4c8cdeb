//! The weld graph of a part (part-format.md, "The weld graph").
//!
//! Vertices are the blocks (by index); a directed edge runs from a block to each existing
//! block one step sideways within its layer or one layer straight up: the torch never
//! moves down. The graph also keeps the six face neighbours of every block, which the
//! thermal model needs, so that neighbour lists are computed once per part.
//!
//! A graph part (beads along a mesh's contours) gives its moves and its "stands on"
//! relation directly ([`WeldGraph::from_moves`]): a deposit may stand on several below it.
//! Gravity reads [`WeldGraph::supports`] either way: on a cube part it is the one block
//! directly below.

use crate::Part;

/// Marks an absent neighbour in the fixed-size neighbour arrays.
pub const NONE: u32 = u32::MAX;

/// Face-neighbour order used everywhere (also the summation order of the heat flux):
/// -x, +x, -y, +y, -z, +z. Opposite directions differ in the lowest bit (`k ^ 1`).
pub const FACE_DIRS: [[i64; 3]; 6] = [
    [-1, 0, 0],
    [1, 0, 0],
    [0, -1, 0],
    [0, 1, 0],
    [0, 0, -1],
    [0, 0, 1],
];

/// Weld-graph moves: sideways within a layer or one layer up.
pub const MOVES: [[i64; 3]; 5] = [[-1, 0, 0], [1, 0, 0], [0, -1, 0], [0, 1, 0], [0, 0, 1]];

/// The weld graph in compressed adjacency form, plus face neighbours.
#[derive(Debug, Clone)]
pub struct WeldGraph {
    succ_start: Vec<u32>,
    succ: Vec<u32>,
    pred_start: Vec<u32>,
    pred: Vec<u32>,
    /// What each vertex stands on (gravity), compressed like the successors.
    sup_start: Vec<u32>,
    sup: Vec<u32>,
    /// Face neighbours of cube parts; all [`NONE`] for a graph part.
    faces: Vec<[u32; 6]>,
}

/// Compressed rows of `lists`: (row starts with a final end, entries).
fn compressed(lists: impl Iterator<Item = impl IntoIterator<Item = u32>>) -> (Vec<u32>, Vec<u32>) {
    let (mut start, mut all) = (vec![0u32], Vec::new());
    for row in lists {
        all.extend(row);
        start.push(all.len() as u32);
    }
    (start, all)
}

/// Predecessor rows of the successor rows `(start, succ)` of `n` vertices.
fn reversed(n: usize, succ_start: &[u32], succ: &[u32]) -> (Vec<u32>, Vec<u32>) {
    let mut pred_count = vec![0u32; n + 1];
    for &j in succ {
        pred_count[j as usize + 1] += 1;
    }
    for i in 0..n {
        pred_count[i + 1] += pred_count[i];
    }
    let pred_start = pred_count.clone();
    let mut fill = pred_count;
    let mut pred = vec![0u32; succ.len()];
    for i in 0..n {
        for &j in &succ[succ_start[i] as usize..succ_start[i + 1] as usize] {
            pred[fill[j as usize] as usize] = i as u32;
            fill[j as usize] += 1;
        }
    }
    (pred_start, pred)
}

impl WeldGraph {
    pub fn new(part: &Part) -> WeldGraph {
        if let Some(beads) = part.bead_part() {
            let moves = beads.moves();
            let n = beads.len();
            let successors: Vec<Vec<u32>> = (0..n).map(|i| moves.successors(i).to_vec()).collect();
            let supports: Vec<Vec<u32>> = (0..n).map(|i| moves.stands_on(i).to_vec()).collect();
            return WeldGraph::from_moves(&successors, &supports);
        }
        let n = part.len();
        let faces: Vec<[u32; 6]> = part
            .blocks()
            .iter()
            .map(|&b| FACE_DIRS.map(|d| part.neighbour(b, d).map_or(NONE, |j| j as u32)))
            .collect();
        let mut succ_start = Vec::with_capacity(n + 1);
        let mut succ = Vec::with_capacity(n * 3);
        for f in &faces {
            succ_start.push(succ.len() as u32);
            // MOVES are FACE_DIRS without -z: faces 0..4 and 5.
            succ.extend(
                [f[0], f[1], f[2], f[3], f[5]]
                    .into_iter()
                    .filter(|&j| j != NONE),
            );
        }
        succ_start.push(succ.len() as u32);
        let (pred_start, pred) = reversed(n, &succ_start, &succ);
        let (sup_start, sup) = compressed(faces.iter().map(|f| Some(f[4]).filter(|&j| j != NONE)));
        WeldGraph {
            succ_start,
            succ,
            pred_start,
            pred,
            sup_start,
            sup,
            faces,
        }
    }

    /// The weld graph of a graph part: `successors[i]`, the vertices the torch may move to
    /// from `i` (sideways within its layer or up onto what stands on it), and
    /// `supports[i]`, the vertices `i` stands on. There are no face neighbours.
    pub fn from_moves(successors: &[Vec<u32>], supports: &[Vec<u32>]) -> WeldGraph {
        let n = successors.len();
        assert_eq!(supports.len(), n, "one support list per vertex");
        let (succ_start, succ) = compressed(successors.iter().map(|r| r.iter().copied()));
        let (pred_start, pred) = reversed(n, &succ_start, &succ);
        let (sup_start, sup) = compressed(supports.iter().map(|r| r.iter().copied()));
        WeldGraph {
            succ_start,
            succ,
            pred_start,
            pred,
            sup_start,
            sup,
            faces: vec![[NONE; 6]; n],
        }
    }

    /// Number of blocks (vertices).
    pub fn len(&self) -> usize {
        self.faces.len()
    }

    /// True for a graph without vertices (never for a graph of a part).
    pub fn is_empty(&self) -> bool {
        self.faces.is_empty()
    }

    /// Number of directed edges.
    pub fn edge_count(&self) -> usize {
        self.succ.len()
    }

    /// Blocks the torch may move to from `i`.
    pub fn successors(&self, i: usize) -> &[u32] {
        &self.succ[self.succ_start[i] as usize..self.succ_start[i + 1] as usize]
    }

    /// Blocks the torch may come to `i` from.
    pub fn predecessors(&self, i: usize) -> &[u32] {
        &self.pred[self.pred_start[i] as usize..self.pred_start[i + 1] as usize]
    }

    /// Whether `a -> b` is an edge.
    pub fn has_edge(&self, a: usize, b: usize) -> bool {
        self.successors(a).contains(&(b as u32))
    }

    /// What `i` stands on: it is never welded in an earlier fragment than any of them (on a
    /// cube part, the block directly below, if any).
    pub fn supports(&self, i: usize) -> &[u32] {
        &self.sup[self.sup_start[i] as usize..self.sup_start[i + 1] as usize]
    }

    /// Whether `i` stands on nothing (the plate).
    pub fn on_plate(&self, i: usize) -> bool {
        self.supports(i).is_empty()
    }

    /// The six face neighbours of `i` in [`FACE_DIRS`] order, [`NONE`] where absent.
    pub fn faces(&self, i: usize) -> [u32; 6] {
        self.faces[i]
    }

    /// The block directly below `i`, if any.
    pub fn below(&self, i: usize) -> Option<usize> {
        let j = self.faces[i][4];
        (j != NONE).then_some(j as usize)
    }

    /// The block directly above `i`, if any.
    pub fn above(&self, i: usize) -> Option<usize> {
        let j = self.faces[i][5];
        (j != NONE).then_some(j as usize)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edges_go_sideways_and_up_never_down() {
        let part = Part::parse(
            "name: t\nblock_mm: [1,1,1]\nmax_fragments: 1\nblocks: [[0,0,0],[1,0,0],[0,0,1]]\n",
        )
        .unwrap();
        let g = WeldGraph::new(&part);
        let (a, b, c) = (0, 1, 2); // [0,0,0], [1,0,0], [0,0,1]
        assert!(g.has_edge(a, b) && g.has_edge(b, a) && g.has_edge(a, c));
        assert!(!g.has_edge(c, a) && !g.has_edge(b, c) && !g.has_edge(c, b));
        assert_eq!(g.edge_count(), 3);
        assert_eq!(g.predecessors(c), &[a as u32]);
        assert_eq!(g.below(c), Some(a));
        assert_eq!(g.above(a), Some(c));
        assert_eq!(g.below(a), None);
        assert_eq!(g.supports(c), &[a as u32]);
        assert!(g.on_plate(a) && g.on_plate(b) && !g.on_plate(c));
    }

    #[test]
    fn a_graph_part_stands_on_several() {
        // 0, 1 on the plate side by side; 2 above both; moves 0 <-> 1, 0 -> 2, 1 -> 2.
        let g = WeldGraph::from_moves(
            &[vec![1, 2], vec![0, 2], vec![]],
            &[vec![], vec![], vec![0, 1]],
        );
        assert_eq!(g.edge_count(), 4);
        assert_eq!(g.predecessors(2), &[0, 1]);
        assert_eq!(g.supports(2), &[0, 1]);
        assert!(g.on_plate(0) && !g.on_plate(2));
        assert_eq!(g.below(2), None);
    }
}
