//! Scan conversion in horizontal bands (one rayon task per band) and per-pixel resolve of the
//! requested buffers.
//!
//! Triangles are binned to bands of [`BAND_ROWS`] rows in face order ([`bin_triangles`]), so each
//! band sees its triangles in the same order whatever the thread count: output is identical for
//! any number of threads. Within a band the inner loop is an f32 edge-function test over the
//! triangle's bounding box with an inverse-depth (`1/z`) test; attributes are computed once per
//! pixel afterwards, for the winning triangle only.

use rayon::prelude::*;

use super::params::NormalMode;
use super::samples::Dirs;
use super::setup::{face_normal, TriSetup};
use super::view::NO_TRIANGLE;
use crate::math::DVec3;

/// Rows per band (one parallel task). 16 rows × 1600 px keeps the band's z and id buffers
/// (200 KB) in L2.
pub(crate) const BAND_ROWS: usize = 16;

/// Output slices of one band (each empty when its buffer is not requested).
pub(crate) struct BandOut<'a> {
    pub(crate) y0: usize,
    pub(crate) rows: usize,
    pub(crate) mask: &'a mut [u8],
    pub(crate) depth: &'a mut [f32],
    pub(crate) camera_z: &'a mut [f32],
    pub(crate) normal: &'a mut [[f32; 3]],
    pub(crate) triangle: &'a mut [u32],
    pub(crate) bary: &'a mut [[f32; 2]],
}

/// What the resolve step needs besides the triangle set-ups.
pub(crate) struct ResolveCtx<'a> {
    pub(crate) faces: &'a [[u32; 3]],
    pub(crate) pos: &'a [DVec3],
    /// Camera-frame vertex normals (smooth mode) or empty (flat mode).
    pub(crate) vertex_normals: &'a [[f32; 3]],
    pub(crate) normals: NormalMode,
}

/// Band bins: `order[start[b]..start[b+1]]` are the faces touching band `b`, in face order.
pub(crate) struct Bins {
    pub(crate) start: Vec<usize>,
    pub(crate) order: Vec<u32>,
}

/// Faces per task of [`bin_triangles`].
const BIN_CHUNK: usize = 1 << 16;

/// Bins the set-up faces to bands: each chunk of faces lists its faces per band in parallel,
/// then each band's lists are joined in chunk order, so every band holds its faces in face
/// order whatever the thread count (a serial counting sort gives the same bins; on a dense
/// mesh its two passes over every face were a serial part of each render).
pub(crate) fn bin_triangles(tris: &[Option<TriSetup>], n_bands: usize) -> Bins {
    let lists: Vec<Vec<Vec<u32>>> = tris
        .par_chunks(BIN_CHUNK)
        .enumerate()
        .map(|(ci, chunk)| {
            let mut per_band = vec![Vec::new(); n_bands];
            for (k, t) in chunk.iter().enumerate() {
                let Some(t) = t else { continue };
                let face = (ci * BIN_CHUNK + k) as u32;
                for list in &mut per_band[t.y0 as usize / BAND_ROWS..=t.y1 as usize / BAND_ROWS] {
                    list.push(face);
                }
            }
            per_band
        })
        .collect();
    let mut start = vec![0usize; n_bands + 1];
    for b in 0..n_bands {
        start[b + 1] = start[b] + lists.iter().map(|l| l[b].len()).sum::<usize>();
    }
    let mut order = vec![0u32; start[n_bands]];
    let mut bands = Vec::with_capacity(n_bands);
    let mut rest = order.as_mut_slice();
    for b in 0..n_bands {
        let (band, tail) = rest.split_at_mut(start[b + 1] - start[b]);
        bands.push(band);
        rest = tail;
    }
    bands.into_par_iter().enumerate().for_each(|(b, band)| {
        let mut at = 0;
        for l in &lists {
            band[at..at + l[b].len()].copy_from_slice(&l[b]);
            at += l[b].len();
        }
    });
    Bins { start, order }
}

#[inline(always)]
fn edge(e: &[f32; 3], d: [f32; 2]) -> f32 {
    e[0] * d[0] + e[1] * d[1] + e[2]
}

/// Branch-free coverage test (fill rule in the module docs of `setup`).
#[inline(always)]
fn inside(t: &TriSetup, d: [f32; 2]) -> bool {
    let v0 = edge(&t.e[0], d);
    let v1 = edge(&t.e[1], d);
    let v2 = edge(&t.e[2], d);
    ((v0 > 0.0) | ((v0 == 0.0) & t.top_left[0]))
        & ((v1 > 0.0) | ((v1 == 0.0) & t.top_left[1]))
        & ((v2 > 0.0) | ((v2 == 0.0) & t.top_left[2]))
}

