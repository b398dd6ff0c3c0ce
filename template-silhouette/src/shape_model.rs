//! A dynamic shape model learned from molded sequences and driven by poses alone: capture a
//! few representative motions in the studio, then animate the same performer's template
//! from any skeletal motion capture (the thesis's closing aim, Vlasic 2010 Ch. 6 and
//! Figure 6-1; Ch. 2's future work: "a model of shape motion that takes clothing and
//! dynamics into account").
//!
//! **Shape.** A frame of the template is linear blend skinning plus an offset of each vertex
//! along its skinned normal: `x_v = LBS_v(θ) + r_v n_v(θ)`. Normal offsets, not 3-D
//! residuals: silhouettes determine the surface, not where on it a vertex sits — molded
//! vertices slide along the surface (the thesis's §2.6 texture sliding) and a garment's
//! material turns about the body — and those tangential motions, invisible to every surface
//! measure, dominate the 3-D residual of a skirt (on the studio's skirt exercise its
//! vertex-to-material-point distance is ten times its surface distance); learned, they are
//! noise the model reproduces. The offsets live in a `k`-dimensional subspace `r = U c`
//! learned by one streaming pass ([`ShapeModelParams::components`]).
//!
//! **Pose-dependent part** `c_pose = W (f(θ) − f(θ₀))`: ridge regression on SMPL's pose
//! features (each joint's local rotation relative to rest minus the identity, nine numbers per
//! joint) and gravity's direction in the root frame, taken relative to the rest pose `θ₀` and
//! without an intercept, as SMPL's pose blend shapes: the model is zero at rest, where the
//! template is the performer, so the ridge shrinks it towards the template — the one shape
//! known to hold for every motion — and not towards the training motions' mean, which for a
//! garment is the mean of those motions' swing (measured on the studio's skirt, 600 frames:
//! with an intercept the model learned from the truth has 1.15 × LBS's skirt error in unseen
//! motions, without it 0.97 ×).
//! A linear regression, not needle-model's
//! normalised radial basis functions over prototype poses: those interpolate between the
//! training poses and fall back to their mean far from them, while a model captured on a
//! few motions must extrapolate to motions it never saw; the linear map of rotation
//! matrices is what SMPL's pose blend shapes use for the same reason.
//!
//! **Dynamic part** (after Dyna, Pons-Moll et al. 2015: a second-order autoregressive
//! model in a low-dimensional subspace driven by the motion): the motion inputs — the root's
//! velocity, acceleration, angular velocity and angular acceleration in its own frame and the
//! local angular velocities of the bones that carry loose vertices — pass through a bank of
//! damped second-order filters ([`ShapeModelParams::poles`], [`DynamicPole`]), and a linear
//! map takes the filtered inputs into the residual subspace. Each filter is a second-order
//! autoregression with its poles inside the unit circle: stable by construction, bounded for
//! bounded motion, silent when the body stops. Both parts are one ridge regression of the
//! residual coordinates on the pose features and the filtered inputs together, fitted on the
//! dynamic part's free-running output (what it gives when driven).
//!
//! **Learning** ([`ShapeModel::learn`]) reads a [`FrameStream`] twice (the subspace, then the
//! coordinates) and keeps only low-dimensional data per frame: a sequence of any length is
//! streamed, from [`SequenceWriter`] files or memory. **Driving** ([`ShapeDriver::step`])
//! takes one pose per frame at the model's frame rate. The file format is documented at
//! [`ShapeModel::save`].

mod dynamics;
mod features;
mod file;
mod sketch;
#[cfg(test)]
mod tests;

use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};
use skin_core::math::DVec3;
use skin_core::mesh::{skin, vertex_normals, NormalWeighting};
use skin_core::skeleton::ForwardKinematics;

use crate::error::{Context, Error, Result, ResultExt};
use crate::template::Template;
use dynamics::Bank;
pub use dynamics::DynamicPole;
use features::{FeatureLayout, Kinematics};
pub use file::{SequenceFiles, SequenceWriter};
use sketch::FrequentDirections;

