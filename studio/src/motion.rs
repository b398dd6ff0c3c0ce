//! Procedural motions for the studio's performers: a range-of-motion sequence that takes every
//! limited DOF to both of its limits, a fast, jerky motion to stress trackers and the flap
//! dynamics, and a free multi-DOF exercise that moves every limited DOF at once through most of
//! its range. All return a [`Motion`] (resample with [`Motion::resample`]); BVH playback is in
//! [`retarget`](super::retarget).
//!
//! Two measures tell such motions apart: [`range_coverage`] (how much of each DOF's range a
//! motion visits) and [`max_pose_share`] (how long the most-held pose of any bone is held).

use nalgebra::DMatrix;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use skin_core::check::{in_range, positive};
use skin_core::skeleton::{Motion, Skeleton};
use skin_core::{Error, Result};
use std::collections::HashMap;
use std::f64::consts::TAU;

/// Parameters of [`range_of_motion`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RangeOfMotionParams {
    /// Frame time, seconds. Default: 1/30.
    pub frame_time_s: f64,
    /// Time spent on each DOF (rest → max → rest → min → rest), seconds. Default: 2.0.
    pub seconds_per_dof: f64,
    /// Fraction of each limit reached (1 = the limit itself). Default: 1.0.
    pub reach: f64,
    /// Rate at which the performer turns on the spot (root yaw, `pelvis.yaw`), degrees per
    /// second, while exercising its DOFs. Default: 0 (faces the same way throughout).
    ///
    /// Silhouette methods need it: a body that never turns shows each surface patch to fixed
    /// cameras from the same few directions only, so a visual-hull bound never tightens
    /// (Sand 2003 §1: "when the subject moves, many observations of the same local geometries
    /// allow the construction of a complete model").
    pub turn_deg_per_s: f64,
}

impl Default for RangeOfMotionParams {
    fn default() -> Self {
        RangeOfMotionParams {
            frame_time_s: 1.0 / 30.0,
            seconds_per_dof: 2.0,
            reach: 1.0,
            turn_deg_per_s: 0.0,
        }
    }
}

/// The root's unlimited yaw DOF (`pelvis.yaw` of [`skin_core::skeleton::human_skeleton`]).
fn root_yaw(skeleton: &Skeleton) -> Option<usize> {
    skeleton
        .dof_index("pelvis.yaw")
        .filter(|&d| skeleton.is_rotation(d) && skeleton.dof(d).limits.is_none())
}

/// Parameters of [`fast_motion`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FastMotionParams {
    /// Frame time, seconds. Default: 1/60 (fast motion needs a high rate).
    pub frame_time_s: f64,
    /// Duration, seconds. Default: 4.0.
    pub duration_s: f64,
    /// Lowest and highest oscillation frequency of a DOF, Hz. Default: (1.5, 3.0) — brisk
    /// limb swings (a sprint's stride is ≈ 1.5 Hz per leg).
    pub frequency_hz: (f64, f64),
    /// Fraction of each DOF's range swept. Default: 0.6.
    pub amplitude: f64,
    /// Vertical bounce of the root, metres (peak). Default: 0.08.
    pub bounce_m: f64,
    /// Ramp-in time from rest, seconds (smooth start). Default: 0.3.
    pub ramp_s: f64,
    /// Seed of the random frequencies and phases. Default: 7.
    pub seed: u64,
}

impl Default for FastMotionParams {
    fn default() -> Self {
        FastMotionParams {
            frame_time_s: 1.0 / 60.0,
            duration_s: 4.0,
            frequency_hz: (1.5, 3.0),
            amplitude: 0.6,
            bounce_m: 0.08,
            ramp_s: 0.3,
            seed: 7,
        }
    }
}

fn frames_for(
    name: &'static str,
    duration_s: f64,
    frame_time_s: f64,
    dofs: usize,
) -> Result<usize> {
    let n = (duration_s / frame_time_s).round() + 1.0;
    if n * dofs as f64 > 1e8 {
        return Err(Error::InvalidParam {
            name,
            reason: format!("{n} frames of {dofs} DOFs is too many"),
        });
    }
    Ok(n as usize)
}

