//! Ground truth for validating the needle model on the synthetic studio (Sand, McMillan and
//! Popović 2003 §6, "Results": reconstruction error against a known surface).
//!
//! The studio's performer gives the TRUE posed surface (linear-blend skinning plus the
//! non-skinning bulge and flap) and the LBS-only surface. A needle's true length is the
//! distance from its origin along its direction to where the ray leaves the true mesh; the
//! LBS baseline's length is the same ray against the LBS-skinned rest shape, which is what a
//! skinning-only model predicts. [`TestSet`] precomputes both for a sequence of test poses so
//! that any number of models can be scored cheaply with [`TestSet::errors`].

use glam::DVec3;
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
            let cfg = prim.config.point(&fk)?;
            frame.config.push(cfg.iter().map(|&x| x as f32).collect());
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
                out.push(n, (l as f64 - n.true_m).abs() * 1e3);
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
        mut surface: impl FnMut(&[f64]) -> Result<TriMesh>,
    ) -> Result<Errors> {
        let mut out = Errors::default();
        for f in &self.frames {
            let query = MeshQuery::new(&surface(&f.theta)?)?;
            let fk = skeleton.forward_kinematics(&f.theta)?;
            for n in &f.needles {
                let prim =
                    body.primitives
                        .get(n.primitive as usize)
                        .ok_or(Error::SizeMismatch {
                            what: "body primitives vs test set",
                            expected: n.primitive as usize + 1,
                            got: body.primitives.len(),
                        })?;
                if n.needle as usize >= prim.needle_count() {
                    return Err(Error::SizeMismatch {
                        what: "primitive needles vs test set",
                        expected: n.needle as usize + 1,
                        got: prim.needle_count(),
                    });
                }
                let t = fk.world_from_joint()[prim.carrier];
                let (o, d) = prim.needle_world(&t, n.needle as usize);
                let l = exit_length(&query, o, d, 2.0 * prim.max_length_m)?.unwrap_or(0.0);
                out.push(n, (l - n.true_m).abs() * 1e3);
            }
        }
        Ok(out)
    }

    /// Errors of the LBS baseline (the skinned rest shape).
    pub fn lbs_errors(&self) -> Errors {
        let mut out = Errors::default();
        for n in self.frames.iter().flat_map(|f| &f.needles) {
            out.push(n, (n.lbs_m - n.true_m).abs() * 1e3);
        }
        out
    }
}

impl Errors {
    fn push(&mut self, n: &NeedleTruth, e_mm: f64) {
        self.all_mm.push(e_mm);
        if n.near_joint {
            self.near_joints_mm.push(e_mm);
        }
        if (n.true_m - n.lbs_m).abs() > DEFORMING_M {
            self.deforming_mm.push(e_mm);
        }
    }
}
