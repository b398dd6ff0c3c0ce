//! Camera calibration with the calibration device (Sand, McMillan and Popović 2003 §4.1;
//! thesis §4.1): a motion-capture marker on a green sphere, tracked by the motion-capture
//! system and seen by a video camera.
//!
//! The method is documented on [`calibrate_device`]; the module is private and
//! everything public is re-exported at the crate root.

use glam::{DVec2, DVec3};
use serde::{Deserialize, Serialize};
use skin_core::camera::{
    calibrate, estimate_time_offset, CalibrationParams, CalibrationReport, SampledSignal,
    TimeOffsetParams,
};
use skin_core::check;

use crate::{Error, Result};

/// The device's marker as tracked by motion capture: uniformly sampled world positions.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DeviceTrack {
    /// Time of the first sample in the motion-capture clock, s.
    pub start_s: f64,
    /// Sampling rate, Hz (Sand: 120).
    pub rate_hz: f64,
    /// Marker positions, world metres.
    pub positions: Vec<DVec3>,
}

/// The sphere as seen by one video camera: its detected image centre per frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DeviceVideo {
    /// Time of the first frame in the video clock, s.
    pub start_s: f64,
    /// Frame rate, Hz (Sand: 30).
    pub rate_hz: f64,
    /// Image size, px.
    pub width: u32,
    /// Image size, px.
    pub height: u32,
    /// Sphere centre per frame, px; `None` where it was not detected.
    pub centres: Vec<Option<DVec2>>,
}

/// Parameters of [`calibrate_device`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct DeviceParams {
    /// World "up" (the vertical world coordinate correlated with image `v`). Default: +y.
    pub up: Option<DVec3>,
    /// Only the first this many seconds of video are correlated (the up-and-down phase);
    /// `None` correlates the whole recording. Default: `None`.
    pub sync_seconds: Option<f64>,
    /// Offset search range and settings. Default: [`TimeOffsetParams::default`] (±5 s).
    pub sync: TimeOffsetParams,
    /// Calibration settings. Default: [`CalibrationParams::default`].
    pub calibration: CalibrationParams,
}

/// Result of [`calibrate_device`].
#[derive(Debug, Clone)]
pub struct DeviceCalibration {
    /// Offset δ, s: motion-capture time `t` is video time `t + δ`.
    pub offset_s: f64,
    /// Normalised cross-correlation of height and image `v` at the offset (negative:
    /// inverted, as expected for an upright camera).
    pub sync_score: f64,
    /// Number of matched (world, image) points used for the calibration.
    pub correspondences: usize,
    /// The calibrated camera and its residuals.
    pub report: CalibrationReport,
}

