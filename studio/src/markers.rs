//! Retro-reflective skin markers for the synthetic studio (Fua et al. §2: "retroreflective
//! points stuck on the skin"): small bright spheres attached to template vertices, offset
//! along the surface normal so that they follow the true (pose-deformed) skin, drawn into grey
//! camera images with occlusion by the body.

use ::image::{GrayImage, Luma};

use skin_core::camera::Camera;
use skin_core::check::positive;
use skin_core::image::{GrayF32Image, Mask};
use skin_core::math::{DVec2, DVec3};
use skin_core::mesh::{vertex_normals, NormalWeighting, TriMesh};
use skin_core::random::SplitMix64;
use skin_core::{Error, Result};

use super::{CaptureFrame, FrameTruth, Performer};
use skin_core::markers::{
    detect_markers, reconstruct_markers, MarkerDetectParams, TrackParams, DEFAULT_MARKER_OFFSET_M,
    DEFAULT_MARKER_RADIUS_M,
};
use skin_core::raster::{Buffers, RenderParams};
use skin_core::{Context, ResultExt};

/// Markers attached to a performer's skin: each at a template vertex plus an offset along the
/// posed vertex normal, so a marker slides with the pose-driven and dynamic deformation of the
/// true surface, not only with its bone.
#[derive(Debug, Clone, PartialEq)]
pub struct MarkerSet {
    /// Template (body) vertex of each marker.
    pub vertices: Vec<usize>,
    /// Centre offset from the skin along the outward normal, m.
    pub offset_m: f64,
    /// Sphere radius, m.
    pub radius_m: f64,
}

impl MarkerSet {
    /// `count` markers spread over the body (garment vertices excluded) by farthest-point
    /// sampling on the rest template, starting from a vertex drawn with `seed`; default radius
    /// and offset.
    ///
    /// # Errors
    /// [`Error::InvalidParam`] for `count = 0` or more markers than body vertices.
    pub fn on_performer(performer: &Performer, count: usize, seed: u64) -> Result<Self> {
        let body = performer.garment_vertices().start;
        if count == 0 || count > body {
            return Err(Error::InvalidParam {
                name: "count",
                reason: format!("need 1 ≤ count ≤ {body} body vertices, got {count}"),
            });
        }
        let v = &performer.template.vertices[..body];
        let first = (SplitMix64::new(seed).u64_at(0) % body as u64) as usize;
        let mut chosen = vec![first];
        let mut dist: Vec<f64> = v.iter().map(|p| p.distance_squared(v[first])).collect();
        while chosen.len() < count {
            let (next, _) = dist
                .iter()
                .enumerate()
                .max_by(|a, b| a.1.total_cmp(b.1))
                .unwrap_or((0, &0.0));
            chosen.push(next);
            for (d, p) in dist.iter_mut().zip(v) {
                *d = d.min(p.distance_squared(v[next]));
            }
        }
        Ok(Self {
            vertices: chosen,
            offset_m: DEFAULT_MARKER_OFFSET_M,
            radius_m: DEFAULT_MARKER_RADIUS_M,
        })
    }

    /// Number of markers.
    pub fn len(&self) -> usize {
        self.vertices.len()
    }

    /// True when there are no markers.
    pub fn is_empty(&self) -> bool {
        self.vertices.is_empty()
    }

