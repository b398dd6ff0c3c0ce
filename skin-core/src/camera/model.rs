//! The calibrated camera: intrinsics, radial distortion and rigid pose; projection of world
//! points to pixels and back-projection of pixels to world rays (Sand 2003 §4.1,
//! `p = D_{c,r}(P_{q,f,a} w)`).

use serde::{Deserialize, Serialize};

use super::distortion::RadialDistortion;
use super::intrinsics::Intrinsics;
use crate::check::all_finite;
use crate::error::{Error, Result};
use crate::math::{DAffine3, DMat3, DVec2, DVec3, Ray};

/// Points closer to the camera plane than this (m, camera z) are treated as behind the camera:
/// their projection is numerically meaningless.
pub const MIN_DEPTH_M: f64 = 1e-9;
/// Tolerance on `‖RᵀR − I‖` and `|det R − 1|` when checking that a pose is rigid.
const RIGID_TOLERANCE: f64 = 1e-6;

/// A projected point: distorted pixel and depth along the optical axis.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Projection {
    /// Observed (distorted) pixel, px.
    pub pixel: DVec2,
    /// Depth, m: the camera-frame z of the point (> 0 in front of the camera).
    pub depth_m: f64,
}

/// A projection with its derivative with respect to the world point.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ProjectionJacobian {
    /// The projection.
    pub projection: Projection,
    /// Rows of `∂pixel/∂p_world` (px/m): `[∂u/∂p, ∂v/∂p]`.
    pub d_pixel_d_world: [DVec3; 2],
}

/// A calibrated camera: `pixel = D(K · π(camera_from_world · p))` with `π(x, y, z) = (x/z, y/z)`.
///
/// The pose is kept as both `world_from_camera` (the camera's placement; its translation is the
/// camera centre) and its inverse `camera_from_world`; both are rigid, checked on construction.
/// Serialises as intrinsics, distortion and `world_from_camera`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "CameraRepr", into = "CameraRepr")]
pub struct Camera {
    /// Pinhole intrinsics.
    pub intrinsics: Intrinsics,
    /// Radial distortion (Sand's `D_{c,r}`).
    pub distortion: RadialDistortion,
    world_from_camera: DAffine3,
    camera_from_world: DAffine3,
}

#[derive(Serialize, Deserialize)]
struct CameraRepr {
    intrinsics: Intrinsics,
    distortion: RadialDistortion,
    world_from_camera: DAffine3,
}

impl TryFrom<CameraRepr> for Camera {
    type Error = Error;
    fn try_from(r: CameraRepr) -> Result<Self> {
        Camera::new(r.intrinsics, r.distortion, r.world_from_camera)
    }
}

impl From<Camera> for CameraRepr {
    fn from(c: Camera) -> Self {
        CameraRepr {
            intrinsics: c.intrinsics,
            distortion: c.distortion,
            world_from_camera: c.world_from_camera,
        }
    }
}

fn check_rigid(what: &'static str, t: &DAffine3) -> Result<()> {
    all_finite(what, t.to_cols_array().iter())?;
    let r = t.matrix3;
    let off = (r.transpose() * r - DMat3::IDENTITY)
        .to_cols_array()
        .iter()
        .fold(0.0f64, |m, v| m.max(v.abs()));
    if off > RIGID_TOLERANCE || (r.determinant() - 1.0).abs() > RIGID_TOLERANCE {
        return Err(Error::InvalidParam {
            name: what,
            reason: "pose must be a rotation (orthonormal, det +1) plus translation".into(),
        });
    }
    Ok(())
}

impl Camera {
    /// A camera placed by `world_from_camera` (camera frame: x right, y down, z forward).
    ///
    /// # Errors
    /// Errors of [`Intrinsics::validate`]; [`Error::NonFinite`] for a non-finite distortion or
    /// pose; [`Error::InvalidParam`] if the pose is not rigid.
    pub fn new(
        intrinsics: Intrinsics,
        distortion: RadialDistortion,
        world_from_camera: DAffine3,
    ) -> Result<Self> {
        intrinsics.validate()?;
        all_finite(
            "distortion",
            [&distortion.k1, &distortion.centre.x, &distortion.centre.y],
        )?;
        check_rigid("world_from_camera", &world_from_camera)?;
        Ok(Self {
            intrinsics,
            distortion,
            world_from_camera,
            camera_from_world: world_from_camera.inverse(),
        })
    }

