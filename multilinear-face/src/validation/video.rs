//! Synthetic face videos (§5.4.1 validation): the faces and head motion of
//! [`point_track_sequence`](super::point_track_sequence) rendered by skin-core's rasteriser
//! into 640 × 480 RGB frames with a procedural skin texture, the true 3D face and camera kept
//! per frame.
//!
//! **Texture** ([`FaceVideoParams::texture`]): skin-core's solid [`AlbedoTexture`] skin,
//! evaluated per pixel at the rest position of the visible point (the generic neutral face,
//! model units read as cm and converted to m), so the pattern moves with the skin: base tone
//! `[0.8, 0.6, 0.5]`, blotches of 1.5 cm at ±25 % and brown freckles on a 4 mm lattice,
//! darkening up to 45 % — at 20 px per cm, freckles of 4–8 px, the detail a 9 × 9 KLT window
//! needs (the default studio skin, 12 mm freckles at 20 % contrast, is too smooth at this
//! scale). **Shading**: one light at the camera, `ρ (0.35 + 0.65 max(0, n·v))`, so the shading
//! changes as the head turns (the KLT removes each window's mean). **Pixels**: linear values
//! × 255 on a uniform dark grey backdrop, plus Gaussian noise of 1 grey level.

use dynamic_shapes_studio::{AlbedoTexture, TextureParams};
use image::{Rgb, RgbImage};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use skin_core::math::DVec3;
use skin_core::raster::NO_TRIANGLE;

use super::point_track_sequence;
use crate::face_data::FaceTensor;
use crate::tracking::WeakPerspective;
use crate::transfer::render_view;
use crate::video::FeaturePoints;
use crate::{Context, Error, Result, ResultExt};

/// Parameters of [`render_face_video`].
#[derive(Clone, Debug, PartialEq)]
pub struct FaceVideoParams {
    /// Frame size, px. Default 640 × 480.
    pub size: (u32, u32),
    /// The skin texture (module docs). Default: freckled skin.
    pub texture: TextureParams,
    /// Pixel noise, grey levels (σ). Default 1.
    pub noise: f64,
    /// Feature-point error of the initialisation, px (σ). Default 1.
    pub feature_noise_px: f64,
    /// Seed of the noise. Default 11.
    pub seed: u64,
}

impl Default for FaceVideoParams {
    fn default() -> Self {
        FaceVideoParams {
            size: (640, 480),
            texture: TextureParams {
                skin_variation: 0.25,
                blotch_scale_m: 0.015,
                freckle_scale_m: 0.004,
                freckle_darkening: 0.45,
                ..TextureParams::default()
            },
            noise: 1.0,
            feature_noise_px: 1.0,
            seed: 11,
        }
    }
}

/// A rendered face video with its ground truth.
#[derive(Clone, Debug)]
pub struct FaceVideo {
    /// The frames.
    pub frames: Vec<RgbImage>,
    /// Per frame, the true face (all vertices, model units).
    pub truth: Vec<Vec<DVec3>>,
    /// Per frame, the true camera.
    pub cameras: Vec<WeakPerspective>,
    /// The initialisation: the given feature vertices at their frame-0 projections plus noise.
    pub features: FeaturePoints,
    /// The backdrop colour (a frame without the face is this plus noise).
    pub background: [u8; 3],
}

/// The backdrop of every frame.
const BACKGROUND: [u8; 3] = [50, 52, 56];

/// Renders one frame of `face` under `cam` (module docs); `rest` are the texture coordinates
/// (rest positions, model units = cm) of the vertices.
///
/// # Errors
/// Errors of the rasteriser; [`Error::InvalidParam`] for a bad texture or noise.
pub fn render_face_frame(
    face: &[DVec3],
    triangles: &[[u32; 3]],
    rest: &[DVec3],
    cam: &WeakPerspective,
    params: &FaceVideoParams,
    seed: u64,
) -> Result<RgbImage> {
    skin_core::check::same_size("rest positions (one per vertex)", face.len(), rest.len())?;
    skin_core::check::non_negative("noise", params.noise)?;
    let texture = AlbedoTexture::new(params.texture)?;
    let (w, h) = params.size;
    let (view, _) = render_view(face, triangles, cam, w, h)?;
    let noise = Normal::new(0.0, params.noise.max(1e-300)).map_err(|e| Error::InvalidParam {
        name: "noise",
        reason: e.to_string(),
    })?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut img = RgbImage::from_pixel(w, h, Rgb(BACKGROUND));
    for (x, y, px) in img.enumerate_pixels_mut() {
        let i = view.index(x, y);
        let t = view.triangle[i];
        let mut c = BACKGROUND.map(f64::from);
        if t != NO_TRIANGLE {
            let tri = triangles[t as usize];
            let [b1, b2] = view.bary[i].map(f64::from);
            let p = rest[tri[0] as usize] * (1.0 - b1 - b2)
                + rest[tri[1] as usize] * b1
                + rest[tri[2] as usize] * b2;
            let rho = texture.skin(p * 0.01);
            // The pinhole looks along +z: a surface facing it has a normal with z < 0.
            let facing = f64::from(-view.normal_camera[i][2]).max(0.0);
            let light = 0.35 + 0.65 * facing;
            c = rho.map(|r| 255.0 * f64::from(r) * light);
        }
        let n = if params.noise > 0.0 {
            noise.sample(&mut rng)
        } else {
            0.0
        };
        *px = Rgb(c.map(|v| (v + n).round().clamp(0.0, 255.0) as u8));
    }
    Ok(img)
}

/// Renders the sequence of [`point_track_sequence`](super::point_track_sequence) (`person`,
/// `order`, `frame_count`: expressions and head motion) with `triangles` and the texture at
/// `rest` (the generic neutral face), and the initialisation's `feature_vertices` at their
/// true frame-0 projections plus [`FaceVideoParams::feature_noise_px`].
///
/// # Errors
/// As [`point_track_sequence`](super::point_track_sequence) and [`render_face_frame`] (in
/// [`Error::At`] with the frame).
pub fn render_face_video(
    person: &FaceTensor,
    order: &[usize],
    frame_count: usize,
    triangles: &[[u32; 3]],
    rest: &[DVec3],
    feature_vertices: &[usize],
    params: &FaceVideoParams,
) -> Result<FaceVideo> {
    let seq = point_track_sequence(person, order, feature_vertices, frame_count, 0.0, 0)?;
    let mut frames = Vec::with_capacity(frame_count);
    for (t, (face, cam)) in seq.truth.iter().zip(&seq.cameras).enumerate() {
        frames.push(
            render_face_frame(
                face,
                triangles,
                rest,
                cam,
                params,
                params.seed ^ (t as u64 + 1),
            )
            .at(Context::Frame(t))?,
        );
    }
    skin_core::check::non_negative("feature_noise_px", params.feature_noise_px)?;
    let noise =
        Normal::new(0.0, params.feature_noise_px.max(1e-300)).map_err(|e| Error::InvalidParam {
            name: "feature_noise_px",
            reason: e.to_string(),
        })?;
    let mut rng = ChaCha8Rng::seed_from_u64(params.seed.wrapping_add(1000));
    let pixels = seq.frames[0]
        .iter()
        .map(|p| {
            if params.feature_noise_px > 0.0 {
                [p[0] + noise.sample(&mut rng), p[1] + noise.sample(&mut rng)]
            } else {
                *p
            }
        })
        .collect();
    Ok(FaceVideo {
        frames,
        truth: seq.truth,
        cameras: seq.cameras,
        features: FeaturePoints {
            vertices: feature_vertices.to_vec(),
            pixels,
        },
        background: BACKGROUND,
    })
}
