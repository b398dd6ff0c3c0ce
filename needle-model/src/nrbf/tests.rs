use super::*;
use rand::RngExt;

const DIM: usize = 3;
const NEEDLES: usize = 24;

/// Synthetic primitive: needle `j`'s true length is a smooth function of a 3-D
/// configuration point; observations overestimate it one-sidedly, like silhouette walks
/// (small positive noise, and 15 % large "occluded" overestimates), and each needle is
/// seen in about half of the samples.
struct Synthetic {
    freq: Vec<[f32; 3]>,
    phase: Vec<f32>,
}

impl Synthetic {
    fn new(rng: &mut ChaCha8Rng) -> Self {
        let freq = (0..NEEDLES)
            .map(|_| std::array::from_fn(|_| rng.random_range(-1.2f32..1.2)))
            .collect();
        let phase = (0..NEEDLES)
            .map(|_| rng.random_range(0.0f32..std::f32::consts::TAU))
            .collect();
        Self { freq, phase }
    }

    fn truth(&self, x: &[f32], j: usize) -> f32 {
        let a = &self.freq[j];
        1.0 + 0.25 * (a[0] * x[0] + a[1] * x[1] + a[2] * x[2] + self.phase[j]).sin()
    }

    fn data(&self, rng: &mut ChaCha8Rng, count: usize) -> (Vec<f32>, NeedleObservations) {
        let samples: Vec<f32> = (0..count * DIM)
            .map(|_| rng.random_range(-1.0f32..1.0))
            .collect();
        self.observe(rng, samples)
    }

    /// Observations of every needle along given configuration samples.
    fn observe(&self, rng: &mut ChaCha8Rng, samples: Vec<f32>) -> (Vec<f32>, NeedleObservations) {
        let mut per_needle = vec![Vec::new(); NEEDLES];
        for (s, x) in samples.chunks_exact(DIM).enumerate() {
            for (j, list) in per_needle.iter_mut().enumerate() {
                if rng.random_range(0.0f32..1.0) < 0.5 {
                    let u: f32 = rng.random_range(f32::EPSILON..1.0);
                    let mut l = self.truth(x, j) - 0.005 * u.ln();
                    if rng.random_range(0.0f32..1.0) < 0.15 {
                        l += rng.random_range(0.0f32..1.0);
                    }
                    list.push((s as u32, l));
                }
            }
        }
        (
            samples,
            NeedleObservations::from_lists(&per_needle).unwrap(),
        )
    }

    /// RMS error over held-out interior points.
    fn rms_error(&self, model: &Nrbf, rng: &mut ChaCha8Rng) -> f32 {
        let pts: Vec<f32> = (0..400 * DIM)
            .map(|_| rng.random_range(-0.85f32..0.85))
            .collect();
        self.rms_error_at(model, &pts)
    }

    fn rms_error_at(&self, model: &Nrbf, pts: &[f32]) -> f32 {
        let count = pts.len() / DIM;
        let pred = model.evaluate_batch(pts).unwrap();
        let mut ss = 0.0f64;
        for (x, p) in pts.chunks_exact(DIM).zip(pred.chunks_exact(NEEDLES)) {
            for (j, &l) in p.iter().enumerate() {
                ss += ((l - self.truth(x, j)) as f64).powi(2);
            }
        }
        (ss / (count * NEEDLES) as f64).sqrt() as f32
    }
}

fn ring_adjacency() -> Vec<Vec<u16>> {
    (0..NEEDLES as u16)
        .map(|j| {
            vec![
                (j + 1) % NEEDLES as u16,
                (j + NEEDLES as u16 - 1) % NEEDLES as u16,
            ]
        })
        .collect()
}

fn fit_error(params: &ReconstructionParams, count: usize, seed: u64) -> (f32, NrbfFit) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let syn = Synthetic::new(&mut rng);
    let (samples, obs) = syn.data(&mut rng, count);
    let fit = Nrbf::fit(&samples, DIM, &obs, &ring_adjacency(), params).unwrap();
    (syn.rms_error(&fit.model, &mut rng), fit)
}

#[test]
fn recovers_true_function_on_held_out_points() {
    let params = ReconstructionParams::default();
    let (err, fit) = fit_error(&params, 16_000, 1);
    let (static_err, _) = fit_error(&params.with_f_near(1.0), 16_000, 1);
    eprintln!("held-out RMS: nrbf {err:.4}, static {static_err:.4}");
    assert_eq!(fit.model.num_prototypes(), 100);
    assert!(err < 0.05, "held-out RMS error {err} (amplitude 0.25)");
    assert!(err < 0.35 * static_err, "nrbf {err} vs static {static_err}");
}

