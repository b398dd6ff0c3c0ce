//! Tracking the model's attributes through 2D point tracks (§5.4.1, Eq. 5.7–5.9 with the
//! point motion given, i.e. `Z = I`): a weak-perspective camera, coordinate descent that frees
//! one attribute at a time, per-frame attributes solved per frame, constant attributes
//! (identity) accumulated over all frames, several passes. From video, [`crate::track_video`]
//! produces the point systems with the KLT and solves them with the weighted forms here.

use std::time::Instant;

use nalgebra::{DMatrix, DVector, Matrix2x3, Vector2};

use crate::model::MultilinearModel;
use crate::{Context, Error, Result, ResultExt};

/// A weak-perspective (scaled orthographic) camera: `p = s R₂ f + t` (Eq. 5.7), `R₂` the first
/// two rows of a rotation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WeakPerspective {
    /// Scale `s` (pixels per model unit).
    pub scale: f64,
    /// The first two rows of the rotation `R`.
    pub rows: [[f64; 3]; 2],
    /// Image-space translation `t` (pixels).
    pub translation: [f64; 2],
}

impl WeakPerspective {
    /// Scale 1, no rotation, no translation.
    pub(crate) fn identity() -> Self {
        WeakPerspective {
            scale: 1.0,
            rows: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            translation: [0.0, 0.0],
        }
    }

    fn r2(&self) -> Matrix2x3<f64> {
        Matrix2x3::new(
            self.rows[0][0],
            self.rows[0][1],
            self.rows[0][2],
            self.rows[1][0],
            self.rows[1][1],
            self.rows[1][2],
        )
    }

    /// Projects a point.
    pub fn project(&self, f: [f64; 3]) -> [f64; 2] {
        let p = self.r2() * nalgebra::Vector3::from(f) * self.scale;
        [p[0] + self.translation[0], p[1] + self.translation[1]]
    }

    /// The least-squares affine camera for `points → pixels`, projected to the nearest
    /// weak-perspective one (orthonormal rows by SVD, scale the mean singular value).
    pub(crate) fn fit(points: &[[f64; 3]], pixels: &[[f64; 2]]) -> Result<Self> {
        Self::fit_weighted(points, pixels, None)
    }

    /// As [`WeakPerspective::fit`], each point's residual `r` weighted as `rᵀ Z r` with its
    /// symmetric 2 × 2 `Z = [zxx, zxy, zyy]` (Eq. 5.7: the KLT system of the point).
    pub(crate) fn fit_weighted(
        points: &[[f64; 3]],
        pixels: &[[f64; 2]],
        z: Option<&[[f64; 3]]>,
    ) -> Result<Self> {
        let n = points.len();
        // Unknowns [a₀ (3), a₁ (3), t (2)]; per point J = [[xᵀ 0 1 0], [0 xᵀ 0 1]].
        let mut ata = nalgebra::SMatrix::<f64, 8, 8>::zeros();
        let mut atb = nalgebra::SVector::<f64, 8>::zeros();
        for (k, (x, p)) in points.iter().zip(pixels).enumerate() {
            let w = z.map_or([1.0, 0.0, 1.0], |z| z[k]);
            let mut j = nalgebra::SMatrix::<f64, 2, 8>::zeros();
            for c in 0..3 {
                j[(0, c)] = x[c];
                j[(1, 3 + c)] = x[c];
            }
            j[(0, 6)] = 1.0;
            j[(1, 7)] = 1.0;
            let zm = nalgebra::Matrix2::new(w[0], w[1], w[1], w[2]);
            let jz = j.transpose() * zm;
            ata += jz * j;
            atb += jz * Vector2::new(p[0], p[1]);
        }
        let sol = ata
            .cholesky()
            .map(|c| c.solve(&atb))
            .ok_or(Error::InvalidParam {
                name: "tracked points",
                reason: "the tracked points are coplanar or degenerate".into(),
            })?;
        let m = Matrix2x3::new(sol[0], sol[1], sol[2], sol[3], sol[4], sol[5]);
        let svd = m.svd(true, true);
        let (Some(u), Some(vt)) = (svd.u, svd.v_t) else {
            return Err(Error::InvalidParam {
                name: "tracked points",
                reason: "camera SVD failed".into(),
            });
        };
        let r2 = u * vt;
        let scale = 0.5 * (svd.singular_values[0] + svd.singular_values[1]);
        // Translation by (weighted) least squares with the projected camera.
        let (mut zs, mut zr) = (nalgebra::Matrix2::zeros(), Vector2::zeros());
        for (k, (x, p)) in points.iter().zip(pixels).enumerate() {
            let w = z.map_or([1.0, 0.0, 1.0], |z| z[k]);
            let zm = nalgebra::Matrix2::new(w[0], w[1], w[1], w[2]);
            let r = Vector2::from(*p) - r2 * nalgebra::Vector3::from(*x) * scale;
            zs += zm;
            zr += zm * r;
        }
        let t = zs
            .try_inverse()
            .map_or_else(|| zr / n.max(1) as f64, |i| i * zr);
        Ok(WeakPerspective {
            scale,
            rows: [
                [r2[(0, 0)], r2[(0, 1)], r2[(0, 2)]],
                [r2[(1, 0)], r2[(1, 1)], r2[(1, 2)]],
            ],
            translation: [t[0], t[1]],
        })
    }
}

