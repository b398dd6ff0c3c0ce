//! Indexed triangle meshes and the geometry processing the methods share.
//!
//! The core type is [`TriMesh`]: vertex positions (`DVec3`, metres) and faces (`[u32; 3]`,
//! counter-clockwise seen from outside). Further submodules add IO, normals, adjacency,
//! Laplacians (Vlasic thesis §2.4.1), surface queries, skinning (§2.5.1) and distance metrics.

mod heat_weights;
mod laplacian;
pub mod shapes;
mod skinning;
mod trimesh;

pub use heat_weights::{
    bone_heat_weights, bone_heat_weights_dense, BoneSegment, HeatWeightsParams,
    DEFAULT_HEAT_CONSTANT, DEFAULT_TIE_TOLERANCE,
};
pub use laplacian::{
    cotangent_laplacian, mass_matrix, uniform_laplacian, DegenerateFaces, LaplacianParams,
    MassKind, DEFAULT_DEGENERATE_TOL,
};
pub use skinning::{skin, SkinWeights, DEFAULT_MAX_INFLUENCES, DEFAULT_PRUNE_BELOW};
pub use trimesh::TriMesh;
