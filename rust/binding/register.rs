//! Python wrappers of registration (`crate::register`): `register_frames`, `warp_frame` and
//! `applied_matrix`.
//! Arrays arrive 2-D and C-contiguous (the Python layer decides the layout), each in any
//! supported sample type; conversion and search run with the GIL released. Both are
//! planned against `max_bytes` (the arrays given count as held) before anything is
//! allocated, and memory the system refuses is an error too (`crate::budget`).

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2, PyArrayDescrMethods, PyReadonlyArrayDyn, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::prelude::*;

use super::dtypes::{mask_samples, pair_shape, unsupported_dtype};
use super::{args, detached};
use crate::budget;
use crate::register::{self, Affine, Frame, Interp, Method, Model, Options, Source};
use crate::Error;

/// Bytes of the arrays given (held throughout the call).
pub(crate) fn nbytes(arrays: &[&Bound<'_, PyUntypedArray>]) -> u64 {
    arrays.iter().map(|a| budget::size_of_vec::<u8>(a.len() * a.dtype().itemsize())).sum()
}

/// Bytes of an optional mask.
pub(crate) fn mask_bytes(mask: Option<&[bool]>) -> u64 {
    mask.map_or(0, |m| budget::size_of_vec::<bool>(m.len()))
}

/// A registration for Python: `(matrix as 6 floats row-major, method used, confidence,
/// overlap, inverted)`.
pub(crate) type RegistrationTuple = ([f64; 6], &'static str, f64, f64, bool);

pub(crate) fn registration_tuple(reg: &register::Registration) -> RegistrationTuple {
    (flat(&reg.matrix), reg.method.name(), reg.confidence, reg.overlap, reg.inverted)
}

fn shape_of(a: &Bound<'_, PyUntypedArray>, what: &str) -> crate::Result<(usize, usize)> {
    match a.shape() {
        &[rows, cols] => Ok((rows, cols)),
        s => Err(crate::Error::Shape(format!("{what} frame must be 2-D, got shape {s:?}"))),
    }
}

/// `$body` (a `PyResult`) with `$s` bound to the array's contiguous samples as `&[T]` for
/// its sample type (`with_frame_dtype!`).
macro_rules! with_samples {
    ($py:expr, $arr:expr, $what:expr, |$s:ident| $body:expr) => {{
        let dt = $arr.dtype();
        let out = with_frame_dtype!($py, &dt, |T| {
            let array = $arr.extract::<PyReadonlyArrayDyn<'_, T>>()?;
            let $s = super::dtypes::contiguous(&array, $what)?;
            $body
        });
        out.unwrap_or_else(|| Err(unsupported_dtype($what, dt).into()))
    }};
}

fn matrix_of(m: [f64; 6]) -> Affine {
    Affine([[m[0], m[1], m[2]], [m[3], m[4], m[5]]])
}

pub(crate) fn flat(m: &Affine) -> [f64; 6] {
    let a = &m.0;
    [a[0][0], a[0][1], a[0][2], a[1][0], a[1][1], a[1][2]]
}

/// Register `sim` onto `real`. Returns `(matrix as 6 floats row-major, method used,
/// confidence, overlap, inverted)`; raises `RegistrationError` when the pair cannot be
/// registered, or when the registration's plan does not fit `max_bytes` (default: the
/// default budget).
#[pyfunction]
#[pyo3(signature = (real, sim, model, method, max_shift=None, mask=None, *, max_bytes=None))]
#[allow(clippy::too_many_arguments)]
fn register_frames(
    py: Python<'_>,
    real: &Bound<'_, PyUntypedArray>,
    sim: &Bound<'_, PyUntypedArray>,
    model: &str,
    method: &str,
    max_shift: Option<f64>,
    mask: Option<PyReadonlyArrayDyn<'_, bool>>,
    #[pyo3(from_py_with = args::max_bytes)] max_bytes: Option<u64>,
) -> PyResult<RegistrationTuple> {
    let opts = Options {
        model: Model::parse(model).map_err(PyErr::from)?,
        method: Method::parse(method).map_err(PyErr::from)?,
        max_shift,
    };
    let (rows, cols) = pair_shape(real, sim)?;
    let mask = mask_samples(mask.as_ref(), (rows, cols))?;
    register::register_plan((rows, cols), &opts)
        .holding(nbytes(&[real, sim]) + mask_bytes(mask))
        .check(max_bytes.unwrap_or(crate::io::DEFAULT_MAX_BYTES), Error::Registration)?;
    let reg = with_samples!(py, real, "real", |real| with_samples!(py, sim, "simulated", |sim| detached(py, || {
        budget::guard("registration", Error::Registration, || {
            let real = Frame::new(real, rows, cols, mask, "real")?;
            let sim = Frame::new(sim, rows, cols, mask, "simulated")?;
            register::register_frames(&real, &sim, &opts)
        })
    })))?;
    Ok(registration_tuple(&reg))
}

/// The matrix a warp applies (6 floats row-major, simulated → real): a translation within
/// `REGISTRATION_INTEGER_SNAP` px of whole pixels snapped to them, any other map unchanged.
#[pyfunction]
fn applied_matrix(matrix: [f64; 6]) -> [f64; 6] {
    flat(&matrix_of(matrix).snapped())
}

/// Resample `frame` (the simulated frame) onto the real frame's `shape` through `matrix`
/// (simulated → real coordinates, 6 floats row-major) with interpolation `order` (1
/// bilinear, 3 bicubic). Returns `(float64 frame, bool mask of valid pixels)`; invalid
/// pixels hold NaN. The frame, its mask and the output must fit `max_bytes`.
#[pyfunction]
#[pyo3(signature = (frame, matrix, order, shape, mask=None, *, max_bytes=None))]
fn warp_frame<'py>(
    py: Python<'py>,
    frame: &Bound<'py, PyUntypedArray>,
    matrix: [f64; 6],
    order: u32,
    shape: (usize, usize),
    mask: Option<PyReadonlyArrayDyn<'py, bool>>,
    #[pyo3(from_py_with = args::max_bytes)] max_bytes: Option<u64>,
) -> PyResult<WarpedArrays<'py>> {
    let interp = Interp::from_order(order)
        .ok_or_else(|| crate::Error::Value(format!("order must be 1 (bilinear) or 3 (bicubic), got {order}")))
        .map_err(PyErr::from)?;
    let to_source = matrix_of(matrix)
        .inverse()
        .ok_or_else(|| crate::Error::Value(format!("the matrix {matrix:?} is singular and cannot be applied")))
        .map_err(PyErr::from)?;
    let (rows, cols) = shape_of(frame, "simulated")?;
    let mask = mask_samples(mask.as_ref(), (rows, cols))?;
    register::warp_plan(shape)
        .holding(nbytes(&[frame]) + mask_bytes(mask))
        .check(max_bytes.unwrap_or(crate::io::DEFAULT_MAX_BYTES), Error::Value)?;
    let (values, valid) = warped(py, frame, (rows, cols), mask, &to_source, interp, shape)?;
    let values = Array2::from_shape_vec(shape, values).expect("warp returns rows × cols values");
    let valid = Array2::from_shape_vec(shape, valid).expect("warp returns rows × cols flags");
    Ok((values.into_pyarray(py), valid.into_pyarray(py)))
}