/// Per-worker scratch: inverse depth and winning face per band pixel.
pub(crate) struct Scratch {
    w: Vec<f32>,
    id: Vec<u32>,
}

impl Scratch {
    pub(crate) fn new(len: usize) -> Self {
        Self {
            w: vec![0.0; len],
            id: vec![NO_TRIANGLE; len],
        }
    }
}

/// Silhouette-only band: no depth test. Returns the covered pixel count.
pub(crate) fn mask_band<D: Dirs>(
    dirs: &D,
    width: usize,
    tris: &[Option<TriSetup>],
    ids: &[u32],
    out: &mut BandOut<'_>,
) -> usize {
    let rows = out.rows;
    out.mask.fill(0);
    let (y0, y1) = (out.y0, out.y0 + rows - 1);
    for &i in ids {
        let Some(t) = &tris[i as usize] else { continue };
        let (x0, x1) = (t.x0 as usize, t.x1 as usize);
        for y in (t.y0 as usize).max(y0)..=(t.y1 as usize).min(y1) {
            let base = (y - y0) * width;
            let row = &mut out.mask[base + x0..=base + x1];
            let (nxs, nys) = dirs.span(y, x0, x1);
            for ((m, &nx), ny) in row.iter_mut().zip(nxs).zip(nys) {
                *m |= inside(t, [nx, ny]) as u8;
            }
        }
    }
    out.mask.iter().filter(|&&m| m != 0).count()
}

/// Full band: depth-tested scan conversion, then resolve of every requested buffer. Returns
/// the covered pixel count.
pub(crate) fn full_band<D: Dirs>(
    dirs: &D,
    width: usize,
    tris: &[Option<TriSetup>],
    ids: &[u32],
    ctx: &ResolveCtx<'_>,
    scratch: &mut Scratch,
    out: &mut BandOut<'_>,
) -> usize {
    let rows = out.rows;
    let n = rows * width;
    let (zb, idb) = (&mut scratch.w[..n], &mut scratch.id[..n]);
    zb.fill(0.0);
    idb.fill(NO_TRIANGLE);
    let (y0, y1) = (out.y0, out.y0 + rows - 1);
    for &i in ids {
        let Some(t) = &tris[i as usize] else { continue };
        let (x0, x1) = (t.x0 as usize, t.x1 as usize);
        for y in (t.y0 as usize).max(y0)..=(t.y1 as usize).min(y1) {
            let base = (y - y0) * width;
            let (nxs, nys) = dirs.span(y, x0, x1);
            let zrow = &mut zb[base + x0..=base + x1];
            let irow = &mut idb[base + x0..=base + x1];
            for (((z, id), &nx), ny) in zrow.iter_mut().zip(irow.iter_mut()).zip(nxs).zip(nys) {
                let d = [nx, ny];
                let w = edge(&t.w, d);
                let win = inside(t, d) & (w > *z);
                *z = if win { w } else { *z };
                *id = if win { i } else { *id };
            }
        }
    }
    fill_background(out);
    let mut cache = FaceCache::new();
    let mut covered = 0;
    for yy in 0..rows {
        let y = y0 + yy;
        for x in 0..width {
            let j = yy * width + x;
            let face = idb[j];
            if face == NO_TRIANGLE {
                continue;
            }
            covered += 1;
            let d = dirs.dir(x, y);
            let (lam, z) = cache.resolve(ctx, face, d, zb[j]);
            if !out.mask.is_empty() {
                out.mask[j] = 1;
            }
            if !out.depth.is_empty() {
                out.depth[j] = z * (d[0] * d[0] + d[1] * d[1] + 1.0).sqrt();
            }
            if !out.camera_z.is_empty() {
                out.camera_z[j] = z;
            }
            if !out.triangle.is_empty() {
                out.triangle[j] = face;
                out.bary[j] = [lam[1], lam[2]];
            }
            if !out.normal.is_empty() {
                out.normal[j] = pixel_normal(ctx, face, lam);
            }
        }
    }
    covered
}

/// The f64 quantities of one face that [`FaceCache::resolve`] needs, cached across the run of
/// pixels that see the same face.
pub(crate) struct FaceCache {
    face: u32,
    /// `v₁×v₂, v₂×v₀, v₀×v₁` (camera frame).
    e: [DVec3; 3],
    /// `((v₁−v₀)×(v₂−v₀))·v₀`.
    det: f64,
}

impl FaceCache {
    pub(crate) fn new() -> Self {
        Self {
            face: NO_TRIANGLE,
            e: [DVec3::ZERO; 3],
            det: 0.0,
        }
    }