    /// A camera given `camera_from_world` (the extrinsics `[R | t]` of OpenCV and of `P = K[R|t]`).
    ///
    /// # Errors
    /// As [`Camera::new`].
    pub fn from_camera_from_world(
        intrinsics: Intrinsics,
        distortion: RadialDistortion,
        camera_from_world: DAffine3,
    ) -> Result<Self> {
        check_rigid("camera_from_world", &camera_from_world)?;
        Self::new(intrinsics, distortion, camera_from_world.inverse())
    }

    /// An undistorted camera at `eye` (m) looking at `target`, with `up` (world) projecting to
    /// "up" in the image (towards smaller `v`).
    ///
    /// # Errors
    /// [`Error::Degenerate`] if `eye == target` or the viewing direction is parallel to `up`;
    /// errors of [`Camera::new`].
    pub fn look_at(intrinsics: Intrinsics, eye: DVec3, target: DVec3, up: DVec3) -> Result<Self> {
        all_finite(
            "look_at input",
            [eye, target, up].iter().flat_map(|v| v.as_ref().iter()),
        )?;
        let forward = (target - eye).normalize_or_zero();
        let right = forward.cross(up).normalize_or_zero();
        if forward == DVec3::ZERO || right == DVec3::ZERO {
            return Err(Error::Degenerate {
                what: "look_at: eye equals target or view direction is parallel to up".into(),
            });
        }
        let down = forward.cross(right);
        let world_from_camera =
            DAffine3::from_mat3_translation(DMat3::from_cols(right, down, forward), eye);
        Self::new(intrinsics, RadialDistortion::NONE, world_from_camera)
    }

    /// Returns the camera with the given distortion.
    pub fn with_distortion(mut self, distortion: RadialDistortion) -> Self {
        self.distortion = distortion;
        self
    }

    /// Pose of the camera in the world (camera → world).
    pub fn world_from_camera(&self) -> DAffine3 {
        self.world_from_camera
    }

    /// Extrinsics (world → camera).
    pub fn camera_from_world(&self) -> DAffine3 {
        self.camera_from_world
    }

    /// Replaces the pose.
    ///
    /// # Errors
    /// [`Error::NonFinite`] or [`Error::InvalidParam`] if `world_from_camera` is not rigid.
    pub fn set_world_from_camera(&mut self, world_from_camera: DAffine3) -> Result<()> {
        check_rigid("world_from_camera", &world_from_camera)?;
        self.world_from_camera = world_from_camera;
        self.camera_from_world = world_from_camera.inverse();
        Ok(())
    }

    /// Camera centre (optical centre) in the world, m.
    pub fn centre(&self) -> DVec3 {
        self.world_from_camera.translation
    }

    /// Unit optical axis (camera +z) in the world.
    pub fn optical_axis(&self) -> DVec3 {
        self.world_from_camera.matrix3.z_axis
    }

    /// Projects a point given in the camera frame (m).
    ///
    /// # Errors
    /// [`Error::NonFinite`] for a non-finite point; [`Error::NotVisible`] if it is behind (or
    /// within [`MIN_DEPTH_M`] of) the camera plane, or beyond the fold of a barrel distortion.
    pub fn project_camera_point(&self, p_camera: DVec3) -> Result<Projection> {
        if !p_camera.is_finite() {
            return Err(Error::NonFinite {
                what: "point to project",
            });
        }
        if p_camera.z <= MIN_DEPTH_M {
            return Err(Error::NotVisible {
                what: format!(
                    "point at camera depth {} m is behind the camera",
                    p_camera.z
                ),
            });
        }
        let n = DVec2::new(p_camera.x / p_camera.z, p_camera.y / p_camera.z);
        let undistorted = self.intrinsics.pixel_from_normalized(n);
        let pixel = self
            .distortion
            .distort(&self.intrinsics, undistorted)
            .ok_or_else(|| Error::NotVisible {
                what: "point lies beyond the valid radius of the barrel distortion".into(),
            })?;
        Ok(Projection {
            pixel,
            depth_m: p_camera.z,
        })
    }

