//! Pose estimation: the skeleton fitted to the visual hull (Vlasic 2010 §2.3.1, §2.3.3).
//!
//! ```text
//! argmin_θ  w_D E_D(θ) + w_T E_T(θ) + w_R E_R(θ) + w_U E_U(θ),   θ within the joint limits
//! E_D = Σ_i γ(d(p_i(θ)) − r_i)                       bones deep in the hull (four samples/bone)
//! E_T = ‖θ − θ_{t−1}‖²  (forward)  or  + ‖θ − θ_{t+1}‖²  (backward pass)
//! E_R = Σ_j ‖q_j(θ) − (q_j(θ_0) + Δm_j)‖²            end effectors moved by shape estimation
//! E_U = Σ_u ‖(q_{j_u}(θ) − o_u) × r_u‖²               user rays
//! ```
//!
//! with `w_D = 5, w_T = 1, w_R = 500, w_U = 5000` (§2.3.1). The thesis minimised this with
//! SNOPT; here it is a bounded Levenberg–Marquardt ([`skin_core::optim::levenberg_marquardt_bounded`],
//! joint limits as the box) on residuals whose squares sum to the objective: `√(w_D γ)` for
//! each depth sample (γ is a sum of hinge terms, not of squares, so its square root is the
//! residual), `√w_T (θ − θ_{t±1})`, `√w_R (q_j − target_j)`, `√w_U (q_j − o) × r`. Every
//! Jacobian is analytic: skin-core's positional Jacobians of attached points, the visual-hull
//! distance gradient of [`crate::ContourRayHull::distance`], and γ′.
//!
//! **γ** is the softplus `γ(x) = s ln(1 + e^{−x/s})`: approximately `−x` for `x ≪ −s` and
//! approximately 0 for `x ≫ s`, smooth in between — the "smooth function that is approximately
//! −x when x is negative and approximately 0 when x is positive" of §2.3.1. The smoothing
//! width `s` is [`PoseParams::gamma_width_m`] (default 5 mm, about two pixels at 3 m with a
//! 1600-pixel-wide camera: below what the silhouettes resolve, wide enough that the
//! Gauss–Newton model of `√γ` stays good across a pixel).
//!
//! **Processing** (§2.3.3): frames in order, each initialised with the linear prediction
//! `2θ_{t−1} − θ_{t−2}` (the second frame with the first's solution, the first with the
//! caller's guess), then a reverse pass that starts each frame from its forward solution and
//! penalises deviation from both neighbours. With a [`ShapeEstimator`] the refinement term
//! is applied: an initial fit with `w_R = 0`, then twice one shape solve and a refit with the
//! end effectors pulled by `Δm_j`; the reverse pass reuses the forward pass's targets.

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};
use skin_core::math::{fit_similarity, Alignment, DVec3, Ray};
use skin_core::mesh::MeshQuery;
use skin_core::optim::{levenberg_marquardt_bounded, LmParams, LmReport};
use skin_core::skeleton::{AttachedPoint, ForwardKinematics, Skeleton};

use crate::error::{Context, Error, Result, ResultExt};
use crate::shape::ShapeEstimator;
use crate::silhouette_constraints::ContourRay;
use crate::template::Template;
use crate::visual_hull::ContourRayHull;

/// Bones shorter than this carry no depth samples, m (a joint at its parent's origin).
const MIN_BONE_LENGTH_M: f64 = 0.01;

/// Knobs of pose estimation (§2.3), the thesis' values by default.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PoseParams {
    /// `w_D`, 1/m. §2.3.1. Default: [`Self::DEFAULT_W_D`] = 5.
    pub w_d: f64,
    /// `w_T`, 1/rad² (and 1/m² on the root translation). §2.3.1. Default:
    /// [`Self::DEFAULT_W_T`] = 1.
    pub w_t: f64,
    /// `w_R`, 1/m². §2.3.1. Default: [`Self::DEFAULT_W_R`] = 500.
    pub w_r: f64,
    /// `w_U`, 1/m². §2.3.1. Default: [`Self::DEFAULT_W_U`] = 5000.
    pub w_u: f64,
    /// Depth samples per bone, evenly spaced at `(k + ½)/n` of its length. §2.3.1. Default:
    /// [`Self::DEFAULT_SAMPLES_PER_BONE`] = 4.
    pub samples_per_bone: usize,
    /// Smoothing width `s` of γ, m. Not in the thesis. Default: [`Self::DEFAULT_GAMMA_WIDTH_M`].
    pub gamma_width_m: f64,
    /// Rounds of (shape solve, refit with `E_R`). §2.3.1: twice. Default:
    /// [`Self::DEFAULT_REFINEMENT_ROUNDS`] = 2.
    pub refinement_rounds: usize,
    /// LBS weight from which a vertex belongs to an end effector's portion. Default:
    /// [`Self::DEFAULT_EFFECTOR_MIN_WEIGHT`] = 0.95.
    pub effector_min_weight: f64,
    /// What the refinement term pulls on each end effector. Default:
    /// [`Self::DEFAULT_EFFECTOR_TARGETS`] (the whole rigid frame; the thesis: the tip only).
    pub effector_targets: EffectorTargets,
    /// The optimiser's stopping rules. Default: 100 iterations, relative cost change 1e-6
    /// (a pose is settled well before; the thesis re-optimises "several times per second").
    pub lm: LmParams,
}

