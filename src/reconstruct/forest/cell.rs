//! Where one tree's crown ends and its neighbour's begins: a plane between
//! every two trees whose crowns' boxes overlap, and a tree's *cell*, its side
//! of all of them. Random tips are drawn only inside a tree's cell and the
//! flow is kept in it, so no branch of one tree grows into another's volume.
//!
//! The plane's normal points from one crown's box centre to the other's
//! (box centres move only when a tip at the edge of a crown moves, so a tip
//! moving inside a crown leaves the neighbour's cell, and its tree, as they
//! were). It sits in the middle of the widest gap between the two trees'
//! tips along that normal; where no gap separates them, at the threshold
//! with the fewest tips on the wrong side.

use glam::DVec3;

use crate::reconstruct::trunk::Bounds;

/// One side of a plane: the points with `normal · p <= offset`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HalfSpace {
    /// Unit normal, pointing out of the cell.
    pub normal: DVec3,
    /// Offset along the normal (m).
    pub offset: f64,
    /// The tree on the other side.
    pub neighbour: usize,
}

/// The region a tree may grow in: the intersection of its half-spaces
/// (everything, for a tree alone).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Cell {
    /// The planes towards each neighbour.
    pub sides: Vec<HalfSpace>,
}

/// How far inside a plane a projected point is put (m), so that rounding
/// never leaves it a hair outside.
const INSET: f64 = 1e-9;

impl Cell {
    /// True when `p` is inside (or on) every plane.
    pub fn contains(&self, p: DVec3) -> bool {
        self.sides
            .iter()
            .all(|s| s.normal.dot(p) <= s.offset + 1e-7)
    }

    /// `p` moved into the cell: clamped to `bounds`, then projected onto
    /// each plane it lies beyond, a few rounds (the cell and the box are
    /// convex, so alternating projections close in on their intersection).
    /// The planes come last: the cell is the promise, the box a bound.
    pub fn project(&self, mut p: DVec3, bounds: &Bounds) -> DVec3 {
        if self.sides.is_empty() {
            return p;
        }
        for _ in 0..4 {
            p = p.clamp(bounds.min, bounds.max);
            let mut moved = false;
            for s in &self.sides {
                let over = s.normal.dot(p) - (s.offset - INSET);
                if over > 0.0 {
                    p -= s.normal * over;
                    moved = true;
                }
            }
            if !moved {
                break;
            }
        }
        p
    }
}

/// The cells of every tree, from each tree's tips. Trees whose tip boxes,
/// grown by `margin` on every side, do not overlap need no plane.
pub fn cells(trees: &[Vec<DVec3>], margin: f64) -> Vec<Cell> {
    let boxes: Vec<Option<Bounds>> = trees
        .iter()
        .map(|t| Bounds::of(t.iter().copied()))
        .collect();
    let mut cells = vec![Cell::default(); trees.len()];
    for i in 0..trees.len() {
        for j in i + 1..trees.len() {
            let (Some(a), Some(b)) = (boxes[i], boxes[j]) else {
                continue;
            };
            let apart =
                (0..3).any(|k| a.min[k] - margin > b.max[k] || b.min[k] - margin > a.max[k]);
            if apart {
                continue;
            }
            let Some((normal, offset)) = plane(&trees[i], &trees[j], a, b) else {
                continue;
            };
            cells[i].sides.push(HalfSpace {
                normal,
                offset,
                neighbour: j,
            });
            cells[j].sides.push(HalfSpace {
                normal: -normal,
                offset: -offset,
                neighbour: i,
            });
        }
    }
    cells
}

/// The plane between tips `a` (its inside) and `b`: normal from a's box
/// centre towards b's, offset at the best threshold. `None` when the box
/// centres coincide.
fn plane(a: &[DVec3], b: &[DVec3], box_a: Bounds, box_b: Bounds) -> Option<(DVec3, f64)> {
    let centre = |x: Bounds| 0.5 * (x.min + x.max);
    let normal = (centre(box_b) - centre(box_a)).try_normalize()?;
    // Projections tagged with their side: false = a, true = b.
    let mut proj: Vec<(f64, bool)> = a
        .iter()
        .map(|p| (normal.dot(*p), false))
        .chain(b.iter().map(|p| (normal.dot(*p), true)))
        .collect();
    proj.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
    // A threshold between sorted positions k-1 and k puts the first k on
    // a's side: wrong are the b's among them and the a's after.
    let mut wrong = a.len(); // threshold below everything: every a is wrong
    let mut best: Option<(usize, f64, f64)> = None; // (wrong, gap, threshold)
    for k in 1..proj.len() {
        if proj[k - 1].1 {
            wrong += 1;
        } else {
            wrong -= 1;
        }
        let gap = proj[k].0 - proj[k - 1].0;
        let threshold = 0.5 * (proj[k].0 + proj[k - 1].0);
        let better = match best {
            None => true,
            Some((w, g, _)) => wrong < w || (wrong == w && gap > g),
        };
        if better {
            best = Some((wrong, gap, threshold));
        }
    }
    best.map(|(_, _, threshold)| (normal, threshold))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ring(centre: DVec3, r: f64, n: usize) -> Vec<DVec3> {
        (0..n)
            .map(|i| {
                let a = i as f64 * 0.9;
                centre + DVec3::new(r * a.cos(), 0.1 * (i % 5) as f64, r * a.sin())
            })
            .collect()
    }

    #[test]
    fn overlapping_crowns_get_a_plane_that_separates_their_tips() {
        let a = ring(DVec3::new(0.0, 1.0, 0.0), 0.8, 20);
        let b = ring(DVec3::new(1.2, 1.0, 0.0), 0.5, 20);
        let c = ring(DVec3::new(10.0, 1.0, 0.0), 0.5, 20);
        let cells = cells(&[a.clone(), b.clone(), c.clone()], 0.1);
        assert_eq!(cells[0].sides.len(), 1);
        assert_eq!(cells[1].sides.len(), 1);
        assert!(cells[2].sides.is_empty(), "far apart: no plane");
        // Tips with x ≤ 0.8 (a's) and ≥ 0.7 (b's): a's ring reaches 0.8,
        // b's starts at 0.7, so at most the few in between are cut off.
        let wrong = a.iter().filter(|p| !cells[0].contains(**p)).count()
            + b.iter().filter(|p| !cells[1].contains(**p)).count();
        assert!(wrong <= 3, "{wrong}");
        // No point is strictly inside both cells.
        let s = cells[0].sides[0];
        for x in 0..50 {
            let p = DVec3::new(x as f64 * 0.04 - 0.5, 1.0, 0.0);
            let on_plane = (s.normal.dot(p) - s.offset).abs() < 1e-6;
            assert!(on_plane || !(cells[0].contains(p) && cells[1].contains(p)));
        }
    }

    #[test]
    fn projection_lands_inside_the_cell_and_the_box() {
        let a = ring(DVec3::new(0.0, 1.0, 0.0), 0.8, 20);
        let b = ring(DVec3::new(1.0, 1.0, 0.0), 0.8, 20);
        let cells = cells(&[a.clone(), b], 0.1);
        let bounds = Bounds::of(a.iter().copied()).unwrap();
        for x in 0..40 {
            let p = DVec3::new(-1.0 + 0.07 * x as f64, 0.5 + 0.05 * x as f64, 0.3);
            let q = cells[0].project(p, &bounds);
            assert!(cells[0].contains(q), "{p} -> {q}");
            if cells[0].contains(p) && p.clamp(bounds.min, bounds.max) == p {
                assert_eq!(q, p, "a point inside stays put");
            }
        }
    }
}
