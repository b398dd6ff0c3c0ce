//! photometric-normals (Vlasic 2010 §3.2–3.3): normal maps from the half-on patterns, their
//! integration into depth, the two-pass reconstruction of a frame.

use glam::DVec3;
use numpy::ndarray::{ArrayViewD, Axis};
use numpy::{PyArray2, PyArray3};
use photometric_normals::{
    estimate_normals as rust_normals, integrate_normals as rust_integrate,
    reconstruct as rust_reconstruct, CalibrationParams, CalibrationSphere, DepthMap, Exposure,
    HeightCalibration, IntegrationParams, LookupTable, NormalMap, NormalParams, PatternImages,
    PolygonalHull, ReconstructParams, PATTERNS,
};
use pyo3::prelude::*;
use pyo3::types::PyTuple;
use skin_core::image::{GrayF32Image, Mask};

use crate::arrays::{finite, owned2, owned3, view};
use crate::core::{mesh_arrays, Camera};
use crate::errors::{invalid, to_py};

/// The seven pattern images `(7, h, w)` float64 in the order X, Y, Z, Full, X̄, Ȳ, Z̄ (Eq.
/// 3.1), linear intensities.
fn pattern_images(images: &Bound<'_, PyAny>) -> PyResult<PatternImages> {
    // NaN and infinity are refused by `PatternImages::new`.
    let v = view::<f64>(
        images,
        "images",
        "float64",
        &[Some(PATTERNS.len()), None, None],
    )?;
    let a = v.as_array();
    let (h, w) = (a.shape()[1], a.shape()[2]);
    let (hu, wu) = (
        u32::try_from(h).map_err(|_| invalid("images: height too large"))?,
        u32::try_from(w).map_err(|_| invalid("images: width too large"))?,
    );
    // Stored as f32, the library's image type (the values are rounded to f32); a contiguous
    // array is read as one slice, a strided one element by element.
    let flat: Vec<f32> = match v.as_slice() {
        Ok(s) => s.iter().map(|&x| x as f32).collect(),
        Err(_) => a.iter().map(|&x| x as f32).collect(),
    };
    let list = PATTERNS
        .iter()
        .zip(flat.chunks_exact(h * w))
        .map(|(&p, chunk)| {
            GrayF32Image::from_raw(wu, hu, chunk.to_vec())
                .map(|im| (p, im))
                .ok_or_else(|| invalid("images: size does not match its shape"))
        })
        .collect::<PyResult<Vec<_>>>()?;
    PatternImages::new(list).map_err(to_py)
}

/// The seven pattern images of one view, converted once (to reuse with several calls).
#[pyclass(module = "dynamic_shapes.photometric", frozen, name = "PatternImages")]
pub(crate) struct Patterns {
    inner: PatternImages,
}

#[pymethods]
impl Patterns {
    /// From `(7, h, w)` float64 images in the order X, Y, Z, Full, X̄, Ȳ, Z̄ (Eq. 3.1).
    #[new]
    fn new(images: &Bound<'_, PyAny>) -> PyResult<Self> {
        Ok(Patterns {
            inner: pattern_images(images)?,
        })
    }

    /// `(height, width)` of the images, px.
    #[getter]
    fn shape(&self) -> (u32, u32) {
        (self.inner.height(), self.inner.width())
    }
}

/// Runs `f` on the pattern images given as a [`Patterns`] or as a `(7, h, w)` array.
fn with_images<T>(
    images: &Bound<'_, PyAny>,
    f: impl FnOnce(&PatternImages) -> PyResult<T>,
) -> PyResult<T> {
    match images.cast::<Patterns>() {
        Ok(p) => f(&p.get().inner),
        Err(_) => f(&pattern_images(images)?),
    }
}

