//! Geometry vocabulary: `glam` f64 types used at every public boundary (points, directions,
//! rotations, rigid transforms). Linear algebra (state vectors, Jacobians, covariances) uses
//! `nalgebra` instead; see DESIGN.md "Two vocabularies".

pub use glam::{DAffine3, DMat3, DMat4, DQuat, DVec2, DVec3, DVec4};
