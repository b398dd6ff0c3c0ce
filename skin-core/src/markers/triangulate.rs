//! Multi-view forward intersection (Fua et al. §2.3): a linear least-squares intersection of
//! the viewing rays, refined by Gauss–Newton on the image reprojection error.

use crate::camera::Camera;
use crate::check::all_finite;
use crate::math::{DMat3, DVec2, DVec3};
use crate::{Context, Error, Result, ResultExt};

/// Gauss–Newton iterations of [`triangulate`] at most.
const MAX_TRIANGULATION_ITERATIONS: usize = 20;
/// Gauss–Newton stops when a step is shorter than this, m.
const STEP_TOLERANCE_M: f64 = 1e-12;
/// Smallest accepted `det(A) / (tr(A)/3)³` of the linear system: below it the rays are
/// (nearly) parallel and the intersection is undetermined.
const MIN_RAY_CONDITION: f64 = 1e-10;

/// One marker seen by one camera.
#[derive(Debug, Clone, Copy)]
pub struct MarkerView<'a> {
    /// The camera.
    pub camera: &'a Camera,
    /// The observed (distorted) pixel, px.
    pub pixel: DVec2,
}

/// A triangulated marker.
#[derive(Debug, Clone, PartialEq)]
pub struct Triangulation {
    /// The world point, m.
    pub point: DVec3,
    /// Reprojection residual in each view, px, in the order of the views given.
    pub residuals_px: Vec<f64>,
    /// Root mean square of `residuals_px`, px.
    pub rms_px: f64,
    /// Gauss–Newton iterations performed.
    pub iterations: usize,
}

