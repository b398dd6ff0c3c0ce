//! The orientation part of the filter for one sensor board (§4.4 restricted to a single free
//! rotation): gyroscope (Eq. 4.3) and accelerometer (Eq. 4.2 without the point's linear
//! acceleration, which a lone board cannot model) fused by the same dynamics as the skeletal
//! filter — state (rotation, rate, angular acceleration), `r += Δt ω`, `ω += Δt ω̇`,
//! `ω̇ += w` with `w ~ N(0, process_sigma²)` per step — and the same sequential scalar updates.
//!
//! The rotation is kept as a quaternion with a 3-vector error state in the board's own axes
//! (`R = R̂ exp([δ]ₓ)`, folded into `R̂` after every step), and the rate in the board's axes:
//! unlike the skeleton's Euler joints this has no singular pose, so it runs on real
//! recordings of arbitrary rotations (the BROAD and x-io logs in the example and tests).
//!
//! Initialisation follows §4.4.4 for one board: over a rest interval the gyroscope offset is
//! the mean reading (it then integrates to zero over the rest) and the tilt is the rotation
//! that aligns the mean accelerometer reading with `up` (the heading is unobservable without
//! a magnetometer and is left at zero).
//!
//! [`FilterParams`] supplies every noise level (its `sensors` switch the accelerometer and
//! gyroscope rows on and off; distances do not apply).

use crate::ekf::InertialReading;
use crate::params::FilterParams;
use crate::{Context, Error, Result, ResultExt};
use nalgebra::{SMatrix, SVector};
use skin_core::math::{DQuat, DVec3};

type Mat9 = SMatrix<f64, 9, 9>;
type Vec9 = SVector<f64, 9>;

/// Orientation of one board at rest (§4.4.4 for a single sensor).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RestAlignment {
    /// Board-to-world rotation whose accelerometer direction matches `up` (zero heading).
    pub orientation: DQuat,
    /// Mean gyroscope reading over the rest, rad/s (subtracted from every reading).
    pub gyro_offset_rad_s: DVec3,
}

impl RestAlignment {
    /// Tilt and gyroscope offset from readings taken at rest, with `up` the world's up axis.
    ///
    /// # Errors
    /// [`Error::Empty`] without readings; [`Error::NonFinite`] (at the frame) for a NaN
    /// reading; [`Error::InvalidParam`] if `up` or the mean accelerometer reading is zero.
    pub fn from_rest(rest: &[InertialReading], up: DVec3) -> Result<Self> {
        if rest.is_empty() {
            return Err(Error::Empty {
                what: "rest readings",
            });
        }
        let (mut g, mut a) = (DVec3::ZERO, DVec3::ZERO);
        for (i, r) in rest.iter().enumerate() {
            check_reading(r).at(Context::Frame(i))?;
            g += r.gyro_rad_s;
            a += r.accel_m_s2;
        }
        let n = rest.len() as f64;
        let up = unit("up", up)?;
        let a = unit("mean rest accelerometer reading", a / n)?;
        Ok(RestAlignment {
            orientation: DQuat::from_rotation_arc(a, up),
            gyro_offset_rad_s: g / n,
        })
    }
}

fn unit(name: &'static str, v: DVec3) -> Result<DVec3> {
    let l = v.length();
    if l.is_finite() && l > 0.0 {
        Ok(v / l)
    } else {
        Err(Error::InvalidParam {
            name,
            reason: format!("must be a finite non-zero vector, got {v}"),
        })
    }
}

fn check_reading(r: &InertialReading) -> Result<()> {
    skin_core::check::all_finite(
        "inertial reading",
        r.gyro_rad_s
            .to_array()
            .iter()
            .chain(r.accel_m_s2.to_array().iter()),
    )?;
    Ok(())
}

/// One board's orientation filter: the skeletal EKF's dynamics and inertial rows for a single
/// free rotation (see the module docs).
#[derive(Debug, Clone)]
pub struct OrientationEkf {
    params: FilterParams,
    up: DVec3,
    offset: DVec3,
    q: DQuat,
    good_q: DQuat,
    /// (δ, ω, ω̇); δ is zero between steps.
    x: Vec9,
    p: Mat9,
    p0: Mat9,
}

/// What one [`OrientationEkf::step`] did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct OrientationStep {
    /// Scalar rows applied (3 per sensor type used).
    pub rows: usize,
    /// The filter diverged (non-finite state or a rate above `divergence_rate`) and was reset
    /// to its last good orientation at rest.
    pub diverged: bool,
}

