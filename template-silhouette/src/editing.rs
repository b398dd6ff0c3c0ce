//! Editing the captured sequence (§2.5.3): a geometry edit of the template carried to every
//! frame by deformation transfer (Sumner and Popović, *Deformation Transfer for Triangle
//! Meshes*, SIGGRAPH 2004; the thesis' reference [136], its Figure 2-9).
//!
//! Texture coordinates need no transfer: the captured frames keep the template's vertices
//! and faces, so the template's coordinates (`skin_core::mesh::UvLayout`) serve every frame
//! (the thesis' Figure 2-8).
//!
//! **The objective.** Per triangle `j`, the source deformation `Q_j` maps the template's
//! triangle onto the frame's: `Q_j = Ṽ_j V_j⁻¹` with `V = [v₂ − v₁, v₃ − v₁, v₄ − v₁]` and
//! Sumner and Popović's fourth vertex `v₄ = v₁ + (v₂ − v₁) × (v₃ − v₁) / √‖(v₂ − v₁) × (v₃ −
//! v₁)‖`, so `Q_j` also says how the triangle's normal turns and stretches. The edited
//! frame's vertices `y` minimise `Σ_j A_j ‖J_j(y) − Q_j P_j‖²_F`, where `J_j(y) = Σ_k y_k
//! ∇φ_kᵀ` is the gradient of the piecewise-linear map on the *edited* template's triangle
//! (area `A_j`, tangent projector `P_j`). This is Sumner and Popović's energy for a
//! one-to-one correspondence written in the gradient form of Botsch, Sumner, Pauly and Gross
//! (*Deformation Transfer for Detail-Preserving Surface Editing*, VMV 2006), who show the
//! two agree; the gradient form needs no auxiliary fourth vertex per triangle in the unknowns,
//! and its normal matrix is the edited template's cotangent Laplacian, the same for every
//! frame: it is factorised once, and each frame is one back-substitution with three
//! right-hand sides.
//!
//! **Translation.** The energy sees only gradients, so each connected part's position is free
//! (Sumner and Popović fix one vertex). Here every vertex the edit did not move is softly tied
//! to its captured position with the weight [`DeformationTransfer::DEFAULT_ANCHOR_WEIGHT`],
//! small against the gradient rows, so it places each part without pulling on the edit; a
//! part the edit moved entirely is tied instead to its captured positions plus the edit's
//! displacement. With no edit the transfer reproduces every frame exactly.

use nalgebra::DMatrix;
use nalgebra_sparse::{CooMatrix, CscMatrix};
use skin_core::check;
use skin_core::lsq::{LsqParams, LsqProblem, LsqSolver};
use skin_core::math::{DMat3, DVec3};
use skin_core::mesh::{connected_parts, TriMesh};

use crate::error::Result;

/// A vertex counts as unedited when the edit moved it less than this, m.
const UNEDITED_TOLERANCE_M: f64 = 1e-9;

/// Deformation transfer of one template edit to the frames of a captured sequence.
///
/// ```
/// use skin_core::math::DVec3;
/// use skin_core::mesh::shapes::uv_sphere;
/// use template_silhouette::DeformationTransfer;
///
/// let template = uv_sphere(DVec3::ZERO, 1.0, 12, 16)?;
/// // The edit: the north pole pulled out by 0.3.
/// let mut edited = template.vertices.clone();
/// let pole = (0..edited.len()).max_by(|&a, &b| edited[a].y.total_cmp(&edited[b].y)).unwrap();
/// edited[pole].y += 0.3;
/// // A frame: the sphere shifted by 2 along x.
/// let frame: Vec<DVec3> = template.vertices.iter().map(|v| *v + DVec3::X * 2.0).collect();
/// let transfer = DeformationTransfer::new(&template, &edited)?;
/// let out = transfer.transfer(&frame)?;
/// assert!((out[pole] - (edited[pole] + DVec3::X * 2.0)).length() < 1e-6);
/// # Ok::<(), template_silhouette::Error>(())
/// ```
#[derive(Debug)]
pub struct DeformationTransfer {
    /// Template triangles' inverse frames `V_j⁻¹`.
    template_frames_inv: Vec<DMat3>,
    /// Per edited triangle, `√A_j`.
    root_areas: Vec<f64>,
    /// Per edited triangle, its tangent projector `P_j = I − n nᵀ`.
    projectors: Vec<DMat3>,
    faces: Vec<[u32; 3]>,
    /// Tied vertices and the offset from their captured position they are tied to.
    anchors: Vec<(usize, DVec3)>,
    solver: LsqSolver,
}

