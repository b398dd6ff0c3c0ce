//! Pairwise matching of neighbouring views (Vlasic 2010 §3.3.2): four matching metrics,
//! epipolar-plane grids of matching costs, and the lowest-cost path through each grid by a
//! four-state dynamic programme after Criminisi et al. [41], which also finds the depth
//! discontinuities that §3.3.1 removes from the integration.
//!
//! **Epipolar planes.** For a pair (left, right) the planes through both camera centres are
//! taken one per row of the left image (the plane through the ray of the row's centre pixel),
//! so neighbouring planes are about a pixel apart. Each plane meets each image in a line
//! (`l = K⁻ᵀ m` for the plane normal `m` in the camera frame; the cameras must be
//! undistorted — undistort images first); the line is sampled "one pixel at a time in each
//! view" at the integer pixels it crosses, keeping those where the view's integrated surface
//! exists. Samples are ordered by the angle between their ray and the baseline, which orders
//! the points of an opaque surface the same way in both views.
//!
//! **Grid.** Cell `(a, b)` pairs left sample `a` with right sample `b`; their rays meet (closest
//! approach) at a point `X`. The cell is evaluated only if `X` lies within
//! [`MatchingParams::band_m`] of both views' guide surfaces along their rays (pass 1: the
//! integrated surfaces themselves; pass 2: the proxy mesh, Figure 3-6c), the two rays pass
//! within two pixel footprints of each other, and `X` is inside the visual hull when one is
//! given (Figure 3-6's light blue). Other cells cost `∞`.
//!
//! **Metrics** ([`MatchMetric`]): the full-on image window, the stack of the six half-on
//! images, the surface-based metric (5 × 5 windows of surface points compared under their
//! optimal rigid alignment, rendered each way and the larger of the two mean distances taken
//! — the thesis' best) and the illumination stack projected through the aligned surface
//! windows. Image metrics are mean squared differences over the window.
//!
//! **Path.** States (Criminisi's four): a match reached by a step in the left view (diagonal
//! or left-slanted), a match reached by a step in the right view only (right-slanted), left
//! occluded, right occluded. A match costs its cell, an occluded sample costs
//! [`MatchingParams::occlusion_cost`] × the grid's median cost, and entering or leaving an
//! occlusion adds [`MatchingParams::discontinuity_penalty`] × that. Matches costing at most
//! [`MatchingParams::good_cost`] × the median are kept (Figure 3-6's green); jumps of the
//! matched depth above 1 cm per pixel ([`IntegrationParams::match_jump_m`](crate::IntegrationParams))
//! between consecutive matches are depth discontinuities (red).

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use skin_core::camera::Camera;
use skin_core::check;
use skin_core::image::{GrayF32Image, Mask};
use skin_core::math::{DVec2, DVec3};
use skin_core::mesh::TriMesh;
use skin_core::stats::median;

use crate::integrate::{camera_rays, IntegrationParams};
use crate::{
    mesh_proxy_depth, DepthMap, Error, Pattern, PatternImages, PolygonalHull, Result, PATTERNS,
};

/// The four matching metrics of §3.3.2.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum MatchMetric {
    /// Pixel windows of the full-on (tracking) image: traditional stereo.
    FullOnWindow,
    /// Pixel windows of the stack of the six half-on images.
    IlluminationStack,
    /// Surface patches under their optimal rigid alignment, symmetric (the thesis' best).
    #[default]
    SurfaceRigid,
    /// The illumination stacks projected onto the corresponding surface patches.
    ProjectedIllumination,
}

impl MatchMetric {
    /// All four, in the thesis' order.
    pub const ALL: [MatchMetric; 4] = [
        MatchMetric::FullOnWindow,
        MatchMetric::IlluminationStack,
        MatchMetric::SurfaceRigid,
        MatchMetric::ProjectedIllumination,
    ];

    fn needs_images(self) -> bool {
        self != MatchMetric::SurfaceRigid
    }
}

/// Knobs of the pairwise matching.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MatchingParams {
    /// The metric. Default [`MatchMetric::SurfaceRigid`] (§3.3.2: "usually yields the least
    /// noisy surfaces").
    pub metric: MatchMetric,
    /// Window side, px (odd). Default 5 (§3.3.2: "5 × 5 pixels").
    pub window_px: usize,
    /// Half-width of the search band around each view's guide surface along its rays, m.
    /// Default 0.2 (ours; the thesis evaluates the whole grid in pass 1 and "nearby" cells in
    /// pass 2 without a number). Issue 14, ninth session: 0.1 → 0.2 in pass 1 reached the
    /// surface where the visual hull is more than 10 cm off (the Ghost's folds) and improved
    /// every pass-2 figure of the skirt at 1024² (coverage 84.98 → 86.01 %, normal deviation
    /// 14.02 → 13.28°, merged median 1.961 → 1.728 mm, p95 33.8 → 21.3 mm) for ≈ 23 % more CPU;
    /// 0.3 was no better (docs: "Ninth session: the pass-1 band").
    pub band_m: f64,
    /// Cost of an occluded sample, in units of the grid's median cost. Default 1 (ours).
    pub occlusion_cost: f64,
    /// Cost of entering or leaving an occlusion, in units of the grid's median cost.
    /// Default 2 (ours).
    pub discontinuity_penalty: f64,
    /// Matches costing more than this many grid medians are not used. Default 1.5 (ours).
    pub good_cost: f64,
    /// Matched depth jumps above this per pixel (m, at the thesis' width, scaled like
    /// [`IntegrationParams::jump_threshold_m`]) are discontinuities. Default 0.01 (§3.3.1).
    pub jump_m: f64,
    /// Coarse-to-fine matching (ours; the thesis evaluates the whole band at full
    /// resolution). The pair is first matched at half resolution (cameras, surfaces, guides
    /// and images halved; the same band in metres); at full resolution a sample's cells are
    /// then evaluated only where its ray depth lies within [`MatchingParams::coarse_band_px`]
    /// pixel footprints of the depths the coarse lowest-cost paths give the 3 × 3 coarse
    /// pixels around it (samples without a coarse path depth keep the whole band). Criminisi's
    /// programme costs O(samples × band) per plane and the surface metric dominates it: the
    /// coarse pass costs about an eighth, and the narrow band cuts the full-resolution cells
    /// several times. Applied to images of at least 128 × 128 pixels. Default false here
    /// (the thesis's matching); pass 1 of the two-pass pipeline turns it on
    /// ([`SurfaceParams::pass1`](crate::SurfaceParams::pass1), issue 14, tenth session: with
    /// the ±20 cm band, at 1024² pass 2's figures stayed within 0.26 point / 0.02° and the
    /// example's CPU fell 12 %; with the ±10 cm band of the sixth session it had cost the
    /// 1024² merged median its goal; `docs/photometric-normals.md`, *Tenth session: pass-1
    /// speed*).
    pub coarse_to_fine: bool,
    /// Half-width of the full-resolution band around the coarse path, in pixel footprints
    /// (depth / focal length) along each ray. Default 4 (ours: a coarse pixel is two, and
    /// its match is quantised to it).
    pub coarse_band_px: f64,
    /// Sub-pixel matches (ours, issue 14; standard in stereo, not in the thesis): see
    /// [`SubPixel`]. Default [`SubPixel::Off`] (the thesis: matches at whole samples).
    #[serde(default)]
    pub subpixel: SubPixel,
    /// [`SubPixel::PathFit`]: path steps each side of a match in its line fit. Default 3.
    #[serde(default = "default_subpixel_window")]
    pub subpixel_window: usize,
    /// Contour-aware surface windows (ours, issue 14, tenth session; beyond the thesis, whose
    /// §3.3.2 compares whole 5 × 5 windows): `Some(j)` leaves out of a surface-metric window
    /// every point whose depth along its ray differs from the window centre's by more than `j`
    /// per pixel of (Chebyshev) distance from the centre (m at the thesis's width, scaled like
    /// [`IntegrationParams::jump_threshold_m`]), in both windows of a comparison (the view's
    /// own surface and the other surface rendered into it), so each window keeps only its
    /// centre's side of an occluding contour. Why: at a contour a whole window straddles
    /// the foreground and the background, and the background part differs between the views
    /// (each sees a different stretch of it behind the occluder), so the cost beside every
    /// contour is wrong — stereo's "foreground fattening", cured there by adaptive windows.
    /// The metric already compares partial windows (the pairs where both points exist, ∞ if
    /// fewer than half). Only [`MatchMetric::SurfaceRigid`] uses it. Default `None` (the
    /// thesis's whole windows). `Some(0.01)` improved every pass-2 figure of the skirt at
    /// 1024² (coverage 86.01 → 86.29 %, normal deviation 13.28 → 13.19°, merged p95 21.30 →
    /// 17.58 mm) and pass 1 more, but at 256² (the integration test) pass 1's merged p95 fell
    /// to 18.9 mm and pass 2's stayed at 22.9 mm, against that test's bound of pass 1's + 1 mm,
    /// so it is not the default (docs: "Windows at occluding contours").
    #[serde(default)]
    pub contour_jump_m: Option<f64>,
}

fn default_subpixel_window() -> usize {
    3
}

/// How a match's depth is refined below the sample spacing ([`MatchingParams::subpixel`]).
///
/// Without refinement a matched depth is one of the depths where the pixel's ray meets the
/// other view's whole-pixel rays, and Eq. 3.4 pulls the surface onto those steps. Either
/// refinement gives each view a fractional sample of the other view and interpolates the
/// matched depth linearly between the two whole samples around it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum SubPixel {
    /// Whole samples (the thesis).
    #[default]
    Off,
    /// The vertex of the parabola through the costs of the cells `(a, b − 1)`, `(a, b)`,
    /// `(a, b + 1)` for the left view's depth (`(a ± 1, b)` for the right's), within half a
    /// sample; whole where a cost is missing or the three are not convex.
    CostParabola,
    /// The lowest-cost path's own trend: a least-squares line of the right sample against the
    /// left one (and the converse) through the path's matches within
    /// [`MatchingParams::subpixel_window`] steps, not across discontinuities or occlusions,
    /// within a sample of the match.
    PathFit,
}

impl Default for MatchingParams {
    fn default() -> Self {
        Self {
            metric: MatchMetric::default(),
            window_px: 5,
            band_m: 0.2,
            occlusion_cost: 1.0,
            discontinuity_penalty: 2.0,
            good_cost: 1.5,
            jump_m: IntegrationParams::default().match_jump_m,
            coarse_to_fine: false,
            coarse_band_px: 4.0,
            subpixel: SubPixel::Off,
            subpixel_window: 3,
            contour_jump_m: None,
        }
    }
}

impl MatchingParams {
    fn validate(&self) -> Result<()> {
        if self.window_px == 0 || self.window_px.is_multiple_of(2) {
            return Err(Error::InvalidParam {
                name: "window_px",
                reason: format!("must be odd and positive, got {}", self.window_px),
            });
        }
        check::positive("band_m", self.band_m)?;
        check::positive("occlusion_cost", self.occlusion_cost)?;
        check::non_negative("discontinuity_penalty", self.discontinuity_penalty)?;
        check::positive("good_cost", self.good_cost)?;
        check::positive("jump_m", self.jump_m)?;
        check::positive("coarse_band_px", self.coarse_band_px)?;
        if let Some(j) = self.contour_jump_m {
            check::positive("contour_jump_m", j)?;
        }
        Ok(())
    }
}

/// The images of one view as the image-based metrics take them: the full-on image first,
/// then the six half-on conditions in [`PATTERNS`](crate::PATTERNS) order.
pub fn matching_images(images: &PatternImages) -> Vec<GrayF32Image> {
    std::iter::once(Pattern::Full)
        .chain(PATTERNS.iter().copied().filter(|&p| p != Pattern::Full))
        .map(|p| images.image(p).clone())
        .collect()
}