/// Parameters of [`ShapeModel::learn`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ShapeModelParams {
    /// Dimension `k` of the residual subspace. Default: 48 (SMPL-like garment models keep
    /// tens of components; the 10,000-vertex skirt template's molded residuals keep over 99 %
    /// of their energy in 48).
    pub components: usize,
    /// Ridge weight of the pose regression, relative to the mean diagonal of the centred
    /// features' Gram matrix. Default: 0.1 (a few hundred training frames
    /// against two hundred features: without it the regression fits each frame's noise).
    pub pose_ridge: f64,
    /// Ridge weight of the dynamic part's weights, relative to the mean diagonal of the
    /// filtered inputs' Gram matrix. Default: 0.01.
    pub dynamic_ridge: f64,
    /// Choose both ridge weights from [`RIDGE_GRID`] by leave-one-sequence-out validation
    /// when the stream has two or more sequences (more than ten: ten groups of consecutive
    /// sequences, left out in turn; the fields above serve with one sequence).
    /// Default: true — a few hundred frames of a few motions leave the right amount of
    /// shrinkage to the data: too little, and the regression learns what one motion's
    /// swinging cloth happened to do at each pose and replays it in every other motion.
    pub cross_validate: bool,
    /// The filters of the dynamic part's bank. Default: lags of 0.1, 0.33 and 1 s and swings
    /// of 0.5 and 1 Hz decaying in 1 s (why: [`DynamicPole`]'s defaults in the module
    /// source); empty: no dynamic part.
    pub poles: Vec<DynamicPole>,
}

impl Default for ShapeModelParams {
    fn default() -> Self {
        ShapeModelParams {
            components: 48,
            pose_ridge: 0.1,
            dynamic_ridge: 0.01,
            cross_validate: true,
            poles: dynamics::default_poles(),
        }
    }
}

impl ShapeModelParams {
    fn validate(&self) -> Result<()> {
        if self.components == 0 {
            return Err(Error::InvalidParam {
                name: "components",
                reason: "must be at least 1".into(),
            });
        }
        for (name, v) in [
            ("pose_ridge", self.pose_ridge),
            ("dynamic_ridge", self.dynamic_ridge),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::InvalidParam {
                    name,
                    reason: format!("{v}: give a finite value ≥ 0"),
                });
            }
        }
        if let Some(p) = self.poles.iter().find(|p| {
            !(p.decay_per_s.is_finite()
                && p.decay_per_s > 0.0
                && p.frequency_hz.is_finite()
                && p.frequency_hz >= 0.0)
        }) {
            return Err(Error::InvalidParam {
                name: "poles",
                reason: format!(
                    "{p:?}: give a positive finite decay rate and a finite frequency ≥ 0"
                ),
            });
        }
        Ok(())
    }
}

/// One frame of a training stream.
#[derive(Debug, Clone, Copy)]
pub struct TrainingFrame<'a> {
    /// Which sequence the frame belongs to (frames of a sequence come in order, one after
    /// another; a new value restarts the motion history).
    pub sequence: usize,
    /// The frame's pose θ (the tracked pose of a molded frame).
    pub theta: &'a [f64],
    /// The frame's vertices, metres (a molded frame of the template).
    pub vertices: &'a [DVec3],
}

/// A source of training frames that can be read more than once.
pub trait FrameStream {
    /// The frames' time step, seconds.
    ///
    /// # Errors
    /// Whatever reading the source raises.
    fn frame_time_s(&mut self) -> Result<f64>;

