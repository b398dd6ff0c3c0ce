//! Prototype shapes: Sand, McMillan and Popović 2003 §5.3 (thesis §5.3).
//!
//! The method is documented on [`prototype_shapes()`]; the module is private and
//! everything public is re-exported at the crate root.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::config::{check_samples, config_scale, dist2};
use crate::error::{Context, ResultExt};
use crate::params::{Neighbourhood, ReconstructionParams};
use crate::store::NeedleObservations;
use crate::store::MAX_NEEDLES_PER_PRIMITIVE;
use crate::{Error, Result};

/// Ring/axial grid adjacency of a primitive's needles in ring-major order
/// (`j = ring · radial + k`, the layout of [`crate::NeedleBody`]): the two ring neighbours
/// (wrapping around) and the needles at the same angle in the previous and next ring.
/// Used by [`prototype_shapes`] to fill never-observed needles.
///
/// # Errors
/// [`Error::InvalidParam`] if `radial · axial` is 0 or exceeds
/// [`MAX_NEEDLES_PER_PRIMITIVE`].
pub fn grid_adjacency(radial: usize, axial: usize) -> Result<Vec<Vec<u16>>> {
    let n = radial.saturating_mul(axial);
    if n == 0 || n > MAX_NEEDLES_PER_PRIMITIVE {
        return Err(Error::InvalidParam {
            name: "radial × axial",
            reason: format!(
                "needle count must be in 1..={MAX_NEEDLES_PER_PRIMITIVE}, got {radial} × {axial}"
            ),
        });
    }
    Ok((0..n)
        .map(|j| {
            let (ring, k) = (j / radial, j % radial);
            let mut nb = Vec::with_capacity(4);
            if radial > 1 {
                nb.push(ring * radial + (k + 1) % radial);
                nb.push(ring * radial + (k + radial - 1) % radial);
            }
            if ring > 0 {
                nb.push((ring - 1) * radial + k);
            }
            if ring + 1 < axial {
                nb.push((ring + 1) * radial + k);
            }
            nb.sort_unstable();
            nb.dedup();
            nb.into_iter()
                .filter(|&x| x != j)
                .map(|x| x as u16)
                .collect() // < MAX_NEEDLES_PER_PRIMITIVE
        })
        .collect())
}

/// Prototype shapes `v_jk` (§5.3) of one primitive.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PrototypeShapes {
    /// Number of needles `J`.
    pub num_needles: usize,
    /// Number of prototypes `N`.
    pub num_prototypes: usize,
    /// Lengths, prototype-major: `lengths[k * J + j]` is needle `j` in prototype `k`
    /// (same unit as the observed lengths).
    pub lengths: Vec<f32>,
    /// Needles that had no observation and were filled from neighbouring needles.
    pub filled_needles: Vec<u32>,
    /// How the prototype neighbourhoods came out.
    #[serde(default)]
    pub neighbourhood: NeighbourhoodStats,
}

/// How the neighbourhoods behind the prototype estimates came out (carried by
/// [`PrototypeShapes`], [`crate::NrbfFit`] and [`crate::PrimitiveFitReport`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct NeighbourhoodStats {
    /// Cap radius `R` of [`Neighbourhood::Capped`] in configuration-space units (`None` for
    /// [`Neighbourhood::Fraction`] or a single prototype).
    pub radius: Option<f32>,
    /// Number of (needle, prototype) estimates of observed needles.
    pub estimates: usize,
    /// Of [`Self::estimates`], how many had the `min_near` floor bind under
    /// [`Neighbourhood::Capped`] (the ball held fewer than `min(min_near, m)` observations of
    /// the needle, an empty ball included); always 0 for [`Neighbourhood::Fraction`].
    pub floor_bound: usize,
    /// Median over the estimates of the pool radius: the configuration-space distance from
    /// the prototype to the farthest observation its estimate used (`None` when no estimate
    /// walked a neighbourhood, e.g. the static model `F_near = 1`).
    #[serde(default)]
    pub pool_radius_median: Option<f32>,
    /// [`Self::pool_radius_median`] in degrees of the primitive's driving joints
    /// ([`crate::ConfigSpace::units_per_radian`]); filled by [`crate::NeedleModel::reconstruct`],
    /// `None` when the configuration space's rate is unknown.
    #[serde(default)]
    pub pool_radius_deg_median: Option<f32>,
    /// Median over the estimates (of every 4th needle) of the largest share of one pose in the
    /// pool: the observations are binned in configuration-space cells the size of a 5° turn of
    /// the driving joints ([`NeighbourhoodStats::POOL_POSE_CELL_DEG`]) and the fullest cell's count
    /// is divided by the pool's size. Near 1: one held pose makes the estimate (the failure the
    /// capped neighbourhood exists to avoid); `None` when the cell size is unknown (as
    /// [`Self::pool_radius_deg_median`]).
    #[serde(default)]
    pub pool_max_pose_share_median: Option<f32>,
}

