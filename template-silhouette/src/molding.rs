//! Laplacian coordinates and the soft-constrained molding solve (Vlasic 2010 §2.4.1).
//!
//! ```text
//! L = Δ V_T,     V = argmin ‖Δ V − w_L L'‖² + w_C ‖C V − P‖²          (§2.4.1, Eq. 2.1–2.2)
//! ```
//!
//! `Δ` is the cotangent Laplacian ("cotangent weights work best", [101]) normalised per row
//! (`Δ = I − D⁻¹W`, `W` the cotangent weights, `D` their row sums), the form of the Laplacian
//! coordinates of [3, 97]: `ℓ_i = v_i − Σ_j w_ij v_j / Σ_j w_ij` is dimensionless in its
//! weights and independent of the mesh's resolution, which is what gives `w_C = 1000` of
//! Eq. 2.1–2.2 a meaning (with an area-normalised operator the same weight would mean
//! something different for every mesh). `C` has one row per constrained surface point with
//! its barycentric coordinates (a vertex is a row with a single 1).
//!
//! **One symbolic factorisation for the whole sequence.** The normal matrix is
//! `ΔᵀΔ + w_C CᵀC`. A barycentric row couples the three corners of one face, and those pairs
//! are already in the pattern of `ΔᵀΔ` (corners of a face are mesh neighbours), so the
//! pattern — stored with the face pairs added explicitly, in case a cotangent weight is
//! exactly zero — never changes: [`Molding::solve`] only adds values and refactorises
//! numerically through skin-core's [`SparseCholesky::refactor`].

use nalgebra::DMatrix;
use nalgebra_sparse::{CooMatrix, CscMatrix};
use skin_core::lsq::{CholeskyParams, SparseCholesky};
use skin_core::math::DVec3;
use skin_core::mesh::{
    connected_parts, cotangent_laplacian, LaplacianParams, SurfacePoint, TriMesh,
};

use crate::error::{Error, Result};

/// A soft positional constraint `w_C ‖c·V − p‖²` on a surface point (one row of `C` and `P`
/// in Eq. 2.1–2.2).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SoftConstraint {
    /// The constrained point: a face and barycentric weights (a vertex is a corner with
    /// weight 1).
    pub point: SurfacePoint,
    /// Its target position, world metres.
    pub target: DVec3,
}

/// The template's Laplacian operator, its Laplacian coordinates and a Cholesky factorisation
/// whose symbolic analysis is made once and reused by every [`Molding::solve`]. A clone
/// shares that analysis and refactorises on its own (one per thread).
///
/// Eq. 2.2 at full detail (`w_L = 1`) with three vertices moved by the same shift: the
/// whole template follows them.
///
/// ```
/// use skin_core::math::DVec3;
/// use skin_core::mesh::shapes::uv_sphere;
/// use skin_core::mesh::{LaplacianParams, SurfacePoint};
/// use template_silhouette::{Molding, SoftConstraint};
///
/// let sphere = uv_sphere(DVec3::ZERO, 1.0, 12, 16)?;
/// let mut molding = Molding::new(&sphere, &LaplacianParams::default())?;
/// let shift = DVec3::new(0.1, -0.2, 0.05);
/// let constraints = [0, 40, 80]
///     .into_iter()
///     .map(|f| {
///         let point = SurfacePoint::corner(f, 0)?;
///         let v = sphere.faces[f as usize][0] as usize;
///         Ok(SoftConstraint { point, target: sphere.vertices[v] + shift })
///     })
///     .collect::<Result<Vec<_>, skin_core::Error>>()?;
/// let coords = molding.coordinates().to_vec();
/// let moved = molding.solve(1.0, &coords, 1000.0, &constraints)?;
/// for (m, v) in moved.iter().zip(&sphere.vertices) {
///     assert!((*m - (*v + shift)).length() < 1e-6);
/// }
/// # Ok::<(), template_silhouette::Error>(())
/// ```
#[derive(Clone)]
pub struct Molding {
    faces: Vec<[u32; 3]>,
    /// `Δ` (n × n, row-normalised cotangent Laplacian).
    delta: CscMatrix<f64>,
    /// Laplacian coordinates of the template, `L = Δ V_T` (rows `ℓ_i`).
    coords: Vec<DVec3>,
    /// Lower triangle of `ΔᵀΔ` on the fixed pattern (face pairs included).
    normal: CscMatrix<f64>,
    /// `ΔᵀΔ` values on that pattern.
    base_values: Vec<f64>,
    /// Per face, the value slots of its corner pairs `(a, b)` (lower entry) in `normal`.
    face_slots: Vec<[[usize; 3]; 3]>,
    /// Per vertex, its connected part of the template (parts share no edge: a body and a
    /// separate skirt are two). The Laplacian fixes each part only up to a translation, so
    /// every part needs a constraint in each solve.
    part: Vec<u32>,
    /// Vertices per part.
    part_sizes: Vec<usize>,
    chol: SparseCholesky,
}

