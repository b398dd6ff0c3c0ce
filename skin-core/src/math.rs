//! Geometry vocabulary: `glam` f64 types used at every public boundary (points, directions,
//! rotations, rigid transforms), the [`Ray`] shared by cameras and mesh queries, and least-squares
//! alignment of point sets ([`fit_similarity`]). Linear
//! algebra (state vectors, Jacobians, covariances) uses `nalgebra` instead; see DESIGN.md
//! "Two vocabularies".

mod similarity;

pub use glam::{DAffine3, DMat3, DMat4, DQuat, DVec2, DVec3, DVec4};
use serde::{Deserialize, Serialize};
pub use similarity::{fit_similarity, Alignment, Similarity};

/// A ray `origin + t·direction`, `t ≥ 0`: the pixel rays of [`crate::camera::Camera::ray`]
/// and the queries of [`crate::mesh::MeshQuery::cast_ray`].
///
/// **Direction length.** The direction is stored as given, never rescaled, so a ray built
/// from an exact direction keeps its exact values. Camera rays have unit directions; a ray
/// cast into a mesh may have any non-zero length, since [`crate::mesh::MeshQuery::cast_ray`]
/// normalises it and reports hits at distances along the unit direction. [`Ray::at`] measures
/// `t` in multiples of `direction`, i.e. in the frame's units when the direction is unit.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Ray {
    /// Start point (the frame's units, e.g. m in the world frame; the camera centre for pixel
    /// rays).
    pub origin: DVec3,
    /// Direction, same frame: unit for camera rays; any non-zero length for mesh queries.
    pub direction: DVec3,
}

impl Ray {
    /// A ray from `origin` along `direction` (stored as given, not normalised).
    pub fn new(origin: DVec3, direction: DVec3) -> Self {
        Ray { origin, direction }
    }

    /// The point `origin + t·direction` (at distance `t` when the direction is unit).
    pub fn at(&self, t: f64) -> DVec3 {
        self.origin + self.direction * t
    }
}
