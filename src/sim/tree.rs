//! Seeded synthetic trees: a trunk and recursive branches inside a crown
//! envelope, and the choice of which branch tips carry markers.
//!
//! Sizes follow the paper's lab trees (§3: indoor trees under 2.5 m): a tree
//! is 1.5–2.6 m tall. Two crown habits cover the paper's examples (§7):
//! - **Maple** (decurrent): a short trunk splits into 3–5 limbs that fork
//!   recursively; branch ends are clipped to an ellipsoid, so the crown is round.
//! - **Pine** (excurrent): a leader runs to the top with whorls of laterals
//!   whose length shrinks with height; branch ends are clipped to a cone.
//!
//! Clipping to the envelope (**ours**) is what makes the outer tips trace the
//! crown's shape, the property the particle-flow reconstruction relies on.

use std::f64::consts::{PI, TAU};
use std::fmt;
use std::str::FromStr;

use glam::DVec3;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::rng::Rng;

/// The crown habit of a synthetic tree.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CrownShape {
    /// Round, decurrent crown (no leader), like the paper's maple.
    #[default]
    Maple,
    /// Conical, excurrent crown (a leader with whorls), like the paper's pine.
    Pine,
}

impl FromStr for CrownShape {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "maple" => Ok(CrownShape::Maple),
            "pine" => Ok(CrownShape::Pine),
            _ => Err(format!(
                "unknown crown shape '{s}' (expected maple or pine)"
            )),
        }
    }
}

impl fmt::Display for CrownShape {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            CrownShape::Maple => "maple",
            CrownShape::Pine => "pine",
        })
    }
}

/// One node of the true branching structure.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TreeNode {
    /// Metres, Y up, the trunk's foot at the origin.
    pub position: DVec3,
    /// The node this one grows from; `None` only for the trunk's foot (node 0).
    /// Parents always come before their children in `TreeTruth::nodes`.
    pub parent: Option<usize>,
    /// Branch order: 0 trunk (or pine leader), 1 a limb off the trunk, 2 a
    /// branch off a limb, … Lets a reconstruction be scored per order.
    pub order: u32,
    /// Branch radius at this node (m), pipe model from 3 mm tips, so meshes of
    /// the true tree can be compared with reconstructed ones.
    pub radius: f64,
}

/// The true tree behind a synthetic session, as written to `NAME.truth.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TreeTruth {
    /// The crown form it was grown with.
    pub shape: CrownShape,
    /// Height of the highest node (m).
    pub height: f64,
    /// Height where the crown envelope starts (m).
    pub crown_base: f64,
    /// Widest horizontal radius of the crown envelope (m).
    pub crown_radius: f64,
    /// Every node; a node that no other node names as parent is a branch tip.
    pub nodes: Vec<TreeNode>,
}

/// Radius of every branch tip (m); parents follow the pipe model r² = Σ rᵢ².
const TIP_RADIUS: f64 = 0.003;
/// Branch pieces shorter than this after clipping are not grown (m).
const MIN_SEGMENT: f64 = 0.015;

/// The envelope a crown must stay in, and how far out a point is in it.
#[derive(Debug, Clone, Copy)]
enum Envelope {
    /// Centre height, horizontal radius, vertical half-axis.
    Ellipsoid { cy: f64, r: f64, b: f64 },
    /// Base height, base radius, apex height.
    Cone { y0: f64, r: f64, apex: f64 },
}

impl Envelope {
    /// 0 on the axis (or centre), 1 on the envelope's surface, > 1 outside.
    fn ratio(&self, p: DVec3) -> f64 {
        let horizontal = (p.x * p.x + p.z * p.z).sqrt();
        match *self {
            Envelope::Ellipsoid { cy, r, b } => {
                ((horizontal / r).powi(2) + ((p.y - cy) / b).powi(2)).sqrt()
            }
            // r/R_base + height fraction: exactly 1 on the slanted surface
            // (radius R_base·(apex − y)/(apex − y0)) and at the apex.
            Envelope::Cone { y0, r, apex } => horizontal / r + ((p.y - y0) / (apex - y0)).max(0.0),
        }
    }

