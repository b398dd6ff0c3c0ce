//! Table 3.1's accuracy figures (§3.4), computed from the capture's own data (no ground
//! truth), and the distance of a mesh to a true surface (beyond the thesis).
//!
//! For every camera the reconstructed mesh is rendered (smooth vertex normals, both faces);
//! a *measured normal* is a valid normal-map pixel inside the camera's silhouette.
//!
//! * **coverage** — the percentage of measured normals whose pixel ray hits the mesh within
//!   `near_m` of the view's own per-view surface (the normal "yielded an actual surface").
//! * **normal deviation** — per vertex, as the thesis: a camera *samples* a mesh vertex if
//!   the vertex projects onto covered pixels (at least half of its bilinear footprint) and is
//!   the surface the camera sees there (its distance to the camera within `near_m / 2` of
//!   the rendered hit depth interpolated at its projection); the sample's *measured normal* is
//!   the normal map interpolated bilinearly over the covered pixels, its *mesh normal* the
//!   area-weighted vertex normal turned toward the camera. Each vertex keeps the sample of
//!   the camera that sees it most frontally (largest cosine between mesh normal and line of
//!   sight); the figure is the mean angle between mesh and measured normal over the sampled
//!   vertices.
//! * **local normal deviation** — thesis: "the angle between a vertex and its neighbors is
//!   compared to the angle between the measured normal for that vertex and the measured
//!   normals for the neighbors": for each mesh edge (u, v) whose ends were both sampled by
//!   the same camera, |∠(n_mesh(u), n_mesh(v)) − ∠(n_meas(u), n_meas(v))|, averaged over
//!   those edges (degrees).
//! * the **pixel variants** (`pixel_*`, kept for comparison): the same two figures on the
//!   pixel grid — the rendered mesh's (Phong) normal against the measured normal at every
//!   covered pixel, and the local figure over each covered pixel's right and lower covered
//!   neighbours.
//!
//! Beyond the thesis: [`surface_distance`] to a true mesh, and [`displacement_survival`], the
//! share of a known relief (the studio's wrinkles) a reconstruction keeps.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use skin_core::camera::Camera;
use skin_core::check;
use skin_core::image::Mask;
use skin_core::math::DVec3;
#[cfg(feature = "validation")]
use skin_core::math::Ray;
#[cfg(feature = "validation")]
use skin_core::mesh::MeshQuery;
use skin_core::mesh::{one_sided_distance, vertex_normals, NormalWeighting, TriMesh};
use skin_core::raster::{Buffers, Rasterizer, RenderParams};

#[cfg(feature = "validation")]
use crate::{depth_jumps, IntegrationParams, ViewSurfaces};
use crate::{rendered_normals, Context, DepthMap, Error, NormalMap, Result, ResultExt};

/// Parameters of [`table_metrics`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MetricParams {
    /// A pixel counts as covered if the mesh is hit within this distance (m, along the ray)
    /// of the view's per-view surface. Default 1 cm (the thesis's discontinuity threshold).
    pub near_m: f64,
}

impl Default for MetricParams {
    fn default() -> Self {
        Self { near_m: 0.01 }
    }
}

/// Table 3.1's three figures for one mesh.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TableMetrics {
    /// Measured normals (valid normal-map pixels inside the silhouettes), all cameras.
    pub measured_px: usize,
    /// Of those, the covered ones.
    pub covered_px: usize,
    /// `100 · covered / measured`.
    pub coverage_pct: f64,
    /// Mesh vertices sampled by some camera (see the module docs), each once.
    pub vertex_samples: usize,
    /// Mean angle between each sampled vertex's normal and the measured normal interpolated
    /// at its projection, degrees (the thesis's vertex form; see the module docs).
    pub normal_dev_deg: f64,
    /// Mean local normal deviation over the mesh's edges (vertex neighbourhoods, as the
    /// thesis defines it; see the module docs), degrees.
    pub local_normal_dev_deg: f64,
    /// Pixel variant of `normal_dev_deg`: mean angle between the rendered mesh's and the
    /// measured normals at covered pixels, degrees.
    pub pixel_normal_dev_deg: f64,
    /// Pixel variant of `local_normal_dev_deg`: over right/lower neighbouring covered
    /// pixels, degrees.
    pub pixel_local_normal_dev_deg: f64,
}

fn angle_deg(a: DVec3, b: DVec3) -> f64 {
    a.dot(b).clamp(-1.0, 1.0).acos().to_degrees()
}

