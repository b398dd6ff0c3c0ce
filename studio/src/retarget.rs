//! BVH playback on a performer: retargeting a source skeleton's motion (CMU mocap, MakeHuman
//! animations) onto the performer's skeleton through a joint name map.
//!
//! **Method** (rest-pose alignment by world-space bone directions, the usual practice of
//! MotionBuilder/Blender retargeters):
//! 1. A global rotation `G` maps the source world to the performer world: both rest poses give
//!    an up direction (pelvis → neck/head) and a left direction (right hip → left hip); the
//!    rotation between these body frames is snapped to the nearest axis permutation (both
//!    worlds are axis-aligned; this keeps a leaning rest spine from tilting the trajectory).
//! 2. For each mapped joint, a rest correction `Cⱼ` rotates the performer's rest bone direction
//!    (towards its first mapped child, else its end site) onto the source's (`G`-rotated) rest
//!    bone direction by the shortest arc; this absorbs T-pose vs A-pose differences. A source
//!    leaf's bone runs to its end site, else to the first joint down its first-child chain
//!    that lies away from it: zero-length joints such as CMU's `LeftWrist → lhand` are skipped
//!    (without that the wrist had no correction, and on the A-pose MakeHuman performer its
//!    flexion flipped across ±180°).
//! 3. Each frame, the performer joint's desired world rotation is `G · R_src(t) · Gᵀ · Cⱼ`
//!    (source joints' rest world rotations are the identity in BVH), its local rotation is
//!    taken relative to the parent's *achieved* rotation (errors do not accumulate) and
//!    decomposed onto the joint's own rotation DOFs: exactly for three orthogonal axes
//!    (Euler angles in the DOF order), by dropping the third angle for two, by swing–twist
//!    for one.
//! 4. Optionally ([`RetargetParams::twist_rate_limit_rad_per_s`]), a 3-DOF joint's twist
//!    about its bone from one frame to the next is slew-limited, its swing kept exactly.
//! 5. The root follows `s · G · p_src(t)`, with `s` the ratio of the performer's to the
//!    source's leg length (hip → knee → ankle).
//!
//! Motions come out at the source frame rate; use [`Motion::resample`] for any other.

use super::makehuman::MAKEHUMAN_SUBSET;
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};
use skin_core::math::{DMat3, DQuat, DVec3};
use skin_core::skeleton::{DofKind, Motion, Skeleton};
use skin_core::{Error, Result};

/// One source → performer joint correspondence.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct JointPair {
    /// Joint name in the source (BVH) skeleton.
    pub source: String,
    /// Joint name in the performer's skeleton.
    pub target: String,
}

/// A joint name map from a source skeleton onto a performer skeleton with the joint names of
/// [`human_skeleton`](skin_core::skeleton::human_skeleton). It must map `pelvis`, `l_hip`, `r_hip`
/// and at least one of `neck`/`head` (for the global alignment) and one leg's hip, knee and
/// ankle (for the scale). Each mapped source joint should be the one whose rotation moves the
/// same bone as the performer joint's DOFs (e.g. CMU `LeftHip` rotates the thigh, like
/// `l_hip`).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct JointMap {
    /// Name of the preset or map (for messages).
    pub name: String,
    /// The correspondences.
    pub pairs: Vec<JointPair>,
}

fn pairs(name: &str, list: &[(&str, &str)]) -> JointMap {
    JointMap {
        name: name.into(),
        pairs: list
            .iter()
            .map(|(s, t)| JointPair {
                source: (*s).into(),
                target: (*t).into(),
            })
            .collect(),
    }
}

