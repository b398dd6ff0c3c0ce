//! Ground truth for validating the needle model on the synthetic studio (Sand, McMillan and
//! Popović 2003 §6, "Results": reconstruction error against a known surface).
//!
//! The studio's performer gives the TRUE posed surface (linear-blend skinning plus the
//! non-skinning bulge and flap) and the LBS-only surface. A needle's true length is the
//! distance from its origin along its direction to where the ray leaves the true mesh; the
//! LBS baseline's length is the same ray against the LBS-skinned rest shape, which is what a
//! skinning-only model predicts. [`TestSet`] precomputes both for a sequence of test poses so
//! that any number of models can be scored cheaply with [`TestSet::errors`].
//!
//! [`HullOracle`] is the pose-local visual hull: the needles' lengths as many cameras see the
//! body at exactly the test pose.
//!
//! Two tools take a predictor's errors apart:
//!
//! * [`TestSet::coverage`] and [`Errors::restricted`]: for a predictor that knows only some
//!   needles (the hull oracle knows the needles some camera saw) and falls back to another
//!   predictor elsewhere, how often it fell back, and every predictor's errors on the
//!   needle-frames it did know, so they are compared on the same needles.
//! * [`EffectAttribution`]: which of the studio's effects — the geometry of skinning itself,
//!   each pose-driven muscle or crease ([`dynamic_shapes_studio::PoseDeformParams`]), the hip
//!   flap — moves each pose-deforming needle most over the test, and
//!   [`EffectAttribution::breakdown`] a predictor's mean error per effect: what "hidden from
//!   silhouettes" means, measured (an inward crease against an outward muscle).

use std::collections::{HashMap, HashSet};

use dynamic_shapes_studio::{
    DeformationParams, DeformationState, FrameTruth, Performer, PoseDeformParams,
    STUDIO_RING_HEIGHT_M, STUDIO_RING_HFOV_DEG, STUDIO_RING_RADIUS_M, STUDIO_RING_TARGET_M,
};
use glam::DVec3;
use rayon::prelude::*;
use skin_core::camera::{Camera, Intrinsics, Rig};
use skin_core::math::Ray;
use skin_core::mesh::{MeshQuery, TriMesh};

use crate::observe::{FrameInput, Observer};
use crate::primitive::NeedleBody;
use crate::reconstruct::NeedleModel;
use crate::{Error, Result};

/// Distance from a needle endpoint to an elbow or knee joint below which the needle counts as
/// "near a joint", metres. The deformation the model must capture (bulges, creases) is
/// concentrated there. Default of the validation: 0.10 m (the goal's 10 cm).
pub const NEAR_JOINT_M: f64 = 0.10;

/// Difference between the true and the LBS length above which a needle counts as
/// "deforming" (it sees non-skinning deformation), metres. Where the performer has no
/// non-skinning deformation the LBS baseline is exact, so errors over all needles favour it;
/// errors over deforming needles measure what the method adds. Default: 0.002 m.
pub const DEFORMING_M: f64 = 0.002;

/// Span over a test set of a needle's non-skinning length (true minus LBS length) above which
/// the needle counts as "pose-deforming", metres: 3 mm (the validation protocol's threshold). With the
/// performer's dynamic effects off, this is the needles whose length the pose-driven shapes
/// change — what a pose-dependent model exists to recover.
pub const POSE_DEFORMING_SPAN_M: f64 = 0.003;

/// A needle's identity: (primitive, needle within it).
pub type NeedleKey = (u32, u32);

/// Name of [`EffectAttribution`]'s category for the geometry of skinning itself: the needle's
/// length under linear blend skinning of the exact rest shape ([`NeedleTruth::lbs_m`]).
pub const SKINNING_GEOMETRY: &str = "skinning_geometry";

/// Name of [`EffectAttribution`]'s category for the performer's dynamic deformation (the hip
/// flap's lag, a garment's departure from its skinning:
/// [`dynamic_shapes_studio::PosedFrame::dynamic_displacement`]).
pub const FLAP: &str = "flap";

/// Largest difference, metres, allowed between the sum of the per-effect displacements
/// [`EffectAttribution`] computes and the performer's own pose-driven displacement before it
/// decides the performer was built with other effects. The effects add exactly
/// (`dynamic_shapes_studio` muscles: linear in their rest-space offsets); 1 µm leaves room for
/// rounding only.
pub const EFFECT_SUM_TOLERANCE_M: f64 = 1e-6;

/// One needle-frame of a pose-deforming needle: the predicted and the true length, metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NeedleSample {
    /// Which needle.
    pub key: NeedleKey,
    /// Predicted length, metres.
    pub predicted_m: f64,
    /// True length, metres.
    pub true_m: f64,
}

