//! The recording format: a lossless round trip, and one bad-file test per field.

use super::Recording;
use crate::ekf::{DistanceMeasurement, FrameObservations, InertialReading, KnownDofs};
use crate::suit::{BoardNoise, Suit};
use crate::Error;
use skin_core::math::DVec3;
use skin_core::skeleton::{human_skeleton, HumanParams, Skeleton};
use std::path::{Path, PathBuf};

/// A fresh scratch directory for one test.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "inertial-acoustic-recording-{name}-{}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// Values that print with many digits, so that a lossy format would change them.
fn awkward(i: usize) -> f64 {
    (i as f64 * 0.377_123_456_7 + 0.1).sin() * 10f64.powi((i % 7) as i32 - 3)
}

/// A recording of the thesis's suit with every field exercised: lost readings, saturation
/// flags, several distances per frame, known root DOFs and per-board (and per-axis) noise.
fn sample(skeleton: &Skeleton, frames: usize) -> Recording {
    let suit = Suit::vlasic(skeleton).unwrap();
    let nb = suit.boards().len();
    let noise = (0..nb)
        .map(|b| {
            let n = BoardNoise::new(0.01 + awkward(b).abs(), 0.3 + awkward(b + 1).abs());
            if b % 2 == 0 {
                n.with_axes([0.02, 0.03, awkward(b).abs() + 0.01], [0.4, 0.5, 0.6])
            } else {
                n
            }
        })
        .collect();
    let suit = suit.with_board_noise(noise).unwrap();
    let ns = suit.sources().len();
    let root: Vec<usize> = skeleton.joint_dofs(0).collect();
    let mut i = 0;
    let mut next = || {
        i += 1;
        awkward(i)
    };
    let frames_v = (0..frames)
        .map(|k| FrameObservations {
            inertial: (0..nb)
                .map(|b| {
                    ((k + b) % 5 != 0).then(|| InertialReading {
                        gyro_rad_s: DVec3::new(next(), next(), next()),
                        accel_m_s2: DVec3::new(next(), next(), next()),
                        saturated: [k % 3 == 0, false, b % 4 == 0, false, false, k % 7 == 0],
                    })
                })
                .collect(),
            distances: (0..(k % 3))
                .map(|m| DistanceMeasurement {
                    sensor: (k + 5 * m) % nb,
                    source: (k + m) % ns,
                    distance_m: 0.5 + next().abs(),
                    confidence: next().abs().min(1.0),
                    age_s: next().abs() * 1e-3,
                })
                .collect(),
        })
        .collect();
    let mut rest_pose = skeleton.rest_pose();
    for v in rest_pose.iter_mut() {
        *v += next() * 1e-3;
    }
    let known = (0..frames)
        .map(|_| KnownDofs {
            theta: root.iter().map(|_| next()).collect(),
            theta_dot: root.iter().map(|_| next()).collect(),
            theta_ddot: root.iter().map(|_| next()).collect(),
        })
        .collect();
    Recording {
        rate_hz: 140.0,
        start_s: 12.5,
        suit,
        rest_frames: 3,
        rest_pose,
        frames: frames_v,
        known_dofs: root,
        known,
    }
}

fn skeleton() -> Skeleton {
    human_skeleton(&HumanParams::default()).unwrap()
}

