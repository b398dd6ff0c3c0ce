//! Indexed triangle meshes and the geometry processing the methods share.
//!
//! The core type is [`TriMesh`]: vertex positions (`DVec3`, metres) and faces (`[u32; 3]`,
//! counter-clockwise seen from outside). Further submodules add IO, normals, adjacency,
//! Laplacians (Vlasic thesis §2.4.1), surface queries, skinning (§2.5.1) and distance metrics.

mod marching_cubes;
mod trimesh;

pub use marching_cubes::{marching_cubes, ScalarGrid};
pub use trimesh::TriMesh;
