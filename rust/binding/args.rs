//! Arguments shared by several functions: the kernel requests (`irfidelity.stats.PairRequest`,
//! `irfidelity.sequence.plan.SequenceRequest`) and non-negative integers. Both are extracted so that a bad value is an irfidelity error
//! naming it, not a bare `OverflowError`.

use pyo3::exceptions::PyOverflowError;
use pyo3::prelude::*;

use crate::register::{Method, Model, Options};
use crate::sequence::{EachWarp, FixedWarp, SeqRequest, Warp};
use crate::stats::{HistRequest, Request};
use crate::Error;

/// `irfidelity.stats.PairRequest`, read attribute by attribute: what one kernel pass
/// computes on a frame pair.
#[derive(FromPyObject)]
pub(crate) struct PairRequest {
    sse: bool,
    moments: bool,
    bins: Option<usize>,
    levels: bool,
    each: bool,
    hist_range: Option<(f64, f64)>,
    valid: Option<(i64, i64)>,
    mask_nonfinite: bool,
}

/// `irfidelity.sequence.plan.SequenceRequest`: the request of every pair of a sequence and
/// what a sequence adds (decoding, registration, the real frame's extent).
#[derive(FromPyObject)]
pub(crate) struct SequenceRequest {
    pair: PairRequest,
    real_channel: Option<String>,
    sim_channel: Option<String>,
    real_extent: bool,
    max_pixels: Option<u64>,
    max_bytes: Option<u64>,
    warp: Option<([f64; 6], u32)>,
    register_each: Option<(String, String, Option<f64>, u32)>,
}

impl PairRequest {
    fn hist(&self) -> Option<HistRequest> {
        if self.levels {
            Some(HistRequest::Levels)
        } else {
            self.bins.map(|bins| match self.each {
                true => HistRequest::Each { bins },
                false => HistRequest::Bins { bins, range: self.hist_range },
            })
        }
    }

    /// The kernel's request for one in-memory pair.
    pub(crate) fn frame_request<'m>(
        &self,
        mask: Option<&'m [bool]>,
        shape: (usize, usize),
        fortran: bool,
    ) -> Request<'m> {
        Request {
            sse: self.sse,
            moments: self.moments,
            hist: self.hist(),
            mask,
            valid: self.valid,
            mask_nonfinite: self.mask_nonfinite,
            shape,
            fortran,
        }
    }
}

impl SequenceRequest {
    /// The request for every pair of a sequence, decode options included.
    pub(crate) fn sequence_request(self) -> crate::Result<SeqRequest> {
        let warp = match (self.warp, self.register_each) {
            (Some((matrix, order)), None) => Some(Warp::Fixed(FixedWarp::from_matrix(matrix, order)?)),
            (None, Some((model, method, max_shift, order))) => {
                let options = Options { model: Model::parse(&model)?, method: Method::parse(&method)?, max_shift };
                Some(Warp::Each(EachWarp::new(options, order)?))
            }
            (None, None) => None,
            (Some(_), Some(_)) => {
                return Err(Error::Value("request: warp and register_each exclude each other".into()));
            }
        };
        let pair = self.pair;
        Ok(SeqRequest {
            hist: pair.hist(),
            sse: pair.sse,
            moments: pair.moments,
            valid: pair.valid,
            mask_nonfinite: pair.mask_nonfinite,
            real_channel: self.real_channel,
            sim_channel: self.sim_channel,
            real_extent: self.real_extent,
            max_pixels: self.max_pixels.unwrap_or(crate::io::DEFAULT_MAX_PIXELS),
            max_bytes: self.max_bytes,
            warp,
            fingerprint: false,
        })
    }
}

/// `from_py_with` extractor of a pair's `request` argument.
pub(crate) fn pair_request(obj: &Bound<'_, PyAny>) -> PyResult<PairRequest> {
    obj.extract::<PairRequest>().map_err(|err| request_error(obj.py(), err, "irfidelity.stats.PairRequest"))
}

/// `from_py_with` extractor of a sequence's `request` argument.
pub(crate) fn sequence_request(obj: &Bound<'_, PyAny>) -> PyResult<SequenceRequest> {
    obj.extract::<SequenceRequest>()
        .map_err(|err| request_error(obj.py(), err, "irfidelity.sequence.plan.SequenceRequest"))
}

/// A request that could not be read: a field of the wrong type or out of range is a
/// `FidelityError` (`RangeError` for an integer out of range) naming the field. The derive
/// reports "failed to extract field <Struct>.<name>" with the conversion error as the cause
/// (a nested request one cause deeper); a missing attribute comes as it is.
fn request_error(py: Python<'_>, err: PyErr, expected: &str) -> PyErr {
    let mut detail = message(py, &err);
    let (mut cause, mut overflow) = (err.cause(py), false);
    while let Some(c) = cause {
        detail = format!("{detail}: {}", message(py, &c));
        overflow = c.is_instance_of::<PyOverflowError>(py);
        cause = c.cause(py);
    }
    let detail = format!("request: {detail} (expected an {expected})");
    if overflow {
        Error::Range(detail).into()
    } else {
        Error::Value(detail).into()
    }
}

fn message(py: Python<'_>, err: &PyErr) -> String {
    err.value(py).str().map(|s| s.to_string()).unwrap_or_default()
}

/// A non-negative integer argument that fits `T`; a negative value or one ≥ 2⁶⁴ is a
/// `RangeError` naming `name` (other types keep PyO3's `TypeError`).
fn unsigned<T: TryFrom<u64>>(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<T> {
    let out_of_range =
        || -> PyErr { Error::Range(format!("{name} must be an integer in 0..={}, got {obj}", u64::MAX)).into() };
    match obj.extract::<u64>() {
        Ok(v) => T::try_from(v).map_err(|_| out_of_range()),
        Err(e) if e.is_instance_of::<PyOverflowError>(obj.py()) => Err(out_of_range()),
        Err(e) => Err(e),
    }
}

/// [`unsigned`], or `None` for Python's `None`.
fn optional_unsigned<T: TryFrom<u64>>(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Option<T>> {
    if obj.is_none() {
        Ok(None)
    } else {
        unsigned(obj, name).map(Some)
    }
}

/// A list of [`unsigned`] values, or `None`.
fn optional_unsigned_list<T: TryFrom<u64>>(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Option<Vec<T>>> {
    if obj.is_none() {
        return Ok(None);
    }
    obj.extract::<Vec<Bound<'_, PyAny>>>()?.iter().map(|item| unsigned(item, name)).collect::<PyResult<_>>().map(Some)
}

// `from_py_with` extractors, one per argument so that errors name it.

pub(crate) fn page(obj: &Bound<'_, PyAny>) -> PyResult<usize> {
    unsigned(obj, "page")
}

pub(crate) fn workers(obj: &Bound<'_, PyAny>) -> PyResult<usize> {
    unsigned(obj, "workers")
}

pub(crate) fn max_pixels(obj: &Bound<'_, PyAny>) -> PyResult<Option<u64>> {
    optional_unsigned(obj, "max_pixels")
}

pub(crate) fn max_bytes(obj: &Bound<'_, PyAny>) -> PyResult<Option<u64>> {
    optional_unsigned(obj, "max_bytes")
}

pub(crate) fn real_pages(obj: &Bound<'_, PyAny>) -> PyResult<Option<Vec<usize>>> {
    optional_unsigned_list(obj, "real_pages")
}

pub(crate) fn sim_pages(obj: &Bound<'_, PyAny>) -> PyResult<Option<Vec<usize>>> {
    optional_unsigned_list(obj, "sim_pages")
}
