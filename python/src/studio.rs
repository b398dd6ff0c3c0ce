//! The synthetic capture studio (dynamic-shapes-studio, with the method crates' validation
//! scenes): the captures the Rust examples' quick runs score, as NumPy arrays with their
//! ground truth, for the Python examples and the batch runs. Plain values in; the scene is
//! built, rendered and returned in one call (a scene object would hold a borrowed capture).

use std::path::PathBuf;

use glam::DVec3;
use numpy::ndarray::{ArrayD, IxDyn};
use numpy::PyArrayDyn;
use photometric_normals::truth::{
    dome_power_fraction, pattern_images, skirt_subject, SensorNoise, StudioScene, TrueSurface,
    STUDIO_FRAME,
};
use photometric_normals::PATTERNS;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use skin_core::camera::{Camera as RustCamera, Intrinsics, Rig};
use skin_core::image::Mask;
use skin_core::mesh::{decimate, TriMesh};
use skin_core::skeleton::Motion;

use dynamic_shapes_studio::{
    exercise_motion, fast_motion, makehuman_performer, procedural_performer, scan_outer_surface,
    studio_ring, Capture, CaptureSpec, DeformationParams, ExerciseParams, FastMotionParams,
    Performer, ProceduralBodyParams, ScanParams, WrinkleParams,
};

use crate::core::{mesh_arrays, Camera, Skeleton};
use crate::errors::{invalid, to_py};
use crate::photometric::Calibration;

/// A row-major buffer moved into NumPy with any number of axes.
fn owned_n<'py, T: numpy::Element>(
    py: Python<'py>,
    flat: Vec<T>,
    shape: &[usize],
) -> PyResult<Bound<'py, PyArrayDyn<T>>> {
    ArrayD::from_shape_vec(IxDyn(shape), flat)
        .map(|a| PyArrayDyn::from_owned_array(py, a))
        .map_err(|e| invalid(format!("array of shape {shape:?}: {e}")))
}

/// Masks `(n, h, w)` uint8 (1 inside) in order.
fn mask_array<'py>(
    py: Python<'py>,
    masks: &[Mask],
    lead: &[usize],
) -> PyResult<Bound<'py, PyArrayDyn<u8>>> {
    let (w, h) = masks
        .first()
        .map_or((0, 0), |m| (m.width() as usize, m.height() as usize));
    let flat: Vec<u8> = masks.iter().flat_map(|m| m.iter().map(u8::from)).collect();
    let mut shape = lead.to_vec();
    shape.extend([h, w]);
    owned_n(py, flat, &shape)
}

fn camera_list(py: Python<'_>, cams: &[RustCamera]) -> PyResult<Vec<Py<Camera>>> {
    cams.iter()
        .map(|c| Py::new(py, Camera { inner: c.clone() }))
        .collect()
}

