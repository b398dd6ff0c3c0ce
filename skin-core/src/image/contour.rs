//! Silhouette contours with outward unit normals, and arc-length resampling.
//!
//! Silhouette-based fitting needs boundary points of the observed silhouette with the direction
//! that leaves the body: Fua et al. §5.3 turn each silhouette point into a tangent plane
//! (Eq. 11–13); Vlasic 2010 §2.4.2 ("Silhouette Constraints", Algorithm 1 line 10) samples the
//! contours every 10 pixels and uses "the outward facing silhouette normal" to choose which
//! surface point each contour ray pulls. Borders are traced with
//! `imageproc::contours::find_contours` (Suzuki–Abe border following, 8-connected foreground);
//! normals come from a smoothed tangent and are oriented from foreground to background, then
//! verified against the mask.
//!
//! Pixel convention: pixel `(x, y)` has its centre at `(x, y)` (see [`crate::image::Mask`]).

use ::image::{GrayImage, Luma};
use imageproc::contours::{find_contours, BorderType};
use serde::{Deserialize, Serialize};

use super::mask::{Mask, MASK_FOREGROUND_GREY};
use crate::error::{Error, Result};
use crate::math::DVec2;

impl ContourParams {
    /// Default half-width of the tangent window, in contour points (see
    /// [`ContourParams::tangent_half_window`]).
    pub const DEFAULT_TANGENT_HALF_WINDOW: usize = 3;

    /// Default offset of contour points along their normal, pixels: half a pixel puts the points
    /// on the pixel edges between foreground and background, the zero level set of
    /// [`crate::image::signed_distance`].
    pub const DEFAULT_OUTWARD_OFFSET_PX: f64 = 0.5;

    /// Default arc-length spacing of contour samples, pixels: Vlasic 2010 §2.4.2 "we sample the
    /// contours (every 10 pixels)".
    pub const DEFAULT_SAMPLE_STEP_PX: f64 = 10.0;

    /// Default minimum number of traced boundary pixels for a contour to be kept.
    pub const DEFAULT_MIN_POINTS: usize = 1;
}

/// Below this length a smoothed tangent (or fallback direction) is treated as zero.
const DIRECTION_EPS: f64 = 1e-9;
/// Largest number of samples [`Contour::resample`] will produce for one contour.
const MAX_RESAMPLED_POINTS: f64 = 1e8;
/// Distance, in pixels, of the in/out probes used to verify normal orientation.
const PROBE_STEP_PX: f64 = 1.0;

/// Knobs of contour extraction.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ContourParams {
    /// Half-width `w` of the tangent window, in contour points: the tangent at point `i` is
    /// `Σ_{j=1..w} (p_{i+j} − p_{i−j})` (a box-smoothed central difference, indices cyclic).
    /// Traced 8-connected borders are staircases; `w = 3` smooths the staircase over about
    /// seven pixels, which keeps normal errors on straight edges of any slope within a few
    /// degrees while following corners of a human silhouette. Not from a paper.
    /// Default: [`ContourParams::DEFAULT_TANGENT_HALF_WINDOW`] = 3.
    pub tangent_half_window: usize,
    /// Offset of each returned point along its outward normal, pixels. 0 returns the centres
    /// of the traced boundary pixels (which lie inside the foreground); 0.5 moves them onto
    /// the pixel-edge boundary. Default: [`ContourParams::DEFAULT_OUTWARD_OFFSET_PX`] = 0.5.
    pub outward_offset_px: f64,
    /// Contours with fewer traced pixels are dropped (1 keeps single-pixel specks).
    /// Default: [`ContourParams::DEFAULT_MIN_POINTS`] = 1.
    pub min_points: usize,
    /// If `> 0`, each contour is resampled every `sample_step_px` pixels of arc length
    /// ([`Contour::resample`]); 0 keeps one point per boundary pixel. Source: Vlasic 2010
    /// §2.4.2. Default: [`ContourParams::DEFAULT_SAMPLE_STEP_PX`] = 10.
    pub sample_step_px: f64,
}

