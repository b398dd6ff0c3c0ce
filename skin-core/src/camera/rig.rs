//! Camera rigs: several calibrated cameras around a capture volume (Sand 2003 §4 places
//! "one or more video cameras … around the motion-capture workspace").

use serde::{Deserialize, Serialize};

use super::intrinsics::Intrinsics;
use super::model::Camera;
use crate::check::all_finite;
use crate::error::{Error, Result};
use crate::math::DVec3;

/// A set of cameras observing one volume. Serialisable (e.g. to JSON with `serde_json`).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Rig {
    /// The cameras, in capture order.
    pub cameras: Vec<Camera>,
}

impl Rig {
    /// `n` undistorted cameras evenly spaced on a horizontal circle of radius `radius_m` around
    /// `look_at`, all looking at it. "Horizontal" is the plane perpendicular to `up` (world);
    /// each camera sits at signed height `height_m` along `up` measured from the world origin,
    /// and camera 0 lies in the direction of the world axis least aligned with `up` from the
    /// centre (X for a Y- or Z-up world).
    ///
    /// # Errors
    /// [`Error::InvalidParam`] for `n = 0`, a non-positive radius or a zero `up`;
    /// [`Error::NonFinite`] for non-finite input; [`Error::Degenerate`] if a camera would sit
    /// exactly above or below `look_at`.
    pub fn ring(
        n: usize,
        radius_m: f64,
        height_m: f64,
        look_at: DVec3,
        up: DVec3,
        intrinsics: Intrinsics,
    ) -> Result<Self> {
        if n == 0 {
            return Err(Error::InvalidParam {
                name: "n",
                reason: "a ring needs at least one camera".into(),
            });
        }
        all_finite(
            "ring geometry",
            [
                radius_m, height_m, look_at.x, look_at.y, look_at.z, up.x, up.y, up.z,
            ]
            .iter(),
        )?;
        if radius_m <= 0.0 {
            return Err(Error::InvalidParam {
                name: "radius_m",
                reason: format!("must be > 0, got {radius_m}"),
            });
        }
        let up = up.normalize_or_zero();
        if up == DVec3::ZERO {
            return Err(Error::InvalidParam {
                name: "up",
                reason: "must be non-zero".into(),
            });
        }
        let (e1, e2) = horizontal_basis(up);
        let centre = look_at - up * look_at.dot(up) + up * height_m;
        let cameras = (0..n)
            .map(|i| {
                let theta = std::f64::consts::TAU * i as f64 / n as f64;
                let eye = centre + (e1 * theta.cos() + e2 * theta.sin()) * radius_m;
                Camera::look_at(intrinsics, eye, look_at, up)
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Self { cameras })
    }

    /// Adds a camera at `height_m` along `up` straight above `look_at`, looking down at it, with
    /// the image "up" direction along the ring's camera-0 axis.
    ///
    /// # Errors
    /// [`Error::Degenerate`] if `look_at` is not below the camera; errors of [`Camera::look_at`].
    pub fn with_top_camera(
        mut self,
        height_m: f64,
        look_at: DVec3,
        up: DVec3,
        intrinsics: Intrinsics,
    ) -> Result<Self> {
        let up = up.normalize_or_zero();
        if up == DVec3::ZERO {
            return Err(Error::InvalidParam {
                name: "up",
                reason: "must be non-zero".into(),
            });
        }
        let (e1, _) = horizontal_basis(up);
        let eye = look_at - up * look_at.dot(up) + up * height_m;
        if (eye - look_at).dot(up) <= 0.0 {
            return Err(Error::Degenerate {
                what: "top camera must be above the point it looks at".into(),
            });
        }
        self.cameras
            .push(Camera::look_at(intrinsics, eye, look_at, e1)?);
        Ok(self)
    }

    /// Number of cameras.
    pub fn len(&self) -> usize {
        self.cameras.len()
    }

    /// True if the rig has no camera.
    pub fn is_empty(&self) -> bool {
        self.cameras.is_empty()
    }

    /// For each camera, the indices of the points it sees.
    ///
    /// # Errors
    /// [`Error::Empty`] for no points; [`Error::NotVisible`] naming the first camera that sees
    /// none of them.
    pub fn visibility(&self, points_world: &[DVec3]) -> Result<Vec<Vec<usize>>> {
        self.cameras
            .iter()
            .enumerate()
            .map(|(i, c)| {
                c.visible_points(points_world).map_err(|e| match e {
                    Error::NotVisible { what } => Error::NotVisible {
                        what: format!("camera {i}: {what}"),
                    },
                    other => other,
                })
            })
            .collect()
    }
}

/// Orthonormal basis `(e1, e2)` of the plane perpendicular to unit `up`, `e1` from the world axis
/// least aligned with `up`, so `(e1, e2, up)` is right-handed.
fn horizontal_basis(up: DVec3) -> (DVec3, DVec3) {
    let a = up.abs();
    let axis = if a.x <= a.y && a.x <= a.z {
        DVec3::X
    } else if a.y <= a.z {
        DVec3::Y
    } else {
        DVec3::Z
    };
    let e1 = (axis - up * axis.dot(up)).normalize();
    (e1, up.cross(e1))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ring_cameras_look_at_the_target() {
        let k = Intrinsics::from_horizontal_fov(1.0, 640, 480).unwrap();
        let target = DVec3::new(0.0, 1.0, 0.0);
        let rig = Rig::ring(8, 4.0, 2.0, target, DVec3::Y, k)
            .unwrap()
            .with_top_camera(5.0, target, DVec3::Y, k)
            .unwrap();
        assert_eq!(rig.len(), 9);
        for cam in &rig.cameras {
            let px = cam.project(target).unwrap();
            assert!((px - k.principal_point()).length() < 1e-9);
        }
        for cam in &rig.cameras[..8] {
            assert!((cam.centre().y - 2.0).abs() < 1e-12);
            let horizontal = (cam.centre() - target) * DVec3::new(1.0, 0.0, 1.0);
            assert!((horizontal.length() - 4.0).abs() < 1e-12);
        }
        assert!((rig.cameras[8].centre() - DVec3::new(0.0, 5.0, 0.0)).length() < 1e-12);
        let vis = rig.visibility(&[target]).unwrap();
        assert!(vis.iter().all(|v| v == &vec![0]));
        let json = serde_json::to_string(&rig).unwrap();
        let back: Rig = serde_json::from_str(&json).unwrap();
        assert_eq!(back.len(), 9);
        assert!((back.cameras[3].centre() - rig.cameras[3].centre()).length() < 1e-12);
    }

    #[test]
    fn bad_rigs_are_errors() {
        let k = Intrinsics::from_horizontal_fov(1.0, 640, 480).unwrap();
        assert!(Rig::ring(0, 1.0, 0.0, DVec3::ZERO, DVec3::Y, k).is_err());
        assert!(Rig::ring(3, -1.0, 0.0, DVec3::ZERO, DVec3::Y, k).is_err());
        assert!(Rig::ring(3, 1.0, f64::NAN, DVec3::ZERO, DVec3::Y, k).is_err());
        assert!(Rig::ring(3, 1.0, 0.0, DVec3::ZERO, DVec3::ZERO, k).is_err());
        assert!(Rig::default()
            .with_top_camera(-1.0, DVec3::ZERO, DVec3::Y, k)
            .is_err());
        let rig = Rig::ring(4, 3.0, 0.0, DVec3::ZERO, DVec3::Y, k).unwrap();
        // A point behind every... camera 0 cannot see a point far outside its view.
        assert!(matches!(
            rig.visibility(&[DVec3::new(0.0, 50.0, 0.0)]),
            Err(Error::NotVisible { .. })
        ));
    }
}
