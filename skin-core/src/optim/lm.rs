//! Dense Levenberg–Marquardt for `min_x ½‖r(x)‖²`.
//!
//! Each iteration solves the damped normal equations `(JᵀJ + λ D) h = −Jᵀr` with Marquardt's
//! diagonal scaling `D = diag(dⱼ²)`, `dⱼ` the largest norm column `j` of `J` has had so far
//! (Moré 1978, "The Levenberg–Marquardt algorithm: implementation and theory", §3), so the
//! method is invariant to the units of each parameter (focal lengths in pixels next to rotations
//! in radians). The damping `λ` follows Nielsen's gain-ratio rule (Madsen, Nielsen & Tingleff
//! 2004, "Methods for non-linear least squares problems", Alg. 3.16): after a step with gain
//! ratio `ρ > 0`, `λ ← λ·max(1/3, 1 − (2ρ − 1)³)`; after a rejected step `λ ← λ·ν`, `ν ← 2ν`.

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use super::numeric::numeric_jacobian;
use crate::check::all_finite;
use crate::error::{Error, Result};

impl LmParams {
    /// Default iteration limit. Default: 200.
    pub const DEFAULT_MAX_ITERATIONS: usize = 200;

    /// Default relative cost tolerance. Default: 1e-12.
    pub const DEFAULT_COST_TOLERANCE: f64 = 1e-12;

    /// Default relative step tolerance. Default: 1e-10.
    pub const DEFAULT_STEP_TOLERANCE: f64 = 1e-10;

    /// Default gradient tolerance. Default: 1e-12.
    pub const DEFAULT_GRADIENT_TOLERANCE: f64 = 1e-12;

    /// Default initial damping relative to the scaling. Default: 1e-3 (Madsen et al. 2004, §3.2).
    pub const DEFAULT_INITIAL_LAMBDA: f64 = 1e-3;
}

/// Damping beyond which no step can make progress; the method stops.
const MAX_LAMBDA: f64 = 1e32;
/// Columns whose norm is below this fraction of the largest get this floor in `D`, so a
/// parameter that (temporarily) has no effect stays put instead of making `JᵀJ + λD` singular.
const SCALE_FLOOR: f64 = 1e-12;

/// Knobs of [`levenberg_marquardt`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LmParams {
    /// Maximum number of accepted or rejected iterations (Jacobian evaluations count once each).
    /// Default: 200.
    pub max_iterations: usize,
    /// Stop when an accepted step lowers the cost by less than this fraction of it.
    /// Dimensionless. Default: 1e-12.
    pub cost_tolerance: f64,
    /// Stop when the scaled step `‖D^½ h‖` is below `step_tolerance · (‖D^½ x‖ + step_tolerance)`.
    /// Dimensionless. Default: 1e-10.
    pub step_tolerance: f64,
    /// Stop when the scaled gradient `max_j |(Jᵀr)_j| / dⱼ` is below this, in units of the
    /// residual. Default: 1e-12.
    pub gradient_tolerance: f64,
    /// Initial damping `λ₀` (relative: `D` already carries the scale of `JᵀJ`). Default: 1e-3.
    pub initial_lambda: f64,
}

impl Default for LmParams {
    fn default() -> Self {
        Self {
            max_iterations: LmParams::DEFAULT_MAX_ITERATIONS,
            cost_tolerance: LmParams::DEFAULT_COST_TOLERANCE,
            step_tolerance: LmParams::DEFAULT_STEP_TOLERANCE,
            gradient_tolerance: LmParams::DEFAULT_GRADIENT_TOLERANCE,
            initial_lambda: LmParams::DEFAULT_INITIAL_LAMBDA,
        }
    }
}

impl LmParams {
    /// Sets [`LmParams::max_iterations`].
    pub fn with_max_iterations(mut self, max_iterations: usize) -> Self {
        self.max_iterations = max_iterations;
        self
    }

    fn validate(&self) -> Result<()> {
        use crate::check::{non_negative, positive};
        non_negative("cost_tolerance", self.cost_tolerance)?;
        non_negative("step_tolerance", self.step_tolerance)?;
        non_negative("gradient_tolerance", self.gradient_tolerance)?;
        positive("initial_lambda", self.initial_lambda)?;
        Ok(())
    }
}

