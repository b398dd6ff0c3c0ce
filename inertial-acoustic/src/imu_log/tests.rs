//! The BROAD reader: a file in BROAD's layout reads back, and one test per way a file can be
//! wrong. The files are written here with `hdf5-pure`'s writer, in BROAD's storage (one
//! whole-array chunk, gzip level 9, `movement` as an 8-bit enum FALSE/TRUE).

use super::read_broad_hdf5;
use crate::{Context, Error};
use hdf5_pure::{make_i8_type, AttrValue, EnumTypeBuilder, FileBuilder};
use std::path::PathBuf;

/// One dataset of a test file: name, values (row-major) and shape.
struct Part {
    name: &'static str,
    values: Vec<f64>,
    shape: Vec<u64>,
}

/// A BROAD trial of `n` samples, before a test breaks it: the datasets, `movement` and the
/// root attribute `sampling_rate`.
struct Trial {
    parts: Vec<Part>,
    movement: Vec<u8>,
    rate: Option<f64>,
}

const RATE_HZ: f64 = 2000.0 / 7.0;

fn trial(n: usize) -> Trial {
    let series = |cols: usize, f: fn(usize, usize) -> f64| Part {
        name: "",
        values: (0..n * cols).map(|v| f(v / cols, v % cols)).collect(),
        shape: vec![n as u64, cols as u64],
    };
    let gyr = series(3, |i, c| 0.01 * (i as f64 + 1.0) * (c as f64 - 1.0));
    let acc = series(3, |i, c| if c == 2 { 9.81 } else { 0.001 * i as f64 });
    let mag = series(3, |_, c| 20.0 * c as f64);
    let pos = series(3, |i, _| 0.1 * i as f64);
    // Sample 1 has no reference (markers lost); the others are 2 × unit quaternions.
    let quat = series(4, |i, c| match (i, c) {
        (1, _) => f64::NAN,
        (_, 0) => 2.0 * 0.6,
        (_, 3) => 2.0 * 0.8,
        _ => 0.0,
    });
    let named = |name, p: Part| Part { name, ..p };
    Trial {
        parts: vec![
            named("imu_acc", acc),
            named("imu_gyr", gyr),
            named("imu_mag", mag),
            named("opt_pos", pos),
            named("opt_quat", quat),
        ],
        movement: (0..n).map(|i| u8::from(i % 2 == 0)).collect(),
        rate: Some(RATE_HZ),
    }
}

impl Trial {
    fn part(&mut self, name: &str) -> &mut Part {
        self.parts.iter_mut().find(|p| p.name == name).unwrap()
    }

    /// Writes the trial to a fresh file named after the test.
    fn write(&self, test: &str) -> PathBuf {
        let mut b = FileBuilder::new();
        for p in &self.parts {
            let d = b.create_dataset(p.name);
            d.with_f64_data(&p.values).with_shape(&p.shape);
            if !p.values.is_empty() {
                d.with_chunks(&p.shape).with_deflate(9);
            }
        }
        let bool_type = EnumTypeBuilder::with_base(make_i8_type())
            .value("FALSE", 0)
            .value("TRUE", 1)
            .build()
            .unwrap();
        let d = b.create_dataset("movement");
        d.with_enum_u8_data(bool_type, &self.movement);
        if !self.movement.is_empty() {
            d.with_chunks(&[self.movement.len() as u64]).with_deflate(9);
        }
        if let Some(rate) = self.rate {
            b.set_attr("sampling_rate", AttrValue::F64(rate));
        }
        b.set_attr("info", AttrValue::VarLenString("a test trial".into()));
        let path = scratch(test);
        b.write(&path).unwrap();
        path
    }
}

