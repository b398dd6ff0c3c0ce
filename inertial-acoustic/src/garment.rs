//! Validation equipment: the suit on the garment over the studio performer's skin.
//!
//! Every board and source is attached to a point of a triangle of the performer's rest body
//! surface (barycentric weights fixed at rest), so it moves with the studio's pose-driven
//! deformation — linear blend skinning plus the muscle and joint shapes of
//! [`dynamic_shapes_studio::PoseDeformParams`] — rather than rigidly with its bone: the
//! skin-motion error real suits have (§4.5). A board is a rigid plate on a patch of skin: its
//! axes turn with the best-fitting rotation (Kabsch) of the skin vertices within
//! [`PATCH_RADIUS_M`] of its point (at least the [`MIN_PATCH`] nearest), from rest to the
//! pose.
//!
//! Only the attachment triangles are posed: they form a small performer of their own with
//! the full performer's skeleton, skin weights and pose-driven deformation, which is exact
//! because the studio's skinning and pose shapes act on each vertex through its rest
//! position and weights alone (checked against the full performer when built). The hip flap
//! (dynamic, a loose skirt's stand-in) is left out: the suit is a tight garment.

use crate::suit::{SensorBoard, Suit, UltrasonicSource};
use crate::{Error, Result};
use dynamic_shapes_studio::{DeformationParams, DeformationState, Performer};
use skin_core::math::{fit_similarity, Alignment, DQuat, DVec3};
use skin_core::mesh::{closest_point_on_triangle, SkinWeights, TriMesh};
use skin_core::skeleton::{AttachedPoint, Skeleton};

/// Smallest mean skin weight on the carrying bone for a triangle to take a board or source.
const MIN_BONE_WEIGHT: f64 = 0.5;

/// Radius of the skin patch under a board or source, metres: its axes turn with the skin
/// vertices within this distance of its point (at least [`MIN_PATCH`] of them, the nearest).
pub const PATCH_RADIUS_M: f64 = 0.03;

/// Fewest skin vertices in a patch.
pub const MIN_PATCH: usize = 8;

/// One attachment: a point of a posed triangle and a rotation riding on its skin patch.
#[derive(Debug, Clone)]
struct Attachment {
    /// First vertex of its triangle in the small performer (three consecutive vertices,
    /// followed by the rest of the patch).
    first: usize,
    /// Number of patch vertices (the triangle's three included).
    patch: usize,
    /// Barycentric weights.
    bary: [f64; 3],
    /// The item's world rotation at rest.
    world_rest: DQuat,
}

/// The world placement of every board and source at one pose.
#[derive(Debug, Clone, PartialEq)]
pub struct GarmentPose {
    /// Board positions, world, metres.
    pub board_positions: Vec<DVec3>,
    /// Board orientations (`world_from_sensor`).
    pub board_rotations: Vec<DQuat>,
    /// Source positions, world, metres.
    pub source_positions: Vec<DVec3>,
    /// Source emission axes, world, unit.
    pub source_normals: Vec<DVec3>,
}

/// A suit attached to a performer's deforming surface.
#[derive(Debug, Clone)]
pub struct GarmentSurface {
    patches: Performer,
    boards: Vec<Attachment>,
    sources: Vec<Attachment>,
    /// Source emission axes in their joint frames.
    source_normals: Vec<DVec3>,
    /// The template vertex each patch vertex copies.
    origin: Vec<usize>,
}

/// Skin weight of `joint` at vertex `v`.
fn weight_on(weights: &SkinWeights, v: usize, joint: usize) -> f64 {
    weights
        .influences(v)
        .filter(|q| q.0 as usize == joint)
        .map(|q| q.1)
        .sum()
}