/// The share of the pose variance of the pose-deforming needles a predictor explains
/// ([`Errors::pose_r2`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseR2 {
    /// `1 − Σ(pred − true)² / Σ(true − mean_true)²` pooled over the needle-frames of the
    /// pose-deforming needles, each needle's mean true length its own; NaN without samples.
    /// A constant bias of a needle (the visual hull's) alone can make it negative.
    pub r2: f64,
    /// The same with each needle's mean error removed from its predictions: how well the
    /// predictor follows the pose, whatever its bias.
    pub r2_centred: f64,
    /// RMS over the needle-frames of each needle's mean error, mm: the part of the error no
    /// pose dependence can fix (the visual hull's bias). `bias_rms_mm² + centred_rms_mm²` is
    /// the mean squared error.
    pub bias_rms_mm: f64,
    /// RMS of the errors with each needle's mean error removed, mm.
    pub centred_rms_mm: f64,
    /// RMS of the true lengths about each needle's mean, mm: how much the pose moves them.
    pub pose_rms_mm: f64,
}

/// Length of the needle `origin + t·dir`, `t ∈ [0, max_m]`, inside `query`'s closed mesh:
/// the distance to the first hit if that hit is a back face (the ray leaves the body there).
/// `None` when the origin is outside the mesh (first hit is a front face) or nothing is hit.
///
/// # Errors
/// As [`MeshQuery::cast_ray`] (non-finite ray).
pub fn exit_length(
    query: &MeshQuery,
    origin: DVec3,
    dir: DVec3,
    max_m: f64,
) -> Result<Option<f64>> {
    Ok(query
        .cast_ray(Ray::new(origin, dir), max_m)?
        .filter(|h| !h.front_face)
        .map(|h| h.t))
}

/// One scored needle in one test frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NeedleTruth {
    /// Primitive index.
    pub primitive: u32,
    /// Needle index within the primitive.
    pub needle: u32,
    /// True length (ray exit from the true posed mesh), metres.
    pub true_m: f64,
    /// LBS-baseline length (ray exit from the LBS-skinned rest shape; 0 if the origin lies
    /// outside it), metres.
    pub lbs_m: f64,
    /// Whether the true endpoint lies within [`NEAR_JOINT_M`] of an elbow or knee.
    pub near_joint: bool,
}

/// Ground truth of one test frame.
#[derive(Clone, Debug, PartialEq)]
pub struct TestFrame {
    /// The pose θ.
    pub theta: Vec<f64>,
    /// Configuration point of every primitive (the model's input, §3.3).
    pub config: Vec<Vec<f32>>,
    /// Needles whose origin lies inside the true mesh and whose ray leaves it.
    pub needles: Vec<NeedleTruth>,
}

/// Ground truth for a sequence of test poses.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct TestSet {
    /// One entry per scored frame.
    pub frames: Vec<TestFrame>,
}

/// Absolute needle-length errors of one predictor over a [`TestSet`], millimetres.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Errors {
    /// Every scored needle.
    pub all_mm: Vec<f64>,
    /// Needles near an elbow or knee.
    pub near_joints_mm: Vec<f64>,
    /// Needles whose true and LBS lengths differ by more than [`DEFORMING_M`].
    pub deforming_mm: Vec<f64>,
    /// Pose-deforming needles ([`TestSet::pose_deforming`]), every frame they are scored in.
    pub pose_deforming_mm: Vec<f64>,
    /// The needle-frames of the pose-deforming needles (for [`Errors::pose_r2`]).
    pub pose_samples: Vec<NeedleSample>,
    /// Every scored needle-frame in scoring order (frame by frame, each frame's
    /// [`TestFrame::needles`] in order), parallel to [`Errors::all_mm`]: what the predictor
    /// said, e.g. to draw its surface.
    pub samples: Vec<NeedleSample>,
}

/// Cameras per ring of [`HullOracle::rig`].
pub const HULL_ORACLE_CAMERAS_PER_RING: usize = 8;

/// Heights of [`HullOracle::rig`]'s three rings above the floor, metres: below the knees
/// (looking up), the studio ring's at mid-body ([`STUDIO_RING_HEIGHT_M`]), above the head
/// (looking down).
pub const HULL_ORACLE_RING_HEIGHTS_M: [f64; 3] = [0.3, STUDIO_RING_HEIGHT_M, 2.3];

/// The pose-local visual-hull oracle: at each test frame, every needle's length as the
/// cameras of [`HullOracle::rig`] see the body at exactly that pose — the shortest of its
/// silhouette observations ([`Observer`], Sand 2003 §4.3), each the length to where the needle
/// leaves one silhouette. It sees the test poses, so it is an oracle no capture has: what
/// silhouettes show of each pose with no interpolation between poses and no robust
/// percentile. Where no view saw a needle it knows nothing ([`HullOracle::length`] is `None`);
/// [`HullOracle::errors`] fills those in from a fallback model and
/// [`HullOracle::coverage`] counts how often.
///
/// **Where it is a bound.** The visual hull contains the body, so with exact silhouettes each
/// observation, and their shortest, is at least the true length: an upper bound on what the
/// silhouettes say about that needle at that pose. Pixels and the walk's knots make it fall
/// short of the truth by up to about a pixel's footprint, where it is no bound. Nor is it a
/// bound on how well a model follows the pose: a model pooling many poses can follow it
/// better than the per-pose shortest, whose noise changes from pose to pose.
#[derive(Clone, Debug, Default)]
pub struct HullOracle {
    /// Per frame: its pose and the shortest observation of every needle some view saw.
    frames: Vec<(Vec<f64>, HashMap<NeedleKey, f64>)>,
}