/// A range-of-motion sequence: every rotation DOF with limits is exercised in turn, in θ
/// order, going smoothly from rest to `reach × max`, back, to `reach × min` and back
/// (`θ = s·max` while `s = sin(2πu) > 0`, `θ = −s·min` otherwise, `u ∈ [0, 1]` over
/// `seconds_per_dof`); all other DOFs stay at 0. Limits that exclude 0 are approached from the
/// nearest bound. The sequence starts at rest and ends with every limited DOF at rest; with
/// `turn_deg_per_s ≠ 0` the root yaw turns at that constant rate throughout.
///
/// # Errors
/// [`Error::InvalidParam`] for non-positive or non-finite times, `reach` outside (0, 1], a
/// non-finite turn rate, a turn rate on a skeleton without an unlimited `pelvis.yaw`, a
/// skeleton without limited rotation DOFs, or more than 10⁸ values.
pub fn range_of_motion(skeleton: &Skeleton, params: &RangeOfMotionParams) -> Result<Motion> {
    positive("frame_time_s", params.frame_time_s)?;
    positive("seconds_per_dof", params.seconds_per_dof)?;
    if !(params.reach > 0.0 && params.reach <= 1.0) {
        return Err(Error::InvalidParam {
            name: "reach",
            reason: format!("must be in (0, 1], got {}", params.reach),
        });
    }
    let turn = turn_of(skeleton, params.turn_deg_per_s)?;
    let limited = limited_rotations(skeleton);
    if limited.is_empty() {
        return Err(Error::InvalidParam {
            name: "skeleton",
            reason: "has no limited rotation DOF to exercise".into(),
        });
    }
    let per = params.seconds_per_dof;
    let n = frames_for(
        "seconds_per_dof",
        per * limited.len() as f64,
        params.frame_time_s,
        skeleton.dof_count(),
    )?;
    let mut frames = DMatrix::zeros(skeleton.dof_count(), n);
    for k in 0..n {
        let t = k as f64 * params.frame_time_s;
        if let Some((yaw, rate)) = turn {
            frames[(yaw, k)] = rate * t;
        }
        let seg = ((t / per).floor() as usize).min(limited.len() - 1);
        let u = ((t - seg as f64 * per) / per).clamp(0.0, 1.0);
        let d = limited[seg];
        // `limited` holds only DOFs with limits.
        let Some(l) = skeleton.dof(d).limits else {
            continue;
        };
        let (lo, hi) = (l.min.min(0.0), l.max.max(0.0));
        let s = (TAU * u).sin();
        let v = if s > 0.0 { s * hi } else { -s * lo };
        frames[(d, k)] = l.clamp(v * params.reach);
    }
    Motion::new(params.frame_time_s, frames)
}

