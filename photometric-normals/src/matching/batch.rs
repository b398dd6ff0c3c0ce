//! The surface metric of one window against many ([`window_distances`]): the comparisons of
//! one grid row, computed four at a time.
//!
//! Two full windows are compared as one comparison alone would be, operation for operation:
//! the cross-covariance of the centred points summed in window order, Horn's rotation of it
//! ([`horn_rotation`]), the distances summed in order. Only the comparisons are interleaved
//! (one per SIMD lane), so every cost is the same to the bit as one comparison at a time (the
//! unit test keeps that scalar computation as its reference). A window that is not full is
//! compared alone ([`partial_window_distance`]); such comparisons are about a third of a
//! studio reconstruction's (about 19 of 25 pairs each). In lanes too, with a missing pair's
//! terms as `-0.0` (the identity of IEEE addition, so still to the bit), they were measured
//! no faster there: moving each lane's pairs into place costs what the lanes save. The lanes
//! are compiled for the widest instruction set the processor has (`pulp`'s run-time dispatch:
//! AVX2 on most x86-64, NEON on aarch64), where one comparison at a time leaves the sums
//! serial and scalar.

use super::horn::horn_rotation;
use super::metrics::{partial_window_distance, Windows};

/// Comparisons per group: one per lane of an AVX2 register of `f64`.
const LANES: usize = 4;

/// Which of a comparison's two windows is the same for the whole batch.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum Fixed {
    /// The view's own surface window (the one rotated onto the other).
    Own,
    /// The other surface's window, rendered into the view.
    Other,
}

/// Scratch space of [`window_distances`], reused across a plane's rows.
#[derive(Default)]
pub(super) struct Scratch {
    /// Batch positions of the comparisons whose windows are both full.
    full: Vec<usize>,
    /// One group's varying windows, centred: per point, x then y then z, each `LANES` wide.
    lanes: Vec<[f64; LANES]>,
    /// [`partial_window_distance`]'s scratch space.
    pairs: Vec<(skin_core::math::DVec3, skin_core::math::DVec3)>,
}

/// The surface metric's distance of the window `s` of `fixed_windows` against each window
/// `ts` of `varying`, into `out` (cleared first), in the order of `ts`: the mean distance of
/// corresponding points after the optimal rigid alignment of the own window onto the other
/// (where either window is not full, [`partial_window_distance`]'s). `fixed` says whether the
/// fixed window is the comparison's own or its other.
pub(super) fn window_distances(
    (fixed_windows, s): (&Windows, usize),
    varying: &Windows,
    ts: &[usize],
    fixed: Fixed,
    scratch: &mut Scratch,
    out: &mut Vec<f64>,
) {
    out.clear();
    scratch.full.clear();
    let fixed_full = fixed_windows.centroids[s].is_some();
    for (j, &t) in ts.iter().enumerate() {
        if fixed_full && varying.centroids[t].is_some() {
            scratch.full.push(j);
            out.push(f64::NAN);
            continue;
        }
        // A partial window: the pairs where both points exist, one comparison at a time.
        out.push(match fixed {
            Fixed::Own => partial_window_distance(fixed_windows, s, varying, t, &mut scratch.pairs),
            Fixed::Other => {
                partial_window_distance(varying, t, fixed_windows, s, &mut scratch.pairs)
            }
        });
    }
    if scratch.full.is_empty() {
        return;
    }
    let Scratch { full, lanes, .. } = scratch;
    let groups = Groups {
        fixed: (fixed_windows, s),
        varying,
        ts,
        full,
        lanes,
        out,
    };
    match fixed {
        Fixed::Own => pulp::Arch::new().dispatch(OwnFixed::<true>(groups)),
        Fixed::Other => pulp::Arch::new().dispatch(OwnFixed::<false>(groups)),
    }
}

/// [`full_groups`]'s arguments.
struct Groups<'a> {
    fixed: (&'a Windows, usize),
    varying: &'a Windows,
    ts: &'a [usize],
    full: &'a [usize],
    lanes: &'a mut Vec<[f64; LANES]>,
    out: &'a mut [f64],
}

/// [`full_groups`] for `pulp`'s dispatch. A closure would not do: its body is compiled apart
/// from the dispatched function, for the baseline instruction set; `with_simd`, inlined
/// always, is compiled inside it.
struct OwnFixed<'a, const OWN_FIXED: bool>(Groups<'a>);

impl<const OWN_FIXED: bool> pulp::WithSimd for OwnFixed<'_, OWN_FIXED> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) {
        let g = self.0;
        full_groups::<OWN_FIXED>(g.fixed, g.varying, g.ts, g.full, g.lanes, g.out);
    }
}

