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
    /// Intensity and gradients interleaved (one cache line per bilinear corner pair).
    igg: Vec<[f32; 3]>,
}

impl Level {
    fn new(width: usize, height: usize, img: Vec<f32>) -> Self {
        let mut gx = vec![0.0; img.len()];
        let mut gy = vec![0.0; img.len()];
        for y in 0..height {
            for x in 0..width {
                let i = y * width + x;
                let (xl, xr) = (x.saturating_sub(1), (x + 1).min(width - 1));
                let (yu, yd) = (y.saturating_sub(1), (y + 1).min(height - 1));
                gx[i] = (img[y * width + xr] - img[y * width + xl]) / (xr - xl).max(1) as f32;
                gy[i] = (img[yd * width + x] - img[yu * width + x]) / (yd - yu).max(1) as f32;
            }
        }
        let igg = img
            .iter()
            .zip(gx.iter().zip(&gy))
            .map(|(&i, (&x, &y))| [i, x, y])
            .collect();
        Level {
            width,
            height,
            img,
            igg,
        }
    }

    /// Bilinear samples of (intensity, gx, gy) at `(x, y)`; `None` outside the image.
    #[inline]
    fn sample(&self, x: f64, y: f64) -> Option<[f32; 3]> {
        if !(x >= 0.0 && y >= 0.0) {
            return None;
        }
        let (x0, y0) = (x as usize, y as usize);
        if x0 + 1 >= self.width || y0 + 1 >= self.height {
            return None;
        }
        let (fx, fy) = ((x - x0 as f64) as f32, (y - y0 as f64) as f32);
        let i = y0 * self.width + x0;
        let w = self.width;
        let (a, b, c, d) = (
            self.igg[i],
            self.igg[i + 1],
            self.igg[i + w],
            self.igg[i + w + 1],
        );
        Some(std::array::from_fn(|k| {
            let top = a[k] + fx * (b[k] - a[k]);
            let bot = c[k] + fx * (d[k] - c[k]);
            top + fy * (bot - top)
        }))
    }
}

/// A grey pyramid of one frame (level 0 full resolution).
#[derive(Clone, Debug)]
pub(crate) struct Pyramid {
    pub(crate) levels: Vec<Level>,
}

