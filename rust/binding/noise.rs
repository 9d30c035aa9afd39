//! Python wrappers of the 3-D noise pass (`crate::noise`): `noise_sums_array`,
//! `noise_sums_paths` and the `NoiseSums` class. Passes run with the GIL released.

use std::path::PathBuf;

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArrayDescrMethods, PyReadonlyArrayDyn, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};

use super::dtypes::{contiguous, unsupported_dtype};
use super::{args, detached};
use crate::budget;
use crate::io::{self, DecodeOptions};
use crate::noise::{self, FrameSample, NoiseSums, PassOptions, Window, PARTS};
use crate::Error;

/// Sufficient statistics of a recording for the 3-D noise decomposition (see
/// `irfidelity.noise` for the public face). Mergeable and serialisable.
#[pyclass(module = "irfidelity._core", name = "NoiseSums", frozen)]
pub struct PyNoiseSums {
    inner: NoiseSums,
}

fn to_array2<'py>(py: Python<'py>, v: Vec<f64>, shape: (usize, usize)) -> PyResult<Bound<'py, PyAny>> {
    Ok(Array2::from_shape_vec(shape, v)
        .map_err(|e| crate::Error::Value(format!("internal: bad map shape: {e}")))?
        .into_pyarray(py)
        .into_any())
}

#[pymethods]
impl PyNoiseSums {
    #[getter]
    fn frames(&self) -> usize {
        self.inner.frames
    }
    #[getter]
    fn rows(&self) -> usize {
        self.inner.rows
    }
    #[getter]
    fn cols(&self) -> usize {
        self.inner.cols
    }
    #[getter]
    fn dtype(&self) -> &'static str {
        self.inner.dtype.name()
    }
    /// `{"mean", "ss": {part: float}, "ss_total"}`: sums of squares of the seven parts.
    fn decomposition<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = detached(py, || budget::guard("the 3-D noise decomposition", Error::Value, || self.inner.finish()))?;
        let out = PyDict::new(py);
        out.set_item("mean", d.mean)?;
        let ss = PyDict::new(py);
        for (name, v) in PARTS.iter().zip(d.ss) {
            ss.set_item(*name, v)?;
        }
        out.set_item("ss", ss)?;
        out.set_item("ss_total", d.ss_total)?;
        Ok(out)
    }
    /// Integer frames: `{part: N²·SS, ..., "total": N²·SS_total}` as exact Python ints; None
    /// for float frames.
    fn exact_ss<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let d = detached(py, || budget::guard("the 3-D noise decomposition", Error::Value, || self.inner.finish()))?;
        let Some(exact) = d.exact else { return Ok(None) };
        let from_bytes = py.import("builtins")?.getattr("int")?.getattr("from_bytes")?;
        let out = PyDict::new(py);
        for (name, v) in PARTS.iter().chain(["total"].iter()).zip(exact) {
            out.set_item(*name, from_bytes.call1((PyBytes::new(py, &v.to_le_bytes()), "little"))?)?;
        }
        Ok(Some(out))
    }
    /// Per-pixel temporal mean, shape (rows, cols).
    fn pixel_mean<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let v =
            detached(py, || budget::guard("the temporal-mean frame", Error::Value, || Ok(self.inner.pixel_mean())))?;
        to_array2(py, v, (self.inner.rows, self.inner.cols))
    }
    /// Per-pixel temporal population variance, shape (rows, cols).
    fn pixel_var<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let v =
            detached(py, || budget::guard("the temporal-variance frame", Error::Value, || Ok(self.inner.pixel_var())))?;
        to_array2(py, v, (self.inner.rows, self.inner.cols))
    }
    /// Mean of every row of every frame, shape (frames, rows).
    fn row_means<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let v = detached(py, || Ok(self.inner.row_means()))?;
        to_array2(py, v, (self.inner.frames, self.inner.rows))
    }
    /// Mean of every column of every frame, shape (frames, cols).
    fn col_means<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let v = detached(py, || Ok(self.inner.col_means()))?;
        to_array2(py, v, (self.inner.frames, self.inner.cols))
    }
    /// `{"min", "max"}` and for integer frames `{"lo", "hi", "at_lo", "at_hi"}`.
    fn value_range<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let r = self.inner.value_range();
        let out = PyDict::new(py);
        out.set_item("min", r.min)?;
        out.set_item("max", r.max)?;
        if let Some(c) = r.clipped {
            out.set_item("lo", c.lo)?;
            out.set_item("hi", c.hi)?;
            out.set_item("at_lo", c.at_lo)?;
            out.set_item("at_hi", c.at_hi)?;
        }
        Ok(out)
    }
    /// The sums of `self`'s frames followed by `other`'s.
    fn merge(&self, py: Python<'_>, other: &PyNoiseSums) -> PyResult<PyNoiseSums> {
        let (a, b) = (&self.inner, &other.inner);
        Ok(PyNoiseSums { inner: detached(py, || a.merge(b))? })
    }
    fn to_bytes<'py>(&self, py: Python<'py>) -> Bound<'py, PyBytes> {
        PyBytes::new(py, &self.inner.to_bytes())
    }
    #[staticmethod]
    fn from_bytes(py: Python<'_>, data: &[u8]) -> PyResult<PyNoiseSums> {
        Ok(PyNoiseSums { inner: detached(py, || NoiseSums::from_bytes(data))? })
    }
}

