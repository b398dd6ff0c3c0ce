//! The skirt performer at the studio frame seen by the ring of cameras with the rasteriser's
//! exact normals: the shared set-up of the photometric diagnostics (the Table 3.1 trace and
//! the coverage budget).

use dynamic_shapes::core::image::Mask;
use dynamic_shapes::core::mesh::TriMesh;
use dynamic_shapes::core::raster::RenderedView;
use dynamic_shapes::photometric::truth::{
    render_both_faces, skirt_subject, StudioScene, TrueSurface, STUDIO_FRAME,
};
use dynamic_shapes::photometric::{rendered_normals, DepthMap, NormalMap, PolygonalHull};
use dynamic_shapes_studio::DeformationParams;

/// The studio scene with exact normals.
pub struct ExactStudio {
    /// The scene (performer, ring of cameras).
    pub scene: StudioScene,
    /// The true mesh at the frame.
    pub mesh: TriMesh,
    /// Silhouettes per camera.
    pub sil: Vec<Mask>,
    /// True depth maps per camera.
    pub truths: Vec<DepthMap>,
    /// Exact (rendered) normals per camera.
    pub exact: Vec<NormalMap>,
    /// The visual hull of the silhouettes.
    pub hull: PolygonalHull,
    /// The ring's neighbouring pairs.
    pub pairs: Vec<(usize, usize)>,
}

/// `cameras` ring cameras at `size`² (both faces rendered), the true mesh as `surface`.
pub fn exact_studio(cameras: usize, size: u32, surface: TrueSurface) -> ExactStudio {
    exact_studio_of(&skirt_subject(), STUDIO_FRAME, cameras, size, surface)
}

/// As [`exact_studio`] for any `subject` (e.g. `ghost_subject()`) at `frame`.
pub fn exact_studio_of(
    subject: &DeformationParams,
    frame: usize,
    cameras: usize,
    size: u32,
    surface: TrueSurface,
) -> ExactStudio {
    let scene = StudioScene::with_surface(
        example_kit::data_path("makehuman").unwrap(),
        subject,
        frame,
        cameras,
        size,
        surface,
    )
    .unwrap();
    let mesh = scene.true_mesh().unwrap();
    let cams = &scene.ring.cameras;
    let views = render_both_faces(cams, &mesh).unwrap();
    let sil: Vec<Mask> = views.iter().map(RenderedView::silhouette).collect();
    let truths = views
        .iter()
        .map(|v| DepthMap::from_view(v).unwrap())
        .collect();
    let exact = cams
        .iter()
        .zip(&views)
        .map(|(c, v)| rendered_normals(c, v).unwrap())
        .collect();
    let hull = PolygonalHull::new(cams, &sil).unwrap();
    let pairs = (0..cameras).map(|c| (c, (c + 1) % cameras)).collect();
    ExactStudio {
        scene,
        mesh,
        sil,
        truths,
        exact,
        hull,
        pairs,
    }
}
