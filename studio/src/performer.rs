//! The studio's performer: a rigged template (mesh in metres, skeleton, skin weights) plus a
//! known non-skinning deformation ([`DeformationModel`]). Posing gives both the linear blend
//! skinning surface (Vlasic thesis §2.5.1: `v' = Σⱼ wⱼ Mⱼ v`, the model every method assumes)
//! and the ground-truth surface (LBS plus the pose-driven shapes plus the dynamic flap), each
//! part recorded separately, so a method's error against truth can be split into what skinning
//! cannot explain, what is a function of pose, what is dynamic and what the method got wrong.

use super::deformation::{DeformationModel, DeformationParams, DeformationState};
use super::garment::Garment;
use super::texture::Material;
use super::wrinkles::{FineSurface, WrinkleModel};
use serde::{Deserialize, Serialize};
use skin_core::math::{DAffine3, DVec3};
use skin_core::mesh::{resize_rest, skin, SkinBinding, SkinWeights, TriMesh, UvLayout};
use skin_core::skeleton::{ForwardKinematics, Motion, Skeleton};
use skin_core::Result;

/// A rigged performer with known non-skinning deformation.
///
/// Invariants (checked by [`Performer::new`]): one weight row per template vertex and one
/// weight column per joint.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Performer {
    /// Name (e.g. `"makehuman"`, `"procedural"`).
    pub name: String,
    /// Template mesh at rest pose θ = 0, metres, world frame (+Y up, +Z forward, +X left):
    /// the body, then the garment's rest drape when there is one
    /// ([`Performer::garment_vertices`]) — the shape a scan at rest would show.
    pub template: TriMesh,
    /// The skeleton; θ = 0 is the template's pose.
    pub skeleton: Skeleton,
    /// Skin weights (bones = joints of `skeleton`), rows summing to 1; the garment's rows are
    /// [`Garment::weights`], the skinned garment a rigger would make.
    pub weights: SkinWeights,
    /// The non-skinning deformation.
    pub deformation: DeformationModel,
    /// Texture coordinates of the template, when known ([`Performer::with_body_uvs`]): the
    /// body's own (MakeHuman's atlas), then a cylindrical projection of the garment.
    pub uvs: Option<UvLayout>,
    /// The garment, when [`DeformationParams::garment`] is set.
    garment: Option<Garment>,
    /// Render-time wrinkles on a refined surface, when [`DeformationParams::wrinkles`] is set.
    wrinkles: Option<WrinkleModel>,
    /// Number of body vertices and faces (the template's first; a garment's follow).
    body_vertex_count: usize,
    body_face_count: usize,
    /// The LBS bind matrices (inverse rest frames at θ = 0).
    binding: SkinBinding,
}

/// One posed frame: skinned and true surfaces and the skeleton's state.
#[derive(Debug, Clone, PartialEq)]
pub struct PosedFrame {
    /// Joint frames `world_from_joint`, metres.
    pub world_from_joint: Vec<DAffine3>,
    /// World position of every joint origin, metres.
    pub joint_positions: Vec<DVec3>,
    /// Linear-blend-skinned template vertices, metres (what a skinning method can reach).
    pub lbs_vertices: Vec<DVec3>,
    /// Ground-truth vertices, metres: exactly
    /// `lbs_vertices + pose_displacement + dynamic_displacement`.
    pub true_vertices: Vec<DVec3>,
    /// The pose-driven part of the truth, per vertex, metres: the muscle and joint shapes of
    /// [`DeformationParams::pose`], a pure function of θ (what a pose-driven model such as
    /// Sand's needles can learn); zero vectors when that deformation is off.
    pub pose_displacement: Vec<DVec3>,
    /// The dynamic part of the truth, per vertex, metres: the hip flap's lag and the garment's
    /// departure from the skinned garment ([`Garment::step`] minus its LBS), which depend on
    /// the motion's history and no function of the current pose can predict; zero vectors
    /// when neither is on.
    pub dynamic_displacement: Vec<DVec3>,
}