    /// The point of the segment start→end where it leaves the envelope (end
    /// itself when it stays inside), pulled in slightly so it counts as inside.
    fn clip(&self, start: DVec3, end: DVec3) -> DVec3 {
        if self.ratio(end) <= 1.0 {
            return end;
        }
        if self.ratio(start) > 1.0 {
            return start;
        }
        let (mut lo, mut hi) = (0.0, 1.0);
        for _ in 0..30 {
            let mid = 0.5 * (lo + hi);
            if self.ratio(start.lerp(end, mid)) <= 1.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        start.lerp(end, lo * 0.995)
    }
}

/// Rounds a length to the nanometre, so the truth file holds exactly the
/// numbers the simulation used and prints them short (**ours**).
pub(crate) fn q9(x: f64) -> f64 {
    (x * 1e9).round() / 1e9
}

fn q9v(v: DVec3) -> DVec3 {
    DVec3::new(q9(v.x), q9(v.y), q9(v.z))
}

/// A unit vector at `angle` from `dir`, turned by `roll` around it.
fn deflect(dir: DVec3, angle: f64, roll: f64) -> DVec3 {
    let dir = dir.normalize();
    let helper = if dir.y.abs() < 0.9 {
        DVec3::Y
    } else {
        DVec3::X
    };
    let u = dir.cross(helper).normalize();
    let v = dir.cross(u);
    let side = u * roll.cos() + v * roll.sin();
    (dir * angle.cos() + side * angle.sin()).normalize()
}

/// A horizontal unit vector at azimuth `a` tilted by `elevation` (rad).
fn heading(a: f64, elevation: f64) -> DVec3 {
    DVec3::new(
        a.cos() * elevation.cos(),
        elevation.sin(),
        a.sin() * elevation.cos(),
    )
}

struct Builder {
    nodes: Vec<TreeNode>,
    envelope: Envelope,
}

impl Builder {
    fn add(&mut self, position: DVec3, parent: Option<usize>, order: u32) -> usize {
        self.nodes.push(TreeNode {
            position: q9v(position),
            parent,
            order,
            radius: TIP_RADIUS,
        });
        self.nodes.len() - 1
    }

    /// Grows one straight-ish piece of branch from `from` along `dir`, clipped
    /// to the envelope. Returns the new end node, or `None` if clipping left
    /// too little to grow.
    fn segment(&mut self, from: usize, dir: DVec3, len: f64, order: u32) -> Option<usize> {
        let start = self.nodes[from].position;
        let end = self.envelope.clip(start, start + dir * len);
        if start.distance(end) < MIN_SEGMENT {
            return None;
        }
        Some(self.add(end, Some(from), order))
    }

    /// Maple: a branch (two slightly bent pieces while it is long) that forks
    /// into 2–3 children until `depth` runs out or it meets the envelope.
    #[allow(clippy::too_many_arguments)]
    fn maple_branch(
        &mut self,
        rng: &mut Rng,
        from: usize,
        dir: DVec3,
        len: f64,
        depth: u32,
        order: u32,
        min_len: f64,
    ) {
        let bent = deflect(dir, rng.range(0.0, 0.15), rng.range(0.0, TAU));
        let end = if depth >= 3 {
            let Some(mid) = self.segment(from, dir, len * 0.5, order) else {
                return;
            };
            self.segment(mid, bent, len * 0.5, order)
        } else {
            self.segment(from, bent, len, order)
        };
        let Some(end) = end else { return };
        if depth == 0 || len < min_len || self.envelope.ratio(self.nodes[end].position) > 0.99 {
            return;
        }
        let n = if rng.chance(0.3) { 3 } else { 2 };
        let roll0 = rng.range(0.0, TAU);
        for k in 0..n {
            let roll = roll0 + TAU * k as f64 / n as f64 + rng.range(-0.3, 0.3);
            let spread = rng.range(25f64.to_radians(), 45f64.to_radians());
            // A slight upward pull: maples reach for light.
            let child = (deflect(bent, spread, roll) + DVec3::Y * 0.25).normalize();
            let child_len = len * rng.range(0.62, 0.78);
            self.maple_branch(rng, end, child, child_len, depth - 1, order + 1, min_len);
        }
    }

