//! Wind direction from the sway of the tips: the principal axis of their
//! horizontal displacement from the rest positions over a sliding window.
//!
//! Decisions: only the horizontal plane is analysed (the wind of a lab fan is
//! level, and vertical bobbing would tilt the axis); the axis is taken about
//! the mean displacement (the sway), and its sign from the mean displacement
//! itself (a tree bends *with* the wind, so the mean points downwind). Every
//! frame is reduced to five sums on arrival, so the window costs a few bytes
//! per frame however many tips there are.

use std::collections::VecDeque;

use glam::DVec3;

use crate::model::wind::{WindEstimate, WindSource};

/// Second moments of one frame's horizontal displacements.
#[derive(Debug, Clone, Copy, Default)]
struct Moments {
    time_s: f64,
    n: f64,
    x: f64,
    z: f64,
    xx: f64,
    xz: f64,
    zz: f64,
}

impl Moments {
    fn add(&mut self, o: &Moments) {
        self.n += o.n;
        self.x += o.x;
        self.z += o.z;
        self.xx += o.xx;
        self.xz += o.xz;
        self.zz += o.zz;
    }
}

/// Sliding-window PCA of tip sway.
#[derive(Debug, Clone)]
pub struct SwayPca {
    window_s: f64,
    /// Below this RMS sway (m) the tree is taken as still: no estimate.
    min_sway_m: f64,
    /// Per-frame moments inside a finite window (dropped as they leave it).
    frames: VecDeque<Moments>,
    /// With an infinite window (a whole recording): the running sums of
    /// every push, so memory stays constant however long the session.
    total: Moments,
}

impl SwayPca {
    /// An empty window of `window_s` seconds (session clock); a sway under
    /// `min_sway_m` RMS gives no estimate.
    pub fn new(window_s: f64, min_sway_m: f64) -> Self {
        SwayPca {
            window_s,
            min_sway_m,
            frames: VecDeque::new(),
            total: Moments::default(),
        }
    }

    /// Adds one frame: each tracked tip's position minus its rest position.
    pub fn push(&mut self, time_s: f64, displacements: impl IntoIterator<Item = DVec3>) {
        let mut m = Moments {
            time_s,
            ..Moments::default()
        };
        for d in displacements {
            if !d.is_finite() {
                continue;
            }
            m.n += 1.0;
            m.x += d.x;
            m.z += d.z;
            m.xx += d.x * d.x;
            m.xz += d.x * d.z;
            m.zz += d.z * d.z;
        }
        if self.window_s.is_infinite() {
            self.total.add(&m);
            self.total.time_s = time_s;
            return;
        }
        self.frames.push_back(m);
        while self
            .frames
            .front()
            .is_some_and(|f| time_s - f.time_s > self.window_s)
        {
            self.frames.pop_front();
        }
    }

    /// The downwind direction over the window, or `None` while the tree is
    /// still or the window is empty.
    pub fn estimate(&self) -> Option<WindEstimate> {
        let mut s = self.total;
        for f in &self.frames {
            s.add(f);
        }
        let last_time = self.frames.back().map_or(self.total.time_s, |f| f.time_s);
        if s.n < 2.0 {
            return None;
        }
        let (mx, mz) = (s.x / s.n, s.z / s.n);
        let cxx = s.xx / s.n - mx * mx;
        let cxz = s.xz / s.n - mx * mz;
        let czz = s.zz / s.n - mz * mz;
        if (cxx + czz).max(0.0).sqrt() < self.min_sway_m {
            return None;
        }
        // Principal axis of the 2×2 covariance [[cxx, cxz], [cxz, czz]].
        let theta = 0.5 * (2.0 * cxz).atan2(cxx - czz);
        let mut axis = DVec3::new(theta.cos(), 0.0, theta.sin());
        if axis.x * mx + axis.z * mz < 0.0 {
            axis = -axis;
        }
        Some(WindEstimate {
            time_s: last_time,
            source: WindSource::Pca,
            direction: axis,
            speed_m_s: None,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::wind::{angle_between_deg, direction_of};
    use crate::rng::Rng;

    #[test]
    fn finds_the_sway_axis_with_the_downwind_sign() {
        let mut rng = Rng::new(3);
        for az in [0.0, 37.0, 135.0, 200.0, 300.0] {
            let wind = direction_of(az);
            let cross = DVec3::Y.cross(wind);
            let mut pca = SwayPca::new(5.0, 0.001);
            for k in 0..500 {
                let t = k as f64 * 0.01;
                let d = (0..30).map(|i| {
                    let phase = i as f64;
                    let along = 0.01 + 0.02 * (t * 6.0 + phase).sin();
                    let across = 0.005 * (t * 9.0 + phase).cos();
                    wind * along + cross * across + DVec3::splat(rng.normal() * 2e-4)
                });
                pca.push(t, d);
            }
            let e = pca.estimate().unwrap();
            assert!(
                angle_between_deg(e.direction, wind) < 2.0,
                "{az}: {}",
                e.azimuth_deg()
            );
        }
    }

    #[test]
    fn still_tree_gives_no_estimate_and_window_slides() {
        let mut pca = SwayPca::new(1.0, 0.001);
        for k in 0..100 {
            pca.push(k as f64 * 0.01, [DVec3::splat(1e-5)]);
        }
        assert!(pca.estimate().is_none());
        for k in 100..300 {
            pca.push(k as f64 * 0.01, [DVec3::ZERO]);
        }
        assert!(pca.frames.len() <= 101);
    }

    #[test]
    fn an_infinite_window_keeps_sums_not_samples_and_agrees_with_a_long_one() {
        let wind = direction_of(120.0);
        let mut whole = SwayPca::new(f64::INFINITY, 0.001);
        let mut long = SwayPca::new(1e9, 0.001);
        for k in 0..20_000 {
            let t = k as f64 * 0.01;
            let d = [wind * (0.01 + 0.02 * (t * 3.0).sin()) + DVec3::Z * 0.003 * t.cos()];
            whole.push(t, d);
            long.push(t, d);
        }
        assert!(whole.frames.is_empty(), "no per-sample memory");
        let (a, b) = (whole.estimate().unwrap(), long.estimate().unwrap());
        assert!(angle_between_deg(a.direction, b.direction) < 1e-9);
        assert_eq!(a.time_s, b.time_s);
        assert!(angle_between_deg(a.direction, wind) < 5.0);
    }
}