impl Default for ContourParams {
    fn default() -> Self {
        ContourParams {
            tangent_half_window: ContourParams::DEFAULT_TANGENT_HALF_WINDOW,
            outward_offset_px: ContourParams::DEFAULT_OUTWARD_OFFSET_PX,
            min_points: ContourParams::DEFAULT_MIN_POINTS,
            sample_step_px: ContourParams::DEFAULT_SAMPLE_STEP_PX,
        }
    }
}

impl ContourParams {
    /// Sets [`ContourParams::tangent_half_window`].
    pub fn with_tangent_half_window(mut self, w: usize) -> Self {
        self.tangent_half_window = w;
        self
    }
    /// Sets [`ContourParams::outward_offset_px`].
    pub fn with_outward_offset_px(mut self, px: f64) -> Self {
        self.outward_offset_px = px;
        self
    }
    /// Sets [`ContourParams::min_points`].
    pub fn with_min_points(mut self, n: usize) -> Self {
        self.min_points = n;
        self
    }
    /// Sets [`ContourParams::sample_step_px`].
    pub fn with_sample_step_px(mut self, px: f64) -> Self {
        self.sample_step_px = px;
        self
    }

    fn validate(&self) -> Result<()> {
        if self.tangent_half_window == 0 {
            return Err(Error::InvalidParam {
                name: "tangent_half_window",
                reason: "must be at least 1".into(),
            });
        }
        if !self.outward_offset_px.is_finite() {
            return Err(Error::InvalidParam {
                name: "outward_offset_px",
                reason: format!("must be finite, got {}", self.outward_offset_px),
            });
        }
        crate::check::non_negative("sample_step_px", self.sample_step_px)?;
        Ok(())
    }
}

/// One closed border of a foreground region.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Contour {
    /// Points along the border in tracing order (closed: the last connects to the first),
    /// image pixels.
    pub points: Vec<DVec2>,
    /// Outward unit normal at each point (from foreground towards background); for a hole
    /// border it points into the hole.
    pub normals: Vec<DVec2>,
    /// `true` for the outer border of a foreground region, `false` for the border of a hole.
    pub is_outer: bool,
    /// Index, in the returned vector, of the enclosing contour (a hole's region border, or
    /// the hole around an island), if any and if it was kept.
    pub parent: Option<usize>,
}

impl Contour {
    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether the contour has no points.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Length of the closed polyline through the points, pixels.
    pub fn perimeter_px(&self) -> f64 {
        let n = self.points.len();
        (0..n)
            .map(|i| self.points[i].distance(self.points[(i + 1) % n]))
            .sum()
    }

