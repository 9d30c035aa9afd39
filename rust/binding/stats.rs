//! Python wrappers of the statistics kernel: `pair_stats` and the `PairStats` class.
//! Arrays arrive contiguous (the Python layer decides the layout); the pass runs with
//! the GIL released.

use numpy::{PyArrayDescrMethods, PyReadonlyArrayDyn, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};

use super::IntoPy;
use std::sync::OnceLock;

use crate::hist::{Entropies, HistSpec, JointTable};
use crate::stats::{self, HistRequest, Request, Sums};

/// A joint histogram for Python: the int64 table and the keys of its first row and column.
type JointCounts<'py> = (Bound<'py, numpy::PyArray2<i64>>, u64, u64);

/// Sufficient statistics of a frame pair (see `irfidelity.PairStats` for the public face).
#[pyclass(module = "irfidelity._core", name = "PairStats", frozen)]
pub struct PyPairStats {
    pub(crate) inner: stats::PairStats,
    /// `inner.entropies()`, computed once (the sequence engine fills it on its worker threads).
    entropies: OnceLock<Option<Entropies>>,
}

impl PyPairStats {
    pub(crate) fn new(inner: stats::PairStats) -> Self {
        PyPairStats { inner, entropies: OnceLock::new() }
    }

    /// With the entropies already known (they must be `inner.entropies()`).
    pub(crate) fn with_entropies(inner: stats::PairStats, entropies: Option<Entropies>) -> Self {
        PyPairStats { inner, entropies: OnceLock::from(entropies) }
    }
}

#[pymethods]
impl PyPairStats {
    #[getter]
    fn n(&self) -> u64 {
        self.inner.n
    }
    #[getter]
    fn masked(&self) -> u64 {
        self.inner.masked
    }
    #[getter]
    fn nonfinite(&self) -> u64 {
        self.inner.nonfinite
    }
    #[getter]
    fn is_int(&self) -> bool {
        matches!(self.inner.sums, Sums::Int(_))
    }
    #[getter]
    fn has_sse(&self) -> bool {
        self.inner.has_sse
    }
    #[getter]
    fn has_moments(&self) -> bool {
        self.inner.has_moments
    }
    #[getter]
    fn has_hist(&self) -> bool {
        self.inner.hist.is_some()
    }
    fn sse(&self) -> Option<f64> {
        self.inner.sse()
    }
    fn mse(&self) -> Option<f64> {
        self.inner.mse()
    }
    /// `(mean_real, mean_sim, var_real, var_sim, cov)`, population moments, or None.
    fn moments(&self) -> Option<(f64, f64, f64, f64, f64)> {
        self.inner.moments().map(|m| (m.mean_real, m.mean_sim, m.var_real, m.var_sim, m.cov))
    }
    /// `(d_real, d_sim, d_cov)`: centred second sums in a common scale (exact for ints).
    fn centred(&self) -> Option<(f64, f64, f64)> {
        self.inner.centred()
    }
    /// `(h_real, h_sim, h_joint)` in bits, or None without a histogram.
    fn entropies(&self, py: Python<'_>) -> Option<(f64, f64, f64)> {
        // Not `get_or_init`: a second thread would wait on it holding the GIL, which the
        // first needs back after computing without it. Two threads may both compute (same
        // value); the first to finish keeps it.
        let e = match self.entropies.get() {
            Some(e) => *e,
            None => {
                let e = py.detach(|| self.inner.entropies());
                *self.entropies.get_or_init(|| e)
            }
        };
        e.map(|e| (e.h_real, e.h_sim, e.h_joint))
    }
    /// `("levels",)` or `("bins", bins, lo, width)`, or None.
    fn hist_spec<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        Ok(match &self.inner.hist {
            None => None,
            Some((HistSpec::Levels, _)) => Some(("levels",).into_pyobject(py)?.into_any()),
            Some((HistSpec::Binned { bins, lo, width }, _)) => {
                Some(("bins", *bins, *lo, *width).into_pyobject(py)?.into_any())
            }
        })
    }
    /// `(counts, real_first, sim_first)`: the joint histogram as a dense int64 table (see
    /// `crate::hist::JointTable`), or None without a histogram.
    fn joint_histogram<'py>(&self, py: Python<'py>, max_cells: usize) -> PyResult<Option<JointCounts<'py>>> {
        let Some((spec, joint)) = &self.inner.hist else { return Ok(None) };
        let table = py.detach(|| JointTable::of(spec, joint, max_cells)).py_err()?;
        // counts of pixels: far below 2^63
        let counts: Vec<i64> = table.counts.into_iter().map(|c| c as i64).collect();
        let counts = numpy::ndarray::Array2::from_shape_vec((table.rows, table.cols), counts)
            .map_err(|e| PyTypeError::new_err(format!("internal: joint histogram shape: {e}")))?;
        Ok(Some((numpy::PyArray2::from_owned_array(py, counts), table.real_first, table.sim_first)))
    }
    /// Exact integer sums as Python ints (integer frames), for exact references.
    fn int_sums<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Sums::Int(s) = &self.inner.sums else {
            return Ok(None);
        };
        let d = PyDict::new(py);
        d.set_item("sum_real", s.sr)?;
        d.set_item("sum_sim", s.ss)?;
        d.set_item("sum_real_sq", s.srr)?;
        d.set_item("sum_sim_sq", s.sss)?;
        d.set_item("sum_cross", s.srs)?;
        d.set_item("sse", s.sse)?;
        Ok(Some(d))
    }
    fn merge(&self, py: Python<'_>, other: &PyPairStats) -> PyResult<PyPairStats> {
        let (a, b) = (&self.inner, &other.inner);
        let merged = py.detach(|| a.merge(b)).py_err()?;
        Ok(PyPairStats::new(merged))
    }
    fn to_bytes<'py>(&self, py: Python<'py>) -> Bound<'py, PyBytes> {
        PyBytes::new(py, &self.inner.to_bytes())
    }
    #[staticmethod]
    fn from_bytes(data: &[u8]) -> PyResult<PyPairStats> {
        Ok(PyPairStats::new(stats::PairStats::from_bytes(data).py_err()?))
    }
}