impl Default for PoseParams {
    fn default() -> Self {
        let mut lm = LmParams::default().with_max_iterations(100);
        lm.cost_tolerance = 1e-6;
        lm.step_tolerance = 1e-6;
        PoseParams {
            w_d: Self::DEFAULT_W_D,
            w_t: Self::DEFAULT_W_T,
            w_r: Self::DEFAULT_W_R,
            w_u: Self::DEFAULT_W_U,
            samples_per_bone: Self::DEFAULT_SAMPLES_PER_BONE,
            gamma_width_m: Self::DEFAULT_GAMMA_WIDTH_M,
            refinement_rounds: Self::DEFAULT_REFINEMENT_ROUNDS,
            effector_min_weight: Self::DEFAULT_EFFECTOR_MIN_WEIGHT,
            effector_targets: Self::DEFAULT_EFFECTOR_TARGETS,
            lm,
        }
    }
}

impl PoseParams {
    /// Default weight of the depth term (§2.3.1: `w_D = 5`, 1/m).
    pub const DEFAULT_W_D: f64 = 5.0;

    /// Default weight of the temporal term (§2.3.1: `w_T = 1`, 1/rad²).
    pub const DEFAULT_W_T: f64 = 1.0;

    /// Default weight of the refinement term (§2.3.1: `w_R = 500`, 1/m²).
    pub const DEFAULT_W_R: f64 = 500.0;

    /// Default weight of the user term (§2.3.1: `w_U = 5000`, 1/m²).
    pub const DEFAULT_W_U: f64 = 5000.0;

    /// Default number of depth samples per bone (§2.3.1: "four evenly spaced samples per bone").
    pub const DEFAULT_SAMPLES_PER_BONE: usize = 4;

    /// Default smoothing width of γ, m (not in the thesis; see the module docs).
    pub const DEFAULT_GAMMA_WIDTH_M: f64 = 0.005;

    /// Default number of refinement rounds (§2.3.1: "We repeat this process twice").
    pub const DEFAULT_REFINEMENT_ROUNDS: usize = 2;

    /// Default LBS weight from which a vertex belongs to an end effector's rigid portion
    /// (§2.3.1 "nearly rigidly bound"; the 0.95 of §2.4.2's nearly-rigid vertices).
    pub const DEFAULT_EFFECTOR_MIN_WEIGHT: f64 = 0.95;

    /// Default handling of end effectors in `E_R`: their whole rigid frame (ours; see
    /// [`EffectorTargets`]).
    pub const DEFAULT_EFFECTOR_TARGETS: EffectorTargets =
        EffectorTargets::RigidFrame { max_roundness: 0.5 };

    /// Sets [`Self::refinement_rounds`].
    pub fn with_refinement_rounds(mut self, rounds: usize) -> Self {
        self.refinement_rounds = rounds;
        self
    }

    /// Sets [`Self::effector_targets`].
    pub fn with_effector_targets(mut self, targets: EffectorTargets) -> Self {
        self.effector_targets = targets;
        self
    }

    fn validate(&self) -> Result<()> {
        for (name, w) in [
            ("w_d", self.w_d),
            ("w_t", self.w_t),
            ("w_r", self.w_r),
            ("w_u", self.w_u),
        ] {
            skin_core::check::non_negative(name, w)?;
        }
        skin_core::check::nonzero("samples_per_bone", self.samples_per_bone)?;
        skin_core::check::positive("gamma_width_m", self.gamma_width_m)?;
        skin_core::check::in_range("effector_min_weight", self.effector_min_weight, 0.5..=1.0)?;
        if let EffectorTargets::RigidFrame { max_roundness } = self.effector_targets {
            skin_core::check::in_range("max_roundness", max_roundness, 0.0..=1.0)?;
        }
        Ok(())
    }
}

