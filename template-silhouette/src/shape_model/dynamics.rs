//! The dynamic part's memory: a bank of damped second-order filters through which the motion
//! inputs pass; the model's dynamic response is a linear map of the filtered inputs.

use serde::{Deserialize, Serialize};

/// One filter of the bank, in continuous time (so a model means the same at any frame rate):
/// the impulse response `e^{−d t} cos(2π f t)`-like of a pole pair `ρ e^{±iφ}` with
/// `ρ = e^{−d Δt}`, `φ = 2π f Δt`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DynamicPole {
    /// Decay rate `d`, 1/s (an impulse's response falls by e in `1/d` seconds).
    pub decay_per_s: f64,
    /// Oscillation frequency `f`, Hz (0: two real poles, a smooth lag).
    pub frequency_hz: f64,
}

impl DynamicPole {
    /// The difference equation's `(a₁, a₂)` at frame time `dt_s`: `y_t = a₁ y_{t−1} +
    /// a₂ y_{t−2} + g u_t` with `a₁ = 2ρ cos φ`, `a₂ = −ρ²`, and the gain
    /// `g = 1 − a₁ − a₂` that makes a constant input come out unchanged (so every filtered
    /// input keeps the input's scale and one ridge weight suits them all).
    pub(crate) fn coefficients(&self, dt_s: f64) -> [f64; 3] {
        let rho = (-self.decay_per_s * dt_s).exp();
        let phi = std::f64::consts::TAU * self.frequency_hz * dt_s;
        let (a1, a2) = (2.0 * rho * phi.cos(), -rho * rho);
        [a1, a2, 1.0 - a1 - a2]
    }
}

/// The bank's state: per filter and input, the last two outputs.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Bank {
    coefficients: Vec<[f64; 3]>,
    inputs: usize,
    /// `y_{t−1}` and `y_{t−2}`, filter after filter, `inputs` each.
    last: [Vec<f64>; 2],
}

impl Bank {
    /// A bank at rest (zero state: the body has not moved before the first frame).
    pub(crate) fn new(poles: &[DynamicPole], dt_s: f64, inputs: usize) -> Self {
        let n = poles.len() * inputs;
        Bank {
            coefficients: poles.iter().map(|p| p.coefficients(dt_s)).collect(),
            inputs,
            last: [vec![0.0; n], vec![0.0; n]],
        }
    }

    /// Number of outputs: one per filter and input.
    pub(crate) fn outputs(&self) -> usize {
        self.coefficients.len() * self.inputs
    }

    /// Feeds one frame's inputs; returns the filtered inputs (filter after filter).
    pub(crate) fn step(&mut self, u: &[f64]) -> Vec<f64> {
        let mut y = Vec::with_capacity(self.outputs());
        for (p, [a1, a2, g]) in self.coefficients.iter().enumerate() {
            for (i, x) in u.iter().enumerate().take(self.inputs) {
                let k = p * self.inputs + i;
                y.push(a1 * self.last[0][k] + a2 * self.last[1][k] + g * x);
            }
        }
        self.last[1] = std::mem::replace(&mut self.last[0], y.clone());
        y
    }
}

/// The default bank: smooth lags of 0.1, 0.33 and 1 s and two swings of 1 s decay at 0.5 and
/// 1 Hz. A garment's own modes are a pendulum's (`f = √(g/L) / 2π`: 0.5–1 Hz for a hem
/// 0.25–1 m below its support) damped by air within a second or two; the lags cover the
/// trailing of cloth behind the body's speed. Five filters, not a fitted pole per
/// component: the filters are fixed, so the whole model stays one linear least-squares fit
/// (pose and dynamic parts together: fitted apart, the pose part takes what the motion
/// explains — a walk's steady drag, correlated with the walking poses — and the dynamic part
/// loses it), stable by construction (every pole
/// inside the unit circle).
pub(crate) fn default_poles() -> Vec<DynamicPole> {
    vec![
        DynamicPole {
            decay_per_s: 10.0,
            frequency_hz: 0.0,
        },
        DynamicPole {
            decay_per_s: 3.0,
            frequency_hz: 0.0,
        },
        DynamicPole {
            decay_per_s: 1.0,
            frequency_hz: 0.0,
        },
        DynamicPole {
            decay_per_s: 1.0,
            frequency_hz: 0.5,
        },
        DynamicPole {
            decay_per_s: 1.0,
            frequency_hz: 1.0,
        },
    ]
}