/// Run the kernel on arrays of one element type.
/// (The dtype is compared first: a failed `extract` builds a Python exception, and trying
/// every type in turn cost microseconds per call on small frames.)
macro_rules! dispatch {
    ($py:expr, $real:expr, $sim:expr, $req:expr, $($t:ty),*) => {{
        let dt = $real.dtype();
        $(
            if dt.is_equiv_to(&numpy::dtype::<$t>($py)) {
                if let (Ok(r), Ok(s)) = ($real.extract::<PyReadonlyArrayDyn<$t>>(), $sim.extract::<PyReadonlyArrayDyn<$t>>()) {
                    let (rs, ss) = (slice(&r)?, slice(&s)?);
                    let req = $req;
                    return $py.detach(|| stats::pair_stats(rs, ss, &req)).py_err().map(PyPairStats::new);
                }
            }
        )*
    }};
}

fn slice<'a, T: numpy::Element>(a: &'a PyReadonlyArrayDyn<'_, T>) -> PyResult<&'a [T]> {
    a.as_slice().map_err(|_| PyTypeError::new_err("internal: frames must be contiguous (the Python layer copies them)"))
}

/// `pair_stats(real, sim, *, sse, moments, bins, levels, hist_range, mask, valid,
/// mask_nonfinite, shape, fortran)`: see `irfidelity.stats.pair_stats`.
#[pyfunction]
#[pyo3(signature = (real, sim, *, sse=true, moments=true, bins=None, levels=false, hist_range=None,
                    mask=None, valid=None, mask_nonfinite=false, shape=(0, 0), fortran=false))]
