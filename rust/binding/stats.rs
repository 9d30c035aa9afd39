//! Python wrappers of the statistics kernel: `pair_stats` and the `PairStats` class. The
//! frames are read in place when aligned and contiguous in a shared memory order (copied
//! otherwise); the pass runs with the GIL released.

use std::sync::OnceLock;

use numpy::{
    PyArrayDescrMethods, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArray, PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyTuple};

use super::args::{self, PairRequest};
use super::detached;
use super::dtypes::{contiguous, pair_shape, shape_text, supported_dtypes, unsupported_dtype};
use crate::hist::{Entropies, HistSpec, JointTable};
use crate::stats::{self, Request, Sample, Sums};

/// `(mean_real, mean_sim, var_real, var_sim, cov)`.
type Moments = (f64, f64, f64, f64, f64);

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
    /// The real frame's `(min, max)` when the pass's scan read all of it, else None.
    #[getter]
    fn real_range(&self) -> Option<(f64, f64)> {
        self.inner.real_range
    }
    fn sse(&self) -> Option<f64> {
        self.inner.sse()
    }
    fn mse(&self) -> Option<f64> {
        self.inner.mse()
    }
    /// `(mean_real, mean_sim, var_real, var_sim, cov)`, population moments, or None.
    fn moments(&self) -> Option<Moments> {
        self.inner.moments().map(|m| (m.mean_real, m.mean_sim, m.var_real, m.var_sim, m.cov))
    }
    /// `(d_real, d_sim, d_cov)`: centred second sums in a common scale (exact for ints).
    fn centred(&self) -> Option<(f64, f64, f64)> {
        self.inner.centred()
    }
    /// `(h_real, h_sim, h_joint)` in bits, or None without a histogram.
    fn entropies(&self, py: Python<'_>) -> PyResult<Option<(f64, f64, f64)>> {
        // Not `get_or_init`: a second thread would wait on it holding the GIL, which the
        // first needs back after computing without it. Two threads may both compute (same
        // value); the first to finish keeps it.
        let e = match self.entropies.get() {
            Some(e) => *e,
            None => {
                let e = detached(py, || Ok(self.inner.entropies()))?;
                *self.entropies.get_or_init(|| e)
            }
        };
        Ok(e.map(|e| (e.h_real, e.h_sim, e.h_joint)))
    }
    /// `(mse, moments, centred, entropies)`: what every image metric reads, in one call (each
    /// None when not computed).
    #[allow(clippy::type_complexity)]
    fn summary(
        &self,
        py: Python<'_>,
    ) -> PyResult<(Option<f64>, Option<Moments>, Option<(f64, f64, f64)>, Option<(f64, f64, f64)>)> {
        Ok((self.mse(), self.moments(), self.centred(), self.entropies(py)?))
    }
    /// `("levels",)`, `("bins", bins, lo, width)` or `("each", bins, real_lo, real_width,
    /// sim_lo, sim_width)`, or None.
    fn hist_spec<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        Ok(match &self.inner.hist {
            None => None,
            Some((HistSpec::Levels, _)) => Some(("levels",).into_pyobject(py)?.into_any()),
            Some((HistSpec::Binned { bins, lo, width }, _)) => {
                Some(("bins", *bins, *lo, *width).into_pyobject(py)?.into_any())
            }
            Some((HistSpec::Each { bins, real, sim }, _)) => {
                Some(("each", *bins, real.0, real.1, sim.0, sim.1).into_pyobject(py)?.into_any())
            }
        })
    }
    /// `(counts, real_first, sim_first)`: the joint histogram as a dense int64 table (see
    /// `crate::hist::JointTable`), or None without a histogram.
    fn joint_histogram<'py>(&self, py: Python<'py>, max_cells: usize) -> PyResult<Option<JointCounts<'py>>> {
        let Some((spec, joint)) = &self.inner.hist else { return Ok(None) };
        let table = detached(py, || JointTable::of(spec, joint, max_cells))?;
        // counts of pixels: far below 2^63
        let counts: Vec<i64> = table.counts.into_iter().map(|c| c as i64).collect();
        let counts = numpy::ndarray::Array2::from_shape_vec((table.rows, table.cols), counts)
            .map_err(|e| crate::Error::Value(format!("internal: joint histogram shape: {e}")))?;
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
        let merged = detached(py, || a.merge(b))?;
        Ok(PyPairStats::new(merged))
    }
    fn to_bytes<'py>(&self, py: Python<'py>) -> Bound<'py, PyBytes> {
        PyBytes::new(py, &self.inner.to_bytes())
    }
    #[staticmethod]
    fn from_bytes(data: &[u8]) -> PyResult<PyPairStats> {
        Ok(PyPairStats::new(stats::PairStats::from_bytes(data)?))
    }
}

