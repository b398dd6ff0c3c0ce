//! **Pose-driven deformation**: muscle and joint shapes that linear blend skinning cannot
//! express, as a pure, smooth function of the joint angles θ (no state, no history).
//!
//! Each [`PoseEffect`] moves the vertices of one body region radially from a bone's axis:
//!
//! ```text
//! d(v, θ) = M_v(θ) · A · a(θ) · w_region(v) · bump(s_v) · max(0, r̂_v · f̂)² · (±r̂_v)
//! ```
//!
//! * `a(θ) = smoothstep(Σ θ_dof / θ_ref)`: the activation, from the sum of the effect's
//!   driving DOFs over its (signed) reference angle; exactly 0 at rest and for the inactive
//!   sign, 1 at the reference angle and beyond, C¹ in θ (`smoothstep(x) = 3x² − 2x³` on
//!   `[0, 1]`, clamped).
//! * `A`: the amplitude, metres, reached at the reference angle where the profiles peak.
//! * `w_region(v)`: the vertex's summed skin weight on the region's joints (bones).
//! * `s_v`: position along the effect's axis in bone lengths (see [`EffectAxis`]), and
//!   `bump(s)` a C¹ cos² bump ([`Bump`]) peaking at 1.
//! * `r̂_v`: unit radial direction from the axis at rest; `f̂` the side that swells or creases
//!   ([`EffectSide`]), so `max(0, r̂·f̂)²` is a lobe over half the limb's circumference.
//! * `+r̂` pushes outward (a swelling muscle), `−r̂` inward (a crease), see [`Push`].
//! * `M_v(θ)`: the vertex's blended skinning rotation, the normalised sum `Σⱼ wⱼ(v) qⱼ(θ)` of
//!   its bones' rotations as sign-aligned unit quaternions (the rotation part of dual
//!   quaternion skinning), so the rest-space offset follows the surface it sits on (a
//!   pose-space corrective in the sense of Lewis et al. 2000) and keeps its length, also
//!   across a bent joint where the linear blend of rotations would shrink it.
//!
//! Everything but `a(θ)` and `M_v(θ)` is precomputed per vertex when the performer is built;
//! posing costs one multiply-add per moved vertex and effect plus one 3×3 blend per moved
//! vertex. [`PoseDeformParams::default`] lists the human body's effects with realistic sizes.

use serde::{Deserialize, Serialize};
use skin_core::check;
use skin_core::math::{DAffine3, DQuat, DVec3};
use skin_core::mesh::SkinWeights;
use skin_core::skeleton::{ForwardKinematics, Skeleton};
use skin_core::{Error, Result};
use std::f64::consts::FRAC_PI_2;

/// Where an effect's along-axis coordinate `s` and radial direction are measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum EffectAxis {
    /// The segment of joint [`PoseEffect::bone`]: `s = 0` at that joint, `s = 1` at the far
    /// end of its segment (its child joint, the mean of several children, or its end site);
    /// radial from the segment's line. For muscles lying along one bone.
    Bone,
    /// Around the joint at the far end of [`PoseEffect::bone`]'s segment (which must have
    /// exactly one child joint: the elbow for the upper arm, the knee for the thigh): `s = 0`
    /// at that joint, measured in lengths of `bone`'s segment along the bisector of the two
    /// segments' rest directions; radial from that line. For joint shapes that straddle two
    /// segments (creases, the round outside of a bent joint).
    Joint,
}

/// Which side of the axis an effect acts on: the centre `f̂` of its angular lobe, taken at
/// rest perpendicular to the effect's axis.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub enum EffectSide {
    /// Towards where positive motion of the named rotation DOF swings the far end of that
    /// DOF's joint segment (e.g. `"l_elbow.flexion"`: the flexor, anterior side of the arm;
    /// `"l_knee.flexion"`: the posterior side of the leg; `"l_shoulder.abduction"`: the
    /// lateral side of the upper arm; `"spine.flexion"`: the front of the trunk).
    Towards(String),
    /// The opposite side of [`EffectSide::Towards`] (e.g. the extensor side, the back).
    AwayFrom(String),
}

/// Direction of an effect's displacement.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Push {
    /// Away from the axis: a swelling muscle, the outside of a joint staying round.
    Outward,
    /// Towards the axis: a crease.
    Inward,
}

