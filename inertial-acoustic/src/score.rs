//! Validation: the pipeline's runs on simulated recordings scored against their truth —
//! per-joint orientation errors, NEES, swing and twist — and the protocols built on them
//! (Table 4.1, the tuning grid of §4.4.1).

use std::f64::consts::TAU;

use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};
use skin_core::skeleton::Skeleton;

use crate::pipeline::{self, BoardNoiseEstimate, PipelineParams, PipelineRun};
use crate::simulate::SimulatedRecording;
use crate::{Error, Result};

/// One filter run over a simulated recording, scored against its truth.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FilterRun {
    /// Sensor combination label (Table 4.1), e.g. `"A+G+D"`.
    pub sensors: String,
    /// Whether the root transform was supplied.
    pub root_supplied: bool,
    /// Per evaluated joint, per frame after the rest hold: orientation error, degrees.
    pub errors_deg: Vec<Vec<f64>>,
    /// Per evaluated joint: mean and standard deviation.
    pub stats: Vec<crate::ErrorStats>,
    /// Frames at which the filter diverged and was reset.
    pub diverged_frames: usize,
    /// Seconds of EKF compute (initialisation and steps), wall clock.
    pub ekf_s: f64,
    /// Seconds of EKF compute, CPU time of the (single) thread that ran it: the code's cost
    /// without the time the thread waited for a core on a loaded machine.
    #[serde(default)]
    pub ekf_cpu_s: f64,
    /// Distances used.
    pub distances_used: usize,
    /// The filter's innovation statistics at the end of the run, per sensor type
    /// ([`crate::INNOVATION_TYPES`]) and board.
    #[serde(default)]
    pub innovations: [Vec<crate::InnovationStats>; 3],
    /// Per evaluated joint: mean NEES of its angles over the frames after the rest hold
    /// (`(θ − θ_true)ᵀ P⁻¹ (θ − θ_true)`, angles wrapped to ±π; ≈ the joint's DOF count for a
    /// consistent filter). Exact in the Euler chart; with re-centred joints P is in the local
    /// chart and the figure is first-order.
    #[serde(default)]
    pub nees_mean: Vec<f64>,
    /// Per evaluated joint: mean swing and mean twist (about the bone) of its orientation
    /// error, degrees ([`crate::joint_swing_twist_errors_deg`]).
    #[serde(default)]
    pub swing_twist_deg: Vec<[f64; 2]>,
    /// The per-board measurement noise the run used (the suit's; empty: the global σ).
    #[serde(default)]
    pub board_noise: Vec<crate::BoardNoise>,
}

/// Runs the pipeline ([`pipeline::run`]) on `rec`'s recording with `params` and the suit's
/// noise as recorded ([`BoardNoiseEstimate::Suit`]), supplying the root DOFs if
/// `root_supplied`, and scores `joints` against the truth on every frame after the rest
/// hold.
///
/// # Errors
/// As [`pipeline::run`]; [`Error::Empty`] for a recording no longer than its rest hold.
pub fn run_filter(
    skeleton: &Skeleton,
    rec: &SimulatedRecording,
    params: crate::FilterParams,
    root_supplied: bool,
    joints: &[usize],
) -> Result<FilterRun> {
    let pipeline = PipelineParams {
        filter: params,
        use_known_dofs: root_supplied,
        board_noise: BoardNoiseEstimate::Suit,
        heading_fit: false,
        covariance_joints: joints.to_vec(),
        ..PipelineParams::default()
    };
    score(skeleton, rec, &pipeline)
}

/// [`run_filter`] after per-board measurement noise from a first pass (same `params`,
/// `root_supplied`) over the rest hold and the first `seconds` of motion
/// ([`BoardNoiseEstimate::PerBoard`], the pipeline's default). The run's
/// [`FilterRun::board_noise`] holds the σ used; its `ekf_s` and `ekf_cpu_s` include the first
/// pass.
///
/// # Errors
/// As [`run_filter`].
pub fn run_filter_board_noise(
    skeleton: &Skeleton,
    rec: &SimulatedRecording,
    params: crate::FilterParams,
    root_supplied: bool,
    joints: &[usize],
    seconds: f64,
) -> Result<FilterRun> {
    let pipeline = PipelineParams {
        filter: params,
        use_known_dofs: root_supplied,
        board_noise: BoardNoiseEstimate::PerBoard,
        first_pass_s: seconds,
        heading_fit: false,
        covariance_joints: joints.to_vec(),
    };
    score(skeleton, rec, &pipeline)
}

/// [`pipeline::run`] on `rec`'s recording with `params` (its `covariance_joints` are the
/// joints scored), scored against the truth on every frame after the rest hold.
///
/// # Errors
/// As [`pipeline::run`]; [`Error::Empty`] for a recording no longer than its rest hold.
pub fn score(
    skeleton: &Skeleton,
    rec: &SimulatedRecording,
    params: &PipelineParams,
) -> Result<FilterRun> {
    let recording = &rec.recording;
    if recording.frames.len() <= recording.rest_frames + 1 {
        return Err(Error::Empty {
            what: "frames after the rest hold",
        });
    }
    skin_core::check::same_size("truth frames", recording.frames.len(), rec.truth.len())?;
    let run = pipeline::run(skeleton, recording, params)?;
    score_run(skeleton, rec, params, run)
}

