//! Deformable primitives: needles in rings around a bone axis (Sand 2003 §3.1–3.2, Table 3.1).
//!
//! The method is documented on [`NeedleBody`]; the module is private and
//! everything public is re-exported at the crate root.

use serde::{Deserialize, Serialize};
use skin_core::check;
use skin_core::math::{DAffine3, DVec3};
use skin_core::skeleton::{ForwardKinematics, Skeleton};

use crate::config::{resolve_marker, ConfigSpace};
use crate::error::{Context, Error, Result, ResultExt};
use crate::store::{PrimitiveShape, MAX_NEEDLES_PER_PRIMITIVE};

/// Description of one deformable primitive by joint names (resolved against a skeleton by
/// [`NeedleBody::new`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PrimitiveSpec {
    /// Name (Table 3.1 "Name of Deformable Primitive").
    pub name: String,
    /// Joint whose frame carries the primitive (its axis and needles are rigid in it).
    pub carrier: String,
    /// Markers whose rest-pose mean is the start of the axis (see
    /// [`crate::resolve_marker`] for the marker syntax: a joint name, or `joint.tip` for its end site).
    pub axis_from: Vec<String>,
    /// Markers whose rest-pose mean is the end of the axis.
    pub axis_to: Vec<String>,
    /// Extension of the axis before its start, as a fraction of the axis length (junction
    /// overlap, §3.2). Default in Table 3.1 layout: 0–0.1.
    pub extend_start: f64,
    /// Extension of the axis past its end, fraction of the axis length.
    pub extend_end: f64,
    /// Needles per ring (Table 3.1 "Radial Needles").
    pub radial: usize,
    /// Number of rings (Table 3.1 "Axial Needles").
    pub axial: usize,
    /// Maximum needle length, m (Table 3.1 "Maximum Needle Length"; §4.3 discards longer walks).
    pub max_length_m: f64,
    /// Configuration markers (§3.3): points of the bones the primitive depends on, expressed in
    /// the carrier frame; 3 dimensions each.
    pub config_markers: Vec<String>,
}

/// A body layout: the list of primitives.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BodyLayout {
    /// The primitives, in order (primitive index = position).
    pub primitives: Vec<PrimitiveSpec>,
}

#[allow(clippy::too_many_arguments)] // a table row; named fields would only repeat the header
fn spec(
    name: &str,
    carrier: &str,
    from: &[&str],
    to: &[&str],
    ext: (f64, f64),
    radial: usize,
    axial: usize,
    max_length_m: f64,
    markers: &[&str],
) -> PrimitiveSpec {
    let s = |v: &[&str]| v.iter().map(|x| x.to_string()).collect();
    PrimitiveSpec {
        name: name.into(),
        carrier: carrier.into(),
        axis_from: s(from),
        axis_to: s(to),
        extend_start: ext.0,
        extend_end: ext.1,
        radial,
        axial,
        max_length_m,
        config_markers: s(markers),
    }
}

