//! The 3D convex hull of the captured tips (paper §5, Figure 6), by
//! quickhull, and uniform sampling inside it.
//!
//! Written here rather than taken from a crate: the hull is ~200 lines, the
//! crates on offer either pull in a large geometry stack or panic on
//! coplanar input, and we need a specific tolerance policy (points within
//! `eps` of a face count as inside, so coplanar markers never create
//! sliver faces or break the face adjacency).

use std::collections::HashMap;

use glam::DVec3;

use crate::rng::Rng;

/// Why a hull could not be built.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum HullError {
    /// Fewer than 4 points, or all points on one line or plane: the hull
    /// has no volume.
    #[error("the convex hull has no volume: {0}")]
    Degenerate(&'static str),
    /// Rounding broke the face adjacency (should not happen; reported rather
    /// than returning a hull with holes).
    #[error("the convex hull failed on rounding errors")]
    Numerical,
}

/// A closed convex polyhedron made of triangles whose corners are input points.
#[derive(Debug, Clone)]
pub struct Hull {
    /// The input points (faces index into these).
    pub points: Vec<DVec3>,
    /// Triangles, counter-clockwise seen from outside.
    pub faces: Vec<[usize; 3]>,
    /// Outward unit normal and plane offset (n·x = d) of each face.
    planes: Vec<(DVec3, f64)>,
    /// Distance tolerance: points this close to a face plane are on it.
    pub eps: f64,
}

struct Face {
    v: [usize; 3],
    normal: DVec3,
    offset: f64,
    outside: Vec<usize>,
    alive: bool,
}

impl Face {
    fn new(points: &[DVec3], v: [usize; 3]) -> Face {
        let [a, b, c] = v.map(|i| points[i]);
        let normal = (b - a).cross(c - a).normalize_or_zero();
        Face {
            v,
            normal,
            offset: normal.dot(a),
            outside: Vec::new(),
            alive: true,
        }
    }

    fn distance(&self, p: DVec3) -> f64 {
        self.normal.dot(p) - self.offset
    }
}

impl Hull {
    /// Quickhull over `points`. Fails when they span no volume.
    pub fn build(points: &[DVec3]) -> Result<Hull, HullError> {
        if points.len() < 4 {
            return Err(HullError::Degenerate("fewer than 4 points"));
        }
        if points.iter().any(|p| !p.is_finite()) {
            return Err(HullError::Degenerate("a point is not finite"));
        }
        let lo = points.iter().fold(points[0], |m, p| m.min(*p));
        let hi = points.iter().fold(points[0], |m, p| m.max(*p));
        // Relative tolerance: rounding in plane distances grows with the
        // coordinates' magnitude, not only with the cloud's size.
        let size = (hi - lo).length() + lo.abs().max(hi.abs()).length();
        let eps = 1e-10 * size.max(f64::MIN_POSITIVE);
        let mut b = Builder::start(points, eps)?;
        // Work on the lowest-index face with outside points, so the hull
        // (and the random tips drawn in it) is the same on every run.
        let mut cursor = 0;
        while cursor < b.faces.len() {
            if !b.faces[cursor].alive || b.faces[cursor].outside.is_empty() {
                cursor += 1;
                continue;
            }
            let first_new = b.add_eye_of(cursor)?;
            cursor = cursor.min(first_new);
        }
        let alive: Vec<&Face> = b.faces.iter().filter(|f| f.alive).collect();
        Ok(Hull {
            points: points.to_vec(),
            faces: alive.iter().map(|f| f.v).collect(),
            planes: alive.iter().map(|f| (f.normal, f.offset)).collect(),
            eps,
        })
    }

    /// True when `p` is inside or within `eps` of the surface.
    pub fn contains(&self, p: DVec3) -> bool {
        self.planes.iter().all(|(n, d)| n.dot(p) - d <= self.eps)
    }

    /// Enclosed volume (m³).
    pub fn volume(&self) -> f64 {
        let c = self.centre();
        self.tetrahedra(c).iter().sum()
    }

