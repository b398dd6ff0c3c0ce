//! The silhouette error of a reconstruction (Sand, McMillan and Popović 2003 §6.2; thesis
//! §6.1).
//!
//! The method is documented on [`SilhouetteScorer`]; the module is private and
//! everything public is re-exported at the crate root.

use serde::{Deserialize, Serialize};
use skin_core::camera::Camera;
use skin_core::check;
use skin_core::image::Mask;
use skin_core::mesh::TriMesh;
use skin_core::raster::{Buffers, Rasterizer, RenderParams};

use crate::{Context, Error, Result, ResultExt};

/// Parameters of the silhouette error.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SilhouetteErrorParams {
    /// Half-width of the comparison band around the predicted silhouette boundary, pixels (see
    /// [`Mask::boundary_band`]). The paper says only "pixels near the projected silhouette
    /// boundary" (§6.2); 3 px covers the typical needle-length errors of a few millimetres to
    /// a centimetre at the thesis's 640×480 resolution and ≈3 m camera distance (≈ 2–3 mm per
    /// pixel), while keeping far unmodelled geometry (head, hands) out. Must be finite and ≥ 0.
    /// Default: 3.
    pub band_radius_px: f64,
}

impl Default for SilhouetteErrorParams {
    fn default() -> Self {
        Self {
            band_radius_px: 3.0,
        }
    }
}

/// Silhouette error of one frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrameSilhouetteError {
    /// Mismatched band pixels per camera.
    pub mismatched_px: Vec<usize>,
    /// Band pixels per camera (0 where the prediction is not visible: that camera is skipped).
    pub band_px: Vec<usize>,
    /// Pooled error `Σ mismatched / Σ band` in [0, 1].
    pub error: f64,
}

/// Silhouette error of a sequence of frames.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SilhouetteError {
    /// One entry per frame.
    pub frames: Vec<FrameSilhouetteError>,
    /// Mean of the frame errors (§6.2: normalised by the number of frames).
    pub mean: f64,
}

/// Renders predicted bodies and scores them against observed masks (§6.2). Build once per
/// camera set (the rasterisers precompute their pixel rays), score many frames.
///
/// The silhouette error of a reconstruction (Sand, McMillan and Popović 2003 §6.2; thesis
/// §6.1).
///
/// "We measure the silhouette matching error by comparing the segmented video images to a
/// projection of the reconstructed geometry. To reduce the effect of unmodeled geometry (such
/// as the head), we consider only pixels near the projected silhouette boundary. We define the
/// silhouette error … to be the fraction of pixels for which the predicted and observed
/// silhouette do not match" (§6.2).
///
/// Here the predicted body mesh is rendered mask-only by one
/// [`skin_core::raster::Rasterizer`] per camera; the comparison region is
/// [`Mask::boundary_band`] of the *predicted* silhouette (as in the paper: unmodelled observed
/// geometry away from the predicted boundary is ignored), and the error of a frame is the
/// pooled fraction `Σ_cameras mismatched / Σ_cameras band pixels`. The sequence error is the
/// mean over frames ("we normalize the error value by dividing by the number of frames").
///
/// Any closed, outward mesh of the body works. Since the silhouette of a union of solids is the
/// union of their silhouettes, [`crate::merged_mesh`] (overlapping primitive shells)
/// gives the same masks as [`crate::union_mesh`] at a fraction of the cost.
#[derive(Clone)]
pub struct SilhouetteScorer {
    rasterizers: Vec<Rasterizer>,
    params: SilhouetteErrorParams,
}

impl SilhouetteScorer {
    /// A scorer for `cameras`.
    ///
    /// # Errors
    /// [`Error::Empty`] without cameras; an invalid-parameter [`Error::Core`] for a negative
    /// or non-finite band radius.
    pub fn new(cameras: &[Camera], params: SilhouetteErrorParams) -> Result<Self> {
        if cameras.is_empty() {
            return Err(Error::Empty { what: "cameras" });
        }
        check::non_negative("band_radius_px", params.band_radius_px)?;
        Ok(Self {
            rasterizers: cameras.iter().map(Rasterizer::new).collect(),
            params,
        })
    }

