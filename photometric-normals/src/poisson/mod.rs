//! Screened Poisson surface reconstruction (Kazhdan & Hoppe 2013) for hole filling: beyond
//! the thesis, which filled holes with unscreened Poisson reconstruction (Kazhdan et al.
//! 2006) from samples of the merged surface and, at weight 0.01, of the visual hull (§3.3.3).
//!
//! **Problem.** In the unit cube that holds the samples (their bounding cube enlarged by
//! [`PoissonParams::scale`]), find the indicator `χ` minimising
//! `∫ ‖∇χ − V‖² + α Σᵢ wᵢ aᵢ χ(pᵢ)²`, where `V = Σᵢ wᵢ aᵢ nᵢ δ(pᵢ)` is the samples' oriented
//! area (`aᵢ` the area a sample stands for, from the sample density; `wᵢ` its confidence) and
//! `α` the screening weight (Kazhdan's default 4). The surface is the level set of `χ` at the
//! weighted mean of `χ` over the samples. `V` points outwards, so `χ` grows by about 1 from
//! inside to outside.
//!
//! **Discretisation (documented simplifications of Kazhdan's).** Instead of degree-2
//! B-splines on an adaptive octree this uses the **trilinear (degree-1) basis on a hierarchy of
//! sparse regular grids**: level `d` has `2ᵈ` cells per axis; levels up to
//! [`PoissonParams::dense_depth`] are complete, finer levels hold only the 4³-node blocks
//! around the samples (a band a few cells wide). `V` is splatted onto nodes by the quadratic
//! B-spline around the nearest node or trilinearly ([`FluxSplat`]), the gradient energy is the 7-point finite-difference form (`V` averaged onto grid edges), the
//! screening term is mass-lumped onto nodes (`Σᵢ wᵢ aᵢ φₙ(pᵢ)`) by default or taken at the
//! samples as written ([`ScreeningForm`]), and the domain boundary is free (Neumann). The sample area `aᵢ` is `1 / σᵢ`, the inverse of the local sample density
//! per unit area estimated by a smooth kernel over the 40 nearest samples within at most 4
//! finest cells (`ρᵢ = Σⱼ (1 − dᵢⱼ²/rᵢ²)²`, `σᵢ = 3ρᵢ / (π rᵢ²)`), so confidences scale a sample's pull
//! relative to equally dense samples, as in Kazhdan's code (which splats a B-spline density
//! two levels above the finest). A per-cell count, used before, gave samples in cells that the
//! surface only clips a large area each: a wiggle of the surface at the grid's period, the
//! main part of the error where sampled.
//!
//! **Solver: cascadic conjugate gradients with multigrid on the complete levels.** Levels run
//! coarse to fine from depth 2. Each is solved by preconditioned CG, started from the coarser
//! solution interpolated; a band level keeps the coarser solution (interpolated) as Dirichlet
//! values where the band ends. The complete levels are preconditioned by a multigrid V-cycle
//! over all coarser levels (damped Jacobi 1 + 1 sweeps, restriction `Pᵀ`, the coarser level's
//! own operator as coarse problem — equal to the Galerkin `Pᵀ A P` up to the factor 2 of the
//! spacing — and 60 Jacobi sweeps on the 5³-node level): 5–6 iterations instead of 100–220.
//! The band levels use Jacobi by default: there the coarser bands do not end where the fine
//! band ends, so the V-cycle corrects badly near the band's edge and costs more than it saves
//! ([`PoissonParams::multigrid_bands`] turns it on). The composite `χ` is the finest level
//! that holds a node, trilinearly interpolated from coarser levels elsewhere, so it is
//! continuous and single-valued at every finest-level node.
//!
//! **Extraction.** Marching cubes on the finest level, descending from the complete level
//! only into cells whose corners straddle the iso-value or whose region holds a finer band (a
//! trilinear cell without a sign change at its corners has no zero inside). Every cell of the
//! domain is covered, so the output is **closed** (watertight and 2-manifold) unless the
//! surface runs into the domain boundary. A vertex sits at the zero, on its grid edge, of the
//! cubic through the four collinear node values around the edge (χ is a smoothed step a few
//! cells wide, not linear over one cell). Components smaller than
//! [`PoissonParams::min_component_fraction`] of the largest are dropped.
//!
//! **Files**, in dependency order: `cells.rs` (a grid's cells and nodes, splat weights),
//! `screening.rs` (the consistent screening's couplings), `grid.rs` (levels of blocks, the
//! composite indicator), `samples.rs` (sample areas, band blocks), `solve.rs` (a level's
//! conjugate gradients and V-cycle), `assembly.rs` (the cascade of levels, each assembled and
//! solved), `extract.rs` (the cells to march, small components dropped); this file holds the
//! public types and [`screened_poisson`].

