//! The multilinear face model (§5.3.3, Eq. 5.4–5.5): N-mode SVD of the data tensor without
//! factoring the vertex mode, faces from attribute weights, the linear basis of one attribute
//! with the others fixed (Eq. 5.9), and "dial tuning" (§5.4).

use std::time::Instant;

use nalgebra::{DMatrix, DVector};
use skin_core::math::DVec3;
use skin_core::tensor::{hooi, hosvd, FactorMethod, HooiParams, Tensor};

use crate::face_data::FaceTensor;
use crate::{Error, Result};

/// Parameters of [`MultilinearModel::fit`].
#[derive(Clone, Debug, PartialEq)]
pub struct ModelParams {
    /// Knobs kept per attribute mode (`[expression, identity]` or `[viseme, expression,
    /// identity]`); thesis: 6 expression × 9 identity knobs (bilinear, §5.3.1) and 4 viseme ×
    /// 4 expression × 16 identity knobs (trilinear). Each must be in `1..=dₙ`.
    pub ranks: Vec<usize>,
    /// Refine the truncated N-mode SVD by HOOI (alternating least squares, recommended after
    /// Eq. 5.3). Default `true` with TensorLy's stopping rule ([`HooiParams::default`]).
    pub refine: Option<HooiParams>,
}

impl ModelParams {
    /// The given ranks, HOOI refinement on.
    pub fn new(ranks: &[usize]) -> Self {
        ModelParams {
            ranks: ranks.to_vec(),
            refine: Some(HooiParams::default()),
        }
    }

    /// The thesis's bilinear model: 6 expression × 9 identity knobs.
    pub fn thesis_bilinear() -> Self {
        Self::new(&[6, 9])
    }

    /// The thesis's trilinear model: 4 viseme × 4 expression × 16 identity knobs.
    pub fn thesis_trilinear() -> Self {
        Self::new(&[4, 4, 16])
    }

    /// Without (`None`) or with HOOI refinement.
    pub fn with_refine(mut self, refine: Option<HooiParams>) -> Self {
        self.refine = refine;
        self
    }
}

/// How well a [`MultilinearModel`] reproduces its data.
#[derive(Clone, Debug, PartialEq)]
pub struct ModelFit {
    /// `‖𝒯 − 𝒯̂‖ / ‖𝒯‖` of the truncated N-mode SVD.
    pub hosvd_rel_error: f64,
    /// The same after HOOI (equal to `hosvd_rel_error` without refinement).
    pub hooi_rel_error: f64,
    /// HOOI sweeps run (0 without refinement).
    pub sweeps: usize,
    /// Wall time of the decomposition, ms.
    pub time_ms: f64,
}

/// The multilinear model `ℳ` with its attribute factors `Ǔₙ` (Eq. 5.4): `𝒯 ≈ ℳ ×₂ Ǔ₂ ⋯`.
#[derive(Clone, Debug, PartialEq)]
pub struct MultilinearModel {
    vertex_count: usize,
    core: Tensor,
    factors: Vec<DMatrix<f64>>,
}

impl MultilinearModel {
    /// Decomposes `faces` by the N-mode SVD (Eq. 5.1–5.3) truncated to `params.ranks`,
    /// without factoring the vertex mode (Eq. 5.4), then refines by HOOI if asked.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] for a ranks list whose length is not the number of attribute
    /// modes; [`Error::InvalidParam`] for a rank of 0 or larger than its mode.
    pub fn fit(faces: &FaceTensor, params: &ModelParams) -> Result<(Self, ModelFit)> {
        let sizes = faces.attribute_sizes();
        skin_core::check::same_size(
            "ranks (one per attribute mode)",
            sizes.len(),
            params.ranks.len(),
        )?;
        for (&r, &d) in params.ranks.iter().zip(sizes) {
            if r == 0 || r > d {
                return Err(Error::InvalidParam {
                    name: "ranks",
                    reason: format!("a rank must be in 1..={d} (its mode's size), got {r}"),
                });
            }
        }
        let mut ranks = vec![None];
        ranks.extend(params.ranks.iter().map(|&r| Some(r)));
        let x = faces.tensor();
        let t0 = Instant::now();
        let (tucker, hosvd_rel_error, hooi_rel_error, sweeps) = match &params.refine {
            Some(hp) => {
                let res = hooi(x, &ranks, hp)?;
                let last = res.errors.last().copied().unwrap_or(res.hosvd_error);
                (res.tucker, res.hosvd_error, last, res.errors.len())
            }
            None => {
                let t = hosvd(x, &ranks, FactorMethod::Auto)?;
                let e = x.relative_error(&t.reconstruct()?)?;
                (t, e, e, 0)
            }
        };
        let time_ms = 1e3 * t0.elapsed().as_secs_f64();
        let factors: Vec<DMatrix<f64>> = tucker.factors.into_iter().skip(1).flatten().collect();
        skin_core::check::same_size("model factors", sizes.len(), factors.len())?;
        Ok((
            MultilinearModel {
                vertex_count: faces.vertex_count(),
                core: tucker.core,
                factors,
            },
            ModelFit {
                hosvd_rel_error,
                hooi_rel_error,
                sweeps,
                time_ms,
            },
        ))
    }

