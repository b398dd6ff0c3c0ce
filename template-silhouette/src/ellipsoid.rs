//! Articulated ellipsoid fitting after Fua, Gruen, Plänkers, D'Apuzzo, Thalmann, *Human Body
//! Modeling and Motion Analysis from Video Sequences* (paper `003_…`, §4.2 and §5).
//!
//! **Model (§4.2, Eq. 3).** The skeleton's DOFs θ, a length scale `s_b` per bone (the
//! variable coefficient `q` of `D_ini = (RX + qT)`, §4.2.1) and one ellipsoid per bone,
//! centred on the bone, symmetric about it: in the frame of the bone's parent joint `p`, with
//! `a` the unit bone direction, `z = u·a` and `ρ² = |u|² − z²`,
//! `F(u) = ρ²/w² + (z − l)²/h² − 1`, `l = s_b·L_b/2` (half the bone length, `L_b` the
//! default skeleton's; the centre), `w` the half-width (`part_w`) and `h` the ellipsoid's
//! half-length. Eq. 3 ties `h = l`; we keep `h` as its own unknown (the brief's "half-length
//! and half-width unknowns"), held near its start by a prior
//! ([`EllipsoidParams::sigma_half_length_prior_m`]). Measured on the studio (a limb's surface
//! reaches both joints with non-zero radius, unlike Eq. 3's ellipsoid): with `h = l` tied
//! the fit lowers its cost by lengthening the upper bones to the scale bound while their
//! children shrink; with `h` free of a strong prior the ellipsoids grow into long cylinders.
//! A bone's length is then observable where its chain bends (the joint is where two bone
//! axes meet), hence [`fit_ellipsoids_multi`] over frames of a motion; the length of a
//! chain's last bone (forearm, shin) only moves its ellipsoid along a nearly cylindrical limb
//! and stays weakly determined (see `docs/template-silhouette.md`).
//!
//! **Residual.** Eq. 9 writes `F(u_a) = 0 − ε` for an attractor `u_a`. `F` is unit-less; we
//! use `e = (w/2)·F`, which is ≈ the radial distance to the surface near it (`F ≈ 2d/w`), so
//! the a-priori σ of every observation type is in metres and Eq. 7 homogenises the weights
//! as `P = 1/σ²` (Eq. 8 is then `Σ P e²`).
//!
//! **Jacobians (analytic).** The attractor `X` is fixed in the world and the joint frame
//! moves: `u = R_pᵀ(X − o_p)`, so for a rotation DOF `k` on the chain of `p` (world axis
//! `ω_k` through `c_k`) `∂u/∂θ_k = −R_pᵀ(ω_k × (X − c_k))`, for a translation DOF
//! `−R_pᵀ t_k`; a bone scale `s_m` whose child joint is on the chain of `p` moves `o_p` by
//! `R_{parent}·offset_m`, so `∂u/∂s_m = −R_pᵀ R_{parent}·offset_m`. With
//! `g = ∂e/∂u = w·[(u − z a)/w² + (z − l) a/h²]`: `∂e/∂θ_k = −(R_p g)·v_k`. The own
//! scale also enters the centre `l`: `∂F/∂l = −2 (z − l)/h²`, `∂l/∂s_b = L_b/2`; the width:
//! `∂e/∂w = F/2 − ρ²/w²`; the half-length: `∂e/∂h = −w (z − l)²/h³`.
//!
//! **Silhouettes (§5.3, Eq. 11–17).** Eq. 14–17 add the tangent point `P^s` as three unknowns
//! per ray, constrained to the ray (collinearity, Eq. 15) and to the tangent plane (Eq. 12–13,
//! with the heavy pseudo-observation Eq. 17). We eliminate `P^s` exactly: in the ellipsoid's
//! normalised coordinates (the ellipsoid a unit sphere) `F` along the ray is a quadratic in
//! the ray parameter `t`, and the tangent point of the ray-plane is the ray's point of least
//! `F`, `t* = argmin F(c + t d)`. The residual is `e(c + t* d)`; by the envelope theorem
//! (`∂F/∂t = 0` at `t*`) its gradient w.r.t. the state is the attractor gradient at the fixed
//! point `c + t* d`. So a silhouette ray is an attractor re-placed every iteration.
//!
//! **Assignment and robustness (§5.2).** Each iteration every attractor and ray goes to the
//! ellipsoid with the smallest `|e|` (so the objective is `Σ P min_b e_b²`, one function),
//! chosen among the two bones of smallest `|e|` at the start of the IRLS round (pruning:
//! each round assigns among all bones);
//! markers stay on their bone with the high weight of their small σ. IRLS: the first round
//! weighs every observation equally (within its type); each later round gives
//! Tukey's biweight `(1 − (r/c)²)²` (0 beyond `c`) of the residual normalised by a robust
//! scale per type (`1.4826·median|e|`, not below the type's σ; over every observation of
//! the type, or over those the previous round kept when that round rejected a large
//! fraction of them: [`EllipsoidParams::kept_scale_min_rejected`]), `c = 4.685` —
//! the paper "weighs them inversely proportionally to their residuals"; Tukey's redescending weight
//! is the variant we chose because it gives gross outliers exactly zero weight.
//!
//! One deviation, measured: the paper's first round is an unweighted fit, and the weights
//! come from its residuals. With 30 % gross outliers that fit swells ellipsoids around the
//! outliers (half-widths of a metre in the unit test) and its residuals no longer separate
//! inliers from outliers, so when IRLS is on (`irls_rounds > 1`) the first weights come from
//! the residuals at the *starting* state (default proportions, approximate pose), and every
//! round reweights at the previous round's result. `irls_rounds = 1` is the plain,
//! unweighted least squares. The first [`EllipsoidParams::pose_only_rounds`] rounds hold the
//! lengths and widths (a pose a few degrees off would otherwise let ellipsoids swell over
//! their neighbours' points first).
//!
//! **Several frames (§5: the paper fits sequences).** [`fit_ellipsoids_multi`] shares the
//! length scales, widths and half-lengths between frames, each frame has its own θ.
//!
//! **Solver.** Levenberg–Marquardt on the normal equations, accumulated observation by
//! observation (no dense Jacobian) in fixed chunks in parallel, frames in parallel; the
//! normal equations are kept in blocks (a pose block per frame, the shared block, their
//! couplings) and solved by the Schur complement on the shared unknowns. A weak prior on the
//! starting state (a pseudo-observation type with its own σ, so DOFs without data stay put),
//! scales clamped to a box and widths to a floor.

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use skin_core::math::{DAffine3, DVec3};
use skin_core::skeleton::Skeleton;
use skin_core::{check, Context};

use crate::error::{Error, Result, ResultExt};
use crate::silhouette_constraints::ContourRay;

/// One bone of the ellipsoid model: the segment from joint `parent`'s origin to joint
/// `child`'s origin, or to `parent`'s end site (a hand, a foot, the top of the head), carried
/// by `parent`'s frame (§4.2.2, Figure 7b).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EllipsoidBone {
    /// The joint whose frame carries the ellipsoid.
    pub parent: usize,
    /// The joint at the far end of the bone (its offset is the bone); `None` for the segment
    /// to `parent`'s end site (its length scale moves no joint).
    pub child: Option<usize>,
}

impl EllipsoidBone {
    /// The joint that names the bone in errors: its child, or its parent for an end-site
    /// segment.
    pub fn joint(&self) -> usize {
        self.child.unwrap_or(self.parent)
    }
}

