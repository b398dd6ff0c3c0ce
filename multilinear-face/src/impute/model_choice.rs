//! The imputation's model, chosen from the known faces by cross-validation (ours, beyond
//! §5.3.4): the thesis's PPCA at a few ranks and the additive model of the averaging
//! baseline are candidates; known faces are held out in folds, filled by each candidate, and
//! the candidate with the smallest error fills the missing faces.

use rayon::prelude::*;
use skin_core::random::SplitMix64;

use super::averaging::{averaging_can_fill, averaging_fill, check_shapes};
use super::moments::{AffineFill, CentredKnown, Moments};
use super::ppca::{ppca_fill, PpcaParams};
use crate::face_data::{FaceTensor, KnownFaces};
#[cfg(doc)]
use crate::{impute_by_averaging, impute_ppca};
use crate::{Error, Result};

/// A model that fills missing faces: a candidate of [`impute`].
#[derive(Clone, Debug, PartialEq)]
pub enum ImputeModel {
    /// The additive model of the averaging baseline ([`impute_by_averaging`]: the other
    /// identities' mean displacement copied; exact when expression and identity add).
    Averaging,
    /// The thesis's per-mode PPCA ([`impute_ppca`], §5.3.4) with these parameters.
    Ppca(PpcaParams),
}

/// Parameters of [`impute`]. All ours: the thesis (§5.3.4) fills missing faces with one model.
#[derive(Clone, Debug, PartialEq)]
pub struct ImputeParams {
    /// The candidate models, in order of preference on equal errors. Default: the averaging
    /// baseline's additive model, then the thesis's PPCA as [`impute_ppca`] runs it
    /// ([`PpcaParams::default`]). PPCA at other ranks (fixed, or keeping 99.9 % or 99 % of
    /// each mode's variance) can be added; on the trilinear sets of the validation they never
    /// filled better than the default ranks by more than the folds' noise, at the cost of a
    /// full set of folds each, so they are not in the default.
    pub candidates: Vec<ImputeModel>,
    /// Folds of the cross-validation; 0 skips it (the first candidate fills). Default 3.
    pub folds: usize,
    /// Fraction of the known faces each fold holds out, in `(0, 1)`. Default 0.1: a fold's
    /// problem misses only a little more than the user's (at 50 % missing: 55 %), so the
    /// validation measures each model near the fraction it will fill.
    pub fold_fraction: f64,
    /// At most this many PPCA iterations per candidate and fold (the final fill runs the
    /// chosen candidate to its own stopping rule). Default 30: on the trilinear set at 50 %
    /// missing the error after 30 iterations is within 4 % of the converged one.
    pub validation_iterations: usize,
    /// Seed of the folds (which known faces each holds out). Default 0.
    pub seed: u64,
}

impl Default for ImputeParams {
    fn default() -> Self {
        ImputeParams {
            candidates: vec![
                ImputeModel::Averaging,
                ImputeModel::Ppca(PpcaParams::default()),
            ],
            folds: 3,
            fold_fraction: 0.1,
            validation_iterations: 30,
            seed: 0,
        }
    }
}

impl ImputeParams {
    /// With these candidates (in order of preference on equal errors).
    pub fn with_candidates(mut self, candidates: Vec<ImputeModel>) -> Self {
        self.candidates = candidates;
        self
    }
}

/// The result of [`impute`] (§5.3.4 and the model choice beyond it).
#[derive(Clone, Debug, PartialEq)]
pub struct Imputation {
    /// The completed data tensor (known faces unchanged).
    pub faces: FaceTensor,
    /// The candidate that filled the missing faces.
    pub model: ImputeModel,
    /// Per candidate (in [`ImputeParams::candidates`] order), its cross-validation error:
    /// `‖X̂ − X‖_F / ‖X − x̄‖_F` over the held-out known faces of all folds, `x̄` the known
    /// faces' mean face (∞ for a candidate that could not fill a fold). Empty when no fold
    /// could be formed.
    pub validation_errors: Vec<f64>,
    /// Known faces held out over all folds.
    pub validated_faces: usize,
    /// PPCA iterations of the final fill (0 for the averaging model).
    pub iterations: usize,
    /// PPCA latent dimension per attribute mode of the final fill (empty for averaging).
    pub ranks: Vec<usize>,
}

