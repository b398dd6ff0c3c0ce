//! Tracking of 3-D marker sets through a sequence with the three-frame rule of particle
//! tracking velocimetry (Fua et al. §2.4, after Maas et al. 1992).
//!
//! A point of `Set_i` defines a search volume in `Set_{i+1}` (a sphere of radius the maximum
//! velocity times one frame). When two or more candidates lie in it, each feasible connection
//! is extrapolated to `Set_{i+2}`, where a reduced volume (radius the maximum acceleration
//! times one frame²) is searched; if still ambiguous, the connection with the smallest
//! acceleration (difference of the velocity vectors of adjacent frames) wins. A trajectory
//! with two or more points is continued the same way from its own velocity. Conflicts (two
//! trajectories wanting one point) go to the smaller acceleration. Unmatched trajectories end
//! ("the trajectories are broken") and unused points start new ones.

use crate::check::{all_finite, positive};
use crate::math::DVec3;
use crate::{Context, Result, ResultExt};

/// Largest speed of a point on the human body, m/s: an upper bound for any skin marker, used
/// as the premise of the velocity search volume (§2.4: "the premise of a maximum velocity of
/// the movement"; the paper gives no value). Among the fastest body points measured in sport
/// is the throwing hand at ball release, which moves with the ball: pitched-ball speed at
/// release 37.4 ± 0.8 m/s in the faster group of 30 collegiate pitchers (Kageyama, Sugiyama,
/// Takai, Kanehisa, Maeda 2014, *J. Sports Sci. Med.* 13: 742–750, three-dimensional motion
/// analysis);
/// 40 m/s is that mean plus three standard deviations, rounded up. (Other segments are
/// slower: an Olympic boxer's fist 9.14 ± 2.06 m/s at impact, Walilko, Viano, Bir 2005,
/// *Br. J. Sports Med.* 39: 710–719, high-speed video of 18 straight punches.)
pub const HUMAN_MAX_SPEED_M_PER_S: f64 = 40.0;

/// Largest acceleration of a point on the human body, m/s², as seen at camera frame rates:
/// the premise of the reduced (acceleration) search volume (§2.4; the paper gives no value).
/// No published peak acceleration of a skin marker was found to cite; this value is derived.
/// In pitching the hand is brought to the release speed during the arm-acceleration phase,
/// from maximum shoulder external rotation to ball release, which lasts about 50 ms (Pappas,
/// Zawacki, Sullivan 1985, *Am. J. Sports Med.* 13: 216–222, high-speed film of 147 pitches
/// by 15 major-league pitchers). Reaching [`HUMAN_MAX_SPEED_M_PER_S`] from rest in 50 ms
/// takes a mean of 800 m/s²; the tracker's second difference at 60 Hz averages the
/// acceleration over 33 ms, so a mean over a comparable window is the quantity it bounds.
/// Impacts (a fist or a foot stopped by a target) decelerate far harder for a few
/// milliseconds, which no frame-rate tracker follows.
pub const HUMAN_MAX_ACCELERATION_M_PER_S2: f64 = 800.0;

/// Parameters of [`track_markers`] (the paper names the two limits but gives no values; they
/// are per frame, so they depend on the frame rate: [`TrackParams::from_limits`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackParams {
    /// Largest marker displacement between adjacent frames, m (the velocity search volume).
    pub max_velocity_m_per_frame: f64,
    /// Largest change of that displacement between adjacent frame pairs, m (the reduced,
    /// acceleration search volume).
    pub max_acceleration_m_per_frame2: f64,
}

impl TrackParams {
    /// The search volumes of a speed limit (m/s) and an acceleration limit (m/s²) at a frame
    /// rate (Hz): `speed / rate` and `acceleration / rate²`. Non-finite or non-positive
    /// arguments give limits that [`track_markers`] refuses.
    pub fn from_limits(speed_m_per_s: f64, acceleration_m_per_s2: f64, frame_rate_hz: f64) -> Self {
        Self {
            max_velocity_m_per_frame: speed_m_per_s / frame_rate_hz,
            max_acceleration_m_per_frame2: acceleration_m_per_s2 / (frame_rate_hz * frame_rate_hz),
        }
    }

