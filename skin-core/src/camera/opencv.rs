//! Import and export of OpenCV calibrations (`K`, distortion coefficients, `R`, `t`) as
//! `FileStorage` YAML, the format `cv::FileStorage` and OpenCV's calibration samples write.
//!
//! OpenCV's lens model distorts normalised coordinates about the **principal point** with
//! `(k1, k2, p1, p2[, k3[, k4, k5, k6]])`; ours (Sand 2003 §4.1) is first-order radial about a
//! **separate centre**. The mapping:
//! * **Exact** when only `k1` is non-zero (OpenCV → ours: centre = principal point), or when our
//!   centre equals the principal point (ours → OpenCV: `(k1, 0, 0, 0, 0)`).
//! * **Fitted** otherwise: the other model's coefficients are fitted by least squares to the
//!   distorted positions of a grid of undistorted pixels covering the image (import: `k1` and
//!   centre by Levenberg–Marquardt; export: `k1, k2, p1, p2, k3`, which enter linearly). The
//!   largest deviation over the grid is reported, and if it exceeds
//!   [`OpenCvParams::max_deviation_px`] the conversion is refused with [`Error::InvalidParam`] —
//!   we prefer a clear error to a silently wrong camera.
//!
//! Files may carry no extrinsics (`R`, `T` absent): the camera is then placed at the world
//! origin (`camera_from_world = I`).

use nalgebra::{DMatrix, DVector, Matrix3, Vector3};
use serde::{Deserialize, Serialize};

use super::distortion::RadialDistortion;
use super::intrinsics::Intrinsics;
use super::model::Camera;
use super::opencv_yaml::{self, YamlMatrix, YamlValue, FORMAT};
use crate::check::all_finite;
use crate::error::{Error, Result};
use crate::math::{DAffine3, DMat3, DQuat, DVec2, DVec3};
use crate::optim::{levenberg_marquardt_numeric, LmParams};

/// Knobs of the OpenCV conversions.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct OpenCvParams {
    /// Largest accepted deviation between the two distortion models over the image, px.
    /// Default: 0.5 (sub-pixel, the accuracy Sand's calibration reaches, §4.1).
    pub max_deviation_px: f64,
    /// Grid points per image axis used for fitting and measuring the deviation. Default: 25.
    pub grid: usize,
    /// Metres per unit of the file's translation `T` (0.001 for millimetres). Default: 1.0.
    pub translation_unit_m: f64,
}

impl Default for OpenCvParams {
    fn default() -> Self {
        Self {
            max_deviation_px: 0.5,
            grid: 25,
            translation_unit_m: 1.0,
        }
    }
}

/// An OpenCV calibration: `x_pixel = K · distort([R | t] X)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OpenCvCalibration {
    /// Image width, px.
    pub image_width: u32,
    /// Image height, px.
    pub image_height: u32,
    /// Camera matrix `K` (3×3, OpenCV `camera_matrix`).
    pub camera_matrix: Matrix3<f64>,
    /// Distortion coefficients `(k1, k2, p1, p2[, k3[, k4, k5, k6[, s1..s4[, τx, τy]]]])`.
    pub distortion: Vec<f64>,
    /// Rotation `R` of `camera_from_world`.
    pub rotation: Matrix3<f64>,
    /// Translation `t` of `camera_from_world`, file units.
    pub translation: Vector3<f64>,
}

/// A converted camera with the model deviation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OpenCvImport {
    /// The camera in our model.
    pub camera: Camera,
    /// Largest difference between the two distortion models over the image grid, px (0 when
    /// the mapping is exact).
    pub max_deviation_px: f64,
    /// True if the mapping is exact.
    pub exact: bool,
}

/// An exported calibration with the model deviation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OpenCvExport {
    /// The calibration in OpenCV's model.
    pub calibration: OpenCvCalibration,
    /// Largest difference between the two distortion models over the image grid, px.
    pub max_deviation_px: f64,
    /// True if the mapping is exact.
    pub exact: bool,
}

