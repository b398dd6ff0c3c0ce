//! Motions: a sequence of poses θ at a fixed frame rate, and resampling to another rate.

use super::model::Skeleton;
use crate::{Error, Result};
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};
use std::f64::consts::{PI, TAU};

/// A motion: poses θ sampled every `frame_time_s` seconds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Motion {
    /// Time between consecutive frames, seconds (BVH `Frame Time`).
    pub frame_time_s: f64,
    /// Poses, one column per frame (`dof_count × frame_count`); a column is contiguous, so
    /// `frames.column(k).as_slice()` is θ of frame k.
    pub frames: DMatrix<f64>,
}

/// Wraps an angle difference into (−π, π].
fn wrap_angle(a: f64) -> f64 {
    let w = (a + PI).rem_euclid(TAU) - PI;
    if w <= -PI {
        w + TAU
    } else {
        w
    }
}

impl Motion {
    /// Builds a motion, checking the frame time and values.
    ///
    /// # Errors
    /// [`Error::InvalidParam`] unless `frame_time_s` is finite and positive;
    /// [`Error::NonFinite`] for NaN/inf poses.
    pub fn new(frame_time_s: f64, frames: DMatrix<f64>) -> Result<Self> {
        crate::check::positive("frame_time_s", frame_time_s)?;
        crate::check::all_finite("motion frames", frames.iter())?;
        Ok(Motion {
            frame_time_s,
            frames,
        })
    }

    /// Number of frames.
    pub fn frame_count(&self) -> usize {
        self.frames.ncols()
    }

    /// θ of frame `k`.
    ///
    /// # Panics
    /// If `k >= frame_count()`.
    pub fn frame(&self, k: usize) -> &[f64] {
        let n = self.frames.nrows();
        &self.frames.as_slice()[k * n..(k + 1) * n]
    }

    /// Duration from the first to the last frame, seconds.
    pub fn duration_s(&self) -> f64 {
        self.frame_count().saturating_sub(1) as f64 * self.frame_time_s
    }

    /// Checks that every frame is a valid pose of `skeleton`.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if the row count is not `skeleton.dof_count()`; as
    /// [`Skeleton::check_pose`] (naming the joint) for a non-finite value.
    pub fn check_for(&self, skeleton: &Skeleton) -> Result<()> {
        if self.frames.nrows() != skeleton.dof_count() {
            return Err(Error::SizeMismatch {
                what: "motion rows (DOFs)",
                expected: skeleton.dof_count(),
                got: self.frames.nrows(),
            });
        }
        (0..self.frame_count()).try_for_each(|k| skeleton.check_pose("motion frame", self.frame(k)))
    }

