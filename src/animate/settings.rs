//! The animation's settings (`[animate]` in the config).

use serde::{Deserialize, Serialize};

use crate::error::{check_range, Error, Result};

/// How the captured motion is put on the tree and sampled
/// (docs/animation.md).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AnimateSettings {
    /// Keys per second of the animation (Hz).
    pub rate_hz: f64,
    /// The part of the recording to animate, `[start_s, end_s]` on the
    /// recording's clock; empty = the whole recording.
    pub window_s: Vec<f64>,
    /// Longest window animated (s): a longer one is cut to its first
    /// `max_duration_s`, so that an hour-long session does not make a
    /// gigabyte file by default.
    pub max_duration_s: f64,
    /// Power `p` of the bending profile `s^p` (s = path length from the
    /// trunk base); 2 is a cantilever's small-deflection shape.
    pub bend_power: f64,
    /// How many captured tips a random tip (or a captured tip whose marker
    /// is missing) borrows its motion from.
    pub neighbours: usize,
    /// Most live pose messages per second the daemon sends (WebSocket and
    /// OSC); 0 = none.
    pub live_rate_hz: f64,
}

impl Default for AnimateSettings {
    fn default() -> Self {
        AnimateSettings {
            rate_hz: 30.0,
            window_s: Vec::new(),
            max_duration_s: 120.0,
            bend_power: 2.0,
            neighbours: 3,
            live_rate_hz: 60.0,
        }
    }
}

impl AnimateSettings {
    /// Range checks, each naming the key and its allowed range.
    pub fn validate(&self) -> Result<()> {
        check_range("animate.rate_hz", self.rate_hz, 1.0, 1000.0)?;
        check_range("animate.max_duration_s", self.max_duration_s, 1.0, 3600.0)?;
        check_range("animate.bend_power", self.bend_power, 0.5, 4.0)?;
        check_range("animate.neighbours", self.neighbours as f64, 1.0, 16.0)?;
        check_range("animate.live_rate_hz", self.live_rate_hz, 0.0, 1000.0)?;
        match self.window_s.as_slice() {
            [] => Ok(()),
            [a, b] if a.is_finite() && b.is_finite() && a < b => Ok(()),
            _ => Err(Error::config(
                "animate.window_s",
                "must be [] (the whole recording) or [start_s, end_s] with start_s < end_s",
            )),
        }
    }

    /// The window as `(start, end)`, `None` for the whole recording.
    pub fn window(&self) -> Option<(f64, f64)> {
        match self.window_s.as_slice() {
            [a, b] => Some((*a, *b)),
            _ => None,
        }
    }
}
