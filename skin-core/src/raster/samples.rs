//! Per-pixel sample rays of a camera.
//!
//! Each output (observed, distorted) pixel `(x, y)` is sampled at its centre — integer pixel
//! coordinates, the OpenCV convention of [`crate::camera::Intrinsics`] — along the ray
//! [`crate::camera::Camera::ray`] returns for it. The ray is stored as its camera-frame
//! direction `(nx, ny, 1)`, the undistorted normalised image point. Without distortion these
//! are separable (`nx` depends on `x` only); with distortion they are inverted once per camera
//! by Newton's method ([`crate::camera::RadialDistortion::undistort`]) and kept in a table.

use rayon::prelude::*;

use crate::camera::Camera;
use crate::math::DVec2;

/// Camera-frame sample directions `(nx, ny)` (third component 1) of every pixel.
#[derive(Clone)]
pub(crate) enum SampleGrid {
    /// Undistorted camera: `nx` per column, `ny` per row.
    Pinhole { col_nx: Vec<f32>, row_ny: Vec<f32> },
    /// Distorted camera: one direction per pixel, row-major, as separate `nx` and `ny`
    /// tables; NaN for pixels outside the range of a barrel model (never covered).
    Table {
        width: usize,
        nx: Vec<f32>,
        ny: Vec<f32>,
    },
}

impl SampleGrid {
    /// The sample directions of `camera`'s pixels.
    pub(crate) fn new(camera: &Camera) -> Self {
        let k = camera.intrinsics;
        let (w, h) = (k.width as usize, k.height as usize);
        if camera.distortion.k1 == 0.0 {
            let col_nx = (0..w).map(|x| ((x as f64 - k.cx) / k.fx) as f32).collect();
            let row_ny = (0..h).map(|y| ((y as f64 - k.cy) / k.fy) as f32).collect();
            return SampleGrid::Pinhole { col_nx, row_ny };
        }
        let mut dirs = vec![[0.0f32; 2]; w * h];
        dirs.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            for (x, d) in row.iter_mut().enumerate() {
                let px = DVec2::new(x as f64, y as f64);
                *d = match camera.distortion.undistort(&k, px) {
                    Ok(u) => {
                        let n = k.normalized_from_pixel(u);
                        [n.x as f32, n.y as f32]
                    }
                    Err(_) => [f32::NAN, f32::NAN],
                };
            }
        });
        let (nx, ny) = dirs.into_iter().map(|[a, b]| (a, b)).unzip();
        SampleGrid::Table { width: w, nx, ny }
    }
}

/// Sample directions as the inner loops read them; one implementation per grid kind so each
/// loop is compiled without a branch on the kind and vectorises.
pub(crate) trait Dirs: Sync {
    /// Iterator over the `ny` of a row span.
    type Ny<'a>: Iterator<Item = f32>
    where
        Self: 'a;
    /// `nx` and `ny` of pixels `x0..=x1` of row `y`.
    fn span(&self, y: usize, x0: usize, x1: usize) -> (&[f32], Self::Ny<'_>);
    /// Direction `(nx, ny)` of pixel `(x, y)`.
    fn dir(&self, x: usize, y: usize) -> [f32; 2];
}

/// [`SampleGrid::Pinhole`] as [`Dirs`].
pub(crate) struct PinholeDirs<'a> {
    pub(crate) col_nx: &'a [f32],
    pub(crate) row_ny: &'a [f32],
}

impl Dirs for PinholeDirs<'_> {
    type Ny<'b>
        = std::iter::Repeat<f32>
    where
        Self: 'b;
    #[inline(always)]
    fn span(&self, y: usize, x0: usize, x1: usize) -> (&[f32], Self::Ny<'_>) {
        (&self.col_nx[x0..=x1], std::iter::repeat(self.row_ny[y]))
    }
    #[inline(always)]
    fn dir(&self, x: usize, y: usize) -> [f32; 2] {
        [self.col_nx[x], self.row_ny[y]]
    }
}

/// [`SampleGrid::Table`] as [`Dirs`].
pub(crate) struct TableDirs<'a> {
    pub(crate) width: usize,
    pub(crate) nx: &'a [f32],
    pub(crate) ny: &'a [f32],
}

impl Dirs for TableDirs<'_> {
    type Ny<'b>
        = std::iter::Copied<std::slice::Iter<'b, f32>>
    where
        Self: 'b;
    #[inline(always)]
    fn span(&self, y: usize, x0: usize, x1: usize) -> (&[f32], Self::Ny<'_>) {
        let r = y * self.width;
        (
            &self.nx[r + x0..=r + x1],
            self.ny[r + x0..=r + x1].iter().copied(),
        )
    }
    #[inline(always)]
    fn dir(&self, x: usize, y: usize) -> [f32; 2] {
        let i = y * self.width + x;
        [self.nx[i], self.ny[i]]
    }
}
