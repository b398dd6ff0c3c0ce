//! Non-linear camera calibration from 2D–3D correspondences, Sand 2003 §4.1:
//!
//! ```text
//! min_{q,f,a,c,r} Σᵢ ‖pᵢ − D_{c,r}(P_{q,f,a} wᵢ)‖
//! ```
//!
//! over pose `q`, focal length `f`, aspect ratio `a`, distortion centre `c` and coefficient `r`.
//! We also free the principal point (Sand's `P` fixes it implicitly; with a 3D calibration
//! volume it is well determined, and the DLT estimates it anyway). Parameters (13): `fx, fy, cx,
//! cy, k1, c_x, c_y`, a rotation increment `ω` (`R = exp([ω]×)·R₀`, so no gimbal lock) and the
//! translation `t` of `camera_from_world`.
//!
//! Two refinements start from the normalised DLT ([`super::dlt`]):
//! * [`CalibrationMethod::LevenbergMarquardt`] (default) minimises the sum of squared pixel
//!   errors — the maximum-likelihood estimate under Gaussian pixel noise — with
//!   [`crate::optim::levenberg_marquardt`].
//! * [`CalibrationMethod::NelderMead`] is Sand's downhill simplex, over parameters rescaled so a
//!   unit step changes the RMS error by about a pixel; its objective is chosen by
//!   [`SimplexObjective`] (default: Sand's sum of distances, exactly as printed).

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use super::distortion::RadialDistortion;
use super::dlt::{dlt, reprojection_rms};
use super::intrinsics::Intrinsics;
use super::model::{Camera, MIN_DEPTH_M};
use crate::error::{Error, Result};
use crate::math::{DAffine3, DMat3, DQuat, DVec2, DVec3};
use crate::optim::{
    levenberg_marquardt, nelder_mead_with_steps, numeric_jacobian, LmParams, NelderMeadParams,
};

impl CalibrationParams {
    /// Default coplanarity tolerance: world points whose smallest principal spread is below 1e-3 of
    /// the largest (1 mm of depth over 1 m) give a DLT too ill-conditioned to trust.
    pub const DEFAULT_COPLANARITY_TOLERANCE: f64 = 1e-3;
}
/// Initial-simplex step, in rescaled units (one unit ≈ 0.7 px change of the RMS error).
const DEFAULT_SIMPLEX_STEP: f64 = 2.0;
/// Scale (px) of the distortion-centre parameters when `k1 = 0` makes them unobservable at the
/// start of the simplex search.
const DISTORTION_CENTRE_SCALE_PX: f64 = 20.0;

/// Which refinement follows the DLT.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum CalibrationMethod {
    /// Levenberg–Marquardt on squared pixel errors.
    #[default]
    LevenbergMarquardt,
    /// Nelder–Mead downhill simplex, as Sand 2003 §4.1.
    NelderMead,
}

/// The objective of the simplex variant.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum SimplexObjective {
    /// `Σ‖eᵢ‖` (px), Sand 2003 §4.1 as printed; less sensitive to outliers.
    #[default]
    SumOfDistances,
    /// `Σ‖eᵢ‖²` (px²), the maximum-likelihood objective under Gaussian noise.
    SumOfSquares,
}

/// Knobs of [`calibrate`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CalibrationParams {
    /// Refinement method. Default: Levenberg–Marquardt.
    pub method: CalibrationMethod,
    /// Estimate the radial distortion `k1` and its centre (Sand §4.1). `false` fits a pure
    /// pinhole. Default: true.
    pub refine_distortion: bool,
    /// Reject world points whose smallest principal spread is below this fraction of the largest.
    /// Dimensionless. Default: 1e-3.
    pub coplanarity_tolerance: f64,
    /// Levenberg–Marquardt settings. Default: [`LmParams::default`].
    pub lm: LmParams,
    /// Simplex settings; `initial_step` is in rescaled units (≈ 0.7 px of RMS change per unit).
    /// Default: step 2, relative f tolerance 1e-12, x tolerance 1e-7, 200 000 evaluations,
    /// 5 restarts.
    pub nelder_mead: NelderMeadParams,
    /// Simplex objective. Default: sum of distances (Sand §4.1).
    pub simplex_objective: SimplexObjective,
}

