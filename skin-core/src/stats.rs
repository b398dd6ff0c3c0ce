//! Summary statistics of samples (errors, distances, timings): the one set every crate,
//! metric and example uses, so that a "median" or a "95th percentile" means the same
//! everywhere.
//!
//! Percentiles interpolate linearly between order statistics — the definition NumPy's
//! `percentile` uses by default — so figures compare directly with the Python peers. Empty
//! input gives NaN rather than an error: a statistic of no samples is "not a number", and
//! reports print it as such.

/// Arithmetic mean; NaN for no samples.
pub fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

/// Root mean square; NaN for no samples.
pub fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
}

/// Median (the mean of the two middle values for an even count); NaN for no samples.
pub fn median(v: &[f64]) -> f64 {
    let sorted = sorted(v);
    let n = sorted.len();
    match n {
        0 => f64::NAN,
        _ if n % 2 == 1 => sorted[n / 2],
        _ => 0.5 * (sorted[n / 2 - 1] + sorted[n / 2]),
    }
}

/// Percentile `q ∈ [0, 1]` (0.95 for the 95th) with linear interpolation; NaN for no samples
/// or a `q` outside `[0, 1]`.
pub fn percentile(v: &[f64], q: f64) -> f64 {
    percentile_sorted(&sorted(v), q)
}

/// [`percentile`] of samples already sorted in increasing order (no copy).
pub fn percentile_sorted(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() || !(0.0..=1.0).contains(&q) {
        return f64::NAN;
    }
    let pos = q * (sorted.len() - 1) as f64;
    let lo = pos.floor() as usize;
    let hi = pos.ceil() as usize;
    let frac = pos - lo as f64;
    sorted[lo] + frac * (sorted[hi] - sorted[lo])
}

/// Largest value; NaN for no samples.
pub fn max(v: &[f64]) -> f64 {
    v.iter().copied().reduce(f64::max).unwrap_or(f64::NAN)
}

/// A copy of `v` sorted in increasing order (NaN last, by `total_cmp`).
pub fn sorted(v: &[f64]) -> Vec<f64> {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn match_hand_computation_and_numpy() {
        let v = [4.0, 1.0, 3.0, 2.0];
        assert_eq!(mean(&v), 2.5);
        assert_eq!(median(&v), 2.5);
        assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
        assert!((rms(&[3.0, 4.0]) - 12.5f64.sqrt()).abs() < 1e-15);
        // numpy.percentile([1, 2, 3, 4], 95) = 3.85
        assert!((percentile(&v, 0.95) - 3.85).abs() < 1e-12);
        assert_eq!(percentile(&v, 0.0), 1.0);
        assert_eq!(percentile(&v, 1.0), 4.0);
        assert_eq!(max(&v), 4.0);
        assert_eq!(sorted(&v), vec![1.0, 2.0, 3.0, 4.0]);
    }

    #[test]
    fn empty_or_bad_input_is_nan() {
        for s in [
            mean(&[]),
            rms(&[]),
            median(&[]),
            max(&[]),
            percentile(&[], 0.5),
        ] {
            assert!(s.is_nan());
        }
        assert!(percentile(&[1.0], 1.5).is_nan());
        assert!(percentile(&[1.0], f64::NAN).is_nan());
    }
}
