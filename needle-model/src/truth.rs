//! Ground truth for validating the needle model on the synthetic studio (Sand, McMillan and
//! Popović 2003 §6, "Results": reconstruction error against a known surface).
//!
//! The studio's performer gives the TRUE posed surface (linear-blend skinning plus the
//! non-skinning bulge and flap) and the LBS-only surface. A needle's true length is the
//! distance from its origin along its direction to where the ray leaves the true mesh; the
//! LBS baseline's length is the same ray against the LBS-skinned rest shape, which is what a
//! skinning-only model predicts. [`TestSet`] precomputes both for a sequence of test poses so
//! that any number of models can be scored cheaply with [`TestSet::errors`].

use std::collections::{HashMap, HashSet};

use glam::DVec3;
use rayon::prelude::*;
use skin_core::math::Ray;
use skin_core::mesh::{MeshQuery, TriMesh};
use skin_core::studio::{FrameTruth, Performer};

use crate::primitive::NeedleBody;
use crate::reconstruct::NeedleModel;
use crate::{Error, Result};

/// Distance from a needle endpoint to an elbow or knee joint below which the needle counts as
/// "near a joint", metres. The deformation the model must capture (bulges, creases) is
/// concentrated there. Default of the validation: 0.10 m (the 10 cm).
pub const NEAR_JOINT_M: f64 = 0.10;

/// Difference between the true and the LBS length above which a needle counts as
/// "deforming" (it sees non-skinning deformation), metres. Where the performer has no
/// non-skinning deformation the LBS baseline is exact, so errors over all needles favour it;
/// errors over deforming needles measure what the method adds. Default: 0.002 m.
pub const DEFORMING_M: f64 = 0.002;

/// Span over a test set of a needle's non-skinning length (true minus LBS length) above which
/// the needle counts as "pose-deforming", metres: 3 mm (the needle follow-up issue). With the
/// performer's dynamic effects off, this is the needles whose length the pose-driven shapes
/// change — what a pose-dependent model exists to recover.
pub const POSE_DEFORMING_SPAN_M: f64 = 0.003;

/// A needle's identity: (primitive, needle within it).
pub type NeedleKey = (u32, u32);

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

impl TestSet {
    /// Records the truth of one captured frame (its pose and the performer's true and
    /// LBS surfaces there, from [`skin_core::studio::Capture`]).
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

    /// The share of the pose variance of the pose-deforming needles this predictor explains
    /// (the needle follow-up issue's `pose_r2` and `pose_r2_centred`).
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
mod tests {
    use super::*;

    fn needle(primitive: u32, true_m: f64, lbs_m: f64) -> NeedleTruth {
        NeedleTruth {
            primitive,
            needle: 0,
            true_m,
            lbs_m,
            near_joint: false,
        }
    }

    /// Three frames of two needles: needle 0's non-skinning length spans 6 mm (pose-deforming),
    /// needle 1's 1 mm (not).
    fn set(lbs_bias_m: f64) -> TestSet {
        let frames = [(0.000, 0.000), (0.003, 0.001), (0.006, 0.0005)]
            .iter()
            .map(|&(d0, d1)| TestFrame {
                theta: vec![],
                config: vec![],
                needles: vec![
                    needle(0, 0.05 + d0, 0.05 + lbs_bias_m),
                    needle(1, 0.04 + d1, 0.04),
                ],
            })
            .collect();
        TestSet { frames }
    }

    #[test]
    fn pose_deforming_needles_and_their_r2() {
        let t = set(0.0);
        assert_eq!(t.pose_deforming(), HashSet::from([(0, 0)]));
        // The LBS predicts needle 0's mean-free part not at all: its constant prediction at
        // the first frame's length explains nothing (r2 < 0: it is also biased), and nothing
        // once its mean error is removed (r2_centred = 0).
        let e = t.lbs_errors();
        assert_eq!(e.all_mm.len(), 6);
        assert_eq!(e.samples.len(), 6);
        assert_eq!(e.samples[2].key, (0, 0));
        assert_eq!(e.samples[2].predicted_m, 0.05);
        assert_eq!(e.pose_deforming_mm.len(), 3);
        let r = e.pose_r2();
        // Truth 0, 3, 6 mm above 50 mm (mean 3): total = 9 + 0 + 9 = 18 mm²; errors 0, 3,
        // 6 mm: residual 45 mm², centred residual 18 mm².
        assert!((r.r2 - (1.0 - 45.0 / 18.0)).abs() < 1e-9, "{r:?}");
        assert!(r.r2_centred.abs() < 1e-9, "{r:?}");
        // Mean error 3 mm on needle 0: bias² + centred² = (9 + 9 + 9 + 18) / 3 = 15 mm²,
        // the mean squared error 45 / 3; the truth's pose RMS sqrt(18 / 3).
        assert!((r.bias_rms_mm - 3.0).abs() < 1e-9, "{r:?}");
        assert!((r.centred_rms_mm - 6f64.sqrt()).abs() < 1e-9, "{r:?}");
        assert!((r.pose_rms_mm - 6f64.sqrt()).abs() < 1e-9, "{r:?}");
        // A biased LBS (every length 10 mm long) moves r2 but not r2_centred.
        let b = set(0.010).lbs_errors().pose_r2();
        assert!(b.r2 < r.r2);
        assert!((b.r2_centred - r.r2_centred).abs() < 1e-9);
        // No pose-deforming needle: NaN, not a division by zero.
        let flat = TestSet {
            frames: vec![TestFrame {
                theta: vec![],
                config: vec![],
                needles: vec![needle(0, 0.05, 0.05)],
            }],
        };
        assert!(flat.pose_deforming().is_empty());
        assert!(flat.lbs_errors().pose_r2().r2.is_nan());
    }
}
