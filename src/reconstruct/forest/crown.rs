//! A crown as a surface of revolution around a (possibly leaning) axis:
//! the horizontal radius squared is a quadratic in height,
//! `r(y)² = a + b·y + c·y²`. An ellipsoid (a maple's round crown), a cone (a
//! pine) and a paraboloid all have this form, and the fit is linear: with
//! `x, z` relative to an anchor and `y` relative to the tips' mean height,
//!
//! ```text
//! x² + z² = 2·ox·x + 2·oz·z + a + b·y + c·y²  [+ 2·tx·x·y + 2·tz·z·y]
//! ```
//!
//! where `(ox, oz)` is the axis's offset from the anchor and `(tx, tz)` its
//! lean. A ridge term keeps the offset near the anchor (the trunk base) when
//! the tips cannot tell it; it is weak when the crown is used to find the
//! trees and strong when the bases are known.

use glam::DVec3;

/// Unknowns of the fit: ox, oz, a, b, c, tx, tz.
const UNKNOWNS: usize = 7;

/// A fitted crown surface.
#[derive(Debug, Clone, PartialEq)]
pub struct Crown {
    /// The point the fit is relative to (x, z: the anchor; y: the tips'
    /// mean height).
    origin: DVec3,
    /// ox, oz, a, b, c, tx, tz.
    p: [f64; UNKNOWNS],
    /// Height range of the tips fitted (relative to `origin.y`): beyond it
    /// the crown has no surface and the distance grows with the height.
    y_range: (f64, f64),
}

/// How the fit may move the axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitOptions {
    /// Ridge weight per tip on the axis offset (m⁻² scale): large pins the
    /// axis to the anchor, small lets the tips place it.
    pub offset_ridge: f64,
    /// Let the axis lean (needs at least 8 tips; fewer fit upright).
    pub lean: bool,
    /// Weight each tip by 1/its distance from the axis, so the fit
    /// minimises distances rather than squared radii (see [`weight`]).
    pub weighted: bool,
}

impl Crown {
    /// Fits the crown surface to `tips` around `anchor` (only its x and z
    /// are used). `None` for fewer than 4 tips or a degenerate set (all at
    /// one height, all on a line).
    pub fn fit(tips: &[DVec3], anchor: DVec3, opts: FitOptions) -> Option<Crown> {
        if tips.len() < 4 {
            return None;
        }
        let mean_y = tips.iter().map(|p| p.y).sum::<f64>() / tips.len() as f64;
        let origin = DVec3::new(anchor.x, mean_y, anchor.z);
        let lean = opts.lean && tips.len() >= 8;
        let k = if lean { 7 } else { 5 };
        let mut ata = [[0.0; UNKNOWNS]; UNKNOWNS];
        let mut atb = [0.0; UNKNOWNS];
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for &t in tips {
            let q = t - origin;
            lo = lo.min(q.y);
            hi = hi.max(q.y);
            let row = [
                2.0 * q.x,
                2.0 * q.z,
                1.0,
                q.y,
                q.y * q.y,
                2.0 * q.x * q.y,
                2.0 * q.z * q.y,
            ];
            let rhs = q.x * q.x + q.z * q.z;
            // The residual of a row is in m² (≈ 2·r·δr): weighting it by
            // 1/r makes it a distance, so the narrow top of a cone counts
            // as much as its wide base (ours; without it the fit sacrifices
            // a pine's top, and tips there go to a neighbour).
            let w = if opts.weighted {
                weight(rhs.sqrt())
            } else {
                1.0
            };
            for i in 0..k {
                atb[i] += w * w * row[i] * rhs;
                for j in 0..k {
                    ata[i][j] += w * w * row[i] * row[j];
                }
            }
        }
        let ridge = opts.offset_ridge.max(0.0) * tips.len() as f64;
        for i in [0, 1, 5, 6].into_iter().filter(|&i| i < k) {
            ata[i][i] += ridge;
        }
        let p = solve(ata, atb, k)?;
        Some(Crown {
            origin,
            p,
            y_range: (lo, hi),
        })
    }

    /// The axis's horizontal position at height `y` (absolute).
    pub fn axis_at(&self, y: f64) -> DVec3 {
        let yc = (y - self.origin.y).clamp(self.y_range.0, self.y_range.1);
        DVec3::new(
            self.origin.x + self.p[0] + self.p[5] * yc,
            y,
            self.origin.z + self.p[1] + self.p[6] * yc,
        )
    }

    /// Distance of `q` from the surface: along the horizontal ray from the
    /// axis through `q`, and the height by which `q` lies above or below the
    /// crown's height range. Where the fitted radius² is negative (above a
    /// cone's apex) the surface has shrunk to the axis and the radius² below
    /// zero adds to the distance.
    pub fn distance(&self, q: DVec3) -> f64 {
        let r = q - self.origin;
        let yc = r.y.clamp(self.y_range.0, self.y_range.1);
        let [ox, oz, a, b, c, tx, tz] = self.p;
        let cx = ox + tx * yc;
        let cz = oz + tz * yc;
        let h2 = (r.x - cx).powi(2) + (r.z - cz).powi(2);
        let rho2 = a + b * yc + c * yc * yc + cx * cx + cz * cz;
        let radial = if rho2 >= 0.0 {
            (h2.sqrt() - rho2.sqrt()).abs()
        } else {
            (h2 - rho2).sqrt()
        };
        radial.hypot(r.y - yc)
    }
}

