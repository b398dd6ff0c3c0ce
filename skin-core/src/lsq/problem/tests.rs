use super::*;
use nalgebra_sparse::CooMatrix;
use proptest::prelude::*;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::lsq::test_util::random_sparse;

fn random_dense(rng: &mut ChaCha8Rng, m: usize, k: usize) -> DMatrix<f64> {
    DMatrix::from_fn(m, k, |_, _| rng.random_range(-1.0..1.0))
}

/// Dense reference: solve the stacked weighted system by QR-free normal equations in
/// dense arithmetic (LU of a small matrix).
fn dense_reference(
    a: &CscMatrix<f64>,
    cs: &[(CscMatrix<f64>, f64)],
    b: &DMatrix<f64>,
    d: &[DMatrix<f64>],
) -> DMatrix<f64> {
    let da = DMatrix::from(a);
    let mut n = da.transpose() * &da;
    let mut r = da.transpose() * b;
    for ((c, w), dk) in cs.iter().zip(d) {
        let dc = DMatrix::from(c);
        n += dc.transpose() * &dc * *w;
        r += dc.transpose() * dk * *w;
    }
    n.lu().solve(&r).unwrap()
}

fn case(seed: u64) -> (CscMatrix<f64>, Vec<(CscMatrix<f64>, f64)>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = 15;
    // A = identity-ish plus noise guarantees full column rank.
    let mut a = random_sparse(&mut rng, 25, n, 0.15);
    let eye = CscMatrix::identity(n);
    let stacked = {
        let mut coo = CooMatrix::new(25 + n, n);
        for (i, j, v) in a.triplet_iter() {
            coo.push(i, j, *v);
        }
        for (i, j, v) in eye.triplet_iter() {
            coo.push(25 + i, j, *v);
        }
        CscMatrix::from(&coo)
    };
    a = stacked;
    let c1 = random_sparse(&mut rng, 4, n, 0.3);
    let c2 = random_sparse(&mut rng, 6, n, 0.2);
    (a, vec![(c1, 10.0), (c2, 0.5)])
}

#[test]
fn matches_dense_reference_and_reuses_analysis() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let (a, cs) = case(1);
    let b = random_dense(&mut rng, a.nrows(), 3);
    let d: Vec<_> = cs
        .iter()
        .map(|(c, _)| random_dense(&mut rng, c.nrows(), 3))
        .collect();
    let mut problem = LsqProblem::new(a.clone());
    for (c, w) in &cs {
        problem = problem.with_term(c.clone(), *w);
    }
    let mut solver = problem.factor(&LsqParams::default()).unwrap();
    let x = solver.solve(&b, &d).unwrap();
    let reference = dense_reference(&a, &cs, &b, &d);
    assert!((&x - &reference).norm() < 1e-10 * reference.norm());
    let diag = solver.diagnostics(&x, &b, &d).unwrap();
    assert!(diag.normal_rel_residual < 1e-12);
    // The minimiser has a smaller objective than a perturbed point.
    let perturbed = &x + DMatrix::from_element(x.nrows(), 3, 1e-3);
    let diag_p = solver.diagnostics(&perturbed, &b, &d).unwrap();
    assert!(diag_p.objective > diag.objective);

    // New weights: same analysis, new numeric factor.
    solver.set_weights(&[100.0, 0.0]).unwrap();
    let cs2 = vec![(cs[0].0.clone(), 100.0), (cs[1].0.clone(), 0.0)];
    let x2 = solver.solve(&b, &d).unwrap();
    let reference2 = dense_reference(&a, &cs2, &b, &d);
    assert!((&x2 - &reference2).norm() < 1e-9 * reference2.norm());

    // New values, same pattern.
    let mut a3 = a.clone();
    a3.values_mut().iter_mut().for_each(|v| *v *= 1.5);
    let mut c3 = cs[0].0.clone();
    c3.values_mut().iter_mut().for_each(|v| *v = -*v + 0.25);
    solver.set_values(&a3, &[&c3, &cs[1].0]).unwrap();
    let x3 = solver.solve(&b, &d).unwrap();
    let cs3 = vec![(c3, 100.0), (cs[1].0.clone(), 0.0)];
    let reference3 = dense_reference(&a3, &cs3, &b, &d);
    assert!((&x3 - &reference3).norm() < 1e-9 * reference3.norm());
}

#[test]
fn solvers_can_move_between_threads() {
    fn send_sync<T: Send + Sync>() {}
    send_sync::<LsqSolver>();
    send_sync::<SparseCholesky>();
}

