//! The residuals' principal subspace from one pass over a stream: Frequent Directions
//! (Liberty 2013; Ghashami et al. 2016).

use nalgebra::{DMatrix, DVector, SymmetricEigen};

/// A Frequent Directions sketch of a stream of `d`-vectors: `ℓ` rows `B` such that
/// `‖AᵀA − BᵀB‖₂ ≤ ‖A − A_k‖²_F / (ℓ − k)` for the stream `A` and any rank `k < ℓ`, so its
/// top right singular vectors span the stream's principal subspace. Memory is `d × ℓ`
/// whatever the stream's length; each row costs `O(d ℓ)` amortised (an `ℓ × ℓ`
/// eigendecomposition of the Gram matrix and two `d × ℓ` products every `ℓ / 2` rows).
#[derive(Debug, Clone)]
pub(crate) struct FrequentDirections {
    /// The sketch's rows as columns (`d × ℓ`).
    rows: DMatrix<f64>,
    /// Rows in use.
    used: usize,
    /// Their Gram matrix `B Bᵀ` (`ℓ × ℓ`), kept up to date row by row: after a shrink it is
    /// diagonal (the rows are then orthogonal), so it never needs recomputing from `B`.
    gram: DMatrix<f64>,
}

impl FrequentDirections {
    pub(crate) fn new(d: usize, ell: usize) -> Self {
        FrequentDirections {
            rows: DMatrix::zeros(d, ell),
            used: 0,
            gram: DMatrix::zeros(ell, ell),
        }
    }

    pub(crate) fn push(&mut self, row: &[f64]) {
        if self.used == self.rows.ncols() {
            self.shrink();
        }
        let i = self.used;
        self.rows.column_mut(i).copy_from_slice(row);
        let new = self.rows.column(i);
        for j in 0..=i {
            let g = self.rows.column(j).dot(&new);
            self.gram[(i, j)] = g;
            self.gram[(j, i)] = g;
        }
        self.used += 1;
    }

    /// The eigenpairs of the sketch's Gram matrix `B Bᵀ`, largest first.
    fn gram_eigen(&self) -> (DVector<f64>, DMatrix<f64>) {
        let eigen =
            SymmetricEigen::new(self.gram.view((0, 0), (self.used, self.used)).into_owned());
        let mut order: Vec<usize> = (0..eigen.eigenvalues.len()).collect();
        order.sort_by(|&i, &j| eigen.eigenvalues[j].total_cmp(&eigen.eigenvalues[i]));
        let values =
            DVector::from_iterator(order.len(), order.iter().map(|&i| eigen.eigenvalues[i]));
        let vectors = eigen.eigenvectors.select_columns(&order);
        (values, vectors)
    }

    /// Shrinks every squared singular value by the median one: half the rows become zero.
    fn shrink(&mut self) {
        let (values, vectors) = self.gram_eigen();
        let half = self.used / 2;
        let delta = values[half].max(0.0);
        let mut scaled = vectors.columns(0, half).into_owned();
        for (i, mut c) in scaled.column_iter_mut().enumerate() {
            let s = values[i];
            let f = if s > 0.0 {
                ((s - delta).max(0.0) / s).sqrt()
            } else {
                0.0
            };
            c *= f;
        }
        let kept = self.rows.columns(0, self.used) * scaled;
        self.rows.fill(0.0);
        self.rows.columns_mut(0, half).copy_from(&kept);
        self.gram.fill(0.0);
        for i in 0..half {
            self.gram[(i, i)] = (values[i] - delta).max(0.0);
        }
        self.used = half;
    }

    /// The top `k` directions (orthonormal columns, `d × k'` with `k' ≤ k`: only directions
    /// with a positive singular value) and their squared singular values.
    pub(crate) fn basis(&self, k: usize) -> (DMatrix<f64>, Vec<f64>) {
        if self.used == 0 {
            return (DMatrix::zeros(self.rows.nrows(), 0), Vec::new());
        }
        let (values, vectors) = self.gram_eigen();
        let top = values[0].max(0.0);
        let keep = (0..k.min(self.used))
            .take_while(|&i| values[i] > 1e-12 * top && values[i] > 0.0)
            .count();
        // `B uᵢ / √λᵢ` are orthonormal up to rounding in the kept Gram matrix; a QR
        // factorisation (Gram–Schmidt order: each span of the leading directions kept) makes
        // them orthonormal to the last bit.
        let v = self.rows.columns(0, self.used) * vectors.columns(0, keep);
        let q = v.qr().q();
        (q, values.iter().take(keep).copied().collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_sketch_finds_a_low_rank_streams_subspace() {
        // 200 rows of dimension 50 in a 3-dimensional subspace, plus small noise.
        let d = 50;
        let basis = DMatrix::from_fn(d, 3, |i, j| ((i * (j + 2)) as f64 * 0.37).sin());
        let mut sketch = FrequentDirections::new(d, 8);
        let mut seed = 1u64;
        let mut next = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        for _ in 0..200 {
            let c = DVector::from_fn(3, |_, _| next());
            let row: Vec<f64> = (&basis * c).iter().map(|x| x + 1e-6 * next()).collect();
            sketch.push(&row);
        }
        let (u, values) = sketch.basis(3);
        assert_eq!(u.ncols(), 3);
        assert!(values.iter().all(|&v| v > 0.0));
        // Every true direction lies in the found span.
        for j in 0..3 {
            let b = basis.column(j);
            let inside = &u * (u.tr_mul(&b));
            assert!((b - inside).norm() < 1e-4 * b.norm());
        }
        assert!((u.tr_mul(&u) - DMatrix::identity(3, 3)).norm() < 1e-12);
    }
}
