//! Parameters with the thesis's constants (Vlasic 2010, Chapter 4): the suit's timing and
//! ultrasonic signal processing (§4.2.2, §4.3.1) and the skeletal EKF (§4.4).

use crate::{Error, Result};
use serde::{Deserialize, Serialize};
use skin_core::check::{in_range, positive};

/// Inertial frame rate, Hz (§4.2.3: "The sampling rate of the inertial data is 140Hz").
pub const INERTIAL_RATE_HZ: f64 = 140.0;
/// Interval between pulses of consecutive sources, seconds (§4.2.2: "about 8 ms").
pub const PULSE_INTERVAL_S: f64 = 0.008;
/// Microphone samples per pulse frame (§4.3.1: 1,120 samples, i.e. 140 kHz × 8 ms; the
/// thesis's "about 150 kHz" in §4.2.1 disagrees with its own numbers).
pub const SAMPLES_PER_PULSE: usize = 1120;
/// Microphone sampling rate, Hz (`SAMPLES_PER_PULSE / PULSE_INTERVAL_S`).
pub const MIC_RATE_HZ: f64 = SAMPLES_PER_PULSE as f64 / PULSE_INTERVAL_S;
/// Ultrasonic carrier, Hz (§4.2.2: 40 kHz).
pub const CARRIER_HZ: f64 = 40_000.0;
/// Cycles per pulse (§4.2.2: "ten cycles wide").
pub const PULSE_CYCLES: usize = 10;
/// Speed of sound at 20 °C, m/s (§4.2.2: 8 ms ↔ 2.75 m gives 344 m/s).
pub const SPEED_OF_SOUND_M_S: f64 = 343.4;
/// Standard gravity, m/s².
pub const GRAVITY_M_S2: f64 = 9.806_65;

/// Ultrasonic signal processing (§4.3.1).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct UltrasoundParams {
    /// Microphone sampling rate, Hz. Default: [`MIC_RATE_HZ`] = 140 kHz.
    pub sample_rate_hz: f64,
    /// Band-pass centre, Hz. Default: 40 kHz (§4.3.1).
    pub band_centre_hz: f64,
    /// Band-pass width, Hz. Default: 5 kHz (§4.3.1: "width of 5kHz").
    pub band_width_hz: f64,
    /// Envelope low-pass cut-off, Hz. Default: 30 kHz (§4.3.1).
    pub envelope_cutoff_hz: f64,
    /// Speed of sound, m/s. Default: [`SPEED_OF_SOUND_M_S`].
    pub speed_of_sound_m_s: f64,
    /// Detection threshold on the envelope, as a multiple of the frame's noise power (the
    /// median envelope; §4.3.1 "well above the estimated ambient noise"). Default: 12.
    pub noise_factor: f64,
    /// Normalised signal strength (envelope peak × r², in units of the noise power × m²) at
    /// and above which `w_s = 1`; below, `w_s = (value / threshold)²` (§4.3.1). Default: 400.
    pub strength_threshold: f64,
    /// Jump of one pair's distance between its consecutive pulses (64 ms apart) up to which
    /// `w_t = 1`, metres; beyond, `w_t = threshold / jump` squared (§4.3.1). Default: 0.05.
    pub continuity_threshold_m: f64,
}

impl Default for UltrasoundParams {
    fn default() -> Self {
        UltrasoundParams {
            sample_rate_hz: MIC_RATE_HZ,
            band_centre_hz: CARRIER_HZ,
            band_width_hz: 5_000.0,
            envelope_cutoff_hz: 30_000.0,
            speed_of_sound_m_s: SPEED_OF_SOUND_M_S,
            noise_factor: 12.0,
            strength_threshold: 400.0,
            continuity_threshold_m: 0.05,
        }
    }
}

impl UltrasoundParams {
    /// Checks every field.
    ///
    /// # Errors
    /// [`Error::InvalidParam`] (through [`skin_core::check`]) for a non-positive or non-finite
    /// value, or a band or cut-off at or above the Nyquist frequency.
    pub fn validate(&self) -> Result<()> {
        let nyquist = 0.5 * positive("sample_rate_hz", self.sample_rate_hz)?;
        positive("band_width_hz", self.band_width_hz)?;
        in_range(
            "band_centre_hz",
            self.band_centre_hz,
            self.band_width_hz..=nyquist - self.band_width_hz,
        )?;
        in_range(
            "envelope_cutoff_hz",
            self.envelope_cutoff_hz,
            1.0..=nyquist * 0.99,
        )?;
        positive("speed_of_sound_m_s", self.speed_of_sound_m_s)?;
        positive("noise_factor", self.noise_factor)?;
        positive("strength_threshold", self.strength_threshold)?;
        positive("continuity_threshold_m", self.continuity_threshold_m)?;
        Ok(())
    }
}

