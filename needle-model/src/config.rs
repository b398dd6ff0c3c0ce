//! Configuration spaces of deformable primitives (Sand 2003 §3.3, Table 3.1).
//!
//! The method is documented on [`ConfigSpace`]; the module is private and
//! everything public is re-exported at the crate root.

use serde::{Deserialize, Serialize};
use skin_core::math::DVec3;
use skin_core::skeleton::{AttachedPoint, ForwardKinematics, Skeleton};

use crate::error::{Error, Result};

/// Resolves a marker name to a point attached to a joint: a joint name (`"r_knee"`) is that
/// joint's origin; `"joint.tip"` is its end site (e.g. `"r_ankle.tip"`, the toe tip of
/// `human_skeleton`).
///
/// # Errors
/// [`Error::InvalidParam`] for an unknown joint or a `.tip` of a joint without end site.
pub fn resolve_marker(skeleton: &Skeleton, name: &str) -> Result<AttachedPoint> {
    let (joint_name, tip) = match name.strip_suffix(".tip") {
        Some(j) => (j, true),
        None => (name, false),
    };
    let joint = skeleton
        .joint_index(joint_name)
        .ok_or_else(|| Error::InvalidParam {
            name: "marker",
            reason: format!("no joint named {joint_name:?}"),
        })?;
    let offset = if tip {
        skeleton.joints()[joint]
            .end_site
            .ok_or_else(|| Error::InvalidParam {
                name: "marker",
                reason: format!("joint {joint_name:?} has no end site"),
            })?
    } else {
        DVec3::ZERO
    };
    Ok(AttachedPoint { joint, offset })
}

/// The configuration space of one primitive: marker positions in the carrier frame (§3.3).
///
/// Configuration spaces of deformable primitives (Sand 2003 §3.3, Table 3.1).
///
/// "To avoid the issues of joint-angle representation, we use marker coordinates to determine
/// the configuration space. For example, the configuration of the right thigh depends on
/// markers attached to the hip and the right calf, where the positions are expressed with
/// respect to the local coordinate frame of the thigh bone" (§3.3). A [`ConfigSpace`] is a
/// carrier joint plus a list of markers (points rigid on other bones); its configuration
/// point is the concatenation of the markers' positions in the carrier frame (3 values each,
/// metres).
///
/// Marker syntax: a joint name (`"r_knee"`) is that joint's origin; `"joint.tip"` is its end
/// site (e.g. `"r_ankle.tip"`, the toe tip of `human_skeleton`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ConfigSpace {
    /// Carrier joint index (the primitive's frame).
    pub carrier: usize,
    /// Markers, each a point on another bone.
    pub markers: Vec<AttachedPoint>,
}

impl ConfigSpace {
    /// A configuration space from marker names.
    ///
    /// # Errors
    /// [`Error::Empty`] without markers; errors of [`resolve_marker`];
    /// [`Error::IndexOutOfRange`] if `carrier` is not a joint of `skeleton`.
    pub fn new(skeleton: &Skeleton, carrier: usize, markers: &[String]) -> Result<Self> {
        if markers.is_empty() {
            return Err(Error::Empty {
                what: "configuration markers",
            });
        }
        if carrier >= skeleton.joint_count() {
            return Err(Error::IndexOutOfRange {
                what: "carrier joint",
                index: carrier,
                len: skeleton.joint_count(),
            });
        }
        let markers = markers
            .iter()
            .map(|m| resolve_marker(skeleton, m))
            .collect::<Result<Vec<_>>>()?;
        Ok(Self { carrier, markers })
    }

    /// Dimension `3 × markers`.
    pub fn dim(&self) -> usize {
        3 * self.markers.len()
    }

