//! Mesh decimation by quadric edge collapses (meshoptimizer's simplifier, through the
//! `meshopt` crate): a coarser mesh whose vertices are a subset of the original's, so every
//! per-vertex attribute (skin weights, texture coordinates, a ground truth) carries over
//! through [`Decimation::original_index`].
//!
//! Why a subset: meshoptimizer collapses each edge onto one of its end points rather than an
//! optimal quadric point. The coarse mesh is a little less faithful than with free placement,
//! but its vertices lie on the original surface, so the barycentric embedding of the coarse
//! mesh in the original (what a template-silhouette user scores a decimated template with,
//! Vlasic 2010 §2.5) is exact and fixed.

use super::trimesh::compact_vertices;
use super::{EdgeTopology, TriMesh};
use crate::{Error, Result};

/// A decimated mesh and where its vertices came from.
#[cfg_attr(docsrs, doc(cfg(feature = "decimate")))]
#[derive(Debug, Clone, PartialEq)]
pub struct Decimation {
    /// The coarse mesh, vertices compacted in the original order.
    pub mesh: TriMesh,
    /// `original_index[i]` is the original vertex that coarse vertex `i` is.
    pub original_index: Vec<u32>,
    /// meshoptimizer's error estimate of the result, relative to the mesh's extent.
    pub relative_error: f64,
}

/// Decimates `mesh` to about `target_vertices` vertices, keeping its boundary loops
/// (meshoptimizer's `LockBorder`: a garment's hem and openings keep their outline) and
/// refusing a result with non-manifold edges.
///
/// The count is a target: meshoptimizer stops earlier when only collapses that would flip
/// triangles or cross a locked border remain.
///
/// # Errors
/// [`Error::InvalidParam`] if `target_vertices` is below 4 or not below the mesh's count;
/// [`Error::Degenerate`] if the result has non-manifold edges; as [`TriMesh::validate`].
#[cfg_attr(docsrs, doc(cfg(feature = "decimate")))]
pub fn decimate(mesh: &TriMesh, target_vertices: usize) -> Result<Decimation> {
    mesh.validate()?;
    let n = mesh.vertex_count();
    if target_vertices < 4 || target_vertices >= n {
        return Err(Error::InvalidParam {
            name: "target_vertices",
            reason: format!("must be in 4..{n} (the mesh's vertex count), got {target_vertices}"),
        });
    }
    let positions: Vec<[f32; 3]> = mesh
        .vertices
        .iter()
        .map(|v| v.as_vec3().to_array())
        .collect();
    let indices: Vec<u32> = mesh.faces.iter().flatten().copied().collect();
    // A closed triangle mesh has about twice as many faces as vertices; the target index count
    // scales the faces like the vertices.
    let target_indices = (indices.len() as f64 * target_vertices as f64 / n as f64) as usize;
    let mut error = 0.0f32;
    let kept = meshopt::simplify_decoder(
        &indices,
        &positions,
        target_indices,
        1.0,
        meshopt::SimplifyOptions::LockBorder,
        Some(&mut error),
    );
    let kept = drop_coincident_pairs(&kept);
    let (new_index, original_index) = compact_vertices(n, kept.iter().copied());
    let faces: Vec<[u32; 3]> = kept
        .chunks_exact(3)
        .map(|f| [f[0], f[1], f[2]].map(|i| new_index[i as usize]))
        .collect();
    let coarse = TriMesh::new(
        original_index
            .iter()
            .map(|&i| mesh.vertices[i as usize])
            .collect(),
        faces,
    )?;
    let bad = EdgeTopology::new(&coarse)?.non_manifold_edges();
    if let Some(e) = bad.first() {
        return Err(Error::Degenerate {
            what: format!(
                "decimation to {target_vertices} vertices left {} non-manifold edges (first: \
                 coarse vertices {} and {})",
                bad.len(),
                e[0],
                e[1]
            ),
        });
    }
    Ok(Decimation {
        mesh: coarse,
        original_index,
        relative_error: f64::from(error),
    })
}

/// `indices` without the triangles that occur more than once over the same three vertices
/// (in either orientation). Edge collapses that close a thin place (a web between two fingers
/// of a scanned surface) fold its two sheets onto each other as a pair of coincident opposite
/// triangles, which make three or four faces meet at their edges; the pair encloses nothing,
/// and removing it leaves the surface around it manifold.
fn drop_coincident_pairs(indices: &[u32]) -> Vec<u32> {
    let key = |f: &[u32]| {
        let mut k = [f[0], f[1], f[2]];
        k.sort_unstable();
        k
    };
    let mut count: std::collections::HashMap<[u32; 3], usize> = Default::default();
    for f in indices.chunks_exact(3) {
        *count.entry(key(f)).or_default() += 1;
    }
    indices
        .chunks_exact(3)
        .filter(|f| count[&key(f)] == 1)
        .flatten()
        .copied()
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::DVec3;
    use crate::mesh::shapes::uv_sphere;

    #[test]
    fn a_sphere_halves_and_its_vertices_stay_on_it() {
        let sphere = uv_sphere(DVec3::new(0.0, 1.0, 0.0), 0.5, 40, 60).unwrap();
        let n = sphere.vertex_count();
        let d = decimate(&sphere, n / 2).unwrap();
        let m = d.mesh.vertex_count();
        assert!(m <= n / 2 + n / 20 && m >= n / 3, "{m} of {n}");
        for (v, &o) in d.mesh.vertices.iter().zip(&d.original_index) {
            assert_eq!(*v, sphere.vertices[o as usize]);
        }
        assert!(EdgeTopology::new(&d.mesh).unwrap().is_closed());
        // Still a sphere: the area is within 2 % of the original's.
        let (a, b) = (
            sphere.surface_area().unwrap(),
            d.mesh.surface_area().unwrap(),
        );
        assert!((a - b).abs() < 0.02 * a, "{a} vs {b}");
    }

    #[test]
    fn coincident_triangle_pairs_are_dropped_and_the_rest_kept() {
        // Faces 0 and 2 are the same triangle in opposite orientations; face 1 is alone.
        let indices = [0, 1, 2, 1, 2, 3, 0, 2, 1, 2, 3, 4];
        assert_eq!(drop_coincident_pairs(&indices), [1, 2, 3, 2, 3, 4]);
    }

    #[test]
    fn impossible_targets_are_clear_errors() {
        let sphere = uv_sphere(DVec3::ZERO, 1.0, 8, 12).unwrap();
        for t in [0, 3, sphere.vertex_count()] {
            assert!(matches!(
                decimate(&sphere, t),
                Err(Error::InvalidParam { .. })
            ));
        }
    }
}
