//! The FilterPy peer workload (`../shared/bench/peers/ekf.py`, workload 4) regenerated in
//! Rust with the skeletal filter's structure: 40 DOFs, state (θ, θ̇, θ̈) (120), dt = 1/60,
//! `F = [[I, dt I, dt²/2 I], [0, I, dt I], [0, 0, I]]` applied block-wise (O(N²)),
//! `Q = diag(1e-6 I, 1e-4 I, 1e-2 I)`, P0 = I; 54 readings `h = sin(W1 θ) + cos(W2 θ)` with
//! `R = 1e-4 I` processed as sequential scalar updates with one linearisation per step
//! (innovation corrected to first order for the rows before it) — the same estimate as
//! FilterPy's batch update, since R is diagonal. Inputs from the peers' SplitMix64 stream
//! (bit-exact uniforms), timing as ekf.py: per predict + update step, median of 3 runs of
//! 1000 steps, input generation not timed. Prints the peer line shape.

use dynamic_shapes::core::random::SplitMix64;
use nalgebra::{DMatrix, DVector};
use serde_json::{json, Value};

const D: usize = 40;
const NZ: usize = 54;
const T: usize = 1000;
const DT: f64 = 1.0 / 60.0;

struct Workload {
    w1: DMatrix<f64>,
    w2: DMatrix<f64>,
    truth: Vec<DVector<f64>>,
    z: Vec<DVector<f64>>,
}

fn workload() -> Workload {
    let mat = |seed, rows, cols, scale: f64| {
        let v = SplitMix64::new(seed).normal(rows * cols);
        DMatrix::from_row_iterator(rows, cols, v.into_iter().map(|x| scale * x))
    };
    let w1 = mat(50, NZ, D, 0.3);
    let w2 = mat(51, NZ, D, 0.3);
    let a: Vec<f64> = SplitMix64::new(52)
        .uniform(D)
        .iter()
        .map(|u| 0.2 + 0.8 * u)
        .collect();
    let om: Vec<f64> = SplitMix64::new(53)
        .uniform(D)
        .iter()
        .map(|u| 0.5 + 4.5 * u)
        .collect();
    let ph: Vec<f64> = SplitMix64::new(54)
        .uniform(D)
        .iter()
        .map(|u| std::f64::consts::TAU * u)
        .collect();
    let noise = mat(55, T, NZ, 0.01);
    let mut truth = Vec::with_capacity(T);
    let mut z = Vec::with_capacity(T);
    for k in 1..=T {
        let t = DT * k as f64;
        let th = DVector::from_fn(D, |d, _| a[d] * (om[d] * t + ph[d]).sin());
        let h = (&w1 * &th).map(f64::sin) + (&w2 * &th).map(f64::cos);
        z.push(h + noise.row(k - 1).transpose());
        truth.push(th);
    }
    Workload { w1, w2, truth, z }
}

