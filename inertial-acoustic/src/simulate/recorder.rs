//! The recorder: the suit simulated along a motion down to its raw signals (inertial counts
//! through the link, microphone frames), processed by the crate's own signal processing into
//! a [`Recording`]; and the oracle recording of the filter's own measurement models.

use super::motion::SmoothMotion;
use super::physics::{lerp_geometry, rotation_vector, segment_distance, Channel, Geometry};
use super::{GyroBiasModel, SuitSimulator};
use crate::ekf::{DistanceMeasurement, FrameObservations, InertialReading, KnownDofs};
use crate::inertial::{AxisCalibration, CHANNELS, FRAME_BITS};
use crate::params::{GRAVITY_M_S2, INERTIAL_RATE_HZ, PULSE_INTERVAL_S, SAMPLES_PER_PULSE};
use crate::pipeline::thread_cpu_s;
use crate::recording::Recording;
use crate::suit::Suit;
use crate::ultrasound::PulseDetector;
use crate::{Context, Error, Result, ResultExt};
use nalgebra::DMatrix;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};
use skin_core::check::positive;
use skin_core::math::DVec3;
use skin_core::skeleton::Skeleton;
use std::f64::consts::PI;
use std::time::Instant;

/// One 140 Hz frame of truth.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TruthFrame {
    /// True pose θ.
    pub theta: Vec<f64>,
}

/// A simulated and processed recording: what the suit would have recorded (a public
/// [`Recording`], the input of [`crate::pipeline::run`]), with the truth and the
/// simulator's own diagnostics beside it.
#[derive(Debug, Clone)]
pub struct SimulatedRecording {
    /// What the suit recorded: the processed observations, one per 140 Hz frame, the
    /// nominal suit (what the filter is told), the rest hold and the root DOFs' θ, θ̇, θ̈
    /// (the thesis's root transform input).
    pub recording: Recording,
    /// The true pose of every frame.
    pub truth: Vec<TruthFrame>,
    /// The true suit at the rest pose (with placement errors).
    pub true_suit: Suit,
    /// Seconds spent in ultrasonic processing (filters, detection, confidences), wall clock.
    pub ultrasound_s: f64,
    /// The same, CPU time of the thread that ran it.
    pub ultrasound_cpu_s: f64,
    /// Seconds spent in inertial decoding (descrambling, ECC, delta decoding, calibration).
    pub inertial_s: f64,
    /// Detected minus true distance of every used pulse with a clear line of sight, metres.
    pub los_distance_errors_m: Vec<f64>,
    /// Every detection: (detected − true distance in metres, confidence, line of sight clear).
    pub detections: Vec<(f64, f64, bool)>,
    /// Pulses heard (detections) and emitted (per microphone).
    pub pulses_heard: usize,
    /// Pulses emitted × microphones.
    pub pulses_total: usize,
    /// Inertial frames flagged by the error-correcting code (dropped).
    pub inertial_frames_flagged: usize,
    /// Bit errors corrected by the code.
    pub bits_corrected: usize,
    /// Channel readings of the decoded frames flagged unsynced (key frames, and lost codes
    /// until their channel's next key frame; [`crate::Saturation::unsynced`]).
    pub inertial_channels_unsynced: usize,
    /// Channel readings of the decoded frames (six per board and decoded frame).
    pub inertial_channels_decoded: usize,
    /// Per board: how far it moved relative to its bone (the skin motion) after the rest hold.
    pub skin_motion: Vec<SkinMotion>,
}

/// How far one board moved relative to its bone over a recording: its position and axes
/// against the same rest placement fixed rigidly to the bone.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SkinMotion {
    /// Board name.
    pub board: String,
    /// Mean displacement, millimetres.
    pub mean_mm: f64,
    /// Largest displacement, millimetres.
    pub max_mm: f64,
    /// Mean rotation of the board's axes, degrees.
    pub mean_deg: f64,
    /// Largest rotation, degrees.
    pub max_deg: f64,
}

