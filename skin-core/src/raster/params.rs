//! Which buffers to render and how.

use serde::{Deserialize, Serialize};

/// The per-pixel buffers a render produces. Asking for fewer is faster: the silhouette alone
/// ([`Buffers::MASK_ONLY`]) skips the depth test entirely.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Buffers {
    /// Silhouette mask (0 background, 1 performer). Default: true.
    pub mask: bool,
    /// Distance from the camera centre to the surface along the pixel ray, m. Default: true.
    pub depth: bool,
    /// Camera-frame z of the surface point (depth along the optical axis), m. Default: false.
    pub camera_z: bool,
    /// Unit surface normal in the camera frame (x right, y down, z forward). Default: true.
    pub normal: bool,
    /// Index of the visible face and its perspective-correct barycentric weights. Default: false.
    pub triangle: bool,
}

impl Buffers {
    /// Silhouette only: the fast path with no depth test.
    pub const MASK_ONLY: Self = Self {
        mask: true,
        depth: false,
        camera_z: false,
        normal: false,
        triangle: false,
    };
    /// Every buffer.
    pub const ALL: Self = Self {
        mask: true,
        depth: true,
        camera_z: true,
        normal: true,
        triangle: true,
    };

    /// True when only the mask is requested (no depth test needed).
    pub(crate) fn mask_only(&self) -> bool {
        !(self.depth || self.camera_z || self.normal || self.triangle)
    }

    /// True when at least one buffer is requested.
    pub(crate) fn any(&self) -> bool {
        self.mask || !self.mask_only()
    }
}

impl Default for Buffers {
    /// Mask, depth along the ray and normals: what the silhouette and photometric methods use.
    fn default() -> Self {
        Self {
            mask: true,
            depth: true,
            camera_z: false,
            normal: true,
            triangle: false,
        }
    }
}

/// How surface normals are computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum NormalMode {
    /// Area-weighted vertex normals of the posed mesh, interpolated with the perspective-correct
    /// barycentrics and renormalised (Phong normals): the smooth surface a fine mesh samples.
    #[default]
    Smooth,
    /// The geometric normal of the visible face.
    Flat,
}

/// Options of [`super::Rasterizer::render`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RenderParams {
    /// Buffers to produce. Default: [`Buffers::default`] (mask, depth, normals).
    pub buffers: Buffers,
    /// Skip faces whose outward side faces away from the camera. Exact for closed,
    /// outward-oriented meshes seen from outside (the nearest hit along any ray is then a front
    /// face) and about twice as fast; turn off for open meshes whose inside can be seen.
    /// Default: true.
    pub cull_back_faces: bool,
    /// Normal computation. Default: [`NormalMode::Smooth`].
    pub normals: NormalMode,
    /// Accept a view in which no pixel is covered (returned with an empty mask). When false, such
    /// a view is an [`crate::Error::NotVisible`] — a camera that sees nothing is usually a set-up
    /// mistake. Default: false.
    pub allow_empty: bool,
}

impl Default for RenderParams {
    fn default() -> Self {
        Self {
            buffers: Buffers::default(),
            cull_back_faces: true,
            normals: NormalMode::Smooth,
            allow_empty: false,
        }
    }
}

impl RenderParams {
    /// Returns the params with the given buffers.
    pub fn with_buffers(mut self, buffers: Buffers) -> Self {
        self.buffers = buffers;
        self
    }

    /// Returns the params with back-face culling on or off.
    pub fn with_cull_back_faces(mut self, cull: bool) -> Self {
        self.cull_back_faces = cull;
        self
    }

    /// Returns the params with the given normal mode.
    pub fn with_normals(mut self, normals: NormalMode) -> Self {
        self.normals = normals;
        self
    }

    /// Returns the params accepting (or rejecting) views that see nothing.
    pub fn with_allow_empty(mut self, allow_empty: bool) -> Self {
        self.allow_empty = allow_empty;
        self
    }
}
