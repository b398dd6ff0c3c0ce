//! What a suit records (§4.2–4.3, after the signal processing): per 140 Hz frame, each
//! board's decoded inertial reading and the distances detected since the previous frame;
//! with the suit the filter is told, the rest hold that starts it (§4.4.4), and the DOFs an
//! external system supplies (the thesis's root transform). The input of
//! [`crate::pipeline::run`], written and read by [`Recording::write`] and [`Recording::read`]
//! (the format is documented on [`Recording`]).

mod file;
#[cfg(test)]
mod tests;

use crate::ekf::{FrameObservations, KnownDofs};
use crate::suit::Suit;
use crate::{Context, Error, Result, ResultExt};
use skin_core::skeleton::Skeleton;

/// What a suit records, ready for the filter: per frame of the inertial stream, each
/// board's decoded reading (`None` where it was lost) and the distances detected since the
/// previous frame (§4.3's output); the suit the filter is told, the rest hold (§4.4.4) and the
/// DOFs another system measures. The input of [`crate::pipeline::run`].
///
/// A single IMU log is a recording too: one board, no sources, no known DOFs. The raw
/// signals stay upstream: inertial counts are decoded by [`crate::DeltaCodec`] and
/// calibrated by [`crate::AxisCalibration`], microphone streams turned into distances by
/// [`crate::PulseDetector`], before they are recorded here.
///
/// # File format
///
/// A recording is a directory of one JSON manifest and CSV streams, so that Python (the
/// standard library's `json` and `csv`, or pandas) and spreadsheets read it without this
/// crate, and so that every number is exact: each value is the shortest decimal that reads
/// back to the same `f64` (Rust's `Display`, Python's `repr`), so writing and reading loses
/// nothing (in pandas, pass `float_precision="round_trip"`; Python's `float` and `csv` are
/// exact). The manifest's `rate_hz` and `start_s` are JSON numbers, exact for rates such as
/// 140 Hz; everything else with a fraction is in the CSV files. A binary container (HDF5,
/// NPZ) would be smaller — the exercise recording of 30 s is 17 MB as CSV — but needs a
/// library to open; one table per stream keeps each file rectangular and lets a board's
/// stream be read alone.
///
/// | File | Columns (one header row) |
/// |---|---|
/// | `manifest.json` | `format` = `"inertial-acoustic recording"`, `version` (this crate writes and reads [`Recording::FORMAT_VERSION`]), `rate_hz`, `start_s`, `frames`, `rest_frames`, `skeleton` (`joints`, `dofs`: the names, checked on reading), `boards`, `sources` (names, in suit order), `known_dofs` (DOF names, empty without) |
/// | `boards.csv` | `name, joint, offset_x_m, offset_y_m, offset_z_m, rot_x, rot_y, rot_z, rot_w` (the board's axes in its joint frame, a unit quaternion) and, when the suit carries per-board noise, `gyro_sigma_rad_s, accel_sigma_m_s2` and per axis `gyro_x_sigma_rad_s … accel_z_sigma_m_s2` (empty cells: no per-axis σ) |
/// | `sources.csv` | `name, joint, offset_x_m, offset_y_m, offset_z_m, normal_x, normal_y, normal_z` |
/// | `rest_pose.csv` | `dof, value` (rad or m), one row per skeleton DOF |
/// | `inertial/<board>.csv` | `t_s, gyro_x_rad_s, gyro_y_rad_s, gyro_z_rad_s, accel_x_m_s2, accel_y_m_s2, accel_z_m_s2, saturated` — one row per frame with a reading (a frame without a row had none); `saturated` is six `0`/`1` characters, gyroscope x y z then accelerometer x y z ([`InertialReading::saturated`](crate::InertialReading::saturated)) |
/// | `distances.csv` | `t_s, board, source, distance_m, confidence, age_s` — the frame each distance is processed at, in the order the filter takes them |
/// | `known_dofs.csv` | `t_s` then per known DOF `<dof>`, `<dof>_rate`, `<dof>_acc` — present only with known DOFs, one row per frame |
///
/// Frame `k` is at `start_s + k / rate_hz`; a row's frame is its time rounded to the nearest
/// frame, which must lie within a quarter of a frame of it. Times increase strictly down each
/// inertial and known-DOF file and never decrease down `distances.csv`. Reading rejects a
/// wrong format or version, a skeleton whose joint or DOF names differ, unknown board,
/// source or DOF names, missing or extra columns, NaN or infinite values, out-of-order or
/// duplicated times and times outside the recording, each with the file and line.
///
/// # Example
///
/// Two seconds of a still suit in the rest pose (gravity on the accelerometers, zero rates;
/// the first second is the rest hold), written and read back exactly:
///
/// ```
/// use inertial_acoustic::{FrameObservations, InertialReading, Recording, Suit};
/// use skin_core::math::DVec3;
/// use skin_core::skeleton::{human_skeleton, HumanParams};
///
/// let skeleton = human_skeleton(&HumanParams::default())?;
/// let suit = Suit::vlasic(&skeleton)?;
/// let rest_pose = skeleton.rest_pose();
/// let fk = skeleton.forward_kinematics(&rest_pose)?;
/// let still: Vec<Option<InertialReading>> = suit
///     .boards()
///     .iter()
///     .map(|b| {
///         let up = fk.frame_rotation(&b.frame()).map(|q| q.inverse() * DVec3::Y * 9.80665);
///         up.map(|a| Some(InertialReading::new(DVec3::ZERO, a)))
///     })
///     .collect::<Result<_, _>>()?;
/// let frame = FrameObservations { inertial: still, distances: vec![] };
/// let recording = Recording {
///     rate_hz: 140.0,
///     start_s: 0.0,
///     suit,
///     rest_frames: 140,
///     rest_pose,
///     frames: vec![frame; 280],
///     known_dofs: vec![],
///     known: vec![],
/// };
/// recording.check(&skeleton)?;
///
/// let dir = std::env::temp_dir().join(format!("ia-recording-doc-{}", std::process::id()));
/// recording.write(&dir, &skeleton)?; // manifest.json, boards.csv, inertial/<board>.csv, …
/// let back = Recording::read(&dir, &skeleton)?;
/// assert_eq!(back, recording);
/// # std::fs::remove_dir_all(&dir).ok();
/// # Ok::<(), inertial_acoustic::Error>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Recording {
    /// Frame rate of the inertial stream, Hz (the thesis's suit: 140).
    pub rate_hz: f64,
    /// Time of frame 0, seconds.
    pub start_s: f64,
    /// The suit as the filter is told it: nominal placements (and optional per-board noise).
    pub suit: Suit,
    /// Frames of the rest hold at the start (§4.4.4: the subject stands in `rest_pose`).
    pub rest_frames: usize,
    /// The pose held during the rest hold, θ (one value per skeleton DOF).
    pub rest_pose: Vec<f64>,
    /// The observations, one per frame.
    pub frames: Vec<FrameObservations>,
    /// DOFs whose θ, θ̇, θ̈ another system measures (the thesis's root transform, from the
    /// optical system or a treadmill); empty if none.
    pub known_dofs: Vec<usize>,
    /// Per frame, the values of `known_dofs` (empty when `known_dofs` is).
    pub known: Vec<KnownDofs>,
}

