//! Synthetic calibration problems with known ground truth, for tests, examples and benchmarks:
//! a distorted camera a few metres from a cube of random 3D points (the "several hundred"
//! points of Sand 2003 §4.1), observed with Gaussian pixel noise.

use rand::{Rng, RngExt};
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};

use super::distortion::RadialDistortion;
use super::intrinsics::Intrinsics;
use super::model::Camera;
use crate::error::{Error, Result};
use crate::math::{DVec2, DVec3};

/// Rejection-sampling attempts per requested point before giving up.
const ATTEMPTS_PER_POINT: usize = 1000;

/// Knobs of [`synthetic_calibration`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SyntheticCalibrationParams {
    /// Number of visible correspondences. Default: 300 (Sand §4.1: "several hundred").
    pub n_points: usize,
    /// Distance from the camera centre to the centre of the point volume, m. Default: 3.0.
    pub distance_m: f64,
    /// Edge of the cubic point volume (centred on the world origin), m. Default: 3.0 (points
    /// spread in depth pin down the camera centre: ≈1 mm error at 0.5 px noise).
    pub volume_m: f64,
    /// Standard deviation of the Gaussian pixel noise per axis, px. Default: 0.5.
    pub noise_px: f64,
    /// Image width, px. Default: 1280.
    pub width: u32,
    /// Image height, px. Default: 960.
    pub height: u32,
    /// Horizontal focal length, px. Default: 1100.
    pub fx: f64,
    /// Aspect ratio `fy/fx` (Sand's `a`). Default: 1.01.
    pub aspect: f64,
    /// Principal point offset from the image centre, px. Default: (8, −6).
    pub principal_offset_px: DVec2,
    /// Distortion coefficient. Default: −0.08 (mild barrel, ≈ 20 px at the corners).
    pub k1: f64,
    /// Distortion centre offset from the principal point, px. Default: (15, −10).
    pub distortion_offset_px: DVec2,
}

impl Default for SyntheticCalibrationParams {
    fn default() -> Self {
        Self {
            n_points: 300,
            distance_m: 3.0,
            volume_m: 3.0,
            noise_px: 0.5,
            width: 1280,
            height: 960,
            fx: 1100.0,
            aspect: 1.01,
            principal_offset_px: DVec2::new(8.0, -6.0),
            k1: -0.08,
            distortion_offset_px: DVec2::new(15.0, -10.0),
        }
    }
}

/// A synthetic calibration problem.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SyntheticCalibration {
    /// The true camera.
    pub truth: Camera,
    /// World points, m.
    pub world: Vec<DVec3>,
    /// Noisy observed pixels.
    pub pixels: Vec<DVec2>,
    /// Noise-free pixels.
    pub pixels_exact: Vec<DVec2>,
}

/// Draws a camera looking at the origin from `distance_m` (random azimuth, 5–25° elevation,
/// world up +Y) and `n_points` uniform points of the volume that it sees.
///
/// # Errors
/// [`Error::InvalidParam`] for non-positive sizes or noise; [`Error::NotVisible`] if the camera
/// sees too little of the volume to draw the points.
pub fn synthetic_calibration<R: Rng + ?Sized>(
    params: &SyntheticCalibrationParams,
    rng: &mut R,
) -> Result<SyntheticCalibration> {
    let p = params;
    if !(p.distance_m > 0.0
        && p.volume_m > 0.0
        && p.noise_px >= 0.0
        && p.fx > 0.0
        && p.aspect > 0.0)
    {
        return Err(Error::InvalidParam {
            name: "SyntheticCalibrationParams",
            reason: "distance, volume, focal length and aspect must be > 0 and noise >= 0".into(),
        });
    }
    let centre = DVec2::new(0.5 * (p.width as f64 - 1.0), 0.5 * (p.height as f64 - 1.0))
        + p.principal_offset_px;
    let k = Intrinsics::new(p.fx, p.fx * p.aspect, centre.x, centre.y, p.width, p.height)?;
    let azimuth = rng.random_range(0.0..std::f64::consts::TAU);
    let elevation = rng.random_range(5f64..25.0).to_radians();
    let eye = DVec3::new(
        azimuth.cos() * elevation.cos(),
        elevation.sin(),
        azimuth.sin() * elevation.cos(),
    ) * p.distance_m;
    let truth = Camera::look_at(k, eye, DVec3::ZERO, DVec3::Y)?
        .with_distortion(RadialDistortion::new(p.k1, centre + p.distortion_offset_px));
    let mut world = Vec::with_capacity(p.n_points);
    let mut pixels_exact = Vec::with_capacity(p.n_points);
    let mut attempts = 0;
    while world.len() < p.n_points {
        attempts += 1;
        if attempts > ATTEMPTS_PER_POINT * p.n_points.max(1) {
            return Err(Error::NotVisible {
                what: "synthetic camera sees too little of the point volume".into(),
            });
        }
        let w = DVec3::new(
            rng.random::<f64>() - 0.5,
            rng.random::<f64>() - 0.5,
            rng.random::<f64>() - 0.5,
        ) * p.volume_m;
        if let Ok(px) = truth.project(w) {
            if k.contains(px) {
                world.push(w);
                pixels_exact.push(px);
            }
        }
    }
    let pixels = pixels_exact
        .iter()
        .map(|px| {
            let noise = DVec2::new(rng.sample(StandardNormal), rng.sample(StandardNormal));
            *px + noise * p.noise_px
        })
        .collect();
    Ok(SyntheticCalibration {
        truth,
        world,
        pixels,
        pixels_exact,
    })
}
