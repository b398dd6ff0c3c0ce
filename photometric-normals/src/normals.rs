//! §3.2.2 normal estimation: per pixel, the key `k/‖k‖` of its intensities under the
//! patterns, the N-best lookup of Eq. 3.2 in the calibration of its height (§3.2.3), and
//! invalid marks for dark or saturated pixels (§3.2.3, "Impact of Albedo").

use std::num::NonZero;

use image::{Rgb, Rgb32FImage, RgbImage};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use skin_core::camera::Camera;
use skin_core::image::Mask;
use skin_core::math::{DVec2, DVec3};

use crate::calibration::HeightCalibration;
use crate::patterns::{key, Exposure, PatternImages};
use crate::{DepthMap, Error, Result};

/// Options of [`estimate_normals`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct NormalParams {
    /// N of Eq. 3.2 (the thesis does not give it). Default: 8.
    pub n_best: usize,
    /// Exposure of the images (§3.2.3: normalised intensities 0.03–0.97 trusted).
    pub exposure: Exposure,
    /// A pixel's height (for §3.2.3's choice of calibration spheres) is taken where its ray
    /// crosses the vertical plane through this point facing the camera: the performance
    /// area's centre (world, m). The thesis does not say how heights are found; the subject
    /// stands near the centre and the cameras are almost level, so the proxy errs by a few
    /// centimetres. Default: `(0, 1, 0)`.
    pub performance_centre: DVec3,
    /// World up (heights are along it). Default: +Y.
    pub up: DVec3,
}

impl Default for NormalParams {
    fn default() -> Self {
        Self {
            n_best: 8,
            exposure: Exposure::default(),
            performance_centre: DVec3::new(0.0, 1.0, 0.0),
            up: DVec3::Y,
        }
    }
}

impl NormalParams {
    /// Returns the params with `exposure`.
    pub fn with_exposure(mut self, exposure: Exposure) -> Self {
        self.exposure = exposure;
        self
    }

    /// Returns the params with the performance centre.
    pub fn with_performance_centre(mut self, centre: DVec3) -> Self {
        self.performance_centre = centre;
        self
    }
}

/// Per-pixel unit normals in the camera frame (x right, y down, z forward), row-major, with
/// a validity flag (invalid: background, dark, saturated, or no usable key).
#[derive(Debug, Clone, PartialEq)]
pub struct NormalMap {
    /// Width, px.
    pub width: u32,
    /// Height, px.
    pub height: u32,
    /// Unit normals; zero where invalid.
    pub normals: Vec<DVec3>,
    /// Validity per pixel.
    pub valid: Vec<bool>,
}

impl NormalMap {
    /// Fraction of the pixels of `region` (all pixels when `None`) with a valid normal.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] for a region of another size.
    pub fn valid_fraction(&self, region: Option<&Mask>) -> Result<f64> {
        let n = self.valid.len();
        let (mut inside, mut ok) = (0usize, 0usize);
        match region {
            None => {
                inside = n;
                ok = self.valid.iter().filter(|&&v| v).count();
            }
            Some(m) => {
                if m.pixel_count() != n {
                    return Err(Error::SizeMismatch {
                        what: "region vs normal map pixels",
                        expected: n,
                        got: m.pixel_count(),
                    });
                }
                for (r, &v) in m.iter().zip(&self.valid) {
                    inside += usize::from(r);
                    ok += usize::from(r && v);
                }
            }
        }
        Ok(if inside == 0 {
            0.0
        } else {
            ok as f64 / inside as f64
        })
    }

    /// The usual colour picture of a normal map: `(n + 1)/2` as RGB with y and z flipped to the
    /// OpenGL convention (x right, y up, z towards the viewer); black where invalid.
    pub fn to_rgb8(&self) -> RgbImage {
        let w = self.width;
        RgbImage::from_fn(self.width, self.height, |x, y| {
            let i = (y * w + x) as usize;
            if !self.valid[i] {
                return Rgb([0, 0, 0]);
            }
            let n = self.normals[i];
            let c = [n.x, -n.y, -n.z]
                .map(|v| ((v + 1.0) * 0.5 * 255.0).round().clamp(0.0, 255.0) as u8);
            Rgb(c)
        })
    }

    /// The normals as a float image (zero where invalid).
    pub fn to_image(&self) -> Rgb32FImage {
        let w = self.width;
        Rgb32FImage::from_fn(self.width, self.height, |x, y| {
            let n = self.normals[(y * w + x) as usize];
            Rgb([n.x as f32, n.y as f32, n.z as f32])
        })
    }
}

/// The height proxy of [`NormalParams::performance_centre`] for every pixel of `camera`.
fn pixel_height(camera: &Camera, px: DVec2, p: &NormalParams) -> Option<f64> {
    let ray = camera.ray(px).ok()?;
    let up = p.up;
    // Plane through the centre, normal = horizontal direction from the centre to the camera.
    let mut nrm = camera.centre() - p.performance_centre;
    nrm -= up * nrm.dot(up);
    let nrm = nrm.try_normalize()?;
    let denom = ray.direction.dot(nrm);
    if denom.abs() < 1e-9 {
        return None;
    }
    let t = (p.performance_centre - ray.origin).dot(nrm) / denom;
    (t > 0.0).then(|| (ray.origin + ray.direction * t).dot(up))
}

