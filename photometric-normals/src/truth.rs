//! Validation equipment (feature `validation`): the studio's light patterns and calibration
//! spheres, ground-truth scoring of normal maps (angular error, shadowed concavities,
//! wrinkled regions) and the distant-light baseline (the analytic solution the thesis
//! replaces by its data-driven lookup).

use image::Rgb32FImage;
use serde::{Deserialize, Serialize};
use skin_core::camera::Camera;
use skin_core::math::DVec3;
use skin_core::mesh::shapes::uv_sphere;
use skin_core::mesh::TriMesh;
use skin_core::raster::{Buffers, Rasterizer, RenderParams, RenderedView};
use skin_core::stats::{mean, median};
use skin_core::studio::shading::{
    dome_lights, shade, shade_patterns, Albedo, DomeParams, Light, LightVisibility, Shadows,
};
use skin_core::studio::{FineSurface, LightPatterns, PatternSchedule, ViewTruth};

use crate::calibration::{CalibrationParams, CalibrationSphere, HeightCalibration, LookupTable};
use crate::normals::NormalMap;
use crate::patterns::{grey, key, patterns_weights, Exposure, PatternImages, CYCLE, PATTERNS};
use crate::{Error, Result};

/// Centre of the dome's sphere (the origin of the pattern directions of Eq. 3.1), world, m.
pub fn dome_centre(p: &DomeParams) -> DVec3 {
    let up = p.up.normalize_or_zero();
    let h_min = 1.0 - 2.0 * p.height_fraction;
    p.floor_centre - up * (h_min * p.radius_m)
}

/// Height of the studio floor below the performer's lowest rest vertex, m.
pub const FLOOR_BELOW_PERFORMER_M: f64 = 0.02;
/// The calibration spheres' heights above the floor (§3.2.3: seven heights): the lowest, m.
pub const SPHERE_LOWEST_M: f64 = 0.2;
/// The calibration spheres' height step, m.
pub const SPHERE_STEP_M: f64 = 0.25;
/// The number of calibration sphere heights (§3.2.3).
pub const SPHERE_HEIGHTS: usize = 7;

/// The light stage set up around a performer: the floor just under its rest template, the
/// default dome standing on that floor centred under `root`, its lights and the centre of its
/// sphere (the origin of the pattern directions).
#[derive(Debug, Clone)]
pub struct LightStage {
    /// Floor height, world y, m ([`FLOOR_BELOW_PERFORMER_M`] under the lowest rest vertex).
    pub floor_y: f64,
    /// The dome's lights at their real positions.
    pub lights: Vec<Light>,
    /// [`dome_centre`] of the dome.
    pub centre: DVec3,
}

impl LightStage {
    /// The stage around `template` (the performer's rest mesh) with the dome centred under
    /// `root` (e.g. the root joint's position in the captured frame).
    ///
    /// # Errors
    /// [`Error::Empty`] for a template without vertices; errors of the dome's lights.
    pub fn around(template: &TriMesh, root: DVec3) -> Result<Self> {
        let lowest = template
            .vertices
            .iter()
            .map(|v| v.y)
            .fold(f64::INFINITY, f64::min);
        if !lowest.is_finite() {
            return Err(Error::Empty {
                what: "template vertices",
            });
        }
        let floor_y = lowest - FLOOR_BELOW_PERFORMER_M;
        let dome = DomeParams {
            floor_centre: DVec3::new(root.x, floor_y, root.z),
            ..Default::default()
        };
        Ok(LightStage {
            floor_y,
            lights: dome_lights(&dome)?,
            centre: dome_centre(&dome),
        })
    }

    /// The heights of the calibration spheres (§3.2.3), world y, m: [`SPHERE_HEIGHTS`] of
    /// them from [`SPHERE_LOWEST_M`] above the floor every [`SPHERE_STEP_M`].
    pub fn sphere_heights_m(&self) -> Vec<f64> {
        (0..SPHERE_HEIGHTS)
            .map(|i| self.floor_y + SPHERE_LOWEST_M + SPHERE_STEP_M * i as f64)
            .collect()
    }
}

/// The studio's [`LightPatterns`]: the 8-frame [`CYCLE`] for [`PatternSchedule::Cycle`], the
/// seven distinct [`PATTERNS`] for [`PatternSchedule::AllEachFrame`].
///
/// # Errors
/// As [`crate::pattern_weights`].
pub fn studio_patterns(
    lights: &[Light],
    centre: DVec3,
    schedule: PatternSchedule,
) -> Result<LightPatterns> {
    let pos: Vec<DVec3> = lights.iter().map(Light::position).collect();
    let order: &[crate::Pattern] = match schedule {
        PatternSchedule::Cycle => &CYCLE,
        PatternSchedule::AllEachFrame => &PATTERNS,
    };
    Ok(LightPatterns {
        weights: patterns_weights(&pos, centre, order)?,
        schedule,
    })
}