impl std::fmt::Debug for Molding {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Molding")
            .field("vertices", &self.coords.len())
            .field("pattern_nnz", &self.normal.nnz())
            .finish()
    }
}

impl Molding {
    /// Builds `Δ` and `L = Δ V_T` for `template` and analyses the normal matrix's pattern.
    ///
    /// # Errors
    /// Errors of [`cotangent_laplacian`] (degenerate triangles, invalid mesh);
    /// [`Error::InvalidParam`] for a vertex whose cotangent weights do not sum to a positive
    /// value (an isolated vertex or a fan of degenerate or very obtuse triangles).
    pub fn new(template: &TriMesh, params: &LaplacianParams) -> Result<Self> {
        let n = template.vertex_count();
        let lap = cotangent_laplacian(template, params)?;
        // skin-core's convention: L_ij = w_ij, L_ii = −Σ_j w_ij. Normalise rows: Δ = −D⁻¹L.
        let mut diag = vec![0.0; n];
        for (r, c, v) in lap.triplet_iter() {
            if r == c {
                diag[r] = -*v;
            }
        }
        if let Some(i) = diag.iter().position(|d| !(*d > 0.0 && d.is_finite())) {
            return Err(Error::InvalidParam {
                name: "template",
                reason: format!(
                    "vertex {i} has cotangent weights summing to {} (isolated vertex or \
                     degenerate fan); the Laplacian coordinates need a positive sum: remove the \
                     vertex or its degenerate faces",
                    diag[i]
                ),
            });
        }
        let mut delta = lap;
        {
            let (_, rows, values) = delta.csc_data_mut();
            for (r, v) in rows.iter().zip(values.iter_mut()) {
                *v = -*v / diag[*r];
            }
        }
        let coords = apply(&delta, &template.vertices);
        let dtd = &delta.transpose() * &delta;
        let mut coo = CooMatrix::new(n, n);
        for (r, c, v) in dtd.triplet_iter() {
            if r >= c {
                coo.push(r, c, *v);
            }
        }
        for f in &template.faces {
            for a in f {
                for b in f {
                    if a >= b {
                        coo.push(*a as usize, *b as usize, 0.0);
                    }
                }
            }
        }
        let normal = CscMatrix::from(&coo);
        let slot = |r: usize, c: usize| -> Result<usize> {
            let col = normal.col(c);
            let off = normal.col_offsets()[c];
            col.row_indices()
                .binary_search(&r)
                .map(|k| off + k)
                .map_err(|_| Error::InvalidParam {
                    name: "template",
                    reason: "internal: face pair missing from the normal pattern".into(),
                })
        };
        let mut face_slots = Vec::with_capacity(template.faces.len());
        for f in &template.faces {
            let mut s = [[0usize; 3]; 3];
            for (a, row) in s.iter_mut().enumerate() {
                for (b, out) in row.iter_mut().enumerate() {
                    let (i, j) = (f[a] as usize, f[b] as usize);
                    *out = slot(i.max(j), i.min(j))?;
                }
            }
            face_slots.push(s);
        }
        let base_values = normal.values().to_vec();
        // The analysis needs a positive definite matrix on the pattern: ΔᵀΔ + I.
        let mut analysed = normal.clone();
        for c in 0..n {
            let s = slot(c, c)?;
            analysed.values_mut()[s] += 1.0;
        }
        let chol = SparseCholesky::new(&analysed, &CholeskyParams::default())?;
        let (part, part_sizes) = connected_parts(template)?;
        Ok(Molding {
            faces: template.faces.clone(),
            delta,
            coords,
            normal,
            base_values,
            face_slots,
            part,
            part_sizes,
            chol,
        })
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.coords.len()
    }

