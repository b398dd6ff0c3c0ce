//! Silhouette clean-up: removal of small foreground specks and filling of small holes.
//!
//! Sand 2003 §4.2 uses plain per-pixel background subtraction; Vlasic 2010 §3.2.1 stresses that
//! "it is important that the silhouettes not contain spurious holes, so small gaps in the
//! foreground are detected and filled". Vlasic fills gaps by comparing colour statistics inside
//! and outside each hole; we use the simpler and more predictable area criterion (a hole is
//! filled when it is small), which is what most capture pipelines do. Both operations only ever
//! *grow* the silhouette at holes and drop isolated specks, so the silhouette stays an upper
//! bound on the body where it matters to Sand's needles (§4.3, §7).
//!
//! Connectivity: foreground components are 8-connected (as the contours of
//! [`crate::image::extract_contours`]); holes are 4-connected background regions, the dual
//! connectivity, so that a diagonal gap in a foreground ring does not count as a hole's exit.

use ::image::Luma;
use imageproc::region_labelling::{connected_components, Connectivity};

use super::mask::Mask;
use crate::error::{Error, Result};

/// Largest pixel count `imageproc::region_labelling::connected_components` accepts (exclusive).
const MAX_LABEL_PIXELS: usize = 1 << 32;

fn labels(mask: &Mask, conn: Connectivity) -> Result<(Vec<u32>, usize)> {
    if mask.pixel_count() >= MAX_LABEL_PIXELS {
        return Err(Error::InvalidParam {
            name: "mask size",
            reason: format!(
                "component labelling supports fewer than 2^32 pixels, got {}",
                mask.pixel_count()
            ),
        });
    }
    let lab = connected_components(&mask.to_gray(), conn, Luma([0u8])).into_raw();
    let n = lab.iter().copied().max().unwrap_or(0) as usize;
    Ok((lab, n))
}

/// Removes 8-connected foreground components with fewer than `min_px` pixels (they become
/// background). `min_px = 0` or `1` changes nothing.
///
/// # Errors
/// [`Error::InvalidParam`] if the mask has 2³² pixels or more.
pub fn remove_small_components(mask: &Mask, min_px: usize) -> Result<Mask> {
    if min_px <= 1 || mask.is_empty() {
        return Ok(mask.clone());
    }
    let (lab, n) = labels(mask, Connectivity::Eight)?;
    let mut area = vec![0usize; n + 1];
    for &l in &lab {
        area[l as usize] += 1;
    }
    let keep: Vec<bool> = lab
        .iter()
        .map(|&l| l != 0 && area[l as usize] >= min_px)
        .collect();
    Mask::from_bools(mask.width(), mask.height(), &keep)
}

/// Fills holes: 4-connected background regions that do not touch the image border and have at
/// most `max_px` pixels become foreground. `max_px = 0` changes nothing.
///
/// # Errors
/// [`Error::InvalidParam`] if the mask has 2³² pixels or more.
pub fn fill_small_holes(mask: &Mask, max_px: usize) -> Result<Mask> {
    if max_px == 0 || mask.is_full() || mask.is_zero_sized() {
        return Ok(mask.clone());
    }
    let (lab, n) = labels(&mask.not(), Connectivity::Four)?;
    let (w, h) = (mask.width() as usize, mask.height() as usize);
    let mut area = vec![0usize; n + 1];
    let mut touches_border = vec![false; n + 1];
    for (i, &l) in lab.iter().enumerate() {
        let (x, y) = (i % w, i / w);
        area[l as usize] += 1;
        if x == 0 || y == 0 || x + 1 == w || y + 1 == h {
            touches_border[l as usize] = true;
        }
    }
    let fg: Vec<bool> = lab
        .iter()
        .map(|&l| {
            let l = l as usize;
            l == 0 || (!touches_border[l] && area[l] <= max_px)
        })
        .collect();
    Mask::from_bools(mask.width(), mask.height(), &fg)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn removes_specks_keeps_body() {
        let mut m = Mask::from_fn(30, 30, |x, y| (5..20).contains(&x) && (5..20).contains(&y));
        m.set(25, 25, true).unwrap();
        m.set(26, 26, true).unwrap(); // 8-connected to (25, 25): a 2-pixel speck
        m.set(28, 2, true).unwrap();
        let c = remove_small_components(&m, 3).unwrap();
        assert_eq!(c.count(), 15 * 15);
        assert!(!c.get(25, 25) && !c.get(28, 2) && c.get(5, 5));
        let c2 = remove_small_components(&m, 2).unwrap();
        assert_eq!(c2.count(), 15 * 15 + 2);
        assert_eq!(remove_small_components(&m, 0).unwrap(), m);
    }

    #[test]
    fn fills_small_holes_not_large_or_open_ones() {
        let ring =
            |x: u32, y: u32, lo: u32, hi: u32| (lo..hi).contains(&x) && (lo..hi).contains(&y);
        // A square with a 2x2 hole and a 6x6 hole, plus a notch open to the outside.
        let m = Mask::from_fn(40, 40, |x, y| {
            let small_hole = ring(x, y, 5, 7);
            let big_hole = ring(x, y, 20, 26);
            let notch = x < 10 && y == 30;
            ring(x, y, 2, 38) && !(small_hole || big_hole || notch)
        });
        let f = fill_small_holes(&m, 10).unwrap();
        assert!(f.get(5, 5) && f.get(6, 6));
        assert!(!f.get(22, 22));
        assert!(!f.get(4, 30));
        assert_eq!(f.count(), m.count() + 4);
        assert_eq!(fill_small_holes(&m, 36).unwrap().count(), m.count() + 40);
        assert_eq!(fill_small_holes(&m, 0).unwrap(), m);
        // Empty and zero-sized masks pass through.
        assert!(fill_small_holes(&Mask::new(3, 3), 5).unwrap().is_empty());
        assert!(fill_small_holes(&Mask::new(0, 3), 5)
            .unwrap()
            .is_zero_sized());
    }
}