/// OpenCV's distortion of a normalised point (`cv::projectPoints` without tilt).
fn opencv_distort(d: &[f64], p: DVec2) -> DVec2 {
    let c = |i: usize| d.get(i).copied().unwrap_or(0.0);
    let (x, y) = (p.x, p.y);
    let r2 = x * x + y * y;
    let radial = (1.0 + c(0) * r2 + c(1) * r2 * r2 + c(4) * r2 * r2 * r2)
        / (1.0 + c(5) * r2 + c(6) * r2 * r2 + c(7) * r2 * r2 * r2);
    let (s1, s2, s3, s4) = (c(8), c(9), c(10), c(11));
    DVec2::new(
        x * radial + 2.0 * c(2) * x * y + c(3) * (r2 + 2.0 * x * x) + s1 * r2 + s2 * r2 * r2,
        y * radial + c(2) * (r2 + 2.0 * y * y) + 2.0 * c(3) * x * y + s3 * r2 + s4 * r2 * r2,
    )
}

/// Undistorted pixels on a `g × g` grid covering the image.
fn grid(k: &Intrinsics, g: usize) -> Vec<DVec2> {
    let g = g.max(2);
    let (w, h) = (k.width as f64 - 1.0, k.height as f64 - 1.0);
    (0..g * g)
        .map(|i| {
            DVec2::new(
                (i % g) as f64 * w / (g - 1) as f64,
                (i / g) as f64 * h / (g - 1) as f64,
            )
        })
        .collect()
}

fn matrix_entry(entries: &opencv_yaml::YamlEntries, names: &[&str]) -> Option<YamlMatrix> {
    entries.iter().find_map(|(k, v, _)| match v {
        YamlValue::Matrix(m) if names.contains(&k.as_str()) => Some(m.clone()),
        _ => None,
    })
}

fn scalar_u32(entries: &opencv_yaml::YamlEntries, names: &[&str]) -> Result<Option<u32>> {
    for (k, v, line) in entries {
        if names.contains(&k.as_str()) {
            if let YamlValue::Scalar(s) = v {
                return s.parse::<u32>().map(Some).map_err(|_| Error::Parse {
                    format: FORMAT,
                    line: *line,
                    message: format!("{k} must be a non-negative integer, got {s:?}"),
                });
            }
        }
    }
    Ok(None)
}

fn shape_err(m: &YamlMatrix, what: &str) -> Error {
    Error::Parse {
        format: FORMAT,
        line: m.line,
        message: format!("{what} has shape {}x{}", m.rows, m.cols),
    }
}

impl OpenCvCalibration {
    /// Parses OpenCV `FileStorage` YAML. Keys (aliases in brackets): `image_width`,
    /// `image_height`, `camera_matrix` (`K`, `cameraMatrix`), `distortion_coefficients`
    /// (`dist_coeffs`, `distCoeffs`, `D`), optional `R` (3×3, or a 3-vector Rodrigues `rvec`)
    /// and `T` (`t`, `tvec`).
    ///
    /// # Errors
    /// [`Error::Parse`] with a line number for malformed YAML, missing keys, wrong matrix shapes
    /// or unsupported distortion vector lengths.
    pub fn from_yaml_str(text: &str) -> Result<Self> {
        let entries = opencv_yaml::parse(text)?;
        let missing = |what: &str| Error::Parse {
            format: FORMAT,
            line: 0,
            message: format!("missing {what}"),
        };
        let image_width = scalar_u32(&entries, &["image_width", "imageWidth"])?
            .ok_or_else(|| missing("image_width"))?;
        let image_height = scalar_u32(&entries, &["image_height", "imageHeight"])?
            .ok_or_else(|| missing("image_height"))?;
        let k = matrix_entry(&entries, &["camera_matrix", "cameraMatrix", "K"])
            .ok_or_else(|| missing("camera_matrix"))?;
        if (k.rows, k.cols) != (3, 3) {
            return Err(shape_err(&k, "camera_matrix"));
        }
        let d = matrix_entry(
            &entries,
            &["distortion_coefficients", "dist_coeffs", "distCoeffs", "D"],
        )
        .ok_or_else(|| missing("distortion_coefficients"))?;
        if d.rows.min(d.cols) != 1 || ![4, 5, 8, 12, 14].contains(&d.data.len()) {
            return Err(shape_err(
                &d,
                "distortion_coefficients (expected 1x4, 1x5, 1x8, 1x12 or 1x14)",
            ));
        }
        let rotation = match matrix_entry(&entries, &["R", "rotation_matrix", "rvec", "rvecs"]) {
            None => Matrix3::identity(),
            Some(r) if (r.rows, r.cols) == (3, 3) => Matrix3::from_row_slice(&r.data),
            Some(r) if r.data.len() == 3 && r.rows.min(r.cols) == 1 => {
                let v = Vector3::from_column_slice(&r.data);
                nalgebra::Rotation3::new(v).into_inner()
            }
            Some(r) => return Err(shape_err(&r, "R")),
        };
        let translation = match matrix_entry(&entries, &["T", "t", "tvec", "tvecs"]) {
            None => Vector3::zeros(),
            Some(t) if t.data.len() == 3 && t.rows.min(t.cols) == 1 => {
                Vector3::from_column_slice(&t.data)
            }
            Some(t) => return Err(shape_err(&t, "T")),
        };
        if !rotation.iter().all(|v| v.is_finite()) {
            return Err(Error::Parse {
                format: FORMAT,
                line: 0,
                message: "rotation vector too large".into(),
            });
        }
        Ok(Self {
            image_width,
            image_height,
            camera_matrix: Matrix3::from_row_slice(&k.data),
            distortion: d.data,
            rotation,
            translation,
        })
    }

