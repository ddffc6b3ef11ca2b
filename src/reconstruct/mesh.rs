//! The branch surface (spec §7): a generalized cylinder around every chain
//! of the tree, a ring of `sides` vertices per node. Rings are carried along
//! a chain by parallel transport (each ring's frame is the previous one
//! rotated by the minimal rotation between the two tangents), so the
//! cylinders never twist; chain ends are capped and every vertex has a
//! normal.

use std::f64::consts::TAU;

use glam::{DQuat, DVec3};

use crate::error::Result;
use crate::model::tree::Tree;
use crate::reconstruct::error::ReconstructError;

/// Which skeleton nodes a vertex follows when the tree moves (the skin of
/// the animated glTF): `nodes[0]` with `weight`, `nodes[1]` with the rest.
/// A ring vertex follows its own node; a leaf follows the point of the
/// segment it grows from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bind {
    /// The two nodes (equal when the vertex follows one).
    pub nodes: [u32; 2],
    /// Weight of `nodes[0]`, 0 to 1.
    pub weight: f32,
}

impl Bind {
    /// Follows node `n` alone.
    pub fn node(n: usize) -> Result<Bind> {
        let n = node_index(n)?;
        Ok(Bind {
            nodes: [n, n],
            weight: 1.0,
        })
    }

    /// Follows the point `f` (0 to 1) of the way from node `a` to node `b`.
    pub fn between(a: usize, b: usize, f: f64) -> Result<Bind> {
        Ok(Bind {
            nodes: [node_index(a)?, node_index(b)?],
            weight: (1.0 - f).clamp(0.0, 1.0) as f32,
        })
    }
}

fn node_index(n: usize) -> Result<u32> {
    u32::try_from(n).map_err(|_| ReconstructError::TooLarge { what: "the tree" }.into())
}

/// A triangle mesh as glTF wants it: f32 positions and unit normals, u32
/// indices, counter-clockwise triangles seen from outside.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions (m).
    pub positions: Vec<[f32; 3]>,
    /// Unit vertex normals.
    pub normals: Vec<[f32; 3]>,
    /// The skeleton nodes each vertex follows.
    pub binds: Vec<Bind>,
    /// Three indices per triangle.
    pub indices: Vec<u32>,
}

impl Mesh {
    /// Adds a vertex that follows `bind` and returns its index.
    pub fn vertex(&mut self, p: DVec3, n: DVec3, bind: Bind) -> Result<u32> {
        let i = u32::try_from(self.positions.len())
            .map_err(|_| ReconstructError::TooLarge { what: "the mesh" })?;
        self.binds.push(bind);
        self.positions.push(p.as_vec3().to_array());
        self.normals.push(
            n.try_normalize()
                .unwrap_or(DVec3::Y)
                .as_vec3()
                .normalize()
                .to_array(),
        );
        Ok(i)
    }

    /// Adds one triangle.
    pub fn triangle(&mut self, a: u32, b: u32, c: u32) {
        self.indices.extend_from_slice(&[a, b, c]);
    }

    /// Number of triangles.
    pub fn triangles(&self) -> usize {
        self.indices.len() / 3
    }
}

/// Generalized cylinders around every chain of `tree`.
pub fn branches(tree: &Tree, sides: usize) -> Result<Mesh> {
    let sides = sides.max(3);
    let children = tree.children();
    let mut mesh = Mesh::default();
    for (c, chain) in tree.chains().iter().enumerate() {
        if chain.len() < 2 {
            continue;
        }
        let points: Vec<DVec3> = chain.iter().map(|&n| tree.nodes[n].position).collect();
        let mut radii: Vec<f64> = chain.iter().map(|&n| tree.nodes[n].radius).collect();
        let is_trunk_chain = c == 0;
        if !is_trunk_chain {
            // A side chain starts inside its parent node: use the branch's
            // own radius there, not the parent's.
            radii[0] = radii[1];
        }
        let tangents = tangents(&points);
        let frames = transport(&tangents);

        let mut rings = Vec::with_capacity(points.len());
        for i in 0..points.len() {
            let (n, b) = frames[i];
            let first = mesh.positions.len();
            let bind = Bind::node(chain[i])?;
            for j in 0..sides {
                let (s, co) = (TAU * j as f64 / sides as f64).sin_cos();
                let dir = n * co + b * s;
                mesh.vertex(points[i] + dir * radii[i], dir, bind)?;
            }
            rings.push(first as u32);
        }
        for w in rings.windows(2) {
            let (r0, r1) = (w[0], w[1]);
            for j in 0..sides as u32 {
                let k = (j + 1) % sides as u32;
                mesh.triangle(r0 + j, r0 + k, r1 + k);
                mesh.triangle(r0 + j, r1 + k, r1 + j);
            }
        }
        let last = points.len() - 1;
        if children[chain[last]].is_empty() {
            cap(
                &mut mesh,
                (points[last], Bind::node(chain[last])?),
                tangents[last],
                frames[last],
                radii[last],
                sides,
            )?;
        }
        if is_trunk_chain {
            cap(
                &mut mesh,
                (points[0], Bind::node(chain[0])?),
                -tangents[0],
                frames[0],
                radii[0],
                sides,
            )?;
        }
    }
    Ok(mesh)
}