/// Disjoint folds of known faces (flat indices, ascending): each holds out up to
/// `fold_fraction` of the known faces, drawn in a seeded random order, skipping a face whose
/// removal would leave an attribute value without a known face or a missing face without a
/// reference for the averaging baseline (both needed by every candidate).
fn validation_folds(known: &KnownFaces, params: &ImputeParams) -> Result<Vec<Vec<usize>>> {
    let sizes = known.attribute_sizes();
    let observed = known.known();
    let k: usize = sizes.iter().product();
    let per_fold = ((params.fold_fraction * observed.len() as f64).round() as usize).max(1);
    let order = SplitMix64::new(params.seed).choose(observed.len(), observed.len())?;
    let base: Vec<bool> = (0..k).map(|f| known.is_known(f)).collect();
    let mut used = vec![false; observed.len()];
    let mut folds = Vec::new();
    for _ in 0..params.folds {
        let mut flags = base.clone();
        let mut fold = Vec::new();
        for &p in &order {
            if fold.len() == per_fold {
                break;
            }
            if used[p] {
                continue;
            }
            let f = observed[p];
            flags[f] = false;
            let fillable =
                KnownFaces::new(sizes, flags.clone()).is_ok_and(|kf| averaging_can_fill(&kf));
            if fillable {
                fold.push(f);
                used[p] = true;
            } else {
                flags[f] = true;
            }
        }
        if !fold.is_empty() {
            fold.sort_unstable();
            folds.push(fold);
        }
    }
    Ok(folds)
}

/// The fill of one candidate for the known faces `known` (their centred moments given).
fn candidate_fill(
    model: &ImputeModel,
    known: &KnownFaces,
    moments: &Moments,
) -> Result<(AffineFill, usize, Vec<usize>)> {
    match model {
        ImputeModel::Averaging => Ok((averaging_fill(known)?, 0, Vec::new())),
        ImputeModel::Ppca(p) => {
            let (fill, run) = ppca_fill(known, moments, p)?;
            Ok((fill, run.iterations, run.ranks))
        }
    }
}

/// One fold: its known faces, the positions (among all known faces) it keeps and holds out,
/// and the rows of the held-out faces among the fold's missing faces.
struct Fold {
    known: KnownFaces,
    keep: Vec<usize>,
    targets: Vec<usize>,
    rows: Vec<usize>,
}

impl Fold {
    fn new(known: &KnownFaces, held: &[usize]) -> Result<Self> {
        let sizes = known.attribute_sizes();
        let k: usize = sizes.iter().product();
        let flags: Vec<bool> = (0..k)
            .map(|f| known.is_known(f) && held.binary_search(&f).is_err())
            .collect();
        let fold_known = KnownFaces::new(sizes, flags)?;
        let observed = known.known();
        let (mut keep, mut targets) = (Vec::new(), Vec::new());
        for (p, f) in observed.iter().enumerate() {
            if held.binary_search(f).is_ok() {
                targets.push(p);
            } else {
                keep.push(p);
            }
        }
        let missing = fold_known.missing();
        let rows = held
            .iter()
            .filter_map(|f| missing.binary_search(f).ok())
            .collect();
        Ok(Fold {
            known: fold_known,
            keep,
            targets,
            rows,
        })
    }
}

