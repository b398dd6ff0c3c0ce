//! The joint least-squares fit of the ellipsoid model (Fua et al. §5.1, Eq. 8): the
//! assignment of observations to ellipsoids (§5.2), Levenberg–Marquardt on the normal
//! equations in blocks (Schur complement on the shared unknowns), IRLS with Tukey's biweight
//! (§5.2); one frame or several with shared lengths and widths.

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use skin_core::math::DVec3;
use skin_core::{check, Context};

use super::model::{EllipsoidModel, EllipsoidState, Eval};
use super::observations::{check_observations, EllipsoidObservations};
use super::params::EllipsoidParams;
use crate::error::{Error, Result, ResultExt};

/// Result of [`fit_ellipsoids`].
#[derive(Debug, Clone)]
pub struct EllipsoidFit {
    /// The fitted state.
    pub state: EllipsoidState,
    /// Weighted cost `Σ P w_irls e²` at the end of each IRLS round.
    pub round_costs: Vec<f64>,
    /// Observations (points + rays + markers) each bone holds with non-zero weight at the end.
    pub observations_per_bone: Vec<usize>,
    /// Points given zero weight by the last IRLS round.
    pub rejected_points: usize,
    /// Per IRLS round that reweighted, for points, rays and markers: the fraction of the
    /// type's observations the previous round rejected (0 in the first round; NaN for a
    /// type without observations).
    pub irls_rejected: Vec<[f64; 3]>,
    /// Per IRLS round that reweighted, for points, rays and markers: whether the robust scale
    /// came from the kept observations ([`EllipsoidParams::kept_scale_min_rejected`]).
    pub irls_scale_from_kept: Vec<[bool; 3]>,
}

/// Kind of an observation row (for σ and IRLS scale).
#[derive(Clone, Copy, PartialEq, Eq)]
enum Kind {
    Point,
    Ray,
    Marker,
}

/// Bones kept per point or ray between two IRLS rounds: the assignment of §5.2 is re-done
/// every LM iteration among the `CANDIDATES` bones of smallest `|e|` at the round's start
/// (the pruning that makes an iteration cost 2 evaluations per observation instead of one
/// per bone); every round and the final count assign among all bones.
const CANDIDATES: usize = 2;

/// Observations per parallel chunk (fixed, so sums are identical for any thread count).
const CHUNK: usize = 256;

/// One frame of the problem.
pub(super) struct FrameData<'a> {
    pub(super) obs: &'a EllipsoidObservations,
    pub(super) start_theta: &'a [f64],
    /// Markers actually seen: (bone, position).
    pub(super) markers: Vec<(usize, DVec3)>,
    /// IRLS weight per observation (points, rays, markers in order).
    pub(super) robust: Vec<f64>,
    /// Candidate bones per point and ray.
    pub(super) candidates: Vec<[usize; CANDIDATES]>,
}

impl FrameData<'_> {
    pub(super) fn n_obs(&self) -> usize {
        self.obs.points.len() + self.obs.rays.len() + self.markers.len()
    }

    fn kind(&self, i: usize) -> Kind {
        let (np, nr) = (self.obs.points.len(), self.obs.rays.len());
        if i < np {
            Kind::Point
        } else if i < np + nr {
            Kind::Ray
        } else {
            Kind::Marker
        }
    }
}

/// A frame's part of the normal equations, in local indices: θ of the frame first, then
/// the shared scales, widths, half-lengths.
struct FrameLin {
    cost: f64,
    /// Unweighted residual and bone per observation (only from a full assignment).
    residuals: Vec<(f64, usize)>,
    /// Best bones per point and ray (only from a full assignment).
    candidates: Vec<[usize; CANDIDATES]>,
    h: DMatrix<f64>,
    g: DVector<f64>,
}

