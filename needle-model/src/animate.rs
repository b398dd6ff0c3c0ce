//! Animation of the reconstructed body for a new pose (Sand, McMillan and Popović 2003 §5.4;
//! thesis §5.4).
//!
//! The method is documented on [`animate`]; the module is private and
//! everything public is re-exported at the crate root.

use serde::{Deserialize, Serialize};
use skin_core::math::DVec3;
use skin_core::skeleton::{ForwardKinematics, Skeleton};

use crate::primitive::{NeedleBody, Primitive};
use crate::reconstruct::NeedleModel;
use crate::{Context, Error, Result, ResultExt};

/// One posed primitive: its needles in world space.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AnimatedPrimitive {
    /// Needles per ring (copied from the [`crate::Primitive`]).
    pub radial: usize,
    /// Rings (copied from the [`crate::Primitive`]).
    pub axial: usize,
    /// Axis start, world frame, m.
    pub axis_start: DVec3,
    /// Axis end, world frame, m.
    pub axis_end: DVec3,
    /// Needle origins, world frame, m (ring-major, `radial · axial` entries).
    pub origins: Vec<DVec3>,
    /// Unit needle directions, world frame (perpendicular to the axis).
    pub directions: Vec<DVec3>,
    /// Needle endpoints (surface points), world frame, m: origin + direction · length.
    pub endpoints: Vec<DVec3>,
    /// Predicted needle lengths, m (§5.4).
    pub lengths: Vec<f64>,
}

/// The whole body posed at one θ (§5.4).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AnimatedBody {
    /// One entry per primitive, in body order.
    pub primitives: Vec<AnimatedPrimitive>,
}

impl AnimatedBody {
    /// Total number of needles.
    pub fn needle_count(&self) -> usize {
        self.primitives.iter().map(|p| p.endpoints.len()).sum()
    }
}

/// Poses `body` at θ and evaluates `model` for every primitive (Sand 2003 §5.4).
///
/// Animation of the reconstructed body for a new pose (Sand, McMillan and Popović 2003 §5.4;
/// thesis §5.4).
///
/// "To animate the body we evaluate the reconstructed deformable primitives for the new
/// skeletal configuration": for a pose θ the skeleton's forward kinematics gives every bone
/// frame; each primitive's configuration point (marker coordinates in its carrier frame, §3.3)
/// is evaluated by its NRBF ([`NeedleModel::needle_lengths`], §5.1) and every needle endpoint is
/// `origin + direction · length` in the posed carrier frame. The result, an [`AnimatedBody`],
/// is the input of the surface builders ([`crate::primitive_meshes`], [`crate::union_mesh`]).
///
/// # Errors
/// [`Error::Core`] for a pose of the wrong length or with NaN/∞ (from the skeleton's pose
/// check); [`Error::SizeMismatch`] if `model` and `body` disagree on the number of primitives or
/// a primitive's needle count or configuration dimension; [`Error::NonFinite`] if a predicted
/// length is not finite.
pub fn animate(
    body: &NeedleBody,
    model: &NeedleModel,
    skeleton: &Skeleton,
    theta: &[f64],
) -> Result<AnimatedBody> {
    if model.primitives.len() != body.primitives.len() {
        return Err(Error::SizeMismatch {
            what: "model primitives vs body primitives",
            expected: body.primitives.len(),
            got: model.primitives.len(),
        });
    }
    let fk = skeleton.forward_kinematics(theta)?;
    let mut primitives = Vec::with_capacity(body.primitives.len());
    for (p, prim) in body.primitives.iter().enumerate() {
        primitives.push(animate_primitive(prim, p, model, &fk).at(Context::Primitive(p))?);
    }
    Ok(AnimatedBody { primitives })
}

