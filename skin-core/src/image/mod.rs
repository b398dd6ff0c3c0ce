//! Silhouette images: binary masks, background subtraction, contours with outward normals,
//! distance transforms and PNG IO of masks, depth maps and normal maps.
//!
//! | file | what | paper |
//! | --- | --- | --- |
//! | [`Mask`] (`mask.rs`) | bit-packed binary masks, set operations, bounding box, silhouette mismatch (optionally within a band) | Sand et al. 2003 §6.2 (silhouette error) |
//! | [`BackgroundModel`] (`background.rs`) | background mean and per-pixel threshold map from empty frames, foreground classification | Sand 2003 thesis §4.2, Sand et al. 2003 §4.2 |
//! | `cleanup.rs` | connected-component labelling ([`label_components`]), removal of small foreground specks, filling of small holes | Vlasic 2010 §3.2.1 |
//! | [`extract_contours`] (`contour.rs`) | borders with outward unit normals, arc-length resampling | Fua et al. §5.3, Vlasic 2010 §2.4.2 |
//! | [`signed_distance`] (`distance.rs`) | exact Euclidean distance transforms, signed distance to the boundary, the boundary band [`Mask::boundary_band`] | Vlasic 2010 §2.3.2; Sand et al. 2003 §6.2 (band) |
//! | [`sample_bilinear_with_gradient`] (`sample.rs`) | sub-pixel value and gradient of distance fields and depth maps | Vlasic 2010 §2.3.2 |
//! | `io.rs` | PNG IO: masks, 16-bit depth with [`DepthEncoding`], false-colour depth, normal maps | — |
//!
//! ## Conventions
//!
//! * **Pixel centres at integers**: pixel `(x, y)` has its centre at image coordinate
//!   `(x, y)`, `x` right, `y` down (OpenCV convention); it covers `[x−½, x+½] × [y−½, y+½]`.
//! * Masks: `true` = foreground (the performer). Pixels outside the image are background for
//!   neighbour look-ups and contour tracing, but the image border is never a silhouette
//!   boundary for distances.
//! * Signed distance: negative inside, positive outside, zero on the pixel edges between
//!   foreground and background ([`signed_distance`]).
//! * Intensities for background subtraction on `[0, 1]`; depth in metres with NaN, ±∞ and
//!   values ≤ 0 meaning "no data"; normals are unit vectors with NaN meaning "no data".
//!
//! Inside `skin-core` the external `image` crate is `::image`; this module is
//! `crate::image`.
//!
//! ## Example
//! ```
//! use skin_core::image::{extract_contours, signed_distance, ContourParams, Mask};
//! let m = Mask::from_fn(32, 32, |x, y| (x as f64 - 16.0).hypot(y as f64 - 16.0) < 10.0);
//! let sd = signed_distance(&m)?;
//! assert!(sd.get_pixel(16, 16).0[0] < -9.0);
//! let contours = extract_contours(&m, &ContourParams::default().with_sample_step_px(4.0))?;
//! assert_eq!(contours.len(), 1);
//! # Ok::<(), skin_core::Error>(())
//! ```

mod background;
mod cleanup;
mod contour;
mod distance;
mod io;
mod mask;
mod sample;

pub use background::{BackgroundFrame, BackgroundModel, BackgroundParams, Segmentation};
pub use cleanup::{
    fill_small_holes, label_components, remove_small_components, Components, Neighbourhood,
};
pub use contour::{extract_contours, Contour, ContourParams};
pub use distance::{distance_to_background, distance_to_foreground, signed_distance, GrayF32Image};
pub use io::{
    decode_depth_u16, depth_false_colour, encode_depth_u16, is_valid_depth, normals_rgb8,
    read_depth_png16, read_mask_png, read_normal_png, write_depth_false_colour_png,
    write_depth_png16, write_mask_png, write_normal_png, DepthEncoding, DepthRange, Gray16Image,
    NormalBits, Rgb16Image, DEPTH_NO_DATA, MASK_READ_THRESHOLD,
};
pub use mask::{Mask, PixelRect, MASK_FOREGROUND_GREY};
pub use sample::{sample_bilinear, sample_bilinear_with_gradient, BilinearSample};
