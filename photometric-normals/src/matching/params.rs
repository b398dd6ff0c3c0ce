//! The knobs of pairwise matching: the four metrics, the sub-pixel refinement, the band and
//! the path's costs.

use serde::{Deserialize, Serialize};
use skin_core::check;

use crate::integrate::IntegrationParams;
use crate::{Error, Result};

/// The four matching metrics of §3.3.2.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum MatchMetric {
    /// Pixel windows of the full-on (tracking) image: traditional stereo.
    FullOnWindow,
    /// Pixel windows of the stack of the six half-on images.
    IlluminationStack,
    /// Surface patches under their optimal rigid alignment, symmetric (the thesis' best).
    #[default]
    SurfaceRigid,
    /// The illumination stacks projected onto the corresponding surface patches.
    ProjectedIllumination,
}

impl MatchMetric {
    /// All four, in the thesis' order.
    pub const ALL: [MatchMetric; 4] = [
        MatchMetric::FullOnWindow,
        MatchMetric::IlluminationStack,
        MatchMetric::SurfaceRigid,
        MatchMetric::ProjectedIllumination,
    ];

    pub(super) fn needs_images(self) -> bool {
        self != MatchMetric::SurfaceRigid
    }
}

/// Knobs of the pairwise matching.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MatchingParams {
    /// The metric. Default [`MatchMetric::SurfaceRigid`] (§3.3.2: "usually yields the least
    /// noisy surfaces").
    pub metric: MatchMetric,
    /// Window side, px (odd). Default 5 (§3.3.2: "5 × 5 pixels").
    pub window_px: usize,
    /// Half-width of the search band around each view's guide surface along its rays, m. Default
    /// 0.2 (ours; the thesis evaluates the whole grid in pass 1 and "nearby" cells in pass 2
    /// without a number). Measured: 0.1 → 0.2 in pass 1 reached the surface where the visual hull
    /// is more than 10 cm off (the Ghost's folds) and improved every pass-2 figure of the skirt at
    /// 1024² (coverage 84.98 → 86.01 %, normal deviation 14.02 → 13.28°, merged median 1.961 →
    /// 1.728 mm, p95 33.8 → 21.3 mm) for ≈ 23 % more CPU; 0.3 was no better
    /// (`docs/photometric-normals.md`, *The pass-1 band*).
    pub band_m: f64,
    /// Cost of an occluded sample, in units of the grid's median cost. Default 1 (ours).
    pub occlusion_cost: f64,
    /// Cost of entering or leaving an occlusion, in units of the grid's median cost.
    /// Default 2 (ours).
    pub discontinuity_penalty: f64,
    /// Matches costing more than this many grid medians are not used. Default 1.5 (ours).
    pub good_cost: f64,
    /// Matched depth jumps above this per pixel (m, at the thesis' width, scaled like
    /// [`IntegrationParams::jump_threshold_m`]) are discontinuities. Default 0.01 (§3.3.1).
    pub jump_m: f64,
    /// Coarse-to-fine matching (ours; the thesis evaluates the whole band at full
    /// resolution). The pair is first matched at half resolution (cameras, surfaces, guides
    /// and images halved; the same band in metres); at full resolution a sample's cells are
    /// then evaluated only where its ray depth lies within [`MatchingParams::coarse_band_px`]
    /// pixel footprints of the depths the coarse lowest-cost paths give the 3 × 3 coarse
    /// pixels around it (samples without a coarse path depth keep the whole band). Criminisi's
    /// programme costs O(samples × band) per plane and the surface metric dominates it: the
    /// coarse pass costs about an eighth, and the narrow band cuts the full-resolution cells
    /// several times. Applied to images of at least 128 × 128 pixels. Default false here
    /// (the thesis's matching); pass 1 of the two-pass pipeline turns it on
    /// ([`SurfaceParams::pass1`](crate::SurfaceParams::pass1): with
    /// the ±20 cm band, at 1024² pass 2's figures stayed within 0.26 point / 0.02° and the
    /// example's CPU fell 12 %; with a ±10 cm band it cost the 1024² merged median its 2 mm
    /// goal; `docs/photometric-normals.md`, *Pass-1 speed*).
    pub coarse_to_fine: bool,
    /// Half-width of the full-resolution band around the coarse path, in pixel footprints
    /// (depth / focal length) along each ray. Default 4 (ours: a coarse pixel is two, and
    /// its match is quantised to it).
    pub coarse_band_px: f64,
    /// Sub-pixel matches (ours; standard in stereo, not in the thesis): see
    /// [`SubPixel`]. Default [`SubPixel::Off`] (the thesis: matches at whole samples).
    #[serde(default)]
    pub subpixel: SubPixel,
    /// [`SubPixel::PathFit`]: path steps each side of a match in its line fit. Default 3.
    #[serde(default = "default_subpixel_window")]
    pub subpixel_window: usize,
    /// Contour-aware surface windows (ours; beyond the thesis, whose
    /// §3.3.2 compares whole 5 × 5 windows): `Some(j)` leaves out of a surface-metric window
    /// every point whose depth along its ray differs from the window centre's by more than `j`
    /// per pixel of (Chebyshev) distance from the centre (m at the thesis's width, scaled like
    /// [`IntegrationParams::jump_threshold_m`]), in both windows of a comparison (the view's
    /// own surface and the other surface rendered into it), so each window keeps only its
    /// centre's side of an occluding contour. Why: at a contour a whole window straddles
    /// the foreground and the background, and the background part differs between the views
    /// (each sees a different stretch of it behind the occluder), so the cost beside every
    /// contour is wrong — stereo's "foreground fattening", cured there by adaptive windows.
    /// The metric already compares partial windows (the pairs where both points exist, ∞ if
    /// fewer than half). Only [`MatchMetric::SurfaceRigid`] uses it. Default `None` (the
    /// thesis's whole windows). `Some(0.01)` improved every pass-2 figure of the skirt at
    /// 1024² (coverage 86.01 → 86.29 %, normal deviation 13.28 → 13.19°, merged p95 21.30 →
    /// 17.58 mm) and pass 1 more, but at 256² (the integration test) pass 1's merged p95 fell
    /// to 18.9 mm and pass 2's stayed at 22.9 mm, against that test's bound of pass 1's + 1 mm,
    /// so it is not the default (docs: "Windows at occluding contours").
    #[serde(default)]
    pub contour_jump_m: Option<f64>,
}

