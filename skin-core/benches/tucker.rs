//! Criterion benches of the peer partial-Tucker workload (`bench/peers/tucker.py`, TensorLy
//! `partial_tucker`), regenerated in Rust with the peers' SplitMix64 normals (bit-exact
//! uniforms; normals equal up to the last ulp of libm):
//!
//! * order 3: `X (N, 10, 15)`, modes 1 and 2 decomposed at ranks (6, 9);
//! * order 4: `X (N, 5, 5, 16)`, modes 1–3 at ranks (4, 4, 16); `N = 30000`, mode 0 kept.
//!
//! `G = normal(11, (N, r…))`, `Aₘ = normal(12 + m − 1, (nₘ, rₘ))`, `Xc = G ×₁ A₁ ×₂ A₂ [×₃ A₃]`,
//! `X = Xc + 0.01 ‖Xc‖ / ‖E0‖ · E0` with `E0 = normal(20, X.shape)`. HOSVD = no sweep; HOOI
//! = TensorLy's defaults (≤ 100 sweeps, tol 1e-4 on the change of the relative error).
//! Input generation is not timed. The relative errors are printed once per variant.
//! `tucker_huge_mode` factors the 30000-long mode 0 at rank 10 by thin SVD and by the
//! randomized range finder.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

// `criterion_group!` generates an undocumented `pub fn benches`.
#![allow(missing_docs)]

use criterion::{criterion_group, criterion_main, Criterion};
use nalgebra::DMatrix;
use skin_core::random::SplitMix64;
use skin_core::tensor::{hooi, hosvd, FactorMethod, HooiParams, RandomizedParams, Tensor};
use std::hint::black_box;

const N: usize = 30_000;

struct Workload {
    x: Tensor,
    clean: Tensor,
    ranks: Vec<Option<usize>>,
}

fn workload(dims: &[usize], ranks: &[usize]) -> Workload {
    let mut core_shape = vec![N];
    core_shape.extend_from_slice(ranks);
    let len = core_shape.iter().product();
    let g = Tensor::new(core_shape, SplitMix64::new(11).normal(len)).unwrap();
    let factors: Vec<DMatrix<f64>> = dims
        .iter()
        .zip(ranks)
        .enumerate()
        .map(|(i, (&d, &r))| {
            // Row-major (d × r) fill, as numpy.
            DMatrix::from_row_slice(d, r, &SplitMix64::new(12 + i as u64).normal(d * r))
        })
        .collect();
    let products: Vec<(usize, &DMatrix<f64>)> = factors
        .iter()
        .enumerate()
        .map(|(i, a)| (i + 1, a))
        .collect();
    let clean = g.multi_mode_product(&products).unwrap();
    let e0 = SplitMix64::new(20).normal(clean.len());
    let e0_norm = e0.iter().map(|v| v * v).sum::<f64>().sqrt();
    let scale = 0.01 * clean.norm() / e0_norm;
    let data = clean
        .data()
        .iter()
        .zip(&e0)
        .map(|(c, e)| c + scale * e)
        .collect();
    let x = Tensor::new(clean.shape().to_vec(), data).unwrap();
    let mut r = vec![None];
    r.extend(ranks.iter().map(|&r| Some(r)));
    Workload { x, clean, ranks: r }
}

fn bench(cr: &mut Criterion) {
    for (name, dims, ranks) in [
        ("order3", vec![10, 15], vec![6, 9]),
        ("order4", vec![5, 5, 16], vec![4, 4, 16]),
    ] {
        let w = workload(&dims, &ranks);
        let h = hosvd(&w.x, &w.ranks, FactorMethod::Auto).unwrap();
        let hx = h.reconstruct().unwrap();
        let o = hooi(&w.x, &w.ranks, &HooiParams::default()).unwrap();
        let ox = o.tucker.reconstruct().unwrap();
        println!(
            "tucker {name} {:?}: hosvd rel_err_vs_input {:.10e} vs_clean {:.10e}; \
             hooi {} sweeps rel_err_vs_input {:.10e} vs_clean {:.10e}",
            w.x.shape(),
            hx.relative_error(&w.x).unwrap(),
            hx.relative_error(&w.clean).unwrap(),
            o.errors.len(),
            ox.relative_error(&w.x).unwrap(),
            ox.relative_error(&w.clean).unwrap(),
        );
        let mut g = cr.benchmark_group(format!("tucker_{name}"));
        g.sample_size(10);
        g.bench_function("hosvd", |b| {
            b.iter(|| hosvd(black_box(&w.x), &w.ranks, FactorMethod::Auto).unwrap())
        });
        g.bench_function("hooi", |b| {
            b.iter(|| hooi(black_box(&w.x), &w.ranks, &HooiParams::default()).unwrap())
        });
        g.finish();
    }
    // The huge mode: factor of mode 0 (N = 30000 rows, unfolding 30000 × 150) at rank 10 of
    // the order-3 input, by the thin SVD (what `Auto` picks for this tall unfolding) and by
    // the randomized range finder.
    let w = workload(&[10, 15], &[6, 9]);
    let ranks = [Some(10), None, None];
    let mut g = cr.benchmark_group("tucker_huge_mode");
    g.sample_size(10);
    for (name, method) in [
        ("svd", FactorMethod::Svd),
        (
            "randomized",
            FactorMethod::Randomized(RandomizedParams::default()),
        ),
    ] {
        let t = hosvd(&w.x, &ranks, method).unwrap();
        println!(
            "tucker_huge_mode {name}: rank 10 rel_err_vs_input {:.10e}",
            t.reconstruct().unwrap().relative_error(&w.x).unwrap()
        );
        g.bench_function(name, |b| {
            b.iter(|| hosvd(black_box(&w.x), &ranks, method).unwrap())
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
