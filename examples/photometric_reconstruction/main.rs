//! Part 2 of photometric-normals (Vlasic 2010 thesis §3.3, §3.4): per-view surfaces, both passes and Table 3.1 on the
//! synthetic studio.
//!
//! The MakeHuman performer in the skirt with the albedo texture, under the 1,200-light dome
//! with cast shadows and sensor noise, seen by a ring of cameras 1.7 m above the floor; one
//! static frame of the exercise motion under the seven lighting conditions. Part 1 turns the
//! images into normal maps (each camera calibrated with grey spheres at 7 heights); the
//! visual hull of the silhouettes is rendered per camera as the proxy; then one pass of
//! §3.3's per-view stage: Eq. 3.3 integration with the hull's discontinuities removed,
//! matching of the ring's neighbouring pairs with the surface metric (epipolar-plane grids,
//! four-state dynamic programming), integration again without the discontinuities matching
//! found, matching again and the Eq. 3.4 offsets. The same per-view stage runs with the
//! rasteriser's exact normals as a control. Then the two passes of §3.3 ([`reconstruct_from_hull_depths`]):
//! the pass-1 surfaces merged (VRIP, §3.3.3) and hole-filled (screened Poisson, the merged
//! mesh's samples at weight 1 and the visual hull's at 0.01), and pass 2 with that mesh as
//! the proxy, merged and filled again. Each pass is scored by Table 3.1 (coverage, normal
//! deviation, local normal deviation, on the merged mesh before hole filling) and by the
//! distance of the merged and filled meshes to the true mesh, beside the visual hull's
//! surface (the baseline that could win); the four matching metrics are compared on one pair
//! (Figure 3-5). Every per-view stage is scored against the true depth maps beside the hull
//! alone.
//!
//! Then (unless `--skirt-only`) the same part-1 normals, both passes, Table 3.1 and distances
//! for two more subjects: the thesis' Ghost (the figure under the studio's draped sheet, at
//! the same frame) and the skirt with the studio's wrinkles,
//! for which [`displacement_survival`] measures how much of the true wrinkle height the
//! meshes keep (`wrinkle_amplitude_ratio`, beside the visual hull's).
//!
//! Last, the workload of `bench/peers/normal_integration.py` regenerated in Rust (Eq. 3.3 on
//! a 512² Gaussian-bump depth map with analytic normals and a 1 cm-noise prior, α = 10⁻³):
//! the time of [`integrate_normals`] and its RMS depth error, to set beside the Python peer's
//! JSON line run on the same machine (`--peer-only` runs only this).
//!
//! Writes under `out/photometric_reconstruction/`: `per_view_error.png` (camera 0's depth error
//! per stage with a colour bar, in the manner of Figure 3-8's first column),
//! `matching.png` (camera 0's matched pixels and discontinuities, as Figure 3-6 colours
//! them), `stages.png` (camera 0's surface, merged and hole-filled meshes of both passes
//! coloured by distance to the truth, as Figure 3-8), `view_<c>.ply` (each offset surface as
//! a mesh), `pass{1,2}_{merged,filled}.ply`, `stages_{ghost,wrinkled}.png` and
//! `{ghost,wrinkled}_pass2_{merged,filled}.ply` for the other subjects, `wrinkles_wrinkled.png`
//! (true against reconstructed wrinkle heights), `figures.json`, `manifest.json`;
//! the last stdout line is one JSON object.
//!
//! `cargo run --release --example photometric_reconstruction [-- --quick]` (`--quick`: 8
//! cameras at 256²; the full run: 8 cameras at 512²; `--size` and `--cameras` change them).
//! The true surface is the studio's polygonal mesh by default; `--truth-edge-mm 4` renders
//! the smooth, consistent one (`TrueSurface::Smooth`, every face Phong-tessellated to 4 mm
//! edges, shadows in light bins; docs: "A consistent studio truth"). `--subject ghost` (or
//! `wrinkled`) runs only that subject, with each pass's per-view stages traced against the
//! truth and the exact-normal control (docs: "The Ghost and the wrinkle amplitude").
//! `--top-camera` adds the thesis's optional ninth camera above the performer (docs: "The
//! optional top camera").
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code
#![recursion_limit = "256"] // the figures' json! literal

use std::time::Instant;

use clap::Parser;
use image::{Rgb, RgbImage};
use serde_json::json;

use dynamic_shapes::core::camera::{Camera, Intrinsics, RadialDistortion};
use dynamic_shapes::core::image::GrayF32Image;
use dynamic_shapes::core::image::Mask;
use dynamic_shapes::core::math::{DAffine3, DVec3};
use dynamic_shapes::core::mesh::{points_to_surface, write_ply, MeshQuery, PlyEncoding, TriMesh};
use dynamic_shapes::core::random::SplitMix64;
use dynamic_shapes::core::raster::{Buffers, Rasterizer, RenderParams, NO_TRIANGLE};
use dynamic_shapes::photometric::truth::{
    facet_shading_gap, ghost_subject, pattern_images, render_both_faces, skirt_subject,
    StudioScene, TrueSurface, GHOST_FRAME, RING_RADIUS_M, STUDIO_FRAME,
};
use dynamic_shapes::photometric::{
    coverage_budget, covered_pixels, depth_errors, depth_map_mesh, displacement_survival,
    estimate_normals, estimate_normals_on_proxy, hull_samples, integrate_normals, match_pair,
    matching_images, merge_views, per_view_surfaces, reconstruct_from_hull_depths,
    rendered_normals, surface_distance, table_metrics, BudgetInputs, DepthMap, IntegrationParams,
    MatchMetric, MatchView, MatchingParams, MergeView, MetricParams, NormalMap, OffsetOutliers,
    PolygonalHull, PolygonalHullParams, ReconstructParams, Reconstruction, RefineParams,
    RobustWeights, SubPixel, SurfaceDistance, SurfaceErrors, SurfaceParams, TargetNormals,
    ViewSurfaces,
};
use dynamic_shapes_studio::shading::DomeParams;
use dynamic_shapes_studio::{DeformationParams, FineSurface, WrinkleParams};
use example_kit::plot::{
    error_colour, side_by_side, titled, with_colour_bar, Chart, ColourBar, LegendPosition, Series,
    Style,
};
use example_kit::{Goal, Headline, Run};

/// Linear intensity at which the cameras saturate (the capture's exposure).
const WHITE_LEVEL: f32 = 0.4;
/// Top of the depth-error colour scale, mm.
const ERROR_MAX_MM: f64 = 50.0;
/// Top of the mesh-distance colour scale, mm.
const MESH_ERROR_MAX_MM: f64 = 10.0;

#[derive(Parser, Debug)]
struct Args {
    #[command(flatten)]
    common: example_kit::cli::Common,
    /// Image size, px (default: 256 with `--quick`, 512 otherwise).
    #[arg(long)]
    size: Option<u32>,
    /// Number of cameras on the ring.
    #[arg(long, default_value_t = 8)]
    cameras: usize,
    /// Only the normal-integration peer workload (`bench/peers/normal_integration.py`).
    #[arg(long)]
    peer_only: bool,
    /// Size of the peer workload, px.
    #[arg(long, default_value_t = 512)]
    peer_size: u32,
    /// Only the performer in the skirt (not the Ghost and the wrinkled skirt after it).
    #[arg(long)]
    skirt_only: bool,
    /// Light bins of the wrinkled subject's cast shadows (0: exact; see `photometric_normals`);
    /// also of every subject on the smooth true surface (its fine mesh is too large for one
    /// shadow ray per light).
    #[arg(long, default_value_t = 100)]
    wrinkle_light_bins: usize,
    /// Scale the merge's depth-jump threshold with the image width
    /// (`ReconstructParams::scale_merge_jump`; see the coverage budget in the docs).
    #[arg(long)]
    scale_merge_jump: bool,
    /// Pass 1's hole-filling depth (`ReconstructParams::pass1_poisson_depth`; default: the
    /// same as pass 2's).
    #[arg(long)]
    pass1_poisson_depth: Option<u32>,
    /// Pass 2's proxy-jump threshold, m per pixel at 1024 px (default 0.02).
    #[arg(long)]
    pass2_proxy_jump_m: Option<f64>,
    /// Pass 2 integrates the pixels straddling the proxy's jumps on the layer (side) their
    /// first matching agrees with (`IntegrationParams::layers`).
    #[arg(long)]
    pass2_layers: bool,
    /// With `--pass2-layers`: how near the matched depth must be to a layer, as a fraction of
    /// the proxy-jump threshold (`IntegrationParams::layer_agreement`, default 0.5).
    #[arg(long)]
    pass2_layer_agreement: Option<f64>,
    /// Longest edge of the smooth, consistent true surface (`TrueSurface::Smooth`: every face
    /// Phong-tessellated), mm; 0: the polygonal mesh. Default 0: a 4 mm smooth truth's
    /// capture takes 25× as long and, with the Ghost, the run far more memory (docs: "A
    /// consistent studio truth"). 4 is the setting of the 1024² headline and of the floors
    /// (`floor_*`): on the polygonal truth the floors also carry its facets' gap from its
    /// shading normals (docs: "Floors of Table 3.1").
    #[arg(long)]
    truth_edge_mm: Option<f64>,
    /// Sub-pixel matches in both passes and the control (`MatchingParams::subpixel`: `off`,
    /// `cost` for `SubPixel::CostParabola`, `path` for `SubPixel::PathFit`; docs:
    /// "Sub-pixel matches and normal deviation").
    #[arg(long, default_value = "off")]
    subpixel_matches: String,
    /// Eq. 3.4 as the thesis writes it, every match kept, in both passes and the control
    /// (`OffsetParams::outliers = None`; the default rejects the matches whose offset is an
    /// outlier of their neighbourhood's, `OffsetOutliers::default()` unless the three knobs
    /// below are given; docs: "Reliable matches in Eq. 3.4").
    #[arg(long)]
    thesis_offsets: bool,
    /// Outlier rejection: multiple of 1.4826 · MAD allowed (default 2).
    #[arg(long)]
    outlier_k: Option<f64>,
    /// Outlier rejection: window radius, px at 1024 (default 8).
    #[arg(long)]
    outlier_radius_px: Option<f64>,
    /// Outlier rejection: smallest allowed deviation, mm (default 2).
    #[arg(long)]
    outlier_floor_mm: Option<f64>,
    /// Cauchy-reweighted Eq. 3.4 (`OffsetParams::robust`, 3 reweighted solves) with this
    /// scale, mm, in both passes and the control.
    #[arg(long)]
    robust_offsets_mm: Option<f64>,
    /// Only this other subject (`ghost` or `wrinkled`), not the skirt before it: its capture,
    /// both passes, Table 3.1, distances and wrinkle survival as in the full run, plus each
    /// pass's per-view stages against the truth (how many pixels are off by more than 1, 3
    /// and 10 cm) and the exact-normal control (the Ghost and the
    /// wrinkles at 1024² without the skirt's run before them).
    #[arg(long)]
    subject: Option<String>,
    /// Add the thesis's optional ninth camera (§3.2.1: it "looks down onto the performer from
    /// the top of the dome"), the ring's lens at the dome's top; it is matched with every
    /// other ring camera (`TOP_PAIRS_EVERY`) and its part-1 normals take their heights from
    /// the visual hull (`estimate_normals_on_proxy`).
    #[arg(long)]
    top_camera: bool,
    /// Pass 1's matching band about each view's integrated surface, m, also the exact-normal
    /// control's (`MatchingParams::band_m`, default 0.2; docs: "the
    /// pass-1 band").
    #[arg(long)]
    pass1_band_m: Option<f64>,
    /// Contour-aware surface windows in both passes and the control
    /// (`MatchingParams::contour_jump_m`, 0.01 m per pixel at 1024 unless `--contour-jump-m`
    /// gives it; docs: "Windows at occluding contours").
    #[arg(long)]
    contour_windows: bool,
    /// With `--contour-windows`: the depth jump per pixel, m at 1024 (default 0.01).
    #[arg(long)]
    contour_jump_m: Option<f64>,
    /// Coarse-to-fine matching in pass 1, `true` or `false` (`MatchingParams::coarse_to_fine`
    /// of `ReconstructParams::pass1`; default: `ReconstructParams::default()`'s; docs:
    /// "Pass-1 speed").
    #[arg(long)]
    pass1_coarse_to_fine: Option<bool>,
    /// Coarse-to-fine matching in pass 2, `true` or `false` (default:
    /// `ReconstructParams::default()`'s).
    #[arg(long)]
    pass2_coarse_to_fine: Option<bool>,
    /// Half-width of the full-resolution band about the coarse path, pixel footprints, in
    /// both passes (`MatchingParams::coarse_band_px`, default 4).
    #[arg(long)]
    coarse_band_px: Option<f64>,
    /// Refine pass 2's merged mesh with the measured normals before Table 3.1 and the hole
    /// filling (`ReconstructParams::refine`: Nehab et al. 2005's positions and normals, one
    /// sparse solve; beyond the thesis; docs: "Fusing the merged mesh with the
    /// normals"). On by default; the flag is kept for old commands.
    #[arg(long, conflicts_with = "no_refine")]
    refine: bool,
    /// Do not refine (`ReconstructParams::refine = None`: the thesis's pipeline).
    #[arg(long)]
    no_refine: bool,
    /// Refinement (unless `--no-refine`): the position weight λ in (0, 1] (default 0.1).
    #[arg(long)]
    refine_lambda: Option<f64>,
    /// Refinement (unless `--no-refine`): the target normals, `frontal` (the most frontal
    /// camera's, as Table 3.1's vertex figure) or `cos2` (all cameras', weighted by the
    /// squared cosine of the view angle) (default: `RefineParams::default()`'s, cos2).
    #[arg(long)]
    refine_targets: Option<String>,
    /// Refinement (unless `--no-refine`): also refine pass 1's merged mesh (pass 2's proxy
    /// is then built from it) (`ReconstructParams::refine_pass1`).
    #[arg(long)]
    refine_pass1: bool,
    /// Refinement (unless `--no-refine`): drop a target normal farther than this from the
    /// vertex's own normal, degrees (`RefineParams::max_angle_deg`; default: none dropped).
    #[arg(long)]
    refine_max_angle_deg: Option<f64>,
    /// Refinement (unless `--no-refine`): rounds of neighbour averaging of the target normals
    /// (`RefineParams::smoothing`; default 2).
    #[arg(long)]
    refine_smoothing: Option<usize>,
    /// Refinement (unless `--no-refine`): Nehab 2005's first step, rounds of 1-ring
    /// averaging that define the low frequencies the targets take from the positions
    /// (`RefineParams::correction_rounds`; default 8; 0: the refinement without correction
    /// rounds).
    #[arg(long)]
    refine_correct_rounds: Option<usize>,
}

