use nalgebra::{DMatrix, DVector};

use super::*;

/// A 1-D Laplacian plus a varying diagonal (symmetric positive definite), `n` unknowns.
fn spd(n: usize) -> DMatrix<f64> {
    DMatrix::from_fn(n, n, |i, j| match i.abs_diff(j) {
        0 => 2.0 + 0.1 * (i % 5) as f64,
        1 => -1.0,
        _ => 0.0,
    })
}

fn operator(m: &DMatrix<f64>) -> impl Fn(&[f64], &mut [f64]) + '_ {
    move |x, y| y.copy_from_slice((m * DVector::from_column_slice(x)).as_slice())
}

fn params(reference: Reference, reduction: Reduction) -> PcgParams {
    PcgParams {
        tolerance: 1e-12,
        max_iterations: 500,
        reference,
        reduction,
    }
}

#[test]
fn solves_a_small_spd_system_as_the_direct_solve_does() {
    let n = 40;
    let m = spd(n);
    let b: Vec<f64> = (0..n).map(|i| (i as f64 * 0.7).sin()).collect();
    let direct = m
        .clone()
        .cholesky()
        .unwrap()
        .solve(&DVector::from_column_slice(&b));
    let diag: Vec<f64> = (0..n).map(|i| m[(i, i)]).collect();
    let a = operator(&m);
    for reduction in [Reduction::Serial, Reduction::Chunked(7)] {
        for reference in [Reference::RightHandSide, Reference::Start] {
            for use_closure in [false, true] {
                let scales = vec![2.0; n];
                for norm in [ResidualNorm::Euclidean, ResidualNorm::DividedBy(&scales)] {
                    let mut x = vec![0.5; n];
                    let mut jacobi = |r: &[f64], z: &mut [f64]| {
                        for ((zi, ri), di) in z.iter_mut().zip(r).zip(&diag) {
                            *zi = ri / di;
                        }
                    };
                    let pre = if use_closure {
                        Preconditioner::Apply(&mut jacobi)
                    } else {
                        Preconditioner::Jacobi(&diag)
                    };
                    let stats =
                        pcg(&a, pre, &b, &mut x, norm, &params(reference, reduction)).unwrap();
                    assert_eq!(stats.stop, PcgStop::Converged, "{stats:?}");
                    assert!(stats.iterations <= n, "{stats:?}");
                    assert!(stats.relative_residual <= 1e-12, "{stats:?}");
                    let err = x
                        .iter()
                        .zip(direct.iter())
                        .map(|(a, b)| (a - b).abs())
                        .fold(0.0, f64::max);
                    assert!(err < 1e-9, "{reduction:?} {reference:?}: {err}");
                }
            }
        }
    }
}

#[test]
fn a_jacobi_closure_gives_the_same_iterates_as_the_fused_jacobi() {
    let n = 50;
    let m = spd(n);
    let b: Vec<f64> = (0..n).map(|i| 1.0 + (i as f64).cos()).collect();
    let diag: Vec<f64> = (0..n).map(|i| m[(i, i)]).collect();
    let a = operator(&m);
    for reduction in [Reduction::Serial, Reduction::Chunked(16)] {
        let p = PcgParams {
            tolerance: 1e-9,
            ..params(Reference::RightHandSide, reduction)
        };
        let mut fused = vec![0.0; n];
        let s1 = pcg(
            &a,
            Preconditioner::Jacobi(&diag),
            &b,
            &mut fused,
            ResidualNorm::Euclidean,
            &p,
        )
        .unwrap();
        let mut jacobi = |r: &[f64], z: &mut [f64]| {
            for ((zi, ri), di) in z.iter_mut().zip(r).zip(&diag) {
                *zi = ri / di;
            }
        };
        let mut general = vec![0.0; n];
        let s2 = pcg(
            &a,
            Preconditioner::Apply(&mut jacobi),
            &b,
            &mut general,
            ResidualNorm::Euclidean,
            &p,
        )
        .unwrap();
        assert_eq!(s1, s2);
        assert_eq!(fused, general);
    }
}

#[test]
fn a_zero_start_residual_takes_no_iteration() {
    let m = spd(5);
    let x_true = vec![1.0, -2.0, 0.5, 3.0, 0.0];
    let b: Vec<f64> = (&m * DVector::from_column_slice(&x_true))
        .iter()
        .copied()
        .collect();
    let mut x = x_true.clone();
    let diag: Vec<f64> = (0..5).map(|i| m[(i, i)]).collect();
    let stats = pcg(
        &operator(&m),
        Preconditioner::Jacobi(&diag),
        &b,
        &mut x,
        ResidualNorm::Euclidean,
        &params(Reference::Start, Reduction::Serial),
    );
    // The start is exact only up to rounding of `A x`; either no iteration or converged.
    let stats = stats.unwrap();
    assert_eq!(stats.stop, PcgStop::Converged);
    assert!(x.iter().zip(&x_true).all(|(a, b)| (a - b).abs() < 1e-12));
    let zero = vec![0.0; 5];
    let mut x0 = vec![0.0; 5];
    let stats = pcg(
        &operator(&m),
        Preconditioner::Jacobi(&diag),
        &zero,
        &mut x0,
        ResidualNorm::Euclidean,
        &params(Reference::Start, Reduction::Chunked(2)),
    )
    .unwrap();
    assert_eq!((stats.iterations, stats.relative_residual), (0, 0.0));
}

