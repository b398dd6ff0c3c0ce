//! Synchronisation of video and motion capture from silhouettes (Sand 2003 §4.1–4.2).
//!
//! The method is documented on [`estimate_sync_offset`]; the module is private and
//! everything public is re-exported at the crate root.

use nalgebra::DVector;
use serde::{Deserialize, Serialize};
use skin_core::camera::Camera;
use skin_core::image::{distance_to_foreground, sample_bilinear, GrayF32Image, Mask};
use skin_core::optim::{nelder_mead, NelderMeadParams};
use skin_core::skeleton::{AttachedPoint, ForwardKinematics, Motion, Skeleton};

use crate::config::resolve_marker;
use crate::error::{Error, Result};

impl SyncParams {
    /// Default of [`SyncParams::cap_px`].
    pub const DEFAULT_CAP_PX: f64 = 20.0;

    /// Default of [`SyncParams::initial_step_s`].
    pub const DEFAULT_INITIAL_STEP_S: f64 = 0.1;
}

/// Knobs of [`estimate_sync_offset`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SyncParams {
    /// Markers whose projections are pulled into the silhouettes (see [`crate::resolve_marker`] for
    /// the syntax). Sand §4.2 uses "arm and leg markers": they move fastest, so they carry the
    /// most timing information. Default: elbows, wrists, fingertips, knees, ankles, toe tips.
    pub markers: Vec<String>,
    /// Cap on one marker's distance to the silhouette, px. Default: 20 px.
    pub cap_px: f64,
    /// Initial simplex step, s: the expected size of the offset's error. Default: 0.1 s.
    pub initial_step_s: f64,
    /// Maximum objective evaluations. Default: 400.
    pub max_evaluations: usize,
}

impl Default for SyncParams {
    fn default() -> Self {
        let markers = [
            "l_elbow",
            "r_elbow",
            "l_wrist",
            "r_wrist",
            "l_wrist.tip",
            "r_wrist.tip",
            "l_knee",
            "r_knee",
            "l_ankle",
            "r_ankle",
            "l_ankle.tip",
            "r_ankle.tip",
        ];
        Self {
            markers: markers.iter().map(|s| s.to_string()).collect(),
            cap_px: SyncParams::DEFAULT_CAP_PX,
            initial_step_s: SyncParams::DEFAULT_INITIAL_STEP_S,
            max_evaluations: 400,
        }
    }
}

/// One video frame: its time on the video clock and one silhouette per camera.
#[derive(Debug, Clone, Copy)]
pub struct VideoFrame<'a> {
    /// Video time, s.
    pub time_s: f64,
    /// Silhouettes, one per camera, each of its camera's size.
    pub masks: &'a [Mask],
}

/// Result of [`estimate_sync_offset`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SyncResult {
    /// Offset, s: video time `t` shows the motion at `t + offset_s`.
    pub offset_s: f64,
    /// Mean capped marker-to-silhouette distance at the offset, px.
    pub mean_distance_px: f64,
    /// Objective evaluations used.
    pub evaluations: usize,
    /// Whether the simplex converged (false: the evaluation limit stopped it).
    pub converged: bool,
}

