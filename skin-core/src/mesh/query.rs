//! BVH-accelerated closest-point and ray queries on a triangle mesh.
//!
//! Closest points give the correspondences of Vlasic's template molding (thesis §2.4: each
//! template vertex is pulled toward the nearest visual-hull surface point) and the mesh
//! distance metrics of [`crate::mesh::metrics`]; ray casts give visibility and the depth
//! observations of the synthetic studio. Both run on `parry3d-f64`'s triangle mesh with its
//! bounding-volume hierarchy; a [`MeshQuery`] is built once per mesh state (one frame) in
//! O(F log F) and answers each query in roughly O(log F).
//!
//! **Degenerate triangles** (see [`crate::mesh::triangle_normal`]) are left out of the
//! hierarchy: they have no normal, no interior and no well-defined barycentric coordinates.
//! Where they are embedded in a surface their edges belong to neighbouring faces, so closest
//! points are unchanged; an isolated degenerate face is invisible to the queries.
//!
//! **Signed distance** uses the angle-weighted pseudo-normal at the closest feature (Bærentzen
//! & Aanæs 2005, as `parry`'s `ORIENTED` flag computes it). It is the true inside/outside test
//! only for a closed, consistently outward-oriented mesh; on an open mesh it tells on which side
//! of the nearby surface the point lies.

use crate::math::{DVec3, Ray};
use crate::mesh::normals::triangle_normal;
use crate::mesh::surface_point::{closest_point_on_triangle, SurfacePoint};
use crate::mesh::TriMesh;
use crate::{Error, Result};
use parry3d_f64::query::{PointQueryWithLocation, Ray as ParryRay, RayCast};
use parry3d_f64::shape::{TriMesh as ParryTriMesh, TriMeshFlags};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// The closest surface point to a query point.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ClosestPoint {
    /// The closest point as a face and barycentric weights (in `[0, 1]`, summing to one).
    pub point: SurfacePoint,
    /// Its position (mesh units and frame).
    pub position: DVec3,
    /// Euclidean distance from the query point (≥ 0).
    pub distance: f64,
    /// `distance`, negated when the query point is inside (behind the surface; see the module
    /// docs for when this is meaningful).
    pub signed_distance: f64,
}

/// The first intersection of a ray with the mesh.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RayHit {
    /// Distance from the ray origin along the normalised direction.
    pub t: f64,
    /// The hit as a face and barycentric weights.
    pub point: SurfacePoint,
    /// The hit position.
    pub position: DVec3,
    /// Unit geometric normal of the hit face, as the face is oriented (counter-clockwise
    /// seen from the side it points to) — not flipped toward the ray.
    pub normal: DVec3,
    /// `true` when the ray hits the side the normal points to (`direction · normal < 0`).
    pub front_face: bool,
}

/// A triangle mesh prepared for closest-point and ray queries (one mesh state; rebuild when
/// the vertices move).
#[derive(Clone)]
pub struct MeshQuery {
    shape: ParryTriMesh,
    /// `face_map[t]` is the mesh face of parry triangle `t`.
    face_map: Vec<u32>,
    /// The mesh faces (for mapping back and triangle access).
    faces: Vec<[u32; 3]>,
    vertices: Vec<DVec3>,
}

impl std::fmt::Debug for MeshQuery {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MeshQuery")
            .field("faces", &self.faces.len())
            .field("indexed_faces", &self.face_map.len())
            .field("vertices", &self.vertices.len())
            .finish()
    }
}

fn check_point(p: DVec3, what: &'static str) -> Result<()> {
    if p.is_finite() {
        Ok(())
    } else {
        Err(Error::NonFinite { what })
    }
}

/// Clamps tiny negative weights from rounding and renormalises to sum one.
fn clean_bary(b: [f64; 3]) -> [f64; 3] {
    let c = b.map(|x| x.max(0.0));
    let s: f64 = c.iter().sum();
    if s > 0.0 && s.is_finite() {
        c.map(|x| x / s)
    } else {
        [1.0, 0.0, 0.0]
    }
}

