//! Validation of photometric-normals (Vlasic 2010 thesis, §3.2) on the synthetic studio.
//!
//! The MakeHuman performer in the skirt, with wrinkles and the albedo texture, under the
//! 1,200-light dome (901 sphere lights on the top two thirds of an 8 m sphere, 299 floor
//! lights, at their real positions) with cast shadows and sensor noise; a ring of cameras
//! 1.7 m above the floor (§3.2.1). Each camera is calibrated with a grey diffuse sphere at 7
//! heights (§3.2.3); one static frame of the exercise motion is rendered under the seven
//! conditions of the 8-frame cycle through `Capture` and turned into normal maps (§3.2.2,
//! Eq. 3.2). Scored against the rasteriser's true normals, outside and inside shadowed
//! concavities (pixels receiving < 90 % of their unoccluded dome power), on the wrinkled
//! regions, and against the distant-light baseline (the analytic `n = k/‖k‖`).
//!
//! Then §3.2.3 on a moving performer (the skirt performer in the studio's fast motion at 240 fps
//! under the 8-frame cycle): normals of 6 tracking frames (3 cycles; 1 with `--quick`) with
//! and without motion compensation, with the true motion and held still (diagnostics), and
//! the flow against the studio's true motion. Sensor noise: `truth::SensorNoise` (shot, read,
//! 10 bits); the full run bins the dome's lights for the shadow rays (`--light-bins`). Last, the optical-flow
//! workload of `bench/peers/flow.py` regenerated in Rust (`--flow-only`: only that, at 1024²).
//!
//! Writes under `out/photometric_normals/`: `patterns.png` (the 8-frame cycle seen by camera
//! 0), `normals.png` (estimated and true normal maps), `normal_error.png` (angular error with a
//! colour bar), `silhouette.png` (camera 0's full-on frame over the green screen and the
//! silhouette's errors), `figures.json`, `manifest.json`; the last stdout line is one JSON
//! object. Also per camera: silhouettes by background subtraction + chroma key (§3.2.1) over a
//! composed green screen with the performer's shadow, and the 3 × 3 colour transfer matrix
//! from a Macbeth chart seen through a simulated colour response.
//!
//! `cargo run --release --example photometric_normals [-- --quick]` (`--quick`: 2 cameras at
//! 256 × 256; the full run: 8 cameras at 1024 × 1024; `--cameras N` changes the count). `--no-noise` and `--no-shadows` switch
//! off the sensor noise and the cast shadows (to separate the error sources).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

use std::time::Instant;

use clap::Parser;
use image::{Rgb, RgbImage};
use serde_json::{json, Value};

use dynamic_shapes::core::camera::Rig;
use dynamic_shapes::core::math::DVec3;
use dynamic_shapes::photometric::truth::{
    angular_errors_deg, colour_scores, distant_light_normals, dome_power_fraction, pattern_images,
    silhouette_scores, skirt_subject, summarize, GreenScreen, LightStage, SensorNoise, StudioScene,
    TrueSurface, STUDIO_FRAME,
};
use dynamic_shapes::photometric::{
    estimate_normals, Exposure, FlowParams, NormalMap, NormalParams, Pattern, PatternImages,
    SilhouetteParams, CYCLE, PATTERNS,
};
use dynamic_shapes_studio::{makehuman_performer, Capture, PatternSchedule, WrinkleParams};
use example_kit::plot::{
    error_colour, label_rows, side_by_side, titled, with_colour_bar, ColourBar,
};
use example_kit::{Goal, Headline, Run};

/// Linear intensity at which the cameras saturate (the capture's exposure).
const WHITE_LEVEL: f32 = 0.4;
/// Top of the error colour scale, degrees.
const ERROR_MAX_DEG: f64 = 20.0;
/// Wrinkled regions: faces with a vertex moved more than this by the wrinkles, m.
const WRINKLE_MIN_M: f64 = 0.5e-3;
/// The values of Eq. 3.2's N tried on the static frame.
const N_BEST_SWEEP: [usize; 5] = [1, 4, 8, 16, 32];

