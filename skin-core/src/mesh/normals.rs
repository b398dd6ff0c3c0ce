//! Face normals, face areas and vertex normals.
//!
//! Vertex normals are the shading/offset normals every method uses: the Laplacian template
//! molding of Vlasic's thesis (§2.4.1) moves vertices along them, the photometric-normal
//! pipeline (Ch. 3) compares against them, and the mesh metrics colour with them.
//!
//! Two weightings are offered ([`NormalWeighting`]); the default is **angle-weighted**
//! (Thürmer & Wüthrich 1998, "Computing vertex normals from polygonal facets"), because it
//! depends only on the surface and not on how it is triangulated — splitting a quad along either
//! diagonal gives the same normal — which matters for quad-dominant artist meshes such as the
//! MakeHuman base mesh. Area weighting (the sum of unnormalised face normals) is cheaper and is
//! what many tools use; it is offered for comparison.

use crate::math::DVec3;
use crate::mesh::{triangle_area, TriMesh};
use crate::Result;
use serde::{Deserialize, Serialize};

/// Relative tolerance below which a triangle counts as degenerate: a triangle is degenerate when
/// `|(b - a) × (c - a)| <= DEGENERATE_REL_TOL * (longest edge)²`, i.e. when the sine of its
/// largest-scale angle is below this value. Scale-free, so it works in metres or decimetres.
/// Default: `1e-12` (well above f64 rounding noise of a cross product, ~1e-16, yet far below
/// any triangle a scanner or an artist produces on purpose).
pub(crate) const DEGENERATE_REL_TOL: f64 = 1e-12;

/// How face normals are weighted when accumulated into vertex normals.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum NormalWeighting {
    /// Each incident face contributes its unit normal times the interior angle at the vertex
    /// (Thürmer & Wüthrich 1998). Independent of the triangulation. Default.
    #[default]
    Angle,
    /// Each incident face contributes its unit normal times its area (sum of the raw cross
    /// products). Depends on the triangulation.
    Area,
}

/// The unit normal of triangle `[a, b, c]` (counter-clockwise seen from outside), or `None`
/// when it is degenerate (twice its area at most 1e-12 of its longest edge squared) or
/// non-finite.
pub fn triangle_normal(tri: [DVec3; 3]) -> Option<DVec3> {
    let [a, b, c] = tri;
    let n = (b - a).cross(c - a);
    let len = n.length();
    let longest2 = (b - a)
        .length_squared()
        .max((c - b).length_squared())
        .max((a - c).length_squared());
    if !len.is_finite() || len <= DEGENERATE_REL_TOL * longest2 || len == 0.0 {
        return None;
    }
    Some(n / len)
}

/// Unit normal of every face, in face order. Degenerate faces get `DVec3::ZERO`, so callers
/// can detect them with `n == DVec3::ZERO` rather than meet NaN.
///
/// # Errors
/// As [`TriMesh::validate`] (non-finite vertex, face index out of range).
pub fn face_normals(mesh: &TriMesh) -> Result<Vec<DVec3>> {
    mesh.validate()?;
    Ok((0..mesh.face_count())
        .map(|f| triangle_normal(mesh.triangle(f)).unwrap_or(DVec3::ZERO))
        .collect())
}

/// Area of every face, in face order (mesh units squared).
///
/// # Errors
/// As [`TriMesh::validate`].
pub fn face_areas(mesh: &TriMesh) -> Result<Vec<f64>> {
    mesh.validate()?;
    Ok((0..mesh.face_count())
        .map(|f| triangle_area(mesh.triangle(f)))
        .collect())
}

