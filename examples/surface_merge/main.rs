//! Volumetric merging (Vlasic 2010 §3.3.3: VRIP with boundary × cosine × inverse-distance
//! weights on a sparse 8³-block volume) and screened Poisson hole filling, on the documented
//! workloads of the peer benchmarks, regenerated in Rust bit for bit:
//!
//! * `bench/peers/tsdf_mc.py` (6a): a sphere and a box seen by 8 exact depth maps at 512²
//!   (`--quick`: 256²). Merged at the peer's 4 mm voxels and ±2 cm truncation with uniform
//!   weights (what Open3D's TSDF does) and with the thesis's weights; then at the thesis's own
//!   2 mm voxels and 6 cm ramp, and the unseen bottoms filled by screened Poisson from the
//!   merged surface (weight 1) and a proxy 1 cm outside the scene (weight 0.01, as the thesis's
//!   visual hull). Distances are to the exact scene.
//! * `bench/peers/poisson.py` (6b): 200,000 oriented samples of a sphere of radius 0.4 without
//!   its cap z > 0.3, all weight 1 (Open3D takes no weights), depth 8 and 9 (`--quick`: 50,000
//!   samples, depth 7). Errors `| ‖v‖ − 0.4 |` as the peer reports them (means over
//!   vertices), and per unit area over the whole surface and the filled cap
//!   (`err_all_area_mm`, `err_filled_area_mm`): a mean over vertices weighs each region by how
//!   finely it is triangulated, and the peer triangulates the filled cap coarsely. The first
//!   depth again with the screening taken at the samples at Kazhdan's strength
//!   (`ScreeningForm::Consistent`, α = 4 · 2^depth: `poisson_consistent`).
//!
//! `--peers FILE` reads the JSON lines the peer scripts printed in the same run (one per
//! run; CI never needs Python) and reports the time ratios ours / peer, among them
//! `merge_time_ratio_open3d` (6a, uniform weights) and `poisson_time_ratio_open3d` (6b,
//! depth 8).
//!
//! Writes under `out/surface_merge/`: `merge.png` (merged surface, its distance to the scene
//! in false colour, the hole-filled surface's), `poisson.png` (the filled sphere's error),
//! `merged.ply`, `filled.ply`, `poisson_sphere.ply`, `figures.json`, `manifest.json`; the last
//! stdout line is one JSON object.
//!
//! `cargo run --release --example surface_merge [-- --quick] [-- --peers results.jsonl]`
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

use std::path::PathBuf;
use std::time::Instant;

use clap::Parser;
use image::{Rgb, RgbImage};
use serde_json::{json, Value};

use dynamic_shapes::core::camera::{Camera, Intrinsics};
use dynamic_shapes::core::math::DVec3;
use dynamic_shapes::core::mesh::{unique_edges, write_ply, EdgeTopology, PlyEncoding, TriMesh};
use dynamic_shapes::core::raster::{Buffers, Rasterizer, RenderParams, NO_TRIANGLE};
use dynamic_shapes::core::stats::{mean, median, percentile};
use dynamic_shapes::photometric::peer_workloads::{
    poisson_samples, tsdf_proxy_samples, tsdf_scene_sdf, tsdf_views, POISSON_SPHERE, TSDF_TRUNC_M,
    TSDF_VOXEL_M,
};
use dynamic_shapes::photometric::{
    merge_views, screened_poisson, MergeParams, MergeView, MergedSurface, OrientedSample,
    PoissonLevel, PoissonParams, PoissonSurface, ReconstructParams, ScreeningForm,
};
use example_kit::plot::{error_colour, side_by_side, titled, with_colour_bar, ColourBar};
use example_kit::{Goal, Headline, Run};