/// A fast motion: every limited rotation DOF oscillates about the middle of its range (clamped
/// to include rest) at a random frequency in `frequency_hz` and random phase, sweeping
/// `amplitude` of its range, while the root bounces vertically and yaws; everything ramps in
/// from rest over `ramp_s` with a smoothstep, so frame 0 is the rest pose. Deterministic for a
/// given seed.
///
/// # Errors
/// [`Error::InvalidParam`] for non-positive or non-finite times or frequencies, an amplitude
/// outside (0, 1], or more than 10⁸ values.
pub fn fast_motion(skeleton: &Skeleton, params: &FastMotionParams) -> Result<Motion> {
    positive("frame_time_s", params.frame_time_s)?;
    positive("duration_s", params.duration_s)?;
    positive("ramp_s", params.ramp_s)?;
    let (f0, f1) = params.frequency_hz;
    positive("frequency_hz", f0)?;
    positive("frequency_hz", f1)?;
    if f1 < f0
        || !(params.amplitude > 0.0 && params.amplitude <= 1.0)
        || !params.bounce_m.is_finite()
    {
        return Err(Error::InvalidParam {
            name: "fast motion",
            reason: format!(
                "need frequency min ≤ max, amplitude in (0, 1] and a finite bounce, got {:?}, {}, {}",
                params.frequency_hz, params.amplitude, params.bounce_m
            ),
        });
    }
    let n = frames_for(
        "duration_s",
        params.duration_s,
        params.frame_time_s,
        skeleton.dof_count(),
    )?;
    let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
    let nd = skeleton.dof_count();
    // (centre, half-amplitude, frequency, phase) per DOF.
    let mut waves = vec![(0.0, 0.0, 0.0, 0.0); nd];
    for (d, w) in waves.iter_mut().enumerate() {
        let freq = f0 + (f1 - f0) * rng.random::<f64>();
        let phase = TAU * rng.random::<f64>();
        let dof = skeleton.dof(d);
        *w = match (skeleton.is_rotation(d), dof.limits) {
            (true, Some(l)) => {
                let half = 0.5 * (l.max - l.min) * params.amplitude;
                let centre = (0.5 * (l.min + l.max)).clamp(l.min + half, l.max - half);
                (centre, half, freq, phase)
            }
            (true, None) if Some(d) == root_yaw(skeleton) => (0.0, 0.6, 0.5 * f0, phase),
            (false, None) if dof.axis.y.abs() > 0.9 => (0.0, params.bounce_m, 2.0 * f0, 0.0),
            _ => (0.0, 0.0, 0.0, 0.0),
        };
    }
    let mut frames = DMatrix::zeros(nd, n);
    for k in 0..n {
        let t = k as f64 * params.frame_time_s;
        let x = (t / params.ramp_s).clamp(0.0, 1.0);
        let ramp = x * x * (3.0 - 2.0 * x);
        for (d, &(c, a, f, ph)) in waves.iter().enumerate() {
            // Offset by sin(ph) so the oscillation itself starts at the centre.
            let v = c + a * ((TAU * f * t + ph).sin() - ph.sin());
            let v = match skeleton.dof(d).limits {
                Some(l) => l.clamp(v),
                None => v,
            };
            frames[(d, k)] = ramp * v;
        }
    }
    Motion::new(params.frame_time_s, frames)
}

/// Sinusoids summed per DOF by [`exercise_motion`]: enough for a non-periodic path that turns
/// at many levels, few enough that each one stays a visible swing.
const EXERCISE_COMPONENTS: usize = 3;

/// Knots of the monotone warp that makes each exercised DOF's occupancy uniform (each knot
/// interval holds 1/64 of the frames, about 2° of a 120° range; 32 knots leave ≈ 10 % more
/// frames in the knee's fullest 5° cell).
const EXERCISE_WARP_KNOTS: usize = 64;

impl ExerciseParams {
    /// Default duration of [`exercise_motion`], seconds: the 5-minute acceptance run.
    pub const DEFAULT_DURATION_S: f64 = 300.0;

    /// Default turn rate of [`exercise_motion`], degrees per second: one turn every 30 s.
    pub const DEFAULT_TURN_DEG_PER_S: f64 = 12.0;
}

/// Parameters of [`exercise_motion`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ExerciseParams {
    /// Frame time, seconds. Default: 1/30 (the studio's video rate).
    pub frame_time_s: f64,
    /// Duration, seconds. Default: [`ExerciseParams::DEFAULT_DURATION_S`] = 300 (the 5 minutes over
    /// which the acceptance figures are measured).
    pub duration_s: f64,
    /// Lowest and highest frequency of a DOF's sinusoids, Hz; the lower must be below the
    /// higher. Default: (0.05, 0.3) — a slow, deliberate exercise (one swing in 3–20 s), slow
    /// enough for 30 fps and for silhouettes to change gradually.
    pub frequency_hz: (f64, f64),
    /// Fraction of each DOF's range used, centred in the range, in (0, 1]. Default: 0.9 —
    /// close to the limits without resting on them.
    pub reach: f64,
    /// Rate at which the performer turns on the spot (root yaw, `pelvis.yaw`), degrees per
    /// second, as [`RangeOfMotionParams::turn_deg_per_s`]. Default:
    /// [`ExerciseParams::DEFAULT_TURN_DEG_PER_S`] = 12 — one turn every 30 s, ten in 5 minutes;
    /// below the frequency band, so every limb pose is seen from many directions by fixed
    /// cameras. It does not enter [`range_coverage`] or [`max_pose_share`] (the root is not
    /// counted), so any rate meets the acceptance.
    pub turn_deg_per_s: f64,
    /// Seed of the random frequencies and phases: different seeds give different motions.
    /// Default: 11.
    pub seed: u64,
}