/// `warp_frame`'s values and validity flags.
type WarpedArrays<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<bool>>);

/// [`register::warp`] on the array's own sample type, without the GIL.
fn warped(
    py: Python<'_>,
    frame: &Bound<'_, PyUntypedArray>,
    (rows, cols): (usize, usize),
    mask: Option<&[bool]>,
    to_source: &Affine,
    interp: Interp,
    shape: (usize, usize),
) -> PyResult<(Vec<f64>, Vec<bool>)> {
    with_samples!(py, frame, "simulated", |data| {
        let src = Source { data, rows, cols, valid: mask };
        let resample = || Ok(register::warp(&src, to_source, interp, shape.0, shape.1, f64::NAN));
        detached(py, || budget::guard("resampling", Error::Value, resample))
    })
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(register_frames, m)?)?;
    m.add_function(wrap_pyfunction!(warp_frame, m)?)?;
    m.add_function(wrap_pyfunction!(applied_matrix, m)?)?;
    m.add("REGISTRATION_MODELS", Model::ALL.map(Model::name))?;
    m.add("REGISTRATION_METHODS", Method::ALL.map(Method::name))?;
    m.add("REGISTRATION_INTEGER_SNAP", register::INTEGER_SNAP)?;
    m.add("REGISTRATION_LOW_CONFIDENCE", register::LOW_CONFIDENCE)?;
    m.add("REGISTRATION_AMBIGUOUS", register::AMBIGUOUS)?;
    m.add("REGISTRATION_MIN_OVERLAP", register::MIN_OVERLAP)?;
    Ok(())
}
