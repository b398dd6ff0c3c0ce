//! Least-squares rigid and similarity alignment of corresponding point sets (Umeyama 1991):
//! the rotation, scale and translation minimising `Σ w_i ‖s R a_i + t − b_i‖²`.

use glam::{DAffine3, DMat3, DQuat, DVec3};
use nalgebra::Matrix3;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// A similarity transform `p ↦ scale · rotation · p + translation` (rigid when `scale` = 1).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Similarity {
    /// Rotation (unit quaternion).
    pub rotation: DQuat,
    /// Uniform scale (1 for a rigid fit).
    pub scale: f64,
    /// Translation, in the target's units.
    pub translation: DVec3,
}

impl Similarity {
    /// The transform applied to a point.
    pub fn apply(&self, p: DVec3) -> DVec3 {
        self.scale * (self.rotation * p) + self.translation
    }

    /// The transform as an affine matrix.
    pub fn to_affine(&self) -> DAffine3 {
        DAffine3::from_scale_rotation_translation(
            DVec3::splat(self.scale),
            self.rotation,
            self.translation,
        )
    }
}

/// Whether [`fit_similarity`] may scale.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Alignment {
    /// Rotation and translation only (Kabsch).
    Rigid,
    /// Rotation, uniform scale and translation (Umeyama).
    Similarity,
}

