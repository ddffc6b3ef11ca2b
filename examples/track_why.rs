//! Why a stress session fails issue 14's targets: for one stress and seed,
//! every output tip made of more than one true tip (or of a ghost), as the
//! runs of whose samples it holds, with how far apart the two true tips
//! were where it changes from one to the other, after how many frames
//! of the output tip's gap, and whether the two are partners of one of
//! the stress's close pairs (swung towards each other: most of what is
//! left under `all`, docs/tracking.md §4a, session 49). What to look at
//! before changing the tracker.
//!
//! `cargo run --release --example track_why STRESS SEED [WIND_S] [NOISE_MM]`
//!
//! More, by environment variable: `ORIGIN=1` names the tracker's traces
//! (and their identities) behind each run of a mixed tip; `FILLS=1` lists
//! the true gaps of 11–50 frames whose fill misses by more than 4 mm
//! (`ALLFILLS=1`: every one), with the fill around each and the true
//! samples inside it that no tip holds or another tip holds (`FILLS=1,10`:
//! the gaps of 1–10 frames);
//! `LOST=tip,from,to` names the tracker's traces holding a true tip's
//! samples in a frame range; `PAIR=a,b,from,to` follows two true tips
//! frame by frame; `SUMMARY=1` prints the cleaning's summary;
//! `REJOIN_DEBUG=1` prints every decision of `src/track/rejoin.rs`, after
//! each tip's anchor (`anchor a<k> t<trace>`: its mean offset from where
//! its neighbours say it is, and that offset's spread; a tip alone on its
//! limb has a wide spread and fits any marker near it; each piece's line
//! says how much it moves for each unit the neighbours of the tip the
//! tracker gave it to say that tip moved (`moves`), and ends with the
//! tips near it it was not judged at, `b` busy or `?`
//! unjudged (neighbours hidden), and their distance in mm); `MAP=1` names the
//! true tip most of each output tip's samples come from (`map t<trace> =
//! tip (n samples)`), to read the anchors' trace ids; `COLUMNS=1` the true
//! tip behind each source column (`col c tip k`), to read the source ids
//! `UNTANGLE_DEBUG=1` prints; `LONG=1` adds the long occlusions of
//! `track_stress … long`.