use std::time::Instant;

use rayon::prelude::*;

use skin_core::check;
use skin_core::math::DVec3;
use skin_core::mesh::{vertex_normals, NormalWeighting, TriMesh};

use crate::marching_cubes::{march_cells_par, EdgeFit, NodeMap};
use crate::{Error, Result};

mod assembly;
mod cells;
mod extract;
mod grid;
mod samples;
mod screening;
mod solve;

use assembly::solve_hierarchy;
use extract::{drop_small_components, extraction_cells, MARCH_CHUNK};
use grid::Composite;
use samples::unit_samples;

/// An oriented point sample with a confidence weight.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OrientedSample {
    /// Position, m.
    pub position: DVec3,
    /// Outward normal (any positive length; normalised internally).
    pub normal: DVec3,
    /// Confidence (> 0): 1 for the merged surface and 0.01 for the proxy in the thesis.
    pub weight: f64,
}

impl OrientedSample {
    /// One sample per vertex of `mesh` (area-weighted vertex normals), all with `weight`.
    /// Vertices without a normal (isolated, or only in degenerate faces) are skipped.
    ///
    /// # Errors
    /// Errors of the normal computation; [`Error::InvalidParam`] for a weight that is not
    /// finite and positive.
    pub fn from_mesh(mesh: &TriMesh, weight: f64) -> Result<Vec<Self>> {
        check::positive("weight", weight)?;
        let normals = vertex_normals(mesh, NormalWeighting::Area)?;
        Ok(mesh
            .vertices
            .iter()
            .zip(normals)
            .filter(|(_, n)| n.length_squared() > 0.5)
            .map(|(&position, normal)| Self {
                position,
                normal,
                weight,
            })
            .collect())
    }
}