#[derive(Parser, Debug)]
struct Args {
    #[command(flatten)]
    common: example_kit::cli::Common,
    /// No sensor noise.
    #[arg(long)]
    no_noise: bool,
    /// The studio's additive Gaussian noise (σ = 0.005) instead of the camera model.
    #[arg(long)]
    studio_noise: bool,
    /// Tracking frames of the moving sequence (two per 8-frame cycle; default: 1 with
    /// `--quick`, 6 = three cycles otherwise).
    #[arg(long)]
    maps: Option<usize>,
    /// Approximate the cast shadows with about this many light direction bins (one shadow
    /// ray per bin and vertex; 0: exact, one ray per light). Default: exact with `--quick`,
    /// 100 otherwise.
    #[arg(long)]
    light_bins: Option<usize>,
    /// Linear radiance at which the cameras saturate (the exposure).
    #[arg(long, default_value_t = WHITE_LEVEL)]
    white_level: f32,
    /// No cast shadows.
    #[arg(long)]
    no_shadows: bool,
    /// Number of cameras (default: 2 with `--quick`, 8 otherwise); the image size stays.
    #[arg(long)]
    cameras: Option<usize>,
    /// Only the optical-flow peer workload at 1024² (for a side-by-side run with
    /// `bench/peers/flow.py`); prints one JSON line.
    #[arg(long)]
    flow_only: bool,
    /// Timed repetitions of `--flow-only` (after one warm-up).
    #[arg(long, default_value_t = 10)]
    flow_reps: usize,
    /// JSON lines printed by `bench/peers/flow.py` in the same run: with it (and without
    /// `--quick`) the flow workload also runs `FlowParams::fast()` and reports its time and
    /// EPE against OpenCV's DIS medium (`flow_time_ratio_dis`, `flow_epe_ratio_dis`).
    #[arg(long)]
    peers: Option<std::path::PathBuf>,
    /// Render a smooth, consistent true surface (`TrueSurface::Smooth`): every face, not only
    /// the wrinkle regions, Phong-tessellated to the wrinkles' 3 mm edges.
    #[arg(long)]
    smooth_truth: bool,
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = Args::parse();
    let dis = match &args.peers {
        Some(p) => dis_medium(p)?,
        None => None,
    };
    if args.flow_only {
        let (ms, epe, epe_interior) =
            peer_flow_workload(1024, args.flow_reps, &FlowParams::default())?;
        let mut line = json!({"flow_size_px": 1024, "flow_ms": ms, "flow_epe_px": epe, "flow_epe_interior_px": epe_interior});
        if let Some(dis) = &dis {
            line["flow_fast"] = fast_flow_against_dis(1024, args.flow_reps, dis)?;
            line["flow_time_ratio_dis"] = line["flow_fast"]["time_ratio_dis"].clone();
            line["flow_epe_ratio_dis"] = line["flow_fast"]["epe_ratio_dis"].clone();
        }
        println!("{line}");
        return Ok(());
    }
    let quick = args.common.quick;
    let (n_cams, size) = if quick { (2, 256) } else { (8, 1024) };
    let n_cams = args.cameras.unwrap_or(n_cams).max(1);
    let mut run = Run::start(
        "photometric_normals",
        &args.common,
        &format!(
            "MakeHuman in the skirt under the 1,200-light dome, {n_cams} cameras at \
             {size}×{size}: normal maps from the half-on patterns with grey-sphere lookup \
             (Vlasic 2010 §3.2)"
        ),
    )?;
    let stage = run.stage("performer", None);
    let scene = StudioScene::with_surface(
        example_kit::data_path("makehuman")?,
        &skirt_subject().with_wrinkles(Some(WrinkleParams::default())),
        STUDIO_FRAME,
        n_cams,
        size,
        if args.smooth_truth {
            TrueSurface::Smooth {
                max_edge_m: WrinkleParams::default().max_edge_m,
            }
        } else {
            TrueSurface::Polygonal
        },
    )?;
    let (performer, light_stage) = (&scene.performer, &scene.stage);
    let frame_index = scene.frame_index;
    let lights = &light_stage.lights;
    stage.finish(format!("{} vertices", performer.vertex_count()));

    let cameras = scene.ring.cameras.clone();
    let mut spec = scene.capture_spec(scene.ring.clone())?;
    let light_bins = match args.light_bins.unwrap_or(if quick { 0 } else { 100 }) {
        0 => None,
        b => Some(b),
    };
    if let Some(lighting) = &mut spec.lighting {
        lighting.shadows = !args.no_shadows;
        lighting.shadow_light_bins = light_bins;
    }
    let noise = if args.no_noise {
        Noise::Off
    } else if args.studio_noise {
        Noise::Studio
    } else {
        Noise::Sensor(SensorNoise::default().with_white_level(args.white_level))
    };
    noise.set_studio(&mut spec);
    let stage = run.stage("capture", None);
    let t = Instant::now();
    let mut frame = scene.capture(spec)?;
    let capture_s = t.elapsed().as_secs_f64();
    for (c, obs) in frame.observations.iter_mut().enumerate() {
        for (p, im) in obs.patterns.iter_mut().enumerate() {
            noise.apply(im, (1000 + 8 * c + p) as u64)?;
        }
    }
    stage.finish(format!(
        "frame {frame_index} under 7 conditions, {} lights, in {capture_s:.1} s (includes posing the skirt's earlier frames)",
        lights.len()
    ));

    let (exposure, cal_params, params) = scene.photometric_params(args.white_level);
    let mesh = frame.truth.rendered_mesh(performer);
    let fine = frame
        .truth
        .fine
        .as_ref()
        .ok_or("the performer has wrinkles")?;
    let stage = run.stage("normals", Some(n_cams as u64));
    let mut acc = Acc::default();
    let (mut cal_ms, mut normals_ms) = (Vec::new(), Vec::new());
    let mut first: Option<(NormalMap, Vec<Option<f64>>)> = None;
    let mut cals = Vec::new();
    for (c, cam) in cameras.iter().enumerate() {
        let t = Instant::now();
        let cal = scene.calibrate(cam, &cal_params)?;
        cal_ms.push(t.elapsed().as_secs_f64() * 1e3);
        let obs = &frame.observations[c];
        let images = pattern_images(obs)?;
        let t = Instant::now();
        let map = estimate_normals(cam, &cal, &images, Some(&obs.mask), &params)?;
        normals_ms.push(t.elapsed().as_secs_f64() * 1e3);
        let baseline = distant_light_normals(cam, &images, &exposure)?;
        let view = &frame.truth.views[c];
        let truth = view.normals_camera.as_ref().ok_or("normal truth")?;
        let err = angular_errors_deg(&map, truth)?;
        acc.base.extend(angular_errors_deg(&baseline, truth)?);
        // Eq. 3.2's N (not given in the thesis), swept on the same images.
        for (i, &n) in N_BEST_SWEEP.iter().enumerate() {
            let p = NormalParams {
                n_best: n,
                ..params
            };
            let m = estimate_normals(cam, &cal, &images, Some(&obs.mask), &p)?;
            acc.n_best[i].extend(angular_errors_deg(&m, truth)?);
        }
        // Exposure: how much of the well the brightest body pixels of the full-on frame use.
        let full = &obs.patterns[Pattern::Full.index()];
        acc.full_on.extend(
            obs.mask
                .iter()
                .zip(full.pixels())
                .filter(|(m, _)| *m)
                .map(|(_, px)| f64::from(px.0[0].max(px.0[1]).max(px.0[2]) / args.white_level)),
        );
        let power = match &frame.light_visibility {
            Some(vis) => dome_power_fraction(view, &mesh, lights, vis)?,
            None => vec![1.0; err.len()],
        };
        acc.concave.extend(power.iter().map(|&p| p < 0.9));
        // Grazing view: the true normal more than 60° from the direction to the camera.
        acc.grazing
            .extend(truth.pixels().map(|n| n.0[2].abs() < 0.5));
        acc.wrinkled
            .extend(dynamic_shapes::photometric::truth::wrinkle_pixels(
                view,
                fine,
                WRINKLE_MIN_M,
            )?);
        acc.body.extend(obs.mask.iter());
        let garment = performer
            .wrinkles()
            .map(|w| w.garment_faces())
            .unwrap_or(&[]);
        if let Some(tri) = &view.triangle_ids {
            acc.skin.extend(
                tri.as_raw()
                    .iter()
                    .map(|&t| !garment.get(t as usize).copied().unwrap_or(false)),
            );
        }
        acc.valid += map
            .valid
            .iter()
            .zip(obs.mask.iter())
            .filter(|(v, m)| **v && *m)
            .count();
        acc.covered += obs.mask.count();
        acc.err.extend(err.iter().copied());
        if c == 0 {
            write_patterns(&mut run, &obs.patterns, &obs.mask, exposure)?;
            first = Some((map, err));
        }
        cals.push(cal);
        stage.inc(1);
    }
    stage.finish("done");

