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
///
/// ## Marker weights (ours)
///
/// Raw marker coordinates make some DOFs nearly invisible. The thigh depends on the hip and
/// the knee (§3.3, Table 3.1), but its pelvis marker sits a few centimetres from the hip's
/// flexion axis while the ankle marker swings on a 40 cm calf: over the joint ranges the
/// ankle moves ~10× more, so in the Euclidean distances of prototype selection (§5.2),
/// neighbourhoods (§5.3) and the kernel (§5.1) hip flexion barely registers and the thigh's
/// prototypes cannot tell a flexed hip from rest. Each marker `m` is therefore scaled by a
/// weight `w_m = max_n r_n / r_m`, where `r_m` is its RMS displacement in the carrier frame
/// over the sweeps of the DOFs that move it (`marker_rms_displacement`: each rotational DOF
/// through its limits, others at rest). After weighting every marker moves about as much as
/// the most mobile one, so every DOF the primitive depends on moves its configuration point
/// comparably; coordinates stay in metres of the most mobile marker. Weights are floored at
/// `r_m ≥ 10⁻³ · max r` and a marker that no DOF moves keeps weight 1. The weights are
/// computed once from the skeleton in [`ConfigSpace::new`] (a property of the body, not of
/// the training motion, so an unseen test pose is scaled the same way).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ConfigSpace {
    /// Carrier joint index (the primitive's frame).
    pub carrier: usize,
    /// Markers, each a point on another bone.
    pub markers: Vec<AttachedPoint>,
    /// Weight of each marker's coordinates (see [Marker weights](#marker-weights-ours));
    /// empty means 1 for every marker (the paper's raw coordinates).
    #[serde(default)]
    pub weights: Vec<f64>,
    /// How far the configuration point moves per radian of the joints that drive it: the
    /// median, over the rotational DOFs that move it at the rest pose, of `‖∂x/∂θ_d‖`
    /// (configuration units per radian). It converts configuration-space distances into
    /// degrees of the driving joints for the neighbourhood diagnostics
    /// ([`crate::NeighbourhoodStats::pool_radius_deg_median`]). `None` when unknown (a space
    /// built by hand, or [`Self::unweighted`], whose metric differs).
    #[serde(default)]
    pub units_per_radian: Option<f64>,
}

/// Sweep samples per DOF in [`marker_rms_displacement`].
const SWEEP_STEPS: usize = 9;
/// Range swept for a rotational DOF without limits, radians either side of rest.
const UNLIMITED_SWEEP_RAD: f64 = std::f64::consts::FRAC_PI_2;

/// RMS displacement (metres) of each marker in the carrier frame, over sweeps of every
/// rotational DOF of `skeleton` through its limits (±90° if unlimited) with the other DOFs at
/// rest, averaged over the DOFs that move the marker at all (by more than 1 µm). 0 for a
/// marker that no DOF moves.
///
/// # Errors
/// Errors of forward kinematics.
pub(crate) fn marker_rms_displacement(
    skeleton: &Skeleton,
    carrier: usize,
    markers: &[AttachedPoint],
) -> Result<Vec<f64>> {
    let rest = skeleton.rest_pose();
    let raw = ConfigSpace {
        carrier,
        markers: markers.to_vec(),
        weights: vec![],
        units_per_radian: None,
    };
    let p0 = raw.point(&skeleton.forward_kinematics(&rest)?)?;
    let mut sum = vec![0f64; markers.len()];
    let mut dofs = vec![0usize; markers.len()];
    let mut theta = rest.clone();
    let mut ms = vec![0f64; markers.len()];
    let mut moved = vec![0f64; markers.len()];
    for d in 0..skeleton.dof_count() {
        if !skeleton.is_rotation(d) {
            continue;
        }
        let (lo, hi) = match skeleton.dof(d).limits {
            Some(l) => (l.min, l.max),
            None => (rest[d] - UNLIMITED_SWEEP_RAD, rest[d] + UNLIMITED_SWEEP_RAD),
        };
        ms.iter_mut().for_each(|v| *v = 0.0);
        moved.iter_mut().for_each(|v| *v = 0.0);
        for i in 0..SWEEP_STEPS {
            theta[d] = lo + (hi - lo) * i as f64 / (SWEEP_STEPS - 1) as f64;
            let p = raw.point(&skeleton.forward_kinematics(&theta)?)?;
            for (m, (a, b)) in p.chunks_exact(3).zip(p0.chunks_exact(3)).enumerate() {
                let d2: f64 = a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum();
                ms[m] += d2 / SWEEP_STEPS as f64;
                moved[m] = moved[m].max(d2);
            }
        }
        theta[d] = rest[d];
        for m in 0..markers.len() {
            if moved[m] > 1e-12 {
                sum[m] += ms[m];
                dofs[m] += 1;
            }
        }
    }
    Ok(sum
        .iter()
        .zip(&dofs)
        .map(|(&s, &n)| if n == 0 { 0.0 } else { (s / n as f64).sqrt() })
        .collect())
}