/// The quick run of the Rust example `photometric_normals`: MakeHuman in the wrinkled skirt
/// at the studio frame under the 1,200-light dome (cast shadows, exact per-light visibility),
/// `cameras` ring cameras of `size` × `size` px, the seven half-on pattern images read through
/// the sensor model (shot, read and 10-bit noise; camera `c`'s pattern `p` seeded
/// `1000 + 8c + p`) with saturation at `white_level`. `makehuman_dir` holds the MakeHuman
/// files (the repository's `data/makehuman`).
///
/// Returns a dict: `cameras` (list of `Camera`), `images` `(cameras, 7, h, w)` float64 (grey,
/// X, Y, Z, Full, X̄, Ȳ, Z̄), `masks` `(cameras, h, w)` uint8, `true_normals`
/// `(cameras, h, w, 3)` float64 (camera frame), `open` `(cameras, h, w)` uint8 (body pixels
/// that receive at least 90 % of the dome's power: outside shadowed concavities),
/// `calibrations` (one `photometric.Calibration` per camera, grey spheres at the stage's
/// heights), `performance_centre` (the root, m) and `white_level`.
#[pyfunction]
#[pyo3(signature = (makehuman_dir, cameras = 2, size = 256, white_level = 0.4))]
fn photometric_frame<'py>(
    py: Python<'py>,
    makehuman_dir: PathBuf,
    cameras: usize,
    size: u32,
    white_level: f32,
) -> PyResult<Bound<'py, PyDict>> {
    struct Out {
        cams: Vec<RustCamera>,
        images: Vec<f64>,
        masks: Vec<Mask>,
        normals: Vec<f64>,
        open: Vec<u8>,
        cals: Vec<photometric_normals::HeightCalibration>,
        centre: DVec3,
    }
    let out = py
        .detach(|| -> photometric_normals::Result<Out> {
            let scene = StudioScene::with_surface(
                &makehuman_dir,
                &skirt_subject().with_wrinkles(Some(WrinkleParams::default())),
                STUDIO_FRAME,
                cameras,
                size,
                TrueSurface::Polygonal,
            )?;
            let mut spec = scene.capture_spec(scene.ring.clone())?;
            if let Some(lighting) = &mut spec.lighting {
                lighting.shadows = true;
                lighting.shadow_light_bins = None;
            }
            spec.noise = None;
            let mut frame = scene.capture(spec)?;
            let noise = SensorNoise::default().with_white_level(white_level);
            for (c, obs) in frame.observations.iter_mut().enumerate() {
                for (p, im) in obs.patterns.iter_mut().enumerate() {
                    noise.apply(im, (1000 + 8 * c + p) as u64)?;
                }
            }
            let (_, cal_params, _) = scene.photometric_params(white_level);
            let mesh = frame.truth.rendered_mesh(&scene.performer);
            let mut out = Out {
                cams: scene.ring.cameras.clone(),
                images: vec![],
                masks: vec![],
                normals: vec![],
                open: vec![],
                cals: vec![],
                centre: scene.root,
            };
            for (c, cam) in scene.ring.cameras.iter().enumerate() {
                out.cals.push(scene.calibrate(cam, &cal_params)?);
                let obs = &frame.observations[c];
                let images = pattern_images(obs)?;
                for &p in &PATTERNS {
                    out.images
                        .extend(images.image(p).as_raw().iter().map(|&x| f64::from(x)));
                }
                let view = &frame.truth.views[c];
                let truth =
                    view.normals_camera
                        .as_ref()
                        .ok_or(photometric_normals::Error::Empty {
                            what: "the studio's true normals",
                        })?;
                out.normals
                    .extend(truth.as_raw().iter().map(|&x| f64::from(x)));
                let power = match &frame.light_visibility {
                    Some(vis) => dome_power_fraction(view, &mesh, &scene.stage.lights, vis)?,
                    None => vec![1.0; obs.mask.iter().count()],
                };
                out.open.extend(
                    obs.mask
                        .iter()
                        .zip(&power)
                        .map(|(m, &p)| u8::from(m && p >= 0.9)),
                );
                out.masks.push(obs.mask.clone());
            }
            Ok(out)
        })
        .map_err(to_py)?;
    let (n, h, w) = (out.cams.len(), size as usize, size as usize);
    let d = PyDict::new(py);
    d.set_item("cameras", camera_list(py, &out.cams)?)?;
    d.set_item(
        "images",
        owned_n(py, out.images, &[n, PATTERNS.len(), h, w])?,
    )?;
    d.set_item("masks", mask_array(py, &out.masks, &[n])?)?;
    d.set_item("true_normals", owned_n(py, out.normals, &[n, h, w, 3])?)?;
    d.set_item("open", owned_n(py, out.open, &[n, h, w])?)?;
    let cals = out
        .cals
        .into_iter()
        .map(|inner| Py::new(py, Calibration { inner }))
        .collect::<PyResult<Vec<_>>>()?;
    d.set_item("calibrations", cals)?;
    d.set_item("performance_centre", out.centre.to_array())?;
    d.set_item("white_level", white_level)?;
    Ok(d)
}

