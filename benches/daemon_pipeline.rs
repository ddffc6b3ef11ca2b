//! The daemon's per-frame work at Motive's widest (issue 15): storing a
//! frame of 1 000 markers in the analysis window, handing the window to the
//! analysis (must cost the same for 1 s and 60 s of frames: no copy), and
//! following 1 000 tips among 1 000 markers (target: well under the 2.8 ms
//! a frame lasts at 360 Hz, for a p99 frame-to-tips latency under 1 ms).

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use glam::DVec3;
use treemocap::config::Config;
use treemocap::daemon::window::FrameWindow;
use treemocap::rng::Rng;
use treemocap::track::live::LiveTips;
use treemocap::{Marker, MarkerFrame};

fn markers(rng: &mut Rng, n: usize) -> Vec<DVec3> {
    (0..n)
        .map(|_| {
            DVec3::new(
                rng.range(-1.0, 1.0),
                rng.range(0.5, 3.0),
                rng.range(-1.0, 1.0),
            )
        })
        .collect()
}

fn window(c: &mut Criterion) {
    let mut rng = Rng::new(1);
    let frame = MarkerFrame::new(
        0,
        0.0,
        markers(&mut rng, 1000)
            .into_iter()
            .map(Marker::new)
            .collect(),
    );
    let mut g = c.benchmark_group("window_360hz_1000_markers");
    g.bench_function("push", |b| {
        let mut w = FrameWindow::new(60.0);
        let mut f = frame.clone();
        b.iter(|| {
            f.frame += 1;
            f.time_s += 1.0 / 360.0;
            w.push(black_box(&f));
        })
    });
    for seconds in [1.0, 60.0] {
        let mut w = FrameWindow::new(60.0);
        let mut f = frame.clone();
        for _ in 0..(seconds * 360.0) as usize {
            f.frame += 1;
            f.time_s += 1.0 / 360.0;
            w.push(&f);
        }
        g.bench_with_input(
            BenchmarkId::new("snapshot", format!("{seconds}s")),
            &seconds,
            |b, _| b.iter(|| black_box(w.snapshot())),
        );
    }
    g.finish();
}

fn follower(c: &mut Criterion) {
    let mut rng = Rng::new(2);
    let tips: Vec<(usize, DVec3)> = markers(&mut rng, 1000).into_iter().enumerate().collect();
    // 100 frames of the tips jittered by 5 mm, played in a loop at 360 Hz:
    // the live tracker (the same one a replay runs) labels them with the tips.
    let frames: Vec<Vec<Marker>> = (0..100)
        .map(|_| {
            tips.iter()
                .map(|t| {
                    Marker::new(t.1 + DVec3::new(rng.normal(), rng.normal(), rng.normal()) * 0.005)
                })
                .collect()
        })
        .collect();
    let mut f = LiveTips::new(&Config::default().tracking, Some(360.0), 0.06);
    f.set_tips(&tips);
    let mut n = 0i64;
    c.bench_function("follow_1000_tips_1000_markers", |b| {
        b.iter(|| {
            let markers = frames[n as usize % frames.len()].clone();
            let frame = MarkerFrame::new(n, n as f64 / 360.0, markers);
            n += 1;
            black_box(f.update(black_box(&frame)))
        })
    });
}

criterion_group!(benches, window, follower);
criterion_main!(benches);