    // Silhouettes (§3.2.1) and photometric calibration, on every camera's full-on image.
    let stage = run.stage("silhouettes and colour calibration", Some(n_cams as u64));
    let screen = GreenScreen::default();
    let sil_params = SilhouetteParams::default();
    let (mut sil, mut colour) = (Vec::new(), Vec::new());
    for (c, obs) in frame.observations.iter().enumerate() {
        let full = &obs.patterns[Pattern::Full.index()];
        let s = silhouette_scores(&screen, full, &obs.mask, 4, &sil_params, 10 + c as u64)?;
        if c == 0 {
            write_silhouette(
                &mut run,
                &screen.composite(full, &obs.mask, 10)?,
                &s.silhouette.mask,
                &obs.mask,
            )?;
        }
        sil.push(s);
        colour.push(colour_scores(full, &obs.mask, 100 + c as u64)?);
        stage.inc(1);
    }
    let mean_of = |v: Vec<f64>| v.iter().sum::<f64>() / v.len().max(1) as f64;
    let silhouette_iou = mean_of(sil.iter().map(|s| s.iou).collect());
    let silhouette_iou_subtraction = mean_of(sil.iter().map(|s| s.iou_subtraction_only).collect());
    let silhouette_iou_grey = mean_of(sil.iter().map(|s| s.iou_grey_threshold).collect());
    let colour_recovery = colour.iter().map(|s| s.recovery).fold(0.0, f64::max);
    let colour_rms_matrix = mean_of(colour.iter().map(|s| s.rms_matrix).collect());
    let colour_rms_white = mean_of(colour.iter().map(|s| s.rms_white_balance).collect());
    let colour_rms_raw = mean_of(colour.iter().map(|s| s.rms_uncorrected).collect());
    stage.finish(format!(
        "silhouette IoU {silhouette_iou:.4} (subtraction only {silhouette_iou_subtraction:.4}, \
         grey threshold {silhouette_iou_grey:.4}); colour matrix ‖M·A − I‖ ≤ {colour_recovery:.1e}, \
         image RMS {colour_rms_matrix:.1e} (white balance {colour_rms_white:.1e})"
    ));
    let region = |f: &dyn Fn(usize) -> bool| -> Vec<bool> { (0..acc.body.len()).map(f).collect() };
    let open = region(&|i| acc.body[i] && !acc.concave[i]);
    let shadowed = region(&|i| acc.body[i] && acc.concave[i]);
    let wrinkled = region(&|i| acc.body[i] && acc.wrinkled[i]);
    let skin_open = region(&|i| open[i] && acc.skin.get(i).copied().unwrap_or(false));
    let skirt_open = region(&|i| open[i] && !acc.skin.get(i).copied().unwrap_or(true));
    let facing = region(&|i| open[i] && !acc.grazing[i]);
    let grazing = region(&|i| open[i] && acc.grazing[i]);
    let skin_facing = region(&|i| skin_open[i] && !acc.grazing[i]);
    let skirt_facing = region(&|i| skirt_open[i] && !acc.grazing[i]);
    let e_facing = summarize(&acc.err, Some(&facing));
    let e_grazing = summarize(&acc.err, Some(&grazing));
    let e_skin_facing = summarize(&acc.err, Some(&skin_facing));
    let e_skirt_facing = summarize(&acc.err, Some(&skirt_facing));
    let e_skin = summarize(&acc.err, Some(&skin_open));
    let e_skirt = summarize(&acc.err, Some(&skirt_open));
    let e_open = summarize(&acc.err, Some(&open));
    let e_shadow = summarize(&acc.err, Some(&shadowed));
    let e_all = summarize(&acc.err, Some(&acc.body));
    let e_wr = summarize(&acc.err, Some(&wrinkled));
    let b_open = summarize(&acc.base, Some(&open));
    let b_shadow = summarize(&acc.base, Some(&shadowed));
    let b_wr = summarize(&acc.base, Some(&wrinkled));
    let valid_fraction = acc.valid as f64 / acc.covered.max(1) as f64;
    let median = |v: &[f64]| dynamic_shapes::core::stats::median(v);
    let normals_ms_per_view = median(&normals_ms);
    // Measured when the run is at 1024²; otherwise scaled by the pixel count (an estimate).
    let normals_ms_per_view_1024 = normals_ms_per_view * (1024.0 * 1024.0) / f64::from(size * size);
    let normals_1024_measured = size == 1024;

