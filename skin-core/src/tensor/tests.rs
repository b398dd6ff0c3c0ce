//! Tests of the tensor algebra: layout and unfolding conventions, mode products, HOSVD
//! exactness at the multilinear rank, HOOI monotonicity, and every error path.

use nalgebra::DMatrix;
use proptest::prelude::*;

use super::*;
use crate::random::SplitMix64;
use crate::Error;

fn normal_tensor(shape: Vec<usize>, seed: u64) -> Tensor {
    let rng = SplitMix64::new(seed);
    let n = shape.iter().product();
    Tensor::new(shape, rng.normal(n)).unwrap()
}

fn normal_matrix(rows: usize, cols: usize, seed: u64) -> DMatrix<f64> {
    let rng = SplitMix64::new(seed);
    DMatrix::from_fn(rows, cols, |i, j| rng.normal_at((i * cols + j) as u64))
}

/// A tensor of shape `shape` with multilinear rank at most `ranks` (exactly, for generic
/// seeds): a Gaussian core times Gaussian factors.
fn low_rank(shape: &[usize], ranks: &[usize], seed: u64) -> Tensor {
    let core = normal_tensor(ranks.to_vec(), seed);
    let factors: Vec<DMatrix<f64>> = shape
        .iter()
        .zip(ranks)
        .enumerate()
        .map(|(n, (&d, &r))| normal_matrix(d, r, seed + 1 + n as u64))
        .collect();
    let products: Vec<(usize, &DMatrix<f64>)> = factors.iter().enumerate().collect();
    core.multi_mode_product(&products).unwrap()
}