/// Marker weights from RMS displacements: `max r / r_m`, with `r_m` floored at `10⁻³ max r`;
/// all 1 if no marker moves.
fn weights_from_rms(rms: &[f64]) -> Vec<f64> {
    let max = rms.iter().copied().fold(0.0, f64::max);
    if max <= 0.0 || !max.is_finite() {
        return vec![1.0; rms.len()];
    }
    rms.iter()
        .map(|&r| {
            if r > 0.0 {
                max / r.max(1e-3 * max)
            } else {
                1.0
            }
        })
        .collect()
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
        let weights = weights_from_rms(&marker_rms_displacement(skeleton, carrier, &markers)?);
        let mut space = Self {
            carrier,
            markers,
            weights,
            units_per_radian: None,
        };
        space.units_per_radian = space.rate_at_rest(skeleton)?;
        Ok(space)
    }

    /// The same space without marker weights: raw marker coordinates, as in the paper
    /// ([`Self::units_per_radian`] becomes unknown).
    pub fn unweighted(mut self) -> Self {
        self.weights.clear();
        self.units_per_radian = None;
        self
    }

    /// [`Self::units_per_radian`] by central differences of ±1° at the rest pose; `None` if no
    /// rotational DOF moves the configuration point.
    fn rate_at_rest(&self, skeleton: &Skeleton) -> Result<Option<f64>> {
        let h = 1f64.to_radians();
        let mut theta = skeleton.rest_pose();
        let mut rates = vec![];
        for d in (0..skeleton.dof_count()).filter(|&d| skeleton.is_rotation(d)) {
            let rest = theta[d];
            theta[d] = rest + h;
            let a = self.point(&skeleton.forward_kinematics(&theta)?)?;
            theta[d] = rest - h;
            let b = self.point(&skeleton.forward_kinematics(&theta)?)?;
            theta[d] = rest;
            let step: f64 = a.iter().zip(&b).map(|(x, y)| (x - y).powi(2)).sum();
            rates.push(step.sqrt() / (2.0 * h));
        }
        let max = rates.iter().copied().fold(0.0, f64::max);
        let mut moving: Vec<f64> = rates.into_iter().filter(|&r| r > 1e-6 * max).collect();
        if moving.is_empty() || max <= 0.0 {
            return Ok(None);
        }
        let mid = moving.len() / 2;
        Ok(Some(*moving.select_nth_unstable_by(mid, f64::total_cmp).1))
    }

    /// Dimension `3 × markers`.
    pub fn dim(&self) -> usize {
        3 * self.markers.len()
    }

    /// Writes the configuration point for the pose in `fk` into `out` (length [`Self::dim`]):
    /// each marker's position in the carrier frame times its weight (metres of the most
    /// mobile marker, see [Marker weights](#marker-weights-ours)).
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
        for (i, (m, chunk)) in self.markers.iter().zip(out.chunks_exact_mut(3)).enumerate() {
            let w = self.weights.get(i).copied().unwrap_or(1.0);
            let p = carrier_from_world.transform_point3(fk.point(m)?) * w;
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

    /// [`Self::point`] in `f32`, the precision of the store's configuration rows and the
    /// input of [`crate::NeedleModel::needle_lengths`].
    ///
    /// # Errors
    /// As [`Self::point_into`].
    pub fn point_f32(&self, fk: &ForwardKinematics) -> Result<Vec<f32>> {
        Ok(self.point(fk)?.iter().map(|&v| v as f32).collect())
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
        // One marker: weight 1. Distance from elbow to shoulder is the upper-arm length
        // regardless of pose.
        assert_eq!(cs.weights, vec![1.0]);
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

    /// Displacement of the thigh's configuration point between rest and `dof` at `deg`.
    fn thigh_move(cs: &ConfigSpace, sk: &Skeleton, dof: &str, deg: f64) -> f64 {
        let rest = sk.rest_pose();
        let p0 = cs.point(&sk.forward_kinematics(&rest).unwrap()).unwrap();
        let mut th = rest;
        th[sk.dof_index(dof).unwrap()] = deg.to_radians();
        let p = cs.point(&sk.forward_kinematics(&th).unwrap()).unwrap();
        p.iter()
            .zip(&p0)
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f64>()
            .sqrt()
    }

    #[test]
    fn thigh_sees_hip_flexion_as_much_as_knee_flexion() {
        let sk = human_skeleton(&HumanParams::default()).unwrap();
        let hip = sk.joint_index("r_hip").unwrap();
        let cs = ConfigSpace::new(&sk, hip, &["pelvis".into(), "r_ankle".into()]).unwrap();
        let raw = cs.clone().unweighted();
        let ratio = |c: &ConfigSpace| {
            thigh_move(c, &sk, "r_hip.flexion", 60.0) / thigh_move(c, &sk, "r_knee.flexion", 60.0)
        };
        eprintln!(
            "thigh weights {:?}; hip/knee flexion response, raw {:.3}, weighted {:.3}",
            cs.weights,
            ratio(&raw),
            ratio(&cs)
        );
        // Raw marker coordinates: hip flexion moves the thigh's point ~10× less than the knee.
        assert!(ratio(&raw) < 0.2, "raw {}", ratio(&raw));
        // Weighted: comparable.
        assert!((0.4..2.5).contains(&ratio(&cs)), "weighted {}", ratio(&cs));
        // The ankle, the most mobile marker, keeps metres.
        assert_eq!(cs.weights[1], 1.0);
        assert!(cs.weights[0] > 3.0);
        // Serialised spaces from before the weights read as unweighted.
        let json = serde_json::to_string(&raw)
            .unwrap()
            .replace(",\"weights\":[]", "");
        let back: ConfigSpace = serde_json::from_str(&json).unwrap();
        assert_eq!(back, raw);
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
