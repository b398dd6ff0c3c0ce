//! Accumulation of needle-length observations from silhouettes (Sand 2003 §4.3).
//!
//! The method is documented on [`Observer`]; the module is private and
//! everything public is re-exported at the crate root.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use skin_core::camera::Camera;
use skin_core::image::Mask;
use skin_core::math::{DVec2, DVec3};
use skin_core::skeleton::{ForwardKinematics, Skeleton};

use crate::error::{Context, Error, Result, ResultExt};
use crate::primitive::NeedleBody;
use crate::store::ObservationStore;

impl ObserveParams {
    /// Default of [`ObserveParams::min_ray_angle_deg`].
    pub const DEFAULT_MIN_RAY_ANGLE_DEG: f64 = 60.0;

    /// Default of [`ObserveParams::max_knot_spacing_px`].
    pub const DEFAULT_MAX_KNOT_SPACING_PX: f64 = 8.0;
}

/// Knobs of the silhouette walk.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ObserveParams {
    /// Needles making an angle below this with the viewing ray through their origin (i.e.
    /// nearly perpendicular to the image plane) are discarded, degrees. Sand §4.3 discards
    /// them ("nearly perpendicular to the image") without giving a threshold.
    ///
    /// Why 60°: a needle at angle `α` to the viewing ray, radial on a round limb of radius
    /// `r`, meets the silhouette at `r / sin α`, so its observation overestimates by
    /// `r (1/sin α − 1)`: 286 % at 15°, 41 % at 45°, 15 % at 60°. The robust minimum (§5.3)
    /// only removes that bias if enough near-perpendicular views survive among a needle's
    /// nearest observations; on the studio's 3-minute turning range of motion, 60° lowered
    /// the median error of both the static and the pose-dependent model by about 15 %
    /// against 15° (`docs/needle-model.md`). It also bounds the pixel-to-metre amplification
    /// `1 / sin α` of silhouette errors to 1.15. Default: 60°.
    pub min_ray_angle_deg: f64,
    /// With radial distortion, the needle's image is followed as a polyline of projected knots
    /// at most this far apart, px (the chord error of first-order distortion over 8 px is far
    /// below 0.01 px). Ignored for distortion-free cameras (one exact segment). Default: 8 px.
    pub max_knot_spacing_px: f64,
}

impl Default for ObserveParams {
    fn default() -> Self {
        Self {
            min_ray_angle_deg: ObserveParams::DEFAULT_MIN_RAY_ANGLE_DEG,
            max_knot_spacing_px: ObserveParams::DEFAULT_MAX_KNOT_SPACING_PX,
        }
    }
}

impl ObserveParams {
    fn validate(&self) -> Result<()> {
        if !(self.min_ray_angle_deg.is_finite() && (0.0..90.0).contains(&self.min_ray_angle_deg)) {
            return Err(Error::InvalidParam {
                name: "min_ray_angle_deg",
                reason: format!("must be in [0, 90), got {}", self.min_ray_angle_deg),
            });
        }
        if !(self.max_knot_spacing_px.is_finite() && self.max_knot_spacing_px >= 0.5) {
            return Err(Error::InvalidParam {
                name: "max_knot_spacing_px",
                reason: format!("must be ≥ 0.5, got {}", self.max_knot_spacing_px),
            });
        }
        Ok(())
    }
}

/// Why a walk produced no observation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Discard {
    /// Still inside the silhouette at the maximum length.
    TooLong,
    /// Needle nearly parallel to the viewing ray.
    AlongRay,
    /// The origin projects onto background (or off the image).
    OriginOutside,
    /// The path left the image while inside the silhouette.
    LeftImage,
    /// Origin or end behind the camera.
    BehindCamera,
}

/// Outcome of one needle walk.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum Walk {
    /// The needle leaves the silhouette.
    Exit {
        /// Length from the needle origin to the silhouette exit, m (an upper bound of the
        /// true length, §4.3).
        length_m: f64,
        /// Metres along the needle per pixel along its image at the exit (to express errors
        /// in pixels).
        m_per_px: f64,
    },
    /// No observation.
    Discarded(Discard),
}

