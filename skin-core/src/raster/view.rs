//! The rendered buffers of one view and their conversion to `image` buffers.

use image::{ImageBuffer, Luma, Pixel, Rgb32FImage};
use serde::{Deserialize, Serialize};

use crate::image::Mask;
use crate::{Error, Result};

/// Triangle id of a pixel that sees no surface.
pub const NO_TRIANGLE: u32 = u32::MAX;

/// The ground-truth buffers of one camera view, row-major (`index = y·width + x`), pixel
/// centres at integer coordinates (the [`crate::camera::Intrinsics`] convention). A buffer that
/// was not requested in [`super::Buffers`] is empty.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct RenderedView {
    /// Image width, px.
    pub width: u32,
    /// Image height, px.
    pub height: u32,
    /// Silhouette: 1 where the pixel ray hits the mesh, 0 elsewhere.
    pub mask: Vec<u8>,
    /// Distance from the camera centre to the visible surface along the pixel ray, m;
    /// `f32::INFINITY` on background.
    pub depth_m: Vec<f32>,
    /// Camera-frame z (depth along the optical axis) of the visible surface, m;
    /// `f32::INFINITY` on background.
    pub camera_z_m: Vec<f32>,
    /// Unit outward surface normal in the camera frame (x right, y down, z forward), not flipped
    /// towards the camera (a visible back face of an open mesh has `z > 0`); zero on background.
    pub normal_camera: Vec<[f32; 3]>,
    /// Visible mesh face, [`NO_TRIANGLE`] on background.
    pub triangle: Vec<u32>,
    /// Perspective-correct barycentric weights `(λ₁, λ₂)` of face corners 1 and 2 (corner 0 has
    /// `1 − λ₁ − λ₂`) of the visible point; zero on background.
    pub bary: Vec<[f32; 2]>,
    /// Number of pixels that see the mesh.
    pub covered_pixels: usize,
}

fn missing(what: &'static str) -> Error {
    Error::Empty { what }
}

/// A `width × height` image of row-major `samples` (channels interleaved): the one conversion
/// of a rendered buffer, moved rather than copied (used by [`RenderedView`]'s image methods and
/// by the studio's per-view ground truth).
///
/// # Errors
/// [`Error::SizeMismatch`] naming `what` unless there are `width · height · channels` samples.
pub fn buffer_image<P: Pixel>(
    width: u32,
    height: u32,
    samples: Vec<P::Subpixel>,
    what: &'static str,
) -> Result<ImageBuffer<P, Vec<P::Subpixel>>> {
    let got = samples.len();
    ImageBuffer::from_raw(width, height, samples).ok_or(Error::SizeMismatch {
        what,
        expected: width as usize * height as usize * usize::from(P::CHANNEL_COUNT),
        got,
    })
}

impl RenderedView {
    /// Number of pixels.
    pub fn pixel_count(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// The silhouette as a [`Mask`] (all background if the mask buffer was not rendered).
    pub fn silhouette(&self) -> Mask {
        if self.mask.len() != self.pixel_count() {
            return Mask::new(self.width, self.height);
        }
        Mask::from_flags(self.width, self.height, self.mask.iter().map(|&m| m != 0))
    }

    /// Row-major index of pixel `(x, y)`.
    pub fn index(&self, x: u32, y: u32) -> usize {
        y as usize * self.width as usize + x as usize
    }

    /// Depth along the ray as a float image (background `+∞`).
    ///
    /// # Errors
    /// [`Error::Empty`] if depth was not rendered.
    pub fn depth_image(&self) -> Result<ImageBuffer<Luma<f32>, Vec<f32>>> {
        if self.depth_m.is_empty() {
            return Err(missing("depth buffer (enable Buffers::depth)"));
        }
        buffer_image(
            self.width,
            self.height,
            self.depth_m.clone(),
            "depth buffer",
        )
    }

    /// Camera-frame normals as a float RGB image (x, y, z).
    ///
    /// # Errors
    /// [`Error::Empty`] if normals were not rendered.
    pub fn normal_image(&self) -> Result<Rgb32FImage> {
        if self.normal_camera.is_empty() {
            return Err(missing("normal buffer (enable Buffers::normal)"));
        }
        let data = self.normal_camera.iter().flatten().copied().collect();
        buffer_image(self.width, self.height, data, "normal buffer")
    }
}
