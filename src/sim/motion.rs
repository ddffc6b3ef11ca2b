//! How the marked tips move: the parameters behind [`Truth::position`].
//!
//! **ours** (the paper only shows that still tips wobble within 1 mm, §7):
//! - Still phase: one slow sinusoid per tip with a random direction, peak
//!   amplitude up to `still_motion_mm` (so its range stays within 1 mm).
//! - Wind phase: the tip bends downwind by a fixed mean deflection and sways
//!   around it with three sinusoids: a *limb mode* shared by every tip on the
//!   same limb (0.5–1.2 Hz, amplitude growing with the tip's lever), a *twig
//!   mode* of its own whose frequency rises as its last twig gets shorter
//!   (1–3 Hz, like a cantilever), both mainly along the wind, and a cross-wind
//!   mode about a third as large. Peak displacements come out at 1–6 cm.
//!
//! - Stress model (`sway_hz = [low, high]`), closer to a real crown in strong
//!   wind: every tip moves with its limb (an along-wind and a cross-wind mode,
//!   both shared by all tips of the limb, near `low`), with its branch (one
//!   mode shared by the tips above the same fork, near the band's geometric
//!   middle) and on its own twig (near `high`, amplitude growing only with
//!   the square root of `sway_scale`: the small, fast modes of a twig carry
//!   little of the wind's energy). Neighbours thus move coherently, as they
//!   do on a tree.
//! - Trunk mode (forest sessions only, [`trunk_mode`]): every tip of a tree
//!   also sways with its trunk — a narrow band near the trunk's low
//!   frequency (0.4–0.7 Hz) on two axes, shared by the whole crown and
//!   growing with the tip's height — and each tree's trunk draws its own
//!   frequencies, phases and directions, so two trees sway independently
//!   while the limbs of one crown share its trunk's motion. One-tree sessions keep
//!   the motion they always had (their shipped replays stay byte-identical).
//! - Gusts (`gusts_per_min`) raise the wind's strength for a few seconds;
//!   close pairs (`close_pairs`) swing two neighbouring tips towards each
//!   other so that their markers pass close.
//!
//! [`Truth::position`]: super::Truth::position

use std::f64::consts::TAU;

use glam::DVec3;

use super::tree::{q9, TreeTruth};
use super::truth::{pair_tips, GustTruth, Sinusoid, TipTruth};
use crate::rng::Rng;

/// A random stream that depends only on `base`'s state and `label`, not on
/// how many other streams were taken before (fork() advances its parent).
pub(crate) fn stream(base: &Rng, label: u64) -> Rng {
    base.stream(label)
}

fn sinusoid(direction: DVec3, amplitude: f64, frequency: f64, phase: f64) -> Sinusoid {
    let d = direction.normalize();
    Sinusoid {
        direction: DVec3::new(q9(d.x), q9(d.y), q9(d.z)),
        amplitude: q9(amplitude),
        frequency: q9(frequency),
        phase: q9(phase),
    }
}

/// A random unit vector, uniform on the sphere.
fn unit(rng: &mut Rng) -> DVec3 {
    loop {
        let v = DVec3::new(
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
        );
        let l = v.length();
        if l > 0.1 && l <= 1.0 {
            return v / l;
        }
    }
}