    /// Pine: a branch of `pieces` straight pieces with a pair of side branches
    /// at every inner node, side branches getting one piece less.
    fn pine_branch(&mut self, rng: &mut Rng, from: usize, dir: DVec3, len: f64, order: u32) {
        let pieces = 4u32.saturating_sub(order).max(1);
        let piece = len / pieces as f64;
        let mut at = from;
        let mut dir = dir;
        for i in 0..pieces {
            // Pine branches droop a little more towards their ends.
            dir = (dir - DVec3::Y * rng.range(0.0, 0.08)).normalize();
            let Some(next) = self.segment(at, dir, piece, order) else {
                return;
            };
            at = next;
            if i + 1 < pieces && order < 3 {
                let remaining = len - piece * (i + 1) as f64;
                let flat = DVec3::new(dir.x, 0.0, dir.z).normalize_or_zero();
                if flat == DVec3::ZERO {
                    continue;
                }
                let azimuth = flat.z.atan2(flat.x);
                for side in [-1.0, 1.0] {
                    let a = azimuth + side * rng.range(40f64.to_radians(), 60f64.to_radians());
                    let side_dir = heading(a, rng.range(-0.2, 0.05));
                    let side_len = remaining.max(piece) * rng.range(0.5, 0.7);
                    self.pine_branch(rng, at, side_dir, side_len, order + 1);
                }
            }
        }
    }
}

/// Grows a tree of the given habit from `rng`. The tree does not depend on
/// how many markers will be placed, so the same seed gives the same tree for
/// any marker count.
pub fn grow(shape: CrownShape, rng: &mut Rng) -> TreeTruth {
    match shape {
        CrownShape::Maple => grow_maple(rng),
        CrownShape::Pine => grow_pine(rng),
    }
}

fn grow_maple(rng: &mut Rng) -> TreeTruth {
    // The envelope's top; branches end a little below it.
    let height = rng.range(1.75, 2.7);
    let trunk_h = height * rng.range(0.28, 0.36);
    let crown_base = trunk_h - 0.05 * height;
    let b = (height - crown_base) / 2.0;
    let radius = height * rng.range(0.34, 0.42);
    let envelope = Envelope::Ellipsoid {
        cy: crown_base + b,
        r: radius,
        b,
    };
    let mut t = Builder {
        nodes: Vec::new(),
        envelope,
    };
    let mut at = t.add(DVec3::ZERO, None, 0);
    let lean = DVec3::new(rng.range(-0.02, 0.02), 0.0, rng.range(-0.02, 0.02));
    for k in 1..=3 {
        let f = k as f64 / 3.0;
        at = t.add(DVec3::Y * trunk_h * f + lean * f, Some(at), 0);
    }
    let limbs = rng.int(3, 5) as usize;
    let a0 = rng.range(0.0, TAU);
    for k in 0..limbs {
        let a = a0 + TAU * k as f64 / limbs as f64 + rng.range(-0.3, 0.3);
        let tilt = rng.range(15f64.to_radians(), 45f64.to_radians());
        let dir = heading(a, PI / 2.0 - tilt);
        let len = height * rng.range(0.17, 0.21);
        t.maple_branch(rng, at, dir, len, 6, 1, 0.015 * height);
    }
    finish(CrownShape::Maple, t, crown_base, radius)
}

fn grow_pine(rng: &mut Rng) -> TreeTruth {
    let height = rng.range(1.5, 2.5);
    let crown_base = height * rng.range(0.12, 0.2);
    let radius = height * rng.range(0.32, 0.4);
    let envelope = Envelope::Cone {
        y0: crown_base,
        r: radius,
        apex: height,
    };
    let mut t = Builder {
        nodes: Vec::new(),
        envelope,
    };
    let mut at = t.add(DVec3::ZERO, None, 0);
    let whorls = rng.int(7, 9) as usize;
    let top_whorl = height * 0.92;
    let a0 = rng.range(0.0, TAU);
    for w in 0..whorls {
        let y = crown_base + (top_whorl - crown_base) * w as f64 / (whorls - 1) as f64;
        let y = y + rng.range(-0.01, 0.01) * height;
        let wobble = DVec3::new(rng.range(-0.01, 0.01), 0.0, rng.range(-0.01, 0.01));
        at = t.add(DVec3::Y * y + wobble, Some(at), 0);
        let surface = radius * (height - y) / (height - crown_base);
        let n = rng.int(4, 6) as usize;
        // Successive whorls are turned so branches do not stack.
        let turn = a0 + w as f64 * 0.7;
        for k in 0..n {
            let a = turn + TAU * k as f64 / n as f64 + rng.range(-0.3, 0.3);
            let dir = heading(a, rng.range(-0.25, 0.1));
            let len = surface * rng.range(0.85, 1.0);
            if len > 0.03 {
                t.pine_branch(rng, at, dir, len, 1);
            }
        }
    }
    let top = DVec3::new(0.0, height, 0.0) + DVec3::new(rng.range(-0.01, 0.01), 0.0, 0.0);
    let top = envelope.clip(t.nodes[at].position, top);
    t.add(top, Some(at), 0);
    finish(CrownShape::Pine, t, crown_base, radius)
}

fn finish(shape: CrownShape, mut t: Builder, crown_base: f64, crown_radius: f64) -> TreeTruth {
    // Children come after parents, so one backward pass sums the pipe model.
    let mut sum_sq = vec![0.0f64; t.nodes.len()];
    for i in (0..t.nodes.len()).rev() {
        let r = if sum_sq[i] > 0.0 {
            sum_sq[i].sqrt()
        } else {
            TIP_RADIUS
        };
        t.nodes[i].radius = q9(r);
        if let Some(p) = t.nodes[i].parent {
            sum_sq[p] += r * r;
        }
    }
    let height = t.nodes.iter().map(|n| n.position.y).fold(0.0, f64::max);
    TreeTruth {
        shape,
        height,
        crown_base: q9(crown_base),
        crown_radius: q9(crown_radius),
        nodes: t.nodes,
    }
}

impl TreeTruth {
    /// Indices of the branch tips (nodes without children), ascending.
    pub fn leaves(&self) -> Vec<usize> {
        let mut has_child = vec![false; self.nodes.len()];
        for n in &self.nodes {
            if let Some(p) = n.parent {
                if let Some(h) = has_child.get_mut(p) {
                    *h = true;
                }
            }
        }
        (0..self.nodes.len())
            .filter(|&i| !has_child[i] && self.nodes[i].parent.is_some())
            .collect()
    }