/// Sums of one camera: pixel (measured, covered, Σ deviation, Σ local deviation, local
/// pairs) and vertex (samples, Σ deviation, Σ local deviation, local pairs).
#[derive(Debug, Clone, Copy, Default)]
struct Sums {
    measured: usize,
    covered: usize,
    dev: f64,
    local: f64,
    pairs: usize,
    v_samples: usize,
    v_dev: f64,
    v_local: f64,
    v_pairs: usize,
}

impl Sums {
    fn add(self, o: Self) -> Self {
        Self {
            measured: self.measured + o.measured,
            covered: self.covered + o.covered,
            dev: self.dev + o.dev,
            local: self.local + o.local,
            pairs: self.pairs + o.pairs,
            v_samples: self.v_samples + o.v_samples,
            v_dev: self.v_dev + o.v_dev,
            v_local: self.v_local + o.v_local,
            v_pairs: self.v_pairs + o.v_pairs,
        }
    }
}

/// The mesh's shared data for the vertex variant: vertex normals and unique edges.
struct VertexData {
    normals: Vec<DVec3>,
    edges: Vec<(usize, usize)>,
}

impl VertexData {
    /// The vertex normals only (no edges: for the samples without the local deviation).
    fn normals_only(mesh: &TriMesh) -> Result<Self> {
        Ok(Self {
            normals: vertex_normals(mesh, NormalWeighting::Area)?,
            edges: Vec::new(),
        })
    }

    fn new(mesh: &TriMesh) -> Result<Self> {
        let normals = vertex_normals(mesh, NormalWeighting::Area)?;
        let mut edges: Vec<(usize, usize)> = mesh
            .faces
            .iter()
            .flat_map(|f| {
                (0..3).map(move |k| {
                    let (a, b) = (f[k] as usize, f[(k + 1) % 3] as usize);
                    (a.min(b), a.max(b))
                })
            })
            .collect();
        edges.sort_unstable();
        edges.dedup();
        Ok(Self { normals, edges })
    }
}

/// One vertex seen by one camera: mesh normal and measured normal (camera frame) and the
/// cosine between the mesh normal and the line of sight.
#[derive(Debug, Clone, Copy)]
struct VertexSample {
    camera: usize,
    mesh: DVec3,
    measured: DVec3,
    cosine: f64,
}

/// The vertex variant in one camera: every mesh vertex that projects onto a covered pixel
/// and is the surface the camera sees there (its distance to the camera within `tol_m` of
/// the rendered hit depth interpolated at its projection) gets the measured normal
/// interpolated bilinearly from the covered pixels around its projection; its mesh normal is
/// its vertex normal in the camera frame, turned toward the camera.
#[allow(clippy::too_many_arguments)]
fn vertex_samples(
    c: usize,
    camera: &Camera,
    normals: &NormalMap,
    covered: &[bool],
    hit: &DepthMap,
    mesh: &TriMesh,
    data: &VertexData,
    tol_m: f64,
) -> Vec<Option<VertexSample>> {
    let (w, h) = (hit.width as usize, hit.height as usize);
    let from_world = camera.camera_from_world();
    let centre = camera.centre();
    let sample = |p: DVec3, n: DVec3| -> Option<VertexSample> {
        let px = camera.project(p).ok()?;
        let (x0, y0) = (px.x.floor(), px.y.floor());
        if !(x0 >= -1.0 && y0 >= -1.0 && x0 < w as f64 && y0 < h as f64) {
            return None;
        }
        let (fx, fy) = (px.x - x0, px.y - y0);
        let (mut m, mut depth, mut wsum) = (DVec3::ZERO, 0.0, 0.0);
        for (dx, dy, wt) in [
            (0.0, 0.0, (1.0 - fx) * (1.0 - fy)),
            (1.0, 0.0, fx * (1.0 - fy)),
            (0.0, 1.0, (1.0 - fx) * fy),
            (1.0, 1.0, fx * fy),
        ] {
            let (x, y) = (x0 + dx, y0 + dy);
            if x < 0.0 || y < 0.0 || x >= w as f64 || y >= h as f64 {
                continue;
            }
            let i = y as usize * w + x as usize;
            if covered[i] {
                m += wt * normals.normals[i];
                depth += wt * hit.depth_m[i];
                wsum += wt;
            }
        }
        // Most of the bilinear footprint must be covered, and the vertex must be the
        // surface seen there (not one hidden just behind it).
        if wsum < 0.5 || ((p - centre).length() - depth / wsum).abs() > tol_m {
            return None;
        }
        let measured = m.try_normalize()?;
        let p_cam = from_world.transform_point3(p);
        let n = from_world.transform_vector3(n).try_normalize()?;
        let n = if n.dot(p_cam) > 0.0 { -n } else { n };
        let cosine = -n.dot(p_cam.try_normalize()?);
        Some(VertexSample {
            camera: c,
            mesh: n,
            measured,
            cosine,
        })
    };
    mesh.vertices
        .par_iter()
        .zip(&data.normals)
        .map(|(&p, &n)| sample(p, n))
        .collect()
}