    /// Calls `each` on every frame in order.
    ///
    /// # Errors
    /// Whatever reading the source raises; any error `each` returns.
    fn for_each(&mut self, each: &mut dyn FnMut(TrainingFrame<'_>) -> Result<()>) -> Result<()>;
}

/// A sequence held in memory (tests, short clips): poses and vertices per frame.
#[derive(Debug, Clone, PartialEq)]
pub struct TrainingSequence {
    /// Per frame, the pose θ.
    pub poses: Vec<Vec<f64>>,
    /// Per frame, the vertices, metres.
    pub frames: Vec<Vec<DVec3>>,
    /// Time step, seconds.
    pub frame_time_s: f64,
}

impl FrameStream for [TrainingSequence] {
    fn frame_time_s(&mut self) -> Result<f64> {
        let first = self.first().ok_or(Error::Empty {
            what: "training sequences",
        })?;
        if let Some(s) = self.iter().find(|s| s.frame_time_s != first.frame_time_s) {
            return Err(Error::InvalidParam {
                name: "frame_time_s",
                reason: format!(
                    "sequences at {} and {} s per frame",
                    first.frame_time_s, s.frame_time_s
                ),
            });
        }
        Ok(first.frame_time_s)
    }

    fn for_each(&mut self, each: &mut dyn FnMut(TrainingFrame<'_>) -> Result<()>) -> Result<()> {
        for (sequence, s) in self.iter().enumerate() {
            skin_core::check::same_size("poses vs frames", s.frames.len(), s.poses.len())?;
            for (theta, vertices) in s.poses.iter().zip(&s.frames) {
                each(TrainingFrame {
                    sequence,
                    theta,
                    vertices,
                })?;
            }
        }
        Ok(())
    }
}

/// The model's small parts (everything but the residual basis).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct Parts {
    template: Template,
    frame_time_s: f64,
    params: ShapeModelParams,
    layout: FeatureLayout,
    /// The pose features at the rest pose, subtracted from every frame's.
    feature_rest: Vec<f64>,
    /// Pose regression, `features × k` (row-major).
    pose_weights: Vec<f64>,
    /// Per motion input, its training root-mean-square.
    input_scale: Vec<f64>,
    /// Dynamic map, `(filters · inputs) × k` (row-major): filtered inputs to coordinates.
    dynamic_weights: Vec<f64>,
    /// Frames and sequences learned from.
    training_frames: usize,
    training_sequences: usize,
    /// The ridge weights used (pose, dynamic): chosen or given.
    ridge: [f64; 2],
    /// With cross-validation, the left-out sequences' RMS normal-offset error, metres.
    validation_error_m: Option<f64>,
}

/// A learned dynamic shape model of one template (see the [module](self) documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct ShapeModel {
    parts: Parts,
    /// Residual basis `U`, `n × k` (a row per vertex: its normal offset).
    basis: DMatrix<f64>,
    parents: Vec<Option<usize>>,
}

/// One frame's residual over skinning in the root's frame, flattened.
/// The skinned template at a pose and its unit vertex normals.
fn skinned(template: &Template, fk: &ForwardKinematics) -> Result<(Vec<DVec3>, Vec<DVec3>)> {
    let lbs = skin(
        &template.mesh().vertices,
        template.weights(),
        &template.world_from_rest(fk),
    )?;
    let normals = vertex_normals(&template.mesh_with(lbs.clone()), NormalWeighting::Area)?;
    Ok((lbs, normals))
}

/// One frame's residual over skinning: each vertex's offset along its skinned normal.
fn residual(template: &Template, fk: &ForwardKinematics, vertices: &[DVec3]) -> Result<Vec<f64>> {
    let (lbs, normals) = skinned(template, fk)?;
    Ok(vertices
        .iter()
        .zip(&lbs)
        .zip(&normals)
        .map(|((x, l), n)| (*x - *l).dot(*n))
        .collect())
}

/// What learning keeps per frame: sequence, pose features, motion state.
struct Streamed {
    sequence: Vec<usize>,
    features: Vec<Vec<f64>>,
    inputs: Vec<Vec<f64>>,
}

impl Streamed {
    fn sequence_count(&self) -> usize {
        self.sequence.last().map_or(0, |_| {
            1 + self.sequence.windows(2).filter(|w| w[0] != w[1]).count()
        })
    }
}

impl ShapeModel {
    /// Learns the model of `template` from `stream` (see the [module](self) documentation):
    /// pass 1 sketches the residuals' subspace and gathers the pose features and motion
    /// inputs; pass 2 projects each residual on it; both parts are fitted together on the
    /// `k`-dimensional coordinates.
    ///
    /// # Errors
    /// [`Error::InvalidParam`] for bad parameters or a non-positive frame time;
    /// [`Error::Empty`] for a stream without frames; [`Error::SizeMismatch`] for a frame of
    /// another template or skeleton; [`Error::NonFinite`] for NaN or infinite coordinates;
    /// [`Error::InvalidParam`] when the stream gives other frames the second time; whatever
    /// reading the stream raises. Errors inside the stream say which frame.
    pub fn learn(
        template: &Template,
        stream: &mut (impl FrameStream + ?Sized),
        params: &ShapeModelParams,
    ) -> Result<ShapeModel> {
        params.validate()?;
        let frame_time_s = stream.frame_time_s()?;
        if !(frame_time_s.is_finite() && frame_time_s > 0.0) {
            return Err(Error::InvalidParam {
                name: "frame_time_s",
                reason: format!("{frame_time_s}: give a positive frame time"),
            });
        }
        let skeleton = template.skeleton();
        let parents: Vec<Option<usize>> = skeleton.joints().iter().map(|j| j.parent).collect();
        let layout = FeatureLayout::new(template)?;
        let n = template.vertex_count();
        let ell = 2 * params.components;
        let mut sketch = FrequentDirections::new(n, ell);
        let mut streamed = Streamed {
            sequence: Vec::new(),
            features: Vec::new(),
            inputs: Vec::new(),
        };
        let mut fk = ForwardKinematics::new(skeleton);
        let mut history: Vec<Kinematics> = Vec::new();
        let mut frame = 0;
        stream.for_each(&mut |f: TrainingFrame<'_>| {
            let at = Context::Frame(frame);
            skin_core::check::same_size("frame vertices vs template", n, f.vertices.len())
                .at(at)?;
            if f.vertices.iter().any(|v| !v.is_finite()) {
                return Err(Error::NonFinite {
                    what: "training frame vertices",
                })
                .at(at);
            }
            skeleton.forward_kinematics_into(f.theta, &mut fk).at(at)?;
            sketch.push(&residual(template, &fk, f.vertices).at(at)?);
            if streamed.sequence.last() != Some(&f.sequence) {
                history.clear();
            }
            let k0 = layout.kinematics(&fk, &parents);
            while history.len() < 2 {
                history.push(k0.clone());
            }
            streamed
                .inputs
                .push(layout.motion([&history[0], &history[1], &k0], frame_time_s));
            history.remove(0);
            history.push(k0);
            streamed.features.push(layout.pose(&fk, &parents));
            streamed.sequence.push(f.sequence);
            frame += 1;
            Ok(())
        })?;
        let frames = streamed.sequence.len();
        if frames == 0 {
            return Err(Error::Empty {
                what: "training frames",
            });
        }
        let (basis, _) = sketch.basis(params.components);
        let k = basis.ncols();
        // Pass 2: the coordinates.
        let mut coords = DMatrix::zeros(frames, k);
        let mut t = 0;
        stream.for_each(&mut |f: TrainingFrame<'_>| {
            if t >= frames || streamed.sequence[t] != f.sequence {
                return Err(Error::InvalidParam {
                    name: "stream",
                    reason: "gave other frames on its second reading; give a stream that \
                             repeats itself"
                        .into(),
                });
            }
            skeleton
                .forward_kinematics_into(f.theta, &mut fk)
                .at(Context::Frame(t))?;
            let r = nalgebra::DVector::from_vec(residual(template, &fk, f.vertices)?);
            coords.row_mut(t).copy_from(&basis.tr_mul(&r).transpose());
            t += 1;
            Ok(())
        })?;
        if t != frames {
            return Err(Error::InvalidParam {
                name: "stream",
                reason: format!("gave {t} frames on its second reading, {frames} on its first"),
            });
        }
        let parts = fit_parts(template, frame_time_s, params, layout, &streamed, &coords)?;
        Ok(ShapeModel {
            parts,
            basis,
            parents,
        })
    }

    /// The template the model animates.
    pub fn template(&self) -> &Template {
        &self.parts.template
    }

    /// The frame time the model was learned at (and must be driven at), seconds.
    pub fn frame_time_s(&self) -> f64 {
        self.parts.frame_time_s
    }

    /// The parameters it was learned with.
    pub fn params(&self) -> &ShapeModelParams {
        &self.parts.params
    }

    /// Frames it was learned from.
    pub fn training_frames(&self) -> usize {
        self.parts.training_frames
    }

    /// The ridge weights of the pose and the dynamic part (chosen by cross-validation or
    /// given), and the left-out sequences' RMS normal-offset error when validated, metres.
    pub fn ridge(&self) -> ([f64; 2], Option<f64>) {
        (self.parts.ridge, self.parts.validation_error_m)
    }

    /// Dimension of the residual subspace actually kept (at most
    /// [`ShapeModelParams::components`]; fewer when the data span fewer directions).
    pub fn components(&self) -> usize {
        self.basis.ncols()
    }

    /// The pose-dependent part's coordinates for pose features `f`.
    fn pose_coords(&self, f: &[f64]) -> Vec<f64> {
        let p = &self.parts;
        let k = self.components();
        let mut c = vec![0.0; k];
        for (i, &x) in f.iter().enumerate() {
            let s = x - p.feature_rest[i];
            for (cj, w) in c.iter_mut().zip(&p.pose_weights[i * k..(i + 1) * k]) {
                *cj += s * w;
            }
        }
        c
    }

    /// Vertices from skinning and residual coordinates `c`.
    fn vertices(&self, fk: &ForwardKinematics, c: &[f64]) -> Result<Vec<DVec3>> {
        let (mut x, normals) = skinned(&self.parts.template, fk)?;
        let r = &self.basis * nalgebra::DVector::from_column_slice(c);
        for ((x, n), r) in x.iter_mut().zip(&normals).zip(r.iter()) {
            *x += *n * *r;
        }
        Ok(x)
    }

    /// The template at pose θ with the pose-dependent part alone (no motion history).
    ///
    /// # Errors
    /// As [`skin_core::skeleton::Skeleton::check_pose`].
    pub fn pose_shape(&self, theta: &[f64]) -> Result<Vec<DVec3>> {
        let fk = self.template().skeleton().forward_kinematics(theta)?;
        let c = self.pose_coords(&self.parts.layout.pose(&fk, &self.parents));
        self.vertices(&fk, &c)
    }

    /// A driver from rest: feed it one pose per frame, at [`ShapeModel::frame_time_s`].
    pub fn driver(&self) -> ShapeDriver<'_> {
        let p = &self.parts;
        ShapeDriver {
            model: self,
            fk: ForwardKinematics::new(self.template().skeleton()),
            history: Vec::new(),
            bank: Bank::new(&p.params.poles, p.frame_time_s, p.input_scale.len()),
        }
    }
}