    if let Some((map, err)) = &first {
        let truth = frame.truth.views[0]
            .normals_camera
            .as_ref()
            .ok_or("normal truth")?;
        let truth_map = NormalMap {
            width: size,
            height: size,
            normals: truth
                .pixels()
                .map(|p| DVec3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2])))
                .collect(),
            valid: frame.observations[0].mask.iter().collect(),
        };
        let pair = side_by_side(&[
            titled(&map.to_rgb8(), "estimated (§3.2.2)", None)?,
            titled(&truth_map.to_rgb8(), "true", None)?,
        ])?;
        run.save_picture(
            "normals.png",
            &titled(&pair, "Camera 0 normal maps", Some("RGB = (n + 1)/2 with x right, y up, z towards the viewer; black: invalid or background"))?,
            "Estimated and true camera-frame normal maps of camera 0.",
        )?;
        let err_img = RgbImage::from_fn(size, size, |x, y| {
            let i = (y * size + x) as usize;
            if !frame.observations[0].mask.get(x, y) {
                return Rgb([255, 255, 255]);
            }
            Rgb(error_colour(err[i], ERROR_MAX_DEG))
        });
        let ramp = |t: f64| error_colour(Some(t * ERROR_MAX_DEG), ERROR_MAX_DEG);
        let img = with_colour_bar(
            &titled(
                &err_img,
                "Camera 0: angular error of the normals",
                Some("against the rasteriser's true normals"),
            )?,
            &ColourBar {
                label: "angular error (deg)",
                min: 0.0,
                max: ERROR_MAX_DEG,
                ramp: &ramp,
                note: Some("grey: invalid; values above the top in red"),
            },
        )?;
        run.save_picture(
            "normal_error.png",
            &img,
            "Angular error per pixel of camera 0 (degrees, colour bar); grey: invalid.",
        )?;
    }

    let stage = run.stage("moving sequence", None);
    let maps = args.maps.unwrap_or(if quick { 1 } else { 6 });
    let moving = moving_sequence(
        &cameras,
        &cals,
        light_stage,
        &params,
        noise,
        maps,
        light_bins,
    )?;
    stage.finish(format!(
        "compensated median {:.2}°, uncompensated {:.2}°, flow EPE {:.3} px vs true motion (mean motion {:.2} px)",
        moving["moving_normal_median_deg"].as_f64().unwrap_or(f64::NAN),
        moving["moving_uncompensated_median_deg"].as_f64().unwrap_or(f64::NAN),
        moving["studio_flow_epe_px"].as_f64().unwrap_or(f64::NAN),
        moving["studio_motion_mean_px"].as_f64().unwrap_or(f64::NAN),
    ));
    let stage = run.stage("flow (peer workload)", None);
    let flow_n = if quick { 256 } else { 1024 };
    let flow_reps = if quick { 3 } else { 10 };
    let (flow_ms, flow_epe_px, flow_epe_interior_px) =
        peer_flow_workload(flow_n, flow_reps, &FlowParams::default())?;
    let flow_fast = match (&dis, quick) {
        (Some(dis), false) => Some(fast_flow_against_dis(flow_n, flow_reps, dis)?),
        _ => None,
    };
    stage.finish(format!(
        "{flow_n}² pair: {flow_ms:.0} ms, EPE {flow_epe_px:.3} px (interior {flow_epe_interior_px:.3} px)"
    ));

    let mut figures = json!({
        "flow_size_px": flow_n,
        "flow_ms": flow_ms,
        "flow_epe_px": flow_epe_px,
        "flow_epe_interior_px": flow_epe_interior_px,
        "cameras": n_cams,
        "size_px": size,
        "lights": lights.len(),
        "noise": noise.name(),
        "white_level": args.white_level,
        "shadow_light_bins": light_bins,
        "shadows": !args.no_shadows,
        "normal_median_deg": e_open.median_deg,
        "normal_mean_deg": e_open.mean_deg,
        "normal_median_concave_deg": e_shadow.median_deg,
        "normal_mean_concave_deg": e_shadow.mean_deg,
        "normal_median_all_deg": e_all.median_deg,
        "normal_median_skin_deg": e_skin.median_deg,
        "normal_median_skirt_deg": e_skirt.median_deg,
        "wrinkle_normal_median_deg": e_wr.median_deg,
        "baseline_normal_median_deg": b_open.median_deg,
        "baseline_normal_mean_deg": b_open.mean_deg,
        "baseline_normal_median_concave_deg": b_shadow.median_deg,
        "baseline_wrinkle_normal_median_deg": b_wr.median_deg,
        "pixels_outside_concavities": e_open.pixels,
        "pixels_concave": e_shadow.pixels,
        "pixels_wrinkled": e_wr.pixels,
        "concave_fraction": shadowed.iter().filter(|&&b| b).count() as f64 / acc.covered.max(1) as f64,
        "valid_fraction": valid_fraction,
        "normals_ms_per_view": normals_ms_per_view,
        "normals_ms_per_view_1024": normals_ms_per_view_1024,
        "calibration_ms_per_camera": median(&cal_ms),
        "capture_s": capture_s,
    });
    let peer_compared = flow_fast.is_some();
    if let Some(fast) = flow_fast {
        figures["flow_time_ratio_dis"] = fast["time_ratio_dis"].clone();
        figures["flow_epe_ratio_dis"] = fast["epe_ratio_dis"].clone();
        figures["flow_fast"] = fast;
    }
    let n_best_sweep: Vec<_> = N_BEST_SWEEP
        .iter()
        .zip(&acc.n_best)
        .map(|(&n, e)| {
            let s = summarize(e, Some(&open));
            json!({"n_best": n, "median_deg": s.median_deg, "mean_deg": s.mean_deg})
        })
        .collect();
    let mut full_on = acc.full_on.clone();
    full_on.sort_by(f64::total_cmp);
    let pct = |q: f64| {
        full_on
            .get(((full_on.len() as f64 - 1.0) * q).round() as usize)
            .copied()
    };
    let extra = json!({
        "n_best_sweep": n_best_sweep,
        "normal_median_facing_deg": e_facing.median_deg,
        "normal_median_grazing_deg": e_grazing.median_deg,
        "grazing_fraction_outside": e_grazing.pixels as f64 / e_open.pixels.max(1) as f64,
        "normal_median_skin_facing_deg": e_skin_facing.median_deg,
        "normal_median_skirt_facing_deg": e_skirt_facing.median_deg,
        "full_on_normalised_p50": pct(0.5),
        "full_on_normalised_p99": pct(0.99),
        "normals_ms_per_view_1024_measured": normals_1024_measured,
        "normals_ms_all_views": normals_ms,
        "silhouette_iou": silhouette_iou,
        "silhouette_iou_min": sil.iter().map(|s| s.iou).fold(1.0, f64::min),
        "silhouette_iou_subtraction_only": silhouette_iou_subtraction,
        "silhouette_iou_grey_threshold": silhouette_iou_grey,
        "silhouette_keyed_px": sil.iter().map(|s| s.silhouette.keyed_px).sum::<usize>(),
        "silhouette_holes_filled": sil.iter().map(|s| s.silhouette.holes_filled).sum::<usize>(),
        "silhouette_holes_kept": sil.iter().map(|s| s.silhouette.holes_kept).sum::<usize>(),
        "colour_matrix_recovery_max": colour_recovery,
        "colour_rms_matrix": colour_rms_matrix,
        "colour_rms_white_balance": colour_rms_white,
        "colour_rms_uncorrected": colour_rms_raw,
    });
    if let (Some(f), Some(m), Some(e)) = (
        figures.as_object_mut(),
        moving.as_object(),
        extra.as_object(),
    ) {
        f.extend(m.clone());
        f.extend(e.clone());
    }
    for h in [
        Headline::new(
            "moving_normal_median_deg",
            "moving sequence, motion-compensated (median)",
            "deg",
        )
        .goal(Goal::AtMost(5.0)),
        Headline::new(
            "moving_true_motion_median_deg",
            "moving sequence, compensated with the true motion (diagnostic)",
            "deg",
        )
        .oracle(),
        Headline::new(
            "moving_static_same_pose_median_deg",
            "first tracking frame held still (diagnostic)",
            "deg",
        )
        .oracle(),
        Headline::new(
            "moving_uncompensated_median_deg",
            "moving sequence, without compensation (median)",
            "deg",
        )
        .baseline(),
        Headline::new(
            "studio_flow_epe_px",
            "flow EPE against the studio's true motion",
            "px",
        ),
        Headline::new(
            "normal_median_deg",
            "normal error outside shadowed concavities (median)",
            "deg",
        )
        .goal(Goal::AtMost(3.0)),
        Headline::new(
            "normal_mean_deg",
            "normal error outside shadowed concavities (mean)",
            "deg",
        ),
        Headline::new(
            "normal_median_concave_deg",
            "normal error in shadowed concavities (median)",
            "deg",
        ),
        Headline::new(
            "wrinkle_normal_median_deg",
            "normal error on the wrinkles (median)",
            "deg",
        ),
        Headline::new(
            "baseline_normal_median_deg",
            "distant-light baseline (median, outside concavities)",
            "deg",
        )
        .baseline(),
        Headline::new("valid_fraction", "valid normals on the body", ""),
        Headline::new("flow_ms", "optical flow per pair (peer workload)", "ms")
            .note("goal: ≤ 2× OpenCV DIS medium at 1024² (54 ms in bench/peers)"),
        Headline::new("flow_epe_px", "optical flow EPE (peer workload)", "px")
            .note("goal: ≤ OpenCV DIS medium at 1024² (0.058 px)"),
        Headline::new(
            "silhouette_iou",
            "silhouette IoU (background subtraction + chroma key)",
            "",
        )
        .note("baselines: subtraction alone, grey threshold (figures.json)"),
        Headline::new(
            "colour_rms_matrix",
            "colour error after the 3×3 transfer matrix",
            "linear RGB",
        ),
        Headline::new(
            "normals_ms_per_view_1024",
            if normals_1024_measured {
                "normals per 1024² view (measured)"
            } else {
                "normals per 1024² view (scaled from the run's size)"
            },
            "ms",
        )
        .goal(Goal::AtMost(300.0)),
    ] {
        run.headline(h);
    }
    if peer_compared {
        // Only with `--peers`: OpenCV's DIS medium measured in the same run.
        run.headline(
            Headline::new(
                "flow_time_ratio_dis",
                "fast flow setting's time over OpenCV DIS medium's (peer workload, same run)",
                "×",
            )
            .goal(Goal::AtMost(1.0)),
        );
        run.headline(
            Headline::new(
                "flow_epe_ratio_dis",
                "fast flow setting's EPE over OpenCV DIS medium's (peer workload)",
                "×",
            )
            .goal(Goal::AtMost(1.0)),
        );
    }
    run.finish(figures)?;
    Ok(())
}