    /// Resamples the closed polyline every `step_px` pixels of arc length, starting at the
    /// first point. Normals are interpolated linearly and renormalised (where they cancel, the
    /// nearer original normal is used). A contour of zero length is returned unchanged.
    ///
    /// # Errors
    /// [`Error::InvalidParam`] if `step_px` is not finite and positive or would give more than
    /// 10⁸ samples; [`Error::SizeMismatch`] if `points` and `normals` differ in length;
    /// [`Error::NonFinite`] if a point or normal is NaN or infinite.
    pub fn resample(&self, step_px: f64) -> Result<Contour> {
        crate::check::positive("step_px", step_px)?;
        if self.normals.len() != self.points.len() {
            return Err(Error::SizeMismatch {
                what: "contour normals vs points",
                expected: self.points.len(),
                got: self.normals.len(),
            });
        }
        if !self
            .points
            .iter()
            .chain(&self.normals)
            .all(|p| p.is_finite())
        {
            return Err(Error::NonFinite {
                what: "contour points or normals",
            });
        }
        let total = self.perimeter_px();
        if total / step_px > MAX_RESAMPLED_POINTS {
            return Err(Error::InvalidParam {
                name: "step_px",
                reason: format!("{step_px} px gives more than 1e8 samples over {total} px"),
            });
        }
        if total <= 0.0 {
            return Ok(self.clone());
        }
        let n = self.points.len();
        let mut points = Vec::new();
        let mut normals = Vec::new();
        let mut seg = 0usize;
        let mut seg_start = 0.0;
        let count = (total / step_px).ceil() as usize;
        for k in 0..count {
            let s = k as f64 * step_px;
            // Advance to the segment containing arc length s (s < total, so this terminates).
            loop {
                let len = self.points[seg].distance(self.points[(seg + 1) % n]);
                if s < seg_start + len || seg + 1 == n {
                    break;
                }
                seg_start += len;
                seg += 1;
            }
            let (a, b) = (seg, (seg + 1) % n);
            let len = self.points[a].distance(self.points[b]);
            let t = if len > 0.0 {
                ((s - seg_start) / len).clamp(0.0, 1.0)
            } else {
                0.0
            };
            points.push(self.points[a].lerp(self.points[b], t));
            let nrm = self.normals[a].lerp(self.normals[b], t);
            normals.push(if nrm.length() > DIRECTION_EPS {
                nrm.normalize()
            } else if t < 0.5 {
                self.normals[a]
            } else {
                self.normals[b]
            });
        }
        Ok(Contour {
            points,
            normals,
            is_outer: self.is_outer,
            parent: self.parent,
        })
    }
}

/// Mean direction from pixel `p` to its background 8-neighbours (zero if none or balanced).
fn background_direction(mask: &Mask, p: (i64, i64)) -> DVec2 {
    let mut d = DVec2::ZERO;
    for dy in -1i64..=1 {
        for dx in -1i64..=1 {
            if (dx, dy) != (0, 0) && !mask.get_i64(p.0 + dx, p.1 + dy) {
                d += DVec2::new(dx as f64, dy as f64).normalize();
            }
        }
    }
    d
}

fn is_fg_at(mask: &Mask, q: DVec2) -> bool {
    mask.get_i64(q.x.round() as i64, q.y.round() as i64)
}

/// Unit normals of a traced border, oriented from foreground to background.
fn border_normals(
    mask: &Mask,
    pix: &[(i64, i64)],
    is_outer: bool,
    half_window: usize,
) -> Vec<DVec2> {
    let n = pix.len();
    let pts: Vec<DVec2> = pix
        .iter()
        .map(|&(x, y)| DVec2::new(x as f64, y as f64))
        .collect();
    let centroid = pts.iter().copied().sum::<DVec2>() / n as f64;
    // Shoelace signed area: > 0 means the right-hand perpendicular (t.y, −t.x) points out of
    // the polygon. Outer borders want "out of the polygon", hole borders "into" it.
    let area2: f64 = (0..n).map(|i| pts[i].perp_dot(pts[(i + 1) % n])).sum();
    let mut sign = if area2 >= 0.0 { 1.0 } else { -1.0 };
    if !is_outer {
        sign = -sign;
    }
    let w = half_window.min(n.saturating_sub(1) / 2).max(1);
    let mut normals: Vec<DVec2> = (0..n)
        .map(|i| {
            let t: DVec2 = (1..=w)
                .map(|j| pts[(i + j) % n] - pts[(i + n - j % n) % n])
                .sum();
            if n >= 3 && t.length() > DIRECTION_EPS {
                return sign * DVec2::new(t.y, -t.x).normalize();
            }
            // Degenerate tangent (spikes of thin structures, 1–2 pixel borders): fall back to
            // the local background direction, then to the direction away from the region.
            let b = background_direction(mask, pix[i]);
            if b.length() > DIRECTION_EPS {
                return b.normalize();
            }
            let c = if is_outer {
                pts[i] - centroid
            } else {
                centroid - pts[i]
            };
            if c.length() > DIRECTION_EPS {
                c.normalize()
            } else {
                // An isolated pixel: every direction leaves the mask.
                DVec2::X
            }
        })
        .collect();
    // Verify the orientation against the mask: probes one pixel along ±n must find
    // background outside and foreground inside. Flip the whole border if most disagree
    // (robust to the tracer's orientation convention).
    let votes: i64 = pts
        .iter()
        .zip(&normals)
        .map(|(&p, &nrm)| {
            let out_fg = is_fg_at(mask, p + PROBE_STEP_PX * nrm);
            let in_fg = is_fg_at(mask, p - PROBE_STEP_PX * nrm);
            match (out_fg, in_fg) {
                (false, true) => 1,
                (true, false) => -1,
                _ => 0,
            }
        })
        .sum();
    if votes < 0 {
        for nrm in &mut normals {
            *nrm = -*nrm;
        }
    }
    normals
}

