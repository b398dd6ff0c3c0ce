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
    /// Intensity, gx and gy interleaved, three floats per pixel (a window row is one
    /// contiguous run).
    igg: Vec<f32>,
}

impl Level {
    fn new(width: usize, height: usize, img: &[f32]) -> Self {
        let mut igg = vec![0.0f32; 3 * img.len()];
        // One-sided differences at the borders, central ones inside (each divided by its span;
        // `· 0.5` rounds as `/ 2`).
        for (y, out) in igg.chunks_exact_mut(3 * width).enumerate() {
            let (yu, yd) = (y.saturating_sub(1), (y + 1).min(height - 1));
            let span = (yd - yu).max(1) as f32;
            let row = &img[y * width..(y + 1) * width];
            let (up, down) = (
                &img[yu * width..(yu + 1) * width],
                &img[yd * width..(yd + 1) * width],
            );
            if width > 2 {
                // Pixels 1 ..= width − 2: `l`, `r` are their left and right neighbours.
                let inner = out[3..3 * (width - 1)]
                    .chunks_exact_mut(3)
                    .zip(&row[1..])
                    .zip(up[1..].iter().zip(&down[1..]))
                    .zip(row.iter().zip(&row[2..]));
                if span == 2.0 {
                    for (((o, &v), (&u, &d)), (&l, &r)) in inner {
                        o[0] = v;
                        o[1] = (r - l) * 0.5;
                        o[2] = (d - u) * 0.5;
                    }
                } else {
                    for (((o, &v), (&u, &d)), (&l, &r)) in inner {
                        o[0] = v;
                        o[1] = (r - l) * 0.5;
                        o[2] = (d - u) / span;
                    }
                }
            }
            for x in [0, width - 1] {
                let (xl, xr) = (x.saturating_sub(1), (x + 1).min(width - 1));
                let o = &mut out[3 * x..3 * x + 3];
                o[0] = row[x];
                o[1] = (row[xr] - row[xl]) / (xr - xl).max(1) as f32;
                o[2] = (down[x] - up[x]) / span;
            }
        }
        Level { width, height, igg }
    }

    /// Bilinear samples of (intensity, gx, gy) at the `n × n` pixel grid whose top-left
    /// sample is `(x, y)`, into `out` (row-major, three floats per sample; `rows` is
    /// scratch), and the sum of their intensities in sample order; `None` when a sample
    /// falls outside the image. The grid's offsets are whole pixels, so one pair of
    /// interpolation weights serves every sample: each of the `n + 1` image rows is
    /// interpolated horizontally once (one contiguous run), and each output row vertically
    /// from the two it lies between. (The intensity sum, a chain of dependent additions, is
    /// taken row by row, alongside the vector work of the next row.)
    fn window(
        &self,
        x: f64,
        y: f64,
        n: usize,
        rows: &mut Vec<f32>,
        out: &mut [f32],
    ) -> Option<f32> {
        if !(x >= 0.0 && y >= 0.0) {
            return None;
        }
        let (x0, y0) = (x as usize, y as usize);
        if x0 + n >= self.width || y0 + n >= self.height {
            return None;
        }
        let (fx, fy) = ((x - x0 as f64) as f32, (y - y0 as f64) as f32);
        let (i0, out) = (3 * (y0 * self.width + x0), &mut out[..3 * n * n]);
        // The usual window sizes as fixed-length rows (straight-line vector code).
        Some(match 3 * n {
            9 => self.window_rows::<9>(i0, fx, fy, out),
            15 => self.window_rows::<15>(i0, fx, fy, out),
            21 => self.window_rows::<21>(i0, fx, fy, out),
            27 => self.window_rows::<27>(i0, fx, fy, out),
            33 => self.window_rows::<33>(i0, fx, fy, out),
            39 => self.window_rows::<39>(i0, fx, fy, out),
            45 => self.window_rows::<45>(i0, fx, fy, out),
            len => {
                rows.resize(2 * len, 0.0);
                let (top, bottom) = rows.split_at_mut(len);
                self.window_pass(i0, fx, fy, top, bottom, out)
            }
        })
    }

