//! Linear camera calibration: the normalised direct linear transform (Hartley & Zisserman 2004,
//! *Multiple View Geometry*, Alg. 7.1) and the RQ decomposition of `P = K[R | t]` (ibid. §6.2.4).
//! It initialises the non-linear refinement that Sand 2003 §4.1 describes.

use nalgebra::{DMatrix, Matrix3, Matrix3x4, SymmetricEigen, Vector3};
use serde::{Deserialize, Serialize};

use super::distortion::RadialDistortion;
use super::intrinsics::Intrinsics;
use super::model::Camera;
use crate::check::all_finite;
use crate::error::{Error, Result};
use crate::math::{DAffine3, DMat3, DVec2, DVec3};

/// Fewest correspondences the DLT accepts: 11 unknowns, two equations per point.
pub const MIN_CORRESPONDENCES: usize = 6;
/// Smallest singular value ratio `σ₁₁/σ₁` of the DLT system still treated as full rank.
const DLT_RANK_TOLERANCE: f64 = 1e-12;

/// Result of [`dlt`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DltEstimate {
    /// Camera with `K` from the decomposition (skew dropped) and no distortion.
    pub camera: Camera,
    /// The projection matrix `P` (scale: `P = K[R|t]` with `K₃₃ = 1`).
    pub projection: Matrix3x4<f64>,
    /// Skew `K₁₂` of the decomposition, px (dropped from [`DltEstimate::camera`]; large values
    /// signal bad data).
    pub skew_px: f64,
    /// Reprojection RMS of [`DltEstimate::camera`] over the input, px.
    pub rms_px: f64,
}

/// Result of [`decompose_projection`]: `P ∝ K [R | t]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ProjectionDecomposition {
    /// Upper-triangular calibration matrix with positive diagonal and `K₃₃ = 1`.
    pub k: DMat3,
    /// Rigid world → camera transform `[R | t]`, `det R = +1`.
    pub camera_from_world: DAffine3,
}

/// Checks 2D–3D correspondences for calibration: equal lengths, at least
/// [`MIN_CORRESPONDENCES`], finite values, and world points that are not (nearly) coplanar —
/// the smallest principal standard deviation must exceed `coplanarity_tolerance` times the
/// largest.
///
/// # Errors
/// [`Error::SizeMismatch`], [`Error::InvalidParam`] (too few points), [`Error::NonFinite`],
/// [`Error::Singular`] (coplanar, collinear or coincident world points).
pub fn validate_correspondences(
    world: &[DVec3],
    pixels: &[DVec2],
    coplanarity_tolerance: f64,
) -> Result<()> {
    if world.len() != pixels.len() {
        return Err(Error::SizeMismatch {
            what: "calibration world points vs pixels",
            expected: world.len(),
            got: pixels.len(),
        });
    }
    if world.len() < MIN_CORRESPONDENCES {
        return Err(Error::InvalidParam {
            name: "correspondences",
            reason: format!(
                "calibration needs at least {MIN_CORRESPONDENCES} 2D-3D points, got {}",
                world.len()
            ),
        });
    }
    all_finite(
        "calibration world points",
        world.iter().flat_map(|p| p.as_ref().iter()),
    )?;
    all_finite(
        "calibration pixels",
        pixels.iter().flat_map(|p| p.as_ref().iter()),
    )?;
    let n = world.len() as f64;
    let mean = world.iter().fold(DVec3::ZERO, |a, p| a + *p) / n;
    let mut cov = Matrix3::<f64>::zeros();
    for p in world {
        let d = Vector3::new(p.x - mean.x, p.y - mean.y, p.z - mean.z);
        cov += d * d.transpose();
    }
    let eig = SymmetricEigen::new(cov / n).eigenvalues;
    let (lo, hi) = (eig.min().max(0.0), eig.max());
    if hi <= 0.0 || (lo / hi).sqrt() < coplanarity_tolerance {
        return Err(Error::Singular {
            what: format!(
                "calibration world points are coplanar (spread ratio {:.2e} < {coplanarity_tolerance:.0e}); \
                 the DLT needs points spread in depth",
                (lo / hi.max(f64::MIN_POSITIVE)).sqrt()
            ),
        });
    }
    Ok(())
}