    /// A point strictly inside (the mean of the hull's corner points).
    fn centre(&self) -> DVec3 {
        let mut used: Vec<usize> = self.faces.iter().flatten().copied().collect();
        used.sort_unstable();
        used.dedup();
        used.iter().map(|&i| self.points[i]).sum::<DVec3>() / used.len().max(1) as f64
    }

    /// Volume of the tetrahedron (c, face) for every face.
    fn tetrahedra(&self, c: DVec3) -> Vec<f64> {
        self.faces
            .iter()
            .map(|f| {
                let [a, b, d] = f.map(|i| self.points[i] - c);
                a.dot(b.cross(d)) / 6.0
            })
            .collect()
    }

    /// `count` points uniformly distributed inside the hull: a face's
    /// tetrahedron (with the centre) is chosen in proportion to its volume,
    /// then a point uniformly inside it.
    pub fn sample(&self, count: usize, rng: &mut Rng) -> Vec<DVec3> {
        self.sample_where(count, rng, |_| true, count)
    }

    /// Like [`Hull::sample`], keeping only the points `keep` accepts, with
    /// at most `tries` draws in all (so a `keep` that accepts little cannot
    /// loop for ever). With a `keep` that accepts everything the draws are
    /// exactly those of `sample`.
    pub fn sample_where(
        &self,
        count: usize,
        rng: &mut Rng,
        keep: impl Fn(DVec3) -> bool,
        tries: usize,
    ) -> Vec<DVec3> {
        let c = self.centre();
        let vols = self.tetrahedra(c);
        let mut cumulative = Vec::with_capacity(vols.len());
        let mut total = 0.0;
        for v in &vols {
            total += v.max(0.0);
            cumulative.push(total);
        }
        let mut out = Vec::with_capacity(count);
        if total <= 0.0 {
            return out;
        }
        for _ in 0..tries {
            if out.len() == count {
                break;
            }
            let pick = rng.f64() * total;
            let k = cumulative
                .partition_point(|&s| s <= pick)
                .min(self.faces.len() - 1);
            let [a, b, d] = self.faces[k].map(|i| self.points[i]);
            let p = in_tetrahedron(c, a, b, d, rng);
            if keep(p) {
                out.push(p);
            }
        }
        out
    }
}

/// Quickhull's working state: the faces so far (dead ones stay, so indices
/// are stable) and the directed edges that index them.
struct Builder<'a> {
    points: &'a [DVec3],
    eps: f64,
    faces: Vec<Face>,
    edges: HashMap<(usize, usize), usize>,
}

impl<'a> Builder<'a> {
    /// The initial simplex, oriented outwards, with every other point given
    /// to the first face it lies outside of.
    fn start(points: &'a [DVec3], eps: f64) -> Result<Self, HullError> {
        let simplex = initial_simplex(points, eps)?;
        let centre = simplex.iter().map(|&i| points[i]).sum::<DVec3>() / 4.0;
        let mut b = Builder {
            points,
            eps,
            faces: Vec::new(),
            edges: HashMap::new(),
        };
        let [a, bb, c, d] = simplex;
        for tri in [[a, bb, c], [a, d, bb], [bb, d, c], [c, d, a]] {
            let mut f = Face::new(points, tri);
            if f.distance(centre) > 0.0 {
                f = Face::new(points, [tri[0], tri[2], tri[1]]);
            }
            add_face(&mut b.faces, &mut b.edges, f)?;
        }
        for (i, &p) in points.iter().enumerate() {
            if simplex.contains(&i) {
                continue;
            }
            if let Some(f) = b.faces.iter_mut().find(|f| f.distance(p) > eps) {
                f.outside.push(i);
            }
        }
        Ok(b)
    }