impl Pyramid {
    /// Luminance (Rec. 709 weights of the 8-bit values, in `[0, 1]`) and `levels` levels.
    pub(crate) fn new(frame: &RgbImage, levels: usize) -> Self {
        let (w, h) = (frame.width() as usize, frame.height() as usize);
        let img: Vec<f32> = frame
            .pixels()
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
            // Separable [1 4 6 4 1]/16 blur, sampled at even pixels.
            let k = [1.0f32, 4.0, 6.0, 4.0, 1.0];
            let clampi = |v: isize, n: usize| v.clamp(0, n as isize - 1) as usize;
            let mut rows = vec![0.0f32; nw * ph];
            for y in 0..ph {
                for x in 0..nw {
                    let mut s = 0.0;
                    for (j, kj) in k.iter().enumerate() {
                        s += kj * prev.img[y * pw + clampi(2 * x as isize + j as isize - 2, pw)];
                    }
                    rows[y * nw + x] = s / 16.0;
                }
            }
            let mut next = vec![0.0f32; nw * nh];
            for y in 0..nh {
                for x in 0..nw {
                    let mut s = 0.0;
                    for (j, kj) in k.iter().enumerate() {
                        s += kj * rows[clampi(2 * y as isize + j as isize - 2, ph) * nw + x];
                    }
                    next[y * nw + x] = s / 16.0;
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

/// One direction: `q` in `from` → `p` in `to`, starting at `p0`.
fn track_one(from: &Pyramid, to: &Pyramid, q: [f64; 2], p0: [f64; 2], k: &Klt) -> Solve {
    let r = k.radius as isize;
    let n = ((2 * r + 1) * (2 * r + 1)) as usize;
    let mut tmpl = vec![[0.0f32; 3]; n];
    let mut win: Vec<[f32; 3]> = Vec::with_capacity(n);
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
        let mut inside = true;
        let mut mean_a = 0.0f32;
        let mut idx = 0;
        for dy in -r..=r {
            for dx in -r..=r {
                match a_lvl.sample(ql[0] + dx as f64, ql[1] + dy as f64) {
                    Some(v) => tmpl[idx] = v,
                    None => inside = false,
                }
                mean_a += tmpl[idx][0];
                idx += 1;
            }
        }
        if !inside {
            if l == 0 {
                out.inside = false;
                return out;
            }
            continue;
        }
        mean_a /= n as f32;
        for it in 0..k.iterations.max(1) {
            let (mut zxx, mut zxy, mut zyy, mut ex, mut ey) = (0.0f64, 0.0f64, 0.0f64, 0.0, 0.0);
            let mut sq = 0.0f64; // sum of squared mean-removed differences
            let mut mean_b = 0.0f32;
            win.clear();
            let mut ok = true;
            for dy in -r..=r {
                for dx in -r..=r {
                    match b_lvl.sample(pl[0] + dx as f64, pl[1] + dy as f64) {
                        Some(v) => {
                            mean_b += v[0];
                            win.push(v);
                        }
                        None => {
                            ok = false;
                            win.push([0.0; 3]);
                        }
                    }
                }
            }
            if !ok {
                if l == 0 {
                    out.inside = false;
                    return out;
                }
                break;
            }
            mean_b /= n as f32;
            let mut contrast = 0.0f64;
            for (a, b) in tmpl.iter().zip(&win) {
                let gx = 0.5 * f64::from(a[1] + b[1]);
                let gy = 0.5 * f64::from(a[2] + b[2]);
                let da = a[0] - mean_a;
                let diff = f64::from(da - (b[0] - mean_b));
                zxx += gx * gx;
                zxy += gx * gy;
                zyy += gy * gy;
                ex += diff * gx;
                ey += diff * gy;
                sq += diff * diff;
                contrast += f64::from(da * da);
            }
            let det = zxx * zyy - zxy * zxy;
            let last = l == 0;
            if last {
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

/// Tracks `q` in `from` to `to`, starting at `p0`, with the forward–backward check.
pub(crate) fn track(from: &Pyramid, to: &Pyramid, q: [f64; 2], p0: [f64; 2], k: &Klt) -> KltPoint {
    let f = track_one(from, to, q, p0, k);
    let mut ok = f.inside && f.residual.is_finite();
    let (tr, det) = (f.z[0] + f.z[2], f.z[0] * f.z[2] - f.z[1] * f.z[1]);
    // Smallest eigenvalue of Z must not vanish against the largest (a flat or edge-only
    // window cannot be tracked on its own; it still constrains the model along its gradient).
    let disc = (0.25 * tr * tr - det).max(0.0).sqrt();
    let lmin = 0.5 * tr - disc;
    ok &= lmin > 1e-9;
    ok &= f.residual <= k.residual_ratio * f.contrast;
    if ok && k.fb_max_px.is_finite() {
        let b = track_one(to, from, f.p, q, k);
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
            let r = track(&a, &b, q, q, &params());
            assert!(r.ok, "{r:?}");
            let err = (r.p[0] - q[0] - shift[0]).hypot(r.p[1] - q[1] - shift[1]);
            assert!(err < 0.1, "error {err} px at {q:?}");
        }
    }

    #[test]
    fn flat_or_absent_texture_is_rejected() {
        let a = Pyramid::new(&pattern([0.0, 0.0]), 3);
        let flat = Pyramid::new(&RgbImage::from_pixel(160, 120, image::Rgb([90, 90, 90])), 3);
        let r = track(&a, &flat, [60.0, 50.0], [60.0, 50.0], &params());
        assert!(!r.ok);
        // Off the frame.
        let r = track(&a, &a, [2.0, 50.0], [2.0, 50.0], &params());
        assert!(!r.ok);
    }
}
