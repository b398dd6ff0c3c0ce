//! Writes the inputs and the Rust results the Python tests (`python/tests`) compare the
//! bindings against: NumPy `.npy` arrays and `fixtures.json` scalars in
//! `$CARGO_TARGET_TMPDIR/python-fixtures` (`target/tmp/python-fixtures`). Each result is
//! computed by the same Rust calls the binding makes, so the Python side must match it to
//! the last bit.
#![allow(clippy::unwrap_used, clippy::expect_used)] // not library code

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use dynamic_shapes_studio::{
    exercise_motion, fast_motion, procedural_performer, studio_ring, Capture, CaptureSpec,
    ExerciseParams, FastMotionParams, ProceduralBodyParams,
};
use glam::{DAffine3, DVec3};
use inertial_acoustic::simulate::{prepare_motion, SimulationParams, SuitSimulator};
use photometric_normals::truth::small_dome_sphere;
use photometric_normals::{
    estimate_normals, integrate_normals, CalibrationParams, CalibrationSphere, DepthMap,
    HeightCalibration, IntegrationParams, LookupTable, NormalParams, PatternImages, PolygonalHull,
    PATTERNS,
};
use serde_json::{json, Value};
use skin_core::camera::{Camera, Intrinsics};
use skin_core::image::Mask;
use skin_core::mesh::shapes::uv_sphere;
use skin_core::mesh::{self, LaplacianParams, SkinBinding, SkinWeights, TriMesh};
use skin_core::skeleton::{read_bvh, BvhParams, CMU_METRES_PER_UNIT};

/// An `.npy` file (format 1.0, little endian, C order).
fn npy(dir: &Path, name: &str, descr: &str, shape: &[usize], bytes: Vec<u8>) {
    dynamic_shapes_py::batch::npy::write(&dir.join(format!("{name}.npy")), descr, shape, &bytes)
        .unwrap();
}

fn f64s(dir: &Path, name: &str, shape: &[usize], v: impl IntoIterator<Item = f64>) {
    let bytes: Vec<u8> = v.into_iter().flat_map(f64::to_le_bytes).collect();
    assert_eq!(bytes.len(), 8 * shape.iter().product::<usize>(), "{name}");
    npy(dir, name, "<f8", shape, bytes);
}

fn u8s(dir: &Path, name: &str, shape: &[usize], v: impl IntoIterator<Item = u8>) {
    let bytes: Vec<u8> = v.into_iter().collect();
    assert_eq!(bytes.len(), shape.iter().product::<usize>(), "{name}");
    npy(dir, name, "|u1", shape, bytes);
}

fn u32s(dir: &Path, name: &str, shape: &[usize], v: impl IntoIterator<Item = u32>) {
    let bytes: Vec<u8> = v.into_iter().flat_map(u32::to_le_bytes).collect();
    npy(dir, name, "<u4", shape, bytes);
}

fn points(dir: &Path, name: &str, p: &[DVec3]) {
    f64s(
        dir,
        name,
        &[p.len(), 3],
        p.iter().flat_map(|v| v.to_array()),
    );
}

fn mesh_files(dir: &Path, name: &str, m: &TriMesh) {
    points(dir, &format!("{name}_vertices"), &m.vertices);
    u32s(
        dir,
        &format!("{name}_faces"),
        &[m.faces.len(), 3],
        m.faces.iter().flatten().copied(),
    );
}

fn affine_rows(t: &DAffine3) -> Vec<f64> {
    let (m, p) = (t.matrix3, t.translation);
    vec![
        m.x_axis.x, m.y_axis.x, m.z_axis.x, p.x, m.x_axis.y, m.y_axis.y, m.z_axis.y, p.y,
        m.x_axis.z, m.y_axis.z, m.z_axis.z, p.z, 0.0, 0.0, 0.0, 1.0,
    ]
}