impl NeighbourhoodStats {
    /// Side of the pose cells of [`NeighbourhoodStats::pool_max_pose_share_median`], degrees of
    /// the driving joints (a 5° quantisation).
    pub const POOL_POSE_CELL_DEG: f64 = 5.0;
}

/// The pose shares of [`NeighbourhoodStats::pool_max_pose_share_median`] are counted on every
/// this-many-th needle (a hash per pool entry; the median over a quarter of the needles is
/// the same figure at a quarter of the cost).
const POOL_SHARE_NEEDLE_STRIDE: usize = 4;

impl PrototypeShapes {
    /// The needle lengths of prototype `k` (panics if `k ≥ num_prototypes`, like slicing).
    pub fn shape(&self, k: usize) -> &[f32] {
        &self.lengths[k * self.num_needles..(k + 1) * self.num_needles]
    }
}

/// Number of nearest observations used for a needle with `m` observations (§5.3):
/// `n = round(F_near · m)`, raised to `min_near` (see [`ReconstructionParams::min_near`]) and
/// clamped to `1..=m`.
pub(crate) fn near_count(m: usize, f_near: f64, min_near: usize) -> usize {
    ((f_near * m as f64).round() as usize)
        .max(min_near)
        .clamp(1, m.max(1))
}

/// Prototype spacing: the median over prototypes of the distance to the nearest other
/// prototype (`N × dim` row-major). `None` for fewer than two prototypes.
pub(crate) fn prototype_spacing(points: &[f32], dim: usize) -> Option<f32> {
    let n = points.len() / dim.max(1);
    if n < 2 {
        return None;
    }
    let mut nearest: Vec<f32> = points
        .chunks_exact(dim)
        .enumerate()
        .map(|(i, p)| {
            points
                .chunks_exact(dim)
                .enumerate()
                .filter(|&(j, _)| j != i)
                .map(|(_, q)| dist2(p, q))
                .fold(f32::INFINITY, f32::min)
                .sqrt()
        })
        .collect();
    median_f32(&mut nearest)
}

/// Number of nearest observations a capped neighbourhood uses ([`Neighbourhood::Capped`]):
/// `min(n_frac, ball)` when the ball of the cap radius holds `ball ≥ floor` observations of the
/// needle, else `floor` (the floor binds; second value `true`).
pub(crate) fn capped_count(n_frac: usize, ball: usize, floor: usize) -> (usize, bool) {
    if ball >= floor {
        (n_frac.min(ball), false)
    } else {
        (floor, true)
    }
}

/// Index of the `F_min` percentile in `n` sorted values: `round(F_min · (n − 1))`.
pub(crate) fn percentile_index(n: usize, f_min: f64) -> usize {
    ((f_min * (n.saturating_sub(1)) as f64).round() as usize).min(n.saturating_sub(1))
}

/// `F_min` percentile of `values` (reordered in place); `values` must be non-empty.
fn robust_minimum(values: &mut [f32], f_min: f64) -> f32 {
    let idx = percentile_index(values.len(), f_min);
    *values.select_nth_unstable_by(idx, f32::total_cmp).1
}

