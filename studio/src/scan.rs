//! What a 3D scanner gives of a performer in its rest pose: the outer surface as one closed
//! mesh, as the templates of Vlasic 2010 §2.5.1 were ("a 3D scan of the performer in the
//! clothes", decimated to 10,000 vertices).
//!
//! A scanner sees the outside only. A performer in a skirt is, to it, one solid: the body and
//! the skirt's volume (the legs inside the skirt are never seen, and the hem is closed where
//! the scan's surface reconstruction joins the skirt to the legs). The scan is the boundary of
//! that solid: inside is where the generalised winding number (Jacobson et al. 2013) of the
//! body, or of the garment closed by a flat cap over each of its open boundary loops, is at
//! least ½; the field is that inside/outside sign times the distance to the nearer of the two
//! surfaces, sampled on a grid and meshed by [`marching_tetrahedra`]; the largest connected
//! piece is kept.

use std::collections::{HashMap, HashSet};

use serde::{Deserialize, Serialize};
use skin_core::math::DVec3;
use skin_core::mesh::{
    connected_parts, decimate, marching_tetrahedra, vertex_neighbors, vertex_normals, EdgeTopology,
    MeshQuery, NormalWeighting, ScalarGrid, TriMesh, WindingNumber,
};
use skin_core::{Error, Result};

use crate::Performer;

/// Knobs of [`scan_outer_surface`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ScanParams {
    /// Grid spacing, m. Default: [`Self::DEFAULT_VOXEL_M`] = 2 cm. The templates of §2.5.1
    /// are decimated to 10,000 vertices, about 2 cm apart on a body, so finer detail is
    /// decimated away (the fingers merge at this spacing, as in a decimated scan). Finer
    /// spacings trade time for detail (MakeHuman in its skirt: 1.1 s at 2 cm, 7.3 s at 1 cm)
    /// and leave meshoptimizer's decimation to 10,000 vertices one or two non-manifold
    /// edges at thin places (measured at 1, 1.2 and 1.5 cm), which
    /// `skin_core::mesh::decimate` refuses.
    pub voxel_m: f64,
    /// Vertices of the template made from the scan, as §2.5.1 decimated its scans to
    /// 10,000: the iso-surface decimated (meshoptimizer) to about this many, then relaxed
    /// ([`Self::relax_iterations`]); `None` keeps the iso-surface as it is. Default:
    /// [`Self::DEFAULT_VERTICES`].
    pub vertices: Option<usize>,
    /// Tangential relaxation steps after decimation: each vertex moves to its neighbours'
    /// centroid within its tangent plane and back onto the iso-surface. Marching tetrahedra
    /// leave slivers that decimation keeps, and a sliver's cotangent weights are huge or
    /// negative, which turns Laplacian molding (§2.4) into spikes; relaxed triangles are
    /// near-equilateral. Default: [`Self::DEFAULT_RELAX_ITERATIONS`].
    pub relax_iterations: usize,
}

impl ScanParams {
    /// Default grid spacing, m.
    pub const DEFAULT_VOXEL_M: f64 = 0.02;
    /// Default template size: 10,000 vertices (§2.5.1).
    pub const DEFAULT_VERTICES: Option<usize> = Some(10_000);
    /// Default relaxation steps.
    pub const DEFAULT_RELAX_ITERATIONS: usize = 10;
}

impl Default for ScanParams {
    fn default() -> Self {
        ScanParams {
            voxel_m: Self::DEFAULT_VOXEL_M,
            vertices: Self::DEFAULT_VERTICES,
            relax_iterations: Self::DEFAULT_RELAX_ITERATIONS,
        }
    }
}

/// A scan of a performer's rest pose ([`scan_outer_surface`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Scan {
    /// The outer surface, one closed mesh in the performer's rest frame, metres.
    pub mesh: TriMesh,
    /// Per vertex of the scan: whether it lies on the garment's closed volume (the skirt and
    /// its hem cap) rather than on the body.
    pub on_garment: Vec<bool>,
    /// Per vertex of the performer's template: whether the scanner cannot see it (body
    /// vertices inside the garment's closed volume: the legs under a skirt).
    pub hidden: Vec<bool>,
}

