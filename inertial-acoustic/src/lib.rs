//! # inertial-acoustic
//!
//! Wearable motion capture from gyroscopes, accelerometers and ultrasonic time of flight,
//! after D. Vlasic, *Dynamic Shape Capture* (MIT PhD thesis, 2010), Chapter 4 (and Vlasic et
//! al., *Practical Motion Capture in Everyday Surroundings*, SIGGRAPH 2007).
//!
//! Eighteen sensor boards on the garment each carry a 3-axis gyroscope, a 3-axis
//! accelerometer and a microphone; eight ultrasonic sources pulse in turn every 8 ms. The
//! microphone streams give distances (§4.3.1), the inertial stream rates and accelerations
//! (§4.3.2), and an extended Kalman filter over the skeleton's joint angles, rates and
//! accelerations fuses them into poses at 140 Hz (§4.4).
//!
//! ## Stages, in pipeline order
//!
//! | Stage | Module or file | Main items | Thesis |
//! |---|---|---|---|
//! | parameters | `params.rs` | [`UltrasoundParams`], [`FilterParams`], [`SensorSet`] | §4.2–4.4 |
//! | suit | `suit.rs` | [`Suit`], [`SensorBoard`], [`UltrasonicSource`] | §4.2.1 |
//! | ultrasonic processing | `ultrasound.rs` | [`PulseDetector`], [`calibrate_offsets`] | §4.3.1, §4.3.3 |
//! | inertial processing | `inertial.rs` | [`AxisCalibration`], [`DeltaCodec`] | §4.2.3, §4.3.2–4.3.3 |
//! | recording | `recording/` | [`Recording`] (the file format: [`Recording::write`], [`Recording::read`]) | what §4.3 hands §4.4 |
//! | initialisation | `initialise.rs` | [`initialise`], [`refine_headings`] (beyond §4.4.4) | §4.4.4 |
//! | noise from the data | [`tuning`] | [`tuning::estimate_board_noise`] (beyond §4.4.2) | §4.4.2 |
//! | pose estimation | `ekf.rs` | [`SkeletalEkf`], [`FrameObservations`] | §4.4.1–4.4.3 |
//! | local 3-DOF joints | `local_joints.rs` | (private; [`FilterParams::recentre_rad`]) | §4.4 (not in the thesis) |
//! | the method on a recording | [`pipeline`] | [`pipeline::run`], [`pipeline::PipelineParams`] | §4.4 |
//! | one board's orientation | `orientation.rs`, [`imu_log`] | [`OrientationEkf`], [`RestAlignment`], [`imu_log::run_orientation`] on real logs ([`imu_log::read_broad_hdf5`]) | §4.4 for a single rotation |
//! | evaluation | `evaluate.rs` | [`joint_orientation_errors_deg`], [`ErrorStats`] | §4.5 |
//!
//! The derivatives the accelerometer rows need (`∂(J̇θ̇)/∂θ`, `∂(J̇θ̇)/∂θ̇`) live in
//! `skin_core::skeleton` (`Skeleton::point_bias_acceleration_jacobians_into`).
//!
//! A user with a suit writes its decoded readings and detected distances as a [`Recording`]
//! (a JSON manifest and CSV streams, documented on [`Recording`]) and runs
//! [`pipeline::run`]: the rest-hold start, the per-board noise from a first pass, and the
//! filter over every frame, giving joint angles per frame and the NIS per sensor type. A
//! single IMU log (BROAD's, x-io's) runs through [`imu_log::run_orientation`].
//!
//! Validation equipment sits behind the cargo feature `validation`: the module `simulate`
//! (the suit simulated on studio motions down to its raw signals — inertial counts through
//! the link with noise, bias, scale and quantisation; 140 kHz microphone streams with
//! 10-cycle 40 kHz pulses, 1/r amplitude, directivity, body occlusion, a floor reflection and
//! noise — riding on the studio performer's deforming surface, and processed by this crate
//! into a [`Recording`]) and the module `score` (pipeline runs scored against the truth:
//! Table 4.1, the tuning grid).
//!
//! Errors are one [`Error`]; an error inside a loop over frames, boards or sources says where
//! ([`Error::At`] with a [`Context`]).
//!
//! ## Quick start
//!
//! A still subject in the rest pose: the filter, fed the readings a still suit gives
//! (gravity on the accelerometers, zero rates), stays at the rest pose.
//!
//! ```
//! use inertial_acoustic::{FilterParams, FrameObservations, InertialReading, SkeletalEkf, Suit};
//! use skin_core::math::DVec3;
//! use skin_core::skeleton::{human_skeleton, HumanParams};
//!
//! let skeleton = human_skeleton(&HumanParams::default())?;
//! let suit = Suit::vlasic(&skeleton)?;
//! let rest = skeleton.rest_pose();
//! let fk = skeleton.forward_kinematics(&rest)?;
//! let still: Vec<Option<InertialReading>> = suit
//!     .boards()
//!     .iter()
//!     .map(|b| {
//!         let up = fk.frame_rotation(&b.frame()).map(|q| q.inverse() * DVec3::Y * 9.80665);
//!         up.map(|a| Some(InertialReading::new(DVec3::ZERO, a)))
//!     })
//!     .collect::<Result<_, _>>()?;
//! let root = skeleton.joint_dofs(0).collect::<Vec<_>>();
//! let mut ekf = SkeletalEkf::new(skeleton, suit, &rest, FilterParams::default(), &[])?;
//! let obs = FrameObservations { inertial: still, distances: vec![] };
//! for _ in 0..140 {
//!     let report = ekf.step(&obs, None)?;
//!     assert!(!report.diverged);
//! }
//! assert!(ekf.theta().iter().skip(root.len()).all(|v| v.abs() < 1e-3));
//! # Ok::<(), inertial_acoustic::Error>(())
//! ```
#![warn(missing_docs)]
#![warn(unnameable_types, unreachable_pub)]

