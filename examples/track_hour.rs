//! Memory check for issue 3: a 1-hour session at 240 Hz with 70 markers
//! (60 million marker samples, generated on the fly so the frames are never
//! all in memory) through the tracker and the whole cleaning stage.
//!
//! Run with: `cargo run --release --example track_hour` under
//! `/usr/bin/time -v` and read "Maximum resident set size".
//! Optional arguments: seconds (default 3600), rate (240), markers (70).

use glam::DVec3;
use treemocap::config::TrackingConfig;
use treemocap::rng::Rng;
use treemocap::track::{self, Tracker};
use treemocap::{Marker, MarkerFrame};

fn main() {
    let args: Vec<f64> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let seconds = args.first().copied().unwrap_or(3600.0);
    let rate = args.get(1).copied().unwrap_or(240.0);
    let n = args.get(2).copied().unwrap_or(70.0) as usize;
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
    let cfg = TrackingConfig::default();
    let mut tracker = Tracker::new(&cfg, Some(rate));
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
        tracker.push(&frame);
    }
    let trace_bytes: usize = tracker.traces().iter().map(|t| t.heap_bytes()).sum();
    let samples: u64 = tracker.stats().markers;
    println!(
        "tracked {frames} frames, {samples} marker samples, {} traces; traces use {:.1} MB ({:.2} bytes/sample)",
        tracker.traces().len(),
        trace_bytes as f64 / 1e6,
        trace_bytes as f64 / samples.max(1) as f64
    );
    let started = std::time::Instant::now();
    let (tips, summary) = track::clean(tracker.finish(), &cfg, "track_hour", rate);
    println!("cleaned in {:.1} s", started.elapsed().as_secs_f64());
    println!("{summary}");
    assert_eq!(tips.tips.len(), n, "tips found");
}
