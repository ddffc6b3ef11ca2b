//! The motion model of one trace: a constant-acceleration Kalman filter
//! (ours; the paper's forward differencing, `p̂ = 2p(M−1) − p(M−2)`, is the
//! same model without the smoothing and without an uncertainty).
//!
//! A tip in the wind swings like a pendulum: its velocity changes every
//! frame, and by more the stronger the wind. The filter keeps position,
//! velocity and acceleration and, above all, how uncertain its prediction
//! is: after a miss, or while the tree sways hard, the prediction is less
//! sure and the gate around it grows; at rest it shrinks to a few times
//! the measurement noise, so a ghost or a neighbour passing close is not
//! taken. The three axes share one covariance (the noise of a mocap system
//! is about isotropic), so the filter costs a few dozen multiplications.
//!
//! How hard the marker is being shaken is learnt on line: the process
//! noise (white jerk) is scaled up when the normalised innovations run
//! above 1 and down when below, so one filter serves a still tree and a
//! gale alike.

use glam::DVec3;

/// State and covariance of one trace's filter. Units: metres and frames.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Motion {
    /// Position, velocity (m/frame), acceleration (m/frame²) at `t`.
    p: DVec3,
    v: DVec3,
    a: DVec3,
    /// Symmetric 3 × 3 covariance of (p, v, a), shared by the axes.
    cov: [[f64; 3]; 3],
    /// Frame of the state.
    t: i64,
    /// Spectral density of the white jerk (m²/frame⁵), adapted on line.
    q: f64,
    /// Average squared innovation per axis (m²): the spread actually seen,
    /// a floor under the predicted one (real noise may exceed `noise_mm`).
    iv: f64,
}

/// Fixed parameters of the filters, from the tracker's settings and rate.
#[derive(Debug, Clone, Copy)]
pub(crate) struct MotionParams {
    /// Measurement noise variance per axis (m²).
    pub(crate) r: f64,
    /// Prior variance of a new trace's velocity and acceleration.
    pub(crate) v0: f64,
    pub(crate) a0: f64,
    /// Range and start of the process noise.
    pub(crate) q_min: f64,
    pub(crate) q_max: f64,
    pub(crate) q0: f64,
}

impl MotionParams {
    /// `noise_m`: measurement noise σ; `dt`: frame interval (s).
    pub(crate) fn new(noise_m: f64, dt: f64) -> Self {
        // A tip moves at most a few m/s and a few g; jerk from 0.05 m/s³
        // (a still tree's wobble) to 5 000 m/s³ (a twig snapping back).
        let per_frame = |jerk: f64| (jerk * dt.powi(3)).powi(2);
        MotionParams {
            r: noise_m * noise_m,
            v0: (3.0 * dt).powi(2),
            a0: (60.0 * dt * dt).powi(2),
            q_min: per_frame(0.05),
            q_max: per_frame(5000.0),
            q0: per_frame(50.0),
        }
    }
}

impl Motion {
    /// A new trace first seen at `p` in frame `t`.
    pub(crate) fn new(p: DVec3, t: i64, m: &MotionParams) -> Self {
        Motion {
            p,
            v: DVec3::ZERO,
            a: DVec3::ZERO,
            cov: [[m.r, 0.0, 0.0], [0.0, m.v0, 0.0], [0.0, 0.0, m.a0]],
            t,
            q: m.q0,
            iv: m.r,
        }
    }

    /// Frame of the last update.
    pub(crate) fn t(&self) -> i64 {
        self.t
    }

    /// Predicted position at frame `t` and its variance per axis,
    /// measurement noise included (the innovation variance S).
    pub(crate) fn predict(&self, t: i64, m: &MotionParams) -> (DVec3, f64) {
        let k = (t - self.t).max(0) as f64;
        let p = self.p + self.v * k + self.a * (0.5 * k * k);
        let c = &self.cov;
        // (F P Fᵀ)₀₀ with F's first row (1, k, k²/2), plus Q₀₀.
        let f = [1.0, k, 0.5 * k * k];
        let mut s = 0.0;
        for i in 0..3 {
            for j in 0..3 {
                s += f[i] * c[i][j] * f[j];
            }
        }
        s += self.q * k.powi(5) / 20.0;
        (p, (s + m.r).max(self.iv))
    }

