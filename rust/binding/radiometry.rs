//! Python wrappers of the radiometric calibration (`crate::io::read_camera_info`) and of the
//! conversions between counts and temperatures (`crate::radiometry`), with the GIL released.

use std::path::PathBuf;

use numpy::{
    IntoPyArray, PyArrayDescrMethods, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use pyo3::IntoPyObject;

use super::dtypes::{contiguous, unsupported_dtype};
use super::{args, detached};
use crate::io::{self, DecodeOptions};
use crate::radiometry::{self, Calibration, Converted, Sample, Unit};

/// The camera-info record of a radiometric FLIR file (frame `page` of a SEQ) as a dict keyed by
/// the `Radiometry` field names; `date` is `(unix seconds, milliseconds, minutes east of UTC)`.
#[pyfunction]
#[pyo3(signature = (path, page=0, *, max_bytes=None))]
fn read_camera_info<'py>(
    py: Python<'py>,
    path: PathBuf,
    #[pyo3(from_py_with = args::page)] page: usize,
    #[pyo3(from_py_with = args::max_bytes)] max_bytes: Option<u64>,
) -> PyResult<Bound<'py, PyDict>> {
    let opts = DecodeOptions { page, max_bytes: max_bytes.unwrap_or(io::DEFAULT_MAX_BYTES), ..Default::default() };
    let c = detached(py, || io::read_camera_info(&path, &opts))?;
    let d = c.calibration.into_pyobject(py)?;
    d.set_item("camera_model", c.camera_model)?;
    d.set_item("camera_serial", c.camera_serial)?;
    d.set_item("lens_model", c.lens_model)?;
    d.set_item("date", c.date)?;
    d.set_item("frame_rate", c.frame_rate)?;
    Ok(d)
}

fn unit(name: &str) -> crate::Result<Unit> {
    match name {
        "C" => Ok(Unit::Celsius),
        "K" => Ok(Unit::Kelvin),
        other => Err(crate::Error::Value(format!("unit must be \"C\" or \"K\", got {other:?}"))),
    }
}

type Conversion<T> = fn(&[T], &Calibration, Unit) -> crate::Result<Converted>;

/// `convert` over a C-contiguous array of a supported dtype: float64 values of its shape, and
/// the counts of finite inputs outside the domain and of non-finite inputs.
fn apply<'py, T: numpy::Element + Sample>(
    py: Python<'py>,
    values: &Bound<'py, PyUntypedArray>,
    calibration: &Calibration,
    unit: Unit,
    convert: Conversion<T>,
) -> PyResult<(Bound<'py, PyAny>, usize, usize)> {
    let array = values
        .cast::<PyArrayDyn<T>>()?
        .try_readonly()
        .map_err(|e| crate::Error::Value(format!("the array is being written elsewhere: {e}")))?;
    let slice = array.as_slice().map_err(|e| crate::Error::Value(format!("internal: array not C-contiguous: {e}")))?;
    let out = detached(py, || convert(slice, calibration, unit))?;
    let shaped = numpy::ndarray::ArrayD::from_shape_vec(values.shape(), out.values)
        .map_err(|e| crate::Error::Value(format!("internal: {e}")))?;
    Ok((shaped.into_pyarray(py).into_any(), out.outside, out.nonfinite))
}

fn unsupported(values: &Bound<'_, PyUntypedArray>) -> PyErr {
    unsupported_dtype("values", values.dtype()).into()
}

/// Temperatures (float64, in `unit`) of raw counts, or with `inverse` raw counts (float64,
/// unrounded) of temperatures in `unit`; with the number of finite inputs outside the
/// calibration's domain and of non-finite inputs (both now NaN).
#[pyfunction]
fn radiometric_conversion<'py>(
    py: Python<'py>,
    values: &Bound<'py, PyUntypedArray>,
    calibration: Calibration,
    unit: &str,
    inverse: bool,
) -> PyResult<(Bound<'py, PyAny>, usize, usize)> {
    let unit = self::unit(unit)?;
    with_frame_dtype!(py, values.dtype(), |T| {
        let convert: Conversion<T> = if inverse { radiometry::counts } else { radiometry::temperatures };
        apply::<T>(py, values, &calibration, unit, convert)
    })
    .unwrap_or_else(|| Err(unsupported(values)))
}

/// `temperature_errors(real, sim, mask=None, *, tolerance)` -> `(n, Σd, Σd², Σ|d|, within)` of
/// `d = sim − real` over the pairs `mask` keeps whose difference is finite (float64 arrays of
/// one size, C-contiguous; `crate::radiometry::error_sums`), without the GIL.
#[pyfunction]
#[pyo3(signature = (real, sim, mask=None, *, tolerance))]
fn temperature_errors(
    py: Python<'_>,
    real: PyReadonlyArrayDyn<'_, f64>,
    sim: PyReadonlyArrayDyn<'_, f64>,
    mask: Option<PyReadonlyArrayDyn<'_, bool>>,
    tolerance: f64,
) -> PyResult<(u64, f64, f64, f64, u64)> {
    let (r, s) = (contiguous(&real, "the real temperatures")?, contiguous(&sim, "the simulated temperatures")?);
    let m = mask.as_ref().map(|m| contiguous(m, "the mask")).transpose()?;
    let e = detached(py, || radiometry::error_sums(r, s, m, tolerance))?;
    Ok((e.n, e.sum, e.squares, e.magnitudes, e.within))
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(read_camera_info, m)?)?;
    m.add_function(wrap_pyfunction!(temperature_errors, m)?)?;
    m.add_function(wrap_pyfunction!(radiometric_conversion, m)?)?;
    Ok(())
}