/// The vertex figures from each vertex's most frontal sample: (samples, Σ deviation,
/// Σ local deviation over edges whose ends were sampled by the same camera, edges).
fn vertex_sums(
    best: &[Option<VertexSample>],
    edges: &[(usize, usize)],
) -> (usize, f64, f64, usize) {
    let (mut count, mut dev) = (0, 0.0);
    for s in best.iter().flatten() {
        count += 1;
        dev += angle_deg(s.mesh, s.measured);
    }
    let (mut local, mut pairs) = (0.0, 0);
    for &(a, b) in edges {
        if let (Some(u), Some(v)) = (best[a], best[b]) {
            if u.camera == v.camera {
                local += (angle_deg(u.mesh, v.mesh) - angle_deg(u.measured, v.measured)).abs();
                pairs += 1;
            }
        }
    }
    (count, dev, local, pairs)
}

/// One camera's rendering of `mesh` for the metrics: the rendered view (the depth, and the
/// mask and normals if `with_normals`), its hit depth and the covered pixels (a valid normal
/// inside the silhouette whose mesh hit lies within `near_m` of the view's per-view surface).
fn covered_render(
    camera: &Camera,
    normals: &NormalMap,
    silhouette: &Mask,
    surface: &DepthMap,
    mesh: &TriMesh,
    params: &MetricParams,
    with_normals: bool,
) -> Result<(skin_core::raster::RenderedView, Vec<bool>, DepthMap)> {
    surface.check_camera(camera)?;
    let w = surface.width;
    check::same_size(
        "normal-map pixels",
        surface.depth_m.len(),
        normals.normals.len(),
    )?;
    check::same_size(
        "normal-map validity",
        surface.depth_m.len(),
        normals.valid.len(),
    )?;
    check::same_size(
        "silhouette pixels",
        surface.depth_m.len(),
        silhouette.pixel_count(),
    )?;
    let buffers = Buffers {
        mask: with_normals,
        depth: true,
        camera_z: false,
        normal: with_normals,
        triangle: false,
    };
    let view = Rasterizer::new(camera).render(
        mesh,
        &RenderParams::default()
            .with_buffers(buffers)
            .with_cull_back_faces(false)
            .with_allow_empty(true),
    )?;
    let hit = DepthMap::from_view(&view)?;
    let covered: Vec<bool> = (0..surface.depth_m.len())
        .map(|i| {
            let (x, y) = (i as u32 % w, i as u32 / w);
            normals.valid[i]
                && silhouette.get(x, y)
                && (hit.depth_m[i] - surface.depth_m[i]).abs() < params.near_m
        })
        .collect();
    Ok((view, covered, hit))
}

fn camera_sums(
    camera: &Camera,
    normals: &NormalMap,
    silhouette: &Mask,
    surface: &DepthMap,
    mesh: &TriMesh,
    params: &MetricParams,
) -> Result<(Sums, Vec<bool>, DepthMap)> {
    let (view, covered, hit) =
        covered_render(camera, normals, silhouette, surface, mesh, params, true)?;
    let (w, h) = (surface.width, surface.height);
    let rec = rendered_normals(camera, &view)?;
    let measured = (0..surface.depth_m.len())
        .filter(|&i| normals.valid[i] && silhouette.get(i as u32 % w, i as u32 / w))
        .count();
    let (mut n_cov, mut dev, mut local, mut pairs) = (0, 0.0, 0.0, 0);
    for y in 0..h {
        for x in 0..w {
            let p = surface.index(x, y);
            if !covered[p] {
                continue;
            }
            n_cov += 1;
            dev += angle_deg(rec.normals[p], normals.normals[p]);
            let right = (x + 1 < w).then(|| surface.index(x + 1, y));
            let down = (y + 1 < h).then(|| surface.index(x, y + 1));
            for q in [right, down].into_iter().flatten().filter(|&q| covered[q]) {
                let a = angle_deg(rec.normals[p], rec.normals[q]);
                let b = angle_deg(normals.normals[p], normals.normals[q]);
                local += (a - b).abs();
                pairs += 1;
            }
        }
    }
    let sums = Sums {
        measured,
        covered: n_cov,
        dev,
        local,
        pairs,
        ..Sums::default()
    };
    Ok((sums, covered, hit))
}

