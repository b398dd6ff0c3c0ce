//! Validation equipment for the ellipsoid fit (feature `validation`): the studio scenario
//! and its scores.
//!
//! **Scenario.** The studio's procedural performer defines the *default* skeleton. The
//! *true* performer has every model bone's length scaled by a factor drawn in
//! `1 ± length_spread`; its rest mesh follows by moving each vertex with its skin weights'
//! blend of the joint frames' moves (translation-only LBS from the default to the true rest
//! frames), so the limbs' cross-sections (widths) are the default performer's and the bones
//! are longer or shorter. Each frame poses the true mesh by LBS at a frame of the studio's
//! fast motion. Observations: `points` 3D points sampled area-uniformly from the limb
//! surface (the triangles whose vertices are carried by a modelled bone), σ = 5 mm Gaussian
//! noise, plus a fraction of gross outliers uniform in the body's bounding box grown by
//! 0.3 m; the silhouettes of the posed true mesh in a 3-camera studio ring, as contour rays;
//! markers at vertices of the modelled limbs (σ = 1 mm). The fit starts from the default
//! proportions, half-widths of 5 cm and the true pose with Gaussian noise on every rotation.
//!
//! **Truth.** Bone lengths from the true skeleton; the reference half-width of each bone is
//! the geometric fit of Eq. 3 ([`fit_half_width`]) to the true vertices carried by that
//! bone at the rest pose, with the true lengths (posed, LBS's joint regions bend it); the joint angle error is the angle between the
//! fitted and the true bone directions (axial twist excluded: the ellipsoids are symmetric
//! about the bone).

use dynamic_shapes_studio::{
    exercise_motion, fast_motion, procedural_performer, studio_ring, Capture, CaptureSpec,
    DeformationParams, ExerciseParams, FastMotionParams, MarkerImageStyle, MarkerSet, Performer,
    ProceduralBodyParams,
};
use skin_core::camera::Camera;
use skin_core::image::Mask;
use skin_core::markers::{
    id_switches, track_markers, MarkerDetectParams, TrackParams, DEFAULT_MARKER_OFFSET_M,
    DEFAULT_MARKER_RADIUS_M,
};
use skin_core::math::DVec3;
use skin_core::mesh::{resize_rest, SkinWeights, TriMesh};
use skin_core::random::SplitMix64;
use skin_core::raster::{Buffers, RenderParams};
use skin_core::skeleton::Skeleton;
use skin_core::{check, Context};

use super::{
    fit_half_width, Ellipsoid, EllipsoidModel, EllipsoidObservations, EllipsoidState,
    MarkerObservation,
};
use crate::error::{Error, Result, ResultExt};
use crate::silhouette_constraints::{contour_rays, SilhouetteParams};

/// Parameters of [`ellipsoid_scenario`] (the validation protocol as defaults).
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(docsrs, doc(cfg(feature = "validation")))]
pub struct EllipsoidScenarioParams {
    /// Seed of every random draw. Default 12.
    pub seed: u64,
    /// 3D points per frame, outliers included. Default 5000.
    pub points: usize,
    /// Fraction of gross outliers among them. Default 0.3.
    pub outlier_fraction: f64,
    /// σ of the inlier points' noise, metres. Default 0.005.
    pub point_sigma_m: f64,
    /// Markers (studio balls rendered, detected, triangulated and tracked). Default 20.
    pub markers: usize,
    /// Bone lengths of the performer differ from the default skeleton's by up to this
    /// fraction. Default 0.10.
    pub length_spread: f64,
    /// Cameras of the studio ring. Default 3.
    pub cameras: usize,
    /// Image size, px. Default 400 × 300.
    pub image_size: (u32, u32),
    /// σ of the starting pose's noise on each rotation DOF, degrees. Default 5.
    pub pose_noise_deg: f64,
    /// Frames of the studio's fast motion. Default 0, 20, 40.
    pub frames: Vec<usize>,
    /// The studio motion the frames are taken from. Default the fast motion
    /// ([`FastMotionParams::default`]: 60 Hz, limb swings at 1.5–3 Hz).
    pub motion: ScenarioMotion,
    /// Marching-cubes spacing of the procedural performer, metres. Default 0.02.
    pub grid_spacing_m: f64,
    /// Model the end-site segments too (hands, feet, head;
    /// [`EllipsoidModel::with_end_sites`]); scores stay over the limbs. Default true: the
    /// end sites pin the far end of a chain's last bone (forearm, shin), whose length the limb
    /// model alone leaves weakly determined (measured, 8-frame fit: mean length error 7.5 vs
    /// 17.4 mm).
    pub end_sites: bool,
}