impl MeshQuery {
    /// Builds the hierarchy over the non-degenerate faces of `mesh`.
    ///
    /// # Errors
    /// As [`TriMesh::validate`]; [`Error::Empty`] for a mesh without faces;
    /// [`Error::Degenerate`] when every face is degenerate.
    pub fn new(mesh: &TriMesh) -> Result<Self> {
        mesh.validate()?;
        if mesh.faces.is_empty() {
            return Err(Error::Empty {
                what: "mesh faces (closest-point / ray query)",
            });
        }
        let mut face_map = Vec::with_capacity(mesh.face_count());
        let mut indices = Vec::with_capacity(mesh.face_count());
        for (f, face) in mesh.faces.iter().enumerate() {
            if triangle_normal(mesh.triangle(f)).is_some() {
                face_map.push(f as u32);
                indices.push(*face);
            }
        }
        if indices.is_empty() {
            return Err(Error::Degenerate {
                what: format!(
                    "all {} faces have zero area; nothing to query",
                    mesh.face_count()
                ),
            });
        }
        let shape =
            ParryTriMesh::with_flags(mesh.vertices.clone(), indices, TriMeshFlags::ORIENTED)
                .map_err(|e| Error::Degenerate {
                    what: format!("parry rejected the mesh: {e}"),
                })?;
        Ok(MeshQuery {
            shape,
            face_map,
            faces: mesh.faces.clone(),
            vertices: mesh.vertices.clone(),
        })
    }

    /// Number of faces of the mesh the query was built from.
    pub fn face_count(&self) -> usize {
        self.faces.len()
    }

    /// Number of faces left out because they are degenerate.
    pub fn degenerate_face_count(&self) -> usize {
        self.faces.len() - self.face_map.len()
    }

    /// Answer for one (checked finite) point within `max_distance`.
    fn closest_unchecked(&self, p: DVec3, max_distance: f64) -> Option<ClosestPoint> {
        let (proj, (tri, location)) = self
            .shape
            .project_local_point_and_get_location_with_max_dist(p, false, max_distance)?;
        let face = self.face_map[tri as usize];
        let corners = self.faces[face as usize].map(|i| self.vertices[i as usize]);
        // `solid = false` never yields `OnSolid`; fall back to the exact projection anyway.
        let bary = match location.barycentric_coordinates() {
            Some(b) if b.iter().all(|x| x.is_finite()) => clean_bary(b),
            _ => closest_point_on_triangle(p, corners).bary,
        };
        let position = corners[0] * bary[0] + corners[1] * bary[1] + corners[2] * bary[2];
        let distance = (p - proj.point).length();
        Some(ClosestPoint {
            point: SurfacePoint { face, bary },
            position,
            distance,
            signed_distance: if proj.is_inside { -distance } else { distance },
        })
    }

    /// The closest surface point to `p`.
    ///
    /// # Errors
    /// [`Error::NonFinite`] when `p` has NaN/inf coordinates.
    pub fn closest_point(&self, p: DVec3) -> Result<ClosestPoint> {
        check_point(p, "closest-point query point")?;
        self.closest_unchecked(p, f64::MAX)
            .ok_or_else(|| Error::NotVisible {
                what: "no closest point found (internal: BVH returned nothing)".into(),
            })
    }

    /// The closest surface point to `p` if it lies within `max_distance`, else `None`.
    /// Faster than [`MeshQuery::closest_point`] when most points are far.
    ///
    /// # Errors
    /// [`Error::NonFinite`] for a non-finite `p`; [`Error::InvalidParam`] for a negative or
    /// NaN `max_distance`.
    pub fn closest_point_within(
        &self,
        p: DVec3,
        max_distance: f64,
    ) -> Result<Option<ClosestPoint>> {
        check_point(p, "closest-point query point")?;
        if max_distance.is_nan() || max_distance < 0.0 {
            return Err(Error::InvalidParam {
                name: "max_distance",
                reason: format!("must be >= 0, got {max_distance}"),
            });
        }
        Ok(self
            .closest_unchecked(p, max_distance)
            .filter(|c| c.distance <= max_distance))
    }

    /// [`MeshQuery::closest_point`] for many points, in parallel; the result is in input order
    /// and identical for any thread count.
    ///
    /// # Errors
    /// [`Error::NonFinite`] if any point is non-finite (checked before any work).
    pub fn closest_points(&self, points: &[DVec3]) -> Result<Vec<ClosestPoint>> {
        if !points.iter().all(|p| p.is_finite()) {
            return Err(Error::NonFinite {
                what: "closest-point query points",
            });
        }
        points.par_iter().map(|&p| self.closest_point(p)).collect()
    }