/// Which observation types the EKF uses (the rows of Table 4.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct SensorSet {
    /// Accelerometers (Eq. 4.2).
    pub accelerometers: bool,
    /// Gyroscopes (Eq. 4.3).
    pub gyroscopes: bool,
    /// Ultrasonic distances (Eq. 4.4).
    pub distances: bool,
}

impl SensorSet {
    /// All three (A+G+D).
    pub const ALL: SensorSet = SensorSet {
        accelerometers: true,
        gyroscopes: true,
        distances: true,
    };

    /// The seven combinations of Table 4.1 in its order: A, A+D, D, G, G+D, A+G, A+G+D.
    pub fn table_4_1() -> [SensorSet; 7] {
        let s = |a, g, d| SensorSet {
            accelerometers: a,
            gyroscopes: g,
            distances: d,
        };
        [
            s(true, false, false),
            s(true, false, true),
            s(false, false, true),
            s(false, true, false),
            s(false, true, true),
            s(true, true, false),
            s(true, true, true),
        ]
    }

    /// Table 4.1's label, e.g. `"A+G+D"`.
    pub fn label(&self) -> String {
        let mut parts = Vec::new();
        if self.accelerometers {
            parts.push("A");
        }
        if self.gyroscopes {
            parts.push("G");
        }
        if self.distances {
            parts.push("D");
        }
        parts.join("+")
    }
}

/// Down-weighting of large normalised distance innovations `e = ν/√s` in the scalar update
/// (M-estimation as an iteratively inflated R; not in the thesis): the update uses
/// `s' = s · ρ(e)` instead of `s`, which bounds (Huber) or removes (Cauchy) the pull of a
/// distance far from the prediction — a detection of a longer path (floor echo, the pulse
/// around an occluding limb) the confidence missed.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub enum RobustLoss {
    /// Plain Kalman update (`s' = s`), as the thesis's filter.
    #[default]
    None,
    /// Huber: `s' = s · |e| / k` where `|e| > k` — the correction is capped at `k`
    /// standard deviations.
    Huber {
        /// Threshold in standard deviations (1.345 is the usual 95 %-efficiency value).
        k: f64,
    },
    /// Cauchy: `s' = s · (1 + e² / c²)` — the correction falls off as `1/|e|` far out.
    Cauchy {
        /// Scale in standard deviations (2.385 is the usual 95 %-efficiency value).
        c: f64,
    },
}

impl RobustLoss {
    /// The factor `s' / s` for a normalised innovation `e` (≥ 1).
    pub fn inflation(&self, e: f64) -> f64 {
        match *self {
            RobustLoss::None => 1.0,
            RobustLoss::Huber { k } => (e.abs() / k).max(1.0),
            RobustLoss::Cauchy { c } => 1.0 + (e / c).powi(2),
        }
    }
}

