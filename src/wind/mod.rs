//! The wind on the tree: where it blows and how hard, from one of three
//! sources, logged, and handed to the particle flow's wind force.
//!
//! Sources by default priority: a wind sensor on a serial port (`serial`),
//! the fan's position in the config (`fan`), or the principal direction of
//! the tips' sway (`pca`). [`WindSelector`] keeps the latest estimate of each
//! and answers with the best one that is still fresh.

use glam::DVec3;
use serde::{Deserialize, Serialize};

pub mod fan;
pub mod log;
pub mod pca;
pub mod serial;

/// Where a wind estimate came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum WindSource {
    Sensor,
    Fan,
    Pca,
}

impl WindSource {
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

/// Keeps the latest estimate per source and picks by priority.
#[derive(Debug, Clone)]
pub struct WindSelector {
    priority: Vec<WindSource>,
    /// An estimate older than this (s, on the session clock) is ignored, so a
    /// sensor that was unplugged hands over to the next source.
    max_age_s: f64,
    latest: Vec<WindEstimate>,
}

impl WindSelector {
    pub fn new(priority: Vec<WindSource>, max_age_s: f64) -> Self {
        WindSelector {
            priority,
            max_age_s,
            latest: Vec::new(),
        }
    }

    pub fn update(&mut self, estimate: WindEstimate) {
        self.latest.retain(|e| e.source != estimate.source);
        self.latest.push(estimate);
    }

    /// The best fresh estimate at `now_s`. The fan never goes stale: it is a
    /// fixed fact of the rig.
    pub fn current(&self, now_s: f64) -> Option<WindEstimate> {
        self.priority.iter().find_map(|source| {
            self.latest
                .iter()
                .find(|e| e.source == *source)
                .filter(|e| e.source == WindSource::Fan || now_s - e.time_s <= self.max_age_s)
                .copied()
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn est(source: WindSource, t: f64, az: f64) -> WindEstimate {
        WindEstimate {
            time_s: t,
            source,
            direction: direction_of(az),
            speed_m_s: None,
        }
    }

    #[test]
    fn azimuth_round_trip() {
        for az in [0.0, 45.0, 90.0, 180.0, 270.0, 359.0] {
            assert!((azimuth_of(direction_of(az)) - az).abs() < 1e-9);
        }
        assert!((azimuth_of(DVec3::X) - 90.0).abs() < 1e-12);
    }

    #[test]
    fn priority_and_staleness() {
        let mut s = WindSelector::new(
            vec![WindSource::Sensor, WindSource::Fan, WindSource::Pca],
            5.0,
        );
        assert!(s.current(0.0).is_none());
        s.update(est(WindSource::Pca, 0.0, 10.0));
        assert_eq!(s.current(1.0).unwrap().source, WindSource::Pca);
        s.update(est(WindSource::Sensor, 1.0, 20.0));
        s.update(est(WindSource::Fan, 0.0, 30.0));
        assert_eq!(s.current(2.0).unwrap().source, WindSource::Sensor);
        // The sensor went quiet: the fan takes over, and never goes stale.
        assert_eq!(s.current(100.0).unwrap().source, WindSource::Fan);
    }
}