impl Default for CalibrationParams {
    fn default() -> Self {
        Self {
            method: CalibrationMethod::LevenbergMarquardt,
            refine_distortion: true,
            coplanarity_tolerance: CalibrationParams::DEFAULT_COPLANARITY_TOLERANCE,
            lm: LmParams::default(),
            nelder_mead: NelderMeadParams {
                initial_step: DEFAULT_SIMPLEX_STEP,
                f_tolerance: 1e-12,
                x_tolerance: 1e-7,
                max_evaluations: 200_000,
                max_restarts: 5,
                adaptive: true,
            },
            simplex_objective: SimplexObjective::SumOfDistances,
        }
    }
}

impl CalibrationParams {
    /// Sets [`CalibrationParams::method`].
    pub fn with_method(mut self, method: CalibrationMethod) -> Self {
        self.method = method;
        self
    }
}

/// Result of [`calibrate`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CalibrationReport {
    /// The calibrated camera.
    pub camera: Camera,
    /// Reprojection RMS over the input correspondences, px, per image coordinate (see
    /// [`reprojection_rms`]; equals σ for per-axis pixel noise σ).
    pub rms_px: f64,
    /// Largest reprojection error, px.
    pub max_px: f64,
    /// Reprojection RMS of the DLT initialisation, px.
    pub dlt_rms_px: f64,
    /// Iterations of the refinement.
    pub iterations: usize,
    /// Objective (residual) evaluations of the refinement.
    pub evaluations: usize,
    /// False if the refinement stopped at its iteration/evaluation limit.
    pub converged: bool,
    /// Method used.
    pub method: CalibrationMethod,
}

/// Number of refined parameters with/without distortion.
const N_FULL: usize = 13;
const N_PINHOLE: usize = 10;

/// Camera parameters in the refinement's coordinates.
#[derive(Clone, Copy)]
struct Unpacked {
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
    distortion: RadialDistortion,
    rotation: DQuat,
    translation: DVec3,
}

struct Problem<'a> {
    world: &'a [DVec3],
    pixels: &'a [DVec2],
    rotation0: DQuat,
    refine_distortion: bool,
    width: u32,
    height: u32,
}

impl Problem<'_> {
    fn pack(&self, cam: &Camera) -> DVector<f64> {
        let k = cam.intrinsics;
        let t = cam.camera_from_world().translation;
        let mut v = vec![k.fx, k.fy, k.cx, k.cy];
        if self.refine_distortion {
            v.extend([
                cam.distortion.k1,
                cam.distortion.centre.x,
                cam.distortion.centre.y,
            ]);
        }
        v.extend([0.0, 0.0, 0.0, t.x, t.y, t.z]);
        DVector::from_vec(v)
    }

    fn unpack(&self, x: &DVector<f64>) -> Unpacked {
        let (distortion, o) = if self.refine_distortion {
            (RadialDistortion::new(x[4], DVec2::new(x[5], x[6])), 7)
        } else {
            (RadialDistortion::NONE, 4)
        };
        let omega = DVec3::new(x[o], x[o + 1], x[o + 2]);
        Unpacked {
            fx: x[0],
            fy: x[1],
            cx: x[2],
            cy: x[3],
            distortion,
            rotation: DQuat::from_scaled_axis(omega) * self.rotation0,
            translation: DVec3::new(x[o + 3], x[o + 4], x[o + 5]),
        }
    }

    /// Residuals `predicted − observed` (2N), or an error if a point leaves the valid region.
    fn residuals(&self, x: &DVector<f64>) -> Result<DVector<f64>> {
        let u = self.unpack(x);
        if !(u.fx > 0.0 && u.fy > 0.0) {
            return Err(Error::InvalidParam {
                name: "focal length",
                reason: "left the positive range".into(),
            });
        }
        let k = Intrinsics {
            fx: u.fx,
            fy: u.fy,
            cx: u.cx,
            cy: u.cy,
            width: self.width,
            height: self.height,
        };
        let r = DMat3::from_quat(u.rotation);
        let mut out = DVector::zeros(2 * self.world.len());
        for (i, (w, p)) in self.world.iter().zip(self.pixels).enumerate() {
            let pc = r * *w + u.translation;
            if pc.z <= MIN_DEPTH_M {
                return Err(Error::NotVisible {
                    what: "calibration point behind the camera".into(),
                });
            }
            let undistorted = k.pixel_from_normalized(DVec2::new(pc.x / pc.z, pc.y / pc.z));
            let d = u
                .distortion
                .distort(&k, undistorted)
                .ok_or_else(|| Error::NotVisible {
                    what: "calibration point beyond the distortion fold".into(),
                })?;
            out[2 * i] = d.x - p.x;
            out[2 * i + 1] = d.y - p.y;
        }
        Ok(out)
    }

    fn camera(&self, x: &DVector<f64>) -> Result<Camera> {
        let u = self.unpack(x);
        let k = Intrinsics::new(u.fx, u.fy, u.cx, u.cy, self.width, self.height)?;
        Camera::from_camera_from_world(
            k,
            u.distortion,
            DAffine3::from_rotation_translation(u.rotation.normalize(), u.translation),
        )
    }
}

