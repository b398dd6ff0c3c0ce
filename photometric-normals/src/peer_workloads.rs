//! The documented inputs of the peer benchmarks `bench/peers/tsdf_mc.py` (workload 6a),
//! `bench/peers/poisson.py` (workload 6b) and `bench/peers/flow.py` (the flow workload),
//! regenerated bit for bit (the peers' counter-based SplitMix64 is
//! `skin_core::random::SplitMix64`), with their ground truth, so the merge, the hole filling
//! and the dense flow run on exactly the peers' workloads.

use std::f64::consts::TAU;

use skin_core::camera::{Camera, Intrinsics, RadialDistortion};
use skin_core::image::GrayF32Image;
use skin_core::math::{DAffine3, DMat3, DVec2, DVec3};
use skin_core::mesh::shapes::uv_sphere;
use skin_core::random::SplitMix64;

use crate::{DepthMap, Error, Flow, OrientedSample, Result};

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

/// The flow workload of `bench/peers/flow.py` (its README, §7): a texture of 64 sines
/// quantised to 8 bits and the same texture warped by a smooth analytic field, at `n`² pixels
/// (the peer's is 1024²; the warp scales with `n`).
#[derive(Debug, Clone)]
pub struct FlowWorkload {
    /// The first image.
    pub first: GrayF32Image,
    /// The second image: the first moved by the warp.
    pub second: GrayF32Image,
    n: u32,
}

/// Sines of the workload's texture.
const FLOW_SINES: usize = 64;

/// The warp at pixel `(x, y)` of an `n`² image, px: where the texture at `(x, y)` of the
/// second image came from is `(x, y) − warp(x, y)`.
fn flow_warp(n: f64, x: f64, y: f64) -> [f64; 2] {
    let s = n / 1024.0;
    let (cx, cy) = (x / n, y / n);
    [
        s * (6.0 * (TAU * 1.5 * cy + 0.3).sin() + 3.0 * (TAU * cx).cos()),
        s * (5.0 * (TAU * 2.0 * cx).cos() - 4.0 * (TAU * (cy + 0.25)).sin()),
    ]
}

impl FlowWorkload {
    /// The workload at `n`² pixels.
    ///
    /// # Errors
    /// [`Error::InvalidParam`] for `n` below 64 (the border the interior EPE leaves out would
    /// cover the image).
    pub fn new(n: u32) -> Result<Self> {
        if n < 64 {
            return Err(Error::InvalidParam {
                name: "n",
                reason: format!("{n} px: give at least 64"),
            });
        }
        let draw = |seed: u64, lo: f64, span: f64| -> Vec<f64> {
            SplitMix64::new(seed)
                .uniform(FLOW_SINES)
                .iter()
                .map(|u| lo + span * u)
                .collect()
        };
        let (rho, th, ph) = (draw(70, 0.01, 0.14), draw(71, 0.0, TAU), draw(72, 0.0, TAU));
        let tex = |x: f64, y: f64| -> f32 {
            let mut t = 0.0;
            for k in 0..FLOW_SINES {
                t += (TAU * (rho[k] * th[k].cos() * x + rho[k] * th[k].sin() * y) + ph[k]).sin();
            }
            ((128.0 + 32.0 * t / (FLOW_SINES as f64 / 2.0).sqrt() + 0.5)
                .floor()
                .clamp(0.0, 255.0)
                / 255.0) as f32
        };
        let nf = f64::from(n);
        let first =
            GrayF32Image::from_fn(n, n, |x, y| image::Luma([tex(f64::from(x), f64::from(y))]));
        let second = GrayF32Image::from_fn(n, n, |x, y| {
            let w = flow_warp(nf, f64::from(x), f64::from(y));
            image::Luma([tex(f64::from(x) - w[0], f64::from(y) - w[1])])
        });
        Ok(FlowWorkload { first, second, n })
    }

    /// The mean end-point error of `flow` (first to second image) against the true forward
    /// flow (the warp inverted by 20 fixed-point iterations), px: over the pixels whose
    /// target lies inside the image, and over those of them at least 32 px from the border.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] for a flow of another size.
    pub fn epe(&self, flow: &Flow) -> Result<(f64, f64)> {
        let n = self.n;
        skin_core::check::same_size("flow pixels", (n * n) as usize, flow.u.len())?;
        let nf = f64::from(n);
        let (mut e, mut c, mut ei, mut ci) = (0.0, 0usize, 0.0, 0usize);
        for y in 0..n {
            for x in 0..n {
                let (px, py) = (f64::from(x), f64::from(y));
                let mut u = flow_warp(nf, px, py);
                for _ in 0..20 {
                    u = flow_warp(nf, px + u[0], py + u[1]);
                }
                let (tx, ty) = (px + u[0], py + u[1]);
                if !(0.0..=nf - 1.0).contains(&tx) || !(0.0..=nf - 1.0).contains(&ty) {
                    continue;
                }
                let f = flow.u[(y * n + x) as usize];
                let d =
                    ((f64::from(f[0]) - u[0]).powi(2) + (f64::from(f[1]) - u[1]).powi(2)).sqrt();
                e += d;
                c += 1;
                if x >= 32 && y >= 32 && x < n - 32 && y < n - 32 {
                    ei += d;
                    ci += 1;
                }
            }
        }
        Ok((e / c.max(1) as f64, ei / ci.max(1) as f64))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{dense_flow, FlowParams};

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

    #[test]
    fn the_flow_workload_scores_a_flow_against_its_warp() {
        let w = FlowWorkload::new(128).unwrap();
        let zero = Flow {
            width: 128,
            height: 128,
            u: vec![[0.0; 2]; 128 * 128],
        };
        // No motion scores the warp's own mean length (≈ 8 px at 1024², an eighth here).
        let (still, _) = w.epe(&zero).unwrap();
        assert!(still > 0.4 && still < 1.5, "zero flow EPE {still}");
        let (epe, interior) = w
            .epe(&dense_flow(&w.first, &w.second, &FlowParams::default()).unwrap())
            .unwrap();
        assert!(
            epe < 0.2 * still && interior <= epe * 1.5,
            "EPE {epe} ({interior} inside), still {still}"
        );
    }

    #[test]
    fn bad_flow_workload_input_is_a_clear_error() {
        assert!(matches!(
            FlowWorkload::new(32),
            Err(Error::InvalidParam { name: "n", .. })
        ));
        let w = FlowWorkload::new(64).unwrap();
        let small = Flow {
            width: 32,
            height: 32,
            u: vec![[0.0; 2]; 32 * 32],
        };
        assert!(w.epe(&small).is_err());
    }
}