/// A fresh file path for one test.
fn scratch(test: &str) -> PathBuf {
    let dir =
        std::env::temp_dir().join(format!("inertial-acoustic-imu-log-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(format!("{test}.hdf5"))
}

/// The message of an [`Error::Hdf5`], or a panic naming the error it got.
fn hdf5_message(e: Error) -> String {
    match e {
        Error::Hdf5 { message, .. } => message,
        e => panic!("expected Error::Hdf5, got {e:?}"),
    }
}

#[test]
fn a_trial_in_broads_layout_reads_back() {
    let t = trial(4);
    let rec = read_broad_hdf5(t.write("reads_back")).unwrap();
    assert_eq!(rec.len(), 4);
    for (k, time) in rec.time_s.iter().enumerate() {
        assert_eq!(*time, k as f64 / RATE_HZ);
    }
    assert!((rec.sample_time_s() - 0.0035).abs() < 1e-15);
    let r = &rec.readings[3];
    assert_eq!(r.gyro_rad_s.to_array(), [-0.04, 0.0, 0.04]);
    assert_eq!(r.accel_m_s2.to_array(), [0.003, 0.003, 9.81]);
    // (w, x, y, z) = 2 × (0.6, 0, 0, 0.8), normalised; NaN kept where markers were lost.
    let q = rec.reference[0];
    assert!((q.w - 0.6).abs() < 1e-15 && (q.z - 0.8).abs() < 1e-15 && q.x == 0.0 && q.y == 0.0);
    assert!(rec.reference[1].is_nan());
    assert_eq!(rec.movement, [true, false, true, false]);
}

#[test]
fn a_file_that_is_not_hdf5_is_refused() {
    let path = scratch("not_hdf5");
    std::fs::write(&path, "t_s,gyr_x_rad_s\n0,0.1\n").unwrap();
    let msg = hdf5_message(read_broad_hdf5(&path).unwrap_err());
    assert!(msg.contains("not an HDF5 file"), "{msg}");
    // An empty file is not HDF5 either.
    std::fs::write(&path, "").unwrap();
    let e = read_broad_hdf5(&path).unwrap_err();
    assert!(e.to_string().contains("not an HDF5 file (0 bytes"), "{e}");
    // A missing file is an I/O error naming it.
    let e = read_broad_hdf5(scratch("no_such_file")).unwrap_err();
    assert!(
        matches!(e, Error::Core(skin_core::Error::Io { .. })),
        "{e:?}"
    );
}

#[test]
fn a_missing_dataset_or_rate_is_named() {
    let mut t = trial(4);
    t.parts.retain(|p| p.name != "opt_quat");
    let msg = hdf5_message(read_broad_hdf5(t.write("missing_dataset")).unwrap_err());
    assert!(msg.contains("`opt_quat`"), "{msg}");
    let mut t = trial(4);
    t.rate = None;
    let msg = hdf5_message(read_broad_hdf5(t.write("missing_rate")).unwrap_err());
    assert!(msg.contains("no root attribute `sampling_rate`"), "{msg}");
    let mut t = trial(4);
    t.rate = Some(0.0);
    let e = read_broad_hdf5(t.write("zero_rate")).unwrap_err();
    assert!(
        matches!(e, Error::Core(skin_core::Error::InvalidParam { .. })),
        "{e:?}"
    );
}

#[test]
fn a_dataset_of_the_wrong_shape_is_refused() {
    let mut t = trial(4);
    let gyr = t.part("imu_gyr");
    gyr.values.truncate(8);
    gyr.shape = vec![4, 2];
    let msg = hdf5_message(read_broad_hdf5(t.write("gyr_n_by_2")).unwrap_err());
    assert!(
        msg.contains("`imu_gyr` has shape [4, 2], expected [N, 3]"),
        "{msg}"
    );
    let mut t = trial(4);
    t.part("opt_quat").shape = vec![4, 2, 2];
    let msg = hdf5_message(read_broad_hdf5(t.write("quat_rank_3")).unwrap_err());
    assert!(
        msg.contains("`opt_quat` has shape [4, 2, 2], expected [N, 4]"),
        "{msg}"
    );
}

#[test]
fn datasets_of_different_lengths_are_refused() {
    let mut t = trial(4);
    let acc = t.part("imu_acc");
    acc.values.truncate(9);
    acc.shape = vec![3, 3];
    let msg = hdf5_message(read_broad_hdf5(t.write("acc_short")).unwrap_err());
    assert!(
        msg.contains("`imu_acc` has 3 samples, `imu_gyr` 4"),
        "{msg}"
    );
    let mut t = trial(4);
    t.movement.push(1);
    let msg = hdf5_message(read_broad_hdf5(t.write("movement_long")).unwrap_err());
    assert!(
        msg.contains("`movement` has 5 samples, `imu_gyr` 4"),
        "{msg}"
    );
}

#[test]
fn a_non_finite_inertial_value_is_refused_at_its_sample() {
    for (name, at) in [("imu_gyr", 4), ("imu_acc", 8)] {
        let mut t = trial(4);
        t.part(name).values[at] = f64::INFINITY;
        let e = read_broad_hdf5(t.write(name)).unwrap_err();
        assert_eq!(e.contexts(), [Context::Frame(at / 3)], "{e}");
        assert!(
            matches!(e.root(), Error::Core(skin_core::Error::NonFinite { .. })),
            "{e:?}"
        );
    }
}

#[test]
fn a_trial_without_samples_is_refused() {
    let t = trial(0);
    let e = read_broad_hdf5(t.write("no_samples")).unwrap_err();
    assert!(matches!(e, Error::Empty { .. }), "{e:?}");
}