impl HullOracle {
    /// The oracle's 24 cameras: [`HULL_ORACLE_CAMERAS_PER_RING`] on each of three rings of the
    /// studio's radius ([`STUDIO_RING_RADIUS_M`]) at [`HULL_ORACLE_RING_HEIGHTS_M`], all
    /// looking at the studio's mid-body target ([`STUDIO_RING_TARGET_M`]) with the studio
    /// ring's lens ([`STUDIO_RING_HFOV_DEG`]), the rings turned a third of their spacing from
    /// each other (24 azimuths 15° apart), images `width × height`.
    ///
    /// # Errors
    /// As [`Intrinsics::from_horizontal_fov`] (a zero image size) and [`Camera::look_at`].
    pub fn rig(width: u32, height: u32) -> Result<Rig> {
        let k = Intrinsics::from_horizontal_fov(STUDIO_RING_HFOV_DEG.to_radians(), width, height)?;
        let target = DVec3::from_array(STUDIO_RING_TARGET_M);
        let per_ring = HULL_ORACLE_CAMERAS_PER_RING as f64;
        let mut cameras = Vec::with_capacity(3 * HULL_ORACLE_CAMERAS_PER_RING);
        for (r, &h) in HULL_ORACLE_RING_HEIGHTS_M.iter().enumerate() {
            for i in 0..HULL_ORACLE_CAMERAS_PER_RING {
                let a = std::f64::consts::TAU * (i as f64 + r as f64 / 3.0) / per_ring;
                let eye = DVec3::new(
                    STUDIO_RING_RADIUS_M * a.cos(),
                    h,
                    STUDIO_RING_RADIUS_M * a.sin(),
                );
                cameras.push(Camera::look_at(k, eye, target, DVec3::Y)?);
            }
        }
        Ok(Rig { cameras })
    }

    /// Records test frames, in the order of the test set's frames: each the pose and one
    /// silhouette per camera of `observer` (whose cameras are [`HullOracle::rig`]'s or any
    /// others). Frames are walked in parallel.
    ///
    /// # Errors
    /// As [`Observer::accumulate`] (masks of the wrong count or size, a bad pose), in
    /// [`Error::At`] with the frame's [`crate::Context::Frame`] among these frames.
    pub fn push_frames(&mut self, observer: &Observer, frames: &[FrameInput<'_>]) -> Result<()> {
        use crate::ResultExt;
        let shortest: Vec<HashMap<NeedleKey, f64>> = frames
            .par_iter()
            .enumerate()
            .map(|(i, f)| {
                let store = observer
                    .accumulate(std::slice::from_ref(f))
                    .at(crate::Context::Frame(i))?
                    .store;
                let mut map = HashMap::new();
                for p in 0..store.primitive_count() {
                    for o in store.observations(p) {
                        let l = map
                            .entry((p as u32, u32::from(o.needle)))
                            .or_insert(f64::INFINITY);
                        *l = f64::min(*l, f64::from(o.length_m));
                    }
                }
                Ok(map)
            })
            .collect::<Result<_>>()?;
        self.frames
            .extend(frames.iter().map(|f| f.theta.to_vec()).zip(shortest));
        Ok(())
    }

    /// Number of frames recorded.
    pub fn frame_count(&self) -> usize {
        self.frames.len()
    }

    /// The oracle's length of needle `key` in frame `k`, metres; `None` where no view saw it.
    pub fn length(&self, k: usize, key: NeedleKey) -> Option<f64> {
        self.frames.get(k).and_then(|(_, m)| m.get(&key).copied())
    }

    /// How many of `set`'s needle-frames some view saw ([`TestSet::coverage`]).
    pub fn coverage(&self, set: &TestSet) -> Coverage {
        set.coverage(|k, n| self.length(k, (n.primitive, n.needle)).is_some())
    }

    /// The oracle's errors on `set` (recorded frame by frame from the same poses), with
    /// `fallback`'s length where no view saw a needle. Restrict them to the needles it saw
    /// with [`Errors::restricted`] and [`HullOracle::length`].
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] for a test set of another frame count, [`Error::InvalidParam`]
    /// for one of other poses; as [`NeedleModel::needle_lengths`] (a fallback of another
    /// body).
    pub fn errors(&self, set: &TestSet, fallback: &NeedleModel) -> Result<Errors> {
        if self.frames.len() != set.frames.len() {
            return Err(Error::SizeMismatch {
                what: "hull oracle frames vs test set",
                expected: set.frames.len(),
                got: self.frames.len(),
            });
        }
        if self
            .frames
            .iter()
            .zip(&set.frames)
            .any(|((theta, _), f)| *theta != f.theta)
        {
            return Err(Error::InvalidParam {
                name: "set",
                reason: "the hull oracle saw other poses than the test set's".into(),
            });
        }
        set.errors_of(|k, n| match self.length(k, (n.primitive, n.needle)) {
            Some(l) => Ok(l),
            None => {
                let p = n.primitive as usize;
                let l = fallback.needle_lengths(p, &set.frames[k].config[p])?;
                l.get(n.needle as usize)
                    .map(|&l| f64::from(l))
                    .ok_or(Error::SizeMismatch {
                        what: "fallback needle count",
                        expected: n.needle as usize + 1,
                        got: l.len(),
                    })
            }
        })
    }
}

