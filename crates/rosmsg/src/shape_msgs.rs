//! `shape_msgs`: triangle meshes (the node's mesh input).

use serde::{Deserialize, Serialize};

use super::geometry_msgs::Point;
use super::ros_message;

/// A triangle mesh: vertices (metres) and triangles indexing them.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Mesh {
    pub triangles: Vec<MeshTriangle>,
    pub vertices: Vec<Point>,
}
ros_message!(
    Mesh,
    "shape_msgs/msg/Mesh",
    "RIHS01_f2150b82d8ee7e8bc3f396a2b158aefb4b9a5510a474be271ba1268aebb55289"
);

/// Three vertex indices (a fixed-size array: no length on the wire).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct MeshTriangle {
    pub vertex_indices: [u32; 3],
}
ros_message!(
    MeshTriangle,
    "shape_msgs/msg/MeshTriangle",
    "RIHS01_618e5c073eeb729e433ef6226e72c01d995c459fb7d76348c9700409a5020bd0"
);
