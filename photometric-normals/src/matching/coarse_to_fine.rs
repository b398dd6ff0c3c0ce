//! The entry point [`match_pair`]: its checks, then (coarse-to-fine) the pair matched at half
//! resolution to narrow the full-resolution band, then the full-resolution matching.

use skin_core::camera::Camera;
use skin_core::check;
use skin_core::image::GrayF32Image;
use skin_core::math::DVec3;

use crate::integrate::IntegrationParams;
use crate::{DepthMap, Error, PolygonalHull, Result};

use super::epipolar::check_view;
use super::pair::{match_views, PathRanges};
use super::params::MatchingParams;
use super::views::{MatchView, PairMatches};

/// Matches a pair of neighbouring views by §3.3.2 and returns each view's matched depths and
/// discontinuities. `hull`, when given, removes cells outside the visual hull.
///
/// # Errors
/// [`Error::InvalidParam`] for bad params, distorted cameras or maps of another size than
/// their camera; [`Error::Empty`] if a surface has no triangles, or images are missing for an
/// image-based metric; rendering errors.
pub fn match_pair(
    left: &MatchView<'_>,
    right: &MatchView<'_>,
    hull: Option<&PolygonalHull>,
    params: &MatchingParams,
) -> Result<PairMatches> {
    match_pair_with_rays(left, right, hull, params, None)
}

/// [`match_pair`] with the two cameras' [`crate::integrate::camera_rays`] when the caller has
/// them (computed once per camera for all of a pass's pairs and integrations).
pub(crate) fn match_pair_with_rays(
    left: &MatchView<'_>,
    right: &MatchView<'_>,
    hull: Option<&PolygonalHull>,
    params: &MatchingParams,
    camera_rays: Option<[&[DVec3]; 2]>,
) -> Result<PairMatches> {
    params.validate()?;
    if params.metric.needs_images() {
        for v in [left, right] {
            let ok = v.images.is_some_and(|im| {
                im.len() >= 2
                    && im.iter().all(|i| {
                        i.dimensions() == (v.camera.intrinsics.width, v.camera.intrinsics.height)
                    })
            });
            if !ok {
                return Err(Error::Empty {
                    what: "images (full-on then half-on, camera-sized) for an image-based metric",
                });
            }
        }
    }
    for v in [left, right] {
        check_view(v)?;
    }
    if let Some(rays) = camera_rays {
        for (v, r) in [left, right].into_iter().zip(rays) {
            check::same_size("camera rays", v.surface.depth_m.len(), r.len())?;
        }
    }
    let coarse = params.coarse_to_fine
        && [left, right].iter().all(|v| {
            let k = &v.camera.intrinsics;
            k.width >= 2 * COARSE_MIN_PX && k.height >= 2 * COARSE_MIN_PX
        });
    let narrow = if coarse {
        Some(coarse_intervals(left, right, hull, params)?)
    } else {
        None
    };
    Ok(match_views(left, right, hull, params, narrow, camera_rays)?.0)
}

/// Coarse-to-fine applies to images at least twice this size.
pub(super) const COARSE_MIN_PX: u32 = 64;

/// A view at half resolution: each coarse pixel is a 2 × 2 block of the view's.
pub(super) struct HalfView {
    pub(super) camera: Camera,
    pub(super) surface: DepthMap,
    pub(super) guide: Option<DepthMap>,
    pub(super) images: Option<Vec<GrayF32Image>>,
}

impl HalfView {
    pub(super) fn new(view: &MatchView<'_>, jump_m: f64) -> Result<Self> {
        let cam = view.camera;
        let k = &cam.intrinsics;
        // Pixel centres are at integer coordinates: coarse pixel X is full 2X + ½.
        let half = skin_core::camera::Intrinsics::new(
            k.fx / 2.0,
            k.fy / 2.0,
            (k.cx - 0.5) / 2.0,
            (k.cy - 0.5) / 2.0,
            k.width / 2,
            k.height / 2,
        )?;
        let camera = Camera::new(half, cam.distortion, cam.world_from_camera())?;
        let depth = |d: &DepthMap| half_depth(d, jump_m);
        Ok(Self {
            camera,
            surface: depth(view.surface)?,
            guide: view.guide.map(depth).transpose()?,
            images: view.images.map(|im| im.iter().map(half_image).collect()),
        })
    }