/// Checks one normal map, silhouette and surface per camera and a positive `near_m`; the
/// number of cameras.
fn check_views(
    cameras: &[Camera],
    normals: &[NormalMap],
    silhouettes: &[Mask],
    surfaces: &[DepthMap],
    params: &MetricParams,
) -> Result<usize> {
    let n = cameras.len();
    check::same_size("normal maps per camera", n, normals.len())?;
    check::same_size("silhouettes per camera", n, silhouettes.len())?;
    check::same_size("surfaces per camera", n, surfaces.len())?;
    check::positive("near_m", params.near_m)?;
    Ok(n)
}

/// The pixels Table 3.1 counts as covered in each camera: a measured normal (valid, inside
/// the silhouette) whose pixel ray hits `mesh` within [`MetricParams::near_m`] of the view's
/// own per-view surface — the pixels [`table_metrics`]'s coverage counts and its normal
/// figures are taken over. One mask per camera, row-major.
///
/// With it a second mesh can be scored over the same pixels as a first one (normal maps whose
/// `valid` is restricted to the first mesh's covered pixels), e.g. a perfect geometry against
/// a reconstruction, whose coverage differs.
///
/// # Errors
/// As [`table_metrics`] (it does not fail when nothing is covered).
pub fn covered_pixels(
    cameras: &[Camera],
    normals: &[NormalMap],
    silhouettes: &[Mask],
    surfaces: &[DepthMap],
    mesh: &TriMesh,
    params: &MetricParams,
) -> Result<Vec<Vec<bool>>> {
    Ok(
        covered_renders(cameras, normals, silhouettes, surfaces, mesh, params)?
            .into_iter()
            .map(|(covered, _)| covered)
            .collect(),
    )
}

/// Per camera, [`covered_render`]'s covered pixels and hit depth (errors named by camera).
fn covered_renders(
    cameras: &[Camera],
    normals: &[NormalMap],
    silhouettes: &[Mask],
    surfaces: &[DepthMap],
    mesh: &TriMesh,
    params: &MetricParams,
) -> Result<Vec<(Vec<bool>, DepthMap)>> {
    let n = check_views(cameras, normals, silhouettes, surfaces, params)?;
    (0..n)
        .into_par_iter()
        .map(|c| {
            covered_render(
                &cameras[c],
                &normals[c],
                &silhouettes[c],
                &surfaces[c],
                mesh,
                params,
                false,
            )
            .map(|(_, covered, hit)| (covered, hit))
            .at(Context::Camera(c))
        })
        .collect()
}

/// Table 3.1's coverage, normal deviation and local normal deviation of `mesh` against the
/// measured `normals` of `cameras` (see the module docs), with each view's per-view
/// `surfaces` deciding which hits belong to the view.
///
/// # Errors
/// [`Error::SizeMismatch`] for counts or image sizes that differ; [`Error::InvalidParam`] for
/// a non-positive `near_m`; [`Error::Empty`] if no pixel is a measured normal or none is
/// covered; errors of the rasteriser (named by camera).
pub fn table_metrics(
    cameras: &[Camera],
    normals: &[NormalMap],
    silhouettes: &[Mask],
    surfaces: &[DepthMap],
    mesh: &TriMesh,
    params: &MetricParams,
) -> Result<TableMetrics> {
    let n = check_views(cameras, normals, silhouettes, surfaces, params)?;
    let data = VertexData::new(mesh)?;
    let per_camera = (0..n)
        .into_par_iter()
        .map(|c| {
            camera_sums(
                &cameras[c],
                &normals[c],
                &silhouettes[c],
                &surfaces[c],
                mesh,
                params,
            )
            .at(Context::Camera(c))
        })
        .collect::<Result<Vec<_>>>()?;
    // Each vertex's measured normal from the camera that sees it most frontally.
    let mut best: Vec<Option<VertexSample>> = vec![None; mesh.vertices.len()];
    let mut s = Sums::default();
    for (c, (sums, covered, hit)) in per_camera.into_iter().enumerate() {
        s = s.add(sums);
        let tol = 0.5 * params.near_m;
        let samples = vertex_samples(
            c,
            &cameras[c],
            &normals[c],
            &covered,
            &hit,
            mesh,
            &data,
            tol,
        );
        for (b, v) in best.iter_mut().zip(samples) {
            if let Some(v) = v {
                if b.is_none_or(|b| v.cosine > b.cosine) {
                    *b = Some(v);
                }
            }
        }
    }
    (s.v_samples, s.v_dev, s.v_local, s.v_pairs) = vertex_sums(&best, &data.edges);
    let (m, c) = (s.measured, s.covered);
    if m == 0 {
        return Err(Error::Empty {
            what: "measured normals inside the silhouettes",
        });
    }
    if c == 0 {
        return Err(Error::Empty {
            what: "measured normals covered by the mesh",
        });
    }
    Ok(TableMetrics {
        measured_px: m,
        covered_px: c,
        coverage_pct: 100.0 * c as f64 / m as f64,
        vertex_samples: s.v_samples,
        normal_dev_deg: if s.v_samples > 0 {
            s.v_dev / s.v_samples as f64
        } else {
            f64::NAN
        },
        local_normal_dev_deg: if s.v_pairs > 0 {
            s.v_local / s.v_pairs as f64
        } else {
            f64::NAN
        },
        pixel_normal_dev_deg: s.dev / c as f64,
        pixel_local_normal_dev_deg: if s.pairs > 0 {
            s.local / s.pairs as f64
        } else {
            f64::NAN
        },
    })
}

