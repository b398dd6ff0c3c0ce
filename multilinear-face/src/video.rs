//! Tracking the model's attributes from video (§5.4.1–5.4.2): the symmetric KLT system of
//! every tracked vertex (Eq. 5.6) tied to the model through the weak-perspective camera
//! (Eq. 5.7), coordinate descent over the attributes (Eq. 5.8–5.9), per-frame attributes solved
//! per frame pair, constant ones (identity) accumulated over all pairs, multi-scale (the KLT
//! pyramid) and several passes; initialised from a handful of 2D feature points in the first
//! frame.
//!
//! **How Eq. 5.7 is solved.** For a frame pair `(s, t)` each tracked vertex visible in both is
//! projected by the current model of frame `s` (its template position `q`) and of frame `t`
//! (the current guess `p₀`; in the first pass the previous frame's, as the thesis says). The
//! symmetric KLT (module `klt`) iterates Eq. 5.6 to its fixed point `p̂ = p₀ + Z⁻¹e` and keeps
//! the point's `Z`. The model is then fitted to all points at once by minimising
//! `Σᵢ (pᵢ − p̂ᵢ)ᵀ Zᵢ (pᵢ − p̂ᵢ)` with `pᵢ = s R fᵢ + t` — the Gauss–Newton form of Eq. 5.7
//! (`Z d = e` has the same per-point solution; weighting by `Z` rather than `Z²` is the
//! linearised photometric error itself, so a point on an edge constrains the model only across
//! the edge, the aperture problem handled by the model). Coordinate descent: the camera
//! (weighted affine least squares projected to weak perspective), then each per-frame
//! attribute with the others fixed (Eq. 5.8 with the basis of Eq. 5.9), `rounds` times. After a
//! pass, each constant attribute from the weighted systems of all pairs together.
//!
//! **Passes.** Pass 1 runs forward, each frame starting from the previous one's fit. Later
//! passes re-track every pair from the refined fits (template and guess both from the model),
//! and also the pair `(1, 0)`: the first frame, set by the feature points alone in pass 1, is
//! tracked back from the second ("tracking the first few frames back and forth until the model
//! snaps", §5.4.2).
//!
//! **Visibility.** A tracked vertex is used in a pair when its model normal (one incident
//! triangle's) faces the camera by more than [`VideoTrackParams::min_facing`] in both frames;
//! points occluded in spite of that (behind the nose) fail the KLT checks.
//!
//! **Lost face.** When fewer than [`VideoTrackParams::min_tracked_fraction`] of the visible
//! tracked vertices pass the KLT checks (in the frame, textured window, forward–backward
//! consistent, residual below [`VideoTrackParams::residual_ratio`] of the window's contrast)
//! the face is reported lost: [`Error::FaceLost`] inside [`Error::At`] with the frame.

use std::time::Instant;

use image::RgbImage;
use nalgebra::DVector;
use rayon::prelude::*;

use crate::klt::{track as klt_track, Klt, Pyramid, Scratch};
use crate::model::MultilinearModel;
use crate::tracking::{
    fit_constants, fit_frame, mean_weights, points_reprojection_rms, track_points, FrameSystem,
    TrackParams, WeakPerspective,
};
use crate::{Context, Error, Result, ResultExt};

/// A handful of 2D feature points in the first frame (§5.4.2: eye corners, nose tip, mouth
/// corners — user-marked or detected): model vertex `vertices[k]` is seen at `pixels[k]`.
#[derive(Clone, Debug, PartialEq)]
pub struct FeaturePoints {
    /// Model vertex of each feature.
    pub vertices: Vec<usize>,
    /// Its pixel position in frame 0.
    pub pixels: Vec<[f64; 2]>,
}