fn pass_options(
    limits: Option<(i64, i64)>,
    window: Option<(usize, usize, usize, usize)>,
    workers: usize,
    max_bytes: Option<u64>,
) -> PassOptions {
    let window = window.map(|(row0, col0, rows, cols)| Window { row0, col0, rows, cols });
    PassOptions { workers, limits, window, max_bytes }
}

/// `noise_sums_array(cube, *, limits=None, window=None, workers=0, max_bytes=None)`: one
/// pass over a C-contiguous `(frames, rows, cols)` array of a supported dtype. `limits=(lo,
/// hi)` is the valid range of integer samples; `window=(row0, col0, rows, cols)` a region;
/// `max_bytes` the pass's memory budget (the cube itself is the caller's and not counted).
#[pyfunction]
#[pyo3(signature = (cube, *, limits=None, window=None, workers=0, max_bytes=None))]
fn noise_sums_array(
    py: Python<'_>,
    cube: &Bound<'_, PyUntypedArray>,
    limits: Option<(i64, i64)>,
    window: Option<(usize, usize, usize, usize)>,
    #[pyo3(from_py_with = args::workers)] workers: usize,
    #[pyo3(from_py_with = args::max_bytes)] max_bytes: Option<u64>,
) -> PyResult<PyNoiseSums> {
    if cube.ndim() != 3 || !cube.is_c_contiguous() {
        return Err(crate::Error::Value("internal: the cube must be a C-contiguous 3-D array".into()).into());
    }
    let (frames, rows, cols) = (cube.shape()[0], cube.shape()[1], cube.shape()[2]);
    let opts = pass_options(limits, window, workers, max_bytes);
    let dt = cube.dtype();
    let pass = with_frame_dtype!(py, &dt, |T| {
        let arr = cube.extract::<PyReadonlyArrayDyn<'_, T>>()?;
        let data = contiguous(&arr, "the cube")?;
        detached(py, || noise::noise_sums_from_array(T::samples(data), frames, rows, cols, &opts))?
    });
    match pass {
        Some(sums) => Ok(PyNoiseSums { inner: sums }),
        None => Err(unsupported_dtype("the cube", dt).into()),
    }
}

/// `noise_sums_paths(paths, pages, *, channel=None, max_pixels=None, max_bytes=None,
/// limits=None, window=None, workers=0)`: one pass over frames decoded from files
/// (`pages[i]` of `paths[i]`), on `workers` threads with the GIL released. `max_bytes` is the
/// pass's memory budget, the frames decoded included (each decode within it too).
#[pyfunction]
#[pyo3(signature = (paths, pages, *, channel=None, max_pixels=None, max_bytes=None, limits=None, window=None,
                    workers=0))]
#[allow(clippy::too_many_arguments)]
fn noise_sums_paths(
    py: Python<'_>,
    paths: Vec<PathBuf>,
    pages: Vec<usize>,
    channel: Option<String>,
    #[pyo3(from_py_with = args::max_pixels)] max_pixels: Option<u64>,
    #[pyo3(from_py_with = args::max_bytes)] max_bytes: Option<u64>,
    limits: Option<(i64, i64)>,
    window: Option<(usize, usize, usize, usize)>,
    #[pyo3(from_py_with = args::workers)] workers: usize,
) -> PyResult<PyNoiseSums> {
    if paths.len() != pages.len() {
        return Err(crate::Error::Value(format!("{} paths but {} pages", paths.len(), pages.len())).into());
    }
    let frames: Vec<(PathBuf, usize)> = paths.into_iter().zip(pages).collect();
    let opts = pass_options(limits, window, workers, max_bytes);
    let decode = DecodeOptions {
        channel,
        max_pixels: max_pixels.unwrap_or(io::DEFAULT_MAX_PIXELS),
        max_bytes: max_bytes.unwrap_or(io::DEFAULT_MAX_BYTES),
        page: 0,
    };
    let sums = detached(py, || noise::noise_sums_from_paths(frames, &decode, &opts))?;
    Ok(PyNoiseSums { inner: sums })
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyNoiseSums>()?;
    m.add_function(wrap_pyfunction!(noise_sums_array, m)?)?;
    m.add_function(wrap_pyfunction!(noise_sums_paths, m)?)?;
    Ok(())
}
