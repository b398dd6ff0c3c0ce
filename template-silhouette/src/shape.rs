//! Shape estimation: non-rigid template matching to the silhouettes (Vlasic 2010 §2.4.2,
//! Algorithm 1).
//!
//! ```text
//! for each frame t:   V_t ← Eq. 2.1 with the nearly-rigid LBS vertices        (lines 2–5)
//! V ← TemporalFilter(V)                                                        (line 6)
//! for w_L = 0, 0.2, …, 1:                                                      (line 7)
//!     for each frame t:
//!         L' ← Laplacian coordinates rotated by the LBS-blended bone rotations (line 9)
//!         (C_SIL, P_SIL) ← silhouette constraints of the current V_t          (line 10)
//!         V_t ← Eq. 2.2                                                        (line 11)
//!     V ← TemporalFilter(V)                                                    (line 13)
//! ```
//!
//! The bilateral temporal filter (lines 6, 13) is
//! `v_i^t ← v_i^t + (v_i^{t−1} − 2v_i^t + v_i^{t+1})/4 · exp(−(‖v_i^{t+1} − v_i^t‖² +
//! ‖v_i^{t−1} − v_i^t‖²)/σ²)` with σ = 0.07 m, two passes after each iteration.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use skin_core::math::{DMat3, DVec3};
use skin_core::mesh::{LaplacianParams, SurfacePoint};

use crate::error::{Context, Error, Result, ResultExt};
use crate::molding::{Molding, SoftConstraint};
use crate::silhouette_constraints::{silhouette_constraints, ContourRay, SilhouetteParams};
use crate::template::Template;

/// Knobs of shape estimation (§2.4.2, Algorithm 1), the thesis' values by default.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ShapeParams {
    /// LBS weight of a single bone from which a vertex is nearly rigid and constrained in
    /// Eq. 2.1. §2.4.2. Default: [`Self::DEFAULT_RIGID_MIN_WEIGHT`] = 0.95. A rig whose weights
    /// blend whole regions (MakeHuman's torso: 2 of its pelvis and spine vertices reach 0.95)
    /// leaves those regions unanchored ([`ShapeEstimator::unanchored_bones`]).
    pub rigid_min_weight: f64,
    /// `w_C` of Eq. 2.1 and 2.2. §2.4.2. Default: [`Self::DEFAULT_W_C`] = 1000.
    pub w_c: f64,
    /// `w_A`, beyond the thesis: every vertex not marked loose
    /// ([`Template::with_loose_vertices`]) is held at its skinned position with this weight
    /// in Eq. 2.1 and every Eq. 2.2 solve (0: the thesis, whose Eq. 2.2 has the silhouette
    /// constraints alone). Default: [`Self::DEFAULT_W_ANCHOR`] = 0.
    ///
    /// Why: Eq. 2.2 fixes the surface only where a contour ray touches it; elsewhere the
    /// shape is rebuilt from Laplacian coordinates rotated by blended bone rotations, which
    /// drift where the rig blends several bones (MakeHuman's torso has two nearly-rigid
    /// vertices). Molding the studio's body on its *true* poses at 480 × 360 with the
    /// thesis' Eq. 2.2 left 14.9 mm RMS (27.5 mm on the pose-deforming vertices) where LBS
    /// has 1.2 mm (5.4 mm); with `w_A = 1` it left 2.8 mm (5.6 mm). A weak pull to the
    /// skinned surface keeps what the silhouettes cannot see where the pose puts it. A
    /// weight of 1 against the row-normalised Laplacian's unit rows and `w_C = 1000`
    /// leaves the contours in charge where they see the surface.
    pub w_anchor: f64,
    /// Step of `w_L` from 0 to 1 (iterations = 1/step + 1). §2.4.2. Default:
    /// [`Self::DEFAULT_W_L_STEP`] = 0.2 (six iterations).
    pub w_l_step: f64,
    /// σ of the bilateral temporal filter, m. §2.4.2. Default: [`Self::DEFAULT_FILTER_SIGMA_M`].
    pub filter_sigma_m: f64,
    /// Filter passes after the initial solve and after each iteration. §2.4.2. Default:
    /// [`Self::DEFAULT_FILTER_PASSES`] = 2.
    pub filter_passes: usize,
    /// The silhouette constraints. Default: the thesis' (10 px, 0.25, 5 cm, 90°).
    pub silhouette: SilhouetteParams,
    /// How the cotangent Laplacian treats degenerate triangles. Default: skin-core's.
    pub laplacian: LaplacianParams,
    /// Where each frame's molding starts. Default: [`ShapeStart::Skinning`], the thesis'.
    #[serde(default)]
    pub start: ShapeStart,
}

