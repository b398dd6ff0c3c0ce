//! Matrix-free preconditioned conjugate gradients for symmetric positive definite systems.
//!
//! [`pcg`] (its doc has the iteration, the stopping rule and the order of the sums), its
//! operator trait, preconditioners and parameters.

use rayon::prelude::*;

use crate::{check, Error, Result};

/// How the sums over a vector (dot products, norms) are taken. Each order is fixed, so results
/// are bit-identical from run to run; the two orders round differently.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reduction {
    /// One front-to-back sum; every vector pass serial.
    Serial,
    /// Parallel over chunks of this many entries (rayon): each chunk summed front to back,
    /// the chunks' sums then added in chunk order. Must be positive.
    Chunked(usize),
}

impl Reduction {
    /// `Σ aᵢ bᵢ` in this order.
    ///
    /// Panics if `self` is [`Reduction::Chunked`]`(0)`; [`pcg`] checks it.
    pub fn dot(self, a: &[f64], b: &[f64]) -> f64 {
        match self {
            Self::Serial => a.iter().zip(b).map(|(x, y)| x * y).sum(),
            Self::Chunked(c) => ordered_sum(
                a.par_chunks(c)
                    .zip(b.par_chunks(c))
                    .map(|(a, b)| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>())
                    .collect(),
            ),
        }
    }

    /// The residual norm `‖r‖₂` or `‖r ⊘ s‖₂` in this order.
    fn norm(self, r: &[f64], measure: ResidualNorm<'_>) -> f64 {
        match (self, measure) {
            (_, ResidualNorm::Euclidean) => self.dot(r, r).sqrt(),
            (Self::Serial, ResidualNorm::DividedBy(s)) => r
                .iter()
                .zip(s)
                .map(|(r, s)| (r / s).powi(2))
                .sum::<f64>()
                .sqrt(),
            (Self::Chunked(c), ResidualNorm::DividedBy(s)) => ordered_sum(
                r.par_chunks(c)
                    .zip(s.par_chunks(c))
                    .map(|(r, s)| r.iter().zip(s).map(|(r, s)| (r / s).powi(2)).sum::<f64>())
                    .collect(),
            )
            .sqrt(),
        }
    }
}

/// Partial sums added in order.
fn ordered_sum(partial: Vec<f64>) -> f64 {
    partial.iter().sum()
}

/// A symmetric positive definite linear operator `y = A x`, applied without a matrix.
pub trait LinearOperator {
    /// `y = A x` (`x` and `y` of the system's length; `y`'s old values are overwritten).
    fn apply(&self, x: &[f64], y: &mut [f64]);

    /// `y = A x` and `xᵀ y`, summed as `reduction` sums ([`Reduction::dot`]). An operator may
    /// fuse the two passes; it must return the same value as this default does.
    fn apply_dot(&self, x: &[f64], y: &mut [f64], reduction: Reduction) -> f64 {
        self.apply(x, y);
        reduction.dot(x, y)
    }
}

impl<F: Fn(&[f64], &mut [f64])> LinearOperator for F {
    fn apply(&self, x: &[f64], y: &mut [f64]) {
        self(x, y);
    }
}

/// The preconditioner `z = M⁻¹ r` of [`pcg`]; it must be symmetric positive definite.
pub enum Preconditioner<'a> {
    /// Jacobi: `z = r ⊘ d` with the operator's diagonal `d` (positive and finite).
    Jacobi(&'a [f64]),
    /// Any map `(r, z)` writing `z = M⁻¹ r` (e.g. one multigrid cycle from `z = 0`).
    Apply(&'a mut dyn FnMut(&[f64], &mut [f64])),
}

impl std::fmt::Debug for Preconditioner<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Jacobi(d) => write!(f, "Jacobi({} entries)", d.len()),
            Self::Apply(_) => f.write_str("Apply(..)"),
        }
    }
}

/// How [`pcg`] measures the residual.
#[derive(Debug, Clone, Copy)]
pub enum ResidualNorm<'a> {
    /// `‖r‖₂`.
    Euclidean,
    /// `‖r ⊘ s‖₂`: each entry divided by its scale `sᵢ` (nonzero and finite), e.g. the
    /// residual of unknowns `zᵢ = sᵢ tᵢ` when the system is solved for `t`.
    DividedBy(&'a [f64]),
}

/// What the residual of [`pcg`] is relative to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reference {
    /// `‖b‖` (floored at 10⁻³⁰⁰); the start is tested as well.
    RightHandSide,
    /// The start's residual; the start itself is not tested, and a zero start residual
    /// returns at once.
    Start,
}

