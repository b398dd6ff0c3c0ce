//! Time-offset estimation between two sampled 1D signals (Sand 2003 §4.1: "we move the
//! calibration device up and down … and correlate the vertical image coordinate with the
//! vertical world coordinate").
//!
//! The thesis does not spell out the correlation. We maximise the normalised cross-correlation
//! (Pearson correlation over the overlap) between the signals as a function of a continuous
//! offset `δ`: a grid search with the faster signal's sample period, then golden-section
//! refinement inside the best grid cell. The signals may have different rates: the slower one
//! is evaluated at its own samples and the faster one linearly interpolated, so interpolation
//! error stays small. Because image `v` grows downward while world height grows upward, the two
//! signals are often anti-correlated; [`TimeOffsetParams::allow_inverted`] maximises `|NCC|`.

use serde::{Deserialize, Serialize};

use crate::check::all_finite;
use crate::error::{Error, Result};

/// Most grid offsets the coarse search evaluates (guards against absurd ranges).
const MAX_GRID_OFFSETS: usize = 10_000_000;
/// Golden ratio conjugate `(√5 − 1)/2` for the golden-section search.
const INV_PHI: f64 = 0.618_033_988_749_894_8;

/// A uniformly sampled scalar signal: `values[i]` at time `start_s + i / rate_hz`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SampledSignal {
    /// Time of the first sample, s (in the signal's own clock).
    pub start_s: f64,
    /// Sampling rate, Hz.
    pub rate_hz: f64,
    /// Samples (any unit).
    pub values: Vec<f64>,
}

impl SampledSignal {
    /// A validated signal.
    ///
    /// # Errors
    /// [`Error::InvalidParam`] for a non-positive rate or fewer than 3 samples;
    /// [`Error::NonFinite`] for non-finite values or start time.
    pub fn new(start_s: f64, rate_hz: f64, values: Vec<f64>) -> Result<Self> {
        let s = Self {
            start_s,
            rate_hz,
            values,
        };
        s.validate()?;
        Ok(s)
    }

    fn validate(&self) -> Result<()> {
        all_finite("signal start time", [&self.start_s])?;
        crate::check::positive("rate_hz", self.rate_hz)?;
        if self.values.len() < 3 {
            return Err(Error::InvalidParam {
                name: "values",
                reason: format!(
                    "a signal needs at least 3 samples, got {}",
                    self.values.len()
                ),
            });
        }
        all_finite("signal values", self.values.iter())
    }

    /// Time of sample `i`, s.
    pub fn time(&self, i: usize) -> f64 {
        self.start_s + i as f64 / self.rate_hz
    }

    /// Duration from the first to the last sample, s.
    pub fn duration_s(&self) -> f64 {
        (self.values.len().saturating_sub(1)) as f64 / self.rate_hz
    }

    /// Linearly interpolated value at time `t_s`, or `None` outside the sampled span.
    pub fn sample_at(&self, t_s: f64) -> Option<f64> {
        let x = (t_s - self.start_s) * self.rate_hz;
        let last = self.values.len().checked_sub(1)? as f64;
        if !(x >= 0.0 && x <= last) {
            return None;
        }
        let i = (x.floor() as usize).min(self.values.len().saturating_sub(2));
        let f = x - i as f64;
        Some(self.values[i] * (1.0 - f) + self.values[i + 1] * f)
    }
}

/// Knobs of [`estimate_time_offset`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TimeOffsetParams {
    /// Smallest offset searched, s. Default: −5 (a manual start of two recorders rarely differs
    /// by more; the thesis gives no value).
    pub min_offset_s: f64,
    /// Largest offset searched, s. Default: 5.
    pub max_offset_s: f64,
    /// Smallest overlap accepted, as a fraction of the shorter signal's duration. Default: 0.5
    /// (short overlaps give spurious high correlations).
    pub min_overlap_fraction: f64,
    /// Maximise `|NCC|`, accepting anti-correlated signals (image `v` vs world height).
    /// Default: true.
    pub allow_inverted: bool,
    /// Width of the final golden-section bracket, s. Default: 1e-6.
    pub tolerance_s: f64,
}

impl Default for TimeOffsetParams {
    fn default() -> Self {
        Self {
            min_offset_s: -5.0,
            max_offset_s: 5.0,
            min_overlap_fraction: 0.5,
            allow_inverted: true,
            tolerance_s: 1e-6,
        }
    }
}

/// Result of [`estimate_time_offset`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TimeOffset {
    /// Offset δ, s: an event at time `t` in signal `a`'s clock is at `t + δ` in `b`'s clock,
    /// i.e. `b(t + δ) ≈ α·a(t) + β`.
    pub offset_s: f64,
    /// Normalised cross-correlation at the offset, in `[−1, 1]` (negative: inverted).
    pub score: f64,
    /// Number of sample pairs in the overlap.
    pub overlap_samples: usize,
}

