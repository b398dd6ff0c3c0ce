//! The matching metrics of a grid cell: surface windows under their optimal rigid alignment,
//! and the image windows (full-on, half-on stack, projected through the surfaces).

use skin_core::math::DVec3;

use super::epipolar::Prepared;
use super::horn::horn_rotation;

/// Mean distance of corresponding points after the optimal rigid alignment (the Kabsch
/// problem: the rotation that minimises the summed squared distances of the centred points).
///
/// The rotation is found as Horn's unit quaternion — the eigenvector of the largest
/// eigenvalue of the 4 × 4 key matrix of the cross-covariance — with the eigenvalue from
/// Newton's method on the key matrix's characteristic polynomial (Theobald's QCP, Liu et al.
/// 2010) and the eigenvector as the longest column of the adjugate of `N − λI`. This is the
/// Kabsch rotation with the reflection fix, found in a fixed small number of operations
/// instead of a 3 × 3 SVD.
pub(super) fn rigid_residual(pairs: &[(DVec3, DVec3)]) -> f64 {
    let n = pairs.len() as f64;
    let ca = pairs.iter().map(|p| p.0).sum::<DVec3>() / n;
    let cb = pairs.iter().map(|p| p.1).sum::<DVec3>() / n;
    aligned_distance(pairs.len(), || {
        pairs.iter().map(|(a, b)| (*a - ca, *b - cb))
    })
}

/// The mean distance of `n` centred point pairs (`centred` yields them, twice) under the
/// optimal rotation.
pub(super) fn aligned_distance<I: Iterator<Item = (DVec3, DVec3)>>(
    n: usize,
    centred: impl Fn() -> I,
) -> f64 {
    let mut h = [[0.0f64; 3]; 3];
    let mut g = 0.0;
    for (a, b) in centred() {
        let (a, b) = (a.to_array(), b.to_array());
        for (r, row) in h.iter_mut().enumerate() {
            for (c, v) in row.iter_mut().enumerate() {
                *v += a[r] * b[c];
            }
        }
        g += a.iter().chain(&b).map(|v| v * v).sum::<f64>();
    }
    if g <= 0.0 {
        // Every point at its centroid: nothing to align.
        return 0.0;
    }
    // Scale to unit mean squared spread so that the tolerances below are relative.
    let s = 1.0 / (0.5 * g);
    for v in h.iter_mut().flatten() {
        *v *= s;
    }
    let Some(r) = horn_rotation(&h) else {
        return f64::INFINITY;
    };
    centred()
        .map(|(a, b)| {
            let ra = DVec3::new(
                r[0][0] * a.x + r[0][1] * a.y + r[0][2] * a.z,
                r[1][0] * a.x + r[1][1] * a.y + r[1][2] * a.z,
                r[2][0] * a.x + r[2][1] * a.y + r[2][2] * a.z,
            );
            (ra - b).length()
        })
        .sum::<f64>()
        / n as f64
}

/// The surface windows of a plane's samples, gathered once per plane: `k = window²` points
/// per sample in window order (rows, then columns; `NaN` where the pixel is outside the image
/// or has no surface), and the centroid of each window whose points all exist.
pub(super) struct Windows {
    pub(super) k: usize,
    pub(super) points: Vec<DVec3>,
    pub(super) centroids: Vec<Option<DVec3>>,
    /// Per window: its points less the centroid (of full windows; else the points), as `k`
    /// xs, then ys, then zs.
    pub(super) centred: Vec<f64>,
    /// Per window: the sum of the centred points' squared norms.
    pub(super) spread: Vec<f64>,
}

impl Windows {
    /// The windows of `field` (per pixel of a `width × height` image) around `centres`.
    /// With `contour = Some((camera centre, jump per pixel))`, a window's points whose
    /// distance from the camera centre differs from the window centre's by more than the
    /// jump per pixel of Chebyshev distance are left out ([`MatchingParams::contour_jump_m`]).
    pub(super) fn gather(
        field: &[Option<DVec3>],
        (width, height): (u32, u32),
        centres: impl Iterator<Item = Option<usize>>,
        half: i64,
        contour: Option<(DVec3, f64)>,
    ) -> Self {
        let (w, h) = (i64::from(width), i64::from(height));
        let side = (2 * half + 1) as usize;
        let k = side * side;
        let mut points = Vec::new();
        let mut centroids = Vec::new();
        let mut centred = Vec::new();
        let mut spread = Vec::new();
        for centre in centres {
            let start = points.len();
            match centre {
                None => points.resize(start + k, DVec3::NAN),
                Some(c) => {
                    let (cx, cy) = ((c % width as usize) as i64, (c / width as usize) as i64);
                    for dy in -half..=half {
                        for dx in -half..=half {
                            let (x, y) = (cx + dx, cy + dy);
                            let p = (x >= 0 && y >= 0 && x < w && y < h)
                                .then(|| field[(y * w + x) as usize])
                                .flatten();
                            points.push(p.unwrap_or(DVec3::NAN));
                        }
                    }
                }
            }
            if let Some((eye, jump)) = contour {
                let window = &mut points[start..];
                let mid = window[k / 2];
                if !mid.x.is_nan() {
                    let r0 = (mid - eye).length();
                    for (i, p) in window.iter_mut().enumerate() {
                        let (dx, dy) = ((i % side) as i64 - half, (i / side) as i64 - half);
                        let steps = dx.abs().max(dy.abs()) as f64;
                        if !p.x.is_nan() && ((*p - eye).length() - r0).abs() > jump * steps {
                            *p = DVec3::NAN;
                        }
                    }
                }
            }
            let window = &points[start..];
            let centroid = window
                .iter()
                .all(|p| !p.x.is_nan())
                .then(|| window.iter().copied().sum::<DVec3>() / k as f64);
            let c = centroid.unwrap_or(DVec3::ZERO);
            centred.extend(window.iter().map(|p| p.x - c.x));
            centred.extend(window.iter().map(|p| p.y - c.y));
            centred.extend(window.iter().map(|p| p.z - c.z));
            spread.push(window.iter().map(|p| (*p - c).length_squared()).sum());
            centroids.push(centroid);
        }
        Self {
            k,
            points,
            centroids,
            centred,
            spread,
        }
    }