#[test]
fn round_trip_is_lossless() {
    let s = skeleton();
    let rec = sample(&s, 40);
    let dir = scratch("round-trip");
    rec.write(&dir, &s).unwrap();
    let back = Recording::read(&dir, &s).unwrap();
    assert_eq!(back, rec);
    // Writing again over the same directory gives the same files.
    back.write(&dir, &s).unwrap();
    assert_eq!(Recording::read(&dir, &s).unwrap(), rec);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn one_board_without_sources_or_known_dofs_round_trips() {
    let s = skeleton();
    let full = Suit::vlasic(&s).unwrap();
    let suit = Suit::new(&s, vec![full.boards()[3].clone()], Vec::new()).unwrap();
    let rec = Recording {
        rate_hz: 285.714_285_714_285_7,
        start_s: 0.0,
        suit,
        rest_frames: 0,
        rest_pose: s.rest_pose(),
        frames: (0..25)
            .map(|k| FrameObservations {
                inertial: vec![Some(InertialReading::new(
                    DVec3::new(awkward(k), 0.0, 1e-9),
                    DVec3::new(0.0, 9.81, awkward(k + 3)),
                ))],
                distances: Vec::new(),
            })
            .collect(),
        known_dofs: Vec::new(),
        known: Vec::new(),
    };
    let dir = scratch("one-board");
    rec.write(&dir, &s).unwrap();
    assert!(!dir.join("known_dofs.csv").exists());
    assert_eq!(Recording::read(&dir, &s).unwrap(), rec);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Writes the sample, applies `edit` to `file`'s text, and returns the read's error.
fn read_after(name: &str, file: &str, edit: impl Fn(&str) -> String) -> Error {
    let s = skeleton();
    let dir = scratch(name);
    sample(&s, 12).write(&dir, &s).unwrap();
    let path = dir.join(file);
    let text = std::fs::read_to_string(&path).unwrap();
    std::fs::write(&path, edit(&text)).unwrap();
    let read = Recording::read(&dir, &s);
    let _ = std::fs::remove_dir_all(&dir);
    match read {
        Ok(_) => panic!("{name}: the edited {file} read without an error"),
        Err(e) => e,
    }
}

fn says(err: &Error, words: &[&str]) {
    let text = err.to_string();
    for w in words {
        assert!(text.contains(w), "error '{text}' should mention '{w}'");
    }
}

/// Replaces the `n`-th data row's `col`-th field (0-based) of a CSV text.
fn set_field(text: &str, row: usize, col: usize, value: &str) -> String {
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let mut fields: Vec<String> = lines[row + 1].split(',').map(str::to_string).collect();
    fields[col] = value.to_string();
    lines[row + 1] = fields.join(",");
    lines.join("\n") + "\n"
}

fn swap_rows(text: &str, a: usize, b: usize) -> String {
    let mut lines: Vec<&str> = text.lines().collect();
    lines.swap(a + 1, b + 1);
    lines.join("\n") + "\n"
}

fn truncate(text: &str) -> String {
    // Cut the last row in the middle of a field.
    let cut = text.trim_end().rfind(',').unwrap();
    text[..cut].to_string()
}

#[test]
fn manifest_errors_name_the_field() {
    let e = read_after("version", "manifest.json", |t| {
        t.replace("\"version\": 1", "\"version\": 2")
    });
    says(&e, &["manifest.json", "version", "reads version 1"]);
    let e = read_after("format", "manifest.json", |t| {
        t.replace("inertial-acoustic recording", "something else")
    });
    says(&e, &["format"]);
    let e = read_after("manifest-truncated", "manifest.json", |t| {
        t[..t.len() / 2].to_string()
    });
    says(&e, &["manifest.json"]);
    let e = read_after("rate", "manifest.json", |t| {
        t.replace("\"rate_hz\": 140.0", "\"rate_hz\": -140.0")
    });
    says(&e, &["rate_hz"]);
    let e = read_after("rest-frames", "manifest.json", |t| {
        t.replace("\"rest_frames\": 3", "\"rest_frames\": 99")
    });
    says(&e, &["rest_frames"]);
    let e = read_after("board-name", "manifest.json", |t| {
        t.replace("\"sternum\"", "\"../x\"")
    });
    says(&e, &["../x"]);
    // A skeleton with other names.
    let s = skeleton();
    let dir = scratch("skeleton");
    sample(&s, 5).write(&dir, &s).unwrap();
    let mut other = s.joints().to_vec();
    other[1].name = "renamed".into();
    let other = Skeleton::new(other).unwrap();
    says(
        &Recording::read(&dir, &other).unwrap_err(),
        &["skeleton", "recorded on"],
    );
    let _ = std::fs::remove_dir_all(&dir);
    says(
        &Recording::read(Path::new("/nonexistent/recording"), &s).unwrap_err(),
        &["manifest.json"],
    );
}

#[test]
fn inertial_stream_errors_name_file_and_line() {
    let f = "inertial/sternum.csv";
    says(
        &read_after("in-nan", f, |t| set_field(t, 2, 3, "NaN")),
        &["sternum.csv", "line 4", "finite"],
    );
    says(
        &read_after("in-inf", f, |t| set_field(t, 0, 5, "inf")),
        &["line 2", "finite"],
    );
    says(
        &read_after("in-text", f, |t| set_field(t, 1, 1, "fast")),
        &["line 3", "not a number"],
    );
    says(
        &read_after("in-unsorted", f, |t| swap_rows(t, 1, 2)),
        &["increase strictly"],
    );
    says(
        &read_after("in-duplicate", f, |t| {
            let second = t.lines().nth(2).unwrap().to_string();
            set_field(t, 0, 0, second.split(',').next().unwrap())
        }),
        &["increase strictly"],
    );
    says(
        &read_after("in-off-frame", f, |t| set_field(t, 0, 0, "12.5035")),
        &["not on a frame"],
    );
    says(
        &read_after("in-outside", f, |t| set_field(t, 0, 0, "11.0")),
        &["outside"],
    );
    says(&read_after("in-truncated", f, truncate), &["sternum.csv"]);
    says(
        &read_after("in-flags", f, |t| set_field(t, 0, 7, "0102")),
        &["saturated"],
    );
    says(
        &read_after("in-columns", f, |t| t.replacen("t_s", "time", 1)),
        &["columns"],
    );
    says(
        &read_after("in-missing", f, |_| String::new()),
        &["sternum.csv"],
    );
}

#[test]
fn distance_known_and_suit_errors_name_file_and_line() {
    let d = "distances.csv";
    says(
        &read_after("d-nan", d, |t| set_field(t, 0, 3, "nan")),
        &["distances.csv", "finite"],
    );
    says(
        &read_after("d-board", d, |t| set_field(t, 0, 1, "elbow_patch")),
        &["unknown board"],
    );
    says(
        &read_after("d-source", d, |t| set_field(t, 0, 2, "nowhere")),
        &["unknown source"],
    );
    says(
        &read_after("d-unsorted", d, |t| {
            let n = t.lines().count() - 1;
            swap_rows(t, 0, n - 1)
        }),
        &["not decrease"],
    );
    says(&read_after("d-truncated", d, truncate), &["distances.csv"]);
    let k = "known_dofs.csv";
    says(
        &read_after("k-nan", k, |t| set_field(t, 4, 2, "NaN")),
        &["known_dofs.csv", "finite"],
    );
    says(
        &read_after("k-unsorted", k, |t| {
            let earlier = t
                .lines()
                .nth(3)
                .unwrap()
                .split(',')
                .next()
                .unwrap()
                .to_string();
            set_field(t, 4, 0, &earlier)
        }),
        &["increase strictly"],
    );
    says(
        &read_after("k-frame", k, |t| swap_rows(t, 3, 4)),
        &["row for frame 3"],
    );
    says(
        &read_after("k-rows", k, |t| {
            let mut l: Vec<&str> = t.lines().collect();
            l.pop();
            l.join("\n") + "\n"
        }),
        &["one per frame"],
    );
    says(&read_after("k-truncated", k, truncate), &["known_dofs.csv"]);
    let b = "boards.csv";
    says(
        &read_after("b-joint", b, |t| set_field(t, 1, 1, "tail")),
        &["unknown joint 'tail'"],
    );
    says(
        &read_after("b-nan", b, |t| set_field(t, 1, 3, "NaN")),
        &["boards.csv", "finite"],
    );
    says(
        &read_after("b-quat", b, |t| set_field(t, 1, 8, "2")),
        &["unit"],
    );
    says(
        &read_after("b-sigma", b, |t| set_field(t, 2, 9, "-1")),
        &["gyroscope_sigma"],
    );
    says(
        &read_after("b-name", b, |t| set_field(t, 0, 0, "hip")),
        &["where the manifest has"],
    );
    says(
        &read_after("s-normal", "sources.csv", |t| set_field(t, 0, 7, "0.5")),
        &["unit"],
    );
    says(
        &read_after("r-nan", "rest_pose.csv", |t| set_field(t, 4, 1, "NaN")),
        &["rest_pose.csv", "finite"],
    );
    says(
        &read_after("r-rows", "rest_pose.csv", truncate),
        &["rest_pose.csv"],
    );
}

#[test]
fn writing_rejects_what_it_could_not_read_back() {
    let s = skeleton();
    let dir = scratch("write-errors");
    let mut rec = sample(&s, 6);
    rec.frames[2].inertial[1] = Some(InertialReading::new(
        DVec3::new(f64::NAN, 0.0, 0.0),
        DVec3::ZERO,
    ));
    assert!(matches!(rec.write(&dir, &s).unwrap_err(), Error::At { .. }));
    let mut rec = sample(&s, 6);
    rec.frames[1].distances.push(DistanceMeasurement {
        sensor: 99,
        source: 0,
        distance_m: 1.0,
        confidence: 1.0,
        age_s: 0.0,
    });
    assert!(rec.write(&dir, &s).is_err());
    let mut rec = sample(&s, 6);
    rec.known.pop();
    assert!(rec.write(&dir, &s).is_err());
    let mut rec = sample(&s, 6);
    rec.rest_pose.pop();
    assert!(rec.write(&dir, &s).is_err());
    let mut rec = sample(&s, 6);
    rec.rate_hz = f64::NAN;
    assert!(rec.write(&dir, &s).is_err());
    let _ = std::fs::remove_dir_all(&dir);
}