/// A flat disc closing a cylinder end, facing `outward`; its vertices
/// follow the end's node.
fn cap(
    mesh: &mut Mesh,
    (centre, bind): (DVec3, Bind),
    outward: DVec3,
    (n, b): (DVec3, DVec3),
    radius: f64,
    sides: usize,
) -> Result<()> {
    let c = mesh.vertex(centre, outward, bind)?;
    let mut ring = Vec::with_capacity(sides);
    for j in 0..sides {
        let (s, co) = (TAU * j as f64 / sides as f64).sin_cos();
        ring.push(mesh.vertex(centre + (n * co + b * s) * radius, outward, bind)?);
    }
    // The ring runs counter-clockwise around the chain's tangent; a cap
    // facing backwards must wind the other way.
    let forward = outward.dot(n.cross(b)) > 0.0;
    for j in 0..sides {
        let (a, d) = (ring[j], ring[(j + 1) % sides]);
        if forward {
            mesh.triangle(c, a, d);
        } else {
            mesh.triangle(c, d, a);
        }
    }
    Ok(())
}

/// Unit tangents: the mean of the incoming and outgoing directions; a
/// zero-length segment borrows its neighbour's direction.
fn tangents(points: &[DVec3]) -> Vec<DVec3> {
    let segs: Vec<Option<DVec3>> = points
        .windows(2)
        .map(|w| (w[1] - w[0]).try_normalize())
        .collect();
    // Fill gaps so every segment has a direction (Y if the whole chain is a point).
    let mut fill = vec![DVec3::Y; segs.len()];
    let mut last = segs.iter().flatten().next().copied().unwrap_or(DVec3::Y);
    for (i, s) in segs.iter().enumerate() {
        if let Some(d) = s {
            last = *d;
        }
        fill[i] = last;
    }
    (0..points.len())
        .map(|i| {
            let before = i.checked_sub(1).map(|k| fill[k]);
            let after = fill.get(i).copied();
            match (before, after) {
                (Some(a), Some(b)) => (a + b).try_normalize().unwrap_or(b),
                (Some(a), None) => a,
                (None, Some(b)) => b,
                (None, None) => DVec3::Y,
            }
        })
        .collect()
}

/// Parallel-transported (normal, binormal) frames along the tangents.
fn transport(tangents: &[DVec3]) -> Vec<(DVec3, DVec3)> {
    let mut frames = Vec::with_capacity(tangents.len());
    let Some(&t0) = tangents.first() else {
        return frames;
    };
    let mut n = t0.any_orthonormal_vector();
    frames.push((n, t0.cross(n)));
    for w in tangents.windows(2) {
        let (a, b) = (w[0], w[1]);
        n = DQuat::from_rotation_arc(a, b) * n;
        // Re-orthogonalise against rounding drift.
        n = (n - b * n.dot(b))
            .try_normalize()
            .unwrap_or_else(|| b.any_orthonormal_vector());
        frames.push((n, b.cross(n)));
    }
    frames
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_do_not_twist_on_a_planar_bend() {
        // A quarter circle in the x-y plane: the binormal of a twist-free
        // frame keeps a constant angle to the plane's normal (z), so the ring
        // vertex that starts on one side of the plane stays on that side.
        let points: Vec<DVec3> = (0..=20)
            .map(|i| {
                let a = i as f64 / 20.0 * std::f64::consts::FRAC_PI_2;
                DVec3::new(a.cos(), a.sin(), 0.0)
            })
            .collect();
        let t = tangents(&points);
        let f = transport(&t);
        let z0 = f[0].0.dot(DVec3::Z);
        for (n, b) in &f {
            assert!((n.dot(DVec3::Z) - z0).abs() < 1e-9);
            assert!(n.length() - 1.0 < 1e-12 && b.length() - 1.0 < 1e-12);
        }
        for (i, (n, _)) in f.iter().enumerate() {
            assert!(n.dot(t[i]).abs() < 1e-12);
        }
    }

    #[test]
    fn caps_face_outward_and_normals_are_unit() {
        use crate::model::tree::{Kind, Node, Tree};
        let node = |y: f64, parent| Node {
            position: DVec3::new(0.0, y, 0.0),
            parent,
            radius: 0.1,
            kind: Kind::Trunk,
        };
        let tree = Tree {
            nodes: vec![node(0.0, None), node(1.0, Some(0)), node(2.0, Some(1))],
            trunk: vec![0, 1, 2],
            attractor: 0,
            forced_joins: 0,
            steps: 0,
            wind: DVec3::ZERO,
        };
        let m = branches(&tree, 6).unwrap();
        // 3 rings + 2 caps of (1 + 6) vertices; 2 × 6 × 2 side + 2 × 6 cap triangles.
        assert_eq!(m.positions.len(), 3 * 6 + 2 * 7);
        assert_eq!(m.triangles(), 24 + 12);
        for n in &m.normals {
            let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            assert!((l - 1.0).abs() < 1e-6);
        }
        // Every triangle's winding normal points away from the axis or
        // along the caps' outward direction: the mesh is closed, so its
        // signed volume is positive and equals the prism's (6-gon area × 2).
        let p: Vec<DVec3> = m
            .positions
            .iter()
            .map(|v| DVec3::from(v.map(f64::from)))
            .collect();
        let vol: f64 = m
            .indices
            .chunks(3)
            .map(|t| p[t[0] as usize].dot(p[t[1] as usize].cross(p[t[2] as usize])) / 6.0)
            .sum();
        let hexagon = 1.5 * 3f64.sqrt() * 0.01;
        assert!((vol - 2.0 * hexagon).abs() < 1e-6, "{vol}");
    }
}