impl Default for EllipsoidScenarioParams {
    fn default() -> Self {
        EllipsoidScenarioParams {
            seed: 12,
            points: 5000,
            outlier_fraction: 0.3,
            point_sigma_m: 0.005,
            markers: 20,
            length_spread: 0.10,
            cameras: 3,
            image_size: (400, 300),
            pose_noise_deg: 5.0,
            frames: vec![0, 20, 40],
            motion: ScenarioMotion::Fast(FastMotionParams::default()),
            grid_spacing_m: 0.02,
            end_sites: true,
        }
    }
}

/// The studio motion of [`ellipsoid_scenario`].
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(docsrs, doc(cfg(feature = "validation")))]
pub enum ScenarioMotion {
    /// The fast motion (brisk swings of every DOF).
    Fast(FastMotionParams),
    /// The free multi-DOF exercise (slow, deliberate: what a tracker follows frame to frame).
    Exercise(ExerciseParams),
}

/// One frame of the scenario.
#[derive(Debug, Clone)]
#[cfg_attr(docsrs, doc(cfg(feature = "validation")))]
pub struct ScenarioFrame {
    /// What the fit sees.
    pub observations: EllipsoidObservations,
    /// The starting state (default proportions, noisy pose).
    pub start: EllipsoidState,
    /// The true state: pose, length scales, reference half-widths (Eq. 3 fit to the limb).
    pub truth: EllipsoidState,
    /// The true posed mesh.
    pub mesh: TriMesh,
    /// The silhouettes, one per camera.
    pub masks: Vec<Mask>,
}

/// The scenario: the model (default skeleton), the cameras, the frames.
#[derive(Debug, Clone)]
#[cfg_attr(docsrs, doc(cfg(feature = "validation")))]
pub struct EllipsoidScenario {
    /// The ellipsoid model over the default skeleton's limbs.
    pub model: EllipsoidModel,
    /// The cameras.
    pub cameras: Vec<Camera>,
    /// The frames.
    pub frames: Vec<ScenarioFrame>,
    /// Identity switches of the marker tracking through the captured frames (links between
    /// detections of different true markers, [`skin_core::markers::id_switches`]): a switched
    /// trajectory keeps the bone of its first frame's marker.
    pub marker_id_switches: usize,
}

impl EllipsoidScenario {
    /// Every frame's starting state and observations, as [`super::fit_ellipsoids_multi`]
    /// takes them.
    pub fn starts_and_observations(&self) -> (Vec<EllipsoidState>, Vec<EllipsoidObservations>) {
        self.frames
            .iter()
            .map(|f| (f.start.clone(), f.observations.clone()))
            .unzip()
    }
}

/// Scores of a fitted state against the truth.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(docsrs, doc(cfg(feature = "validation")))]
pub struct EllipsoidScores {
    /// Mean |fitted − true| bone length, mm.
    pub bone_length_error_mm: f64,
    /// Mean |fitted − reference| half-width, mm.
    pub width_error_mm: f64,
    /// Mean angle between fitted and true bone directions, degrees (twist excluded).
    pub joint_angle_error_deg: f64,
}

/// Largest stretch of a triangle edge (posed / rest length) kept in the true mesh.
const MAX_STRETCH: f64 = 1.5;

fn dominant(weights: &SkinWeights, i: usize) -> Option<u32> {
    weights
        .influences(i)
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(b, _)| b)
}

/// The performer's skinning weights with each vertex's influences restricted to its dominant
/// joint and the joints adjacent to it in the skeleton (parent, children). The procedural
/// body is built at a rest pose in which the forearms touch the hips and the hands the thighs;
/// its distance-based weights give such vertices influences from the touching part, and LBS
/// then smears them between a raised arm and the pelvis (traced: at frame 10 of the fast
/// motion 64 % of the right forearm's triangles were stretched beyond 1.5×). A skin vertex
/// of a limb moves with its bone and the bones next to it.
fn adjacent_only(weights: &SkinWeights, sk: &Skeleton) -> Result<SkinWeights> {
    let lists: Vec<Vec<(u32, f64)>> = (0..weights.vertex_count())
        .map(|i| {
            let Some(d) = dominant(weights, i) else {
                return Vec::new();
            };
            let d = d as usize;
            let parent = sk.joints()[d].parent;
            weights
                .influences(i)
                .filter(|&(j, _)| {
                    let j = j as usize;
                    j == d || Some(j) == parent || sk.joints()[j].parent == Some(d)
                })
                .collect()
        })
        .collect();
    Ok(SkinWeights::from_lists(&lists, sk.joint_count())?)
}