/// The normal equations of the multi-frame problem in blocks (the state: every frame's θ,
/// then the shared unknowns): per frame the pose block `A_f`, its coupling `B_f` to the
/// shared unknowns and its gradient `g_f`; the shared block `C` and gradient `g_s`.
pub(super) struct Normal {
    pub(super) a: Vec<DMatrix<f64>>,
    pub(super) b: Vec<DMatrix<f64>>,
    pub(super) gf: Vec<DVector<f64>>,
    pub(super) c: DMatrix<f64>,
    pub(super) gs: DVector<f64>,
}

impl Normal {
    /// The gradient in the state's layout.
    #[cfg(test)]
    pub(super) fn gradient(&self) -> DVector<f64> {
        let mut v: Vec<f64> = self.gf.iter().flat_map(|g| g.iter().copied()).collect();
        v.extend(self.gs.iter());
        DVector::from_vec(v)
    }

    /// Solves `(H + λ·diag(H)) x = g` by the Schur complement on the shared block (per-frame
    /// Cholesky of the pose blocks, then one of the shared block): `O(F·n_θ³ + n_s³)` instead
    /// of `O((F·n_θ + n_s)³)`. With `pose_only` the shared part of `x` is zero. `None` when a
    /// block is not positive definite.
    pub(super) fn solve(&self, lambda: f64, pose_only: bool) -> Option<DVector<f64>> {
        let nf = self.a.len();
        let nd = self.gf.first().map_or(0, |g| g.len());
        let ns = self.gs.len();
        let damp = |m: &DMatrix<f64>| {
            let mut m = m.clone();
            for k in 0..m.nrows() {
                m[(k, k)] += lambda * (m[(k, k)] + 1e-9);
            }
            m
        };
        let mut x = DVector::zeros(nf * nd + ns);
        let mut s = damp(&self.c);
        let mut r = self.gs.clone();
        let mut parts = Vec::with_capacity(nf);
        for f in 0..nf {
            let chol = damp(&self.a[f]).cholesky()?;
            let y = chol.solve(&self.gf[f]);
            if pose_only {
                x.rows_mut(f * nd, nd).copy_from(&y);
                continue;
            }
            let xb = chol.solve(&self.b[f]);
            let bt = self.b[f].transpose();
            s -= &bt * &xb;
            r -= &bt * &y;
            parts.push((y, xb));
        }
        if pose_only {
            return Some(x);
        }
        let ds = s.cholesky()?.solve(&r);
        for (f, (y, xb)) in parts.into_iter().enumerate() {
            x.rows_mut(f * nd, nd).copy_from(&(y - xb * &ds));
        }
        x.rows_mut(nf * nd, ns).copy_from(&ds);
        Some(x)
    }
}

pub(super) struct Problem<'a> {
    pub(super) model: &'a EllipsoidModel,
    pub(super) params: &'a EllipsoidParams,
    /// Start of the shared unknowns (the first frame's).
    pub(super) start: &'a EllipsoidState,
    pub(super) frames: Vec<FrameData<'a>>,
}

