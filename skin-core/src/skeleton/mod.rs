//! Articulated skeletons: joint tree with per-joint DOFs and limits, forward kinematics,
//! attached points and frames, analytic Jacobians and `J̇θ̇`, a human model, BVH import and
//! export, and motion resampling.
//!
//! Implements the kinematic model of Vlasic thesis §4.4.1–4.4.2 (pose vector θ, `p = F(θ)`,
//! `v = J θ̇`, `a = J θ̈ + J̇ θ̇` for accelerometers, Eq. 4.2, and `ω = J_ω θ̇` for gyroscopes,
//! Eq. 4.3), shared by the skeletal EKF, the silhouette pose tracker (Vlasic §2.3) and the
//! synthetic studio; markers on bones are Fua et al.'s attached points.
//!
//! * [`Skeleton`]: [`Joint`]s (parent, rest offset, [`Dof`]s, optional end site). θ is a
//!   `&[f64]` (pass `DVector::as_slice()`), joint by joint in DOF order; radians and metres.
//! * [`Skeleton::forward_kinematics_into`] → [`ForwardKinematics`]: all `world_from_joint`
//!   frames plus world DOF axes/origins in one sweep; [`AttachedPoint`], [`AttachedFrame`].
//! * [`Skeleton::point_jacobians_into`], [`Skeleton::frame_jacobians_into`] (world or
//!   [`AngularFrame::Local`] axes), [`Skeleton::rates_into`] → [`JointRates`],
//!   [`Skeleton::point_bias_accelerations_into`] (`J̇θ̇`),
//!   [`Skeleton::frame_bias_accelerations_into`] (`J̇_ω θ̇`), and the full `J̇` matrices;
//!   their pose derivatives for EKF observation Jacobians:
//!   [`Skeleton::point_bias_acceleration_jacobians_into`] (`∂(J̇θ̇)/∂θ`, `∂(J̇θ̇)/∂θ̇`),
//!   [`Skeleton::point_jacobian_product_jacobians_into`] (`∂(Jy)/∂θ`),
//!   [`Skeleton::frame_angular_velocity_jacobians_into`] (`∂(J_ω θ̇)/∂θ`).
//!   All `_into` forms write preallocated buffers and do not allocate.
//! * [`human_skeleton`]: 42 DOFs, 19 joints, 1.75 m.
//! * [`parse_bvh`], [`read_bvh`], [`write_bvh`], [`to_bvh_string`]: BVH files ↔
//!   ([`Skeleton`], [`Motion`]); [`Motion::resample`] changes the frame rate.
//!
//! # Example
//! ```
//! use skin_core::math::DVec3;
//! use skin_core::skeleton::{human_skeleton, AttachedPoint, HumanParams};
//! let s = human_skeleton(&HumanParams::default())?;
//! let mut theta = s.rest_pose();
//! theta[s.dof_index("l_elbow.flexion").unwrap()] = 1.2;
//! let fk = s.forward_kinematics(&theta)?;
//! let wrist = AttachedPoint { joint: s.joint_index("l_wrist").unwrap(), offset: DVec3::ZERO };
//! let j = s.point_jacobians(&fk, &[wrist])?; // 3 × 42
//! assert_eq!(j.shape(), (3, 42));
//! # Ok::<(), skin_core::Error>(())
//! ```

mod bias_jacobian;
mod bvh;
mod bvh_export;
mod dof;
mod fk;
mod human;
mod jacobian;
mod model;
mod motion;

pub use bvh::{parse_bvh, read_bvh, Bvh, BvhParams, CMU_METRES_PER_UNIT};
pub use bvh_export::{to_bvh_string, write_bvh};
pub use dof::{Dof, DofKind, DofLimits};
pub use fk::{AttachedFrame, AttachedPoint, ForwardKinematics};
pub use human::{human_skeleton, HumanParams};
pub use jacobian::{AngularFrame, JointRates};
pub use model::{Joint, Skeleton};
pub use motion::Motion;
