//! The needle model as a residual over skinning (ours, beyond Sand 2003).
//!
//! The method is documented on [`PoseSpaceModel`]; the module is private and everything
//! public is re-exported at the crate root.

use glam::DVec3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use skin_core::mesh::{bone_heat_weights, rest_bones, skin, HeatWeightsParams, MeshQuery};
use skin_core::mesh::{SkinBinding, SkinWeights, TriMesh};
use skin_core::skeleton::{ForwardKinematics, Skeleton};

use crate::animate::animate;
use crate::params::ReconstructionParams;
use crate::primitive::NeedleBody;
use crate::reconstruct::{NeedleModel, PrimitiveFitReport, Reconstruction};
use crate::store::{NeedleObservations, ObservationStore};
use crate::surface::{union_mesh, SurfaceParams};
use crate::{Context, Error, Result, ResultExt};

/// Needle lengths of a captured rest shape under linear blend skinning, needle by needle: each
/// needle's rest endpoint is skinned with the bone weights of the surface there, and its
/// length at a pose is the skinned endpoint's distance along the posed needle.
///
/// Projecting a skinned endpoint onto its needle instead of casting the needle against a
/// skinned mesh costs a few affine transforms per needle (every needle of every training
/// frame is needed) and agrees with the ray cast wherever skinning moves the surface along
/// the needle; where it shears the surface sideways the two differ, and the residual model
/// on top absorbs the difference like any other pose effect.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SkinnedNeedles {
    /// Rest endpoints (world, θ = 0), primitive-major, needle order within each.
    endpoints: Vec<DVec3>,
    /// Skinning weights of each endpoint (bones = joints).
    weights: SkinWeights,
    /// First endpoint of each primitive, plus the total.
    offsets: Vec<usize>,
    /// The captured surface's binding to the skeleton (its LBS bind matrices).
    binding: SkinBinding,
}

impl SkinnedNeedles {
    /// Skins the needle endpoints of `rest_model` at the rest pose (θ = 0) by bone-heat
    /// weights (Baran and Popović 2007) computed on its watertight union surface
    /// ([`union_mesh`] with `surface`): each endpoint takes the weights of its closest surface
    /// point, blended over that triangle's corners.
    ///
    /// # Errors
    /// Errors of [`animate`], [`union_mesh`], [`bone_heat_weights`] (degenerate surface) and
    /// the closest-point queries.
    pub fn from_rest(
        body: &NeedleBody,
        skeleton: &Skeleton,
        rest_model: &NeedleModel,
        surface: &SurfaceParams,
    ) -> Result<Self> {
        let rest = animate(body, rest_model, skeleton, &skeleton.rest_pose())?;
        let mesh = union_mesh(&rest, surface)?;
        let bones = rest_bones(skeleton)?;
        let vertex_weights = bone_heat_weights(&mesh, &bones, &HeatWeightsParams::default())?;
        let endpoints: Vec<DVec3> = rest
            .primitives
            .iter()
            .flat_map(|p| p.endpoints.iter().copied())
            .collect();
        let mut offsets = vec![0];
        for p in &rest.primitives {
            offsets.push(offsets[offsets.len() - 1] + p.endpoints.len());
        }
        let weights = blend_weights(&mesh, &vertex_weights, &endpoints, bones.len())?;
        Ok(Self {
            endpoints,
            weights,
            offsets,
            binding: SkinBinding::new(&mesh, skeleton, &vertex_weights)?,
        })
    }

    /// Skinned needle lengths (metres, signed: negative when skinning pushes the endpoint
    /// behind the bone axis) of every primitive at the pose of `fk`.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] (or its skin-core form from [`skin`]) for a body or skeleton
    /// other than the one it was built for.
    pub fn lengths(&self, body: &NeedleBody, fk: &ForwardKinematics) -> Result<Vec<Vec<f32>>> {
        let world = fk.world_from_joint();
        if body.primitives.len() + 1 != self.offsets.len() {
            return Err(Error::SizeMismatch {
                what: "skinned needles: primitives of another body",
                expected: self.offsets.len() - 1,
                got: body.primitives.len(),
            });
        }
        // `skin` checks the joint count against the weights' bones.
        let posed = skin(
            &self.endpoints,
            &self.weights,
            &self.binding.world_from_rest(world),
        )?;
        body.primitives
            .iter()
            .enumerate()
            .map(|(p, prim)| {
                let range = self.offsets[p]..self.offsets[p + 1];
                if range.len() != prim.needle_count() {
                    return Err(Error::SizeMismatch {
                        what: "skinned needles of a primitive",
                        expected: range.len(),
                        got: prim.needle_count(),
                    });
                }
                let t = world[prim.carrier];
                Ok(posed[range]
                    .iter()
                    .enumerate()
                    .map(|(j, q)| {
                        let (o, d) = prim.needle_world(&t, j);
                        (*q - o).dot(d) as f32
                    })
                    .collect())
            })
            .collect()
    }
}