    /// Adds the farthest outside point of face `cursor` (the eye): the faces
    /// it sees are replaced by a cone from the horizon to the eye. Returns
    /// the index of the first new face.
    fn add_eye_of(&mut self, cursor: usize) -> Result<usize, HullError> {
        let f = &self.faces[cursor];
        let mut eye = f.outside[0];
        let mut best = f.distance(self.points[eye]);
        for &i in &f.outside[1..] {
            let dist = f.distance(self.points[i]);
            if dist > best {
                best = dist;
                eye = i;
            }
        }
        let visible = self.visible_from(cursor, self.points[eye])?;
        let horizon = self.horizon(&visible)?;
        let mut orphans = Vec::new();
        for &fi in &visible {
            let face = &mut self.faces[fi];
            face.alive = false;
            orphans.append(&mut face.outside);
            let v = face.v;
            for k in 0..3 {
                self.edges.remove(&(v[k], v[(k + 1) % 3]));
            }
        }
        let first_new = self.faces.len();
        for (u, w) in horizon {
            let face = Face::new(self.points, [u, w, eye]);
            add_face(&mut self.faces, &mut self.edges, face)?;
        }
        for i in orphans {
            if i == eye {
                continue;
            }
            let p = self.points[i];
            let eps = self.eps;
            if let Some(f) = self.faces[first_new..]
                .iter_mut()
                .find(|f| f.distance(p) > eps)
            {
                f.outside.push(i);
            }
        }
        Ok(first_new)
    }

    /// The faces that see `eye`, grown from face `from` across edges.
    fn visible_from(&self, from: usize, eye: DVec3) -> Result<Vec<usize>, HullError> {
        let mut visible = vec![from];
        let mut seen = vec![from];
        let mut head = 0;
        while let Some(&fi) = visible.get(head) {
            head += 1;
            let v = self.faces[fi].v;
            for k in 0..3 {
                let nb = *self
                    .edges
                    .get(&(v[(k + 1) % 3], v[k]))
                    .ok_or(HullError::Numerical)?;
                if !seen.contains(&nb) {
                    seen.push(nb);
                    if self.faces[nb].distance(eye) > self.eps {
                        visible.push(nb);
                    }
                }
            }
        }
        Ok(visible)
    }

    /// Edges of the visible faces whose neighbour is not visible, kept in the
    /// visible faces' orientation.
    fn horizon(&self, visible: &[usize]) -> Result<Vec<(usize, usize)>, HullError> {
        let mut horizon = Vec::new();
        for &fi in visible {
            let v = self.faces[fi].v;
            for k in 0..3 {
                let (u, w) = (v[k], v[(k + 1) % 3]);
                let nb = *self.edges.get(&(w, u)).ok_or(HullError::Numerical)?;
                if !visible.contains(&nb) {
                    horizon.push((u, w));
                }
            }
        }
        Ok(horizon)
    }
}

fn add_face(
    faces: &mut Vec<Face>,
    edges: &mut HashMap<(usize, usize), usize>,
    face: Face,
) -> Result<(), HullError> {
    let id = faces.len();
    let v = face.v;
    for k in 0..3 {
        if edges.insert((v[k], v[(k + 1) % 3]), id).is_some() {
            return Err(HullError::Numerical);
        }
    }
    faces.push(face);
    Ok(())
}