/// One view as the matcher sees it.
#[derive(Debug, Clone, Copy)]
pub struct MatchView<'a> {
    /// The (undistorted) camera.
    pub camera: &'a Camera,
    /// The view's integrated surface (Eq. 3.3).
    pub surface: &'a DepthMap,
    /// The guide of the search band: the proxy in pass 2; `None` uses the surface (pass 1).
    pub guide: Option<&'a DepthMap>,
    /// Images for the image-based metrics: the full-on image first, then the six half-on
    /// images (any number ≥ 1 of the latter; [`matching_images`] makes them); `None` for the
    /// surface metric alone.
    pub images: Option<&'a [GrayF32Image]>,
}

/// What matching found for one view of a pair.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewMatches {
    /// Matched depth along each pixel ray (the good matches' triangulated points), `NaN`
    /// where the pixel has no match: the `z_i + d̄_i` of Eq. 3.4.
    pub target: DepthMap,
    /// Pixels straddling a depth discontinuity found by matching (jumps over 1 cm per pixel).
    pub breaks: Mask,
}

/// Sizes of one pair's matching.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub struct MatchStats {
    /// Epipolar planes with samples in both views.
    pub planes: usize,
    /// Grid cells evaluated (inside the band).
    pub cells_evaluated: usize,
    /// Matches on the lowest-cost paths.
    pub matches: usize,
    /// Of which good (cost within [`MatchingParams::good_cost`]).
    pub good_matches: usize,
    /// Discontinuities found (matched depth jumps).
    pub discontinuities: usize,
}

/// The matches of a pair of views.
#[derive(Debug, Clone, PartialEq)]
pub struct PairMatches {
    /// For the left view.
    pub left: ViewMatches,
    /// For the right view.
    pub right: ViewMatches,
    /// Sizes.
    pub stats: MatchStats,
}

/// A sampled epipolar line: pixel indices and their world rays, ordered by angle to the
/// baseline.
struct Line {
    pixels: Vec<usize>,
    rays: Vec<DVec3>,
}

/// Per-view data computed once per pair.
struct Prepared<'a> {
    view: MatchView<'a>,
    width: u32,
    height: u32,
    centre: DVec3,
    /// World ray direction per pixel.
    rays: &'a [DVec3],
    /// Surface point per pixel (NaN-free only where the surface exists).
    points: Vec<Option<DVec3>>,
    /// The other view's surface rendered into this camera, as points.
    other_points: Vec<Option<DVec3>>,
    guide: &'a DepthMap,
    /// Coarse-to-fine: per pixel, the depth interval along its ray around the coarse path
    /// (`NaN` where the coarse path gave none).
    narrow: Option<Vec<(f64, f64)>>,
}

fn points_of(camera: &Camera, depth: &DepthMap, rays: &[DVec3]) -> Vec<Option<DVec3>> {
    depth
        .depth_m
        .iter()
        .zip(rays)
        .map(|(d, r)| (!d.is_nan()).then(|| camera.centre() + *r * *d))
        .collect()
}

/// A depth map's surface as a triangle mesh: two triangles per 2 × 2 block of pixels that
/// all have a surface, unless a depth jump across the block exceeds `max_jump_m` (so that
/// depth discontinuities are not bridged).
///
/// # Errors
/// [`Error::InvalidParam`] if the camera's image size is not the map's or the threshold is
/// not positive; [`Error::Empty`] if no triangle is made.
pub fn depth_map_mesh(camera: &Camera, depth: &DepthMap, max_jump_m: f64) -> Result<TriMesh> {
    depth.check_camera(camera)?;
    check::positive("max_jump_m", max_jump_m)?;
    let rays = world_rays(camera)?;
    mesh_of_points(depth, &points_of(camera, depth, &rays), max_jump_m)
}

/// [`depth_map_mesh`] from the map's points (`points_of`, one per pixel).
fn mesh_of_points(depth: &DepthMap, points: &[Option<DVec3>], max_jump_m: f64) -> Result<TriMesh> {
    let (w, h) = (depth.width as usize, depth.height as usize);
    let mut index = vec![u32::MAX; w * h];
    let mut vertices = Vec::new();
    for (i, p) in points.iter().enumerate() {
        if let Some(p) = p {
            index[i] = vertices.len() as u32;
            vertices.push(*p);
        }
    }
    let mut faces = Vec::new();
    for y in 0..h.saturating_sub(1) {
        for x in 0..w.saturating_sub(1) {
            let q = [
                y * w + x,
                y * w + x + 1,
                (y + 1) * w + x,
                (y + 1) * w + x + 1,
            ];
            if q.iter().any(|&i| index[i] == u32::MAX) {
                continue;
            }
            let d: Vec<f64> = q.iter().map(|&i| depth.depth_m[i]).collect();
            let spread = d.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
                - d.iter().cloned().fold(f64::INFINITY, f64::min);
            if spread > max_jump_m {
                continue;
            }
            // Counter-clockwise seen from the camera (image y points down).
            for tri in [[q[0], q[2], q[1]], [q[1], q[2], q[3]]] {
                let [a, b, c] = tri.map(|i| vertices[index[i] as usize]);
                if (b - a).cross(c - a).length() > 1e-14 {
                    faces.push(tri.map(|i| index[i]));
                }
            }
        }
    }
    if faces.is_empty() {
        return Err(Error::Empty {
            what: "triangles of the depth map's surface",
        });
    }
    Ok(TriMesh::new(vertices, faces)?)
}

/// The input checks of one view: maps of the camera's size, an undistorted camera.
fn check_view(view: &MatchView<'_>) -> Result<()> {
    let cam = view.camera;
    view.surface.check_camera(cam)?;
    if let Some(g) = view.guide {
        g.check_camera(cam)?;
    }
    if cam.distortion.k1 != 0.0 {
        return Err(Error::InvalidParam {
            name: "camera",
            reason: "matching needs undistorted cameras (undistort the images first)".into(),
        });
    }
    Ok(())
}

fn world_rays(camera: &Camera) -> Result<Vec<DVec3>> {
    let r = camera.world_from_camera();
    Ok(camera_rays(camera)?
        .into_par_iter()
        .map(|d| r.transform_vector3(d))
        .collect())
}

impl<'a> Prepared<'a> {
    /// The view's set-up: `rays` are its world rays, `other_points` the other view's surface
    /// points (both computed once per pair and shared by the two sides).
    fn new(
        view: MatchView<'a>,
        rays: &'a [DVec3],
        points: Vec<Option<DVec3>>,
        (other, other_points): (&MatchView<'_>, &[Option<DVec3>]),
        jump_m: f64,
    ) -> Result<Self> {
        let cam = view.camera;
        let other_mesh = mesh_of_points(other.surface, other_points, jump_m)?;
        let other_depth = mesh_proxy_depth(cam, &other_mesh)?;
        let other_points = points_of(cam, &other_depth, rays);
        Ok(Self {
            view,
            width: cam.intrinsics.width,
            height: cam.intrinsics.height,
            centre: cam.centre(),
            rays,
            points,
            other_points,
            guide: view.guide.unwrap_or(view.surface),
            narrow: None,
        })
    }

    /// The samples of the plane with world normal `m`: integer pixels on the image line that
    /// have a surface, ordered by the angle of their ray to `baseline`.
    fn line(&self, m: DVec3, baseline: DVec3) -> Line {
        let cam = self.view.camera;
        let k = &cam.intrinsics;
        let mc = cam.camera_from_world().transform_vector3(m);
        let l = DVec3::new(
            mc.x / k.fx,
            mc.y / k.fy,
            mc.z - k.cx * mc.x / k.fx - k.cy * mc.y / k.fy,
        );
        let (w, h) = (self.width as i64, self.height as i64);
        let mut pixels = Vec::new();
        let mut push = |x: i64, y: i64| {
            if x >= 0 && y >= 0 && x < w && y < h {
                let i = (y * w + x) as usize;
                if self.points[i].is_some() && pixels.last() != Some(&i) {
                    pixels.push(i);
                }
            }
        };
        if l.y.abs() >= l.x.abs() {
            for x in 0..w {
                let y = -(l.x * x as f64 + l.z) / l.y;
                push(x, y.round() as i64);
            }
        } else {
            for y in 0..h {
                let x = -(l.y * y as f64 + l.z) / l.x;
                push(x.round() as i64, y);
            }
        }
        let b = baseline.normalize();
        let mut keyed: Vec<(f64, usize)> = pixels
            .into_iter()
            .map(|i| (self.rays[i].dot(b), i))
            .collect();
        // Decreasing cosine = increasing angle to the baseline.
        keyed.sort_by(|p, q| q.0.total_cmp(&p.0));
        keyed.dedup_by_key(|k| k.1);
        Line {
            rays: keyed.iter().map(|k| self.rays[k.1]).collect(),
            pixels: keyed.into_iter().map(|k| k.1).collect(),
        }
    }

    /// The coarse path's depth interval at a pixel, if any.
    fn narrow(&self, pixel: usize) -> Option<(f64, f64)> {
        let (lo, hi) = self.narrow.as_ref()?[pixel];
        (!lo.is_nan()).then_some((lo, hi))
    }

    fn pixel_footprint(&self, depth: f64) -> f64 {
        depth / self.view.camera.intrinsics.fx
    }

    /// Nearest pixel of a world point's projection.
    fn pixel_of(&self, p: DVec3) -> Option<usize> {
        let px = self.view.camera.project(p).ok()?;
        let (x, y) = (px.x.round(), px.y.round());
        (x >= 0.0 && y >= 0.0 && x < f64::from(self.width) && y < f64::from(self.height))
            .then(|| y as usize * self.width as usize + x as usize)
    }

    fn window(&self, centre: usize, half: i64) -> impl Iterator<Item = Option<usize>> + '_ {
        let (w, h) = (i64::from(self.width), i64::from(self.height));
        let (cx, cy) = ((centre % w as usize) as i64, (centre / w as usize) as i64);
        (-half..=half).flat_map(move |dy| {
            (-half..=half).map(move |dx| {
                let (x, y) = (cx + dx, cy + dy);
                (x >= 0 && y >= 0 && x < w && y < h).then_some((y * w + x) as usize)
            })
        })
    }

    fn stack_at(&self, pixel: usize, out: &mut Vec<f64>, from: usize) -> bool {
        let Some(images) = self.view.images else {
            return false;
        };
        let (x, y) = (pixel as u32 % self.width, pixel as u32 / self.width);
        for im in &images[from.min(images.len())..] {
            out.push(f64::from(im.get_pixel(x, y).0[0]));
        }
        true
    }
}

/// Mean distance of corresponding points after the optimal rigid alignment (the Kabsch
/// problem: the rotation that minimises the summed squared distances of the centred points).
///
/// The rotation is found as Horn's unit quaternion — the eigenvector of the largest
/// eigenvalue of the 4 × 4 key matrix of the cross-covariance — with the eigenvalue from
/// Newton's method on the key matrix's characteristic polynomial (Theobald's QCP, Liu et al.
/// 2010) and the eigenvector as the longest column of the adjugate of `N − λI`. This is the
/// Kabsch rotation with the reflection fix, found in a fixed small number of operations
/// instead of a 3 × 3 SVD.
fn rigid_residual(pairs: &[(DVec3, DVec3)]) -> f64 {
    let n = pairs.len() as f64;
    let ca = pairs.iter().map(|p| p.0).sum::<DVec3>() / n;
    let cb = pairs.iter().map(|p| p.1).sum::<DVec3>() / n;
    aligned_distance(pairs.len(), || {
        pairs.iter().map(|(a, b)| (*a - ca, *b - cb))
    })
}

