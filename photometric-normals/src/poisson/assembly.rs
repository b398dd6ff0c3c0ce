//! The cascade: each level's system assembled from the samples (flux and screening splats)
//! and the coarser levels (start and Dirichlet values), then solved.

use rayon::prelude::*;
use skin_core::math::DVec3;

use crate::marching_cubes::{Node, NodeMap};
use crate::Result;

use super::cells::{add, cell_of, corners8, nearest_node, quadratic, trilinear, AXES, NONE};
use super::grid::{Composite, Level, B};
use super::samples::{band_blocks, UnitSample};
use super::screening::CellScreening;
use super::solve::{level_cg, parents, COARSEST_DEPTH};
use super::{FluxSplat, PoissonLevel, PoissonParams, ScreeningForm};

/// Every level from the coarsest (dense down to `params.dense_depth`, then the band around
/// the samples) to `params.depth`, each solved from the coarser ones, with its figures.
pub(super) fn solve_hierarchy(
    unit: &[UnitSample],
    params: &PoissonParams,
) -> Result<(Vec<Level>, Vec<PoissonLevel>)> {
    let mut levels: Vec<Level> = Vec::new();
    let mut figures = Vec::new();
    for depth in COARSEST_DEPTH.min(params.dense_depth)..=params.depth {
        let nb = (1i64 << depth) / B + 1;
        let active = if depth <= params.dense_depth {
            vec![true; (nb * nb * nb) as usize]
        } else {
            band_blocks(unit, depth, i64::from(params.band_blocks))
        };
        let mut level = Level::new(depth, &active);
        figures.push(solve_level(&mut level, &levels, unit, params)?);
        levels.push(level);
    }
    Ok((levels, figures))
}

