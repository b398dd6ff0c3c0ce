//! The "Ghost" sheet (Vlasic thesis: a performer under a cloth, for non-articulated
//! reconstruction): a square, horizontal grid of `resolution²` vertices centred above the
//! head, [`SheetParams::drop_height_m`] above the top of the body, dropped onto the standing
//! figure and settled ([`super::Garment::new`]).
//!
//! **Keeping it on.** After settling, every vertex within [`SheetParams::pin_distance_m`] of
//! the cloth's collision surface around a [`SheetParams::pin_joints`] capsule (head, neck,
//! across the shoulders) is pinned: it then follows its skinned position, i.e. the head and
//! shoulders carry the sheet as a hat would, and the rest hangs and swings freely. Without
//! pins a fast turn of the body would throw the sheet off, since friction alone cannot hold
//! cloth on a round head.

use super::colliders::PosedColliders;
use super::{SheetParams, MAX_GARMENT_VERTICES};
use skin_core::check;
use skin_core::math::DVec3;
use skin_core::mesh::TriMesh;
use skin_core::{Error, Result};

/// Checks the sheet's own parameters (not the cloth's).
fn check_params(p: &SheetParams) -> Result<()> {
    check::positive("sheet.size_m", p.size_m)?;
    check::non_negative("sheet.drop_height_m", p.drop_height_m)?;
    check::positive("sheet.settle_s", p.settle_s)?;
    check::non_negative("sheet.pin_distance_m", p.pin_distance_m)?;
    if p.resolution < 3 {
        return Err(Error::InvalidParam {
            name: "sheet.resolution",
            reason: format!("need at least 3 vertices a side, got {}", p.resolution),
        });
    }
    let n = p.resolution.saturating_mul(p.resolution);
    if n > MAX_GARMENT_VERTICES {
        return Err(Error::InvalidParam {
            name: "sheet.resolution",
            reason: format!(
                "{0}² = {n} vertices, more than the {MAX_GARMENT_VERTICES} a coarse garment may have",
                p.resolution
            ),
        });
    }
    if p.pin_joints.is_empty() {
        return Err(Error::InvalidParam {
            name: "sheet.pin_joints",
            reason: "need at least one joint to carry the sheet".into(),
        });
    }
    Ok(())
}

/// The flat sheet centred at (`centre.x`, `centre.z`), `drop_height_m` above `top_y`; faces
/// counter-clockwise seen from above (normals up).
///
/// # Errors
/// [`Error::InvalidParam`] for bad parameters.
pub(super) fn pattern(p: &SheetParams, centre: DVec3, top_y: f64) -> Result<TriMesh> {
    check_params(p)?;
    let n = p.resolution;
    let step = p.size_m / (n - 1) as f64;
    let y = top_y + p.drop_height_m;
    let half = 0.5 * p.size_m;
    let mut vertices = Vec::with_capacity(n * n);
    for j in 0..n {
        for i in 0..n {
            vertices.push(DVec3::new(
                centre.x - half + i as f64 * step,
                y,
                centre.z - half + j as f64 * step,
            ));
        }
    }
    let id = |i: usize, j: usize| (j * n + i) as u32;
    let mut faces = Vec::with_capacity(2 * (n - 1) * (n - 1));
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            // (i, j) → (i, j+1) → (i+1, j): Z × X = +Y, counter-clockwise from above.
            faces.push([id(i, j), id(i, j + 1), id(i + 1, j)]);
            faces.push([id(i + 1, j), id(i, j + 1), id(i + 1, j + 1)]);
        }
    }
    TriMesh::new(vertices, faces)
}

/// Vertices of the settled sheet `x` resting on the capsules of `carriers`.
///
/// # Errors
/// [`Error::Degenerate`] when no vertex rests on them (the sheet slid off).
pub(super) fn pins(
    p: &SheetParams,
    x: &[DVec3],
    carriers: &PosedColliders,
    margin: f64,
) -> Result<Vec<bool>> {
    let pinned: Vec<bool> = x
        .iter()
        .map(|&v| carriers.signed_distance(v) < margin + p.pin_distance_m)
        .collect();
    if pinned.iter().any(|&b| b) {
        Ok(pinned)
    } else {
        Err(Error::Degenerate {
            what: "the settled sheet touches none of its pin joints (it slid off the body)".into(),
        })
    }
}
