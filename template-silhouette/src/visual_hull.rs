//! Distance to the visual hull (Vlasic 2010 §2.3.2).
//!
//! The visual hull is the intersection of the silhouette cones of the cameras. Inside an
//! intersection the distance to its boundary is the minimum of the distances to the
//! boundaries of the individual cones, and the distance to the boundary of cone `i` (apex
//! `o_i`) scales along rays through the apex: `d_i(o_i + a (p − o_i)) = a d_i(p)`. So a
//! transform computed once on the image plane gives `d_i` everywhere in space.
//!
//! **On the image plane** ([`ConeDistance`]): every contour point of the silhouette defines a
//! contour ray from the camera centre; the boundary of the cone is the union of these rays.
//! A vector distance transform (two raster scans with an 8-neighbourhood, after Danielsson,
//! the [43] of the thesis) propagates, from the contour pixels outward, the index of the
//! *nearest contour ray* — compared by the 3D point-to-ray distance of the pixel's own ray
//! at unit range, i.e. the sine of the angle between the two rays — instead of the nearest
//! contour pixel. This is the correction the thesis makes to image-space distances.
//!
//! **Anywhere in space**: a point `p` is projected to its pixel, the nearest contour ray
//! `(o, v)` stored there is read, and the distance is `|(p − o) × v|`, the exact distance to
//! that ray. This is the scaling property applied with the stored ray rather than a stored
//! scalar, so it is also exact between pixel centres and gives the analytic gradient
//! `(p − o)⊥ / |(p − o)⊥|` the pose optimiser needs (§2.3.1).
//!
//! **Outside the hull** ([`ContourRayHull`]): a bone sample outside the hull is far from where it
//! should be and needs less accuracy (§2.3.2); the distance is then the distance to a
//! polygonal hull extracted once per frame with marching cubes (skin-core's watertight
//! marching tetrahedra) from the signed field `min_i s_i(p)` sampled near the hull, and
//! queried through skin-core's [`MeshQuery`] (a parry BVH).
//!
//! Signs: distances are **positive inside** the hull and negative outside, so the depth term
//! of §2.3.1 penalises `d(p) − r < 0` in both cases.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use skin_core::camera::Camera;
use skin_core::image::{extract_contours, ContourParams, Mask, PixelRect};
use skin_core::math::{DVec2, DVec3};
use skin_core::mesh::{marching_tetrahedra, BoundingBox, MeshQuery, ScalarGrid, TriMesh};

use crate::error::{Context, Error, Result, ResultExt};

/// No contour ray reaches this pixel (yet).
const NO_RAY: u32 = u32::MAX;

/// Knobs of [`ContourRayHull`], the visual-hull distance by the nearest contour ray
/// (§2.3.2). The thesis gives no values: the defaults are
/// chosen here and justified per field.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ContourRayHullParams {
    /// Pixels added around each silhouette's bounding box for the cone transform. Outside
    /// this window a point counts as far outside that cone. It must exceed the coarse cell's
    /// half-diagonal projected from the nearest camera, so that the coarse occupancy test
    /// never loses a cell touching the hull: at 1600 × 1200 px (focal ≈ 1400 px) and 2.5 m,
    /// the default 0.08 m cell's 0.07 m half-diagonal is 39 px. Default:
    /// [`Self::DEFAULT_MARGIN_PX`] = 48.
    pub margin_px: u32,
    /// The capture volume searched for the hull, world metres; the polygonal hull is clipped
    /// to it. Default: x, z in ±2.5 m and y in −1.5…2.5 m (+Y up): larger than the 8-camera
    /// studios of §2.5.1, for a performer standing on y = 0 or centred on its pelvis (the
    /// MakeHuman template).
    pub volume: BoundingBox,
    /// Node spacing of the coarse occupancy grid over [`Self::volume`], m. A coarse node is
    /// kept when it is within its cell's half-diagonal of every cone, which no cell touching
    /// the hull fails, so the hull's box is found whatever its limbs' thickness. Default:
    /// [`Self::DEFAULT_COARSE_SPACING_M`] = 0.08.
    pub coarse_spacing_m: f64,
    /// Node spacing of the marching-cubes grid of the polygonal hull, m. It serves points
    /// outside the hull only, which "don't need as much accuracy" (§2.3.2): 2.5 cm is the
    /// thickness of a finger and a tenth of a thigh. Default: [`Self::DEFAULT_POLYGON_SPACING_M`]
    /// = 0.025.
    pub polygon_spacing_m: f64,
}