/// Weights of each point: those of its closest point on `mesh`, blended over the triangle's
/// corners by barycentric weights.
fn blend_weights(
    mesh: &TriMesh,
    vertex_weights: &SkinWeights,
    points: &[DVec3],
    bone_count: usize,
) -> Result<SkinWeights> {
    let query = MeshQuery::new(mesh)?;
    let closest = query.closest_points(points)?;
    let lists: Vec<Vec<(u32, f64)>> = closest
        .iter()
        .map(|c| {
            let face = mesh.faces[c.point.face as usize];
            face.iter()
                .zip(c.point.bary)
                .flat_map(|(&v, b)| {
                    vertex_weights
                        .influences(v as usize)
                        .map(move |(bone, w)| (bone, w * b))
                })
                .collect()
        })
        .collect();
    Ok(SkinWeights::from_lists(&lists, bone_count)?)
}

/// The needle model as a residual over skinning (ours, beyond Sand 2003): pose-space
/// deformation (Lewis, Cordner and Fong 2000) with silhouette observations.
///
/// Sand's NRBF predicts each needle's whole length from the configuration point, so between
/// prototypes it blends lengths, and the purely geometric change of a needle with the joint
/// angle (the forearm needle near the elbow shortening as the elbow closes) is interpolated
/// from about a hundred prototypes. Here the prediction is
///
/// ```text
/// ℓ_j(θ) = ℓ^LBS_j(θ) + r_j(x(θ)),
/// ```
///
/// where `ℓ^LBS` are the needle lengths of the captured rest shape under linear blend
/// skinning ([`SkinnedNeedles`]: the plain model at θ = 0, bone-heat weights) and `r` is the
/// NRBF of §5.1–5.3 fitted to the *residuals* of the observations, `ℓ_obs − ℓ^LBS(θ_frame)`,
/// each at the pose of its own frame. Skinning carries the geometric change exactly at every
/// pose; the NRBF carries only what skinning misses (muscles, creases, the silhouette's bias
/// at each pose). The robust minimum still applies: an observed length bounds the true one
/// from above, so its residual bounds the true residual from above too.
///
/// Training: [`PoseSpaceModel::reconstruct`] needs the pose θ of every frame of the store
/// ([`ObservationStore::sample_frames`] ties each sample to its frame). The same parameters
/// as [`NeedleModel::reconstruct`] apply to the residual NRBF.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PoseSpaceModel {
    /// The skinned rest shape, needle by needle.
    pub skinned: SkinnedNeedles,
    /// The NRBF of the residuals over skinning.
    pub residual: NeedleModel,
}

/// Result of [`PoseSpaceModel::reconstruct`].
#[derive(Clone, Debug, PartialEq)]
pub struct PoseSpaceReconstruction {
    /// The model.
    pub model: PoseSpaceModel,
    /// The plain model whose rest shape is skinned (as [`NeedleModel::reconstruct`]).
    pub plain: Reconstruction,
    /// One report per primitive of the residual NRBF's fit (the model is
    /// [`PoseSpaceModel::residual`]).
    pub residual_reports: Vec<PrimitiveFitReport>,
}

impl PoseSpaceModel {
    /// Fits the plain model, skins its rest shape ([`SkinnedNeedles::from_rest`]) and fits
    /// the NRBF of the observations' residuals over that skinning; `thetas[f]` is the pose of
    /// frame `f` of `store`.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if `thetas` has fewer entries than the store has frames (in
    /// [`Error::At`] with the primitive of the first sample beyond them); the errors of
    /// [`NeedleModel::reconstruct`], [`SkinnedNeedles::from_rest`] and forward kinematics.
    pub fn reconstruct(
        store: &ObservationStore,
        body: &NeedleBody,
        skeleton: &Skeleton,
        thetas: &[Vec<f64>],
        params: &ReconstructionParams,
        surface: &SurfaceParams,
    ) -> Result<PoseSpaceReconstruction> {
        if thetas.len() < store.frame_count() {
            return Err(Error::SizeMismatch {
                what: "poses (one per frame of the store)",
                expected: store.frame_count(),
                got: thetas.len(),
            });
        }
        let plain = NeedleModel::reconstruct(store, body, params)?;
        let skinned = SkinnedNeedles::from_rest(body, skeleton, &plain.model, surface)?;
        // Skinned lengths of every frame, per primitive: frames × needles.
        let per_frame: Vec<Vec<Vec<f32>>> = thetas[..store.frame_count()]
            .par_iter()
            .enumerate()
            .map(|(f, theta)| {
                let fk = skeleton.forward_kinematics(theta).at(Context::Frame(f))?;
                skinned.lengths(body, &fk)
            })
            .collect::<Result<_>>()?;
        let residuals = |p: usize| -> Result<NeedleObservations> {
            let obs = store.by_needle(p)?;
            let frames = store.sample_frames(p);
            let mut length_m = obs.lengths_m().to_vec();
            let offsets = obs.offsets();
            for j in 0..obs.needle_count() {
                let range = offsets[j] as usize..offsets[j + 1] as usize;
                for (l, &s) in length_m[range.clone()]
                    .iter_mut()
                    .zip(&obs.samples()[range])
                {
                    let f = frames.get(s as usize).copied().ok_or(Error::SizeMismatch {
                        what: "frame tags of the store's samples",
                        expected: s as usize + 1,
                        got: frames.len(),
                    })? as usize;
                    *l -= per_frame[f][p][j];
                }
            }
            NeedleObservations::from_csr(offsets.to_vec(), obs.samples().to_vec(), length_m)
        };
        let residual = NeedleModel::reconstruct_observations(store, body, params, residuals)?;
        Ok(PoseSpaceReconstruction {
            model: PoseSpaceModel {
                skinned,
                residual: residual.model,
            },
            plain,
            residual_reports: residual.reports,
        })
    }

