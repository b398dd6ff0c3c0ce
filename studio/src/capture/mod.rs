//! The capture builder of the synthetic studio: a rig × a performer × a motion × a frame rate
//! → per-frame observations (silhouettes and, under lights, shaded images of every camera)
//! plus ground truth (pose θ, joint frames and positions, true and skinned vertices, per-pixel
//! depth and normals) — the synthetic counterpart of the multi-view captures of Vlasic thesis
//! §2.5.1 ("a ring of eight cameras looking down at the performer", 1600×1200 at 25 FPS) and
//! §3.2 (the light-stage dome), and of the silhouette video of Sand 2003 §4.
//!
//! **Streaming.** [`Capture::frames`] is an iterator: one [`CaptureFrame`] at a time, nothing
//! kept, so a long capture needs the memory of one frame. The flap of the non-skinning
//! deformation ([`crate::DeformationModel`]) has dynamics, so frame `k`'s truth
//! depends on every earlier pose: frames are produced in order, and
//! [`Capture::frames_in`] poses (without rendering) the frames before its range to carry the
//! dynamics exactly. The result of any range is therefore identical to the same frames of a
//! full run.
//!
//! **Determinism.** Cameras of a frame are rendered in parallel with rayon; each camera's
//! output depends only on the frame and its index (pixel noise is keyed by `(seed, frame,
//! camera, pixel)`, see [`PixelNoise`]), so frames are bit-identical for any thread count.
//!
//! **Checks per frame.** A camera centre inside the performer's body (parity rays through the
//! posed mesh) is an [`Error::InvalidParam`] naming the camera and frame; a camera that sees
//! none of the body is an [`Error::NotVisible`] naming them (unless
//! [`skin_core::raster::RenderParams::allow_empty`]); lights inside the body are rejected as in
//! [`crate::shading::check_lights_outside`].

mod frame;
mod noise;
mod spec;
#[cfg(test)]
mod tests;

pub use frame::{
    BarycentricImage, CameraObservation, CaptureFrame, FrameTruth, TriangleIdImage, ViewTruth,
};
pub use spec::{
    studio_ring, CaptureLighting, CaptureSpec, LightPatterns, PatternSchedule, PixelNoise,
    STUDIO_RING_HEIGHT_M, STUDIO_RING_HFOV_DEG, STUDIO_RING_RADIUS_M, STUDIO_RING_TARGET_M,
};

use rayon::prelude::*;

use crate::shading::ShadedView;
use crate::shading::{
    check_lights_outside, shade, shade_patterns, vertices_seen, Albedo, LightVisibility, Shadows,
};
use crate::{AlbedoTexture, DeformationState, Material, Performer, PosedFrame};
use skin_core::mesh::MeshQuery;
use skin_core::raster::{Rasterizer, RenderParams, RenderedView};
use skin_core::skeleton::Motion;
use skin_core::{Context, Error, Result, ResultExt};

