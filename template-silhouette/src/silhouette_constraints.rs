//! Silhouette constraints of shape estimation (Vlasic 2010 §2.4.2, Algorithm 1 line 10;
//! Figure 2-6).
//!
//! Every ray from a camera centre through a contour point is tangent to the subject. The
//! contours are sampled every 10 pixels ([`contour_rays`]); for each sampled ray one mesh
//! point is chosen to be pulled onto it ([`silhouette_constraints`]):
//!
//! - the ray misses the current shape: the mesh point closest to the ray;
//! - the ray passes through the shape: the point of the ray deepest inside the shape is found
//!   and the mesh point closest to it is used.
//!
//! Distances are measured in a metric that scales by 0.25 the component along the ray's 3D
//! silhouette normal — the normal of the plane through the ray and the contour tangent,
//! oriented outward — which prefers points in the direction the silhouette faces and so
//! keeps the surface from folding (Figure 2-6, bottom). Points farther than 5 cm from the ray
//! in that metric, or whose mesh normal differs from the silhouette normal by more than 90°,
//! are not constrained. The target is the point of the ray nearest the chosen mesh point.
//!
//! Choices where the thesis is silent (each documented on its field of
//! [`SilhouetteParams`]): candidates are mesh *vertices* (the 10k-vertex template's edges,
//! about 1–2 cm, are finer than the contour sampling); the normal test filters candidates
//! before the closest one is chosen, so the back of a thin limb never wins over its front;
//! the deepest point is the best of a fixed number of samples of the inside interval.
//!
//! The candidate search is exact but indexed: per camera centre, the vertices sit in a 2-D
//! grid of normalised image coordinates, and a ray reads only the cells within the distance
//! at which a vertex could still pass the 5 cm test (falling back to all vertices in the one
//! case the bound does not settle); a test checks it finds what the full search finds.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use skin_core::camera::Camera;
use skin_core::image::{extract_contours, ContourParams, Mask};
use skin_core::math::{DVec2, DVec3, Ray};
use skin_core::mesh::{vertex_normals, MeshQuery, NormalWeighting, TriMesh};

use crate::error::{Error, Result};

/// Knobs of the silhouette constraints (§2.4.2).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SilhouetteParams {
    /// Contour sampling step, pixels. §2.4.2: "we sample the contours (every 10 pixels)".
    /// Default: 10.
    pub sample_step_px: f64,
    /// Scale of the distance component along the silhouette normal. §2.4.2. Default:
    /// [`Self::DEFAULT_NORMAL_SCALE`] = 0.25.
    pub normal_scale: f64,
    /// Largest scaled distance from the ray of a constrained point, m. §2.4.2: 5 cm.
    /// Default: [`Self::DEFAULT_MAX_DISTANCE_M`] = 0.05.
    pub max_distance_m: f64,
    /// Largest angle between the mesh normal at a candidate and the silhouette normal,
    /// degrees. §2.4.2: 90°. Default: [`Self::DEFAULT_MAX_NORMAL_ANGLE_DEG`] = 90.
    pub max_normal_angle_deg: f64,
    /// Samples of the inside interval of a ray that passes through the shape, searched for
    /// the deepest point (the thesis does not say how it finds it; 12 samples resolve a
    /// 12 cm limb to 1 cm). Default: [`Self::DEFAULT_DEPTH_SAMPLES`] = 12.
    pub depth_samples: usize,
}

impl Default for SilhouetteParams {
    fn default() -> Self {
        SilhouetteParams {
            sample_step_px: ContourParams::DEFAULT_SAMPLE_STEP_PX,
            normal_scale: Self::DEFAULT_NORMAL_SCALE,
            max_distance_m: Self::DEFAULT_MAX_DISTANCE_M,
            max_normal_angle_deg: Self::DEFAULT_MAX_NORMAL_ANGLE_DEG,
            depth_samples: Self::DEFAULT_DEPTH_SAMPLES,
        }
    }
}

impl SilhouetteParams {
    /// Default scale of the distance component along the silhouette normal (§2.4.2: "we scale
    /// the distance metric by 0.25 in this direction").
    pub const DEFAULT_NORMAL_SCALE: f64 = 0.25;

    /// Default largest scaled distance of a constrained point from its ray, m (§2.4.2: 5 cm).
    pub const DEFAULT_MAX_DISTANCE_M: f64 = 0.05;

