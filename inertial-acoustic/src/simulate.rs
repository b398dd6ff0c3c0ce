// Over 1,000 lines: the motion, suit physics, recorder and filter run of one simulated recording
// share its private state.
//! Validation equipment: the suit simulated on a studio motion, down to the raw signals the
//! thesis's hardware records, then processed by this crate's own signal processing.
//!
//! * **Motion.** The motion is smoothed (binomial passes), preceded by a rest-pose hold and
//!   a smooth blend into its first frame (§4.4.4's rest pose), and interpolated by natural
//!   cubic splines so θ, θ̇, θ̈ exist at any time.
//! * **Garment.** Each board and source sits where [`Suit::vlasic`] puts it, off by a random
//!   placement error (position and orientation) the filter does not know. On a studio
//!   performer ([`SuitSimulator::on_performer`]) it is attached to the performer's skin
//!   ([`GarmentSurface`]) and moves with its pose-driven deformation; on a bare skeleton
//!   ([`SuitSimulator::new`]) it slides along its bone with the bone's joint angles instead.
//!   [`SuitSimulator::with_rigid_attachment`] fixes the same placements to the bones.
//! * **Inertial.** Accelerations by second differences of the true garment positions (an
//!   independent path from the filter's analytic `J θ̈ + J̇θ̇`), angular velocities by central
//!   differences of the boards' true orientations; the paper's white noise (0.02 m/s², 0.002
//!   rad/s), per-axis zero and
//!   slope errors, a gyroscope bias random walk, 12-bit counts (four 10-bit samples
//!   accumulated), 6-bit delta modulation with error-correcting code and scrambling, random bit
//!   errors; decoded and calibrated by the §4.3.3 procedure (±g poses and ±45 rpm turntable
//!   runs simulated with the same errors).
//! * **Ultrasonic.** Round-robin pulses every 8 ms; per microphone and pulse a 1,120-sample
//!   frame at 140 kHz: 10-cycle 40 kHz piezo bursts (exponential ring-up and ring-down),
//!   amplitude ∝ 1/r, cosine-like source directivity with a weak back lobe, a floor reflection,
//!   body occlusion (capsules around the bones), the 13 kbit/s digital stream multiplexed on
//!   the same wire, white noise; processed by [`PulseDetector`] with per-source offsets
//!   calibrated from static placements 30–90 cm apart.

use crate::ekf::{DistanceMeasurement, FrameObservations, InertialReading, KnownDofs};
pub use crate::garment::{GarmentPose, GarmentSurface, MIN_PATCH, PATCH_RADIUS_M};
use crate::inertial::{AxisCalibration, DeltaCodec, CHANNELS, FRAME_BITS};
use crate::params::{
    UltrasoundParams, CARRIER_HZ, GRAVITY_M_S2, INERTIAL_RATE_HZ, PULSE_CYCLES, PULSE_INTERVAL_S,
    SAMPLES_PER_PULSE,
};
use crate::suit::{SensorBoard, Suit, UltrasonicSource};
use crate::ultrasound::{
    calibrate_offsets, leave_one_out_errors_m, CalibrationShot, PulseDetector,
};
use crate::{Context, Error, Result, ResultExt};
use dynamic_shapes_studio::{DeformationParams, Performer};
use nalgebra::DMatrix;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};
use skin_core::check::{non_negative, positive};
use skin_core::math::{DQuat, DVec3};
use skin_core::skeleton::{ForwardKinematics, Motion, Skeleton};
use std::f64::consts::{PI, TAU};
use std::time::Instant;

/// Parameters of the simulated suit.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SimulationParams {
    /// Accelerometer white noise, m/s². Default: 0.02 (§4.4.2).
    pub accel_noise: f64,
    /// Gyroscope white noise, rad/s. Default: 0.002 (§4.4.2).
    pub gyro_noise: f64,
    /// Spread of the accelerometers' zero offsets before calibration, m/s². Default: 0.5.
    pub accel_zero_sd: f64,
    /// Spread of the gyroscopes' zero offsets before calibration, rad/s. Default: 0.1.
    pub gyro_zero_sd: f64,
    /// Spread of the scale (slope) errors, relative. Default: 0.03.
    pub scale_sd: f64,
    /// Gyroscope bias random walk, rad/s per √s. Default: 0.0005.
    pub gyro_bias_walk: f64,
    /// Accelerometer range (full scale of the 12-bit count), m/s². Default: ±6 g.
    pub accel_range: f64,
    /// Gyroscope range, rad/s. Default: ±20 (1150 °/s). The 6-bit delta code slews at most
    /// 31 counts per frame, i.e. `31 · 2 · range / 4096 · 140` per second: 42 rad/s² at this
    /// range; at ±8.7 rad/s (500 °/s) it is 18 rad/s², below the exercise motion's angular
    /// accelerations, and the slew lag alone costs the shoulders tens of degrees.
    pub gyro_range: f64,
    /// Whether each 12-bit count is four 10-bit samples accumulated (§4.2.3, the default) or
    /// one 12-bit sample (a diagnostic: without noise of at least about one 10-bit step the
    /// accumulation gains no precision, and the counts keep 10-bit steps). Default: true.
    #[serde(default = "default_true")]
    pub accumulate_10bit: bool,
    /// Analog noise at the converter's input, in 10-bit steps (σ of each 10-bit sample). The
    /// thesis states the precision of the 12-bit quantities (0.002 rad/s, 0.02 m/s², §4.4.2)
    /// and that accumulating "several" 10-bit readings gives "more precise 12-bit quantities"
    /// (§4.2.3). That is only true physically when the analog signal carries noise of about half
    /// a 10-bit step or more (dither): without it four samples of a slowly varying signal fall
    /// into the same 10-bit bin and their sum keeps the 10-bit step. Default 0.5: the mean of
    /// four samples then has σ = one 12-bit count — at a ±4.1 rad/s / ±4.2 g range exactly the
    /// thesis's 0.002 rad/s / 0.02 m/s² (an inference from the thesis's numbers, it names no
    /// parts); at the simulated ±20 rad/s / ±6 g it is 0.0098 rad/s / 0.029 m/s². 0 gives the
    /// earlier front end (only the white noise `gyro_noise`/`accel_noise`, no dither).
    #[serde(default = "default_analog_noise_lsb")]
    pub analog_noise_lsb: f64,
    /// The inertial link's delta code: `Some(step)` for the noise-shaped code whose unit is
    /// `step` counts ([`DeltaCodec::noise_shaped`]: the thesis's "compensate by
    /// overestimating in the next frame", slew `31 · step` counts per frame; issue 15, seventh
    /// session), `None` for whole-count deltas without feedback ([`DeltaCodec::new`], the
    /// default until the eighth session). Default:
    /// `Some(`[`SimulationParams::DEFAULT_DELTA_STEP`]`)`. The filter must be told the code's
    /// per-frame error: [`SimulationParams::with_code_noise`].
    #[serde(default = "default_delta_step")]
    pub delta_step: Option<i32>,
    /// Frames between a channel's key frames on the inertial link (its absolute count in two
    /// 6-bit halves, [`DeltaCodec::with_key_interval`]; beyond the
    /// thesis): after a lost frame the decoder flags the channel unsynced (the filter skips
    /// it, [`crate::FilterParams::skip_saturated`]) until its next key frame restores it.
    /// 0: no key frames (the thesis's code). Default: [`SimulationParams::DEFAULT_KEY_INTERVAL`].
    #[serde(default = "default_key_interval")]
    pub key_interval: u32,
    /// Bit error rate of the digital inertial link. Default: 2·10⁻⁴.
    pub bit_error_rate: f64,
    /// Garment placement error: position, metres (per axis). Default: 0.01.
    pub placement_sd_m: f64,
    /// Garment placement error: orientation, degrees (per axis). Default: 3.
    pub placement_sd_deg: f64,
    /// Skin and garment slide along the bone per radian of the bone's joint angles, metres
    /// (the skin-motion stand-in of [`SuitSimulator::new`]; a suit on a performer's surface
    /// does not use it). Default: 0.01.
    pub skin_slide_m_per_rad: f64,
    /// Source amplitude at 1 m on its axis (microphone units). Default: 1.
    pub source_amplitude: f64,
    /// White noise of the microphone channel (same units). Default: 0.01 (40 dB below the
    /// on-axis signal at 1 m).
    pub mic_noise: f64,
    /// Floor reflection coefficient. Default: 0.4.
    pub floor_reflection: f64,
    /// Amplitude factor behind the body (diffraction around an occluding bone). Default: 0.03.
    pub occlusion_factor: f64,
    /// Amplitude of the multiplexed digital stream on the microphone wire. Default: 0.05.
    pub digital_crosstalk: f64,
    /// Rest-pose hold before the motion (§4.4.4), seconds. Default: 1.5.
    pub rest_s: f64,
    /// Blend from the rest pose into the motion's first frame, seconds. Default: 1.0.
    pub blend_s: f64,
    /// Binomial [1, 2, 1]/4 smoothing passes over the motion frames. Default: 2.
    pub smoothing_passes: usize,
    /// Whether to simulate and process the ultrasonic subsystem. Default: true.
    pub ultrasound: bool,
    /// Seed.
    pub seed: u64,
}