    /// Where `p` (in the tree's own coordinates) lies in the crown
    /// envelope: below 1 inside, 1 on its surface, above 1 outside.
    pub fn envelope_ratio(&self, p: DVec3) -> f64 {
        self.envelope().ratio(p)
    }

    fn envelope(&self) -> Envelope {
        match self.shape {
            CrownShape::Maple => {
                let b = (self.height - self.crown_base) / 2.0;
                Envelope::Ellipsoid {
                    cy: self.crown_base + b,
                    r: self.crown_radius,
                    b,
                }
            }
            CrownShape::Pine => Envelope::Cone {
                y0: self.crown_base,
                r: self.crown_radius,
                apex: self.height,
            },
        }
    }

    /// Path length (m) from node `i` down to the first trunk node: the lever
    /// a tip swings on.
    pub fn lever(&self, i: usize) -> f64 {
        let mut len = 0.0;
        let mut at = i;
        while let Some(n) = self.nodes.get(at) {
            if n.order == 0 {
                break;
            }
            let Some(p) = n.parent else { break };
            len += n.position.distance(self.nodes[p].position);
            at = p;
        }
        len
    }

    /// The limb (order-1 branch's first node) a node belongs to, or the node
    /// itself for trunk nodes: tips on one limb sway together.
    pub fn limb(&self, i: usize) -> usize {
        let mut at = i;
        while let Some(n) = self.nodes.get(at) {
            match n.parent {
                Some(p) if self.nodes[p].order > 0 => at = p,
                _ => break,
            }
        }
        at
    }

