//! Procedural motions for the studio's performers: a range-of-motion sequence that takes every
//! limited DOF to both of its limits, and a fast, jerky motion to stress trackers and the flap
//! dynamics. Both return a [`Motion`] (resample with [`Motion::resample`]); BVH playback is in
//! [`retarget`](super::retarget).

use crate::check::positive;
use crate::skeleton::{Motion, Skeleton};
use crate::{Error, Result};
use nalgebra::DMatrix;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
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

/// The root's unlimited yaw DOF (`pelvis.yaw` of [`crate::skeleton::human_skeleton`]).
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
    let turn = match (params.turn_deg_per_s, root_yaw(skeleton)) {
        (0.0, _) => None,
        (r, Some(d)) if r.is_finite() => Some((d, r.to_radians())),
        (r, _) => {
            return Err(Error::InvalidParam {
                name: "turn_deg_per_s",
                reason: format!(
                    "must be finite, and non-zero only with an unlimited pelvis.yaw; got {r}"
                ),
            })
        }
    };
    let limited: Vec<usize> = (0..skeleton.dof_count())
        .filter(|&d| skeleton.is_rotation(d) && skeleton.dof(d).limits.is_some())
        .collect();
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::skeleton::{human_skeleton, HumanParams};

    #[test]
    fn rom_reaches_every_limit_and_stays_inside() {
        let s = human_skeleton(&HumanParams::default()).unwrap();
        let m = range_of_motion(&s, &RangeOfMotionParams::default()).unwrap();
        m.check_for(&s).unwrap();
        let h = 1.0 / 30.0 * 2.0 * std::f64::consts::PI / 2.0; // one step of u in radians of sin
        for d in 0..s.dof_count() {
            let row: Vec<f64> = (0..m.frame_count()).map(|k| m.frame(k)[d]).collect();
            match s.dof(d).limits {
                Some(l) if s.is_rotation(d) => {
                    let max = row.iter().copied().fold(f64::MIN, f64::max);
                    let min = row.iter().copied().fold(f64::MAX, f64::min);
                    assert!(max <= l.max + 1e-12 && min >= l.min - 1e-12);
                    let tol = (l.max - l.min) * h * h;
                    assert!(
                        max >= l.max.max(0.0) - tol && min <= l.min.min(0.0) + tol,
                        "{}: {min}..{max}",
                        s.dof(d).name
                    );
                }
                _ => assert!(row.iter().all(|&v| v == 0.0)),
            }
        }
        assert!(m
            .frame(0)
            .iter()
            .chain(m.frame(m.frame_count() - 1))
            .all(|v| v.abs() < 1e-9));
    }

    #[test]
    fn rom_can_turn_on_the_spot() {
        let s = human_skeleton(&HumanParams::default()).unwrap();
        let p = RangeOfMotionParams {
            turn_deg_per_s: 60.0,
            ..Default::default()
        };
        let m = range_of_motion(&s, &p).unwrap();
        let still = range_of_motion(&s, &RangeOfMotionParams::default()).unwrap();
        let yaw = s.dof_index("pelvis.yaw").unwrap();
        for k in [0, 1, 100, m.frame_count() - 1] {
            let t = k as f64 * p.frame_time_s;
            assert!((m.frame(k)[yaw] - 60f64.to_radians() * t).abs() < 1e-12);
            // Everything else is the still range of motion.
            for d in (0..s.dof_count()).filter(|&d| d != yaw) {
                assert_eq!(m.frame(k)[d], still.frame(k)[d]);
            }
        }
        for bad in [f64::NAN, f64::INFINITY] {
            let p = RangeOfMotionParams {
                turn_deg_per_s: bad,
                ..Default::default()
            };
            assert!(range_of_motion(&s, &p).is_err());
        }
    }

    #[test]
    fn fast_motion_is_fast_bounded_and_deterministic() {
        let s = human_skeleton(&HumanParams::default()).unwrap();
        let p = FastMotionParams::default();
        let m = fast_motion(&s, &p).unwrap();
        assert_eq!(m, fast_motion(&s, &p).unwrap());
        assert!(s.limit_violations(m.frame(0)).unwrap().is_empty());
        assert!(m.frame(0).iter().all(|v| v.abs() < 1e-12), "starts at rest");
        for k in 0..m.frame_count() {
            assert!(s.limit_violations(m.frame(k)).unwrap().is_empty());
        }
        // Peak elbow speed above 3 rad/s: genuinely fast.
        let d = s.dof_index("l_elbow.flexion").unwrap();
        let speed = (1..m.frame_count())
            .map(|k| (m.frame(k)[d] - m.frame(k - 1)[d]).abs() / m.frame_time_s)
            .fold(0.0, f64::max);
        assert!(speed > 3.0, "{speed}");
        let other = fast_motion(&s, &FastMotionParams { seed: 8, ..p }).unwrap();
        assert_ne!(m, other);
    }

    #[test]
    fn rejects_bad_params() {
        let s = human_skeleton(&HumanParams::default()).unwrap();
        let r = RangeOfMotionParams::default();
        assert!(range_of_motion(
            &s,
            &RangeOfMotionParams {
                frame_time_s: 0.0,
                ..r
            }
        )
        .is_err());
        assert!(range_of_motion(&s, &RangeOfMotionParams { reach: 1.5, ..r }).is_err());
        assert!(range_of_motion(
            &s,
            &RangeOfMotionParams {
                seconds_per_dof: f64::NAN,
                ..r
            }
        )
        .is_err());
        assert!(range_of_motion(
            &s,
            &RangeOfMotionParams {
                frame_time_s: 1e-12,
                ..r
            }
        )
        .is_err());
        let f = FastMotionParams::default();
        assert!(fast_motion(
            &s,
            &FastMotionParams {
                amplitude: 0.0,
                ..f
            }
        )
        .is_err());
        assert!(fast_motion(
            &s,
            &FastMotionParams {
                frequency_hz: (3.0, 1.0),
                ..f
            }
        )
        .is_err());
        assert!(fast_motion(
            &s,
            &FastMotionParams {
                duration_s: -1.0,
                ..f
            }
        )
        .is_err());
        let free = Skeleton::new(vec![crate::skeleton::Joint::new(
            "a",
            None,
            crate::math::DVec3::ZERO,
            vec![],
        )])
        .unwrap();
        assert!(range_of_motion(&free, &r).is_err());
    }
}