    /// Writes OpenCV `FileStorage` YAML (`image_width`, `image_height`, `camera_matrix`,
    /// `distortion_coefficients`, `R`, `T`), readable by `cv::FileStorage`.
    pub fn to_yaml_string(&self) -> String {
        let mat = |rows: usize, cols: usize, data: Vec<f64>| {
            YamlValue::Matrix(YamlMatrix {
                rows,
                cols,
                data,
                line: 0,
            })
        };
        let row_major = |m: &Matrix3<f64>| m.transpose().as_slice().to_vec();
        opencv_yaml::write(&[
            (
                "image_width",
                YamlValue::Scalar(self.image_width.to_string()),
            ),
            (
                "image_height",
                YamlValue::Scalar(self.image_height.to_string()),
            ),
            ("camera_matrix", mat(3, 3, row_major(&self.camera_matrix))),
            (
                "distortion_coefficients",
                mat(1, self.distortion.len(), self.distortion.clone()),
            ),
            ("R", mat(3, 3, row_major(&self.rotation))),
            ("T", mat(3, 1, self.translation.as_slice().to_vec())),
        ])
    }

    /// Converts to our camera model (module docs for the distortion mapping).
    ///
    /// # Errors
    /// [`Error::NonFinite`]; [`Error::InvalidParam`] for skew, a non-rigid `R`, unsupported
    /// tilt coefficients, or a distortion our model cannot match within
    /// [`OpenCvParams::max_deviation_px`].
    pub fn to_camera(&self, params: &OpenCvParams) -> Result<OpenCvImport> {
        let k = &self.camera_matrix;
        all_finite("camera_matrix", k.iter())?;
        all_finite("distortion coefficients", self.distortion.iter())?;
        if k[(2, 0)] != 0.0 || k[(2, 1)] != 0.0 || k[(2, 2)] == 0.0 || k[(1, 0)] != 0.0 {
            return Err(Error::InvalidParam {
                name: "camera_matrix",
                reason: "must be upper triangular with K[2][2] != 0".into(),
            });
        }
        let k = k / k[(2, 2)];
        if k[(0, 1)].abs() > 1e-9 * k[(0, 0)].abs() {
            return Err(Error::InvalidParam {
                name: "camera_matrix",
                reason: format!("skew {} is not supported", k[(0, 1)]),
            });
        }
        if self.distortion.len() > 12 && self.distortion[12..].iter().any(|v| *v != 0.0) {
            return Err(Error::InvalidParam {
                name: "distortion_coefficients",
                reason: "tilted-sensor terms are not supported".into(),
            });
        }
        let intr = Intrinsics::new(
            k[(0, 0)],
            k[(1, 1)],
            k[(0, 2)],
            k[(1, 2)],
            self.image_width,
            self.image_height,
        )?;
        let pose = rigid(
            &self.rotation,
            &(self.translation * params.translation_unit_m),
        )?;
        let pp = intr.principal_point();
        let k1_only = self
            .distortion
            .iter()
            .enumerate()
            .all(|(i, v)| i == 0 || *v == 0.0);
        let d0 = RadialDistortion::new(self.distortion.first().copied().unwrap_or(0.0), pp);
        let (distortion, deviation, exact) = if k1_only {
            (d0, 0.0, true)
        } else {
            let pts = grid(&intr, params.grid);
            let targets: Vec<DVec2> = pts
                .iter()
                .map(|u| {
                    intr.pixel_from_normalized(opencv_distort(
                        &self.distortion,
                        intr.normalized_from_pixel(*u),
                    ))
                })
                .collect();
            let residual = |x: &DVector<f64>| {
                let d = RadialDistortion::new(x[0], DVec2::new(x[1], x[2]));
                let mut r = DVector::zeros(2 * pts.len());
                for (i, (u, t)) in pts.iter().zip(&targets).enumerate() {
                    let p = d.distort(&intr, *u).ok_or_else(|| Error::NotVisible {
                        what: "beyond fold".into(),
                    })?;
                    r[2 * i] = p.x - t.x;
                    r[2 * i + 1] = p.y - t.y;
                }
                Ok(r)
            };
            let rep = levenberg_marquardt_numeric(
                &DVector::from_vec(vec![d0.k1, pp.x, pp.y]),
                &LmParams::default(),
                residual,
            )?;
            let d = RadialDistortion::new(rep.x[0], DVec2::new(rep.x[1], rep.x[2]));
            let dev = (0..pts.len())
                .map(|i| rep.residuals[2 * i].hypot(rep.residuals[2 * i + 1]))
                .fold(0.0, f64::max);
            (d, dev, false)
        };
        check_deviation(deviation, params)?;
        Ok(OpenCvImport {
            camera: Camera::from_camera_from_world(intr, distortion, pose)?,
            max_deviation_px: deviation,
            exact,
        })
    }