/// Ridge weights [`ShapeModelParams::cross_validate`] chooses from, for the pose and the
/// dynamic part each (relative to the mean diagonal of their block of the Gram matrix).
pub const RIDGE_GRID: [f64; 6] = [0.01, 0.1, 1.0, 10.0, 100.0, 1000.0];

/// The normal equations of a regression: `XᵀX`, `XᵀY` and `tr(YᵀY)`.
struct Normal {
    gram: DMatrix<f64>,
    rhs: DMatrix<f64>,
    energy: f64,
}

impl Normal {
    fn of(x: &DMatrix<f64>, y: &DMatrix<f64>) -> Self {
        Normal {
            gram: x.tr_mul(x),
            rhs: x.tr_mul(y),
            energy: y.norm_squared(),
        }
    }

    /// The ridge solution with block ridge weights `ridge` (relative to each block's mean
    /// Gram diagonal).
    fn solve(&self, blocks: &[std::ops::Range<usize>; 2], ridge: [f64; 2]) -> Result<DMatrix<f64>> {
        let mut gram = self.gram.clone();
        for (range, r) in blocks.iter().zip(ridge) {
            let n = range.len().max(1) as f64;
            let lambda = r * range.clone().map(|i| gram[(i, i)]).sum::<f64>() / n;
            for i in range.clone() {
                gram[(i, i)] += lambda.max(1e-9);
            }
        }
        let chol = gram.cholesky().ok_or(Error::InvalidParam {
            name: "pose_ridge",
            reason: "the regression is singular; give positive ridge weights".into(),
        })?;
        Ok(chol.solve(&self.rhs))
    }