/// Linear intersection: the point minimising the summed squared distance to the rays,
/// `Σ (I − dᵢdᵢᵀ)(X − cᵢ) = 0` (the homogeneous DLT in normalised camera coordinates, with
/// distortion removed first).
fn linear_intersection(views: &[MarkerView<'_>]) -> Result<DVec3> {
    let mut a = DMat3::ZERO;
    let mut b = DVec3::ZERO;
    for (i, v) in views.iter().enumerate() {
        let ray = v.camera.ray(v.pixel).at(Context::Camera(i))?;
        let d = ray.direction;
        let m = DMat3::IDENTITY - DMat3::from_cols(d * d.x, d * d.y, d * d.z);
        a += m;
        b += m * ray.origin;
    }
    let scale = (a.x_axis.x + a.y_axis.y + a.z_axis.z) / 3.0;
    let det = a.determinant();
    if !(det.is_finite() && det > MIN_RAY_CONDITION * scale.powi(3)) {
        return Err(Error::Singular {
            what: format!(
                "the {} viewing rays of the marker are (nearly) parallel",
                views.len()
            ),
        });
    }
    Ok(a.inverse() * b)
}

fn residuals(views: &[MarkerView<'_>], p: DVec3) -> Result<Vec<DVec2>> {
    views
        .iter()
        .enumerate()
        .map(|(i, v)| Ok(v.camera.project(p).at(Context::Camera(i))? - v.pixel))
        .collect()
}

/// Forward intersection of one marker seen in two or more views: the linear ray intersection,
/// then Gauss–Newton on `Σ‖project(X) − pixel‖²`, keeping only steps that reduce the error.
///
/// # Errors
/// [`Error::InvalidParam`] for fewer than two views; [`Error::NonFinite`] for a non-finite
/// pixel; [`Error::Singular`] for parallel rays; [`Error::At`] with the view's index when the
/// point falls behind one of the cameras.
pub fn triangulate(views: &[MarkerView<'_>]) -> Result<Triangulation> {
    if views.len() < 2 {
        return Err(Error::InvalidParam {
            name: "views",
            reason: format!(
                "forward intersection needs at least two views of the marker, got {}",
                views.len()
            ),
        });
    }
    for (i, v) in views.iter().enumerate() {
        all_finite("marker pixel", [v.pixel.x, v.pixel.y].iter()).at(Context::Camera(i))?;
    }
    let mut p = linear_intersection(views)?;
    let mut r = residuals(views, p)?;
    let mut cost: f64 = r.iter().map(|e| e.length_squared()).sum();
    let mut iterations = 0;
    for _ in 0..MAX_TRIANGULATION_ITERATIONS {
        iterations += 1;
        let mut jtj = DMat3::ZERO;
        let mut jtr = DVec3::ZERO;
        for (i, v) in views.iter().enumerate() {
            let j = v
                .camera
                .project_with_jacobian(p)
                .at(Context::Camera(i))?
                .d_pixel_d_world;
            for (row, res) in j.iter().zip([r[i].x, r[i].y]) {
                jtj += DMat3::from_cols(*row * row.x, *row * row.y, *row * row.z);
                jtr += *row * res;
            }
        }
        if jtj.determinant().abs() <= f64::EPSILON {
            break;
        }
        let step = -(jtj.inverse() * jtr);
        let candidate = p + step;
        let Ok(rc) = residuals(views, candidate) else {
            break;
        };
        let cc: f64 = rc.iter().map(|e| e.length_squared()).sum();
        if cc > cost {
            break;
        }
        p = candidate;
        r = rc;
        cost = cc;
        if step.length() < STEP_TOLERANCE_M {
            break;
        }
    }
    let residuals_px: Vec<f64> = r.iter().map(|e| e.length()).collect();
    let rms_px = (cost / views.len() as f64).sqrt();
    Ok(Triangulation {
        point: p,
        residuals_px,
        rms_px,
        iterations,
    })
}

/// A marker reconstructed from detections in several cameras by [`reconstruct_markers`].
#[derive(Debug, Clone, PartialEq)]
pub struct ReconstructedMarker {
    /// The forward intersection of all its views.
    pub triangulation: Triangulation,
    /// `(camera, detection)` indices of its views, in camera order.
    pub views: Vec<(usize, usize)>,
}

/// Finds which detections of different cameras are the same marker and intersects them: every
/// pair of detections of two cameras whose two-view intersection reprojects within
/// `max_residual_px` is a hypothesis, completed with the nearest unused detection within
/// `max_residual_px` of its projection in every other camera and re-intersected; hypotheses
/// with at least `min_views` views are accepted greedily, most views first, then smallest RMS,
/// each detection used at most once. With three or more cameras, `min_views = 3` removes the
/// ambiguity of two-view (epipolar) matches.
///
/// # Errors
/// [`Error::SizeMismatch`] unless there is one detection list per camera;
/// [`Error::InvalidParam`] for `min_views < 2` or a non-positive tolerance;
/// [`Error::NonFinite`] (in [`Error::At`] naming the camera) for a non-finite detection.
pub fn reconstruct_markers(
    cameras: &[Camera],
    detections: &[Vec<DVec2>],
    max_residual_px: f64,
    min_views: usize,
) -> Result<Vec<ReconstructedMarker>> {
    crate::check::same_size(
        "detection lists (one per camera)",
        cameras.len(),
        detections.len(),
    )?;
    crate::check::positive("max_residual_px", max_residual_px)?;
    if min_views < 2 {
        return Err(Error::InvalidParam {
            name: "min_views",
            reason: format!("forward intersection needs at least two views, got {min_views}"),
        });
    }
    for (c, d) in detections.iter().enumerate() {
        all_finite("marker detection", d.iter().flat_map(|p| [&p.x, &p.y]))
            .at(Context::Camera(c))?;
    }
    let solve = |views: &[(usize, usize)]| {
        let mv: Vec<MarkerView<'_>> = views
            .iter()
            .map(|&(c, k)| MarkerView {
                camera: &cameras[c],
                pixel: detections[c][k],
            })
            .collect();
        triangulate(&mv)
    };
    let mut hypotheses: Vec<ReconstructedMarker> = Vec::new();
    for a in 0..cameras.len() {
        for b in a + 1..cameras.len() {
            for ka in 0..detections[a].len() {
                for kb in 0..detections[b].len() {
                    let pair = [(a, ka), (b, kb)];
                    let Ok(t) = solve(&pair) else { continue };
                    if t.residuals_px.iter().any(|r| *r > max_residual_px) {
                        continue;
                    }
                    let mut views = pair.to_vec();
                    for (c, cam) in cameras.iter().enumerate() {
                        if c == a || c == b {
                            continue;
                        }
                        let Ok(px) = cam.project(t.point) else {
                            continue;
                        };
                        let best = detections[c]
                            .iter()
                            .enumerate()
                            .map(|(k, d)| (k, (*d - px).length()))
                            .filter(|(_, r)| *r <= max_residual_px)
                            .min_by(|x, y| x.1.total_cmp(&y.1));
                        if let Some((k, _)) = best {
                            views.push((c, k));
                        }
                    }
                    if views.len() < min_views {
                        continue;
                    }
                    views.sort_unstable();
                    let Ok(t) = solve(&views) else { continue };
                    if t.residuals_px.iter().all(|r| *r <= max_residual_px) {
                        hypotheses.push(ReconstructedMarker {
                            triangulation: t,
                            views,
                        });
                    }
                }
            }
        }
    }
    hypotheses.sort_by(|x, y| {
        y.views
            .len()
            .cmp(&x.views.len())
            .then(x.triangulation.rms_px.total_cmp(&y.triangulation.rms_px))
    });
    let mut used: Vec<Vec<bool>> = detections.iter().map(|d| vec![false; d.len()]).collect();
    let mut accepted = Vec::new();
    for h in hypotheses {
        if h.views.iter().any(|&(c, k)| used[c][k]) {
            continue;
        }
        for &(c, k) in &h.views {
            used[c][k] = true;
        }
        accepted.push(h);
    }
    Ok(accepted)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Intrinsics, RadialDistortion, Rig};
    use crate::random::SplitMix64;

    fn rig() -> Rig {
        let k = Intrinsics::from_horizontal_fov(0.9, 640, 480).unwrap();
        Rig::ring(4, 3.0, 1.5, DVec3::new(0.0, 1.0, 0.0), DVec3::Y, k).unwrap()
    }

    #[test]
    fn recovers_a_point_from_noisy_views_better_than_the_linear_step() {
        let mut rig = rig();
        for c in &mut rig.cameras {
            c.distortion = RadialDistortion {
                centre: c.intrinsics.principal_point(),
                k1: -0.08,
            };
        }
        let rng = SplitMix64::new(7);
        let mut draw = 0u64;
        let mut normal = || {
            draw += 1;
            rng.normal_at(draw)
        };
        let (mut gn_err, mut lin_err) = (0.0, 0.0);
        for k in 0..50 {
            let truth = DVec3::new(
                0.3 * (k as f64 * 0.7).sin(),
                1.0 + 0.4 * (k as f64 * 1.3).cos(),
                0.2 * (k as f64 * 0.4).sin(),
            );
            let views: Vec<MarkerView<'_>> = rig
                .cameras
                .iter()
                .map(|c| MarkerView {
                    camera: c,
                    pixel: c.project(truth).unwrap() + DVec2::new(normal(), normal()) * 0.3,
                })
                .collect();
            let t = triangulate(&views).unwrap();
            assert_eq!(t.residuals_px.len(), 4);
            assert!(t.rms_px < 1.0, "rms {}", t.rms_px);
            gn_err += (t.point - truth).length_squared();
            lin_err += (linear_intersection(&views).unwrap() - truth).length_squared();
        }
        let (gn, lin) = ((gn_err / 50.0).sqrt(), (lin_err / 50.0).sqrt());
        assert!(gn < 2e-3, "GN rms error {gn} m");
        assert!(gn <= lin, "GN {gn} m worse than the linear step {lin} m");
    }

    #[test]
    fn reconstructs_unlabelled_detections_of_several_markers() {
        let rig = rig();
        let truth: Vec<DVec3> = (0..15)
            .map(|k| {
                let k = k as f64;
                DVec3::new(
                    0.3 * (k * 0.7).sin(),
                    1.0 + 0.5 * (k * 1.3).cos(),
                    0.3 * (k * 0.4).cos(),
                )
            })
            .collect();
        let rng = SplitMix64::new(3);
        let mut n = 0u64;
        let detections: Vec<Vec<DVec2>> = rig
            .cameras
            .iter()
            .map(|c| {
                // Reverse order per camera so indices do not match across cameras.
                truth
                    .iter()
                    .rev()
                    .map(|p| {
                        n += 2;
                        c.project(*p).unwrap()
                            + DVec2::new(rng.normal_at(n), rng.normal_at(n + 1)) * 0.2
                    })
                    .collect()
            })
            .collect();
        let found = reconstruct_markers(&rig.cameras, &detections, 1.5, 3).unwrap();
        assert_eq!(found.len(), truth.len());
        for m in &found {
            let nearest = truth
                .iter()
                .map(|p| p.distance(m.triangulation.point))
                .fold(f64::INFINITY, f64::min);
            assert!(nearest < 3e-3, "{nearest} m");
            assert_eq!(m.views.len(), 4);
        }
        assert!(reconstruct_markers(&rig.cameras, &detections[..2], 1.5, 3).is_err());
        assert!(reconstruct_markers(&rig.cameras, &detections, 1.5, 1).is_err());
    }

    #[test]
    fn bad_input_is_an_error() {
        let rig = rig();
        let c = &rig.cameras[0];
        let one = [MarkerView {
            camera: c,
            pixel: DVec2::new(320.0, 240.0),
        }];
        assert!(matches!(triangulate(&one), Err(Error::InvalidParam { .. })));
        assert!(matches!(triangulate(&[]), Err(Error::InvalidParam { .. })));
        let nan = [
            one[0],
            MarkerView {
                camera: &rig.cameras[1],
                pixel: DVec2::new(f64::NAN, 1.0),
            },
        ];
        assert!(matches!(
            triangulate(&nan).map_err(|e| e.root().to_string()),
            Err(s) if s.contains("non-finite")
        ));
        // The same camera twice: parallel rays.
        let twice = [one[0], one[0]];
        assert!(matches!(triangulate(&twice), Err(Error::Singular { .. })));
    }
}
