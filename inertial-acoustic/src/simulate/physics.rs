//! The suit's physics: the garment's placement errors and skin motion, the inertial front
//! ends (zero, slope, noise, bias), the sources' electrical lags, the body's occluding
//! capsules, and the static offset calibration of §4.3.3.

use super::SimulationParams;
use crate::garment::{GarmentPose, GarmentSurface};
use crate::params::{UltrasoundParams, CARRIER_HZ, PULSE_CYCLES, SAMPLES_PER_PULSE};
use crate::suit::{SensorBoard, Suit, UltrasonicSource};
use crate::ultrasound::{
    calibrate_offsets, leave_one_out_errors_m, CalibrationShot, PulseDetector,
};
use crate::{Context, Error, Result, ResultExt};
use dynamic_shapes_studio::{DeformationParams, Performer};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};
use skin_core::check::non_negative;
use skin_core::math::{DQuat, DVec3};
use skin_core::skeleton::{ForwardKinematics, Skeleton};
use std::f64::consts::TAU;

/// Per-axis true analogue front end of one board channel.
#[derive(Debug, Clone, Copy)]
pub(super) struct Channel {
    pub(super) zero: f64,
    pub(super) slope: f64,
    pub(super) noise: f64,
    pub(super) accumulate: bool,
}

impl Channel {
    /// 12-bit count of `value` (four noisy 10-bit samples accumulated, §4.2.3).
    pub(super) fn count(&self, value: f64, rng: &mut ChaCha8Rng, normal: &Normal<f64>) -> i32 {
        if !self.accumulate {
            let v = self.zero + self.slope * (value + self.noise * normal.sample(rng));
            return (v.round() as i32).clamp(0, 4095);
        }
        let mut acc = 0i32;
        for _ in 0..4 {
            let v = self.zero + self.slope * (value + self.noise * normal.sample(rng));
            acc += ((v / 4.0).round() as i32).clamp(0, 1023);
        }
        acc
    }
}

/// A capsule of the body (occlusion model).
#[derive(Debug, Clone, Copy)]
pub(super) struct Capsule {
    pub(super) joint: usize,
    pub(super) tip: DVec3,
    pub(super) radius: f64,
}

pub(super) fn capsule_radius(name: &str) -> f64 {
    let base = name.trim_start_matches("l_").trim_start_matches("r_");
    match base {
        "pelvis" | "spine" | "chest" => 0.10,
        "neck" => 0.05,
        "head" => 0.08,
        "clavicle" => 0.04,
        "shoulder" => 0.04,
        "elbow" => 0.035,
        "wrist" => 0.025,
        "hip" => 0.065,
        "knee" => 0.045,
        "ankle" => 0.035,
        _ => 0.04,
    }
}

/// Closest distance between segments [p0, p1] and [q0, q1].
pub(super) fn segment_distance(p0: DVec3, p1: DVec3, q0: DVec3, q1: DVec3) -> f64 {
    let (d1, d2, r) = (p1 - p0, q1 - q0, p0 - q0);
    let (a, e, f) = (d1.dot(d1), d2.dot(d2), d2.dot(r));
    let (s, t);
    if a <= 1e-12 && e <= 1e-12 {
        return r.length();
    }
    if a <= 1e-12 {
        s = 0.0;
        t = (f / e).clamp(0.0, 1.0);
    } else {
        let c = d1.dot(r);
        if e <= 1e-12 {
            t = 0.0;
            s = (-c / a).clamp(0.0, 1.0);
        } else {
            let b = d1.dot(d2);
            let denom = a * e - b * b;
            let s0 = if denom > 1e-12 {
                ((b * f - c * e) / denom).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let t0 = (b * s0 + f) / e;
            if t0 < 0.0 {
                t = 0.0;
                s = (-c / a).clamp(0.0, 1.0);
            } else if t0 > 1.0 {
                t = 1.0;
                s = ((b - c) / a).clamp(0.0, 1.0);
            } else {
                t = t0;
                s = s0;
            }
        }
    }
    ((p0 + d1 * s) - (q0 + d2 * t)).length()
}

/// `nominal` with random placement errors (position per axis `placement_sd_m`, half that for
/// sources; orientation per axis `placement_sd_deg`).
pub(super) fn perturbed(
    skeleton: &Skeleton,
    nominal: &Suit,
    params: &SimulationParams,
    rng: &mut ChaCha8Rng,
) -> Result<Suit> {
    let normal = Normal::new(0.0, 1.0).map_err(|e| Error::InvalidParam {
        name: "normal",
        reason: e.to_string(),
    })?;
    let mut g3 = |s: f64| {
        DVec3::new(
            normal.sample(&mut *rng),
            normal.sample(&mut *rng),
            normal.sample(&mut *rng),
        ) * s
    };
    let boards: Vec<SensorBoard> = nominal
        .boards()
        .iter()
        .map(|b| SensorBoard {
            offset: b.offset + g3(params.placement_sd_m),
            joint_from_sensor: b.joint_from_sensor
                * DQuat::from_scaled_axis(g3(params.placement_sd_deg.to_radians())),
            ..b.clone()
        })
        .collect();
    let sources: Vec<UltrasonicSource> = nominal
        .sources()
        .iter()
        .map(|s| UltrasonicSource {
            offset: s.offset + g3(0.5 * params.placement_sd_m),
            ..s.clone()
        })
        .collect();
    Suit::new(skeleton, boards, sources)
}

/// The rotation vector of `q` (shortest way round).
pub(super) fn rotation_vector(q: DQuat) -> DVec3 {
    if q.w < 0.0 {
        (-q).to_scaled_axis()
    } else {
        q.to_scaled_axis()
    }
}

/// Static offset calibration of the sources (§4.3.3).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OffsetCalibration {
    /// Per-source offset, samples.
    pub offsets: Vec<f64>,
    /// Leave-one-out absolute distance errors, metres.
    pub loo_abs_errors_m: Vec<f64>,
    /// Signal-to-noise ratio at the farthest placement (0.9 m, on axis): peak amplitude over
    /// noise RMS, dB.
    pub snr_db_at_90cm: f64,
}