/// The template example's performer: with the skirt as the photometric scene's subject (the
/// hip flap off, it only distorts the thighs the skirt collides with); the pose-driven
/// muscles in both.
fn body_deformation(skirt: bool) -> DeformationParams {
    if skirt {
        skirt_subject()
    } else {
        DeformationParams::default()
    }
}

fn motion_named(name: &str, performer: &Performer) -> PyResult<Motion> {
    match name {
        "exercise" => exercise_motion(&performer.skeleton, &ExerciseParams::default()),
        "fast" => fast_motion(&performer.skeleton, &FastMotionParams::default()),
        other => {
            return Err(invalid(format!(
                "motion {other:?}: give \"exercise\" or \"fast\""
            )))
        }
    }
    .map_err(to_py)
}

/// The silhouette capture of the Rust example `template_capture` (its quick `body_exercise`
/// run with the defaults, the thesis' protocol): MakeHuman (`skirt`: in the skirt) in the
/// studio's `motion` (`"exercise"` or `"fast"`), `frames` frames from `first` at `fps` frames
/// per second (`None`: every `step`-th frame), seen by a ring of `cameras` cameras of `width`
/// × `height` px (55° horizontal field of view) at `radius_m` around the first frame's root,
/// `camera_height_m` above the performer's lowest rest vertex (`None`: 0.15 m above the
/// root). `makehuman_dir` holds the MakeHuman files.
///
/// Returns a dict: `cameras` (list of `Camera`), `masks` `(frames, cameras, h, w)` uint8,
/// `thetas` `(frames, dofs)` the true poses, `skeleton` (`Skeleton`), `rest_vertices`,
/// `rest_faces` (the performer's rest mesh), `template_vertices`, `template_faces` (the
/// template a user would rig: with `scan_template`, the outer surface a scanner sees,
/// otherwise the rest mesh, decimated to `template_vertices` vertices, 0: kept whole).
#[pyfunction]
#[pyo3(signature = (makehuman_dir, skirt = false, motion = "exercise", frames = 12, first = 40,
    fps = Some(30.0), step = 2, cameras = 8, width = 480, height = 360, radius_m = 3.5,
    camera_height_m = Some(2.2), scan_template = true, template_vertices = 10_000))]
