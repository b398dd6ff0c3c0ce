//! Symmetric pyramidal Kanade–Lucas–Tomasi point tracking (§5.4.1, Eq. 5.6; Birchfield's KLT,
//! the thesis's reference [18]).
//!
//! **Eq. 5.6, derived.** A point at `q` in frame `I` moves to `p` in frame `J`; over a window
//! `W` of offsets `o`, brightness constancy `J(p + o) = I(q + o)` linearised at the current
//! guess `p₀` (`p = p₀ + d`) gives `Σ_W (I(q + o) − J(p₀ + o) − gᵀd) g = 0`, i.e.
//! `Z d = e` with `Z = Σ_W g gᵀ` and `e = Σ_W (I − J) g`. The **symmetric** formulation takes
//! `g = ½ (∇I(q + o) + ∇J(p₀ + o))`, the mean of both images' gradients, which makes the
//! linearisation exact to second order for a translation (it is the same for the forward and
//! the backward problem). The intensity difference has each window's mean removed (a
//! brightness offset between the frames, e.g. from shading as the head turns, does not move
//! the point). Iterated until the update is below `epsilon_px`, coarse to fine over an image
//! pyramid (a 5-tap binomial blur and every other pixel per level).
//!
//! **Forward–backward check.** The converged `p` is tracked back into `I`; a point whose way
//! back misses `q` by more than `fb_max_px` is rejected, as is one whose window leaves the
//! frame, whose `Z` is nearly singular (a flat window), or whose final residual is more than
//! `residual_ratio` of the template window's own contrast.
//!
//! The tracker (`video.rs`) does not use the converged `p` alone: it keeps `Z` and solves the
//! model through Eq. 5.7 weighted by `Z` (module docs there).

use image::RgbImage;

/// One level of a pyramid: intensity and its central-difference gradients.
#[derive(Clone, Debug)]
pub(crate) struct Level {
    pub(crate) width: usize,
    pub(crate) height: usize,
    img: Vec<f32>,
    /// Intensity, gx and gy interleaved, three floats per pixel (a window row is one
    /// contiguous run).
    igg: Vec<f32>,
}

impl Level {
    fn new(width: usize, height: usize, img: Vec<f32>) -> Self {
        let mut igg = vec![0.0f32; 3 * img.len()];
        // One-sided differences at the borders, central ones inside (each divided by its span).
        for y in 0..height {
            let (yu, yd) = (y.saturating_sub(1), (y + 1).min(height - 1));
            let span = (yd - yu).max(1) as f32;
            let row = &img[y * width..(y + 1) * width];
            let (up, down) = (
                &img[yu * width..(yu + 1) * width],
                &img[yd * width..(yd + 1) * width],
            );
            let out = &mut igg[3 * y * width..3 * (y + 1) * width];
            for (x, o) in out.chunks_exact_mut(3).enumerate() {
                o[0] = row[x];
                o[1] = if x > 0 && x + 1 < width {
                    (row[x + 1] - row[x - 1]) / 2.0
                } else {
                    let (xl, xr) = (x.saturating_sub(1), (x + 1).min(width - 1));
                    (row[xr] - row[xl]) / (xr - xl).max(1) as f32
                };
                o[2] = (down[x] - up[x]) / span;
            }
        }
        Level {
            width,
            height,
            img,
            igg,
        }
    }

    /// Bilinear samples of (intensity, gx, gy) at the `n × n` pixel grid whose top-left
    /// sample is `(x, y)`, into `out` (row-major, three floats per sample; `rows` is
    /// scratch); `false` when a sample falls outside the image. The grid's offsets are whole
    /// pixels, so one pair of interpolation weights serves every sample: each of the `n + 1`
    /// image rows is interpolated horizontally once, then each pair of consecutive rows
    /// vertically (one contiguous run).
    fn window(&self, x: f64, y: f64, n: usize, rows: &mut Vec<f32>, out: &mut [f32]) -> bool {
        if !(x >= 0.0 && y >= 0.0) {
            return false;
        }
        let (x0, y0) = (x as usize, y as usize);
        if x0 + n >= self.width || y0 + n >= self.height {
            return false;
        }
        let (fx, fy) = ((x - x0 as f64) as f32, (y - y0 as f64) as f32);
        let len = 3 * n;
        rows.resize((n + 1) * len, 0.0);
        for (j, h) in rows[..(n + 1) * len].chunks_exact_mut(len).enumerate() {
            let i = 3 * ((y0 + j) * self.width + x0);
            // Left and right corners, each `len` long: a loop the compiler vectorises.
            let (a, b) = (&self.igg[i..i + len], &self.igg[i + 3..i + 3 + len]);
            for m in 0..len {
                h[m] = a[m] + fx * (b[m] - a[m]);
            }
        }
        let (t, u, out) = (
            &rows[..n * len],
            &rows[len..(n + 1) * len],
            &mut out[..n * len],
        );
        for m in 0..n * len {
            out[m] = t[m] + fy * (u[m] - t[m]);
        }
        true
    }
}