/// Parameters of [`track_points`].
#[derive(Clone, Debug, PartialEq)]
pub struct TrackParams {
    /// Passes through the whole sequence ("several passes", §5.4.1). Default 10.
    pub passes: usize,
    /// Coordinate-descent rounds per frame and pass (pose, then each per-frame attribute).
    /// Default 3.
    pub rounds: usize,
    /// Ridge weight pulling each attribute's weights towards the mean of the training rows,
    /// relative to the data term's scale. Default 1e-5 (ours: keeps the linear solves
    /// well posed when an attribute is barely visible; 1e-3 biases the result, 1.5 % vs
    /// 0.9 % vertex error in the validation).
    pub prior: f64,
}

impl Default for TrackParams {
    fn default() -> Self {
        TrackParams {
            passes: 10,
            rounds: 3,
            prior: 1e-5,
        }
    }
}

/// The result of [`track_points`].
#[derive(Clone, Debug, PartialEq)]
pub struct PointTrack {
    /// Per frame: the camera.
    pub cameras: Vec<WeakPerspective>,
    /// Per frame: one weight vector per attribute (constant attributes repeated).
    pub weights: Vec<Vec<DVector<f64>>>,
    /// Per frame: RMS reprojection error of the tracked points, pixels.
    pub reprojection_rms_px: Vec<f64>,
    /// Wall time, seconds.
    pub seconds: f64,
}

/// The mean of the training rows of each attribute (the starting weights).
pub fn mean_weights(model: &MultilinearModel) -> Result<Vec<DVector<f64>>> {
    (0..model.ranks().len())
        .map(|m| {
            let u = model.factor(m)?;
            Ok(u.row_mean().transpose())
        })
        .collect()
}

/// Rows of the basis `Mₘ` (Eq. 5.9) for the tracked vertices, projected by the camera:
/// `(2N × rₘ, 2N rhs)` for `s R₂ Mₘ,ᵢ wₘ = pᵢ − t`. With `z`, each point's two rows are
/// multiplied by `Lᵀ` (`Z = L Lᵀ`), so that the least squares minimise `Σ rᵀ Z r` (Eq. 5.8).
pub(crate) fn projected_system(
    model: &MultilinearModel,
    mode: usize,
    weights: &[DVector<f64>],
    cam: &WeakPerspective,
    tracked: &[usize],
    pixels: &[[f64; 2]],
    z: Option<&[[f64; 3]]>,
) -> Result<(DMatrix<f64>, DVector<f64>)> {
    let basis = model.linear_basis_rows(mode, weights, tracked)?;
    let r = basis.ncols();
    let r2 = cam.r2() * cam.scale;
    let mut a = DMatrix::zeros(2 * tracked.len(), r);
    let mut b = DVector::zeros(2 * tracked.len());
    for (k, p) in pixels.iter().enumerate().take(tracked.len()) {
        let rows = basis.rows(3 * k, 3);
        let proj = r2 * rows; // 2 × r
        let rhs = Vector2::new(p[0] - cam.translation[0], p[1] - cam.translation[1]);
        match z {
            None => {
                a.rows_mut(2 * k, 2).copy_from(&proj);
                b.rows_mut(2 * k, 2).copy_from(&rhs);
            }
            Some(z) => {
                let lt = sqrt_weight(z[k]);
                a.rows_mut(2 * k, 2).copy_from(&(lt * proj));
                b.rows_mut(2 * k, 2).copy_from(&(lt * rhs));
            }
        }
    }
    Ok((a, b))
}

