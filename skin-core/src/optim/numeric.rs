//! Central-difference Jacobians for residual functions without an analytic derivative.

use nalgebra::{DMatrix, DVector};

use crate::error::{Error, Result};

/// Relative step of the central difference, ε^(1/3) for f64 (truncation error ∝ h², rounding
/// error ∝ ε/h; the sum is smallest at h ≈ ε^(1/3) ≈ 6·10⁻⁶, Nocedal & Wright §8.1).
const CENTRAL_DIFFERENCE_STEP: f64 = 6.055_454_452_393_343e-6;

/// Jacobian `J[i][j] = ∂rᵢ/∂xⱼ` of `residual` at `x` by central differences, with step
/// `hⱼ = 6·10⁻⁶ · max(|xⱼ|, 1)`. Costs `2n` residual evaluations.
///
/// # Errors
/// Propagates errors of `residual`; [`Error::SizeMismatch`] if `residual` changes length between
/// calls; [`Error::NonFinite`] if `x` or a residual is not finite.
///
/// # Example
/// ```
/// use nalgebra::{dvector, DVector};
/// use skin_core::optim::numeric_jacobian;
/// let mut f = |x: &DVector<f64>| Ok(dvector![x[0] * x[1], x[0].sin()]);
/// let j = numeric_jacobian(&mut f, &dvector![2.0, 3.0])?;
/// assert!((j[(0, 1)] - 2.0).abs() < 1e-8);
/// # Ok::<(), skin_core::Error>(())
/// ```
pub fn numeric_jacobian<F>(residual: &mut F, x: &DVector<f64>) -> Result<DMatrix<f64>>
where
    F: FnMut(&DVector<f64>) -> Result<DVector<f64>>,
{
    crate::check::all_finite("numeric_jacobian point", x.iter())?;
    let mut m: Option<usize> = None;
    let mut columns = Vec::with_capacity(x.len());
    let mut xp = x.clone();
    for j in 0..x.len() {
        let h = CENTRAL_DIFFERENCE_STEP * x[j].abs().max(1.0);
        xp[j] = x[j] + h;
        let rp = residual(&xp)?;
        xp[j] = x[j] - h;
        let rm = residual(&xp)?;
        xp[j] = x[j];
        for r in [&rp, &rm] {
            let expected = *m.get_or_insert(r.len());
            if r.len() != expected {
                return Err(Error::SizeMismatch {
                    what: "residual length between evaluations",
                    expected,
                    got: r.len(),
                });
            }
        }
        // Actual step taken (x ± h is rounded), keeps the quotient consistent.
        let step = (x[j] + h) - (x[j] - h);
        columns.push((rp - rm) / step);
    }
    let m = match m {
        Some(m) => m,
        None => residual(x)?.len(),
    };
    let jac = DMatrix::from_fn(m, x.len(), |i, j| columns[j][i]);
    crate::check::all_finite("numeric Jacobian", jac.iter())?;
    Ok(jac)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::dvector;

    #[test]
    fn matches_analytic_jacobian() {
        let mut f =
            |x: &DVector<f64>| Ok(dvector![x[0] * x[0] * x[1], x[1].exp(), x[0] - 3.0 * x[1]]);
        let x = dvector![1.3, -0.4];
        let j = numeric_jacobian(&mut f, &x).unwrap();
        let exact = DMatrix::from_row_slice(
            3,
            2,
            &[2.0 * x[0] * x[1], x[0] * x[0], 0.0, x[1].exp(), 1.0, -3.0],
        );
        assert!((j - exact).amax() < 1e-8);
    }

    #[test]
    fn rejects_changing_length_and_nan() {
        let mut calls = 0;
        let mut f = |_: &DVector<f64>| {
            calls += 1;
            Ok(DVector::zeros(calls))
        };
        assert!(matches!(
            numeric_jacobian(&mut f, &dvector![1.0]),
            Err(Error::SizeMismatch { .. })
        ));
        let mut g = |x: &DVector<f64>| Ok(x.clone());
        assert!(matches!(
            numeric_jacobian(&mut g, &dvector![f64::NAN]),
            Err(Error::NonFinite { .. })
        ));
    }
}
