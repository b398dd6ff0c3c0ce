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

/// Smallest RMS of the predicted rate perpendicular to a board's up axis for which
/// [`refine_headings`] turns the board, rad/s (0.2: twenty times the dithered gyroscope's
/// 0.01 rad/s noise; the supplied root of the exercise motion turns slower and its
/// fit was decided by noise — 176° on one seed).
pub const MIN_HEADING_RATE_RAD_S: f64 = 0.2;

/// What [`refine_headings`] found.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HeadingRefinement {
    /// The suit with each board turned about its rest-pose up axis.
    pub suit: Suit,
    /// Per board: the turn applied about its up axis, degrees (positive counter-clockwise
    /// seen from above, in the board's axes).
    pub headings_deg: Vec<f64>,
    /// Per board: frames whose readings entered the fit (0 where the board kept its heading:
    /// no readings, or too slow, see [`MIN_HEADING_RATE_RAD_S`]).
    pub frames_used: Vec<usize>,
}

/// Per-board heading about gravity — an initialisation step beyond §4.4.4 (not in the
/// thesis): the rest-pose gravity alignment cannot see a board's rotation about up, so after
/// a first filter pass over the start of the motion, each board is turned about its rest-pose
/// up axis `u` (in its own axes) by the angle ψ that best maps the angular rates predicted
/// from the estimated poses onto the measured ones (gyroscope minus offset): with `m` the
/// measured and `p` the predicted rate in the board's assumed axes, ψ = atan2(Σ (u × m)·p,
/// Σ m⊥·p⊥), the closed-form least-squares turn about `u`. The predicted rates are central
/// differences of the boards' orientations along `poses` (one pose per frame, `dt` apart).
///
/// What it can see: a board on a bone whose motion the other sensors (or the supplied root)
/// pin down; a board that alone decides its bone's estimate is absorbed into that estimate
/// and gets ψ ≈ 0. Where a bone carries two boards (the chest) each is turned onto their
/// common estimate.
///
/// # Errors
/// [`Error::Empty`] for fewer than three poses; [`Error::SizeMismatch`] for readings,
/// offsets or poses of the wrong size; [`Error::InvalidParam`] for a non-positive or
/// non-finite `dt`; a non-finite pose value is an error naming its frame; as
/// [`Skeleton::forward_kinematics`]. Non-finite gyroscope readings are skipped.
pub fn refine_headings(
    skeleton: &Skeleton,
    suit: &Suit,
    rest_pose: &[f64],
    poses: &[Vec<f64>],
    readings: &[Vec<Option<InertialReading>>],
    gyro_offsets: &[DVec3],
    dt: f64,
) -> Result<HeadingRefinement> {
    if poses.len() < 3 {
        return Err(Error::Empty {
            what: "poses for the heading fit (at least 3)",
        });
    }
    if !(dt.is_finite() && dt > 0.0) {
        return Err(Error::InvalidParam {
            name: "dt",
            reason: format!("must be positive and finite, got {dt}"),
        });
    }
    let nb = suit.boards().len();
    skin_core::check::same_size("readings per pose", poses.len(), readings.len())?;
    skin_core::check::same_size("gyro offsets", nb, gyro_offsets.len())?;
    let frames: Vec<_> = suit.boards().iter().map(|b| b.frame()).collect();
    let fk_rest = skeleton.forward_kinematics(rest_pose)?;
    let mut up = Vec::with_capacity(nb);
    for f in &frames {
        up.push(fk_rest.frame_rotation(f)?.inverse() * DVec3::Y);
    }
    let mut rotations = Vec::with_capacity(poses.len());
    for (k, pose) in poses.iter().enumerate() {
        skin_core::check::all_finite("pose", pose).at(Context::Frame(k))?;
        let fk = skeleton.forward_kinematics(pose).at(Context::Frame(k))?;
        let r = frames
            .iter()
            .map(|f| fk.frame_rotation(f).map_err(Error::from))
            .collect::<Result<Vec<_>>>()?;
        rotations.push(r);
    }
    let (mut sin_sum, mut cos_sum) = (vec![0.0; nb], vec![0.0; nb]);
    let mut energy = vec![0.0; nb];
    let mut used = vec![0usize; nb];
    for k in 1..poses.len() - 1 {
        skin_core::check::same_size("readings per board", nb, readings[k].len())
            .at(Context::Frame(k))?;
        for b in 0..nb {
            let Some(r) = readings[k][b].filter(|r| r.gyro_rad_s.is_finite()) else {
                continue;
            };
            let mut d = rotations[k + 1][b] * rotations[k - 1][b].inverse();
            if d.w < 0.0 {
                d = -d;
            }
            let world = d.to_scaled_axis() / (2.0 * dt);
            let p = rotations[k][b].inverse() * world;
            let m = r.gyro_rad_s - gyro_offsets[b];
            let u = up[b];
            let (mp, pp) = (m - u * m.dot(u), p - u * p.dot(u));
            sin_sum[b] += u.cross(m).dot(p);
            cos_sum[b] += mp.dot(pp);
            energy[b] += pp.length_squared();
            used[b] += 1;
        }
    }
    let mut out = suit.clone();
    let mut headings = Vec::with_capacity(nb);
    for b in 0..nb {
        // A board whose predicted rate about axes other than up stays below
        // `MIN_HEADING_RATE_RAD_S` (RMS) keeps its heading: noise would decide the fit.
        let rms = (energy[b] / used[b].max(1) as f64).sqrt();
        let psi = if used[b] == 0 || rms < MIN_HEADING_RATE_RAD_S {
            used[b] = 0;
            0.0
        } else {
            f64::atan2(sin_sum[b], cos_sum[b])
        };
        headings.push(psi.to_degrees());
        let board = &suit.boards()[b];
        out = out
            .with_board_orientation(
                b,
                board.joint_from_sensor * DQuat::from_axis_angle(up[b], psi),
            )
            .at(Context::Sensor(b))?;
    }
    Ok(HeadingRefinement {
        suit: out,
        headings_deg: headings,
        frames_used: used,
    })
}