/// Builds each chosen tip's motion. `base` is the motion stream of the
/// session; every tip and limb draws from its own sub-stream.
pub(crate) fn tips(
    tree: &TreeTruth,
    nodes: &[usize],
    wind: DVec3,
    still_motion: f64,
    sway_scale: f64,
    base: &Rng,
) -> Vec<TipTruth> {
    let levers: Vec<f64> = nodes.iter().map(|&n| tree.lever(n)).collect();
    let max_lever = levers.iter().copied().fold(0.0, f64::max).max(1e-6);
    let cross = DVec3::Y.cross(wind).normalize();
    let limb_base = stream(base, 1);
    let tip_base = stream(base, 2);
    nodes
        .iter()
        .zip(&levers)
        .map(|(&node, &lever)| {
            let mut limb_rng = stream(&limb_base, tree.limb(node) as u64);
            let limb_freq = limb_rng.range(0.5, 1.2);
            let limb_phase = limb_rng.range(0.0, TAU);
            let limb_amp = limb_rng.range(0.010, 0.022);

            let mut rng = stream(&tip_base, node as u64);
            let wobble = vec![sinusoid(
                unit(&mut rng),
                still_motion * rng.range(0.1, 1.0),
                rng.range(0.2, 2.0),
                rng.range(0.0, TAU),
            )];
            let reach = lever / max_lever;
            let along = limb_amp * (0.4 + 0.6 * reach) * sway_scale;
            let twig = tree.twig_length(node).max(0.02);
            // 1 Hz for a long twig, approaching 3 Hz for a very short one.
            let twig_freq = ((1.0 + 2.0 * 0.08 / (0.08 + twig)) * rng.range(0.93, 1.07)).min(3.0);
            let twig_amp = rng.range(0.002, 0.007) * (0.5 + reach) * sway_scale;
            // Twigs are not aligned with the wind: turn their mode by up to 25°.
            let turn = rng.range(-25f64, 25.0).to_radians();
            let twig_dir = wind * turn.cos() + cross * turn.sin();
            let sway = vec![
                sinusoid(wind, along, limb_freq, limb_phase),
                sinusoid(twig_dir, twig_amp, twig_freq, rng.range(0.0, TAU)),
                sinusoid(
                    cross,
                    along * rng.range(0.25, 0.4),
                    rng.range(0.5, 2.5),
                    rng.range(0.0, TAU),
                ),
            ];
            let bend = wind * ((along + twig_amp) * rng.range(0.4, 0.7));
            TipTruth {
                node,
                rest: tree.nodes[node].position,
                lever: q9(lever),
                wobble,
                bend: DVec3::new(q9(bend.x), q9(bend.y), q9(bend.z)),
                sway,
            }
        })
        .collect()
}

/// The stress model's tips (see the module comment): limb, branch and twig
/// modes in the band `hz` (Hz).
pub(crate) fn tree_tips(
    tree: &TreeTruth,
    nodes: &[usize],
    wind: DVec3,
    still_motion: f64,
    sway_scale: f64,
    hz: (f64, f64),
    base: &Rng,
) -> Vec<TipTruth> {
    let (lo, hi) = hz;
    let mid = (lo * hi).sqrt();
    let levers: Vec<f64> = nodes.iter().map(|&n| tree.lever(n)).collect();
    let max_lever = levers.iter().copied().fold(0.0, f64::max).max(1e-6);
    let cross = DVec3::Y.cross(wind).normalize();
    let limb_base = stream(base, 11);
    let fork_base = stream(base, 12);
    let tip_base = stream(base, 13);
    nodes
        .iter()
        .zip(&levers)
        .map(|(&node, &lever)| {
            let reach = lever / max_lever;
            let mut limb = stream(&limb_base, tree.limb(node) as u64);
            let along_f = limb.range(lo, (lo * 2.5).min(mid));
            let along_ph = limb.range(0.0, TAU);
            let along_a = limb.range(0.010, 0.022);
            let cross_f = limb.range(lo, (lo * 3.0).min(hi));
            let cross_ph = limb.range(0.0, TAU);
            let cross_a = along_a * limb.range(0.25, 0.4);
            let mut fork = stream(&fork_base, tree.fork(node) as u64);
            let fork_f = fork.range(0.8 * mid, (1.8 * mid).min(hi));
            let fork_ph = fork.range(0.0, TAU);
            let fork_a = fork.range(0.003, 0.008);
            let fork_turn = fork.range(-40f64, 40.0).to_radians();
            let mut rng = stream(&tip_base, node as u64);
            let wobble = vec![sinusoid(
                unit(&mut rng),
                still_motion * rng.range(0.1, 1.0),
                rng.range(0.2, 2.0),
                rng.range(0.0, TAU),
            )];
            let lever_gain = 0.4 + 0.6 * reach;
            let twig_turn = rng.range(-60f64, 60.0).to_radians();
            let twig_a = rng.range(0.002, 0.006) * (0.5 + reach) * sway_scale.sqrt();
            let sway = vec![
                sinusoid(wind, along_a * lever_gain * sway_scale, along_f, along_ph),
                sinusoid(cross, cross_a * lever_gain * sway_scale, cross_f, cross_ph),
                sinusoid(
                    wind * fork_turn.cos() + cross * fork_turn.sin(),
                    fork_a * (0.5 + reach) * sway_scale,
                    fork_f,
                    fork_ph,
                ),
                sinusoid(
                    wind * twig_turn.cos() + cross * twig_turn.sin(),
                    twig_a,
                    rng.range(hi / 2.0, hi),
                    rng.range(0.0, TAU),
                ),
            ];
            let bend = wind * (along_a * lever_gain * sway_scale * rng.range(0.4, 0.7));
            TipTruth {
                node,
                rest: tree.nodes[node].position,
                lever: q9(lever),
                wobble,
                bend: DVec3::new(q9(bend.x), q9(bend.y), q9(bend.z)),
                sway,
            }
        })
        .collect()
}