/// Similarity `T` with `T·x` centred and mean distance `√dim` (Hartley normalisation): returns
/// (centroid, scale) so that `x' = scale·(x − centroid)`.
fn normalisation<const D: usize>(
    points: impl Iterator<Item = [f64; D]> + Clone,
) -> ([f64; D], f64) {
    let mut c = [0.0; D];
    let mut n = 0.0;
    for p in points.clone() {
        for k in 0..D {
            c[k] += p[k];
        }
        n += 1.0;
    }
    c.iter_mut().for_each(|v| *v /= n);
    let mean_dist = points
        .map(|p| (0..D).map(|k| (p[k] - c[k]).powi(2)).sum::<f64>().sqrt())
        .sum::<f64>()
        / n;
    let scale = if mean_dist > 0.0 {
        (D as f64).sqrt() / mean_dist
    } else {
        1.0
    };
    (c, scale)
}

/// Decomposes a finite projection matrix into `K[R|t]` by RQ decomposition of its left 3×3 block
/// (Hartley & Zisserman §6.2.4), fixing the overall sign so that `det M > 0` (points in front of
/// the camera have positive depth).
///
/// # Errors
/// [`Error::NonFinite`] for non-finite entries; [`Error::Singular`] if the left 3×3 block is
/// singular (a camera at infinity).
pub fn decompose_projection(p: &Matrix3x4<f64>) -> Result<ProjectionDecomposition> {
    all_finite("projection matrix", p.iter())?;
    let mut p = *p;
    let m: Matrix3<f64> = p.fixed_view::<3, 3>(0, 0).into_owned();
    let det = m.determinant();
    if det.abs() <= 1e-300 || !det.is_finite() || det.abs() < 1e-12 * m.norm().powi(3) {
        return Err(Error::Singular {
            what: "projection matrix has a singular 3x3 block (camera at infinity)".into(),
        });
    }
    if det < 0.0 {
        p = -p;
    }
    let m: Matrix3<f64> = p.fixed_view::<3, 3>(0, 0).into_owned();
    // RQ via QR of the flipped transpose: with J the exchange matrix, (J M)ᵀ = Q U gives
    // M = (J Uᵀ J)(J Qᵀ), an upper-triangular times an orthogonal matrix.
    let j = Matrix3::new(0.0, 0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 0.0);
    let qr = (j * m).transpose().qr();
    let (q, u) = (qr.q(), qr.r());
    let mut k = j * u.transpose() * j;
    let mut r = j * q.transpose();
    for i in 0..3 {
        if k[(i, i)] < 0.0 {
            // K·D and D·R with D = diag(±1) leave the product unchanged.
            k.column_mut(i).neg_mut();
            r.row_mut(i).neg_mut();
        }
    }
    let t = k.try_inverse().ok_or_else(|| Error::Singular {
        what: "calibration matrix of the projection is singular".into(),
    })? * p.column(3);
    let k = k / k[(2, 2)];
    let to_glam = |a: &Matrix3<f64>| DMat3::from_cols_slice(a.as_slice());
    let rot = to_glam(&r);
    if (rot.determinant() - 1.0).abs() > 1e-6 {
        return Err(Error::Singular {
            what: "projection decomposition did not yield a rotation".into(),
        });
    }
    Ok(ProjectionDecomposition {
        k: to_glam(&k),
        camera_from_world: DAffine3::from_mat3_translation(rot, DVec3::new(t[0], t[1], t[2])),
    })
}