impl GarmentSurface {
    /// Snaps every board and source of `suit` to the closest point of the rest body surface
    /// of `performer` among the triangles whose vertices' mean skin weight on the item's bone
    /// is at least ½, and attaches it there. Returns the snapped suit (positions moved onto
    /// the surface, orientations and normals unchanged) and the attachment. `deformation`
    /// must be the pose-driven deformation the performer was built with (the flap, garment
    /// and wrinkles are ignored).
    ///
    /// # Errors
    /// [`Error::InvalidParam`] for a suit on another skeleton or a bone without skinned body
    /// triangles, or if `deformation` does not reproduce the performer's pose-driven surface
    /// (checked at a test pose to 1 µm); errors of the skeleton and the performer.
    pub fn new(
        performer: &Performer,
        deformation: &DeformationParams,
        suit: &Suit,
    ) -> Result<(Self, Suit)> {
        let skeleton = &performer.skeleton;
        let rest = skeleton.forward_kinematics(&skeleton.rest_pose())?;
        let body = performer.garment_vertices().start;
        let template = &performer.template;
        let weights = &performer.weights;
        for j in suit
            .boards()
            .iter()
            .map(|b| b.joint)
            .chain(suit.sources().iter().map(|s| s.joint))
        {
            if j >= skeleton.joints().len() {
                return Err(Error::InvalidParam {
                    name: "suit",
                    reason: format!("joint {j} is not in the performer's skeleton"),
                });
            }
        }
        let mut vertices = Vec::new();
        let mut origin = Vec::new();
        let mut lists = Vec::new();
        let mut snap = |joint: usize, offset: DVec3| -> Result<(usize, usize, [f64; 3], DVec3)> {
            let target = rest.point(&AttachedPoint { joint, offset })?;
            let mut best: Option<(f64, usize, [f64; 3], DVec3)> = None;
            for (f, face) in template.faces.iter().enumerate() {
                let idx = face.map(|c| c as usize);
                if idx.iter().any(|&v| v >= body) {
                    continue;
                }
                let w = idx
                    .iter()
                    .map(|&v| weight_on(weights, v, joint))
                    .sum::<f64>()
                    / 3.0;
                if w < MIN_BONE_WEIGHT {
                    continue;
                }
                let tri = idx.map(|v| template.vertices[v]);
                let cp = closest_point_on_triangle(target, tri);
                if best.is_none_or(|b| cp.distance < b.0) {
                    best = Some((cp.distance, f, cp.bary, cp.position));
                }
            }
            let Some((_, f, bary, position)) = best else {
                return Err(Error::InvalidParam {
                    name: "suit",
                    reason: format!(
                        "bone '{}' carries no skinned body triangle",
                        skeleton.joints()[joint].name
                    ),
                });
            };
            let idx = template.faces[f].map(|c| c as usize);
            let first = vertices.len();
            let mut near: Vec<(f64, usize)> = (0..body)
                .filter(|v| {
                    !idx.contains(v) && weight_on(weights, *v, joint) >= 0.5 * MIN_BONE_WEIGHT
                })
                .map(|v| (template.vertices[v].distance(position), v))
                .collect();
            near.sort_by(|a, b| a.0.total_cmp(&b.0));
            let k = near
                .iter()
                .take_while(|(d, _)| *d <= PATCH_RADIUS_M)
                .count()
                .max(MIN_PATCH - 3);
            let near = near.into_iter().take(k).map(|(_, v)| v);
            for v in idx.into_iter().chain(near) {
                vertices.push(template.vertices[v]);
                origin.push(v);
                lists.push(weights.influences(v).collect::<Vec<_>>());
            }
            Ok((first, vertices.len() - first, bary, position))
        };
        let world_rest = rest.world_from_joint();
        // One attachment: the item's patch, and its offset in its joint frame on the skin.
        let mut attach = |joint: usize, offset: DVec3, rotation: DQuat| -> Result<_> {
            let (first, patch, bary, position) = snap(joint, offset)?;
            let w = world_rest[joint];
            let attachment = Attachment {
                first,
                patch,
                bary,
                world_rest: DQuat::from_mat3(&w.matrix3) * rotation,
            };
            Ok((attachment, w.inverse().transform_point3(position)))
        };
        let mut boards = Vec::new();
        let mut snapped_boards = Vec::new();
        for b in suit.boards() {
            let (a, offset) = attach(b.joint, b.offset, b.joint_from_sensor)?;
            boards.push(a);
            snapped_boards.push(SensorBoard {
                offset,
                ..b.clone()
            });
        }
        let mut sources = Vec::new();
        let mut snapped_sources = Vec::new();
        let mut source_normals = Vec::new();
        for s in suit.sources() {
            let (a, offset) = attach(s.joint, s.offset, DQuat::IDENTITY)?;
            source_normals.push(s.normal);
            sources.push(a);
            snapped_sources.push(UltrasonicSource {
                offset,
                ..s.clone()
            });
        }
        let faces = boards
            .iter()
            .chain(&sources)
            .map(|a| {
                let f = a.first as u32;
                [f, f + 1, f + 2]
            })
            .collect();
        let weights = SkinWeights::from_lists(&lists, performer.weights.bone_count())?;
        let params = DeformationParams {
            flap: None,
            garment: None,
            wrinkles: None,
            ..deformation.clone()
        };
        let patches = Performer::new(
            format!("{} suit patches", performer.name),
            TriMesh { vertices, faces },
            skeleton.clone(),
            weights,
            &params,
        )?;
        let surface = GarmentSurface {
            patches,
            boards,
            sources,
            source_normals,
            origin,
        };
        surface.check_against(performer)?;
        let snapped = Suit::new(skeleton, snapped_boards, snapped_sources)?;
        Ok((surface, snapped))
    }

    /// Compares the patches with the full performer's LBS + pose-driven surface at a test pose.
    fn check_against(&self, performer: &Performer) -> Result<()> {
        let skeleton = &performer.skeleton;
        let theta: Vec<f64> = (0..skeleton.dof_count())
            .map(|d| {
                if skeleton.is_rotation(d) {
                    0.2 * ((d % 5) as f64 - 2.0)
                } else {
                    0.0
                }
            })
            .collect();
        let full = performer.pose(&theta, &mut DeformationState::default(), 0.0)?;
        let part = self
            .patches
            .pose(&theta, &mut DeformationState::default(), 0.0)?;
        let worst = self
            .origin
            .iter()
            .zip(&part.true_vertices)
            .map(|(&v, x)| (full.lbs_vertices[v] + full.pose_displacement[v]).distance(*x))
            .fold(0.0, f64::max);
        if worst > 1e-6 {
            return Err(Error::InvalidParam {
                name: "deformation",
                reason: format!(
                    "does not reproduce the performer's pose-driven surface ({:.3} mm off)",
                    1e3 * worst
                ),
            });
        }
        Ok(())
    }

