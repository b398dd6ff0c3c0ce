//! Real IMU recordings as [`InertialReading`]s, and the orientation filter run over them.
//!
//! * BROAD (Laidig, Caruso, Cereatti, Seel, *BROAD — A Benchmark for Robust Inertial
//!   Orientation Estimation*, Data 6(7):72, 2021; CC BY 4.0), read by [`read_broad_hdf5`]
//!   from its published HDF5 files (`data_hdf5/*.hdf5`) or from excerpts in the same layout
//!   (the repository's `data/imu-broad/` ships the first 60 s of trials 07 and 09; see its
//!   SOURCE.md): 285.7 Hz gyroscope (rad/s) and accelerometer (m/s²) with an optical
//!   reference orientation (board-to-ENU, NaN where markers were lost) and the benchmark's
//!   `movement` flags.
//! * x-io Fusion's example log (MIT, `data/imu-xio/`), read by [`read_xio_csv`]: 135 s at
//!   about 100 Hz, gyroscope in deg/s and accelerometer in g, no reference.
//!
//! [`run_orientation`] runs [`OrientationEkf`] (the skeletal filter's equations for one free
//! rotation) over a log, initialised from a rest interval at its start (§4.4.4).
//!
//! # Example
//!
//! BROAD's trial 07 (the shipped excerpt: rest until 26.5 s, then fast rotations by hand),
//! with the noise levels `examples/inertial_capture` selects on trial 09, scored against the
//! optical reference over the benchmark's `movement` samples:
//!
//! ```
//! use inertial_acoustic::imu_log::{read_broad_hdf5, run_orientation};
//! use inertial_acoustic::{heading_inclination_rmse, FilterParams};
//! use skin_core::math::DVec3;
//!
//! let log = read_broad_hdf5("../data/imu-broad/07_undisturbed_fast_rotation_B_first60s.hdf5")?;
//! let params = FilterParams::default()
//!     .with_process_sigma(4.0)
//!     .with_measurement_sigmas(5.0, 0.002, 0.0025);
//! let run = run_orientation(&log, params, 20.0)?; // the first 20 s are rest
//! assert_eq!(run.diverged, 0);
//! let rmse = heading_inclination_rmse(&run.orientation, &log.reference, &log.movement, DVec3::Z)?;
//! println!("inclination {:.2}°, heading {:.2}°", rmse.inclination_deg, rmse.heading_deg);
//! assert!(rmse.combined_deg() < 3.0);
//! # Ok::<(), inertial_acoustic::Error>(())
//! ```

use std::path::Path;

use crate::orientation::{OrientationEkf, RestAlignment};
use crate::{Context, Error, FilterParams, InertialReading, Result, ResultExt, GRAVITY_M_S2};
use skin_core::math::{DQuat, DVec3};

/// A recording of one IMU: readings in the board's axes, their times, and (where the data set
/// has one) a reference orientation and the samples to score.
#[derive(Debug, Clone)]
pub struct ImuLog {
    /// Sample times, seconds.
    pub time_s: Vec<f64>,
    /// Readings, SI units.
    pub readings: Vec<InertialReading>,
    /// Reference board-to-world rotation per sample (NaN where unavailable); empty without a
    /// reference.
    pub reference: Vec<DQuat>,
    /// Samples the benchmark scores (BROAD's `movement`); empty without a reference.
    pub movement: Vec<bool>,
}

impl ImuLog {
    /// Mean sample interval, seconds.
    pub fn sample_time_s(&self) -> f64 {
        match (self.time_s.first(), self.time_s.last()) {
            (Some(a), Some(b)) if self.time_s.len() > 1 => (b - a) / (self.time_s.len() - 1) as f64,
            _ => 0.0,
        }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.readings.len()
    }

    /// No samples.
    pub fn is_empty(&self) -> bool {
        self.readings.is_empty()
    }

    /// The first `n` samples (all if fewer).
    pub fn head(&self, n: usize) -> ImuLog {
        let cut = |v: usize| v.min(n);
        ImuLog {
            time_s: self.time_s[..cut(self.time_s.len())].to_vec(),
            readings: self.readings[..cut(self.readings.len())].to_vec(),
            reference: self.reference[..cut(self.reference.len())].to_vec(),
            movement: self.movement[..cut(self.movement.len())].to_vec(),
        }
    }
}