/// The articulated ellipsoid model of §4.2: a default skeleton (the "standard body model"
/// the fit starts from) and the bones that carry ellipsoids.
#[derive(Debug, Clone)]
pub struct EllipsoidModel {
    skeleton: Skeleton,
    bones: Vec<EllipsoidBone>,
    /// Default bone length `L_b`, metres.
    lengths: Vec<f64>,
    /// Unit bone direction in the parent frame.
    axes: Vec<DVec3>,
    /// For each joint, the bones whose child joint lies on the root → joint path.
    chain_bones: Vec<Vec<usize>>,
}

/// The unknowns of §4.2: pose θ, a length scale per bone, a half-width per bone.
#[derive(Debug, Clone, PartialEq)]
pub struct EllipsoidState {
    /// Pose θ of the skeleton (radians, metres).
    pub theta: Vec<f64>,
    /// Length scale `s_b` per bone (1 = the default skeleton).
    pub length_scale: Vec<f64>,
    /// Half-width `part_w` per bone, metres.
    pub half_width: Vec<f64>,
    /// Axial radius of each ellipsoid, metres (Eq. 3 ties it to half the bone length; here it
    /// is its own unknown, see the module docs).
    pub half_length: Vec<f64>,
}

/// One ellipsoid in the world, for drawing and scoring.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ellipsoid {
    /// Centre (the bone's midpoint), world metres.
    pub centre: DVec3,
    /// Unit axis along the bone, world.
    pub axis: DVec3,
    /// Axial radius (half-length) of the ellipsoid, metres.
    pub half_length: f64,
    /// Half the bone's length `bone_l`, metres (the centre's distance from the joint).
    pub half_bone: f64,
    /// Half-width `part_w`, metres.
    pub half_width: f64,
}

/// A tracked marker of one frame (§2.4, §5.2): a skin point on a known bone, missing when the
/// tracker lost it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarkerObservation {
    /// Index into [`EllipsoidModel::bones`].
    pub bone: usize,
    /// Triangulated position, world metres; `None` when not seen.
    pub position: Option<DVec3>,
}

/// One frame's observations for [`fit_ellipsoids`].
#[derive(Debug, Clone, Default)]
pub struct EllipsoidObservations {
    /// 3D attractor points (stereo, visual-hull samples), world metres (Eq. 9).
    pub points: Vec<DVec3>,
    /// Tracked markers: high-weight attractors on their bone.
    pub markers: Vec<MarkerObservation>,
    /// Silhouette contour rays ([`crate::contour_rays`]), tangent to the body (Eq. 11–17).
    pub rays: Vec<ContourRay>,
}

/// Parameters of [`fit_ellipsoids`]. The paper gives no numbers; the defaults are ours and
/// documented per field.
#[derive(Debug, Clone, PartialEq)]
pub struct EllipsoidParams {
    /// A-priori σ of a 3D attractor point, metres (Eq. 7). Default 0.005 (stereo noise).
    pub sigma_point_m: f64,
    /// A-priori σ of a tracked marker, metres: "much higher weights" (§5.2). Default 0.001.
    pub sigma_marker_m: f64,
    /// Height of a marker's centre above the skin, metres: a marker's residual is its
    /// distance to the ellipsoid's surface minus this. Default 0.010 (the studio's balls,
    /// [`skin_core::markers::DEFAULT_MARKER_OFFSET_M`]: radius 8 mm on a 2 mm base).
    pub marker_offset_m: f64,
    /// A-priori σ of a silhouette ray's tangency, metres. Default 0.005.
    pub sigma_silhouette_m: f64,
    /// σ of the prior pulling θ to its starting value, radians (metres for translations).
    /// Default 1.0 (weak: only DOFs without data feel it).
    pub sigma_theta_prior: f64,
    /// σ of the same prior on the translation DOFs (the root's position), metres; `None`:
    /// [`EllipsoidParams::sigma_theta_prior`]. Default `None`. [`crate::SizingParams`] holds
    /// the given poses' root (docs/template-silhouette.md, "Sizing": with it free the joint
    /// fit lifts the pelvis by 6 cm and lengthens the thighs to reach the knees).
    pub sigma_translation_prior_m: Option<f64>,
    /// σ of the prior pulling each length scale to 1. Default 0.2.
    pub sigma_scale_prior: f64,
    /// σ of the prior pulling an end-site segment's length scale (a hand, a foot, the head:
    /// [`EllipsoidModel::with_end_sites`]) to 1. Its scale moves no joint, only the
    /// ellipsoid's extent along a limb that continues the last bone, so it trades freely with
    /// that bone's length (measured on the studio, 8-frame fit with σ = 0.2 as the limbs':
    /// the right forearm to the scale box's top, +62 mm, its hand to the bottom, −38 mm).
    /// Default 0.002: the end sites keep the default proportions and serve to pin the end
    /// of the last bone (forearm, shin).
    pub sigma_end_site_scale_prior: f64,
    /// σ of the prior pulling each half-width to its starting value, metres. Default 0.05.
    pub sigma_width_prior_m: f64,
    /// σ of the prior pulling each ellipsoid's half-length to its starting value, metres.
    /// Default 0.002: in effect the axial radius stays at the default skeleton's half bone
    /// length (with σ = 0.1 m the ellipsoids grow into long cylinders and the widths and
    /// angles degrade, measured: width error 33 mm vs 1.9 mm on the studio frame 0).
    pub sigma_half_length_prior_m: f64,
    /// IRLS rounds (§5.2, "several times"); 1 = plain least squares. Default 6 (two of them
    /// pose-only, see [`EllipsoidParams::pose_only_rounds`]).
    pub irls_rounds: usize,
    /// Tukey biweight constant, in robust-scale units. Default 4.685.
    pub tukey_c: f64,
    /// Levenberg–Marquardt iterations per IRLS round. Default 4: each round continues the
    /// descent of the previous one (measured on the studio, eight-frame fit: 4 iterations
    /// give the figures of 30 at 70 % of the time).
    pub lm_iterations: usize,
    /// An LM round stops when a step lowers the cost by less than this fraction. Default 1e-3
    /// (measured on the studio: 1e-6 costs 5–10× the time for the same accuracy, the IRLS
    /// rounds refine anyway).
    pub lm_tolerance: f64,
    /// The first IRLS rounds that fit the pose alone (lengths, widths and half-lengths held at
    /// their start): a pose several degrees off would otherwise let ellipsoids swell over
    /// their neighbours' points before the pose is right. Default 2 (measured on the studio,
    /// four-frame fit from a pose with 5° noise per rotation: width error 3.8 / 8.9 / 39 mm
    /// and direction 1.7° / 5.5° / 12° with 2 / 1 / 0 pose-only rounds).
    pub pose_only_rounds: usize,
    /// Fit the pose alone in every round, the lengths, widths and half-lengths held at their
    /// start (tracking a performer of known proportions, as [`crate::size_performer`] does
    /// between its first frame and the frames it sizes from). Default false.
    pub pose_only: bool,
    /// Floor of every half-width, metres; a width ending on it is a collapsed ellipsoid
    /// ([`fit_ellipsoids`] errors). Default 0.005.
    pub min_half_width_m: f64,
    /// Box of every length scale. Default 0.8..=1.2: the prior knowledge of the protocol
    /// (performers within ±10 % of the default proportions) with a margin. With 0.5..=1.5
    /// the chain-end bones (forearms, shins), whose length only moves their ellipsoid's
    /// centre along a nearly cylindrical limb, run to the bounds (mean length error 119 vs
    /// 39 mm over four frames, measured).
    pub scale_range: (f64, f64),
    /// Fewest observations (points, rays, markers) a bone must keep after the fit. Default 5.
    pub min_observations_per_bone: usize,
    /// When an IRLS round (§5.2) takes its robust scale from the observations the previous
    /// round kept (non-zero weight) instead of from all of them, per observation type: when
    /// the previous round rejected at least this fraction of the type's observations (`None`:
    /// never; `Some(0.0)`: always). Default `Some(0.2)`.
    ///
    /// `1.4826·median|e|` over all residuals (the MAD scale of Beaton and Tukey 1974, cited by
    /// §5.2) is inflated by the gross outliers: with a fraction ε of them beyond the inliers'
    /// median and Gaussian inliers, by `Φ⁻¹(½ + ¼/(1 − ε)) / Φ⁻¹(¾)` — 1.06 at ε = 5 %, 1.13
    /// at 10 %, 1.31 at 20 %, 1.58 at 30 % — and Tukey's cut then lets ellipsoids hold points
    /// well outside the inliers. Over the kept observations the scale is the inliers' again;
    /// without gross outliers the two agree (the cut at 4.685 scales rejects almost nothing of
    /// a Gaussian). The rejected fraction measures ε. The threshold lies between the kinds
    /// of data measured: stereo-like points with 30 % gross outliers (the `ellipsoid_fit`
    /// scenario) lose 23–30 % per round after the first, visual-hull samples (a one-sided
    /// error, the hull's excess; sizing, the tracker inputs) 0.5–9 %, silhouette rays 2–9 %
    /// (23–28 % when the fit starts far off, from the rest pose), markers 4–12 %. Measured on
    /// the `ellipsoid_fit` scenario (`--quick`, 8 frames): mean length error 7.0 mm with this
    /// default, 12.0 with the scale over all observations in every round. The kept scale on
    /// every type and round (`Some(0.0)`) fits the hull samples no worse, but through the
    /// automatic initialisation it moves the template tracker's poses, and the sizing from
    /// them then fails its width claim (13.9 mm against the default proportions' 15.8; 9.0
    /// with this default). Details in docs/template-silhouette.md ("The IRLS scale").
    pub kept_scale_min_rejected: Option<f64>,
}

