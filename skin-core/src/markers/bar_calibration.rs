//! Bar calibration (Fua et al. §2.2, after Maas 1998): "a reference bar with two
//! retroreflective target points is moved through the object space ... the camera system can
//! then be calibrated by self-calibrating bundle adjustment with the additional information
//! of the known distance between the two points at every location".
//!
//! Unknowns: every camera's pose (rotation and centre) and focal length (aspect ratio,
//! principal point and distortion kept), every bar position's midpoint and direction (a unit
//! vector); the endpoints are `midpoint ± ½·length·direction`, so the known length fixes the
//! scale. The gauge (rotation and translation of the world) is fixed by holding camera 0's
//! pose.
//!
//! Minimisation: sparse Levenberg–Marquardt on the reprojection error. Each iteration
//! linearises about the current estimate with local increments — a rotation vector applied on
//! the left of each camera's rotation, a centre shift, a relative focal change, a midpoint shift
//! and two tangent components of the bar direction — so no angle parameterisation has
//! singularities. The Jacobian is analytic ([`Camera::project_with_jacobian`]; a world-point
//! shift `v × δ` for a rotation `δ`, `−δ` for a centre shift) except the focal column, a
//! central difference of the projection (the radial distortion's radius is measured in focal
//! units, which makes its analytic form long for one column). Each endpoint's two rows touch
//! one camera block (7 unknowns, 1 for camera 0) and one bar block (5), so the normal matrix is
//! the classic arrow of bundle adjustment; skin-core's sparse least squares
//! ([`crate::lsq::LsqSolver`]) factorises it with a fill-reducing order, keeps the symbolic
//! analysis across iterations, and takes the Marquardt damping as a second term
//! `λ‖diag(JᵀJ)^½ δ‖²` whose weight changes without a new analysis.
//!
//! Initialisation (documented method): an approximate rig (e.g. the rig as planned or
//! measured with a tape); each bar position starts from the forward intersection of its two
//! endpoints through the approximate cameras.

use nalgebra::DMatrix;
use nalgebra_sparse::{CscMatrix, CsrMatrix};

use super::{triangulate, MarkerView};
use crate::camera::Camera;
use crate::check::{all_finite, positive};
use crate::lsq::{LsqParams, LsqProblem, LsqSolver};
use crate::math::{DAffine3, DMat3, DQuat, DVec2, DVec3};
use crate::{Context, Error, Result, ResultExt};

/// Parameters of [`calibrate_with_bar`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BarCalibrationParams {
    /// Distance between the two bar markers, m.
    pub bar_length_m: f64,
    /// Levenberg–Marquardt iterations at most. Default: 50.
    pub max_iterations: usize,
    /// Stop when the relative decrease of the cost is below this. Default: 1e-10.
    pub tolerance: f64,
}

impl BarCalibrationParams {
    /// Defaults for a bar of the given length.
    pub fn new(bar_length_m: f64) -> Self {
        Self {
            bar_length_m,
            max_iterations: 50,
            tolerance: 1e-10,
        }
    }
}

/// Result of [`calibrate_with_bar`].
#[derive(Debug, Clone)]
pub struct BarCalibration {
    /// The calibrated cameras (camera 0's pose as given).
    pub cameras: Vec<Camera>,
    /// Both endpoints of every bar position, m.
    pub bars: Vec<[DVec3; 2]>,
    /// RMS reprojection error over all observed endpoints, px.
    pub rms_px: f64,
    /// Iterations performed.
    pub iterations: usize,
    /// Unknowns of the bundle adjustment (cameras and bar positions).
    pub unknowns: usize,
}

/// Unknowns of a camera other than camera 0: relative focal change, rotation vector, centre
/// shift. Camera 0 has only the focal change (it fixes the gauge).
const CAMERA_PARAMS: usize = 7;
/// Unknowns of a bar position: midpoint shift and two tangent components of the direction.
const BAR_PARAMS: usize = 5;
/// Relative focal step of the focal column's central difference.
const FOCAL_STEP: f64 = 1e-6;

/// Two unit vectors perpendicular to the unit vector `d` and to each other (a fixed choice per
/// `d`, so that the Jacobian and the update use the same basis).
fn tangent_basis(d: DVec3) -> [DVec3; 2] {
    let a = if d.x.abs() < 0.6 { DVec3::X } else { DVec3::Y };
    let t1 = d.cross(a).normalize();
    [t1, d.cross(t1)]
}