use treemocap::sim::{self, stress};
use treemocap::track::{self, Tracker, TrackingSettings};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let name = args.get(1).map(String::as_str).unwrap_or("all");
    let seed: u64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(100);
    let wind_s: f64 = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(20.0);
    let mut cfg = TrackingSettings::default();
    if let Some(n) = args.get(4).and_then(|s| s.parse().ok()) {
        cfg.noise_mm = n;
    }
    let Some(st) = stress::named(&stress::base(seed, 70, 8.0, wind_s), name) else {
        eprintln!("no stress named {name}");
        return;
    };
    let opts = if std::env::var_os("LONG").is_some() {
        stress::long_gaps(st.options)
    } else {
        st.options
    };
    let syn = sim::generate(&opts).expect("stress options are valid");
    let mut tracker = Tracker::new(&cfg, Some(240.0));
    for f in &syn.frames {
        tracker.push(f);
    }
    let tracked = tracker.finish();
    let before = tracked.clone();
    let (tips, summary) = track::clean(tracked, &cfg, "sim", 240.0);
    let truth = &syn.truth;
    if std::env::var_os("SUMMARY").is_some() {
        println!("{summary}");
    }
    missing(&tips, &before, truth);
    if std::env::var_os("FILLS").is_some() {
        fills(&tips, truth);
    }
    if let Ok(spec) = std::env::var("LOST") {
        lost(&spec, &before, truth);
    }
    if let Ok(spec) = std::env::var("PAIR") {
        pair(&spec, &tips, truth);
    }
    if std::env::var_os("COLUMNS").is_some() {
        for (c, col) in truth.columns.iter().enumerate() {
            match col.tip {
                Some(k) => println!("col {c} tip {k}"),
                None => println!("col {c} ghost"),
            }
        }
    }
    if std::env::var_os("MAP").is_some() {
        for tip in &tips.tips {
            let who = match sim::score::main_owner(&tip.trace, truth) {
                Some((Some(k), n)) => format!("tip {k} ({n} samples)"),
                Some((None, n)) => format!("ghosts ({n} samples)"),
                None => "no samples".to_string(),
            };
            println!("map t{} = {who}", tip.trace.id);
        }
    }
    // The stress's close pairs (`close`, `all`): the tips swung towards
    // each other, each against the other.
    let pairs = truth.close_pairs();
    println!(
        "{} tips found, {} placed",
        tips.tips.len(),
        truth.tips.len()
    );
    for (n, tip) in tips.tips.iter().enumerate() {
        let (k, err) = (0..truth.tips.len())
            .map(|k| (k, truth.tips[k].rest.distance(tip.rest)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap_or((0, 0.0));
        if err > 0.0005 {
            println!(
                "output tip {n}: rest {:.2} mm from tip {k}'s, {} samples at rest, spread {:.2} mm, first frame {}",
                err * 1000.0,
                tip.samples,
                tip.spread_m * 1000.0,
                tip.trace.first_frame()
            );
        }
        let runs = owner_runs(tip, truth);
        if runs.len() < 2 {
            continue;
        }
        println!("output tip {n} (marker {}):", tip.marker);
        let mut previous: Option<&(Option<usize>, i64, i64, usize)> = None;
        for r in &runs {
            let apart = match (previous, r) {
                (Some(&(Some(a), _, last, _)), &(Some(b), f, _, _)) => {
                    let pa = truth_position(truth, a, f);
                    let pb = truth_position(truth, b, f);
                    let partners = pairs.contains(&(a.min(b), a.max(b)));
                    format!(
                        "{:.1} mm from the previous tip, after {} frames{}",
                        pa.distance(pb) * 1000.0,
                        f - last - 1,
                        if partners { ", its close partner" } else { "" }
                    )
                }
                _ => String::new(),
            };
            println!(
                "  {:>9} frames {:>5}..{:>5} ({:>4} samples) {apart}",
                r.0.map_or("ghost".to_string(), |k| format!("tip {k}")),
                r.1,
                r.2,
                r.3
            );
            previous = Some(r);
        }
        if std::env::var_os("ORIGIN").is_some() {
            origin(&runs, tip, &before);
        }
    }
}

/// For each run of an output tip: the tracker's traces that held its
/// samples and the identity each was in (or none: a ghost).
fn origin(
    runs: &[(Option<usize>, i64, i64, usize)],
    tip: &treemocap::model::tips::Tip,
    tracked: &track::Tracked,
) {
    for r in runs {
        let mut seen: Vec<usize> = Vec::new();
        for (f, p) in tip.trace.measurements() {
            if f < r.1 || f > r.2 {
                continue;
            }
            for tr in &tracked.traces {
                if tr.first_frame() <= f && f <= tr.last_frame() && !seen.contains(&tr.id) {
                    let hit = tr
                        .measurements()
                        .any(|(g, q)| g == f && q.distance(p) < 1e-9);
                    if hit {
                        seen.push(tr.id);
                    }
                }
            }
        }
        let desc: Vec<String> = seen
            .iter()
            .map(|&t| {
                let tr = &tracked.traces[t];
                format!(
                    "trace {t} [{}..{}, {} meas] id {:?}",
                    tr.first_frame(),
                    tr.last_frame(),
                    tr.measured(),
                    identity_of(tracked, t)
                )
            })
            .collect();
        println!("      {:?} {}..{}: {}", r.0, r.1, r.2, desc.join("; "));
    }
}

/// The runs of consecutive samples of `tip` from one true owner:
/// (owner, first frame, last frame, samples).
fn owner_runs(
    tip: &treemocap::model::tips::Tip,
    truth: &sim::Truth,
) -> Vec<(Option<usize>, i64, i64, usize)> {
    let mut runs: Vec<(Option<usize>, i64, i64, usize)> = Vec::new();
    for (frame, who) in sim::score::owners(&tip.trace, truth) {
        match runs.last_mut() {
            Some(last) if last.0 == who => {
                last.2 = frame;
                last.3 += 1;
            }
            _ => runs.push((who, frame, frame, 1)),
        }
    }
    runs
}

/// Where true tip `k` is in frame `f` (m).
fn truth_position(truth: &sim::Truth, k: usize, f: i64) -> glam::DVec3 {
    truth.position(k, truth.time_of(f))
}

/// `PAIR=a,b,from,to`: frame by frame, how far apart true tips `a` and `b`
/// are, whether each is hidden, and which output tip holds each.
fn pair(spec: &str, tips: &treemocap::model::tips::Tips, truth: &sim::Truth) {
    let v: Vec<i64> = spec.split(',').filter_map(|x| x.parse().ok()).collect();
    let [a, b, from, to] = v[..] else { return };
    let hidden = |k: usize, f: i64| {
        truth
            .gaps
            .iter()
            .any(|g| g.tip == k && g.first_frame <= f && f <= g.last_frame)
    };
    let mut holder = std::collections::HashMap::new();
    for (n, tip) in tips.tips.iter().enumerate() {
        for r in owner_runs(tip, truth) {
            if let Some(k) = r.0 {
                if k as i64 == a || k as i64 == b {
                    for (f, _) in tip.trace.measurements() {
                        if f >= r.1 && f <= r.2 {
                            holder.insert((k, f), n);
                        }
                    }
                }
            }
        }
    }
    for f in from..=to {
        let (a, b) = (a as usize, b as usize);
        let d = truth_position(truth, a, f).distance(truth_position(truth, b, f));
        println!(
            "{f}: {:.1} mm  a {} {:?}  b {} {:?}",
            d * 1000.0,
            if hidden(a, f) { "hid" } else { "   " },
            holder.get(&(a, f)),
            if hidden(b, f) { "hid" } else { "   " },
            holder.get(&(b, f))
        );
    }
}

/// Every true tip no output tip holds most samples of: which of the
/// tracker's traces hold its samples (identity or ghost, frames, samples).
fn missing(tips: &treemocap::model::tips::Tips, tracked: &track::Tracked, truth: &sim::Truth) {
    let mut claimed = vec![false; truth.tips.len()];
    for tip in &tips.tips {
        if let Some((Some(k), _)) = sim::score::main_owner(&tip.trace, truth) {
            claimed[k] = true;
        }
    }
    for k in (0..truth.tips.len()).filter(|&k| !claimed[k]) {
        println!("true tip {k} held by no output tip; its samples in the tracker's traces:");
        for tr in &tracked.traces {
            let runs: Vec<(i64, i64, usize)> = {
                let mut v: Vec<(i64, i64, usize)> = Vec::new();
                for (f, who) in sim::score::owners(tr, truth) {
                    if who != Some(k) {
                        continue;
                    }
                    match v.last_mut() {
                        Some(l) if f - l.1 <= 1 => {
                            l.1 = f;
                            l.2 += 1;
                        }
                        _ => v.push((f, f, 1)),
                    }
                }
                v
            };
            let n: usize = runs.iter().map(|r| r.2).sum();
            if n == 0 {
                continue;
            }
            println!(
                "  trace {} ({} samples, frames {}..{}, identity {:?}): {} of tip {k}, first {}..{}",
                tr.id,
                tr.measured(),
                tr.first_frame(),
                tr.last_frame(),
                identity_of(tracked, tr.id),
                n,
                runs[0].0,
                runs[runs.len() - 1].1
            );
        }
    }
}

/// `FILLS=1`: every true gap of 11–50 frames (`FILLS=lo,hi`: of `lo` to
/// `hi`) in the wind phase whose fill misses the truth by more than 4 mm
/// on average: the fill around it (its
/// ends and who they belong to, neighbour or PCHIP) and its error.
fn fills(tips: &treemocap::model::tips::Tips, truth: &sim::Truth) {
    let bin: Vec<i64> = std::env::var("FILLS")
        .unwrap_or_default()
        .split(',')
        .filter_map(|x| x.parse().ok())
        .collect();
    let (lo, hi) = match bin[..] {
        [lo, hi] => (lo, hi),
        _ => (11, 50),
    };
    let mut holder: std::collections::HashMap<(i64, usize), usize> = Default::default();
    for (n, tip) in tips.tips.iter().enumerate() {
        for (f, who) in sim::score::owners(&tip.trace, truth) {
            if let Some(w) = who {
                holder.insert((f, w), n);
            }
        }
    }
    let hidden = |k: usize, f: i64| {
        truth
            .gaps
            .iter()
            .any(|g| g.tip == k && g.first_frame <= f && f <= g.last_frame)
    };
    for (n, tip) in tips.tips.iter().enumerate() {
        let runs = owner_runs(tip, truth);
        let Some(k) = runs.iter().max_by_key(|r| r.3).and_then(|r| r.0) else {
            continue;
        };
        let owner: std::collections::HashMap<i64, Option<usize>> =
            sim::score::owners(&tip.trace, truth).collect();
        for g in truth.gaps.iter().filter(|g| g.tip == k) {
            let len = g.last_frame - g.first_frame + 1;
            if !(lo..=hi).contains(&len) || truth.time_of(g.first_frame) < truth.wind.0 + 2.0 {
                continue;
            }
            let Some(fill) = tip
                .trace
                .fills()
                .iter()
                .find(|f| f.from < g.first_frame && f.to > g.last_frame)
            else {
                continue;
            };
            let err: f64 = (g.first_frame..=g.last_frame)
                .map(|f| fill.at(f).distance(truth_position(truth, k, f)))
                .sum::<f64>()
                / len as f64;
            if err < 0.004 && std::env::var_os("ALLFILLS").is_none() {
                continue;
            }
            let lost = (fill.from + 1..fill.to)
                .filter(|f| *f < g.first_frame || *f > g.last_frame)
                .count();
            let mut runs: Vec<(i64, i64, Option<usize>)> = Vec::new();
            for f in fill.from + 1..fill.to {
                if hidden(k, f) {
                    continue;
                }
                let h = holder.get(&(f, k)).copied();
                match runs.last_mut() {
                    Some(r) if r.1 == f - 1 && r.2 == h => r.1 = f,
                    _ => runs.push((f, f, h)),
                }
            }
            let runs: Vec<String> = runs
                .iter()
                .map(|r| {
                    let off = fill.at(r.0).distance(truth_position(truth, k, r.0)) * 1000.0;
                    let edge = (r.0 - fill.from).min(fill.to - r.1);
                    format!(
                        "{}..{} in {:?} off {off:.1} mm {edge} f from an edge",
                        r.0, r.1, r.2
                    )
                })
                .collect();
            println!(
                "tip {k} (out {n}) gap {}..{} ({len} f) lost [{}]: fill {}..{} ({} f, {lost} beyond the true gap, {}), ends {:?} {:?}, error {:.1} mm, ends off {:.1} / {:.1} mm",
                g.first_frame,
                g.last_frame,
                runs.join(", "),
                fill.from,
                fill.to,
                fill.to - fill.from - 1,
                if fill.from_neighbours() { "neighbours" } else { "pchip" },
                owner.get(&fill.from),
                owner.get(&fill.to),
                err * 1000.0,
                fill.at(fill.from).distance(truth_position(truth, k, fill.from)) * 1000.0,
                fill.at(fill.to).distance(truth_position(truth, k, fill.to)) * 1000.0,
            );
        }
    }
}

/// The identity (marker found on line) trace `t` belongs to, if any.
fn identity_of(tracked: &track::Tracked, t: usize) -> Option<usize> {
    tracked.identities.iter().position(|ids| ids.contains(&t))
}

/// `LOST=tip,from,to`: the tracker's traces holding true tip `tip`'s
/// samples in frames `from..=to`, with their identity and every true tip
/// they hold samples of.
fn lost(spec: &str, tracked: &track::Tracked, truth: &sim::Truth) {
    let v: Vec<i64> = spec.split(',').filter_map(|x| x.parse().ok()).collect();
    let [k, from, to] = v[..] else { return };
    for tr in &tracked.traces {
        let n = sim::score::owners(tr, truth)
            .filter(|&(f, w)| w == Some(k as usize) && f >= from && f <= to)
            .count();
        if n == 0 {
            continue;
        }
        let owners: std::collections::BTreeSet<Option<usize>> =
            sim::score::owners(tr, truth).map(|x| x.1).collect();
        println!(
            "trace {} [{}..{}, {} meas] identity {:?}: {n} samples of tip {k} in {from}..{to}; owners {:?}",
            tr.id,
            tr.first_frame(),
            tr.last_frame(),
            tr.measured(),
            identity_of(tracked, tr.id),
            owners
        );
    }
}