/// Below this distance from the axis (m) a row's weight stops growing, so
/// a tip on the axis (a pine's top) does not outweigh the whole crown.
const WEIGHT_FLOOR: f64 = 0.3;

/// Weight of a row whose tip lies `r` from the anchor's axis.
fn weight(r: f64) -> f64 {
    1.0 / r.max(WEIGHT_FLOOR)
}

/// Solves the `k`×`k` system by Gaussian elimination with partial pivoting;
/// `None` when it is singular.
fn solve(
    mut a: [[f64; UNKNOWNS]; UNKNOWNS],
    mut b: [f64; UNKNOWNS],
    k: usize,
) -> Option<[f64; UNKNOWNS]> {
    let scale = (0..k).map(|i| a[i][i].abs()).fold(0.0, f64::max);
    if !scale.is_finite() || scale <= 0.0 {
        return None;
    }
    for col in 0..k {
        let pivot = (col..k).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[pivot][col].abs() <= 1e-12 * scale {
            return None;
        }
        a.swap(col, pivot);
        b.swap(col, pivot);
        let pivot_row = a[col];
        for row in col + 1..k {
            let f = a[row][col] / pivot_row[col];
            for (x, p) in a[row][col..k].iter_mut().zip(&pivot_row[col..k]) {
                *x -= f * p;
            }
            b[row] -= f * b[col];
        }
    }
    let mut x = [0.0; UNKNOWNS];
    for row in (0..k).rev() {
        let s: f64 = (row + 1..k).map(|j| a[row][j] * x[j]).sum();
        x[row] = (b[row] - s) / a[row][row];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    /// Points on an ellipsoid (centre c, horizontal radius r, half-height h).
    fn ellipsoid(c: DVec3, r: f64, h: f64, n: usize) -> Vec<DVec3> {
        (0..n)
            .map(|i| {
                let u = (i as f64 + 0.5) / n as f64 * 2.0 - 1.0; // -1..1 height
                let a = i as f64 * 2.399_963; // golden angle
                let s = (1.0 - u * u).sqrt();
                c + DVec3::new(r * s * a.cos(), h * u, r * s * a.sin())
            })
            .collect()
    }

    #[test]
    fn an_ellipsoid_is_fitted_exactly() {
        let c = DVec3::new(1.0, 1.5, -2.0);
        let tips = ellipsoid(c, 0.8, 0.6, 40);
        let opts = FitOptions {
            offset_ridge: 0.0,
            lean: false,
            weighted: true,
        };
        // Anchored 0.3 m off: the fit finds the axis anyway.
        let crown = Crown::fit(&tips, c + DVec3::new(0.3, 0.0, 0.0), opts).unwrap();
        for t in &tips {
            assert!(crown.distance(*t) < 1e-9, "{}", crown.distance(*t));
        }
        let axis = crown.axis_at(1.5);
        assert!((axis - c).length() < 1e-9, "{axis}");
        // 0.2 m outside at the equator, 0.2 m inside towards the axis.
        assert!((crown.distance(c + DVec3::new(1.0, 0.0, 0.0)) - 0.2).abs() < 1e-9);
        assert!((crown.distance(c + DVec3::new(0.0, 0.0, 0.6)) - 0.2).abs() < 1e-9);
        // Above the crown: the height beyond the highest tip counts, with
        // the distance from the crown's rim at that height.
        let top = tips.iter().map(|t| t.y - c.y).fold(f64::MIN, f64::max);
        let rim = 0.8 * (1.0 - (top / 0.6).powi(2)).sqrt();
        let above = crown.distance(c + DVec3::new(0.0, 1.0, 0.0));
        assert!((above - rim.hypot(1.0 - top)).abs() < 1e-6, "{above}");
    }

    #[test]
    fn a_leaning_cone_is_fitted_with_lean() {
        // A cone of base radius 0.6 at y = 0.3 and apex at y = 2.0, its axis
        // leaning 0.2 m per metre of height towards +x.
        let mut tips = Vec::new();
        for i in 0..30 {
            let y = 0.3 + 1.6 * (i as f64 + 0.5) / 30.0;
            let r = 0.6 * (2.0 - y) / 1.7;
            let a = TAU * i as f64 * 0.382;
            let axis = DVec3::new(0.2 * y, y, 0.0);
            tips.push(axis + DVec3::new(r * a.cos(), 0.0, r * a.sin()));
        }
        let upright = Crown::fit(
            &tips,
            DVec3::ZERO,
            FitOptions {
                offset_ridge: 0.0,
                lean: false,
                weighted: true,
            },
        )
        .unwrap();
        let leaning = Crown::fit(
            &tips,
            DVec3::ZERO,
            FitOptions {
                offset_ridge: 0.0,
                lean: true,
                weighted: true,
            },
        )
        .unwrap();
        let worst = |c: &Crown| tips.iter().map(|t| c.distance(*t)).fold(0.0, f64::max);
        assert!(worst(&leaning) < 1e-6, "{}", worst(&leaning));
        assert!(worst(&upright) > 0.02, "{}", worst(&upright));
    }

    #[test]
    fn too_few_or_flat_tips_fit_nothing() {
        let opts = FitOptions {
            offset_ridge: 1.0,
            lean: true,
            weighted: true,
        };
        assert!(Crown::fit(&[DVec3::ZERO; 3], DVec3::ZERO, opts).is_none());
        assert!(Crown::fit(&[DVec3::ONE; 10], DVec3::ZERO, opts).is_none());
    }
}