/// Counts of walks by outcome.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct ObserveStats {
    /// Needle walks attempted (needles × cameras × frames).
    pub walks: u64,
    /// Observations kept.
    pub accepted: u64,
    /// Discarded: beyond the maximum length.
    pub too_long: u64,
    /// Discarded: nearly parallel to the viewing ray.
    pub along_ray: u64,
    /// Discarded: origin on background or off the image.
    pub origin_outside: u64,
    /// Discarded: path left the image inside the silhouette.
    pub left_image: u64,
    /// Discarded: behind the camera.
    pub behind_camera: u64,
}

impl ObserveStats {
    fn count(&mut self, w: &Walk) {
        self.walks += 1;
        match w {
            Walk::Exit { .. } => self.accepted += 1,
            Walk::Discarded(Discard::TooLong) => self.too_long += 1,
            Walk::Discarded(Discard::AlongRay) => self.along_ray += 1,
            Walk::Discarded(Discard::OriginOutside) => self.origin_outside += 1,
            Walk::Discarded(Discard::LeftImage) => self.left_image += 1,
            Walk::Discarded(Discard::BehindCamera) => self.behind_camera += 1,
        }
    }

    fn add(&mut self, o: &ObserveStats) {
        self.walks += o.walks;
        self.accepted += o.accepted;
        self.too_long += o.too_long;
        self.along_ray += o.along_ray;
        self.origin_outside += o.origin_outside;
        self.left_image += o.left_image;
        self.behind_camera += o.behind_camera;
    }
}

/// One frame of input: the pose and one silhouette per camera (in camera order).
#[derive(Debug, Clone, Copy)]
pub struct FrameInput<'a> {
    /// Pose θ of the skeleton (synchronised to the video frame, see [`crate::estimate_sync_offset`]).
    pub theta: &'a [f64],
    /// Silhouette masks, one per camera, each of its camera's image size.
    pub masks: &'a [Mask],
}

/// Result of [`Observer::accumulate`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Accumulation {
    /// All kept observations.
    pub store: ObservationStore,
    /// Walk outcome counts.
    pub stats: ObserveStats,
}

/// Walks needles of a body through silhouettes of a fixed camera set.
///
/// Accumulation of needle-length observations from silhouettes (Sand 2003 §4.3).
///
/// "The system projects each needle into each video frame to compute the needle length from
/// its intersection with the silhouette. Starting at the origin of the needle, we traverse the
/// image outward until the needle projection leaves the silhouette. If the traversal extends
/// beyond a prescribed maximum length, the measurement is discarded. [...] Based on the
/// world-space orientation of the needle, we convert the image-space measurement into a
/// world-space length" (§4.3). Each kept length is stored with the primitive's configuration
/// point (§3.3) in an [`ObservationStore`].
///
/// **Walk.** The needle from its origin `o` to `o + L_max·d` is projected; the image path is
/// traversed cell by cell (exact grid traversal, Amanatides–Woo) under the pixel convention of
/// [`skin_core::image`] (pixel `(x, y)` covers `[x−½, x+½] × [y−½, y+½]`). The exit point is
/// where the path enters the first background pixel, i.e. the boundary between the last
/// foreground and first background pixel centres — the unbiased sub-pixel estimate of the
/// silhouette edge for a mask sampled at pixel centres (error within ±½ px along the path).
/// The image fraction is mapped back to a world length by the exact inverse of the
/// perspective division along the segment (`μ = λ z_a / (z_b − λ (z_b − z_a))`). With radial
/// distortion the needle's image is a curve; it is followed as a polyline of projected knots no
/// more than [`ObserveParams::max_knot_spacing_px`] apart.
///
/// **Discarded walks** (counted in [`ObserveStats`]): the walk reaches `L_max` while still
/// inside the silhouette (§4.3; this is what happens everywhere for an all-foreground mask);
/// the needle is nearly parallel to the viewing ray ([`ObserveParams::min_ray_angle_deg`]);
/// the origin projects onto a background pixel (an empty mask, or a bone outside its
/// silhouette: the data disagree, so no bound can be read); the path leaves the image while
/// inside the silhouette (the silhouette is clipped); the needle is behind the camera.
///
/// A camera that sees no needle simply yields no observation (its walks are counted as
/// `origin_outside`/`behind_camera`); this is not an error, since in a moving capture some
/// cameras lose the performer in some frames.
///
/// Frames are processed in parallel (rayon); each frame fills its own store, and stores are
/// appended in frame order, so the result is identical for any thread count.
#[derive(Debug, Clone)]
pub struct Observer {
    body: NeedleBody,
    skeleton: Skeleton,
    cameras: Vec<Camera>,
    params: ObserveParams,
    sin_min_angle: f64,
}