/// Where Algorithm 1 starts each frame's molding.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum ShapeStart {
    /// The thesis (§2.4.2, lines 2–5): every frame from Eq. 2.1, the nearly-rigid vertices at
    /// their skinned places and the rest interpolated; frames are independent between the
    /// temporal filter's passes and are solved in parallel.
    #[default]
    Skinning,
    /// Beyond the thesis: frame `t` starts from frame `t − 1`'s molded surface carried by
    /// the pose change ([`Template::carry`]), the first frame from Eq. 2.1; each frame then
    /// runs the same `w_L` schedule of Eq. 2.2 solves, and the temporal filter runs its
    /// passes once over the whole sequence at the end.
    ///
    /// Why: the silhouette constraints pair each contour ray with the nearest vertex of the
    /// current shape within 5 cm (§2.4.2). Cloth hangs 10–30 cm from where skinning and
    /// Eq. 2.1 put it, so from the thesis' start a swinging skirt's contour rays pair with
    /// the wrong vertices or none and the skirt is re-found, often not at all, every frame;
    /// from the previous frame's surface it is followed. The cost: frames are solved one
    /// after another (no parallelism over frames), and an error of one frame is carried to
    /// the next until the silhouettes correct it.
    PreviousFrame,
}

impl Default for ShapeParams {
    fn default() -> Self {
        ShapeParams {
            rigid_min_weight: Self::DEFAULT_RIGID_MIN_WEIGHT,
            w_c: Self::DEFAULT_W_C,
            w_anchor: Self::DEFAULT_W_ANCHOR,
            w_l_step: Self::DEFAULT_W_L_STEP,
            filter_sigma_m: Self::DEFAULT_FILTER_SIGMA_M,
            filter_passes: Self::DEFAULT_FILTER_PASSES,
            silhouette: SilhouetteParams::default(),
            laplacian: LaplacianParams::default(),
            start: ShapeStart::default(),
        }
    }
}

impl ShapeParams {
    /// Default weight of the positional constraints, Eq. 2.1 and 2.2: `w_C = 1000`.
    pub const DEFAULT_W_C: f64 = 1000.0;

    /// Default LBS weight from which a vertex counts as nearly rigid (§2.4.2: "at least .95").
    pub const DEFAULT_RIGID_MIN_WEIGHT: f64 = 0.95;

    /// Default weight of the nearly-rigid vertices' skinned positions in Eq. 2.2, `w_A` (beyond
    /// the thesis, whose Eq. 2.2 has none: see [`ShapeParams::w_anchor`]).
    pub const DEFAULT_W_ANCHOR: f64 = 0.0;

    /// Default step of `w_L` over the iterations (§2.4.2: six iterations from 0 to 1).
    pub const DEFAULT_W_L_STEP: f64 = 0.2;

    /// Default σ of the bilateral temporal filter, m (§2.4.2: 0.07 m).
    pub const DEFAULT_FILTER_SIGMA_M: f64 = 0.07;

    /// Default number of filter passes after each iteration (§2.4.2: twice).
    pub const DEFAULT_FILTER_PASSES: usize = 2;

    /// Sets [`Self::silhouette`].
    pub fn with_silhouette(mut self, silhouette: SilhouetteParams) -> Self {
        self.silhouette = silhouette;
        self
    }
    /// Sets [`Self::start`].
    pub fn with_start(mut self, start: ShapeStart) -> Self {
        self.start = start;
        self
    }
    /// Sets [`Self::filter_passes`] (0 turns the temporal filter off).
    pub fn with_filter_passes(mut self, passes: usize) -> Self {
        self.filter_passes = passes;
        self
    }

    /// The `w_L` of each iteration: 0, step, …, 1.
    pub fn w_l_schedule(&self) -> Vec<f64> {
        let n = (1.0 / self.w_l_step).round() as usize;
        (0..=n)
            .map(|k| (k as f64 * self.w_l_step).min(1.0))
            .collect()
    }

