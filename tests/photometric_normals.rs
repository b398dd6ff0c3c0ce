//! End-to-end validation of photometric-normals (Vlasic thesis §3.2) on the studio, CI-sized:
//! the MakeHuman performer in the skirt with the albedo texture (no render-time wrinkles: their
//! refined surface makes the shadow rays 4× slower; the example scores them), under the
//! 1,200-light dome with cast shadows and the camera model's noise (`SensorNoise`); two cameras at 256 × 256 calibrated with grey spheres at
//! 7 heights; one static frame rendered under the seven conditions through `Capture`. Normals
//! are scored against the rasteriser's true normals, outside and inside shadowed concavities,
//! and against the distant-light baseline (the analytic solution of the same images).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

use std::time::Instant;

use dynamic_shapes::core::camera::Camera;
use dynamic_shapes::core::camera::{Intrinsics, Rig};
use dynamic_shapes::core::image::Mask;
use dynamic_shapes::core::math::DVec3;
use dynamic_shapes::photometric::truth::{
    angular_errors_deg, calibrate_camera, colour_scores, distant_light_normals,
    dome_power_fraction, pattern_images, render_sphere_patterns, silhouette_scores, skirt_subject,
    small_dome_sphere, summarize, GreenScreen, LightStage, SensorNoise, StudioScene,
};
use dynamic_shapes::photometric::{
    estimate_normals, estimate_normals_on_proxy, extract_silhouette, macbeth_reference, Backdrop,
    CalibrationParams, CalibrationSphere, ColourParams, ColourTransfer, DepthMap, Error, Exposure,
    HeightCalibration, LookupTable, NormalMap, NormalParams, Pattern, PatternImages,
    SilhouetteParams, PATTERNS,
};
use dynamic_shapes_studio::{makehuman_performer, Capture, PatternSchedule};

/// Linear intensity at which the cameras saturate (the exposure of the capture).
const WHITE_LEVEL: f32 = 0.4;

/// The cameras' sensor (`SensorNoise` defaults at the capture's exposure).
fn sensor() -> SensorNoise {
    SensorNoise::default().with_white_level(WHITE_LEVEL)
}

