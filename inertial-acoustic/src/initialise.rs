//! Initialisation (§4.4.4): while the subject holds the known rest pose, each board's mean
//! accelerometer reading must point along gravity (up) in its own axes, and each gyroscope's
//! readings must integrate to zero. The first tunes the boards' orientations (the smallest
//! rotation taking the measured gravity direction onto the predicted one — the fixed point of
//! the thesis's gradient descent), the second gives per-board gyroscope offsets (their mean
//! reading). The rotation about gravity stays as specified: gravity does not see it.

use crate::ekf::InertialReading;
use crate::suit::Suit;
use crate::{Context, Error, Result, ResultExt};
use serde::{Deserialize, Serialize};
use skin_core::math::{DQuat, DVec3};
use skin_core::skeleton::Skeleton;

/// What [`initialise`] found.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Initialisation {
    /// The suit with tuned board orientations.
    pub suit: Suit,
    /// Per-board gyroscope offsets, rad/s (subtract from readings).
    pub gyro_offsets: Vec<DVec3>,
    /// Per-board orientation correction applied, degrees.
    pub tilt_corrections_deg: Vec<f64>,
}

/// §4.4.4 from `rest_readings` (frames × boards, `None` for dropped readings) taken while
/// the subject holds `rest_pose`.
///
/// # Errors
/// [`Error::Empty`] without frames; [`Error::SizeMismatch`] for a frame without one entry per
/// board; [`Error::Empty`] (in [`Error::At`] naming the board) for a board without any finite
/// reading; as [`Skeleton::forward_kinematics`] for the pose.
pub fn initialise(
    skeleton: &Skeleton,
    suit: &Suit,
    rest_pose: &[f64],
    rest_readings: &[Vec<Option<InertialReading>>],
) -> Result<Initialisation> {
    if rest_readings.is_empty() {
        return Err(Error::Empty {
            what: "rest-pose readings",
        });
    }
    let nb = suit.boards().len();
    let mut acc = vec![DVec3::ZERO; nb];
    let mut gyro = vec![DVec3::ZERO; nb];
    let mut count = vec![0usize; nb];
    for (k, frame) in rest_readings.iter().enumerate() {
        skin_core::check::same_size("rest readings per board", nb, frame.len())
            .at(Context::Frame(k))?;
        for (b, r) in frame.iter().enumerate() {
            if let Some(r) = r.filter(|r| r.accel_m_s2.is_finite() && r.gyro_rad_s.is_finite()) {
                acc[b] += r.accel_m_s2;
                gyro[b] += r.gyro_rad_s;
                count[b] += 1;
            }
        }
    }
    let fk = skeleton.forward_kinematics(rest_pose)?;
    let mut out = suit.clone();
    let mut tilt = Vec::with_capacity(nb);
    for b in 0..nb {
        if count[b] == 0 {
            return Err(Error::Empty {
                what: "finite rest readings",
            })
            .at(Context::Sensor(b));
        }
        gyro[b] /= count[b] as f64;
        let measured = acc[b].normalize_or_zero();
        let board = &suit.boards()[b];
        let predicted = fk.frame_rotation(&board.frame())?.inverse() * DVec3::Y;
        if measured == DVec3::ZERO {
            tilt.push(0.0);
            continue;
        }
        // True axes = assumed · Δ with Δᵀ predicted = measured, i.e. Δ takes measured onto
        // predicted.
        let delta = DQuat::from_rotation_arc(measured, predicted);
        tilt.push(delta.angle_between(DQuat::IDENTITY).to_degrees());
        out = out
            .with_board_orientation(b, board.joint_from_sensor * delta)
            .at(Context::Sensor(b))?;
    }
    Ok(Initialisation {
        suit: out,
        gyro_offsets: gyro,
        tilt_corrections_deg: tilt,
    })
}