impl JointMap {
    /// The CMU database as converted by cgspeed ("3dsMax-friendly", e.g. `131_01.bvh`):
    /// `Hips, lowerback, Chest, lowerneck, Head, LeftCollar, LeftShoulder, LeftElbow,
    /// LeftWrist, LeftHip, LeftKnee, LeftAnkle`, and the right side.
    pub fn cmu() -> Self {
        pairs(
            "cmu",
            &[
                ("Hips", "pelvis"),
                ("lowerback", "spine"),
                ("Chest", "chest"),
                ("lowerneck", "neck"),
                ("Head", "head"),
                ("LeftCollar", "l_clavicle"),
                ("LeftShoulder", "l_shoulder"),
                ("LeftElbow", "l_elbow"),
                ("LeftWrist", "l_wrist"),
                ("RightCollar", "r_clavicle"),
                ("RightShoulder", "r_shoulder"),
                ("RightElbow", "r_elbow"),
                ("RightWrist", "r_wrist"),
                ("LeftHip", "l_hip"),
                ("LeftKnee", "l_knee"),
                ("LeftAnkle", "l_ankle"),
                ("RightHip", "r_hip"),
                ("RightKnee", "r_knee"),
                ("RightAnkle", "r_ankle"),
            ],
        )
    }

    /// The MotionBuilder-style CMU conversion (and Mixamo-like rigs): `Hips, Spine, Spine1,
    /// Neck, Head, LeftShoulder, LeftArm, LeftForeArm, LeftHand, LeftUpLeg, LeftLeg,
    /// LeftFoot`, and the right side.
    pub fn motionbuilder() -> Self {
        pairs(
            "motionbuilder",
            &[
                ("Hips", "pelvis"),
                ("Spine", "spine"),
                ("Spine1", "chest"),
                ("Neck", "neck"),
                ("Head", "head"),
                ("LeftShoulder", "l_clavicle"),
                ("LeftArm", "l_shoulder"),
                ("LeftForeArm", "l_elbow"),
                ("LeftHand", "l_wrist"),
                ("RightShoulder", "r_clavicle"),
                ("RightArm", "r_shoulder"),
                ("RightForeArm", "r_elbow"),
                ("RightHand", "r_wrist"),
                ("LeftUpLeg", "l_hip"),
                ("LeftLeg", "l_knee"),
                ("LeftFoot", "l_ankle"),
                ("RightUpLeg", "r_hip"),
                ("RightLeg", "r_knee"),
                ("RightFoot", "r_ankle"),
            ],
        )
    }

    /// The MakeHuman animation BVHs (`walk1.bvh`, `dance1.bvh`; the older "game" rig names):
    /// `Root, Spine1, Spine3, Neck, Head, Clavicle_L, UpArm_L, LoArm_L, Hand_L, UpLeg_L,
    /// LoLeg_L, Foot_L`, and `_R`.
    pub fn makehuman_bvh() -> Self {
        pairs(
            "makehuman_bvh",
            &[
                ("Root", "pelvis"),
                ("Spine1", "spine"),
                ("Spine3", "chest"),
                ("Neck", "neck"),
                ("Head", "head"),
                ("Clavicle_L", "l_clavicle"),
                ("UpArm_L", "l_shoulder"),
                ("LoArm_L", "l_elbow"),
                ("Hand_L", "l_wrist"),
                ("Clavicle_R", "r_clavicle"),
                ("UpArm_R", "r_shoulder"),
                ("LoArm_R", "r_elbow"),
                ("Hand_R", "r_wrist"),
                ("UpLeg_L", "l_hip"),
                ("LoLeg_L", "l_knee"),
                ("Foot_L", "l_ankle"),
                ("UpLeg_R", "r_hip"),
                ("LoLeg_R", "r_knee"),
                ("Foot_R", "r_ankle"),
            ],
        )
    }

    /// BVHs exported from MakeHuman's `default.mhskel` rig (bone names such as
    /// `upperleg01.L`): the bones of [`MAKEHUMAN_SUBSET`].
    pub fn makehuman_rig() -> Self {
        let list: Vec<(&str, &str)> = MAKEHUMAN_SUBSET.iter().map(|t| (t.1, t.0)).collect();
        pairs("makehuman_rig", &list)
    }