/// The kernel on `real` and `sim` (same dtype, aligned, contiguous in `req`'s order), or
/// `None` when `real`'s dtype is not supported. The dtype is compared first: a failed
/// `extract` builds a Python exception, which costs microseconds on small frames.
fn frame_stats(
    py: Python<'_>,
    real: &Bound<'_, PyUntypedArray>,
    sim: &Bound<'_, PyUntypedArray>,
    req: &Request<'_>,
) -> Option<PyResult<stats::PairStats>> {
    with_frame_dtype!(py, real.dtype(), |T| typed_stats::<T>(py, real, sim, req))
}

fn typed_stats<T: numpy::Element + Sample>(
    py: Python<'_>,
    real: &Bound<'_, PyUntypedArray>,
    sim: &Bound<'_, PyUntypedArray>,
    req: &Request<'_>,
) -> PyResult<stats::PairStats> {
    let (Ok(r), Ok(s)) = (real.cast::<PyArrayDyn<T>>(), sim.cast::<PyArrayDyn<T>>()) else {
        return Err(dtype_mismatch(real, sim).into());
    };
    let (r, s) = (readonly(r)?, readonly(s)?);
    let (rs, ss) = (slice(&r)?, slice(&s)?);
    detached(py, || stats::pair_stats(rs, ss, req))
}

fn dtype_mismatch(real: &Bound<'_, PyUntypedArray>, sim: &Bound<'_, PyUntypedArray>) -> crate::Error {
    crate::Error::Shape(format!(
        "real and sim frames differ in dtype: {} vs {}; expected two frames of the same dtype among {}",
        real.dtype(),
        sim.dtype(),
        crate::dtype::Dtype::names()
    ))
}

pub(crate) fn readonly<'py, T: numpy::Element>(
    a: &Bound<'py, PyArrayDyn<T>>,
) -> crate::Result<PyReadonlyArrayDyn<'py, T>> {
    a.try_readonly().map_err(|e| crate::Error::Value(format!("a frame is being written elsewhere: {e}")))
}

fn slice<'a, T: numpy::Element>(a: &'a PyReadonlyArrayDyn<'_, T>) -> crate::Result<&'a [T]> {
    a.as_slice().map_err(|e| crate::Error::Value(format!("internal: frame not laid out for the kernel: {e}")))
}

/// `arr` itself when it is aligned and contiguous in the wanted order, else an aligned copy
/// in that order (an `np.memmap` or `np.frombuffer` at an odd offset is contiguous but not
/// aligned; the kernel reads aligned slices).
fn laid_out<'py>(arr: &Bound<'py, PyUntypedArray>, fortran: bool) -> PyResult<Bound<'py, PyUntypedArray>> {
    let in_order = if fortran { arr.is_fortran_contiguous() } else { arr.is_c_contiguous() };
    if in_order && arr.is_aligned() {
        return Ok(arr.clone());
    }
    let copy = arr.call_method1(pyo3::intern!(arr.py(), "copy"), (if fortran { "F" } else { "C" },))?;
    Ok(copy.cast_into::<PyUntypedArray>()?)
}

/// Both frames laid out in one memory order and whether it is Fortran's: their own when
/// they share one (C preferred), C otherwise. Copies only what is not laid out already.
fn common_layout<'py>(
    real: &Bound<'py, PyUntypedArray>,
    sim: &Bound<'py, PyUntypedArray>,
) -> PyResult<(Bound<'py, PyUntypedArray>, Bound<'py, PyUntypedArray>, bool)> {
    let fortran = !(real.is_c_contiguous() && sim.is_c_contiguous())
        && real.is_fortran_contiguous()
        && sim.is_fortran_contiguous();
    Ok((laid_out(real, fortran)?, laid_out(sim, fortran)?, fortran))
}

/// The mask in the frames' memory order (a copy if it is not), checked against their shape.
fn mask_laid_out<'py>(
    mask: &Bound<'py, PyArrayDyn<bool>>,
    frame: &Bound<'py, PyUntypedArray>,
    fortran: bool,
) -> PyResult<Bound<'py, PyArrayDyn<bool>>> {
    if mask.shape() != frame.shape() {
        let (got, want) = (shape_text(mask.shape()), shape_text(frame.shape()));
        return Err(crate::Error::Shape(format!("mask: shape {got} differs from the frames' {want}")).into());
    }
    Ok(laid_out(mask.as_untyped(), fortran)?.cast_into::<PyArrayDyn<bool>>()?)
}