impl PosedFrame {
    /// Largest distance between a true vertex and its LBS position, metres: the size of the
    /// non-skinning deformation in this frame.
    pub fn max_nonskinning_m(&self) -> f64 {
        self.lbs_vertices
            .iter()
            .zip(&self.true_vertices)
            .map(|(a, b)| a.distance(*b))
            .fold(0.0, f64::max)
    }
}

impl Performer {
    /// Builds a performer and precomputes its deformation.
    ///
    /// # Errors
    /// As [`SkinBinding::new`] (an invalid or empty template, weights without one row per
    /// vertex and one bone per joint); as [`DeformationModel::new`].
    pub fn new(
        name: impl Into<String>,
        template: TriMesh,
        skeleton: Skeleton,
        weights: SkinWeights,
        params: &DeformationParams,
    ) -> Result<Self> {
        let binding = SkinBinding::new(&template, &skeleton, &weights)?;
        let (body_vertex_count, body_face_count) = (template.vertex_count(), template.face_count());
        let deformation = DeformationModel::new(params, &skeleton, &template.vertices, &weights)?;
        let garment = params
            .garment
            .as_ref()
            .map(|g| Garment::new(g, &skeleton, &template, &weights))
            .transpose()?;
        let (template, weights) = match &garment {
            None => (template, weights),
            Some(g) => with_garment(template, weights, g)?,
        };
        let wrinkles = params
            .wrinkles
            .as_ref()
            .map(|w| {
                WrinkleModel::new(
                    w.clone(),
                    &skeleton,
                    &template,
                    &weights,
                    body_vertex_count..template.vertex_count(),
                )
            })
            .transpose()?;
        Ok(Performer {
            name: name.into(),
            template,
            skeleton,
            weights,
            deformation,
            uvs: None,
            garment,
            wrinkles,
            body_vertex_count,
            body_face_count,
            binding,
        })
    }

    /// This performer with other bone lengths: joint `j`'s offset from its parent scaled by
    /// `factors[j]` (one factor per joint; the root's offset is its rest position, so its
    /// factor is normally 1; end sites are kept). The body's rest mesh is re-rigged to the
    /// scaled skeleton by [`resize_rest`] (each rest vertex moves with its skin weights'
    /// blend of the joints' rest-frame moves: limbs keep their cross-sections), then the
    /// deformation, garment and wrinkles are rebuilt on the new body from `params` as
    /// [`Performer::new`] does (pass the parameters this performer was built with). The body's
    /// texture coordinates are kept. All-ones factors give this performer back.
    ///
    /// # Errors
    /// [`skin_core::Error::SizeMismatch`] unless there is one factor per joint;
    /// [`skin_core::Error::InvalidParam`] for a factor that is not finite and positive (naming
    /// the joint); as [`Performer::new`] and [`Performer::with_body_uvs`].
    pub fn with_bone_scales(&self, factors: &[f64], params: &DeformationParams) -> Result<Self> {
        skin_core::check::same_size(
            "bone scale factors vs skeleton joints",
            self.skeleton.joint_count(),
            factors.len(),
        )?;
        let mut joints = self.skeleton.joints().to_vec();
        for (joint, &f) in joints.iter_mut().zip(factors) {
            if !(f.is_finite() && f > 0.0) {
                return Err(skin_core::Error::InvalidParam {
                    name: "bone scale factor",
                    reason: format!(
                        "joint '{}': must be finite and positive, got {f}",
                        joint.name
                    ),
                });
            }
            joint.offset *= f;
        }
        let skeleton = Skeleton::new(joints)?;
        let (body, weights) = self.body()?;
        let vertices = resize_rest(&body.vertices, &weights, &self.skeleton, &skeleton)?;
        let body = TriMesh {
            vertices,
            faces: body.faces,
        };
        let resized = Performer::new(self.name.clone(), body, skeleton, weights, params)?;
        match &self.uvs {
            None => Ok(resized),
            Some(uvs) => {
                // The body's faces come first and use the first coordinates (`concat`).
                let faces = uvs.faces[..self.body_face_count.min(uvs.faces.len())].to_vec();
                let used = faces.iter().flatten().map(|&c| c as usize + 1).max();
                let coords = uvs.coords[..used.unwrap_or(0).min(uvs.coords.len())].to_vec();
                resized.with_body_uvs(UvLayout { coords, faces })
            }
        }
    }