/// A smooth bump along an effect's axis: 1 at `peak`, falling as `cos²` to 0 at
/// `peak − before` and `peak + after` (all in bone lengths), 0 outside; C¹ everywhere.
/// A falling half reaches 30 % of the peak at 0.63 of its width.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Bump {
    /// Position of the maximum, bone lengths from the axis origin.
    pub peak: f64,
    /// Width of the rising half (towards smaller `s`), bone lengths, > 0.
    pub before: f64,
    /// Width of the falling half (towards larger `s`), bone lengths, > 0.
    pub after: f64,
}

impl Bump {
    /// The bump's value at `s` (bone lengths), in `[0, 1]`.
    pub fn value(&self, s: f64) -> f64 {
        let x = if s <= self.peak {
            (self.peak - s) / self.before
        } else {
            (s - self.peak) / self.after
        };
        if x >= 1.0 {
            0.0
        } else {
            (FRAC_PI_2 * x).cos().powi(2)
        }
    }
}

/// The smooth activation ramp `a(x) = smoothstep(x)`: 0 for `x ≤ 0`, `3x² − 2x³` on
/// `[0, 1]`, 1 for `x ≥ 1`; C¹, with zero slope at both ends.
pub fn activation_ramp(x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

/// One pose-driven shape: which DOFs drive it, which region moves, which way and how far.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PoseEffect {
    /// Name, unique within [`PoseDeformParams::effects`] (e.g. `"l_biceps"`).
    pub name: String,
    /// Driving rotation DOFs; the activation reads their sum (e.g. `["l_elbow.flexion"]`, or
    /// `["spine.flexion", "chest.flexion"]` for the whole trunk's forward bend).
    pub dofs: Vec<String>,
    /// Reference angle, radians, signed: full amplitude when the DOF sum reaches it (and
    /// beyond); the effect is inactive for sums of the other sign (e.g. −30° of
    /// `ankle.dorsiflexion` is 30° of plantarflexion). Finite and non-zero.
    pub reference_rad: f64,
    /// Displacement at the reference angle at the centre of the region (peak of the bump,
    /// centre of the side, full region weight), metres, finite and ≥ 0.
    pub amplitude_m: f64,
    /// Joint whose segment carries the effect (e.g. `"l_shoulder"`: the upper arm).
    pub bone: String,
    /// Where `s` and the radial direction are measured.
    pub axis: EffectAxis,
    /// Joints (bones) whose summed skin weight scales the effect per vertex, not empty.
    pub region: Vec<String>,
    /// Profile along the axis.
    pub along: Bump,
    /// Which side of the limb or trunk moves.
    pub side: EffectSide,
    /// Outward (swelling) or inward (crease).
    pub push: Push,
}

impl PoseEffect {
    /// The pose at which the effect reaches its amplitude: the rest pose with the reference
    /// angle shared equally among the driving DOFs.
    ///
    /// # Errors
    /// [`Error::InvalidParam`] naming a driving DOF the skeleton lacks.
    pub fn reference_pose(&self, skeleton: &Skeleton) -> Result<Vec<f64>> {
        let mut theta = skeleton.rest_pose();
        for name in &self.dofs {
            let d = effect(&self.name).dof(skeleton, name)?;
            theta[d] = self.reference_rad / self.dofs.len().max(1) as f64;
        }
        Ok(theta)
    }
}

/// Default biceps/brachialis swelling at the reference elbow flexion, metres.
const DEFAULT_BICEPS_M: f64 = 0.020;
/// Default brachioradialis swelling on the forearm, metres.
const DEFAULT_BRACHIORADIALIS_M: f64 = 0.008;
/// Default deltoid swelling with shoulder abduction, metres.
const DEFAULT_DELTOID_M: f64 = 0.012;
/// Default calf (gastrocnemius) swelling with plantarflexion, metres.
const DEFAULT_CALF_M: f64 = 0.010;
/// Default hamstring swelling with knee flexion, metres.
const DEFAULT_HAMSTRINGS_M: f64 = 0.010;
/// Default abdomen compression and back stretch on forward bending, metres.
const DEFAULT_TRUNK_M: f64 = 0.015;
/// Default elbow crease depth and outside rounding, metres.
const DEFAULT_ELBOW_VOLUME_M: f64 = 0.010;
/// Default knee crease depth and outside rounding, metres.
const DEFAULT_KNEE_VOLUME_M: f64 = 0.012;

