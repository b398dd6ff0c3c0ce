//! Surface proxies rendered per camera (Vlasic 2010 §3.3): the **visual hull** of the
//! silhouettes in pass 1 and the hole-filled mesh of pass 1 in pass 2, each as a [`DepthMap`]
//! that gives the soft depth constraints `z̄_i` of Eq. 3.3 and the large-jump discontinuities
//! of §3.3.1.
//!
//! The visual hull is image-based: for each silhouette pixel of a view, the depth at which
//! its ray first enters the intersection of the other cameras' silhouette cones. A point `p`
//! is inside camera `j`'s cone when its projection lies inside `j`'s silhouette, measured with
//! the silhouette's signed distance `sd_j` (pixels, negative inside; bilinear between pixel
//! centres, so the cone's boundary is continuous). The ray is **sphere-traced**: at a point
//! outside the hull some camera `j` has `sd_j(π_j(p)) = s > 0`, and a 3D move shorter than
//! `s · z_j / f_j` (its camera depth `z_j`, focal length `f_j`) keeps the projection outside,
//! so the march steps `κ · max_j s · z_j / f_j` (κ = [`PolygonalHullParams::step_safety`]) and
//! never jumps over a part of the hull thicker than a pixel; the entry is then refined by
//! bisection of `max_j sd_j = 0` to [`PolygonalHullParams::tolerance_m`]. Outside a camera's
//! image the signed distance continues as the distance to the image border plus the value at
//! the border (the image edge bounds the cone, as the silhouette does).

use serde::{Deserialize, Serialize};
use skin_core::camera::{Camera, MIN_DEPTH_M};
use skin_core::check;
use skin_core::image::{sample_bilinear, signed_distance, GrayF32Image, Mask};
use skin_core::math::{DVec2, DVec3};
use skin_core::mesh::TriMesh;
use skin_core::raster::{Buffers, Rasterizer, RenderParams};

use rayon::prelude::*;
use std::cell::RefCell;
use std::sync::atomic::{AtomicU64, Ordering};

use crate::{DepthMap, Error, Result, ResultExt};

/// Knobs of the image-based visual hull. The thesis does not describe how its visual hull
/// is computed; these are this implementation's.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PolygonalHullParams {
    /// Where the march along a pixel ray starts, m from the camera centre. Default 0.05.
    pub near_m: f64,
    /// Where it gives up, m. Default 30 (a studio is a few metres across).
    pub far_m: f64,
    /// Accuracy of the entry point along the ray (bisection), m. Default 0.1 mm.
    pub tolerance_m: f64,
    /// Fraction κ of the conservative sphere-tracing step taken (≤ 1; the bound assumes a
    /// small move, so κ < 1 absorbs its first-order error). Default 0.5.
    pub step_safety: f64,
    /// Smallest step of the march, m (where the signed distances are near zero). Default 1 mm.
    pub min_step_m: f64,
}

impl Default for PolygonalHullParams {
    fn default() -> Self {
        Self {
            near_m: 0.05,
            far_m: 30.0,
            tolerance_m: 1e-4,
            step_safety: 0.5,
            min_step_m: 1e-3,
        }
    }
}

impl PolygonalHullParams {
    fn validate(&self) -> Result<()> {
        check::positive("near_m", self.near_m)?;
        check::positive("far_m", self.far_m)?;
        check::positive("tolerance_m", self.tolerance_m)?;
        check::in_range("step_safety", self.step_safety, 1e-3..=1.0)?;
        check::positive("min_step_m", self.min_step_m)?;
        if self.far_m <= self.near_m {
            return Err(Error::InvalidParam {
                name: "far_m",
                reason: format!("must exceed near_m = {}", self.near_m),
            });
        }
        Ok(())
    }
}

/// The visual hull of §3.3 as a proxy surface: the silhouettes of a calibrated rig with their
/// signed distances, ready to answer inside/outside queries and to render the hull's depth in
/// any of its cameras.
#[derive(Debug, Clone)]
pub struct PolygonalHull {
    cameras: Vec<Camera>,
    silhouettes: Vec<Mask>,
    signed: Vec<GrayF32Image>,
    /// Per camera, the gain `G` of [`PolygonalHull::contains`]'s certificates (px of signed
    /// distance per unit of `‖δ‖ / z` at the image centre); `None` where certificates do not
    /// apply (radial distortion, a non-finite or degenerate signed-distance image).
    gains: Vec<Option<f64>>,
    /// Identifies this hull's (and its clones') certificates in the per-thread cache.
    id: u64,
}