/// Extracts every border of the mask's 8-connected foreground regions (outer borders and
/// hole borders) with outward unit normals.
///
/// Points are boundary pixel centres moved `outward_offset_px` along their normal, optionally
/// resampled by arc length ([`ContourParams`]). An empty or zero-sized mask has no border and
/// yields an empty vector (not an error). Foreground touching the image border is traced
/// along the image border (pixels outside the image are background).
///
/// # Errors
/// [`Error::InvalidParam`] for invalid [`ContourParams`] or a mask wider or taller than
/// `u32::MAX − 2`.
///
/// # Example
/// ```
/// use skin_core::image::{extract_contours, ContourParams, Mask};
/// let disc = Mask::from_fn(21, 21, |x, y| (x as f64 - 10.0).hypot(y as f64 - 10.0) < 6.0);
/// let contours = extract_contours(&disc, &ContourParams::default())?;
/// assert_eq!(contours.len(), 1);
/// assert!(contours[0].is_outer);
/// # Ok::<(), skin_core::Error>(())
/// ```
pub fn extract_contours(mask: &Mask, params: &ContourParams) -> Result<Vec<Contour>> {
    params.validate()?;
    if mask.is_empty() {
        return Ok(Vec::new());
    }
    // Pad by one background pixel on every side: imageproc's tracer (Suzuki–Abe) assumes a
    // background frame and misses regions touching the left image border without it.
    let (w, h) = mask.dimensions();
    let (Some(pw), Some(ph)) = (w.checked_add(2), h.checked_add(2)) else {
        return Err(Error::InvalidParam {
            name: "mask size",
            reason: format!("{w}x{h} is too large to pad for contour tracing"),
        });
    };
    let padded = GrayImage::from_fn(pw, ph, |x, y| {
        let fg = x >= 1 && y >= 1 && mask.get(x - 1, y - 1);
        Luma([if fg { MASK_FOREGROUND_GREY } else { 0 }])
    });
    let traced = find_contours::<i64>(&padded);
    let mut new_index = vec![None; traced.len()];
    let mut out: Vec<Contour> = Vec::new();
    for (i, c) in traced.iter().enumerate() {
        if c.points.is_empty() || c.points.len() < params.min_points {
            continue;
        }
        let is_outer = c.border_type == BorderType::Outer;
        let pix: Vec<(i64, i64)> = c.points.iter().map(|p| (p.x - 1, p.y - 1)).collect();
        let normals = border_normals(mask, &pix, is_outer, params.tangent_half_window);
        let points = pix
            .iter()
            .zip(&normals)
            .map(|(&(x, y), &nrm)| DVec2::new(x as f64, y as f64) + params.outward_offset_px * nrm)
            .collect();
        new_index[i] = Some(out.len());
        out.push(Contour {
            points,
            normals,
            is_outer,
            // Parents precede children in the tracer's output.
            parent: c.parent.and_then(|p| new_index.get(p).copied().flatten()),
        });
    }
    if params.sample_step_px > 0.0 {
        out = out
            .iter()
            .map(|c| c.resample(params.sample_step_px))
            .collect::<Result<_>>()?;
    }
    Ok(out)
}

#[cfg(test)]
mod tests;
