//! Laplacian editing (Vlasic 2010 thesis §2.4.1, Eq. 2.2 with `w_L = 1`, `w_C = 1000`):
//! `min_V ‖Δ V − δ‖² + w_C ‖C V − P‖²` with the cotangent Laplacian `Δ` and soft positional
//! constraints, solved by `skin_core::lsq`.
//!
//! 1. Peer problem of `bench/peers/laplacian.py`: the deformed level-5 icosphere, 500 random
//!    constraints, factor `ΔᵀΔ + 1000 CᵀC`, one 3-RHS solve; timings are medians of 5 runs
//!    after one warm-up, as the peers measure them.
//! 2. MakeHuman body: pin the feet and the body outside the left arm, pull the left hand up
//!    and forward, write the edited mesh
//!    as OBJ and a before/after render (studio rasteriser) as PNG under `out/laplacian_edit/`.
//!
//! `cargo run --release --example laplacian_edit [-- --quick] [-- --par] [-- --out DIR]`
//! (`--quick`: level-4 icosphere, 3 repetitions; `--par`: rayon inside the factorisation).
//! Last stdout line: one JSON object with all figures.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

use std::path::Path;
use std::time::Instant;

use clap::Parser;
use dynamic_shapes::core::lsq::{CholeskyParams, LsqParams, LsqProblem};
use dynamic_shapes::core::math::DVec3;
use dynamic_shapes::core::mesh::{
    cotangent_laplacian, read_obj_group, shapes, write_obj, LaplacianParams, TriMesh,
};
use dynamic_shapes::core::random::SplitMix64;
use dynamic_shapes_studio::{preview, Paint, PreviewPanel};
use example_kit::{Headline, Run};
use nalgebra::DMatrix;
use nalgebra_sparse::{CooMatrix, CscMatrix};
use serde_json::json;

type AnyResult<T> = Result<T, Box<dyn std::error::Error>>;

/// Constraint weight `w_C` (Vlasic 2010 §2.4.2, Eq. 2.1–2.2).
const W_C: f64 = 1000.0;
/// Laplacian-coordinate weight of the peer problem (`laplacian.py`: w = 0.5).
const PEER_W_L: f64 = 0.5;
/// Constraints of the peer problem.
const PEER_CONSTRAINTS: usize = 500;
/// Noise of the peer targets, mesh units.
const PEER_NOISE: f64 = 0.05;