/// One camera's measured normal at a mesh vertex, as the vertex form of Table 3.1's normal
/// deviation takes it ([`table_metrics`], module docs): the normal map interpolated
/// bilinearly over the covered pixels around the vertex's projection, for a vertex that is
/// the surface the camera sees there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VertexNormalSample {
    /// The camera.
    pub camera: usize,
    /// The measured normal, world frame, unit length.
    pub measured: DVec3,
    /// Cosine between the vertex's (area-weighted) normal, turned toward the camera, and the
    /// line of sight: 1 for a vertex seen head-on.
    pub cosine: f64,
}

/// Every camera's measured normal at every vertex of `mesh` that the camera samples, exactly
/// as [`table_metrics`] samples them for its vertex normal deviation (covered pixels, the
/// visibility tolerance `near_m / 2`), handed to `visit(vertex, sample)` camera by camera.
/// [`table_metrics`] keeps each vertex's most frontal sample; the refinement
/// ([`crate::refine_mesh`]) fuses them.
///
/// # Errors
/// As [`table_metrics`], except that no sampled vertex is not an error.
pub fn vertex_normal_samples(
    cameras: &[Camera],
    normals: &[NormalMap],
    silhouettes: &[Mask],
    surfaces: &[DepthMap],
    mesh: &TriMesh,
    params: &MetricParams,
    mut visit: impl FnMut(usize, VertexNormalSample),
) -> Result<()> {
    let per_camera = covered_renders(cameras, normals, silhouettes, surfaces, mesh, params)?;
    let data = VertexData::normals_only(mesh)?;
    let tol = 0.5 * params.near_m;
    for (c, (covered, hit)) in per_camera.into_iter().enumerate() {
        let to_world = cameras[c].world_from_camera();
        let samples = vertex_samples(
            c,
            &cameras[c],
            &normals[c],
            &covered,
            &hit,
            mesh,
            &data,
            tol,
        );
        for (v, s) in samples.into_iter().enumerate() {
            let Some(s) = s else { continue };
            if let Some(measured) = to_world.transform_vector3(s.measured).try_normalize() {
                visit(
                    v,
                    VertexNormalSample {
                        camera: c,
                        measured,
                        cosine: s.cosine,
                    },
                );
            }
        }
    }
    Ok(())
}

/// Where the measured normals that a mesh does not cover were lost ([`coverage_budget`]):
/// pixel counts over all cameras, each measured normal in exactly one class, in the order
/// of the pipeline.
#[cfg(feature = "validation")]
#[cfg_attr(docsrs, doc(cfg(feature = "validation")))]
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub struct CoverageBudget {
    /// Measured normals (as [`TableMetrics::measured_px`]).
    pub measured_px: usize,
    /// Covered by the mesh (as [`TableMetrics::covered_px`]).
    pub covered_px: usize,
    /// No per-view surface: removed from Eq. 3.3 as a pixel straddling a proxy depth jump.
    pub cut_proxy_jump_px: usize,
    /// No per-view surface: removed from Eq. 3.3 as a discontinuity found by matching.
    pub cut_match_break_px: usize,
    /// No per-view surface: in an integration region too small or without any proxy depth
    /// (outside the proxy), or integrated to a depth behind the camera.
    pub dropped_region_px: usize,
    /// No per-view surface: integrated, but discarded by Eq. 3.4 (too far from any match, or
    /// in a region without one).
    pub discarded_offsets_px: usize,
    /// A per-view surface farther than `near_m` from the reference along the ray (a gross
    /// per-view error), not covered.
    pub gross_uncovered_px: usize,
    /// A gross per-view error that the mesh nevertheless covers (the mesh is as wrong).
    pub gross_covered_px: usize,
    /// A per-view surface within `near_m` of the reference, but the mesh's first hit along
    /// the ray lies more than `near_m` in front of it (another view's surface occludes it).
    pub merge_in_front_px: usize,
    /// As `merge_in_front_px`, but the first hit lies more than `near_m` behind.
    pub merge_behind_px: usize,
    /// As `merge_in_front_px`, but the ray misses the mesh (a hole of the merge).
    pub merge_hole_px: usize,
}