/// The performer's rest pose as a scanner sees it (module docs). A performer without a garment
/// gives its body's outer surface.
///
/// # Errors
/// [`Error::InvalidParam`] for a `voxel_m` that is not positive or a grid too large for it;
/// as [`WindingNumber::new`], [`MeshQuery::new`] and [`marching_tetrahedra`];
/// [`Error::Empty`] when the iso-surface is empty.
///
/// # Example
/// ```
/// use dynamic_shapes_studio::{procedural_performer, scan_outer_surface, ProceduralBodyParams, ScanParams};
/// let p = procedural_performer(&ProceduralBodyParams { grid_spacing_m: 0.04, ..Default::default() })?;
/// let params = ScanParams { voxel_m: 0.04, vertices: None, ..ScanParams::default() };
/// let scan = scan_outer_surface(&p, &params)?;
/// assert!(skin_core::mesh::is_closed(&scan.mesh)?);
/// # Ok::<(), skin_core::Error>(())
/// ```
pub fn scan_outer_surface(performer: &Performer, params: &ScanParams) -> Result<Scan> {
    skin_core::check::positive("voxel_m", params.voxel_m)?;
    let (body, _) = performer.body()?;
    let garment_range = performer.garment_vertices();
    let garment = closed_garment(performer)?;
    let h = params.voxel_m;
    let mut parts = vec![(WindingNumber::new(&body)?, MeshQuery::new(&body)?)];
    if let Some(g) = &garment {
        parts.push((WindingNumber::new(g)?, MeshQuery::new(g)?));
    }
    let bb = performer.template.bounding_box()?;
    let lo = bb.min - DVec3::splat(2.0 * h);
    let dims = ((bb.max + DVec3::splat(2.0 * h) - lo) / h)
        .ceil()
        .to_array()
        .map(|d| d as usize + 1);
    let n = dims
        .iter()
        .try_fold(1usize, |a, &d| a.checked_mul(d))
        .filter(|&n| n <= 1 << 27)
        .ok_or_else(|| Error::InvalidParam {
            name: "voxel_m",
            reason: format!("{h} m makes a grid of {dims:?} nodes; give a coarser spacing"),
        })?;
    let nodes: Vec<DVec3> = (0..n)
        .map(|i| {
            let (x, rest) = (i % dims[0], i / dims[0]);
            let (y, z) = (rest % dims[1], rest / dims[1]);
            lo + DVec3::new(x as f64, y as f64, z as f64) * h
        })
        .collect();
    let mut inside = vec![false; n];
    let mut distance = vec![f64::INFINITY; n];
    for (winding, query) in &parts {
        for (i, w) in winding.at_points(&nodes)?.into_iter().enumerate() {
            inside[i] |= w >= 0.5;
        }
        for (i, c) in query.closest_points(&nodes)?.into_iter().enumerate() {
            distance[i] = distance[i].min(c.distance);
        }
    }
    // Nodes on the surface are nudged off it by a thousandth of a voxel, so that no two
    // iso-vertices coincide (zero-area triangles make later edge collapses non-manifold).
    let floor = 1e-3 * h;
    let values = inside
        .iter()
        .zip(&distance)
        .map(|(&i, &d)| if i { -d.max(floor) } else { d.max(floor) })
        .collect();
    let grid = ScalarGrid {
        origin: lo,
        spacing_m: h,
        dims,
        values,
    };
    let iso = largest_piece(&marching_tetrahedra(&grid, 0.0)?)?;
    let mesh = match params.vertices {
        Some(target) if target < iso.vertex_count() => {
            let mut coarse = decimate(&iso, target)?.mesh;
            relax(&mut coarse, &MeshQuery::new(&iso)?, params.relax_iterations)?;
            coarse
        }
        _ => iso,
    };
    let on_garment = match &parts[..] {
        [(_, body_q), (_, garment_q)] => {
            let to_body = body_q.closest_points(&mesh.vertices)?;
            let to_garment = garment_q.closest_points(&mesh.vertices)?;
            to_body
                .iter()
                .zip(&to_garment)
                .map(|(b, g)| g.distance < b.distance)
                .collect()
        }
        _ => vec![false; mesh.vertex_count()],
    };
    let mut hidden = vec![false; performer.template.vertex_count()];
    if let [_, (garment_w, _)] = &parts[..] {
        let body_vertices = &performer.template.vertices[..garment_range.start];
        for (v, w) in garment_w.at_points(body_vertices)?.into_iter().enumerate() {
            hidden[v] = w >= 0.5;
        }
    }
    Ok(Scan {
        mesh,
        on_garment,
        hidden,
    })
}

