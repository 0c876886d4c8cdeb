//! What a cell's sensors report, as the node hands it to the closed loop: already in the
//! part frame, checked (finite, on the part) and stamped.

/// One sensor reading. `stamp_s` is the message's header stamp in seconds (the ROS clock the
/// node executes on), so a reading can be matched to what was being welded at that time.
#[derive(Debug, Clone, PartialEq)]
pub enum Measured {
    /// A pyrometer aimed at the torch: the temperature of the deposit under the torch, °C.
    Temperature { stamp_s: f64, celsius: f64 },
    /// A layer height scan (e.g. a laser line scanner after a layer): points on the top
    /// surface in the part frame, mm.
    Scan { stamp_s: f64, points: Vec<[f64; 3]> },
    /// A thermal camera's image mapped onto the part: points on its surface in the part
    /// frame, mm, each with its temperature, °C.
    ThermalImage {
        stamp_s: f64,
        points: Vec<([f64; 3], f64)>,
    },
}

impl Measured {
    /// When it was read, s on the ROS clock.
    pub fn stamp_s(&self) -> f64 {
        match *self {
            Measured::Temperature { stamp_s, .. }
            | Measured::Scan { stamp_s, .. }
            | Measured::ThermalImage { stamp_s, .. } => stamp_s,
        }
    }
}