    /// Projects a world point (m) to its observed pixel and depth. Points off the image still
    /// project (see [`Camera::is_visible`]).
    ///
    /// # Errors
    /// As [`Camera::project_camera_point`].
    pub fn project_with_depth(&self, p_world: DVec3) -> Result<Projection> {
        self.project_camera_point(self.camera_from_world.transform_point3(p_world))
    }

    /// Projects a world point (m) to its observed (distorted) pixel.
    ///
    /// # Errors
    /// As [`Camera::project_camera_point`]: behind-camera points are [`Error::NotVisible`].
    ///
    /// # Example
    /// ```
    /// use skin_core::camera::{Camera, Intrinsics};
    /// use skin_core::math::DVec3;
    /// let k = Intrinsics::new(800.0, 800.0, 320.0, 240.0, 640, 480)?;
    /// let cam = Camera::look_at(k, DVec3::new(0.0, 0.0, -3.0), DVec3::ZERO, DVec3::Y)?;
    /// let px = cam.project(DVec3::ZERO)?;
    /// assert!((px.x - 320.0).abs() < 1e-9 && (px.y - 240.0).abs() < 1e-9);
    /// assert!(cam.project(DVec3::new(0.0, 0.0, -5.0)).is_err()); // behind the camera
    /// # Ok::<(), skin_core::Error>(())
    /// ```
    pub fn project(&self, p_world: DVec3) -> Result<DVec2> {
        Ok(self.project_with_depth(p_world)?.pixel)
    }

    /// Projects a world point and returns the analytic Jacobian `∂pixel/∂p_world` (for
    /// reprojection-error optimisers such as marker or silhouette fitting). By the chain rule
    /// through `p_c = R p + t`, `n = (x/z, y/z)`, `u = (fx·nₓ + cx, fy·n_y + cy)` and
    /// `D(u) = c + w(1 + k1ρ²)` with `w = u − c`, `ρ² = (wₓ/fx)² + (w_y/fy)²`:
    /// `∂D/∂u = (1 + k1ρ²) I + k1 w ∇ρ²ᵀ`, `∇ρ² = (2wₓ/fx², 2w_y/fy²)`.
    ///
    /// # Errors
    /// As [`Camera::project`].
    pub fn project_with_jacobian(&self, p_world: DVec3) -> Result<ProjectionJacobian> {
        let pc = self.camera_from_world.transform_point3(p_world);
        let projection = self.project_camera_point(pc)?;
        let k = &self.intrinsics;
        let (x, y, z) = (pc.x, pc.y, pc.z);
        // Rows of ∂u/∂p_c (undistorted pixel w.r.t. the camera-frame point).
        let du = [
            DVec3::new(k.fx / z, 0.0, -k.fx * x / (z * z)),
            DVec3::new(0.0, k.fy / z, -k.fy * y / (z * z)),
        ];
        let w = k.pixel_from_normalized(DVec2::new(x / z, y / z)) - self.distortion.centre;
        let k1 = self.distortion.k1;
        let rho2 = (w.x / k.fx).powi(2) + (w.y / k.fy).powi(2);
        let grad = DVec2::new(2.0 * w.x / (k.fx * k.fx), 2.0 * w.y / (k.fy * k.fy));
        let radial = 1.0 + k1 * rho2;
        let dd = [
            [radial + k1 * w.x * grad.x, k1 * w.x * grad.y],
            [k1 * w.y * grad.x, radial + k1 * w.y * grad.y],
        ];
        // ∂p_c/∂p_world = R, so a row vector r maps to Rᵀ r.
        let rt = self.camera_from_world.matrix3.transpose();
        let row = |i: usize| rt * (du[0] * dd[i][0] + du[1] * dd[i][1]);
        Ok(ProjectionJacobian {
            projection,
            d_pixel_d_world: [row(0), row(1)],
        })
    }

