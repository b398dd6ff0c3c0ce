use super::*;
use crate::optim::test_problems::*;
use nalgebra::dvector;
use proptest::prelude::*;

#[test]
fn rosenbrock_analytic_and_numeric() {
    let p = LmParams::default();
    let a = levenberg_marquardt(
        &dvector![-1.2, 1.0],
        &p,
        rosenbrock_residual,
        rosenbrock_jacobian,
    )
    .unwrap();
    assert!(
        (a.x.clone() - dvector![1.0, 1.0]).amax() < 1e-9,
        "{:?}",
        a.x
    );
    assert!(a.termination.converged());
    let b = levenberg_marquardt_numeric(&dvector![-1.2, 1.0], &p, rosenbrock_residual).unwrap();
    assert!((b.x - dvector![1.0, 1.0]).amax() < 1e-8);
}

#[test]
fn bounded_rosenbrock_stops_on_the_bound_and_free_minimum_is_unchanged() {
    // Rosenbrock's minimum (1, 1) is outside x₀ ≤ 0.5: the constrained minimum lies on
    // x₀ = 0.5 with x₁ = x₀² = 0.25 (the second residual then cannot vanish).
    let p = LmParams::default();
    let (lo, hi) = (dvector![-2.0, -2.0], dvector![0.5, 2.0]);
    let a = levenberg_marquardt_bounded(
        &dvector![-1.2, 1.0],
        &lo,
        &hi,
        &p,
        rosenbrock_residual,
        rosenbrock_jacobian,
    )
    .unwrap();
    assert!((a.x[0] - 0.5).abs() < 1e-12, "{:?}", a.x);
    assert!((a.x[1] - 0.25).abs() < 1e-8, "{:?}", a.x);
    assert!(a.termination.converged(), "{:?}", a.termination);
    // Wide bounds: the same path as the unbounded method.
    let inf = f64::INFINITY;
    let b = levenberg_marquardt_bounded(
        &dvector![-1.2, 1.0],
        &dvector![-inf, -inf],
        &dvector![inf, inf],
        &p,
        rosenbrock_residual,
        rosenbrock_jacobian,
    )
    .unwrap();
    let c = levenberg_marquardt(
        &dvector![-1.2, 1.0],
        &p,
        rosenbrock_residual,
        rosenbrock_jacobian,
    )
    .unwrap();
    assert_eq!(b.x, c.x);
    assert_eq!(b.iterations, c.iterations);
    // x0 outside the box is clamped; bad bounds are errors.
    let d = levenberg_marquardt_bounded(
        &dvector![3.0, 1.0],
        &lo,
        &hi,
        &p,
        rosenbrock_residual,
        rosenbrock_jacobian,
    )
    .unwrap();
    assert!(d.x[0] <= 0.5);
    let bad = levenberg_marquardt_bounded(
        &dvector![0.0, 0.0],
        &dvector![1.0, 0.0],
        &dvector![0.0, 1.0],
        &p,
        rosenbrock_residual,
        rosenbrock_jacobian,
    );
    assert!(matches!(bad, Err(Error::InvalidParam { .. })));
    let bad = levenberg_marquardt_bounded(
        &dvector![0.0, 0.0],
        &dvector![0.0],
        &hi,
        &p,
        rosenbrock_residual,
        rosenbrock_jacobian,
    );
    assert!(matches!(bad, Err(Error::SizeMismatch { .. })));
}

