//! The performer's known **non-skinning** deformation: what linear blend skinning (LBS) cannot
//! produce, so that ground truth differs from any skinned template and the methods (Vlasic
//! §2.4–2.5 molding, Sand 2003 needles) have something real to recover.
//!
//! Two effects are added to the LBS surface, each recorded separately in
//! [`PosedFrame`](super::PosedFrame):
//!
//! * **Pose-driven muscle and joint shapes** ([`DeformationParams::pose`], on by default):
//!   biceps, brachioradialis, deltoid, calf, hamstrings, trunk and joint-volume effects, a pure
//!   smooth function of θ ([`PoseDeformParams`], module `muscles`), in
//!   [`PosedFrame::pose_displacement`](super::PosedFrame::pose_displacement).
//! * **Hip flap** (dynamic, in
//!   [`PosedFrame::dynamic_displacement`](super::PosedFrame::dynamic_displacement)). A loose
//!   cloth-like band around the hips lags behind the body: `K` point
//!   masses spaced in azimuth around the pelvis each follow the skinned position of an anchor
//!   vertex of the band through a damped spring, `m ẍ = −k (x − T) − c (ẋ − Ṫ)` (second-order
//!   dynamics, integrated with backward Euler substeps, unconditionally stable and
//!   deterministic). A band vertex moves by the lag `x − T` of the two masses nearest in
//!   azimuth (linearly blended), scaled by a profile that is 0 at the waist and 1 at the hem,
//!   and saturated smoothly at [`FlapParams::max_lag_m`].
//!   The state ([`DeformationState`]) is explicit: the same inputs give the same frames.
//!
//! Until 0.2 a third effect, a hinge "bulge" of the upper arm and thigh linear in elbow and
//! knee flexion, stood in for muscles; the pose-driven biceps and hamstrings replace it (both
//! together counted those muscles twice).

use super::garment::{GarmentParams, GarmentState};
use super::muscles::{pose_model, PoseDeformParams, PoseModel};
use super::wrinkles::WrinkleParams;
use serde::{Deserialize, Serialize};
use skin_core::check::positive;
use skin_core::math::{DAffine3, DVec3};
use skin_core::mesh::SkinWeights;
use skin_core::skeleton::Skeleton;
use skin_core::{Error, Result};
use std::f64::consts::TAU;

/// Parameters of the hip flap's dynamics and extent.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FlapParams {
    /// Mass of each flap point, kg. Default: 0.2 (a fold of a skirt or coat tail).
    pub mass_kg: f64,
    /// Spring stiffness pulling each mass to its anchor, N/m. Default: 40 (with the default
    /// mass: natural frequency 14 rad/s ≈ 2.3 Hz, a loose fabric sway).
    pub stiffness_n_per_m: f64,
    /// Damping on the velocity relative to the anchor, N·s/m. Default: 1.0 (damping ratio
    /// ≈ 0.18: the flap visibly overshoots and settles in about a second).
    pub damping_n_s_per_m: f64,
    /// Number of masses around the hips. Default: 8.
    pub masses: usize,
    /// Height of the waist line (top of the band, no lag) above the pelvis joint at rest,
    /// metres. Default: 0.02.
    pub waist_above_pelvis_m: f64,
    /// Depth of the hem (full lag) below the pelvis joint at rest, metres. Default: 0.20.
    pub hem_below_pelvis_m: f64,
    /// Distance below the hem over which the lag fades to zero, metres. Default: 0.06.
    pub fade_m: f64,
    /// Joints whose skin weight makes a vertex part of the band (a vertex's share is its summed
    /// weight on them, so hands and arms resting near the hips stay out). Default: pelvis,
    /// spine, both hips.
    pub joints: Vec<String>,
    /// Largest displacement of the hem, metres: the lag `e` of a mass is shown as
    /// `e · L tanh(|e|/L) / |e|` (linear for small lags, saturating at `L`), as real fabric
    /// tethered to the hips cannot swing arbitrarily far. Default: 0.06.
    pub max_lag_m: f64,
    /// Longest integration substep, seconds. Default: 0.002.
    pub max_substep_s: f64,
}

impl Default for FlapParams {
    fn default() -> Self {
        FlapParams {
            mass_kg: 0.2,
            stiffness_n_per_m: 40.0,
            damping_n_s_per_m: 1.0,
            masses: 8,
            waist_above_pelvis_m: 0.02,
            hem_below_pelvis_m: 0.20,
            fade_m: 0.06,
            joints: ["pelvis", "spine", "l_hip", "r_hip"]
                .map(String::from)
                .to_vec(),
            max_lag_m: 0.06,
            max_substep_s: 0.002,
        }
    }
}