/// What the refinement term `E_R` (§2.3.1) pulls on each end effector (hand, foot, head).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum EffectorTargets {
    /// The thesis: the effector's tip is translated by `Δm_j`, the shift of the centre of
    /// mass of its nearly-rigid vertices in the shape solve. This fixes where a hand, foot
    /// or head is but not how it is turned about its bone: the depth term cannot see that
    /// either (a limb's samples lie on its axis), so only the temporal term holds a
    /// forearm's or neck's twist, and it drifts.
    Tip,
    /// Ours: the rigid motion (Kabsch) that best maps the effector's nearly-rigid vertices
    /// from the skinned mesh to the shape solve's mesh moves three points of the effector —
    /// its tip and two points half a bone length off its axis, at right angles — so `E_R`
    /// also turns the effector about its bone as the silhouettes show it. Only effectors
    /// whose [`Effector::roundness`] is at most `max_roundness` get their frame; the others
    /// (and an effector whose rigid vertices are collinear) keep the thesis' tip rule.
    ///
    /// The default gate 0.5 takes MakeHuman's flat hands (roundness 0.10) and feet (0.43)
    /// and leaves its head (0.89), whose twist hardly changes the silhouettes of a near-round
    /// skull, so that the shape solve's turn of it is noise (pulling it made the head worse:
    /// 52° against 33° at 1600 × 1200). Measured on the studio exercise, 8 cameras at
    /// 800 × 600, six 50-frame tracks from frames 65, 115, …, 315 (mean over tracks; a hand
    /// is lost when its wrist ends more than 4 cm off): tip rule — joints 21.1 mm, hands
    /// 35° off, ankles 8.3°, 2 hands lost; hands' and feet's frames (0.5) — 16.6 mm, 16°,
    /// 7.6°, 1 hand lost; hands' frames only (0.3) — 22.8 mm, 35°, 4 hands lost: pulling
    /// the hands alone while the feet may turn freely destabilises the legs' and pelvis'
    /// twist, and the whole track with them.
    RigidFrame {
        /// Largest [`Effector::roundness`] whose frame is pulled.
        max_roundness: f64,
    },
}

/// A user constraint (§2.3.1, `E_U`): joint `joint` must lie on `ray` (e.g. the ray of the
/// pixel the user dragged it to in one camera; two views fix it completely).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct UserRay {
    /// Joint index.
    pub joint: usize,
    /// The ray, world m, unit direction.
    pub ray: Ray,
}

/// A refinement target (§2.3.1, `E_R`): an end effector pulled to `target`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct JointTarget {
    /// The end effector: a point on a bone (the joint itself has a zero offset).
    pub point: AttachedPoint,
    /// Target position, world m.
    pub target: DVec3,
}

/// The skeleton's depth samples with their template radii (§2.3.1), and the end effectors.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PoseModel {
    skeleton: Skeleton,
    samples: Vec<AttachedPoint>,
    radii_m: Vec<f64>,
    outside: Vec<usize>,
    effectors: Vec<Effector>,
}

/// An end effector of the refinement term (§2.3.1): a leaf bone's tip and the vertices
/// nearly rigidly bound to its joint.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Effector {
    /// The tip (the leaf joint's end site, or the joint itself without one).
    pub tip: AttachedPoint,
    /// The nearly-rigid vertices (LBS weight ≥ [`PoseParams::effector_min_weight`]).
    pub vertices: Vec<usize>,
    /// How round the rigid portion's cross-section about the bone is in the rest pose: the
    /// ratio of the smaller to the larger principal variance of the vertices projected on
    /// the plane normal to the bone, in [0, 1] (a flat hand about 0.1, a head about 0.9).
    /// A turn about the bone changes the silhouettes only when this is well below 1.
    pub roundness: f64,
}

