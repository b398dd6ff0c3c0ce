//! NumPy arrays in and out.
//!
//! Inputs: a `float64` (or `uint8`, `uint32`) array of the documented shape; anything else is
//! a `TypeError` (not an array, wrong dtype) or an `InvalidInputError` (wrong shape, NaN or
//! infinity). Inputs are read in place, whatever their strides. Outputs are built in Rust and
//! handed to NumPy without a copy: the array owns the Rust buffer (`PyArray::from_owned_array`).

use glam::{DAffine3, DMat3, DVec2, DVec3};
use numpy::ndarray::{Array1, Array2, Array3, ArrayViewD};
use numpy::{
    dtype, Element, PyArray1, PyArray2, PyArray3, PyArrayDescrMethods, PyArrayDyn, PyArrayMethods,
    PyUntypedArray, PyUntypedArrayMethods,
};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;

use crate::errors::invalid;

/// The shape an input must have: `None` for any length along that axis.
pub(crate) type Shape<'a> = &'a [Option<usize>];

fn shape_text(shape: Shape<'_>) -> String {
    let mut names = ["n", "m", "k", "l", "p"].iter().cycle();
    let parts: Vec<String> = shape
        .iter()
        .map(|s| match s {
            Some(n) => n.to_string(),
            None => names.next().map_or("?", |n| n).to_string(),
        })
        .collect();
    if parts.len() == 1 {
        format!("({},)", parts[0])
    } else {
        format!("({})", parts.join(", "))
    }
}

/// A checked read-only view of `obj` as an array of `T` with `shape`.
pub(crate) fn view<'py, T: Element>(
    obj: &Bound<'py, PyAny>,
    name: &str,
    type_name: &str,
    shape: Shape<'_>,
) -> PyResult<numpy::PyReadonlyArrayDyn<'py, T>> {
    let py = obj.py();
    let untyped = obj.cast::<PyUntypedArray>().map_err(|_| {
        let got = obj
            .get_type()
            .name()
            .map(|n| n.to_string())
            .unwrap_or_else(|_| "?".into());
        PyTypeError::new_err(format!(
            "{name} must be a NumPy array of {type_name} with shape {}, got {got}",
            shape_text(shape)
        ))
    })?;
    let d = untyped.dtype();
    if !d.is_equiv_to(&dtype::<T>(py)) {
        return Err(PyTypeError::new_err(format!(
            "{name} must have dtype {type_name}, got {d}; convert it with .astype(np.{type_name})"
        )));
    }
    let got = untyped.shape();
    let fits = got.len() == shape.len()
        && got
            .iter()
            .zip(shape)
            .all(|(g, s)| s.is_none_or(|s| s == *g));
    if !fits {
        return Err(invalid(format!(
            "{name} must have shape {}, got {got:?}",
            shape_text(shape)
        )));
    }
    Ok(untyped.cast::<PyArrayDyn<T>>()?.readonly())
}

/// A checked `float64` view whose values are all finite.
pub(crate) fn finite<'py>(
    obj: &Bound<'py, PyAny>,
    name: &str,
    shape: Shape<'_>,
) -> PyResult<numpy::PyReadonlyArrayDyn<'py, f64>> {
    let v = view::<f64>(obj, name, "float64", shape)?;
    // Contiguous arrays as one slice (iterating a dynamic-rank view is several times slower).
    let all_finite = match v.as_slice() {
        Ok(s) => s.iter().all(|x| x.is_finite()),
        Err(_) => v.as_array().iter().all(|x| x.is_finite()),
    };
    if !all_finite {
        return Err(invalid(format!(
            "{name} contains NaN or infinity; give finite values"
        )));
    }
    Ok(v)
}

