//! Automatic first-frame initialisation of the template tracker: the
//! thesis needed a user's constraints on the first frame (Vlasic 2010 §2.3.3); here a global
//! search over the articulated ellipsoid model (Fua et al. §4.2) scored against the frame's
//! visual hull, then the robust local fit of §5 ([`fit_ellipsoids`]) from the tracker's own
//! inputs (visual-hull surface samples as attractors, silhouette contour rays; no markers, no
//! stereo points).
//!
//! The global step, in order:
//! 1. **Root position**: the hull samples' centroid.
//! 2. **Heading**: the root's rotation about the vertical aligns the rest model's principal
//!    horizontal axis with the hull's, both signs, ± a few steps
//!    ([`AutoInitParams::heading_offsets_deg`]); every candidate is scored with the rest
//!    limbs, and the best of each sign goes on.
//! 3. **Coordinate search** per joint, top down ([`AutoInitParams::sweeps`] sweeps): every
//!    joint that moves an ellipsoid tries a grid of its swing (first two rotation DOFs) and
//!    its moving children's first rotation DOF over their limits
//!    ([`AutoInitParams::grid_steps`] values each: e.g. an arm down / out / forward / up with
//!    the elbow straight / bent), keeping the best; the root's height tries ±
//!    [`AutoInitParams::root_height_steps_m`]; then a local descent over every DOF with
//!    shrinking steps ([`AutoInitParams::refine_steps_deg`]).
//!
//! The score is a truncated chamfer cost: each hull sample's distance to the nearest
//! ellipsoid surface (radial approximation), and each ellipsoid's axis samples' distance
//! outside the hull ([`ContourRayHull::distance`]), both truncated at
//! [`AutoInitParams::truncation_m`] so a wrong limb costs a bounded amount.

use rayon::prelude::*;
use skin_core::check;
use skin_core::math::DVec3;
use skin_core::skeleton::Skeleton;

use crate::ellipsoid::{
    fit_ellipsoids, Ellipsoid, EllipsoidFit, EllipsoidModel, EllipsoidObservations,
    EllipsoidParams, EllipsoidState,
};
use crate::error::{Error, Result};
use crate::silhouette_constraints::ContourRay;
use crate::visual_hull::ContourRayHull;

/// Parameters of [`initialise_pose`]. Neither paper gives numbers (the thesis' start is
/// manual); the defaults are ours and documented per field.
#[derive(Debug, Clone, PartialEq)]
pub struct AutoInitParams {
    /// Hull surface samples used as attractors (the hull polygon's vertices, evenly
    /// subsampled). Default 600.
    pub points: usize,
    /// Truncation of the global score's distances, metres. Default 0.08 (a limb's width
    /// and a half: a limb placed wrongly costs the same wherever it is).
    pub truncation_m: f64,
    /// Starting half-width of every ellipsoid, metres. Default 0.05.
    pub half_width_m: f64,
    /// Values per rotation DOF in the coordinate search, spread evenly over its limits
    /// (unlimited DOFs: over ±90°). Default 5.
    pub grid_steps: usize,
    /// Top-down sweeps of the coordinate search. Default 2 (the second lets a parent move
    /// once its children are bent).
    pub sweeps: usize,
    /// Heading offsets tried around each sign of the principal axis, degrees. Default
    /// −30, −15, 0, 15, 30.
    pub heading_offsets_deg: Vec<f64>,
    /// Root height offsets tried in each sweep, metres. Default −0.15…0.15 every 0.05.
    pub root_height_steps_m: Vec<f64>,
    /// Steps of the local descent after each sweep's grid, degrees (root translations: 0.2 cm
    /// per degree). Default 16, 8, 4, 2.
    pub refine_steps_deg: Vec<f64>,
    /// Samples along each ellipsoid's axis for the "inside the hull" term. Default 5.
    pub axis_samples: usize,
    /// The world's up direction (the heading turns about the root's rotation DOF closest to
    /// it). Default +Y (the studio's).
    pub up: DVec3,
    /// A known heading: the value of the root's rotation DOF about the vertical (radians,
    /// e.g. tracked from the previous frames, as [`crate::size_performer`] does). The heading
    /// step then tries [`AutoInitParams::heading_offsets_deg`] around it only, instead of
    /// both signs of the hull's principal axis. Default `None`.
    pub heading_hint_rad: Option<f64>,
    /// Parameters of the local robust fit after the global step. Default
    /// [`EllipsoidParams::default`] with `sigma_point_m` 0.02 (hull samples lie outside the
    /// body by the hull's excess; measured in the `ellipsoid_fit` example).
    pub fit: EllipsoidParams,
}

