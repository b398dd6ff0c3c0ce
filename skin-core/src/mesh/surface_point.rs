//! Points attached to a mesh surface by barycentric coordinates.
//!
//! A [`SurfacePoint`] names a face and barycentric weights, not a position, so it stays attached
//! to the same material point while the vertex positions change from frame to frame — the
//! representation Vlasic's thesis uses for correspondences between the template and the
//! visual hull (§2.4) and Sand 2003 for needle endpoints on the skin (§3). Evaluate it on any
//! mesh with the same faces ([`SurfacePoint::position`]).
//!
//! Also here: the exact closest point on a single triangle ([`closest_point_on_triangle`]),
//! robust to degenerate triangles, used by the brute-force reference in tests and by callers
//! that need a point-to-triangle distance without building a BVH.

use crate::math::DVec3;
use crate::mesh::normals::triangle_normal;
use crate::mesh::TriMesh;
use crate::{Error, Result};
use serde::{Deserialize, Serialize};

impl SurfacePoint {
    /// Tolerance on `|b0 + b1 + b2 - 1|` accepted by [`SurfacePoint::new`]. Default: `1e-9`
    /// (coordinates computed in f64 and stored in text files with ≥ 10 digits pass).
    pub const BARY_SUM_TOL: f64 = 1e-9;
}

/// A point on a triangle mesh: a face and barycentric weights of its three corners.
///
/// The position is `bary[0] * v[f[0]] + bary[1] * v[f[1]] + bary[2] * v[f[2]]`. Points returned
/// by the queries of this module have weights in `[0, 1]` summing to one.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SurfacePoint {
    /// Face index into `TriMesh::faces`.
    pub face: u32,
    /// Barycentric weights of the face's corners, in the face's corner order.
    pub bary: [f64; 3],
}

/// The closest point on one triangle to a query point.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TrianglePoint {
    /// Barycentric weights of the closest point (non-negative, summing to one).
    pub bary: [f64; 3],
    /// The closest point (same units as the triangle).
    pub position: DVec3,
    /// Euclidean distance from the query point to `position`.
    pub distance: f64,
}

impl SurfacePoint {
    /// Builds a surface point, checking that the weights are finite and sum to one within
    /// [`SurfacePoint::BARY_SUM_TOL`]. Weights may be negative (a point extrapolated outside its face).
    ///
    /// # Errors
    /// [`Error::NonFinite`] for NaN/inf weights, [`Error::InvalidParam`] when they do not sum
    /// to one.
    pub fn new(face: u32, bary: [f64; 3]) -> Result<Self> {
        if !bary.iter().all(|b| b.is_finite()) {
            return Err(Error::NonFinite {
                what: "barycentric weights",
            });
        }
        let sum: f64 = bary.iter().sum();
        if (sum - 1.0).abs() > SurfacePoint::BARY_SUM_TOL {
            return Err(Error::InvalidParam {
                name: "bary",
                reason: format!("weights must sum to 1, got {sum}"),
            });
        }
        Ok(SurfacePoint { face, bary })
    }

    /// The point at corner `k` (0, 1 or 2) of `face`.
    ///
    /// # Errors
    /// [`Error::InvalidParam`] when `k > 2`.
    pub fn corner(face: u32, k: usize) -> Result<Self> {
        if k > 2 {
            return Err(Error::InvalidParam {
                name: "k",
                reason: format!("corner index must be 0, 1 or 2, got {k}"),
            });
        }
        let mut bary = [0.0; 3];
        bary[k] = 1.0;
        Ok(SurfacePoint { face, bary })
    }

    /// The face's three vertex indices, checked against `mesh`.
    fn face_of(&self, mesh: &TriMesh) -> Result<[u32; 3]> {
        let f = *mesh
            .faces
            .get(self.face as usize)
            .ok_or(Error::IndexOutOfRange {
                what: "surface point face",
                index: self.face as usize,
                len: mesh.face_count(),
            })?;
        Ok(f)
    }