impl Default for ContourRayHullParams {
    fn default() -> Self {
        ContourRayHullParams {
            margin_px: Self::DEFAULT_MARGIN_PX,
            volume: BoundingBox {
                min: DVec3::new(-2.5, -1.5, -2.5),
                max: DVec3::new(2.5, 2.5, 2.5),
            },
            coarse_spacing_m: Self::DEFAULT_COARSE_SPACING_M,
            polygon_spacing_m: Self::DEFAULT_POLYGON_SPACING_M,
        }
    }
}

impl ContourRayHullParams {
    /// Default margin around a silhouette's bounding box in which the cone transform is computed,
    /// pixels. Must cover the coarse cell's half-diagonal seen from the nearest camera (see
    /// [`ContourRayHullParams::margin_px`]).
    pub const DEFAULT_MARGIN_PX: u32 = 48;

    /// Default node spacing of the coarse occupancy grid that finds the hull's bounding box, m.
    pub const DEFAULT_COARSE_SPACING_M: f64 = 0.08;

    /// Default node spacing of the marching-cubes grid of the polygonal hull, m.
    pub const DEFAULT_POLYGON_SPACING_M: f64 = 0.025;

    /// Sets [`Self::margin_px`].
    pub fn with_margin_px(mut self, px: u32) -> Self {
        self.margin_px = px;
        self
    }
    /// Sets [`Self::volume`].
    pub fn with_volume(mut self, volume: BoundingBox) -> Self {
        self.volume = volume;
        self
    }
    /// Sets [`Self::coarse_spacing_m`].
    pub fn with_coarse_spacing_m(mut self, m: f64) -> Self {
        self.coarse_spacing_m = m;
        self
    }
    /// Sets [`Self::polygon_spacing_m`].
    pub fn with_polygon_spacing_m(mut self, m: f64) -> Self {
        self.polygon_spacing_m = m;
        self
    }

    fn validate(&self) -> Result<()> {
        skin_core::check::positive("coarse_spacing_m", self.coarse_spacing_m)?;
        skin_core::check::positive("polygon_spacing_m", self.polygon_spacing_m)?;
        let (lo, hi) = (self.volume.min, self.volume.max);
        if !(lo.is_finite() && hi.is_finite()) {
            return Err(Error::NonFinite {
                what: "visual-hull volume corners",
            });
        }
        if !(hi.cmpgt(lo).all()) {
            return Err(Error::InvalidParam {
                name: "volume",
                reason: format!("max {hi} must exceed min {lo} on every axis; swap the corners"),
            });
        }
        Ok(())
    }
}

/// Where a point lies relative to one silhouette cone, with its signed distance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ConeSample {
    /// Inside the cone or outside it near its boundary (within the transform's window).
    Near {
        /// Signed distance to the cone boundary, m: positive inside.
        signed_m: f64,
        /// Gradient of `signed_m` with respect to the point (unit, or zero on the boundary).
        gradient: DVec3,
    },
    /// Outside the transform's window, behind the camera or off the image: outside the cone
    /// by more than the margin.
    Far,
}

/// The distance to the boundary of one camera's silhouette cone (§2.3.2): the nearest
/// contour ray of every pixel in a window around the silhouette.
#[derive(Debug, Clone)]
pub struct ConeDistance {
    camera: Camera,
    /// The window of the transform (inclusive pixel bounds).
    window: PixelRect,
    /// Unit world directions of the contour rays.
    rays: Vec<DVec3>,
    /// Per window pixel (row-major), the index of its nearest contour ray.
    nearest: Vec<u32>,
    /// Per window pixel, whether it is foreground.
    inside: Vec<bool>,
}