/// Skeleton distance (joints on the path) between joints `a` and `b`.
fn joint_distance(sk: &Skeleton, a: usize, b: usize) -> usize {
    let ancestors = |mut j: usize| {
        let mut path = vec![j];
        while let Some(p) = sk.joints()[j].parent {
            path.push(p);
            j = p;
        }
        path
    };
    let (pa, pb) = (ancestors(a), ancestors(b));
    let common = pa
        .iter()
        .rev()
        .zip(pb.iter().rev())
        .take_while(|(x, y)| x == y)
        .count();
    pa.len() + pb.len() - 2 * common
}

/// The template's faces without the bridging triangles: the procedural body is one
/// marching-cubes surface built at a rest pose where forearms touch the hips and hands the
/// thighs, so triangles join vertices of distant body parts (a forearm's and the pelvis');
/// posed apart by LBS they become a membrane that is no body surface (traced: it held most of
/// a raised forearm's points, 12 cm median residual at the true state). A triangle is kept
/// when the dominant joints of its vertices are at most two joints apart in the skeleton
/// (a joint region: elbow, shoulder across the clavicle); the cut leaves holes where the parts
/// touched at rest, which the cameras see through to the far side of the same limb.
fn separate_parts(faces: &[[u32; 3]], weights: &SkinWeights, sk: &Skeleton) -> Vec<[u32; 3]> {
    faces
        .iter()
        .copied()
        .filter(|f| {
            let d: Vec<Option<u32>> = f.iter().map(|&v| dominant(weights, v as usize)).collect();
            (0..3).all(|e| match (d[e], d[(e + 1) % 3]) {
                (Some(a), Some(b)) => joint_distance(sk, a as usize, b as usize) <= 2,
                _ => true,
            })
        })
        .collect()
}

/// Whether vertex `i` moves with one joint alone (dominant weight ≥ 0.75): a marker's place,
/// away from the joint regions and webs.
fn rigid(weights: &SkinWeights, i: usize) -> bool {
    weights.influences(i).any(|(_, w)| w >= 0.75)
}

