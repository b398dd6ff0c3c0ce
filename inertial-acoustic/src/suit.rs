//! The suit (§4.2.1): 18 sensor boards (3-axis gyroscope, 3-axis accelerometer, microphone)
//! and 8 ultrasonic sources (seven on chest and belly pointing forward, one on the brim of a
//! hat pointing down), each a rigid transform in its bone's frame (§4.4.4: "the sensors are
//! manually specified as rigid transforms in the coordinate frames of their parent bones").

use crate::{Error, Result};
use serde::{Deserialize, Serialize};
use skin_core::math::{DQuat, DVec3};
use skin_core::skeleton::{AttachedFrame, AttachedPoint, Skeleton};

/// A sensor board: gyroscope and accelerometer axes plus a microphone at one point.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SensorBoard {
    /// Name, e.g. `"l_forearm"`.
    pub name: String,
    /// Joint (bone) carrying the board.
    pub joint: usize,
    /// Position in the joint frame, metres (accelerometer and microphone).
    pub offset: DVec3,
    /// Orientation of the board's axes in the joint frame.
    pub joint_from_sensor: DQuat,
}

impl SensorBoard {
    /// The board's position as an attached point.
    pub fn point(&self) -> AttachedPoint {
        AttachedPoint {
            joint: self.joint,
            offset: self.offset,
        }
    }

    /// The board's axes as an attached frame.
    pub fn frame(&self) -> AttachedFrame {
        AttachedFrame {
            joint: self.joint,
            joint_from_frame: self.joint_from_sensor,
        }
    }
}

/// An ultrasonic source (piezo transducer on a plate).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct UltrasonicSource {
    /// Name, e.g. `"chest_centre"`.
    pub name: String,
    /// Joint (bone) carrying the source.
    pub joint: usize,
    /// Position in the joint frame, metres.
    pub offset: DVec3,
    /// Unit normal (emission axis) in the joint frame.
    pub normal: DVec3,
}

impl UltrasonicSource {
    /// The source's position as an attached point.
    pub fn point(&self) -> AttachedPoint {
        AttachedPoint {
            joint: self.joint,
            offset: self.offset,
        }
    }
}

/// One board's measurement noise (the filter's per-board R, beyond §4.4.2's one σ per sensor
/// type): e.g. estimated from the data by [`crate::tuning::board_noise_from_innovations`]. Optionally
/// one σ per sensor axis (a board over blended skin turns against
/// its bone more about some axes than others; [`crate::tuning::board_axis_noise_from_innovations`]),
/// which then replaces the board's σ on those rows.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BoardNoise {
    /// Gyroscope noise, rad/s.
    pub gyroscope_sigma: f64,
    /// Accelerometer noise, m/s².
    pub accelerometer_sigma: f64,
    /// Gyroscope noise per board axis (x, y, z), rad/s; `None`: `gyroscope_sigma` on each.
    #[serde(default)]
    pub gyroscope_axis_sigma: Option<[f64; 3]>,
    /// Accelerometer noise per board axis, m/s²; `None`: `accelerometer_sigma` on each.
    #[serde(default)]
    pub accelerometer_axis_sigma: Option<[f64; 3]>,
}

impl BoardNoise {
    /// One σ per sensor type, the same on the three axes.
    pub fn new(gyroscope_sigma: f64, accelerometer_sigma: f64) -> Self {
        BoardNoise {
            gyroscope_sigma,
            accelerometer_sigma,
            gyroscope_axis_sigma: None,
            accelerometer_axis_sigma: None,
        }
    }

    /// The same with one σ per board axis for each sensor type.
    pub fn with_axes(self, gyroscope: [f64; 3], accelerometer: [f64; 3]) -> Self {
        BoardNoise {
            gyroscope_axis_sigma: Some(gyroscope),
            accelerometer_axis_sigma: Some(accelerometer),
            ..self
        }
    }

    /// The gyroscope σ on the board's x, y, z axes (rad/s).
    pub fn gyroscope_axes(&self) -> [f64; 3] {
        self.gyroscope_axis_sigma
            .unwrap_or([self.gyroscope_sigma; 3])
    }

    /// The accelerometer σ on the board's x, y, z axes (m/s²).
    pub fn accelerometer_axes(&self) -> [f64; 3] {
        self.accelerometer_axis_sigma
            .unwrap_or([self.accelerometer_sigma; 3])
    }