/// Pass 2's Table 3.1 before the refinement (`score_passes`), copied to the top level of the
/// figures beside the refined figures.
const UNREFINED_KEYS: [&str; 6] = [
    "unrefined_coverage_pct",
    "unrefined_normal_dev_deg",
    "unrefined_local_normal_dev_deg",
    "unrefined_true_normal_dev_deg",
    "unrefined_true_local_normal_dev_deg",
    "unrefined_surface_median_mm",
];

/// The floors of Table 3.1's deviations in the goals' form (`perfect_geometry`), copied to the
/// top level of the figures.
const FLOOR_KEYS: [&str; 2] = ["floor_normal_dev_deg", "floor_local_normal_dev_deg"];

/// The top camera is paired with every this many ring cameras (the thesis matches
/// "neighbouring views"; every ring camera is as near the top one, and each pair costs a
/// ring pair's matching).
const TOP_PAIRS_EVERY: usize = 2;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = Args::parse();
    let mut run = Run::start(
        "photometric_reconstruction",
        &args.common,
        "The two passes of Vlasic §3.3: visual-hull proxy, Eq. 3.3 integration of the part-1 \
         normal maps, pairwise matching and Eq. 3.4 offsets, VRIP merging and screened Poisson \
         hole filling, then again with the pass-1 mesh as proxy, on the studio performer in \
         the skirt; Table 3.1 and distances to the true mesh beside the visual hull.",
    )?;
    let stage = run.stage("normal integration (peer workload)", None);
    let peer = peer_integration_workload(args.peer_size)?;
    stage.finish(format!(
        "{0}²: {1:.2} s, RMS {2:.2} mm",
        args.peer_size, peer.0, peer.1
    ));
    let peer_figures = json!({
        "peer_workload": "normal_integration",
        "peer_size": args.peer_size,
        "peer_integration_s": peer.0,
        "peer_rms_depth_err_mm": peer.1,
        "peer_prior_rms_mm": peer.2,
    });
    if args.peer_only {
        run.headline(Headline::new(
            "peer_integration_s",
            "Eq. 3.3 on the peer workload (build + solve)",
            "s",
        ));
        run.finish(peer_figures)?;
        return Ok(());
    }
    let size = args.size.unwrap_or(if run.quick() { 256 } else { 512 });
    let n_cams = args.cameras.max(2);

    let truth_edge_mm = args.truth_edge_mm.unwrap_or(0.0);
    let surface = if truth_edge_mm > 0.0 {
        TrueSurface::Smooth {
            max_edge_m: truth_edge_mm * 1e-3,
        }
    } else {
        TrueSurface::Polygonal
    };
    // A smooth truth's fine mesh takes binned shadows (exact ones: one ray per light and
    // vertex, minutes per view).
    let bins = match args.wrinkle_light_bins {
        0 => Shadowing::Exact,
        b => Shadowing::Binned(b),
    };
    let smooth_shadows = match surface {
        TrueSurface::Polygonal => Shadowing::Exact,
        TrueSurface::Smooth { .. } => bins,
    };
    let mut pairs: Vec<(usize, usize)> = (0..n_cams).map(|c| (c, (c + 1) % n_cams)).collect();
    if args.top_camera {
        pairs.extend((0..n_cams).step_by(TOP_PAIRS_EVERY).map(|c| (n_cams, c)));
    }
    let top = args.top_camera;
    let layout = Layout {
        ring: n_cams,
        pairs,
    };
    let (params, rparams) = reconstruction_params(&args, run.quick())?;
    // The subjects after the skirt: the Ghost (the sheet-covered figure, §3.4) at the skirt's
    // frame of the exercise motion (`GHOST_FRAME`) and the skirt with the studio's wrinkles
    // (how much of their amplitude survives); each captured, reconstructed and measured alone.
    let others = [
        ("ghost", ghost_subject(), GHOST_FRAME, smooth_shadows),
        (
            "wrinkled",
            skirt_subject().with_wrinkles(Some(WrinkleParams::default())),
            STUDIO_FRAME,
            bins,
        ),
    ];
    let other_run =
        |run: &mut Run,
         (name, subject, frame, shadows): &(&str, DeformationParams, usize, Shadowing),
         control: Option<&SurfaceParams>|
         -> Result<serde_json::Value, Box<dyn std::error::Error>> {
            let t = Instant::now();
            let scene = studio_scene(subject, *frame, n_cams, size, surface, top)?;
            let mut f = subject_run(run, name, &scene, &layout, &rparams, *shadows, control)?;
            f["wall_s"] = json!(t.elapsed().as_secs_f64());
            f["frame"] = json!(frame);
            Ok(f)
        };
    if let Some(name) = args.subject.as_deref() {
        let other = others
            .iter()
            .find(|o| o.0 == name)
            .ok_or_else(|| format!("--subject: ghost or wrinkled, not {name}"))?;
        let f = other_run(&mut run, other, Some(&params))?;
        let mut figures = json!({
            "subject": name,
            "cameras": n_cams,
            "top_camera": top,
            "size_px": size,
            "truth_edge_mm": truth_edge_mm.max(0.0),
        });
        for (key, value) in f.as_object().into_iter().flatten() {
            figures[format!("{name}_{key}")] = value.clone();
        }
        figures[name] = f;
        for h in table_goal_headlines(
            &format!("{name}_"),
            &format!("{name}_coverage_pct"),
            &format!("{name}: "),
            &format!("{name}_hull_surface_median_mm"),
        ) {
            run.headline(h);
        }
        run.headline(
            Headline::new(
                &format!("{name}_seconds_per_frame"),
                &format!("{name}: one frame from normal maps: proxy and both passes"),
                "s",
            )
            .paper("10–15 min per frame from the normal maps, thesis §3.4")
            .goal(Goal::AtMost(30.0)),
        );
        run.headline(
            Headline::new("peak_rss_mb", "peak memory of the whole run", "MB")
                .goal(Goal::AtMost(4000.0)),
        );
        figures["peak_rss_mb"] = json!(example_kit::peak_rss_mb());
        run.finish(figures)?;
        return Ok(());
    }
    // The thesis's frame size, timed first: its ≈ 3.3 GB are freed before the runs below.
    let thesis_size = if run.quick() || args.size.is_some() || args.skirt_only {
        None
    } else {
        let scene = studio_scene(
            &skirt_subject(),
            STUDIO_FRAME,
            n_cams,
            THESIS_SIZE_PX,
            surface,
            top,
        )?;
        Some(thesis_size_timing(
            &run,
            &scene,
            smooth_shadows,
            &layout,
            &rparams,
        )?)
    };
    let scene = studio_scene(&skirt_subject(), STUDIO_FRAME, n_cams, size, surface, top)?;
    let obs = observe(&run, &scene, "skirt", smooth_shadows, n_cams)?;
    let (t_hull, t_capture) = (obs.t_hull, obs.t_capture);
    let Observed {
        cameras,
        mesh,
        truths,
        estimated,
        stacks,
        hull,
        proxies,
        ..
    } = &obs;
    let truth_gap = facet_shading_gap(cameras, mesh)?;
    let exact = obs.exact.as_slice();

    let stage = run.stage("two passes: per-view surfaces, merge, hole filling", None);
    let (rec, t_two_pass) = two_passes(&obs, &layout, &rparams)?;
    let est = &rec.pass1.views;
    let est_err = est.errors_against(truths, proxies, estimated)?;
    let pass2 = &rec.pass2.views;
    let pass2_err = pass2.errors_against(truths, &rec.pass2.proxies, estimated)?;
    stage.finish(format!(
        "pass 1: {}; pass 2: {}",
        summary(&est_err),
        summary(&pass2_err)
    ));
    let t_est = rec.pass1.times.per_view_s;
    let t_pass2 = rec.pass2.times.per_view_s;
    let stage = run.stage("per-view surfaces, exact normals (control)", None);
    let ctl = per_view_surfaces(cameras, exact, proxies, &layout.pairs, Some(hull), &params)?;
    let ctl_err = ctl.errors_against(truths, proxies, exact)?;
    stage.finish(summary(&ctl_err));

    // Table 3.1 on the merged meshes (before hole filling), distances to the true mesh.
    let stage = run.stage("Table 3.1 metrics and distances to the true mesh", None);
    let (table, distances) = score_passes(&obs, &rec, &rparams)?;
    // The baseline that could win: the visual hull's surface (its per-view meshes' vertices).
    let hull_surface_median_mm = hull_surface_median_mm(cameras, proxies, &rparams, mesh)?;
    let perfect = perfect_geometry(&obs, &rec, &rparams)?;
    stage.finish(format!(
        "{table:?}; hull median {hull_surface_median_mm:.1} mm; perfect geometry {perfect}"
    ));

    // Figure 3-5's comparison: the four metrics on the pair (0, 1), same surfaces and band.
    let stage = run.stage("four matching metrics on pair 0-1", Some(4));
    let mut metric_figures = serde_json::Map::new();
    for metric in MatchMetric::ALL {
        let view = |c: usize| MatchView {
            camera: &cameras[c],
            surface: &est.integrated[c],
            guide: None,
            images: Some(&stacks[c]),
        };
        let params = MatchingParams {
            metric,
            ..MatchingParams::default()
        };
        let t = Instant::now();
        let m = match_pair(&view(0), &view(1), Some(hull), &params)?;
        let seconds = t.elapsed().as_secs_f64();
        let (l, r) = (
            depth_errors(&m.left.target, &truths[0], None)?,
            depth_errors(&m.right.target, &truths[1], None)?,
        );
        let pixels = l.pixels + r.pixels;
        let pooled = |a: f64, b: f64| (a * l.pixels as f64 + b * r.pixels as f64) / pixels as f64;
        metric_figures.insert(
            format!("{metric:?}"),
            json!({
                "match_median_mm": pooled(l.median_mm, r.median_mm),
                "match_p95_mm": pooled(l.p95_mm, r.p95_mm),
                "matched_px": pixels,
                "seconds": seconds,
            }),
        );
        stage.inc(1);
    }
    stage.finish(format!("{metric_figures:?}"));

    pictures(&mut run, est, &proxies[0], &truths[0])?;
    let jump = IntegrationParams::jump_threshold_m(0.04, size);
    for (c, (cam, surface)) in cameras.iter().zip(&est.surfaces).enumerate() {
        if let Ok(m) = depth_map_mesh(cam, surface, jump) {
            write_ply(
                run.path(&format!("view_{c}.ply")),
                &m,
                PlyEncoding::default(),
            )?;
        }
    }
    for (name, m) in [
        ("pass1_merged", &rec.pass1.merged.mesh),
        ("pass1_filled", &rec.pass1.filled.mesh),
        ("pass2_merged", &rec.pass2.merged.mesh),
        ("pass2_filled", &rec.pass2.filled.mesh),
    ] {
        write_ply(run.path(&format!("{name}.ply")), m, PlyEncoding::default())?;
    }
    let view0 = depth_map_mesh(&cameras[0], &est.surfaces[0], jump)?;
    let view0_d = surface_distance(&view0, mesh)?;
    let mut inputs = vec![(
        &view0,
        &view0_d.per_vertex_mm,
        "camera 0's surface (pass 1)".to_string(),
    )];
    for (k, (pass, (merged_d, filled_d))) in
        [&rec.pass1, &rec.pass2].iter().zip(&distances).enumerate()
    {
        inputs.push((
            &pass.merged.mesh,
            &merged_d.per_vertex_mm,
            format!("merged (pass {})", k + 1),
        ));
        inputs.push((
            &pass.filled.mesh,
            &filled_d.per_vertex_mm,
            format!("hole-filled (pass {})", k + 1),
        ));
    }
    stages_picture(
        &mut run,
        "stages.png",
        &cameras[0],
        &inputs,
        "Reconstruction stages (as Figure 3-8), coloured by distance to the true mesh",
        "Camera 0's per-view surface, the merged and the hole-filled meshes of both passes, \
         shaded and coloured by each vertex's distance to the true mesh (mm, colour bar).",
    )?;

    let mut figures = json!({
        "cameras": n_cams,
        "top_camera": top,
        "size_px": size,
        "hull_median_mm": est_err.proxy.median_mm,
        "hull_p95_mm": est_err.proxy.p95_mm,
        "integrated_median_mm": est_err.integrated.median_mm,
        "integrated_p95_mm": est_err.integrated.p95_mm,
        "match_median_mm": est_err.matches.median_mm,
        "match_p95_mm": est_err.matches.p95_mm,
        "offset_median_mm": est_err.offset.median_mm,
        "offset_p95_mm": est_err.offset.p95_mm,
        "coverage_pct": est_err.coverage_pct,
        "exact_hull_median_mm": ctl_err.proxy.median_mm,
        "exact_integrated_median_mm": ctl_err.integrated.median_mm,
        "exact_match_median_mm": ctl_err.matches.median_mm,
        "exact_offset_median_mm": ctl_err.offset.median_mm,
        "exact_offset_p95_mm": ctl_err.offset.p95_mm,
        "exact_coverage_pct": ctl_err.coverage_pct,
        "hull_s": t_hull,
        "per_view_s": t_est,
        "integration_s": est.times.integration_s,
        "matching_s": est.times.matching_s,
        "offsets_s": est.times.offsets_s,
        "matches": est.match_stats.iter().map(|m| m.good_matches).sum::<usize>(),
        "discontinuities": est.match_stats.iter().map(|m| m.discontinuities).sum::<usize>(),
        "errors": { "estimated": est_err, "exact": ctl_err },
        "metrics_pair_0_1": metric_figures,
        "pass2_proxy_median_mm": pass2_err.proxy.median_mm,
        "pass2_integrated_median_mm": pass2_err.integrated.median_mm,
        "pass2_match_median_mm": pass2_err.matches.median_mm,
        "pass2_offset_median_mm": pass2_err.offset.median_mm,
        "pass2_offset_p95_mm": pass2_err.offset.p95_mm,
        "pass2_coverage_pct": pass2_err.coverage_pct,
        "pass2_s": t_pass2,
        "pass2_errors": pass2_err,
        "two_pass_s": t_two_pass,
        // End to end from the normal maps: the visual-hull proxy, then both passes.
        "seconds_per_frame": t_hull + t_two_pass,
        "scale_merge_jump": rparams.scale_merge_jump,
        "subpixel_matches": format!("{:?}", rparams.pass1.matching.subpixel),
        "contour_jump_m": rparams.pass1.matching.contour_jump_m,
        "offset_outliers": rparams.pass1.offsets.outliers,
        "robust_offsets": rparams.pass1.offsets.robust,
        "offsets_rejected": est.offsets.iter().map(|o| o.rejected).sum::<usize>(),
        "offsets_down_weighted": est.offsets.iter().map(|o| o.down_weighted).sum::<usize>(),
        "pass2_offsets_rejected": pass2.offsets.iter().map(|o| o.rejected).sum::<usize>(),
        "pass2_offsets_down_weighted": pass2.offsets.iter().map(|o| o.down_weighted).sum::<usize>(),
        "pass2_proxy_jump_m": rparams.pass2.integration.proxy_jump_m,
        "pass2_budget_no_surface_pct": table["pass2"]["budget_no_surface_pct"],
        "pass2_budget_gross_uncovered_pct": table["pass2"]["budget_gross_uncovered_pct"],
        "pass2_budget_merge_lost_pct": table["pass2"]["budget_merge_lost_pct"],
        "table_3_1": table,
        "perfect_geometry": perfect,
        "pass1_coverage_pct": table["pass1"]["coverage_pct"],
        "pass1_normal_dev_deg": table["pass1"]["normal_dev_deg"],
        "pass1_local_normal_dev_deg": table["pass1"]["local_normal_dev_deg"],
        "pass1_surface_median_mm": table["pass1"]["surface_median_mm"],
        "pass2_table_coverage_pct": table["pass2"]["coverage_pct"],
        "normal_dev_deg": table["pass2"]["normal_dev_deg"],
        "local_normal_dev_deg": table["pass2"]["local_normal_dev_deg"],
        "pixel_normal_dev_deg": table["pass2"]["pixel_normal_dev_deg"],
        "pixel_local_normal_dev_deg": table["pass2"]["pixel_local_normal_dev_deg"],
        "surface_median_mm": table["pass2"]["surface_median_mm"],
        "surface_p95_mm": table["pass2"]["surface_p95_mm"],
        "filled_surface_median_mm": table["pass2"]["filled_surface_median_mm"],
        "filled_surface_p95_mm": table["pass2"]["filled_surface_p95_mm"],
        "true_normal_dev_deg": table["pass2"]["true_normal_dev_deg"],
        "true_local_normal_dev_deg": table["pass2"]["true_local_normal_dev_deg"],
        "pass1_true_normal_dev_deg": table["pass1"]["true_normal_dev_deg"],
        "pass2_refine_s": table["pass2"]["refine_s"],
        "refine": rparams.refine.map(|r| json!({
            "lambda": r.lambda,
            "targets": format!("{:?}", r.targets),
            "pass1": rparams.refine_pass1,
            "max_angle_deg": r.max_angle_deg,
            "smoothing": r.smoothing,
            "correction_rounds": r.correction_rounds,
        })),
        "hull_surface_median_mm": hull_surface_median_mm,
    });
    // The true surface: its edge bound, size, capture time and how far
    // its shading normals are from its facets.
    figures["truth_edge_mm"] = json!(truth_edge_mm.max(0.0));
    // Table 3.1 before the refinement and the floors in the goals' form (per vertex).
    for key in UNREFINED_KEYS {
        figures[key] = table["pass2"][key].clone();
    }
    for key in FLOOR_KEYS {
        figures[key] = perfect[key].clone();
    }
    stage_times(&mut figures, &rec, t_two_pass);
    if let Some(t) = thesis_size {
        figures["seconds_per_frame_1024"] = t["seconds_per_frame"].clone();
        figures["thesis_size"] = t;
    }
    figures["truth_vertices"] = json!(mesh.vertex_count());
    figures["truth_capture_s"] = json!(t_capture);
    figures["truth_facet_gap_mean_deg"] = json!(truth_gap.mean_deg);
    figures["truth_facet_gap_median_deg"] = json!(truth_gap.median_deg);
    let mut headlines = Vec::new();
    if !args.skirt_only {
        for other in &others {
            figures[other.0] = other_run(&mut run, other, None)?;
        }
        for key in [
            "coverage_pct",
            "normal_dev_deg",
            "local_normal_dev_deg",
            "surface_median_mm",
            "surface_p95_mm",
            "filled_surface_median_mm",
            "hull_surface_median_mm",
        ]
        .into_iter()
        .chain(UNREFINED_KEYS)
        .chain(FLOOR_KEYS)
        {
            figures[format!("ghost_{key}")] = figures["ghost"][key].clone();
        }
        for key in [
            "wrinkle_amplitude_ratio",
            "wrinkle_filled_amplitude_ratio",
            "wrinkle_hull_amplitude_ratio",
            "wrinkle_correlation",
            "wrinkle_true_rms_mm",
            "wrinkle_max_mm",
            "pixel_footprint_mm",
        ] {
            figures[key] = figures["wrinkled"][key].clone();
        }
        headlines = table_goal_headlines(
            "ghost_",
            "ghost_coverage_pct",
            "Ghost: ",
            "ghost_hull_surface_median_mm",
        );
        headlines.extend([
            Headline::new(
                "ghost_hull_surface_median_mm",
                "Ghost: visual hull surface to the true mesh (median)",
                "mm",
            )
            .baseline(),
            Headline::new(
                "wrinkle_amplitude_ratio",
                "wrinkle amplitude kept by the pass-2 merged mesh (slope)",
                "",
            )
            .note("baseline: the visual hull's slope (wrinkle_hull_amplitude_ratio)"),
            Headline::new(
                "wrinkle_hull_amplitude_ratio",
                "wrinkle amplitude kept by the visual hull (slope)",
                "",
            )
            .baseline(),
            Headline::new(
                "wrinkle_true_rms_mm",
                "true wrinkle height RMS (wrinkle region)",
                "mm",
            )
            .oracle()
            .note("against pixel_footprint_mm"),
        ]);
    }
    if let (Some(f), Some(p)) = (figures.as_object_mut(), peer_figures.as_object()) {
        f.extend(p.clone());
    }
    for h in [
        Headline::new(
            "offset_median_mm",
            "per-view surfaces after Eq. 3.4 (median)",
            "mm",
        )
        .note("part-1 normals; baseline: the visual hull (hull_median_mm)"),
        Headline::new(
            "offset_p95_mm",
            "per-view surfaces after Eq. 3.4 (p95)",
            "mm",
        ),
        Headline::new("hull_median_mm", "visual hull proxy alone (median)", "mm").baseline(),
        Headline::new("hull_p95_mm", "visual hull proxy alone (p95)", "mm").baseline(),
        Headline::new(
            "integrated_median_mm",
            "Eq. 3.3 integration alone (median)",
            "mm",
        ),
        Headline::new(
            "match_median_mm",
            "matched depths, surface metric (median)",
            "mm",
        ),
        Headline::new("coverage_pct", "measured normals kept in a surface", "%")
            .goal(Goal::AtLeast(90.0)),
        Headline::new(
            "exact_offset_median_mm",
            "control: exact normals after Eq. 3.4 (median)",
            "mm",
        )
        .oracle(),
        Headline::new(
            "pass2_offset_median_mm",
            "pass 2 after Eq. 3.4 (median; hole-filled pass-1 mesh as proxy)",
            "mm",
        ),
    ]
    .into_iter()
    .chain(table_goal_headlines(
        "",
        "pass2_table_coverage_pct",
        "",
        "hull_surface_median_mm",
    ))
    .chain([
        Headline::new(
            "filled_surface_median_mm",
            "pass-2 hole-filled mesh to the true mesh (median)",
            "mm",
        ),
        Headline::new(
            "hull_surface_median_mm",
            "visual hull surface to the true mesh (median)",
            "mm",
        )
        .baseline(),
        Headline::new(
            "seconds_per_frame",
            "one frame of 8 views at 512² from normal maps: proxy and both passes",
            "s",
        )
        .goal(Goal::AtMost(30.0)),
        Headline::new(
            "seconds_per_frame_1024",
            "one frame of 8 views at the thesis's 1024² from normal maps: proxy and both passes",
            "s",
        )
        .paper("10–15 min per frame from the normal maps, thesis §3.4")
        .goal(Goal::AtMost(20.0)),
        Headline::new("peak_rss_mb", "peak memory of the whole run", "MB")
            .goal(Goal::AtMost(4000.0)),
        Headline::new("two_pass_s", "both passes, all stages", "s"),
        Headline::new("per_view_s", "per-view stage, all views (one pass)", "s"),
        Headline::new(
            "peer_integration_s",
            "Eq. 3.3 on the peer workload (build + solve)",
            "s",
        )
        .note("compare with bench/peers/normal_integration.py run on the same machine"),
    ])
    .chain(headlines)
    {
        run.headline(h);
    }
    figures["peak_rss_mb"] = json!(example_kit::peak_rss_mb());
    run.finish(figures)?;
    Ok(())
}