impl DeformationTransfer {
    /// Default weight of the soft ties that place each connected part (relative to the
    /// area-weighted gradient rows, whose normal matrix has entries of order one): small
    /// enough that the ties bend nothing, large enough for a well-conditioned factorisation.
    pub const DEFAULT_ANCHOR_WEIGHT: f64 = 1e-4;

    /// Prepares the transfer of the edit `template → edited` (the template's faces with the
    /// vertex positions `edited`), with [`Self::DEFAULT_ANCHOR_WEIGHT`].
    ///
    /// # Errors
    /// [`Error::SizeMismatch`](crate::Error::SizeMismatch) if `edited` has not the
    /// template's vertex count; [`Error::NonFinite`](crate::Error::NonFinite); a
    /// skin-core `Degenerate` error naming the first triangle of zero area in the template
    /// or in the edit.
    pub fn new(template: &TriMesh, edited: &[DVec3]) -> Result<Self> {
        Self::with_anchor_weight(template, edited, Self::DEFAULT_ANCHOR_WEIGHT)
    }

    /// As [`DeformationTransfer::new`] with the anchor weight `anchor_weight` (> 0).
    ///
    /// # Errors
    /// As [`DeformationTransfer::new`]; [`Error::InvalidParam`](crate::Error::InvalidParam)
    /// for a weight that is not positive.
    pub fn with_anchor_weight(
        template: &TriMesh,
        edited: &[DVec3],
        anchor_weight: f64,
    ) -> Result<Self> {
        check::positive("anchor_weight", anchor_weight)?;
        template.validate()?;
        let n = template.vertex_count();
        check::same_size("edited vertices vs template vertices", n, edited.len())?;
        check::all_finite(
            "edited vertices",
            edited.iter().flat_map(|v| [&v.x, &v.y, &v.z]),
        )?;
        let faces = template.faces.clone();
        let mut template_frames_inv = Vec::with_capacity(faces.len());
        let mut root_areas = Vec::with_capacity(faces.len());
        let mut projectors = Vec::with_capacity(faces.len());
        let mut a = CooMatrix::new(3 * faces.len(), n);
        for (j, f) in faces.iter().enumerate() {
            let corners = |v: &[DVec3]| f.map(|i| v[i as usize]);
            let frame = triangle_frame(corners(&template.vertices))
                .ok_or_else(|| degenerate("template", j))?;
            template_frames_inv.push(frame.inverse());
            let [p1, p2, p3] = corners(edited);
            // The same zero-area rule as the template's triangles.
            triangle_frame([p1, p2, p3]).ok_or_else(|| degenerate("edited template", j))?;
            let normal = (p2 - p1).cross(p3 - p1);
            let twice_area = normal.length();
            let nh = normal / twice_area;
            let s = (0.5 * twice_area).sqrt() / twice_area;
            let g = [
                nh.cross(p3 - p2) * s,
                nh.cross(p1 - p3) * s,
                nh.cross(p2 - p1) * s,
            ];
            for d in 0..3 {
                for (k, gk) in g.iter().enumerate() {
                    a.push(3 * j + d, f[k] as usize, gk[d]);
                }
            }
            root_areas.push(s * twice_area);
            projectors.push(DMat3::IDENTITY - outer(nh, nh));
        }
        let anchors = anchors(template, edited)?;
        let mut c = CooMatrix::new(anchors.len(), n);
        for (r, (v, _)) in anchors.iter().enumerate() {
            c.push(r, *v, 1.0);
        }
        let solver = LsqProblem::new(CscMatrix::from(&a))
            .with_term(CscMatrix::from(&c), anchor_weight)
            .factor(&LsqParams::default())?;
        Ok(Self {
            template_frames_inv,
            root_areas,
            projectors,
            faces,
            anchors,
            solver,
        })
    }

