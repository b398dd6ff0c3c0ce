//! Horn's quaternion rotation of a cross-covariance with Theobald's QCP eigenvalue (the
//! optimal rigid alignment of the surface metric).

/// The rotation `R` maximising `Σ bᵢ · R aᵢ` for the cross-covariance `h = Σ aᵢ bᵢᵀ` (scaled
/// so that the sum of both point sets' squared norms is 2): Horn's quaternion method with
/// Theobald's QCP eigenvalue. `None` for non-finite input.
pub(super) fn horn_rotation(h: &[[f64; 3]; 3]) -> Option<[[f64; 3]; 3]> {
    let [[sxx, sxy, sxz], [syx, syy, syz], [szx, szy, szz]] = *h;
    // Horn's key matrix N (symmetric 4 × 4); its largest eigenvalue is at most 1 here.
    let k = [
        [sxx + syy + szz, syz - szy, szx - sxz, sxy - syx],
        [syz - szy, sxx - syy - szz, sxy + syx, szx + sxz],
        [szx - sxz, sxy + syx, -sxx + syy - szz, syz + szy],
        [sxy - syx, szx + sxz, syz + szy, -sxx - syy + szz],
    ];
    if k.iter().flatten().any(|v| !v.is_finite()) {
        return None;
    }
    // Characteristic polynomial λ⁴ + c2 λ² + c1 λ + c0 (N is traceless).
    let c2 = -2.0 * h.iter().flatten().map(|v| v * v).sum::<f64>();
    let c1 = 8.0
        * (sxx * syz * szy + syy * szx * sxz + szz * sxy * syx
            - sxx * syy * szz
            - syz * szx * sxy
            - szy * syx * sxz);
    // The determinant of N by its 2 × 2 minors (rows 0-1 against rows 2-3), which the
    // adjugate below reuses.
    let lo = minors2(&k[2], &k[3]);
    let c0 = laplace(&k[0], &k[1], &lo);
    // Newton from the upper bound 1 decreases monotonically onto the largest root and
    // converges quadratically: stop once a step is below 10⁻¹³ (relative), where rounding
    // takes over.
    let mut l = 1.0f64;
    let mut slope = 0.0;
    for _ in 0..50 {
        let l2 = l * l;
        let p = (l2 + c2) * l2 + c1 * l + c0;
        slope = (4.0 * l2 + 2.0 * c2) * l + c1;
        if slope == 0.0 {
            break;
        }
        let step = p / slope;
        l -= step;
        if step.abs() <= 1e-13 * l.abs().max(1e-12) {
            break;
        }
    }
    let mut m = k;
    for (i, row) in m.iter_mut().enumerate() {
        row[i] -= l;
    }
    // The eigenvector: the longest column of adj(N − λI) (N symmetric: the cofactors of a
    // row). Cofactors of rows 0 and 1 expand the 3 × 3 minors along row 1 or 0 with the
    // 2 × 2 minors of rows 2-3; those of rows 2 and 3 along row 3 or 2 with rows 0-1's.
    // Column j is p'(λ) vⱼ v for the unit eigenvector v, and some |vⱼ|² ≥ 1/4: take the first
    // column with |vⱼ|² ≥ 0.1 (well conditioned), else the longest.
    let accept = 0.1 * slope * slope;
    let lo = minors2(&m[2], &m[3]);
    let (mut best, mut best_norm) = ([0.0; 4], 0.0);
    for j in 0..4 {
        let q = match j {
            0 => cofactors(&m[1], &lo, 1.0),
            1 => cofactors(&m[0], &lo, -1.0),
            2 => cofactors(&m[3], &minors2(&m[0], &m[1]), 1.0),
            _ => cofactors(&m[2], &minors2(&m[0], &m[1]), -1.0),
        };
        let norm = q.iter().map(|v| v * v).sum::<f64>();
        if norm > best_norm {
            (best, best_norm) = (q, norm);
        }
        if norm >= accept {
            break;
        }
    }
    if !(best_norm > 0.0 && best_norm.is_finite()) {
        // A degenerate key matrix (e.g. collinear points): any optimum; take identity.
        return Some([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]);
    }
    let inv = 1.0 / best_norm.sqrt();
    let [w, x, y, z] = best.map(|v| v * inv);
    Some([
        [
            w * w + x * x - y * y - z * z,
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            w * w - x * x + y * y - z * z,
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            w * w - x * x - y * y + z * z,
        ],
    ])
}

/// The six 2 × 2 minors of two rows, columns `(0,1), (0,2), (0,3), (1,2), (1,3), (2,3)`.
pub(super) fn minors2(r: &[f64; 4], s: &[f64; 4]) -> [f64; 6] {
    [
        r[0] * s[1] - r[1] * s[0],
        r[0] * s[2] - r[2] * s[0],
        r[0] * s[3] - r[3] * s[0],
        r[1] * s[2] - r[2] * s[1],
        r[1] * s[3] - r[3] * s[1],
        r[2] * s[3] - r[3] * s[2],
    ]
}

/// The 3 × 3 determinants of `row` over the two rows whose 2 × 2 minors are `m2`, one per
/// left-out column `c`, signed as cofactors `(−1)^c · sign`.
pub(super) fn cofactors(row: &[f64; 4], m2: &[f64; 6], sign: f64) -> [f64; 4] {
    let [m01, m02, m03, m12, m13, m23] = *m2;
    [
        sign * (row[1] * m23 - row[2] * m13 + row[3] * m12),
        -sign * (row[0] * m23 - row[2] * m03 + row[3] * m02),
        sign * (row[0] * m13 - row[1] * m03 + row[3] * m01),
        -sign * (row[0] * m12 - row[1] * m02 + row[2] * m01),
    ]
}

/// The determinant of a 4 × 4 matrix from its rows 0, 1 and the 2 × 2 minors `m23` of rows
/// 2, 3 (Laplace expansion by complementary minors).
pub(super) fn laplace(r0: &[f64; 4], r1: &[f64; 4], m23: &[f64; 6]) -> f64 {
    let m01 = minors2(r0, r1);
    m01[0] * m23[5] - m01[1] * m23[4] + m01[2] * m23[3] + m01[3] * m23[2] - m01[4] * m23[1]
        + m01[5] * m23[0]
}