impl Default for ExerciseParams {
    fn default() -> Self {
        ExerciseParams {
            frame_time_s: 1.0 / 30.0,
            duration_s: ExerciseParams::DEFAULT_DURATION_S,
            frequency_hz: (0.05, 0.3),
            reach: 0.9,
            turn_deg_per_s: ExerciseParams::DEFAULT_TURN_DEG_PER_S,
            seed: 11,
        }
    }
}

impl ExerciseParams {
    /// With `duration_s` replaced.
    pub fn with_duration_s(self, duration_s: f64) -> Self {
        ExerciseParams { duration_s, ..self }
    }

    /// With `seed` replaced.
    pub fn with_seed(self, seed: u64) -> Self {
        ExerciseParams { seed, ..self }
    }

    /// With `turn_deg_per_s` replaced.
    pub fn with_turn_deg_per_s(self, turn_deg_per_s: f64) -> Self {
        ExerciseParams {
            turn_deg_per_s,
            ..self
        }
    }
}

/// The root yaw DOF and its rate (rad/s) for a turn rate in degrees per second: `None` for 0.
fn turn_of(skeleton: &Skeleton, turn_deg_per_s: f64) -> Result<Option<(usize, f64)>> {
    match (turn_deg_per_s, root_yaw(skeleton)) {
        (0.0, _) => Ok(None),
        (r, Some(d)) if r.is_finite() => Ok(Some((d, r.to_radians()))),
        (r, _) => Err(Error::InvalidParam {
            name: "turn_deg_per_s",
            reason: format!(
                "must be finite, and non-zero only with an unlimited pelvis.yaw; got {r}"
            ),
        }),
    }
}

/// The rotation DOFs with limits, in θ order: those the procedural motions exercise and
/// [`range_coverage`] measures.
fn limited_rotations(skeleton: &Skeleton) -> Vec<usize> {
    (0..skeleton.dof_count())
        .filter(|&d| skeleton.is_rotation(d) && skeleton.dof(d).limits.is_some())
        .collect()
}

/// A monotone, C¹ map from a signal's values onto [−1, 1] that spreads its samples evenly:
/// knots at the signal's quantiles `i/K` map to `−1 + 2i/K`, joined by the monotone cubic
/// Hermite interpolant of Fritsch & Carlson (1980) with harmonic-mean tangents.
struct UniformWarp {
    x: Vec<f64>,
    y: Vec<f64>,
    slope: Vec<f64>,
}

impl UniformWarp {
    /// The warp of `samples` (finite) with `knots` intervals; `None` when the samples span no
    /// interval (e.g. a single frame).
    fn of(samples: &[f64], knots: usize) -> Option<Self> {
        let sorted = skin_core::stats::sorted(samples);
        let (mut x, mut y) = (Vec::new(), Vec::new());
        for i in 0..=knots {
            let q = i as f64 / knots as f64;
            let xi = skin_core::stats::percentile_sorted(&sorted, q);
            // Equal quantiles (a constant stretch) would give an empty interval: keep the first.
            if x.last().is_none_or(|&last| xi > last) {
                x.push(xi);
                y.push(-1.0 + 2.0 * q);
            }
        }
        if x.len() < 2 {
            return None;
        }
        let m = x.len();
        // The last kept knot is the maximum: make it map to 1.
        y[m - 1] = 1.0;
        let secant: Vec<f64> = (0..m - 1)
            .map(|i| (y[i + 1] - y[i]) / (x[i + 1] - x[i]))
            .collect();
        let mut slope = vec![0.0; m];
        slope[0] = secant[0];
        slope[m - 1] = secant[m - 2];
        for i in 1..m - 1 {
            // Harmonic mean ≤ 2·min(secants): the interpolant stays monotone.
            slope[i] = 2.0 / (1.0 / secant[i - 1] + 1.0 / secant[i]);
        }
        Some(UniformWarp { x, y, slope })
    }

