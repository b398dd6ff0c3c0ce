//! Writing and reading a [`Recording`] directory (the format is documented in the parent
//! module). Every number goes through `f64`'s `Display` (the shortest decimal that reads back
//! to the same value) and `str::parse` (exact), so a round trip is lossless.

use std::fs;
use std::path::Path;

use serde::{Deserialize, Serialize};
use skin_core::math::{DQuat, DVec3};
use skin_core::skeleton::Skeleton;

use super::Recording;
use crate::ekf::{DistanceMeasurement, FrameObservations, InertialReading, KnownDofs};
use crate::suit::{BoardNoise, SensorBoard, Suit, UltrasonicSource};
use crate::{Error, Result};

/// The manifest's `format` field.
const FORMAT: &str = "inertial-acoustic recording";

const MANIFEST: &str = "manifest.json";
const BOARDS: &str = "boards.csv";
const SOURCES: &str = "sources.csv";
const REST_POSE: &str = "rest_pose.csv";
const INERTIAL_DIR: &str = "inertial";
const DISTANCES: &str = "distances.csv";
const KNOWN: &str = "known_dofs.csv";

const BOARD_COLUMNS: [&str; 9] = [
    "name",
    "joint",
    "offset_x_m",
    "offset_y_m",
    "offset_z_m",
    "rot_x",
    "rot_y",
    "rot_z",
    "rot_w",
];
const NOISE_COLUMNS: [&str; 8] = [
    "gyro_sigma_rad_s",
    "accel_sigma_m_s2",
    "gyro_x_sigma_rad_s",
    "gyro_y_sigma_rad_s",
    "gyro_z_sigma_rad_s",
    "accel_x_sigma_m_s2",
    "accel_y_sigma_m_s2",
    "accel_z_sigma_m_s2",
];
const SOURCE_COLUMNS: [&str; 8] = [
    "name",
    "joint",
    "offset_x_m",
    "offset_y_m",
    "offset_z_m",
    "normal_x",
    "normal_y",
    "normal_z",
];
const REST_COLUMNS: [&str; 2] = ["dof", "value"];
const INERTIAL_COLUMNS: [&str; 8] = [
    "t_s",
    "gyro_x_rad_s",
    "gyro_y_rad_s",
    "gyro_z_rad_s",
    "accel_x_m_s2",
    "accel_y_m_s2",
    "accel_z_m_s2",
    "saturated",
];
const DISTANCE_COLUMNS: [&str; 6] = [
    "t_s",
    "board",
    "source",
    "distance_m",
    "confidence",
    "age_s",
];

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct SkeletonNames {
    joints: Vec<String>,
    dofs: Vec<String>,
}

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Manifest {
    format: String,
    version: u32,
    rate_hz: f64,
    start_s: f64,
    frames: usize,
    rest_frames: usize,
    skeleton: SkeletonNames,
    boards: Vec<String>,
    sources: Vec<String>,
    known_dofs: Vec<String>,
}

fn skeleton_names(skeleton: &Skeleton) -> SkeletonNames {
    SkeletonNames {
        joints: skeleton.joints().iter().map(|j| j.name.clone()).collect(),
        dofs: skeleton.dofs().map(|d| d.name.clone()).collect(),
    }
}

/// A malformed-file error naming the file and the 1-based line (0: the file as a whole).
fn bad(path: &Path, line: usize, message: impl std::fmt::Display) -> Error {
    skin_core::Error::Parse {
        format: "inertial-acoustic recording",
        line,
        message: format!("{}: {message}", path.display()),
    }
    .into()
}

/// A name that is also a file name: letters, digits, `_`, `-` and `.`, not starting with `.`.
fn check_name(what: &str, name: &str) -> Result<()> {
    let ok = !name.is_empty()
        && !name.starts_with('.')
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.'));
    if ok {
        Ok(())
    } else {
        Err(Error::InvalidParam {
            name: "recording names",
            reason: format!(
                "{what} name '{name}': use letters, digits, '_', '-' and '.', not leading '.'"
            ),
        })
    }
}