/// Parameters of the pose-driven deformation: a list of effects.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PoseDeformParams {
    /// The effects, applied in order (their displacements add).
    pub effects: Vec<PoseEffect>,
}

impl Default for PoseDeformParams {
    /// The human body's effects, for the joint and DOF names of
    /// [`human_skeleton`](skin_core::skeleton::human_skeleton) (the MakeHuman and procedural
    /// performers share them), both sides (`l_`/`r_`) of each limb effect. Reference angles
    /// are DOF values, measured from the rest pose (the MakeHuman elbows are already bent
    /// ≈ 45° at rest, so 90° of `elbow.flexion` there is ≈ 135° between the segments).
    ///
    /// | effect | DOFs (reference) | amplitude | region, profile | side, push |
    /// | --- | --- | --- | --- | --- |
    /// | `biceps` | `elbow.flexion` (90°) | 20 mm | upper arm (and the forearm's weight near the elbow, so the skin weights' fade does not cut the profile), peak at 60 % down, ≈ 30 % of peak at 95 % | flexor, out |
    /// | `brachioradialis` | `elbow.flexion` (90°) | 8 mm | forearm, peak at 25 % | flexor, out |
    /// | `deltoid` | `shoulder.abduction` (90°) | 12 mm | upper arm and clavicle, peak at 15 % | lateral, out |
    /// | `calf` | `ankle.dorsiflexion` (−30°, i.e. 30° plantarflexion) | 10 mm | shank, peak at 30 % | posterior, out |
    /// | `hamstrings` | `knee.flexion` (90°) | 10 mm | thigh, peak at 60 % | posterior, out |
    /// | `abdomen` | `spine.flexion + chest.flexion` (45°) | 15 mm | pelvis, lumbar, thorax; peak 30 % up the lumbar segment | anterior, out |
    /// | `back` | `spine.flexion + chest.flexion` (45°) | 15 mm | same, peak at 50 % | posterior, in |
    /// | `elbow_crease` / `elbow_round` | `elbow.flexion` (90°) | 10 mm each | ±20 % of the upper arm around the elbow | flexor in / extensor out |
    /// | `knee_crease` / `knee_round` | `knee.flexion` (90°) | 12 mm each | ±15 % of the thigh around the knee | posterior in / anterior out |
    ///
    /// Sizes: biceps, brachioradialis, deltoid, calf and trunk as the studio's specification (docs/studio.md) gives them.
    /// The **calf** is driven by `ankle.dorsiflexion`, the only ankle flexion DOF of both
    /// skeletons, with a negative reference (plantarflexion). The **hamstrings** get 10 mm,
    /// half the biceps: they contract as strongly in knee flexion but are a flatter, deeper
    /// muscle group under a thicker fat layer, and a 10–20 % thickening of their ≈ 5 cm depth
    /// is 5–10 mm. The **abdomen** is compressed between ribs and pelvis and its soft tissue
    /// rolls forward (outward), while the stretched skin and erector spinae of the **back**
    /// flatten towards the spine (inward). **Joint volume**: skinning a hinge bent by φ with
    /// a limb radius r loses about `r (1 − cos(φ/2))` on the outside (12 mm for an elbow of
    /// r ≈ 4 cm at 90°, 16 mm for a knee of r ≈ 5.5 cm) and lets the inside interpenetrate;
    /// the truth keeps the outside round (outward, 10 mm elbow, 12 mm knee, somewhat less
    /// than the loss) and folds the inside into a crease of the same depth.
    fn default() -> Self {
        let deg = f64::to_radians;
        let mut effects = Vec::new();
        for side in ["l", "r"] {
            let j = |n: &str| format!("{side}_{n}");
            let effect = |name: &str,
                          dof: &str,
                          reference_deg: f64,
                          amplitude_m: f64,
                          bone: &str,
                          axis: EffectAxis,
                          region: &[&str],
                          along: (f64, f64, f64),
                          side: EffectSide,
                          push: Push| PoseEffect {
                name: j(name),
                dofs: vec![j(dof)],
                reference_rad: deg(reference_deg),
                amplitude_m,
                bone: j(bone),
                axis,
                region: region.iter().map(|r| j(r)).collect(),
                along: Bump {
                    peak: along.0,
                    before: along.1,
                    after: along.2,
                },
                side,
                push,
            };
            let towards = |d: &str| EffectSide::Towards(j(d));
            let away = |d: &str| EffectSide::AwayFrom(j(d));
            use EffectAxis::{Bone, Joint};
            use Push::{Inward, Outward};
            effects.extend([
                effect(
                    "biceps",
                    "elbow.flexion",
                    90.0,
                    DEFAULT_BICEPS_M,
                    "shoulder",
                    Bone,
                    &["shoulder", "elbow"],
                    (0.6, 0.6, 0.55),
                    towards("elbow.flexion"),
                    Outward,
                ),
                effect(
                    "brachioradialis",
                    "elbow.flexion",
                    90.0,
                    DEFAULT_BRACHIORADIALIS_M,
                    "elbow",
                    Bone,
                    &["elbow"],
                    (0.25, 0.3, 0.45),
                    towards("elbow.flexion"),
                    Outward,
                ),
                effect(
                    "deltoid",
                    "shoulder.abduction",
                    90.0,
                    DEFAULT_DELTOID_M,
                    "shoulder",
                    Bone,
                    &["shoulder", "clavicle"],
                    (0.15, 0.3, 0.3),
                    towards("shoulder.abduction"),
                    Outward,
                ),
                effect(
                    "calf",
                    "ankle.dorsiflexion",
                    -30.0,
                    DEFAULT_CALF_M,
                    "knee",
                    Bone,
                    &["knee"],
                    (0.3, 0.3, 0.4),
                    towards("knee.flexion"),
                    Outward,
                ),
                effect(
                    "hamstrings",
                    "knee.flexion",
                    90.0,
                    DEFAULT_HAMSTRINGS_M,
                    "hip",
                    Bone,
                    &["hip"],
                    (0.6, 0.45, 0.4),
                    towards("knee.flexion"),
                    Outward,
                ),
                effect(
                    "elbow_crease",
                    "elbow.flexion",
                    90.0,
                    DEFAULT_ELBOW_VOLUME_M,
                    "shoulder",
                    Joint,
                    &["shoulder", "elbow"],
                    (0.0, 0.2, 0.2),
                    towards("elbow.flexion"),
                    Inward,
                ),
                effect(
                    "elbow_round",
                    "elbow.flexion",
                    90.0,
                    DEFAULT_ELBOW_VOLUME_M,
                    "shoulder",
                    Joint,
                    &["shoulder", "elbow"],
                    (0.0, 0.2, 0.2),
                    away("elbow.flexion"),
                    Outward,
                ),
                effect(
                    "knee_crease",
                    "knee.flexion",
                    90.0,
                    DEFAULT_KNEE_VOLUME_M,
                    "hip",
                    Joint,
                    &["hip", "knee"],
                    (0.0, 0.15, 0.15),
                    towards("knee.flexion"),
                    Inward,
                ),
                effect(
                    "knee_round",
                    "knee.flexion",
                    90.0,
                    DEFAULT_KNEE_VOLUME_M,
                    "hip",
                    Joint,
                    &["hip", "knee"],
                    (0.0, 0.15, 0.15),
                    away("knee.flexion"),
                    Outward,
                ),
            ]);
        }
        let trunk = |name: &str, peak: f64, side: EffectSide, push: Push| PoseEffect {
            name: name.into(),
            dofs: vec!["spine.flexion".into(), "chest.flexion".into()],
            reference_rad: deg(45.0),
            amplitude_m: DEFAULT_TRUNK_M,
            bone: "spine".into(),
            axis: EffectAxis::Bone,
            region: vec!["pelvis".into(), "spine".into(), "chest".into()],
            along: Bump {
                peak,
                before: 1.0,
                after: 1.0,
            },
            side,
            push,
        };
        effects.push(trunk(
            "abdomen",
            0.3,
            EffectSide::Towards("spine.flexion".into()),
            Push::Outward,
        ));
        effects.push(trunk(
            "back",
            0.5,
            EffectSide::AwayFrom("spine.flexion".into()),
            Push::Inward,
        ));
        PoseDeformParams { effects }
    }
}