impl Observer {
    /// An observer for `body` (resolved against `skeleton`) seen by `cameras`.
    ///
    /// # Errors
    /// [`Error::Empty`] without cameras; [`Error::InvalidParam`] for invalid params.
    pub fn new(
        body: NeedleBody,
        skeleton: Skeleton,
        cameras: Vec<Camera>,
        params: ObserveParams,
    ) -> Result<Self> {
        params.validate()?;
        if cameras.is_empty() {
            return Err(Error::Empty { what: "cameras" });
        }
        let sin_min_angle = params.min_ray_angle_deg.to_radians().sin();
        Ok(Self {
            body,
            skeleton,
            cameras,
            params,
            sin_min_angle,
        })
    }

    /// The body.
    pub fn body(&self) -> &NeedleBody {
        &self.body
    }

    /// The cameras.
    pub fn cameras(&self) -> &[Camera] {
        &self.cameras
    }

    /// An empty store shaped for this body.
    ///
    /// # Errors
    /// As [`ObservationStore::new`].
    pub fn empty_store(&self) -> Result<ObservationStore> {
        ObservationStore::new(&self.body.store_shapes())
    }

    fn check_masks(&self, masks: &[Mask]) -> Result<()> {
        if masks.len() != self.cameras.len() {
            return Err(Error::SizeMismatch {
                what: "masks per frame (one per camera)",
                expected: self.cameras.len(),
                got: masks.len(),
            });
        }
        for (m, c) in masks.iter().zip(&self.cameras) {
            let k = &c.intrinsics;
            if m.width() != k.width {
                return Err(Error::SizeMismatch {
                    what: "mask width vs camera image width",
                    expected: k.width as usize,
                    got: m.width() as usize,
                });
            }
            if m.height() != k.height {
                return Err(Error::SizeMismatch {
                    what: "mask height vs camera image height",
                    expected: k.height as usize,
                    got: m.height() as usize,
                });
            }
        }
        Ok(())
    }

    /// Walks every needle of the body through every camera's mask for one frame and appends
    /// the kept observations to `store` (one sample per primitive and camera that produced
    /// observations), then ends the store's frame ([`ObservationStore::end_frame`]), so
    /// samples know their frame.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] for a wrong number of masks or a mask whose size differs from
    /// its camera's image; errors of [`Skeleton::forward_kinematics`] (wrong length or
    /// non-finite θ); errors of [`ObservationStore::push_sample`] for a store of another body
    /// (in [`Error::At`] with the [`Context::Primitive`] and [`Context::Camera`]).
    pub fn observe_frame(
        &self,
        theta: &[f64],
        masks: &[Mask],
        store: &mut ObservationStore,
    ) -> Result<ObserveStats> {
        self.check_masks(masks)?;
        let fk = self.skeleton.forward_kinematics(theta)?;
        let stats = self.observe_fk(&fk, masks, store)?;
        store.end_frame();
        Ok(stats)
    }