    fn validate(&self) -> Result<()> {
        skin_core::check::in_range("rigid_min_weight", self.rigid_min_weight, 0.5..=1.0)?;
        skin_core::check::positive("w_c", self.w_c)?;
        skin_core::check::non_negative("w_anchor", self.w_anchor)?;
        skin_core::check::in_range("w_l_step", self.w_l_step, 0.01..=1.0)?;
        skin_core::check::positive("filter_sigma_m", self.filter_sigma_m)?;
        Ok(())
    }
}

/// One frame's input to shape estimation: the pose (from pose estimation, §2.3) and the
/// contour rays of every camera ([`crate::contour_rays`]).
#[derive(Debug, Clone, Copy)]
pub struct ShapeFrame<'a> {
    /// Skeleton pose θ (radians, metres).
    pub theta: &'a [f64],
    /// Contour rays of all cameras of the frame.
    pub rays: &'a [ContourRay],
}

/// Diagnostics of one iteration of Algorithm 1 (lines 7–14).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ShapeIteration {
    /// `w_L` of the iteration.
    pub w_l: f64,
    /// Silhouette constraints used per frame.
    pub constraints: Vec<usize>,
}

/// The estimated shapes of a sequence.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ShapeSequence {
    /// Vertex positions per frame, world m, in the template's vertex order.
    pub frames: Vec<Vec<DVec3>>,
    /// Per iteration, what it used.
    pub iterations: Vec<ShapeIteration>,
}

/// Shape estimation for one template: the molding solver (one symbolic factorisation for
/// the whole sequence) and the nearly-rigid vertices.
#[derive(Debug)]
pub struct ShapeEstimator {
    template: Template,
    /// The factorisation; `None` only while a solve has it out (see [`Self::with_molding`]).
    molding: Option<Molding>,
    params: ShapeParams,
    /// Nearly-rigid vertices (vertex, bone).
    rigid: Vec<(usize, usize)>,
    /// Bones that are the largest influence of some vertex but have no nearly-rigid vertex.
    unanchored: Vec<usize>,
    /// A face corner of every vertex, for vertex constraints as barycentric rows.
    corners: Vec<SurfacePoint>,
}