/// Rows of a finite `(n, 3)` array as points.
pub(crate) fn points3(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<DVec3>> {
    let v = finite(obj, name, &[None, Some(3)])?;
    Ok(match v.as_slice() {
        Ok(s) => s
            .chunks_exact(3)
            .map(|c| DVec3::new(c[0], c[1], c[2]))
            .collect(),
        Err(_) => rows3(&v.as_array()),
    })
}

pub(crate) fn rows3(a: &ArrayViewD<'_, f64>) -> Vec<DVec3> {
    a.outer_iter()
        .map(|r| DVec3::new(r[0], r[1], r[2]))
        .collect()
}

/// Rows of a finite `(n, 2)` array as 2-D points.
pub(crate) fn points2(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<DVec2>> {
    let v = finite(obj, name, &[None, Some(2)])?;
    Ok(match v.as_slice() {
        Ok(s) => s.chunks_exact(2).map(|c| DVec2::new(c[0], c[1])).collect(),
        Err(_) => v
            .as_array()
            .outer_iter()
            .map(|r| DVec2::new(r[0], r[1]))
            .collect(),
    })
}

/// A finite `(n,)` array as a vector.
pub(crate) fn vector(obj: &Bound<'_, PyAny>, name: &str, len: Option<usize>) -> PyResult<Vec<f64>> {
    let v = finite(obj, name, &[len])?;
    Ok(v.as_array().iter().copied().collect())
}

/// A finite `(r, c)` array, row by row.
pub(crate) fn matrix_rows(
    obj: &Bound<'_, PyAny>,
    name: &str,
    cols: Option<usize>,
) -> PyResult<Vec<Vec<f64>>> {
    let v = finite(obj, name, &[None, cols])?;
    Ok(v.as_array()
        .outer_iter()
        .map(|r| r.iter().copied().collect())
        .collect())
}

/// A finite `(r, c)` array as a nalgebra matrix.
pub(crate) fn dmatrix(
    obj: &Bound<'_, PyAny>,
    name: &str,
    shape: Shape<'_>,
) -> PyResult<nalgebra::DMatrix<f64>> {
    let v = finite(obj, name, shape)?;
    let a = v.as_array();
    let (r, c) = (a.shape()[0], a.shape()[1]);
    Ok(nalgebra::DMatrix::from_fn(r, c, |i, j| a[[i, j]]))
}

/// Triangles of an `(m, 3)` `uint32` array, each index below `vertex_count`.
pub(crate) fn faces(
    obj: &Bound<'_, PyAny>,
    name: &str,
    vertex_count: usize,
) -> PyResult<Vec<[u32; 3]>> {
    let v = view::<u32>(obj, name, "uint32", &[None, Some(3)])?;
    let out: Vec<[u32; 3]> = v
        .as_array()
        .outer_iter()
        .map(|r| [r[0], r[1], r[2]])
        .collect();
    if let Some((f, bad)) = out.iter().enumerate().find_map(|(f, t)| {
        t.iter()
            .find(|&&i| i as usize >= vertex_count)
            .map(|&i| (f, i))
    }) {
        return Err(invalid(format!(
            "{name}: face {f} has vertex index {bad}, but there are {vertex_count} vertices"
        )));
    }
    Ok(out)
}

/// A 4 × 4 rigid transform (last row 0, 0, 0, 1) as an affine map.
pub(crate) fn affine(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<DAffine3> {
    let v = finite(obj, name, &[Some(4), Some(4)])?;
    let a = v.as_array();
    let last = [a[[3, 0]], a[[3, 1]], a[[3, 2]], a[[3, 3]]];
    if last != [0.0, 0.0, 0.0, 1.0] {
        return Err(invalid(format!(
            "{name} must be a 4 × 4 rigid transform with last row [0, 0, 0, 1], got {last:?}"
        )));
    }
    let col = |j: usize| DVec3::new(a[[0, j]], a[[1, j]], a[[2, j]]);
    Ok(DAffine3::from_mat3_translation(
        DMat3::from_cols(col(0), col(1), col(2)),
        col(3),
    ))
}

/// An affine map as its 4 × 4 matrix, row-major.
pub(crate) fn affine_rows(t: &DAffine3) -> [[f64; 4]; 4] {
    let m = t.matrix3;
    let p = t.translation;
    [
        [m.x_axis.x, m.y_axis.x, m.z_axis.x, p.x],
        [m.x_axis.y, m.y_axis.y, m.z_axis.y, p.y],
        [m.x_axis.z, m.y_axis.z, m.z_axis.z, p.z],
        [0.0, 0.0, 0.0, 1.0],
    ]
}

/// `(n, 3)` from points, without a copy on the way to NumPy.
pub(crate) fn from_points3<'py>(py: Python<'py>, p: &[DVec3]) -> Bound<'py, PyArray2<f64>> {
    from_rows(py, p.iter().map(|v| v.to_array()), p.len())
}

/// `(n, 2)` from 2-D points.
pub(crate) fn from_points2<'py>(py: Python<'py>, p: &[DVec2]) -> Bound<'py, PyArray2<f64>> {
    from_rows(py, p.iter().map(|v| v.to_array()), p.len())
}

