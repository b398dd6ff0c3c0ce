//! Prototype reconstruction speed (Sand 2003 §5.2–5.3, §5.5) on synthetic observation sets
//! of the paper's size: 8 min × 30 fps × 3 cameras = 43,200 camera-frames, the 12 primitives
//! of Sand's Table 1 (6,600 needles, configuration spaces of 3, 6 and 9 dimensions), each
//! needle seen in 5–60 % of the camera-frames with one-sided (overestimating) noise.
//!
//! * `cargo bench -p needle-model --bench reconstruct` — criterion: farthest-point selection,
//!   one full-size forearm fit (3-D, 400 needles) and batch NRBF evaluation.
//! * `NEEDLE_FULL=1 cargo bench -p needle-model --bench reconstruct` — additionally times the
//!   whole body once (figure `reconstruct_s_24min`, target ≤ 60 s on 2 cores) and prints one
//!   JSON line to stdout before criterion runs.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code
#![allow(missing_docs)] // criterion_group! generates an undocumented public function

use std::hint::black_box;
use std::time::Instant;

use criterion::{criterion_group, criterion_main, Criterion};
use needle_model::{
    farthest_point_prototypes, grid_adjacency, NeedleObservations, Nrbf, ReconstructionParams,
};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

const FRAMES: usize = 14_400; // 8 min at 30 fps
const CAMERAS: usize = 3;

/// (configuration dimension, radial needles, axial needles) per primitive, Sand Table 1.
const TABLE_1: [(usize, usize, usize); 12] = [
    (9, 30, 30), // torso
    (9, 30, 30), // hips
    (6, 20, 20), // right upper arm
    (6, 20, 20), // left upper arm
    (3, 20, 20), // right forearm
    (3, 20, 20), // left forearm
    (6, 20, 30), // right thigh
    (6, 20, 30), // left thigh
    (6, 20, 30), // right calf
    (6, 20, 30), // left calf
    (3, 20, 20), // right foot
    (3, 20, 20), // left foot
];

struct Primitive {
    dim: usize,
    samples: Vec<f32>,
    observations: NeedleObservations,
    adjacency: Vec<Vec<u16>>,
}

/// A synthetic primitive: configuration points follow a smooth multi-frequency motion (in cm,
/// like marker coordinates in the bone frame), shared by the 3 cameras of a frame; needle
/// lengths are a smooth function of the configuration plus one-sided noise.
///
/// With `pose_dependent`, each needle is mostly seen in one half of configuration space
/// (probability `2v` where `sin(c·x + ψ) > 0`, `0.1v` elsewhere), as when a needle faces the
/// cameras only in some poses; this is the hard case for the nearest-observation search,
/// which must walk further from prototypes in the other half.
fn synthetic_primitive(
    dim: usize,
    radial: usize,
    axial: usize,
    seed: u64,
    pose_dependent: bool,
) -> Primitive {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let omega: Vec<f32> = (0..dim).map(|_| rng.random_range(0.2f32..1.5)).collect();
    let phase: Vec<f32> = (0..dim).map(|_| rng.random_range(0.0f32..6.0)).collect();
    let mut samples = Vec::with_capacity(FRAMES * CAMERAS * dim);
    for f in 0..FRAMES {
        let t = f as f32 / 30.0;
        let row: Vec<f32> = (0..dim)
            .map(|d| 10.0 * (omega[d] * t + phase[d]).sin() + rng.random_range(-0.3f32..0.3))
            .collect();
        for _ in 0..CAMERAS {
            samples.extend_from_slice(&row);
        }
    }
    let count = FRAMES * CAMERAS;
    let needles = radial * axial;
    let per_needle: Vec<Vec<(u32, f32)>> = (0..needles)
        .map(|_| {
            let visible = rng.random_range(0.05f32..0.6);
            let a: Vec<f32> = (0..dim).map(|_| rng.random_range(-0.1f32..0.1)).collect();
            let c: Vec<f32> = (0..dim).map(|_| rng.random_range(-0.3f32..0.3)).collect();
            let psi = rng.random_range(0.0f32..6.0);
            let base = rng.random_range(4.0f32..8.0);
            let mut list = Vec::with_capacity((count as f32 * visible) as usize + 16);
            for (s, x) in samples.chunks_exact(dim).enumerate() {
                let v = if !pose_dependent {
                    visible
                } else if (x.iter().zip(&c).map(|(x, c)| x * c).sum::<f32>() + psi).sin() > 0.0 {
                    (2.0 * visible).min(1.0)
                } else {
                    0.1 * visible
                };
                if rng.random_range(0.0f32..1.0) < v {
                    let arg: f32 = x.iter().zip(&a).map(|(x, a)| x * a).sum();
                    let u: f32 = rng.random_range(f32::EPSILON..1.0);
                    let mut l = base + arg.sin() - 0.1 * u.ln();
                    if rng.random_range(0.0f32..1.0) < 0.15 {
                        l += rng.random_range(0.0f32..5.0);
                    }
                    list.push((s as u32, l));
                }
            }
            list
        })
        .collect();
    let adjacency = grid_adjacency(radial, axial).expect("Table 1 grids are small");
    Primitive {
        dim,
        samples,
        observations: NeedleObservations::from_lists(&per_needle).unwrap(),
        adjacency,
    }
}

