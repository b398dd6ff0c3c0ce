//! Mesh Laplacians and lumped mass matrices (Vlasic 2010 thesis §2.4.1: "Δ is the n × n
//! mesh Laplacian matrix (cotangent weights work best [101])").
//!
//! Convention (identical to libigl `cotmatrix`): `L_ij = ½ (cot α_ij + cot β_ij)` for an edge
//! `ij` with opposite angles `α_ij`, `β_ij` (one on a boundary edge), `L_ii = −Σ_j L_ij`.
//! `L` is symmetric negative semi-definite, `L·1 = 0`, and `(L V)_i ≈ −2 H_i n_i A_i`
//! (mean curvature `H`, outward normal `n`, vertex area `A`; Meyer et al. 2003).
//! The Laplacian coordinates of the thesis are `δ = Δ V_T` with `Δ = L`.

use nalgebra::DVector;
use nalgebra_sparse::CscMatrix;
use serde::{Deserialize, Serialize};

use crate::math::DVec3;
use crate::mesh::TriMesh;
use crate::{Error, Result};

/// What to do with a degenerate (near zero-area) triangle, whose cotangents are unbounded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum DegenerateFaces {
    /// Leave the face out of the operator (its edges keep the weights of their other
    /// face). `L` stays symmetric with zero row sums; a warning with the count is logged.
    /// This is what robust pipelines do for scanned and artist meshes with slivers.
    #[default]
    Skip,
    /// Return [`Error::Degenerate`] naming the first such face.
    Error,
}

impl LaplacianParams {
    /// Default relative area threshold for degenerate triangles.
    pub const DEFAULT_DEGENERATE_TOL: f64 = 1e-12;
}

/// Knobs of the cotangent Laplacian and mass matrix.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LaplacianParams {
    /// Handling of degenerate triangles. Default: [`DegenerateFaces::Skip`].
    pub degenerate_faces: DegenerateFaces,
    /// A triangle is degenerate when `|e₁ × e₂| ≤ tol · (longest edge)²` (twice its area
    /// relative to the square of its size; 0 for collinear corners), dimensionless. With 1e-12
    /// the largest cotangent kept is about 10¹². Default:
    /// [`LaplacianParams::DEFAULT_DEGENERATE_TOL`].
    pub degenerate_tol: f64,
}

impl Default for LaplacianParams {
    fn default() -> Self {
        Self {
            degenerate_faces: DegenerateFaces::Skip,
            degenerate_tol: LaplacianParams::DEFAULT_DEGENERATE_TOL,
        }
    }
}

/// Lumped (diagonal) mass matrix variants.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum MassKind {
    /// One third of the area of each incident triangle.
    Barycentric,
    /// Mixed Voronoi areas (Meyer, Desbrun, Schröder & Barr 2003; libigl
    /// `MASSMATRIX_TYPE_VORONOI`): circumcentric Voronoi cells for non-obtuse triangles, and
    /// ½ / ¼ / ¼ of the area for obtuse ones (½ at the obtuse corner).
    #[default]
    Voronoi,
}

/// Checks the mesh and returns `|e₁ × e₂|` (twice the area) of each face, or `None` for a
/// degenerate face (after applying the policy).
fn face_double_areas(mesh: &TriMesh, params: &LaplacianParams) -> Result<Vec<Option<f64>>> {
    mesh.validate()?;
    if mesh.vertices.is_empty() || mesh.faces.is_empty() {
        return Err(Error::Empty {
            what: "mesh for a Laplacian (no vertices or no faces)",
        });
    }
    crate::check::non_negative("degenerate_tol", params.degenerate_tol)?;
    let mut skipped = 0usize;
    let mut out = Vec::with_capacity(mesh.faces.len());
    for (f, _) in mesh.faces.iter().enumerate() {
        let [a, b, c] = mesh.triangle(f);
        let (e1, e2, e3) = (b - a, c - a, c - b);
        let dbl = e1.cross(e2).length();
        let size2 = e1
            .length_squared()
            .max(e2.length_squared())
            .max(e3.length_squared());
        if dbl <= params.degenerate_tol * size2 || dbl == 0.0 {
            match params.degenerate_faces {
                DegenerateFaces::Error => {
                    return Err(Error::Degenerate {
                        what: format!(
                            "triangle {f} {:?} has (near) zero area; use DegenerateFaces::Skip or clean the mesh",
                            mesh.faces[f]
                        ),
                    })
                }
                DegenerateFaces::Skip => {
                    skipped += 1;
                    out.push(None);
                }
            }
        } else {
            out.push(Some(dbl));
        }
    }
    if skipped > 0 {
        log::warn!("Laplacian: skipped {skipped} degenerate triangles");
    }
    Ok(out)
}