/// The simulated suit.
#[derive(Debug, Clone)]
pub struct SuitSimulator {
    pub(super) skeleton: Skeleton,
    pub(super) nominal: Suit,
    pub(super) true_suit: Suit,
    pub(super) params: SimulationParams,
    pub(super) ultrasound: UltrasoundParams,
    pub(super) capsules: Vec<Capsule>,
    /// The garment surface the boards and sources ride on, if any.
    pub(super) garment: Option<GarmentSurface>,
    /// Height of the floor (reflections), metres.
    pub(super) floor_y: f64,
    pub(super) slide_dir: Vec<DVec3>,
    /// Per-source electrical delay, seconds (why calibrated offsets differ between sources).
    pub(super) source_lags_s: Vec<f64>,
}

impl SuitSimulator {
    /// The thesis's suit on `skeleton` with random placement errors; boards slide along their
    /// bone by [`SimulationParams::skin_slide_m_per_rad`] (the stand-in for skin motion when
    /// there is no performer surface).
    ///
    /// # Errors
    /// As [`Suit::vlasic`]; [`Error::Core`] for invalid parameters.
    pub fn new(skeleton: &Skeleton, params: SimulationParams) -> Result<Self> {
        params.validate()?;
        let nominal = Suit::vlasic(skeleton)?;
        let mut rng = ChaCha8Rng::seed_from_u64(params.seed ^ 0x5u64);
        let true_suit = perturbed(skeleton, &nominal, &params, &mut rng)?;
        Self::assemble(skeleton, nominal, true_suit, None, 0.0, params, &mut rng)
    }

    /// The thesis's suit on the garment over `performer`'s skin ([`GarmentSurface`]): the
    /// table's positions are snapped to the rest body surface (the nominal suit the filter is
    /// told), the true placements carry the random placement errors and are snapped too, and
    /// every board and source then moves with the performer's pose-driven deformation
    /// (`deformation`: the parameters the performer was built with) instead of rigidly with
    /// its bone. [`SimulationParams::skin_slide_m_per_rad`] is not used.
    ///
    /// # Errors
    /// As [`Suit::vlasic`] and [`GarmentSurface::new`]; [`Error::Core`] for invalid
    /// parameters.
    pub fn on_performer(
        performer: &Performer,
        deformation: &DeformationParams,
        params: SimulationParams,
    ) -> Result<Self> {
        params.validate()?;
        let skeleton = &performer.skeleton;
        let (_, nominal) = GarmentSurface::new(performer, deformation, &Suit::vlasic(skeleton)?)?;
        let mut rng = ChaCha8Rng::seed_from_u64(params.seed ^ 0x5u64);
        let placed = perturbed(skeleton, &nominal, &params, &mut rng)?;
        let (surface, true_suit) = GarmentSurface::new(performer, deformation, &placed)?;
        // The floor under the performer's feet at rest (the template's lowest point).
        let floor_y = performer
            .template
            .vertices
            .iter()
            .map(|v| v.y)
            .fold(f64::INFINITY, f64::min);
        Self::assemble(
            skeleton,
            nominal,
            true_suit,
            Some(surface),
            floor_y,
            params,
            &mut rng,
        )
    }

    /// The same suit (same nominal and true placements, same seed) fixed rigidly to the bones:
    /// no surface deformation and no slide — the baseline that shows what skin motion costs.
    pub fn with_rigid_attachment(mut self) -> Self {
        self.garment = None;
        self.params.skin_slide_m_per_rad = 0.0;
        self
    }