/// Parameters of [`track_video`].
#[derive(Clone, Debug, PartialEq)]
pub struct VideoTrackParams {
    /// Pyramid levels of the KLT ("several levels of multi-scale", §5.4.1). Default 3.
    pub levels: usize,
    /// KLT window radius, px (the window is `2r + 1` square). Default 4 (ours, 9 × 9;
    /// Birchfield's KLT uses 7 × 7; on the validation video 7 × 7, 9 × 9, 11 × 11 and 15 × 15
    /// give 1.46–1.51 % vertex error, the smaller the faster).
    pub window_radius: usize,
    /// KLT iterations per level (at most). Default 10.
    pub klt_iterations: usize,
    /// KLT stops when the update is below this, px. Default 0.02.
    pub epsilon_px: f64,
    /// Forward–backward check: the way back must end within this of the start, px. Default 1.
    pub fb_max_px: f64,
    /// A point fails when its final residual exceeds this fraction of its template window's
    /// contrast (RMS of the mean-removed intensity). Default 0.5.
    pub residual_ratio: f64,
    /// Passes through the whole video ("several passes"). Default 3.
    pub passes: usize,
    /// Coordinate-descent rounds per frame pair (camera, then each per-frame attribute).
    /// Default 2.
    pub rounds: usize,
    /// Ridge towards the mean training weights, relative to the data term. Default 1e-5 (as
    /// [`TrackParams::prior`]).
    pub prior: f64,
    /// Ridge of the initialisation from the few feature points. Default 1e-5 (ours: 1e-3
    /// and 1e-2 bias the first frame's shape, and every later frame inherits its
    /// correspondence — 2.6 and 4 px instead of 1.5 px with 12 exact features).
    pub init_prior: f64,
    /// A vertex is used when `n · view ≥` this (its normal's cosine towards the camera).
    /// Default 0.2.
    pub min_facing: f64,
    /// The face is lost when fewer than this fraction of the visible tracked vertices pass
    /// the KLT checks. Default 0.3.
    pub min_tracked_fraction: f64,
}

impl Default for VideoTrackParams {
    fn default() -> Self {
        VideoTrackParams {
            levels: 3,
            window_radius: 4,
            klt_iterations: 10,
            epsilon_px: 0.02,
            fb_max_px: 1.0,
            residual_ratio: 0.5,
            passes: 3,
            rounds: 2,
            prior: 1e-5,
            init_prior: 1e-5,
            min_facing: 0.2,
            min_tracked_fraction: 0.3,
        }
    }
}

impl VideoTrackParams {
    /// With `passes` passes.
    pub fn with_passes(mut self, passes: usize) -> Self {
        self.passes = passes;
        self
    }
}

/// The result of [`track_video`].
#[derive(Clone, Debug, PartialEq)]
pub struct VideoTrack {
    /// Per frame: the camera.
    pub cameras: Vec<WeakPerspective>,
    /// Per frame: one weight vector per attribute (constant attributes repeated).
    pub weights: Vec<Vec<DVector<f64>>>,
    /// Per frame (last pass): the fraction of visible tracked vertices that passed the KLT
    /// checks (frame 0 with one pass: 1, set by the feature points).
    pub tracked_fraction: Vec<f64>,
    /// Per frame (last pass): RMS distance between the model's projection and the KLT
    /// positions of the points that passed, px.
    pub reprojection_rms_px: Vec<f64>,
    /// Per frame (last pass): median KLT residual over the window contrast.
    pub klt_residual_ratio: Vec<f64>,
    /// Wall time, seconds (pyramids, KLT and model solves, all passes).
    pub seconds: f64,
    /// Of which in the KLT (pyramids and point tracking), seconds.
    pub klt_seconds: f64,
}

/// The KLT observations of one frame (local indices into the restricted model).
#[derive(Clone, Debug, Default)]
struct Obs {
    points: Vec<usize>,
    pixels: Vec<[f64; 2]>,
    z: Vec<[f64; 3]>,
}