impl Default for EllipsoidParams {
    fn default() -> Self {
        EllipsoidParams {
            sigma_point_m: 0.005,
            sigma_marker_m: 0.001,
            marker_offset_m: skin_core::markers::DEFAULT_MARKER_OFFSET_M,
            sigma_silhouette_m: 0.005,
            sigma_theta_prior: 1.0,
            sigma_translation_prior_m: None,
            sigma_scale_prior: 0.2,
            sigma_end_site_scale_prior: 0.002,
            sigma_width_prior_m: 0.05,
            sigma_half_length_prior_m: 0.002,
            irls_rounds: 6,
            tukey_c: 4.685,
            lm_iterations: 4,
            lm_tolerance: 1e-3,
            pose_only_rounds: 2,
            pose_only: false,
            min_half_width_m: 0.005,
            scale_range: (0.8, 1.2),
            min_observations_per_bone: 5,
            kept_scale_min_rejected: Some(0.2),
        }
    }
}

impl EllipsoidParams {
    /// Sets the number of IRLS rounds (1 = no reweighting).
    pub fn with_irls_rounds(mut self, rounds: usize) -> Self {
        self.irls_rounds = rounds;
        self
    }

    /// The plain (unweighted) least squares with the same Levenberg–Marquardt budget: one
    /// round of `irls_rounds × lm_iterations` iterations (24 with the defaults) instead of
    /// `irls_rounds` rounds of `lm_iterations` — the baseline IRLS (§5.2) is measured
    /// against. Measured on the `ellipsoid_fit` scenario: the unweighted fit given 24
    /// iterations or run to convergence (500) ends no better than after 4 (its minimum is
    /// the fit swollen around the outliers, docs/template-silhouette.md).
    pub fn without_irls(mut self) -> Self {
        self.lm_iterations = self.irls_rounds.saturating_mul(self.lm_iterations);
        self.irls_rounds = 1;
        self
    }

    fn validate(&self) -> Result<()> {
        check::positive("sigma_point_m", self.sigma_point_m)?;
        check::positive("sigma_marker_m", self.sigma_marker_m)?;
        check::positive("sigma_silhouette_m", self.sigma_silhouette_m)?;
        check::non_negative("marker_offset_m", self.marker_offset_m)?;
        check::positive("sigma_theta_prior", self.sigma_theta_prior)?;
        if let Some(s) = self.sigma_translation_prior_m {
            check::positive("sigma_translation_prior_m", s)?;
        }
        check::positive("sigma_scale_prior", self.sigma_scale_prior)?;
        check::positive(
            "sigma_end_site_scale_prior",
            self.sigma_end_site_scale_prior,
        )?;
        check::positive("sigma_width_prior_m", self.sigma_width_prior_m)?;
        check::positive("sigma_half_length_prior_m", self.sigma_half_length_prior_m)?;
        check::nonzero("irls_rounds", self.irls_rounds)?;
        check::positive("tukey_c", self.tukey_c)?;
        check::nonzero("lm_iterations", self.lm_iterations)?;
        check::positive("lm_tolerance", self.lm_tolerance)?;
        if let Some(f) = self.kept_scale_min_rejected {
            check::in_range("kept_scale_min_rejected", f, 0.0..=1.0)?;
        }
        check::positive("min_half_width_m", self.min_half_width_m)?;
        check::positive("scale_range.0", self.scale_range.0)?;
        check::in_range(
            "scale_range.1",
            self.scale_range.1,
            self.scale_range.0..=f64::MAX,
        )?;
        Ok(())
    }
}

/// Result of [`fit_ellipsoids`].
#[derive(Debug, Clone)]
pub struct EllipsoidFit {
    /// The fitted state.
    pub state: EllipsoidState,
    /// Weighted cost `Σ P w_irls e²` at the end of each IRLS round.
    pub round_costs: Vec<f64>,
    /// Observations (points + rays + markers) each bone holds with non-zero weight at the end.
    pub observations_per_bone: Vec<usize>,
    /// Points given zero weight by the last IRLS round.
    pub rejected_points: usize,
    /// Per IRLS round that reweighted, for points, rays and markers: the fraction of the
    /// type's observations the previous round rejected (0 in the first round; NaN for a
    /// type without observations).
    pub irls_rejected: Vec<[f64; 3]>,
    /// Per IRLS round that reweighted, for points, rays and markers: whether the robust scale
    /// came from the kept observations ([`EllipsoidParams::kept_scale_min_rejected`]).
    pub irls_scale_from_kept: Vec<[bool; 3]>,
}

/// Evaluation of one attractor against one ellipsoid.
struct Eval {
    e: f64,
    /// ∂e/∂u in world axes (R_p g).
    grad_world: DVec3,
    d_own_scale: f64,
    d_width: f64,
    d_half_length: f64,
}

impl EllipsoidModel {
    /// A model over `bones` of `skeleton` (the default proportions).
    ///
    /// # Errors
    /// [`Error::Empty`] without bones; index errors; [`Error::InvalidParam`] when `child` is
    /// not a child of `parent`, or `parent` has no end site for a `None` child;
    /// [`skin_core::Error::Degenerate`] (inside [`Error::Core`]) for a zero-length bone.
    pub fn new(skeleton: Skeleton, bones: Vec<EllipsoidBone>) -> Result<Self> {
        if bones.is_empty() {
            return Err(Error::Empty {
                what: "ellipsoid bones",
            });
        }
        let n = skeleton.joint_count();
        let mut lengths = Vec::with_capacity(bones.len());
        let mut axes = Vec::with_capacity(bones.len());
        for (b, bone) in bones.iter().enumerate() {
            check::index("bone parent joint", bone.parent, n).at(Context::Joint(b))?;
            let (offset, name) = match bone.child {
                Some(c) => {
                    check::index("bone child joint", c, n).at(Context::Joint(b))?;
                    let joint = &skeleton.joints()[c];
                    if joint.parent != Some(bone.parent) {
                        return Err(Error::InvalidParam {
                            name: "bones",
                            reason: format!("joint {c} is not a child of joint {}", bone.parent),
                        });
                    }
                    (joint.offset, joint.name.clone())
                }
                None => {
                    let joint = &skeleton.joints()[bone.parent];
                    let Some(end) = joint.end_site else {
                        return Err(Error::InvalidParam {
                            name: "bones",
                            reason: format!("joint {} has no end site", bone.parent),
                        });
                    };
                    (end, format!("{} end site", joint.name))
                }
            };
            let len = offset.length();
            if len < 1e-6 {
                return Err(Error::Core(skin_core::Error::Degenerate {
                    what: format!("zero-length bone to {name}"),
                }));
            }
            lengths.push(len);
            axes.push(offset / len);
        }
        let mut chain_bones = vec![Vec::new(); n];
        for (j, chain) in chain_bones.iter_mut().enumerate() {
            let mut k = Some(j);
            while let Some(jj) = k {
                if let Some(b) = bones.iter().position(|bone| bone.child == Some(jj)) {
                    chain.push(b);
                }
                k = skeleton.joints()[jj].parent;
            }
        }
        Ok(EllipsoidModel {
            skeleton,
            bones,
            lengths,
            axes,
            chain_bones,
        })
    }

