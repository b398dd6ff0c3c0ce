//! A pair of views matched plane by plane: both views set up, the planes in parallel, the
//! matches gathered per pixel.

use rayon::prelude::*;
use skin_core::image::Mask;
use skin_core::math::{DVec2, DVec3};

use crate::integrate::IntegrationParams;
use crate::{DepthMap, Error, PolygonalHull, Result};

use super::epipolar::Prepared;
use super::mesh::{points_of, world_rays};
use super::params::MatchingParams;
use super::plane::{match_plane, PlaneResult};
use super::views::{MatchStats, MatchView, PairMatches, ViewMatches};

/// Per-pixel path depth ranges (min, max along the ray; `NaN` where no path match).
pub(super) type PathRanges = Vec<(f64, f64)>;

/// [`match_pair`] after its checks, with the coarse intervals of coarse-to-fine matching and,
/// when the caller has them, the two cameras' [`crate::integrate::camera_rays`]; also returns
/// each view's per-pixel path depth ranges.
pub(super) fn match_views(
    left: &MatchView<'_>,
    right: &MatchView<'_>,
    hull: Option<&PolygonalHull>,
    params: &MatchingParams,
    narrow: Option<(PathRanges, PathRanges)>,
    camera_rays: Option<[&[DVec3]; 2]>,
) -> Result<(PairMatches, (PathRanges, PathRanges))> {
    let jump = IntegrationParams::jump_threshold_m(params.jump_m, left.camera.intrinsics.width);
    // Surfaces are meshed without bridging jumps of a few matching thresholds.
    let mesh_jump = 4.0 * jump;
    // Per pair, once per camera: the world rays and the surface points (each side's set-up
    // needs both views').
    let [own_l, own_r] = camera_rays.map_or([None, None], |r| r.map(Some));
    let (rays_l, rays_r) = rayon::join(
        || world_rays(left.camera, own_l),
        || world_rays(right.camera, own_r),
    );
    let (rays_l, rays_r) = (rays_l?, rays_r?);
    let points_l = points_of(left.camera, left.surface, &rays_l);
    let points_r = points_of(right.camera, right.surface, &rays_r);
    let (pl, pr) = rayon::join(
        || {
            Prepared::new(
                *left,
                &rays_l,
                points_l.clone(),
                (right, &points_r),
                mesh_jump,
            )
        },
        || {
            Prepared::new(
                *right,
                &rays_r,
                points_r.clone(),
                (left, &points_l),
                mesh_jump,
            )
        },
    );
    let (mut pl, mut pr) = (pl?, pr?);
    if let Some((nl, nr)) = narrow {
        (pl.narrow, pr.narrow) = (Some(nl), Some(nr));
    }
    let baseline = pr.centre - pl.centre;
    if baseline.length() < 1e-9 {
        return Err(Error::InvalidParam {
            name: "right",
            reason: "the two cameras share a centre (no baseline); match views of cameras at \
                     different positions"
                .into(),
        });
    }
    let half = (params.window_px / 2) as i64;
    let cx = f64::from(pl.width) / 2.0;
    let results: Vec<PlaneResult> = (0..pl.height)
        .into_par_iter()
        .map(|row| {
            let Ok(ray) = left.camera.ray(DVec2::new(cx, f64::from(row))) else {
                return PlaneResult::default();
            };
            let m = baseline.cross(ray.direction);
            if m.length() < 1e-12 {
                return PlaneResult::default();
            }
            let m = m.normalize();
            let (ll, lr) = (pl.line(m, baseline), pr.line(m, baseline));
            match_plane(&pl, &pr, &ll, &lr, hull, params, half, jump)
        })
        .collect();
    let (w, h) = (pl.width, pl.height);
    let mut sums = (
        vec![(0.0, 0usize); pl.rays.len()],
        vec![(0.0, 0usize); pr.rays.len()],
    );
    let mut breaks = (vec![false; pl.rays.len()], vec![false; pr.rays.len()]);
    let nan = (f64::NAN, f64::NAN);
    let mut ranges = (vec![nan; pl.rays.len()], vec![nan; pr.rays.len()]);
    let mut stats = MatchStats::default();
    for r in &results {
        for &(a, b, za, zb) in &r.path {
            for (range, z) in [(&mut ranges.0[a], za), (&mut ranges.1[b], zb)] {
                *range = if range.0.is_nan() {
                    (z, z)
                } else {
                    (range.0.min(z), range.1.max(z))
                };
            }
        }
        if r.evaluated > 0 {
            stats.planes += 1;
        }
        stats.cells_evaluated += r.evaluated;
        stats.matches += r.path_matches;
        stats.good_matches += r.matches.len();
        stats.discontinuities += r.left_breaks.len() / 2;
        for &(a, b, za, zb) in &r.matches {
            sums.0[a].0 += za;
            sums.0[a].1 += 1;
            sums.1[b].0 += zb;
            sums.1[b].1 += 1;
        }
        for &a in &r.left_breaks {
            breaks.0[a] = true;
        }
        for &b in &r.right_breaks {
            breaks.1[b] = true;
        }
    }
    let target = |s: &[(f64, usize)]| -> Vec<f64> {
        s.iter()
            .map(|&(sum, n)| if n == 0 { f64::NAN } else { sum / n as f64 })
            .collect()
    };
    let (wr, hr) = (pr.width, pr.height);
    let matches = PairMatches {
        left: ViewMatches {
            target: DepthMap::new(w, h, target(&sums.0))?,
            breaks: Mask::from_bools(w, h, &breaks.0)?,
        },
        right: ViewMatches {
            target: DepthMap::new(wr, hr, target(&sums.1))?,
            breaks: Mask::from_bools(wr, hr, &breaks.1)?,
        },
        stats,
    };
    Ok((matches, ranges))
}