#[test]
fn powell_singular_and_badly_scaled() {
    // Powell's singular function: minimum 0 at the origin with a singular Jacobian there.
    let r = |x: &DVector<f64>| {
        Ok(dvector![
            x[0] + 10.0 * x[1],
            5f64.sqrt() * (x[2] - x[3]),
            (x[1] - 2.0 * x[2]).powi(2),
            10f64.sqrt() * (x[0] - x[3]).powi(2)
        ])
    };
    let rep = levenberg_marquardt_numeric(&dvector![3.0, -1.0, 0.0, 1.0], &LmParams::default(), r)
        .unwrap();
    assert!(rep.cost < 1e-12, "cost {}", rep.cost);
    // Scaling invariance: a parameter in units 1e6 times smaller converges just as well.
    let s = 1e6;
    let r2 = |x: &DVector<f64>| rosenbrock_residual(&dvector![x[0] / s, x[1]]);
    let rep2 =
        levenberg_marquardt_numeric(&dvector![-1.2 * s, 1.0], &LmParams::default(), r2).unwrap();
    assert!((rep2.x[0] / s - 1.0).abs() < 1e-6 && (rep2.x[1] - 1.0).abs() < 1e-6);
}

#[test]
fn linear_least_squares_in_one_step_family() {
    // Over-determined linear fit: LM must reach the normal-equation solution.
    let a = DMatrix::from_fn(20, 3, |i, j| ((i * 7 + j * 3) % 11) as f64 - 5.0);
    let b = DVector::from_fn(20, |i, _| (i as f64 * 0.37).sin());
    let exact = a.clone().svd(true, true).solve(&b, 1e-14).unwrap();
    let rep = levenberg_marquardt(
        &DVector::zeros(3),
        &LmParams::default(),
        |x| Ok(&a * x - &b),
        |_| Ok(a.clone()),
    )
    .unwrap();
    assert!((rep.x - exact).amax() < 1e-9);
}

#[test]
fn bad_inputs_are_errors() {
    let p = LmParams::default();
    assert!(matches!(
        levenberg_marquardt_numeric(&DVector::zeros(0), &p, |x| Ok(x.clone())),
        Err(Error::Empty { .. })
    ));
    assert!(matches!(
        levenberg_marquardt_numeric(&dvector![f64::NAN], &p, |x| Ok(x.clone())),
        Err(Error::NonFinite { .. })
    ));
    assert!(matches!(
        levenberg_marquardt_numeric(&dvector![1.0], &p, |_| Ok(dvector![f64::INFINITY])),
        Err(Error::NonFinite { .. })
    ));
    assert!(matches!(
        levenberg_marquardt(
            &dvector![1.0],
            &p,
            |x| Ok(x.clone()),
            |_| Ok(DMatrix::zeros(2, 1))
        ),
        Err(Error::SizeMismatch { .. })
    ));
    let bad = LmParams {
        initial_lambda: -1.0,
        ..p
    };
    assert!(matches!(
        levenberg_marquardt_numeric(&dvector![1.0], &bad, |x| Ok(x.clone())),
        Err(Error::InvalidParam { .. })
    ));
    // Failing trial points are rejected, not fatal: the residual refuses x < 0.5.
    let rep = levenberg_marquardt(
        &dvector![2.0],
        &p,
        |x| {
            if x[0] < 0.5 {
                Err(Error::NotVisible {
                    what: "test".into(),
                })
            } else {
                Ok(dvector![x[0] - 0.4])
            }
        },
        |_| Ok(DMatrix::from_element(1, 1, 1.0)),
    )
    .unwrap();
    assert!(rep.x[0] >= 0.5 && rep.x[0] < 0.51);
}

#[test]
fn iteration_limit_is_reported() {
    let p = LmParams::default().with_max_iterations(2);
    let rep = levenberg_marquardt(
        &dvector![-1.2, 1.0],
        &p,
        rosenbrock_residual,
        rosenbrock_jacobian,
    )
    .unwrap();
    assert_eq!(rep.termination, LmTermination::MaxIterations);
    assert!(rep.cost <= rep.initial_cost);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]
    #[test]
    fn rosenbrock_from_random_starts(x0 in -3.0f64..3.0, y0 in -3.0f64..3.0) {
        let rep = levenberg_marquardt(&dvector![x0, y0], &LmParams::default(), rosenbrock_residual, rosenbrock_jacobian).unwrap();
        prop_assert!((rep.x - dvector![1.0, 1.0]).amax() < 1e-7);
    }
}
