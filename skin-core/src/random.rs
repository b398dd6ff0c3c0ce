//! The one hand-written random stream of the workspace: the counter-based SplitMix64 of the
//! peer benchmarks (`bench/peers/peerlib.py`), kept so tests, benches and examples regenerate
//! the peers' inputs bit-exactly, and so per-pixel noise can be drawn in any order (deviate
//! `i` depends on `i` only). Everything else draws from a generic [`rand::Rng`] (seeded
//! `rand_chacha` in tests) with [`rand_distr`] distributions.
//!
//! For the workspace's crates, tests, examples and peer benchmarks: hidden from the docs.

use crate::{Error, Result};

/// The golden-ratio increment of SplitMix64.
const GOLDEN: u64 = 0x9E37_79B9_7F4A_7C15;

/// Counter-based SplitMix64 stream of the peer benchmarks (`peerlib.py`): the `i`-th output
/// of the classic sequential SplitMix64 generator whose state starts at `seed`.
///
/// `u64(seed, i) = mix(seed + (i + 1)·GOLDEN)` with wrapping arithmetic. Uniform and normal
/// deviates and "choose m of n" follow `peerlib.py` exactly (uniforms bit-exact, normals to
/// the last ulp of libm).
///
/// For the workspace's crates, tests, examples and peer benchmarks (hidden from the docs; not
/// a stable API for others).
#[doc(hidden)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SplitMix64 {
    /// Seed of the stream.
    pub seed: u64,
}

impl SplitMix64 {
    /// The stream with this seed.
    pub fn new(seed: u64) -> Self {
        Self { seed }
    }

    /// The `i`-th 64-bit output.
    pub fn u64_at(&self, i: u64) -> u64 {
        let mut z = self
            .seed
            .wrapping_add(i.wrapping_add(1).wrapping_mul(GOLDEN));
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// The `i`-th uniform in `[0, 1)`: `(u64(seed, i) >> 11) · 2⁻⁵³`.
    pub fn uniform_at(&self, i: u64) -> f64 {
        (self.u64_at(i) >> 11) as f64 * (-53f64).exp2()
    }

    /// `n` uniforms in `[0, 1)`: [`SplitMix64::uniform_at`] for `i = 0..n`.
    pub fn uniform(&self, n: usize) -> Vec<f64> {
        (0..n as u64).map(|i| self.uniform_at(i)).collect()
    }

    /// The `k`-th standard normal, by Box–Muller (cosine branch only) on uniforms `2k` and
    /// `2k + 1`: `sqrt(−2 ln(1 − U[2k])) · cos(2π U[2k+1])`, as `peerlib.normal`.
    pub fn normal_at(&self, k: u64) -> f64 {
        let u1 = self.uniform_at(2 * k);
        let u2 = self.uniform_at(2 * k + 1);
        (-2.0 * (1.0 - u1).ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }

    /// `n` standard normals: [`SplitMix64::normal_at`] for `k = 0..n`. Multi-dimensional
    /// arrays are filled in row-major order.
    pub fn normal(&self, n: usize) -> Vec<f64> {
        (0..n as u64).map(|k| self.normal_at(k)).collect()
    }

    /// `m` distinct indices of `0..n`: those of the `m` smallest keys of `uniform(n)` (stable
    /// order on ties, as `np.argsort(kind="stable")[:m]`).
    ///
    /// # Errors
    /// [`Error::InvalidParam`] if `m > n`.
    pub fn choose(&self, n: usize, m: usize) -> Result<Vec<usize>> {
        if m > n {
            return Err(Error::InvalidParam {
                name: "m",
                reason: format!("cannot choose {m} of {n}"),
            });
        }
        let keys = self.uniform(n);
        let mut idx: Vec<usize> = (0..n).collect();
        idx.sort_by(|&a, &b| keys[a].total_cmp(&keys[b]));
        idx.truncate(m);
        Ok(idx)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splitmix_check_values() {
        let s = SplitMix64::new(1_234_567);
        assert_eq!(s.u64_at(0), 6_457_827_717_110_365_317);
        assert_eq!(s.u64_at(1), 3_203_168_211_198_807_973);
        assert_eq!(s.u64_at(2), 9_817_491_932_198_370_423);
        let u = s.uniform(1000);
        assert!(u.iter().all(|&x| (0.0..1.0).contains(&x)));
        let n = SplitMix64::new(5).normal(20_000);
        let mean = n.iter().sum::<f64>() / n.len() as f64;
        let var = n.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n.len() as f64;
        assert!(mean.abs() < 0.03 && (var - 1.0).abs() < 0.05);
        let c = SplitMix64::new(40).choose(100, 10).unwrap();
        let keys = SplitMix64::new(40).uniform(100);
        let max_chosen = c.iter().map(|&i| keys[i]).fold(0.0, f64::max);
        let unchosen_min = (0..100)
            .filter(|i| !c.contains(i))
            .map(|i| keys[i])
            .fold(1.0, f64::min);
        assert!(max_chosen < unchosen_min);
        assert!(SplitMix64::new(1).choose(3, 4).is_err());
    }

    #[test]
    fn normals_are_peerlib_box_muller_on_the_uniforms() {
        let s = SplitMix64::new(41);
        let u = s.uniform(200);
        for (k, z) in s.normal(100).into_iter().enumerate() {
            let (u1, u2) = (u[2 * k], u[2 * k + 1]);
            let expected = (-2.0 * (1.0 - u1).ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
            assert_eq!(z.to_bits(), expected.to_bits());
            assert_eq!(s.normal_at(k as u64).to_bits(), expected.to_bits());
        }
    }
}
