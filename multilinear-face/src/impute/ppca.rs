//! The thesis's imputation (§5.3.4) as written: per-mode PPCA on the incomplete matrices of
//! mode vectors, the linear constraints of all modes combined through the shared missing
//! values and solved jointly in the least-squares sense, iterated.

use nalgebra::{DMatrix, DVector, SymmetricEigen};

use super::averaging::{averaging_fill, check_shapes};
use super::moments::{AffineFill, CentredKnown, Moments};
use super::spd::spd_inverse;
use crate::face_data::{unflatten, FaceTensor, KnownFaces};
#[cfg(doc)]
use crate::impute_by_averaging;
use crate::{Error, Result};

/// Parameters of [`impute_ppca`]. The thesis gives no constants for its PPCA; these are ours.
#[derive(Clone, Debug, PartialEq)]
pub struct PpcaParams {
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

impl Default for PpcaParams {
    fn default() -> Self {
        PpcaParams {
            ranks: None,
            energy: 0.9999,
            max_iterations: 200,
            tolerance: 1e-4,
            em_covariance: true,
        }
    }
}

impl PpcaParams {
    /// Fixed PPCA latent dimensions per attribute mode.
    pub fn with_ranks(mut self, ranks: &[usize]) -> Self {
        self.ranks = Some(ranks.to_vec());
        self
    }
}

/// The result of [`impute_ppca`].
#[derive(Clone, Debug, PartialEq)]
pub struct PpcaImputation {
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

impl PpcaParams {
    /// Checks the parameters against the attribute sizes.
    pub(super) fn check(&self, sizes: &[usize]) -> Result<()> {
        if let Some(r) = &self.ranks {
            skin_core::check::same_size(
                "PPCA ranks (one per attribute mode)",
                sizes.len(),
                r.len(),
            )?;
            for (&q, &d) in r.iter().zip(sizes) {
                if q == 0 || q > d {
                    return Err(Error::InvalidParam {
                        name: "ranks",
                        reason: format!(
                            "a PPCA rank must be in 1..={d} (its mode's size), got {q}"
                        ),
                    });
                }
            }
        }
        if !(self.energy > 0.0 && self.energy <= 1.0) {
            return Err(Error::InvalidParam {
                name: "energy",
                reason: format!("must be in (0, 1], got {}", self.energy),
            });
        }
        skin_core::check::non_negative("tolerance", self.tolerance)?;
        Ok(())
    }
}

/// How an iteration of [`ppca_fill`] ended.
pub(super) struct PpcaRun {
    pub(super) iterations: usize,
    pub(super) changes: Vec<f64>,
    pub(super) converged: bool,
    pub(super) ranks: Vec<usize>,
}

/// Where a face sits in the joint solve: its row among the missing faces or its column among
/// the known ones.
#[derive(Clone, Copy)]
enum Slot {
    Missing(usize),
    Known(usize),
}

/// The iteration of [`impute_ppca`] on the known faces' moments (`moments` of
/// `known.known()`, centred by their mean face; the parameters checked by the caller): the
/// fill `x_m = a + B y_o` and how the iteration ended.
///
/// # Errors
/// [`Error::Empty`] as [`impute_by_averaging`] (the start); [`Error::InvalidParam`] if the
/// constraints leave a missing face undetermined.
pub(super) fn ppca_fill(
    known: &KnownFaces,
    moments: &Moments,
    params: &PpcaParams,
) -> Result<(AffineFill, PpcaRun)> {
    let sizes = known.attribute_sizes().to_vec();
    let missing = known.missing();
    let observed = known.known();
    let k: usize = sizes.iter().product();
    let (nm, no) = (missing.len(), observed.len());
    let mut ranks = vec![0; sizes.len()];
    let start = averaging_fill(known)?;
    if missing.is_empty() {
        let run = PpcaRun {
            iterations: 0,
            changes: Vec::new(),
            converged: true,
            ranks,
        };
        return Ok((start, run));
    }
    let mut slot = vec![Slot::Known(0); k];
    for (i, &f) in missing.iter().enumerate() {
        slot[f] = Slot::Missing(i);
    }
    for (j, &f) in observed.iter().enumerate() {
        slot[f] = Slot::Known(j);
    }
    let (g, xbar) = (&moments.gram, &moments.mean);
    let groups: Vec<Vec<Vec<usize>>> = (0..sizes.len()).map(|n| mode_groups(&sizes, n)).collect();
    // The second moments PPCA reads: pairs of faces in one mode vector with a missing first.
    let mut pairs: Vec<(usize, usize)> = groups
        .iter()
        .flatten()
        .flat_map(|grp| {
            grp.iter()
                .flat_map(move |&fa| grp.iter().map(move |&fb| (fa, fb)))
                .filter(|&(fa, _)| matches!(slot[fa], Slot::Missing(_)))
        })
        .collect();
    pairs.sort_unstable();
    pairs.dedup();
    // Moments E[y], E[y yᵀ] over the slices: the known block from the data, the missing
    // blocks from x_m = a + B x_o (+ the posterior covariance H⁻¹ in the EM form). Every
    // missing value is affine in the known ones, so these follow from the known faces'
    // moments alone: each iteration costs O(K³), independent of the vertex count.
    let mut m = DVector::zeros(k);
    let mut s = DMatrix::zeros(k, k);
    for (j, &fj) in observed.iter().enumerate() {
        m[fj] = xbar[j];
        for (l, &fl) in observed.iter().enumerate() {
            s[(fj, fl)] = g[(j, l)];
        }
    }
    let set_moments = |m: &mut DVector<f64>,
                       s: &mut DMatrix<f64>,
                       fill: &AffineFill,
                       bg: &DMatrix<f64>,
                       posterior: Option<&DMatrix<f64>>| {
        let bx = &fill.b * xbar;
        // Columns are contiguous: the rows of B G and B as columns.
        let (bg_t, b_t) = (bg.transpose(), fill.b.transpose());
        for (i, &fi) in missing.iter().enumerate() {
            m[fi] = fill.a[i] + bx[i];
        }
        for &(fa, fb) in &pairs {
            let Slot::Missing(i) = slot[fa] else {
                continue;
            };
            let v = match slot[fb] {
                Slot::Known(j) => fill.a[i] * xbar[j] + bg[(i, j)],
                Slot::Missing(l) => {
                    fill.a[i] * fill.a[l]
                        + fill.a[i] * bx[l]
                        + bx[i] * fill.a[l]
                        + bg_t.column(i).dot(&b_t.column(l))
                        + posterior.map_or(0.0, |p| p[(i, l)])
                }
            };
            s[(fa, fb)] = v;
            s[(fb, fa)] = v;
        }
    };
    // The averaging baseline's completion starts the iteration.
    let mut bg = &start.b * g;
    set_moments(&mut m, &mut s, &start, &bg, None);
    let mut fill = AffineFill {
        a: DVector::zeros(nm),
        b: DMatrix::zeros(nm, no),
    };
    bg.fill(0.0);
    let mut changes = Vec::new();
    let mut converged = false;
    let mut iterations = 0;
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
        let h = DMatrix::from_fn(nm, nm, |i, j| q[(missing[i], missing[j])]);
        let q_mo = DMatrix::from_fn(nm, no, |i, j| q[(missing[i], observed[j])]);
        let c_m = DVector::from_fn(nm, |i, _| lin[missing[i]]);
        let h_inv = spd_inverse(&h).ok_or(Error::InvalidParam {
            name: "known faces",
            reason: "the PPCA constraints leave a missing face undetermined".into(),
        })?;
        let b_new: DMatrix<f64> = &h_inv * q_mo;
        let new = AffineFill {
            a: &h_inv * c_m,
            b: -b_new,
        };
        let bg_new = &new.b * g;
        // RMS change of the imputed values over all slices, from the moments:
        // Σ (Δa + ΔB y)² = Δa·Δa + 2 Δa·(ΔB ȳ) + tr(ΔB G ΔBᵀ).
        let sq = |a: &DVector<f64>, b: &DMatrix<f64>, bg: &DMatrix<f64>| -> f64 {
            a.dot(a) + 2.0 * a.dot(&(b * xbar)) + bg.component_mul(b).sum()
        };
        let (da, db) = (&new.a - &fill.a, &new.b - &fill.b);
        let change = (sq(&da, &db, &(&bg_new - &bg)).max(0.0)
            / sq(&new.a, &new.b, &bg_new).max(f64::MIN_POSITIVE))
        .sqrt();
        fill = new;
        bg = bg_new;
        set_moments(
            &mut m,
            &mut s,
            &fill,
            &bg,
            params.em_covariance.then_some(&h_inv),
        );
        changes.push(change);
        if it > 0 && change < params.tolerance {
            converged = true;
            break;
        }
    }
    let run = PpcaRun {
        iterations,
        changes,
        converged,
        ranks,
    };
    Ok((fill, run))
}

/// Imputes the missing faces as the thesis does (§5.3.4). With the known faces' mean
/// subtracted, each slice of the data along the vertex mode (one coordinate of all faces,
/// `Π dₙ` values) contributes, for every attribute mode `n`, its mode-`n` vectors `v` to
/// `Σₙ Σ_v (v − μₙ)ᵀ Cₙ⁻¹ (v − μₙ)`, the negative log-likelihood under the geometric average of
/// the per-mode PPCA Gaussians (the thesis's probabilistic interpretation). Its minimiser over
/// the missing values is the joint least-squares solution of all modes' PPCA constraints:
/// `H x_m = c_m − Q_mo x_o` with one `m × m` matrix `H` shared by all slices (faces are
/// missing whole). Starts from [`impute_by_averaging`]; each iteration re-fits every mode's
/// PPCA to the completed data (EM: with the posterior covariance `H⁻¹`) and re-solves.
///
/// [`crate::impute`] chooses between this and the averaging baseline by cross-validation.
///
/// # Errors
/// [`Error::SizeMismatch`] if `known` is for another shape or `params.ranks` has the wrong
/// length; [`Error::InvalidParam`] for a rank of 0 or above its mode, or an energy outside
/// `(0, 1]`; [`Error::Empty`] as [`impute_by_averaging`].
pub fn impute_ppca(
    faces: &FaceTensor,
    known: &KnownFaces,
    params: &PpcaParams,
) -> Result<PpcaImputation> {
    check_shapes(faces, known)?;
    params.check(faces.attribute_sizes())?;
    let centred = CentredKnown::new(faces, known)?;
    let (fill, run) = ppca_fill(known, &Moments::new(&centred)?, params)?;
    Ok(PpcaImputation {
        faces: centred.apply(faces, known, &fill)?,
        iterations: run.iterations,
        changes: run.changes,
        converged: run.converged,
        ranks: run.ranks,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::impute_by_averaging;
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
        let ours = impute_ppca(&inter, &known, &PpcaParams::default()).unwrap();
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
        assert!(impute_ppca(&t, &known, &PpcaParams::default().with_ranks(&[5, 2])).is_err());
        assert!(impute_ppca(&t, &known, &PpcaParams::default().with_ranks(&[2])).is_err());
        let p = PpcaParams {
            energy: 0.0,
            ..PpcaParams::default()
        };
        assert!(impute_ppca(&t, &known, &p).is_err());
        let other = KnownFaces::new(&[7, 4], vec![true; 28]).unwrap();
        assert!(impute_ppca(&t, &other, &PpcaParams::default()).is_err());
        // Nothing missing: nothing changes.
        let done = impute_ppca(&t, &known, &PpcaParams::default()).unwrap();
        assert!(done.converged && done.iterations == 0);
    }
}