/// Source of [`PolygonalHull`] identities.
static NEXT_HULL_ID: AtomicU64 = AtomicU64::new(1);

/// A ball of world points around `centre` that camera `c` sees all inside (`inside`) or all
/// outside its silhouette: see [`PolygonalHull::contains`].
#[derive(Debug, Clone, Copy)]
struct Certificate {
    centre: DVec3,
    /// Squared radius, m²; negative for no certificate.
    radius2: f64,
    inside: bool,
}

impl Certificate {
    const NONE: Self = Self {
        centre: DVec3::ZERO,
        radius2: -1.0,
        inside: false,
    };
}

/// The certificate gain of a camera (see [`PolygonalHull::contains`]): `(L + 1) · max(fx, fy)`
/// with `L` the Lipschitz constant (px per px) of the bilinear signed distance, which is at
/// most `√(Lx² + Ly²)` for the largest differences `Lx`, `Ly` of horizontally and vertically
/// adjacent samples (the bilinear gradient's components are convex combinations of those
/// differences); `+ 1` for the continuation off the image (`sd(clamp(p)) + ‖p − clamp(p)‖`:
/// per axis the clamped part and the excess change by at most the pixel's change). Inflated
/// by 10⁻⁹ for rounding. `None` with radial distortion (whose pixel map is not bounded here)
/// or a non-finite or smaller than 2 × 2 image.
fn certificate_gain(camera: &Camera, signed: &GrayF32Image) -> Option<f64> {
    if camera.distortion.k1 != 0.0 {
        return None;
    }
    let (w, h) = signed.dimensions();
    if w < 2 || h < 2 {
        return None;
    }
    let data = signed.as_raw();
    if !data.iter().all(|v| v.is_finite()) {
        return None;
    }
    let (mut lx, mut ly) = (0.0f64, 0.0f64);
    for row in data.chunks_exact(w as usize) {
        for p in row.windows(2) {
            lx = lx.max((f64::from(p[1]) - f64::from(p[0])).abs());
        }
    }
    for (r0, r1) in data
        .chunks_exact(w as usize)
        .zip(data.chunks_exact(w as usize).skip(1))
    {
        for (a, b) in r0.iter().zip(r1) {
            ly = ly.max((f64::from(*b) - f64::from(*a)).abs());
        }
    }
    let k = &camera.intrinsics;
    let gain = ((lx * lx + ly * ly).sqrt() + 1.0) * k.fx.max(k.fy) * (1.0 + 1e-9);
    (gain.is_finite() && gain > 0.0).then_some(gain)
}

impl PolygonalHull {
    /// The hull of `silhouettes[c]` seen by `cameras[c]`.
    ///
    /// # Errors
    /// [`Error::Empty`] for fewer than two cameras or an empty silhouette;
    /// [`Error::SizeMismatch`] for mismatched counts or a silhouette whose size is not its
    /// camera's image (with [`Error::At`] naming the camera).
    pub fn new(cameras: &[Camera], silhouettes: &[Mask]) -> Result<Self> {
        if cameras.len() < 2 {
            return Err(Error::Empty {
                what: "visual hull cameras (need at least two)",
            });
        }
        check::same_size("silhouettes per camera", cameras.len(), silhouettes.len())?;
        let signed = cameras
            .par_iter()
            .zip(silhouettes)
            .enumerate()
            .map(|(c, (cam, mask))| {
                let size = (cam.intrinsics.width, cam.intrinsics.height);
                if mask.dimensions() != size {
                    return Err(Error::SizeMismatch {
                        what: "silhouette pixels vs camera image",
                        expected: size.0 as usize * size.1 as usize,
                        got: mask.pixel_count(),
                    })
                    .at(crate::Context::Camera(c));
                }
                if mask.is_empty() {
                    return Err(Error::Empty {
                        what: "silhouette (no foreground pixel)",
                    })
                    .at(crate::Context::Camera(c));
                }
                Ok(signed_distance(mask)?)
            })
            .collect::<Result<Vec<_>>>()?;
        let gains = cameras
            .iter()
            .zip(&signed)
            .map(|(cam, sd)| certificate_gain(cam, sd))
            .collect();
        Ok(Self {
            cameras: cameras.to_vec(),
            silhouettes: silhouettes.to_vec(),
            signed,
            gains,
            id: NEXT_HULL_ID.fetch_add(1, Ordering::Relaxed),
        })
    }

