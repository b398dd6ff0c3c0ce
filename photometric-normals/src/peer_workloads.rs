//! The documented inputs of the peer benchmarks `bench/peers/tsdf_mc.py` (workload 6a) and
//! `bench/peers/poisson.py` (workload 6b), regenerated bit for bit (the peers' counter-based
//! SplitMix64 is `skin_core::random::SplitMix64`), with their ground truth, so the merge and
//! the hole filling run on exactly the peers' workloads.

use skin_core::camera::{Camera, Intrinsics, RadialDistortion};
use skin_core::math::{DAffine3, DMat3, DVec2, DVec3};
use skin_core::mesh::shapes::uv_sphere;
use skin_core::random::SplitMix64;

use crate::{DepthMap, OrientedSample, Result};

/// Workload 6a's sphere: centre and radius, m.
pub const TSDF_SPHERE: (DVec3, f64) = (DVec3::new(-0.15, 0.0, 0.0), 0.2);
/// Workload 6a's box: centre and half extents, m.
pub const TSDF_BOX: (DVec3, DVec3) = (DVec3::new(0.2, 0.05, 0.0), DVec3::new(0.1, 0.15, 0.12));
/// Workload 6a's voxel size, m (Open3D `voxel 0.004`).
pub const TSDF_VOXEL_M: f64 = 0.004;
/// Workload 6a's truncation distance, m (Open3D `sdf_trunc 0.02`): the ramp is twice this.
pub const TSDF_TRUNC_M: f64 = 0.02;

/// Exact signed distance to workload 6a's scene (sphere ∪ box), m, negative inside.
pub fn tsdf_scene_sdf(p: DVec3) -> f64 {
    let ds = (p - TSDF_SPHERE.0).length() - TSDF_SPHERE.1;
    let q = (p - TSDF_BOX.0).abs() - TSDF_BOX.1;
    let db = q.max(DVec3::ZERO).length() + q.max_element().min(0.0);
    ds.min(db)
}

/// A proxy of workload 6a's scene for hole filling, like a visual hull: the sphere and the
/// box grown by `offset_m`, sampled about every 2.5 mm with outward normals and `weight`
/// (0.01 in the thesis), keeping only samples at least `offset_m / 2` outside the scene.
///
/// # Errors
/// Errors of the sphere mesh (none for `offset_m ≥ 0`).
pub fn tsdf_proxy_samples(offset_m: f64, weight: f64) -> Result<Vec<OrientedSample>> {
    let sphere = uv_sphere(TSDF_SPHERE.0, TSDF_SPHERE.1 + offset_m, 120, 240)?;
    let mut out = OrientedSample::from_mesh(&sphere, weight)?;
    let half = TSDF_BOX.1 + DVec3::splat(offset_m);
    let step = 0.0025;
    for axis in 0..3 {
        for side in [-1.0, 1.0] {
            let mut normal = DVec3::ZERO;
            normal[axis] = side;
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            let (nu, nv) = ((half[u] / step) as i32, (half[v] / step) as i32);
            for i in -nu..=nu {
                for j in -nv..=nv {
                    let mut p = TSDF_BOX.0 + normal * half[axis];
                    p[u] += f64::from(i) * step;
                    p[v] += f64::from(j) * step;
                    out.push(OrientedSample {
                        position: p,
                        normal,
                        weight,
                    });
                }
            }
        }
    }
    out.retain(|s| tsdf_scene_sdf(s.position) > 0.5 * offset_m);
    Ok(out)
}

/// Nearest hit (distance along the unit ray) of a ray with workload 6a's scene.
fn scene_hit(o: DVec3, d: DVec3) -> Option<f64> {
    let mut best = f64::INFINITY;
    let oc = o - TSDF_SPHERE.0;
    let b = oc.dot(d);
    let disc = b * b - (oc.length_squared() - TSDF_SPHERE.1 * TSDF_SPHERE.1);
    if disc >= 0.0 {
        let t = -b - disc.sqrt();
        if t > 0.0 {
            best = t;
        }
    }
    let inv = d.recip();
    let t1 = (TSDF_BOX.0 - TSDF_BOX.1 - o) * inv;
    let t2 = (TSDF_BOX.0 + TSDF_BOX.1 - o) * inv;
    let tmin = t1.min(t2).max_element();
    let tmax = t1.max(t2).min_element();
    if tmax >= tmin && tmin > 0.0 {
        best = best.min(tmin);
    }
    best.is_finite().then_some(best)
}

