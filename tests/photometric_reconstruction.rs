//! Per-view surfaces of photometric-normals part 2 (Vlasic thesis §3.3.1–§3.3.2) on the
//! studio, CI-sized: the MakeHuman performer in the skirt seen by a ring of 8 cameras at
//! 256 × 256. The visual hull of the 8 silhouettes is rendered per camera as the proxy; each
//! view's normals are integrated by Eq. 3.3 — exact normals (the rasteriser's, turned to face
//! the camera as a measurement is) on all 8 views, and normals estimated by part 1 from the
//! light stage's half-on images on two neighbouring views — and scored against the true depth
//! maps beside the proxy alone (the baseline that could win).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

use std::time::Instant;

use dynamic_shapes::core::camera::{Camera, Rig};
use dynamic_shapes::core::image::Mask;
use dynamic_shapes::core::math::DVec3;
use dynamic_shapes::core::mesh::{is_closed, points_to_surface, MeshQuery, TriMesh};
use dynamic_shapes::core::raster::{Rasterizer, RenderParams, RenderedView};
use dynamic_shapes::photometric::truth::{pattern_images, skirt_subject, StudioScene};
use dynamic_shapes::photometric::{
    coverage_budget, depth_errors, estimate_normals, hull_samples, match_pair, matching_images,
    merge_views, per_view_surfaces, reconstruct, reconstruct_from_hull_depths, rendered_normals,
    surface_distance, table_metrics, BudgetInputs, DepthMap, MatchMetric, MatchView,
    MatchingParams, MergeView, MetricParams, NormalMap, PolygonalHull, PolygonalHullParams,
    ReconstructParams, SurfaceParams,
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

#[test]
fn per_view_surfaces_and_two_passes_beat_the_visual_hull() {
    let t0 = Instant::now();
    let scene = StudioScene::new(
        example_kit::data_path("makehuman").unwrap(),
        &skirt_subject(),
        CAMERAS,
        SIZE,
    )
    .unwrap();
    let (performer, ring) = (&scene.performer, &scene.ring);
    // The light stage photographs two neighbouring views (45° apart) for part 1's normals.
    let photographed = Rig {
        cameras: ring.cameras[..2].to_vec(),
    };
    let frame = scene
        .capture(scene.capture_spec(photographed).unwrap())
        .unwrap();
    let mesh = frame.truth.rendered_mesh(performer);
    let views: Vec<RenderedView> = ring.cameras.iter().map(|c| render(c, &mesh)).collect();
    let t_capture = t0.elapsed().as_secs_f64();

    // Proxy: the visual hull of the 8 silhouettes.
    let t = Instant::now();
    let silhouettes: Vec<Mask> = views.iter().map(RenderedView::silhouette).collect();
    let hull = PolygonalHull::new(&ring.cameras, &silhouettes).unwrap();
    let proxies = hull.depth_maps(&PolygonalHullParams::default()).unwrap();
    let t_hull = t.elapsed().as_secs_f64();
    let truths: Vec<DepthMap> = views
        .iter()
        .map(|v| DepthMap::from_view(v).unwrap())
        .collect();

    // Exact normals on all views, the 8 neighbouring pairs of the ring.
    let exact: Vec<NormalMap> = ring
        .cameras
        .iter()
        .zip(&views)
        .map(|(c, v)| rendered_normals(c, v).unwrap())
        .collect();
    let pairs: Vec<(usize, usize)> = (0..CAMERAS).map(|c| (c, (c + 1) % CAMERAS)).collect();
    let params = SurfaceParams::default();
    let out = per_view_surfaces(
        &ring.cameras,
        &exact,
        &proxies,
        &pairs,
        Some(&hull),
        &params,
    )
    .unwrap();
    let scores = out.errors_against(&truths, &proxies, &exact).unwrap();
    println!("exact normals, 8 views: {scores:?}; {:?}", out.times);

    // Estimated normals (part 1) on the two photographed views, one pair.
    let t = Instant::now();
    let (_, cal_params, normal_params) = scene.photometric_params(WHITE_LEVEL);
    let mut stacks = Vec::new();
    let estimated: Vec<NormalMap> = (0..2)
        .map(|c| {
            let cam = &ring.cameras[c];
            let cal = scene.calibrate(cam, &cal_params).unwrap();
            let obs = &frame.observations[c];
            let images = pattern_images(obs).unwrap();
            stacks.push(matching_images(&images));
            estimate_normals(cam, &cal, &images, Some(&obs.mask), &normal_params).unwrap()
        })
        .collect();
    let t_normals = t.elapsed().as_secs_f64();
    let est = per_view_surfaces(
        &ring.cameras[..2],
        &estimated,
        &proxies[..2],
        &[(0, 1)],
        Some(&hull),
        &params,
    )
    .unwrap();
    let est_scores = est
        .errors_against(&truths[..2], &proxies[..2], &estimated)
        .unwrap();
    println!(
        "estimated normals, 2 views: {est_scores:?}; {:?}",
        est.times
    );
    // Figure 3-5: the four metrics on the same surfaces; the surface metric beats plain stereo.
    let mut metric_err = Vec::new();
    for metric in MatchMetric::ALL {
        let view = |c: usize| MatchView {
            camera: &ring.cameras[c],
            surface: &est.integrated[c],
            guide: None,
            images: Some(&stacks[c]),
        };
        let params = MatchingParams {
            metric,
            ..MatchingParams::default()
        };
        let m = match_pair(&view(0), &view(1), Some(&hull), &params).unwrap();
        let e = depth_errors(&m.left.target, &truths[0], None).unwrap();
        println!(
            "{metric:?}: matches median {:.1} mm p95 {:.1} mm ({} px)",
            e.median_mm, e.p95_mm, e.pixels
        );
        assert!(e.pixels > 1000, "{metric:?} {e:?}");
        metric_err.push(e);
    }
    let (full_on, surface) = (&metric_err[0], &metric_err[2]);
    assert!(
        surface.median_mm < full_on.median_mm && surface.p95_mm < full_on.p95_mm,
        "{surface:?} vs {full_on:?}"
    );
    println!(
        "capture {t_capture:.1} s, hull {t_hull:.2} s (8 views), part-1 normals {t_normals:.1} s, \
         total {:.1} s",
        t0.elapsed().as_secs_f64()
    );

    // Integration alone keeps the hull's placement error but not its large errors; matching
    // and Eq. 3.4 then beat the hull in median and p95.
    let s = &scores;
    assert!(s.integrated.p95_mm < s.proxy.p95_mm, "{s:?}");
    assert!(
        s.offset.median_mm < s.proxy.median_mm && s.offset.p95_mm < 0.8 * s.proxy.p95_mm,
        "{s:?}"
    );
    assert!(s.offset.median_mm < 0.6 * s.integrated.median_mm, "{s:?}");
    // Matches are quantised to the pixel grid: a 256² pixel covers ≈ 1 cm at 3.5 m.
    assert!(s.matches.median_mm < 12.0 && s.coverage_pct > 85.0, "{s:?}");
    let e = &est_scores;
    assert!(
        e.offset.median_mm < e.integrated.median_mm && e.offset.p95_mm < e.proxy.p95_mm,
        "{e:?}"
    );
    assert!(e.coverage_pct > 50.0, "{e:?}");

    // The two passes of §3.3 on the exact normals (4 mm voxels, Poisson depth 7 for CI),
    // scored with Table 3.1 from the data and against the true mesh beside the hull's surface.
    let t = Instant::now();
    let rparams = ReconstructParams::default()
        .with_voxel_m(0.004)
        .with_poisson_depth(7);
    // The hull's depth maps rendered above are pass 1's proxies (`reconstruct` would render
    // them again).
    let rec = reconstruct_from_hull_depths(
        &ring.cameras,
        &exact,
        &hull,
        proxies.clone(),
        0.0,
        &pairs,
        &rparams,
    )
    .unwrap();
    let t_two_pass = t.elapsed().as_secs_f64();
    let hull_points: Vec<DVec3> = hull_samples(&ring.cameras, &proxies, 0.04, 1.0)
        .unwrap()
        .iter()
        .map(|s| s.position)
        .collect();
    let hull_d = points_to_surface(&hull_points, &MeshQuery::new(&mesh).unwrap()).unwrap();
    let mut hull_mm: Vec<f64> = hull_d.per_vertex.iter().map(|d| d * 1e3).collect();
    hull_mm.sort_by(f64::total_cmp);
    let hull_median_mm = hull_mm[hull_mm.len() / 2];
    let hull_p95_mm = hull_mm[hull_mm.len() * 95 / 100];
    let mut rows = Vec::new();
    for pass in [&rec.pass1, &rec.pass2] {
        let table = table_metrics(
            &ring.cameras,
            &exact,
            &silhouettes,
            &pass.views.surfaces,
            &pass.merged.mesh,
            &MetricParams::default(),
        )
        .unwrap();
        let merged = surface_distance(&pass.merged.mesh, &mesh).unwrap();
        let filled = surface_distance(&pass.filled.mesh, &mesh).unwrap();
        println!(
            "{table:?}; merged median {:.1} p95 {:.1} mm; filled median {:.1} p95 {:.1} mm; {:?}",
            merged.median_mm, merged.p95_mm, filled.median_mm, filled.p95_mm, pass.times
        );
        assert!(is_closed(&pass.filled.mesh).unwrap());
        rows.push((table, merged, filled));
    }
    println!(
        "hull surface median {hull_median_mm:.1} p95 {hull_p95_mm:.1} mm; two passes \
         {t_two_pass:.1} s"
    );
    let (p1, p2) = (&rows[0], &rows[1]);
    // The coverage budget: every measured normal the merged mesh does not cover is in exactly one
    // class (no per-view surface, gross per-view error, lost in merging).
    let budget = coverage_budget(
        &ring.cameras,
        &exact,
        &silhouettes,
        &BudgetInputs {
            proxies: &rec.pass2.proxies,
            views: &rec.pass2.views,
            integration: &rparams.pass2.integration,
            reference: &truths,
        },
        &rec.pass2.merged.mesh,
        &MetricParams::default(),
    )
    .unwrap();
    println!("pass 2 coverage budget: {budget:?}");
    assert_eq!(budget.covered_px, p2.0.covered_px);
    assert_eq!(
        budget.covered_px
            + budget.no_surface_px()
            + budget.gross_uncovered_px
            + budget.merge_lost_px(),
        budget.measured_px,
        "{budget:?}"
    );
    // The merge's depth-jump threshold scaled with the width (`scale_merge_jump`; 4 cm per
    // pixel at 256²) keeps the steep parts of the views that 1 cm cuts into boundary: the
    // same pass-2 surfaces merged again cover more of the measured normals.
    let t = Instant::now();
    let scaled = ReconstructParams {
        scale_merge_jump: true,
        ..rparams
    }
    .merge_at_width(&rec.pass2.views.surfaces);
    let inputs: Vec<MergeView> = ring
        .cameras
        .iter()
        .zip(&rec.pass2.views.surfaces)
        .map(|(c, d)| MergeView::new(c, d))
        .collect();
    let remerged = merge_views(&inputs, &scaled).unwrap();
    let table = table_metrics(
        &ring.cameras,
        &exact,
        &silhouettes,
        &rec.pass2.views.surfaces,
        &remerged.mesh,
        &MetricParams::default(),
    )
    .unwrap();
    let d = surface_distance(&remerged.mesh, &mesh).unwrap();
    println!(
        "pass 2 merged with the scaled jump: {table:?}; median {:.2} p95 {:.1} mm ({:.1} s)",
        d.median_mm,
        d.p95_mm,
        t.elapsed().as_secs_f64()
    );
    assert!(
        table.coverage_pct > p2.0.coverage_pct + 1.0,
        "{table:?} vs {:?}",
        p2.0
    );
    let (m1, m2) = ((p1.1.median_mm, p1.1.p95_mm), (p2.1.median_mm, p2.1.p95_mm));
    // At 256² a pixel covers ≈ 1 cm, and the merged meshes are only slightly closer to the
    // truth than the hull's surface in median. Pass 1's ±20 cm matching band (the thesis
    // evaluates the whole grid in pass 1) reaches the surface where the hull is far off, which
    // with ±10 cm only pass 2 reaches: the ±10 cm band is the baseline that could win on pass
    // 1's p95.
    let mut narrow = rparams;
    narrow.pass1.matching.band_m = 0.1;
    // Only this run's pass 1 is compared: its pass 2 is not refined.
    narrow.refine = None;
    let base = reconstruct_from_hull_depths(
        &ring.cameras,
        &exact,
        &hull,
        proxies.clone(),
        0.0,
        &pairs,
        &narrow,
    )
    .unwrap();
    let base1 = surface_distance(&base.pass1.merged.mesh, &mesh).unwrap();
    println!(
        "pass 1 with a ±10 cm band: merged median {:.1} p95 {:.1} mm",
        base1.median_mm, base1.p95_mm
    );
    assert!(m1.1 < 0.6 * base1.p95_mm, "{m1:?} vs ±10 cm {base1:?}");
    // Pass 2 improves on pass 1 in median, coverage and normal deviation; its p95, which
    // pass 1 now reaches alone, stays within a millimetre of pass 1's.
    assert!(m2.0 < hull_median_mm, "{m2:?} vs hull {hull_median_mm}");
    assert!(m2.0 <= m1.0 && m2.1 < m1.1 + 1.0, "{m2:?} vs pass 1 {m1:?}");
    assert!(
        p2.0.coverage_pct > 50.0 && p2.0.coverage_pct >= p1.0.coverage_pct,
        "{:?} vs {:?}",
        p2.0,
        p1.0
    );
    assert!(
        p2.0.normal_dev_deg < p1.0.normal_dev_deg,
        "{:?} vs {:?}",
        p2.0,
        p1.0
    );
    // Table 3.1's deviations per vertex (the thesis's form; measured 8.6° and 1.8° refined)
    // and on the pixel grid (8.0°, 2.7°). With exact normals the floor is the studio's: its
    // normals are the Phong normals of a polygonal mesh, 7° from its facets on average.
    assert!(p2.0.normal_dev_deg < 15.0, "{:?}", p2.0);
    assert!(p2.0.pixel_normal_dev_deg < 15.0, "{:?}", p2.0);
    assert!(p2.0.local_normal_dev_deg < 5.0, "{:?}", p2.0);
    assert!(p2.0.vertex_samples > 10_000, "{:?}", p2.0);
    // Pass 2's merged mesh is refined by default and keeps the mesh before the refinement,
    // which Table 3.1 scores beside it. Here the measured normals are the exact ones, so
    // fitting them must lower both deviations (measured 9.6° → 8.6° and 2.8° → 1.8°; pass 1
    // is not refined and keeps none).
    assert!(rec.pass1.unrefined.is_none() && rec.pass1.refined.is_none());
    let unrefined = table_metrics(
        &ring.cameras,
        &exact,
        &silhouettes,
        &rec.pass2.views.surfaces,
        rec.pass2
            .unrefined
            .as_ref()
            .expect("pass 2 is refined by default"),
        &MetricParams::default(),
    )
    .unwrap();
    println!("pass 2 before the refinement: {unrefined:?}");
    assert!(
        p2.0.normal_dev_deg < unrefined.normal_dev_deg - 0.5
            && p2.0.local_normal_dev_deg < unrefined.local_normal_dev_deg - 0.5,
        "refined {:?} vs unrefined {unrefined:?}",
        p2.0
    );
    // Bad input is an error, not a panic.
    assert!(reconstruct(&ring.cameras, &exact[..2], &hull, &pairs, &rparams).is_err());
    assert!(reconstruct_from_hull_depths(
        &ring.cameras,
        &exact,
        &hull,
        proxies[..2].to_vec(),
        0.0,
        &pairs,
        &rparams,
    )
    .is_err());
    assert!(table_metrics(
        &ring.cameras,
        &exact,
        &silhouettes[..1],
        &rec.pass2.views.surfaces,
        &rec.pass2.merged.mesh,
        &MetricParams::default(),
    )
    .is_err());
    assert!(table_metrics(
        &ring.cameras,
        &exact,
        &silhouettes,
        &rec.pass2.views.surfaces,
        &rec.pass2.merged.mesh,
        &MetricParams { near_m: f64::NAN },
    )
    .is_err());
}
