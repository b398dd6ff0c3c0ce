// Over 1,000 lines: the motion, suit physics, recorder and filter run of one simulated recording
// share its private state.
//! Validation equipment: the suit simulated on a studio motion, down to the raw signals the
//! thesis's hardware records, then processed by this crate's own signal processing.
//!
//! * **Motion.** The motion is smoothed (binomial passes), preceded by a rest-pose hold and
//!   a smooth blend into its first frame (§4.4.4's rest pose), and interpolated by natural
//!   cubic splines so θ, θ̇, θ̈ exist at any time.
//! * **Garment.** Each board and source sits where [`Suit::vlasic`](crate::Suit::vlasic) puts it, off by a random
//!   placement error (position and orientation) the filter does not know. On a studio
//!   performer ([`SuitSimulator::on_performer`]) it is attached to the performer's skin
//!   ([`GarmentSurface`]) and moves with its pose-driven deformation; on a bare skeleton
//!   ([`SuitSimulator::new`]) it slides along its bone with the bone's joint angles instead.
//!   [`SuitSimulator::with_rigid_attachment`] fixes the same placements to the bones.
//! * **Inertial.** Accelerations by second differences of the true garment positions (an
//!   independent path from the filter's analytic `J θ̈ + J̇θ̇`), angular velocities by central
//!   differences of the boards' true orientations; the paper's white noise (0.02 m/s², 0.002
//!   rad/s), per-axis zero and
//!   slope errors, a gyroscope bias ([`GyroBiasModel`]: by default a MEMS part's turn-on
//!   offset, warm-up drift, instability and g-sensitivity; a random walk as the option), 12-bit counts (four 10-bit samples
//!   accumulated), 6-bit delta modulation with error-correcting code and scrambling, random bit
//!   errors; decoded and calibrated by the §4.3.3 procedure (±g poses and ±45 rpm turntable
//!   runs simulated with the same errors).
//! * **Ultrasonic.** Round-robin pulses every 8 ms; per microphone and pulse a 1,120-sample
//!   frame at 140 kHz: 10-cycle 40 kHz piezo bursts (exponential ring-up and ring-down),
//!   amplitude ∝ 1/r, cosine-like source directivity with a weak back lobe, a floor reflection,
//!   body occlusion (capsules around the bones), the 13 kbit/s digital stream multiplexed on
//!   the same wire, white noise; processed by [`PulseDetector`](crate::PulseDetector) with per-source offsets
//!   calibrated from static placements 30–90 cm apart.

mod bias;
mod motion;
mod physics;
mod recorder;
#[cfg(test)]
mod tests;

pub use crate::garment::{GarmentPose, GarmentSurface, MIN_PATCH, PATCH_RADIUS_M};
pub use bias::{GyroBiasModel, MemsGyroBias};
pub use motion::{
    prepare_motion, treadmill_motion, SmoothMotion, TREADMILL_MIN_CYCLE_S, TREADMILL_MIN_SPEED_M_S,
};
pub use physics::{OffsetCalibration, SuitSimulator};
pub use recorder::{model_recording, SimulatedRecording, SkinMotion, TruthFrame};

use crate::inertial::DeltaCodec;
use crate::params::GRAVITY_M_S2;
use crate::Result;
use serde::{Deserialize, Serialize};
use skin_core::check::{non_negative, positive};

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
    /// Gyroscope bias random walk, rad/s per √s, of [`GyroBiasModel::RandomWalk`] (unused by
    /// the other model). Default: 0.0005.
    pub gyro_bias_walk: f64,
    /// How the gyroscopes' bias starts and moves over a recording. Default:
    /// [`GyroBiasModel::Mems`] with [`MemsGyroBias::adxrs300`]. Parameters written without
    /// this field read back as [`GyroBiasModel::RandomWalk`], the model they were made with.
    #[serde(default = "random_walk")]
    pub gyro_bias: GyroBiasModel,
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
    /// overestimating in the next frame", slew `31 · step` counts per frame), `None` for
    /// whole-count deltas without feedback ([`DeltaCodec::new`]). Default:
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
            gyro_bias: GyroBiasModel::default(),
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

    /// With the gyroscopes' bias model replaced.
    pub fn with_gyro_bias(self, gyro_bias: GyroBiasModel) -> Self {
        SimulationParams { gyro_bias, ..self }
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
        self.gyro_bias.validate()?;
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

fn random_walk() -> GyroBiasModel {
    GyroBiasModel::RandomWalk
}

fn default_true() -> bool {
    true
}
