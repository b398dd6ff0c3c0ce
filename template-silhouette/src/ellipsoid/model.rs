//! The articulated ellipsoid model (Fua et al. §4.2, Eq. 3): the bones that carry
//! ellipsoids, the unknowns of a state (pose, length scales, half-widths, half-lengths), the
//! world ellipsoids of a state, and the scaled residual of Eq. 9 with its analytic
//! derivatives (the module docs of `ellipsoid.rs` derive them).

use skin_core::math::{DAffine3, DVec3};
use skin_core::skeleton::Skeleton;
use skin_core::{check, Context};

use crate::error::{Error, Result, ResultExt};
use crate::silhouette_constraints::ContourRay;

/// One bone of the ellipsoid model: the segment from joint `parent`'s origin to joint
/// `child`'s origin, or to `parent`'s end site (a hand, a foot, the top of the head), carried
/// by `parent`'s frame (§4.2.2, Figure 7b).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EllipsoidBone {
    /// The joint whose frame carries the ellipsoid.
    pub parent: usize,
    /// The joint at the far end of the bone (its offset is the bone); `None` for the segment
    /// to `parent`'s end site (its length scale moves no joint).
    pub child: Option<usize>,
}

impl EllipsoidBone {
    /// The joint that names the bone in errors: its child, or its parent for an end-site
    /// segment.
    pub fn joint(&self) -> usize {
        self.child.unwrap_or(self.parent)
    }
}

/// The articulated ellipsoid model of §4.2: a default skeleton (the "standard body model"
/// the fit starts from) and the bones that carry ellipsoids.
#[derive(Debug, Clone)]
pub struct EllipsoidModel {
    pub(super) skeleton: Skeleton,
    pub(super) bones: Vec<EllipsoidBone>,
    /// Default bone length `L_b`, metres.
    pub(super) lengths: Vec<f64>,
    /// Unit bone direction in the parent frame.
    pub(super) axes: Vec<DVec3>,
    /// For each joint, the bones whose child joint lies on the root → joint path.
    pub(super) chain_bones: Vec<Vec<usize>>,
}

/// The unknowns of §4.2: pose θ, a length scale per bone, a half-width per bone.
#[derive(Debug, Clone, PartialEq)]
pub struct EllipsoidState {
    /// Pose θ of the skeleton (radians, metres).
    pub theta: Vec<f64>,
    /// Length scale `s_b` per bone (1 = the default skeleton).
    pub length_scale: Vec<f64>,
    /// Half-width `part_w` per bone, metres.
    pub half_width: Vec<f64>,
    /// Axial radius of each ellipsoid, metres (Eq. 3 ties it to half the bone length; here it
    /// is its own unknown, see the module docs).
    pub half_length: Vec<f64>,
}

/// One ellipsoid in the world, for drawing and scoring.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ellipsoid {
    /// Centre (the bone's midpoint), world metres.
    pub centre: DVec3,
    /// Unit axis along the bone, world.
    pub axis: DVec3,
    /// Axial radius (half-length) of the ellipsoid, metres.
    pub half_length: f64,
    /// Half the bone's length `bone_l`, metres (the centre's distance from the joint).
    pub half_bone: f64,
    /// Half-width `part_w`, metres.
    pub half_width: f64,
}

/// Evaluation of one attractor against one ellipsoid.
pub(super) struct Eval {
    pub(super) e: f64,
    /// ∂e/∂u in world axes (R_p g).
    pub(super) grad_world: DVec3,
    pub(super) d_own_scale: f64,
    pub(super) d_width: f64,
    pub(super) d_half_length: f64,
}

impl EllipsoidModel {
    /// A model over `bones` of `skeleton` (the default proportions).
    ///
    /// # Errors
    /// [`Error::Empty`] without bones; index errors; [`Error::InvalidParam`] when `child` is
    /// not a child of `parent`, or `parent` has no end site for a `None` child;
    /// [`skin_core::Error::Degenerate`] (inside [`Error::Core`]) for a zero-length bone.
    pub fn new(skeleton: Skeleton, bones: Vec<EllipsoidBone>) -> Result<Self> {
        if bones.is_empty() {
            return Err(Error::Empty {
                what: "ellipsoid bones (give at least one, or build the model with \
                       EllipsoidModel::limbs)",
            });
        }
        let n = skeleton.joint_count();
        let mut lengths = Vec::with_capacity(bones.len());
        let mut axes = Vec::with_capacity(bones.len());
        for (b, bone) in bones.iter().enumerate() {
            check::index("bone parent joint", bone.parent, n).at(Context::Joint(b))?;
            let (offset, name) = match bone.child {
                Some(c) => {
                    check::index("bone child joint", c, n).at(Context::Joint(b))?;
                    let joint = &skeleton.joints()[c];
                    if joint.parent != Some(bone.parent) {
                        return Err(Error::InvalidParam {
                            name: "bones",
                            reason: format!(
                                "joint {c} is not a child of joint {}; give a child of the \
                                 bone's parent, or None for the parent's end site",
                                bone.parent
                            ),
                        });
                    }
                    (joint.offset, joint.name.clone())
                }
                None => {
                    let joint = &skeleton.joints()[bone.parent];
                    let Some(end) = joint.end_site else {
                        return Err(Error::InvalidParam {
                            name: "bones",
                            reason: format!(
                                "joint {} has no end site; give the bone a child joint",
                                bone.parent
                            ),
                        });
                    };
                    (end, format!("{} end site", joint.name))
                }
            };
            let len = offset.length();
            if len < 1e-6 {
                return Err(Error::Core(skin_core::Error::Degenerate {
                    what: format!("zero-length bone to {name}; leave it out of the model"),
                }));
            }
            lengths.push(len);
            axes.push(offset / len);
        }
        let mut chain_bones = vec![Vec::new(); n];
        for (j, chain) in chain_bones.iter_mut().enumerate() {
            let mut k = Some(j);
            while let Some(jj) = k {
                if let Some(b) = bones.iter().position(|bone| bone.child == Some(jj)) {
                    chain.push(b);
                }
                k = skeleton.joints()[jj].parent;
            }
        }
        Ok(EllipsoidModel {
            skeleton,
            bones,
            lengths,
            axes,
            chain_bones,
        })
    }

