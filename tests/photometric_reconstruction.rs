//! Per-view surfaces of photometric-normals part 2 (Vlasic thesis §3.3.1–§3.3.2) on the
//! studio, CI-sized: the MakeHuman performer in the skirt seen by a ring of 8 cameras at
//! 256 × 256. The visual hull of the 8 silhouettes is rendered per camera as the proxy; each
//! view's normals are integrated by Eq. 3.3 — exact normals (the rasteriser's, turned to face
//! the camera as a measurement is) on all 8 views, and normals estimated by part 1 from the
//! light stage's half-on images on two neighbouring views — and scored against the true depth
//! maps beside the proxy alone (the baseline that could win).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

use std::time::Instant;

use dynamic_shapes::core::camera::{Camera, Intrinsics, Rig};
use dynamic_shapes::core::image::Mask;
use dynamic_shapes::core::math::{DVec2, DVec3};
use dynamic_shapes::core::mesh::TriMesh;
use dynamic_shapes::core::raster::{Rasterizer, RenderParams, RenderedView};
use dynamic_shapes::core::studio::{
    exercise_motion, makehuman_performer, Capture, DeformationParams, ExerciseParams,
    GarmentParams, PatternSchedule, SkirtParams,
};
use dynamic_shapes::photometric::truth::{calibrate_camera, LightStage};
use dynamic_shapes::photometric::{
    depth_errors, estimate_normals, integrate_normals, CalibrationParams, DepthErrors, DepthMap,
    Exposure, IntegrationParams, NormalMap, NormalParams, PatternImages, VisualHull,
    VisualHullParams, PATTERNS,
};

/// Linear intensity at which the cameras saturate (the exposure of the capture).
const WHITE_LEVEL: f32 = 0.4;
const CAMERAS: usize = 8;
const SIZE: u32 = 256;

/// The true view of `mesh` by `camera` (both faces: the skirt is open).
fn render(camera: &Camera, mesh: &TriMesh) -> RenderedView {
    Rasterizer::new(camera)
        .render(mesh, &RenderParams::default().with_cull_back_faces(false))
        .unwrap()
}

/// The rasteriser's normals as a measured normal map: unit, facing the camera.
fn exact_normals(camera: &Camera, view: &RenderedView) -> NormalMap {
    let mut normals = Vec::with_capacity(view.pixel_count());
    for y in 0..view.height {
        for x in 0..view.width {
            let n = view.normal_camera[view.index(x, y)];
            let n = DVec3::new(f64::from(n[0]), f64::from(n[1]), f64::from(n[2]));
            let ray = camera.ray(DVec2::new(f64::from(x), f64::from(y))).unwrap();
            let r = camera.camera_from_world().transform_vector3(ray.direction);
            normals.push(if n.dot(r) > 0.0 { -n } else { n });
        }
    }
    NormalMap {
        width: view.width,
        height: view.height,
        normals,
        valid: view.mask.iter().map(|&m| m > 0).collect(),
    }
}

fn pooled(errors: &[DepthErrors]) -> (f64, f64) {
    let n: usize = errors.iter().map(|e| e.pixels).sum();
    let w = |f: fn(&DepthErrors) -> f64| {
        errors.iter().map(|e| f(e) * e.pixels as f64).sum::<f64>() / n as f64
    };
    (w(|e| e.median_mm), w(|e| e.p95_mm))
}

