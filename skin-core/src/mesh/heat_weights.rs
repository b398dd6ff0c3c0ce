//! Automatic skinning weights by bone heat diffusion (Baran & Popović 2007, "Automatic
//! Rigging and Animation of 3D Characters" — Pinocchio, §4), which the Vlasic 2010 thesis
//! uses to attach its templates to their skeletons (§2.5.1).
//!
//! Pinocchio treats the mesh as a heat-conducting body, bone `i` held at temperature 1 and
//! the others at 0, and takes the equilibrium temperature as weight `w_i`:
//!
//! ```text
//! (−Δ + H) w_i = H p_i
//! ```
//!
//! with `Δ` the discrete surface Laplacian, `H_jj = c / d_j²` (`d_j` = distance from vertex
//! `j` to its nearest bone), `p_i^j = 1` if bone `i` is nearest to vertex `j` (shared as
//! `1/k` among `k` equidistant bones, with `H_jj = k c / d_j²`). With the cotangent
//! Laplacian `L` and lumped mass `M` (`Δ = M⁻¹ L`) the system is multiplied by `M` to make it
//! symmetric positive definite: `(−L + M H) w_i = M H p_i`. One sparse Cholesky
//! factorisation serves all bones as one multi-right-hand-side solve.
//!
//! Pinocchio sets `H_jj = 0` when the segment from vertex `j` to its nearest bone leaves the
//! mesh (a visibility test). This implementation omits that test (every vertex is heated by
//! its nearest bone): on meshes where a surface point lies closer to an unrelated bone
//! across a gap (an arm hanging against the torso), weights then bleed across the gap; pose
//! the mesh with limbs apart (T or A pose, as the MakeHuman base mesh) for best results.

use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

use crate::lsq::{CholeskyParams, SparseCholesky};
use crate::math::DVec3;
use crate::mesh::skinning::{SkinWeights, DEFAULT_MAX_INFLUENCES, DEFAULT_PRUNE_BELOW};
use crate::mesh::{cotangent_laplacian, mass_matrix, LaplacianParams, MassKind, TriMesh};
use crate::{Error, Result};

/// A bone as a line segment in rest-pose coordinates (independent of the skeleton module).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BoneSegment {
    /// Joint at the head of the bone, mesh units.
    pub start: DVec3,
    /// Joint at the tail of the bone, mesh units (may equal `start` for a point bone).
    pub end: DVec3,
}