/// The skeletal EKF (§4.4).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FilterParams {
    /// Frame step, seconds. Default: 1/140 (§4.2.3).
    pub frame_time_s: f64,
    /// Standard deviation of the acceleration change per frame (Eq. 4.1's `w`), rad/s² (m/s²
    /// for translations). Default: 0.04 (§4.4.1: "Setting this value to 0.04 rad/s^2 works
    /// well").
    pub process_sigma: f64,
    /// Accelerometer noise, m/s². Default: 0.02 (§4.4.2).
    pub accelerometer_sigma: f64,
    /// Gyroscope noise, rad/s. Default: 0.002 (§4.4.2).
    pub gyroscope_sigma: f64,
    /// Distance noise at confidence 1, metres; divided by the confidence. Default: 0.0025
    /// (§4.4.2).
    pub distance_sigma_m: f64,
    /// Distances with a lower confidence are not used. Default: 0.05.
    pub min_confidence: f64,
    /// Distances whose innovation exceeds this many standard deviations of its predicted
    /// spread are rejected (reflections the confidence missed); 0 disables the gate.
    /// Default: 0 (the thesis has no gate).
    pub distance_gate_sigma: f64,
    /// Initial standard deviation of θ, θ̇ and θ̈ (rad, rad/s, rad/s²). Default:
    /// (0.02, 0.05, 0.5) — the subject holds the known rest pose (§4.4.4).
    pub initial_sigma: (f64, f64, f64),
    /// Gravity, m/s², along −y (the skeleton's up axis is +y). Default: [`GRAVITY_M_S2`].
    pub gravity_m_s2: f64,
    /// The sensors used.
    pub sensors: SensorSet,
    /// A joint rate above this (rad/s, or m/s for translations) is divergence: the filter is
    /// reset to its last good pose at rest and the frame is flagged. Default: 60.
    pub divergence_rate: f64,
    /// Local parameterisation of the 3-DOF joints (shoulders, hips, spine): when one of a
    /// joint's angles leaves ±this (rad), its rotation is folded into the filter's skeleton
    /// and its angles restart at zero, away from the Euler singularity at ±90° (module docs
    /// of the EKF). 0 keeps the skeleton's Euler angles throughout, as the thesis's filter
    /// does. Default: 0 (with the thesis's process noise the Euler chart tracked better in a
    /// four-seed study; at the tuned, larger process noise 0.3 did — `docs/inertial-acoustic.md`,
    /// Parameters).
    #[serde(default)]
    pub recentre_rad: f64,
    /// Time update of θ as Eq. 4.1 prints it, `θ + Δt θ̇` (the first-order step), instead of
    /// the exact transition of the constant-acceleration model it discretises,
    /// `θ + Δt θ̇ + ½Δt² θ̈`. The first-order step's missing `½Δt² θ̈` biases every step;
    /// on a periodic walk that bias makes even perfect measurements drift (left shoulder
    /// 2 → 52° over 60 s of the oracle treadmill walk). Default: false (exact).
    #[serde(default)]
    pub first_order_step: bool,
    /// Down-weighting of large distance innovations (after the gate). Default:
    /// [`RobustLoss::None`] (the thesis's update).
    #[serde(default)]
    pub distance_robust: RobustLoss,
    /// Skip the scalar inertial rows whose channel the decoder flagged as saturated
    /// ([`crate::InertialReading::saturated`]: clipped at full scale, or a delta at the 6-bit
    /// code's extreme). Beyond the thesis, which does not discuss saturation: such a value is
    /// only a bound (the true rate or force is at least as far), so the filter does not read it
    /// as a measurement and lets the dynamics carry the state through it. Default: true —
    /// measured better on the exercise motion (`inertial_capture --quick`, garment A+G+D
    /// neck / shoulder / hip 8.03 / 5.45 / 5.14 → 6.09 / 4.77 / 3.51°); on the treadmill walk,
    /// where the simulated front end saturates on most of the hand's frames, it does not help.
    /// False: every row used, as the thesis's filter does.
    #[serde(default = "default_true")]
    pub skip_saturated: bool,
}

fn default_true() -> bool {
    true
}

impl Default for FilterParams {
    fn default() -> Self {
        FilterParams {
            frame_time_s: 1.0 / INERTIAL_RATE_HZ,
            process_sigma: 0.04,
            accelerometer_sigma: 0.02,
            gyroscope_sigma: 0.002,
            distance_sigma_m: 0.0025,
            min_confidence: 0.05,
            distance_gate_sigma: 0.0,
            initial_sigma: (0.02, 0.05, 0.5),
            gravity_m_s2: GRAVITY_M_S2,
            sensors: SensorSet::ALL,
            divergence_rate: 60.0,
            recentre_rad: 0.0,
            first_order_step: false,
            distance_robust: RobustLoss::None,
            skip_saturated: true,
        }
    }
}

impl FilterParams {
    /// With `sensors` replaced.
    pub fn with_sensors(self, sensors: SensorSet) -> Self {
        FilterParams { sensors, ..self }
    }

    /// With `process_sigma` replaced.
    pub fn with_process_sigma(self, process_sigma: f64) -> Self {
        FilterParams {
            process_sigma,
            ..self
        }
    }