impl ConeDistance {
    /// The nearest-contour-ray transform of `mask` seen by `camera`.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if the mask is not the camera's image size; [`Error::Empty`]
    /// for a silhouette without foreground; errors of the camera's rays (e.g. contour pixels
    /// beyond a barrel distortion's fold).
    pub fn new(camera: &Camera, mask: &Mask, margin_px: u32) -> Result<Self> {
        let (w, h) = (camera.intrinsics.width, camera.intrinsics.height);
        if mask.width() != w {
            return Err(Error::SizeMismatch {
                what: "silhouette width vs camera image width (a mask of the camera's image size)",
                expected: w as usize,
                got: mask.width() as usize,
            });
        }
        if mask.height() != h {
            return Err(Error::SizeMismatch {
                what:
                    "silhouette height vs camera image height (a mask of the camera's image size)",
                expected: h as usize,
                got: mask.height() as usize,
            });
        }
        let bbox = mask.bounding_box().ok_or(Error::Empty {
            what: "silhouette (no foreground pixel: the performer is out of view, or the \
                   background subtraction failed)",
        })?;
        let window = PixelRect {
            x_min: bbox.x_min.saturating_sub(margin_px),
            y_min: bbox.y_min.saturating_sub(margin_px),
            x_max: bbox.x_max.saturating_add(margin_px).min(w - 1),
            y_max: bbox.y_max.saturating_add(margin_px).min(h - 1),
        };
        // One contour point per boundary pixel, on the pixel edges (offset 0.5 px).
        let params = ContourParams::default().with_sample_step_px(0.0);
        let contours = extract_contours(mask, &params)?;
        let mut points = Vec::new();
        for c in &contours {
            points.extend(c.points.iter().zip(&c.normals).map(|(p, n)| (*p, *n)));
        }
        let rays = points
            .iter()
            .map(|(p, _)| camera.ray(*p).map(|r| r.direction))
            .collect::<skin_core::Result<Vec<_>>>()?;
        let (ww, wh) = (window.width() as usize, window.height() as usize);
        let dirs: Vec<DVec3> = (0..ww * wh)
            .into_par_iter()
            .map(|i| {
                let px = DVec2::new(
                    f64::from(window.x_min) + (i % ww) as f64,
                    f64::from(window.y_min) + (i / ww) as f64,
                );
                camera.ray(px).map(|r| r.direction)
            })
            .collect::<skin_core::Result<Vec<_>>>()?;
        let inside: Vec<bool> = (0..ww * wh)
            .map(|i| {
                mask.get(
                    window.x_min + (i % ww) as u32,
                    window.y_min + (i / ww) as u32,
                )
            })
            .collect();
        let mut nearest = vec![NO_RAY; ww * wh];
        let mut cost = vec![f64::INFINITY; ww * wh];
        // Seeds: the pixels on both sides of each contour point's pixel edge.
        for (k, (p, n)) in points.iter().enumerate() {
            for q in [*p - 0.5 * *n, *p + 0.5 * *n] {
                let (x, y) = (q.x.round(), q.y.round());
                if x < f64::from(window.x_min)
                    || y < f64::from(window.y_min)
                    || x > f64::from(window.x_max)
                    || y > f64::from(window.y_max)
                {
                    continue;
                }
                let i = (y as usize - window.y_min as usize) * ww
                    + (x as usize - window.x_min as usize);
                let c = ray_cost(dirs[i], rays[k]);
                if c < cost[i] {
                    cost[i] = c;
                    nearest[i] = k as u32;
                }
            }
        }
        propagate(ww, wh, &dirs, &rays, &mut nearest, &mut cost);
        Ok(ConeDistance {
            camera: camera.clone(),
            window,
            rays,
            nearest,
            inside,
        })
    }

    /// The camera of this cone.
    pub fn camera(&self) -> &Camera {
        &self.camera
    }

    /// Number of contour rays (one per boundary pixel of the silhouette).
    pub fn ray_count(&self) -> usize {
        self.rays.len()
    }

