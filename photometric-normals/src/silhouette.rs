//! Silhouettes by background subtraction plus chroma keying, with small foreground holes
//! filled by comparing colour statistics inside and outside the hole (Vlasic 2010 §3.2.1).
//!
//! The thesis: "We use a combination of background subtraction and chroma-keying to
//! automatically extract approximate silhouettes. […] it is important that the silhouettes not
//! contain spurious holes, so small gaps in the foreground are detected and filled by comparing
//! color statistics (i.e., average and variance) inside and outside the hole." No thresholds
//! are given; ours are documented on [`SilhouetteParams`].
//!
//! * **Background subtraction**: `skin_core::image::BackgroundModel` learned from frames of the
//!   empty backdrop (per-pixel mean, threshold `max(t_min, k·σ)`); a pixel far from the mean is
//!   a foreground candidate.
//! * **Chroma key**: a candidate whose chromaticity `c = rgb / (r + g + b)` lies within
//!   [`SilhouetteParams::key_tolerance`] of the backdrop's chromaticity at that pixel is
//!   backdrop after all — this removes the performer's shadow on the backdrop and shading
//!   changes of the backdrop, which change its brightness but not its hue. Pixels darker than
//!   [`SilhouetteParams::min_key_brightness`] have no reliable hue and are never keyed.
//! * **Clean-up**: foreground specks are removed (`remove_small_components`); then every
//!   enclosed background component ("hole") of at most [`SilhouetteParams::max_hole_px`]
//!   pixels is compared with the backdrop outside the performer at the same place: when the
//!   mean and variance of its chromaticity agree with the backdrop's, it is a real gap (e.g.
//!   between an arm and the torso) and stays open; otherwise it is a patch of the performer
//!   that came close to the backdrop's colour, and it is filled. (A hole of the size-only
//!   clean-up, `fill_small_holes`, would close real gaps too.)

use image::Rgb32FImage;
use serde::{Deserialize, Serialize};
use skin_core::image::{
    label_components, remove_small_components, BackgroundModel, BackgroundParams, Mask,
    Neighbourhood,
};

use crate::{Error, Result};

/// Parameters of [`extract_silhouette`]. The thesis gives no values; ours are documented per
/// field.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SilhouetteParams {
    /// Background subtraction (skin-core's per-pixel model: `k_sigma` = 3, `min_threshold` =
    /// 0.1 on a `[0, 1]` scale). Its own clean-up is not used: specks and holes are handled
    /// here, after the chroma key.
    pub background: BackgroundParams,
    /// Largest distance between a pixel's chromaticity `rgb / (r + g + b)` and the backdrop's
    /// for the pixel to be keyed as backdrop, dimensionless. Default 0.08 (ours: the sensor
    /// noise of a half-shadowed green backdrop moves its chromaticity by ≈ 0.02, skin and
    /// dark cloth differ from green by > 0.3).
    pub key_tolerance: f32,
    /// Pixels whose `r + g + b` is below this (linear intensity units) have no reliable hue and
    /// are never keyed. Default 0.05 (ours; ten times the studio's sensor noise σ = 0.005).
    pub min_key_brightness: f32,
    /// Foreground 8-connected components smaller than this are removed, pixels. Default 16
    /// (skin-core's default).
    pub min_component_px: usize,
    /// Largest enclosed background component examined as a possible spurious hole, pixels.
    /// Default 400 (ours: "small gaps", about a 20 × 20 px patch).
    pub max_hole_px: usize,
    /// Largest distance between the mean chromaticity inside a hole and the backdrop's at the
    /// same pixels for the hole to be a real gap, dimensionless. Default 0.04 (ours: half the
    /// key tolerance).
    pub hole_mean_tolerance: f32,
    /// Largest ratio of the chromaticity variance inside a hole to the backdrop's (its
    /// spatial variance plus sensor noise) for the hole to be a real gap. Default 4 (ours).
    pub hole_variance_ratio: f32,
}

impl Default for SilhouetteParams {
    fn default() -> Self {
        SilhouetteParams {
            background: BackgroundParams::default(),
            key_tolerance: 0.08,
            min_key_brightness: 0.05,
            min_component_px: 16,
            max_hole_px: 400,
            hole_mean_tolerance: 0.04,
            hole_variance_ratio: 4.0,
        }
    }
}