    /// Number of cameras.
    pub fn camera_count(&self) -> usize {
        self.rasterizers.len()
    }

    /// The predicted silhouette of `mesh` in camera `c` (empty mask if it is not visible).
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`] for an unknown camera; rasteriser errors (empty mesh...).
    pub fn predicted_mask(&self, mesh: &TriMesh, c: usize) -> Result<Mask> {
        let r = self.rasterizers.get(c).ok_or(Error::IndexOutOfRange {
            what: "camera",
            index: c,
            len: self.rasterizers.len(),
        })?;
        let params = RenderParams::default()
            .with_buffers(Buffers::MASK_ONLY)
            .with_allow_empty(true);
        Ok(r.render(mesh, &params)?.silhouette())
    }

    /// The silhouette error of one frame: `mesh` against one observed mask per camera.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] for a wrong number of masks; [`Error::Empty`] if the prediction
    /// is visible in no camera; in [`Error::At`] with the [`Context::Camera`]:
    /// [`Error::SizeMismatch`] for a mask of the wrong size, rasteriser errors.
    pub fn frame_error(&self, mesh: &TriMesh, observed: &[Mask]) -> Result<FrameSilhouetteError> {
        if observed.len() != self.rasterizers.len() {
            return Err(Error::SizeMismatch {
                what: "observed masks (one per camera)",
                expected: self.rasterizers.len(),
                got: observed.len(),
            });
        }
        let mut mismatched_px = Vec::with_capacity(observed.len());
        let mut band_px = Vec::with_capacity(observed.len());
        for (c, obs) in observed.iter().enumerate() {
            let (mismatched, band) = self.camera_error(mesh, c, obs).at(Context::Camera(c))?;
            mismatched_px.push(mismatched);
            band_px.push(band);
        }
        let total: usize = band_px.iter().sum();
        if total == 0 {
            return Err(Error::Empty {
                what: "predicted silhouette band (body visible in no camera)",
            });
        }
        let error = mismatched_px.iter().sum::<usize>() as f64 / total as f64;
        Ok(FrameSilhouetteError {
            mismatched_px,
            band_px,
            error,
        })
    }

    /// Mismatched and band pixels of `mesh` against `obs` in camera `c` (the body of
    /// [`Self::frame_error`]'s loop).
    fn camera_error(&self, mesh: &TriMesh, c: usize, obs: &Mask) -> Result<(usize, usize)> {
        let pred = self.predicted_mask(mesh, c)?;
        if pred.dimensions() != obs.dimensions() {
            return Err(Error::SizeMismatch {
                what: "observed mask pixels vs camera image",
                expected: pred.pixel_count(),
                got: obs.pixel_count(),
            });
        }
        let band = pred.boundary_band(self.params.band_radius_px)?;
        Ok((pred.xor(obs)?.and(&band)?.count(), band.count()))
    }

    /// The silhouette error of a sequence: `meshes[f]` against `observed[f]` (one mask per
    /// camera), and the mean over frames.
    ///
    /// # Errors
    /// [`Error::Empty`] without frames; [`Error::SizeMismatch`] if the lists differ in
    /// length; errors of [`Self::frame_error`] in [`Error::At`] with the [`Context::Frame`].
    pub fn sequence_error(
        &self,
        meshes: &[TriMesh],
        observed: &[Vec<Mask>],
    ) -> Result<SilhouetteError> {
        if meshes.is_empty() {
            return Err(Error::Empty { what: "frames" });
        }
        if meshes.len() != observed.len() {
            return Err(Error::SizeMismatch {
                what: "observed frames vs predicted meshes",
                expected: meshes.len(),
                got: observed.len(),
            });
        }
        let frames = meshes
            .iter()
            .zip(observed)
            .enumerate()
            .map(|(f, (m, o))| self.frame_error(m, o).at(Context::Frame(f)))
            .collect::<Result<Vec<_>>>()?;
        let mean = frames.iter().map(|f| f.error).sum::<f64>() / frames.len() as f64;
        Ok(SilhouetteError { frames, mean })
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use skin_core::camera::Intrinsics;
    use skin_core::math::DVec3;
    use skin_core::mesh::{marching_tetrahedra, ScalarGrid};

    /// Two small cameras looking at the origin from the front and the side.
    pub(crate) fn cameras() -> Vec<Camera> {
        let k = Intrinsics::from_horizontal_fov(0.6, 64, 48).unwrap();
        [DVec3::new(0.0, 0.0, 3.0), DVec3::new(3.0, 0.0, 0.0)]
            .iter()
            .map(|&eye| Camera::look_at(k, eye, DVec3::ZERO, DVec3::Y).unwrap())
            .collect()
    }

    fn sphere(r: f64) -> TriMesh {
        let g = ScalarGrid::sample(DVec3::splat(-0.6), 0.05, [25; 3], |p| p.length() - r).unwrap();
        marching_tetrahedra(&g, 0.0).unwrap()
    }

    #[test]
    fn error_is_zero_for_the_truth_and_grows_with_the_misfit() {
        let s = SilhouetteScorer::new(&cameras(), SilhouetteErrorParams::default()).unwrap();
        let truth = sphere(0.4);
        let obs: Vec<Mask> = (0..2)
            .map(|c| s.predicted_mask(&truth, c).unwrap())
            .collect();
        assert!(obs.iter().all(|m| m.count() > 100));
        let e0 = s.frame_error(&truth, &obs).unwrap();
        assert_eq!(e0.error, 0.0);
        let e1 = s.frame_error(&sphere(0.37), &obs).unwrap().error;
        let e2 = s.frame_error(&sphere(0.3), &obs).unwrap().error;
        assert!(e1 > 0.0 && e2 > e1 && e2 <= 1.0, "{e1} {e2}");
        let seq = s
            .sequence_error(&[truth, sphere(0.3)], &[obs.clone(), obs])
            .unwrap();
        assert!((seq.mean - e2 / 2.0).abs() < 1e-12);
    }

    #[test]
    fn bad_input_is_rejected() {
        let cams = cameras();
        assert!(SilhouetteScorer::new(&[], SilhouetteErrorParams::default()).is_err());
        let bad = SilhouetteErrorParams {
            band_radius_px: f64::NAN,
        };
        assert_eq!(
            SilhouetteScorer::new(&cams, bad)
                .err()
                .and_then(|e| e.invalid_param_name()),
            Some("band_radius_px")
        );
        let s = SilhouetteScorer::new(&cams, SilhouetteErrorParams::default()).unwrap();
        let m = sphere(0.4);
        let obs = vec![Mask::new(64, 48); 2];
        assert!(matches!(
            s.frame_error(&m, &obs[..1]),
            Err(Error::SizeMismatch { .. })
        ));
        let small = vec![Mask::new(10, 10); 2];
        let e = s.frame_error(&m, &small).unwrap_err();
        assert_eq!(e.contexts(), vec![Context::Camera(0)]);
        assert!(matches!(e.root(), Error::SizeMismatch { .. }));
        assert!(matches!(
            s.predicted_mask(&m, 5),
            Err(Error::IndexOutOfRange {
                index: 5,
                len: 2,
                ..
            })
        ));
        // A body outside every view has no band.
        let far = TriMesh::new(
            m.vertices
                .iter()
                .map(|v| *v + DVec3::new(0.0, 50.0, 0.0))
                .collect(),
            m.faces.clone(),
        )
        .unwrap();
        assert!(matches!(
            s.frame_error(&far, &obs),
            Err(Error::Empty { .. })
        ));
        assert!(matches!(
            s.sequence_error(&[], &[]),
            Err(Error::Empty { .. })
        ));
        assert!(matches!(
            s.sequence_error(&[m], &[]),
            Err(Error::SizeMismatch { .. })
        ));
    }
}
