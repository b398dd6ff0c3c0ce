//! The parameters of the ellipsoid fit: a-priori σ per observation type (Eq. 7), the priors
//! on the starting state, the IRLS (§5.2) and Levenberg–Marquardt budgets, the bounds.

use skin_core::check;

use crate::error::Result;

/// Parameters of [`fit_ellipsoids`](crate::fit_ellipsoids). The paper gives no numbers; the
/// defaults are ours and documented per field.
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
    /// the given poses' root (docs/template-silhouette.md, "Options and their measured
    /// trade-offs": with it free the joint fit lifts the pelvis by 6 cm and lengthens the
    /// thighs to reach the knees).
    pub sigma_translation_prior_m: Option<f64>,
    /// σ of the prior pulling each length scale to 1. Default 0.2.
    pub sigma_scale_prior: f64,
    /// σ of the prior pulling an end-site segment's length scale (a hand, a foot, the head:
    /// [`EllipsoidModel::with_end_sites`](crate::EllipsoidModel::with_end_sites)) to 1. Its
    /// scale moves no joint, only the ellipsoid's extent along a limb that continues the last
    /// bone, so it trades freely with that bone's length (measured on the studio, 8-frame fit
    /// with σ = 0.2 as the limbs': the right forearm to the scale box's top, +62 mm, its hand
    /// to the bottom, −38 mm).
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
    /// ([`fit_ellipsoids`](crate::fit_ellipsoids) errors). Default 0.005.
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
    /// with this default). Details in docs/template-silhouette.md ("Options and their measured trade-offs").
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

    pub(super) fn validate(&self) -> Result<()> {
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