/// One board's constants of the MEMS bias model ([`super::MemsGyroBias`]): turn-on offset,
/// temperature coefficient (per kelvin) and the rows of the linear-acceleration sensitivity.
struct BoardBias {
    turn_on: DVec3,
    temp_coeff: DVec3,
    g_sensitivity: [DVec3; 3],
}

#[derive(Debug, Clone, Copy, Default)]
struct SkinAccumulator {
    n: usize,
    sum_m: f64,
    max_m: f64,
    sum_rad: f64,
    max_rad: f64,
}

impl SkinAccumulator {
    fn add(&mut self, counted: bool, distance_m: f64, angle_rad: f64) {
        if counted {
            self.n += 1;
            self.sum_m += distance_m;
            self.max_m = self.max_m.max(distance_m);
            self.sum_rad += angle_rad;
            self.max_rad = self.max_rad.max(angle_rad);
        }
    }

    fn finish(&self, board: &str) -> SkinMotion {
        let n = self.n.max(1) as f64;
        SkinMotion {
            board: board.to_string(),
            mean_mm: 1e3 * self.sum_m / n,
            max_mm: 1e3 * self.max_m,
            mean_deg: (self.sum_rad / n).to_degrees(),
            max_deg: self.max_rad.to_degrees(),
        }
    }
}