/// Stopping rule and summation order of [`pcg`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PcgParams {
    /// Stop when the relative residual is at most this (nonnegative, finite).
    pub tolerance: f64,
    /// Most iterations (updates of `x`); 0 returns the start.
    pub max_iterations: usize,
    /// What the residual is relative to.
    pub reference: Reference,
    /// Order of the sums, serial or in parallel chunks.
    pub reduction: Reduction,
}

/// Why [`pcg`] stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PcgStop {
    /// The relative residual reached the tolerance (or was NaN).
    Converged,
    /// [`PcgParams::max_iterations`] updates ran.
    MaxIterations,
    /// The curvature `pᵀ A p` was not positive and finite.
    Breakdown,
}

/// What [`pcg`] reached.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PcgStats {
    /// Updates of `x` made.
    pub iterations: usize,
    /// The last measured residual over the [`Reference`] (the start's when no update ran;
    /// 1 for [`Reference::Start`] stopped by a breakdown before the first update, 0 for a
    /// zero start residual).
    pub relative_residual: f64,
    /// Why the loop stopped.
    pub stop: PcgStop,
}

/// Solves `A x = b` by preconditioned conjugate gradients from the start `x₀` in `x`
/// (overwritten by the solution), with the operator `A` given as a
/// [`LinearOperator`] (any `Fn(&[f64], &mut [f64])` is one) and the preconditioner `M⁻¹` as a
/// [`Preconditioner`] (the diagonal, or any symmetric positive definite map, e.g. a multigrid
/// cycle). It is hand-written rather than faer's `matrix_free::conjugate_gradient` because
/// faer's measures the residual only relative to `‖b‖` and sums its dot products in its own
/// (SIMD) order, while the callers here need a residual relative to the start's, measured in
/// unscaled units, and sums in a fixed order that does not depend on the thread count.
///
/// **Iteration.** The textbook loop (Saad, *Iterative Methods for Sparse Linear Systems*,
/// Alg. 9.1): `r = b − A x`, `z = M⁻¹ r`, `p = z`; then per iteration `q = A p`,
/// `α = rᵀz / pᵀq`, `x += α p`, `r −= α q`, the stopping test, `z = M⁻¹ r`,
/// `β = rᵀz_new / rᵀz_old`, `p = z + β p`.
///
/// **Stopping rule.** The residual is measured as `‖r‖₂` or, with
/// [`ResidualNorm::DividedBy`]`(s)`, as `‖r ⊘ s‖₂` (each entry divided by its scale: the
/// residual of the original unknowns when the system is solved in scaled ones), relative to
/// a [`Reference`]: `‖b‖` (floored at 10⁻³⁰⁰; the start is tested too, so a start that
/// already meets the tolerance takes no iteration) or the start's residual (the start's
/// relative residual is 1 by definition and is not tested; a zero start residual returns at
/// once). The loop stops when the relative residual after an update is at most
/// [`PcgParams::tolerance`] (or is NaN), after [`PcgParams::max_iterations`] updates, or when
/// the curvature `pᵀ A p` is not positive and finite (the operator or the preconditioner is
/// not positive definite, or the iterates overflowed); the iterate of the last full update is
/// kept.
///
/// **Sums.** Every dot product and norm is summed in the order [`Reduction`] names: serially
/// front to back, or in parallel over fixed chunks (each chunk summed front to back, the
/// chunks' sums added in chunk order), so the result never depends on the thread count. With
/// [`Reduction::Chunked`] the vector updates run in parallel too and are fused (one pass for
/// `x`, `r` and the residual's sum; with the Jacobi preconditioner `z` is never stored).
///
/// # Errors
/// [`Error::SizeMismatch`] if `x`, the Jacobi diagonal or the residual scales differ in
/// length from `b`; [`Error::NonFinite`] for a NaN or infinite entry of `b`, `x`, the
/// diagonal or the scales; [`Error::InvalidParam`] for a negative or non-finite tolerance, a
/// zero chunk size, a diagonal entry that is not positive or a zero scale.
pub fn pcg<A: LinearOperator + ?Sized>(
    a: &A,
    mut m: Preconditioner<'_>,
    b: &[f64],
    x: &mut [f64],
    norm: ResidualNorm<'_>,
    params: &PcgParams,
) -> Result<PcgStats> {
    let n = b.len();
    check(&m, b, x, norm, params)?;
    let reduction = params.reduction;
    let tolerance = params.tolerance;
    let mut r = vec![0.0; n];
    a.apply(x, &mut r);
    subtract_from(b, &mut r, reduction);
    let (reference, mut rel) = match params.reference {
        Reference::RightHandSide => {
            let bnorm = reduction.norm(b, norm).max(1e-300);
            (bnorm, reduction.norm(&r, norm) / bnorm)
        }
        Reference::Start => {
            let r0 = reduction.norm(&r, norm);
            if r0 == 0.0 {
                return Ok(PcgStats {
                    iterations: 0,
                    relative_residual: 0.0,
                    stop: PcgStop::Converged,
                });
            }
            (r0, 1.0)
        }
    };
    let mut stats = PcgStats {
        iterations: 0,
        relative_residual: rel,
        stop: PcgStop::MaxIterations,
    };
    if params.reference == Reference::RightHandSide && (rel <= tolerance || rel.is_nan()) {
        stats.stop = PcgStop::Converged;
        return Ok(stats);
    }
    // z = M⁻¹ r and p = z.
    let mut z = vec![0.0; n];
    precondition(&mut m, &r, &mut z, reduction);
    let mut rz = reduction.dot(&r, &z);
    let mut p = z;
    let mut z = match (&m, reduction) {
        // The fused chunked pass sums `rᵀ(r ⊘ d)` itself.
        (Preconditioner::Jacobi(_), Reduction::Chunked(_)) => Vec::new(),
        _ => vec![0.0; n],
    };
    let mut q = vec![0.0; n];
    while stats.iterations < params.max_iterations {
        let pq = a.apply_dot(&p, &mut q, reduction);
        if !(pq > 0.0 && pq.is_finite()) {
            stats.stop = PcgStop::Breakdown;
            break;
        }
        let alpha = rz / pq;
        let (rr, rz_jacobi) = update(x, &mut r, &p, &q, alpha, &m, norm, reduction);
        stats.iterations += 1;
        rel = match rr {
            Some(rr) => rr.sqrt() / reference,
            None => reduction.norm(&r, norm) / reference,
        };
        stats.relative_residual = rel;
        if rel <= tolerance || rel.is_nan() {
            stats.stop = PcgStop::Converged;
            break;
        }
        let rz_new = match (&mut m, rz_jacobi) {
            (Preconditioner::Jacobi(_), Some(s)) => s,
            _ => {
                precondition(&mut m, &r, &mut z, reduction);
                reduction.dot(&r, &z)
            }
        };
        let beta = rz_new / rz;
        rz = rz_new;
        next_direction(&mut p, &z, &r, &m, beta, reduction);
    }
    Ok(stats)
}