#[test]
fn photometric_normals_of_a_static_frame_beat_the_distant_light_baseline() {
    let t0 = Instant::now();
    let scene = StudioScene::new(
        example_kit::data_path("makehuman").unwrap(),
        &skirt_subject(),
        2,
        256,
    )
    .unwrap();
    let (performer, light_stage, root) = (&scene.performer, &scene.stage, scene.root);
    let heights = light_stage.sphere_heights_m();
    let (centre, lights) = (light_stage.centre, &light_stage.lights);
    let cameras = scene.ring.cameras.clone();
    let mut spec = scene.capture_spec(scene.ring.clone()).unwrap();
    // The camera model (shot + read noise, 10 bits) replaces the studio's flat noise.
    spec.noise = None;
    let mut frame = scene.capture(spec).unwrap();
    for (c, obs) in frame.observations.iter_mut().enumerate() {
        for (p, im) in obs.patterns.iter_mut().enumerate() {
            sensor().apply(im, (8 * c + p) as u64).unwrap();
        }
    }
    let t_capture = t0.elapsed().as_secs_f64();

    let (exposure, cal_params, params) = scene.photometric_params(WHITE_LEVEL);
    let mesh = frame.truth.rendered_mesh(performer);
    let (mut err, mut base, mut concave, mut body) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut valid = (0usize, 0usize);
    for (c, cam) in cameras.iter().enumerate() {
        let t = Instant::now();
        let cal = scene.calibrate(cam, &cal_params).unwrap();
        let t_cal = t.elapsed().as_secs_f64();
        let obs = &frame.observations[c];
        let images = pattern_images(obs).unwrap();
        let t = Instant::now();
        let map = estimate_normals(cam, &cal, &images, Some(&obs.mask), &params).unwrap();
        let t_normals = t.elapsed().as_secs_f64();
        let baseline = distant_light_normals(cam, &images, &exposure).unwrap();
        let view = &frame.truth.views[c];
        let truth = view.normals_camera.as_ref().unwrap();
        err.extend(angular_errors_deg(&map, truth).unwrap());
        base.extend(angular_errors_deg(&baseline, truth).unwrap());
        let power = dome_power_fraction(
            view,
            &mesh,
            lights,
            frame.light_visibility.as_ref().unwrap(),
        )
        .unwrap();
        concave.extend(power.iter().map(|&p| p < 0.9));
        body.extend(obs.mask.iter());
        valid.0 += map
            .valid
            .iter()
            .zip(obs.mask.iter())
            .filter(|(v, m)| **v && *m)
            .count();
        valid.1 += obs.mask.count();
        println!(
            "camera {c}: calibration {t_cal:.2} s, normals {:.0} ms",
            t_normals * 1e3
        );
    }
    let open: Vec<bool> = body.iter().zip(&concave).map(|(b, c)| *b && !c).collect();
    let shadowed: Vec<bool> = body.iter().zip(&concave).map(|(b, c)| *b && *c).collect();
    let (e_open, e_shadow) = (
        summarize(&err, Some(&open)),
        summarize(&err, Some(&shadowed)),
    );
    let b_open = summarize(&base, Some(&open));
    let valid_fraction = valid.0 as f64 / valid.1 as f64;
    println!(
        "capture {t_capture:.1} s; outside concavities median {:.2}° mean {:.2}° ({} px), \
         inside median {:.2}° mean {:.2}° ({} px), \
         baseline outside median {:.2}° mean {:.2}°, valid {valid_fraction:.3}, total {:.1} s",
        e_open.median_deg,
        e_open.mean_deg,
        e_open.pixels,
        e_shadow.median_deg,
        e_shadow.mean_deg,
        e_shadow.pixels,
        b_open.median_deg,
        b_open.mean_deg,
        t0.elapsed().as_secs_f64()
    );
    assert!(e_open.pixels > 2000 && e_shadow.pixels > 100);
    // The static goal is 3° (not met: partial shadowing and the lookup itself, see
    // docs/photometric-normals.md); this bounds the measured ~4° with a margin.
    assert!(e_open.median_deg <= 6.0);
    assert!(
        e_open.median_deg < b_open.median_deg && e_open.mean_deg < b_open.mean_deg,
        "the calibration beats the distant-light baseline"
    );
    assert!(
        e_shadow.median_deg > e_open.median_deg,
        "concavities carry the bias of missing light"
    );
    assert!(valid_fraction > 0.8);

    // Silhouettes (§3.2.1) of the full-on frame over a green screen with the performer's
    // shadow: background subtraction + chroma key + statistical hole filling against the
    // true mask, and the two baselines (subtraction alone, a grey-level threshold).
    let t = Instant::now();
    let screen = GreenScreen::default();
    let sil_params = SilhouetteParams::default();
    for (c, obs) in frame.observations.iter().enumerate() {
        let full = &obs.patterns[3];
        let s = silhouette_scores(&screen, full, &obs.mask, 4, &sil_params, 10 + c as u64).unwrap();
        println!(
            "camera {c}: silhouette IoU {:.4} (subtraction only {:.4}, grey threshold {:.4}); \
             keyed {} px, holes filled {} kept {}",
            s.iou,
            s.iou_subtraction_only,
            s.iou_grey_threshold,
            s.silhouette.keyed_px,
            s.silhouette.holes_filled,
            s.silhouette.holes_kept
        );
        assert!(s.iou >= 0.97, "silhouette IoU {}", s.iou);
        assert!(s.iou > s.iou_subtraction_only + 0.05);
        assert!(s.iou > s.iou_grey_threshold + 0.05);
    }
    // Bad input: a frame of another size, a NaN sample.
    let backdrop = Backdrop::learn(&[screen.plate(256, 256, 1)], &sil_params).unwrap();
    let small = screen.plate(128, 256, 2);
    assert!(matches!(
        extract_silhouette(&backdrop, &small, &sil_params).map_err(|e| e.root().to_string()),
        Err(m) if m.contains("size mismatch")
    ));
    let mut nan = screen.plate(256, 256, 3);
    nan.put_pixel(10, 10, image::Rgb([f32::NAN, 0.0, 0.0]));
    assert!(extract_silhouette(&backdrop, &nan, &sil_params).is_err());
    println!("silhouettes {:.2} s", t.elapsed().as_secs_f64());

    // Photometric calibration: each camera sees a Macbeth chart through its own colour
    // response; the fitted transfer matrix must undo it on the studio's full-on image, far
    // better than white balance from the chart's white patch (a diagonal matrix).
    for (c, obs) in frame.observations.iter().enumerate() {
        let s = colour_scores(&obs.patterns[3], &obs.mask, 100 + c as u64).unwrap();
        println!(
            "camera {c}: colour matrix recovery ‖M·A − I‖ = {:.2e}; image RMS {:.2e} \
             (white balance {:.2e}, uncorrected {:.2e})",
            s.recovery, s.rms_matrix, s.rms_white_balance, s.rms_uncorrected
        );
        assert!(s.recovery < 5e-3, "{s:?}");
        assert!(s.rms_matrix < 0.2 * s.rms_white_balance, "{s:?}");
        assert!(s.rms_white_balance < s.rms_uncorrected, "{s:?}");
    }
    let chart = macbeth_reference();
    let greys: Vec<[f64; 3]> = chart[18..].to_vec();
    assert!(ColourTransfer::fit(&greys, &greys, &ColourParams::default()).is_err());
    assert!(ColourTransfer::fit(&chart[..2], &chart[..2], &ColourParams::default()).is_err());

    // Bad input on the same set-up.
    let cam = &cameras[0];
    let out = CalibrationSphere {
        // On the top edge of the image (half field of view 20° at 3 m: 1.09 m).
        centre: cam
            .world_from_camera()
            .transform_point3(DVec3::new(0.0, -1.09, 3.0)),
        radius_m: 0.2,
    };
    let im = render_sphere_patterns(cam, &out, lights, centre, 0.5).unwrap();
    let e = LookupTable::from_sphere(cam, &out, &im, DVec3::Y, &cal_params).unwrap_err();
    assert!(matches!(e.root(), Error::OutOfView { .. }), "{e}");
    let obs = &frame.observations[0];
    let missing = PatternImages::from_rgb(
        &PATTERNS
            .iter()
            .zip(&obs.patterns)
            .filter(|(p, _)| **p != Pattern::YBar)
            .map(|(&p, im)| (p, im))
            .collect::<Vec<_>>(),
    );
    assert!(matches!(
        missing,
        Err(Error::MissingPattern {
            pattern: Pattern::YBar
        })
    ));
    let wrong_mask = Mask::new(128, 128);
    let images = PatternImages::from_rgb(
        &PATTERNS
            .iter()
            .zip(&obs.patterns)
            .map(|(&p, im)| (p, im))
            .collect::<Vec<_>>(),
    )
    .unwrap();
    let cal = calibrate_camera(
        cam,
        lights,
        centre,
        root,
        &heights[..2],
        0.2,
        0.5,
        &cal_params,
    )
    .unwrap();
    assert!(matches!(
        estimate_normals(cam, &cal, &images, Some(&wrong_mask), &params),
        Err(Error::SizeMismatch { .. })
    ));
    // Over-exposed (the sensor clips at a quarter of the capture's white level) and black
    // captures: saturated or dark pixels are marked invalid rather than given a normal.
    let clip = WHITE_LEVEL / 4.0;
    let scaled = |f: &dyn Fn(f32) -> f32| {
        PatternImages::new(
            PATTERNS
                .iter()
                .map(|&p| {
                    let mut im = images.image(p).clone();
                    im.pixels_mut().for_each(|v| v[0] = f(v[0]));
                    (p, im)
                })
                .collect(),
        )
        .unwrap()
    };
    let clipped = scaled(&|v| v.min(clip));
    let p = params.with_exposure(Exposure::default().with_white_level(clip));
    let map = estimate_normals(cam, &cal, &clipped, Some(&obs.mask), &p).unwrap();
    let mut saturated = 0;
    for (i, m) in obs.mask.iter().enumerate() {
        let brightest = PATTERNS
            .iter()
            .map(|&p| images.image(p).as_raw()[i])
            .fold(0.0f32, f32::max);
        if m && brightest >= 0.97 * clip {
            saturated += 1;
            assert!(!map.valid[i], "saturated pixel {i} got a normal");
        }
    }
    assert!(saturated > 1000, "{saturated} saturated pixels");
    assert!(
        map.valid.iter().any(|&v| v),
        "unsaturated pixels keep their normals"
    );
    let black = scaled(&|_| 0.0);
    let map = estimate_normals(cam, &cal, &black, Some(&obs.mask), &params).unwrap();
    assert_eq!(map.valid_fraction(None).unwrap(), 0.0);
}

