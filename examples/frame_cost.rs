//! What one frame costs the live tracker, frame by frame, with the window
//! full: the daemon scale runs' session (`examples/common/steady_session.rs`:
//! still for a minute, then swaying) fed to the daemon's live tips
//! (`track::live::LiveTips`, the tracker in live mode) with a tree of all the
//! markers, as `treemocap run` does after its first tree. Prints the
//! percentiles of the per-frame cost over the swaying part, the frames
//! that daemon's latency p99 is made of.
//!
//! `cargo run --release --example frame_cost [SECONDS] [RATE] [MARKERS]`
//! (defaults: 90 s at 360 Hz with 1 000 markers).

use std::time::Instant;

use glam::DVec3;
use treemocap::track::live::LiveTips;
use treemocap::track::TrackingSettings;

#[path = "common/steady_session.rs"]
mod steady_session;

fn main() {
    let args: Vec<f64> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let seconds = args.first().copied().unwrap_or(90.0);
    let rate = args.get(1).copied().unwrap_or(360.0);
    let n = args.get(2).copied().unwrap_or(1000.0) as usize;
    let session = steady_session::Session::new(seconds, rate, n);
    let rest: Vec<(usize, DVec3)> = session.rest_positions().into_iter().enumerate().collect();
    let mut live = LiveTips::new(&TrackingSettings::default(), None, 0.05);
    live.set_tips(&rest);
    let mut costs = Vec::new();
    let mut seen_total = 0usize;
    for frame in session {
        let frame = frame.expect("generated frame");
        let t0 = Instant::now();
        let seen = live.update(&frame);
        let us = t0.elapsed().as_secs_f64() * 1e6;
        if frame.time_s >= 63.0 {
            costs.push(us);
            seen_total += seen.tips.len();
        }
    }
    costs.sort_by(f64::total_cmp);
    let q = |p: f64| costs[((costs.len() - 1) as f64 * p).round() as usize];
    println!(
        "{} frames at {rate} Hz × {n} markers, swaying: per frame p50 {:.0} µs, p90 {:.0}, p99 {:.0}, p99.9 {:.0}, max {:.0}; {:.1} tips seen a frame",
        costs.len(),
        q(0.5),
        q(0.9),
        q(0.99),
        q(0.999),
        q(1.0),
        seen_total as f64 / costs.len().max(1) as f64
    );
}