#[allow(clippy::too_many_arguments)]
fn silhouette_capture<'py>(
    py: Python<'py>,
    makehuman_dir: PathBuf,
    skirt: bool,
    motion: &str,
    frames: usize,
    first: usize,
    fps: Option<f64>,
    step: usize,
    cameras: usize,
    width: u32,
    height: u32,
    radius_m: f64,
    camera_height_m: Option<f64>,
    scan_template: bool,
    template_vertices: usize,
) -> PyResult<Bound<'py, PyDict>> {
    let performer = py
        .detach(|| makehuman_performer(&makehuman_dir, &body_deformation(skirt)))
        .map_err(to_py)?;
    let motion = motion_named(motion, &performer)?;
    let step = match fps {
        Some(fps) if fps.is_finite() && fps > 0.0 => {
            ((1.0 / motion.frame_time_s / fps).round() as usize).max(1)
        }
        Some(fps) => return Err(invalid(format!("fps {fps}: give a positive frame rate"))),
        None => step,
    };
    if frames == 0 || step == 0 {
        return Err(invalid("frames and step must be positive"));
    }
    let last = first + step * frames;
    if last > motion.frame_count() {
        return Err(invalid(format!(
            "{frames} frames from {first} every {step} pass the motion's {}",
            motion.frame_count()
        )));
    }
    struct Out {
        cams: Vec<RustCamera>,
        masks: Vec<Mask>,
        thetas: Vec<Vec<f64>>,
        template: TriMesh,
    }
    let out = py
        .detach(|| -> skin_core::Result<Out> {
            let root = performer
                .skeleton
                .forward_kinematics(motion.frame(first))?
                .joint_positions()[0];
            let k = Intrinsics::from_horizontal_fov(55f64.to_radians(), width, height)?;
            let lowest = performer
                .template
                .vertices
                .iter()
                .map(|v| v.y)
                .fold(f64::INFINITY, f64::min);
            let y = camera_height_m.map_or(root.y + 0.15, |h| lowest + h);
            let rig = Rig::ring(cameras, radius_m, y, root, DVec3::Y, k)?;
            let cams = rig.cameras.clone();
            let spec = CaptureSpec::masks_only(rig).with_frame_rate_hz(1.0 / motion.frame_time_s);
            let capture = Capture::new(&performer, &motion, spec)?;
            let (mut masks, mut thetas) = (vec![], vec![]);
            for f in capture.frames_stepped(first..last, step) {
                let f = f?;
                masks.extend(f.masks());
                thetas.push(f.truth.theta.clone());
            }
            let template = if scan_template {
                let params = ScanParams {
                    vertices: (template_vertices > 0).then_some(template_vertices),
                    ..ScanParams::default()
                };
                scan_outer_surface(&performer, &params)?.mesh
            } else if template_vertices == 0 {
                performer.template.clone()
            } else {
                decimate(&performer.template, template_vertices)?.mesh
            };
            Ok(Out {
                cams,
                masks,
                thetas,
                template,
            })
        })
        .map_err(to_py)?;
    let d = PyDict::new(py);
    d.set_item("cameras", camera_list(py, &out.cams)?)?;
    d.set_item(
        "masks",
        mask_array(py, &out.masks, &[out.thetas.len(), out.cams.len()])?,
    )?;
    let dofs = performer.skeleton.dof_count();
    d.set_item(
        "thetas",
        crate::arrays::from_vec_rows(py, &out.thetas, dofs)?,
    )?;
    d.set_item(
        "skeleton",
        Py::new(
            py,
            Skeleton {
                inner: performer.skeleton.clone(),
            },
        )?,
    )?;
    let rest = mesh_arrays(py, &performer.template)?;
    d.set_item("rest_vertices", rest.get_item(0)?)?;
    d.set_item("rest_faces", rest.get_item(1)?)?;
    let t = mesh_arrays(py, &out.template)?;
    d.set_item("template_vertices", t.get_item(0)?)?;
    d.set_item("template_faces", t.get_item(1)?)?;
    Ok(d)
}

/// The needle example's performer: procedural, with its pose-driven shapes and no hip flap (the
/// validation protocol: what a pose-driven model can predict).
fn needle_performer() -> skin_core::Result<Performer> {
    procedural_performer(&ProceduralBodyParams {
        deformation: DeformationParams::default().with_flap(None),
        ..Default::default()
    })
}

/// The needle performer and the studio's exercise of `seconds` with `seed`.
fn needle_exercise(seconds: f64, seed: u64) -> skin_core::Result<(Performer, Motion)> {
    let performer = needle_performer()?;
    let motion = exercise_motion(
        &performer.skeleton,
        &ExerciseParams::default()
            .with_duration_s(seconds)
            .with_seed(seed),
    )?;
    Ok((performer, motion))
}

