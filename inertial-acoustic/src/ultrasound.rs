//! Ultrasonic processing (§4.3.1): per-pulse frames of a microphone stream → band-pass
//! 40 kHz ± 2.5 kHz → square → envelope low-pass at 30 kHz → the earliest pulse above the
//! noise → the inflection point of its rise (largest gradient) → distance, with per-source
//! offset calibration (§4.3.3) and the confidence `w = w_s · w_t · w_a`.
//!
//! Filters are second-order sections (RBJ audio-EQ cookbook), two per filter (4th order),
//! run in transposed direct form II; the frame is filtered from rest because every frame
//! starts 8 ms after the previous pulse (§4.2.2). No FFT is needed: the stream is filtered in
//! the time domain as it is framed (`rustfft`/`realfft`/`biquad` are not in the offline
//! registry this workspace builds from; the ~40 lines below replace them).

use crate::params::UltrasoundParams;
use crate::{Error, Result};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// One second-order IIR section `(b0 + b1 z⁻¹ + b2 z⁻²) / (1 + a1 z⁻¹ + a2 z⁻²)`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Biquad {
    b: [f64; 3],
    a: [f64; 2],
}

impl Biquad {
    /// Band-pass with 0 dB peak gain at `f0`, quality `q` (RBJ cookbook).
    fn bandpass(fs: f64, f0: f64, q: f64) -> Self {
        let w = 2.0 * PI * f0 / fs;
        let alpha = w.sin() / (2.0 * q);
        let a0 = 1.0 + alpha;
        Biquad {
            b: [alpha / a0, 0.0, -alpha / a0],
            a: [-2.0 * w.cos() / a0, (1.0 - alpha) / a0],
        }
    }

    /// Low-pass at `f0`, quality `q` (RBJ cookbook).
    fn lowpass(fs: f64, f0: f64, q: f64) -> Self {
        let w = 2.0 * PI * f0 / fs;
        let (s, c) = w.sin_cos();
        let alpha = s / (2.0 * q);
        let a0 = 1.0 + alpha;
        let b1 = (1.0 - c) / a0;
        Biquad {
            b: [0.5 * b1, b1, 0.5 * b1],
            a: [-2.0 * c / a0, (1.0 - alpha) / a0],
        }
    }
}

/// A pulse found in one frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Detection {
    /// Inflection point of the envelope's rise, samples after the pulse emission
    /// (sub-sample, parabolic refinement of the largest gradient).
    pub inflection_sample: f64,
    /// Envelope peak of the pulse (signal power, input units²).
    pub peak: f64,
    /// Noise power of the frame (median envelope, input units²).
    pub noise: f64,
}

/// The §4.3.1 pipeline for one microphone; reusable scratch, no allocation per frame.
#[derive(Debug, Clone)]
pub struct PulseDetector {
    params: UltrasoundParams,
    band: [Biquad; 2],
    envelope: [Biquad; 2],
    work: Vec<f64>,
    sorted: Vec<f64>,
}

impl PulseDetector {
    /// A detector for `params`.
    ///
    /// # Errors
    /// As [`UltrasoundParams::validate`].
    pub fn new(params: UltrasoundParams) -> Result<Self> {
        params.validate()?;
        let fs = params.sample_rate_hz;
        // Two sections of Q = 2·f0/width... each section's −3 dB band is f0/Q; cascading two
        // narrows it by √(√2 − 1) ≈ 0.64, so each gets 0.64 × (f0 / width).
        let q = 0.64 * params.band_centre_hz / params.band_width_hz;
        let band = [
            Biquad::bandpass(fs, params.band_centre_hz, q),
            Biquad::bandpass(fs, params.band_centre_hz, q),
        ];
        // 4th-order Butterworth low-pass: sections with Q = 0.541 and 1.307.
        let envelope = [
            Biquad::lowpass(fs, params.envelope_cutoff_hz, 0.541_196),
            Biquad::lowpass(fs, params.envelope_cutoff_hz, 1.306_563),
        ];
        Ok(PulseDetector {
            params,
            band,
            envelope,
            work: Vec::new(),
            sorted: Vec::new(),
        })
    }