impl PoseDeformParams {
    /// No effects (the pose-driven displacement is zero).
    pub fn none() -> Self {
        PoseDeformParams {
            effects: Vec::new(),
        }
    }

    /// These parameters without the effect called `name` (unchanged if there is none).
    pub fn without(mut self, name: &str) -> Self {
        self.effects.retain(|e| e.name != name);
        self
    }

    /// Only the effect called `name` (none if there is no such effect).
    pub fn only(mut self, name: &str) -> Self {
        self.effects.retain(|e| e.name == name);
        self
    }

    /// The effect called `name`.
    pub fn effect(&self, name: &str) -> Option<&PoseEffect> {
        self.effects.iter().find(|e| e.name == name)
    }
}

/// One effect, precomputed for a template.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct EffectModel {
    dofs: Vec<usize>,
    reference_rad: f64,
    /// (vertex, rest-space displacement at full activation, metres).
    vertices: Vec<(u32, DVec3)>,
}

impl EffectModel {
    fn activation(&self, theta: &[f64]) -> f64 {
        let sum: f64 = self.dofs.iter().map(|&d| theta[d]).sum();
        activation_ramp(sum / self.reference_rad)
    }
}

/// The pose-driven deformation precomputed for one template and skeleton.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(super) struct PoseModel {
    effects: Vec<EffectModel>,
    /// Every vertex some effect moves, ascending.
    touched: Vec<u32>,
}