    /// The rig's cameras.
    pub fn cameras(&self) -> &[Camera] {
        &self.cameras
    }

    /// The silhouettes.
    pub fn silhouettes(&self) -> &[Mask] {
        &self.silhouettes
    }

    /// Signed distance (px, negative inside) of `p`'s projection to camera `c`'s silhouette,
    /// and the point's camera depth; `None` behind the camera.
    ///
    /// The hot loop of the hull (every march step of [`PolygonalHull::depth_map`], every cell of
    /// the matching grids through [`PolygonalHull::contains`]): the camera point is transformed
    /// once and projected term for term as [`Camera::project`] does (the same values bit for
    /// bit, without the second transform and the `Result`), then looked up by
    /// [`sample_bilinear`], which reads the samples from the raw buffer.
    #[inline]
    fn camera_distance(&self, c: usize, p: DVec3) -> Option<(f64, f64)> {
        self.camera_distance_n2(c, p).map(|(sd, z, _)| (sd, z))
    }

    /// [`PolygonalHull::camera_distance`] with the squared length of the point's normalised
    /// image coordinates `(x/z, y/z)` (for the certificates of [`PolygonalHull::contains`]).
    #[inline]
    fn camera_distance_n2(&self, c: usize, p: DVec3) -> Option<(f64, f64, f64)> {
        let cam = &self.cameras[c];
        let pc = cam.camera_from_world().transform_point3(p);
        let z = pc.z;
        if z <= 1e-6 || !pc.is_finite() || z <= MIN_DEPTH_M {
            return None;
        }
        let k = &cam.intrinsics;
        let n = DVec2::new(pc.x / z, pc.y / z);
        let px = cam.distortion.distort(k, k.pixel_from_normalized(n))?;
        let (w, h) = (f64::from(k.width - 1), f64::from(k.height - 1));
        let clamped = DVec2::new(px.x.clamp(0.0, w), px.y.clamp(0.0, h));
        let sd = sample_bilinear(&self.signed[c], clamped)?;
        Some((sd + (px - clamped).length(), z, n.length_squared()))
    }

    /// Largest signed distance over the cameras other than `skip` (px; ≤ 0 inside the hull)
    /// and the safe sphere-tracing step there (m).
    fn hull_distance(&self, p: DVec3, skip: Option<usize>) -> (f64, f64) {
        let mut worst = f64::NEG_INFINITY;
        let mut step: f64 = 0.0;
        for c in 0..self.cameras.len() {
            if Some(c) == skip {
                continue;
            }
            match self.camera_distance(c, p) {
                Some((sd, z)) => {
                    worst = worst.max(sd);
                    if sd > 0.0 {
                        step = step.max(sd * z / self.cameras[c].intrinsics.fx.max(1e-9));
                    }
                }
                // Behind a camera: outside its cone; no bound on the step from it.
                None => worst = worst.max(f64::INFINITY),
            }
        }
        (worst, step)
    }

