//! Preview pictures: front views of meshes side by side, rendered by the studio
//! [`Rasterizer`] and shaded with a headlight (Lambert on the camera-space normal), each
//! panel painted in one colour or with per-vertex colours (e.g. an error map).
//!
//! All panels share one nearly orthographic camera (a long lens far away on the +z axis,
//! framing the union of the meshes' bounding boxes), so sizes and positions compare across
//! panels. For looking at results by eye, not for measurement.

use glam::DVec3;
use image::{Rgb, RgbImage};

use skin_core::camera::{Camera, Intrinsics};
use skin_core::mesh::TriMesh;
use skin_core::raster::{Buffers, Rasterizer, RenderParams, NO_TRIANGLE};
use skin_core::{Error, Result};

/// How a panel is coloured.
#[derive(Debug, Clone, Copy)]
pub enum Paint<'a> {
    /// One colour for the whole mesh.
    Flat([u8; 3]),
    /// One colour per vertex, interpolated over each face.
    PerVertex(&'a [[u8; 3]]),
}

/// One panel of a [`preview`].
#[derive(Debug, Clone, Copy)]
pub struct PreviewPanel<'a> {
    /// The mesh (closed or not; back faces are culled).
    pub mesh: &'a TriMesh,
    /// Its colours.
    pub paint: Paint<'a>,
}

/// Front views of `panels` side by side, each `size × size` pixels, on white: rendered by
/// the [`Rasterizer`] and shaded with a headlight (Lambert on the camera-space normal), each
/// panel painted in one colour or with per-vertex colours (e.g. an error map).
///
/// All panels share one nearly orthographic camera (a long lens far away on the +z axis,
/// framing the union of the meshes' bounding boxes), so sizes and positions compare across
/// panels. For looking at results by eye, not for measurement.
///
/// # Errors
/// [`Error::Empty`] for no panels or a mesh without vertices; [`Error::InvalidParam`] for
/// `size < 2`; [`Error::SizeMismatch`] for per-vertex colours of the wrong length;
/// [`Error::NonFinite`] for NaN/∞ vertices; the rasteriser's errors (degenerate mesh).
pub fn preview(panels: &[PreviewPanel<'_>], size: u32) -> Result<RgbImage> {
    if panels.is_empty() {
        return Err(Error::Empty {
            what: "preview panels",
        });
    }
    if size < 2 {
        return Err(Error::InvalidParam {
            name: "size",
            reason: format!("must be at least 2 pixels, got {size}"),
        });
    }
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    for p in panels {
        if p.mesh.vertices.is_empty() {
            return Err(Error::Empty {
                what: "preview mesh vertices",
            });
        }
        if let Paint::PerVertex(c) = p.paint {
            if c.len() != p.mesh.vertices.len() {
                return Err(Error::SizeMismatch {
                    what: "preview vertex colours vs vertices",
                    expected: p.mesh.vertices.len(),
                    got: c.len(),
                });
            }
        }
        for v in &p.mesh.vertices {
            if !v.is_finite() {
                return Err(Error::NonFinite {
                    what: "preview mesh vertices",
                });
            }
            lo = lo.min(*v);
            hi = hi.max(*v);
        }
    }
    let extent = ((hi - lo).x.max((hi - lo).y) * 1.1).max(1e-6);
    let centre = (lo + hi) * 0.5;
    // A long lens far away: nearly orthographic, every mesh in view.
    let distance = 10.0 * extent;
    let focal_px = size as f64 * distance / extent;
    let half = (size as f64 - 1.0) / 2.0;
    let intrinsics = Intrinsics::new(focal_px, focal_px, half, half, size, size)?;
    let eye = centre + DVec3::Z * (distance + (hi.z - centre.z));
    let camera = Camera::look_at(intrinsics, eye, centre, DVec3::Y)?;
    let rasterizer = Rasterizer::new(&camera);
    let params = RenderParams::default()
        .with_buffers(Buffers {
            triangle: true,
            ..Buffers::default()
        })
        .with_allow_empty(true);
    let mut img = RgbImage::from_pixel(size * panels.len() as u32, size, Rgb([255, 255, 255]));
    for (i, p) in panels.iter().enumerate() {
        let view = rasterizer.render(p.mesh, &params)?;
        for y in 0..size {
            for x in 0..size {
                let k = view.index(x, y);
                let face = view.triangle[k];
                if view.mask[k] == 0 || face == NO_TRIANGLE {
                    continue;
                }
                let colour = match p.paint {
                    Paint::Flat(c) => c.map(f64::from),
                    Paint::PerVertex(c) => {
                        let f = p.mesh.faces[face as usize];
                        let [b1, b2] = view.bary[k].map(f64::from);
                        let w = [1.0 - b1 - b2, b1, b2];
                        let mut out = [0.0; 3];
                        for (corner, wc) in f.iter().zip(w) {
                            for (o, v) in out.iter_mut().zip(c[*corner as usize]) {
                                *o += wc * f64::from(v);
                            }
                        }
                        out
                    }
                };
                let n = view.normal_camera[k];
                let shade = 0.25 + 0.75 * f64::from(-n[2]).max(0.0);
                let c = colour.map(|c| (c * shade).clamp(0.0, 255.0) as u8);
                img.put_pixel(x + i as u32 * size, y, Rgb(c));
            }
        }
    }
    Ok(img)
}

#[cfg(test)]
mod tests {
    use super::*;
    use skin_core::mesh::shapes;

    #[test]
    fn panels_are_painted_side_by_side() {
        let s = shapes::icosphere(2).unwrap();
        let colours = vec![[0u8, 0, 255]; s.vertices.len()];
        let img = preview(
            &[
                PreviewPanel {
                    mesh: &s,
                    paint: Paint::Flat([255, 0, 0]),
                },
                PreviewPanel {
                    mesh: &s,
                    paint: Paint::PerVertex(&colours),
                },
            ],
            64,
        )
        .unwrap();
        assert_eq!((img.width(), img.height()), (128, 64));
        // Centre of each panel: lit, in the panel's colour.
        let a = img.get_pixel(32, 32).0;
        let b = img.get_pixel(96, 32).0;
        assert!(a[0] > 200 && a[1] == 0 && a[2] == 0, "{a:?}");
        assert!(b[2] > 200 && b[0] == 0 && b[1] == 0, "{b:?}");
        // Corners stay white.
        assert_eq!(img.get_pixel(0, 0).0, [255, 255, 255]);
    }

    #[test]
    fn bad_input_is_refused() {
        let s = shapes::icosphere(1).unwrap();
        assert!(matches!(preview(&[], 64), Err(Error::Empty { .. })));
        let flat = PreviewPanel {
            mesh: &s,
            paint: Paint::Flat([0, 0, 0]),
        };
        assert!(matches!(
            preview(&[flat], 1),
            Err(Error::InvalidParam { .. })
        ));
        let few = [[0u8; 3]; 3];
        let wrong = PreviewPanel {
            mesh: &s,
            paint: Paint::PerVertex(&few),
        };
        assert!(matches!(
            preview(&[wrong], 64),
            Err(Error::SizeMismatch { .. })
        ));
        let mut nan = s.clone();
        nan.vertices[0].y = f64::NAN;
        let bad = PreviewPanel {
            mesh: &nan,
            paint: Paint::Flat([0, 0, 0]),
        };
        assert!(matches!(preview(&[bad], 64), Err(Error::NonFinite { .. })));
    }
}
