//! A small reader and writer for the subset of OpenCV `FileStorage` YAML used by calibration
//! files: a `%YAML:1.0` header, top-level `key: scalar` entries and `!!opencv-matrix` maps with
//! `rows`, `cols`, `dt` and a `data: [ … ]` list that may span lines. Other top-level entries
//! (nested maps, sequences) are skipped. Every malformed input is an [`Error::Parse`] with its
//! line number; nothing panics (fuzzed by `fuzz/fuzz_targets/opencv_yaml.rs`).

use crate::error::{Error, Result};

/// Format name used in parse errors.
pub(crate) const FORMAT: &str = "OpenCV YAML";
/// Largest matrix accepted (entries); calibration matrices are tiny, this bounds allocation.
const MAX_ENTRIES: usize = 1 << 20;

/// A dense matrix read from a file, row-major.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct YamlMatrix {
    pub rows: usize,
    pub cols: usize,
    pub data: Vec<f64>,
    /// Line of the entry's key (for error messages).
    pub line: usize,
}

/// A top-level value.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum YamlValue {
    Scalar(String),
    Matrix(YamlMatrix),
}

/// Top-level `(key, value, line)` entries in file order.
pub(crate) type YamlEntries = Vec<(String, YamlValue, usize)>;

fn err(line: usize, message: impl Into<String>) -> Error {
    Error::Parse {
        format: FORMAT,
        line,
        message: message.into(),
    }
}

fn strip_comment(line: &str) -> &str {
    // '#' starts a comment unless inside quotes; calibration files do not quote '#'.
    match line.find('#') {
        Some(i) if !line[..i].contains('"') && !line[..i].contains('\'') => &line[..i],
        _ => line,
    }
}

fn indent(line: &str) -> usize {
    line.len() - line.trim_start_matches([' ', '\t']).len()
}

fn parse_usize(s: &str, line: usize, what: &str) -> Result<usize> {
    s.trim().parse::<usize>().map_err(|_| {
        err(
            line,
            format!("{what} must be a non-negative integer, got {:?}", s.trim()),
        )
    })
}

/// Parses a `FileStorage` YAML document into its top-level entries.
pub(crate) fn parse(text: &str) -> Result<YamlEntries> {
    let lines: Vec<&str> = text.lines().collect();
    let mut i = 0;
    // Header: first non-blank line must be the %YAML directive.
    while i < lines.len() && lines[i].trim().is_empty() {
        i += 1;
    }
    match lines.get(i) {
        Some(l) if l.trim_start().starts_with("%YAML") => i += 1,
        _ => {
            return Err(err(
                i + 1,
                "missing %YAML:1.0 header (not an OpenCV FileStorage file)",
            ))
        }
    }
    let mut entries = YamlEntries::new();
    while i < lines.len() {
        let line_no = i + 1;
        let raw = strip_comment(lines[i]);
        i += 1;
        let t = raw.trim();
        if t.is_empty() || t == "---" || t == "..." {
            continue;
        }
        if indent(raw) > 0 {
            return Err(err(line_no, "unexpected indented line outside an entry"));
        }
        let (key, rest) = t
            .split_once(':')
            .ok_or_else(|| err(line_no, format!("expected `key: value`, got {t:?}")))?;
        let key = key.trim().trim_matches('"').to_string();
        if key.is_empty() {
            return Err(err(line_no, "empty key"));
        }
        let rest = rest.trim();
        // Collect the indented block that belongs to this entry.
        let start = i;
        while i < lines.len() {
            let l = strip_comment(lines[i]);
            if !l.trim().is_empty() && indent(l) == 0 {
                break;
            }
            i += 1;
        }
        let block: Vec<(usize, &str)> = (start..i)
            .map(|k| (k + 1, strip_comment(lines[k])))
            .collect();
        if rest.contains("opencv-matrix") {
            entries.push((
                key,
                YamlValue::Matrix(parse_matrix(&block, line_no)?),
                line_no,
            ));
        } else if rest.is_empty() || rest.starts_with('[') || rest.starts_with('{') {
            // Nested map or sequence: not used by calibration files; skipped.
            continue;
        } else {
            entries.push((
                key,
                YamlValue::Scalar(rest.trim_matches('"').to_string()),
                line_no,
            ));
        }
    }
    Ok(entries)
}