#[test]
fn an_indefinite_operator_stops_without_panicking() {
    let n = 6;
    let a = |x: &[f64], y: &mut [f64]| {
        for (yi, xi) in y.iter_mut().zip(x) {
            *yi = -xi;
        }
    };
    let b = vec![1.0; n];
    let mut identity = |r: &[f64], z: &mut [f64]| z.copy_from_slice(r);
    let mut x = vec![0.0; n];
    let stats = pcg(
        &a,
        Preconditioner::Apply(&mut identity),
        &b,
        &mut x,
        ResidualNorm::Euclidean,
        &params(Reference::RightHandSide, Reduction::Serial),
    )
    .unwrap();
    assert_eq!(stats.stop, PcgStop::Breakdown);
    assert_eq!(stats.iterations, 0);
    assert_eq!(x, vec![0.0; n]);
}

#[test]
fn bad_input_is_an_error() {
    let n = 4;
    let m = spd(n);
    let a = operator(&m);
    let diag = vec![2.0; n];
    let b = vec![1.0; n];
    let ok = params(Reference::RightHandSide, Reduction::Serial);
    let run = |b: &[f64], x: &mut [f64], d: &[f64], norm: ResidualNorm<'_>, p: &PcgParams| {
        pcg(&a, Preconditioner::Jacobi(d), b, x, norm, p)
    };
    let e = ResidualNorm::Euclidean;
    // Wrong sizes.
    assert!(matches!(
        run(&b, &mut [0.0; 3], &diag, e, &ok),
        Err(Error::SizeMismatch { .. })
    ));
    assert!(matches!(
        run(&b, &mut [0.0; 4], &diag[..3], e, &ok),
        Err(Error::SizeMismatch { .. })
    ));
    assert!(matches!(
        run(
            &b,
            &mut [0.0; 4],
            &diag,
            ResidualNorm::DividedBy(&[1.0; 5]),
            &ok
        ),
        Err(Error::SizeMismatch { .. })
    ));
    // NaN and infinity.
    assert!(matches!(
        run(&[1.0, f64::NAN, 1.0, 1.0], &mut [0.0; 4], &diag, e, &ok),
        Err(Error::NonFinite { .. })
    ));
    assert!(matches!(
        run(&b, &mut [0.0, 0.0, f64::INFINITY, 0.0], &diag, e, &ok),
        Err(Error::NonFinite { .. })
    ));
    assert!(matches!(
        run(
            &b,
            &mut [0.0; 4],
            &diag,
            ResidualNorm::DividedBy(&[1.0, 1.0, f64::NAN, 1.0]),
            &ok
        ),
        Err(Error::NonFinite { .. })
    ));
    let nan_tolerance = PcgParams {
        tolerance: f64::NAN,
        ..ok
    };
    assert!(matches!(
        run(&b, &mut [0.0; 4], &diag, e, &nan_tolerance),
        Err(Error::InvalidParam { .. })
    ));
    // Bad diagonal, scales and chunk size.
    assert!(matches!(
        run(&b, &mut [0.0; 4], &[2.0, 0.0, 2.0, 2.0], e, &ok),
        Err(Error::InvalidParam { .. })
    ));
    assert!(matches!(
        run(
            &b,
            &mut [0.0; 4],
            &diag,
            ResidualNorm::DividedBy(&[1.0, 0.0, 1.0, 1.0]),
            &ok
        ),
        Err(Error::InvalidParam { .. })
    ));
    let zero_chunks = params(Reference::RightHandSide, Reduction::Chunked(0));
    assert!(matches!(
        run(&b, &mut [0.0; 4], &diag, e, &zero_chunks),
        Err(Error::InvalidParam { .. })
    ));
    // An operator that returns NaN stops as a breakdown, never panics.
    let nan_op = |_: &[f64], y: &mut [f64]| y.fill(f64::NAN);
    let mut x = vec![0.0; n];
    let stats = pcg(
        &nan_op,
        Preconditioner::Jacobi(&diag),
        &b,
        &mut x,
        e,
        &PcgParams {
            reference: Reference::Start,
            ..ok
        },
    )
    .unwrap();
    assert_eq!(stats.iterations, 0);
}