    /// Interpolates per-vertex values (positions, normals, displacements, colours) at this
    /// point: `Σ bary[k] * values[face[k]]`.
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`] if the face is not in `mesh` or a corner is past
    /// `values.len()`.
    pub fn interpolate(&self, mesh: &TriMesh, values: &[DVec3]) -> Result<DVec3> {
        let f = self.face_of(mesh)?;
        let mut out = DVec3::ZERO;
        for (k, &v) in f.iter().enumerate() {
            let value = values.get(v as usize).ok_or(Error::IndexOutOfRange {
                what: "surface point corner (values)",
                index: v as usize,
                len: values.len(),
            })?;
            out += self.bary[k] * *value;
        }
        Ok(out)
    }

    /// The point's position on `mesh` (which may be any frame of a mesh sequence with the
    /// same faces).
    ///
    /// # Errors
    /// As [`SurfacePoint::interpolate`].
    ///
    /// # Example
    /// ```
    /// use skin_core::math::DVec3;
    /// use skin_core::mesh::{SurfacePoint, TriMesh};
    /// let mut mesh = TriMesh::new(vec![DVec3::ZERO, DVec3::X, DVec3::Y], vec![[0, 1, 2]])?;
    /// let p = SurfacePoint::new(0, [0.5, 0.25, 0.25])?;
    /// assert_eq!(p.position(&mesh)?, DVec3::new(0.25, 0.25, 0.0));
    /// mesh.vertices[0].z = 4.0; // the next frame: the point moves with the surface
    /// assert_eq!(p.position(&mesh)?, DVec3::new(0.25, 0.25, 2.0));
    /// # Ok::<(), skin_core::Error>(())
    /// ```
    pub fn position(&self, mesh: &TriMesh) -> Result<DVec3> {
        self.interpolate(mesh, &mesh.vertices)
    }

    /// The unit normal of the point's face on `mesh`, or `None` if the face is degenerate.
    ///
    /// # Errors
    /// As [`SurfacePoint::interpolate`].
    pub fn face_normal(&self, mesh: &TriMesh) -> Result<Option<DVec3>> {
        let f = self.face_of(mesh)?;
        let mut tri = [DVec3::ZERO; 3];
        for k in 0..3 {
            tri[k] = *mesh
                .vertices
                .get(f[k] as usize)
                .ok_or(Error::IndexOutOfRange {
                    what: "surface point corner",
                    index: f[k] as usize,
                    len: mesh.vertex_count(),
                })?;
        }
        Ok(triangle_normal(tri))
    }
}

/// Positions of many surface points on `mesh`, in order.
///
/// # Errors
/// As [`SurfacePoint::position`], for the first point that fails.
pub fn evaluate_surface_points(mesh: &TriMesh, points: &[SurfacePoint]) -> Result<Vec<DVec3>> {
    points.iter().map(|p| p.position(mesh)).collect()
}

/// Closest point to `p` on segment `[a, b]` as the parameter `t` of `a + t (b - a)`.
fn segment_parameter(p: DVec3, a: DVec3, b: DVec3) -> f64 {
    let ab = b - a;
    let len2 = ab.length_squared();
    if len2 <= 0.0 {
        return 0.0;
    }
    ((p - a).dot(ab) / len2).clamp(0.0, 1.0)
}