    /// The normal equations of the rows `self` has and `part` has not (`part`'s rows being
    /// some of `self`'s).
    fn without(&self, part: &Normal) -> Normal {
        Normal {
            gram: &self.gram - &part.gram,
            rhs: &self.rhs - &part.rhs,
            energy: self.energy - part.energy,
        }
    }

    /// `‖Y − X W‖²` from the normal equations.
    fn error(&self, w: &DMatrix<f64>) -> f64 {
        self.energy - 2.0 * w.dot(&self.rhs) + w.dot(&(&self.gram * w))
    }
}

/// Most folds [`cross_validate`] leaves out in turn: a stream of more sequences is split into
/// this many groups of consecutive sequences (leave-one-group-out), which keeps validation
/// a few seconds for any number of sequences.
const MAX_FOLDS: usize = 10;

/// Leave-one-sequence-out choice of the two ridge weights from [`RIDGE_GRID`]: each pair is
/// fitted on all sequences but one and scored on the one left out (squared error of the
/// residual coordinates, i.e. of the normal offsets within the subspace), summed over the
/// sequences; returns the best pair and its mean squared coordinate error per frame, m².
/// Beyond [`MAX_FOLDS`] sequences, groups of consecutive sequences are left out instead.
/// Each fold's training equations are the whole stream's minus the fold's own, so the
/// stream's rows are multiplied out once.
fn cross_validate(
    x: &DMatrix<f64>,
    y: &DMatrix<f64>,
    total: &Normal,
    sequence: &[usize],
    blocks: &[std::ops::Range<usize>; 2],
) -> Result<([f64; 2], f64)> {
    // Each frame's sequence number in order of appearance, then its fold.
    let mut rank = Vec::with_capacity(sequence.len());
    for (t, s) in sequence.iter().enumerate() {
        let r = rank
            .last()
            .map_or(0, |&r| r + usize::from(sequence[t - 1] != *s));
        rank.push(r);
    }
    let count = rank.last().map_or(0, |r| r + 1);
    let folds = count.min(MAX_FOLDS);
    let parts: Vec<Normal> = (0..folds)
        .map(|f| {
            let rows: Vec<usize> = (0..sequence.len())
                .filter(|&t| rank[t] * folds / count == f)
                .collect();
            Normal::of(&x.select_rows(&rows), &y.select_rows(&rows))
        })
        .collect();
    let grid = |g: usize| {
        [
            RIDGE_GRID[g / RIDGE_GRID.len()],
            RIDGE_GRID[g % RIDGE_GRID.len()],
        ]
    };
    let mut error = vec![0.0; RIDGE_GRID.len() * RIDGE_GRID.len()];
    for check in &parts {
        let fit = total.without(check);
        for (g, e) in error.iter_mut().enumerate() {
            *e += check.error(&fit.solve(blocks, grid(g))?);
        }
    }
    let (g, e) = error
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))
        .map(|(g, e)| (g, *e))
        .unwrap_or((0, f64::NAN));
    Ok((grid(g), e / sequence.len().max(1) as f64))
}

