//! `MarkerFrame`: one capture instant, the unit every source yields and every
//! stage consumes.

use glam::DVec3;
use serde::{Deserialize, Serialize};

/// One marker seen in one frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Marker {
    /// Position in metres, Y up (converted at the source's edge).
    pub position: DVec3,
    /// The source's own ID for this marker (NatNet marker ID, the number in a
    /// Motive `Unlabeled 1036` column, a C3D point index). Only a hint:
    /// unlabeled IDs change after every occlusion, so tracking never relies on it.
    pub id: Option<i64>,
}

impl Marker {
    pub fn new(position: DVec3) -> Self {
        Marker { position, id: None }
    }
}

/// The unindexed markers of one capture instant.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct MarkerFrame {
    /// The source's frame number. May start anywhere and may jump (trimmed
    /// takes, dropped packets) or go back (a restarted source).
    pub frame: i64,
    /// Seconds since the start of the recording (frame / rate for files).
    pub time_s: f64,
    /// Markers in source order; the order carries no identity.
    pub markers: Vec<Marker>,
    /// Live sources only: seconds from mid-exposure to transmission, when the
    /// source reports it (NatNet 3.0+), so lag can be exported as a metric.
    pub latency_s: Option<f64>,
}

impl MarkerFrame {
    pub fn new(frame: i64, time_s: f64, markers: Vec<Marker>) -> Self {
        MarkerFrame {
            frame,
            time_s,
            markers,
            latency_s: None,
        }
    }

    /// Positions only, in source order.
    pub fn positions(&self) -> impl Iterator<Item = DVec3> + '_ {
        self.markers.iter().map(|m| m.position)
    }
}