    /// Converts our camera to OpenCV's model with 5 coefficients `(k1, k2, p1, p2, k3)`.
    ///
    /// # Errors
    /// [`Error::InvalidParam`] if OpenCV's model cannot match ours within
    /// [`OpenCvParams::max_deviation_px`] or the unit is not positive.
    pub fn from_camera(camera: &Camera, params: &OpenCvParams) -> Result<OpenCvExport> {
        if !(params.translation_unit_m.is_finite() && params.translation_unit_m > 0.0) {
            return Err(Error::InvalidParam {
                name: "translation_unit_m",
                reason: "must be finite and > 0".into(),
            });
        }
        let intr = camera.intrinsics;
        let d = camera.distortion;
        let exact = d.k1 == 0.0 || (d.centre - intr.principal_point()).length() <= 1e-9;
        let (coeffs, deviation) = if exact {
            (vec![d.k1, 0.0, 0.0, 0.0, 0.0], 0.0)
        } else {
            // Linear least squares: x_d − x = x(k1 r² + k2 r⁴ + k3 r⁶) + 2p1xy + p2(r² + 2x²), …
            let pts: Vec<(DVec2, DVec2)> = grid(&intr, params.grid)
                .into_iter()
                .filter_map(|u| {
                    d.distort(&intr, u)
                        .map(|q| (intr.normalized_from_pixel(u), intr.normalized_from_pixel(q)))
                })
                .collect();
            let mut a = DMatrix::zeros(2 * pts.len(), 5);
            let mut b = DVector::zeros(2 * pts.len());
            for (i, (n, q)) in pts.iter().enumerate() {
                let (x, y) = (n.x, n.y);
                let r2 = x * x + y * y;
                let rows = [
                    [
                        x * r2,
                        x * r2 * r2,
                        2.0 * x * y,
                        r2 + 2.0 * x * x,
                        x * r2 * r2 * r2,
                    ],
                    [
                        y * r2,
                        y * r2 * r2,
                        r2 + 2.0 * y * y,
                        2.0 * x * y,
                        y * r2 * r2 * r2,
                    ],
                ];
                for c in 0..5 {
                    a[(2 * i, c)] = rows[0][c] * intr.fx;
                    a[(2 * i + 1, c)] = rows[1][c] * intr.fy;
                }
                b[2 * i] = (q.x - x) * intr.fx;
                b[2 * i + 1] = (q.y - y) * intr.fy;
            }
            let sol = a
                .clone()
                .svd(true, true)
                .solve(&b, 1e-15)
                .map_err(|e| Error::Singular {
                    what: format!("OpenCV distortion fit: {e}"),
                })?;
            let r = &a * &sol - &b;
            let dev = (0..pts.len())
                .map(|i| r[2 * i].hypot(r[2 * i + 1]))
                .fold(0.0, f64::max);
            (vec![sol[0], sol[1], sol[2], sol[3], sol[4]], dev)
        };
        check_deviation(deviation, params)?;
        let cfw = camera.camera_from_world();
        let m = cfw.matrix3;
        let t = cfw.translation / params.translation_unit_m;
        Ok(OpenCvExport {
            calibration: OpenCvCalibration {
                image_width: intr.width,
                image_height: intr.height,
                camera_matrix: Matrix3::new(
                    intr.fx, 0.0, intr.cx, 0.0, intr.fy, intr.cy, 0.0, 0.0, 1.0,
                ),
                distortion: coeffs,
                rotation: Matrix3::from_column_slice(&m.to_cols_array()),
                translation: Vector3::new(t.x, t.y, t.z),
            },
            max_deviation_px: deviation,
            exact,
        })
    }
}