fn parse_fields(line: &str, n: usize, format: &'static str, lineno: usize) -> Result<Vec<f64>> {
    let v: Vec<f64> = line
        .split(',')
        .map(|f| {
            let f = f.trim();
            if f.eq_ignore_ascii_case("nan") {
                Ok(f64::NAN)
            } else {
                f.parse::<f64>()
            }
        })
        .collect::<std::result::Result<_, _>>()
        .map_err(|e| skin_core::Error::Parse {
            format,
            line: lineno,
            message: e.to_string(),
        })?;
    if v.len() < n {
        return Err(skin_core::Error::Parse {
            format,
            line: lineno,
            message: format!("expected {n} fields, got {}", v.len()),
        }
        .into());
    }
    Ok(v)
}

fn read_rows(path: &Path, format: &'static str, n: usize) -> Result<Vec<Vec<f64>>> {
    let text = std::fs::read_to_string(path).map_err(|e| skin_core::Error::io(path, e))?;
    let mut rows = Vec::new();
    for (i, line) in text.lines().enumerate().skip(1) {
        if line.trim().is_empty() {
            continue;
        }
        rows.push(parse_fields(line, n, format, i + 1)?);
    }
    if rows.is_empty() {
        return Err(Error::Empty { what: "recording" });
    }
    Ok(rows)
}

fn vec3(r: &[f64], at: usize) -> DVec3 {
    DVec3::new(r[at], r[at + 1], r[at + 2])
}

/// A BROAD file opened for reading: the path (for errors) and the parsed file.
struct BroadFile<'a> {
    path: &'a Path,
    file: hdf5_pure::File,
}

impl BroadFile<'_> {
    fn error(&self, message: String) -> Error {
        Error::Hdf5 {
            path: self.path.to_path_buf(),
            message,
        }
    }

    /// The root attribute `sampling_rate`, Hz.
    fn sampling_rate(&self) -> Result<f64> {
        let attrs = self
            .file
            .root()
            .attrs()
            .map_err(|e| self.error(format!("root attributes: {e}")))?;
        let rate = attrs
            .get("sampling_rate")
            .ok_or_else(|| self.error("no root attribute `sampling_rate`".into()))?
            .as_f64()
            .ok_or_else(|| self.error("root attribute `sampling_rate` is not a number".into()))?;
        Ok(skin_core::check::positive(
            "BROAD sampling_rate (Hz)",
            rate,
        )?)
    }

    /// The dataset `name` and its number of rows, after checking that its shape is
    /// `[rows, columns]` (`[rows]` for `columns` = `None`).
    fn dataset(&self, name: &str, columns: Option<u64>) -> Result<(hdf5_pure::Dataset, usize)> {
        let ds = self
            .file
            .dataset(name)
            .map_err(|e| self.error(format!("dataset `{name}`: {e}")))?;
        let shape = ds
            .shape()
            .map_err(|e| self.error(format!("dataset `{name}`: {e}")))?;
        let rows = match (columns, shape.as_slice()) {
            (Some(c), &[n, k]) if k == c => n,
            (None, &[n]) => n,
            _ => {
                let expected = columns.map_or("[N]".into(), |c| format!("[N, {c}]"));
                return Err(self.error(format!(
                    "dataset `{name}` has shape {shape:?}, expected {expected}"
                )));
            }
        };
        let rows = usize::try_from(rows)
            .map_err(|_| self.error(format!("dataset `{name}` has {rows} rows")))?;
        Ok((ds, rows))
    }

    /// The dataset `name` of shape `[n, columns]` (`[n]` for `None`), like `imu_gyr`.
    fn same_length(
        &self,
        name: &str,
        columns: Option<u64>,
        n: usize,
    ) -> Result<hdf5_pure::Dataset> {
        let (ds, rows) = self.dataset(name, columns)?;
        if rows != n {
            return Err(self.error(format!(
                "dataset `{name}` has {rows} samples, `imu_gyr` {n}"
            )));
        }
        Ok(ds)
    }

    fn read_f64(&self, name: &str, ds: &hdf5_pure::Dataset) -> Result<Vec<f64>> {
        ds.read_f64()
            .map_err(|e| self.error(format!("dataset `{name}`: {e}")))
    }

    /// A flag per sample from `movement` (BROAD's bool: an 8-bit enum FALSE = 0, TRUE = 1;
    /// any integer type is taken, non-zero as true).
    fn read_flags(&self, ds: &hdf5_pure::Dataset) -> Result<Vec<bool>> {
        use hdf5_pure::DType;
        let err = |e: hdf5_pure::Error| self.error(format!("dataset `movement`: {e}"));
        let flags = match ds.dtype().map_err(err)? {
            DType::Enum(_) | DType::I8 | DType::U8 => ds.read_u8().map_err(err)?,
            DType::I16 | DType::I32 | DType::I64 | DType::U16 | DType::U32 | DType::U64 => ds
                .read_i64()
                .map_err(err)?
                .into_iter()
                .map(|v| u8::from(v != 0))
                .collect(),
            t => {
                return Err(self.error(format!(
                    "dataset `movement` is of type {t}, expected a bool (8-bit enum) or an integer"
                )))
            }
        };
        Ok(flags.into_iter().map(|v| v != 0).collect())
    }
}