impl BodyLayout {
    /// Sand 2003 Table 3.1 on the `human_skeleton` joints: counts, maximum lengths and
    /// configuration dependencies of the thesis. Mapping of the thesis's bones:
    ///
    /// | primitive | carrier | axis | configuration markers (Table 3.1 "Depends On") |
    /// |---|---|---|---|
    /// | Torso | chest | spine → neck | elbows (upper arms), pelvis (hips) — 9 D |
    /// | Hips | pelvis | hip centres → spine | neck (torso), knees (thighs) — 9 D |
    /// | Upper arm | shoulder | shoulder → elbow | chest (torso), wrist (forearm) — 6 D |
    /// | Forearm | elbow | elbow → wrist | shoulder (upper arm) — 3 D |
    /// | Thigh | hip | hip → knee | pelvis (hips), ankle (calf) — 6 D |
    /// | Calf | knee | knee → ankle | hip (thigh), toe tip (foot) — 6 D |
    /// | Foot | ankle | ankle → toe tip | knee (calf) — 3 D |
    ///
    /// Each marker is the far end of the bone it stands for, so it moves in the carrier frame
    /// exactly when the joint between them bends (the thesis's "marker coordinates", §3.3).
    /// Hips start half an axis length below the hip centres to cover the buttocks; limbs overlap their
    /// neighbours by 5–10 % (junction unions, §3.2).
    pub fn table_3_1() -> Self {
        let mut p = vec![
            spec(
                "torso",
                "chest",
                &["spine"],
                &["neck"],
                (0.0, 0.0),
                30,
                30,
                0.30,
                &["l_elbow", "r_elbow", "pelvis"],
            ),
            spec(
                "hips",
                "pelvis",
                &["l_hip", "r_hip"],
                &["spine"],
                (0.5, 0.1),
                30,
                30,
                0.30,
                &["neck", "l_knee", "r_knee"],
            ),
        ];
        for (side, s) in [("right", "r"), ("left", "l")] {
            let j = |n: &str| format!("{s}_{n}");
            let (sh, el, wr, hip, kn, an) = (
                j("shoulder"),
                j("elbow"),
                j("wrist"),
                j("hip"),
                j("knee"),
                j("ankle"),
            );
            let toe = format!("{an}.tip");
            p.push(spec(
                &format!("{side} upper arm"),
                &sh,
                &[&sh],
                &[&el],
                (0.05, 0.05),
                20,
                20,
                0.15,
                &["chest", &wr],
            ));
            p.push(spec(
                &format!("{side} forearm"),
                &el,
                &[&el],
                &[&wr],
                (0.05, 0.05),
                20,
                20,
                0.10,
                &[&sh],
            ));
            p.push(spec(
                &format!("{side} thigh"),
                &hip,
                &[&hip],
                &[&kn],
                (0.05, 0.05),
                20,
                30,
                0.20,
                &["pelvis", &an],
            ));
            p.push(spec(
                &format!("{side} calf"),
                &kn,
                &[&kn],
                &[&an],
                (0.05, 0.05),
                20,
                30,
                0.15,
                &[&hip, &toe],
            ));
            p.push(spec(
                &format!("{side} foot"),
                &an,
                &[&an],
                &[&toe],
                (0.0, 0.0),
                20,
                20,
                0.15,
                &[&kn],
            ));
        }
        // Order as in Table 3.1: torso, hips, R/L upper arm, R/L forearm, R/L thigh, R/L calf,
        // R/L foot.
        let order = [0usize, 1, 2, 7, 3, 8, 4, 9, 5, 10, 6, 11];
        Self {
            primitives: order.iter().map(|&i| p[i].clone()).collect(),
        }
    }

    /// The same layout with needle counts scaled (e.g. `0.5` gives the quarter-count body of
    /// thesis Figure 3-1); counts are rounded and kept ≥ 1.
    pub fn with_density(mut self, factor: f64) -> Self {
        for s in &mut self.primitives {
            s.radial = ((s.radial as f64 * factor).round() as usize).max(1);
            s.axial = ((s.axial as f64 * factor).round() as usize).max(1);
        }
        self
    }
}

/// One resolved deformable primitive: needles in its carrier joint's frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Primitive {
    /// Name.
    pub name: String,
    /// Index of the carrier joint.
    pub carrier: usize,
    /// Axis start, carrier frame, m.
    pub axis_start: DVec3,
    /// Axis end, carrier frame, m.
    pub axis_end: DVec3,
    /// Needles per ring.
    pub radial: usize,
    /// Rings.
    pub axial: usize,
    /// Maximum needle length, m.
    pub max_length_m: f64,
    /// Needle origins on the axis, carrier frame, m (`radial · axial` entries, ring-major).
    pub needle_origin: Vec<DVec3>,
    /// Unit needle directions, carrier frame (perpendicular to the axis).
    pub needle_dir: Vec<DVec3>,
    /// The configuration space (§3.3).
    pub config: ConfigSpace,
}

impl Primitive {
    /// Number of needles.
    pub fn needle_count(&self) -> usize {
        self.needle_origin.len()
    }

    /// World origin and unit direction of needle `j` given the carrier's `world_from_joint`.
    pub fn needle_world(&self, world_from_carrier: &DAffine3, j: usize) -> (DVec3, DVec3) {
        (
            world_from_carrier.transform_point3(self.needle_origin[j]),
            world_from_carrier.transform_vector3(self.needle_dir[j]),
        )
    }
}

