//! The crown volume the random tips are placed in (paper §5, Figures 5, 6
//! and 10; spec §6): a vertical stack of bounding boxes, each receiving
//! random tips in proportion to the captured tips inside it, or the convex
//! hull of the captured tips with random tips uniformly inside.

use glam::DVec3;

use crate::error::Result;
use crate::reconstruct::error::ReconstructError;
use crate::reconstruct::hull::Hull;
use crate::reconstruct::trunk::Bounds;
use crate::reconstruct::{ReconstructSettings, VolumeKind};
use crate::rng::Rng;

/// One box of the vertical stack.
#[derive(Debug, Clone, PartialEq)]
pub struct CrownBox {
    /// Lower corner: x/z of the captured tips in this slab, y of the slab.
    pub min: DVec3,
    /// Upper corner.
    pub max: DVec3,
    /// Captured tips whose height falls in this slab.
    pub captured: usize,
    /// Random tips placed in this box.
    pub random: usize,
}

/// The volume that was used, kept so tests and reports can check it.
#[derive(Debug, Clone)]
pub enum Volume {
    /// A vertical stack of boxes, bottom first.
    Boxes(Vec<CrownBox>),
    /// The convex hull of the captured tips.
    Hull(Hull),
}

/// Which slab of `boxes` evenly divided heights in `[y0, y0 + height]` a
/// height falls in; the top edge belongs to the top slab.
pub fn slab_of(y: f64, y0: f64, height: f64, boxes: usize) -> usize {
    if height <= 0.0 || boxes <= 1 {
        return 0;
    }
    let k = ((y - y0) / height * boxes as f64).floor();
    if k.is_nan() || k < 0.0 {
        0
    } else {
        (k as usize).min(boxes - 1)
    }
}

/// Splits `total` among shares in proportion to `weights` (largest
/// remainder, ties to the lower index): each part is within 1 of its exact
/// quota and the parts sum to `total`.
pub fn proportional(total: usize, weights: &[usize]) -> Vec<usize> {
    let sum: usize = weights.iter().sum();
    if sum == 0 {
        return vec![0; weights.len()];
    }
    let quotas: Vec<f64> = weights
        .iter()
        .map(|&w| total as f64 * w as f64 / sum as f64)
        .collect();
    let mut parts: Vec<usize> = quotas.iter().map(|q| q.floor() as usize).collect();
    let assigned: usize = parts.iter().sum();
    let mut order: Vec<usize> = (0..weights.len()).collect();
    // Stable sort keeps lower indices first among equal remainders.
    order.sort_by(|&a, &b| {
        let ra = quotas[a] - quotas[a].floor();
        let rb = quotas[b] - quotas[b].floor();
        rb.total_cmp(&ra)
    });
    for &k in order.iter().take(total.saturating_sub(assigned)) {
        parts[k] += 1;
    }
    parts
}

/// Builds the configured volume around `captured` and draws the random tips
/// so that captured + random = `total_tips`.
pub fn random_tips(
    captured: &[DVec3],
    cfg: &ReconstructSettings,
    rng: &mut Rng,
) -> Result<(Volume, Vec<DVec3>)> {
    random_tips_where(captured, cfg, rng, &|_| true)
}

/// Draws per random tip when some are refused by `keep` (a neighbouring
/// tree's side): enough for a cell holding a fiftieth of the volume.
const TRIES_PER_TIP: usize = 50;

