//! BVH (Biovision Hierarchy) import into a [`Skeleton`] and a [`Motion`].
//!
//! **Interpretation.** Each joint's local transform is
//! `T(OFFSET) · T(position channels) · R₁(c₁) · R₂(c₂) · R₃(c₃)`, where the rotation channels
//! are applied intrinsically in the order they are listed (`Zrotation Yrotation Xrotation`
//! means `R = R_z · R_y · R_x`), in degrees. Position channels are translations in the parent
//! frame whatever their position in the list — the convention of the Biovision format and of
//! common importers (Blender, MotionBuilder). In the resulting [`Skeleton`] every joint lists
//! its translation DOFs first, then its rotation DOFs, each group in file order; the motion
//! columns are permuted accordingly. DOFs are named `"<joint>.<channel>"`, e.g.
//! `"Hips.Zrotation"`; rotations become radians and lengths are multiplied by
//! [`BvhParams::metres_per_unit`]. An `End Site` becomes its joint's
//! [`end_site`](super::Joint::end_site). Several `ROOT`s are accepted (a forest).
//!
//! Any subset of the six channels in any order is accepted. The parser is iterative (no
//! recursion, so deep nesting cannot overflow the stack) and never allocates from a count
//! read from the file before the corresponding data is present.

use super::dof::{Dof, DofKind};
use super::model::{Joint, Skeleton};
use super::motion::Motion;
use crate::math::DVec3;
use crate::{Error, Result};
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Metres per length unit of the CMU motion-capture BVH conversions (cgspeed), from the CMU
/// FAQ: one unit is `1/0.45` inch, i.e. `(1.0 / 0.45) · 2.54 / 100` m.
pub const CMU_METRES_PER_UNIT: f64 = (1.0 / 0.45) * 2.54 / 100.0;

/// Units of a BVH file.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BvhParams {
    /// Metres per file length unit (offsets and position channels); import multiplies by it,
    /// export divides. E.g. [`CMU_METRES_PER_UNIT`] for CMU files, 0.1 for MakeHuman
    /// (decimetres). Default: 1.0 (file in metres).
    pub metres_per_unit: f64,
}

impl Default for BvhParams {
    fn default() -> Self {
        BvhParams {
            metres_per_unit: 1.0,
        }
    }
}

impl BvhParams {
    pub(super) fn check(&self) -> Result<()> {
        crate::check::positive("metres_per_unit", self.metres_per_unit).map(|_| ())
    }
}

/// A parsed BVH file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Bvh {
    /// The hierarchy (metres, DOFs as described in the module docs).
    pub skeleton: Skeleton,
    /// The frames (radians, metres), one column per frame in the skeleton's DOF order.
    pub motion: Motion,
}

const FORMAT: &str = "BVH";

fn perr(line: usize, message: impl Into<String>) -> Error {
    Error::Parse {
        format: FORMAT,
        line,
        message: message.into(),
    }
}

#[derive(Clone, Copy)]
struct Tok<'a> {
    text: &'a str,
    line: usize,
}

struct Lexer<'a> {
    lines: std::iter::Peekable<std::iter::Enumerate<std::str::Lines<'a>>>,
    current: std::str::SplitWhitespace<'a>,
    line: usize,
}

impl<'a> Lexer<'a> {
    fn new(text: &'a str) -> Self {
        Lexer {
            lines: text.lines().enumerate().peekable(),
            current: "".split_whitespace(),
            line: 0,
        }
    }

    /// Next token, or `None` at end of input.
    fn next(&mut self) -> Option<Tok<'a>> {
        loop {
            if let Some(t) = self.current.next() {
                return Some(Tok {
                    text: t,
                    line: self.line,
                });
            }
            let (i, l) = self.lines.next()?;
            self.line = i + 1;
            self.current = l.split_whitespace();
        }
    }

    /// Next token on the current line only.
    fn next_on_line(&mut self) -> Option<Tok<'a>> {
        self.current.next().map(|t| Tok {
            text: t,
            line: self.line,
        })
    }

    fn expect(&mut self, what: &str) -> Result<Tok<'a>> {
        let line = self.line;
        let t = self
            .next()
            .ok_or_else(|| perr(line, format!("unexpected end of file, expected '{what}'")))?;
        if t.text != what {
            return Err(perr(
                t.line,
                format!("expected '{what}', found '{}'", t.text),
            ));
        }
        Ok(t)
    }

    fn number(&mut self, what: &str) -> Result<f64> {
        let line = self.line;
        let t = self
            .next()
            .ok_or_else(|| perr(line, format!("unexpected end of file, expected {what}")))?;
        parse_finite(t.text)
            .ok_or_else(|| perr(t.line, format!("expected {what}, found '{}'", t.text)))
    }

    /// Remaining lines after the current one (for the MOTION section).
    fn rest_lines(self) -> impl Iterator<Item = (usize, &'a str)> {
        self.lines.map(|(i, l)| (i + 1, l))
    }
}