/// The per-view stage's parameters (the exact-normal control's) and the two passes' from the
/// command line: sub-pixel matches, Poisson depth 9 (≈ 4 mm cells; 8 with `--quick`), and the
/// options that are off by default.
fn reconstruction_params(
    args: &Args,
    quick: bool,
) -> Result<(SurfaceParams, ReconstructParams), Box<dyn std::error::Error>> {
    let subpixel = match args.subpixel_matches.as_str() {
        "off" => SubPixel::Off,
        "cost" => SubPixel::CostParabola,
        "path" => SubPixel::PathFit,
        other => return Err(format!("--subpixel-matches: off, cost or path, not {other}").into()),
    };
    let outliers = (!args.thesis_offsets).then(|| {
        let d = OffsetOutliers::default();
        OffsetOutliers {
            k: args.outlier_k.unwrap_or(d.k),
            radius_px: args.outlier_radius_px.unwrap_or(d.radius_px),
            floor_m: args.outlier_floor_mm.map_or(d.floor_m, |f| f * 1e-3),
            ..d
        }
    });
    let robust = args.robust_offsets_mm.map(|mm| RobustWeights {
        scale_m: mm * 1e-3,
        ..RobustWeights::default()
    });
    let mut params = SurfaceParams::default();
    params.matching.subpixel = subpixel;
    params.offsets.outliers = outliers;
    params.offsets.robust = robust;
    // The two passes of §3.3 (Poisson depth 9 ≈ 4 mm cells; 8 with --quick).
    let mut rparams = ReconstructParams::default().with_poisson_depth(if quick { 8 } else { 9 });
    rparams.scale_merge_jump = args.scale_merge_jump;
    rparams.pass1.matching.subpixel = subpixel;
    rparams.pass2.matching.subpixel = subpixel;
    for pass in [&mut rparams.pass1, &mut rparams.pass2] {
        pass.offsets.outliers = outliers;
        pass.offsets.robust = robust;
    }
    if args.contour_windows {
        let j = Some(args.contour_jump_m.unwrap_or(0.01));
        params.matching.contour_jump_m = j;
        rparams.pass1.matching.contour_jump_m = j;
        rparams.pass2.matching.contour_jump_m = j;
    }
    if let Some(m) = args.pass1_band_m {
        params.matching.band_m = m;
        rparams.pass1.matching.band_m = m;
    }
    if let Some(on) = args.pass1_coarse_to_fine {
        rparams.pass1.matching.coarse_to_fine = on;
    }
    if let Some(on) = args.pass2_coarse_to_fine {
        rparams.pass2.matching.coarse_to_fine = on;
    }
    if let Some(px) = args.coarse_band_px {
        rparams.pass1.matching.coarse_band_px = px;
        rparams.pass2.matching.coarse_band_px = px;
    }
    if args.pass1_poisson_depth.is_some() {
        rparams.pass1_poisson_depth = args.pass1_poisson_depth;
    }
    if let Some(m) = args.pass2_proxy_jump_m {
        rparams.pass2.integration.proxy_jump_m = m;
    }
    rparams.pass2.integration.layers = args.pass2_layers;
    let targets = match args.refine_targets.as_deref() {
        None => RefineParams::default().targets,
        Some("frontal") => TargetNormals::MostFrontal,
        Some("cos2") => TargetNormals::CosineSquared,
        Some(other) => return Err(format!("--refine-targets: frontal or cos2, not {other}").into()),
    };
    if args.no_refine {
        rparams.refine = None;
    } else {
        let d = RefineParams::default();
        rparams.refine = Some(RefineParams {
            lambda: args.refine_lambda.unwrap_or(d.lambda),
            targets,
            max_angle_deg: args.refine_max_angle_deg.or(d.max_angle_deg),
            smoothing: args.refine_smoothing.unwrap_or(d.smoothing),
            correction_rounds: args.refine_correct_rounds.unwrap_or(d.correction_rounds),
            ..d
        });
        rparams.refine_pass1 = args.refine_pass1;
    }
    if let Some(a) = args.pass2_layer_agreement {
        rparams.pass2.integration.layer_agreement = a;
    }
    Ok((params, rparams))
}

