//! The captured motion on the tree (issue 13): one frame's deformation for
//! 35 captured tips on a ~560-node tree (maple-24's has 557; target
//! < 50 µs) and on a ~50 000-node tree (< 1 ms), and writing the animation
//! of the 40 s maple-24 session (motion + skinned, animated glb; target
//! < 1 s).
//!
//! `cargo bench --bench animate` (criterion ids
//! `deform_one_frame/nodes/N` and `write_animation/maple_24_40s_30hz`).

use std::hint::black_box;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use glam::DVec3;
use treemocap::animate::{animate, AnimateSettings, Deformer, Rig, TipInput};
use treemocap::app::open::open_recording;
use treemocap::config::Config;
use treemocap::model::motion::TipSource;
use treemocap::reconstruct::{mesh, reconstruct, ReconstructSettings};
use treemocap::render::gltf::{to_glb, Movement};

#[path = "../tests/it/common/crowns.rs"]
mod crowns;

/// Sways every captured tip by a few centimetres, each with its own phase.
fn inputs(n: usize, t: f64) -> Vec<TipInput> {
    (0..n)
        .map(|i| {
            let phase = i as f64 * 0.7;
            TipInput::Tracked(
                DVec3::new(
                    0.03 * (t + phase).sin(),
                    -0.002,
                    0.01 * (1.3 * t + phase).cos(),
                ),
                TipSource::Measured,
            )
        })
        .collect()
}

fn deform(c: &mut Criterion) {
    let mut group = c.benchmark_group("deform_one_frame");
    group.measurement_time(Duration::from_secs(4));
    // Total tips (captured + random) chosen for ~560 and ~50 000 nodes.
    for (captured, total) in [(35usize, 140usize), (35, 47_500)] {
        let tips = crowns::crown_tips(crowns::Shape::Pine, captured, 1);
        let cfg = ReconstructSettings {
            total_tips: total,
            ..Default::default()
        };
        let tree = reconstruct(&tips, DVec3::new(2.0, 0.0, 0.0), &cfg, cfg.seed).expect("tree");
        let rig = Rig::new(&tree, &AnimateSettings::default()).expect("rig");
        eprintln!(
            "{captured} captured + {total} tips: {} nodes",
            tree.nodes.len()
        );
        let mut deformer = Deformer::new(&rig);
        let (mut out, mut sources) = (Vec::new(), Vec::new());
        let frames: Vec<Vec<TipInput>> =
            (0..64).map(|f| inputs(captured, f as f64 * 0.01)).collect();
        let mut f = 0;
        group.bench_function(BenchmarkId::new("nodes", tree.nodes.len()), |b| {
            b.iter(|| {
                f = (f + 1) % frames.len();
                deformer.deform(&rig, &frames[f], &mut out, &mut sources);
                black_box(out[out.len() - 1])
            })
        });
    }
    group.finish();
}

fn write_animation(c: &mut Criterion) {
    let config = Config::default();
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut rec = open_recording(&root.join("replays/maple-24.csv"), &config).expect("replay");
    let (tips, _) = treemocap::track::process(rec.as_mut(), &config.tracking).expect("tips");
    let cfg = &config.reconstruct;
    let tree = reconstruct(&tips.captured(), DVec3::ZERO, cfg, cfg.seed).expect("tree");
    let branches = mesh::branches(&tree, cfg.sides).expect("mesh");
    let settings = AnimateSettings::default();
    let write = || {
        let motion = animate(&tree, &tips, &settings).expect("motion");
        to_glb(&tree, &branches, None, Movement::Animated(&motion)).expect("glb")
    };
    let bytes = write();
    eprintln!(
        "maple-24: {} nodes, animated tree.glb {} bytes ({:.2} MB)",
        tree.nodes.len(),
        bytes.len(),
        bytes.len() as f64 / 1e6
    );
    let mut group = c.benchmark_group("write_animation");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(6));
    group.bench_function("maple_24_40s_30hz", |b| b.iter(|| black_box(write().len())));
    group.finish();
}

criterion_group!(benches, deform, write_animation);
criterion_main!(benches);