/// How many of a test set's scored needle-frames a partial predictor knew
/// ([`TestSet::coverage`]); the rest it filled in from a fallback.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Coverage {
    /// Scored needle-frames.
    pub needle_frames: usize,
    /// Of those, the ones the predictor knew.
    pub observed: usize,
    /// Needle-frames of the pose-deforming needles ([`TestSet::pose_deforming`]).
    pub pose_deforming_needle_frames: usize,
    /// Of those, the ones the predictor knew.
    pub pose_deforming_observed: usize,
}

impl Coverage {
    /// Share of all scored needle-frames filled in from the fallback; NaN without any.
    pub fn fallback_share(&self) -> f64 {
        share(self.needle_frames - self.observed, self.needle_frames)
    }

    /// Share of the pose-deforming needle-frames filled in from the fallback; NaN without any.
    pub fn pose_deforming_fallback_share(&self) -> f64 {
        share(
            self.pose_deforming_needle_frames - self.pose_deforming_observed,
            self.pose_deforming_needle_frames,
        )
    }
}

fn short_share(samples: &[NeedleSample], slack_m: f64) -> f64 {
    let short = samples
        .iter()
        .filter(|s| s.predicted_m < s.true_m - slack_m)
        .count();
    share(short, samples.len())
}

fn share(part: usize, whole: usize) -> f64 {
    if whole == 0 {
        f64::NAN
    } else {
        part as f64 / whole as f64
    }
}

/// One category's share of a predictor's error on the pose-deforming needles
/// ([`EffectAttribution::breakdown`]).
#[derive(Clone, Debug, PartialEq)]
pub struct EffectErrors {
    /// The category: [`SKINNING_GEOMETRY`], a pose effect's name (e.g. `"l_elbow_crease"`) or
    /// [`FLAP`].
    pub effect: String,
    /// Pose-deforming needles this category dominates (among those the errors cover).
    pub needles: usize,
    /// Their needle-frames in the errors.
    pub needle_frames: usize,
    /// Mean absolute length error over those needle-frames, mm; NaN without any.
    pub mean_mm: f64,
}

/// Which studio effect moves each needle most over a test set: the geometry of skinning
/// itself, each pose-driven effect of the performer, or its dynamic deformation (the flap).
///
/// **The rule.** For needle-frame `(k, n)` of a needle with unit direction `d̂` leaving the
/// true mesh at point `x` (a face and barycentric weights), each category has a value:
///
/// * [`SKINNING_GEOMETRY`]: the needle's length under LBS of the exact rest shape,
///   [`NeedleTruth::lbs_m`];
/// * each pose effect `e` of the performer ([`dynamic_shapes_studio::PoseEffect`], in the order of
///   [`PoseDeformParams::effects`]): `u_e(x) · d̂`, its displacement at `x` (barycentric over
///   the face's vertices) projected on the needle — to first order the length it adds where
///   the surface is normal to the needle;
/// * [`FLAP`]: the same of the dynamic displacement
///   ([`dynamic_shapes_studio::PosedFrame::dynamic_displacement`]).
///
/// A category's **span** for a needle is the largest minus the smallest of its values over
/// the frames in which the needle is scored, and the needle's **dominant** category is the one
/// of largest span (ties to the earlier category, skinning geometry first). So a needle whose
/// length the bending of skinning moves by 4 cm while a crease moves it 1 cm is skinning
/// geometry's, even though it is pose-deforming; an upper-arm needle in the middle of the
/// biceps, which skinning carries rigidly, is the biceps'.
#[derive(Clone, Debug)]
pub struct EffectAttribution {
    /// Category names: skinning geometry, the effects, the flap.
    categories: Vec<String>,
    /// One performer per pose effect, with that effect alone.
    single: Vec<Performer>,
    /// Per needle, per category: (smallest, largest) value so far.
    ranges: HashMap<NeedleKey, Vec<(f64, f64)>>,
}

impl EffectAttribution {
    /// Prepares the attribution for `performer`, whose pose-driven deformation is `effects`
    /// (the [`DeformationParams::pose`] it was built with; an empty list if it has none).
    /// Each effect's displacement comes from a copy of the performer with that effect alone;
    /// [`EffectAttribution::push_frame`] checks that they add up to the performer's own.
    ///
    /// # Errors
    /// As [`Performer::new`] (an effect the skeleton cannot carry).
    pub fn new(performer: &Performer, effects: &PoseDeformParams) -> Result<Self> {
        let single = effects
            .effects
            .iter()
            .map(|e| {
                Performer::new(
                    performer.name.clone(),
                    performer.template.clone(),
                    performer.skeleton.clone(),
                    performer.weights.clone(),
                    &DeformationParams::none().with_pose(Some(effects.clone().only(&e.name))),
                )
            })
            .collect::<skin_core::Result<Vec<_>>>()?;
        Ok(Self::with_categories(
            effects.effects.iter().map(|e| e.name.clone()),
            single,
        ))
    }

