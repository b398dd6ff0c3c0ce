//! Indexed triangle meshes and the geometry processing the methods share.
//!
//! The core type is [`TriMesh`]: vertex positions (`DVec3`, metres) and faces (`[u32; 3]`,
//! counter-clockwise seen from outside). Further submodules add IO, normals, adjacency,
//! Laplacians (Vlasic thesis §2.4.1), surface queries, skinning (§2.5.1) and distance metrics;
//! with the feature `gltf`, glTF 2.0 export of mesh sequences (`write_gltf_animation`); with
//! the feature `decimate`, decimation by edge collapses (`decimate`).

#[cfg(feature = "decimate")]
mod decimate;
#[cfg(feature = "gltf")]
mod gltf;
mod heat_weights;
mod laplacian;
mod marching_tetrahedra;
mod metrics;
mod normals;
mod obj;
mod ply;
mod query;
pub mod shapes;
mod skinning;
mod subdivide;
mod surface_point;
mod topology;
mod trimesh;
mod uv;
mod winding_number;

#[cfg(feature = "decimate")]
pub use decimate::{decimate, Decimation};
#[cfg(feature = "gltf")]
pub use gltf::{save_gltf_animation, write_gltf_animation, MeshSequence};
pub use heat_weights::{
    bone_heat_weights, bone_heat_weights_dense, rest_bones, Bone, BoneSegment, HeatWeightsParams,
    VisibilityParams,
};
pub use laplacian::{
    cotangent_laplacian, mass_matrix, uniform_laplacian, DegenerateFaces, LaplacianParams, MassKind,
};
pub use marching_tetrahedra::{marching_tetrahedra, ScalarGrid};
pub use metrics::{
    mesh_distance, one_sided_distance, points_to_surface, DistanceStats, MeshDistance,
    OneSidedDistance,
};
pub use normals::{face_areas, face_normals, triangle_normal, vertex_normals, NormalWeighting};
pub use obj::{
    read_obj, read_obj_from_reader, read_obj_from_str, read_obj_group, read_obj_group_with_map,
    write_obj, write_obj_to, ObjFile, ObjGroupMesh,
};
pub use ply::{read_ply, read_ply_from_reader, write_ply, write_ply_to, PlyEncoding};
pub use query::{ClosestPoint, MeshQuery, RayHit};
pub use skinning::{resize_rest, skin, SkinBinding, SkinWeights};
pub use subdivide::{FaceRefinement, FinePoint, RefineParams, Refinement};
pub use surface_point::{
    closest_point_on_triangle, evaluate_surface_points, SurfacePoint, TrianglePoint,
};
pub use topology::{
    boundary_edges, connected_parts, is_closed, unique_edges, vertex_faces, vertex_neighbors,
    Adjacency, EdgeTopology,
};
pub use trimesh::{triangle_area, BoundingBox, TriMesh};
pub use uv::{UvLayout, UvSplit};
pub use winding_number::WindingNumber;
