//! Python wrappers of the radiometric calibration (`crate::io::read_camera_info`) and of the
//! conversions between counts and temperatures (`crate::radiometry`), with the GIL released.

use std::path::PathBuf;

use numpy::{IntoPyArray, PyArrayDescrMethods, PyArrayDyn, PyArrayMethods, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use super::args;
use super::dtypes::SUPPORTED_DTYPES;
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
    let c = py.detach(|| io::read_camera_info(&path, &opts))?;
    let d = PyDict::new(py);
    for (name, value) in [
        ("planck_r1", c.planck_r1),
        ("planck_r2", c.planck_r2),
        ("planck_b", c.planck_b),
        ("planck_f", c.planck_f),
        ("planck_o", c.planck_o),
        ("emissivity", c.emissivity),
        ("object_distance", c.object_distance),
        ("reflected_temperature", c.reflected_temperature),
        ("atmospheric_temperature", c.atmospheric_temperature),
        ("window_temperature", c.window_temperature),
        ("window_transmission", c.window_transmission),
        ("relative_humidity", c.relative_humidity),
        ("alpha1", c.alpha1),
        ("alpha2", c.alpha2),
        ("beta1", c.beta1),
        ("beta2", c.beta2),
        ("x", c.x),
    ] {
        d.set_item(name, value)?;
    }
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
    let out = py.detach(|| convert(slice, calibration, unit))?;
    let shaped = numpy::ndarray::ArrayD::from_shape_vec(values.shape(), out.values)
        .map_err(|e| crate::Error::Value(format!("internal: {e}")))?;
    Ok((shaped.into_pyarray(py).into_any(), out.outside, out.nonfinite))
}

fn unsupported(values: &Bound<'_, PyUntypedArray>) -> PyErr {
    crate::Error::Value(format!(
        "unsupported dtype {}; expected one of {}",
        values.dtype(),
        SUPPORTED_DTYPES.join(", ")
    ))
    .into()
}

/// Temperatures (float64, in `unit`) of raw counts, with the number of finite counts outside
/// the calibration's domain and of non-finite counts (both now NaN).
#[pyfunction]
fn counts_to_temperature<'py>(
    py: Python<'py>,
    counts: &Bound<'py, PyUntypedArray>,
    calibration: Calibration,
    unit: &str,
) -> PyResult<(Bound<'py, PyAny>, usize, usize)> {
    let unit = self::unit(unit)?;
    with_frame_dtype!(py, counts.dtype(), |T| apply::<T>(py, counts, &calibration, unit, radiometry::temperatures))
        .unwrap_or_else(|| Err(unsupported(counts)))
}

/// Raw counts (float64, unrounded) of temperatures in `unit`: the inverse of
/// `counts_to_temperature`, with the same counts of NaN results.
#[pyfunction]
fn temperature_to_counts<'py>(
    py: Python<'py>,
    temperature: &Bound<'py, PyUntypedArray>,
    calibration: Calibration,
    unit: &str,
) -> PyResult<(Bound<'py, PyAny>, usize, usize)> {
    let unit = self::unit(unit)?;
    with_frame_dtype!(py, temperature.dtype(), |T| apply::<T>(py, temperature, &calibration, unit, radiometry::counts))
        .unwrap_or_else(|| Err(unsupported(temperature)))
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(read_camera_info, m)?)?;
    m.add_function(wrap_pyfunction!(counts_to_temperature, m)?)?;
    m.add_function(wrap_pyfunction!(temperature_to_counts, m)?)?;
    Ok(())
}