impl OrientationEkf {
    /// A filter starting at `start` (board-to-world) at rest; `up` is the world's up axis (the
    /// accelerometer reads `gravity_m_s2 · up` at rest).
    ///
    /// # Errors
    /// As [`FilterParams::validate`]; [`Error::InvalidParam`] for a zero `up` or an invalid
    /// start rotation.
    pub fn new(params: FilterParams, up: DVec3, start: RestAlignment) -> Result<Self> {
        params.validate()?;
        let up = unit("up", up)?;
        let q = start.orientation;
        if !(q.is_finite() && (q.length() - 1.0).abs() < 1e-6) {
            return Err(Error::InvalidParam {
                name: "start orientation",
                reason: format!("must be a unit quaternion, got {q}"),
            });
        }
        skin_core::check::all_finite("gyro offset", start.gyro_offset_rad_s.to_array().iter())?;
        let (s0, s1, s2) = params.initial_sigma;
        let mut p0 = Mat9::zeros();
        for i in 0..3 {
            p0[(i, i)] = s0 * s0;
            p0[(3 + i, 3 + i)] = s1 * s1;
            p0[(6 + i, 6 + i)] = s2 * s2;
        }
        Ok(OrientationEkf {
            params,
            up,
            offset: start.gyro_offset_rad_s,
            q,
            good_q: q,
            x: Vec9::zeros(),
            p: p0,
            p0,
        })
    }

    /// Current board-to-world rotation.
    pub fn orientation(&self) -> DQuat {
        self.q
    }

    /// Current angular rate in the board's axes, rad/s.
    pub fn rate_rad_s(&self) -> DVec3 {
        DVec3::new(self.x[3], self.x[4], self.x[5])
    }

    /// One time step (`params.frame_time_s`) and the reading's updates.
    ///
    /// # Errors
    /// [`Error::NonFinite`] for a NaN or infinite reading (the filter is left unchanged).
    pub fn step(&mut self, reading: &InertialReading) -> Result<OrientationStep> {
        check_reading(reading)?;
        let mut report = OrientationStep::default();
        self.predict_rates();
        let sensors = self.params.sensors;
        if sensors.gyroscopes {
            // Eq. 4.3 for one board: the gyroscope reads the board's rate (offset removed).
            let z = reading.gyro_rad_s - self.offset;
            let r = self.params.gyroscope_sigma.powi(2);
            for k in 0..3 {
                let mut h = Vec9::zeros();
                h[3 + k] = 1.0;
                self.scalar_update(&h, z[k] - self.x[3 + k], r);
                report.rows += 1;
            }
        }
        // The rotation integrates the step's rate (semi-implicit Euler): a gyroscope sample
        // is the mean rate over the interval that ends at its time stamp.
        self.predict_rotation();
        let v = self.q.inverse() * (self.params.gravity_m_s2 * self.up);
        if sensors.accelerometers {
            // Eq. 4.2 without the linear acceleration: a = R̂ᵀ g·up, and for R = R̂ exp([δ]ₓ)
            // a ≈ v + v × δ, so the rows are those of [v]ₓ.
            let x0 = self.x;
            let r = self.params.accelerometer_sigma.powi(2);
            let rows = [[0.0, -v.z, v.y], [v.z, 0.0, -v.x], [-v.y, v.x, 0.0]];
            for (k, row) in rows.iter().enumerate() {
                let mut h = Vec9::zeros();
                h.fixed_rows_mut::<3>(0).copy_from_slice(row);
                // Innovation at the linearisation point, corrected to first order for the
                // rows before it (as the skeletal filter does).
                let innov = reading.accel_m_s2[k] - v[k] - h.dot(&(self.x - x0));
                self.scalar_update(&h, innov, r);
                report.rows += 1;
            }
        }
        // Fold the error rotation into the quaternion.
        let d = DVec3::new(self.x[0], self.x[1], self.x[2]);
        self.q = (self.q * DQuat::from_scaled_axis(d)).normalize();
        self.x.fixed_rows_mut::<3>(0).fill(0.0);
        let rate_ok = self.rate_rad_s().length() <= self.params.divergence_rate;
        let finite = self.q.is_finite()
            && self.x.iter().all(|v| v.is_finite())
            && (0..9).all(|i| self.p[(i, i)].is_finite() && self.p[(i, i)] >= 0.0);
        if !(rate_ok && finite) {
            report.diverged = true;
            self.q = self.good_q;
            self.x = Vec9::zeros();
            self.p = self.p0;
        } else {
            self.good_q = self.q;
        }
        Ok(report)
    }