/// Adds the tree's trunk mode to its tips' motion (module comment). A
/// trunk in turbulent wind rings near its natural frequency with a slowly
/// changing amplitude and phase: each of its two axes — the major one
/// turned by up to 60° from the wind, the minor one across it at 50–90 % of
/// the size — is the sum of [`TRUNK_PARTIALS`] sinusoids of random phase
/// within ±10 % of the trunk's frequency (0.4–0.7 Hz, below most limbs).
/// The top sways 12–25 mm × `sway_scale` in all; a tip at height y gets
/// `(y / height)^1.5` of it (a cantilever's first mode: small low in the
/// crown), plus the steady downwind lean it carries. Every tree draws its
/// own from `base`, its own stream, so two trees sway independently.
pub(crate) fn trunk_mode(
    tips: &mut [TipTruth],
    tree: &TreeTruth,
    ground: f64,
    wind: DVec3,
    sway_scale: f64,
    base: &Rng,
) {
    let mut rng = stream(base, 21);
    let cross_wind = DVec3::Y.cross(wind).normalize();
    let turn = rng.range(-60f64, 60.0).to_radians();
    let major = wind * turn.cos() + cross_wind * turn.sin();
    let minor = DVec3::Y.cross(major).normalize();
    let freq = rng.range(0.4, 0.7);
    let top = rng.range(0.012, 0.025) * sway_scale;
    let minor_ratio = rng.range(0.5, 0.9);
    // (direction, amplitude at the top, frequency, phase) of every partial.
    let mut partials = Vec::with_capacity(2 * TRUNK_PARTIALS);
    for (dir, share) in [(major, 1.0), (minor, minor_ratio)] {
        for _ in 0..TRUNK_PARTIALS {
            let a = top * share / (TRUNK_PARTIALS as f64).sqrt();
            partials.push((dir, a, freq * rng.range(0.9, 1.1), rng.range(0.0, TAU)));
        }
    }
    let lean = top * rng.range(0.5, 0.8);
    let height = tree.height.max(1e-6);
    for t in tips {
        let gain = ((t.rest.y - ground) / height).clamp(0.0, 1.0).powf(1.5);
        for &(dir, a, f, ph) in &partials {
            t.sway.push(sinusoid(dir, a * gain, f, ph));
        }
        let bend = t.bend + wind * (lean * gain);
        t.bend = DVec3::new(q9(bend.x), q9(bend.y), q9(bend.z));
    }
}

/// Sinusoids per axis of a trunk's sway (see [`trunk_mode`]).
const TRUNK_PARTIALS: usize = 3;