impl Default for AutoInitParams {
    fn default() -> Self {
        AutoInitParams {
            points: 600,
            truncation_m: 0.08,
            half_width_m: 0.05,
            grid_steps: 5,
            sweeps: 2,
            heading_offsets_deg: vec![-30.0, -15.0, 0.0, 15.0, 30.0],
            root_height_steps_m: vec![-0.15, -0.1, -0.05, 0.0, 0.05, 0.1, 0.15],
            refine_steps_deg: vec![16.0, 8.0, 4.0, 2.0],
            axis_samples: 5,
            up: DVec3::Y,
            heading_hint_rad: None,
            fit: EllipsoidParams {
                sigma_point_m: 0.02,
                ..EllipsoidParams::default()
            },
        }
    }
}

impl AutoInitParams {
    fn validate(&self) -> Result<()> {
        check::nonzero("points", self.points)?;
        check::positive("truncation_m", self.truncation_m)?;
        check::positive("half_width_m", self.half_width_m)?;
        check::nonzero("grid_steps", self.grid_steps)?;
        check::nonzero("axis_samples", self.axis_samples)?;
        if self.heading_offsets_deg.is_empty() {
            return Err(Error::Empty {
                what: "heading offsets (0° is one)",
            });
        }
        for &h in self
            .heading_offsets_deg
            .iter()
            .chain(&self.root_height_steps_m)
            .chain(&self.heading_hint_rad)
        {
            check::finite("heading/height offset", h)?;
        }
        if !(self.up.is_finite() && self.up.length() > 0.0) {
            return Err(Error::NonFinite {
                what: "up (give a finite, non-zero vertical direction)",
            });
        }
        Ok(())
    }
}

/// Result of [`initialise_pose`].
#[derive(Debug, Clone)]
pub struct AutoInit {
    /// The pose after the global search (before the local fit), default proportions.
    pub global: EllipsoidState,
    /// The global score of [`AutoInit::global`].
    pub global_cost: f64,
    /// The local robust fit from [`AutoInit::global`].
    pub fit: EllipsoidFit,
    /// Whether the fit (its pose, lengths and widths) scores lower than [`AutoInit::global`] on
    /// the global score, hence its pose is kept as the first pose.
    pub fit_kept: bool,
    /// Candidate poses scored by the global search.
    pub evaluations: usize,
    /// Per heading family (the principal axis' two signs): the root's heading after the
    /// search (radians, about its vertical DOF) and the global score reached.
    pub headings: Vec<(f64, f64)>,
}

/// The global score of [`initialise_pose`] for the pose `theta` (default proportions,
/// [`AutoInitParams::half_width_m`]): for diagnosing whether a wrong start comes from the score
/// (the true pose scores higher) or from the search.
///
/// # Errors
/// Invalid parameters, a hull without surface samples, a θ of the wrong size.
pub fn initial_pose_score(
    model: &EllipsoidModel,
    hull: &ContourRayHull,
    theta: &[f64],
    params: &AutoInitParams,
) -> Result<f64> {
    params.validate()?;
    let scorer = Scorer::new(model, hull, params)?;
    scorer.cost(&model.initial_state(theta, params.half_width_m)?)
}

impl AutoInit {
    /// The skeleton pose θ for the template tracker's first frame: the fit's when it scores
    /// lower than the global step's, else the global step's.
    pub fn theta(&self) -> &[f64] {
        if self.fit_kept {
            &self.fit.state.theta
        } else {
            &self.global.theta
        }
    }
}