    /// The operator `Δ` (row-normalised cotangent Laplacian, n × n).
    pub fn laplacian(&self) -> &CscMatrix<f64> {
        &self.delta
    }

    /// The template's Laplacian coordinates `L = Δ V_T` (§2.4.1).
    pub fn coordinates(&self) -> &[DVec3] {
        &self.coords
    }

    /// Solves `argmin_V ‖Δ V − w_L L'‖² + w_C ‖C V − P‖²` (Eq. 2.1 with `w_L = 0`, Eq. 2.2),
    /// with `coords` the (rotated) Laplacian coordinates `L'` and one row of `C`, `P` per
    /// constraint. Only a numeric refactorisation is made.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if `coords` does not have one row per vertex;
    /// [`Error::IndexOutOfRange`] for a constraint on a missing face; [`Error::NonFinite`]
    /// for NaN/inf weights, coordinates or targets; [`Error::InvalidParam`] for a negative
    /// weight, and for a connected part of the template that no constraint with a positive
    /// weight touches (the Laplacian fixes each part only up to a translation: a separate
    /// skirt, say, needs a nearly-rigid vertex, a silhouette constraint or
    /// `ShapeParams::w_anchor > 0`); skin-core's `Singular` if the system is singular
    /// nonetheless.
    pub fn solve(
        &mut self,
        w_l: f64,
        coords: &[DVec3],
        w_c: f64,
        constraints: &[SoftConstraint],
    ) -> Result<Vec<DVec3>> {
        self.solve_weighted(w_l, coords, &[(w_c, constraints)])
    }

    /// [`Molding::solve`] with several groups of constraints, each with its own weight:
    /// `argmin_V ‖Δ V − w_L L'‖² + Σ_g w_g ‖C_g V − P_g‖²`.
    ///
    /// # Errors
    /// As [`Molding::solve`].
    pub fn solve_weighted(
        &mut self,
        w_l: f64,
        coords: &[DVec3],
        groups: &[(f64, &[SoftConstraint])],
    ) -> Result<Vec<DVec3>> {
        let n = self.vertex_count();
        skin_core::check::non_negative("w_L", w_l)?;
        for (w_c, _) in groups {
            skin_core::check::non_negative("w_C", *w_c)?;
        }
        if coords.len() != n {
            return Err(Error::SizeMismatch {
                what: "Laplacian coordinates vs template vertices (give one per template vertex)",
                expected: n,
                got: coords.len(),
            });
        }
        if !coords.iter().all(|c| c.is_finite()) {
            return Err(Error::NonFinite {
                what: "Laplacian coordinates (remove NaN or infinite values)",
            });
        }
        let mut values = self.base_values.clone();
        // Right side: Δᵀ (w_L L') + w_C Cᵀ P.
        let scaled: Vec<DVec3> = coords.iter().map(|c| w_l * *c).collect();
        let mut rhs = apply_transpose(&self.delta, &scaled);
        for (w_c, c) in groups
            .iter()
            .flat_map(|(w, cs)| cs.iter().map(move |c| (*w, c)))
        {
            let f = c.point.face as usize;
            let (Some(face), Some(slots)) = (self.faces.get(f), self.face_slots.get(f)) else {
                return Err(Error::IndexOutOfRange {
                    what: "constraint face (give a face of the template)",
                    index: f,
                    len: self.faces.len(),
                });
            };
            if !(c.target.is_finite() && c.point.bary.iter().all(|b| b.is_finite())) {
                return Err(Error::NonFinite {
                    what:
                        "constraint target or barycentric weights (remove NaN or infinite values)",
                });
            }
            let b = c.point.bary;
            for a in 0..3 {
                rhs[face[a] as usize] += w_c * b[a] * c.target;
                for k in 0..=a {
                    // Lower entry (a, k): Σ over both orders for a ≠ k is one product each
                    // side of the diagonal, so the stored lower entry gets b_a b_k once.
                    values[slots[a][k]] += w_c * b[a] * b[k];
                }
            }
        }
        self.check_every_part_constrained(groups)?;
        let mut m = self.normal.clone();
        m.values_mut().copy_from_slice(&values);
        self.chol.refactor(&m)?;
        let mut x = DMatrix::zeros(n, 3);
        for (i, r) in rhs.iter().enumerate() {
            x[(i, 0)] = r.x;
            x[(i, 1)] = r.y;
            x[(i, 2)] = r.z;
        }
        self.chol.solve_in_place(&mut x)?;
        Ok((0..n)
            .map(|i| DVec3::new(x[(i, 0)], x[(i, 1)], x[(i, 2)]))
            .collect())
    }
}

