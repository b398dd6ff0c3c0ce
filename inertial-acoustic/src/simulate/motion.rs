//! The motion the simulated suit performs: a studio motion smoothed, preceded by a rest
//! hold and a blend, interpolated by natural cubic splines (θ, θ̇, θ̈ at any time); and the
//! treadmill loop of a walk (Figure 4-7).

use super::SimulationParams;
use crate::{Error, Result};
use nalgebra::DMatrix;
use skin_core::check::positive;
use skin_core::skeleton::{Motion, Skeleton};
use std::f64::consts::TAU;

/// Natural cubic splines through every DOF of a motion.
#[derive(Debug, Clone)]
pub struct SmoothMotion {
    h: f64,
    y: DMatrix<f64>,
    m: DMatrix<f64>,
}

impl SmoothMotion {
    /// Splines through `frames` (DOFs × frames) spaced `h` seconds.
    pub(super) fn new(h: f64, y: DMatrix<f64>) -> Self {
        let (nd, n) = y.shape();
        let mut m = DMatrix::zeros(nd, n);
        if n >= 3 {
            // Tridiagonal system (h/6, 2h/3, h/6) M = Δ²y / h, natural ends; Thomas algorithm.
            let mut c = vec![0.0; n];
            let mut dd = vec![0.0; n];
            for d in 0..nd {
                c[0] = 0.0;
                dd[0] = 0.0;
                for i in 1..n - 1 {
                    let rhs = (y[(d, i + 1)] - 2.0 * y[(d, i)] + y[(d, i - 1)]) * 6.0 / (h * h);
                    let denom = 4.0 - c[i - 1];
                    c[i] = 1.0 / denom;
                    dd[i] = (rhs - dd[i - 1]) / denom;
                }
                m[(d, n - 1)] = 0.0;
                for i in (1..n - 1).rev() {
                    m[(d, i)] = dd[i] - c[i] * m[(d, i + 1)];
                }
            }
        }
        SmoothMotion { h, y, m }
    }

    /// Duration, seconds.
    pub fn duration_s(&self) -> f64 {
        self.h * (self.y.ncols().saturating_sub(1)) as f64
    }

    /// θ, θ̇, θ̈ at time `t` (clamped into the motion).
    pub fn eval(&self, t: f64, theta: &mut [f64], rate: &mut [f64], acc: &mut [f64]) {
        let n = self.y.ncols();
        let h = self.h;
        let s = (t / h).clamp(0.0, (n - 1) as f64);
        let i = (s.floor() as usize).min(n.saturating_sub(2));
        let u = s - i as f64;
        let (a, b) = (1.0 - u, u);
        for d in 0..self.y.nrows() {
            let (y0, y1) = (self.y[(d, i)], self.y[(d, (i + 1).min(n - 1))]);
            let (m0, m1) = (self.m[(d, i)], self.m[(d, (i + 1).min(n - 1))]);
            theta[d] =
                a * y0 + b * y1 + ((a * a * a - a) * m0 + (b * b * b - b) * m1) * h * h / 6.0;
            rate[d] =
                (y1 - y0) / h + ((1.0 - 3.0 * a * a) * m0 + (3.0 * b * b - 1.0) * m1) * h / 6.0;
            acc[d] = a * m0 + b * m1;
        }
    }
}

/// The motion the suit performs: `motion` smoothed, after a rest hold and a blend.
///
/// # Errors
/// As [`Motion::check_for`].
pub fn prepare_motion(
    skeleton: &Skeleton,
    motion: &Motion,
    params: &SimulationParams,
) -> Result<SmoothMotion> {
    motion.check_for(skeleton)?;
    params.validate()?;
    let h = motion.frame_time_s;
    let mut frames = motion.frames.clone();
    // Unwrap rotation DOFs (mocap decompositions jump by 2π), so splines do not swing round.
    for d in 0..frames.nrows() {
        if skeleton.is_rotation(d) {
            for k in 1..frames.ncols() {
                let jump = frames[(d, k)] - frames[(d, k - 1)];
                frames[(d, k)] -= TAU * (jump / TAU).round();
            }
        }
    }
    for _ in 0..params.smoothing_passes {
        let prev = frames.clone();
        let n = prev.ncols();
        for k in 1..n.saturating_sub(1) {
            for d in 0..prev.nrows() {
                frames[(d, k)] =
                    0.25 * prev[(d, k - 1)] + 0.5 * prev[(d, k)] + 0.25 * prev[(d, k + 1)];
            }
        }
    }
    let nd = skeleton.dof_count();
    let root: Vec<usize> = skeleton.joint_dofs(0).collect();
    let first: Vec<f64> = frames.column(0).iter().copied().collect();
    let mut rest = first.clone();
    for (d, v) in rest.iter_mut().enumerate() {
        if !root.contains(&d) {
            *v = 0.0;
        }
    }
    let n_rest = (params.rest_s / h).round() as usize;
    let n_blend = (params.blend_s / h).round() as usize;
    let n = n_rest + n_blend + frames.ncols();
    let mut y = DMatrix::zeros(nd, n);
    for k in 0..n {
        for d in 0..nd {
            y[(d, k)] = if k < n_rest {
                rest[d]
            } else if k < n_rest + n_blend {
                let u = (k - n_rest) as f64 / n_blend.max(1) as f64;
                let s = u * u * (3.0 - 2.0 * u);
                rest[d] + s * (first[d] - rest[d])
            } else {
                frames[(d, k - n_rest - n_blend)]
            };
        }
    }
    Ok(SmoothMotion::new(h, y))
}

