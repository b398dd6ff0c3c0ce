//! Extraction: the finest cells that can hold the iso-surface, and the small components
//! dropped from the marched mesh.

use rayon::prelude::*;
use skin_core::mesh::TriMesh;

use crate::marching_cubes::{Node, NodeMap};
use crate::Result;

use super::cells::{add, corners8, NONE};
use super::grid::{Composite, Level, B};

/// Drops the connected components (sharing vertices) of `mesh` with fewer vertices than
/// `fraction` × the largest component's; returns the mesh and the number dropped.
pub(super) fn drop_small_components(mesh: TriMesh, fraction: f64) -> Result<(TriMesh, usize)> {
    fn find(parent: &mut [u32], mut i: u32) -> u32 {
        while parent[i as usize] != i {
            let p = parent[parent[i as usize] as usize];
            parent[i as usize] = p;
            i = p;
        }
        i
    }
    let nv = mesh.vertex_count();
    if fraction <= 0.0 || nv == 0 {
        return Ok((mesh, 0));
    }
    let mut parent: Vec<u32> = (0..nv as u32).collect();
    for f in &mesh.faces {
        let a = find(&mut parent, f[0]);
        for &v in &f[1..] {
            let b = find(&mut parent, v);
            if a != b {
                parent[b as usize] = a;
            }
        }
    }
    let roots: Vec<u32> = (0..nv as u32).map(|i| find(&mut parent, i)).collect();
    let mut size = vec![0usize; nv];
    for &r in &roots {
        size[r as usize] += 1;
    }
    let largest = size.iter().copied().max().unwrap_or(0);
    let min = fraction * largest as f64;
    let keep = |v: u32| size[roots[v as usize] as usize] as f64 >= min;
    let dropped = size.iter().filter(|&&s| s > 0 && (s as f64) < min).count();
    if dropped == 0 {
        return Ok((mesh, 0));
    }
    let mut map = vec![u32::MAX; nv];
    let mut vertices = Vec::new();
    for (i, v) in mesh.vertices.iter().enumerate() {
        if keep(i as u32) {
            map[i] = vertices.len() as u32;
            vertices.push(*v);
        }
    }
    let faces = mesh
        .faces
        .iter()
        .filter(|f| keep(f[0]))
        .map(|f| f.map(|v| map[v as usize]))
        .collect();
    Ok((TriMesh::new(vertices, faces)?, dropped))
}

/// Cells of the finest level to polygonise: descend from the complete level into cells whose
/// corners straddle `iso` or whose region holds a finer band.
pub(super) fn collect_cells(
    comp: &mut Composite,
    li: usize,
    cell: Node,
    iso: f64,
    out: &mut Vec<Node>,
) {
    let levels = comp.levels;
    if li + 1 == levels.len() {
        out.push(cell);
        return;
    }
    let mut below = false;
    let mut above = false;
    for o in corners8() {
        if comp.value(li, add(cell, o, 1)) < iso {
            below = true;
        } else {
            above = true;
        }
    }
    let finer = &levels[li + 1];
    let refine = (below && above) || {
        let lo = cell.map(|c| ((2 * c) / B).max(0));
        let hi = cell.map(|c| ((2 * c + 2) / B).min(finer.nb - 1));
        let mut any = false;
        for bz in lo[2]..=hi[2] {
            for by in lo[1]..=hi[1] {
                for bx in lo[0]..=hi[0] {
                    any |= finer.dir[(bx + finer.nb * (by + finer.nb * bz)) as usize] != NONE;
                }
            }
        }
        any
    };
    if refine {
        for o in corners8() {
            collect_cells(comp, li + 1, add(cell.map(|c| 2 * c), o, 1), iso, out);
        }
    }
}

/// The finest-level cells to polygonise ([`collect_cells`] from every cell of the complete
/// level and one ring outside it), in parallel over the complete level's z-slices (each with a
/// memo of its own: a cache, the values are the same), in the serial order.
pub(super) fn extraction_cells(levels: &[Level], iso: f64, outside: f64) -> Vec<Node> {
    let n0 = levels[0].n;
    (-1..=n0)
        .into_par_iter()
        .map(|k| {
            let mut comp = Composite {
                levels,
                memo: NodeMap::default(),
                outside,
            };
            let mut cells = Vec::new();
            for j in -1..=n0 {
                for i in -1..=n0 {
                    collect_cells(&mut comp, 0, [i, j, k], iso, &mut cells);
                }
            }
            cells
        })
        .collect::<Vec<_>>()
        .concat()
}

/// Cells per parallel task of the extraction's marching cubes.
pub(super) const MARCH_CHUNK: usize = 32_768;
