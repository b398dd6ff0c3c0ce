use super::*;
use crate::prototype_locations::farthest_point_prototypes;
use crate::prototype_locations::tests::uniform_points;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

#[test]
fn grid_adjacency_is_symmetric_ring_and_axial() {
    let adj = grid_adjacency(4, 3).unwrap();
    assert_eq!(adj.len(), 12);
    assert_eq!(adj[0], vec![1, 3, 4]);
    assert_eq!(adj[5], vec![1, 4, 6, 9]);
    for (j, nb) in adj.iter().enumerate() {
        for &n in nb {
            assert!(adj[n as usize].contains(&(j as u16)));
        }
    }
    assert!(grid_adjacency(1, 1).unwrap()[0].is_empty());
    assert!(matches!(
        grid_adjacency(0, 3),
        Err(Error::InvalidParam { .. })
    ));
    assert!(matches!(
        grid_adjacency(300, 300),
        Err(Error::InvalidParam { .. })
    ));
}

/// Brute-force cap radius of `pr` for prototypes `points`: `radius_factor ×` the median
/// (upper median for an even count) of the nearest-other-prototype distances.
fn brute_cap(points: &[f32], dim: usize, pr: &ReconstructionParams) -> Option<f32> {
    let Neighbourhood::Capped { radius_factor } = pr.neighbourhood else {
        return None;
    };
    let rows: Vec<&[f32]> = points.chunks_exact(dim).collect();
    if rows.len() < 2 {
        return None;
    }
    let mut nn: Vec<f32> = (0..rows.len())
        .map(|i| {
            (0..rows.len())
                .filter(|&j| j != i)
                .map(|j| dist2(rows[i], rows[j]).sqrt())
                .fold(f32::INFINITY, f32::min)
        })
        .collect();
    nn.sort_by(f32::total_cmp);
    Some(nn[nn.len() / 2] * radius_factor as f32)
}

/// The variants every brute-force test runs: the paper's and capped at three radii.
fn variants() -> [Neighbourhood; 4] {
    [
        Neighbourhood::Fraction,
        Neighbourhood::Capped { radius_factor: 0.3 },
        Neighbourhood::Capped { radius_factor: 1.0 },
        Neighbourhood::Capped { radius_factor: 3.0 },
    ]
}

/// Brute force §5.3 (and the capped variant, `cap` from [`brute_cap`]) for one needle and
/// prototype.
fn brute(
    samples: &[f32],
    dim: usize,
    s: &[u32],
    l: &[f32],
    p: &[f32],
    pr: &ReconstructionParams,
    cap: Option<f32>,
) -> f32 {
    let mut d: Vec<(f32, f32)> = s
        .iter()
        .zip(l)
        .map(|(&i, &len)| {
            (
                dist2(&samples[i as usize * dim..(i as usize + 1) * dim], p).sqrt(),
                len,
            )
        })
        .collect();
    d.sort_by(|a, b| a.0.total_cmp(&b.0));
    let m = s.len();
    let n = match cap {
        None => near_count(m, pr.f_near, pr.min_near),
        Some(r) => {
            let ball = d.iter().filter(|x| x.0 <= r).count();
            let floor = pr.min_near.clamp(1, m);
            let n_frac = ((pr.f_near * m as f64).round() as usize).clamp(1, m);
            if n_frac == m {
                m
            } else if ball >= floor {
                n_frac.min(ball)
            } else {
                floor
            }
        }
    };
    let reach = d[n - 1].0 + TIE_RADIUS * config_scale(samples, dim).unwrap();
    let mut near: Vec<f32> = d.iter().filter(|x| x.0 <= reach).map(|x| x.1).collect();
    let n = near.len();
    near.sort_by(f32::total_cmp);
    near[percentile_index(n, pr.f_min)]
}