/// A camera with its focal lengths scaled by `1 + df`.
fn with_focal_scale(camera: &Camera, df: f64) -> Result<Camera> {
    let mut k = camera.intrinsics;
    k.fx *= 1.0 + df;
    k.fy *= 1.0 + df;
    Camera::new(k, camera.distortion, camera.world_from_camera())
}

/// The current estimate: cameras and bar positions (midpoint, unit direction).
#[derive(Clone)]
struct Estimate {
    cameras: Vec<Camera>,
    bars: Vec<(DVec3, DVec3)>,
}

struct Problem<'a> {
    observations: &'a [Vec<[DVec2; 2]>],
    length: f64,
}

impl Problem<'_> {
    fn camera_offset(c: usize) -> usize {
        if c == 0 {
            0
        } else {
            1 + (c - 1) * CAMERA_PARAMS
        }
    }

    fn bar_offset(cameras: usize, b: usize) -> usize {
        Self::camera_offset(cameras) + b * BAR_PARAMS
    }

    fn ends(&self, bar: (DVec3, DVec3)) -> [DVec3; 2] {
        let d = bar.1 * (0.5 * self.length);
        [bar.0 - d, bar.0 + d]
    }

    /// Reprojection residuals, ordered bar, camera, endpoint, (x, y).
    fn residuals(&self, est: &Estimate) -> Result<Vec<f64>> {
        let mut r = Vec::with_capacity(self.observations.len() * est.cameras.len() * 4);
        for (obs, &bar) in self.observations.iter().zip(&est.bars) {
            let ends = self.ends(bar);
            for (c, cam) in est.cameras.iter().enumerate() {
                for (end, seen) in ends.iter().zip(&obs[c]) {
                    let p = cam.project(*end).at(Context::Camera(c))? - *seen;
                    r.extend([p.x, p.y]);
                }
            }
        }
        Ok(r)
    }

    /// Jacobian of [`Problem::residuals`] with respect to the local increments (module docs),
    /// row by row in the residuals' order; the sparsity pattern depends only on the sizes.
    fn jacobian(&self, est: &Estimate) -> Result<CscMatrix<f64>> {
        let cams = est.cameras.len();
        let n = Self::bar_offset(cams, est.bars.len());
        let focal: Vec<[Camera; 2]> = est
            .cameras
            .iter()
            .map(|c| {
                Ok([
                    with_focal_scale(c, FOCAL_STEP)?,
                    with_focal_scale(c, -FOCAL_STEP)?,
                ])
            })
            .collect::<Result<_>>()?;
        let mut offsets = vec![0usize];
        let mut cols = Vec::new();
        let mut vals = Vec::new();
        for &bar in &est.bars {
            let b = offsets.len() / (4 * cams);
            let ends = self.ends(bar);
            let tangents = tangent_basis(bar.1);
            let bo = Self::bar_offset(cams, b);
            for (c, cam) in est.cameras.iter().enumerate() {
                let co = Self::camera_offset(c);
                for (e, end) in ends.iter().enumerate() {
                    let jac = cam.project_with_jacobian(*end).at(Context::Camera(c))?;
                    let df = (focal[c][0].project(*end)? - focal[c][1].project(*end)?)
                        / (2.0 * FOCAL_STEP);
                    let half = if e == 0 { -0.5 } else { 0.5 } * self.length;
                    let v = *end - cam.centre();
                    for (row, g) in jac.d_pixel_d_world.iter().enumerate() {
                        cols.push(co);
                        vals.push(if row == 0 { df.x } else { df.y });
                        if c > 0 {
                            // Rotation δ moves the world point by v × δ; column k is g·(v × e_k).
                            let rot = v.cross(*g) * -1.0;
                            cols.extend(co + 1..co + 7);
                            vals.extend([rot.x, rot.y, rot.z, -g.x, -g.y, -g.z]);
                        }
                        cols.extend(bo..bo + BAR_PARAMS);
                        vals.extend([
                            g.x,
                            g.y,
                            g.z,
                            half * g.dot(tangents[0]),
                            half * g.dot(tangents[1]),
                        ]);
                        offsets.push(cols.len());
                    }
                }
            }
        }
        let rows = offsets.len() - 1;
        let csr = CsrMatrix::try_from_csr_data(rows, n, offsets, cols, vals).map_err(|e| {
            Error::InvalidParam {
                name: "bar calibration Jacobian",
                reason: e.to_string(),
            }
        })?;
        Ok(CscMatrix::from(&csr))
    }

    /// The estimate moved by the increments `x` (module docs).
    fn apply(&self, est: &Estimate, x: &[f64]) -> Result<Estimate> {
        let cams = est.cameras.len();
        let cameras = est
            .cameras
            .iter()
            .enumerate()
            .map(|(c, cam)| {
                let o = Self::camera_offset(c);
                let scaled = with_focal_scale(cam, x[o])?;
                if c == 0 {
                    return Ok(scaled);
                }
                let rotation = DQuat::from_scaled_axis(DVec3::new(x[o + 1], x[o + 2], x[o + 3]))
                    * DQuat::from_mat3(&cam.world_from_camera().matrix3);
                let centre = cam.centre() + DVec3::new(x[o + 4], x[o + 5], x[o + 6]);
                Camera::new(
                    scaled.intrinsics,
                    cam.distortion,
                    DAffine3::from_mat3_translation(DMat3::from_quat(rotation.normalize()), centre),
                )
            })
            .collect::<Result<_>>()?;
        let bars = est
            .bars
            .iter()
            .enumerate()
            .map(|(b, &(m, d))| {
                let o = Self::bar_offset(cams, b);
                let [t1, t2] = tangent_basis(d);
                (
                    m + DVec3::new(x[o], x[o + 1], x[o + 2]),
                    (d + t1 * x[o + 3] + t2 * x[o + 4]).normalize(),
                )
            })
            .collect();
        Ok(Estimate { cameras, bars })
    }
}

