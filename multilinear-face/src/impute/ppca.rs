//! Missing data (§5.3.4): per-mode PPCA on the incomplete matrices of mode vectors, the linear
//! constraints of all modes combined through the shared missing values and solved jointly in
//! the least-squares sense, iterated; and the averaging baseline (Blanz et al. generalised:
//! copy the mean displacement of the identities that have the face).

use nalgebra::{DMatrix, DVector, SymmetricEigen};

use skin_core::tensor::Tensor;

use crate::face_data::{unflatten, FaceTensor, KnownFaces};
use crate::{Error, Result};

/// Parameters of [`impute`]. The thesis gives no constants for its PPCA; these are ours.
#[derive(Clone, Debug, PartialEq)]
pub struct ImputeParams {
    /// PPCA latent dimension per attribute mode; `None`: the smallest that keeps
    /// `energy` of the mode vectors' variance (at most `dₙ − 1`).
    pub ranks: Option<Vec<usize>>,
    /// Variance fraction kept when `ranks` is `None`. Default 0.9999.
    pub energy: f64,
    /// Iterations (re-estimate the PPCA means and covariances, re-solve). Default 200.
    pub max_iterations: usize,
    /// Stop when the imputed values change by less than this fraction of their norm.
    /// Default 1e-4.
    pub tolerance: f64,
    /// Add the posterior covariance of the imputed values to the second moments before
    /// re-fitting the PPCA (EM); `false` re-fits to the completed data as if it were known.
    /// Default `true`.
    pub em_covariance: bool,
}

impl Default for ImputeParams {
    fn default() -> Self {
        ImputeParams {
            ranks: None,
            energy: 0.9999,
            max_iterations: 200,
            tolerance: 1e-4,
            em_covariance: true,
        }
    }
}

impl ImputeParams {
    /// Fixed PPCA latent dimensions per attribute mode.
    pub fn with_ranks(mut self, ranks: &[usize]) -> Self {
        self.ranks = Some(ranks.to_vec());
        self
    }
}

/// The result of [`impute`].
#[derive(Clone, Debug, PartialEq)]
pub struct Imputation {
    /// The completed data tensor (known faces unchanged).
    pub faces: FaceTensor,
    /// Iterations run.
    pub iterations: usize,
    /// Relative change of the imputed values per iteration.
    pub changes: Vec<f64>,
    /// Whether the change fell below the tolerance.
    pub converged: bool,
    /// PPCA latent dimension used per attribute mode (last iteration).
    pub ranks: Vec<usize>,
}

fn check_shapes(faces: &FaceTensor, known: &KnownFaces) -> Result<()> {
    if faces.attribute_sizes() != known.attribute_sizes() {
        return Err(Error::SizeMismatch {
            what: "known-face flags (attribute sizes)",
            expected: faces.face_count(),
            got: known.attribute_sizes().iter().product(),
        });
    }
    Ok(())
}

/// The averaging baseline (Figure 5-6, "a simple averaging scheme"; Blanz et al.'s copy of
/// one person's displacement, generalised to the mean over every identity that has both
/// faces): a missing face `(c, i)` (`c` the non-identity attributes, `i` the identity, the
/// last mode) is `x(c', i) + mean_{i'} [x(c, i') − x(c', i')]` averaged over the known
/// reference faces `c'` of `i`, with `i'` over the identities that have both `c` and `c'`.
///
/// # Errors
/// [`Error::SizeMismatch`] if `known` is for another shape; [`Error::Empty`] if a missing face
/// has no usable reference (no identity has both it and one of the person's known faces).
pub fn impute_by_averaging(faces: &FaceTensor, known: &KnownFaces) -> Result<FaceTensor> {
    check_shapes(faces, known)?;
    let sizes = faces.attribute_sizes();
    let d_id = sizes[sizes.len() - 1];
    let d_c = faces.face_count() / d_id;
    let k = faces.face_count();
    let mut data = faces.tensor().data().to_vec();
    let src = faces.tensor().data();
    for f in known.missing() {
        let (c, i) = (f / d_id, f % d_id);
        // (reference c', identities i' with both c and c').
        let mut pairs: Vec<(usize, Vec<usize>)> = Vec::new();
        for cp in 0..d_c {
            if cp == c || !known.is_known(cp * d_id + i) {
                continue;
            }
            let others: Vec<usize> = (0..d_id)
                .filter(|&ip| known.is_known(c * d_id + ip) && known.is_known(cp * d_id + ip))
                .collect();
            if !others.is_empty() {
                pairs.push((cp, others));
            }
        }
        if pairs.is_empty() {
            return Err(Error::Empty {
                what: "reference faces for the averaging baseline",
            });
        }
        let np = pairs.len() as f64;
        for (r, row) in src.chunks_exact(k).enumerate() {
            let mut acc = 0.0;
            for (cp, others) in &pairs {
                let disp: f64 = others
                    .iter()
                    .map(|&ip| row[c * d_id + ip] - row[cp * d_id + ip])
                    .sum::<f64>()
                    / others.len() as f64;
                acc += row[cp * d_id + i] + disp;
            }
            data[r * k + f] = acc / np;
        }
    }
    FaceTensor::from_tensor(Tensor::new(faces.tensor().shape().to_vec(), data)?)
}