fn score_run(
    skeleton: &Skeleton,
    rec: &SimulatedRecording,
    params: &PipelineParams,
    run: PipelineRun,
) -> Result<FilterRun> {
    use crate::{joint_orientation_errors_deg, joint_swing_twist_errors_deg, ErrorStats};
    let joints = &params.covariance_joints;
    let rest = rec.recording.rest_frames;
    let joint_dofs: Vec<Vec<usize>> = joints
        .iter()
        .map(|&j| skeleton.joint_dofs(j).collect())
        .collect();
    let mut errors = vec![Vec::new(); joints.len()];
    let mut nees = vec![0.0; joints.len()];
    let mut swing_twist = vec![[0.0; 2]; joints.len()];
    let estimates = &run.theta[rest..];
    for (i, (est, cov)) in estimates.iter().zip(&run.covariances[rest..]).enumerate() {
        let truth = &rec.truth[rest + i].theta;
        let e = joint_orientation_errors_deg(skeleton, est, truth, joints)?;
        for (acc, v) in errors.iter_mut().zip(e) {
            acc.push(v);
        }
        let st = joint_swing_twist_errors_deg(skeleton, est, truth, joints)?;
        for (acc, v) in swing_twist.iter_mut().zip(st) {
            acc[0] += v[0];
            acc[1] += v[1];
        }
        for ((n, d), c) in nees.iter_mut().zip(&joint_dofs).zip(cov) {
            let m = d.len();
            let diff = nalgebra::DVector::from_iterator(
                m,
                d.iter().map(|&q| {
                    let v = est[q] - truth[q];
                    v - TAU * (v / TAU).round()
                }),
            );
            let p = DMatrix::from_row_slice(m, m, c);
            if let Some(inv) = p.try_inverse() {
                *n += diff.dot(&(inv * &diff));
            }
        }
    }
    let nees_mean = nees
        .iter()
        .map(|n| n / estimates.len().max(1) as f64)
        .collect();
    let frames = estimates.len().max(1) as f64;
    let swing_twist_deg = swing_twist
        .iter()
        .map(|v| [v[0] / frames, v[1] / frames])
        .collect();
    let stats = errors
        .iter()
        .map(|e| ErrorStats::of(e))
        .collect::<Result<Vec<_>>>()?;
    Ok(FilterRun {
        sensors: params.filter.sensors.label(),
        root_supplied: params.use_known_dofs,
        errors_deg: errors,
        stats,
        diverged_frames: run.diverged_frames,
        ekf_s: run.seconds,
        ekf_cpu_s: run.cpu_seconds,
        distances_used: run.distances_used,
        innovations: run.innovations,
        nees_mean,
        swing_twist_deg,
        board_noise: run.suit.board_noise().to_vec(),
    })
}

/// The Table 4.1 protocol: every sensor combination of [`crate::SensorSet::table_4_1`], with
/// and without the root transform supplied, on one recording, with `params` otherwise; with
/// `board_noise_s`, each run estimates its per-board noise from its own first pass over that
/// many seconds of motion ([`run_filter_board_noise`]), else uses the suit as it is.
///
/// # Errors
/// As [`run_filter`] and [`run_filter_board_noise`].
pub fn table_4_1(
    skeleton: &Skeleton,
    rec: &SimulatedRecording,
    params: crate::FilterParams,
    joints: &[usize],
    board_noise_s: Option<f64>,
) -> Result<Vec<FilterRun>> {
    let mut out = Vec::with_capacity(14);
    for sensors in crate::SensorSet::table_4_1() {
        for root in [true, false] {
            let p = params.with_sensors(sensors);
            out.push(match board_noise_s {
                Some(secs) => run_filter_board_noise(skeleton, rec, p, root, joints, secs)?,
                None => run_filter(skeleton, rec, p, root, joints)?,
            });
        }
    }
    Ok(out)
}

/// A tuning grid point and its score.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TuningPoint {
    /// Process noise σ (per frame), rad/s².
    pub process_sigma: f64,
    /// Accelerometer σ, m/s².
    pub accelerometer_sigma: f64,
    /// Distance innovation gate, standard deviations (0: none).
    pub distance_gate_sigma: f64,
    /// Re-centring threshold of the 3-DOF joints (`base`'s; 0: Euler angles throughout).
    #[serde(default)]
    pub recentre_rad: f64,
    /// Mean over the evaluated joints of the mean orientation error, degrees (A+G+D, root
    /// supplied).
    pub score_deg: f64,
}

/// Hand tuning made reproducible (§4.4.1: "We hand tune the standard deviation of the noise
/// term by tracking several motions"): every combination of the three grids, scored with all
/// sensors and the root supplied on a tuning recording; returns the points, best first.
///
/// # Errors
/// As [`run_filter`]; [`Error::Empty`] for an empty grid.
pub fn tune(
    skeleton: &Skeleton,
    rec: &SimulatedRecording,
    base: crate::FilterParams,
    joints: &[usize],
    process_sigmas: &[f64],
    accelerometer_sigmas: &[f64],
    gates: &[f64],
) -> Result<Vec<TuningPoint>> {
    let mut out = Vec::new();
    for &q in process_sigmas {
        for &sa in accelerometer_sigmas {
            for &gate in gates {
                let p = crate::FilterParams {
                    process_sigma: q,
                    accelerometer_sigma: sa,
                    distance_gate_sigma: gate,
                    sensors: crate::SensorSet::ALL,
                    ..base
                };
                let r = run_filter(skeleton, rec, p, true, joints)?;
                let score = r.stats.iter().map(|s| s.mean_deg).sum::<f64>() / r.stats.len() as f64;
                out.push(TuningPoint {
                    process_sigma: q,
                    accelerometer_sigma: sa,
                    distance_gate_sigma: gate,
                    recentre_rad: base.recentre_rad,
                    score_deg: score,
                });
            }
        }
    }
    if out.is_empty() {
        return Err(Error::Empty {
            what: "tuning grid",
        });
    }
    out.sort_by(|a, b| a.score_deg.total_cmp(&b.score_deg));
    Ok(out)
}