pub(super) fn default_subpixel_window() -> usize {
    3
}

/// How a match's depth is refined below the sample spacing ([`MatchingParams::subpixel`]).
///
/// Without refinement a matched depth is one of the depths where the pixel's ray meets the
/// other view's whole-pixel rays, and Eq. 3.4 pulls the surface onto those steps. Either
/// refinement gives each view a fractional sample of the other view and interpolates the
/// matched depth linearly between the two whole samples around it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum SubPixel {
    /// Whole samples (the thesis).
    #[default]
    Off,
    /// The vertex of the parabola through the costs of the cells `(a, b − 1)`, `(a, b)`,
    /// `(a, b + 1)` for the left view's depth (`(a ± 1, b)` for the right's), within half a
    /// sample; whole where a cost is missing or the three are not convex.
    CostParabola,
    /// The lowest-cost path's own trend: a least-squares line of the right sample against the
    /// left one (and the converse) through the path's matches within
    /// [`MatchingParams::subpixel_window`] steps, not across discontinuities or occlusions,
    /// within a sample of the match.
    PathFit,
}

impl Default for MatchingParams {
    fn default() -> Self {
        Self {
            metric: MatchMetric::default(),
            window_px: 5,
            band_m: 0.2,
            occlusion_cost: 1.0,
            discontinuity_penalty: 2.0,
            good_cost: 1.5,
            jump_m: IntegrationParams::default().match_jump_m,
            coarse_to_fine: false,
            coarse_band_px: 4.0,
            subpixel: SubPixel::Off,
            subpixel_window: 3,
            contour_jump_m: None,
        }
    }
}

impl MatchingParams {
    pub(super) fn validate(&self) -> Result<()> {
        if self.window_px == 0 || self.window_px.is_multiple_of(2) {
            return Err(Error::InvalidParam {
                name: "window_px",
                reason: format!("must be odd and positive, got {}", self.window_px),
            });
        }
        check::positive("band_m", self.band_m)?;
        check::positive("occlusion_cost", self.occlusion_cost)?;
        check::non_negative("discontinuity_penalty", self.discontinuity_penalty)?;
        check::positive("good_cost", self.good_cost)?;
        check::positive("jump_m", self.jump_m)?;
        check::positive("coarse_band_px", self.coarse_band_px)?;
        if let Some(j) = self.contour_jump_m {
            check::positive("contour_jump_m", j)?;
        }
        Ok(())
    }
}
