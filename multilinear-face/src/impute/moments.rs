//! What every imputation of §5.3.4 here reduces to. Faces are missing whole, so a fill is the
//! same affine map in every slice of the data along the vertex mode (one coordinate of all
//! faces); and the fit of a PPCA model, or the error of a fill on known faces, needs only the
//! known faces' first and second moments over those slices — `O(K²)` numbers, whatever the
//! vertex count.

use nalgebra::{DMatrix, DVector};
use skin_core::tensor::Tensor;

use crate::face_data::{FaceTensor, KnownFaces};
use crate::Result;

/// The missing faces as an affine function of the known ones, the same in every vertex slice
/// `r`: `x_m,r = μ_r + a + B (x_o,r − μ_r)`, `μ_r` the known faces' mean in slice `r`. Rows
/// follow [`KnownFaces::missing`], columns [`KnownFaces::known`].
#[derive(Clone, Debug)]
pub(super) struct AffineFill {
    /// Offset per missing face.
    pub(super) a: DVector<f64>,
    /// Weights of the known faces, `m × o`.
    pub(super) b: DMatrix<f64>,
}

/// The known faces' data centred by their mean face: the mean face `μ` (`3V`) and the
/// `3V × o` matrix (a `[3V, o]` tensor) of `x_o,r − μ_r`.
pub(super) struct CentredKnown {
    mean_face: Vec<f64>,
    data: Tensor,
}

impl CentredKnown {
    /// The known faces of `faces` (in [`KnownFaces::known`] order), centred.
    pub(super) fn new(faces: &FaceTensor, known: &KnownFaces) -> Result<Self> {
        let observed = known.known();
        let k = faces.face_count();
        let mean_face = faces.mean_of(&observed);
        let rows = mean_face.len();
        let mut data = Vec::with_capacity(rows * observed.len());
        for (row, mu) in faces.tensor().data().chunks_exact(k).zip(&mean_face) {
            data.extend(observed.iter().map(|&f| row[f] - mu));
        }
        Ok(CentredKnown {
            mean_face,
            data: Tensor::new(vec![rows, observed.len()], data)?,
        })
    }

    /// `faces` with its missing faces replaced by `fill` (known faces untouched).
    pub(super) fn apply(
        &self,
        faces: &FaceTensor,
        known: &KnownFaces,
        fill: &AffineFill,
    ) -> Result<FaceTensor> {
        let missing = known.missing();
        if missing.is_empty() {
            return Ok(faces.clone());
        }
        let k = faces.face_count();
        let m = missing.len();
        let filled = self.data.mode_product(1, &fill.b)?;
        let mut data = faces.tensor().data().to_vec();
        for ((row, new), mu) in data
            .chunks_exact_mut(k)
            .zip(filled.data().chunks_exact(m))
            .zip(&self.mean_face)
        {
            for (i, &f) in missing.iter().enumerate() {
                row[f] = mu + fill.a[i] + new[i];
            }
        }
        FaceTensor::from_tensor(Tensor::new(faces.tensor().shape().to_vec(), data)?)
    }
}

/// The first and second moments over the `R = 3V` vertex slices of known faces centred by
/// their own mean face: `mean = Yᵀ 1 / R`, `gram = Yᵀ Y / R` (`Y` the `R × o` centred data).
#[derive(Clone, Debug)]
pub(super) struct Moments {
    pub(super) mean: DVector<f64>,
    pub(super) gram: DMatrix<f64>,
}

impl Moments {
    /// The moments of centred known faces.
    pub(super) fn new(centred: &CentredKnown) -> Result<Self> {
        let shape = centred.data.shape();
        let (rows, o) = (shape[0], shape[1]);
        let nr = rows as f64;
        let gram = centred.data.gram(1)? / nr;
        let mut mean = DVector::zeros(o);
        for row in centred.data.data().chunks_exact(o) {
            for (m, x) in mean.iter_mut().zip(row) {
                *m += x / nr;
            }
        }
        Ok(Moments { mean, gram })
    }

    /// The moments of a subset of these faces (positions, ascending), re-centred by the
    /// subset's own mean face: with `C = I − 11ᵀ/n'`, `gram' = C G_SS C`, `mean' = C mean_S`.
    pub(super) fn subset(&self, keep: &[usize]) -> Moments {
        let n = keep.len();
        let g = DMatrix::from_fn(n, n, |i, j| self.gram[(keep[i], keep[j])]);
        let mean = DVector::from_fn(n, |i, _| self.mean[keep[i]]);
        let inv = 1.0 / n.max(1) as f64;
        let col: DVector<f64> = g.row_sum().transpose() * inv;
        let all = col.sum() * inv;
        let gram = DMatrix::from_fn(n, n, |i, j| g[(i, j)] - col[i] - col[j] + all);
        let mean = mean.add_scalar(-mean.sum() * inv);
        Moments { mean, gram }
    }