/// The input checks of [`pcg`].
fn check(
    m: &Preconditioner<'_>,
    b: &[f64],
    x: &[f64],
    norm: ResidualNorm<'_>,
    params: &PcgParams,
) -> Result<()> {
    let n = b.len();
    check::same_size("pcg start x", n, x.len())?;
    check::all_finite("pcg right-hand side b", b)?;
    check::all_finite("pcg start x", x)?;
    check::non_negative("pcg tolerance", params.tolerance)?;
    if let Reduction::Chunked(c) = params.reduction {
        check::nonzero("pcg chunk size", c)?;
    }
    if let Preconditioner::Jacobi(d) = m {
        check::same_size("pcg Jacobi diagonal", n, d.len())?;
        check::all_finite("pcg Jacobi diagonal", *d)?;
        if d.iter().any(|&v| v <= 0.0) {
            return Err(Error::InvalidParam {
                name: "pcg Jacobi diagonal",
                reason: "every entry must be positive (the operator must be positive \
                         definite); use Preconditioner::Apply for another preconditioner"
                    .into(),
            });
        }
    }
    if let ResidualNorm::DividedBy(s) = norm {
        check::same_size("pcg residual scales", n, s.len())?;
        check::all_finite("pcg residual scales", s)?;
        if s.contains(&0.0) {
            return Err(Error::InvalidParam {
                name: "pcg residual scales",
                reason: "every scale must be nonzero; pass ResidualNorm::Euclidean to \
                         measure the residual unscaled"
                    .into(),
            });
        }
    }
    Ok(())
}

/// `r = b − r`.
fn subtract_from(b: &[f64], r: &mut [f64], reduction: Reduction) {
    match reduction {
        Reduction::Serial => r.iter_mut().zip(b).for_each(|(ri, bi)| *ri = bi - *ri),
        Reduction::Chunked(_) => r.par_iter_mut().zip(b).for_each(|(ri, bi)| *ri = bi - *ri),
    }
}

