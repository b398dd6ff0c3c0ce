//! Automatic selection of the reconstruction parameters (Sand, McMillan and Popović 2003 §6.3;
//! thesis §5.5, Figure 5-4 / paper Figure 11).
//!
//! The method is documented on [`select_params`]; the module is private and
//! everything public is re-exported at the crate root.

use std::collections::HashMap;

use serde::{Deserialize, Serialize};
use skin_core::check;
use skin_core::image::Mask;
use skin_core::skeleton::Skeleton;

use crate::animate::animate;
use crate::params::ReconstructionParams;
use crate::primitive::NeedleBody;
use crate::reconstruct::NeedleModel;
use crate::silhouette_error::SilhouetteScorer;
use crate::store::ObservationStore;
use crate::surface::merged_mesh;
use crate::{Context, Error, Result, ResultExt};

/// One validation frame: a pose and the observed mask of each camera.
#[derive(Debug, Clone, Copy)]
pub struct ValidationFrame<'a> {
    /// Skeleton pose θ.
    pub theta: &'a [f64],
    /// Observed silhouettes, one per camera of the scorer.
    pub masks: &'a [Mask],
}

/// The four parameters of §6.3.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Parameter {
    /// `F_near` ([`ReconstructionParams::f_near`]).
    FNear,
    /// `F_min` ([`ReconstructionParams::f_min`]).
    FMin,
    /// `W` ([`ReconstructionParams::kernel_width_w`]).
    KernelWidthW,
    /// `N` ([`ReconstructionParams::prototype_count_n`]).
    PrototypeCountN,
}

impl Parameter {
    fn apply(self, p: ReconstructionParams, v: f64) -> ReconstructionParams {
        match self {
            Parameter::FNear => p.with_f_near(v),
            Parameter::FMin => p.with_f_min(v),
            Parameter::KernelWidthW => p.with_kernel_width_w(v),
            // Grid values of N are validated to be whole numbers ≥ 1.
            Parameter::PrototypeCountN => p.with_prototype_count_n(v as usize),
        }
    }
}

/// Grids and stopping rule of the selection.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SelectionParams {
    /// Candidate `F_near` values (fraction, in (0, 1]). Log-spaced around the paper's optimum
    /// 0.022 (§6.3). Default: [0.005, 0.01, 0.022, 0.05, 0.1, 0.2].
    pub f_near_grid: Vec<f64>,
    /// Candidate `F_min` percentiles (fraction, in [0, 1]); paper optimum 0.10 (§6.3).
    /// Default: [0.0, 0.05, 0.1, 0.2, 0.3, 0.5].
    pub f_min_grid: Vec<f64>,
    /// Candidate kernel widths `W` (> 0, see [`ReconstructionParams::kernel_width_w`]); paper
    /// optimum 7 (§6.3). Default: [1, 2, 4, 7, 10, 15].
    pub kernel_width_w_grid: Vec<f64>,
    /// Candidate prototype counts `N` (≥ 1); the paper chose 100 (§6.3).
    /// Default: [10, 25, 50, 100, 200].
    pub prototype_count_n_grid: Vec<usize>,
    /// Maximum coordinate-descent rounds (each sweeps all four parameters); stops earlier when
    /// a round changes nothing. Must be ≥ 1. Default: 2 (the paper's "repeated
    /// optimizations").
    pub rounds: usize,
    /// Relative error tolerance of the `N` rule (see [`select_params`]): the smallest `N` with
    /// `error ≤ best · (1 + tol)` is chosen. Must be finite and ≥ 0. Default: 0.01.
    pub n_relative_tolerance: f64,
}

impl Default for SelectionParams {
    fn default() -> Self {
        Self {
            f_near_grid: vec![0.005, 0.01, 0.022, 0.05, 0.1, 0.2],
            f_min_grid: vec![0.0, 0.05, 0.1, 0.2, 0.3, 0.5],
            kernel_width_w_grid: vec![1.0, 2.0, 4.0, 7.0, 10.0, 15.0],
            prototype_count_n_grid: vec![10, 25, 50, 100, 200],
            rounds: 2,
            n_relative_tolerance: 0.01,
        }
    }
}

