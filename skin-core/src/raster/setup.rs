//! Per-vertex transform and per-triangle set-up: homogeneous edge functions, inverse-depth
//! plane and a conservative pixel bounding box.
//!
//! **Edge functions in ray space** (Olano & Greer 1997, "Triangle scan conversion using 2D
//! homogeneous coordinates"). With camera-frame corners `v₀, v₁, v₂` and a sample ray direction
//! `r = (nx, ny, 1)`, write `e₀ = v₁×v₂, e₁ = v₂×v₀, e₂ = v₀×v₁` and `det = v₀·(v₁×v₂)`. Then
//! `r = Σ λₖ vₖ` with `λₖ = r·eₖ / det`, so the ray meets the triangle in front of the camera
//! iff every `λₖ ≥ 0`; the hit is `r·det/Σ(r·eₖ)`, its camera z is `det / Σ(r·eₖ)` (so the
//! inverse depth `1/z` is linear in `(nx, ny)`) and `λₖ/Σλ` are its perspective-correct
//! barycentrics. No clipping is needed: triangles crossing the camera plane are handled
//! exactly, and because `r` is the exact undistorted direction of each pixel the test is exact
//! under radial distortion too (straight edges stay straight in ray space).
//!
//! **Fill rule.** A shared edge has exactly negated coefficients in its two triangles
//! (`a×b = −(b×a)` holds in floating point), so a sample strictly inside one is strictly
//! outside the other. Ties (`r·e = 0` exactly) go to the triangle for which the oriented edge
//! coefficients `(eₓ, e_y, e_z)` are lexicographically positive — the ray-space form of the
//! top-left rule — so adjacent triangles neither overlap nor leave cracks.

use rayon::prelude::*;

use crate::camera::{Camera, MIN_DEPTH_M};
use crate::math::{DVec2, DVec3};
use crate::mesh::TriMesh;

/// Camera-frame positions and (optional) projected pixels of the mesh vertices.
pub(crate) struct VertexSetup {
    /// Camera-frame positions, m.
    pub(crate) pos: Vec<DVec3>,
    /// Observed (distorted) and undistorted pixels, or `None` behind the camera or beyond the
    /// fold of a barrel model.
    pub(crate) pix: Vec<Option<(DVec2, DVec2)>>,
}

impl VertexSetup {
    pub(crate) fn new(camera: &Camera, mesh: &TriMesh) -> Self {
        let cfw = camera.camera_from_world();
        let k = camera.intrinsics;
        let d = camera.distortion;
        let (pos, pix) = mesh
            .vertices
            .par_iter()
            .map(|&p| {
                let c = cfw.transform_point3(p);
                let pix = (c.z > MIN_DEPTH_M)
                    .then(|| k.pixel_from_normalized(DVec2::new(c.x / c.z, c.y / c.z)))
                    .and_then(|u| Some((d.distort(&k, u)?, u)));
                (c, pix)
            })
            .unzip();
        Self { pos, pix }
    }
}

/// A triangle ready for scan conversion.
#[derive(Debug, Clone, Copy)]
pub(crate) struct TriSetup {
    /// Oriented edge coefficients: the sample `(nx, ny)` is inside iff each
    /// `e[k][0]·nx + e[k][1]·ny + e[k][2]` is `> 0`, or `= 0` with `top_left[k]`.
    pub(crate) e: [[f32; 3]; 3],
    /// Tie-break flags of the fill rule.
    pub(crate) top_left: [bool; 3],
    /// Inverse camera depth `1/z = w[0]·nx + w[1]·ny + w[2]`, 1/m.
    pub(crate) w: [f32; 3],
    /// Inclusive pixel bounding box, clamped to the image.
    pub(crate) x0: u32,
    pub(crate) x1: u32,
    pub(crate) y0: u32,
    pub(crate) y1: u32,
}

fn to_f32(v: DVec3) -> [f32; 3] {
    [v.x as f32, v.y as f32, v.z as f32]
}

/// Lexicographic positivity: the tie-break of the fill rule.
fn lex_positive(e: [f32; 3]) -> bool {
    e[0] > 0.0 || (e[0] == 0.0 && (e[1] > 0.0 || (e[1] == 0.0 && e[2] > 0.0)))
}

/// Safety margin (px) added to every projected bounding box: covers rounding of the f64
/// projection against the f32 edge test.
const BBOX_MARGIN_PX: f64 = 1.0;

/// Pixel bounding box `(x0, x1, y0, y1)` (inclusive, clamped) of the observed image of a
/// triangle whose corners all project, or `None` if it misses the image.
///
/// With distortion the image of a straight edge is a curve; it deviates from its chord by at
/// most `L²/8 · max‖D''‖ ≤ L²/8 · 6|k1| R / f_min²` (L the undistorted edge length, R the
/// largest undistorted distance of its end points from the distortion centre, f_min the smaller
/// focal length; `D(x) = x + k1 x (xᵀWx)`, `W = diag(fx⁻², fy⁻²)` gives
/// `‖D''[v,v]‖ ≤ 6|k1|‖x‖‖v‖²/f_min²`), so widening the box of the distorted corners by that
/// bound keeps it conservative.
fn pixel_bbox(camera: &Camera, p: [(DVec2, DVec2); 3]) -> Option<(u32, u32, u32, u32)> {
    let k = camera.intrinsics;
    let mut margin = BBOX_MARGIN_PX;
    if camera.distortion.k1 != 0.0 {
        let c = camera.distortion.centre;
        let r = p.iter().map(|q| (q.1 - c).length()).fold(0.0, f64::max);
        let l = (0..3)
            .map(|i| (p[i].1 - p[(i + 1) % 3].1).length())
            .fold(0.0, f64::max);
        let f_min = k.fx.min(k.fy);
        margin += l * l / 8.0 * 6.0 * camera.distortion.k1.abs() * r / (f_min * f_min);
    }
    let lo = p[0].0.min(p[1].0).min(p[2].0) - DVec2::splat(margin);
    let hi = p[0].0.max(p[1].0).max(p[2].0) + DVec2::splat(margin);
    full_or_clamped(k.width, k.height, lo, hi)
}

