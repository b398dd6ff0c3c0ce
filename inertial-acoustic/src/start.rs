//! The §4.4.4 start of a filter run on a [`Recording`] (the initialisation from the rest hold,
//! the filter so started) and the first pass over the start of a recording that the steps
//! beyond the thesis take (the per-board noise, the heading fit).

use skin_core::skeleton::Skeleton;

use crate::ekf::SkeletalEkf;
use crate::initialise::{initialise, Initialisation};
use crate::params::FilterParams;
use crate::recording::Recording;
use crate::{Context, Error, Result, ResultExt};

/// The recording's frame interval on `filter`.
fn at_rate(filter: FilterParams, recording: &Recording) -> FilterParams {
    FilterParams {
        frame_time_s: 1.0 / recording.rate_hz,
        ..filter
    }
}

/// The §4.4.4 start of a filter run on `recording`: the initialisation from the rest hold's
/// readings in the recording's rest pose, and the filter so started, with the recording's
/// known DOFs if `use_known_dofs` and it has them.
///
/// # Errors
/// As [`Recording::check`], [`crate::initialise`] and [`SkeletalEkf::new`].
pub fn start(
    skeleton: &Skeleton,
    recording: &Recording,
    filter: FilterParams,
    use_known_dofs: bool,
) -> Result<(SkeletalEkf, Initialisation)> {
    recording.check(skeleton)?;
    let rest: Vec<_> = recording.frames[..recording.rest_frames.max(1)]
        .iter()
        .map(|f| f.inertial.clone())
        .collect();
    let init = initialise(skeleton, &recording.suit, &recording.rest_pose, &rest)?;
    let known: &[usize] = if use_known_dofs {
        &recording.known_dofs
    } else {
        &[]
    };
    let ekf = SkeletalEkf::new(
        skeleton.clone(),
        init.suit.clone(),
        &recording.rest_pose,
        at_rate(filter, recording),
        known,
    )?
    .with_gyro_offsets(init.gyro_offsets.clone())?;
    Ok((ekf, init))
}

/// A first filter pass over the rest hold and the first `seconds` of motion: the filter at
/// its end, the §4.4.4 initialisation, the estimated poses after the rest hold and the frame
/// it stopped at.
pub(crate) fn first_pass(
    skeleton: &Skeleton,
    recording: &Recording,
    filter: FilterParams,
    use_known_dofs: bool,
    seconds: f64,
) -> Result<(SkeletalEkf, Initialisation, Vec<Vec<f64>>, usize)> {
    if recording.frames.len() <= recording.rest_frames + 2 {
        return Err(Error::Empty {
            what: "frames after the rest hold (a first pass needs at least three)",
        });
    }
    skin_core::check::non_negative("seconds", seconds)?;
    let (mut ekf, init) = start(skeleton, recording, filter, use_known_dofs)?;
    let known = use_known_dofs && !recording.known_dofs.is_empty();
    let end = (recording.rest_frames + (seconds * recording.rate_hz).round() as usize)
        .min(recording.frames.len());
    let mut poses = Vec::with_capacity(end - recording.rest_frames);
    for (k, f) in recording.frames[..end].iter().enumerate() {
        ekf.step(f, known.then(|| &recording.known[k]))
            .at(Context::Frame(k))?;
        if k >= recording.rest_frames {
            poses.push(ekf.theta().to_vec());
        }
    }
    Ok((ekf, init, poses, end))
}