impl PoseModel {
    /// Places `samples_per_bone` samples on every bone (parent origin → child origin, and
    /// joint origin → end site) and measures each sample's distance `r_i` to the template
    /// surface in the rest pose. Samples outside the template (a skeleton partly outside its
    /// mesh) get `r_i = 0`: they are only asked to stay inside the hull; they are listed by
    /// [`Self::outside_samples`] and logged. End effectors are the joints without children
    /// (hands, feet, head) that have nearly-rigid vertices.
    ///
    /// # Errors
    /// [`Error::InvalidParam`] for bad params; [`Error::Empty`] for a skeleton without bones;
    /// errors of the template's BVH.
    pub fn new(template: &Template, params: &PoseParams) -> Result<Self> {
        params.validate()?;
        let skeleton = template.skeleton().clone();
        let n = params.samples_per_bone;
        let mut samples = Vec::new();
        for (j, joint) in skeleton.joints().iter().enumerate() {
            let mut bone = |owner: usize, tip: DVec3| {
                if tip.length() >= MIN_BONE_LENGTH_M {
                    for k in 0..n {
                        samples.push(AttachedPoint {
                            joint: owner,
                            offset: tip * ((k as f64 + 0.5) / n as f64),
                        });
                    }
                }
            };
            if let Some(p) = joint.parent {
                bone(p, joint.offset);
            }
            if let Some(tip) = joint.end_site {
                bone(j, tip);
            }
        }
        if samples.is_empty() {
            return Err(Error::Empty {
                what: "skeleton bones (no bone longer than 1 cm: give a skeleton in metres)",
            });
        }
        let rest = skeleton.forward_kinematics(&skeleton.rest_pose())?;
        let query = MeshQuery::new(template.mesh())?;
        let mut radii_m = Vec::with_capacity(samples.len());
        let mut outside = Vec::new();
        for (i, s) in samples.iter().enumerate() {
            let p = rest.point(s)?;
            if query.contains(p)? {
                radii_m.push(query.closest_point(p)?.distance);
            } else {
                radii_m.push(0.0);
                outside.push(i);
            }
        }
        if !outside.is_empty() {
            log::warn!(
                "{} of {} bone samples lie outside the template; they only need to stay \
                 inside the visual hull",
                outside.len(),
                samples.len()
            );
        }
        let effectors = (0..skeleton.joint_count())
            .filter(|&j| skeleton.children(j).next().is_none())
            .filter_map(|j| {
                let verts: Vec<usize> = template
                    .nearly_rigid(params.effector_min_weight)
                    .into_iter()
                    .filter(|&(_, b)| b == j)
                    .map(|(v, _)| v)
                    .collect();
                // The effector is the leaf bone's tip (its end site: the top of the head,
                // the hand's or foot's end), which the thesis pulls "into the extremities";
                // a joint without end site is its own effector.
                let tip = AttachedPoint {
                    joint: j,
                    offset: skeleton.joints()[j].end_site.unwrap_or(DVec3::ZERO),
                };
                (!verts.is_empty()).then(|| {
                    let axis = rest.world_from_joint()[j].transform_vector3(tip.offset);
                    let roundness =
                        cross_section_roundness(&template.mesh().vertices, &verts, axis);
                    Effector {
                        tip,
                        vertices: verts,
                        roundness,
                    }
                })
            })
            .collect();
        Ok(PoseModel {
            skeleton,
            samples,
            radii_m,
            outside,
            effectors,
        })
    }

    /// The skeleton.
    pub fn skeleton(&self) -> &Skeleton {
        &self.skeleton
    }

    /// The depth samples (points attached to bones).
    pub fn samples(&self) -> &[AttachedPoint] {
        &self.samples
    }

    /// Template radius `r_i` of each sample, m.
    pub fn radii_m(&self) -> &[f64] {
        &self.radii_m
    }

    /// Indices of samples that lie outside the template (radius 0).
    pub fn outside_samples(&self) -> &[usize] {
        &self.outside
    }

    /// End effectors (the tip of each leaf bone) and the vertices nearly rigidly bound to
    /// their joint.
    pub fn effectors(&self) -> &[Effector] {
        &self.effectors
    }
}

/// [`Effector::roundness`] of `verts` about `axis` (1 for an axis of zero length, or fewer
/// than two vertices: nothing to turn).
fn cross_section_roundness(points: &[DVec3], verts: &[usize], axis: DVec3) -> f64 {
    let Some(axis) = axis.try_normalize() else {
        return 1.0;
    };
    if verts.len() < 2 {
        return 1.0;
    }
    let (e1, e2) = axis.any_orthonormal_pair();
    let c = verts.iter().map(|&v| points[v]).sum::<DVec3>() / verts.len() as f64;
    let (mut a, mut b, mut d) = (0.0, 0.0, 0.0);
    for &v in verts {
        let p = points[v] - c;
        let (x, y) = (p.dot(e1), p.dot(e2));
        a += x * x;
        b += x * y;
        d += y * y;
    }
    let half_trace = 0.5 * (a + d);
    let disc = (0.25 * (a - d) * (a - d) + b * b).sqrt();
    let (large, small) = (half_trace + disc, (half_trace - disc).max(0.0));
    if large > 0.0 {
        small / large
    } else {
        1.0
    }
}

/// `γ(x) = s ln(1 + e^{−x/s})` and `γ′(x)`, evaluated without overflow.
fn gamma(x: f64, s: f64) -> (f64, f64) {
    let z = -x / s;
    // ln(1 + e^z) = max(z, 0) + ln(1 + e^{−|z|}).
    let value = s * (z.max(0.0) + (-z.abs()).exp().ln_1p());
    // γ′ = −σ(z) = −1 / (1 + e^{−z}).
    let slope = -1.0 / (1.0 + (-z).exp());
    (value, slope)
}

/// Temporal neighbours of a frame for `E_T`.
#[derive(Debug, Clone, Copy, Default)]
pub struct Temporal<'a> {
    /// θ_{t−1}, if any.
    pub previous: Option<&'a [f64]>,
    /// θ_{t+1}, if any (reverse pass).
    pub next: Option<&'a [f64]>,
}

