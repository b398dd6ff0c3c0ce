//! Development support shared by the tests, examples and benches of `dynamic-shapes`. Not
//! published: the libraries never read it, they take every path from their caller.
//!
//! [`data_path`] locates the small real data sets that ship with the repository in `data/`
//! (meshes, motion capture, sensor and face recordings, each with its `SOURCE.md` and
//! licence).
//!
//! The examples share their contract through it (`DESIGN.md`, "Examples contract"):
//! [`cli`] (`--quick`, `--out DIR` with `clap`), [`report`] (out folder, timings,
//! `figures.json`, `manifest.json` for `tour`, the last-line JSON), [`progress`]
//! (`indicatif` bars on stderr), [`record`] (the committed records under `results/`) and
//! [`plot`] (`plotters` charts with titles, axis labels with
//! units, legends and colour bars, in the bundled DejaVu Sans font).

use std::path::PathBuf;

pub mod cli;
pub mod plot;
pub mod progress;
pub mod record;
pub mod report;

pub use cli::Common;
pub use progress::Stage;
pub use report::{Goal, Headline, Role, Run};

/// An error of the examples' support code.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file or folder could not be written or read.
    #[error("io: {0}")]
    Io(String),
    /// Malformed or non-object JSON.
    #[error("json: {0}")]
    Json(String),
    /// A picture could not be written.
    #[error("image: {0}")]
    Image(String),
    /// Plotting failed.
    #[error("plot: {0}")]
    Plot(String),
}

/// Result of this crate.
pub type Result<T> = std::result::Result<T, Error>;

/// The repository's `data/` folder.
pub fn data_dir() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../data"))
}

/// The path of `relative` (e.g. `"makehuman/base.obj"`) inside [`data_dir`].
///
/// # Errors
/// `NotFound` naming the path tried when the file does not exist (a checkout without its
/// `data/` folder).
pub fn data_path(relative: &str) -> std::io::Result<PathBuf> {
    let path = data_dir().join(relative);
    if path.exists() {
        Ok(path)
    } else {
        Err(std::io::Error::new(
            std::io::ErrorKind::NotFound,
            format!(
                "data file {} not found: the repository's data/ folder is incomplete",
                path.display()
            ),
        ))
    }
}

/// Peak resident memory of this process so far, MB (Linux `VmHWM`; `None` elsewhere or when
/// `/proc/self/status` cannot be read).
pub fn peak_rss_mb() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn peak_memory_is_read_on_linux() {
        // Touch every page of 64 MB so that it is resident.
        let mut big = vec![0u8; 64 << 20];
        for i in (0..big.len()).step_by(4096) {
            big[i] = 1;
        }
        std::hint::black_box(&big);
        let mb = peak_rss_mb().unwrap();
        assert!(mb >= 64.0 && mb.is_finite(), "{mb} MB");
        drop(big);
    }

    #[test]
    fn finds_the_shipped_data_and_names_missing_files() {
        for rel in [
            "makehuman/base.obj",
            "mocap-cmu/131_01.bvh",
            "imu-broad/07_undisturbed_fast_rotation_B_first60s.hdf5",
            "imu-xio/sensor_data.csv",
            "ict-face/neutral_face.obj",
        ] {
            assert!(data_path(rel).is_ok(), "{rel}");
        }
        let err = data_path("no/such/file.txt").unwrap_err();
        assert!(err.to_string().contains("no/such/file.txt"));
    }

    #[test]
    fn a_chart_with_text_and_a_colour_bar_draws() {
        let chart = plot::Chart::new("t", "x (mm)", "y (s)")
            .with(plot::Series::new(
                "a",
                [0, 0, 255],
                plot::Style::LineMarkers,
                vec![(1.0, 2.0), (3.0, 4.0)],
            ))
            .draw()
            .unwrap();
        assert_eq!(chart.dimensions(), (640, 420));
        // Text was drawn: some dark pixels outside the data.
        assert!(chart.pixels().any(|p| p.0 == [0, 0, 0]));
        let ramp = |t: f64| [(255.0 * t) as u8, 0, 0];
        let bar = plot::ColourBar {
            label: "e (mm)",
            min: 0.0,
            max: 20.0,
            ramp: &ramp,
            note: Some("grey: none"),
        };
        let img = plot::with_colour_bar(&chart, &bar).unwrap();
        assert_eq!(img.width(), 640 + 150);
        assert_eq!(plot::tick(2.5), "2.5");
        assert_eq!(plot::tick(-0.0), "0");
    }

    #[test]
    fn a_run_writes_figures_and_manifest() {
        let dir = std::env::temp_dir().join(format!("example-kit-test-{}", std::process::id()));
        let common = cli::Common {
            quick: true,
            out: Some(dir.clone()),
        };
        let mut run = Run::start("demo", &common, "what ran").unwrap();
        run.stage("stage one", Some(3)).finish("done");
        run.headline(Headline::new("x_mm", "x", "mm").goal(Goal::AtMost(2.0)));
        run.picture("a.png", "a picture");
        run.finish(serde_json::json!({ "x_mm": 1.5 })).unwrap();
        let figures: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("figures.json")).unwrap())
                .unwrap();
        assert_eq!(figures["x_mm"], 1.5);
        assert!(figures["seconds"].is_number());
        assert!(figures["stage_seconds"]["stage one"].is_number());
        let m = report::read_manifest(&dir).unwrap();
        assert_eq!(m.caption, "what ran");
        assert!(m.quick);
        assert!(m.headlines[0].goal.unwrap().met(1.5));
        assert_eq!(m.pictures[0].file, "a.png");
        assert!(Run::start("demo", &common, "")
            .unwrap()
            .finish(serde_json::json!(1))
            .is_err());
        std::fs::remove_dir_all(&dir).unwrap();
        assert_eq!(plot::tick(100.0), "100");
    }
}