/// All primitives of a body, resolved against one skeleton.
///
/// Deformable primitives: needles in rings around a bone axis (Sand 2003 §3.1–3.2, Table 3.1).
///
/// "Each deformable primitive consists of a rigid axis, which usually corresponds to a bone in
/// the skeleton, and a set of needles, which are rigidly attached to the axis. Each needle
/// originates at a point along the axis and extends outward in a fixed direction" (§3.1). The
/// needles sit in rings: `axial` rings evenly spaced along the axis, `radial` needles per ring
/// evenly spaced in angle, perpendicular to the axis. Needle `j = ring · radial + k` (ring-major).
/// Junctions are unions of overlapping primitives (§3.2), so the axes are extended a little
/// past the joints ([`PrimitiveSpec::extend_start`], [`PrimitiveSpec::extend_end`]).
///
/// [`BodyLayout::table_3_1`] is the thesis's default body (12 primitives, 6 600 needles) mapped
/// onto the 19-joint skeleton of [`skin_core::skeleton::human_skeleton`] (the MakeHuman
/// performer has the same joint names).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NeedleBody {
    /// The primitives.
    pub primitives: Vec<Primitive>,
}

impl NeedleBody {
    /// Resolves `layout` against `skeleton`: axis ends and configuration markers are placed
    /// using the rest pose (θ = 0) and expressed in each carrier frame.
    ///
    /// # Errors
    /// [`Error::Empty`] for a layout without primitives. Per primitive, in [`Error::At`] with
    /// its [`Context::Primitive`]: an invalid-parameter error ([`Error::invalid_param_name`])
    /// for an unknown joint name, a zero count, more than 65 536 needles, a non-positive
    /// maximum length, a negative extension, or a degenerate (zero-length) axis;
    /// [`Error::Empty`] for a primitive without markers.
    pub fn new(skeleton: &Skeleton, layout: &BodyLayout) -> Result<Self> {
        if layout.primitives.is_empty() {
            return Err(Error::Empty {
                what: "body layout primitives",
            });
        }
        let rest = skeleton.forward_kinematics(&skeleton.rest_pose())?;
        let mut primitives = Vec::with_capacity(layout.primitives.len());
        for (i, s) in layout.primitives.iter().enumerate() {
            primitives.push(build_primitive(skeleton, &rest, s).at(Context::Primitive(i))?);
        }
        Ok(Self { primitives })
    }

    /// Total number of needles.
    pub fn needle_count(&self) -> usize {
        self.primitives.iter().map(Primitive::needle_count).sum()
    }

    /// Shapes for an [`crate::ObservationStore`] of this body.
    pub fn store_shapes(&self) -> Vec<PrimitiveShape> {
        self.primitives
            .iter()
            .map(|p| PrimitiveShape {
                config_dim: p.config.dim(),
                needle_count: p.needle_count(),
                max_length_m: p.max_length_m,
            })
            .collect()
    }
}

/// Resolves one primitive of a layout against `skeleton` at rest (`rest`), the body of
/// [`NeedleBody::new`]'s loop (errors get the primitive's context there).
fn build_primitive(
    skeleton: &Skeleton,
    rest: &ForwardKinematics,
    s: &PrimitiveSpec,
) -> Result<Primitive> {
    let world = rest.world_from_joint();
    let carrier = skeleton
        .joint_index(&s.carrier)
        .ok_or_else(|| Error::InvalidParam {
            name: "carrier",
            reason: format!("no joint named {:?} (primitive {:?})", s.carrier, s.name),
        })?;
    let n = s.radial.saturating_mul(s.axial);
    if s.radial == 0 || s.axial == 0 || n > MAX_NEEDLES_PER_PRIMITIVE {
        return Err(Error::InvalidParam {
            name: "radial/axial",
            reason: format!(
                "{:?}: counts must be ≥ 1 with ≤ {MAX_NEEDLES_PER_PRIMITIVE} needles, got {} × {}",
                s.name, s.radial, s.axial
            ),
        });
    }
    check::positive("max_length_m", s.max_length_m)?;
    check::non_negative("extend_start", s.extend_start)?;
    check::non_negative("extend_end", s.extend_end)?;
    let carrier_from_world = world[carrier].inverse();
    let mean = |names: &[String]| -> Result<DVec3> {
        if names.is_empty() {
            return Err(Error::Empty {
                what: "axis markers",
            });
        }
        let mut sum = DVec3::ZERO;
        for m in names {
            let pt = resolve_marker(skeleton, m)?;
            sum += carrier_from_world.transform_point3(rest.point(&pt)?);
        }
        Ok(sum / names.len() as f64)
    };
    let a = mean(&s.axis_from)?;
    let b = mean(&s.axis_to)?;
    let len = a.distance(b);
    if len < 1e-6 {
        return Err(Error::InvalidParam {
            name: "axis",
            reason: format!("{:?}: axis start and end coincide", s.name),
        });
    }
    let axis = (b - a) / len;
    let start = a - axis * (s.extend_start * len);
    let end = b + axis * (s.extend_end * len);
    let (u, v) = perpendicular_basis(axis);
    let mut needle_origin = Vec::with_capacity(n);
    let mut needle_dir = Vec::with_capacity(n);
    for ring in 0..s.axial {
        let t = (ring as f64 + 0.5) / s.axial as f64;
        let o = start.lerp(end, t);
        for k in 0..s.radial {
            let phi = std::f64::consts::TAU * k as f64 / s.radial as f64;
            needle_origin.push(o);
            needle_dir.push(u * phi.cos() + v * phi.sin());
        }
    }
    let config = ConfigSpace::new(skeleton, carrier, &s.config_markers)?;
    Ok(Primitive {
        name: s.name.clone(),
        carrier,
        axis_start: start,
        axis_end: end,
        radial: s.radial,
        axial: s.axial,
        max_length_m: s.max_length_m,
        needle_origin,
        needle_dir,
        config,
    })
}

