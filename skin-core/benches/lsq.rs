//! Criterion benches of the peer Laplacian-editing problem (`bench/peers/laplacian.py`):
//! cotangent Laplacian of the deformed level-5 icosphere, factorisation of
//! `ΔᵀΔ + 1000 CᵀC` (500 constraints `choose(40, n, 500)`), one 3-RHS solve.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

// `criterion_group!` generates an undocumented `pub fn benches`.
#![allow(missing_docs)]

use criterion::{criterion_group, criterion_main, Criterion};
use nalgebra::DMatrix;
use nalgebra_sparse::{CooMatrix, CscMatrix};
use skin_core::lsq::{LsqParams, LsqProblem};
use skin_core::mesh::{cotangent_laplacian, shapes, LaplacianParams};
use skin_core::random::SplitMix64;
use std::hint::black_box;

struct Peer {
    l: CscMatrix<f64>,
    c: CscMatrix<f64>,
    b: DMatrix<f64>,
    p: DMatrix<f64>,
}

fn peer_problem(level: u32) -> (skin_core::mesh::TriMesh, Peer) {
    let mesh = shapes::peer_blob(level).expect("valid level");
    let n = mesh.vertices.len();
    let l = cotangent_laplacian(&mesh, &LaplacianParams::default()).expect("valid mesh");
    let v = DMatrix::from_fn(n, 3, |i, k| mesh.vertices[i][k]);
    let b = (&l * &v) * 0.5;
    let chosen = SplitMix64::new(40).choose(n, 500).expect("500 <= n");
    let noise = SplitMix64::new(41).normal(500 * 3);
    let p = DMatrix::from_fn(500, 3, |r, k| v[(chosen[r], k)] + 0.05 * noise[3 * r + k]);
    let mut coo = CooMatrix::new(500, n);
    for (r, &i) in chosen.iter().enumerate() {
        coo.push(r, i, 1.0);
    }
    let c = CscMatrix::from(&coo);
    (mesh, Peer { l, c, b, p })
}

fn bench(cr: &mut Criterion) {
    let (mesh, peer) = peer_problem(5);
    let mut g = cr.benchmark_group("lsq_icosphere5");
    g.sample_size(20);
    g.bench_function("cotangent_laplacian", |bch| {
        bch.iter(|| cotangent_laplacian(black_box(&mesh), &LaplacianParams::default()).unwrap())
    });
    let problem = LsqProblem::new(peer.l.clone()).with_term(peer.c.clone(), 1000.0);
    g.bench_function("factor_full", |bch| {
        bch.iter(|| problem.clone().factor(&LsqParams::default()).unwrap())
    });
    let mut solver = problem.clone().factor(&LsqParams::default()).unwrap();
    let mut w = 1000.0;
    g.bench_function("refactor_new_weight", |bch| {
        bch.iter(|| {
            w = if w == 1000.0 { 999.0 } else { 1000.0 };
            solver.set_weights(&[w]).unwrap()
        })
    });
    let d = [peer.p.clone()];
    g.bench_function("solve_3rhs", |bch| {
        bch.iter(|| solver.solve(black_box(&peer.b), &d).unwrap())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