fn unique(what: &str, names: &[String]) -> Result<()> {
    for (i, n) in names.iter().enumerate() {
        check_name(what, n)?;
        if names[..i].contains(n) {
            return Err(Error::InvalidParam {
                name: "recording names",
                reason: format!("two {what}s are called '{n}'; give each its own name"),
            });
        }
    }
    Ok(())
}

fn writer(path: &Path, header: &[&str]) -> Result<csv::Writer<fs::File>> {
    let file = fs::File::create(path).map_err(|e| skin_core::Error::io(path, e))?;
    let mut w = csv::Writer::from_writer(file);
    w.write_record(header).map_err(|e| csv_error(path, e))?;
    Ok(w)
}

fn csv_error(path: &Path, e: csv::Error) -> Error {
    let line = e.position().map_or(0, |p| p.line() as usize);
    match e.into_kind() {
        csv::ErrorKind::Io(io) => skin_core::Error::io(path, io).into(),
        other => bad(path, line, format!("{other:?}")),
    }
}

fn finish(path: &Path, mut w: csv::Writer<fs::File>) -> Result<()> {
    w.flush().map_err(|e| skin_core::Error::io(path, e))?;
    Ok(())
}

fn saturated_text(s: &[bool; 6]) -> String {
    s.iter().map(|&b| if b { '1' } else { '0' }).collect()
}

impl Recording {
    /// The version of the recording format this crate writes and reads.
    pub const FORMAT_VERSION: u32 = 1;

    /// Writes the recording into the directory `dir` (created if needed; the files of the
    /// format are replaced, other files left alone), with joints and DOFs named after
    /// `skeleton`.
    ///
    /// # Errors
    /// As [`Recording::check`]; [`Error::InvalidParam`] for board, source or DOF names that
    /// are empty, repeated or not file-name safe; [`Error::Core`] for I/O errors.
    pub fn write(&self, dir: impl AsRef<Path>, skeleton: &Skeleton) -> Result<()> {
        self.check(skeleton)?;
        let dir = dir.as_ref();
        let names = skeleton_names(skeleton);
        let boards: Vec<String> = self.suit.boards().iter().map(|b| b.name.clone()).collect();
        let sources: Vec<String> = self.suit.sources().iter().map(|s| s.name.clone()).collect();
        unique("board", &boards)?;
        if sources.iter().any(|s| s.is_empty()) {
            return Err(Error::InvalidParam {
                name: "recording names",
                reason: "a source without a name; name every source".into(),
            });
        }
        unique("source", &sources)?;
        let known: Vec<String> = self
            .known_dofs
            .iter()
            .map(|&d| names.dofs[d].clone())
            .collect();
        if names
            .dofs
            .iter()
            .enumerate()
            .any(|(i, n)| names.dofs[..i].contains(n))
        {
            return Err(Error::InvalidParam {
                name: "skeleton",
                reason: "two DOFs share a name; the recording names DOFs".into(),
            });
        }
        fs::create_dir_all(dir.join(INERTIAL_DIR))
            .map_err(|e| skin_core::Error::io(dir.join(INERTIAL_DIR), e))?;
        let manifest = Manifest {
            format: FORMAT.into(),
            version: Recording::FORMAT_VERSION,
            rate_hz: self.rate_hz,
            start_s: self.start_s,
            frames: self.frames.len(),
            rest_frames: self.rest_frames,
            skeleton: names,
            boards,
            sources,
            known_dofs: known,
        };
        let path = dir.join(MANIFEST);
        let text = serde_json::to_string_pretty(&manifest).map_err(|e| Error::InvalidParam {
            name: "manifest",
            reason: e.to_string(),
        })?;
        fs::write(&path, text + "\n").map_err(|e| skin_core::Error::io(&path, e))?;
        self.write_suit(dir, &manifest)?;
        self.write_streams(dir, &manifest)?;
        Ok(())
    }

