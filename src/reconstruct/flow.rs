//! Particle flow (paper §5, Table 1 and equations 1–3; spec §6): every tip
//! is a particle that walks towards the trunk; where particles meet they
//! merge into a junction, and their paths are the branches.
//!
//! Per step, for a particle at S_p with nearest trunk node S_t at distance d:
//! - gravity G = (0, −1, 0) · d
//! - shape-format S = unit(S_r − S_p) · α · (mean particle height above the
//!   ground, computed once over all tips)
//! - wind W = the wind vector (direction × speed)
//! - D = (ω1 G + ω2 S + ω3 W) / 3, and the particle moves by β d · D/|D|
//!   (ours: D normalised so β alone sets the step length).
//!
//! Ours, after the paper's "the bounding space ... bounds particle flow":
//! a particle never leaves the bounding box of the tips and the trunk.
//! Without that bound a negative gravity weight (the willow) pushes a
//! particle above the trunk top further up each step, by a growing step,
//! to infinity.
//!
//! After all particles moved, particles closer than `merge_distance` merge
//! and a particle closer than `trunk_distance` to a trunk node joins it.
//! Neighbour searches use a k-d tree (kiddo) built once per step, so a step
//! costs O(n log n), not O(n²).

use glam::DVec3;
use kiddo::{ImmutableKdTree, SquaredEuclidean};

use crate::error::Result;
use crate::model::tree::{Kind, Node, Tree};
use crate::reconstruct::error::ReconstructError;
use crate::reconstruct::forest::cell::Cell;
use crate::reconstruct::trunk::{Bounds, Trunk};
use crate::reconstruct::ReconstructSettings;

/// A particle still flowing: where it is and the tree node it last left.
#[derive(Debug, Clone, Copy)]
struct Particle {
    position: DVec3,
    node: usize,
}

/// Runs the flow from `tips` (position and kind of each start) to the trunk.
/// Radii are left at zero; `radii::assign` fills them.
pub fn run(
    tips: &[(DVec3, Kind)],
    trunk: &Trunk,
    wind: DVec3,
    cfg: &ReconstructSettings,
) -> Result<Tree> {
    run_in(tips, trunk, wind, cfg, &Cell::default())
}

/// Like [`run`], every step kept inside `cell` (a tree's side of the planes
/// between it and its neighbours; docs/forest.md). The cell and the bounds
/// are convex, so a junction — the mean of particles inside — is inside
/// too. An empty cell changes nothing.
pub fn run_in(
    tips: &[(DVec3, Kind)],
    trunk: &Trunk,
    wind: DVec3,
    cfg: &ReconstructSettings,
    cell: &Cell,
) -> Result<Tree> {
    let (mut nodes, trunk_ids, mut particles) = start(tips, trunk);
    let forces = Forces {
        cell,
        bounds: Bounds::of(tips.iter().map(|t| t.0).chain(trunk.nodes.iter().copied())).unwrap_or(
            Bounds {
                min: DVec3::ZERO,
                max: DVec3::ZERO,
            },
        ),
        attractor: trunk.attractor_point(),
        shape_magnitude: cfg.alpha * mean_height(tips, cfg.ground_height),
        wind,
        cfg,
    };
    let mut steps = 0;
    while !particles.is_empty() && steps < cfg.max_steps {
        steps += 1;
        particles = step(&particles, &forces, trunk, &trunk_ids, &mut nodes)?;
    }
    // Ours: whatever is still free joins its nearest trunk node directly.
    let forced_joins = particles.len();
    for p in &particles {
        let (t, _) = trunk.nearest(p.position);
        nodes[p.node].parent = Some(trunk_ids[t]);
    }
    if forced_joins > 0 {
        tracing::warn!(
            forced_joins,
            max_steps = cfg.max_steps,
            "particles did not reach the trunk within max_steps and were joined to it directly"
        );
    }
    Ok(Tree {
        nodes,
        trunk: trunk_ids,
        attractor: trunk.attractor,
        forced_joins,
        steps,
        wind,
    })
}

/// The trunk's nodes (each the parent of the next) and one free particle
/// per tip, each with its node.
fn start(tips: &[(DVec3, Kind)], trunk: &Trunk) -> (Vec<Node>, Vec<usize>, Vec<Particle>) {
    let mut nodes: Vec<Node> = trunk
        .nodes
        .iter()
        .enumerate()
        .map(|(i, &p)| Node {
            position: p,
            parent: i.checked_sub(1),
            radius: 0.0,
            kind: Kind::Trunk,
        })
        .collect();
    let trunk_ids: Vec<usize> = (0..nodes.len()).collect();
    let mut particles: Vec<Particle> = Vec::with_capacity(tips.len());
    for &(p, kind) in tips {
        particles.push(Particle {
            position: p,
            node: nodes.len(),
        });
        nodes.push(Node {
            position: p,
            parent: None,
            radius: 0.0,
            kind,
        });
    }
    (nodes, trunk_ids, particles)
}

/// The tips' mean height above the ground: the shape-format force's scale.
fn mean_height(tips: &[(DVec3, Kind)], ground_height: f64) -> f64 {
    if tips.is_empty() {
        return 0.0;
    }
    tips.iter().map(|(p, _)| p.y - ground_height).sum::<f64>() / tips.len() as f64
}