/// The global score's data: subsampled hull points and the hull itself.
struct Scorer<'a> {
    model: &'a EllipsoidModel,
    hull: &'a ContourRayHull,
    points: Vec<DVec3>,
    params: &'a AutoInitParams,
}

/// Signed distance of `p` to `e`'s surface along the ray from its centre (positive outside).
fn radial_distance(e: &Ellipsoid, p: DVec3) -> f64 {
    let u = p - e.centre;
    let z = u.dot(e.axis);
    let rho = (u - e.axis * z).length();
    let r = ((z / e.half_length).powi(2) + (rho / e.half_width).powi(2)).sqrt();
    if r <= f64::EPSILON {
        return -e.half_width.min(e.half_length);
    }
    u.length() * (1.0 - 1.0 / r)
}

impl<'a> Scorer<'a> {
    fn new(
        model: &'a EllipsoidModel,
        hull: &'a ContourRayHull,
        params: &'a AutoInitParams,
    ) -> Result<Self> {
        Ok(Scorer {
            model,
            hull,
            points: hull_samples(hull, params.points)?,
            params,
        })
    }

    fn cost(&self, state: &EllipsoidState) -> Result<f64> {
        let tau = self.params.truncation_m;
        let es = self.model.ellipsoids(state)?;
        let forward: f64 = self
            .points
            .iter()
            .map(|&p| {
                let d = es
                    .iter()
                    .map(|e| radial_distance(e, p).abs())
                    .fold(f64::INFINITY, f64::min);
                d.min(tau).powi(2)
            })
            .sum();
        // Each axis sample weighs like the hull samples' share per ellipsoid.
        let k = self.params.axis_samples;
        let weight = self.points.len() as f64 / (es.len() * k).max(1) as f64;
        let mut reverse = 0.0;
        for e in &es {
            for i in 0..k {
                let t = if k == 1 {
                    0.0
                } else {
                    0.8 * (2.0 * i as f64 / (k - 1) as f64 - 1.0)
                };
                let d = self
                    .hull
                    .distance(e.centre + e.axis * (t * e.half_length))?;
                if d.signed_m < 0.0 {
                    reverse += weight * (-d.signed_m).min(tau).powi(2);
                }
            }
        }
        Ok(forward + reverse)
    }

    /// Coordinate descent from `current` (scoring `cost`): each DOF of `dofs` ± each step of
    /// `steps_deg` in turn (root translations: 0.2 cm per degree), within its limits. Returns
    /// the pose, its score and the poses scored.
    fn descend(
        &self,
        mut current: Vec<f64>,
        mut cost: f64,
        base: &EllipsoidState,
        dofs: &[usize],
        steps_deg: &[f64],
    ) -> Result<(Vec<f64>, f64, usize)> {
        let sk = self.model.skeleton();
        let mut evaluations = 0;
        for step in steps_deg {
            let step = step.to_radians();
            for &d in dofs {
                let delta = if sk.is_rotation(d) { step } else { step * 0.2 };
                let candidates: Vec<Vec<f64>> = [-delta, delta]
                    .iter()
                    .map(|x| {
                        let mut t = current.clone();
                        t[d] += x;
                        if let Some(l) = sk.dof(d).limits {
                            t[d] = t[d].clamp(l.min, l.max);
                        }
                        t
                    })
                    .collect();
                evaluations += candidates.len();
                let (t, c) = self.best(candidates, base)?;
                if c < cost {
                    (current, cost) = (t, c);
                }
            }
        }
        Ok((current, cost, evaluations))
    }

    /// The best of `candidates` (θ vectors), scored in parallel.
    fn best(&self, candidates: Vec<Vec<f64>>, base: &EllipsoidState) -> Result<(Vec<f64>, f64)> {
        let scored = candidates
            .into_par_iter()
            .map(|theta| {
                let s = EllipsoidState {
                    theta,
                    ..base.clone()
                };
                let c = self.cost(&s)?;
                Ok((s.theta, c))
            })
            .collect::<Result<Vec<_>>>()?;
        scored
            .into_iter()
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .ok_or(Error::Empty {
                what: "candidate poses",
            })
    }
}

