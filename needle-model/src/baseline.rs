//! The skinning baseline of the validation (Sand, McMillan and Popović 2003 §6 compare the
//! needle model with "the standard skinning approach"): a rest shape posed by linear blend
//! skinning.
//!
//! A skinning pipeline has no exact rest shape either; it must capture one. [`SkinnedShape`]
//! takes any rest-pose surface — in `needle_capture`, the needle model's own surface at the
//! rest pose, captured from the same silhouettes — attaches it to the performer's skeleton
//! with the performer's skinning weights transferred to it, and poses it by LBS. Comparing
//! the needle model against it isolates what the pose-dependent NRBF adds over skinning the
//! same captured shape. (The studio's own `lbs_vertices` skin the EXACT rest shape, an oracle
//! no capture method has; [`crate::truth::TestSet::lbs_errors`] reports it too.)
//!
//! Two ways to get its skinning weights:
//!
//! * [`SkinnedShape::heat`] — automatic bone-heat weights on the captured surface (Baran and
//!   Popović 2007 §4, [`skin_core::mesh::bone_heat_weights`]), what a capture pipeline
//!   without an artist would do. `needle_capture` reports it with the library's default
//!   weights, Pinocchio's visibility test on ([`HeatWeightsParams::default`]), as `lbs_*`,
//!   and with every vertex heated by its nearest bone whether or not the bone is visible from
//!   it ([`HeatWeightsParams::without_visibility`], the weights before the visibility test)
//!   as `lbs_no_visibility_*`.
//! * [`SkinnedShape::transfer`] — the performer's own weights interpolated barycentrically at
//!   each vertex's closest point on the rest-pose template. On the studio those are the very
//!   weights that generated the truth, so this variant knows more than any capture could.

use dynamic_shapes_studio::Performer;
use glam::DVec3;
use skin_core::math::DAffine3;
use skin_core::mesh::{
    bone_heat_weights, rest_bones, skin, HeatWeightsParams, MeshQuery, SkinWeights, TriMesh,
};
use skin_core::skeleton::Skeleton;

use crate::{Error, Result};

/// A rest-pose surface attached to a performer's skeleton by transferred LBS weights.
#[derive(Debug, Clone)]
pub struct SkinnedShape {
    rest: TriMesh,
    weights: SkinWeights,
}

impl SkinnedShape {
    /// Attaches `rest` (a closed surface in `skeleton`'s rest pose, world frame) by bone-heat
    /// weights computed with `params` (Baran and Popović 2007 §4; `HeatWeightsParams::default()`
    /// is Pinocchio's, with its visibility test). Joint `j`'s bone is its segments to each
    /// child joint, or to its end site for a leaf ([`rest_bones`]).
    ///
    /// # Errors
    /// [`Error::Empty`] for a mesh without vertices; [`Error::NonFinite`] for NaN/∞
    /// vertices; the errors of [`rest_bones`] and [`bone_heat_weights`] (degenerate mesh,
    /// invalid `params`).
    pub fn heat(skeleton: &Skeleton, rest: TriMesh, params: &HeatWeightsParams) -> Result<Self> {
        check_rest(&rest)?;
        let bones = rest_bones(skeleton)?;
        let weights = bone_heat_weights(&rest, &bones, params)?;
        Ok(Self { rest, weights })
    }

    /// Attaches `rest` (a closed surface in the performer's rest pose, world frame) to
    /// `performer` by transferring its weights (module docs).
    ///
    /// # Errors
    /// [`Error::Empty`] for a mesh without vertices; [`Error::NonFinite`] for NaN/∞
    /// vertices; the template's query errors (degenerate template).
    pub fn transfer(performer: &Performer, rest: TriMesh) -> Result<Self> {
        check_rest(&rest)?;
        let template = &performer.template;
        let query = MeshQuery::new(template)?;
        let closest = query.closest_points(&rest.vertices)?;
        let lists: Vec<Vec<(u32, f64)>> = closest
            .iter()
            .map(|c| {
                let face = template.faces[c.point.face as usize];
                let mut acc: Vec<(u32, f64)> = Vec::with_capacity(8);
                for (&v, &b) in face.iter().zip(&c.point.bary) {
                    for (bone, w) in performer.weights.influences(v as usize) {
                        match acc.iter_mut().find(|(j, _)| *j == bone) {
                            Some(e) => e.1 += b * w,
                            None => acc.push((bone, b * w)),
                        }
                    }
                }
                acc.retain(|&(_, w)| w > 0.0);
                acc
            })
            .collect();
        let weights = SkinWeights::from_lists(&lists, performer.weights.bone_count())?;
        Ok(Self { rest, weights })
    }

    /// The rest-pose surface.
    pub fn rest(&self) -> &TriMesh {
        &self.rest
    }