impl Problem<'_> {
    fn sigma(&self, kind: Kind) -> f64 {
        match kind {
            Kind::Point => self.params.sigma_point_m,
            Kind::Ray => self.params.sigma_silhouette_m,
            Kind::Marker => self.params.sigma_marker_m,
        }
    }

    fn local_size(&self) -> usize {
        self.model.skeleton.dof_count() + 3 * self.model.bones.len()
    }

    /// Cost (and, when `jac`, local normal equations) of frame `f` at `state`. `full`:
    /// assign among all bones and return residuals and candidates; otherwise among the
    /// round's candidates, skipping observations of zero IRLS weight.
    fn linearise_frame(
        &self,
        f: usize,
        state: &EllipsoidState,
        jac: bool,
        full: bool,
    ) -> Result<FrameLin> {
        let model = self.model;
        let frame = &self.frames[f];
        let nd = model.skeleton.dof_count();
        let nb = model.bones.len();
        let nl = self.local_size();
        let sk = model.scaled_skeleton(state)?;
        let fk = sk.forward_kinematics(&state.theta)?;
        let frames = fk.world_from_joint();
        let axes = fk.dof_axes_world();
        let origins = fk.dof_origins_world();
        // World direction each bone scale moves its child joint along (R_parent · offset).
        let scale_dirs: Vec<DVec3> = model
            .bones
            .iter()
            .enumerate()
            .map(|(b, bone)| frames[bone.parent].matrix3 * (model.axes[b] * model.lengths[b]))
            .collect();
        let np = frame.obs.points.len();
        let nr = frame.obs.rays.len();
        let n_obs = frame.n_obs();
        let chunk = |range: std::ops::Range<usize>| -> FrameLin {
            let (mut h, mut g) = if jac {
                (DMatrix::zeros(nl, nl), DVector::zeros(nl))
            } else {
                (DMatrix::zeros(0, 0), DVector::zeros(0))
            };
            let mut cost = 0.0;
            let mut residuals = Vec::new();
            let mut candidates = Vec::new();
            let mut row: Vec<(usize, f64)> = Vec::with_capacity(64);
            for i in range {
                let kind = frame.kind(i);
                if !full && frame.robust[i] == 0.0 {
                    continue;
                }
                let x_of = |b: usize| {
                    if kind == Kind::Point {
                        frame.obs.points[i]
                    } else {
                        model.ray_point(frames, state, b, &frame.obs.rays[i - np])
                    }
                };
                // Assignment (§5.2): the bone with the smallest |e|.
                let (b, x, ev) = match kind {
                    Kind::Marker => {
                        let (b, x) = frame.markers[i - np - nr];
                        let mut ev = model.eval(frames, state, b, x);
                        ev.e -= self.params.marker_offset_m;
                        (b, x, ev)
                    }
                    Kind::Point | Kind::Ray if full => {
                        let mut best: [(f64, usize); CANDIDATES] = [(f64::MAX, 0); CANDIDATES];
                        let mut chosen: Option<(usize, DVec3, Eval)> = None;
                        for b in 0..nb {
                            let x = x_of(b);
                            let ev = model.eval(frames, state, b, x);
                            let a = ev.e.abs();
                            if let Some(pos) = best.iter().position(|&(e, _)| a < e) {
                                best[pos..].rotate_right(1);
                                best[pos] = (a, b);
                            }
                            if chosen.as_ref().is_none_or(|(_, _, e)| a < e.e.abs()) {
                                chosen = Some((b, x, ev));
                            }
                        }
                        candidates.push(best.map(|(_, b)| b));
                        match chosen {
                            Some(v) => v,
                            None => continue,
                        }
                    }
                    Kind::Point | Kind::Ray => {
                        let mut chosen: Option<(usize, DVec3, Eval)> = None;
                        for &b in &frame.candidates[i] {
                            let x = x_of(b);
                            let ev = model.eval(frames, state, b, x);
                            if chosen
                                .as_ref()
                                .is_none_or(|(_, _, e)| ev.e.abs() < e.e.abs())
                            {
                                chosen = Some((b, x, ev));
                            }
                        }
                        match chosen {
                            Some(v) => v,
                            None => continue,
                        }
                    }
                };
                if full {
                    residuals.push((ev.e, b));
                }
                let sigma = self.sigma(kind);
                let weight = frame.robust[i] / (sigma * sigma);
                if weight == 0.0 {
                    continue;
                }
                cost += weight * ev.e * ev.e;
                if !jac {
                    continue;
                }
                row.clear();
                let p = model.bones[b].parent;
                for &k in sk.chain_dofs(p) {
                    let v = if sk.is_rotation(k) {
                        axes[k].cross(x - origins[k])
                    } else {
                        axes[k]
                    };
                    row.push((k, -ev.grad_world.dot(v)));
                }
                let mut own = ev.d_own_scale;
                for &m in &model.chain_bones[p] {
                    let d = -ev.grad_world.dot(scale_dirs[m]);
                    if m == b {
                        own += d;
                    } else {
                        row.push((nd + m, d));
                    }
                }
                row.push((nd + b, own));
                row.push((nd + nb + b, ev.d_width));
                row.push((nd + 2 * nb + b, ev.d_half_length));
                // The upper triangle (row indices ascend within a row's blocks; mirrored
                // below).
                for (i, &(r, jr)) in row.iter().enumerate() {
                    let wr = weight * jr;
                    g[r] += wr * ev.e;
                    for &(c, jc) in &row[i..] {
                        let (lo, hi) = if r <= c { (r, c) } else { (c, r) };
                        h[(lo, hi)] += wr * jc;
                    }
                }
            }
            FrameLin {
                cost,
                residuals,
                candidates,
                h,
                g,
            }
        };
        let starts: Vec<usize> = (0..n_obs).step_by(CHUNK).collect();
        let parts: Vec<FrameLin> = starts
            .par_iter()
            .map(|&s| chunk(s..(s + CHUNK).min(n_obs)))
            .collect();
        let mut total = FrameLin {
            cost: 0.0,
            residuals: Vec::new(),
            candidates: Vec::new(),
            h: if jac {
                DMatrix::zeros(nl, nl)
            } else {
                DMatrix::zeros(0, 0)
            },
            g: if jac {
                DVector::zeros(nl)
            } else {
                DVector::zeros(0)
            },
        };
        for mut p in parts {
            if jac {
                // Mirror the upper triangle accumulated per observation.
                for c in 0..nl {
                    for r in c + 1..nl {
                        p.h[(r, c)] = p.h[(c, r)];
                    }
                }
            }
            total.cost += p.cost;
            total.residuals.extend(p.residuals);
            total.candidates.extend(p.candidates);
            if jac {
                total.h += p.h;
                total.g += p.g;
            }
        }
        // The θ prior of this frame (a pseudo-observation type, Eq. 7).
        let pr = 1.0 / (self.params.sigma_theta_prior * self.params.sigma_theta_prior);
        let ptr = self
            .params
            .sigma_translation_prior_m
            .map_or(pr, |s| 1.0 / (s * s));
        for k in 0..nd {
            let pt = if sk.is_rotation(k) { pr } else { ptr };
            let r = state.theta[k] - frame.start_theta[k];
            total.cost += pt * r * r;
            if jac {
                total.h[(k, k)] += pt;
                total.g[k] += pt * r;
            }
        }
        Ok(total)
    }

    /// Cost and (when `jac`) the normal equations in blocks at `states` (one per frame,
    /// shared unknowns equal); the frames are linearised in parallel.
    pub(super) fn linearise(
        &self,
        states: &[EllipsoidState],
        jac: bool,
    ) -> Result<(f64, Option<Normal>)> {
        let nd = self.model.skeleton.dof_count();
        let nb = self.model.bones.len();
        let ns = 3 * nb;
        let lins: Vec<FrameLin> = states
            .par_iter()
            .enumerate()
            .map(|(f, state)| {
                self.linearise_frame(f, state, jac, false)
                    .at(Context::Frame(f))
            })
            .collect::<Result<_>>()?;
        let mut cost: f64 = lins.iter().map(|l| l.cost).sum();
        let mut normal = jac.then(|| Normal {
            a: Vec::with_capacity(lins.len()),
            b: Vec::with_capacity(lins.len()),
            gf: Vec::with_capacity(lins.len()),
            c: DMatrix::zeros(ns, ns),
            gs: DVector::zeros(ns),
        });
        if let Some(n) = normal.as_mut() {
            for lin in &lins {
                n.a.push(lin.h.view((0, 0), (nd, nd)).into_owned());
                n.b.push(lin.h.view((0, nd), (nd, ns)).into_owned());
                n.gf.push(lin.g.rows(0, nd).into_owned());
                n.c += lin.h.view((nd, nd), (ns, ns));
                n.gs += lin.g.rows(nd, ns);
            }
        }
        // Priors on the shared unknowns (a pseudo-observation type each, Eq. 7).
        let s = &states[0];
        for b in 0..nb {
            for (k, r, sigma) in [
                (
                    b,
                    s.length_scale[b] - 1.0,
                    if self.model.bones[b].child.is_some() {
                        self.params.sigma_scale_prior
                    } else {
                        self.params.sigma_end_site_scale_prior
                    },
                ),
                (
                    nb + b,
                    s.half_width[b] - self.start.half_width[b],
                    self.params.sigma_width_prior_m,
                ),
                (
                    2 * nb + b,
                    s.half_length[b] - self.start.half_length[b],
                    self.params.sigma_half_length_prior_m,
                ),
            ] {
                let p = 1.0 / (sigma * sigma);
                cost += p * r * r;
                if let Some(n) = normal.as_mut() {
                    n.c[(k, k)] += p;
                    n.gs[k] += p * r;
                }
            }
        }
        Ok((cost, normal))
    }

    fn step(&self, states: &[EllipsoidState], delta: &DVector<f64>) -> Vec<EllipsoidState> {
        let nd = self.model.skeleton.dof_count();
        let nb = self.model.bones.len();
        let base = self.frames.len() * nd;
        let (lo, hi) = self.params.scale_range;
        let floor = self.params.min_half_width_m;
        let s = &states[0];
        let length_scale: Vec<f64> = (0..nb)
            .map(|b| (s.length_scale[b] + delta[base + b]).clamp(lo, hi))
            .collect();
        let half_width: Vec<f64> = (0..nb)
            .map(|b| (s.half_width[b] + delta[base + nb + b]).max(floor))
            .collect();
        let half_length: Vec<f64> = (0..nb)
            .map(|b| (s.half_length[b] + delta[base + 2 * nb + b]).max(floor))
            .collect();
        states
            .iter()
            .enumerate()
            .map(|(f, st)| EllipsoidState {
                theta: (0..nd).map(|k| st.theta[k] + delta[f * nd + k]).collect(),
                length_scale: length_scale.clone(),
                half_width: half_width.clone(),
                half_length: half_length.clone(),
            })
            .collect()
    }

    /// Levenberg–Marquardt at fixed IRLS weights and candidates; with `pose_only` the shared
    /// unknowns are held.
    fn solve(
        &self,
        mut states: Vec<EllipsoidState>,
        pose_only: bool,
    ) -> Result<(Vec<EllipsoidState>, f64)> {
        let mut lambda = 1e-3;
        let (mut cost, normal) = self.linearise(&states, true)?;
        let mut normal = normal.ok_or(Error::Empty {
            what: "normal equations",
        })?;
        for _ in 0..self.params.lm_iterations {
            let mut accepted = false;
            while lambda < 1e12 {
                let Some(x) = normal.solve(lambda, pose_only) else {
                    lambda *= 10.0;
                    continue;
                };
                let delta = -x;
                let trial = self.step(&states, &delta);
                // Linearised at once: most trials are accepted (measured: 41 of 46 on the
                // studio), so the cost-only pass would be followed by this one anyway.
                let (trial_cost, trial_normal) = self.linearise(&trial, true)?;
                if trial_cost < cost {
                    // Converged: a step below 1 µm / µrad or a small relative decrease.
                    let small =
                        delta.amax() < 1e-6 || cost - trial_cost < self.params.lm_tolerance * cost;
                    states = trial;
                    cost = trial_cost;
                    if let Some(n) = trial_normal {
                        normal = n;
                    }
                    lambda = (lambda * 0.3).max(1e-9);
                    accepted = !small;
                    break;
                }
                lambda *= 10.0;
            }
            if !accepted {
                break;
            }
        }
        Ok((states, cost))
    }

    /// Full assignment of every frame at `states`: residuals per frame; refreshes the
    /// candidates.
    pub(super) fn assign(&mut self, states: &[EllipsoidState]) -> Result<Vec<Vec<(f64, usize)>>> {
        let mut out = Vec::with_capacity(states.len());
        for (f, state) in states.iter().enumerate() {
            let lin = self
                .linearise_frame(f, state, false, true)
                .at(Context::Frame(f))?;
            self.frames[f].candidates = lin.candidates;
            out.push(lin.residuals);
        }
        Ok(out)
    }
}