/// Both parts by one ridge regression of the coordinates on the pose features relative to
/// rest and the filtered motion inputs.
fn fit_parts(
    template: &Template,
    frame_time_s: f64,
    params: &ShapeModelParams,
    layout: FeatureLayout,
    streamed: &Streamed,
    coords: &DMatrix<f64>,
) -> Result<Parts> {
    let (frames, k) = coords.shape();
    let nf = layout.pose_len();
    let m = layout.motion_len();
    if let Some(p) = params
        .poles
        .iter()
        .find(|p| p.frequency_hz >= 0.5 / frame_time_s)
    {
        return Err(Error::InvalidParam {
            name: "poles",
            reason: format!(
                "{} Hz is above the Nyquist frequency of {} s frames",
                p.frequency_hz, frame_time_s
            ),
        });
    }
    // Features relative to rest (not scaled: the rotation features share one natural scale,
    // and a joint that barely moved in training must not get a large weight that a new motion
    // multiplies).
    let skeleton = template.skeleton();
    let rest = layout.pose(
        &skeleton.forward_kinematics(&skeleton.rest_pose())?,
        &skeleton
            .joints()
            .iter()
            .map(|j| j.parent)
            .collect::<Vec<_>>(),
    );
    // Motion inputs scaled by their root-mean-square (not centred: no motion, no input),
    // then filtered from rest at each sequence's start.
    let mut input_scale = vec![0.0; m];
    for u in &streamed.inputs {
        for (s, x) in input_scale.iter_mut().zip(u) {
            *s += x * x / frames as f64;
        }
    }
    for s in &mut input_scale {
        *s = if s.sqrt() > 1e-9 { s.sqrt() } else { 1.0 };
    }
    let mut bank = Bank::new(&params.poles, frame_time_s, m);
    let nd = bank.outputs();
    let mut filtered = Vec::with_capacity(frames);
    for (t, u) in streamed.inputs.iter().enumerate() {
        if t > 0 && streamed.sequence[t] != streamed.sequence[t - 1] {
            bank = Bank::new(&params.poles, frame_time_s, m);
        }
        let scaled: Vec<f64> = u.iter().zip(&input_scale).map(|(x, s)| x / s).collect();
        filtered.push(bank.step(&scaled));
    }
    let x = DMatrix::from_fn(frames, nf + nd, |t, i| {
        if i < nf {
            streamed.features[t][i] - rest[i]
        } else {
            filtered[t][i - nf]
        }
    });
    let blocks = [0..nf, nf..nf + nd];
    let total = Normal::of(&x, coords);
    let (ridge, validation_error) = if params.cross_validate && streamed.sequence_count() > 1 {
        let (ridge, error) = cross_validate(&x, coords, &total, &streamed.sequence, &blocks)?;
        (ridge, Some((error / template.vertex_count() as f64).sqrt()))
    } else {
        ([params.pose_ridge, params.dynamic_ridge], None)
    };
    let w = total.solve(&blocks, ridge)?;
    let w = &w;
    let row = |i: usize| (0..k).map(move |j| w[(i, j)]);
    Ok(Parts {
        template: template.clone(),
        frame_time_s,
        params: params.clone(),
        layout,
        feature_rest: rest,
        pose_weights: (0..nf).flat_map(row).collect(),
        input_scale,
        dynamic_weights: (nf..nf + nd).flat_map(row).collect(),
        training_frames: frames,
        training_sequences: streamed.sequence_count(),
        ridge,
        validation_error_m: validation_error,
    })
}

