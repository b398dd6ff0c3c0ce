//! The inverse of a symmetric positive definite matrix by recursive 2 × 2 blocks (Schur
//! complements), so that nearly all of its `4n³/3` flops are matrix products: the joint solve
//! of the imputation (§5.3.4) needs the whole inverse `H⁻¹` (the posterior covariance of the
//! missing faces) every iteration.

use nalgebra::DMatrix;

/// Below this size the inverse comes from nalgebra's Cholesky factor.
const BASE: usize = 96;

/// `H⁻¹` for a symmetric positive definite `H`; `None` if `H` is not positive definite.
/// With `H = [A Bᵀ; B C]` and `S = C − B A⁻¹ Bᵀ`:
/// `H⁻¹ = [A⁻¹ + A⁻¹Bᵀ S⁻¹ B A⁻¹, −A⁻¹Bᵀ S⁻¹; −S⁻¹ B A⁻¹, S⁻¹]`.
pub(super) fn spd_inverse(h: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    let n = h.nrows();
    if n <= BASE {
        return h.clone().cholesky().map(|c| c.inverse());
    }
    let k = n / 2;
    let a = h.view((0, 0), (k, k)).into_owned();
    let b = h.view((k, 0), (n - k, k));
    let a_inv = spd_inverse(&a)?;
    let ba: DMatrix<f64> = b * &a_inv;
    let s = h.view((k, k), (n - k, n - k)) - &ba * b.transpose();
    let s_inv = spd_inverse(&((&s + s.transpose()) * 0.5))?;
    let lower: DMatrix<f64> = -(&s_inv * &ba);
    let top = a_inv - ba.transpose() * &lower;
    let mut out = DMatrix::zeros(n, n);
    out.view_mut((0, 0), (k, k)).copy_from(&top);
    out.view_mut((k, 0), (n - k, k)).copy_from(&lower);
    out.view_mut((0, k), (k, n - k))
        .copy_from(&lower.transpose());
    out.view_mut((k, k), (n - k, n - k)).copy_from(&s_inv);
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_block_inverse_inverts_and_rejects_indefinite_matrices() {
        let n = 250;
        let a = DMatrix::from_fn(n, n, |i, j| ((i * 7 + j * 13) % 17) as f64 / 17.0 - 0.4);
        let h = &a * a.transpose() + DMatrix::identity(n, n);
        let inv = spd_inverse(&h).unwrap();
        assert!((&h * &inv - DMatrix::identity(n, n)).norm() < 1e-9);
        let mut bad = h.clone();
        bad[(200, 200)] = -1.0;
        assert!(spd_inverse(&bad).is_none());
    }
}