/// A grey pyramid of one frame (level 0 full resolution).
#[derive(Clone, Debug)]
pub(crate) struct Pyramid {
    pub(crate) levels: Vec<Level>,
}

/// One output sample of the [1 4 6 4 1]/16 blur from five taps.
#[inline]
fn binomial(t: [f32; 5]) -> f32 {
    let mut s = 0.0f32;
    for (kj, v) in [1.0f32, 4.0, 6.0, 4.0, 1.0].iter().zip(t) {
        s += kj * v;
    }
    s / 16.0
}

impl Pyramid {
    /// Luminance (Rec. 709 weights of the 8-bit values, in `[0, 1]`) and `levels` levels.
    pub(crate) fn new(frame: &RgbImage, levels: usize) -> Self {
        let (w, h) = (frame.width() as usize, frame.height() as usize);
        let img: Vec<f32> = frame
            .as_raw()
            .chunks_exact(3)
            .map(|p| {
                (0.2126 * f32::from(p[0]) + 0.7152 * f32::from(p[1]) + 0.0722 * f32::from(p[2]))
                    / 255.0
            })
            .collect();
        let mut out = vec![Level::new(w, h, img)];
        while out.len() < levels.max(1) {
            let Some(prev) = out.last() else { break };
            let (pw, ph) = (prev.width, prev.height);
            let (nw, nh) = (pw.div_ceil(2), ph.div_ceil(2));
            if nw < 8 || nh < 8 {
                break;
            }
            // Separable [1 4 6 4 1]/16 blur, sampled at even pixels; the image's border
            // pixels repeat outside it.
            let clampi = |v: isize, n: usize| v.clamp(0, n as isize - 1) as usize;
            let mut rows = vec![0.0f32; nw * ph];
            for (src, dst) in prev.img.chunks_exact(pw).zip(rows.chunks_exact_mut(nw)) {
                for (x, d) in dst.iter_mut().enumerate() {
                    let c = 2 * x;
                    *d = if c >= 2 && c + 2 < pw {
                        binomial([src[c - 2], src[c - 1], src[c], src[c + 1], src[c + 2]])
                    } else {
                        binomial(std::array::from_fn(|j| {
                            src[clampi(c as isize + j as isize - 2, pw)]
                        }))
                    };
                }
            }
            let mut next = vec![0.0f32; nw * nh];
            for (y, dst) in next.chunks_exact_mut(nw).enumerate() {
                let taps: [&[f32]; 5] = std::array::from_fn(|j| {
                    let r = clampi(2 * y as isize + j as isize - 2, ph);
                    &rows[r * nw..(r + 1) * nw]
                });
                for (x, d) in dst.iter_mut().enumerate() {
                    *d = binomial(taps.map(|t| t[x]));
                }
            }
            out.push(Level::new(nw, nh, next));
        }
        Pyramid { levels: out }
    }
}

/// KLT settings (a part of [`crate::VideoTrackParams`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Klt {
    /// Pyramid levels used (at most the pyramids' own).
    pub(crate) levels: usize,
    pub(crate) radius: usize,
    pub(crate) iterations: usize,
    pub(crate) epsilon_px: f64,
    pub(crate) fb_max_px: f64,
    pub(crate) residual_ratio: f64,
}

/// The outcome for one point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct KltPoint {
    /// Converged position in `J`, px.
    pub(crate) p: [f64; 2],
    /// `Z / |W|` at full resolution: `[zxx, zxy, zyy]` (intensity² per px²).
    pub(crate) z: [f64; 3],
    /// RMS of the mean-removed intensity difference over the window at the end.
    pub(crate) residual: f64,
    /// RMS of the template window's mean-removed intensity (its contrast).
    pub(crate) contrast: f64,
    /// Passed every check (in the frame, textured, consistent forward and backward, small
    /// residual).
    pub(crate) ok: bool,
}

struct Solve {
    p: [f64; 2],
    z: [f64; 3],
    residual: f64,
    contrast: f64,
    inside: bool,
}

/// The template and the current window of one point (three floats per sample), and the
/// interpolation's scratch rows.
#[derive(Default)]
struct Windows {
    tmpl: Vec<f32>,
    win: Vec<f32>,
    rows: Vec<f32>,
}