    /// Default largest angle between mesh and silhouette normals, degrees (§2.4.2: 90°).
    pub const DEFAULT_MAX_NORMAL_ANGLE_DEG: f64 = 90.0;

    /// Default number of samples of a ray's inside interval searched for the deepest point.
    pub const DEFAULT_DEPTH_SAMPLES: usize = 12;

    /// Sets [`Self::sample_step_px`].
    pub fn with_sample_step_px(mut self, px: f64) -> Self {
        self.sample_step_px = px;
        self
    }
    /// Sets [`Self::max_distance_m`].
    pub fn with_max_distance_m(mut self, m: f64) -> Self {
        self.max_distance_m = m;
        self
    }

    fn validate(&self) -> Result<()> {
        skin_core::check::positive("sample_step_px", self.sample_step_px)?;
        skin_core::check::positive("normal_scale", self.normal_scale)?;
        skin_core::check::positive("max_distance_m", self.max_distance_m)?;
        skin_core::check::in_range(
            "max_normal_angle_deg",
            self.max_normal_angle_deg,
            0.0..=180.0,
        )?;
        skin_core::check::nonzero("depth_samples", self.depth_samples)?;
        Ok(())
    }
}

/// A sampled contour ray: tangent to the subject, with its outward silhouette normal.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ContourRay {
    /// Camera centre, world m.
    pub origin: DVec3,
    /// Unit direction through the contour point.
    pub direction: DVec3,
    /// Outward unit normal of the plane through the ray and the contour tangent (the
    /// silhouette normal in 3D), perpendicular to `direction`.
    pub normal: DVec3,
}

/// The contour rays of one silhouette, sampled every `params.sample_step_px` pixels of arc
/// length (§2.4.2).
///
/// # Errors
/// [`Error::SizeMismatch`] if the mask is not the camera's image size; [`Error::Empty`] for a
/// silhouette without foreground (a camera that does not see the subject has no tangent ray
/// to give: drop it from the frame); errors of the camera's rays.
pub fn contour_rays(
    camera: &Camera,
    mask: &Mask,
    params: &SilhouetteParams,
) -> Result<Vec<ContourRay>> {
    params.validate()?;
    let k = &camera.intrinsics;
    if mask.dimensions() != (k.width, k.height) {
        return Err(Error::SizeMismatch {
            what: "silhouette pixels vs camera image pixels (a mask of the camera's image size)",
            expected: k.width as usize * k.height as usize,
            got: mask.pixel_count(),
        });
    }
    if mask.is_empty() {
        return Err(Error::Empty {
            what: "silhouette (no foreground pixel: the performer is out of view, or the \
                   background subtraction failed)",
        });
    }
    let contours = extract_contours(
        mask,
        &ContourParams::default().with_sample_step_px(params.sample_step_px),
    )?;
    let mut out = Vec::new();
    for c in &contours {
        for (p, n) in c.points.iter().zip(&c.normals) {
            let tangent = DVec2::new(-n.y, n.x);
            let u = camera.ray(*p)?.direction;
            let ut = camera.ray(*p + tangent)?.direction;
            let un = camera.ray(*p + *n)?.direction;
            let Some(mut normal) = u.cross(ut).try_normalize() else {
                continue;
            };
            if normal.dot(un - u) < 0.0 {
                normal = -normal;
            }
            out.push(ContourRay {
                origin: camera.centre(),
                direction: u,
                normal,
            });
        }
    }
    Ok(out)
}

/// Which case of §2.4.2 produced a constraint (Figure 2-6, top).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum RayCase {
    /// The ray misses the shape: the mesh point closest to the ray.
    Outside,
    /// The ray passes through the shape: the mesh point closest to the ray's deepest point.
    Inside,
}

/// A vertex pulled onto a contour ray (one row of `C_SIL`, `P_SIL` in Eq. 2.2).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SilhouetteConstraint {
    /// Index of the ray in the slice given to [`silhouette_constraints`].
    pub ray: usize,
    /// The constrained vertex.
    pub vertex: usize,
    /// Its target: the point of the ray nearest the vertex, world m.
    pub target: DVec3,
    /// Scaled distance from the vertex to the ray, m.
    pub scaled_distance_m: f64,
    /// Which case chose the vertex.
    pub case: RayCase,
}