/// The root's rotation DOF about `up` (unit), if it has one.
pub(crate) fn yaw_dof(sk: &Skeleton, up: DVec3) -> Option<usize> {
    sk.joint_dofs(0)
        .filter(|&d| sk.is_rotation(d))
        .max_by(|&a, &b| {
            sk.dof(a)
                .axis
                .dot(up)
                .abs()
                .total_cmp(&sk.dof(b).axis.dot(up).abs())
        })
        .filter(|&d| sk.dof(d).axis.dot(up).abs() > 0.9)
}

/// The joints below the root whose rotation moves an ellipsoid (the coordinate search's).
fn moving_joints(model: &EllipsoidModel) -> Vec<usize> {
    let sk = model.skeleton();
    (1..sk.joint_count())
        .filter(|&j| {
            model.bones().iter().any(|b| {
                sk.chain_dofs(b.parent)
                    .iter()
                    .any(|&d| sk.dof_joint(d) == j)
            }) && sk.joint_dofs(j).any(|d| sk.is_rotation(d))
        })
        .collect()
}

/// The root's DOFs and those of [`moving_joints`]: what the local descent moves.
fn searched_dofs(model: &EllipsoidModel) -> Vec<usize> {
    let sk = model.skeleton();
    sk.joint_dofs(0)
        .chain(moving_joints(model).iter().flat_map(|&j| sk.joint_dofs(j)))
        .collect()
}

/// Tracking by the global score (for [`crate::size_performer`]): the coordinate descent of
/// [`initialise_pose`] ([`AutoInitParams::refine_steps_deg`] is replaced by `steps_deg`) from
/// `theta` on `hull`, default proportions and [`AutoInitParams::half_width_m`]. Returns the
/// pose and its score.
///
/// # Errors
/// As [`initial_pose_score`].
pub(crate) fn descend_pose(
    model: &EllipsoidModel,
    hull: &ContourRayHull,
    theta: &[f64],
    params: &AutoInitParams,
    steps_deg: &[f64],
) -> Result<(Vec<f64>, f64)> {
    params.validate()?;
    let scorer = Scorer::new(model, hull, params)?;
    let base = model.initial_state(theta, params.half_width_m)?;
    let cost = scorer.cost(&base)?;
    let (t, c, _) = scorer.descend(
        base.theta.clone(),
        cost,
        &base,
        &searched_dofs(model),
        steps_deg,
    )?;
    Ok((t, c))
}

/// About `n` visual-hull surface samples: the hull polygon's vertices, evenly subsampled
/// (the attractors of [`initialise_pose`] and of the sizing).
///
/// # Errors
/// [`Error::Empty`] for a hull without surface samples.
pub(crate) fn hull_samples(hull: &ContourRayHull, n: usize) -> Result<Vec<DVec3>> {
    let vertices = &hull.polygon().vertices;
    if vertices.is_empty() {
        return Err(Error::Empty {
            what: "visual-hull samples (the hull has no surface: check the silhouettes and \
                   ContourRayHullParams::volume)",
        });
    }
    let step = vertices.len().div_ceil(n.max(1)).max(1);
    Ok(vertices.iter().step_by(step).copied().collect())
}

/// Azimuth about `up` (from `a` towards `up × a`) of the principal horizontal axis of
/// `points`, defined modulo π.
fn principal_azimuth(points: &[DVec3], up: DVec3, a: DVec3) -> f64 {
    let b = up.cross(a);
    let n = points.len().max(1) as f64;
    let c = points.iter().fold(DVec3::ZERO, |s, p| s + *p) / n;
    let (mut saa, mut sab, mut sbb) = (0.0, 0.0, 0.0);
    for p in points {
        let (x, y) = ((*p - c).dot(a), (*p - c).dot(b));
        saa += x * x;
        sab += x * y;
        sbb += y * y;
    }
    0.5 * (2.0 * sab).atan2(saa - sbb)
}