    /// The first preset ([`cmu`](Self::cmu), [`motionbuilder`](Self::motionbuilder),
    /// [`makehuman_bvh`](Self::makehuman_bvh), [`makehuman_rig`](Self::makehuman_rig)) whose
    /// source joints all exist in `source`.
    ///
    /// # Errors
    /// [`Error::InvalidParam`] naming, for the closest preset, the joints `source` lacks.
    pub fn detect(source: &Skeleton) -> Result<Self> {
        let presets = [
            Self::cmu(),
            Self::motionbuilder(),
            Self::makehuman_bvh(),
            Self::makehuman_rig(),
        ];
        let missing = |m: &JointMap| -> Vec<String> {
            m.pairs
                .iter()
                .filter(|p| source.joint_index(&p.source).is_none())
                .map(|p| p.source.clone())
                .collect()
        };
        let mut best: Option<(usize, String, Vec<String>)> = None;
        for m in presets {
            let miss = missing(&m);
            if miss.is_empty() {
                return Ok(m);
            }
            if best.as_ref().is_none_or(|b| miss.len() < b.0) {
                best = Some((miss.len(), m.name.clone(), miss));
            }
        }
        let (_, name, miss) = best.unwrap_or_default();
        Err(Error::InvalidParam {
            name: "joint map",
            reason: format!(
                "no preset maps this skeleton onto the performer; closest preset '{name}' lacks source joints {miss:?}"
            ),
        })
    }
}

/// Options of [`retarget`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub struct RetargetParams {
    /// Clamp every frame into the performer's DOF limits. Default: false (mocap slightly
    /// beyond the nominal ranges is kept as captured).
    pub clamp_to_limits: bool,
    /// Opt-in twist filter: the largest rate (rad/s) at which a 3-DOF joint's bone (one with a
    /// mapped child) may twist about its own axis from one frame to the next. Faster twist is
    /// slew-limited (the joint catches up at this rate) while the bone's direction (the swing)
    /// stays the source's exactly. Meant for captures whose twist about a nearly straight limb
    /// is poorly determined: CMU 131_01 twists the right humerus at 34 rad/s for 0.1 s as the
    /// elbow extends (frames 228–238), faster than body-worn gyroscopes measure. The
    /// correction (a rotation about the bone) is applied to the descendants too, so their
    /// rotations relative to the bone stay the source's (the limb below turns with the
    /// limited twist: the forearm no longer spins at 34 rad/s, the hand moves off the
    /// source's during the limited frames). Default: `None` (rotations as captured).
    pub twist_rate_limit_rad_per_s: Option<f64>,
}

/// A retargeted motion.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Retargeted {
    /// The motion on the performer's skeleton, at the source frame rate.
    pub motion: Motion,
    /// Performer metres per source metre (leg-length ratio).
    pub scale: f64,
    /// Rotation from the source world to the performer world (`performer_from_source`).
    pub performer_from_source: DQuat,
}

/// Shortest-arc rotation taking unit `a` onto unit `b` (identity for degenerate input).
fn arc(a: DVec3, b: DVec3) -> DMat3 {
    let (a, b) = (a.normalize_or_zero(), b.normalize_or_zero());
    if a == DVec3::ZERO || b == DVec3::ZERO {
        return DMat3::IDENTITY;
    }
    DMat3::from_quat(DQuat::from_rotation_arc(a, b))
}