    /// The human limits ([`HUMAN_MAX_SPEED_M_PER_S`], [`HUMAN_MAX_ACCELERATION_M_PER_S2`]) at
    /// `frame_rate_hz`.
    pub fn human(frame_rate_hz: f64) -> Self {
        Self::from_limits(
            HUMAN_MAX_SPEED_M_PER_S,
            HUMAN_MAX_ACCELERATION_M_PER_S2,
            frame_rate_hz,
        )
    }
}

impl Default for TrackParams {
    /// The human limits at 60 Hz ([`TrackParams::human`]): 0.67 m per frame, 0.22 m per
    /// frame².
    fn default() -> Self {
        Self::human(60.0)
    }
}

/// A tracked marker: consecutive frames from `first_frame`.
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    /// Frame of the first point.
    pub first_frame: usize,
    /// Index of the point in each frame's set, from `first_frame` on.
    pub points: Vec<usize>,
}

impl Trajectory {
    /// Frame after the last point.
    pub fn end_frame(&self) -> usize {
        self.first_frame + self.points.len()
    }
}

/// Nearest point of `set` to `q` within `radius` (index, distance).
fn best_within(set: &[DVec3], q: DVec3, radius: f64) -> Option<(usize, f64)> {
    set.iter()
        .enumerate()
        .map(|(j, p)| (j, p.distance(q)))
        .filter(|(_, d)| *d <= radius)
        .min_by(|a, b| a.1.total_cmp(&b.1))
}

/// Links the 3-D points of successive frames into trajectories with the three-frame rule (see
/// the module documentation). Every point belongs to exactly one trajectory; trajectories are
/// returned in order of creation.
///
/// # Errors
/// [`crate::Error::InvalidParam`] for non-positive limits; [`crate::Error::NonFinite`] (in an
/// [`crate::Error::At`] naming the frame) for a non-finite point.
pub fn track_markers(sets: &[Vec<DVec3>], params: &TrackParams) -> Result<Vec<Trajectory>> {
    let v_max = positive("max_velocity_m_per_frame", params.max_velocity_m_per_frame)?;
    let a_max = positive(
        "max_acceleration_m_per_frame2",
        params.max_acceleration_m_per_frame2,
    )?;
    for (f, set) in sets.iter().enumerate() {
        all_finite("marker point", set.iter().flat_map(|p| [&p.x, &p.y, &p.z]))
            .at(Context::Frame(f))?;
    }
    let mut done: Vec<Trajectory> = Vec::new();
    let mut active: Vec<Trajectory> = Vec::new();
    for i in 0..sets.len() {
        // Points of frame i not continued from frame i − 1 start trajectories.
        let mut used = vec![false; sets[i].len()];
        for t in &active {
            if let Some(&j) = t.points.last() {
                used[j] = true;
            }
        }
        for (j, u) in used.iter().enumerate() {
            if !u {
                active.push(Trajectory {
                    first_frame: i,
                    points: vec![j],
                });
            }
        }
        let Some(next) = sets.get(i + 1) else {
            break;
        };
        let after = sets.get(i + 2);
        // Proposals (cost, trajectory, point of frame i + 1).
        let mut proposals: Vec<(f64, usize, usize)> = Vec::new();
        for (ti, t) in active.iter().enumerate() {
            let n = t.points.len();
            let p = sets[i][t.points[n - 1]];
            if n >= 2 {
                // Continuing trajectory: reduced volume around the constant-velocity prediction.
                let prev = sets[i - 1][t.points[n - 2]];
                let predicted = p + (p - prev);
                if let Some((j, acc)) = best_within(next, predicted, a_max) {
                    if next[j].distance(p) <= v_max {
                        proposals.push((acc, ti, j));
                    }
                }
                continue;
            }
            // New trajectory: velocity volume in i + 1, then the reduced volume in i + 2.
            let candidates: Vec<(usize, f64)> = next
                .iter()
                .enumerate()
                .map(|(j, c)| (j, c.distance(p)))
                .filter(|(_, d)| *d <= v_max)
                .collect();
            let scored = candidates.iter().map(|&(j, d)| {
                let c = next[j];
                let acc = after
                    .and_then(|s| best_within(s, c + (c - p), a_max))
                    .map(|(_, a)| a);
                (j, d, acc)
            });
            // Smallest acceleration among candidates confirmed in i + 2; without any
            // confirmation, the nearest candidate (cost above every confirmed one).
            let best = scored.min_by(|a, b| match (a.2, b.2) {
                (Some(x), Some(y)) => x.total_cmp(&y),
                (Some(_), None) => std::cmp::Ordering::Less,
                (None, Some(_)) => std::cmp::Ordering::Greater,
                (None, None) => a.1.total_cmp(&b.1),
            });
            if let Some((j, d, acc)) = best {
                proposals.push((acc.unwrap_or(a_max + d), ti, j));
            }
        }
        proposals.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut taken = vec![false; next.len()];
        let mut extended = vec![false; active.len()];
        for (_, ti, j) in proposals {
            if !taken[j] && !extended[ti] {
                taken[j] = true;
                extended[ti] = true;
                active[ti].points.push(j);
            }
        }
        let mut keep = Vec::with_capacity(active.len());
        for (t, e) in active.into_iter().zip(extended) {
            if e {
                keep.push(t);
            } else {
                done.push(t);
            }
        }
        active = keep;
    }
    done.extend(active);
    done.sort_by_key(|t| (t.first_frame, t.points[0]));
    Ok(done)
}