    /// Whether `p` lies inside every camera's silhouette cone.
    ///
    /// The same answer as `hull_distance(p, None).0 <= 0.0`, found with less work for runs of
    /// nearby queries (a matching grid's cells): each thread keeps, per camera, a
    /// **certificate** — a ball around the last point it evaluated in which that camera's
    /// answer cannot change — and answers from it where the query lies inside the ball.
    /// Why it is exact: for a point at camera depth `z₀` with normalised image coordinates
    /// `n₀` and a move `δ` (`‖δ‖ ≤ r < z₀`), the normalised coordinates move by
    /// `‖(δx − n₀ₓδz, δy − n₀ᵧδz)‖ / (z₀ + δz) ≤ √(1 + ‖n₀‖²) · r / (z₀ − r)` (the 2 × 3
    /// matrix's largest singular value is `√(1 + ‖n₀‖²)`), the pixel by at most `max(fx, fy)`
    /// times that (no distortion), and the signed distance by at most `L + 1` times the pixel
    /// (see `certificate_gain`). So with the gain `G = (L + 1) max(fx, fy)` and
    /// `K = G √(1 + ‖n₀‖²)`, every point within `r = a z₀ / (K + a)` of the evaluated point
    /// has a signed distance of the same sign as `sd₀`, for `a = |sd₀|` less a margin for
    /// rounding (10⁻⁹ relative + 10⁻⁶ px, many orders above the ≈ 10⁻¹³ px of the
    /// arithmetic), and `r` is also kept below `z₀ / 2` so that the point stays in front of the
    /// camera. Cameras with radial distortion are always evaluated.
    pub fn contains(&self, p: DVec3) -> bool {
        // First every camera's certificate (cheap: a squared distance each), so that a
        // certified outside answers at once; then the others evaluated, stopping at the first
        // camera that sees `p` outside its silhouette (or cannot see it). The camera that
        // rejected the thread's previous point is evaluated first: neighbouring queries are
        // mostly rejected by the same camera. The answer does not depend on the order.
        let n = self.cameras.len();
        CERTIFICATES.with_borrow_mut(|(id, certs)| {
            if *id != self.id || certs.len() != n {
                *id = self.id;
                certs.clear();
                certs.resize(n, Certificate::NONE);
            }
            // Bit c: camera c is certified inside.
            let mut known = 0u64;
            for (c, cert) in certs.iter().enumerate() {
                if (p - cert.centre).length_squared() < cert.radius2 {
                    #[cfg(test)]
                    CERTIFIED.with(|k| k.set(k.get() + 1));
                    if !cert.inside {
                        return false;
                    }
                    if c < 64 {
                        known |= 1 << c;
                    }
                }
            }
            let mut inside = |c: usize| {
                let d = self.camera_distance_n2(c, p);
                if let (Some(gain), Some((sd, z, n2)), Some(cert)) =
                    (self.gains[c], d, certs.get_mut(c))
                {
                    *cert = certificate(p, sd, z, n2, gain);
                }
                d.is_some_and(|(sd, _, _)| sd <= 0.0 || sd.is_nan())
            };
            let first = LAST_REJECTING.with(std::cell::Cell::get).min(n - 1);
            let certified = |c: usize| c < 64 && known & (1 << c) != 0;
            if !certified(first) && !inside(first) {
                return false;
            }
            for c in (0..n).filter(|&c| c != first && !certified(c)) {
                if !inside(c) {
                    LAST_REJECTING.with(|l| l.set(c));
                    return false;
                }
            }
            true
        })
    }

    /// [`PolygonalHull::contains`] without the certificates: every camera evaluated (the
    /// reference of the unit test).
    #[cfg(test)]
    fn contains_evaluated(&self, p: DVec3) -> bool {
        (0..self.cameras.len()).all(|c| {
            self.camera_distance(c, p)
                .is_some_and(|(sd, _)| sd <= 0.0 || sd.is_nan())
        })
    }

