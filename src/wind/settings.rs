//! Where the wind estimate comes from (`[wind]` in the config).

use serde::{Deserialize, Serialize};

use crate::model::wind::WindSource;

/// Where the wind estimate comes from (see `wind`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WindSettings {
    /// Sources in order of trust ("sensor", "fan", "pca" in the config).
    pub priority: Vec<WindSource>,
    /// Age after which a sensor or PCA estimate is ignored (s).
    pub max_age_s: f64,
    /// The fan's position (m, Y up), or empty for no fan.
    pub fan_position: Vec<f64>,
    /// The fan's wind speed at the tree (m/s), 0 when unknown.
    pub fan_speed_m_s: f64,
    /// Serial device of a wind sensor, empty for none.
    pub sensor_port: String,
    /// Baud rate of the sensor's serial line (NMEA 0183 is 4800).
    pub sensor_baud: u32,
    /// Capture azimuth of the sensor's 0° mark (degrees).
    pub sensor_heading_deg: f64,
    /// PCA window (s).
    pub pca_window_s: f64,
    /// RMS sway below which PCA gives no estimate (mm).
    pub pca_min_sway_mm: f64,
}

impl WindSettings {
    /// The fan's position, when one is configured.
    pub fn fan(&self) -> Option<glam::DVec3> {
        match self.fan_position[..] {
            [x, y, z] => Some(glam::DVec3::new(x, y, z)),
            _ => None,
        }
    }
}