#[test]
fn shapes_match_brute_force_in_any_dimension() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for dim in [1usize, 2, 3, 5, 6, 9, 11, 16] {
        let count = 600;
        // Every configuration is shared by 3 "cameras" (exact distance ties).
        let frames = uniform_points(&mut rng, count / 3, dim);
        let samples: Vec<f32> = frames
            .chunks_exact(dim)
            .flat_map(|r| r.iter().chain(r).chain(r).copied())
            .collect();
        let per_needle: Vec<Vec<(u32, f32)>> = (0..4)
            .map(|_| {
                let mut v = Vec::new();
                for s in 0..count as u32 {
                    if rng.random_range(0.0f32..1.0) < 0.6 {
                        v.push((s, rng.random_range(0.5f32..2.0)));
                    }
                    if rng.random_range(0.0f32..1.0) < 0.1 {
                        // A second observation in the same sample.
                        v.push((s, rng.random_range(0.5f32..2.0)));
                    }
                }
                v
            })
            .collect();
        let obs = NeedleObservations::from_lists(&per_needle).unwrap();
        let locs = farthest_point_prototypes(&samples, dim, 7, &mut rng).unwrap();
        let adj = vec![vec![]; 4];
        for nb in variants() {
            let params = ReconstructionParams::default()
                .with_f_near(0.05)
                .with_f_min(0.2)
                .with_min_near(20)
                .with_neighbourhood(nb);
            let cap = brute_cap(&locs.points, dim, &params);
            let shapes =
                prototype_shapes(&samples, dim, &obs, &locs.points, &adj, &params).unwrap();
            assert_eq!(shapes.neighbourhood.radius, cap);
            assert_eq!(shapes.neighbourhood.estimates, 7 * 4);
            for k in 0..7 {
                for j in 0..4 {
                    let (s, l) = obs.needle(j);
                    let p = &locs.points[k * dim..(k + 1) * dim];
                    assert_eq!(
                        shapes.shape(k)[j],
                        brute(&samples, dim, s, l, p, &params, cap),
                        "dim {dim}, {nb:?}"
                    );
                }
            }
        }
    }
}

#[test]
fn large_pose_groups_match_brute_force() {
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    let dim = 4;
    // Two poses held for 150 and 90 samples among 300 distinct ones, interleaved in time.
    let distinct = uniform_points(&mut rng, 300, dim);
    let mut samples = vec![];
    for (i, row) in distinct.chunks_exact(dim).enumerate() {
        samples.extend_from_slice(row);
        if i % 2 == 0 {
            samples.extend_from_slice(&distinct[..dim]);
        }
        if i % 3 == 0 {
            samples.extend_from_slice(&distinct[dim..2 * dim]);
        }
    }
    let count = samples.len() / dim;
    let per_needle: Vec<Vec<(u32, f32)>> = (0..3)
        .map(|_| {
            let mut v = vec![];
            for s in 0..count as u32 {
                if rng.random_range(0.0f32..1.0) < 0.7 {
                    v.push((s, rng.random_range(0.5f32..2.0)));
                }
            }
            v
        })
        .collect();
    let obs = NeedleObservations::from_lists(&per_needle).unwrap();
    let locs = farthest_point_prototypes(&samples, dim, 9, &mut rng).unwrap();
    let mut points = locs.points.clone();
    // Prototypes at the held poses themselves, too.
    points.extend_from_slice(&distinct[..2 * dim]);
    for (f_near, nb) in [0.01, 0.05, 0.3]
        .into_iter()
        .flat_map(|f| variants().map(|nb| (f, nb)))
    {
        let params = ReconstructionParams::default()
            .with_f_near(f_near)
            .with_f_min(0.2)
            .with_neighbourhood(nb);
        let cap = brute_cap(&points, dim, &params);
        let shapes =
            prototype_shapes(&samples, dim, &obs, &points, &vec![vec![]; 3], &params).unwrap();
        for (k, p) in points.chunks_exact(dim).enumerate() {
            for j in 0..3 {
                let (s, l) = obs.needle(j);
                assert_eq!(
                    shapes.shape(k)[j],
                    brute(&samples, dim, s, l, p, &params, cap),
                    "f_near {f_near}, {nb:?}, prototype {k}, needle {j}"
                );
            }
        }
    }
}

/// 1-D: 3 000 samples at rest (0) with short lengths, a sparse sweep of 40 samples over
/// [1, 2] with long ones; prototypes at rest and along the sweep, spacing 0.25.
fn rest_and_sparse_sweep() -> (Vec<f32>, NeedleObservations, Vec<f32>) {
    let mut samples = vec![0.0f32; 3000];
    samples.extend((0..40).map(|i| 1.0 + i as f32 / 39.0));
    let per_needle = vec![(0..samples.len() as u32)
        .map(|s| {
            (
                s,
                if s < 3000 {
                    1.0
                } else {
                    2.0 + samples[s as usize]
                },
            )
        })
        .collect::<Vec<_>>()];
    let obs = NeedleObservations::from_lists(&per_needle).unwrap();
    let points = vec![0.0f32, 1.0, 1.25, 1.5, 1.75, 2.0];
    (samples, obs, points)
}