#[test]
fn motion_compensation_recovers_normals_of_a_moving_performer() {
    use dynamic_shapes::photometric::{
        compensate_motion, grey, MotionParams, CYCLE, CYCLE_FRAME_RATE_HZ,
    };
    use dynamic_shapes_studio::{fast_motion, FastMotionParams};
    let performer = makehuman_performer(
        example_kit::data_path("makehuman").unwrap(),
        &skirt_subject(),
    )
    .unwrap();
    let motion = fast_motion(&performer.skeleton, &FastMotionParams::default()).unwrap();
    let root = performer
        .skeleton
        .forward_kinematics(motion.frame(0))
        .unwrap()
        .joint_positions()[0];
    let light_stage = LightStage::around(&performer.template, root).unwrap();
    let heights = light_stage.sphere_heights_m();
    let (floor_y, centre, lights) = (light_stage.floor_y, light_stage.centre, &light_stage.lights);
    let k = Intrinsics::from_horizontal_fov(40f64.to_radians(), 256, 256).unwrap();
    let rig = Rig::ring(1, 3.5, floor_y + 1.7, root, DVec3::Y, k).unwrap();
    let cam = rig.cameras[0].clone();
    let mut spec = light_stage
        .capture_spec(rig, CYCLE_FRAME_RATE_HZ, PatternSchedule::Cycle)
        .unwrap();
    spec.noise = None;
    let capture = Capture::new(&performer, &motion, spec).unwrap();
    // Frames 75–83: F X̄ Ȳ Z̄ F X Y Z F around the tracking frame 79.
    let mut frames: Vec<_> = capture.frames_in(75..84).map(|f| f.unwrap()).collect();
    for f in &mut frames {
        let im = f.observations[0].shaded.as_mut().unwrap();
        sensor().apply(im, f.index as u64).unwrap();
    }
    let exposure = Exposure::default().with_white_level(WHITE_LEVEL);
    let cal_params = CalibrationParams {
        exposure,
        ..Default::default()
    };
    let cal =
        calibrate_camera(&cam, lights, centre, root, &heights, 0.2, 0.5, &cal_params).unwrap();
    let params = NormalParams::default()
        .with_exposure(exposure)
        .with_performance_centre(root);
    let greys: Vec<_> = frames
        .iter()
        .map(|f| grey(f.observations[0].shaded.as_ref().unwrap()))
        .collect();
    let pairs: Vec<_> = (75..84).map(|k| CYCLE[k % 8]).zip(greys.iter()).collect();
    let c = compensate_motion(&pairs, &MotionParams::default()).unwrap();
    let mid = &frames[4];
    let mask = mid.observations[0].mask.and(&c.confident).unwrap();
    let truth = mid.truth.views[0].normals_camera.as_ref().unwrap();
    let compensated = estimate_normals(&cam, &cal, &c.images, Some(&mask), &params).unwrap();
    let raw = PatternImages::new(
        pairs[1..8]
            .iter()
            .map(|(p, im)| (*p, (*im).clone()))
            .collect(),
    )
    .unwrap();
    let uncompensated = estimate_normals(&cam, &cal, &raw, Some(&mask), &params).unwrap();
    let e_c = summarize(&angular_errors_deg(&compensated, truth).unwrap(), None);
    let e_u = summarize(&angular_errors_deg(&uncompensated, truth).unwrap(), None);
    println!(
        "moving: compensated median {:.2}° ({} px), uncompensated {:.2}° ({} px)",
        e_c.median_deg, e_c.pixels, e_u.median_deg, e_u.pixels
    );
    assert!(e_c.pixels > 1000);
    assert!(e_c.median_deg <= 9.0);
    assert!(
        e_u.median_deg >= 1.5 * e_c.median_deg,
        "without compensation at least 1.5× worse"
    );
}