/// Sum of the intensities (every third float) of a window, in sample order.
fn intensity_sum(w: &[f32]) -> f32 {
    w.iter().step_by(3).fold(0.0, |s, v| s + v)
}

/// One direction: `q` in `from` → `p` in `to`, starting at `p0`.
fn track_one(
    from: &Pyramid,
    to: &Pyramid,
    q: [f64; 2],
    p0: [f64; 2],
    k: &Klt,
    w: &mut Windows,
) -> Solve {
    let side = 2 * k.radius + 1;
    let n = side * side;
    let rf = k.radius as f64;
    w.tmpl.resize(3 * n, 0.0);
    w.win.resize(3 * n, 0.0);
    let (tmpl, win, rows) = (&mut w.tmpl[..3 * n], &mut w.win[..3 * n], &mut w.rows);
    let mut p = p0;
    let nl = from.levels.len().min(to.levels.len()).min(k.levels.max(1));
    let mut out = Solve {
        p,
        z: [0.0; 3],
        residual: f64::INFINITY,
        contrast: 0.0,
        inside: false,
    };
    for l in (0..nl).rev() {
        let s = 0.5f64.powi(l as i32);
        let (a_lvl, b_lvl) = (&from.levels[l], &to.levels[l]);
        let ql = [q[0] * s, q[1] * s];
        let mut pl = [p[0] * s, p[1] * s];
        // Template window (fixed for the level).
        if !a_lvl.window(ql[0] - rf, ql[1] - rf, side, rows, tmpl) {
            if l == 0 {
                out.inside = false;
                return out;
            }
            continue;
        }
        let mean_a = intensity_sum(tmpl) / n as f32;
        // The template's mean-removed intensity and its contrast, fixed for the level.
        let mut contrast = 0.0f64;
        for a in tmpl.chunks_exact_mut(3) {
            a[0] -= mean_a;
            contrast += f64::from(a[0] * a[0]);
        }
        for it in 0..k.iterations.max(1) {
            if !b_lvl.window(pl[0] - rf, pl[1] - rf, side, rows, win) {
                if l == 0 {
                    out.inside = false;
                    return out;
                }
                break;
            }
            let mean_b = intensity_sum(win) / n as f32;
            let (mut zxx, mut zxy, mut zyy, mut ex, mut ey) = (0.0f64, 0.0f64, 0.0f64, 0.0, 0.0);
            let mut sq = 0.0f64; // sum of squared mean-removed differences
            for (a, b) in tmpl.chunks_exact(3).zip(win.chunks_exact(3)) {
                let gx = 0.5 * f64::from(a[1] + b[1]);
                let gy = 0.5 * f64::from(a[2] + b[2]);
                let diff = f64::from(a[0] - (b[0] - mean_b));
                zxx += gx * gx;
                zxy += gx * gy;
                zyy += gy * gy;
                ex += diff * gx;
                ey += diff * gy;
                sq += diff * diff;
            }
            let det = zxx * zyy - zxy * zxy;
            if l == 0 {
                let nn = n as f64;
                // Z at full resolution: the gradients at level l are per level-l pixel.
                out.z = [zxx / nn, zxy / nn, zyy / nn];
                out.residual = (sq / nn).sqrt();
                out.contrast = (contrast / nn).sqrt();
                out.inside = true;
            }
            if det <= 1e-12 * (zxx + zyy).powi(2).max(f64::MIN_POSITIVE) {
                break;
            }
            let d = [(zyy * ex - zxy * ey) / det, (zxx * ey - zxy * ex) / det];
            pl = [pl[0] + d[0], pl[1] + d[1]];
            if d[0].hypot(d[1]) < k.epsilon_px * s || it + 1 == k.iterations.max(1) {
                break;
            }
        }
        p = [pl[0] / s, pl[1] / s];
        out.p = p;
    }
    out
}

/// Scratch of [`track`] (its windows), kept between points to spare allocations.
#[derive(Default)]
pub(crate) struct Scratch(Windows);