/// The exact closest point to `p` on triangle `tri` (Ericson, *Real-Time Collision Detection*,
/// §5.1.5, Voronoi-region walk).
///
/// Degenerate triangles (see [`crate::mesh::triangle_normal`]) are handled as the union of
/// their three edges, so the result is always finite for finite input.
pub fn closest_point_on_triangle(p: DVec3, tri: [DVec3; 3]) -> TrianglePoint {
    let [a, b, c] = tri;
    let finish = |bary: [f64; 3]| {
        let position = a * bary[0] + b * bary[1] + c * bary[2];
        TrianglePoint {
            bary,
            position,
            distance: (p - position).length(),
        }
    };
    if triangle_normal(tri).is_none() {
        // Degenerate: best of the three edges.
        let candidates = [
            (0usize, 1usize, segment_parameter(p, a, b)),
            (1, 2, segment_parameter(p, b, c)),
            (2, 0, segment_parameter(p, c, a)),
        ];
        let mut best: Option<TrianglePoint> = None;
        for (i, j, t) in candidates {
            let mut bary = [0.0; 3];
            bary[i] += 1.0 - t;
            bary[j] += t;
            let cand = finish(bary);
            if best.is_none_or(|b| cand.distance < b.distance) {
                best = Some(cand);
            }
        }
        // `candidates` is non-empty, so `best` is set.
        return best.unwrap_or_else(|| finish([1.0, 0.0, 0.0]));
    }
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return finish([1.0, 0.0, 0.0]);
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return finish([0.0, 1.0, 0.0]);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return finish([1.0 - v, v, 0.0]);
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return finish([0.0, 0.0, 1.0]);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return finish([1.0 - w, 0.0, w]);
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return finish([0.0, 1.0 - w, w]);
    }
    let denom = 1.0 / (va + vb + vc);
    let v = vb * denom;
    let w = vc * denom;
    finish([1.0 - v - w, v, w])
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn new_validates_weights() {
        assert!(SurfacePoint::new(0, [0.2, 0.3, 0.5]).is_ok());
        assert!(SurfacePoint::new(0, [-0.5, 0.5, 1.0]).is_ok());
        assert!(matches!(
            SurfacePoint::new(0, [0.2, 0.3, 0.6]),
            Err(Error::InvalidParam { .. })
        ));
        assert!(matches!(
            SurfacePoint::new(0, [f64::NAN, 0.5, 0.5]),
            Err(Error::NonFinite { .. })
        ));
        assert!(SurfacePoint::corner(0, 3).is_err());
        assert_eq!(SurfacePoint::corner(7, 2).unwrap().bary, [0.0, 0.0, 1.0]);
    }

    #[test]
    fn evaluation_follows_the_mesh_and_checks_indices() {
        let mut mesh = TriMesh::new(
            vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z],
            vec![[0, 1, 2], [0, 2, 3]],
        )
        .unwrap();
        let p = SurfacePoint::new(1, [0.2, 0.3, 0.5]).unwrap();
        assert!((p.position(&mesh).unwrap() - DVec3::new(0.0, 0.3, 0.5)).length() < 1e-15);
        mesh.vertices[3] = DVec3::new(0.0, 0.0, 2.0);
        assert!((p.position(&mesh).unwrap() - DVec3::new(0.0, 0.3, 1.0)).length() < 1e-15);
        assert!((p.face_normal(&mesh).unwrap().unwrap() - DVec3::X).length() < 1e-15);
        let bad = SurfacePoint::new(2, [1.0, 0.0, 0.0]).unwrap();
        assert!(matches!(
            bad.position(&mesh),
            Err(Error::IndexOutOfRange { index: 2, .. })
        ));
        assert!(matches!(
            p.interpolate(&mesh, &[DVec3::ZERO; 2]),
            Err(Error::IndexOutOfRange { index: 2, .. })
        ));
        let all = evaluate_surface_points(&mesh, &[p, p]).unwrap();
        assert_eq!(all.len(), 2);
    }

    /// Reference: minimise over a fine barycentric grid plus the exact edge projections.
    #[test]
    fn closest_point_on_triangle_beats_sampling() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut r = || {
            DVec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            )
        };
        for _ in 0..200 {
            let tri = [r(), r(), r()];
            let p = 2.0 * r();
            let cp = closest_point_on_triangle(p, tri);
            assert!(cp.bary.iter().all(|&b| (-1e-12..=1.0 + 1e-12).contains(&b)));
            assert!((cp.bary.iter().sum::<f64>() - 1.0).abs() < 1e-12);
            let n = 60;
            for i in 0..=n {
                for j in 0..=(n - i) {
                    let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
                    let q = tri[0] * (1.0 - u - v) + tri[1] * u + tri[2] * v;
                    assert!(cp.distance <= (p - q).length() + 1e-12);
                }
            }
        }
    }

    #[test]
    fn degenerate_triangles_give_finite_answers() {
        let p = DVec3::new(0.5, 1.0, 0.0);
        // Collinear.
        let cp = closest_point_on_triangle(p, [DVec3::ZERO, DVec3::X, DVec3::new(2.0, 0.0, 0.0)]);
        assert!((cp.position - DVec3::new(0.5, 0.0, 0.0)).length() < 1e-12);
        assert!((cp.distance - 1.0).abs() < 1e-12);
        // Two coincident corners.
        let cp = closest_point_on_triangle(p, [DVec3::ZERO, DVec3::ZERO, DVec3::X]);
        assert!((cp.position - DVec3::new(0.5, 0.0, 0.0)).length() < 1e-12);
        // All coincident.
        let cp = closest_point_on_triangle(p, [DVec3::X; 3]);
        assert_eq!(cp.position, DVec3::X);
        assert!(cp.bary.iter().all(|b| b.is_finite()));
    }
}