    /// The warped value of `v` (clamped to the knots' span).
    fn apply(&self, v: f64) -> f64 {
        let m = self.x.len();
        let i = self.x.partition_point(|&k| k <= v).clamp(1, m - 1) - 1;
        let h = self.x[i + 1] - self.x[i];
        let s = ((v - self.x[i]) / h).clamp(0.0, 1.0);
        let (s2, s3) = (s * s, s * s * s);
        let h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
        let h10 = s3 - 2.0 * s2 + s;
        let h01 = -2.0 * s3 + 3.0 * s2;
        let h11 = s3 - s2;
        (h00 * self.y[i]
            + h10 * h * self.slope[i]
            + h01 * self.y[i + 1]
            + h11 * h * self.slope[i + 1])
            .clamp(-1.0, 1.0)
    }
}

/// A free multi-DOF exercise: every limited rotation DOF moves at once, smoothly and
/// non-periodically, through `reach` of its range (centred in it), while the performer turns on
/// the spot at `turn_deg_per_s`; the root translation, other unlimited DOFs and translations
/// stay at rest. Deterministic for a seed; different seeds give different motions.
///
/// **Construction.** Each limited DOF `d` gets three sinusoids
/// `x_d(t) = ⅓ Σₖ sin(2π f_k t + φ_k)`, one frequency drawn uniformly in each third of
/// `frequency_hz` (distinct and, being random reals, incommensurate) and phases uniform in
/// [0, 2π), all from a `ChaCha8Rng` seeded with `seed`. A plain sum of sinusoids sits near
/// its middle most of the time, so `x_d` is mapped through a monotone C¹ warp onto [−1, 1]
/// that spreads its frames evenly: knots at the 64-quantiles of `x_d` over the motion, joined
/// by a monotone cubic (Fritsch–Carlson). Then
/// `θ_d = mid + reach · half_range · warp(x_d)`. Every DOF thus spends about equal time in
/// every part of its band and reaches both ends of it; turnarounds happen at all levels, as the
/// sum of sinusoids turns. Because the warp is estimated from the whole motion, a longer motion
/// with the same seed is not an extension of a shorter one.
///
/// **Combined poses** come from all DOFs moving at once with independent frequencies: with the
/// defaults, shoulder abduction and elbow flexion are both in the upper 40 % of their ranges in
/// 14–20 % of frames, and likewise hip and knee flexion in 15–16 % (measured in the tests; 15 %
/// for independent DOFs spread evenly over 90 % of their ranges).
///
/// Frame 0 is generally not the rest pose.
///
/// # Errors
/// [`Error::InvalidParam`] for a non-positive or non-finite frame time or duration, a band
/// that is not `0 < min < max` (finite), `reach` outside (0, 1], a non-finite turn rate, a turn
/// rate on a skeleton without an unlimited `pelvis.yaw`, a skeleton without limited rotation
/// DOFs, or more than 10⁸ values.
///
/// # Example
/// ```
/// use skin_core::skeleton::{human_skeleton, HumanParams};
/// use dynamic_shapes_studio::{exercise_motion, max_pose_share, range_coverage, ExerciseParams};
/// let s = human_skeleton(&HumanParams::default())?;
/// let m = exercise_motion(&s, &ExerciseParams::default().with_duration_s(60.0))?;
/// assert_eq!(m.frame_count(), 1801);
/// assert!(range_coverage(&s, &m)?.iter().all(|c| c.coverage > 0.8));
/// assert!(max_pose_share(&s, &m, 5.0)?.share < 0.1);
/// # Ok::<(), skin_core::Error>(())
/// ```
pub fn exercise_motion(skeleton: &Skeleton, params: &ExerciseParams) -> Result<Motion> {
    positive("frame_time_s", params.frame_time_s)?;
    positive("duration_s", params.duration_s)?;
    let (f0, f1) = params.frequency_hz;
    positive("frequency_hz", f0)?;
    positive("frequency_hz", f1)?;
    if f1 <= f0 {
        return Err(Error::InvalidParam {
            name: "frequency_hz",
            reason: format!("the band must satisfy min < max, got ({f0}, {f1})"),
        });
    }
    in_range("reach", positive("reach", params.reach)?, 0.0..=1.0)?;
    let turn = turn_of(skeleton, params.turn_deg_per_s)?;
    let limited = limited_rotations(skeleton);
    if limited.is_empty() {
        return Err(Error::InvalidParam {
            name: "skeleton",
            reason: "has no limited rotation DOF to exercise".into(),
        });
    }
    let nd = skeleton.dof_count();
    let n = frames_for("duration_s", params.duration_s, params.frame_time_s, nd)?;
    let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
    let mut frames = DMatrix::zeros(nd, n);
    if let Some((yaw, rate)) = turn {
        for k in 0..n {
            frames[(yaw, k)] = rate * k as f64 * params.frame_time_s;
        }
    }
    let width = (f1 - f0) / EXERCISE_COMPONENTS as f64;
    let mut x = vec![0.0; n];
    for &d in &limited {
        let waves: Vec<(f64, f64)> = (0..EXERCISE_COMPONENTS)
            .map(|c| {
                let f = f0 + width * (c as f64 + rng.random::<f64>());
                (TAU * f, TAU * rng.random::<f64>())
            })
            .collect();
        for (k, xk) in x.iter_mut().enumerate() {
            let t = k as f64 * params.frame_time_s;
            *xk = waves.iter().map(|&(w, ph)| (w * t + ph).sin()).sum::<f64>()
                / EXERCISE_COMPONENTS as f64;
        }
        // `limited` holds only DOFs with limits.
        let Some(l) = skeleton.dof(d).limits else {
            continue;
        };
        let mid = 0.5 * (l.min + l.max);
        let half = 0.5 * (l.max - l.min) * params.reach;
        let warp = UniformWarp::of(&x, EXERCISE_WARP_KNOTS);
        for (k, &xk) in x.iter().enumerate() {
            let u = warp.as_ref().map_or(0.0, |w| w.apply(xk));
            frames[(d, k)] = l.clamp(mid + half * u);
        }
    }
    Motion::new(params.frame_time_s, frames)
}