#[test]
fn rejects_mismatched_sizes() {
    let (a, cs) = case(2);
    let n = a.ncols();
    // C with the wrong column count.
    let bad_c = CscMatrix::identity(n + 1);
    assert!(matches!(
        LsqProblem::new(a.clone())
            .with_term(bad_c, 1.0)
            .factor(&LsqParams::default()),
        Err(Error::SizeMismatch { .. })
    ));
    let solver = LsqProblem::new(a.clone())
        .with_term(cs[0].0.clone(), 2.0)
        .factor(&LsqParams::default())
        .unwrap();
    let b = DMatrix::zeros(a.nrows(), 2);
    let d_ok = DMatrix::zeros(cs[0].0.nrows(), 2);
    assert!(solver.solve(&b, std::slice::from_ref(&d_ok)).is_ok());
    // B with wrong rows.
    assert!(matches!(
        solver.solve(
            &DMatrix::zeros(a.nrows() + 1, 2),
            std::slice::from_ref(&d_ok)
        ),
        Err(Error::SizeMismatch { .. })
    ));
    // D with a different column count than B.
    assert!(matches!(
        solver.solve(&b, &[DMatrix::zeros(cs[0].0.nrows(), 3)]),
        Err(Error::SizeMismatch { .. })
    ));
    // Wrong number of D_k.
    assert!(matches!(
        solver.solve(&b, &[]),
        Err(Error::SizeMismatch { .. })
    ));
    // Wrong number of weights.
    let mut solver = solver;
    assert!(matches!(
        solver.set_weights(&[1.0, 2.0]),
        Err(Error::SizeMismatch { .. })
    ));
    // Changed pattern.
    assert!(matches!(
        solver.set_values(&CscMatrix::identity(n), &[&cs[0].0]),
        Err(Error::SizeMismatch { .. })
    ));
}

#[test]
fn rejects_nan_negative_weight_and_rank_deficiency() {
    let (a, cs) = case(3);
    let mut bad = a.clone();
    bad.values_mut()[0] = f64::NAN;
    assert!(matches!(
        LsqProblem::new(bad).factor(&LsqParams::default()),
        Err(Error::NonFinite { .. })
    ));
    assert!(matches!(
        LsqProblem::new(a.clone())
            .with_term(cs[0].0.clone(), -1.0)
            .factor(&LsqParams::default()),
        Err(Error::InvalidParam { .. })
    ));
    assert!(matches!(
        LsqProblem::new(a.clone())
            .with_term(cs[0].0.clone(), f64::NAN)
            .factor(&LsqParams::default()),
        Err(Error::NonFinite { .. })
    ));
    // A path-graph difference operator has the constant vector in its null space:
    // without constraints the normal matrix is singular.
    let n = 6;
    let mut coo = CooMatrix::new(n - 1, n);
    for r in 0..n - 1 {
        coo.push(r, r, -1.0);
        coo.push(r, r + 1, 1.0);
    }
    let diff = CscMatrix::from(&coo);
    assert!(matches!(
        LsqProblem::new(diff.clone()).factor(&LsqParams::default()),
        Err(Error::Singular { .. })
    ));
    // One pinned vertex makes it definite.
    let mut pin = CooMatrix::new(1, n);
    pin.push(0, 2, 1.0);
    let solver = LsqProblem::new(diff)
        .with_term(CscMatrix::from(&pin), 1.0)
        .factor(&LsqParams::default())
        .unwrap();
    let x = solver
        .solve(
            &DMatrix::from_element(n - 1, 1, 1.0),
            &[DMatrix::from_element(1, 1, 3.0)],
        )
        .unwrap();
    // x_{i+1} - x_i = 1 and x_2 = 3 -> x_i = i + 1.
    for i in 0..n {
        assert!((x[i] - (i as f64 + 1.0)).abs() < 1e-9);
    }
    // Empty problem.
    assert!(matches!(
        LsqProblem::new(CscMatrix::from(&CooMatrix::<f64>::new(3, 0)))
            .factor(&LsqParams::default()),
        Err(Error::Empty { .. })
    ));
    // NaN right-hand side.
    assert!(matches!(
        solver.solve(
            &DMatrix::from_element(n - 1, 1, f64::NAN),
            &[DMatrix::zeros(1, 1)]
        ),
        Err(Error::NonFinite { .. })
    ));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    /// The normal residual of the returned solution is at rounding level for any seed
    /// and any positive weights.
    #[test]
    fn normal_equations_hold(seed in 0u64..1000, w1 in 0.01f64..1e3, w2 in 0.0f64..10.0) {
        let (a, cs) = case(seed);
        let mut rng = ChaCha8Rng::seed_from_u64(seed + 1);
        let solver = LsqProblem::new(a.clone())
            .with_term(cs[0].0.clone(), w1)
            .with_term(cs[1].0.clone(), w2)
            .factor(&LsqParams::default())
            .unwrap();
        let b = random_dense(&mut rng, a.nrows(), 2);
        let d: Vec<_> = cs.iter().map(|(c, _)| random_dense(&mut rng, c.nrows(), 2)).collect();
        let x = solver.solve(&b, &d).unwrap();
        let diag = solver.diagnostics(&x, &b, &d).unwrap();
        prop_assert!(diag.normal_rel_residual < 1e-10);
    }
}
