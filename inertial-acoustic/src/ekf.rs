// Over 1,000 lines: one `SkeletalEkf`; its time update and observation models share its buffers.
//! The skeletal extended Kalman filter (§4.4): state `x = (θ, θ̇, θ̈)` of the skeleton's free
//! DOFs, dynamics Eq. 4.1 as the exact constant-acceleration transition (`θ += Δt θ̇ +
//! ½Δt² θ̈`, `θ̇ += Δt θ̈`, `θ̈ += w`; the printed first-order `θ += Δt θ̇` with
//! [`FilterParams::first_order_step`]), observations of
//! gyroscopes (Eq. 4.3), accelerometers (Eq. 4.2) and distances (Eq. 4.4) processed
//! sequentially per sensor type, each scalar reading on its own (Eq. 4.7–4.9 with a scalar
//! `H P Hᵀ + R`), with analytic Jacobians from `skin_core::skeleton` (re-linearised once per
//! sensor type; within a type each scalar's innovation is corrected to first order for the
//! updates before it).
//!
//! **Structure.** `F = [[I, Δt I, ½Δt² I], [0, I, Δt I], [0, 0, I]]` is applied to P
//! block-wise in O(N²) (column and row axpys) instead of two dense products; the process noise
//! enters the θ̈ block only (`W = [0; 0; I]`). Observation rows are sparse (only the DOFs on
//! the sensor's chain), so `P Hᵀ` costs O(N · chain) and each scalar update one rank-1
//! downdate of P's lower triangle (mirrored once per frame before the time update).
//!
//! **Known DOFs.** DOFs listed as known (the root transform, as in the thesis's Vicon
//! comparison) are not in the state; their θ, θ̇, θ̈ are supplied every frame.
//!
//! **Divergence.** A non-finite state or covariance, or a joint rate above
//! [`FilterParams::divergence_rate`], resets the filter to the last good pose at rest with
//! the initial covariance, and the frame's [`StepReport::diverged`] is set: the filter never
//! emits a NaN pose.

use crate::local_joints::{
    decompose, fold_rotation, orthogonal_triple, rate_matrix, subtree, to_recentred, transport,
    triple_rotation,
};
use crate::params::{FilterParams, RobustLoss};
use crate::suit::Suit;
use crate::{Context, Error, Result, ResultExt};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};
use skin_core::math::{DMat3, DQuat, DVec3};
use skin_core::skeleton::{
    AngularFrame, AttachedFrame, AttachedPoint, ForwardKinematics, JointRates, Skeleton,
};

/// One board's inertial reading in its own axes.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct InertialReading {
    /// Gyroscope, rad/s.
    pub gyro_rad_s: DVec3,
    /// Accelerometer (specific force: reads +g upwards at rest), m/s².
    pub accel_m_s2: DVec3,
    /// Per channel (gyroscope x, y, z, accelerometer x, y, z): the value is a bound, not a
    /// reading — clipped at full scale or slew-saturated by the delta code
    /// ([`crate::Saturation`]). Beyond the thesis; the filter skips flagged rows if
    /// [`FilterParams::skip_saturated`] is set. Default: none flagged.
    #[serde(default)]
    pub saturated: [bool; crate::inertial::CHANNELS],
}

impl InertialReading {
    /// A reading with no channel flagged.
    pub fn new(gyro_rad_s: DVec3, accel_m_s2: DVec3) -> Self {
        InertialReading {
            gyro_rad_s,
            accel_m_s2,
            saturated: [false; crate::inertial::CHANNELS],
        }
    }
}

/// A distance from one pulse (§4.3.1).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DistanceMeasurement {
    /// Sensor board (microphone) index.
    pub sensor: usize,
    /// Ultrasonic source index.
    pub source: usize,
    /// Distance, metres.
    pub distance_m: f64,
    /// Confidence `w_s · w_t` in [0, 1] (the filter multiplies in `w_a`).
    pub confidence: f64,
    /// How long before the frame it is processed at the pulse was emitted, seconds (0 to one
    /// frame step plus the flight time); the filter predicts the distance at that time from
    /// the frame's pose and rates (`d − age · ḋ`).
    pub age_s: f64,
}

/// Everything observed in one 140 Hz frame: one optional inertial reading per board (`None`
/// for a dropped or uncorrectable frame) and the distances measured since the previous frame.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct FrameObservations {
    /// Per board, in suit order.
    pub inertial: Vec<Option<InertialReading>>,
    /// Distances measured between the previous frame and this one.
    pub distances: Vec<DistanceMeasurement>,
}

/// θ, θ̇, θ̈ of the known DOFs for one frame, in the order they were declared.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct KnownDofs {
    /// Values (rad or m).
    pub theta: Vec<f64>,
    /// Rates.
    pub theta_dot: Vec<f64>,
    /// Accelerations.
    pub theta_ddot: Vec<f64>,
}

/// What one [`SkeletalEkf::step`] did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct StepReport {
    /// The filter diverged and was reset this frame.
    pub diverged: bool,
    /// Scalar inertial readings used.
    pub inertial_used: usize,
    /// Inertial readings skipped (missing or non-finite).
    pub inertial_skipped: usize,
    /// Scalar inertial rows skipped because their channel was flagged saturated
    /// ([`InertialReading::saturated`]).
    #[serde(default)]
    pub inertial_saturated: usize,
    /// Distances used.
    pub distances_used: usize,
    /// Distances not used (low confidence, source facing away, gate).
    pub distances_rejected: usize,
}