/// `M x` for a sparse `M` and per-row 3-vectors.
fn apply(m: &CscMatrix<f64>, x: &[DVec3]) -> Vec<DVec3> {
    let mut out = vec![DVec3::ZERO; m.nrows()];
    for (r, c, v) in m.triplet_iter() {
        out[r] += *v * x[c];
    }
    out
}

/// `Mᵀ x` for a sparse `M` and per-row 3-vectors.
fn apply_transpose(m: &CscMatrix<f64>, x: &[DVec3]) -> Vec<DVec3> {
    let mut out = vec![DVec3::ZERO; m.ncols()];
    for (r, c, v) in m.triplet_iter() {
        out[c] += *v * x[r];
    }
    out
}

impl Molding {
    /// [`Error::InvalidParam`] naming the first connected part that no constraint of a
    /// positive weight touches (its system is singular: a free translation).
    fn check_every_part_constrained(&self, groups: &[(f64, &[SoftConstraint])]) -> Result<()> {
        let mut touched = vec![false; self.part_sizes.len()];
        for (w_c, constraints) in groups {
            if *w_c <= 0.0 {
                continue;
            }
            for c in *constraints {
                // Faces were checked by the caller.
                if let Some(face) = self.faces.get(c.point.face as usize) {
                    for (k, &v) in face.iter().enumerate() {
                        if c.point.bary[k] != 0.0 {
                            touched[self.part[v as usize] as usize] = true;
                        }
                    }
                }
            }
        }
        match touched.iter().position(|t| !t) {
            None => Ok(()),
            Some(p) => {
                let vertex = self.part.iter().position(|&q| q as usize == p).unwrap_or(0);
                Err(Error::InvalidParam {
                    name: "constraints",
                    reason: format!(
                        "no constraint touches the template's connected part of {} vertices \
                         that holds vertex {vertex} ({} parts in all), so its position is \
                         undetermined; constrain it (a nearly-rigid vertex, a silhouette \
                         constraint, or ShapeParams::w_anchor > 0 to anchor it to skinning) or \
                         join it to the rest of the mesh",
                        self.part_sizes[p],
                        self.part_sizes.len()
                    ),
                })
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use skin_core::math::DQuat;
    use skin_core::mesh::shapes;

    fn vertex_constraint(mesh: &TriMesh, v: usize, target: DVec3) -> SoftConstraint {
        let (f, k) = mesh
            .faces
            .iter()
            .enumerate()
            .find_map(|(f, face)| face.iter().position(|&x| x as usize == v).map(|k| (f, k)))
            .unwrap();
        SoftConstraint {
            point: SurfacePoint::corner(f as u32, k).unwrap(),
            target,
        }
    }

    #[test]
    fn full_detail_with_rigidly_moved_constraints_reproduces_the_rigid_motion() {
        // w_L = 1 with L' = R L and constraints at the rigidly moved template: the rigid
        // motion of the template is the exact minimiser (both terms vanish).
        let mesh = shapes::icosphere(2).unwrap();
        let mut m = Molding::new(&mesh, &LaplacianParams::default()).unwrap();
        let r = DQuat::from_rotation_y(0.7) * DQuat::from_rotation_x(-0.3);
        let t = DVec3::new(0.2, -1.0, 3.0);
        let moved: Vec<DVec3> = mesh.vertices.iter().map(|v| r * *v + t).collect();
        let coords: Vec<DVec3> = m.coordinates().iter().map(|l| r * *l).collect();
        let cons: Vec<SoftConstraint> = [0, 17, 40, 99]
            .iter()
            .map(|&v| vertex_constraint(&mesh, v, moved[v]))
            .collect();
        let v = m.solve(1.0, &coords, 1000.0, &cons).unwrap();
        let err = v
            .iter()
            .zip(&moved)
            .map(|(a, b)| (*a - *b).length())
            .fold(0.0, f64::max);
        assert!(err < 1e-9, "max error {err}");
    }

    #[test]
    fn barycentric_constraints_pull_the_point_not_a_vertex() {
        // Eq. 2.1 (w_L = 0): a barycentric point pulled by a large weight lands on its
        // target; repeated solves with other constraints reuse the analysis.
        let mesh = shapes::icosphere(2).unwrap();
        let mut m = Molding::new(&mesh, &LaplacianParams::default()).unwrap();
        let zero = vec![DVec3::ZERO; mesh.vertex_count()];
        for (i, f) in [3u32, 50, 120].into_iter().enumerate() {
            let bary = [0.2, 0.3, 0.5];
            let target = DVec3::new(0.1 * i as f64, 0.5, -0.2);
            let cons = [
                SoftConstraint {
                    point: SurfacePoint::new(f, bary).unwrap(),
                    target,
                },
                vertex_constraint(&mesh, 0, DVec3::new(1.0, 0.0, 0.0)),
            ];
            let v = m.solve(0.0, &zero, 1e6, &cons).unwrap();
            let face = mesh.faces[f as usize];
            let p: DVec3 = (0..3).map(|k| bary[k] * v[face[k] as usize]).sum();
            assert!((p - target).length() < 1e-4, "{p} vs {target}");
            assert!((v[0] - DVec3::X).length() < 1e-4);
        }
    }

    #[test]
    fn bad_inputs_are_clear_errors() {
        let mesh = shapes::icosphere(1).unwrap();
        let mut m = Molding::new(&mesh, &LaplacianParams::default()).unwrap();
        let coords = m.coordinates().to_vec();
        // No constraint: the translation is free.
        assert!(matches!(
            m.solve(1.0, &coords, 1000.0, &[]),
            Err(Error::InvalidParam {
                name: "constraints",
                ..
            })
        ));
        let c = vertex_constraint(&mesh, 0, DVec3::ZERO);
        assert!(matches!(
            m.solve(1.0, &coords[1..], 1000.0, &[c]),
            Err(Error::SizeMismatch { .. })
        ));
        let mut bad = c;
        bad.point.face = 10_000;
        assert!(matches!(
            m.solve(1.0, &coords, 1000.0, &[bad]),
            Err(Error::IndexOutOfRange { .. })
        ));
        let mut bad = c;
        bad.target = DVec3::NAN;
        assert!(matches!(
            m.solve(1.0, &coords, 1000.0, &[bad]),
            Err(Error::NonFinite { .. })
        ));
        assert!(m.solve(-1.0, &coords, 1000.0, &[c]).is_err());
        // Still usable after errors.
        assert!(m.solve(1.0, &coords, 1000.0, &[c]).is_ok());
    }

    /// A template of two separate parts (a sphere and a shifted copy, as a body and a separate
    /// skirt): constraints on one part only are a clear error naming the other part; one
    /// constraint on each solves; a zero-weight group does not count.
    #[test]
    fn every_connected_part_needs_a_constraint() {
        let one = shapes::icosphere(1).unwrap();
        let k = one.vertex_count() as u32;
        let mut vertices = one.vertices.clone();
        vertices.extend(one.vertices.iter().map(|v| *v + DVec3::new(3.0, 0.0, 0.0)));
        let mut faces = one.faces.clone();
        faces.extend(one.faces.iter().map(|f| [f[0] + k, f[1] + k, f[2] + k]));
        let mesh = TriMesh::new(vertices, faces).unwrap();
        let mut m = Molding::new(&mesh, &LaplacianParams::default()).unwrap();
        let coords = m.coordinates().to_vec();
        let first = vertex_constraint(&mesh, 0, mesh.vertices[0]);
        let second = vertex_constraint(&mesh, k as usize, mesh.vertices[k as usize]);
        let err = m
            .solve(1.0, &coords, 1000.0, &[first])
            .unwrap_err()
            .to_string();
        assert!(
            err.contains(&format!("part of {k} vertices")) && err.contains("2 parts"),
            "{err}"
        );
        assert!(m
            .solve_weighted(1.0, &coords, &[(1000.0, &[first]), (0.0, &[second])])
            .is_err());
        let v = m.solve(1.0, &coords, 1000.0, &[first, second]).unwrap();
        assert!((v[k as usize] - mesh.vertices[k as usize]).length() < 1e-6);
    }
}