/// `Lᵀ` of the Cholesky factor `Z = L Lᵀ` of a symmetric 2 × 2 `[zxx, zxy, zyy]` (a tiny
/// ridge keeps a rank-deficient `Z` — an edge — factorable).
fn sqrt_weight(z: [f64; 3]) -> nalgebra::Matrix2<f64> {
    let eps = 1e-12 * (z[0] + z[2]).abs().max(f64::MIN_POSITIVE);
    let l00 = (z[0] + eps).sqrt();
    let l10 = z[1] / l00;
    let l11 = (z[2] + eps - l10 * l10).max(0.0).sqrt();
    nalgebra::Matrix2::new(l00, l10, 0.0, l11)
}

pub(crate) fn solve_ridge(
    ata: &DMatrix<f64>,
    atb: &DVector<f64>,
    prior_w: &DVector<f64>,
    prior: f64,
) -> Result<DVector<f64>> {
    let lam = prior * (ata.trace() / ata.nrows().max(1) as f64).max(f64::MIN_POSITIVE);
    let mut m = ata.clone();
    for i in 0..m.nrows() {
        m[(i, i)] += lam;
    }
    let rhs = atb + prior_w * lam;
    m.cholesky()
        .map(|c| c.solve(&rhs))
        .ok_or(Error::InvalidParam {
            name: "tracked points",
            reason: "the attribute's linear system is singular".into(),
        })
}

/// The point equations of one frame: model vertices `points` seen at `pixels`, each
/// weighted by its KLT `Z` (or unweighted).
pub(crate) struct FrameSystem<'a> {
    pub(crate) points: &'a [usize],
    pub(crate) pixels: &'a [[f64; 2]],
    pub(crate) z: Option<&'a [[f64; 3]]>,
}

/// Coordinate descent on one frame (Eq. 5.8): the camera, then each per-frame attribute with
/// the others fixed, `rounds` times; returns the camera. `start`: the model points of
/// `sys.points` for the given `weights`, when the caller has them.
#[allow(
    clippy::too_many_arguments,
    reason = "the frame's system, its solve settings and start"
)]
pub(crate) fn fit_frame(
    model: &MultilinearModel,
    weights: &mut [DVector<f64>],
    constant: &[bool],
    sys: &FrameSystem<'_>,
    mean: &[DVector<f64>],
    prior: f64,
    rounds: usize,
    mut start: Option<Vec<[f64; 3]>>,
) -> Result<WeakPerspective> {
    let mut cam = WeakPerspective::identity();
    for _ in 0..rounds.max(1) {
        let pts = match start.take() {
            Some(pts) => pts,
            None => model.face_points(weights, sys.points)?,
        };
        cam = WeakPerspective::fit_weighted(&pts, sys.pixels, sys.z)?;
        for m in (0..weights.len()).filter(|&m| !constant[m]) {
            let (a, b) = projected_system(model, m, weights, &cam, sys.points, sys.pixels, sys.z)?;
            weights[m] = solve_ridge(&a.tr_mul(&a), &a.tr_mul(&b), &mean[m], prior)?;
        }
    }
    Ok(cam)
}

