//! Nelder–Mead downhill simplex (Nelder & Mead 1965), the optimiser Sand 2003 (§4.1) uses for
//! camera calibration and for synchronising video with motion data.
//!
//! Uses the dimension-adaptive coefficients of Gao & Han (2012, "Implementing the Nelder–Mead
//! simplex algorithm with adaptive parameters"): reflection 1, expansion `1 + 2/n`, contraction
//! `3/4 − 1/(2n)`, shrink `1 − 1/n`. For `n = 2` these are the classic (1, 2, ½, ½); for larger
//! `n` they avoid the well-known stagnation of the classic coefficients. After convergence the
//! simplex is rebuilt around the best point and the search restarted (Press et al., *Numerical
//! Recipes* §10.5: "it never hurts to restart"), which catches false convergence on a collapsed
//! simplex.

use nalgebra::DVector;
use serde::{Deserialize, Serialize};

use crate::check::all_finite;
use crate::error::{Error, Result};

/// Knobs of [`nelder_mead`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct NelderMeadParams {
    /// Edge length of the initial simplex along every coordinate, in the units of `x`
    /// (used by [`nelder_mead`]; [`nelder_mead_with_steps`] takes one per coordinate).
    /// Default: 0.1.
    pub initial_step: f64,
    /// Converged when `|f_worst − f_best| ≤ f_tolerance · (|f_best| + f_tolerance)`, with the
    /// same condition on the vertices. Dimensionless (relative). Default: 1e-10.
    pub f_tolerance: f64,
    /// Converged when every vertex is within this distance (max-norm, units of `x`) of the best.
    /// Default: 1e-8.
    pub x_tolerance: f64,
    /// Maximum number of objective evaluations over all restarts. Default: 20 000.
    pub max_evaluations: usize,
    /// Restarts from a fresh simplex around the best point after convergence; stops early when a
    /// restart improves nothing. Default: 2.
    pub max_restarts: usize,
    /// Use Gao–Han dimension-adaptive coefficients (`false`: classic 1, 2, ½, ½). Default: true.
    pub adaptive: bool,
}

impl Default for NelderMeadParams {
    fn default() -> Self {
        Self {
            initial_step: 0.1,
            f_tolerance: 1e-10,
            x_tolerance: 1e-8,
            max_evaluations: 20_000,
            max_restarts: 2,
            adaptive: true,
        }
    }
}

impl NelderMeadParams {
    /// Sets [`NelderMeadParams::max_evaluations`].
    pub fn with_max_evaluations(mut self, max_evaluations: usize) -> Self {
        self.max_evaluations = max_evaluations;
        self
    }

    /// Sets [`NelderMeadParams::initial_step`].
    pub fn with_initial_step(mut self, initial_step: f64) -> Self {
        self.initial_step = initial_step;
        self
    }
}

/// Result of [`nelder_mead`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NelderMeadReport {
    /// Best point found.
    pub x: DVector<f64>,
    /// Objective at [`NelderMeadReport::x`].
    pub f: f64,
    /// Simplex iterations (reflections, expansions, contractions or shrinks).
    pub iterations: usize,
    /// Objective evaluations.
    pub evaluations: usize,
    /// Restarts performed.
    pub restarts: usize,
    /// True if the tolerances were met (false: the evaluation limit stopped the search).
    pub converged: bool,
}

/// Minimises `f` from `x0` with an initial simplex of edge [`NelderMeadParams::initial_step`]
/// along every axis. Non-finite objective values are treated as `+∞` (the simplex moves away).
///
/// # Errors
/// [`Error::Empty`] for empty `x0`; [`Error::NonFinite`] for non-finite `x0` or `f(x0)`;
/// [`Error::InvalidParam`] for non-positive steps or tolerances.
///
/// # Example
/// ```
/// use nalgebra::dvector;
/// use skin_core::optim::{nelder_mead, NelderMeadParams};
/// let rep = nelder_mead(&dvector![-1.2, 1.0], &NelderMeadParams::default(), |x| {
///     100.0 * (x[1] - x[0] * x[0]).powi(2) + (1.0 - x[0]).powi(2)
/// })?;
/// assert!((rep.x[0] - 1.0).abs() < 1e-4);
/// # Ok::<(), skin_core::Error>(())
/// ```
pub fn nelder_mead<F>(
    x0: &DVector<f64>,
    params: &NelderMeadParams,
    f: F,
) -> Result<NelderMeadReport>
where
    F: FnMut(&DVector<f64>) -> f64,
{
    let steps = DVector::from_element(x0.len(), params.initial_step);
    nelder_mead_with_steps(x0, &steps, params, f)
}