/// Tracks `q` in `from` to `to`, starting at `p0`, with the forward–backward check.
pub(crate) fn track(
    from: &Pyramid,
    to: &Pyramid,
    q: [f64; 2],
    p0: [f64; 2],
    k: &Klt,
    scratch: &mut Scratch,
) -> KltPoint {
    let w = &mut scratch.0;
    let f = track_one(from, to, q, p0, k, w);
    let mut ok = f.inside && f.residual.is_finite();
    let (tr, det) = (f.z[0] + f.z[2], f.z[0] * f.z[2] - f.z[1] * f.z[1]);
    // Smallest eigenvalue of Z must not vanish against the largest (a flat or edge-only
    // window cannot be tracked on its own; it still constrains the model along its gradient).
    let disc = (0.25 * tr * tr - det).max(0.0).sqrt();
    let lmin = 0.5 * tr - disc;
    ok &= lmin > 1e-9;
    ok &= f.residual <= k.residual_ratio * f.contrast;
    if ok && k.fb_max_px.is_finite() {
        let b = track_one(to, from, f.p, q, k, w);
        ok &= b.inside && (b.p[0] - q[0]).hypot(b.p[1] - q[1]) <= k.fb_max_px;
    }
    KltPoint {
        p: f.p,
        z: f.z,
        residual: f.residual,
        contrast: f.contrast,
        ok,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pattern(shift: [f64; 2]) -> RgbImage {
        RgbImage::from_fn(160, 120, |x, y| {
            let (x, y) = (f64::from(x) - shift[0], f64::from(y) - shift[1]);
            let v = 0.5
                + 0.2 * (0.31 * x).sin() * (0.23 * y).cos()
                + 0.15 * (0.11 * x + 0.17 * y).sin()
                + 0.1 * (0.5 * x - 0.3 * y).cos();
            let g = (v.clamp(0.0, 1.0) * 255.0).round() as u8;
            image::Rgb([g, g, g])
        })
    }

    fn params() -> Klt {
        Klt {
            levels: 3,
            radius: 6,
            iterations: 20,
            epsilon_px: 0.005,
            fb_max_px: 0.5,
            residual_ratio: 0.5,
        }
    }

    #[test]
    fn recovers_a_subpixel_translation_from_far_away() {
        let shift = [5.3, -3.7];
        let a = Pyramid::new(&pattern([0.0, 0.0]), 3);
        let b = Pyramid::new(&pattern(shift), 3);
        for q in [[60.0, 50.0], [80.5, 70.25], [100.0, 60.0]] {
            let r = track(&a, &b, q, q, &params(), &mut Scratch::default());
            assert!(r.ok, "{r:?}");
            let err = (r.p[0] - q[0] - shift[0]).hypot(r.p[1] - q[1] - shift[1]);
            assert!(err < 0.1, "error {err} px at {q:?}");
        }
    }

    #[test]
    fn window_samples_are_bilinear_interpolations() {
        // Reference: each sample interpolated on its own from the level's four corners.
        let lvl = &Pyramid::new(&pattern([0.0, 0.0]), 1).levels[0];
        let w = lvl.width;
        let (x, y) = (57.37, 43.81);
        let (mut out, mut rows) = (vec![0.0f32; 3 * 81], Vec::new());
        assert!(lvl.window(x, y, 9, &mut rows, &mut out));
        let mut worst = 0.0f64;
        for r in 0..9 {
            for c in 0..9 {
                let (sx, sy) = (x + c as f64, y + r as f64);
                let (x0, y0) = (sx.floor() as usize, sy.floor() as usize);
                let (fx, fy) = (sx - x0 as f64, sy - y0 as f64);
                for ch in 0..3 {
                    let v = |x: usize, y: usize| f64::from(lvl.igg[3 * (y * w + x) + ch]);
                    let top = v(x0, y0) * (1.0 - fx) + v(x0 + 1, y0) * fx;
                    let bot = v(x0, y0 + 1) * (1.0 - fx) + v(x0 + 1, y0 + 1) * fx;
                    let want = top * (1.0 - fy) + bot * fy;
                    worst = worst.max((want - f64::from(out[3 * (r * 9 + c) + ch])).abs());
                }
            }
        }
        assert!(worst < 1e-6, "largest difference {worst}");
        // Outside: the top-left sample left of the image, the last one past its right edge.
        assert!(!lvl.window(-0.5, 50.0, 9, &mut rows, &mut out));
        assert!(!lvl.window(w as f64 - 8.5, 50.0, 9, &mut rows, &mut out));
        assert!(lvl.window(w as f64 - 9.5, 50.0, 9, &mut rows, &mut out));
    }

    #[test]
    fn flat_or_absent_texture_is_rejected() {
        let a = Pyramid::new(&pattern([0.0, 0.0]), 3);
        let flat = Pyramid::new(&RgbImage::from_pixel(160, 120, image::Rgb([90, 90, 90])), 3);
        let r = track(
            &a,
            &flat,
            [60.0, 50.0],
            [60.0, 50.0],
            &params(),
            &mut Scratch::default(),
        );
        assert!(!r.ok);
        // Off the frame.
        let r = track(
            &a,
            &a,
            [2.0, 50.0],
            [2.0, 50.0],
            &params(),
            &mut Scratch::default(),
        );
        assert!(!r.ok);
    }
}
