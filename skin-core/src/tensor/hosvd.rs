//! The N-mode SVD / truncated HOSVD (Vlasic Eq. 5.1–5.3, De Lathauwer et al. 2000) with a
//! rank per mode, modes that are not decomposed (Eq. 5.4), and three ways to get a factor.

use nalgebra::DMatrix;

use super::dense::Tensor;
use crate::faer_bridge::{matmul, sym_top_eigen, thin_q, thin_svd_left};
use crate::random::SplitMix64;
use crate::{check, Error, Result};

/// How the leading left singular vectors of an unfolding `X₍ₙ₎` (`dₙ × J`) are computed.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub enum FactorMethod {
    /// [`FactorMethod::Gram`] when `dₙ ≤ J`, else [`FactorMethod::Svd`] (the tall unfolding
    /// of a huge mode, whose Gram matrix would be `dₙ × dₙ`).
    #[default]
    Auto,
    /// Eigenvectors of the `dₙ × dₙ` Gram matrix `X₍ₙ₎ X₍ₙ₎ᵀ` (faer's self-adjoint
    /// eigensolver), formed slab by slab without the unfolding — what TensorLy does for a
    /// wide unfolding. Squares the condition number: singular values below
    /// `≈ 1e-8 · σ₁` are not resolved, which truncation discards anyway.
    Gram,
    /// faer's thin SVD of the materialised unfolding.
    Svd,
    /// Randomized range finder (Halko, Martinsson & Tropp 2011, Alg. 4.4 with power
    /// iterations, then Alg. 5.1): for a huge mode with a small rank.
    Randomized(RandomizedParams),
}

/// Parameters of [`FactorMethod::Randomized`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RandomizedParams {
    /// Extra sample columns beyond the rank (Halko's `p`). Default 10.
    pub oversample: usize,
    /// Power (subspace) iterations `q`, each re-orthonormalised. Default 2.
    pub power_iterations: usize,
    /// Seed of the Gaussian test matrix (SplitMix64 normals). Default 0.
    pub seed: u64,
}

impl Default for RandomizedParams {
    fn default() -> Self {
        Self {
            oversample: 10,
            power_iterations: 2,
            seed: 0,
        }
    }
}

/// A Tucker decomposition `𝒯 ≈ 𝒞 ×₁ Ǔ₁ ⋯ ×_N Ǔ_N` (Eq. 5.3): the core and one factor per
/// mode, `None` for a mode that is not decomposed (Eq. 5.4: the core keeps that mode, and
/// the core is then the "multilinear model" `ℳ`).
#[derive(Clone, Debug, PartialEq)]
pub struct Tucker {
    /// The (reduced) core tensor `𝒞`: mode `n` has size `rₙ` (or `dₙ` if not decomposed).
    pub core: Tensor,
    /// `Ǔₙ` (`dₙ × rₙ`, orthonormal columns, leading singular vectors first) or `None`.
    pub factors: Vec<Option<DMatrix<f64>>>,
}

impl Tucker {
    /// The approximation `𝒞 ×₁ Ǔ₁ ⋯ ×_N Ǔ_N` (Eq. 5.2–5.3).
    ///
    /// # Errors
    /// As [`Tensor::multi_mode_product`] (only for a hand-edited, inconsistent `Tucker`).
    pub fn reconstruct(&self) -> Result<Tensor> {
        let products: Vec<(usize, &DMatrix<f64>)> = self
            .factors
            .iter()
            .enumerate()
            .filter_map(|(n, f)| f.as_ref().map(|f| (n, f)))
            .collect();
        self.core.multi_mode_product(&products)
    }

    /// The rank kept in each mode (the core's shape).
    pub fn ranks(&self) -> &[usize] {
        self.core.shape()
    }
}

/// Checks `ranks` against `x`: one entry per mode, each `None` or `1 ≤ r ≤ dₙ`.
pub(crate) fn check_ranks(x: &Tensor, ranks: &[Option<usize>]) -> Result<()> {
    check::same_size("ranks (one per mode)", x.order(), ranks.len())?;
    for (n, (&rank, &d)) in ranks.iter().zip(x.shape()).enumerate() {
        match rank {
            Some(0) => {
                return Err(Error::InvalidParam {
                    name: "rank",
                    reason: format!("mode {n}: a rank must be ≥ 1 (use None to keep a mode)"),
                })
            }
            Some(r) if r > d => {
                return Err(Error::InvalidParam {
                    name: "rank",
                    reason: format!("mode {n}: rank {r} exceeds the mode's size {d}"),
                })
            }
            _ => {}
        }
    }
    Ok(())
}