/// Parameters of the screened Poisson reconstruction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoissonParams {
    /// Finest level: `2^depth` cells along the domain's side. Default 8 (Open3D's and
    /// Kazhdan's default depth).
    pub depth: u32,
    /// Screening weight α. Default 4 (Kazhdan & Hoppe 2013's default, in unit-cube units).
    /// Not the same screening as Kazhdan's code at the same number: it multiplies the weight
    /// of a node at depth `d` by `2^d` (its `adaptiveExponent` of 1, as Open3D calls it), so its
    /// default is about α = 4 · 2^depth here (1,024 at depth 8). With the default
    /// [`ScreeningForm::Lumped`] that strength does not pay: workload 6b's mean error where
    /// sampled, depth 8, is 0.047 mm at α = 4, 0.039 at 64, 0.048 at 256 and 0.086 at 1,024
    /// (stronger screening removes the smooth bias the hole leaves on the sampled part, but
    /// the lumped screening adds artefacts at the grid's period); with
    /// [`ScreeningForm::Consistent`] it does (see there). Stronger screening also trades the
    /// filled holes for the sampled part (measured with the lumped form at α = 32: the
    /// studio's filled holes pulled towards the low-weight visual hull, p95 distance 26.5 →
    /// 36.7 mm).
    pub screening: f64,
    /// Domain side over the samples' bounding cube. Default 1.1 (Kazhdan's `--scale`).
    pub scale: f64,
    /// Levels up to this one are complete grids (all nodes unknown); finer levels are bands
    /// around the samples. Default 5 (33³ nodes).
    pub dense_depth: u32,
    /// Blocks (4 cells each) added around the samples' blocks in each band. Default 1.
    pub band_blocks: u32,
    /// Relative residual at which each level's CG stops. Default 10⁻⁴ (ours: on workloads
    /// 6a and 6b, 10⁻⁶ gives the same surface within 1 µm at 1.5× the time; Kazhdan's
    /// solver runs a fixed 8 Gauss–Seidel sweeps per level).
    pub tolerance: f64,
    /// CG iterations per level at most. Default 300.
    pub max_iterations: usize,
    /// Precondition the band levels' CG by multigrid V-cycles too (the complete levels always
    /// are). Default `false` (ours, measured): on the thin bands a V-cycle over the coarser
    /// bands cuts the iterations 3× but costs 5–8 Jacobi iterations' work, and the coarse
    /// bands do not end where the fine band ends, so it is 2× slower overall.
    pub multigrid_bands: bool,
    /// Connected components of the output with fewer vertices than this fraction of the
    /// largest component's are dropped (closed specks that noisy, grazing samples leave
    /// off sharp edges). Default 0.01 (ours); 0 keeps everything.
    pub min_component_fraction: f64,
    /// How each sample's oriented area is spread onto the nodes. Default
    /// [`FluxSplat::Quadratic`].
    pub flux_splat: FluxSplat,
    /// How the screening term is discretised. Default [`ScreeningForm::Lumped`].
    pub screening_form: ScreeningForm,
}

/// How [`screened_poisson`] discretises the screening term `α Σᵢ wᵢ aᵢ χ(pᵢ)²`.
///
/// Measured on workload 6b (200,000 random samples of a holed sphere, depth 8; Open3D's
/// error where sampled 0.020 mm), mean error where sampled:
///
/// | form | α = 4 | α = 256 | α = 1,024 (Kazhdan's strength) | α = 4,096 |
/// |---|---|---|---|---|
/// | lumped | 0.047 mm | 0.048 mm | 0.086 mm | |
/// | consistent | 0.047 mm | 0.034 mm | 0.032 mm | 0.032 mm |
///
/// In alternated runs the consistent form at α = 1,024 and 4,096 took 1.0–1.2× the time of
/// the lumped form at α = 4 (4.8–5.0 s): its couplings cost little, and the complete levels'
/// V-cycles need 4–23 iterations instead of 5–6. The consistent form's error does not fall
/// with depth at 200,000 samples (0.032 mm at depth 7, 0.036 at 9) nor with a tighter
/// tolerance (10⁻⁷: the same), but does with denser samples: with 2,000,000 it is 0.012 mm
/// at depth 8 (Open3D 0.009 mm, the lumped form 0.035 mm). Most of the gap at 200,000 is how
/// the trilinear basis follows about one random sample per finest cell.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ScreeningForm {
    /// Mass-lumped onto the nodes: each node's own value is pulled towards 0 with the
    /// weight `Σᵢ wᵢ aᵢ φₙ(pᵢ)` (ours: a diagonal term, so the operator stays 7-point; the
    /// default, with which the thesis pipeline's figures are measured). It pulls both sides of
    /// the surface towards the iso-value, by amounts that depend on where the surface cuts
    /// each cell: artefacts at the grid's period under strong screening.
    #[default]
    Lumped,
    /// As written (Kazhdan & Hoppe 2013): the trilinear value at each sample is pulled
    /// towards 0, which couples the 8 corners of each sample's cell.
    Consistent,
}