/// The cameras of a run: the ring's count (the top camera, if any, after them) and the pairs
/// that are matched.
struct Layout {
    ring: usize,
    pairs: Vec<(usize, usize)>,
}

/// The studio scene of `subject` at `frame` on a ring of `n_cams` cameras of `size` px, with
/// the dome's top camera after them if `top` (`--top-camera`).
fn studio_scene(
    subject: &DeformationParams,
    frame: usize,
    n_cams: usize,
    size: u32,
    surface: TrueSurface,
    top: bool,
) -> Result<StudioScene, Box<dyn std::error::Error>> {
    let mut scene = StudioScene::with_surface(
        example_kit::data_path("makehuman")?,
        subject,
        frame,
        n_cams,
        size,
        surface,
    )?;
    if top {
        let lens = scene
            .ring
            .cameras
            .first()
            .ok_or("the ring has no camera")?
            .intrinsics;
        let height = scene.stage.centre.y + DomeParams::default().radius_m;
        scene.ring = scene
            .ring
            .clone()
            .with_top_camera(height, scene.root, DVec3::Y, lens)?;
    }
    Ok(scene)
}

/// One subject on the studio ring: the true mesh, its depth maps and exact normals per
/// camera, part 1's normal maps from the light stage's images, the silhouettes and the visual
/// hull rendered per camera.
struct Observed {
    cameras: Vec<Camera>,
    mesh: TriMesh,
    truths: Vec<DepthMap>,
    /// The rasteriser's exact normals of the true mesh (the control's normal maps).
    exact: Vec<NormalMap>,
    estimated: Vec<NormalMap>,
    stacks: Vec<Vec<GrayF32Image>>,
    /// The wrinkled fine surface the cameras saw, when the subject has wrinkles (a smooth
    /// truth without them is not kept: nothing reads it, and at 1024² it is ≈ 0.2 GB).
    fine: Option<FineSurface>,
    silhouettes: Vec<Mask>,
    hull: PolygonalHull,
    proxies: Vec<DepthMap>,
    t_hull: f64,
    /// Wall time of the capture (posing, rendering, shading), s.
    t_capture: f64,
    /// The ring's cameras come first, this many; the top camera (if any) after them.
    ring: usize,
}

/// How a capture casts shadows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Shadowing {
    /// Every light's shadow ray (the studio's default).
    Exact,
    /// Shadows of about this many light-direction bins (`photometric_normals`' full run).
    Binned(usize),
}

/// Captures `scene` on its whole ring (cast shadows as `shadows`), renders the truth, renders
/// the visual hull proxies and estimates part 1's normal maps: the first `ring` cameras'
/// pixel heights on the plane through the root, the others' (the top camera's) on the hull.
fn observe(
    run: &Run,
    scene: &StudioScene,
    name: &str,
    shadows: Shadowing,
    ring: usize,
) -> Result<Observed, Box<dyn std::error::Error>> {
    let cameras = scene.ring.cameras.clone();
    let (n_cams, size) = (
        cameras.len(),
        cameras.first().map_or(0, |c| c.intrinsics.width),
    );
    let stage = run.stage(&format!("{name}: performer and capture"), None);
    let mut spec = scene.capture_spec(scene.ring.clone())?;
    if let Some(lighting) = &mut spec.lighting {
        match shadows {
            Shadowing::Exact => {}
            Shadowing::Binned(bins) => lighting.shadow_light_bins = Some(bins),
        }
    }
    let t = Instant::now();
    let mut frame = scene.capture(spec)?;
    let t_capture = t.elapsed().as_secs_f64();
    // Nothing below reads the shadows' visibility or the capture's own truth buffers (the true
    // mesh is rendered again with both faces): freed before the next peak (a smooth truth's
    // visibility is ≈ 0.35 GB).
    frame.light_visibility = None;
    frame.truth.views = Vec::new();
    let mesh = frame.truth.rendered_mesh(&scene.performer);
    let views = render_both_faces(&cameras, &mesh)?;
    let truths: Vec<DepthMap> = views
        .iter()
        .map(DepthMap::from_view)
        .collect::<Result<_, _>>()?;
    // The rendered views are not kept (≈ 33 bytes a pixel: 0.26 GB at 8 × 1024²).
    let exact = cameras
        .iter()
        .zip(&views)
        .map(|(c, v)| rendered_normals(c, v))
        .collect::<Result<Vec<_>, _>>()?;
    drop(views);
    stage.finish(format!(
        "{n_cams} cameras at {size}², {} true vertices",
        mesh.vertex_count()
    ));

    let stage = run.stage(&format!("{name}: visual hull proxy"), None);
    let silhouettes: Vec<Mask> = frame.observations.iter().map(|o| o.mask.clone()).collect();
    let hull = PolygonalHull::new(&cameras, &silhouettes)?;
    let proxies = hull.depth_maps(&PolygonalHullParams::default())?;
    let t_hull = stage.finish(format!("{} views", proxies.len()));

    let stage = run.stage(
        &format!("{name}: normal maps (part 1)"),
        Some(n_cams as u64),
    );
    let (_, cal_params, normal_params) = scene.photometric_params(WHITE_LEVEL);
    let mut estimated = Vec::with_capacity(n_cams);
    let mut stacks = Vec::with_capacity(n_cams);
    for (c, cam) in cameras.iter().enumerate() {
        let cal = scene.calibrate(cam, &cal_params)?;
        let obs = &mut frame.observations[c];
        let images = pattern_images(obs)?;
        estimated.push(if c < ring {
            estimate_normals(cam, &cal, &images, Some(&obs.mask), &normal_params)?
        } else {
            estimate_normals_on_proxy(
                cam,
                &cal,
                &images,
                Some(&obs.mask),
                &proxies[c],
                &normal_params,
            )?
        });
        stacks.push(matching_images(&images));
        // This camera's images are no longer read (12 MB each at 1024²).
        (obs.patterns, obs.shaded) = (Vec::new(), None);
        stage.inc(1);
    }
    stage.finish("done");

    // Only wrinkles are measured on the fine surface (`subject_run`).
    let fine = frame
        .truth
        .fine
        .filter(|f| f.max_wrinkle_m() > WRINKLE_MIN_M);
    Ok(Observed {
        cameras,
        fine,
        mesh,
        truths,
        exact,
        estimated,
        stacks,
        silhouettes,
        hull,
        proxies,
        t_hull,
        t_capture,
        ring,
    })
}

/// Fine vertices moved more than this by the wrinkles are the wrinkle region, m (as in
/// `photometric_normals`).
const WRINKLE_MIN_M: f64 = 0.5e-3;
/// How far along the smooth surface's normal the reconstruction is looked for, m.
const WRINKLE_REACH_M: f64 = 0.01;
/// Most points drawn per series of the wrinkle scatter plot.
const SCATTER_POINTS: usize = 4000;

