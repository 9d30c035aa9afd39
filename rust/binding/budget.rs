//! Python access to the memory budget's check (`crate::budget::Plan`), so that the plans of
//! the Python layer (evaluation, noise spectra, reports) are refused with the same message
//! and error classes as those of the core.

use pyo3::prelude::*;

use super::args;
use crate::budget::{self, Plan};
use crate::Error;

/// `check_budget(operation, shape, bytes, max_bytes=None, kind="value")`: raise when an
/// operation on `shape` frames that holds `bytes` at its peak exceeds `max_bytes` (default:
/// the default budget) — `RegistrationError` for `kind="registration"`, `FrameError` for
/// `"frame"`, else `FidelityError` — naming the operation, the frame size, the bytes needed,
/// the budget and how to raise it.
#[pyfunction]
#[pyo3(signature = (operation, shape, bytes, max_bytes=None, kind="value"))]
fn check_budget(
    operation: String,
    shape: (usize, usize),
    bytes: u64,
    #[pyo3(from_py_with = args::max_bytes)] max_bytes: Option<u64>,
    kind: &str,
) -> PyResult<()> {
    let kind: budget::Kind = match kind {
        "value" => Error::Value,
        "registration" => Error::Registration,
        "frame" => Error::Frame,
        other => {
            return Err(Error::Value(format!("kind must be 'value', 'registration' or 'frame', got {other:?}")).into())
        }
    };
    Ok(Plan { operation, shape, bytes }.check(max_bytes.unwrap_or(crate::io::DEFAULT_MAX_BYTES), kind)?)
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(check_budget, m)?)?;
    Ok(())
}