    /// The body alone: the template's first vertices and faces (before a garment's) and their
    /// skin weights, the rest mesh a performer is built from ([`Performer::new`]).
    ///
    /// # Errors
    /// As [`SkinWeights::from_lists`] (not for a performer built by [`Performer::new`]).
    pub fn body(&self) -> Result<(TriMesh, SkinWeights)> {
        let mesh = TriMesh {
            vertices: self.template.vertices[..self.body_vertex_count].to_vec(),
            faces: self.template.faces[..self.body_face_count].to_vec(),
        };
        let lists: Vec<Vec<(u32, f64)>> = (0..self.body_vertex_count)
            .map(|v| self.weights.influences(v).collect())
            .collect();
        Ok((
            mesh,
            SkinWeights::from_lists(&lists, self.weights.bone_count())?,
        ))
    }

    /// The template's faces with `vertices` (e.g. [`PosedFrame::true_vertices`]): the posed
    /// surface as a mesh.
    pub fn mesh(&self, vertices: Vec<DVec3>) -> TriMesh {
        TriMesh {
            vertices,
            faces: self.template.faces.clone(),
        }
    }

    /// Number of template vertices.
    pub fn vertex_count(&self) -> usize {
        self.template.vertex_count()
    }

    /// This performer with the body's texture coordinates `body` (one entry per body face);
    /// a garment gets a cylindrical projection about its vertical axis
    /// ([`UvLayout::cylindrical`]) after them, so [`Performer::uvs`] covers the template.
    ///
    /// # Errors
    /// As [`UvLayout::validate_for_faces`] with the body's faces; as [`UvLayout::cylindrical`].
    pub fn with_body_uvs(mut self, body: UvLayout) -> Result<Self> {
        body.validate_for_faces(self.body_face_count)?;
        self.uvs = Some(match &self.garment {
            None => body,
            Some(g) => {
                let rest = g.rest_mesh();
                let centre = rest.bounding_box()?.center();
                body.concat(&UvLayout::cylindrical(rest, centre)?)
            }
        });
        Ok(self)
    }

    /// The template vertices of the garment (empty without one): they follow the body's.
    pub fn garment_vertices(&self) -> std::ops::Range<usize> {
        self.body_vertex_count..self.vertex_count()
    }

    /// The render-time wrinkle model, when [`DeformationParams::wrinkles`] is set.
    pub fn wrinkles(&self) -> Option<&WrinkleModel> {
        self.wrinkles.as_ref()
    }

    /// The material of every template face (skin; the garment's faces are
    /// [`Material::Garment`]): what [`crate::shading::Albedo::Textured`] needs with
    /// the template's rest positions.
    pub fn face_materials(&self) -> Vec<Material> {
        (0..self.template.face_count())
            .map(|f| {
                if f < self.body_face_count {
                    Material::Skin
                } else {
                    Material::Garment
                }
            })
            .collect()
    }

    /// The garment, when [`DeformationParams::garment`] is set.
    pub fn garment(&self) -> Option<&Garment> {
        self.garment.as_ref()
    }

    /// The surface the cameras see at pose θ, refined and wrinkled at render time
    /// ([`WrinkleModel::apply`] on `posed.true_vertices`), or `None` when the performer has no
    /// wrinkles (the template's faces on the true vertices are then the surface). The
    /// wrinkle displacement it records is the fourth part of the truth, after
    /// [`PosedFrame`]'s skinned, pose-driven and dynamic parts.
    ///
    /// # Errors
    /// As [`WrinkleModel::apply`] (a θ or vertex count of another performer).
    pub fn fine_surface(&self, theta: &[f64], posed: &PosedFrame) -> Result<Option<FineSurface>> {
        self.wrinkles
            .as_ref()
            .map(|w| w.apply(theta, &posed.true_vertices))
            .transpose()
    }