    /// The edited frame: the template's deformation into `frame` applied to the edited
    /// template.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`](crate::Error::SizeMismatch) if `frame` has not the template's
    /// vertex count; [`Error::NonFinite`](crate::Error::NonFinite); a skin-core `Degenerate`
    /// error for a frame triangle collapsed to zero area.
    pub fn transfer(&self, frame: &[DVec3]) -> Result<Vec<DVec3>> {
        check::same_size(
            "frame vertices vs template vertices",
            self.solver.n(),
            frame.len(),
        )?;
        check::all_finite(
            "frame vertices",
            frame.iter().flat_map(|v| [&v.x, &v.y, &v.z]),
        )?;
        let mut b = DMatrix::zeros(3 * self.faces.len(), 3);
        for (j, f) in self.faces.iter().enumerate() {
            let deformed = triangle_frame(f.map(|i| frame[i as usize]))
                .ok_or_else(|| degenerate("frame", j))?;
            let q = deformed * self.template_frames_inv[j] * self.projectors[j];
            // Row d of triangle j's block is Σ_k y_k ∇φ_k[d] (scaled by √A), the column d
            // of J: it must equal column d of Q P (scaled alike); one right-hand side per
            // coordinate.
            for d in 0..3 {
                let col = q.col(d) * self.root_areas[j];
                for c in 0..3 {
                    b[(3 * j + d, c)] = col[c];
                }
            }
        }
        let mut d = DMatrix::zeros(self.anchors.len(), 3);
        for (r, (v, offset)) in self.anchors.iter().enumerate() {
            let p = frame[*v] + *offset;
            for c in 0..3 {
                d[(r, c)] = p[c];
            }
        }
        let y = self.solver.solve(&b, &[d])?;
        Ok((0..frame.len())
            .map(|i| DVec3::new(y[(i, 0)], y[(i, 1)], y[(i, 2)]))
            .collect())
    }

    /// [`DeformationTransfer::transfer`] for every frame of a sequence.
    ///
    /// # Errors
    /// As [`DeformationTransfer::transfer`], located at the frame
    /// ([`Context::Frame`](crate::Context::Frame)).
    pub fn transfer_sequence(&self, frames: &[Vec<DVec3>]) -> Result<Vec<Vec<DVec3>>> {
        use crate::error::ResultExt;
        frames
            .iter()
            .enumerate()
            .map(|(t, f)| self.transfer(f).at(crate::Context::Frame(t)))
            .collect()
    }

    /// How many vertices tie the connected parts in place (the unedited ones, or every
    /// vertex of a part the edit moved entirely).
    pub fn anchor_count(&self) -> usize {
        self.anchors.len()
    }
}

/// `[v₂ − v₁, v₃ − v₁, v₄ − v₁]` with Sumner and Popović's fourth vertex; `None` for a
/// triangle of (numerically) zero area.
fn triangle_frame([p1, p2, p3]: [DVec3; 3]) -> Option<DMat3> {
    let (e1, e2) = (p2 - p1, p3 - p1);
    let n = e1.cross(e2);
    let len = n.length();
    if len <= f64::EPSILON * e1.length_squared().max(e2.length_squared()) {
        return None;
    }
    Some(DMat3::from_cols(e1, e2, n / len.sqrt()))
}

fn outer(a: DVec3, b: DVec3) -> DMat3 {
    DMat3::from_cols(a * b.x, a * b.y, a * b.z)
}

fn degenerate(which: &str, face: usize) -> crate::Error {
    skin_core::Error::Degenerate {
        what: format!(
            "triangle {face} of the {which} has zero area; remove it or move its vertices apart"
        ),
    }
    .into()
}

