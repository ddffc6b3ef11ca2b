//! A session's motion on its tree: the captured tips' traces sampled at the
//! keys, one deformation per key, and the branch-length change measured.

use glam::DVec3;

use super::deform::{Deformer, TipInput};
use super::keys::{choose_keys, Keys};
use super::paths::TipPaths;
use super::rig::Rig;
use super::AnimateSettings;
use crate::error::{Error, Result};
use crate::model::motion::{CapturedMotion, Stretch, TreeMotion};
use crate::model::tree::Tree;

/// Most node positions one animation holds (keys × nodes): 50 million is
/// 600 MB of f32, and as much again in the file.
const MAX_KEY_NODES: usize = 50_000_000;
/// Segments shorter than this (m) are left out of the stretch figures: a
/// zero-length segment has no length to keep.
const MIN_SEGMENT: f64 = 1e-6;

/// Animates `tree` with the paths of its captured tips (matched by marker)
/// over the keys `settings` chooses. A captured tip whose marker has no path
/// is missing throughout and borrows its motion.
pub fn animate(
    tree: &Tree,
    paths: &dyn TipPaths,
    settings: &AnimateSettings,
) -> Result<TreeMotion> {
    let rig = Rig::new(tree, settings)?;
    let keys = choose_keys(paths.times(), settings)?;
    let n = rig.nodes();
    if keys.frames.len().saturating_mul(n) > MAX_KEY_NODES {
        return Err(Error::Runtime(format!(
            "the animation would hold {} keys × {n} nodes; shorten animate.window_s or lower animate.rate_hz",
            keys.frames.len()
        )));
    }
    let inputs = sample_tips(&rig, paths, &keys);
    let mut deformer = Deformer::new(&rig);
    let mut positions = Vec::with_capacity(keys.frames.len() * n);
    let mut captured: Vec<CapturedMotion> = rig
        .captured
        .iter()
        .map(|c| CapturedMotion {
            node: c.node,
            marker: c.marker,
            sources: Vec::with_capacity(keys.frames.len()),
        })
        .collect();
    let mut stretch = StretchSum::default();
    let (mut pose, mut sources, mut row) = (Vec::new(), Vec::new(), Vec::new());
    for k in 0..keys.frames.len() {
        row.clear();
        row.extend(inputs.iter().map(|tip| tip[k]));
        deformer.deform(&rig, &row, &mut pose, &mut sources);
        for (c, s) in captured.iter_mut().zip(&sources) {
            c.sources.push(*s);
        }
        stretch.add(tree, &pose);
        positions.extend(pose.iter().map(|p| p.as_vec3().to_array()));
    }
    let start_s = keys.times[0];
    Ok(TreeMotion {
        start_s,
        times: keys.times.iter().map(|t| t - start_s).collect(),
        frames: keys.frames,
        nodes: n,
        positions,
        captured,
        stretch: stretch.finish(),
        rate_hz: settings.rate_hz,
        bend_power: settings.bend_power,
        cut: keys.cut,
    })
}

/// Every captured tip's input at every key (rig order, then keys).
fn sample_tips(rig: &Rig, paths: &dyn TipPaths, keys: &Keys) -> Vec<Vec<TipInput>> {
    rig.captured
        .iter()
        .map(|c| {
            let rest = rig.rest[c.slot];
            match paths.sample(c.marker, &keys.frames) {
                Some(samples) => samples
                    .into_iter()
                    .map(|s| match s {
                        Some((p, source)) => TipInput::Tracked(p - rest, source),
                        None => TipInput::Missing,
                    })
                    .collect(),
                None => vec![TipInput::Missing; keys.frames.len()],
            }
        })
        .collect()
}

/// Running sums of the length change.
#[derive(Default)]
struct StretchSum {
    max: f64,
    worst: Option<usize>,
    sum: f64,
    count: u64,
}

impl StretchSum {
    fn add(&mut self, tree: &Tree, pose: &[DVec3]) {
        for (i, node) in tree.nodes.iter().enumerate() {
            let Some(p) = node.parent else { continue };
            let rest = node.position.distance(tree.nodes[p].position);
            if rest < MIN_SEGMENT {
                continue;
            }
            let change = (pose[i].distance(pose[p]) / rest - 1.0).abs();
            self.sum += change;
            self.count += 1;
            if change > self.max {
                self.max = change;
                self.worst = Some(i);
            }
        }
    }

