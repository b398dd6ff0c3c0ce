//! What a capture records: the rig, the frame rate, the seed and the rendering options.

use serde::{Deserialize, Serialize};

use crate::shading::{Light, LightVisibility};
use crate::TextureParams;
use skin_core::camera::{Intrinsics, Rig};
use skin_core::math::DVec3;
use skin_core::raster::{Buffers, RenderParams};
use skin_core::{Error, Result};

/// Lighting of the shaded observations: Lambertian shading ([`crate::shading::shade`])
/// of a uniform albedo, or of a texture, under a set of lights, optionally with cast shadows.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CaptureLighting {
    /// The lights, world frame (e.g. [`crate::shading::dome_lights`]).
    pub lights: Vec<Light>,
    /// Uniform linear-RGB albedo of the skin, each in `[0, 1]` (NaN rejected). Default: `[0.8, 0.6, 0.5]`
    /// (a light skin tone; any value works, the methods only need it known).
    pub albedo: [f32; 3],
    /// A non-uniform albedo instead of `albedo`: skin variation and the garment's print
    /// ([`crate::AlbedoTexture`]), evaluated at the rest-pose position of the visible
    /// point so that it moves with the skin (what optical flow and matching lock on).
    /// Default: `None` (uniform).
    #[serde(default)]
    pub texture: Option<TextureParams>,
    /// Cast shadows by per-vertex visibility ([`crate::shading::LightVisibility`],
    /// computed once per frame for the vertices any camera sees). Default: true.
    pub shadows: bool,
    /// Offset of shadow-ray origins along the normal, m. Default:
    /// [`LightVisibility::DEFAULT_SHADOW_BIAS_M`].
    pub shadow_bias_m: f64,
    /// Approximate the cast shadows with about this many light direction bins, one shadow
    /// ray per bin and vertex ([`crate::shading::LightVisibility::compute_binned`]);
    /// `None`: one ray per light (exact). Default: `None`.
    #[serde(default)]
    pub shadow_light_bins: Option<usize>,
    /// Light-stage patterns switching the lights on and off (e.g. the half-on patterns of
    /// Vlasic thesis Eq. 3.1); `None`: every light on in every frame. Default: `None`.
    #[serde(default)]
    pub patterns: Option<LightPatterns>,
}

/// Light-stage patterns: weights in `[0, ∞)` (1 = on, 0 = off) per pattern and light.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LightPatterns {
    /// `weights[p][l]`: the weight of light `l` in pattern `p`. One weight per light of the
    /// lighting, finite and non-negative; at least one pattern.
    pub weights: Vec<Vec<f32>>,
    /// How the patterns map to frames.
    pub schedule: PatternSchedule,
}

/// How [`LightPatterns`] map to the frames of a capture.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum PatternSchedule {
    /// Frame `k` is lit by pattern `k mod P` (a time-multiplexed light stage, e.g. the
    /// 8-frame cycle at 240 fps of Vlasic §3.2.2): [`super::CameraObservation::shaded`] is
    /// that pattern's image.
    Cycle,
    /// Every frame is rendered under every pattern (a static subject, calibration objects):
    /// [`super::CameraObservation::patterns`] holds one image per pattern and
    /// [`super::CameraObservation::shaded`] the first. All patterns share one visibility
    /// pass and one shading pass ([`crate::shading::shade_patterns`]).
    AllEachFrame,
}

impl CaptureLighting {
    /// Shadowed lighting with the default albedo.
    pub fn new(lights: Vec<Light>) -> Self {
        Self {
            lights,
            albedo: [0.8, 0.6, 0.5],
            texture: None,
            shadows: true,
            shadow_bias_m: LightVisibility::DEFAULT_SHADOW_BIAS_M,
            shadow_light_bins: None,
            patterns: None,
        }
    }

    /// Returns the lighting with shadows approximated by about `bins` light direction bins
    /// (`None`: exact; see [`CaptureLighting::shadow_light_bins`]).
    pub fn with_shadow_light_bins(mut self, bins: Option<usize>) -> Self {
        self.shadow_light_bins = bins;
        self
    }