    /// The skinning transforms `world_from_rest[j] = world_from_joint[j] ·
    /// joint_from_world_rest[j]` that map rest-pose (template) coordinates to the pose whose
    /// joint frames are `world_from_joint` — what [`skin_core::mesh::skin`] takes to pose any
    /// surface attached to this performer's rest pose. Extra or missing frames are ignored
    /// (the result has `min(len, joint count)` entries).
    pub fn world_from_rest(&self, world_from_joint: &[DAffine3]) -> Vec<DAffine3> {
        self.binding.world_from_rest(world_from_joint)
    }

    /// Poses the performer at θ: forward kinematics, LBS, then the non-skinning deformation
    /// (the pose-driven shapes of [`DeformationParams::pose`], the hip flap's dynamics, the
    /// garment's simulation against the true body).
    /// `state` carries the flap's dynamics from frame to frame (start with
    /// `DeformationState::default()`); `dt_s` is the time since the previous call (ignored on
    /// the first).
    ///
    /// # Errors
    /// As [`Skeleton::check_pose`]; [`skin_core::Error::InvalidParam`] for a bad `dt_s` after the
    /// first frame; [`skin_core::Error::SizeMismatch`] for a state of another performer; as
    /// [`Garment::step`].
    pub fn pose(
        &self,
        theta: &[f64],
        state: &mut DeformationState,
        dt_s: f64,
    ) -> Result<PosedFrame> {
        let mut fk = ForwardKinematics::new(&self.skeleton);
        self.skeleton.forward_kinematics_into(theta, &mut fk)?;
        let world_from_joint = fk.world_from_joint().to_vec();
        let world_from_rest = self.world_from_rest(&world_from_joint);
        let lbs_vertices = skin(&self.template.vertices, &self.weights, &world_from_rest)?;
        let pose_displacement =
            self.deformation
                .pose_displacement(theta, &world_from_rest, &self.weights);
        let mut dynamic_displacement = vec![DVec3::ZERO; lbs_vertices.len()];
        self.deformation
            .add_flap(&lbs_vertices, state, dt_s, &mut dynamic_displacement)?;
        if let Some(g) = &self.garment {
            // The garment collides with the true body (muscles and flap included).
            let b = self.body_vertex_count;
            let body: Vec<DVec3> = (0..b)
                .map(|v| lbs_vertices[v] + pose_displacement[v] + dynamic_displacement[v])
                .collect();
            let simulated = g.step(
                &mut state.garment,
                &lbs_vertices[b..],
                &world_from_joint,
                &body,
                dt_s,
            )?;
            for ((d, x), l) in dynamic_displacement[b..]
                .iter_mut()
                .zip(&simulated)
                .zip(&lbs_vertices[b..])
            {
                *d = *x - *l;
            }
        }
        let true_vertices = lbs_vertices
            .iter()
            .zip(&pose_displacement)
            .zip(&dynamic_displacement)
            .map(|((l, p), d)| *l + *p + *d)
            .collect();
        Ok(PosedFrame {
            joint_positions: fk.joint_positions(),
            world_from_joint,
            lbs_vertices,
            true_vertices,
            pose_displacement,
            dynamic_displacement,
        })
    }

    /// Plays a whole motion from a fresh [`DeformationState`], calling `each(frame_index,
    /// &frame)` in order (frames are not kept, so long motions need no memory).
    ///
    /// # Errors
    /// As [`Motion::check_for`] and [`Performer::pose`]; any error `each` returns.
    pub fn perform(
        &self,
        motion: &Motion,
        mut each: impl FnMut(usize, &PosedFrame) -> Result<()>,
    ) -> Result<()> {
        motion.check_for(&self.skeleton)?;
        let mut state = DeformationState::default();
        for k in 0..motion.frame_count() {
            let frame = self.pose(motion.frame(k), &mut state, motion.frame_time_s)?;
            each(k, &frame)?;
        }
        Ok(())
    }