    /// [`Level::window`] for rows of `L` floats (`n = L / 3` samples), the window's top-left
    /// pixel at `igg[i0]`: the same operations on fixed-length arrays.
    #[inline(always)]
    fn window_rows<const L: usize>(&self, i0: usize, fx: f32, fy: f32, out: &mut [f32]) -> f32 {
        #[inline(always)]
        fn horizontal<const L: usize>(igg: &[f32], i: usize, fx: f32) -> [f32; L] {
            let mut h = [0.0f32; L];
            for ((h, &a), &b) in h.iter_mut().zip(&igg[i..i + L]).zip(&igg[i + 3..i + 3 + L]) {
                *h = a + fx * (b - a);
            }
            h
        }
        let mut top = horizontal::<L>(&self.igg, i0, fx);
        let mut sum = 0.0f32;
        for (j, o) in out.chunks_exact_mut(L).enumerate() {
            let i = i0 + 3 * (j + 1) * self.width;
            let (a, b) = (&self.igg[i..i + L], &self.igg[i + 3..i + 3 + L]);
            for (((o, t), &a), &b) in o.iter_mut().zip(top.iter_mut()).zip(a).zip(b) {
                let h = a + fx * (b - a);
                *o = *t + fy * (h - *t);
                *t = h;
            }
            for v in o.iter().step_by(3) {
                sum += v;
            }
        }
        sum
    }

    /// [`Level::window`] for any row length: the same operations, `top` and `bottom` scratch
    /// rows as long as an output row.
    fn window_pass(
        &self,
        i0: usize,
        fx: f32,
        fy: f32,
        top: &mut [f32],
        bottom: &mut [f32],
        out: &mut [f32],
    ) -> f32 {
        let len = top.len();
        let horizontal = |i: usize, h: &mut [f32]| {
            let (a, b) = (&self.igg[i..i + len], &self.igg[i + 3..i + 3 + len]);
            for ((h, &a), &b) in h.iter_mut().zip(a).zip(b) {
                *h = a + fx * (b - a);
            }
        };
        horizontal(i0, top);
        let mut sum = 0.0f32;
        for (j, o) in out.chunks_exact_mut(len).enumerate() {
            horizontal(i0 + 3 * (j + 1) * self.width, bottom);
            for ((o, &t), &u) in o.iter_mut().zip(&*top).zip(&*bottom) {
                *o = t + fy * (u - t);
            }
            for v in o.iter().step_by(3) {
                sum += v;
            }
            top.copy_from_slice(bottom);
        }
        sum
    }
}

/// A grey pyramid of one frame (level 0 full resolution).
#[derive(Clone, Debug)]
pub(crate) struct Pyramid {
    pub(crate) levels: Vec<Level>,
}

/// One output sample of the [1 4 6 4 1]/16 blur from five taps (non-negative, so the sum
/// starts at the first tap).
#[inline]
fn binomial(t: [f32; 5]) -> f32 {
    (t[0] + 4.0 * t[1] + 6.0 * t[2] + 4.0 * t[3] + t[4]) / 16.0
}

/// The next pyramid level of the `pw × ph` intensity image `img`: the separable
/// [1 4 6 4 1]/16 blur sampled at even pixels (horizontal pass into `rows`, then vertical);
/// the image's border pixels repeat outside it.
fn downsample(img: &[f32], pw: usize, ph: usize, rows: &mut Vec<f32>) -> Vec<f32> {
    let (nw, nh) = (pw.div_ceil(2), ph.div_ceil(2));
    let clampi = |v: isize, n: usize| v.clamp(0, n as isize - 1) as usize;
    rows.clear();
    rows.resize(nw * ph, 0.0);
    for (src, dst) in img.chunks_exact(pw).zip(rows.chunks_exact_mut(nw)) {
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
        let [t0, t1, t2, t3, t4]: [&[f32]; 5] = std::array::from_fn(|j| {
            let r = clampi(2 * y as isize + j as isize - 2, ph);
            &rows[r * nw..(r + 1) * nw]
        });
        let taps = t0.iter().zip(t1).zip(t2.iter().zip(t3)).zip(t4);
        for (d, (((&a, &b), (&c, &e)), &f)) in dst.iter_mut().zip(taps) {
            *d = binomial([a, b, c, e, f]);
        }
    }
    next
}

