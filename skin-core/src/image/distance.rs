//! Exact Euclidean distance transforms of masks and the signed distance to the silhouette
//! boundary.
//!
//! These feed the silhouette-fitting methods: Vlasic 2010 §2.3.2 computes, on each camera's
//! image plane, a distance transform initialised at the contour pixels and evaluates it at
//! projected points; the signed version tells inside from outside. The transform itself is the exact linear-time algorithm of Felzenszwalb and
//! Huttenlocher ("Distance Transforms of Sampled Functions"), as implemented by
//! `imageproc::distance_transform::euclidean_squared_distance_transform`.
//!
//! Conventions: pixel `(x, y)` has its centre at `(x, y)` (see [`crate::image::Mask`]);
//! distances are in pixels between pixel centres and stored as `f32`.

use ::image::{ImageBuffer, Luma};
use imageproc::distance_transform::euclidean_squared_distance_transform;

use super::mask::Mask;
use crate::error::{Error, Result};

/// A single-channel `f32` image (distances in pixels, depths in metres...).
pub type GrayF32Image = ImageBuffer<Luma<f32>, Vec<f32>>;

/// Half a pixel: the distance from a pixel centre to the edge it shares with a 4-neighbour.
const HALF_PIXEL: f32 = 0.5;

fn require_pixels(mask: &Mask) -> Result<()> {
    if mask.is_zero_sized() {
        return Err(Error::Empty {
            what: "mask (zero width or height)",
        });
    }
    Ok(())
}

/// Exact Euclidean distance (pixels) from every pixel centre to the centre of the nearest
/// *set* pixel of `target` (0 on set pixels).
#[allow(
    clippy::expect_used,
    reason = "the transform writes width × height samples"
)]
fn edt_to_set(target: &Mask) -> GrayF32Image {
    let sq = euclidean_squared_distance_transform(&target.to_gray());
    let data: Vec<f32> = sq.as_raw().iter().map(|&d2| d2.sqrt() as f32).collect();
    // The buffer length is width * height by construction of `sq`.
    GrayF32Image::from_raw(target.width(), target.height(), data)
        .expect("EDT output has width * height samples")
}

/// Exact Euclidean distance, in pixels, from each pixel centre to the nearest foreground pixel
/// centre; 0 on foreground pixels.
///
/// # Errors
/// [`Error::Empty`] if the mask is zero-sized or has no foreground pixel (the distance would
/// be infinite everywhere).
///
/// # Example
/// ```
/// use skin_core::image::{distance_to_foreground, Mask};
/// let m = Mask::from_fn(5, 1, |x, _| x == 0);
/// let d = distance_to_foreground(&m)?;
/// assert_eq!(d.get_pixel(3, 0).0[0], 3.0);
/// # Ok::<(), skin_core::Error>(())
/// ```
pub fn distance_to_foreground(mask: &Mask) -> Result<GrayF32Image> {
    require_pixels(mask)?;
    if mask.is_empty() {
        return Err(Error::Empty {
            what: "mask foreground (distance to foreground of an all-background mask)",
        });
    }
    Ok(edt_to_set(mask))
}

/// Exact Euclidean distance, in pixels, from each pixel centre to the nearest background pixel
/// centre; 0 on background pixels. Pixels outside the image are *not* background.
///
/// # Errors
/// [`Error::Empty`] if the mask is zero-sized or has no background pixel.
pub fn distance_to_background(mask: &Mask) -> Result<GrayF32Image> {
    require_pixels(mask)?;
    if mask.is_full() {
        return Err(Error::Empty {
            what: "mask background (distance to background of an all-foreground mask)",
        });
    }
    Ok(edt_to_set(&mask.not()))
}