#[test]
fn error_falls_as_prototypes_are_added() {
    let errs: Vec<f32> = [10usize, 30, 100, 300]
        .iter()
        .map(|&n| {
            let p = ReconstructionParams::default().with_prototype_count_n(n);
            fit_error(&p, 16_000, 2).0
        })
        .collect();
    eprintln!("N = 10, 30, 100, 300 -> RMS {errs:?}");
    for w in errs.windows(2) {
        assert!(w[1] < w[0] * 1.05, "error should not grow with N: {errs:?}");
    }
    assert!(errs[3] < 0.65 * errs[0], "{errs:?}");
}

/// A performer's motion: a 3-D Lissajous path through configuration space at time `t`.
fn motion_at(t: f32) -> [f32; 3] {
    const OMEGA: [f32; 3] = [0.5, 0.707, 0.866];
    OMEGA.map(|w| 0.9 * (w * t).sin())
}

/// `count` samples of the motion at a fixed rate: a longer capture covers more of the
/// range of motion.
fn motion(count: usize) -> Vec<f32> {
    const DT: f32 = 0.005;
    (0..count).flat_map(|i| motion_at(i as f32 * DT)).collect()
}

#[test]
fn error_falls_with_more_training_data() {
    // As in Sand's thesis Figure 6-2 (30 s vs 3 min of motion): a longer capture covers
    // more of the range of motion, so unseen poses of the same motion (random times) are
    // predicted better. (With F_near fixed, the neighbourhood is a fixed fraction of the
    // data, so the robust-minimum bias inside a well-covered region does not shrink with
    // more data; coverage and noise do.)
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let syn = Synthetic::new(&mut rng);
    let held_out: Vec<f32> = (0..2_000)
        .flat_map(|_| motion_at(rng.random_range(0.0f32..10_000.0)))
        .collect();
    let errs: Vec<f32> = [1_000usize, 4_000, 16_000]
        .iter()
        .map(|&count| {
            let (samples, obs) = syn.observe(&mut rng, motion(count));
            let fit = Nrbf::fit(
                &samples,
                DIM,
                &obs,
                &ring_adjacency(),
                &ReconstructionParams::default(),
            )
            .unwrap();
            syn.rms_error_at(&fit.model, &held_out)
        })
        .collect();
    eprintln!("S = 1000, 4000, 16000 -> RMS {errs:?}");
    for w in errs.windows(2) {
        assert!(w[1] < w[0], "error should fall with more data: {errs:?}");
    }
    assert!(errs[2] < 0.7 * errs[0], "{errs:?}");
}

#[test]
fn f_near_one_gives_a_static_model() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let syn = Synthetic::new(&mut rng);
    let (samples, obs) = syn.data(&mut rng, 2_000);
    let params = ReconstructionParams::default().with_f_near(1.0);
    let fit = Nrbf::fit(&samples, DIM, &obs, &ring_adjacency(), &params).unwrap();
    for j in 0..NEEDLES {
        let mut all = obs.needle(j).1.to_vec();
        all.sort_by(f32::total_cmp);
        let expect = all[crate::prototype_shapes::percentile_index(all.len(), params.f_min)];
        for k in 0..fit.model.num_prototypes() {
            assert_eq!(fit.model.shapes()[k * NEEDLES + j], expect);
        }
        for x in [[0.3f32, -0.2, 0.9], [5.0, 5.0, -5.0]] {
            let l = fit.model.evaluate(&x).unwrap()[j];
            assert!((l - expect).abs() < 1e-5 * expect);
        }
    }
}