/// OpenCV's DIS medium line (`bench/peers/flow.py --variant dis`) of a peers file, if any.
fn dis_medium(path: &std::path::Path) -> Result<Option<Value>, Box<dyn std::error::Error>> {
    Ok(std::fs::read_to_string(path)?
        .lines()
        .filter_map(|l| serde_json::from_str::<Value>(l).ok())
        .find(|p| p["workload"] == "flow" && p["peer"].as_str().is_some_and(|s| s.contains("DIS"))))
}

/// [`FlowParams::fast`] on the flow workload beside the peer's DIS medium line: its time and
/// EPE and their ratios to the peer's.
fn fast_flow_against_dis(
    n: u32,
    reps: usize,
    dis: &Value,
) -> Result<Value, Box<dyn std::error::Error>> {
    let (ms, epe, epe_interior) = peer_flow_workload(n, reps, &FlowParams::fast())?;
    let dis_ms = dis["seconds"].as_f64().unwrap_or(f64::NAN) * 1e3;
    let dis_epe = dis["quality"]["epe_px"].as_f64().unwrap_or(f64::NAN);
    Ok(json!({
        "params": "FlowParams::fast()",
        "flow_ms": ms,
        "flow_epe_px": epe,
        "flow_epe_interior_px": epe_interior,
        "peer": dis["peer"],
        "peer_ms": dis_ms,
        "peer_epe_px": dis_epe,
        "time_ratio_dis": ms / dis_ms,
        "epe_ratio_dis": epe / dis_epe,
    }))
}