/// Builds and solves one level's system; `prev` (the coarser levels) gives the start and the
/// Dirichlet values where the band ends.
pub(super) fn solve_level(
    level: &mut Level,
    coarser: &[Level],
    samples: &[UnitSample],
    params: &PoissonParams,
) -> Result<PoissonLevel> {
    let nn = level.nodes.len();
    let h = level.h();
    let n = level.n;
    // Splat flux ([`FluxSplat`]) and screening mass (trilinear). Each chunk of samples finds
    // its nodes in parallel (4 bytes a node: the weights are recomputed below, which keeps the
    // transient to 140 bytes a sample); the sums are then taken serially in sample order (the
    // same sums, bit for bit, as one serial loop).
    let nodes_of: Vec<Vec<SplatNodes>> = samples
        .par_chunks(SPLAT_CHUNK)
        .map(|chunk| {
            chunk
                .iter()
                .map(|s| {
                    // A cell's corners are in the domain (`cell_of` clamps the cell).
                    let (c, _) = cell_of(s.q, n);
                    let mut mass = [NONE; 8];
                    for (slot, off) in mass.iter_mut().zip(corners8()) {
                        *slot = level.index(add(c, off, 1)).map_or(NONE, |i| i as u32);
                    }
                    let flux = match params.flux_splat {
                        FluxSplat::Quadratic => level.stencil_indices(nearest_node(s.q, n).0),
                        FluxSplat::Trilinear => [NONE; 27],
                    };
                    SplatNodes { flux, mass }
                })
                .collect()
        })
        .collect();
    let mut v = vec![DVec3::ZERO; nn];
    let mut mass = vec![0.0; nn];
    for (s, nodes) in samples.iter().zip(nodes_of.iter().flatten()) {
        let (_, t) = cell_of(s.q, n);
        match params.flux_splat {
            FluxSplat::Quadratic => {
                let (_, t) = nearest_node(s.q, n);
                let (wx, wy, wz) = (quadratic(t.x), quadratic(t.y), quadratic(t.z));
                let flux = s.flux / (h * h * h);
                for (k, &i) in nodes.flux.iter().enumerate() {
                    if i != NONE {
                        v[i as usize] += flux * (wx[k % 3] * wy[(k / 3) % 3] * wz[k / 9]);
                    }
                }
            }
            FluxSplat::Trilinear => {
                for (&i, off) in nodes.mass.iter().zip(corners8()) {
                    if i != NONE {
                        v[i as usize] += s.flux * (trilinear(t, off) / (h * h * h));
                    }
                }
            }
        }
        for (&i, off) in nodes.mass.iter().zip(corners8()) {
            if i != NONE {
                mass[i as usize] += s.mass * trilinear(t, off);
            }
        }
    }
    drop(nodes_of);
    if params.screening_form == ScreeningForm::Consistent {
        let points = samples.iter().map(|s| (s.q, s.mass));
        let screen = CellScreening::new(points, n, params.screening, |p| level.index(p), nn);
        level.screen = Some(screen);
    }
    // Start values and Dirichlet values from the coarser levels.
    let start_and_boundary = |p: Node, comp: &mut Composite| -> f64 {
        match coarser.len() {
            0 => 0.0,
            n => comp.interpolated_from(n - 1, p),
        }
    };
    // Per node, independently (in parallel; each chunk of nodes memoises the coarser
    // levels' values in its own `Composite`, a cache that does not change any value): the
    // start value, the diagonal, the right-hand side and the neighbour table (`NONE` =
    // outside the domain or the band), written in place.
    let mut x = vec![0.0; nn];
    let mut diag = vec![0.0; nn];
    let mut b = vec![0.0; nn];
    let mut nbr = vec![[NONE; 6]; nn];
    level
        .nodes
        .par_chunks(ASSEMBLY_CHUNK)
        .zip(x.par_chunks_mut(ASSEMBLY_CHUNK))
        .zip(diag.par_chunks_mut(ASSEMBLY_CHUNK))
        .zip(b.par_chunks_mut(ASSEMBLY_CHUNK))
        .zip(nbr.par_chunks_mut(ASSEMBLY_CHUNK))
        .enumerate()
        .for_each(|(ci, ((((chunk, xc), dc), bc), nc))| {
            let mut comp = Composite {
                levels: coarser,
                memo: NodeMap::default(),
                outside: 0.0,
            };
            for (k, &p) in chunk.iter().enumerate() {
                let i = ci * ASSEMBLY_CHUNK + k;
                xc[k] = start_and_boundary(p, &mut comp);
                let mut d = match &level.screen {
                    Some(screen) => screen.diagonal(i),
                    None => params.screening / h * mass[i],
                };
                let mut rhs = 0.0;
                for (ai, axis) in AXES.iter().enumerate() {
                    for (si, s) in [-1i64, 1].into_iter().enumerate() {
                        let m = add(p, *axis, s);
                        if !level.in_domain(m) {
                            continue;
                        }
                        d += 1.0;
                        let a = axis.iter().position(|&c| c == 1).unwrap_or(0);
                        let (vm, known) = match level.index(m) {
                            Some(j) => {
                                nc[k][2 * ai + si] = j as u32;
                                (v[j][a], None)
                            }
                            None => (0.0, Some(start_and_boundary(m, &mut comp))),
                        };
                        let ve = 0.5 * (v[i][a] + vm);
                        // Edge below (s = −1) adds +h·V_e, edge above subtracts it.
                        rhs -= s as f64 * h * ve;
                        if let Some(val) = known {
                            rhs += val;
                        }
                    }
                }
                dc[k] = d;
                bc[k] = rhs;
            }
        });
    drop(v);
    // The consistent screening's smoother and Jacobi preconditioner: the diagonal plus the
    // screening's off-diagonal row sums (its entries are positive and each row sums to the
    // lumped mass), an l1-Jacobi that stays convergent where the screening's couplings
    // outweigh its diagonal (ours, measured on workload 6b at α = 1,024: with the plain
    // diagonal the complete levels' V-cycles needed 17–50 iterations instead of 5–6).
    if let Some(screen) = &level.screen {
        level.l1_diag = diag
            .par_iter()
            .zip(&mass)
            .enumerate()
            .map(|(i, (d, m))| d - screen.diagonal(i) + params.screening / h * m)
            .collect();
    }
    drop(mass);
    level.diag = diag;
    level.nbr = nbr;
    // The coarse parents are needed only where this level takes part in a V-cycle: a
    // complete level, or a band level when the bands are multigrid-preconditioned (ours,
    // measured: at depth 9 the table is 32 bytes per band node, unused by Jacobi).
    let in_v_cycle = level.complete || params.multigrid_bands;
    if let Some(coarse) = coarser.last().filter(|_| in_v_cycle) {
        level.up = level
            .nodes
            .par_iter()
            .map(|&p| {
                let mut out = [NONE; 8];
                for (k, (q, _)) in parents(p).enumerate() {
                    if coarse.in_domain(q) {
                        if let Some(j) = coarse.index(q) {
                            out[k] = j as u32;
                        }
                    }
                }
                out
            })
            .collect();
    }
    // Complete levels: a V-cycle. Band levels: Jacobi unless asked (see
    // `PoissonParams::multigrid_bands`).
    let multigrid = level.complete || params.multigrid_bands;
    let cg = level_cg(level, coarser, multigrid, &b, &mut x, params)?;
    level.x = x;
    Ok(PoissonLevel {
        depth: level.depth,
        nodes: nn,
        iterations: cg.iterations,
        residual: cg.relative_residual,
    })
}

/// A sample's unknowns (`NONE` = outside the domain or the band): those of its quadratic
/// flux splat, in [`Level::stencil_indices`] order (all `NONE` for the trilinear splat,
/// which uses `mass`'s), and of its cell's corners, in [`corners8`] order.
struct SplatNodes {
    flux: [u32; 27],
    mass: [u32; 8],
}

/// Samples per parallel task of a level's splat.
pub(super) const SPLAT_CHUNK: usize = 65_536;

/// Nodes per parallel task of a level's assembly (each task memoises its own coarser values).
pub(super) const ASSEMBLY_CHUNK: usize = 16_384;