/// A capture ready to run: the performer, its motion resampled to the capture's frame rate,
/// and one rasteriser per camera (their per-pixel rays are computed once, in [`Capture::new`]).
///
/// **Streaming.** [`Capture::frames`] is an iterator: one [`CaptureFrame`] at a time, nothing
/// kept, so a long capture needs the memory of one frame. The flap of the non-skinning
/// deformation ([`crate::DeformationModel`]) has dynamics, so frame `k`'s truth
/// depends on every earlier pose: frames are produced in order, and
/// [`Capture::frames_in`] poses (without rendering) the frames before its range to carry the
/// dynamics exactly. The result of any range is therefore identical to the same frames of a
/// full run.
///
/// **Determinism.** Cameras of a frame are rendered in parallel with rayon; each camera's
/// output depends only on the frame and its index (pixel noise is keyed by `(seed, frame,
/// camera, pixel)`, see [`PixelNoise`]), so frames are bit-identical for any thread count.
///
/// **Checks per frame.** A camera centre inside the performer's body (parity rays through the
/// posed mesh) is an [`Error::InvalidParam`] naming the camera and frame; a camera that sees
/// none of the body is an [`Error::NotVisible`] naming them (unless
/// [`skin_core::raster::RenderParams::allow_empty`]); lights inside the body are rejected as in
/// [`crate::shading::check_lights_outside`].
///
/// # Example
/// ```
/// use skin_core::camera::{Intrinsics, Rig};
/// use skin_core::math::DVec3;
/// use dynamic_shapes_studio::{
///     fast_motion, procedural_performer, Capture, CaptureSpec, FastMotionParams,
///     ProceduralBodyParams,
/// };
/// let body = ProceduralBodyParams { grid_spacing_m: 0.05, ..Default::default() };
/// let performer = procedural_performer(&body)?;
/// let motion = fast_motion(
///     &performer.skeleton,
///     &FastMotionParams { duration_s: 0.2, ..Default::default() },
/// )?;
/// let k = Intrinsics::from_horizontal_fov(0.7, 48, 64)?;
/// let rig = Rig::ring(4, 3.5, 1.0, DVec3::new(0.0, 0.9, 0.0), DVec3::Y, k)?;
/// let capture = Capture::new(&performer, &motion, CaptureSpec::new(rig).with_seed(7))?;
/// for frame in capture.frames() {
///     let frame = frame?;
///     assert_eq!(frame.observations.len(), 4);
///     assert!(!frame.observations[0].mask.is_empty());
///     assert_eq!(frame.truth.posed.true_vertices.len(), performer.vertex_count());
/// }
/// # Ok::<(), skin_core::Error>(())
/// ```
#[derive(Debug, Clone)]
pub struct Capture<'a> {
    performer: &'a Performer,
    motion: Motion,
    spec: CaptureSpec,
    render: RenderParams,
    rasterizers: Vec<Rasterizer>,
    texture: Option<AlbedoTexture>,
    /// Material of every rendered face (fine faces when the performer has wrinkles), for the
    /// texture.
    face_materials: Vec<Material>,
}

impl<'a> Capture<'a> {
    /// Prepares a capture of `performer` playing `motion` (any frame rate; resampled to
    /// `spec.frame_rate_hz`).
    ///
    /// # Errors
    /// As [`CaptureSpec::validate`]; as [`Motion::check_for`] / [`Motion::resample`] for a
    /// motion of another skeleton; [`Error::Empty`] for a motion without frames.
    pub fn new(performer: &'a Performer, motion: &Motion, spec: CaptureSpec) -> Result<Self> {
        spec.validate()?;
        motion.check_for(&performer.skeleton)?;
        if motion.frame_count() == 0 {
            return Err(Error::Empty {
                what: "motion frames",
            });
        }
        let motion = motion.resample(&performer.skeleton, 1.0 / spec.frame_rate_hz)?;
        let rasterizers = spec.rig.cameras.par_iter().map(Rasterizer::new).collect();
        let texture = spec
            .lighting
            .as_ref()
            .and_then(|l| l.texture)
            .map(AlbedoTexture::new)
            .transpose()?;
        let face_materials = match performer.wrinkles() {
            Some(w) => w
                .garment_faces()
                .iter()
                .map(|&g| if g { Material::Garment } else { Material::Skin })
                .collect(),
            None => performer.face_materials(),
        };
        Ok(Self {
            performer,
            motion,
            render: spec.effective_render(),
            spec,
            rasterizers,
            texture,
            face_materials,
        })
    }

    /// The performer.
    pub fn performer(&self) -> &Performer {
        self.performer
    }

    /// The motion at the capture's frame rate.
    pub fn motion(&self) -> &Motion {
        &self.motion
    }

    /// The spec.
    pub fn spec(&self) -> &CaptureSpec {
        &self.spec
    }

    /// The rasteriser of every camera (rig order).
    pub fn rasterizers(&self) -> &[Rasterizer] {
        &self.rasterizers
    }

    /// Number of frames.
    pub fn frame_count(&self) -> usize {
        self.motion.frame_count()
    }