/// Normalised DLT: the camera minimising the algebraic error of `pᵢ × P wᵢ = 0` with points and
/// pixels normalised to unit spread (Hartley & Zisserman Alg. 7.1), then decomposed into
/// `K[R|t]`. Ignores distortion, so it is the initialisation for [`super::calibrate`].
///
/// # Errors
/// Errors of [`validate_correspondences`]; [`Error::Singular`] for a rank-deficient system or a
/// solution that puts points behind the camera; [`Error::InvalidParam`] for an empty image.
pub fn dlt(
    world: &[DVec3],
    pixels: &[DVec2],
    width: u32,
    height: u32,
    coplanarity_tolerance: f64,
) -> Result<DltEstimate> {
    validate_correspondences(world, pixels, coplanarity_tolerance)?;
    let (cw, sw) = normalisation(world.iter().map(|p| p.to_array()));
    let (cp, sp) = normalisation(pixels.iter().map(|p| p.to_array()));
    let n = world.len();
    let mut a = DMatrix::<f64>::zeros(2 * n, 12);
    for (i, (w, px)) in world.iter().zip(pixels).enumerate() {
        let x = [
            (w.x - cw[0]) * sw,
            (w.y - cw[1]) * sw,
            (w.z - cw[2]) * sw,
            1.0,
        ];
        let (u, v) = ((px.x - cp[0]) * sp, (px.y - cp[1]) * sp);
        for k in 0..4 {
            a[(2 * i, k)] = x[k];
            a[(2 * i, 8 + k)] = -u * x[k];
            a[(2 * i + 1, 4 + k)] = x[k];
            a[(2 * i + 1, 8 + k)] = -v * x[k];
        }
    }
    let svd = a.svd(false, true);
    let v_t = svd.v_t.ok_or_else(|| Error::Singular {
        what: "DLT singular value decomposition failed".into(),
    })?;
    let mut order: Vec<usize> = (0..svd.singular_values.len()).collect();
    order.sort_by(|&x, &y| svd.singular_values[x].total_cmp(&svd.singular_values[y]));
    let (s_min2, s_max) = (
        svd.singular_values[order[1]],
        svd.singular_values[order[order.len() - 1]],
    );
    if s_min2 <= DLT_RANK_TOLERANCE * s_max {
        return Err(Error::Singular {
            what: "DLT system is rank deficient (degenerate point configuration)".into(),
        });
    }
    let h = v_t.row(order[0]);
    let p_norm = Matrix3x4::from_row_slice(h.transpose().as_slice());
    // Undo the normalisations: P = T_pix⁻¹ · P̃ · T_world.
    let t_world = nalgebra::Matrix4::new(
        sw,
        0.0,
        0.0,
        -sw * cw[0],
        0.0,
        sw,
        0.0,
        -sw * cw[1],
        0.0,
        0.0,
        sw,
        -sw * cw[2],
        0.0,
        0.0,
        0.0,
        1.0,
    );
    let t_pix_inv = Matrix3::new(1.0 / sp, 0.0, cp[0], 0.0, 1.0 / sp, cp[1], 0.0, 0.0, 1.0);
    let p = t_pix_inv * p_norm * t_world;
    let dec = decompose_projection(&p)?;
    let behind = world
        .iter()
        .filter(|w| dec.camera_from_world.transform_point3(**w).z <= 0.0)
        .count();
    if behind > 0 {
        return Err(Error::Singular {
            what: format!("DLT solution puts {behind} of {n} points behind the camera; check the correspondences"),
        });
    }
    let k = dec.k;
    let intrinsics = Intrinsics::new(
        k.x_axis.x, k.y_axis.y, k.z_axis.x, k.z_axis.y, width, height,
    )?;
    let camera =
        Camera::from_camera_from_world(intrinsics, RadialDistortion::NONE, dec.camera_from_world)?;
    let rms_px = reprojection_rms(&camera, world, pixels)?;
    let m = dec.camera_from_world.matrix3;
    let kr = k * m;
    let mut projection = Matrix3x4::zeros();
    let kt = k * dec.camera_from_world.translation;
    for r in 0..3 {
        for c in 0..3 {
            projection[(r, c)] = kr.col(c)[r];
        }
        projection[(r, 3)] = kt[r];
    }
    Ok(DltEstimate {
        camera,
        projection,
        skew_px: k.y_axis.x,
        rms_px,
    })
}