/// Synchronises the device's track with one camera's video and calibrates that camera
/// (see [`calibrate_device`]).
///
/// Camera calibration with the calibration device (Sand, McMillan and Popović 2003 §4.1;
/// thesis §4.1): a motion-capture marker on a green sphere, tracked by the motion-capture
/// system and seen by a video camera.
///
/// "The calibration process starts with synchronization of video and motion data. We move the
/// calibration device up and down in a plane roughly parallel to the image plane of a
/// particular camera and correlate the vertical image coordinate with the vertical world
/// coordinate. After synchronization, the calibration device can be moved freely in three
/// dimensions. We resample the resulting motion-capture sequence to obtain a sequence of
/// matching image `p_i` and world `w_i` points" and minimise the image error.
///
/// [`calibrate_device`] chains the skin-core pieces: the time offset by normalised
/// cross-correlation of the device's height with the sphere's image `v` coordinate
/// ([`estimate_time_offset`], which accepts the inverted sign: `v` grows downwards), the
/// motion-capture track resampled at each video frame's time (linear interpolation), and
/// [`calibrate`] (DLT, then Levenberg–Marquardt or Sand's simplex, with radial distortion).
/// Frames where the sphere was not detected are skipped; for the correlation their `v` is
/// interpolated from the neighbouring detections.
///
/// # Errors
/// [`Error::Empty`] for an empty track or a video without detections; [`Error::NonFinite`]
/// for NaN/∞ positions, centres or times; an invalid-parameter error
/// ([`Error::invalid_param_name`]) for non-positive rates, a zero `up` or `sync_seconds ≤ 0`; the errors of [`estimate_time_offset`] (no overlap,
/// constant signals) and [`calibrate`] (fewer than six matched points, coplanar motion).
pub fn calibrate_device(
    track: &DeviceTrack,
    video: &DeviceVideo,
    params: &DeviceParams,
) -> Result<DeviceCalibration> {
    for (name, rate) in [
        ("track rate_hz", track.rate_hz),
        ("video rate_hz", video.rate_hz),
    ] {
        check::positive(name, rate)?;
    }
    if !(track.start_s.is_finite() && video.start_s.is_finite()) {
        return Err(Error::NonFinite {
            what: "device start times",
        });
    }
    if track.positions.is_empty() {
        return Err(Error::Empty {
            what: "device track",
        });
    }
    if track.positions.iter().any(|p| !p.is_finite()) {
        return Err(Error::NonFinite {
            what: "device track positions",
        });
    }
    if video.centres.iter().flatten().any(|c| !c.is_finite()) {
        return Err(Error::NonFinite {
            what: "device image centres",
        });
    }
    let up = params.up.unwrap_or(DVec3::Y);
    if !(up.is_finite() && up.length() > 0.0) {
        return Err(Error::InvalidParam {
            name: "up",
            reason: format!("must be a finite non-zero vector, got {up}"),
        });
    }
    let up = up.normalize();
    let frames = match params.sync_seconds {
        None => video.centres.len(),
        Some(s) => {
            let s = check::positive("sync_seconds", s)?;
            ((s * video.rate_hz).ceil() as usize).min(video.centres.len())
        }
    };
    let v = fill_gaps(&video.centres[..frames]).ok_or(Error::Empty {
        what: "sphere detections in the synchronisation frames",
    })?;
    let heights = track.positions.iter().map(|p| p.dot(up)).collect();
    let a = SampledSignal::new(track.start_s, track.rate_hz, heights)?;
    let b = SampledSignal::new(video.start_s, video.rate_hz, v)?;
    let sync = estimate_time_offset(&a, &b, &params.sync)?;

    let mut world = Vec::new();
    let mut pixels = Vec::new();
    for (k, c) in video.centres.iter().enumerate() {
        let Some(c) = c else { continue };
        let t_video = video.start_s + k as f64 / video.rate_hz;
        if let Some(w) = track_at(track, t_video - sync.offset_s) {
            world.push(w);
            pixels.push(*c);
        }
    }
    let report = calibrate(
        &world,
        &pixels,
        video.width,
        video.height,
        &params.calibration,
    )?;
    Ok(DeviceCalibration {
        offset_s: sync.offset_s,
        sync_score: sync.score,
        correspondences: world.len(),
        report,
    })
}

/// Image `v` per frame with undetected frames interpolated linearly between detections
/// (held constant before the first and after the last); `None` without any detection.
fn fill_gaps(centres: &[Option<DVec2>]) -> Option<Vec<f64>> {
    let known: Vec<(usize, f64)> = centres
        .iter()
        .enumerate()
        .filter_map(|(k, c)| c.map(|c| (k, c.y)))
        .collect();
    let (&first, &last) = (known.first()?, known.last()?);
    let mut out = vec![0.0; centres.len()];
    for (k, o) in out.iter_mut().enumerate() {
        *o = if k <= first.0 {
            first.1
        } else if k >= last.0 {
            last.1
        } else {
            let i = known.partition_point(|&(j, _)| j <= k);
            let ((k0, v0), (k1, v1)) = (known[i - 1], known[i]);
            v0 + (v1 - v0) * (k - k0) as f64 / (k1 - k0) as f64
        };
    }
    Some(out)
}

/// The track's position at motion-capture time `t` (linear interpolation), `None` outside it.
fn track_at(track: &DeviceTrack, t: f64) -> Option<DVec3> {
    let x = (t - track.start_s) * track.rate_hz;
    let n = track.positions.len();
    if x.is_nan() || x < 0.0 || x > (n - 1) as f64 {
        return None;
    }
    let i = (x.floor() as usize).min(n.saturating_sub(2));
    if n == 1 {
        return Some(track.positions[0]);
    }
    let f = x - i as f64;
    Some(track.positions[i].lerp(track.positions[i + 1], f))
}

#[cfg(test)]
mod tests;