/// Prototype shapes by the robust minimum of nearby observations (Sand 2003 §5.3).
///
/// Prototype shapes: Sand, McMillan and Popović 2003 §5.3 (thesis §5.3).
///
/// For needle `j` with `m_j` observations and prototype `k`, take the `n = F_near · m_j`
/// observations of that needle whose configuration points are nearest to `p_k`, and use their
/// `F_min` percentile length as `v_jk` (the "robust minimum": silhouettes only overestimate,
/// §5). Selecting a fraction rather than a radius borrows from other poses where data is
/// sparse — the paper's hole filling across configuration space. Needles that have *no*
/// observation at all are filled from neighbouring needles on the primitive
/// ([`prototype_shapes`], with the needle grid of [`grid_adjacency`]); see its docs.
///
/// Data layout: configuration points are `f32` rows of length `dim` (one per (frame, camera)
/// sample), observations are grouped per needle in [`NeedleObservations`].
///
/// * `samples`: configuration points, `S × dim` row-major.
/// * `observations`: per-needle observations indexing rows of `samples`.
/// * `prototype_points`: prototype locations `N × dim` (e.g. [`crate::PrototypeLocations::points`]).
/// * `adjacency`: neighbouring needles of each needle on the primitive (ring and axial grid),
///   used only to fill needles without any observation; must have one entry per needle.
///
/// All needles of a primitive share its samples, so instead of one kd-tree per needle we sort
/// the `S` samples by distance to each prototype once (`O(N·S log S)`, parallel over
/// prototypes); then for needle `j` and prototype `k` the samples are walked in that order,
/// collecting needle `j`'s observations until `n = F_near·m_j` are found, and the `F_min`
/// percentile is taken with `select_nth_unstable`. This is exact and
/// costs about `F_near·S` steps per (needle, prototype) whatever the configuration dimension,
/// where a kd-tree `n`-nearest query in 6–9 dimensions visits far more points. Needles run
/// in parallel. Total `O(N·S log S + J·S + N·J·F_near·S)`.
///
/// **Ties.** "The `n` nearest" is ambiguous when many samples share a configuration, and on
/// a real capture they do: the body rests in one pose for long stretches (on a range of
/// motion most primitives spend most of the time at rest), and the configuration points of
/// those frames are equal to float precision. Cutting such a tie by sample index keeps the
/// first `n` in time, i.e. the few views of a short stretch of the capture, and their
/// robust minimum stays far above the surface (on the studio this made the calves' median
/// error 10 mm instead of 1 mm). Samples within `TIE_RADIUS` = 10⁻³ × the data's RMS radius of
/// the one that completes the `n` nearest are equally near and are all taken: a pose held
/// for a thousand frames gives its prototype every one of those views. So that this costs
/// no more than the plain walk, groups of more than `LARGE_TIE_SAMPLES` = 64 bit-identical
/// configurations keep one sorted list of each needle's observations, taken in one step,
/// and the percentile is found by merging the sorted lists (`O(F_min · n)`).
///
/// **Capped neighbourhoods (default; a documented departure from §5.3).** With
/// [`Neighbourhood::Capped`] the walk stops at `R = radius_factor ×` the prototype spacing
/// (median nearest-prototype distance, [`NeighbourhoodStats::radius`]): the count
/// is `min(F_near·m_j, ball)` where `ball` is the needle's observations within `R`, so a far
/// pose held for most of the capture (the rest pose of a range of motion) cannot enter a
/// sweep prototype's pool and make every prototype the static estimate. When the ball holds
/// fewer than `min(min_near, m_j)` observations (an empty ball included) the floor binds and
/// the `min_near` nearest are used, cap or not ([`NeighbourhoodStats::floor_bound`] counts it).
/// Ties are taken whole as above. [`Neighbourhood::Fraction`] is the paper's rule, kept
/// selectable.
///
/// **Hole filling for unobserved needles.** The paper's fraction rule fills holes in
/// configuration space, but a needle that was never observed (e.g. always perpendicular to
/// the image plane) has nothing to borrow. We fill it per prototype with the mean of its
/// already-known neighbours' lengths, in breadth-first rounds (each round uses only needles
/// known before the round, so the result does not depend on order): neighbouring needles
/// describe nearby surface, and the mean is the smooth choice for a surface that is already
/// a robust-minimum estimate.
///
/// # Errors
/// [`Error::InvalidParam`] for invalid `params` or `dim`; [`Error::SizeMismatch`] for a
/// `prototype_points` length not a multiple of `dim` or an adjacency of wrong length;
/// [`Error::IndexOutOfRange`] for an observation's sample index beyond the samples, or (in
/// [`Error::At`] with the [`Context::Needle`]) a neighbour index beyond the needles;
/// [`Error::NonFinite`] for NaN/∞ coordinates; [`Error::Empty`] for no samples, prototypes
/// or needles; [`Error::NoObservations`] in [`Error::At`] with the [`Context::Needle`] when
/// a needle has no observation and no observed needle is reachable through `adjacency`.
pub fn prototype_shapes(
    samples: &[f32],
    dim: usize,
    observations: &NeedleObservations,
    prototype_points: &[f32],
    adjacency: &[Vec<u16>],
    params: &ReconstructionParams,
) -> Result<PrototypeShapes> {
    prototype_shapes_in_cells(
        samples,
        dim,
        observations,
        prototype_points,
        adjacency,
        params,
        None,
    )
}

