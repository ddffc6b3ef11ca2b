//! How the marked tips move: the parameters behind [`Truth::position`].
//!
//! **ours** (the paper only shows that still tips wobble within 1 mm, §7):
//! - Still phase: one slow sinusoid per tip with a random direction, peak
//!   amplitude up to `still_motion_mm` (so its range stays within 1 mm).
//! - Wind phase: the tip bends downwind by a fixed mean deflection and sways
//!   around it with three sinusoids: a *limb mode* shared by every tip on the
//!   same limb (0.5–1.2 Hz, amplitude growing with the tip's lever), a *twig
//!   mode* of its own whose frequency rises as its last twig gets shorter
//!   (1–3 Hz, cantilever-like), both mainly along the wind, and a cross-wind
//!   mode about a third as large. Peak displacements come out at 1–6 cm.
//!
//! [`Truth::position`]: super::Truth::position

use std::f64::consts::TAU;

use glam::DVec3;

use super::tree::{q9, TreeTruth};
use super::truth::{Sinusoid, TipTruth};
use crate::rng::Rng;

/// A random stream that depends only on `base`'s state and `label`, not on
/// how many other streams were taken before (fork() advances its parent).
pub(crate) fn stream(base: &Rng, label: u64) -> Rng {
    base.clone().fork(label)
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
            let twig_freq = (0.55 / twig.sqrt()).clamp(1.0, 3.0) * rng.range(0.9, 1.1);
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