    /// True if the world point is in front of the camera and projects onto the image.
    pub fn is_visible(&self, p_world: DVec3) -> bool {
        self.project(p_world)
            .is_ok_and(|px| self.intrinsics.contains(px))
    }

    /// Indices of the points the camera sees (see [`Camera::is_visible`]).
    ///
    /// # Errors
    /// [`Error::Empty`] for no points; [`Error::NotVisible`] if the camera sees none of them.
    pub fn visible_points(&self, points_world: &[DVec3]) -> Result<Vec<usize>> {
        if points_world.is_empty() {
            return Err(Error::Empty {
                what: "points to test for visibility",
            });
        }
        let seen: Vec<usize> = (0..points_world.len())
            .filter(|&i| self.is_visible(points_world[i]))
            .collect();
        if seen.is_empty() {
            return Err(Error::NotVisible {
                what: format!(
                    "the camera at {} sees none of the {} points",
                    self.centre(),
                    points_world.len()
                ),
            });
        }
        Ok(seen)
    }

    /// Camera-frame direction `(x/z, y/z, 1)` of an observed pixel (distortion removed).
    fn normalized_direction(&self, pixel: DVec2) -> Result<DVec3> {
        let undistorted = self.distortion.undistort(&self.intrinsics, pixel)?;
        let n = self.intrinsics.normalized_from_pixel(undistorted);
        Ok(DVec3::new(n.x, n.y, 1.0))
    }

    /// World-space ray through an observed (distorted) pixel: origin at the camera centre, unit
    /// direction.
    ///
    /// # Errors
    /// [`Error::NonFinite`] for a non-finite pixel; [`Error::NotVisible`] for a pixel outside
    /// the range of a barrel distortion.
    pub fn ray(&self, pixel: DVec2) -> Result<Ray> {
        let d = self.normalized_direction(pixel)?;
        Ok(Ray {
            origin: self.centre(),
            direction: self.world_from_camera.transform_vector3(d).normalize(),
        })
    }

