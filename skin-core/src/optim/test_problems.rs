//! Classic test functions shared by the optimiser tests.

use nalgebra::{dvector, DMatrix, DVector};

use crate::error::Result;

/// Rosenbrock's function as residuals `(10(x₁ − x₀²), 1 − x₀)`; minimum 0 at (1, 1).
pub fn rosenbrock_residual(x: &DVector<f64>) -> Result<DVector<f64>> {
    Ok(dvector![10.0 * (x[1] - x[0] * x[0]), 1.0 - x[0]])
}

/// Jacobian of [`rosenbrock_residual`].
pub fn rosenbrock_jacobian(x: &DVector<f64>) -> Result<DMatrix<f64>> {
    Ok(DMatrix::from_row_slice(
        2,
        2,
        &[-20.0 * x[0], 10.0, -1.0, 0.0],
    ))
}

/// Rosenbrock's function `100(x₁ − x₀²)² + (1 − x₀)²`, summed over consecutive pairs in n-D.
pub fn rosenbrock(x: &DVector<f64>) -> f64 {
    (0..x.len() - 1)
        .map(|i| 100.0 * (x[i + 1] - x[i] * x[i]).powi(2) + (1.0 - x[i]).powi(2))
        .sum()
}