/// For each contour ray, the vertex of `mesh` to pull onto it, or none (§2.4.2). `mesh` is
/// the current shape estimate (closed, outward-oriented). Rays are handled in parallel; the
/// result is in ray order and the same for any thread count.
///
/// # Errors
/// [`Error::InvalidParam`] for bad params; errors of the mesh's normals and BVH (invalid
/// mesh, non-finite vertices).
pub fn silhouette_constraints(
    mesh: &TriMesh,
    rays: &[ContourRay],
    params: &SilhouetteParams,
) -> Result<Vec<SilhouetteConstraint>> {
    params.validate()?;
    let normals = vertex_normals(mesh, NormalWeighting::Angle)?;
    let query = MeshQuery::new(mesh)?;
    let min_cos = params.max_normal_angle_deg.to_radians().cos();
    // A vertex that can be accepted is within this distance of its ray (scaled by
    // `normal_scale` along the normal, 1 across): the radius of the candidate search.
    let reach =
        params.max_distance_m * (1.0 / (params.normal_scale * params.normal_scale) + 1.0).sqrt();
    // Rays of one camera share its centre: one index of the vertices per centre.
    let mut origins: Vec<DVec3> = Vec::new();
    for r in rays {
        if !origins.contains(&r.origin) {
            origins.push(r.origin);
        }
    }
    let views: Vec<Option<ViewIndex>> = origins
        .iter()
        .map(|o| {
            let dirs: Vec<DVec3> = rays
                .iter()
                .filter(|r| r.origin == *o)
                .map(|r| r.direction)
                .collect();
            ViewIndex::new(&mesh.vertices, *o, &dirs, reach)
        })
        .collect();
    let search = Search {
        mesh,
        normals: &normals,
        query: &query,
        params,
        min_cos,
        reach,
    };
    let found = rays
        .par_iter()
        .enumerate()
        .map(|(r, ray)| {
            let view = origins
                .iter()
                .position(|o| *o == ray.origin)
                .and_then(|v| views[v].as_ref());
            search.constrain(r, ray, view)
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(found.into_iter().flatten().collect())
}

/// The scaled metric of §2.4.2 of an offset `e` (perpendicular to the ray or from the
/// deepest point), squared.
fn scaled_sq(e: DVec3, normal: DVec3, scale: f64) -> f64 {
    let en = e.dot(normal);
    (e - en * normal).length_squared() + (scale * en) * (scale * en)
}

/// The vertices seen from one camera centre in a 2-D grid of normalised coordinates
/// `(p·e₁/z, p·e₂/z)`, `z = p·w`, `w` the mean ray direction. For a ray of normalised
/// direction `m`, a point at depth `z` within distance `R` of the ray has `|n − m| ≤
/// R |(m, 1)| / z` (the first two components of `(n, 1) × (m, 1)` bound its length), so the
/// cells around `m` of size `R max|(m, 1)| / z_min` hold every vertex that can be accepted.
struct ViewIndex {
    origin: DVec3,
    basis: [DVec3; 3],
    cell: f64,
    lo: DVec2,
    dims: [usize; 2],
    cells: Vec<Vec<u32>>,
    /// Vertices at depth below `NEAR_M` (or behind): always candidates.
    near: Vec<u32>,
}

/// Depth below which a vertex is not put in the grid, m.
const NEAR_M: f64 = 0.05;
/// Largest grid side, cells (a finer grid is not worth its memory).
const MAX_GRID_SIDE: usize = 4096;
/// Rays closer than this cosine to the grid's plane are searched by brute force.
const MIN_RAY_COS: f64 = 0.1;

impl ViewIndex {
    fn new(vertices: &[DVec3], origin: DVec3, dirs: &[DVec3], reach: f64) -> Option<Self> {
        let w = dirs.iter().copied().sum::<DVec3>().try_normalize()?;
        let e1 = w.any_orthonormal_vector();
        let basis = [e1, w.cross(e1), w];
        let mut near = Vec::new();
        let mut pts = Vec::with_capacity(vertices.len());
        let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
        let mut z_min = f64::INFINITY;
        for (i, x) in vertices.iter().enumerate() {
            let p = *x - origin;
            let z = p.dot(w);
            if z <= NEAR_M {
                near.push(i as u32);
                continue;
            }
            let n = DVec2::new(p.dot(basis[0]) / z, p.dot(basis[1]) / z);
            lo = lo.min(n);
            hi = hi.max(n);
            z_min = z_min.min(z);
            pts.push((i as u32, n));
        }
        let mut widest: f64 = 1.0;
        for d in dirs {
            let c = d.dot(w);
            if c < MIN_RAY_COS {
                return None;
            }
            widest = widest
                .max(DVec2::new(d.dot(basis[0]) / c, d.dot(basis[1]) / c).length_squared() + 1.0);
        }
        if pts.is_empty() {
            return None;
        }
        let cell = reach * widest.sqrt() / z_min;
        let span = (hi - lo) / cell;
        let dims = [span.x as usize + 1, span.y as usize + 1];
        if dims[0] > MAX_GRID_SIDE || dims[1] > MAX_GRID_SIDE {
            return None;
        }
        let mut cells = vec![Vec::new(); dims[0] * dims[1]];
        for (i, n) in pts {
            let c = ((n - lo) / cell).as_uvec2();
            cells[c.y as usize * dims[0] + c.x as usize].push(i);
        }
        Some(ViewIndex {
            origin,
            basis,
            cell,
            lo,
            dims,
            cells,
            near,
        })
    }

    /// Candidate vertices for a ray from this view's centre (`None`: search all).
    fn candidates(&self, u: DVec3) -> Option<Vec<u32>> {
        let c = u.dot(self.basis[2]);
        if c < MIN_RAY_COS {
            return None;
        }
        let m = DVec2::new(u.dot(self.basis[0]) / c, u.dot(self.basis[1]) / c);
        let g = ((m - self.lo) / self.cell).floor();
        let mut out = self.near.clone();
        for dy in -1..=1 {
            for dx in -1..=1 {
                let (x, y) = (g.x as i64 + dx, g.y as i64 + dy);
                if x >= 0 && y >= 0 && (x as usize) < self.dims[0] && (y as usize) < self.dims[1] {
                    out.extend_from_slice(&self.cells[y as usize * self.dims[0] + x as usize]);
                }
            }
        }
        Some(out)
    }
}

/// What every ray's search reads.
struct Search<'a> {
    mesh: &'a TriMesh,
    normals: &'a [DVec3],
    query: &'a MeshQuery,
    params: &'a SilhouetteParams,
    min_cos: f64,
    reach: f64,
}

impl Search<'_> {
    /// The best vertex by `metric` among `candidates` (all vertices for `None`), ties to the
    /// lowest index so the result does not depend on the order of the candidates.
    fn best(
        &self,
        ray: &ContourRay,
        candidates: Option<&[u32]>,
        metric: &dyn Fn(DVec3) -> f64,
    ) -> Option<(f64, usize)> {
        let (o, u, n) = (ray.origin, ray.direction, ray.normal);
        let mut best: Option<(f64, usize)> = None;
        let mut consider = |i: usize| {
            let (x, nx) = (self.mesh.vertices[i], self.normals[i]);
            if nx.dot(n) < self.min_cos || (x - o).dot(u) <= 0.0 {
                return;
            }
            let m = metric(x);
            if best.is_none_or(|b| m < b.0 || (m == b.0 && i < b.1)) {
                best = Some((m, i));
            }
        };
        match candidates {
            Some(c) => c.iter().for_each(|&i| consider(i as usize)),
            None => (0..self.mesh.vertices.len()).for_each(consider),
        }
        best
    }

    fn constrain(
        &self,
        r: usize,
        ray: &ContourRay,
        view: Option<&ViewIndex>,
    ) -> Result<Option<SilhouetteConstraint>> {
        let params = self.params;
        let (o, u, n) = (ray.origin, ray.direction, ray.normal);
        let perp = |x: DVec3| {
            let rel = x - o;
            rel - rel.dot(u) * u
        };
        let candidates = view.filter(|v| v.origin == o).and_then(|v| v.candidates(u));
        let deepest = deepest_point(self.query, Ray::new(o, u), params.depth_samples)?;
        let best = match deepest {
            None => {
                // Exact: a vertex the 5 cm test accepts lies within `reach` of the ray.
                let metric = |x: DVec3| scaled_sq(perp(x), n, params.normal_scale);
                let best = self.best(ray, candidates.as_deref(), &metric);
                best.map(|b| (RayCase::Outside, b.1))
            }
            Some(q) => {
                // A vertex farther than `reach` from the ray is farther than
                // `normal_scale · reach` from q in the metric; when the candidates' best is
                // not nearer than that, search every vertex.
                let metric = |x: DVec3| scaled_sq(x - q, n, params.normal_scale);
                let bound = params.normal_scale * self.reach;
                let best = match self.best(ray, candidates.as_deref(), &metric) {
                    Some(b) if b.0 < bound * bound => Some(b),
                    _ if candidates.is_some() => self.best(ray, None, &metric),
                    b => b,
                };
                best.map(|b| (RayCase::Inside, b.1))
            }
        };
        let Some((case, vertex)) = best else {
            return Ok(None);
        };
        let x = self.mesh.vertices[vertex];
        let scaled = scaled_sq(perp(x), n, params.normal_scale).sqrt();
        if scaled > params.max_distance_m {
            return Ok(None);
        }
        Ok(Some(SilhouetteConstraint {
            ray: r,
            vertex,
            target: o + (x - o).dot(u) * u,
            scaled_distance_m: scaled,
            case,
        }))
    }
}