    /// The parameters.
    pub fn params(&self) -> &UltrasoundParams {
        &self.params
    }

    /// The power envelope of one frame (band-pass, square, low-pass), into `out`.
    ///
    /// # Errors
    /// [`Error::Empty`] for an empty frame; [`Error::NonFinite`] for NaN or infinite samples.
    pub fn envelope_into(&self, frame: &[f32], out: &mut Vec<f64>) -> Result<()> {
        if frame.is_empty() {
            return Err(Error::Empty {
                what: "microphone frame",
            });
        }
        if frame.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite {
                what: "microphone frame",
            });
        }
        out.clear();
        out.reserve(frame.len());
        // The four sections in one pass (states in registers): band-pass, band-pass, square,
        // low-pass, low-pass.
        let [b0, b1] = &self.band;
        let [l0, l1] = &self.envelope;
        let mut st = [[0.0f64; 2]; 4];
        let step = |q: &Biquad, s: &mut [f64; 2], x: f64| {
            let y = q.b[0] * x + s[0];
            s[0] = q.b[1] * x - q.a[0] * y + s[1];
            s[1] = q.b[2] * x - q.a[1] * y;
            y
        };
        for &v in frame {
            let [s0, s1, s2, s3] = &mut st;
            let x = step(b1, s1, step(b0, s0, f64::from(v)));
            out.push(step(l1, s3, step(l0, s2, x * x)));
        }
        Ok(())
    }

    /// The earliest pulse well above the noise in one frame (samples counted from the pulse
    /// emission), or `None` if nothing rises above `noise_factor ×` the frame's median power.
    ///
    /// # Errors
    /// As [`PulseDetector::envelope_into`].
    pub fn detect(&mut self, frame: &[f32]) -> Result<Option<Detection>> {
        let mut env = std::mem::take(&mut self.work);
        let r = self.envelope_into(frame, &mut env);
        let out = r.map(|()| self.find(&env));
        self.work = env;
        out
    }

    fn find(&mut self, env: &[f64]) -> Option<Detection> {
        // Noise power: the median of every fourth sample (the pulse and its echoes cover a
        // small part of the frame).
        self.sorted.clear();
        self.sorted.extend(env.iter().step_by(4).map(|v| v.abs()));
        let mid = self.sorted.len() / 2;
        let noise = *self
            .sorted
            .select_nth_unstable_by(mid, |a, b| a.total_cmp(b))
            .1;
        let threshold = self.params.noise_factor * noise.max(f64::MIN_POSITIVE);
        let start = env.iter().position(|&v| v > threshold)?;
        // The peak of this (first) pulse: climb while the envelope keeps rising, tolerating
        // the carrier ripple the low-pass leaves (look 6 samples ahead).
        let mut peak_i = start;
        let mut i = start;
        while i + 1 < env.len() {
            let ahead = (i + 6).min(env.len() - 1);
            let (best, best_v) =
                env[i + 1..=ahead]
                    .iter()
                    .enumerate()
                    .fold(
                        (i, env[i]),
                        |acc, (k, &v)| {
                            if v > acc.1 {
                                (i + 1 + k, v)
                            } else {
                                acc
                            }
                        },
                    );
            if best_v <= env[peak_i] {
                break;
            }
            peak_i = best;
            i = best;
        }
        // Largest gradient (central differences) between a few samples before the crossing
        // and the peak.
        let lo = start.saturating_sub(8).max(1);
        let hi = peak_i.max(lo + 1).min(env.len() - 2);
        let grad = |k: usize| env[k + 1] - env[k - 1];
        let mut best = lo;
        for k in lo..=hi {
            if grad(k) > grad(best) {
                best = k;
            }
        }
        // The largest-gradient region is flat-topped (the rise is nearly linear), so its
        // location is the gradient-weighted centroid where the gradient exceeds half its
        // maximum: sub-sample and free of the one-sample jitter of a plain argmax.
        let g_max = grad(best);
        let half = 0.5 * g_max;
        let (mut a, mut b) = (best, best);
        while a > 1 && grad(a - 1) > half {
            a -= 1;
        }
        while b + 2 < env.len() && grad(b + 1) > half {
            b += 1;
        }
        let (mut sw, mut swk) = (0.0, 0.0);
        for k in a..=b {
            let w = grad(k) - half;
            sw += w;
            swk += w * k as f64;
        }
        let inflection = if sw > 0.0 { swk / sw } else { best as f64 };
        Some(Detection {
            inflection_sample: inflection,
            peak: env[peak_i],
            noise,
        })
    }

    /// Distance, metres, of a detection from a source with calibrated `offset_samples`.
    pub fn distance_m(&self, detection: &Detection, offset_samples: f64) -> f64 {
        (detection.inflection_sample - offset_samples) / self.params.sample_rate_hz
            * self.params.speed_of_sound_m_s
    }

    /// Signal-strength confidence `w_s` (§4.3.1): the peak over the noise, normalised by r²;
    /// 1 at and above `strength_threshold`, `(value / threshold)²` below.
    pub fn strength_confidence(&self, detection: &Detection, distance_m: f64) -> f64 {
        let value = detection.peak / detection.noise.max(f64::MIN_POSITIVE) * distance_m.powi(2);
        (value / self.params.strength_threshold).min(1.0).powi(2)
    }

    /// Temporal-continuity confidence `w_t` (§4.3.1): 1 while the pair's distance moved at
    /// most `continuity_threshold_m` since its previous pulse, `(threshold / jump)²` beyond;
    /// 1 without a previous pulse.
    pub fn continuity_confidence(&self, distance_m: f64, previous_m: Option<f64>) -> f64 {
        previous_m.map_or(1.0, |prev| {
            let jump = (distance_m - prev).abs();
            let t = self.params.continuity_threshold_m;
            if jump <= t {
                1.0
            } else {
                (t / jump).powi(2)
            }
        })
    }
}