/// `pair_stats(real, sim, request, mask=None)`: see `irfidelity.stats.pair_stats`. The
/// frames are used in place when they are aligned and share a memory order, else copied.
#[pyfunction]
#[pyo3(signature = (real, sim, request, mask=None))]
fn pair_stats(
    py: Python<'_>,
    real: &Bound<'_, PyUntypedArray>,
    sim: &Bound<'_, PyUntypedArray>,
    #[pyo3(from_py_with = args::pair_request)] request: PairRequest,
    mask: Option<&Bound<'_, PyArrayDyn<bool>>>,
) -> PyResult<PyPairStats> {
    let shape = pair_shape(real, sim)?;
    let (real, sim, fortran) = common_layout(real, sim)?;
    let mask = mask.map(|m| mask_laid_out(m, &real, fortran)).transpose()?;
    let mask = mask.as_ref().map(readonly).transpose()?;
    let mask_slice = mask.as_ref().map(slice).transpose()?;
    let req = request.frame_request(mask_slice, shape, fortran);
    match frame_stats(py, &real, &sim, &req) {
        Some(stats) => Ok(PyPairStats::new(stats?)),
        None => Err(unsupported_dtype("real", real.dtype()).into()),
    }
}

/// The kernel on two non-empty, aligned, 2-D C-contiguous arrays of one supported dtype
/// and shape, else `None` (the caller takes the general path, which also explains what is
/// wrong). The single-metric fast path: no keyword parsing, no Python-side checks.
fn plain_stats(
    py: Python<'_>,
    real: &Bound<'_, PyAny>,
    sim: &Bound<'_, PyAny>,
    sse: bool,
    moments: bool,
) -> PyResult<Option<PyPairStats>> {
    let (Ok(r), Ok(s)) = (real.cast::<PyUntypedArray>(), sim.cast::<PyUntypedArray>()) else { return Ok(None) };
    let plain = |a: &Bound<'_, PyUntypedArray>| a.ndim() == 2 && a.is_c_contiguous() && a.is_aligned();
    if !(plain(r) && plain(s)) || r.shape() != s.shape() || r.len() == 0 || !r.dtype().is_equiv_to(&s.dtype()) {
        return Ok(None);
    }
    let shape = (r.shape()[0], r.shape()[1]);
    let req = Request { sse, moments, hist: None, shape, ..Request::default() };
    match frame_stats(py, r, s, &req) {
        Some(stats) => Ok(Some(PyPairStats::new(stats?))),
        None => Ok(None),
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

/// `scored_range(values, mask=None)` -> `((min, max) or None, any kept value not finite)`:
/// one frame's range over the pixels `mask` keeps whose values are finite (C-contiguous, of a
/// frame dtype; `crate::kernel::scored_range`), without the GIL.
#[pyfunction]
#[pyo3(signature = (values, mask=None))]
fn scored_range(
    py: Python<'_>,
    values: &Bound<'_, PyUntypedArray>,
    mask: Option<PyReadonlyArrayDyn<'_, bool>>,
) -> PyResult<(Option<(f64, f64)>, bool)> {
    if let Some(m) = mask.as_ref().filter(|m| m.shape() != values.shape()) {
        let (mask_shape, frame_shape) = (shape_text(m.shape()), shape_text(values.shape()));
        return Err(crate::Error::Shape(format!("the mask is {mask_shape} and the frame {frame_shape}")).into());
    }
    let keep = mask.as_ref().map(|m| contiguous(m, "the mask")).transpose()?;
    with_frame_dtype!(py, values.dtype(), |T| {
        let array = readonly(values.cast::<PyArrayDyn<T>>()?)?;
        let run = contiguous(&array, "the frame")?;
        Ok(py.detach(|| crate::kernel::scored_range(run, keep)))
    })
    .unwrap_or_else(|| Err(unsupported_dtype("the frame", values.dtype()).into()))
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(scored_range, m)?)?;
    m.add_function(wrap_pyfunction!(plain_mse, m)?)?;
    m.add_function(wrap_pyfunction!(plain_moments, m)?)?;
    m.add_class::<PyPairStats>()?;
    m.add_function(wrap_pyfunction!(pair_stats, m)?)?;
    m.add("SUPPORTED_DTYPES", PyTuple::new(m.py(), supported_dtypes())?)?;
    m.add("MAX_HIST_BINS", crate::hist::MAX_BINS)?;
    Ok(())
}
