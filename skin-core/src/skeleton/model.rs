//! The joint tree: joints, their rest offsets and DOFs, validation and pose-vector checks.

use super::dof::{Dof, DofKind};
use crate::math::DVec3;
use crate::{Error, Result};
use serde::{Deserialize, Serialize};
use std::ops::Range;

/// One joint (equivalently the bone it carries) of a [`Skeleton`].
///
/// Its frame relative to its parent is `parent_from_joint(θ) = T(offset) · M₀(θ₀) · M₁(θ₁) · …`
/// (see [`Dof`]); a root joint's parent frame is the world.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Joint {
    /// Joint name, unique within the skeleton.
    pub name: String,
    /// Index of the parent joint (must be smaller than this joint's index), `None` for a root.
    pub parent: Option<usize>,
    /// Rest offset of this joint's origin in the parent joint frame, metres
    /// (BVH `OFFSET`). For a root: the origin in world coordinates at θ = 0.
    pub offset: DVec3,
    /// The joint's DOFs, applied in this order; their values are consecutive entries of θ.
    pub dofs: Vec<Dof>,
    /// Optional bone tip in this joint's frame, metres (BVH `End Site`); gives leaf bones a
    /// length and a drawable end.
    pub end_site: Option<DVec3>,
}

impl Joint {
    /// A joint without end site.
    pub fn new(
        name: impl Into<String>,
        parent: Option<usize>,
        offset: DVec3,
        dofs: Vec<Dof>,
    ) -> Self {
        Joint {
            name: name.into(),
            parent,
            offset,
            dofs,
            end_site: None,
        }
    }

    /// The same joint with an end site (bone tip in the joint frame, metres).
    pub fn with_end_site(mut self, tip: DVec3) -> Self {
        self.end_site = Some(tip);
        self
    }
}

/// Serialised form of a [`Skeleton`]: only the joints; caches are rebuilt and validated on load.
#[derive(Serialize, Deserialize)]
struct SkeletonDef {
    joints: Vec<Joint>,
}

/// An articulated skeleton: a forest of joints with per-joint DOFs.
///
/// **Pose vector θ.** All DOFs of all joints, joint by joint in joint-index order and in each
/// joint's DOF order; `θ.len() == dof_count()`. Rotations in radians, translations in metres.
/// Functions take `&[f64]`; pass a `nalgebra::DVector<f64>` as `theta.as_slice()`.
///
/// **Invariants** (checked by [`Skeleton::new`] and on deserialisation): at least one joint,
/// every parent index smaller than its child's index (so one forward sweep computes forward
/// kinematics), unique joint names, finite offsets, finite non-zero DOF axes (stored
/// normalised), finite limits with `min ≤ max`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "SkeletonDef", into = "SkeletonDef")]
pub struct Skeleton {
    joints: Vec<Joint>,
    /// `dof_start[j]..dof_start[j + 1]` are joint j's entries in θ.
    dof_start: Vec<usize>,
    /// Joint owning each DOF.
    dof_joint: Vec<usize>,
    /// For each joint, all DOF indices on the path root → joint (ascending).
    chain_dofs: Vec<Vec<usize>>,
    /// For each DOF, `Some((i, ±1))` if its axis is exactly `±eᵢ` (fast FK path).
    dof_fast_axis: Vec<Option<(usize, f64)>>,
}

impl TryFrom<SkeletonDef> for Skeleton {
    type Error = Error;
    fn try_from(def: SkeletonDef) -> Result<Self> {
        Skeleton::new(def.joints)
    }
}

impl From<Skeleton> for SkeletonDef {
    fn from(s: Skeleton) -> Self {
        SkeletonDef { joints: s.joints }
    }
}

fn invalid(name: &'static str, reason: String) -> Error {
    Error::InvalidParam { name, reason }
}

