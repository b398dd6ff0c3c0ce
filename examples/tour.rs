//! The main job: runs every other example of the workspace in its `--quick` form and writes
//! `out/tour/index.html` for a person: per example a caption saying what ran, its pictures
//! with captions, and its headline figures rounded, with units, beside their goals (met or
//! not). Each example says what these are in the `manifest.json` it writes beside its
//! `figures.json` (`example_kit::report`); the full JSON stays in `figures.json`.
//!
//! Run with `cargo run --release --example tour [-- --full] [-- --out DIR] [-- --record]
//! [-- --only a,b] [-- --full --peers FILE]`; `--record` commits each example's figures under `results/` (see
//! `example_kit::record`), from which `--example results` writes `docs/results.md`. Examples are
//! discovered from `examples/*.rs` and `examples/*/main.rs` so a new example joins the tour by
//! existing. `--full` runs them at full size. The examples' progress goes to stderr as they
//! run; the last stdout line is one JSON object with every example's figures.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

use clap::Parser;
use example_kit::record::{Machine, Record};
use example_kit::report::{read_manifest, round3, with_unit, Manifest};
use example_kit::Run;
use serde_json::{Map, Value};

/// Runs every example in its quick form and writes out/tour/index.html.
#[derive(Parser)]
struct Args {
    /// Run the examples at full size instead of `--quick`.
    #[arg(long)]
    full: bool,
    /// Folder of the page [default: out/tour]; each example writes into a sibling folder named
    /// after it.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Commit each example's figures, with the commit, machine and date, under `results/`
    /// (full runs) or `results/quick/` (quick runs): the records the results page is made from.
    #[arg(long)]
    record: bool,
    /// Run only these examples (comma-separated names) [default: all].
    #[arg(long, value_delimiter = ',')]
    only: Vec<String>,
    /// With `--full`: the JSON lines the peer scripts printed in the same run
    /// (`../shared/bench/peers/run_all.sh` writes them to `results/peers.jsonl`), passed to the
    /// examples that compare against them ([`PEER_EXAMPLES`]), whose records then carry the
    /// time and accuracy ratios to OpenCV and Open3D. Needs the peers' virtualenv: never in CI.
    #[arg(long, value_name = "FILE", requires = "full")]
    peers: Option<PathBuf>,
}

/// The examples that take `--peers FILE`.
const PEER_EXAMPLES: [&str; 2] = ["photometric_normals", "surface_merge"];

