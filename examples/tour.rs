//! The main job: runs every other example of the workspace in its `--quick` form, collects the
//! JSON figures each prints as its last line, and writes `out/tour/index.html` with a table of
//! all figures and links to every picture the examples wrote.
//!
//! Run with `cargo run --release --example tour`. Examples are discovered from `examples/*.rs` and `examples/*/main.rs`
//! so a new example joins the tour by existing. Pass `--full` to run them at full size.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

struct Outcome {
    name: String,
    ok: bool,
    figures: Option<serde_json::Map<String, serde_json::Value>>,
    seconds: f64,
    pictures: Vec<PathBuf>,
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let full = std::env::args().any(|a| a == "--full");
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
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
        .filter(|n| n != "tour")
        .collect();
    names.sort();

    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let mut outcomes = Vec::new();
    for name in &names {
        eprintln!(
            "tour: running example {name}{}",
            if full { "" } else { " --quick" }
        );
        let start = Instant::now();
        let mut cmd = Command::new(&cargo);
        cmd.current_dir(root)
            .args(["run", "--release", "--quiet", "--example", name]);
        if !full {
            cmd.args(["--", "--quick"]);
        }
        let output = cmd.output()?;
        let seconds = start.elapsed().as_secs_f64();
        eprint!("{}", String::from_utf8_lossy(&output.stderr));
        let stdout = String::from_utf8_lossy(&output.stdout);
        let figures = stdout
            .lines()
            .rev()
            .find(|l| !l.trim().is_empty())
            .and_then(|l| serde_json::from_str::<serde_json::Value>(l).ok())
            .and_then(|v| v.as_object().cloned());
        let pictures = list_pictures(&root.join("out").join(name));
        let ok = output.status.success() && figures.is_some();
        eprintln!(
            "tour: {name} {} in {seconds:.1} s",
            if ok { "ok" } else { "FAILED" }
        );
        outcomes.push(Outcome {
            name: name.clone(),
            ok,
            figures,
            seconds,
            pictures,
        });
    }

    let out_dir = root.join("out").join("tour");
    std::fs::create_dir_all(&out_dir)?;
    std::fs::write(
        out_dir.join("index.html"),
        render_html(&outcomes, &root.join("out")),
    )?;

    let summary: serde_json::Map<String, serde_json::Value> = outcomes
        .iter()
        .map(|o| {
            (
                o.name.clone(),
                o.figures
                    .clone()
                    .map(serde_json::Value::Object)
                    .unwrap_or(serde_json::Value::Null),
            )
        })
        .collect();
    let failed: Vec<&str> = outcomes
        .iter()
        .filter(|o| !o.ok)
        .map(|o| o.name.as_str())
        .collect();
    eprintln!("tour: wrote {}", out_dir.join("index.html").display());
    println!(
        "{}",
        serde_json::json!({
            "examples": outcomes.len(),
            "failed": failed,
            "figures": summary,
            "seconds": outcomes.iter().map(|o| o.seconds).sum::<f64>(),
        })
    );
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
}

fn render_html(outcomes: &[Outcome], out_root: &Path) -> String {
    let mut html = String::from(
        "<!doctype html><html><head><meta charset=\"utf-8\"><title>dynamic-shapes tour</title>\
         <style>body{font-family:sans-serif;margin:2em}table{border-collapse:collapse}\
         td,th{border:1px solid #ccc;padding:4px 8px;text-align:left}img{max-width:480px;margin:4px}\
         .fail{color:#b00}</style></head><body><h1>dynamic-shapes tour</h1>\
         <table><tr><th>example</th><th>status</th><th>figure</th><th>value</th></tr>",
    );
    for o in outcomes {
        let status = if o.ok {
            "ok"
        } else {
            "<span class=\"fail\">failed</span>"
        };
        match &o.figures {
            Some(map) if !map.is_empty() => {
                for (i, (k, v)) in map.iter().enumerate() {
                    let head = if i == 0 {
                        format!(
                            "<td rowspan=\"{}\">{}</td><td rowspan=\"{}\">{status}</td>",
                            map.len(),
                            escape(&o.name),
                            map.len()
                        )
                    } else {
                        String::new()
                    };
                    html += &format!(
                        "<tr>{head}<td>{}</td><td>{}</td></tr>",
                        escape(k),
                        escape(&v.to_string())
                    );
                }
            }
            _ => {
                html += &format!(
                "<tr><td>{}</td><td>{status}</td><td colspan=\"2\">no figures ({:.1} s)</td></tr>",
                escape(&o.name),
                o.seconds
            )
            }
        }
    }
    html += "</table>";
    for o in outcomes.iter().filter(|o| !o.pictures.is_empty()) {
        html += &format!("<h2>{}</h2>", escape(&o.name));
        for p in &o.pictures {
            // Pictures live under out/<example>/; the page is out/tour/index.html.
            let rel = Path::new("..").join(p.strip_prefix(out_root).unwrap_or(p));
            let rel = rel.to_string_lossy();
            html += &format!(
                "<a href=\"{0}\"><img src=\"{0}\" alt=\"{0}\"></a>",
                escape(&rel)
            );
        }
    }
    html += "</body></html>\n";
    html
}