/// One static calibration placement (§4.3.3): a source and a microphone at a known distance.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CalibrationShot {
    /// Source index.
    pub source: usize,
    /// Detected inflection point, samples.
    pub inflection_sample: f64,
    /// Measured (digitizer) distance, metres.
    pub distance_m: f64,
}

/// Per-source offsets (samples between the pulse start and the detected inflection point,
/// §4.3.3): the mean of `inflection − distance · fs / c` over the source's shots.
///
/// # Errors
/// [`Error::IndexOutOfRange`] for a source index ≥ `source_count`; [`Error::NonFinite`] for
/// non-finite shots; [`Error::Empty`] if a source has no shot.
pub fn calibrate_offsets(
    shots: &[CalibrationShot],
    source_count: usize,
    params: &UltrasoundParams,
) -> Result<Vec<f64>> {
    let mut sum = vec![0.0; source_count];
    let mut n = vec![0usize; source_count];
    let per_m = params.sample_rate_hz / params.speed_of_sound_m_s;
    for s in shots {
        skin_core::check::index("calibration source", s.source, source_count)?;
        if !(s.inflection_sample.is_finite() && s.distance_m.is_finite()) {
            return Err(Error::NonFinite {
                what: "calibration shot",
            });
        }
        sum[s.source] += s.inflection_sample - s.distance_m * per_m;
        n[s.source] += 1;
    }
    if n.contains(&0) {
        return Err(Error::Empty {
            what: "calibration shots of a source",
        });
    }
    Ok(sum.iter().zip(&n).map(|(s, &k)| s / k as f64).collect())
}

