//! The synthetic capture studio: a rigged performer with known deformation, motions, a
//! rasteriser and lighting that render ground truth for every method of `dynamic-shapes`.
//!
//! | module | holds |
//! | --- | --- |
//! | [`raster`] | CPU rasteriser: silhouette masks, depth along the ray, camera-space normals, triangle ids and perspective-correct barycentrics, exact under the camera's radial distortion |
//! | [`shading`] | lights (point, area, the light-stage dome of Vlasic thesis §3.2.1), Lambertian shading with albedo, cast shadows by ray casts |

pub mod raster;
pub mod shading;

pub use raster::{Buffers, Rasterizer, RenderParams, RenderedView, NO_TRIANGLE};