/// Automatic first-frame pose of the template tracker (no user constraint): the global
/// search of the module docs, then [`fit_ellipsoids`] on the hull samples and `rays`.
///
/// # Errors
/// Invalid parameters; [`Error::Empty`] for a hull without surface samples; a root without
/// translations or a rotation DOF about the vertical ([`skin_core::Error::InvalidParam`]
/// inside [`Error::Core`]); errors of [`fit_ellipsoids`] (non-finite rays, a limb without
/// observations, a collapsed ellipsoid).
pub fn initialise_pose(
    model: &EllipsoidModel,
    hull: &ContourRayHull,
    rays: &[ContourRay],
    params: &AutoInitParams,
) -> Result<AutoInit> {
    params.validate()?;
    if rays
        .iter()
        .any(|r| !(r.origin.is_finite() && r.direction.is_finite()))
    {
        return Err(Error::NonFinite {
            what: "contour rays (remove rays with a NaN or infinite origin or direction)",
        });
    }
    let up = params.up.normalize();
    let scorer = Scorer::new(model, hull, params)?;
    let sk = model.skeleton();
    let root_dofs = sk.joint_dofs(0);
    let invalid = |reason: &str| {
        Error::Core(skin_core::Error::InvalidParam {
            name: "skeleton root",
            reason: reason.to_string(),
        })
    };
    let translations: Vec<usize> = root_dofs.clone().filter(|&d| !sk.is_rotation(d)).collect();
    if translations.len() < 3 {
        return Err(invalid(
            "needs three translation DOFs; give the root joint a free position",
        ));
    }
    let yaw = yaw_dof(sk, up).ok_or_else(|| {
        invalid(
            "needs a rotation DOF about the vertical; give the root a heading DOF about \
             AutoInitParams::up, or set up to the axis it has",
        )
    })?;
    let yaw_sign = sk.dof(yaw).axis.dot(up).signum();
    let mut evaluations = 0;

    // 1. Root position: the rest model's root moved to the hull's centroid.
    let n = scorer.points.len() as f64;
    let centroid = scorer.points.iter().fold(DVec3::ZERO, |s, p| s + *p) / n;
    let rest = model.initial_state(&sk.rest_pose(), params.half_width_m)?;
    let root0 = sk.forward_kinematics(&rest.theta)?.joint_positions()[0];
    let mut theta = rest.theta.clone();
    let shift = centroid - root0;
    // The root's translations are along their DOF axes, assumed orthonormal.
    for &d in &translations {
        theta[d] += shift.dot(sk.dof(d).axis);
    }
    let base = model.initial_state(&theta, params.half_width_m)?;

    // 2. Heading from the principal horizontal axes (both signs, ± offsets).
    let a = if up.cross(DVec3::X).length() > 0.5 {
        DVec3::Z.cross(up).normalize()
    } else {
        up.cross(DVec3::Y).normalize()
    };
    let rest_samples: Vec<DVec3> = model
        .ellipsoids(&base)?
        .iter()
        .flat_map(|e| [-0.5, 0.0, 0.5].map(|t| e.centre + e.axis * (t * e.half_bone * 2.0)))
        .collect();
    let turn = principal_azimuth(&scorer.points, up, a) - principal_azimuth(&rest_samples, up, a);
    let mut starts = Vec::new();
    let families = match params.heading_hint_rad {
        Some(h) => vec![yaw_sign * h],
        None => vec![turn, turn + std::f64::consts::PI],
    };
    for family in families {
        let candidates: Vec<Vec<f64>> = params
            .heading_offsets_deg
            .iter()
            .map(|o| {
                let mut t = theta.clone();
                t[yaw] = yaw_sign * (family + o.to_radians());
                t
            })
            .collect();
        evaluations += candidates.len();
        starts.push(scorer.best(candidates, &base)?.0);
    }

    // 3. Coordinate search per joint, top down, from each heading.
    let movers = moving_joints(model);
    let values = |d: usize| -> Vec<f64> {
        let (lo, hi) = sk.dof(d).limits.map_or(
            (-std::f64::consts::FRAC_PI_2, std::f64::consts::FRAC_PI_2),
            |l| (l.min, l.max),
        );
        let k = params.grid_steps;
        let mut v: Vec<f64> = if k == 1 {
            vec![0.5 * (lo + hi)]
        } else {
            (0..k)
                .map(|i| lo + (hi - lo) * i as f64 / (k - 1) as f64)
                .collect()
        };
        if lo <= 0.0 && hi >= 0.0 {
            v.push(0.0);
        }
        v
    };
    let refined = searched_dofs(model);
    let mut best: Option<(Vec<f64>, f64)> = None;
    let mut headings = Vec::new();
    for start in starts {
        let mut current = start;
        let mut cost = scorer.cost(&EllipsoidState {
            theta: current.clone(),
            ..base.clone()
        })?;
        for _ in 0..params.sweeps {
            // Root height.
            let candidates: Vec<Vec<f64>> = params
                .root_height_steps_m
                .iter()
                .map(|h| {
                    let mut t = current.clone();
                    for &d in &translations {
                        t[d] += h * sk.dof(d).axis.dot(up);
                    }
                    t
                })
                .chain(std::iter::once(current.clone()))
                .collect();
            evaluations += candidates.len();
            (current, cost) = scorer.best(candidates, &base)?;
            for &j in &movers {
                // The joint's swing (its first two rotation DOFs; a third is the twist about
                // the bone, unobservable on its own ellipsoid) with each moving child's first
                // rotation DOF (an arm's elbow, a leg's knee), so a bent limb is found at once.
                let mut dofs: Vec<usize> = sk
                    .joint_dofs(j)
                    .filter(|&d| sk.is_rotation(d))
                    .take(2)
                    .collect();
                dofs.extend(
                    sk.children(j)
                        .filter(|c| movers.contains(c))
                        .filter_map(|c| sk.joint_dofs(c).find(|&d| sk.is_rotation(d))),
                );
                let mut candidates = vec![current.clone()];
                for d in &dofs {
                    let vs = values(*d);
                    candidates = candidates
                        .into_iter()
                        .flat_map(|t| {
                            vs.iter().map(move |&v| {
                                let mut t = t.clone();
                                t[*d] = v;
                                t
                            })
                        })
                        .collect();
                }
                candidates.push(current.clone());
                evaluations += candidates.len();
                (current, cost) = scorer.best(candidates, &base)?;
            }
            // Local descent: every searched DOF (and the root's) ± a shrinking step.
            let n;
            (current, cost, n) =
                scorer.descend(current, cost, &base, &refined, &params.refine_steps_deg)?;
            evaluations += n;
        }
        headings.push((current[yaw], cost));
        if best.as_ref().is_none_or(|b| cost < b.1) {
            best = Some((current, cost));
        }
    }
    let (theta, global_cost) = best.ok_or(Error::Empty {
        what: "heading candidates",
    })?;
    let global = EllipsoidState {
        theta,
        ..base.clone()
    };
    let obs = EllipsoidObservations {
        points: scorer.points.clone(),
        markers: Vec::new(),
        rays: rays.to_vec(),
    };
    let fit = fit_ellipsoids(model, &global, &obs, &params.fit)?;
    let fit_cost = scorer.cost(&fit.state)?;
    Ok(AutoInit {
        fit_kept: fit_cost <= global_cost,
        global,
        global_cost,
        fit,
        evaluations,
        headings,
    })
}