#[derive(Parser, Debug)]
struct Args {
    #[command(flatten)]
    common: example_kit::cli::Common,
    /// JSON lines printed by bench/peers/tsdf_mc.py and poisson.py in the same run.
    #[arg(long, value_name = "FILE")]
    peers: Option<PathBuf>,
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// CPU time of the whole process so far (all threads, user + system), ms, from
/// `/proc/self/stat` (Linux; `None` elsewhere). The machine is shared, so wall time alone
/// says little about the work done.
fn cpu_ms() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the parenthesised command name; utime and stime are the 14th and 15th
    // fields of the line, in clock ticks of 10 ms.
    let rest = stat.rsplit_once(')')?.1;
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks: f64 = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
    Some(ticks * 10.0)
}

/// CPU ms spent since `start` (`None` where unavailable).
fn cpu_since(start: Option<f64>) -> Option<f64> {
    Some(cpu_ms()? - start?)
}

/// Distance figures (mm) of per-vertex distances (m).
fn distance_figures(d_m: &[f64]) -> Value {
    let mm: Vec<f64> = d_m.iter().map(|d| d * 1e3).collect();
    json!({
        "mean_dist_mm": mean(&mm),
        "median_dist_mm": median(&mm),
        "p95_dist_mm": percentile(&mm, 0.95),
        "p99_dist_mm": percentile(&mm, 0.99),
        "vertices": mm.len(),
    })
}

fn scene_distances(mesh: &TriMesh) -> Vec<f64> {
    mesh.vertices
        .iter()
        .map(|v| tsdf_scene_sdf(*v).abs())
        .collect()
}

fn topology(mesh: &TriMesh) -> Value {
    let topo = EdgeTopology::new(mesh).unwrap();
    let edges = unique_edges(mesh).unwrap().len() as i64;
    json!({
        "closed": topo.is_closed(),
        "boundary_edges": topo.boundary_edges().len(),
        "non_manifold_edges": topo.non_manifold_edges().len(),
        "euler": mesh.vertex_count() as i64 - edges + mesh.face_count() as i64,
    })
}

/// Merges the views `reps` times; the median time (ms) and the last result.
fn timed_merge(
    views: &[MergeView],
    params: &MergeParams,
    reps: usize,
) -> Result<(f64, MergedSurface), Box<dyn std::error::Error>> {
    let mut times = Vec::new();
    let mut out = None;
    for _ in 0..reps {
        let t = Instant::now();
        out = Some(merge_views(views, params)?);
        times.push(ms(t));
    }
    Ok((median(&times), out.expect("reps >= 1")))
}

/// The mesh seen from `cam`, coloured by per-vertex error (m) up to `max_mm`, shaded.
fn error_render(mesh: &TriMesh, err_m: &[f64], cam: &Camera, max_mm: f64) -> RgbImage {
    let params = RenderParams::default().with_buffers(Buffers {
        triangle: true,
        normal: true,
        ..Buffers::MASK_ONLY
    });
    let view = Rasterizer::new(cam).render(mesh, &params).unwrap();
    RgbImage::from_fn(view.width, view.height, |x, y| {
        let i = (y * view.width + x) as usize;
        let t = view.triangle[i];
        if t == NO_TRIANGLE {
            return Rgb([255, 255, 255]);
        }
        let f = mesh.faces[t as usize];
        let e = f.iter().map(|&v| err_m[v as usize]).sum::<f64>() / 3.0 * 1e3;
        let shade = 0.35 + 0.65 * f64::from(view.normal_camera[i][2].abs());
        Rgb(error_colour(Some(e), max_mm).map(|c| (f64::from(c) * shade) as u8))
    })
}

fn bar<'a>(label: &'a str, max: f64, ramp: &'a dyn Fn(f64) -> [u8; 3]) -> ColourBar<'a> {
    ColourBar {
        label,
        min: 0.0,
        max,
        ramp,
        note: Some("above the top: red"),
    }
}

