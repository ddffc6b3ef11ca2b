//! The daemon scale runs' session, generated frame by frame: `n` tips on a
//! crown, still for the first minute, then swaying as the wind rises over
//! 3 s; 1 % of samples missing. Shared by `examples/scale` (streamed to a
//! daemon over NatNet) and `examples/frame_cost` (fed to the live tracker).

use glam::DVec3;
use treemocap::format::{Format, Recording, RecordingInfo};
use treemocap::model::frame::{Marker, MarkerFrame};
use treemocap::rng::Rng;

/// A session generated frame by frame: `n` tips on a crown, still for the
/// first minute, then each swaying with its own period; 1 % of samples
/// missing; never all in memory.
pub struct Session {
    info: RecordingInfo,
    rng: Rng,
    rest: Vec<(DVec3, f64, f64)>,
    next: i64,
    frames: i64,
}

impl Session {
    /// `seconds` at `rate` Hz with `n` markers.
    pub fn new(seconds: f64, rate: f64, n: usize) -> Session {
        let mut rng = Rng::new(15);
        let rest = (0..n)
            .map(|i| {
                let a = i as f64 * 2.399_963;
                let h = 1.0 + (i as f64 / n as f64) * 1.5;
                let r = 0.6 + 0.3 * (i as f64 / n as f64) + 0.02 * rng.f64();
                (
                    DVec3::new(r * a.cos(), h, r * a.sin()),
                    rng.range(0.5, 2.0),
                    rng.range(0.0, 6.3),
                )
            })
            .collect();
        Session {
            info: RecordingInfo {
                format: Format::Log,
                version: "2".into(),
                frame_rate: rate,
                units: "m".into(),
                up_axis: "Y".into(),
                source: "scale".into(),
            },
            rng,
            rest,
            next: 0,
            frames: (seconds * rate) as i64,
        }
    }
}

impl Session {
    /// Where each marker rests (the still minute's positions, without noise).
    #[allow(dead_code)] // `examples/scale` streams the session only
    pub fn rest_positions(&self) -> Vec<DVec3> {
        self.rest.iter().map(|r| r.0).collect()
    }
}

impl Iterator for Session {
    type Item = treemocap::Result<MarkerFrame>;
    fn next(&mut self) -> Option<Self::Item> {
        if self.next >= self.frames {
            return None;
        }
        let f = self.next;
        self.next += 1;
        let t = f as f64 / self.info.frame_rate;
        // The wind rises over 3 s: a tree starts swaying from rest. (A step
        // here would move every marker by up to 30 mm in one frame, which
        // no tree does and which the tracker rightly takes as every marker
        // lost at once.)
        let ramp = ((t - 60.0) / 3.0).clamp(0.0, 1.0);
        let wind = ramp * ramp * (3.0 - 2.0 * ramp);
        let mut markers = Vec::with_capacity(self.rest.len());
        for &(p, freq, ph) in &self.rest {
            if self.rng.chance(0.01) {
                continue;
            }
            let sway = DVec3::new(
                0.03 * (freq * t + ph).sin(),
                0.0,
                0.01 * (1.7 * freq * t).cos(),
            );
            let noise = DVec3::new(self.rng.normal(), self.rng.normal(), self.rng.normal()) * 2e-4;
            markers.push(Marker::new(p + sway * wind + noise));
        }
        Some(Ok(MarkerFrame::new(f, t, markers)))
    }
}

impl Recording for Session {
    fn info(&self) -> &RecordingInfo {
        &self.info
    }
}