/// Primitive `p` of the body posed by `fk` (the body of [`animate`]'s loop).
fn animate_primitive(
    prim: &Primitive,
    p: usize,
    model: &NeedleModel,
    fk: &ForwardKinematics,
) -> Result<AnimatedPrimitive> {
    let frame = fk
        .world_from_joint()
        .get(prim.carrier)
        .ok_or(Error::SizeMismatch {
            what: "skeleton joints (primitive carrier)",
            expected: prim.carrier + 1,
            got: fk.world_from_joint().len(),
        })?;
    let lengths32 = model.needle_lengths(p, &prim.config.point_f32(fk)?)?;
    if lengths32.len() != prim.needle_count() {
        return Err(Error::SizeMismatch {
            what: "model needle lengths vs primitive needles",
            expected: prim.needle_count(),
            got: lengths32.len(),
        });
    }
    if lengths32.iter().any(|l| !l.is_finite()) {
        return Err(Error::NonFinite {
            what: "predicted needle length",
        });
    }
    let lengths: Vec<f64> = lengths32.iter().map(|&l| f64::from(l)).collect();
    let mut origins = Vec::with_capacity(lengths.len());
    let mut endpoints = Vec::with_capacity(lengths.len());
    let mut directions = Vec::with_capacity(lengths.len());
    for (j, &l) in lengths.iter().enumerate() {
        let (o, d) = prim.needle_world(frame, j);
        origins.push(o);
        endpoints.push(o + d * l);
        directions.push(d);
    }
    Ok(AnimatedPrimitive {
        radial: prim.radial,
        axial: prim.axial,
        axis_start: frame.transform_point3(prim.axis_start),
        axis_end: frame.transform_point3(prim.axis_end),
        origins,
        directions,
        endpoints,
        lengths,
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::primitive::BodyLayout;
    use crate::reconstruct::NeedleModel;
    use crate::store::ObservationStore;
    use crate::ReconstructionParams;
    use skin_core::skeleton::{human_skeleton, HumanParams};

    /// A sparse Table 3.1 body and a static model whose every needle has length `len` m
    /// (observations of one constant length at a few rest-pose samples).
    pub(crate) fn constant_model(len: f32) -> (Skeleton, NeedleBody, NeedleModel) {
        let sk = human_skeleton(&HumanParams::default()).unwrap();
        let body = NeedleBody::new(&sk, &BodyLayout::table_3_1().with_density(0.2)).unwrap();
        let mut store = ObservationStore::new(&body.store_shapes()).unwrap();
        let mut theta = sk.rest_pose();
        for s in 0..4 {
            theta[sk.dof_count() - 1] = 0.05 * s as f64;
            let fk = sk.forward_kinematics(&theta).unwrap();
            for (p, prim) in body.primitives.iter().enumerate() {
                let x = prim.config.point(&fk).unwrap();
                let obs: Vec<(u16, f32)> =
                    (0..prim.needle_count()).map(|j| (j as u16, len)).collect();
                store.push_sample(p, &x, &obs).unwrap();
            }
        }
        let params = ReconstructionParams::default()
            .with_prototype_count_n(2)
            .with_f_near(1.0);
        let rec = NeedleModel::reconstruct(&store, &body, &params).unwrap();
        (sk, body, rec.model)
    }

    #[test]
    fn endpoints_lie_at_predicted_length_along_needles() {
        let (sk, body, model) = constant_model(0.05);
        let mut theta = sk.rest_pose();
        theta[0] = 0.3;
        theta[4] = 0.7;
        let a = animate(&body, &model, &sk, &theta).unwrap();
        assert_eq!(a.needle_count(), body.needle_count());
        let fk = sk.forward_kinematics(&theta).unwrap();
        for (prim, ap) in body.primitives.iter().zip(&a.primitives) {
            let frame = fk.world_from_joint()[prim.carrier];
            for j in 0..prim.needle_count() {
                assert!((ap.lengths[j] - 0.05).abs() < 1e-3, "{}", ap.lengths[j]);
                let (o, d) = prim.needle_world(&frame, j);
                assert!(ap.origins[j].distance(o) < 1e-12);
                assert!((ap.endpoints[j] - (o + d * ap.lengths[j])).length() < 1e-12);
                // The endpoint is at the needle length from the posed axis.
                assert!((ap.endpoints[j].distance(ap.origins[j]) - ap.lengths[j]).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn bad_poses_and_models_are_rejected() {
        let (sk, body, model) = constant_model(0.05);
        let mut theta = sk.rest_pose();
        theta[2] = f64::NAN;
        assert!(matches!(
            animate(&body, &model, &sk, &theta),
            Err(Error::Core(_))
        ));
        assert!(matches!(
            animate(&body, &model, &sk, &theta[..3]),
            Err(Error::Core(_))
        ));
        let mut short = model.clone();
        short.primitives.pop();
        assert!(matches!(
            animate(&body, &short, &sk, &sk.rest_pose()),
            Err(Error::SizeMismatch { .. })
        ));
    }
}