    /// Perspective-correct barycentrics and camera z of the hit of ray `(nx, ny, 1)` with
    /// `face`, recomputed in f64 from the camera-frame corners (the f32 edge values of the
    /// coverage test lose relative precision near a grazing silhouette). `w32` is the f32
    /// inverse depth of the z-test, used only if the f64 solve degenerates.
    fn resolve(
        &mut self,
        ctx: &ResolveCtx<'_>,
        face: u32,
        d: [f32; 2],
        w32: f32,
    ) -> ([f32; 3], f32) {
        if face != self.face {
            let [a, b, c] = ctx.faces[face as usize].map(|i| ctx.pos[i as usize]);
            self.face = face;
            self.e = [b.cross(c), c.cross(a), a.cross(b)];
            self.det = (b - a).cross(c - a).dot(a);
        }
        let r = DVec3::new(d[0] as f64, d[1] as f64, 1.0);
        let ev = self.e.map(|e| r.dot(e));
        let sum = ev[0] + ev[1] + ev[2];
        let z = self.det / sum;
        if !(z.is_finite() && z > 0.0) {
            return ([1.0 / 3.0; 3], 1.0 / w32);
        }
        (ev.map(|v| (v / sum).max(0.0) as f32), z as f32)
    }
}

/// Sets every requested buffer of the band to its background value (empty slices are no-ops).
fn fill_background(out: &mut BandOut<'_>) {
    out.mask.fill(0);
    out.depth.fill(f32::INFINITY);
    out.camera_z.fill(f32::INFINITY);
    out.triangle.fill(NO_TRIANGLE);
    // Flattened so the zero fills compile to memset.
    out.bary.as_flattened_mut().fill(0.0);
    out.normal.as_flattened_mut().fill(0.0);
}

fn pixel_normal(ctx: &ResolveCtx<'_>, face: u32, lam: [f32; 3]) -> [f32; 3] {
    let [a, b, c] = ctx.faces[face as usize].map(|i| i as usize);
    if ctx.normals == NormalMode::Smooth {
        let n = [
            ctx.vertex_normals[a],
            ctx.vertex_normals[b],
            ctx.vertex_normals[c],
        ];
        let mut s = [0.0f32; 3];
        for k in 0..3 {
            s[k] = lam[0] * n[0][k] + lam[1] * n[1][k] + lam[2] * n[2][k];
        }
        let len = (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt();
        if len > 1e-6 {
            return s.map(|v| v / len);
        }
    }
    face_normal([ctx.pos[a], ctx.pos[b], ctx.pos[c]])
}

/// Splits the requested output buffers of `view` into bands (empty buffers give empty
/// slices).
pub(crate) fn split_bands<'a>(
    width: usize,
    height: usize,
    view: &'a mut super::view::RenderedView,
) -> Vec<BandOut<'a>> {
    let chunk = BAND_ROWS * width;
    let n_bands = height.div_ceil(BAND_ROWS);
    fn parts<T>(s: &mut [T], chunk: usize, n: usize) -> Vec<&mut [T]> {
        if s.is_empty() {
            (0..n).map(|_| <&mut [T]>::default()).collect()
        } else {
            s.chunks_mut(chunk).collect()
        }
    }
    let mut m = parts(&mut view.mask, chunk, n_bands).into_iter();
    let mut d = parts(&mut view.depth_m, chunk, n_bands).into_iter();
    let mut z = parts(&mut view.camera_z_m, chunk, n_bands).into_iter();
    let mut nn = parts(&mut view.normal_camera, chunk, n_bands).into_iter();
    let mut t = parts(&mut view.triangle, chunk, n_bands).into_iter();
    let mut b = parts(&mut view.bary, chunk, n_bands).into_iter();
    (0..n_bands)
        .map(|i| BandOut {
            y0: i * BAND_ROWS,
            rows: BAND_ROWS.min(height - i * BAND_ROWS),
            // Each iterator has exactly n_bands items (chunks of a width*height buffer, or
            // n_bands empties), so `next` cannot run out; default to empty regardless.
            mask: m.next().unwrap_or_default(),
            depth: d.next().unwrap_or_default(),
            camera_z: z.next().unwrap_or_default(),
            normal: nn.next().unwrap_or_default(),
            triangle: t.next().unwrap_or_default(),
            bary: b.next().unwrap_or_default(),
        })
        .collect()
}

/// Runs `f` on every band in parallel with a per-worker scratch; returns the summed coverage.
pub(crate) fn par_bands<F>(bands: Vec<BandOut<'_>>, scratch_len: usize, f: F) -> usize
where
    F: Fn(&mut Scratch, &mut BandOut<'_>) -> usize + Sync + Send,
{
    bands
        .into_par_iter()
        .map_init(|| Scratch::new(scratch_len), |s, mut band| f(s, &mut band))
        .sum()
}
