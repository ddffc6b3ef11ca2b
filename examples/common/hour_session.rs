//! A synthetic session of any length, generated frame by frame so that it
//! never sits in memory: markers on a jittered shell, still for a minute,
//! then swaying; about 5 % of samples lost in bursts of 1–50 frames and a
//! spurious reflection every two seconds. Shared by the long-run examples.

use glam::DVec3;
use treemocap::rng::Rng;
use treemocap::{Marker, MarkerFrame};

/// `[seconds] [rate] [markers]` from the command line; defaults: one hour at
/// 240 Hz with 70 markers.
pub fn args() -> (f64, f64, usize) {
    let args: Vec<f64> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    (
        args.first().copied().unwrap_or(3600.0),
        args.get(1).copied().unwrap_or(240.0),
        args.get(2).copied().unwrap_or(70.0) as usize,
    )
}

/// Calls `each` with every frame of a `seconds`-long session at `rate` Hz
/// with `n` markers (the same frame buffer, refilled).
pub fn for_each_frame(seconds: f64, rate: f64, n: usize, mut each: impl FnMut(&MarkerFrame)) {
    let frames = (seconds * rate) as i64;
    let still = (60.0 * rate) as i64;
    let mut rng = Rng::new(42);
    // Markers 120 mm apart on a jittered shell; each sways with its own
    // frequency and phase once the wind starts after one minute.
    let markers: Vec<(DVec3, f64, f64)> = (0..n)
        .map(|i| {
            let a = i as f64 * 2.399_963;
            let h = 1.0 + (i as f64 / n as f64) * 1.5;
            let r = 0.6 + 0.05 * rng.f64();
            (
                DVec3::new(r * a.cos(), h, r * a.sin()),
                rng.range(0.5, 2.0),
                rng.range(0.0, 6.3),
            )
        })
        .collect();
    let mut hidden = vec![0i64; n];
    let mut spurious: Vec<(DVec3, i64)> = Vec::new();
    let mut frame = MarkerFrame::new(0, 0.0, Vec::with_capacity(n + 4));
    for f in 0..frames {
        let t = f as f64 / rate;
        let wind = if f < still { 0.0 } else { 1.0 };
        frame.frame = f;
        frame.time_s = t;
        frame.markers.clear();
        for (k, (rest, freq, ph)) in markers.iter().enumerate() {
            // About 5 % of samples lost in bursts of 1–50 frames.
            if hidden[k] > 0 {
                hidden[k] -= 1;
                continue;
            }
            if rng.chance(0.002) {
                hidden[k] = rng.int(1, 50);
                continue;
            }
            let sway = DVec3::new(
                0.03 * (freq * t + ph).sin(),
                0.0,
                0.01 * (1.7 * freq * t).cos(),
            );
            let noise = DVec3::new(rng.normal(), rng.normal(), rng.normal()) * 0.0002;
            frame.markers.push(Marker::new(*rest + sway * wind + noise));
        }
        // Spurious reflections: about one every two seconds, 1–50 frames.
        if rng.chance(0.5 / rate) {
            let p = DVec3::new(
                rng.range(-1.0, 1.0),
                rng.range(0.5, 3.0),
                rng.range(-1.0, 1.0),
            );
            spurious.push((p, rng.int(1, 50)));
        }
        spurious.retain_mut(|s| {
            s.1 -= 1;
            s.1 >= 0
        });
        for s in &spurious {
            frame.markers.push(Marker::new(s.0));
        }
        each(&frame);
    }
}