fn one_mask(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Mask> {
    let (_, mut m) = crate::arrays::masks(obj, name, 0)?;
    m.pop().ok_or_else(|| invalid(format!("{name}: no mask")))
}

/// A photometric calibration: per height, the grey sphere's lookup table (§3.2.3).
#[pyclass(module = "dynamic_shapes.photometric", frozen)]
pub(crate) struct Calibration {
    pub(crate) inner: HeightCalibration,
}

#[pymethods]
impl Calibration {
    fn __repr__(&self) -> String {
        "Calibration(grey-sphere lookup)".to_string()
    }
}

/// Calibrates a camera from a grey sphere (centre in m, radius in m) photographed under the
/// seven patterns `images` (`(7, h, w)` float64 or a `PatternImages`); `up` is the world's up
/// direction.
#[pyfunction]
#[pyo3(signature = (camera, centre, radius_m, images, up = (0.0, 1.0, 0.0)))]
fn calibrate_sphere(
    py: Python<'_>,
    camera: &Camera,
    centre: (f64, f64, f64),
    radius_m: f64,
    images: &Bound<'_, PyAny>,
    up: (f64, f64, f64),
) -> PyResult<Calibration> {
    let sphere = CalibrationSphere {
        centre: DVec3::new(centre.0, centre.1, centre.2),
        radius_m,
    };
    let up = DVec3::new(up.0, up.1, up.2);
    let inner = with_images(images, |images| {
        py.detach(|| -> photometric_normals::Result<HeightCalibration> {
            let table = LookupTable::from_sphere(
                &camera.inner,
                &sphere,
                images,
                up,
                &CalibrationParams::default(),
            )?;
            HeightCalibration::new(vec![table])
        })
        .map_err(to_py)
    })?;
    Ok(Calibration { inner })
}

/// Calibrates a camera from grey spheres at several heights (§3.2.3): `centres` (m, one per
/// sphere) of radius `radius_m`, photographed under the seven patterns `images` `(spheres, 7,
/// h, w)` float64; `up` is the world's up direction. The keywords are `CalibrationParams`'
/// fields with their defaults: the exposure (`white_level`, `min_normalised`,
/// `max_normalised`), `rim_fraction` and `min_samples`.
#[pyfunction]
#[pyo3(signature = (camera, centres, radius_m, images, up = (0.0, 1.0, 0.0), *, white_level = 1.0,
    min_normalised = 0.03, max_normalised = 0.97, rim_fraction = 0.97, min_samples = 50))]
#[allow(clippy::too_many_arguments)]
fn calibrate_spheres(
    py: Python<'_>,
    camera: &Camera,
    centres: Vec<(f64, f64, f64)>,
    radius_m: f64,
    images: &Bound<'_, PyAny>,
    up: (f64, f64, f64),
    white_level: f32,
    min_normalised: f32,
    max_normalised: f32,
    rim_fraction: f64,
    min_samples: usize,
) -> PyResult<Calibration> {
    let v = view::<f64>(
        images,
        "images",
        "float64",
        &[Some(centres.len()), Some(PATTERNS.len()), None, None],
    )?;
    let a = v.as_array();
    let per = (0..centres.len())
        .map(|i| {
            let one = a.index_axis(Axis(0), i).to_owned();
            let arr = numpy::PyArray::from_owned_array(py, one);
            pattern_images(arr.as_any())
        })
        .collect::<PyResult<Vec<_>>>()?;
    let params = CalibrationParams {
        exposure: Exposure {
            white_level,
            min_normalised,
            max_normalised,
        },
        rim_fraction,
        min_samples,
    };
    let up = DVec3::new(up.0, up.1, up.2);
    let inner = py
        .detach(|| -> photometric_normals::Result<HeightCalibration> {
            let tables = centres
                .iter()
                .zip(&per)
                .map(|(c, im)| {
                    let sphere = CalibrationSphere {
                        centre: DVec3::new(c.0, c.1, c.2),
                        radius_m,
                    };
                    LookupTable::from_sphere(&camera.inner, &sphere, im, up, &params)
                })
                .collect::<photometric_normals::Result<Vec<_>>>()?;
            HeightCalibration::new(tables)
        })
        .map_err(to_py)?;
    Ok(Calibration { inner })
}

/// Per-pixel normals from the seven pattern images (§3.2; `(7, h, w)` float64 or a
/// `PatternImages`, converted once for repeated calls): `(normals, valid)`,
/// `(h, w, 3)` unit normals in the camera frame (x right, y down, z forward; zero where
/// invalid) and an `(h, w)` uint8 mask of the pixels with a normal.
/// `mask` `(h, w)` uint8 limits the pixels (non-zero = subject). The keywords are
/// `NormalParams`' fields with its defaults: `n_best` (Eq. 3.2's N), the exposure
/// (`white_level`, the linear intensity of normalised 1; the trusted normalised range
/// `min_normalised`–`max_normalised`, §3.2.3), `performance_centre` (m, where a pixel's height
/// is taken) and `up`.
#[pyfunction]
#[pyo3(signature = (camera, calibration, images, mask = None, *, n_best = 8, white_level = 1.0,
    min_normalised = 0.03, max_normalised = 0.97, performance_centre = (0.0, 1.0, 0.0),
    up = (0.0, 1.0, 0.0)))]