fn mask_bytes(masks: &[Mask]) -> Vec<u8> {
    masks
        .iter()
        .flat_map(|m| {
            (0..m.height()).flat_map(move |y| (0..m.width()).map(move |x| u8::from(m.get(x, y))))
        })
        .collect()
}

/// `value` written as JSON text to `name` and read back from that text: the Python side
/// passes the same text to `from_json`, so both sides parse the same digits.
fn via_json<T: serde::Serialize + serde::de::DeserializeOwned>(
    dir: &Path,
    name: &str,
    value: &T,
) -> T {
    let text = serde_json::to_string(value).unwrap();
    std::fs::write(dir.join(name), &text).unwrap();
    serde_json::from_str(&text).unwrap()
}

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

#[test]
fn write_python_fixtures() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("python-fixtures");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let mut js: BTreeMap<&str, Value> = BTreeMap::new();

    // Core: a camera, 1,000 points, their pixels and the rays back.
    let k = Intrinsics::from_horizontal_fov(1.0, 640, 480).unwrap();
    let cam = Camera::look_at(
        k,
        DVec3::new(0.3, 1.2, 3.0),
        DVec3::new(0.0, 1.0, 0.0),
        DVec3::Y,
    )
    .unwrap();
    let pts: Vec<DVec3> = (0..1000)
        .map(|i| {
            let i = i as f64;
            DVec3::new(
                0.5 * (0.7 * i).sin(),
                1.0 + 0.5 * (1.3 * i).cos(),
                0.5 * (0.37 * i).sin(),
            )
        })
        .collect();
    let px: Vec<_> = pts.iter().map(|&p| cam.project(p).unwrap()).collect();
    let rays: Vec<_> = px.iter().map(|&p| cam.ray(p).unwrap()).collect();
    std::fs::write(
        dir.join("camera.json"),
        serde_json::to_string(&cam).unwrap(),
    )
    .unwrap();
    points(&dir, "camera_points", &pts);
    f64s(
        &dir,
        "camera_pixels",
        &[px.len(), 2],
        px.iter().flat_map(|p| p.to_array()),
    );
    points(
        &dir,
        "camera_ray_origins",
        &rays.iter().map(|r| r.origin).collect::<Vec<_>>(),
    );
    points(
        &dir,
        "camera_ray_directions",
        &rays.iter().map(|r| r.direction).collect::<Vec<_>>(),
    );

    // Meshes: a sphere written as OBJ and PLY, read back; its cotangent Laplacian.
    let sphere = uv_sphere(DVec3::new(0.1, 0.2, 0.3), 0.5, 8, 16).unwrap();
    mesh::write_obj(dir.join("sphere.obj"), &sphere).unwrap();
    mesh::write_ply(
        dir.join("sphere.ply"),
        &sphere,
        mesh::PlyEncoding::BinaryLittleEndian,
    )
    .unwrap();
    let from_obj = mesh::read_obj(dir.join("sphere.obj")).unwrap();
    mesh_files(&dir, "sphere_obj", &from_obj);
    mesh_files(
        &dir,
        "sphere_ply",
        &mesh::read_ply(dir.join("sphere.ply")).unwrap(),
    );
    let l = mesh::cotangent_laplacian(&from_obj, &LaplacianParams::default()).unwrap();
    let (offsets, rows, values) = l.disassemble();
    f64s(&dir, "laplacian_data", &[values.len()], values);
    f64s(
        &dir,
        "laplacian_indices",
        &[rows.len()],
        rows.iter().map(|&r| r as f64),
    );
    f64s(
        &dir,
        "laplacian_indptr",
        &[offsets.len()],
        offsets.iter().map(|&r| r as f64),
    );

    // Skeletons: the CMU walk, forward kinematics of frame 10.
    let bvh_path = repo().join("data/mocap-cmu/131_01.bvh");
    let bvh = read_bvh(
        &bvh_path,
        &BvhParams {
            metres_per_unit: CMU_METRES_PER_UNIT,
        },
    )
    .unwrap();
    let theta10 = bvh.motion.frame(10).to_vec();
    let fk = bvh.skeleton.forward_kinematics(&theta10).unwrap();
    let nj = bvh.skeleton.joint_count();
    f64s(
        &dir,
        "bvh_fk10",
        &[nj, 4, 4],
        fk.world_from_joint().iter().flat_map(affine_rows),
    );
    points(&dir, "bvh_joints10", &fk.joint_positions());
    js.insert("bvh_path", json!(bvh_path));
    js.insert("bvh_frames", json!(bvh.motion.frame_count()));
    js.insert("bvh_frame_time_s", json!(bvh.motion.frame_time_s));
    js.insert("bvh_metres_per_unit", json!(CMU_METRES_PER_UNIT));

    // The studio: a coarse procedural performer in fast motion, 4 cameras at 160 × 120, 3 frames.
    let performer = procedural_performer(&ProceduralBodyParams {
        grid_spacing_m: 0.04,
        ..Default::default()
    })
    .unwrap();
    let skel = via_json(&dir, "skeleton.json", &performer.skeleton);
    let motion = fast_motion(&skel, &FastMotionParams::default()).unwrap();
    let rig = studio_ring(4, 160, 120).unwrap();
    // Through JSON, as the Python side receives them (the pose inverse is recomputed there).
    let cams: Vec<Camera> = rig
        .cameras
        .iter()
        .enumerate()
        .map(|(i, c)| via_json(&dir, &format!("camera{i}.json"), c))
        .collect();
    let spec = CaptureSpec::masks_only(rig).with_frame_rate_hz(1.0 / motion.frame_time_s);
    let capture = Capture::new(&performer, &motion, spec).unwrap();
    let (mut thetas, mut masks) = (Vec::new(), Vec::new());
    for frame in capture.frames_stepped(0..30, 10) {
        let frame = frame.unwrap();
        masks.push(frame.masks());
        thetas.push(frame.truth.theta);
    }
    let dofs = skel.dof_count();
    js.insert("cameras", json!(cams.len()));
    f64s(
        &dir,
        "studio_thetas",
        &[thetas.len(), dofs],
        thetas.concat(),
    );
    u8s(
        &dir,
        "studio_masks",
        &[masks.len(), cams.len(), 120, 160],
        masks.iter().flat_map(|m| mask_bytes(m)),
    );
    mesh_files(&dir, "performer", &performer.template);

    // Skinning: the performer's weights through dense form (as a Python caller gives them),
    // posed at frame 1; bone-heat weights of the template.
    let dense = performer.weights.to_dense();
    f64s(
        &dir,
        "performer_weights",
        &[dense.nrows(), dense.ncols()],
        (0..dense.nrows()).flat_map(|i| dense.row(i).iter().copied().collect::<Vec<_>>()),
    );
    let w = SkinWeights::from_dense(&dense, 0.0, skel.joint_count()).unwrap();
    let binding = SkinBinding::new(&performer.template, &skel, &w).unwrap();
    let fk1 = skel.forward_kinematics(&thetas[1]).unwrap();
    let skinned = mesh::skin(
        &performer.template.vertices,
        &w,
        &binding.world_from_rest(fk1.world_from_joint()),
    )
    .unwrap();
    points(&dir, "lbs_frame1", &skinned);
    let heat = mesh::bone_heat_weights(
        &performer.template,
        &mesh::rest_bones(&skel).unwrap(),
        &mesh::HeatWeightsParams::default(),
    )
    .unwrap()
    .to_dense();
    f64s(
        &dir,
        "heat_weights",
        &[heat.nrows(), heat.ncols()],
        (0..heat.nrows()).flat_map(|i| heat.row(i).iter().copied().collect::<Vec<_>>()),
    );

    // needle-model: the observations of the 3 frames, N = 2, a quarter of Table 3.1's needles.
    let body = needle_model::NeedleBody::new(
        &skel,
        &needle_model::BodyLayout::table_3_1().with_density(0.25),
    )
    .unwrap();
    let observer = needle_model::Observer::new(
        body,
        skel.clone(),
        cams.clone(),
        needle_model::ObserveParams::default(),
    )
    .unwrap();
    let frames: Vec<needle_model::FrameInput<'_>> = thetas
        .iter()
        .zip(&masks)
        .map(|(theta, masks)| needle_model::FrameInput { theta, masks })
        .collect();
    let acc = observer.accumulate(&frames).unwrap();
    let params = needle_model::ReconstructionParams::default().with_prototype_count_n(2);
    let rec = needle_model::NeedleModel::reconstruct(&acc.store, observer.body(), &params).unwrap();
    let x = observer.body().primitives[0]
        .config
        .point_f32(&skel.forward_kinematics(&thetas[0]).unwrap())
        .unwrap();
    let lengths = rec.model.needle_lengths(0, &x).unwrap();
    f64s(
        &dir,
        "needle_lengths0",
        &[lengths.len()],
        lengths.iter().map(|&l| f64::from(l)),
    );
    let animated = needle_model::animate(observer.body(), &rec.model, &skel, &thetas[1]).unwrap();
    mesh_files(
        &dir,
        "needle_surface1",
        &needle_model::merged_mesh(&animated).unwrap(),
    );
    js.insert("needle_observations", json!(acc.store.total_observations()));

    // template-silhouette: the performer's template tracked through frames 0 and 1.
    let template =
        template_silhouette::Template::new(performer.template.clone(), skel.clone(), w.clone())
            .unwrap();
    let obs: Vec<_> = masks[..2]
        .iter()
        .map(|m| {
            template_silhouette::FrameObservation::new(
                &cams,
                m,
                &Default::default(),
                &Default::default(),
            )
            .unwrap()
        })
        .collect();
    let seq = template_silhouette::capture_sequence(
        &template,
        &obs,
        &thetas[0],
        &[],
        &Default::default(),
        &Default::default(),
    )
    .unwrap();
    f64s(&dir, "template_poses", &[2, dofs], seq.poses.poses.concat());
    f64s(
        &dir,
        "template_vertices",
        &[2, template.vertex_count(), 3],
        seq.shapes
            .frames
            .iter()
            .flatten()
            .flat_map(|p| p.to_array()),
    );
    // Deformation transfer: a bulge edit carried onto the frame-1 pose.
    let edited: Vec<DVec3> = performer
        .template
        .vertices
        .iter()
        .map(|v| *v + DVec3::new(0.02 * v.y, 0.0, 0.0))
        .collect();
    points(&dir, "transfer_edited", &edited);
    let dt = template_silhouette::DeformationTransfer::new(&performer.template, &edited).unwrap();
    points(&dir, "transfer_frame1", &dt.transfer(&skinned).unwrap());

    // photometric-normals: the crate's quick start (a grey sphere under a small dome, 64 × 64).
    let pk = Intrinsics::from_horizontal_fov(0.2, 64, 64).unwrap();
    let pcam = Camera::look_at(
        pk,
        DVec3::new(0.0, 1.0, 3.0),
        DVec3::new(0.0, 1.0, 0.0),
        DVec3::Y,
    )
    .unwrap();
    let pcam = via_json(&dir, "photo_camera.json", &pcam);
    let photograph_with = |cam: &Camera, s: &CalibrationSphere| -> Vec<f32> {
        let (images, _) = small_dome_sphere(cam, s).unwrap();
        PATTERNS
            .iter()
            .flat_map(|&p| images.image(p).as_raw().clone())
            .collect()
    };
    let images_of = |raw: &[f32]| {
        let list = PATTERNS
            .iter()
            .enumerate()
            .map(|(i, &p)| {
                (
                    p,
                    skin_core::image::GrayF32Image::from_raw(
                        64,
                        64,
                        raw[i * 4096..(i + 1) * 4096].to_vec(),
                    )
                    .unwrap(),
                )
            })
            .collect();
        PatternImages::new(list).unwrap()
    };
    let sphere = CalibrationSphere {
        centre: DVec3::new(0.0, 1.0, 0.0),
        radius_m: 0.2,
    };
    let probe = CalibrationSphere {
        radius_m: 0.15,
        ..sphere
    };
    let (raw_sphere, raw_probe) = (
        photograph_with(&pcam, &sphere),
        photograph_with(&pcam, &probe),
    );
    // The overhead benchmark's inputs (benches/overhead.*): the same scene at 256 × 256.
    let big = Intrinsics::from_horizontal_fov(0.2, 256, 256).unwrap();
    let big = Camera::look_at(
        big,
        DVec3::new(0.0, 1.0, 3.0),
        DVec3::new(0.0, 1.0, 0.0),
        DVec3::Y,
    )
    .unwrap();
    let big = via_json(&dir, "overhead_camera.json", &big);
    f64s(
        &dir,
        "overhead_sphere_images",
        &[7, 256, 256],
        photograph_with(&big, &sphere).iter().map(|&v| f64::from(v)),
    );
    f64s(
        &dir,
        "overhead_probe_images",
        &[7, 256, 256],
        photograph_with(&big, &probe).iter().map(|&v| f64::from(v)),
    );
    f64s(
        &dir,
        "photo_sphere_images",
        &[7, 64, 64],
        raw_sphere.iter().map(|&v| f64::from(v)),
    );
    f64s(
        &dir,
        "photo_probe_images",
        &[7, 64, 64],
        raw_probe.iter().map(|&v| f64::from(v)),
    );
    let table = LookupTable::from_sphere(
        &pcam,
        &sphere,
        &images_of(&raw_sphere),
        DVec3::Y,
        &CalibrationParams::default(),
    )
    .unwrap();
    let calibration = HeightCalibration::new(vec![table]).unwrap();
    let map = estimate_normals(
        &pcam,
        &calibration,
        &images_of(&raw_probe),
        None,
        &NormalParams::default(),
    )
    .unwrap();
    f64s(
        &dir,
        "photo_normals",
        &[64, 64, 3],
        map.normals.iter().flat_map(|n| n.to_array()),
    );
    u8s(
        &dir,
        "photo_valid",
        &[64, 64],
        map.valid.iter().map(|&v| u8::from(v)),
    );
    // Integration near a flat proxy 2.85 m away (the probe's front).
    let proxy: Vec<f64> = map
        .valid
        .iter()
        .map(|&v| if v { 2.85 } else { f64::NAN })
        .collect();
    f64s(&dir, "photo_proxy", &[64, 64], proxy.iter().copied());
    let depth = integrate_normals(
        &pcam,
        &map,
        &DepthMap::new(64, 64, proxy).unwrap(),
        None,
        &IntegrationParams::default(),
    )
    .unwrap();
    f64s(
        &dir,
        "photo_depth",
        &[64, 64],
        depth.depth.depth_m.iter().copied(),
    );
    // The visual hull's depth maps of the studio's frame 0.
    let hull = PolygonalHull::new(&cams, &masks[0])
        .unwrap()
        .depth_maps(&Default::default())
        .unwrap();
    f64s(
        &dir,
        "hull_depths0",
        &[cams.len(), 120, 160],
        hull.iter().flat_map(|d| d.depth_m.iter().copied()),
    );

    // inertial-acoustic: BROAD trial 07 through the one-board filter; a simulated suit
    // recording through the pipeline.
    let broad = repo().join("data/imu-broad/07_undisturbed_fast_rotation_B_first60s.hdf5");
    let log = inertial_acoustic::imu_log::read_broad_hdf5(&broad).unwrap();
    let fp = inertial_acoustic::FilterParams {
        process_sigma: 4.0,
        accelerometer_sigma: 5.0,
        gyroscope_sigma: 0.002,
        ..Default::default()
    };
    let run = inertial_acoustic::imu_log::run_orientation(&log, fp, 20.0).unwrap();
    f64s(
        &dir,
        "broad_orientation",
        &[run.orientation.len(), 4],
        run.orientation.iter().flat_map(|q| q.to_array()),
    );
    let err = inertial_acoustic::heading_inclination_rmse(
        &run.orientation,
        &log.reference,
        &log.movement,
        DVec3::Z,
    )
    .unwrap();
    js.insert("broad_path", json!(broad));
    js.insert("broad_inclination_deg", json!(err.inclination_deg));
    js.insert("broad_heading_deg", json!(err.heading_deg));
    let human = skin_core::skeleton::human_skeleton(&Default::default()).unwrap();
    let sim_params = SimulationParams::default();
    let sim = SuitSimulator::new(&human, sim_params).unwrap();
    let cal = sim.calibrate_offsets(3).unwrap();
    let exercise =
        exercise_motion(&human, &ExerciseParams::default().with_duration_s(8.0)).unwrap();
    let smooth = prepare_motion(&human, &exercise, &sim_params).unwrap();
    let recorded = sim.record(&smooth, &cal.offsets).unwrap().recording;
    recorded.write(dir.join("recording"), &human).unwrap();
    let pipe = inertial_acoustic::pipeline::run(&human, &recorded, &Default::default()).unwrap();
    f64s(
        &dir,
        "pipeline_theta",
        &[pipe.theta.len(), human.dof_count()],
        pipe.theta.concat(),
    );
    f64s(&dir, "pipeline_mean_nis", &[3], pipe.mean_nis());

    // multilinear-face: the crate's quick start (2 expressions × 3 people, 20 vertices).
    let face = |e: f64, i: f64| -> Vec<DVec3> {
        (0..20)
            .map(|k| {
                let k = k as f64;
                DVec3::new(
                    k,
                    (0.3 * k).sin() * (1.0 + 0.5 * i),
                    e * (0.2 * k).cos() * (1.0 + 0.3 * i),
                )
            })
            .collect()
    };
    let faces: Vec<Vec<DVec3>> = (0..6)
        .map(|f| face((f / 3) as f64, (f % 3) as f64))
        .collect();
    f64s(
        &dir,
        "face_data",
        &[6, 20, 3],
        faces.iter().flatten().flat_map(|p| p.to_array()),
    );
    let data = multilinear_face::FaceTensor::from_faces(&[2, 3], &faces).unwrap();
    let (model, fit) = multilinear_face::MultilinearModel::fit(
        &data,
        &multilinear_face::ModelParams::new(&[2, 3]),
    )
    .unwrap();
    js.insert("face_hooi_rel_error", json!(fit.hooi_rel_error));
    js.insert("face_hosvd_rel_error", json!(fit.hosvd_rel_error));
    for m in 0..2 {
        let f = model.factor(m).unwrap();
        f64s(
            &dir,
            &format!("face_factor{m}"),
            &[f.nrows(), f.ncols()],
            (0..f.nrows()).flat_map(|i| f.row(i).iter().copied().collect::<Vec<_>>()),
        );
    }
    let wts = [
        model.training_weights(0, 1).unwrap(),
        model.training_weights(1, 2).unwrap(),
    ];
    points(&dir, "face_synth", &model.face(&wts).unwrap());
    let known =
        multilinear_face::KnownFaces::new(&[2, 3], vec![true, true, true, false, true, true])
            .unwrap();
    let filled = multilinear_face::impute(&data, &known, &Default::default())
        .unwrap()
        .faces;
    f64s(
        &dir,
        "face_imputed",
        &[6, 20, 3],
        (0..6)
            .flat_map(|f| filled.face(f).unwrap())
            .flat_map(|p| p.to_array()),
    );
    let tracked: Vec<usize> = (0..20).collect();
    let pixels: Vec<[f64; 2]> = faces[5]
        .iter()
        .map(|p| [100.0 + 2.0 * p.x, 50.0 + 2.0 * p.y])
        .collect();
    let frames = vec![pixels; 3];
    f64s(
        &dir,
        "face_tracks",
        &[3, 20, 2],
        frames.iter().flatten().flatten().copied(),
    );
    let track = multilinear_face::track_points(
        &model,
        &tracked,
        &frames,
        &[false, true],
        &Default::default(),
    )
    .unwrap();
    f64s(
        &dir,
        "face_track_rms",
        &[3],
        track.reprojection_rms_px.iter().copied(),
    );
    for m in 0..2 {
        let r = model.ranks()[m];
        f64s(
            &dir,
            &format!("face_track_weights{m}"),
            &[3, r],
            track.weights.iter().flat_map(|w| w[m].as_slice().to_vec()),
        );
    }

    // Video tracking: a person outside the training set rendered over 4 frames (the
    // validation's face video), tracked by the thesis's 6 × 9 model of the bilinear set.
    {
        use multilinear_face::validation::{IctBasis, TrackingScenario};
        let basis = IctBasis::read(repo().join("data/ict-face")).unwrap();
        let scenario = TrackingScenario::new(basis, 300).unwrap();
        let video = scenario.video(&[0, 1, 3, 0], 4, 12).unwrap();
        let TrackingScenario {
            training: bi,
            model,
            tracked,
            ..
        } = scenario;
        let (w, h) = video.frames[0].dimensions();
        u8s(
            &dir,
            "video_frames",
            &[4, h as usize, w as usize, 3],
            video.frames.iter().flat_map(|f| f.as_raw().clone()),
        );
        js.insert("video_tracked", json!(tracked));
        js.insert("video_feature_vertices", json!(video.features.vertices));
        f64s(
            &dir,
            "video_feature_pixels",
            &[video.features.pixels.len(), 2],
            video.features.pixels.iter().flatten().copied(),
        );
        let track = multilinear_face::track_video(
            &model,
            &bi.triangles,
            &tracked,
            &video.frames,
            &video.features,
            &[false, true],
            &Default::default(),
        )
        .unwrap();
        f64s(
            &dir,
            "video_tracked_fraction",
            &[4],
            track.tracked_fraction.iter().copied(),
        );
        f64s(
            &dir,
            "video_rms",
            &[4],
            track.reprojection_rms_px.iter().copied(),
        );
        // Face transfer: frame 0's colours lifted onto its tracked face, rendered as frame 2's
        // face under frame 2's camera over frame 2.
        let (f0, f2) = (
            model.face(&track.weights[0]).unwrap(),
            model.face(&track.weights[2]).unwrap(),
        );
        points(&dir, "transfer_source_face", &f0);
        points(&dir, "transfer_target_face", &f2);
        for (name, c) in [("source", &track.cameras[0]), ("target", &track.cameras[2])] {
            f64s(
                &dir,
                &format!("transfer_{name}_camera"),
                &[9],
                [
                    c.scale,
                    c.rows[0][0],
                    c.rows[0][1],
                    c.rows[0][2],
                    c.rows[1][0],
                    c.rows[1][1],
                    c.rows[1][2],
                    c.translation[0],
                    c.translation[1],
                ],
            );
        }
        u32s(
            &dir,
            "video_triangles",
            &[bi.triangles.len(), 3],
            bi.triangles.iter().flatten().copied(),
        );
        let texture =
            multilinear_face::lift_texture(&f0, &bi.triangles, &track.cameras[0], &video.frames[0])
                .unwrap();
        let out = multilinear_face::render_textured(
            &f2,
            &bi.triangles,
            &track.cameras[2],
            &texture,
            &video.frames[2],
        )
        .unwrap();
        u8s(
            &dir,
            "transfer_rendered",
            &[h as usize, w as usize, 3],
            out.into_raw(),
        );
    }

    std::fs::write(
        dir.join("fixtures.json"),
        serde_json::to_string_pretty(&js).unwrap(),
    )
    .unwrap();
}