/// A camera 5 m above the dome's floor centre looking straight down, calibrated with grey
/// spheres at two heights under the axis, and a probe sphere at `probe_y`: its pattern
/// images and rendered depth along the pixel rays.
fn top_camera_probe(probe_y: f64) -> (Camera, HeightCalibration, PatternImages, DepthMap) {
    let k = Intrinsics::from_horizontal_fov(0.15, 64, 64).unwrap();
    let cam = Camera::look_at(k, DVec3::new(0.0, 5.0, 0.0), DVec3::ZERO, DVec3::Z).unwrap();
    let render = |s: &CalibrationSphere| small_dome_sphere(&cam, s).unwrap();
    let tables = [0.6, 1.4]
        .iter()
        .map(|&y| {
            let sphere = CalibrationSphere {
                centre: DVec3::new(0.0, y, 0.0),
                radius_m: 0.2,
            };
            let (images, _) = render(&sphere);
            LookupTable::from_sphere(
                &cam,
                &sphere,
                &images,
                DVec3::Y,
                &CalibrationParams::default(),
            )
            .unwrap()
        })
        .collect();
    let calibration = HeightCalibration::new(tables).unwrap();
    let (images, depth) = render(&CalibrationSphere {
        centre: DVec3::new(0.0, probe_y, 0.0),
        radius_m: 0.15,
    });
    (cam, calibration, images, depth)
}

#[test]
fn a_camera_above_the_centre_gets_normals_only_on_a_proxy() {
    let (cam, calibration, images, depth) = top_camera_probe(1.4);
    let params = NormalParams::default().with_performance_centre(DVec3::new(0.0, 1.0, 0.0));
    let plane = estimate_normals(&cam, &calibration, &images, None, &params).unwrap();
    let on_proxy =
        estimate_normals_on_proxy(&cam, &calibration, &images, None, &depth, &params).unwrap();
    let count = |m: &NormalMap| m.valid.iter().filter(|&&v| v).count();
    // The plane through the centre facing a camera above it does not exist.
    assert_eq!(count(&plane), 0);
    // The probe covers a disc of about 18 px radius; its top faces the camera (−z).
    assert!(count(&on_proxy) > 500, "{}", count(&on_proxy));
    let centre_normal = on_proxy.normals[32 * 64 + 32];
    assert!(centre_normal.z < -0.99, "{centre_normal}");
    let bad = DepthMap::empty(32, 32).unwrap();
    assert!(matches!(
        estimate_normals_on_proxy(&cam, &calibration, &images, None, &bad, &params),
        Err(Error::InvalidParam { .. })
    ));
}