impl SilhouetteParams {
    /// Sets [`SilhouetteParams::key_tolerance`].
    pub fn with_key_tolerance(mut self, t: f32) -> Self {
        self.key_tolerance = t;
        self
    }
    /// Sets [`SilhouetteParams::max_hole_px`] (0 disables hole filling).
    pub fn with_max_hole_px(mut self, px: usize) -> Self {
        self.max_hole_px = px;
        self
    }
    /// Sets [`SilhouetteParams::background`].
    pub fn with_background(mut self, b: BackgroundParams) -> Self {
        self.background = b;
        self
    }

    fn validate(&self) -> Result<()> {
        skin_core::check::non_negative("key_tolerance", f64::from(self.key_tolerance))?;
        skin_core::check::non_negative("min_key_brightness", f64::from(self.min_key_brightness))?;
        skin_core::check::non_negative("hole_mean_tolerance", f64::from(self.hole_mean_tolerance))?;
        skin_core::check::positive("hole_variance_ratio", f64::from(self.hole_variance_ratio))?;
        Ok(())
    }
}

/// The empty backdrop of one camera: the background-subtraction model and the backdrop's
/// chromaticity per pixel. Learned from frames of the empty scene ([`Backdrop::learn`]).
#[derive(Clone, Debug)]
pub struct Backdrop {
    model: BackgroundModel,
    /// Per-pixel mean colour of the backdrop.
    mean: Vec<[f32; 3]>,
    /// Per-pixel chromaticity of the mean.
    chroma: Vec<[f32; 3]>,
}

fn chromaticity(p: [f32; 3]) -> [f32; 3] {
    let s = p[0] + p[1] + p[2];
    if s > 0.0 {
        [p[0] / s, p[1] / s, p[2] / s]
    } else {
        [1.0 / 3.0; 3]
    }
}

fn dist2(a: [f32; 3], b: [f32; 3]) -> f32 {
    (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)
}

impl Backdrop {
    /// Learns the backdrop from frames of the empty scene (at least one; several give the
    /// per-pixel noise).
    ///
    /// # Errors
    /// [`Error::Empty`] for no frames, size or NaN errors of the frames (through skin-core's
    /// background model), [`Error::InvalidParam`] for bad parameters.
    pub fn learn(frames: &[Rgb32FImage], params: &SilhouetteParams) -> Result<Self> {
        params.validate()?;
        if frames.is_empty() {
            return Err(Error::Empty {
                what: "backdrop frames",
            });
        }
        let model = BackgroundModel::learn(frames, &params.background.without_cleanup())?;
        let mean: Vec<[f32; 3]> = model
            .mean()
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2]])
            .collect();
        let chroma = mean.iter().map(|&m| chromaticity(m)).collect();
        Ok(Backdrop {
            model,
            mean,
            chroma,
        })
    }

    /// `(width, height)` of the camera's images.
    pub fn dimensions(&self) -> (u32, u32) {
        self.model.dimensions()
    }
}

/// A silhouette and what each stage did.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Silhouette {
    /// The foreground mask.
    pub mask: Mask,
    /// Pixels background subtraction called foreground.
    pub subtracted_px: usize,
    /// Of those, pixels the chroma key returned to the backdrop.
    pub keyed_px: usize,
    /// Holes filled (statistics unlike the backdrop's).
    pub holes_filled: usize,
    /// Pixels added by filling them.
    pub filled_px: usize,
    /// Small holes left open (statistics like the backdrop's: real gaps).
    pub holes_kept: usize,
}

/// Mean and variance (summed over the three chromaticity channels) of a set of pixels.
fn stats(values: impl Iterator<Item = [f32; 3]>) -> Option<([f64; 3], f64)> {
    let (mut n, mut s, mut s2) = (0usize, [0f64; 3], 0f64);
    for v in values {
        n += 1;
        for c in 0..3 {
            s[c] += f64::from(v[c]);
            s2 += f64::from(v[c]).powi(2);
        }
    }
    if n == 0 {
        return None;
    }
    let nf = n as f64;
    let mu = [s[0] / nf, s[1] / nf, s[2] / nf];
    let var = (s2 / nf - mu.iter().map(|m| m * m).sum::<f64>()).max(0.0);
    Some((mu, var))
}