/// Running innovation statistics of one sensor channel (a board's gyroscope, accelerometer
/// or microphone), for consistency checks: with a consistent filter the normalised
/// innovations `ν/√s` have mean ≈ 0 and their squares (NIS) mean ≈ 1; a mean far from 0 shows
/// a modelling error (lever arm, frame, gravity sign, time alignment), a NIS far above 1
/// noise levels too small for what the model misses.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct InnovationStats {
    /// Scalar updates counted (gated ones included, rejected ones not).
    pub count: usize,
    /// Sum of the normalised innovations `ν / √s`.
    pub sum_normalised: f64,
    /// Sum of the normalised innovations squared `ν² / s`.
    pub sum_nis: f64,
    /// Scalar updates that passed the gate (distances; every inertial update passes).
    #[serde(default)]
    pub passed: usize,
    /// Sum of `ν² / s` over the updates that passed the gate (`s` before any robust
    /// down-weighting): the NIS of what the filter used.
    #[serde(default)]
    pub sum_nis_passed: f64,
}

impl InnovationStats {
    /// Mean normalised innovation (≈ 0 for an unbiased model).
    pub fn mean_normalised(&self) -> f64 {
        self.sum_normalised / self.count.max(1) as f64
    }

    /// Mean normalised innovation squared (≈ 1 for a consistent filter).
    pub fn mean_nis(&self) -> f64 {
        self.sum_nis / self.count.max(1) as f64
    }

    /// Mean NIS over the updates that passed the gate.
    pub fn mean_nis_passed(&self) -> f64 {
        self.sum_nis_passed / self.passed.max(1) as f64
    }

    /// Share of the counted updates that passed the gate (1 without a gate).
    pub fn pass_rate(&self) -> f64 {
        self.passed as f64 / self.count.max(1) as f64
    }

    /// The statistics of several channels pooled (e.g. every board of one sensor type).
    pub fn pooled<'a>(stats: impl IntoIterator<Item = &'a InnovationStats>) -> Self {
        stats
            .into_iter()
            .fold(InnovationStats::default(), |a, b| InnovationStats {
                count: a.count + b.count,
                sum_normalised: a.sum_normalised + b.sum_normalised,
                sum_nis: a.sum_nis + b.sum_nis,
                passed: a.passed + b.passed,
                sum_nis_passed: a.sum_nis_passed + b.sum_nis_passed,
            })
    }
}

/// The sensor types of [`SkeletalEkf::innovation_stats`], in its order.
pub const INNOVATION_TYPES: [&str; 3] = ["gyroscope", "accelerometer", "distance"];

/// A sensor type's observation rows, run with the board Jacobian buffers.
type BoardRows =
    fn(&mut SkeletalEkf, &FrameObservations, &mut StepReport, &mut [DMatrix<f64>]) -> Result<()>;

/// Scratch of one sparse observation row.
#[derive(Debug, Clone, Default)]
struct Row {
    idx: Vec<usize>,
    val: Vec<f64>,
}

impl Row {
    fn clear(&mut self) {
        self.idx.clear();
        self.val.clear();
    }
    fn push(&mut self, i: usize, v: f64) {
        if v != 0.0 {
            self.idx.push(i);
            self.val.push(v);
        }
    }
    fn dot(&self, x: &[f64]) -> f64 {
        self.idx
            .iter()
            .zip(&self.val)
            .map(|(&i, &v)| v * x[i])
            .sum()
    }
}

/// The filter. Build with [`SkeletalEkf::new`], feed one [`FrameObservations`] per frame.
#[derive(Debug, Clone)]
pub struct SkeletalEkf {
    /// The filter's own copy of the skeleton: 3-DOF joints re-centred (module
    /// `local_joints`).
    skeleton: Skeleton,
    /// The skeleton as given (the reported pose's parameterisation).
    original: Skeleton,
    /// Per joint: the true frame is the filter's frame times this rotation.
    conj: Vec<DMat3>,
    /// Re-centred joints: joint, state slots of its three DOFs, original axes.
    local: Vec<(usize, [usize; 3], [DVec3; 3])>,
    /// The pose in the original skeleton's angles.
    out_theta: Vec<f64>,
    /// The previous frame's `out_theta` (decomposition branch).
    prev_out: Vec<f64>,
    suit: Suit,
    params: FilterParams,
    known: Vec<usize>,
    /// State slot of each DOF (`None`: known).
    slot: Vec<Option<usize>>,
    nf: usize,
    x: DVector<f64>,
    p: DMatrix<f64>,
    p0: DMatrix<f64>,
    good_theta: DVector<f64>,
    /// θ in the filter's chart (re-centred joints local).
    chart_theta: Vec<f64>,
    theta_dot: Vec<f64>,
    theta_ddot: Vec<f64>,
    gyro_offsets: Vec<DVec3>,
    points: Vec<AttachedPoint>,
    frames: Vec<AttachedFrame>,
    fk: ForwardKinematics,
    rates: JointRates,
    /// Four `3·boards × dof_count` Jacobian buffers.
    mb: Vec<DMatrix<f64>>,
    /// `3·(boards + sources) × dof_count` positional Jacobians.
    mp: DMatrix<f64>,
    bias: Vec<DVec3>,
    x0: DVector<f64>,
    dx: Vec<f64>,
    ph: Vec<f64>,
    row: Row,
    dense: Vec<f64>,
    /// Deferred downdates: `P = P_stored − Σ uᵢ uᵢᵀ` over the `npend` vectors stored here
    /// (row-major, `DEFER × 3nf`), applied to P's lower triangle in blocks.
    pend: Vec<f64>,
    npend: usize,
    /// Per sensor type (gyroscope, accelerometer, distance) and board.
    innovations: [Vec<InnovationStats>; 3],
    /// Per board and sensor axis, gyroscope and accelerometer.
    axis_innovations: [Vec<[InnovationStats; 3]>; 2],
    /// Where the current scalar update's innovation is counted: (type, board, axis).
    counting: (usize, usize, usize),
    /// Per board: gyroscope and accelerometer noise variances per sensor axis (the suit's
    /// [`Suit::board_noise`], per axis if it has them, else the global σ of
    /// [`FilterParams`]).
    board_r: Vec<[[f64; 3]; 2]>,
}