    /// Returns the lighting with light-stage patterns (`None`: all lights on).
    pub fn with_patterns(mut self, patterns: Option<LightPatterns>) -> Self {
        self.patterns = patterns;
        self
    }

    /// Returns the lighting with the texture `texture` (`None`: the uniform `albedo`).
    pub fn with_texture(mut self, texture: Option<TextureParams>) -> Self {
        self.texture = texture;
        self
    }

    /// Returns the lighting with shadows on or off.
    pub fn with_shadows(mut self, shadows: bool) -> Self {
        self.shadows = shadows;
        self
    }
}

/// Sensor noise added to the shaded observations: zero-mean Gaussian per pixel and channel
/// with standard deviation `sigma` (linear radiance units), drawn from a counter-based stream
/// keyed by `(seed, frame, camera, pixel)` — so any frame or camera can be re-rendered alone
/// and gets the same noise, whatever order or thread count produced it. Background pixels get
/// noise too (a real sensor is noisy everywhere); radiance is not clamped.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PixelNoise {
    /// Standard deviation of the radiance noise per channel. Default: 0.005 (about 1 % of the
    /// dome's lit radiance ≈ 1/π · 0.8, a good machine-vision camera).
    pub sigma: f32,
}

impl Default for PixelNoise {
    fn default() -> Self {
        Self { sigma: 0.005 }
    }
}

impl CaptureSpec {
    /// Frame rate of [`CaptureSpec::new`], Hz: Vlasic thesis §2.5.1 captures "video at 1600 by
    /// 1200 resolution also at 25 FPS" with "a ring of eight cameras" (Sand et al. 2003 §6.1 record
    /// 30 frames per second).
    pub const DEFAULT_FRAME_RATE_HZ: f64 = 25.0;
}

/// Everything that defines a capture besides the performer and the motion.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CaptureSpec {
    /// The cameras. Must not be empty.
    pub rig: Rig,
    /// Frame rate of the capture, Hz; the motion is resampled to it
    /// ([`skin_core::skeleton::Motion::resample`]). Default:
    /// [`CaptureSpec::DEFAULT_FRAME_RATE_HZ`].
    pub frame_rate_hz: f64,
    /// Seed of everything random in the capture (pixel noise). Default: 0.
    pub seed: u64,
    /// Rasteriser options. The mask is always rendered (it is the observation) and the
    /// triangle buffer too when `lighting` is set (shading needs it); other buffers as
    /// requested. Default: [`RenderParams::default`] (mask, depth along the ray, normals).
    pub render: RenderParams,
    /// Lighting of the shaded observations; `None` renders no shaded images. Default: `None`.
    pub lighting: Option<CaptureLighting>,
    /// Noise on the shaded observations; ignored without `lighting`. Default: `None`.
    pub noise: Option<PixelNoise>,
}

impl CaptureSpec {
    /// A spec for `rig` with the defaults of every other field.
    pub fn new(rig: Rig) -> Self {
        Self {
            rig,
            frame_rate_hz: CaptureSpec::DEFAULT_FRAME_RATE_HZ,
            seed: 0,
            render: RenderParams::default(),
            lighting: None,
            noise: None,
        }
    }

    /// A spec that renders silhouettes only — the input of the silhouette methods (Sand 2003
    /// §4.2, Vlasic thesis §2.3) — at the speed of the mask rasteriser: no depth or normal
    /// truth buffers, and a camera that misses the performer gives an empty mask instead of an
    /// error (a limb may leave a view).
    pub fn masks_only(rig: Rig) -> Self {
        Self::new(rig).with_render(
            RenderParams::default()
                .with_buffers(Buffers::MASK_ONLY)
                .with_allow_empty(true),
        )
    }

    /// Returns the spec with the given frame rate, Hz.
    pub fn with_frame_rate_hz(mut self, hz: f64) -> Self {
        self.frame_rate_hz = hz;
        self
    }

    /// Returns the spec with the given seed.
    pub fn with_seed(mut self, seed: u64) -> Self {
        self.seed = seed;
        self
    }

    /// Returns the spec with the given render params.
    pub fn with_render(mut self, render: RenderParams) -> Self {
        self.render = render;
        self
    }