    /// Writes the configuration point for the pose in `fk` into `out` (length [`Self::dim`]):
    /// each marker's position in the carrier frame, metres.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if `out` has the wrong length; errors of
    /// [`ForwardKinematics::point`]; [`Error::NonFinite`] for a non-finite result.
    pub fn point_into(&self, fk: &ForwardKinematics, out: &mut [f64]) -> Result<()> {
        if out.len() != self.dim() {
            return Err(Error::SizeMismatch {
                what: "configuration point buffer",
                expected: self.dim(),
                got: out.len(),
            });
        }
        let world = fk.world_from_joint();
        let carrier = world.get(self.carrier).ok_or(Error::SizeMismatch {
            what: "forward kinematics joints",
            expected: self.carrier + 1,
            got: world.len(),
        })?;
        let carrier_from_world = carrier.inverse();
        for (m, chunk) in self.markers.iter().zip(out.chunks_exact_mut(3)) {
            let p = carrier_from_world.transform_point3(fk.point(m)?);
            chunk.copy_from_slice(&p.to_array());
        }
        if out.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite {
                what: "configuration point",
            });
        }
        Ok(())
    }

    /// The configuration point for the pose in `fk` (see [`Self::point_into`]).
    ///
    /// # Errors
    /// As [`Self::point_into`].
    pub fn point(&self, fk: &ForwardKinematics) -> Result<Vec<f64>> {
        let mut out = vec![0.0; self.dim()];
        self.point_into(fk, &mut out)?;
        Ok(out)
    }
}

// Configuration points as flat rows (`S × dim` row-major `f32`), the form the store keeps
// them in (§4.3) and prototype selection (§5.2), prototype shapes (§5.3) and the NRBF (§5.1)
// consume.

/// Largest configuration-space dimension accepted by prototype selection, prototype shapes
/// and the NRBF (Sand's Table 1 has at most 9; in much higher dimensions nearest-neighbour
/// neighbourhoods stop being local).
pub const MAX_CONFIG_DIM: usize = 16;

/// Checks a flat sample array: `dim` in `1..=MAX_CONFIG_DIM`, length a multiple of `dim`,
/// non-empty, all finite. Returns the number of samples.
pub(crate) fn check_samples(samples: &[f32], dim: usize) -> Result<usize> {
    if dim == 0 || dim > MAX_CONFIG_DIM {
        return Err(Error::InvalidParam {
            name: "dim",
            reason: format!("configuration dimension must be in 1..={MAX_CONFIG_DIM}, got {dim}"),
        });
    }
    if samples.is_empty() {
        return Err(Error::Empty {
            what: "configuration samples",
        });
    }
    if !samples.len().is_multiple_of(dim) {
        return Err(Error::SizeMismatch {
            what: "configuration samples (length must be a multiple of dim)",
            expected: samples.len().div_ceil(dim) * dim,
            got: samples.len(),
        });
    }
    if samples.iter().any(|v| !v.is_finite()) {
        return Err(Error::NonFinite {
            what: "configuration samples",
        });
    }
    Ok(samples.len() / dim)
}

/// Squared Euclidean distance of two configuration points.
#[inline]
pub(crate) fn dist2(a: &[f32], b: &[f32]) -> f32 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

/// RMS radius `s = sqrt(mean ‖x_i − x̄‖²)` of the *distinct* configuration points
/// (`S × dim` row-major), the distance unit of the NRBF kernel (§5.1) and of the tie radius
/// of prototype shapes (§5.3). Returns 1 when all points coincide (any unit works then).
///
/// Rows that are bit-identical are counted once (ours; the paper does not say how its unit
/// was computed). On a range of motion a primitive sits at rest for most frames, so over all
/// rows the mean sits at the rest pose and the RMS is the spread of a few sweeps diluted by
/// thousands of copies of one point: `W = 7` then makes a kernel far narrower than the
/// prototype spacing everywhere except at rest. The spread of the poses *visited* does not
/// depend on how long each was held, which is what a kernel width should scale with.
///
/// # Errors
/// As [`check_samples`].
pub(crate) fn config_scale(samples: &[f32], dim: usize) -> Result<f32> {
    check_samples(samples, dim)?;
    let mut seen: std::collections::HashSet<Vec<u32>> = Default::default();
    let distinct: Vec<&[f32]> = samples
        .chunks_exact(dim)
        .filter(|row| seen.insert(row.iter().map(|v| v.to_bits()).collect()))
        .collect();
    let count = distinct.len();
    let mut mean = vec![0f64; dim];
    for row in &distinct {
        for (m, &v) in mean.iter_mut().zip(row.iter()) {
            *m += v as f64;
        }
    }
    mean.iter_mut().for_each(|m| *m /= count as f64);
    let ss: f64 = distinct
        .iter()
        .map(|row| {
            row.iter()
                .zip(&mean)
                .map(|(&v, m)| (v as f64 - m).powi(2))
                .sum::<f64>()
        })
        .sum();
    let s = (ss / count as f64).sqrt() as f32;
    Ok(if s > 0.0 && s.is_finite() { s } else { 1.0 })
}