    fn with_categories(effects: impl Iterator<Item = String>, single: Vec<Performer>) -> Self {
        let mut categories = vec![SKINNING_GEOMETRY.to_string()];
        categories.extend(effects);
        categories.push(FLAP.to_string());
        Self {
            categories,
            single,
            ranges: HashMap::new(),
        }
    }

    /// The categories, in order: [`SKINNING_GEOMETRY`], the pose effects, [`FLAP`].
    pub fn categories(&self) -> &[String] {
        &self.categories
    }

    /// Records the values of every scored needle of `frame` (the [`TestFrame`] that
    /// [`TestSet::push_frame`] made of `truth`).
    ///
    /// # Errors
    /// [`Error::InvalidParam`] if `frame` is not `truth`'s (another pose), if a scored needle
    /// no longer leaves the true mesh where `frame` says, or if the per-effect displacements do
    /// not add up to `truth`'s pose-driven displacement within [`EFFECT_SUM_TOLERANCE_M`] (a
    /// performer built with other effects); [`Error::SizeMismatch`] for a truth of another
    /// performer or a frame of another body; as forward kinematics and [`MeshQuery::new`].
    pub fn push_frame(
        &mut self,
        body: &NeedleBody,
        performer: &Performer,
        truth: &FrameTruth,
        frame: &TestFrame,
    ) -> Result<()> {
        if frame.theta != truth.theta {
            return Err(Error::InvalidParam {
                name: "frame",
                reason: "the test frame's pose is not the truth's".into(),
            });
        }
        let nv = performer.template.vertices.len();
        let posed = &truth.posed;
        for (what, len) in [
            ("true vertices", posed.true_vertices.len()),
            ("pose displacement", posed.pose_displacement.len()),
            ("dynamic displacement", posed.dynamic_displacement.len()),
        ] {
            if len != nv {
                return Err(Error::SizeMismatch {
                    what,
                    expected: nv,
                    got: len,
                });
            }
        }
        // Each effect alone at this pose (no dynamics: a fresh state).
        let per_effect: Vec<Vec<DVec3>> = self
            .single
            .par_iter()
            .map(|p| {
                p.pose(&truth.theta, &mut DeformationState::default(), 1.0)
                    .map(|f| f.pose_displacement)
            })
            .collect::<skin_core::Result<_>>()?;
        for (v, total) in posed.pose_displacement.iter().enumerate() {
            let sum: DVec3 = per_effect.iter().map(|d| d[v]).sum();
            let gap = sum.distance(*total);
            // NaN (a non-finite displacement) fails too.
            if gap.is_nan() || gap > EFFECT_SUM_TOLERANCE_M {
                return Err(Error::InvalidParam {
                    name: "effects",
                    reason: format!(
                        "the effects' displacements miss the performer's by {gap} m at vertex \
                         {v}: it was built with other pose effects"
                    ),
                });
            }
        }
        let mesh = performer.mesh(posed.true_vertices.clone());
        let query = MeshQuery::new(&mesh)?;
        let fk = performer.skeleton.forward_kinematics(&truth.theta)?;
        let values: Vec<Vec<f64>> = frame
            .needles
            .par_iter()
            .map(|n| {
                let prim =
                    body.primitives
                        .get(n.primitive as usize)
                        .ok_or(Error::SizeMismatch {
                            what: "body primitives vs test frame",
                            expected: n.primitive as usize + 1,
                            got: body.primitives.len(),
                        })?;
                if n.needle as usize >= prim.needle_count() {
                    return Err(Error::SizeMismatch {
                        what: "primitive needles vs test frame",
                        expected: n.needle as usize + 1,
                        got: prim.needle_count(),
                    });
                }
                let (o, d) =
                    prim.needle_world(&fk.world_from_joint()[prim.carrier], n.needle as usize);
                let hit = query
                    .cast_ray(Ray::new(o, d), prim.max_length_m)?
                    .filter(|h| !h.front_face && (h.t - n.true_m).abs() <= 1e-9)
                    .ok_or_else(|| Error::InvalidParam {
                        name: "frame",
                        reason: format!(
                            "needle {} of primitive {} does not leave the true mesh at its \
                             true length",
                            n.needle, n.primitive
                        ),
                    })?;
                let face = mesh.faces[hit.point.face as usize];
                let at = |u: &[DVec3]| -> f64 {
                    face.iter()
                        .zip(&hit.point.bary)
                        .map(|(&v, &b)| u[v as usize] * b)
                        .sum::<DVec3>()
                        .dot(d)
                };
                let mut row = Vec::with_capacity(self.categories.len());
                row.push(n.lbs_m);
                row.extend(per_effect.iter().map(|u| at(u)));
                row.push(at(&posed.dynamic_displacement));
                Ok(row)
            })
            .collect::<Result<_>>()?;
        for (n, row) in frame.needles.iter().zip(&values) {
            self.push((n.primitive, n.needle), row);
        }
        Ok(())
    }

    /// Records one needle-frame's values, one per category (the rule in the type's docs).
    fn push(&mut self, key: NeedleKey, values: &[f64]) {
        let ranges = self
            .ranges
            .entry(key)
            .or_insert_with(|| vec![(f64::INFINITY, f64::NEG_INFINITY); values.len()]);
        for (r, &v) in ranges.iter_mut().zip(values) {
            *r = (r.0.min(v), r.1.max(v));
        }
    }