/// [`prototype_shapes`], with the pose-share diagnostic
/// ([`NeighbourhoodStats::pool_max_pose_share_median`]) computed in cells of side
/// `pose_cell` (configuration units) when given.
pub(crate) fn prototype_shapes_in_cells(
    samples: &[f32],
    dim: usize,
    observations: &NeedleObservations,
    prototype_points: &[f32],
    adjacency: &[Vec<u16>],
    params: &ReconstructionParams,
    pose_cell: Option<f32>,
) -> Result<PrototypeShapes> {
    params.validate()?;
    let count = check_samples(samples, dim)?;
    if count >= PoseGroups::GROUP as usize {
        return Err(Error::InvalidParam {
            name: "samples",
            reason: format!("{count} configuration samples; at most 2^31 − 1 are supported"),
        });
    }
    if prototype_points.is_empty() {
        return Err(Error::Empty {
            what: "prototype locations",
        });
    }
    if !prototype_points.len().is_multiple_of(dim) {
        return Err(Error::SizeMismatch {
            what: "prototype locations (length must be a multiple of dim)",
            expected: prototype_points.len().div_ceil(dim) * dim,
            got: prototype_points.len(),
        });
    }
    if prototype_points.iter().any(|v| !v.is_finite()) {
        return Err(Error::NonFinite {
            what: "prototype locations",
        });
    }
    let num_needles = observations.needle_count();
    if num_needles == 0 {
        return Err(Error::Empty { what: "needles" });
    }
    if adjacency.len() != num_needles {
        return Err(Error::SizeMismatch {
            what: "needle adjacency (one list per needle)",
            expected: num_needles,
            got: adjacency.len(),
        });
    }
    for (j, nb) in adjacency.iter().enumerate() {
        if let Some(&bad) = nb.iter().find(|&&n| n as usize >= num_needles) {
            return Err(Error::IndexOutOfRange {
                what: "neighbour in needle adjacency",
                index: bad as usize,
                len: num_needles,
            })
            .at(Context::Needle(j));
        }
    }
    if let Some(&bad) = observations
        .samples()
        .iter()
        .find(|&&s| s as usize >= count)
    {
        return Err(Error::IndexOutOfRange {
            what: "sample of an observation (row of the configuration samples)",
            index: bad as usize,
            len: count,
        });
    }
    let num_protos = prototype_points.len() / dim;

    // Every sample with its distance, in order of distance to each prototype: O(N·S log S).
    // A large group of identical configurations is one entry, `GROUP | g`.
    let tie = TIE_RADIUS * config_scale(samples, dim)?;
    let cap = match params.neighbourhood {
        Neighbourhood::Fraction => None,
        Neighbourhood::Capped { radius_factor } => {
            prototype_spacing(prototype_points, dim).map(|sp| sp * radius_factor as f32)
        }
    };
    let pose_groups = PoseGroups::new(samples, dim);
    let cells = pose_cell.map(|c| pose_cells(samples, dim, c));
    let order: Vec<Vec<(f32, u32)>> = prototype_points
        .par_chunks_exact(dim)
        .map(|p| {
            let mut d: Vec<(f32, u32)> = samples
                .chunks_exact(dim)
                .enumerate()
                .filter_map(|(i, x)| {
                    let entry = match pose_groups.group_of[i] {
                        PoseGroups::NONE => i as u32,
                        g if pose_groups.members[g as usize][0] == i as u32 => {
                            PoseGroups::GROUP | g
                        }
                        _ => return None,
                    };
                    Some((dist2(x, p).sqrt(), entry))
                })
                .collect();
            d.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            d
        })
        .collect();

    // Per needle: its N estimates, or None when unobserved.
    let per_needle: Vec<Option<NeedleEstimates>> = (0..num_needles)
        .into_par_iter()
        .map_init(Scratch::default, |scratch, j| {
            let (s, l) = observations.needle(j);
            if s.is_empty() {
                None
            } else {
                Some(needle_prototype_lengths(
                    &order,
                    tie,
                    cap,
                    &pose_groups,
                    cells
                        .as_deref()
                        .filter(|_| j % POOL_SHARE_NEEDLE_STRIDE == 0),
                    s,
                    l,
                    params,
                    scratch,
                ))
            }
        })
        .collect();

    let mut lengths = vec![0f32; num_protos * num_needles];
    let mut known = vec![false; num_needles];
    let (mut estimates, mut floor_bound) = (0, 0);
    let (mut radii, mut shares) = (vec![], vec![]);
    for (j, v) in per_needle.into_iter().enumerate() {
        if let Some(v) = v {
            known[j] = true;
            estimates += v.lengths.len();
            floor_bound += v.floored;
            radii.extend(v.radii);
            shares.extend(v.shares);
            for (k, &x) in v.lengths.iter().enumerate() {
                lengths[k * num_needles + j] = x;
            }
        }
    }
    let mut filled_needles = Vec::new();
    loop {
        let round: Vec<usize> = (0..num_needles)
            .filter(|&j| !known[j] && adjacency[j].iter().any(|&n| known[n as usize]))
            .collect();
        if round.is_empty() {
            break;
        }
        let mut updates = Vec::with_capacity(round.len());
        for &j in &round {
            let nbrs: Vec<usize> = adjacency[j]
                .iter()
                .map(|&n| n as usize)
                .filter(|&n| known[n])
                .collect();
            let inv = 1.0 / nbrs.len() as f32;
            let vals: Vec<f32> = (0..num_protos)
                .map(|k| {
                    nbrs.iter()
                        .map(|&n| lengths[k * num_needles + n])
                        .sum::<f32>()
                        * inv
                })
                .collect();
            updates.push((j, vals));
        }
        for (j, vals) in updates {
            for (k, x) in vals.into_iter().enumerate() {
                lengths[k * num_needles + j] = x;
            }
            known[j] = true;
            filled_needles.push(j as u32);
        }
    }
    if let Some(j) = known.iter().position(|&k| !k) {
        return Err(Error::NoObservations {
            what: "never observed and no observed needle reachable through the adjacency".into(),
        })
        .at(Context::Needle(j));
    }
    filled_needles.sort_unstable();
    Ok(PrototypeShapes {
        num_needles,
        num_prototypes: num_protos,
        lengths,
        filled_needles,
        neighbourhood: NeighbourhoodStats {
            radius: cap,
            estimates,
            floor_bound,
            pool_radius_median: median_f32(&mut radii),
            pool_radius_deg_median: None,
            pool_max_pose_share_median: median_f32(&mut shares),
        },
    })
}