/// Pose error of `theta` against `truth` on `skeleton`: the mean joint position error
/// (metres) and the mean bone direction error (radians; the angle between each joint's
/// parent → joint vectors, so axial twist is excluded). For scoring a start against the truth.
///
/// # Errors
/// A θ of the wrong size or non-finite (skin-core's errors inside [`Error::Core`]).
pub fn pose_error(skeleton: &Skeleton, theta: &[f64], truth: &[f64]) -> Result<(f64, f64)> {
    let est = skeleton.forward_kinematics(theta)?.joint_positions();
    let tru = skeleton.forward_kinematics(truth)?.joint_positions();
    let n = est.len().max(1) as f64;
    let joint = est
        .iter()
        .zip(&tru)
        .map(|(a, b)| a.distance(*b))
        .sum::<f64>()
        / n;
    let angles: Vec<f64> = skeleton
        .joints()
        .iter()
        .enumerate()
        .filter_map(|(j, joint)| {
            let p = joint.parent?;
            let (a, b) = (est[j] - est[p], tru[j] - tru[p]);
            (a.length() > 1e-9 && b.length() > 1e-9)
                .then(|| a.normalize().dot(b.normalize()).clamp(-1.0, 1.0).acos())
        })
        .collect();
    let angle = angles.iter().sum::<f64>() / angles.len().max(1) as f64;
    Ok((joint, angle))
}