/// How [`screened_poisson`] spreads each sample's oriented area onto the grid's nodes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FluxSplat {
    /// The trilinear weights of the 8 corners of the sample's cell (two cells wide). Enough
    /// for dense, regular samples such as a merged mesh's vertices (several per finest cell),
    /// and cheaper: measured on the studio's two-pass reconstruction, the quadratic splat
    /// changed no figure beyond its run-to-run spread and took the Poisson solve from 2.9 to
    /// 4.1–4.5 s per pass at depth 9 (850,000 samples).
    Trilinear,
    /// The quadratic B-spline around the nearest node (27 nodes, three cells wide):
    /// Kazhdan et al. 2006's smoothing filter, the box convolved with itself twice. It
    /// averages out samples placed at random (measured on workload 6b at depth 8, about two
    /// samples per finest cell: 0.047 mm mean error where sampled against the trilinear
    /// splat's 0.060 mm, for 8 % more time).
    #[default]
    Quadratic,
}

impl Default for PoissonParams {
    fn default() -> Self {
        Self {
            depth: 8,
            screening: 4.0,
            scale: 1.1,
            dense_depth: 5,
            band_blocks: 1,
            tolerance: 1e-4,
            max_iterations: 300,
            multigrid_bands: false,
            min_component_fraction: 0.01,
            flux_splat: FluxSplat::Quadratic,
            screening_form: ScreeningForm::Lumped,
        }
    }
}

impl PoissonParams {
    /// With another finest depth.
    pub fn with_depth(mut self, depth: u32) -> Self {
        self.depth = depth;
        self
    }

    /// With another screening weight.
    pub fn with_screening(mut self, alpha: f64) -> Self {
        self.screening = alpha;
        self
    }

    /// With another band width, blocks.
    pub fn with_band_blocks(mut self, blocks: u32) -> Self {
        self.band_blocks = blocks;
        self
    }

    /// With or without multigrid preconditioning on the band levels.
    pub fn with_multigrid_bands(mut self, on: bool) -> Self {
        self.multigrid_bands = on;
        self
    }

    /// With another flux splat.
    pub fn with_flux_splat(mut self, splat: FluxSplat) -> Self {
        self.flux_splat = splat;
        self
    }

    /// With another discretisation of the screening term.
    pub fn with_screening_form(mut self, form: ScreeningForm) -> Self {
        self.screening_form = form;
        self
    }

    /// With another minimum component size (fraction of the largest component's vertices).
    pub fn with_min_component_fraction(mut self, fraction: f64) -> Self {
        self.min_component_fraction = fraction;
        self
    }

    fn validate(&self) -> Result<()> {
        check::non_negative("screening", self.screening)?;
        check::in_range(
            "min_component_fraction",
            self.min_component_fraction,
            0.0..=1.0,
        )?;
        check::in_range("scale", self.scale, 1.0..=4.0)?;
        check::positive("tolerance", self.tolerance)?;
        check::nonzero("max_iterations", self.max_iterations)?;
        if !(2..=self.depth).contains(&self.dense_depth) || self.depth > 11 {
            return Err(Error::InvalidParam {
                name: "depth",
                reason: format!(
                    "need 2 <= dense_depth ({}) <= depth ({}) <= 11",
                    self.dense_depth, self.depth
                ),
            });
        }
        Ok(())
    }
}

/// Per-level figures of a reconstruction.
#[derive(Debug, Clone, PartialEq)]
pub struct PoissonLevel {
    /// Level (cells per axis = 2^depth).
    pub depth: u32,
    /// Unknown nodes.
    pub nodes: usize,
    /// CG iterations run.
    pub iterations: usize,
    /// Relative residual reached.
    pub residual: f64,
}

/// Wall times of a reconstruction's stages, s.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PoissonTimes {
    /// The samples in the unit cube and their areas (the local sample density).
    pub samples_s: f64,
    /// Every level assembled and solved, coarse to fine.
    pub solve_s: f64,
    /// The iso-value and the finest cells that can hold the surface.
    pub cells_s: f64,
    /// Marching cubes over those cells and the small components dropped.
    pub march_s: f64,
}