#[test]
fn weights_are_normalised_and_extrapolate_to_nearest_prototype() {
    let (_, fit) = fit_error(
        &ReconstructionParams::default().with_prototype_count_n(20),
        2_000,
        5,
    );
    let m = &fit.model;
    let w = m.weights(&[0.1, 0.2, -0.3]).unwrap();
    assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
    assert!(w.iter().all(|&v| v >= 0.0));
    // Far away: the NRBF replicates the nearest prototype (§5.1), no 0/0.
    let far = [1e4f32, -3e3, 2e4];
    let nearest = m
        .prototypes()
        .chunks_exact(DIM)
        .enumerate()
        .map(|(k, p)| {
            (
                k,
                p.iter()
                    .zip(&far)
                    .map(|(a, b)| (a - b).powi(2))
                    .sum::<f32>(),
            )
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap()
        .0;
    let l = m.evaluate(&far).unwrap();
    for (a, b) in l
        .iter()
        .zip(&m.shapes()[nearest * NEEDLES..(nearest + 1) * NEEDLES])
    {
        assert!((a - b).abs() < 1e-5);
    }
    // Batch evaluation equals single evaluation.
    let pts = [0.1f32, 0.2, -0.3, 0.5, 0.5, 0.5];
    let batch = m.evaluate_batch(&pts).unwrap();
    assert_eq!(&batch[..NEEDLES], &m.evaluate(&pts[..3]).unwrap()[..]);
    assert_eq!(&batch[NEEDLES..], &m.evaluate(&pts[3..]).unwrap()[..]);
}

#[test]
fn serde_round_trip_preserves_predictions() {
    let (_, fit) = fit_error(
        &ReconstructionParams::default().with_prototype_count_n(15),
        1_000,
        6,
    );
    let json = serde_json::to_string(&fit.model).unwrap();
    let back: Nrbf = serde_json::from_str(&json).unwrap();
    assert_eq!(back, fit.model);
    let x = [0.2f32, -0.4, 0.1];
    assert_eq!(back.evaluate(&x).unwrap(), fit.model.evaluate(&x).unwrap());
}

#[test]
fn bad_input_gives_clear_errors() {
    let (_, fit) = fit_error(
        &ReconstructionParams::default().with_prototype_count_n(5),
        500,
        7,
    );
    let m = &fit.model;
    assert!(matches!(
        m.evaluate(&[0.0, 0.0]),
        Err(Error::SizeMismatch { .. })
    ));
    assert!(matches!(
        m.evaluate(&[0.0, f32::NAN, 0.0]),
        Err(Error::NonFinite { .. })
    ));
    assert!(matches!(
        m.weights(&[f32::INFINITY, 0.0, 0.0]),
        Err(Error::NonFinite { .. })
    ));
    assert!(matches!(
        m.evaluate_batch(&[0.0; 4]),
        Err(Error::SizeMismatch { .. })
    ));
    assert!(matches!(
        m.evaluate_into(&[0.0; 3], &mut [0.0; 2]),
        Err(Error::SizeMismatch { .. })
    ));
    let shapes = |n: usize| PrototypeShapes {
        num_needles: 1,
        num_prototypes: n,
        lengths: vec![1.0; n],
        filled_needles: vec![],
        neighbourhood: NeighbourhoodStats {
            estimates: n,
            ..Default::default()
        },
    };
    assert!(matches!(
        Nrbf::new(1, vec![0.0, 1.0], shapes(3), 1.0, 7.0),
        Err(Error::SizeMismatch { .. })
    ));
    assert_eq!(
        Nrbf::new(1, vec![0.0], shapes(1), 0.0, 7.0)
            .unwrap_err()
            .invalid_param_name(),
        Some("config_scale")
    );
    assert_eq!(
        Nrbf::new(1, vec![0.0], shapes(1), 1.0, -1.0)
            .unwrap_err()
            .invalid_param_name(),
        Some("kernel_width_w")
    );
    assert!(matches!(
        Nrbf::new(1, vec![f32::NAN], shapes(1), 1.0, 7.0),
        Err(Error::NonFinite { .. })
    ));
    let mut nan_shape = shapes(1);
    nan_shape.lengths[0] = f32::NAN;
    assert!(matches!(
        Nrbf::new(1, vec![0.0], nan_shape, 1.0, 7.0),
        Err(Error::NonFinite { .. })
    ));
    let obs = NeedleObservations::from_lists(&[vec![(0, 1.0)]]).unwrap();
    let e = Nrbf::fit(
        &[0.0],
        1,
        &obs,
        &[vec![]],
        &ReconstructionParams::default().with_kernel_width_w(0.0),
    )
    .unwrap_err();
    assert_eq!(e.invalid_param_name(), Some("kernel_width_w"));
    assert!(matches!(
        config_scale(&[f32::NAN], 1),
        Err(Error::NonFinite { .. })
    ));
    assert_eq!(config_scale(&[2.0, 2.0], 1).unwrap(), 1.0);
}
