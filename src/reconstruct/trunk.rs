//! The synthetic trunk (paper §5, Figure 4; spec §6): a vertical line under
//! the crown centre, cut into nodes with random x/z offsets, plus the two
//! trunk queries the flow needs: the root attractor S_r and the nearest trunk
//! node S_t of a particle.

use glam::DVec3;
use kiddo::{ImmutableKdTree, SquaredEuclidean};

use crate::error::Result;
use crate::reconstruct::error::ReconstructError;
use crate::reconstruct::ReconstructSettings;
use crate::rng::Rng;

/// Trunk nodes and a nearest-neighbour index over them.
pub struct Trunk {
    /// Node positions, base first (the base is the tree's root).
    pub nodes: Vec<DVec3>,
    /// Index of the root attractor S_r in `nodes`.
    pub attractor: usize,
    index: ImmutableKdTree<f64, 3>,
}

/// Axis-aligned bounds of a point set.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bounds {
    /// Smallest x, y, z.
    pub min: DVec3,
    /// Largest x, y, z.
    pub max: DVec3,
}

impl Bounds {
    /// Bounds of `points`; `None` when there are none.
    pub fn of(points: impl IntoIterator<Item = DVec3>) -> Option<Bounds> {
        let mut it = points.into_iter();
        let first = it.next()?;
        let mut b = Bounds {
            min: first,
            max: first,
        };
        for p in it {
            b.min = b.min.min(p);
            b.max = b.max.max(p);
        }
        Some(b)
    }
}

impl Trunk {
    /// Builds the trunk for captured tips with the given bounds, under the
    /// crown's centre.
    pub fn build(crown: Bounds, cfg: &ReconstructSettings, rng: &mut Rng) -> Result<Trunk> {
        let centre_x = 0.5 * (crown.min.x + crown.max.x);
        let centre_z = 0.5 * (crown.min.z + crown.max.z);
        Trunk::build_at(centre_x, centre_z, crown, cfg, rng)
    }

    /// Builds the trunk standing at (`centre_x`, `ground_height`,
    /// `centre_z`): a configured trunk base of several trees.
    pub fn build_at(
        centre_x: f64,
        centre_z: f64,
        crown: Bounds,
        cfg: &ReconstructSettings,
        rng: &mut Rng,
    ) -> Result<Trunk> {
        let n = cfg.trunk_nodes.max(2);
        let height = cfg.height_factor * (crown.max.y - crown.min.y);
        let mut nodes = Vec::with_capacity(n);
        for i in 0..n {
            let y = cfg.ground_height + height * i as f64 / (n - 1) as f64;
            // The base keeps the crown centre so the tree stands where it
            // stood; the paper offsets "these nodes" without saying which.
            let (dx, dz) = if i == 0 {
                (0.0, 0.0)
            } else {
                (
                    rng.range(-cfg.trunk_offset, cfg.trunk_offset),
                    rng.range(-cfg.trunk_offset, cfg.trunk_offset),
                )
            };
            nodes.push(DVec3::new(centre_x + dx, y, centre_z + dz));
        }
        let points: Vec<[f64; 3]> = nodes.iter().map(|p| p.to_array()).collect();
        let index = ImmutableKdTree::<f64, 3>::builder()
            .with_serial_construction()
            .build_from_slice(&points)
            .map_err(|e| ReconstructError::Index {
                what: "trunk",
                message: e.to_string(),
            })?;
        let attractor = if cfg.attractor_node >= 0 {
            (cfg.attractor_node as usize).min(n - 1)
        } else {
            // Paper: "the trunk node closest to the lower bound of the
            // bounding box for the entire crown".
            let lower = DVec3::new(centre_x, crown.min.y, centre_z);
            nearest_linear(&nodes, lower)
        };
        Ok(Trunk {
            nodes,
            attractor,
            index,
        })
    }

    /// The root attractor S_r.
    pub fn attractor_point(&self) -> DVec3 {
        self.nodes[self.attractor]
    }

    /// The nearest trunk node S_t to `p`: (index, distance).
    pub fn nearest(&self, p: DVec3) -> (usize, f64) {
        let hit = self
            .index
            .query(&p.to_array())
            .nearest_one::<SquaredEuclidean<f64>>()
            .execute();
        (hit.item as usize, hit.distance.sqrt())
    }
}

/// Index of the point nearest to `q` (ties to the lower index).
fn nearest_linear(points: &[DVec3], q: DVec3) -> usize {
    let mut best = 0;
    let mut best_d = f64::INFINITY;
    for (i, p) in points.iter().enumerate() {
        let d = p.distance_squared(q);
        if d < best_d {
            best = i;
            best_d = d;
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    fn crown() -> Bounds {
        Bounds {
            min: DVec3::new(-0.5, 1.0, 2.0),
            max: DVec3::new(0.5, 2.0, 3.0),
        }
    }

    #[test]
    fn trunk_stands_under_the_crown_centre() {
        let cfg = ReconstructSettings::default();
        let t = Trunk::build(crown(), &cfg, &mut Rng::new(1)).unwrap();
        assert_eq!(t.nodes.len(), cfg.trunk_nodes);
        // Base at the ground under the centre (0, ground, 2.5).
        assert_eq!(t.nodes[0], DVec3::new(0.0, 0.0, 2.5));
        // Top at height_factor × crown height = 1.2 × 1.0.
        let top = t.nodes[cfg.trunk_nodes - 1];
        assert!((top.y - 1.2).abs() < 1e-12);
        for p in &t.nodes {
            assert!((p.x).abs() <= cfg.trunk_offset && (p.z - 2.5).abs() <= cfg.trunk_offset);
        }
        // The crown's lower bound is y = 1.0; nodes are 1.2/9 apart, so the
        // nearest is node round(1.0 / (1.2/9)) = round(7.5): node 7 or 8.
        assert!(t.attractor == 7 || t.attractor == 8, "{}", t.attractor);
    }

    #[test]
    fn nearest_matches_a_linear_scan() {
        let cfg = ReconstructSettings::default();
        let t = Trunk::build(crown(), &cfg, &mut Rng::new(3)).unwrap();
        let mut rng = Rng::new(9);
        for _ in 0..200 {
            let q = DVec3::new(
                rng.range(-1.0, 1.0),
                rng.range(-0.5, 3.0),
                rng.range(1.5, 3.5),
            );
            let (i, d) = t.nearest(q);
            let j = nearest_linear(&t.nodes, q);
            assert!((t.nodes[j].distance(q) - d).abs() < 1e-12, "{i} vs {j}");
        }
    }

    #[test]
    fn attractor_can_be_chosen() {
        let cfg = ReconstructSettings {
            attractor_node: 0,
            ..Default::default()
        };
        let t = Trunk::build(crown(), &cfg, &mut Rng::new(1)).unwrap();
        assert_eq!(t.attractor, 0);
        assert_eq!(t.attractor_point(), t.nodes[0]);
    }
}