/// Parameters of the whole non-skinning deformation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DeformationParams {
    /// Hip flap; `None` disables it. Default: `Some(FlapParams::default())`.
    pub flap: Option<FlapParams>,
    /// Pose-driven muscle and joint shapes ([`PoseDeformParams`]); `None` disables them.
    /// Default: `Some(PoseDeformParams::default())`, the human body's effects.
    pub pose: Option<PoseDeformParams>,
    /// A loose garment with its own dynamics ([`GarmentParams`]: a skirt, or the "Ghost"
    /// sheet), appended to the template as its rest drape (the shape a scan at rest would
    /// show); `None`: no garment. Default: `None` (the needle and inertial validations use
    /// the body alone; template-silhouette and photometric-normals opt in). With a garment,
    /// switch the [`flap`](Self::flap) off: it is the skin-tight stand-in for loose clothing,
    /// and under a skirt it only distorts the thighs the skirt collides with.
    #[serde(default)]
    pub garment: Option<GarmentParams>,
    /// Render-time wrinkles ([`WrinkleParams`]: elbow and knee creases, garment folds) on a
    /// refined surface ([`Performer::fine_surface`](super::Performer::fine_surface)); `None`
    /// renders the template's own faces. Default: `None` (the silhouette methods need no
    /// millimetre folds, and the refined body takes several times longer to rasterise);
    /// the photometric validations switch it on.
    #[serde(default)]
    pub wrinkles: Option<WrinkleParams>,
}

impl Default for DeformationParams {
    fn default() -> Self {
        DeformationParams {
            flap: Some(FlapParams::default()),
            pose: Some(PoseDeformParams::default()),
            garment: None,
            wrinkles: None,
        }
    }
}

impl DeformationParams {
    /// No non-skinning deformation at all (ground truth equals LBS).
    pub fn none() -> Self {
        DeformationParams {
            flap: None,
            pose: None,
            garment: None,
            wrinkles: None,
        }
    }

    /// These parameters with the pose-driven deformation `pose` (`None`: off).
    pub fn with_pose(mut self, pose: Option<PoseDeformParams>) -> Self {
        self.pose = pose;
        self
    }

    /// These parameters with the garment `garment` (`None`: none).
    pub fn with_garment(mut self, garment: Option<GarmentParams>) -> Self {
        self.garment = garment;
        self
    }

    /// These parameters with the render-time wrinkles `wrinkles` (`None`: off).
    pub fn with_wrinkles(mut self, wrinkles: Option<WrinkleParams>) -> Self {
        self.wrinkles = wrinkles;
        self
    }

    /// These parameters with the hip flap `flap` (`None`: off).
    pub fn with_flap(mut self, flap: Option<FlapParams>) -> Self {
        self.flap = flap;
        self
    }
}

/// Precomputed hip flap.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct FlapModel {
    params: FlapParams,
    /// Anchor vertex of each mass.
    anchors: Vec<u32>,
    /// (vertex, mass a, mass b, blend towards b, profile weight).
    vertices: Vec<(u32, u32, u32, f64, f64)>,
}

/// The performer's non-skinning deformation, precomputed for one template and skeleton.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DeformationModel {
    flap: Option<FlapModel>,
    pose: Option<PoseModel>,
}

/// State of the deformation's dynamics across frames (the flap masses). Start from
/// `DeformationState::default()`: the first posed frame puts every mass at rest on its anchor.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct DeformationState {
    /// World position of each flap mass, metres (empty before the first frame).
    pub positions: Vec<DVec3>,
    /// World velocity of each flap mass, m/s.
    pub velocities: Vec<DVec3>,
    /// Anchor positions at the previous frame, metres.
    pub anchors: Vec<DVec3>,
    /// The garment's simulation state (empty without a garment or before the first frame).
    #[serde(default)]
    pub garment: GarmentState,
}

fn non_negative(name: &'static str, v: f64) -> Result<()> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(Error::InvalidParam {
            name,
            reason: format!("must be finite and non-negative, got {v}"),
        })
    }
}

fn joint_named(skeleton: &Skeleton, name: &str, what: &'static str) -> Result<usize> {
    skeleton
        .joint_index(name)
        .ok_or_else(|| Error::InvalidParam {
            name: what,
            reason: format!("the skeleton has no joint '{name}'"),
        })
}

