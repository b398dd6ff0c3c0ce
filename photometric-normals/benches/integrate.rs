//! Eq. 3.3 (§3.3.1) on one sphere view at 512² and 1024², foreground pixels only: the direct
//! sparse Cholesky (`IntegrationSolver::Direct`, the default) against multigrid-preconditioned
//! CG (`IntegrationSolver::Multigrid`), with α = 10⁻⁶ (pass 1).
//!
//! The view: a sphere of radius 0.4 m seen from 1.5 m (63 % of the pixels are
//! foreground), normals perturbed by a deterministic 0.1-rad-scale noise, and a proxy pushed
//! 3 cm forward with a 5 cm bulge, so that the proxy is wrong in shape and the normals are
//! not exactly integrable (like the visual hull and part-1 normals).
//!
//! Runs:
//! * `cargo bench -p photometric-normals --bench integrate`: first one line of JSON per size
//!   (seconds, CG iterations, relative residual, max / RMS depth difference between the two
//!   solvers), then criterion's timings.
//! * `… --bench integrate -- --once {direct|multigrid|setup} SIZE [SWEEPS SCALE [SIDE OMEGA]]`:
//!   one solve (or only the view's set-up), for timing the whole process from outside;
//!   optionally with other multigrid smoothing sweeps, coarse-correction scale, aggregate side
//!   and prolongator smoothing (`1 1.8 2 0` is plain 2 × 2 aggregation).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

// criterion_group!/criterion_main! generate undocumented public functions.
#![allow(missing_docs)]

use std::hint::black_box;
use std::time::Instant;

mod common;
use common::max_rms_diff;

use criterion::Criterion;
use photometric_normals::{
    integrate_normals, rendered_normals, DepthMap, IntegrationParams, IntegrationSolver, NormalMap,
};
use skin_core::camera::{Camera, Intrinsics};
use skin_core::math::DVec3;
use skin_core::mesh::shapes::uv_sphere;
use skin_core::random::SplitMix64;
use skin_core::raster::{Rasterizer, RenderParams};

struct View {
    camera: Camera,
    normals: NormalMap,
    proxy: DepthMap,
}

fn sphere_view(size: u32) -> View {
    let k = Intrinsics::from_horizontal_fov(0.6, size, size).unwrap();
    let camera = Camera::look_at(k, DVec3::new(0.0, 0.0, 1.5), DVec3::ZERO, DVec3::Y).unwrap();
    let mesh = uv_sphere(DVec3::ZERO, 0.4, 256, 512).unwrap();
    let view = Rasterizer::new(&camera)
        .render(&mesh, &RenderParams::default())
        .unwrap();
    let truth = DepthMap::from_view(&view).unwrap();
    let mut normals = rendered_normals(&camera, &view).unwrap();
    let noise = SplitMix64::new(7);
    for (i, n) in normals.normals.iter_mut().enumerate() {
        let e = noise.uniform_at(i as u64) - 0.5;
        *n = (*n + DVec3::new(0.1 * e, -0.05 * e, 0.0)).normalize();
    }
    let s = f64::from(size);
    let proxy = DepthMap::new(
        size,
        size,
        truth
            .depth_m
            .iter()
            .enumerate()
            .map(|(i, d)| {
                d - 0.03 + 0.05 * ((i % size as usize) as f64 / s * std::f64::consts::PI).sin()
            })
            .collect(),
    )
    .unwrap();
    View {
        camera,
        normals,
        proxy,
    }
}

fn params(direct: bool) -> IntegrationParams {
    IntegrationParams::default().with_solver(if direct {
        IntegrationSolver::Direct
    } else {
        IntegrationSolver::multigrid()
    })
}

fn solve(view: &View, direct: bool) -> photometric_normals::Integrated {
    integrate_normals(
        &view.camera,
        &view.normals,
        &view.proxy,
        None,
        &params(direct),
    )
    .unwrap()
}

fn summary(size: u32) {
    let view = sphere_view(size);
    let t = Instant::now();
    let direct = solve(&view, true);
    let direct_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let mg = solve(&view, false);
    let mg_s = t.elapsed().as_secs_f64();
    let (max, rms) = max_rms_diff(&direct.depth.depth_m, &mg.depth.depth_m);
    println!(
        "{{\"size\":{size},\"unknowns\":{},\"direct_s\":{direct_s:.3},\"multigrid_s\":{mg_s:.3},\
         \"speedup\":{:.2},\"iterations\":{},\"relative_residual\":{:.2e},\
         \"max_diff_m\":{max:.3e},\"rms_diff_m\":{rms:.3e}}}",
        mg.report.unknowns,
        direct_s / mg_s,
        mg.report.iterations,
        mg.report.relative_residual,
    );
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if let Some(k) = args.iter().position(|a| a == "--once") {
        let which = args.get(k + 1).map(String::as_str).unwrap_or("multigrid");
        let size = args.get(k + 2).and_then(|s| s.parse().ok()).unwrap_or(1024);
        let view = sphere_view(size);
        let mut p = params(which == "direct");
        // Optional tuning arguments: smoothing sweeps, coarse-correction scale, aggregate
        // side and prolongator smoothing.
        let arg = |i: usize| args.get(k + i).and_then(|s| s.parse::<f64>().ok());
        if let IntegrationSolver::Multigrid(mg) = &mut p.solver {
            if let (Some(sweeps), Some(scale)) = (arg(3), arg(4)) {
                mg.smoothing_sweeps = sweeps as usize;
                mg.coarse_scale = scale;
            }
            if let (Some(side), Some(omega)) = (arg(5), arg(6)) {
                mg.aggregate_side = side as usize;
                mg.prolongation_smoothing = omega;
            }
        }
        if which != "setup" {
            let t = Instant::now();
            let out =
                integrate_normals(&view.camera, &view.normals, &view.proxy, None, &p).unwrap();
            println!(
                "{which} {size}: {:.3} s, {:?}",
                t.elapsed().as_secs_f64(),
                out.report
            );
        }
        return;
    }
    // Under `cargo bench` (not `cargo test --benches`, which runs each benchmark once).
    if args.iter().any(|a| a == "--bench") {
        for size in [512, 1024] {
            summary(size);
        }
    }
    let mut c = Criterion::default().configure_from_args();
    for size in [512u32, 1024] {
        let view = sphere_view(size);
        let mut g = c.benchmark_group(format!("integrate_sphere_{size}"));
        g.sample_size(10);
        for (name, direct) in [("direct", true), ("multigrid", false)] {
            g.bench_function(name, |b| b.iter(|| solve(black_box(&view), direct)));
        }
        g.finish();
    }
    c.final_summary();
}