/// The baseline [`initialise_pose`] must beat: the rest pose with its root moved to the hull
/// samples' centroid (no global search), then the same robust fit to the hull samples and
/// `rays` — what the `ellipsoid_fit` example measured as the automatic start before this
/// module.
///
/// # Errors
/// As [`initialise_pose`].
pub fn rest_pose_start(
    model: &EllipsoidModel,
    hull: &ContourRayHull,
    rays: &[ContourRay],
    params: &AutoInitParams,
) -> Result<EllipsoidFit> {
    params.validate()?;
    let scorer = Scorer::new(model, hull, params)?;
    let sk = model.skeleton();
    let mut theta = sk.rest_pose();
    let root = sk.forward_kinematics(&theta)?.joint_positions()[0];
    let n = scorer.points.len() as f64;
    let shift = scorer.points.iter().fold(DVec3::ZERO, |s, p| s + *p) / n - root;
    for d in sk.joint_dofs(0).filter(|&d| !sk.is_rotation(d)) {
        theta[d] += shift.dot(sk.dof(d).axis);
    }
    let obs = EllipsoidObservations {
        points: scorer.points,
        markers: Vec::new(),
        rays: rays.to_vec(),
    };
    fit_ellipsoids(
        model,
        &model.initial_state(&theta, params.half_width_m)?,
        &obs,
        &params.fit,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::visual_hull::tests::{ring, sphere_mask};
    use crate::visual_hull::ContourRayHullParams;
    use skin_core::image::Mask;
    use skin_core::skeleton::{human_skeleton, HumanParams};

    fn setup() -> (EllipsoidModel, ContourRayHull) {
        let cams = ring(4, 160, 120);
        let masks: Vec<Mask> = cams
            .iter()
            .map(|c| sphere_mask(c, DVec3::new(0.0, 1.0, 0.0), 0.3))
            .collect();
        let hull = ContourRayHull::new(&cams, &masks, &ContourRayHullParams::default()).unwrap();
        let sk = human_skeleton(&HumanParams::default()).unwrap();
        (EllipsoidModel::with_end_sites(sk, 0.1).unwrap(), hull)
    }

    #[test]
    fn bad_input_is_reported() {
        let (model, hull) = setup();
        let bad = |p: AutoInitParams| initialise_pose(&model, &hull, &[], &p).is_err();
        assert!(bad(AutoInitParams {
            points: 0,
            ..AutoInitParams::default()
        }));
        assert!(bad(AutoInitParams {
            truncation_m: f64::NAN,
            ..AutoInitParams::default()
        }));
        assert!(bad(AutoInitParams {
            heading_offsets_deg: vec![],
            ..AutoInitParams::default()
        }));
        assert!(bad(AutoInitParams {
            up: DVec3::ZERO,
            ..AutoInitParams::default()
        }));
        // No root rotation DOF about a diagonal "up".
        assert!(bad(AutoInitParams {
            up: DVec3::new(1.0, 1.0, 1.0),
            ..AutoInitParams::default()
        }));
        let nan_ray = ContourRay {
            origin: DVec3::new(f64::NAN, 0.0, 0.0),
            direction: DVec3::Z,
            normal: DVec3::X,
        };
        assert!(matches!(
            initialise_pose(&model, &hull, &[nan_ray], &AutoInitParams::default()),
            Err(Error::NonFinite { .. })
        ));
        let sk = model.skeleton();
        assert!(pose_error(sk, &[0.0; 3], &sk.rest_pose()).is_err());
        let (m, a) = pose_error(sk, &sk.rest_pose(), &sk.rest_pose()).unwrap();
        assert!(m == 0.0 && a < 1e-6, "{m} m, {a} rad");
        assert!(initial_pose_score(&model, &hull, &[0.0; 3], &AutoInitParams::default()).is_err());
    }
}