/// `iterations` steps of tangential relaxation of `mesh` onto the surface of `onto`
/// ([`ScanParams::relax_iterations`]).
fn relax(mesh: &mut TriMesh, onto: &MeshQuery, iterations: usize) -> Result<()> {
    let neighbours = vertex_neighbors(mesh)?;
    for _ in 0..iterations {
        let normals = vertex_normals(mesh, NormalWeighting::Angle)?;
        let moved: Vec<DVec3> = (0..mesh.vertex_count())
            .map(|v| {
                let ring = neighbours.row(v);
                let p = mesh.vertices[v];
                if ring.is_empty() {
                    return p;
                }
                let centroid = ring
                    .iter()
                    .map(|&u| mesh.vertices[u as usize])
                    .sum::<DVec3>()
                    / ring.len() as f64;
                let step = centroid - p;
                p + step - normals[v] * normals[v].dot(step)
            })
            .collect();
        mesh.vertices = onto
            .closest_points(&moved)?
            .into_iter()
            .map(|c| c.position)
            .collect();
    }
    Ok(())
}

/// The garment's rest mesh with a fan over each open boundary loop (its centroid the fan's
/// apex), so that its winding number is one inside the cloth's volume; `None` without a
/// garment.
fn closed_garment(performer: &Performer) -> Result<Option<TriMesh>> {
    let range = performer.garment_vertices();
    if range.is_empty() {
        return Ok(None);
    }
    let offset = range.start as u32;
    let mut mesh = TriMesh {
        vertices: performer.template.vertices[range].to_vec(),
        faces: performer
            .template
            .faces
            .iter()
            .filter(|f| f.iter().all(|&v| v >= offset))
            .map(|f| f.map(|v| v - offset))
            .collect(),
    };
    // Boundary edges as the faces orient them; a loop followed along them, capped with the
    // opposite orientation, closes the surface consistently.
    let boundary: HashSet<[u32; 2]> = EdgeTopology::new(&mesh)?
        .boundary_edges()
        .into_iter()
        .map(|[a, b]| [a.min(b), a.max(b)])
        .collect();
    let oriented: HashMap<u32, u32> = mesh
        .faces
        .iter()
        .flat_map(|f| [[f[0], f[1]], [f[1], f[2]], [f[2], f[0]]])
        .filter(|[a, b]| boundary.contains(&[*a.min(b), *a.max(b)]))
        .map(|[a, b]| (a, b))
        .collect();
    let mut seen = HashSet::new();
    let mut starts: Vec<u32> = oriented.keys().copied().collect();
    starts.sort_unstable();
    for start in starts {
        if !seen.insert(start) {
            continue;
        }
        let mut ring = vec![start];
        let mut v = start;
        while let Some(&next) = oriented.get(&v) {
            if next == start || !seen.insert(next) {
                break;
            }
            ring.push(next);
            v = next;
        }
        if ring.len() < 3 {
            continue;
        }
        let centre = ring
            .iter()
            .map(|&i| mesh.vertices[i as usize])
            .sum::<DVec3>()
            / ring.len() as f64;
        let apex = mesh.vertices.len() as u32;
        mesh.vertices.push(centre);
        for k in 0..ring.len() {
            let (a, b) = (ring[k], ring[(k + 1) % ring.len()]);
            mesh.faces.push([b, a, apex]);
        }
    }
    Ok(Some(mesh))
}

/// The connected part of `mesh` with the most vertices, compacted.
fn largest_piece(mesh: &TriMesh) -> Result<TriMesh> {
    let (part, sizes) = connected_parts(mesh)?;
    let Some(best) = (0..sizes.len()).max_by_key(|&p| sizes[p]) else {
        return Err(Error::Empty {
            what: "scanned surface (the performer occupies no grid node; give a finer voxel)",
        });
    };
    let mut index = vec![u32::MAX; mesh.vertex_count()];
    let mut out = TriMesh {
        vertices: Vec::new(),
        faces: Vec::new(),
    };
    for f in mesh
        .faces
        .iter()
        .filter(|f| part[f[0] as usize] as usize == best)
    {
        let face = f.map(|v| {
            let v = v as usize;
            if index[v] == u32::MAX {
                index[v] = out.vertices.len() as u32;
                out.vertices.push(mesh.vertices[v]);
            }
            index[v]
        });
        out.faces.push(face);
    }
    if out.faces.is_empty() {
        return Err(Error::Empty {
            what: "scanned surface (the performer occupies no grid node; give a finer voxel)",
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests;