impl Pyramid {
    /// Luminance (Rec. 709 weights of the 8-bit values, in `[0, 1]`) and `levels` levels.
    pub(crate) fn new(frame: &RgbImage, levels: usize) -> Self {
        let (mut w, mut h) = (frame.width() as usize, frame.height() as usize);
        // Each channel's weighted values from a table (the same products).
        let table = |weight: f32| -> [f32; 256] { std::array::from_fn(|v| weight * v as f32) };
        let (r, g, b) = (table(0.2126), table(0.7152), table(0.0722));
        let mut img: Vec<f32> = frame
            .as_raw()
            .chunks_exact(3)
            .map(|p| (r[usize::from(p[0])] + g[usize::from(p[1])] + b[usize::from(p[2])]) / 255.0)
            .collect();
        let mut out = vec![Level::new(w, h, &img)];
        let mut rows = Vec::new();
        while out.len() < levels.max(1) {
            let (nw, nh) = (w.div_ceil(2), h.div_ceil(2));
            if nw < 8 || nh < 8 {
                break;
            }
            img = downsample(&img, w, h, &mut rows);
            (w, h) = (nw, nh);
            out.push(Level::new(w, h, &img));
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

/// The template and the current window of one point (three floats per sample), the
/// interpolation's scratch rows, and the forward track's template at the coarsest level
/// before its mean is removed (`first`, and its intensity sum, `None` when it left the image):
/// the backward track's first window, sampled at the same place.
#[derive(Default)]
struct Windows {
    tmpl: Vec<f32>,
    win: Vec<f32>,
    rows: Vec<f32>,
    first: Vec<f32>,
    first_sum: Option<f32>,
}

/// What [`track_one`] does with [`Windows::first`].
#[derive(Clone, Copy, PartialEq)]
enum First {
    /// Keep the coarsest template (the forward track).
    Keep,
    /// Take it as the first window at the coarsest level (the backward track, which starts
    /// at the forward track's `q`).
    Take,
}

/// `Σ_W` of `[gx², gx gy, gy², diff gx, diff gy, diff²]` with `g` the mean of both windows'
/// gradients and `diff` the template's mean-removed intensity minus the window's
/// (`mean_b` removed), each sum in sample order. Six independent sums, kept in pairs so the
/// compiler puts each pair in one vector register (the same additions in the same order).
fn normal_sums(tmpl: &[f32], win: &[f32], mean_b: f32) -> [f64; 6] {
    let (mut p0, mut p1, mut p2) = ([0.0f64; 2], [0.0f64; 2], [0.0f64; 2]);
    for (a, b) in tmpl.chunks_exact(3).zip(win.chunks_exact(3)) {
        let gx = 0.5 * f64::from(a[1] + b[1]);
        let gy = 0.5 * f64::from(a[2] + b[2]);
        let diff = f64::from(a[0] - (b[0] - mean_b));
        p0 = [p0[0] + gx * gx, p0[1] + gx * gy];
        p1 = [p1[0] + gy * gy, p1[1] + diff * gx];
        p2 = [p2[0] + diff * gy, p2[1] + diff * diff];
    }
    [p0[0], p0[1], p1[0], p1[1], p2[0], p2[1]]
}

/// `|d| < eps` as `d[0].hypot(d[1]) < eps` decides it, without the `hypot` call unless
/// `|d|²` is within rounding of `eps²`.
fn shorter_than(d: [f64; 2], eps: f64) -> bool {
    let (n2, e2) = (d[0] * d[0] + d[1] * d[1], eps * eps);
    if n2 < e2 * (1.0 - 1e-9) {
        true
    } else if n2 > e2 * (1.0 + 1e-9) {
        false
    } else {
        d[0].hypot(d[1]) < eps
    }
}

/// One direction: `q` in `from` → `p` in `to`, starting at `p0`.
fn track_one(
    from: &Pyramid,
    to: &Pyramid,
    q: [f64; 2],
    p0: [f64; 2],
    k: &Klt,
    w: &mut Windows,
    first: First,
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
        let sum_a = a_lvl.window(ql[0] - rf, ql[1] - rf, side, rows, tmpl);
        if first == First::Keep && l + 1 == nl {
            w.first.clear();
            w.first.extend_from_slice(tmpl);
            w.first_sum = sum_a;
        }
        let Some(sum_a) = sum_a else {
            if l == 0 {
                out.inside = false;
                return out;
            }
            continue;
        };
        let mean_a = sum_a / n as f32;
        // The template's mean-removed intensity and its contrast, fixed for the level.
        let mut contrast = 0.0f64;
        for a in tmpl.chunks_exact_mut(3) {
            a[0] -= mean_a;
            contrast += f64::from(a[0] * a[0]);
        }
        for it in 0..k.iterations.max(1) {
            let sum_b = if first == First::Take && l + 1 == nl && it == 0 {
                if w.first_sum.is_some() {
                    win.copy_from_slice(&w.first);
                }
                w.first_sum
            } else {
                b_lvl.window(pl[0] - rf, pl[1] - rf, side, rows, win)
            };
            let Some(sum_b) = sum_b else {
                if l == 0 {
                    out.inside = false;
                    return out;
                }
                break;
            };
            let mean_b = sum_b / n as f32;
            let [zxx, zxy, zyy, ex, ey, sq] = normal_sums(tmpl, win, mean_b);
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
            if shorter_than(d, k.epsilon_px * s) || it + 1 == k.iterations.max(1) {
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
    let f = track_one(from, to, q, p0, k, w, First::Keep);
    let mut ok = f.inside && f.residual.is_finite();
    let (tr, det) = (f.z[0] + f.z[2], f.z[0] * f.z[2] - f.z[1] * f.z[1]);
    // Smallest eigenvalue of Z must not vanish against the largest (a flat or edge-only
    // window cannot be tracked on its own; it still constrains the model along its gradient).
    let disc = (0.25 * tr * tr - det).max(0.0).sqrt();
    let lmin = 0.5 * tr - disc;
    ok &= lmin > 1e-9;
    ok &= f.residual <= k.residual_ratio * f.contrast;
    if ok && k.fb_max_px.is_finite() {
        // Starts at `q`, so its first window at the coarsest level is the forward template.
        let b = track_one(to, from, f.p, q, k, w, First::Take);
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
        // 9 × 9 takes the fixed-length rows, 17 × 17 the general ones.
        for n in [9, 17] {
            let (mut out, mut rows) = (vec![0.0f32; 3 * n * n], Vec::new());
            let sum = lvl.window(x, y, n, &mut rows, &mut out).unwrap();
            let mut worst = 0.0f64;
            for r in 0..n {
                for c in 0..n {
                    let (sx, sy) = (x + c as f64, y + r as f64);
                    let (x0, y0) = (sx.floor() as usize, sy.floor() as usize);
                    let (fx, fy) = (sx - x0 as f64, sy - y0 as f64);
                    for ch in 0..3 {
                        let v = |x: usize, y: usize| f64::from(lvl.igg[3 * (y * w + x) + ch]);
                        let top = v(x0, y0) * (1.0 - fx) + v(x0 + 1, y0) * fx;
                        let bot = v(x0, y0 + 1) * (1.0 - fx) + v(x0 + 1, y0 + 1) * fx;
                        let want = top * (1.0 - fy) + bot * fy;
                        worst = worst.max((want - f64::from(out[3 * (r * n + c) + ch])).abs());
                    }
                }
            }
            assert!(worst < 1e-6, "{n} × {n}: largest difference {worst}");
            // The intensity sum is the samples' own, added in sample order.
            let want = out.iter().step_by(3).fold(0.0f32, |s, v| s + v);
            assert_eq!(sum.to_bits(), want.to_bits(), "{n} × {n}");
            // Outside: the top-left sample left of the image, the last one past its right
            // edge.
            assert!(lvl.window(-0.5, 50.0, n, &mut rows, &mut out).is_none());
            let right = (w - n) as f64;
            assert!(lvl
                .window(right + 0.5, 50.0, n, &mut rows, &mut out)
                .is_none());
            assert!(lvl
                .window(right - 0.5, 50.0, n, &mut rows, &mut out)
                .is_some());
        }
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