/// Another subject through the same two passes (pass `rparams` and ring `pairs`): Table 3.1,
/// distances to the true mesh beside the visual hull's, and — for a subject with wrinkles —
/// how much of the wrinkle displacement the meshes keep ([`displacement_survival`]), with a
/// scatter plot `wrinkles.png`, in all and per wrinkle region (skirt, elbows, knees).
/// With `control` (`--subject`), also the per-view stages of both passes against the true
/// depth maps ([`stage_trace`]) and the per-view stage with the rasteriser's exact normals
/// under those parameters: where the subject's error comes from.
fn subject_run(
    run: &mut Run,
    name: &str,
    scene: &StudioScene,
    layout: &Layout,
    rparams: &ReconstructParams,
    shadows: Shadowing,
    control: Option<&SurfaceParams>,
) -> Result<serde_json::Value, Box<dyn std::error::Error>> {
    let obs = observe(run, scene, name, shadows, layout.ring)?;
    let pairs = &layout.pairs;
    let stage = run.stage(&format!("{name}: two passes"), None);
    let (rec, two_pass_s) = two_passes(&obs, layout, rparams)?;
    let per_view =
        rec.pass2
            .views
            .errors_against(&obs.truths, &rec.pass2.proxies, &obs.estimated)?;
    let exact = obs.exact.as_slice();
    let (table, distances) = score_passes(&obs, &rec, rparams)?;
    let perfect = perfect_geometry(&obs, &rec, rparams)?;
    let zero = vec![0.0; obs.mesh.vertices.len()];
    let (merged_d, filled_d) = &distances[1];
    stages_picture(
        run,
        &format!("stages_{name}.png"),
        &obs.cameras[0],
        &[
            (&obs.mesh, &zero, "true surface".to_string()),
            (
                &rec.pass2.merged.mesh,
                &merged_d.per_vertex_mm,
                "merged (pass 2)".into(),
            ),
            (
                &rec.pass2.filled.mesh,
                &filled_d.per_vertex_mm,
                "hole-filled (pass 2)".into(),
            ),
        ],
        &format!(
            "{name}: the true surface and both pass-2 meshes, coloured by distance to the truth"
        ),
        &format!(
            "The {name} subject's true surface and the pass-2 merged and hole-filled meshes seen \
             from camera 0, coloured by each vertex's distance to the true mesh (mm, colour bar)."
        ),
    )?;
    let hull_median = hull_surface_median_mm(&obs.cameras, &obs.proxies, rparams, &obs.mesh)?;
    stage.finish(format!(
        "{}; hull median {hull_median:.1} mm",
        summary(&per_view)
    ));
    let p2 = &table["pass2"];
    let mut out = json!({
        "table_3_1": table,
        "perfect_geometry": perfect,
        "coverage_pct": p2["coverage_pct"],
        "normal_dev_deg": p2["normal_dev_deg"],
        "local_normal_dev_deg": p2["local_normal_dev_deg"],
        "surface_median_mm": p2["surface_median_mm"],
        "surface_p95_mm": p2["surface_p95_mm"],
        "filled_surface_median_mm": p2["filled_surface_median_mm"],
        "filled_surface_p95_mm": p2["filled_surface_p95_mm"],
        "true_normal_dev_deg": p2["true_normal_dev_deg"],
        "true_local_normal_dev_deg": p2["true_local_normal_dev_deg"],
        "hull_surface_median_mm": hull_median,
        "pass2_offset_median_mm": per_view.offset.median_mm,
        "pass2_coverage_pct": per_view.coverage_pct,
        "true_vertices": obs.mesh.vertices.len(),
        "hull_s": obs.t_hull,
        "two_pass_s": two_pass_s,
    });
    stage_times(&mut out, &rec, two_pass_s);
    for key in UNREFINED_KEYS {
        out[key] = p2[key].clone();
    }
    for key in FLOOR_KEYS {
        out[key] = perfect[key].clone();
    }
    if let (Some(params), Some(o)) = (control, out.as_object_mut()) {
        let stage = run.stage(
            &format!("{name}: per-view trace and exact-normal control"),
            None,
        );
        let pass1 = rec
            .pass1
            .views
            .errors_against(&obs.truths, &obs.proxies, &obs.estimated)?;
        let ctl = per_view_surfaces(
            &obs.cameras,
            exact,
            &obs.proxies,
            pairs,
            Some(&obs.hull),
            params,
        )?;
        let ctl_err = ctl.errors_against(&obs.truths, &obs.proxies, exact)?;
        let trace = json!({
            "hull": stage_trace(&obs.proxies, &obs.truths, &obs.proxies)?,
            "pass1_integrated": stage_trace(&rec.pass1.views.integrated, &obs.truths, &obs.proxies)?,
            "pass1_offsets": stage_trace(&rec.pass1.views.surfaces, &obs.truths, &obs.proxies)?,
            "pass2_proxy": stage_trace(&rec.pass2.proxies, &obs.truths, &obs.proxies)?,
            "pass2_integrated": stage_trace(&rec.pass2.views.integrated, &obs.truths, &obs.proxies)?,
            "pass2_offsets": stage_trace(&rec.pass2.views.surfaces, &obs.truths, &obs.proxies)?,
            "exact_integrated": stage_trace(&ctl.integrated, &obs.truths, &obs.proxies)?,
            "exact_offsets": stage_trace(&ctl.surfaces, &obs.truths, &obs.proxies)?,
        });
        stage.finish(format!(
            "pass 1: {}; exact normals: {}",
            summary(&pass1),
            summary(&ctl_err)
        ));
        o.insert("stage_trace".into(), trace);
        o.insert(
            "errors".into(),
            json!({ "pass1": pass1, "pass2": per_view, "exact": ctl_err }),
        );
        o.insert("offset_median_mm".into(), json!(pass1.offset.median_mm));
        o.insert(
            "exact_offset_median_mm".into(),
            json!(ctl_err.offset.median_mm),
        );
        o.insert("exact_coverage_pct".into(), json!(ctl_err.coverage_pct));
        o.insert("seconds_per_frame".into(), json!(obs.t_hull + two_pass_s));
    }
    for (mesh, file) in [
        (&rec.pass2.merged.mesh, "merged"),
        (&rec.pass2.filled.mesh, "filled"),
    ] {
        write_ply(
            run.path(&format!("{name}_pass2_{file}.ply")),
            mesh,
            PlyEncoding::default(),
        )?;
    }
    let Some(fine) = &obs.fine else {
        return Ok(out);
    };
    // A smooth truth without wrinkles (`--truth-edge-mm`) has a fine surface that nothing
    // displaces: no wrinkle region to measure.
    if fine.max_wrinkle_m() <= WRINKLE_MIN_M {
        return Ok(out);
    }

    // How much of the studio's wrinkle amplitude survives.
    let stage = run.stage(&format!("{name}: wrinkle amplitude"), None);
    let smooth = TriMesh::new(
        fine.mesh
            .vertices
            .iter()
            .zip(&fine.wrinkle_displacement)
            .map(|(v, d)| *v - *d)
            .collect(),
        fine.mesh.faces.clone(),
    )?;
    let region: Vec<bool> = fine
        .wrinkle_displacement
        .iter()
        .map(|d| d.length() > WRINKLE_MIN_M)
        .collect();
    // The baseline that could win: the visual hull's surface, its per-view meshes joined.
    let jump = IntegrationParams::jump_threshold_m(rparams.hull_jump_m, obs.truths[0].width);
    let mut hull_mesh = TriMesh::new(Vec::new(), Vec::new())?;
    for (cam, proxy) in obs.cameras.iter().zip(&obs.proxies) {
        if let Ok(m) = depth_map_mesh(cam, proxy, jump) {
            let base = hull_mesh.vertices.len() as u32;
            hull_mesh.vertices.extend(m.vertices);
            hull_mesh
                .faces
                .extend(m.faces.iter().map(|f| f.map(|v| v + base)));
        }
    }
    let mut survival = serde_json::Map::new();
    let mut scatter = Vec::new();
    for (label, key, mesh) in [
        ("pass-2 merged", "pass2_merged", &rec.pass2.merged.mesh),
        ("pass-2 hole-filled", "pass2_filled", &rec.pass2.filled.mesh),
        ("pass-1 merged", "pass1_merged", &rec.pass1.merged.mesh),
        ("visual hull (baseline)", "hull", &hull_mesh),
    ] {
        let s = displacement_survival(
            &smooth,
            &fine.wrinkle_displacement,
            &region,
            mesh,
            WRINKLE_REACH_M,
        )?;
        survival.insert(key.into(), serde_json::to_value(&s)?);
        scatter.push((label, s));
    }
    // By region: the garment (the skirt's folds) and the creases, each fine vertex off the
    // garment given to the nearest of the crease joints at rest (elbows, knees).
    let mut by_region = serde_json::Map::new();
    let regions = match wrinkle_regions(scene, fine) {
        Ok(r) => r,
        Err(e) => {
            by_region.insert("error".into(), json!(e.to_string()));
            Vec::new()
        }
    };
    for (label, flags) in &regions {
        let mut one = serde_json::Map::new();
        let inside: Vec<bool> = region.iter().zip(flags).map(|(a, b)| *a && *b).collect();
        for (key, mesh) in [
            ("pass2_merged", &rec.pass2.merged.mesh),
            ("pass2_filled", &rec.pass2.filled.mesh),
            ("pass1_merged", &rec.pass1.merged.mesh),
            ("hull", &hull_mesh),
        ] {
            // A region the cameras do not reach (no vertex within reach) is left out.
            if let Ok(s) = displacement_survival(
                &smooth,
                &fine.wrinkle_displacement,
                &inside,
                mesh,
                WRINKLE_REACH_M,
            ) {
                one.insert(key.into(), serde_json::to_value(&s)?);
            }
        }
        by_region.insert((*label).into(), one.into());
    }
    let size = obs.truths[0].width;
    let fx = obs.cameras[0].intrinsics.fx;
    // A pixel's footprint on a surface facing the camera at the ring's radius, mm.
    let pixel_mm = RING_RADIUS_M / fx * 1e3;
    let main = &scatter[0].1;
    stage.finish(format!(
        "slope {:.2} (hull {:.2}), correlation {:.2}, true RMS {:.2} mm, pixel {pixel_mm:.1} mm",
        main.slope, scatter[3].1.slope, main.correlation, main.true_rms_mm
    ));
    let colours = [
        [200, 30, 30],
        [30, 90, 200],
        [230, 150, 20],
        [120, 120, 120],
    ];
    let mut chart = Chart::new(
        format!("Wrinkle amplitude that survives ({name}, {size}² px)"),
        "true wrinkle height along the smooth normal (mm)",
        "reconstructed height (mm)",
    );
    chart.y_from_zero = false;
    chart.marker_px = 1;
    chart.legend = LegendPosition::UpperLeft;
    let lim = 1.5 * main.true_rms_mm.max(0.5) * 2f64.sqrt() + 1.0;
    chart.x_range = Some((-lim, lim));
    chart.y_range = Some((-2.0 * lim, 2.0 * lim));
    for ((label, s), colour) in scatter.iter().zip(colours).rev() {
        let step = s.heights_mm.len().div_ceil(SCATTER_POINTS).max(1);
        chart = chart.with(Series::new(
            format!("{label}: slope {:.2}, r = {:.2}", s.slope, s.correlation),
            colour,
            Style::Markers,
            s.heights_mm
                .iter()
                .step_by(step)
                .map(|h| (h[0], h[1]))
                .collect(),
        ));
    }
    chart = chart.with(Series::new(
        "all amplitude kept (slope 1)",
        [0, 0, 0],
        Style::Dashed,
        vec![(-lim, -lim), (lim, lim)],
    ));
    run.save_picture(
        &format!("wrinkles_{name}.png"),
        &chart.draw()?,
        "Per wrinkle-region vertex of the true fine surface: the true wrinkle height along the \
         smooth surface's normal against the reconstructed mesh's height there (nearest hit \
         along ±normal within 1 cm), for the pass-2 merged and hole-filled meshes, pass 1's \
         merged mesh and the visual hull (the baseline); the legend gives each fit's slope \
         (amplitude ratio) and correlation.",
    )?;
    if let Some(o) = out.as_object_mut() {
        o.insert("wrinkle_survival".into(), survival.into());
        o.insert("wrinkle_survival_by_region".into(), by_region.into());
        o.insert("wrinkle_amplitude_ratio".into(), json!(main.slope));
        o.insert(
            "wrinkle_filled_amplitude_ratio".into(),
            json!(scatter[1].1.slope),
        );
        o.insert(
            "wrinkle_hull_amplitude_ratio".into(),
            json!(scatter[3].1.slope),
        );
        o.insert("wrinkle_correlation".into(), json!(main.correlation));
        o.insert("wrinkle_true_rms_mm".into(), json!(main.true_rms_mm));
        o.insert("wrinkle_max_mm".into(), json!(fine.max_wrinkle_m() * 1e3));
        o.insert(
            "wrinkle_region_vertices".into(),
            json!(region.iter().filter(|&&r| r).count()),
        );
        o.insert("pixel_footprint_mm".into(), json!(pixel_mm));
    }
    Ok(out)
}

