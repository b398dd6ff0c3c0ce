//! Progress on stderr: an `indicatif` bar or spinner per long stage when stderr is a
//! terminal (hidden otherwise), and always one plain line when a stage ends, so logs stay
//! useful and the last stdout line stays the figures JSON.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// Stage durations in seconds, in the order the stages ended (shared by a run and its stages).
pub(crate) type Timings = Arc<Mutex<Vec<(String, f64)>>>;

/// One long stage: a progress bar (`len` known) or a spinner, timed.
pub struct Stage {
    name: String,
    bar: ProgressBar,
    start: Instant,
    timings: Option<Timings>,
}

impl Stage {
    /// Starts a stage of `len` steps (a bar), or of unknown length (a spinner) for `None`.
    pub fn new(name: &str, len: Option<u64>) -> Self {
        Self::with_timings(name, len, None)
    }

    pub(crate) fn with_timings(name: &str, len: Option<u64>, timings: Option<Timings>) -> Self {
        let target = ProgressDrawTarget::stderr();
        let bar = match len {
            Some(n) => {
                let bar = ProgressBar::with_draw_target(Some(n), target);
                if let Ok(style) = ProgressStyle::with_template(
                    "{prefix:>14} [{bar:30}] {pos}/{len} {msg} ({elapsed}, eta {eta})",
                ) {
                    bar.set_style(style.progress_chars("=> "));
                }
                bar
            }
            None => {
                let bar = ProgressBar::with_draw_target(None, target);
                if let Ok(style) =
                    ProgressStyle::with_template("{prefix:>14} {spinner} {msg} ({elapsed})")
                {
                    bar.set_style(style);
                }
                bar.enable_steady_tick(Duration::from_millis(120));
                bar
            }
        };
        bar.set_prefix(name.to_owned());
        Stage {
            name: name.to_owned(),
            bar,
            start: Instant::now(),
            timings,
        }
    }

    /// Advances the bar by `n` steps.
    pub fn inc(&self, n: u64) {
        self.bar.inc(n);
    }

    /// Sets the bar's position.
    pub fn set_position(&self, pos: u64) {
        self.bar.set_position(pos);
    }

    /// A short message beside the bar (e.g. a running count).
    pub fn set_message(&self, msg: impl Into<String>) {
        self.bar.set_message(msg.into());
    }

    /// A line printed above the bar (plain on stderr when there is no terminal).
    pub fn println(&self, line: impl AsRef<str>) {
        if self.bar.is_hidden() {
            eprintln!("{}: {}", self.name, line.as_ref());
        } else {
            self.bar
                .println(format!("{}: {}", self.name, line.as_ref()));
        }
    }

    /// Seconds since the stage started.
    pub fn elapsed_s(&self) -> f64 {
        self.start.elapsed().as_secs_f64()
    }

    /// Ends the stage: clears the bar, prints `name: done in … s (summary)` on stderr, records
    /// the time in the run's timings and returns it in seconds.
    pub fn finish(self, summary: impl AsRef<str>) -> f64 {
        let s = self.elapsed_s();
        self.bar.finish_and_clear();
        let summary = summary.as_ref();
        if summary.is_empty() {
            eprintln!("{}: done in {s:.2} s", self.name);
        } else {
            eprintln!("{}: {summary} ({s:.2} s)", self.name);
        }
        if let Some(t) = &self.timings {
            t.lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner)
                .push((self.name.clone(), s));
        }
        s
    }
}