/// What one frame's objective sees.
#[derive(Debug, Clone, Copy)]
pub struct PoseTerms<'a> {
    /// The frame's visual hull (`E_D`).
    pub hull: &'a ContourRayHull,
    /// Temporal neighbours (`E_T`).
    pub temporal: Temporal<'a>,
    /// Refinement targets (`E_R`).
    pub refinement: &'a [JointTarget],
    /// User rays (`E_U`).
    pub user: &'a [UserRay],
}

/// The solution of one frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PoseFit {
    /// The pose θ.
    pub theta: Vec<f64>,
    /// The optimiser's final report (cost is ½ of the weighted objective).
    pub report: LmReport,
}

/// Fits θ for one frame from `theta0` (§2.3.1) by bounded Levenberg–Marquardt with the
/// joint limits as bounds.
///
/// # Errors
/// [`Error::SizeMismatch`] for poses of another skeleton; [`Error::IndexOutOfRange`] for a
/// joint index of a refinement target or user ray; errors of the hull and the optimiser.
pub fn fit_pose(
    model: &PoseModel,
    terms: &PoseTerms<'_>,
    theta0: &[f64],
    params: &PoseParams,
) -> Result<PoseFit> {
    params.validate()?;
    let sk = &model.skeleton;
    sk.check_pose("initial pose", theta0)?;
    for t in [terms.temporal.previous, terms.temporal.next]
        .into_iter()
        .flatten()
    {
        sk.check_pose("temporal neighbour pose", t)?;
    }
    let joints = sk.joint_count();
    let joint_points: Vec<AttachedPoint> = terms
        .refinement
        .iter()
        .map(|r| r.point)
        .chain(terms.user.iter().map(|u| AttachedPoint {
            joint: u.joint,
            offset: DVec3::ZERO,
        }))
        .collect();
    for p in &joint_points {
        skin_core::check::index("constraint joint", p.joint, joints)?;
    }
    let (lower, upper) = bounds(sk);
    let x0 = DVector::from_column_slice(theta0);
    let report = levenberg_marquardt_bounded(
        &x0,
        &lower,
        &upper,
        &params.lm,
        |x| residuals(model, terms, &joint_points, params, x.as_slice(), None),
        |x| {
            let mut j = DMatrix::zeros(0, 0);
            residuals(
                model,
                terms,
                &joint_points,
                params,
                x.as_slice(),
                Some(&mut j),
            )?;
            Ok(j)
        },
    )?;
    Ok(PoseFit {
        theta: report.x.as_slice().to_vec(),
        report,
    })
}

/// The residuals of §2.3.1 at θ (their squares sum to the weighted objective) and, when
/// `jac` is given, their analytic Jacobian (resized to residuals × DOFs).
fn residuals(
    model: &PoseModel,
    terms: &PoseTerms<'_>,
    joint_points: &[AttachedPoint],
    params: &PoseParams,
    theta: &[f64],
    jac: Option<&mut DMatrix<f64>>,
) -> skin_core::Result<DVector<f64>> {
    let sk = &model.skeleton;
    let n = sk.dof_count();
    let sqrt = |w: f64| w.sqrt();
    let s = params.gamma_width_m;
    let fk: ForwardKinematics = sk.forward_kinematics(theta)?;
    let ns = model.samples.len();
    let nt = [terms.temporal.previous, terms.temporal.next]
        .iter()
        .flatten()
        .count();
    let m = ns + nt * n + 3 * joint_points.len();
    let mut r = DVector::zeros(m);
    let pj = jac
        .as_ref()
        .map(|_| sk.point_jacobians(&fk, &model.samples))
        .transpose()?;
    let qj = jac
        .as_ref()
        .map(|_| sk.point_jacobians(&fk, joint_points))
        .transpose()?;
    let mut jm = jac;
    if let Some(j) = jm.as_deref_mut() {
        *j = DMatrix::zeros(m, n);
    }
    // E_D: √(w_D γ(d(p_i) − r_i)).
    for (i, (sample, r_i)) in model.samples.iter().zip(&model.radii_m).enumerate() {
        let p = fk.point(sample)?;
        let d = terms.hull.distance_core(p)?;
        let (g, dg) = gamma(d.signed_m - r_i, s);
        let rho = (params.w_d * g).sqrt();
        r[i] = rho;
        if let (Some(j), Some(pj)) = (jm.as_deref_mut(), pj.as_ref()) {
            if rho > f64::MIN_POSITIVE {
                let f = params.w_d * dg / (2.0 * rho);
                for c in 0..n {
                    let col = DVec3::new(pj[(3 * i, c)], pj[(3 * i + 1, c)], pj[(3 * i + 2, c)]);
                    j[(i, c)] = f * d.gradient.dot(col);
                }
            }
        }
    }
    // E_T: √w_T (θ − θ_neighbour).
    let mut row = ns;
    for nb in [terms.temporal.previous, terms.temporal.next]
        .into_iter()
        .flatten()
    {
        for c in 0..n {
            r[row + c] = sqrt(params.w_t) * (theta[c] - nb[c]);
            if let Some(j) = jm.as_deref_mut() {
                j[(row + c, c)] = sqrt(params.w_t);
            }
        }
        row += n;
    }
    // E_R: √w_R (q_j − target); E_U: √w_U (q_j − o) × r.
    for (k, point) in joint_points.iter().enumerate() {
        let q = fk.point(point)?;
        let (res, w, cross_dir) = if k < terms.refinement.len() {
            (q - terms.refinement[k].target, params.w_r, None)
        } else {
            let u = &terms.user[k - terms.refinement.len()];
            (
                (q - u.ray.origin).cross(u.ray.direction),
                params.w_u,
                Some(u.ray.direction),
            )
        };
        let sw = sqrt(w);
        for a in 0..3 {
            r[row + a] = sw * res[a];
        }
        if let (Some(j), Some(qj)) = (jm.as_deref_mut(), qj.as_ref()) {
            for c in 0..n {
                let col = DVec3::new(qj[(3 * k, c)], qj[(3 * k + 1, c)], qj[(3 * k + 2, c)]);
                let dcol = match cross_dir {
                    None => col,
                    Some(dir) => col.cross(dir),
                };
                for a in 0..3 {
                    j[(row + a, c)] = sw * dcol[a];
                }
            }
        }
        row += 3;
    }
    Ok(r)
}

