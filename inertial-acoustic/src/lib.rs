#![doc = include_str!("../README.md")]
//!
//! ## Stages, in pipeline order
//!
//! | Stage | Thesis | Public items |
//! |---|---|---|
//! | parameters | §4.2–4.4 | [`UltrasoundParams`], [`FilterParams`], [`SensorSet`], constants ([`INERTIAL_RATE_HZ`], …) |
//! | suit | §4.2.1 | [`Suit`] ([`Suit::vlasic`]), [`SensorBoard`], [`UltrasonicSource`], [`BoardNoise`] |
//! | ultrasonic processing | §4.3.1, §4.3.3 | [`PulseDetector`], [`calibrate_offsets`], [`leave_one_out_errors_m`] |
//! | inertial processing | §4.2.3, §4.3.2–4.3.3 | [`DeltaCodec`], [`AxisCalibration`] |
//! | recording (the file format) | §4.3 → §4.4 | [`Recording`] ([`Recording::write`], [`Recording::read`]) |
//! | initialisation | §4.4.4 | [`initialise`], [`refine_headings`] (beyond §4.4.4) |
//! | noise from the data | §4.4.2 (beyond) | [`tuning::estimate_board_noise`], [`tuning::estimate_board_axis_noise`] |
//! | pose estimation | §4.4.1–4.4.3 | [`SkeletalEkf`], [`FrameObservations`], [`InnovationStats`] |
//! | the method on a recording | §4.4 | [`pipeline::run`], [`pipeline::PipelineParams`] |
//! | one board on a real IMU log | §4.4 for one rotation | [`OrientationEkf`], [`imu_log::read_broad_hdf5`], [`imu_log::run_orientation`] |
//! | evaluation | §4.5 | [`joint_orientation_errors_deg`], [`heading_inclination_rmse`], [`ErrorStats`] |
//!
//! The accelerometer rows' derivatives (`∂(J̇θ̇)/∂θ`, `∂(J̇θ̇)/∂θ̇`) are in
//! `skin_core::skeleton` (`Skeleton::point_bias_acceleration_jacobians_into`).
//!
//! With the feature `validation`: the module `simulate` (the suit simulated on studio motions
//! down to its raw signals and processed by this crate into a [`Recording`]) and the module
//! `score` (pipeline runs scored against the truth: Table 4.1, the tuning grid).
//!
//! Errors are one [`Error`]; an error inside a loop over frames, boards or sources says where
//! ([`Error::At`] with a [`Context`]).
#![cfg_attr(docsrs, feature(doc_cfg))]
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
#[cfg_attr(docsrs, doc(cfg(feature = "validation")))]
pub mod score;
#[cfg(feature = "validation")]
#[cfg_attr(docsrs, doc(cfg(feature = "validation")))]
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
