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
//!   Popović 2007, [`skin_core::mesh::bone_heat_weights`]), what a capture pipeline without
//!   an artist would do. This is the baseline `needle_capture` reports as `lbs_*`.
//! * [`SkinnedShape::transfer`] — the performer's own weights interpolated barycentrically at
//!   each vertex's closest point on the rest-pose template. On the studio those are the very
//!   weights that generated the truth, so this variant knows more than any capture could.

use glam::DVec3;
use skin_core::math::DAffine3;
use skin_core::mesh::{
    bone_heat_weights, rest_bones, skin, HeatWeightsParams, MeshQuery, SkinWeights, TriMesh,
};
use skin_core::skeleton::Skeleton;
use skin_core::studio::Performer;

use crate::{Error, Result};

/// A rest-pose surface attached to a performer's skeleton by transferred LBS weights.
#[derive(Debug, Clone)]
pub struct SkinnedShape {
    rest: TriMesh,
    weights: SkinWeights,
}

impl SkinnedShape {
    /// Attaches `rest` (a closed surface in `skeleton`'s rest pose, world frame) by bone-heat
    /// weights. Joint `j`'s bone runs from its rest position to its end site, or else to the
    /// centroid of its children (the pelvis to the middle of hips and spine), or is a point
    /// for a leaf without end site.
    ///
    /// # Errors
    /// [`Error::Empty`] for a mesh without vertices; [`Error::NonFinite`] for NaN/∞
    /// vertices; the errors of [`bone_heat_weights`] (degenerate mesh).
    pub fn heat(skeleton: &Skeleton, rest: TriMesh) -> Result<Self> {
        check_rest(&rest)?;
        let bones = rest_bones(skeleton)?;
        let weights = bone_heat_weights(&rest, &bones, &HeatWeightsParams::default())?;
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
    use skin_core::studio::{procedural_performer, ProceduralBodyParams};

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
        let shape = SkinnedShape::heat(&p.skeleton, p.template.clone()).unwrap();
        let mut theta = p.skeleton.rest_pose();
        let elbow = p.skeleton.dof_index("l_elbow.flexion").unwrap();
        theta[elbow] = 1.2;
        let mut state = Default::default();
        let posed = p.pose(&theta, &mut state, 1.0 / 30.0).unwrap();
        let mesh = shape.pose(&p, &posed.world_from_joint).unwrap();
        let mut d: Vec<f64> = mesh
            .vertices
            .iter()
            .zip(&posed.lbs_vertices)
            .map(|(a, b)| a.distance(*b))
            .collect();
        d.sort_by(f64::total_cmp);
        // Different weights, same bones: most of the body agrees exactly, the elbow region
        // within a few centimetres.
        // Same bones, different weights: the body away from the elbow agrees exactly; the
        // smoother heat weights differ around the elbow and, lacking Pinocchio's visibility
        // test, where the hanging forearm lies close to the hip (a few per cent of vertices).
        let q = |f: f64| d[((d.len() - 1) as f64 * f) as usize];
        assert!(q(0.5) < 1e-9, "median {}", q(0.5));
        assert!(q(0.9) < 0.05, "90th percentile {}", q(0.9));
        assert!(
            d[d.len() - 1] > 1e-4,
            "heat weights are not the performer's own"
        );
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
            SkinnedShape::heat(&p.skeleton, nan),
            Err(Error::NonFinite { .. })
        ));
    }
}
