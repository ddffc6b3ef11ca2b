//! The tracker's cost on pathological input: 2 000 markers a frame at
//! random places (every one a ghost), 50 and 300 frames through the whole
//! marker stage (track, then join, clean, fill and average). The target is
//! a cost bounded by the frame's markers and the live traces, not by the
//! history: 300 frames at most 300/50 × the cost of 50.

use glam::DVec3;
use treemocap::rng::Rng;
use treemocap::track::{clean, Tracker, TrackingSettings};
use treemocap::{Marker, MarkerFrame};

use crate::util::{best_of, timed, Row, Scale};

/// Seconds the whole marker stage takes on `frames` frames of `n` random markers.
fn stage_seconds(frames: usize, n: usize) -> f64 {
    let rate = 100.0;
    let cfg = TrackingSettings::default();
    let mut rng = Rng::new(15);
    let input: Vec<MarkerFrame> = (0..frames)
        .map(|f| {
            let markers = (0..n)
                .map(|_| {
                    Marker::new(DVec3::new(
                        rng.range(-2.0, 2.0),
                        rng.range(0.0, 4.0),
                        rng.range(-2.0, 2.0),
                    ))
                })
                .collect();
            MarkerFrame::new(f as i64, f as f64 / rate, markers)
        })
        .collect();
    let (_, s) = timed(|| {
        let mut tracker = Tracker::new(&cfg, Some(rate));
        for frame in &input {
            tracker.push(frame);
        }
        clean(tracker.finish(), &cfg, "random", rate)
    });
    s
}

/// The history row: 50 and 300 frames of 2 000 random markers.
pub fn growth(scale: &Scale) -> Vec<Row> {
    let n = 2000;
    let long = if scale.quick { 150 } else { 300 };
    let short_s = best_of(2, || stage_seconds(50, n));
    let long_s = best_of(2, || stage_seconds(long, n));
    let ratio = long_s / short_s;
    let allowed = long as f64 / 50.0;
    println!("tracker history: {n} random markers, 50 frames {short_s:.2} s, {long} frames {long_s:.2} s");
    vec![Row::new(
        format!("marker stage on {n} random markers a frame, 50 vs {long} frames"),
        &format!("≤ {allowed:.0} × the cost of 50 frames"),
        format!(
            "{short_s:.2} s vs {long_s:.2} s = {ratio:.1} × ({})",
            if ratio <= allowed { "met" } else { "not met" }
        ),
        "—".into(),
    )]
}