impl Default for SimulationParams {
    fn default() -> Self {
        SimulationParams {
            accel_noise: 0.02,
            gyro_noise: 0.002,
            accel_zero_sd: 0.5,
            gyro_zero_sd: 0.1,
            scale_sd: 0.03,
            gyro_bias_walk: 0.0005,
            accel_range: 6.0 * GRAVITY_M_S2,
            gyro_range: 20.0,
            accumulate_10bit: true,
            analog_noise_lsb: 0.5,
            delta_step: default_delta_step(),
            key_interval: default_key_interval(),
            bit_error_rate: 2e-4,
            placement_sd_m: 0.01,
            placement_sd_deg: 3.0,
            skin_slide_m_per_rad: 0.01,
            source_amplitude: 1.0,
            mic_noise: 0.01,
            floor_reflection: 0.4,
            occlusion_factor: 0.03,
            digital_crosstalk: 0.05,
            rest_s: 1.5,
            blend_s: 1.0,
            smoothing_passes: 2,
            ultrasound: true,
            seed: 1,
        }
    }
}

impl SimulationParams {
    /// With `seed` replaced.
    pub fn with_seed(self, seed: u64) -> Self {
        SimulationParams { seed, ..self }
    }

    /// With the ultrasonic subsystem on or off.
    pub fn with_ultrasound(self, ultrasound: bool) -> Self {
        SimulationParams { ultrasound, ..self }
    }

    /// The delta code's per-frame reading error as a σ per axis in physical units,
    /// `(gyroscope rad/s, accelerometer m/s²)` — what a filter must add to the sensors' own
    /// noise. In counts it is
    /// [`DeltaCodec::frame_error_sigma_counts`]: step/√6 for the noise-shaped code (the
    /// difference of two successive round-offs of at most step/2 each; derivation in
    /// [`DeltaCodec`]'s docs), 0 for the whole-count code. A count is `2 · range / 4096` units
    /// (the 12-bit count spans ±range; the calibration's slope differs from this by the 3 %
    /// scale error, which is immaterial to a noise level), so at the default ±20 rad/s and
    /// ±6 g with 16-count units: 16/√6 · 40/4096 = 0.064 rad/s and 16/√6 · 117.7/4096 =
    /// 0.19 m/s². (The code's error is negatively correlated at lag 1, which the filter's
    /// white-noise model ignores: it then over-states the error of the integrated reading,
    /// the safe side.)
    ///
    /// # Errors
    /// As [`DeltaCodec::noise_shaped`] for a bad step.
    pub fn code_noise(&self) -> Result<(f64, f64)> {
        let codec = self.codec()?;
        let counts = codec.frame_error_sigma_counts();
        Ok((
            counts * 2.0 * self.gyro_range / 4096.0,
            counts * 2.0 * self.accel_range / 4096.0,
        ))
    }

    /// `params` with the delta code's per-frame error ([`code_noise`](Self::code_noise))
    /// combined with its gyroscope and accelerometer σ in quadrature, `√(σ_s² + σ_q²)`: the
    /// sensor noise and the code's round-off are independent. With the whole-count code
    /// `params` is returned unchanged.
    ///
    /// # Errors
    /// As [`code_noise`](Self::code_noise).
    pub fn with_code_noise(&self, params: crate::FilterParams) -> Result<crate::FilterParams> {
        let (gyro, accel) = self.code_noise()?;
        Ok(crate::FilterParams {
            gyroscope_sigma: params.gyroscope_sigma.hypot(gyro),
            accelerometer_sigma: params.accelerometer_sigma.hypot(accel),
            ..params
        })
    }

    /// The inertial link's codec as these parameters set it ([`delta_step`](Self::delta_step),
    /// [`key_interval`](Self::key_interval)), both ends at mid-scale.
    ///
    /// # Errors
    /// As [`DeltaCodec::noise_shaped`] and [`DeltaCodec::with_key_interval`].
    pub fn codec(&self) -> Result<DeltaCodec> {
        match self.delta_step {
            Some(step) => DeltaCodec::noise_shaped(step)?,
            None => DeltaCodec::new(),
        }
        .with_key_interval(self.key_interval)
    }

    fn validate(&self) -> Result<()> {
        for (name, v) in [
            ("accel_noise", self.accel_noise),
            ("gyro_noise", self.gyro_noise),
            ("accel_zero_sd", self.accel_zero_sd),
            ("gyro_zero_sd", self.gyro_zero_sd),
            ("scale_sd", self.scale_sd),
            ("gyro_bias_walk", self.gyro_bias_walk),
            ("bit_error_rate", self.bit_error_rate),
            ("placement_sd_m", self.placement_sd_m),
            ("placement_sd_deg", self.placement_sd_deg),
            ("skin_slide_m_per_rad", self.skin_slide_m_per_rad),
            ("mic_noise", self.mic_noise),
            ("floor_reflection", self.floor_reflection),
            ("occlusion_factor", self.occlusion_factor),
            ("digital_crosstalk", self.digital_crosstalk),
            ("blend_s", self.blend_s),
            ("analog_noise_lsb", self.analog_noise_lsb),
        ] {
            non_negative(name, v)?;
        }
        positive("accel_range", self.accel_range)?;
        positive("gyro_range", self.gyro_range)?;
        positive("source_amplitude", self.source_amplitude)?;
        positive("rest_s", self.rest_s)?;
        self.codec()?;
        Ok(())
    }
}

impl SimulationParams {
    /// The noise-shaped delta code's default unit, counts. The
    /// thesis gives no step size; 16 is chosen from data (docs, "The noise-shaped code as the
    /// default"): its slew, `31 · 16` counts per frame (4.8 rad/s per frame, 680 rad/s², at ±20
    /// rad/s; 14 m/s² per frame at ±6 g), covers the walk's arm (99th percentile 541 rad/s²) where
    /// 8-count units still slew, and its per-frame error (σ 16/√6 = 6.5 counts: 0.064 rad/s,
    /// 0.19 m/s²) is half of 32-count units'.
    pub const DEFAULT_DELTA_STEP: i32 = 16;

    /// The inertial link's default key interval, frames (see
    /// [`SimulationParams::key_interval`] and the docs, "A resynchronising code"): 0.2 s at
    /// 140 Hz. Chosen from data: per channel it costs 2/K of the readings (7 %) and leaves a
    /// lost code flagged for K/2 frames on average; at a bit error rate of 10⁻² (a code lost
    /// every ≈ 190 frames per channel) 28 held the 30 s exercise within 8° on every joint where
    /// 70 let the shoulder go to 33°, and at the default rate the exercise and the walk were no
    /// worse than without keys.
    pub const DEFAULT_KEY_INTERVAL: u32 = 28;
}

fn default_key_interval() -> u32 {
    SimulationParams::DEFAULT_KEY_INTERVAL
}

fn default_delta_step() -> Option<i32> {
    Some(SimulationParams::DEFAULT_DELTA_STEP)
}

fn default_analog_noise_lsb() -> f64 {
    0.5
}

fn default_true() -> bool {
    true
}

/// Natural cubic splines through every DOF of a motion.
#[derive(Debug, Clone)]
pub struct SmoothMotion {
    h: f64,
    y: DMatrix<f64>,
    m: DMatrix<f64>,
}