/// The mean distance of `n` centred point pairs (`centred` yields them, twice) under the
/// optimal rotation.
fn aligned_distance<I: Iterator<Item = (DVec3, DVec3)>>(n: usize, centred: impl Fn() -> I) -> f64 {
    let mut h = [[0.0f64; 3]; 3];
    let mut g = 0.0;
    for (a, b) in centred() {
        let (a, b) = (a.to_array(), b.to_array());
        for (r, row) in h.iter_mut().enumerate() {
            for (c, v) in row.iter_mut().enumerate() {
                *v += a[r] * b[c];
            }
        }
        g += a.iter().chain(&b).map(|v| v * v).sum::<f64>();
    }
    if g <= 0.0 {
        // Every point at its centroid: nothing to align.
        return 0.0;
    }
    // Scale to unit mean squared spread so that the tolerances below are relative.
    let s = 1.0 / (0.5 * g);
    for v in h.iter_mut().flatten() {
        *v *= s;
    }
    let Some(r) = horn_rotation(&h) else {
        return f64::INFINITY;
    };
    centred()
        .map(|(a, b)| {
            let ra = DVec3::new(
                r[0][0] * a.x + r[0][1] * a.y + r[0][2] * a.z,
                r[1][0] * a.x + r[1][1] * a.y + r[1][2] * a.z,
                r[2][0] * a.x + r[2][1] * a.y + r[2][2] * a.z,
            );
            (ra - b).length()
        })
        .sum::<f64>()
        / n as f64
}

/// [`aligned_distance`] of two full windows, centred (`xs, ys, zs`), with the sum `g` of
/// both windows' squared norms.
fn aligned_distance_full(
    (ax, ay, az): (&[f64], &[f64], &[f64]),
    (bx, by, bz): (&[f64], &[f64], &[f64]),
    g: f64,
) -> f64 {
    if g <= 0.0 {
        return 0.0;
    }
    let k = ax
        .len()
        .min(ay.len())
        .min(az.len())
        .min(bx.len())
        .min(by.len())
        .min(bz.len());
    let (ax, ay, az, bx, by, bz) = (&ax[..k], &ay[..k], &az[..k], &bx[..k], &by[..k], &bz[..k]);
    let mut h = [0.0f64; 9];
    for i in 0..k {
        let (x, y, z) = (ax[i], ay[i], az[i]);
        let (u, v, w) = (bx[i], by[i], bz[i]);
        h[0] += x * u;
        h[1] += x * v;
        h[2] += x * w;
        h[3] += y * u;
        h[4] += y * v;
        h[5] += y * w;
        h[6] += z * u;
        h[7] += z * v;
        h[8] += z * w;
    }
    let s = 1.0 / (0.5 * g);
    let h = h.map(|v| v * s);
    let Some(r) = horn_rotation(&[[h[0], h[1], h[2]], [h[3], h[4], h[5]], [h[6], h[7], h[8]]])
    else {
        return f64::INFINITY;
    };
    let [[r00, r01, r02], [r10, r11, r12], [r20, r21, r22]] = r;
    let mut sum = 0.0;
    for i in 0..k {
        let (x, y, z) = (ax[i], ay[i], az[i]);
        let dx = r00 * x + r01 * y + r02 * z - bx[i];
        let dy = r10 * x + r11 * y + r12 * z - by[i];
        let dz = r20 * x + r21 * y + r22 * z - bz[i];
        sum += (dx * dx + dy * dy + dz * dz).sqrt();
    }
    sum / k as f64
}

/// The surface windows of a plane's samples, gathered once per plane: `k = window²` points
/// per sample in window order (rows, then columns; `NaN` where the pixel is outside the image
/// or has no surface), and the centroid of each window whose points all exist.
struct Windows {
    k: usize,
    points: Vec<DVec3>,
    centroids: Vec<Option<DVec3>>,
    /// Per window: its points less the centroid (of full windows; else the points), as `k`
    /// xs, then ys, then zs.
    centred: Vec<f64>,
    /// Per window: the sum of the centred points' squared norms.
    spread: Vec<f64>,
}

impl Windows {
    /// The windows of `field` (per pixel of a `width × height` image) around `centres`.
    /// With `contour = Some((camera centre, jump per pixel))`, a window's points whose
    /// distance from the camera centre differs from the window centre's by more than the
    /// jump per pixel of Chebyshev distance are left out ([`MatchingParams::contour_jump_m`]).
    fn gather(
        field: &[Option<DVec3>],
        (width, height): (u32, u32),
        centres: impl Iterator<Item = Option<usize>>,
        half: i64,
        contour: Option<(DVec3, f64)>,
    ) -> Self {
        let (w, h) = (i64::from(width), i64::from(height));
        let side = (2 * half + 1) as usize;
        let k = side * side;
        let mut points = Vec::new();
        let mut centroids = Vec::new();
        let mut centred = Vec::new();
        let mut spread = Vec::new();
        for centre in centres {
            let start = points.len();
            match centre {
                None => points.resize(start + k, DVec3::NAN),
                Some(c) => {
                    let (cx, cy) = ((c % width as usize) as i64, (c / width as usize) as i64);
                    for dy in -half..=half {
                        for dx in -half..=half {
                            let (x, y) = (cx + dx, cy + dy);
                            let p = (x >= 0 && y >= 0 && x < w && y < h)
                                .then(|| field[(y * w + x) as usize])
                                .flatten();
                            points.push(p.unwrap_or(DVec3::NAN));
                        }
                    }
                }
            }
            if let Some((eye, jump)) = contour {
                let window = &mut points[start..];
                let mid = window[k / 2];
                if !mid.x.is_nan() {
                    let r0 = (mid - eye).length();
                    for (i, p) in window.iter_mut().enumerate() {
                        let (dx, dy) = ((i % side) as i64 - half, (i / side) as i64 - half);
                        let steps = dx.abs().max(dy.abs()) as f64;
                        if !p.x.is_nan() && ((*p - eye).length() - r0).abs() > jump * steps {
                            *p = DVec3::NAN;
                        }
                    }
                }
            }
            let window = &points[start..];
            let centroid = window
                .iter()
                .all(|p| !p.x.is_nan())
                .then(|| window.iter().copied().sum::<DVec3>() / k as f64);
            let c = centroid.unwrap_or(DVec3::ZERO);
            centred.extend(window.iter().map(|p| p.x - c.x));
            centred.extend(window.iter().map(|p| p.y - c.y));
            centred.extend(window.iter().map(|p| p.z - c.z));
            spread.push(window.iter().map(|p| (*p - c).length_squared()).sum());
            centroids.push(centroid);
        }
        Self {
            k,
            points,
            centroids,
            centred,
            spread,
        }
    }

    fn centred(&self, s: usize) -> (&[f64], &[f64], &[f64]) {
        let w = &self.centred[3 * s * self.k..3 * (s + 1) * self.k];
        let (x, yz) = w.split_at(self.k);
        let (y, z) = yz.split_at(self.k);
        (x, y, z)
    }

    fn window(&self, s: usize) -> &[DVec3] {
        &self.points[s * self.k..(s + 1) * self.k]
    }
}

/// The surface metric's distance between the window `s` of `own` (a view's surface) and the
/// window `t` of `other` (the other surface rendered into that view): the mean distance of
/// the pairs of existing points after the optimal rigid alignment, `∞` if fewer than half
/// the window's pairs exist. `pairs` is scratch space.
fn window_distance(
    own: &Windows,
    s: usize,
    other: &Windows,
    t: usize,
    pairs: &mut Vec<(DVec3, DVec3)>,
) -> f64 {
    let (a, b) = (own.window(s), other.window(t));
    if own.centroids[s].is_some() && other.centroids[t].is_some() {
        // Full windows: the centroids are the ones `rigid_residual` would compute.
        return aligned_distance_full(
            own.centred(s),
            other.centred(t),
            own.spread[s] + other.spread[t],
        );
    }
    pairs.clear();
    pairs.extend(
        a.iter()
            .zip(b)
            .filter(|(p, q)| !p.x.is_nan() && !q.x.is_nan())
            .map(|(p, q)| (*p, *q)),
    );
    if pairs.len() * 2 < own.k {
        return f64::INFINITY;
    }
    rigid_residual(pairs)
}

/// The rotation `R` maximising `Σ bᵢ · R aᵢ` for the cross-covariance `h = Σ aᵢ bᵢᵀ` (scaled
/// so that the sum of both point sets' squared norms is 2): Horn's quaternion method with
/// Theobald's QCP eigenvalue. `None` for non-finite input.
fn horn_rotation(h: &[[f64; 3]; 3]) -> Option<[[f64; 3]; 3]> {
    let [[sxx, sxy, sxz], [syx, syy, syz], [szx, szy, szz]] = *h;
    // Horn's key matrix N (symmetric 4 × 4); its largest eigenvalue is at most 1 here.
    let k = [
        [sxx + syy + szz, syz - szy, szx - sxz, sxy - syx],
        [syz - szy, sxx - syy - szz, sxy + syx, szx + sxz],
        [szx - sxz, sxy + syx, -sxx + syy - szz, syz + szy],
        [sxy - syx, szx + sxz, syz + szy, -sxx - syy + szz],
    ];
    if k.iter().flatten().any(|v| !v.is_finite()) {
        return None;
    }
    // Characteristic polynomial λ⁴ + c2 λ² + c1 λ + c0 (N is traceless).
    let c2 = -2.0 * h.iter().flatten().map(|v| v * v).sum::<f64>();
    let c1 = 8.0
        * (sxx * syz * szy + syy * szx * sxz + szz * sxy * syx
            - sxx * syy * szz
            - syz * szx * sxy
            - szy * syx * sxz);
    // The determinant of N by its 2 × 2 minors (rows 0-1 against rows 2-3), which the
    // adjugate below reuses.
    let lo = minors2(&k[2], &k[3]);
    let c0 = laplace(&k[0], &k[1], &lo);
    // Newton from the upper bound 1 decreases monotonically onto the largest root and
    // converges quadratically: stop once a step is below 10⁻¹³ (relative), where rounding
    // takes over.
    let mut l = 1.0f64;
    let mut slope = 0.0;
    for _ in 0..50 {
        let l2 = l * l;
        let p = (l2 + c2) * l2 + c1 * l + c0;
        slope = (4.0 * l2 + 2.0 * c2) * l + c1;
        if slope == 0.0 {
            break;
        }
        let step = p / slope;
        l -= step;
        if step.abs() <= 1e-13 * l.abs().max(1e-12) {
            break;
        }
    }
    let mut m = k;
    for (i, row) in m.iter_mut().enumerate() {
        row[i] -= l;
    }
    // The eigenvector: the longest column of adj(N − λI) (N symmetric: the cofactors of a
    // row). Cofactors of rows 0 and 1 expand the 3 × 3 minors along row 1 or 0 with the
    // 2 × 2 minors of rows 2-3; those of rows 2 and 3 along row 3 or 2 with rows 0-1's.
    // Column j is p'(λ) vⱼ v for the unit eigenvector v, and some |vⱼ|² ≥ 1/4: take the first
    // column with |vⱼ|² ≥ 0.1 (well conditioned), else the longest.
    let accept = 0.1 * slope * slope;
    let lo = minors2(&m[2], &m[3]);
    let (mut best, mut best_norm) = ([0.0; 4], 0.0);
    for j in 0..4 {
        let q = match j {
            0 => cofactors(&m[1], &lo, 1.0),
            1 => cofactors(&m[0], &lo, -1.0),
            2 => cofactors(&m[3], &minors2(&m[0], &m[1]), 1.0),
            _ => cofactors(&m[2], &minors2(&m[0], &m[1]), -1.0),
        };
        let norm = q.iter().map(|v| v * v).sum::<f64>();
        if norm > best_norm {
            (best, best_norm) = (q, norm);
        }
        if norm >= accept {
            break;
        }
    }
    if !(best_norm > 0.0 && best_norm.is_finite()) {
        // A degenerate key matrix (e.g. collinear points): any optimum; take identity.
        return Some([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]);
    }
    let inv = 1.0 / best_norm.sqrt();
    let [w, x, y, z] = best.map(|v| v * inv);
    Some([
        [
            w * w + x * x - y * y - z * z,
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            w * w - x * x + y * y - z * z,
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            w * w - x * x - y * y + z * z,
        ],
    ])
}