impl SuitSimulator {
    /// The whole recording of `motion` (see the module docs), processed from the raw signals
    /// with per-source `offsets` (from [`SuitSimulator::calibrate_offsets`]).
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] for offsets not one per source; errors of the skeleton, the
    /// codec or the detector (with the frame in [`Error::At`]).
    pub fn record(&self, motion: &SmoothMotion, offsets: &[f64]) -> Result<SimulatedRecording> {
        let ns = self.nominal.sources().len();
        let nb = self.nominal.boards().len();
        skin_core::check::same_size("source offsets", ns, offsets.len())?;
        let mut rng = ChaCha8Rng::seed_from_u64(self.params.seed.wrapping_mul(0x9E37_79B9));
        let normal = Normal::new(0.0, 1.0).map_err(|e| Error::InvalidParam {
            name: "normal",
            reason: e.to_string(),
        })?;
        let p = &self.params;
        let dt = 1.0 / INERTIAL_RATE_HZ;
        let n_frames = (motion.duration_s() / dt).floor() as usize + 1;
        let nd = self.skeleton.dof_count();
        // Front ends: per board 3 gyro + 3 accel channels.
        let mut channels = Vec::with_capacity(nb);
        for _ in 0..nb {
            let mut ch = [Channel {
                zero: 0.0,
                slope: 0.0,
                noise: 0.0,
                accumulate: p.accumulate_10bit,
            }; CHANNELS];
            for (c, x) in ch.iter_mut().enumerate() {
                let (range, zero_sd, noise) = if c < 3 {
                    (p.gyro_range, p.gyro_zero_sd, p.gyro_noise)
                } else {
                    (p.accel_range, p.accel_zero_sd, p.accel_noise)
                };
                let slope = 4096.0 / (2.0 * range) * (1.0 + p.scale_sd * normal.sample(&mut rng));
                // One 10-bit step is four 12-bit counts; the analog noise adds to the white noise.
                let analog = p.analog_noise_lsb * 4.0 / slope;
                *x = Channel {
                    zero: 2048.0 + slope * zero_sd * normal.sample(&mut rng),
                    slope,
                    noise: noise.hypot(analog),
                    accumulate: p.accumulate_10bit,
                };
            }
            channels.push(ch);
        }
        // §4.3.3 calibration runs: 2 s per orientation.
        let mut calib = Vec::with_capacity(nb);
        for ch in &channels {
            let mut cal = [AxisCalibration {
                zero: 2048.0,
                slope: 1.0,
            }; CHANNELS];
            for (c, x) in ch.iter().enumerate() {
                let reference = if c < 3 { 1.5 * PI } else { GRAVITY_M_S2 };
                let mut mean = |v: f64| {
                    (0..280)
                        .map(|_| f64::from(x.count(v, &mut rng, &normal)))
                        .sum::<f64>()
                        / 280.0
                };
                let (plus, minus) = (mean(reference), mean(-reference));
                cal[c] = AxisCalibration::from_opposite(plus, minus, reference)
                    .at(Context::Sensor(calib.len()))?;
            }
            calib.push(cal);
        }
        let codec = p.codec()?;
        let mut encoders = vec![codec.clone(); nb];
        let mut decoders = vec![codec; nb];
        // Prime the codecs at the first frame's values (the link runs before the recording).
        // The gyroscopes' bias (`GyroBiasModel`): the stochastic part (the random walk, or the
        // MEMS model's instability) draws three normals per board and frame from the main
        // stream under either model; the MEMS model's per-board constants come from a stream
        // of their own, so every other random stream is the same under both models.
        let mut gyro_bias = vec![DVec3::ZERO; nb];
        let mut bias_rng =
            ChaCha8Rng::seed_from_u64(self.params.seed.wrapping_mul(0x9E37_79B9) ^ 0x6D65_6D73);
        let board_bias: Vec<BoardBias> = match p.gyro_bias {
            GyroBiasModel::RandomWalk => Vec::new(),
            GyroBiasModel::Mems(m) => (0..nb)
                .map(|_| {
                    let mut v = |sd: f64| {
                        DVec3::new(
                            normal.sample(&mut bias_rng),
                            normal.sample(&mut bias_rng),
                            normal.sample(&mut bias_rng),
                        ) * sd
                    };
                    BoardBias {
                        turn_on: v(m.turn_on_sd),
                        temp_coeff: v(m.temp_coeff_sd),
                        g_sensitivity: [
                            v(m.g_sensitivity_sd),
                            v(m.g_sensitivity_sd),
                            v(m.g_sensitivity_sd),
                        ],
                    }
                })
                .collect(),
        };
        let (mut th, mut rate, mut acc) = (vec![0.0; nd], vec![0.0; nd], vec![0.0; nd]);
        let (mut th_p, mut th_m) = (vec![0.0; nd], vec![0.0; nd]);
        let (mut scratch_r, mut scratch_a) = (vec![0.0; nd], vec![0.0; nd]);
        let root: Vec<usize> = self.skeleton.joint_dofs(0).collect();
        let h = 1e-3;
        let up = DVec3::new(0.0, GRAVITY_M_S2, 0.0);
        let mut out_frames = Vec::with_capacity(n_frames);
        let mut truth = Vec::with_capacity(n_frames);
        let mut roots = Vec::with_capacity(n_frames);
        let mut geometry = Vec::with_capacity(n_frames);
        let mut inertial_s = 0.0;
        let (mut flagged, mut corrected) = (0usize, 0usize);
        let (mut unsynced, mut decoded_channels) = (0usize, 0usize);
        let frames_true: Vec<_> = self.true_suit.boards().iter().map(|b| b.frame()).collect();
        let mut skin = vec![SkinAccumulator::default(); nb];
        let rest_frames = (p.rest_s / dt).floor() as usize;
        for k in 0..n_frames {
            let t = k as f64 * dt;
            motion.eval(t, &mut th, &mut rate, &mut acc);
            motion.eval(t + h, &mut th_p, &mut scratch_r, &mut scratch_a);
            motion.eval(t - h, &mut th_m, &mut scratch_r, &mut scratch_a);
            let (fk, now) = self.placement(&th).at(Context::Frame(k))?;
            let (_, plus) = self.placement(&th_p).at(Context::Frame(k))?;
            let (_, minus) = self.placement(&th_m).at(Context::Frame(k))?;
            let mut readings = Vec::with_capacity(nb);
            for b in 0..nb {
                let pos = now.board_positions[b];
                let a = (plus.board_positions[b] - 2.0 * pos + minus.board_positions[b]) / (h * h);
                let q = now.board_rotations[b];
                let to_local = q.inverse();
                let f = to_local * (a + up);
                let w = to_local
                    * (rotation_vector(
                        plus.board_rotations[b] * minus.board_rotations[b].inverse(),
                    ) / (2.0 * h));
                let bone = &frames_true[b];
                let rigid = fk.point(&self.true_suit.boards()[b].point())?;
                skin[b].add(
                    k >= rest_frames,
                    pos.distance(rigid),
                    q.angle_between(fk.frame_rotation(bone)?),
                );
                let step = DVec3::new(
                    normal.sample(&mut rng),
                    normal.sample(&mut rng),
                    normal.sample(&mut rng),
                );
                let bias = match p.gyro_bias {
                    GyroBiasModel::RandomWalk => {
                        gyro_bias[b] += step * (p.gyro_bias_walk * dt.sqrt());
                        gyro_bias[b]
                    }
                    GyroBiasModel::Mems(m) => {
                        // Exact discretisation of the Gauss–Markov process at dt.
                        let decay = (-dt / m.instability_tau_s).exp();
                        gyro_bias[b] = gyro_bias[b] * decay
                            + step * (m.instability_sd * (1.0 - decay * decay).sqrt());
                        let c = &board_bias[b];
                        let warm = m.warm_up_k * (1.0 - (-t / m.warm_up_tau_s).exp());
                        let g = &c.g_sensitivity;
                        c.turn_on
                            + c.temp_coeff * warm
                            + gyro_bias[b]
                            + DVec3::new(g[0].dot(f), g[1].dot(f), g[2].dot(f))
                    }
                };
                let values = [w.x + bias.x, w.y + bias.y, w.z + bias.z, f.x, f.y, f.z];
                let mut counts = [0i32; CHANNELS];
                for c in 0..CHANNELS {
                    counts[c] = channels[b][c].count(values[c], &mut rng, &normal);
                }
                if k == 0 {
                    // Lock both codec ends onto the first counts (a link already running).
                    for _ in 0..160 {
                        let bits = encoders[b].encode(&counts)?;
                        let _ = decoders[b].decode(&bits);
                    }
                }
                let mut bits = encoders[b].encode(&counts).at(Context::Sensor(b))?;
                for bit in bits.iter_mut().take(FRAME_BITS) {
                    if p.bit_error_rate > 0.0 && rng.random_bool(p.bit_error_rate.min(1.0)) {
                        *bit ^= true;
                    }
                }
                let t0 = Instant::now();
                let decoded = decoders[b].decode(&bits);
                let reading = decoded.map(|(cnt, fixed)| {
                    corrected += fixed;
                    let v = |c: usize| calib[b][c].value(f64::from(cnt[c]));
                    let flags = decoders[b].saturation();
                    unsynced += flags.iter().filter(|s| s.unsynced).count();
                    decoded_channels += CHANNELS;
                    InertialReading {
                        gyro_rad_s: DVec3::new(v(0), v(1), v(2)),
                        accel_m_s2: DVec3::new(v(3), v(4), v(5)),
                        saturated: flags.map(|s| s.any()),
                    }
                });
                inertial_s += t0.elapsed().as_secs_f64();
                if reading.is_none() {
                    flagged += 1;
                }
                readings.push(reading);
            }
            let capsules = self
                .capsules
                .iter()
                .map(|c| {
                    let w = fk.world_from_joint()[c.joint];
                    (w.translation, w.transform_point3(c.tip))
                })
                .collect();
            geometry.push(Geometry {
                boards: now.board_positions,
                sources: now.source_positions,
                normals: now.source_normals,
                capsules,
            });
            truth.push(TruthFrame { theta: th.clone() });
            roots.push(KnownDofs {
                theta: root.iter().map(|&d| th[d]).collect(),
                theta_dot: root.iter().map(|&d| rate[d]).collect(),
                theta_ddot: root.iter().map(|&d| acc[d]).collect(),
            });
            out_frames.push(FrameObservations {
                inertial: readings,
                distances: Vec::new(),
            });
        }
        let recording = Recording {
            rate_hz: INERTIAL_RATE_HZ,
            start_s: 0.0,
            suit: self.nominal.clone(),
            rest_frames,
            rest_pose: truth[0].theta.clone(),
            frames: out_frames,
            known_dofs: root,
            known: roots,
        };
        let mut rec = SimulatedRecording {
            recording,
            truth,
            true_suit: self.true_suit.clone(),
            ultrasound_s: 0.0,
            ultrasound_cpu_s: 0.0,
            inertial_s,
            los_distance_errors_m: Vec::new(),
            detections: Vec::new(),
            pulses_heard: 0,
            pulses_total: 0,
            inertial_frames_flagged: flagged,
            bits_corrected: corrected,
            inertial_channels_unsynced: unsynced,
            inertial_channels_decoded: decoded_channels,
            skin_motion: self
                .true_suit
                .boards()
                .iter()
                .zip(&skin)
                .map(|(b, acc)| acc.finish(&b.name))
                .collect(),
        };
        if p.ultrasound {
            self.ultrasonic_pass(&geometry, offsets, &mut rec, &mut rng, &normal)?;
        }
        Ok(rec)
    }

    fn ultrasonic_pass(
        &self,
        geometry: &[Geometry],
        offsets: &[f64],
        rec: &mut SimulatedRecording,
        rng: &mut ChaCha8Rng,
        normal: &Normal<f64>,
    ) -> Result<()> {
        let dt = 1.0 / INERTIAL_RATE_HZ;
        let fs = self.ultrasound.sample_rate_hz;
        let c = self.ultrasound.speed_of_sound_m_s;
        let ns = self.nominal.sources().len();
        let nb = self.nominal.boards().len();
        let duration = (geometry.len() - 1) as f64 * dt;
        let mut det = PulseDetector::new(self.ultrasound)?;
        let mut previous: Vec<Option<f64>> = vec![None; nb * ns];
        let mut frames = vec![vec![0f32; SAMPLES_PER_PULSE]; nb];
        let mut truth = vec![(0.0, 0.0, false); nb];
        let mut measured: Vec<Option<DistanceMeasurement>> = vec![None; nb];
        let board_joint: Vec<usize> = self.true_suit.boards().iter().map(|b| b.joint).collect();
        let source_joint: Vec<usize> = self.true_suit.sources().iter().map(|s| s.joint).collect();
        let mut slot = 0usize;
        loop {
            let t_s = slot as f64 * PULSE_INTERVAL_S;
            if t_s + PULSE_INTERVAL_S > duration {
                break;
            }
            let j = slot % ns;
            let kf = t_s / dt;
            let k0 = kf.floor() as usize;
            let g = lerp_geometry(
                &geometry[k0],
                &geometry[(k0 + 1).min(geometry.len() - 1)],
                kf - k0 as f64,
            );
            // The slot's raw frames first (simulation), then their processing (timed as one
            // block: the stage's wall and thread CPU time).
            for (i, &mic_joint) in board_joint.iter().enumerate() {
                let frame = &mut frames[i];
                self.background(frame, rng, normal);
                let (pi, pj) = (g.boards[i], g.sources[j]);
                let diff = pi - pj;
                let r = diff.length().max(1e-3);
                let cos = g.normals[j].dot(diff) / r;
                let occluded = self.capsules.iter().zip(&g.capsules).any(|(cap, seg)| {
                    cap.joint != mic_joint
                        && cap.joint != source_joint[j]
                        && segment_distance(pi, pj, seg.0, seg.1) < cap.radius
                });
                let amp = self.params.source_amplitude / r
                    * Self::directivity(cos)
                    * if occluded {
                        self.params.occlusion_factor
                    } else {
                        1.0
                    };
                let lag = self.source_lags_s[j];
                Self::add_burst(frame, r / c + lag, amp, fs);
                let mirror = DVec3::new(pi.x, 2.0 * self.floor_y - pi.y, pi.z);
                let dm = mirror - pj;
                let rm = dm.length().max(1e-3);
                let amp_m = self.params.floor_reflection * self.params.source_amplitude / rm
                    * Self::directivity(g.normals[j].dot(dm) / rm);
                Self::add_burst(frame, rm / c + lag, amp_m, fs);
                truth[i] = (r, cos, occluded);
                rec.pulses_total += 1;
            }
            let (t0, c0) = (Instant::now(), thread_cpu_s());
            for (i, (frame, out)) in frames.iter().zip(measured.iter_mut()).enumerate() {
                let detection = det.detect(frame).at(Context::Frame(slot))?;
                *out = detection.map(|x| {
                    let d = det.distance_m(&x, offsets[j]);
                    let pair = i * ns + j;
                    let w = det.strength_confidence(&x, d)
                        * det.continuity_confidence(d, previous[pair]);
                    previous[pair] = Some(d);
                    DistanceMeasurement {
                        sensor: i,
                        source: j,
                        distance_m: d,
                        confidence: w,
                        age_s: 0.0,
                    }
                });
            }
            rec.ultrasound_s += t0.elapsed().as_secs_f64();
            rec.ultrasound_cpu_s += thread_cpu_s() - c0;
            for (m, &(r, cos, occluded)) in measured.iter().zip(&truth) {
                if let Some(m) = *m {
                    rec.pulses_heard += 1;
                    rec.detections
                        .push((m.distance_m - r, m.confidence, !occluded && cos > 0.0));
                    if !occluded && cos > 0.0 && m.confidence >= 0.5 {
                        rec.los_distance_errors_m.push(m.distance_m - r);
                    }
                    let k = ((t_s + m.distance_m.max(0.0) / c) / dt).ceil() as usize;
                    if let Some(f) = rec.recording.frames.get_mut(k) {
                        f.distances.push(DistanceMeasurement {
                            age_s: k as f64 * dt - t_s,
                            ..m
                        });
                    }
                }
            }
            slot += 1;
        }
        Ok(())
    }
}