    /// The hull's depth along each silhouette pixel ray of camera `view` (first entry point;
    /// `NaN` outside the silhouette and where the ray misses the other cones).
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`] for a bad view; [`Error::InvalidParam`] for bad params.
    pub fn depth_map(&self, view: usize, params: &PolygonalHullParams) -> Result<DepthMap> {
        params.validate()?;
        check::index("visual hull view", view, self.cameras.len())?;
        let cam = &self.cameras[view];
        let mask = &self.silhouettes[view];
        let (w, h) = (cam.intrinsics.width, cam.intrinsics.height);
        let depth: Vec<f64> = (0..w as usize * h as usize)
            .into_par_iter()
            .map(|i| {
                let (x, y) = ((i % w as usize) as u32, (i / w as usize) as u32);
                if !mask.get(x, y) {
                    return Ok(f64::NAN);
                }
                let ray = cam.ray(DVec2::new(f64::from(x), f64::from(y)))?;
                Ok(self
                    .entry_depth(ray.origin, ray.direction, view, params)
                    .unwrap_or(f64::NAN))
            })
            .collect::<Result<_>>()?;
        DepthMap::new(w, h, depth)
    }

    /// [`PolygonalHull::depth_map`] of every camera.
    ///
    /// # Errors
    /// As [`PolygonalHull::depth_map`], with [`Error::At`] naming the camera.
    pub fn depth_maps(&self, params: &PolygonalHullParams) -> Result<Vec<DepthMap>> {
        (0..self.cameras.len())
            .map(|c| self.depth_map(c, params).at(crate::Context::Camera(c)))
            .collect()
    }

    /// First depth along the ray at which every other cone contains the point.
    fn entry_depth(
        &self,
        origin: DVec3,
        dir: DVec3,
        view: usize,
        params: &PolygonalHullParams,
    ) -> Option<f64> {
        let at = |t: f64| self.hull_distance(origin + dir * t, Some(view));
        let mut t_prev = params.near_m;
        let (d, mut step) = at(t_prev);
        if d <= 0.0 {
            return Some(t_prev);
        }
        while t_prev < params.far_m {
            let t = t_prev + (params.step_safety * step).max(params.min_step_m);
            let (d_t, step_t) = at(t);
            if d_t <= 0.0 {
                // Bisect the crossing of max_j sd_j = 0 in [t_prev, t].
                let (mut lo, mut hi) = (t_prev, t);
                while hi - lo > params.tolerance_m {
                    let mid = 0.5 * (lo + hi);
                    if at(mid).0 <= 0.0 {
                        hi = mid;
                    } else {
                        lo = mid;
                    }
                }
                return Some(hi);
            }
            (t_prev, step) = (t, step_t);
        }
        None
    }
}

thread_local! {
    /// The camera that last found a [`PolygonalHull::contains`] query outside, per thread.
    static LAST_REJECTING: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
    /// Per thread, the hull whose certificates these are and one certificate per camera.
    static CERTIFICATES: RefCell<(u64, Vec<Certificate>)> = const { RefCell::new((0, Vec::new())) };
}

#[cfg(test)]
thread_local! {
    /// Camera answers given by a certificate on this thread (unit tests).
    static CERTIFIED: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
}

/// The certificate of a point evaluated in a camera with signed distance `sd` (px), camera
/// depth `z` and squared normalised image radius `n2`, for the camera's `gain` (see
/// [`PolygonalHull::contains`]); [`Certificate::NONE`] where the margin leaves nothing.
fn certificate(p: DVec3, sd: f64, z: f64, n2: f64, gain: f64) -> Certificate {
    let a = sd.abs() * (1.0 - 1e-9) - 1e-6;
    let k = gain * (1.0 + n2).sqrt();
    let r = (a * z / (k + a)).min(0.5 * z) * (1.0 - 1e-9);
    if !(a > 0.0 && r > 0.0 && r.is_finite() && p.is_finite()) {
        return Certificate::NONE;
    }
    Certificate {
        centre: p,
        radius2: r * r,
        inside: sd < 0.0,
    }
}

/// A mesh proxy (pass 2 of §3.3: the hole-filled mesh of pass 1) rendered as `camera`'s
/// depth map through the rasteriser (both faces of each triangle, so an open mesh works too).
///
/// # Errors
/// Errors of [`Rasterizer::render`] (degenerate mesh); a camera that does not see the mesh
/// gives an empty map, not an error.
pub fn mesh_proxy_depth(camera: &Camera, mesh: &TriMesh) -> Result<DepthMap> {
    let params = RenderParams::default()
        .with_buffers(Buffers {
            mask: true,
            depth: true,
            camera_z: false,
            normal: false,
            triangle: false,
        })
        .with_cull_back_faces(false)
        .with_allow_empty(true);
    let view = Rasterizer::new(camera).render(mesh, &params)?;
    DepthMap::from_view(&view)
}

#[cfg(test)]
mod tests {
    use super::*;
    use skin_core::camera::{Intrinsics, Rig};
    use skin_core::mesh::shapes::uv_sphere;

    fn sphere_rig(n: usize) -> (Vec<Camera>, TriMesh) {
        let k = Intrinsics::from_horizontal_fov(0.6, 128, 128).unwrap();
        let rig = Rig::ring(n, 3.0, 1.0, DVec3::new(0.0, 1.0, 0.0), DVec3::Y, k).unwrap();
        let mesh = uv_sphere(DVec3::new(0.0, 1.0, 0.0), 0.4, 48, 96).unwrap();
        (rig.cameras, mesh)
    }

    /// [`sphere_rig`] and the visual hull of its rendered silhouettes.
    fn sphere_hull(n: usize) -> (Vec<Camera>, TriMesh, PolygonalHull) {
        let (cams, mesh) = sphere_rig(n);
        let masks: Vec<Mask> = cams
            .iter()
            .map(|c| {
                Rasterizer::new(c)
                    .render(&mesh, &RenderParams::default())
                    .unwrap()
                    .silhouette()
            })
            .collect();
        let hull = PolygonalHull::new(&cams, &masks).unwrap();
        (cams, mesh, hull)
    }

    #[test]
    fn hull_of_a_sphere_lies_on_or_outside_it_and_close() {
        let (cams, mesh, hull) = sphere_hull(6);
        let vh = hull.depth_map(0, &PolygonalHullParams::default()).unwrap();
        let truth = mesh_proxy_depth(&cams[0], &mesh).unwrap();
        // Gap between the hull and the sphere along the rays (m; > 0 in front of it).
        let mut gap: Vec<f64> = vh
            .depth_m
            .iter()
            .zip(&truth.depth_m)
            .filter(|(a, b)| !a.is_nan() && !b.is_nan())
            .map(|(a, b)| b - a)
            .collect();
        gap.sort_by(f64::total_cmp);
        let n = gap.len();
        assert!(n > 500, "{n}");
        // The hull contains the sphere up to the silhouettes' discretisation: a silhouette
        // boundary is placed on pixel edges, up to half a pixel (7 mm here) inside the true
        // outline, which moves grazing rim rays' entries behind the sphere. 90 % of the rays
        // enter at most 5 mm behind it, 98 % at most 1 cm, and from six views the median
        // entry is in front of the sphere by a few mm.
        let (p02, p10, median) = (gap[n / 50], gap[n / 10], gap[n / 2]);
        assert!(p02 > -0.01 && p10 > -0.005, "{p02} {p10}");
        assert!((0.0..0.03).contains(&median), "{median}");
        assert!(hull.contains(DVec3::new(0.0, 1.0, 0.0)));
        assert!(!hull.contains(DVec3::new(0.0, 1.6, 0.0)));
    }

    /// The hot-loop look-up (`camera_distance`, `contains`) gives bit for bit what the
    /// reference path — `Camera::project` and `sample_bilinear` — gives, on points inside,
    /// outside, off the image and behind cameras.
    #[test]
    fn fast_hull_queries_equal_the_reference_path() {
        let (cams, _, hull) = sphere_hull(6);
        let reference = |c: usize, p: DVec3| -> Option<(f64, f64)> {
            let cam = &hull.cameras[c];
            let z = cam.camera_from_world().transform_point3(p).z;
            if z <= 1e-6 {
                return None;
            }
            let px = cam.project(p).ok()?;
            let (w, h) = (
                f64::from(cam.intrinsics.width - 1),
                f64::from(cam.intrinsics.height - 1),
            );
            let clamped = DVec2::new(px.x.clamp(0.0, w), px.y.clamp(0.0, h));
            let sd = sample_bilinear(&hull.signed[c], clamped)?;
            Some((sd + (px - clamped).length(), z))
        };
        let (mut inside, mut outside, mut none) = (0, 0, 0);
        for i in 0..20_000u32 {
            // A quasi-random cloud around the sphere and out to the cameras' ring.
            let f = |k: f64| ((f64::from(i) * k).fract() - 0.5) * 8.0;
            let p = DVec3::new(f(0.618_034), 1.0 + f(0.414_214) * 0.5, f(0.732_051));
            let p = if i % 2 == 0 {
                DVec3::new(0.0, 1.0, 0.0) + (p - DVec3::new(0.0, 1.0, 0.0)) * 0.08
            } else {
                p
            };
            let mut all_in = true;
            for c in 0..cams.len() {
                let (fast, slow) = (hull.camera_distance(c, p), reference(c, p));
                assert_eq!(
                    fast.map(|(a, b)| (a.to_bits(), b.to_bits())),
                    slow.map(|(a, b)| (a.to_bits(), b.to_bits())),
                    "camera {c} at {p}"
                );
                none += usize::from(slow.is_none());
                all_in &= slow.is_some_and(|(sd, _)| sd <= 0.0 || sd.is_nan());
            }
            assert_eq!(hull.contains(p), all_in, "{p}");
            if all_in {
                inside += 1;
            } else {
                outside += 1;
            }
        }
        assert!(
            inside > 1000 && outside > 1000 && none > 100,
            "{inside} {outside} {none}"
        );
    }

    /// The certificates of `contains` change no answer: runs of nearby points (steps of
    /// 0.2–3 mm along rays through the hull and across its surface, as a matching grid's cells
    /// come) get the answer of every camera evaluated, and many camera answers come from a
    /// certificate.
    #[test]
    fn certified_hull_answers_equal_every_camera_evaluated() {
        let (cams, _, hull) = sphere_hull(6);
        let centre = DVec3::new(0.0, 1.0, 0.0);
        CERTIFIED.with(|k| k.set(0));
        let (mut inside, mut outside, mut queries) = (0usize, 0usize, 0usize);
        for i in 0..400u32 {
            let f = |k: f64| (f64::from(i) * k).fract() - 0.5;
            // A ray from a camera (or from a point off the ring) towards near the sphere.
            let from = if i % 3 == 0 {
                cams[i as usize % cams.len()].centre()
            } else {
                centre + DVec3::new(f(0.318_7), f(0.207_107), f(0.577_215)).normalize() * 2.5
            };
            let aim = centre + DVec3::new(f(0.618_034), f(0.414_214), f(0.732_051)) * 0.9;
            let dir = (aim - from).normalize();
            let step = 2e-4 + 3e-3 * (f(0.141_421) + 0.5);
            let t0 = (centre - from).dot(dir) - 0.6;
            let mut t = t0;
            while t < t0 + 1.2 {
                // A small sideways wobble, as the midpoints of a grid's closest approaches.
                let p = from + dir * t + DVec3::new(1.0, 0.3, -0.7) * (1e-4 * (t * 997.0).sin());
                let (fast, slow) = (hull.contains(p), hull.contains_evaluated(p));
                assert_eq!(fast, slow, "{p}");
                if slow {
                    inside += 1;
                } else {
                    outside += 1;
                }
                queries += 1;
                t += step;
            }
        }
        let certified = CERTIFIED.with(std::cell::Cell::get);
        assert!(inside > 10_000 && outside > 10_000, "{inside} {outside}");
        // More than one camera answer per query came from a certificate, on average (2.4 when
        // written; each query needs 1–6 camera answers).
        assert!(certified > queries, "{certified} of {queries} queries");
        // Bad input: a non-finite point is outside, as before.
        assert!(!hull.contains(DVec3::NAN) && !hull.contains_evaluated(DVec3::NAN));
    }

    #[test]
    fn rejects_bad_input() {
        let (cams, _) = sphere_rig(2);
        let empty = Mask::new(128, 128);
        assert!(PolygonalHull::new(&cams[..1], std::slice::from_ref(&empty)).is_err());
        assert!(PolygonalHull::new(&cams, &[empty.clone(), empty.clone()]).is_err());
        let small = Mask::from_fn(8, 8, |_, _| true);
        assert!(PolygonalHull::new(&cams, &[small.clone(), small]).is_err());
        let full = Mask::from_fn(128, 128, |x, _| x > 10);
        let hull = PolygonalHull::new(&cams, &[full.clone(), full]).unwrap();
        assert!(hull.depth_map(2, &PolygonalHullParams::default()).is_err());
        let bad = PolygonalHullParams {
            far_m: 0.01,
            ..Default::default()
        };
        assert!(hull.depth_map(0, &bad).is_err());
    }
}