/// Signed distance, in pixels, from each pixel centre to the silhouette boundary: **negative
/// inside** (foreground), positive outside.
///
/// The boundary is taken to be the pixel edges between foreground and background pixels,
/// i.e. half-way between their centres:
///
/// * background pixel `p`: `sd(p) = d_fg(p) − ½`,
/// * foreground pixel `p`: `sd(p) = −(d_bg(p) − ½)`,
///
/// where `d_fg`, `d_bg` are the exact centre-to-centre distances of
/// [`distance_to_foreground`] and [`distance_to_background`]. Thus the two pixels either side
/// of a straight axis-aligned edge get `∓½`, `|sd| ≥ ½` everywhere, and `sd` is exact for
/// axis-aligned boundaries; elsewhere it over-estimates the distance to the true pixel-edge
/// boundary by less than `(√2 − 1)/2 ≈ 0.21` px (the nearest centre of the other class may sit
/// diagonally). The image border is not a boundary.
///
/// # Errors
/// [`Error::Empty`] if the mask is zero-sized, empty or full (no boundary exists).
#[allow(
    clippy::expect_used,
    reason = "the transform writes width × height samples"
)]
pub fn signed_distance(mask: &Mask) -> Result<GrayF32Image> {
    // The two transforms are independent; run them on two threads (results are identical
    // for any thread count).
    let (d_fg, d_bg) = rayon::join(
        || distance_to_foreground(mask),
        || distance_to_background(mask),
    );
    let (d_fg, d_bg) = (d_fg?, d_bg?);
    let data: Vec<f32> = d_fg
        .as_raw()
        .iter()
        .zip(d_bg.as_raw())
        .map(|(&f, &b)| {
            if f == 0.0 {
                -(b - HALF_PIXEL)
            } else {
                f - HALF_PIXEL
            }
        })
        .collect();
    // Same dimensions as the inputs by construction.
    Ok(GrayF32Image::from_raw(mask.width(), mask.height(), data)
        .expect("signed distance has width * height samples"))
}

