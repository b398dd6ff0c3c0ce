//! Linear blend skinning with sparse per-vertex weights (Vlasic 2010 thesis §2.4 and §2.5.1:
//! the template is attached to its skeleton with linear blend skinning, weights from
//! Pinocchio; see [`super::bone_heat_weights`]).
//!
//! `v'_i = Σ_j b_i^j T_j v_i`, where `T_j = world_from_rest` of bone `j` (the bone's current
//! world transform composed with the inverse of its rest transform) and the weights `b_i^j`
//! of each vertex are non-negative and sum to one.

use nalgebra::DMatrix;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::TriMesh;
use crate::math::{DAffine3, DMat3, DVec3};
use crate::skeleton::Skeleton;
use crate::{Error, Result};

/// A mesh bound to a skeleton for linear blend skinning: the checked sizes of a rig and its
/// bind matrices `joint_from_world_rest` (the inverse joint frames of the rest pose θ = 0),
/// shared by the studio's performer and the template of Vlasic 2010 §2.2.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SkinBinding {
    joint_from_world_rest: Vec<DAffine3>,
}

impl SkinBinding {
    /// Checks that `mesh` is valid and not empty and that `weights` has one row per vertex
    /// and one bone per joint, then computes the bind matrices at θ = 0.
    ///
    /// # Errors
    /// The mesh's validation errors; [`Error::Empty`] for a mesh without vertices;
    /// [`Error::SizeMismatch`] for weights of another mesh or skeleton; errors of forward
    /// kinematics.
    pub fn new(mesh: &TriMesh, skeleton: &Skeleton, weights: &SkinWeights) -> Result<Self> {
        mesh.validate()?;
        if mesh.vertices.is_empty() {
            return Err(Error::Empty {
                what: "skinned mesh (no vertices)",
            });
        }
        if weights.vertex_count() != mesh.vertex_count() {
            return Err(Error::SizeMismatch {
                what: "skin weight rows vs mesh vertices",
                expected: mesh.vertex_count(),
                got: weights.vertex_count(),
            });
        }
        if weights.bone_count() != skeleton.joint_count() {
            return Err(Error::SizeMismatch {
                what: "skin weight bones vs skeleton joints",
                expected: skeleton.joint_count(),
                got: weights.bone_count(),
            });
        }
        let rest = skeleton.forward_kinematics(&skeleton.rest_pose())?;
        Ok(SkinBinding {
            joint_from_world_rest: rest
                .world_from_joint()
                .iter()
                .map(|t| t.inverse())
                .collect(),
        })
    }

    /// The skinning transforms `world_from_rest[j] = world_from_joint[j] ·
    /// joint_from_world_rest[j]` that map rest-pose coordinates to the pose whose joint
    /// frames are `world_from_joint` (what [`skin`] takes). Extra or missing frames are
    /// ignored (the result has `min(len, joint count)` entries).
    pub fn world_from_rest(&self, world_from_joint: &[DAffine3]) -> Vec<DAffine3> {
        world_from_joint
            .iter()
            .zip(&self.joint_from_world_rest)
            .map(|(w, r)| *w * *r)
            .collect()
    }
}

/// Sparse skinning weights: for each vertex a short list of `(bone, weight)` pairs, weights
/// positive and summing to one (compressed row storage).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SkinWeights {
    /// `offsets[i]..offsets[i + 1]` indexes the influences of vertex `i`.
    offsets: Vec<usize>,
    /// Bone index of each influence.
    bones: Vec<u32>,
    /// Weight of each influence.
    weights: Vec<f64>,
    /// Number of bones the indices refer to.
    bone_count: usize,
}

