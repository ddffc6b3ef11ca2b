//! Where the time of the tips stage goes on one recording: reading,
//! tracking, cleaning. `cargo run --release --example stage_timing FILE
//! [N]`: with N, cleans N times (the time printed is the mean), for a
//! profiler to see the clean step (`perf record --call-graph dwarf`).

use std::time::Instant;

use treemocap::config::Config;
use treemocap::track::{self, Tracker};

fn main() {
    let path = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "replays/pine-35.csv".into());
    let path = std::path::Path::new(&path);
    let config = Config::default();
    let t0 = Instant::now();
    let frames: Vec<_> = treemocap::app::open::open_with(
        path,
        &treemocap::app::open::ReplayOptions::from_config(&config),
    )
    .and_then(|rec| rec.collect::<treemocap::Result<Vec<_>>>())
    .unwrap_or_else(|e| panic!("{e}"));
    let read = t0.elapsed();
    let t1 = Instant::now();
    let mut tracker = Tracker::new(&config.tracking, Some(100.0));
    for f in &frames {
        tracker.push(f);
    }
    let tracked = tracker.finish();
    let track_time = t1.elapsed();
    let repeat: u32 = std::env::args()
        .nth(2)
        .and_then(|n| n.parse().ok())
        .unwrap_or(1)
        .max(1);
    let t2 = Instant::now();
    for _ in 1..repeat {
        std::hint::black_box(track::clean(tracked.clone(), &config.tracking, "x", 100.0));
    }
    let (tips, _) = track::clean(tracked, &config.tracking, "x", 100.0);
    let clean = t2.elapsed() / repeat;
    println!(
        "{} frames: read {:.1} ms, track {:.1} ms ({:.1} µs/frame), clean {:.1} ms, {} tips",
        frames.len(),
        read.as_secs_f64() * 1e3,
        track_time.as_secs_f64() * 1e3,
        track_time.as_secs_f64() * 1e6 / frames.len() as f64,
        clean.as_secs_f64() * 1e3,
        tips.tips.len()
    );
}