    /// The signed distance of `p` (world, m) to the cone's boundary: the distance to the
    /// nearest contour ray stored at `p`'s pixel (the scaling property of §2.3.2).
    ///
    /// # Errors
    /// [`Error::Core`] with skin-core's `NonFinite` for a non-finite point.
    pub fn sample(&self, p: DVec3) -> Result<ConeSample> {
        Ok(self.sample_core(p)?)
    }

    /// [`Self::sample`] with skin-core's error type (for optimiser closures).
    pub(crate) fn sample_core(&self, p: DVec3) -> skin_core::Result<ConeSample> {
        if !p.is_finite() {
            return Err(skin_core::Error::NonFinite {
                what: "visual-hull query point",
            });
        }
        let Ok(pixel) = self.camera.project(p) else {
            return Ok(ConeSample::Far);
        };
        let (x, y) = (pixel.x.round(), pixel.y.round());
        let w = &self.window;
        if !(x >= f64::from(w.x_min)
            && y >= f64::from(w.y_min)
            && x <= f64::from(w.x_max)
            && y <= f64::from(w.y_max))
        {
            return Ok(ConeSample::Far);
        }
        let i =
            (y as usize - w.y_min as usize) * w.width() as usize + (x as usize - w.x_min as usize);
        let k = self.nearest[i];
        let Some(v) = self.rays.get(k as usize) else {
            return Ok(ConeSample::Far);
        };
        let rel = p - self.camera.centre();
        let perp = rel - rel.dot(*v) * *v;
        let d = perp.length();
        let unit = if d > 0.0 { perp / d } else { DVec3::ZERO };
        let sign = if self.inside[i] { 1.0 } else { -1.0 };
        Ok(ConeSample::Near {
            signed_m: sign * d,
            gradient: sign * unit,
        })
    }
}

/// Squared sine of the angle between a pixel's unit ray and a contour ray: the squared
/// distance between the pixel's ray point at unit range and the contour ray (the point-ray
/// distance of §2.3.2 at range 1). Rays more than 90° apart never compete.
fn ray_cost(pixel_dir: DVec3, ray: DVec3) -> f64 {
    if pixel_dir.dot(ray) <= 0.0 {
        f64::INFINITY
    } else {
        pixel_dir.cross(ray).length_squared()
    }
}

/// Two-pass 8-neighbour propagation of the nearest contour ray (a vector distance transform
/// that carries ray indices instead of pixel offsets).
fn propagate(
    w: usize,
    h: usize,
    dirs: &[DVec3],
    rays: &[DVec3],
    nearest: &mut [u32],
    cost: &mut [f64],
) {
    let relax = |i: usize, j: usize, nearest: &mut [u32], cost: &mut [f64]| {
        let k = nearest[j];
        if k == NO_RAY || k == nearest[i] {
            return;
        }
        let c = ray_cost(dirs[i], rays[k as usize]);
        if c < cost[i] {
            cost[i] = c;
            nearest[i] = k;
        }
    };
    // Forward: top to bottom, neighbours above and to the left, then a right-to-left sweep.
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            if x > 0 {
                relax(i, i - 1, nearest, cost);
            }
            if y > 0 {
                relax(i, i - w, nearest, cost);
                if x > 0 {
                    relax(i, i - w - 1, nearest, cost);
                }
                if x + 1 < w {
                    relax(i, i - w + 1, nearest, cost);
                }
            }
        }
        for x in (0..w.saturating_sub(1)).rev() {
            let i = y * w + x;
            relax(i, i + 1, nearest, cost);
        }
    }
    // Backward: bottom to top, neighbours below and to the right, then left-to-right.
    for y in (0..h).rev() {
        for x in (0..w).rev() {
            let i = y * w + x;
            if x + 1 < w {
                relax(i, i + 1, nearest, cost);
            }
            if y + 1 < h {
                relax(i, i + w, nearest, cost);
                if x + 1 < w {
                    relax(i, i + w + 1, nearest, cost);
                }
                if x > 0 {
                    relax(i, i + w - 1, nearest, cost);
                }
            }
        }
        for x in 1..w {
            let i = y * w + x;
            relax(i, i - 1, nearest, cost);
        }
    }
}