    /// The model restricted to some vertices (in the given order): faces of the restricted
    /// model are those vertices of this model's faces.
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`] for a vertex past the model, [`Error::Empty`] for none.
    pub fn restrict(&self, vertices: &[usize]) -> Result<Self> {
        if vertices.is_empty() {
            return Err(Error::Empty { what: "vertices" });
        }
        let block: usize = self.ranks().iter().product();
        let src = self.core.data();
        let mut data = Vec::with_capacity(3 * vertices.len() * block);
        for &v in vertices {
            skin_core::check::index("vertex", v, self.vertex_count)?;
            data.extend_from_slice(&src[3 * v * block..3 * (v + 1) * block]);
        }
        let mut shape = self.core.shape().to_vec();
        shape[0] = 3 * vertices.len();
        Ok(MultilinearModel {
            vertex_count: vertices.len(),
            core: Tensor::new(shape, data)?,
            factors: self.factors.clone(),
        })
    }

    /// Vertices per face.
    pub fn vertex_count(&self) -> usize {
        self.vertex_count
    }

    /// The knobs per attribute mode `[r₁, …]`.
    pub fn ranks(&self) -> &[usize] {
        &self.core.shape()[1..]
    }

    /// The model tensor `ℳ` (`[3V, r₁, …]`).
    pub fn core(&self) -> &Tensor {
        &self.core
    }

    /// `Ǔₙ` of attribute mode `mode` (`dₙ × rₙ`): row `i` holds the weights of the `i`-th
    /// training value of that attribute (e.g. the `i`-th person).
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`] for a mode past the last attribute.
    pub fn factor(&self, mode: usize) -> Result<&DMatrix<f64>> {
        skin_core::check::index("attribute mode", mode, self.factors.len())?;
        Ok(&self.factors[mode])
    }

    /// The weights of training value `index` of attribute `mode` (row of `Ǔₙ`).
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`] for a bad mode or index.
    pub fn training_weights(&self, mode: usize, index: usize) -> Result<DVector<f64>> {
        let u = self.factor(mode)?;
        skin_core::check::index("attribute value", index, u.nrows())?;
        Ok(u.row(index).transpose())
    }

    fn check_weights(&self, weights: &[DVector<f64>], skip: Option<usize>) -> Result<()> {
        skin_core::check::same_size(
            "weight vectors (one per attribute)",
            self.factors.len(),
            weights.len(),
        )?;
        for (n, w) in weights.iter().enumerate() {
            if Some(n) == skip {
                continue;
            }
            skin_core::check::same_size("weights of an attribute", self.ranks()[n], w.len())?;
            skin_core::check::all_finite("weights", w.iter())?;
        }
        Ok(())
    }

    /// `ℳ ×ₙ wₙᵀ` over the modes other than `skip`, as a `3V × (rₛₖᵢₚ or 1)` matrix (weights
    /// already checked), or only the rows of `vertices` (`3 × vertices.len()` rows, in their
    /// order; indices checked). Each row of `ℳ` (one coordinate: its `r₁ × r₂ × ⋯` block,
    /// row-major) is viewed as `outer × rₛₖᵢₚ × inner` (the modes before and after `skip`) and
    /// contracted with the Kronecker product of the other modes' weights, one pass over the
    /// tensor. A row's value does not depend on which other rows are computed.
    fn contract(
        &self,
        weights: &[DVector<f64>],
        skip: Option<usize>,
        vertices: Option<&[usize]>,
    ) -> Result<DMatrix<f64>> {
        let ranks = self.ranks();
        let block: usize = ranks.iter().product();
        let (cols, inner) = match skip {
            Some(m) => (ranks[m], ranks[m + 1..].iter().product::<usize>()),
            None => (1, block),
        };
        let outer = block / (cols * inner);
        // coef[o · inner + i]: the product of the weights of the multi-index (o, i).
        let mut coef = vec![1.0; outer * inner];
        let mut stride = outer * inner;
        for (n, w) in weights.iter().enumerate() {
            if Some(n) == skip {
                continue;
            }
            stride /= ranks[n];
            for (k, c) in coef.iter_mut().enumerate() {
                *c *= w[(k / stride) % ranks[n]];
            }
        }
        let data = self.core.data();
        let rows: Vec<&[f64]> = match vertices {
            None => data.chunks_exact(block).collect(),
            Some(vs) => {
                let mut rows = Vec::with_capacity(3 * vs.len());
                for &v in vs {
                    skin_core::check::index("vertex", v, self.vertex_count)?;
                    rows.extend(data[3 * v * block..3 * (v + 1) * block].chunks_exact(block));
                }
                rows
            }
        };
        let mut out = DMatrix::zeros(rows.len(), cols);
        let mut acc = vec![0.0; cols];
        for (i, row) in rows.into_iter().enumerate() {
            if inner == 1 {
                // `skip` is the last mode: the row is `outer × cols`, a weighted sum of rows.
                acc.fill(0.0);
                for (seg, &c) in row.chunks_exact(cols).zip(&coef) {
                    for (s, &v) in acc.iter_mut().zip(seg) {
                        *s += c * v;
                    }
                }
            } else {
                for (a, s) in acc.iter_mut().enumerate() {
                    *s = coef
                        .chunks_exact(inner)
                        .enumerate()
                        .map(|(o, c)| dot(&row[(o * cols + a) * inner..][..inner], c))
                        .sum();
                }
            }
            for (a, s) in acc.iter().enumerate() {
                out[(i, a)] = *s;
            }
        }
        Ok(out)
    }

    /// A face from one weight vector per attribute (Eq. 5.5):
    /// `f = ℳ ×₂ w₂ᵀ ×₃ w₃ᵀ ⋯`. A row of each `Ǔₙ` reproduces a training face.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] for the wrong number or length of weight vectors,
    /// [`Error::NonFinite`].
    pub fn face(&self, weights: &[DVector<f64>]) -> Result<Vec<DVec3>> {
        self.check_weights(weights, None)?;
        let f = self.contract(weights, None, None)?;
        Ok(f.as_slice()
            .chunks_exact(3)
            .map(|c| DVec3::new(c[0], c[1], c[2]))
            .collect())
    }

    /// The points of `vertices` (in their order) of the face of `weights`: the same values as
    /// those rows of [`MultilinearModel::face`], without computing the others.
    pub(crate) fn face_points(
        &self,
        weights: &[DVector<f64>],
        vertices: &[usize],
    ) -> Result<Vec<[f64; 3]>> {
        self.check_weights(weights, None)?;
        let f = self.contract(weights, None, Some(vertices))?;
        Ok(f.as_slice()
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2]])
            .collect())
    }

    /// The linear basis `Mₘ` of attribute `mode` with every other attribute fixed (Eq. 5.9):
    /// `3V × rₘ`, so that the face is `Mₘ wₘ` (the entry `weights[mode]` is ignored).
    ///
    /// # Errors
    /// As [`MultilinearModel::face`]; [`Error::IndexOutOfRange`] for a bad mode.
    pub fn linear_basis(&self, mode: usize, weights: &[DVector<f64>]) -> Result<DMatrix<f64>> {
        skin_core::check::index("attribute mode", mode, self.factors.len())?;
        self.check_weights(weights, Some(mode))?;
        self.contract(weights, Some(mode), None)
    }

    /// The rows of [`MultilinearModel::linear_basis`] of `vertices` only (`3 ×
    /// vertices.len()` rows: vertex `vertices[k]` in rows `3k..3k + 3`), the same values.
    pub(crate) fn linear_basis_rows(
        &self,
        mode: usize,
        weights: &[DVector<f64>],
        vertices: &[usize],
    ) -> Result<DMatrix<f64>> {
        skin_core::check::index("attribute mode", mode, self.factors.len())?;
        self.check_weights(weights, Some(mode))?;
        self.contract(weights, Some(mode), Some(vertices))
    }
}