/// Drives a [`ShapeModel`] along a motion, one pose per frame ([`ShapeModel::driver`]).
#[derive(Debug, Clone)]
pub struct ShapeDriver<'a> {
    model: &'a ShapeModel,
    fk: ForwardKinematics,
    /// The two previous frames' kinematic states.
    history: Vec<Kinematics>,
    /// The filter bank's state.
    bank: Bank,
}

impl ShapeDriver<'_> {
    /// The template at the next frame's pose θ: skinning, the pose-dependent part and the
    /// dynamic part's response to the motion so far. The first frame starts from rest (no
    /// velocity, no swing), as the model was learned.
    ///
    /// # Errors
    /// As [`skin_core::skeleton::Skeleton::check_pose`].
    pub fn step(&mut self, theta: &[f64]) -> Result<Vec<DVec3>> {
        let model = self.model;
        let p = &model.parts;
        model
            .template()
            .skeleton()
            .forward_kinematics_into(theta, &mut self.fk)?;
        let k0 = p.layout.kinematics(&self.fk, &model.parents);
        while self.history.len() < 2 {
            self.history.push(k0.clone());
        }
        let u: Vec<f64> = p
            .layout
            .motion([&self.history[0], &self.history[1], &k0], p.frame_time_s)
            .iter()
            .zip(&p.input_scale)
            .map(|(x, s)| x / s)
            .collect();
        self.history.remove(0);
        self.history.push(k0);
        let y = self.bank.step(&u);
        let mut c = model.pose_coords(&p.layout.pose(&self.fk, &model.parents));
        let k = c.len();
        for (i, yi) in y.iter().enumerate() {
            for (cj, w) in c.iter_mut().zip(&p.dynamic_weights[i * k..(i + 1) * k]) {
                *cj += yi * w;
            }
        }
        model.vertices(&self.fk, &c)
    }
}