    /// Largest distance between truth and LBS over a motion, metres (the studio's
    /// `max_nonskinning_mm` / 1000).
    ///
    /// # Errors
    /// As [`Performer::perform`].
    pub fn max_nonskinning_m(&self, motion: &Motion) -> Result<f64> {
        let mut worst: f64 = 0.0;
        self.perform(motion, |_, f| {
            worst = worst.max(f.max_nonskinning_m());
            Ok(())
        })?;
        Ok(worst)
    }
}

/// The template and skin weights of the body followed by the garment's rest drape and weights.
fn with_garment(
    body: TriMesh,
    weights: SkinWeights,
    garment: &Garment,
) -> Result<(TriMesh, SkinWeights)> {
    let n = body.vertex_count() as u32;
    let rest = garment.rest_mesh();
    let mut mesh = body;
    mesh.vertices.extend_from_slice(&rest.vertices);
    mesh.faces
        .extend(rest.faces.iter().map(|f| f.map(|c| c + n)));
    let lists: Vec<Vec<(u32, f64)>> = (0..weights.vertex_count())
        .map(|v| weights.influences(v).collect())
        .chain((0..garment.vertex_count()).map(|v| garment.weights().influences(v).collect()))
        .collect();
    let weights = SkinWeights::from_lists(&lists, weights.bone_count())?;
    Ok((mesh, weights))
}

#[cfg(test)]
mod tests {
    use super::super::tests::{data, makehuman};
    use super::super::{makehuman_performer, GarmentParams, SkirtParams};
    use super::*;

    fn ones(p: &Performer) -> Vec<f64> {
        vec![1.0; p.skeleton.joint_count()]
    }

    #[test]
    fn unit_bone_scales_give_the_same_performer() {
        let p = makehuman();
        let q = p
            .with_bone_scales(&ones(p), &DeformationParams::default())
            .unwrap();
        // The same joints (Skeleton::new renormalises the DOF axes: equal to rounding).
        for (a, b) in q.skeleton.joints().iter().zip(p.skeleton.joints()) {
            assert!(a.name == b.name && a.parent == b.parent && a.offset == b.offset);
            assert!(a.end_site == b.end_site && a.dofs.len() == b.dofs.len());
            assert!(a
                .dofs
                .iter()
                .zip(&b.dofs)
                .all(|(x, y)| x.axis.distance(y.axis) < 1e-12 && x.limits == y.limits));
        }
        assert_eq!(q.template.faces, p.template.faces);
        // The same texture coordinate at every face corner.
        let corners = |p: &Performer| -> Vec<_> {
            let uvs = p.uvs.as_ref().unwrap();
            uvs.faces
                .iter()
                .flatten()
                .map(|&c| uvs.coords[c as usize])
                .collect()
        };
        assert_eq!(corners(&q), corners(p));
        assert!(q
            .template
            .vertices
            .iter()
            .zip(&p.template.vertices)
            .all(|(a, b)| a.distance(*b) < 1e-12));
        for v in 0..p.vertex_count() {
            let (a, b): (Vec<_>, Vec<_>) = (
                p.weights.influences(v).collect(),
                q.weights.influences(v).collect(),
            );
            assert_eq!(a.len(), b.len());
            assert!(a
                .iter()
                .zip(&b)
                .all(|(x, y)| x.0 == y.0 && (x.1 - y.1).abs() < 1e-12));
        }
    }