/// Mean distance to the sphere of radius `r`, mm, per unit area (each face at its centroid,
/// weighted by its area) over the whole mesh and over the filled hole (`z > cut`). Unlike a
/// mean over vertices, it does not depend on how finely a region is triangulated.
fn area_weighted_errors(mesh: &TriMesh, r: f64, cut: f64) -> (f64, f64) {
    let (mut all, mut all_a, mut filled, mut filled_a) = (0.0, 0.0, 0.0, 0.0);
    for f in 0..mesh.face_count() {
        let [p, q, s] = mesh.triangle(f);
        let a = 0.5 * (q - p).cross(s - p).length();
        let c = (p + q + s) / 3.0;
        let e = (c.length() - r).abs() * 1e3;
        all += a * e;
        all_a += a;
        if c.z > cut {
            filled += a * e;
            filled_a += a;
        }
    }
    (all / all_a, filled / filled_a)
}

/// Workload 6b's errors `| ‖v‖ − 0.4 |` of a reconstruction: means over the vertices where
/// sampled (`z ≤ 0.25`) and everywhere, per unit area everywhere and over the filled cap,
/// and the mesh's size, levels and topology.
fn sphere_errors(s: &PoissonSurface) -> Value {
    let (r, cut) = POISSON_SPHERE;
    let err: Vec<f64> = s
        .mesh
        .vertices
        .iter()
        .map(|v| (v.length() - r).abs())
        .collect();
    let observed: Vec<f64> = s
        .mesh
        .vertices
        .iter()
        .zip(&err)
        .filter(|(v, _)| v.z <= cut - 0.05)
        .map(|(_, &e)| e * 1e3)
        .collect();
    let (err_all_area_mm, err_filled_area_mm) = area_weighted_errors(&s.mesh, r, cut);
    json!({
        "err_all_area_mm": err_all_area_mm,
        "err_filled_area_mm": err_filled_area_mm,
        "filled_vertices": s.mesh.vertices.iter().filter(|v| v.z > cut).count(),
        "err_observed_mm": mean(&observed),
        "max_observed_mm": observed.iter().fold(0.0f64, |a, &b| a.max(b)),
        "err_all_mm": mean(&err) * 1e3,
        "vertices": s.mesh.vertex_count(),
        "dropped_components": s.dropped_components,
        "triangles": s.mesh.face_count(),
        "levels": level_figures(&s.levels),
        "topology": topology(&s.mesh),
    })
}

/// Per level of a reconstruction: depth, nodes, CG iterations and the residual reached.
fn level_figures(levels: &[PoissonLevel]) -> Vec<Value> {
    levels
        .iter()
        .map(|l| json!({"depth": l.depth, "nodes": l.nodes, "cg_iterations": l.iterations, "residual": l.residual}))
        .collect()
}