/// Where a per-view stage's depth is wrong, over the pixels where both it and the true depth
/// map have a surface, all views pooled: the pixel count, the median |error| and the share
/// (%) off by more than 1 cm (Table 3.1's `near_m`), 3 cm (pass 2's band about its proxy)
/// and 10 cm (pass 1's matching band about the integrated surface): gross errors that the
/// next stage's band cannot bring back, against small ones it can. The same split by how far
/// the visual hull is from the truth at the pixel (`hull`: ≤ 3 cm, 3–10 cm, > 10 cm — the
/// concavities, such as a sheet's folds, that the silhouettes cannot see): each class's share
/// of the pixels and the stage's median error there.
fn stage_trace(
    stage: &[DepthMap],
    truths: &[DepthMap],
    hull: &[DepthMap],
) -> Result<serde_json::Value, Box<dyn std::error::Error>> {
    if stage.len() != truths.len() || hull.len() != truths.len() {
        return Err(format!(
            "{} stage maps and {} hull maps for {} truths",
            stage.len(),
            hull.len(),
            truths.len()
        )
        .into());
    }
    // (|stage − truth|, |hull − truth|; NaN where the hull has no surface).
    let mut err: Vec<(f64, f64)> = Vec::new();
    for ((s, t), h) in stage.iter().zip(truths).zip(hull) {
        if s.depth_m.len() != t.depth_m.len() || h.depth_m.len() != t.depth_m.len() {
            return Err("a stage map, its truth and its hull differ in size".into());
        }
        err.extend(
            s.depth_m
                .iter()
                .zip(&t.depth_m)
                .zip(&h.depth_m)
                .filter(|((a, b), _)| a.is_finite() && b.is_finite())
                .map(|((a, b), c)| ((a - b).abs(), (c - b).abs())),
        );
    }
    let median_mm = |e: &mut Vec<f64>| {
        e.sort_by(f64::total_cmp);
        e.get(e.len() / 2).map_or(f64::NAN, |m| m * 1e3)
    };
    let n = err.len().max(1) as f64;
    let over = |m: f64| 100.0 * err.iter().filter(|e| e.0 > m).count() as f64 / n;
    let mut by_hull = serde_json::Map::new();
    for (label, lo, hi) in [
        ("hull_within_3cm", 0.0, 0.03),
        ("hull_3_to_10cm", 0.03, 0.10),
        ("hull_over_10cm", 0.10, f64::INFINITY),
    ] {
        let mut e: Vec<f64> = err
            .iter()
            .filter(|e| e.1 >= lo && e.1 < hi)
            .map(|e| e.0)
            .collect();
        by_hull.insert(
            label.into(),
            json!({ "share_pct": 100.0 * e.len() as f64 / n, "median_mm": median_mm(&mut e) }),
        );
    }
    let mut all: Vec<f64> = err.iter().map(|e| e.0).collect();
    Ok(json!({
        "pixels": err.len(),
        "median_mm": median_mm(&mut all),
        "over_1cm_pct": over(0.01),
        "over_3cm_pct": over(0.03),
        "over_10cm_pct": over(0.10),
        "by_hull_error": by_hull,
    }))
}