fn smoothstep(x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

impl DeformationModel {
    /// Precomputes the deformation for a rest template (`rest_vertices`, metres, at θ = 0),
    /// its skeleton and skin weights (bones = joints).
    ///
    /// # Errors
    /// [`Error::InvalidParam`] for a flap joint name the skeleton lacks, a non-positive or
    /// non-finite parameter, or a pose effect's error (see [`PoseDeformParams`]);
    /// [`Error::SizeMismatch`] if `weights` and `rest_vertices` differ in length.
    pub fn new(
        params: &DeformationParams,
        skeleton: &Skeleton,
        rest_vertices: &[DVec3],
        weights: &SkinWeights,
    ) -> Result<Self> {
        if weights.vertex_count() != rest_vertices.len() {
            return Err(Error::SizeMismatch {
                what: "skin weights per vertex",
                expected: rest_vertices.len(),
                got: weights.vertex_count(),
            });
        }
        let rest = skeleton.forward_kinematics(&skeleton.rest_pose())?;
        let frames = rest.world_from_joint();
        let flap = match &params.flap {
            None => None,
            Some(fp) => flap_model(fp, skeleton, frames, rest_vertices, weights)?,
        };
        let pose = match &params.pose {
            None => None,
            Some(pp) => Some(pose_model(pp, skeleton, &rest, rest_vertices, weights)?),
        };
        Ok(DeformationModel { flap, pose })
    }

    /// Number of pose-driven effects (0 when the pose-driven deformation is off).
    pub fn pose_effect_count(&self) -> usize {
        self.pose.as_ref().map_or(0, PoseModel::effect_count)
    }

    /// Whether the pose-driven deformation is on.
    pub fn has_pose(&self) -> bool {
        self.pose.is_some()
    }

    /// The pose-driven displacement of every vertex at pose θ (zero vectors when it is off),
    /// with the skinning transforms `world_from_rest` (one per joint) and the performer's
    /// skin weights.
    pub(super) fn pose_displacement(
        &self,
        theta: &[f64],
        world_from_rest: &[DAffine3],
        weights: &SkinWeights,
    ) -> Vec<DVec3> {
        let mut out = vec![DVec3::ZERO; weights.vertex_count()];
        if let Some(p) = &self.pose {
            p.add_displacement(theta, world_from_rest, weights, &mut out);
        }
        out
    }

    /// Number of flap masses (0 when the flap is disabled or the template has no band).
    pub fn flap_mass_count(&self) -> usize {
        self.flap.as_ref().map_or(0, |f| f.anchors.len())
    }

    /// Advances the flap dynamics to the current frame (anchors read from the LBS positions
    /// `lbs`) and adds the flap's displacement to `out` (one entry per vertex). `dt_s` is the time since the previous frame; it is
    /// ignored on the first frame (empty `state`), which starts the masses at rest.
    ///
    /// # Errors
    /// [`Error::InvalidParam`] for a non-positive or non-finite `dt_s` after the first frame;
    /// [`Error::SizeMismatch`] for a state built for another performer.
    pub(super) fn add_flap(
        &self,
        lbs: &[DVec3],
        state: &mut DeformationState,
        dt_s: f64,
        out: &mut [DVec3],
    ) -> Result<()> {
        let Some(f) = &self.flap else { return Ok(()) };
        let targets: Vec<DVec3> = f.anchors.iter().map(|&a| lbs[a as usize]).collect();
        if state.positions.is_empty() {
            state.positions = targets.clone();
            state.velocities = vec![DVec3::ZERO; targets.len()];
            state.anchors = targets;
            return Ok(());
        }
        if state.positions.len() != targets.len()
            || state.velocities.len() != targets.len()
            || state.anchors.len() != targets.len()
        {
            return Err(Error::SizeMismatch {
                what: "deformation state (flap masses)",
                expected: targets.len(),
                got: state.positions.len(),
            });
        }
        positive("dt_s", dt_s)?;
        let p = &f.params;
        let steps = (dt_s / p.max_substep_s).ceil().max(1.0);
        let h = dt_s / steps;
        let (m, k, c) = (p.mass_kg, p.stiffness_n_per_m, p.damping_n_s_per_m);
        for (i, &t1) in targets.iter().enumerate() {
            let t0 = state.anchors[i];
            let t_dot = (t1 - t0) / dt_s;
            let (mut x, mut v) = (state.positions[i], state.velocities[i]);
            for s in 1..=steps as usize {
                let t = t0 + (t1 - t0) * (s as f64 / steps);
                // Backward Euler: v' (1 + h c/m + h² k/m) = v + h/m (−k (x − T') + c Ṫ).
                let denom = 1.0 + h * c / m + h * h * k / m;
                v = (v + (h / m) * (-k * (x - t) + c * t_dot)) / denom;
                x += h * v;
            }
            state.positions[i] = x;
            state.velocities[i] = v;
            state.anchors[i] = t1;
        }
        let limit = p.max_lag_m;
        let lags: Vec<DVec3> = state
            .positions
            .iter()
            .zip(&targets)
            .map(|(x, t)| {
                let e = *x - *t;
                let n = e.length();
                if n > 1e-15 {
                    e * (limit * (n / limit).tanh() / n)
                } else {
                    e
                }
            })
            .collect();
        for &(v, a, b, s, wgt) in &f.vertices {
            out[v as usize] += (lags[a as usize] * (1.0 - s) + lags[b as usize] * s) * wgt;
        }
        Ok(())
    }
}

fn flap_model(
    p: &FlapParams,
    skeleton: &Skeleton,
    frames: &[DAffine3],
    rest: &[DVec3],
    weights: &SkinWeights,
) -> Result<Option<FlapModel>> {
    positive("flap.mass_kg", p.mass_kg)?;
    positive("flap.stiffness_n_per_m", p.stiffness_n_per_m)?;
    non_negative("flap.damping_n_s_per_m", p.damping_n_s_per_m)?;
    positive("flap.max_substep_s", p.max_substep_s)?;
    positive("flap.max_lag_m", p.max_lag_m)?;
    positive(
        "flap.hem_below_pelvis_m + waist_above_pelvis_m",
        p.hem_below_pelvis_m + p.waist_above_pelvis_m,
    )?;
    non_negative("flap.fade_m", p.fade_m)?;
    if p.masses < 2 {
        return Err(Error::InvalidParam {
            name: "flap.masses",
            reason: format!("need at least 2 masses, got {}", p.masses),
        });
    }
    let root = skeleton.joint_index("pelvis").unwrap_or(0);
    let band_joints: Vec<usize> = p
        .joints
        .iter()
        .map(|n| joint_named(skeleton, n, "flap.joints"))
        .collect::<Result<_>>()?;
    let centre = frames[root].translation;
    let top = centre.y + p.waist_above_pelvis_m;
    let hem = centre.y - p.hem_below_pelvis_m;
    let sector = TAU / p.masses as f64;
    let mut vertices = Vec::new();
    let mut best: Vec<Option<(f64, u32)>> = vec![None; p.masses];
    for (v, x) in rest.iter().enumerate() {
        let share: f64 = weights
            .influences(v)
            .filter(|q| band_joints.contains(&(q.0 as usize)))
            .map(|q| q.1)
            .sum();
        let profile = if x.y >= hem {
            smoothstep((top - x.y) / (top - hem))
        } else if p.fade_m > 0.0 {
            1.0 - smoothstep((hem - x.y) / p.fade_m)
        } else {
            0.0
        };
        let wgt = share * profile;
        if wgt <= 1e-6 {
            continue;
        }
        let az = (x.x - centre.x).atan2(x.z - centre.z).rem_euclid(TAU);
        let pos = az / sector;
        let a = (pos.floor() as usize).min(p.masses - 1);
        let b = (a + 1) % p.masses;
        vertices.push((v as u32, a as u32, b as u32, pos - a as f64, wgt));
        // Anchor of mass k: the strongest band vertex closest in azimuth (score favours lag).
        for (k, slot) in best.iter_mut().enumerate() {
            let d = (az - k as f64 * sector).abs();
            let d = d.min(TAU - d);
            if d < 0.5 * sector {
                let score = wgt - d / sector;
                if slot.is_none_or(|(s, _)| score > s) {
                    *slot = Some((score, v as u32));
                }
            }
        }
    }
    if vertices.is_empty() || best.iter().any(Option::is_none) {
        log::warn!("template has no complete band around the hips; flap disabled");
        return Ok(None);
    }
    let anchors = best.into_iter().flatten().map(|(_, v)| v).collect();
    Ok(Some(FlapModel {
        params: p.clone(),
        anchors,
        vertices,
    }))
}