/// One named entry of a parameter list (a pose effect, a wrinkle crease): its errors name
/// the list and the entry, and its DOF and joint names resolve against a skeleton.
#[derive(Debug, Clone, Copy)]
pub(super) struct Named<'a> {
    /// The parameter list (e.g. `"pose.effects"`).
    pub(super) list: &'static str,
    /// What an entry is called in parameter errors (e.g. `"effect"`).
    pub(super) kind: &'static str,
    /// What an entry is called in geometry errors, outside its list (e.g. `"pose effect"`).
    pub(super) long_kind: &'static str,
    /// The entry's name.
    pub(super) name: &'a str,
}

impl Named<'_> {
    /// An [`Error::InvalidParam`] of this entry ("effect 'l_biceps': …").
    pub(super) fn invalid(&self, reason: String) -> Error {
        Error::InvalidParam {
            name: self.list,
            reason: format!("{} '{}': {reason}", self.kind, self.name),
        }
    }

    /// A check's error, restated for this entry.
    pub(super) fn wrap(&self, e: Error) -> Error {
        let reason = match e {
            Error::InvalidParam { name, reason } => format!("{name} {reason}"),
            other => other.to_string(),
        };
        self.invalid(reason)
    }

    /// An [`Error::Degenerate`] of this entry.
    pub(super) fn degenerate(&self, what: String) -> Error {
        Error::Degenerate {
            what: format!("{} '{}': {what}", self.long_kind, self.name),
        }
    }

    /// The rotation DOF `dof` of `skeleton`.
    pub(super) fn dof(&self, skeleton: &Skeleton, dof: &str) -> Result<usize> {
        let d = skeleton
            .dof_index(dof)
            .ok_or_else(|| self.invalid(format!("the skeleton has no DOF '{dof}'")))?;
        if skeleton.is_rotation(d) {
            Ok(d)
        } else {
            Err(self.invalid(format!("DOF '{dof}' is not a rotation")))
        }
    }

    /// The joint `joint` of `skeleton`.
    pub(super) fn joint(&self, skeleton: &Skeleton, joint: &str) -> Result<usize> {
        skeleton
            .joint_index(joint)
            .ok_or_else(|| self.invalid(format!("the skeleton has no joint '{joint}'")))
    }

    /// The segment of joint `bone` at rest: its start, its far end ([`distal_tip`]) and its
    /// length.
    pub(super) fn segment(
        &self,
        skeleton: &Skeleton,
        frames: &[DAffine3],
        bone: usize,
    ) -> Result<(DVec3, DVec3, f64)> {
        let a = frames[bone].translation;
        let b = distal_tip(skeleton, frames, bone);
        let length = a.distance(b);
        if length < 1e-6 {
            return Err(self.degenerate(format!(
                "bone of '{}' has zero length",
                skeleton.joints()[bone].name
            )));
        }
        Ok((a, b, length))
    }

    /// The axis of [`EffectAxis::Joint`] for the segment `a → b` (length `length`) of joint
    /// `bone`: origin at its one child joint, direction the bisector of the two segments' rest
    /// directions.
    pub(super) fn joint_axis(
        &self,
        skeleton: &Skeleton,
        frames: &[DAffine3],
        bone: usize,
        (a, b, length): (DVec3, DVec3, f64),
    ) -> Result<(DVec3, DVec3)> {
        let children: Vec<usize> = skeleton.children(bone).collect();
        let [child] = children[..] else {
            return Err(self.invalid(format!(
                "a joint axis needs a bone with one child joint; '{}' has {}",
                skeleton.joints()[bone].name,
                children.len()
            )));
        };
        let c = frames[child].translation;
        let distal = (distal_tip(skeleton, frames, child) - c).normalize_or_zero();
        let axis = ((b - a) / length + distal).normalize_or_zero();
        if axis == DVec3::ZERO {
            return Err(self.degenerate("the joint is folded back on itself".into()));
        }
        Ok((c, axis))
    }

    /// The unit direction `f̂` of `side` perpendicular to `axis` at rest (see [`EffectSide`]).
    pub(super) fn side(
        &self,
        skeleton: &Skeleton,
        rest: &ForwardKinematics,
        side: &EffectSide,
        axis: DVec3,
    ) -> Result<DVec3> {
        let (sign, side_dof) = match side {
            EffectSide::Towards(d) => (1.0, d),
            EffectSide::AwayFrom(d) => (-1.0, d),
        };
        let sd = self.dof(skeleton, side_dof)?;
        let tip = distal_tip(skeleton, rest.world_from_joint(), skeleton.dof_joint(sd));
        let swing = rest.dof_axes_world()[sd].cross(tip - rest.dof_origins_world()[sd]);
        let f = (swing - axis * swing.dot(axis)).normalize_or_zero() * sign;
        if f == DVec3::ZERO {
            return Err(self.degenerate(format!("side '{side_dof}' is parallel to the axis")));
        }
        Ok(f)
    }
}