fn check_deviation(deviation: f64, params: &OpenCvParams) -> Result<()> {
    if deviation > params.max_deviation_px {
        return Err(Error::InvalidParam {
            name: "distortion",
            reason: format!(
                "the two distortion models differ by up to {deviation:.3} px over the image (limit {} px); \
                 raise OpenCvParams::max_deviation_px to accept the approximation",
                params.max_deviation_px
            ),
        });
    }
    Ok(())
}

fn rigid(r: &Matrix3<f64>, t: &Vector3<f64>) -> Result<DAffine3> {
    all_finite("R", r.iter())?;
    all_finite("T", t.iter())?;
    let m = DMat3::from_cols_slice(r.as_slice());
    // Re-orthonormalise (files store ~8 digits) via the nearest rotation of the quaternion.
    let q = DQuat::from_mat3(&m).normalize();
    if (DMat3::from_quat(q) - m)
        .to_cols_array()
        .iter()
        .any(|v| v.abs() > 1e-5)
    {
        return Err(Error::InvalidParam {
            name: "R",
            reason: "is not a rotation matrix".into(),
        });
    }
    Ok(DAffine3::from_rotation_translation(
        q,
        DVec3::new(t[0], t[1], t[2]),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::synthetic::{synthetic_calibration, SyntheticCalibrationParams};
    use rand::SeedableRng;

    fn truth() -> Camera {
        let s = synthetic_calibration(
            &SyntheticCalibrationParams::default(),
            &mut rand_chacha::ChaCha8Rng::seed_from_u64(4),
        )
        .unwrap();
        s.truth
    }

    #[test]
    fn yaml_round_trip_exact_k1() {
        let mut cam = truth();
        cam.distortion.centre = cam.intrinsics.principal_point();
        let exp = OpenCvCalibration::from_camera(&cam, &OpenCvParams::default()).unwrap();
        assert!(exp.exact && exp.max_deviation_px == 0.0);
        let text = exp.calibration.to_yaml_string();
        let back = OpenCvCalibration::from_yaml_str(&text).unwrap();
        assert_eq!(back, exp.calibration);
        let imp = back.to_camera(&OpenCvParams::default()).unwrap();
        assert!(imp.exact);
        for p in [DVec3::ZERO, DVec3::new(0.5, -0.4, 0.3)] {
            assert!((imp.camera.project(p).unwrap() - cam.project(p).unwrap()).length() < 1e-9);
        }
    }

    #[test]
    fn offset_centre_is_fitted_and_reported() {
        let cam = truth(); // distortion centre 18 px from the principal point
        let exp = OpenCvCalibration::from_camera(&cam, &OpenCvParams::default()).unwrap();
        assert!(
            !exp.exact && exp.max_deviation_px > 0.0 && exp.max_deviation_px < 0.5,
            "{}",
            exp.max_deviation_px
        );
        // Importing the fitted OpenCV model comes back close to the original.
        let imp = exp.calibration.to_camera(&OpenCvParams::default()).unwrap();
        assert!(!imp.exact && imp.max_deviation_px < 0.5);
        let p = DVec3::new(0.6, 0.5, -0.4);
        assert!((imp.camera.project(p).unwrap() - cam.project(p).unwrap()).length() < 1.0);
        // Strong higher-order terms cannot be matched: a clear error.
        let mut strong = exp.calibration.clone();
        strong.distortion = vec![-0.3, 0.4, 0.0, 0.0, -0.5];
        assert!(matches!(
            strong.to_camera(&OpenCvParams::default()),
            Err(Error::InvalidParam { .. })
        ));
        let lenient = OpenCvParams {
            max_deviation_px: 1e9,
            ..Default::default()
        };
        assert!(strong.to_camera(&lenient).unwrap().max_deviation_px > 0.5);
    }

    #[test]
    fn reads_opencv_sample_with_rvec_and_mm() {
        let text = "%YAML:1.0\nimage_width: 640\nimage_height: 480\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 500., 0., 320., 0., 510., 240., 0., 0., 1. ]\ndistortion_coefficients: !!opencv-matrix\n   rows: 5\n   cols: 1\n   dt: d\n   data: [ -0.1, 0., 0., 0., 0. ]\nrvec: !!opencv-matrix\n   rows: 3\n   cols: 1\n   dt: d\n   data: [ 0., 0.5, 0. ]\ntvec: !!opencv-matrix\n   rows: 3\n   cols: 1\n   dt: d\n   data: [ 10., 20., 3000. ]\n";
        let c = OpenCvCalibration::from_yaml_str(text).unwrap();
        let imp = c
            .to_camera(&OpenCvParams {
                translation_unit_m: 1e-3,
                ..Default::default()
            })
            .unwrap();
        assert!(imp.exact);
        assert!(
            (imp.camera.camera_from_world().translation - DVec3::new(0.01, 0.02, 3.0)).length()
                < 1e-12
        );
        let r = imp.camera.camera_from_world().matrix3;
        assert!(
            (r.x_axis.z - (-(0.5f64).sin())).abs() < 1e-9,
            "rvec about y"
        );
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(256))]
        /// Mutated files never panic the reader; whatever it accepts survives a round trip.
        #[test]
        fn mutated_files_never_panic(cut in 0usize..400, len in 0usize..40, insert in "[ -~\n]{0,12}") {
            let good = OpenCvCalibration::from_camera(&truth().with_distortion(RadialDistortion::NONE), &OpenCvParams::default())
                .unwrap()
                .calibration
                .to_yaml_string();
            let start = cut.min(good.len());
            let end = (start + len).min(good.len());
            let text = format!("{}{}{}", &good[..start], insert, &good[end..]);
            if let Ok(c) = OpenCvCalibration::from_yaml_str(&text) {
                let again = OpenCvCalibration::from_yaml_str(&c.to_yaml_string()).unwrap();
                proptest::prop_assert_eq!(again, c);
            }
        }
    }

    #[test]
    fn malformed_files_are_clear_errors() {
        let good = OpenCvCalibration::from_camera(
            &truth().with_distortion(RadialDistortion::NONE),
            &OpenCvParams::default(),
        )
        .unwrap()
        .calibration
        .to_yaml_string();
        for (from, to) in [
            ("image_width: 1280", ""),
            ("image_width: 1280", "image_width: wide"),
            ("rows: 1\n   cols: 5", "rows: 1\n   cols: 3"),
            ("camera_matrix", "cam"),
            ("%YAML:1.0", "{"),
        ] {
            let bad = good.replacen(from, to, 1);
            assert!(
                matches!(
                    OpenCvCalibration::from_yaml_str(&bad),
                    Err(Error::Parse { .. })
                ),
                "{from} -> {to}"
            );
        }
        let mut c = OpenCvCalibration::from_yaml_str(&good).unwrap();
        c.camera_matrix[(0, 1)] = 3.0;
        assert!(matches!(
            c.to_camera(&OpenCvParams::default()),
            Err(Error::InvalidParam { .. })
        ));
        c.camera_matrix[(0, 1)] = f64::NAN;
        assert!(matches!(
            c.to_camera(&OpenCvParams::default()),
            Err(Error::NonFinite { .. })
        ));
    }
}