impl SmoothMotion {
    /// Splines through `frames` (DOFs × frames) spaced `h` seconds.
    fn new(h: f64, y: DMatrix<f64>) -> Self {
        let (nd, n) = y.shape();
        let mut m = DMatrix::zeros(nd, n);
        if n >= 3 {
            // Tridiagonal system (h/6, 2h/3, h/6) M = Δ²y / h, natural ends; Thomas algorithm.
            let mut c = vec![0.0; n];
            let mut dd = vec![0.0; n];
            for d in 0..nd {
                c[0] = 0.0;
                dd[0] = 0.0;
                for i in 1..n - 1 {
                    let rhs = (y[(d, i + 1)] - 2.0 * y[(d, i)] + y[(d, i - 1)]) * 6.0 / (h * h);
                    let denom = 4.0 - c[i - 1];
                    c[i] = 1.0 / denom;
                    dd[i] = (rhs - dd[i - 1]) / denom;
                }
                m[(d, n - 1)] = 0.0;
                for i in (1..n - 1).rev() {
                    m[(d, i)] = dd[i] - c[i] * m[(d, i + 1)];
                }
            }
        }
        SmoothMotion { h, y, m }
    }

    /// Duration, seconds.
    pub fn duration_s(&self) -> f64 {
        self.h * (self.y.ncols().saturating_sub(1)) as f64
    }

    /// θ, θ̇, θ̈ at time `t` (clamped into the motion).
    pub fn eval(&self, t: f64, theta: &mut [f64], rate: &mut [f64], acc: &mut [f64]) {
        let n = self.y.ncols();
        let h = self.h;
        let s = (t / h).clamp(0.0, (n - 1) as f64);
        let i = (s.floor() as usize).min(n.saturating_sub(2));
        let u = s - i as f64;
        let (a, b) = (1.0 - u, u);
        for d in 0..self.y.nrows() {
            let (y0, y1) = (self.y[(d, i)], self.y[(d, (i + 1).min(n - 1))]);
            let (m0, m1) = (self.m[(d, i)], self.m[(d, (i + 1).min(n - 1))]);
            theta[d] =
                a * y0 + b * y1 + ((a * a * a - a) * m0 + (b * b * b - b) * m1) * h * h / 6.0;
            rate[d] =
                (y1 - y0) / h + ((1.0 - 3.0 * a * a) * m0 + (3.0 * b * b - 1.0) * m1) * h / 6.0;
            acc[d] = a * m0 + b * m1;
        }
    }
}

/// The motion the suit performs: `motion` smoothed, after a rest hold and a blend.
///
/// # Errors
/// As [`Motion::check_for`].
pub fn prepare_motion(
    skeleton: &Skeleton,
    motion: &Motion,
    params: &SimulationParams,
) -> Result<SmoothMotion> {
    motion.check_for(skeleton)?;
    params.validate()?;
    let h = motion.frame_time_s;
    let mut frames = motion.frames.clone();
    // Unwrap rotation DOFs (mocap decompositions jump by 2π), so splines do not swing round.
    for d in 0..frames.nrows() {
        if skeleton.is_rotation(d) {
            for k in 1..frames.ncols() {
                let jump = frames[(d, k)] - frames[(d, k - 1)];
                frames[(d, k)] -= TAU * (jump / TAU).round();
            }
        }
    }
    for _ in 0..params.smoothing_passes {
        let prev = frames.clone();
        let n = prev.ncols();
        for k in 1..n.saturating_sub(1) {
            for d in 0..prev.nrows() {
                frames[(d, k)] =
                    0.25 * prev[(d, k - 1)] + 0.5 * prev[(d, k)] + 0.25 * prev[(d, k + 1)];
            }
        }
    }
    let nd = skeleton.dof_count();
    let root: Vec<usize> = skeleton.joint_dofs(0).collect();
    let first: Vec<f64> = frames.column(0).iter().copied().collect();
    let mut rest = first.clone();
    for (d, v) in rest.iter_mut().enumerate() {
        if !root.contains(&d) {
            *v = 0.0;
        }
    }
    let n_rest = (params.rest_s / h).round() as usize;
    let n_blend = (params.blend_s / h).round() as usize;
    let n = n_rest + n_blend + frames.ncols();
    let mut y = DMatrix::zeros(nd, n);
    for k in 0..n {
        for d in 0..nd {
            y[(d, k)] = if k < n_rest {
                rest[d]
            } else if k < n_rest + n_blend {
                let u = (k - n_rest) as f64 / n_blend.max(1) as f64;
                let s = u * u * (3.0 - 2.0 * u);
                rest[d] + s * (first[d] - rest[d])
            } else {
                frames[(d, k - n_rest - n_blend)]
            };
        }
    }
    Ok(SmoothMotion::new(h, y))
}

/// Per-axis true analogue front end of one board channel.
#[derive(Debug, Clone, Copy)]
struct Channel {
    zero: f64,
    slope: f64,
    noise: f64,
    accumulate: bool,
}

impl Channel {
    /// 12-bit count of `value` (four noisy 10-bit samples accumulated, §4.2.3).
    fn count(&self, value: f64, rng: &mut ChaCha8Rng, normal: &Normal<f64>) -> i32 {
        if !self.accumulate {
            let v = self.zero + self.slope * (value + self.noise * normal.sample(rng));
            return (v.round() as i32).clamp(0, 4095);
        }
        let mut acc = 0i32;
        for _ in 0..4 {
            let v = self.zero + self.slope * (value + self.noise * normal.sample(rng));
            acc += ((v / 4.0).round() as i32).clamp(0, 1023);
        }
        acc
    }
}

/// A capsule of the body (occlusion model).
#[derive(Debug, Clone, Copy)]
struct Capsule {
    joint: usize,
    tip: DVec3,
    radius: f64,
}

fn capsule_radius(name: &str) -> f64 {
    let base = name.trim_start_matches("l_").trim_start_matches("r_");
    match base {
        "pelvis" | "spine" | "chest" => 0.10,
        "neck" => 0.05,
        "head" => 0.08,
        "clavicle" => 0.04,
        "shoulder" => 0.04,
        "elbow" => 0.035,
        "wrist" => 0.025,
        "hip" => 0.065,
        "knee" => 0.045,
        "ankle" => 0.035,
        _ => 0.04,
    }
}

/// Closest distance between segments [p0, p1] and [q0, q1].
fn segment_distance(p0: DVec3, p1: DVec3, q0: DVec3, q1: DVec3) -> f64 {
    let (d1, d2, r) = (p1 - p0, q1 - q0, p0 - q0);
    let (a, e, f) = (d1.dot(d1), d2.dot(d2), d2.dot(r));
    let (s, t);
    if a <= 1e-12 && e <= 1e-12 {
        return r.length();
    }
    if a <= 1e-12 {
        s = 0.0;
        t = (f / e).clamp(0.0, 1.0);
    } else {
        let c = d1.dot(r);
        if e <= 1e-12 {
            t = 0.0;
            s = (-c / a).clamp(0.0, 1.0);
        } else {
            let b = d1.dot(d2);
            let denom = a * e - b * b;
            let s0 = if denom > 1e-12 {
                ((b * f - c * e) / denom).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let t0 = (b * s0 + f) / e;
            if t0 < 0.0 {
                t = 0.0;
                s = (-c / a).clamp(0.0, 1.0);
            } else if t0 > 1.0 {
                t = 1.0;
                s = ((b - c) / a).clamp(0.0, 1.0);
            } else {
                t = t0;
                s = s0;
            }
        }
    }
    ((p0 + d1 * s) - (q0 + d2 * t)).length()
}

/// `nominal` with random placement errors (position per axis `placement_sd_m`, half that for
/// sources; orientation per axis `placement_sd_deg`).
fn perturbed(
    skeleton: &Skeleton,
    nominal: &Suit,
    params: &SimulationParams,
    rng: &mut ChaCha8Rng,
) -> Result<Suit> {
    let normal = Normal::new(0.0, 1.0).map_err(|e| Error::InvalidParam {
        name: "normal",
        reason: e.to_string(),
    })?;
    let mut g3 = |s: f64| {
        DVec3::new(
            normal.sample(&mut *rng),
            normal.sample(&mut *rng),
            normal.sample(&mut *rng),
        ) * s
    };
    let boards: Vec<SensorBoard> = nominal
        .boards()
        .iter()
        .map(|b| SensorBoard {
            offset: b.offset + g3(params.placement_sd_m),
            joint_from_sensor: b.joint_from_sensor
                * DQuat::from_scaled_axis(g3(params.placement_sd_deg.to_radians())),
            ..b.clone()
        })
        .collect();
    let sources: Vec<UltrasonicSource> = nominal
        .sources()
        .iter()
        .map(|s| UltrasonicSource {
            offset: s.offset + g3(0.5 * params.placement_sd_m),
            ..s.clone()
        })
        .collect();
    Suit::new(skeleton, boards, sources)
}

/// The rotation vector of `q` (shortest way round).
fn rotation_vector(q: DQuat) -> DVec3 {
    if q.w < 0.0 {
        (-q).to_scaled_axis()
    } else {
        q.to_scaled_axis()
    }
}

/// One 140 Hz frame of truth.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TruthFrame {
    /// True pose θ.
    pub theta: Vec<f64>,
}