impl BoneSegment {
    /// Euclidean distance from `p` to the segment.
    pub fn distance(&self, p: DVec3) -> f64 {
        let d = self.end - self.start;
        let len2 = d.length_squared();
        let t = if len2 > 0.0 {
            ((p - self.start).dot(d) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (p - (self.start + d * t)).length()
    }
}

/// Default heat constant `c` (Baran & Popović 2007 §4: "c = 1").
pub const DEFAULT_HEAT_CONSTANT: f64 = 1.0;
/// Default relative tolerance under which bones count as equidistant.
pub const DEFAULT_TIE_TOLERANCE: f64 = 1e-9;
/// Default distance floor as a fraction of the bounding-box diagonal.
pub const DEFAULT_MIN_DISTANCE_REL: f64 = 1e-6;

/// Knobs of [`bone_heat_weights`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct HeatWeightsParams {
    /// Heat constant `c` in `H_jj = c / d_j²`, dimensionless (Baran & Popović 2007 §4).
    /// Default: [`DEFAULT_HEAT_CONSTANT`] = 1.
    pub heat_constant: f64,
    /// Weights below this are dropped before renormalising (Pinocchio output is dense;
    /// sparse weights are what real-time skinning consumes). Default:
    /// [`DEFAULT_PRUNE_BELOW`] = 0.01.
    pub prune_below: f64,
    /// Maximum influences kept per vertex (GPU skinning convention). Default:
    /// [`DEFAULT_MAX_INFLUENCES`] = 4.
    pub max_influences: usize,
    /// Relative distance tolerance under which bones are equidistant and share the vertex.
    /// Default: [`DEFAULT_TIE_TOLERANCE`].
    pub tie_tolerance: f64,
    /// Distances are floored at this fraction of the bounding-box diagonal, so vertices on a
    /// bone get a large but finite `H`. Default: [`DEFAULT_MIN_DISTANCE_REL`].
    pub min_distance_rel: f64,
    /// Laplacian construction (degenerate triangles). Default: [`LaplacianParams::default`].
    pub laplacian: LaplacianParams,
    /// Mass lumping for `Δ = M⁻¹ L`. Default: [`MassKind::Voronoi`].
    pub mass: MassKind,
    /// Sparse Cholesky settings. Default: [`CholeskyParams::default`].
    pub cholesky: CholeskyParams,
}

impl Default for HeatWeightsParams {
    fn default() -> Self {
        Self {
            heat_constant: DEFAULT_HEAT_CONSTANT,
            prune_below: DEFAULT_PRUNE_BELOW,
            max_influences: DEFAULT_MAX_INFLUENCES,
            tie_tolerance: DEFAULT_TIE_TOLERANCE,
            min_distance_rel: DEFAULT_MIN_DISTANCE_REL,
            laplacian: LaplacianParams::default(),
            mass: MassKind::Voronoi,
            cholesky: CholeskyParams::default(),
        }
    }
}

/// Dense bone-heat weights (n × bones), before pruning; rows sum to one up to rounding.
///
/// # Errors
/// As [`bone_heat_weights`].
pub fn bone_heat_weights_dense(
    mesh: &TriMesh,
    bones: &[BoneSegment],
    params: &HeatWeightsParams,
) -> Result<DMatrix<f64>> {
    if bones.is_empty() {
        return Err(Error::Empty { what: "bones" });
    }
    if !bones
        .iter()
        .all(|b| b.start.is_finite() && b.end.is_finite())
    {
        return Err(Error::NonFinite { what: "bones" });
    }
    crate::check::positive("heat_constant", params.heat_constant)?;
    crate::check::positive("min_distance_rel", params.min_distance_rel)?;
    crate::check::positive("tie_tolerance", params.tie_tolerance)?;
    let l = cotangent_laplacian(mesh, &params.laplacian)?;
    let mut mass = mass_matrix(mesh, params.mass, &params.laplacian)?;
    let n = mesh.vertices.len();
    // Vertices without area (unreferenced or only in skipped degenerate faces) would make the
    // system singular; a tiny mass makes their equation H w = H p (nearest bone wins).
    let mean_mass = mass.sum() / n as f64;
    for m in mass.iter_mut() {
        *m = m.max(1e-12 * mean_mass);
    }
    let (lo, hi) = mesh.vertices.iter().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    );
    let min_d = params.min_distance_rel * (hi - lo).length().max(f64::MIN_POSITIVE);
    let k = bones.len();
    let mut rhs = DMatrix::zeros(n, k);
    let mut diag_add = vec![0.0; n];
    let mut dist = vec![0.0; k];
    for (j, p) in mesh.vertices.iter().enumerate() {
        for (b, bone) in bones.iter().enumerate() {
            dist[b] = bone.distance(*p);
        }
        let dmin = dist.iter().copied().fold(f64::INFINITY, f64::min);
        let cut = dmin * (1.0 + params.tie_tolerance) + min_d * params.tie_tolerance;
        let nearest: Vec<usize> = (0..k).filter(|&b| dist[b] <= cut).collect();
        let d = dmin.max(min_d);
        let h = nearest.len() as f64 * params.heat_constant / (d * d);
        diag_add[j] = mass[j] * h;
        for &b in &nearest {
            rhs[(j, b)] = mass[j] * h / nearest.len() as f64;
        }
    }
    // A = −L + M H on L's pattern (the Laplacian always stores its diagonal).
    let mut a = l;
    let offsets = a.col_offsets().to_vec();
    let rows = a.row_indices().to_vec();
    let values = a.values_mut();
    for j in 0..n {
        for p in offsets[j]..offsets[j + 1] {
            values[p] = -values[p];
            if rows[p] == j {
                values[p] += diag_add[j];
            }
        }
    }
    let chol = SparseCholesky::new(&a, &params.cholesky)?;
    chol.solve_in_place(&mut rhs)?;
    Ok(rhs)
}