#[cfg(feature = "validation")]
impl CoverageBudget {
    fn add(self, o: Self) -> Self {
        Self {
            measured_px: self.measured_px + o.measured_px,
            covered_px: self.covered_px + o.covered_px,
            cut_proxy_jump_px: self.cut_proxy_jump_px + o.cut_proxy_jump_px,
            cut_match_break_px: self.cut_match_break_px + o.cut_match_break_px,
            dropped_region_px: self.dropped_region_px + o.dropped_region_px,
            discarded_offsets_px: self.discarded_offsets_px + o.discarded_offsets_px,
            gross_uncovered_px: self.gross_uncovered_px + o.gross_uncovered_px,
            gross_covered_px: self.gross_covered_px + o.gross_covered_px,
            merge_in_front_px: self.merge_in_front_px + o.merge_in_front_px,
            merge_behind_px: self.merge_behind_px + o.merge_behind_px,
            merge_hole_px: self.merge_hole_px + o.merge_hole_px,
        }
    }

    /// `px` as a percentage of the measured normals.
    pub fn pct(&self, px: usize) -> f64 {
        100.0 * px as f64 / self.measured_px.max(1) as f64
    }

    /// Measured normals without a per-view surface (cut, dropped or discarded).
    pub fn no_surface_px(&self) -> usize {
        self.cut_proxy_jump_px
            + self.cut_match_break_px
            + self.dropped_region_px
            + self.discarded_offsets_px
    }

    /// Measured normals with a correct per-view surface that the merged mesh loses.
    pub fn merge_lost_px(&self) -> usize {
        self.merge_in_front_px + self.merge_behind_px + self.merge_hole_px
    }
}

/// The inputs of one pass that [`coverage_budget`] traces.
#[cfg(feature = "validation")]
#[cfg_attr(docsrs, doc(cfg(feature = "validation")))]
#[derive(Debug, Clone, Copy)]
pub struct BudgetInputs<'a> {
    /// The pass's proxy depth per camera.
    pub proxies: &'a [DepthMap],
    /// The pass's per-view surfaces.
    pub views: &'a ViewSurfaces,
    /// The integration's parameters of the pass (its proxy-jump threshold).
    pub integration: &'a IntegrationParams,
    /// Reference depth maps (e.g. the studio's true depths, or a scan) that decide which
    /// per-view surfaces are gross errors.
    pub reference: &'a [DepthMap],
}