mod ekf;
mod error;
mod evaluate;
#[cfg(feature = "validation")]
mod garment;
pub mod imu_log;
mod inertial;
mod initialise;
mod local_joints;
mod orientation;
mod params;
pub mod pipeline;
mod recording;
#[cfg(feature = "validation")]
pub mod score;
#[cfg(feature = "validation")]
pub mod simulate;
mod start;
mod suit;
pub mod tuning;
mod ultrasound;

pub use ekf::{
    DistanceMeasurement, FrameObservations, InertialReading, InnovationStats, KnownDofs,
    SkeletalEkf, StepReport, INNOVATION_TYPES,
};
pub use error::{Context, Error, Result, ResultExt};
pub use evaluate::{joint_orientation_errors_deg, joint_swing_twist_errors_deg, ErrorStats};
pub use inertial::{AxisCalibration, DeltaCodec, Saturation};
pub use initialise::{
    initialise, refine_headings, HeadingRefinement, Initialisation, MIN_HEADING_RATE_RAD_S,
};
pub use orientation::{
    heading_inclination_rmse, HeadingInclinationRmse, OrientationEkf, OrientationStep,
    RestAlignment,
};
pub use params::{
    FilterParams, RobustLoss, SensorSet, UltrasoundParams, CARRIER_HZ, GRAVITY_M_S2,
    INERTIAL_RATE_HZ, MIC_RATE_HZ, PULSE_CYCLES, PULSE_INTERVAL_S, SAMPLES_PER_PULSE,
    SPEED_OF_SOUND_M_S,
};
pub use recording::Recording;
pub use suit::{BoardNoise, SensorBoard, Suit, UltrasonicSource};
pub use ultrasound::{
    calibrate_offsets, leave_one_out_errors_m, CalibrationShot, Detection, PulseDetector,
};