    /// The limbs of a skeleton: every bone whose parent joint articulates (has DOFs) and has
    /// exactly one child, and whose length is at least `min_length_m` (so the bone, and its
    /// ellipsoid, are unambiguous; a fixed link such as a clavicle carries no body part).
    ///
    /// # Errors
    /// As [`EllipsoidModel::new`]; `min_length_m` must be positive.
    pub fn limbs(skeleton: Skeleton, min_length_m: f64) -> Result<Self> {
        check::positive("min_length_m", min_length_m)?;
        let bones = (0..skeleton.joint_count())
            .filter_map(|c| {
                let p = skeleton.joints()[c].parent?;
                let single =
                    skeleton.children(p).count() == 1 && !skeleton.joints()[p].dofs.is_empty();
                (single && skeleton.joints()[c].offset.length() >= min_length_m).then_some(
                    EllipsoidBone {
                        parent: p,
                        child: Some(c),
                    },
                )
            })
            .collect();
        Self::new(skeleton, bones)
    }

    /// The limbs ([`EllipsoidModel::limbs`]) and the end-site segments at least
    /// `min_length_m` long (hands, feet, the head of the human skeleton): everything a
    /// silhouette or a visual hull shows of the extremities has an ellipsoid to go to.
    ///
    /// # Errors
    /// As [`EllipsoidModel::limbs`].
    pub fn with_end_sites(skeleton: Skeleton, min_length_m: f64) -> Result<Self> {
        let limbs = Self::limbs(skeleton, min_length_m)?;
        let mut bones = limbs.bones;
        let skeleton = limbs.skeleton;
        bones.extend(skeleton.joints().iter().enumerate().filter_map(|(p, j)| {
            j.end_site
                .is_some_and(|e| e.length() >= min_length_m)
                .then_some(EllipsoidBone {
                    parent: p,
                    child: None,
                })
        }));
        Self::new(skeleton, bones)
    }

    /// The bones, in state order.
    pub fn bones(&self) -> &[EllipsoidBone] {
        &self.bones
    }

    /// The default skeleton.
    pub fn skeleton(&self) -> &Skeleton {
        &self.skeleton
    }

    /// Default bone lengths `L_b`, metres.
    pub fn default_lengths(&self) -> &[f64] {
        &self.lengths
    }

    /// Bone lengths of a state, `s_b L_b`, metres.
    pub fn bone_lengths(&self, state: &EllipsoidState) -> Vec<f64> {
        self.lengths
            .iter()
            .zip(&state.length_scale)
            .map(|(l, s)| l * s)
            .collect()
    }

    /// A starting state: pose `theta`, default lengths, every half-width `half_width_m`.
    ///
    /// # Errors
    /// Wrong θ length or non-finite values; a non-positive width.
    pub fn initial_state(&self, theta: &[f64], half_width_m: f64) -> Result<EllipsoidState> {
        check::positive("half_width_m", half_width_m)?;
        let state = EllipsoidState {
            theta: theta.to_vec(),
            length_scale: vec![1.0; self.bones.len()],
            half_width: vec![half_width_m; self.bones.len()],
            half_length: self.lengths.iter().map(|l| 0.5 * l).collect(),
        };
        self.check_state(&state)?;
        Ok(state)
    }

    pub(super) fn check_state(&self, state: &EllipsoidState) -> Result<()> {
        check::same_size("theta", self.skeleton.dof_count(), state.theta.len())?;
        check::same_size("length_scale", self.bones.len(), state.length_scale.len())?;
        check::same_size("half_width", self.bones.len(), state.half_width.len())?;
        check::same_size("half_length", self.bones.len(), state.half_length.len())?;
        for &h in &state.half_length {
            check::positive("half_length", h)?;
        }
        check::all_finite("theta", &state.theta)?;
        for (&s, &w) in state.length_scale.iter().zip(&state.half_width) {
            check::positive("length_scale", s)?;
            check::positive("half_width", w)?;
        }
        Ok(())
    }