/// Orthonormal `(u, v)` perpendicular to unit `axis`; `u` is the carrier frame's +z (forward)
/// made perpendicular, or +x if the axis is nearly along z — so needle 0 of each ring points
/// the same way in every primitive.
fn perpendicular_basis(axis: DVec3) -> (DVec3, DVec3) {
    let reference = if axis.z.abs() < 0.9 {
        DVec3::Z
    } else {
        DVec3::X
    };
    let u = (reference - axis * reference.dot(axis)).normalize();
    (u, axis.cross(u))
}

#[cfg(test)]
mod tests {
    use super::*;
    use skin_core::skeleton::{human_skeleton, HumanParams};

    #[test]
    fn table_3_1_has_6600_needles_and_paper_dimensions() {
        let sk = human_skeleton(&HumanParams::default()).unwrap();
        let body = NeedleBody::new(&sk, &BodyLayout::table_3_1()).unwrap();
        assert_eq!(body.primitives.len(), 12);
        assert_eq!(body.needle_count(), 6600);
        let dims: Vec<usize> = body.primitives.iter().map(|p| p.config.dim()).collect();
        assert_eq!(dims, vec![9, 9, 6, 6, 3, 3, 6, 6, 6, 6, 3, 3]);
        for p in &body.primitives {
            let axis = (p.axis_end - p.axis_start).normalize();
            for (o, d) in p.needle_origin.iter().zip(&p.needle_dir) {
                assert!((d.length() - 1.0).abs() < 1e-12);
                assert!(d.dot(axis).abs() < 1e-12);
                // Origins lie on the axis segment.
                let t = (*o - p.axis_start).dot(axis);
                assert!(t > 0.0 && t < p.axis_start.distance(p.axis_end));
            }
        }
        let quarter = NeedleBody::new(&sk, &BodyLayout::table_3_1().with_density(0.5)).unwrap();
        assert_eq!(quarter.needle_count(), 6600 / 4);
    }

    #[test]
    fn bad_layouts_are_rejected() {
        let sk = human_skeleton(&HumanParams::default()).unwrap();
        let good = BodyLayout::table_3_1();
        assert!(NeedleBody::new(&sk, &BodyLayout { primitives: vec![] }).is_err());
        let mut l = good.clone();
        l.primitives[0].carrier = "tail".into();
        assert!(NeedleBody::new(&sk, &l).is_err());
        let mut l = good.clone();
        l.primitives[0].radial = 0;
        assert!(NeedleBody::new(&sk, &l).is_err());
        let mut l = good.clone();
        l.primitives[0].max_length_m = f64::NAN;
        assert!(NeedleBody::new(&sk, &l).is_err());
        let mut l = good.clone();
        l.primitives[0].axis_to = l.primitives[0].axis_from.clone();
        assert!(NeedleBody::new(&sk, &l).is_err());
        let mut l = good;
        l.primitives[0].config_markers = vec!["nobody".into()];
        assert!(NeedleBody::new(&sk, &l).is_err());
    }
}