#[test]
fn capped_neighbourhood_keeps_a_far_tie_group_out() {
    let (samples, obs, points) = rest_and_sparse_sweep();
    let adj = [vec![]];
    // F_near · m = 67 > the 40 sweep samples: the paper's walk reaches the rest pose from
    // every prototype and takes its 3 000 views whole, so every prototype is the static 1.
    let fraction = ReconstructionParams::default()
        .with_min_near(10)
        .with_neighbourhood(Neighbourhood::Fraction);
    let shapes = prototype_shapes(&samples, 1, &obs, &points, &adj, &fraction).unwrap();
    assert!(
        shapes.lengths.iter().all(|&l| l == 1.0),
        "{:?}",
        shapes.lengths
    );
    assert_eq!(shapes.neighbourhood.floor_bound, 0);
    assert_eq!(shapes.neighbourhood.radius, None);
    // Capped at one spacing (0.25): the sweep prototypes see only sweep views (ball of
    // ≥ 10 observations, so the floor does not bind); the rest prototype sees rest.
    let capped = fraction.with_neighbourhood(Neighbourhood::Capped { radius_factor: 1.0 });
    let shapes = prototype_shapes(&samples, 1, &obs, &points, &adj, &capped).unwrap();
    assert_eq!(shapes.neighbourhood.radius, Some(0.25));
    assert_eq!(shapes.neighbourhood.floor_bound, 0);
    assert_eq!(shapes.shape(0)[0], 1.0);
    for (k, &p) in points.iter().enumerate().skip(1) {
        let v = shapes.shape(k)[0];
        assert!((v - (2.0 + p)).abs() < 0.3, "prototype at {p}: {v}");
        let (s, l) = obs.needle(0);
        assert_eq!(v, brute(&samples, 1, s, l, &[p], &capped, Some(0.25)));
    }
}

#[test]
fn capped_neighbourhood_floors_a_rarely_seen_needle() {
    let (samples, _, points) = rest_and_sparse_sweep();
    // Needle 0 seen in 12 sweep samples only, all above 1.7; needle 1 everywhere.
    let per_needle = vec![
        (3000..3040u32)
            .filter(|&s| samples[s as usize] > 1.7)
            .map(|s| (s, 2.0 + samples[s as usize]))
            .collect::<Vec<_>>(),
        (0..3040u32).map(|s| (s, 1.5)).collect(),
    ];
    let obs = NeedleObservations::from_lists(&per_needle).unwrap();
    let params = ReconstructionParams::default()
        .with_min_near(8)
        .with_neighbourhood(Neighbourhood::Capped { radius_factor: 1.0 });
    let shapes = prototype_shapes(&samples, 1, &obs, &points, &[vec![], vec![]], &params).unwrap();
    let (s, l) = obs.needle(0);
    assert_eq!(s.len(), 12);
    for (k, &p) in points.iter().enumerate() {
        let v = shapes.shape(k)[0];
        assert_eq!(
            v,
            brute(&samples, 1, s, l, &[p], &params, Some(0.25)),
            "{p}"
        );
    }
    // Prototypes at 0, 1, 1.25 have an empty ball for needle 0 (its views start above
    // 1.7), the one at 1.5 a ball of 1–2: the floor binds, the 8 nearest views are used.
    // Needle 1 has 3 000 views in the rest ball, but only ≈ 10 in each sweep ball (≥ 8).
    let mut nearest8: Vec<f32> = l.to_vec();
    nearest8.sort_by(f32::total_cmp);
    let mut low8 = nearest8[..8].to_vec();
    assert_eq!(shapes.shape(0)[0], robust_minimum(&mut low8, params.f_min));
    assert_eq!(shapes.neighbourhood.floor_bound, 4);
    assert_eq!(shapes.neighbourhood.estimates, 12);
    // The same needle under the paper's rule uses the 8 nearest everywhere, never floored.
    let fraction = params.with_neighbourhood(Neighbourhood::Fraction);
    let shapes =
        prototype_shapes(&samples, 1, &obs, &points, &[vec![], vec![]], &fraction).unwrap();
    assert_eq!(shapes.neighbourhood.floor_bound, 0);
    assert_eq!(shapes.shape(0)[0], robust_minimum(&mut low8, params.f_min));
}

#[test]
fn tied_configurations_are_all_near_not_the_first_in_time() {
    // 1000 frames at one rest configuration, then 100 elsewhere. Lengths at rest fall with
    // time (later views are tighter), so a tie cut by sample index would keep the
    // earliest, longest observations.
    let dim = 3;
    let mut samples = vec![0.25f32; 1000 * dim];
    samples.extend((0..100 * dim).map(|i| 1.0 + (i % 7) as f32 * 0.1));
    let per_needle = vec![(0..1100u32)
        .map(|s| (s, if s < 1000 { 2.0 - s as f32 * 1e-3 } else { 5.0 }))
        .collect::<Vec<_>>()];
    let obs = NeedleObservations::from_lists(&per_needle).unwrap();
    let params = ReconstructionParams::default()
        .with_f_near(0.02)
        .with_f_min(0.1);
    let rest = [0.25f32; 3];
    let shapes = prototype_shapes(&samples, dim, &obs, &rest, &[vec![]], &params).unwrap();
    // Every one of the 1000 rest observations is used: their 10th percentile. The first
    // 22 in time would have given 1.98.
    let mut rest_lengths: Vec<f32> = (0..1000).map(|s| 2.0 - s as f32 * 1e-3).collect();
    assert_eq!(shapes.shape(0)[0], robust_minimum(&mut rest_lengths, 0.1));
    // The same when the tie is too small for the pre-sorted path.
    let mut small = samples.clone();
    small[..dim * (1000 - LARGE_TIE_SAMPLES)].fill(0.3);
    let shapes = prototype_shapes(&small, dim, &obs, &rest, &[vec![]], &params).unwrap();
    let mut tied: Vec<f32> = (1000 - LARGE_TIE_SAMPLES as u32..1000)
        .map(|s| 2.0 - s as f32 * 1e-3)
        .collect();
    assert_eq!(shapes.shape(0)[0], robust_minimum(&mut tied, 0.1));
}