/// One run of T steps; returns the θ estimates.
fn filter(w: &Workload) -> Vec<DVector<f64>> {
    let n = 3 * D;
    let mut x = DVector::<f64>::zeros(n);
    let mut p = DMatrix::<f64>::identity(n, n);
    let q = [1e-6, 1e-4, 1e-2];
    let r = 1e-4;
    let mut est = Vec::with_capacity(T);
    let mut hrow = vec![0.0; D];
    let mut ph = vec![0.0; n];
    for zk in &w.z {
        // Predict: x = F x; P = F P Fᵀ + Q, F applied block-wise.
        for i in 0..D {
            x[i] += DT * x[D + i] + 0.5 * DT * DT * x[2 * D + i];
            x[D + i] += DT * x[2 * D + i];
        }
        {
            let data = p.as_mut_slice();
            // Rows: row block 0 += dt row block 1 + dt²/2 row block 2; block 1 += dt block 2.
            for c in 0..n {
                let col = &mut data[c * n..(c + 1) * n];
                for i in 0..D {
                    col[i] += DT * col[D + i] + 0.5 * DT * DT * col[2 * D + i];
                    col[D + i] += DT * col[2 * D + i];
                }
            }
            // Columns likewise.
            for i in 0..D {
                for rr in 0..n {
                    let v =
                        DT * data[(D + i) * n + rr] + 0.5 * DT * DT * data[(2 * D + i) * n + rr];
                    data[i * n + rr] += v;
                }
                for rr in 0..n {
                    let v = DT * data[(2 * D + i) * n + rr];
                    data[(D + i) * n + rr] += v;
                }
            }
        }
        for (b, qb) in q.iter().enumerate() {
            for i in 0..D {
                p[(b * D + i, b * D + i)] += qb;
            }
        }
        // Linearise once at the prior.
        let th0 = x.rows(0, D).into_owned();
        let s1 = &w.w1 * &th0;
        let s2 = &w.w2 * &th0;
        let x0 = th0.clone();
        for m in 0..NZ {
            let (c, s) = (s1[m].cos(), s2[m].sin());
            for (d, h) in hrow.iter_mut().enumerate() {
                *h = c * w.w1[(m, d)] - s * w.w2[(m, d)];
            }
            let h0 = s1[m].sin() + s2[m].cos();
            let lin: f64 = (0..D).map(|d| hrow[d] * (x[d] - x0[d])).sum();
            let innov = zk[m] - h0 - lin;
            // P Hᵀ (H touches the θ block only). Only the lower triangle of P is kept
            // current between predictions (as the crate's filter does): P[r, d] for r < d is
            // read from its mirror P[d, r].
            let data = p.as_slice();
            ph.fill(0.0);
            for (d, hd) in hrow.iter().enumerate() {
                for (rr, o) in ph[..d].iter_mut().enumerate() {
                    *o += hd * data[rr * n + d];
                }
                let col = &data[d * n + d..(d + 1) * n];
                for (o, pc) in ph[d..].iter_mut().zip(col) {
                    *o += hd * pc;
                }
            }
            let sv: f64 = (0..D).map(|d| hrow[d] * ph[d]).sum::<f64>() + r;
            let k = innov / sv;
            for (xi, pi) in x.iter_mut().zip(&ph) {
                *xi += pi * k;
            }
            let data = p.as_mut_slice();
            for c in 0..n {
                let f = ph[c] / sv;
                let col = &mut data[c * n + c..(c + 1) * n];
                for (o, pr) in col.iter_mut().zip(&ph[c..]) {
                    *o -= pr * f;
                }
            }
        }
        // Mirror the lower triangle before the next prediction.
        let data = p.as_mut_slice();
        for c in 1..n {
            for rr in 0..c {
                data[c * n + rr] = data[rr * n + c];
            }
        }
        est.push(x.rows(0, D).into_owned());
    }
    est
}

/// Runs the workload (median of 3) and returns the peer-shaped line.
pub fn run() -> Value {
    let w = workload();
    let mut times = Vec::new();
    let mut est = Vec::new();
    for _ in 0..3 {
        let t0 = std::time::Instant::now();
        est = filter(&w);
        times.push(t0.elapsed().as_secs_f64());
    }
    let mut sorted = times.clone();
    sorted.sort_by(f64::total_cmp);
    let med = sorted[1];
    let mut se = 0.0;
    for (e, t) in est[T / 2..].iter().zip(&w.truth[T / 2..]) {
        se += (e - t).norm_squared();
    }
    let rms = (se / ((T - T / 2) * D) as f64).sqrt();
    json!({
        "workload": "ekf",
        "peer": "rust:inertial_capture sequential scalar EKF (block F)",
        "size": {"dim_x": 3 * D, "dim_z": NZ, "steps": T},
        "seconds": med / T as f64,
        "unit": "seconds per predict+update step",
        "quality": {"rms_angle_err": rms},
        "total_seconds": times,
    })
}