    /// Eq. 4.1, rates part: `ω += Δt ω̇`, `ω̇ += w`.
    fn predict_rates(&mut self) {
        let dt = self.params.frame_time_s;
        for i in 0..3 {
            self.x[3 + i] += dt * self.x[6 + i];
        }
        let mut f = Mat9::identity();
        for r in 0..3 {
            f[(3 + r, 6 + r)] = dt;
        }
        self.p = f * self.p * f.transpose();
        let q = self.params.process_sigma.powi(2);
        for i in 6..9 {
            self.p[(i, i)] += q;
        }
    }

    /// Eq. 4.1, rotation part, with the rate of the step (after the gyroscope rows): the
    /// quaternion turns by `exp(ωΔt)` and the error state follows `δ' = exp(−[ωΔt]ₓ) δ + Δt δω`.
    ///
    /// Checked against the skeletal filter's first-order-step bias: the gyroscope row reads the
    /// state's rate, and a gyroscope sample is the mean rate over the interval that ends at its
    /// time stamp, so the rate after the rows is that interval's mean and `Δt ω` is the interval's
    /// rotation exactly (about a fixed axis) —
    /// no `½Δt² ω̇` is missing (test `mean_rate_samples_of_a_constant_angular_acceleration_integrate_exactly`).
    /// Reading the samples as instantaneous rates instead (turning by `Δt ω − ½Δt² ω̇`, the
    /// constant-acceleration transition for that reading) made BROAD worse, 1.57° / 0.80° →
    /// 2.35° / 1.34° (inclination / heading, `examples/inertial_capture`).
    fn predict_rotation(&mut self) {
        let dt = self.params.frame_time_s;
        let step = DQuat::from_scaled_axis(self.rate_rad_s() * dt);
        self.q = (self.q * step).normalize();
        let rt = skin_core::math::DMat3::from_quat(step.inverse());
        let mut f = Mat9::identity();
        for r in 0..3 {
            for c in 0..3 {
                f[(r, c)] = rt.col(c)[r];
            }
            f[(r, 3 + r)] = dt;
        }
        self.p = f * self.p * f.transpose();
    }

    fn scalar_update(&mut self, h: &Vec9, innov: f64, r: f64) {
        let ph = self.p * h;
        let s = h.dot(&ph) + r;
        if !(s.is_finite() && s > 0.0) {
            return;
        }
        self.x += ph * (innov / s);
        self.p -= ph * ph.transpose() / s;
        self.p = (self.p + self.p.transpose()) * 0.5;
    }
}

/// Orientation error of an estimate against a reference, split as the BROAD benchmark does
/// (Laidig et al. 2021): the error rotation `q_ref q_est⁻¹` (world axes) is decomposed into a
/// twist about `up` (heading) and the remaining swing (inclination).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct HeadingInclinationRmse {
    /// RMS inclination error, degrees.
    pub inclination_deg: f64,
    /// RMS heading error after removing the constant heading offset (circular mean), degrees.
    pub heading_deg: f64,
    /// The removed heading offset, degrees.
    pub heading_offset_deg: f64,
    /// Samples scored.
    pub samples: usize,
}

impl HeadingInclinationRmse {
    /// `√(inclination² + heading²)`, degrees: the RMS of the (inclination, heading) error
    /// pair over the scored samples — one figure for both parts, as used to tune a filter's
    /// gain on a recording.
    pub fn combined_deg(&self) -> f64 {
        self.inclination_deg.hypot(self.heading_deg)
    }
}