/// Four points spanning a volume: the farthest pair among the axis
/// extremes, the point farthest from their line, the point farthest from
/// that plane.
fn initial_simplex(points: &[DVec3], eps: f64) -> Result<[usize; 4], HullError> {
    let mut extremes = [0usize; 6];
    for (i, p) in points.iter().enumerate() {
        for axis in 0..3 {
            if p[axis] < points[extremes[2 * axis]][axis] {
                extremes[2 * axis] = i;
            }
            if p[axis] > points[extremes[2 * axis + 1]][axis] {
                extremes[2 * axis + 1] = i;
            }
        }
    }
    let (mut a, mut b, mut best) = (0, 0, -1.0);
    for &i in &extremes {
        for &j in &extremes {
            let d = points[i].distance_squared(points[j]);
            if d > best {
                (a, b, best) = (i, j, d);
            }
        }
    }
    if best.sqrt() <= eps {
        return Err(HullError::Degenerate("all points coincide"));
    }
    let ab = (points[b] - points[a]).normalize();
    let farthest = |score: &dyn Fn(DVec3) -> f64| {
        let mut best = (0usize, -1.0f64);
        for (i, p) in points.iter().enumerate() {
            let s = score(*p);
            if s > best.1 {
                best = (i, s);
            }
        }
        best
    };
    let (c, dist) = farthest(&|p| {
        let v = p - points[a];
        (v - ab * v.dot(ab)).length()
    });
    if dist <= eps {
        return Err(HullError::Degenerate("all points lie on one line"));
    }
    let n = (points[b] - points[a])
        .cross(points[c] - points[a])
        .normalize();
    let (d, dist) = farthest(&|p| n.dot(p - points[a]).abs());
    if dist <= eps {
        return Err(HullError::Degenerate("all points lie in one plane"));
    }
    Ok([a, b, c, d])
}

/// Uniform point in a tetrahedron (Rocchini & Cignoni 2000: fold the unit
/// cube into the unit simplex).
fn in_tetrahedron(p0: DVec3, p1: DVec3, p2: DVec3, p3: DVec3, rng: &mut Rng) -> DVec3 {
    let (mut s, mut t, mut u) = (rng.f64(), rng.f64(), rng.f64());
    if s + t > 1.0 {
        s = 1.0 - s;
        t = 1.0 - t;
    }
    if t + u > 1.0 {
        let tmp = u;
        u = 1.0 - s - t;
        t = 1.0 - tmp;
    } else if s + t + u > 1.0 {
        let tmp = u;
        u = s + t + u - 1.0;
        s = 1.0 - t - tmp;
    }
    let a = 1.0 - s - t - u;
    p0 * a + p1 * s + p2 * t + p3 * u
}

#[cfg(test)]
mod tests {
    use super::*;

    fn edge_count_ok(h: &Hull) {
        // A closed triangulated sphere: every directed edge has its twin and
        // V − E + F = 2.
        let mut directed = std::collections::HashSet::new();
        let mut verts = std::collections::HashSet::new();
        for f in &h.faces {
            for k in 0..3 {
                assert!(directed.insert((f[k], f[(k + 1) % 3])), "edge used twice");
                verts.insert(f[k]);
            }
        }
        for &(u, w) in &directed {
            assert!(directed.contains(&(w, u)), "open edge {u}-{w}");
        }
        let (v, e, f) = (
            verts.len() as i64,
            directed.len() as i64 / 2,
            h.faces.len() as i64,
        );
        assert_eq!(v - e + f, 2);
    }

    #[test]
    fn cube_with_interior_and_coplanar_points() {
        // The 8 corners, a 5×5 grid on every face (coplanar points, the
        // classic quickhull trap) and random interior points: the hull is
        // the unit cube, volume exactly 1, made only of corners... or of
        // face points, but in any case enclosing everything.
        let mut pts = Vec::new();
        for k in 0..8 {
            pts.push(DVec3::new(
                (k & 1) as f64,
                ((k >> 1) & 1) as f64,
                ((k >> 2) & 1) as f64,
            ));
        }
        for axis in 0..3 {
            for side in [0.0, 1.0] {
                for i in 0..5 {
                    for j in 0..5 {
                        let mut p = [0.0; 3];
                        p[axis] = side;
                        p[(axis + 1) % 3] = i as f64 / 4.0;
                        p[(axis + 2) % 3] = j as f64 / 4.0;
                        pts.push(DVec3::from_array(p));
                    }
                }
            }
        }
        let mut rng = Rng::new(5);
        for _ in 0..200 {
            pts.push(DVec3::new(rng.f64(), rng.f64(), rng.f64()));
        }
        let h = Hull::build(&pts).unwrap();
        assert!((h.volume() - 1.0).abs() < 1e-12, "{}", h.volume());
        edge_count_ok(&h);
        for p in &pts {
            assert!(h.contains(*p));
        }
        assert!(!h.contains(DVec3::new(0.5, 1.0 + 1e-6, 0.5)));
    }