#[test]
fn integrated_views_beat_the_visual_hull_with_exact_and_estimated_normals() {
    let t0 = Instant::now();
    let performer = makehuman_performer(
        example_kit::data_path("makehuman").unwrap(),
        &DeformationParams::default()
            .with_flap(None)
            .with_garment(Some(GarmentParams::Skirt(SkirtParams::default()))),
    )
    .unwrap();
    let motion = exercise_motion(&performer.skeleton, &ExerciseParams::default()).unwrap();
    let frame_index = 45;
    let root = performer
        .skeleton
        .forward_kinematics(motion.frame(frame_index))
        .unwrap()
        .joint_positions()[0];
    let stage = LightStage::around(&performer.template, root).unwrap();
    let k = Intrinsics::from_horizontal_fov(40f64.to_radians(), SIZE, SIZE).unwrap();
    let ring = Rig::ring(CAMERAS, 3.5, stage.floor_y + 1.7, root, DVec3::Y, k).unwrap();
    // The light stage photographs two neighbouring views (45° apart) for part 1's normals.
    let photographed = Rig {
        cameras: ring.cameras[..2].to_vec(),
    };
    let spec = stage
        .capture_spec(
            photographed,
            1.0 / motion.frame_time_s,
            PatternSchedule::AllEachFrame,
        )
        .unwrap();
    let capture = Capture::new(&performer, &motion, spec).unwrap();
    let frame = capture
        .frames_in(frame_index..frame_index + 1)
        .next()
        .unwrap()
        .unwrap();
    let mesh = frame.truth.rendered_mesh(&performer);
    let views: Vec<RenderedView> = ring.cameras.iter().map(|c| render(c, &mesh)).collect();
    let t_capture = t0.elapsed().as_secs_f64();

    // Proxy: the visual hull of the 8 silhouettes.
    let t = Instant::now();
    let silhouettes: Vec<Mask> = views.iter().map(RenderedView::silhouette).collect();
    let hull = VisualHull::new(&ring.cameras, &silhouettes).unwrap();
    let proxies = hull.depth_maps(&VisualHullParams::default()).unwrap();
    let t_hull = t.elapsed().as_secs_f64();
    let truths: Vec<DepthMap> = views
        .iter()
        .map(|v| DepthMap::from_view(v).unwrap())
        .collect();

    // Exact normals on all views.
    let env = |k: &str, d: f64| std::env::var(k).ok().and_then(|v| v.parse().ok()).unwrap_or(d);
    let params = IntegrationParams {
        alpha: env("PR_ALPHA", 1e-6),
        proxy_jump_m: env("PR_JUMP", 0.05),
        refit_scale: env("PR_REFIT", 1.0) > 0.5,
        ..IntegrationParams::default()
    };
    let (mut ours, mut base) = (Vec::new(), Vec::new());
    let mut solve_ms = 0.0;
    let (mut integrated_px, mut measured_px) = (0usize, 0usize);
    for (c, cam) in ring.cameras.iter().enumerate() {
        let normals = exact_normals(cam, &views[c]);
        let tb = std::env::var("PR_TRUEBREAKS").ok().and_then(|v| v.parse::<f64>().ok()).map(|j| dynamic_shapes::photometric::depth_jumps(&truths[c], j).unwrap());
        let out = integrate_normals(cam, &normals, &proxies[c], tb.as_ref(), &params).unwrap();
        solve_ms += out.report.solve_ms;
        integrated_px += out.depth.valid_count();
        measured_px += normals.valid.iter().filter(|&&v| v).count();
        // Scored where the result, the proxy and the truth all have a surface.
        let both: Vec<bool> = proxies[c].depth_m.iter().map(|d| !d.is_nan()).collect();
        let e = depth_errors(&out.depth, &truths[c], Some(&both)).unwrap();
        let region: Vec<bool> = out.depth.depth_m.iter().map(|d| !d.is_nan()).collect();
        let b = depth_errors(&proxies[c], &truths[c], Some(&region)).unwrap();
        println!(
            "camera {c}: exact normals median {:.1} mm p95 {:.1} mm; visual hull median {:.1} mm \
             p95 {:.1} mm ({} px); {:?}",
            e.median_mm, e.p95_mm, b.median_mm, b.p95_mm, e.pixels, out.report
        );
        ours.push(e);
        base.push(b);
    }
    let (ours_med, ours_p95) = pooled(&ours);
    let (base_med, base_p95) = pooled(&base);
    let coverage = integrated_px as f64 / measured_px as f64;

    // Estimated normals (part 1) on the two photographed views.
    let t = Instant::now();
    let exposure = Exposure::default().with_white_level(WHITE_LEVEL);
    let cal_params = CalibrationParams {
        exposure,
        ..Default::default()
    };
    let normal_params = NormalParams::default()
        .with_exposure(exposure)
        .with_performance_centre(root);
    let (mut est, mut est_base) = (Vec::new(), Vec::new());
    for c in 0..2 {
        let cam = &ring.cameras[c];
        let cal = calibrate_camera(
            cam,
            &stage.lights,
            stage.centre,
            root,
            &stage.sphere_heights_m(),
            0.2,
            0.5,
            &cal_params,
        )
        .unwrap();
        let obs = &frame.observations[c];
        let images = PatternImages::from_rgb(
            &PATTERNS
                .iter()
                .zip(&obs.patterns)
                .map(|(&p, im)| (p, im))
                .collect::<Vec<_>>(),
        )
        .unwrap();
        let normals = estimate_normals(cam, &cal, &images, Some(&obs.mask), &normal_params).unwrap();
        let out = integrate_normals(cam, &normals, &proxies[c], None, &params).unwrap();
        let both: Vec<bool> = proxies[c].depth_m.iter().map(|d| !d.is_nan()).collect();
        let e = depth_errors(&out.depth, &truths[c], Some(&both)).unwrap();
        let region: Vec<bool> = out.depth.depth_m.iter().map(|d| !d.is_nan()).collect();
        let b = depth_errors(&proxies[c], &truths[c], Some(&region)).unwrap();
        println!(
            "camera {c}: estimated normals median {:.1} mm p95 {:.1} mm; visual hull median \
             {:.1} mm p95 {:.1} mm ({} px)",
            e.median_mm, e.p95_mm, b.median_mm, b.p95_mm, e.pixels
        );
        est.push(e);
        est_base.push(b);
    }
    let t_estimated = t.elapsed().as_secs_f64();
    let (est_med, est_p95) = pooled(&est);
    let (est_base_med, _) = pooled(&est_base);
    println!(
        "capture {t_capture:.1} s, hull {t_hull:.2} s, integration {:.2} s (8 views), \
         estimated-normal views {t_estimated:.1} s; exact normals median {ours_med:.1} mm p95 \
         {ours_p95:.1} mm vs hull {base_med:.1} / {base_p95:.1} mm, coverage {coverage:.3}; \
         estimated normals median {est_med:.1} mm p95 {est_p95:.1} mm vs hull {est_base_med:.1} mm; \
         total {:.1} s",
        solve_ms / 1e3,
        t0.elapsed().as_secs_f64()
    );
    assert!(ours_med < 0.5 * base_med, "{ours_med} vs {base_med}");
    assert!(ours_p95 < base_p95, "{ours_p95} vs {base_p95}");
    assert!(coverage > 0.8, "{coverage}");
    assert!(est_med < base_med, "{est_med} vs {est_base_med}");
}