/// Like [`random_tips`], keeping only the points `keep` accepts (the
/// tree's own cell when several trees stand in one capture). A point
/// refused is drawn again, up to [`TRIES_PER_TIP`] times per tip; a box's
/// `random` is the number actually placed. With a `keep` that accepts
/// everything the draws are exactly those of `random_tips`.
pub fn random_tips_where(
    captured: &[DVec3],
    cfg: &ReconstructSettings,
    rng: &mut Rng,
    keep: &dyn Fn(DVec3) -> bool,
) -> Result<(Volume, Vec<DVec3>)> {
    let count = cfg.total_tips.saturating_sub(captured.len());
    let Some(bounds) = Bounds::of(captured.iter().copied()) else {
        return Err(ReconstructError::NoTips.into());
    };
    match cfg.volume {
        VolumeKind::Boxes => {
            let mut boxes = box_stack(captured, bounds, cfg.boxes.max(1), count);
            let mut tips = Vec::with_capacity(count);
            for b in &mut boxes {
                let mut placed = 0;
                for _ in 0..b.random * TRIES_PER_TIP {
                    if placed == b.random {
                        break;
                    }
                    let p = DVec3::new(
                        rng.range(b.min.x, b.max.x),
                        rng.range(b.min.y, b.max.y),
                        rng.range(b.min.z, b.max.z),
                    );
                    if keep(p) {
                        tips.push(p);
                        placed += 1;
                    }
                }
                b.random = placed;
            }
            Ok((Volume::Boxes(boxes), tips))
        }
        VolumeKind::Hull => {
            let hull = match Hull::build(captured) {
                Ok(h) => h,
                Err(e) if count > 0 => return Err(ReconstructError::Hull(e).into()),
                // Nothing to place: a flat set of tips is no obstacle.
                Err(_) => return Ok((Volume::Boxes(Vec::new()), Vec::new())),
            };
            let tips = hull.sample_where(count, rng, keep, count * TRIES_PER_TIP);
            Ok((Volume::Hull(hull), tips))
        }
    }
}

/// The stack of boxes: slabs of equal height over the captured tips' height
/// range, each as wide as the captured tips in it, with `count` random tips
/// shared in proportion to the captured tips per slab.
fn box_stack(captured: &[DVec3], bounds: Bounds, n: usize, count: usize) -> Vec<CrownBox> {
    let y0 = bounds.min.y;
    let height = bounds.max.y - bounds.min.y;
    let mut members: Vec<Vec<DVec3>> = vec![Vec::new(); n];
    for &p in captured {
        members[slab_of(p.y, y0, height, n)].push(p);
    }
    let weights: Vec<usize> = members.iter().map(Vec::len).collect();
    let shares = proportional(count, &weights);
    members
        .iter()
        .zip(shares)
        .enumerate()
        .map(|(k, (tips, random))| {
            let slab_lo = y0 + height * k as f64 / n as f64;
            let slab_hi = y0 + height * (k + 1) as f64 / n as f64;
            let b = Bounds::of(tips.iter().copied()).unwrap_or(Bounds {
                min: DVec3::ZERO,
                max: DVec3::ZERO,
            });
            CrownBox {
                min: DVec3::new(b.min.x, slab_lo, b.min.z),
                max: DVec3::new(b.max.x, slab_hi, b.max.z),
                captured: tips.len(),
                random,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn proportional_shares_by_hand() {
        // 10 among 1:2:2 → quotas 2, 4, 4.
        assert_eq!(proportional(10, &[1, 2, 2]), vec![2, 4, 4]);
        // 7 among 1:1:1 → 2.33 each; the extra one to the first.
        assert_eq!(proportional(7, &[1, 1, 1]), vec![3, 2, 2]);
        // Empty slabs get nothing.
        assert_eq!(proportional(5, &[0, 3, 0, 2]), vec![0, 3, 0, 2]);
        assert_eq!(proportional(5, &[0, 0]), vec![0, 0]);
    }

    #[test]
    fn slabs_split_evenly_and_keep_the_top() {
        assert_eq!(slab_of(1.0, 1.0, 2.0, 4), 0);
        assert_eq!(slab_of(1.49, 1.0, 2.0, 4), 0);
        assert_eq!(slab_of(1.5, 1.0, 2.0, 4), 1);
        assert_eq!(slab_of(3.0, 1.0, 2.0, 4), 3);
        assert_eq!(slab_of(5.0, 1.0, 0.0, 4), 0);
    }

    #[test]
    fn boxes_hold_their_random_tips() {
        let mut rng = Rng::new(4);
        let captured: Vec<DVec3> = (0..30)
            .map(|_| {
                DVec3::new(
                    rng.range(-1.0, 1.0),
                    rng.range(1.0, 2.0),
                    rng.range(-1.0, 1.0),
                )
            })
            .collect();
        let cfg = ReconstructSettings::default();
        let (vol, tips) = random_tips(&captured, &cfg, &mut rng).unwrap();
        assert_eq!(tips.len(), cfg.total_tips - 30);
        let Volume::Boxes(boxes) = vol else { panic!() };
        let mut k = 0;
        for b in &boxes {
            for p in &tips[k..k + b.random] {
                assert!(p.cmpge(b.min).all() && p.cmple(b.max).all());
            }
            k += b.random;
        }
    }
}