/// One step of every free particle: move, merge the ones that come close
/// into a junction, and join the trunk where it is near. Returns the
/// particles still free.
fn step(
    particles: &[Particle],
    forces: &Forces,
    trunk: &Trunk,
    trunk_ids: &[usize],
    nodes: &mut Vec<Node>,
) -> Result<Vec<Particle>> {
    let cfg = forces.cfg;
    let moved: Vec<DVec3> = particles
        .iter()
        .map(|p| forces.step(p.position, trunk))
        .collect();
    let groups = merge_groups(&moved, cfg.merge_distance)?;
    let mut next = Vec::with_capacity(groups.len());
    for group in groups {
        let position = group.iter().map(|&m| moved[m]).sum::<DVec3>() / group.len() as f64;
        let id = nodes.len();
        nodes.push(Node {
            position,
            parent: None,
            radius: 0.0,
            kind: if group.len() > 1 {
                Kind::Junction
            } else {
                Kind::Branch
            },
        });
        for &m in &group {
            nodes[particles[m].node].parent = Some(id);
        }
        let (t, d) = trunk.nearest(position);
        if d < cfg.trunk_distance {
            nodes[id].parent = Some(trunk_ids[t]);
        } else {
            next.push(Particle { position, node: id });
        }
    }
    Ok(next)
}

/// The three forces of Table 1 and the step of equations 1–3.
struct Forces<'a> {
    /// The tree's own side of its neighbours (empty for a tree alone).
    cell: &'a Cell,
    bounds: Bounds,
    attractor: DVec3,
    shape_magnitude: f64,
    wind: DVec3,
    cfg: &'a ReconstructSettings,
}

impl Forces<'_> {
    fn step(&self, p: DVec3, trunk: &Trunk) -> DVec3 {
        let (t, d) = trunk.nearest(p);
        let gravity = DVec3::new(0.0, -d, 0.0);
        let shape = (self.attractor - p).normalize_or_zero() * self.shape_magnitude;
        let c = self.cfg;
        let dir =
            (c.gravity_weight * gravity + c.shape_weight * shape + c.wind_weight * self.wind) / 3.0;
        // When the forces cancel exactly, head for the nearest trunk node so
        // the particle still arrives.
        let unit = dir
            .try_normalize()
            .unwrap_or_else(|| (trunk.nodes[t] - p).normalize_or_zero());
        let next = (p + c.beta * d * unit).clamp(self.bounds.min, self.bounds.max);
        self.cell.project(next, &self.bounds)
    }
}

/// Groups of particles to merge: walking particles in index order, each
/// particle not yet taken takes every other untaken particle closer than
/// `distance`. Groups are stars around their first member, so a junction is
/// never far from any merged particle (a transitive closure could chain a
/// whole row of particles into one junction).
fn merge_groups(points: &[DVec3], distance: f64) -> Result<Vec<Vec<usize>>> {
    let coords: Vec<[f64; 3]> = points.iter().map(|p| p.to_array()).collect();
    let index = ImmutableKdTree::<f64, 3>::builder()
        .with_serial_construction()
        .build_from_slice(&coords)
        .map_err(|e| ReconstructError::Index {
            what: "particle",
            message: e.to_string(),
        })?;
    let limit = distance * distance;
    let mut taken = vec![false; points.len()];
    let mut groups = Vec::new();
    let mut near: Vec<usize> = Vec::new();
    for i in 0..points.len() {
        if taken[i] {
            continue;
        }
        taken[i] = true;
        let mut group = vec![i];
        near.clear();
        let hits = index
            .query(&coords[i])
            .within::<SquaredEuclidean<f64>>(limit)
            .unsorted()
            .execute();
        for h in hits {
            let j = h.item as usize;
            if j < points.len() && !taken[j] && h.distance < limit {
                near.push(j);
            }
        }
        near.sort_unstable();
        for &j in &near {
            taken[j] = true;
            group.push(j);
        }
        groups.push(group);
    }
    Ok(groups)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn merge_groups_match_brute_force() {
        let mut rng = crate::rng::Rng::new(11);
        let pts: Vec<DVec3> = (0..500)
            .map(|_| DVec3::new(rng.f64(), rng.f64(), rng.f64()))
            .collect();
        let groups = merge_groups(&pts, 0.05).unwrap();
        // Same rule, all pairs.
        let mut taken = vec![false; pts.len()];
        let mut expect = Vec::new();
        for i in 0..pts.len() {
            if taken[i] {
                continue;
            }
            taken[i] = true;
            let mut g = vec![i];
            for j in 0..pts.len() {
                if !taken[j] && pts[i].distance_squared(pts[j]) < 0.05 * 0.05 {
                    taken[j] = true;
                    g.push(j);
                }
            }
            expect.push(g);
        }
        assert_eq!(groups, expect);
        assert!(groups.iter().any(|g| g.len() > 1));
    }

    #[test]
    fn many_identical_points_merge_into_one() {
        let pts = vec![DVec3::new(0.5, 1.0, -0.25); 300];
        let groups = merge_groups(&pts, 0.01).unwrap();
        assert_eq!(groups, vec![(0..300).collect::<Vec<_>>()]);
    }
}