#[test]
fn unobserved_needles_are_filled_from_neighbours() {
    // A ring of 6 needles; needles 2 and 3 are never observed.
    let samples = [0.0f32, 1.0, 2.0, 3.0];
    let per_needle: Vec<Vec<(u32, f32)>> = (0..6)
        .map(|j| {
            if j == 2 || j == 3 {
                vec![]
            } else {
                (0..4u32).map(|s| (s, j as f32 + 1.0)).collect()
            }
        })
        .collect();
    let obs = NeedleObservations::from_lists(&per_needle).unwrap();
    let adj: Vec<Vec<u16>> = (0..6u16).map(|j| vec![(j + 5) % 6, (j + 1) % 6]).collect();
    let params = ReconstructionParams::default()
        .with_f_near(0.5)
        .with_f_min(0.0);
    let shapes = prototype_shapes(&samples, 1, &obs, &[0.0, 3.0], &adj, &params).unwrap();
    assert_eq!(shapes.filled_needles, vec![2, 3]);
    for k in 0..2 {
        let s = shapes.shape(k);
        assert_eq!(s[2], 2.0, "needle 2 = its observed neighbour 1 (length 2)");
        assert_eq!(s[3], 5.0, "needle 3 = its observed neighbour 4 (length 5)");
    }
    // With needles 2..=4 unobserved, needle 3 is filled in a second round from 2 and 4.
    let mut per2 = per_needle.clone();
    per2[4].clear();
    let obs2 = NeedleObservations::from_lists(&per2).unwrap();
    let shapes = prototype_shapes(&samples, 1, &obs2, &[0.0], &adj, &params).unwrap();
    assert_eq!(shapes.shape(0)[2], 2.0);
    assert_eq!(shapes.shape(0)[4], 6.0);
    assert_eq!(shapes.shape(0)[3], 4.0);
    // No neighbours: a clear error.
    let no_adj = vec![vec![]; 6];
    let e = prototype_shapes(&samples, 1, &obs, &[0.0], &no_adj, &params).unwrap_err();
    assert_eq!(e.contexts(), vec![Context::Needle(2)]);
    assert!(matches!(e.root(), Error::NoObservations { .. }));
}

#[test]
fn shapes_reject_bad_input() {
    let samples = [0.0f32, 1.0];
    let p = ReconstructionParams::default();
    let ok = NeedleObservations::from_lists(&[vec![(0, 1.0)]]).unwrap();
    let adj = vec![vec![]];
    let bad_idx = NeedleObservations::from_lists(&[vec![(5, 1.0)]]).unwrap();
    assert!(prototype_shapes(&samples, 1, &ok, &[0.0], &adj, &p).is_ok());
    assert!(matches!(
        prototype_shapes(&samples, 1, &bad_idx, &[0.0], &adj, &p),
        Err(Error::IndexOutOfRange {
            index: 5,
            len: 2,
            ..
        })
    ));
    assert!(matches!(
        prototype_shapes(&samples, 1, &ok, &[f32::NAN], &adj, &p),
        Err(Error::NonFinite { .. })
    ));
    assert!(matches!(
        prototype_shapes(&samples, 1, &ok, &[], &adj, &p),
        Err(Error::Empty { .. })
    ));
    assert!(matches!(
        prototype_shapes(&samples, 1, &ok, &[0.0], &[], &p),
        Err(Error::SizeMismatch { .. })
    ));
    let e = prototype_shapes(&samples, 1, &ok, &[0.0], &[vec![3]], &p).unwrap_err();
    assert_eq!(e.contexts(), vec![Context::Needle(0)]);
    assert!(matches!(e.root(), Error::IndexOutOfRange { index: 3, .. }));
    assert!(matches!(
        prototype_shapes(&samples, 1, &ok, &[0.0], &adj, &p.with_f_near(2.0)),
        Err(Error::InvalidParam { name: "f_near", .. })
    ));
    let none = NeedleObservations::from_lists(&[]).unwrap();
    assert!(matches!(
        prototype_shapes(&samples, 1, &none, &[0.0], &[], &p),
        Err(Error::Empty { .. })
    ));
}