/// Which evaluation gave a [`HullDistance`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum HullRegion {
    /// Inside every cone: the minimum of the cone distances (exact up to the pixel grid).
    Inside,
    /// Outside at least one cone: the distance to the polygonal hull.
    Outside,
}

/// The signed distance of a point to the visual hull and its gradient.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct HullDistance {
    /// Signed distance to the hull surface, m: positive inside, negative outside.
    pub signed_m: f64,
    /// Gradient of `signed_m` with respect to the point (a unit vector, or zero where the
    /// point lies on a contour ray or the polygon).
    pub gradient: DVec3,
    /// How it was evaluated.
    pub region: HullRegion,
    /// The camera whose cone is nearest, for [`HullRegion::Inside`].
    pub camera: Option<usize>,
}

/// The visual hull of one frame as a distance field by the nearest contour ray (§2.3.2): the
/// cone distances of every camera (exact inside the hull, with the analytic gradient the pose
/// fit needs) and the polygonal hull for points outside it.
#[derive(Debug)]
pub struct ContourRayHull {
    cones: Vec<ConeDistance>,
    polygon: TriMesh,
    query: MeshQuery,
}

impl ContourRayHull {
    /// Builds the cone transforms of every camera, then extracts the polygonal hull: coarse
    /// occupancy over [`ContourRayHullParams::volume`], then marching cubes of `min_i s_i` on a
    /// [`ContourRayHullParams::polygon_spacing_m`] grid over the occupied box.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if cameras and masks differ in number; [`Error::Empty`] for no
    /// camera, or when no grid node lies inside every silhouette (cameras that disagree, or a
    /// volume that misses the performer); [`Error::InvalidParam`] for bad params; errors of
    /// [`ConeDistance::new`] wrapped in [`Error::At`] with the camera.
    pub fn new(cameras: &[Camera], masks: &[Mask], params: &ContourRayHullParams) -> Result<Self> {
        params.validate()?;
        check_views(cameras, masks)?;
        let cones = cameras
            .par_iter()
            .zip(masks)
            .enumerate()
            .map(|(c, (camera, mask))| {
                ConeDistance::new(camera, mask, params.margin_px).at(Context::Camera(c))
            })
            .collect::<Result<Vec<_>>>()?;
        let polygon = extract_polygon(&cones, params)?;
        let query = MeshQuery::new(&polygon)?;
        Ok(ContourRayHull {
            cones,
            polygon,
            query,
        })
    }

    /// The cone transforms, one per camera.
    pub fn cones(&self) -> &[ConeDistance] {
        &self.cones
    }

    /// The polygonal hull (marching cubes of the sampled field; §2.3.2).
    pub fn polygon(&self) -> &TriMesh {
        &self.polygon
    }

    /// The signed field `min_i s_i(p)` (positive inside): exact inside the hull, a bound
    /// outside; `None` where some cone sees `p` as far outside.
    ///
    /// # Errors
    /// [`Error::Core`] with skin-core's `NonFinite` for a non-finite point.
    pub fn cone_field(&self, p: DVec3) -> Result<Option<(f64, DVec3, usize)>> {
        Ok(self.cone_field_core(p)?)
    }

    fn cone_field_core(&self, p: DVec3) -> skin_core::Result<Option<(f64, DVec3, usize)>> {
        let mut best: Option<(f64, DVec3, usize)> = None;
        for (c, cone) in self.cones.iter().enumerate() {
            match cone.sample_core(p)? {
                ConeSample::Far => return Ok(None),
                ConeSample::Near { signed_m, gradient } => {
                    if best.is_none_or(|b| signed_m < b.0) {
                        best = Some((signed_m, gradient, c));
                    }
                }
            }
        }
        Ok(best)
    }

    /// The signed distance of `p` to the visual hull (§2.3.2): the minimum over cameras of
    /// the cone distances when `p` is inside every cone, else minus the distance to the
    /// polygonal hull.
    ///
    /// # Errors
    /// [`Error::Core`] with skin-core's `NonFinite` for a non-finite point.
    pub fn distance(&self, p: DVec3) -> Result<HullDistance> {
        Ok(self.distance_core(p)?)
    }

