//! One captured frame: what the cameras observe and the ground truth behind it, in the
//! library's own image types ([`Mask`] for silhouettes, `image` buffers for the rest).

use image::{ImageBuffer, LumaA, Rgb32FImage};

use crate::shading::LightVisibility;
use crate::{FineSurface, Performer, PosedFrame};
use skin_core::image::{GrayF32Image, Mask};
use skin_core::mesh::TriMesh;
use skin_core::raster::{buffer_image, RenderedView};
use skin_core::Result;

/// Triangle ids of a view: the visible face per pixel, [`skin_core::raster::NO_TRIANGLE`] on
/// background.
pub type TriangleIdImage = ImageBuffer<image::Luma<u32>, Vec<u32>>;

/// Perspective-correct barycentric weights `(λ₁, λ₂)` of face corners 1 and 2 per pixel
/// (corner 0 has `1 − λ₁ − λ₂`); zero on background.
pub type BarycentricImage = ImageBuffer<LumaA<f32>, Vec<f32>>;

/// What one camera observes in one frame: the pipeline's input.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraObservation {
    /// Index of the camera in the rig.
    pub camera: usize,
    /// Silhouette: set on the performer.
    pub mask: Mask,
    /// Shaded image (linear radiance, with the spec's noise), when the spec has lighting
    /// (under light patterns: this frame's pattern, or the first with
    /// [`super::PatternSchedule::AllEachFrame`]).
    pub shaded: Option<Rgb32FImage>,
    /// One shaded image per light pattern with [`super::PatternSchedule::AllEachFrame`];
    /// empty otherwise.
    pub patterns: Vec<Rgb32FImage>,
}

/// The ground-truth buffers of one camera view (rig order), each present when the capture's
/// render params asked for it ([`skin_core::raster::Buffers`]). Only metrics read these.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewTruth {
    /// Distance from the camera centre to the visible surface along the pixel ray, m;
    /// `+∞` on background.
    pub depth_m: Option<GrayF32Image>,
    /// Camera-frame z of the visible surface, m; `+∞` on background.
    pub camera_z_m: Option<GrayF32Image>,
    /// Unit outward surface normal in the camera frame (x right, y down, z forward); zero on
    /// background.
    pub normals_camera: Option<Rgb32FImage>,
    /// Visible face per pixel.
    pub triangle_ids: Option<TriangleIdImage>,
    /// Barycentric weights of the visible point.
    pub barycentric: Option<BarycentricImage>,
    /// Number of pixels that see the performer.
    pub covered_pixels: usize,
}

impl ViewTruth {
    /// Moves the buffers of a rendered view into image buffers (the mask is the
    /// observation's, not repeated here).
    pub(super) fn from_view(v: RenderedView) -> Result<Self> {
        // A buffer that was not rendered is empty and stays `None`.
        fn rendered<P: image::Pixel>(
            (w, h): (u32, u32),
            samples: Vec<P::Subpixel>,
            what: &'static str,
        ) -> Result<Option<ImageBuffer<P, Vec<P::Subpixel>>>> {
            (!samples.is_empty())
                .then(|| buffer_image(w, h, samples, what))
                .transpose()
        }
        let size = (v.width, v.height);
        Ok(Self {
            depth_m: rendered(size, v.depth_m, "depth buffer")?,
            camera_z_m: rendered(size, v.camera_z_m, "camera z buffer")?,
            normals_camera: rendered(size, v.normal_camera.concat(), "normal buffer")?,
            triangle_ids: rendered(size, v.triangle, "triangle id buffer")?,
            barycentric: rendered(size, v.bary.concat(), "barycentric buffer")?,
            covered_pixels: v.covered_pixels,
        })
    }
}

/// The ground truth of one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameTruth {
    /// The pose θ (one value per DOF of the performer's skeleton).
    pub theta: Vec<f64>,
    /// Joint frames, joint positions, LBS and true vertices, and the pose-driven part of the
    /// truth (world frame, m).
    pub posed: PosedFrame,
    /// The render-time refined and wrinkled surface, when the performer has wrinkles
    /// ([`Performer::fine_surface`]): then the cameras saw this mesh, and the views' triangle
    /// ids and barycentrics refer to its faces; otherwise they refer to the template's faces.
    pub fine: Option<FineSurface>,
    /// The ground-truth buffers of every camera (rig order).
    pub views: Vec<ViewTruth>,
}

impl FrameTruth {
    /// The true posed mesh (true vertices with the performer's faces).
    pub fn true_mesh(&self, performer: &Performer) -> TriMesh {
        performer.mesh(self.posed.true_vertices.clone())
    }

    /// The mesh the cameras saw: the fine surface when there is one, else the true mesh.
    pub fn rendered_mesh(&self, performer: &Performer) -> TriMesh {
        match &self.fine {
            Some(f) => f.mesh.clone(),
            None => self.true_mesh(performer),
        }
    }

    /// Distance between each true vertex and its LBS position, m (the non-skinning
    /// deformation a skinning method cannot reach).
    pub fn nonskinning_m(&self) -> Vec<f64> {
        self.posed
            .lbs_vertices
            .iter()
            .zip(&self.posed.true_vertices)
            .map(|(a, b)| a.distance(*b))
            .collect()
    }
}

/// One frame of a capture.
#[derive(Debug, Clone, PartialEq)]
pub struct CaptureFrame {
    /// Frame index in the capture (at the capture's frame rate).
    pub index: usize,
    /// Time since the first frame, s.
    pub time_s: f64,
    /// One observation per camera, rig order.
    pub observations: Vec<CameraObservation>,
    /// The ground truth.
    pub truth: FrameTruth,
    /// The per-vertex light visibility the shading used (lighting with shadows only), for
    /// analyses of the shadows (e.g. which pixels receive less than their unoccluded power).
    /// Its vertices are those of [`FrameTruth::rendered_mesh`].
    pub light_visibility: Option<LightVisibility>,
}

impl CaptureFrame {
    /// The silhouettes of every camera, rig order (the input of the silhouette methods).
    pub fn masks(&self) -> Vec<Mask> {
        self.observations.iter().map(|o| o.mask.clone()).collect()
    }
}