/// The comparisons `full` (positions in `ts`, both windows full) in groups of [`LANES`]; the
/// fixed window is the own one when `OWN_FIXED`.
#[inline(always)]
fn full_groups<const OWN_FIXED: bool>(
    (fixed_windows, s): (&Windows, usize),
    varying: &Windows,
    ts: &[usize],
    full: &[usize],
    lanes: &mut Vec<[f64; LANES]>,
    out: &mut [f64],
) {
    let k = fixed_windows.k;
    let (fx, fy, fz) = fixed_windows.centred(s);
    let fixed_spread = fixed_windows.spread[s];
    for group in full.chunks(LANES) {
        // The group's varying windows, lane by lane (a short last group repeats its first).
        let t_of = |l: usize| ts[group[if l < group.len() { l } else { 0 }]];
        lanes.clear();
        lanes.resize(3 * k, [0.0; LANES]);
        for l in 0..LANES {
            let (vx, vy, vz) = varying.centred(t_of(l));
            let (lx, rest) = lanes.split_at_mut(k);
            let (ly, lz) = rest.split_at_mut(k);
            for (dst, &v) in lx.iter_mut().zip(vx) {
                dst[l] = v;
            }
            for (dst, &v) in ly.iter_mut().zip(vy) {
                dst[l] = v;
            }
            for (dst, &v) in lz.iter_mut().zip(vz) {
                dst[l] = v;
            }
        }
        let (vx, rest) = lanes.split_at(k);
        let (vy, vz) = rest.split_at(k);
        // Point i of each lane's two windows: (own, other).
        let point = |i: usize| {
            let fixed = ([fx[i]; LANES], [fy[i]; LANES], [fz[i]; LANES]);
            let varying = (vx[i], vy[i], vz[i]);
            if OWN_FIXED {
                (fixed, varying)
            } else {
                (varying, fixed)
            }
        };
        // The cross-covariance Σ aᵢ bᵢᵀ of each lane (a: own, b: other), summed in order.
        let mut h = [[0.0f64; LANES]; 9];
        for i in 0..k {
            let ((x, y, z), (u, v, w)) = point(i);
            for (e, (p, q)) in [
                (x, u),
                (x, v),
                (x, w),
                (y, u),
                (y, v),
                (y, w),
                (z, u),
                (z, v),
                (z, w),
            ]
            .into_iter()
            .enumerate()
            {
                h[e] = add(h[e], mul(p, q));
            }
        }
        // Per lane: the rotation of the cross-covariance scaled to unit mean squared spread,
        // then its nine entries as lanes. The rotation is scalar: Horn's eigenvalue is found by
        // a Newton iteration of each lane's own length (in lanes, measured: 4 % slower).
        let mut r = [[0.0f64; LANES]; 9];
        let mut lane_value = [None::<f64>; LANES];
        for l in 0..LANES {
            // IEEE addition commutes: the own window's spread plus the other's, either way.
            let g = fixed_spread + varying.spread[t_of(l)];
            if g <= 0.0 {
                // Every point at its centroid: nothing to align.
                lane_value[l] = Some(0.0);
                continue;
            }
            let sc = 1.0 / (0.5 * g);
            let e = |i: usize| h[i][l] * sc;
            let m = [[e(0), e(1), e(2)], [e(3), e(4), e(5)], [e(6), e(7), e(8)]];
            match horn_rotation(&m) {
                None => lane_value[l] = Some(f64::INFINITY),
                Some(rot) => {
                    for (i, v) in rot.iter().flatten().enumerate() {
                        r[i][l] = *v;
                    }
                }
            }
        }
        // The distances |R aᵢ − bᵢ| of each lane, summed in order.
        let mut sum = [0.0f64; LANES];
        for i in 0..k {
            let ((x, y, z), (bx, by, bz)) = point(i);
            let row = |a: usize| {
                add(
                    add(mul(r[3 * a], x), mul(r[3 * a + 1], y)),
                    mul(r[3 * a + 2], z),
                )
            };
            let (dx, dy, dz) = (sub(row(0), bx), sub(row(1), by), sub(row(2), bz));
            let d2 = add(add(mul(dx, dx), mul(dy, dy)), mul(dz, dz));
            sum = add(sum, d2.map(f64::sqrt));
        }
        for (l, &j) in group.iter().enumerate() {
            out[j] = lane_value[l].unwrap_or(sum[l] / k as f64);
        }
    }
}

/// Lane-wise IEEE operations (never fused: each lane is the scalar computation to the bit).
#[inline(always)]
fn add(a: [f64; LANES], b: [f64; LANES]) -> [f64; LANES] {
    std::array::from_fn(|l| a[l] + b[l])
}

#[inline(always)]
fn sub(a: [f64; LANES], b: [f64; LANES]) -> [f64; LANES] {
    std::array::from_fn(|l| a[l] - b[l])
}

#[inline(always)]
fn mul(a: [f64; LANES], b: [f64; LANES]) -> [f64; LANES] {
    std::array::from_fn(|l| a[l] * b[l])
}