/// Rest direction (world, unnormalised) of the bone that source joint `s` rotates when no
/// mapped child gives it: its end site, else the first joint down its first-child chain that
/// lies away from `s` (or that joint's end site). BVH rigs often put a zero-length joint at
/// the wrist: CMU's cgspeed `LeftWrist` has `lhand` at offset 0 and the hand's length in
/// `lhand → LFingers`. Taking the first child's offset there gave a zero direction, so the
/// wrist got no rest correction at all; on the MakeHuman performer, whose A-pose hand points
/// ≈ 45° off the source's hanging one, the retargeted wrist then sat near the Euler angles'
/// singularity (deviation 55–89°) and its flexion flipped between ±180° (the hand spinning at
/// up to 364 rad/s).
fn leaf_bone_direction(source: &Skeleton, rest_positions: &[DVec3], s: usize) -> DVec3 {
    const MIN_LENGTH: f64 = 1e-9;
    let joints = source.joints();
    if let Some(e) = joints[s].end_site.filter(|e| e.length() > MIN_LENGTH) {
        return e;
    }
    let mut at = s;
    while let Some(c) = source.children(at).next() {
        let d = rest_positions[c] - rest_positions[s];
        if d.length() > MIN_LENGTH {
            return d;
        }
        if let Some(e) = joints[c].end_site.filter(|e| e.length() > MIN_LENGTH) {
            // Rest rotations are the identity in BVH: a local end site is a world offset.
            return rest_positions[c] - rest_positions[s] + e;
        }
        at = c;
    }
    DVec3::ZERO
}

/// Orthonormal frame (left, up, forward) from an up and a left direction.
fn body_frame(up: DVec3, left: DVec3) -> Result<DMat3> {
    let u = up.normalize_or_zero();
    let l = (left - u * left.dot(u)).normalize_or_zero();
    if u == DVec3::ZERO || l == DVec3::ZERO {
        return Err(Error::Degenerate {
            what: "rest pose: hips coincide or are aligned with the spine".into(),
        });
    }
    Ok(DMat3::from_cols(l, u, l.cross(u)))
}

/// The signed axis permutation nearest to `g` (each column snapped to its largest
/// component), if it is a proper rotation; else `g` itself. Source and performer worlds are
/// axis-aligned (Y-up or Z-up, facing along an axis), so this removes the few degrees of lean
/// a rest pose's spine gives the body frames — which, applied to a root that may be metres
/// from the origin, would otherwise tilt the whole trajectory.
fn snap_to_axes(g: DMat3) -> DMat3 {
    let snap = |c: DVec3| {
        let a = c.abs();
        if a.x >= a.y && a.x >= a.z {
            DVec3::X * c.x.signum()
        } else if a.y >= a.z {
            DVec3::Y * c.y.signum()
        } else {
            DVec3::Z * c.z.signum()
        }
    };
    let s = DMat3::from_cols(snap(g.x_axis), snap(g.y_axis), snap(g.z_axis));
    if (s.determinant() - 1.0).abs() < 1e-9 {
        s
    } else {
        g
    }
}

/// Angles `θ` with `L = Rot(a₀, θ₀) · Rot(a₁, θ₁) · …` (intrinsic) for orthonormal axes
/// (1 axis: swing–twist; 2: third axis completed and its angle dropped; 3: exact Euler).
fn decompose(l: DMat3, axes: &[DVec3]) -> Option<Vec<f64>> {
    match axes.len() {
        0 => Some(vec![]),
        1 => {
            let q = DQuat::from_mat3(&l);
            let proj = DVec3::new(q.x, q.y, q.z).dot(axes[0]);
            let mut t = 2.0 * proj.atan2(q.w);
            if t > std::f64::consts::PI {
                t -= std::f64::consts::TAU;
            } else if t < -std::f64::consts::PI {
                t += std::f64::consts::TAU;
            }
            Some(vec![t])
        }
        2 | 3 => {
            let a2 = if axes.len() == 3 {
                axes[2]
            } else {
                axes[0].cross(axes[1])
            };
            let (a0, a1) = (axes[0], axes[1]);
            if a0.dot(a1).abs() > 1e-9 || a0.dot(a2).abs() > 1e-9 || a1.dot(a2).abs() > 1e-9 {
                return None;
            }
            let b = DMat3::from_cols(a0, a1, a2);
            let det = b.determinant().signum();
            let r = b.transpose() * l * b;
            // R = Rx(α) Ry(β) Rz(γ): r[col][row] in glam.
            let beta = r.z_axis.x.clamp(-1.0, 1.0).asin();
            let gamma = (-r.y_axis.x).atan2(r.x_axis.x);
            let alpha = (-r.z_axis.y).atan2(r.z_axis.z);
            let mut out = vec![det * alpha, det * beta, det * gamma];
            out.truncate(axes.len());
            Some(out)
        }
        _ => None,
    }
}

