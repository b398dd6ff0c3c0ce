//! Eq. 3.3 (§3.3.1) on the studio's own views: the MakeHuman performer in the skirt seen by
//! the ring of 8 cameras, exact normals (the rasteriser's), the visual hull of the 8
//! silhouettes as proxy — the ragged masks (thin limbs, the hull's discontinuity cuts,
//! grazing silhouettes) of the reconstruction, not the compact sphere of `integrate`. Each
//! view is solved by the direct sparse Cholesky and by the multigrid-preconditioned CG, at
//! α = 10⁻⁶ (pass 1) and 10⁻⁵ (pass 2), side by side.
//!
//! `cargo bench -p photometric-normals --features validation --bench integrate_studio
//! [-- SIZE [VIEW …]]` (default 1024, all 8 views): one JSON line per view and α (foreground
//! unknowns, wall and CPU seconds of each solver, CG iterations, max / RMS depth difference),
//! then one summary line (total CPU seconds of each solver).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

use std::path::PathBuf;
use std::time::Instant;

mod common;
use common::{cpu_seconds, max_rms_diff};

use photometric_normals::truth::{render_both_faces, skirt_subject, StudioScene};
use photometric_normals::{
    integrate_normals, rendered_normals, Integrated, IntegrationParams, IntegrationSolver,
    MultigridParams, PolygonalHull, PolygonalHullParams,
};
use skin_core::camera::Camera;
use skin_core::image::Mask;
use skin_core::raster::RenderedView;

/// One solve: the result, wall and CPU seconds.
fn timed(f: impl FnOnce() -> Integrated) -> (Integrated, f64, f64) {
    let (t, c) = (Instant::now(), cpu_seconds());
    let out = f();
    (out, t.elapsed().as_secs_f64(), cpu_seconds() - c)
}

fn main() {
    let args: Vec<usize> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let size = args.first().copied().unwrap_or(1024) as u32;
    let cameras = 8;
    let views: Vec<usize> = if args.len() > 1 {
        args[1..].to_vec()
    } else {
        (0..cameras).collect()
    };
    let data = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../data/makehuman");
    let t0 = Instant::now();
    let scene = StudioScene::new(&data, &skirt_subject(), cameras, size).unwrap();
    let mesh = scene.true_mesh().unwrap();
    let cams: &[Camera] = &scene.ring.cameras;
    let rendered = render_both_faces(cams, &mesh).unwrap();
    let silhouettes: Vec<Mask> = rendered.iter().map(RenderedView::silhouette).collect();
    let hull = PolygonalHull::new(cams, &silhouettes).unwrap();
    println!(
        "{{\"setup_s\":{:.1},\"size\":{size}}}",
        t0.elapsed().as_secs_f64()
    );
    // Multigrid knobs from the environment, for tuning (MG_SCALE, MG_SWEEPS, MG_CYCLE, MG_EPS,
    // MG_OMEGA).
    let env = |k: &str| std::env::var(k).ok().and_then(|v| v.parse::<f64>().ok());
    let mut mg = MultigridParams::default();
    if let Some(v) = env("MG_SCALE") {
        mg.coarse_scale = v;
    }
    if let Some(v) = env("MG_SWEEPS") {
        mg.smoothing_sweeps = v as usize;
    }
    if let Some(v) = env("MG_CYCLE") {
        mg.cycle_index = v as usize;
    }
    if let Some(v) = env("MG_EPS") {
        mg.strength_threshold = v;
    }
    if let Some(v) = env("MG_OMEGA") {
        mg.prolongation_smoothing = v;
    }
    println!("{{\"multigrid\":\"{mg:?}\"}}");
    let (mut direct_cpu, mut mg_cpu, mut max_iter, mut max_diff) = (0.0, 0.0, 0, 0.0f64);
    for &v in &views {
        let proxy = hull.depth_map(v, &PolygonalHullParams::default()).unwrap();
        let normals = rendered_normals(&cams[v], &rendered[v]).unwrap();
        for alpha in [1e-6, 1e-5] {
            let base = IntegrationParams {
                alpha,
                ..IntegrationParams::default()
            };
            let run = |solver| {
                integrate_normals(&cams[v], &normals, &proxy, None, &base.with_solver(solver))
                    .unwrap()
            };
            let (d, d_wall, d_cpu) = timed(|| run(IntegrationSolver::Direct));
            let (m, m_wall, m_cpu) = timed(|| run(IntegrationSolver::Multigrid(mg)));
            let (max, rms) = max_rms_diff(&d.depth.depth_m, &m.depth.depth_m);
            direct_cpu += d_cpu;
            mg_cpu += m_cpu;
            max_iter = max_iter.max(m.report.iterations);
            max_diff = max_diff.max(max);
            println!(
                "{{\"view\":{v},\"alpha\":{alpha:e},\"unknowns\":{},\"direct_wall_s\":{d_wall:.3},\
                 \"direct_cpu_s\":{d_cpu:.3},\"multigrid_wall_s\":{m_wall:.3},\
                 \"multigrid_cpu_s\":{m_cpu:.3},\"iterations\":{},\"relative_residual\":{:.2e},\
                 \"max_diff_m\":{max:.3e},\"rms_diff_m\":{rms:.3e}}}",
                m.report.unknowns, m.report.iterations, m.report.relative_residual,
            );
        }
    }
    println!(
        "{{\"size\":{size},\"views\":{},\"direct_cpu_s\":{direct_cpu:.2},\"multigrid_cpu_s\":{mg_cpu:.2},\
         \"cpu_ratio\":{:.2},\"max_iterations\":{max_iter},\"max_diff_m\":{max_diff:.3e}}}",
        views.len(),
        mg_cpu / direct_cpu
    );
}