/// Identity switches of `trajectories` given the true identity of every point
/// (`ids[frame][point]`): the number of links between points of different identities.
///
/// # Errors
/// [`crate::Error::IndexOutOfRange`] for a trajectory reaching beyond `ids`.
pub fn id_switches(trajectories: &[Trajectory], ids: &[Vec<usize>]) -> Result<usize> {
    let id = |f: usize, j: usize| -> Result<usize> {
        let frame = ids.get(f).ok_or(crate::Error::IndexOutOfRange {
            what: "trajectory frame",
            index: f,
            len: ids.len(),
        })?;
        crate::check::index("trajectory point", j, frame.len())?;
        Ok(frame[j])
    };
    let mut switches = 0;
    for t in trajectories {
        for (k, w) in t.points.windows(2).enumerate() {
            let f = t.first_frame + k;
            switches += usize::from(id(f, w[0])? != id(f + 1, w[1])?);
        }
    }
    Ok(switches)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::random::SplitMix64;

    /// 20 markers in a zig-zag row 5 cm apart (alternately 3 cm to the side), all moving 4 cm
    /// per frame along the row, so that the neighbour behind is nearer (3.2 cm) than the
    /// marker's own next position; a slow 5 mm sideways wave, 1 mm noise, shuffled per frame; marker 7
    /// is missing in frames 10 and 11. Returns the sets and the true marker id of each point.
    fn row(frames: usize) -> (Vec<Vec<DVec3>>, Vec<Vec<usize>>) {
        let rng = SplitMix64::new(11);
        let mut k = 0u64;
        let mut noise = || {
            k += 1;
            rng.normal_at(k) * 0.001
        };
        let mut sets = Vec::new();
        let mut ids = Vec::new();
        for f in 0..frames {
            let t = f as f64;
            let mut pts: Vec<(usize, DVec3)> = (0..20)
                .filter(|&m| !(m == 7 && (10..12).contains(&f)))
                .map(|m| {
                    let p = DVec3::new(
                        0.05 * m as f64 + 0.04 * t,
                        0.03 * (m % 2) as f64 + 0.005 * (0.3 * t + m as f64).sin(),
                        0.0,
                    );
                    (m, p + DVec3::new(noise(), noise(), noise()))
                })
                .collect();
            // Shuffle deterministically so indices carry no identity.
            pts.sort_by_key(|(m, _)| (m * 7 + f * 3) % 20);
            ids.push(pts.iter().map(|(m, _)| *m).collect());
            sets.push(pts.into_iter().map(|(_, p)| p).collect());
        }
        (sets, ids)
    }

    /// Baseline: greedy nearest-neighbour linking within the velocity volume.
    fn nearest_neighbour(sets: &[Vec<DVec3>], v_max: f64) -> Vec<Trajectory> {
        let mut trajs: Vec<Trajectory> = (0..sets[0].len())
            .map(|j| Trajectory {
                first_frame: 0,
                points: vec![j],
            })
            .collect();
        for i in 0..sets.len() - 1 {
            let mut taken = vec![false; sets[i + 1].len()];
            for t in trajs.iter_mut().filter(|t| t.end_frame() == i + 1) {
                let p = sets[i][*t.points.last().unwrap()];
                let best = sets[i + 1]
                    .iter()
                    .enumerate()
                    .filter(|(j, q)| !taken[*j] && q.distance(p) <= v_max)
                    .min_by(|a, b| a.1.distance(p).total_cmp(&b.1.distance(p)));
                if let Some((j, _)) = best {
                    taken[j] = true;
                    t.points.push(j);
                }
            }
            for (j, _) in taken.iter().enumerate().filter(|(_, t)| !**t) {
                trajs.push(Trajectory {
                    first_frame: i + 1,
                    points: vec![j],
                });
            }
        }
        trajs
    }

    #[test]
    fn three_frame_rule_keeps_identities_where_nearest_neighbour_swaps() {
        let (sets, ids) = row(30);
        let params = TrackParams {
            max_velocity_m_per_frame: 0.055,
            max_acceleration_m_per_frame2: 0.015,
        };
        let trajs = track_markers(&sets, &params).unwrap();
        let points: usize = trajs.iter().map(|t| t.points.len()).sum();
        assert_eq!(points, sets.iter().map(Vec::len).sum::<usize>());
        let ours = id_switches(&trajs, &ids).unwrap();
        let nn = id_switches(&nearest_neighbour(&sets, 0.055), &ids).unwrap();
        assert_eq!(ours, 0, "three-frame rule switched identities {ours} times");
        assert!(nn > 10, "nearest neighbour only switched {nn} times");
        // Marker 7's gap breaks its trajectory: 20 long ones, one that ends, one restart.
        assert_eq!(
            trajs.len(),
            21,
            "{:?}",
            trajs
                .iter()
                .map(|t| (t.first_frame, t.points.len()))
                .collect::<Vec<_>>()
        );
    }

    #[test]
    fn the_search_volumes_scale_with_the_frame_rate() {
        let p = TrackParams::human(60.0);
        assert!((p.max_velocity_m_per_frame - 40.0 / 60.0).abs() < 1e-12);
        assert!((p.max_acceleration_m_per_frame2 - 800.0 / 3600.0).abs() < 1e-12);
        assert_eq!(TrackParams::default(), p);
        let fast = TrackParams::human(120.0);
        assert!((fast.max_velocity_m_per_frame - p.max_velocity_m_per_frame / 2.0).abs() < 1e-12);
        assert!(
            (fast.max_acceleration_m_per_frame2 - p.max_acceleration_m_per_frame2 / 4.0).abs()
                < 1e-12
        );
        // A frame rate that is not finite and positive gives limits the tracker refuses.
        for rate in [0.0, -60.0, f64::NAN, f64::INFINITY] {
            let bad = TrackParams::human(rate);
            assert!(track_markers(&[vec![DVec3::ZERO]], &bad).is_err(), "{rate}");
        }
    }

    #[test]
    fn bad_input_is_an_error() {
        let p = TrackParams::default();
        assert!(track_markers(&[], &p).unwrap().is_empty());
        let nan = vec![vec![DVec3::ZERO], vec![DVec3::new(f64::NAN, 0.0, 0.0)]];
        let e = track_markers(&nan, &p).unwrap_err();
        assert!(e.to_string().contains("frame 1"), "{e}");
        let bad = TrackParams {
            max_velocity_m_per_frame: 0.0,
            ..p
        };
        assert!(track_markers(&[vec![DVec3::ZERO]], &bad).is_err());
        let t = Trajectory {
            first_frame: 0,
            points: vec![0, 0],
        };
        assert!(id_switches(&[t], &[vec![0]]).is_err());
    }
}