    /// The nearest fork below node `i` (a node with more than one child), or
    /// the trunk's foot: tips that share it sway together on that branch.
    pub fn fork(&self, i: usize) -> usize {
        let mut children = vec![0u32; self.nodes.len()];
        for n in &self.nodes {
            if let Some(p) = n.parent {
                children[p] += 1;
            }
        }
        let mut at = i;
        while let Some(p) = self.nodes[at].parent {
            at = p;
            if children[p] > 1 {
                break;
            }
        }
        at
    }

    /// Length (m) of the last piece of branch to a tip, from its nearest
    /// fork: short twigs sway faster.
    pub fn twig_length(&self, i: usize) -> f64 {
        let mut children = vec![0u32; self.nodes.len()];
        for n in &self.nodes {
            if let Some(p) = n.parent {
                children[p] += 1;
            }
        }
        let mut len = 0.0;
        let mut at = i;
        while let Some(p) = self.nodes[at].parent {
            len += self.nodes[at].position.distance(self.nodes[p].position);
            at = p;
            if children[p] > 1 {
                break;
            }
        }
        len
    }

    /// Picks `n` branch tips for markers: among the outer half of the tips
    /// (by their place in the crown envelope), farthest-point sampling, which
    /// spreads markers evenly over the crown as the paper asks (§3) and keeps
    /// them as far apart as the tree allows. Fails when the chosen tips would
    /// be closer than `min_spacing` (m).
    pub fn choose_tips(&self, n: usize, min_spacing: f64) -> Result<Vec<usize>> {
        self.choose_tips_among(n, min_spacing, |_| true)
    }