/// The [`Named`] of pose effect `name`.
fn effect(name: &str) -> Named<'_> {
    Named {
        list: "pose.effects",
        kind: "effect",
        long_kind: "pose effect",
        name,
    }
}

/// Checks the parameters against `skeleton`: names, amplitudes, angles, widths.
fn validate(p: &PoseEffect, skeleton: &Skeleton) -> Result<()> {
    let n = effect(&p.name);
    let wrap = |e| n.wrap(e);
    check::nonzero("dofs (count)", p.dofs.len()).map_err(wrap)?;
    check::nonzero("region (count)", p.region.len()).map_err(wrap)?;
    for d in &p.dofs {
        n.dof(skeleton, d)?;
    }
    for j in &p.region {
        n.joint(skeleton, j)?;
    }
    n.joint(skeleton, &p.bone)?;
    let (EffectSide::Towards(d) | EffectSide::AwayFrom(d)) = &p.side;
    n.dof(skeleton, d)?;
    check::non_negative("amplitude_m", p.amplitude_m).map_err(wrap)?;
    check::positive("|reference_rad|", p.reference_rad.abs()).map_err(wrap)?;
    check::finite("along.peak", p.along.peak).map_err(wrap)?;
    check::positive("along.before", p.along.before).map_err(wrap)?;
    check::positive("along.after", p.along.after).map_err(wrap)?;
    Ok(())
}