    /// The limbs of a skeleton: every bone whose parent joint articulates (has DOFs) and has
    /// exactly one child, and whose length is at least `min_length_m` (so the bone, and its
    /// ellipsoid, are unambiguous; a fixed link such as a clavicle carries no body part).
    ///
    /// # Errors
    /// As [`EllipsoidModel::new`]; `min_length_m` must be positive.
    pub fn limbs(skeleton: Skeleton, min_length_m: f64) -> Result<Self> {
        check::positive("min_length_m", min_length_m)?;
        let bones = (0..skeleton.joint_count())
            .filter_map(|c| {
                let p = skeleton.joints()[c].parent?;
                let single =
                    skeleton.children(p).count() == 1 && !skeleton.joints()[p].dofs.is_empty();
                (single && skeleton.joints()[c].offset.length() >= min_length_m).then_some(
                    EllipsoidBone {
                        parent: p,
                        child: Some(c),
                    },
                )
            })
            .collect();
        Self::new(skeleton, bones)
    }

    /// The limbs ([`EllipsoidModel::limbs`]) and the end-site segments at least
    /// `min_length_m` long (hands, feet, the head of the human skeleton): everything a
    /// silhouette or a visual hull shows of the extremities has an ellipsoid to go to.
    ///
    /// # Errors
    /// As [`EllipsoidModel::limbs`].
    pub fn with_end_sites(skeleton: Skeleton, min_length_m: f64) -> Result<Self> {
        let limbs = Self::limbs(skeleton, min_length_m)?;
        let mut bones = limbs.bones;
        let skeleton = limbs.skeleton;
        bones.extend(skeleton.joints().iter().enumerate().filter_map(|(p, j)| {
            j.end_site
                .is_some_and(|e| e.length() >= min_length_m)
                .then_some(EllipsoidBone {
                    parent: p,
                    child: None,
                })
        }));
        Self::new(skeleton, bones)
    }

    /// The bones, in state order.
    pub fn bones(&self) -> &[EllipsoidBone] {
        &self.bones
    }

    /// The default skeleton.
    pub fn skeleton(&self) -> &Skeleton {
        &self.skeleton
    }

    /// Default bone lengths `L_b`, metres.
    pub fn default_lengths(&self) -> &[f64] {
        &self.lengths
    }

    /// Bone lengths of a state, `s_b L_b`, metres.
    pub fn bone_lengths(&self, state: &EllipsoidState) -> Vec<f64> {
        self.lengths
            .iter()
            .zip(&state.length_scale)
            .map(|(l, s)| l * s)
            .collect()
    }

    /// A starting state: pose `theta`, default lengths, every half-width `half_width_m`.
    ///
    /// # Errors
    /// Wrong θ length or non-finite values; a non-positive width.
    pub fn initial_state(&self, theta: &[f64], half_width_m: f64) -> Result<EllipsoidState> {
        check::positive("half_width_m", half_width_m)?;
        let state = EllipsoidState {
            theta: theta.to_vec(),
            length_scale: vec![1.0; self.bones.len()],
            half_width: vec![half_width_m; self.bones.len()],
            half_length: self.lengths.iter().map(|l| 0.5 * l).collect(),
        };
        self.check_state(&state)?;
        Ok(state)
    }

    fn check_state(&self, state: &EllipsoidState) -> Result<()> {
        check::same_size("theta", self.skeleton.dof_count(), state.theta.len())?;
        check::same_size("length_scale", self.bones.len(), state.length_scale.len())?;
        check::same_size("half_width", self.bones.len(), state.half_width.len())?;
        check::same_size("half_length", self.bones.len(), state.half_length.len())?;
        for &h in &state.half_length {
            check::positive("half_length", h)?;
        }
        check::all_finite("theta", &state.theta)?;
        for (&s, &w) in state.length_scale.iter().zip(&state.half_width) {
            check::positive("length_scale", s)?;
            check::positive("half_width", w)?;
        }
        Ok(())
    }

    /// The skeleton with every bone's offset scaled by its length scale.
    ///
    /// # Errors
    /// A state of the wrong size.
    pub fn scaled_skeleton(&self, state: &EllipsoidState) -> Result<Skeleton> {
        self.check_state(state)?;
        let mut joints = self.skeleton.joints().to_vec();
        for (bone, &s) in self.bones.iter().zip(&state.length_scale) {
            if let Some(c) = bone.child {
                joints[c].offset *= s;
            }
        }
        Ok(Skeleton::new(joints)?)
    }

    /// The world ellipsoids of a state (Eq. 3).
    ///
    /// # Errors
    /// A state of the wrong size or non-finite.
    pub fn ellipsoids(&self, state: &EllipsoidState) -> Result<Vec<Ellipsoid>> {
        let sk = self.scaled_skeleton(state)?;
        let fk = sk.forward_kinematics(&state.theta)?;
        let frames = fk.world_from_joint();
        Ok(self
            .bones
            .iter()
            .enumerate()
            .map(|(b, bone)| {
                let f = frames[bone.parent];
                let l = 0.5 * self.lengths[b] * state.length_scale[b];
                let axis = f.matrix3 * self.axes[b];
                Ellipsoid {
                    centre: f.translation + axis * l,
                    axis,
                    half_length: state.half_length[b],
                    half_bone: l,
                    half_width: state.half_width[b],
                }
            })
            .collect())
    }

    /// Residual of Eq. 9 (scaled, see the module docs) of a world point against bone `b`.
    fn eval(&self, frames: &[DAffine3], state: &EllipsoidState, b: usize, x: DVec3) -> Eval {
        let f = frames[self.bones[b].parent];
        let u = f.matrix3.transpose() * (x - f.translation);
        let a = self.axes[b];
        let l = 0.5 * self.lengths[b] * state.length_scale[b];
        let w = state.half_width[b];
        let h = state.half_length[b];
        let z = u.dot(a);
        let radial = u - a * z;
        let rho2 = radial.length_squared();
        let zl = z - l;
        let big_f = rho2 / (w * w) + zl * zl / (h * h) - 1.0;
        let g = (radial / (w * w) + a * (zl / (h * h))) * w;
        let d_f_dl = -2.0 * zl / (h * h);
        Eval {
            e: 0.5 * w * big_f,
            grad_world: f.matrix3 * g,
            d_own_scale: 0.5 * w * d_f_dl * 0.5 * self.lengths[b],
            d_width: 0.5 * big_f - rho2 / (w * w),
            d_half_length: -w * zl * zl / (h * h * h),
        }
    }

