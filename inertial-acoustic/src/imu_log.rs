//! Real IMU recordings shipped with the repository (`data/imu-broad/`, `data/imu-xio/`; see
//! their SOURCE.md) as [`InertialReading`]s, and the orientation filter run over them.
//!
//! * BROAD trials 07 and 09, first 60 s of each (Laidig, Caruso, Cereatti, Seel, *BROAD — A
//!   Benchmark for Robust Inertial Orientation Estimation*, Data 6(7):72, 2021; CC BY 4.0):
//!   285.7 Hz gyroscope (rad/s) and accelerometer (m/s²) with an optical reference
//!   orientation (board-to-ENU, NaN where markers were lost) and the benchmark's `movement`
//!   flags.
//! * x-io Fusion's example log (MIT): 135 s at about 100 Hz, gyroscope in deg/s and
//!   accelerometer in g, no reference.

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

/// Reads a BROAD CSV excerpt (`data/imu-broad/*_first60s.csv`, written by its
/// `hdf5_to_csv.py`: time, gyroscope rad/s, accelerometer m/s², magnetometer µT (unused),
/// reference quaternion w, x, y, z, position (unused), movement flag).
///
/// # Errors
/// [`Error::Core`] I/O or parse error (with the line); [`Error::Empty`] without rows;
/// [`Error::NonFinite`] (at the frame) for a non-finite time or inertial value.
pub fn read_broad_csv(path: impl AsRef<Path>) -> Result<ImuLog> {
    let rows = read_rows(path.as_ref(), "BROAD CSV", 18)?;
    let mut rec = ImuLog {
        time_s: Vec::with_capacity(rows.len()),
        readings: Vec::with_capacity(rows.len()),
        reference: Vec::with_capacity(rows.len()),
        movement: Vec::with_capacity(rows.len()),
    };
    for (i, r) in rows.iter().enumerate() {
        skin_core::check::all_finite("BROAD time and inertial values", r[..7].iter())
            .at(Context::Frame(i))?;
        rec.time_s.push(r[0]);
        rec.readings
            .push(InertialReading::new(vec3(r, 1), vec3(r, 4)));
        let q = DQuat::from_xyzw(r[11], r[12], r[13], r[10]);
        rec.reference
            .push(if q.is_finite() { q.normalize() } else { q });
        rec.movement.push(r[17] != 0.0);
    }
    Ok(rec)
}

/// Reads x-io Fusion's `sensor_data.csv` (time s, gyroscope deg/s, accelerometer g,
/// magnetometer µT (unused)), converting to rad/s and m/s² (1 g = [`GRAVITY_M_S2`]).
///
/// # Errors
/// As [`read_broad_csv`].
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