/// Marquardt's scaling: `diag(JᵀJ)^½` as a diagonal matrix (a tiny floor keeps it definite).
fn marquardt_scaling(j: &CscMatrix<f64>) -> CscMatrix<f64> {
    let n = j.ncols();
    let diag: Vec<f64> = (0..n)
        .map(|c| {
            let col = j.col(c);
            (col.values().iter().map(|v| v * v).sum::<f64>() + 1e-12).sqrt()
        })
        .collect();
    CscMatrix::try_from_csc_data(n, n, (0..=n).collect(), (0..n).collect(), diag)
        .unwrap_or_else(|_| CscMatrix::identity(n))
}

/// Self-calibrating bundle adjustment from a bar of known length waved through the volume (see
/// the module documentation). `observations[b][c]` are the two endpoint pixels of bar position
/// `b` in camera `c` (every camera sees both endpoints; the endpoint order must agree across
/// cameras).
///
/// # Errors
/// [`Error::InvalidParam`] for fewer than two cameras or a non-positive bar length;
/// [`Error::SizeMismatch`] for an observation without one pair per camera;
/// [`Error::NonFinite`] for non-finite pixels; [`Error::Degenerate`] for fewer than three bar
/// positions or bar positions on one line (the rig is then not determined);
/// [`Error::At`] naming a camera that sees a bar behind it.
pub fn calibrate_with_bar(
    initial: &[Camera],
    observations: &[Vec<[DVec2; 2]>],
    params: &BarCalibrationParams,
) -> Result<BarCalibration> {
    let length = positive("bar_length_m", params.bar_length_m)?;
    if initial.len() < 2 {
        return Err(Error::InvalidParam {
            name: "initial",
            reason: format!(
                "bar calibration needs at least two cameras, got {}",
                initial.len()
            ),
        });
    }
    for (b, obs) in observations.iter().enumerate() {
        crate::check::same_size(
            "bar observation (one pair per camera)",
            initial.len(),
            obs.len(),
        )
        .at(Context::Frame(b))?;
        all_finite(
            "bar pixel",
            obs.iter()
                .flat_map(|p| [&p[0].x, &p[0].y, &p[1].x, &p[1].y]),
        )
        .at(Context::Frame(b))?;
    }
    // Initial bars: forward intersection through the approximate cameras.
    let bars0 = observations
        .iter()
        .enumerate()
        .map(|(b, obs)| triangulate_bar(initial, obs).at(Context::Frame(b)))
        .collect::<Result<Vec<_>>>()?;
    check_not_collinear(&bars0)?;
    let problem = Problem {
        observations,
        length,
    };
    let mut est = Estimate {
        cameras: initial.to_vec(),
        bars: bars0
            .iter()
            .map(|e| (0.5 * (e[0] + e[1]), (e[1] - e[0]).normalize_or(DVec3::Z)))
            .collect(),
    };
    let mut r = problem.residuals(&est)?;
    let mut cost: f64 = r.iter().map(|v| v * v).sum();
    let mut lambda = 1e-3;
    let mut iterations = 0;
    let mut solver: Option<LsqSolver> = None;
    let unknowns = Problem::bar_offset(initial.len(), est.bars.len());
    let zeros = DMatrix::zeros(unknowns, 1);
    for _ in 0..params.max_iterations {
        iterations += 1;
        let j = problem.jacobian(&est)?;
        let scaling = marquardt_scaling(&j);
        let lsq = match solver.take() {
            Some(mut s) => {
                s.set_values(&j, &[&scaling])?;
                s
            }
            None => LsqProblem::new(j)
                .with_term(scaling, lambda)
                .factor(&LsqParams::default())?,
        };
        let solver_ref = solver.insert(lsq);
        let rhs = DMatrix::from_iterator(r.len(), 1, r.iter().map(|v| -v));
        let mut improved = false;
        for _ in 0..10 {
            if solver_ref.set_weights(&[lambda]).is_err() {
                lambda *= 10.0;
                continue;
            }
            let step = solver_ref.solve(&rhs, std::slice::from_ref(&zeros))?;
            let trial = problem.apply(&est, step.as_slice())?;
            match problem.residuals(&trial) {
                Ok(rn) => {
                    let cn: f64 = rn.iter().map(|v| v * v).sum();
                    if cn < cost {
                        let rel = (cost - cn) / cost.max(f64::MIN_POSITIVE);
                        est = trial;
                        r = rn;
                        cost = cn;
                        lambda = (lambda * 0.3).max(1e-12);
                        improved = rel > params.tolerance;
                        break;
                    }
                    lambda *= 10.0;
                }
                Err(_) => lambda *= 10.0,
            }
        }
        if !improved {
            break;
        }
    }
    let bars = est.bars.iter().map(|&b| problem.ends(b)).collect();
    let count = (r.len() / 2).max(1);
    Ok(BarCalibration {
        cameras: est.cameras,
        bars,
        rms_px: (cost / count as f64).sqrt(),
        iterations,
        unknowns,
    })
}