/// The training capture of the Rust example `needle_capture --quick`: the procedural
/// performer (pose-driven shapes, no flap) turning through the studio's free exercise
/// (`seconds` long, seed `seed`) at the motion's frame rate, seen by the studio ring of
/// `cameras` cameras at `width` × `height` px.
///
/// Returns a dict: `cameras`, `skeleton`, `thetas` `(frames, dofs)` (the mocap poses the
/// needle model takes), `masks` `(frames, cameras, h, w)` uint8.
#[pyfunction]
#[pyo3(signature = (seconds = 24.0, seed = 11, cameras = 3, width = 360, height = 240))]
fn needle_capture<'py>(
    py: Python<'py>,
    seconds: f64,
    seed: u64,
    cameras: usize,
    width: u32,
    height: u32,
) -> PyResult<Bound<'py, PyDict>> {
    let (skeleton, cams, thetas, masks) = py
        .detach(|| -> skin_core::Result<_> {
            let (performer, motion) = needle_exercise(seconds, seed)?;
            let rig = studio_ring(cameras, width, height)?;
            let cams = rig.cameras.clone();
            let spec = CaptureSpec::masks_only(rig).with_frame_rate_hz(1.0 / motion.frame_time_s);
            let capture = Capture::new(&performer, &motion, spec)?;
            let (mut thetas, mut masks) = (vec![], vec![]);
            for f in capture.frames() {
                let f = f?;
                masks.extend(f.masks());
                thetas.push(f.truth.theta.clone());
            }
            Ok((performer.skeleton.clone(), cams, thetas, masks))
        })
        .map_err(to_py)?;
    let d = PyDict::new(py);
    d.set_item("cameras", camera_list(py, &cams)?)?;
    d.set_item(
        "thetas",
        crate::arrays::from_vec_rows(py, &thetas, skeleton.dof_count())?,
    )?;
    d.set_item(
        "masks",
        mask_array(py, &masks, &[thetas.len(), cams.len()])?,
    )?;
    d.set_item("skeleton", Py::new(py, Skeleton { inner: skeleton })?)?;
    Ok(d)
}

/// The needle example's test scoring: `model`'s needle-length errors against the true
/// surface on the studio's exercise of seed `seed` (`seconds` long, every `stride`-th frame),
/// a motion it was not trained on (`needle_model::truth::TestSet`). Returns a dict of mm
/// arrays: `all_mm` (every scored needle-frame), `near_joints_mm`, `deforming_mm` (true and
/// LBS lengths differ), `pose_deforming_mm` (the needles the pose deforms: the headline's).
#[pyfunction]
#[pyo3(signature = (model, seconds = 8.0, seed = 23, stride = 8))]
fn needle_test_errors<'py>(
    py: Python<'py>,
    model: &crate::needle::NeedleModel,
    seconds: f64,
    seed: u64,
    stride: usize,
) -> PyResult<Bound<'py, PyDict>> {
    if stride == 0 {
        return Err(invalid("stride must be positive"));
    }
    let errors = py
        .detach(|| -> needle_model::Result<needle_model::truth::Errors> {
            let (performer, motion) = needle_exercise(seconds, seed)?;
            let spec = CaptureSpec::masks_only(studio_ring(3, 360, 240)?)
                .with_frame_rate_hz(1.0 / motion.frame_time_s);
            let capture = Capture::new(&performer, &motion, spec)?;
            let mut set = needle_model::truth::TestSet::default();
            for frame in capture.frames_stepped(0..capture.frame_count(), stride) {
                set.push_frame(&model.body, &performer, &frame?.truth)?;
            }
            set.errors(&model.model)
        })
        .map_err(to_py)?;
    let d = PyDict::new(py);
    d.set_item("all_mm", crate::arrays::owned1(py, errors.all_mm))?;
    d.set_item(
        "near_joints_mm",
        crate::arrays::owned1(py, errors.near_joints_mm),
    )?;
    d.set_item(
        "deforming_mm",
        crate::arrays::owned1(py, errors.deforming_mm),
    )?;
    d.set_item(
        "pose_deforming_mm",
        crate::arrays::owned1(py, errors.pose_deforming_mm),
    )?;
    Ok(d)
}

pub(crate) fn register(parent: &Bound<'_, PyModule>) -> PyResult<()> {
    let m = PyModule::new(parent.py(), "studio")?;
    m.add("STUDIO_FRAME", STUDIO_FRAME)?;
    m.add_function(wrap_pyfunction!(photometric_frame, &m)?)?;
    m.add_function(wrap_pyfunction!(silhouette_capture, &m)?)?;
    m.add_function(wrap_pyfunction!(needle_capture, &m)?)?;
    m.add_function(wrap_pyfunction!(needle_test_errors, &m)?)?;
    parent.add_submodule(&m)
}