    /// One σ per sensor type, the largest of its axes, on all three axes. Per-axis NIS only sees
    /// the part of a board's misfit that no state can absorb: over blended skin the neck board's
    /// twist about its bone (no DOF of the 2-DOF neck turns that way) shows on one axis, while its
    /// skin's swing is followed by the neck's own angles and stays consistent-looking on the other
    /// two. The worst axis is then the better measure of how far the whole board can be trusted.
    pub fn worst_axis(&self) -> BoardNoise {
        let max = |v: [f64; 3]| v[0].max(v[1]).max(v[2]);
        BoardNoise::new(max(self.gyroscope_axes()), max(self.accelerometer_axes()))
    }
}

/// Sensor boards and sources of one suit, valid for the skeleton it was built for (joint
/// indices in range, finite offsets, unit normals).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Suit {
    boards: Vec<SensorBoard>,
    sources: Vec<UltrasonicSource>,
    /// Per-board measurement noise; empty: the filter's global σ for every board.
    #[serde(default)]
    board_noise: Vec<BoardNoise>,
}

/// One row of the placement table: bone, fraction along the bone towards its (first) child or
/// end site, and an offset to the garment surface in the joint frame (metres).
struct Placement {
    name: &'static str,
    joint: &'static str,
    along: f64,
    surface: [f64; 3],
}

/// The 18 boards (tabled in `docs/inertial-acoustic.md`, Suit). The human skeleton faces
/// +z with its left at +x and +y up.
const BOARDS: [Placement; 18] = [
    p("sacrum", "pelvis", 0.0, [0.0, 0.02, -0.12]),
    p("lower_back", "spine", 0.5, [0.0, 0.0, -0.13]),
    p("upper_back", "chest", 0.5, [0.0, 0.0, -0.12]),
    p("sternum", "chest", 0.8, [0.0, 0.0, 0.11]),
    p("neck", "neck", 0.5, [0.0, 0.0, -0.06]),
    p("head", "head", 0.9, [0.0, 0.0, 0.0]),
    p("l_upper_arm", "l_shoulder", 0.5, [0.05, 0.0, 0.0]),
    p("l_forearm", "l_elbow", 0.6, [0.0, 0.0, 0.04]),
    p("l_hand", "l_wrist", 0.4, [0.0, 0.0, 0.02]),
    p("r_upper_arm", "r_shoulder", 0.5, [-0.05, 0.0, 0.0]),
    p("r_forearm", "r_elbow", 0.6, [0.0, 0.0, 0.04]),
    p("r_hand", "r_wrist", 0.4, [0.0, 0.0, 0.02]),
    p("l_thigh", "l_hip", 0.5, [0.0, 0.0, 0.08]),
    p("l_shin", "l_knee", 0.4, [0.0, 0.0, 0.06]),
    p("l_foot", "l_ankle", 0.6, [0.0, 0.04, 0.0]),
    p("r_thigh", "r_hip", 0.5, [0.0, 0.0, 0.08]),
    p("r_shin", "r_knee", 0.4, [0.0, 0.0, 0.06]),
    p("r_foot", "r_ankle", 0.6, [0.0, 0.04, 0.0]),
];

/// The 8 sources: seven on chest and belly pointing forward (+z), one on a hat brim pointing
/// down (and slightly forward).
const SOURCES: [Placement; 8] = [
    p("chest_left", "chest", 0.6, [0.09, 0.0, 0.12]),
    p("chest_centre", "chest", 0.6, [0.0, 0.0, 0.13]),
    p("chest_right", "chest", 0.6, [-0.09, 0.0, 0.12]),
    p("belly_left", "spine", 0.4, [0.07, 0.0, 0.13]),
    p("belly_right", "spine", 0.4, [-0.07, 0.0, 0.13]),
    p("lower_belly_left", "pelvis", 0.0, [0.08, 0.04, 0.12]),
    p("lower_belly_right", "pelvis", 0.0, [-0.08, 0.04, 0.12]),
    p("hat_brim", "head", 0.8, [0.0, 0.0, 0.14]),
];

const fn p(name: &'static str, joint: &'static str, along: f64, surface: [f64; 3]) -> Placement {
    Placement {
        name,
        joint,
        along,
        surface,
    }
}

fn place(skeleton: &Skeleton, pl: &Placement, what: &'static str) -> Result<(usize, DVec3)> {
    let j = skeleton
        .joint_index(pl.joint)
        .ok_or_else(|| Error::MissingBone {
            what,
            name: pl.joint.to_string(),
        })?;
    let tip = skeleton.joints()[j]
        .end_site
        .or_else(|| {
            skeleton
                .children(j)
                .next()
                .map(|c| skeleton.joints()[c].offset)
        })
        .unwrap_or(DVec3::ZERO);
    Ok((j, tip * pl.along + DVec3::from_array(pl.surface)))
}