    fn observe_fk(
        &self,
        fk: &ForwardKinematics,
        masks: &[Mask],
        store: &mut ObservationStore,
    ) -> Result<ObserveStats> {
        let mut stats = ObserveStats::default();
        let world = fk.world_from_joint();
        let mut obs: Vec<(u16, f32)> = Vec::new();
        let mut config = Vec::new();
        for (p, prim) in self.body.primitives.iter().enumerate() {
            config.resize(prim.config.dim(), 0.0);
            prim.config
                .point_into(fk, &mut config)
                .at(Context::Primitive(p))?;
            let t = world
                .get(prim.carrier)
                .ok_or(Error::SizeMismatch {
                    what: "forward kinematics joints",
                    expected: prim.carrier + 1,
                    got: world.len(),
                })
                .at(Context::Primitive(p))?;
            for (c, (cam, mask)) in self.cameras.iter().zip(masks).enumerate() {
                obs.clear();
                for j in 0..prim.needle_count() {
                    let (o, d) = prim.needle_world(t, j);
                    let w = self.walk(cam, mask, o, d, prim.max_length_m);
                    stats.count(&w);
                    if let Walk::Exit { length_m, .. } = w {
                        // j < MAX_NEEDLES_PER_PRIMITIVE: checked by NeedleBody::new.
                        obs.push((j as u16, length_m as f32));
                    }
                }
                store
                    .push_sample(p, &config, &obs)
                    .at(Context::Camera(c))
                    .at(Context::Primitive(p))?;
            }
        }
        Ok(stats)
    }

