//! The sparse grid hierarchy: levels of 4³-node blocks (complete or a band around the
//! samples) and the composite indicator read across them.

use skin_core::math::DVec3;

use crate::marching_cubes::{Node, NodeMap};

use super::cells::{cell_of, corners8, trilinear, NONE};
use super::screening::CellScreening;

pub(super) const B: i64 = 4; // nodes per block side
pub(super) const B3: usize = (B * B * B) as usize;

/// One level: a directory of 4³-node blocks, the active ones holding unknowns.
pub(super) struct Level {
    pub(super) depth: u32,
    /// Cells per axis.
    pub(super) n: i64,
    /// Blocks per axis.
    pub(super) nb: i64,
    /// Block → active block index (or `NONE`).
    pub(super) dir: Vec<u32>,
    /// Node slot (active block × 64 + local) → unknown index (or `NONE` outside the domain).
    pub(super) slot: Vec<u32>,
    /// Unknown → node.
    pub(super) nodes: Vec<Node>,
    /// Solution.
    pub(super) x: Vec<f64>,
    /// Whether every block is active (a complete grid, no band).
    pub(super) complete: bool,
    /// Diagonal of the level's operator (filled by `solve_level`).
    pub(super) diag: Vec<f64>,
    /// Unknown neighbours along −x, +x, −y, +y, −z, +z (`NONE` = outside the domain or the
    /// band); every off-diagonal entry of the operator is −1. A table, not computed from the
    /// block layout (ours, measured on the `poisson` bench at depth 9: computing them saved
    /// the table's 24 bytes a node, 17 % of the peak memory, but the solve ran 15 % slower).
    pub(super) nbr: Vec<[u32; 6]>,
    /// Unknowns of the coarser level whose basis functions are nonzero at each node (`NONE`
    /// = absent or outside the coarser band), in the order of `solve::parents`.
    pub(super) up: Vec<[u32; 8]>,
    /// The screening's couplings between the corners of the samples' cells
    /// ([`ScreeningForm::Consistent`](super::ScreeningForm::Consistent)); `None` when the
    /// screening is lumped onto `diag`.
    pub(super) screen: Option<CellScreening>,
    /// With the consistent screening, the smoother's and Jacobi preconditioner's diagonal
    /// (filled by `solve_level`); empty otherwise, where `diag` serves.
    pub(super) l1_diag: Vec<f64>,
}

impl Level {
    pub(super) fn new(depth: u32, active: &[bool]) -> Self {
        let n = 1i64 << depth;
        let nb = n / B + 1;
        let mut dir = vec![NONE; active.len()];
        let mut slot = Vec::new();
        let mut nodes = Vec::new();
        for (count, (bi, _)) in active.iter().enumerate().filter(|(_, &a)| a).enumerate() {
            dir[bi] = count as u32;
            let b = [bi as i64 % nb, (bi as i64 / nb) % nb, bi as i64 / (nb * nb)];
            for l in 0..B3 as i64 {
                let node = [
                    b[0] * B + l % B,
                    b[1] * B + (l / B) % B,
                    b[2] * B + l / (B * B),
                ];
                if node.iter().all(|&c| c <= n) {
                    slot.push(nodes.len() as u32);
                    nodes.push(node);
                } else {
                    slot.push(NONE);
                }
            }
        }
        let x = vec![0.0; nodes.len()];
        let complete = active.iter().all(|&a| a);
        Self {
            depth,
            n,
            nb,
            dir,
            slot,
            nodes,
            x,
            complete,
            diag: Vec::new(),
            nbr: Vec::new(),
            up: Vec::new(),
            screen: None,
            l1_diag: Vec::new(),
        }
    }

    /// The diagonal of the smoother and the Jacobi preconditioner: `l1_diag` with the
    /// consistent screening, `diag` otherwise.
    pub(super) fn smoother_diag(&self) -> &[f64] {
        if self.l1_diag.is_empty() {
            &self.diag
        } else {
            &self.l1_diag
        }
    }

    pub(super) fn h(&self) -> f64 {
        1.0 / self.n as f64
    }

    pub(super) fn in_domain(&self, p: Node) -> bool {
        p.iter().all(|&c| (0..=self.n).contains(&c))
    }

