//! Leaves (paper §6; optional, off by default): diamond-shaped quads along
//! every branch beyond `leaf_start` × the branch's length, `leaf_density`
//! per metre, `leaf_size` long, at seeded random places and turns.

use glam::DVec3;

use crate::error::Result;
use crate::model::tree::{Kind, Tree};
use crate::reconstruct::mesh::{Bind, Mesh};
use crate::reconstruct::ReconstructSettings;
use crate::rng::Rng;

/// Label of the leaves' random stream (see `Rng::fork`).
pub const RNG_LABEL: u64 = 3;

/// The leaf quads of `tree`, as a mesh of their own (a separate glTF mesh
/// with a double-sided material).
pub fn leaves(tree: &Tree, cfg: &ReconstructSettings, seed: u64) -> Result<Mesh> {
    let mut rng = Rng::new(seed).fork(RNG_LABEL);
    let mut mesh = Mesh::default();
    for chain in tree.chains() {
        if chain.len() < 2
            || chain[1..]
                .iter()
                .all(|&n| tree.nodes[n].kind == Kind::Trunk)
        {
            continue; // the trunk carries no leaves
        }
        let points: Vec<DVec3> = chain.iter().map(|&n| tree.nodes[n].position).collect();
        let mut arc = vec![0.0];
        for w in points.windows(2) {
            let last = arc.last().copied().unwrap_or(0.0);
            arc.push(last + w[0].distance(w[1]));
        }
        let length = arc.last().copied().unwrap_or(0.0);
        let start = cfg.leaf_start * length;
        let expected = cfg.leaf_density * (length - start);
        // Stochastic rounding keeps the mean density right on short branches.
        let mut count = expected.floor() as usize;
        if rng.chance(expected - expected.floor()) {
            count += 1;
        }
        for _ in 0..count {
            let s = rng.range(start, length);
            let k = arc.partition_point(|&a| a <= s).clamp(1, points.len() - 1);
            let (a, b) = (points[k - 1], points[k]);
            let seg = arc[k] - arc[k - 1];
            let f = if seg > 0.0 {
                (s - arc[k - 1]) / seg
            } else {
                0.0
            };
            let at = a.lerp(b, f);
            let radius = tree.nodes[chain[k]].radius;
            let t = (b - a).try_normalize().unwrap_or(DVec3::Y);
            let n = t.any_orthonormal_vector();
            let phi = rng.range(0.0, std::f64::consts::TAU);
            let out = n * phi.cos() + t.cross(n) * phi.sin();
            // Leaves point outwards and a little towards the branch end.
            let axis = (out + 0.5 * t).normalize();
            let across = t.cross(axis).try_normalize().unwrap_or(n) * (0.25 * cfg.leaf_size);
            let base = at + out * radius;
            let tip = base + axis * cfg.leaf_size;
            let mid = base + axis * (0.5 * cfg.leaf_size);
            let (left, right) = (mid + across, mid - across);
            let normal = (right - base).cross(tip - base);
            // The leaf follows the point of the segment it grows from.
            let bind = Bind::between(chain[k - 1], chain[k], f)?;
            let i0 = mesh.vertex(base, normal, bind)?;
            let i1 = mesh.vertex(right, normal, bind)?;
            let i2 = mesh.vertex(tip, normal, bind)?;
            let i3 = mesh.vertex(left, normal, bind)?;
            mesh.triangle(i0, i1, i2);
            mesh.triangle(i0, i2, i3);
        }
    }
    Ok(mesh)
}
