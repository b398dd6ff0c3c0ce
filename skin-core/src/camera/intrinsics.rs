//! Pinhole intrinsics: focal lengths, principal point and image size (Sand 2003 §4.1's
//! "focal length f and aspect ratio a" are `fx = f`, `fy = a·f`).

use serde::{Deserialize, Serialize};

use crate::check::all_finite;
use crate::error::{Error, Result};
use crate::math::{DMat3, DVec2, DVec3};

/// Pinhole intrinsics. Pixel coordinates `(u, v)` run right and down with integer values at
/// pixel centres (OpenCV convention), so the image covers `[-½, width − ½) × [-½, height − ½)`.
/// The camera frame is x right, y down, z forward (optical axis).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Intrinsics {
    /// Horizontal focal length, px.
    pub fx: f64,
    /// Vertical focal length, px (`fy / fx` is Sand's aspect ratio `a`).
    pub fy: f64,
    /// Principal point, horizontal, px.
    pub cx: f64,
    /// Principal point, vertical, px.
    pub cy: f64,
    /// Image width, px.
    pub width: u32,
    /// Image height, px.
    pub height: u32,
}

impl Intrinsics {
    /// Validated intrinsics.
    ///
    /// # Errors
    /// [`Error::NonFinite`] for non-finite values; [`Error::InvalidParam`] for a focal length
    /// `≤ 0` or an empty image.
    pub fn new(fx: f64, fy: f64, cx: f64, cy: f64, width: u32, height: u32) -> Result<Self> {
        let k = Self {
            fx,
            fy,
            cx,
            cy,
            width,
            height,
        };
        k.validate()?;
        Ok(k)
    }

    /// Square-pixel intrinsics with the principal point at the image centre and the given
    /// horizontal field of view (radians, in `(0, π)`).
    ///
    /// # Errors
    /// [`Error::InvalidParam`] for a field of view outside `(0, π)` or an empty image.
    pub fn from_horizontal_fov(fov_rad: f64, width: u32, height: u32) -> Result<Self> {
        if !(fov_rad > 0.0 && fov_rad < std::f64::consts::PI) {
            return Err(Error::InvalidParam {
                name: "fov_rad",
                reason: format!("must be in (0, pi), got {fov_rad}"),
            });
        }
        let f = 0.5 * width as f64 / (0.5 * fov_rad).tan();
        Self::new(
            f,
            f,
            0.5 * (width as f64 - 1.0),
            0.5 * (height as f64 - 1.0),
            width,
            height,
        )
    }

    /// Checks finiteness, positive focal lengths and a non-empty image.
    ///
    /// # Errors
    /// As [`Intrinsics::new`].
    pub fn validate(&self) -> Result<()> {
        all_finite("intrinsics", [&self.fx, &self.fy, &self.cx, &self.cy])?;
        if self.fx <= 0.0 || self.fy <= 0.0 {
            return Err(Error::InvalidParam {
                name: "focal length",
                reason: format!("fx and fy must be > 0, got {} and {}", self.fx, self.fy),
            });
        }
        if self.width == 0 || self.height == 0 {
            return Err(Error::InvalidParam {
                name: "image size",
                reason: format!("must be non-empty, got {}x{}", self.width, self.height),
            });
        }
        Ok(())
    }

    /// The calibration matrix `K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`.
    pub fn matrix(&self) -> DMat3 {
        DMat3::from_cols(
            DVec3::new(self.fx, 0.0, 0.0),
            DVec3::new(0.0, self.fy, 0.0),
            DVec3::new(self.cx, self.cy, 1.0),
        )
    }

    /// Principal point `(cx, cy)`, px.
    pub fn principal_point(&self) -> DVec2 {
        DVec2::new(self.cx, self.cy)
    }

    /// Undistorted pixel of a normalised image point `(x/z, y/z)`.
    pub fn pixel_from_normalized(&self, n: DVec2) -> DVec2 {
        DVec2::new(self.fx * n.x + self.cx, self.fy * n.y + self.cy)
    }

    /// Normalised image point `(x/z, y/z)` of an undistorted pixel.
    pub fn normalized_from_pixel(&self, px: DVec2) -> DVec2 {
        DVec2::new((px.x - self.cx) / self.fx, (px.y - self.cy) / self.fy)
    }

    /// True if the pixel lies on the image, `[-½, width − ½) × [-½, height − ½)`.
    pub fn contains(&self, px: DVec2) -> bool {
        px.x >= -0.5
            && px.y >= -0.5
            && px.x < self.width as f64 - 0.5
            && px.y < self.height as f64 - 0.5
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn validation_and_normalisation() {
        let k = Intrinsics::from_horizontal_fov(1.0, 640, 480).unwrap();
        let px = DVec2::new(12.5, 400.25);
        assert!((k.pixel_from_normalized(k.normalized_from_pixel(px)) - px).length() < 1e-12);
        assert!(k.contains(DVec2::new(-0.5, 479.4)) && !k.contains(DVec2::new(639.5, 0.0)));
        assert!(matches!(
            Intrinsics::new(0.0, 1.0, 0.0, 0.0, 10, 10),
            Err(Error::InvalidParam { .. })
        ));
        assert!(matches!(
            Intrinsics::new(1.0, 1.0, f64::NAN, 0.0, 10, 10),
            Err(Error::NonFinite { .. })
        ));
        assert!(matches!(
            Intrinsics::new(1.0, 1.0, 0.0, 0.0, 0, 10),
            Err(Error::InvalidParam { .. })
        ));
        assert!(Intrinsics::from_horizontal_fov(4.0, 10, 10).is_err());
    }
}