    /// The point of a ray with the least `F` for bone `b` (the tangent point of §5.3).
    fn ray_point(
        &self,
        frames: &[DAffine3],
        state: &EllipsoidState,
        b: usize,
        ray: &ContourRay,
    ) -> DVec3 {
        let f = frames[self.bones[b].parent];
        let rt = f.matrix3.transpose();
        let a = self.axes[b];
        let l = 0.5 * self.lengths[b] * state.length_scale[b];
        let w = state.half_width[b];
        let h = state.half_length[b];
        let norm = |v: DVec3, shift: f64| {
            let z = v.dot(a);
            let radial = v - a * z;
            radial / w + a * ((z - shift) / h)
        };
        let q0 = norm(rt * (ray.origin - f.translation), l);
        let qd = norm(rt * ray.direction, 0.0);
        let t = (-q0.dot(qd) / qd.length_squared().max(1e-300)).max(0.0);
        ray.origin + ray.direction * t
    }
}

/// Kind of an observation row (for σ and IRLS scale).
#[derive(Clone, Copy, PartialEq, Eq)]
enum Kind {
    Point,
    Ray,
    Marker,
}

/// Bones kept per point or ray between two IRLS rounds: the assignment of §5.2 is re-done
/// every LM iteration among the `CANDIDATES` bones of smallest `|e|` at the round's start
/// (the pruning that makes an iteration cost 2 evaluations per observation instead of one
/// per bone); every round and the final count assign among all bones.
const CANDIDATES: usize = 2;

/// Observations per parallel chunk (fixed, so sums are identical for any thread count).
const CHUNK: usize = 256;

/// One frame of the problem.
struct FrameData<'a> {
    obs: &'a EllipsoidObservations,
    start_theta: &'a [f64],
    /// Markers actually seen: (bone, position).
    markers: Vec<(usize, DVec3)>,
    /// IRLS weight per observation (points, rays, markers in order).
    robust: Vec<f64>,
    /// Candidate bones per point and ray.
    candidates: Vec<[usize; CANDIDATES]>,
}

impl FrameData<'_> {
    fn n_obs(&self) -> usize {
        self.obs.points.len() + self.obs.rays.len() + self.markers.len()
    }

    fn kind(&self, i: usize) -> Kind {
        let (np, nr) = (self.obs.points.len(), self.obs.rays.len());
        if i < np {
            Kind::Point
        } else if i < np + nr {
            Kind::Ray
        } else {
            Kind::Marker
        }
    }
}

/// A frame's part of the normal equations, in local indices: θ of the frame first, then
/// the shared scales, widths, half-lengths.
struct FrameLin {
    cost: f64,
    /// Unweighted residual and bone per observation (only from a full assignment).
    residuals: Vec<(f64, usize)>,
    /// Best bones per point and ray (only from a full assignment).
    candidates: Vec<[usize; CANDIDATES]>,
    h: DMatrix<f64>,
    g: DVector<f64>,
}

/// The normal equations of the multi-frame problem in blocks (the state: every frame's θ,
/// then the shared unknowns): per frame the pose block `A_f`, its coupling `B_f` to the
/// shared unknowns and its gradient `g_f`; the shared block `C` and gradient `g_s`.
struct Normal {
    a: Vec<DMatrix<f64>>,
    b: Vec<DMatrix<f64>>,
    gf: Vec<DVector<f64>>,
    c: DMatrix<f64>,
    gs: DVector<f64>,
}

impl Normal {
    /// The gradient in the state's layout.
    #[cfg(test)]
    fn gradient(&self) -> DVector<f64> {
        let mut v: Vec<f64> = self.gf.iter().flat_map(|g| g.iter().copied()).collect();
        v.extend(self.gs.iter());
        DVector::from_vec(v)
    }

    /// Solves `(H + λ·diag(H)) x = g` by the Schur complement on the shared block (per-frame
    /// Cholesky of the pose blocks, then one of the shared block): `O(F·n_θ³ + n_s³)` instead
    /// of `O((F·n_θ + n_s)³)`. With `pose_only` the shared part of `x` is zero. `None` when a
    /// block is not positive definite.
    fn solve(&self, lambda: f64, pose_only: bool) -> Option<DVector<f64>> {
        let nf = self.a.len();
        let nd = self.gf.first().map_or(0, |g| g.len());
        let ns = self.gs.len();
        let damp = |m: &DMatrix<f64>| {
            let mut m = m.clone();
            for k in 0..m.nrows() {
                m[(k, k)] += lambda * (m[(k, k)] + 1e-9);
            }
            m
        };
        let mut x = DVector::zeros(nf * nd + ns);
        let mut s = damp(&self.c);
        let mut r = self.gs.clone();
        let mut parts = Vec::with_capacity(nf);
        for f in 0..nf {
            let chol = damp(&self.a[f]).cholesky()?;
            let y = chol.solve(&self.gf[f]);
            if pose_only {
                x.rows_mut(f * nd, nd).copy_from(&y);
                continue;
            }
            let xb = chol.solve(&self.b[f]);
            let bt = self.b[f].transpose();
            s -= &bt * &xb;
            r -= &bt * &y;
            parts.push((y, xb));
        }
        if pose_only {
            return Some(x);
        }
        let ds = s.cholesky()?.solve(&r);
        for (f, (y, xb)) in parts.into_iter().enumerate() {
            x.rows_mut(f * nd, nd).copy_from(&(y - xb * &ds));
        }
        x.rows_mut(nf * nd, ns).copy_from(&ds);
        Some(x)
    }
}

struct Problem<'a> {
    model: &'a EllipsoidModel,
    params: &'a EllipsoidParams,
    /// Start of the shared unknowns (the first frame's).
    start: &'a EllipsoidState,
    frames: Vec<FrameData<'a>>,
}