    pub(super) fn centred(&self, s: usize) -> (&[f64], &[f64], &[f64]) {
        let w = &self.centred[3 * s * self.k..3 * (s + 1) * self.k];
        let (x, yz) = w.split_at(self.k);
        let (y, z) = yz.split_at(self.k);
        (x, y, z)
    }

    pub(super) fn window(&self, s: usize) -> &[DVec3] {
        &self.points[s * self.k..(s + 1) * self.k]
    }
}

/// The surface metric's distance between the window `s` of `own` (a view's surface) and the
/// window `t` of `other` (the other surface rendered into that view) when either is not full:
/// the mean distance of the pairs of existing points after the optimal rigid alignment, `∞`
/// if fewer than half the window's pairs exist. `pairs` is scratch space. Two full windows
/// are compared, a grid row's at once, by [`window_distances`](super::batch::window_distances).
pub(super) fn partial_window_distance(
    own: &Windows,
    s: usize,
    other: &Windows,
    t: usize,
    pairs: &mut Vec<(DVec3, DVec3)>,
) -> f64 {
    let (a, b) = (own.window(s), other.window(t));
    pairs.clear();
    pairs.extend(
        a.iter()
            .zip(b)
            .filter(|(p, q)| !p.x.is_nan() && !q.x.is_nan())
            .map(|(p, q)| (*p, *q)),
    );
    if pairs.len() * 2 < own.k {
        return f64::INFINITY;
    }
    rigid_residual(pairs)
}

/// Adds the squared differences of two pixels' image stacks (from image `from` on) to `sum`
/// and their count to `n`; false if a view has no images.
pub(super) fn add_stack_difference(
    (pl, a): (&Prepared<'_>, usize),
    (pr, b): (&Prepared<'_>, usize),
    from: usize,
    (sa, sb): (&mut Vec<f64>, &mut Vec<f64>),
    (sum, n): (&mut f64, &mut usize),
) -> bool {
    sa.clear();
    sb.clear();
    if !(pl.stack_at(a, sa, from) && pr.stack_at(b, sb, from)) {
        return false;
    }
    for (u, v) in sa.iter().zip(sb.iter()) {
        *sum += (u - v).powi(2);
        *n += 1;
    }
    true
}

/// Mean squared difference of the image stacks (from image `from` on) over the windows
/// around `ia` (left) and `ib` (right).
pub(super) fn window_difference(
    pl: &Prepared<'_>,
    pr: &Prepared<'_>,
    ia: usize,
    ib: usize,
    half: i64,
    from: usize,
    (sa, sb): &mut (Vec<f64>, Vec<f64>),
) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for (a, b) in pl.window(ia, half).zip(pr.window(ib, half)) {
        let (Some(a), Some(b)) = (a, b) else { continue };
        if !add_stack_difference((pl, a), (pr, b), from, (sa, sb), (&mut sum, &mut n)) {
            return f64::INFINITY;
        }
    }
    if n == 0 {
        f64::INFINITY
    } else {
        sum / n as f64
    }
}

/// The half-on stacks compared through the surface: the left window's pixels against the
/// right image at the points of the right surface (rendered into the left view) that
/// correspond to them around the projection of the right sample's point `xb`.
pub(super) fn projected_difference(
    pl: &Prepared<'_>,
    pr: &Prepared<'_>,
    ia: usize,
    xb: DVec3,
    half: i64,
    (sa, sb): &mut (Vec<f64>, Vec<f64>),
) -> f64 {
    let Some(centre) = pl.pixel_of(xb) else {
        return f64::INFINITY;
    };
    let (mut sum, mut n) = (0.0, 0usize);
    for (a, b) in pl.window(ia, half).zip(pl.window(centre, half)) {
        let (Some(a), Some(b)) = (a, b) else { continue };
        let (Some(_), Some(q)) = (pl.points[a], pl.other_points[b]) else {
            continue;
        };
        let Some(qb) = pr.pixel_of(q) else { continue };
        if !add_stack_difference((pl, a), (pr, qb), 1, (sa, sb), (&mut sum, &mut n)) {
            return f64::INFINITY;
        }
    }
    let full = ((2 * half + 1) * (2 * half + 1)) as usize;
    if n == 0 || n * 2 < full {
        f64::INFINITY
    } else {
        sum / n as f64
    }
}