fn parse_matrix(block: &[(usize, &str)], key_line: usize) -> Result<YamlMatrix> {
    let mut rows: Option<usize> = None;
    let mut cols: Option<usize> = None;
    let mut dt: Option<String> = None;
    let mut data: Option<(usize, String)> = None;
    let mut k = 0;
    while k < block.len() {
        let (ln, l) = block[k];
        k += 1;
        let t = l.trim();
        if t.is_empty() {
            continue;
        }
        let (field, value) = t
            .split_once(':')
            .ok_or_else(|| err(ln, format!("expected `field: value` in matrix, got {t:?}")))?;
        match field.trim() {
            "rows" => rows = Some(parse_usize(value, ln, "rows")?),
            "cols" => cols = Some(parse_usize(value, ln, "cols")?),
            "dt" => dt = Some(value.trim().trim_matches('"').to_string()),
            "data" => {
                let mut text = value.to_string();
                while !text.contains(']') {
                    let (_, next) = *block
                        .get(k)
                        .ok_or_else(|| err(ln, "unterminated data list (missing `]`)"))?;
                    k += 1;
                    text.push(' ');
                    text.push_str(next);
                }
                data = Some((ln, text));
            }
            other => return Err(err(ln, format!("unknown matrix field {other:?}"))),
        }
    }
    let rows = rows.ok_or_else(|| err(key_line, "matrix without `rows`"))?;
    let cols = cols.ok_or_else(|| err(key_line, "matrix without `cols`"))?;
    let dt = dt.ok_or_else(|| err(key_line, "matrix without `dt`"))?;
    if !matches!(dt.as_str(), "d" | "f" | "i" | "u" | "s" | "w" | "c") {
        return Err(err(
            key_line,
            format!("unsupported matrix element type dt: {dt:?}"),
        ));
    }
    let (data_line, text) = data.ok_or_else(|| err(key_line, "matrix without `data`"))?;
    let n = rows
        .checked_mul(cols)
        .filter(|n| *n <= MAX_ENTRIES)
        .ok_or_else(|| err(key_line, "matrix too large"))?;
    let open = text
        .find('[')
        .ok_or_else(|| err(data_line, "data must be a `[ ... ]` list"))?;
    let close = text
        .rfind(']')
        .filter(|c| *c > open)
        .ok_or_else(|| err(data_line, "data must be a `[ ... ]` list"))?;
    if !text[close + 1..].trim().is_empty() || !text[..open].trim().is_empty() {
        return Err(err(data_line, "unexpected text around the data list"));
    }
    let values = text[open + 1..close]
        .split(|c: char| c == ',' || c.is_whitespace())
        .filter(|s| !s.is_empty())
        .map(|s| {
            let v: f64 = s
                .parse()
                .map_err(|_| err(data_line, format!("not a number: {s:?}")))?;
            if v.is_finite() {
                Ok(v)
            } else {
                Err(err(data_line, format!("non-finite value {s:?}")))
            }
        })
        .collect::<Result<Vec<f64>>>()?;
    if values.len() != n {
        return Err(err(
            data_line,
            format!(
                "matrix is {rows}x{cols} but data has {} values",
                values.len()
            ),
        ));
    }
    Ok(YamlMatrix {
        rows,
        cols,
        data: values,
        line: key_line,
    })
}

/// Writes a `FileStorage` YAML document (header, then entries in order).
pub(crate) fn write(entries: &[(&str, YamlValue)]) -> String {
    let mut s = String::from("%YAML:1.0\n---\n");
    for (key, value) in entries {
        match value {
            YamlValue::Scalar(v) => s.push_str(&format!("{key}: {v}\n")),
            YamlValue::Matrix(m) => {
                let data: Vec<String> = m.data.iter().map(|v| format!("{v:?}")).collect();
                s.push_str(&format!(
                    "{key}: !!opencv-matrix\n   rows: {}\n   cols: {}\n   dt: d\n   data: [ {} ]\n",
                    m.rows,
                    m.cols,
                    data.join(", ")
                ));
            }
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_opencv_output_with_multiline_data() {
        let text = "%YAML:1.0\n---\n# comment\nimage_width: 640\nimage_height: 480\ncalibration_time: \"Mon\"\n\
                    nested:\n   a: 1\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 5.e+02, 0., 3.2e+02, 0.,\n       5.e+02, 2.4e+02, 0., 0., 1. ]\n";
        let e = parse(text).unwrap();
        assert_eq!(e.len(), 4);
        match &e[3].1 {
            YamlValue::Matrix(m) => {
                assert_eq!((m.rows, m.cols, m.data[2], m.data[8]), (3, 3, 320.0, 1.0))
            }
            other => panic!("expected matrix, got {other:?}"),
        }
        assert_eq!(e[0].1, YamlValue::Scalar("640".into()));
    }

    #[test]
    fn malformed_inputs_are_parse_errors_with_lines() {
        let m = |body: &str| format!("%YAML:1.0\nK: !!opencv-matrix\n{body}");
        let cases = [
            ("image_width: 3".to_string(), 1),
            ("%YAML:1.0\n  indented: 1".to_string(), 2),
            ("%YAML:1.0\nno colon here".to_string(), 2),
            (
                m("   rows: 2\n   cols: 2\n   dt: d\n   data: [ 1, 2, 3 ]"),
                6,
            ),
            (m("   rows: x\n"), 3),
            (m("   rows: 1\n   cols: 1\n   dt: d\n   data: [ 1"), 6),
            (m("   rows: 1\n   cols: 1\n   dt: d\n   data: [ .Nan ]"), 6),
            (m("   rows: 1\n   cols: 1\n   dt: q\n   data: [ 1 ]"), 2),
            (m("   cols: 1\n   dt: d\n   data: [ 1 ]"), 2),
            (
                m("   rows: 100000\n   cols: 100000\n   dt: d\n   data: [ 1 ]"),
                2,
            ),
            (m("   rows: 1\n   cols: 1\n   dt: d\n   data: [ abc ]"), 6),
            (m("   rows: 1\n   cols: 1\n   dt: d\n   data: 1"), 6),
            (m("   bogus: 1"), 3),
        ];
        for (text, line) in cases {
            match parse(&text) {
                Err(Error::Parse { line: l, .. }) => assert_eq!(l, line, "{text}"),
                other => panic!("{text:?} gave {other:?}"),
            }
        }
    }

    #[test]
    fn write_then_parse() {
        let m = YamlMatrix {
            rows: 2,
            cols: 2,
            data: vec![1.0, -2.5e-12, 3.0, 0.1 + 0.2],
            line: 0,
        };
        let text = write(&[
            ("w", YamlValue::Scalar("7".into())),
            ("M", YamlValue::Matrix(m.clone())),
        ]);
        let e = parse(&text).unwrap();
        match &e[1].1 {
            YamlValue::Matrix(back) => assert_eq!(back.data, m.data),
            other => panic!("{other:?}"),
        }
    }
}