/// The flow workload of `bench/peers/flow.py` (`peer_workloads::FlowWorkload`) at `n`²:
/// the median time of `reps` runs (after one warm-up), ms, the mean EPE over pixels whose
/// target is inside, px, and the same without a 32 px border.
fn peer_flow_workload(
    n: u32,
    reps: usize,
    params: &FlowParams,
) -> Result<(f64, f64, f64), Box<dyn std::error::Error>> {
    use dynamic_shapes::photometric::dense_flow;
    use dynamic_shapes::photometric::peer_workloads::FlowWorkload;
    let w = FlowWorkload::new(n)?;
    dense_flow(&w.first, &w.second, params)?;
    let mut times = Vec::new();
    let mut flow = None;
    for _ in 0..reps {
        let t = Instant::now();
        flow = Some(dense_flow(&w.first, &w.second, params)?);
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    let flow = flow.ok_or("at least one rep")?;
    let (epe, epe_interior) = w.epe(&flow)?;
    Ok((
        dynamic_shapes::core::stats::median(&times),
        epe,
        epe_interior,
    ))
}

/// One captured frame of the moving sequence, reduced to what the normal maps need: the grey
/// image per camera, the true mesh, and for tracking frames the masks and the view truth.
struct MovingFrame {
    index: usize,
    greys: Vec<dynamic_shapes::core::image::GrayF32Image>,
    mesh: dynamic_shapes::core::mesh::TriMesh,
    masks: Vec<dynamic_shapes::core::image::Mask>,
    views: Vec<dynamic_shapes_studio::ViewTruth>,
}

/// §3.2.3 on a moving performer: the skirt performer (no wrinkles: cheaper shadow rays) in
/// the studio's fast motion at 240 fps under the 8-frame cycle (`PatternSchedule::Cycle`),
/// sensor noise as `noise`. From frame 75 on, `maps` tracking frames 79, 83, … (two per
/// cycle: `maps` = 6 is three cycles, frames 75–103), each from the nine frames around it
/// (`F X̄ Ȳ Z̄ F X Y Z F` or `F X Y Z F X̄ Ȳ Z̄ F`). Normals with and without motion
/// compensation, and with the pattern frames warped by the *true* motion (the diagnostic
/// that separates the flow's error from what compensation cannot remove: shading that
/// changes as the surface turns, resampling), all against the truth of the tracking frame on
/// the same confident pixels; the forward flow against the projected true motion. Frames are
/// streamed (nine held at a time).
fn moving_sequence(
    cameras: &[dynamic_shapes::core::camera::Camera],
    cals: &[dynamic_shapes::photometric::HeightCalibration],
    light_stage: &LightStage,
    params: &NormalParams,
    noise: Noise,
    maps: usize,
    light_bins: Option<usize>,
) -> Result<serde_json::Value, Box<dyn std::error::Error>> {
    use dynamic_shapes::photometric::{
        compensate_motion, grey, warp, Flow, MotionParams, CYCLE_FRAME_RATE_HZ,
    };
    use dynamic_shapes_studio::{fast_motion, FastMotionParams};
    use std::collections::VecDeque;
    const FIRST: usize = 75;
    let performer = makehuman_performer(example_kit::data_path("makehuman")?, &skirt_subject())?;
    let motion = fast_motion(&performer.skeleton, &FastMotionParams::default())?;
    let rig = Rig {
        cameras: cameras.to_vec(),
    };
    let mut spec =
        light_stage.capture_spec(rig.clone(), CYCLE_FRAME_RATE_HZ, PatternSchedule::Cycle)?;
    noise.set_studio(&mut spec);
    if let Some(l) = &mut spec.lighting {
        l.shadow_light_bins = light_bins;
    }
    let capture = Capture::new(&performer, &motion, spec)?;
    // The first tracking frame held still under all seven conditions: the static error of
    // the moving sequence's own pose, scored on the pixels the compensated map is scored on.
    let mut still_spec =
        light_stage.capture_spec(rig, CYCLE_FRAME_RATE_HZ, PatternSchedule::AllEachFrame)?;
    noise.set_studio(&mut still_spec);
    if let Some(l) = &mut still_spec.lighting {
        l.shadow_light_bins = light_bins;
    }
    let mut still = Capture::new(&performer, &motion, still_spec)?
        .frames_in(FIRST + 4..FIRST + 5)
        .next()
        .ok_or("the frame is in the motion")??;
    let mut still_images = Vec::new();
    for (c, obs) in still.observations.iter_mut().enumerate() {
        for (p, im) in obs.patterns.iter_mut().enumerate() {
            noise.apply(im, (5000 + 8 * c + p) as u64)?;
        }
        still_images.push(PatternImages::from_rgb(
            &PATTERNS
                .iter()
                .zip(&obs.patterns)
                .map(|(&p, im)| (p, im))
                .collect::<Vec<_>>(),
        )?);
    }
    let mut still_err = Vec::new();
    let last = FIRST + 4 * maps.max(1) + 4;
    let (mut comp, mut raw, mut truef, mut body) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let (mut epe, mut mag) = (Vec::new(), Vec::new());
    let mut per_map = Vec::new();
    let mut still_summary = json!({});
    let mut window: VecDeque<MovingFrame> = VecDeque::new();
    let t0 = Instant::now();
    let mut capture_s = 0.0;
    let mut t_frame = Instant::now();
    for frame in capture.frames_in(FIRST..last + 1) {
        let mut frame = frame?;
        capture_s += t_frame.elapsed().as_secs_f64();
        let k = frame.index;
        let tracking = CYCLE[k % 8] == Pattern::Full;
        let mut greys = Vec::new();
        for (c, obs) in frame.observations.iter_mut().enumerate() {
            let im = obs.shaded.as_mut().ok_or("shaded image")?;
            noise.apply(im, (k * 64 + c) as u64)?;
            greys.push(grey(im));
        }
        let mesh = frame.truth.rendered_mesh(&performer);
        let (masks, views) = if tracking {
            (
                frame.observations.iter().map(|o| o.mask.clone()).collect(),
                std::mem::take(&mut frame.truth.views),
            )
        } else {
            (Vec::new(), Vec::new())
        };
        drop(frame);
        window.push_back(MovingFrame {
            index: k,
            greys,
            mesh,
            masks,
            views,
        });
        if window.len() > 9 {
            window.pop_front();
        }
        t_frame = Instant::now();
        if window.len() < 9 || CYCLE[window[4].index % 8] != Pattern::Full {
            continue;
        }
        let mid = &window[4];
        let (mut m_comp, mut m_raw, mut m_true, mut m_body) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for (c, cam) in cameras.iter().enumerate() {
            let pairs: Vec<_> = window
                .iter()
                .map(|f| (CYCLE[f.index % 8], &f.greys[c]))
                .collect();
            let compensated = compensate_motion(&pairs, &MotionParams::default())?;
            let mask = mid.masks[c].and(&compensated.confident)?;
            let map = estimate_normals(cam, &cals[c], &compensated.images, Some(&mask), params)?;
            let uncompensated = PatternImages::new(
                pairs[1..8]
                    .iter()
                    .map(|(p, im)| (*p, (*im).clone()))
                    .collect(),
            )?;
            // Scored on the same (confident) pixels as the compensated map.
            let map_raw = estimate_normals(cam, &cals[c], &uncompensated, Some(&mask), params)?;
            let view = &mid.views[c];
            let truth = view.normals_camera.as_ref().ok_or("normal truth")?;
            let (Some(tri), Some(bary)) = (&view.triangle_ids, &view.barycentric) else {
                return Err("triangle truth".into());
            };
            // True motion of every pixel's surface point to each frame of the window (same
            // faces: no wrinkles); zero off the body.
            let true_flow = |to: &dynamic_shapes::core::mesh::TriMesh| -> Flow {
                let u = tri
                    .as_raw()
                    .iter()
                    .enumerate()
                    .map(|(i, &t)| {
                        let Some(f) = mid.mesh.faces.get(t as usize) else {
                            return [0.0, 0.0];
                        };
                        let (b1, b2) = (
                            f64::from(bary.as_raw()[2 * i]),
                            f64::from(bary.as_raw()[2 * i + 1]),
                        );
                        let at = |m: &dynamic_shapes::core::mesh::TriMesh| {
                            m.vertices[f[0] as usize] * (1.0 - b1 - b2)
                                + m.vertices[f[1] as usize] * b1
                                + m.vertices[f[2] as usize] * b2
                        };
                        match (cam.project(at(&mid.mesh)), cam.project(at(to))) {
                            (Ok(p0), Ok(p1)) => [(p1.x - p0.x) as f32, (p1.y - p0.y) as f32],
                            _ => [0.0, 0.0],
                        }
                    })
                    .collect();
                Flow {
                    width: truth.width(),
                    height: truth.height(),
                    u,
                }
            };
            let mut true_images = vec![(Pattern::Full, pairs[4].1.clone())];
            for (i, f) in window.iter().enumerate() {
                if i % 4 != 0 {
                    true_images.push((pairs[i].0, warp(&f.greys[c], &true_flow(&f.mesh), 1.0)?));
                }
            }
            let map_true = estimate_normals(
                cam,
                &cals[c],
                &PatternImages::new(true_images)?,
                Some(&mask),
                params,
            )?;
            if mid.index == FIRST + 4 {
                let m = estimate_normals(cam, &cals[c], &still_images[c], Some(&mask), params)?;
                still_err.extend(angular_errors_deg(&m, truth)?);
            }
            m_comp.extend(angular_errors_deg(&map, truth)?);
            m_raw.extend(angular_errors_deg(&map_raw, truth)?);
            m_true.extend(angular_errors_deg(&map_true, truth)?);
            m_body.extend(mid.masks[c].iter());
            let forward_truth = true_flow(&window[8].mesh);
            for (i, &t) in tri.as_raw().iter().enumerate() {
                if (t as usize) >= mid.mesh.faces.len() {
                    continue;
                }
                let (tu, est) = (forward_truth.u[i], compensated.forward.u[i]);
                epe.push(f64::from(
                    ((est[0] - tu[0]).powi(2) + (est[1] - tu[1]).powi(2)).sqrt(),
                ));
                mag.push(f64::from((tu[0].powi(2) + tu[1].powi(2)).sqrt()));
            }
        }
        let (ec, er, et) = (
            summarize(&m_comp, Some(&m_body)),
            summarize(&m_raw, Some(&m_body)),
            summarize(&m_true, Some(&m_body)),
        );
        if mid.index == FIRST + 4 {
            let e = summarize(&still_err, Some(&m_body));
            still_summary = json!({
                "moving_static_same_pose_median_deg": e.median_deg,
                "moving_first_map_compensated_median_deg": ec.median_deg,
                "moving_first_map_true_motion_median_deg": et.median_deg,
            });
        }
        per_map.push(json!({
            "tracking_frame": mid.index,
            "compensated_median_deg": ec.median_deg,
            "uncompensated_median_deg": er.median_deg,
            "true_motion_median_deg": et.median_deg,
            "scored_pixels": ec.pixels,
        }));
        comp.extend(m_comp);
        raw.extend(m_raw);
        truef.extend(m_true);
        body.extend(m_body);
    }
    if per_map.len() != maps.max(1) {
        return Err(format!("expected {maps} tracking frames, got {}", per_map.len()).into());
    }
    let e_comp = summarize(&comp, Some(&body));
    let e_raw = summarize(&raw, Some(&body));
    let e_true = summarize(&truef, Some(&body));
    let valid = comp
        .iter()
        .zip(&body)
        .filter(|(e, b)| **b && e.is_some())
        .count() as f64
        / body.iter().filter(|&&b| b).count().max(1) as f64;
    let m = |v: &[f64]| {
        if v.is_empty() {
            f64::NAN
        } else {
            dynamic_shapes::core::stats::mean(v)
        }
    };
    let mut out = json!({
        "moving_normal_median_deg": e_comp.median_deg,
        "moving_normal_mean_deg": e_comp.mean_deg,
        "moving_uncompensated_median_deg": e_raw.median_deg,
        "moving_uncompensated_mean_deg": e_raw.mean_deg,
        "moving_true_motion_median_deg": e_true.median_deg,
        "moving_true_motion_mean_deg": e_true.mean_deg,
        "moving_valid_fraction": valid,
        "moving_scored_pixels": e_comp.pixels,
        "moving_uncompensated_scored_pixels": e_raw.pixels,
        "moving_maps": per_map.len(),
        "moving_frames": last + 1 - FIRST,
        "moving_per_map": per_map,
        "moving_capture_s": capture_s,
        "moving_s": t0.elapsed().as_secs_f64(),
        "studio_flow_epe_px": m(&epe),
        "studio_motion_mean_px": m(&mag),
    });
    if let (Some(o), Some(s)) = (out.as_object_mut(), still_summary.as_object()) {
        o.extend(s.clone());
    }
    Ok(out)
}

/// The sensor noise of a run: the camera model (`SensorNoise`, default), the studio's
/// additive Gaussian (`--studio-noise`), or none (`--no-noise`).
#[derive(Clone, Copy)]
enum Noise {
    Sensor(SensorNoise),
    Studio,
    Off,
}

impl Noise {
    /// Keeps the studio's own noise only for `Noise::Studio`.
    fn set_studio(&self, spec: &mut dynamic_shapes_studio::CaptureSpec) {
        if !matches!(self, Noise::Studio) {
            spec.noise = None;
        }
    }

    /// Reads a rendered image through the camera model (nothing for the others).
    fn apply(
        &self,
        image: &mut image::Rgb32FImage,
        seed: u64,
    ) -> Result<(), Box<dyn std::error::Error>> {
        if let Noise::Sensor(s) = self {
            s.apply(image, seed)?;
        }
        Ok(())
    }

    fn name(&self) -> &'static str {
        match self {
            Noise::Sensor(_) => "sensor (shot + read + 10-bit)",
            Noise::Studio => "studio additive sigma 0.005",
            Noise::Off => "none",
        }
    }
}