/// Reads a BROAD trial in the benchmark's HDF5 layout: one of its published files
/// (`data_hdf5/*.hdf5`) or an excerpt in the same layout (`data/imu-broad/*_first60s.hdf5`,
/// cut by its `excerpt.py`).
///
/// Reads the datasets `imu_gyr` (N × 3, rad/s), `imu_acc` (N × 3, m/s²), `opt_quat` (N × 4,
/// reference board-to-ENU rotation w, x, y, z; NaN where the markers were lost) and
/// `movement` (N, BROAD's bool: the samples to score), and the root attribute
/// `sampling_rate` (Hz). Sample `k` is at `k / sampling_rate` seconds, as BROAD's own tools
/// time it. Reference quaternions are normalised where finite and kept as NaN elsewhere.
/// `imu_mag`, `opt_pos` and `info` are not read.
///
/// # Errors
/// [`Error::Core`] with an I/O error if the file cannot be read; [`Error::Hdf5`] if it is
/// not HDF5, lacks one of the datasets or `sampling_rate`, has a dataset of another shape
/// (e.g. `imu_gyr` N × 2) or type, or datasets of different lengths; [`Error::Empty`] for a
/// trial without samples; [`Error::InvalidParam`] for a sampling rate that is not finite and
/// positive; [`Error::NonFinite`] (at the frame) for a non-finite gyroscope or
/// accelerometer value.
pub fn read_broad_hdf5(path: impl AsRef<Path>) -> Result<ImuLog> {
    let path = path.as_ref();
    let bytes = std::fs::read(path).map_err(|e| skin_core::Error::io(path, e))?;
    if !hdf5_pure::is_hdf5_bytes(&bytes) {
        return Err(Error::Hdf5 {
            path: path.to_path_buf(),
            message: format!(
                "not an HDF5 file ({} bytes, no HDF5 signature)",
                bytes.len()
            ),
        });
    }
    let file = hdf5_pure::File::from_bytes(bytes).map_err(|e| Error::Hdf5 {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    let f = BroadFile { path, file };
    let (gyr, n) = f.dataset("imu_gyr", Some(3))?;
    let acc = f.same_length("imu_acc", Some(3), n)?;
    let quat = f.same_length("opt_quat", Some(4), n)?;
    let movement = f.same_length("movement", None, n)?;
    if n == 0 {
        return Err(Error::Empty {
            what: "BROAD trial",
        });
    }
    let rate = f.sampling_rate()?;
    let gyr = f.read_f64("imu_gyr", &gyr)?;
    let acc = f.read_f64("imu_acc", &acc)?;
    let quat = f.read_f64("opt_quat", &quat)?;
    let movement = f.read_flags(&movement)?;
    if (gyr.len(), acc.len(), quat.len(), movement.len()) != (3 * n, 3 * n, 4 * n, n) {
        return Err(f.error(format!(
            "decoded {} / {} / {} / {} values of imu_gyr / imu_acc / opt_quat / movement for {n} \
             samples",
            gyr.len(),
            acc.len(),
            quat.len(),
            movement.len()
        )));
    }
    let mut rec = ImuLog {
        time_s: Vec::with_capacity(n),
        readings: Vec::with_capacity(n),
        reference: Vec::with_capacity(n),
        movement,
    };
    let samples = gyr
        .chunks_exact(3)
        .zip(acc.chunks_exact(3))
        .zip(quat.chunks_exact(4));
    for (i, ((g, a), q)) in samples.enumerate() {
        skin_core::check::all_finite(
            "BROAD gyroscope and accelerometer values",
            g.iter().chain(a),
        )
        .at(Context::Frame(i))?;
        rec.time_s.push(i as f64 / rate);
        rec.readings
            .push(InertialReading::new(vec3(g, 0), vec3(a, 0)));
        let q = DQuat::from_xyzw(q[1], q[2], q[3], q[0]);
        rec.reference
            .push(if q.is_finite() { q.normalize() } else { q });
    }
    Ok(rec)
}

/// Reads x-io Fusion's `sensor_data.csv` (time s, gyroscope deg/s, accelerometer g,
/// magnetometer µT (unused)), converting to rad/s and m/s² (1 g = [`GRAVITY_M_S2`]).
///
/// # Errors
/// [`Error::Core`] I/O or parse error (with the line); [`Error::Empty`] without rows;
/// [`Error::NonFinite`] (at the frame) for a non-finite time or inertial value.
pub fn read_xio_csv(path: impl AsRef<Path>) -> Result<ImuLog> {
    let rows = read_rows(path.as_ref(), "x-io CSV", 7)?;
    let mut rec = ImuLog {
        time_s: Vec::with_capacity(rows.len()),
        readings: Vec::with_capacity(rows.len()),
        reference: Vec::new(),
        movement: Vec::new(),
    };
    for (i, r) in rows.iter().enumerate() {
        skin_core::check::all_finite("x-io time and inertial values", r[..7].iter())
            .at(Context::Frame(i))?;
        rec.time_s.push(r[0]);
        rec.readings.push(InertialReading::new(
            vec3(r, 1) * std::f64::consts::PI / 180.0,
            vec3(r, 4) * GRAVITY_M_S2,
        ));
    }
    Ok(rec)
}

/// The orientation filter's estimates over a recording.
#[derive(Debug, Clone)]
pub struct OrientationRun {
    /// Board-to-world rotation after each sample.
    pub orientation: Vec<DQuat>,
    /// Estimated rate after each sample (board axes), rad/s.
    pub rate_rad_s: Vec<DVec3>,
    /// Samples at which the filter diverged and was reset.
    pub diverged: usize,
    /// Wall-clock seconds spent in the filter.
    pub seconds: f64,
}

/// Runs [`OrientationEkf`] over `rec` with `up` = +z (both data sets' world frames are
/// z-up), `params.frame_time_s` set to the recording's mean sample interval, initialised
/// (§4.4.4) from the samples in `[0, rest_s)`.
///
/// # Errors
/// [`Error::Empty`] for an empty recording or no sample in the rest interval; as
/// [`RestAlignment::from_rest`], [`OrientationEkf::new`], [`OrientationEkf::step`] (at the
/// frame).
pub fn run_orientation(rec: &ImuLog, params: FilterParams, rest_s: f64) -> Result<OrientationRun> {
    if rec.is_empty() {
        return Err(Error::Empty { what: "recording" });
    }
    let t0 = rec.time_s[0];
    let n_rest = rec.time_s.iter().take_while(|t| **t - t0 < rest_s).count();
    let start = RestAlignment::from_rest(&rec.readings[..n_rest], DVec3::Z)?;
    let params = FilterParams {
        frame_time_s: rec.sample_time_s(),
        ..params
    };
    let mut ekf = OrientationEkf::new(params, DVec3::Z, start)?;
    let mut out = OrientationRun {
        orientation: Vec::with_capacity(rec.len()),
        rate_rad_s: Vec::with_capacity(rec.len()),
        diverged: 0,
        seconds: 0.0,
    };
    let clock = std::time::Instant::now();
    for (i, r) in rec.readings.iter().enumerate() {
        let s = ekf.step(r).at(Context::Frame(i))?;
        out.diverged += usize::from(s.diverged);
        out.orientation.push(ekf.orientation());
        out.rate_rad_s.push(ekf.rate_rad_s());
    }
    out.seconds = clock.elapsed().as_secs_f64();
    Ok(out)
}

#[cfg(test)]
mod tests;
