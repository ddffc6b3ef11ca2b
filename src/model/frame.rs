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
    /// A marker without a source ID (simulated, or from a source that has
    /// none).
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
    /// A frame without a latency: files and OSC carry none (the NatNet
    /// client fills `latency_s` itself).
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

/// The vertical axis of a source's coordinates. Inside treemocap Y is up
/// (as in Motive and the paper); a Z-up source is turned at its edge, here
/// and nowhere else.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum UpAxis {
    /// Y up, as inside treemocap and in Motive's default export.
    #[serde(alias = "Y")]
    Y,
    /// Z up: the usual C3D convention (Vicon, Qualisys), a NatNet→OSC
    /// bridge's `--yup2zup`, Blender, Unreal.
    #[serde(alias = "Z")]
    Z,
}

impl UpAxis {
    /// A position in this axis convention as treemocap's Y up. Z up (x right,
    /// y forward, z up) becomes (x, z, −y): a right-handed turn about +X, so
    /// forward becomes −Z, as in Motive's Y-up frame.
    pub fn to_y_up(self, p: DVec3) -> DVec3 {
        match self {
            UpAxis::Y => p,
            UpAxis::Z => DVec3::new(p.x, p.z, -p.y),
        }
    }
}

/// The length unit a source sends positions in; frames are always metres.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LengthUnit {
    /// Metres (Motive's streaming unit).
    M,
    /// Centimetres.
    Cm,
    /// Millimetres (most C3D files, Motive CSV exports in mm).
    Mm,
}

impl LengthUnit {
    /// Metres per unit.
    pub fn metres(self) -> f64 {
        match self {
            LengthUnit::M => 1.0,
            LengthUnit::Cm => 0.01,
            LengthUnit::Mm => 0.001,
        }
    }
}