/// Joint limits as boxes (unlimited DOFs: ±∞).
fn bounds(sk: &Skeleton) -> (DVector<f64>, DVector<f64>) {
    let n = sk.dof_count();
    let mut lo = DVector::from_element(n, f64::NEG_INFINITY);
    let mut hi = DVector::from_element(n, f64::INFINITY);
    for (d, dof) in sk.dofs().enumerate() {
        if let Some(l) = dof.limits {
            lo[d] = l.min;
            hi[d] = l.max;
        }
    }
    (lo, hi)
}

/// One frame of a tracked sequence.
#[derive(Debug, Clone, Copy)]
pub struct PoseFrame<'a> {
    /// The frame's visual hull.
    pub hull: &'a ContourRayHull,
    /// The frame's contour rays (for the refinement term's shape solve; may be empty when no
    /// shape estimator is given).
    pub rays: &'a [ContourRay],
    /// User rays of the frame (forward pass only, as in §2.3.3).
    pub user: &'a [UserRay],
}

/// Poses of a sequence after both passes (§2.3.3).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PoseTrack {
    /// Forward-pass poses, per frame.
    pub forward: Vec<Vec<f64>>,
    /// Final (reverse-pass) poses, per frame.
    pub poses: Vec<Vec<f64>>,
    /// Per frame, the user rays a [`FrameCorrector`] added during the forward pass (empty
    /// lists from [`track`]).
    #[serde(default)]
    pub added_user_rays: Vec<Vec<UserRay>>,
}

/// Pose estimation of one frame with the refinement of §2.3.1: fit with `w_R = 0`; then,
/// with a shape estimator, `refinement_rounds` times: one full-detail shape solve (Eq. 2.2,
/// `w_L = 1`, from the LBS mesh), the shift `Δm_j` of each end effector's rigid portion, and
/// a refit with `E_R`. The first iteration of Algorithm 1 (`w_L = 0`) would smooth a hand
/// away; the full-detail solve moves the template's vertices onto the contours while keeping
/// the hand's shape, so the shift of its centre of mass measures the pose error.
///
/// # Errors
/// As [`fit_pose`] and [`ShapeEstimator::refine`].
pub fn fit_frame(
    model: &PoseModel,
    frame: &PoseFrame<'_>,
    temporal: Temporal<'_>,
    theta0: &[f64],
    shape: Option<&mut ShapeEstimator>,
    params: &PoseParams,
) -> Result<FrameFit> {
    let terms = PoseTerms {
        hull: frame.hull,
        temporal,
        refinement: &[],
        user: frame.user,
    };
    let mut fit = fit_pose(model, &terms, theta0, params)?;
    let mut refinement = Vec::new();
    let Some(shape) = shape else {
        return Ok(FrameFit { fit, refinement });
    };
    if params.w_r == 0.0 || model.effectors.is_empty() {
        return Ok(FrameFit { fit, refinement });
    }
    for _ in 0..params.refinement_rounds {
        let theta0 = fit.theta.clone();
        let lbs = shape.template().skin(&theta0)?;
        let (moved, _) = shape.refine(&theta0, &lbs, 1.0, frame.rays)?;
        let fk = model.skeleton.forward_kinematics(&theta0)?;
        let mut targets = Vec::new();
        for effector in &model.effectors {
            effector_targets(&fk, effector, (&lbs, &moved), params, &mut targets)?;
        }
        let refined = PoseTerms {
            refinement: &targets,
            ..terms
        };
        fit = fit_pose(model, &refined, &theta0, params)?;
        refinement = targets;
    }
    Ok(FrameFit { fit, refinement })
}