/// Result of [`fit_ellipsoids_multi`].
#[derive(Debug, Clone)]
pub struct EllipsoidMultiFit {
    /// The fitted state of each frame (the same lengths, widths and half-lengths in all).
    pub states: Vec<EllipsoidState>,
    /// Weighted cost at the end of each IRLS round (all frames).
    pub round_costs: Vec<f64>,
    /// Observations each bone holds with non-zero weight at the end, summed over frames.
    pub observations_per_bone: Vec<usize>,
    /// Points given zero weight by the last IRLS round, per frame.
    pub rejected_points: Vec<usize>,
    /// Per frame, per attractor point: the bone holding it at the end (`None`: zero weight).
    pub point_bones: Vec<Vec<Option<usize>>>,
    /// As [`EllipsoidFit::irls_rejected`] (pooled over the frames).
    pub irls_rejected: Vec<[f64; 3]>,
    /// As [`EllipsoidFit::irls_scale_from_kept`].
    pub irls_scale_from_kept: Vec<[bool; 3]>,
}

/// Fits the articulated ellipsoid model to one frame's observations by joint least squares
/// (§5.1, Eq. 8) with IRLS (§5.2), starting from `initial`: [`fit_ellipsoids_multi`] with
/// one frame.
///
/// Points on the limb ellipsoids of a performer in the rest pose whose half-widths are 6 cm,
/// fitted from the default 4 cm:
///
/// ```
/// use skin_core::skeleton::{human_skeleton, HumanParams};
/// use template_silhouette::{
///     fit_ellipsoids, EllipsoidModel, EllipsoidObservations, EllipsoidParams,
/// };
///
/// let model = EllipsoidModel::limbs(human_skeleton(&HumanParams::default())?, 0.1)?;
/// let rest = model.skeleton().rest_pose();
/// let truth = model.initial_state(&rest, 0.06)?;
/// let mut points = Vec::new();
/// for e in model.ellipsoids(&truth)? {
///     let (side, up) = e.axis.any_orthonormal_pair();
///     for i in 0..15 {
///         for j in 0..12 {
///             let t = -0.9 + 1.8 * f64::from(i) / 14.0;
///             let phi = std::f64::consts::TAU * f64::from(j) / 12.0;
///             let r = e.half_width * (1.0 - t * t).sqrt();
///             let around = side * phi.cos() + up * phi.sin();
///             points.push(e.centre + e.axis * (t * e.half_length) + around * r);
///         }
///     }
/// }
/// let obs = EllipsoidObservations { points, ..Default::default() };
/// let start = model.initial_state(&rest, 0.04)?;
/// let fit = fit_ellipsoids(&model, &start, &obs, &EllipsoidParams::default())?;
/// for w in &fit.state.half_width {
///     assert!((w - 0.06).abs() < 0.005, "half-width {w} m");
/// }
/// # Ok::<(), template_silhouette::Error>(())
/// ```
///
/// # Errors
/// As [`fit_ellipsoids_multi`].
pub fn fit_ellipsoids(
    model: &EllipsoidModel,
    initial: &EllipsoidState,
    obs: &EllipsoidObservations,
    params: &EllipsoidParams,
) -> Result<EllipsoidFit> {
    let multi = fit_ellipsoids_multi(
        model,
        std::slice::from_ref(initial),
        std::slice::from_ref(obs),
        params,
    )?;
    let state = multi.states.into_iter().next().ok_or(Error::Empty {
        what: "fitted frames",
    })?;
    Ok(EllipsoidFit {
        state,
        round_costs: multi.round_costs,
        observations_per_bone: multi.observations_per_bone,
        rejected_points: multi.rejected_points.iter().sum(),
        irls_rejected: multi.irls_rejected,
        irls_scale_from_kept: multi.irls_scale_from_kept,
    })
}