    /// The skeleton with every bone's offset scaled by its length scale.
    ///
    /// # Errors
    /// A state of the wrong size.
    pub fn scaled_skeleton(&self, state: &EllipsoidState) -> Result<Skeleton> {
        self.check_state(state)?;
        let mut joints = self.skeleton.joints().to_vec();
        for (bone, &s) in self.bones.iter().zip(&state.length_scale) {
            if let Some(c) = bone.child {
                joints[c].offset *= s;
            }
        }
        Ok(Skeleton::new(joints)?)
    }

    /// The world ellipsoids of a state (Eq. 3).
    ///
    /// # Errors
    /// A state of the wrong size or non-finite.
    pub fn ellipsoids(&self, state: &EllipsoidState) -> Result<Vec<Ellipsoid>> {
        let sk = self.scaled_skeleton(state)?;
        let fk = sk.forward_kinematics(&state.theta)?;
        let frames = fk.world_from_joint();
        Ok(self
            .bones
            .iter()
            .enumerate()
            .map(|(b, bone)| {
                let f = frames[bone.parent];
                let l = 0.5 * self.lengths[b] * state.length_scale[b];
                let axis = f.matrix3 * self.axes[b];
                Ellipsoid {
                    centre: f.translation + axis * l,
                    axis,
                    half_length: state.half_length[b],
                    half_bone: l,
                    half_width: state.half_width[b],
                }
            })
            .collect())
    }

    /// Residual of Eq. 9 (scaled, see the module docs) of a world point against bone `b`.
    pub(super) fn eval(
        &self,
        frames: &[DAffine3],
        state: &EllipsoidState,
        b: usize,
        x: DVec3,
    ) -> Eval {
        let f = frames[self.bones[b].parent];
        let u = f.matrix3.transpose() * (x - f.translation);
        let a = self.axes[b];
        let l = 0.5 * self.lengths[b] * state.length_scale[b];
        let w = state.half_width[b];
        let h = state.half_length[b];
        let z = u.dot(a);
        let radial = u - a * z;
        let rho2 = radial.length_squared();
        let zl = z - l;
        let big_f = rho2 / (w * w) + zl * zl / (h * h) - 1.0;
        let g = (radial / (w * w) + a * (zl / (h * h))) * w;
        let d_f_dl = -2.0 * zl / (h * h);
        Eval {
            e: 0.5 * w * big_f,
            grad_world: f.matrix3 * g,
            d_own_scale: 0.5 * w * d_f_dl * 0.5 * self.lengths[b],
            d_width: 0.5 * big_f - rho2 / (w * w),
            d_half_length: -w * zl * zl / (h * h * h),
        }
    }

    /// The point of a ray with the least `F` for bone `b` (the tangent point of §5.3).
    pub(super) fn ray_point(
        &self,
        frames: &[DAffine3],
        state: &EllipsoidState,
        b: usize,
        ray: &ContourRay,
    ) -> DVec3 {
        let f = frames[self.bones[b].parent];
        let rt = f.matrix3.transpose();
        let a = self.axes[b];
        let l = 0.5 * self.lengths[b] * state.length_scale[b];
        let w = state.half_width[b];
        let h = state.half_length[b];
        let norm = |v: DVec3, shift: f64| {
            let z = v.dot(a);
            let radial = v - a * z;
            radial / w + a * ((z - shift) / h)
        };
        let q0 = norm(rt * (ray.origin - f.translation), l);
        let qd = norm(rt * ray.direction, 0.0);
        let t = (-q0.dot(qd) / qd.length_squared().max(1e-300)).max(0.0);
        ray.origin + ray.direction * t
    }
}

/// The half-width of Eq. 3 that best fits `points` around bone `b` of `state` (its length
/// and pose fixed): the 1-D least-squares minimiser of `Σ e²` (golden-section search over
/// 1 mm … 1 m). Validation uses it on the true limb's vertices as the reference width.
///
/// # Errors
/// A bad bone index or state; [`Error::Empty`] without points.
pub fn fit_half_width(
    model: &EllipsoidModel,
    state: &EllipsoidState,
    b: usize,
    points: &[DVec3],
) -> Result<f64> {
    check::index("bone", b, model.bones.len())?;
    if points.is_empty() {
        return Err(Error::Empty {
            what: "limb points (give at least one point around the bone)",
        });
    }
    let sk = model.scaled_skeleton(state)?;
    let fk = sk.forward_kinematics(&state.theta)?;
    let frames = fk.world_from_joint();
    let mut s = state.clone();
    let mut cost = |w: f64| {
        s.half_width[b] = w;
        points
            .iter()
            .map(|&x| model.eval(frames, &s, b, x).e.powi(2))
            .sum::<f64>()
    };
    let (mut lo, mut hi) = (0.001_f64, 1.0_f64);
    let phi = 0.5 * (5f64.sqrt() - 1.0);
    for _ in 0..80 {
        let m1 = hi - phi * (hi - lo);
        let m2 = lo + phi * (hi - lo);
        if cost(m1) < cost(m2) {
            hi = m2;
        } else {
            lo = m1;
        }
    }
    Ok(0.5 * (lo + hi))
}