    /// Walks all frames (in parallel over frames) into a new store; samples are in frame,
    /// then primitive, then camera order, identical for any thread count.
    ///
    /// # Errors
    /// [`Error::Empty`] for no frames; the errors of [`Observer::observe_frame`] for the first
    /// failing frame, in [`Error::At`] with its [`Context::Frame`].
    pub fn accumulate(&self, frames: &[FrameInput<'_>]) -> Result<Accumulation> {
        if frames.is_empty() {
            return Err(Error::Empty { what: "frames" });
        }
        let shapes = self.body.store_shapes();
        let parts: Vec<(ObservationStore, ObserveStats)> = frames
            .par_iter()
            .enumerate()
            .map(|(i, f)| {
                let mut st = ObservationStore::new(&shapes)?;
                let stats = self
                    .observe_frame(f.theta, f.masks, &mut st)
                    .at(Context::Frame(i))?;
                Ok((st, stats))
            })
            .collect::<Result<_>>()?;
        let mut store = ObservationStore::new(&shapes)?;
        let mut stats = ObserveStats::default();
        for (st, s) in &parts {
            store.append(st)?;
            stats.add(s);
        }
        Ok(Accumulation { store, stats })
    }

    /// Walks one needle (world origin `origin`, unit direction `dir`) through `mask` seen by
    /// `camera`, up to `max_length_m` (see [`Observer`]). Inputs are assumed valid
    /// (finite, mask of the camera's size); a non-finite projection is reported as
    /// [`Discard::BehindCamera`].
    pub fn walk(
        &self,
        camera: &Camera,
        mask: &Mask,
        origin: DVec3,
        dir: DVec3,
        max_length_m: f64,
    ) -> Walk {
        walk_needle(
            camera,
            mask,
            origin,
            dir,
            max_length_m,
            self.sin_min_angle,
            self.params.max_knot_spacing_px,
        )
    }
}

/// A projected knot of the needle polyline.
#[derive(Clone, Copy)]
struct Knot {
    px: DVec2,
    depth: f64,
    s: f64,
}

fn project_knot(camera: &Camera, origin: DVec3, dir: DVec3, s: f64) -> Option<Knot> {
    let p = camera.project_with_depth(origin + dir * s).ok()?;
    (p.pixel.is_finite() && p.depth_m.is_finite()).then_some(Knot {
        px: p.pixel,
        depth: p.depth_m,
        s,
    })
}

fn walk_needle(
    camera: &Camera,
    mask: &Mask,
    origin: DVec3,
    dir: DVec3,
    max_length_m: f64,
    sin_min_angle: f64,
    max_knot_spacing_px: f64,
) -> Walk {
    let view = origin - camera.centre();
    let view_len = view.length();
    // Also catches NaN (a non-finite needle).
    if view_len.is_nan() || view_len <= 0.0 {
        return Walk::Discarded(Discard::BehindCamera);
    }
    if dir.cross(view / view_len).length() < sin_min_angle {
        return Walk::Discarded(Discard::AlongRay);
    }
    let (Some(k0), Some(k1)) = (
        project_knot(camera, origin, dir, 0.0),
        project_knot(camera, origin, dir, max_length_m),
    ) else {
        return Walk::Discarded(Discard::BehindCamera);
    };
    // Start cell: pixel containing the origin's projection.
    let cx = (k0.px.x + 0.5).floor();
    let cy = (k0.px.y + 0.5).floor();
    if !mask.get_i64(cx as i64, cy as i64) {
        return Walk::Discarded(Discard::OriginOutside);
    }
    let mut cell = (cx as i64, cy as i64);
    let segments = if camera.distortion.k1 == 0.0 {
        1
    } else {
        // Bounded: the image length is finite and the spacing ≥ 0.5 px.
        ((k1.px - k0.px).length() / max_knot_spacing_px)
            .ceil()
            .clamp(1.0, 1e4) as usize
    };
    let (w, h) = (i64::from(mask.width()), i64::from(mask.height()));
    let mut a = k0;
    for seg in 1..=segments {
        let b = if seg == segments {
            k1
        } else {
            match project_knot(
                camera,
                origin,
                dir,
                max_length_m * seg as f64 / segments as f64,
            ) {
                Some(k) => k,
                None => return Walk::Discarded(Discard::BehindCamera),
            }
        };
        match traverse(mask, (w, h), &mut cell, a.px, b.px) {
            Traverse::Through => {}
            Traverse::LeftImage => return Walk::Discarded(Discard::LeftImage),
            Traverse::Exit(lambda) => {
                // Exact inverse of the perspective division along the segment.
                let dz = b.depth - a.depth;
                let den = b.depth - lambda * dz;
                let mu = (lambda * a.depth / den).clamp(0.0, 1.0);
                let length_m = a.s + mu * (b.s - a.s);
                let img_len = (b.px - a.px).length();
                let dmu_dlambda = a.depth * b.depth / (den * den);
                let m_per_px = if img_len > 0.0 {
                    (b.s - a.s) * dmu_dlambda / img_len
                } else {
                    f64::INFINITY
                };
                return Walk::Exit { length_m, m_per_px };
            }
        }
        a = b;
    }
    Walk::Discarded(Discard::TooLong)
}

enum Traverse {
    /// Stayed inside the silhouette to the segment end.
    Through,
    /// Entered a background pixel at this fraction of the segment.
    Exit(f64),
    /// Left the image while inside.
    LeftImage,
}

/// Grid traversal (Amanatides & Woo 1987) of the segment `p → q` starting in `cell` (which is
/// foreground); pixel `(x, y)` is the cell `[x−½, x+½] × [y−½, y+½]`. On `Through`, `cell`
/// is the cell containing `q`.
fn traverse(
    mask: &Mask,
    (w, h): (i64, i64),
    cell: &mut (i64, i64),
    p: DVec2,
    q: DVec2,
) -> Traverse {
    let d = q - p;
    let step_x: i64 = if d.x > 0.0 { 1 } else { -1 };
    let step_y: i64 = if d.y > 0.0 { 1 } else { -1 };
    // Parametric distance to the next vertical / horizontal cell boundary and between them.
    let next_boundary = |c: i64, s: i64| c as f64 + 0.5 * s as f64;
    let (mut t_max_x, t_delta_x) = if d.x != 0.0 {
        (
            (next_boundary(cell.0, step_x) - p.x) / d.x,
            (1.0 / d.x).abs(),
        )
    } else {
        (f64::INFINITY, f64::INFINITY)
    };
    let (mut t_max_y, t_delta_y) = if d.y != 0.0 {
        (
            (next_boundary(cell.1, step_y) - p.y) / d.y,
            (1.0 / d.y).abs(),
        )
    } else {
        (f64::INFINITY, f64::INFINITY)
    };
    loop {
        let t = if t_max_x < t_max_y {
            if t_max_x > 1.0 {
                return Traverse::Through;
            }
            cell.0 += step_x;
            let t = t_max_x;
            t_max_x += t_delta_x;
            t
        } else {
            if t_max_y > 1.0 {
                return Traverse::Through;
            }
            cell.1 += step_y;
            let t = t_max_y;
            t_max_y += t_delta_y;
            t
        };
        if cell.0 < 0 || cell.1 < 0 || cell.0 >= w || cell.1 >= h {
            return Traverse::LeftImage;
        }
        if !mask.get(cell.0 as u32, cell.1 as u32) {
            return Traverse::Exit(t.max(0.0));
        }
    }
}

#[cfg(test)]
pub(crate) mod tests;