/// Fits the articulated ellipsoid model to several frames of one performer at once (§5: the
/// paper fits over sequences): the length scales, half-widths and half-lengths are shared,
/// each frame has its own pose θ. A straight chain's inner joint slides along the limb in one
/// frame; a frame where the chain bends pins it, so the shared lengths are observable.
/// `initial[f]` gives frame `f`'s starting pose; the shared unknowns start from `initial[0]`.
/// With one frame this is [`fit_ellipsoids`].
///
/// # Errors
/// Invalid parameters, states of the wrong size, `initial` and `obs` of different lengths or
/// empty, non-finite observations, a marker on a bone that does not exist (each wrapped in
/// [`Error::At`] with [`Context::Frame`] when there are several frames); [`Error::Empty`] without
/// any observation; for a bone left with fewer than
/// [`EllipsoidParams::min_observations_per_bone`] weighted observations over all frames ("no
/// points near a limb") an [`Error::Empty`] and for a half-width that ended on
/// [`EllipsoidParams::min_half_width_m`] (a collapsed ellipsoid) an
/// [`skin_core::Error::Degenerate`] (inside [`Error::Core`]), both wrapped in [`Error::At`]
/// with the bone's child joint as [`Context::Joint`].
pub fn fit_ellipsoids_multi(
    model: &EllipsoidModel,
    initial: &[EllipsoidState],
    obs: &[EllipsoidObservations],
    params: &EllipsoidParams,
) -> Result<EllipsoidMultiFit> {
    params.validate()?;
    check::nonzero("frames", initial.len())?;
    check::same_size("observation frames", initial.len(), obs.len())?;
    let nb = model.bones.len();
    let mut frames = Vec::with_capacity(obs.len());
    for (f, (s, o)) in initial.iter().zip(obs).enumerate() {
        // One frame's errors name the frame when there are several.
        let in_frame = |r: Result<()>| {
            if obs.len() > 1 {
                r.at(Context::Frame(f))
            } else {
                r
            }
        };
        in_frame(model.check_state(s))?;
        let mut markers = Vec::new();
        in_frame(check_observations(model, o).map(|m| markers = m))?;
        let mut frame = FrameData {
            obs: o,
            start_theta: &s.theta,
            markers,
            robust: Vec::new(),
            candidates: Vec::new(),
        };
        frame.robust = vec![1.0; frame.n_obs()];
        frames.push(frame);
    }
    if frames.iter().all(|f| f.n_obs() == 0) {
        return Err(Error::Empty {
            what: "ellipsoid observations (give points, markers or silhouette rays in at least \
                   one frame)",
        });
    }
    let mut problem = Problem {
        model,
        params,
        start: &initial[0],
        frames,
    };
    let shared = &initial[0];
    let mut states: Vec<EllipsoidState> = initial
        .iter()
        .map(|s| EllipsoidState {
            theta: s.theta.clone(),
            ..shared.clone()
        })
        .collect();
    let mut round_costs = Vec::new();
    let (mut irls_rejected, mut irls_scale_from_kept) = (Vec::new(), Vec::new());
    for round in 0..params.irls_rounds {
        let residuals = problem.assign(&states)?;
        if params.irls_rounds > 1 {
            let (rejected, from_kept) = reweight(&mut problem, &residuals);
            irls_rejected.push(rejected);
            irls_scale_from_kept.push(from_kept);
        }
        let pose_only =
            params.pose_only || (round < params.pose_only_rounds && round + 1 < params.irls_rounds);
        let (s, cost) = problem.solve(states, pose_only)?;
        states = s;
        round_costs.push(cost);
    }
    let residuals = problem.assign(&states)?;
    let mut observations_per_bone = vec![0; nb];
    let mut rejected_points = Vec::with_capacity(states.len());
    let mut point_bones = Vec::with_capacity(states.len());
    for (frame, res) in problem.frames.iter().zip(&residuals) {
        point_bones.push(
            (0..frame.obs.points.len())
                .map(|i| (frame.robust[i] > 0.0).then_some(res[i].1))
                .collect(),
        );
        for (i, &(_, b)) in res.iter().enumerate() {
            if frame.robust[i] > 0.0 {
                observations_per_bone[b] += 1;
            }
        }
        rejected_points.push(
            (0..frame.obs.points.len())
                .filter(|&i| frame.robust[i] == 0.0)
                .count(),
        );
    }
    let state = &states[0];
    for (b, bone) in model.bones.iter().enumerate() {
        if observations_per_bone[b] < params.min_observations_per_bone {
            return Err(Error::Empty {
                what: "observations near the bone's ellipsoid (fewer than \
                       min_observations_per_bone: start from a closer pose, observe this limb, \
                       or leave the bone out of the model)",
            })
            .at(Context::Joint(bone.joint()));
        }
        if !params.pose_only && state.half_width[b] <= params.min_half_width_m * (1.0 + 1e-9) {
            return Err(Error::Core(skin_core::Error::Degenerate {
                what: format!(
                    "ellipsoid collapsed to the minimum half-width {} m; start from a closer \
                     pose, or lower min_half_width_m for a thinner limb",
                    params.min_half_width_m
                ),
            }))
            .at(Context::Joint(bone.joint()));
        }
    }
    Ok(EllipsoidMultiFit {
        states,
        round_costs,
        observations_per_bone,
        rejected_points,
        point_bones,
        irls_rejected,
        irls_scale_from_kept,
    })
}

