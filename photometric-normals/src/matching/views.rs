//! What the matcher takes (a view: camera, surface, guide, images) and what it returns per
//! pair (matched depths, breaks, sizes).

use serde::{Deserialize, Serialize};
use skin_core::camera::Camera;
use skin_core::image::{GrayF32Image, Mask};

use crate::{DepthMap, Pattern, PatternImages, PATTERNS};

/// The images of one view as the image-based metrics take them: the full-on image first,
/// then the six half-on conditions in [`PATTERNS`](crate::PATTERNS) order.
pub fn matching_images(images: &PatternImages) -> Vec<GrayF32Image> {
    std::iter::once(Pattern::Full)
        .chain(PATTERNS.iter().copied().filter(|&p| p != Pattern::Full))
        .map(|p| images.image(p).clone())
        .collect()
}

/// One view as the matcher sees it.
#[derive(Debug, Clone, Copy)]
pub struct MatchView<'a> {
    /// The (undistorted) camera.
    pub camera: &'a Camera,
    /// The view's integrated surface (Eq. 3.3).
    pub surface: &'a DepthMap,
    /// The guide of the search band: the proxy in pass 2; `None` uses the surface (pass 1).
    pub guide: Option<&'a DepthMap>,
    /// Images for the image-based metrics: the full-on image first, then the six half-on
    /// images (any number ≥ 1 of the latter; [`matching_images`] makes them); `None` for the
    /// surface metric alone.
    pub images: Option<&'a [GrayF32Image]>,
}

/// What matching found for one view of a pair.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewMatches {
    /// Matched depth along each pixel ray (the good matches' triangulated points), `NaN`
    /// where the pixel has no match: the `z_i + d̄_i` of Eq. 3.4.
    pub target: DepthMap,
    /// Pixels straddling a depth discontinuity found by matching (jumps over 1 cm per pixel).
    pub breaks: Mask,
}

/// Sizes of one pair's matching.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub struct MatchStats {
    /// Epipolar planes with samples in both views.
    pub planes: usize,
    /// Grid cells evaluated (inside the band).
    pub cells_evaluated: usize,
    /// Matches on the lowest-cost paths.
    pub matches: usize,
    /// Of which good (cost within [`MatchingParams::good_cost`](crate::MatchingParams::good_cost)).
    pub good_matches: usize,
    /// Discontinuities found (matched depth jumps).
    pub discontinuities: usize,
}

/// The matches of a pair of views.
#[derive(Debug, Clone, PartialEq)]
pub struct PairMatches {
    /// For the left view.
    pub left: ViewMatches,
    /// For the right view.
    pub right: ViewMatches,
    /// Sizes.
    pub stats: MatchStats,
}
