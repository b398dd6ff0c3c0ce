//! The simulated gyroscopes' bias after the §4.3.3 calibration: how it starts and how it moves
//! over a recording.
//!
//! The thesis calibrates each gyroscope's zero on a turntable (§4.3.3) and refines the
//! offsets at the start of each recording from the rest pose ("the readings of each sensor
//! during the initial pose integrate to zero", §4.4.4). A constant offset is therefore removed
//! to the rest window's noise; what the filter has to live with is the part of the bias that
//! changes after the rest pose. Two models of it:
//!
//! * [`GyroBiasModel::RandomWalk`]: a random walk from zero at
//!   [`SimulationParams::gyro_bias_walk`](super::SimulationParams::gyro_bias_walk) — a rate
//!   random walk of fixed strength, no offset at turn-on, nothing tied to temperature or
//!   motion.
//! * [`GyroBiasModel::Mems`] ([`MemsGyroBias`]): the error terms MEMS rate gyroscopes of the
//!   thesis's generation carry (the taxonomy of O. J. Woodman, *An introduction to inertial
//!   navigation*, Univ. of Cambridge tech. report UCAM-CL-TR-696, 2007: constant bias,
//!   bias instability, temperature effects, calibration errors; the white noise is
//!   [`SimulationParams::gyro_noise`](super::SimulationParams::gyro_noise)), with figures
//!   from the Analog Devices ADXRS300 datasheet (Rev. B), the ±300 °/s ADXRS part of
//!   2004–2007. The thesis names no parts (it refers to Adelsberger's 2007 thesis for them),
//!   so the ADXRS300 stands for the class, not for the boards' exact part.

use serde::{Deserialize, Serialize};
use skin_core::check::{non_negative, positive};

use crate::params::GRAVITY_M_S2;
use crate::Result;

/// The gyroscopes' bias model of a simulated suit
/// ([`SimulationParams::gyro_bias`](super::SimulationParams::gyro_bias); see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum GyroBiasModel {
    /// A random walk from zero per axis, at
    /// [`SimulationParams::gyro_bias_walk`](super::SimulationParams::gyro_bias_walk) rad/s
    /// per √s (0.0005 by default: 0.0067 rad/s, 0.38 °/s, after 3 min).
    RandomWalk,
    /// Turn-on offset, bias instability, warm-up temperature drift and linear-acceleration
    /// sensitivity of a MEMS rate gyroscope ([`MemsGyroBias`]).
    Mems(MemsGyroBias),
}

impl Default for GyroBiasModel {
    /// [`MemsGyroBias::adxrs300`]: what a suit of the thesis's generation carries.
    fn default() -> Self {
        GyroBiasModel::Mems(MemsGyroBias::adxrs300())
    }
}

impl GyroBiasModel {
    /// Checks the model's parameters.
    ///
    /// # Errors
    /// [`crate::Error`] naming the first negative or non-finite figure, or a time constant
    /// that is not positive.
    pub fn validate(&self) -> Result<()> {
        match self {
            GyroBiasModel::RandomWalk => Ok(()),
            GyroBiasModel::Mems(m) => m.validate(),
        }
    }
}

/// A MEMS rate gyroscope's bias over a recording, per board and axis:
///
/// `b(t) = b_on + k_T · ΔT · (1 − e^(−t/τ_T)) + g(t) + G · f(t)`
///
/// * `b_on ~ N(0, turn_on_sd)`: the turn-on offset, the shift of the null since the turntable
///   calibration (another day, another temperature). Constant: the rest pose (§4.4.4)
///   removes it, to the rest window's noise.
/// * `k_T ~ N(0, temp_coeff_sd)`, `ΔT = warm_up_k`, `τ_T = warm_up_tau_s`: the board warms
///   from room temperature towards skin temperature under the garment after it is put on
///   and powered, and the null moves with it. The rest pose sees only the start of the
///   warm-up; the rest of it is a drift over minutes.
/// * `g(t)`: bias instability, a first-order Gauss–Markov process from zero (stationary σ
///   `instability_sd`, correlation time `instability_tau_s`), the usual stand-in for the
///   flicker floor of an Allan deviation plot.
/// * `G`: linear-acceleration sensitivity, a 3 × 3 matrix per board with entries
///   `N(0, g_sensitivity_sd)` (rad/s per m/s²), times the specific force `f` the board's
///   accelerometer senses. Gravity's share at the rest pose is a constant the rest removes;
///   in any other orientation, and under the motion's accelerations, it is not.
///
/// The per-board constants are drawn from their own stream of the simulation's seed, so the
/// other random streams (white noise, placement, bit errors, microphones) are the same under
/// either model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MemsGyroBias {
    /// σ of the turn-on offset per axis, rad/s.
    pub turn_on_sd: f64,
    /// σ of the null's temperature coefficient per axis, rad/s per kelvin.
    pub temp_coeff_sd: f64,
    /// Temperature rise of a board after it is put on, kelvin.
    pub warm_up_k: f64,
    /// Time constant of the warm-up, seconds.
    pub warm_up_tau_s: f64,
    /// Stationary σ of the bias instability per axis, rad/s.
    pub instability_sd: f64,
    /// Correlation time of the bias instability, seconds.
    pub instability_tau_s: f64,
    /// σ of each entry of the linear-acceleration sensitivity matrix, rad/s per m/s².
    pub g_sensitivity_sd: f64,
}

