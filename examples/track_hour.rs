//! Memory check for issue 3: a 1-hour session at 240 Hz with 70 markers
//! (60 million marker samples, generated on the fly so the frames are never
//! all in memory) through the tracker and the whole cleaning stage.
//!
//! Run with: `cargo run --release --example track_hour` under
//! `/usr/bin/time -v` and read "Maximum resident set size".
//! Optional arguments: seconds (default 3600), rate (240), markers (70).

#[path = "common/hour_session.rs"]
mod hour_session;

use treemocap::track::TrackingSettings;
use treemocap::track::{self, Tracker};

fn main() {
    let (seconds, rate, n) = hour_session::args();
    let frames = (seconds * rate) as i64;
    let cfg = TrackingSettings::default();
    let mut tracker = Tracker::new(&cfg, Some(rate));
    hour_session::for_each_frame(seconds, rate, n, |frame| tracker.push(frame));
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
