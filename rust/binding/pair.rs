//! Python wrapper of the one path of a registered pair (`crate::sequence::Warp::score_pair`):
//! `score_registered`, register → resample → masked statistics in one call with the GIL
//! released, as the sequence engine scores each of its pairs.

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2, PyArrayDescrMethods, PyReadonlyArrayDyn, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::prelude::*;

use super::args::{self, PairRequest};
use super::detached;
use super::dtypes::{contiguous, mask_samples, pair_shape, unsupported_dtype};
use super::register::{mask_bytes, nbytes, registration_tuple, RegistrationTuple};
use super::stats::PyPairStats;
use crate::kernel::Sample;
use crate::register::{Method, Model, Options};
use crate::sequence::{Aligned, EachWarp, FixedWarp, PairSlices, Warp};
use crate::stats::Request;
use crate::Error;

/// What `score_registered` returns: the statistics, the pair's own registration (searched),
/// the real frame's (min, max) over the scored pixels, the resampled simulated frame and
/// the scored pixels.
type Registered<'py> =
    (PyPairStats, Option<RegistrationTuple>, Option<(f64, f64)>, Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<bool>>);

/// The warp asked for: `search = (model, method, max_shift)` registers the pair, `matrix`
/// (simulated → real, 6 floats row-major) applies a registration found before.
fn warp_of(search: Option<(String, String, Option<f64>)>, matrix: Option<[f64; 6]>, order: u32) -> crate::Result<Warp> {
    match (search, matrix) {
        (Some((model, method, max_shift)), None) => {
            let options = Options { model: Model::parse(&model)?, method: Method::parse(&method)?, max_shift };
            Ok(Warp::Each(EachWarp::new(options, order)?))
        }
        (None, Some(matrix)) => Ok(Warp::Fixed(FixedWarp::from_matrix(matrix, order)?)),
        _ => Err(Error::Value("score_registered: give exactly one of search and matrix".into())),
    }
}

/// `score_registered(real, sim, request, *, search=None, matrix=None, order=3, mask=None,
/// extent=False, max_bytes=None)`: register `sim` onto `real` (`search = (model, method, max_shift)`) or
/// apply `matrix`, resample it with interpolation `order`, and compute the statistics
/// `request` asks for over the overlap (and `mask`), both frames as float64. Frames: 2-D,
/// C-contiguous, one shape and one supported dtype. The peak is planned against `max_bytes`
/// (default: the default budget) before anything is allocated.
#[pyfunction]
#[pyo3(signature = (real, sim, request, *, search=None, matrix=None, order=3, mask=None, extent=false, max_bytes=None))]
#[allow(clippy::too_many_arguments)]
fn score_registered<'py>(
    py: Python<'py>,
    real: &Bound<'py, PyUntypedArray>,
    sim: &Bound<'py, PyUntypedArray>,
    #[pyo3(from_py_with = args::pair_request)] request: PairRequest,
    search: Option<(String, String, Option<f64>)>,
    matrix: Option<[f64; 6]>,
    order: u32,
    mask: Option<PyReadonlyArrayDyn<'py, bool>>,
    extent: bool,
    #[pyo3(from_py_with = args::max_bytes)] max_bytes: Option<u64>,
) -> PyResult<Registered<'py>> {
    let warp = warp_of(search, matrix, order)?;
    let shape = pair_shape(real, sim)?;
    let mask = mask_samples(mask.as_ref(), shape)?;
    let (plan, kind) = warp.plan(shape);
    plan.holding(nbytes(&[real, sim]) + mask_bytes(mask))
        .check(max_bytes.unwrap_or(crate::io::DEFAULT_MAX_BYTES), kind)?;
    let kreq = request.frame_request(None, shape, false);
    let dtype = real.dtype();
    let scored =
        with_frame_dtype!(py, &dtype, |T| score_typed::<T>(py, (real, sim), shape, mask, &warp, &kreq, extent));
    let Aligned { registration, stats, extent, sim, scored } =
        scored.unwrap_or_else(|| Err(unsupported_dtype("real", &dtype).into()))?;
    let frame = |e: numpy::ndarray::ShapeError| Error::Value(format!("internal: warp shape: {e}"));
    let sim = Array2::from_shape_vec(shape, sim).map_err(frame)?;
    let scored = Array2::from_shape_vec(shape, scored).map_err(frame)?;
    let registration = registration.as_ref().map(registration_tuple);
    Ok((PyPairStats::new(stats), registration, extent, sim.into_pyarray(py), scored.into_pyarray(py)))
}

/// [`Warp::score_pair`] on two arrays of the sample type `T` (the simulated one must be of
/// the real one's type), without the GIL.
#[allow(clippy::too_many_arguments)]
fn score_typed<T: numpy::Element + Sample>(
    py: Python<'_>,
    (real, sim): (&Bound<'_, PyUntypedArray>, &Bound<'_, PyUntypedArray>),
    shape: (usize, usize),
    mask: Option<&[bool]>,
    warp: &Warp,
    kreq: &Request<'_>,
    extent: bool,
) -> PyResult<Aligned> {
    let Ok(sim) = sim.extract::<PyReadonlyArrayDyn<'_, T>>() else {
        let message = format!("real and simulated frames differ in dtype: {} vs {}", real.dtype(), sim.dtype());
        return Err(Error::Shape(message).into());
    };
    let real = real.extract::<PyReadonlyArrayDyn<'_, T>>().map_err(|e| Error::Value(format!("internal: {e}")))?;
    let pair = PairSlices {
        real: contiguous(&real, "the real frame")?,
        sim: contiguous(&sim, "the simulated frame")?,
        shape,
        mask,
    };
    let (operation, kind): (&str, crate::budget::Kind) = match warp {
        Warp::Each(_) => ("registration and scoring of a frame pair", Error::Registration),
        Warp::Fixed(_) => ("resampling and scoring of a frame pair", Error::Value),
    };
    detached(py, || crate::budget::guard(operation, kind, || warp.score_pair(&pair, kreq, extent)))
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(score_registered, m)?)?;
    Ok(())
}