    /// The first hit of `ray` within distance `max_t` (may be `f64::INFINITY`), or `None`.
    /// Both faces of every triangle are hit; [`RayHit::front_face`] says which.
    ///
    /// # Errors
    /// [`Error::NonFinite`] for a non-finite origin or direction; [`Error::InvalidParam`] for
    /// a zero direction or a negative or NaN `max_t`.
    pub fn cast_ray(&self, ray: Ray, max_t: f64) -> Result<Option<RayHit>> {
        check_point(ray.origin, "ray origin")?;
        check_point(ray.direction, "ray direction")?;
        let dir = ray.direction.try_normalize().ok_or(Error::InvalidParam {
            name: "direction",
            reason: "ray direction must be non-zero".into(),
        })?;
        if max_t.is_nan() || max_t < 0.0 {
            return Err(Error::InvalidParam {
                name: "max_t",
                reason: format!("must be >= 0, got {max_t}"),
            });
        }
        let Some(hit) =
            self.shape
                .cast_local_ray_and_get_normal(&ParryRay::new(ray.origin, dir), max_t, false)
        else {
            return Ok(None);
        };
        let face = self.face_map[hit.subshape as usize];
        let corners = self.faces[face as usize].map(|i| self.vertices[i as usize]);
        let t = hit.time_of_impact;
        let on_ray = ray.origin + t * dir;
        let bary = closest_point_on_triangle(on_ray, corners).bary;
        let position = corners[0] * bary[0] + corners[1] * bary[1] + corners[2] * bary[2];
        // Non-degenerate by construction of the hierarchy.
        let normal = triangle_normal(corners).unwrap_or(hit.normal);
        Ok(Some(RayHit {
            t,
            point: SurfacePoint { face, bary },
            position,
            normal,
            front_face: dir.dot(normal) < 0.0,
        }))
    }

    /// [`MeshQuery::cast_ray`] for many rays, in parallel; results in input order.
    ///
    /// # Errors
    /// As [`MeshQuery::cast_ray`], checked for all rays before any work.
    pub fn cast_rays(&self, rays: &[Ray], max_t: f64) -> Result<Vec<Option<RayHit>>> {
        for r in rays {
            check_point(r.origin, "ray origin")?;
            check_point(r.direction, "ray direction")?;
            if r.direction == DVec3::ZERO {
                return Err(Error::InvalidParam {
                    name: "direction",
                    reason: "ray direction must be non-zero".into(),
                });
            }
        }
        rays.par_iter().map(|&r| self.cast_ray(r, max_t)).collect()
    }