/// Why [`levenberg_marquardt`] stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum LmTermination {
    /// The scaled gradient fell below [`LmParams::gradient_tolerance`] (a stationary point).
    Gradient,
    /// The relative cost decrease fell below [`LmParams::cost_tolerance`].
    Cost,
    /// The scaled step fell below [`LmParams::step_tolerance`].
    Step,
    /// The damping grew without finding a descent step (the cost is at rounding-error level
    /// or the Jacobian is wrong).
    NoProgress,
    /// [`LmParams::max_iterations`] was reached.
    MaxIterations,
}

impl LmTermination {
    /// True unless the iteration limit stopped the method.
    pub fn converged(self) -> bool {
        self != LmTermination::MaxIterations
    }
}

/// Result of [`levenberg_marquardt`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LmReport {
    /// Final parameters.
    pub x: DVector<f64>,
    /// Residuals at [`LmReport::x`].
    pub residuals: DVector<f64>,
    /// Final cost `½‖r‖²`.
    pub cost: f64,
    /// Initial cost `½‖r(x₀)‖²`.
    pub initial_cost: f64,
    /// Iterations performed (one Jacobian each, accepted or not).
    pub iterations: usize,
    /// Residual evaluations, including the initial one.
    pub residual_evaluations: usize,
    /// Why the method stopped.
    pub termination: LmTermination,
}

impl LmReport {
    /// Root-mean-square residual `‖r‖/√m` (0 for no residuals).
    pub fn rms(&self) -> f64 {
        if self.residuals.is_empty() {
            0.0
        } else {
            (2.0 * self.cost / self.residuals.len() as f64).sqrt()
        }
    }
}

/// Minimises `½‖r(x)‖²` from `x0` with an analytic Jacobian `J = ∂r/∂x` (`m × n`).
///
/// A residual evaluation that fails at a trial point (returns `Err` or non-finite values, e.g.
/// a calibration point that moves behind the camera) rejects that step and raises the damping;
/// only failures at `x0` or in the Jacobian are returned.
///
/// # Errors
/// [`Error::Empty`] for `x0` empty; [`Error::NonFinite`] for non-finite `x0`, residuals at `x0`
/// or Jacobian entries; [`Error::SizeMismatch`] if the Jacobian is not `m × n` or the residual
/// length changes; [`Error::InvalidParam`] for bad params; errors of the closures at `x0`.
///
/// # Example
/// ```
/// use nalgebra::{dvector, DMatrix, DVector};
/// use skin_core::optim::{levenberg_marquardt, LmParams};
/// // Rosenbrock as residuals r = (10(x₁ − x₀²), 1 − x₀).
/// let r = |x: &DVector<f64>| Ok(dvector![10.0 * (x[1] - x[0] * x[0]), 1.0 - x[0]]);
/// let j = |x: &DVector<f64>| Ok(DMatrix::from_row_slice(2, 2, &[-20.0 * x[0], 10.0, -1.0, 0.0]));
/// let report = levenberg_marquardt(&dvector![-1.2, 1.0], &LmParams::default(), r, j)?;
/// assert!((report.x[0] - 1.0).abs() < 1e-8 && (report.x[1] - 1.0).abs() < 1e-8);
/// # Ok::<(), skin_core::Error>(())
/// ```
pub fn levenberg_marquardt<R, J>(
    x0: &DVector<f64>,
    params: &LmParams,
    residual: R,
    jacobian: J,
) -> Result<LmReport>
where
    R: FnMut(&DVector<f64>) -> Result<DVector<f64>>,
    J: FnMut(&DVector<f64>) -> Result<DMatrix<f64>>,
{
    lm_core(x0, None, params, residual, jacobian)
}

