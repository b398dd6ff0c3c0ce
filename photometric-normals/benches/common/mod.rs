//! Helpers shared by the benches (`mod common;`).
#![allow(dead_code)] // each bench uses a part

/// This process's CPU time (user + system, all threads), s, from `/proc/self/stat` (Linux;
/// `NaN` elsewhere): wall time on a shared machine measures the other users too.
pub fn cpu_seconds() -> f64 {
    std::fs::read_to_string("/proc/self/stat")
        .ok()
        .and_then(|s| {
            let rest = s.rsplit_once(')')?.1.split_whitespace().collect::<Vec<_>>();
            let utime: f64 = rest.get(11)?.parse().ok()?;
            let stime: f64 = rest.get(12)?.parse().ok()?;
            Some((utime + stime) / 100.0)
        })
        .unwrap_or(f64::NAN)
}

/// Max and RMS absolute difference of two depth maps over the pixels both have, m.
pub fn max_rms_diff(a: &[f64], b: &[f64]) -> (f64, f64) {
    let d: Vec<f64> = a
        .iter()
        .zip(b)
        .filter(|(a, b)| !a.is_nan() && !b.is_nan())
        .map(|(a, b)| (a - b).abs())
        .collect();
    let max = d.iter().copied().fold(0.0, f64::max);
    let rms = (d.iter().map(|x| x * x).sum::<f64>() / d.len().max(1) as f64).sqrt();
    (max, rms)
}