    #[test]
    fn a_longer_forearm_moves_the_hand_by_the_offset_change() {
        let p = makehuman();
        let sk = &p.skeleton;
        let wrist = sk.joint_index("l_wrist").unwrap();
        let mut factors = ones(p);
        factors[wrist] = 1.1;
        let q = p
            .with_bone_scales(&factors, &DeformationParams::default())
            .unwrap();
        let change = sk.joints()[wrist].offset * 0.1;
        assert!(change.length() > 0.02, "forearm {change}");
        // The wrist's subtree: the wrist and its descendants.
        let in_hand = |j: u32| {
            let mut k = Some(j as usize);
            while let Some(i) = k {
                if i == wrist {
                    return true;
                }
                k = sk.joints()[i].parent;
            }
            false
        };
        let (mut hand, mut rest) = (0, 0);
        for v in 0..p.vertex_count() {
            let moved = q.template.vertices[v] - p.template.vertices[v];
            let carried: Vec<bool> = p.weights.influences(v).map(|(j, _)| in_hand(j)).collect();
            if carried.iter().all(|&h| h) {
                hand += 1;
                assert!((moved - change).length() < 1e-9, "hand vertex {v}: {moved}");
            } else if carried.iter().all(|&h| !h) {
                rest += 1;
                assert!(
                    moved.length() < 1e-9,
                    "vertex {v} off the hand moved {moved}"
                );
            }
        }
        assert!(
            hand > 100 && rest > 1000,
            "{hand} hand, {rest} other vertices"
        );
        // The new skeleton's wrist sits 10 % further from the elbow, and the rest pose still
        // skins to the new template.
        assert!(
            (q.skeleton.joints()[wrist].offset - sk.joints()[wrist].offset * 1.1).length() < 1e-12
        );
        let posed = q
            .pose(
                &q.skeleton.rest_pose(),
                &mut DeformationState::default(),
                0.0,
            )
            .unwrap();
        assert!(posed
            .lbs_vertices
            .iter()
            .zip(&q.template.vertices)
            .all(|(a, b)| a.distance(*b) < 1e-9));
    }

    #[test]
    fn bad_bone_scales_are_refused() {
        let p = makehuman();
        let params = DeformationParams::default();
        let e = p.with_bone_scales(&[1.0; 3], &params).unwrap_err();
        assert!(matches!(e, skin_core::Error::SizeMismatch { .. }), "{e}");
        for bad in [f64::NAN, 0.0, -1.0, f64::INFINITY] {
            let mut f = ones(p);
            f[5] = bad;
            let e = p.with_bone_scales(&f, &params).unwrap_err();
            assert!(
                matches!(&e, skin_core::Error::InvalidParam { name: "bone scale factor", reason } if reason.contains(&p.skeleton.joints()[5].name)),
                "{bad}: {e}"
            );
        }
    }

    #[test]
    fn the_skirted_performer_takes_other_bone_lengths() {
        let params = DeformationParams::default()
            .with_flap(None)
            .with_garment(Some(GarmentParams::Skirt(SkirtParams::default())));
        let p = makehuman_performer(data("makehuman"), &params).unwrap();
        let factors: Vec<f64> = (0..p.skeleton.joint_count())
            .map(|j| {
                if j == 0 {
                    1.0
                } else {
                    0.9 + 0.2 * ((j * 7) % 10) as f64 / 10.0
                }
            })
            .collect();
        let q = p.with_bone_scales(&factors, &params).unwrap();
        assert!(q.garment().is_some());
        assert_eq!(q.body().unwrap().0.faces, p.body().unwrap().0.faces);
        q.uvs.as_ref().unwrap().validate(&q.template).unwrap();
        let posed = q
            .pose(
                &q.skeleton.rest_pose(),
                &mut DeformationState::default(),
                0.0,
            )
            .unwrap();
        assert!(posed.true_vertices.iter().all(|v| v.is_finite()));
        // The body is taller or shorter: the head moved.
        let head = q.skeleton.joint_index("head").unwrap();
        let rest = |s: &Skeleton| {
            s.forward_kinematics(&s.rest_pose())
                .unwrap()
                .joint_positions()[head]
        };
        assert!(rest(&q.skeleton).distance(rest(&p.skeleton)) > 0.005);
    }
}
