//! Prototype locations: Sand, McMillan and Popović 2003 §5.2 (thesis §5.2).
//!
//! The method is documented on [`farthest_point_prototypes`]; the module is private and
//! everything public is re-exported at the crate root.

use rand::{Rng, RngExt};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use skin_core::check;

use crate::config::{check_samples, dist2};
use crate::Result;

/// Prototype locations chosen by farthest-point selection (§5.2).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PrototypeLocations {
    /// Indices of the chosen samples, in selection order (the first is the random start).
    pub sample_indices: Vec<usize>,
    /// Chosen configuration points, row-major `sample_indices.len() × dim`.
    pub points: Vec<f32>,
    /// Configuration-space dimension.
    pub dim: usize,
    /// Covering radius: the largest distance from any sample to its nearest prototype
    /// (configuration-space units). Zero when every distinct sample is a prototype.
    pub covering_radius: f32,
}

/// Farthest-point prototype selection (Sand 2003 §5.2): exact, `O(n · S · dim)`, parallel over
/// samples. Ties go to the lowest sample index, so the result does not depend on the thread
/// count.
///
/// Prototype locations: Sand, McMillan and Popović 2003 §5.2 (thesis §5.2).
///
/// The first prototype is a random observed configuration point; each further prototype is
/// the observed point farthest (Euclidean) from all prototypes chosen so far
/// ([`farthest_point_prototypes`]). Unlike clustering or random sampling this also places
/// prototypes where the data is sparse.
///
/// Configuration points are `f32` rows of length `dim`, one per (frame, camera) sample.
///
/// `samples` holds `S` configuration points as rows of length `dim`. Selection stops early
/// (with fewer than `n` prototypes) when every sample coincides with a prototype.
///
/// # Errors
/// [`Error::InvalidParam`](crate::Error::InvalidParam) for `dim ∉ 1..=16`;
/// [`Error::Core`](crate::Error::Core) (invalid parameter `prototype_count_n`) for `n = 0`;
/// [`Error::Empty`](crate::Error::Empty) for no samples;
/// [`Error::SizeMismatch`](crate::Error::SizeMismatch) if `samples.len()` is not a multiple
/// of `dim`; [`Error::NonFinite`](crate::Error::NonFinite) for NaN/∞ coordinates.
///
/// # Example
/// ```
/// use needle_model::farthest_point_prototypes;
/// use rand::SeedableRng;
/// let samples = [0.0f32, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 1.0];
/// let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
/// let protos = farthest_point_prototypes(&samples, 2, 4, &mut rng)?;
/// assert_eq!(protos.sample_indices.len(), 4);
/// assert_eq!(protos.covering_radius, 0.0);
/// # Ok::<(), needle_model::Error>(())
/// ```
pub fn farthest_point_prototypes<R: Rng + ?Sized>(
    samples: &[f32],
    dim: usize,
    n: usize,
    rng: &mut R,
) -> Result<PrototypeLocations> {
    let count = check_samples(samples, dim)?;
    check::nonzero("prototype_count_n", n)?;
    let first = rng.random_range(0..count);
    let mut chosen = vec![first];
    let mut last = first;
    let mut min_d2: Vec<f32> = vec![f32::INFINITY; count];
    const CHUNK: usize = 4096;
    loop {
        let p = &samples[last * dim..(last + 1) * dim];
        // Update distances to the newest prototype and find the farthest sample (lowest
        // index on ties) in one parallel pass.
        let (best_d2, best_i) = min_d2
            .par_chunks_mut(CHUNK)
            .enumerate()
            .map(|(c, chunk)| {
                let mut best = (-1.0f32, usize::MAX);
                for (o, d) in chunk.iter_mut().enumerate() {
                    let i = c * CHUNK + o;
                    let nd = dist2(&samples[i * dim..(i + 1) * dim], p);
                    if nd < *d {
                        *d = nd;
                    }
                    if *d > best.0 {
                        best = (*d, i);
                    }
                }
                best
            })
            .reduce(
                || (-1.0f32, usize::MAX),
                |a, b| {
                    if b.0 > a.0 || (b.0 == a.0 && b.1 < a.1) {
                        b
                    } else {
                        a
                    }
                },
            );
        if chosen.len() == n || best_d2 <= 0.0 {
            let covering_radius = best_d2.max(0.0).sqrt();
            let points = chosen
                .iter()
                .flat_map(|&i| samples[i * dim..(i + 1) * dim].iter().copied())
                .collect();
            return Ok(PrototypeLocations {
                sample_indices: chosen,
                points,
                dim,
                covering_radius,
            });
        }
        chosen.push(best_i);
        last = best_i;
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::Error;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// `count` points uniform in `[-1, 1)^dim`, flattened (a fixture of the shape tests too).
    pub(crate) fn uniform_points(rng: &mut ChaCha8Rng, count: usize, dim: usize) -> Vec<f32> {
        (0..count * dim)
            .map(|_| rng.random_range(-1.0f32..1.0))
            .collect()
    }

    fn covering_radius(samples: &[f32], dim: usize, chosen: &[usize]) -> f32 {
        samples
            .chunks_exact(dim)
            .map(|x| {
                chosen
                    .iter()
                    .map(|&c| dist2(x, &samples[c * dim..(c + 1) * dim]))
                    .fold(f32::INFINITY, f32::min)
            })
            .fold(0.0, f32::max)
            .sqrt()
    }

    #[test]
    fn farthest_point_is_greedy_and_spreads_better_than_random() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        // Clustered data: a dense blob plus a sparse shell, as in Sand's Figure 7.
        let dim = 3;
        let mut samples = uniform_points(&mut rng, 3000, dim);
        samples.iter_mut().for_each(|v| *v *= 0.2);
        samples.extend(uniform_points(&mut rng, 300, dim));
        let n = 40;
        let locs = farthest_point_prototypes(&samples, dim, n, &mut rng).unwrap();
        assert_eq!(locs.sample_indices.len(), n);
        assert_eq!(locs.points.len(), n * dim);
        let mut sorted = locs.sample_indices.clone();
        sorted.sort_unstable();
        sorted.dedup();
        assert_eq!(sorted.len(), n, "prototypes must be distinct samples");
        // Greedy property: each new prototype maximises the distance to the previous ones.
        for k in 1..n {
            let prev = &locs.sample_indices[..k];
            let r = covering_radius(&samples, dim, prev);
            let i = locs.sample_indices[k];
            let di = prev
                .iter()
                .map(|&c| {
                    dist2(
                        &samples[i * dim..(i + 1) * dim],
                        &samples[c * dim..(c + 1) * dim],
                    )
                })
                .fold(f32::INFINITY, f32::min)
                .sqrt();
            assert!((di - r).abs() <= 1e-5 * r.max(1.0), "step {k}: {di} vs {r}");
        }
        let exact = covering_radius(&samples, dim, &locs.sample_indices);
        assert!((exact - locs.covering_radius).abs() < 1e-5);
        // Random selection of the same size covers worse (mean over several draws).
        let mut random_mean = 0.0;
        for _ in 0..10 {
            let idx: Vec<usize> = (0..n).map(|_| rng.random_range(0..3300)).collect();
            random_mean += covering_radius(&samples, dim, &idx) / 10.0;
        }
        assert!(
            locs.covering_radius < 0.7 * random_mean,
            "farthest point {} vs random {}",
            locs.covering_radius,
            random_mean
        );
    }

    #[test]
    fn farthest_point_stops_when_all_samples_are_prototypes() {
        let samples = [0.0f32, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 1.0];
        let mut rng = ChaCha8Rng::seed_from_u64(0);
        let locs = farthest_point_prototypes(&samples, 2, 10, &mut rng).unwrap();
        assert_eq!(locs.sample_indices.len(), 2);
        assert_eq!(locs.covering_radius, 0.0);
    }

    #[test]
    fn farthest_point_rejects_bad_input() {
        let mut rng = ChaCha8Rng::seed_from_u64(0);
        let f = |s: &[f32], d, n, rng: &mut ChaCha8Rng| farthest_point_prototypes(s, d, n, rng);
        assert!(matches!(f(&[], 2, 3, &mut rng), Err(Error::Empty { .. })));
        assert!(matches!(
            f(&[1.0, 2.0, 3.0], 2, 3, &mut rng),
            Err(Error::SizeMismatch { .. })
        ));
        assert!(matches!(
            f(&[1.0, f32::NAN], 2, 3, &mut rng),
            Err(Error::NonFinite { .. })
        ));
        assert!(matches!(
            f(&[1.0, 2.0], 0, 3, &mut rng),
            Err(Error::InvalidParam { name: "dim", .. })
        ));
        assert!(matches!(
            f(&[0.0; 17], 17, 3, &mut rng),
            Err(Error::InvalidParam { name: "dim", .. })
        ));
        assert_eq!(
            f(&[1.0, 2.0], 2, 0, &mut rng)
                .unwrap_err()
                .invalid_param_name(),
            Some("prototype_count_n")
        );
    }
}