/// How much of one limited DOF's range a motion covers (see [`range_coverage`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DofCoverage {
    /// Index of the DOF in θ.
    pub dof: usize,
    /// Fraction of the range covered, in [0, 1].
    pub coverage: f64,
}

/// Lower percentile of [`range_coverage`]'s span (the upper one is `1 −` it).
const COVERAGE_TAIL: f64 = 0.005;

/// The fraction of its range that each limited rotation DOF covers over `motion`, in θ order.
///
/// **Definition.** With the DOF's values clamped into its limits `[min, max]`, the coverage is
/// `(P₉₉.₅ − P₀.₅) / (max − min)`: the span between the 0.5th and 99.5th percentiles
/// ([`skin_core::stats::percentile`]) over the range. The percentiles ignore the 1 % of frames at
/// the extremes, so a single excursion does not count as covering the range (45 frames of a
/// 5-minute motion at 30 fps do not). A DOF whose limits are equal covers its (empty) range:
/// 1. The span says where a DOF went, not how long it stayed; [`max_pose_share`] measures that.
///
/// # Errors
/// As [`Motion::check_for`]; [`Error::Empty`] for a motion without frames.
pub fn range_coverage(skeleton: &Skeleton, motion: &Motion) -> Result<Vec<DofCoverage>> {
    motion.check_for(skeleton)?;
    if motion.frame_count() == 0 {
        return Err(Error::Empty { what: "motion" });
    }
    let mut values = vec![0.0; motion.frame_count()];
    Ok(limited_rotations(skeleton)
        .into_iter()
        .filter_map(|d| {
            let l = skeleton.dof(d).limits?;
            for (k, v) in values.iter_mut().enumerate() {
                *v = l.clamp(motion.frame(k)[d]);
            }
            let sorted = skin_core::stats::sorted(&values);
            let lo = skin_core::stats::percentile_sorted(&sorted, COVERAGE_TAIL);
            let hi = skin_core::stats::percentile_sorted(&sorted, 1.0 - COVERAGE_TAIL);
            let coverage = if l.max > l.min {
                ((hi - lo) / (l.max - l.min)).clamp(0.0, 1.0)
            } else {
                1.0
            };
            Some(DofCoverage { dof: d, coverage })
        })
        .collect())
}