    /// With the three measurement noises replaced (accelerometer m/s², gyroscope rad/s,
    /// distance m).
    pub fn with_measurement_sigmas(self, accel: f64, gyro: f64, distance_m: f64) -> Self {
        FilterParams {
            accelerometer_sigma: accel,
            gyroscope_sigma: gyro,
            distance_sigma_m: distance_m,
            ..self
        }
    }

    /// With `recentre_rad` replaced (0: the skeleton's Euler angles throughout).
    pub fn with_recentre_rad(self, recentre_rad: f64) -> Self {
        FilterParams {
            recentre_rad,
            ..self
        }
    }

    /// With `first_order_step` replaced (true: Eq. 4.1's `θ + Δt θ̇` as printed).
    pub fn with_first_order_step(self, first_order_step: bool) -> Self {
        FilterParams {
            first_order_step,
            ..self
        }
    }

    /// With `skip_saturated` replaced (true: flagged inertial channels are not used).
    pub fn with_skip_saturated(self, skip_saturated: bool) -> Self {
        FilterParams {
            skip_saturated,
            ..self
        }
    }

    /// With `distance_robust` replaced.
    pub fn with_distance_robust(self, distance_robust: RobustLoss) -> Self {
        FilterParams {
            distance_robust,
            ..self
        }
    }

    /// With `distance_gate_sigma` replaced.
    pub fn with_distance_gate_sigma(self, distance_gate_sigma: f64) -> Self {
        FilterParams {
            distance_gate_sigma,
            ..self
        }
    }

    /// Checks every field.
    ///
    /// # Errors
    /// [`Error::InvalidParam`] for a non-positive or non-finite value, a confidence floor
    /// outside [0, 1] or no sensor at all.
    pub fn validate(&self) -> Result<()> {
        positive("frame_time_s", self.frame_time_s)?;
        positive("process_sigma", self.process_sigma)?;
        positive("accelerometer_sigma", self.accelerometer_sigma)?;
        positive("gyroscope_sigma", self.gyroscope_sigma)?;
        positive("distance_sigma_m", self.distance_sigma_m)?;
        in_range("min_confidence", self.min_confidence, 0.0..=1.0)?;
        in_range(
            "distance_gate_sigma",
            self.distance_gate_sigma,
            0.0..=f64::MAX,
        )?;
        positive("initial_sigma.0", self.initial_sigma.0)?;
        positive("initial_sigma.1", self.initial_sigma.1)?;
        positive("initial_sigma.2", self.initial_sigma.2)?;
        positive("gravity_m_s2", self.gravity_m_s2)?;
        positive("divergence_rate", self.divergence_rate)?;
        in_range(
            "recentre_rad",
            self.recentre_rad,
            0.0..=std::f64::consts::PI,
        )?;
        match self.distance_robust {
            RobustLoss::None => {}
            RobustLoss::Huber { k } => {
                positive("distance_robust.k", k)?;
            }
            RobustLoss::Cauchy { c } => {
                positive("distance_robust.c", c)?;
            }
        }
        let s = self.sensors;
        if !(s.accelerometers || s.gyroscopes || s.distances) {
            return Err(Error::InvalidParam {
                name: "sensors",
                reason: "at least one of accelerometers, gyroscopes, distances".into(),
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Huber caps the correction at k σ, Cauchy lets it fall off; neither touches a small
    /// innovation.
    #[test]
    fn robust_inflation_bounds_the_pull_of_large_innovations() {
        let huber = RobustLoss::Huber { k: 1.345 };
        let cauchy = RobustLoss::Cauchy { c: 2.385 };
        assert_eq!(RobustLoss::None.inflation(100.0), 1.0);
        assert_eq!(huber.inflation(1.0), 1.0);
        assert!((cauchy.inflation(0.1) - 1.0).abs() < 0.002);
        // The correction in σ units is e / inflation(e).
        for e in [5.0, 50.0, 500.0] {
            assert!((e / huber.inflation(e) - 1.345).abs() < 1e-12);
            assert!(e / cauchy.inflation(e) < 2.385 * 2.385 / e + 1e-12);
        }
        for bad in [
            RobustLoss::Huber { k: 0.0 },
            RobustLoss::Cauchy { c: f64::NAN },
        ] {
            assert!(FilterParams::default()
                .with_distance_robust(bad)
                .validate()
                .is_err());
        }
    }
}