/// Median wall time (ms) of `reps` runs after one warm-up, and the last result.
fn median_ms<T>(reps: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let mut out = f();
    let mut times = Vec::with_capacity(reps);
    for _ in 0..reps {
        let t = Instant::now();
        out = f();
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    (dynamic_shapes::core::stats::median(&times), out)
}

fn positions(mesh: &TriMesh) -> DMatrix<f64> {
    DMatrix::from_fn(mesh.vertices.len(), 3, |i, k| mesh.vertices[i][k])
}

fn selection(n: usize, rows: &[usize]) -> CscMatrix<f64> {
    let mut coo = CooMatrix::new(rows.len(), n);
    for (r, &i) in rows.iter().enumerate() {
        coo.push(r, i, 1.0);
    }
    CscMatrix::from(&coo)
}

fn peer(run: &Run, level: u32, reps: usize, params: &LsqParams) -> AnyResult<serde_json::Value> {
    let stage = run.stage("peer problem", None);
    let mesh = shapes::peer_blob(level)?;
    let n = mesh.vertices.len();
    stage.set_message(format!("icosphere level {level}, {n} vertices"));
    let (build_ms, l) = median_ms(reps, || {
        cotangent_laplacian(&mesh, &LaplacianParams::default())
    });
    let l = l?;
    let v = positions(&mesh);
    let b = (&l * &v) * PEER_W_L;
    let chosen = SplitMix64::new(40).choose(n, PEER_CONSTRAINTS)?;
    let noise = SplitMix64::new(41).normal(PEER_CONSTRAINTS * 3);
    let p = DMatrix::from_fn(PEER_CONSTRAINTS, 3, |r, k| {
        v[(chosen[r], k)] + PEER_NOISE * noise[3 * r + k]
    });
    let c = selection(n, &chosen);
    let problem = LsqProblem::new(l).with_term(c, W_C);
    let (factor_ms, solver) = median_ms(reps, || problem.clone().factor(params));
    let mut solver = solver?;
    let stats = solver.stats();
    // Numeric-only refactorisation (new weight, same pattern), as in Vlasic Algorithm 1.
    let mut w = W_C;
    let (refactor_ms, r) = median_ms(reps, || {
        w = if w == W_C { W_C * 0.999 } else { W_C };
        solver.set_weights(&[w])
    });
    r?;
    solver.set_weights(&[W_C])?;
    let refactor_stats = solver.stats();
    let d = [p];
    let (solve_ms, x) = median_ms(reps, || solver.solve(&b, &d));
    let x = x?;
    let diag = solver.diagnostics(&x, &b, &d)?;
    stage.finish(format!(
        "icosphere level {level}, {n} vertices: build {build_ms:.2} ms, factor {factor_ms:.2} ms (pattern {:.2}, symbolic {:.2}, assemble {:.2}, numeric {:.2}), refactor {refactor_ms:.2} ms, solve {solve_ms:.2} ms, objective {:.4}, residual {:.2e}",
        stats.pattern_ms,
        stats.cholesky.symbolic_ms,
        stats.assemble_ms,
        stats.cholesky.numeric_ms,
        diag.objective,
        diag.normal_rel_residual
    ));
    Ok(json!({
        "level": level,
        "vertices": n,
        "faces": mesh.faces.len(),
        "laplacian_build_ms": build_ms,
        "lsq_factor_ms": factor_ms,
        "lsq_pattern_ms": stats.pattern_ms,
        "lsq_symbolic_ms": stats.cholesky.symbolic_ms,
        "lsq_assemble_ms": refactor_stats.assemble_ms,
        "lsq_numeric_ms": refactor_stats.cholesky.numeric_ms,
        "lsq_refactor_ms": refactor_ms,
        "lsq_solve_ms": solve_ms,
        "lsq_factor_plus_solve_ms": factor_ms + solve_ms,
        "normal_nnz_lower": stats.cholesky.matrix_nnz_lower,
        "factor_values": stats.cholesky.factor_values,
        "supernodal": stats.cholesky.supernodal,
        "normal_eq_rel_residual": diag.normal_rel_residual,
        "objective": diag.objective,
    }))
}

/// Front views of several meshes side by side ([`preview`], studio rasteriser, headlight
/// shading) under a title, written to `path`.
fn render(
    meshes: &[(&TriMesh, [u8; 3])],
    title: &str,
    subtitle: &str,
    path: &Path,
) -> AnyResult<()> {
    let panels: Vec<PreviewPanel> = meshes
        .iter()
        .map(|&(mesh, c)| PreviewPanel {
            mesh,
            paint: Paint::Flat(c),
        })
        .collect();
    let img = example_kit::plot::titled(&preview(&panels, 480)?, title, Some(subtitle))?;
    example_kit::plot::save(&img, path)?;
    Ok(())
}

fn makehuman(run: &mut Run, params: &LsqParams) -> AnyResult<serde_json::Value> {
    let stage = run.stage("makehuman edit", None);
    let path = example_kit::data_path("makehuman/base.obj")?;
    let mesh = read_obj_group(&path, "body")?;
    let n = mesh.vertices.len();
    stage.set_message(format!(
        "body with {n} vertices, {} faces",
        mesh.faces.len()
    ));
    let t = Instant::now();
    let l = cotangent_laplacian(&mesh, &LaplacianParams::default())?;
    let build_ms = t.elapsed().as_secs_f64() * 1e3;
    let v = positions(&mesh);
    let delta = &l * &v; // w_L = 1: full detail (Vlasic §2.4.1)
    let (lo, hi) = mesh.vertices.iter().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    );
    let height = hi.y - lo.y;
    // Anchors: the feet (lowest 3 % of the body height) and, as in region-of-interest
    // Laplacian editing (Sorkine et al. 2004), everything outside the left arm (x below 35 %
    // of the half-width), so that only the arm bends. Hand: the outermost 5 % along +x (the
    // model's left hand in its rest A pose).
    let arm_start = 0.35 * hi.x;
    let anchor: Vec<usize> = (0..n)
        .filter(|&i| {
            let p = mesh.vertices[i];
            p.y < lo.y + 0.03 * height || p.x < arm_start
        })
        .collect();
    let hand: Vec<usize> = (0..n)
        .filter(|&i| mesh.vertices[i].x > hi.x - 0.05 * height)
        .collect();
    if anchor.is_empty() || hand.is_empty() {
        return Err("no anchor or hand vertices found".into());
    }
    let pull = DVec3::new(-0.03, 0.12, 0.08) * height;
    let p_anchor = DMatrix::from_fn(anchor.len(), 3, |r, k| v[(anchor[r], k)]);
    let p_hand = DMatrix::from_fn(hand.len(), 3, |r, k| v[(hand[r], k)] + pull[k]);
    let t = Instant::now();
    let solver = LsqProblem::new(l)
        .with_term(selection(n, &anchor), W_C)
        .with_term(selection(n, &hand), W_C)
        .factor(params)?;
    let factor_ms = t.elapsed().as_secs_f64() * 1e3;
    let t = Instant::now();
    let x = solver.solve(&delta, &[p_anchor.clone(), p_hand.clone()])?;
    let solve_ms = t.elapsed().as_secs_f64() * 1e3;
    let diag = solver.diagnostics(&x, &delta, &[p_anchor, p_hand])?;
    let edited = TriMesh::new(
        (0..n)
            .map(|i| DVec3::new(x[(i, 0)], x[(i, 1)], x[(i, 2)]))
            .collect(),
        mesh.faces.clone(),
    )?;
    let anchor_err = anchor
        .iter()
        .map(|&i| (edited.vertices[i] - mesh.vertices[i]).length())
        .fold(0.0, f64::max);
    let hand_shift = hand
        .iter()
        .map(|&i| edited.vertices[i] - mesh.vertices[i])
        .sum::<DVec3>()
        / hand.len() as f64;
    let hand_err = (hand_shift - pull).length() / pull.length();
    write_obj(run.path("makehuman_edit.obj"), &edited)?;
    render(
        &[(&mesh, [90, 120, 200]), (&edited, [230, 140, 60])],
        "Laplacian edit of the MakeHuman body: left hand pulled up and forward",
        "front views; blue: before, orange: after (feet and body outside the left arm pinned)",
        &run.path("makehuman_before_after.png"),
    )?;
    run.picture(
        "makehuman_before_after.png",
        "The MakeHuman body before (blue) and after (orange) the edit: the left hand is pulled \
         up and forward while the feet and everything outside the left arm stay pinned; the \
         arm bends smoothly and keeps its detail (cotangent Laplacian, w_C = 1000).",
    );
    stage.finish(format!(
        "build {build_ms:.2} ms, factor {factor_ms:.2} ms, solve {solve_ms:.2} ms, anchors moved <= {anchor_err:.2e}, hand pull error {:.1} %",
        100.0 * hand_err
    ));
    Ok(json!({
        "makehuman_vertices": n,
        "makehuman_faces": mesh.faces.len(),
        "makehuman_anchor_constraints": anchor.len(),
        "makehuman_hand_constraints": hand.len(),
        "makehuman_laplacian_build_ms": build_ms,
        "makehuman_lsq_factor_ms": factor_ms,
        "makehuman_lsq_solve_ms": solve_ms,
        "makehuman_anchor_max_move": anchor_err,
        "makehuman_hand_pull_rel_err": hand_err,
        "makehuman_normal_eq_rel_residual": diag.normal_rel_residual,
        "makehuman_objective": diag.objective,
    }))
}