struct Outcome {
    name: String,
    ok: bool,
    figures: Option<Map<String, Value>>,
    manifest: Option<Manifest>,
    seconds: f64,
    /// Pictures in the example's folder that its manifest does not caption.
    other_pictures: Vec<PathBuf>,
    dir: PathBuf,
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = Args::parse();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let run = Run::start(
        "tour",
        &example_kit::Common {
            quick: !args.full,
            out: Some(
                args.out
                    .clone()
                    .unwrap_or_else(|| root.join("out").join("tour")),
            ),
        },
        "Every example of the workspace.",
    )?;
    let mut names: Vec<String> = std::fs::read_dir(root.join("examples"))?
        .filter_map(|e| e.ok())
        .filter_map(|e| {
            let p = e.path();
            // `name.rs`, or a directory `name/` with a `main.rs` (multi-file examples).
            let is_example =
                p.extension().is_some_and(|x| x == "rs") || p.join("main.rs").is_file();
            is_example
                .then(|| p.file_stem()?.to_str().map(str::to_owned))
                .flatten()
        })
        .filter(|n| n != "tour" && n != "results")
        .filter(|n| args.only.is_empty() || args.only.contains(n))
        .collect();
    names.sort();

    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let mut outcomes = Vec::new();
    for (i, name) in names.iter().enumerate() {
        eprintln!(
            "tour: [{}/{}] running example {name}{}",
            i + 1,
            names.len(),
            if args.full { "" } else { " --quick" }
        );
        // Beside the tour's own folder: `out/<name>` by default.
        let dir = run.out().parent().unwrap_or(run.out()).join(name);
        let load_start = example_kit::record::load_1min();
        let start = Instant::now();
        let mut cmd = Command::new(&cargo);
        cmd.current_dir(root)
            .args(["run", "--release", "--quiet", "--example", name, "--"])
            .arg("--out")
            .arg(&dir)
            .stderr(Stdio::inherit());
        if !args.full {
            cmd.arg("--quick");
        }
        if let Some(peers) = args
            .peers
            .as_ref()
            .filter(|_| PEER_EXAMPLES.contains(&name.as_str()))
        {
            cmd.arg("--peers").arg(std::path::absolute(peers)?);
        }
        let output = cmd.output()?;
        let seconds = start.elapsed().as_secs_f64();
        let stdout = String::from_utf8_lossy(&output.stdout);
        let figures = stdout
            .lines()
            .rev()
            .find(|l| !l.trim().is_empty())
            .and_then(|l| serde_json::from_str::<Value>(l).ok())
            .and_then(|v| v.as_object().cloned());
        let manifest = read_manifest(&dir).ok();
        let captioned: Vec<PathBuf> = manifest
            .iter()
            .flat_map(|m| m.pictures.iter().map(|p| dir.join(&p.file)))
            .collect();
        let other_pictures = list_pictures(&dir)
            .into_iter()
            .filter(|p| !captioned.contains(p))
            .collect();
        let ok = output.status.success() && figures.is_some();
        if let (true, true, Some(m), Some(f)) = (args.record, ok, &manifest, &figures) {
            let machine = Machine {
                load_1min_start: load_start,
                ..Machine::now()
            };
            let path = Record::new(m, f.clone(), machine, seconds).write(&root.join("results"))?;
            eprintln!("tour: recorded {}", path.display());
        }
        eprintln!(
            "tour: {name} {} in {seconds:.1} s",
            if ok { "ok" } else { "FAILED" }
        );
        outcomes.push(Outcome {
            name: name.clone(),
            ok,
            figures,
            manifest,
            seconds,
            other_pictures,
            dir,
        });
    }

    let page = run.path("index.html");
    std::fs::write(&page, render_html(&outcomes, run.out(), !args.full))?;
    eprintln!("tour: wrote {}", page.display());

    let summary: Map<String, Value> = outcomes
        .iter()
        .map(|o| {
            (
                o.name.clone(),
                o.figures.clone().map(Value::Object).unwrap_or(Value::Null),
            )
        })
        .collect();
    let failed: Vec<&str> = outcomes
        .iter()
        .filter(|o| !o.ok)
        .map(|o| o.name.as_str())
        .collect();
    run.finish(serde_json::json!({
        "examples": outcomes.len(),
        "failed": failed,
        "figures": summary,
        "seconds": outcomes.iter().map(|o| o.seconds).sum::<f64>(),
    }))?;
    if failed.is_empty() {
        Ok(())
    } else {
        Err(format!("examples failed: {}", failed.join(", ")).into())
    }
}

fn list_pictures(dir: &Path) -> Vec<PathBuf> {
    let mut found = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&d) else {
            continue;
        };
        for e in entries.flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if matches!(
                p.extension().and_then(|x| x.to_str()),
                Some("png" | "svg" | "jpg")
            ) {
                found.push(p);
            }
        }
    }
    found.sort();
    found
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// A duration for a person: ms below a second, s above.
fn duration(s: f64) -> String {
    if s < 1.0 {
        format!("{} ms", round3(s * 1e3))
    } else {
        format!("{} s", round3(s))
    }
}

/// The repository's root for a page written under its `out/` folder (the page's folder with
/// its `out/...` tail removed; the folder itself when it is not under an `out/`).
fn root_dir(page_dir: &Path) -> PathBuf {
    page_dir
        .ancestors()
        .find(|p| p.file_name().is_some_and(|n| n == "out"))
        .and_then(Path::parent)
        .map_or_else(|| page_dir.to_path_buf(), Path::to_path_buf)
}

/// `path` relative to the page's folder `from` (both under the repository's `out/`).
fn relative(path: &Path, from: &Path) -> String {
    let mut up = PathBuf::new();
    let mut base = from.to_path_buf();
    loop {
        if let Ok(rest) = path.strip_prefix(&base) {
            return up.join(rest).to_string_lossy().into_owned();
        }
        if !base.pop() {
            return path.to_string_lossy().into_owned();
        }
        up.push("..");
    }
}