/// Scalar updates whose rank-1 downdates of P are applied together: P's lower triangle is
/// swept once per block (each column stays in L1 cache for the block's axpys) instead of once
/// per update.
const DEFER: usize = 8;

impl SkeletalEkf {
    /// A filter at `initial_pose` (the rest pose the subject holds, §4.4.4) at rest, with the
    /// DOFs in `known` (e.g. `skeleton.joint_dofs(0)` for the root transform) supplied per
    /// frame instead of estimated.
    ///
    /// # Errors
    /// As [`FilterParams::validate`]; as [`Skeleton::check_pose`] for the pose;
    /// [`Error::IndexOutOfRange`] for a known DOF index or a suit joint outside the skeleton;
    /// [`Error::Empty`] if every DOF is known.
    pub fn new(
        skeleton: Skeleton,
        suit: Suit,
        initial_pose: &[f64],
        params: FilterParams,
        known: &[usize],
    ) -> Result<Self> {
        params.validate()?;
        skeleton.check_pose("initial_pose", initial_pose)?;
        let n = skeleton.dof_count();
        let nj = skeleton.joint_count();
        for b in suit.boards() {
            skin_core::check::index("board joint", b.joint, nj)?;
        }
        for s in suit.sources() {
            skin_core::check::index("source joint", s.joint, nj)?;
        }
        let mut slot = vec![Some(0); n];
        for &d in known {
            skin_core::check::index("known DOF", d, n)?;
            slot[d] = None;
        }
        let mut nf = 0;
        for s in slot.iter_mut() {
            if s.is_some() {
                *s = Some(nf);
                nf += 1;
            }
        }
        if nf == 0 {
            return Err(Error::Empty {
                what: "free DOFs (every DOF is known)",
            });
        }
        let big_n = 3 * nf;
        let mut x = DVector::zeros(big_n);
        for (d, s) in slot.iter().enumerate() {
            if let Some(s) = s {
                x[*s] = initial_pose[d];
            }
        }
        let (s0, s1, s2) = params.initial_sigma;
        let p0 = DMatrix::from_fn(big_n, big_n, |i, j| {
            if i != j {
                0.0
            } else if i < nf {
                s0 * s0
            } else if i < 2 * nf {
                s1 * s1
            } else {
                s2 * s2
            }
        });
        let points: Vec<AttachedPoint> = suit
            .boards()
            .iter()
            .map(|b| b.point())
            .chain(suit.sources().iter().map(|s| s.point()))
            .collect();
        let frames: Vec<AttachedFrame> = suit.boards().iter().map(|b| b.frame()).collect();
        let rows = 3 * points.len();
        let board_r = (0..suit.boards().len())
            .map(|b| match suit.board_noise().get(b) {
                Some(n) => [
                    n.gyroscope_axes().map(|s| s * s),
                    n.accelerometer_axes().map(|s| s * s),
                ],
                None => [
                    [params.gyroscope_sigma.powi(2); 3],
                    [params.accelerometer_sigma.powi(2); 3],
                ],
            })
            .collect();
        let local = (0..nj)
            .filter(|&j| skeleton.joints()[j].parent.is_some())
            .filter_map(|j| {
                let axes = orthogonal_triple(&skeleton, j)?;
                let d: Vec<usize> = skeleton.joint_dofs(j).collect();
                let slots = [slot[d[0]]?, slot[d[1]]?, slot[d[2]]?];
                Some((j, slots, axes))
            })
            .collect();
        Ok(SkeletalEkf {
            original: skeleton.clone(),
            conj: vec![DMat3::IDENTITY; nj],
            local,
            out_theta: initial_pose.to_vec(),
            prev_out: initial_pose.to_vec(),
            fk: ForwardKinematics::new(&skeleton),
            rates: JointRates::new(&skeleton),
            mb: vec![DMatrix::zeros(3 * frames.len(), n); 4],
            mp: DMatrix::zeros(rows, n),
            bias: vec![DVec3::ZERO; points.len()],
            gyro_offsets: vec![DVec3::ZERO; suit.boards().len()],
            chart_theta: initial_pose.to_vec(),
            theta_dot: vec![0.0; n],
            theta_ddot: vec![0.0; n],
            good_theta: x.rows(0, nf).into_owned(),
            x0: x.clone(),
            dx: vec![0.0; big_n],
            ph: vec![0.0; big_n],
            row: Row::default(),
            dense: vec![0.0; n],
            pend: vec![0.0; DEFER * big_n],
            npend: 0,
            innovations: std::array::from_fn(|_| {
                vec![InnovationStats::default(); suit.boards().len()]
            }),
            axis_innovations: std::array::from_fn(|_| {
                vec![[InnovationStats::default(); 3]; suit.boards().len()]
            }),
            counting: (0, 0, 0),
            board_r,
            x,
            p: p0.clone(),
            p0,
            known: known.to_vec(),
            slot,
            nf,
            points,
            frames,
            skeleton,
            suit,
            params,
        })
    }