/// Unit normal of each tracked vertex from one incident triangle, rotated by the camera; its
/// component towards the viewer (image y down, so the viewer looks along `−(r₀ × r₁)`).
fn facing(pts: &[[f64; 3]], tri_local: &[[usize; 3]], cam: &WeakPerspective) -> Vec<f64> {
    let toward = {
        let (a, b) = (cam.rows[0], cam.rows[1]);
        // r₀ × r₁ points away from the viewer for the image convention of the projection.
        [
            -(a[1] * b[2] - a[2] * b[1]),
            -(a[2] * b[0] - a[0] * b[2]),
            -(a[0] * b[1] - a[1] * b[0]),
        ]
    };
    tri_local
        .iter()
        .map(|t| {
            let (a, b, c) = (pts[t[0]], pts[t[1]], pts[t[2]]);
            let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
            let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
            let n = [
                u[1] * v[2] - u[2] * v[1],
                u[2] * v[0] - u[0] * v[2],
                u[0] * v[1] - u[1] * v[0],
            ];
            let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            if len > 0.0 {
                (n[0] * toward[0] + n[1] * toward[1] + n[2] * toward[2]) / len
            } else {
                -1.0
            }
        })
        .collect()
}

/// Tracks the model through `frames` (§5.4.1): `tracked` are the model vertices followed by
/// the KLT (the thesis: about a thousand), `triangles` the model's mesh (for the vertices'
/// normals), `features` a handful of points in frame 0 for the initialisation (§5.4.2),
/// `constant[m]` marks attributes constant over the video (identity). See the module docs
/// for the method.
///
/// # Errors
/// [`Error::Empty`] for no frame, fewer than 4 tracked vertices or features;
/// [`Error::SizeMismatch`] for a frame of another size than the first (in [`Error::At`] with
/// [`Context::Frame`]), a `constant` list of the wrong length or features with as many pixels
/// as vertices; [`Error::IndexOutOfRange`] for a vertex past the model or a triangle corner
/// past it; [`Error::InvalidParam`] for a frame too small for the pyramid or invalid
/// parameters; [`Error::NonFinite`] for NaN feature pixels; [`Error::FaceLost`] (in
/// [`Error::At`] with the frame) when the face is lost.
pub fn track_video(
    model: &MultilinearModel,
    triangles: &[[u32; 3]],
    tracked: &[usize],
    frames: &[RgbImage],
    features: &FeaturePoints,
    constant: &[bool],
    params: &VideoTrackParams,
) -> Result<VideoTrack> {
    let t0 = Instant::now();
    let Some(first) = frames.first() else {
        return Err(Error::Empty { what: "frames" });
    };
    if tracked.len() < 4 {
        return Err(Error::Empty {
            what: "tracked vertices (at least 4)",
        });
    }
    let nv = model.vertex_count();
    for &v in tracked.iter().chain(&features.vertices) {
        skin_core::check::index("tracked or feature vertex", v, nv)?;
    }
    for t in triangles {
        for &c in t {
            skin_core::check::index("triangle corner", c as usize, nv)?;
        }
    }
    let modes = model.ranks().len();
    skin_core::check::same_size("constant flags (one per attribute)", modes, constant.len())?;
    skin_core::check::same_size(
        "feature pixels (one per feature vertex)",
        features.vertices.len(),
        features.pixels.len(),
    )?;
    skin_core::check::all_finite("feature pixels", features.pixels.iter().flatten())?;
    skin_core::check::nonzero("levels", params.levels)?;
    skin_core::check::nonzero("window_radius", params.window_radius)?;
    skin_core::check::positive("epsilon_px", params.epsilon_px)?;
    skin_core::check::positive("fb_max_px", params.fb_max_px)?;
    skin_core::check::positive("residual_ratio", params.residual_ratio)?;
    skin_core::check::non_negative("prior", params.prior)?;
    skin_core::check::non_negative("init_prior", params.init_prior)?;
    skin_core::check::in_range("min_facing", params.min_facing, -1.0..=1.0)?;
    skin_core::check::in_range(
        "min_tracked_fraction",
        params.min_tracked_fraction,
        0.0..=1.0,
    )?;
    let (w, h) = first.dimensions();
    let need = (2 * params.window_radius + 3) << (params.levels - 1);
    if (w.min(h) as usize) < need {
        return Err(Error::InvalidParam {
            name: "frames",
            reason: format!(
                "{w} × {h} is too small for {} pyramid levels of {}-px windows (needs {need} px)",
                params.levels,
                2 * params.window_radius + 1
            ),
        });
    }
    for (t, f) in frames.iter().enumerate() {
        skin_core::check::same_size("frame width, px", w as usize, f.width() as usize)
            .at(Context::Frame(t))?;
        skin_core::check::same_size("frame height, px", h as usize, f.height() as usize)
            .at(Context::Frame(t))?;
    }

    // Restrict the model to the tracked vertices, one incident triangle's corners each (for
    // the normal) and the features.
    let mut incident: Vec<Option<[u32; 3]>> = vec![None; nv];
    for t in triangles {
        for &c in t {
            incident[c as usize].get_or_insert(*t);
        }
    }
    let mut local = vec![usize::MAX; nv];
    let mut ext: Vec<usize> = Vec::new();
    let mut add = |v: usize, ext: &mut Vec<usize>| {
        if local[v] == usize::MAX {
            local[v] = ext.len();
            ext.push(v);
        }
        local[v]
    };
    let track_local: Vec<usize> = tracked.iter().map(|&v| add(v, &mut ext)).collect();
    let mut tri_local = Vec::with_capacity(tracked.len());
    for &v in tracked {
        let Some(t) = incident[v] else {
            return Err(Error::InvalidParam {
                name: "tracked vertex",
                reason: format!("vertex {v} is in no triangle (no normal)"),
            });
        };
        tri_local.push(t.map(|c| add(c as usize, &mut ext)));
    }
    let feature_local: Vec<usize> = features
        .vertices
        .iter()
        .map(|&v| add(v, &mut ext))
        .collect();
    let model = &model.restrict(&ext)?;
    let all: Vec<usize> = (0..ext.len()).collect();
    let mean = mean_weights(model)?;
    // The tracked vertices come first in `ext` (local indices `0..n_tracked`): the solves,
    // which see only them, contract a model of those rows alone.
    let n_tracked = track_local.iter().max().map_or(0, |&v| v + 1);
    let solve_model = &model.restrict(&all[..n_tracked])?;

    let klt_fine = Klt {
        levels: 1,
        radius: params.window_radius,
        iterations: params.klt_iterations,
        epsilon_px: params.epsilon_px,
        fb_max_px: params.fb_max_px,
        residual_ratio: params.residual_ratio,
    };
    let tk = Instant::now();
    let pyramids: Vec<Pyramid> = frames
        .iter()
        .map(|f| Pyramid::new(f, params.levels))
        .collect();
    let mut klt_seconds = tk.elapsed().as_secs_f64();

    // Initialisation (§5.4.2): all attributes and the camera from the feature points.
    let init = track_points(
        model,
        &feature_local,
        std::slice::from_ref(&features.pixels),
        &vec![false; modes],
        &TrackParams {
            passes: 10,
            rounds: 3,
            prior: params.init_prior,
        },
    )
    .at(Context::Frame(0))?;
    let n = frames.len();
    let mut cameras = vec![init.cameras[0]; n];
    let mut weights = vec![init.weights[0].clone(); n];
    let mut obs: Vec<Obs> = vec![Obs::default(); n];
    let mut tracked_fraction = vec![1.0; n];
    let mut reprojection_rms_px = vec![0.0; n];
    let mut klt_residual_ratio = vec![0.0; n];
    // Each frame's model points (all of `ext`) for its current weights, once computed.
    let mut shapes: Vec<Option<Vec<[f64; 3]>>> = vec![None; n];

    for pass in 0..params.passes.max(1) {
        let pairs: Vec<(usize, usize)> = (pass > 0 && n > 1)
            .then_some((1, 0))
            .into_iter()
            .chain((1..n).map(|t| (t - 1, t)))
            .collect();
        for (s, t) in pairs {
            if pass == 0 {
                weights[t] = weights[s].clone();
                cameras[t] = cameras[s];
                shapes[t] = None;
            }
            let ps = match shapes[s].take() {
                Some(ps) => ps,
                None => model.face_points(&weights[s], &all)?,
            };
            // Pass 1 starts frame t from frame s's weights: the same shape.
            let pt = match shapes[t].take() {
                Some(pt) => pt,
                None if weights[t] == weights[s] => ps.clone(),
                None => model.face_points(&weights[t], &all)?,
            };
            let (fs, ft) = (
                facing(&ps, &tri_local, &cameras[s]),
                facing(&pt, &tri_local, &cameras[t]),
            );
            let visible: Vec<usize> = (0..tracked.len())
                .filter(|&k| fs[k] >= params.min_facing && ft[k] >= params.min_facing)
                .collect();
            // Pass 1 starts from the previous frame: the whole pyramid. Later passes start
            // from the refined fit, within a pixel: the finest level only.
            let klt = if pass == 0 {
                Klt {
                    levels: params.levels,
                    ..klt_fine
                }
            } else {
                klt_fine
            };
            let tk = Instant::now();
            let results: Vec<_> = visible
                .par_iter()
                .map_init(Scratch::default, |scratch, &k| {
                    let v = track_local[k];
                    let q = cameras[s].project(ps[v]);
                    let p0 = cameras[t].project(pt[v]);
                    (
                        v,
                        klt_track(&pyramids[s], &pyramids[t], q, p0, &klt, scratch),
                    )
                })
                .collect();
            klt_seconds += tk.elapsed().as_secs_f64();
            let good: Vec<_> = results.iter().filter(|(_, r)| r.ok).collect();
            let fraction = good.len() as f64 / visible.len().max(1) as f64;
            if visible.is_empty() || fraction < params.min_tracked_fraction {
                return Err(Error::FaceLost {
                    tracked_fraction: fraction,
                    min: params.min_tracked_fraction,
                })
                .at(Context::Frame(t));
            }
            let mut ratios: Vec<f64> = good
                .iter()
                .map(|(_, r)| r.residual / r.contrast.max(f64::MIN_POSITIVE))
                .collect();
            ratios.sort_by(f64::total_cmp);
            // Z normalised by its median trace: the weights are relative.
            let mut traces: Vec<f64> = good.iter().map(|(_, r)| r.z[0] + r.z[2]).collect();
            traces.sort_by(f64::total_cmp);
            let norm = traces[traces.len() / 2].max(f64::MIN_POSITIVE);
            let o = Obs {
                points: good.iter().map(|(v, _)| *v).collect(),
                pixels: good.iter().map(|(_, r)| r.p).collect(),
                z: good.iter().map(|(_, r)| r.z.map(|x| x / norm)).collect(),
            };
            let sys = FrameSystem {
                points: &o.points,
                pixels: &o.pixels,
                z: Some(&o.z),
            };
            // The solve starts from frame t's points (`pt`), and the fitted frame's points serve
            // its reprojection error and the next pair (the tracked vertices are the first of
            // `ext`, so `solve_model`'s points are theirs).
            let start = o.points.iter().map(|&v| pt[v]).collect();
            cameras[t] = fit_frame(
                solve_model,
                &mut weights[t],
                constant,
                &sys,
                &mean,
                params.prior,
                params.rounds,
                Some(start),
            )
            .at(Context::Frame(t))?;
            let fitted = model.face_points(&weights[t], &all)?;
            let pts: Vec<[f64; 3]> = o.points.iter().map(|&v| fitted[v]).collect();
            reprojection_rms_px[t] = points_reprojection_rms(&pts, &cameras[t], sys.pixels);
            shapes[s] = Some(ps);
            shapes[t] = Some(fitted);
            tracked_fraction[t] = fraction;
            klt_residual_ratio[t] = ratios[ratios.len() / 2];
            obs[t] = o;
        }
        // Constant attributes from the systems of all pairs together.
        let systems: Vec<FrameSystem<'_>> = obs
            .iter()
            .map(|o| FrameSystem {
                points: &o.points,
                pixels: &o.pixels,
                z: Some(&o.z),
            })
            .collect();
        fit_constants(
            solve_model,
            constant,
            &mut weights,
            &cameras,
            &systems,
            &mean,
            params.prior,
        )?;
        // The constant attributes changed every frame's weights.
        shapes.fill(None);
    }
    Ok(VideoTrack {
        cameras,
        weights,
        tracked_fraction,
        reprojection_rms_px,
        klt_residual_ratio,
        seconds: t0.elapsed().as_secs_f64(),
        klt_seconds,
    })
}
