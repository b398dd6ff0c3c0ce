//! Per-view depth maps: the one currency of the reconstruction stages of §3.3 — proxies
//! rendered per camera, single-view integration (Eq. 3.3), matching offsets (Eq. 3.4) and
//! volumetric merging all read and write a [`DepthMap`].
//!
//! Depth is the **distance from the camera centre along the pixel's unit ray** (what
//! [`Camera::ray`] returns for the pixel), not camera z: Eq. 3.3 integrates depth along each
//! pixel ray, and the rasteriser's [`RenderedView::depth_m`] uses the same definition. Pixels
//! have integer coordinates at their centres (the OpenCV convention of `skin_core::camera`).

use skin_core::camera::Camera;
use skin_core::math::{DVec2, DVec3};
use skin_core::raster::RenderedView;

use crate::{Error, Result};

/// One camera's depth map: `depth_m[y * width + x]` is the distance (m) from the camera centre
/// along pixel `(x, y)`'s ray to the surface, `NaN` where the view has no surface.
#[derive(Debug, Clone, PartialEq)]
pub struct DepthMap {
    /// Image width, px.
    pub width: u32,
    /// Image height, px.
    pub height: u32,
    /// Row-major depths along the pixel rays, m; `NaN` = no surface.
    pub depth_m: Vec<f64>,
}

impl DepthMap {
    /// A depth map from row-major depths.
    ///
    /// # Errors
    /// [`Error::Empty`] for a zero size, [`Error::SizeMismatch`] for a length that is not
    /// `width × height`, [`Error::InvalidParam`] for a depth that is neither `NaN` (no surface)
    /// nor finite and positive.
    pub fn new(width: u32, height: u32, depth_m: Vec<f64>) -> Result<Self> {
        if width == 0 || height == 0 {
            return Err(Error::Empty { what: "depth map" });
        }
        let pixels = width as usize * height as usize;
        if depth_m.len() != pixels {
            return Err(Error::SizeMismatch {
                what: "depth map pixels",
                expected: pixels,
                got: depth_m.len(),
            });
        }
        if let Some(i) = depth_m
            .iter()
            .position(|d| !(d.is_nan() || (d.is_finite() && *d > 0.0)))
        {
            return Err(Error::InvalidParam {
                name: "depth_m",
                reason: format!(
                    "pixel {i} is {}: must be NaN (no surface) or finite and > 0",
                    depth_m[i]
                ),
            });
        }
        Ok(Self {
            width,
            height,
            depth_m,
        })
    }

    /// A map with no surface anywhere.
    ///
    /// # Errors
    /// [`Error::Empty`] for a zero size.
    pub fn empty(width: u32, height: u32) -> Result<Self> {
        Self::new(
            width,
            height,
            vec![f64::NAN; width as usize * height as usize],
        )
    }

    /// The rasteriser's depth buffer as a depth map (background becomes `NaN`).
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if the view was rendered without its depth buffer.
    pub fn from_view(view: &RenderedView) -> Result<Self> {
        let depth = view
            .depth_m
            .iter()
            .map(|&d| {
                if d.is_finite() && d > 0.0 {
                    f64::from(d)
                } else {
                    f64::NAN
                }
            })
            .collect();
        Self::new(view.width, view.height, depth)
    }

    /// Row-major index of pixel `(x, y)`.
    pub fn index(&self, x: u32, y: u32) -> usize {
        y as usize * self.width as usize + x as usize
    }

    /// Depth at pixel `(x, y)`, `None` outside the image or where there is no surface.
    pub fn get(&self, x: u32, y: u32) -> Option<f64> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let d = self.depth_m[self.index(x, y)];
        (!d.is_nan()).then_some(d)
    }

    /// Number of pixels with a surface.
    pub fn valid_count(&self) -> usize {
        self.depth_m.iter().filter(|d| !d.is_nan()).count()
    }

    /// World point seen at pixel `(x, y)` through `camera`, `None` where there is no surface.
    ///
    /// # Errors
    /// [`Error::InvalidParam`] if the camera's image size differs from the map's; errors of
    /// [`Camera::ray`].
    pub fn point(&self, camera: &Camera, x: u32, y: u32) -> Result<Option<DVec3>> {
        self.check_camera(camera)?;
        let Some(d) = self.get(x, y) else {
            return Ok(None);
        };
        let ray = camera.ray(DVec2::new(f64::from(x), f64::from(y)))?;
        Ok(Some(ray.origin + ray.direction * d))
    }

    /// Checks that `camera` images this map's pixel grid.
    ///
    /// # Errors
    /// [`Error::InvalidParam`] if the camera's image size differs from the map's.
    pub fn check_camera(&self, camera: &Camera) -> Result<()> {
        let (w, h) = (camera.intrinsics.width, camera.intrinsics.height);
        if (w, h) != (self.width, self.height) {
            return Err(Error::InvalidParam {
                name: "camera",
                reason: format!(
                    "images {w} x {h} but the depth map is {} x {}; pass the camera's image size",
                    self.width, self.height
                ),
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use skin_core::camera::Intrinsics;

    #[test]
    fn rejects_wrong_sizes_and_bad_depths() {
        assert!(DepthMap::new(0, 2, vec![]).is_err());
        assert!(DepthMap::new(2, 2, vec![1.0; 3]).is_err());
        assert!(DepthMap::new(1, 2, vec![1.0, -1.0]).is_err());
        assert!(DepthMap::new(1, 2, vec![1.0, f64::INFINITY]).is_err());
        let map = DepthMap::new(1, 2, vec![1.0, f64::NAN]).unwrap();
        assert_eq!(map.valid_count(), 1);
        assert_eq!(map.get(0, 1), None);
        assert_eq!(map.get(5, 0), None);
    }

    #[test]
    fn point_lies_at_the_depth_along_the_ray() {
        let k = Intrinsics::from_horizontal_fov(0.5, 8, 6).unwrap();
        let cam = Camera::look_at(k, DVec3::new(0.0, 0.0, 3.0), DVec3::ZERO, DVec3::Y).unwrap();
        let map = DepthMap::new(8, 6, vec![2.5; 48]).unwrap();
        let p = map.point(&cam, 1, 4).unwrap().unwrap();
        assert!(((p - cam.centre()).length() - 2.5).abs() < 1e-12);
        let wrong = DepthMap::empty(4, 4).unwrap();
        assert!(wrong.point(&cam, 0, 0).is_err());
    }
}
