//! HOOI: higher-order orthogonal iteration, the alternating least-squares refinement of the
//! truncated HOSVD that §5.2 recommends after Eq. 5.3 (De Lathauwer, Kroonenberg).

use nalgebra::DMatrix;

use super::dense::Tensor;
use super::hosvd::{check_ranks, hosvd, leading_factor, project, FactorMethod, Tucker};
use crate::{check, Result};

/// Parameters of [`hooi`]; the defaults are TensorLy's `partial_tucker` defaults.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HooiParams {
    /// Maximum number of sweeps over the decomposed modes. Default 100.
    pub max_iterations: usize,
    /// Stop when the relative error changes by less than this between two consecutive
    /// sweeps, checked from the third sweep on (TensorLy's rule, so both stop after the same
    /// number of sweeps). Default 1e-4.
    pub tolerance: f64,
    /// How each factor is computed (also for the HOSVD start). Default [`FactorMethod::Auto`].
    pub method: FactorMethod,
}

impl Default for HooiParams {
    fn default() -> Self {
        Self {
            max_iterations: 100,
            tolerance: 1e-4,
            method: FactorMethod::Auto,
        }
    }
}

/// The result of [`hooi`].
#[derive(Clone, Debug)]
pub struct HooiResult {
    /// The refined decomposition.
    pub tucker: Tucker,
    /// Relative error `‖𝒯 − 𝒯̂‖ / ‖𝒯‖` of the HOSVD start.
    pub hosvd_error: f64,
    /// Relative error after each sweep (non-increasing up to rounding).
    pub errors: Vec<f64>,
    /// Whether the tolerance was met before `max_iterations`.
    pub converged: bool,
}

/// Relative error of a Tucker approximation with orthonormal factors from the norms alone:
/// `‖𝒯 − 𝒯̂‖² = ‖𝒯‖² − ‖𝒞‖²` (TensorLy's formula; resolves errors down to ≈ 1e-8).
fn error_from_core(norm_x: f64, core: &Tensor) -> f64 {
    if norm_x == 0.0 {
        return 0.0;
    }
    let c = core.norm();
    (norm_x * norm_x - c * c).abs().sqrt() / norm_x
}

/// HOOI from the truncated HOSVD ([`hosvd`]): each sweep replaces, mode by mode, `Ǔₙ` by the
/// `rₙ` leading left singular vectors of `(𝒯 ×_{m≠n} Ǔₘᵀ)₍ₙ₎` — the best `Ǔₙ` with the
/// others fixed, so `‖𝒞‖` never decreases and the error never increases — then
/// `𝒞 = 𝒯 ×ₙ Ǔₙᵀ` (Eq. 5.1). Stops after `max_iterations` sweeps or when the relative error
/// changes by less than `tolerance`.
///
/// # Errors
/// As [`hosvd`]; [`crate::Error::InvalidParam`] for a negative or non-finite tolerance.
pub fn hooi(x: &Tensor, ranks: &[Option<usize>], params: &HooiParams) -> Result<HooiResult> {
    check_ranks(x, ranks)?;
    check::non_negative("tolerance", params.tolerance)?;
    let start = hosvd(x, ranks, params.method)?;
    let norm_x = x.norm();
    let hosvd_error = error_from_core(norm_x, &start.core);
    let Tucker {
        mut core,
        mut factors,
    } = start;
    let modes: Vec<(usize, usize)> = ranks
        .iter()
        .enumerate()
        .filter_map(|(n, r)| r.map(|r| (n, r)))
        .collect();
    let mut errors = Vec::new();
    let mut converged = false;
    for _ in 0..params.max_iterations {
        if modes.is_empty() {
            converged = true;
            break;
        }
        let mut last: Option<(usize, Tensor)> = None;
        for &(n, r) in &modes {
            // A mode kept at full rank has a square orthogonal factor: projecting on it
            // rotates that mode only and changes neither mode n's Gram matrix nor ‖𝒞‖, so
            // the update skips it (exact, and the full-rank mode of the order-4 peer
            // workload would otherwise cost a third of each sweep).
            let skip: Vec<Option<DMatrix<f64>>> = factors
                .iter()
                .enumerate()
                .map(|(m, f)| {
                    f.as_ref()
                        .filter(|u| m == n || u.nrows() > u.ncols())
                        .cloned()
                })
                .collect();
            let y = project(x, &skip, Some(n))?;
            factors[n] = Some(leading_factor(&y, n, r, params.method)?);
            last = Some((n, y));
        }
        if let Some((n, y)) = last {
            // 𝒞 = 𝒯 ×ₘ Ǔₘᵀ (Eq. 5.1): the last projection lacks mode n and the skipped
            // full-rank modes.
            let mut c = y;
            for (m, f) in factors.iter().enumerate() {
                if let Some(u) = f.as_ref().filter(|u| m == n || u.nrows() == u.ncols()) {
                    c = c.mode_product(m, &u.transpose())?;
                }
            }
            core = c;
        }
        let err = error_from_core(norm_x, &core);
        errors.push(err);
        // TensorLy's rule: compare the last two errors from the third sweep on.
        let done = errors.len() >= 3 && (errors[errors.len() - 2] - err).abs() < params.tolerance;
        if done {
            converged = true;
            break;
        }
    }
    Ok(HooiResult {
        tucker: Tucker { core, factors },
        hosvd_error,
        errors,
        converged,
    })
}
