//! The sparse grid hierarchy: levels of 4³-node blocks (complete or a band around the
//! samples) and the composite indicator read across them.

use skin_core::math::DVec3;

use crate::marching_cubes::{Node, NodeMap};

use super::screening::CellScreening;

pub(super) const B: i64 = 4; // nodes per block side
pub(super) const B3: usize = (B * B * B) as usize;
pub(super) const NONE: u32 = u32::MAX;

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

/// Cell (lowest node) holding unit-cube point `q` on a grid of `n` cells, and the local
/// coordinates in it.
pub(super) fn cell_of(q: DVec3, n: i64) -> (Node, DVec3) {
    let g = q * n as f64;
    let c = [
        (g.x.floor() as i64).clamp(0, n - 1),
        (g.y.floor() as i64).clamp(0, n - 1),
        (g.z.floor() as i64).clamp(0, n - 1),
    ];
    let t = g - DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64);
    (c, t)
}

pub(super) fn trilinear(t: DVec3, o: [i64; 3]) -> f64 {
    let f = |t: f64, o: i64| if o == 0 { 1.0 - t } else { t };
    f(t.x, o[0]) * f(t.y, o[1]) * f(t.z, o[2])
}

/// Node nearest to unit-cube point `q` on a grid of `n` cells, and the offset of `q` from it,
/// cells (each component in `[−½, ½]`).
pub(super) fn nearest_node(q: DVec3, n: i64) -> (Node, DVec3) {
    let g = q * n as f64;
    let c = [g.x.round() as i64, g.y.round() as i64, g.z.round() as i64];
    (c, g - DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64))
}

/// Weights along one axis of the nodes at offsets −1, 0, 1 from [`nearest_node`], for a
/// point at offset `t` from it: the quadratic B-spline, `(½ − t)²/2`, `¾ − t²`,
/// `(½ + t)²/2`. The 27 products of the three axes' weights (x fastest)
/// sum to 1 and their centroid is the point, as the trilinear weights' are, but the kernel
/// is three cells wide and smooth.
pub(super) fn quadratic(t: f64) -> [f64; 3] {
    [
        0.5 * (0.5 - t) * (0.5 - t),
        0.75 - t * t,
        0.5 * (0.5 + t) * (0.5 + t),
    ]
}

/// The 8 corner offsets of a cell, x fastest.
pub(super) fn corners8() -> impl Iterator<Item = [i64; 3]> {
    (0..8i64).map(|o| [o & 1, (o >> 1) & 1, (o >> 2) & 1])
}

pub(super) const AXES: [[i64; 3]; 3] = [[1, 0, 0], [0, 1, 0], [0, 0, 1]];

pub(super) fn add(p: Node, d: [i64; 3], s: i64) -> Node {
    [p[0] + s * d[0], p[1] + s * d[1], p[2] + s * d[2]]
}