/// Pearson correlation and pair count of `a` and `b` at offset `delta_s`.
fn ncc(
    a: &SampledSignal,
    b: &SampledSignal,
    delta_s: f64,
    min_pairs: usize,
) -> Option<(f64, usize)> {
    // Evaluate the slower signal at its samples; interpolate the faster one.
    let (reference, other, sign) = if a.rate_hz <= b.rate_hz {
        (a, b, 1.0)
    } else {
        (b, a, -1.0)
    };
    let (mut n, mut sx, mut sy, mut sxx, mut syy, mut sxy) = (0usize, 0.0, 0.0, 0.0, 0.0, 0.0);
    // First pass for means (numerically safer than one-pass sums of squares).
    for (i, &x) in reference.values.iter().enumerate() {
        if let Some(y) = other.sample_at(reference.time(i) + sign * delta_s) {
            n += 1;
            sx += x;
            sy += y;
        }
    }
    if n < min_pairs.max(3) {
        return None;
    }
    let (mx, my) = (sx / n as f64, sy / n as f64);
    for (i, &x) in reference.values.iter().enumerate() {
        if let Some(y) = other.sample_at(reference.time(i) + sign * delta_s) {
            let (dx, dy) = (x - mx, y - my);
            sxx += dx * dx;
            syy += dy * dy;
            sxy += dx * dy;
        }
    }
    let denom = (sxx * syy).sqrt();
    if denom <= 0.0 || !denom.is_finite() {
        return None;
    }
    Some((sxy / denom, n))
}