impl ShapeEstimator {
    /// Prepares Laplacian coordinates, the factorisation and the nearly-rigid vertices.
    ///
    /// # Errors
    /// [`Error::InvalidParam`] for bad params or a template without nearly-rigid vertices;
    /// errors of [`Molding::new`]; [`Error::At`] with the vertex for a vertex in no face.
    pub fn new(template: Template, params: ShapeParams) -> Result<Self> {
        params.validate()?;
        let molding = Molding::new(template.mesh(), &params.laplacian)?;
        let rigid = template.nearly_rigid(params.rigid_min_weight);
        if rigid.is_empty() {
            return Err(Error::InvalidParam {
                name: "rigid_min_weight",
                reason: format!(
                    "no template vertex has a bone weight of at least {} (Eq. 2.1 needs \
                     nearly-rigid vertices): lower rigid_min_weight or give the template \
                     rigid skin weights",
                    params.rigid_min_weight
                ),
            });
        }
        let unanchored = unanchored_bones(&template, &rigid);
        if !unanchored.is_empty() {
            log::warn!(
                "{} bones dominate some vertices but have none with a weight of at least {}: \
                 Eq. 2.1 leaves their regions unconstrained and smooths them away (see \
                 ShapeEstimator::unanchored_bones)",
                unanchored.len(),
                params.rigid_min_weight
            );
        }
        let mesh = template.mesh();
        let mut corners: Vec<Option<SurfacePoint>> = vec![None; mesh.vertex_count()];
        for (f, face) in mesh.faces.iter().enumerate() {
            for (k, v) in face.iter().enumerate() {
                if corners[*v as usize].is_none() {
                    corners[*v as usize] = Some(SurfacePoint::corner(f as u32, k)?);
                }
            }
        }
        let corners = corners
            .into_iter()
            .enumerate()
            .map(|(i, c)| {
                c.ok_or(Error::InvalidParam {
                    name: "template",
                    reason: "vertex belongs to no face; remove the unreferenced vertex".into(),
                })
                .at(Context::Vertex(i))
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(ShapeEstimator {
            template,
            molding: Some(molding),
            params,
            rigid,
            unanchored,
            corners,
        })
    }

    /// The template.
    pub fn template(&self) -> &Template {
        &self.template
    }

    /// The parameters.
    pub fn params(&self) -> &ShapeParams {
        &self.params
    }

    /// Bones (joint indices) that are the largest influence of some vertex but have no
    /// nearly-rigid vertex: Eq. 2.1 does not anchor their regions, which it then smooths
    /// away (e.g. a torso whose weights are blended everywhere). A rig with many of them
    /// needs a lower [`ShapeParams::rigid_min_weight`].
    pub fn unanchored_bones(&self) -> &[usize] {
        &self.unanchored
    }

    fn vertex_constraint(&self, v: usize, target: DVec3) -> SoftConstraint {
        SoftConstraint {
            point: self.corners[v],
            target,
        }
    }

    /// The skinned positions that hold every vertex but the loose ones when
    /// [`ShapeParams::w_anchor`] > 0 (none otherwise).
    /// `skinned`: the template skinned to `theta`, when the caller already has it.
    fn anchors(&self, theta: &[f64], skinned: Option<&[DVec3]>) -> Result<Vec<SoftConstraint>> {
        if self.params.w_anchor == 0.0 {
            return Ok(Vec::new());
        }
        let computed;
        let lbs = match skinned {
            Some(lbs) => lbs,
            None => {
                computed = self.template.skin(theta)?;
                &computed
            }
        };
        Ok((0..lbs.len())
            .filter(|&v| !self.template.is_loose(v))
            .map(|v| self.vertex_constraint(v, lbs[v]))
            .collect())
    }

    /// The initial guess of Eq. 2.1 (Algorithm 1 lines 3–4): the nearly-rigid vertices at
    /// their LBS positions, the rest interpolated smoothly (`w_L = 0`).
    ///
    /// # Errors
    /// As [`Template::skin`] and [`Molding::solve`].
    pub fn initial_shape(&mut self, theta: &[f64]) -> Result<Vec<DVec3>> {
        self.with_molding(|this, molding| this.initial_shape_with(molding, theta))
    }

    /// [`Self::initial_shape`] on `molding` (this estimator's, or a clone on another thread).
    fn initial_shape_with(&self, molding: &mut Molding, theta: &[f64]) -> Result<Vec<DVec3>> {
        let lbs = self.template.skin(theta)?;
        let cons: Vec<SoftConstraint> = self
            .rigid
            .iter()
            .map(|&(v, _)| self.vertex_constraint(v, lbs[v]))
            .collect();
        let zero = vec![DVec3::ZERO; self.template.vertex_count()];
        let anchors = self.anchors(theta, Some(&lbs))?;
        molding.solve_weighted(
            0.0,
            &zero,
            &[(self.params.w_c, &cons), (self.params.w_anchor, &anchors)],
        )
    }

    /// Runs `f` with this estimator's factorisation taken out of it (so `f` may borrow the
    /// rest of the estimator), then puts it back.
    fn with_molding<T>(&mut self, f: impl FnOnce(&Self, &mut Molding) -> Result<T>) -> Result<T> {
        let mut molding = self.molding.take().ok_or(Error::Empty {
            what: "shape estimator's factorisation (a previous solve panicked)",
        })?;
        let out = f(self, &mut molding);
        self.molding = Some(molding);
        out
    }

    /// The factorisation (always present outside [`Self::with_molding`]).
    fn molding(&self) -> Result<&Molding> {
        self.molding.as_ref().ok_or(Error::Empty {
            what: "shape estimator's factorisation (a previous solve panicked)",
        })
    }

    /// The Laplacian coordinates rotated by the LBS-blended bone rotations,
    /// `ℓ'_i = Σ_j b_i^j R^j ℓ_i` (§2.4.2, Algorithm 1 line 9).
    ///
    /// # Errors
    /// As [`skin_core::skeleton::Skeleton::check_pose`].
    pub fn rotated_coordinates(&self, theta: &[f64]) -> Result<Vec<DVec3>> {
        self.rotate(self.molding()?.coordinates(), theta)
    }

    /// `coords` (the template's Laplacian coordinates) rotated for the pose `theta`.
    fn rotate(&self, coords: &[DVec3], theta: &[f64]) -> Result<Vec<DVec3>> {
        let fk = self.template.skeleton().forward_kinematics(theta)?;
        let rot: Vec<DMat3> = self
            .template
            .world_from_rest(&fk)
            .iter()
            .map(|t| t.matrix3)
            .collect();
        let w = self.template.weights();
        Ok(coords
            .iter()
            .enumerate()
            .map(|(i, l)| {
                w.influences(i)
                    .map(|(b, bw)| bw * (rot[b as usize] * *l))
                    .sum()
            })
            .collect())
    }

    /// One solve of Eq. 2.2 (Algorithm 1 lines 9–11) from the current shape: silhouette
    /// constraints of `rays` on `current`, rotated coordinates scaled by `w_l`.
    /// Returns the new vertices and the number of constraints.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] for a `current` of another mesh; errors of the constraints
    /// and of [`Molding::solve`] ([`Error::InvalidParam`] when no constraint reaches a
    /// connected part of the template).
    pub fn refine(
        &mut self,
        theta: &[f64],
        current: &[DVec3],
        w_l: f64,
        rays: &[ContourRay],
    ) -> Result<(Vec<DVec3>, usize)> {
        self.with_molding(|this, molding| this.refine_with(molding, theta, current, w_l, rays))
    }

    /// [`Self::refine`] on `molding` (this estimator's, or a clone on another thread).
    fn refine_with(
        &self,
        molding: &mut Molding,
        theta: &[f64],
        current: &[DVec3],
        w_l: f64,
        rays: &[ContourRay],
    ) -> Result<(Vec<DVec3>, usize)> {
        if current.len() != self.template.vertex_count() {
            return Err(Error::SizeMismatch {
                what: "current shape vs template vertices (give one position per template vertex)",
                expected: self.template.vertex_count(),
                got: current.len(),
            });
        }
        let coords = self.rotate(molding.coordinates(), theta)?;
        let mesh = self.template.mesh_with(current.to_vec());
        let sil = silhouette_constraints(&mesh, rays, &self.params.silhouette)?;
        let cons: Vec<SoftConstraint> = sil
            .iter()
            .map(|c| self.vertex_constraint(c.vertex, c.target))
            .collect();
        let anchors = self.anchors(theta, None)?;
        let v = molding.solve_weighted(
            w_l,
            &coords,
            &[(self.params.w_c, &cons), (self.params.w_anchor, &anchors)],
        )?;
        Ok((v, cons.len()))
    }

    /// Algorithm 1 on a sequence of frames: initial guesses, filter, then the `w_L`
    /// schedule of refinements, each followed by the filter.
    ///
    /// # Errors
    /// [`Error::Empty`] for no frame; errors of [`Self::initial_shape`] and
    /// [`Self::refine`] wrapped in [`Error::At`] with the frame.
    pub fn estimate(&mut self, frames: &[ShapeFrame<'_>]) -> Result<ShapeSequence> {
        if frames.is_empty() {
            return Err(Error::Empty { what: "frames" });
        }
        if self.params.start == ShapeStart::PreviousFrame {
            return self.with_molding(|this, molding| this.estimate_carried(molding, frames));
        }
        // Frames are independent between filter passes: solved in parallel, each thread
        // with its own clone of the factorisation (the symbolic analysis is shared).
        let base = self.molding()?;
        let mut shapes = frames
            .par_iter()
            .enumerate()
            .map_init(
                || base.clone(),
                |m, (t, f)| self.initial_shape_with(m, f.theta).at(Context::Frame(t)),
            )
            .collect::<Result<Vec<_>>>()?;
        temporal_filter(
            &mut shapes,
            self.params.filter_sigma_m,
            self.params.filter_passes,
        )?;
        let mut iterations = Vec::new();
        for w_l in self.params.w_l_schedule() {
            let solved = frames
                .par_iter()
                .zip(&shapes)
                .enumerate()
                .map_init(
                    || base.clone(),
                    |m, (t, (f, current))| {
                        self.refine_with(m, f.theta, current, w_l, f.rays)
                            .at(Context::Frame(t))
                    },
                )
                .collect::<Result<Vec<_>>>()?;
            let counts = solved.iter().map(|(_, n)| *n).collect();
            shapes = solved.into_iter().map(|(v, _)| v).collect();
            temporal_filter(
                &mut shapes,
                self.params.filter_sigma_m,
                self.params.filter_passes,
            )?;
            iterations.push(ShapeIteration {
                w_l,
                constraints: counts,
            });
        }
        Ok(ShapeSequence {
            frames: shapes,
            iterations,
        })
    }

    /// Algorithm 1 with [`ShapeStart::PreviousFrame`]: frame by frame, each from the previous
    /// frame's result carried by the pose change, the `w_L` schedule per frame, then the
    /// temporal filter over the sequence.
    fn estimate_carried(
        &self,
        molding: &mut Molding,
        frames: &[ShapeFrame<'_>],
    ) -> Result<ShapeSequence> {
        let schedule = self.params.w_l_schedule();
        let mut counts = vec![Vec::with_capacity(frames.len()); schedule.len()];
        let mut shapes: Vec<Vec<DVec3>> = Vec::with_capacity(frames.len());
        for (t, f) in frames.iter().enumerate() {
            let start = match shapes.last() {
                Some(prev) => self.template.carry(prev, frames[t - 1].theta, f.theta),
                None => self.initial_shape_with(molding, f.theta),
            };
            let mut v = start.at(Context::Frame(t))?;
            for (k, &w_l) in schedule.iter().enumerate() {
                let (next, n) = self
                    .refine_with(molding, f.theta, &v, w_l, f.rays)
                    .at(Context::Frame(t))?;
                v = next;
                counts[k].push(n);
            }
            shapes.push(v);
        }
        temporal_filter(
            &mut shapes,
            self.params.filter_sigma_m,
            self.params.filter_passes,
        )?;
        Ok(ShapeSequence {
            frames: shapes,
            iterations: schedule
                .into_iter()
                .zip(counts)
                .map(|(w_l, constraints)| ShapeIteration { w_l, constraints })
                .collect(),
        })
    }
}

/// Bones that dominate at least one vertex and own none of the nearly-rigid vertices.
fn unanchored_bones(template: &Template, rigid: &[(usize, usize)]) -> Vec<usize> {
    let w = template.weights();
    let mut dominant = vec![false; w.bone_count()];
    for i in 0..template.vertex_count() {
        if let Some((b, _)) = w.influences(i).max_by(|a, b| a.1.total_cmp(&b.1)) {
            dominant[b as usize] = true;
        }
    }
    let mut anchored = vec![false; w.bone_count()];
    for &(_, b) in rigid {
        anchored[b] = true;
    }
    (0..w.bone_count())
        .filter(|&b| dominant[b] && !anchored[b])
        .collect()
}

/// The bilateral temporal filter of §2.4.2, `passes` times over a sequence of shapes (all
/// with the same vertex count). Each pass reads the previous pass's shapes (a Jacobi
/// update, independent of frame order). The first and last frames have one neighbour and
/// are left as they are.
///
/// # Errors
/// [`Error::SizeMismatch`] for frames of different vertex counts; [`Error::InvalidParam`]
/// for a σ that is not positive.
pub fn temporal_filter(frames: &mut [Vec<DVec3>], sigma_m: f64, passes: usize) -> Result<()> {
    skin_core::check::positive("sigma_m", sigma_m)?;
    let Some(n) = frames.first().map(Vec::len) else {
        return Ok(());
    };
    if let Some(bad) = frames.iter().find(|f| f.len() != n) {
        return Err(Error::SizeMismatch {
            what: "vertices of a frame vs the first frame (give every frame the same vertex count)",
            expected: n,
            got: bad.len(),
        });
    }
    let inv_s2 = 1.0 / (sigma_m * sigma_m);
    for _ in 0..passes {
        let prev = frames.to_vec();
        for t in 1..frames.len().saturating_sub(1) {
            for i in 0..n {
                let (a, v, b) = (prev[t - 1][i], prev[t][i], prev[t + 1][i]);
                let w = (-((b - v).length_squared() + (a - v).length_squared()) * inv_s2).exp();
                frames[t][i] = v + 0.25 * (a - 2.0 * v + b) * w;
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests;