#[allow(clippy::too_many_arguments)]
fn estimate_normals<'py>(
    py: Python<'py>,
    camera: &Camera,
    calibration: &Calibration,
    images: &Bound<'py, PyAny>,
    mask: Option<&Bound<'py, PyAny>>,
    n_best: usize,
    white_level: f32,
    min_normalised: f32,
    max_normalised: f32,
    performance_centre: (f64, f64, f64),
    up: (f64, f64, f64),
) -> PyResult<Bound<'py, PyTuple>> {
    let mask = mask.map(|m| one_mask(m, "mask")).transpose()?;
    let params = NormalParams {
        n_best,
        exposure: Exposure {
            white_level,
            min_normalised,
            max_normalised,
        },
        performance_centre: DVec3::new(
            performance_centre.0,
            performance_centre.1,
            performance_centre.2,
        ),
        up: DVec3::new(up.0, up.1, up.2),
    };
    let map = with_images(images, |images| {
        py.detach(|| {
            rust_normals(
                &camera.inner,
                &calibration.inner,
                images,
                mask.as_ref(),
                &params,
            )
        })
        .map_err(to_py)
    })?;
    normal_arrays(py, &map)
}

fn normal_arrays<'py>(py: Python<'py>, map: &NormalMap) -> PyResult<Bound<'py, PyTuple>> {
    let (w, h) = (map.width as usize, map.height as usize);
    let n: Vec<f64> = map.normals.iter().flat_map(|v| v.to_array()).collect();
    let valid: Vec<u8> = map.valid.iter().map(|&b| u8::from(b)).collect();
    PyTuple::new(
        py,
        [
            owned3(py, n, (h, w, 3)).into_any(),
            owned2(py, valid, h, w).into_any(),
        ],
    )
}

fn normal_map(normals: &Bound<'_, PyAny>, valid: &Bound<'_, PyAny>) -> PyResult<NormalMap> {
    let n = finite(normals, "normals", &[None, None, Some(3)])?;
    let a = n.as_array();
    let (h, w) = (a.shape()[0], a.shape()[1]);
    let v = view::<u8>(valid, "valid", "uint8", &[Some(h), Some(w)])?;
    normal_map_of(a, v.as_array())
}

/// A normal map from `(h, w, 3)` normals and `(h, w)` validity, both already checked.
fn normal_map_of(n: ArrayViewD<'_, f64>, v: ArrayViewD<'_, u8>) -> PyResult<NormalMap> {
    let (h, w) = (n.shape()[0], n.shape()[1]);
    let normals: Vec<DVec3> = n
        .to_shape((h * w, 3))
        .map_err(|e| invalid(format!("normals: {e}")))?
        .outer_iter()
        .map(|r| DVec3::new(r[0], r[1], r[2]))
        .collect();
    Ok(NormalMap {
        width: u32::try_from(w).map_err(|_| invalid("normals: width too large"))?,
        height: u32::try_from(h).map_err(|_| invalid("normals: height too large"))?,
        normals,
        valid: v.iter().map(|&b| b != 0).collect(),
    })
}

/// Integrates a normal map into depth along the pixel rays (Eq. 3.3) near a proxy depth map
/// `proxy_depth_m` `(h, w)` (m; NaN where the proxy has no surface). Returns the `(h, w)`
/// depth map (m, NaN outside the surface).
#[pyfunction]
fn integrate_normals<'py>(
    py: Python<'py>,
    camera: &Camera,
    normals: &Bound<'py, PyAny>,
    valid: &Bound<'py, PyAny>,
    proxy_depth_m: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let map = normal_map(normals, valid)?;
    let (h, w) = (map.height as usize, map.width as usize);
    let p = view::<f64>(
        proxy_depth_m,
        "proxy_depth_m",
        "float64",
        &[Some(h), Some(w)],
    )?;
    let depth: Vec<f64> = p.as_array().iter().copied().collect();
    let out = py
        .detach(|| -> photometric_normals::Result<DepthMap> {
            let proxy = DepthMap::new(map.width, map.height, depth)?;
            Ok(rust_integrate(
                &camera.inner,
                &map,
                &proxy,
                None,
                &IntegrationParams::default(),
            )?
            .depth)
        })
        .map_err(to_py)?;
    Ok(owned2(py, out.depth_m, h, w))
}