/// Each constant attribute from the equations of all frames together (§5.4.1), the result
/// put into every frame's weights; `systems[t]` are frame `t`'s equations (frames without
/// points add none).
pub(crate) fn fit_constants(
    model: &MultilinearModel,
    constant: &[bool],
    weights: &mut [Vec<DVector<f64>>],
    cameras: &[WeakPerspective],
    systems: &[FrameSystem<'_>],
    mean: &[DVector<f64>],
    prior: f64,
) -> Result<()> {
    for m in (0..constant.len()).filter(|&m| constant[m]) {
        let r = model.ranks()[m];
        let (mut ata, mut atb) = (DMatrix::zeros(r, r), DVector::zeros(r));
        for ((w, cam), sys) in weights.iter().zip(cameras).zip(systems) {
            if sys.points.is_empty() {
                continue;
            }
            let (a, b) = projected_system(model, m, w, cam, sys.points, sys.pixels, sys.z)?;
            ata += a.tr_mul(&a);
            atb += a.tr_mul(&b);
        }
        if ata.trace() > 0.0 {
            let w = solve_ridge(&ata, &atb, &mean[m], prior)?;
            for wt in weights.iter_mut() {
                wt[m] = w.clone();
            }
        }
    }
    Ok(())
}

/// RMS distance between the model's projection and the observed pixels, px.
pub(crate) fn reprojection_rms(
    model: &MultilinearModel,
    weights: &[DVector<f64>],
    cam: &WeakPerspective,
    sys: &FrameSystem<'_>,
) -> Result<f64> {
    let pts = model.face_points(weights, sys.points)?;
    Ok(points_reprojection_rms(&pts, cam, sys.pixels))
}

/// RMS distance between the projections of model points `pts` and the observed pixels, px.
pub(crate) fn points_reprojection_rms(
    pts: &[[f64; 3]],
    cam: &WeakPerspective,
    pixels: &[[f64; 2]],
) -> f64 {
    let se: f64 = pts
        .iter()
        .zip(pixels)
        .map(|(x, p)| {
            let q = cam.project(*x);
            (q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2)
        })
        .sum();
    (se / pts.len().max(1) as f64).sqrt()
}

/// Tracks the model through 2D point tracks: `frames[t][k]` is the pixel position of model
/// vertex `tracked[k]` in frame `t`. Attributes with `constant[m]` (identity) get one weight
/// vector for the whole sequence, solved from the equations of all frames together; the others
/// one per frame. Per pass and frame: camera (weak perspective, least squares), then each
/// per-frame attribute with the rest fixed (Eq. 5.8), `rounds` times; after each pass, each
/// constant attribute from all frames. Starts from the mean training weights.
///
/// # Errors
/// [`Error::Empty`] for no frame or fewer than 4 tracked vertices; [`Error::SizeMismatch`] for
/// a frame with another number of points (in [`Error::At`] with [`Context::Frame`]) or a
/// `constant` list of the wrong length; [`Error::IndexOutOfRange`] for a tracked vertex past the
/// model; [`Error::NonFinite`] for NaN pixels; [`Error::InvalidParam`] for a singular system.
///
/// # Example
///
/// A bilinear model of 2 expressions × 3 people; person 2's expression 1 seen by an
/// orthographic camera (2 pixels per unit, shifted by (100, 50) px) in three frames. With the
/// identity constant, the tracked weights reproduce the face.
///
/// ```
/// use multilinear_face::{track_points, FaceTensor, ModelParams, MultilinearModel, TrackParams};
/// use skin_core::math::DVec3;
///
/// let face = |e: f64, i: f64| -> Vec<DVec3> {
///     (0..20)
///         .map(|k| {
///             let k = k as f64;
///             let depth = e * (0.2 * k).cos() * (1.0 + 0.3 * i);
///             DVec3::new(k.cos() * (1.0 + 0.1 * i), k.sin() + 0.2 * e * (0.5 * k).sin(), depth)
///         })
///         .collect()
/// };
/// let faces: Vec<Vec<DVec3>> = (0..6).map(|f| face((f / 3) as f64, (f % 3) as f64)).collect();
/// let data = FaceTensor::from_faces(&[2, 3], &faces)?;
/// let (model, _) = MultilinearModel::fit(&data, &ModelParams::new(&[2, 3]))?;
///
/// let tracked: Vec<usize> = (0..20).collect();
/// let pixels: Vec<[f64; 2]> =
///     faces[5].iter().map(|p| [100.0 + 2.0 * p.x, 50.0 + 2.0 * p.y]).collect();
/// let frames = vec![pixels; 3];
/// let track = track_points(&model, &tracked, &frames, &[false, true], &TrackParams::default())?;
/// assert_eq!(track.cameras.len(), 3);
/// assert!(track.reprojection_rms_px.iter().all(|&r| r < 0.05));
/// # Ok::<(), multilinear_face::Error>(())
/// ```
pub fn track_points(
    model: &MultilinearModel,
    tracked: &[usize],
    frames: &[Vec<[f64; 2]>],
    constant: &[bool],
    params: &TrackParams,
) -> Result<PointTrack> {
    let t0 = Instant::now();
    if frames.is_empty() {
        return Err(Error::Empty { what: "frames" });
    }
    if tracked.len() < 4 {
        return Err(Error::Empty {
            what: "tracked vertices (at least 4)",
        });
    }
    for &v in tracked {
        skin_core::check::index("tracked vertex", v, model.vertex_count())?;
    }
    let modes = model.ranks().len();
    skin_core::check::same_size("constant flags (one per attribute)", modes, constant.len())?;
    skin_core::check::non_negative("prior", params.prior)?;
    for (t, f) in frames.iter().enumerate() {
        skin_core::check::same_size("points in a frame", tracked.len(), f.len())
            .at(Context::Frame(t))?;
        skin_core::check::all_finite("pixels", f.iter().flatten()).at(Context::Frame(t))?;
    }
    // Only the tracked vertices enter the solves: restrict the model to them once.
    let model = &model.restrict(tracked)?;
    let tracked: &[usize] = &(0..tracked.len()).collect::<Vec<_>>();
    let mean = mean_weights(model)?;
    let mut weights: Vec<Vec<DVector<f64>>> = vec![mean.clone(); frames.len()];
    let mut cameras = Vec::with_capacity(frames.len());
    for (t, px) in frames.iter().enumerate() {
        cameras.push(
            WeakPerspective::fit(&model.face_points(&weights[t], tracked)?, px)
                .at(Context::Frame(t))?,
        );
    }
    for _ in 0..params.passes.max(1) {
        for t in 0..frames.len() {
            if t > 0 {
                // Per-frame attributes start from the previous frame's.
                for m in 0..modes {
                    if !constant[m] {
                        weights[t][m] = weights[t - 1][m].clone();
                    }
                }
            }
            let sys = FrameSystem {
                points: tracked,
                pixels: &frames[t],
                z: None,
            };
            cameras[t] = fit_frame(
                model,
                &mut weights[t],
                constant,
                &sys,
                &mean,
                params.prior,
                params.rounds,
                None,
            )
            .at(Context::Frame(t))?;
        }
        let systems: Vec<FrameSystem<'_>> = frames
            .iter()
            .map(|f| FrameSystem {
                points: tracked,
                pixels: f,
                z: None,
            })
            .collect();
        fit_constants(
            model,
            constant,
            &mut weights,
            &cameras,
            &systems,
            &mean,
            params.prior,
        )?;
    }
    let mut reprojection_rms_px = Vec::with_capacity(frames.len());
    for t in 0..frames.len() {
        let sys = FrameSystem {
            points: tracked,
            pixels: &frames[t],
            z: None,
        };
        reprojection_rms_px.push(reprojection_rms(model, &weights[t], &cameras[t], &sys)?);
    }
    Ok(PointTrack {
        cameras,
        weights,
        reprojection_rms_px,
        seconds: t0.elapsed().as_secs_f64(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weak_perspective_fit_recovers_a_camera() {
        let pts: Vec<[f64; 3]> = (0..10)
            .map(|i| {
                let i = i as f64;
                [i.sin(), (1.3 * i).cos(), 0.2 * i]
            })
            .collect();
        let (c, s) = (0.3f64.cos(), 0.3f64.sin());
        let cam = WeakPerspective {
            scale: 40.0,
            rows: [[c, 0.0, s], [0.0, 1.0, 0.0]],
            translation: [320.0, 240.0],
        };
        let px: Vec<[f64; 2]> = pts.iter().map(|p| cam.project(*p)).collect();
        let fit = WeakPerspective::fit(&pts, &px).unwrap();
        assert!((fit.scale - 40.0).abs() < 1e-9);
        for (p, q) in pts.iter().zip(&px) {
            let r = fit.project(*p);
            assert!((r[0] - q[0]).abs() < 1e-9 && (r[1] - q[1]).abs() < 1e-9);
        }
    }
}