    /// The placement of every board and source at pose θ.
    ///
    /// # Errors
    /// As [`Performer::pose`] (a θ of another skeleton); as [`fit_similarity`] for a skin
    /// patch degenerated into a line.
    pub fn pose(&self, theta: &[f64]) -> Result<GarmentPose> {
        let posed = self
            .patches
            .pose(theta, &mut DeformationState::default(), 0.0)?;
        let v = &posed.true_vertices;
        let rest = &self.patches.template.vertices;
        let place = |a: &Attachment| -> Result<(DVec3, DQuat)> {
            let (p0, p1, p2) = (v[a.first], v[a.first + 1], v[a.first + 2]);
            let position = p0 * a.bary[0] + p1 * a.bary[1] + p2 * a.bary[2];
            let range = a.first..a.first + a.patch;
            let turn = fit_similarity(&rest[range.clone()], &v[range], None, Alignment::Rigid)?;
            Ok((position, turn.rotation * a.world_rest))
        };
        let (mut board_positions, mut board_rotations) = (Vec::new(), Vec::new());
        for a in &self.boards {
            let (p, q) = place(a)?;
            board_positions.push(p);
            board_rotations.push(q);
        }
        let mut source_positions = Vec::with_capacity(self.sources.len());
        let mut source_normals = Vec::with_capacity(self.sources.len());
        for (a, n) in self.sources.iter().zip(&self.source_normals) {
            let (p, q) = place(a)?;
            source_positions.push(p);
            source_normals.push(q * *n);
        }
        Ok(GarmentPose {
            board_positions,
            board_rotations,
            source_positions,
            source_normals,
        })
    }

    /// The skeleton the surface is rigged to.
    pub fn skeleton(&self) -> &Skeleton {
        &self.patches.skeleton
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dynamic_shapes_studio::makehuman_performer;

    fn performer() -> (Performer, DeformationParams) {
        let deformation = DeformationParams::default().with_flap(None);
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/makehuman");
        let t = std::time::Instant::now();
        let p = makehuman_performer(dir, &deformation).unwrap();
        eprintln!("loaded in {:.2} s", t.elapsed().as_secs_f64());
        (p, deformation)
    }

    #[test]
    fn attachments_sit_on_the_surface_and_follow_the_deformation() {
        let (performer, deformation) = performer();
        let suit = Suit::vlasic(&performer.skeleton).unwrap();
        let (surface, snapped) = GarmentSurface::new(&performer, &deformation, &suit).unwrap();
        for a in surface.boards.iter().chain(&surface.sources) {
            assert!(a.patch >= MIN_PATCH, "patch of {} vertices", a.patch);
        }
        let skeleton = &performer.skeleton;
        let rest = skeleton.forward_kinematics(&skeleton.rest_pose()).unwrap();
        for (a, b) in suit.boards().iter().zip(snapped.boards()) {
            let d = rest
                .point(&a.point())
                .unwrap()
                .distance(rest.point(&b.point()).unwrap());
            eprintln!("{}: snapped {:.1} mm", a.name, 1e3 * d);
            assert!(d < 0.12, "{} snapped {d} m", a.name);
        }
        // At rest the garment placement is the snapped suit's rigid placement.
        let at_rest = surface.pose(&skeleton.rest_pose()).unwrap();
        for (b, (p, q)) in snapped
            .boards()
            .iter()
            .zip(at_rest.board_positions.iter().zip(&at_rest.board_rotations))
        {
            assert!(p.distance(rest.point(&b.point()).unwrap()) < 1e-9);
            assert!(q.angle_between(rest.frame_rotation(&b.frame()).unwrap()) < 1e-6);
        }
        // Bent: the boards leave their bone-fixed placements by millimetres to centimetres.
        let mut theta = skeleton.rest_pose();
        for name in [
            "l_elbow.flexion",
            "r_knee.flexion",
            "l_shoulder.abduction",
            "r_shoulder.flexion",
            "l_hip.flexion",
            "spine.flexion",
        ] {
            theta[skeleton.dof_index(name).unwrap()] = 1.2;
        }
        let fk = skeleton.forward_kinematics(&theta).unwrap();
        let bent = surface.pose(&theta).unwrap();
        let moved: Vec<f64> = snapped
            .boards()
            .iter()
            .zip(&bent.board_positions)
            .map(|(b, p)| p.distance(fk.point(&b.point()).unwrap()))
            .collect();
        eprintln!(
            "moved (mm): {:?}",
            moved.iter().map(|m| (1e3 * m).round()).collect::<Vec<_>>()
        );
        assert!(moved.iter().cloned().fold(0.0, f64::max) > 0.001);
    }
}