const STYLE: &str = "body{font-family:system-ui,sans-serif;margin:2em auto;max-width:1150px;\
    color:#222;line-height:1.4}h1{margin-bottom:0}h2{margin-top:2em;border-bottom:1px solid #ccc}\
    table{border-collapse:collapse;margin:0.5em 0}td,th{border:1px solid #ddd;padding:4px 10px;\
    text-align:left;vertical-align:top}th{background:#f4f4f4}td.num{text-align:right;\
    white-space:nowrap;font-variant-numeric:tabular-nums}.met{color:#0a7d2c;font-weight:600}\
    .missed{color:#b3261e;font-weight:600}.fail{color:#b3261e;font-weight:600}\
    .note{color:#666;font-size:0.9em}figure{margin:1em 0}figure img{max-width:100%;\
    border:1px solid #eee}figcaption{color:#444;font-size:0.95em;margin-top:0.3em}\
    p.caption{font-size:1.05em}table{display:block;max-width:100%;overflow-x:auto}\
    @media(max-width:700px){body{margin:0.5em}td,th{padding:3px 5px}}";

fn render_html(outcomes: &[Outcome], page_dir: &Path, quick: bool) -> String {
    let mut h = String::new();
    let _ = write!(
        h,
        "<!doctype html><html lang=\"en\"><head><meta charset=\"utf-8\">\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\
         <title>dynamic-shapes tour</title><style>{STYLE}</style></head><body>\
         <h1>dynamic-shapes tour</h1><p>dynamic-shapes captures, reconstructs and \
         re-animates moving human bodies and faces: five published methods (Sand 2003; \
         Vlasic 2010, Chapters 2–5), each validated against the ground truth of a synthetic \
         capture studio beside the baselines a user could have chosen instead.</p>\
         <p class=\"note\">Every example of the workspace{}. Figures are rounded to 3 \
         significant digits; each example's full figures are in its <code>figures.json</code>. \
         Goals are those the method's reference page (<code>docs/&lt;crate&gt;.md</code>) \
         states; most are stated for the full-size run, so a quick run can miss a speed or \
         accuracy goal that the full run meets. Each example links to its method's section of \
         the results page (<code>docs/results.md</code>), made from the committed full-run \
         records.</p>",
        if quick {
            ", each run in its quick (CI-sized) form"
        } else {
            ", each run at full size"
        }
    );
    // Overview.
    h += "<table><tr><th>example</th><th>status</th><th>time</th><th>goals met</th></tr>";
    for o in outcomes {
        let (met, total) = goal_count(o);
        let _ = write!(
            h,
            "<tr><td><a href=\"#{0}\">{0}</a></td><td>{1}</td><td class=\"num\">{2:.0} s</td>\
             <td class=\"num\">{3}</td></tr>",
            escape(&o.name),
            if o.ok {
                "ran".to_owned()
            } else {
                "<span class=\"fail\">failed</span>".to_owned()
            },
            o.seconds,
            if total == 0 {
                "no goal stated".to_owned()
            } else {
                format!("{met} of {total}")
            }
        );
    }
    h += "</table>";

    for o in outcomes {
        let _ = write!(h, "<h2 id=\"{0}\">{0}</h2>", escape(&o.name));
        if let Some(krate) = example_kit::record::method_of(&o.name) {
            let page = relative(
                &root_dir(page_dir).join("docs").join("results.md"),
                page_dir,
            );
            let _ = write!(
                h,
                "<p class=\"note\">Method: <code>{krate}</code> — its figures from the full-run \
                 records: <a href=\"{page}#{krate}\">results page, {krate}</a>.</p>",
            );
        }
        if !o.ok {
            let _ = write!(
                h,
                "<p class=\"fail\">The example failed (see the tour's log on stderr).</p>"
            );
        }
        let Some(m) = &o.manifest else {
            h += "<p class=\"note\">This example wrote no manifest.json.</p>";
            continue;
        };
        let _ = write!(
            h,
            "<p class=\"caption\">{} <span class=\"note\">({}, {:.0} s)</span></p>",
            escape(&m.caption),
            if m.quick { "quick run" } else { "full run" },
            o.seconds
        );
        let any_goal = m.headlines.iter().any(|hl| hl.goal.is_some());
        if !m.headlines.is_empty() {
            h += if any_goal {
                "<table><tr><th>figure</th><th>value</th><th>goal</th><th></th></tr>"
            } else {
                "<table><tr><th>figure</th><th>value</th></tr>"
            };
            for hl in &m.headlines {
                let v = o
                    .figures
                    .as_ref()
                    .and_then(|f| f.get(&hl.key))
                    .and_then(Value::as_f64);
                let value = v.map_or("—".to_owned(), |v| with_unit(&round3(v), &hl.unit));
                let (goal, verdict) = match (hl.goal, v) {
                    (Some(g), v) => {
                        let (op, x) = match g {
                            example_kit::Goal::AtMost(x) => ("≤", x),
                            example_kit::Goal::AtLeast(x) => ("≥", x),
                        };
                        let verdict = match v {
                            Some(v) if g.met(v) => "<span class=\"met\">met</span>",
                            Some(_) => "<span class=\"missed\">not met</span>",
                            None => "",
                        };
                        (
                            format!("{op} {}", with_unit(&format!("{x}"), &hl.unit)),
                            verdict,
                        )
                    }
                    (None, _) => ("—".to_owned(), ""),
                };
                let note = hl
                    .note
                    .as_deref()
                    .map(|n| format!("<br><span class=\"note\">{}</span>", escape(n)))
                    .unwrap_or_default();
                let _ = write!(
                    h,
                    "<tr><td>{}<br><span class=\"note\"><code>{}</code></span></td>\
                     <td class=\"num\">{}</td>",
                    escape(&hl.label),
                    match hl.role {
                        example_kit::Role::Method => escape(&hl.key),
                        example_kit::Role::Baseline => format!("{} · baseline", escape(&hl.key)),
                        example_kit::Role::Oracle => format!("{} · oracle", escape(&hl.key)),
                    },
                    escape(&value),
                );
                if any_goal {
                    let _ = write!(
                        h,
                        "<td class=\"num\">{}</td><td>{}{}</td>",
                        escape(&goal),
                        verdict,
                        note
                    );
                }
                h += "</tr>";
            }
            h += "</table>";
        }
        let stages: Vec<String> = m
            .stages
            .iter()
            .map(|(s, t)| format!("{} {}", escape(s), duration(*t)))
            .collect();
        if !stages.is_empty() {
            let _ = write!(h, "<p class=\"note\">Stages: {}.</p>", stages.join(" · "));
        }
        for p in &m.pictures {
            let src = escape(&relative(&o.dir.join(&p.file), page_dir));
            let _ = write!(
                h,
                "<figure><a href=\"{src}\"><img src=\"{src}\" alt=\"{}\"></a>\
                 <figcaption>{}</figcaption></figure>",
                escape(&p.caption),
                escape(&p.caption)
            );
        }
        let figures = escape(&relative(&o.dir.join("figures.json"), page_dir));
        let mut links = vec![format!("<a href=\"{figures}\">figures.json</a>")];
        for p in &o.other_pictures {
            let src = escape(&relative(p, page_dir));
            let name = p
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            links.push(format!("<a href=\"{src}\">{}</a>", escape(&name)));
        }
        let _ = write!(
            h,
            "<p class=\"note\">All figures and files: {}.</p>",
            links.join(", ")
        );
    }
    h += "</body></html>\n";
    h
}

/// Goals met and goals stated of an example's headline figures.
fn goal_count(o: &Outcome) -> (usize, usize) {
    let Some(m) = &o.manifest else { return (0, 0) };
    let mut met = 0;
    let mut total = 0;
    for hl in &m.headlines {
        if let Some(g) = hl.goal {
            total += 1;
            let v = o
                .figures
                .as_ref()
                .and_then(|f| f.get(&hl.key))
                .and_then(Value::as_f64);
            if v.is_some_and(|v| g.met(v)) {
                met += 1;
            }
        }
    }
    (met, total)
}