/// Per-pixel scores of all cameras, concatenated.
#[derive(Default)]
struct Acc {
    err: Vec<Option<f64>>,
    base: Vec<Option<f64>>,
    concave: Vec<bool>,
    wrinkled: Vec<bool>,
    body: Vec<bool>,
    skin: Vec<bool>,
    n_best: [Vec<Option<f64>>; N_BEST_SWEEP.len()],
    grazing: Vec<bool>,
    full_on: Vec<f64>,
    valid: usize,
    covered: usize,
}

/// `patterns.png`: the 8-frame cycle of camera 0, cropped to the performer.
fn write_patterns(
    run: &mut Run,
    images: &[image::Rgb32FImage],
    mask: &dynamic_shapes::core::image::Mask,
    exposure: Exposure,
) -> Result<(), Box<dyn std::error::Error>> {
    let bb = mask.bounding_box().ok_or("camera 0 sees the performer")?;
    let (x0, y0) = (bb.x_min.saturating_sub(4), bb.y_min.saturating_sub(4));
    let (w, h) = (
        (bb.width() + 8).min(mask.width() - x0),
        (bb.height() + 8).min(mask.height() - y0),
    );
    let mut panels = Vec::new();
    for p in CYCLE {
        let im = &images[p.index()];
        let rgb = RgbImage::from_fn(w, h, |x, y| {
            let c = im.get_pixel(x + x0, y + y0).0;
            Rgb(c.map(|v| {
                let s = (v / exposure.white_level).clamp(0.0, 1.0).powf(1.0 / 2.2);
                (s * 255.0).round() as u8
            }))
        });
        panels.push(titled(&rgb, &format!("{p:?}"), None)?);
    }
    let row = side_by_side(&panels)?;
    let row = label_rows(&row, &["camera 0"], 0).unwrap_or(row);
    run.save_picture(
        "patterns.png",
        &titled(&row, "The 8-frame cycle [X, Y, Z, F, X̄, Ȳ, Z̄, F] (Eq. 3.1), camera 0", Some("linear radiance / white level, gamma 2.2"))?,
        "The performer under the 8-frame cycle of half-on patterns and full-on tracking frames, as camera 0 sees it (static frame).",
    )?;
    Ok(())
}

