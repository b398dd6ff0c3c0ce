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

use super::mask::Mask;
use crate::error::{Error, Result};

/// Largest supported pixel count (exclusive): component labels are `u32`.
const MAX_LABEL_PIXELS: usize = 1 << 32;

fn check_labelable(mask: &Mask) -> Result<()> {
    if mask.pixel_count() >= MAX_LABEL_PIXELS {
        return Err(Error::InvalidParam {
            name: "mask size",
            reason: format!(
                "component labelling supports fewer than 2^32 pixels, got {}",
                mask.pixel_count()
            ),
        });
    }
    Ok(())
}

/// Which neighbours of a pixel are connected to it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Neighbourhood {
    /// Left, right, up and down.
    Four,
    /// The four above and the four diagonal neighbours.
    Eight,
}

/// The connected components of a mask's pixels of one value ([`label_components`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Components {
    /// Per pixel (row-major): component index + 1, or 0 for a pixel of the other value.
    pub label: Vec<u32>,
    /// Per component: pixel count.
    pub area: Vec<usize>,
    /// Per component: whether it touches the image border.
    pub touches_border: Vec<bool>,
}

impl Components {
    /// Number of components.
    pub fn count(&self) -> usize {
        self.area.len()
    }

    /// The component (0-based) of pixel `i` (row-major), `None` for a pixel of the other
    /// value or out of range.
    pub fn component_of(&self, i: usize) -> Option<usize> {
        match self.label.get(i) {
            Some(&l) if l > 0 => Some(l as usize - 1),
            _ => None,
        }
    }

    /// The row-major pixel indices of each component, in ascending order.
    pub fn members(&self) -> Vec<Vec<usize>> {
        let mut out: Vec<Vec<usize>> = self.area.iter().map(|&a| Vec::with_capacity(a)).collect();
        for (i, &l) in self.label.iter().enumerate() {
            if l > 0 {
                out[l as usize - 1].push(i);
            }
        }
        out
    }
}

/// Labels the connected components of the pixels of `mask` whose flag equals `value`
/// (`true`: foreground pieces; `false`: background regions such as holes) by flood fill,
/// linear in the pixel count. Components are numbered in row-major order of their first
/// pixel. Written here rather than using `imageproc::region_labelling` (the test oracle)
/// because callers also need each component's border contact, which the flood fill records
/// in the same pass on the mask's flags without image conversions.
///
/// # Errors
/// [`Error::InvalidParam`] if the mask has 2³² pixels or more (labels are `u32`).
pub fn label_components(
    mask: &Mask,
    value: bool,
    neighbourhood: Neighbourhood,
) -> Result<Components> {
    check_labelable(mask)?;
    let (w, h) = (mask.width() as usize, mask.height() as usize);
    let flags = mask.to_bools();
    let mut label = vec![0u32; flags.len()];
    let mut area = Vec::new();
    let mut touches_border = Vec::new();
    let mut stack = Vec::new();
    let offsets: &[(isize, isize)] = match neighbourhood {
        Neighbourhood::Eight => &[
            (-1, -1),
            (0, -1),
            (1, -1),
            (-1, 0),
            (1, 0),
            (-1, 1),
            (0, 1),
            (1, 1),
        ],
        Neighbourhood::Four => &[(0, -1), (-1, 0), (1, 0), (0, 1)],
    };
    for seed in 0..flags.len() {
        if flags[seed] != value || label[seed] != 0 {
            continue;
        }
        area.push(0usize);
        touches_border.push(false);
        // Fits: checked above that the mask has fewer than 2^32 pixels (hence components).
        let id = area.len() as u32;
        label[seed] = id;
        stack.push(seed);
        while let Some(i) = stack.pop() {
            let (x, y) = (i % w, i / w);
            let c = area.len() - 1;
            area[c] += 1;
            if x == 0 || y == 0 || x + 1 == w || y + 1 == h {
                touches_border[c] = true;
            }
            for &(dx, dy) in offsets {
                let (nx, ny) = (x as isize + dx, y as isize + dy);
                if nx < 0 || ny < 0 || nx >= w as isize || ny >= h as isize {
                    continue;
                }
                let j = ny as usize * w + nx as usize;
                if flags[j] == value && label[j] == 0 {
                    label[j] = id;
                    stack.push(j);
                }
            }
        }
    }
    Ok(Components {
        label,
        area,
        touches_border,
    })
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
    let c = label_components(mask, true, Neighbourhood::Eight)?;
    let keep: Vec<bool> = c
        .label
        .iter()
        .map(|&l| l != 0 && c.area[l as usize - 1] >= min_px)
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
    let c = label_components(mask, false, Neighbourhood::Four)?;
    let fg: Vec<bool> = c
        .label
        .iter()
        .map(|&l| {
            l == 0 || {
                let k = l as usize - 1;
                !c.touches_border[k] && c.area[k] <= max_px
            }
        })
        .collect();
    Mask::from_bools(mask.width(), mask.height(), &fg)
}