    /// Needle lengths of every primitive at pose θ (metres): skinned lengths plus the
    /// residual NRBF at each primitive's configuration point.
    ///
    /// # Errors
    /// Errors of forward kinematics, [`SkinnedNeedles::lengths`] and
    /// [`NeedleModel::needle_lengths`] (a model of another body).
    pub fn lengths(
        &self,
        body: &NeedleBody,
        skeleton: &Skeleton,
        theta: &[f64],
    ) -> Result<Vec<Vec<f32>>> {
        let fk = skeleton.forward_kinematics(theta)?;
        let mut out = self.skinned.lengths(body, &fk)?;
        for (p, (prim, base)) in body.primitives.iter().zip(&mut out).enumerate() {
            let r = self
                .residual
                .needle_lengths(p, &prim.config.point_f32(&fk)?)?;
            for (b, r) in base.iter_mut().zip(r) {
                *b += r;
            }
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::primitive::BodyLayout;
    use skin_core::skeleton::{human_skeleton, HumanParams};

    /// Poses of `frames` frames bending both elbows and the left knee from 0 to 1.2 rad.
    fn bends(sk: &Skeleton, frames: usize) -> Vec<Vec<f64>> {
        let dofs: Vec<usize> = ["l_elbow.flexion", "r_elbow.flexion", "l_knee.flexion"]
            .iter()
            .map(|n| sk.dof_index(n).unwrap())
            .collect();
        (0..frames)
            .map(|f| {
                let mut theta = sk.rest_pose();
                for &d in &dofs {
                    theta[d] = 1.2 * f as f64 / (frames - 1) as f64;
                }
                theta
            })
            .collect()
    }

    /// A store in which frame `f` observes every needle once at `lengths(θ_f)[p][j]`.
    fn store_of(
        sk: &Skeleton,
        body: &NeedleBody,
        thetas: &[Vec<f64>],
        lengths: impl Fn(&[f64]) -> Vec<Vec<f32>>,
    ) -> ObservationStore {
        let mut store = ObservationStore::new(&body.store_shapes()).unwrap();
        for theta in thetas {
            let fk = sk.forward_kinematics(theta).unwrap();
            let l = lengths(theta);
            for (p, prim) in body.primitives.iter().enumerate() {
                let config = prim.config.point(&fk).unwrap();
                let obs: Vec<(u16, f32)> = l[p]
                    .iter()
                    .enumerate()
                    .map(|(j, &v)| (j as u16, v.clamp(0.001, prim.max_length_m as f32 - 0.001)))
                    .collect();
                store.push_sample(p, &config, &obs).unwrap();
            }
            store.end_frame();
        }
        store
    }

    /// A fixed pattern of lengths, 4–4.6 cm.
    fn pattern(body: &NeedleBody) -> Vec<Vec<f32>> {
        body.primitives
            .iter()
            .enumerate()
            .map(|(p, prim)| {
                (0..prim.needle_count())
                    .map(|j| 0.04 + 0.001 * ((p + j) % 7) as f32)
                    .collect()
            })
            .collect()
    }

    fn fixture() -> (Skeleton, NeedleBody) {
        let sk = human_skeleton(&HumanParams::default()).unwrap();
        let body = NeedleBody::new(&sk, &BodyLayout::table_3_1().with_density(0.25)).unwrap();
        (sk, body)
    }

    #[test]
    fn skinned_needles_reproduce_the_rest_shape_and_move_with_the_bones() {
        let (sk, body) = fixture();
        let thetas = bends(&sk, 12);
        let store = store_of(&sk, &body, &thetas, |_| pattern(&body));
        let params = ReconstructionParams::default().with_prototype_count_n(5);
        let plain = NeedleModel::reconstruct(&store, &body, &params)
            .unwrap()
            .model;
        let skinned =
            SkinnedNeedles::from_rest(&body, &sk, &plain, &SurfaceParams::default()).unwrap();
        let rest = sk.forward_kinematics(&sk.rest_pose()).unwrap();
        let at_rest = skinned.lengths(&body, &rest).unwrap();
        let model = animate(&body, &plain, &sk, &sk.rest_pose()).unwrap();
        for (l, p) in at_rest.iter().zip(&model.primitives) {
            for (a, b) in l.iter().zip(&p.lengths) {
                assert!((f64::from(*a) - b).abs() < 1e-5, "{a} vs {b}");
            }
        }
        // A rigid turn of the whole body (the root) changes no length.
        let mut theta = sk.rest_pose();
        theta[sk.dof_index("pelvis.yaw").unwrap()] = 0.7;
        let turned = skinned
            .lengths(&body, &sk.forward_kinematics(&theta).unwrap())
            .unwrap();
        for (a, b) in turned.iter().flatten().zip(at_rest.iter().flatten()) {
            assert!((a - b).abs() < 1e-5, "{a} vs {b}");
        }
        // Another body is an error, not a panic.
        let other = NeedleBody::new(&sk, &BodyLayout::table_3_1()).unwrap();
        assert!(skinned.lengths(&other, &rest).is_err());
    }

    #[test]
    fn a_body_that_skins_is_followed_between_training_poses_better_than_by_the_plain_model() {
        let (sk, body) = fixture();
        let params = ReconstructionParams::default()
            .with_prototype_count_n(6)
            .with_min_near(1);
        // The reference skinning: a fixed shape's rest needles skinned by bone heat.
        let thetas = bends(&sk, 40);
        let still = store_of(&sk, &body, &thetas, |_| pattern(&body));
        let shape = NeedleModel::reconstruct(&still, &body, &params)
            .unwrap()
            .model;
        let reference =
            SkinnedNeedles::from_rest(&body, &sk, &shape, &SurfaceParams::default()).unwrap();
        // Observations: that skinning, 2 mm out (a constant residual).
        let truth = |theta: &[f64]| {
            let mut l = reference
                .lengths(&body, &sk.forward_kinematics(theta).unwrap())
                .unwrap();
            l.iter_mut().flatten().for_each(|v| *v += 0.002);
            l
        };
        let train: Vec<Vec<f64>> = thetas.iter().step_by(2).cloned().collect();
        let store = store_of(&sk, &body, &train, truth);
        let fit = PoseSpaceModel::reconstruct(
            &store,
            &body,
            &sk,
            &train,
            &params,
            &SurfaceParams::default(),
        )
        .unwrap();
        // Scored on the needles the bends deform (more than 1 mm between the straight and the
        // most bent pose): elsewhere both models reproduce a constant and share the store's
        // f32 floor, which would dilute the comparison.
        let (first, last) = (truth(&thetas[0]), truth(&thetas[thetas.len() - 1]));
        let deforming: Vec<Vec<bool>> = first
            .iter()
            .zip(&last)
            .map(|(a, b)| a.iter().zip(b).map(|(a, b)| (a - b).abs() > 1e-3).collect())
            .collect();
        assert!(deforming.iter().flatten().filter(|d| **d).count() >= 20);
        // At poses between the training poses.
        let (mut psd, mut plain) = (vec![], vec![]);
        for theta in thetas.iter().skip(1).step_by(2) {
            let fk = sk.forward_kinematics(theta).unwrap();
            let t = truth(theta);
            let a = fit.model.lengths(&body, &sk, theta).unwrap();
            for (p, prim) in body.primitives.iter().enumerate() {
                let config = prim.config.point_f32(&fk).unwrap();
                let b = fit.plain.model.needle_lengths(p, &config).unwrap();
                for j in (0..prim.needle_count()).filter(|&j| deforming[p][j]) {
                    let t = t[p][j].clamp(0.001, prim.max_length_m as f32 - 0.001);
                    psd.push((a[p][j] - t).abs());
                    plain.push((b[j] - t).abs());
                }
            }
        }
        let mean = |v: &[f32]| v.iter().sum::<f32>() / v.len() as f32;
        let (e_psd, e_plain) = (mean(&psd), mean(&plain));
        assert!(
            e_psd < 1e-3,
            "model over skinning: mean error {e_psd} m, plain {e_plain} m"
        );
        assert!(
            e_psd < 0.5 * e_plain,
            "over skinning {e_psd} m, plain {e_plain} m"
        );
        // Too few poses for the store's frames is an error.
        assert!(PoseSpaceModel::reconstruct(
            &store,
            &body,
            &sk,
            &train[..3],
            &params,
            &SurfaceParams::default()
        )
        .is_err());
    }
}
