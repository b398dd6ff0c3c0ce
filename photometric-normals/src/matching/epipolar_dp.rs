//! Criminisi's four-state dynamic programme: the lowest-cost path through one plane's grid of
//! matching costs, evaluated on the band only.

pub(super) const LV: usize = 0;
pub(super) const RV: usize = 1;

/// The lowest-cost path through an `na × nb` grid of costs (`∞` = not allowed), four states;
/// returns the matched `(a, b)` cells in order. `rows[a]` is the half-open range of `b`
/// holding row `a`'s finite cells (empty when none).
///
/// Criminisi's four-state programme evaluated on the band only. Outside the evaluated cells
/// a path can only be occluded, and an occluded stretch between two matches costs
/// `2 · disc + k · occ` for its `k ≥ 1` steps, whatever their order (entering an occlusion
/// and leaving it into a diagonal match each pay `disc`; occluded steps pay `occ`; slanted
/// steps need a matched predecessor). So the best path into cell `(i, j)` through an
/// occlusion comes from the best matched cell `(i', j')` with `i' < i`, `j' < j` of
/// `F − occ · (i' + j')`, a prefix minimum kept per column. The start (`LO` at the corner,
/// no penalty) and the end (a last occlusion pays `disc`) are the same sums. This is the
/// same minimisation as the programme over every node of the `(na + 1) × (nb + 1)` grid (the
/// form before; kept as the unit test's reference, the same matches), with work in the band
/// and `O(nb)` per row for the prefix minima.
pub(super) fn lowest_cost_path(
    costs: &[f64],
    na: usize,
    nb: usize,
    rows: &[(usize, usize)],
    occ: f64,
    disc: f64,
) -> Vec<(usize, usize)> {
    // Per evaluated cell (row-major in the bands): the best cost ending in a match of the
    // cell reached by a left step (LV: diagonal or left-slanted) or a right step (RV), and
    // where it came from.
    let mut offset = Vec::with_capacity(na + 1);
    let mut total = 0;
    for &(lo, hi) in rows {
        offset.push(total);
        total += hi.saturating_sub(lo);
    }
    offset.push(total);
    let cell = |i: usize, j: usize| -> Option<usize> {
        let (lo, hi) = rows[i];
        (j >= lo && j < hi).then(|| offset[i] + j - lo)
    };
    #[derive(Clone, Copy)]
    enum From {
        None,
        Start,
        /// A matched cell (row, column, state) before this one: a diagonal or slanted step.
        Step(usize, usize, usize),
        /// A matched cell (row, column, state) before an occluded stretch.
        Occluded(usize, usize, usize),
    }
    let mut f = vec![[f64::INFINITY; 2]; total];
    let mut from = vec![[From::None; 2]; total];
    let best_of = |v: &[f64; 2]| if v[RV] < v[LV] { RV } else { LV };
    // Per column j: the least `F − occ · (i' + j')` over the rows done and columns ≤ j, and
    // its cell.
    let mut prefix = vec![(f64::INFINITY, 0usize, 0usize, LV); nb];
    for i in 0..na {
        let (lo, hi) = rows[i];
        for j in lo..hi {
            let c = costs[i * nb + j];
            if !c.is_finite() {
                continue;
            }
            let k = offset[i] + j - lo;
            let mut lv = (occ * (i + j) as f64 + disc + c, From::Start);
            let offer = |v: f64, p: From, best: &mut (f64, From)| {
                if v < best.0 {
                    *best = (v, p);
                }
            };
            if i > 0 && j > 0 {
                if let Some(q) = cell(i - 1, j - 1) {
                    for s in [LV, RV] {
                        offer(f[q][s] + c, From::Step(i - 1, j - 1, s), &mut lv);
                    }
                }
                let (g, pi, pj, ps) = prefix[j - 1];
                offer(
                    g + occ * (i + j - 2) as f64 + 2.0 * disc + c,
                    From::Occluded(pi, pj, ps),
                    &mut lv,
                );
            }
            if i > 0 {
                if let Some(q) = cell(i - 1, j) {
                    for s in [LV, RV] {
                        offer(f[q][s] + c, From::Step(i - 1, j, s), &mut lv);
                    }
                }
            }
            let mut rv = (f64::INFINITY, From::None);
            if j > 0 {
                if let Some(q) = cell(i, j - 1) {
                    for s in [LV, RV] {
                        offer(f[q][s] + c, From::Step(i, j - 1, s), &mut rv);
                    }
                }
            }
            f[k] = [lv.0, rv.0];
            from[k] = [lv.1, rv.1];
        }
        // Fold the row into the prefix minima (columns ≥ the row's first cell).
        let mut run = (f64::INFINITY, 0usize, 0usize, LV);
        for (j, p) in prefix.iter_mut().enumerate().skip(lo) {
            if let Some(k) = cell(i, j) {
                let s = best_of(&f[k]);
                let g = f[k][s] - occ * (i + j) as f64;
                if g < run.0 {
                    run = (g, i, j, s);
                }
            }
            if run.0 < p.0 {
                *p = run;
            }
        }
    }
    // The end: every sample occluded, or the last match then an occluded stretch.
    let mut end = (occ * (na + nb) as f64, None);
    for i in 0..na {
        let (lo, hi) = rows[i];
        for j in lo..hi {
            let k = offset[i] + j - lo;
            let s = best_of(&f[k]);
            let steps = (na - 1 - i) + (nb - 1 - j);
            let v = if steps == 0 {
                f[k][s]
            } else {
                f[k][s] + disc + occ * steps as f64
            };
            if v < end.0 {
                end = (v, Some((i, j, s)));
            }
        }
    }
    let mut path = Vec::new();
    let mut at = end.1;
    while let Some((i, j, s)) = at {
        path.push((i, j));
        let Some(k) = cell(i, j) else { break };
        at = match from[k][s] {
            From::Step(pi, pj, ps) | From::Occluded(pi, pj, ps) => Some((pi, pj, ps)),
            From::Start | From::None => None,
        };
    }
    path.reverse();
    path
}