/// A named region of the fine surface: a flag per fine vertex.
type Region = (&'static str, Vec<bool>);

/// The wrinkle regions of `fine` (the studio's `WrinkleParams::default()`: the skirt's garment
/// folds and the elbow and knee creases) as per-fine-vertex flags: `skirt` for the vertices
/// of the garment's fine faces, and every other vertex given to `elbows` or `knees` by its
/// nearest crease joint at rest (rest positions against the skeleton at its rest pose).
fn wrinkle_regions(
    scene: &StudioScene,
    fine: &FineSurface,
) -> Result<Vec<Region>, Box<dyn std::error::Error>> {
    let performer = &scene.performer;
    let n = fine.mesh.vertices.len();
    let wrinkles = performer
        .wrinkles()
        .ok_or("wrinkle regions: the performer has no wrinkle model")?;
    let garment_faces = wrinkles.garment_faces();
    if garment_faces.len() != fine.mesh.faces.len() || fine.rest_positions.len() != n {
        return Err("wrinkle regions: the fine surface is not the wrinkle model's".into());
    }
    let mut skirt = vec![false; n];
    for (f, g) in fine.mesh.faces.iter().zip(garment_faces) {
        if *g {
            for &v in f {
                skirt[v as usize] = true;
            }
        }
    }
    let skeleton = &performer.skeleton;
    let joints = skeleton
        .forward_kinematics(&skeleton.rest_pose())?
        .joint_positions();
    let mut creases = Vec::new();
    for (joint, elbow) in [
        ("l_elbow", true),
        ("r_elbow", true),
        ("l_knee", false),
        ("r_knee", false),
    ] {
        let j = skeleton
            .joint_index(joint)
            .ok_or_else(|| format!("wrinkle regions: no joint {joint}"))?;
        creases.push((joints[j], elbow));
    }
    let nearest_is_elbow: Vec<bool> = fine
        .rest_positions
        .iter()
        .map(|p| {
            creases
                .iter()
                .min_by(|a, b| a.0.distance(*p).total_cmp(&b.0.distance(*p)))
                .is_some_and(|c| c.1)
        })
        .collect();
    let elbows = (0..n).map(|i| !skirt[i] && nearest_is_elbow[i]).collect();
    let knees = (0..n).map(|i| !skirt[i] && !nearest_is_elbow[i]).collect();
    Ok(vec![("skirt", skirt), ("elbows", elbows), ("knees", knees)])
}

/// Table 3.1 of each pass (by name) and its merged and filled meshes' distances to the truth.
type PassScores = (
    serde_json::Map<String, serde_json::Value>,
    Vec<(SurfaceDistance, SurfaceDistance)>,
);

/// Table 3.1 of both passes (on the merged meshes, before hole filling), each pass's coverage
/// budget against the true depth maps, the merged and filled meshes' distances to the true
/// mesh, and each merged mesh's Table 3.1 vertex figures against the exact normals
/// (the true-normal control), all of the subject `obs`. A refined pass is also scored before
/// its refinement (`unrefined_*`: Table 3.1, the control and the distances of
/// [`Pass::unrefined`]), because the refinement fits the mesh to the normals Table 3.1 then
/// scores it against; an unrefined pass repeats its own figures there. With fewer ring
/// cameras than cameras (`--top-camera`), each pass also gets Table 3.1 over the ring's
/// measured normals alone (`ring_*` keys), comparable with a run without the top camera.
fn score_passes(
    obs: &Observed,
    rec: &Reconstruction,
    rparams: &ReconstructParams,
) -> Result<PassScores, Box<dyn std::error::Error>> {
    let Observed {
        cameras,
        estimated,
        exact,
        silhouettes,
        mesh: truth,
        truths,
        ring,
        ..
    } = obs;
    let ring = *ring;
    let mut table = serde_json::Map::new();
    let mut distances = Vec::new();
    for (name, pass, surface) in [
        ("pass1", &rec.pass1, &rparams.pass1),
        ("pass2", &rec.pass2, &rparams.pass2),
    ] {
        let m = table_metrics(
            cameras,
            estimated,
            silhouettes,
            &pass.views.surfaces,
            &pass.merged.mesh,
            &MetricParams::default(),
        )?;
        let ring_table = if ring < cameras.len() {
            let r = table_metrics(
                &cameras[..ring],
                &estimated[..ring],
                &silhouettes[..ring],
                &pass.views.surfaces[..ring],
                &pass.merged.mesh,
                &MetricParams::default(),
            )?;
            json!({
                "ring_coverage_pct": r.coverage_pct,
                "ring_normal_dev_deg": r.normal_dev_deg,
                "ring_local_normal_dev_deg": r.local_normal_dev_deg,
            })
        } else {
            json!({})
        };
        // The merged mesh's normals against the true (rendered) normals: the control for a
        // stage that fits the measured normals (`--refine`), which must not just fit their noise.
        let t = table_metrics(
            cameras,
            exact,
            silhouettes,
            &pass.views.surfaces,
            &pass.merged.mesh,
            &MetricParams::default(),
        )?;
        let merged_d = surface_distance(&pass.merged.mesh, truth)?;
        let filled_d = surface_distance(&pass.filled.mesh, truth)?;
        // The same before the refinement (the refined mesh's own figures when it did not run).
        let (um, ut, ud) = match &pass.unrefined {
            Some(mesh) => {
                let score = |normals: &[NormalMap]| {
                    table_metrics(
                        cameras,
                        normals,
                        silhouettes,
                        &pass.views.surfaces,
                        mesh,
                        &MetricParams::default(),
                    )
                };
                let d = surface_distance(mesh, truth)?;
                (score(estimated)?, score(exact)?, Some(d))
            }
            None => (m, t, None),
        };
        let ud = ud.as_ref().unwrap_or(&merged_d);
        // Where the uncovered measured normals were lost (the coverage budget).
        let budget = coverage_budget(
            cameras,
            estimated,
            silhouettes,
            &BudgetInputs {
                proxies: &pass.proxies,
                views: &pass.views,
                integration: &surface.integration,
                reference: truths,
            },
            &pass.merged.mesh,
            &MetricParams::default(),
        )?;
        table.insert(
            name.into(),
            json!({
                "coverage_pct": m.coverage_pct,
                "normal_dev_deg": m.normal_dev_deg,
                "local_normal_dev_deg": m.local_normal_dev_deg,
                "pixel_normal_dev_deg": m.pixel_normal_dev_deg,
                "pixel_local_normal_dev_deg": m.pixel_local_normal_dev_deg,
                "vertex_samples": m.vertex_samples,
                "measured_px": m.measured_px,
                "covered_px": m.covered_px,
                "surface_median_mm": merged_d.median_mm,
                "surface_p95_mm": merged_d.p95_mm,
                "filled_surface_median_mm": filled_d.median_mm,
                "filled_surface_p95_mm": filled_d.p95_mm,
                "merged_vertices": pass.merged.mesh.vertices.len(),
                "filled_vertices": pass.filled.mesh.vertices.len(),
                "samples": pass.samples,
                "proxy_s": pass.times.proxy_s,
                "per_view_s": pass.times.per_view_s,
                "merge_s": pass.times.merge_s,
                "poisson_s": pass.times.poisson_s,
                "refine_s": pass.times.refine_s,
                "refine": pass.refined.map(|r| json!({
                    "targeted": r.targeted,
                    "faces": r.faces,
                    "mean_move_mm": r.mean_move_mm,
                    "max_move_mm": r.max_move_mm,
                    "targets_s": r.targets_s,
                    "solve_s": r.solve_s,
                })),
                "true_normal_dev_deg": t.normal_dev_deg,
                "true_local_normal_dev_deg": t.local_normal_dev_deg,
                "unrefined_coverage_pct": um.coverage_pct,
                "unrefined_normal_dev_deg": um.normal_dev_deg,
                "unrefined_local_normal_dev_deg": um.local_normal_dev_deg,
                "unrefined_pixel_normal_dev_deg": um.pixel_normal_dev_deg,
                "unrefined_pixel_local_normal_dev_deg": um.pixel_local_normal_dev_deg,
                "unrefined_vertex_samples": um.vertex_samples,
                "unrefined_true_normal_dev_deg": ut.normal_dev_deg,
                "unrefined_true_local_normal_dev_deg": ut.local_normal_dev_deg,
                "unrefined_surface_median_mm": ud.median_mm,
                "unrefined_surface_p95_mm": ud.p95_mm,
                "coverage_budget": budget,
                "budget_no_surface_pct": budget.pct(budget.no_surface_px()),
                "budget_gross_uncovered_pct": budget.pct(budget.gross_uncovered_px),
                "budget_merge_lost_pct": budget.pct(budget.merge_lost_px()),
            }),
        );
        if let (Some(entry), Some(ring_keys)) = (
            table.get_mut(name).and_then(|e| e.as_object_mut()),
            ring_table.as_object(),
        ) {
            entry.extend(ring_keys.clone());
        }
        distances.push((merged_d, filled_d));
    }
    Ok((table, distances))
}

/// Table 3.1 of a perfect geometry: the subject's true depth maps merged as the passes merge
/// their per-view surfaces (same cameras, voxels and ramps, so the same marching-cubes mesh
/// form and vertex density as a pass's merged mesh), scored per vertex as Table 3.1 scores a
/// reconstruction: against the part-1 normals that score the passes on all of its covered
/// pixels (`measured_*`), against the exact normals (`exact_*`), and against the part-1
/// normals on only the pixels pass 2's merged mesh covers (`floor_*`; the perfect geometry
/// covers more pixels, and harder grazing ones, than a reconstruction).
///
/// `floor_normal_dev_deg` and `floor_local_normal_dev_deg` are the floors of Table 3.1's
/// normal and local normal deviation in the goals' own form (per vertex of a merged mesh, on
/// the pixels the reconstruction is scored on): what the correct geometry scores against
/// these normal maps. A reconstruction that scores below them fits the part-1 normals'
/// errors, not the surface (docs: "Floors of Table 3.1"). On the polygonal truth
/// (`--truth-edge-mm 0`) they also carry its facets' gap from its shading normals; the
/// smooth truth removes it.
///
/// Beside them, part 1's own error on pass 2's pixels in pixel form (not Table 3.1's form,
/// and not a floor of it): the mean angle between the part-1 and the exact normals
/// (`pixel_part1_vs_exact_deg`), and over each covered pixel's right and lower covered
/// neighbours |∠(exact) − ∠(part 1)| (`pixel_part1_vs_exact_local_deg`).
fn perfect_geometry(
    obs: &Observed,
    rec: &Reconstruction,
    rparams: &ReconstructParams,
) -> Result<serde_json::Value, Box<dyn std::error::Error>> {
    let exact = &obs.exact;
    let views: Vec<MergeView> = obs
        .cameras
        .iter()
        .zip(&obs.truths)
        .map(|(c, d)| MergeView::new(c, d))
        .collect();
    let merged = merge_views(&views, &rparams.merge_at_width(&obs.truths))?;
    let score = |normals: &[NormalMap]| {
        table_metrics(
            &obs.cameras,
            normals,
            &obs.silhouettes,
            &obs.truths,
            &merged.mesh,
            &MetricParams::default(),
        )
    };
    let (measured, true_normals) = (score(&obs.estimated)?, score(exact)?);
    let pass2_covered = covered_pixels(
        &obs.cameras,
        &obs.estimated,
        &obs.silhouettes,
        &rec.pass2.views.surfaces,
        &rec.pass2.merged.mesh,
        &MetricParams::default(),
    )?;
    let on_pass2: Vec<NormalMap> = obs
        .estimated
        .iter()
        .zip(&pass2_covered)
        .map(|(n, covered)| {
            let mut n = n.clone();
            for (v, &c) in n.valid.iter_mut().zip(covered) {
                *v &= c;
            }
            n
        })
        .collect();
    let floor = score(&on_pass2)?;
    drop(on_pass2);
    let angle = |a: DVec3, b: DVec3| a.dot(b).clamp(-1.0, 1.0).acos().to_degrees();
    let (mut part1_sum, mut part1_n, mut local_sum, mut local_n) = (0.0, 0usize, 0.0, 0usize);
    for ((est, ex), covered) in obs.estimated.iter().zip(exact).zip(&pass2_covered) {
        let w = est.width as usize;
        let ok = |i: usize| covered[i] && ex.valid[i];
        for i in (0..covered.len()).filter(|&i| ok(i)) {
            part1_sum += angle(est.normals[i], ex.normals[i]);
            part1_n += 1;
            let right = (i % w + 1 < w).then_some(i + 1);
            let down = (i + w < covered.len()).then_some(i + w);
            for j in [right, down].into_iter().flatten().filter(|&j| ok(j)) {
                let (e, m) = (
                    angle(ex.normals[i], ex.normals[j]),
                    angle(est.normals[i], est.normals[j]),
                );
                local_sum += (e - m).abs();
                local_n += 1;
            }
        }
    }
    let d = surface_distance(&merged.mesh, &obs.mesh)?;
    Ok(json!({
        "measured_coverage_pct": measured.coverage_pct,
        "measured_normal_dev_deg": measured.normal_dev_deg,
        "measured_local_normal_dev_deg": measured.local_normal_dev_deg,
        "floor_normal_dev_deg": floor.normal_dev_deg,
        "floor_local_normal_dev_deg": floor.local_normal_dev_deg,
        "floor_vertex_samples": floor.vertex_samples,
        "floor_pass2_px_covered_pct": floor.coverage_pct,
        "pixel_part1_vs_exact_deg": part1_sum / part1_n.max(1) as f64,
        "pixel_part1_vs_exact_local_deg": local_sum / local_n.max(1) as f64,
        "exact_coverage_pct": true_normals.coverage_pct,
        "exact_normal_dev_deg": true_normals.normal_dev_deg,
        "exact_local_normal_dev_deg": true_normals.local_normal_dev_deg,
        "merged_vertices": merged.mesh.vertices.len(),
        "surface_median_mm": d.median_mm,
        "surface_p95_mm": d.p95_mm,
    }))
}

/// Both passes from `obs`'s part-1 normal maps, with the hull's depth maps rendered in
/// `observe` (timed in `t_hull`) as pass 1's proxies, and their wall time, s.
fn two_passes(
    obs: &Observed,
    layout: &Layout,
    rparams: &ReconstructParams,
) -> Result<(Reconstruction, f64), Box<dyn std::error::Error>> {
    let t = Instant::now();
    let rec = reconstruct_from_hull_depths(
        &obs.cameras,
        &obs.estimated,
        &obs.hull,
        obs.proxies.clone(),
        0.0,
        &layout.pairs,
        rparams,
    )?;
    Ok((rec, t.elapsed().as_secs_f64()))
}

/// Image side of the thesis's cameras, px (Vlasic 2010 §3.4: eight 1024 × 1024 views).
const THESIS_SIZE_PX: u32 = 1024;

/// One frame of `scene` (the skirt at [`THESIS_SIZE_PX`]) captured and reconstructed, timed
/// only: `seconds_per_frame` (the visual-hull proxy and both passes, from the normal maps)
/// and every stage's time (`pass1_*_s`, `pass2_*_s`). The accuracy figures are the run's at
/// its own size, where the truth's scoring fits in memory beside the other subjects.
fn thesis_size_timing(
    run: &Run,
    scene: &StudioScene,
    shadows: Shadowing,
    layout: &Layout,
    rparams: &ReconstructParams,
) -> Result<serde_json::Value, Box<dyn std::error::Error>> {
    let obs = observe(run, scene, "skirt at 1024² (timing)", shadows, layout.ring)?;
    let stage = run.stage("skirt at 1024² (timing): two passes", None);
    let (rec, two_pass_s) = two_passes(&obs, layout, rparams)?;
    let seconds = obs.t_hull + two_pass_s;
    let mut figures = json!({
        "size_px": THESIS_SIZE_PX,
        "seconds_per_frame": seconds,
        "hull_s": obs.t_hull,
        "two_pass_s": two_pass_s,
    });
    stage_times(&mut figures, &rec, two_pass_s);
    stage.finish(format!("{seconds:.1} s per frame"));
    Ok(figures)
}

/// Where the two passes' wall time goes: for each pass (`pass1_`, `pass2_`) the proxy, the
/// per-view stage (integration, matching, offsets), the merge (preparing the views, finding
/// the blocks, filling the voxels, finding the cells, marching cubes), the refinement
/// (targets, solve) and the hole filling (samples, solve, cells, marching cubes), s; and
/// `two_pass_other_s`, the part of `two_pass_s` outside every pass's stages (the hull's
/// samples, the passes' bookkeeping).
fn stage_times(figures: &mut serde_json::Value, rec: &Reconstruction, two_pass_s: f64) {
    let mut staged = 0.0;
    for (name, pass) in [("pass1", &rec.pass1), ("pass2", &rec.pass2)] {
        let (t, v, m, p) = (
            &pass.times,
            &pass.views.times,
            &pass.merged.times,
            &pass.filled.times,
        );
        let refine = pass.refined.unwrap_or_default();
        staged += t.proxy_s + t.per_view_s + t.merge_s + t.refine_s + t.poisson_s;
        for (key, value) in [
            ("proxy_s", t.proxy_s),
            ("per_view_s", t.per_view_s),
            ("integration_s", v.integration_s),
            ("matching_s", v.matching_s),
            ("offsets_s", v.offsets_s),
            ("merge_s", t.merge_s),
            ("merge_prepare_s", m.prepare_s),
            ("merge_blocks_s", m.blocks_s),
            ("merge_fill_s", m.fill_s),
            ("merge_cells_s", m.cells_s),
            ("merge_march_s", m.march_s),
            ("refine_s", t.refine_s),
            ("refine_targets_s", refine.targets_s),
            ("refine_solve_s", refine.solve_s),
            ("poisson_s", t.poisson_s),
            ("poisson_samples_s", p.samples_s),
            ("poisson_solve_s", p.solve_s),
            ("poisson_cells_s", p.cells_s),
            ("poisson_march_s", p.march_s),
        ] {
            figures[format!("{name}_{key}")] = json!(value);
        }
    }
    figures["two_pass_other_s"] = json!(two_pass_s - staged);
}

/// The median distance of the visual hull's surface (its per-view meshes' vertices) to the
/// true mesh, mm: the baseline that could win.
fn hull_surface_median_mm(
    cameras: &[Camera],
    proxies: &[DepthMap],
    rparams: &ReconstructParams,
    truth: &TriMesh,
) -> Result<f64, Box<dyn std::error::Error>> {
    let hull_points: Vec<DVec3> = hull_samples(cameras, proxies, rparams.hull_jump_m, 1.0)?
        .iter()
        .map(|s| s.position)
        .collect();
    let hull_d = points_to_surface(&hull_points, &MeshQuery::new(truth)?)?;
    let mut hull_mm: Vec<f64> = hull_d.per_vertex.iter().map(|d| d * 1e3).collect();
    hull_mm.sort_by(f64::total_cmp);
    Ok(hull_mm[hull_mm.len() / 2])
}

/// `inputs` (mesh, per-vertex distance to the truth in mm, label) side by side as seen by
/// `camera`, coloured by the distance, with a colour bar: saved as `file`.
fn stages_picture(
    run: &mut Run,
    file: &str,
    camera: &Camera,
    inputs: &[(&TriMesh, &Vec<f64>, String)],
    title: &str,
    caption: &str,
) -> Result<(), Box<dyn std::error::Error>> {
    let panels = inputs
        .iter()
        .map(
            |(m, e, label)| -> Result<RgbImage, Box<dyn std::error::Error>> {
                Ok(titled(
                    &error_render(m, e, camera, MESH_ERROR_MAX_MM)?,
                    label,
                    None,
                )?)
            },
        )
        .collect::<Result<Vec<_>, _>>()?;
    let ramp = |t: f64| error_colour(Some(t * MESH_ERROR_MAX_MM), MESH_ERROR_MAX_MM);
    let img = with_colour_bar(
        &titled(
            &side_by_side(&panels)?,
            title,
            Some("seen from camera 0; part-1 normals"),
        )?,
        &ColourBar {
            label: "distance to the true surface (mm)",
            min: 0.0,
            max: MESH_ERROR_MAX_MM,
            ramp: &ramp,
            note: Some("above the top: red"),
        },
    )?;
    run.save_picture(file, &img, caption)?;
    Ok(())
}

/// `mesh` seen from `cam`, coloured by per-vertex distance (mm) up to `max_mm`, shaded.
fn error_render(
    mesh: &TriMesh,
    err_mm: &[f64],
    cam: &Camera,
    max_mm: f64,
) -> Result<RgbImage, Box<dyn std::error::Error>> {
    let params = RenderParams::default()
        .with_buffers(Buffers {
            triangle: true,
            normal: true,
            ..Buffers::MASK_ONLY
        })
        .with_cull_back_faces(false)
        .with_allow_empty(true);
    let view = Rasterizer::new(cam).render(mesh, &params)?;
    Ok(RgbImage::from_fn(view.width, view.height, |x, y| {
        let i = (y * view.width + x) as usize;
        let t = view.triangle[i];
        if t == NO_TRIANGLE {
            return Rgb([255, 255, 255]);
        }
        let f = mesh.faces[t as usize];
        let e = f.iter().map(|&v| err_mm[v as usize]).sum::<f64>() / 3.0;
        let shade = 0.35 + 0.65 * f64::from(view.normal_camera[i][2].abs());
        Rgb(error_colour(Some(e), max_mm).map(|c| (f64::from(c) * shade) as u8))
    }))
}

fn summary(e: &SurfaceErrors) -> String {
    format!(
        "proxy {:.1} mm, integrated {:.1} mm, matches {:.1} mm, offsets {:.1} mm (medians), \
         coverage {:.1} %",
        e.proxy.median_mm,
        e.integrated.median_mm,
        e.matches.median_mm,
        e.offset.median_mm,
        e.coverage_pct
    )
}

/// Camera 0's error per stage and its matches.
fn pictures(
    run: &mut Run,
    out: &ViewSurfaces,
    proxy: &DepthMap,
    truth: &DepthMap,
) -> Result<(), Box<dyn std::error::Error>> {
    let (w, h) = (truth.width, truth.height);
    let error_image = |m: &DepthMap| {
        RgbImage::from_fn(w, h, |x, y| {
            let i = m.index(x, y);
            let (a, b) = (m.depth_m[i], truth.depth_m[i]);
            if b.is_nan() {
                Rgb([255, 255, 255])
            } else if a.is_nan() {
                Rgb(error_colour(None, ERROR_MAX_MM))
            } else {
                Rgb(error_colour(Some((a - b).abs() * 1e3), ERROR_MAX_MM))
            }
        })
    };
    let panels = side_by_side(&[
        titled(&error_image(proxy), "visual hull (proxy)", None)?,
        titled(
            &error_image(&out.integrated[0]),
            "integrated (Eq. 3.3)",
            None,
        )?,
        titled(&error_image(&out.surfaces[0]), "offset (Eq. 3.4)", None)?,
    ])?;
    let ramp = |t: f64| error_colour(Some(t * ERROR_MAX_MM), ERROR_MAX_MM);
    let img = with_colour_bar(
        &titled(
            &panels,
            "Camera 0: per-view surface, depth error along the rays",
            Some("part-1 normals; against the true depth map"),
        )?,
        &ColourBar {
            label: "depth error (mm)",
            min: 0.0,
            max: ERROR_MAX_MM,
            ramp: &ramp,
            note: Some("grey: no surface; values above the top in red"),
        },
    )?;
    run.save_picture(
        "per_view_error.png",
        &img,
        "Camera 0's depth error (mm, colour bar) of the visual hull, the integrated surface and \
         the surface after matching offsets; grey: no surface.",
    )?;
    let matched = RgbImage::from_fn(w, h, |x, y| {
        let i = truth.index(x, y);
        if out.breaks[0].get(x, y) {
            Rgb([220, 30, 30])
        } else if out.matched[0].iter().any(|m| !m.depth_m[i].is_nan()) {
            Rgb([40, 180, 60])
        } else if !out.integrated[0].depth_m[i].is_nan() {
            Rgb([150, 150, 150])
        } else {
            Rgb([255, 255, 255])
        }
    });
    run.save_picture(
        "matching.png",
        &titled(
            &matched,
            "Camera 0: matches",
            Some("green: matched; red: discontinuity; grey: unmatched"),
        )?,
        "Camera 0's pixels matched in its neighbours (green), the discontinuities matching \
         found (red) and integrated pixels without a match (grey), as in Figure 3-6.",
    )?;
    Ok(())
}

/// `bench/peers/normal_integration.py` regenerated: returns (seconds, RMS depth error mm,
/// prior RMS mm).
fn peer_integration_workload(n: u32) -> Result<(f64, f64, f64), Box<dyn std::error::Error>> {
    const K: usize = 12;
    let nf = f64::from(n);
    let f = 600.0 * nf / 512.0;
    let c = (nf - 1.0) / 2.0;
    let a: Vec<f64> = SplitMix64::new(60)
        .uniform(K)
        .iter()
        .map(|u| 0.1 * (2.0 * u - 1.0))
        .collect();
    let mu: Vec<f64> = SplitMix64::new(61)
        .uniform(K)
        .iter()
        .map(|u| nf * u)
        .collect();
    let nu: Vec<f64> = SplitMix64::new(62)
        .uniform(K)
        .iter()
        .map(|u| nf * u)
        .collect();
    let s: Vec<f64> = SplitMix64::new(63)
        .uniform(K)
        .iter()
        .map(|u| nf * (0.05 + 0.1 * u))
        .collect();
    let noise = SplitMix64::new(64).normal((n * n) as usize);
    let k = Intrinsics::new(f, f, c, c, n, n)?;
    let camera = Camera::from_camera_from_world(k, RadialDistortion::NONE, DAffine3::IDENTITY)?;
    let px = (n * n) as usize;
    let (mut normals, mut truth, mut prior) = (
        Vec::with_capacity(px),
        Vec::with_capacity(px),
        Vec::with_capacity(px),
    );
    for v in 0..n {
        for u in 0..n {
            let (uf, vf) = (f64::from(u), f64::from(v));
            let (mut d, mut du, mut dv) = (1.0, 0.0, 0.0);
            for j in 0..K {
                let g = a[j]
                    * (-((uf - mu[j]).powi(2) + (vf - nu[j]).powi(2)) / (2.0 * s[j] * s[j])).exp();
                d += g;
                du += -g * (uf - mu[j]) / (s[j] * s[j]);
                dv += -g * (vf - nu[j]) / (s[j] * s[j]);
            }
            let r = DVec3::new((uf - c) / f, (vf - c) / f, 1.0);
            let pu = du * r + DVec3::X * (d / f);
            let pv = dv * r + DVec3::Y * (d / f);
            normals.push(-pu.cross(pv).normalize());
            // The peer's depths are camera z; DepthMap's are along the unit ray (× |r|).
            let i = (v * n + u) as usize;
            truth.push(d * r.length());
            prior.push((d + 0.01 * noise[i]) * r.length());
        }
    }
    let normals = NormalMap {
        width: n,
        height: n,
        normals,
        valid: vec![true; px],
    };
    let prior = DepthMap::new(n, n, prior)?;
    // As the peer: α = 10⁻³, every pixel, no discontinuities, no scale refit.
    let params = IntegrationParams {
        alpha: 1e-3,
        proxy_jump_m: 1e6,
        refit_scale: false,
        ..IntegrationParams::default()
    };
    let t = Instant::now();
    let out = integrate_normals(&camera, &normals, &prior, None, &params)?;
    let seconds = t.elapsed().as_secs_f64();
    let rms = |m: &DepthMap| {
        // Errors in camera z, as the peer scores them.
        let sum: f64 = (0..px)
            .map(|i| {
                let (x, y) = ((i as u32 % n) as f64, (i as u32 / n) as f64);
                let len = DVec3::new((x - c) / f, (y - c) / f, 1.0).length();
                ((m.depth_m[i] - truth[i]) / len).powi(2)
            })
            .sum();
        (sum / px as f64).sqrt() * 1e3
    };
    Ok((seconds, rms(&out.depth), rms(&prior)))
}

/// The four goals on the pass-2 merged mesh (Table 3.1's coverage `coverage_key`,
/// normal and local normal deviation, median distance to the truth, each other key named
/// `{prefix}normal_dev_deg` etc.) as headlines, labels prefixed by `subject`, with the visual
/// hull's figure `baseline_key` named as the baseline; beside the deviations, the same
/// figures before the refinement (`{prefix}unrefined_*`) and their floors in the same form
/// (`{prefix}floor_*`, [`perfect_geometry`]).
fn table_goal_headlines(
    prefix: &str,
    coverage_key: &str,
    subject: &str,
    baseline_key: &str,
) -> Vec<Headline> {
    let key = |k: &str| format!("{prefix}{k}");
    let floor = |k: &str| {
        format!(
            "floor: {} (the true depth maps merged, per vertex on the same pixels)",
            key(k)
        )
    };
    vec![
        Headline::new(
            coverage_key,
            &format!("{subject}Table 3.1 coverage, pass-2 merged mesh"),
            "%",
        )
        .paper(if prefix == "ghost_" {
            "92.26 % (Ghost), Table 3.1"
        } else {
            "81.27–92.26 % over four sequences, Table 3.1"
        })
        .goal(Goal::AtLeast(90.0)),
        Headline::new(
            &key("normal_dev_deg"),
            &format!("{subject}Table 3.1 normal deviation, pass-2 merged mesh"),
            "deg",
        )
        .paper(if prefix == "ghost_" {
            "14.03° (Ghost), Table 3.1"
        } else {
            "12.18–15.00° over four sequences, Table 3.1"
        })
        .goal(Goal::AtMost(8.0))
        .note(&floor("floor_normal_dev_deg")),
        Headline::new(
            &key("local_normal_dev_deg"),
            &format!("{subject}Table 3.1 local normal deviation, pass-2 merged mesh"),
            "deg",
        )
        .paper(if prefix == "ghost_" {
            "1.26° (Ghost), Table 3.1"
        } else {
            "1.26–2.04° over four sequences, Table 3.1"
        })
        .goal(Goal::AtMost(1.5))
        .note(&floor("floor_local_normal_dev_deg")),
        Headline::new(
            &key("unrefined_normal_dev_deg"),
            &format!("{subject}Table 3.1 normal deviation, pass 2 before the refinement"),
            "deg",
        )
        .baseline()
        .paper(if prefix == "ghost_" {
            "14.03° (Ghost), Table 3.1"
        } else {
            "12.18–15.00° over four sequences, Table 3.1"
        })
        .goal(Goal::AtMost(8.0))
        .note(&floor("floor_normal_dev_deg")),
        Headline::new(
            &key("unrefined_local_normal_dev_deg"),
            &format!("{subject}Table 3.1 local normal deviation, pass 2 before the refinement"),
            "deg",
        )
        .baseline()
        .paper(if prefix == "ghost_" {
            "1.26° (Ghost), Table 3.1"
        } else {
            "1.26–2.04° over four sequences, Table 3.1"
        })
        .goal(Goal::AtMost(1.5))
        .note(&floor("floor_local_normal_dev_deg")),
        Headline::new(
            &key("floor_normal_dev_deg"),
            &format!("{subject}floor of the normal deviation: a perfect geometry, same form"),
            "deg",
        )
        .oracle()
        .note("what the correct geometry scores; a mesh below it fits part 1's errors"),
        Headline::new(
            &key("floor_local_normal_dev_deg"),
            &format!("{subject}floor of the local normal deviation: a perfect geometry, same form"),
            "deg",
        )
        .oracle()
        .note("what the correct geometry scores; a mesh below it fits part 1's errors"),
        Headline::new(
            &key("surface_median_mm"),
            &format!("{subject}pass-2 merged mesh to the true mesh (median)"),
            "mm",
        )
        .goal(Goal::AtMost(2.0))
        .note(&format!(
            "baseline: the visual hull's surface ({baseline_key})"
        )),
    ]
}
