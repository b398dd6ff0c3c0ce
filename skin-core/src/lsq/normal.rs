//! Assembly of the normal matrix `N = Σ_t w_t M_tᵀ M_t` (lower triangle) with a precomputed
//! pattern and scatter map, so a numeric refactorisation only re-multiplies values.
//!
//! For each term `M` (CSC, m × n) and each row `r`, every pair of non-zeros `(r, i)`, `(r, j)`
//! with `i ≥ j` contributes `M_ri M_rj` to `N_ij`. The analysis enumerates these products once
//! (Gustavson-style, column by column of `N` with a marker array) and stores for each product
//! the two value positions in `M` and the target position in `N`, grouped by target column,
//! so the refactorisation streams through memory.

use nalgebra_sparse::CscMatrix;

use crate::{Error, Result};

/// One product `N[target] += w · M.values[a] · M.values[b]`.
#[derive(Debug, Clone, Copy)]
struct Product {
    a: u32,
    b: u32,
    target: u32,
}

/// The lower-triangle pattern of `N` and, per term, the products that fill it.
#[derive(Debug, Clone)]
pub(crate) struct NormalPattern {
    /// Order `n` of `N`.
    pub n: usize,
    /// CSC column pointers of the lower triangle of `N` (diagonal always present).
    pub col_ptr: Vec<usize>,
    /// Sorted row indices of the lower triangle of `N`.
    pub row_idx: Vec<usize>,
    /// Products of each term, in the order of the terms given to [`NormalPattern::new`].
    products: Vec<Vec<Product>>,
}

/// Row-wise index of a CSC matrix: for each row, the (column, value position) pairs.
struct RowIndex {
    row_ptr: Vec<usize>,
    col: Vec<u32>,
    pos: Vec<u32>,
}

impl RowIndex {
    fn new(m: &CscMatrix<f64>) -> Self {
        let mut row_ptr = vec![0usize; m.nrows() + 1];
        for &r in m.row_indices() {
            row_ptr[r + 1] += 1;
        }
        for r in 0..m.nrows() {
            row_ptr[r + 1] += row_ptr[r];
        }
        let mut next = row_ptr.clone();
        let mut col = vec![0u32; m.nnz()];
        let mut pos = vec![0u32; m.nnz()];
        let offsets = m.col_offsets();
        for j in 0..m.ncols() {
            for p in offsets[j]..offsets[j + 1] {
                let r = m.row_indices()[p];
                // Columns are visited in increasing order, so each row's list is sorted.
                col[next[r]] = j as u32;
                pos[next[r]] = p as u32;
                next[r] += 1;
            }
        }
        Self { row_ptr, col, pos }
    }
}

impl NormalPattern {
    /// Analyses the terms `M_t` (all with `n` columns; checked by the caller).
    ///
    /// # Errors
    /// [`Error::InvalidParam`] if a term or `N` has more than `u32::MAX` non-zeros (the
    /// scatter map stores 32-bit positions to halve its memory traffic).
    pub fn new(n: usize, terms: &[&CscMatrix<f64>]) -> Result<Self> {
        let limit = u32::MAX as usize;
        if n > limit || terms.iter().any(|m| m.nnz() > limit) {
            return Err(Error::InvalidParam {
                name: "terms",
                reason: format!("more than {limit} non-zeros are not supported"),
            });
        }
        let rows: Vec<RowIndex> = terms.iter().map(|m| RowIndex::new(m)).collect();
        let mut col_ptr = Vec::with_capacity(n + 1);
        let mut row_idx: Vec<usize> = Vec::new();
        let mut products: Vec<Vec<Product>> = terms.iter().map(|_| Vec::new()).collect();
        // marker[i] == j  <=>  row i already in column j of N; slot[i] = its position.
        let mut marker = vec![usize::MAX; n];
        let mut slot = vec![0usize; n];
        let mut col_rows: Vec<usize> = Vec::new();
        col_ptr.push(0);
        for j in 0..n {
            col_rows.clear();
            col_rows.push(j);
            marker[j] = j;
            for (m, ri) in terms.iter().zip(&rows) {
                let offsets = m.col_offsets();
                for &r in &m.row_indices()[offsets[j]..offsets[j + 1]] {
                    for &i in &ri.col[ri.row_ptr[r]..ri.row_ptr[r + 1]] {
                        let i = i as usize;
                        if i >= j && marker[i] != j {
                            marker[i] = j;
                            col_rows.push(i);
                        }
                    }
                }
            }
            col_rows.sort_unstable();
            let base = row_idx.len();
            for (k, &i) in col_rows.iter().enumerate() {
                slot[i] = base + k;
            }
            row_idx.extend_from_slice(&col_rows);
            if row_idx.len() > limit {
                return Err(Error::InvalidParam {
                    name: "terms",
                    reason: format!("normal matrix has more than {limit} non-zeros"),
                });
            }
            for ((m, ri), prods) in terms.iter().zip(&rows).zip(products.iter_mut()) {
                let offsets = m.col_offsets();
                for a in offsets[j]..offsets[j + 1] {
                    let r = m.row_indices()[a];
                    for q in ri.row_ptr[r]..ri.row_ptr[r + 1] {
                        let i = ri.col[q] as usize;
                        if i >= j {
                            prods.push(Product {
                                a: a as u32,
                                b: ri.pos[q],
                                target: slot[i] as u32,
                            });
                        }
                    }
                }
            }
            col_ptr.push(row_idx.len());
        }
        Ok(Self {
            n,
            col_ptr,
            row_idx,
            products,
        })
    }

    /// Number of stored lower-triangle entries of `N`.
    pub fn nnz(&self) -> usize {
        self.row_idx.len()
    }

    /// Fills `out` (length `nnz`) with the values of `Σ_t w_t M_tᵀ M_t`. `terms` must have
    /// the patterns given to [`NormalPattern::new`] (checked by the caller).
    pub fn assemble(&self, terms: &[&CscMatrix<f64>], weights: &[f64], out: &mut [f64]) {
        out.fill(0.0);
        for ((m, prods), &w) in terms.iter().zip(&self.products).zip(weights) {
            let v = m.values();
            for p in prods {
                out[p.target as usize] += w * v[p.a as usize] * v[p.b as usize];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DMatrix;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    use crate::lsq::test_util::random_sparse;

    #[test]
    fn assembled_values_match_dense_products() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for _ in 0..5 {
            let n = 12;
            let a = random_sparse(&mut rng, 20, n, 0.2);
            let c = random_sparse(&mut rng, 5, n, 0.3);
            let w = [1.0, 7.5];
            let pat = NormalPattern::new(n, &[&a, &c]).unwrap();
            let mut vals = vec![0.0; pat.nnz()];
            pat.assemble(&[&a, &c], &w, &mut vals);
            let (da, dc) = (DMatrix::from(&a), DMatrix::from(&c));
            let expect = da.transpose() * &da + dc.transpose() * &dc * w[1];
            let mut got = DMatrix::zeros(n, n);
            for j in 0..n {
                let r = pat.col_ptr[j]..pat.col_ptr[j + 1];
                for (&i, &v) in pat.row_idx[r.clone()].iter().zip(&vals[r]) {
                    assert!(i >= j);
                    got[(i, j)] = v;
                }
            }
            for j in 0..n {
                for i in j..n {
                    assert!((got[(i, j)] - expect[(i, j)]).abs() < 1e-12);
                }
            }
        }
    }
}