/// Whether a hole's chromaticity statistics (mean, variance) agree with the backdrop's at
/// the same pixels: means within [`SilhouetteParams::hole_mean_tolerance`] and variance at
/// most [`SilhouetteParams::hole_variance_ratio`] times the backdrop's (a textured patch of
/// the performer has a larger spread than the backdrop's sensor noise).
fn looks_like_backdrop(
    inside: ([f64; 3], f64),
    back: ([f64; 3], f64),
    params: &SilhouetteParams,
) -> bool {
    let d2: f64 = (0..3).map(|c| (inside.0[c] - back.0[c]).powi(2)).sum();
    let floor = 1e-4; // (0.01)²: chromaticity spread below which variances are not compared
    d2 <= f64::from(params.hole_mean_tolerance).powi(2)
        && inside.1 + floor <= f64::from(params.hole_variance_ratio) * (back.1 + floor)
}

/// The silhouette of one frame against its camera's [`Backdrop`]: background subtraction,
/// chroma key, speck removal and statistical hole filling (§3.2.1, see the module docs).
///
/// # Errors
/// [`Error::SizeMismatch`] if the frame's size differs from the backdrop's, [`Error::NonFinite`]
/// for NaN or infinite samples (both through skin-core), [`Error::InvalidParam`] for bad
/// parameters.
pub fn extract_silhouette(
    backdrop: &Backdrop,
    frame: &Rgb32FImage,
    params: &SilhouetteParams,
) -> Result<Silhouette> {
    params.validate()?;
    let subtracted = backdrop.model.classify(frame)?.mask;
    let (w, h) = subtracted.dimensions();
    let px = |i: usize| -> [f32; 3] {
        let s = &frame.as_raw()[3 * i..3 * i + 3];
        [s[0], s[1], s[2]]
    };
    let tol2 = params.key_tolerance * params.key_tolerance;
    let mut flags = subtracted.to_bools();
    let subtracted_px = flags.iter().filter(|&&f| f).count();
    let mut keyed_px = 0;
    for (i, f) in flags.iter_mut().enumerate() {
        if !*f {
            continue;
        }
        let p = px(i);
        if p[0] + p[1] + p[2] >= params.min_key_brightness
            && dist2(chromaticity(p), backdrop.chroma[i]) <= tol2
        {
            *f = false;
            keyed_px += 1;
        }
    }
    let keyed = Mask::from_bools(w, h, &flags)?;
    let cleaned = remove_small_components(&keyed, params.min_component_px)?;
    let (mask, holes_filled, filled_px, holes_kept) =
        fill_holes(&cleaned, frame, backdrop, params)?;
    Ok(Silhouette {
        mask,
        subtracted_px,
        keyed_px,
        holes_filled,
        filled_px,
        holes_kept,
    })
}

/// Fills the enclosed background components of at most `max_hole_px` pixels whose colour
/// statistics differ from the backdrop's. Returns
/// (the filled mask, holes filled, pixels filled, small holes kept).
fn fill_holes(
    mask: &Mask,
    frame: &Rgb32FImage,
    backdrop: &Backdrop,
    params: &SilhouetteParams,
) -> Result<(Mask, usize, usize, usize)> {
    let chroma_at = |i: usize| -> [f32; 3] {
        let s = &frame.as_raw()[3 * i..3 * i + 3];
        chromaticity([s[0], s[1], s[2]])
    };
    // The 4-connected background components (holes have the dual of the foreground's
    // 8-connectivity).
    let holes = label_components(mask, false, Neighbourhood::Four)?;
    let mut fg = mask.to_bools();
    let (mut filled, mut filled_px, mut kept) = (0, 0, 0);
    for (k, component) in holes.members().into_iter().enumerate() {
        if holes.touches_border[k] || component.len() > params.max_hole_px {
            continue;
        }
        let inside = stats(component.iter().map(|&i| chroma_at(i)));
        let back = stats(component.iter().map(|&i| backdrop.chroma[i]))
            .map(|(mu, var)| (mu, var + stats_noise(backdrop, &component)));
        let (Some(inside), Some(back)) = (inside, back) else {
            continue;
        };
        if !looks_like_backdrop(inside, back, params) {
            for &i in &component {
                fg[i] = true;
            }
            filled += 1;
            filled_px += component.len();
        } else {
            kept += 1;
        }
    }
    Ok((
        Mask::from_bools(mask.width(), mask.height(), &fg)?,
        filled,
        filled_px,
        kept,
    ))
}