impl SkinWeights {
    /// Builds weights from per-vertex `(bone, weight)` lists, merging repeated bones and
    /// normalising each list to sum one. Zero weights are dropped.
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`] for a bone `≥ bone_count`, [`Error::NonFinite`] for NaN/inf,
    /// [`Error::InvalidParam`] for a negative weight, [`Error::Degenerate`] for a vertex whose
    /// weights sum to zero.
    pub fn from_lists(lists: &[Vec<(u32, f64)>], bone_count: usize) -> Result<Self> {
        let mut out = Self {
            offsets: Vec::with_capacity(lists.len() + 1),
            bones: Vec::new(),
            weights: Vec::new(),
            bone_count,
        };
        out.offsets.push(0);
        let mut row: Vec<(u32, f64)> = Vec::new();
        for (i, list) in lists.iter().enumerate() {
            row.clear();
            for &(b, w) in list {
                if b as usize >= bone_count {
                    return Err(Error::IndexOutOfRange {
                        what: "skinning weight bone",
                        index: b as usize,
                        len: bone_count,
                    });
                }
                if !w.is_finite() {
                    return Err(Error::NonFinite {
                        what: "skinning weight",
                    });
                }
                if w < 0.0 {
                    return Err(Error::InvalidParam {
                        name: "skinning weight",
                        reason: format!("vertex {i}: weights must be >= 0, got {w}"),
                    });
                }
                if w > 0.0 {
                    match row.iter_mut().find(|e| e.0 == b) {
                        Some(e) => e.1 += w,
                        None => row.push((b, w)),
                    }
                }
            }
            let sum: f64 = row.iter().map(|e| e.1).sum();
            if sum <= 0.0 {
                return Err(Error::Degenerate {
                    what: format!("vertex {i} has no positive skinning weight"),
                });
            }
            row.sort_by_key(|e| e.0);
            for &(b, w) in &row {
                out.bones.push(b);
                out.weights.push(w / sum);
            }
            out.offsets.push(out.bones.len());
        }
        Ok(out)
    }

    /// Sparsifies dense weights (n × bones, e.g. from a heat solve): negative values are
    /// clamped to 0, each vertex keeps its `max_influences` largest weights that are
    /// `≥ prune_below` (at least its largest one), and the kept weights are renormalised.
    ///
    /// # Errors
    /// [`Error::NonFinite`] for NaN/inf, [`Error::InvalidParam`] if `max_influences` is 0 or
    /// `prune_below` is negative or not finite, [`Error::Degenerate`] for a vertex whose
    /// weights are all ≤ 0.
    pub fn from_dense(w: &DMatrix<f64>, prune_below: f64, max_influences: usize) -> Result<Self> {
        if max_influences == 0 {
            return Err(Error::InvalidParam {
                name: "max_influences",
                reason: "must be >= 1".into(),
            });
        }
        crate::check::non_negative("prune_below", prune_below)?;
        crate::check::all_finite("dense skinning weights", w.iter())?;
        let mut lists = Vec::with_capacity(w.nrows());
        let mut row: Vec<(u32, f64)> = Vec::new();
        for i in 0..w.nrows() {
            row.clear();
            row.extend((0..w.ncols()).map(|j| (j as u32, w[(i, j)].max(0.0))));
            row.sort_by(|a, b| b.1.total_cmp(&a.1));
            let keep = row
                .iter()
                .take(max_influences)
                .enumerate()
                .filter(|(k, e)| *k == 0 || e.1 >= prune_below)
                .map(|(_, e)| *e)
                .collect();
            lists.push(keep);
        }
        Self::from_lists(&lists, w.ncols())
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.offsets.len() - 1
    }

    /// Number of bones the indices refer to.
    pub fn bone_count(&self) -> usize {
        self.bone_count
    }

    /// The `(bone, weight)` influences of vertex `i`, bones ascending.
    ///
    /// # Panics
    /// If `i ≥ vertex_count()` (an indexing error in the caller).
    pub fn influences(&self, i: usize) -> impl Iterator<Item = (u32, f64)> + '_ {
        let r = self.offsets[i]..self.offsets[i + 1];
        self.bones[r.clone()]
            .iter()
            .copied()
            .zip(self.weights[r].iter().copied())
    }

    /// Dense n × bones weight matrix.
    pub fn to_dense(&self) -> DMatrix<f64> {
        let mut d = DMatrix::zeros(self.vertex_count(), self.bone_count);
        for i in 0..self.vertex_count() {
            for (b, w) in self.influences(i) {
                d[(i, b as usize)] = w;
            }
        }
        d
    }
}

/// Linear blend skinning: `v'_i = (Σ_j b_i^j T_j) v_i`, in parallel over vertices.
///
/// `world_from_rest[j]` maps rest-pose coordinates to posed world coordinates for bone `j`.
///
/// # Errors
/// [`Error::SizeMismatch`] if `rest.len()` differs from the weights' vertex count or
/// `world_from_rest.len()` from their bone count; [`Error::NonFinite`] for NaN/inf
/// transforms or positions.
pub fn skin(
    rest: &[DVec3],
    weights: &SkinWeights,
    world_from_rest: &[DAffine3],
) -> Result<Vec<DVec3>> {
    if rest.len() != weights.vertex_count() {
        return Err(Error::SizeMismatch {
            what: "rest vertices vs skinning weight rows",
            expected: weights.vertex_count(),
            got: rest.len(),
        });
    }
    if world_from_rest.len() != weights.bone_count() {
        return Err(Error::SizeMismatch {
            what: "bone transforms vs skinning weight bones",
            expected: weights.bone_count(),
            got: world_from_rest.len(),
        });
    }
    if !world_from_rest.iter().all(|t| t.is_finite()) {
        return Err(Error::NonFinite {
            what: "bone transforms",
        });
    }
    if !rest.iter().all(|v| v.is_finite()) {
        return Err(Error::NonFinite {
            what: "rest vertices",
        });
    }
    Ok(rest
        .par_iter()
        .enumerate()
        .map(|(i, v)| {
            let mut m = DMat3::ZERO;
            let mut t = DVec3::ZERO;
            for (b, w) in weights.influences(i) {
                let tr = &world_from_rest[b as usize];
                m += tr.matrix3 * w;
                t += tr.translation * w;
            }
            m * *v + t
        })
        .collect())
}

/// A rest mesh rigged to `from` carried to `to`, the same joint tree with other bone lengths
/// (a performer with other proportions, a template sized to one): each rest vertex moves with
/// its skin weights' blend of the joints' rest-frame moves, i.e. linear blend skinning with
/// `to_rest[j] · from_rest[j]⁻¹` (both skeletons at θ = 0). A vertex carried by one bone
/// follows its joint, so the limbs keep their cross-sections and only their lengths change;
/// vertices in a joint region blend the two joints' moves.
///
/// # Errors
/// [`Error::InvalidParam`] for skeletons with other joint counts or other parents; as
/// [`skin`] (weights of another mesh or skeleton, non-finite input); errors of forward
/// kinematics.
pub fn resize_rest(
    rest: &[DVec3],
    weights: &SkinWeights,
    from: &Skeleton,
    to: &Skeleton,
) -> Result<Vec<DVec3>> {
    let (a, b) = (from.joints(), to.joints());
    if a.len() != b.len() || a.iter().zip(b).any(|(x, y)| x.parent != y.parent) {
        return Err(Error::InvalidParam {
            name: "skeleton",
            reason: format!(
                "the resized skeleton must have the same joint tree ({} joints, got {})",
                a.len(),
                b.len()
            ),
        });
    }
    let rest_frames = |sk: &Skeleton| -> Result<Vec<DAffine3>> {
        Ok(sk
            .forward_kinematics(&sk.rest_pose())?
            .world_from_joint()
            .to_vec())
    };
    let moves: Vec<DAffine3> = rest_frames(from)?
        .iter()
        .zip(rest_frames(to)?)
        .map(|(a, b)| b * a.inverse())
        .collect();
    skin(rest, weights, &moves)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::DQuat;

    fn sample() -> (Vec<DVec3>, SkinWeights) {
        let rest: Vec<DVec3> = (0..10)
            .map(|i| DVec3::new(i as f64 * 0.1, 0.2, -0.3))
            .collect();
        let lists: Vec<Vec<(u32, f64)>> = (0..10)
            .map(|i| vec![(0, 10.0 - i as f64), (1, i as f64 + 0.5), (0, 0.5)])
            .collect();
        (rest, SkinWeights::from_lists(&lists, 2).unwrap())
    }

    #[test]
    fn binding_checks_sizes_and_maps_rest_to_pose() {
        use crate::skeleton::{Dof, Joint};
        let root = Joint::new(
            "root",
            None,
            DVec3::new(0.0, 1.0, 0.0),
            vec![Dof::rotation("rz", DVec3::Z, None)],
        );
        let skeleton = Skeleton::new(vec![root]).unwrap();
        let mesh = crate::mesh::shapes::icosphere(0).unwrap();
        let one = |n: usize| SkinWeights::from_lists(&vec![vec![(0, 1.0)]; n], 1).unwrap();
        let b = SkinBinding::new(&mesh, &skeleton, &one(mesh.vertex_count())).unwrap();
        // θ = 0: identity; a turn about the joint at (0, 1, 0) keeps that point fixed.
        let fk = skeleton.forward_kinematics(&[0.0]).unwrap();
        let t = b.world_from_rest(fk.world_from_joint());
        assert!(t[0].abs_diff_eq(DAffine3::IDENTITY, 1e-12));
        let fk = skeleton.forward_kinematics(&[1.0]).unwrap();
        let t = b.world_from_rest(fk.world_from_joint());
        assert!((t[0].transform_point3(DVec3::Y) - DVec3::Y).length() < 1e-12);
        assert!(matches!(
            SkinBinding::new(&mesh, &skeleton, &one(3)),
            Err(Error::SizeMismatch { .. })
        ));
        let two = SkinWeights::from_lists(&vec![vec![(1, 1.0)]; mesh.vertex_count()], 2).unwrap();
        assert!(matches!(
            SkinBinding::new(&mesh, &skeleton, &two),
            Err(Error::SizeMismatch { .. })
        ));
        let empty = TriMesh {
            vertices: vec![],
            faces: vec![],
        };
        assert!(SkinBinding::new(&empty, &skeleton, &one(0)).is_err());
    }

    #[test]
    fn normalised_and_identity_gives_rest() {
        let (rest, w) = sample();
        for i in 0..w.vertex_count() {
            let s: f64 = w.influences(i).map(|e| e.1).sum();
            assert!((s - 1.0).abs() < 1e-15);
            assert_eq!(w.influences(i).count(), 2); // repeated bone 0 merged
        }
        let posed = skin(&rest, &w, &[DAffine3::IDENTITY; 2]).unwrap();
        for (a, b) in posed.iter().zip(&rest) {
            assert!((*a - *b).length() < 1e-15);
        }
        // One common rigid motion moves the mesh rigidly.
        let t = DAffine3::from_rotation_translation(
            DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 0.7),
            DVec3::new(0.1, -2.0, 0.3),
        );
        let posed = skin(&rest, &w, &[t, t]).unwrap();
        for (a, b) in posed.iter().zip(&rest) {
            assert!((*a - t.transform_point3(*b)).length() < 1e-14);
        }
        // Blend of two translations is the weighted translation.
        let t0 = DAffine3::from_translation(DVec3::X);
        let t1 = DAffine3::from_translation(DVec3::Y);
        let posed = skin(&rest, &w, &[t0, t1]).unwrap();
        for (i, p) in posed.iter().enumerate() {
            let d = w.to_dense();
            let expect = rest[i] + DVec3::X * d[(i, 0)] + DVec3::Y * d[(i, 1)];
            assert!((*p - expect).length() < 1e-14);
        }
    }