/// The point of `ray` deepest inside the mesh on its first inside interval (the sample of
/// the interval farthest from the surface), or `None` if the ray misses.
fn deepest_point(query: &MeshQuery, ray: Ray, samples: usize) -> Result<Option<DVec3>> {
    /// Step past a hit before casting again, m.
    const PAST_HIT_M: f64 = 1e-7;
    let Some(entry) = query.cast_ray(ray, f64::INFINITY)? else {
        return Ok(None);
    };
    let t_in = entry.t;
    let again = Ray::new(ray.at(t_in + PAST_HIT_M), ray.direction);
    let Some(exit) = query.cast_ray(again, f64::INFINITY)? else {
        // Grazing an open edge: no inside interval.
        return Ok(None);
    };
    let t_out = t_in + PAST_HIT_M + exit.t;
    let mut best = (f64::NEG_INFINITY, ray.at(0.5 * (t_in + t_out)));
    for s in 0..samples {
        let t = t_in + (t_out - t_in) * (s as f64 + 0.5) / samples as f64;
        let p = ray.at(t);
        let d = query.closest_point(p)?.distance;
        if d > best.0 {
            best = (d, p);
        }
    }
    Ok(Some(best.1))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::visual_hull::tests::{ring, sphere_mask};
    use skin_core::mesh::shapes;

    /// An icosphere with edges of about 1 cm at r = 0.3 m.
    fn sphere(c: DVec3, r: f64) -> TriMesh {
        let mut m = shapes::icosphere(4).unwrap();
        for v in &mut m.vertices {
            *v = c + r * *v;
        }
        m
    }

    const SPHERE_CENTRE: DVec3 = DVec3::new(0.0, 1.0, 0.0);
    const SPHERE_RADIUS: f64 = 0.3;

    /// The contour rays of a 0.3 m sphere seen by four cameras at 320 × 240.
    fn sphere_rays() -> Vec<ContourRay> {
        ring(4, 320, 240)
            .iter()
            .flat_map(|cam| {
                let mask = sphere_mask(cam, SPHERE_CENTRE, SPHERE_RADIUS);
                contour_rays(cam, &mask, &Default::default()).unwrap()
            })
            .collect()
    }

    #[test]
    fn contour_rays_are_tangent_to_the_sphere_with_outward_normals() {
        let (c, r) = (DVec3::new(0.0, 1.0, 0.0), 0.3);
        let cams = ring(1, 320, 240);
        let rays =
            contour_rays(&cams[0], &sphere_mask(&cams[0], c, r), &Default::default()).unwrap();
        // Perimeter of a ~30 px radius disc / 10 px.
        assert!(rays.len() > 10 && rays.len() < 40, "{}", rays.len());
        let pixel_m = 3.0 / cams[0].intrinsics.fx;
        for ray in &rays {
            let rel = c - ray.origin;
            let d = (rel - rel.dot(ray.direction) * ray.direction).length();
            assert!((d - r).abs() < pixel_m, "ray at {d} m from the centre");
            // The outward normal points away from the centre.
            assert!(ray.normal.dot(-rel) > 0.0);
            assert!(ray.normal.dot(ray.direction).abs() < 1e-9);
        }
    }

    #[test]
    fn too_small_and_too_large_shapes_are_pulled_to_the_rays() {
        let (c, r) = (SPHERE_CENTRE, SPHERE_RADIUS);
        let rays = sphere_rays();
        for (radius, case) in [(0.27, RayCase::Outside), (0.33, RayCase::Inside)] {
            let mesh = sphere(c, radius);
            let cons = silhouette_constraints(&mesh, &rays, &Default::default()).unwrap();
            assert!(
                cons.len() > rays.len() * 3 / 4,
                "{} of {}",
                cons.len(),
                rays.len()
            );
            for k in &cons {
                assert_eq!(k.case, case);
                // The vertex is about |radius − r| from its ray and its target is on the
                // true sphere's tangent ray, so the target is about r from the centre.
                let dist = (k.target - c).length();
                // The metric leaves the offset along the ray free, so the target may sit a
                // few centimetres along the tangent ray (farther from the centre).
                assert!(dist > r - 0.01 && dist < r + 0.02, "target at {dist}");
                assert!(k.scaled_distance_m <= 0.05);
                // The pull is along the outward silhouette normal: inward for a too small
                // shape, outward for a too large one, by about |radius − r| = 3 cm.
                let pull = (k.target - mesh.vertices[k.vertex]).dot(rays[k.ray].normal);
                let expected = if case == RayCase::Outside {
                    0.03
                } else {
                    -0.03
                };
                assert!((pull - expected).abs() < 0.02, "pull {pull} vs {expected}");
            }
        }
        // 15 cm inside is 3.75 cm in the scaled metric: still pulled; 22 cm (5.5 cm scaled)
        // is beyond the 5 cm limit: no constraint.
        let cons = silhouette_constraints(&sphere(c, 0.15), &rays, &Default::default()).unwrap();
        assert!(cons.len() > rays.len() / 2);
        let cons = silhouette_constraints(&sphere(c, 0.08), &rays, &Default::default()).unwrap();
        assert!(cons.is_empty(), "{}", cons.len());
    }

    #[test]
    fn the_candidate_index_finds_what_the_full_search_finds() {
        let c = SPHERE_CENTRE;
        let rays = sphere_rays();
        let params = SilhouetteParams::default();
        for radius in [0.2, 0.27, 0.33] {
            // An off-centre sphere, so rays of every case and distance occur.
            let mesh = sphere(c + DVec3::new(0.05, -0.03, 0.02), radius);
            let indexed = silhouette_constraints(&mesh, &rays, &params).unwrap();
            let normals = vertex_normals(&mesh, NormalWeighting::Angle).unwrap();
            let query = MeshQuery::new(&mesh).unwrap();
            let search = Search {
                mesh: &mesh,
                normals: &normals,
                query: &query,
                params: &params,
                min_cos: 0.0,
                reach: 0.05 * (16.0f64 + 1.0).sqrt(),
            };
            let full: Vec<SilhouetteConstraint> = rays
                .iter()
                .enumerate()
                .filter_map(|(i, ray)| search.constrain(i, ray, None).unwrap())
                .collect();
            assert!(!full.is_empty());
            assert_eq!(indexed, full, "radius {radius}");
        }
    }

    #[test]
    fn bad_inputs_are_clear_errors() {
        let cams = ring(1, 64, 48);
        let e = contour_rays(&cams[0], &Mask::new(64, 48), &Default::default()).unwrap_err();
        assert!(matches!(e, Error::Empty { .. }), "{e}");
        let e = contour_rays(&cams[0], &Mask::new(60, 48), &Default::default()).unwrap_err();
        assert!(matches!(e, Error::SizeMismatch { .. }), "{e}");
        let p = SilhouetteParams::default().with_sample_step_px(0.0);
        let m = sphere_mask(&cams[0], DVec3::new(0.0, 1.0, 0.0), 0.3);
        assert!(contour_rays(&cams[0], &m, &p).is_err());
        let mut bad = sphere(DVec3::ZERO, 1.0);
        bad.vertices[0] = DVec3::NAN;
        assert!(silhouette_constraints(&bad, &[], &Default::default()).is_err());
    }
}