#[cfg(test)]
mod tests {
    use super::*;
    use skin_core::skeleton::{human_skeleton, HumanParams};

    #[test]
    fn forearm_config_moves_with_elbow_only() {
        let sk = human_skeleton(&HumanParams::default()).unwrap();
        let elbow = sk.joint_index("r_elbow").unwrap();
        let cs = ConfigSpace::new(&sk, elbow, &["r_shoulder".into()]).unwrap();
        let theta0 = sk.rest_pose();
        let p0 = cs.point(&sk.forward_kinematics(&theta0).unwrap()).unwrap();
        // Distance from elbow to shoulder is the upper-arm length regardless of pose.
        let upper = sk.joints()[elbow].offset.length();
        assert!((DVec3::from_slice(&p0).length() - upper).abs() < 1e-9);
        // Moving the pelvis (global motion) does not change the configuration.
        let mut th = theta0.clone();
        th[0] = 0.7;
        th[3] = 1.1;
        let p1 = cs.point(&sk.forward_kinematics(&th).unwrap()).unwrap();
        for (a, b) in p0.iter().zip(&p1) {
            assert!((a - b).abs() < 1e-9);
        }
        // Bending the elbow does.
        let d = sk.joint_dofs(elbow).start;
        let mut th = theta0;
        th[d] = 0.8;
        let p2 = cs.point(&sk.forward_kinematics(&th).unwrap()).unwrap();
        assert!(p0.iter().zip(&p2).any(|(a, b)| (a - b).abs() > 0.01));
    }

    #[test]
    fn config_scale_counts_each_configuration_once() {
        // 100 distinct 2-D rows, then the first repeated until it is 90 % of the rows.
        let distinct: Vec<f32> = (0..100)
            .flat_map(|i| [(i as f32 * 0.37).sin(), (i as f32 * 0.11).cos() * 2.0])
            .collect();
        let mut tied = distinct.clone();
        for _ in 0..900 {
            tied.extend_from_slice(&distinct[..2]);
        }
        let s = config_scale(&distinct, 2).unwrap();
        assert_eq!(config_scale(&tied, 2).unwrap(), s);
        // The plain RMS over all rows would have shrunk towards the tie's spread (zero).
        assert!(s > 0.5, "{s}");
        assert_eq!(config_scale(&[3.0, 3.0, 3.0], 1).unwrap(), 1.0);
    }

    #[test]
    fn bad_markers_and_buffers() {
        let sk = human_skeleton(&HumanParams::default()).unwrap();
        assert!(resolve_marker(&sk, "r_ankle.tip").is_ok());
        assert!(resolve_marker(&sk, "r_knee.tip").is_err());
        assert!(resolve_marker(&sk, "x").is_err());
        assert!(ConfigSpace::new(&sk, 0, &[]).is_err());
        assert!(ConfigSpace::new(&sk, 99, &["pelvis".into()]).is_err());
        let cs = ConfigSpace::new(&sk, 1, &["pelvis".into()]).unwrap();
        let fk = sk.forward_kinematics(&sk.rest_pose()).unwrap();
        assert!(cs.point_into(&fk, &mut [0.0; 2]).is_err());
    }
}