/// Time ratio ours / peer for the peer line whose `peer` field ends with `variant`.
fn peer_ratio(peers: &[Value], workload: &str, variant: &str, ours_ms: f64) -> Value {
    peers
        .iter()
        .find(|p| {
            p["workload"] == workload && p["peer"].as_str().is_some_and(|s| s.ends_with(variant))
        })
        .map_or(Value::Null, |p| {
            let s = p["seconds"].as_f64().unwrap_or(f64::NAN);
            json!({
                "peer": p["peer"],
                "peer_ms": s * 1e3,
                "ours_ms": ours_ms,
                "time_ratio_ours_over_peer": ours_ms / (s * 1e3),
                "peer_quality": p["quality"],
            })
        })
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = Args::parse();
    let quick = args.common.quick;
    let size = if quick { 256 } else { 512 };
    let reps = if quick { 1 } else { 3 };
    let mut run = Run::start(
        "surface_merge",
        &args.common,
        &format!(
            "VRIP merging of 8 depth maps at {size}² (Vlasic 2010 §3.3.3; peer workload 6a) and \
             screened Poisson hole filling (peer workload 6b)"
        ),
    )?;
    let peers: Vec<Value> = match &args.peers {
        Some(p) => std::fs::read_to_string(p)?
            .lines()
            .filter_map(|l| serde_json::from_str(l).ok())
            .collect(),
        None => Vec::new(),
    };

    let stage = run.stage("depth maps (workload 6a)", None);
    let scene = tsdf_views(size)?;
    let views: Vec<MergeView> = scene
        .iter()
        .map(|(camera, depth)| MergeView::new(camera, depth))
        .collect();
    stage.finish(format!("8 views at {size}²"));

    // The peer's settings: 4 mm voxels, ±2 cm truncation.
    let stage = run.stage("merge at the peer's settings", None);
    let peer_params = MergeParams::default()
        .with_voxel_m(TSDF_VOXEL_M)
        .with_ramp_m(2.0 * TSDF_TRUNC_M);
    let (uniform_ms, uniform) = timed_merge(&views, &peer_params.with_uniform_weights(true), reps)?;
    let (weighted_ms, weighted) = timed_merge(&views, &peer_params, reps)?;
    stage.finish(format!(
        "{uniform_ms:.0} ms uniform, {weighted_ms:.0} ms weighted"
    ));

    // The thesis's settings: 2 mm voxels, 6 cm ramp, then hole filling.
    let stage = run.stage("merge at the thesis's settings", None);
    let cpu0 = cpu_ms();
    let (merge_ms, merged) = timed_merge(&views, &MergeParams::default(), 1)?;
    let merge_cpu_ms = cpu_since(cpu0);
    let merged_d = scene_distances(&merged.mesh);
    stage.finish(format!("{merge_ms:.0} ms, {} blocks", merged.stats.blocks));
    let stage = run.stage("hole filling", None);
    let mut samples = OrientedSample::from_mesh(&merged.mesh, 1.0)?;
    let proxy = tsdf_proxy_samples(0.01, 0.01)?;
    samples.extend(&proxy);
    let t = Instant::now();
    let cpu0 = cpu_ms();
    // The reconstruction's hole filling (its flux splat for merged meshes) at depth 8.
    let fill_params = ReconstructParams::default().poisson.with_depth(8);
    let filled = screened_poisson(&samples, &fill_params)?;
    let fill_ms = ms(t);
    let fill_cpu_ms = cpu_since(cpu0);
    let filled_d = scene_distances(&filled.mesh);
    stage.finish(format!("{fill_ms:.0} ms"));

    // Workload 6b.
    let (n_points, depths): (usize, &[u32]) = if quick {
        (50_000, &[7])
    } else {
        (200_000, &[8, 9])
    };
    let stage = run.stage("screened Poisson (workload 6b)", None);
    let sphere_samples = poisson_samples(n_points, 1.0);
    let mut poisson_runs = Vec::new();
    let mut last: Option<PoissonSurface> = None;
    for &depth in depths {
        let t = Instant::now();
        let cpu0 = cpu_ms();
        let s = screened_poisson(&sphere_samples, &PoissonParams::default().with_depth(depth))?;
        let elapsed = ms(t);
        let cpu = cpu_since(cpu0);
        let mut run_figures = sphere_errors(&s);
        run_figures["depth"] = json!(depth);
        run_figures["points"] = json!(n_points);
        run_figures["poisson_ms"] = json!(elapsed);
        run_figures["poisson_cpu_ms"] = json!(cpu);
        run_figures["peer"] = if quick {
            Value::Null
        } else {
            peer_ratio(&peers, "poisson", &format!("depth{depth}"), elapsed)
        };
        poisson_runs.push(run_figures);
        last = Some(s);
    }
    // The same solve with multigrid V-cycles preconditioning the band levels too (the
    // default uses them on the complete levels only): iterations and CPU time side by side.
    let cpu0 = cpu_ms();
    let t = Instant::now();
    let mg = screened_poisson(
        &sphere_samples,
        &PoissonParams::default()
            .with_depth(depths[0])
            .with_multigrid_bands(true),
    )?;
    let multigrid_bands = json!({
        "depth": depths[0],
        "poisson_ms": ms(t),
        "poisson_cpu_ms": cpu_since(cpu0),
        "levels": level_figures(&mg.levels),
    });
    // The screening taken at the samples (`ScreeningForm::Consistent`) at Kazhdan's strength:
    // his code scales the weight of a depth-d node by 2^d, so his α = 4 is α = 4 · 2^depth
    // here.
    let alpha = 4.0 * f64::from(1u32 << depths[0]);
    let cpu0 = cpu_ms();
    let t = Instant::now();
    let consistent = screened_poisson(
        &sphere_samples,
        &PoissonParams::default()
            .with_depth(depths[0])
            .with_screening(alpha)
            .with_screening_form(ScreeningForm::Consistent),
    )?;
    let mut consistent_figures = sphere_errors(&consistent);
    consistent_figures["depth"] = json!(depths[0]);
    consistent_figures["screening"] = json!(alpha);
    consistent_figures["poisson_ms"] = json!(ms(t));
    consistent_figures["poisson_cpu_ms"] = json!(cpu_since(cpu0));
    stage.finish(format!("{} runs", poisson_runs.len() + 2));

    // Pictures and meshes.
    let k = Intrinsics::from_horizontal_fov(0.9, 480, 400)?;
    let cam = Camera::look_at(k, DVec3::new(0.9, -0.7, -0.25), DVec3::ZERO, DVec3::Z)?;
    let ramp_mm = |t: f64| error_colour(Some(t * 2.0), 2.0);
    let merge_png = side_by_side(&[
        titled(
            &error_render(&uniform.mesh, &scene_distances(&uniform.mesh), &cam, 2.0),
            "uniform weights, 4 mm",
            Some("Open3D's weighting"),
        )?,
        titled(
            &error_render(&merged.mesh, &merged_d, &cam, 2.0),
            "VRIP, thesis weights, 2 mm",
            Some("merged (§3.3.3)"),
        )?,
        titled(
            &error_render(&filled.mesh, &filled_d, &cam, 2.0),
            "hole-filled",
            Some("screened Poisson, proxy at weight 0.01"),
        )?,
    ])?;
    let merge_png = with_colour_bar(
        &titled(
            &merge_png,
            "Merging and hole filling: distance to the true scene",
            Some("workload 6a seen from below the cameras; the bottoms are unseen"),
        )?,
        &bar("distance to the scene (mm)", 2.0, &ramp_mm),
    )?;
    run.save_picture(
        "merge.png",
        &merge_png,
        "Merged and hole-filled surfaces, error-coloured",
    )?;
    if let Some(s) = &last {
        let err: Vec<f64> = s
            .mesh
            .vertices
            .iter()
            .map(|v| (v.length() - POISSON_SPHERE.0).abs())
            .collect();
        let kc = Intrinsics::from_horizontal_fov(0.9, 400, 400)?;
        let top = Camera::look_at(kc, DVec3::new(0.8, 0.3, 1.1), DVec3::ZERO, DVec3::Z)?;
        let ramp = |t: f64| error_colour(Some(t * 1.0), 1.0);
        let img = with_colour_bar(
            &titled(
                &error_render(&s.mesh, &err, &top, 1.0),
                "Screened Poisson: sphere with its cap (z > 0.3 m) filled",
                Some(&format!(
                    "{n_points} samples, depth {}",
                    depths[depths.len() - 1]
                )),
            )?,
            &bar("| |v| − 0.4 m | (mm)", 1.0, &ramp),
        )?;
        run.save_picture(
            "poisson.png",
            &img,
            "Workload 6b's filled sphere, error-coloured",
        )?;
        write_ply(
            run.path("poisson_sphere.ply"),
            &s.mesh,
            PlyEncoding::default(),
        )?;
    }
    write_ply(run.path("merged.ply"), &merged.mesh, PlyEncoding::default())?;
    write_ply(run.path("filled.ply"), &filled.mesh, PlyEncoding::default())?;

    let observed_fill: Vec<f64> = filled
        .mesh
        .vertices
        .iter()
        .zip(&filled_d)
        .filter(|(v, _)| v.z > -0.05)
        .map(|(_, &d)| d)
        .collect();
    let p0 = &poisson_runs[0];
    let mut figures = json!({
        "quick": quick,
        "image_size": size,
        "merge_ms": merge_ms,
        "merge_cpu_ms": merge_cpu_ms,
        "poisson_ms": fill_ms,
        "poisson_cpu_ms": fill_cpu_ms,
        "blocks": merged.stats.blocks,
        "voxels_allocated": merged.stats.voxels_allocated,
        "voxels_observed": merged.stats.voxels_observed,
        "volume_mb": merged.stats.volume_bytes as f64 / 1e6,
        "surface_median_mm": median(&merged_d) * 1e3,
        "surface_p95_mm": percentile(&merged_d, 0.95) * 1e3,
        "filled_median_mm": median(&filled_d) * 1e3,
        "filled_p95_mm": percentile(&filled_d, 0.95) * 1e3,
        "filled_observed_median_mm": median(&observed_fill) * 1e3,
        "peak_rss_mb": example_kit::peak_rss_mb(),
        "thesis_merge": {
            "params": "voxel 2 mm, ramp 6 cm, thesis weights",
            "merge_ms": merge_ms,
            "merge_cpu_ms": merge_cpu_ms,
            "faces": merged.mesh.face_count(),
            "distance": distance_figures(&merged_d),
            "topology": topology(&merged.mesh),
        },
        "hole_filling": {
            "samples_merged": samples.len() - proxy.len(),
            "samples_proxy": proxy.len(),
            "poisson_ms": fill_ms,
            "poisson_cpu_ms": fill_cpu_ms,
            "dropped_components": filled.dropped_components,
            "levels": filled.levels.iter().map(|l| json!({"depth": l.depth, "nodes": l.nodes, "cg_iterations": l.iterations})).collect::<Vec<_>>(),
            "distance": distance_figures(&filled_d),
            "distance_observed_z_above_-0.05": distance_figures(&observed_fill),
            "topology": topology(&filled.mesh),
        },
        "peer_tsdf": {
            "params": "voxel 4 mm, ramp ±2 cm (Open3D sdf_trunc 0.02)",
            "uniform": {
                "merge_ms": uniform_ms,
                "blocks": uniform.stats.blocks,
                "distance": distance_figures(&scene_distances(&uniform.mesh)),
                "peer_uniform": if quick { Value::Null } else { peer_ratio(&peers, "tsdf_mc", ":uniform", uniform_ms) },
                "peer_vbg": if quick { Value::Null } else { peer_ratio(&peers, "tsdf_mc", ":vbg", uniform_ms) },
            },
            "thesis_weights": {
                "merge_ms": weighted_ms,
                "distance": distance_figures(&scene_distances(&weighted.mesh)),
            },
        },
        "peer_poisson": poisson_runs,
        "poisson_multigrid_bands": multigrid_bands,
        "poisson_consistent": consistent_figures,
        "poisson_consistent_err_observed_mm": consistent_figures["err_observed_mm"],
        "poisson_err_observed_mm": p0["err_observed_mm"],
        "poisson_err_all_mm": p0["err_all_mm"],
        "poisson_depth_ms": p0["poisson_ms"],
    });
    if !quick && !peers.is_empty() {
        // Workload 6a at the peer's settings against Open3D's uniform TSDF; 6b at depth 8.
        let merge = &figures["peer_tsdf"]["uniform"]["peer_uniform"]["time_ratio_ours_over_peer"];
        let poisson = &p0["peer"]["time_ratio_ours_over_peer"];
        let (merge, poisson) = (merge.clone(), poisson.clone());
        figures["merge_time_ratio_open3d"] = merge;
        figures["poisson_time_ratio_open3d"] = poisson;
        let peer_quality = &p0["peer"]["peer_quality"];
        for (ours, theirs, ratio) in [
            (
                "err_observed_mm",
                "err_observed_mm",
                "poisson_err_observed_ratio_open3d",
            ),
            ("err_all_mm", "err_all_mm", "poisson_err_all_ratio_open3d"),
        ] {
            figures[ratio] = json!(
                p0[ours].as_f64().unwrap_or(f64::NAN)
                    / peer_quality[theirs].as_f64().unwrap_or(f64::NAN)
            );
        }
        // The consistent screening at Kazhdan's strength against the same Open3D run.
        let consistent = figures["poisson_consistent"].clone();
        figures["poisson_consistent_err_observed_ratio_open3d"] = json!(
            consistent["err_observed_mm"].as_f64().unwrap_or(f64::NAN)
                / peer_quality["err_observed_mm"].as_f64().unwrap_or(f64::NAN)
        );
        figures["poisson_consistent_time_ratio_open3d"] = json!(
            consistent["poisson_ms"].as_f64().unwrap_or(f64::NAN)
                / p0["peer"]["peer_ms"].as_f64().unwrap_or(f64::NAN)
        );
        for (key, label) in [
            (
                "merge_time_ratio_open3d",
                "merge time over Open3D's uniform TSDF (6a, same run)",
            ),
            (
                "poisson_time_ratio_open3d",
                "screened Poisson time over Open3D's (6b, depth 8, same run)",
            ),
            (
                "poisson_err_observed_ratio_open3d",
                "screened Poisson error where sampled over Open3D's (6b)",
            ),
            (
                "poisson_consistent_err_observed_ratio_open3d",
                "screened Poisson error where sampled over Open3D's, screening at the samples (6b)",
            ),
        ] {
            run.headline(Headline::new(key, label, "×").goal(Goal::AtMost(1.0)));
        }
        // Not a goal: the two meshes cover different surfaces. The domain (the samples'
        // bounding cube × 1.1, as Open3D's `scale`) ends at z = 0.39, below the sphere's top
        // at 0.40, so neither reconstruction can close the cap on the sphere.
        run.headline(
            Headline::new(
                "poisson_err_all_ratio_open3d",
                "screened Poisson error over the whole surface over Open3D's (6b, per vertex; \
                 Open3D leaves the cap open)",
                "×",
            )
            .note(
                "not comparable: the domain ends at z = 0.39 below the sphere's top (0.40); \
                 Open3D leaves the cap open there and its mean covers little more than the \
                 sampled part, this closes it with a lid on the domain's face",
            ),
        );
    }
    for h in [
        Headline::new("merge_ms", "VRIP merge, 8 views, 2 mm voxels", "ms")
            .paper("2 min per frame (merging), thesis §3.4"),
        Headline::new("blocks", "allocated 8³ blocks at 2 mm", ""),
        Headline::new("volume_mb", "volume memory at 2 mm", "MB"),
        Headline::new(
            "surface_median_mm",
            "merged surface to the scene (median)",
            "mm",
        ),
        Headline::new("surface_p95_mm", "merged surface to the scene (p95)", "mm"),
        Headline::new(
            "poisson_ms",
            "hole filling (screened Poisson, depth 8)",
            "ms",
        ),
        Headline::new(
            "filled_median_mm",
            "hole-filled surface to the scene (median)",
            "mm",
        ),
        Headline::new(
            "poisson_err_observed_mm",
            "workload 6b error where sampled (mean)",
            "mm",
        )
        .note("Open3D depth 8: 0.020 mm (bench/peers)"),
        Headline::new("peak_rss_mb", "peak memory", "MB"),
    ] {
        run.headline(h);
    }
    run.finish(figures)?;
    Ok(())
}
