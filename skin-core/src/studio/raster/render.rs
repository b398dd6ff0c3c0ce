//! Scan conversion in horizontal bands (one rayon task per band) and per-pixel resolve of the
//! requested buffers.
//!
//! Triangles are binned to bands of [`BAND_ROWS`] rows in face order (a counting sort), so each
//! band sees its triangles in the same order whatever the thread count: output is identical for
//! any number of threads. Within a band the inner loop is an f32 edge-function test over the
//! triangle's bounding box with an inverse-depth (`1/z`) test; attributes are computed once per
//! pixel afterwards, for the winning triangle only.

use rayon::prelude::*;

use super::params::NormalMode;
use super::samples::Dirs;
use super::setup::{face_normal, TriSetup};
use super::view::NO_TRIANGLE;

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
    pub(crate) pos: &'a [crate::math::DVec3],
    /// Camera-frame vertex normals (smooth mode) or empty (flat mode).
    pub(crate) vertex_normals: &'a [[f32; 3]],
    pub(crate) normals: NormalMode,
}

/// Band bins: `order[start[b]..start[b+1]]` are the set-up indices touching band `b`, in face
/// order.
pub(crate) struct Bins {
    pub(crate) start: Vec<usize>,
    pub(crate) order: Vec<u32>,
}

pub(crate) fn bin_triangles(tris: &[TriSetup], n_bands: usize) -> Bins {
    let mut count = vec![0usize; n_bands + 1];
    for t in tris {
        for b in t.y0 as usize / BAND_ROWS..=t.y1 as usize / BAND_ROWS {
            count[b + 1] += 1;
        }
    }
    for b in 0..n_bands {
        count[b + 1] += count[b];
    }
    let mut fill = count.clone();
    let mut order = vec![0u32; count[n_bands]];
    for (i, t) in tris.iter().enumerate() {
        for b in t.y0 as usize / BAND_ROWS..=t.y1 as usize / BAND_ROWS {
            order[fill[b]] = i as u32;
            fill[b] += 1;
        }
    }
    Bins {
        start: count,
        order,
    }
}

#[inline(always)]
fn edge(e: &[f32; 3], d: [f32; 2]) -> f32 {
    e[0] * d[0] + e[1] * d[1] + e[2]
}

#[inline(always)]
fn inside(t: &TriSetup, d: [f32; 2]) -> bool {
    let mut ok = true;
    for k in 0..3 {
        let v = edge(&t.e[k], d);
        ok &= v > 0.0 || (v == 0.0 && t.top_left[k]);
    }
    ok
}

/// Per-worker scratch: inverse depth and winning set-up index per band pixel.
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
    tris: &[TriSetup],
    ids: &[u32],
    out: &mut BandOut<'_>,
) -> usize {
    let rows = out.rows;
    out.mask.fill(0);
    let (y0, y1) = (out.y0, out.y0 + rows - 1);
    for &i in ids {
        let t = &tris[i as usize];
        for y in (t.y0 as usize).max(y0)..=(t.y1 as usize).min(y1) {
            let row = &mut out.mask[(y - y0) * width..(y - y0 + 1) * width];
            for x in t.x0 as usize..=t.x1 as usize {
                if inside(t, dirs.dir(x, y)) {
                    row[x] = 1;
                }
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
    tris: &[TriSetup],
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
        let t = &tris[i as usize];
        for y in (t.y0 as usize).max(y0)..=(t.y1 as usize).min(y1) {
            let base = (y - y0) * width;
            for x in t.x0 as usize..=t.x1 as usize {
                let d = dirs.dir(x, y);
                if inside(t, d) {
                    let w = edge(&t.w, d);
                    if w > zb[base + x] {
                        zb[base + x] = w;
                        idb[base + x] = i;
                    }
                }
            }
        }
    }
    let mut covered = 0;
    for j in 0..n {
        let (x, y) = (j % width, y0 + j / width);
        let id = idb[j];
        if id == NO_TRIANGLE {
            write_background(out, j);
            continue;
        }
        covered += 1;
        let t = &tris[id as usize];
        let d = dirs.dir(x, y);
        let ev = [edge(&t.e[0], d), edge(&t.e[1], d), edge(&t.e[2], d)];
        let sum = ev[0] + ev[1] + ev[2];
        let lam = ev.map(|v| (v / sum).max(0.0));
        let z = 1.0 / zb[j];
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
            out.triangle[j] = t.face;
            out.bary[j] = [lam[1], lam[2]];
        }
        if !out.normal.is_empty() {
            out.normal[j] = pixel_normal(ctx, t.face, lam);
        }
    }
    covered
}

fn write_background(out: &mut BandOut<'_>, j: usize) {
    if !out.mask.is_empty() {
        out.mask[j] = 0;
    }
    if !out.depth.is_empty() {
        out.depth[j] = f32::INFINITY;
    }
    if !out.camera_z.is_empty() {
        out.camera_z[j] = f32::INFINITY;
    }
    if !out.triangle.is_empty() {
        out.triangle[j] = NO_TRIANGLE;
        out.bary[j] = [0.0; 2];
    }
    if !out.normal.is_empty() {
        out.normal[j] = [0.0; 3];
    }
}

fn pixel_normal(ctx: &ResolveCtx<'_>, face: u32, lam: [f32; 3]) -> [f32; 3] {
    let [a, b, c] = ctx.faces[face as usize].map(|i| i as usize);
    if ctx.normals == NormalMode::Smooth {
        let n = [ctx.vertex_normals[a], ctx.vertex_normals[b], ctx.vertex_normals[c]];
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

/// Splits the requested output buffers into bands.
pub(crate) fn split_bands<'a>(
    width: usize,
    height: usize,
    mask: &'a mut [u8],
    depth: &'a mut [f32],
    camera_z: &'a mut [f32],
    normal: &'a mut [[f32; 3]],
    triangle: &'a mut [u32],
    bary: &'a mut [[f32; 2]],
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
    let mut m = parts(mask, chunk, n_bands).into_iter();
    let mut d = parts(depth, chunk, n_bands).into_iter();
    let mut z = parts(camera_z, chunk, n_bands).into_iter();
    let mut nn = parts(normal, chunk, n_bands).into_iter();
    let mut t = parts(triangle, chunk, n_bands).into_iter();
    let mut b = parts(bary, chunk, n_bands).into_iter();
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
        .map_init(
            || Scratch::new(scratch_len),
            |s, mut band| f(s, &mut band),
        )
        .sum()
}