    fn write_suit(&self, dir: &Path, m: &Manifest) -> Result<()> {
        let joint = |j: usize| m.skeleton.joints[j].as_str();
        let path = dir.join(BOARDS);
        let noise = self.suit.board_noise();
        let mut header: Vec<&str> = BOARD_COLUMNS.to_vec();
        if !noise.is_empty() {
            header.extend(NOISE_COLUMNS);
        }
        let mut w = writer(&path, &header)?;
        for (i, b) in self.suit.boards().iter().enumerate() {
            let q = b.joint_from_sensor;
            let mut row = vec![b.name.clone(), joint(b.joint).to_string()];
            row.extend(
                [b.offset.x, b.offset.y, b.offset.z, q.x, q.y, q.z, q.w].map(|v| v.to_string()),
            );
            if let Some(n) = noise.get(i) {
                row.push(n.gyroscope_sigma.to_string());
                row.push(n.accelerometer_sigma.to_string());
                let axes = |a: Option<[f64; 3]>| {
                    a.map_or([String::new(), String::new(), String::new()], |v| {
                        v.map(|x| x.to_string())
                    })
                };
                row.extend(axes(n.gyroscope_axis_sigma));
                row.extend(axes(n.accelerometer_axis_sigma));
            }
            w.write_record(&row).map_err(|e| csv_error(&path, e))?;
        }
        finish(&path, w)?;
        let path = dir.join(SOURCES);
        let mut w = writer(&path, &SOURCE_COLUMNS)?;
        for s in self.suit.sources() {
            let mut row = vec![s.name.clone(), joint(s.joint).to_string()];
            row.extend(
                [
                    s.offset.x, s.offset.y, s.offset.z, s.normal.x, s.normal.y, s.normal.z,
                ]
                .map(|v| v.to_string()),
            );
            w.write_record(&row).map_err(|e| csv_error(&path, e))?;
        }
        finish(&path, w)?;
        let path = dir.join(REST_POSE);
        let mut w = writer(&path, &REST_COLUMNS)?;
        for (name, v) in m.skeleton.dofs.iter().zip(&self.rest_pose) {
            w.write_record([name.as_str(), &v.to_string()])
                .map_err(|e| csv_error(&path, e))?;
        }
        finish(&path, w)
    }