/// `Σ aᵢ bᵢ` over equal-length slices, four partial sums (no serial chain of additions).
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut acc = [0.0f64; 4];
    let (a4, b4) = (a.chunks_exact(4), b.chunks_exact(4));
    let tail: f64 = a4
        .remainder()
        .iter()
        .zip(b4.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in a4.zip(b4) {
        for k in 0..4 {
            acc[k] += x[k] * y[k];
        }
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

/// Dial tuning (§5.4): a linear transform of one attribute's weights so that the dials are
/// named attributes (e.g. "smile", "brow raise") instead of the N-mode SVD's directions of
/// most variance — `w = w̄ + B a`, fitted in the least-squares sense to the training values of
/// that attribute and their labels (as Allen et al. do for height and weight).
#[derive(Clone, Debug, PartialEq)]
pub struct Dials {
    mode: usize,
    offset: DVector<f64>,
    map: DMatrix<f64>,
    residual: f64,
}

impl Dials {
    /// Fits the transform for attribute `mode` from `labels` (`dₙ × A`: row `i` holds the
    /// named attribute values of training value `i`, e.g. how much smile and frown the `i`-th
    /// expression has).
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if `labels` does not have `dₙ` rows, [`Error::Empty`] for no
    /// label column, [`Error::NonFinite`]; [`Error::IndexOutOfRange`] for a bad mode.
    pub fn fit(model: &MultilinearModel, mode: usize, labels: &DMatrix<f64>) -> Result<Self> {
        let u = model.factor(mode)?;
        skin_core::check::same_size(
            "label rows (one per training value)",
            u.nrows(),
            labels.nrows(),
        )?;
        if labels.ncols() == 0 {
            return Err(Error::Empty { what: "labels" });
        }
        skin_core::check::all_finite("labels", labels.iter())?;
        // [1 a] [w̄ B]ᵀ = U in the least-squares sense (minimum norm when underdetermined).
        let a = DMatrix::from_fn(labels.nrows(), labels.ncols() + 1, |i, j| {
            if j == 0 {
                1.0
            } else {
                labels[(i, j - 1)]
            }
        });
        let svd = a.clone().svd(true, true);
        let coef = svd
            .solve(u, 1e-12 * svd.singular_values.max())
            .map_err(|reason| Error::InvalidParam {
                name: "labels",
                reason: reason.into(),
            })?;
        let residual = (&a * &coef - u).norm() / u.norm().max(f64::MIN_POSITIVE);
        Ok(Dials {
            mode,
            offset: coef.row(0).transpose(),
            map: coef.rows(1, labels.ncols()).transpose(),
            residual,
        })
    }

    /// The attribute mode the dials drive.
    pub fn mode(&self) -> usize {
        self.mode
    }

    /// Relative residual of the fit `‖[1 A][w̄ B]ᵀ − Ǔₙ‖ / ‖Ǔₙ‖` (0 when the labels explain
    /// every training value).
    pub fn residual(&self) -> f64 {
        self.residual
    }

    /// The weights `w̄ + B a` for dial settings `a`.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] for the wrong number of dials, [`Error::NonFinite`].
    pub fn weights(&self, dials: &[f64]) -> Result<DVector<f64>> {
        skin_core::check::same_size("dials", self.map.ncols(), dials.len())?;
        skin_core::check::all_finite("dials", dials.iter())?;
        Ok(&self.offset + &self.map * DVector::from_column_slice(dials))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Faces exactly bilinear in (expression, identity): f(e, i) = Σ a_e b_i B_ab.
    fn bilinear_faces(d_e: usize, d_i: usize, v: usize) -> FaceTensor {
        let faces: Vec<Vec<DVec3>> = (0..d_e * d_i)
            .map(|f| {
                let (e, i) = ((f / d_i) as f64, (f % d_i) as f64);
                (0..v)
                    .map(|k| {
                        let k = k as f64;
                        let a = [1.0, (0.3 * e).sin()];
                        let b = [1.0, (0.7 * i).cos(), 0.1 * i];
                        DVec3::new(
                            k + a[1] * b[1] * (0.2 * k).sin(),
                            a[0] * b[2] * k.cos() + a[1] * b[0],
                            a[1] * b[2] + (0.1 * k).cos() * b[1],
                        )
                    })
                    .collect()
            })
            .collect();
        FaceTensor::from_faces(&[d_e, d_i], &faces).unwrap()
    }

    #[test]
    fn exact_ranks_reproduce_every_training_face() {
        let t = bilinear_faces(5, 6, 30);
        let (m, fit) = MultilinearModel::fit(&t, &ModelParams::new(&[2, 3])).unwrap();
        // (errors from the core norm resolve down to ≈ 1e-8 only)
        assert!(
            fit.hosvd_rel_error < 1e-6 && fit.hooi_rel_error < 1e-6,
            "{fit:?}"
        );
        for f in [0, 7, 29] {
            let w = vec![
                m.training_weights(0, f / 6).unwrap(),
                m.training_weights(1, f % 6).unwrap(),
            ];
            let got = m.face(&w).unwrap();
            let want = t.face(f).unwrap();
            let err = got
                .iter()
                .zip(&want)
                .map(|(a, b)| a.distance(*b))
                .fold(0.0, f64::max);
            assert!(err < 1e-9, "face {f}: {err}");
            // Eq. 5.9: the linear basis of identity with expression fixed gives the same face.
            let basis = m.linear_basis(1, &w).unwrap();
            let lin = &basis * &w[1];
            assert!((lin[3 * 5 + 1] - want[5].y).abs() < 1e-9);
        }
    }

    #[test]
    fn truncation_errs_and_bad_ranks_are_errors() {
        let t = bilinear_faces(5, 6, 30);
        let (_, fit) = MultilinearModel::fit(&t, &ModelParams::new(&[1, 1])).unwrap();
        assert!(fit.hosvd_rel_error > 1e-4);
        assert!(fit.hooi_rel_error <= fit.hosvd_rel_error + 1e-12);
        for ranks in [vec![6, 3], vec![0, 3], vec![2]] {
            assert!(MultilinearModel::fit(&t, &ModelParams::new(&ranks)).is_err());
        }
        let (m, _) = MultilinearModel::fit(&t, &ModelParams::new(&[2, 3])).unwrap();
        let bad = vec![DVector::zeros(2), DVector::zeros(2)];
        assert!(matches!(m.face(&bad), Err(Error::Core(_))));
        assert!(m.linear_basis(2, &bad).is_err());
    }

    #[test]
    fn a_restricted_model_gives_the_same_vertices() {
        let t = bilinear_faces(5, 6, 30);
        let (m, _) = MultilinearModel::fit(&t, &ModelParams::new(&[2, 3])).unwrap();
        let sub = m.restrict(&[7, 2, 29]).unwrap();
        let w = vec![
            m.training_weights(0, 4).unwrap(),
            m.training_weights(1, 1).unwrap(),
        ];
        let (full, part) = (m.face(&w).unwrap(), sub.face(&w).unwrap());
        assert_eq!(part, vec![full[7], full[2], full[29]]);
        // Some rows only: the same values as those of the whole face and basis.
        let points = m.face_points(&w, &[7, 2, 29]).unwrap();
        assert_eq!(
            points,
            vec![full[7].to_array(), full[2].to_array(), full[29].to_array()]
        );
        for mode in 0..2 {
            let (basis, rows) = (
                m.linear_basis(mode, &w).unwrap(),
                m.linear_basis_rows(mode, &w, &[7, 2, 29]).unwrap(),
            );
            for (k, v) in [7, 2, 29].into_iter().enumerate() {
                assert_eq!(rows.rows(3 * k, 3), basis.rows(3 * v, 3));
            }
        }
        assert!(m.face_points(&w, &[30]).is_err());
        assert!(m.linear_basis_rows(0, &w, &[30]).is_err());
        assert!(m.restrict(&[30]).is_err());
        assert!(m.restrict(&[]).is_err());
    }

    #[test]
    fn dials_reach_the_labelled_training_values() {
        let t = bilinear_faces(5, 6, 30);
        let (m, _) = MultilinearModel::fit(&t, &ModelParams::new(&[2, 3])).unwrap();
        // Label each expression by sin(0.3 e): exactly what its weights depend on.
        let labels = DMatrix::from_fn(5, 1, |e, _| (0.3 * e as f64).sin());
        let dials = Dials::fit(&m, 0, &labels).unwrap();
        assert!(dials.residual() < 1e-9, "{}", dials.residual());
        let w = dials.weights(&[(0.9f64).sin()]).unwrap();
        assert!((w - m.training_weights(0, 3).unwrap()).norm() < 1e-9);
        assert!(dials.weights(&[f64::NAN]).is_err());
        assert!(Dials::fit(&m, 0, &DMatrix::zeros(4, 1)).is_err());
    }
}
