//! Bar calibration (Fua et al. §2.2, after Maas 1998): "a reference bar with two
//! retroreflective target points is moved through the object space ... the camera system can
//! then be calibrated by self-calibrating bundle adjustment with the additional information
//! of the known distance between the two points at every location".
//!
//! Unknowns: every camera's pose (rotation increment and centre) and focal length (aspect
//! ratio, principal point and distortion kept), every bar position's midpoint and direction
//! (two angles); the endpoints are `midpoint ± ½·length·direction`, so the known length fixes
//! the scale. The gauge (rotation and translation of the world) is fixed by holding camera 0's
//! pose. Minimisation: dense Levenberg–Marquardt on the reprojection error with a
//! central-difference Jacobian (a few hundred unknowns for a three-camera rig).
//!
//! Initialisation (documented method): an approximate rig (e.g. the rig as planned or
//! measured with a tape); each bar position starts from the forward intersection of its two
//! endpoints through the approximate cameras.

use nalgebra::{DMatrix, DVector};

use crate::camera::Camera;
use crate::check::{all_finite, positive};
use crate::markers::{triangulate, MarkerView};
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
}

/// Per camera unknowns (camera 0 has only the focal length).
const CAMERA_PARAMS: usize = 7;
const BAR_PARAMS: usize = 5;

fn direction(theta: f64, phi: f64) -> DVec3 {
    DVec3::new(
        theta.sin() * phi.cos(),
        theta.sin() * phi.sin(),
        theta.cos(),
    )
}

struct Problem<'a> {
    initial: &'a [Camera],
    observations: &'a [Vec<[DVec2; 2]>],
    length: f64,
}

impl Problem<'_> {
    fn camera_offset(&self, c: usize) -> usize {
        if c == 0 {
            0
        } else {
            1 + (c - 1) * CAMERA_PARAMS
        }
    }

    fn bar_offset(&self, b: usize) -> usize {
        1 + (self.initial.len() - 1) * CAMERA_PARAMS + b * BAR_PARAMS
    }

    fn len(&self) -> usize {
        self.bar_offset(self.observations.len())
    }

    fn camera(&self, x: &DVector<f64>, c: usize) -> Result<Camera> {
        let c0 = &self.initial[c];
        let o = self.camera_offset(c);
        let mut k = c0.intrinsics;
        let aspect = k.fy / k.fx;
        let f = x[o] * c0.intrinsics.fx;
        k.fx = f;
        k.fy = f * aspect;
        if c == 0 {
            return Camera::new(k, c0.distortion, c0.world_from_camera());
        }
        let w = DVec3::new(x[o + 1], x[o + 2], x[o + 3]);
        let centre = DVec3::new(x[o + 4], x[o + 5], x[o + 6]);
        let r0 = DQuat::from_mat3(&c0.world_from_camera().matrix3);
        let r = DQuat::from_scaled_axis(w) * r0;
        Camera::new(
            k,
            c0.distortion,
            DAffine3::from_mat3_translation(DMat3::from_quat(r.normalize()), centre),
        )
    }

    fn bar(&self, x: &DVector<f64>, b: usize) -> [DVec3; 2] {
        let o = self.bar_offset(b);
        let m = DVec3::new(x[o], x[o + 1], x[o + 2]);
        let d = direction(x[o + 3], x[o + 4]) * (0.5 * self.length);
        [m - d, m + d]
    }

    fn residuals(&self, x: &DVector<f64>) -> Result<DVector<f64>> {
        let cams: Vec<Camera> = (0..self.initial.len())
            .map(|c| self.camera(x, c))
            .collect::<Result<_>>()?;
        let n = self.observations.len() * cams.len() * 4;
        let mut r = DVector::zeros(n);
        let mut k = 0;
        for (b, obs) in self.observations.iter().enumerate() {
            let ends = self.bar(x, b);
            for (c, cam) in cams.iter().enumerate() {
                for e in 0..2 {
                    let p = cam.project(ends[e]).at(Context::Camera(c))? - obs[c][e];
                    r[k] = p.x;
                    r[k + 1] = p.y;
                    k += 2;
                }
            }
        }
        Ok(r)
    }
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
        initial,
        observations,
        length,
    };
    let mut x = DVector::zeros(problem.len());
    for (c, camera) in initial.iter().enumerate() {
        let o = problem.camera_offset(c);
        x[o] = 1.0;
        if c > 0 {
            let centre = camera.centre();
            x[o + 4] = centre.x;
            x[o + 5] = centre.y;
            x[o + 6] = centre.z;
        }
    }
    for (b, ends) in bars0.iter().enumerate() {
        let o = problem.bar_offset(b);
        let m = 0.5 * (ends[0] + ends[1]);
        let d = (ends[1] - ends[0]).normalize_or(DVec3::Z);
        x[o] = m.x;
        x[o + 1] = m.y;
        x[o + 2] = m.z;
        x[o + 3] = d.z.clamp(-1.0, 1.0).acos();
        x[o + 4] = d.y.atan2(d.x);
    }
    let mut r = problem.residuals(&x)?;
    let mut cost = r.norm_squared();
    let mut lambda = 1e-3;
    let mut iterations = 0;
    let h = 1e-7;
    for _ in 0..params.max_iterations {
        iterations += 1;
        let n = x.len();
        let mut j = DMatrix::zeros(r.len(), n);
        for i in 0..n {
            let mut xp = x.clone();
            xp[i] += h;
            let mut xm = x.clone();
            xm[i] -= h;
            let d = (problem.residuals(&xp)? - problem.residuals(&xm)?) / (2.0 * h);
            j.set_column(i, &d);
        }
        let jtj = j.transpose() * &j;
        let jtr = j.transpose() * &r;
        let mut improved = false;
        for _ in 0..10 {
            let mut a = jtj.clone();
            for i in 0..n {
                a[(i, i)] += lambda * (jtj[(i, i)] + 1e-12);
            }
            let Some(chol) = a.cholesky() else {
                lambda *= 10.0;
                continue;
            };
            let step = chol.solve(&(-&jtr));
            let xn = &x + &step;
            match problem.residuals(&xn) {
                Ok(rn) if rn.norm_squared() < cost => {
                    let cn = rn.norm_squared();
                    let rel = (cost - cn) / cost.max(f64::MIN_POSITIVE);
                    x = xn;
                    r = rn;
                    cost = cn;
                    lambda = (lambda * 0.3).max(1e-12);
                    improved = rel > params.tolerance;
                    break;
                }
                _ => lambda *= 10.0,
            }
        }
        if !improved {
            break;
        }
    }
    let cameras = (0..initial.len())
        .map(|c| problem.camera(&x, c))
        .collect::<Result<Vec<_>>>()?;
    let bars = (0..observations.len())
        .map(|b| problem.bar(&x, b))
        .collect();
    let count = (r.len() / 2).max(1);
    Ok(BarCalibration {
        cameras,
        bars,
        rms_px: (cost / count as f64).sqrt(),
        iterations,
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
