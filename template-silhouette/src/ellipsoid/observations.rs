//! One frame's observations of the ellipsoid fit (Fua et al. §5): attractor points (Eq. 9),
//! tracked markers (§5.2) and silhouette rays (§5.3), and their checks.

use skin_core::check;
use skin_core::math::DVec3;

use super::model::EllipsoidModel;
use crate::error::{Error, Result};
use crate::silhouette_constraints::ContourRay;

/// A tracked marker of one frame (§2.4, §5.2): a skin point on a known bone, missing when the
/// tracker lost it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarkerObservation {
    /// Index into [`EllipsoidModel::bones`].
    pub bone: usize,
    /// Triangulated position, world metres; `None` when not seen.
    pub position: Option<DVec3>,
}

/// One frame's observations for [`fit_ellipsoids`](crate::fit_ellipsoids).
#[derive(Debug, Clone, Default)]
pub struct EllipsoidObservations {
    /// 3D attractor points (stereo, visual-hull samples), world metres (Eq. 9).
    pub points: Vec<DVec3>,
    /// Tracked markers: high-weight attractors on their bone.
    pub markers: Vec<MarkerObservation>,
    /// Silhouette contour rays ([`crate::contour_rays`]), tangent to the body (Eq. 11–17).
    pub rays: Vec<ContourRay>,
}

/// The markers seen (bone, position) after checking every observation is finite and every
/// marker's bone exists.
pub(super) fn check_observations(
    model: &EllipsoidModel,
    obs: &EllipsoidObservations,
) -> Result<Vec<(usize, DVec3)>> {
    for p in &obs.points {
        if !p.is_finite() {
            return Err(Error::NonFinite {
                what: "attractor points (remove NaN or infinite points)",
            });
        }
    }
    for r in &obs.rays {
        if !(r.origin.is_finite() && r.direction.is_finite()) {
            return Err(Error::NonFinite {
                what: "contour rays (remove rays with a NaN or infinite origin or direction)",
            });
        }
    }
    let mut markers = Vec::new();
    for m in &obs.markers {
        check::index("marker bone", m.bone, model.bones.len())?;
        if let Some(x) = m.position {
            if !x.is_finite() {
                return Err(Error::NonFinite {
                    what: "marker positions (give None for a marker not seen)",
                });
            }
            markers.push((m.bone, x));
        }
    }
    Ok(markers)
}