/// Retargets `motion` of the `source` skeleton onto `target` through `map` (see the module
/// docs for the method).
///
/// # Errors
/// [`Error::InvalidParam`] naming every source joint of the map missing from `source` and every
/// target joint missing from `target` (the "BVH whose joints do not map" case), a map without
/// `pelvis`, `l_hip`, `r_hip`, `neck`/`head` or a full leg, a target joint with more than 3 or
/// non-orthogonal rotation DOFs, or translation DOFs off the root; [`Error::Degenerate`] for a
/// source leg of zero length; as [`Motion::check_for`].
pub fn retarget(
    source: &Skeleton,
    motion: &Motion,
    target: &Skeleton,
    map: &JointMap,
    params: &RetargetParams,
) -> Result<Retargeted> {
    motion.check_for(source)?;
    if let Some(v) = params.twist_rate_limit_rad_per_s {
        skin_core::check::positive("twist_rate_limit_rad_per_s", v)?;
    }
    let missing_src: Vec<&str> = map
        .pairs
        .iter()
        .filter(|p| source.joint_index(&p.source).is_none())
        .map(|p| p.source.as_str())
        .collect();
    let missing_tgt: Vec<&str> = map
        .pairs
        .iter()
        .filter(|p| target.joint_index(&p.target).is_none())
        .map(|p| p.target.as_str())
        .collect();
    if !missing_src.is_empty() || !missing_tgt.is_empty() {
        return Err(Error::InvalidParam {
            name: "joint map",
            reason: format!(
                "map '{}' does not fit: source skeleton lacks joints {missing_src:?}, performer lacks joints {missing_tgt:?}",
                map.name
            ),
        });
    }
    // src_of[target joint] = source joint index.
    let mut src_of: Vec<Option<usize>> = vec![None; target.joint_count()];
    for p in &map.pairs {
        // Both names were checked above.
        if let (Some(t), Some(s)) = (target.joint_index(&p.target), source.joint_index(&p.source)) {
            src_of[t] = Some(s);
        }
    }
    let need = |n: &str| -> Result<(usize, usize)> {
        let t = target.joint_index(n).ok_or_else(|| Error::InvalidParam {
            name: "joint map",
            reason: format!("performer has no joint '{n}'"),
        })?;
        let s = src_of[t].ok_or_else(|| Error::InvalidParam {
            name: "joint map",
            reason: format!("map '{}' must map performer joint '{n}'", map.name),
        })?;
        Ok((t, s))
    };
    let (root_t, root_s) = need("pelvis")?;
    if target.joints()[root_t].parent.is_some() {
        return Err(Error::InvalidParam {
            name: "joint map",
            reason: "performer joint 'pelvis' must be the root".into(),
        });
    }
    let (lh_t, lh_s) = need("l_hip")?;
    let (rh_t, rh_s) = need("r_hip")?;
    let (up_t, up_s) = need("neck").or_else(|_| need("head"))?;
    let src_rest = source.forward_kinematics(&source.rest_pose())?;
    let tgt_rest = target.forward_kinematics(&target.rest_pose())?;
    let sp = src_rest.joint_positions();
    let tp = tgt_rest.joint_positions();
    let f_src = body_frame(sp[up_s] - sp[root_s], sp[lh_s] - sp[rh_s])?;
    let f_tgt = body_frame(tp[up_t] - tp[root_t], tp[lh_t] - tp[rh_t])?;
    let g = snap_to_axes(f_tgt * f_src.transpose());
    // Scale: leg lengths of the mapped sides.
    let mut ratios = Vec::new();
    for side in ["l", "r"] {
        let (Ok((h_t, h_s)), Ok((k_t, k_s)), Ok((a_t, a_s))) = (
            need(&format!("{side}_hip")),
            need(&format!("{side}_knee")),
            need(&format!("{side}_ankle")),
        ) else {
            continue;
        };
        let lt = tp[h_t].distance(tp[k_t]) + tp[k_t].distance(tp[a_t]);
        let ls = sp[h_s].distance(sp[k_s]) + sp[k_s].distance(sp[a_s]);
        if ls < 1e-9 {
            return Err(Error::Degenerate {
                what: format!("source leg '{side}' has zero length"),
            });
        }
        ratios.push(lt / ls);
    }
    if ratios.is_empty() {
        return Err(Error::InvalidParam {
            name: "joint map",
            reason: format!("map '{}' must map one leg's hip, knee and ankle", map.name),
        });
    }
    let scale = ratios.iter().sum::<f64>() / ratios.len() as f64;
    // Per target joint: rotation DOF indices and axes; translation DOFs only at the root.
    let mut rot_dofs: Vec<Vec<usize>> = Vec::with_capacity(target.joint_count());
    let mut trans_dofs: Vec<usize> = Vec::new();
    for (j, joint) in target.joints().iter().enumerate() {
        let range = target.joint_dofs(j);
        let mut rots = Vec::new();
        for d in range {
            match target.dof(d).kind {
                DofKind::Rotation => rots.push(d),
                DofKind::Translation if j == root_t && rots.is_empty() => trans_dofs.push(d),
                DofKind::Translation => {
                    return Err(Error::InvalidParam {
                        name: "target skeleton",
                        reason: format!("joint '{}': retargeting supports translations only on the root, before its rotations", joint.name),
                    })
                }
            }
        }
        let axes: Vec<DVec3> = rots.iter().map(|&d| target.dof(d).axis).collect();
        if decompose(DMat3::IDENTITY, &axes).is_none() {
            return Err(Error::InvalidParam {
                name: "target skeleton",
                reason: format!(
                    "joint '{}': retargeting needs at most 3 orthogonal rotation axes",
                    joint.name
                ),
            });
        }
        rot_dofs.push(rots);
    }
    // Rest corrections C_j from bone directions.
    let mut correction = vec![DMat3::IDENTITY; target.joint_count()];
    for j in 0..target.joint_count() {
        let Some(s) = src_of[j] else { continue };
        if j == root_t {
            continue;
        }
        let child = target.children(j).find(|&c| src_of[c].is_some());
        let (dt, ds) = match child {
            Some(c) => (tp[c] - tp[j], sp[src_of[c].unwrap_or(s)] - sp[s]),
            None => {
                let dt = target.joints()[j].end_site.unwrap_or(DVec3::ZERO);
                (dt, leaf_bone_direction(source, &sp, s))
            }
        };
        correction[j] = arc(dt, g * ds);
    }
    // Twist axes (the rest bone direction in the joint frame; performer rest rotations are
    // the identity) of the joints the twist filter applies to: 3 DOFs and a mapped child.
    let twist_axis: Vec<Option<DVec3>> = (0..target.joint_count())
        .map(|j| {
            let child = target.children(j).find(|&c| src_of[c].is_some())?;
            let u = (tp[child] - tp[j]).normalize_or_zero();
            (params.twist_rate_limit_rad_per_s.is_some()
                && src_of[j].is_some()
                && j != root_t
                && rot_dofs[j].len() == 3
                && u != DVec3::ZERO)
                .then_some(u)
        })
        .collect();
    let max_twist =
        params.twist_rate_limit_rad_per_s.unwrap_or(f64::INFINITY) * motion.frame_time_s;
    let n = motion.frame_count();
    let mut frames = DMatrix::zeros(target.dof_count(), n);
    let mut src_fk = skin_core::skeleton::ForwardKinematics::new(source);
    let mut achieved = vec![DMat3::IDENTITY; target.joint_count()];
    let mut twist_fix: Vec<Option<DMat3>> = vec![None; target.joint_count()];
    for k in 0..n {
        source.forward_kinematics_into(motion.frame(k), &mut src_fk)?;
        let w = src_fk.world_from_joint();
        let mut theta = vec![0.0; target.dof_count()];
        for j in 0..target.joint_count() {
            let parent = target.joints()[j]
                .parent
                .map_or(DMat3::IDENTITY, |p| achieved[p]);
            // The twist corrections of the ancestors, as one world-frame rotation (`None`: no
            // correction, so unfiltered joints stay bit for bit the plain retarget's).
            let inherited = target.joints()[j].parent.and_then(|p| twist_fix[p]);
            let mut desired = match src_of[j] {
                Some(s) => {
                    let d = g * w[s].matrix3 * g.transpose() * correction[j];
                    inherited.map_or(d, |c| c * d)
                }
                None => parent,
            };
            twist_fix[j] = inherited;
            // Twist filter: the twist about the bone between the previous frame's achieved
            // rotation and this one's, slew-limited; the bone direction `desired · u` is kept,
            // and the correction (a rotation about the bone) carries on to the descendants so
            // that their rotations relative to this bone stay the source's.
            if let (Some(u), true) = (twist_axis[j], k > 0) {
                let step = decompose(achieved[j].transpose() * desired, &[u])
                    .and_then(|t| t.first().copied())
                    .unwrap_or(0.0);
                if step.abs() > max_twist {
                    let fix = DMat3::from_axis_angle(u, step.clamp(-max_twist, max_twist) - step);
                    let world_fix = desired * fix * desired.transpose();
                    desired *= fix;
                    twist_fix[j] = Some(inherited.map_or(world_fix, |c| world_fix * c));
                }
            }
            let axes: Vec<DVec3> = rot_dofs[j].iter().map(|&d| target.dof(d).axis).collect();
            // Axes were validated above, so the decomposition exists.
            let angles = decompose(parent.transpose() * desired, &axes)
                .unwrap_or_else(|| vec![0.0; axes.len()]);
            let mut rot = parent;
            for ((&d, &a), axis) in rot_dofs[j].iter().zip(&angles).zip(&axes) {
                let a = match (params.clamp_to_limits, target.dof(d).limits) {
                    (true, Some(l)) => l.clamp(a),
                    _ => a,
                };
                theta[d] = a;
                rot *= DMat3::from_axis_angle(*axis, a);
            }
            achieved[j] = rot;
        }
        // Root translation: world position s·G·p_src, minus the rest offset, on the axes.
        let want = g * w[root_s].translation * scale - target.joints()[root_t].offset;
        for &d in &trans_dofs {
            theta[d] = want.dot(target.dof(d).axis);
        }
        frames.column_mut(k).copy_from_slice(&theta);
    }
    Ok(Retargeted {
        motion: Motion::new(motion.frame_time_s, frames)?,
        scale,
        performer_from_source: DQuat::from_mat3(&g),
    })
}

/// Reads a BVH file, picks its joint map with [`JointMap::detect`], retargets it onto
/// `target` and resamples it to `frame_time_s` — BVH playback in one call.
///
/// # Errors
/// As [`read_bvh`](skin_core::skeleton::read_bvh), [`JointMap::detect`] (naming the joints that
/// do not map), [`retarget`] and [`Motion::resample`].
pub fn play_bvh(
    path: impl AsRef<std::path::Path>,
    bvh_params: &skin_core::skeleton::BvhParams,
    target: &Skeleton,
    frame_time_s: f64,
    params: &RetargetParams,
) -> Result<Retargeted> {
    let bvh = skin_core::skeleton::read_bvh(path, bvh_params)?;
    let map = JointMap::detect(&bvh.skeleton)?;
    let mut out = retarget(&bvh.skeleton, &bvh.motion, target, &map, params)?;
    out.motion = out.motion.resample(target, frame_time_s)?;
    Ok(out)
}

#[cfg(test)]
mod tests;