    fn finish(self) -> Stretch {
        Stretch {
            max_pct: 100.0 * self.max,
            mean_pct: if self.count == 0 {
                0.0
            } else {
                100.0 * self.sum / self.count as f64
            },
            worst_node: self.worst,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::animate::fixture::small_tree;
    use crate::model::motion::TipSource;
    use crate::model::tips::{Tip, Tips};
    use crate::model::trace::{Curve, Fill, Timeline, Trace};

    fn tips_with(traces: Vec<(usize, Trace)>, frames: usize) -> Tips {
        Tips {
            version: 1,
            source: "test".into(),
            frame_rate: 100.0,
            rest_window_s: [0.0, 1.0],
            tips: traces
                .into_iter()
                .map(|(marker, trace)| Tip {
                    marker,
                    rest: DVec3::ZERO,
                    samples: trace.measured(),
                    gap_fraction: 0.0,
                    spread_m: 0.0,
                    trace,
                })
                .collect(),
            wind: None,
            timeline: Timeline {
                times: (0..frames).map(|i| i as f64 / 100.0).collect(),
                anchors: vec![(0, 0)],
            },
        }
    }

    /// What `replay` animates from (the traces sampled at the keys, the
    /// traces then dropped) moves the tree exactly as the traces do, with
    /// a window and a cut, a fill and a gap.
    #[test]
    fn key_samples_animate_as_the_traces_do() {
        let tree = small_tree();
        let at = |f: i64| tree.nodes[3].position + DVec3::X * 0.02 * (f as f64 * 0.1).sin();
        let mut tr = Trace::new(0, 3, at(3), None);
        for f in (4..300).filter(|f| !(40..50).contains(f) && !(90..160).contains(f)) {
            tr.push(f, at(f), None);
        }
        tr.add_fill(Fill {
            from: 39,
            to: 50,
            curve: Curve::Points((40..50).map(at).collect()),
        });
        let tips = tips_with(vec![(5, tr)], 320);
        for settings in [
            AnimateSettings::default(),
            AnimateSettings {
                window_s: vec![0.3, 2.9],
                max_duration_s: 1.5,
                rate_hz: 24.0,
                ..AnimateSettings::default()
            },
        ] {
            let keys = crate::animate::KeyPaths::of(&tips, &settings).unwrap();
            let from_traces = animate(&tree, &tips, &settings).unwrap();
            assert_eq!(animate(&tree, &keys, &settings).unwrap(), from_traces);
            let flags = |s| from_traces.captured.iter().any(|c| c.sources.contains(&s));
            assert!(flags(TipSource::Filled) && flags(TipSource::Measured));
        }
    }

    #[test]
    fn captured_tips_follow_their_traces_with_flags() {
        let tree = small_tree();
        let rest5 = tree.nodes[3].position;
        let at = |f: i64| rest5 + DVec3::new(0.02 * (f as f64 * 0.1).sin(), 0.0, 0.0);
        // Marker 5 measured at every frame but 40..=49, filled there;
        // marker 2 has no trace at all.
        let mut tr = Trace::new(0, 0, at(0), None);
        for f in 1..100 {
            if !(40..50).contains(&f) {
                tr.push(f, at(f), None);
            }
        }
        tr.add_fill(Fill {
            from: 39,
            to: 50,
            curve: Curve::Hermite {
                p0: at(39),
                m0: DVec3::ZERO,
                p1: at(50),
                m1: DVec3::ZERO,
            },
        });
        let tips = tips_with(vec![(5, tr.clone())], 100);
        let m = animate(&tree, &tips, &AnimateSettings::default()).unwrap();
        assert_eq!(m.keys(), 30);
        assert_eq!(m.nodes, tree.nodes.len());
        let samples: Vec<_> = tr.samples().collect();
        let c5 = m.captured.iter().find(|c| c.marker == 5).unwrap();
        let c2 = m.captured.iter().find(|c| c.marker == 2).unwrap();
        for (k, &f) in m.frames.iter().enumerate() {
            let s = samples[f as usize];
            let p = DVec3::from(m.pose(k)[3].map(f64::from));
            assert!(p.distance(s.position) < 1e-6, "key {k}");
            let want = if (40..50).contains(&f) {
                TipSource::Filled
            } else {
                TipSource::Measured
            };
            assert_eq!(c5.sources[k], want);
            assert_eq!(c2.sources[k], TipSource::Borrowed);
            // The trunk base never moves.
            assert_eq!(m.pose(k)[0], [0.0, 0.0, 0.0]);
        }
        assert!(m.stretch.max_pct < 2.0, "{:?}", m.stretch);
        assert_eq!(m.times[0], 0.0);
    }
}