/// PPCA of the mode vectors: the precision `C⁻¹` of `C = W Wᵀ + σ² I` and the mean.
struct Ppca {
    mean: DVector<f64>,
    precision: DMatrix<f64>,
    rank: usize,
}

/// Fits PPCA (Tipping & Bishop: `W` from the leading eigenvectors of the sample covariance,
/// `σ²` the mean of the discarded eigenvalues) to the mode-`mode` vectors of the slices, from
/// the slices' first and second moments (`m = E[y]`, `S = E[y yᵀ]`, both over `K` faces).
fn fit_ppca(
    m: &DVector<f64>,
    s: &DMatrix<f64>,
    groups: &[Vec<usize>],
    d: usize,
    rank: Option<usize>,
    energy: f64,
) -> Ppca {
    let n = groups.len() as f64;
    let mut mean = DVector::zeros(d);
    let mut gram = DMatrix::zeros(d, d);
    for g in groups {
        for (a, &fa) in g.iter().enumerate() {
            mean[a] += m[fa] / n;
            for (b, &fb) in g.iter().enumerate() {
                gram[(a, b)] += s[(fa, fb)] / n;
            }
        }
    }
    let cov = gram - &mean * mean.transpose();
    let eig: SymmetricEigen<f64, nalgebra::Dyn> = SymmetricEigen::new(cov);
    let mut order: Vec<usize> = (0..d).collect();
    order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
    let lambda: Vec<f64> = order.iter().map(|&i| eig.eigenvalues[i].max(0.0)).collect();
    let total: f64 = lambda.iter().sum::<f64>().max(f64::MIN_POSITIVE);
    let top = d.saturating_sub(1).max(1);
    let q = match rank {
        Some(q) => q.clamp(1, d),
        None => {
            let mut acc = 0.0;
            let mut q = top;
            for (i, l) in lambda.iter().enumerate() {
                acc += l;
                if acc >= energy * total {
                    q = (i + 1).min(top);
                    break;
                }
            }
            q
        }
    };
    let tail = &lambda[q..];
    let floor = 1e-10 * lambda[0].max(f64::MIN_POSITIVE);
    let sigma2 = if tail.is_empty() {
        floor
    } else {
        (tail.iter().sum::<f64>() / tail.len() as f64).max(floor)
    };
    // C⁻¹ = Σ_{i<q} uᵢuᵢᵀ/λᵢ + (I − Σ_{i<q} uᵢuᵢᵀ)/σ².
    let mut precision = DMatrix::identity(d, d) / sigma2;
    for (j, &i) in order.iter().take(q).enumerate() {
        let u = eig.eigenvectors.column(i);
        let li = lambda[j].max(sigma2);
        precision.ger(1.0 / li - 1.0 / sigma2, &u, &u, 1.0);
    }
    Ppca {
        mean,
        precision,
        rank: q,
    }
}

