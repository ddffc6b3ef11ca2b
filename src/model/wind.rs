//! The wind on the tree as the rest of the program sees it: where it blows
//! and how hard, and which source said so.

use glam::DVec3;
use serde::{Deserialize, Serialize};

/// The relative strength used when only the wind's direction is known (the
/// sway PCA): the flow's wind force is then `reconstruct.wind_weight` × the
/// direction.
pub const UNKNOWN_SPEED: f64 = 1.0;

/// Where a wind estimate came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum WindSource {
    /// A wind sensor on a serial port: direction and speed, measured.
    Sensor,
    /// The fan's place in the config: the wind blows from it through the crown.
    Fan,
    /// The principal axis of the tips' sway: direction only.
    Pca,
}

impl WindSource {
    /// The name used in the config (`wind.priority`), wind.csv, tips.json
    /// and `/status`.
    pub fn name(self) -> &'static str {
        match self {
            WindSource::Sensor => "sensor",
            WindSource::Fan => "fan",
            WindSource::Pca => "pca",
        }
    }

    /// Parses a config name (`"sensor"`, `"fan"`, `"pca"`).
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "sensor" => Some(WindSource::Sensor),
            "fan" => Some(WindSource::Fan),
            "pca" => Some(WindSource::Pca),
            _ => None,
        }
    }
}

/// One estimate of the wind in capture coordinates (Y up).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct WindEstimate {
    /// Seconds on the session clock when the estimate was made.
    pub time_s: f64,
    /// Which source made the estimate; the selector ranks them by it.
    pub source: WindSource,
    /// Unit horizontal vector the wind blows *towards* (downwind): the
    /// direction the flow's wind force pushes branches.
    pub direction: DVec3,
    /// Metres per second, when the source measures it (sensor, configured fan).
    pub speed_m_s: Option<f64>,
}

impl WindEstimate {
    /// Downwind azimuth in degrees [0, 360): 0 blows towards +Z, 90 towards +X
    /// (a right-handed turn about +Y, the up axis).
    pub fn azimuth_deg(&self) -> f64 {
        azimuth_of(self.direction)
    }
}

/// Downwind azimuth of a horizontal direction, degrees in [0, 360).
pub fn azimuth_of(direction: DVec3) -> f64 {
    let a = direction.x.atan2(direction.z).to_degrees();
    if a < 0.0 {
        a + 360.0
    } else {
        a
    }
}

/// Unit horizontal vector for a downwind azimuth (inverse of [`azimuth_of`]).
pub fn direction_of(azimuth_deg: f64) -> DVec3 {
    let a = azimuth_deg.to_radians();
    DVec3::new(a.sin(), 0.0, a.cos())
}

/// Angle between two directions in degrees (0 to 180).
pub fn angle_between_deg(a: DVec3, b: DVec3) -> f64 {
    let d = a
        .normalize_or_zero()
        .dot(b.normalize_or_zero())
        .clamp(-1.0, 1.0);
    d.acos().to_degrees()
}

impl WindEstimate {
    /// The vector the particle flow's wind force uses: direction × speed in
    /// m/s, or × [`UNKNOWN_SPEED`] when the speed is not known or zero (a
    /// fan whose speed was left at 0 still gives its direction).
    pub fn flow_vector(&self) -> DVec3 {
        let speed = self.speed_m_s.filter(|s| *s > 0.0).unwrap_or(UNKNOWN_SPEED);
        self.direction * speed
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn azimuth_round_trip() {
        for az in [0.0, 45.0, 90.0, 180.0, 270.0, 359.0] {
            assert!((azimuth_of(direction_of(az)) - az).abs() < 1e-9);
        }
        assert!((azimuth_of(DVec3::X) - 90.0).abs() < 1e-12);
    }
}