/// Laplacian editing (Vlasic 2010 §2.4.1) solved by `skin_core::lsq`: the peers' icosphere
/// problem, then a hand pulled on the MakeHuman body.
#[derive(Parser)]
struct Args {
    #[command(flatten)]
    common: example_kit::Common,
    /// Use rayon inside the factorisation.
    #[arg(long)]
    par: bool,
}

fn main() -> AnyResult<()> {
    let start = Instant::now();
    let args = Args::parse();
    let quick = args.common.quick;
    let par = args.par;
    let params = LsqParams {
        cholesky: CholeskyParams {
            parallel: par,
            ..Default::default()
        },
    };
    let (level, reps) = if quick { (4, 3) } else { (5, 5) };
    let mut run = Run::start(
        "laplacian_edit",
        &args.common,
        &format!(
            "Laplacian editing (Vlasic 2010 §2.4.1, cotangent Laplacian, soft constraints w_C = \
             1000) solved by sparse least squares: the peers' problem on a level-{level} \
             icosphere (500 noisy constraints, median of {reps} runs), then the left hand of \
             the MakeHuman body pulled up and forward with its feet and the rest of the body \
             pinned."
        ),
    )?;
    let peer_figures = peer(&run, level, reps, &params)?;
    let mh = makehuman(&mut run, &params)?;
    for (key, label, unit) in [
        (
            "laplacian_build_ms",
            "cotangent Laplacian build (icosphere)",
            "ms",
        ),
        (
            "lsq_factor_ms",
            "factorisation of ΔᵀΔ + w_C CᵀC (icosphere)",
            "ms",
        ),
        ("lsq_solve_ms", "3-right-hand-side solve (icosphere)", "ms"),
        ("vertices", "icosphere vertices", ""),
        (
            "makehuman_lsq_factor_ms",
            "factorisation (MakeHuman body)",
            "ms",
        ),
        ("makehuman_lsq_solve_ms", "solve (MakeHuman body)", "ms"),
        (
            "makehuman_hand_pull_rel_err",
            "hand displacement error, relative to the pull",
            "",
        ),
    ] {
        run.headline(Headline::new(key, label, unit));
    }
    let mut out = json!({ "example": "laplacian_edit", "quick": quick, "parallel": par });
    let obj = out.as_object_mut().ok_or("json object")?;
    for fig in [peer_figures, mh] {
        if let serde_json::Value::Object(m) = fig {
            obj.extend(m);
        }
    }
    obj.insert("seconds".into(), json!(start.elapsed().as_secs_f64()));
    run.finish(out)?;
    Ok(())
}
