//! §3.2.2 the lighting conditions: the binary half-on patterns X, Y, Z and their complements
//! (Eq. 3.1), the full-on tracking frame F, and the 8-frame cycle `[X, Y, Z, F, X̄, Ȳ, Z̄, F]`
//! at 240 fps.

use serde::{Deserialize, Serialize};
use skin_core::math::DVec3;

/// A lighting condition of the light stage.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Pattern {
    /// Lights with `x > 0` (direction from the dome centre, world frame), Eq. 3.1.
    X,
    /// Lights with `y > 0`.
    Y,
    /// Lights with `z > 0`.
    Z,
    /// Every light on: the tracking frame.
    Full,
    /// Complement of X: lights with `x ≤ 0`.
    XBar,
    /// Complement of Y.
    YBar,
    /// Complement of Z.
    ZBar,
}

/// The seven distinct conditions, in the order of [`PatternImages`](crate::PatternImages).
pub const PATTERNS: [Pattern; 7] = [
    Pattern::X,
    Pattern::Y,
    Pattern::Z,
    Pattern::Full,
    Pattern::XBar,
    Pattern::YBar,
    Pattern::ZBar,
];

/// The 8-frame cycle of §3.2.2: `[X, Y, Z, F, X̄, Ȳ, Z̄, F]`.
pub const CYCLE: [Pattern; 8] = [
    Pattern::X,
    Pattern::Y,
    Pattern::Z,
    Pattern::Full,
    Pattern::XBar,
    Pattern::YBar,
    Pattern::ZBar,
    Pattern::Full,
];

/// Frame rate of the cycle, Hz (§3.2.1: "captured at a constant rate of 240fps", geometry at
/// an effective 60 fps).
pub const CYCLE_FRAME_RATE_HZ: f64 = 240.0;

impl Pattern {
    /// Index in [`PATTERNS`].
    pub fn index(self) -> usize {
        self as usize
    }

    /// Eq. 3.1: whether the pattern switches on a light in unit direction `d` from the dome
    /// centre (world axes).
    pub fn lights(self, d: DVec3) -> bool {
        match self {
            Pattern::X => d.x > 0.0,
            Pattern::Y => d.y > 0.0,
            Pattern::Z => d.z > 0.0,
            Pattern::Full => true,
            Pattern::XBar => d.x <= 0.0,
            Pattern::YBar => d.y <= 0.0,
            Pattern::ZBar => d.z <= 0.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cycle_shows_every_condition_with_a_full_frame_each_half() {
        assert_eq!(CYCLE.len(), 8);
        assert_eq!(CYCLE[3], Pattern::Full);
        assert_eq!(CYCLE[7], Pattern::Full);
        for (i, p) in PATTERNS.iter().enumerate() {
            assert_eq!(p.index(), i);
            assert!(CYCLE.contains(p));
        }
        for (a, b) in [
            (Pattern::X, Pattern::XBar),
            (Pattern::Y, Pattern::YBar),
            (Pattern::Z, Pattern::ZBar),
        ] {
            for d in [DVec3::X, DVec3::Y, DVec3::Z, DVec3::new(-1.0, 0.5, -0.2)] {
                assert_ne!(a.lights(d), b.lights(d));
            }
        }
    }
}