fn max_abs_diff(a: &Tensor, b: &Tensor) -> f64 {
    assert_eq!(a.shape(), b.shape());
    a.data()
        .iter()
        .zip(b.data())
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

fn orthonormality_error(u: &DMatrix<f64>) -> f64 {
    (u.transpose() * u - DMatrix::identity(u.ncols(), u.ncols())).amax()
}

/// Shapes of order 2–4 with modes of size 1–5, and a seed.
fn shape_and_seed() -> impl Strategy<Value = (Vec<usize>, u64)> {
    (prop::collection::vec(1usize..=5, 2..=4), 0u64..1000)
}

#[test]
fn layout_is_row_major_and_unfolding_orders_columns_last_index_fastest() {
    // t[i][j][k] = 100 i + 10 j + k, shape (2, 3, 2).
    let x = Tensor::from_fn(vec![2, 3, 2], |i| (100 * i[0] + 10 * i[1] + i[2]) as f64).unwrap();
    assert_eq!(&x.data()[..4], &[0.0, 1.0, 10.0, 11.0]);
    assert_eq!(x.get(&[1, 2, 1]).unwrap(), 121.0);
    // Mode 1: rows j, columns (i, k) with k fastest.
    let u1 = x.unfold(1).unwrap();
    assert_eq!(u1.shape(), (3, 4));
    let row0: Vec<f64> = u1.row(0).iter().copied().collect();
    assert_eq!(row0, vec![0.0, 1.0, 100.0, 101.0]);
    // Mode 0: columns (j, k) with k fastest; mode 2: columns (i, j) with j fastest.
    let row1: Vec<f64> = x.unfold(0).unwrap().row(1).iter().copied().collect();
    assert_eq!(row1, vec![100.0, 101.0, 110.0, 111.0, 120.0, 121.0]);
    let row2: Vec<f64> = x.unfold(2).unwrap().row(1).iter().copied().collect();
    assert_eq!(row2, vec![1.0, 11.0, 21.0, 101.0, 111.0, 121.0]);
    assert!((x.norm() - x.data().iter().map(|v| v * v).sum::<f64>().sqrt()).abs() < 1e-12);
}

#[test]
fn mode_product_replaces_each_mode_vector_by_its_image() {
    // Hand example: 𝒯 ×₂ M on a 2 × 2 × 1 tensor (mode 1 here, counted from 0).
    let x = Tensor::new(vec![2, 2, 1], vec![1.0, 2.0, 3.0, 4.0]).unwrap();
    let m = DMatrix::from_row_slice(3, 2, &[1.0, 0.0, 0.0, 1.0, 1.0, 1.0]);
    let y = x.mode_product(1, &m).unwrap();
    assert_eq!(y.shape(), &[2, 3, 1]);
    assert_eq!(y.data(), &[1.0, 2.0, 3.0, 3.0, 4.0, 7.0]);
}

#[test]
fn gemm_paths_match_the_unfolding_definition() {
    // Slabs large enough for faer's GEMM in both the product and the Gram matrix.
    let x = normal_tensor(vec![3, 40, 60], 5);
    let m = normal_matrix(30, 40, 6);
    let y = x.mode_product(1, &m).unwrap();
    let expected = &m * x.unfold(1).unwrap();
    assert!((y.unfold(1).unwrap() - &expected).amax() < 1e-10);
    let u = x.unfold(1).unwrap();
    assert!((x.gram(1).unwrap() - &u * u.transpose()).amax() < 1e-9);
    // Mode 0 (L = 1): one big slab.
    let m0 = normal_matrix(2, 3, 7);
    let y0 = x.mode_product(0, &m0).unwrap();
    assert!((y0.unfold(0).unwrap() - &m0 * x.unfold(0).unwrap()).amax() < 1e-10);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    #[test]
    fn fold_inverts_unfold((shape, seed) in shape_and_seed()) {
        let x = normal_tensor(shape.clone(), seed);
        for n in 0..shape.len() {
            let back = Tensor::fold(&x.unfold(n).unwrap(), n, shape.clone()).unwrap();
            prop_assert_eq!(&back, &x);
        }
    }

    #[test]
    fn mode_product_unfolds_to_matrix_product_and_gram_matches((shape, seed) in shape_and_seed(), rows in 1usize..4) {
        let x = normal_tensor(shape.clone(), seed);
        for (n, &d) in shape.iter().enumerate() {
            let m = normal_matrix(rows, d, seed + 100);
            let y = x.mode_product(n, &m).unwrap();
            let u = x.unfold(n).unwrap();
            prop_assert!((y.unfold(n).unwrap() - &m * &u).amax() < 1e-12);
            prop_assert!((x.gram(n).unwrap() - &u * u.transpose()).amax() < 1e-12);
        }
    }

    #[test]
    fn mode_products_along_different_modes_commute((shape, seed) in shape_and_seed(), ra in 1usize..4, rb in 1usize..4) {
        let x = normal_tensor(shape.clone(), seed);
        let (a_mode, b_mode) = (0, shape.len() - 1);
        let a = normal_matrix(ra, shape[a_mode], seed + 1);
        let b = normal_matrix(rb, shape[b_mode], seed + 2);
        let ab = x.mode_product(a_mode, &a).unwrap().mode_product(b_mode, &b).unwrap();
        let ba = x.mode_product(b_mode, &b).unwrap().mode_product(a_mode, &a).unwrap();
        prop_assert!(max_abs_diff(&ab, &ba) < 1e-12);
        // Same mode twice composes: 𝒯 ×ₙ A ×ₙ B = 𝒯 ×ₙ (BA).
        let c = normal_matrix(2, ra, seed + 3);
        let twice = x.mode_product(a_mode, &a).unwrap().mode_product(a_mode, &c).unwrap();
        let once = x.mode_product(a_mode, &(&c * &a)).unwrap();
        prop_assert!(max_abs_diff(&twice, &once) < 1e-12);
    }

    #[test]
    fn hosvd_at_the_multilinear_rank_reconstructs((shape, seed) in shape_and_seed()) {
        // Ranks ≤ the mode sizes and below the product of the other modes' ranks.
        let ranks: Vec<usize> = shape.iter().map(|&d| d.div_ceil(2)).collect();
        let x = low_rank(&shape, &ranks, seed);
        let opt: Vec<Option<usize>> = ranks.iter().map(|&r| Some(r)).collect();
        for method in [FactorMethod::Gram, FactorMethod::Svd, FactorMethod::Randomized(RandomizedParams::default())] {
            let t = hosvd(&x, &opt, method).unwrap();
            prop_assert_eq!(t.ranks(), &ranks[..]);
            for u in t.factors.iter().flatten() {
                prop_assert!(orthonormality_error(u) < 1e-10);
            }
            let err = t.reconstruct().unwrap().relative_error(&x).unwrap();
            prop_assert!(err < 1e-10, "{:?}: relative error {}", method, err);
        }
    }

    #[test]
    fn hooi_never_increases_the_error_of_its_hosvd_start((shape, seed) in shape_and_seed()) {
        let x = normal_tensor(shape.clone(), seed);
        let ranks: Vec<Option<usize>> = shape.iter().map(|&d| Some(d.div_ceil(2))).collect();
        let start = hosvd(&x, &ranks, FactorMethod::Auto).unwrap();
        let start_err = start.reconstruct().unwrap().relative_error(&x).unwrap();
        let params = HooiParams { max_iterations: 5, tolerance: 0.0, ..HooiParams::default() };
        let r = hooi(&x, &ranks, &params).unwrap();
        let err = r.tucker.reconstruct().unwrap().relative_error(&x).unwrap();
        prop_assert!(err <= start_err + 1e-10, "HOOI {} > HOSVD {}", err, start_err);
        prop_assert!((r.hosvd_error - start_err).abs() < 1e-6);
        for w in r.errors.windows(2) {
            prop_assert!(w[1] <= w[0] + 1e-10);
        }
        prop_assert!((r.errors.last().copied().unwrap_or(r.hosvd_error) - err).abs() < 1e-6);
    }
}

#[test]
fn hooi_improves_on_hosvd_of_a_noisy_tensor_and_stops_at_the_tolerance() {
    let clean = low_rank(&[12, 8, 9], &[3, 3, 3], 21);
    let noise = normal_tensor(vec![12, 8, 9], 22);
    let data: Vec<f64> = clean
        .data()
        .iter()
        .zip(noise.data())
        .map(|(c, e)| c + 0.5 * e)
        .collect();
    let x = Tensor::new(vec![12, 8, 9], data).unwrap();
    let ranks = [Some(2), Some(2), Some(2)];
    let r = hooi(&x, &ranks, &HooiParams::default()).unwrap();
    assert!(r.converged);
    assert!(r.errors.len() >= 3 && r.errors.len() < 100);
    let last = *r.errors.last().unwrap();
    assert!(last < r.hosvd_error, "{last} vs {}", r.hosvd_error);
    // A full-rank mode (skipped in the sweeps' projections) still gets a consistent core.
    let full = [Some(2), Some(8), Some(2)];
    let r = hooi(&x, &full, &HooiParams::default()).unwrap();
    let err = r.tucker.reconstruct().unwrap().relative_error(&x).unwrap();
    assert!((err - r.errors.last().unwrap()).abs() < 1e-8);
    assert!(err <= r.hosvd_error + 1e-12);
}

#[test]
fn undecomposed_modes_and_tall_unfoldings() {
    // Eq. 5.4: mode 0 kept; Auto takes the thin SVD for the tall mode-2 unfolding (30 > 6).
    let x = low_rank(&[3, 2, 30], &[3, 2, 4], 31);
    let t = hosvd(&x, &[None, Some(2), Some(4)], FactorMethod::Auto).unwrap();
    assert!(t.factors[0].is_none());
    assert_eq!(t.ranks(), &[3, 2, 4]);
    assert!(t.reconstruct().unwrap().relative_error(&x).unwrap() < 1e-10);
    // Nothing decomposed: the core is the tensor.
    let none = hosvd(&x, &[None, None, None], FactorMethod::Auto).unwrap();
    assert_eq!(none.core, x);
    // A rank above the unfolding's column count still gives an orthonormal factor.
    let y = normal_tensor(vec![5, 2], 32);
    let t = hosvd(&y, &[Some(4), None], FactorMethod::Auto).unwrap();
    let u = t.factors[0].as_ref().unwrap();
    assert_eq!(u.shape(), (5, 4));
    assert!(orthonormality_error(u) < 1e-10);
    assert!(t.reconstruct().unwrap().relative_error(&y).unwrap() < 1e-10);
}

#[test]
fn randomized_range_finder_recovers_a_huge_mode_with_small_rank() {
    let x = low_rank(&[600, 6, 5], &[3, 4, 5], 41);
    let p = RandomizedParams {
        oversample: 5,
        power_iterations: 1,
        seed: 3,
    };
    let t = hosvd(&x, &[Some(3), None, None], FactorMethod::Randomized(p)).unwrap();
    assert!(t.reconstruct().unwrap().relative_error(&x).unwrap() < 1e-10);
}

#[test]
fn bad_inputs_give_clear_errors() {
    let x = normal_tensor(vec![3, 4, 2], 1);
    let m = |r| matches!(r, Err(Error::InvalidParam { name: "rank", .. }));
    assert!(m(hosvd(&x, &[Some(4), None, None], FactorMethod::Auto)));
    assert!(m(hosvd(&x, &[Some(0), None, None], FactorMethod::Auto)));
    assert!(m(
        hooi(&x, &[None, Some(5), None], &HooiParams::default()).map(|r| r.tucker)
    ));
    assert!(matches!(
        hosvd(&x, &[Some(1), Some(1)], FactorMethod::Auto),
        Err(Error::SizeMismatch { .. })
    ));
    let bad_tol = HooiParams {
        tolerance: f64::NAN,
        ..HooiParams::default()
    };
    assert!(matches!(
        hooi(&x, &[Some(1), None, None], &bad_tol),
        Err(Error::InvalidParam {
            name: "tolerance",
            ..
        })
    ));
    // Construction.
    assert!(matches!(
        Tensor::new(vec![2, 2], vec![1.0; 3]),
        Err(Error::SizeMismatch { .. })
    ));
    assert!(matches!(
        Tensor::new(vec![2], vec![1.0, f64::NAN]),
        Err(Error::NonFinite { .. })
    ));
    assert!(matches!(
        Tensor::new(vec![], vec![]),
        Err(Error::Empty { .. })
    ));
    assert!(matches!(
        Tensor::zeros(vec![2, 0]),
        Err(Error::Empty { .. })
    ));
    assert!(matches!(
        Tensor::from_fn(vec![2], |_| f64::INFINITY),
        Err(Error::NonFinite { .. })
    ));
    // Products, unfoldings, indices.
    assert!(matches!(
        x.mode_product(1, &DMatrix::zeros(2, 3)),
        Err(Error::InvalidParam { .. })
    ));
    assert!(matches!(
        x.mode_product(1, &DMatrix::from_element(2, 4, f64::NAN)),
        Err(Error::NonFinite { .. })
    ));
    assert!(matches!(
        x.mode_product(3, &DMatrix::zeros(2, 4)),
        Err(Error::IndexOutOfRange { .. })
    ));
    let a = DMatrix::zeros(2, 3);
    assert!(matches!(
        x.multi_mode_product(&[(0, &a), (0, &a)]),
        Err(Error::InvalidParam { .. })
    ));
    assert!(matches!(x.unfold(3), Err(Error::IndexOutOfRange { .. })));
    assert!(matches!(
        Tensor::fold(&DMatrix::zeros(3, 7), 0, vec![3, 4, 2]),
        Err(Error::SizeMismatch { .. })
    ));
    assert!(matches!(
        Tensor::fold(&DMatrix::zeros(4, 6), 0, vec![3, 4, 2]),
        Err(Error::SizeMismatch { .. })
    ));
    assert!(matches!(
        x.get(&[0, 4, 0]),
        Err(Error::IndexOutOfRange { .. })
    ));
    assert!(matches!(
        x.relative_error(&normal_tensor(vec![3, 4, 1], 2)),
        Err(Error::InvalidParam { .. })
    ));
}