/// Precomputes the pose-driven deformation for a rest template.
///
/// # Errors
/// [`Error::InvalidParam`] naming the effect and the unknown DOF or joint, a non-rotation DOF,
/// a negative or non-finite amplitude, a zero or non-finite reference angle, a bad profile, a
/// duplicate effect name; [`Error::Degenerate`] for a zero-length bone or a side parallel to
/// the axis.
pub(super) fn pose_model(
    params: &PoseDeformParams,
    skeleton: &Skeleton,
    rest: &ForwardKinematics,
    rest_vertices: &[DVec3],
    weights: &SkinWeights,
) -> Result<PoseModel> {
    for (i, e) in params.effects.iter().enumerate() {
        validate(e, skeleton)?;
        if params.effects[..i].iter().any(|o| o.name == e.name) {
            return Err(effect(&e.name).invalid("duplicate effect name".into()));
        }
    }
    let frames = rest.world_from_joint();
    let mut effects = Vec::with_capacity(params.effects.len());
    let mut moved = vec![false; rest_vertices.len()];
    for p in &params.effects {
        let n = effect(&p.name);
        let dofs = p
            .dofs
            .iter()
            .map(|d| n.dof(skeleton, d))
            .collect::<Result<Vec<_>>>()?;
        let region = p
            .region
            .iter()
            .map(|j| n.joint(skeleton, j))
            .collect::<Result<Vec<_>>>()?;
        let bone = n.joint(skeleton, &p.bone)?;
        let segment = n.segment(skeleton, frames, bone)?;
        let (a, b, length) = segment;
        let (origin, axis) = match p.axis {
            EffectAxis::Bone => (a, (b - a) / length),
            EffectAxis::Joint => n.joint_axis(skeleton, frames, bone, segment)?,
        };
        let side = n.side(skeleton, rest, &p.side, axis)?;
        let push = match p.push {
            Push::Outward => 1.0,
            Push::Inward => -1.0,
        };
        let mut vertices = Vec::new();
        for (v, x) in rest_vertices.iter().enumerate() {
            let w: f64 = weights
                .influences(v)
                .filter(|q| region.contains(&(q.0 as usize)))
                .map(|q| q.1)
                .sum();
            if w <= 0.0 {
                continue;
            }
            let along = (*x - origin).dot(axis);
            let bump = p.along.value(along / length);
            if bump <= 0.0 {
                continue;
            }
            let radial = (*x - origin - axis * along).normalize_or_zero();
            let c = radial.dot(side);
            if c <= 0.0 {
                continue;
            }
            let k = p.amplitude_m * w * bump * c * c;
            if k > 0.0 {
                vertices.push((v as u32, radial * (k * push)));
                moved[v] = true;
            }
        }
        effects.push(EffectModel {
            dofs,
            reference_rad: p.reference_rad,
            vertices,
        });
    }
    let touched = (0..rest_vertices.len() as u32)
        .filter(|&v| moved[v as usize])
        .collect();
    Ok(PoseModel { effects, touched })
}

impl PoseModel {
    /// Number of effects.
    pub(super) fn effect_count(&self) -> usize {
        self.effects.len()
    }

    /// Adds the pose-driven displacement at pose θ to `out` (one entry per template vertex,
    /// zero or holding earlier displacements), with the skinning transforms
    /// `world_from_rest` (one per joint, rigid) and the skin weights that blend their
    /// rotations. Linear in the effects' rest-space offsets, so effects add exactly.
    pub(super) fn add_displacement(
        &self,
        theta: &[f64],
        world_from_rest: &[DAffine3],
        weights: &SkinWeights,
        out: &mut [DVec3],
    ) {
        let mut rest = vec![DVec3::ZERO; out.len()];
        let mut active = false;
        for e in &self.effects {
            let a = e.activation(theta);
            if a == 0.0 {
                continue;
            }
            active = true;
            for &(v, d) in &e.vertices {
                rest[v as usize] += d * a;
            }
        }
        if !active {
            return;
        }
        // Joint rotations as quaternions, blended per vertex (sign-aligned, normalised).
        let rotations: Vec<DQuat> = world_from_rest
            .iter()
            .map(|t| DQuat::from_mat3(&t.matrix3))
            .collect();
        for &v in &self.touched {
            let v = v as usize;
            let d = rest[v];
            if d == DVec3::ZERO {
                continue;
            }
            let mut reference = None;
            let mut blend = DQuat::from_xyzw(0.0, 0.0, 0.0, 0.0);
            for (j, w) in weights.influences(v) {
                let q = rotations[j as usize];
                let r = *reference.get_or_insert(q);
                let aligned = if q.dot(r) < 0.0 { -q } else { q };
                blend += aligned * w;
            }
            let n = blend.length();
            let q = if n > 1e-9 {
                blend / n
            } else {
                reference.unwrap_or(DQuat::IDENTITY)
            };
            out[v] += q * d;
        }
    }
}

/// Far end of a joint's distal segment at rest: its end site, else the mean of its children.
fn distal_tip(skeleton: &Skeleton, frames: &[DAffine3], j: usize) -> DVec3 {
    if let Some(e) = skeleton.joints()[j].end_site {
        return frames[j].transform_point3(e);
    }
    let children: Vec<usize> = skeleton.children(j).collect();
    if children.is_empty() {
        frames[j].translation
    } else {
        children
            .iter()
            .map(|&c| frames[c].translation)
            .sum::<DVec3>()
            / children.len() as f64
    }
}

#[cfg(test)]
mod tests;