/// The truncated N-mode SVD (Eq. 5.1–5.3): `Ǔₙ` = the `rₙ` leading left singular vectors of
/// each unfolding `X₍ₙ₎` of the input (modes with rank `None` are not decomposed, Eq. 5.4),
/// and the core `𝒞 = 𝒯 ×ₙ Ǔₙᵀ` over the decomposed modes (Eq. 5.1). Reconstruction is
/// exact when every `rₙ` is at least the multilinear rank of mode `n`.
///
/// # Errors
/// [`Error::SizeMismatch`] if `ranks` has not one entry per mode, [`Error::InvalidParam`]
/// for a rank of 0 or larger than its mode, [`Error::NoConvergence`] if an eigen/SVD solve
/// fails.
pub fn hosvd(x: &Tensor, ranks: &[Option<usize>], method: FactorMethod) -> Result<Tucker> {
    check_ranks(x, ranks)?;
    let mut factors = Vec::with_capacity(ranks.len());
    for (n, rank) in ranks.iter().enumerate() {
        factors.push(match rank {
            Some(r) => Some(leading_factor(x, n, *r, method)?),
            None => None,
        });
    }
    let core = project(x, &factors, None)?;
    Ok(Tucker { core, factors })
}

/// `𝒯 ×ₘ Ǔₘᵀ` over every mode `m ≠ skip` that has a factor.
pub(crate) fn project(
    x: &Tensor,
    factors: &[Option<DMatrix<f64>>],
    skip: Option<usize>,
) -> Result<Tensor> {
    let transposed: Vec<(usize, DMatrix<f64>)> = factors
        .iter()
        .enumerate()
        .filter(|(m, _)| Some(*m) != skip)
        .filter_map(|(m, f)| f.as_ref().map(|f| (m, f.transpose())))
        .collect();
    let products: Vec<(usize, &DMatrix<f64>)> = transposed.iter().map(|(m, f)| (*m, f)).collect();
    x.multi_mode_product(&products)
}

/// The `r` leading left singular vectors of `X₍ₙ₎` (`dₙ × r`, orthonormal), by `method`.
pub(crate) fn leading_factor(
    x: &Tensor,
    n: usize,
    r: usize,
    method: FactorMethod,
) -> Result<DMatrix<f64>> {
    let (left, d, right) = x.split(n)?;
    let others = left * right;
    let method = match method {
        FactorMethod::Auto if d <= others => FactorMethod::Gram,
        FactorMethod::Auto => FactorMethod::Svd,
        m => m,
    };
    let mut u = match method {
        FactorMethod::Gram | FactorMethod::Auto => sym_top_eigen(&x.gram(n)?, r)?.0,
        FactorMethod::Svd => thin_svd_left(&x.unfold(n)?, r)?,
        FactorMethod::Randomized(p) => randomized_range(&x.unfold(n)?, r, p)?,
    };
    // A rank above min(dₙ, J) leaves the SVD short of columns: complete with an orthonormal
    // basis of the rest (any is optimal, the data has no energy there).
    if u.ncols() < r {
        u = complete_basis(&u, r);
    }
    fix_signs(&mut u);
    Ok(u)
}

/// Halko et al. (2011): `Y = X Ω` (`Ω` Gaussian, `r + p` columns), `q` power iterations
/// `Y ← X (Xᵀ Y)` re-orthonormalised by QR, `Q = qr(Y)`, then the `r` leading left singular
/// vectors of the small `B = Qᵀ X` (eigenvectors of `B Bᵀ`) mapped back: `U = Q W`.
fn randomized_range(x: &DMatrix<f64>, r: usize, p: RandomizedParams) -> Result<DMatrix<f64>> {
    let (d, cols) = x.shape();
    let k = (r + p.oversample).min(d).min(cols);
    let rng = SplitMix64::new(p.seed);
    let omega = DMatrix::from_fn(cols, k, |i, j| rng.normal_at((i * k + j) as u64));
    let mut q = thin_q(&matmul(x, false, &omega));
    for _ in 0..p.power_iterations {
        let z = thin_q(&matmul(x, true, &q));
        q = thin_q(&matmul(x, false, &z));
    }
    let b = matmul(&q, true, x);
    let (w, _) = sym_top_eigen(&(&b * b.transpose()), r)?;
    Ok(&q * w)
}

/// `u` (orthonormal columns) extended to `r` orthonormal columns by Gram–Schmidt against the
/// unit vectors.
fn complete_basis(u: &DMatrix<f64>, r: usize) -> DMatrix<f64> {
    let d = u.nrows();
    let mut cols: Vec<nalgebra::DVector<f64>> = u.column_iter().map(|c| c.into_owned()).collect();
    for e in 0..d {
        if cols.len() >= r {
            break;
        }
        let mut v = nalgebra::DVector::zeros(d);
        v[e] = 1.0;
        for _ in 0..2 {
            for c in &cols {
                let dot = c.dot(&v);
                v.axpy(-dot, c, 1.0);
            }
        }
        let norm = v.norm();
        if norm > 1e-6 {
            cols.push(v / norm);
        }
    }
    DMatrix::from_columns(&cols)
}

/// Makes the largest-magnitude entry of each column positive (a deterministic sign, as
/// TensorLy's `svd_flip`; the decomposition itself does not depend on it).
fn fix_signs(u: &mut DMatrix<f64>) {
    for mut c in u.column_iter_mut() {
        let big = c
            .iter()
            .copied()
            .fold(0.0f64, |a, v| if v.abs() > a.abs() { v } else { a });
        if big < 0.0 {
            c.neg_mut();
        }
    }
}