/// Camera 0's full-on frame over the green screen, and the silhouette's agreement with the
/// true mask (white: both, red: extra, blue: missed).
fn write_silhouette(
    run: &mut Run,
    composite: &image::Rgb32FImage,
    ours: &dynamic_shapes::core::image::Mask,
    truth: &dynamic_shapes::core::image::Mask,
) -> Result<(), Box<dyn std::error::Error>> {
    let frame = RgbImage::from_fn(composite.width(), composite.height(), |x, y| {
        Rgb(composite
            .get_pixel(x, y)
            .0
            .map(|v| ((v / WHITE_LEVEL).clamp(0.0, 1.0).powf(1.0 / 2.2) * 255.0).round() as u8))
    });
    let agreement = RgbImage::from_fn(ours.width(), ours.height(), |x, y| {
        match (ours.get(x, y), truth.get(x, y)) {
            (true, true) => Rgb([255, 255, 255]),
            (true, false) => Rgb([230, 30, 30]),
            (false, true) => Rgb([40, 80, 255]),
            (false, false) => Rgb([0, 0, 0]),
        }
    });
    let pair = side_by_side(&[
        titled(&frame, "full-on frame over the green screen", None)?,
        titled(&agreement, "silhouette vs truth", None)?,
    ])?;
    run.save_picture(
        "silhouette.png",
        &titled(
            &pair,
            "Camera 0: silhouette by background subtraction + chroma key (§3.2.1)",
            Some("white: foreground in both; red: extra (false positive); blue: missed; black: backdrop in both"),
        )?,
        "Camera 0's full-on frame over the composed green screen (with the performer's shadow) and the extracted silhouette against the true mask.",
    )?;
    Ok(())
}