/// Builds the scenario.
///
/// # Errors
/// Invalid parameters; errors of the studio (performer, motion, rendering) and of the
/// silhouettes.
#[cfg_attr(docsrs, doc(cfg(feature = "validation")))]
pub fn ellipsoid_scenario(params: &EllipsoidScenarioParams) -> Result<EllipsoidScenario> {
    check::in_range("outlier_fraction", params.outlier_fraction, 0.0..=0.9)?;
    check::positive("point_sigma_m", params.point_sigma_m)?;
    check::in_range("length_spread", params.length_spread, 0.0..=0.5)?;
    check::nonzero("points", params.points)?;
    check::nonzero("frames", params.frames.len())?;
    let performer = procedural_performer(&ProceduralBodyParams {
        grid_spacing_m: params.grid_spacing_m,
        ..ProceduralBodyParams::default()
    })?;
    let default_sk = performer.skeleton.clone();
    let model = if params.end_sites {
        EllipsoidModel::with_end_sites(default_sk.clone(), 0.1)?
    } else {
        EllipsoidModel::limbs(default_sk.clone(), 0.1)?
    };
    let rng = SplitMix64::new(params.seed);
    let mut draw = 0u64;
    let mut uniform = || {
        draw += 1;
        rng.uniform_at(draw)
    };
    // The true performer: bone lengths scaled.
    let nb = model.bones().len();
    // An end-site segment's scale moves no joint: the true performer keeps its length.
    let factors: Vec<f64> = model
        .bones()
        .iter()
        .map(|bone| {
            let f = 1.0 + params.length_spread * (2.0 * uniform() - 1.0);
            if bone.child.is_some() {
                f
            } else {
                1.0
            }
        })
        .collect();
    let mut joints = default_sk.joints().to_vec();
    for (bone, f) in model.bones().iter().zip(&factors) {
        if let Some(c) = bone.child {
            joints[c].offset *= *f;
        }
    }
    let true_sk = Skeleton::new(joints)?;
    let weights = &adjacent_only(&performer.weights, &default_sk)?;
    let rest_true = resize_rest(&performer.template.vertices, weights, &default_sk, &true_sk)?;
    let faces = performer.template.faces.clone();
    // Limb triangles: all three vertices carried by a modelled bone's joint.
    let limb_joint =
        |j: Option<u32>| j.and_then(|j| model.bones().iter().position(|b| b.parent == j as usize));
    let vertex_bone: Vec<Option<usize>> = (0..rest_true.len())
        .map(|i| limb_joint(dominant(weights, i)))
        .collect();
    // One bone's triangles (a triangle across two bones is a joint region or a web).
    let limb_faces: Vec<[u32; 3]> = faces
        .iter()
        .copied()
        .filter(|f| {
            let b = vertex_bone[f[0] as usize];
            b.is_some() && f.iter().all(|&v| vertex_bone[v as usize] == b)
        })
        .collect();
    // Truth: lengths, and the reference half-widths: Eq. 3 fitted to each true limb's
    // vertices at the rest pose (the widths do not depend on the pose here; posed, the
    // skinning's joint regions would bend the reference).
    let mut rest_truth = EllipsoidState {
        theta: vec![0.0; default_sk.dof_count()],
        length_scale: factors.clone(),
        half_width: vec![0.05; nb],
        // Eq. 3: the reference ellipsoid spans the true bone.
        half_length: model
            .default_lengths()
            .iter()
            .zip(&factors)
            .map(|(l, f)| 0.5 * l * f)
            .collect(),
    };
    for b in 0..nb {
        let limb: Vec<DVec3> = (0..rest_true.len())
            .filter(|&i| vertex_bone[i] == Some(b))
            .map(|i| rest_true[i])
            .collect();
        rest_truth.half_width[b] = fit_half_width(&model, &rest_truth, b, &limb)
            .at(Context::Joint(model.bones()[b].joint()))?;
    }
    // The true performer, captured by the studio: its rest mesh without the bridging
    // triangles (see `separate_parts`), the true skeleton, the adjacent-only weights, no
    // non-skinning deformation (the ellipsoids model the skinned limbs).
    let body_faces = separate_parts(&faces, weights, &true_sk);
    let limb_faces: Vec<[u32; 3]> = {
        let kept: std::collections::HashSet<[u32; 3]> = body_faces.iter().copied().collect();
        limb_faces
            .into_iter()
            .filter(|f| kept.contains(f))
            .collect()
    };
    let true_performer = Performer::new(
        "procedural, true proportions",
        TriMesh::new(rest_true.clone(), body_faces)?,
        true_sk.clone(),
        weights.clone(),
        &DeformationParams::none(),
    )?;
    let motion = match &params.motion {
        ScenarioMotion::Fast(p) => fast_motion(&default_sk, p)?,
        ScenarioMotion::Exercise(p) => exercise_motion(&default_sk, p)?,
    };
    let rate_hz = 1.0 / motion.frame_time_s;
    let rig = studio_ring(params.cameras, params.image_size.0, params.image_size.1)?;
    let cameras = rig.cameras.clone();
    let spec = CaptureSpec::masks_only(rig)
        .with_frame_rate_hz(rate_hz)
        .with_seed(params.seed)
        .with_render(
            RenderParams::default()
                .with_buffers(Buffers {
                    // The markers' occluder.
                    camera_z: params.markers > 0,
                    ..Buffers::MASK_ONLY
                })
                .with_allow_empty(true),
        );
    let capture = Capture::new(&true_performer, &motion, spec)?;
    // Markers: skin markers (the studio's balls, 10 mm off the skin) on rigidly skinned
    // vertices of the modelled bones, spread along each bone.
    let limb_vertices: Vec<usize> = (0..rest_true.len())
        .filter(|&i| vertex_bone[i].is_some() && rigid(weights, i))
        .collect();
    let mut marker_bone = Vec::with_capacity(params.markers);
    let mut marker_vertex = Vec::with_capacity(params.markers);
    for m in 0..params.markers {
        let bone_target = m % nb;
        let on_bone: Vec<usize> = limb_vertices
            .iter()
            .copied()
            .filter(|&i| vertex_bone[i] == Some(bone_target))
            .collect();
        if on_bone.is_empty() {
            return Err(Error::Empty {
                what: "performer vertices carried by a modelled bone",
            })
            .at(Context::Joint(model.bones()[bone_target].joint()));
        }
        // Spread along the bone: the vertices are in mesh order, not random.
        let step = on_bone.len() / (params.markers / nb + 1).max(1);
        marker_vertex.push(on_bone[((m / nb) * step + step / 2) % on_bone.len()]);
        marker_bone.push(bone_target);
    }
    let marker_set = MarkerSet {
        vertices: marker_vertex,
        offset_m: DEFAULT_MARKER_OFFSET_M,
        radius_m: DEFAULT_MARKER_RADIUS_M,
    };
    let last = params.frames.iter().copied().max().unwrap_or(0);
    check::index("frame", last, capture.frame_count())?;
    // Every frame up to the last is captured: the markers are tracked through them.
    let (style, detect) = (MarkerImageStyle::default(), MarkerDetectParams::default());
    let mut marker_sets = Vec::with_capacity(last + 1);
    let mut nearest = Vec::with_capacity(last + 1);
    let mut captured = Vec::with_capacity(params.frames.len());
    for frame in capture.frames_in(0..last + 1) {
        let frame = frame?;
        let k = frame.index;
        if params.markers > 0 {
            let seen = marker_set
                .observe(&true_performer, &frame, &cameras, &style, &detect, 1.5, 2)
                .at(Context::Frame(k))?;
            marker_sets.push(seen.points);
            nearest.push(seen.nearest_true);
        } else {
            marker_sets.push(Vec::new());
            nearest.push(Vec::new());
        }
        if params.frames.contains(&k) {
            captured.push(frame);
        }
    }
    // The search volumes of the published human limits at the capture's rate.
    let tracks = track_markers(&marker_sets, &TrackParams::human(rate_hz))?;
    let marker_id_switches = id_switches(&tracks, &nearest)?;
    let mut frames = Vec::with_capacity(params.frames.len());
    let mut normal_k = 0u64;
    for &k in &params.frames {
        let frame = (|| -> Result<ScenarioFrame> {
            let cap = captured.iter().find(|c| c.index == k).ok_or(Error::Empty {
                what: "captured frame",
            })?;
            let theta = cap.truth.theta.clone();
            let verts = cap.truth.posed.true_vertices.clone();
            let mesh = cap.truth.true_mesh(&true_performer);
            // The 3-D points only: drop the triangles stretched beyond `MAX_STRETCH` × their
            // rest length (what remains of the joint regions' membranes after
            // `separate_parts`); the cameras saw the whole surface.
            let intact = |f: &[u32; 3]| {
                (0..3).all(|e| {
                    let (a, b) = (f[e] as usize, f[(e + 1) % 3] as usize);
                    verts[a].distance(verts[b])
                        <= MAX_STRETCH * rest_true[a].distance(rest_true[b]) + 1e-9
                })
            };
            let limb_faces: Vec<[u32; 3]> =
                limb_faces.iter().copied().filter(|f| intact(f)).collect();
            // Points: area-uniform on the limb triangles, noisy; then outliers.
            let areas: Vec<f64> = limb_faces
                .iter()
                .map(|f| {
                    let [a, b, c] = f.map(|v| verts[v as usize]);
                    0.5 * (b - a).cross(c - a).length()
                })
                .collect();
            let total: f64 = areas.iter().sum();
            let mut cdf = Vec::with_capacity(areas.len());
            let mut acc = 0.0;
            for a in &areas {
                acc += a / total;
                cdf.push(acc);
            }
            let n_out = (params.points as f64 * params.outlier_fraction).round() as usize;
            let mut points = Vec::with_capacity(params.points);
            let mut gauss = || {
                normal_k += 1;
                rng.normal_at(normal_k + (1 << 40))
            };
            for _ in 0..params.points - n_out {
                let u = uniform();
                let fi = cdf.partition_point(|&c| c < u).min(limb_faces.len() - 1);
                let [a, b, c] = limb_faces[fi].map(|v| verts[v as usize]);
                let (mut r1, mut r2) = (uniform(), uniform());
                if r1 + r2 > 1.0 {
                    (r1, r2) = (1.0 - r1, 1.0 - r2);
                }
                let p = a + (b - a) * r1 + (c - a) * r2;
                points.push(p + DVec3::new(gauss(), gauss(), gauss()) * params.point_sigma_m);
            }
            let (lo, hi) = verts.iter().fold(
                (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN)),
                |(lo, hi), v| (lo.min(*v), hi.max(*v)),
            );
            let (lo, hi) = (lo - DVec3::splat(0.3), hi + DVec3::splat(0.3));
            for _ in 0..n_out {
                points.push(lo + (hi - lo) * DVec3::new(uniform(), uniform(), uniform()));
            }
            // Markers: the tracked trajectories through frame k, each labelled once, at its
            // first frame, with its marker (the operator's identification of Fua et al.
            // §2.4; here the nearest true marker), hence with the marker's bone.
            let mut markers: Vec<MarkerObservation> = Vec::new();
            let mut labelled = vec![false; marker_bone.len()];
            for t in &tracks {
                if k < t.first_frame || k >= t.end_frame() {
                    continue;
                }
                let label = nearest[t.first_frame][t.points[0]];
                if label >= marker_bone.len() || labelled[label] {
                    continue;
                }
                labelled[label] = true;
                markers.push(MarkerObservation {
                    bone: marker_bone[label],
                    position: Some(marker_sets[k][t.points[k - t.first_frame]]),
                });
            }
            for (m, seen) in labelled.iter().enumerate() {
                if !seen {
                    markers.push(MarkerObservation {
                        bone: marker_bone[m],
                        position: None,
                    });
                }
            }
            // Silhouettes (the capture's masks) and their contour rays.
            let masks = cap.masks();
            let mut rays = Vec::new();
            for (c, mask) in masks.iter().enumerate() {
                rays.extend(
                    contour_rays(&cameras[c], mask, &SilhouetteParams::default())
                        .at(Context::Camera(c))?,
                );
            }
            let truth = EllipsoidState {
                theta: theta.clone(),
                ..rest_truth.clone()
            };
            let noisy: Vec<f64> = theta
                .iter()
                .enumerate()
                .map(|(d, t)| {
                    if default_sk.is_rotation(d) {
                        t + gauss() * params.pose_noise_deg.to_radians()
                    } else {
                        *t
                    }
                })
                .collect();
            let start = model.initial_state(&noisy, 0.05)?;
            Ok(ScenarioFrame {
                observations: EllipsoidObservations {
                    points,
                    markers,
                    rays,
                },
                start,
                truth,
                mesh,
                masks,
            })
        })()
        .at(Context::Frame(k))?;
        frames.push(frame);
    }
    Ok(EllipsoidScenario {
        model,
        cameras,
        frames,
        marker_id_switches,
    })
}

