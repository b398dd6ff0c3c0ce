//! Records of the examples' figures, committed under `results/` (full runs) and
//! `results/quick/` (quick runs) by `cargo run --release --example tour -- [--full] --record`:
//! each example's figures with its headlines, the commit, the machine and the date they were
//! measured. The results page (`docs/results.md`, `--example results`) is generated from them,
//! and CI re-runs the fast quick examples against their records ([`accuracy_differences`]).

use std::path::{Path, PathBuf};
use std::process::Command;

use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};

use crate::report::{Headline, Manifest};
use crate::{Error, Result};

/// The machine a record was measured on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Machine {
    /// Logical cores.
    pub cores: usize,
    /// One-minute load average when the example started (`/proc/loadavg`; NaN elsewhere).
    pub load_1min_start: f64,
    /// The same when it finished.
    pub load_1min_end: f64,
}

impl Machine {
    /// This machine, with the load now as both loads.
    pub fn now() -> Machine {
        let load = load_1min();
        Machine {
            cores: std::thread::available_parallelism().map_or(1, |n| n.get()),
            load_1min_start: load,
            load_1min_end: load,
        }
    }
}

/// The one-minute load average (NaN where `/proc/loadavg` is missing).
pub fn load_1min() -> f64 {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|t| t.split_whitespace().next()?.parse().ok())
        .unwrap_or(f64::NAN)
}

/// One example's figures as measured.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Record {
    /// The example's name.
    pub example: String,
    /// A quick (`--quick`) or full-size run.
    pub quick: bool,
    /// The commit measured (`git rev-parse HEAD`), with `-dirty` when the tree had changes.
    pub commit: String,
    /// UTC date and time the run finished, ISO 8601.
    pub date: String,
    /// Where it ran.
    pub machine: Machine,
    /// Wall-clock seconds of the run.
    pub seconds: f64,
    /// What ran (the manifest's caption).
    pub caption: String,
    /// The headline figures with their units and goals.
    pub headlines: Vec<Headline>,
    /// Every figure the example wrote.
    pub figures: Map<String, Value>,
}

impl Record {
    /// A record of the run of `manifest` that wrote `figures`, measured now.
    pub fn new(
        manifest: &Manifest,
        figures: Map<String, Value>,
        machine: Machine,
        seconds: f64,
    ) -> Record {
        Record {
            example: manifest.example.clone(),
            quick: manifest.quick,
            commit: commit(),
            date: utc_now(),
            machine,
            seconds,
            caption: manifest.caption.clone(),
            headlines: manifest.headlines.clone(),
            figures,
        }
    }

    /// Its file under the results folder `dir`: `dir/<example>.json` or
    /// `dir/quick/<example>.json`.
    pub fn path_in(dir: &Path, example: &str, quick: bool) -> PathBuf {
        if quick {
            dir.join("quick").join(format!("{example}.json"))
        } else {
            dir.join(format!("{example}.json"))
        }
    }

    /// Writes it under the results folder `dir` (pretty JSON, keys sorted by serde_json).
    ///
    /// # Errors
    /// [`Error::Io`] when the folder or file cannot be written.
    pub fn write(&self, dir: &Path) -> Result<PathBuf> {
        let path = Record::path_in(dir, &self.example, self.quick);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent)
                .map_err(|e| Error::Io(format!("{}: {e}", parent.display())))?;
        }
        let text = serde_json::to_string_pretty(self).map_err(|e| Error::Json(e.to_string()))?;
        std::fs::write(&path, text + "\n")
            .map_err(|e| Error::Io(format!("{}: {e}", path.display())))?;
        Ok(path)
    }

    /// Reads a record file.
    ///
    /// # Errors
    /// [`Error::Io`] or [`Error::Json`] naming the file.
    pub fn read(path: &Path) -> Result<Record> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| Error::Io(format!("{}: {e}", path.display())))?;
        serde_json::from_str(&text).map_err(|e| Error::Json(format!("{}: {e}", path.display())))
    }

    /// Every record in the results folder `dir` (full runs, or with `quick` the quick ones),
    /// sorted by example.
    ///
    /// # Errors
    /// As [`Record::read`]; a missing folder gives no records.
    pub fn read_all(dir: &Path, quick: bool) -> Result<Vec<Record>> {
        let dir = if quick {
            dir.join("quick")
        } else {
            dir.to_path_buf()
        };
        let Ok(entries) = std::fs::read_dir(&dir) else {
            return Ok(Vec::new());
        };
        let mut paths: Vec<PathBuf> = entries
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.extension().is_some_and(|x| x == "json"))
            .collect();
        paths.sort();
        paths.iter().map(|p| Record::read(p)).collect()
    }
}

/// The methods in order, each with its crate (its reference page is `docs/<crate>.md`, its
/// section of the results page `docs/results.md#<crate>`), what it does and its examples.
pub const METHODS: [(&str, &str, &[&str]); 6] = [
    (
        "needle-model",
        "Skin deformation from silhouettes (Sand 2003)",
        &["needle_capture"],
    ),
    (
        "template-silhouette",
        "Skeleton tracking and template molding to silhouettes (Vlasic thesis Ch. 2; Fua et al.)",
        &["template_capture", "ellipsoid_fit", "capture_anywhere"],
    ),
    (
        "photometric-normals",
        "Normals from spherical lighting, integration, matching, merging (Ch. 3)",
        &[
            "photometric_normals",
            "photometric_reconstruction",
            "surface_merge",
        ],
    ),
    (
        "inertial-acoustic",
        "Wearable capture: inertial and ultrasonic sensing, skeletal EKF (Ch. 4)",
        &["inertial_capture"],
    ),
    (
        "multilinear-face",
        "Multilinear face models, tracking and transfer (Ch. 5)",
        &["face_transfer"],
    ),
    (
        "skin-core",
        "Foundations and the studio: cameras, markers, skeletons, meshes",
        &["studio", "calibrate", "markers", "laplacian_edit"],
    ),
];