/// §3.2.2: the normal map of one camera from its images under the patterns and its
/// calibration, for the pixels of `mask` (all pixels when `None`). A pixel's height is taken
/// on the vertical plane of [`NormalParams::performance_centre`]; a camera looking straight
/// down at that centre has no such plane and gets no normals — use
/// [`estimate_normals_on_proxy`] for it.
///
/// # Errors
/// [`Error::SizeMismatch`] if the images, the mask and the camera differ in size;
/// [`Error::InvalidParam`] for `n_best` = 0, a bad exposure or a zero `up`.
pub fn estimate_normals(
    camera: &Camera,
    calibration: &HeightCalibration,
    images: &PatternImages,
    mask: Option<&Mask>,
    params: &NormalParams,
) -> Result<NormalMap> {
    estimate_at_heights(camera, calibration, images, mask, params, |_, px, p| {
        pixel_height(camera, px, p)
    })
}

/// [`estimate_normals`] with each pixel's height (§3.2.3's choice of calibration spheres)
/// taken where its ray meets `proxy` (e.g. the visual hull rendered for `camera`), and on
/// the vertical plane of [`NormalParams::performance_centre`] where the proxy has no depth.
///
/// Ours (for the thesis's optional ninth camera that "looks down onto the performer from
/// the top of the dome", §3.2.1): the thesis does not say how a pixel's height is found. The
/// plane through the performance centre facing the camera serves the ring, whose cameras are
/// almost level, but a camera above the centre has no such plane, and the surfaces it sees
/// span the performer's whole height (head, shoulders, skirt, feet). The visual hull is known
/// before the normals (it needs only the silhouettes) and is within centimetres of the
/// surface where the subject is convex.
///
/// # Errors
/// As [`estimate_normals`]; [`Error::InvalidParam`] if `proxy` is not of the camera's size.
pub fn estimate_normals_on_proxy(
    camera: &Camera,
    calibration: &HeightCalibration,
    images: &PatternImages,
    mask: Option<&Mask>,
    proxy: &DepthMap,
    params: &NormalParams,
) -> Result<NormalMap> {
    proxy.check_camera(camera)?;
    estimate_at_heights(camera, calibration, images, mask, params, |i, px, p| {
        let d = proxy.depth_m[i];
        if d.is_nan() {
            return pixel_height(camera, px, p);
        }
        let ray = camera.ray(px).ok()?;
        Some((ray.origin + ray.direction * d).dot(p.up))
    })
}

/// The body of [`estimate_normals`] with the pixel heights of `height(index, pixel, params)`
/// (`params.up` normalised).
fn estimate_at_heights(
    camera: &Camera,
    calibration: &HeightCalibration,
    images: &PatternImages,
    mask: Option<&Mask>,
    params: &NormalParams,
    height: impl Fn(usize, DVec2, &NormalParams) -> Option<f64> + Sync,
) -> Result<NormalMap> {
    params.exposure.validate()?;
    let n_best = NonZero::new(params.n_best).ok_or(Error::InvalidParam {
        name: "n_best",
        reason: "must be >= 1".into(),
    })?;
    skin_core::check::all_finite(
        "performance centre and up",
        [params.performance_centre, params.up]
            .iter()
            .flat_map(|v| v.as_ref().iter()),
    )?;
    let up = params.up.try_normalize().ok_or(Error::InvalidParam {
        name: "up",
        reason: "must be non-zero".into(),
    })?;
    let params = NormalParams { up, ..*params };
    let (w, h) = (images.width(), images.height());
    let k = &camera.intrinsics;
    if (w, h) != (k.width, k.height) {
        return Err(Error::SizeMismatch {
            what: "pattern images vs camera pixels",
            expected: (k.width * k.height) as usize,
            got: (w * h) as usize,
        });
    }
    if let Some(m) = mask {
        if m.dimensions() != (w, h) {
            return Err(Error::SizeMismatch {
                what: "mask vs pattern image pixels",
                expected: (w * h) as usize,
                got: m.pixel_count(),
            });
        }
    }
    let n = (w * h) as usize;
    let flags = mask.map(Mask::to_bools);
    let normals: Vec<Option<DVec3>> = (0..n)
        .into_par_iter()
        .map(|i| {
            if flags.as_ref().is_some_and(|f| !f[i]) {
                return None;
            }
            let inten = images.pixel(i);
            let brightest = inten.iter().copied().fold(f32::MIN, f32::max);
            if !params.exposure.trusted(inten[3], brightest) {
                return None;
            }
            let kn = key(&inten).try_normalize()?;
            let px = DVec2::new((i % w as usize) as f64, (i / w as usize) as f64);
            let height = height(i, px, &params)?;
            calibration.lookup(kn, height, n_best)
        })
        .collect();
    Ok(NormalMap {
        width: w,
        height: h,
        valid: normals.iter().map(Option::is_some).collect(),
        normals: normals.into_iter().map(Option::unwrap_or_default).collect(),
    })
}