/// Both endpoints of one bar position by forward intersection through `cameras`.
fn triangulate_bar(cameras: &[Camera], obs: &[[DVec2; 2]]) -> Result<[DVec3; 2]> {
    let mut ends = [DVec3::ZERO; 2];
    for (e, end) in ends.iter_mut().enumerate() {
        let views: Vec<MarkerView<'_>> = cameras
            .iter()
            .zip(obs)
            .map(|(camera, p)| MarkerView {
                camera,
                pixel: p[e],
            })
            .collect();
        *end = triangulate(&views)?.point;
    }
    Ok(ends)
}

/// Bar positions must span more than a line: the spread of their midpoints across the
/// principal direction must exceed 1 % of the spread along it.
fn check_not_collinear(bars: &[[DVec3; 2]]) -> Result<()> {
    if bars.len() < 3 {
        return Err(Error::Degenerate {
            what: format!(
                "bar calibration needs at least three bar positions, got {}",
                bars.len()
            ),
        });
    }
    let mids: Vec<DVec3> = bars.iter().map(|e| 0.5 * (e[0] + e[1])).collect();
    let mean = mids.iter().copied().sum::<DVec3>() / mids.len() as f64;
    let mut cov = nalgebra::Matrix3::<f64>::zeros();
    for m in &mids {
        let d = *m - mean;
        let v = nalgebra::Vector3::new(d.x, d.y, d.z);
        cov += v * v.transpose();
    }
    let mut ev: Vec<f64> = cov.symmetric_eigenvalues().iter().copied().collect();
    ev.sort_by(|a, b| b.total_cmp(a));
    if !(ev[1] > 1e-4 * ev[0] && ev[0] > 0.0) {
        return Err(Error::Degenerate {
            what: "the bar positions lie on one line; wave the bar through the whole volume".into(),
        });
    }
    Ok(())
}