/// The images of a grey diffuse sphere (uniform `albedo`) under the seven patterns, seen by
/// `camera`: the studio's rasteriser and Lambertian shading (a convex sphere casts no shadow
/// on itself). Pixels off the sphere are zero.
///
/// # Errors
/// Rasteriser and shading errors (e.g. a sphere the camera does not see).
pub fn render_sphere_patterns(
    camera: &Camera,
    sphere: &CalibrationSphere,
    lights: &[Light],
    centre: DVec3,
    albedo: f32,
) -> Result<PatternImages> {
    let mesh = uv_sphere(sphere.centre, sphere.radius_m, 96, 192)?;
    let view = Rasterizer::new(camera).render(
        &mesh,
        &RenderParams::default().with_buffers(Buffers {
            triangle: true,
            ..Buffers::MASK_ONLY
        }),
    )?;
    let pos: Vec<DVec3> = lights.iter().map(Light::position).collect();
    let weights = patterns_weights(&pos, centre, &PATTERNS)?;
    let shaded = shade_patterns(
        &view,
        &mesh,
        lights,
        &weights,
        &Albedo::Uniform([albedo; 3]),
        &Shadows::None,
    )?;
    let images = PATTERNS
        .iter()
        .zip(shaded)
        .map(|(&p, s)| Ok((p, grey(&s.to_image()?))))
        .collect::<Result<Vec<_>>>()?;
    PatternImages::new(images)
}

/// §3.2.3 calibration of one camera: a grey sphere of radius `radius_m` at each of `heights`
/// (world `up` = +Y, m) above the point `axis` (its x and z), rendered under the patterns and
/// turned into a [`HeightCalibration`].
///
/// # Errors
/// As [`render_sphere_patterns`] and [`LookupTable::from_sphere`].
#[allow(
    clippy::too_many_arguments,
    reason = "the calibration set-up, spelled out"
)]
pub fn calibrate_camera(
    camera: &Camera,
    lights: &[Light],
    centre: DVec3,
    axis: DVec3,
    heights: &[f64],
    radius_m: f64,
    albedo: f32,
    params: &CalibrationParams,
) -> Result<HeightCalibration> {
    let tables = heights
        .iter()
        .enumerate()
        .map(|(i, &h)| {
            let sphere = CalibrationSphere {
                centre: DVec3::new(axis.x, h, axis.z),
                radius_m,
            };
            let images = render_sphere_patterns(camera, &sphere, lights, centre, albedo)?;
            LookupTable::from_sphere(camera, &sphere, &images, DVec3::Y, params).map_err(|e| {
                Error::At {
                    at: skin_core::Context::Frame(i),
                    source: Box::new(e),
                }
            })
        })
        .collect::<Result<Vec<_>>>()?;
    HeightCalibration::new(tables)
}

/// The baseline: the analytic solution under the distant-light assumption. For lights at
/// infinity covering the whole sphere uniformly, `I_X − I_X̄ ∝ ρ n_x` exactly (the
/// symmetric part of `max(n·ω, 0)` cancels), so `n = k/‖k‖` in the world axes of the
/// patterns, here rotated to the camera frame. It ignores the dome's missing lower third,
/// the floor lights and their finite distance, which the calibration spheres capture.
///
/// # Errors
/// [`Error::SizeMismatch`] for images not of the camera's size; a bad exposure.
pub fn distant_light_normals(
    camera: &Camera,
    images: &PatternImages,
    exposure: &Exposure,
) -> Result<NormalMap> {
    exposure.validate()?;
    let k = &camera.intrinsics;
    if (images.width(), images.height()) != (k.width, k.height) {
        return Err(Error::SizeMismatch {
            what: "pattern images vs camera pixels",
            expected: (k.width * k.height) as usize,
            got: (images.width() * images.height()) as usize,
        });
    }
    let cam_from_world = camera.camera_from_world();
    let n = (k.width * k.height) as usize;
    let normals: Vec<Option<DVec3>> = (0..n)
        .map(|i| {
            let inten = images.pixel(i);
            let brightest = inten.iter().copied().fold(f32::MIN, f32::max);
            if !exposure.trusted(inten[3], brightest) {
                return None;
            }
            key(&inten)
                .try_normalize()
                .map(|nw| cam_from_world.transform_vector3(nw))
        })
        .collect();
    Ok(NormalMap {
        width: k.width,
        height: k.height,
        valid: normals.iter().map(Option::is_some).collect(),
        normals: normals.into_iter().map(Option::unwrap_or_default).collect(),
    })
}