/// A simulated and processed recording.
#[derive(Debug, Clone)]
pub struct SimulatedRecording {
    /// The processed observations, one per 140 Hz frame.
    pub frames: Vec<FrameObservations>,
    /// The true pose of every frame.
    pub truth: Vec<TruthFrame>,
    /// The root DOFs' θ, θ̇, θ̈ of every frame (the thesis's root transform input).
    pub root: Vec<KnownDofs>,
    /// Frames of the rest-pose hold at the start.
    pub rest_frames: usize,
    /// The nominal suit (what the filter is told).
    pub nominal_suit: Suit,
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

/// Static offset calibration of the sources (§4.3.3).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OffsetCalibration {
    /// Per-source offset, samples.
    pub offsets: Vec<f64>,
    /// Leave-one-out absolute distance errors, metres.
    pub loo_abs_errors_m: Vec<f64>,
    /// Signal-to-noise ratio at the farthest placement (0.9 m, on axis): peak amplitude over
    /// noise RMS, dB.
    pub snr_db_at_90cm: f64,
}

/// The simulated suit.
#[derive(Debug, Clone)]
pub struct SuitSimulator {
    skeleton: Skeleton,
    nominal: Suit,
    true_suit: Suit,
    params: SimulationParams,
    ultrasound: UltrasoundParams,
    capsules: Vec<Capsule>,
    /// The garment surface the boards and sources ride on, if any.
    garment: Option<GarmentSurface>,
    /// Height of the floor (reflections), metres.
    floor_y: f64,
    slide_dir: Vec<DVec3>,
    /// Per-source electrical delay, seconds (why calibrated offsets differ between sources).
    source_lags_s: Vec<f64>,
}

impl SuitSimulator {
    /// The thesis's suit on `skeleton` with random placement errors; boards slide along their
    /// bone by [`SimulationParams::skin_slide_m_per_rad`] (the stand-in for skin motion when
    /// there is no performer surface).
    ///
    /// # Errors
    /// As [`Suit::vlasic`]; [`Error::Core`] for invalid parameters.
    pub fn new(skeleton: &Skeleton, params: SimulationParams) -> Result<Self> {
        params.validate()?;
        let nominal = Suit::vlasic(skeleton)?;
        let mut rng = ChaCha8Rng::seed_from_u64(params.seed ^ 0x5u64);
        let true_suit = perturbed(skeleton, &nominal, &params, &mut rng)?;
        Self::assemble(skeleton, nominal, true_suit, None, 0.0, params, &mut rng)
    }

    /// The thesis's suit on the garment over `performer`'s skin ([`GarmentSurface`]): the
    /// table's positions are snapped to the rest body surface (the nominal suit the filter is
    /// told), the true placements carry the random placement errors and are snapped too, and
    /// every board and source then moves with the performer's pose-driven deformation
    /// (`deformation`: the parameters the performer was built with) instead of rigidly with
    /// its bone. [`SimulationParams::skin_slide_m_per_rad`] is not used.
    ///
    /// # Errors
    /// As [`Suit::vlasic`] and [`GarmentSurface::new`]; [`Error::Core`] for invalid
    /// parameters.
    pub fn on_performer(
        performer: &Performer,
        deformation: &DeformationParams,
        params: SimulationParams,
    ) -> Result<Self> {
        params.validate()?;
        let skeleton = &performer.skeleton;
        let (_, nominal) = GarmentSurface::new(performer, deformation, &Suit::vlasic(skeleton)?)?;
        let mut rng = ChaCha8Rng::seed_from_u64(params.seed ^ 0x5u64);
        let placed = perturbed(skeleton, &nominal, &params, &mut rng)?;
        let (surface, true_suit) = GarmentSurface::new(performer, deformation, &placed)?;
        // The floor under the performer's feet at rest (the template's lowest point).
        let floor_y = performer
            .template
            .vertices
            .iter()
            .map(|v| v.y)
            .fold(f64::INFINITY, f64::min);
        Self::assemble(
            skeleton,
            nominal,
            true_suit,
            Some(surface),
            floor_y,
            params,
            &mut rng,
        )
    }

    /// The same suit (same nominal and true placements, same seed) fixed rigidly to the bones:
    /// no surface deformation and no slide — the baseline that shows what skin motion costs.
    pub fn with_rigid_attachment(mut self) -> Self {
        self.garment = None;
        self.params.skin_slide_m_per_rad = 0.0;
        self
    }

    /// The same suit (same placements and seed) on another inertial link: its bit error rate
    /// and key interval ([`SimulationParams::bit_error_rate`],
    /// [`SimulationParams::key_interval`]) — the bit-error sweep of issue 15's ninth session.
    ///
    /// # Errors
    /// [`Error::Core`] (invalid parameter) for a negative or non-finite rate; as
    /// [`DeltaCodec::with_key_interval`] for a bad interval.
    pub fn with_link(mut self, bit_error_rate: f64, key_interval: u32) -> Result<Self> {
        non_negative("bit_error_rate", bit_error_rate)?;
        self.params.bit_error_rate = bit_error_rate;
        self.params.key_interval = key_interval;
        self.params.codec()?;
        Ok(self)
    }

    /// Whether the boards and sources ride on a performer's deforming surface.
    pub fn on_garment_surface(&self) -> bool {
        self.garment.is_some()
    }

    fn assemble(
        skeleton: &Skeleton,
        nominal: Suit,
        true_suit: Suit,
        garment: Option<GarmentSurface>,
        floor_y: f64,
        params: SimulationParams,
        rng: &mut ChaCha8Rng,
    ) -> Result<Self> {
        let mut capsules = Vec::new();
        for (j, joint) in skeleton.joints().iter().enumerate() {
            let r = capsule_radius(&joint.name);
            if let Some(e) = joint.end_site {
                capsules.push(Capsule {
                    joint: j,
                    tip: e,
                    radius: r,
                });
            }
            for c in skeleton.children(j) {
                capsules.push(Capsule {
                    joint: j,
                    tip: skeleton.joints()[c].offset,
                    radius: r,
                });
            }
        }
        let source_lags_s = (0..nominal.sources().len())
            .map(|_| 20e-6 + 10e-6 * rng.random::<f64>())
            .collect();
        let slide_dir = nominal
            .boards()
            .iter()
            .map(|b| b.offset.normalize_or_zero())
            .collect();
        Ok(SuitSimulator {
            skeleton: skeleton.clone(),
            nominal,
            true_suit,
            garment,
            floor_y,
            params,
            ultrasound: UltrasoundParams::default(),
            capsules,
            slide_dir,
            source_lags_s,
        })
    }

    /// The nominal suit (what the filter is told).
    pub fn nominal_suit(&self) -> &Suit {
        &self.nominal
    }

    /// Forward kinematics at θ and the world placement of every board and source: on the
    /// garment surface, or fixed to the bone (plus the slide rule).
    fn placement(&self, theta: &[f64]) -> Result<(ForwardKinematics, GarmentPose)> {
        let fk = self.skeleton.forward_kinematics(theta)?;
        if let Some(g) = &self.garment {
            let pose = g.pose(theta)?;
            return Ok((fk, pose));
        }
        let (mut board_positions, mut board_rotations) = (Vec::new(), Vec::new());
        for (b, board) in self.true_suit.boards().iter().enumerate() {
            let slide: f64 = self
                .skeleton
                .joint_dofs(board.joint)
                .filter(|&d| self.skeleton.is_rotation(d))
                .map(|d| theta[d])
                .sum::<f64>()
                * self.params.skin_slide_m_per_rad;
            let mut p = board.point();
            p.offset += self.slide_dir[b] * slide;
            board_positions.push(fk.point(&p)?);
            board_rotations.push(fk.frame_rotation(&board.frame())?);
        }
        let source_positions = self
            .true_suit
            .sources()
            .iter()
            .map(|s| fk.point(&s.point()))
            .collect::<std::result::Result<_, _>>()?;
        let source_normals = self
            .true_suit
            .sources()
            .iter()
            .map(|s| fk.world_from_joint()[s.joint].matrix3 * s.normal)
            .collect();
        Ok((
            fk,
            GarmentPose {
                board_positions,
                board_rotations,
                source_positions,
                source_normals,
            },
        ))
    }