/// Calibrates a camera from world points (m) and their observed pixels: normalised DLT
/// initialisation, then the refinement chosen in `params` (module docs).
///
/// # Errors
/// [`Error::SizeMismatch`] for different lengths; [`Error::InvalidParam`] for fewer than six
/// points or an empty image; [`Error::NonFinite`] for NaN/∞ input; [`Error::Singular`] for
/// coplanar or otherwise degenerate world points.
///
/// # Example
/// ```
/// use rand::SeedableRng;
/// use skin_core::camera::{calibrate, synthetic_calibration, CalibrationParams, SyntheticCalibrationParams};
/// let p = SyntheticCalibrationParams::default();
/// let s = synthetic_calibration(&p, &mut rand_chacha::ChaCha8Rng::seed_from_u64(1))?;
/// let report = calibrate(&s.world, &s.pixels, p.width, p.height, &CalibrationParams::default())?;
/// assert!(report.rms_px < 0.6);
/// # Ok::<(), skin_core::Error>(())
/// ```
pub fn calibrate(
    world: &[DVec3],
    pixels: &[DVec2],
    width: u32,
    height: u32,
    params: &CalibrationParams,
) -> Result<CalibrationReport> {
    let init = dlt(world, pixels, width, height, params.coplanarity_tolerance)?;
    let mut start = init.camera.clone();
    if params.refine_distortion {
        start.distortion = RadialDistortion::new(0.0, start.intrinsics.principal_point());
    }
    let problem = Problem {
        world,
        pixels,
        rotation0: DQuat::from_affine3(&start.camera_from_world()),
        refine_distortion: params.refine_distortion,
        width,
        height,
    };
    let x0 = problem.pack(&start);
    debug_assert_eq!(
        x0.len(),
        if params.refine_distortion {
            N_FULL
        } else {
            N_PINHOLE
        }
    );
    let (x, iterations, evaluations, converged) = match params.method {
        CalibrationMethod::LevenbergMarquardt => {
            let rep = levenberg_marquardt(
                &x0,
                &params.lm,
                |x| problem.residuals(x),
                |x| numeric_jacobian(&mut |y: &DVector<f64>| problem.residuals(y), x),
            )?;
            (
                rep.x,
                rep.iterations,
                rep.residual_evaluations,
                rep.termination.converged(),
            )
        }
        CalibrationMethod::NelderMead => {
            // Rescale so that a unit step in every coordinate changes the RMS by ~0.7 px.
            let jac: DMatrix<f64> =
                numeric_jacobian(&mut |y: &DVector<f64>| problem.residuals(y), &x0)?;
            let sqrt_n = (world.len() as f64).sqrt();
            let max_norm = jac.column_iter().map(|c| c.norm()).fold(0.0, f64::max);
            let scale = DVector::from_fn(x0.len(), |j, _| {
                let norm = jac.column(j).norm();
                if norm > 1e-9 * max_norm {
                    sqrt_n / norm
                } else {
                    DISTORTION_CENTRE_SCALE_PX
                }
            });
            let objective = params.simplex_objective;
            let f = |z: &DVector<f64>| {
                let x = &x0 + z.component_mul(&scale);
                match problem.residuals(&x) {
                    Ok(r) => match objective {
                        SimplexObjective::SumOfSquares => r.norm_squared(),
                        SimplexObjective::SumOfDistances => {
                            (0..r.len() / 2).map(|i| r[2 * i].hypot(r[2 * i + 1])).sum()
                        }
                    },
                    Err(_) => f64::INFINITY,
                }
            };
            let steps = DVector::from_element(x0.len(), params.nelder_mead.initial_step);
            let rep =
                nelder_mead_with_steps(&DVector::zeros(x0.len()), &steps, &params.nelder_mead, f)?;
            (
                &x0 + rep.x.component_mul(&scale),
                rep.iterations,
                rep.evaluations,
                rep.converged,
            )
        }
    };
    let camera = problem.camera(&x)?;
    let errors: Vec<f64> = world
        .iter()
        .zip(pixels)
        .map(|(w, p)| camera.project(*w).map(|q| (q - *p).length()))
        .collect::<Result<_>>()?;
    let rms_px = reprojection_rms(&camera, world, pixels)?;
    Ok(CalibrationReport {
        camera,
        rms_px,
        max_px: errors.iter().copied().fold(0.0, f64::max),
        dlt_rms_px: init.rms_px,
        iterations,
        evaluations,
        converged,
        method: params.method,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::synthetic::{synthetic_calibration, SyntheticCalibrationParams};
    use rand::SeedableRng;

    fn problem(
        seed: u64,
        noise_px: f64,
    ) -> (
        SyntheticCalibrationParams,
        crate::camera::SyntheticCalibration,
    ) {
        let p = SyntheticCalibrationParams {
            noise_px,
            ..Default::default()
        };
        let s =
            synthetic_calibration(&p, &mut rand_chacha::ChaCha8Rng::seed_from_u64(seed)).unwrap();
        (p, s)
    }

    #[test]
    fn lm_recovers_truth_without_noise() {
        let (p, s) = problem(5, 0.0);
        let rep = calibrate(
            &s.world,
            &s.pixels,
            p.width,
            p.height,
            &CalibrationParams::default(),
        )
        .unwrap();
        assert!(rep.rms_px < 1e-6, "rms {}", rep.rms_px);
        assert!((rep.camera.centre() - s.truth.centre()).length() < 1e-6);
        assert!((rep.camera.distortion.k1 - p.k1).abs() < 1e-6);
        assert!((rep.camera.distortion.centre - s.truth.distortion.centre).length() < 1e-3);
        assert!(
            rep.dlt_rms_px > 0.2,
            "distortion must matter for this test to mean anything"
        );
    }

    #[test]
    fn accuracy_with_half_pixel_noise() {
        // The task's accuracy goal: <= 0.6 px RMS and <= 2 mm camera-centre error.
        let (p, s) = problem(2024, 0.5);
        let lm = calibrate(
            &s.world,
            &s.pixels,
            p.width,
            p.height,
            &CalibrationParams::default(),
        )
        .unwrap();
        let centre_mm = (lm.camera.centre() - s.truth.centre()).length() * 1e3;
        assert!(
            lm.rms_px <= 0.6 && centre_mm <= 2.0,
            "LM rms {} px, centre {} mm",
            lm.rms_px,
            centre_mm
        );
        let nm_params = CalibrationParams::default().with_method(CalibrationMethod::NelderMead);
        let nm = calibrate(&s.world, &s.pixels, p.width, p.height, &nm_params).unwrap();
        let nm_centre_mm = (nm.camera.centre() - s.truth.centre()).length() * 1e3;
        assert!(
            nm.rms_px <= 0.6 && nm_centre_mm <= 5.0,
            "NM rms {} px, centre {} mm",
            nm.rms_px,
            nm_centre_mm
        );
        // LM minimises the squared error, so nothing beats it on RMS.
        assert!(lm.rms_px <= nm.rms_px + 1e-9);
    }

    #[test]
    fn pinhole_only_fit() {
        let p = SyntheticCalibrationParams {
            k1: 0.0,
            noise_px: 0.0,
            ..Default::default()
        };
        let s = synthetic_calibration(&p, &mut rand_chacha::ChaCha8Rng::seed_from_u64(9)).unwrap();
        let params = CalibrationParams {
            refine_distortion: false,
            ..Default::default()
        };
        let rep = calibrate(&s.world, &s.pixels, p.width, p.height, &params).unwrap();
        assert!(rep.rms_px < 1e-6 && rep.camera.distortion.k1 == 0.0);
    }

    #[test]
    fn bad_input_is_rejected() {
        let (p, s) = problem(3, 0.5);
        let c = CalibrationParams::default();
        assert!(matches!(
            calibrate(&s.world[..5], &s.pixels[..5], p.width, p.height, &c),
            Err(Error::InvalidParam { .. })
        ));
        assert!(matches!(
            calibrate(&s.world, &s.pixels[1..], p.width, p.height, &c),
            Err(Error::SizeMismatch { .. })
        ));
        let mut w = s.world.clone();
        w[7].y = f64::NAN;
        assert!(matches!(
            calibrate(&w, &s.pixels, p.width, p.height, &c),
            Err(Error::NonFinite { .. })
        ));
        let flat: Vec<DVec3> = s.world.iter().map(|q| DVec3::new(q.x, q.y, 0.0)).collect();
        assert!(matches!(
            calibrate(&flat, &s.pixels, p.width, p.height, &c),
            Err(Error::Singular { .. })
        ));
    }
}