    pub(super) fn view(&self) -> MatchView<'_> {
        MatchView {
            camera: &self.camera,
            surface: &self.surface,
            guide: self.guide.as_ref(),
            images: self.images.as_deref(),
        }
    }
}

/// A depth map at half resolution: per 2 × 2 block the mean of its depths, or the nearest
/// where they spread more than `jump_m` (a discontinuity is not averaged into a surface
/// between its sides); `NaN` where the block has none.
pub(super) fn half_depth(d: &DepthMap, jump_m: f64) -> Result<DepthMap> {
    let (w, h) = (d.width / 2, d.height / 2);
    let fw = d.width as usize;
    let mut out = Vec::with_capacity(w as usize * h as usize);
    for y in 0..h as usize {
        for x in 0..w as usize {
            let block = [
                d.depth_m[2 * y * fw + 2 * x],
                d.depth_m[2 * y * fw + 2 * x + 1],
                d.depth_m[(2 * y + 1) * fw + 2 * x],
                d.depth_m[(2 * y + 1) * fw + 2 * x + 1],
            ];
            let (mut n, mut sum, mut lo, mut hi) = (0usize, 0.0, f64::INFINITY, f64::NEG_INFINITY);
            for v in block.into_iter().filter(|v| !v.is_nan()) {
                n += 1;
                sum += v;
                lo = lo.min(v);
                hi = hi.max(v);
            }
            out.push(match n {
                0 => f64::NAN,
                _ if hi - lo > jump_m => lo,
                _ => sum / n as f64,
            });
        }
    }
    DepthMap::new(w.max(1), h.max(1), out)
}

/// An image at half resolution (2 × 2 block means).
pub(super) fn half_image(im: &GrayF32Image) -> GrayF32Image {
    let (w, h) = (im.width() / 2, im.height() / 2);
    GrayF32Image::from_fn(w, h, |x, y| {
        let v = (0..4)
            .map(|k| im.get_pixel(2 * x + k % 2, 2 * y + k / 2).0[0])
            .sum::<f32>();
        image::Luma([v / 4.0])
    })
}

/// The coarse pass of coarse-to-fine matching: the pair matched at half resolution, and per
/// full-resolution pixel of each view the depth interval its cells are kept to — the range
/// of the coarse path's depths over the 3 × 3 coarse pixels around it, widened by
/// [`MatchingParams::coarse_band_px`] footprints (`NaN` where none of them has a path depth).
pub(super) fn coarse_intervals(
    left: &MatchView<'_>,
    right: &MatchView<'_>,
    hull: Option<&PolygonalHull>,
    params: &MatchingParams,
) -> Result<(PathRanges, PathRanges)> {
    let jump = IntegrationParams::jump_threshold_m(params.jump_m, left.camera.intrinsics.width);
    let (hl, hr) = (
        HalfView::new(left, 2.0 * jump)?,
        HalfView::new(right, 2.0 * jump)?,
    );
    let coarse_params = MatchingParams {
        coarse_to_fine: false,
        ..*params
    };
    let (_, (rl, rr)) = match_views(&hl.view(), &hr.view(), hull, &coarse_params, None, None)?;
    let widen = |view: &MatchView<'_>, half: &HalfView, ranges: &[(f64, f64)]| {
        let k = &view.camera.intrinsics;
        let (w, h) = (k.width as usize, k.height as usize);
        let (cw, ch) = (
            half.camera.intrinsics.width as usize,
            half.camera.intrinsics.height as usize,
        );
        let margin = params.coarse_band_px / k.fx;
        (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) / 2, (i / w) / 2);
                let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
                for cy in y.saturating_sub(1)..(y + 2).min(ch) {
                    for cx in x.saturating_sub(1)..(x + 2).min(cw) {
                        let (a, b) = ranges[cy * cw + cx];
                        if !a.is_nan() {
                            lo = lo.min(a);
                            hi = hi.max(b);
                        }
                    }
                }
                if lo > hi {
                    (f64::NAN, f64::NAN)
                } else {
                    (lo * (1.0 - margin), hi * (1.0 + margin))
                }
            })
            .collect::<Vec<_>>()
    };
    Ok((widen(left, &hl, &rl), widen(right, &hr, &rr)))
}
