//! Reading C3D point data: open a file and stream every frame through
//! `replay::open`, as `replay` and `tips` do. Target: ≥ 5 million point
//! samples per second (one sample = one point in one frame).

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use treemocap::app::open as replay;
use treemocap::format::c3d::encode::{encode, Sample, WriteSpec};
use treemocap::format::c3d::Processor;

const POINTS: usize = 70;
const FRAMES: usize = 12_000;

fn spec(processor: Processor, float: bool) -> WriteSpec {
    let frames = (0..FRAMES)
        .map(|f| {
            (0..POINTS)
                .map(|i| Sample {
                    position: [i as f64 * 10.0, 1500.0 + (f % 100) as f64, -(i as f64)],
                    // One point in 20 missing, like occlusions in a real take.
                    residual: if (f + i) % 20 == 0 { -1.0 } else { 3.0 },
                })
                .collect()
        })
        .collect();
    WriteSpec {
        processor,
        float,
        scale: 0.1,
        labels: (0..POINTS).map(|i| format!("Tip{i}")).collect(),
        analog_channels: 4,
        analog_per_channel: 10,
        frames,
        ..Default::default()
    }
}

fn bench(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let mut group = c.benchmark_group("c3d_read");
    group.throughput(Throughput::Elements((POINTS * FRAMES) as u64));
    group.sample_size(10);
    for (name, processor, float) in [
        ("intel_int16", Processor::Intel, false),
        ("intel_float32", Processor::Intel, true),
        ("dec_float32", Processor::Dec, true),
        ("mips_int16", Processor::Mips, false),
    ] {
        let path = dir.path().join(format!("{name}.c3d"));
        std::fs::write(&path, encode(&spec(processor, float))).unwrap();
        group.bench_function(name, |b| {
            b.iter(|| {
                let rec = replay::open(&path).unwrap();
                let mut markers = 0usize;
                for f in rec {
                    markers += f.unwrap().markers.len();
                }
                assert!(markers > 0);
                markers
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