impl Skeleton {
    /// Builds and validates a skeleton; normalises DOF axes.
    ///
    /// # Errors
    /// [`Error::Empty`] without joints; [`Error::InvalidParam`] (naming the joint) for a parent
    /// index not smaller than the child's, a duplicate name, a zero or non-finite axis,
    /// non-finite offsets or limits, or `min > max`.
    pub fn new(mut joints: Vec<Joint>) -> Result<Self> {
        if joints.is_empty() {
            return Err(Error::Empty {
                what: "skeleton joints",
            });
        }
        let mut names = std::collections::HashSet::new();
        for (j, joint) in joints.iter_mut().enumerate() {
            if let Some(p) = joint.parent {
                if p >= j {
                    return Err(invalid(
                        "joint.parent",
                        format!(
                            "joint {j} '{}' has parent {p}; parents must precede children",
                            joint.name
                        ),
                    ));
                }
            }
            if !names.insert(joint.name.clone()) {
                return Err(invalid(
                    "joint.name",
                    format!("duplicate joint name '{}'", joint.name),
                ));
            }
            if !joint.offset.is_finite() || !joint.end_site.is_none_or(|e| e.is_finite()) {
                return Err(invalid(
                    "joint.offset",
                    format!("joint '{}' has a non-finite offset or end site", joint.name),
                ));
            }
            for dof in &mut joint.dofs {
                let len = dof.axis.length();
                if !len.is_finite() || len < 1e-12 {
                    return Err(invalid(
                        "dof.axis",
                        format!(
                            "DOF '{}' of joint '{}' has a zero or non-finite axis",
                            dof.name, joint.name
                        ),
                    ));
                }
                dof.axis /= len;
                if let Some(l) = dof.limits {
                    if !(l.min.is_finite() && l.max.is_finite() && l.min <= l.max) {
                        return Err(invalid(
                            "dof.limits",
                            format!(
                                "DOF '{}' of joint '{}' has invalid limits [{}, {}]",
                                dof.name, joint.name, l.min, l.max
                            ),
                        ));
                    }
                }
            }
        }
        let mut dof_start = Vec::with_capacity(joints.len() + 1);
        let mut dof_joint = Vec::new();
        let mut chain_dofs: Vec<Vec<usize>> = Vec::with_capacity(joints.len());
        let mut next = 0;
        for (j, joint) in joints.iter().enumerate() {
            dof_start.push(next);
            let mut chain = joint
                .parent
                .map_or_else(Vec::new, |p| chain_dofs[p].clone());
            for _ in &joint.dofs {
                dof_joint.push(j);
                chain.push(next);
                next += 1;
            }
            chain_dofs.push(chain);
        }
        dof_start.push(next);
        let dof_fast_axis = joints
            .iter()
            .flat_map(|j| j.dofs.iter())
            .map(|d| {
                (0..3).find_map(|i| {
                    let mut e = DVec3::ZERO;
                    e[i] = 1.0;
                    if d.axis == e {
                        Some((i, 1.0))
                    } else if d.axis == -e {
                        Some((i, -1.0))
                    } else {
                        None
                    }
                })
            })
            .collect();
        Ok(Skeleton {
            joints,
            dof_start,
            dof_joint,
            chain_dofs,
            dof_fast_axis,
        })
    }

    /// The joints, in index order (parents before children).
    pub fn joints(&self) -> &[Joint] {
        &self.joints
    }

    /// Number of joints.
    pub fn joint_count(&self) -> usize {
        self.joints.len()
    }

    /// Number of DOFs, i.e. the length of θ.
    pub fn dof_count(&self) -> usize {
        self.dof_joint.len()
    }

    /// Index of the joint called `name`.
    pub fn joint_index(&self, name: &str) -> Option<usize> {
        self.joints.iter().position(|j| j.name == name)
    }

    /// Index in θ of the DOF called `name` (first match).
    pub fn dof_index(&self, name: &str) -> Option<usize> {
        self.dofs().position(|d| d.name == name)
    }

    /// The entries of θ belonging to joint `j`.
    ///
    /// # Panics
    /// If `j >= joint_count()` (an indexing error in the caller).
    pub fn joint_dofs(&self, j: usize) -> Range<usize> {
        self.dof_start[j]..self.dof_start[j + 1]
    }