/// Median (upper middle) of `v`, reordered in place; `None` when empty.
fn median_f32(v: &mut [f32]) -> Option<f32> {
    let mid = v.len() / 2;
    (!v.is_empty()).then(|| *v.select_nth_unstable_by(mid, f32::total_cmp).1)
}

/// Pose cell of every sample (`S × dim` row-major): a hash of its coordinates quantised to
/// cells of side `cell`.
fn pose_cells(samples: &[f32], dim: usize, cell: f32) -> Vec<u64> {
    samples
        .chunks_exact(dim)
        .map(|row| {
            row.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &x| {
                let q = (x / cell).floor() as i64 as u64;
                (h ^ q).wrapping_mul(0x0100_0000_01b3).rotate_left(17)
            })
        })
        .collect()
}

/// One needle's estimates from [`needle_prototype_lengths`].
struct NeedleEstimates {
    /// Length per prototype.
    lengths: Vec<f32>,
    /// Prototypes whose `min_near` floor bound.
    floored: usize,
    /// Pool radius per walked prototype ([`NeighbourhoodStats::pool_radius_median`]).
    radii: Vec<f32>,
    /// Largest pose share per walked prototype, when pose cells are given.
    shares: Vec<f32>,
}

/// Samples whose configurations lie within this fraction of the data's RMS radius of the
/// `n`-th nearest one count as equally near (see [`prototype_shapes`]).
pub(crate) const TIE_RADIUS: f32 = 1e-3;
/// Groups of more samples than this with bit-identical configurations are taken through a
/// pre-sorted list per needle (an optimisation with the same result, see
/// [`prototype_shapes`]).
pub(crate) const LARGE_TIE_SAMPLES: usize = 64;