    fn write_streams(&self, dir: &Path, m: &Manifest) -> Result<()> {
        for (b, name) in m.boards.iter().enumerate() {
            let path = dir.join(INERTIAL_DIR).join(format!("{name}.csv"));
            let mut w = writer(&path, &INERTIAL_COLUMNS)?;
            for (k, f) in self.frames.iter().enumerate() {
                if let Some(r) = f.inertial[b] {
                    let (g, a) = (r.gyro_rad_s, r.accel_m_s2);
                    let mut row: Vec<String> = [self.time_s(k), g.x, g.y, g.z, a.x, a.y, a.z]
                        .iter()
                        .map(|v| v.to_string())
                        .collect();
                    row.push(saturated_text(&r.saturated));
                    w.write_record(&row).map_err(|e| csv_error(&path, e))?;
                }
            }
            finish(&path, w)?;
        }
        let path = dir.join(DISTANCES);
        let mut w = writer(&path, &DISTANCE_COLUMNS)?;
        for (k, f) in self.frames.iter().enumerate() {
            for d in &f.distances {
                w.write_record([
                    self.time_s(k).to_string(),
                    m.boards[d.sensor].clone(),
                    m.sources[d.source].clone(),
                    d.distance_m.to_string(),
                    d.confidence.to_string(),
                    d.age_s.to_string(),
                ])
                .map_err(|e| csv_error(&path, e))?;
            }
        }
        finish(&path, w)?;
        let path = dir.join(KNOWN);
        if self.known_dofs.is_empty() {
            return match fs::remove_file(&path) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                    Err(skin_core::Error::io(&path, e).into())
                }
                _ => Ok(()),
            };
        }
        let mut header = vec!["t_s".to_string()];
        for n in &m.known_dofs {
            header.extend([n.clone(), format!("{n}_rate"), format!("{n}_acc")]);
        }
        let header: Vec<&str> = header.iter().map(String::as_str).collect();
        let mut w = writer(&path, &header)?;
        for (k, kd) in self.known.iter().enumerate() {
            let mut row = vec![self.time_s(k).to_string()];
            for i in 0..m.known_dofs.len() {
                row.extend([kd.theta[i], kd.theta_dot[i], kd.theta_ddot[i]].map(|v| v.to_string()));
            }
            w.write_record(&row).map_err(|e| csv_error(&path, e))?;
        }
        finish(&path, w)
    }

    /// Reads the recording in the directory `dir` (as [`Recording::write`] writes it, or as
    /// any tool writes the documented format), for `skeleton`, and checks it
    /// ([`Recording::check`]).
    ///
    /// # Errors
    /// [`Error::Core`] with a parse error naming the file and line for a malformed manifest or
    /// CSV (wrong format or version, a skeleton whose joint or DOF names differ from the
    /// manifest's, unknown names, missing columns, unparsable or non-finite numbers, a
    /// truncated row, times out of order, repeated or outside the recording); I/O errors; as
    /// [`Suit::new`] and [`Recording::check`].
    pub fn read(dir: impl AsRef<Path>, skeleton: &Skeleton) -> Result<Recording> {
        let dir = dir.as_ref();
        let m = read_manifest(&dir.join(MANIFEST), skeleton)?;
        let timing = Timing {
            rate_hz: m.rate_hz,
            start_s: m.start_s,
            frames: m.frames,
        };
        let suit = read_suit(dir, &m, skeleton)?;
        let rest_pose = read_rest_pose(&dir.join(REST_POSE), &m)?;
        let mut frames = vec![
            FrameObservations {
                inertial: vec![None; m.boards.len()],
                distances: Vec::new(),
            };
            m.frames
        ];
        for (b, name) in m.boards.iter().enumerate() {
            let path = dir.join(INERTIAL_DIR).join(format!("{name}.csv"));
            read_inertial(&path, &timing, b, &mut frames)?;
        }
        read_distances(&dir.join(DISTANCES), &timing, &m, &mut frames)?;
        let known_dofs: Vec<usize> = m
            .known_dofs
            .iter()
            .map(|n| {
                skeleton
                    .dof_index(n)
                    .ok_or_else(|| bad(&dir.join(MANIFEST), 0, format!("unknown DOF '{n}'")))
            })
            .collect::<Result<_>>()?;
        let known = if known_dofs.is_empty() {
            Vec::new()
        } else {
            read_known(&dir.join(KNOWN), &timing, &m.known_dofs)?
        };
        let rec = Recording {
            rate_hz: m.rate_hz,
            start_s: m.start_s,
            suit,
            rest_frames: m.rest_frames,
            rest_pose,
            frames,
            known_dofs,
            known,
        };
        rec.check(skeleton)?;
        Ok(rec)
    }
}

fn read_manifest(path: &Path, skeleton: &Skeleton) -> Result<Manifest> {
    let text = fs::read_to_string(path).map_err(|e| skin_core::Error::io(path, e))?;
    let value: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| bad(path, e.line(), e))?;
    match value.get("format").and_then(|f| f.as_str()) {
        Some(FORMAT) => {}
        other => {
            return Err(bad(
                path,
                0,
                format!("format {other:?}, expected \"{FORMAT}\""),
            ))
        }
    }
    match value.get("version").and_then(|v| v.as_u64()) {
        Some(v) if v == u64::from(Recording::FORMAT_VERSION) => {}
        other => {
            return Err(bad(
                path,
                0,
                format!(
                    "version {other:?}: this build reads version {}; \
                     convert the recording or use a matching release",
                    Recording::FORMAT_VERSION
                ),
            ))
        }
    }
    let m: Manifest = serde_json::from_value(value).map_err(|e| bad(path, 0, e))?;
    let names = skeleton_names(skeleton);
    if m.skeleton.joints != names.joints || m.skeleton.dofs != names.dofs {
        return Err(bad(
            path,
            0,
            "the recording's skeleton (joint and DOF names) is not the one given; \
             read it with the skeleton it was recorded on",
        ));
    }
    if !(m.rate_hz.is_finite() && m.rate_hz > 0.0 && m.start_s.is_finite()) {
        return Err(bad(path, 0, "rate_hz must be positive and start_s finite"));
    }
    if m.rest_frames > m.frames {
        return Err(bad(path, 0, "rest_frames exceeds frames"));
    }
    if m.boards.is_empty() {
        return Err(bad(path, 0, "no boards"));
    }
    for (what, list) in [("board", &m.boards), ("source", &m.sources)] {
        unique(what, list).map_err(|e| bad(path, 0, e))?;
    }
    Ok(m)
}