    /// Every frame, in order, one at a time.
    pub fn frames(&self) -> CaptureFrames<'_, 'a> {
        self.frames_in(0..self.frame_count())
    }

    /// The frames of `range` (clipped to the capture), in order. Earlier frames are posed but
    /// not rendered, so the deformation's dynamics match a full run exactly.
    pub fn frames_in(&self, range: std::ops::Range<usize>) -> CaptureFrames<'_, 'a> {
        self.frames_stepped(range, 1)
    }

    /// Every `step`-th frame of `range` (clipped to the capture; `step` 0 counts as 1), in
    /// order: e.g. test frames spread over a motion. Every frame is posed, so the
    /// deformation's dynamics match a full run exactly; only the yielded ones are rendered.
    pub fn frames_stepped(
        &self,
        range: std::ops::Range<usize>,
        step: usize,
    ) -> CaptureFrames<'_, 'a> {
        let end = range.end.min(self.frame_count());
        CaptureFrames {
            capture: self,
            state: DeformationState::default(),
            next_pose: 0,
            next: range.start.min(end),
            end,
            step: step.max(1),
            failed: false,
        }
    }

    /// Calls `each` on every frame in order (the callback form of [`Capture::frames`]),
    /// stopping at the first error.
    ///
    /// # Errors
    /// As [`CaptureFrames`] yields; any error of `each`.
    pub fn for_each_frame(&self, mut each: impl FnMut(CaptureFrame) -> Result<()>) -> Result<()> {
        for f in self.frames() {
            each(f?)?;
        }
        Ok(())
    }

