//! The dense N-mode tensor: shape, row-major storage, constructors, norms.

use crate::{check, Error, Result};

/// A dense N-mode tensor of `f64` (Vlasic §5.2 "Tensors": a block of data indexed by `N`
/// indices, `𝒯 = (t_{i₁ i₂ … i_N})`).
///
/// **Layout: row-major (C order)**, the last index varies fastest: element `(i₀, …, i_{N−1})`
/// of a tensor of shape `(d₀, …, d_{N−1})` is at `Σₖ iₖ · Πⱼ₍ⱼ₎₌ₖ₊₁ dⱼ`. For mode `n` the
/// buffer is therefore an `L × dₙ × R` block (`L = Π_{k<n} dₖ`, `R = Π_{k>n} dₖ`) in which
/// every `l` holds one contiguous `dₙ × R` slab: the mode-`n` product, the Gram matrix of an
/// unfolding and the unfolding itself all stream through contiguous rows of length `R`, and
/// the layout is NumPy's/TensorLy's, so the peer benchmarks' inputs (filled in row-major
/// order) are generated straight into the buffer.
///
/// Every value is finite and every mode has size ≥ 1 (checked by the constructors).
#[derive(Clone, Debug, PartialEq)]
pub struct Tensor {
    shape: Vec<usize>,
    data: Vec<f64>,
}

impl Tensor {
    /// A tensor of the given shape from its row-major `data`.
    ///
    /// # Errors
    /// [`Error::Empty`] for an empty shape or a mode of size 0, [`Error::SizeMismatch`] if
    /// `data.len()` is not the product of the shape, [`Error::NonFinite`] for NaN or ±∞.
    pub fn new(shape: Vec<usize>, data: Vec<f64>) -> Result<Self> {
        let len = checked_len(&shape)?;
        check::same_size("tensor data (product of the shape)", len, data.len())?;
        check::all_finite("tensor data", &data)?;
        Ok(Self { shape, data })
    }

    /// The tensor of the given shape filled with zeros.
    ///
    /// # Errors
    /// [`Error::Empty`] for an empty shape or a mode of size 0.
    pub fn zeros(shape: Vec<usize>) -> Result<Self> {
        let len = checked_len(&shape)?;
        Ok(Self {
            shape,
            data: vec![0.0; len],
        })
    }

    /// The tensor whose element at multi-index `idx` is `f(idx)`, filled in row-major order.
    ///
    /// # Errors
    /// As [`Tensor::new`].
    pub fn from_fn(shape: Vec<usize>, mut f: impl FnMut(&[usize]) -> f64) -> Result<Self> {
        let len = checked_len(&shape)?;
        let mut data = Vec::with_capacity(len);
        let mut idx = vec![0; shape.len()];
        for _ in 0..len {
            data.push(f(&idx));
            for k in (0..shape.len()).rev() {
                idx[k] += 1;
                if idx[k] < shape[k] {
                    break;
                }
                idx[k] = 0;
            }
        }
        Self::new(shape, data)
    }

    /// Internal constructor for buffers produced by the module's own algebra (shape checked
    /// by the caller, values finite because the inputs were).
    pub(crate) fn from_parts(shape: Vec<usize>, data: Vec<f64>) -> Self {
        debug_assert_eq!(shape.iter().product::<usize>(), data.len());
        Self { shape, data }
    }

    /// The size of each mode.
    pub fn shape(&self) -> &[usize] {
        &self.shape
    }

    /// The number of modes `N`.
    pub fn order(&self) -> usize {
        self.shape.len()
    }

    /// The row-major buffer.
    pub fn data(&self) -> &[f64] {
        &self.data
    }

    /// Consumes the tensor, returning its row-major buffer.
    pub fn into_data(self) -> Vec<f64> {
        self.data
    }

    /// The number of elements.
    pub fn len(&self) -> usize {
        self.data.len()
    }

    /// Always `false`: a tensor has at least one element.
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    /// The element at multi-index `idx`.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if `idx` has not `N` entries, [`Error::IndexOutOfRange`] if an
    /// entry is outside its mode.
    pub fn get(&self, idx: &[usize]) -> Result<f64> {
        check::same_size("tensor index length", self.order(), idx.len())?;
        let mut offset = 0;
        for (&i, &d) in idx.iter().zip(&self.shape) {
            offset = offset * d + check::index("tensor index", i, d)?;
        }
        Ok(self.data[offset])
    }

    /// The Frobenius norm `‖𝒯‖ = sqrt(Σ t²)`.
    pub fn norm(&self) -> f64 {
        self.data.iter().map(|v| v * v).sum::<f64>().sqrt()
    }

    /// `‖self − other‖ / ‖other‖`, the relative Frobenius error of `self` as an approximation
    /// of `other` (0 when both are zero).
    ///
    /// # Errors
    /// [`Error::InvalidParam`] if the shapes differ.
    pub fn relative_error(&self, other: &Tensor) -> Result<f64> {
        same_shape("tensor shapes", &self.shape, &other.shape)?;
        let diff = self
            .data
            .iter()
            .zip(&other.data)
            .map(|(a, b)| (a - b) * (a - b))
            .sum::<f64>()
            .sqrt();
        let norm = other.norm();
        Ok(if norm > 0.0 { diff / norm } else { diff })
    }

    /// `(L, dₙ, R)`: the product of the sizes before mode `n`, mode `n`'s size and the product
    /// of the sizes after it (the `L × dₙ × R` block view of the buffer).
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`] if `n ≥ N`.
    pub fn split(&self, n: usize) -> Result<(usize, usize, usize)> {
        check::index("mode", n, self.order())?;
        let left = self.shape[..n].iter().product();
        let right = self.shape[n + 1..].iter().product();
        Ok((left, self.shape[n], right))
    }
}

/// The product of the shape, checking it is non-empty and has no zero mode.
fn checked_len(shape: &[usize]) -> Result<usize> {
    if shape.is_empty() {
        return Err(Error::Empty {
            what: "tensor shape",
        });
    }
    if shape.contains(&0) {
        return Err(Error::Empty {
            what: "tensor mode (a mode of size 0)",
        });
    }
    shape
        .iter()
        .try_fold(1usize, |acc, &d| acc.checked_mul(d))
        .ok_or_else(|| Error::InvalidParam {
            name: "tensor shape",
            reason: format!("{shape:?} has more elements than fit in memory"),
        })
}

/// `Ok` if the two shapes are equal, else [`Error::InvalidParam`] naming both.
pub(crate) fn same_shape(name: &'static str, a: &[usize], b: &[usize]) -> Result<()> {
    if a == b {
        Ok(())
    } else {
        Err(Error::InvalidParam {
            name,
            reason: format!("shapes differ: {a:?} vs {b:?}"),
        })
    }
}