/// Coverage budget of `mesh`: every measured normal that Table 3.1's coverage
/// ([`table_metrics`]) does not count is assigned to the first stage that lost it — cut from
/// Eq. 3.3 at a proxy jump or a matched discontinuity, dropped with its region, discarded by
/// Eq. 3.4, a per-view surface more than `near_m` from the reference (gross error), or a
/// correct per-view surface that the mesh misses (its first hit in front, behind, or none).
///
/// # Errors
/// [`Error::SizeMismatch`] for counts or image sizes that differ; [`Error::InvalidParam`] for
/// a non-positive `near_m`; errors of the rasteriser (named by camera).
#[cfg(feature = "validation")]
#[cfg_attr(docsrs, doc(cfg(feature = "validation")))]
pub fn coverage_budget(
    cameras: &[Camera],
    normals: &[NormalMap],
    silhouettes: &[Mask],
    inputs: &BudgetInputs<'_>,
    mesh: &TriMesh,
    params: &MetricParams,
) -> Result<CoverageBudget> {
    let n = cameras.len();
    let views = inputs.views;
    check::same_size("normal maps per camera", n, normals.len())?;
    check::same_size("silhouettes per camera", n, silhouettes.len())?;
    check::same_size("proxies per camera", n, inputs.proxies.len())?;
    check::same_size("reference depth maps per camera", n, inputs.reference.len())?;
    check::same_size("per-view surfaces per camera", n, views.surfaces.len())?;
    check::same_size("integrated surfaces per camera", n, views.integrated.len())?;
    check::same_size("matched breaks per camera", n, views.breaks.len())?;
    check::positive("near_m", params.near_m)?;
    let per_camera = (0..n)
        .into_par_iter()
        .map(|c| -> Result<CoverageBudget> {
            let surface = &views.surfaces[c];
            let (sums, covered, hit) = camera_sums(
                &cameras[c],
                &normals[c],
                &silhouettes[c],
                surface,
                mesh,
                params,
            )?;
            let n_px = surface.depth_m.len();
            for (what, len) in [
                ("proxy pixels", inputs.proxies[c].depth_m.len()),
                ("reference pixels", inputs.reference[c].depth_m.len()),
                ("integrated pixels", views.integrated[c].depth_m.len()),
                ("matched break pixels", views.breaks[c].pixel_count()),
            ] {
                check::same_size(what, n_px, len)?;
            }
            let w = surface.width;
            let jumps = depth_jumps(
                &inputs.proxies[c],
                IntegrationParams::jump_threshold_m(inputs.integration.proxy_jump_m, w),
            )?;
            let mut b = CoverageBudget {
                measured_px: sums.measured,
                covered_px: sums.covered,
                ..CoverageBudget::default()
            };
            for (i, &is_covered) in covered.iter().enumerate() {
                let (x, y) = (i as u32 % w, i as u32 / w);
                if !normals[c].valid[i] || !silhouettes[c].get(x, y) {
                    continue;
                }
                let s = surface.depth_m[i];
                let error = (s - inputs.reference[c].depth_m[i]).abs();
                let gross = error.is_nan() || error > params.near_m;
                let class = if views.integrated[c].depth_m[i].is_nan() {
                    if jumps.get(x, y) {
                        &mut b.cut_proxy_jump_px
                    } else if views.breaks[c].get(x, y) {
                        &mut b.cut_match_break_px
                    } else {
                        &mut b.dropped_region_px
                    }
                } else if s.is_nan() {
                    &mut b.discarded_offsets_px
                } else if gross {
                    if is_covered {
                        &mut b.gross_covered_px
                    } else {
                        &mut b.gross_uncovered_px
                    }
                } else if is_covered {
                    continue;
                } else if hit.depth_m[i].is_nan() {
                    &mut b.merge_hole_px
                } else if hit.depth_m[i] < s {
                    &mut b.merge_in_front_px
                } else {
                    &mut b.merge_behind_px
                };
                *class += 1;
            }
            Ok(b)
        })
        .enumerate()
        .map(|(c, r)| r.at(Context::Camera(c)))
        .collect::<Result<Vec<_>>>()?;
    Ok(per_camera
        .into_iter()
        .fold(CoverageBudget::default(), CoverageBudget::add))
}

/// Distances (mm) from a mesh's vertices to a true surface.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SurfaceDistance {
    /// Median, mm.
    pub median_mm: f64,
    /// 95th percentile, mm.
    pub p95_mm: f64,
    /// Vertices measured.
    pub vertices: usize,
    /// Each vertex's distance, mm, in vertex order (for colouring the mesh).
    #[serde(skip)]
    pub per_vertex_mm: Vec<f64>,
}

/// The distance of every vertex of `mesh` to the surface of `truth`: median and 95th
/// percentile, mm.
///
/// # Errors
/// Errors of [`one_sided_distance`] (empty or non-finite meshes).
pub fn surface_distance(mesh: &TriMesh, truth: &TriMesh) -> Result<SurfaceDistance> {
    let d = one_sided_distance(mesh, truth)?;
    let per_vertex_mm: Vec<f64> = d.per_vertex.iter().map(|v| v * 1e3).collect();
    let mut sorted = per_vertex_mm.clone();
    sorted.sort_by(f64::total_cmp);
    let at = |q: f64| sorted[((sorted.len() - 1) as f64 * q).round() as usize];
    Ok(SurfaceDistance {
        median_mm: at(0.5),
        p95_mm: at(0.95),
        vertices: sorted.len(),
        per_vertex_mm,
    })
}