impl Recording {
    /// Duration from frame 0 to the last frame, seconds.
    pub fn duration_s(&self) -> f64 {
        self.frames.len().saturating_sub(1) as f64 / self.rate_hz
    }

    /// The time of frame `k`, seconds.
    pub fn time_s(&self, k: usize) -> f64 {
        self.start_s + k as f64 / self.rate_hz
    }

    /// Checks the recording against `skeleton`: a positive finite rate, a finite start, a
    /// rest pose with one finite value per DOF and a rest hold no longer than the recording,
    /// one reading slot per board in every frame with finite values, distances naming boards
    /// and sources of the suit with finite values, and one set of known values per frame of
    /// the declared sizes.
    ///
    /// # Errors
    /// [`Error::InvalidParam`], [`Error::SizeMismatch`], [`Error::NonFinite`] and
    /// [`Error::IndexOutOfRange`] saying which, in [`Error::At`] with the frame where one is
    /// at fault; [`Error::Empty`] without frames.
    pub fn check(&self, skeleton: &Skeleton) -> Result<()> {
        skin_core::check::positive("rate_hz", self.rate_hz)?;
        skin_core::check::finite("start_s", self.start_s)?;
        if self.frames.is_empty() {
            return Err(Error::Empty {
                what: "recording frames",
            });
        }
        let nd = skeleton.dof_count();
        skin_core::check::same_size("rest pose (one value per DOF)", nd, self.rest_pose.len())?;
        skin_core::check::all_finite("rest pose", self.rest_pose.iter())?;
        if self.rest_frames > self.frames.len() {
            return Err(Error::InvalidParam {
                name: "rest_frames",
                reason: format!(
                    "{} rest frames in a recording of {} frames",
                    self.rest_frames,
                    self.frames.len()
                ),
            });
        }
        let nj = skeleton.joint_count();
        for (i, b) in self.suit.boards().iter().enumerate() {
            skin_core::check::index("board joint", b.joint, nj).at(Context::Sensor(i))?;
        }
        for (i, s) in self.suit.sources().iter().enumerate() {
            skin_core::check::index("source joint", s.joint, nj).at(Context::Source(i))?;
        }
        let (nb, ns) = (self.suit.boards().len(), self.suit.sources().len());
        for (k, f) in self.frames.iter().enumerate() {
            check_frame(f, nb, ns).at(Context::Frame(k))?;
        }
        for &d in &self.known_dofs {
            skin_core::check::index("known DOF", d, nd)?;
        }
        if !self.known_dofs.is_empty() || !self.known.is_empty() {
            skin_core::check::same_size(
                "known DOF values (one set per frame)",
                self.frames.len(),
                self.known.len(),
            )?;
            let m = self.known_dofs.len();
            for (k, kd) in self.known.iter().enumerate() {
                check_known(kd, m).at(Context::Frame(k))?;
            }
        }
        Ok(())
    }
}

fn check_frame(f: &FrameObservations, boards: usize, sources: usize) -> Result<()> {
    skin_core::check::same_size(
        "inertial readings (one slot per board)",
        boards,
        f.inertial.len(),
    )?;
    for r in f.inertial.iter().flatten() {
        if !(r.gyro_rad_s.is_finite() && r.accel_m_s2.is_finite()) {
            return Err(Error::NonFinite {
                what: "inertial reading (leave the slot empty for a lost reading)",
            });
        }
    }
    for d in &f.distances {
        skin_core::check::index("distance board", d.sensor, boards)?;
        skin_core::check::index("distance source", d.source, sources)?;
        skin_core::check::all_finite(
            "distance, confidence or age",
            [d.distance_m, d.confidence, d.age_s].iter(),
        )?;
    }
    Ok(())
}

fn check_known(kd: &KnownDofs, m: usize) -> Result<()> {
    skin_core::check::same_size("known DOF values", m, kd.theta.len())?;
    skin_core::check::same_size("known DOF rates", m, kd.theta_dot.len())?;
    skin_core::check::same_size("known DOF accelerations", m, kd.theta_ddot.len())?;
    skin_core::check::all_finite(
        "known DOF values",
        kd.theta.iter().chain(&kd.theta_dot).chain(&kd.theta_ddot),
    )?;
    Ok(())
}