    /// The piezo burst: 10 cycles with exponential ring-up, then ring-down (τ = 60 µs).
    fn burst(t: f64) -> f64 {
        const TAU_S: f64 = 60e-6;
        let len = PULSE_CYCLES as f64 / CARRIER_HZ;
        if t < 0.0 {
            return 0.0;
        }
        let env = if t < len {
            1.0 - (-t / TAU_S).exp()
        } else {
            (1.0 - (-len / TAU_S).exp()) * (-(t - len) / TAU_S).exp()
        };
        env * (TAU * CARRIER_HZ * t).sin()
    }

    /// Adds a burst arriving `delay_s` after the frame start with `amplitude`.
    fn add_burst(frame: &mut [f32], delay_s: f64, amplitude: f64, fs: f64) {
        let start = (delay_s * fs).floor().max(0.0) as usize;
        let end = (start + 200).min(frame.len());
        for (n, v) in frame.iter_mut().enumerate().take(end).skip(start) {
            *v += (amplitude * Self::burst(n as f64 / fs - delay_s)) as f32;
        }
    }

    /// Noise plus the multiplexed digital stream (13 kbit/s).
    fn background(&self, frame: &mut [f32], rng: &mut ChaCha8Rng, normal: &Normal<f64>) {
        let fs = self.ultrasound.sample_rate_hz;
        let samples_per_bit = fs / 13_000.0;
        let mut bit = 0.0;
        let mut next_bit = 0.0;
        for (n, v) in frame.iter_mut().enumerate() {
            if n as f64 >= next_bit {
                bit = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
                next_bit += samples_per_bit;
            }
            *v = (self.params.mic_noise * normal.sample(rng) + self.params.digital_crosstalk * bit)
                as f32;
        }
    }

    /// Source directivity: `0.2 + 0.8 cos` in front, a weak back lobe (0.05) behind.
    fn directivity(cos_angle: f64) -> f64 {
        if cos_angle > 0.0 {
            0.2 + 0.8 * cos_angle
        } else {
            0.05
        }
    }

    /// Static calibration (§4.3.3): every source with a microphone at 7 distances from 30 to
    /// 90 cm, at random angles within 60° of its axis, no body, a bench (no floor echo).
    ///
    /// # Errors
    /// [`Error::Empty`] if a source is never detected on the bench.
    pub fn calibrate_offsets(&self, seed: u64) -> Result<OffsetCalibration> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let normal = Normal::new(0.0, 1.0).map_err(|e| Error::InvalidParam {
            name: "normal",
            reason: e.to_string(),
        })?;
        let mut det = PulseDetector::new(self.ultrasound)?;
        let fs = self.ultrasound.sample_rate_hz;
        let c = self.ultrasound.speed_of_sound_m_s;
        let ns = self.nominal.sources().len();
        let mut shots = Vec::new();
        let mut frame = vec![0f32; SAMPLES_PER_PULSE];
        for s in 0..ns {
            let lag_s = self.source_lags_s[s];
            for i in 0..7 {
                let d = 0.3 + 0.1 * i as f64;
                let angle = (rng.random::<f64>() * 60.0).to_radians();
                self.background(&mut frame, &mut rng, &normal);
                let amp = self.params.source_amplitude / d * Self::directivity(angle.cos());
                Self::add_burst(&mut frame, d / c + lag_s, amp, fs);
                if let Some(x) = det.detect(&frame).at(Context::Source(s))? {
                    shots.push(CalibrationShot {
                        source: s,
                        inflection_sample: x.inflection_sample,
                        distance_m: d,
                    });
                }
            }
        }
        let offsets = calibrate_offsets(&shots, ns, &self.ultrasound)?;
        let loo = leave_one_out_errors_m(&shots, ns, &self.ultrasound)?;
        let snr = 20.0 * (self.params.source_amplitude / 0.9 / self.params.mic_noise).log10();
        Ok(OffsetCalibration {
            offsets,
            loo_abs_errors_m: loo.iter().map(|e| e.abs()).collect(),
            snr_db_at_90cm: snr,
        })
    }
}

/// Per-frame geometry kept for the ultrasonic pass.
struct Geometry {
    boards: Vec<DVec3>,
    sources: Vec<DVec3>,
    normals: Vec<DVec3>,
    capsules: Vec<(DVec3, DVec3)>,
}