#[allow(clippy::too_many_arguments)]
fn pair_stats(
    py: Python<'_>,
    real: &Bound<'_, PyUntypedArray>,
    sim: &Bound<'_, PyUntypedArray>,
    sse: bool,
    moments: bool,
    bins: Option<usize>,
    levels: bool,
    hist_range: Option<(f64, f64)>,
    mask: Option<PyReadonlyArrayDyn<'_, bool>>,
    valid: Option<(i64, i64)>,
    mask_nonfinite: bool,
    shape: (usize, usize),
    fortran: bool,
) -> PyResult<PyPairStats> {
    let hist =
        if levels { Some(HistRequest::Levels) } else { bins.map(|b| HistRequest::Bins { bins: b, range: hist_range }) };
    let mask_slice = match &mask {
        Some(m) => Some(slice(m)?),
        None => None,
    };
    let req = Request { sse, moments, hist, mask: mask_slice, valid, mask_nonfinite, shape, fortran };
    dispatch!(py, real, sim, req.clone(), u8, u16, i16, u32, half::f16, f32, f64);
    Err(PyTypeError::new_err(format!(
        "unsupported frame dtype pair ({}, {}): expected two frames of the same dtype among \
         uint8, uint16, int16, uint32, float16, float32, float64",
        real.dtype(),
        sim.dtype()
    )))
}

/// The kernel on two non-empty 2-D C-contiguous arrays of one supported dtype and shape,
/// else `None` (the caller takes the general path, which also explains what is wrong).
/// The single-metric fast path: no keyword parsing, no Python-side checks.
fn plain_stats(
    py: Python<'_>,
    real: &Bound<'_, PyAny>,
    sim: &Bound<'_, PyAny>,
    sse: bool,
    moments: bool,
) -> PyResult<Option<PyPairStats>> {
    let (Ok(r), Ok(s)) = (real.cast::<PyUntypedArray>(), sim.cast::<PyUntypedArray>()) else { return Ok(None) };
    let plain = |a: &Bound<'_, PyUntypedArray>| a.ndim() == 2 && a.is_c_contiguous();
    if !(plain(r) && plain(s)) || r.shape() != s.shape() || r.len() == 0 || !r.dtype().is_equiv_to(&s.dtype()) {
        return Ok(None);
    }
    let shape = (r.shape()[0], r.shape()[1]);
    let req = Request { sse, moments, hist: None, shape, ..Request::default() };
    let stats = (|| -> PyResult<PyPairStats> {
        dispatch!(py, r, s, req.clone(), u8, u16, i16, u32, half::f16, f32, f64);
        Err(PyTypeError::new_err("unsupported dtype"))
    })();
    match stats {
        Ok(st) => Ok(Some(st)),
        Err(e) if e.is_instance_of::<PyTypeError>(py) => Ok(None),
        Err(e) => Err(e),
    }
}

/// `plain_mse(real, sim)`: the mean squared error of plain arrays (see `plain_stats`), or
/// `None`.
#[pyfunction]
fn plain_mse(py: Python<'_>, real: &Bound<'_, PyAny>, sim: &Bound<'_, PyAny>) -> PyResult<Option<f64>> {
    Ok(plain_stats(py, real, sim, true, false)?.and_then(|st| st.inner.mse()))
}

/// `plain_moments(real, sim)`: `PairStats` with the moments only (SSIM) of plain arrays
/// (see `plain_stats`), or `None`.
#[pyfunction]
fn plain_moments(py: Python<'_>, real: &Bound<'_, PyAny>, sim: &Bound<'_, PyAny>) -> PyResult<Option<PyPairStats>> {
    plain_stats(py, real, sim, false, true)
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(plain_mse, m)?)?;
    m.add_function(wrap_pyfunction!(plain_moments, m)?)?;
    m.add_class::<PyPairStats>()?;
    m.add_function(wrap_pyfunction!(pair_stats, m)?)?;
    Ok(())
}