    /// Whether `p` lies inside the mesh, taken as closed and outward-oriented: most of three
    /// rays from `p` in fixed directions first hit the back of a face (a ray leaving a closed
    /// surface meets it from inside). The majority vote makes one ray grazing an edge
    /// harmless; the directions are far from the axes and from each other, so they avoid
    /// the axis-aligned edges and vertices of typical meshes.
    ///
    /// # Errors
    /// [`Error::NonFinite`] for a non-finite `p`.
    pub fn contains(&self, p: DVec3) -> Result<bool> {
        const PROBE_DIRECTIONS: [DVec3; 3] = [
            DVec3::new(0.267_261_2, 0.534_522_5, 0.801_783_7),
            DVec3::new(-0.723_102_3, 0.106_339_8, -0.682_496_1),
            DVec3::new(0.154_303_3, -0.925_820_1, 0.345_032_8),
        ];
        let mut votes = 0;
        for d in PROBE_DIRECTIONS {
            if matches!(self.cast_ray(Ray::new(p, d), f64::INFINITY)?, Some(hit) if !hit.front_face)
            {
                votes += 1;
            }
        }
        Ok(votes >= 2)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Closed latitude/longitude sphere of radius `r` centred at the origin, outward faces.
    pub(crate) fn uv_sphere(r: f64, n_lon: usize, n_lat: usize) -> TriMesh {
        crate::mesh::shapes::uv_sphere(DVec3::ZERO, r, n_lat, n_lon).unwrap()
    }

    fn brute_force(mesh: &TriMesh, p: DVec3) -> f64 {
        (0..mesh.face_count())
            .map(|f| closest_point_on_triangle(p, mesh.triangle(f)).distance)
            .fold(f64::INFINITY, f64::min)
    }

    fn random_point(rng: &mut ChaCha8Rng, scale: f64) -> DVec3 {
        DVec3::new(
            rng.random_range(-scale..scale),
            rng.random_range(-scale..scale),
            rng.random_range(-scale..scale),
        )
    }

    #[test]
    fn sphere_is_closed_and_outward() {
        let m = uv_sphere(1.0, 16, 8);
        assert!(crate::mesh::topology::is_closed(&m).unwrap());
        let n = crate::mesh::normals::face_normals(&m).unwrap();
        for (f, nf) in n.iter().enumerate() {
            assert!(nf.dot(m.triangle(f)[0]) > 0.0);
        }
    }

    #[test]
    fn closest_point_matches_brute_force() {
        let mesh = uv_sphere(1.0, 24, 12);
        let q = MeshQuery::new(&mesh).unwrap();
        let r_min = brute_force(&mesh, DVec3::ZERO);
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let pts: Vec<DVec3> = (0..300).map(|_| random_point(&mut rng, 2.0)).collect();
        let batch = q.closest_points(&pts).unwrap();
        for (p, cp) in pts.iter().zip(&batch) {
            let reference = brute_force(&mesh, *p);
            assert!(
                (cp.distance - reference).abs() < 1e-10,
                "{p}: {} vs {reference}",
                cp.distance
            );
            // The surface point evaluates to the returned position, at the returned distance.
            let eval = cp.point.position(&mesh).unwrap();
            assert!((eval - cp.position).length() < 1e-10);
            assert!(((*p - eval).length() - cp.distance).abs() < 1e-10);
            assert!(cp.point.bary.iter().all(|&b| (0.0..=1.0).contains(&b)));
            // Inside/outside on a closed outward mesh.
            if p.length() < r_min {
                assert!(cp.signed_distance < 0.0);
            } else if p.length() > 1.0 {
                assert!(cp.signed_distance > 0.0);
            }
            assert_eq!(cp.signed_distance.abs(), cp.distance);
            assert_eq!(*cp, q.closest_point(*p).unwrap());
        }
    }

    #[test]
    fn closest_point_within_respects_the_radius() {
        let q = MeshQuery::new(&uv_sphere(1.0, 16, 8)).unwrap();
        let p = DVec3::new(3.0, 0.0, 0.0);
        assert!(q.closest_point_within(p, 1.5).unwrap().is_none());
        let c = q.closest_point_within(p, 2.5).unwrap().unwrap();
        assert!((c.distance - 2.0).abs() < 1e-12);
        assert!(q.closest_point_within(p, -1.0).is_err());
        assert!(q.closest_point_within(p, f64::NAN).is_err());
    }

    /// The polyhedral sphere lies in the shell `r_min ≤ |x| ≤ r`, so the first hit of a ray from
    /// outside lies between its entry into the outer and the inner analytic spheres.
    #[test]
    fn contains_tells_inside_from_outside() {
        let q = MeshQuery::new(&uv_sphere(1.0, 24, 12)).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        for _ in 0..200 {
            let p = random_point(&mut rng, 1.5);
            let r = p.length();
            // Facets lie up to 1 − cos(π/12) ≈ 0.034 inside the sphere.
            if (r - 1.0).abs() > 0.05 {
                assert_eq!(q.contains(p).unwrap(), r < 1.0, "{p}");
            }
        }
        assert!(q.contains(DVec3::ZERO).unwrap());
        assert!(matches!(
            q.contains(DVec3::new(f64::NAN, 0.0, 0.0)),
            Err(Error::NonFinite { .. })
        ));
    }

    #[test]
    fn ray_hits_match_analytic_sphere() {
        let r = 2.0;
        let mesh = uv_sphere(r, 64, 32);
        let q = MeshQuery::new(&mesh).unwrap();
        let r_min = brute_force(&mesh, DVec3::ZERO);
        assert!(r - r_min < 0.01 * r);
        let entry = |o: DVec3, d: DVec3, rad: f64| {
            let b = o.dot(d);
            let c = o.length_squared() - rad * rad;
            -b - (b * b - c).sqrt()
        };
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let mut rays = Vec::new();
        for _ in 0..300 {
            let origin = random_point(&mut rng, 1.0).normalize() * 5.0;
            // Aim at a point well inside the inner sphere, so both spheres are hit.
            let target = random_point(&mut rng, 0.5 * r_min / 3f64.sqrt());
            rays.push(Ray::new(origin, (target - origin) * 3.0));
        }
        let hits = q.cast_rays(&rays, f64::INFINITY).unwrap();
        for (ray, hit) in rays.iter().zip(&hits) {
            let hit = hit.expect("ray aimed at the sphere must hit");
            let d = ray.direction.normalize();
            let (t_out, t_in) = (entry(ray.origin, d, r), entry(ray.origin, d, r_min));
            assert!(
                hit.t >= t_out - 1e-9 && hit.t <= t_in + 1e-9,
                "{} not in [{t_out}, {t_in}]",
                hit.t
            );
            assert!((hit.position - (ray.origin + hit.t * d)).length() < 1e-9);
            assert!((hit.point.position(&mesh).unwrap() - hit.position).length() < 1e-12);
            assert!(hit.front_face);
            assert!(hit.normal.dot(hit.position.normalize()) > 0.99);
        }
        // From the centre: exits through a back face at distance in [r_min, r].
        let h = q
            .cast_ray(Ray::new(DVec3::ZERO, DVec3::new(0.3, -0.2, 0.9)), 10.0)
            .unwrap()
            .unwrap();
        assert!(!h.front_face && h.t >= r_min - 1e-12 && h.t <= r + 1e-12);
        // Misses and range limit.
        assert!(q
            .cast_ray(Ray::new(DVec3::new(5.0, 0.0, 0.0), DVec3::X), 100.0)
            .unwrap()
            .is_none());
        assert!(q
            .cast_ray(Ray::new(DVec3::new(5.0, 0.0, 0.0), DVec3::NEG_X), 2.0)
            .unwrap()
            .is_none());
    }

    #[test]
    fn bad_queries_are_errors() {
        let q = MeshQuery::new(&uv_sphere(1.0, 8, 4)).unwrap();
        assert!(matches!(
            q.closest_point(DVec3::new(f64::NAN, 0.0, 0.0)),
            Err(Error::NonFinite { .. })
        ));
        assert!(matches!(
            q.closest_points(&[DVec3::ZERO, DVec3::splat(f64::INFINITY)]),
            Err(Error::NonFinite { .. })
        ));
        assert!(matches!(
            q.cast_ray(Ray::new(DVec3::ZERO, DVec3::ZERO), 1.0),
            Err(Error::InvalidParam { .. })
        ));
        assert!(matches!(
            q.cast_ray(Ray::new(DVec3::ZERO, DVec3::X), -1.0),
            Err(Error::InvalidParam { .. })
        ));
        assert!(matches!(
            q.cast_ray(Ray::new(DVec3::NAN, DVec3::X), 1.0),
            Err(Error::NonFinite { .. })
        ));
        assert!(q
            .cast_rays(&[Ray::new(DVec3::ZERO, DVec3::ZERO)], 1.0)
            .is_err());
    }

    #[test]
    fn empty_and_degenerate_meshes() {
        assert!(matches!(
            MeshQuery::new(&TriMesh::default()),
            Err(Error::Empty { .. })
        ));
        let flat = TriMesh::new(
            vec![DVec3::ZERO, DVec3::X, DVec3::new(2.0, 0.0, 0.0)],
            vec![[0, 1, 2], [0, 0, 1]],
        )
        .unwrap();
        assert!(matches!(
            MeshQuery::new(&flat),
            Err(Error::Degenerate { .. })
        ));
        let bad = TriMesh {
            vertices: vec![DVec3::ZERO; 2],
            faces: vec![[0, 1, 2]],
        };
        assert!(matches!(
            MeshQuery::new(&bad),
            Err(Error::IndexOutOfRange { .. })
        ));
    }

    #[test]
    fn degenerate_faces_are_skipped_without_changing_answers() {
        let mut mesh = uv_sphere(1.0, 16, 8);
        let clean = MeshQuery::new(&mesh).unwrap();
        // Sliver faces along existing edges and a collapsed face: zero area, embedded.
        let [a, b, _] = mesh.faces[10];
        mesh.faces.push([a, b, a]);
        mesh.faces.push([a, a, a]);
        mesh.faces.insert(0, [b, a, b]);
        let q = MeshQuery::new(&mesh).unwrap();
        assert_eq!(q.degenerate_face_count(), 3);
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for _ in 0..100 {
            let p = random_point(&mut rng, 2.0);
            let (c1, c2) = (clean.closest_point(p).unwrap(), q.closest_point(p).unwrap());
            assert!((c1.distance - c2.distance).abs() < 1e-12);
            assert!(mesh
                .triangle(c2.point.face as usize)
                .iter()
                .all(|v| v.is_finite()));
            assert!(triangle_normal(mesh.triangle(c2.point.face as usize)).is_some());
        }
        let hit = q
            .cast_ray(Ray::new(DVec3::new(0.0, 0.0, 5.0), DVec3::NEG_Z), 10.0)
            .unwrap();
        assert!(hit.is_some());
    }

    #[test]
    fn parallel_batch_equals_serial() {
        let q = MeshQuery::new(&uv_sphere(1.0, 32, 16)).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let pts: Vec<DVec3> = (0..500).map(|_| random_point(&mut rng, 3.0)).collect();
        let serial: Vec<ClosestPoint> = pts.iter().map(|&p| q.closest_point(p).unwrap()).collect();
        assert_eq!(q.closest_points(&pts).unwrap(), serial);
    }
}