fn parse_finite(s: &str) -> Option<f64> {
    s.parse::<f64>().ok().filter(|v| v.is_finite())
}

struct PendingJoint {
    name: String,
    parent: Option<usize>,
    offset: Option<DVec3>,
    channels: Option<Vec<(DofKind, usize, String)>>,
    end_site: Option<DVec3>,
    line: usize,
}

fn channel(text: &str) -> Option<(DofKind, usize)> {
    let lower = text.to_ascii_lowercase();
    let (axis, rest) = lower.split_at_checked(1)?;
    let axis = match axis {
        "x" => 0,
        "y" => 1,
        "z" => 2,
        _ => return None,
    };
    match rest {
        "position" => Some((DofKind::Translation, axis)),
        "rotation" => Some((DofKind::Rotation, axis)),
        _ => None,
    }
}

fn offset(lx: &mut Lexer) -> Result<DVec3> {
    Ok(DVec3::new(
        lx.number("OFFSET x")?,
        lx.number("OFFSET y")?,
        lx.number("OFFSET z")?,
    ))
}

/// Parses the HIERARCHY section up to and including the `MOTION` keyword.
fn parse_hierarchy(lx: &mut Lexer) -> Result<Vec<PendingJoint>> {
    lx.expect("HIERARCHY")?;
    let mut joints: Vec<PendingJoint> = Vec::new();
    let mut stack: Vec<usize> = Vec::new();
    let mut names = std::collections::HashSet::new();
    loop {
        let line = lx.line;
        let Some(t) = lx.next() else {
            return Err(match stack.last() {
                Some(&j) => perr(
                    line,
                    format!(
                        "unexpected end of file: joint '{}' (line {}) is not closed with '}}'",
                        joints[j].name, joints[j].line
                    ),
                ),
                None => perr(line, "unexpected end of file: missing MOTION section"),
            });
        };
        match t.text {
            "ROOT" | "JOINT" => {
                if (t.text == "ROOT") != stack.is_empty() {
                    return Err(perr(
                        t.line,
                        if stack.is_empty() {
                            "JOINT outside of a ROOT block (missing '{' or extra '}'?)"
                        } else {
                            "ROOT inside another joint (missing '}'?)"
                        },
                    ));
                }
                let mut parts = Vec::new();
                let mut brace = false;
                while let Some(n) = lx.next_on_line() {
                    if n.text == "{" {
                        brace = true;
                        break;
                    }
                    parts.push(n.text);
                }
                if parts.is_empty() {
                    return Err(perr(t.line, format!("{} without a name", t.text)));
                }
                if !brace {
                    lx.expect("{")?;
                }
                let name = parts.join(" ");
                if !names.insert(name.clone()) {
                    return Err(perr(t.line, format!("duplicate joint name '{name}'")));
                }
                joints.push(PendingJoint {
                    name,
                    parent: stack.last().copied(),
                    offset: None,
                    channels: None,
                    end_site: None,
                    line: t.line,
                });
                stack.push(joints.len() - 1);
            }
            "End" => {
                let Some(&j) = stack.last() else {
                    return Err(perr(t.line, "End Site outside of a joint"));
                };
                lx.expect("Site")?;
                lx.expect("{")?;
                lx.expect("OFFSET")?;
                let o = offset(lx)?;
                lx.expect("}")?;
                if joints[j].end_site.replace(o).is_some() {
                    return Err(perr(
                        t.line,
                        format!("joint '{}' has two End Sites", joints[j].name),
                    ));
                }
            }
            "OFFSET" => {
                let Some(&j) = stack.last() else {
                    return Err(perr(t.line, "OFFSET outside of a joint"));
                };
                let o = offset(lx)?;
                if joints[j].offset.replace(o).is_some() {
                    return Err(perr(
                        t.line,
                        format!("joint '{}' has two OFFSETs", joints[j].name),
                    ));
                }
            }
            "CHANNELS" => {
                let Some(&j) = stack.last() else {
                    return Err(perr(t.line, "CHANNELS outside of a joint"));
                };
                let n_tok = lx
                    .next()
                    .ok_or_else(|| perr(t.line, "unexpected end of file after CHANNELS"))?;
                let n: usize = n_tok.text.parse().map_err(|_| {
                    perr(
                        n_tok.line,
                        format!("expected a channel count, found '{}'", n_tok.text),
                    )
                })?;
                let mut chans = Vec::new();
                for _ in 0..n {
                    let line = lx.line;
                    let c = lx
                        .next()
                        .ok_or_else(|| perr(line, "unexpected end of file in CHANNELS"))?;
                    let (kind, axis) = channel(c.text).ok_or_else(|| {
                        perr(
                            c.line,
                            format!(
                                "joint '{}': '{}' is not a channel (Xposition…Zrotation); CHANNELS count {n} too large?",
                                joints[j].name, c.text
                            ),
                        )
                    })?;
                    chans.push((kind, axis, c.text.to_string()));
                }
                if joints[j].channels.replace(chans).is_some() {
                    return Err(perr(
                        t.line,
                        format!("joint '{}' has two CHANNELS lines", joints[j].name),
                    ));
                }
            }
            "}" => {
                let Some(j) = stack.pop() else {
                    return Err(perr(t.line, "unmatched '}'"));
                };
                if joints[j].offset.is_none() {
                    return Err(perr(
                        t.line,
                        format!("joint '{}' has no OFFSET", joints[j].name),
                    ));
                }
            }
            "MOTION" => {
                if let Some(&j) = stack.last() {
                    return Err(perr(
                        t.line,
                        format!(
                            "MOTION before joint '{}' (line {}) is closed: missing '}}'",
                            joints[j].name, joints[j].line
                        ),
                    ));
                }
                if joints.is_empty() {
                    return Err(perr(t.line, "no ROOT joint before MOTION"));
                }
                if let Some(extra) = lx.next_on_line() {
                    return Err(perr(
                        extra.line,
                        format!("unexpected '{}' after MOTION", extra.text),
                    ));
                }
                return Ok(joints);
            }
            other => return Err(perr(t.line, format!("unexpected '{other}' in HIERARCHY"))),
        }
    }
}