/// Large groups of samples with bit-identical configurations (a pose held for a while):
/// [`needle_prototype_lengths`] takes such a group whole through one pre-sorted list per
/// needle instead of walking its samples for every prototype.
struct PoseGroups {
    /// Group of each sample, or [`PoseGroups::NONE`].
    group_of: Vec<u32>,
    /// Samples of each group.
    members: Vec<Vec<u32>>,
}

impl PoseGroups {
    const NONE: u32 = u32::MAX;
    /// Flag of a group entry in the distance order (sample indices stay below it).
    const GROUP: u32 = 1 << 31;

    fn new(samples: &[f32], dim: usize) -> Self {
        let mut by_row: std::collections::HashMap<Vec<u32>, Vec<u32>> = Default::default();
        for (i, row) in samples.chunks_exact(dim).enumerate() {
            by_row
                .entry(row.iter().map(|v| v.to_bits()).collect())
                .or_default()
                .push(i as u32);
        }
        let mut members: Vec<Vec<u32>> = by_row
            .into_values()
            .filter(|m| m.len() > LARGE_TIE_SAMPLES)
            .collect();
        members.sort_unstable();
        let mut group_of = vec![Self::NONE; samples.len() / dim.max(1)];
        for (g, m) in members.iter().enumerate() {
            for &s in m {
                group_of[s as usize] = g as u32;
            }
        }
        Self { group_of, members }
    }
}

/// Per-thread scratch of [`needle_prototype_lengths`].
#[derive(Default)]
struct Scratch {
    /// Counting-sort ends: after filling, observations of sample `s` are
    /// `vals[ends[s-1]..ends[s]]` (`ends[-1] = 0`).
    ends: Vec<u32>,
    vals: Vec<f32>,
    buf: Vec<f32>,
    /// This needle's observations in each large pose group, sorted.
    group_vals: Vec<Vec<f32>>,
    /// Large pose groups taken by the current prototype (each is one entry of the order).
    taken: Vec<u32>,
    /// Observations per pose cell in the current pool.
    cell_counts: std::collections::HashMap<u64, usize>,
}

