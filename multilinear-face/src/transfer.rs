//! Face transfer into video (§5.4, Figures 5-1 and 5-7): the target's texture lifted from its
//! frame onto the tracked geometry, and a face of new geometry rendered with that texture
//! back into the frame.
//!
//! **Rendering a weak-perspective camera.** skin-core's rasteriser is a pinhole; a
//! weak-perspective camera `p = s R₂ f + t` is rendered by a pinhole of focal length `s D`
//! looking along `+z` at the face placed at depth `D = 5,000` model units (≈ 50 m for a face
//! in cm): `f` goes to `R′f + ((t − c)/s, D)` with `R′ = [r₀; r₁; r₀ × r₁]` (image `y` down, so
//! `R′` is the rotation whose first two rows are the camera's). The face's depth range
//! (≈ 10 units) changes the projection by ≈ 0.2 %, below 0.3 px for a face 300 px wide.
//!
//! **Texture.** One colour per vertex, sampled (bilinearly) from the frame at the vertex's
//! projection where the vertex is visible (its depth agrees with the rendered depth at its
//! pixel); invisible vertices get their visible neighbours' mean (repeated along the mesh),
//! so a turned-away cheek still has a colour when new geometry shows it. The colours are what
//! the camera saw, shading included (as the thesis's lifted texture).

use image::{Rgb, RgbImage};
use skin_core::camera::{Camera, Intrinsics, RadialDistortion};
use skin_core::math::{DAffine3, DMat3, DVec3};
use skin_core::mesh::TriMesh;
use skin_core::raster::{Buffers, Rasterizer, RenderParams, RenderedView, NO_TRIANGLE};

use crate::tracking::WeakPerspective;
use crate::{Error, Result};

/// Depth of the face in front of the equivalent pinhole, model units.
const DEPTH: f64 = 5000.0;

/// A face's colours lifted from a frame ([`lift_texture`]).
#[derive(Clone, Debug, PartialEq)]
pub struct FaceTexture {
    /// One RGB colour per vertex (8-bit scale, `0..=255`).
    pub colours: Vec<[f32; 3]>,
    /// Whether the vertex was visible in the frame (the others are filled from neighbours).
    pub visible: Vec<bool>,
}

/// The rasterised view of `face` (model units) under the weak-perspective `cam` in a
/// `width × height` frame: every buffer on, back faces kept (the face mesh is open), the mesh
/// in the pinhole's world frame returned with it.
pub(crate) fn render_view(
    face: &[DVec3],
    triangles: &[[u32; 3]],
    cam: &WeakPerspective,
    width: u32,
    height: u32,
) -> Result<(RenderedView, TriMesh)> {
    skin_core::check::positive("camera scale", cam.scale)?;
    let (cx, cy) = (0.5 * f64::from(width) - 0.5, 0.5 * f64::from(height) - 0.5);
    let focal = cam.scale * DEPTH;
    let k = Intrinsics::new(focal, focal, cx, cy, width, height)?;
    let camera = Camera::new(k, RadialDistortion::NONE, DAffine3::IDENTITY)?;
    let r0 = DVec3::from_array(cam.rows[0]);
    let r1 = DVec3::from_array(cam.rows[1]);
    let rot = DMat3::from_cols(r0, r1, r0.cross(r1)).transpose();
    let offset = DVec3::new(
        (cam.translation[0] - cx) / cam.scale,
        (cam.translation[1] - cy) / cam.scale,
        DEPTH,
    );
    let mesh = TriMesh::new(
        face.iter().map(|&f| rot * f + offset).collect(),
        triangles.to_vec(),
    )?;
    let params = RenderParams::default()
        .with_buffers(Buffers::ALL)
        .with_cull_back_faces(false)
        .with_allow_empty(true);
    let view = Rasterizer::new(&camera).render(&mesh, &params)?;
    Ok((view, mesh))
}

fn bilinear(frame: &RgbImage, x: f64, y: f64) -> Option<[f32; 3]> {
    let (w, h) = (f64::from(frame.width()), f64::from(frame.height()));
    if !(x >= 0.0 && y >= 0.0 && x < w - 1.0 && y < h - 1.0) {
        return None;
    }
    let (x0, y0) = (x as u32, y as u32);
    let (fx, fy) = ((x - f64::from(x0)) as f32, (y - f64::from(y0)) as f32);
    let px = |dx, dy| frame.get_pixel(x0 + dx, y0 + dy).0.map(f32::from);
    let (a, b, c, d) = (px(0, 0), px(1, 0), px(0, 1), px(1, 1));
    Some(std::array::from_fn(|i| {
        let top = a[i] + fx * (b[i] - a[i]);
        let bot = c[i] + fx * (d[i] - c[i]);
        top + fy * (bot - top)
    }))
}