/// The rows of a CSV file whose header must be `expected` (or, with `optional`, `expected`
/// followed by `optional`): each row with its 1-based line.
fn read_table(
    path: &Path,
    expected: &[&str],
    optional: &[&str],
) -> Result<(Vec<(usize, csv::StringRecord)>, bool)> {
    let file = fs::File::open(path).map_err(|e| skin_core::Error::io(path, e))?;
    let mut r = csv::ReaderBuilder::new().flexible(false).from_reader(file);
    let header = r.headers().map_err(|e| csv_error(path, e))?.clone();
    let got: Vec<&str> = header.iter().map(str::trim).collect();
    let full: Vec<&str> = expected.iter().chain(optional).copied().collect();
    let with_optional = if got == expected {
        false
    } else if !optional.is_empty() && got == full {
        true
    } else {
        return Err(bad(
            path,
            1,
            format!("columns {got:?}, expected {expected:?}"),
        ));
    };
    let mut rows = Vec::new();
    for rec in r.records() {
        let rec = rec.map_err(|e| csv_error(path, e))?;
        let line = rec.position().map_or(0, |p| p.line() as usize);
        rows.push((line, rec));
    }
    Ok((rows, with_optional))
}

/// Field `i` of a row as a finite number.
fn number(path: &Path, line: usize, row: &csv::StringRecord, i: usize, name: &str) -> Result<f64> {
    let text = row.get(i).unwrap_or("").trim();
    let v: f64 = text
        .parse()
        .map_err(|_| bad(path, line, format!("{name} '{text}' is not a number")))?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(bad(
            path,
            line,
            format!("{name} is {text}; give a finite value"),
        ))
    }
}

fn numbers<const N: usize>(
    path: &Path,
    line: usize,
    row: &csv::StringRecord,
    first: usize,
    names: &[&str],
) -> Result<[f64; N]> {
    let mut out = [0.0; N];
    for (k, v) in out.iter_mut().enumerate() {
        *v = number(path, line, row, first + k, names[first + k])?;
    }
    Ok(out)
}

fn joint_index(path: &Path, line: usize, skeleton: &Skeleton, name: &str) -> Result<usize> {
    skeleton
        .joint_index(name)
        .ok_or_else(|| bad(path, line, format!("unknown joint '{name}'")))
}

/// Checks that `rows` are one per name of `names`, in order, each naming its `what` in its
/// first field.
fn check_named(
    path: &Path,
    rows: &[(usize, csv::StringRecord)],
    names: &[String],
    what: &str,
) -> Result<()> {
    if rows.len() != names.len() {
        return Err(bad(
            path,
            0,
            format!(
                "{} rows, one per {what} ({}) expected",
                rows.len(),
                names.len()
            ),
        ));
    }
    for ((line, row), name) in rows.iter().zip(names) {
        let got = row.get(0).unwrap_or("").trim();
        if got != name {
            return Err(bad(
                path,
                *line,
                format!("{what} '{got}' where the manifest has '{name}'"),
            ));
        }
    }
    Ok(())
}