/// Root-mean-square reprojection error (px) of `camera` over the correspondences, per image
/// coordinate: `√(Σᵢ‖eᵢ‖²/(2N))`. With per-axis Gaussian pixel noise σ it tends to σ (minus the
/// fitted degrees of freedom). OpenCV's `calibrateCamera` reports `√(Σᵢ‖eᵢ‖²/N)`, √2 times this.
///
/// # Errors
/// [`Error::SizeMismatch`] for different lengths, [`Error::Empty`] for none, projection errors
/// (e.g. [`Error::NotVisible`] for a point behind the camera).
pub fn reprojection_rms(camera: &Camera, world: &[DVec3], pixels: &[DVec2]) -> Result<f64> {
    if world.len() != pixels.len() {
        return Err(Error::SizeMismatch {
            what: "world points vs pixels",
            expected: world.len(),
            got: pixels.len(),
        });
    }
    if world.is_empty() {
        return Err(Error::Empty {
            what: "correspondences",
        });
    }
    let mut sum = 0.0;
    for (w, p) in world.iter().zip(pixels) {
        sum += (camera.project(*w)? - *p).length_squared();
    }
    Ok((sum / (2 * world.len()) as f64).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::synthetic::{synthetic_calibration, SyntheticCalibrationParams};
    use rand::SeedableRng;

    #[test]
    fn dlt_is_exact_on_noise_free_data() {
        let params = SyntheticCalibrationParams {
            noise_px: 0.0,
            k1: 0.0,
            ..Default::default()
        };
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let s = synthetic_calibration(&params, &mut rng).unwrap();
        let est = dlt(&s.world, &s.pixels, params.width, params.height, 1e-3).unwrap();
        assert!(est.rms_px < 1e-8, "rms {}", est.rms_px);
        assert!((est.camera.centre() - s.truth.centre()).length() < 1e-9);
        let (a, b) = (est.camera.intrinsics, s.truth.intrinsics);
        assert!(
            (a.fx - b.fx).abs() < 1e-7 && (a.fy - b.fy).abs() < 1e-7 && (a.cx - b.cx).abs() < 1e-7
        );
        assert!(est.skew_px.abs() < 1e-7);
    }

    #[test]
    fn bad_correspondences_are_errors() {
        let w: Vec<DVec3> = (0..10)
            .map(|i| DVec3::new(i as f64, (i * i) as f64 * 0.1, 0.0))
            .collect();
        let p: Vec<DVec2> = (0..10).map(|i| DVec2::new(i as f64, 1.0)).collect();
        assert!(
            matches!(dlt(&w, &p, 64, 64, 1e-3), Err(Error::Singular { .. })),
            "coplanar"
        );
        assert!(matches!(
            dlt(&w[..5], &p[..5], 64, 64, 1e-3),
            Err(Error::InvalidParam { .. })
        ));
        assert!(matches!(
            dlt(&w, &p[..9], 64, 64, 1e-3),
            Err(Error::SizeMismatch { .. })
        ));
        let mut pn = p.clone();
        pn[3].x = f64::NAN;
        assert!(matches!(
            dlt(&w, &pn, 64, 64, 1e-3),
            Err(Error::NonFinite { .. })
        ));
        let same = vec![DVec3::ONE; 10];
        assert!(matches!(
            dlt(&same, &p, 64, 64, 1e-3),
            Err(Error::Singular { .. })
        ));
    }

    #[test]
    fn decomposition_round_trip_and_singular() {
        let k = Matrix3::new(900.0, 2.0, 300.0, 0.0, 950.0, 200.0, 0.0, 0.0, 1.0);
        let r = nalgebra::Rotation3::from_euler_angles(0.3, -0.2, 1.1).into_inner();
        let t = Vector3::new(0.1, -0.3, 4.0);
        let mut rt = Matrix3x4::zeros();
        rt.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
        rt.set_column(3, &t);
        let p = k * rt * -2.5; // arbitrary scale and sign
        let d = decompose_projection(&p).unwrap();
        assert!((d.k.x_axis.x - 900.0).abs() < 1e-9 && (d.k.y_axis.x - 2.0).abs() < 1e-9);
        assert!((d.camera_from_world.translation - DVec3::new(0.1, -0.3, 4.0)).length() < 1e-12);
        assert!(matches!(
            decompose_projection(&Matrix3x4::zeros()),
            Err(Error::Singular { .. })
        ));
    }
}
