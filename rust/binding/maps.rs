//! Python wrappers of the SSIM map and MS-SSIM kernels (`crate::maps`). Frames arrive 2-D and
//! C-contiguous (the Python layer, `irfidelity.maps`, decides the layout and the peak); the
//! kernels run with the GIL released.

use numpy::ndarray::Array2;
use numpy::{PyArray2, PyArrayDescrMethods, PyReadonlyArrayDyn, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::prelude::*;

use super::dtypes::pair_shape;
use super::register::nbytes;
use super::{args, detached};
use crate::maps::{self, SsimParams};
use crate::Error;

/// `run` on both frames as slices of `T`, or `None` when either is not a readable `T` array.
fn on_slices<T: numpy::Element, R>(
    real: &Bound<'_, PyUntypedArray>,
    sim: &Bound<'_, PyUntypedArray>,
    run: impl FnOnce(&[T], &[T]) -> PyResult<R>,
) -> Option<PyResult<R>> {
    let (Ok(ra), Ok(sa)) = (real.extract::<PyReadonlyArrayDyn<T>>(), sim.extract::<PyReadonlyArrayDyn<T>>()) else {
        return None;
    };
    Some(contiguous(&ra).and_then(|r| run(r, contiguous(&sa)?)))
}

fn contiguous<'a, T: numpy::Element>(a: &'a PyReadonlyArrayDyn<'_, T>) -> PyResult<&'a [T]> {
    a.as_slice().map_err(|_| {
        crate::Error::Value("internal: frames must be C-contiguous (the Python layer copies them)".into()).into()
    })
}

fn unsupported(real: &Bound<'_, PyUntypedArray>, sim: &Bound<'_, PyUntypedArray>) -> PyErr {
    PyErr::from(crate::Error::Shape(format!(
        "unsupported frame dtype pair ({}, {}): expected two frames of the same dtype among {}",
        real.dtype(),
        sim.dtype(),
        crate::dtype::Dtype::names()
    )))
}

/// `ssim_map(real, sim, *, peak, sigma, win_size, k1, k2, valid, step=1, max_bytes=None)`
/// -> `(map, mean)`: see `irfidelity.maps.ssim_map`. `step` keeps every `step`-th row and
/// column of the map (the mean is that of the whole map); the frames and the map kept must
/// fit `max_bytes`.
#[pyfunction]
#[pyo3(signature = (real, sim, *, peak, sigma, win_size, k1, k2, valid=None, step=1, max_bytes=None))]
#[allow(clippy::too_many_arguments)]
fn ssim_map<'py>(
    py: Python<'py>,
    real: &Bound<'py, PyUntypedArray>,
    sim: &Bound<'py, PyUntypedArray>,
    peak: f64,
    sigma: f64,
    win_size: usize,
    k1: f64,
    k2: f64,
    valid: Option<(i64, i64)>,
    step: usize,
    #[pyo3(from_py_with = args::max_bytes)] max_bytes: Option<u64>,
) -> PyResult<(Bound<'py, PyArray2<f64>>, f64)> {
    let (rows, cols) = pair_shape(real, sim)?;
    let params = SsimParams { sigma, win_size, k1, k2, peak };
    params.check()?;
    maps::ssim_map_plan((rows, cols), &params, step)
        .holding(nbytes(&[real, sim]))
        .check(max_bytes.unwrap_or(crate::io::DEFAULT_MAX_BYTES), Error::Value)?;
    let finish = |m: maps::SsimMap| -> PyResult<(Bound<'py, PyArray2<f64>>, f64)> {
        let map = Array2::from_shape_vec((m.rows, m.cols), m.map)
            .map_err(|e| crate::Error::Value(format!("internal: map shape: {e}")))?;
        Ok((PyArray2::from_owned_array(py, map), m.mean))
    };
    with_frame_dtype!(py, real.dtype(), |T| on_slices::<T, _>(real, sim, |r, s| {
        finish(detached(py, || maps::ssim_map(r, s, rows, cols, &params, valid, step))?)
    }))
    .flatten()
    .unwrap_or_else(|| Err(unsupported(real, sim)))
}

/// `ms_ssim(real, sim, *, peak, sigma, win_size, k1, k2, valid, scales, max_bytes=None)` ->
/// `(value, weights, ssim per scale, cs per scale)`: see `irfidelity.maps.ms_ssim`. The
/// frames and the coarser scales must fit `max_bytes`.
#[pyfunction]
#[pyo3(signature = (real, sim, *, peak, sigma, win_size, k1, k2, valid=None, scales=None, max_bytes=None))]
#[allow(clippy::too_many_arguments)]
#[allow(clippy::type_complexity)]
fn ms_ssim(
    py: Python<'_>,
    real: &Bound<'_, PyUntypedArray>,
    sim: &Bound<'_, PyUntypedArray>,
    peak: f64,
    sigma: f64,
    win_size: usize,
    k1: f64,
    k2: f64,
    valid: Option<(i64, i64)>,
    scales: Option<usize>,
    #[pyo3(from_py_with = args::max_bytes)] max_bytes: Option<u64>,
) -> PyResult<(f64, Vec<f64>, Vec<f64>, Vec<f64>)> {
    let (rows, cols) = pair_shape(real, sim)?;
    let params = SsimParams { sigma, win_size, k1, k2, peak };
    params.check()?;
    maps::ms_ssim_plan((rows, cols), &params)
        .holding(nbytes(&[real, sim]))
        .check(max_bytes.unwrap_or(crate::io::DEFAULT_MAX_BYTES), Error::Value)?;
    with_frame_dtype!(py, real.dtype(), |T| on_slices::<T, _>(real, sim, |r, s| {
        let m = detached(py, || maps::ms_ssim(r, s, rows, cols, &params, valid, scales))?;
        Ok((m.value, m.weights, m.ssim, m.cs))
    }))
    .flatten()
    .unwrap_or_else(|| Err(unsupported(real, sim)))
}

/// `max_scales(rows, cols, win_size)`: see `crate::maps::max_scales`.
#[pyfunction]
fn max_scales(rows: usize, cols: usize, win_size: usize) -> usize {
    maps::max_scales(rows, cols, win_size)
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(ssim_map, m)?)?;
    m.add_function(wrap_pyfunction!(ms_ssim, m)?)?;
    m.add_function(wrap_pyfunction!(max_scales, m)?)?;
    m.add("MS_SSIM_WEIGHTS", maps::MS_SSIM_WEIGHTS.to_vec())?;
    Ok(())
}
