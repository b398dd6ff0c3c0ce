//! One captured frame: what the cameras observe and the ground truth behind it.

use crate::mesh::TriMesh;
use crate::raster::RenderedView;
use crate::studio::shading::ShadedView;
use crate::studio::{Performer, PosedFrame};

/// What one camera observes in one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraObservation {
    /// Index of the camera in the rig.
    pub camera: usize,
    /// Image width, px.
    pub width: u32,
    /// Image height, px.
    pub height: u32,
    /// Silhouette, row-major, 1 on the performer and 0 elsewhere.
    pub mask: Vec<u8>,
    /// Shaded image (linear radiance, with the spec's noise), when the spec has lighting.
    pub shaded: Option<ShadedView>,
}

/// The ground truth of one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameTruth {
    /// The pose θ (one value per DOF of the performer's skeleton).
    pub theta: Vec<f64>,
    /// Joint frames, joint positions, LBS and true vertices (world frame, m).
    pub posed: PosedFrame,
    /// The full rendered buffers of every camera (rig order): mask, depth along the ray and
    /// camera-frame normals, plus whatever else the spec's render params asked for.
    pub views: Vec<RenderedView>,
}

impl FrameTruth {
    /// The true posed mesh (true vertices with the performer's faces).
    pub fn true_mesh(&self, performer: &Performer) -> TriMesh {
        performer.mesh(self.posed.true_vertices.clone())
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
}