/// Adds to `pairs` pairs of nearest neighbouring tips an opposite swing
/// along the line between them, of amplitude (distance − `close`) / 2 at
/// the wind's `strongest` strength (1 without gusts; the swing scales with
/// the wind like every mode), so that the two come within about `close` of
/// each other twice a period and never swing through each other.
/// The pairs are [`pair_tips`]'s.
pub(crate) fn close_pairs(
    tips: &mut [TipTruth],
    pairs: usize,
    close: f64,
    strongest: f64,
    tree: &TreeTruth,
    base: &Rng,
) {
    for (i, j) in pair_tips(tips, pairs, close) {
        let d = tips[i].rest.distance(tips[j].rest);
        let mut rng = stream(base, (tree.nodes.len() * i + j) as u64);
        let u = (tips[j].rest - tips[i].rest) / d;
        let amp = (d - close) / 2.0 / strongest.max(1.0);
        let f = rng.range(0.4, 1.2);
        let ph = rng.range(0.0, TAU);
        tips[i].sway.push(sinusoid(u, amp, f, ph));
        tips[j].sway.push(sinusoid(-u, amp, f, ph));
    }
}

/// Gusts as a Poisson process at `per_min` over `span` (s on the take's
/// clock), none reaching past its end.
pub(crate) fn gusts(per_min: f64, span: (f64, f64), base: &Rng) -> Vec<GustTruth> {
    let mut out = Vec::new();
    if per_min <= 0.0 {
        return out;
    }
    let mut rng = base.clone();
    let mut t = span.0;
    loop {
        t += -(1.0 - rng.f64()).ln() * 60.0 / per_min;
        let g = GustTruth {
            start_s: q9(t),
            rise_s: q9(rng.range(0.3, 1.5)),
            hold_s: q9(rng.range(0.5, 3.0)),
            fall_s: q9(rng.range(0.5, 2.0)),
            extra: q9(rng.range(0.3, 1.0)),
        };
        if g.start_s + g.rise_s + g.hold_s + g.fall_s >= span.1 {
            break;
        }
        t = g.start_s + g.rise_s + g.hold_s + g.fall_s;
        out.push(g);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::tree::{grow, CrownShape};

    #[test]
    fn sway_is_branch_dependent_and_in_range() {
        for shape in [CrownShape::Maple, CrownShape::Pine] {
            let tree = grow(shape, &mut Rng::new(2));
            let nodes = tree.choose_tips(40, 0.06).unwrap();
            let wind = DVec3::new(0.6, 0.0, 0.8);
            let tips = tips(&tree, &nodes, wind, 0.0004, 1.0, &Rng::new(3));
            let mut freqs = Vec::new();
            for t in &tips {
                assert!(t.wobble.iter().all(|s| s.amplitude <= 0.0004 + 1e-12));
                let peak: f64 = t.bend.length() + t.sway.iter().map(|s| s.amplitude).sum::<f64>();
                assert!((0.005..=0.06).contains(&peak), "peak {peak} m");
                assert!(t.bend.dot(wind) > 0.0);
                for s in &t.sway {
                    assert!((0.5..=3.0).contains(&s.frequency), "{} Hz", s.frequency);
                    freqs.push(s.frequency);
                }
                // Mainly along the wind: the along-wind amplitudes outweigh
                // the cross-wind one.
                let along: f64 = t
                    .sway
                    .iter()
                    .map(|s| (s.amplitude * s.direction.dot(wind)).abs())
                    .sum();
                let cross: f64 = t
                    .sway
                    .iter()
                    .map(|s| (s.amplitude * s.direction.cross(wind).y).abs())
                    .sum();
                assert!(along > 1.5 * cross, "{along} vs {cross}");
            }
            // Different branches, different frequencies.
            freqs.sort_by(f64::total_cmp);
            freqs.dedup();
            assert!(
                freqs.len() > 2 * tips.len(),
                "{shape}: {} distinct frequencies",
                freqs.len()
            );
        }
    }
}