/// Leave-one-out distance errors of the offset calibration (§4.3.3: "according to our
/// leave-one-out experiments"), metres, one per shot whose source has another shot.
///
/// # Errors
/// As [`calibrate_offsets`].
pub fn leave_one_out_errors_m(
    shots: &[CalibrationShot],
    source_count: usize,
    params: &UltrasoundParams,
) -> Result<Vec<f64>> {
    calibrate_offsets(shots, source_count, params)?;
    let per_m = params.sample_rate_hz / params.speed_of_sound_m_s;
    let mut out = Vec::with_capacity(shots.len());
    for (i, s) in shots.iter().enumerate() {
        let others: Vec<f64> = shots
            .iter()
            .enumerate()
            .filter(|(k, o)| *k != i && o.source == s.source)
            .map(|(_, o)| o.inflection_sample - o.distance_m * per_m)
            .collect();
        if others.is_empty() {
            continue;
        }
        let offset = others.iter().sum::<f64>() / others.len() as f64;
        out.push((s.inflection_sample - offset) / per_m - s.distance_m);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::{CARRIER_HZ, PULSE_CYCLES, SAMPLES_PER_PULSE};

    fn pulse_frame(delay_samples: f64, amplitude: f64) -> Vec<f32> {
        let fs = UltrasoundParams::default().sample_rate_hz;
        let len = PULSE_CYCLES as f64 / CARRIER_HZ;
        (0..SAMPLES_PER_PULSE)
            .map(|n| {
                let t = (n as f64 - delay_samples) / fs;
                if (0.0..len).contains(&t) {
                    (amplitude * (2.0 * PI * CARRIER_HZ * t).sin()) as f32
                } else {
                    0.0
                }
            })
            .collect()
    }

    #[test]
    fn inflection_moves_with_the_delay_sub_sample() {
        let mut d = PulseDetector::new(UltrasoundParams::default()).unwrap();
        let a = d.detect(&pulse_frame(200.0, 1.0)).unwrap().unwrap();
        let b = d.detect(&pulse_frame(437.3, 1.0)).unwrap().unwrap();
        let shift = b.inflection_sample - a.inflection_sample;
        assert!((shift - 237.3).abs() < 0.35, "shift {shift}");
        // The inflection point sits tens of samples after the pulse start (§4.3.1: "about
        // 40 samples").
        let lag = a.inflection_sample - 200.0;
        assert!((5.0..60.0).contains(&lag), "lag {lag}");
    }

    #[test]
    fn silence_is_no_detection_and_nan_is_an_error() {
        let mut d = PulseDetector::new(UltrasoundParams::default()).unwrap();
        let quiet: Vec<f32> = (0..SAMPLES_PER_PULSE)
            .map(|n| (1e-3 * ((n * 7919 % 113) as f64 / 113.0 - 0.5)) as f32)
            .collect();
        assert!(d.detect(&quiet).unwrap().is_none());
        let mut bad = quiet.clone();
        bad[3] = f32::NAN;
        assert!(matches!(d.detect(&bad), Err(Error::NonFinite { .. })));
        assert!(matches!(d.detect(&[]), Err(Error::Empty { .. })));
    }

    #[test]
    fn offsets_recover_a_constant_lag() {
        let p = UltrasoundParams::default();
        let per_m = p.sample_rate_hz / p.speed_of_sound_m_s;
        let shots: Vec<CalibrationShot> = (0..6)
            .map(|i| {
                let d = 0.3 + 0.1 * i as f64;
                CalibrationShot {
                    source: i % 2,
                    inflection_sample: d * per_m + 30.0 + 10.0 * (i % 2) as f64,
                    distance_m: d,
                }
            })
            .collect();
        let off = calibrate_offsets(&shots, 2, &p).unwrap();
        assert!((off[0] - 30.0).abs() < 1e-9 && (off[1] - 40.0).abs() < 1e-9);
        let loo = leave_one_out_errors_m(&shots, 2, &p).unwrap();
        assert_eq!(loo.len(), 6);
        assert!(loo.iter().all(|e| e.abs() < 1e-9));
        assert!(calibrate_offsets(&shots, 3, &p).is_err());
    }
}