/// A screened Poisson reconstruction.
#[derive(Debug, Clone)]
pub struct PoissonSurface {
    /// The closed iso-surface.
    pub mesh: TriMesh,
    /// The iso-value (weighted mean of the indicator at the samples).
    pub iso_value: f64,
    /// Per-level figures, coarsest first.
    pub levels: Vec<PoissonLevel>,
    /// Connected components dropped as specks ([`PoissonParams::min_component_fraction`]).
    pub dropped_components: usize,
    /// Wall times of the stages.
    pub times: PoissonTimes,
}

/// Screened Poisson reconstruction of a closed surface from oriented, weighted samples (see
/// the module docs for the discretisation and solver).
///
/// # Errors
/// [`Error::Empty`] for fewer than 4 samples; [`Error::NonFinite`] for a non-finite position
/// or normal; [`Error::InvalidParam`] for a zero normal, a weight that is not finite and
/// positive, or bad parameters.
///
/// # Example
/// A sphere's vertices without its top cap come back as a closed surface:
/// ```
/// use photometric_normals::{screened_poisson, OrientedSample, PoissonParams};
/// use skin_core::math::DVec3;
/// use skin_core::mesh::{is_closed, shapes::uv_sphere};
///
/// let sphere = uv_sphere(DVec3::ZERO, 0.3, 40, 80)?;
/// let mut samples = OrientedSample::from_mesh(&sphere, 1.0)?;
/// samples.retain(|s| s.position.y < 0.2);
/// let filled = screened_poisson(&samples, &PoissonParams::default().with_depth(6))?;
/// assert!(is_closed(&filled.mesh)?);
/// # Ok::<(), photometric_normals::Error>(())
/// ```
pub fn screened_poisson(
    samples: &[OrientedSample],
    params: &PoissonParams,
) -> Result<PoissonSurface> {
    params.validate()?;
    if samples.len() < 4 {
        return Err(Error::Empty {
            what: "oriented samples (need at least 4)",
        });
    }
    for (i, s) in samples.iter().enumerate() {
        if !(s.position.is_finite() && s.normal.is_finite()) {
            return Err(Error::NonFinite {
                what: "sample position or normal",
            });
        }
        if s.normal.length_squared() == 0.0 {
            return Err(Error::InvalidParam {
                name: "normal",
                reason: format!("sample {i} has a zero normal; drop it or give it an orientation"),
            });
        }
        check::positive("weight", s.weight)?;
    }
    let mut times = PoissonTimes::default();
    let t = Instant::now();
    let (unit, origin, side) = unit_samples(samples, params.scale, params.depth);
    times.samples_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let (levels, figures) = solve_hierarchy(&unit, params)?;
    times.solve_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let finest = levels.len() - 1;
    // The indicator at every sample in parallel (each task memoises in its own `Composite`,
    // which changes no value), then the weighted mean summed in sample order.
    let at_samples: Vec<f64> = unit
        .par_iter()
        .map_init(
            || Composite {
                levels: &levels,
                memo: NodeMap::default(),
                outside: 0.0,
            },
            |comp, s| comp.at_point(finest, s.q),
        )
        .collect();
    let (mut sw, mut swx) = (0.0, 0.0);
    for (s, x) in unit.iter().zip(&at_samples) {
        sw += s.weight;
        swx += s.weight * x;
    }
    let iso = swx / sw;
    let outside = iso + 0.5;
    let cells = extraction_cells(&levels, iso, outside);
    times.cells_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let hf = levels[finest].h();
    let mesh = march_cells_par(
        &cells,
        MARCH_CHUNK,
        || {
            let mut comp = Composite {
                levels: &levels,
                memo: NodeMap::default(),
                outside,
            };
            move |p| Some(comp.value(finest, p))
        },
        iso,
        |p| origin + DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64) * (hf * side),
        EdgeFit::Cubic,
    )?;
    let (mesh, dropped_components) = drop_small_components(mesh, params.min_component_fraction)?;
    times.march_s = t.elapsed().as_secs_f64();
    Ok(PoissonSurface {
        mesh,
        iso_value: iso,
        levels: figures,
        dropped_components,
        times,
    })
}

#[cfg(test)]
mod tests;