/// The least-squares alignment of `from` onto `to` (corresponding points), optionally
/// weighted (non-negative weights, one per point; `None` for equal weights), by Umeyama's
/// closed form: the SVD of the weighted cross-covariance, with the reflection case corrected
/// so the result is always a proper rotation.
///
/// # Errors
/// [`Error::SizeMismatch`] when the lists (or weights) differ in length;
/// [`Error::NonFinite`] for NaN or infinite coordinates or weights; [`Error::InvalidParam`]
/// for a negative weight; [`Error::Degenerate`] for fewer than three points of positive
/// weight, or `from` points that are (nearly) collinear, so that the rotation about their line
/// is undetermined.
pub fn fit_similarity(
    from: &[DVec3],
    to: &[DVec3],
    weights: Option<&[f64]>,
    alignment: Alignment,
) -> Result<Similarity> {
    crate::check::same_size("alignment point lists", from.len(), to.len())?;
    if let Some(w) = weights {
        crate::check::same_size("alignment weights", from.len(), w.len())?;
        crate::check::all_finite("alignment weights", w)?;
        for &x in w {
            crate::check::non_negative("alignment weight", x)?;
        }
    }
    let weight = |i: usize| weights.map_or(1.0, |w| w[i]);
    for p in from.iter().chain(to) {
        if !p.is_finite() {
            return Err(Error::NonFinite {
                what: "alignment points",
            });
        }
    }
    let used = (0..from.len()).filter(|&i| weight(i) > 0.0).count();
    if used < 3 {
        return Err(Error::Degenerate {
            what: format!("alignment needs at least 3 weighted points, got {used}"),
        });
    }
    let total: f64 = (0..from.len()).map(weight).sum();
    let (mut ca, mut cb) = (DVec3::ZERO, DVec3::ZERO);
    for i in 0..from.len() {
        ca += weight(i) * from[i];
        cb += weight(i) * to[i];
    }
    ca /= total;
    cb /= total;
    // Weighted cross-covariance Σ = Σ w (b − cb)(a − ca)ᵀ / W and the spread of `from`.
    let mut cov = Matrix3::<f64>::zeros();
    let mut spread_a = Matrix3::<f64>::zeros();
    for i in 0..from.len() {
        let w = weight(i) / total;
        let a = from[i] - ca;
        let b = to[i] - cb;
        let av = nalgebra::Vector3::new(a.x, a.y, a.z);
        let bv = nalgebra::Vector3::new(b.x, b.y, b.z);
        cov += w * bv * av.transpose();
        spread_a += w * av * av.transpose();
    }
    // Collinear (or coincident) `from`: the second principal spread vanishes.
    let mut eig: Vec<f64> = spread_a.symmetric_eigenvalues().iter().copied().collect();
    eig.sort_by(|x, y| y.total_cmp(x));
    if eig[0] <= 0.0 || eig[1] <= 1e-12 * eig[0] {
        return Err(Error::Degenerate {
            what: "alignment points are collinear or coincident".into(),
        });
    }
    let svd = cov.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Err(Error::Degenerate {
            what: "alignment covariance SVD failed".into(),
        });
    };
    // D = diag(1, 1, sign(det U det V)) keeps the rotation proper.
    let d = if (u.determinant() * v_t.determinant()) < 0.0 {
        -1.0
    } else {
        1.0
    };
    let mut dm = Matrix3::<f64>::identity();
    dm[(2, 2)] = d;
    let r = u * dm * v_t;
    let scale = match alignment {
        Alignment::Rigid => 1.0,
        Alignment::Similarity => {
            let var_a = spread_a.trace();
            let sv = svd.singular_values;
            (sv[0] + sv[1] + d * sv[2]) / var_a
        }
    };
    let m = DMat3::from_cols_array(&[
        r[(0, 0)],
        r[(1, 0)],
        r[(2, 0)],
        r[(0, 1)],
        r[(1, 1)],
        r[(2, 1)],
        r[(0, 2)],
        r[(1, 2)],
        r[(2, 2)],
    ]);
    let rotation = DQuat::from_mat3(&m).normalize();
    let translation = cb - scale * (rotation * ca);
    Ok(Similarity {
        rotation,
        scale,
        translation,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn cloud(n: usize, seed: u64) -> Vec<DVec3> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..n)
            .map(|_| {
                DVec3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                )
            })
            .collect()
    }

    #[test]
    fn recovers_an_exact_similarity() {
        let a = cloud(20, 1);
        let truth = Similarity {
            rotation: DQuat::from_axis_angle(DVec3::new(1.0, 2.0, -0.5).normalize(), 2.3),
            scale: 1.7,
            translation: DVec3::new(0.3, -4.0, 2.0),
        };
        let b: Vec<DVec3> = a.iter().map(|&p| truth.apply(p)).collect();
        let s = fit_similarity(&a, &b, None, Alignment::Similarity).unwrap();
        // Rotations compared by their action (an angle from acos near 1 is only good to 1e-8).
        let same_rotation = |q: DQuat| {
            [DVec3::X, DVec3::Y, DVec3::Z]
                .iter()
                .all(|&v| (q * v).distance(truth.rotation * v) < 1e-10)
        };
        assert!((s.scale - 1.7).abs() < 1e-12);
        assert!(same_rotation(s.rotation));
        assert!(s.translation.distance(truth.translation) < 1e-10);
        let r = fit_similarity(&a, &b, None, Alignment::Rigid).unwrap();
        assert_eq!(r.scale, 1.0);
        assert!(same_rotation(r.rotation));
    }

    #[test]
    fn a_reflection_gives_a_proper_rotation_and_weights_select_points() {
        let a = cloud(30, 2);
        // A mirror image cannot be reached by a rotation: the fit stays proper.
        let b: Vec<DVec3> = a.iter().map(|p| DVec3::new(-p.x, p.y, p.z)).collect();
        let s = fit_similarity(&a, &b, None, Alignment::Rigid).unwrap();
        assert!((DMat3::from_quat(s.rotation).determinant() - 1.0).abs() < 1e-9);
        // Zero weights drop outliers completely.
        let shift = DVec3::new(0.1, 0.2, 0.3);
        let mut b: Vec<DVec3> = a.iter().map(|&p| p + shift).collect();
        b[0] += DVec3::splat(10.0);
        let mut w = vec![1.0; a.len()];
        w[0] = 0.0;
        let s = fit_similarity(&a, &b, Some(&w), Alignment::Rigid).unwrap();
        assert!(s.translation.distance(shift) < 1e-12);
    }

    #[test]
    fn bad_input_is_an_error() {
        let a = cloud(5, 3);
        assert!(matches!(
            fit_similarity(&a, &a[..4], None, Alignment::Rigid),
            Err(Error::SizeMismatch { .. })
        ));
        let line: Vec<DVec3> = (0..5).map(|i| DVec3::X * i as f64).collect();
        assert!(matches!(
            fit_similarity(&line, &line, None, Alignment::Rigid),
            Err(Error::Degenerate { .. })
        ));
        assert!(matches!(
            fit_similarity(&a[..2], &a[..2], None, Alignment::Rigid),
            Err(Error::Degenerate { .. })
        ));
        let mut nan = a.clone();
        nan[1].y = f64::NAN;
        assert!(matches!(
            fit_similarity(&a, &nan, None, Alignment::Rigid),
            Err(Error::NonFinite { .. })
        ));
        assert!(
            fit_similarity(&a, &a, Some(&[1.0, -1.0, 1.0, 1.0, 1.0]), Alignment::Rigid).is_err()
        );
    }
}