    #[test]
    fn dense_round_trip_and_pruning() {
        let d = DMatrix::from_row_slice(2, 4, &[0.7, 0.2, 0.005, 0.095, -0.1, 0.3, 0.3, 0.4]);
        let w = SkinWeights::from_dense(&d, 0.01, 2).unwrap();
        let back = w.to_dense();
        assert!((back[(0, 0)] - 0.7 / 0.9).abs() < 1e-15);
        assert!((back[(0, 1)] - 0.2 / 0.9).abs() < 1e-15);
        assert_eq!(back[(0, 2)], 0.0);
        assert_eq!(back[(0, 3)], 0.0);
        assert!((back.row(1).sum() - 1.0).abs() < 1e-15);
        assert_eq!(back[(1, 0)], 0.0);
        assert!(SkinWeights::from_dense(&d, 0.01, 0).is_err());
        assert!(SkinWeights::from_dense(&d, -1.0, 2).is_err());
        assert!(matches!(
            SkinWeights::from_dense(&DMatrix::from_element(1, 2, -1.0), 0.0, 2),
            Err(Error::Degenerate { .. })
        ));
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(32))]
        /// Any positive weights normalise to a partition of unity, and a transform shared by
        /// all bones moves every vertex rigidly.
        #[test]
        fn partition_of_unity_and_rigid_invariance(
            raw in proptest::collection::vec(
                proptest::collection::vec((0u32..5, 0.001f64..10.0), 1..6), 1..20),
            angle in -3.0f64..3.0,
            shift in -5.0f64..5.0,
        ) {
            let w = SkinWeights::from_lists(&raw, 5).unwrap();
            for i in 0..w.vertex_count() {
                let s: f64 = w.influences(i).map(|e| e.1).sum();
                proptest::prop_assert!((s - 1.0).abs() < 1e-12);
            }
            let rest: Vec<DVec3> =
                (0..raw.len()).map(|i| DVec3::new(i as f64, -0.5 * i as f64, 1.0)).collect();
            let t = DAffine3::from_rotation_translation(
                DQuat::from_rotation_y(angle),
                DVec3::splat(shift),
            );
            let posed = skin(&rest, &w, &[t; 5]).unwrap();
            for (p, r) in posed.iter().zip(&rest) {
                proptest::prop_assert!((*p - t.transform_point3(*r)).length() < 1e-12);
            }
        }
    }

    #[test]
    fn errors() {
        let (rest, w) = sample();
        assert!(matches!(
            skin(&rest[..5], &w, &[DAffine3::IDENTITY; 2]),
            Err(Error::SizeMismatch { .. })
        ));
        assert!(matches!(
            skin(&rest, &w, &[DAffine3::IDENTITY; 3]),
            Err(Error::SizeMismatch { .. })
        ));
        let mut bad = DAffine3::IDENTITY;
        bad.translation.x = f64::NAN;
        assert!(matches!(
            skin(&rest, &w, &[bad, DAffine3::IDENTITY]),
            Err(Error::NonFinite { .. })
        ));
        assert!(matches!(
            SkinWeights::from_lists(&[vec![(2, 1.0)]], 2),
            Err(Error::IndexOutOfRange { .. })
        ));
        assert!(matches!(
            SkinWeights::from_lists(&[vec![(0, -1.0)]], 2),
            Err(Error::InvalidParam { .. })
        ));
        assert!(matches!(
            SkinWeights::from_lists(&[vec![(0, f64::NAN)]], 2),
            Err(Error::NonFinite { .. })
        ));
        assert!(matches!(
            SkinWeights::from_lists(&[vec![]], 2),
            Err(Error::Degenerate { .. })
        ));
    }
}