impl Problem<'_> {
    fn sigma(&self, kind: Kind) -> f64 {
        match kind {
            Kind::Point => self.params.sigma_point_m,
            Kind::Ray => self.params.sigma_silhouette_m,
            Kind::Marker => self.params.sigma_marker_m,
        }
    }

    fn local_size(&self) -> usize {
        self.model.skeleton.dof_count() + 3 * self.model.bones.len()
    }

    /// Cost (and, when `jac`, local normal equations) of frame `f` at `state`. `full`:
    /// assign among all bones and return residuals and candidates; otherwise among the
    /// round's candidates, skipping observations of zero IRLS weight.
    fn linearise_frame(
        &self,
        f: usize,
        state: &EllipsoidState,
        jac: bool,
        full: bool,
    ) -> Result<FrameLin> {
        let model = self.model;
        let frame = &self.frames[f];
        let nd = model.skeleton.dof_count();
        let nb = model.bones.len();
        let nl = self.local_size();
        let sk = model.scaled_skeleton(state)?;
        let fk = sk.forward_kinematics(&state.theta)?;
        let frames = fk.world_from_joint();
        let axes = fk.dof_axes_world();
        let origins = fk.dof_origins_world();
        // World direction each bone scale moves its child joint along (R_parent · offset).
        let scale_dirs: Vec<DVec3> = model
            .bones
            .iter()
            .enumerate()
            .map(|(b, bone)| frames[bone.parent].matrix3 * (model.axes[b] * model.lengths[b]))
            .collect();
        let np = frame.obs.points.len();
        let nr = frame.obs.rays.len();
        let n_obs = frame.n_obs();
        let chunk = |range: std::ops::Range<usize>| -> FrameLin {
            let (mut h, mut g) = if jac {
                (DMatrix::zeros(nl, nl), DVector::zeros(nl))
            } else {
                (DMatrix::zeros(0, 0), DVector::zeros(0))
            };
            let mut cost = 0.0;
            let mut residuals = Vec::new();
            let mut candidates = Vec::new();
            let mut row: Vec<(usize, f64)> = Vec::with_capacity(64);
            for i in range {
                let kind = frame.kind(i);
                if !full && frame.robust[i] == 0.0 {
                    continue;
                }
                let x_of = |b: usize| {
                    if kind == Kind::Point {
                        frame.obs.points[i]
                    } else {
                        model.ray_point(frames, state, b, &frame.obs.rays[i - np])
                    }
                };
                // Assignment (§5.2): the bone with the smallest |e|.
                let (b, x, ev) = match kind {
                    Kind::Marker => {
                        let (b, x) = frame.markers[i - np - nr];
                        let mut ev = model.eval(frames, state, b, x);
                        ev.e -= self.params.marker_offset_m;
                        (b, x, ev)
                    }
                    Kind::Point | Kind::Ray if full => {
                        let mut best: [(f64, usize); CANDIDATES] = [(f64::MAX, 0); CANDIDATES];
                        let mut chosen: Option<(usize, DVec3, Eval)> = None;
                        for b in 0..nb {
                            let x = x_of(b);
                            let ev = model.eval(frames, state, b, x);
                            let a = ev.e.abs();
                            if let Some(pos) = best.iter().position(|&(e, _)| a < e) {
                                best[pos..].rotate_right(1);
                                best[pos] = (a, b);
                            }
                            if chosen.as_ref().is_none_or(|(_, _, e)| a < e.e.abs()) {
                                chosen = Some((b, x, ev));
                            }
                        }
                        candidates.push(best.map(|(_, b)| b));
                        match chosen {
                            Some(v) => v,
                            None => continue,
                        }
                    }
                    Kind::Point | Kind::Ray => {
                        let mut chosen: Option<(usize, DVec3, Eval)> = None;
                        for &b in &frame.candidates[i] {
                            let x = x_of(b);
                            let ev = model.eval(frames, state, b, x);
                            if chosen
                                .as_ref()
                                .is_none_or(|(_, _, e)| ev.e.abs() < e.e.abs())
                            {
                                chosen = Some((b, x, ev));
                            }
                        }
                        match chosen {
                            Some(v) => v,
                            None => continue,
                        }
                    }
                };
                if full {
                    residuals.push((ev.e, b));
                }
                let sigma = self.sigma(kind);
                let weight = frame.robust[i] / (sigma * sigma);
                if weight == 0.0 {
                    continue;
                }
                cost += weight * ev.e * ev.e;
                if !jac {
                    continue;
                }
                row.clear();
                let p = model.bones[b].parent;
                for &k in sk.chain_dofs(p) {
                    let v = if sk.is_rotation(k) {
                        axes[k].cross(x - origins[k])
                    } else {
                        axes[k]
                    };
                    row.push((k, -ev.grad_world.dot(v)));
                }
                let mut own = ev.d_own_scale;
                for &m in &model.chain_bones[p] {
                    let d = -ev.grad_world.dot(scale_dirs[m]);
                    if m == b {
                        own += d;
                    } else {
                        row.push((nd + m, d));
                    }
                }
                row.push((nd + b, own));
                row.push((nd + nb + b, ev.d_width));
                row.push((nd + 2 * nb + b, ev.d_half_length));
                // The upper triangle (row indices ascend within a row's blocks; mirrored
                // below).
                for (i, &(r, jr)) in row.iter().enumerate() {
                    let wr = weight * jr;
                    g[r] += wr * ev.e;
                    for &(c, jc) in &row[i..] {
                        let (lo, hi) = if r <= c { (r, c) } else { (c, r) };
                        h[(lo, hi)] += wr * jc;
                    }
                }
            }
            FrameLin {
                cost,
                residuals,
                candidates,
                h,
                g,
            }
        };
        let starts: Vec<usize> = (0..n_obs).step_by(CHUNK).collect();
        let parts: Vec<FrameLin> = starts
            .par_iter()
            .map(|&s| chunk(s..(s + CHUNK).min(n_obs)))
            .collect();
        let mut total = FrameLin {
            cost: 0.0,
            residuals: Vec::new(),
            candidates: Vec::new(),
            h: if jac {
                DMatrix::zeros(nl, nl)
            } else {
                DMatrix::zeros(0, 0)
            },
            g: if jac {
                DVector::zeros(nl)
            } else {
                DVector::zeros(0)
            },
        };
        for mut p in parts {
            if jac {
                // Mirror the upper triangle accumulated per observation.
                for c in 0..nl {
                    for r in c + 1..nl {
                        p.h[(r, c)] = p.h[(c, r)];
                    }
                }
            }
            total.cost += p.cost;
            total.residuals.extend(p.residuals);
            total.candidates.extend(p.candidates);
            if jac {
                total.h += p.h;
                total.g += p.g;
            }
        }
        // The θ prior of this frame (a pseudo-observation type, Eq. 7).
        let pr = 1.0 / (self.params.sigma_theta_prior * self.params.sigma_theta_prior);
        let ptr = self
            .params
            .sigma_translation_prior_m
            .map_or(pr, |s| 1.0 / (s * s));
        for k in 0..nd {
            let pt = if sk.is_rotation(k) { pr } else { ptr };
            let r = state.theta[k] - frame.start_theta[k];
            total.cost += pt * r * r;
            if jac {
                total.h[(k, k)] += pt;
                total.g[k] += pt * r;
            }
        }
        Ok(total)
    }

    /// Cost and (when `jac`) the normal equations in blocks at `states` (one per frame,
    /// shared unknowns equal); the frames are linearised in parallel.
    fn linearise(&self, states: &[EllipsoidState], jac: bool) -> Result<(f64, Option<Normal>)> {
        let nd = self.model.skeleton.dof_count();
        let nb = self.model.bones.len();
        let ns = 3 * nb;
        let lins: Vec<FrameLin> = states
            .par_iter()
            .enumerate()
            .map(|(f, state)| {
                self.linearise_frame(f, state, jac, false)
                    .at(Context::Frame(f))
            })
            .collect::<Result<_>>()?;
        let mut cost: f64 = lins.iter().map(|l| l.cost).sum();
        let mut normal = jac.then(|| Normal {
            a: Vec::with_capacity(lins.len()),
            b: Vec::with_capacity(lins.len()),
            gf: Vec::with_capacity(lins.len()),
            c: DMatrix::zeros(ns, ns),
            gs: DVector::zeros(ns),
        });
        if let Some(n) = normal.as_mut() {
            for lin in &lins {
                n.a.push(lin.h.view((0, 0), (nd, nd)).into_owned());
                n.b.push(lin.h.view((0, nd), (nd, ns)).into_owned());
                n.gf.push(lin.g.rows(0, nd).into_owned());
                n.c += lin.h.view((nd, nd), (ns, ns));
                n.gs += lin.g.rows(nd, ns);
            }
        }
        // Priors on the shared unknowns (a pseudo-observation type each, Eq. 7).
        let s = &states[0];
        for b in 0..nb {
            for (k, r, sigma) in [
                (
                    b,
                    s.length_scale[b] - 1.0,
                    if self.model.bones[b].child.is_some() {
                        self.params.sigma_scale_prior
                    } else {
                        self.params.sigma_end_site_scale_prior
                    },
                ),
                (
                    nb + b,
                    s.half_width[b] - self.start.half_width[b],
                    self.params.sigma_width_prior_m,
                ),
                (
                    2 * nb + b,
                    s.half_length[b] - self.start.half_length[b],
                    self.params.sigma_half_length_prior_m,
                ),
            ] {
                let p = 1.0 / (sigma * sigma);
                cost += p * r * r;
                if let Some(n) = normal.as_mut() {
                    n.c[(k, k)] += p;
                    n.gs[k] += p * r;
                }
            }
        }
        Ok((cost, normal))
    }

    fn step(&self, states: &[EllipsoidState], delta: &DVector<f64>) -> Vec<EllipsoidState> {
        let nd = self.model.skeleton.dof_count();
        let nb = self.model.bones.len();
        let base = self.frames.len() * nd;
        let (lo, hi) = self.params.scale_range;
        let floor = self.params.min_half_width_m;
        let s = &states[0];
        let length_scale: Vec<f64> = (0..nb)
            .map(|b| (s.length_scale[b] + delta[base + b]).clamp(lo, hi))
            .collect();
        let half_width: Vec<f64> = (0..nb)
            .map(|b| (s.half_width[b] + delta[base + nb + b]).max(floor))
            .collect();
        let half_length: Vec<f64> = (0..nb)
            .map(|b| (s.half_length[b] + delta[base + 2 * nb + b]).max(floor))
            .collect();
        states
            .iter()
            .enumerate()
            .map(|(f, st)| EllipsoidState {
                theta: (0..nd).map(|k| st.theta[k] + delta[f * nd + k]).collect(),
                length_scale: length_scale.clone(),
                half_width: half_width.clone(),
                half_length: half_length.clone(),
            })
            .collect()
    }

    /// Levenberg–Marquardt at fixed IRLS weights and candidates; with `pose_only` the shared
    /// unknowns are held.
    fn solve(
        &self,
        mut states: Vec<EllipsoidState>,
        pose_only: bool,
    ) -> Result<(Vec<EllipsoidState>, f64)> {
        let mut lambda = 1e-3;
        let (mut cost, normal) = self.linearise(&states, true)?;
        let mut normal = normal.ok_or(Error::Empty {
            what: "normal equations",
        })?;
        for _ in 0..self.params.lm_iterations {
            let mut accepted = false;
            while lambda < 1e12 {
                let Some(x) = normal.solve(lambda, pose_only) else {
                    lambda *= 10.0;
                    continue;
                };
                let delta = -x;
                let trial = self.step(&states, &delta);
                // Linearised at once: most trials are accepted (measured: 41 of 46 on the
                // studio), so the cost-only pass would be followed by this one anyway.
                let (trial_cost, trial_normal) = self.linearise(&trial, true)?;
                if trial_cost < cost {
                    // Converged: a step below 1 µm / µrad or a small relative decrease.
                    let small =
                        delta.amax() < 1e-6 || cost - trial_cost < self.params.lm_tolerance * cost;
                    states = trial;
                    cost = trial_cost;
                    if let Some(n) = trial_normal {
                        normal = n;
                    }
                    lambda = (lambda * 0.3).max(1e-9);
                    accepted = !small;
                    break;
                }
                lambda *= 10.0;
            }
            if !accepted {
                break;
            }
        }
        Ok((states, cost))
    }

    /// Full assignment of every frame at `states`: residuals per frame; refreshes the
    /// candidates.
    fn assign(&mut self, states: &[EllipsoidState]) -> Result<Vec<Vec<(f64, usize)>>> {
        let mut out = Vec::with_capacity(states.len());
        for (f, state) in states.iter().enumerate() {
            let lin = self
                .linearise_frame(f, state, false, true)
                .at(Context::Frame(f))?;
            self.frames[f].candidates = lin.candidates;
            out.push(lin.residuals);
        }
        Ok(out)
    }
}