    /// The same suit (placements, front ends, seed) with the gyroscopes' bias model
    /// replaced ([`SimulationParams::gyro_bias`]).
    ///
    /// # Errors
    /// As [`GyroBiasModel::validate`](super::GyroBiasModel::validate).
    pub fn with_gyro_bias(mut self, gyro_bias: super::GyroBiasModel) -> Result<Self> {
        gyro_bias.validate()?;
        self.params.gyro_bias = gyro_bias;
        Ok(self)
    }

    /// The same suit (same placements and seed) on another inertial link: its bit error rate
    /// and key interval ([`SimulationParams::bit_error_rate`],
    /// [`SimulationParams::key_interval`]), e.g. to sweep the bit error rate on one suit.
    ///
    /// # Errors
    /// [`Error::Core`] (invalid parameter) for a negative or non-finite rate; as
    /// [`DeltaCodec::with_key_interval`](crate::DeltaCodec::with_key_interval) for a bad interval.
    pub fn with_link(mut self, bit_error_rate: f64, key_interval: u32) -> Result<Self> {
        non_negative("bit_error_rate", bit_error_rate)?;
        self.params.bit_error_rate = bit_error_rate;
        self.params.key_interval = key_interval;
        self.params.codec()?;
        Ok(self)
    }

    /// Whether the boards and sources ride on a performer's deforming surface.
    pub fn on_garment_surface(&self) -> bool {
        self.garment.is_some()
    }

    fn assemble(
        skeleton: &Skeleton,
        nominal: Suit,
        true_suit: Suit,
        garment: Option<GarmentSurface>,
        floor_y: f64,
        params: SimulationParams,
        rng: &mut ChaCha8Rng,
    ) -> Result<Self> {
        let mut capsules = Vec::new();
        for (j, joint) in skeleton.joints().iter().enumerate() {
            let r = capsule_radius(&joint.name);
            if let Some(e) = joint.end_site {
                capsules.push(Capsule {
                    joint: j,
                    tip: e,
                    radius: r,
                });
            }
            for c in skeleton.children(j) {
                capsules.push(Capsule {
                    joint: j,
                    tip: skeleton.joints()[c].offset,
                    radius: r,
                });
            }
        }
        let source_lags_s = (0..nominal.sources().len())
            .map(|_| 20e-6 + 10e-6 * rng.random::<f64>())
            .collect();
        let slide_dir = nominal
            .boards()
            .iter()
            .map(|b| b.offset.normalize_or_zero())
            .collect();
        Ok(SuitSimulator {
            skeleton: skeleton.clone(),
            nominal,
            true_suit,
            garment,
            floor_y,
            params,
            ultrasound: UltrasoundParams::default(),
            capsules,
            slide_dir,
            source_lags_s,
        })
    }

    /// The nominal suit (what the filter is told).
    pub fn nominal_suit(&self) -> &Suit {
        &self.nominal
    }

    /// Forward kinematics at θ and the world placement of every board and source: on the
    /// garment surface, or fixed to the bone (plus the slide rule).
    pub(super) fn placement(&self, theta: &[f64]) -> Result<(ForwardKinematics, GarmentPose)> {
        let fk = self.skeleton.forward_kinematics(theta)?;
        if let Some(g) = &self.garment {
            let pose = g.pose(theta)?;
            return Ok((fk, pose));
        }
        let (mut board_positions, mut board_rotations) = (Vec::new(), Vec::new());
        for (b, board) in self.true_suit.boards().iter().enumerate() {
            let slide: f64 = self
                .skeleton
                .joint_dofs(board.joint)
                .filter(|&d| self.skeleton.is_rotation(d))
                .map(|d| theta[d])
                .sum::<f64>()
                * self.params.skin_slide_m_per_rad;
            let mut p = board.point();
            p.offset += self.slide_dir[b] * slide;
            board_positions.push(fk.point(&p)?);
            board_rotations.push(fk.frame_rotation(&board.frame())?);
        }
        let source_positions = self
            .true_suit
            .sources()
            .iter()
            .map(|s| fk.point(&s.point()))
            .collect::<std::result::Result<_, _>>()?;
        let source_normals = self
            .true_suit
            .sources()
            .iter()
            .map(|s| fk.world_from_joint()[s.joint].matrix3 * s.normal)
            .collect();
        Ok((
            fk,
            GarmentPose {
                board_positions,
                board_rotations,
                source_positions,
                source_normals,
            },
        ))
    }

    /// The piezo burst: 10 cycles with exponential ring-up, then ring-down (τ = 60 µs).
    fn burst(t: f64) -> f64 {
        const TAU_S: f64 = 60e-6;
        let len = PULSE_CYCLES as f64 / CARRIER_HZ;
        if t < 0.0 {
            return 0.0;
        }
        let env = if t < len {
            1.0 - (-t / TAU_S).exp()
        } else {
            (1.0 - (-len / TAU_S).exp()) * (-(t - len) / TAU_S).exp()
        };
        env * (TAU * CARRIER_HZ * t).sin()
    }