/// Fills the missing faces with the model that fills held-out known faces best.
///
/// The thesis's imputation (§5.3.4, [`impute_ppca`]) relies on each attribute mode being
/// low-dimensional ("if the data is truly low-dimensional in each of the modes, the missing
/// samples will fall within the span and density of the known ones"). Where a mode is not —
/// as many identity modes as people, or faces where expression and identity simply add, like
/// the ICT shapes — its PPCA has no constraint to use and draws the missing faces towards the
/// mean, and the averaging baseline's additive model does better (it is exact on additive
/// data). Which holds is a property of the user's data, and the known faces are the only
/// evidence. So (ours, beyond the thesis) the known faces are split into
/// [`ImputeParams::folds`] disjoint folds; each fold is held out, filled by every candidate
/// from the remaining known faces, and scored against its true values; the candidate with
/// the smallest total error fills the missing faces from all known faces. The additive model
/// is a candidate, so the chosen model is never worse than averaging on the held-out known
/// faces. Every fill is an affine map of the known faces, and its error follows from the
/// known faces' moments, so the validation costs `O(K³)` per PPCA iteration whatever the
/// vertex count; folds and candidates run in parallel (results do not depend on the thread
/// count).
///
/// # Errors
/// [`Error::SizeMismatch`] if `known` is for another shape; [`Error::Empty`] for no candidate
/// or as [`impute_by_averaging`]; [`Error::InvalidParam`] for a fold fraction outside
/// `(0, 1)` or a PPCA candidate's invalid parameters (as [`impute_ppca`]), or if the chosen
/// PPCA leaves a missing face undetermined.
pub fn impute(faces: &FaceTensor, known: &KnownFaces, params: &ImputeParams) -> Result<Imputation> {
    check_shapes(faces, known)?;
    if params.candidates.is_empty() {
        return Err(Error::Empty {
            what: "imputation candidates",
        });
    }
    if !(params.fold_fraction > 0.0 && params.fold_fraction < 1.0) {
        return Err(Error::InvalidParam {
            name: "fold_fraction",
            reason: format!("must be in (0, 1), got {}", params.fold_fraction),
        });
    }
    for c in &params.candidates {
        if let ImputeModel::Ppca(p) = c {
            p.check(faces.attribute_sizes())?;
        }
    }
    let centred = CentredKnown::new(faces, known)?;
    let moments = Moments::new(&centred)?;
    let folds: Vec<Fold> = if known.missing().is_empty() {
        Vec::new()
    } else {
        validation_folds(known, params)?
            .iter()
            .map(|held| Fold::new(known, held))
            .collect::<Result<_>>()?
    };
    let validated_faces = folds.iter().map(|f| f.targets.len()).sum();
    let tasks: Vec<(usize, usize)> = (0..folds.len())
        .flat_map(|f| (0..params.candidates.len()).map(move |c| (f, c)))
        .collect();
    let scores: Vec<f64> = tasks
        .par_iter()
        .map(|&(f, c)| {
            let fold = &folds[f];
            let model = match &params.candidates[c] {
                ImputeModel::Ppca(p) => ImputeModel::Ppca(PpcaParams {
                    max_iterations: p.max_iterations.min(params.validation_iterations),
                    ..p.clone()
                }),
                m => m.clone(),
            };
            let sub = moments.subset(&fold.keep);
            match candidate_fill(&model, &fold.known, &sub) {
                Ok((fill, _, _)) => {
                    moments.fill_error(&fold.keep, &fold.targets, &fold.rows, &fill)
                }
                // A candidate that cannot fill a fold is not a choice.
                Err(_) => f64::INFINITY,
            }
        })
        .collect();
    let n = params.candidates.len();
    let mut err = vec![0.0; n];
    for (&(_, c), e) in tasks.iter().zip(&scores) {
        err[c] += e;
    }
    let norm: f64 = folds.iter().map(|f| moments.spread(&f.targets)).sum();
    let validation_errors: Vec<f64> = if folds.is_empty() {
        Vec::new()
    } else {
        err.iter()
            .map(|e| (e / norm.max(f64::MIN_POSITIVE)).sqrt())
            .collect()
    };
    // The smallest error; the earlier candidate on equal errors.
    let chosen = (0..validation_errors.len()).fold(0, |best, c| {
        if validation_errors[c] < validation_errors[best] {
            c
        } else {
            best
        }
    });
    let model = params.candidates[chosen].clone();
    let (fill, iterations, ranks) = candidate_fill(&model, known, &moments)?;
    Ok(Imputation {
        faces: centred.apply(faces, known, &fill)?,
        model,
        validation_errors,
        validated_faces,
        iterations,
        ranks,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use skin_core::math::DVec3;

    /// 4 × 7 faces of 30 vertices: additive plus an expression × identity interaction.
    fn faces() -> FaceTensor {
        let faces: Vec<Vec<DVec3>> = (0..28)
            .map(|f| {
                let (e, i) = ((f / 7) as f64, (f % 7) as f64);
                (0..30)
                    .map(|k| {
                        let k = k as f64;
                        let a = (0.9 * e + 0.3 * k).sin();
                        let b = (1.7 * i).cos() * (0.2 * k).cos();
                        let s = 0.5 * (1.0 + (0.7 * e).cos()) * (1.3 * i).sin() * (0.4 * k).sin();
                        DVec3::new(k + a + b + s, 2.0 * a - b, b + s)
                    })
                    .collect()
            })
            .collect();
        FaceTensor::from_faces(&[4, 7], &faces).unwrap()
    }

    #[test]
    fn fold_errors_from_moments_match_filling_the_fold() {
        let t = faces();
        let mut flags = vec![true; 28];
        for f in [3, 12, 26] {
            flags[f] = false;
        }
        let known = KnownFaces::new(&[4, 7], flags).unwrap();
        let held = vec![5, 15, 22];
        let fold = Fold::new(&known, &held).unwrap();
        let centred = CentredKnown::new(&t, &known).unwrap();
        let moments = Moments::new(&centred).unwrap();
        let sub = moments.subset(&fold.keep);
        let nr = (3 * t.vertex_count()) as f64;
        for model in [
            ImputeModel::Averaging,
            ImputeModel::Ppca(PpcaParams::default()),
        ] {
            let (fill, _, _) = candidate_fill(&model, &fold.known, &sub).unwrap();
            let from_moments = moments.fill_error(&fold.keep, &fold.targets, &fold.rows, &fill);
            let filled = match &model {
                ImputeModel::Averaging => crate::impute_by_averaging(&t, &fold.known).unwrap(),
                ImputeModel::Ppca(p) => crate::impute_ppca(&t, &fold.known, p).unwrap().faces,
            };
            let direct: f64 = held
                .iter()
                .map(|&f| {
                    let (a, b) = (filled.face(f).unwrap(), t.face(f).unwrap());
                    a.iter()
                        .zip(&b)
                        .map(|(x, y)| x.distance_squared(*y))
                        .sum::<f64>()
                })
                .sum::<f64>()
                / nr;
            assert!(
                (from_moments - direct).abs() < 1e-9 * (1.0 + direct),
                "{model:?}: {from_moments} vs {direct}"
            );
        }
    }
}