    /// Renders frame `index` from its posed surfaces (observations and per-camera truth).
    fn render_frame(&self, index: usize, posed: PosedFrame) -> Result<CaptureFrame> {
        let theta = self.motion.frame(index);
        let fine = self
            .performer
            .fine_surface(theta, &posed)
            .at(Context::Frame(index))?;
        let coarse;
        let mesh = match &fine {
            Some(f) => &f.mesh,
            None => {
                coarse = self.performer.mesh(posed.true_vertices.clone());
                &coarse
            }
        };
        // The body's search structure is built only when something needs it: lighting, or a
        // camera inside the body's bounding box (a mask-only capture from outside skips it).
        let mut query = None;
        let bounds = mesh.bounding_box()?;
        for (i, cam) in self.spec.rig.cameras.iter().enumerate() {
            let c = cam.centre();
            if c.cmpge(bounds.min).all() && c.cmple(bounds.max).all() {
                let q = match query.take() {
                    Some(q) => q,
                    None => MeshQuery::new(mesh)?,
                };
                if q.contains(c)? {
                    return Err(Error::InvalidParam {
                        name: "rig",
                        reason: format!(
                            "camera at {c} is inside the performer's body; move it outside the \
                             capture volume"
                        ),
                    })
                    .at(Context::Camera(i))
                    .at(Context::Frame(index));
                }
                query = Some(q);
            }
        }
        let views = self
            .rasterizers
            .par_iter()
            .enumerate()
            .map(|(i, r)| r.render(mesh, &self.render).at(Context::Camera(i)))
            .collect::<Result<Vec<RenderedView>>>()
            .at(Context::Frame(index))?;
        let mut light_visibility = None;
        let shaded = match &self.spec.lighting {
            None => vec![Vec::new(); views.len()],
            Some(lighting) => {
                let query = match query {
                    Some(q) => q,
                    None => MeshQuery::new(mesh)?,
                };
                check_lights_outside(&query, &lighting.lights)?;
                let vis = if lighting.shadows {
                    let refs: Vec<&RenderedView> = views.iter().collect();
                    let needed = vertices_seen(mesh, &refs)?;
                    Some(LightVisibility::compute_binned(
                        mesh,
                        &query,
                        &lighting.lights,
                        lighting.shadow_bias_m,
                        Some(&needed),
                        lighting.shadow_light_bins,
                    )?)
                } else {
                    None
                };
                let shadows = vis.as_ref().map_or(Shadows::None, Shadows::PerVertex);
                let albedo = match &self.texture {
                    None => Albedo::Uniform(lighting.albedo),
                    Some(texture) => Albedo::Textured {
                        rest_positions: match &fine {
                            Some(f) => &f.rest_positions,
                            None => &self.performer.template.vertices,
                        },
                        face_materials: &self.face_materials,
                        texture,
                    },
                };
                // Which patterns light this frame (none: every light on).
                let patterns: Option<Vec<Vec<f32>>> =
                    lighting.patterns.as_ref().map(|p| match p.schedule {
                        PatternSchedule::Cycle => {
                            vec![p.weights[index % p.weights.len()].clone()]
                        }
                        PatternSchedule::AllEachFrame => p.weights.clone(),
                    });
                let images = views
                    .par_iter()
                    .enumerate()
                    .map(|(i, v)| {
                        let mut images = match &patterns {
                            None => vec![shade(v, mesh, &lighting.lights, &albedo, &shadows)?],
                            Some(ws) => {
                                shade_patterns(v, mesh, &lighting.lights, ws, &albedo, &shadows)?
                            }
                        };
                        for (p, s) in images.iter_mut().enumerate() {
                            if let Some(n) = &self.spec.noise {
                                // Pattern `p > 0` of an every-frame schedule gets its own
                                // noise stream (as if it were another frame).
                                let key = index + p * self.frame_count();
                                noise::add(s, n, self.spec.seed, key, i);
                            }
                        }
                        images
                            .iter()
                            .map(ShadedView::to_image)
                            .collect::<Result<Vec<_>>>()
                    })
                    .collect::<Result<Vec<_>>>()?;
                light_visibility = vis;
                images
            }
        };
        let every_frame = self
            .spec
            .lighting
            .as_ref()
            .and_then(|l| l.patterns.as_ref())
            .is_some_and(|p| p.schedule == PatternSchedule::AllEachFrame);
        let observations = views
            .iter()
            .zip(shaded)
            .enumerate()
            .map(|(camera, (v, images))| CameraObservation {
                camera,
                mask: v.silhouette(),
                shaded: images.first().cloned(),
                patterns: if every_frame { images } else { Vec::new() },
            })
            .collect();
        let views = views
            .into_iter()
            .map(|mut v| {
                v.mask = Vec::new();
                ViewTruth::from_view(v)
            })
            .collect::<Result<_>>()?;
        Ok(CaptureFrame {
            index,
            time_s: index as f64 * self.motion.frame_time_s,
            observations,
            truth: FrameTruth {
                theta: theta.to_vec(),
                posed,
                fine,
                views,
            },
            light_visibility,
        })
    }
}

/// The iterator of [`Capture::frames`]: yields `Result<CaptureFrame>` in order and stops after
/// the first error.
#[derive(Debug)]
pub struct CaptureFrames<'c, 'a> {
    capture: &'c Capture<'a>,
    state: DeformationState,
    next_pose: usize,
    next: usize,
    end: usize,
    step: usize,
    failed: bool,
}

impl CaptureFrames<'_, '_> {
    fn pose_next(&mut self) -> Result<PosedFrame> {
        let c = self.capture;
        let k = self.next_pose;
        self.next_pose += 1;
        c.performer
            .pose(c.motion.frame(k), &mut self.state, c.motion.frame_time_s)
    }

    fn produce(&mut self) -> Result<CaptureFrame> {
        while self.next_pose < self.next {
            self.pose_next()?;
        }
        let posed = self.pose_next()?;
        let index = self.next;
        self.next += self.step;
        self.capture.render_frame(index, posed)
    }
}

impl Iterator for CaptureFrames<'_, '_> {
    type Item = Result<CaptureFrame>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.failed || self.next >= self.end {
            return None;
        }
        let r = self.produce();
        self.failed = r.is_err();
        Some(r)
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        let n = if self.failed {
            0
        } else {
            (self.end - self.next).div_ceil(self.step)
        };
        (0, Some(n))
    }
}