/// The most-held pose of a motion (see [`max_pose_share`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PoseShare {
    /// Share of frames, in (0, 1], in which the bone sits in its most frequent cell.
    pub share: f64,
    /// Index of the joint whose bone it is (the first such joint on a tie).
    pub joint: usize,
}

/// Per joint, the share of frames its bone spends in its most frequent pose cell; `None` for
/// joints that are not counted (the root and joints without rotation DOFs). See
/// [`max_pose_share`] for the definition.
///
/// # Errors
/// As [`Motion::check_for`]; [`Error::InvalidParam`] for a non-positive or non-finite
/// `cell_deg`; [`Error::Empty`] for a motion without frames.
pub fn pose_shares(
    skeleton: &Skeleton,
    motion: &Motion,
    cell_deg: f64,
) -> Result<Vec<Option<f64>>> {
    motion.check_for(skeleton)?;
    let cell = positive("cell_deg", cell_deg)?.to_radians();
    let n = motion.frame_count();
    if n == 0 {
        return Err(Error::Empty { what: "motion" });
    }
    let mut counts: HashMap<Vec<i64>, usize> = HashMap::new();
    Ok((0..skeleton.joint_count())
        .map(|j| {
            // The root (no parent) is not counted.
            skeleton.joints()[j].parent?;
            let dofs: Vec<usize> = skeleton
                .joint_dofs(j)
                .filter(|&d| skeleton.is_rotation(d))
                .collect();
            if dofs.is_empty() {
                return None;
            }
            counts.clear();
            for k in 0..n {
                let theta = motion.frame(k);
                // Poses are finite (checked above); cells beyond i64 saturate, harmlessly.
                let key = dofs
                    .iter()
                    .map(|&d| (theta[d] / cell).floor() as i64)
                    .collect();
                *counts.entry(key).or_insert(0) += 1;
            }
            let most = counts.values().copied().max().unwrap_or(0);
            Some(most as f64 / n as f64)
        })
        .collect())
}

/// The largest share of frames any bone spends in one pose: the studio example's
/// `exercise_max_pose_share`.
///
/// **Definition.** For each bone (a non-root joint with rotation DOFs), its pose in a frame is
/// the cell of `cell_deg`-wide bins (anchored at 0) holding its own rotation DOFs, e.g. the
/// 3-D (flexion, abduction, rotation) cell of a shoulder, i.e. of the upper arm. Its share is
/// the largest cell's count over the frame count; the result is the maximum over bones and the
/// joint attaining it. Parent DOFs are deliberately not included: with the whole chain every
/// distal bone would sit in a 10-plus-dimensional cell that a moving spine alone makes unique
/// in every frame, hiding a held elbow or knee. The root is not counted: its DOFs are the
/// performer's placement and heading, not a limb pose. With 5° cells a 1-DOF knee sweeping
/// 90 % of its 135° range evenly puts ≈ 4 % of frames in each cell; today's
/// [`range_of_motion`] keeps the upper arm in its rest cell ≈ 90 % of the time.
///
/// # Errors
/// As [`pose_shares`]; [`Error::InvalidParam`] when the skeleton has no counted bone.
pub fn max_pose_share(skeleton: &Skeleton, motion: &Motion, cell_deg: f64) -> Result<PoseShare> {
    let shares = pose_shares(skeleton, motion, cell_deg)?;
    let mut best: Option<PoseShare> = None;
    for (joint, s) in shares.into_iter().enumerate() {
        if let Some(share) = s {
            if best.is_none_or(|b| share > b.share) {
                best = Some(PoseShare { share, joint });
            }
        }
    }
    best.ok_or_else(|| Error::InvalidParam {
        name: "skeleton",
        reason: "has no non-root joint with rotation DOFs to measure".into(),
    })
}

#[cfg(test)]
mod tests;