/// IRLS weights (§5.2): Tukey's biweight of each residual over a robust scale of its type
/// (pooled over the frames). Returns, for points, rays and markers, the fraction of the
/// type's observations the previous weights rejected (NaN without observations) and whether
/// the scale came from the kept ones ([`EllipsoidParams::kept_scale_min_rejected`]).
fn reweight(problem: &mut Problem<'_>, residuals: &[Vec<(f64, usize)>]) -> ([f64; 3], [bool; 3]) {
    let mut rejected = [f64::NAN; 3];
    let mut from_kept = [false; 3];
    for (t, kind) in [Kind::Point, Kind::Ray, Kind::Marker]
        .into_iter()
        .enumerate()
    {
        let abs_of = |kept_only: bool| -> Vec<f64> {
            problem
                .frames
                .iter()
                .zip(residuals)
                .flat_map(|(frame, res)| {
                    (0..res.len())
                        .filter(move |&i| {
                            frame.kind(i) == kind && (!kept_only || frame.robust[i] > 0.0)
                        })
                        .map(move |i| res[i].0.abs())
                })
                .collect()
        };
        let all = abs_of(false);
        if all.is_empty() {
            continue;
        }
        let kept = abs_of(true);
        let fraction = 1.0 - kept.len() as f64 / all.len() as f64;
        rejected[t] = fraction;
        // The kept observations' scale once the previous round rejected a large fraction
        // (gross outliers inflate the median of all |e|; see the parameter's docs).
        from_kept[t] = !kept.is_empty()
            && problem
                .params
                .kept_scale_min_rejected
                .is_some_and(|min| fraction >= min);
        let mut abs = if from_kept[t] { kept } else { all };
        abs.sort_by(f64::total_cmp);
        let median = abs[abs.len() / 2];
        let scale = (1.4826 * median).max(problem.sigma(kind));
        let c = problem.params.tukey_c * scale;
        for (frame, res) in problem.frames.iter_mut().zip(residuals) {
            for (i, &(e, _)) in res.iter().enumerate() {
                if frame.kind(i) != kind {
                    continue;
                }
                let r = e / c;
                frame.robust[i] = if r.abs() < 1.0 {
                    (1.0 - r * r).powi(2)
                } else {
                    0.0
                };
            }
        }
    }
    (rejected, from_kept)
}