    /// The surface posed by LBS for joint frames `world_from_joint` (from forward kinematics
    /// of `performer`'s skeleton).
    ///
    /// # Errors
    /// [`Error::Core`] (size mismatch) if `world_from_joint` is not one frame per joint;
    /// non-finite transforms.
    pub fn pose(&self, performer: &Performer, world_from_joint: &[DAffine3]) -> Result<TriMesh> {
        let vertices: Vec<DVec3> = skin(
            &self.rest.vertices,
            &self.weights,
            &performer.world_from_rest(world_from_joint),
        )?;
        Ok(TriMesh {
            vertices,
            faces: self.rest.faces.clone(),
        })
    }
}

fn check_rest(rest: &TriMesh) -> Result<()> {
    if rest.vertices.is_empty() {
        return Err(Error::Empty {
            what: "rest shape vertices",
        });
    }
    if rest.vertices.iter().any(|v| !v.is_finite()) {
        return Err(Error::NonFinite {
            what: "rest shape vertices",
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use dynamic_shapes_studio::{procedural_performer, ProceduralBodyParams};

    #[test]
    fn the_template_itself_reproduces_the_performers_lbs() {
        let p = procedural_performer(&ProceduralBodyParams::default()).unwrap();
        let shape = SkinnedShape::transfer(&p, p.template.clone()).unwrap();
        let mut theta = p.skeleton.rest_pose();
        for (d, v) in theta.iter_mut().enumerate() {
            if p.skeleton.is_rotation(d) && p.skeleton.dof(d).limits.is_some() {
                *v = p.skeleton.dof(d).limits.unwrap().clamp(0.3);
            }
        }
        let mut state = Default::default();
        let posed = p.pose(&theta, &mut state, 1.0 / 30.0).unwrap();
        let mesh = shape.pose(&p, &posed.world_from_joint).unwrap();
        let worst = mesh
            .vertices
            .iter()
            .zip(&posed.lbs_vertices)
            .map(|(a, b)| a.distance(*b))
            .fold(0.0, f64::max);
        assert!(worst < 1e-9, "{worst}");
    }

    #[test]
    fn heat_weights_pose_the_template_close_to_its_own_lbs() {
        let p = procedural_performer(&ProceduralBodyParams::default()).unwrap();
        let mut theta = p.skeleton.rest_pose();
        let elbow = p.skeleton.dof_index("l_elbow.flexion").unwrap();
        theta[elbow] = 1.2;
        let mut state = Default::default();
        let posed = p.pose(&theta, &mut state, 1.0 / 30.0).unwrap();
        let mut p99 = vec![];
        for (name, params) in [
            ("visibility", HeatWeightsParams::default()),
            (
                "no visibility",
                HeatWeightsParams::default().without_visibility(),
            ),
        ] {
            let shape = SkinnedShape::heat(&p.skeleton, p.template.clone(), &params).unwrap();
            let mesh = shape.pose(&p, &posed.world_from_joint).unwrap();
            let mut d: Vec<f64> = mesh
                .vertices
                .iter()
                .zip(&posed.lbs_vertices)
                .map(|(a, b)| a.distance(*b))
                .collect();
            d.sort_by(f64::total_cmp);
            let q = |f: f64| d[((d.len() - 1) as f64 * f) as usize];
            // Same bones, different weights: the body away from the elbow agrees exactly; the
            // smoother heat weights differ around the elbow and where the hanging forearm lies
            // close to the hip (a few per cent of vertices).
            assert!(q(0.5) < 1e-9, "{name}: median {}", q(0.5));
            assert!(q(0.9) < 0.05, "{name}: 90th percentile {}", q(0.9));
            assert!(
                d[d.len() - 1] > 1e-4,
                "{name}: heat weights are not the performer's own"
            );
            p99.push(q(0.99));
        }
        // Pinocchio's visibility test keeps the hip from heating the forearm and the forearm
        // the hip: the tail shrinks (99th percentile 8.8 against 13.7 cm on this body).
        assert!(p99[0] < 0.8 * p99[1], "99th percentiles {p99:?}");
    }

    #[test]
    fn bad_rest_shapes_are_refused() {
        let p = procedural_performer(&ProceduralBodyParams::default()).unwrap();
        let empty = TriMesh {
            vertices: vec![],
            faces: vec![],
        };
        assert!(matches!(
            SkinnedShape::transfer(&p, empty),
            Err(Error::Empty { .. })
        ));
        let mut nan = p.template.clone();
        nan.vertices[0].x = f64::NAN;
        assert!(matches!(
            SkinnedShape::transfer(&p, nan.clone()),
            Err(Error::NonFinite { .. })
        ));
        assert!(matches!(
            SkinnedShape::heat(&p.skeleton, nan, &HeatWeightsParams::default()),
            Err(Error::NonFinite { .. })
        ));
    }
}