/// [`nelder_mead`] with one initial simplex edge per coordinate (`steps`, units of `x`), for
/// parameters of different scales; [`NelderMeadParams::initial_step`] is ignored.
///
/// # Errors
/// As [`nelder_mead`], plus [`Error::SizeMismatch`] if `steps` and `x0` differ in length.
pub fn nelder_mead_with_steps<F>(
    x0: &DVector<f64>,
    steps: &DVector<f64>,
    params: &NelderMeadParams,
    mut f: F,
) -> Result<NelderMeadReport>
where
    F: FnMut(&DVector<f64>) -> f64,
{
    let n = x0.len();
    if n == 0 {
        return Err(Error::Empty {
            what: "optimisation parameters",
        });
    }
    if steps.len() != n {
        return Err(Error::SizeMismatch {
            what: "Nelder-Mead steps vs parameters",
            expected: n,
            got: steps.len(),
        });
    }
    all_finite("initial parameters", x0.iter())?;
    if steps.iter().any(|s| !(s.is_finite() && *s != 0.0)) {
        return Err(Error::InvalidParam {
            name: "initial_step",
            reason: "every step must be finite and non-zero".into(),
        });
    }
    crate::check::non_negative("f_tolerance", params.f_tolerance)?;
    crate::check::non_negative("x_tolerance", params.x_tolerance)?;
    let nf = n as f64;
    let (alpha, beta, gamma, delta) = if params.adaptive && n > 2 {
        (1.0, 1.0 + 2.0 / nf, 0.75 - 0.5 / nf, 1.0 - 1.0 / nf)
    } else {
        (1.0, 2.0, 0.5, 0.5)
    };
    let mut evaluations = 0usize;
    let mut eval = |x: &DVector<f64>, evaluations: &mut usize| {
        *evaluations += 1;
        let v = f(x);
        if v.is_finite() {
            v
        } else {
            f64::INFINITY
        }
    };
    let f0 = eval(x0, &mut evaluations);
    if !f0.is_finite() {
        return Err(Error::NonFinite {
            what: "objective at the initial parameters",
        });
    }
    let mut best_x = x0.clone();
    let mut best_f = f0;
    let mut iterations = 0usize;
    let mut restarts = 0usize;
    let mut converged;
    loop {
        // Build the simplex around the current best point.
        let mut xs: Vec<DVector<f64>> = vec![best_x.clone()];
        let mut fs: Vec<f64> = vec![best_f];
        for j in 0..n {
            let mut v = best_x.clone();
            v[j] += steps[j];
            fs.push(eval(&v, &mut evaluations));
            xs.push(v);
        }
        converged = false;
        while evaluations < params.max_evaluations {
            // Order: best first, worst last.
            let mut order: Vec<usize> = (0..=n).collect();
            order.sort_by(|&a, &b| fs[a].total_cmp(&fs[b]));
            xs = order.iter().map(|&i| xs[i].clone()).collect();
            fs = order.iter().map(|&i| fs[i]).collect();
            let (fb, fw) = (fs[0], fs[n]);
            let f_spread_ok =
                (fw - fb).abs() <= params.f_tolerance * (fb.abs() + params.f_tolerance);
            let x_spread = xs[1..]
                .iter()
                .map(|v| (v - &xs[0]).amax())
                .fold(0.0, f64::max);
            if f_spread_ok && x_spread <= params.x_tolerance {
                converged = true;
                break;
            }
            iterations += 1;
            let centroid = xs[..n].iter().fold(DVector::zeros(n), |acc, v| acc + v) / nf;
            let xr = &centroid + (&centroid - &xs[n]) * alpha;
            let fr = eval(&xr, &mut evaluations);
            if fr < fs[0] {
                let xe = &centroid + (&xr - &centroid) * beta;
                let fe = eval(&xe, &mut evaluations);
                if fe < fr {
                    xs[n] = xe;
                    fs[n] = fe;
                } else {
                    xs[n] = xr;
                    fs[n] = fr;
                }
                continue;
            }
            if fr < fs[n - 1] {
                xs[n] = xr;
                fs[n] = fr;
                continue;
            }
            // Contraction: outside if the reflection beats the worst, inside otherwise.
            let (xc, fc) = if fr < fs[n] {
                let xc = &centroid + (&xr - &centroid) * gamma;
                let fc = eval(&xc, &mut evaluations);
                (xc, fc)
            } else {
                let xc = &centroid + (&xs[n] - &centroid) * gamma;
                let fc = eval(&xc, &mut evaluations);
                (xc, fc)
            };
            if fc < fr.min(fs[n]) {
                xs[n] = xc;
                fs[n] = fc;
                continue;
            }
            // Shrink towards the best vertex.
            for i in 1..=n {
                xs[i] = &xs[0] + (&xs[i] - &xs[0]) * delta;
                fs[i] = eval(&xs[i], &mut evaluations);
            }
        }
        let (ib, fb) = fs
            .iter()
            .copied()
            .enumerate()
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap_or((0, best_f)); // fs has n + 1 >= 2 entries
        let improved = fb < best_f - params.f_tolerance * (best_f.abs() + params.f_tolerance);
        if fb <= best_f {
            best_f = fb;
            best_x = xs[ib].clone();
        }
        if !converged || restarts >= params.max_restarts || (restarts > 0 && !improved) {
            break;
        }
        restarts += 1;
    }
    Ok(NelderMeadReport {
        x: best_x,
        f: best_f,
        iterations,
        evaluations,
        restarts,
        converged,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optim::test_problems::rosenbrock;
    use nalgebra::dvector;

    #[test]
    fn rosenbrock_2d_and_4d() {
        let p = NelderMeadParams::default();
        let r = nelder_mead(&dvector![-1.2, 1.0], &p, rosenbrock).unwrap();
        assert!(r.converged);
        assert!(
            (r.x.clone() - dvector![1.0, 1.0]).amax() < 1e-5,
            "{:?}",
            r.x
        );
        let r4 = nelder_mead(
            &dvector![-1.0, 1.0, -1.0, 1.0],
            &p.with_max_evaluations(50_000),
            rosenbrock,
        )
        .unwrap();
        assert!(
            (r4.x - dvector![1.0, 1.0, 1.0, 1.0]).amax() < 1e-4,
            "f = {}",
            r4.f
        );
    }

    #[test]
    fn badly_scaled_quadratic_with_steps() {
        // 8-D quadratic with scales over four decades: per-coordinate steps handle it.
        let scales = DVector::from_fn(8, |i, _| 10f64.powi(i as i32 / 2 - 2));
        let target = DVector::from_fn(8, |i, _| (i as f64 + 1.0) * scales[i]);
        let f = |x: &DVector<f64>| (x - &target).component_div(&scales).norm_squared();
        let p = NelderMeadParams::default().with_max_evaluations(100_000);
        let r = nelder_mead_with_steps(&DVector::zeros(8), &scales, &p, f).unwrap();
        assert!(
            ((&r.x - &target).component_div(&scales)).amax() < 1e-4,
            "f = {}",
            r.f
        );
    }

    #[test]
    fn nan_regions_are_avoided_and_limits_reported() {
        // Objective undefined (NaN) for x < 0: the minimum on the boundary side is still found.
        let f = |x: &DVector<f64>| {
            if x[0] < 0.0 {
                f64::NAN
            } else {
                (x[0] - 0.3).powi(2) + x[1] * x[1]
            }
        };
        let r = nelder_mead(&dvector![1.0, 1.0], &NelderMeadParams::default(), f).unwrap();
        assert!((r.x[0] - 0.3).abs() < 1e-4 && r.x[1].abs() < 1e-4);
        let limited = nelder_mead(
            &dvector![-1.2, 1.0],
            &NelderMeadParams::default().with_max_evaluations(30),
            rosenbrock,
        )
        .unwrap();
        assert!(!limited.converged);
        assert!(limited.evaluations <= 30 + 3);
    }

    #[test]
    fn bad_inputs_are_errors() {
        let p = NelderMeadParams::default();
        let f = |x: &DVector<f64>| x.norm_squared();
        assert!(matches!(
            nelder_mead(&DVector::zeros(0), &p, f),
            Err(Error::Empty { .. })
        ));
        assert!(matches!(
            nelder_mead(&dvector![f64::NAN], &p, f),
            Err(Error::NonFinite { .. })
        ));
        assert!(matches!(
            nelder_mead(&dvector![1.0], &p, |_| f64::NAN),
            Err(Error::NonFinite { .. })
        ));
        assert!(matches!(
            nelder_mead(&dvector![1.0], &p.with_initial_step(0.0), f),
            Err(Error::InvalidParam { .. })
        ));
        assert!(matches!(
            nelder_mead_with_steps(&dvector![1.0], &dvector![1.0, 1.0], &p, f),
            Err(Error::SizeMismatch { .. })
        ));
    }
}
