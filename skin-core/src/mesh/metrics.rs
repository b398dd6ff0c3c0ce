//! Mesh-to-mesh distance metrics: vertex-to-surface distances and their statistics.
//!
//! These are the accuracy figures the methods report against ground truth — Vlasic's thesis
//! evaluates reconstructions by the distance from each reconstructed vertex to the reference
//! surface (Ch. 2 and 3 result tables); Hausdorff distance is the symmetric worst case. For each
//! vertex of mesh A we take the exact distance to the closest point on the *surface* of mesh B
//! (not to B's vertices, which would depend on B's resolution), via the BVH of
//! [`MeshQuery`]. All vertices of A are used, referenced by a face or not.
//!
//! Statistics are [`crate::stats`]'s (the 95th percentile interpolates as NumPy does).

use crate::math::DVec3;
use crate::mesh::query::MeshQuery;
use crate::mesh::TriMesh;
use crate::{stats, Error, Result};
use serde::{Deserialize, Serialize};

/// Summary statistics of a set of non-negative distances (mesh units).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DistanceStats {
    /// Number of distances.
    pub count: usize,
    /// Arithmetic mean.
    pub mean: f64,
    /// Root mean square.
    pub rms: f64,
    /// 95th percentile (linear interpolation between order statistics).
    pub p95: f64,
    /// Maximum (the one-sided Hausdorff distance when the distances are vertex-to-surface).
    pub max: f64,
}

impl DistanceStats {
    /// Statistics of `distances`.
    ///
    /// # Errors
    /// [`Error::Empty`] for no distances; [`Error::NonFinite`] for NaN/inf values;
    /// [`Error::InvalidParam`] for a negative value.
    pub fn from_distances(distances: &[f64]) -> Result<Self> {
        if distances.is_empty() {
            return Err(Error::Empty {
                what: "distances (statistics)",
            });
        }
        crate::check::all_finite("distances", distances)?;
        if let Some(d) = distances.iter().find(|&&d| d < 0.0) {
            return Err(Error::InvalidParam {
                name: "distances",
                reason: format!("distances must be >= 0, got {d}"),
            });
        }
        let sorted = stats::sorted(distances);
        Ok(DistanceStats {
            count: distances.len(),
            mean: stats::mean(distances),
            rms: stats::rms(distances),
            p95: stats::percentile_sorted(&sorted, 0.95),
            max: sorted[sorted.len() - 1],
        })
    }
}

/// Distances from every vertex of one mesh to the surface of another.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OneSidedDistance {
    /// Statistics of `per_vertex`.
    pub stats: DistanceStats,
    /// Unsigned distance of each source vertex to the target surface, in vertex order (for
    /// colouring the source mesh).
    pub per_vertex: Vec<f64>,
    /// Signed distance of each source vertex (negative inside/behind the target; see
    /// [`crate::mesh::ClosestPoint::signed_distance`]).
    pub per_vertex_signed: Vec<f64>,
}

/// Distances from each point of `points` to the surface held by `target`.
///
/// # Errors
/// [`Error::Empty`] for no points; [`Error::NonFinite`] for a non-finite point.
pub fn points_to_surface(points: &[DVec3], target: &MeshQuery) -> Result<OneSidedDistance> {
    if points.is_empty() {
        return Err(Error::Empty {
            what: "source vertices (distance metric)",
        });
    }
    let closest = target.closest_points(points)?;
    let per_vertex: Vec<f64> = closest.iter().map(|c| c.distance).collect();
    let per_vertex_signed = closest.iter().map(|c| c.signed_distance).collect();
    Ok(OneSidedDistance {
        stats: DistanceStats::from_distances(&per_vertex)?,
        per_vertex,
        per_vertex_signed,
    })
}

/// Distances from every vertex of `from` to the surface of `to`.
///
/// # Errors
/// As [`MeshQuery::new`] for `to`; as [`points_to_surface`] for the vertices of `from`.
pub fn one_sided_distance(from: &TriMesh, to: &TriMesh) -> Result<OneSidedDistance> {
    from.validate()?;
    points_to_surface(&from.vertices, &MeshQuery::new(to)?)
}

/// Symmetric distance between two meshes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MeshDistance {
    /// From the vertices of A to the surface of B.
    pub a_to_b: OneSidedDistance,
    /// From the vertices of B to the surface of A.
    pub b_to_a: OneSidedDistance,
    /// Statistics over both directions' distances pooled together; `symmetric.max` is the
    /// (vertex-sampled) Hausdorff distance `max(a_to_b.max, b_to_a.max)`.
    pub symmetric: DistanceStats,
}

impl MeshDistance {
    /// The symmetric distance from its two one-sided distances (e.g. computed with
    /// [`points_to_surface`] against queries built once and reused): both directions'
    /// distances pooled into [`MeshDistance::symmetric`].
    ///
    /// # Errors
    /// As [`DistanceStats::from_distances`].
    pub fn from_sides(a_to_b: OneSidedDistance, b_to_a: OneSidedDistance) -> Result<Self> {
        let pooled: Vec<f64> = a_to_b
            .per_vertex
            .iter()
            .chain(&b_to_a.per_vertex)
            .copied()
            .collect();
        Ok(MeshDistance {
            symmetric: DistanceStats::from_distances(&pooled)?,
            a_to_b,
            b_to_a,
        })
    }

