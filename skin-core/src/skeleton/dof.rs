//! Degrees of freedom: one scalar joint parameter each (a rotation angle or a translation).

use crate::math::DVec3;
use serde::{Deserialize, Serialize};

/// What a degree of freedom does to its joint frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum DofKind {
    /// Rotation by θ (radians, right-handed) about the DOF axis, through the current origin.
    Rotation,
    /// Translation by θ (metres) along the DOF axis.
    Translation,
}

/// Closed interval of valid values of one DOF (radians for rotations, metres for translations).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DofLimits {
    /// Smallest valid value (radians or metres).
    pub min: f64,
    /// Largest valid value (radians or metres).
    pub max: f64,
}

impl DofLimits {
    /// Limits from a range given in degrees (convenience for anatomical tables).
    pub fn degrees(min_deg: f64, max_deg: f64) -> Self {
        DofLimits {
            min: min_deg.to_radians(),
            max: max_deg.to_radians(),
        }
    }

    /// Whether `value` lies inside the closed interval.
    pub fn contains(&self, value: f64) -> bool {
        value >= self.min && value <= self.max
    }

    /// `value` clamped into the interval.
    pub fn clamp(&self, value: f64) -> f64 {
        value.clamp(self.min, self.max)
    }
}

/// One degree of freedom of a joint.
///
/// A joint applies its DOFs one after another in its local frame (intrinsic order): the joint
/// transform is `T(offset) · M₀(θ₀) · M₁(θ₁) · …`, where `Mₖ` rotates about or translates
/// along `axis`, expressed in the frame produced by the DOFs before it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Dof {
    /// Name, unique within the skeleton by convention (e.g. `"l_knee.flexion"`).
    pub name: String,
    /// Rotation or translation.
    pub kind: DofKind,
    /// Axis in the frame preceding this DOF (any non-zero length; normalised by
    /// [`Skeleton::new`](super::Skeleton::new)).
    pub axis: DVec3,
    /// Valid range, or `None` for an unlimited DOF (e.g. root translation).
    pub limits: Option<DofLimits>,
}

impl Dof {
    /// A rotation DOF about `axis`.
    pub fn rotation(name: impl Into<String>, axis: DVec3, limits: Option<DofLimits>) -> Self {
        Dof {
            name: name.into(),
            kind: DofKind::Rotation,
            axis,
            limits,
        }
    }

    /// A translation DOF along `axis`.
    pub fn translation(name: impl Into<String>, axis: DVec3, limits: Option<DofLimits>) -> Self {
        Dof {
            name: name.into(),
            kind: DofKind::Translation,
            axis,
            limits,
        }
    }
}