fn read_suit(dir: &Path, m: &Manifest, skeleton: &Skeleton) -> Result<Suit> {
    let path = dir.join(BOARDS);
    let (rows, with_noise) = read_table(&path, &BOARD_COLUMNS, &NOISE_COLUMNS)?;
    check_named(&path, &rows, &m.boards, "board")?;
    let columns: Vec<&str> = BOARD_COLUMNS
        .iter()
        .chain(&NOISE_COLUMNS)
        .copied()
        .collect();
    let mut boards = Vec::with_capacity(rows.len());
    let mut noise = Vec::new();
    for ((line, row), name) in rows.iter().zip(&m.boards) {
        let line = *line;
        let joint = joint_index(&path, line, skeleton, row.get(1).unwrap_or(""))?;
        let v: [f64; 7] = numbers(&path, line, row, 2, &columns)?;
        boards.push(SensorBoard {
            name: name.clone(),
            joint,
            offset: DVec3::new(v[0], v[1], v[2]),
            joint_from_sensor: DQuat::from_xyzw(v[3], v[4], v[5], v[6]),
        });
        if with_noise {
            let s: [f64; 2] = numbers(&path, line, row, 9, &columns)?;
            let axes = |first: usize| -> Result<Option<[f64; 3]>> {
                if (first..first + 3).all(|i| row.get(i).is_some_and(|t| t.trim().is_empty())) {
                    Ok(None)
                } else {
                    numbers(&path, line, row, first, &columns).map(Some)
                }
            };
            noise.push(BoardNoise {
                gyroscope_sigma: s[0],
                accelerometer_sigma: s[1],
                gyroscope_axis_sigma: axes(11)?,
                accelerometer_axis_sigma: axes(14)?,
            });
        }
    }
    let path = dir.join(SOURCES);
    let (rows, _) = read_table(&path, &SOURCE_COLUMNS, &[])?;
    check_named(&path, &rows, &m.sources, "source")?;
    let mut sources = Vec::with_capacity(rows.len());
    for ((line, row), name) in rows.iter().zip(&m.sources) {
        let line = *line;
        let joint = joint_index(&path, line, skeleton, row.get(1).unwrap_or(""))?;
        let v: [f64; 6] = numbers(&path, line, row, 2, &SOURCE_COLUMNS)?;
        sources.push(UltrasonicSource {
            name: name.clone(),
            joint,
            offset: DVec3::new(v[0], v[1], v[2]),
            normal: DVec3::new(v[3], v[4], v[5]),
        });
    }
    let suit = Suit::from_unit_parts(skeleton, boards, sources)?;
    if noise.is_empty() {
        Ok(suit)
    } else {
        suit.with_board_noise(noise)
    }
}

fn read_rest_pose(path: &Path, m: &Manifest) -> Result<Vec<f64>> {
    let (rows, _) = read_table(path, &REST_COLUMNS, &[])?;
    check_named(path, &rows, &m.skeleton.dofs, "DOF")?;
    rows.iter()
        .map(|(line, row)| number(path, *line, row, 1, "value"))
        .collect()
}

/// Frame timing, for mapping times to frames.
struct Timing {
    rate_hz: f64,
    start_s: f64,
    frames: usize,
}

impl Timing {
    /// The frame a time belongs to: within a quarter frame of it, inside the recording.
    fn frame(&self, path: &Path, line: usize, t: f64) -> Result<usize> {
        let x = (t - self.start_s) * self.rate_hz;
        let k = x.round();
        if (x - k).abs() > 0.25 {
            return Err(bad(
                path,
                line,
                format!("time {t} s is not on a frame (start_s + k / rate_hz)"),
            ));
        }
        if k < 0.0 || k >= self.frames as f64 {
            return Err(bad(
                path,
                line,
                format!(
                    "time {t} s is outside the recording's {} frames",
                    self.frames
                ),
            ));
        }
        Ok(k as usize)
    }
}

/// Checks `t` against the previous time of the file: increasing (strictly with `strict`).
fn ordered(
    path: &Path,
    line: usize,
    previous: &mut Option<f64>,
    t: f64,
    strict: bool,
) -> Result<()> {
    if let Some(p) = *previous {
        if t < p || (strict && t == p) {
            return Err(bad(
                path,
                line,
                format!(
                    "time {t} s after {p} s: times must {} down the file",
                    if strict {
                        "increase strictly"
                    } else {
                        "not decrease"
                    }
                ),
            ));
        }
    }
    *previous = Some(t);
    Ok(())
}