    #[test]
    fn sphere_points_approach_the_ball_volume() {
        let mut rng = Rng::new(2);
        let pts: Vec<DVec3> = (0..2000)
            .map(|_| DVec3::new(rng.normal(), rng.normal(), rng.normal()).normalize() * 2.0)
            .collect();
        let h = Hull::build(&pts).unwrap();
        edge_count_ok(&h);
        // Every point is on the sphere, hence a hull vertex.
        let mut used: Vec<usize> = h.faces.iter().flatten().copied().collect();
        used.sort_unstable();
        used.dedup();
        assert_eq!(used.len(), pts.len());
        let ball = 4.0 / 3.0 * std::f64::consts::PI * 8.0;
        assert!(
            h.volume() < ball && h.volume() > 0.98 * ball,
            "{}",
            h.volume()
        );
    }

    #[test]
    fn tetrahedron_volume_and_samples() {
        let pts = [
            DVec3::new(1.0, 2.0, 3.0),
            DVec3::new(3.0, 2.0, 3.0),
            DVec3::new(1.0, 5.0, 3.0),
            DVec3::new(1.0, 2.0, 7.0),
        ];
        let h = Hull::build(&pts).unwrap();
        // (2 × 3 × 4) / 6 = 4.
        assert!((h.volume() - 4.0).abs() < 1e-12);
        let mut rng = Rng::new(1);
        let s = h.sample(20_000, &mut rng);
        // Uniform in a tetrahedron: the mean is the centroid.
        let mean = s.iter().sum::<DVec3>() / s.len() as f64;
        let centroid = pts.iter().sum::<DVec3>() / 4.0;
        assert!(mean.distance(centroid) < 0.03, "{mean} vs {centroid}");
        assert!(s.iter().all(|p| h.contains(*p)));
    }

    #[test]
    fn duplicates_and_near_coplanar_jitter_stay_closed() {
        // Marker data: repeated positions and points a hair off the faces
        // of a box, in a place far from the origin (capture coordinates).
        let mut rng = Rng::new(8);
        let offset = DVec3::new(1200.0, 3.0, -800.0);
        let mut pts = Vec::new();
        for _ in 0..400 {
            let mut p = DVec3::new(rng.f64(), rng.f64(), rng.f64());
            let axis = rng.int(0, 2) as usize;
            p[axis] = if rng.chance(0.5) { 0.0 } else { 1.0 };
            p += DVec3::new(rng.normal(), rng.normal(), rng.normal()) * 1e-12;
            pts.push(p + offset);
            if rng.chance(0.2) {
                pts.push(p + offset);
            }
        }
        for k in 0..8 {
            pts.push(
                offset + DVec3::new((k & 1) as f64, ((k >> 1) & 1) as f64, ((k >> 2) & 1) as f64),
            );
        }
        let h = Hull::build(&pts).unwrap();
        edge_count_ok(&h);
        assert!((h.volume() - 1.0).abs() < 1e-6, "{}", h.volume());
        assert!(pts.iter().all(|p| h.contains(*p)));
    }

    #[test]
    fn degenerate_inputs_are_errors() {
        let flat: Vec<DVec3> = (0..10)
            .map(|i| DVec3::new(i as f64, (i * i) as f64, 0.0))
            .collect();
        assert!(matches!(Hull::build(&flat), Err(HullError::Degenerate(_))));
        let line: Vec<DVec3> = (0..10).map(|i| DVec3::splat(i as f64)).collect();
        assert!(matches!(Hull::build(&line), Err(HullError::Degenerate(_))));
        assert!(Hull::build(&[DVec3::ZERO; 3]).is_err());
        assert!(Hull::build(&[DVec3::ONE; 8]).is_err());
    }
}