/// A synthetic bar calibration with ground truth (the test and example problem): three
/// 768 × 576 cameras (the paper's frames) in a ring of radius 3 m, a 0.5 m bar at `bars`
/// random positions and orientations in a 1.8 × 1.6 × 1.8 m volume (or, with `collinear`,
/// midpoints on one line), pixel noise `σ = sigma_px`; the approximate rig moves cameras 1 and 2
/// by (4, −3, 3) cm, turns them by ~1° and scales their focal length by 1.02.
#[derive(Debug, Clone)]
pub struct SyntheticBarCalibration {
    /// The true rig.
    pub truth: crate::camera::Rig,
    /// The approximate rig (initialisation).
    pub initial: Vec<Camera>,
    /// `observations[b][c]`: the two endpoint pixels of bar position `b` in camera `c`.
    pub observations: Vec<Vec<[DVec2; 2]>>,
    /// True endpoints of every bar position, m.
    pub bars: Vec<[DVec3; 2]>,
    /// Bar length, m.
    pub bar_length_m: f64,
}

/// Builds a [`SyntheticBarCalibration`] (deterministic for a seed).
///
/// # Errors
/// [`Error::InvalidParam`] for a negative or non-finite noise; [`Error::At`] naming a camera that
/// does not see a bar end (not for the volume used here).
pub fn synthetic_bar_calibration(
    bars: usize,
    sigma_px: f64,
    collinear: bool,
    seed: u64,
) -> Result<SyntheticBarCalibration> {
    crate::check::non_negative("sigma_px", sigma_px)?;
    let k = crate::camera::Intrinsics::from_horizontal_fov(0.9, 768, 576)?;
    let truth = crate::camera::Rig::ring(3, 3.0, 1.2, DVec3::new(0.0, 1.0, 0.0), DVec3::Y, k)?;
    let rng = crate::random::SplitMix64::new(seed);
    let mut n = 0u64;
    let mut u = || {
        n += 1;
        rng.uniform_at(n) * 2.0 - 1.0
    };
    let mut noise_k = 0u64;
    let half = 0.25;
    let mut observations = Vec::with_capacity(bars);
    let mut ends_true = Vec::with_capacity(bars);
    for b in 0..bars {
        let m = if collinear {
            DVec3::new(-0.6 + 1.2 * b as f64 / bars.max(1) as f64, 1.0, 0.0)
        } else {
            DVec3::new(0.9 * u(), 1.0 + 0.8 * u(), 0.9 * u())
        };
        let d = DVec3::new(u(), u(), u()).normalize_or(DVec3::X) * half;
        ends_true.push([m - d, m + d]);
        let mut per_camera = Vec::with_capacity(truth.cameras.len());
        for (c, cam) in truth.cameras.iter().enumerate() {
            let mut e = [
                cam.project(m - d).at(Context::Camera(c))?,
                cam.project(m + d).at(Context::Camera(c))?,
            ];
            for p in &mut e {
                noise_k += 2;
                *p += DVec2::new(
                    rng.normal_at(1 << 40 | noise_k),
                    rng.normal_at(1 << 40 | (noise_k + 1)),
                ) * sigma_px;
            }
            per_camera.push(e);
        }
        observations.push(per_camera);
    }
    let mut initial = Vec::with_capacity(truth.cameras.len());
    for (i, c) in truth.cameras.iter().enumerate() {
        if i == 0 {
            initial.push(c.clone());
            continue;
        }
        let mut k = c.intrinsics;
        k.fx *= 1.02;
        k.fy *= 1.02;
        let r = DQuat::from_scaled_axis(DVec3::new(0.01, -0.015, 0.01))
            * DQuat::from_mat3(&c.world_from_camera().matrix3);
        let pose = DAffine3::from_mat3_translation(
            DMat3::from_quat(r),
            c.centre() + DVec3::new(0.04, -0.03, 0.03),
        );
        initial.push(Camera::new(k, c.distortion, pose)?);
    }
    Ok(SyntheticBarCalibration {
        truth,
        initial,
        observations,
        bars: ends_true,
        bar_length_m: 2.0 * half,
    })
}