/// [`levenberg_marquardt`] with box constraints `lower ≤ x ≤ upper` (infinite bounds
/// allowed), by projection with an active set (the projected Levenberg–Marquardt of Kanzow,
/// Yamashita & Fukushima 2004, with the active set of Bertsekas 1982): `x0` is first clamped
/// into the box; at each iteration the parameters at a bound whose gradient points out of the
/// box are held fixed, the damped step of the others is solved, and the trial point is
/// clamped into the box. The gain ratio compares the actual decrease with the quadratic
/// model's prediction for the *projected* step, and the gradient test uses the free
/// parameters only, so a minimum on a bound is recognised. For joint limits (Vlasic 2010
/// §2.3.1: "Joint limits constrain it to lie in a range") and any other box.
///
/// # Errors
/// As [`levenberg_marquardt`]; [`Error::SizeMismatch`] for bounds of another length;
/// [`Error::InvalidParam`] for a NaN bound or a lower bound above its upper bound.
///
/// # Example
/// ```
/// use nalgebra::{dvector, DMatrix, DVector};
/// use skin_core::optim::{levenberg_marquardt_bounded, LmParams};
/// // Minimum of (x − 2)² + (y + 1)² in the box [0, 1] × [−5, 5]: (1, −1).
/// let r = |x: &DVector<f64>| Ok(dvector![x[0] - 2.0, x[1] + 1.0]);
/// let j = |_: &DVector<f64>| Ok(DMatrix::identity(2, 2));
/// let (lo, hi) = (dvector![0.0, -5.0], dvector![1.0, 5.0]);
/// let report = levenberg_marquardt_bounded(&dvector![0.5, 3.0], &lo, &hi, &LmParams::default(), r, j)?;
/// assert!((report.x[0] - 1.0).abs() < 1e-12 && (report.x[1] + 1.0).abs() < 1e-9);
/// # Ok::<(), skin_core::Error>(())
/// ```
pub fn levenberg_marquardt_bounded<R, J>(
    x0: &DVector<f64>,
    lower: &DVector<f64>,
    upper: &DVector<f64>,
    params: &LmParams,
    residual: R,
    jacobian: J,
) -> Result<LmReport>
where
    R: FnMut(&DVector<f64>) -> Result<DVector<f64>>,
    J: FnMut(&DVector<f64>) -> Result<DMatrix<f64>>,
{
    for (what, b) in [("lower bounds", lower), ("upper bounds", upper)] {
        if b.len() != x0.len() {
            return Err(Error::SizeMismatch {
                what,
                expected: x0.len(),
                got: b.len(),
            });
        }
    }
    for (j, (l, u)) in lower.iter().zip(upper.iter()).enumerate() {
        if l.is_nan() || u.is_nan() || l > u {
            return Err(Error::InvalidParam {
                name: "bounds",
                reason: format!("parameter {j}: lower bound {l} must be <= upper bound {u}"),
            });
        }
    }
    lm_core(x0, Some((lower, upper)), params, residual, jacobian)
}