    /// [`Self::distance`] with skin-core's error type (for optimiser closures).
    pub(crate) fn distance_core(&self, p: DVec3) -> skin_core::Result<HullDistance> {
        if let Some((signed_m, gradient, camera)) = self.cone_field_core(p)? {
            if signed_m >= 0.0 {
                return Ok(HullDistance {
                    signed_m,
                    gradient,
                    region: HullRegion::Inside,
                    camera: Some(camera),
                });
            }
        }
        let c = self.query.closest_point(p)?;
        let towards = c.position - p;
        let d = towards.length();
        Ok(HullDistance {
            signed_m: -d,
            gradient: if d > 0.0 { towards / d } else { DVec3::ZERO },
            region: HullRegion::Outside,
            camera: None,
        })
    }
}

/// One silhouette per camera, and at least one camera.
pub(crate) fn check_views(cameras: &[Camera], masks: &[Mask]) -> Result<()> {
    if cameras.len() != masks.len() {
        return Err(Error::SizeMismatch {
            what: "silhouettes (one per camera)",
            expected: cameras.len(),
            got: masks.len(),
        });
    }
    if cameras.is_empty() {
        return Err(Error::Empty { what: "cameras" });
    }
    Ok(())
}

/// Marching cubes of the signed cone field over the box the coarse occupancy finds.
fn extract_polygon(cones: &[ConeDistance], params: &ContourRayHullParams) -> Result<TriMesh> {
    let field = |p: DVec3, far: f64| -> f64 {
        let mut best = f64::INFINITY;
        for cone in cones {
            // Query points are grid nodes, finite by construction.
            match cone.sample(p) {
                Ok(ConeSample::Near { signed_m, .. }) => best = best.min(signed_m),
                _ => return -far,
            }
        }
        best
    };
    // Coarse occupancy: nodes within a cell's half-diagonal of every cone.
    let vol = &params.volume;
    let s = params.coarse_spacing_m;
    let reach = 0.5 * 3f64.sqrt() * s;
    let dims = grid_dims(vol, s)?;
    let occupied: Vec<DVec3> = (0..dims[0] * dims[1] * dims[2])
        .into_par_iter()
        .filter_map(|n| {
            let p = node(vol.min, s, dims, n);
            (field(p, f64::INFINITY) >= -reach).then_some(p)
        })
        .collect();
    if occupied.is_empty() {
        return Err(Error::Empty {
            what: "visual hull (no point of the volume lies inside every silhouette: the \
                   cameras disagree, or the volume misses the performer: check the calibration and \
                   ContourRayHullParams::volume)",
        });
    }
    let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
    for p in &occupied {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    let (lo, hi) = (lo - DVec3::splat(s), hi + DVec3::splat(s));
    let fine = params.polygon_spacing_m;
    let fine_box = BoundingBox { min: lo, max: hi };
    let fdims = grid_dims(&fine_box, fine)?;
    let values: Vec<f64> = (0..fdims[0] * fdims[1] * fdims[2])
        .into_par_iter()
        .map(|n| field(node(lo, fine, fdims, n), fine))
        .collect();
    // Grid borders are outside (the box is padded by a coarse cell), so the surface closes.
    let grid = ScalarGrid {
        origin: lo,
        spacing_m: fine,
        dims: fdims,
        values,
    };
    let mesh = marching_tetrahedra(&grid, 0.0)?;
    if mesh.faces.is_empty() {
        return Err(Error::Empty {
            what: "polygonal visual hull (no grid node inside every silhouette at the polygon \
                   spacing: make polygon_spacing_m smaller)",
        });
    }
    Ok(mesh)
}

/// Node counts of a grid of spacing `s` covering `b`.
fn grid_dims(b: &BoundingBox, s: f64) -> Result<[usize; 3]> {
    let e = b.extent() / s;
    let n = [e.x, e.y, e.z].map(|v| v.ceil() as usize + 1);
    const MAX_NODES: usize = 200_000_000;
    if n.iter().product::<usize>() > MAX_NODES {
        return Err(Error::InvalidParam {
            name: "spacing",
            reason: format!(
                "grid of {n:?} nodes is too large (max {MAX_NODES}); use a larger spacing"
            ),
        });
    }
    Ok(n)
}

/// World position of node `n` (x fastest) of a grid.
fn node(origin: DVec3, s: f64, dims: [usize; 3], n: usize) -> DVec3 {
    let i = n % dims[0];
    let j = (n / dims[0]) % dims[1];
    let k = n / (dims[0] * dims[1]);
    origin + s * DVec3::new(i as f64, j as f64, k as f64)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use skin_core::camera::{Intrinsics, Rig};

    /// A ring of `n` cameras at 3 m radius and 1.6 m height looking at (0, 1, 0).
    pub(crate) fn ring(n: usize, width: u32, height: u32) -> Vec<Camera> {
        let k = Intrinsics::from_horizontal_fov(50f64.to_radians(), width, height).unwrap();
        Rig::ring(n, 3.0, 1.6, DVec3::new(0.0, 1.0, 0.0), DVec3::Y, k)
            .unwrap()
            .cameras
    }

    /// The silhouette of a sphere: pixels whose ray passes within `r` of `c`.
    pub(crate) fn sphere_mask(cam: &Camera, c: DVec3, r: f64) -> Mask {
        let k = &cam.intrinsics;
        Mask::from_fn(k.width, k.height, |x, y| {
            let ray = cam.ray(DVec2::new(f64::from(x), f64::from(y))).unwrap();
            let rel = c - ray.origin;
            (rel - rel.dot(ray.direction) * ray.direction).length() < r
        })
    }

    const C: DVec3 = DVec3::new(0.0, 1.0, 0.0);
    const R: f64 = 0.3;

    fn sphere_hull(n: usize) -> (Vec<Camera>, ContourRayHull) {
        let cams = ring(n, 320, 240);
        let masks: Vec<Mask> = cams.iter().map(|c| sphere_mask(c, C, R)).collect();
        let hull = ContourRayHull::new(&cams, &masks, &ContourRayHullParams::default()).unwrap();
        (cams, hull)
    }

    /// One pixel at 3 m for these cameras, m.
    fn pixel_m(cam: &Camera) -> f64 {
        3.0 / cam.intrinsics.fx
    }

    #[test]
    fn propagated_ray_is_the_nearest_ray_up_to_a_pixel() {
        let cams = ring(1, 320, 240);
        let cam = &cams[0];
        let cone = ConeDistance::new(cam, &sphere_mask(cam, C, R), 16).unwrap();
        let o = cam.centre();
        let mut worst: f64 = 0.0;
        for i in 0..400 {
            let t = i as f64 / 400.0;
            // Points on a plane through the sphere centre, inside and outside the cone.
            let p = C + DVec3::new(0.5 * (t * 37.0).sin(), 0.5 * (t * 23.0).cos(), 0.0);
            let ConeSample::Near { signed_m, .. } = cone.sample(p).unwrap() else {
                continue;
            };
            let brute = cone
                .rays
                .iter()
                .map(|v| {
                    let rel = p - o;
                    (rel - rel.dot(*v) * *v).length()
                })
                .fold(f64::INFINITY, f64::min);
            worst = worst.max((signed_m.abs() - brute).abs());
        }
        assert!(worst < pixel_m(cam), "worst {worst} m");
    }

    #[test]
    fn sphere_centre_is_one_radius_deep() {
        let (cams, hull) = sphere_hull(8);
        let d = hull.distance(C).unwrap();
        assert_eq!(d.region, HullRegion::Inside);
        let tol = 2.0 * pixel_m(&cams[0]);
        assert!((d.signed_m - R).abs() < tol, "{} vs {R}", d.signed_m);
        // Inside the sphere: the sphere of radius R − δ around p is inside the hull.
        for (i, e) in [
            DVec3::X,
            DVec3::Y,
            DVec3::Z,
            DVec3::new(1.0, 1.0, 0.0).normalize(),
        ]
        .into_iter()
        .enumerate()
        {
            let delta = 0.05 * (i + 1) as f64;
            let d = hull.distance(C + delta * e).unwrap();
            assert!(d.signed_m > R - delta - tol, "{e}: {}", d.signed_m);
            assert!(d.signed_m < R + tol, "{e}: {}", d.signed_m);
        }
    }

    #[test]
    fn outside_points_use_the_polygon() {
        let (_, hull) = sphere_hull(8);
        for e in [DVec3::X, DVec3::Z, DVec3::new(1.0, 0.0, 1.0).normalize()] {
            let dist = 0.7;
            let d = hull.distance(C + dist * e).unwrap();
            assert_eq!(d.region, HullRegion::Outside);
            // The hull holds the sphere and, seen from a ring of eight, lies within the
            // circumscribed octagon of the sphere (1/cos 22.5° ≈ 1.08) plus perspective.
            assert!(d.signed_m > -(dist - R) - 0.03, "{e}: {}", d.signed_m);
            assert!(d.signed_m < -(dist - 1.2 * R) + 0.03, "{e}: {}", d.signed_m);
            assert!(
                d.gradient.dot(-e) > 0.9,
                "gradient {} points to the hull",
                d.gradient
            );
        }
        let bb = hull.polygon().bounding_box().unwrap();
        assert!((bb.center() - C).length() < 0.05);
    }

    #[test]
    fn gradient_matches_finite_differences() {
        let (_, hull) = sphere_hull(8);
        let h = 1e-6;
        for p in [
            C + DVec3::new(0.1, 0.05, -0.02),
            C + DVec3::new(-0.05, -0.15, 0.1),
            C + DVec3::new(0.6, 0.0, 0.1),
        ] {
            let d = hull.distance(p).unwrap();
            for e in [DVec3::X, DVec3::Y, DVec3::Z] {
                let fd = (hull.distance(p + h * e).unwrap().signed_m
                    - hull.distance(p - h * e).unwrap().signed_m)
                    / (2.0 * h);
                assert!(
                    (fd - d.gradient.dot(e)).abs() < 1e-4,
                    "{p} {e}: {fd} vs {}",
                    d.gradient
                );
            }
        }
    }

    #[test]
    fn bad_inputs_are_clear_errors() {
        let cams = ring(2, 64, 48);
        let good = sphere_mask(&cams[0], C, R);
        // Empty silhouette in camera 1.
        let e = ContourRayHull::new(
            &cams,
            &[good.clone(), Mask::new(64, 48)],
            &Default::default(),
        )
        .unwrap_err();
        assert_eq!(e.contexts(), [Context::Camera(1)]);
        assert!(matches!(e.root(), Error::Empty { .. }), "{e}");
        // Wrong size.
        let e = ContourRayHull::new(
            &cams,
            &[good.clone(), Mask::new(10, 48)],
            &Default::default(),
        )
        .unwrap_err();
        assert!(matches!(e.root(), Error::SizeMismatch { .. }), "{e}");
        // Count mismatch.
        let e = ContourRayHull::new(&cams, std::slice::from_ref(&good), &Default::default())
            .unwrap_err();
        assert!(matches!(e, Error::SizeMismatch { .. }), "{e}");
        // Silhouettes that do not intersect.
        let far = sphere_mask(&cams[1], C + DVec3::new(0.0, 0.0, 1.2), 0.1);
        let e = ContourRayHull::new(&cams, &[good.clone(), far], &Default::default()).unwrap_err();
        assert!(matches!(e, Error::Empty { .. }), "{e}");
        // Bad params and points.
        let p = ContourRayHullParams::default().with_polygon_spacing_m(f64::NAN);
        assert!(ContourRayHull::new(&cams, &[good.clone(), good.clone()], &p).is_err());
        let cone = ConeDistance::new(&cams[0], &good, 8).unwrap();
        assert!(matches!(
            cone.sample(DVec3::NAN),
            Err(Error::Core(skin_core::Error::NonFinite { .. }))
        ));
        // Behind the camera: far outside, not an error.
        let behind = cams[0].centre() + (cams[0].centre() - C);
        assert_eq!(cone.sample(behind).unwrap(), ConeSample::Far);
    }
}