/// `(n, C)` from fixed-size rows.
pub(crate) fn from_rows<'py, T: Element + Copy, const C: usize>(
    py: Python<'py>,
    rows: impl Iterator<Item = [T; C]>,
    n: usize,
) -> Bound<'py, PyArray2<T>> {
    let mut flat = Vec::with_capacity(n * C);
    rows.for_each(|r| flat.extend_from_slice(&r));
    owned2(py, flat, n, C)
}

/// `(rows, cols)` from a row-major buffer, moved into NumPy.
pub(crate) fn owned2<T: Element>(
    py: Python<'_>,
    flat: Vec<T>,
    rows: usize,
    cols: usize,
) -> Bound<'_, PyArray2<T>> {
    match Array2::from_shape_vec((rows, cols), flat) {
        Ok(a) => PyArray2::from_owned_array(py, a),
        // Unreachable: every caller passes rows · cols values.
        Err(_) => PyArray2::zeros(py, (rows, cols), false),
    }
}

/// `(a, b, c)` from a row-major buffer, moved into NumPy.
pub(crate) fn owned3<T: Element>(
    py: Python<'_>,
    flat: Vec<T>,
    shape: (usize, usize, usize),
) -> Bound<'_, PyArray3<T>> {
    match Array3::from_shape_vec(shape, flat) {
        Ok(a) => PyArray3::from_owned_array(py, a),
        // Unreachable: every caller passes a · b · c values.
        Err(_) => PyArray3::zeros(py, shape, false),
    }
}

/// `(n,)` from a vector, moved into NumPy.
pub(crate) fn owned1<T: Element>(py: Python<'_>, v: Vec<T>) -> Bound<'_, PyArray1<T>> {
    PyArray1::from_owned_array(py, Array1::from_vec(v))
}

/// A nalgebra matrix as `(rows, cols)`.
pub(crate) fn from_dmatrix<'py>(
    py: Python<'py>,
    m: &nalgebra::DMatrix<f64>,
) -> Bound<'py, PyArray2<f64>> {
    let (r, c) = m.shape();
    let flat: Vec<f64> = (0..r)
        .flat_map(|i| (0..c).map(move |j| m[(i, j)]))
        .collect();
    owned2(py, flat, r, c)
}

/// `(n, k)` from rows of one length (`k` given for `n = 0`).
pub(crate) fn from_vec_rows<'py>(
    py: Python<'py>,
    rows: &[Vec<f64>],
    k: usize,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    if let Some(bad) = rows.iter().position(|r| r.len() != k) {
        return Err(invalid(format!(
            "row {bad} has {} values, expected {k}",
            rows[bad].len()
        )));
    }
    Ok(owned2(py, rows.concat(), rows.len(), k))
}

/// Masks of a `(..., h, w)` `uint8` array (non-zero = inside), in row-major order of the
/// leading axes; `leading` is the number of axes before `h, w`.
pub(crate) fn masks(
    obj: &Bound<'_, PyAny>,
    name: &str,
    leading: usize,
) -> PyResult<(Vec<usize>, Vec<skin_core::image::Mask>)> {
    let shape: Vec<Option<usize>> = vec![None; leading + 2];
    let v = view::<u8>(obj, name, "uint8", &shape)?;
    let a = v.as_array();
    let dims = a.shape().to_vec();
    let (h, w) = (dims[leading], dims[leading + 1]);
    let (hu, wu) = (
        u32::try_from(h).map_err(|_| invalid(format!("{name}: height {h} too large")))?,
        u32::try_from(w).map_err(|_| invalid(format!("{name}: width {w} too large")))?,
    );
    let count: usize = dims[..leading].iter().product();
    let flat = a
        .to_shape((count, h, w))
        .map_err(|e| invalid(format!("{name}: {e}")))?;
    let out = flat
        .outer_iter()
        .map(|m| skin_core::image::Mask::from_fn(wu, hu, |x, y| m[[y as usize, x as usize]] != 0))
        .collect();
    Ok((dims[..leading].to_vec(), out))
}