/// Sparse, normalised skinning weights by bone heat diffusion (module docs): one sparse
/// Cholesky factorisation and one solve with a right-hand side per bone, then weights below
/// `params.prune_below` dropped, at most `params.max_influences` kept, and renormalised.
///
/// # Errors
/// [`Error::Empty`] for no bones or an empty mesh, [`Error::NonFinite`] for NaN bones or
/// vertices, [`Error::InvalidParam`] for invalid params, [`Error::Degenerate`] for a
/// degenerate triangle under [`crate::mesh::DegenerateFaces::Error`], [`Error::Singular`] if
/// the heat system cannot be factorised.
///
/// # Example
/// ```
/// use skin_core::math::DVec3;
/// use skin_core::mesh::{bone_heat_weights, shapes, BoneSegment, HeatWeightsParams};
/// let arm = shapes::cylinder(0.1, 2.0, 12, 20)?;
/// let bones = [
///     BoneSegment { start: DVec3::ZERO, end: DVec3::Z },
///     BoneSegment { start: DVec3::Z, end: 2.0 * DVec3::Z },
/// ];
/// let w = bone_heat_weights(&arm, &bones, &HeatWeightsParams::default())?;
/// assert_eq!(w.vertex_count(), arm.vertices.len());
/// # Ok::<(), skin_core::Error>(())
/// ```
pub fn bone_heat_weights(
    mesh: &TriMesh,
    bones: &[BoneSegment],
    params: &HeatWeightsParams,
) -> Result<SkinWeights> {
    let dense = bone_heat_weights_dense(mesh, bones, params)?;
    SkinWeights::from_dense(&dense, params.prune_below, params.max_influences)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{DAffine3, DQuat};
    use crate::mesh::{shapes, skin};

    fn two_bone_arm() -> (TriMesh, [BoneSegment; 2]) {
        let arm = shapes::cylinder(0.1, 2.0, 16, 40).unwrap();
        let bones = [
            BoneSegment {
                start: DVec3::ZERO,
                end: DVec3::Z,
            },
            BoneSegment {
                start: DVec3::Z,
                end: 2.0 * DVec3::Z,
            },
        ];
        (arm, bones)
    }

    #[test]
    fn partition_of_unity_and_bone_middles() {
        let (arm, bones) = two_bone_arm();
        let dense = bone_heat_weights_dense(&arm, &bones, &HeatWeightsParams::default()).unwrap();
        for i in 0..arm.vertices.len() {
            assert!((dense.row(i).sum() - 1.0).abs() < 1e-9, "row {i}");
        }
        let w = bone_heat_weights(&arm, &bones, &HeatWeightsParams::default()).unwrap();
        let d = w.to_dense();
        for (i, p) in arm.vertices.iter().enumerate() {
            assert!((d.row(i).sum() - 1.0).abs() < 1e-12);
            // Middle of each bone: rigidly attached.
            if (p.z - 0.5).abs() < 0.06 {
                assert!(d[(i, 0)] > 0.97, "z {} w {}", p.z, d[(i, 0)]);
            }
            if (p.z - 1.5).abs() < 0.06 {
                assert!(d[(i, 1)] > 0.97, "z {} w {}", p.z, d[(i, 1)]);
            }
            // At the joint: shared about equally, and monotone along the arm.
            if (p.z - 1.0).abs() < 1e-9 {
                assert!((d[(i, 0)] - 0.5).abs() < 0.1, "joint w {}", d[(i, 0)]);
            }
        }
        // Monotone transition from bone 0 to bone 1 along z (one ring per 0.05).
        let ring_w0: Vec<f64> = (0..=40).map(|r| d[(r * 16, 0)]).collect();
        assert!(ring_w0.windows(2).all(|p| p[1] <= p[0] + 1e-9));
    }

    #[test]
    fn skinning_with_heat_weights_bends_the_arm() {
        let (arm, bones) = two_bone_arm();
        let w = bone_heat_weights(&arm, &bones, &HeatWeightsParams::default()).unwrap();
        // Identity pose reproduces the rest mesh.
        let rest = skin(&arm.vertices, &w, &[DAffine3::IDENTITY; 2]).unwrap();
        for (a, b) in rest.iter().zip(&arm.vertices) {
            assert!((*a - *b).length() < 1e-14);
        }
        // Bend the forearm 90° about the elbow (x axis through z = 1).
        let elbow = DVec3::Z;
        let bend = DAffine3::from_translation(elbow)
            * DAffine3::from_quat(DQuat::from_rotation_x(std::f64::consts::FRAC_PI_2))
            * DAffine3::from_translation(-elbow);
        let posed = skin(&arm.vertices, &w, &[DAffine3::IDENTITY, bend]).unwrap();
        for (p, q) in arm.vertices.iter().zip(&posed) {
            if (p.z - 1.75).abs() < 0.06 {
                assert!((*q - bend.transform_point3(*p)).length() < 1e-2);
            }
            if (p.z - 0.25).abs() < 0.06 {
                assert!((*q - *p).length() < 1e-2);
            }
        }
    }

    #[test]
    fn errors() {
        let (arm, bones) = two_bone_arm();
        let p = HeatWeightsParams::default();
        assert!(matches!(
            bone_heat_weights(&arm, &[], &p),
            Err(Error::Empty { .. })
        ));
        let nan = [BoneSegment {
            start: DVec3::NAN,
            end: DVec3::Z,
        }];
        assert!(matches!(
            bone_heat_weights(&arm, &nan, &p),
            Err(Error::NonFinite { .. })
        ));
        let bad = HeatWeightsParams {
            heat_constant: 0.0,
            ..p
        };
        assert!(matches!(
            bone_heat_weights(&arm, &bones, &bad),
            Err(Error::InvalidParam { .. })
        ));
        assert!(matches!(
            bone_heat_weights(&TriMesh::default(), &bones, &p),
            Err(Error::Empty { .. })
        ));
        // A vertex lying on a bone and an unreferenced vertex still get valid weights.
        let mut m = arm.clone();
        m.vertices.push(DVec3::new(0.0, 0.0, 0.5));
        let w = bone_heat_weights(&m, &bones, &p).unwrap();
        let last: Vec<_> = w.influences(m.vertices.len() - 1).collect();
        assert_eq!(last, vec![(0, 1.0)]);
    }
}