/// Shortest gait cycle [`treadmill_motion`] loops, seconds (a stride is ≈ 1 s).
pub const TREADMILL_MIN_CYCLE_S: f64 = 0.8;

/// A treadmill-like motion (Figure 4-7) from a walk: a gait cycle of the walk looped until
/// `duration_s`, the root's horizontal translation removed (the treadmill) and its yaw held
/// at the first frame's.
///
/// **The loop.** The cycle is the pair of frames `i < j`, at least
/// [`TREADMILL_MIN_CYCLE_S`] apart, whose poses *and* velocities agree best over every DOF
/// except the three held ones: cost `‖θᵢ − θⱼ‖² + (τ/Δt)² ‖Δθᵢ − Δθⱼ‖²` with τ = 0.1 s
/// (the usual motion-graph transition cost, Kovar et al. 2002, on joint angles). Frames
/// `i … j−1` repeat; the residual `θᵢ − θⱼ` is spread linearly over each cycle, so the
/// looped motion is continuous in angle and, up to the chosen residual, in rate. (An earlier
/// version played the walk forwards and backwards: every reversal flipped all joint rates in
/// one frame, an impulse no body and no constant-acceleration filter follows — it made even
/// the oracle filter diverge on the treadmill.) Only stretches over which the root travels at
/// [`TREADMILL_MIN_SPEED_M_S`] or more are candidates: a pause matches itself best of all.
///
/// # Errors
/// As [`Motion::check_for`]; [`Error::InvalidParam`] for a skeleton without the human root
/// DOFs, a non-positive duration or a walk shorter than two cycles' search needs.
pub fn treadmill_motion(skeleton: &Skeleton, walk: &Motion, duration_s: f64) -> Result<Motion> {
    walk.check_for(skeleton)?;
    positive("duration_s", duration_s)?;
    let find = |name: &'static str| {
        skeleton.dof_index(name).ok_or(Error::InvalidParam {
            name: "skeleton",
            reason: format!("no DOF {name}"),
        })
    };
    let (tx, tz, yaw) = (find("pelvis.tx")?, find("pelvis.tz")?, find("pelvis.yaw")?);
    let (n, nd) = (walk.frame_count(), skeleton.dof_count());
    let dt = walk.frame_time_s;
    let min_len = (TREADMILL_MIN_CYCLE_S / dt).round().max(2.0) as usize;
    if n < min_len + 2 {
        return Err(Error::InvalidParam {
            name: "walk",
            reason: format!(
                "{n} frames: a gait cycle needs at least {} ({TREADMILL_MIN_CYCLE_S} s)",
                min_len + 2
            ),
        });
    }
    let looped: Vec<usize> = (0..nd)
        .filter(|&d| d != tx && d != tz && d != yaw)
        .collect();
    let (start, end) = gait_cycle(walk, &looped, (tx, tz), min_len)?;
    let len = end - start;
    let total = (duration_s / dt).round() as usize + 1;
    let mut frames = DMatrix::zeros(nd, total);
    for k in 0..total {
        let m = k % len;
        let src = start + m;
        let ramp = m as f64 / len as f64;
        for &d in &looped {
            let residual = walk.frames[(d, start)] - walk.frames[(d, end)];
            frames[(d, k)] = walk.frames[(d, src)] + ramp * residual;
        }
        frames[(tx, k)] = walk.frames[(tx, 0)];
        frames[(tz, k)] = walk.frames[(tz, 0)];
        frames[(yaw, k)] = walk.frames[(yaw, 0)];
    }
    Ok(Motion::new(dt, frames)?)
}

/// Least average root speed of a looped cycle, m/s: a walking cycle, not a pause (a standing
/// stretch matches itself best of all).
pub const TREADMILL_MIN_SPEED_M_S: f64 = 0.5;

/// The frames `(i, j)` of [`treadmill_motion`]'s loop: the lowest transition cost over the
/// `looped` DOFs among pairs at least `min_len` frames apart over which the root (DOFs
/// `root_xz`) travels at [`TREADMILL_MIN_SPEED_M_S`] or more on average.
fn gait_cycle(
    walk: &Motion,
    looped: &[usize],
    root_xz: (usize, usize),
    min_len: usize,
) -> Result<(usize, usize)> {
    let n = walk.frame_count();
    let dt = walk.frame_time_s;
    let w = (0.1 / dt).powi(2);
    let f = &walk.frames;
    let cost = |i: usize, j: usize| -> f64 {
        looped
            .iter()
            .map(|&d| {
                let (a, b) = (f[(d, i)], f[(d, j)]);
                let (va, vb) = (f[(d, i + 1)] - a, f[(d, j + 1)] - b);
                (a - b).powi(2) + w * (va - vb).powi(2)
            })
            .sum()
    };
    let travel = |i: usize, j: usize| {
        let (x, z) = root_xz;
        (f[(x, j)] - f[(x, i)]).hypot(f[(z, j)] - f[(z, i)])
    };
    let mut best: Option<(f64, usize, usize)> = None;
    for i in 0..n.saturating_sub(1 + min_len) {
        for j in i + min_len..n - 1 {
            if travel(i, j) < TREADMILL_MIN_SPEED_M_S * (j - i) as f64 * dt {
                continue;
            }
            let c = cost(i, j);
            if best.is_none_or(|(b, _, _)| c < b) {
                best = Some((c, i, j));
            }
        }
    }
    best.map(|(_, i, j)| (i, j)).ok_or(Error::InvalidParam {
        name: "walk",
        reason: format!(
            "no stretch of at least {:.2} s in which the root travels at {TREADMILL_MIN_SPEED_M_S} m/s",
            min_len as f64 * dt
        ),
    })
}