/// Times the whole body once (generation excluded); returns (fit seconds, observations).
fn full_body(pose_dependent: bool) -> (f64, usize) {
    let params = ReconstructionParams::default();
    let (mut fit_s, mut obs, mut needles) = (0.0f64, 0usize, 0usize);
    for (i, &(dim, radial, axial)) in TABLE_1.iter().enumerate() {
        let p = synthetic_primitive(dim, radial, axial, 100 + i as u64, pose_dependent);
        let t = Instant::now();
        let fit = Nrbf::fit(&p.samples, p.dim, &p.observations, &p.adjacency, &params)
            .expect("synthetic primitive fits");
        let s = t.elapsed().as_secs_f64();
        fit_s += s;
        obs += p.observations.observation_count();
        needles += fit.model.num_needles();
        eprintln!(
            "primitive {i} (pose-dependent visibility {pose_dependent}): dim {dim}, {} needles, {} observations, fit {s:.2} s",
            fit.model.num_needles(),
            p.observations.observation_count()
        );
    }
    assert_eq!(needles, 6_600);
    (fit_s, obs)
}

fn bench(c: &mut Criterion) {
    if std::env::var_os("NEEDLE_FULL").is_some() {
        let wall = Instant::now();
        let (uniform_s, uniform_obs) = full_body(false);
        let (pose_s, pose_obs) = full_body(true);
        println!(
            "{{\"reconstruct_s_24min\": {uniform_s:.2}, \"reconstruct_s_24min_pose_dependent\": {pose_s:.2}, \"samples\": {}, \"needles\": 6600, \"observations\": {uniform_obs}, \"observations_pose_dependent\": {pose_obs}, \"threads\": {}, \"seconds\": {:.2}}}",
            FRAMES * CAMERAS,
            rayon::current_num_threads(),
            wall.elapsed().as_secs_f64()
        );
    }
    let forearm = synthetic_primitive(3, 20, 20, 7, true);
    let params = ReconstructionParams::default();
    let mut g = c.benchmark_group("reconstruct");
    g.sample_size(10);
    g.bench_function("farthest_point_n100_s43200_d9", |b| {
        let p9 = synthetic_primitive(9, 2, 2, 8, false);
        b.iter(|| {
            let mut rng = ChaCha8Rng::seed_from_u64(1);
            farthest_point_prototypes(black_box(&p9.samples), 9, 100, &mut rng)
        })
    });
    g.bench_function("fit_forearm_s43200_j400_d3", |b| {
        b.iter(|| {
            Nrbf::fit(
                black_box(&forearm.samples),
                3,
                &forearm.observations,
                &forearm.adjacency,
                &params,
            )
        })
    });
    let model = Nrbf::fit(
        &forearm.samples,
        3,
        &forearm.observations,
        &forearm.adjacency,
        &params,
    )
    .expect("forearm fits")
    .model;
    let points = &forearm.samples[..1000 * 3];
    g.bench_function("evaluate_batch_1000_j400_n100", |b| {
        b.iter(|| model.evaluate_batch(black_box(points)))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