    /// The joint owning DOF `d`.
    ///
    /// # Panics
    /// If `d >= dof_count()`.
    pub fn dof_joint(&self, d: usize) -> usize {
        self.dof_joint[d]
    }

    /// All DOFs in θ order.
    pub fn dofs(&self) -> impl Iterator<Item = &Dof> + '_ {
        self.joints.iter().flat_map(|j| j.dofs.iter())
    }

    /// The DOF with θ index `d`.
    ///
    /// # Panics
    /// If `d >= dof_count()`.
    pub fn dof(&self, d: usize) -> &Dof {
        let j = self.dof_joint[d];
        &self.joints[j].dofs[d - self.dof_start[j]]
    }

    /// The DOF indices on the path from the root to joint `j` (ascending): the only non-zero
    /// Jacobian columns of anything attached to `j`.
    ///
    /// # Panics
    /// If `j >= joint_count()`.
    pub fn chain_dofs(&self, j: usize) -> &[usize] {
        &self.chain_dofs[j]
    }

    /// Children of joint `j`, in index order.
    pub fn children(&self, j: usize) -> impl Iterator<Item = usize> + '_ {
        self.joints
            .iter()
            .enumerate()
            .filter(move |(_, c)| c.parent == Some(j))
            .map(|(i, _)| i)
    }

    /// Rest length of joint `j`'s bone, metres: the distance to its end site, else the mean
    /// offset length of its children, else 0.
    ///
    /// # Panics
    /// If `j >= joint_count()`.
    pub fn bone_length(&self, j: usize) -> f64 {
        if let Some(e) = self.joints[j].end_site {
            return e.length();
        }
        let (sum, n) = self.children(j).fold((0.0, 0usize), |(s, n), c| {
            (s + self.joints[c].offset.length(), n + 1)
        });
        if n == 0 {
            0.0
        } else {
            sum / n as f64
        }
    }

    /// θ = 0: the rest pose.
    pub fn rest_pose(&self) -> Vec<f64> {
        vec![0.0; self.dof_count()]
    }

    /// Checks that θ has `dof_count()` finite entries.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] for a wrong length; [`Error::InvalidParam`] naming the first
    /// non-finite entry, its DOF and joint.
    pub fn check_pose(&self, what: &'static str, theta: &[f64]) -> Result<()> {
        if theta.len() != self.dof_count() {
            return Err(Error::SizeMismatch {
                what,
                expected: self.dof_count(),
                got: theta.len(),
            });
        }
        if let Some(i) = theta.iter().position(|v| !v.is_finite()) {
            let j = self.dof_joint[i];
            return Err(invalid(
                what,
                format!(
                    "entry {i} (DOF '{}' of joint '{}') is {}",
                    self.dof(i).name,
                    self.joints[j].name,
                    theta[i]
                ),
            ));
        }
        Ok(())
    }

    /// Indices of the DOFs whose value in θ lies outside their limits (empty when all hold).
    ///
    /// # Errors
    /// As [`Skeleton::check_pose`].
    pub fn limit_violations(&self, theta: &[f64]) -> Result<Vec<usize>> {
        self.check_pose("theta", theta)?;
        Ok(self
            .dofs()
            .zip(theta)
            .enumerate()
            .filter(|(_, (d, &v))| d.limits.is_some_and(|l| !l.contains(v)))
            .map(|(i, _)| i)
            .collect())
    }

    /// Clamps θ into the DOF limits in place (unlimited DOFs are left alone).
    ///
    /// # Errors
    /// As [`Skeleton::check_pose`].
    pub fn clamp_to_limits(&self, theta: &mut [f64]) -> Result<()> {
        self.check_pose("theta", theta)?;
        for (d, v) in self.dofs().zip(theta.iter_mut()) {
            if let Some(l) = d.limits {
                *v = l.clamp(*v);
            }
        }
        Ok(())
    }

    /// `Some((i, ±1))` when DOF `d`'s axis is exactly `±eᵢ`.
    pub(super) fn fast_axis(&self, d: usize) -> Option<(usize, f64)> {
        self.dof_fast_axis[d]
    }

    /// Whether DOF `d` is a rotation.
    ///
    /// # Panics
    /// If `d >= dof_count()`.
    pub fn is_rotation(&self, d: usize) -> bool {
        self.dof(d).kind == DofKind::Rotation
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::skeleton::DofLimits;

    fn two_joints() -> Vec<Joint> {
        vec![
            Joint::new(
                "a",
                None,
                DVec3::ZERO,
                vec![Dof::rotation("a.x", DVec3::X * 2.0, None)],
            ),
            Joint::new(
                "b",
                Some(0),
                DVec3::Y,
                vec![Dof::rotation(
                    "b.z",
                    DVec3::Z,
                    Some(DofLimits::degrees(-10.0, 10.0)),
                )],
            )
            .with_end_site(DVec3::Y * 0.5),
        ]
    }

    #[test]
    fn builds_and_normalises() {
        let s = Skeleton::new(two_joints()).unwrap();
        assert_eq!(s.dof_count(), 2);
        assert_eq!(s.dof(0).axis, DVec3::X);
        assert_eq!(s.chain_dofs(1), &[0, 1]);
        assert_eq!(s.joint_dofs(1), 1..2);
        assert_eq!(s.joint_index("b"), Some(1));
        assert_eq!(s.dof_index("b.z"), Some(1));
        assert!((s.bone_length(0) - 1.0).abs() < 1e-15);
        assert!((s.bone_length(1) - 0.5).abs() < 1e-15);
    }

    #[test]
    fn rejects_bad_skeletons() {
        assert!(matches!(Skeleton::new(vec![]), Err(Error::Empty { .. })));
        let mut j = two_joints();
        j[1].parent = Some(1);
        assert!(matches!(
            Skeleton::new(j),
            Err(Error::InvalidParam {
                name: "joint.parent",
                ..
            })
        ));
        let mut j = two_joints();
        j[1].name = "a".into();
        assert!(matches!(
            Skeleton::new(j),
            Err(Error::InvalidParam {
                name: "joint.name",
                ..
            })
        ));
        let mut j = two_joints();
        j[0].dofs[0].axis = DVec3::ZERO;
        assert!(matches!(
            Skeleton::new(j),
            Err(Error::InvalidParam {
                name: "dof.axis",
                ..
            })
        ));
        let mut j = two_joints();
        j[1].offset.x = f64::NAN;
        assert!(matches!(
            Skeleton::new(j),
            Err(Error::InvalidParam {
                name: "joint.offset",
                ..
            })
        ));
        let mut j = two_joints();
        j[1].dofs[0].limits = Some(DofLimits { min: 1.0, max: 0.0 });
        assert!(matches!(
            Skeleton::new(j),
            Err(Error::InvalidParam {
                name: "dof.limits",
                ..
            })
        ));
    }

    #[test]
    fn pose_checks_name_the_joint() {
        let s = Skeleton::new(two_joints()).unwrap();
        assert!(matches!(
            s.check_pose("theta", &[0.0]),
            Err(Error::SizeMismatch {
                expected: 2,
                got: 1,
                ..
            })
        ));
        let err = s
            .check_pose("theta", &[0.0, f64::NAN])
            .unwrap_err()
            .to_string();
        assert!(err.contains("'b'") && err.contains("b.z"), "{err}");
        let mut theta = [0.3, 1.0];
        assert_eq!(s.limit_violations(&theta).unwrap(), vec![1]);
        s.clamp_to_limits(&mut theta).unwrap();
        assert!(s.limit_violations(&theta).unwrap().is_empty());
        assert_eq!(theta[0], 0.3);
    }

    #[test]
    fn serde_round_trip_revalidates() {
        let s = Skeleton::new(two_joints()).unwrap();
        let json = serde_json::to_string(&s).unwrap();
        let back: Skeleton = serde_json::from_str(&json).unwrap();
        assert_eq!(back, s);
        let bad = json.replace("\"parent\":0", "\"parent\":5");
        assert!(serde_json::from_str::<Skeleton>(&bad).is_err());
    }
}