/// RMS difference between the bar length and the distance of its two endpoints triangulated
/// freely (forward intersection, no length constraint) through `cameras`, m: the check of a
/// calibration on its own data (or on held-out bar positions).
///
/// # Errors
/// As [`triangulate`]; [`Error::Empty`] for no observations.
pub fn bar_length_rms_m(
    cameras: &[Camera],
    observations: &[Vec<[DVec2; 2]>],
    bar_length_m: f64,
) -> Result<f64> {
    if observations.is_empty() {
        return Err(Error::Empty {
            what: "bar observations",
        });
    }
    let mut sq = 0.0;
    for (b, obs) in observations.iter().enumerate() {
        let ends = triangulate_bar(cameras, obs).at(Context::Frame(b))?;
        sq += (ends[0].distance(ends[1]) - bar_length_m).powi(2);
    }
    Ok((sq / observations.len() as f64).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Rig;
    use crate::math::{fit_similarity, Alignment};

    fn centre_error_m(cams: &[Camera], truth: &Rig) -> f64 {
        let from: Vec<DVec3> = cams.iter().map(Camera::centre).collect();
        let to: Vec<DVec3> = truth.cameras.iter().map(Camera::centre).collect();
        let s = fit_similarity(&from, &to, None, Alignment::Similarity).unwrap();
        from.iter()
            .zip(&to)
            .map(|(f, t)| s.apply(*f).distance(*t))
            .fold(0.0, f64::max)
    }

    #[test]
    fn noise_free_bars_give_the_exact_rig() {
        let s = synthetic_bar_calibration(20, 0.0, false, 5).unwrap();
        let cal = calibrate_with_bar(&s.initial, &s.observations, &BarCalibrationParams::new(0.5))
            .unwrap();
        let err = centre_error_m(&cal.cameras, &s.truth);
        eprintln!("noise-free: rms {} px centre {} mm", cal.rms_px, err * 1e3);
        assert!(err < 1e-5, "{err}");
    }

    #[test]
    fn recovers_the_rig_from_a_waved_bar() {
        let s = synthetic_bar_calibration(120, 0.3, false, 5).unwrap();
        let cal = calibrate_with_bar(&s.initial, &s.observations, &BarCalibrationParams::new(0.5))
            .unwrap();
        let before = centre_error_m(&s.initial, &s.truth);
        let after = centre_error_m(&cal.cameras, &s.truth);
        let length_rms = bar_length_rms_m(&cal.cameras, &s.observations, 0.5).unwrap();
        eprintln!(
            "bar_calibration_rms_px {} bar_camera_centre_mm {} (initial {}) bar_length_rms_mm {} iterations {}",
            cal.rms_px,
            after * 1e3,
            before * 1e3,
            length_rms * 1e3,
            cal.iterations
        );
        assert!(cal.rms_px <= 0.5, "rms {} px", cal.rms_px);
        assert!(after <= 3e-3, "centre error {} mm", after * 1e3);
        assert!(after < before / 5.0, "{after} vs initial {before}");
        assert!(length_rms < 2e-3, "length rms {length_rms}");
        assert_eq!(s.bars.len(), cal.bars.len());
    }

    #[test]
    fn bad_input_is_an_error() {
        let s = synthetic_bar_calibration(10, 0.0, true, 5).unwrap();
        let e = calibrate_with_bar(&s.initial, &s.observations, &BarCalibrationParams::new(0.5))
            .unwrap_err();
        assert!(matches!(e, Error::Degenerate { .. }), "{e}");
        let s = synthetic_bar_calibration(5, 0.0, false, 5).unwrap();
        assert!(calibrate_with_bar(
            &s.initial[..1],
            &s.observations,
            &BarCalibrationParams::new(0.5)
        )
        .is_err());
        assert!(
            calibrate_with_bar(&s.initial, &s.observations, &BarCalibrationParams::new(0.0))
                .is_err()
        );
        let mut nan = s.observations.clone();
        nan[2][1][0].x = f64::NAN;
        let e = calibrate_with_bar(&s.initial, &nan, &BarCalibrationParams::new(0.5)).unwrap_err();
        assert!(e.to_string().contains("non-finite"), "{e}");
        assert!(calibrate_with_bar(
            &s.initial,
            &s.observations[..2],
            &BarCalibrationParams::new(0.5)
        )
        .is_err());
    }
}