/// Heading and inclination RMSE of `estimate` against `reference` over the samples where
/// `use_sample` is true and the reference is finite (optical references lose markers).
///
/// # Errors
/// [`Error::SizeMismatch`] for different lengths; [`Error::NonFinite`] for a non-finite
/// estimate on a scored sample; [`Error::Empty`] when no sample is scored;
/// [`Error::InvalidParam`] for a zero `up`.
pub fn heading_inclination_rmse(
    estimate: &[DQuat],
    reference: &[DQuat],
    use_sample: &[bool],
    up: DVec3,
) -> Result<HeadingInclinationRmse> {
    skin_core::check::same_size("reference orientations", estimate.len(), reference.len())?;
    skin_core::check::same_size("sample mask", estimate.len(), use_sample.len())?;
    let up = unit("up", up)?;
    let mut heading = Vec::new();
    let mut incl_sq = 0.0;
    for (i, ((e, r), &u)) in estimate.iter().zip(reference).zip(use_sample).enumerate() {
        if !u || !r.is_finite() {
            continue;
        }
        if !e.is_finite() {
            return Err(Error::NonFinite { what: "estimate" }).at(Context::Frame(i));
        }
        let d = *r * e.inverse();
        let along = d.xyz().dot(up);
        let h = 2.0 * along.atan2(d.w);
        // |w| of the swing: the twist removes the along-up part of the vector.
        let swing_w = (d.w * d.w + along * along).sqrt().min(1.0);
        incl_sq += (2.0 * swing_w.acos()).powi(2);
        heading.push(h);
    }
    if heading.is_empty() {
        return Err(Error::Empty {
            what: "scored samples",
        });
    }
    let n = heading.len() as f64;
    let (s, c) = heading
        .iter()
        .fold((0.0, 0.0), |(s, c), h| (s + h.sin(), c + h.cos()));
    let offset = s.atan2(c);
    let head_sq = heading
        .iter()
        .map(|h| {
            let e = h - offset;
            e.sin().atan2(e.cos()).powi(2)
        })
        .sum::<f64>();
    Ok(HeadingInclinationRmse {
        inclination_deg: (incl_sq / n).sqrt().to_degrees(),
        heading_deg: (head_sq / n).sqrt().to_degrees(),
        heading_offset_deg: offset.to_degrees(),
        samples: heading.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::SensorSet;

    fn still(q: DQuat) -> InertialReading {
        InertialReading::new(DVec3::ZERO, q.inverse() * DVec3::Z * 9.80665)
    }

    #[test]
    fn rest_alignment_recovers_tilt_and_offset() {
        let q = DQuat::from_rotation_x(0.3) * DQuat::from_rotation_y(-0.2);
        let mut r = still(q);
        r.gyro_rad_s = DVec3::new(0.01, -0.02, 0.005);
        let a = RestAlignment::from_rest(&[r; 10], DVec3::Z).unwrap();
        assert!((a.gyro_offset_rad_s - r.gyro_rad_s).length() < 1e-12);
        // Same tilt: the up axis maps to the same board direction.
        let up_a = a.orientation.inverse() * DVec3::Z;
        let up_q = q.inverse() * DVec3::Z;
        assert!((up_a - up_q).length() < 1e-9);
        assert!(RestAlignment::from_rest(&[], DVec3::Z).is_err());
        let mut bad = r;
        bad.accel_m_s2.x = f64::NAN;
        assert!(RestAlignment::from_rest(&[r, bad], DVec3::Z).is_err());
        assert!(RestAlignment::from_rest(&[r], DVec3::ZERO).is_err());
    }

    /// A constant rotation about a tilted axis: the filter tracks it with gyro + accel, and
    /// the accelerometer corrects a wrong initial tilt that gyro-only integration keeps.
    #[test]
    fn tracks_a_constant_rotation_and_corrects_tilt() {
        let dt = 0.01;
        let params = FilterParams {
            frame_time_s: dt,
            process_sigma: 1.0,
            accelerometer_sigma: 0.5,
            ..FilterParams::default()
        };
        let w = DVec3::new(0.5, 1.0, -0.3);
        let wrong = RestAlignment {
            orientation: DQuat::from_rotation_x(0.2),
            gyro_offset_rad_s: DVec3::ZERO,
        };
        let mut fused = OrientationEkf::new(params, DVec3::Z, wrong).unwrap();
        let gyro_only = params.with_sensors(SensorSet {
            accelerometers: false,
            ..SensorSet::ALL
        });
        let mut gyro = OrientationEkf::new(gyro_only, DVec3::Z, wrong).unwrap();
        let mut q = DQuat::IDENTITY;
        for _ in 0..2000 {
            q = (q * DQuat::from_scaled_axis(w * dt)).normalize();
            let mut r = still(q);
            r.gyro_rad_s = w;
            assert!(!fused.step(&r).unwrap().diverged);
            gyro.step(&r).unwrap();
        }
        let tilt = |e: DQuat| heading_inclination_rmse(&[e], &[q], &[true], DVec3::Z).unwrap();
        assert!(tilt(fused.orientation()).inclination_deg < 0.5);
        assert!(tilt(gyro.orientation()).inclination_deg > 5.0);
        assert!((fused.rate_rad_s() - w).length() < 0.01);
        let mut bad = still(q);
        bad.gyro_rad_s.y = f64::INFINITY;
        assert!(fused.step(&bad).is_err());
    }

    /// A constant angular acceleration about a fixed axis, gyroscope rows only, each sample
    /// the mean rate over the interval ending at its time stamp (the filter's reading of a
    /// sample): the rotation integrates to the truth — no `½Δt² α` per step is lost or gained
    /// (that bias would add up to ½ T Δt α = 0.5 · 10 s · 0.01 s · 0.6 rad/s² = 1.7° here).
    #[test]
    fn mean_rate_samples_of_a_constant_angular_acceleration_integrate_exactly() {
        let dt = 0.01;
        let params = FilterParams {
            frame_time_s: dt,
            process_sigma: 1.0,
            gyroscope_sigma: 0.001,
            ..FilterParams::default()
        }
        .with_sensors(SensorSet {
            accelerometers: false,
            ..SensorSet::ALL
        });
        let axis = DVec3::new(0.3, -0.5, 0.8).normalize();
        let alpha = 0.6;
        let start = RestAlignment {
            orientation: DQuat::IDENTITY,
            gyro_offset_rad_s: DVec3::ZERO,
        };
        let mut f = OrientationEkf::new(params, DVec3::Z, start).unwrap();
        let n = 1000;
        for k in 1..=n {
            // Mean of α t over ((k − 1) Δt, k Δt].
            let mean_rate = alpha * (k as f64 - 0.5) * dt;
            let r = InertialReading::new(axis * mean_rate, DVec3::Z * 9.80665);
            assert!(!f.step(&r).unwrap().diverged);
        }
        let t = n as f64 * dt;
        let truth = DQuat::from_scaled_axis(axis * (0.5 * alpha * t * t));
        let d = truth * f.orientation().inverse();
        let err = (2.0 * d.xyz().length().atan2(d.w.abs())).to_degrees();
        assert!(err < 0.1, "{err:.3}°");
    }

    #[test]
    fn divergence_resets_to_the_last_good_orientation() {
        let params = FilterParams {
            divergence_rate: 5.0,
            ..FilterParams::default()
        };
        let start = RestAlignment {
            orientation: DQuat::IDENTITY,
            gyro_offset_rad_s: DVec3::ZERO,
        };
        let mut f = OrientationEkf::new(params, DVec3::Z, start).unwrap();
        let mut r = still(DQuat::IDENTITY);
        r.gyro_rad_s = DVec3::new(0.0, 0.0, 50.0);
        let rep = f.step(&r).unwrap();
        assert!(rep.diverged);
        assert!(f.orientation().is_finite());
        assert_eq!(f.rate_rad_s(), DVec3::ZERO);
    }

    #[test]
    fn heading_offset_is_removed_and_inclination_kept() {
        let refs: Vec<DQuat> = (0..50)
            .map(|i| DQuat::from_rotation_x(0.01 * i as f64) * DQuat::from_rotation_z(0.1))
            .collect();
        // Estimate = reference turned 40° about up, plus a 2° tilt error on every sample.
        let est: Vec<DQuat> = refs
            .iter()
            .map(|r| DQuat::from_rotation_y(2f64.to_radians()) * DQuat::from_rotation_z(0.7) * *r)
            .collect();
        let mut mask = vec![true; 50];
        mask[3] = false;
        let mut refs_nan = refs.clone();
        refs_nan[7] = DQuat::from_xyzw(f64::NAN, 0.0, 0.0, 1.0);
        let e = heading_inclination_rmse(&est, &refs_nan, &mask, DVec3::Z).unwrap();
        assert_eq!(e.samples, 48);
        assert!((e.inclination_deg - 2.0).abs() < 1e-6, "{e:?}");
        assert!(
            (e.heading_offset_deg + 0.7f64.to_degrees()).abs() < 0.1,
            "{e:?}"
        );
        assert!(e.heading_deg < 0.1, "{e:?}");
        // The pair's RMS: the 2° tilt with next to no heading error left.
        assert!((e.combined_deg() - 2.0).abs() < 0.01, "{e:?}");
        assert!(heading_inclination_rmse(&est, &refs, &mask[1..], DVec3::Z).is_err());
        assert!(heading_inclination_rmse(&est, &refs, &[false; 50], DVec3::Z).is_err());
    }
}