    /// Each category's span for needle `key`, metres, in the order of
    /// [`EffectAttribution::categories`]; `None` for a needle never pushed.
    pub fn spans(&self, key: NeedleKey) -> Option<Vec<f64>> {
        self.ranges
            .get(&key)
            .map(|r| r.iter().map(|(lo, hi)| hi - lo).collect())
    }

    /// The dominant category of needle `key` (an index into
    /// [`EffectAttribution::categories`]); `None` for a needle never pushed.
    pub fn dominant(&self, key: NeedleKey) -> Option<usize> {
        let spans = self.spans(key)?;
        let mut best = 0;
        for (i, s) in spans.iter().enumerate() {
            if *s > spans[best] {
                best = i;
            }
        }
        Some(best)
    }

    /// `errors`' pose-deforming needle-frames ([`Errors::pose_samples`]) grouped by their
    /// needle's dominant category, one entry per category in the order of
    /// [`EffectAttribution::categories`] (empty categories too).
    ///
    /// # Errors
    /// [`Error::InvalidParam`] naming a needle of `errors` that was never pushed (errors of
    /// another test set).
    pub fn breakdown(&self, errors: &Errors) -> Result<Vec<EffectErrors>> {
        let mut needles: Vec<HashSet<NeedleKey>> = vec![HashSet::new(); self.categories.len()];
        let mut sums = vec![(0usize, 0.0f64); self.categories.len()];
        for s in &errors.pose_samples {
            let c = self.dominant(s.key).ok_or_else(|| Error::InvalidParam {
                name: "errors",
                reason: format!(
                    "needle {} of primitive {} has no attribution: errors of another test set",
                    s.key.1, s.key.0
                ),
            })?;
            needles[c].insert(s.key);
            sums[c].0 += 1;
            sums[c].1 += (s.predicted_m - s.true_m).abs() * 1e3;
        }
        Ok(self
            .categories
            .iter()
            .zip(needles)
            .zip(sums)
            .map(|((effect, needles), (count, sum))| EffectErrors {
                effect: effect.clone(),
                needles: needles.len(),
                needle_frames: count,
                mean_mm: if count == 0 {
                    f64::NAN
                } else {
                    sum / count as f64
                },
            })
            .collect())
    }
}

impl TestSet {
    /// Records the truth of one captured frame (its pose and the performer's true and
    /// LBS surfaces there, from [`dynamic_shapes_studio::Capture`]).
    ///
    /// # Errors
    /// As forward kinematics, [`MeshQuery::new`] and the configuration points;
    /// [`Error::SizeMismatch`] if the vertex counts differ from the template's.
    pub fn push_frame(
        &mut self,
        body: &NeedleBody,
        performer: &Performer,
        truth: &FrameTruth,
    ) -> Result<()> {
        let theta = &truth.theta[..];
        let (true_vertices, lbs_vertices) = (
            &truth.posed.true_vertices[..],
            &truth.posed.lbs_vertices[..],
        );
        let nv = performer.template.vertices.len();
        for (what, v) in [
            ("true vertices", true_vertices),
            ("lbs vertices", lbs_vertices),
        ] {
            if v.len() != nv {
                return Err(Error::SizeMismatch {
                    what,
                    expected: nv,
                    got: v.len(),
                });
            }
        }
        let mesh = |v: &[DVec3]| performer.mesh(v.to_vec());
        let true_q = MeshQuery::new(&mesh(true_vertices))?;
        let lbs_q = MeshQuery::new(&mesh(lbs_vertices))?;
        let fk = performer.skeleton.forward_kinematics(theta)?;
        let joints = fk.joint_positions();
        let near: Vec<DVec3> = ["l_elbow", "r_elbow", "l_knee", "r_knee"]
            .iter()
            .filter_map(|n| performer.skeleton.joint_index(n))
            .map(|j| joints[j])
            .collect();
        let mut frame = TestFrame {
            theta: theta.to_vec(),
            config: Vec::with_capacity(body.primitives.len()),
            needles: vec![],
        };
        for (p, prim) in body.primitives.iter().enumerate() {
            frame.config.push(prim.config.point_f32(&fk)?);
            let t = fk.world_from_joint()[prim.carrier];
            for j in 0..prim.needle_count() {
                let (o, d) = prim.needle_world(&t, j);
                let Some(true_m) = exit_length(&true_q, o, d, prim.max_length_m)? else {
                    continue;
                };
                let lbs_m = exit_length(&lbs_q, o, d, 2.0 * prim.max_length_m)?.unwrap_or(0.0);
                let end = o + d * true_m;
                frame.needles.push(NeedleTruth {
                    primitive: p as u32,
                    needle: j as u32,
                    true_m,
                    lbs_m,
                    near_joint: near.iter().any(|&c| c.distance(end) <= NEAR_JOINT_M),
                });
            }
        }
        self.frames.push(frame);
        Ok(())
    }