    /// The vertex-sampled Hausdorff distance.
    pub fn hausdorff(&self) -> f64 {
        self.symmetric.max
    }
}

/// Vertex-to-surface distances in both directions between meshes `a` and `b`.
///
/// # Errors
/// As [`one_sided_distance`] in either direction.
///
/// # Example
/// ```
/// use skin_core::math::DVec3;
/// use skin_core::mesh::{mesh_distance, TriMesh};
/// let a = TriMesh::new(vec![DVec3::ZERO, DVec3::X, DVec3::Y], vec![[0, 1, 2]])?;
/// let mut b = a.clone();
/// b.vertices.iter_mut().for_each(|v| v.z += 0.1);
/// let d = mesh_distance(&a, &b)?;
/// assert!((d.symmetric.mean - 0.1).abs() < 1e-12 && (d.hausdorff() - 0.1).abs() < 1e-12);
/// # Ok::<(), skin_core::Error>(())
/// ```
pub fn mesh_distance(a: &TriMesh, b: &TriMesh) -> Result<MeshDistance> {
    MeshDistance::from_sides(one_sided_distance(a, b)?, one_sided_distance(b, a)?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::query::tests::uv_sphere;

    #[test]
    fn stats_match_hand_computation() {
        let d: Vec<f64> = (0..=20).map(f64::from).collect(); // 0..20
        let s = DistanceStats::from_distances(&d).unwrap();
        assert_eq!(s.count, 21);
        assert!((s.mean - 10.0).abs() < 1e-12);
        let rms = (d.iter().map(|x| x * x).sum::<f64>() / 21.0).sqrt();
        assert!((s.rms - rms).abs() < 1e-12);
        assert!((s.p95 - 19.0).abs() < 1e-12); // 0.95 * 20 = 19
        assert_eq!(s.max, 20.0);
        let s = DistanceStats::from_distances(&[3.0, 1.0]).unwrap();
        assert!((s.p95 - 2.9).abs() < 1e-12);
        let one = DistanceStats::from_distances(&[0.5]).unwrap();
        assert_eq!((one.mean, one.p95, one.max), (0.5, 0.5, 0.5));
    }

    #[test]
    fn stats_reject_bad_input() {
        assert!(matches!(
            DistanceStats::from_distances(&[]),
            Err(Error::Empty { .. })
        ));
        assert!(matches!(
            DistanceStats::from_distances(&[1.0, f64::NAN]),
            Err(Error::NonFinite { .. })
        ));
        assert!(matches!(
            DistanceStats::from_distances(&[-1.0]),
            Err(Error::InvalidParam { .. })
        ));
    }

    /// Concentric spheres r and r + d: every vertex of the inner sphere is at distance in
    /// [d, d + (r + d - r_min(outer))] from the outer surface, so the mean is ≈ d.
    #[test]
    fn concentric_spheres_offset() {
        let (r, d) = (1.0, 0.05);
        let inner = uv_sphere(r, 96, 48);
        let outer = uv_sphere(r + d, 96, 48);
        let res = mesh_distance(&inner, &outer).unwrap();
        // Polyhedral sag of the outer sphere, the only error source.
        let sag = (r + d) * 0.002;
        for s in [res.a_to_b.stats, res.b_to_a.stats, res.symmetric] {
            assert!((s.mean - d).abs() < sag, "{s:?}");
            assert!((s.rms - d).abs() < sag);
            assert!(s.p95 <= s.max + 1e-15 && s.mean <= s.rms + 1e-12);
            assert!((s.max - d).abs() < sag);
        }
        // Inner vertices are inside the outer sphere: negative signed distance.
        assert!(res.a_to_b.per_vertex_signed.iter().all(|&s| s < 0.0));
        assert!(res.b_to_a.per_vertex_signed.iter().all(|&s| s > 0.0));
        assert_eq!(res.a_to_b.per_vertex.len(), inner.vertex_count());
        assert_eq!(
            res.hausdorff(),
            res.a_to_b.stats.max.max(res.b_to_a.stats.max)
        );
        // Identical meshes are at distance zero.
        let same = mesh_distance(&inner, &inner).unwrap();
        assert!(same.symmetric.max < 1e-12);
    }

    #[test]
    fn empty_or_degenerate_inputs_are_errors() {
        let s = uv_sphere(1.0, 8, 4);
        assert!(matches!(
            mesh_distance(&s, &TriMesh::default()),
            Err(Error::Empty { .. })
        ));
        let no_vertices = TriMesh::default();
        assert!(matches!(
            one_sided_distance(&no_vertices, &s),
            Err(Error::Empty { .. })
        ));
        let flat = TriMesh::new(vec![DVec3::ZERO, DVec3::X, DVec3::X], vec![[0, 1, 2]]).unwrap();
        assert!(matches!(
            mesh_distance(&s, &flat),
            Err(Error::Degenerate { .. })
        ));
        let mut nan = s.clone();
        nan.vertices[0].x = f64::NAN;
        assert!(matches!(
            mesh_distance(&nan, &s),
            Err(Error::NonFinite { .. })
        ));
    }
}
