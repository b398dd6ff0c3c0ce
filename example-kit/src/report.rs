//! The examples contract (`DESIGN.md`): pictures and files under the out folder
//! (`out/<example>/` unless `--out DIR`), progress on stderr, and as the last stdout line one
//! JSON object of figures, also written to `figures.json`. Beside it, `manifest.json` tells
//! `tour` what ran, which pictures show what, and which figures are the headline ones with
//! their units and goals.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};

use crate::cli::Common;
use crate::progress::{Stage, Timings};
use crate::{Error, Result};

/// A goal stated for a figure (by the example or the method's reference page).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Goal {
    /// Met when the figure is at most this.
    AtMost(f64),
    /// Met when the figure is at least this.
    AtLeast(f64),
}

impl Goal {
    /// Whether `v` meets the goal.
    pub fn met(&self, v: f64) -> bool {
        match *self {
            Goal::AtMost(g) => v <= g,
            Goal::AtLeast(g) => v >= g,
        }
    }
}

/// One headline figure: a field of the figures JSON, how to show it, its goal if any.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Headline {
    /// The JSON field.
    pub key: String,
    /// What it is, for a person.
    pub label: String,
    /// Its unit (`""` for none).
    pub unit: String,
    /// The goal, if one is stated.
    pub goal: Option<Goal>,
    /// Where the goal is stated or under which conditions it applies (e.g. "at 1600×1200").
    pub note: Option<String>,
    /// What the figure measures: the method, a baseline or an oracle.
    #[serde(default)]
    pub role: Role,
    /// The paper's own figure for this quantity, with its source (e.g. "6.1–14.1 %, Table
    /// 2.1"), where the paper reports one.
    #[serde(default)]
    pub paper: Option<String>,
}

/// What a headline figure measures.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Role {
    /// The method (accuracy, or its speed and memory).
    #[default]
    Method,
    /// A baseline: what a user of another method would have, with the same information.
    Baseline,
    /// An oracle: something that sees the truth (a floor or a control, not a competitor).
    Oracle,
}

impl Headline {
    /// A figure without a goal.
    pub fn new(key: &str, label: &str, unit: &str) -> Self {
        Headline {
            key: key.into(),
            label: label.into(),
            unit: unit.into(),
            goal: None,
            note: None,
            role: Role::Method,
            paper: None,
        }
    }

    /// Marked as a baseline.
    pub fn baseline(mut self) -> Self {
        self.role = Role::Baseline;
        self
    }

    /// Marked as an oracle.
    pub fn oracle(mut self) -> Self {
        self.role = Role::Oracle;
        self
    }

    /// With the paper's own figure and its source.
    pub fn paper(mut self, figure: &str) -> Self {
        self.paper = Some(figure.into());
        self
    }

    /// With a goal.
    pub fn goal(mut self, goal: Goal) -> Self {
        self.goal = Some(goal);
        self
    }

    /// With a note (source of the goal, conditions).
    pub fn note(mut self, note: &str) -> Self {
        self.note = Some(note.into());
        self
    }
}

/// A picture the example wrote, with its caption.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Picture {
    /// File name inside the out folder.
    pub file: String,
    /// What it shows.
    pub caption: String,
}

/// What `tour` reads beside `figures.json`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Manifest {
    /// The example's name.
    pub example: String,
    /// What ran, in a sentence or two.
    pub caption: String,
    /// `--quick` or full size.
    pub quick: bool,
    /// Headline figures.
    pub headlines: Vec<Headline>,
    /// Pictures with captions.
    pub pictures: Vec<Picture>,
    /// Seconds per stage, in order.
    pub stages: Vec<(String, f64)>,
}

/// One run of an example.
pub struct Run {
    manifest: Manifest,
    out: PathBuf,
    start: Instant,
    timings: Timings,
}

impl Run {
    /// Starts the run of example `name`: creates its out folder (`--out`, or `out/<name>`
    /// relative to the working directory).
    ///
    /// # Errors
    /// [`Error::Io`] when the folder cannot be created.
    pub fn start(name: &str, common: &Common, caption: &str) -> Result<Run> {
        let out = common
            .out
            .clone()
            .unwrap_or_else(|| Path::new("out").join(name));
        std::fs::create_dir_all(&out).map_err(|e| Error::Io(format!("{}: {e}", out.display())))?;
        eprintln!(
            "{name}: {}writing under {}",
            if common.quick { "--quick, " } else { "" },
            out.display()
        );
        Ok(Run {
            manifest: Manifest {
                example: name.into(),
                caption: caption.into(),
                quick: common.quick,
                headlines: Vec::new(),
                pictures: Vec::new(),
                stages: Vec::new(),
            },
            out,
            start: Instant::now(),
            timings: Arc::new(Mutex::new(Vec::new())),
        })
    }

    /// Whether this is the `--quick` run.
    pub fn quick(&self) -> bool {
        self.manifest.quick
    }

    /// The out folder.
    pub fn out(&self) -> &Path {
        &self.out
    }

    /// `file` inside the out folder.
    pub fn path(&self, file: &str) -> PathBuf {
        self.out.join(file)
    }

    /// Seconds since [`Run::start`].
    pub fn elapsed_s(&self) -> f64 {
        self.start.elapsed().as_secs_f64()
    }

