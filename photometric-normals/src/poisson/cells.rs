//! Cells and nodes of a regular grid over the unit cube: the cell holding a point and its
//! corners, the trilinear and quadratic splat weights, axis offsets, and the marker of an
//! absent unknown.

use skin_core::math::DVec3;

use crate::marching_cubes::Node;

/// An absent unknown (outside the domain or the band) in the levels' index tables.
pub(super) const NONE: u32 = u32::MAX;

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