/// Reads the next non-blank line as `<key>: <value>` (whitespace around the colon free).
fn header<'a>(
    lines: &mut impl Iterator<Item = (usize, &'a str)>,
    key: &str,
    last_line: usize,
) -> Result<(usize, &'a str)> {
    for (i, l) in lines.by_ref() {
        let t = l.trim();
        if t.is_empty() {
            continue;
        }
        let words: Vec<&str> = t.split_whitespace().collect();
        let n_key = key.split(' ').count();
        let value = (words.len() >= n_key)
            .then(|| {
                let head = words[..n_key].join(" ");
                let rest = &words[n_key..];
                match (head.strip_suffix(':'), rest) {
                    (Some(h), [v]) if h == key => Some(*v),
                    (None, [":", v]) if head == key => Some(*v),
                    _ => None,
                }
            })
            .flatten();
        return value
            .map(|v| (i, v))
            .ok_or_else(|| perr(i, format!("expected '{key}: <value>', found '{t}'")));
    }
    Err(perr(
        last_line,
        format!("unexpected end of file, expected '{key}: <value>'"),
    ))
}

/// Largest frame count accepted for a hierarchy without channels (no data lines to count).
const MAX_EMPTY_FRAMES: usize = 1_000_000;

/// Parses BVH text.
///
/// # Errors
/// [`Error::Parse`] with the line number for malformed input: missing or unmatched braces,
/// unknown keywords or channels, missing OFFSET, non-numeric or non-finite numbers, a frame
/// line whose value count differs from the channel count (naming the joint the first missing
/// or extra value would belong to), or a frame count different from `Frames:`.
/// [`Error::InvalidParam`] for bad `params`, duplicate joint names (from [`Skeleton::new`]).
///
/// # Example
/// ```
/// use skin_core::skeleton::{parse_bvh, BvhParams};
/// let text = "HIERARCHY\nROOT hips\n{\n OFFSET 0 1 0\n CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation\n End Site\n {\n  OFFSET 0 0.5 0\n }\n}\nMOTION\nFrames: 1\nFrame Time: 0.01\n0 0 0 90 0 0\n";
/// let bvh = parse_bvh(text, &BvhParams::default())?;
/// assert_eq!(bvh.skeleton.dof_count(), 6);
/// assert!((bvh.motion.frame(0)[3] - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
/// # Ok::<(), skin_core::Error>(())
/// ```
pub fn parse_bvh(text: &str, params: &BvhParams) -> Result<Bvh> {
    params.check()?;
    let scale = params.metres_per_unit;
    let mut lx = Lexer::new(text);
    let pending = parse_hierarchy(&mut lx)?;
    let motion_line = lx.line;

    // Build joints (translations first) and the file-column → DOF permutation.
    let mut joints = Vec::with_capacity(pending.len());
    let mut column_dof: Vec<usize> = Vec::new();
    let mut column_joint: Vec<usize> = Vec::new();
    let mut column_rot: Vec<bool> = Vec::new();
    let mut next_dof = 0;
    for (j, p) in pending.into_iter().enumerate() {
        let chans = p.channels.unwrap_or_default();
        let n_trans = chans.iter().filter(|c| c.0 == DofKind::Translation).count();
        let (mut ti, mut ri) = (0, n_trans);
        let mut dofs: Vec<Option<Dof>> = vec![None; chans.len()];
        for (kind, axis, name) in chans {
            let slot = match kind {
                DofKind::Translation => &mut ti,
                DofKind::Rotation => &mut ri,
            };
            let dof = Dof {
                name: format!("{}.{}", p.name, name),
                kind,
                axis: DVec3::AXES[axis],
                limits: None,
            };
            dofs[*slot] = Some(dof);
            column_dof.push(next_dof + *slot);
            column_joint.push(j);
            column_rot.push(kind == DofKind::Rotation);
            *slot += 1;
        }
        next_dof += dofs.len();
        joints.push(Joint {
            name: p.name,
            parent: p.parent,
            // Proven: parse_hierarchy rejects a closed joint without OFFSET, and every joint
            // is closed before MOTION is accepted.
            offset: p.offset.unwrap_or_default() * scale,
            // Proven: every slot 0..n is filled once (translations 0..n_trans, rotations after).
            dofs: dofs.into_iter().flatten().collect(),
            end_site: p.end_site.map(|e| e * scale),
        });
    }
    let skeleton = Skeleton::new(joints).map_err(|e| match e {
        Error::InvalidParam { reason, .. } => perr(0, reason),
        other => other,
    })?;
    let n_ch = column_dof.len();

    let mut lines = lx.rest_lines();
    let (fl, frames_text) = header(&mut lines, "Frames", motion_line)?;
    let n_frames: usize = frames_text
        .parse()
        .map_err(|_| perr(fl, format!("expected a frame count, found '{frames_text}'")))?;
    let (tl, time_text) = header(&mut lines, "Frame Time", fl)?;
    let frame_time = parse_finite(time_text)
        .filter(|t| *t > 0.0)
        .ok_or_else(|| {
            perr(
                tl,
                format!("Frame Time must be a positive number, found '{time_text}'"),
            )
        })?;

    let mut data: Vec<f64> = Vec::new();
    let mut count = 0usize;
    let mut last_line = tl;
    for (i, l) in lines {
        last_line = i;
        if l.trim().is_empty() {
            continue;
        }
        count += 1;
        if count > n_frames {
            return Err(perr(
                i,
                format!("more frame lines than 'Frames: {n_frames}'"),
            ));
        }
        let start = data.len();
        data.resize(start + n_ch, 0.0);
        let mut k = 0;
        for tok in l.split_whitespace() {
            if k >= n_ch {
                return Err(perr(
                    i,
                    format!(
                        "frame {count}: more than the {n_ch} values the HIERARCHY channels require"
                    ),
                ));
            }
            let v = parse_finite(tok).ok_or_else(|| {
                perr(
                    i,
                    format!(
                        "frame {count}, value {} (joint '{}', DOF '{}'): '{tok}' is not a finite number",
                        k + 1,
                        skeleton.joints()[column_joint[k]].name,
                        skeleton.dof(column_dof[k]).name
                    ),
                )
            })?;
            data[start + column_dof[k]] = if column_rot[k] {
                v.to_radians()
            } else {
                v * scale
            };
            k += 1;
        }
        if k < n_ch {
            return Err(perr(
                i,
                format!(
                    "frame {count}: {k} values but the HIERARCHY has {n_ch} channels (first missing: joint '{}', DOF '{}')",
                    skeleton.joints()[column_joint[k]].name,
                    skeleton.dof(column_dof[k]).name
                ),
            ));
        }
    }
    if n_ch == 0 {
        if n_frames > MAX_EMPTY_FRAMES {
            return Err(perr(
                fl,
                format!("'Frames: {n_frames}' for a hierarchy without channels"),
            ));
        }
        count = n_frames;
    } else if count != n_frames {
        return Err(perr(
            last_line,
            format!("'Frames: {n_frames}' but {count} frame lines"),
        ));
    }
    let frames = DMatrix::from_vec(n_ch, count, data);
    let motion = Motion::new(frame_time, frames)?;
    Ok(Bvh { skeleton, motion })
}

/// Reads and parses a BVH file.
///
/// # Errors
/// [`Error::Io`] if the file cannot be read; otherwise as [`parse_bvh`].
pub fn read_bvh(path: impl AsRef<Path>, params: &BvhParams) -> Result<Bvh> {
    let path = path.as_ref();
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    parse_bvh(&text, params)
}

#[cfg(test)]
mod tests;