/// The vertices that place each connected part: its unedited vertices (offset zero), or, in
/// a part the edit moved entirely, all its vertices with the edit's displacement.
fn anchors(template: &TriMesh, edited: &[DVec3]) -> Result<Vec<(usize, DVec3)>> {
    let (part, sizes) = connected_parts(template)?;
    let moved: Vec<DVec3> = edited
        .iter()
        .zip(&template.vertices)
        .map(|(e, t)| *e - *t)
        .collect();
    let mut has_unedited = vec![false; sizes.len()];
    for (v, d) in moved.iter().enumerate() {
        if d.length() < UNEDITED_TOLERANCE_M {
            has_unedited[part[v] as usize] = true;
        }
    }
    Ok((0..moved.len())
        .filter_map(|v| {
            if !has_unedited[part[v] as usize] {
                Some((v, moved[v]))
            } else if moved[v].length() < UNEDITED_TOLERANCE_M {
                Some((v, DVec3::ZERO))
            } else {
                None
            }
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use skin_core::math::DAffine3;
    use skin_core::mesh::shapes::uv_sphere;

    /// A unit sphere and the edit that pulls a cap around its north pole out by 0.2 m.
    fn sphere_and_bump() -> (TriMesh, Vec<DVec3>) {
        let sphere = uv_sphere(DVec3::ZERO, 1.0, 16, 24).unwrap();
        let edited = sphere
            .vertices
            .iter()
            .map(|v| {
                let cap = ((v.y - 0.8) / 0.2).clamp(0.0, 1.0);
                *v + *v * 0.2 * cap * cap
            })
            .collect();
        (sphere, edited)
    }

    fn max_distance(a: &[DVec3], b: &[DVec3]) -> f64 {
        a.iter()
            .zip(b)
            .map(|(x, y)| x.distance(*y))
            .fold(0.0, f64::max)
    }

    #[test]
    fn without_an_edit_every_frame_comes_back_unchanged() {
        let (sphere, _) = sphere_and_bump();
        let transfer = DeformationTransfer::new(&sphere, &sphere.vertices).unwrap();
        // A non-rigid frame: a wave along y and a twist.
        let frame: Vec<DVec3> = sphere
            .vertices
            .iter()
            .map(|v| {
                let a = 0.6 * v.y;
                DVec3::new(
                    v.x * a.cos() - v.z * a.sin(),
                    v.y + 0.1 * (3.0 * v.x).sin(),
                    v.x * a.sin() + v.z * a.cos(),
                ) + DVec3::new(0.5, -1.0, 2.0)
            })
            .collect();
        let out = transfer.transfer(&frame).unwrap();
        assert!(
            max_distance(&out, &frame) < 1e-8,
            "{}",
            max_distance(&out, &frame)
        );
    }

    #[test]
    fn a_similar_frame_carries_the_edit_alike_where_copying_the_offsets_does_not() {
        let (sphere, edited) = sphere_and_bump();
        let transfer = DeformationTransfer::new(&sphere, &edited).unwrap();
        // A rotation by 90° about z, a scaling by 1.3 and a shift: a similarity, which
        // Sumner and Popović's fourth vertex follows exactly (a shear would turn it off the
        // sheared normal, by design of their method).
        let map = DAffine3::from_translation(DVec3::new(1.0, 2.0, -0.5))
            * DAffine3::from_rotation_z(std::f64::consts::FRAC_PI_2)
            * DAffine3::from_scale(DVec3::splat(1.3));
        let frame: Vec<DVec3> = sphere
            .vertices
            .iter()
            .map(|v| map.transform_point3(*v))
            .collect();
        let expected: Vec<DVec3> = edited.iter().map(|v| map.transform_point3(*v)).collect();
        let out = transfer.transfer(&frame).unwrap();
        assert!(
            max_distance(&out, &expected) < 1e-6,
            "{}",
            max_distance(&out, &expected)
        );
        // The baseline: the edit's offsets added to the frame, unrotated: off by the bump.
        let copied: Vec<DVec3> = frame
            .iter()
            .zip(edited.iter().zip(&sphere.vertices))
            .map(|(f, (e, t))| *f + (*e - *t))
            .collect();
        assert!(max_distance(&copied, &expected) > 0.2);
        assert!(transfer.anchor_count() < sphere.vertex_count());
    }

    #[test]
    fn a_part_moved_entirely_by_the_edit_is_placed_by_the_edit() {
        let (sphere, _) = sphere_and_bump();
        let shifted: Vec<DVec3> = sphere.vertices.iter().map(|v| *v + DVec3::Z).collect();
        let transfer = DeformationTransfer::new(&sphere, &shifted).unwrap();
        assert_eq!(transfer.anchor_count(), sphere.vertex_count());
        let frame: Vec<DVec3> = sphere.vertices.iter().map(|v| *v * 2.0).collect();
        let out = transfer.transfer(&frame).unwrap();
        let expected: Vec<DVec3> = frame.iter().map(|v| *v + DVec3::Z).collect();
        assert!(max_distance(&out, &expected) < 1e-6);
    }

    #[test]
    fn bad_inputs_are_clear_errors() {
        let (sphere, edited) = sphere_and_bump();
        let short = &edited[1..];
        let e = DeformationTransfer::new(&sphere, short).unwrap_err();
        assert!(e.to_string().contains("size mismatch"), "{e}");
        let mut nan = edited.clone();
        nan[3].x = f64::NAN;
        let e = DeformationTransfer::new(&sphere, &nan).unwrap_err();
        assert!(e.to_string().contains("non-finite"), "{e}");
        let mut flat = edited.clone();
        let f = sphere.faces[sphere.faces.len() / 2];
        flat[f[1] as usize] = flat[f[0] as usize];
        flat[f[2] as usize] = flat[f[0] as usize];
        let e = DeformationTransfer::new(&sphere, &flat).unwrap_err();
        assert!(e.to_string().contains("zero area"), "{e}");
        assert!(matches!(
            DeformationTransfer::with_anchor_weight(&sphere, &edited, 0.0),
            Err(crate::Error::Core(_))
        ));
        let transfer = DeformationTransfer::new(&sphere, &edited).unwrap();
        let e = transfer.transfer(short).unwrap_err();
        assert!(e.to_string().contains("size mismatch"), "{e}");
        let e = transfer
            .transfer_sequence(&[sphere.vertices.clone(), nan])
            .unwrap_err();
        assert!(e.to_string().starts_with("frame 1:"), "{e}");
    }
}