/// The crate whose section of the results page holds `example`.
pub fn method_of(example: &str) -> Option<&'static str> {
    METHODS
        .iter()
        .find(|(_, _, examples)| examples.contains(&example))
        .map(|(krate, _, _)| *krate)
}

/// Whether a figure's key names a timing, a speed, a memory size or a machine load: those
/// vary from run to run and are not accuracy figures.
pub fn is_timing_key(key: &str) -> bool {
    let k = key.to_ascii_lowercase();
    [
        "_ms",
        "_s",
        "_us",
        "ms_",
        "fps",
        "seconds",
        "time",
        "realtime",
        "per_s",
        "rss",
        "_mb",
        "cpu",
        "speed",
        "hz_achieved",
        "load",
        "bytes",
        "_kb",
    ]
    .iter()
    .any(|p| k.contains(p))
}

/// The accuracy figures that differ between a record's figures and a new run's, timings and
/// memory aside ([`is_timing_key`]): one line per difference, `path: recorded -> now`. Numbers
/// agree within 10⁻⁹ relative; fields listed in `ignore` (dotted paths) are skipped.
pub fn accuracy_differences(recorded: &Value, now: &Value, ignore: &[&str]) -> Vec<String> {
    let mut out = Vec::new();
    walk(recorded, now, "", ignore, &mut out);
    out
}

fn walk(a: &Value, b: &Value, path: &str, ignore: &[&str], out: &mut Vec<String>) {
    if ignore.contains(&path.trim_end_matches('.')) {
        return;
    }
    match (a, b) {
        (Value::Object(x), Value::Object(y)) => {
            for (k, va) in x {
                if is_timing_key(k) {
                    continue;
                }
                match y.get(k) {
                    Some(vb) => walk(va, vb, &format!("{path}{k}."), ignore, out),
                    None => out.push(format!("{path}{k}: missing now")),
                }
            }
        }
        (Value::Array(x), Value::Array(y)) => {
            if x.len() != y.len() {
                out.push(format!(
                    "{}: length {} -> {}",
                    path.trim_end_matches('.'),
                    x.len(),
                    y.len()
                ));
                return;
            }
            for (i, (va, vb)) in x.iter().zip(y).enumerate() {
                walk(va, vb, &format!("{path}{i}."), ignore, out);
            }
        }
        (Value::Number(x), Value::Number(y)) => {
            let (p, q) = (
                x.as_f64().unwrap_or(f64::NAN),
                y.as_f64().unwrap_or(f64::NAN),
            );
            let same = p == q || (p.is_finite() && (p - q).abs() <= 1e-9 * p.abs().max(1.0));
            if !same {
                out.push(format!("{}: {p} -> {q}", path.trim_end_matches('.')));
            }
        }
        _ => {
            if a != b {
                let short = |v: &Value| v.to_string().chars().take(40).collect::<String>();
                out.push(format!(
                    "{}: {} -> {}",
                    path.trim_end_matches('.'),
                    short(a),
                    short(b)
                ));
            }
        }
    }
}

/// The commit checked out (`git rev-parse HEAD`, `-dirty` when `git status` shows tracked
/// changes; `unknown` without git).
pub fn commit() -> String {
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/..");
    let head = Command::new("git")
        .args(["-C", root, "rev-parse", "HEAD"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string());
    let Some(head) = head else {
        return "unknown".into();
    };
    let dirty = Command::new("git")
        .args(["-C", root, "status", "--porcelain", "--untracked-files=no"])
        .output()
        .ok()
        .is_some_and(|o| !o.stdout.is_empty());
    if dirty {
        format!("{head}-dirty")
    } else {
        head
    }
}

/// The UTC date and time now, ISO 8601 to the second.
pub fn utc_now() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    let (days, rem) = (secs / 86_400, secs % 86_400);
    // Civil date from days since 1970-01-01 (H. Hinnant's algorithm).
    let z = days as i64 + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}Z",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn differences_skip_timings_and_find_moved_figures() {
        let a = serde_json::json!({"err_mm": 1.0, "fit_ms": 3.0, "nested": {"x": [1, 2]}, "label": "a"});
        let b = serde_json::json!({"err_mm": 1.0 + 1e-12, "fit_ms": 9.0, "nested": {"x": [1, 3]}, "label": "a"});
        assert_eq!(
            accuracy_differences(&a, &b, &[]),
            vec!["nested.x.1: 2 -> 3".to_string()]
        );
        assert!(accuracy_differences(&a, &b, &["nested.x"]).is_empty());
        let c = serde_json::json!({"err_mm": 2.0});
        assert_eq!(accuracy_differences(&a, &c, &[]).len(), 3);
    }

    #[test]
    fn utc_date_is_iso() {
        let d = utc_now();
        assert_eq!(d.len(), 20, "{d}");
        assert!(d.starts_with("20") && d.ends_with('Z'));
    }
}