/// The `E_R` targets of one end effector after a shape solve moved the skinned vertices
/// `lbs` to `moved` (see [`EffectorTargets`]).
fn effector_targets(
    fk: &ForwardKinematics,
    effector: &Effector,
    (lbs, moved): (&[DVec3], &[DVec3]),
    params: &PoseParams,
    out: &mut Vec<JointTarget>,
) -> Result<()> {
    let (tip, verts) = (effector.tip, &effector.vertices);
    let dm: DVec3 = verts.iter().map(|&v| moved[v] - lbs[v]).sum::<DVec3>() / verts.len() as f64;
    let translated = |out: &mut Vec<JointTarget>| -> Result<()> {
        out.push(JointTarget {
            point: tip,
            target: fk.point(&tip)? + dm,
        });
        Ok(())
    };
    let frame = match params.effector_targets {
        EffectorTargets::Tip => false,
        EffectorTargets::RigidFrame { max_roundness } => effector.roundness <= max_roundness,
    };
    if !frame {
        return translated(out);
    }
    let from: Vec<DVec3> = verts.iter().map(|&v| lbs[v]).collect();
    let to: Vec<DVec3> = verts.iter().map(|&v| moved[v]).collect();
    let Ok(motion) = fit_similarity(&from, &to, None, Alignment::Rigid) else {
        return translated(out);
    };
    // Two points half a bone length off the axis, at right angles to it and to each other
    // (the bone runs from the joint to the tip; a tip at the joint has no axis to turn about).
    let axis = tip.offset;
    let half = 0.5 * axis.length();
    if half < MIN_BONE_LENGTH_M {
        return translated(out);
    }
    let (side, up) = axis.normalize().any_orthonormal_pair();
    for offset in [axis, axis + half * side, axis + half * up] {
        let point = AttachedPoint {
            joint: tip.joint,
            offset,
        };
        out.push(JointTarget {
            point,
            target: motion.apply(fk.point(&point)?),
        });
    }
    Ok(())
}

/// One frame's fit by [`fit_frame`] with the refinement targets of its last round.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrameFit {
    /// The solution.
    pub fit: PoseFit,
    /// The `E_R` targets the solution was refitted with (empty without refinement).
    pub refinement: Vec<JointTarget>,
}

/// Someone who watches the forward pass and fixes frames (§2.3.3, Figure 2-4): after each
/// frame's fit, [`FrameCorrector::correct`] sees the pose and returns the user rays to add to
/// that frame (none: the frame is accepted). The frame is re-fitted with them and shown
/// again, at most [`MAX_CORRECTION_ROUNDS`] times, before tracking goes on from it.
///
/// Any `FnMut(usize, &[f64]) -> Vec<UserRay>` is a corrector.
pub trait FrameCorrector {
    /// The user rays to add to frame `t`, whose current forward-pass pose is `theta`.
    fn correct(&mut self, t: usize, theta: &[f64]) -> Vec<UserRay>;
}

impl<F: FnMut(usize, &[f64]) -> Vec<UserRay>> FrameCorrector for F {
    fn correct(&mut self, t: usize, theta: &[f64]) -> Vec<UserRay> {
        self(t, theta)
    }
}

/// How many times [`track_corrected`] shows a frame to its corrector: the thesis's user
/// re-checks a frame after each constraint; three rounds bound a corrector that is never
/// satisfied.
pub const MAX_CORRECTION_ROUNDS: usize = 3;