/// Workload 6a's 8 cameras (eye `(1.2 cos 2πk/8, 1.2 sin 2πk/8, 0.4)` looking at the origin,
/// world z up, `f = 500 W / 512`, centre `(W − 1)/2`) and their exact depth maps (distance
/// along each pixel's ray; the peer feeds Open3D the same hits as camera z), `size × size`.
///
/// # Errors
/// Errors of the camera and depth-map constructors (none for `size ≥ 1`).
pub fn tsdf_views(size: u32) -> Result<Vec<(Camera, DepthMap)>> {
    let w = f64::from(size);
    let f = 500.0 * w / 512.0;
    let c = (w - 1.0) / 2.0;
    let k = Intrinsics::new(f, f, c, c, size, size)?;
    let up = DVec3::Z;
    (0..8)
        .map(|i| {
            let th = std::f64::consts::TAU * f64::from(i) / 8.0;
            let eye = DVec3::new(1.2 * th.cos(), 1.2 * th.sin(), 0.4);
            let fwd = -eye.normalize();
            let xc = fwd.cross(up).normalize();
            let yc = fwd.cross(xc);
            let r = DMat3::from_cols(xc, yc, fwd).transpose();
            let cam = Camera::from_camera_from_world(
                k,
                RadialDistortion::NONE,
                DAffine3::from_mat3_translation(r, -(r * eye)),
            )?;
            let mut depth = Vec::with_capacity((size * size) as usize);
            for v in 0..size {
                for u in 0..size {
                    let ray = cam.ray(DVec2::new(f64::from(u), f64::from(v)))?;
                    depth.push(scene_hit(ray.origin, ray.direction).unwrap_or(f64::NAN));
                }
            }
            Ok((cam, DepthMap::new(size, size, depth)?))
        })
        .collect()
}

/// Workload 6b's radius of the sphere and its cut (samples only where `z ≤ 0.3`), m.
pub const POISSON_SPHERE: (f64, f64) = (0.4, 0.3);

/// Workload 6b's `n` oriented samples: uniform by area on the sphere of radius 0.4 at the
/// origin without the cap `z > 0.3` (`z = −0.4 + 0.7 U(80)`, `φ = 2π U(81)`), outward
/// normals, all with `weight`.
pub fn poisson_samples(n: usize, weight: f64) -> Vec<OrientedSample> {
    let (r, cut) = POISSON_SPHERE;
    let zs = SplitMix64::new(80).uniform(n);
    let phis = SplitMix64::new(81).uniform(n);
    zs.iter()
        .zip(&phis)
        .map(|(&u, &v)| {
            let z = -r + (r + cut) * u;
            let phi = std::f64::consts::TAU * v;
            let rho = (r * r - z * z).sqrt();
            let p = DVec3::new(rho * phi.cos(), rho * phi.sin(), z);
            OrientedSample {
                position: p,
                normal: p / r,
                weight,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn views_see_the_scene_surface() {
        let views = tsdf_views(64).unwrap();
        assert_eq!(views.len(), 8);
        for (cam, map) in &views {
            assert!(map.valid_count() > 300);
            for (i, d) in map.depth_m.iter().enumerate().filter(|(_, d)| !d.is_nan()) {
                let (x, y) = ((i % 64) as u32, (i / 64) as u32);
                let p = map.point(cam, x, y).unwrap().unwrap();
                assert!(tsdf_scene_sdf(p).abs() < 1e-9, "{d}");
            }
        }
        // The sphere's centre is in front of camera 0's image centre row.
        let px = views[0].0.project(DVec3::ZERO).unwrap();
        assert!((px.x - 31.5).abs() < 1e-9 && (px.y - 31.5).abs() < 1e-9);
    }

    #[test]
    fn poisson_samples_are_on_the_cut_sphere() {
        let s = poisson_samples(1000, 1.0);
        assert!(s
            .iter()
            .all(|s| (s.position.length() - 0.4).abs() < 1e-12 && s.position.z <= 0.3));
        let first = SplitMix64::new(80).uniform_at(0);
        assert!((s[0].position.z - (-0.4 + 0.7 * first)).abs() < 1e-15);
    }
}