/// `z = M⁻¹ r`.
fn precondition(m: &mut Preconditioner<'_>, r: &[f64], z: &mut [f64], reduction: Reduction) {
    match m {
        Preconditioner::Jacobi(d) => match reduction {
            Reduction::Serial => {
                for ((zi, ri), di) in z.iter_mut().zip(r).zip(*d) {
                    *zi = ri / di;
                }
            }
            Reduction::Chunked(_) => z
                .par_iter_mut()
                .zip(r)
                .zip(*d)
                .for_each(|((zi, ri), di)| *zi = ri / di),
        },
        Preconditioner::Apply(f) => f(r, z),
    }
}

/// `x += α p`, `r −= α q`. Chunked, the pass also returns the residual's sum of squares
/// `Σ rᵢ²` (or `Σ (rᵢ/sᵢ)²`) and, for Jacobi, `Σ rᵢ (rᵢ/dᵢ)`, each chunk summed front to
/// back from 0 and the chunks in order; serially it returns neither (the caller takes the
/// norm in a pass of its own).
#[allow(
    clippy::too_many_arguments,
    reason = "the fused pass's vectors and scalars"
)]
fn update(
    x: &mut [f64],
    r: &mut [f64],
    p: &[f64],
    q: &[f64],
    alpha: f64,
    m: &Preconditioner<'_>,
    norm: ResidualNorm<'_>,
    reduction: Reduction,
) -> (Option<f64>, Option<f64>) {
    let c = match reduction {
        Reduction::Serial => {
            for k in 0..x.len() {
                x[k] += alpha * p[k];
                r[k] -= alpha * q[k];
            }
            return (None, None);
        }
        Reduction::Chunked(c) => c,
    };
    let diag = match m {
        Preconditioner::Jacobi(d) => Some(*d),
        Preconditioner::Apply(_) => None,
    };
    let scale = match norm {
        ResidualNorm::Euclidean => None,
        ResidualNorm::DividedBy(s) => Some(s),
    };
    let sums: Vec<(f64, f64)> = x
        .par_chunks_mut(c)
        .zip(r.par_chunks_mut(c))
        .zip(p.par_chunks(c))
        .zip(q.par_chunks(c))
        .enumerate()
        .map(|(ci, (((xc, rc), pc), qc))| {
            let base = ci * c;
            let (mut rz, mut rr) = (0.0, 0.0);
            for (k, (((xi, ri), pi), qi)) in xc.iter_mut().zip(rc).zip(pc).zip(qc).enumerate() {
                *xi += alpha * pi;
                *ri -= alpha * qi;
                if let Some(d) = diag {
                    rz += *ri * (*ri / d[base + k]);
                }
                match scale {
                    None => rr += *ri * *ri,
                    Some(s) => rr += (*ri / s[base + k]).powi(2),
                }
            }
            (rz, rr)
        })
        .collect();
    let rr = ordered_sum(sums.iter().map(|s| s.1).collect());
    let rz = diag.map(|_| ordered_sum(sums.iter().map(|s| s.0).collect()));
    (Some(rr), rz)
}

/// `p = z + β p` (for Jacobi `z = r ⊘ d`, computed on the fly).
fn next_direction(
    p: &mut [f64],
    z: &[f64],
    r: &[f64],
    m: &Preconditioner<'_>,
    beta: f64,
    reduction: Reduction,
) {
    match (m, reduction) {
        (Preconditioner::Jacobi(d), Reduction::Serial) => {
            for ((pi, ri), di) in p.iter_mut().zip(r).zip(*d) {
                *pi = ri / di + beta * *pi;
            }
        }
        (Preconditioner::Jacobi(d), Reduction::Chunked(_)) => p
            .par_iter_mut()
            .zip(r)
            .zip(*d)
            .for_each(|((pi, ri), di)| *pi = ri / di + beta * *pi),
        (Preconditioner::Apply(_), Reduction::Serial) => {
            for (pi, zi) in p.iter_mut().zip(z) {
                *pi = zi + beta * *pi;
            }
        }
        (Preconditioner::Apply(_), Reduction::Chunked(_)) => p
            .par_iter_mut()
            .zip(z)
            .for_each(|(pi, zi)| *pi = zi + beta * *pi),
    }
}

#[cfg(test)]
mod tests;