    /// Errors of a reconstructed model.
    ///
    /// # Errors
    /// As [`NeedleModel::needle_lengths`] (model of another body).
    pub fn errors(&self, model: &NeedleModel) -> Result<Errors> {
        let deforming = self.pose_deforming();
        let mut out = Errors::default();
        for f in &self.frames {
            let pred: Vec<Vec<f32>> = f
                .config
                .iter()
                .enumerate()
                .map(|(p, c)| model.needle_lengths(p, c))
                .collect::<Result<_>>()?;
            for n in &f.needles {
                let l = pred[n.primitive as usize]
                    .get(n.needle as usize)
                    .copied()
                    .ok_or(Error::SizeMismatch {
                        what: "model needle count",
                        expected: n.needle as usize + 1,
                        got: pred[n.primitive as usize].len(),
                    })?;
                out.push(n, l as f64, &deforming);
            }
        }
        Ok(out)
    }

    /// Errors of any surface predictor: `surface(θ)` is its closed surface at the test pose θ
    /// (e.g. [`crate::baseline::SkinnedShape::pose`]), and a needle's predicted length is
    /// where its ray leaves that surface, as for the truth (0 when the origin lies outside).
    ///
    /// # Errors
    /// As forward kinematics, [`MeshQuery::new`] and `surface`;
    /// [`Error::SizeMismatch`] for a test set of another body.
    pub fn surface_errors(
        &self,
        body: &NeedleBody,
        skeleton: &skin_core::skeleton::Skeleton,
        surface: impl Fn(&[f64]) -> Result<TriMesh> + Sync,
    ) -> Result<Errors> {
        let deforming = self.pose_deforming();
        // Frames in parallel (a surface and its ray-cast tree per frame), pushed in order.
        let lengths: Vec<Vec<f64>> = self
            .frames
            .par_iter()
            .map(|f| {
                let query = MeshQuery::new(&surface(&f.theta)?)?;
                let fk = skeleton.forward_kinematics(&f.theta)?;
                f.needles
                    .iter()
                    .map(|n| {
                        let prim = body.primitives.get(n.primitive as usize).ok_or(
                            Error::SizeMismatch {
                                what: "body primitives vs test set",
                                expected: n.primitive as usize + 1,
                                got: body.primitives.len(),
                            },
                        )?;
                        if n.needle as usize >= prim.needle_count() {
                            return Err(Error::SizeMismatch {
                                what: "primitive needles vs test set",
                                expected: n.needle as usize + 1,
                                got: prim.needle_count(),
                            });
                        }
                        let t = fk.world_from_joint()[prim.carrier];
                        let (o, d) = prim.needle_world(&t, n.needle as usize);
                        Ok(exit_length(&query, o, d, 2.0 * prim.max_length_m)?.unwrap_or(0.0))
                    })
                    .collect()
            })
            .collect::<Result<_>>()?;
        let mut out = Errors::default();
        for (f, l) in self.frames.iter().zip(&lengths) {
            for (n, &l) in f.needles.iter().zip(l) {
                out.push(n, l, &deforming);
            }
        }
        Ok(out)
    }

    /// Errors of the LBS baseline (the skinned rest shape).
    pub fn lbs_errors(&self) -> Errors {
        self.errors_of(|_, n| Ok::<_, std::convert::Infallible>(n.lbs_m))
            .unwrap_or_else(|never| match never {})
    }

    /// Errors of any per-needle predictor: `predict(k, n)` is the predicted length (metres)
    /// of needle-frame `n` of frame `k` ([`TestSet::frames`]).
    ///
    /// # Errors
    /// The first error of `predict`.
    pub fn errors_of<E>(
        &self,
        mut predict: impl FnMut(usize, &NeedleTruth) -> std::result::Result<f64, E>,
    ) -> std::result::Result<Errors, E> {
        let deforming = self.pose_deforming();
        let mut out = Errors::default();
        for (k, f) in self.frames.iter().enumerate() {
            for n in &f.needles {
                out.push(n, predict(k, n)?, &deforming);
            }
        }
        Ok(out)
    }

    /// The pose-deforming needles: those whose non-skinning length (true minus LBS length)
    /// spans more than [`POSE_DEFORMING_SPAN_M`] over the frames in which they are scored.
    pub fn pose_deforming(&self) -> HashSet<NeedleKey> {
        let mut range: HashMap<NeedleKey, (f64, f64)> = HashMap::new();
        for n in self.frames.iter().flat_map(|f| &f.needles) {
            let d = n.true_m - n.lbs_m;
            let r = range
                .entry((n.primitive, n.needle))
                .or_insert((f64::INFINITY, f64::NEG_INFINITY));
            *r = (r.0.min(d), r.1.max(d));
        }
        range
            .into_iter()
            .filter(|(_, (lo, hi))| hi - lo > POSE_DEFORMING_SPAN_M)
            .map(|(k, _)| k)
            .collect()
    }

    /// How many scored needle-frames a partial predictor knew: `observed(k, n)` says whether
    /// it knew needle-frame `n` of frame `k` (the rest it filled in from a fallback).
    pub fn coverage(&self, mut observed: impl FnMut(usize, &NeedleTruth) -> bool) -> Coverage {
        let deforming = self.pose_deforming();
        let mut c = Coverage::default();
        for (k, f) in self.frames.iter().enumerate() {
            for n in &f.needles {
                let seen = observed(k, n);
                c.needle_frames += 1;
                c.observed += usize::from(seen);
                if deforming.contains(&(n.primitive, n.needle)) {
                    c.pose_deforming_needle_frames += 1;
                    c.pose_deforming_observed += usize::from(seen);
                }
            }
        }
        c
    }
}