    /// [`TreeTruth::choose_tips`] among the branch tips `allowed` accepts
    /// (in a forest: the tips the cameras can see, away from the markers
    /// already on other trees).
    pub fn choose_tips_among(
        &self,
        n: usize,
        min_spacing: f64,
        allowed: impl Fn(usize) -> bool,
    ) -> Result<Vec<usize>> {
        let leaves: Vec<usize> = self.leaves().into_iter().filter(|&i| allowed(i)).collect();
        if n == 0 || n > leaves.len() {
            return Err(Error::config(
                "tips",
                format!(
                    "this tree has {} branch tips; asked for {n} markers",
                    leaves.len()
                ),
            ));
        }
        let env = self.envelope();
        let mut pool: Vec<(f64, usize)> = leaves
            .iter()
            .map(|&i| (env.ratio(self.nodes[i].position), i))
            .collect();
        pool.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        pool.truncate(n.max(leaves.len().div_ceil(2)));
        let pos: Vec<DVec3> = pool.iter().map(|&(_, i)| self.nodes[i].position).collect();
        let mut chosen = vec![0usize];
        let mut nearest: Vec<f64> = pos.iter().map(|p| p.distance(pos[0])).collect();
        while chosen.len() < n {
            let (best, dist) =
                nearest.iter().enumerate().fold(
                    (0, -1.0),
                    |acc, (k, &d)| if d > acc.1 { (k, d) } else { acc },
                );
            if dist < min_spacing {
                return Err(Error::config(
                    "tips",
                    format!(
                        "only {} markers fit on this tree at least {:.0} mm apart; use fewer tips, \
                         a smaller spacing or another seed",
                        chosen.len(),
                        min_spacing * 1000.0
                    ),
                ));
            }
            chosen.push(best);
            for (k, p) in pos.iter().enumerate() {
                nearest[k] = nearest[k].min(p.distance(pos[best]));
            }
        }
        Ok(chosen.into_iter().map(|k| pool[k].1).collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn horizontal(p: DVec3) -> f64 {
        (p.x * p.x + p.z * p.z).sqrt()
    }

    #[test]
    fn sizes_are_lab_trees_and_tips_fit() {
        for seed in 0..6 {
            for shape in [CrownShape::Maple, CrownShape::Pine] {
                let tree = grow(shape, &mut Rng::new(seed));
                assert!(
                    (1.45..=2.65).contains(&tree.height),
                    "{shape} {seed}: {}",
                    tree.height
                );
                for (i, n) in tree.nodes.iter().enumerate() {
                    assert!(n.parent.is_none_or(|p| p < i));
                    assert!(n.position.y >= -1e-9 && n.position.y <= tree.height + 1e-9);
                }
                let tips = tree.choose_tips(70, 0.06).unwrap();
                let mut unique = tips.clone();
                unique.sort();
                unique.dedup();
                assert_eq!(unique.len(), 70);
                for (a, &i) in tips.iter().enumerate() {
                    for &j in &tips[..a] {
                        let d = tree.nodes[i].position.distance(tree.nodes[j].position);
                        assert!(d >= 0.06, "{shape} {seed}: tips {i},{j} {d} m apart");
                    }
                }
            }
        }
    }

    #[test]
    fn pine_is_conical_and_maple_is_round_topped() {
        // Widest marked tip (35 of them, what reconstruction sees) in the
        // lower, middle and upper third of the marked tips' height range.
        let widths = |tree: &TreeTruth| {
            let tips: Vec<DVec3> = tree
                .choose_tips(35, 0.06)
                .unwrap()
                .iter()
                .map(|&i| tree.nodes[i].position)
                .collect();
            let lo = tips.iter().map(|p| p.y).fold(f64::MAX, f64::min);
            let hi = tips.iter().map(|p| p.y).fold(f64::MIN, f64::max);
            let mut w = [0.0f64; 3];
            for p in tips {
                let k = (((p.y - lo) / (hi - lo) * 3.0).floor().clamp(0.0, 2.0)) as usize;
                w[k] = w[k].max(horizontal(p));
            }
            w
        };
        for seed in 0..6 {
            let pine = widths(&grow(CrownShape::Pine, &mut Rng::new(seed)));
            assert!(
                pine[0] > pine[1] && pine[1] > pine[2],
                "pine {seed}: {pine:?}"
            );
            assert!(pine[2] < 0.6 * pine[0], "pine {seed}: {pine:?}");
            let maple = widths(&grow(CrownShape::Maple, &mut Rng::new(seed)));
            // A round crown stays wide near the top, unlike a cone.
            let widest = maple.iter().copied().fold(0.0, f64::max);
            assert!(maple[2] > 0.75 * widest, "maple {seed}: {maple:?}");
        }
    }

    #[test]
    fn radii_follow_the_pipe_model() {
        let tree = grow(CrownShape::Maple, &mut Rng::new(3));
        let mut sum = vec![0.0; tree.nodes.len()];
        for n in &tree.nodes {
            if let Some(p) = n.parent {
                sum[p] += n.radius * n.radius;
            }
        }
        for (i, n) in tree.nodes.iter().enumerate() {
            let expect = if sum[i] > 0.0 {
                sum[i].sqrt()
            } else {
                TIP_RADIUS
            };
            assert!((n.radius - expect).abs() < 1e-8, "node {i}");
        }
        assert!(
            tree.nodes[0].radius > 0.02,
            "trunk radius {}",
            tree.nodes[0].radius
        );
    }

    #[test]
    fn shape_names_parse() {
        assert_eq!("Pine".parse::<CrownShape>(), Ok(CrownShape::Pine));
        assert_eq!("maple".parse::<CrownShape>(), Ok(CrownShape::Maple));
        assert!("oak".parse::<CrownShape>().is_err());
    }
}