    /// Returns the spec with shaded observations under `lighting`.
    pub fn with_lighting(mut self, lighting: CaptureLighting) -> Self {
        self.lighting = Some(lighting);
        self
    }

    /// Returns the spec with pixel noise on the shaded observations.
    pub fn with_noise(mut self, noise: PixelNoise) -> Self {
        self.noise = Some(noise);
        self
    }

    /// The render params actually used: `render` with the mask (and, with lighting, the
    /// triangle buffer) switched on.
    pub fn effective_render(&self) -> RenderParams {
        let mut r = self.render;
        r.buffers.mask = true;
        if self.lighting.is_some() {
            r.buffers.triangle = true;
        }
        r
    }

    /// Checks the spec.
    ///
    /// # Errors
    /// [`Error::Empty`] for a rig without cameras or lighting without lights;
    /// [`Error::InvalidParam`] for a non-positive or non-finite frame rate, a negative or
    /// non-finite noise sigma, an albedo outside `[0, 1]`, a bad shadow bias or a negative
    /// pattern weight; [`Error::SizeMismatch`] for a pattern without one weight per light;
    /// errors of [`Light::validate`].
    pub fn validate(&self) -> Result<()> {
        if self.rig.is_empty() {
            return Err(Error::Empty {
                what: "capture rig cameras",
            });
        }
        skin_core::check::positive("frame_rate_hz", self.frame_rate_hz)?;
        if let Some(l) = &self.lighting {
            if l.lights.is_empty() {
                return Err(Error::Empty {
                    what: "capture lights",
                });
            }
            for light in &l.lights {
                light.validate()?;
            }
            if l.albedo.iter().any(|a| !(0.0..=1.0).contains(a)) {
                return Err(Error::InvalidParam {
                    name: "albedo",
                    reason: format!("each channel must be in [0, 1], got {:?}", l.albedo),
                });
            }
            skin_core::check::non_negative("shadow_bias_m", l.shadow_bias_m)?;
            if let Some(p) = &l.patterns {
                if p.weights.is_empty() {
                    return Err(Error::Empty {
                        what: "light patterns",
                    });
                }
                crate::shading::check_patterns(&p.weights, l.lights.len())?;
            }
        }
        if let Some(n) = &self.noise {
            skin_core::check::non_negative("noise sigma", f64::from(n.sigma))?;
        }
        Ok(())
    }
}

/// Radius of [`studio_ring`], m.
pub const STUDIO_RING_RADIUS_M: f64 = 3.5;
/// Height of the cameras of [`studio_ring`] above the floor, m.
pub const STUDIO_RING_HEIGHT_M: f64 = 1.1;
/// Point every camera of [`studio_ring`] looks at: the performer's mid-body (x, y, z), m.
pub const STUDIO_RING_TARGET_M: [f64; 3] = [0.0, 0.95, 0.0];
/// Horizontal field of view of [`studio_ring`], degrees.
pub const STUDIO_RING_HFOV_DEG: f64 = 55.0;

/// The studio's standard silhouette rig: `cameras` evenly spaced on a ring of radius
/// [`STUDIO_RING_RADIUS_M`] at height [`STUDIO_RING_HEIGHT_M`], looking at
/// [`STUDIO_RING_TARGET_M`] with a [`STUDIO_RING_HFOV_DEG`] horizontal field of view, images of
/// `width` × `height` px. A performer standing at the origin fills about two thirds of the
/// image height; Sand 2003 §6.1 used three such views, Vlasic §2.5.1 eight.
///
/// # Errors
/// As [`Intrinsics::from_horizontal_fov`] and [`Rig::ring`] (zero sizes or counts).
pub fn studio_ring(cameras: usize, width: u32, height: u32) -> Result<Rig> {
    let k = Intrinsics::from_horizontal_fov(STUDIO_RING_HFOV_DEG.to_radians(), width, height)?;
    Rig::ring(
        cameras,
        STUDIO_RING_RADIUS_M,
        STUDIO_RING_HEIGHT_M,
        DVec3::from_array(STUDIO_RING_TARGET_M),
        DVec3::Y,
        k,
    )
}