/// The visual hull's depth map for every camera (the proxy of §3.3.1), from `(cameras, h,
/// w)` uint8 silhouettes: `(cameras, h, w)` depths (m, NaN outside).
#[pyfunction]
fn hull_depths<'py>(
    py: Python<'py>,
    cameras: Vec<Camera>,
    masks: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray3<f64>>> {
    let (lead, cams, masks) = crate::core::views(cameras, masks, 1)?;
    let maps = py
        .detach(|| -> photometric_normals::Result<Vec<DepthMap>> {
            PolygonalHull::new(&cams, &masks)?.depth_maps(&Default::default())
        })
        .map_err(to_py)?;
    let (h, w) = maps
        .first()
        .map_or((0, 0), |m| (m.height as usize, m.width as usize));
    if maps
        .iter()
        .any(|m| (m.height as usize, m.width as usize) != (h, w))
    {
        return Err(invalid("hull_depths needs cameras of one image size"));
    }
    let flat: Vec<f64> = maps.into_iter().flat_map(|m| m.depth_m).collect();
    Ok(owned3(py, flat, (lead[0], h, w)))
}

/// The two-pass reconstruction of one frame (§3.3): visual-hull proxies from the silhouettes
/// `masks` `(cameras, h, w)`, normal integration, matching of the camera `pairs`, merging and
/// hole filling, twice. `normals` `(cameras, h, w, 3)` and `valid` `(cameras, h, w)` are the
/// views' normal maps. Returns the watertight surface `(vertices, faces)` of the second pass.
/// `poisson_depth` is the hole filling's octree depth (`ReconstructParams::poisson`; 9 ≈ 4 mm
/// cells).
#[pyfunction]
#[pyo3(signature = (cameras, masks, normals, valid, pairs, *, poisson_depth = 9))]
fn reconstruct<'py>(
    py: Python<'py>,
    cameras: Vec<Camera>,
    masks: &Bound<'py, PyAny>,
    normals: &Bound<'py, PyAny>,
    valid: &Bound<'py, PyAny>,
    pairs: Vec<(usize, usize)>,
    poisson_depth: u32,
) -> PyResult<Bound<'py, PyTuple>> {
    let (_, cams, masks) = crate::core::views(cameras, masks, 1)?;
    let n = finite(normals, "normals", &[Some(cams.len()), None, None, Some(3)])?;
    let (h, w) = (n.as_array().shape()[1], n.as_array().shape()[2]);
    let v = view::<u8>(
        valid,
        "valid",
        "uint8",
        &[Some(cams.len()), Some(h), Some(w)],
    )?;
    let (na, va) = (n.as_array(), v.as_array());
    let maps = (0..cams.len())
        .map(|c| normal_map_of(na.index_axis(Axis(0), c), va.index_axis(Axis(0), c)))
        .collect::<PyResult<Vec<NormalMap>>>()?;
    let mesh = py
        .detach(|| -> photometric_normals::Result<_> {
            let hull = PolygonalHull::new(&cams, &masks)?;
            Ok(rust_reconstruct(
                &cams,
                &maps,
                &hull,
                &pairs,
                &ReconstructParams::default().with_poisson_depth(poisson_depth),
            )?
            .pass2
            .filled
            .mesh)
        })
        .map_err(to_py)?;
    mesh_arrays(py, &mesh)
}

pub(crate) fn register(parent: &Bound<'_, PyModule>) -> PyResult<()> {
    let m = PyModule::new(parent.py(), "photometric")?;
    m.add_class::<Calibration>()?;
    m.add_class::<Patterns>()?;
    m.add_function(wrap_pyfunction!(calibrate_sphere, &m)?)?;
    m.add_function(wrap_pyfunction!(calibrate_spheres, &m)?)?;
    m.add_function(wrap_pyfunction!(estimate_normals, &m)?)?;
    m.add_function(wrap_pyfunction!(integrate_normals, &m)?)?;
    m.add_function(wrap_pyfunction!(hull_depths, &m)?)?;
    m.add_function(wrap_pyfunction!(reconstruct, &m)?)?;
    parent.add_submodule(&m)
}