/// Estimates the time offset between two signals by maximising their normalised
/// cross-correlation (module docs).
///
/// # Errors
/// Errors of [`SampledSignal::new`] for either signal; [`Error::InvalidParam`] for an empty or
/// non-finite offset range or an overlap fraction outside `[0, 1]`; [`Error::Degenerate`] if no
/// offset gives enough overlap with non-constant signals.
///
/// # Example
/// ```
/// use skin_core::camera::{estimate_time_offset, SampledSignal, TimeOffsetParams};
/// let f = |t: f64| (1.3 * t).sin() + 0.5 * (0.37 * t).cos();
/// let a = SampledSignal::new(0.0, 100.0, (0..2000).map(|i| f(i as f64 / 100.0)).collect())?;
/// let b = SampledSignal::new(0.0, 30.0, (0..600).map(|i| -f(i as f64 / 30.0 - 0.25)).collect())?;
/// let off = estimate_time_offset(&a, &b, &TimeOffsetParams::default())?;
/// assert!((off.offset_s - 0.25).abs() < 1e-3 && off.score < -0.99);
/// # Ok::<(), skin_core::Error>(())
/// ```
pub fn estimate_time_offset(
    a: &SampledSignal,
    b: &SampledSignal,
    params: &TimeOffsetParams,
) -> Result<TimeOffset> {
    a.validate()?;
    b.validate()?;
    let p = params;
    all_finite(
        "time offset range",
        [&p.min_offset_s, &p.max_offset_s, &p.tolerance_s],
    )?;
    if p.min_offset_s > p.max_offset_s {
        return Err(Error::InvalidParam {
            name: "min_offset_s",
            reason: format!(
                "offset range [{}, {}] is empty",
                p.min_offset_s, p.max_offset_s
            ),
        });
    }
    if !(0.0..=1.0).contains(&p.min_overlap_fraction) {
        return Err(Error::InvalidParam {
            name: "min_overlap_fraction",
            reason: "must be in [0, 1]".into(),
        });
    }
    let step = 1.0 / a.rate_hz.max(b.rate_hz);
    let n_grid = ((p.max_offset_s - p.min_offset_s) / step).ceil() as usize + 1;
    if n_grid > MAX_GRID_OFFSETS {
        return Err(Error::InvalidParam {
            name: "max_offset_s",
            reason: format!(
                "offset range needs {n_grid} grid offsets (> {MAX_GRID_OFFSETS}); narrow it"
            ),
        });
    }
    let slow_rate = a.rate_hz.min(b.rate_hz);
    let min_pairs =
        (p.min_overlap_fraction * a.duration_s().min(b.duration_s()) * slow_rate).floor() as usize;
    let score = |delta: f64| -> Option<(f64, f64, usize)> {
        let (c, n) = ncc(a, b, delta, min_pairs)?;
        Some((if p.allow_inverted { c.abs() } else { c }, c, n))
    };
    let mut best: Option<(f64, f64)> = None; // (objective, delta)
    for k in 0..n_grid {
        let delta = (p.min_offset_s + k as f64 * step).min(p.max_offset_s);
        if let Some((s, _, _)) = score(delta) {
            if best.is_none_or(|(bs, _)| s > bs) {
                best = Some((s, delta));
            }
        }
    }
    let (_, mut centre) = best.ok_or_else(|| Error::Degenerate {
        what: "no offset in the search range gives enough overlap of non-constant signals".into(),
    })?;
    // Golden-section search for the continuous maximum inside [centre − step, centre + step].
    let obj = |d: f64| score(d).map_or(f64::NEG_INFINITY, |s| s.0);
    let (mut lo, mut hi) = (
        (centre - step).max(p.min_offset_s),
        (centre + step).min(p.max_offset_s),
    );
    let (mut x1, mut x2) = (hi - INV_PHI * (hi - lo), lo + INV_PHI * (hi - lo));
    let (mut f1, mut f2) = (obj(x1), obj(x2));
    while hi - lo > p.tolerance_s.max(1e-12 * centre.abs().max(1.0)) {
        if f1 >= f2 {
            hi = x2;
            x2 = x1;
            f2 = f1;
            x1 = hi - INV_PHI * (hi - lo);
            f1 = obj(x1);
        } else {
            lo = x1;
            x1 = x2;
            f1 = f2;
            x2 = lo + INV_PHI * (hi - lo);
            f2 = obj(x2);
        }
    }
    let refined = 0.5 * (lo + hi);
    if obj(refined) >= obj(centre) {
        centre = refined;
    }
    let (_, c, n) = score(centre).ok_or_else(|| Error::Degenerate {
        what: "time offset refinement lost the overlap".into(),
    })?;
    Ok(TimeOffset {
        offset_s: centre,
        score: c,
        overlap_samples: n,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_distr::StandardNormal;

    /// Smooth pseudo-random motion: a sum of sinusoids with random frequencies and phases.
    fn motion(seed: u64) -> impl Fn(f64) -> f64 {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let comps: Vec<(f64, f64, f64)> = (0..6)
            .map(|_| {
                (
                    rng.random_range(0.1..2.0),
                    rng.random_range(0.0..6.3),
                    rng.random_range(0.2..1.0),
                )
            })
            .collect();
        move |t| {
            comps
                .iter()
                .map(|(f, ph, a)| a * (std::f64::consts::TAU * f * t + ph).sin())
                .sum()
        }
    }

    fn sample(
        f: &impl Fn(f64) -> f64,
        start: f64,
        rate: f64,
        n: usize,
        gain: f64,
        noise: f64,
        seed: u64,
    ) -> SampledSignal {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let v = (0..n)
            .map(|i| {
                gain * f(start + i as f64 / rate)
                    + 3.0
                    + noise * rng.sample::<f64, _>(StandardNormal)
            })
            .collect();
        SampledSignal::new(start, rate, v).unwrap()
    }

    #[test]
    fn recovers_known_offset_at_different_rates() {
        for (seed, delta, rate_a, rate_b) in [
            (1u64, 0.1234, 120.0, 30.0),
            (2, -1.777, 25.0, 240.0),
            (3, 0.0071, 60.0, 60.0),
        ] {
            let f = motion(seed);
            // a: world height (mocap clock); b: image v (video clock), inverted and scaled:
            // b(t + δ) = −300·a(t) + 3, i.e. b(s) = −300·f(s − δ).
            let a = sample(&f, 0.0, rate_a, (20.0 * rate_a) as usize, 1.0, 0.002, seed);
            let shifted = |s: f64| f(s - delta);
            let b = sample(
                &shifted,
                0.5,
                rate_b,
                (18.0 * rate_b) as usize,
                -300.0,
                0.5,
                seed + 10,
            );
            let off = estimate_time_offset(&a, &b, &TimeOffsetParams::default()).unwrap();
            assert!(
                (off.offset_s - delta).abs() < 2e-3,
                "seed {seed}: {} vs {delta}",
                off.offset_s
            );
            assert!(off.score < -0.99);
            let no_inv = TimeOffsetParams {
                allow_inverted: false,
                ..Default::default()
            };
            let wrong = estimate_time_offset(&a, &b, &no_inv).unwrap();
            assert!(wrong.score < off.score.abs());
        }
    }

    #[test]
    fn bad_signals_are_errors() {
        let ok =
            SampledSignal::new(0.0, 10.0, (0..50).map(|i| (i as f64).sin()).collect()).unwrap();
        assert!(SampledSignal::new(0.0, 0.0, vec![1.0; 10]).is_err());
        assert!(SampledSignal::new(0.0, 10.0, vec![1.0; 2]).is_err());
        assert!(matches!(
            SampledSignal::new(0.0, 10.0, vec![1.0, f64::NAN, 2.0]),
            Err(Error::NonFinite { .. })
        ));
        let flat = SampledSignal::new(0.0, 10.0, vec![1.0; 50]).unwrap();
        assert!(matches!(
            estimate_time_offset(&ok, &flat, &TimeOffsetParams::default()),
            Err(Error::Degenerate { .. })
        ));
        let far = SampledSignal {
            start_s: 1000.0,
            ..ok.clone()
        };
        assert!(matches!(
            estimate_time_offset(&ok, &far, &TimeOffsetParams::default()),
            Err(Error::Degenerate { .. })
        ));
        let empty_range = TimeOffsetParams {
            min_offset_s: 1.0,
            max_offset_s: -1.0,
            ..Default::default()
        };
        assert!(matches!(
            estimate_time_offset(&ok, &ok, &empty_range),
            Err(Error::InvalidParam { .. })
        ));
        let mut bad = ok.clone();
        bad.values[3] = f64::INFINITY;
        assert!(matches!(
            estimate_time_offset(&ok, &bad, &TimeOffsetParams::default()),
            Err(Error::NonFinite { .. })
        ));
    }
}