/// Symmetric matrix with off-diagonal entries `(i, j, v)` accumulated at `(i, j)` and
/// `(j, i)`, and diagonal `L_ii = −Σ_j L_ij`. With `unit` the merged off-diagonal values are
/// replaced by 1 (graph Laplacian).
#[allow(
    clippy::expect_used,
    reason = "the assembly sorts and merges entries per column, which is valid CSC"
)]
fn assemble_laplacian(n: usize, entries: &[(u32, u32, f64)], unit: bool) -> CscMatrix<f64> {
    // Bucket both orientations by column (counting sort).
    let mut count = vec![0usize; n + 1];
    for &(i, j, _) in entries {
        count[i as usize + 1] += 1;
        count[j as usize + 1] += 1;
    }
    for k in 0..n {
        count[k + 1] += count[k];
    }
    let mut next = count.clone();
    let mut bucket = vec![(0u32, 0.0f64); count[n]];
    for &(i, j, v) in entries {
        bucket[next[j as usize]] = (i, v);
        next[j as usize] += 1;
        bucket[next[i as usize]] = (j, v);
        next[i as usize] += 1;
    }
    let mut col_offsets = Vec::with_capacity(n + 1);
    let mut row_indices = Vec::with_capacity(count[n] / 2 + n);
    let mut values = Vec::with_capacity(count[n] / 2 + n);
    col_offsets.push(0);
    for j in 0..n {
        let col = &mut bucket[count[j]..count[j + 1]];
        col.sort_unstable_by_key(|e| e.0);
        let start = row_indices.len();
        let mut diag_pos = None;
        let mut sum = 0.0;
        let mut k = 0;
        while k < col.len() {
            let row = col[k].0;
            let mut v = 0.0;
            while k < col.len() && col[k].0 == row {
                v += col[k].1;
                k += 1;
            }
            if unit {
                v = 1.0;
            }
            if diag_pos.is_none() && row as usize > j {
                diag_pos = Some(row_indices.len());
                row_indices.push(j);
                values.push(0.0);
            }
            row_indices.push(row as usize);
            values.push(v);
            sum += v;
        }
        let d = match diag_pos {
            Some(p) => p,
            None => {
                row_indices.push(j);
                values.push(0.0);
                row_indices.len() - 1
            }
        };
        values[d] = -sum;
        debug_assert!(row_indices[start..].windows(2).all(|w| w[0] < w[1]));
        col_offsets.push(row_indices.len());
    }
    // Rows are sorted and unique per column by construction, so this cannot fail.
    CscMatrix::try_from_csc_data(n, n, col_offsets, row_indices, values)
        .expect("Laplacian assembly yields valid CSC")
}

/// Cotangent Laplacian `L` (n × n, libigl `cotmatrix` convention, see the module docs).
///
/// # Errors
/// [`Error::Empty`] for a mesh without vertices or faces, [`Error::NonFinite`] /
/// [`Error::IndexOutOfRange`] for an invalid mesh, [`Error::Degenerate`] for a degenerate
/// triangle when `params.degenerate_faces` is [`DegenerateFaces::Error`],
/// [`Error::InvalidParam`] for a negative or non-finite tolerance.
///
/// # Example
/// ```
/// use skin_core::mesh::{cotangent_laplacian, shapes, LaplacianParams};
/// let mesh = shapes::icosphere(2)?;
/// let l = cotangent_laplacian(&mesh, &LaplacianParams::default())?;
/// assert_eq!(l.nrows(), mesh.vertices.len());
/// # Ok::<(), skin_core::Error>(())
/// ```
pub fn cotangent_laplacian(mesh: &TriMesh, params: &LaplacianParams) -> Result<CscMatrix<f64>> {
    let areas = face_double_areas(mesh, params)?;
    let mut entries = Vec::with_capacity(mesh.faces.len() * 3);
    for (f, dbl) in areas.iter().enumerate() {
        let Some(dbl) = dbl else { continue };
        let idx = mesh.faces[f];
        let p = mesh.triangle(f);
        for k in 0..3 {
            // Corner k is opposite the edge (k+1, k+2).
            let (i, j) = ((k + 1) % 3, (k + 2) % 3);
            let cot = (p[i] - p[k]).dot(p[j] - p[k]) / dbl;
            entries.push((idx[i], idx[j], 0.5 * cot));
        }
    }
    Ok(assemble_laplacian(mesh.vertices.len(), &entries, false))
}