fn lerp_geometry(a: &Geometry, b: &Geometry, u: f64) -> Geometry {
    let l = |x: &[DVec3], y: &[DVec3]| -> Vec<DVec3> {
        x.iter().zip(y).map(|(p, q)| p.lerp(*q, u)).collect()
    };
    Geometry {
        boards: l(&a.boards, &b.boards),
        sources: l(&a.sources, &b.sources),
        normals: l(&a.normals, &b.normals),
        capsules: a
            .capsules
            .iter()
            .zip(&b.capsules)
            .map(|(p, q)| (p.0.lerp(q.0, u), p.1.lerp(q.1, u)))
            .collect(),
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
        let mut gyro_bias = vec![DVec3::ZERO; nb];
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
                gyro_bias[b] += DVec3::new(
                    normal.sample(&mut rng),
                    normal.sample(&mut rng),
                    normal.sample(&mut rng),
                ) * (p.gyro_bias_walk * dt.sqrt());
                let values = [
                    w.x + gyro_bias[b].x,
                    w.y + gyro_bias[b].y,
                    w.z + gyro_bias[b].z,
                    f.x,
                    f.y,
                    f.z,
                ];
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
        let mut rec = SimulatedRecording {
            frames: out_frames,
            truth,
            root: roots,
            rest_frames,
            nominal_suit: self.nominal.clone(),
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
                    if let Some(f) = rec.frames.get_mut(k) {
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

/// CPU time of the calling thread, seconds (0 where the platform cannot tell).
fn thread_cpu_s() -> f64 {
    cpu_time::ThreadTime::try_now().map_or(0.0, |t| t.as_duration().as_secs_f64())
}

/// The §4.4.4 start of a filter run on `rec`: the truth's first pose as the rest pose, the
/// initialisation from the rest hold's readings, the root's DOFs known when supplied.
///
/// # Errors
/// Errors of [`crate::initialise`] and of the filter's construction.
pub fn start_filter(
    skeleton: &Skeleton,
    rec: &SimulatedRecording,
    params: crate::FilterParams,
    root_supplied: bool,
) -> Result<(crate::SkeletalEkf, crate::Initialisation)> {
    let rest_pose = &rec.truth[0].theta;
    let rest: Vec<_> = rec.frames[..rec.rest_frames.max(1)]
        .iter()
        .map(|f| f.inertial.clone())
        .collect();
    let init = crate::initialise(skeleton, &rec.nominal_suit, rest_pose, &rest)?;
    let known: Vec<usize> = if root_supplied {
        skeleton.joint_dofs(0).collect()
    } else {
        Vec::new()
    };
    let ekf = crate::SkeletalEkf::new(
        skeleton.clone(),
        init.suit.clone(),
        rest_pose,
        params,
        &known,
    )?
    .with_gyro_offsets(init.gyro_offsets.clone())?;
    Ok((ekf, init))
}

/// Initialises (§4.4.4, on the rest hold) and runs the EKF over `rec` with `params`,
/// supplying the root DOFs if `root_supplied`, and scores `joints` against the truth on every
/// frame after the rest hold.
///
/// # Errors
/// As [`crate::initialise`], [`crate::SkeletalEkf::new`] and [`crate::SkeletalEkf::step`]
/// (with the frame in [`Error::At`]); [`Error::Empty`] for a recording no longer than its rest
/// hold.
pub fn run_filter(
    skeleton: &Skeleton,
    rec: &SimulatedRecording,
    params: crate::FilterParams,
    root_supplied: bool,
    joints: &[usize],
) -> Result<FilterRun> {
    use crate::{joint_orientation_errors_deg, joint_swing_twist_errors_deg, ErrorStats};
    if rec.frames.len() <= rec.rest_frames + 1 {
        return Err(Error::Empty {
            what: "frames after the rest hold",
        });
    }
    for &j in joints {
        skin_core::check::index("joint", j, skeleton.joint_count())?;
    }
    let (t0, c0) = (Instant::now(), thread_cpu_s());
    let (mut ekf, _) = start_filter(skeleton, rec, params, root_supplied)?;
    let (mut diverged, mut used) = (0, 0);
    // The estimates are kept and scored after the loop, so that the timing is the filter's.
    let mut estimates = Vec::with_capacity(rec.frames.len() - rec.rest_frames);
    let joint_dofs: Vec<Vec<usize>> = joints
        .iter()
        .map(|&j| skeleton.joint_dofs(j).collect())
        .collect();
    let mut covariances = Vec::with_capacity(estimates.capacity());
    for (k, f) in rec.frames.iter().enumerate() {
        let r = ekf
            .step(f, root_supplied.then(|| &rec.root[k]))
            .at(Context::Frame(k))?;
        diverged += usize::from(r.diverged);
        used += r.distances_used;
        if k >= rec.rest_frames {
            estimates.push(ekf.theta().to_vec());
            let cov = joint_dofs
                .iter()
                .map(|d| ekf.theta_covariance(d))
                .collect::<Result<Vec<_>>>()?;
            covariances.push(cov);
        }
    }
    let (ekf_s, ekf_cpu_s) = (t0.elapsed().as_secs_f64(), thread_cpu_s() - c0);
    let mut errors = vec![Vec::new(); joints.len()];
    let mut nees = vec![0.0; joints.len()];
    let mut swing_twist = vec![[0.0; 2]; joints.len()];
    for (i, (est, cov)) in estimates.iter().zip(&covariances).enumerate() {
        let truth = &rec.truth[rec.rest_frames + i].theta;
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
        sensors: params.sensors.label(),
        root_supplied,
        errors_deg: errors,
        stats,
        diverged_frames: diverged,
        ekf_s,
        ekf_cpu_s,
        distances_used: used,
        innovations: ekf.innovation_stats().clone(),
        nees_mean,
        swing_twist_deg,
        board_noise: rec.nominal_suit.board_noise().to_vec(),
    })
}

/// A first filter pass with `params` over the rest hold and the first `seconds` of motion:
/// the filter at its end, the §4.4.4 initialisation, the estimated poses after the rest hold
/// and the frame it stopped at.
fn first_pass(
    skeleton: &Skeleton,
    rec: &SimulatedRecording,
    params: crate::FilterParams,
    root_supplied: bool,
    seconds: f64,
) -> Result<(
    crate::SkeletalEkf,
    crate::Initialisation,
    Vec<Vec<f64>>,
    usize,
)> {
    if rec.frames.len() <= rec.rest_frames + 2 {
        return Err(Error::Empty {
            what: "frames after the rest hold",
        });
    }
    non_negative("seconds", seconds)?;
    let (mut ekf, init) = start_filter(skeleton, rec, params, root_supplied)?;
    let end =
        (rec.rest_frames + (seconds * INERTIAL_RATE_HZ).round() as usize).min(rec.frames.len());
    let mut poses = Vec::with_capacity(end - rec.rest_frames);
    for (k, f) in rec.frames[..end].iter().enumerate() {
        ekf.step(f, root_supplied.then(|| &rec.root[k]))
            .at(Context::Frame(k))?;
        if k >= rec.rest_frames {
            poses.push(ekf.theta().to_vec());
        }
    }
    Ok((ekf, init, poses, end))
}

/// The per-board heading step beyond §4.4.4 ([`crate::refine_headings`]) on a recording: a
/// first filter pass with `params` over the rest hold and the first `seconds` of motion, the
/// heading fit on its estimated poses, and the suit so refined. Returns the refinement; its
/// `suit` replaces `rec.nominal_suit` for the real run (§4.4.4's tilt alignment then leaves
/// it as it is: the turn is about the measured up axis).
///
/// # Errors
/// [`Error::Empty`] if the recording has no frames after the rest hold; as [`run_filter`]
/// and [`crate::refine_headings`].
pub fn refine_recording_headings(
    skeleton: &Skeleton,
    rec: &SimulatedRecording,
    params: crate::FilterParams,
    root_supplied: bool,
    seconds: f64,
) -> Result<crate::HeadingRefinement> {
    let (_, init, poses, end) = first_pass(skeleton, rec, params, root_supplied, seconds)?;
    let readings: Vec<_> = rec.frames[rec.rest_frames..end]
        .iter()
        .map(|f| f.inertial.clone())
        .collect();
    crate::refine_headings(
        skeleton,
        &init.suit,
        &rec.truth[0].theta,
        &poses,
        &readings,
        &init.gyro_offsets,
        1.0 / INERTIAL_RATE_HZ,
    )
}

/// The first pass of the per-board noise estimates: `rec` with the global σ (a suit's own
/// per-board σ set aside).
fn global_sigma_first_pass(
    skeleton: &Skeleton,
    rec: &SimulatedRecording,
    params: crate::FilterParams,
    root_supplied: bool,
    seconds: f64,
) -> Result<crate::SkeletalEkf> {
    let plain;
    let rec = if rec.nominal_suit.board_noise().is_empty() {
        rec
    } else {
        let mut r = rec.clone();
        r.nominal_suit = r.nominal_suit.with_board_noise(Vec::new())?;
        plain = r;
        &plain
    };
    Ok(first_pass(skeleton, rec, params, root_supplied, seconds)?.0)
}

/// Per-board measurement noise estimated from the data ([`crate::board_noise_from_innovations`],
/// beyond §4.4.2): a first filter pass with `params`' global σ over the rest hold and the first `seconds` of motion, each board's σ
/// set from its innovation statistics (a suit's own per-board σ are set aside for the pass).
/// Put the result on `rec.nominal_suit`
/// ([`crate::Suit::with_board_noise`]) for the real run; the truth is not read.
///
/// # Errors
/// As [`refine_recording_headings`] and [`crate::board_noise_from_innovations`].
pub fn estimate_recording_board_noise(
    skeleton: &Skeleton,
    rec: &SimulatedRecording,
    params: crate::FilterParams,
    root_supplied: bool,
    seconds: f64,
) -> Result<Vec<crate::BoardNoise>> {
    let ekf = global_sigma_first_pass(skeleton, rec, params, root_supplied, seconds)?;
    crate::board_noise_from_innovations(
        ekf.innovation_stats(),
        rec.nominal_suit.boards().len(),
        &params,
    )
}

/// [`estimate_recording_board_noise`] with one σ per board axis
/// ([`crate::board_axis_noise_from_innovations`]; issue 15, seventh session): the same first
/// pass, each board's gyroscope and accelerometer axes scaled by their own NIS.
///
/// # Errors
/// As [`estimate_recording_board_noise`].
pub fn estimate_recording_board_axis_noise(
    skeleton: &Skeleton,
    rec: &SimulatedRecording,
    params: crate::FilterParams,
    root_supplied: bool,
    seconds: f64,
) -> Result<Vec<crate::BoardNoise>> {
    let ekf = global_sigma_first_pass(skeleton, rec, params, root_supplied, seconds)?;
    crate::board_axis_noise_from_innovations(
        ekf.axis_innovation_stats(),
        rec.nominal_suit.boards().len(),
        &params,
    )
}

/// [`run_filter`] after [`estimate_recording_board_noise`]: per-board measurement noise
/// from a first pass (same `params`, `root_supplied`) over the rest hold and the first
/// `seconds` of motion, then the whole recording with the suit so set. The run's
/// [`FilterRun::board_noise`] holds the σ used; its `ekf_s` and `ekf_cpu_s` include the first
/// pass.
///
/// # Errors
/// As [`estimate_recording_board_noise`] and [`run_filter`].
pub fn run_filter_board_noise(
    skeleton: &Skeleton,
    rec: &SimulatedRecording,
    params: crate::FilterParams,
    root_supplied: bool,
    joints: &[usize],
    seconds: f64,
) -> Result<FilterRun> {
    let (t0, c0) = (Instant::now(), thread_cpu_s());
    let noise = estimate_recording_board_noise(skeleton, rec, params, root_supplied, seconds)?;
    let (first_s, first_cpu_s) = (t0.elapsed().as_secs_f64(), thread_cpu_s() - c0);
    let mut adapted = rec.clone();
    adapted.nominal_suit = adapted.nominal_suit.with_board_noise(noise)?;
    let mut run = run_filter(skeleton, &adapted, params, root_supplied, joints)?;
    run.ekf_s += first_s;
    run.ekf_cpu_s += first_cpu_s;
    Ok(run)
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

/// Shortest gait cycle [`treadmill_motion`] loops, seconds (a stride is ≈ 1 s).
pub const TREADMILL_MIN_CYCLE_S: f64 = 0.8;

/// A treadmill-like motion (Figure 4-7) from a walk: a gait cycle of the walk looped until
/// `duration_s`, the root's horizontal translation removed (the treadmill) and its yaw held
/// at the first frame's.
///
/// **The loop.** The cycle is the pair of frames `i < j`, at least
/// [`TREADMILL_MIN_CYCLE_S`] apart, whose poses *and* velocities agree best over every DOF
/// except the three held ones: cost `‖θᵢ − θⱼ‖² + (τ/Δt)² ‖Δθᵢ − Δθⱼ‖²` with τ = 0.1 s
/// (the usual motion-graph transition cost, Kovar et al. 2002, on joint angles). Frames
/// `i … j−1` repeat; the residual `θᵢ − θⱼ` is spread linearly over each cycle, so the
/// looped motion is continuous in angle and, up to the chosen residual, in rate. (An earlier
/// version played the walk forwards and backwards: every reversal flipped all joint rates in
/// one frame, an impulse no body and no constant-acceleration filter follows — it made even
/// the oracle filter diverge on the treadmill.) Only stretches over which the root travels at
/// [`TREADMILL_MIN_SPEED_M_S`] or more are candidates: a pause matches itself best of all.
///
/// # Errors
/// As [`Motion::check_for`]; [`Error::InvalidParam`] for a skeleton without the human root
/// DOFs, a non-positive duration or a walk shorter than two cycles' search needs.
pub fn treadmill_motion(skeleton: &Skeleton, walk: &Motion, duration_s: f64) -> Result<Motion> {
    walk.check_for(skeleton)?;
    positive("duration_s", duration_s)?;
    let find = |name: &'static str| {
        skeleton.dof_index(name).ok_or(Error::InvalidParam {
            name: "skeleton",
            reason: format!("no DOF {name}"),
        })
    };
    let (tx, tz, yaw) = (find("pelvis.tx")?, find("pelvis.tz")?, find("pelvis.yaw")?);
    let (n, nd) = (walk.frame_count(), skeleton.dof_count());
    let dt = walk.frame_time_s;
    let min_len = (TREADMILL_MIN_CYCLE_S / dt).round().max(2.0) as usize;
    if n < min_len + 2 {
        return Err(Error::InvalidParam {
            name: "walk",
            reason: format!(
                "{n} frames: a gait cycle needs at least {} ({TREADMILL_MIN_CYCLE_S} s)",
                min_len + 2
            ),
        });
    }
    let looped: Vec<usize> = (0..nd)
        .filter(|&d| d != tx && d != tz && d != yaw)
        .collect();
    let (start, end) = gait_cycle(walk, &looped, (tx, tz), min_len)?;
    let len = end - start;
    let total = (duration_s / dt).round() as usize + 1;
    let mut frames = DMatrix::zeros(nd, total);
    for k in 0..total {
        let m = k % len;
        let src = start + m;
        let ramp = m as f64 / len as f64;
        for &d in &looped {
            let residual = walk.frames[(d, start)] - walk.frames[(d, end)];
            frames[(d, k)] = walk.frames[(d, src)] + ramp * residual;
        }
        frames[(tx, k)] = walk.frames[(tx, 0)];
        frames[(tz, k)] = walk.frames[(tz, 0)];
        frames[(yaw, k)] = walk.frames[(yaw, 0)];
    }
    Ok(Motion::new(dt, frames)?)
}

/// Least average root speed of a looped cycle, m/s: a walking cycle, not a pause (a standing
/// stretch matches itself best of all).
pub const TREADMILL_MIN_SPEED_M_S: f64 = 0.5;

/// The frames `(i, j)` of [`treadmill_motion`]'s loop: the lowest transition cost over the
/// `looped` DOFs among pairs at least `min_len` frames apart over which the root (DOFs
/// `root_xz`) travels at [`TREADMILL_MIN_SPEED_M_S`] or more on average.
fn gait_cycle(
    walk: &Motion,
    looped: &[usize],
    root_xz: (usize, usize),
    min_len: usize,
) -> Result<(usize, usize)> {
    let n = walk.frame_count();
    let dt = walk.frame_time_s;
    let w = (0.1 / dt).powi(2);
    let f = &walk.frames;
    let cost = |i: usize, j: usize| -> f64 {
        looped
            .iter()
            .map(|&d| {
                let (a, b) = (f[(d, i)], f[(d, j)]);
                let (va, vb) = (f[(d, i + 1)] - a, f[(d, j + 1)] - b);
                (a - b).powi(2) + w * (va - vb).powi(2)
            })
            .sum()
    };
    let travel = |i: usize, j: usize| {
        let (x, z) = root_xz;
        (f[(x, j)] - f[(x, i)]).hypot(f[(z, j)] - f[(z, i)])
    };
    let mut best: Option<(f64, usize, usize)> = None;
    for i in 0..n.saturating_sub(1 + min_len) {
        for j in i + min_len..n - 1 {
            if travel(i, j) < TREADMILL_MIN_SPEED_M_S * (j - i) as f64 * dt {
                continue;
            }
            let c = cost(i, j);
            if best.is_none_or(|(b, _, _)| c < b) {
                best = Some((c, i, j));
            }
        }
    }
    best.map(|(_, i, j)| (i, j)).ok_or(Error::InvalidParam {
        name: "walk",
        reason: format!(
            "no stretch of at least {:.2} s in which the root travels at {TREADMILL_MIN_SPEED_M_S} m/s",
            min_len as f64 * dt
        ),
    })
}

/// Oracle observations (diagnosis of the filter, not a simulation of the suit): the
/// filter's OWN measurement models evaluated along the true trajectory of `motion` with
/// `suit` — gyroscopes by Eq. 4.3 (`Rᵀ J_ω θ̇`), accelerometers by Eq. 4.2
/// (`Rᵀ (J θ̈ + J̇θ̇ + g)`), distances by Eq. 4.4 (`‖p_i − p_j‖`, one source per frame in
/// turn, every microphone in its field of view, confidence 1, no age) — without noise,
/// bias, quantisation, placement error or skin motion. A filter fed these must track the
/// truth to within its own lag; if it does not, the error is in the filter (dynamics,
/// Jacobians, initialisation), not in the sensing. `rest_s` is the rest hold at the start of
/// `motion` (as [`prepare_motion`] put it there).
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
    Ok(SimulatedRecording {
        frames: out,
        truth,
        root: roots,
        rest_frames: (rest_s / dt).floor() as usize,
        nominal_suit: suit.clone(),
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

#[cfg(test)]
mod tests {
    use super::*;
    use skin_core::skeleton::{human_skeleton, HumanParams};

    /// §4.2.3's accumulation of four 10-bit samples gives a 12-bit quantity only with dither:
    /// a constant rate 0.3 of a 10-bit step above a bin centre reads as the bin without analog
    /// noise (bias 1.2 counts), and to a tenth of a count with half a step of analog noise.
    #[test]
    fn dither_makes_the_accumulated_counts_twelve_bit() {
        let normal = Normal::new(0.0, 1.0).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let slope = 4096.0 / 40.0; // ±20 rad/s
        let step10 = 4.0 / slope;
        let value = 0.3 * step10; // zero at 2048, a bin centre of the 10-bit converter
        let mean_error = |noise: f64, rng: &mut ChaCha8Rng| {
            let ch = Channel {
                zero: 2048.0,
                slope,
                noise,
                accumulate: true,
            };
            let n = 20_000;
            let sum: f64 = (0..n)
                .map(|_| f64::from(ch.count(value, rng, &normal)))
                .sum();
            sum / f64::from(n) - (2048.0 + slope * value)
        };
        let plain = mean_error(0.002, &mut rng);
        let dithered = mean_error(0.002f64.hypot(0.5 * step10), &mut rng);
        assert!((plain + 1.2).abs() < 0.05, "no dither: bias {plain} counts");
        assert!(dithered.abs() < 0.1, "dither: bias {dithered} counts");
    }

    #[test]
    fn spline_reproduces_a_parabola_inside() {
        let h = 0.05;
        let y = DMatrix::from_fn(1, 41, |_, k| (k as f64 * h).powi(2));
        let s = SmoothMotion::new(h, y);
        let (mut a, mut b, mut c) = ([0.0], [0.0], [0.0]);
        s.eval(1.0, &mut a, &mut b, &mut c);
        assert!(
            (a[0] - 1.0).abs() < 1e-4 && (b[0] - 2.0).abs() < 1e-3 && (c[0] - 2.0).abs() < 0.02
        );
    }

    #[test]
    fn segment_distance_cases() {
        let d = segment_distance(
            DVec3::ZERO,
            DVec3::X,
            DVec3::new(0.5, 1.0, -1.0),
            DVec3::new(0.5, 1.0, 1.0),
        );
        assert!((d - 1.0).abs() < 1e-12);
    }

    #[test]
    fn still_suit_reads_gravity_and_bench_calibration_is_millimetric() {
        let s = human_skeleton(&HumanParams::default()).unwrap();
        let sim = SuitSimulator::new(&s, SimulationParams::default()).unwrap();
        let cal = sim.calibrate_offsets(3).unwrap();
        let mean = cal.loo_abs_errors_m.iter().sum::<f64>() / cal.loo_abs_errors_m.len() as f64;
        assert!(mean < 0.0025, "LOO mean {mean}");
        let still = Motion::new(1.0 / 30.0, DMatrix::zeros(s.dof_count(), 10)).unwrap();
        let motion = prepare_motion(&s, &still, &SimulationParams::default()).unwrap();
        let rec = sim.record(&motion, &cal.offsets).unwrap();
        assert!(rec.pulses_heard > 0);
        // The default front end is the noise-shaped 16-count code:
        // one frame's reading is off by the difference of two round-offs, up to 16 counts per
        // axis (0.16 rad/s, 0.46 m/s²) by design, σ 16/√6 counts (`code_noise`), and the mean
        // over frames is exact to a step over their number. So a single frame is held to the
        // code's documented bound (plus 5σ of the sensor noise), and the mean over 0.5 s (70
        // frames) to the bounds the whole-count code meets per frame (0.05 rad/s, 0.3 m/s²):
        // a biased code or calibration would still fail them.
        let (sg, sa) = SimulationParams::default().code_noise().unwrap();
        let step = f64::from(SimulationParams::DEFAULT_DELTA_STEP);
        let (gyro_count, accel_count) = (40.0 / 4096.0, 6.0 * GRAVITY_M_S2 * 2.0 / 4096.0);
        assert!((sg - step / 6f64.sqrt() * gyro_count).abs() < 1e-12);
        assert!((sa - step / 6f64.sqrt() * accel_count).abs() < 1e-12);
        // With key frames each channel's two key frames of every
        // `key_interval` are flagged unsynced (extrapolated, not readings): skipped here as
        // the filter skips them, and counted.
        let window = 10..80;
        let value = |r: &InertialReading, c: usize| {
            if c < 3 {
                r.gyro_rad_s[c]
            } else {
                r.accel_m_s2[c - 3]
            }
        };
        let (mut sum, mut used) = ([0.0f64; CHANNELS], [0usize; CHANNELS]);
        for k in window.clone() {
            let r = rec.frames[k].inertial[0].unwrap();
            for c in (0..CHANNELS).filter(|&c| !r.saturated[c]) {
                sum[c] += value(&r, c);
                used[c] += 1;
            }
        }
        let flagged = CHANNELS * window.len() - used.iter().sum::<usize>();
        let keys = 2 * CHANNELS * window.len() / SimulationParams::DEFAULT_KEY_INTERVAL as usize;
        assert!(
            flagged.abs_diff(keys) <= CHANNELS,
            "{flagged} flagged, {keys} key frames"
        );
        let mean: [f64; CHANNELS] = std::array::from_fn(|c| sum[c] / used[c] as f64);
        for k in window.clone() {
            let r = rec.frames[k].inertial[0].unwrap();
            for c in (0..CHANNELS).filter(|&c| !r.saturated[c]) {
                let (bound, off) = if c < 3 {
                    (1.05 * step * gyro_count + 0.05, value(&r, c).abs())
                } else {
                    (
                        1.05 * step * accel_count + 0.3,
                        (value(&r, c) - mean[c]).abs(),
                    )
                };
                assert!(off < bound, "frame {k} channel {c}: {off} ≥ {bound}");
            }
        }
        let gyro_mean = DVec3::new(mean[0], mean[1], mean[2]);
        let accel_mean = DVec3::new(mean[3], mean[4], mean[5]);
        assert!(
            (accel_mean.length() - GRAVITY_M_S2).abs() < 0.3,
            "{accel_mean}"
        );
        assert!(gyro_mean.length() < 0.05, "{gyro_mean}");

        // The whole-count code (an option, the earlier default) still reads each frame to
        // the per-frame bounds.
        let whole = SimulationParams {
            delta_step: None,
            ..SimulationParams::default()
        };
        assert_eq!(whole.code_noise().unwrap(), (0.0, 0.0));
        let sim = SuitSimulator::new(&s, whole).unwrap();
        let rec = sim.record(&motion, &cal.offsets).unwrap();
        let r = rec.frames[10].inertial[0].unwrap();
        assert!(
            (r.accel_m_s2.length() - GRAVITY_M_S2).abs() < 0.3,
            "{}",
            r.accel_m_s2
        );
        assert!(r.gyro_rad_s.length() < 0.05);
    }

    /// The treadmill loops a matched gait cycle: on a noisy periodic "walk" (1.1 s period,
    /// 4 s) its largest change of any joint rate between frames (second difference) stays
    /// within 1.5× the walk's own, the held root DOFs are constant, and a walk too short for
    /// a cycle is refused. The old forward–backward playback fails the first check by 20×:
    /// each reversal flips the rates in one frame.
    #[test]
    fn treadmill_loops_a_gait_cycle_without_jumps() {
        let sk = human_skeleton(&HumanParams::default()).unwrap();
        let dt = 1.0 / 120.0;
        let n = 480;
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let noise = Normal::new(0.0, 1e-4).unwrap();
        let tx = sk.dof_index("pelvis.tx").unwrap();
        let frames = DMatrix::from_fn(sk.dof_count(), n, |d, k| {
            let t = k as f64 * dt;
            if d == tx {
                return t; // walking at 1 m/s
            }
            let phase = d as f64 * 0.7;
            0.4 * (TAU * t / 1.1 + phase).sin()
                + 0.05 * t * (d % 2) as f64 / 4.0
                + noise.sample(&mut rng)
        });
        let walk = Motion::new(dt, frames).unwrap();
        let tread = treadmill_motion(&sk, &walk, 20.0).unwrap();
        assert_eq!(tread.frame_count(), 2401);
        // Largest second difference (rate change per frame) of any joint angle.
        let max_jerk = |m: &Motion| {
            (1..m.frame_count() - 1)
                .flat_map(|k| (0..sk.dof_count()).map(move |d| (d, k)))
                .map(|(d, k)| {
                    (m.frames[(d, k + 1)] - 2.0 * m.frames[(d, k)] + m.frames[(d, k - 1)]).abs()
                })
                .fold(0.0, f64::max)
        };
        let (walk_jerk, tread_jerk) = (max_jerk(&walk), max_jerk(&tread));
        assert!(
            tread_jerk < walk_jerk * 1.5,
            "treadmill rate change {tread_jerk} vs walk {walk_jerk}"
        );
        for name in ["pelvis.tx", "pelvis.tz", "pelvis.yaw"] {
            let d = sk.dof_index(name).unwrap();
            assert!((0..tread.frame_count()).all(|k| tread.frames[(d, k)] == walk.frames[(d, 0)]));
        }
        let mut standing = walk.clone();
        standing.frames.row_mut(tx).fill(0.0);
        standing
            .frames
            .row_mut(sk.dof_index("pelvis.tz").unwrap())
            .fill(0.0);
        assert!(matches!(
            treadmill_motion(&sk, &standing, 20.0),
            Err(Error::InvalidParam { name: "walk", .. })
        ));
        let short = Motion::new(dt, walk.frames.columns(0, 90).into_owned()).unwrap();
        assert!(matches!(
            treadmill_motion(&sk, &short, 20.0),
            Err(Error::InvalidParam { name: "walk", .. })
        ));
    }
}