impl Errors {
    /// Records the prediction `predicted_m` of needle-frame `n`; `deforming` is
    /// [`TestSet::pose_deforming`].
    fn push(&mut self, n: &NeedleTruth, predicted_m: f64, deforming: &HashSet<NeedleKey>) {
        let e_mm = (predicted_m - n.true_m).abs() * 1e3;
        let key = (n.primitive, n.needle);
        let sample = NeedleSample {
            key,
            predicted_m,
            true_m: n.true_m,
        };
        self.all_mm.push(e_mm);
        self.samples.push(sample);
        if n.near_joint {
            self.near_joints_mm.push(e_mm);
        }
        if (n.true_m - n.lbs_m).abs() > DEFORMING_M {
            self.deforming_mm.push(e_mm);
        }
        if deforming.contains(&key) {
            self.pose_deforming_mm.push(e_mm);
            self.pose_samples.push(sample);
        }
    }

    /// These errors on the needle-frames of `set` that `keep(k, n)` selects (needle-frame `n`
    /// of frame `k`), `set` being the test set they were scored on: the pose-deforming needles
    /// stay those of the whole set, so predictors restricted to one subset are compared on the
    /// same needle-frames (e.g. those a visual-hull oracle saw, [`TestSet::coverage`]).
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if these errors are not one per needle-frame of `set`, and
    /// [`Error::InvalidParam`] if their needles are not `set`'s, in its order.
    pub fn restricted(
        &self,
        set: &TestSet,
        mut keep: impl FnMut(usize, &NeedleTruth) -> bool,
    ) -> Result<Errors> {
        let total: usize = set.frames.iter().map(|f| f.needles.len()).sum();
        if self.samples.len() != total {
            return Err(Error::SizeMismatch {
                what: "errors vs test set needle-frames",
                expected: total,
                got: self.samples.len(),
            });
        }
        let deforming = set.pose_deforming();
        let mut out = Errors::default();
        let mut samples = self.samples.iter();
        for (k, f) in set.frames.iter().enumerate() {
            for (n, s) in f.needles.iter().zip(samples.by_ref()) {
                if s.key != (n.primitive, n.needle) || s.true_m != n.true_m {
                    return Err(Error::InvalidParam {
                        name: "set",
                        reason: "the errors were scored on another test set".into(),
                    });
                }
                if keep(k, n) {
                    out.push(n, s.predicted_m, &deforming);
                }
            }
        }
        Ok(out)
    }

    /// Share of the scored needle-frames ([`Errors::samples`]) whose prediction falls short of
    /// the truth by more than `slack_m` metres: where a predictor meant as an outer bound (the
    /// visual hull's, [`HullOracle`]) is none. NaN without samples.
    pub fn short_share(&self, slack_m: f64) -> f64 {
        short_share(&self.samples, slack_m)
    }

    /// [`Errors::short_share`] over the pose-deforming needle-frames
    /// ([`Errors::pose_samples`]).
    pub fn pose_short_share(&self, slack_m: f64) -> f64 {
        short_share(&self.pose_samples, slack_m)
    }

    /// The share of the pose variance of the pose-deforming needles this predictor explains
    /// (`pose_r2` and `pose_r2_centred` in `docs/needle-model.md`).
    pub fn pose_r2(&self) -> PoseR2 {
        // Per needle: count, mean true length, mean error.
        let mut per: HashMap<NeedleKey, (f64, f64, f64)> = HashMap::new();
        for s in &self.pose_samples {
            let e = per.entry(s.key).or_insert((0.0, 0.0, 0.0));
            *e = (e.0 + 1.0, e.1 + s.true_m, e.2 + (s.predicted_m - s.true_m));
        }
        let (mut total, mut residual, mut centred, mut bias) = (0.0, 0.0, 0.0, 0.0);
        for s in &self.pose_samples {
            let (n, sum_true, sum_err) = per[&s.key];
            let err = s.predicted_m - s.true_m;
            total += (s.true_m - sum_true / n).powi(2);
            residual += err * err;
            centred += (err - sum_err / n).powi(2);
            bias += (sum_err / n).powi(2);
        }
        let count = self.pose_samples.len() as f64;
        let rms_mm = |ss: f64| (ss / count).sqrt() * 1e3;
        if self.pose_samples.is_empty() || total <= 0.0 {
            return PoseR2 {
                r2: f64::NAN,
                r2_centred: f64::NAN,
                bias_rms_mm: f64::NAN,
                centred_rms_mm: f64::NAN,
                pose_rms_mm: f64::NAN,
            };
        }
        PoseR2 {
            r2: 1.0 - residual / total,
            r2_centred: 1.0 - centred / total,
            bias_rms_mm: rms_mm(bias),
            centred_rms_mm: rms_mm(centred),
            pose_rms_mm: rms_mm(total),
        }
    }
}

#[cfg(test)]
mod tests;