impl MemsGyroBias {
    /// Figures for an ADXRS300-class gyroscope worn on the body:
    ///
    /// * `turn_on_sd` 0.5 °/s (0.0087 rad/s). The datasheet bounds the null at
    ///   2.50 ± 0.20 V over −40…+85 °C at 5 mV/(°/s), i.e. ±40 °/s; the turntable
    ///   calibration removes the part's own null, and what moves it between the calibration
    ///   and a recording is chiefly temperature (a few kelvin at the coefficient below) — the
    ///   datasheet gives no turn-on repeatability, so this figure is that estimate.
    /// * `temp_coeff_sd` 0.05 °/s/K (8.7·10⁻⁴ rad/s/K): the ±40 °/s window over 125 K bounds
    ///   the worst part at 0.32 °/s/K; a typical part is taken at a sixth of that bound.
    /// * `warm_up_k` 8 K, `warm_up_tau_s` 120 s: from a room at about 24 °C towards skin
    ///   temperature under a garment (about 32 °C), with the minutes-long time constant of a
    ///   small board against the body (an estimate; the thesis reports no temperatures).
    ///   With the coefficient above this is a drift of σ 0.4 °/s (0.007 rad/s) per axis
    ///   once warm, 0.31 °/s after 3 min.
    /// * `instability_sd` 0.02 °/s (3.5·10⁻⁴ rad/s), `instability_tau_s` 100 s: the in-run
    ///   stability class (tens of °/h) of consumer MEMS rate gyroscopes of the period; the
    ///   ADXRS300 datasheet does not specify it.
    /// * `g_sensitivity_sd` chosen so that a row of `G` has an RMS norm of 0.2 °/s/g, the
    ///   datasheet's linear-acceleration effect: 0.2/√3 °/s per g per entry.
    pub fn adxrs300() -> Self {
        let deg = std::f64::consts::PI / 180.0;
        MemsGyroBias {
            turn_on_sd: 0.5 * deg,
            temp_coeff_sd: 0.05 * deg,
            warm_up_k: 8.0,
            warm_up_tau_s: 120.0,
            instability_sd: 0.02 * deg,
            instability_tau_s: 100.0,
            g_sensitivity_sd: 0.2 / 3f64.sqrt() * deg / GRAVITY_M_S2,
        }
    }

    /// These figures with every bias term (turn-on, temperature drift, instability,
    /// g-sensitivity) multiplied by `factor` and the warm-up's time constant divided by
    /// `speed` (a faster warm-up: the same drift in a shorter recording). A test device for a
    /// short clip with a strong drift.
    pub fn scaled(self, factor: f64, speed: f64) -> Self {
        MemsGyroBias {
            turn_on_sd: self.turn_on_sd * factor,
            temp_coeff_sd: self.temp_coeff_sd * factor,
            warm_up_tau_s: self.warm_up_tau_s / speed,
            instability_sd: self.instability_sd * factor,
            g_sensitivity_sd: self.g_sensitivity_sd * factor,
            ..self
        }
    }

    /// Checks the figures.
    ///
    /// # Errors
    /// [`crate::Error`] naming the first negative or non-finite figure, or a time constant
    /// that is not positive.
    pub fn validate(&self) -> Result<()> {
        for (name, v) in [
            ("turn_on_sd", self.turn_on_sd),
            ("temp_coeff_sd", self.temp_coeff_sd),
            ("warm_up_k", self.warm_up_k),
            ("instability_sd", self.instability_sd),
            ("g_sensitivity_sd", self.g_sensitivity_sd),
        ] {
            non_negative(name, v)?;
        }
        positive("warm_up_tau_s", self.warm_up_tau_s)?;
        positive("instability_tau_s", self.instability_tau_s)?;
        Ok(())
    }
}
