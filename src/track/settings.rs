//! The marker stage's settings (`[tracking]` in the config).

use serde::{Deserialize, Serialize};

use crate::error::{check_range, Error, Result};

/// Marker processing: tracking, gap filling, noise removal, rest phase
/// (spec/pipeline.md sections 2–4).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrackingSettings {
    /// Gate radius around a trace's prediction (mm).
    pub gate_mm: f64,
    /// Frames a trace survives without a marker before it ends.
    pub max_gap: u32,
    /// Longest gap that is filled from the neighbours' motion (s).
    pub max_fill_s: f64,
    /// Radius (mm) within which a long piece without a rest position joins
    /// the gap of the marker whose neighbourhood it occupies.
    pub max_jump_mm: f64,
    /// Pieces whose rest positions are this close are one marker (mm).
    pub merge_radius_mm: f64,
    /// Traces measured in fewer than this fraction of frames are noise.
    pub noise_fraction: f64,
    /// Motion (standard deviation, mm) below which a marker counts as still.
    pub rest_motion_mm: f64,
    /// A fixed rest window `[start_s, end_s]`, or empty for automatic.
    pub rest_window_s: Vec<f64>,
    /// Markers of one frame closer than this are duplicates (mm).
    pub duplicate_mm: f64,
    /// Measurement noise the motion model assumes (mm, σ per axis).
    pub noise_mm: f64,
    /// Gate in standard deviations of a trace's prediction.
    pub gate_sigma: f64,
    /// Time a new trace is watched before it is compared with the markers
    /// lost before it (s).
    pub link_s: f64,
    /// Time after which a trace nobody claims is a marker of its own (s).
    pub confirm_s: f64,
    /// Smallest radius (RMS distance, mm) within which a new trace follows
    /// the path its neighbours predict for a lost marker.
    pub link_min_mm: f64,
    /// Largest such radius (mm).
    pub link_max_mm: f64,
    /// How long a lost marker can be found again on line (s).
    pub keep_lost_s: f64,
    /// Longest gap filled by interpolation (PCHIP) where the neighbours
    /// say nothing (s); `max_fill_s` bounds fills from the neighbours.
    pub max_pchip_s: f64,
}

impl TrackingSettings {
    /// Range checks, each naming the key and its allowed range.
    pub fn validate(&self) -> Result<()> {
        check_range("tracking.gate_mm", self.gate_mm, 1.0, 500.0)?;
        check_range("tracking.max_gap", f64::from(self.max_gap), 0.0, 100_000.0)?;
        check_range("tracking.max_fill_s", self.max_fill_s, 0.0, 60.0)?;
        check_range("tracking.max_jump_mm", self.max_jump_mm, 1.0, 1000.0)?;
        check_range("tracking.merge_radius_mm", self.merge_radius_mm, 0.0, 100.0)?;
        check_range("tracking.noise_fraction", self.noise_fraction, 0.0, 1.0)?;
        check_range("tracking.rest_motion_mm", self.rest_motion_mm, 0.01, 100.0)?;
        check_range("tracking.duplicate_mm", self.duplicate_mm, 0.0, 10.0)?;
        check_range("tracking.noise_mm", self.noise_mm, 0.01, 10.0)?;
        check_range("tracking.gate_sigma", self.gate_sigma, 2.0, 20.0)?;
        check_range("tracking.link_s", self.link_s, 0.0, 2.0)?;
        check_range("tracking.confirm_s", self.confirm_s, 0.05, 30.0)?;
        check_range("tracking.link_min_mm", self.link_min_mm, 0.1, 100.0)?;
        check_range(
            "tracking.link_max_mm",
            self.link_max_mm,
            self.link_min_mm,
            500.0,
        )?;
        check_range("tracking.keep_lost_s", self.keep_lost_s, 0.0, 3600.0)?;
        check_range("tracking.max_pchip_s", self.max_pchip_s, 0.0, 10.0)?;
        match self.rest_window_s.as_slice() {
            [] => {}
            [a, b] if a.is_finite() && b.is_finite() && *a >= 0.0 && a < b => {}
            _ => {
                return Err(Error::config(
                    "tracking.rest_window_s",
                    "must be [] (automatic) or [start_s, end_s] with 0 <= start_s < end_s",
                ))
            }
        }
        Ok(())
    }
}