/// Oracle observations (diagnosis of the filter, not a simulation of the suit): the
/// filter's OWN measurement models evaluated along the true trajectory of `motion` with
/// `suit` — gyroscopes by Eq. 4.3 (`Rᵀ J_ω θ̇`), accelerometers by Eq. 4.2
/// (`Rᵀ (J θ̈ + J̇θ̇ + g)`), distances by Eq. 4.4 (`‖p_i − p_j‖`, one source per frame in
/// turn, every microphone in its field of view, confidence 1, no age) — without noise,
/// bias, quantisation, placement error or skin motion. A filter fed these must track the
/// truth to within its own lag; if it does not, the error is in the filter (dynamics,
/// Jacobians, initialisation), not in the sensing. `rest_s` is the rest hold at the start of
/// `motion` (as [`prepare_motion`](super::prepare_motion) put it there).
///
/// # Errors
/// As [`Skeleton::forward_kinematics`] and the skeleton's rate and Jacobian routines (with
/// the frame in [`Error::At`]); [`Error::Core`] for a non-positive `rest_s`.
pub fn model_recording(
    skeleton: &Skeleton,
    suit: &Suit,
    motion: &SmoothMotion,
    rest_s: f64,
) -> Result<SimulatedRecording> {
    positive("rest_s", rest_s)?;
    let dt = 1.0 / INERTIAL_RATE_HZ;
    let n_frames = (motion.duration_s() / dt).floor() as usize + 1;
    let nd = skeleton.dof_count();
    let (nb, ns) = (suit.boards().len(), suit.sources().len());
    let (mut th, mut rate, mut acc) = (vec![0.0; nd], vec![0.0; nd], vec![0.0; nd]);
    let points: Vec<_> = suit.boards().iter().map(|b| b.point()).collect();
    let frames: Vec<_> = suit.boards().iter().map(|b| b.frame()).collect();
    let root: Vec<usize> = skeleton.joint_dofs(0).collect();
    let up = DVec3::new(0.0, GRAVITY_M_S2, 0.0);
    let mut jac = DMatrix::zeros(3 * nb, nd);
    let mut bias = vec![DVec3::ZERO; nb];
    let mut out = Vec::with_capacity(n_frames);
    let (mut truth, mut roots) = (Vec::with_capacity(n_frames), Vec::with_capacity(n_frames));
    for k in 0..n_frames {
        motion.eval(k as f64 * dt, &mut th, &mut rate, &mut acc);
        let mut model = || -> Result<FrameObservations> {
            let fk = skeleton.forward_kinematics(&th)?;
            let rates = skeleton.rates(&th, &rate, &fk)?;
            skeleton.point_jacobians_into(&fk, &points, &mut jac)?;
            skeleton.point_bias_accelerations_into(&fk, &rates, &points, &mut bias)?;
            let mut inertial = Vec::with_capacity(nb);
            for b in 0..nb {
                let mut a = bias[b];
                for &d in skeleton.chain_dofs(points[b].joint) {
                    a += DVec3::new(jac[(3 * b, d)], jac[(3 * b + 1, d)], jac[(3 * b + 2, d)])
                        * acc[d];
                }
                let to_local = fk.frame_rotation(&frames[b])?.inverse();
                inertial.push(Some(InertialReading::new(
                    rates.frame_angular_velocity(
                        &fk,
                        &frames[b],
                        skin_core::skeleton::AngularFrame::Local,
                    )?,
                    to_local * (a + up),
                )));
            }
            let mut distances = Vec::new();
            if ns > 0 {
                let s = &suit.sources()[k % ns];
                let ps = fk.point(&s.point())?;
                let normal = fk.world_from_joint()[s.joint].matrix3 * s.normal;
                for (b, p) in points.iter().enumerate() {
                    let diff = fk.point(p)? - ps;
                    if normal.dot(diff) > 0.0 {
                        distances.push(DistanceMeasurement {
                            sensor: b,
                            source: k % ns,
                            distance_m: diff.length(),
                            confidence: 1.0,
                            age_s: 0.0,
                        });
                    }
                }
            }
            Ok(FrameObservations {
                inertial,
                distances,
            })
        };
        out.push(model().at(Context::Frame(k))?);
        truth.push(TruthFrame { theta: th.clone() });
        roots.push(KnownDofs {
            theta: root.iter().map(|&d| th[d]).collect(),
            theta_dot: root.iter().map(|&d| rate[d]).collect(),
            theta_ddot: root.iter().map(|&d| acc[d]).collect(),
        });
    }
    let recording = Recording {
        rate_hz: INERTIAL_RATE_HZ,
        start_s: 0.0,
        suit: suit.clone(),
        rest_frames: (rest_s / dt).floor() as usize,
        rest_pose: truth[0].theta.clone(),
        frames: out,
        known_dofs: root,
        known: roots,
    };
    Ok(SimulatedRecording {
        recording,
        truth,
        true_suit: suit.clone(),
        ultrasound_s: 0.0,
        ultrasound_cpu_s: 0.0,
        inertial_s: 0.0,
        los_distance_errors_m: Vec::new(),
        detections: Vec::new(),
        pulses_heard: 0,
        pulses_total: 0,
        inertial_frames_flagged: 0,
        bits_corrected: 0,
        inertial_channels_unsynced: 0,
        inertial_channels_decoded: 0,
        skin_motion: Vec::new(),
    })
}