/// θ at time `t_s` (s, motion clock starting at 0), interpolated linearly between frames with
/// rotations along the shorter arc; times outside the motion are clamped to its ends.
///
/// # Errors
/// [`Error::NonFinite`] for a non-finite time; [`Error::SizeMismatch`] if the motion is not
/// for `skeleton`; [`Error::Empty`] for a motion without frames.
pub fn sample_motion(skeleton: &Skeleton, motion: &Motion, t_s: f64) -> Result<Vec<f64>> {
    if !t_s.is_finite() {
        return Err(Error::NonFinite { what: "time" });
    }
    let n = motion.frame_count();
    if n == 0 {
        return Err(Error::Empty {
            what: "motion frames",
        });
    }
    if motion.frames.nrows() != skeleton.dof_count() {
        return Err(Error::SizeMismatch {
            what: "motion DOFs vs skeleton",
            expected: skeleton.dof_count(),
            got: motion.frames.nrows(),
        });
    }
    let x = (t_s / motion.frame_time_s).clamp(0.0, (n - 1) as f64);
    let k = (x.floor() as usize).min(n - 1);
    let k1 = (k + 1).min(n - 1);
    let a = x - k as f64;
    let (f0, f1) = (motion.frame(k), motion.frame(k1));
    Ok((0..f0.len())
        .map(|d| {
            let mut delta = f1[d] - f0[d];
            if skeleton.is_rotation(d) {
                delta = (delta + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                    - std::f64::consts::PI;
            }
            f0[d] + a * delta
        })
        .collect())
}

/// Estimates the video-to-motion time offset (Sand §4.2), starting from `initial_offset_s`.
///
/// Synchronisation of video and motion capture from silhouettes (Sand 2003 §4.1–4.2).
///
/// "Our system uses simplex optimizer (the same one used for camera calibration) to minimize
/// an objective function that measures the image-space distance from projected arm and leg
/// markers to the silhouettes over a number of video frames" (§4.2). Video frame `k`, taken at
/// video time `t_k`, shows the pose of the motion at time `t_k + offset`; the offset is found
/// by Nelder–Mead ([`skin_core::optim::nelder_mead`], the downhill simplex of §4.1) on
///
/// `E(offset) = mean_{k, camera, marker} min(D_fg(π(marker(θ(t_k + offset)))), cap)`
///
/// where `D_fg` is the Euclidean distance (px) to the nearest silhouette pixel
/// ([`skin_core::image::distance_to_foreground`], sampled bilinearly so `E` is continuous)
/// and θ(t) interpolates the motion linearly between frames (rotations along the shorter arc).
/// Markers inside the silhouette cost 0; the cap bounds the influence of markers projecting
/// far off the silhouette or off the image (occluded or mis-segmented limbs).
///
/// # Errors
/// [`Error::Empty`] without frames, cameras or markers, or if every mask is empty (no
/// silhouette to measure against); [`Error::SizeMismatch`] for a frame whose mask count or
/// mask size does not match the cameras; [`Error::NonFinite`] for a non-finite time or initial
/// offset; an invalid-parameter error ([`Error::invalid_param_name`]) for an unknown marker or
/// invalid params; errors of [`sample_motion`] and of the optimiser.
pub fn estimate_sync_offset(
    skeleton: &Skeleton,
    motion: &Motion,
    cameras: &[Camera],
    frames: &[VideoFrame<'_>],
    initial_offset_s: f64,
    params: &SyncParams,
) -> Result<SyncResult> {
    if frames.is_empty() {
        return Err(Error::Empty {
            what: "video frames",
        });
    }
    if cameras.is_empty() {
        return Err(Error::Empty { what: "cameras" });
    }
    if params.markers.is_empty() {
        return Err(Error::Empty {
            what: "sync markers",
        });
    }
    skin_core::check::positive("cap_px", params.cap_px)?;
    if !initial_offset_s.is_finite() {
        return Err(Error::NonFinite {
            what: "initial offset",
        });
    }
    let markers: Vec<AttachedPoint> = params
        .markers
        .iter()
        .map(|m| resolve_marker(skeleton, m))
        .collect::<Result<_>>()?;
    // Distance images; `None` for empty masks (they carry no information and are skipped).
    let mut dist: Vec<Vec<Option<GrayF32Image>>> = Vec::with_capacity(frames.len());
    let mut any = false;
    for f in frames {
        if !f.time_s.is_finite() {
            return Err(Error::NonFinite {
                what: "video frame time",
            });
        }
        if f.masks.len() != cameras.len() {
            return Err(Error::SizeMismatch {
                what: "masks per video frame (one per camera)",
                expected: cameras.len(),
                got: f.masks.len(),
            });
        }
        let mut row = Vec::with_capacity(cameras.len());
        for (m, c) in f.masks.iter().zip(cameras) {
            if m.dimensions() != (c.intrinsics.width, c.intrinsics.height) {
                return Err(Error::SizeMismatch {
                    what: "mask pixels vs camera image pixels",
                    expected: c.intrinsics.width as usize * c.intrinsics.height as usize,
                    got: m.pixel_count(),
                });
            }
            if m.is_empty() {
                row.push(None);
            } else {
                any = true;
                row.push(Some(distance_to_foreground(m)?));
            }
        }
        dist.push(row);
    }
    if !any {
        return Err(Error::Empty {
            what: "silhouettes (every mask is empty)",
        });
    }
    let mut fk = ForwardKinematics::new(skeleton);
    let mut objective = |offset: f64| -> f64 {
        let mut sum = 0.0;
        let mut count = 0usize;
        for (f, row) in frames.iter().zip(&dist) {
            let Ok(theta) = sample_motion(skeleton, motion, f.time_s + offset) else {
                return f64::INFINITY;
            };
            if skeleton.forward_kinematics_into(&theta, &mut fk).is_err() {
                return f64::INFINITY;
            }
            for m in &markers {
                let Ok(p) = fk.point(m) else {
                    return f64::INFINITY;
                };
                for (cam, d) in cameras.iter().zip(row) {
                    let Some(d) = d else { continue };
                    let cost = cam
                        .project(p)
                        .ok()
                        .and_then(|px| sample_bilinear(d, px))
                        .map_or(params.cap_px, |v| v.min(params.cap_px));
                    sum += cost;
                    count += 1;
                }
            }
        }
        if count == 0 {
            f64::INFINITY
        } else {
            sum / count as f64
        }
    };
    let nm = NelderMeadParams::default()
        .with_initial_step(params.initial_step_s)
        .with_max_evaluations(params.max_evaluations);
    let nm = NelderMeadParams {
        x_tolerance: 1e-5,
        f_tolerance: 1e-9,
        ..nm
    };
    let rep = nelder_mead(&DVector::from_element(1, initial_offset_s), &nm, |x| {
        objective(x[0])
    })?;
    Ok(SyncResult {
        offset_s: rep.x[0],
        mean_distance_px: rep.f,
        evaluations: rep.evaluations,
        converged: rep.converged,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use dynamic_shapes_studio::{
        fast_motion, procedural_performer, studio_ring, Capture, CaptureFrame, CaptureSpec,
        FastMotionParams, ProceduralBodyParams,
    };

    #[test]
    fn recovers_a_known_offset() {
        let performer = procedural_performer(&ProceduralBodyParams {
            grid_spacing_m: 0.03,
            ..Default::default()
        })
        .unwrap();
        let sk = &performer.skeleton;
        let motion = fast_motion(sk, &FastMotionParams::default()).unwrap();
        let rig = studio_ring(3, 240, 160).unwrap();
        let cams = rig.cameras.clone();
        let true_offset = 0.0437;
        let times: Vec<f64> = (0..8).map(|k| 0.5 + 0.2 * k as f64).collect();
        // The video: the poses at the shifted times, captured 0.2 s apart.
        let poses = times
            .iter()
            .map(|&t| sample_motion(sk, &motion, t + true_offset))
            .collect::<Result<Vec<_>>>()
            .unwrap();
        let columns = nalgebra::DMatrix::from_fn(sk.dof_count(), poses.len(), |d, k| poses[k][d]);
        let video = Motion::new(0.2, columns).unwrap();
        let capture = Capture::new(
            &performer,
            &video,
            CaptureSpec::masks_only(rig).with_frame_rate_hz(5.0),
        )
        .unwrap();
        let masks: Vec<Vec<Mask>> = capture
            .frames()
            .map(|f| f.map(|f| CaptureFrame::masks(&f)))
            .collect::<skin_core::Result<_>>()
            .unwrap();
        assert_eq!(masks.len(), times.len());
        let frames: Vec<VideoFrame> = times
            .iter()
            .zip(&masks)
            .map(|(&t, m)| VideoFrame {
                time_s: t,
                masks: m,
            })
            .collect();
        let r =
            estimate_sync_offset(sk, &motion, &cams, &frames, 0.0, &SyncParams::default()).unwrap();
        eprintln!("sync {r:?}");
        assert!(
            (r.offset_s - true_offset).abs() < 0.005,
            "offset {} vs {true_offset}",
            r.offset_s
        );
        // Bad input.
        let empty: Vec<Mask> = cams.iter().map(|_| Mask::new(240, 160)).collect();
        let ef = [VideoFrame {
            time_s: 0.5,
            masks: &empty,
        }];
        assert!(
            estimate_sync_offset(sk, &motion, &cams, &ef, 0.0, &SyncParams::default()).is_err()
        );
        assert!(
            estimate_sync_offset(sk, &motion, &cams, &[], 0.0, &SyncParams::default()).is_err()
        );
        let nf = [VideoFrame {
            time_s: f64::NAN,
            masks: &masks[0],
        }];
        assert!(
            estimate_sync_offset(sk, &motion, &cams, &nf, 0.0, &SyncParams::default()).is_err()
        );
        let short = [VideoFrame {
            time_s: 0.5,
            masks: &masks[0][..2],
        }];
        assert!(matches!(
            estimate_sync_offset(sk, &motion, &cams, &short, 0.0, &SyncParams::default()),
            Err(Error::SizeMismatch { .. })
        ));
        assert!(estimate_sync_offset(
            sk,
            &motion,
            &cams,
            &frames,
            f64::NAN,
            &SyncParams::default()
        )
        .is_err());
    }
}