/// Scores a fitted state against the truth of a frame, over the limbs (the bones between two
/// joints; end-site segments are not scored).
///
/// # Errors
/// States of the wrong size.
#[cfg_attr(docsrs, doc(cfg(feature = "validation")))]
pub fn score_ellipsoids(
    model: &EllipsoidModel,
    fitted: &EllipsoidState,
    truth: &EllipsoidState,
) -> Result<EllipsoidScores> {
    let limb = |(b, e): (usize, Ellipsoid)| model.bones()[b].child.is_some().then_some(e);
    let ef: Vec<Ellipsoid> = model
        .ellipsoids(fitted)?
        .into_iter()
        .enumerate()
        .filter_map(limb)
        .collect();
    let et: Vec<Ellipsoid> = model
        .ellipsoids(truth)?
        .into_iter()
        .enumerate()
        .filter_map(limb)
        .collect();
    let n = ef.len() as f64;
    let mut s = EllipsoidScores {
        bone_length_error_mm: 0.0,
        width_error_mm: 0.0,
        joint_angle_error_deg: 0.0,
    };
    for (f, t) in ef.iter().zip(&et) {
        s.bone_length_error_mm += 2000.0 * (f.half_bone - t.half_bone).abs() / n;
        s.width_error_mm += 1000.0 * (f.half_width - t.half_width).abs() / n;
        s.joint_angle_error_deg += f.axis.dot(t.axis).clamp(-1.0, 1.0).acos().to_degrees() / n;
    }
    if !s.bone_length_error_mm.is_finite() {
        return Err(Error::NonFinite {
            what: "ellipsoid scores",
        });
    }
    Ok(s)
}