/// The flat indices of each mode-`mode` vector of a slice (one group per combination of the
/// other indices, entries in order of the mode's index).
fn mode_groups(sizes: &[usize], mode: usize) -> Vec<Vec<usize>> {
    let k: usize = sizes.iter().product();
    let stride: usize = sizes[mode + 1..].iter().product();
    let d = sizes[mode];
    (0..k)
        .filter(|&f| unflatten(sizes, f)[mode] == 0)
        .map(|f| (0..d).map(|a| f + a * stride).collect())
        .collect()
}

/// Imputes the missing faces (§5.3.4). With the known faces' mean subtracted, each slice of
/// the data along the vertex mode (one coordinate of all faces, `Π dₙ` values) contributes,
/// for every attribute mode `n`, its mode-`n` vectors `v` to `Σₙ Σ_v (v − μₙ)ᵀ Cₙ⁻¹ (v − μₙ)`,
/// the negative log-likelihood under the geometric average of the per-mode PPCA Gaussians
/// (the thesis's probabilistic interpretation). Its minimiser over the missing values is the
/// joint least-squares solution of all modes' PPCA constraints: `H x_m = c_m − Q_mo x_o` with
/// one `m × m` matrix `H` shared by all slices (faces are missing whole). Starts from
/// [`impute_by_averaging`]; each iteration re-fits every mode's PPCA to the completed data and
/// re-solves.
///
/// # Errors
/// [`Error::SizeMismatch`] if `known` is for another shape or `params.ranks` has the wrong
/// length; [`Error::InvalidParam`] for a rank of 0 or above its mode, or an energy outside
/// `(0, 1]`; [`Error::Empty`] as [`impute_by_averaging`].
pub fn impute(faces: &FaceTensor, known: &KnownFaces, params: &ImputeParams) -> Result<Imputation> {
    check_shapes(faces, known)?;
    let sizes = faces.attribute_sizes().to_vec();
    if let Some(r) = &params.ranks {
        skin_core::check::same_size("PPCA ranks (one per attribute mode)", sizes.len(), r.len())?;
        for (&q, &d) in r.iter().zip(&sizes) {
            if q == 0 || q > d {
                return Err(Error::InvalidParam {
                    name: "ranks",
                    reason: format!("a PPCA rank must be in 1..={d} (its mode's size), got {q}"),
                });
            }
        }
    }
    if !(params.energy > 0.0 && params.energy <= 1.0) {
        return Err(Error::InvalidParam {
            name: "energy",
            reason: format!("must be in (0, 1], got {}", params.energy),
        });
    }
    skin_core::check::non_negative("tolerance", params.tolerance)?;
    let start = impute_by_averaging(faces, known)?;
    let missing = known.missing();
    let observed = known.known();
    let k = faces.face_count();
    let rows = faces.tensor().shape()[0];
    let nr = rows as f64;
    let mean_face = faces.mean_of(&observed);
    let centred = |t: &Tensor, keep_missing: bool| -> Result<Tensor> {
        let mut d = t.data().to_vec();
        for (r, row) in d.chunks_exact_mut(k).enumerate() {
            for (f, x) in row.iter_mut().enumerate() {
                *x = if keep_missing || known.is_known(f) {
                    *x - mean_face[r]
                } else {
                    0.0
                };
            }
        }
        Ok(Tensor::new(vec![rows, k], d)?)
    };
    let mut ranks = vec![0; sizes.len()];
    if missing.is_empty() {
        return Ok(Imputation {
            faces: faces.clone(),
            iterations: 0,
            changes: Vec::new(),
            converged: true,
            ranks,
        });
    }
    // Every missing slice value is affine in the known ones, x_m = a + B x_o (the joint
    // solve below), so the moments E[y], E[y yᵀ] over the 3V slices follow from the known
    // faces' moments alone: each iteration costs O(K³), independent of the vertex count.
    let y0 = centred(faces.tensor(), false)?;
    let g_full = y0.gram(1)? / nr;
    let col_mean = |t: &Tensor| -> DVector<f64> {
        let mut m = DVector::zeros(k);
        for row in t.data().chunks_exact(k) {
            for (f, x) in row.iter().enumerate() {
                m[f] += x / nr;
            }
        }
        m
    };
    let m0 = col_mean(&y0);
    let g = DMatrix::from_fn(observed.len(), observed.len(), |i, j| {
        g_full[(observed[i], observed[j])]
    });
    let xbar = DVector::from_fn(observed.len(), |i, _| m0[observed[i]]);
    // Moments of the averaging baseline's completion start the iteration.
    let ys = centred(start.tensor(), true)?;
    let mut s = ys.gram(1)? / nr;
    let mut m = col_mean(&ys);
    let mut a = DVector::zeros(missing.len());
    let mut b = DMatrix::zeros(missing.len(), observed.len());
    let mut changes = Vec::new();
    let mut converged = false;
    let mut iterations = 0;
    let groups: Vec<Vec<Vec<usize>>> = (0..sizes.len()).map(|n| mode_groups(&sizes, n)).collect();
    for it in 0..params.max_iterations {
        iterations += 1;
        let mut q = DMatrix::zeros(k, k);
        let mut lin = DVector::zeros(k);
        for mode in 0..sizes.len() {
            let ppca = fit_ppca(
                &m,
                &s,
                &groups[mode],
                sizes[mode],
                params.ranks.as_ref().map(|r| r[mode]),
                params.energy,
            );
            ranks[mode] = ppca.rank;
            let pm = &ppca.precision * &ppca.mean;
            for grp in &groups[mode] {
                for (i, &fa) in grp.iter().enumerate() {
                    lin[fa] += pm[i];
                    for (j, &fb) in grp.iter().enumerate() {
                        q[(fa, fb)] += ppca.precision[(i, j)];
                    }
                }
            }
        }
        // Minimiser of Σₙ Σ_v (v − μₙ)ᵀ Cₙ⁻¹ (v − μₙ) over x_m: H x_m = c_m − Q_mo x_o.
        let h = DMatrix::from_fn(missing.len(), missing.len(), |i, j| {
            q[(missing[i], missing[j])]
        });
        let q_mo = DMatrix::from_fn(missing.len(), observed.len(), |i, j| {
            q[(missing[i], observed[j])]
        });
        let c_m = DVector::from_fn(missing.len(), |i, _| lin[missing[i]]);
        let ch = h.cholesky().ok_or(Error::InvalidParam {
            name: "known faces",
            reason: "the PPCA constraints leave a missing face undetermined".into(),
        })?;
        let a_new = ch.solve(&c_m);
        let b_new = -ch.solve(&q_mo);
        // RMS change of the imputed values over all slices, from the moments.
        let (da, db) = (&a_new - &a, &b_new - &b);
        let sq = |a: &DVector<f64>, b: &DMatrix<f64>| -> f64 {
            a.dot(a) + 2.0 * a.dot(&(b * &xbar)) + (b * &g).component_mul(b).sum()
        };
        let change = (sq(&da, &db).max(0.0) / sq(&a_new, &b_new).max(f64::MIN_POSITIVE)).sqrt();
        a = a_new;
        b = b_new;
        // New moments: observed block fixed, missing blocks from x_m = a + B x_o, plus the
        // posterior covariance H⁻¹ in the missing block (EM).
        let bx = &b * &xbar;
        let m_m = &a + &bx;
        let s_mo = &a * xbar.transpose() + &b * &g;
        let mut s_mm = &a * a.transpose()
            + &a * bx.transpose()
            + &bx * a.transpose()
            + &b * &g * b.transpose();
        if params.em_covariance {
            s_mm += ch.inverse();
        }
        for (i, &fi) in missing.iter().enumerate() {
            m[fi] = m_m[i];
            for (j, &fj) in observed.iter().enumerate() {
                s[(fi, fj)] = s_mo[(i, j)];
                s[(fj, fi)] = s_mo[(i, j)];
            }
            for (j, &fj) in missing.iter().enumerate() {
                s[(fi, fj)] = s_mm[(i, j)];
            }
        }
        changes.push(change);
        if it > 0 && change < params.tolerance {
            converged = true;
            break;
        }
    }
    // x_m = a + B x_o for every slice: one mode-1 product of the known data.
    let mut p = DMatrix::zeros(k, k);
    for &f in &observed {
        p[(f, f)] = 1.0;
    }
    for (i, &fi) in missing.iter().enumerate() {
        for (j, &fj) in observed.iter().enumerate() {
            p[(fi, fj)] = b[(i, j)];
        }
    }
    let filled = y0.mode_product(1, &p)?;
    let mut data = faces.tensor().data().to_vec();
    for (r, row) in filled.data().chunks_exact(k).enumerate() {
        for (i, &f) in missing.iter().enumerate() {
            data[r * k + f] = row[f] + a[i] + mean_face[r];
        }
    }
    Ok(Imputation {
        faces: FaceTensor::from_tensor(Tensor::new(faces.tensor().shape().to_vec(), data)?)?,
        iterations,
        changes,
        converged,
        ranks,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use skin_core::math::DVec3;

    /// f(e, i) = base + a_e + b_i + interaction s_e t_i: additive plus a bilinear term.
    fn faces(interaction: f64) -> FaceTensor {
        let (de, di, v) = (4, 7, 40);
        let faces: Vec<Vec<DVec3>> = (0..de * di)
            .map(|f| {
                let (e, i) = ((f / di) as f64, (f % di) as f64);
                (0..v)
                    .map(|k| {
                        let k = k as f64;
                        let a = (0.9 * e + 0.3 * k).sin();
                        let b =
                            (1.7 * i).cos() * (0.2 * k).cos() + 0.3 * (2.3 * i).sin() * (0.05 * k);
                        let s = interaction
                            * (1.0 + (0.7 * e).cos())
                            * (1.0 + 0.5 * (1.1 * i).sin())
                            * (0.4 * k).sin();
                        DVec3::new(k + a + b + s, 2.0 * a - b, b + s)
                    })
                    .collect()
            })
            .collect();
        FaceTensor::from_faces(&[de, di], &faces).unwrap()
    }

    fn err(est: &FaceTensor, truth: &FaceTensor, missing: &[usize]) -> f64 {
        missing
            .iter()
            .map(|&f| {
                let (a, b) = (est.face(f).unwrap(), truth.face(f).unwrap());
                a.iter()
                    .zip(&b)
                    .map(|(x, y)| x.distance_squared(*y))
                    .sum::<f64>()
            })
            .sum::<f64>()
            .sqrt()
    }

    #[test]
    fn averaging_is_exact_on_additive_faces_and_ppca_wins_with_interaction() {
        let mut flags = vec![true; 28];
        for f in [3, 9, 12, 26] {
            flags[f] = false;
        }
        let known = KnownFaces::new(&[4, 7], flags).unwrap();
        let add = faces(0.0);
        let avg = impute_by_averaging(&add, &known).unwrap();
        assert!(err(&avg, &add, &known.missing()) < 1e-9);

        let inter = faces(0.5);
        let avg = impute_by_averaging(&inter, &known).unwrap();
        let ours = impute(&inter, &known, &ImputeParams::default()).unwrap();
        let (ea, eo) = (
            err(&avg, &inter, &known.missing()),
            err(&ours.faces, &inter, &known.missing()),
        );
        assert!(
            eo < 0.2 * ea,
            "ours {eo} vs averaging {ea}; {:?}",
            ours.changes
        );
        // Known faces are untouched.
        assert_eq!(ours.faces.face(0).unwrap(), inter.face(0).unwrap());
    }

    #[test]
    fn bad_parameters_are_errors() {
        let t = faces(0.1);
        let known = KnownFaces::new(&[4, 7], vec![true; 28]).unwrap();
        assert!(impute(&t, &known, &ImputeParams::default().with_ranks(&[5, 2])).is_err());
        assert!(impute(&t, &known, &ImputeParams::default().with_ranks(&[2])).is_err());
        let p = ImputeParams {
            energy: 0.0,
            ..ImputeParams::default()
        };
        assert!(impute(&t, &known, &p).is_err());
        let other = KnownFaces::new(&[7, 4], vec![true; 28]).unwrap();
        assert!(impute(&t, &other, &ImputeParams::default()).is_err());
        // Nothing missing: nothing changes.
        let done = impute(&t, &known, &ImputeParams::default()).unwrap();
        assert!(done.converged && done.iterations == 0);
    }
}
