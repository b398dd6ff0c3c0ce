//! A view's surface as points along its pixel rays and as a triangle mesh (the other view's
//! surface is rendered through it).

use rayon::prelude::*;
use skin_core::camera::Camera;
use skin_core::check;
use skin_core::math::DVec3;
use skin_core::mesh::TriMesh;

use crate::integrate::camera_rays;
use crate::{DepthMap, Error, Result};

pub(super) fn points_of(camera: &Camera, depth: &DepthMap, rays: &[DVec3]) -> Vec<Option<DVec3>> {
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
    let rays = world_rays(camera, None)?;
    mesh_of_points(depth, &points_of(camera, depth, &rays), max_jump_m)
}

/// [`depth_map_mesh`] from the map's points (`points_of`, one per pixel).
pub(super) fn mesh_of_points(
    depth: &DepthMap,
    points: &[Option<DVec3>],
    max_jump_m: f64,
) -> Result<TriMesh> {
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
            let d = q.map(|i| depth.depth_m[i]);
            let spread = d.iter().copied().fold(f64::NEG_INFINITY, f64::max)
                - d.iter().copied().fold(f64::INFINITY, f64::min);
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

/// The camera's world ray direction per pixel: `camera_frame`'s (its [`camera_rays`], when the
/// caller has them) turned into the world, or computed.
pub(super) fn world_rays(camera: &Camera, camera_frame: Option<&[DVec3]>) -> Result<Vec<DVec3>> {
    let r = camera.world_from_camera();
    let mut rays = match camera_frame {
        Some(rays) => rays.to_vec(),
        None => camera_rays(camera)?,
    };
    rays.par_iter_mut()
        .for_each(|d| *d = r.transform_vector3(*d));
    Ok(rays)
}