/// The error curve of one parameter (its last sweep).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ParameterCurve {
    /// Which parameter.
    pub parameter: Parameter,
    /// Grid values.
    pub values: Vec<f64>,
    /// Mean silhouette error at each value, the others held at their values of that sweep.
    pub errors: Vec<f64>,
}

/// Result of [`select_params`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Selection {
    /// The chosen parameters (seed and unswept fields copied from the start).
    pub params: ReconstructionParams,
    /// Mean silhouette error at the chosen parameters.
    pub error: f64,
    /// Mean silhouette error at the starting parameters.
    pub start_error: f64,
    /// One curve per parameter, in the order F_near, F_min, W, N.
    pub curves: Vec<ParameterCurve>,
    /// Rounds run.
    pub rounds: usize,
    /// Distinct parameter sets evaluated (each one reconstruction).
    pub evaluations: usize,
}

/// The mean silhouette error (§6.2) over `frames` of the body reconstructed from `store` with
/// `params`; the predicted surface is [`merged_mesh`] of the animated body (same silhouette
/// as the union, see [`crate::SilhouetteScorer`]).
///
/// # Errors
/// [`Error::Empty`] without frames; errors of [`NeedleModel::reconstruct`]; errors of
/// [`animate`], [`merged_mesh`] and [`SilhouetteScorer::frame_error`] in [`Error::At`] with
/// the validation frame's [`Context::Frame`].
pub fn validation_error(
    store: &ObservationStore,
    body: &NeedleBody,
    skeleton: &Skeleton,
    scorer: &SilhouetteScorer,
    frames: &[ValidationFrame<'_>],
    params: &ReconstructionParams,
) -> Result<f64> {
    if frames.is_empty() {
        return Err(Error::Empty {
            what: "validation frames",
        });
    }
    let model = NeedleModel::reconstruct(store, body, params)?.model;
    let mut sum = 0.0;
    for (i, f) in frames.iter().enumerate() {
        sum += frame_error(body, &model, skeleton, scorer, f).at(Context::Frame(i))?;
    }
    Ok(sum / frames.len() as f64)
}

/// Silhouette error of one validation frame (the body of [`validation_error`]'s loop).
fn frame_error(
    body: &NeedleBody,
    model: &NeedleModel,
    skeleton: &Skeleton,
    scorer: &SilhouetteScorer,
    f: &ValidationFrame<'_>,
) -> Result<f64> {
    let posed = animate(body, model, skeleton, f.theta)?;
    let mesh = merged_mesh(&posed)?;
    Ok(scorer.frame_error(&mesh, f.masks)?.error)
}

fn check_grid(name: &'static str, grid: &[f64], ok: impl Fn(f64) -> bool) -> Result<()> {
    if grid.is_empty() {
        return Err(Error::InvalidParam {
            name,
            reason: "grid is empty".into(),
        });
    }
    if let Some(v) = grid.iter().find(|&&v| !(v.is_finite() && ok(v))) {
        return Err(Error::InvalidParam {
            name,
            reason: format!("grid value {v} out of range"),
        });
    }
    Ok(())
}

/// Selects `F_near`, `F_min`, `W` and `N` by coordinate descent on the validation silhouette
/// error, starting from `start` (normally [`ReconstructionParams::default`], the paper's
/// values). The returned error never exceeds the start's.
///
/// Automatic selection of the reconstruction parameters (Sand, McMillan and Popović 2003 §6.3;
/// thesis §5.5, Figure 5-4 / paper Figure 11).
///
/// "The parameter selection algorithm varies the parameters and computes the silhouette error
/// for each set of values. We perform repeated optimizations of each individual parameter to
/// account for the dependence between the parameters" (§6.3). This is coordinate descent over
/// `F_near`, `F_min`, `W` and `N` ([`ReconstructionParams`]): each parameter in turn is swept
/// over its grid with the others held at their current values, the best value is kept, and
/// the sweep repeats for [`SelectionParams::rounds`] rounds or until nothing changes. The
/// objective is the mean silhouette error (§6.2, [`crate::SilhouetteScorer`]) of the
/// reconstructed body over a set of validation frames.
///
/// `N` is special: "the error continues to decrease as more prototypes are added; we selected
/// N = 100 based on the silhouette error plot" (§6.3). The automatic rule here takes the
/// *smallest* `N` whose error is within [`SelectionParams::n_relative_tolerance`] of the best
/// `N` on the grid — the knee a person reads off the plot.
///
/// Each [`Selection::curves`] entry is the error curve of one parameter from its last sweep
/// (a Figure-11-like plot).
///
/// # Errors
/// An invalid-parameter error ([`Error::invalid_param_name`]) for an empty grid, an
/// out-of-range grid value (ranges of [`ReconstructionParams::validate`]), `rounds = 0` or a
/// bad tolerance; errors of [`validation_error`] (including an invalid `start`).
pub fn select_params(
    store: &ObservationStore,
    body: &NeedleBody,
    skeleton: &Skeleton,
    scorer: &SilhouetteScorer,
    frames: &[ValidationFrame<'_>],
    start: ReconstructionParams,
    sel: &SelectionParams,
) -> Result<Selection> {
    check_grid("f_near_grid", &sel.f_near_grid, |v| v > 0.0 && v <= 1.0)?;
    check_grid("f_min_grid", &sel.f_min_grid, |v| (0.0..=1.0).contains(&v))?;
    check_grid("kernel_width_w_grid", &sel.kernel_width_w_grid, |v| v > 0.0)?;
    let n_grid: Vec<f64> = sel
        .prototype_count_n_grid
        .iter()
        .map(|&n| n as f64)
        .collect();
    check_grid("prototype_count_n_grid", &n_grid, |v| v >= 1.0)?;
    check::nonzero("rounds", sel.rounds)?;
    check::non_negative("n_relative_tolerance", sel.n_relative_tolerance)?;
    start.validate()?;
    // Evaluations are cached by the exact parameter values.
    let mut cache: HashMap<[u64; 4], f64> = HashMap::new();
    let mut eval = |p: &ReconstructionParams| -> Result<f64> {
        let key = [
            p.f_near.to_bits(),
            p.f_min.to_bits(),
            p.kernel_width_w.to_bits(),
            p.prototype_count_n as u64,
        ];
        if let Some(&e) = cache.get(&key) {
            return Ok(e);
        }
        let e = validation_error(store, body, skeleton, scorer, frames, p)?;
        log::info!(
            "select: F_near {} F_min {} W {} N {} → error {e:.5}",
            p.f_near,
            p.f_min,
            p.kernel_width_w,
            p.prototype_count_n
        );
        cache.insert(key, e);
        Ok(e)
    };
    let start_error = eval(&start)?;
    let (mut current, mut current_error) = (start, start_error);
    let sweeps = [
        (Parameter::FNear, sel.f_near_grid.clone()),
        (Parameter::FMin, sel.f_min_grid.clone()),
        (Parameter::KernelWidthW, sel.kernel_width_w_grid.clone()),
        (Parameter::PrototypeCountN, n_grid),
    ];
    let mut curves: Vec<ParameterCurve> = Vec::new();
    let mut rounds = 0;
    for _ in 0..sel.rounds {
        rounds += 1;
        let mut changed = false;
        for (param, grid) in &sweeps {
            let errors = grid
                .iter()
                .map(|&v| eval(&param.apply(current, v)))
                .collect::<Result<Vec<f64>>>()?;
            let best = errors.iter().copied().fold(f64::INFINITY, f64::min);
            let pick = if *param == Parameter::PrototypeCountN {
                // Smallest N within tolerance of the best (grid order is not assumed).
                let limit = best * (1.0 + sel.n_relative_tolerance);
                (0..grid.len())
                    .filter(|&i| errors[i] <= limit)
                    .min_by(|&a, &b| grid[a].total_cmp(&grid[b]))
            } else {
                (0..grid.len()).find(|&i| errors[i] == best)
            };
            // `pick` exists: the grid is non-empty and `best` is one of its errors (or within
            // tolerance of itself).
            if let Some(i) = pick {
                // Never accept a worse set than the current one (keeps descent monotone).
                if errors[i] <= current_error && param.apply(current, grid[i]) != current {
                    current = param.apply(current, grid[i]);
                    current_error = errors[i];
                    changed = true;
                }
            }
            curves.retain(|c| c.parameter != *param);
            curves.push(ParameterCurve {
                parameter: *param,
                values: grid.clone(),
                errors,
            });
        }
        if !changed {
            break;
        }
    }
    Ok(Selection {
        params: current,
        error: current_error,
        start_error,
        curves,
        rounds,
        evaluations: cache.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::primitive::BodyLayout;
    use crate::silhouette_error::SilhouetteErrorParams;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Exp};
    use skin_core::camera::{Camera, Intrinsics};
    use skin_core::math::DVec3;
    use skin_core::skeleton::{human_skeleton, HumanParams};

    const TRUE_LENGTH: f32 = 0.05;

    struct Scene {
        sk: Skeleton,
        body: NeedleBody,
        store: ObservationStore,
        scorer: SilhouetteScorer,
        poses: Vec<Vec<f64>>,
        masks: Vec<Vec<Mask>>,
    }

    /// A sparse body whose true needles all have length 5 cm; observations overestimate it
    /// with one-sided exponential noise (mean 2 cm), as silhouettes do (§5); validation masks
    /// are renderings of the truth.
    fn scene() -> Scene {
        let sk = human_skeleton(&HumanParams::default()).unwrap();
        let body = NeedleBody::new(&sk, &BodyLayout::table_3_1().with_density(0.2)).unwrap();
        let mut store = ObservationStore::new(&body.store_shapes()).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let overestimate = Exp::new(1.0 / 0.02f32).unwrap(); // mean 2 cm
        let pose = |rng: &mut ChaCha8Rng| -> Vec<f64> {
            let mut th = sk.rest_pose();
            for v in th.iter_mut().skip(6) {
                *v += rng.random_range(-0.15..0.15);
            }
            th
        };
        for _ in 0..40 {
            let th = pose(&mut rng);
            let fk = sk.forward_kinematics(&th).unwrap();
            for (p, prim) in body.primitives.iter().enumerate() {
                let x = prim.config.point(&fk).unwrap();
                let obs: Vec<(u16, f32)> = (0..prim.needle_count())
                    .map(|j| {
                        let excess = overestimate.sample(&mut rng);
                        (j as u16, (TRUE_LENGTH + excess).min(0.1))
                    })
                    .collect();
                store.push_sample(p, &x, &obs).unwrap();
            }
        }
        // Truth: a model fitted to exact observations.
        let mut exact = ObservationStore::new(&body.store_shapes()).unwrap();
        let fk = sk.forward_kinematics(&sk.rest_pose()).unwrap();
        for (p, prim) in body.primitives.iter().enumerate() {
            let x = prim.config.point(&fk).unwrap();
            let obs: Vec<(u16, f32)> = (0..prim.needle_count())
                .map(|j| (j as u16, TRUE_LENGTH))
                .collect();
            exact.push_sample(p, &x, &obs).unwrap();
        }
        let truth = NeedleModel::reconstruct(
            &exact,
            &body,
            &ReconstructionParams::default().with_prototype_count_n(1),
        )
        .unwrap()
        .model;
        let poses: Vec<Vec<f64>> = (0..2).map(|_| pose(&mut rng)).collect();
        let meshes: Vec<_> = poses
            .iter()
            .map(|th| merged_mesh(&animate(&body, &truth, &sk, th).unwrap()).unwrap())
            .collect();
        let bb = meshes[0].bounding_box().unwrap();
        let c = bb.center();
        let k = Intrinsics::from_horizontal_fov(0.6, 120, 160).unwrap();
        let cams: Vec<Camera> = [DVec3::Z, DVec3::X]
            .iter()
            .map(|&d| Camera::look_at(k, c + d * 4.0, c, DVec3::Y).unwrap())
            .collect();
        let scorer = SilhouetteScorer::new(&cams, SilhouetteErrorParams::default()).unwrap();
        let masks = meshes
            .iter()
            .map(|m| {
                (0..2)
                    .map(|c| scorer.predicted_mask(m, c).unwrap())
                    .collect()
            })
            .collect();
        Scene {
            sk,
            body,
            store,
            scorer,
            poses,
            masks,
        }
    }

    #[test]
    fn selection_descends_and_prefers_low_percentiles() {
        let s = scene();
        let frames: Vec<ValidationFrame> = s
            .poses
            .iter()
            .zip(&s.masks)
            .map(|(t, m)| ValidationFrame { theta: t, masks: m })
            .collect();
        let sel = SelectionParams {
            f_near_grid: vec![0.05, 0.2],
            f_min_grid: vec![0.0, 0.5, 0.9],
            kernel_width_w_grid: vec![2.0, 7.0],
            prototype_count_n_grid: vec![5, 10],
            rounds: 2,
            n_relative_tolerance: 0.01,
        };
        let start = ReconstructionParams::default()
            .with_f_near(0.2)
            .with_f_min(0.9)
            .with_prototype_count_n(10);
        let r = select_params(&s.store, &s.body, &s.sk, &s.scorer, &frames, start, &sel).unwrap();
        assert!(r.error <= r.start_error);
        assert_eq!(r.curves.len(), 4);
        let fmin = r
            .curves
            .iter()
            .find(|c| c.parameter == Parameter::FMin)
            .unwrap();
        assert_eq!(fmin.values, sel.f_min_grid);
        // Overestimating observations: the 90th percentile is clearly worse than the minimum.
        assert!(fmin.errors[2] > fmin.errors[0], "{:?}", fmin.errors);
        assert!(r.params.f_min < 0.9);
        assert!(r.error < r.start_error);
        // The reported error is the one of the chosen parameters.
        let again =
            validation_error(&s.store, &s.body, &s.sk, &s.scorer, &frames, &r.params).unwrap();
        assert!((again - r.error).abs() < 1e-12);
    }

    #[test]
    fn bad_selection_params_are_rejected() {
        let s = scene();
        let frames = [ValidationFrame {
            theta: &s.poses[0],
            masks: &s.masks[0],
        }];
        let d = ReconstructionParams::default();
        let run = |sel: &SelectionParams| {
            select_params(&s.store, &s.body, &s.sk, &s.scorer, &frames, d, sel)
        };
        let base = SelectionParams::default();
        let cases = [
            SelectionParams {
                f_near_grid: vec![],
                ..base.clone()
            },
            SelectionParams {
                f_min_grid: vec![1.5],
                ..base.clone()
            },
            SelectionParams {
                kernel_width_w_grid: vec![f64::NAN],
                ..base.clone()
            },
            SelectionParams {
                prototype_count_n_grid: vec![0],
                ..base.clone()
            },
            SelectionParams {
                rounds: 0,
                ..base.clone()
            },
            SelectionParams {
                n_relative_tolerance: -1.0,
                ..base.clone()
            },
        ];
        for c in &cases {
            assert!(run(c).unwrap_err().invalid_param_name().is_some(), "{c:?}");
        }
        assert!(matches!(
            validation_error(&s.store, &s.body, &s.sk, &s.scorer, &[], &d),
            Err(Error::Empty { .. })
        ));
        let nan_pose = vec![f64::NAN; s.sk.dof_count()];
        let bad = [ValidationFrame {
            theta: &nan_pose,
            masks: &s.masks[0],
        }];
        let e = validation_error(&s.store, &s.body, &s.sk, &s.scorer, &bad, &d).unwrap_err();
        assert_eq!(e.contexts(), vec![Context::Frame(0)], "{e}");
    }
}
