//! The PyO3 module `irfidelity._core`. Each concern has its own file (`stats`, `io`, …) with
//! a `register` function; this file owns the module and the single mapping of
//! [`crate::Error`] kinds to the Python exception classes of `irfidelity.errors`, so `?`
//! turns a core error into the matching Python exception, and [`detached`], the one way a
//! binding runs core work without the GIL.

use pyo3::prelude::*;

#[macro_use]
mod dtypes;
mod args;
mod budget;
mod defects;
mod fingerprint;
mod io;
mod maps;
mod noise;
mod pair;
mod radiometry;
mod register;
mod sequence;
mod stats;
mod transfer;

pyo3::import_exception!(irfidelity.errors, FidelityError);
pyo3::import_exception!(irfidelity.errors, FrameError);
pyo3::import_exception!(irfidelity.errors, ShapeError);
pyo3::import_exception!(irfidelity.errors, RangeError);
pyo3::import_exception!(irfidelity.errors, RegistrationError);

impl From<crate::Error> for PyErr {
    fn from(err: crate::Error) -> PyErr {
        use crate::Error;
        match err {
            Error::Shape(m) => ShapeError::new_err(m),
            Error::Range(m) => RangeError::new_err(m),
            Error::Frame(m) => FrameError::new_err(m),
            Error::Registration(m) => RegistrationError::new_err(m),
            Error::Value(m) => FidelityError::new_err(m),
        }
    }
}

/// Run `f` with the GIL released, then raise a signal that arrived meanwhile (Ctrl-C:
/// `KeyboardInterrupt`, before the result is handed to Python) or else `f`'s error as its
/// Python exception (the mapping above). Panics are not caught here: a refused allocation is
/// turned into an error inside `f` by the operation's `budget::guard`, a decoder's panic by
/// `io`'s own `catch_unwind`; any other panic reaches PyO3's boundary (`PanicException`).
pub(crate) fn detached<T: Send>(py: Python<'_>, f: impl FnOnce() -> crate::Result<T> + Send) -> PyResult<T> {
    let result = py.detach(f);
    py.check_signals()?;
    Ok(result?)
}

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    stats::register(m)?;
    budget::register(m)?;
    io::register(m)?;
    sequence::register(m)?;
    fingerprint::register(m)?;
    maps::register(m)?;
    noise::register(m)?;
    register::register(m)?;
    pair::register(m)?;
    radiometry::register(m)?;
    defects::register(m)?;
    transfer::register(m)?;
    Ok(())
}