    /// Marker centres on a posed mesh (same vertex order as the template), m.
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`] for a marker vertex outside the mesh; errors of
    /// [`vertex_normals`].
    pub fn positions_on(&self, mesh: &TriMesh) -> Result<Vec<DVec3>> {
        let normals = vertex_normals(mesh, NormalWeighting::default())?;
        self.vertices
            .iter()
            .map(|&i| {
                skin_core::check::index("marker vertex", i, mesh.vertices.len())?;
                Ok(mesh.vertices[i] + normals[i] * self.offset_m)
            })
            .collect()
    }

    /// Marker centres in a captured frame: on the true surface ([`FrameTruth::true_mesh`]), m.
    ///
    /// # Errors
    /// As [`MarkerSet::positions_on`].
    pub fn positions(&self, performer: &Performer, truth: &FrameTruth) -> Result<Vec<DVec3>> {
        self.positions_on(&truth.true_mesh(performer))
    }

    /// One captured frame of these markers through the whole optical chain of Fua et al. §2:
    /// drawn into every camera's grey frame ([`marker_base_image`] of its silhouette) with
    /// occlusion by the body, detected ([`detect_markers`]), matched across cameras and
    /// triangulated ([`reconstruct_markers`] with `max_residual_px` and `min_views`), then
    /// labelled with the nearest true marker for scoring. The capture must render the camera-z
    /// buffer (the occluder).
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] unless `cameras` has one camera per observation;
    /// [`Error::InvalidParam`] if the frame has no camera-z buffer; errors of
    /// [`MarkerSet::positions`], [`draw_markers`], [`detect_markers`] and
    /// [`reconstruct_markers`] (in [`Error::At`] naming the camera).
    #[allow(clippy::too_many_arguments)] // the chain's own knobs, each documented
    pub fn observe(
        &self,
        performer: &Performer,
        frame: &CaptureFrame,
        cameras: &[Camera],
        style: &MarkerImageStyle,
        detect: &MarkerDetectParams,
        max_residual_px: f64,
        min_views: usize,
    ) -> Result<MarkerObservation> {
        skin_core::check::same_size(
            "cameras per observation",
            frame.observations.len(),
            cameras.len(),
        )?;
        let truth = self.positions(performer, &frame.truth)?;
        let mut detections = Vec::with_capacity(cameras.len());
        let mut seen_by = vec![0usize; truth.len()];
        for (c, cam) in cameras.iter().enumerate() {
            let z =
                frame.truth.views[c]
                    .camera_z_m
                    .as_ref()
                    .ok_or_else(|| Error::InvalidParam {
                        name: "capture",
                        reason: "markers need the camera-z buffer (Buffers::camera_z) as occluder"
                            .into(),
                    })?;
            let mut img = marker_base_image(&frame.observations[c].mask, style);
            let visible = draw_markers(&mut img, cam, Some(z), &truth, self.radius_m, style)
                .at(Context::Camera(c))?;
            for (n, v) in seen_by.iter_mut().zip(&visible) {
                *n += usize::from(*v > 0.9);
            }
            let blobs = detect_markers(&img, detect).at(Context::Camera(c))?;
            detections.push(blobs.iter().map(|b| b.centre).collect::<Vec<DVec2>>());
        }
        let found = reconstruct_markers(cameras, &detections, max_residual_px, min_views)?;
        let mut points = Vec::with_capacity(found.len());
        let mut nearest_true = Vec::with_capacity(found.len());
        let mut error_m = Vec::with_capacity(found.len());
        for m in &found {
            let p = m.triangulation.point;
            let (id, d) = truth
                .iter()
                .enumerate()
                .map(|(i, t)| (i, t.distance(p)))
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .unwrap_or((usize::MAX, f64::INFINITY));
            points.push(p);
            nearest_true.push(id);
            error_m.push(d);
        }
        Ok(MarkerObservation {
            truth,
            points,
            nearest_true,
            error_m,
            seen_by,
        })
    }
}

/// One frame of markers observed by [`MarkerSet::observe`].
#[derive(Debug, Clone, PartialEq)]
pub struct MarkerObservation {
    /// True marker centres, m (marker order).
    pub truth: Vec<DVec3>,
    /// Reconstructed marker centres, m (unlabelled, as a tracker receives them).
    pub points: Vec<DVec3>,
    /// For each reconstructed point, the nearest true marker (scoring only).
    pub nearest_true: Vec<usize>,
    /// For each reconstructed point, its distance to that marker, m.
    pub error_m: Vec<f64>,
    /// For each true marker, the cameras that see at least 90 % of its image disc.
    pub seen_by: Vec<usize>,
}

/// Grey levels of a synthetic marker frame (an infrared camera: dim body, dark background,
/// saturated retro-reflective markers), 8 bit like the paper's frames. The default body and
/// background differ by less than the detector's default high-pass threshold, so silhouette
/// edges are not taken for markers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarkerImageStyle {
    /// Background grey level.
    pub background: u8,
    /// Body grey level.
    pub body: u8,
    /// Marker grey level.
    pub marker: u8,
    /// Sub-samples per pixel side for the marker's anti-aliased coverage (≥ 1).
    pub supersampling: u32,
}

impl Default for MarkerImageStyle {
    fn default() -> Self {
        Self {
            background: 30,
            body: 60,
            marker: 250,
            supersampling: 4,
        }
    }
}

/// A grey frame from a silhouette: `style.body` on the performer, `style.background` elsewhere.
pub fn marker_base_image(mask: &Mask, style: &MarkerImageStyle) -> GrayImage {
    GrayImage::from_fn(mask.width(), mask.height(), |x, y| {
        Luma([if mask.get(x, y) {
            style.body
        } else {
            style.background
        }])
    })
}

/// Draws spheres of `radius_m` at `positions` into `image` (anti-aliased discs of the projected
/// sphere's apparent radius), hidden where `occluder_camera_z_m` (camera-frame z of the body
/// per pixel, e.g. [`super::ViewTruth::camera_z_m`]; `None` = nothing occludes) is nearer than
/// the sphere's front. Returns, per marker, the visible fraction of its image disc (0 when
/// hidden, behind the camera or off the image; a marker cut by the image border counts only
/// its part inside the image).
///
/// # Errors
/// [`Error::SizeMismatch`] for an occluder image of another size than `image`;
/// [`Error::InvalidParam`] for a non-positive radius or zero supersampling;
/// [`Error::NonFinite`] for a non-finite position.
pub fn draw_markers(
    image: &mut GrayImage,
    camera: &Camera,
    occluder_camera_z_m: Option<&GrayF32Image>,
    positions: &[DVec3],
    radius_m: f64,
    style: &MarkerImageStyle,
) -> Result<Vec<f64>> {
    positive("radius_m", radius_m)?;
    if style.supersampling == 0 {
        return Err(Error::InvalidParam {
            name: "supersampling",
            reason: "must be ≥ 1".into(),
        });
    }
    let (w, h) = image.dimensions();
    if let Some(z) = occluder_camera_z_m {
        if z.dimensions() != (w, h) {
            return Err(Error::SizeMismatch {
                what: "occluder depth image pixels",
                expected: w as usize * h as usize,
                got: z.len(),
            });
        }
    }
    let k = &camera.intrinsics;
    let n = style.supersampling;
    let mut visible = vec![0.0; positions.len()];
    for (m, p) in positions.iter().enumerate() {
        skin_core::check::all_finite("marker position", [p.x, p.y, p.z].iter())?;
        let Ok(proj) = camera.project_with_depth(*p) else {
            continue; // behind the camera
        };
        if proj.depth_m <= radius_m {
            continue;
        }
        let r_px = k.fx.max(k.fy) * radius_m / proj.depth_m;
        let front_z = (proj.depth_m - radius_m) as f32;
        let c = proj.pixel;
        let x0 = (c.x - r_px - 1.0).floor().max(0.0);
        let y0 = (c.y - r_px - 1.0).floor().max(0.0);
        let x1 = (c.x + r_px + 1.0).ceil().min(f64::from(w) - 1.0);
        let y1 = (c.y + r_px + 1.0).ceil().min(f64::from(h) - 1.0);
        if x1 < x0 || y1 < y0 {
            continue;
        }
        let (mut total, mut shown) = (0.0, 0.0);
        for y in y0 as u32..=y1 as u32 {
            for x in x0 as u32..=x1 as u32 {
                let hidden = occluder_camera_z_m.is_some_and(|z| z.get_pixel(x, y).0[0] < front_z);
                let mut hits = 0u32;
                for sy in 0..n {
                    for sx in 0..n {
                        let s = DVec2::new(
                            f64::from(x) - 0.5 + (f64::from(sx) + 0.5) / f64::from(n),
                            f64::from(y) - 0.5 + (f64::from(sy) + 0.5) / f64::from(n),
                        );
                        hits += u32::from((s - c).length() < r_px);
                    }
                }
                if hits == 0 {
                    continue;
                }
                let cover = f64::from(hits) / f64::from(n * n);
                total += cover;
                if hidden {
                    continue;
                }
                shown += cover;
                let px = image.get_pixel_mut(x, y);
                let old = f64::from(px.0[0]);
                let new = old + cover * (f64::from(style.marker) - old);
                px.0[0] = new.round().clamp(0.0, 255.0) as u8;
            }
        }
        if total > 0.0 {
            visible[m] = shown / total;
        }
    }
    Ok(visible)
}

/// The markers scenario of the validation (Fua et al. §2 on the studio): 20 skin markers on
/// the procedural performer, the studio's fast motion, a ring of grey cameras; every frame goes
/// through [`MarkerSet::observe`]. The test and the example that score marker detection,
/// triangulation and tracking both run it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarkerScenario {
    /// Number of markers (farthest-point sampled, [`MarkerSet::on_performer`]).
    pub markers: usize,
    /// Cameras in a ring of radius 3 m at 1.2 m height around the performer.
    pub cameras: usize,
    /// Image width and height, px.
    pub image: (u32, u32),
    /// Length of the fast motion, s.
    pub duration_s: f64,
    /// Camera frame rate, Hz.
    pub frame_rate_hz: f64,
}

impl Default for MarkerScenario {
    /// 20 markers, four 480 × 640 cameras, 0.5 s of fast motion at 60 Hz.
    fn default() -> Self {
        Self {
            markers: 20,
            cameras: 4,
            image: (480, 640),
            duration_s: 0.5,
            frame_rate_hz: 60.0,
        }
    }
}

impl MarkerScenario {
    /// The tracker's search volumes at this scenario's frame rate: the published human limits
    /// ([`TrackParams::human`]: 40 m/s, 800 m/s², sources at
    /// [`skin_core::markers::HUMAN_MAX_SPEED_M_PER_S`]), not limits fitted to the studio's fast
    /// motion (whose markers move up to 18 m/s and accelerate up to 540 m/s², measured by the
    /// markers test).
    pub fn track_params(&self) -> TrackParams {
        TrackParams::human(self.frame_rate_hz)
    }

    /// Renders, detects and triangulates every frame (default style and detector, 1.5 px
    /// matching tolerance, three views per marker).
    ///
    /// # Errors
    /// Errors of the studio's performer, motion and capture, and of [`MarkerSet::observe`]
    /// (in [`Error::At`] naming the frame).
    pub fn observe(&self) -> Result<Vec<MarkerObservation>> {
        let performer = super::procedural_performer(&super::ProceduralBodyParams {
            grid_spacing_m: 0.03,
            ..Default::default()
        })?;
        let set = MarkerSet::on_performer(&performer, self.markers, 1)?;
        let motion = super::fast_motion(
            &performer.skeleton,
            &super::FastMotionParams {
                duration_s: self.duration_s,
                ..Default::default()
            },
        )?;
        let k =
            skin_core::camera::Intrinsics::from_horizontal_fov(0.7, self.image.0, self.image.1)?;
        let rig = skin_core::camera::Rig::ring(
            self.cameras,
            3.0,
            1.2,
            DVec3::new(0.0, 0.9, 0.0),
            DVec3::Y,
            k,
        )?;
        let spec = super::CaptureSpec::masks_only(rig)
            .with_frame_rate_hz(self.frame_rate_hz)
            .with_render(RenderParams::default().with_buffers(Buffers {
                camera_z: true,
                ..Buffers::MASK_ONLY
            }));
        let capture = super::Capture::new(&performer, &motion, spec)?;
        let cameras = capture.spec().rig.cameras.clone();
        let (style, detect) = (MarkerImageStyle::default(), MarkerDetectParams::default());
        capture
            .frames()
            .enumerate()
            .map(|(f, frame)| {
                set.observe(&performer, &frame?, &cameras, &style, &detect, 1.5, 3)
                    .at(Context::Frame(f))
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{
        fast_motion, procedural_performer, Capture, CaptureSpec, FastMotionParams,
        ProceduralBodyParams,
    };
    use skin_core::camera::{Intrinsics, Rig};
    use skin_core::markers::{detect_markers, MarkerDetectParams};
    use skin_core::raster::{Buffers, RenderParams};

    #[test]
    fn markers_follow_the_skin_and_hide_behind_the_body() {
        let performer = procedural_performer(&ProceduralBodyParams {
            grid_spacing_m: 0.04,
            ..Default::default()
        })
        .unwrap();
        let set = MarkerSet::on_performer(&performer, 20, 3).unwrap();
        assert_eq!(set.len(), 20);
        let motion = fast_motion(
            &performer.skeleton,
            &FastMotionParams {
                duration_s: 0.1,
                ramp_s: 0.05,
                ..Default::default()
            },
        )
        .unwrap();
        let k = Intrinsics::from_horizontal_fov(0.7, 240, 320).unwrap();
        let rig = Rig::ring(3, 3.0, 1.0, DVec3::new(0.0, 0.9, 0.0), DVec3::Y, k).unwrap();
        let spec = CaptureSpec::masks_only(rig).with_render(RenderParams::default().with_buffers(
            Buffers {
                camera_z: true,
                ..Buffers::MASK_ONLY
            },
        ));
        let capture = Capture::new(&performer, &motion, spec).unwrap();
        let frame = capture.frames().next().unwrap().unwrap();
        let pos = set.positions(&performer, &frame.truth).unwrap();
        // Centres sit at the offset from the true surface.
        for (p, &v) in pos.iter().zip(&set.vertices) {
            let d = p.distance(frame.truth.posed.true_vertices[v]);
            assert!((d - DEFAULT_MARKER_OFFSET_M).abs() < 1e-9);
        }
        let style = MarkerImageStyle::default();
        let (mut hidden, mut seen) = (0, 0);
        for (ci, cam) in capture.spec().rig.cameras.iter().enumerate() {
            let obs = &frame.observations[ci];
            let z = frame.truth.views[ci].camera_z_m.as_ref().unwrap();
            let mut img = marker_base_image(&obs.mask, &style);
            let drawn = draw_markers(&mut img, cam, Some(z), &pos, set.radius_m, &style).unwrap();
            let mut unoccluded = marker_base_image(&obs.mask, &style);
            let all = draw_markers(&mut unoccluded, cam, None, &pos, set.radius_m, &style).unwrap();
            hidden += all
                .iter()
                .zip(&drawn)
                .filter(|(a, d)| **a > 0.0 && **d == 0.0)
                .count();
            seen += drawn.iter().filter(|d| **d > 0.9).count();
            // Every marker with > 90 % of its disc visible is detected within a pixel of its
            // projection.
            let blobs = detect_markers(&img, &MarkerDetectParams::default()).unwrap();
            for (m, p) in pos.iter().enumerate() {
                if drawn[m] <= 0.9 {
                    continue;
                }
                let px = cam.project(*p).unwrap();
                let best = blobs
                    .iter()
                    .map(|b| (b.centre - px).length())
                    .fold(f64::INFINITY, f64::min);
                assert!(best < 0.5, "camera {ci} marker {m}: nearest blob {best} px");
            }
        }
        // Some markers face away from some camera and the body hides them.
        assert!(hidden > 0, "no marker was occluded");
        assert!(seen >= 20, "only {seen} marker views");
        // The whole chain: every reconstruction is a real marker.
        let cams = &capture.spec().rig.cameras;
        let detect = MarkerDetectParams::default();
        let observed = set
            .observe(&performer, &frame, cams, &style, &detect, 1.5, 3)
            .unwrap();
        assert!(
            observed.points.len() >= 5,
            "{} markers",
            observed.points.len()
        );
        assert!(
            observed.error_m.iter().all(|e| *e < 0.01),
            "{:?}",
            observed.error_m
        );
        assert!(matches!(
            set.observe(&performer, &frame, &cams[..2], &style, &detect, 1.5, 3),
            Err(Error::SizeMismatch { .. })
        ));
        // Without the occluder buffer the chain refuses to draw.
        let masks_only = Capture::new(
            &performer,
            &motion,
            CaptureSpec::masks_only(capture.spec().rig.clone()),
        )
        .unwrap();
        let bare = masks_only.frames().next().unwrap().unwrap();
        assert!(matches!(
            set.observe(&performer, &bare, cams, &style, &detect, 1.5, 3),
            Err(Error::InvalidParam {
                name: "capture",
                ..
            })
        ));
    }

    #[test]
    fn bad_input_is_an_error() {
        let k = Intrinsics::from_horizontal_fov(0.7, 32, 32).unwrap();
        let cam = Camera::look_at(k, DVec3::new(0.0, 0.0, -2.0), DVec3::ZERO, DVec3::Y).unwrap();
        let style = MarkerImageStyle::default();
        let mut img = GrayImage::new(32, 32);
        let nan = [DVec3::new(f64::NAN, 0.0, 0.0)];
        assert!(draw_markers(&mut img, &cam, None, &nan, 0.01, &style).is_err());
        assert!(draw_markers(&mut img, &cam, None, &[DVec3::ZERO], 0.0, &style).is_err());
        let wrong = GrayF32Image::new(8, 8);
        assert!(matches!(
            draw_markers(&mut img, &cam, Some(&wrong), &[DVec3::ZERO], 0.01, &style),
            Err(Error::SizeMismatch { .. })
        ));
        let ok = draw_markers(&mut img, &cam, None, &[DVec3::ZERO], 0.05, &style).unwrap();
        assert_eq!(ok, vec![1.0]);
    }
}
