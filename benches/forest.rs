//! `replay` of a five-tree session against its five trees replayed one by
//! one (target: the forest no slower than 1.5 × the sum; docs/forest.md).
//! The single-tree sessions are the forest session's own columns, tree by
//! tree, so both sides track and reconstruct the same markers and frames.
//!
//! `cargo bench --bench forest`

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use criterion::{criterion_group, criterion_main, Criterion};
use treemocap::config::Config;
use treemocap::sim::{generate, write_motive_csv, SynthOptions, Synthetic};

/// The columns of tree `k` alone, renumbered.
fn one_tree(syn: &Synthetic, k: usize) -> Synthetic {
    let f = syn.truth.forest.as_ref().expect("forest");
    let keep: Vec<Option<usize>> = {
        let mut next = 0;
        syn.columns
            .iter()
            .map(|c| {
                c.tip.filter(|&t| f.tip_tree[t] == k).map(|_| {
                    next += 1;
                    next - 1
                })
            })
            .collect()
    };
    let mut out = syn.clone();
    out.columns = syn
        .columns
        .iter()
        .zip(&keep)
        .filter(|(_, k)| k.is_some())
        .map(|(c, _)| c.clone())
        .collect();
    for frame in &mut out.frames {
        frame.markers.retain_mut(|m| {
            let new = m.id.and_then(|id| keep[id as usize]);
            m.id = new.map(|n| n as i64);
            new.is_some()
        });
    }
    out.truth.columns = out.columns.clone();
    out
}

fn write(syn: &Synthetic, path: &Path) {
    let mut file = std::io::BufWriter::new(std::fs::File::create(path).expect("create"));
    write_motive_csv(syn, &mut file).expect("write");
}

fn sessions(dir: &Path) -> (PathBuf, Vec<PathBuf>) {
    let opts = SynthOptions {
        seed: 5,
        trees: 5,
        tips: 20,
        overlap: 0.2,
        mixed: true,
        still_s: 10.0,
        wind_s: 10.0,
        take_name: "forest".into(),
        ..SynthOptions::default()
    };
    let syn = generate(&opts).expect("session");
    let forest = dir.join("forest.csv");
    write(&syn, &forest);
    let singles = (0..5)
        .map(|k| {
            let p = dir.join(format!("tree-{k}.csv"));
            write(&one_tree(&syn, k), &p);
            p
        })
        .collect();
    (forest, singles)
}

fn forest_vs_one_by_one(c: &mut Criterion) {
    let dir = tempfile::tempdir().expect("temp dir");
    let (forest, singles) = sessions(dir.path());
    let config = Config::default();
    let out = dir.path().join("out");
    let replay = |file: &Path| treemocap::app::replay::run(file, &config, &out).expect("replay");
    let r = replay(&forest);
    eprintln!("{}", r.tree);
    let t = Instant::now();
    replay(&forest);
    let whole = t.elapsed();
    let t = Instant::now();
    for s in &singles {
        replay(s);
    }
    let parts = t.elapsed();
    eprintln!(
        "one run: forest {:.0} ms, five trees one by one {:.0} ms, ratio {:.2}",
        whole.as_secs_f64() * 1e3,
        parts.as_secs_f64() * 1e3,
        whole.as_secs_f64() / parts.as_secs_f64()
    );
    let mut group = c.benchmark_group("forest_replay");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(20));
    group.bench_function("five_trees_in_one_session", |b| b.iter(|| replay(&forest)));
    group.bench_function("five_trees_one_by_one", |b| {
        b.iter(|| {
            for s in &singles {
                replay(s);
            }
        })
    });
    group.finish();
}

criterion_group!(benches, forest_vs_one_by_one);
criterion_main!(benches);