    /// Unknown index of an in-domain node, `None` if its block is inactive.
    pub(super) fn index(&self, p: Node) -> Option<usize> {
        let b = p.map(|c| c / B);
        let d = self.dir[(b[0] + self.nb * (b[1] + self.nb * b[2])) as usize];
        if d == NONE {
            return None;
        }
        let l = p.map(|c| c % B);
        let s = self.slot[d as usize * B3 + (l[0] + B * (l[1] + B * l[2])) as usize];
        (s != NONE).then_some(s as usize)
    }

    /// Unknown indices (`NONE` outside the domain or the band) of the 27 nodes around node
    /// `c`, offsets −1, 0, 1 along each axis, x fastest: [`Level::index`] with each axis's
    /// blocks and offsets found once.
    pub(super) fn stencil_indices(&self, c: Node) -> [u32; 27] {
        let axis = |v: i64| {
            [v - 1, v, v + 1].map(|p| {
                if (0..=self.n).contains(&p) {
                    Some((p / B, p % B))
                } else {
                    None
                }
            })
        };
        let (ax, ay, az) = (axis(c[0]), axis(c[1]), axis(c[2]));
        let mut out = [NONE; 27];
        for (k, slot) in out.iter_mut().enumerate() {
            let (Some((bx, lx)), Some((by, ly)), Some((bz, lz))) =
                (ax[k % 3], ay[(k / 3) % 3], az[k / 9])
            else {
                continue;
            };
            let d = self.dir[(bx + self.nb * (by + self.nb * bz)) as usize];
            if d != NONE {
                *slot = self.slot[d as usize * B3 + (lx + B * (ly + B * lz)) as usize];
            }
        }
        out
    }
}

/// Values of the composite indicator: the finest level holding a node, interpolated from
/// coarser levels elsewhere; memoised for nodes outside every band.
pub(super) struct Composite<'a> {
    pub(super) levels: &'a [Level],
    pub(super) memo: NodeMap<(usize, Node), f64>,
    /// Value outside the domain (above the iso-value: the surface closes along the domain's
    /// faces if it reaches them).
    pub(super) outside: f64,
}

impl Composite<'_> {
    /// Value at node `p` of level index `li` (`p` in that level's domain).
    pub(super) fn value(&mut self, li: usize, p: Node) -> f64 {
        if !self.levels[li].in_domain(p) {
            return self.outside;
        }
        if let Some(i) = self.levels[li].index(p) {
            return self.levels[li].x[i];
        }
        if li == 0 {
            // Unreachable: the complete level holds every in-domain node.
            return self.outside;
        }
        if let Some(&v) = self.memo.get(&(li, p)) {
            return v;
        }
        let v = self.interpolated_from(li - 1, p);
        self.memo.insert((li, p), v);
        v
    }

    /// Value at node `p` of the level below `coarse`, interpolated trilinearly from level
    /// `coarse`: the mean over the coarse nodes `floor(c/2)`, `ceil(c/2)` of each coordinate.
    pub(super) fn interpolated_from(&mut self, coarse: usize, p: Node) -> f64 {
        let lo = p.map(|c| c.div_euclid(2));
        let hi = p.map(|c| (c + 1).div_euclid(2));
        let mut sum = 0.0;
        for corner in 0..8 {
            let q = [
                if corner & 1 == 0 { lo[0] } else { hi[0] },
                if corner & 2 == 0 { lo[1] } else { hi[1] },
                if corner & 4 == 0 { lo[2] } else { hi[2] },
            ];
            sum += self.value(coarse, q);
        }
        sum / 8.0
    }

    /// Trilinear value at a unit-cube point on level `li`.
    pub(super) fn at_point(&mut self, li: usize, q: DVec3) -> f64 {
        let n = self.levels[li].n;
        let (cell, t) = cell_of(q, n);
        let mut v = 0.0;
        for o in corners8() {
            let w = trilinear(t, o);
            if w > 0.0 {
                v += w * self.value(li, [cell[0] + o[0], cell[1] + o[1], cell[2] + o[2]]);
            }
        }
        v
    }
}