/// Lifts the colours of `face` (the tracked geometry, model units, with its `triangles`) seen
/// by `cam` in `frame` (module docs).
///
/// # Errors
/// [`Error::Empty`] for no visible vertex; errors of the rasteriser (an invalid mesh, a
/// triangle corner past the face) and [`Error::InvalidParam`] for a camera scale ≤ 0.
pub fn lift_texture(
    face: &[DVec3],
    triangles: &[[u32; 3]],
    cam: &WeakPerspective,
    frame: &RgbImage,
) -> Result<FaceTexture> {
    let (w, h) = frame.dimensions();
    let (view, mesh) = render_view(face, triangles, cam, w, h)?;
    let n = face.len();
    let mut colours = vec![[0.0f32; 3]; n];
    let mut visible = vec![false; n];
    for (v, x) in mesh.vertices.iter().enumerate() {
        let p = cam.project(face[v].to_array());
        let (px, py) = (p[0].round(), p[1].round());
        if px < 0.0 || py < 0.0 || px >= f64::from(w) || py >= f64::from(h) {
            continue;
        }
        let i = view.index(px as u32, py as u32);
        // Visible when nothing lies in front of it (depth tolerance 0.3 model units).
        if view.triangle[i] != NO_TRIANGLE && f64::from(view.camera_z_m[i]) > x.z - 0.3 {
            if let Some(c) = bilinear(frame, p[0], p[1]) {
                colours[v] = c;
                visible[v] = true;
            }
        }
    }
    if !visible.iter().any(|&v| v) {
        return Err(Error::Empty {
            what: "visible face vertices to lift a texture from",
        });
    }
    // Fill the invisible vertices from their neighbours, ring by ring.
    let mut known = visible.clone();
    for _ in 0..200 {
        let mut sum = vec![([0.0f32; 3], 0u32); n];
        for t in triangles {
            for a in 0..3 {
                let (u, v) = (t[a] as usize, t[(a + 1) % 3] as usize);
                for (i, j) in [(u, v), (v, u)] {
                    if !known[i] && known[j] {
                        for (acc, c) in sum[i].0.iter_mut().zip(colours[j]) {
                            *acc += c;
                        }
                        sum[i].1 += 1;
                    }
                }
            }
        }
        let mut changed = false;
        for (v, (s, k)) in sum.into_iter().enumerate() {
            if k > 0 {
                colours[v] = s.map(|c| c / k as f32);
                known[v] = true;
                changed = true;
            }
        }
        if !changed {
            break;
        }
    }
    Ok(FaceTexture { colours, visible })
}

/// Renders `face` (new geometry, in correspondence with the texture's) under `cam` with the
/// lifted `texture` (colours interpolated by the barycentrics) over `background` (the target
/// frame): the composited frame of a face transfer.
///
/// # Errors
/// [`Error::SizeMismatch`] for a texture with another vertex count; errors of the rasteriser
/// and [`Error::InvalidParam`] for a camera scale ≤ 0.
pub fn render_textured(
    face: &[DVec3],
    triangles: &[[u32; 3]],
    cam: &WeakPerspective,
    texture: &FaceTexture,
    background: &RgbImage,
) -> Result<RgbImage> {
    skin_core::check::same_size(
        "texture colours (one per vertex)",
        face.len(),
        texture.colours.len(),
    )?;
    let (w, h) = background.dimensions();
    let (view, _) = render_view(face, triangles, cam, w, h)?;
    let mut out = background.clone();
    for (x, y, px) in out.enumerate_pixels_mut() {
        let i = view.index(x, y);
        let t = view.triangle[i];
        if t == NO_TRIANGLE {
            continue;
        }
        let tri = triangles[t as usize];
        let [b1, b2] = view.bary[i];
        let b = [1.0 - b1 - b2, b1, b2];
        let c: [f32; 3] = std::array::from_fn(|k| {
            (0..3)
                .map(|j| b[j] * texture.colours[tri[j] as usize][k])
                .sum()
        });
        *px = Rgb(c.map(|v| v.round().clamp(0.0, 255.0) as u8));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 21 × 21 grid in the x–y plane (model units) and a colour ramp over it.
    fn grid() -> (Vec<DVec3>, Vec<[u32; 3]>, Vec<[f32; 3]>) {
        let n = 21u32;
        let mut v = Vec::new();
        let mut c = Vec::new();
        for j in 0..n {
            for i in 0..n {
                v.push(DVec3::new(f64::from(i) - 10.0, f64::from(j) - 10.0, 0.0));
                c.push([10.0 * i as f32, 10.0 * j as f32, 100.0]);
            }
        }
        let mut t = Vec::new();
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let a = j * n + i;
                t.push([a, a + 1, a + n + 1]);
                t.push([a, a + n + 1, a + n]);
            }
        }
        (v, t, c)
    }

    #[test]
    fn lifted_colours_reproduce_a_rendered_texture() {
        let (v, t, c) = grid();
        let (co, si) = (0.3f64.cos(), 0.3f64.sin());
        let cam = WeakPerspective {
            scale: 5.0,
            rows: [[co, 0.0, si], [0.0, 1.0, 0.0]],
            translation: [80.0, 60.0],
        };
        let tex = FaceTexture {
            colours: c.clone(),
            visible: vec![true; v.len()],
        };
        let frame = render_textured(&v, &t, &cam, &tex, &RgbImage::new(160, 120)).unwrap();
        // The grid's centre is rendered with its interpolated colour.
        let centre = frame.get_pixel(80, 60).0;
        assert!((f32::from(centre[0]) - 100.0).abs() <= 6.0, "{centre:?}");
        let lifted = lift_texture(&v, &t, &cam, &frame).unwrap();
        let mut checked = 0;
        for (k, (a, b)) in lifted.colours.iter().zip(&c).enumerate() {
            // Interior vertices (a border vertex's bilinear sample mixes in the background).
            let (i, j) = (k % 21, k / 21);
            if lifted.visible[k] && (1..20).contains(&i) && (1..20).contains(&j) {
                checked += 1;
                for ch in 0..3 {
                    assert!((a[ch] - b[ch]).abs() <= 6.0, "vertex {k}: {a:?} vs {b:?}");
                }
            }
        }
        assert!(checked == 19 * 19, "{checked} visible vertices");
        // A texture of another size is an error.
        let short = FaceTexture {
            colours: c[..10].to_vec(),
            visible: vec![true; 10],
        };
        assert!(render_textured(&v, &t, &cam, &short, &frame).is_err());
    }
}
