//! Initialisation (§4.4.4): while the subject holds the known rest pose, each board's mean
//! accelerometer reading must point along gravity (up) in its own axes, and each gyroscope's
//! readings must integrate to zero. The first tunes the boards' orientations (the smallest
//! rotation taking the measured gravity direction onto the predicted one — the fixed point of
//! the thesis's gradient descent), the second gives per-board gyroscope offsets (their mean
//! reading). The rotation about gravity stays as specified: gravity does not see it.

use crate::ekf::{InertialReading, InnovationStats};
use crate::params::FilterParams;
use crate::suit::{BoardNoise, Suit};
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

/// Per-board measurement noise from a first filter pass's innovation statistics — a step
/// beyond §4.4.2, which gives one σ per sensor type (not in the thesis): each board's
/// gyroscope and accelerometer σ is the global σ of `params` scaled so that the board's mean
/// NIS in that pass would be 1, `σ_b = σ · √max(1, NIS_b)`, bounded below by the global σ
/// (a board the pass found quieter than the sensor's rating keeps the rating). A board with
/// no counted update of a type keeps the global σ for it.
///
/// What it captures: a board whose readings the filter's models cannot explain to the
/// rated noise — a board over blended skin that turns against its bone (the garment's neck,
/// sacrum, lower back), a misplaced board — is trusted less, so the others carry its bone.
/// `s = H P Hᵀ + r` includes the state's spread, so the NIS after the change is not
/// exactly 1 (a first-order rule, not a fixed point).
///
/// # Errors
/// [`Error::SizeMismatch`] unless the gyroscope and accelerometer statistics have one entry
/// per board; as [`FilterParams::validate`].
pub fn board_noise_from_innovations(
    stats: &[Vec<InnovationStats>; 3],
    boards: usize,
    params: &FilterParams,
) -> Result<Vec<BoardNoise>> {
    params.validate()?;
    skin_core::check::same_size("gyroscope statistics", boards, stats[0].len())?;
    skin_core::check::same_size("accelerometer statistics", boards, stats[1].len())?;
    Ok((0..boards)
        .map(|b| {
            BoardNoise::new(
                params.gyroscope_sigma * nis_scale(&stats[0][b]),
                params.accelerometer_sigma * nis_scale(&stats[1][b]),
            )
        })
        .collect())
}

/// `√max(1, NIS)` of one channel; 1 without a counted update.
fn nis_scale(st: &InnovationStats) -> f64 {
    if st.count == 0 || !st.mean_nis().is_finite() {
        1.0
    } else {
        st.mean_nis().max(1.0).sqrt()
    }
}