fn read_inertial(
    path: &Path,
    timing: &Timing,
    board: usize,
    frames: &mut [FrameObservations],
) -> Result<()> {
    let (rows, _) = read_table(path, &INERTIAL_COLUMNS, &[])?;
    let mut previous = None;
    for (line, row) in &rows {
        let line = *line;
        let v: [f64; 7] = numbers(path, line, row, 0, &INERTIAL_COLUMNS)?;
        ordered(path, line, &mut previous, v[0], true)?;
        let k = timing.frame(path, line, v[0])?;
        let flags = row.get(7).unwrap_or("").trim();
        let mut saturated = [false; 6];
        if flags.len() != 6 || !flags.chars().all(|c| c == '0' || c == '1') {
            return Err(bad(
                path,
                line,
                format!("saturated '{flags}': six 0/1 characters"),
            ));
        }
        for (s, c) in saturated.iter_mut().zip(flags.chars()) {
            *s = c == '1';
        }
        let slot = &mut frames[k].inertial[board];
        if slot.is_some() {
            return Err(bad(path, line, format!("a second reading for frame {k}")));
        }
        *slot = Some(InertialReading {
            gyro_rad_s: DVec3::new(v[1], v[2], v[3]),
            accel_m_s2: DVec3::new(v[4], v[5], v[6]),
            saturated,
        });
    }
    Ok(())
}

fn read_distances(
    path: &Path,
    timing: &Timing,
    m: &Manifest,
    frames: &mut [FrameObservations],
) -> Result<()> {
    let (rows, _) = read_table(path, &DISTANCE_COLUMNS, &[])?;
    let mut previous = None;
    for (line, row) in &rows {
        let line = *line;
        let t = number(path, line, row, 0, "t_s")?;
        ordered(path, line, &mut previous, t, false)?;
        let k = timing.frame(path, line, t)?;
        let index = |col: usize, names: &[String], what: &str| -> Result<usize> {
            let name = row.get(col).unwrap_or("").trim();
            names
                .iter()
                .position(|n| n == name)
                .ok_or_else(|| bad(path, line, format!("unknown {what} '{name}'")))
        };
        let sensor = index(1, &m.boards, "board")?;
        let source = index(2, &m.sources, "source")?;
        let v: [f64; 3] = numbers(path, line, row, 3, &DISTANCE_COLUMNS)?;
        frames[k].distances.push(DistanceMeasurement {
            sensor,
            source,
            distance_m: v[0],
            confidence: v[1],
            age_s: v[2],
        });
    }
    Ok(())
}

fn read_known(path: &Path, timing: &Timing, dofs: &[String]) -> Result<Vec<KnownDofs>> {
    let mut header = vec!["t_s".to_string()];
    for n in dofs {
        header.extend([n.clone(), format!("{n}_rate"), format!("{n}_acc")]);
    }
    let columns: Vec<&str> = header.iter().map(String::as_str).collect();
    let (rows, _) = read_table(path, &columns, &[])?;
    if rows.len() != timing.frames {
        return Err(bad(
            path,
            0,
            format!(
                "{} rows, one per frame ({}) expected",
                rows.len(),
                timing.frames
            ),
        ));
    }
    let mut previous = None;
    let mut out = Vec::with_capacity(rows.len());
    for (i, (line, row)) in rows.iter().enumerate() {
        let line = *line;
        let t = number(path, line, row, 0, "t_s")?;
        ordered(path, line, &mut previous, t, true)?;
        if timing.frame(path, line, t)? != i {
            return Err(bad(path, line, format!("row for frame {i} has time {t} s")));
        }
        let mut kd = KnownDofs::default();
        for d in 0..dofs.len() {
            let at = 1 + 3 * d;
            kd.theta.push(number(path, line, row, at, columns[at])?);
            kd.theta_dot
                .push(number(path, line, row, at + 1, columns[at + 1])?);
            kd.theta_ddot
                .push(number(path, line, row, at + 2, columns[at + 2])?);
        }
        out.push(kd);
    }
    Ok(out)
}