/// The six 2 × 2 minors of two rows, columns `(0,1), (0,2), (0,3), (1,2), (1,3), (2,3)`.
fn minors2(r: &[f64; 4], s: &[f64; 4]) -> [f64; 6] {
    [
        r[0] * s[1] - r[1] * s[0],
        r[0] * s[2] - r[2] * s[0],
        r[0] * s[3] - r[3] * s[0],
        r[1] * s[2] - r[2] * s[1],
        r[1] * s[3] - r[3] * s[1],
        r[2] * s[3] - r[3] * s[2],
    ]
}

/// The 3 × 3 determinants of `row` over the two rows whose 2 × 2 minors are `m2`, one per
/// left-out column `c`, signed as cofactors `(−1)^c · sign`.
fn cofactors(row: &[f64; 4], m2: &[f64; 6], sign: f64) -> [f64; 4] {
    let [m01, m02, m03, m12, m13, m23] = *m2;
    [
        sign * (row[1] * m23 - row[2] * m13 + row[3] * m12),
        -sign * (row[0] * m23 - row[2] * m03 + row[3] * m02),
        sign * (row[0] * m13 - row[1] * m03 + row[3] * m01),
        -sign * (row[0] * m12 - row[1] * m02 + row[2] * m01),
    ]
}

/// The determinant of a 4 × 4 matrix from its rows 0, 1 and the 2 × 2 minors `m23` of rows
/// 2, 3 (Laplace expansion by complementary minors).
fn laplace(r0: &[f64; 4], r1: &[f64; 4], m23: &[f64; 6]) -> f64 {
    let m01 = minors2(r0, r1);
    m01[0] * m23[5] - m01[1] * m23[4] + m01[2] * m23[3] + m01[3] * m23[2] - m01[4] * m23[1]
        + m01[5] * m23[0]
}

const LV: usize = 0;
const RV: usize = 1;

/// The lowest-cost path through an `na × nb` grid of costs (`∞` = not allowed), four states;
/// returns the matched `(a, b)` cells in order. `rows[a]` is the half-open range of `b`
/// holding row `a`'s finite cells (empty when none).
///
/// Criminisi's four-state programme evaluated on the band only. Outside the evaluated cells
/// a path can only be occluded, and an occluded stretch between two matches costs
/// `2 · disc + k · occ` for its `k ≥ 1` steps, whatever their order (entering an occlusion
/// and leaving it into a diagonal match each pay `disc`; occluded steps pay `occ`; slanted
/// steps need a matched predecessor). So the best path into cell `(i, j)` through an
/// occlusion comes from the best matched cell `(i', j')` with `i' < i`, `j' < j` of
/// `F − occ · (i' + j')`, a prefix minimum kept per column. The start (`LO` at the corner,
/// no penalty) and the end (a last occlusion pays `disc`) are the same sums. This is the
/// same minimisation as the programme over every node of the `(na + 1) × (nb + 1)` grid (the
/// form before; kept as the unit test's reference, the same matches), with work in the band
/// and `O(nb)` per row for the prefix minima.
fn lowest_cost_path(
    costs: &[f64],
    na: usize,
    nb: usize,
    rows: &[(usize, usize)],
    occ: f64,
    disc: f64,
) -> Vec<(usize, usize)> {
    // Per evaluated cell (row-major in the bands): the best cost ending in a match of the
    // cell reached by a left step (LV: diagonal or left-slanted) or a right step (RV), and
    // where it came from.
    let mut offset = Vec::with_capacity(na + 1);
    let mut total = 0;
    for &(lo, hi) in rows {
        offset.push(total);
        total += hi.saturating_sub(lo);
    }
    offset.push(total);
    let cell = |i: usize, j: usize| -> Option<usize> {
        let (lo, hi) = rows[i];
        (j >= lo && j < hi).then(|| offset[i] + j - lo)
    };
    #[derive(Clone, Copy)]
    enum From {
        None,
        Start,
        /// A matched cell (row, column, state) before this one: a diagonal or slanted step.
        Step(usize, usize, usize),
        /// A matched cell (row, column, state) before an occluded stretch.
        Occluded(usize, usize, usize),
    }
    let mut f = vec![[f64::INFINITY; 2]; total];
    let mut from = vec![[From::None; 2]; total];
    let best_of = |v: &[f64; 2]| if v[RV] < v[LV] { RV } else { LV };
    // Per column j: the least `F − occ · (i' + j')` over the rows done and columns ≤ j, and
    // its cell.
    let mut prefix = vec![(f64::INFINITY, 0usize, 0usize, LV); nb];
    for i in 0..na {
        let (lo, hi) = rows[i];
        for j in lo..hi {
            let c = costs[i * nb + j];
            if !c.is_finite() {
                continue;
            }
            let k = offset[i] + j - lo;
            let mut lv = (occ * (i + j) as f64 + disc + c, From::Start);
            let offer = |v: f64, p: From, best: &mut (f64, From)| {
                if v < best.0 {
                    *best = (v, p);
                }
            };
            if i > 0 && j > 0 {
                if let Some(q) = cell(i - 1, j - 1) {
                    for s in [LV, RV] {
                        offer(f[q][s] + c, From::Step(i - 1, j - 1, s), &mut lv);
                    }
                }
                let (g, pi, pj, ps) = prefix[j - 1];
                offer(
                    g + occ * (i + j - 2) as f64 + 2.0 * disc + c,
                    From::Occluded(pi, pj, ps),
                    &mut lv,
                );
            }
            if i > 0 {
                if let Some(q) = cell(i - 1, j) {
                    for s in [LV, RV] {
                        offer(f[q][s] + c, From::Step(i - 1, j, s), &mut lv);
                    }
                }
            }
            let mut rv = (f64::INFINITY, From::None);
            if j > 0 {
                if let Some(q) = cell(i, j - 1) {
                    for s in [LV, RV] {
                        offer(f[q][s] + c, From::Step(i, j - 1, s), &mut rv);
                    }
                }
            }
            f[k] = [lv.0, rv.0];
            from[k] = [lv.1, rv.1];
        }
        // Fold the row into the prefix minima (columns ≥ the row's first cell).
        let mut run = (f64::INFINITY, 0usize, 0usize, LV);
        for (j, p) in prefix.iter_mut().enumerate().skip(lo) {
            if let Some(k) = cell(i, j) {
                let s = best_of(&f[k]);
                let g = f[k][s] - occ * (i + j) as f64;
                if g < run.0 {
                    run = (g, i, j, s);
                }
            }
            if run.0 < p.0 {
                *p = run;
            }
        }
    }
    // The end: every sample occluded, or the last match then an occluded stretch.
    let mut end = (occ * (na + nb) as f64, None);
    for i in 0..na {
        let (lo, hi) = rows[i];
        for j in lo..hi {
            let k = offset[i] + j - lo;
            let s = best_of(&f[k]);
            let steps = (na - 1 - i) + (nb - 1 - j);
            let v = if steps == 0 {
                f[k][s]
            } else {
                f[k][s] + disc + occ * steps as f64
            };
            if v < end.0 {
                end = (v, Some((i, j, s)));
            }
        }
    }
    let mut path = Vec::new();
    let mut at = end.1;
    while let Some((i, j, s)) = at {
        path.push((i, j));
        let Some(k) = cell(i, j) else { break };
        at = match from[k][s] {
            From::Step(pi, pj, ps) | From::Occluded(pi, pj, ps) => Some((pi, pj, ps)),
            From::Start | From::None => None,
        };
    }
    path.reverse();
    path
}

/// One plane's result: good matches (left pixel, right pixel, depth along each ray) and break
/// pixels.
#[derive(Default)]
struct PlaneResult {
    matches: Vec<(usize, usize, f64, f64)>,
    left_breaks: Vec<usize>,
    right_breaks: Vec<usize>,
    evaluated: usize,
    path_matches: usize,
    /// Every match of the path (left pixel, right pixel, depth along each ray).
    path: Vec<(usize, usize, f64, f64)>,
}

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
    Ok(match_views(left, right, hull, params, narrow)?.0)
}

/// Coarse-to-fine: the median cost (the unit of the occlusion cost and the good-match
/// threshold) is estimated from every this-many-th cell of the whole band.
const MEDIAN_STRIDE: usize = 8;

/// Coarse-to-fine applies to images at least twice this size.
const COARSE_MIN_PX: u32 = 64;

/// Per-pixel path depth ranges (min, max along the ray; `NaN` where no path match).
type PathRanges = Vec<(f64, f64)>;

/// A view at half resolution: each coarse pixel is a 2 × 2 block of the view's.
struct HalfView {
    camera: Camera,
    surface: DepthMap,
    guide: Option<DepthMap>,
    images: Option<Vec<GrayF32Image>>,
}