/// Result of [`fit_ellipsoids_multi`].
#[derive(Debug, Clone)]
pub struct EllipsoidMultiFit {
    /// The fitted state of each frame (the same lengths, widths and half-lengths in all).
    pub states: Vec<EllipsoidState>,
    /// Weighted cost at the end of each IRLS round (all frames).
    pub round_costs: Vec<f64>,
    /// Observations each bone holds with non-zero weight at the end, summed over frames.
    pub observations_per_bone: Vec<usize>,
    /// Points given zero weight by the last IRLS round, per frame.
    pub rejected_points: Vec<usize>,
    /// Per frame, per attractor point: the bone holding it at the end (`None`: zero weight).
    pub point_bones: Vec<Vec<Option<usize>>>,
    /// As [`EllipsoidFit::irls_rejected`] (pooled over the frames).
    pub irls_rejected: Vec<[f64; 3]>,
    /// As [`EllipsoidFit::irls_scale_from_kept`].
    pub irls_scale_from_kept: Vec<[bool; 3]>,
}

fn check_observations(
    model: &EllipsoidModel,
    obs: &EllipsoidObservations,
) -> Result<Vec<(usize, DVec3)>> {
    for p in &obs.points {
        if !p.is_finite() {
            return Err(Error::NonFinite {
                what: "attractor points",
            });
        }
    }
    for r in &obs.rays {
        if !(r.origin.is_finite() && r.direction.is_finite()) {
            return Err(Error::NonFinite {
                what: "contour rays",
            });
        }
    }
    let mut markers = Vec::new();
    for m in &obs.markers {
        check::index("marker bone", m.bone, model.bones.len())?;
        if let Some(x) = m.position {
            if !x.is_finite() {
                return Err(Error::NonFinite { what: "markers" });
            }
            markers.push((m.bone, x));
        }
    }
    Ok(markers)
}

/// Fits the articulated ellipsoid model to one frame's observations by joint least squares
/// (§5.1, Eq. 8) with IRLS (§5.2), starting from `initial`: [`fit_ellipsoids_multi`] with
/// one frame.
///
/// # Errors
/// As [`fit_ellipsoids_multi`].
pub fn fit_ellipsoids(
    model: &EllipsoidModel,
    initial: &EllipsoidState,
    obs: &EllipsoidObservations,
    params: &EllipsoidParams,
) -> Result<EllipsoidFit> {
    let multi = fit_ellipsoids_multi(
        model,
        std::slice::from_ref(initial),
        std::slice::from_ref(obs),
        params,
    )?;
    let state = multi.states.into_iter().next().ok_or(Error::Empty {
        what: "fitted frames",
    })?;
    Ok(EllipsoidFit {
        state,
        round_costs: multi.round_costs,
        observations_per_bone: multi.observations_per_bone,
        rejected_points: multi.rejected_points.iter().sum(),
        irls_rejected: multi.irls_rejected,
        irls_scale_from_kept: multi.irls_scale_from_kept,
    })
}