/// How much of a known displacement of a surface (e.g. the studio's wrinkles) a reconstructed
/// mesh keeps ([`displacement_survival`]). Displacements are signed heights along the smooth
/// surface's normal; the figures are over the measured vertices.
#[cfg(feature = "validation")]
#[cfg_attr(docsrs, doc(cfg(feature = "validation")))]
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DisplacementSurvival {
    /// Vertices in the region (with a non-zero displacement asked for).
    pub region_vertices: usize,
    /// Of those, the vertices where the reconstruction was found within reach along the
    /// normal (the figures below are over these).
    pub vertices: usize,
    /// Least-squares slope of the reconstructed height on the true height (with an
    /// intercept): 1 keeps the whole amplitude, 0 none of it.
    pub slope: f64,
    /// Intercept of that fit, mm (the reconstruction's mean offset from the smooth surface).
    pub intercept_mm: f64,
    /// Pearson correlation of the true and reconstructed heights.
    pub correlation: f64,
    /// RMS of the true heights, mm.
    pub true_rms_mm: f64,
    /// RMS of the reconstructed heights about their mean, mm.
    pub reconstructed_rms_mm: f64,
    /// `[true, reconstructed]` height of every measured vertex, mm (for plots).
    #[serde(skip)]
    pub heights_mm: Vec<[f64; 2]>,
}

/// How much of a known surface displacement a reconstruction keeps (beyond the thesis: the
/// wrinkle amplitude that survives).
///
/// `smooth` is the surface without the displacement; `displacement[i]` moves its vertex `i`
/// to the displaced (true) surface; `region[i]` selects the vertices measured. Per selected
/// vertex `p` with unit normal `n` (area-weighted, of `smooth`): the true height is
/// `displacement[i] · n`; the reconstructed height is the signed distance along `±n` from
/// `p` to the nearest hit on `reconstructed` within `reach_m` (vertices without one are left
/// out). The figures are the least-squares slope and intercept of reconstructed on true
/// height, their correlation and RMS amplitudes.
///
/// # Errors
/// Size mismatches of `displacement` and `region` with `smooth`; a non-positive or NaN
/// `reach_m`; [`Error::Empty`] when fewer than 3 vertices are measured or the true heights
/// do not vary; mesh errors (non-finite vertices, empty meshes).
#[cfg(feature = "validation")]
#[cfg_attr(docsrs, doc(cfg(feature = "validation")))]
pub fn displacement_survival(
    smooth: &TriMesh,
    displacement: &[DVec3],
    region: &[bool],
    reconstructed: &TriMesh,
    reach_m: f64,
) -> Result<DisplacementSurvival> {
    let n = smooth.vertices.len();
    check::same_size("displacements", n, displacement.len())?;
    check::same_size("region flags", n, region.len())?;
    check::positive("reach_m", reach_m)?;
    let normals = vertex_normals(smooth, NormalWeighting::Area)?;
    let query = MeshQuery::new(reconstructed)?;
    let selected: Vec<usize> = (0..n).filter(|&i| region[i]).collect();
    let pairs = selected
        .par_iter()
        .map(|&i| -> Result<Option<(f64, f64)>> {
            let (p, nrm) = (smooth.vertices[i], normals[i]);
            if nrm.length_squared() < 0.5 {
                return Ok(None);
            }
            let hit = |d: DVec3| query.cast_ray(Ray::new(p, d), reach_m);
            let up = hit(nrm)?.map(|h| h.t);
            let down = hit(-nrm)?.map(|h| -h.t);
            let h = match (up, down) {
                (Some(a), Some(b)) => Some(if a.abs() <= b.abs() { a } else { b }),
                (a, b) => a.or(b),
            };
            Ok(h.map(|h| (displacement[i].dot(nrm), h)))
        })
        .collect::<Result<Vec<_>>>()?;
    let pairs: Vec<(f64, f64)> = pairs.into_iter().flatten().collect();
    let m = pairs.len() as f64;
    let mean = |f: &dyn Fn(&(f64, f64)) -> f64| pairs.iter().map(f).sum::<f64>() / m;
    let (mx, my) = (mean(&|p| p.0), mean(&|p| p.1));
    let sxx = mean(&|p| (p.0 - mx).powi(2));
    let syy = mean(&|p| (p.1 - my).powi(2));
    let sxy = mean(&|p| (p.0 - mx) * (p.1 - my));
    if pairs.len() < 3 || sxx.is_nan() || sxx <= 0.0 {
        return Err(Error::Empty {
            what: "vertices with a varying displacement and a reconstruction within reach",
        });
    }
    let slope = sxy / sxx;
    Ok(DisplacementSurvival {
        region_vertices: selected.len(),
        vertices: pairs.len(),
        slope,
        intercept_mm: (my - slope * mx) * 1e3,
        correlation: if syy > 0.0 {
            sxy / (sxx * syy).sqrt()
        } else {
            0.0
        },
        true_rms_mm: mean(&|p| p.0 * p.0).sqrt() * 1e3,
        reconstructed_rms_mm: syy.sqrt() * 1e3,
        heights_mm: pairs.iter().map(|p| [p.0 * 1e3, p.1 * 1e3]).collect(),
    })
}

#[cfg(test)]
mod tests;