fn full_or_clamped(w: u32, h: u32, lo: DVec2, hi: DVec2) -> Option<(u32, u32, u32, u32)> {
    let (wf, hf) = (w as f64 - 1.0, h as f64 - 1.0);
    let x0 = lo.x.ceil().max(0.0);
    let y0 = lo.y.ceil().max(0.0);
    let x1 = hi.x.floor().min(wf);
    let y1 = hi.y.floor().min(hf);
    // NaN-safe: a NaN bound fails every comparison and drops the triangle only if both are NaN;
    // corners are finite here by construction of `VertexSetup`.
    if !(x0 <= x1 && y0 <= y1) {
        return None;
    }
    Some((x0 as u32, x1 as u32, y0 as u32, y1 as u32))
}

/// The set-up of every face, indexed by face: `None` for a face that cannot cover a pixel
/// (behind the camera, degenerate, culled or outside the image).
///
/// Indexed by face rather than compacted: a merged studio mesh has over a million faces, and
/// a compacted copy doubles the set-up's fresh memory (about 70 bytes a face), whose page
/// faults and copy cost more than the scan conversion of a 512² view (measured with the
/// parallel binning on the `raster` bench, 1.2 M faces: 300 → 135 ms a depth render).
pub(crate) fn setup_triangles(
    camera: &Camera,
    mesh: &TriMesh,
    verts: &VertexSetup,
    cull_back_faces: bool,
) -> Vec<Option<TriSetup>> {
    let (w, h) = (camera.intrinsics.width, camera.intrinsics.height);
    mesh.faces
        .par_iter()
        .map(|&[a, b, c]| {
            let idx = [a as usize, b as usize, c as usize];
            let v = idx.map(|i| verts.pos[i]);
            if v.iter().all(|p| p.z <= 0.0) {
                return None;
            }
            // Edge planes in f64 (no cancellation for small distant triangles), then rounded:
            // rounding is symmetric, so a shared edge keeps exactly negated coefficients.
            let e = [v[1].cross(v[2]), v[2].cross(v[0]), v[0].cross(v[1])];
            let normal = (v[1] - v[0]).cross(v[2] - v[0]);
            let det = normal.dot(v[0]);
            if det == 0.0 || !det.is_finite() || normal == DVec3::ZERO {
                return None;
            }
            // Front-facing (outward normal towards the camera) iff det < 0; see module docs.
            if cull_back_faces && det > 0.0 {
                return None;
            }
            let s = det.signum();
            let e = e.map(|ek| to_f32(ek * s));
            // 1/z = n·r / (n·v₀): the plane of the triangle seen along r = (nx, ny, 1).
            let wsum = to_f32(normal / det);
            if !(e.iter().flatten().all(|x| x.is_finite()) && wsum.iter().all(|x| x.is_finite())) {
                return None;
            }
            let pix = [verts.pix[idx[0]], verts.pix[idx[1]], verts.pix[idx[2]]];
            let bbox = match pix {
                [Some(p0), Some(p1), Some(p2)] => pixel_bbox(camera, [p0, p1, p2])?,
                // A corner behind the camera or beyond a barrel fold: its image is unbounded or
                // not given by the corners; test every pixel (rare, exact).
                _ => (0, w - 1, 0, h - 1),
            };
            Some(TriSetup {
                e,
                top_left: e.map(lex_positive),
                w: wsum,
                x0: bbox.0,
                x1: bbox.1,
                y0: bbox.2,
                y1: bbox.3,
            })
        })
        .collect()
}

/// Camera-frame unit normal of a face (outward for counter-clockwise faces), zero if degenerate.
pub(crate) fn face_normal(v: [DVec3; 3]) -> [f32; 3] {
    to_f32((v[1] - v[0]).cross(v[2] - v[0]).normalize_or_zero())
}

/// Area-weighted vertex normals of the mesh in the camera frame (unit, or zero for vertices
/// without a non-degenerate face).
pub(crate) fn vertex_normals_camera(camera: &Camera, mesh: &TriMesh) -> Vec<[f32; 3]> {
    let mut acc = vec![DVec3::ZERO; mesh.vertices.len()];
    for &[a, b, c] in &mesh.faces {
        let (pa, pb, pc) = (
            mesh.vertices[a as usize],
            mesh.vertices[b as usize],
            mesh.vertices[c as usize],
        );
        let n = (pb - pa).cross(pc - pa);
        acc[a as usize] += n;
        acc[b as usize] += n;
        acc[c as usize] += n;
    }
    let rot = camera.camera_from_world();
    acc.into_iter()
        .map(|n| to_f32(rot.transform_vector3(n).normalize_or_zero()))
        .collect()
}
