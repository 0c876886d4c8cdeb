//! Meshes: STL files and in-memory triangle meshes, their soundness check, and their
//! voxelization into a block [`Part`](waam_part::Part).
//!
//! A CAD part arrives as a triangle mesh. [`read_stl`] reads binary and ASCII STL (with
//! the `stl_io` crate), [`TriangleMesh::check`] refuses meshes that do not bound a solid
//! (open, non-manifold, inconsistently oriented, degenerate, non-finite), and [`voxelize`]
//! keeps every block of a grid whose centre lies inside the mesh.

mod check;
mod stl;
mod voxel;

use std::fmt;

use thiserror::Error;

use waam_part::ThermalParams;
use waam_part::{Block, PartError, Window};

pub use stl::read_stl;
pub use voxel::{voxelize, voxelize_indexed, Voxelized};

/// Coordinates beyond this (mm) are refused: exact geometric predicates need headroom.
pub const MAX_COORD_MM: f64 = 1e9;

/// Default limit on the grid cells a voxelization may visit (nx · ny · nz).
pub const DEFAULT_MAX_CELLS: u64 = 20_000_000;

/// Length unit of mesh coordinates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Units {
    /// Millimetres (the usual unit of STL files from CAD).
    #[default]
    Mm,
    /// Metres (ROS messages such as `shape_msgs/Mesh`).
    M,
}

impl Units {
    /// Millimetres per unit.
    pub fn to_mm(self) -> f64 {
        match self {
            Units::Mm => 1.0,
            Units::M => 1000.0,
        }
    }
}

/// A triangle mesh in millimetres: vertices and triangles as vertex indices.
///
/// Triangles are counter-clockwise seen from outside (the STL convention); the
/// voxelizer also accepts a consistently inside-out mesh.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TriangleMesh {
    pub vertices: Vec<[f64; 3]>,
    pub triangles: Vec<[u32; 3]>,
}

/// Why a mesh cannot be read, checked or voxelized. Triangles are numbered from 1.
#[derive(Debug, Error, PartialEq)]
pub enum MeshError {
    #[error("not an STL file: {0}")]
    NotStl(String),
    #[error("the mesh has no triangles")]
    Empty,
    #[error("triangle {triangle}: vertex index {index} is out of range (the mesh has {vertices} vertices)")]
    BadIndex {
        triangle: usize,
        index: u32,
        vertices: usize,
    },
    #[error("triangle {triangle}: vertex {} has a non-finite coordinate", Point(*.vertex))]
    NonFinite { triangle: usize, vertex: [f64; 3] },
    #[error("triangle {triangle}: vertex {} is out of range (|coordinate| > {MAX_COORD_MM} mm)", Point(*.vertex))]
    OutOfRange { triangle: usize, vertex: [f64; 3] },
    #[error("degenerate triangle {triangle}: its corners {}, {}, {} have zero area", Point(.corners[0]), Point(.corners[1]), Point(.corners[2]))]
    Degenerate {
        triangle: usize,
        corners: [[f64; 3]; 3],
    },
    #[error("open mesh: {count} boundary edge(s), first between vertex {} and {} (triangle {triangle})", Point(*.a), Point(*.b))]
    Open {
        count: usize,
        a: [f64; 3],
        b: [f64; 3],
        triangle: usize,
    },
    #[error("non-manifold mesh: {count} edge(s) shared by more than two triangles, first between vertex {} and {} ({uses} triangles)", Point(*.a), Point(*.b))]
    NonManifold {
        count: usize,
        a: [f64; 3],
        b: [f64; 3],
        uses: usize,
    },
    #[error("inconsistently oriented mesh: {count} edge(s) run the same way in both their triangles, first between vertex {} and {} (triangles {first} and {second}: one of them is flipped)", Point(*.a), Point(*.b))]
    Flipped {
        count: usize,
        a: [f64; 3],
        b: [f64; 3],
        first: usize,
        second: usize,
    },
    #[error("block pitch: {0}")]
    Pitch(String),
    #[error("the grid would have {} x {} x {} = {} cells, more than the limit of {limit}: use a coarser pitch or raise the limit", Count(grid[0]), Count(grid[1]), Count(grid[2]), Count(*cells))]
    TooLarge {
        grid: [f64; 3],
        cells: f64,
        limit: u64,
    },
    #[error("no block centre lies inside the mesh (grid {nx} x {ny} x {nz}): the pitch is too coarse for the part")]
    NoBlocks { nx: u64, ny: u64, nz: u64 },
    #[error("window {index}: {message}")]
    Window { index: usize, message: String },
    #[error(transparent)]
    Part(#[from] PartError),
}

/// A point in messages: `(x, y, z)` with the shortest exact digits.
pub struct Point(pub [f64; 3]);

impl fmt::Display for Point {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let [x, y, z] = self.0.map(Num);
        write!(f, "({x}, {y}, {z})")
    }
}

/// A count that may be astronomically large: exact up to 10^15, then like `2.4e31`.
struct Count(f64);

impl fmt::Display for Count {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.0 < 1e15 {
            write!(f, "{}", self.0 as u64)
        } else {
            write!(f, "{:.2e}", self.0)
        }
    }
}

/// A coordinate that came from an f32 (STL) prints as that f32: `0.1`, not `0.100000001`.
struct Num(f64);

impl fmt::Display for Num {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let narrow = self.0 as f32;
        if narrow as f64 == self.0 {
            write!(f, "{narrow}")
        } else {
            write!(f, "{}", self.0)
        }
    }
}

/// A t8/5 window on the blocks of a grid box (inclusive); later rules override earlier ones.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WindowRule {
    pub min: Block,
    pub max: Block,
    pub window: Window,
}

impl WindowRule {
    /// A window on every block of the part.
    pub fn everywhere(window: Window) -> WindowRule {
        WindowRule {
            min: [0; 3],
            max: [i64::MAX; 3],
            window,
        }
    }

    /// A window on one block.
    pub fn block(block: Block, window: Window) -> WindowRule {
        WindowRule {
            min: block,
            max: block,
            window,
        }
    }
}

/// How to turn a mesh into a part.
#[derive(Debug, Clone)]
pub struct VoxelizeOptions {
    /// The part's name.
    pub name: String,
    /// Block pitch along x, y, z, millimetres.
    pub block_mm: [f64; 3],
    /// Min corner of block (0,0,0), mm; `None`: the mesh's min corner.
    pub origin_mm: Option<[f64; 3]>,
    /// k, the most weld paths a plan may use.
    pub max_fragments: usize,
    /// t8/5 windows, applied in order.
    pub windows: Vec<WindowRule>,
    pub thermal: ThermalParams,
    /// Refuse grids of more cells than this (a tiny pitch must not allocate forever).
    pub max_cells: u64,
}

impl VoxelizeOptions {
    /// Options with a pitch and defaults elsewhere: k = 1, no windows, default thermal model.
    pub fn new(name: impl Into<String>, block_mm: [f64; 3]) -> VoxelizeOptions {
        VoxelizeOptions {
            name: name.into(),
            block_mm,
            origin_mm: None,
            max_fragments: 1,
            windows: Vec::new(),
            thermal: ThermalParams::default(),
            max_cells: DEFAULT_MAX_CELLS,
        }
    }
}