/// Tracks a sequence (§2.3.3): the forward pass from `first_guess` with the linear
/// prediction `2θ_{t−1} − θ_{t−2}` (clamped to the joint limits), then the reverse pass from
/// the forward solutions with both temporal neighbours. `first_guess` stands for the user's
/// fit of the first frame and is that frame's temporal neighbour in the forward pass. The
/// reverse pass reuses each frame's refinement targets from the forward pass instead of new
/// shape solves (§2.5.2: the backward pass is cheaper, "some computations are reused").
///
/// # Errors
/// [`Error::Empty`] for no frame; errors of [`fit_frame`] wrapped with the frame.
pub fn track(
    model: &PoseModel,
    frames: &[PoseFrame<'_>],
    first_guess: &[f64],
    shape: Option<&mut ShapeEstimator>,
    params: &PoseParams,
) -> Result<PoseTrack> {
    let mut accept = |_: usize, _: &[f64]| Vec::new();
    track_corrected(model, frames, first_guess, shape, params, &mut accept)
}

/// [`track`] with a user who fixes frames during the forward pass (§2.3.3): each frame's fit
/// is shown to `corrector`; the rays it returns join the frame's own user rays, the frame is
/// re-fitted from its pose with them (and shown again, at most [`MAX_CORRECTION_ROUNDS`]
/// times), and the forward pass goes on from the corrected pose. The reverse pass keeps every
/// frame's rays. [`PoseTrack::added_user_rays`] lists what the corrector added.
///
/// # Errors
/// As [`track`]; [`Error::IndexOutOfRange`] for a ray on a joint the skeleton does not have
/// and [`Error::NonFinite`] for a ray with NaN or infinite values or a zero direction, each
/// wrapped with the frame.
pub fn track_corrected(
    model: &PoseModel,
    frames: &[PoseFrame<'_>],
    first_guess: &[f64],
    mut shape: Option<&mut ShapeEstimator>,
    params: &PoseParams,
    corrector: &mut dyn FrameCorrector,
) -> Result<PoseTrack> {
    if frames.is_empty() {
        return Err(Error::Empty {
            what: "frames (one observation each)",
        });
    }
    let sk = &model.skeleton;
    let mut forward: Vec<Vec<f64>> = Vec::with_capacity(frames.len());
    let mut targets: Vec<Vec<JointTarget>> = Vec::with_capacity(frames.len());
    let mut added: Vec<Vec<UserRay>> = vec![Vec::new(); frames.len()];
    let mut user: Vec<Vec<UserRay>> = Vec::with_capacity(frames.len());
    for (t, frame) in frames.iter().enumerate() {
        let guess = match t {
            0 => first_guess.to_vec(),
            1 => forward[0].clone(),
            _ => {
                let mut g: Vec<f64> = forward[t - 1]
                    .iter()
                    .zip(&forward[t - 2])
                    .map(|(a, b)| 2.0 * a - b)
                    .collect();
                sk.clamp_to_limits(&mut g)?;
                g
            }
        };
        let temporal = Temporal {
            // Frame 0: the first guess is the user's fit of the first frame (§2.3.3: "the
            // first frame ... needs manual constraints"), so it anchors E_T there too;
            // otherwise DOFs the hull does not see (a head's twist) drift from it.
            previous: Some(forward.last().map_or(first_guess, Vec::as_slice)),
            next: None,
        };
        let mut rays = frame.user.to_vec();
        let mut done = fit_frame(model, frame, temporal, &guess, shape.as_deref_mut(), params)
            .at(Context::Frame(t))?;
        for _ in 0..MAX_CORRECTION_ROUNDS {
            let fix = corrector.correct(t, &done.fit.theta);
            if fix.is_empty() {
                break;
            }
            for ray in fix {
                let ray = checked_user_ray(sk, ray).at(Context::Frame(t))?;
                rays.push(ray);
                added[t].push(ray);
            }
            let corrected = PoseFrame {
                user: &rays,
                ..*frame
            };
            let start = done.fit.theta.clone();
            done = fit_frame(
                model,
                &corrected,
                temporal,
                &start,
                shape.as_deref_mut(),
                params,
            )
            .at(Context::Frame(t))?;
        }
        forward.push(done.fit.theta);
        targets.push(done.refinement);
        user.push(rays);
    }
    let mut poses = forward.clone();
    for t in (0..frames.len()).rev() {
        // User rays stay in their frame's objective; none are added (§2.3.3).
        let frame = frames[t];
        let (prev, next) = (
            t.checked_sub(1).map(|p| poses[p].clone()),
            poses.get(t + 1).cloned(),
        );
        let temporal = Temporal {
            previous: prev.as_deref(),
            next: next.as_deref(),
        };
        let terms = PoseTerms {
            hull: frame.hull,
            temporal,
            refinement: &targets[t],
            user: &user[t],
        };
        let fit = fit_pose(model, &terms, &forward[t], params).at(Context::Frame(t))?;
        poses[t] = fit.theta;
    }
    Ok(PoseTrack {
        forward,
        poses,
        added_user_rays: added,
    })
}

/// `ray` checked (a joint of `sk`, finite, non-zero direction) with its direction normalised.
pub(crate) fn checked_user_ray(sk: &Skeleton, mut ray: UserRay) -> Result<UserRay> {
    skin_core::check::index("joint", ray.joint, sk.joint_count())?;
    if !(ray.ray.origin.is_finite()
        && ray.ray.direction.is_finite()
        && ray.ray.direction.length() > 0.0)
    {
        return Err(Error::NonFinite {
            what: "user ray (give a finite origin and a finite, non-zero direction)",
        });
    }
    ray.ray.direction = ray.ray.direction.normalize();
    Ok(ray)
}

#[cfg(test)]
pub(crate) mod tests;
