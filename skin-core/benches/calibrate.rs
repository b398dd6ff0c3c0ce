//! Calibration speed on the `calibrate` example's problem: 300 points, σ = 0.5 px.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code
#![allow(missing_docs)] // criterion_group! generates an undocumented public function

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use rand::SeedableRng;
use skin_core::camera::{
    calibrate, dlt, synthetic_calibration, CalibrationMethod, CalibrationParams,
    SyntheticCalibrationParams,
};

fn bench(c: &mut Criterion) {
    let p = SyntheticCalibrationParams::default();
    let s = synthetic_calibration(&p, &mut rand_chacha::ChaCha8Rng::seed_from_u64(7))
        .expect("synthetic problem");
    let mut g = c.benchmark_group("calibrate");
    g.bench_function("dlt_300", |b| {
        b.iter(|| {
            dlt(
                black_box(&s.world),
                black_box(&s.pixels),
                p.width,
                p.height,
                1e-3,
            )
        })
    });
    g.bench_function("dlt_lm_300", |b| {
        b.iter(|| {
            calibrate(
                black_box(&s.world),
                black_box(&s.pixels),
                p.width,
                p.height,
                &CalibrationParams::default(),
            )
        })
    });
    g.sample_size(10);
    let nm = CalibrationParams::default().with_method(CalibrationMethod::NelderMead);
    g.bench_function("dlt_nelder_mead_300", |b| {
        b.iter(|| {
            calibrate(
                black_box(&s.world),
                black_box(&s.pixels),
                p.width,
                p.height,
                &nm,
            )
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