    /// World point (m) seen at an observed pixel at depth `depth_m` along the optical axis
    /// (camera z, not distance along the ray).
    ///
    /// # Errors
    /// [`Error::InvalidParam`] for a depth that is not finite and positive; errors of
    /// [`Camera::ray`].
    pub fn unproject(&self, pixel: DVec2, depth_m: f64) -> Result<DVec3> {
        if !(depth_m.is_finite() && depth_m > 0.0) {
            return Err(Error::InvalidParam {
                name: "depth_m",
                reason: format!("must be finite and > 0, got {depth_m}"),
            });
        }
        let d = self.normalized_direction(pixel)?;
        Ok(self.world_from_camera.transform_point3(d * depth_m))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::DQuat;
    use proptest::prelude::*;

    fn camera() -> Camera {
        let k = Intrinsics::new(1000.0, 980.0, 650.0, 470.0, 1280, 960).unwrap();
        Camera::look_at(
            k,
            DVec3::new(2.0, 1.5, -3.0),
            DVec3::new(0.1, 0.2, 0.0),
            DVec3::Y,
        )
        .unwrap()
        .with_distortion(RadialDistortion::new(-0.12, DVec2::new(660.0, 455.0)))
    }

    proptest! {
        #[test]
        fn project_then_ray_round_trip(u in 0.0f64..1280.0, v in 0.0f64..960.0, depth in 0.2f64..20.0) {
            let cam = camera();
            let px = DVec2::new(u, v);
            let ray = cam.ray(px).unwrap();
            prop_assert!((ray.direction.length() - 1.0).abs() < 1e-12);
            let p = ray.at(depth);
            let back = cam.project(p).unwrap();
            prop_assert!((back - px).length() < 1e-7, "{px} -> {back}");
            let q = cam.unproject(px, depth).unwrap();
            let proj = cam.project_with_depth(q).unwrap();
            prop_assert!((proj.depth_m - depth).abs() < 1e-9 && (proj.pixel - px).length() < 1e-7);
        }
    }

    proptest! {
        #[test]
        fn projection_jacobian_matches_finite_differences(x in -1.0f64..1.0, y in -1.0f64..1.0, z in -1.0f64..1.0) {
            let cam = camera();
            let p = DVec3::new(x, y, z);
            let j = cam.project_with_jacobian(p).unwrap();
            prop_assert!((j.projection.pixel - cam.project(p).unwrap()).length() < 1e-12);
            let h = 1e-6;
            for (a, e) in [DVec3::X, DVec3::Y, DVec3::Z].into_iter().enumerate() {
                let fd = (cam.project(p + e * h).unwrap() - cam.project(p - e * h).unwrap()) / (2.0 * h);
                let an = DVec2::new(j.d_pixel_d_world[0][a], j.d_pixel_d_world[1][a]);
                prop_assert!((fd - an).length() < 1e-5 * an.length().max(1.0), "axis {a}: {fd} vs {an}");
            }
        }
    }

    #[test]
    fn look_at_orientation() {
        let k = Intrinsics::new(500.0, 500.0, 320.0, 240.0, 640, 480).unwrap();
        let cam = Camera::look_at(k, DVec3::new(0.0, 0.0, 5.0), DVec3::ZERO, DVec3::Y).unwrap();
        assert!((cam.optical_axis() - DVec3::NEG_Z).length() < 1e-12);
        // World up projects above the centre (smaller v).
        let up = cam.project(DVec3::new(0.0, 0.5, 0.0)).unwrap();
        assert!(up.y < 240.0 && (up.x - 320.0).abs() < 1e-9);
        assert!(Camera::look_at(k, DVec3::ZERO, DVec3::Y, DVec3::Y).is_err());
        assert!(Camera::look_at(k, DVec3::ZERO, DVec3::ZERO, DVec3::Y).is_err());
    }

    #[test]
    fn behind_camera_and_seeing_nothing() {
        let cam = camera();
        let behind = cam.centre() - cam.optical_axis();
        assert!(matches!(cam.project(behind), Err(Error::NotVisible { .. })));
        assert!(matches!(
            cam.project(cam.centre()),
            Err(Error::NotVisible { .. })
        ));
        assert!(matches!(
            cam.project(DVec3::new(f64::NAN, 0.0, 0.0)),
            Err(Error::NonFinite { .. })
        ));
        assert!(!cam.is_visible(behind));
        let target = DVec3::new(0.1, 0.2, 0.0);
        assert_eq!(cam.visible_points(&[behind, target]).unwrap(), vec![1]);
        assert!(matches!(
            cam.visible_points(&[behind]),
            Err(Error::NotVisible { .. })
        ));
        assert!(matches!(cam.visible_points(&[]), Err(Error::Empty { .. })));
        assert!(matches!(
            cam.unproject(DVec2::ZERO, -1.0),
            Err(Error::InvalidParam { .. })
        ));
    }

    #[test]
    fn pose_validation_and_serde() {
        let cam = camera();
        let sheared = DAffine3::from_cols_array(&[
            1.0, 0.0, 0.0, 0.5, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0,
        ]);
        assert!(Camera::new(cam.intrinsics, cam.distortion, sheared).is_err());
        let rot = DAffine3::from_rotation_translation(DQuat::from_rotation_y(0.3), DVec3::X);
        let c2 = Camera::from_camera_from_world(cam.intrinsics, cam.distortion, rot).unwrap();
        assert!((c2.camera_from_world().translation - DVec3::X).length() < 1e-12);
        let json = serde_json::to_string(&cam).unwrap();
        let back: Camera = serde_json::from_str(&json).unwrap();
        assert_eq!(back.intrinsics, cam.intrinsics);
        assert!((back.centre() - cam.centre()).length() < 1e-12);
        let bad = json.replace("\"fx\":1000.0", "\"fx\":-1.0");
        assert!(serde_json::from_str::<Camera>(&bad).is_err());
    }
}