/// The silhouette band lives here, beside the signed distance it is measured with, so that
/// `mask.rs` does not depend on this file.
impl Mask {
    /// The pixels within `radius_px` of the silhouette boundary, on either side: foreground
    /// pixels whose centre is at most `radius_px + ½` from the nearest background pixel
    /// centre, and background pixels at most `radius_px + ½` from the nearest foreground
    /// pixel centre. The `+ ½` places the boundary on the pixel edges between foreground and
    /// background (see [`signed_distance`]), so `radius_px = 0.5` selects the
    /// one-pixel layer on each side of a straight edge.
    ///
    /// This is the region of Sand et al. 2003 §6.2's silhouette error ("only pixels near the
    /// projected silhouette boundary"). The image border is not a silhouette boundary: an
    /// empty or full mask has an empty band.
    ///
    /// # Errors
    /// [`Error::InvalidParam`] if `radius_px` is negative or not finite.
    pub fn boundary_band(&self, radius_px: f64) -> Result<Mask> {
        crate::check::non_negative("radius_px", radius_px)?;
        if self.is_empty() || self.count() == self.pixel_count() {
            return Ok(Mask::new(self.width(), self.height()));
        }
        // Both classes are present, so the signed distance exists.
        let sd = signed_distance(self)?;
        let r = radius_px as f32;
        let flags: Vec<bool> = sd.as_raw().iter().map(|d| d.abs() <= r).collect();
        Mask::from_bools(self.width(), self.height(), &flags)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Brute-force distance from each pixel to the nearest pixel with `flag == want`.
    fn brute(mask: &Mask, want: bool) -> Vec<f32> {
        let (w, h) = mask.dimensions();
        let mut out = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let mut best = f64::INFINITY;
                for v in 0..h {
                    for u in 0..w {
                        if mask.get(u, v) == want {
                            let dx = f64::from(u) - f64::from(x);
                            let dy = f64::from(v) - f64::from(y);
                            best = best.min((dx * dx + dy * dy).sqrt());
                        }
                    }
                }
                out.push(best as f32);
            }
        }
        out
    }

    fn arb_mask() -> impl Strategy<Value = Mask> {
        (1u32..14, 1u32..14, 0.05f64..0.95).prop_flat_map(|(w, h, p)| {
            proptest::collection::vec(proptest::bool::weighted(p), (w * h) as usize)
                .prop_map(move |f| Mask::from_bools(w, h, &f).unwrap())
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(200))]
        #[test]
        fn edt_matches_brute_force(m in arb_mask()) {
            if !m.is_empty() {
                let d = distance_to_foreground(&m).unwrap();
                for (a, b) in d.as_raw().iter().zip(brute(&m, true)) {
                    prop_assert!((a - b).abs() < 1e-4, "{} vs {}", a, b);
                }
            }
            if !m.is_full() {
                let d = distance_to_background(&m).unwrap();
                for (a, b) in d.as_raw().iter().zip(brute(&m, false)) {
                    prop_assert!((a - b).abs() < 1e-4, "{} vs {}", a, b);
                }
            }
            if !m.is_empty() && !m.is_full() {
                let sd = signed_distance(&m).unwrap();
                for (i, (s, inside)) in sd.as_raw().iter().zip(m.iter()).enumerate() {
                    prop_assert!(s.abs() >= 0.5 - 1e-6);
                    prop_assert_eq!(*s < 0.0, inside, "pixel {}", i);
                }
            }
        }
    }

    #[test]
    fn signed_distance_of_a_half_plane_is_exact() {
        // Columns 0..5 foreground: the boundary is the line x = 4.5.
        let m = Mask::from_fn(10, 4, |x, _| x < 5);
        let sd = signed_distance(&m).unwrap();
        for y in 0..4 {
            for x in 0..10 {
                let want = x as f32 - 4.5;
                assert!((sd.get_pixel(x, y).0[0] - want).abs() < 1e-6);
            }
        }
    }

    #[test]
    fn empty_full_and_zero_sized_masks_are_errors() {
        let empty = Mask::new(4, 4);
        let full = empty.not();
        assert!(matches!(
            distance_to_foreground(&empty),
            Err(Error::Empty { .. })
        ));
        assert!(distance_to_background(&empty).is_ok());
        assert!(matches!(
            distance_to_background(&full),
            Err(Error::Empty { .. })
        ));
        assert!(distance_to_foreground(&full).is_ok());
        assert!(matches!(signed_distance(&empty), Err(Error::Empty { .. })));
        assert!(matches!(signed_distance(&full), Err(Error::Empty { .. })));
        let zero = Mask::new(0, 3);
        assert!(matches!(
            distance_to_foreground(&zero),
            Err(Error::Empty { .. })
        ));
        assert!(matches!(
            distance_to_background(&zero),
            Err(Error::Empty { .. })
        ));
    }

    #[test]
    fn mismatch_in_band_counts_only_band_pixels() {
        // Predicted: a 10x10 square; observed: the square shifted by one column.
        let pred = Mask::from_fn(30, 30, |x, y| {
            (10..20).contains(&x) && (10..20).contains(&y)
        });
        let obs = Mask::from_fn(30, 30, |x, y| {
            (11..21).contains(&x) && (10..20).contains(&y)
        });
        let band = pred.boundary_band(1.5).unwrap();
        let f_band = pred.mismatch_fraction(&obs, Some(&band)).unwrap();
        let f_all = pred.mismatch_fraction(&obs, None).unwrap();
        // 20 pixels differ, all inside the band; the band is much smaller than the image.
        assert_eq!(pred.xor(&obs).unwrap().and(&band).unwrap().count(), 20);
        assert!((f_all - 20.0 / 900.0).abs() < 1e-12);
        assert!((f_band - 20.0 / band.count() as f64).abs() < 1e-12);
        assert!(f_band > 5.0 * f_all);
    }

    #[test]
    fn boundary_band_layers() {
        let m = Mask::from_fn(20, 20, |x, y| (5..15).contains(&x) && (5..15).contains(&y));
        let b = m.boundary_band(0.5).unwrap();
        // 0.5 px: the inner ring (36 px) plus the outer 4-adjacent ring (40 px, corners excluded).
        assert_eq!(b.count(), 36 + 40);
        assert_eq!(m.inner_boundary().count(), 36);
        assert!(m.inner_boundary().and_not(&b).unwrap().is_empty());
        assert!(Mask::new(5, 5).boundary_band(2.0).unwrap().is_empty());
        assert!(Mask::new(5, 5).not().boundary_band(2.0).unwrap().is_empty());
        assert!(matches!(
            m.boundary_band(-1.0),
            Err(Error::InvalidParam { .. })
        ));
        assert!(matches!(
            m.boundary_band(f64::NAN),
            Err(Error::InvalidParam { .. })
        ));
    }
}