    /// Takes the measurement `z` at frame `t` (after `t − self.t` frames).
    pub(crate) fn update(&mut self, z: DVec3, t: i64, m: &MotionParams) {
        let k = (t - self.t).max(1) as f64;
        // Predict the state and the covariance: P' = F P Fᵀ + Q.
        let f = [[1.0, k, 0.5 * k * k], [0.0, 1.0, k], [0.0, 0.0, 1.0]];
        let c = self.cov;
        let mut fp = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                fp[i][j] = (0..3).map(|l| f[i][l] * c[l][j]).sum();
            }
        }
        let mut pp = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                pp[i][j] = (0..3).map(|l| fp[i][l] * f[j][l]).sum();
            }
        }
        let q = self.q;
        let (k2, k3, k4, k5) = (k * k, k.powi(3), k.powi(4), k.powi(5));
        let qm = [
            [k5 / 20.0, k4 / 8.0, k3 / 6.0],
            [k4 / 8.0, k3 / 3.0, k2 / 2.0],
            [k3 / 6.0, k2 / 2.0, k],
        ];
        for i in 0..3 {
            for j in 0..3 {
                pp[i][j] += q * qm[i][j];
            }
        }
        let p = self.p + self.v * k + self.a * (0.5 * k2);
        let v = self.v + self.a * k;
        let s = pp[0][0] + m.r;
        let y = z - p;
        let gain = [pp[0][0] / s, pp[1][0] / s, pp[2][0] / s];
        self.p = p + y * gain[0];
        self.v = v + y * gain[1];
        self.a += y * gain[2];
        for (i, row) in self.cov.iter_mut().enumerate() {
            for (j, c) in row.iter_mut().enumerate() {
                *c = pp[i][j] - gain[i] * pp[0][j];
            }
        }
        self.t = t;
        // Normalised innovation (mean 1 when the model fits): scale the
        // process noise towards the motion actually seen.
        let nis = y.length_squared() / (3.0 * s);
        self.iv = 0.95 * self.iv + 0.05 * y.length_squared() / 3.0;
        self.q = (self.q * (0.15 * (nis.min(9.0) - 1.0)).exp()).clamp(m.q_min, m.q_max);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn follows_a_fast_sway_closer_than_forward_differencing() {
        // 150 mm at 1.5 Hz sampled at 240 Hz with 1 mm noise.
        let dt = 1.0 / 240.0;
        let m = MotionParams::new(0.001, dt);
        let mut rng = crate::rng::Rng::new(5);
        let truth = |n: i64| {
            let t = n as f64 * dt;
            DVec3::new(0.15 * (9.42 * t).sin(), 1.0, 0.05 * (4.0 * t).cos())
        };
        let noisy = |n: i64, rng: &mut crate::rng::Rng| {
            truth(n) + DVec3::new(rng.normal(), rng.normal(), rng.normal()) * 0.001
        };
        let mut f = Motion::new(noisy(0, &mut rng), 0, &m);
        let (mut prev2, mut prev1) = (noisy(0, &mut rng), noisy(1, &mut rng));
        let (mut kf_err, mut fd_err, mut inside) = (0.0, 0.0, 0);
        for n in 1..2000 {
            let z = noisy(n, &mut rng);
            if n > 100 {
                let (p, s) = f.predict(n, &m);
                kf_err += p.distance(truth(n));
                fd_err += (prev1 * 2.0 - prev2).distance(truth(n));
                if z.distance(p) <= 5.0 * s.sqrt() {
                    inside += 1;
                }
            }
            f.update(z, n, &m);
            prev2 = prev1;
            prev1 = z;
        }
        assert!(kf_err < 0.6 * fd_err, "{kf_err} vs {fd_err}");
        // The gate (5 σ of the prediction) holds the marker almost always.
        assert!(inside >= 1895, "{inside}");
    }

    #[test]
    fn uncertainty_grows_across_a_gap_and_shrinks_at_rest() {
        let m = MotionParams::new(0.0005, 0.01);
        let mut f = Motion::new(DVec3::ZERO, 0, &m);
        for n in 1..300 {
            f.update(DVec3::ZERO, n, &m);
        }
        let (_, s1) = f.predict(300, &m);
        let (_, s20) = f.predict(320, &m);
        assert!(s1.sqrt() < 0.001, "{}", s1.sqrt());
        assert!(s20 > s1);
    }
}