#[cfg(test)]
mod tests {
    use super::*;
    use ::image::Luma;
    use imageproc::region_labelling::{connected_components, Connectivity};
    use proptest::prelude::*;

    /// Reference clean-up built on `imageproc`'s union-find labelling.
    fn reference(mask: &Mask, min_px: usize, max_hole_px: usize) -> (Mask, Mask) {
        let (w, h) = mask.dimensions();
        let count = |lab: &[u32]| {
            let mut a = vec![0usize; lab.iter().copied().max().unwrap_or(0) as usize + 1];
            lab.iter().for_each(|&l| a[l as usize] += 1);
            a
        };
        let fg = connected_components(&mask.to_gray(), Connectivity::Eight, Luma([0u8])).into_raw();
        let area = count(&fg);
        let kept = Mask::from_fn(w, h, |x, y| {
            let l = fg[(y * w + x) as usize] as usize;
            l != 0 && (min_px <= 1 || area[l] >= min_px)
        });
        let bg =
            connected_components(&mask.not().to_gray(), Connectivity::Four, Luma([0u8])).into_raw();
        let area = count(&bg);
        let mut border = vec![false; area.len()];
        for y in 0..h {
            for x in 0..w {
                if x == 0 || y == 0 || x + 1 == w || y + 1 == h {
                    border[bg[(y * w + x) as usize] as usize] = true;
                }
            }
        }
        let filled = Mask::from_fn(w, h, |x, y| {
            let l = bg[(y * w + x) as usize] as usize;
            l == 0 || (max_hole_px > 0 && !border[l] && area[l] <= max_hole_px)
        });
        (kept, filled)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        #[test]
        fn matches_imageproc_reference(
            // imageproc 0.27's union-find panics on 1-pixel images ("i < self.count"), so the
            // reference comparison starts at 2x2; tiny masks are checked by hand below.
            (w, h, flags) in (2u32..24, 2u32..24).prop_flat_map(|(w, h)| {
                (Just(w), Just(h), proptest::collection::vec(proptest::bool::weighted(0.55), (w * h) as usize))
            }),
            min_px in 0usize..6,
            max_hole_px in 0usize..6,
        ) {
            let m = Mask::from_bools(w, h, &flags).unwrap();
            let (kept, filled) = reference(&m, min_px, max_hole_px);
            prop_assert_eq!(remove_small_components(&m, min_px).unwrap(), kept);
            prop_assert_eq!(fill_small_holes(&m, max_hole_px).unwrap(), filled);
        }
    }

    #[test]
    fn labels_components_with_either_connectivity() {
        // Two pixels touching diagonally, and a separate vertical pair.
        let m = Mask::from_bools(
            4,
            3,
            &[
                true, false, false, true, //
                false, true, false, true, //
                false, false, false, false,
            ],
        )
        .unwrap();
        let four = label_components(&m, true, Neighbourhood::Four).unwrap();
        assert_eq!(four.count(), 3);
        assert_eq!(four.members(), vec![vec![0], vec![3, 7], vec![5]]);
        assert_eq!(four.component_of(1), None);
        assert_eq!(four.component_of(99), None);
        let eight = label_components(&m, true, Neighbourhood::Eight).unwrap();
        assert_eq!(eight.count(), 2);
        assert_eq!(eight.area, vec![2, 2]);
        assert_eq!(eight.component_of(5), Some(0));
        let background = label_components(&m, false, Neighbourhood::Four).unwrap();
        assert_eq!(background.count(), 1);
        assert!(background.touches_border[0]);
    }

    #[test]
    fn one_pixel_and_one_row_masks() {
        for on in [false, true] {
            let m = Mask::from_bools(1, 1, &[on]).unwrap();
            assert_eq!(remove_small_components(&m, 0).unwrap(), m);
            assert_eq!(remove_small_components(&m, 2).unwrap().count(), 0);
            // A single pixel touches the border: never a hole.
            assert_eq!(fill_small_holes(&m, 5).unwrap(), m);
        }
        // 1x5 row: a 1-pixel and a 2-pixel run; the gap between them touches the border.
        let row = Mask::from_bools(5, 1, &[true, false, true, true, false]).unwrap();
        let kept = remove_small_components(&row, 2).unwrap();
        assert!(!kept.get(0, 0) && kept.get(2, 0) && kept.get(3, 0));
        assert_eq!(fill_small_holes(&row, 5).unwrap(), row);
    }

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
