//! Measurement noise set from the data (beyond §4.4.2, which hand-tunes one σ per sensor
//! type): a first filter pass over the start of a recording, then each board's gyroscope and
//! accelerometer σ — or each of its axes' — scaled by the normalised innovation squared
//! (NIS) that pass saw. [`crate::pipeline::run`] does this by default
//! ([`crate::pipeline::BoardNoiseEstimate`]); the functions here are its parts, for a caller
//! that wants the σ themselves.

use crate::ekf::InnovationStats;
use crate::params::FilterParams;
use crate::recording::Recording;
use crate::start::first_pass;
use crate::suit::BoardNoise;
use crate::Result;
use skin_core::skeleton::Skeleton;

/// Per-board measurement noise estimated from `recording` ([`board_noise_from_innovations`]):
/// a first filter pass with `filter`'s global σ (the suit's own per-board σ set aside) over
/// the rest hold and the first `seconds` of motion, with the recording's known DOFs if
/// `use_known_dofs`. Put the result on the suit ([`crate::Suit::with_board_noise`]) for the
/// real run.
///
/// # Errors
/// As [`crate::pipeline::run`] and [`board_noise_from_innovations`]; [`crate::Error::Empty`]
/// for a recording with fewer than three frames after its rest hold.
pub fn estimate_board_noise(
    skeleton: &Skeleton,
    recording: &Recording,
    filter: FilterParams,
    use_known_dofs: bool,
    seconds: f64,
) -> Result<Vec<BoardNoise>> {
    let ekf = global_sigma_first_pass(skeleton, recording, filter, use_known_dofs, seconds)?;
    board_noise_from_innovations(
        ekf.innovation_stats(),
        recording.suit.boards().len(),
        &filter,
    )
}

/// [`estimate_board_noise`] with one σ per board axis
/// ([`board_axis_noise_from_innovations`]): the same first pass, each board's gyroscope and
/// accelerometer axes scaled by their own NIS.
///
/// # Errors
/// As [`estimate_board_noise`].
pub fn estimate_board_axis_noise(
    skeleton: &Skeleton,
    recording: &Recording,
    filter: FilterParams,
    use_known_dofs: bool,
    seconds: f64,
) -> Result<Vec<BoardNoise>> {
    let ekf = global_sigma_first_pass(skeleton, recording, filter, use_known_dofs, seconds)?;
    board_axis_noise_from_innovations(
        ekf.axis_innovation_stats(),
        recording.suit.boards().len(),
        &filter,
    )
}

/// The first pass of the noise estimates: `recording` with the global σ (a suit's own
/// per-board σ set aside).
fn global_sigma_first_pass(
    skeleton: &Skeleton,
    recording: &Recording,
    filter: FilterParams,
    use_known_dofs: bool,
    seconds: f64,
) -> Result<crate::SkeletalEkf> {
    let plain;
    let recording = if recording.suit.board_noise().is_empty() {
        recording
    } else {
        let mut r = recording.clone();
        r.suit = r.suit.with_board_noise(Vec::new())?;
        plain = r;
        &plain
    };
    Ok(first_pass(skeleton, recording, filter, use_known_dofs, seconds)?.0)
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
/// [`crate::Error::SizeMismatch`] unless the gyroscope and accelerometer statistics have one entry
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
/// [`crate::Error::SizeMismatch`] unless both sensor types have one entry per board; as
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