/// Mean chromaticity variance of the backdrop's sensor noise over some pixels: the model's
/// per-pixel deviation σ divided by the brightness `r + g + b` (a first-order propagation).
fn stats_noise(backdrop: &Backdrop, pixels: &[usize]) -> f64 {
    let dev = backdrop.model.deviation_map();
    let raw = dev.as_raw();
    let n = pixels.len().max(1) as f64;
    pixels
        .iter()
        .map(|&i| {
            let m = backdrop.mean[i];
            let s = f64::from(m[0] + m[1] + m[2]).max(1e-3);
            (f64::from(raw[i]) / s).powi(2)
        })
        .sum::<f64>()
        / n
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::Rgb;

    /// A deterministic noise in [−a, a] (SplitMix64 of the pixel, stream `f`).
    fn noise(x: u32, y: u32, f: u32, a: f32) -> f32 {
        let u = skin_core::random::SplitMix64::new(u64::from(f))
            .uniform_at(u64::from(y) * 4096 + u64::from(x));
        (u as f32 * 2.0 - 1.0) * a
    }

    const GREEN: [f32; 3] = [0.06, 0.35, 0.09];

    fn plate(f: u32) -> Rgb32FImage {
        Rgb32FImage::from_fn(64, 64, |x, y| {
            let g = 0.8 + 0.4 * x as f32 / 64.0;
            Rgb([0, 1, 2].map(|c| GREEN[c] * g + noise(x, y, 3 * f + c as u32, 0.01)))
        })
    }

    /// A person (rectangle 20–44 × 10–60) with a closed loop of the arm leaving a real gap
    /// (30–34 × 20–24 shows the backdrop), a green-grey print on the shirt (35–40 × 40–45)
    /// that background subtraction misses, and the person's shadow on the backdrop to the right.
    fn scene() -> (Rgb32FImage, Mask) {
        let truth = Mask::from_fn(64, 64, |x, y| {
            (20..44).contains(&x)
                && (10..60).contains(&y)
                && !((30..34).contains(&x) && (20..24).contains(&y))
        });
        let b = plate(99);
        let img = Rgb32FImage::from_fn(64, 64, |x, y| {
            if truth.get(x, y) {
                if (35..41).contains(&x) && (40..46).contains(&y) {
                    // A green-grey print on the shirt within background subtraction's
                    // threshold of the backdrop: a spurious hole.
                    let p = b.get_pixel(x, y).0;
                    Rgb([p[0] + 0.05, p[1] - 0.03, p[2] + 0.04 + noise(x, y, 8, 0.02)])
                } else {
                    Rgb([0.5 + noise(x, y, 7, 0.02), 0.3, 0.25])
                }
            } else if (44..56).contains(&x) && (10..60).contains(&y) {
                let p = b.get_pixel(x, y).0;
                Rgb(p.map(|v| v * 0.45))
            } else {
                *b.get_pixel(x, y)
            }
        });
        (img, truth)
    }

    #[test]
    fn key_removes_the_shadow_and_holes_are_filled_only_where_the_colour_says_so() {
        let plates: Vec<_> = (0..4).map(plate).collect();
        let params = SilhouetteParams::default();
        let backdrop = Backdrop::learn(&plates, &params).unwrap();
        let (img, truth) = scene();
        let s = extract_silhouette(&backdrop, &img, &params).unwrap();
        assert_eq!(s.mask.xor(&truth).unwrap().count(), 0, "{s:?}");
        assert!(s.keyed_px >= 12 * 50, "the shadow is keyed: {}", s.keyed_px);
        assert_eq!((s.holes_filled, s.holes_kept), (1, 1));
        // Size-only hole filling would close the real gap; without the key the shadow stays.
        let no_key = extract_silhouette(&backdrop, &img, &params.with_key_tolerance(0.0)).unwrap();
        assert!(no_key.mask.and_not(&truth).unwrap().count() >= 12 * 50);
    }

    #[test]
    fn bad_input_is_an_error() {
        let params = SilhouetteParams::default();
        assert!(matches!(
            Backdrop::learn(&[], &params),
            Err(Error::Empty { .. })
        ));
        let backdrop = Backdrop::learn(&[plate(0)], &params).unwrap();
        let small = Rgb32FImage::new(32, 64);
        assert!(extract_silhouette(&backdrop, &small, &params).is_err());
        let mut nan = plate(1);
        nan.put_pixel(3, 3, Rgb([f32::NAN, 0.0, 0.0]));
        assert!(extract_silhouette(&backdrop, &nan, &params).is_err());
        assert!(
            extract_silhouette(&backdrop, &plate(1), &params.with_key_tolerance(-1.0)).is_err()
        );
    }
}