/// Per-board, per-axis measurement noise from a first pass's innovation statistics split by
/// sensor axis ([`crate::SkeletalEkf::axis_innovation_stats`]; not in
/// the thesis): the rule of [`board_noise_from_innovations`] applied to each of a board's
/// three gyroscope and three accelerometer axes, `σ_{b,k} = σ · √max(1, NIS_{b,k})`. The
/// board's own σ (`gyroscope_sigma`, `accelerometer_sigma`) is the per-board rule on the
/// axes pooled, so the result equals [`board_noise_from_innovations`]'s when the axes agree.
///
/// Why per axis: a board over blended skin (the garment's neck, sacrum, lower back) turns
/// against its bone mostly about some axes; one σ per board down-weights its well-modelled
/// axes with the skin-twisted ones. Per axis, only the axes the model cannot explain are
/// trusted less.
///
/// # Errors
/// [`Error::SizeMismatch`] unless both sensor types have one entry per board; as
/// [`FilterParams::validate`].
pub fn board_axis_noise_from_innovations(
    stats: &[Vec<[InnovationStats; 3]>; 2],
    boards: usize,
    params: &FilterParams,
) -> Result<Vec<BoardNoise>> {
    params.validate()?;
    skin_core::check::same_size("gyroscope axis statistics", boards, stats[0].len())?;
    skin_core::check::same_size("accelerometer axis statistics", boards, stats[1].len())?;
    Ok((0..boards)
        .map(|b| {
            let (g, a) = (&stats[0][b], &stats[1][b]);
            BoardNoise::new(
                params.gyroscope_sigma * nis_scale(&InnovationStats::pooled(g)),
                params.accelerometer_sigma * nis_scale(&InnovationStats::pooled(a)),
            )
            .with_axes(
                g.map(|st| params.gyroscope_sigma * nis_scale(&st)),
                a.map(|st| params.accelerometer_sigma * nis_scale(&st)),
            )
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stats(count: usize, nis: f64) -> InnovationStats {
        InnovationStats {
            count,
            sum_nis: nis * count as f64,
            ..InnovationStats::default()
        }
    }

    /// σ_b = σ √NIS_b above the rating, the rating below it and without updates.
    #[test]
    fn board_noise_scales_to_unit_nis_bounded_by_the_global_sigma() {
        let p = FilterParams::default().with_measurement_sigmas(2.0, 0.01, 0.0025);
        let all = [
            vec![stats(30, 25.0), stats(30, 0.2), stats(0, 0.0)],
            vec![stats(30, 0.05), stats(30, 4.0), stats(30, f64::NAN)],
            vec![InnovationStats::default(); 3],
        ];
        let n = board_noise_from_innovations(&all, 3, &p).unwrap();
        let close = |a: f64, b: f64| (a - b).abs() < 1e-12;
        assert!(close(n[0].gyroscope_sigma, 0.05), "{n:?}");
        assert!(close(n[1].gyroscope_sigma, 0.01) && close(n[2].gyroscope_sigma, 0.01));
        assert!(close(n[0].accelerometer_sigma, 2.0) && close(n[1].accelerometer_sigma, 4.0));
        assert!(close(n[2].accelerometer_sigma, 2.0));
        assert!(board_noise_from_innovations(&all, 4, &p).is_err());
        let bad = p.with_measurement_sigmas(-1.0, 0.01, 0.0025);
        assert!(board_noise_from_innovations(&all, 3, &bad).is_err());
    }

    /// Per axis: each axis scaled by its own NIS, the board's σ by the pooled NIS; equal
    /// axes give the per-board rule.
    #[test]
    fn axis_noise_scales_each_axis_by_its_own_nis() {
        let p = FilterParams::default().with_measurement_sigmas(2.0, 0.01, 0.0025);
        let all = [
            vec![
                [stats(30, 100.0), stats(30, 0.5), stats(30, 4.0)],
                [stats(30, 9.0); 3],
            ],
            vec![
                [stats(30, 0.05); 3],
                [stats(0, 0.0), stats(30, 4.0), stats(30, f64::NAN)],
            ],
        ];
        let n = board_axis_noise_from_innovations(&all, 2, &p).unwrap();
        let close = |a: f64, b: f64| (a - b).abs() < 1e-12;
        let g0 = n[0].gyroscope_axes();
        assert!(
            close(g0[0], 0.1) && close(g0[1], 0.01) && close(g0[2], 0.02),
            "{n:?}"
        );
        // Pooled NIS (100 + 0.5 + 4) / 3 for the board's own σ.
        assert!(close(n[0].gyroscope_sigma, 0.01 * (104.5f64 / 3.0).sqrt()));
        // The worst axis on all three.
        let w = n[0].worst_axis();
        assert!(w.gyroscope_axes().iter().all(|&s| close(s, 0.1)) && close(w.gyroscope_sigma, 0.1));
        assert!(close(n[1].worst_axis().accelerometer_sigma, 4.0));
        assert!(n[0].accelerometer_axes().iter().all(|&s| close(s, 2.0)));
        let flat = board_noise_from_innovations(
            &[
                vec![stats(30, 104.5 / 3.0), stats(90, 9.0)],
                vec![stats(90, 0.05), stats(60, f64::NAN)],
                vec![InnovationStats::default(); 2],
            ],
            2,
            &p,
        )
        .unwrap();
        assert!(close(n[1].gyroscope_sigma, flat[1].gyroscope_sigma));
        assert!(n[1].gyroscope_axes().iter().all(|&s| close(s, 0.03)));
        let a1 = n[1].accelerometer_axes();
        assert!(
            close(a1[0], 2.0) && close(a1[1], 4.0) && close(a1[2], 2.0),
            "{n:?}"
        );
        assert!(board_axis_noise_from_innovations(&all, 3, &p).is_err());
    }
}