/// The iteration of [`levenberg_marquardt`] and [`levenberg_marquardt_bounded`]; without
/// bounds it is the plain method, operation for operation.
fn lm_core<R, J>(
    x0: &DVector<f64>,
    bounds: Option<(&DVector<f64>, &DVector<f64>)>,
    params: &LmParams,
    mut residual: R,
    mut jacobian: J,
) -> Result<LmReport>
where
    R: FnMut(&DVector<f64>) -> Result<DVector<f64>>,
    J: FnMut(&DVector<f64>) -> Result<DMatrix<f64>>,
{
    params.validate()?;
    if x0.is_empty() {
        return Err(Error::Empty {
            what: "optimisation parameters",
        });
    }
    all_finite("initial parameters", x0.iter())?;
    let n = x0.len();
    let project = |x: &mut DVector<f64>| {
        if let Some((lo, hi)) = bounds {
            for j in 0..x.len() {
                x[j] = x[j].clamp(lo[j], hi[j]);
            }
        }
    };
    let mut x = x0.clone();
    project(&mut x);
    let mut r = residual(&x)?;
    all_finite("residuals at the initial parameters", r.iter())?;
    let m = r.len();
    let mut cost = 0.5 * r.norm_squared();
    let initial_cost = cost;
    let mut residual_evaluations = 1;
    let mut scale = DVector::<f64>::zeros(n);
    let mut lambda = params.initial_lambda;
    let mut nu = 2.0;
    let mut iterations = 0;
    let termination = 'outer: loop {
        if iterations >= params.max_iterations {
            break LmTermination::MaxIterations;
        }
        let jac = jacobian(&x)?;
        if jac.nrows() != m || jac.ncols() != n {
            return Err(Error::SizeMismatch {
                what: "Jacobian entries (rows x cols) vs residuals x parameters",
                expected: m * n,
                got: jac.nrows() * jac.ncols(),
            });
        }
        all_finite("Jacobian", jac.iter())?;
        let mut jtj = jac.tr_mul(&jac);
        let mut g = jac.tr_mul(&r);
        // Active set: parameters on a bound whose descent direction −g leaves the box stay.
        let mut fixed = vec![false; n];
        if let Some((lo, hi)) = bounds {
            for j in 0..n {
                fixed[j] = (x[j] <= lo[j] && g[j] > 0.0) || (x[j] >= hi[j] && g[j] < 0.0);
            }
        }
        let full_jtj = jtj.clone();
        let full_g = g.clone();
        for j in (0..n).filter(|&j| fixed[j]) {
            jtj.row_mut(j).fill(0.0);
            jtj.column_mut(j).fill(0.0);
            g[j] = 0.0;
        }
        for j in 0..n {
            scale[j] = scale[j].max(jtj[(j, j)].sqrt());
        }
        let floor = SCALE_FLOOR * scale.max().max(f64::MIN_POSITIVE);
        let d: DVector<f64> = scale.map(|s| s.max(floor));
        let scaled_gradient = g.component_div(&d).amax();
        if scaled_gradient <= params.gradient_tolerance {
            break LmTermination::Gradient;
        }
        // Inner loop: raise the damping until a step lowers the cost.
        loop {
            iterations += 1;
            let mut a = jtj.clone();
            for j in 0..n {
                a[(j, j)] += lambda * d[j] * d[j];
            }
            let step = a.cholesky().map(|c| c.solve(&(-&g)));
            if let Some(mut h) = step.filter(|h| h.iter().all(|v| v.is_finite())) {
                let mut x_new = &x + &h;
                project(&mut x_new);
                let projected = x_new != &x + &h;
                if projected {
                    h = &x_new - &x;
                }
                let trial = residual(&x_new);
                residual_evaluations += 1;
                let r_new = trial
                    .ok()
                    .filter(|r_new| r_new.len() == m && r_new.iter().all(|v| v.is_finite()));
                if let Some(r_new) = r_new {
                    let cost_new = 0.5 * r_new.norm_squared();
                    // Predicted decrease of the quadratic model: ½hᵀ(λDh − g) for the
                    // solved step; −gᵀh − ½hᵀJᵀJh for a step the bounds cut.
                    let predicted = if projected {
                        -full_g.dot(&h) - 0.5 * h.dot(&(&full_jtj * &h))
                    } else {
                        let dh = h.component_mul(&d).component_mul(&d) * lambda;
                        0.5 * h.dot(&(dh - &g))
                    };
                    let actual = cost - cost_new;
                    if actual > 0.0 && predicted > 0.0 {
                        let rho = actual / predicted;
                        let scaled_step = h.component_mul(&d).norm();
                        let scaled_x = x.component_mul(&d).norm();
                        x = x_new;
                        r = r_new;
                        let old_cost = cost;
                        cost = cost_new;
                        lambda *= (1.0 - (2.0 * rho - 1.0).powi(3)).max(1.0 / 3.0);
                        nu = 2.0;
                        if actual <= params.cost_tolerance * old_cost {
                            break 'outer LmTermination::Cost;
                        }
                        if scaled_step <= params.step_tolerance * (scaled_x + params.step_tolerance)
                        {
                            break 'outer LmTermination::Step;
                        }
                        break;
                    }
                }
            }
            lambda *= nu;
            nu *= 2.0;
            if lambda > MAX_LAMBDA || !nu.is_finite() {
                break 'outer LmTermination::NoProgress;
            }
            if iterations >= params.max_iterations {
                break 'outer LmTermination::MaxIterations;
            }
        }
    };
    Ok(LmReport {
        x,
        residuals: r,
        cost,
        initial_cost,
        iterations,
        residual_evaluations,
        termination,
    })
}

/// [`levenberg_marquardt`] with a central-difference Jacobian ([`numeric_jacobian`]).
///
/// # Errors
/// As [`levenberg_marquardt`].
pub fn levenberg_marquardt_numeric<R>(
    x0: &DVector<f64>,
    params: &LmParams,
    residual: R,
) -> Result<LmReport>
where
    R: FnMut(&DVector<f64>) -> Result<DVector<f64>>,
{
    // Both closures need the residual; share it through a RefCell (single-threaded, never
    // borrowed re-entrantly: each closure borrows for the duration of one call).
    let cell = std::cell::RefCell::new(residual);
    levenberg_marquardt(
        x0,
        params,
        |x| (cell.borrow_mut())(x),
        |x| numeric_jacobian(&mut *cell.borrow_mut(), x),
    )
}

#[cfg(test)]
mod tests;