    /// Starts a timed stage with a progress bar of `len` steps (a spinner for `None`); its
    /// time joins the run's timings when it finishes.
    pub fn stage(&self, name: &str, len: Option<u64>) -> Stage {
        Stage::with_timings(name, len, Some(Arc::clone(&self.timings)))
    }

    /// Records a picture written to `file` in the out folder.
    pub fn picture(&mut self, file: &str, caption: &str) {
        self.manifest.pictures.push(Picture {
            file: file.into(),
            caption: caption.into(),
        });
    }

    /// Saves `img` as `file` in the out folder and records it with `caption`.
    ///
    /// # Errors
    /// [`Error::Image`] when writing fails.
    pub fn save_picture(&mut self, file: &str, img: &image::RgbImage, caption: &str) -> Result<()> {
        crate::plot::save(img, self.path(file))?;
        self.picture(file, caption);
        Ok(())
    }

    /// Declares a headline figure.
    pub fn headline(&mut self, h: Headline) {
        self.manifest.headlines.push(h);
    }

    /// Ends the run: adds `"seconds"` (whole run) if `figures` lacks it and `"stage_seconds"`
    /// (per stage), writes `figures.json` and `manifest.json`, and prints the figures as one
    /// JSON line on stdout (the example's last line).
    ///
    /// # Errors
    /// [`Error::Json`] when `figures` is not an object; [`Error::Io`] when a file cannot be
    /// written.
    pub fn finish(mut self, figures: Value) -> Result<()> {
        let Value::Object(mut map) = figures else {
            return Err(Error::Json("the figures are not a JSON object".into()));
        };
        self.manifest.stages = self
            .timings
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .clone();
        let stages: Map<String, Value> = self
            .manifest
            .stages
            .iter()
            .map(|(k, v)| (k.clone(), Value::from(*v)))
            .collect();
        map.entry("stage_seconds").or_insert(Value::Object(stages));
        map.entry("seconds")
            .or_insert(Value::from(self.start.elapsed().as_secs_f64()));
        let figures = Value::Object(map);
        let write = |file: &str, v: String| {
            let p = self.out.join(file);
            std::fs::write(&p, v).map_err(|e| Error::Io(format!("{}: {e}", p.display())))
        };
        write("figures.json", pretty(&figures)?)?;
        write(
            "manifest.json",
            serde_json::to_string_pretty(&self.manifest).map_err(|e| Error::Json(e.to_string()))?,
        )?;
        print_last_line(&figures);
        Ok(())
    }
}

fn pretty(v: &Value) -> Result<String> {
    serde_json::to_string_pretty(v).map_err(|e| Error::Json(e.to_string()))
}

/// Prints the figures as the example's last stdout line.
#[allow(
    clippy::print_stdout,
    reason = "the examples contract: the last stdout line is the figures JSON"
)]
fn print_last_line(figures: &Value) {
    println!("{figures}");
}

/// Reads `manifest.json` of an example's out folder.
///
/// # Errors
/// [`Error::Io`] / [`Error::Json`] when it is missing or malformed.
pub fn read_manifest(dir: &Path) -> Result<Manifest> {
    let p = dir.join("manifest.json");
    let s = std::fs::read_to_string(&p).map_err(|e| Error::Io(format!("{}: {e}", p.display())))?;
    serde_json::from_str(&s).map_err(|e| Error::Json(format!("{}: {e}", p.display())))
}

/// `v` rounded to 3 significant digits for a person: thousands separated, no exponent
/// between 0.001 and 10⁶, `a × 10ⁿ` outside.
pub fn round3(v: f64) -> String {
    if !v.is_finite() {
        return "—".into();
    }
    if v == 0.0 {
        return "0".into();
    }
    let a = v.abs();
    if !(1e-3..1e6).contains(&a) {
        let e = a.log10().floor() as i32;
        let m = v / 10f64.powi(e);
        let sup: String = e
            .to_string()
            .chars()
            .map(|c| match c {
                '-' => '⁻',
                d => ['⁰', '¹', '²', '³', '⁴', '⁵', '⁶', '⁷', '⁸', '⁹'][d as usize - '0' as usize],
            })
            .collect();
        return format!("{m:.2} × 10{sup}");
    }
    let decimals = (2 - a.log10().floor() as i32).max(0) as usize;
    let s = format!("{:.*}", decimals, v);
    // Thousands separators in the integer part.
    let (int, frac) = s.split_once('.').map_or((s.as_str(), ""), |(i, f)| (i, f));
    let (sign, digits) = int.strip_prefix('-').map_or(("", int), |d| ("-", d));
    let mut grouped = String::new();
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i) % 3 == 0 {
            grouped.push(',');
        }
        grouped.push(c);
    }
    if frac.is_empty() {
        format!("{sign}{grouped}")
    } else {
        format!("{sign}{grouped}.{frac}")
    }
}

/// A figure with its unit for a person: `"3.2 mm"`, `"2.0×"`, `"0.5"` without a unit.
pub fn with_unit(v: &str, unit: &str) -> String {
    match unit {
        "" => v.to_owned(),
        "×" => format!("{v}×"),
        u => format!("{v} {u}"),
    }
}