/// Fits the articulated ellipsoid model to several frames of one performer at once (§5: the
/// paper fits over sequences): the length scales, half-widths and half-lengths are shared,
/// each frame has its own pose θ. A straight chain's inner joint slides along the limb in one
/// frame; a frame where the chain bends pins it, so the shared lengths are observable.
/// `initial[f]` gives frame `f`'s starting pose; the shared unknowns start from `initial[0]`.
/// With one frame this is [`fit_ellipsoids`].
///
/// # Errors
/// Invalid parameters, states of the wrong size, `initial` and `obs` of different lengths or
/// empty, non-finite observations, a marker on a bone that does not exist (each wrapped in
/// [`Error::At`] with [`Context::Frame`] when there are several frames); [`Error::Empty`] without
/// any observation; for a bone left with fewer than
/// [`EllipsoidParams::min_observations_per_bone`] weighted observations over all frames ("no
/// points near a limb") an [`Error::Empty`] and for a half-width that ended on
/// [`EllipsoidParams::min_half_width_m`] (a collapsed ellipsoid) an
/// [`skin_core::Error::Degenerate`] (inside [`Error::Core`]), both wrapped in [`Error::At`]
/// with the bone's child joint as [`Context::Joint`].
pub fn fit_ellipsoids_multi(
    model: &EllipsoidModel,
    initial: &[EllipsoidState],
    obs: &[EllipsoidObservations],
    params: &EllipsoidParams,
) -> Result<EllipsoidMultiFit> {
    params.validate()?;
    check::nonzero("frames", initial.len())?;
    check::same_size("observation frames", initial.len(), obs.len())?;
    let nb = model.bones.len();
    let mut frames = Vec::with_capacity(obs.len());
    for (f, (s, o)) in initial.iter().zip(obs).enumerate() {
        // One frame's errors name the frame when there are several.
        let in_frame = |r: Result<()>| {
            if obs.len() > 1 {
                r.at(Context::Frame(f))
            } else {
                r
            }
        };
        in_frame(model.check_state(s))?;
        let mut markers = Vec::new();
        in_frame(check_observations(model, o).map(|m| markers = m))?;
        let mut frame = FrameData {
            obs: o,
            start_theta: &s.theta,
            markers,
            robust: Vec::new(),
            candidates: Vec::new(),
        };
        frame.robust = vec![1.0; frame.n_obs()];
        frames.push(frame);
    }
    if frames.iter().all(|f| f.n_obs() == 0) {
        return Err(Error::Empty {
            what: "ellipsoid observations",
        });
    }
    let mut problem = Problem {
        model,
        params,
        start: &initial[0],
        frames,
    };
    let shared = &initial[0];
    let mut states: Vec<EllipsoidState> = initial
        .iter()
        .map(|s| EllipsoidState {
            theta: s.theta.clone(),
            ..shared.clone()
        })
        .collect();
    let mut round_costs = Vec::new();
    let (mut irls_rejected, mut irls_scale_from_kept) = (Vec::new(), Vec::new());
    for round in 0..params.irls_rounds {
        let residuals = problem.assign(&states)?;
        if params.irls_rounds > 1 {
            let (rejected, from_kept) = reweight(&mut problem, &residuals);
            irls_rejected.push(rejected);
            irls_scale_from_kept.push(from_kept);
        }
        let pose_only =
            params.pose_only || (round < params.pose_only_rounds && round + 1 < params.irls_rounds);
        let (s, cost) = problem.solve(states, pose_only)?;
        states = s;
        round_costs.push(cost);
    }
    let residuals = problem.assign(&states)?;
    let mut observations_per_bone = vec![0; nb];
    let mut rejected_points = Vec::with_capacity(states.len());
    let mut point_bones = Vec::with_capacity(states.len());
    for (frame, res) in problem.frames.iter().zip(&residuals) {
        point_bones.push(
            (0..frame.obs.points.len())
                .map(|i| (frame.robust[i] > 0.0).then_some(res[i].1))
                .collect(),
        );
        for (i, &(_, b)) in res.iter().enumerate() {
            if frame.robust[i] > 0.0 {
                observations_per_bone[b] += 1;
            }
        }
        rejected_points.push(
            (0..frame.obs.points.len())
                .filter(|&i| frame.robust[i] == 0.0)
                .count(),
        );
    }
    let state = &states[0];
    for (b, bone) in model.bones.iter().enumerate() {
        if observations_per_bone[b] < params.min_observations_per_bone {
            return Err(Error::Empty {
                what: "observations near the bone's ellipsoid",
            })
            .at(Context::Joint(bone.joint()));
        }
        if !params.pose_only && state.half_width[b] <= params.min_half_width_m * (1.0 + 1e-9) {
            return Err(Error::Core(skin_core::Error::Degenerate {
                what: format!(
                    "ellipsoid collapsed to the minimum half-width {} m",
                    params.min_half_width_m
                ),
            }))
            .at(Context::Joint(bone.joint()));
        }
    }
    Ok(EllipsoidMultiFit {
        states,
        round_costs,
        observations_per_bone,
        rejected_points,
        point_bones,
        irls_rejected,
        irls_scale_from_kept,
    })
}

/// IRLS weights (§5.2): Tukey's biweight of each residual over a robust scale of its type
/// (pooled over the frames). Returns, for points, rays and markers, the fraction of the
/// type's observations the previous weights rejected (NaN without observations) and whether
/// the scale came from the kept ones ([`EllipsoidParams::kept_scale_min_rejected`]).
fn reweight(problem: &mut Problem<'_>, residuals: &[Vec<(f64, usize)>]) -> ([f64; 3], [bool; 3]) {
    let mut rejected = [f64::NAN; 3];
    let mut from_kept = [false; 3];
    for (t, kind) in [Kind::Point, Kind::Ray, Kind::Marker]
        .into_iter()
        .enumerate()
    {
        let abs_of = |kept_only: bool| -> Vec<f64> {
            problem
                .frames
                .iter()
                .zip(residuals)
                .flat_map(|(frame, res)| {
                    (0..res.len())
                        .filter(move |&i| {
                            frame.kind(i) == kind && (!kept_only || frame.robust[i] > 0.0)
                        })
                        .map(move |i| res[i].0.abs())
                })
                .collect()
        };
        let all = abs_of(false);
        if all.is_empty() {
            continue;
        }
        let kept = abs_of(true);
        let fraction = 1.0 - kept.len() as f64 / all.len() as f64;
        rejected[t] = fraction;
        // The kept observations' scale once the previous round rejected a large fraction
        // (gross outliers inflate the median of all |e|; see the parameter's docs).
        from_kept[t] = !kept.is_empty()
            && problem
                .params
                .kept_scale_min_rejected
                .is_some_and(|min| fraction >= min);
        let mut abs = if from_kept[t] { kept } else { all };
        abs.sort_by(f64::total_cmp);
        let median = abs[abs.len() / 2];
        let scale = (1.4826 * median).max(problem.sigma(kind));
        let c = problem.params.tukey_c * scale;
        for (frame, res) in problem.frames.iter_mut().zip(residuals) {
            for (i, &(e, _)) in res.iter().enumerate() {
                if frame.kind(i) != kind {
                    continue;
                }
                let r = e / c;
                frame.robust[i] = if r.abs() < 1.0 {
                    (1.0 - r * r).powi(2)
                } else {
                    0.0
                };
            }
        }
    }
    (rejected, from_kept)
}

/// The half-width of Eq. 3 that best fits `points` around bone `b` of `state` (its length
/// and pose fixed): the 1-D least-squares minimiser of `Σ e²` (golden-section search over
/// 1 mm … 1 m). Validation uses it on the true limb's vertices as the reference width.
///
/// # Errors
/// A bad bone index or state; [`Error::Empty`] without points.
pub fn fit_half_width(
    model: &EllipsoidModel,
    state: &EllipsoidState,
    b: usize,
    points: &[DVec3],
) -> Result<f64> {
    check::index("bone", b, model.bones.len())?;
    if points.is_empty() {
        return Err(Error::Empty {
            what: "limb points",
        });
    }
    let sk = model.scaled_skeleton(state)?;
    let fk = sk.forward_kinematics(&state.theta)?;
    let frames = fk.world_from_joint();
    let mut s = state.clone();
    let mut cost = |w: f64| {
        s.half_width[b] = w;
        points
            .iter()
            .map(|&x| model.eval(frames, &s, b, x).e.powi(2))
            .sum::<f64>()
    };
    let (mut lo, mut hi) = (0.001_f64, 1.0_f64);
    let phi = 0.5 * (5f64.sqrt() - 1.0);
    for _ in 0..80 {
        let m1 = hi - phi * (hi - lo);
        let m2 = lo + phi * (hi - lo);
        if cost(m1) < cost(m2) {
            hi = m2;
        } else {
            lo = m1;
        }
    }
    Ok(0.5 * (lo + hi))
}

#[cfg(test)]
mod tests;
#[cfg(feature = "validation")]
mod validation;
#[cfg(feature = "validation")]
pub use validation::{
    ellipsoid_scenario, score_ellipsoids, EllipsoidScenario, EllipsoidScenarioParams,
    EllipsoidScores, ScenarioFrame, ScenarioMotion,
};