/// Uniform (graph) Laplacian: `L_ij = 1` for every mesh edge, `L_ii = −deg(i)`; the same
/// sign convention as [`cotangent_laplacian`] (symmetric negative semi-definite). Faces are
/// used only for connectivity (degenerate faces are kept).
///
/// # Errors
/// [`Error::Empty`] for a mesh without vertices or faces, [`Error::NonFinite`] /
/// [`Error::IndexOutOfRange`] for an invalid mesh, [`Error::Degenerate`] for a face that
/// repeats a vertex.
pub fn uniform_laplacian(mesh: &TriMesh) -> Result<CscMatrix<f64>> {
    mesh.validate()?;
    if mesh.vertices.is_empty() || mesh.faces.is_empty() {
        return Err(Error::Empty {
            what: "mesh for a Laplacian (no vertices or no faces)",
        });
    }
    let mut entries = Vec::with_capacity(mesh.faces.len() * 3);
    for (f, &[a, b, c]) in mesh.faces.iter().enumerate() {
        if a == b || b == c || c == a {
            return Err(Error::Degenerate {
                what: format!("face {f} repeats a vertex: {:?}", mesh.faces[f]),
            });
        }
        entries.extend_from_slice(&[(a, b, 1.0), (b, c, 1.0), (c, a, 1.0)]);
    }
    Ok(assemble_laplacian(mesh.vertices.len(), &entries, true))
}

/// Diagonal of the lumped mass matrix (vertex areas, squared mesh units); their sum is the
/// surface area (of the non-degenerate faces).
///
/// # Errors
/// As [`cotangent_laplacian`].
pub fn mass_matrix(
    mesh: &TriMesh,
    kind: MassKind,
    params: &LaplacianParams,
) -> Result<DVector<f64>> {
    let areas = face_double_areas(mesh, params)?;
    let mut m = DVector::zeros(mesh.vertices.len());
    for (f, dbl) in areas.iter().enumerate() {
        let Some(dbl) = dbl else { continue };
        let area = 0.5 * dbl;
        let idx = mesh.faces[f];
        let p = mesh.triangle(f);
        match kind {
            MassKind::Barycentric => {
                for &v in &idx {
                    m[v as usize] += area / 3.0;
                }
            }
            MassKind::Voronoi => {
                let share = voronoi_shares(p, *dbl);
                for k in 0..3 {
                    m[idx[k] as usize] += share[k];
                }
            }
        }
    }
    Ok(m)
}

/// Mixed Voronoi area of each corner of one triangle (Meyer et al. 2003, Fig. 4).
fn voronoi_shares(p: [DVec3; 3], dbl: f64) -> [f64; 3] {
    let area = 0.5 * dbl;
    let mut dots = [0.0; 3];
    for (k, d) in dots.iter_mut().enumerate() {
        *d = (p[(k + 1) % 3] - p[k]).dot(p[(k + 2) % 3] - p[k]);
    }
    if let Some(obtuse) = (0..3).find(|&k| dots[k] < 0.0) {
        let mut s = [0.25 * area; 3];
        s[obtuse] = 0.5 * area;
        return s;
    }
    // Non-obtuse: A_k = 1/8 Σ over the two edges at k of |e|² cot(opposite angle).
    let cot = dots.map(|d| d / dbl);
    let mut s = [0.0; 3];
    for k in 0..3 {
        let (i, j) = ((k + 1) % 3, (k + 2) % 3);
        // Edge k–i is opposite corner j, edge k–j is opposite corner i.
        s[k] = 0.125
            * ((p[i] - p[k]).length_squared() * cot[j] + (p[j] - p[k]).length_squared() * cot[i]);
    }
    s
}

#[cfg(test)]
mod tests;
