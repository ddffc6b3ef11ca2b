//! Reconstruction speed: flow + radii + mesh for the paper's tree sizes
//! (35 captured + 500 total tips: target < 20 ms; 70 + 5000: < 500 ms), and
//! how the time grows from 500 to 50 000 total tips (near n log n per step
//! thanks to the k-d tree, not n²).

use std::hint::black_box;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use glam::DVec3;
use treemocap::model::tips::CapturedTip;
use treemocap::reconstruct::ReconstructSettings;
use treemocap::reconstruct::{mesh, reconstruct};

#[path = "../tests/it/common/crowns.rs"]
mod crowns;

fn flow_radii_mesh(tips: &[CapturedTip], cfg: &ReconstructSettings) -> usize {
    let tree = reconstruct(tips, DVec3::new(2.0, 0.0, 0.0), cfg, cfg.seed).expect("reconstruct");
    let m = mesh::branches(&tree, cfg.sides).expect("mesh");
    tree.nodes.len() + m.indices.len()
}

fn targets(c: &mut Criterion) {
    let mut group = c.benchmark_group("flow_radii_mesh");
    for (captured, total) in [(35usize, 500usize), (70, 5000)] {
        let tips = crowns::crown_tips(crowns::Shape::Pine, captured, 1);
        let cfg = ReconstructSettings {
            total_tips: total,
            ..Default::default()
        };
        let tree =
            reconstruct(&tips, DVec3::new(2.0, 0.0, 0.0), &cfg, cfg.seed).expect("reconstruct");
        eprintln!(
            "{captured}+{total}: {} nodes, {} steps, {} forced joins",
            tree.nodes.len(),
            tree.steps,
            tree.forced_joins
        );
        group.bench_with_input(
            BenchmarkId::new("pine", format!("{captured}+{total}")),
            &tips,
            |b, tips| b.iter(|| black_box(flow_radii_mesh(tips, &cfg))),
        );
    }
    group.finish();
}

/// Time of flow + radii + mesh for 70 captured tips as the total grows;
/// `merge_distance` None keeps the default merging.
fn growth_group(c: &mut Criterion, name: &str, totals: &[usize], merge_distance: Option<f64>) {
    let mut group = c.benchmark_group(name);
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(8));
    let tips = crowns::crown_tips(crowns::Shape::Maple, 70, 2);
    for &total in totals {
        let mut cfg = ReconstructSettings {
            total_tips: total,
            ..Default::default()
        };
        if let Some(m) = merge_distance {
            cfg.merge_distance = m;
        }
        let tree =
            reconstruct(&tips, DVec3::new(2.0, 0.0, 0.0), &cfg, cfg.seed).expect("reconstruct");
        eprintln!(
            "{name} 70+{total}: {} nodes, {} steps, {} forced joins",
            tree.nodes.len(),
            tree.steps,
            tree.forced_joins
        );
        group.bench_with_input(BenchmarkId::new("maple_70", total), &tips, |b, tips| {
            b.iter(|| black_box(flow_radii_mesh(tips, &cfg)))
        });
    }
    group.finish();
}

/// How the time grows from 500 to 50 000 total tips (should stay near
/// n log n per step, not n²).
fn growth(c: &mut Criterion) {
    growth_group(c, "growth", &[500, 2000, 5000, 20_000, 50_000], None);
}

/// The same growth with merging nearly off (1 mm): particles stay many for
/// every step, so this shows the cost per step of the neighbour searches.
fn growth_few_merges(c: &mut Criterion) {
    growth_group(c, "growth_few_merges", &[500, 5000, 50_000], Some(0.001));
}

/// tree.png of the 70 + 50 000 tip tree: drawing and encoding, to hold
/// against the growth figure above (target ≤ 20 % of it, issue 15).
fn picture(c: &mut Criterion) {
    let tips = crowns::crown_tips(crowns::Shape::Maple, 70, 2);
    let cfg = ReconstructSettings {
        total_tips: 50_000,
        ..Default::default()
    };
    let tree = reconstruct(&tips, DVec3::new(2.0, 0.0, 0.0), &cfg, cfg.seed).expect("reconstruct");
    let mut group = c.benchmark_group("picture");
    group.sample_size(10);
    group.bench_function("tree_png_maple_70_50000", |b| {
        b.iter(|| black_box(treemocap::render::picture::tree_png(&tree, None).expect("png")))
    });
    group.finish();
}

criterion_group!(benches, targets, growth, growth_few_merges, picture);
criterion_main!(benches);