impl Suit {
    /// A checked suit.
    ///
    /// # Errors
    /// [`Error::Empty`] without boards; [`Error::IndexOutOfRange`] (in [`Error::At`] naming
    /// the board or source) for a joint the skeleton does not have; [`Error::NonFinite`] for
    /// non-finite offsets, orientations or normals; [`Error::InvalidParam`] for a zero normal.
    pub fn new(
        skeleton: &Skeleton,
        boards: Vec<SensorBoard>,
        sources: Vec<UltrasonicSource>,
    ) -> Result<Self> {
        Self::checked(skeleton, boards, sources, false)
    }

    /// A suit whose board orientations and source normals are already of unit length (within
    /// 10⁻⁹), kept bit for bit rather than normalised again — so that a suit written to a
    /// file ([`crate::Recording::write`]) reads back identical.
    ///
    /// # Errors
    /// As [`Suit::new`]; [`Error::InvalidParam`] (in [`Error::At`] naming the board or
    /// source) for an orientation or normal that is not of unit length.
    pub fn from_unit_parts(
        skeleton: &Skeleton,
        boards: Vec<SensorBoard>,
        sources: Vec<UltrasonicSource>,
    ) -> Result<Self> {
        Self::checked(skeleton, boards, sources, true)
    }

    fn checked(
        skeleton: &Skeleton,
        boards: Vec<SensorBoard>,
        sources: Vec<UltrasonicSource>,
        unit: bool,
    ) -> Result<Self> {
        use crate::{Context, ResultExt};
        let not_unit = |len: f64, name: &'static str| Error::InvalidParam {
            name,
            reason: format!("length {len}: give a unit vector or quaternion"),
        };
        if boards.is_empty() {
            return Err(Error::Empty {
                what: "sensor boards",
            });
        }
        let nj = skeleton.joint_count();
        for (i, b) in boards.iter().enumerate() {
            skin_core::check::index("board joint", b.joint, nj).at(Context::Sensor(i))?;
            if !b.offset.is_finite() || !b.joint_from_sensor.is_finite() {
                return Err(Error::NonFinite {
                    what: "board offset or orientation",
                })
                .at(Context::Sensor(i));
            }
        }
        let mut sources = sources;
        for (i, s) in sources.iter_mut().enumerate() {
            skin_core::check::index("source joint", s.joint, nj).at(Context::Source(i))?;
            if !s.offset.is_finite() || !s.normal.is_finite() {
                return Err(Error::NonFinite {
                    what: "source offset or normal",
                })
                .at(Context::Source(i));
            }
            let len = s.normal.length();
            if unit && (len - 1.0).abs() > 1e-9 {
                return Err(not_unit(len, "source.normal")).at(Context::Source(i));
            }
            if len < 1e-9 {
                return Err(Error::InvalidParam {
                    name: "source.normal",
                    reason: "zero vector".into(),
                })
                .at(Context::Source(i));
            }
            if !unit {
                s.normal /= len;
            }
        }
        if unit {
            for (i, b) in boards.iter().enumerate() {
                let len = b.joint_from_sensor.length();
                if (len - 1.0).abs() > 1e-9 {
                    return Err(not_unit(len, "board.joint_from_sensor")).at(Context::Sensor(i));
                }
            }
        }
        let boards = boards
            .into_iter()
            .map(|b| SensorBoard {
                joint_from_sensor: if unit {
                    b.joint_from_sensor
                } else {
                    b.joint_from_sensor.normalize()
                },
                ..b
            })
            .collect();
        Ok(Suit {
            boards,
            sources,
            board_noise: Vec::new(),
        })
    }

    /// The thesis's suit (§4.2.1, Figure 4-2) on `skeleton`, which must have the joints of
    /// [`skin_core::skeleton::human_skeleton`]: 18 boards, one per moving bone plus the
    /// sternum, axes aligned with their bones; 8 sources (see the placement table in
    /// `docs/inertial-acoustic.md`).
    ///
    /// # Errors
    /// [`Error::MissingBone`] naming a joint the skeleton lacks.
    pub fn vlasic(skeleton: &Skeleton) -> Result<Self> {
        let boards = BOARDS
            .iter()
            .map(|pl| {
                let (joint, offset) = place(skeleton, pl, "sensor board")?;
                Ok(SensorBoard {
                    name: pl.name.to_string(),
                    joint,
                    offset,
                    joint_from_sensor: DQuat::IDENTITY,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        let sources = SOURCES
            .iter()
            .map(|pl| {
                let (joint, offset) = place(skeleton, pl, "ultrasonic source")?;
                let normal = if pl.joint == "head" {
                    DVec3::new(0.0, -1.0, 0.35)
                } else {
                    DVec3::Z
                };
                Ok(UltrasonicSource {
                    name: pl.name.to_string(),
                    joint,
                    offset,
                    normal,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        Suit::new(skeleton, boards, sources)
    }

    /// The sensor boards.
    pub fn boards(&self) -> &[SensorBoard] {
        &self.boards
    }

    /// The ultrasonic sources.
    pub fn sources(&self) -> &[UltrasonicSource] {
        &self.sources
    }

    /// The same suit with board `i`'s axes replaced (initialisation, §4.4.4).
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`] for a bad board index; [`Error::NonFinite`] for a non-finite
    /// orientation.
    pub fn with_board_orientation(mut self, i: usize, joint_from_sensor: DQuat) -> Result<Self> {
        let n = self.boards.len();
        let b = self.boards.get_mut(i).ok_or(Error::IndexOutOfRange {
            what: "sensor board",
            index: i,
            len: n,
        })?;
        if !joint_from_sensor.is_finite() {
            return Err(Error::NonFinite {
                what: "board orientation",
            });
        }
        b.joint_from_sensor = joint_from_sensor.normalize();
        Ok(self)
    }

    /// Per-board measurement noise, one per board in board order; empty if the suit uses the
    /// filter's global σ ([`crate::FilterParams`]) for every board.
    pub fn board_noise(&self) -> &[BoardNoise] {
        &self.board_noise
    }

    /// This suit with each board's σ taken from its worst axis ([`BoardNoise::worst_axis`]).
    ///
    /// # Errors
    /// As [`Suit::with_board_noise`].
    pub fn with_worst_axis_noise(self) -> Result<Self> {
        let noise = self
            .board_noise
            .iter()
            .map(BoardNoise::worst_axis)
            .collect();
        self.with_board_noise(noise)
    }

    /// The same suit with per-board measurement noise (one per board; empty: back to the
    /// filter's global σ).
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] unless empty or one per board; [`Error::InvalidParam`] (in
    /// [`Error::At`] naming the board) for a non-positive or non-finite σ.
    pub fn with_board_noise(mut self, noise: Vec<BoardNoise>) -> Result<Self> {
        use crate::{Context, ResultExt};
        if !noise.is_empty() {
            skin_core::check::same_size("board noise", self.boards.len(), noise.len())?;
        }
        for (i, n) in noise.iter().enumerate() {
            skin_core::check::positive("gyroscope_sigma", n.gyroscope_sigma)
                .at(Context::Sensor(i))?;
            skin_core::check::positive("accelerometer_sigma", n.accelerometer_sigma)
                .at(Context::Sensor(i))?;
            for s in n.gyroscope_axes() {
                skin_core::check::positive("gyroscope_axis_sigma", s).at(Context::Sensor(i))?;
            }
            for s in n.accelerometer_axes() {
                skin_core::check::positive("accelerometer_axis_sigma", s).at(Context::Sensor(i))?;
            }
        }
        self.board_noise = noise;
        Ok(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use skin_core::skeleton::{human_skeleton, HumanParams};

    #[test]
    fn vlasic_suit_has_18_boards_and_8_sources() {
        let s = human_skeleton(&HumanParams::default()).unwrap();
        let suit = Suit::vlasic(&s).unwrap();
        assert_eq!(suit.boards().len(), 18);
        assert_eq!(suit.sources().len(), 8);
        let fk = s.forward_kinematics(&s.rest_pose()).unwrap();
        // Seven sources face forward, the hat's points down.
        let down = suit
            .sources()
            .iter()
            .filter(|src| src.normal.y < -0.5)
            .count();
        assert_eq!(down, 1);
        // Every board sits within 1.8 m of the floor and off its joint axis.
        for b in suit.boards() {
            let p = fk.point(&b.point()).unwrap();
            assert!(p.y > 0.0 && p.y < 1.8, "{} at {p}", b.name);
        }
    }

    #[test]
    fn missing_bone_and_bad_joint_are_errors() {
        let s = human_skeleton(&HumanParams::default()).unwrap();
        let joints: Vec<_> = s.joints()[..5].to_vec();
        let small = Skeleton::new(joints).unwrap();
        assert!(matches!(
            Suit::vlasic(&small),
            Err(Error::MissingBone { .. })
        ));
        let board = SensorBoard {
            name: "x".into(),
            joint: 99,
            offset: DVec3::ZERO,
            joint_from_sensor: DQuat::IDENTITY,
        };
        let e = Suit::new(&s, vec![board], vec![]).unwrap_err();
        assert_eq!(e.contexts(), [crate::Context::Sensor(0)]);
    }
}