/// Angle between the estimated and the true camera-frame normal per pixel, degrees; `None`
/// where the estimate is invalid or there is no truth (background).
///
/// # Errors
/// [`Error::SizeMismatch`] for a truth image of another size.
pub fn angular_errors_deg(
    estimate: &NormalMap,
    truth_normals: &Rgb32FImage,
) -> Result<Vec<Option<f64>>> {
    let n = estimate.normals.len();
    let got = (truth_normals.width() * truth_normals.height()) as usize;
    if got != n {
        return Err(Error::SizeMismatch {
            what: "true normals vs normal map pixels",
            expected: n,
            got,
        });
    }
    Ok(truth_normals
        .pixels()
        .zip(estimate.normals.iter().zip(&estimate.valid))
        .map(|(t, (e, &v))| {
            let t = DVec3::new(f64::from(t[0]), f64::from(t[1]), f64::from(t[2]));
            let t = t.try_normalize()?;
            v.then(|| e.dot(t).clamp(-1.0, 1.0).acos().to_degrees())
        })
        .collect())
}

/// Median and mean of angular errors over a region.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct NormalErrors {
    /// Median angular error, degrees (NaN without pixels).
    pub median_deg: f64,
    /// Mean angular error, degrees (NaN without pixels).
    pub mean_deg: f64,
    /// Pixels with an error (valid estimate and a truth) in the region.
    pub pixels: usize,
}

/// [`NormalErrors`] of the pixels with `region[i]` (all when `None`).
pub fn summarize(errors: &[Option<f64>], region: Option<&[bool]>) -> NormalErrors {
    let e: Vec<f64> = errors
        .iter()
        .enumerate()
        .filter(|(i, _)| region.is_none_or(|r| r.get(*i).copied().unwrap_or(false)))
        .filter_map(|(_, e)| *e)
        .collect();
    NormalErrors {
        median_deg: if e.is_empty() { f64::NAN } else { median(&e) },
        mean_deg: if e.is_empty() { f64::NAN } else { mean(&e) },
        pixels: e.len(),
    }
}

/// A [`RenderedView`] with the triangle and barycentric buffers of a view's truth (what
/// shading reads).
fn view_of(view: &ViewTruth) -> Result<RenderedView> {
    let (Some(tri), Some(bary)) = (&view.triangle_ids, &view.barycentric) else {
        return Err(Error::Empty {
            what: "triangle/barycentric truth of the view (render with Buffers::triangle and \
                   Buffers::barycentric)",
        });
    };
    Ok(RenderedView {
        width: tri.width(),
        height: tri.height(),
        triangle: tri.as_raw().clone(),
        bary: bary.as_raw().chunks(2).map(|c| [c[0], c[1]]).collect(),
        covered_pixels: view.covered_pixels,
        ..RenderedView::default()
    })
}

/// Per pixel, the fraction of its unoccluded dome irradiance that reaches it with cast
/// shadows (1 unshadowed; NaN on background): the "shadowed concavities" are the
/// pixels below 0.9. `mesh` is the mesh the camera saw ([`skin_core::studio::FrameTruth`]),
/// `visibility` the frame's ([`skin_core::studio::CaptureFrame::light_visibility`]).
///
/// # Errors
/// [`Error::Empty`] without triangle/barycentric truth; shading errors (e.g. a visibility of
/// another mesh or light set).
pub fn dome_power_fraction(
    view: &ViewTruth,
    mesh: &TriMesh,
    lights: &[Light],
    visibility: &LightVisibility,
) -> Result<Vec<f32>> {
    let v = view_of(view)?;
    let white = Albedo::Uniform([1.0; 3]);
    let lit = shade(&v, mesh, lights, &white, &Shadows::PerVertex(visibility))?;
    let open = shade(&v, mesh, lights, &white, &Shadows::None)?;
    Ok(lit
        .radiance
        .iter()
        .zip(&open.radiance)
        .zip(&v.triangle)
        .map(|((a, b), &t)| {
            if t == skin_core::raster::NO_TRIANGLE || b[0] <= 0.0 {
                f32::NAN
            } else {
                a[0] / b[0]
            }
        })
        .collect())
}

/// Pixels whose visible face of the fine surface has a vertex displaced by the wrinkles by
/// more than `min_m` metres: the wrinkled regions.
///
/// # Errors
/// [`Error::Empty`] without a triangle-id truth.
pub fn wrinkle_pixels(view: &ViewTruth, fine: &FineSurface, min_m: f64) -> Result<Vec<bool>> {
    let tri = view.triangle_ids.as_ref().ok_or(Error::Empty {
        what: "triangle-id truth of the view",
    })?;
    Ok(tri
        .as_raw()
        .iter()
        .map(|&t| {
            fine.mesh.faces.get(t as usize).is_some_and(|f| {
                f.iter().any(|&v| {
                    fine.wrinkle_displacement
                        .get(v as usize)
                        .is_some_and(|d| d.length() > min_m)
                })
            })
        })
        .collect())
}