    /// With per-board gyroscope offsets (rad/s, subtracted from every reading; §4.4.4).
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] unless one per board; [`Error::NonFinite`] for NaN offsets.
    pub fn with_gyro_offsets(mut self, offsets: Vec<DVec3>) -> Result<Self> {
        skin_core::check::same_size("gyro offsets", self.suit.boards().len(), offsets.len())?;
        if offsets.iter().any(|o| !o.is_finite()) {
            return Err(Error::NonFinite {
                what: "gyro offsets",
            });
        }
        self.gyro_offsets = offsets;
        Ok(self)
    }

    /// Number of estimated DOFs (the state has three times as many entries).
    pub fn free_dof_count(&self) -> usize {
        self.nf
    }

    /// The current full pose θ in the skeleton's own angles (known DOFs as last supplied).
    pub fn theta(&self) -> &[f64] {
        &self.out_theta
    }

    /// The current full rates θ̇ of the filter's parameterisation: the skeleton's own rates,
    /// except for 3-DOF joints while [`FilterParams::recentre_rad`] re-centres them (then the
    /// rates of the local angles about the last re-centring).
    pub fn theta_dot(&self) -> &[f64] {
        &self.theta_dot
    }

    /// Innovation statistics since the filter was built, per sensor type
    /// ([`INNOVATION_TYPES`]: gyroscope, accelerometer, distance) and per board (distances
    /// counted at their microphone's board).
    pub fn innovation_stats(&self) -> &[Vec<InnovationStats>; 3] {
        &self.innovations
    }

    /// The gyroscope and accelerometer innovation statistics of [`SkeletalEkf::innovation_stats`]
    /// split by the board's sensor axis: `[gyroscope, accelerometer][board][axis]` (for
    /// per-axis noise, [`crate::tuning::board_axis_noise_from_innovations`]).
    pub fn axis_innovation_stats(&self) -> &[Vec<[InnovationStats; 3]>; 2] {
        &self.axis_innovations
    }

    /// The current covariance of the angles `dofs` (rad², in the filter's chart; zero rows
    /// and columns for known DOFs), row-major `dofs.len()²` — with [`SkeletalEkf::theta`]
    /// against the truth it gives the NEES of a joint.
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`] for a DOF outside the skeleton.
    pub fn theta_covariance(&self, dofs: &[usize]) -> Result<Vec<f64>> {
        let n = self.slot.len();
        let mut out = Vec::with_capacity(dofs.len() * dofs.len());
        for &a in dofs {
            skin_core::check::index("DOF", a, n)?;
            for &b in dofs {
                skin_core::check::index("DOF", b, n)?;
                out.push(match (self.slot[a], self.slot[b]) {
                    (Some(i), Some(j)) => self.p[(i.max(j), i.min(j))],
                    _ => 0.0,
                });
            }
        }
        Ok(out)
    }

    /// The suit the filter uses.
    pub fn suit(&self) -> &Suit {
        &self.suit
    }

    /// One frame: time update (Eq. 4.5–4.6), then gyroscopes, accelerometers and distances
    /// (Eq. 4.7–4.9) as enabled in [`FilterParams::sensors`]. Missing and non-finite inertial
    /// readings are skipped and counted; distances are gated by confidence and by the source's
    /// field of view (`w_a`, §4.3.1).
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if `obs.inertial` has not one entry per board or `known` does
    /// not match the known DOFs; [`Error::IndexOutOfRange`] (in [`Error::At`] naming the
    /// distance's sensor) for a bad sensor or source index; [`Error::NonFinite`] for non-finite
    /// known values or distances.
    pub fn step(
        &mut self,
        obs: &FrameObservations,
        known: Option<&KnownDofs>,
    ) -> Result<StepReport> {
        skin_core::check::same_size(
            "inertial readings per board",
            self.suit.boards().len(),
            obs.inertial.len(),
        )?;
        for m in &obs.distances {
            skin_core::check::index("distance sensor", m.sensor, self.suit.boards().len())
                .at(Context::Sensor(m.sensor))?;
            skin_core::check::index("distance source", m.source, self.suit.sources().len())
                .at(Context::Source(m.source))?;
            if !(m.distance_m.is_finite() && m.confidence.is_finite() && m.age_s.is_finite()) {
                return Err(Error::NonFinite {
                    what: "distance measurement",
                })
                .at(Context::Sensor(m.sensor));
            }
        }
        let nk = self.known.len();
        match known {
            Some(k) => {
                for (what, v) in [
                    ("known theta", &k.theta),
                    ("known theta_dot", &k.theta_dot),
                    ("known theta_ddot", &k.theta_ddot),
                ] {
                    skin_core::check::same_size(what, nk, v.len())?;
                    skin_core::check::all_finite(what, v.iter())?;
                }
                for (i, &d) in self.known.iter().enumerate() {
                    self.chart_theta[d] = k.theta[i];
                    self.theta_dot[d] = k.theta_dot[i];
                    self.theta_ddot[d] = k.theta_ddot[i];
                }
            }
            None => skin_core::check::same_size("known DOF values", nk, 0)?,
        }
        let mut report = StepReport::default();
        self.predict()?;
        let sensors = self.params.sensors;
        let result = (|| -> Result<()> {
            if sensors.gyroscopes {
                self.with_board_buffers(obs, &mut report, Self::gyro_rows)?;
            }
            if sensors.accelerometers {
                self.with_board_buffers(obs, &mut report, Self::accel_rows)?;
            }
            if sensors.distances {
                self.update_distances(obs, &mut report)?;
            }
            Ok(())
        })();
        if !sensors.gyroscopes || !sensors.accelerometers {
            report.inertial_skipped += obs.inertial.iter().filter(|r| r.is_none()).count();
        }
        self.flush_downdates();
        let nf = self.nf;
        let rate_ok = (nf..2 * nf).all(|i| self.x[i].abs() <= self.params.divergence_rate);
        let finite = self.x.iter().all(|v| v.is_finite())
            && (0..3 * nf).all(|i| self.p[(i, i)].is_finite() && self.p[(i, i)] >= 0.0);
        if result.is_err() || !rate_ok || !finite {
            // A skin-core error here means a non-finite pose reached FK: divergence too.
            report.diverged = true;
            self.x.fill(0.0);
            self.x.rows_mut(0, nf).copy_from(&self.good_theta);
            self.p.copy_from(&self.p0);
        } else {
            self.good_theta.copy_from(&self.x.rows(0, nf));
        }
        self.sync_full();
        self.sync_output();
        Ok(report)
    }

    /// The pose in the original skeleton's angles: re-centred joints composed with their
    /// folded rotations and decomposed on their original axes; other joints as they are.
    fn sync_output(&mut self) {
        self.out_theta.copy_from_slice(&self.chart_theta);
        for &(j, _, axes) in &self.local {
            let parent = self.original.joints()[j].parent;
            let g_p = parent.map_or(DMat3::IDENTITY, |p| self.conj[p]);
            if self.conj[j] == g_p {
                continue;
            }
            let d: Vec<usize> = self.skeleton.joint_dofs(j).collect();
            let now = self.skeleton.joints()[j].dofs.iter().map(|f| f.axis);
            let now: Vec<DVec3> = now.collect();
            let r = triple_rotation(
                [now[0], now[1], now[2]],
                [
                    self.chart_theta[d[0]],
                    self.chart_theta[d[1]],
                    self.chart_theta[d[2]],
                ],
            );
            let original = g_p.transpose() * r * self.conj[j];
            let prev = [
                self.prev_out[d[0]],
                self.prev_out[d[1]],
                self.prev_out[d[2]],
            ];
            let v = decompose(axes, original, prev);
            for (i, &di) in d.iter().enumerate() {
                self.out_theta[di] = v[i];
            }
        }
        self.prev_out.copy_from_slice(&self.out_theta);
    }

    /// Re-centres every 3-DOF joint whose angles left `±recentre_rad` (module
    /// `local_joints`): folds its rotation into the filter's skeleton and suit, zeroes its
    /// angles, maps its rates and accelerations and transports the covariance (P full).
    fn recentre(&mut self) -> Result<()> {
        let threshold = self.params.recentre_rad;
        if threshold <= 0.0 {
            return Ok(());
        }
        let nf = self.nf;
        let n = 3 * nf;
        let mut joints: Option<Vec<skin_core::skeleton::Joint>> = None;
        let mut boards = self.suit.boards().to_vec();
        let mut sources = self.suit.sources().to_vec();
        for k in 0..self.local.len() {
            let (j, slots, _) = self.local[k];
            let delta = slots.map(|s| self.x[s]);
            if delta.iter().all(|v| v.abs() < threshold) {
                continue;
            }
            let js = joints.get_or_insert_with(|| self.skeleton.joints().to_vec());
            let axes = [js[j].dofs[0].axis, js[j].dofs[1].axis, js[j].dofs[2].axis];
            let r = triple_rotation(axes, delta);
            let a_new = axes.map(|a| r * a);
            let idx: [usize; 9] = std::array::from_fn(|k| (k / 3) * nf + slots[k % 3]);
            let state = idx.map(|i| self.x[i]);
            let new = to_recentred(axes, a_new, r, state);
            for (&i, v) in idx.iter().zip(new) {
                self.x[i] = v;
            }
            for &s in &slots {
                self.x[s] = 0.0;
                self.good_theta[s] = 0.0;
            }
            // First-order transport: M = (R_c A)⁻¹ E(δ) on each block (module docs).
            let m =
                DMat3::from_cols(a_new[0], a_new[1], a_new[2]).inverse() * rate_matrix(axes, delta);
            let m: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|k| m.col(k)[i]));
            for blk in 0..3 {
                transport(self.p.as_mut_slice(), n, slots.map(|s| blk * nf + s), m);
            }
            let inside = subtree(js, j);
            fold_rotation(js, &inside, j, r);
            let q = DQuat::from_mat3(&r).normalize();
            for (c, g) in self.conj.iter_mut().enumerate() {
                if inside[c] {
                    *g = r * *g;
                }
            }
            for p in self.points.iter_mut().filter(|p| inside[p.joint]) {
                p.offset = r * p.offset;
            }
            for f in self.frames.iter_mut().filter(|f| inside[f.joint]) {
                f.joint_from_frame = q * f.joint_from_frame;
            }
            for b in boards.iter_mut().filter(|b| inside[b.joint]) {
                b.offset = r * b.offset;
                b.joint_from_sensor = q * b.joint_from_sensor;
            }
            for s in sources.iter_mut().filter(|s| inside[s.joint]) {
                s.offset = r * s.offset;
                s.normal = (r * s.normal).normalize();
            }
        }
        if let Some(js) = joints {
            self.skeleton = Skeleton::new(js)?;
            self.fk = ForwardKinematics::new(&self.skeleton);
            self.rates = JointRates::new(&self.skeleton);
            self.suit = Suit::new(&self.skeleton, boards, sources)?;
        }
        Ok(())
    }

    /// Eq. 4.5–4.6 with the block form of F (after re-centring the 3-DOF joints).
    fn predict(&mut self) -> Result<()> {
        self.symmetrise();
        self.recentre()?;
        let nf = self.nf;
        let dt = self.params.frame_time_s;
        // The exact transition of the constant-acceleration model that Eq. 4.1 discretises:
        // θ gains Δt θ̇ + ½Δt² θ̈ (Eq. 4.1's first-order step drops the ½Δt² θ̈ term, a bias
        // that made the oracle drift on the treadmill: docs, "The treadmill drift traced").
        let h2 = if self.params.first_order_step {
            0.0
        } else {
            0.5 * dt * dt
        };
        for i in 0..nf {
            self.x[i] += dt * self.x[nf + i] + h2 * self.x[2 * nf + i];
            self.x[nf + i] += dt * self.x[2 * nf + i];
        }
        let n = 3 * nf;
        let data = self.p.as_mut_slice();
        // Rows (F P): within each column, block 0 += Δt block 1 + ½Δt² block 2, then block 1
        // += Δt block 2.
        for c in 0..n {
            let col = &mut data[c * n..(c + 1) * n];
            for i in 0..nf {
                col[i] += dt * col[nf + i] + h2 * col[2 * nf + i];
            }
            for i in 0..nf {
                col[nf + i] += dt * col[2 * nf + i];
            }
        }
        // Columns ((F P) Fᵀ): column i += Δt column nf + i + ½Δt² column 2nf + i, then column
        // nf + i += Δt column 2nf + i (column 2nf + i itself is unchanged).
        for i in 0..nf {
            let (head, tail) = data.split_at_mut(2 * nf * n + i * n);
            let dst = &mut head[i * n..(i + 1) * n];
            for (d, s) in dst.iter_mut().zip(&tail[..n]) {
                *d += h2 * s;
            }
        }
        for blk in 0..2 {
            for i in 0..nf {
                let (a, b) = (blk * nf + i, (blk + 1) * nf + i);
                let (head, tail) = data.split_at_mut(b * n);
                let dst = &mut head[a * n..(a + 1) * n];
                let src = &tail[..n];
                for (d, s) in dst.iter_mut().zip(src) {
                    *d += dt * s;
                }
            }
        }
        let q = self.params.process_sigma.powi(2);
        for i in 0..nf {
            self.p[(2 * nf + i, 2 * nf + i)] += q;
        }
        Ok(())
    }

    /// Full θ, θ̇, θ̈ from the state (known entries untouched).
    fn sync_full(&mut self) {
        let nf = self.nf;
        for (d, s) in self.slot.iter().enumerate() {
            if let Some(s) = *s {
                self.chart_theta[d] = self.x[s];
                self.theta_dot[d] = self.x[nf + s];
                self.theta_ddot[d] = self.x[2 * nf + s];
            }
        }
    }

    /// Re-linearisation point of one sensor type: FK and rates at the current state.
    fn linearise(&mut self) -> Result<()> {
        self.sync_full();
        self.skeleton
            .forward_kinematics_into(&self.chart_theta, &mut self.fk)?;
        self.skeleton.rates_into(
            &self.chart_theta,
            &self.theta_dot,
            &self.fk,
            &mut self.rates,
        )?;
        self.x0.copy_from(&self.x);
        Ok(())
    }

    /// The innovation statistics the current row counts into (`counting`'s sensor
    /// type and board, and its axis for the inertial types).
    fn counted_stats(&mut self) -> impl Iterator<Item = &mut InnovationStats> {
        let (kind, board, axis) = self.counting;
        let per_axis = self
            .axis_innovations
            .get_mut(kind)
            .and_then(|t| t.get_mut(board))
            .and_then(|a| a.get_mut(axis));
        self.innovations[kind]
            .get_mut(board)
            .into_iter()
            .chain(per_axis)
    }
    /// One scalar update (Eq. 4.7–4.9): `z − h(x₀) − H (x − x₀)` as innovation; past the
    /// gate, `s` is inflated by `robust` ([`RobustLoss`]).
    fn scalar_update(
        &mut self,
        residual0: f64,
        r: f64,
        gate_sigma: f64,
        robust: RobustLoss,
    ) -> bool {
        let n = 3 * self.nf;
        for (d, (x, x0)) in self.dx.iter_mut().zip(self.x.iter().zip(self.x0.iter())) {
            *d = x - x0;
        }
        let innov = residual0 - self.row.dot(&self.dx);
        // Only the lower triangle of P is kept current between time updates (symmetry):
        // column i of P is its lower part below the diagonal and row i to the left of it.
        let data = self.p.as_slice();
        self.ph.fill(0.0);
        for (&i, &v) in self.row.idx.iter().zip(&self.row.val) {
            for (r, p) in self.ph[..i].iter_mut().enumerate() {
                *p += v * data[r * n + i];
            }
            let col = &data[i * n + i..(i + 1) * n];
            for (p, c) in self.ph[i..].iter_mut().zip(col) {
                *p += v * c;
            }
        }
        // The downdates not yet applied to the stored P.
        for u in self.pend[..self.npend * n].chunks_exact(n) {
            let a = self.row.dot(u);
            if a != 0.0 {
                for (p, ui) in self.ph.iter_mut().zip(u) {
                    *p -= a * ui;
                }
            }
        }
        let s = self.row.dot(&self.ph) + r;
        if s.is_nan() || s <= 0.0 {
            return false;
        }
        for st in self.counted_stats() {
            st.count += 1;
            st.sum_normalised += innov / s.sqrt();
            st.sum_nis += innov * innov / s;
        }
        if gate_sigma > 0.0 && innov * innov > gate_sigma * gate_sigma * s {
            return false;
        }
        for st in self.counted_stats() {
            st.passed += 1;
            st.sum_nis_passed += innov * innov / s;
        }
        let s = s * robust.inflation(innov / s.sqrt());
        let k_scale = innov / s;
        for (x, p) in self.x.iter_mut().zip(&self.ph) {
            *x += p * k_scale;
        }
        // P −= (P h)(P h)ᵀ / s, deferred as u uᵀ with u = P h / √s.
        let inv = 1.0 / s.sqrt();
        let slot = &mut self.pend[self.npend * n..(self.npend + 1) * n];
        for (u, p) in slot.iter_mut().zip(&self.ph) {
            *u = p * inv;
        }
        self.npend += 1;
        if self.npend == DEFER {
            self.flush_downdates();
        }
        true
    }

    /// Applies the deferred downdates to P's lower triangle: each element is loaded and
    /// stored once per block (`P[r, c] −= Σₖ uₖ[c] uₖ[r]`).
    fn flush_downdates(&mut self) {
        let n = 3 * self.nf;
        let data = self.p.as_mut_slice();
        if self.npend == DEFER {
            let us: [&[f64]; DEFER] = std::array::from_fn(|k| &self.pend[k * n..(k + 1) * n]);
            for c in 0..n {
                let f: [f64; DEFER] = std::array::from_fn(|k| us[k][c]);
                let tails: [&[f64]; DEFER] = std::array::from_fn(|k| &us[k][c..]);
                let col = &mut data[c * n + c..(c + 1) * n];
                let len = col.len();
                for t in &tails {
                    assert_eq!(t.len(), len);
                }
                for (j, p) in col.iter_mut().enumerate() {
                    let mut acc = 0.0;
                    for k in 0..DEFER {
                        acc += f[k] * tails[k][j];
                    }
                    *p -= acc;
                }
            }
        } else {
            let pend = &self.pend[..self.npend * n];
            for c in 0..n {
                let col = &mut data[c * n + c..(c + 1) * n];
                for u in pend.chunks_exact(n) {
                    let f = u[c];
                    if f == 0.0 {
                        continue;
                    }
                    for (p, h) in col.iter_mut().zip(&u[c..]) {
                        *p -= h * f;
                    }
                }
            }
        }
        self.npend = 0;
    }

    /// Copies the lower triangle of P onto the upper (after a run of scalar updates).
    fn symmetrise(&mut self) {
        self.flush_downdates();
        let n = 3 * self.nf;
        let data = self.p.as_mut_slice();
        for c in 1..n {
            for r in 0..c {
                data[c * n + r] = data[r * n + c];
            }
        }
    }

    fn inertial_reading(&self, obs: &FrameObservations, b: usize) -> Option<InertialReading> {
        obs.inertial[b].filter(|r| r.gyro_rad_s.is_finite() && r.accel_m_s2.is_finite())
    }

    /// Re-linearises, then runs `rows` (gyroscope or accelerometer rows) with the board
    /// Jacobian buffers lent out of `self`.
    fn with_board_buffers(
        &mut self,
        obs: &FrameObservations,
        report: &mut StepReport,
        rows: BoardRows,
    ) -> Result<()> {
        self.linearise()?;
        let mut mb = std::mem::take(&mut self.mb);
        let res = rows(self, obs, report, &mut mb);
        self.mb = mb;
        res
    }

    /// Eq. 4.3: `z = Rᵀ J_ω θ̇`; `∂z/∂θ̇ = J_ω,local`, `∂z/∂θ = ∂(J_ω θ̇)/∂θ` (local axes).
    fn gyro_rows(
        &mut self,
        obs: &FrameObservations,
        report: &mut StepReport,
        mb: &mut [DMatrix<f64>],
    ) -> Result<()> {
        let nb = self.frames.len();
        let [jw3, dw3, ..] = mb else {
            return Ok(());
        };
        self.skeleton
            .frame_jacobians_into(&self.fk, &self.frames, AngularFrame::Local, jw3)?;
        self.skeleton.frame_angular_velocity_jacobians_into(
            &self.fk,
            &self.theta_dot,
            &self.frames,
            AngularFrame::Local,
            dw3,
        )?;
        for b in 0..nb {
            let r = self.board_r[b][0];
            let Some(reading) = self.inertial_reading(obs, b) else {
                report.inertial_skipped += 1;
                continue;
            };
            let z = reading.gyro_rad_s - self.gyro_offsets[b];
            let pred = self.rates.frame_angular_velocity(
                &self.fk,
                &self.frames[b],
                AngularFrame::Local,
            )?;
            let chain = self.skeleton.chain_dofs(self.frames[b].joint).to_vec();
            for axis in 0..3 {
                if reading.saturated[axis] && self.params.skip_saturated {
                    report.inertial_saturated += 1;
                    continue;
                }
                self.counting = (0, b, axis);
                self.row.clear();
                for &d in &chain {
                    if let Some(s) = self.slot[d] {
                        self.row.push(s, dw3[(3 * b + axis, d)]);
                        self.row.push(self.nf + s, jw3[(3 * b + axis, d)]);
                    }
                }
                if self.scalar_update(z[axis] - pred[axis], r[axis], 0.0, RobustLoss::None) {
                    report.inertial_used += 1;
                }
            }
        }
        Ok(())
    }

    /// Eq. 4.2: `z = Rᵀ (J θ̈ + J̇θ̇ − g)`; `∂z/∂θ̈ = Rᵀ J`, `∂z/∂θ̇ = Rᵀ ∂(J̇θ̇)/∂θ̇`,
    /// `∂z/∂θ_m = Rᵀ (∂(Jθ̈)/∂θ_m + ∂(J̇θ̇)/∂θ_m − g_m × (a − g))`.
    fn accel_rows(
        &mut self,
        obs: &FrameObservations,
        report: &mut StepReport,
        mb: &mut [DMatrix<f64>],
    ) -> Result<()> {
        let nb = self.frames.len();
        let pts = &self.points[..nb];
        let [j, dt, dd, djy] = mb else {
            return Ok(());
        };
        self.skeleton.point_jacobians_into(&self.fk, pts, j)?;
        self.skeleton.point_bias_acceleration_jacobians_into(
            &self.fk,
            &self.theta_dot,
            pts,
            dt,
            dd,
        )?;
        self.skeleton.point_jacobian_product_jacobians_into(
            &self.fk,
            &self.theta_ddot,
            pts,
            djy,
        )?;
        self.skeleton.point_bias_accelerations_into(
            &self.fk,
            &self.rates,
            pts,
            &mut self.bias[..nb],
        )?;
        let up = DVec3::new(0.0, self.params.gravity_m_s2, 0.0);
        let axes = self.fk.dof_axes_world().to_vec();
        for b in 0..nb {
            let Some(reading) = self.inertial_reading(obs, b) else {
                report.inertial_skipped += 1;
                continue;
            };
            let chain = self.skeleton.chain_dofs(self.frames[b].joint);
            let col = |m: &DMatrix<f64>, d: usize| {
                DVec3::new(m[(3 * b, d)], m[(3 * b + 1, d)], m[(3 * b + 2, d)])
            };
            let mut a = self.bias[b];
            for &d in chain {
                a += col(j, d) * self.theta_ddot[d];
            }
            let f = a + up;
            let to_local: DQuat = self.fk.frame_rotation(&self.frames[b])?.inverse();
            let pred = to_local * f;
            // Local-axis columns per chain DOF: (θ, θ̇, θ̈).
            let cols: Vec<(usize, DVec3, DVec3, DVec3)> = chain
                .iter()
                .filter_map(|&d| {
                    self.slot[d].map(|s| {
                        let g = if self.skeleton.is_rotation(d) {
                            axes[d]
                        } else {
                            DVec3::ZERO
                        };
                        let h_theta = to_local * (col(djy, d) + col(dt, d) - g.cross(f));
                        (s, h_theta, to_local * col(dd, d), to_local * col(j, d))
                    })
                })
                .collect();
            let z = reading.accel_m_s2;
            let r = self.board_r[b][1];
            for axis in 0..3 {
                if reading.saturated[3 + axis] && self.params.skip_saturated {
                    report.inertial_saturated += 1;
                    continue;
                }
                self.counting = (1, b, axis);
                self.row.clear();
                for &(s, ht, hd, hdd) in &cols {
                    self.row.push(s, ht[axis]);
                    self.row.push(self.nf + s, hd[axis]);
                    self.row.push(2 * self.nf + s, hdd[axis]);
                }
                if self.scalar_update(z[axis] - pred[axis], r[axis], 0.0, RobustLoss::None) {
                    report.inertial_used += 1;
                }
            }
        }
        Ok(())
    }

    /// Eq. 4.4: `z = ‖p_i − p_j‖`, `∂z/∂θ = uᵀ (J_i − J_j)`, σ = σ_d / (w_s w_t w_a).
    fn update_distances(&mut self, obs: &FrameObservations, report: &mut StepReport) -> Result<()> {
        if obs.distances.is_empty() {
            return Ok(());
        }
        self.linearise()?;
        let mut jv = std::mem::take(&mut self.mp);
        let res = self.distance_rows(obs, report, &mut jv);
        self.mp = jv;
        res
    }

    fn distance_rows(
        &mut self,
        obs: &FrameObservations,
        report: &mut StepReport,
        jv: &mut DMatrix<f64>,
    ) -> Result<()> {
        {
            self.skeleton
                .point_jacobians_into(&self.fk, &self.points, jv)?;
            let nb = self.frames.len();
            for m in &obs.distances {
                let src = &self.suit.sources()[m.source];
                let pi = self.fk.point(&self.points[m.sensor])?;
                let pj = self.fk.point(&self.points[nb + m.source])?;
                let normal = self.fk.world_from_joint()[src.joint].matrix3 * src.normal;
                let diff = pi - pj;
                let d = diff.length();
                let w = if normal.dot(diff) > 0.0 {
                    m.confidence.clamp(0.0, 1.0)
                } else {
                    0.0
                };
                if w < self.params.min_confidence || d < 1e-6 {
                    report.distances_rejected += 1;
                    continue;
                }
                let u = diff / d;
                self.dense.fill(0.0);
                let (ci, cj) = (
                    self.skeleton.chain_dofs(self.points[m.sensor].joint),
                    self.skeleton.chain_dofs(self.points[nb + m.source].joint),
                );
                let colv = |row: usize, k: usize| {
                    DVec3::new(jv[(row, k)], jv[(row + 1, k)], jv[(row + 2, k)])
                };
                for &k in ci {
                    self.dense[k] += u.dot(colv(3 * m.sensor, k));
                }
                for &k in cj {
                    self.dense[k] -= u.dot(colv(3 * (nb + m.source), k));
                }
                // Distance at the pulse's time: d − age · ḋ, ḋ = uᵀ(J_i − J_j) θ̇ (its
                // θ-derivative through u and J is left out: age · ḋ is millimetres).
                let age = m.age_s.max(0.0);
                let d_rate: f64 = self
                    .dense
                    .iter()
                    .zip(&self.theta_dot)
                    .map(|(a, b)| a * b)
                    .sum();
                self.row.clear();
                for (k, &v) in self.dense.iter().enumerate() {
                    if let Some(s) = self.slot[k] {
                        self.row.push(s, v);
                    }
                }
                if age > 0.0 {
                    for (k, &v) in self.dense.iter().enumerate() {
                        if let Some(s) = self.slot[k] {
                            self.row.push(self.nf + s, -age * v);
                        }
                    }
                }
                let d = d - age * d_rate;
                let sigma = self.params.distance_sigma_m / w;
                self.counting = (2, m.sensor, 0);
                if self.scalar_update(
                    m.distance_m - d,
                    sigma * sigma,
                    self.params.distance_gate_sigma,
                    self.params.distance_robust,
                ) {
                    report.distances_used += 1;
                } else {
                    report.distances_rejected += 1;
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests;