impl HalfView {
    fn new(view: &MatchView<'_>, jump_m: f64) -> Result<Self> {
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

    fn view(&self) -> MatchView<'_> {
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
fn half_depth(d: &DepthMap, jump_m: f64) -> Result<DepthMap> {
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
fn half_image(im: &GrayF32Image) -> GrayF32Image {
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
fn coarse_intervals(
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
    let (_, (rl, rr)) = match_views(&hl.view(), &hr.view(), hull, &coarse_params, None)?;
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

/// [`match_pair`] after its checks, with the coarse intervals of coarse-to-fine matching;
/// also returns each view's per-pixel path depth ranges.
fn match_views(
    left: &MatchView<'_>,
    right: &MatchView<'_>,
    hull: Option<&PolygonalHull>,
    params: &MatchingParams,
    narrow: Option<(PathRanges, PathRanges)>,
) -> Result<(PairMatches, (PathRanges, PathRanges))> {
    let jump = IntegrationParams::jump_threshold_m(params.jump_m, left.camera.intrinsics.width);
    // Surfaces are meshed without bridging jumps of a few matching thresholds.
    let mesh_jump = 4.0 * jump;
    // Per pair, once per camera: the world rays and the surface points (each side's set-up
    // needs both views').
    let (rays_l, rays_r) = rayon::join(|| world_rays(left.camera), || world_rays(right.camera));
    let (rays_l, rays_r) = (rays_l?, rays_r?);
    let points_l = points_of(left.camera, left.surface, &rays_l);
    let points_r = points_of(right.camera, right.surface, &rays_r);
    let (pl, pr) = rayon::join(
        || {
            Prepared::new(
                *left,
                &rays_l,
                points_l.clone(),
                (right, &points_r),
                mesh_jump,
            )
        },
        || {
            Prepared::new(
                *right,
                &rays_r,
                points_r.clone(),
                (left, &points_l),
                mesh_jump,
            )
        },
    );
    let (mut pl, mut pr) = (pl?, pr?);
    if let Some((nl, nr)) = narrow {
        (pl.narrow, pr.narrow) = (Some(nl), Some(nr));
    }
    let baseline = pr.centre - pl.centre;
    if baseline.length() < 1e-9 {
        return Err(Error::InvalidParam {
            name: "right",
            reason: "the two cameras share a centre (no baseline)".into(),
        });
    }
    let half = (params.window_px / 2) as i64;
    let cx = f64::from(pl.width) / 2.0;
    let results: Vec<PlaneResult> = (0..pl.height)
        .into_par_iter()
        .map(|row| {
            let Ok(ray) = left.camera.ray(DVec2::new(cx, f64::from(row))) else {
                return PlaneResult::default();
            };
            let m = baseline.cross(ray.direction);
            if m.length() < 1e-12 {
                return PlaneResult::default();
            }
            let m = m.normalize();
            let (ll, lr) = (pl.line(m, baseline), pr.line(m, baseline));
            match_plane(&pl, &pr, &ll, &lr, hull, params, half, jump)
        })
        .collect();
    let (w, h) = (pl.width, pl.height);
    let mut sums = (
        vec![(0.0, 0usize); pl.rays.len()],
        vec![(0.0, 0usize); pr.rays.len()],
    );
    let mut breaks = (vec![false; pl.rays.len()], vec![false; pr.rays.len()]);
    let nan = (f64::NAN, f64::NAN);
    let mut ranges = (vec![nan; pl.rays.len()], vec![nan; pr.rays.len()]);
    let mut stats = MatchStats::default();
    for r in &results {
        for &(a, b, za, zb) in &r.path {
            for (range, z) in [(&mut ranges.0[a], za), (&mut ranges.1[b], zb)] {
                *range = if range.0.is_nan() {
                    (z, z)
                } else {
                    (range.0.min(z), range.1.max(z))
                };
            }
        }
        if r.evaluated > 0 {
            stats.planes += 1;
        }
        stats.cells_evaluated += r.evaluated;
        stats.matches += r.path_matches;
        stats.good_matches += r.matches.len();
        stats.discontinuities += r.left_breaks.len() / 2;
        for &(a, b, za, zb) in &r.matches {
            sums.0[a].0 += za;
            sums.0[a].1 += 1;
            sums.1[b].0 += zb;
            sums.1[b].1 += 1;
        }
        for &a in &r.left_breaks {
            breaks.0[a] = true;
        }
        for &b in &r.right_breaks {
            breaks.1[b] = true;
        }
    }
    let target = |s: &[(f64, usize)]| -> Vec<f64> {
        s.iter()
            .map(|&(sum, n)| if n == 0 { f64::NAN } else { sum / n as f64 })
            .collect()
    };
    let (wr, hr) = (pr.width, pr.height);
    let matches = PairMatches {
        left: ViewMatches {
            target: DepthMap::new(w, h, target(&sums.0))?,
            breaks: Mask::from_bools(w, h, &breaks.0)?,
        },
        right: ViewMatches {
            target: DepthMap::new(wr, hr, target(&sums.1))?,
            breaks: Mask::from_bools(wr, hr, &breaks.1)?,
        },
        stats,
    };
    Ok((matches, ranges))
}

/// Whether a depth lies in a coarse-to-fine interval (always, without one).
fn within(t: f64, interval: Option<(f64, f64)>) -> bool {
    interval.is_none_or(|(lo, hi)| t >= lo && t <= hi)
}

#[allow(clippy::too_many_arguments)]
fn match_plane(
    pl: &Prepared<'_>,
    pr: &Prepared<'_>,
    ll: &Line,
    lr: &Line,
    hull: Option<&PolygonalHull>,
    params: &MatchingParams,
    half: i64,
    jump: f64,
) -> PlaneResult {
    let (na, nb) = (ll.pixels.len(), lr.pixels.len());
    let mut out = PlaneResult::default();
    if na == 0 || nb == 0 {
        return out;
    }
    let mut costs = vec![f64::INFINITY; na * nb];
    let mut stack = (Vec::new(), Vec::new());
    let mut pairs = Vec::with_capacity(params.window_px * params.window_px);
    // Per sample, once per plane: the guide depth, the ray's dot with the centres' offset
    // (closest approach then costs one dot product per cell) and, for the surface metric,
    // the pixel of the sample's surface point in the other view.
    let w = pl.centre - pr.centre;
    let guide_b: Vec<f64> = lr.pixels.iter().map(|&i| pr.guide.depth_m[i]).collect();
    let e_b: Vec<f64> = lr.rays.iter().map(|r| r.dot(w)).collect();
    let surface = params.metric == MatchMetric::SurfaceRigid;
    // The surface metric's windows: around each sample in its own surface, and around the
    // pixel of the sample's point in the other view's rendering of this surface.
    // Contour-aware windows: the camera centre and the jump per pixel at the view's width.
    let contour = |view: &Prepared<'_>| {
        params.contour_jump_m.map(|j| {
            (
                view.centre,
                IntegrationParams::jump_threshold_m(j, view.width),
            )
        })
    };
    let windows = |own: &Prepared<'_>, to: &Prepared<'_>, pixels: &[usize]| {
        let n = if surface { pixels.len() } else { 0 };
        let own_windows = Windows::gather(
            &own.points,
            (own.width, own.height),
            pixels[..n].iter().map(|&i| Some(i)),
            half,
            contour(own),
        );
        let centres = pixels[..n]
            .iter()
            .map(|&i| own.points[i].and_then(|x| to.pixel_of(x)));
        let other_windows = Windows::gather(
            &to.other_points,
            (to.width, to.height),
            centres,
            half,
            contour(to),
        );
        (own_windows, other_windows)
    };
    let (own_a, in_right_a) = windows(pl, pr, &ll.pixels);
    let (own_b, in_left_b) = windows(pr, pl, &lr.pixels);
    // Per row, the range of the cells evaluated (the band the programme works in).
    let mut rows = vec![(0usize, 0usize); na];
    // The unit of the costs is the median over the whole band. Coarse-to-fine evaluates a
    // narrow band around the coarse path, whose costs are lower than the band's (they are
    // the likely matches): there the median is taken of every `MEDIAN_STRIDE`-th cell of the
    // whole band, so that the occlusion cost and the good-match threshold keep their meaning.
    let stride = if pl.narrow.is_some() || pr.narrow.is_some() {
        MEDIAN_STRIDE
    } else {
        1
    };
    let (mut band_cells, mut sample) = (0usize, Vec::new());
    for a in 0..na {
        let ia = ll.pixels[a];
        let guide_a = pl.guide.depth_m[ia];
        if guide_a.is_nan() {
            continue;
        }
        let narrow_a = pl.narrow(ia);
        let ray_a = ll.rays[a];
        let d_a = ray_a.dot(w);
        for b in 0..nb {
            let gb = guide_b[b];
            if gb.is_nan() {
                continue;
            }
            // `closest_approach`, term for term.
            let ray_b = lr.rays[b];
            let Some((ta, tb)) = meet(ray_a, d_a, ray_b, e_b[b]) else {
                continue;
            };
            if (ta - guide_a).abs() > params.band_m || (tb - gb).abs() > params.band_m {
                continue;
            }
            // Coarse-to-fine: cells outside the narrow band are evaluated only as the
            // median's sample (every `stride`-th cell of the whole band).
            let narrow = within(ta, narrow_a) && within(tb, pr.narrow(lr.pixels[b]));
            let sampled = band_cells.is_multiple_of(stride);
            band_cells += 1;
            if !(narrow || sampled) {
                continue;
            }
            let (pa, pb) = (pl.centre + ray_a * ta, pr.centre + ray_b * tb);
            if (pa - pb).length() > 2.0 * pl.pixel_footprint(ta).max(pr.pixel_footprint(tb)) {
                continue;
            }
            let ib = lr.pixels[b];
            let x = 0.5 * (pl.centre + ray_a * ta + pr.centre + ray_b * tb);
            if hull.is_some_and(|h| !h.contains(x)) {
                continue;
            }
            let (true, Some(xb)) = (pl.points[ia].is_some(), pr.points[ib]) else {
                continue;
            };
            let c = match params.metric {
                MatchMetric::SurfaceRigid => {
                    let left = window_distance(&own_a, a, &in_left_b, b, &mut pairs);
                    // The larger of the two: the second is not needed once the first is ∞.
                    if left == f64::INFINITY {
                        left
                    } else {
                        left.max(window_distance(&own_b, b, &in_right_a, a, &mut pairs))
                    }
                }
                MatchMetric::FullOnWindow | MatchMetric::IlluminationStack => {
                    let from = usize::from(params.metric == MatchMetric::IlluminationStack);
                    window_difference(pl, pr, ia, ib, half, from, &mut stack)
                }
                MatchMetric::ProjectedIllumination => {
                    projected_difference(pl, pr, ia, xb, half, &mut stack)
                }
            };
            out.evaluated += 1;
            if sampled && c.is_finite() {
                sample.push(c);
            }
            if !narrow {
                continue;
            }
            costs[a * nb + b] = c;
            let r = &mut rows[a];
            *r = if r.0 == r.1 { (b, b + 1) } else { (r.0, b + 1) };
        }
    }
    if sample.is_empty() || rows.iter().all(|r| r.0 == r.1) {
        return out;
    }
    let unit = median(&sample).max(1e-12);
    let (occ, disc) = (
        params.occlusion_cost * unit,
        params.discontinuity_penalty * unit,
    );
    #[cfg(test)]
    let path = if DENSE_PROGRAMME.with(std::cell::Cell::get) {
        tests::lowest_cost_path_dense(&costs, na, nb, occ, disc)
    } else {
        lowest_cost_path(&costs, na, nb, &rows, occ, disc)
    };
    #[cfg(not(test))]
    let path = lowest_cost_path(&costs, na, nb, &rows, occ, disc);
    out.path_matches = path.len();
    let mut prev: Option<(usize, usize, f64, f64)> = None;
    // The path's matches as samples (a, b), whether good, and whether a discontinuity lies
    // between each and the one before.
    let mut kept: Vec<(usize, usize, bool, bool)> = Vec::with_capacity(path.len());
    for &(a, b) in &path {
        // The cell's point again (path cells are evaluated cells, whose rays meet).
        let (ray_a, ray_b) = (ll.rays[a], lr.rays[b]);
        let Some((ta, tb)) = meet(ray_a, ray_a.dot(w), ray_b, ray_b.dot(w)) else {
            continue;
        };
        let x = 0.5 * (pl.centre + ray_a * ta + pr.centre + ray_b * tb);
        let (ia, ib) = (ll.pixels[a], lr.pixels[b]);
        let (za, zb) = ((x - pl.centre).length(), (x - pr.centre).length());
        let mut broken = false;
        if let Some((pa, pb, pza, pzb)) = prev {
            // Jumps per pixel of the matched depth between consecutive matches.
            let step_a = pixel_distance(pa, ia, pl.width).max(1.0);
            let step_b = pixel_distance(pb, ib, pr.width).max(1.0);
            if (za - pza).abs() / step_a > jump || (zb - pzb).abs() / step_b > jump {
                out.left_breaks.extend([pa, ia]);
                out.right_breaks.extend([pb, ib]);
                broken = true;
            }
        }
        prev = Some((ia, ib, za, zb));
        out.path.push((ia, ib, za, zb));
        kept.push((a, b, costs[a * nb + b] <= params.good_cost * unit, broken));
    }
    // The depth along the left ray `a` where it meets the right sample `b`, and along the
    // right ray `b`.
    let depths = |a: usize, b: usize| -> Option<(f64, f64)> {
        let (ray_a, ray_b) = (ll.rays[a], lr.rays[b]);
        let (ta, tb) = meet(ray_a, ray_a.dot(w), ray_b, ray_b.dot(w))?;
        let x = 0.5 * (pl.centre + ray_a * ta + pr.centre + ray_b * tb);
        Some(((x - pl.centre).length(), (x - pr.centre).length()))
    };
    // Sub-pixel positions: per kept match, the fractional right sample for the left view's
    // depth and the fractional left sample for the right view's.
    let fractional: Vec<(f64, f64)> = match params.subpixel {
        SubPixel::Off => kept.iter().map(|k| (k.1 as f64, k.0 as f64)).collect(),
        SubPixel::CostParabola => kept
            .iter()
            .map(|&(a, b, _, _)| {
                let cost = |i: usize, j: usize| costs[i * nb + j];
                let along_b = (b > 0 && b + 1 < nb)
                    .then(|| parabola_vertex(cost(a, b - 1), cost(a, b), cost(a, b + 1)))
                    .flatten()
                    .unwrap_or(0.0);
                let along_a = (a > 0 && a + 1 < na)
                    .then(|| parabola_vertex(cost(a - 1, b), cost(a, b), cost(a + 1, b)))
                    .flatten()
                    .unwrap_or(0.0);
                (b as f64 + along_b, a as f64 + along_a)
            })
            .collect(),
        SubPixel::PathFit => path_fit(&kept, params.subpixel_window),
    };
    for (&(a, b, good, _), &(fb, fa)) in kept.iter().zip(&fractional) {
        if !good {
            continue;
        }
        let Some((za, zb)) = depths(a, b) else {
            continue;
        };
        // Linear interpolation of the depth between the two samples around the fractional
        // position (the match's own depth where it is whole or a neighbour is missing).
        let between = |f: f64, n: usize, z: f64, at: &dyn Fn(usize) -> Option<f64>| -> f64 {
            let f = f.clamp(0.0, (n - 1) as f64);
            let lo = f.floor() as usize;
            let t = f - lo as f64;
            if t == 0.0 {
                return at(lo).unwrap_or(z);
            }
            match (at(lo), at((lo + 1).min(n - 1))) {
                (Some(u), Some(v)) => u + t * (v - u),
                _ => z,
            }
        };
        let za = between(fb, nb, za, &|j| depths(a, j).map(|d| d.0));
        let zb = between(fa, na, zb, &|i| depths(i, b).map(|d| d.1));
        out.matches.push((ll.pixels[a], lr.pixels[b], za, zb));
    }
    out
}

/// [`SubPixel::PathFit`]: per match `k` of the path (samples `a`, `b`; a discontinuity
/// before it ends a run), the least-squares lines `b(a)` and `a(b)` through the matches of
/// its run within `half` path steps each side (the run also ends where the path skips an
/// occlusion), evaluated at the match: (fractional b, fractional a). A run of one keeps the
/// whole samples.
fn path_fit(kept: &[(usize, usize, bool, bool)], half: usize) -> Vec<(f64, f64)> {
    let n = kept.len();
    // Run index per match.
    let mut run = vec![0usize; n];
    for k in 1..n {
        let (pa, pb, _, _) = kept[k - 1];
        let (a, b, _, broken) = kept[k];
        let skip = a > pa + 1 || b > pb + 1;
        run[k] = run[k - 1] + usize::from(broken || skip);
    }
    let fit = |xs: &[f64], ys: &[f64], x: f64, y: f64| -> f64 {
        let m = xs.len() as f64;
        let (mx, my) = (xs.iter().sum::<f64>() / m, ys.iter().sum::<f64>() / m);
        let sxx: f64 = xs.iter().map(|u| (u - mx) * (u - mx)).sum();
        let sxy: f64 = xs.iter().zip(ys).map(|(u, v)| (u - mx) * (v - my)).sum();
        let est = if sxx > 1e-12 {
            my + sxy / sxx * (x - mx)
        } else {
            my
        };
        // Never more than a sample from the match itself.
        est.clamp(y - 1.0, y + 1.0)
    };
    (0..n)
        .map(|k| {
            let lo = (k.saturating_sub(half)..=k)
                .find(|&j| run[j] == run[k])
                .unwrap_or(k);
            let hi = (k..=(k + half).min(n - 1))
                .rev()
                .find(|&j| run[j] == run[k])
                .unwrap_or(k);
            let (a, b) = (kept[k].0 as f64, kept[k].1 as f64);
            if hi == lo {
                return (b, a);
            }
            let xa: Vec<f64> = kept[lo..=hi].iter().map(|m| m.0 as f64).collect();
            let xb: Vec<f64> = kept[lo..=hi].iter().map(|m| m.1 as f64).collect();
            (fit(&xa, &xb, a, b), fit(&xb, &xa, b, a))
        })
        .collect()
}

/// The vertex of the parabola through `(−1, lo)`, `(0, mid)`, `(1, hi)`, clamped to ±½;
/// `None` if a value is not finite or the parabola does not open upward.
fn parabola_vertex(lo: f64, mid: f64, hi: f64) -> Option<f64> {
    if !(lo.is_finite() && mid.is_finite() && hi.is_finite()) {
        return None;
    }
    let curvature = lo - 2.0 * mid + hi;
    if curvature <= 0.0 {
        return None;
    }
    Some((0.5 * (lo - hi) / curvature).clamp(-0.5, 0.5))
}

/// Where two rays (unit directions `ray_a`, `ray_b` from the two centres, and their dot
/// products `d_a`, `e_b` with the centres' offset `left − right`) come closest: the
/// parameters along each, `None` for parallel rays.
fn meet(ray_a: DVec3, d_a: f64, ray_b: DVec3, e_b: f64) -> Option<(f64, f64)> {
    let dot = ray_a.dot(ray_b);
    let denom = 1.0 - dot * dot;
    if denom < 1e-12 {
        return None;
    }
    Some(((dot * e_b - d_a) / denom, (e_b - dot * d_a) / denom))
}

fn pixel_distance(i: usize, j: usize, width: u32) -> f64 {
    let w = width as usize;
    let (xi, yi, xj, yj) = (i % w, i / w, j % w, j / w);
    ((xi as f64 - xj as f64).powi(2) + (yi as f64 - yj as f64).powi(2)).sqrt()
}

/// Adds the squared differences of two pixels' image stacks (from image `from` on) to `sum`
/// and their count to `n`; false if a view has no images.
fn add_stack_difference(
    (pl, a): (&Prepared<'_>, usize),
    (pr, b): (&Prepared<'_>, usize),
    from: usize,
    (sa, sb): (&mut Vec<f64>, &mut Vec<f64>),
    (sum, n): (&mut f64, &mut usize),
) -> bool {
    sa.clear();
    sb.clear();
    if !(pl.stack_at(a, sa, from) && pr.stack_at(b, sb, from)) {
        return false;
    }
    for (u, v) in sa.iter().zip(sb.iter()) {
        *sum += (u - v).powi(2);
        *n += 1;
    }
    true
}

/// Mean squared difference of the image stacks (from image `from` on) over the windows
/// around `ia` (left) and `ib` (right).
fn window_difference(
    pl: &Prepared<'_>,
    pr: &Prepared<'_>,
    ia: usize,
    ib: usize,
    half: i64,
    from: usize,
    (sa, sb): &mut (Vec<f64>, Vec<f64>),
) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for (a, b) in pl.window(ia, half).zip(pr.window(ib, half)) {
        let (Some(a), Some(b)) = (a, b) else { continue };
        if !add_stack_difference((pl, a), (pr, b), from, (sa, sb), (&mut sum, &mut n)) {
            return f64::INFINITY;
        }
    }
    if n == 0 {
        f64::INFINITY
    } else {
        sum / n as f64
    }
}

/// The half-on stacks compared through the surface: the left window's pixels against the
/// right image at the points of the right surface (rendered into the left view) that
/// correspond to them around the projection of the right sample's point `xb`.
fn projected_difference(
    pl: &Prepared<'_>,
    pr: &Prepared<'_>,
    ia: usize,
    xb: DVec3,
    half: i64,
    (sa, sb): &mut (Vec<f64>, Vec<f64>),
) -> f64 {
    let Some(centre) = pl.pixel_of(xb) else {
        return f64::INFINITY;
    };
    let (mut sum, mut n) = (0.0, 0usize);
    for (a, b) in pl.window(ia, half).zip(pl.window(centre, half)) {
        let (Some(a), Some(b)) = (a, b) else { continue };
        let (Some(_), Some(q)) = (pl.points[a], pl.other_points[b]) else {
            continue;
        };
        let Some(qb) = pr.pixel_of(q) else { continue };
        if !add_stack_difference((pl, a), (pr, qb), 1, (sa, sb), (&mut sum, &mut n)) {
            return f64::INFINITY;
        }
    }
    let full = ((2 * half + 1) * (2 * half + 1)) as usize;
    if n == 0 || n * 2 < full {
        f64::INFINITY
    } else {
        sum / n as f64
    }
}

// Tests only: match with the dense programme over every grid node (the form before the
// band-only one), to compare whole pairs. Thread-local and set only on the threads of a
// dedicated rayon pool (`tests::on_dense_pool`), so tests running beside that one keep the
// band-only programme (a process-wide flag made them see the dense one's tie-breaks).
#[cfg(test)]
thread_local! {
    static DENSE_PROGRAMME: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

#[cfg(test)]
mod tests {
    use super::*;

    const LO: usize = 2;
    const RO: usize = 3;
    use nalgebra::Matrix3;

    /// The reference: Kabsch by a 3 × 3 SVD with the reflection fix.
    fn rigid_residual_svd(pairs: &[(DVec3, DVec3)]) -> f64 {
        let n = pairs.len() as f64;
        let ca = pairs.iter().map(|p| p.0).sum::<DVec3>() / n;
        let cb = pairs.iter().map(|p| p.1).sum::<DVec3>() / n;
        let mut h = Matrix3::zeros();
        for (a, b) in pairs {
            let (a, b) = (*a - ca, *b - cb);
            h += nalgebra::Vector3::new(a.x, a.y, a.z)
                * nalgebra::Vector3::new(b.x, b.y, b.z).transpose();
        }
        let svd = h.svd(true, true);
        let (u, vt) = (svd.u.unwrap(), svd.v_t.unwrap());
        let mut d = Matrix3::identity();
        if (vt.transpose() * u.transpose()).determinant() < 0.0 {
            d[(2, 2)] = -1.0;
        }
        let r = vt.transpose() * d * u.transpose();
        pairs
            .iter()
            .map(|(a, b)| {
                let a = *a - ca;
                let ra = r * nalgebra::Vector3::new(a.x, a.y, a.z);
                (DVec3::new(ra.x, ra.y, ra.z) - (*b - cb)).length()
            })
            .sum::<f64>()
            / n
    }

    /// Uniform draws in [0, 1) from a seeded generator.
    fn uniform_draws(seed: u64) -> impl FnMut() -> f64 {
        let rng = skin_core::random::SplitMix64::new(seed);
        let mut draws = 0u64;
        move || {
            draws += 1;
            rng.uniform_at(draws)
        }
    }

    #[test]
    fn quaternion_kabsch_equals_the_svd_kabsch() {
        let mut uniform = uniform_draws(7);
        let mut worst: f64 = 0.0;
        for trial in 0..2000 {
            let n = 13 + trial % 13;
            let q = skin_core::math::DQuat::from_axis_angle(
                DVec3::new(uniform() - 0.5, uniform() - 0.5, uniform() - 0.5).normalize(),
                6.0 * uniform() - 3.0,
            );
            // Patch-like sets: a 5 × 5 grid of cm-sized points, some planar, bent,
            // mirrored or noisy, at a few metres from the origin.
            let kind = trial % 4;
            let pairs: Vec<(DVec3, DVec3)> = (0..n)
                .map(|k| {
                    let p = DVec3::new(
                        (k % 5) as f64 * 0.005,
                        (k / 5) as f64 * 0.005,
                        if kind == 0 { 0.0 } else { 0.002 * uniform() },
                    ) + DVec3::new(1.0, 2.0, 3.0);
                    let mut m = q * p + DVec3::new(0.3, -0.1, 0.2);
                    match kind {
                        1 => m += DVec3::splat(0.001) * (uniform() - 0.5),
                        2 => m.z = -m.z,
                        3 => m += DVec3::new(0.0, 0.0, 0.003 * (p.x * 300.0).sin()),
                        _ => {}
                    }
                    (p, m)
                })
                .collect();
            let (fast, slow) = (rigid_residual(&pairs), rigid_residual_svd(&pairs));
            let scale = slow.abs().max(1e-6);
            worst = worst.max((fast - slow).abs() / scale);
            assert!(
                (fast - slow).abs() <= 1e-7 * scale,
                "trial {trial}: {fast} vs {slow}"
            );
        }
        eprintln!("worst relative difference {worst:e}");
    }

    #[test]
    fn rigid_residual_ignores_a_rigid_motion_and_sees_a_bend() {
        let pts: Vec<DVec3> = (0..25)
            .map(|k| DVec3::new((k % 5) as f64 * 0.01, (k / 5) as f64 * 0.01, 0.0))
            .collect();
        let q = skin_core::math::DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 0.5).normalize(), 0.3);
        let moved: Vec<(DVec3, DVec3)> = pts
            .iter()
            .map(|p| (*p, q * *p + DVec3::new(0.1, -0.2, 0.3)))
            .collect();
        assert!(rigid_residual(&moved) < 1e-9);
        let bent: Vec<(DVec3, DVec3)> = pts
            .iter()
            .map(|p| (*p, *p + DVec3::Z * (p.x * 10.0).powi(2) * 0.01))
            .collect();
        assert!(rigid_residual(&bent) > 1e-4);
    }

    /// Two cameras 45° apart around a bumpy sphere, with its true depth maps.
    fn sphere_pair() -> (Vec<Camera>, Vec<DepthMap>) {
        sphere_ring(96, 2)
    }

    /// The first `n` of a ring of 8 cameras at `size`² around the bumpy sphere.
    fn sphere_ring(size: u32, n: usize) -> (Vec<Camera>, Vec<DepthMap>) {
        use skin_core::camera::{Intrinsics, Rig};
        use skin_core::mesh::shapes::uv_sphere;
        let k = Intrinsics::from_horizontal_fov(0.5, size, size).unwrap();
        let rig = Rig::ring(8, 3.0, 0.0, DVec3::ZERO, DVec3::Y, k).unwrap();
        let cams = rig.cameras[..n].to_vec();
        let mut mesh = uv_sphere(DVec3::ZERO, 0.4, 48, 96).unwrap();
        for v in &mut mesh.vertices {
            // Low bumps so that the surface metric has shape to match.
            *v *= 1.0 + 0.05 * (5.0 * v.x).sin() * (5.0 * v.y).cos();
        }
        let depths = cams
            .iter()
            .map(|c| mesh_proxy_depth(c, &mesh).unwrap())
            .collect();
        (cams, depths)
    }

    fn plain<'a>(camera: &'a Camera, surface: &'a DepthMap) -> MatchView<'a> {
        MatchView {
            camera,
            surface,
            guide: None,
            images: None,
        }
    }

    /// Per matched pixel of `target`, the matched depth minus the true depth, m.
    fn target_errors(target: &DepthMap, truth: &DepthMap) -> Vec<f64> {
        target
            .depth_m
            .iter()
            .zip(&truth.depth_m)
            .map(|(a, b)| a - b)
            .collect()
    }

    #[test]
    fn subpixel_matches_are_closer_to_the_true_depths_and_smoother() {
        // The true surfaces matched at 128²: integer matches snap each pixel's depth to
        // where its ray meets the other view's pixel rays; the parabola's vertex between
        // them must lower both the error and its pixel-to-pixel variation (the slope noise
        // Eq. 3.4 hands to the surface).
        let (cams, truth) = sphere_ring(128, 2);
        let (left, right) = (plain(&cams[0], &truth[0]), plain(&cams[1], &truth[1]));
        let run = |subpixel: SubPixel| {
            let params = MatchingParams {
                subpixel,
                ..MatchingParams::default()
            };
            match_pair(&left, &right, None, &params).unwrap()
        };
        let (whole, sub) = (run(SubPixel::Off), run(SubPixel::PathFit));
        let parabola = run(SubPixel::CostParabola);
        // The same path and matches: only the depths move.
        assert_eq!(whole.stats, sub.stats);
        let w = truth[0].width as usize;
        let summary = |m: &PairMatches| {
            let e = target_errors(&m.left.target, &truth[0]);
            let mut abs: Vec<f64> = e.iter().filter(|x| !x.is_nan()).map(|x| x.abs()).collect();
            abs.sort_by(f64::total_cmp);
            // Differences of the error between horizontally neighbouring matched pixels.
            let mut steps: Vec<f64> = (0..e.len())
                .filter(|&i| (i + 1) % w != 0 && !e[i].is_nan() && !e[i + 1].is_nan())
                .map(|i| (e[i + 1] - e[i]).abs())
                .collect();
            steps.sort_by(f64::total_cmp);
            let mean_step = steps.iter().sum::<f64>() / steps.len() as f64;
            (abs[abs.len() / 2], mean_step, abs.len())
        };
        let (med_whole, step_whole, n_whole) = summary(&whole);
        let (med_sub, step_sub, n_sub) = summary(&sub);
        let (med_par, step_par, _) = summary(&parabola);
        println!(
            "median |error| / mean step, mm: whole {:.3} / {:.3}, cost parabola {:.3} / {:.3}, path fit {:.3} / {:.3}",
            med_whole * 1e3, step_whole * 1e3, med_par * 1e3, step_par * 1e3, med_sub * 1e3, step_sub * 1e3
        );
        assert_eq!(n_whole, n_sub, "matched pixels");
        assert!(n_sub > 500, "{n_sub} matched pixels");
        assert!(
            med_sub < 0.9 * med_whole && step_sub < 0.9 * step_whole,
            "median |error| {med_whole} → {med_sub} m, mean step {step_whole} → {step_sub} m"
        );
    }

    #[test]
    fn matching_true_surfaces_recovers_their_depths_and_bad_input_is_an_error() {
        let (cams, truth) = sphere_pair();
        let (left, right) = (plain(&cams[0], &truth[0]), plain(&cams[1], &truth[1]));
        let m = match_pair(&left, &right, None, &MatchingParams::default()).unwrap();
        assert!(m.stats.good_matches > 300, "{:?}", m.stats);
        let mut err: Vec<f64> = m
            .left
            .target
            .depth_m
            .iter()
            .zip(&truth[0].depth_m)
            .filter(|(a, b)| !a.is_nan() && !b.is_nan())
            .map(|(a, b)| (a - b).abs())
            .collect();
        err.sort_by(f64::total_cmp);
        // A 96² pixel covers ≈ 1.4 cm at 3 m: matches are within a pixel's footprint.
        let median = err[err.len() / 2];
        assert!(median < 0.01, "{median}");
        let distorted = cams[0]
            .clone()
            .with_distortion(skin_core::camera::RadialDistortion::new(
                -0.1,
                DVec2::new(48.0, 48.0),
            ));
        let bad = plain(&distorted, &truth[0]);
        assert!(match_pair(&bad, &right, None, &MatchingParams::default()).is_err());
        let even = MatchingParams {
            window_px: 4,
            ..MatchingParams::default()
        };
        assert!(match_pair(&left, &right, None, &even).is_err());
        let image_metric = MatchingParams {
            metric: MatchMetric::FullOnWindow,
            ..MatchingParams::default()
        };
        assert!(match_pair(&left, &right, None, &image_metric).is_err());
    }

    /// A bumpy box 0.5 m in front of a bumpy backdrop (one height field over the plane
    /// z = 0, facing +z), seen by two cameras 3 m away and 45° apart, with the true depth maps.
    fn box_pair(size: u32) -> (Vec<Camera>, Vec<DepthMap>) {
        use skin_core::camera::Intrinsics;
        let k = Intrinsics::from_horizontal_fov(0.5, size, size).unwrap();
        let eye = |a: f64| DVec3::new(3.0 * a.sin(), 0.0, 3.0 * a.cos());
        let a = std::f64::consts::FRAC_PI_8;
        let cams: Vec<Camera> = [-a, a]
            .iter()
            .map(|&t| Camera::look_at(k, eye(t), DVec3::ZERO, DVec3::Y).unwrap())
            .collect();
        let n = 241;
        let coord = |i: usize| -1.2 + 2.4 * i as f64 / (n - 1) as f64;
        let mut vertices = Vec::with_capacity(n * n);
        for j in 0..n {
            for i in 0..n {
                let (x, y) = (coord(i), coord(j));
                let front = x.abs() < 0.2 && y.abs() < 0.3;
                let z = if front { 0.1 } else { -0.4 };
                let bumps = 0.02 * (17.0 * x).sin() * (13.0 * y).cos();
                vertices.push(DVec3::new(x, y, z + bumps));
            }
        }
        let mut faces = Vec::new();
        let at = |i: usize, j: usize| (j * n + i) as u32;
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                faces.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                faces.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
            }
        }
        let mesh = TriMesh::new(vertices, faces).unwrap();
        let depths = cams
            .iter()
            .map(|c| mesh_proxy_depth(c, &mesh).unwrap())
            .collect();
        (cams, depths)
    }

    #[test]
    fn contour_windows_give_fewer_gross_matches_beside_a_step_and_bad_input_is_an_error() {
        // Exact surfaces of a box in front of a backdrop: the whole 5 × 5 windows of the
        // thesis straddle the box's edges, whose background differs between the views (each
        // sees another stretch of the backdrop beside the box), so matches beside the step go
        // wrong; windows keeping only their centre's side must give at least 3× fewer (300 →
        // 57 when written).
        let size = 192;
        let (cams, truth) = box_pair(size);
        let (left, right) = (plain(&cams[0], &truth[0]), plain(&cams[1], &truth[1]));
        let run = |contour_jump_m: Option<f64>| {
            let params = MatchingParams {
                contour_jump_m,
                ..MatchingParams::default()
            };
            match_pair(&left, &right, None, &params).unwrap()
        };
        let (whole, contour) = (run(None), run(Some(0.01)));
        // Pixels within 3 px of a true depth jump of more than 10 cm (the box's edges).
        let w = size as usize;
        let d = &truth[0].depth_m;
        let jump = |i: usize, j: usize| (d[i] - d[j]).abs() > 0.1;
        let mut edge = vec![false; d.len()];
        for (i, e) in edge.iter_mut().enumerate() {
            let (x, y) = (i % w, i / w);
            *e = (x + 1 < w && jump(i, i + 1)) || (y + 1 < w && jump(i, i + w));
        }
        let near = |i: usize| {
            let (x, y) = ((i % w) as i64, (i / w) as i64);
            (-3..=3i64).any(|dy| {
                (-3..=3i64).any(|dx| {
                    let (u, v) = (x + dx, y + dy);
                    u >= 0
                        && v >= 0
                        && u < w as i64
                        && v < w as i64
                        && edge[(v * w as i64 + u) as usize]
                })
            })
        };
        // Matches more than 1 cm off (a 192² pixel covers ≈ 8 mm at 3 m), and all matches,
        // beside the step.
        let count = |m: &PairMatches| {
            let e = target_errors(&m.left.target, &truth[0]);
            let beside: Vec<f64> = (0..e.len())
                .filter(|&i| near(i) && !e[i].is_nan())
                .map(|i| e[i])
                .collect();
            let gross = beside.iter().filter(|x| x.abs() > 0.01).count();
            let all = e.iter().filter(|x| !x.is_nan()).count();
            (gross, beside.len(), all)
        };
        let (gross_whole, beside_whole, all_whole) = count(&whole);
        let (gross_contour, beside_contour, all_contour) = count(&contour);
        println!(
            "beside the step: > 1 cm off {gross_whole} of {beside_whole} (whole windows) → \
             {gross_contour} of {beside_contour} (contour windows); matched pixels {all_whole} → {all_contour}"
        );
        assert!(
            gross_whole >= 20,
            "the step must trouble whole windows: {gross_whole}"
        );
        assert!(
            3 * gross_contour <= gross_whole,
            "gross matches beside the step {gross_whole} → {gross_contour}"
        );
        // Not by matching less: at least as many matched pixels overall.
        assert!(
            10 * all_contour >= 9 * all_whole,
            "{all_whole} → {all_contour}"
        );
        for bad in [0.0, -0.01, f64::NAN] {
            let params = MatchingParams {
                contour_jump_m: Some(bad),
                ..MatchingParams::default()
            };
            assert!(match_pair(&left, &right, None, &params).is_err(), "{bad}");
        }
    }

    /// The reference: the four-state programme over every node of the `(na + 1) × (nb + 1)`
    /// grid, as it was before the band-only form ([`lowest_cost_path`]).
    pub(super) fn lowest_cost_path_dense(
        costs: &[f64],
        na: usize,
        nb: usize,
        occ: f64,
        disc: f64,
    ) -> Vec<(usize, usize)> {
        let (ri, rj) = (na + 1, nb + 1);
        let at = |i: usize, j: usize| i * rj + j;
        // The costs of rows i − 1 and i (rolling); the back-pointers of all cells.
        let mut above = vec![[f64::INFINITY; 4]; rj];
        let mut here = vec![[f64::INFINITY; 4]; rj];
        let mut from = vec![[u8::MAX; 4]; ri * rj];
        let matched = |s: usize| s == LV || s == RV;
        let offer = |s: usize, v: f64, p: usize, best: &mut [f64; 4], arg: &mut [u8; 4]| {
            if v < best[s] {
                best[s] = v;
                arg[s] = p as u8;
            }
        };
        for i in 0..ri {
            for j in 0..rj {
                if i == 0 && j == 0 {
                    here[0] = [f64::INFINITY; 4];
                    here[0][LO] = 0.0;
                    continue;
                }
                let mut best = [f64::INFINITY; 4];
                let mut arg = [u8::MAX; 4];
                if i > 0 && j > 0 {
                    let c = costs[(i - 1) * nb + (j - 1)];
                    if c.is_finite() {
                        // Diagonal match from any state; left-slanted from a match at (i−1, j).
                        for (p, &prev) in above[j - 1].iter().enumerate() {
                            let pen = if matched(p) { 0.0 } else { disc };
                            offer(LV, prev + c + pen, p, &mut best, &mut arg);
                        }
                        for p in [LV, RV] {
                            offer(LV, above[j][p] + c, 4 + p, &mut best, &mut arg);
                            offer(RV, here[j - 1][p] + c, p, &mut best, &mut arg);
                        }
                    }
                }
                if i > 0 {
                    for (p, &prev) in above[j].iter().enumerate() {
                        let pen = if matched(p) { disc } else { 0.0 };
                        offer(LO, prev + occ + pen, p, &mut best, &mut arg);
                    }
                }
                if j > 0 {
                    for (p, &prev) in here[j - 1].iter().enumerate() {
                        let pen = if matched(p) { disc } else { 0.0 };
                        offer(RO, prev + occ + pen, p, &mut best, &mut arg);
                    }
                }
                here[j] = best;
                from[at(i, j)] = arg;
            }
            std::mem::swap(&mut above, &mut here);
        }
        // Backtrack from the cheapest end state (row na is `above` after the last swap).
        let end = above[nb];
        let Some(mut s) = (0..4)
            .filter(|&s| end[s].is_finite())
            .min_by(|&a, &b| end[a].total_cmp(&end[b]))
        else {
            return Vec::new();
        };
        let (mut i, mut j) = (na, nb);
        let mut path = Vec::new();
        while i > 0 || j > 0 {
            let p = from[at(i, j)][s];
            if p == u8::MAX {
                break;
            }
            let p = p as usize;
            match s {
                LV => {
                    path.push((i - 1, j - 1));
                    if p >= 4 {
                        i -= 1;
                        s = p - 4;
                    } else {
                        i -= 1;
                        j -= 1;
                        s = p;
                    }
                }
                RV => {
                    path.push((i - 1, j - 1));
                    j -= 1;
                    s = p;
                }
                LO => {
                    i -= 1;
                    s = p;
                }
                _ => {
                    j -= 1;
                    s = p;
                }
            }
        }
        path.reverse();
        path
    }

    /// The rows' ranges of finite cells.
    fn row_ranges(costs: &[f64], na: usize, nb: usize) -> Vec<(usize, usize)> {
        (0..na)
            .map(|a| {
                let row = &costs[a * nb..(a + 1) * nb];
                match row.iter().position(|c| c.is_finite()) {
                    None => (0, 0),
                    Some(lo) => (
                        lo,
                        nb - row.iter().rev().position(|c| c.is_finite()).unwrap_or(0),
                    ),
                }
            })
            .collect()
    }

    #[test]
    fn band_only_programme_finds_the_paths_of_the_full_grid() {
        // Random bands of random costs (some holes), random penalties: the band-only form
        // returns the dense programme's path on every grid.
        let mut uniform = uniform_draws(11);
        let mut compared = 0;
        for trial in 0..400 {
            let na = 1 + (uniform() * 40.0) as usize;
            let nb = 1 + (uniform() * 40.0) as usize;
            let half = 1.0 + uniform() * 8.0;
            let slope = nb as f64 / na as f64 * (0.6 + 0.8 * uniform());
            let shift = (uniform() - 0.5) * 10.0;
            let costs: Vec<f64> = (0..na * nb)
                .map(|k| {
                    let (a, b) = (k / nb, k % nb);
                    let inside = ((b as f64) - (a as f64 * slope + shift)).abs() <= half;
                    if inside && uniform() > 0.1 {
                        uniform() * uniform()
                    } else {
                        f64::INFINITY
                    }
                })
                .collect();
            let (occ, disc) = (0.2 + uniform(), 2.0 * uniform());
            let dense = lowest_cost_path_dense(&costs, na, nb, occ, disc);
            let band = lowest_cost_path(&costs, na, nb, &row_ranges(&costs, na, nb), occ, disc);
            assert_eq!(
                dense, band,
                "trial {trial}: {na} × {nb}, occ {occ}, disc {disc}"
            );
            compared += dense.len();
        }
        assert!(compared > 1000, "{compared} matches compared");
    }

    fn bits(d: &DepthMap) -> Vec<u64> {
        d.depth_m.iter().map(|v| v.to_bits()).collect()
    }

    /// Runs `f` on a rayon pool of its own whose threads use the dense programme.
    fn on_dense_pool<T: Send>(f: impl FnOnce() -> T + Send) -> T {
        rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .start_handler(|_| DENSE_PROGRAMME.with(|d| d.set(true)))
            .build()
            .unwrap()
            .install(f)
    }

    #[test]
    fn band_only_matching_equals_the_dense_programme_and_coarse_to_fine_keeps_the_accuracy() {
        // A pair at 192² with the hull of the whole ring: the band-only programme gives the
        // same matches, bit for bit, as the dense one (the form before).
        let (cams, truth) = sphere_ring(192, 8);
        let masks: Vec<Mask> = truth
            .iter()
            .map(|d| {
                Mask::from_fn(d.width, d.height, |x, y| {
                    !d.depth_m[(y * d.width + x) as usize].is_nan()
                })
            })
            .collect();
        let hull = PolygonalHull::new(&cams, &masks).unwrap();
        let (left, right) = (plain(&cams[0], &truth[0]), plain(&cams[1], &truth[1]));
        let params = MatchingParams {
            coarse_to_fine: false,
            ..MatchingParams::default()
        };
        let band = match_pair(&left, &right, Some(&hull), &params).unwrap();
        let dense = on_dense_pool(|| match_pair(&left, &right, Some(&hull), &params)).unwrap();
        assert_eq!(band.stats, dense.stats);
        assert!(band.stats.good_matches > 2000, "{:?}", band.stats);
        for (b, d) in [(&band.left, &dense.left), (&band.right, &dense.right)] {
            assert_eq!(bits(&b.target), bits(&d.target));
            assert_eq!(b.breaks, d.breaks);
        }
        // Coarse-to-fine: far fewer cells, and the matches as close to the truth (median
        // within a tenth of a pixel footprint, ≈ 0.5 mm here).
        let c2f = MatchingParams {
            coarse_to_fine: true,
            ..params
        };
        let fine = match_pair(&left, &right, Some(&hull), &c2f).unwrap();
        let err = |m: &PairMatches| {
            let e = crate::depth_errors(&m.left.target, &truth[0], None).unwrap();
            (e.median_mm, e.p95_mm, e.pixels)
        };
        let (full_e, fine_e) = (err(&band), err(&fine));
        eprintln!(
            "full {:?} {full_e:?}\ncoarse-to-fine {:?} {fine_e:?}",
            band.stats, fine.stats
        );
        assert!(
            fine.stats.cells_evaluated * 4 < band.stats.cells_evaluated * 3,
            "{:?} vs {:?}",
            fine.stats,
            band.stats
        );
        assert!(fine_e.0 <= full_e.0 + 0.5, "{fine_e:?} vs {full_e:?}");
        assert!(
            fine_e.2 as f64 >= 0.95 * full_e.2 as f64,
            "{fine_e:?} vs {full_e:?}"
        );
        // Too small for a coarse level: the same as without.
        let (small, small_truth) = sphere_pair();
        let (l, r) = (
            plain(&small[0], &small_truth[0]),
            plain(&small[1], &small_truth[1]),
        );
        let a = match_pair(&l, &r, None, &params).unwrap();
        let b = match_pair(&l, &r, None, &c2f).unwrap();
        assert_eq!(bits(&a.left.target), bits(&b.left.target));
        let bad = MatchingParams {
            coarse_band_px: f64::NAN,
            ..c2f
        };
        assert!(match_pair(&l, &r, None, &bad).is_err());
    }

    #[test]
    fn dynamic_programme_follows_the_cheap_diagonal_and_skips_an_occlusion() {
        // 6 × 6 grid: cheap along a = b except that left sample 2 has no good match.
        let (na, nb) = (6, 6);
        let mut costs = vec![1.0; na * nb];
        for k in 0..6 {
            costs[k * nb + k] = 0.01;
        }
        costs[2 * nb + 2] = f64::INFINITY;
        let path = lowest_cost_path(&costs, na, nb, &row_ranges(&costs, na, nb), 0.5, 0.1);
        assert!(path.contains(&(0, 0)) && path.contains(&(5, 5)), "{path:?}");
        assert!(!path.iter().any(|&(a, _)| a == 2), "{path:?}");
        let none = lowest_cost_path(&[f64::INFINITY; 4], 2, 2, &[(0, 0); 2], 0.5, 0.1);
        assert!(none.is_empty());
    }
}
