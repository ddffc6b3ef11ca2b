//! Speed of the marker stage (issue 3 targets): tracking per frame with 35
//! and 1000 markers (≤ 20 µs and ≤ 1 ms), and the whole stage on the
//! shipped replays/pine-35.csv (< 100 ms).

use std::hint::black_box;
use std::path::Path;

use criterion::{criterion_group, criterion_main, Criterion};
use glam::DVec3;
use treemocap::config::Config;
use treemocap::rng::Rng;
use treemocap::track::Tracker;
use treemocap::track::TrackingSettings;
use treemocap::{Marker, MarkerFrame};

/// Marker rest positions on a jittered grid 100 mm apart, and per-marker
/// sway phases: a steady state like a crown in wind.
fn markers(n: usize, seed: u64) -> (Vec<DVec3>, Vec<f64>) {
    let mut rng = Rng::new(seed);
    let side = (n as f64).cbrt().ceil() as usize;
    let mut rest = Vec::with_capacity(n);
    let mut phase = Vec::with_capacity(n);
    for i in 0..n {
        let (x, y, z) = (i % side, (i / side) % side, i / (side * side));
        rest.push(
            DVec3::new(x as f64, y as f64 + 10.0, z as f64) * 0.1
                + DVec3::new(
                    rng.range(-0.01, 0.01),
                    rng.range(-0.01, 0.01),
                    rng.range(-0.01, 0.01),
                ),
        );
        phase.push(rng.range(0.0, std::f64::consts::TAU));
    }
    (rest, phase)
}

fn bench_per_frame(c: &mut Criterion, n: usize, name: &str) {
    let (rest, phase) = markers(n, n as u64);
    let cfg = TrackingSettings::default();
    let mut rng = Rng::new(9);
    // 1000 precomputed frames of sway + noise, in shuffled marker order.
    let frames: Vec<Vec<Marker>> = (0..1000)
        .map(|f| {
            let t = f as f64 / 100.0;
            let mut m: Vec<Marker> = rest
                .iter()
                .zip(&phase)
                .map(|(r, ph)| {
                    Marker::new(
                        *r + DVec3::new(
                            0.02 * (1.3 * t + ph).sin(),
                            0.0,
                            0.01 * (0.9 * t + ph).cos(),
                        ) + DVec3::new(rng.normal(), rng.normal(), rng.normal()) * 0.0002,
                    )
                })
                .collect();
            for i in (1..m.len()).rev() {
                let j = rng.int(0, i as i64) as usize;
                m.swap(i, j);
            }
            m
        })
        .collect();
    c.bench_function(name, |b| {
        let mut tracker = Tracker::new(&cfg, Some(100.0));
        let mut frame = MarkerFrame::new(0, 0.0, Vec::new());
        let mut k: i64 = 0;
        b.iter(|| {
            frame.frame = k;
            frame.time_s = k as f64 / 100.0;
            // Forward then backward through the frames, so the motion stays
            // continuous (no jump back to the first frame).
            let i = (k % 2000) as usize;
            let i = if i < 1000 { i } else { 1999 - i };
            frame.markers.clone_from(&frames[i]);
            tracker.push(black_box(&frame));
            k += 1;
        });
        black_box(tracker.stats().traces_started);
    });
}

fn tracking(c: &mut Criterion) {
    bench_per_frame(c, 35, "track frame, 35 markers");
    bench_per_frame(c, 1000, "track frame, 1000 markers");
}

fn whole_stage(c: &mut Criterion) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("replays/pine-35.csv");
    let config = Config::default();
    c.bench_function("tips stage on replays/pine-35.csv", |b| {
        b.iter(|| {
            let mut rec = treemocap::app::open::open_with(
                &path,
                &treemocap::app::open::ReplayOptions::from_config(&config),
            )
            .unwrap();
            let (tips, _) = treemocap::track::process(rec.as_mut(), &config.tracking).unwrap();
            assert_eq!(tips.tips.len(), 35);
            black_box(tips)
        });
    });
}

/// The stage's parts on pine-35, to see where its time goes: reading and
/// tracking, the clean-up after the tracker (joining, noise, gap fill,
/// rest), and gap filling alone (on the final traces, whose measured
/// samples leave the same gaps).
fn stage_parts(c: &mut Criterion) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("replays/pine-35.csv");
    let config = Config::default();
    let cfg = &config.tracking;
    let open = || {
        treemocap::app::open::open_with(
            &path,
            &treemocap::app::open::ReplayOptions::from_config(&config),
        )
        .unwrap()
    };
    let track = || {
        let mut rec = open();
        let rate = rec.info().frame_rate;
        let mut tracker = Tracker::new(cfg, Some(rate));
        for frame in &mut *rec {
            tracker.push(&frame.unwrap());
        }
        (tracker.finish(), rate)
    };
    c.bench_function("pine-35: read + track", |b| b.iter(|| black_box(track())));
    let (tracked, rate) = track();
    c.bench_function("pine-35: clean (join, noise, fill, rest)", |b| {
        b.iter(|| black_box(treemocap::track::clean(tracked.clone(), cfg, "b", rate)))
    });
    let (tips, _) = treemocap::track::clean(tracked, cfg, "b", rate);
    let traces: Vec<_> = tips.tips.iter().map(|t| t.trace.clone()).collect();
    let settings = treemocap::track::gaps::GapSettings {
        max_fill_s: cfg.max_fill_s,
        max_pchip_s: cfg.max_pchip_s,
        neighbours: true,
    };
    c.bench_function("pine-35: gap fill", |b| {
        b.iter(|| {
            let mut t = traces.clone();
            black_box(treemocap::track::gaps::fill_gaps(
                &mut t,
                &tips.timeline,
                settings,
            ))
        })
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20);
    targets = tracking, whole_stage, stage_parts
}
criterion_main!(benches);