/// §5.3 for one needle: the `F_min` percentile of its `F_near·m` nearest observations, for
/// each prototype, given every prototype's samples in order of increasing distance. With a
/// `cap` radius ([`Neighbourhood::Capped`]) the count is first limited to the observations
/// within the cap, floored at `min(min_near, m)` ([`capped_count`]). Returns the lengths and
/// how many prototypes had the floor bind.
///
/// The needle's observations are bucketed by sample (counting sort), then for prototype `k`
/// the samples are walked in distance order collecting this needle's observations until `n`
/// are found, then on through samples tied with the last one (within `tie`). Expected
/// walk length is `F_near·S` samples when the needle's visibility does not depend on pose,
/// and at most `S` (a capped count costs one more walk, counting only). With `cells` (one pose
/// cell per sample) each pool's largest pose share is recorded too.
#[allow(clippy::too_many_arguments)]
fn needle_prototype_lengths(
    order: &[Vec<(f32, u32)>],
    tie: f32,
    cap: Option<f32>,
    groups: &PoseGroups,
    cells: Option<&[u64]>,
    sample_idx: &[u32],
    lengths: &[f32],
    params: &ReconstructionParams,
    scratch: &mut Scratch,
) -> NeedleEstimates {
    let m = sample_idx.len();
    let (n_frac, floor) = match cap {
        None => (near_count(m, params.f_near, params.min_near), 0),
        Some(_) => (
            near_count(m, params.f_near, 1),
            params.min_near.clamp(1, m.max(1)),
        ),
    };
    if n_frac == m {
        // Every observation is "near" every prototype: a static estimate. `F_near = 1` means
        // every observation in both variants (the static model of thesis Figure 6-2c); the cap
        // limits a fraction walk, and there is none.
        scratch.buf.clear();
        scratch.buf.extend_from_slice(lengths);
        return NeedleEstimates {
            lengths: vec![robust_minimum(&mut scratch.buf, params.f_min); order.len()],
            floored: 0,
            radii: vec![],
            shares: vec![],
        };
    }
    let count = groups.group_of.len();
    let Scratch {
        ends,
        vals,
        buf,
        group_vals,
        taken,
        cell_counts,
    } = scratch;
    ends.clear();
    ends.resize(count + 1, 0);
    for &s in sample_idx {
        ends[s as usize + 1] += 1;
    }
    for s in 0..count {
        ends[s + 1] += ends[s];
    }
    // ends[s] is now the start of sample s; filling advances it to the end of sample s.
    vals.clear();
    vals.resize(m, 0.0);
    for (&s, &l) in sample_idx.iter().zip(lengths) {
        let c = &mut ends[s as usize];
        vals[*c as usize] = l;
        *c += 1;
    }
    let obs_of = |s: u32| {
        let s = s as usize;
        let start = if s == 0 { 0 } else { ends[s - 1] as usize };
        start..ends[s] as usize
    };
    group_vals.resize_with(groups.members.len(), Vec::new);
    for (g, members) in group_vals.iter_mut().zip(&groups.members) {
        g.clear();
        for &s in members {
            g.extend_from_slice(&vals[obs_of(s)]);
        }
        g.sort_unstable_by(f32::total_cmp);
    }
    let entry_len = |s: u32| {
        if s & PoseGroups::GROUP == 0 {
            obs_of(s).len()
        } else {
            group_vals[(s & !PoseGroups::GROUP) as usize].len()
        }
    };
    let mut floored = 0;
    let (mut radii, mut shares) = (vec![], vec![]);
    let out = order
        .iter()
        .map(|ord| {
            let n = match cap {
                None => n_frac,
                Some(r) => {
                    // Observations of this needle within the cap, counted until both the
                    // fraction and the floor are reached.
                    let goal = n_frac.max(floor);
                    let mut ball = 0;
                    for &(d, s) in ord {
                        if d > r || ball >= goal {
                            break;
                        }
                        ball += entry_len(s);
                    }
                    let (n, bound) = capped_count(n_frac, ball, floor);
                    floored += usize::from(bound);
                    n
                }
            };
            buf.clear();
            taken.clear();
            cell_counts.clear();
            let mut total = 0;
            let mut reach = f32::INFINITY;
            let mut radius = 0f32;
            for &(d, s) in ord {
                if d > reach {
                    break;
                }
                let len = entry_len(s);
                if len > 0 {
                    radius = d;
                    if let Some(cells) = cells {
                        let first = if s & PoseGroups::GROUP == 0 {
                            s
                        } else {
                            groups.members[(s & !PoseGroups::GROUP) as usize][0]
                        };
                        *cell_counts.entry(cells[first as usize]).or_default() += len;
                    }
                }
                total += len;
                if s & PoseGroups::GROUP == 0 {
                    buf.extend_from_slice(&vals[obs_of(s)]);
                } else {
                    taken.push(s & !PoseGroups::GROUP);
                }
                if total >= n && reach.is_infinite() {
                    reach = d + tie;
                }
            }
            radii.push(radius);
            if let Some(&most) = cell_counts.values().max() {
                shares.push(most as f32 / total.max(1) as f32);
            }
            let k = percentile_index(total, params.f_min);
            if taken.is_empty() {
                *buf.select_nth_unstable_by(k, f32::total_cmp).1
            } else {
                buf.sort_unstable_by(f32::total_cmp);
                let mut lists: Vec<&[f32]> = vec![&buf[..]];
                lists.extend(taken.iter().map(|&g| group_vals[g as usize].as_slice()));
                kth_of_sorted(&mut lists, k)
            }
        })
        .collect();
    NeedleEstimates {
        lengths: out,
        floored,
        radii,
        shares,
    }
}

/// The `k`-th smallest (0-based) of the union of sorted lists; `k` must be below their total
/// length. Merges from the front: `O(k · lists)`.
fn kth_of_sorted(lists: &mut [&[f32]], k: usize) -> f32 {
    let mut last = f32::NAN;
    for _ in 0..=k {
        let Some(i) = (0..lists.len())
            .filter(|&i| !lists[i].is_empty())
            .min_by(|&a, &b| lists[a][0].total_cmp(&lists[b][0]))
        else {
            break;
        };
        last = lists[i][0];
        lists[i] = &lists[i][1..];
    }
    last
}

#[cfg(test)]
mod tests;