    /// Resamples to a new frame time, keeping the first frame and the time span (the last
    /// new frame is the last one at or before the old duration).
    ///
    /// **Interpolation.** DOF-wise linear, with rotation DOFs interpolated along the shorter
    /// arc: between frames a and b the value is `a + s·wrap(b − a)`, `wrap` into (−π, π]. This
    /// removes the ±180° jumps of Euler-angle data (BVH) without leaving the original value
    /// range. For the joint rotations of mocap data (steps of a few degrees per frame at 30–120
    /// Hz) it agrees with per-joint quaternion slerp to second order in the step, while
    /// keeping θ in the skeleton's own DOF parameterisation (limits, names, any axes).
    /// Translations are interpolated linearly.
    ///
    /// # Errors
    /// As [`Motion::check_for`]; [`Error::InvalidParam`] for a non-positive or non-finite
    /// `new_frame_time_s` or a result of more than 10⁸ values.
    pub fn resample(&self, skeleton: &Skeleton, new_frame_time_s: f64) -> Result<Motion> {
        self.check_for(skeleton)?;
        crate::check::positive("new_frame_time_s", new_frame_time_s)?;
        let n_old = self.frame_count();
        let n_dof = skeleton.dof_count();
        // The same rate (to 1e-12 relative, e.g. 1/(1/dt)) keeps the frames bit for bit rather
        // than re-interpolating them at positions that round to just below each frame.
        if (new_frame_time_s - self.frame_time_s).abs() <= 1e-12 * self.frame_time_s {
            return Ok(self.clone());
        }
        if n_old <= 1 {
            return Motion::new(new_frame_time_s, self.frames.clone());
        }
        // Tolerance so that an exact multiple of the new frame time keeps the last frame.
        let span = self.duration_s() / new_frame_time_s;
        let n_new_f = (span + 1e-9).floor() + 1.0;
        if n_new_f * n_dof as f64 > 1e8 {
            return Err(Error::InvalidParam {
                name: "new_frame_time_s",
                reason: format!("{new_frame_time_s} s would give {n_new_f} frames"),
            });
        }
        let n_new = n_new_f as usize;
        let rotation: Vec<bool> = (0..n_dof).map(|d| skeleton.is_rotation(d)).collect();
        let mut out = DMatrix::zeros(n_dof, n_new);
        for k in 0..n_new {
            let s = k as f64 * new_frame_time_s / self.frame_time_s;
            let i = (s.floor() as usize).min(n_old - 2);
            let f = (s - i as f64).clamp(0.0, 1.0);
            let (a, b) = (self.frame(i), self.frame(i + 1));
            for d in 0..n_dof {
                let delta = if rotation[d] {
                    wrap_angle(b[d] - a[d])
                } else {
                    b[d] - a[d]
                };
                out[(d, k)] = a[d] + f * delta;
            }
        }
        Motion::new(new_frame_time_s, out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::DVec3;
    use crate::skeleton::{Dof, Joint};

    fn skel() -> Skeleton {
        Skeleton::new(vec![Joint::new(
            "root",
            None,
            DVec3::ZERO,
            vec![
                Dof::translation("tx", DVec3::X, None),
                Dof::rotation("ry", DVec3::Y, None),
            ],
        )])
        .unwrap()
    }

    #[test]
    fn wrap_is_in_range() {
        for a in [-10.0, -PI, -3.0, 0.0, 3.0, PI, 10.0] {
            let w = wrap_angle(a);
            assert!(w > -PI - 1e-15 && w <= PI + 1e-15);
            assert!(((a - w) / TAU - ((a - w) / TAU).round()).abs() < 1e-12);
        }
    }

    #[test]
    fn resample_linear_and_shortest_arc() {
        let s = skel();
        // Translation 0 → 1; rotation 170° → -170° (a 20° step through 180°).
        let frames = DMatrix::from_column_slice(
            2,
            2,
            &[0.0, 170f64.to_radians(), 1.0, (-170f64).to_radians()],
        );
        let m = Motion::new(0.1, frames).unwrap();
        let r = m.resample(&s, 0.025).unwrap();
        assert_eq!(r.frame_count(), 5);
        assert!((r.frame(2)[0] - 0.5).abs() < 1e-12);
        assert!(
            (r.frame(2)[1] - PI).abs() < 1e-12,
            "halfway through the short arc is 180°"
        );
        assert!((r.frame(4)[0] - 1.0).abs() < 1e-12);
        assert!((wrap_angle(r.frame(4)[1] - (-170f64).to_radians())).abs() < 1e-12);
        // Downsampling of a smooth motion reproduces the samples.
        let n = 121;
        let frames = DMatrix::from_fn(2, n, |d, k| {
            if d == 0 {
                k as f64 * 0.01
            } else {
                (k as f64 * 0.05).sin()
            }
        });
        let m = Motion::new(1.0 / 120.0, frames).unwrap();
        let r = m.resample(&s, 1.0 / 30.0).unwrap();
        assert_eq!(r.frame_count(), 31);
        for k in 0..31 {
            assert!((r.frame(k)[1] - m.frame(4 * k)[1]).abs() < 1e-12);
        }
        // Upsampling error of a smooth curve is small (linear interpolation, O(h²)).
        let up = m.resample(&s, 1.0 / 240.0).unwrap();
        assert_eq!(up.frame_count(), 241);
        let t: f64 = 11.0 / 240.0;
        // Bound h²/8·max|f″| with h = 0.05 rad per old frame.
        assert!((up.frame(11)[1] - (t * 120.0 * 0.05).sin()).abs() < 0.05f64.powi(2) / 8.0);
    }

    #[test]
    fn resample_rejects_bad_input() {
        let s = skel();
        let m = Motion::new(0.1, DMatrix::zeros(2, 3)).unwrap();
        assert!(m.resample(&s, 0.0).is_err());
        assert!(m.resample(&s, f64::NAN).is_err());
        assert!(m.resample(&s, 1e-12).is_err());
        let wrong = Motion::new(0.1, DMatrix::zeros(3, 3)).unwrap();
        assert!(matches!(
            wrong.resample(&s, 0.05),
            Err(Error::SizeMismatch { .. })
        ));
        assert!(Motion::new(0.0, DMatrix::zeros(2, 1)).is_err());
        assert!(Motion::new(0.1, DMatrix::from_element(2, 1, f64::NAN)).is_err());
        let mut nan = m.clone();
        nan.frames[(1, 2)] = f64::NAN;
        let err = nan.check_for(&s).unwrap_err().to_string();
        assert!(err.contains("root") && err.contains("ry"), "{err}");
        assert_eq!(
            Motion::new(0.1, DMatrix::zeros(2, 1))
                .unwrap()
                .resample(&s, 0.05)
                .unwrap()
                .frame_count(),
            1
        );
    }
}