    /// `Σ_t Σ_r err²_t,r / R` for the faces at positions `targets`
    /// (ascending, disjoint from `keep`), predicted by `fill` from the faces at positions
    /// `keep` (ascending): the fill of the problem whose known faces are `keep` and whose
    /// missing faces include `targets`, at rows `rows[t]`. The fill works on data centred by
    /// the `keep` faces' mean face, these moments by another; the difference cancels:
    /// `err_t = a_t + v_tᵀ y` with `v_t = B_t + (1 − ΣB_t)/n'` on `keep` and `−1` at `t`.
    pub(super) fn fill_error(
        &self,
        keep: &[usize],
        targets: &[usize],
        rows: &[usize],
        fill: &AffineFill,
    ) -> f64 {
        let n = keep.len() as f64;
        let mut err = 0.0;
        let mut v = DVector::zeros(self.mean.len());
        for (&t, &i) in targets.iter().zip(rows) {
            let bt = fill.b.row(i);
            let shift = (1.0 - bt.sum()) / n;
            v.fill(0.0);
            for (j, &p) in keep.iter().enumerate() {
                v[p] = bt[j] + shift;
            }
            v[t] -= 1.0;
            let a = fill.a[i];
            err += a * a + 2.0 * a * v.dot(&self.mean) + (&self.gram * &v).dot(&v);
        }
        err.max(0.0)
    }

    /// `Σ_t Σ_r y²_t,r / R` for the faces at positions `targets`: their squared distance to
    /// the mean face these moments are centred by.
    pub(super) fn spread(&self, targets: &[usize]) -> f64 {
        targets.iter().map(|&t| self.gram[(t, t)]).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use skin_core::math::DVec3;

    #[test]
    fn subset_moments_and_fill_errors_match_the_data() {
        // 2 × 3 faces of 4 vertices; known: all but face 4.
        let faces: Vec<Vec<DVec3>> = (0..6)
            .map(|f| {
                (0..4)
                    .map(|v| {
                        let (f, v) = (f as f64, v as f64);
                        DVec3::new((f * 0.7 + v).sin(), f * v * 0.1, (f - v).cos())
                    })
                    .collect()
            })
            .collect();
        let t = FaceTensor::from_faces(&[2, 3], &faces).unwrap();
        let known = KnownFaces::new(&[2, 3], vec![true, true, true, true, false, true]).unwrap();
        let centred = CentredKnown::new(&t, &known).unwrap();
        let all = Moments::new(&centred).unwrap();
        // Known faces 0, 1, 2, 3, 5 at positions 0..5; keep 0, 1, 3, 5 (positions 0, 1, 3, 4).
        let keep = [0, 1, 3, 4];
        let sub_known =
            KnownFaces::new(&[2, 3], vec![true, true, false, true, false, true]).unwrap();
        let direct = Moments::new(&CentredKnown::new(&t, &sub_known).unwrap()).unwrap();
        let sub = all.subset(&keep);
        assert!((sub.gram - &direct.gram).norm() < 1e-12);
        assert!((sub.mean - &direct.mean).norm() < 1e-12);
        // A fill of faces 2 and 4 from the others; its error on face 2 (position 2) from the
        // moments equals the error of the applied fill.
        let fill = AffineFill {
            a: DVector::from_vec(vec![0.3, -0.2]),
            b: DMatrix::from_fn(2, 4, |i, j| 0.1 * (i + 2 * j) as f64 - 0.2),
        };
        let err = all.fill_error(&keep, &[2], &[0], &fill);
        let norm = all.spread(&[2]);
        let filled = CentredKnown::new(&t, &sub_known)
            .unwrap()
            .apply(&t, &sub_known, &fill)
            .unwrap();
        let mean = t.mean_of(&known.known());
        let (got, truth) = (filled.face(2).unwrap(), t.face(2).unwrap());
        let nr = 12.0;
        let want: f64 = got
            .iter()
            .zip(&truth)
            .map(|(a, b)| a.distance_squared(*b))
            .sum::<f64>()
            / nr;
        let want_norm: f64 = truth
            .iter()
            .flat_map(|p| p.to_array())
            .zip(&mean)
            .map(|(x, m)| (x - m).powi(2))
            .sum::<f64>()
            / nr;
        assert!((err - want).abs() < 1e-12, "{err} vs {want}");
        assert!((norm - want_norm).abs() < 1e-12);
    }
}
