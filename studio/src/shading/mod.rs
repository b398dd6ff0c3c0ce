//! Lights and Lambertian shading of rendered views, with optional cast shadows — the
//! synthetic counterpart of the light stage of Vlasic thesis §3.2.1 (a geodesic dome of 1,200
//! individually controllable lights) on which the photometric-normal method (Ch. 3, Eq. 3.1)
//! depends.
//!
//! Radiometry (white lights, RGB albedo `ρ`): a Lambertian surface point `p` with unit normal
//! `n` reflects radiance `L_o = ρ/π · Σ_l V_l E_l` towards the camera, where `E_l` is the
//! irradiance from light `l` ([`Light::irradiance`]) and `V_l ∈ [0, 1]` its visibility
//! (1 without shadows). Point lights have radiant intensity `I` (W/sr): `E = I cos θ / r²`.
//! Area lights are small one-sided Lambertian emitters of radiance `L` and area `A`:
//! `E = L A cos θ_l cos θ / r²` (the small-source limit; accurate to ~1 % once the distance
//! exceeds ~5× the light's size, as on the 8 m dome).
//!
//! | file | holds |
//! | --- | --- |
//! | `lights.rs` | [`Light`] and its irradiance |
//! | `dome.rs` | [`dome_lights`]: the light-stage dome of Vlasic §3.2.1 at real positions |
//! | `visibility.rs` | [`LightVisibility`]: per-vertex shadow-ray visibility through the BVH, lights-inside-the-body check |
//! | `shadow_bvh.rs` | the any-hit hierarchy of the shadow rays (binned SAH, `f32` boxes, `f64` triangles) |
//! | `shade.rs` | [`shade`]: per-pixel Lambertian shading of a [`skin_core::raster::RenderedView`] with an [`Albedo`]; [`shade_patterns`]: the same under several light patterns in one pass |

mod dome;
mod lights;
mod shade;
mod shadow_bvh;
mod visibility;

pub use dome::{dome_lights, DomeParams};
pub use lights::Light;
pub(crate) use shade::check_patterns;
pub use shade::{shade, shade_patterns, srgb8, Albedo, ShadedView, Shadows};
pub use visibility::{check_lights_outside, light_bins, vertices_seen, LightVisibility};