/// Unit normal of every vertex, accumulated from the incident faces with `weighting`.
///
/// Degenerate faces contribute nothing. A vertex with no non-degenerate incident face (an
/// isolated vertex, or one only touched by zero-area faces) — or whose contributions cancel
/// exactly — gets `DVec3::ZERO`: callers that need a direction must check for it.
///
/// # Errors
/// As [`TriMesh::validate`].
///
/// # Example
/// ```
/// use skin_core::math::DVec3;
/// use skin_core::mesh::{vertex_normals, NormalWeighting, TriMesh};
/// let mesh = TriMesh::new(vec![DVec3::ZERO, DVec3::X, DVec3::Y], vec![[0, 1, 2]])?;
/// let n = vertex_normals(&mesh, NormalWeighting::Angle)?;
/// assert!((n[0] - DVec3::Z).length() < 1e-12);
/// # Ok::<(), skin_core::Error>(())
/// ```
pub fn vertex_normals(mesh: &TriMesh, weighting: NormalWeighting) -> Result<Vec<DVec3>> {
    mesh.validate()?;
    let mut acc = vec![DVec3::ZERO; mesh.vertex_count()];
    for (f, face) in mesh.faces.iter().enumerate() {
        let tri = mesh.triangle(f);
        let Some(n) = triangle_normal(tri) else {
            continue;
        };
        match weighting {
            NormalWeighting::Area => {
                let w = triangle_area(tri);
                for &v in face {
                    acc[v as usize] += n * w;
                }
            }
            NormalWeighting::Angle => {
                for k in 0..3 {
                    let p = tri[k];
                    let e1 = tri[(k + 1) % 3] - p;
                    let e2 = tri[(k + 2) % 3] - p;
                    // `angle_between` is acos of a clamped cosine: finite for non-zero edges,
                    // which a non-degenerate triangle has.
                    let angle = e1.angle_between(e2);
                    if angle.is_finite() {
                        acc[face[k] as usize] += n * angle;
                    }
                }
            }
        }
    }
    Ok(acc
        .into_iter()
        .map(|n| n.try_normalize().unwrap_or(DVec3::ZERO))
        .collect())
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::Error;

    /// Unit cube [-1,1]^3 as 12 outward-facing triangles.
    pub(crate) fn cube() -> TriMesh {
        let v: Vec<DVec3> = (0..8)
            .map(|i| {
                DVec3::new(
                    if i & 1 == 0 { -1.0 } else { 1.0 },
                    if i & 2 == 0 { -1.0 } else { 1.0 },
                    if i & 4 == 0 { -1.0 } else { 1.0 },
                )
            })
            .collect();
        let quads = [
            [0, 2, 3, 1], // z = -1
            [4, 5, 7, 6], // z = +1
            [0, 1, 5, 4], // y = -1
            [2, 6, 7, 3], // y = +1
            [0, 4, 6, 2], // x = -1
            [1, 3, 7, 5], // x = +1
        ];
        let mut f = Vec::new();
        for q in quads {
            f.push([q[0], q[1], q[2]]);
            f.push([q[0], q[2], q[3]]);
        }
        TriMesh::new(v, f).unwrap()
    }

    #[test]
    fn cube_face_normals_point_outward_and_areas_sum() {
        let m = cube();
        let n = face_normals(&m).unwrap();
        for (f, nf) in n.iter().enumerate() {
            let c = m.triangle(f).iter().copied().sum::<DVec3>() / 3.0;
            // Outward: the normal is the axis along which the centroid is extreme.
            let axis = c.abs().max_element();
            assert!((nf.dot(c) - axis).abs() < 1e-12, "face {f}: {nf} vs {c}");
        }
        let total: f64 = face_areas(&m).unwrap().iter().sum();
        assert!((total - 24.0).abs() < 1e-12);
    }

    #[test]
    fn cube_angle_weighted_vertex_normals_are_diagonals() {
        // With angle weighting each corner sees three faces with total angle pi/2 each, so the
        // normal is exactly the diagonal regardless of how the quads are split.
        let m = cube();
        let n = vertex_normals(&m, NormalWeighting::Angle).unwrap();
        for (p, nv) in m.vertices.iter().zip(&n) {
            assert!((*nv - p.normalize()).length() < 1e-12, "{nv} vs {p}");
        }
        // Area weighting is triangulation dependent: at least one corner is off-diagonal.
        let na = vertex_normals(&m, NormalWeighting::Area).unwrap();
        let worst = m
            .vertices
            .iter()
            .zip(&na)
            .map(|(p, nv)| (*nv - p.normalize()).length())
            .fold(0.0, f64::max);
        assert!(worst > 1e-3);
    }

    #[test]
    fn sphere_vertex_normals_match_radial_direction() {
        let m = crate::mesh::query::tests::uv_sphere(1.5, 48, 24);
        for w in [NormalWeighting::Angle, NormalWeighting::Area] {
            let n = vertex_normals(&m, w).unwrap();
            for (p, nv) in m.vertices.iter().zip(&n) {
                // Poles and seams are all well resolved on a closed UV sphere.
                assert!(nv.dot(p.normalize()) > 0.998, "{w:?}: {nv} vs {p}");
            }
        }
    }

    #[test]
    fn degenerate_and_isolated_vertices_get_zero_normal() {
        let v = vec![
            DVec3::ZERO,
            DVec3::X,
            DVec3::Y,
            DVec3::new(2.0, 0.0, 0.0), // collinear with 0, 1
            DVec3::new(5.0, 5.0, 5.0), // isolated
        ];
        let m = TriMesh::new(v, vec![[0, 1, 2], [0, 1, 3]]).unwrap();
        let fnorm = face_normals(&m).unwrap();
        assert_eq!(fnorm[1], DVec3::ZERO);
        let n = vertex_normals(&m, NormalWeighting::Angle).unwrap();
        assert!((n[0] - DVec3::Z).length() < 1e-12);
        assert_eq!(n[3], DVec3::ZERO);
        assert_eq!(n[4], DVec3::ZERO);
        assert!(n.iter().all(|x| x.is_finite()));
    }

    #[test]
    fn invalid_mesh_is_an_error_not_a_panic() {
        let mut m = cube();
        m.faces.push([0, 1, 99]);
        assert!(matches!(
            vertex_normals(&m, NormalWeighting::Angle),
            Err(Error::IndexOutOfRange { index: 99, .. })
        ));
        let mut m = cube();
        m.vertices[0].y = f64::NAN;
        assert!(matches!(face_normals(&m), Err(Error::NonFinite { .. })));
        let empty = TriMesh::default();
        assert!(vertex_normals(&empty, NormalWeighting::Area)
            .unwrap()
            .is_empty());
    }
}