    /// Adds a burst arriving `delay_s` after the frame start with `amplitude`.
    pub(super) fn add_burst(frame: &mut [f32], delay_s: f64, amplitude: f64, fs: f64) {
        let start = (delay_s * fs).floor().max(0.0) as usize;
        let end = (start + 200).min(frame.len());
        for (n, v) in frame.iter_mut().enumerate().take(end).skip(start) {
            *v += (amplitude * Self::burst(n as f64 / fs - delay_s)) as f32;
        }
    }

    /// Noise plus the multiplexed digital stream (13 kbit/s).
    pub(super) fn background(&self, frame: &mut [f32], rng: &mut ChaCha8Rng, normal: &Normal<f64>) {
        let fs = self.ultrasound.sample_rate_hz;
        let samples_per_bit = fs / 13_000.0;
        let mut bit = 0.0;
        let mut next_bit = 0.0;
        for (n, v) in frame.iter_mut().enumerate() {
            if n as f64 >= next_bit {
                bit = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
                next_bit += samples_per_bit;
            }
            *v = (self.params.mic_noise * normal.sample(rng) + self.params.digital_crosstalk * bit)
                as f32;
        }
    }

    /// Source directivity: `0.2 + 0.8 cos` in front, a weak back lobe (0.05) behind.
    pub(super) fn directivity(cos_angle: f64) -> f64 {
        if cos_angle > 0.0 {
            0.2 + 0.8 * cos_angle
        } else {
            0.05
        }
    }

    /// Static calibration (§4.3.3): every source with a microphone at 7 distances from 30 to
    /// 90 cm, at random angles within 60° of its axis, no body, a bench (no floor echo).
    ///
    /// # Errors
    /// [`Error::Empty`] if a source is never detected on the bench.
    pub fn calibrate_offsets(&self, seed: u64) -> Result<OffsetCalibration> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let normal = Normal::new(0.0, 1.0).map_err(|e| Error::InvalidParam {
            name: "normal",
            reason: e.to_string(),
        })?;
        let mut det = PulseDetector::new(self.ultrasound)?;
        let fs = self.ultrasound.sample_rate_hz;
        let c = self.ultrasound.speed_of_sound_m_s;
        let ns = self.nominal.sources().len();
        let mut shots = Vec::new();
        let mut frame = vec![0f32; SAMPLES_PER_PULSE];
        for s in 0..ns {
            let lag_s = self.source_lags_s[s];
            for i in 0..7 {
                let d = 0.3 + 0.1 * i as f64;
                let angle = (rng.random::<f64>() * 60.0).to_radians();
                self.background(&mut frame, &mut rng, &normal);
                let amp = self.params.source_amplitude / d * Self::directivity(angle.cos());
                Self::add_burst(&mut frame, d / c + lag_s, amp, fs);
                if let Some(x) = det.detect(&frame).at(Context::Source(s))? {
                    shots.push(CalibrationShot {
                        source: s,
                        inflection_sample: x.inflection_sample,
                        distance_m: d,
                    });
                }
            }
        }
        let offsets = calibrate_offsets(&shots, ns, &self.ultrasound)?;
        let loo = leave_one_out_errors_m(&shots, ns, &self.ultrasound)?;
        let snr = 20.0 * (self.params.source_amplitude / 0.9 / self.params.mic_noise).log10();
        Ok(OffsetCalibration {
            offsets,
            loo_abs_errors_m: loo.iter().map(|e| e.abs()).collect(),
            snr_db_at_90cm: snr,
        })
    }
}

/// Per-frame geometry kept for the ultrasonic pass.
pub(super) struct Geometry {
    pub(super) boards: Vec<DVec3>,
    pub(super) sources: Vec<DVec3>,
    pub(super) normals: Vec<DVec3>,
    pub(super) capsules: Vec<(DVec3, DVec3)>,
}

pub(super) fn lerp_geometry(a: &Geometry, b: &Geometry, u: f64) -> Geometry {
    let l = |x: &[DVec3], y: &[DVec3]| -> Vec<DVec3> {
        x.iter().zip(y).map(|(p, q)| p.lerp(*q, u)).collect()
    };
    Geometry {
        boards: l(&a.boards, &b.boards),
        sources: l(&a.sources, &b.sources),
        normals: l(&a.normals, &b.normals),
        capsules: a
            .capsules
            .iter()
            .zip(&b.capsules)
            .map(|(p, q)| (p.0.lerp(q.0, u), p.1.lerp(q.1, u)))
            .collect(),
    }
}
