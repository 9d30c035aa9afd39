//! The PyO3 module `irfidelity._core`. Each concern has its own file (`stats`, `io`, …) with
//! a `register` function; this file owns the module and the single mapping of
//! [`crate::Error`] kinds to the Python exception classes of `irfidelity.errors`.

use pyo3::prelude::*;

mod io;
mod register;
mod sequence;
mod stats;

/// Map a core error to the matching `irfidelity.errors` class (DESIGN §5).
pub(crate) fn to_pyerr(err: crate::Error) -> PyErr {
    let (class, msg) = match err {
        crate::Error::Shape(m) => ("ShapeError", m),
        crate::Error::Range(m) => ("RangeError", m),
        crate::Error::Frame(m) => ("FrameError", m),
        crate::Error::Value(m) => ("FidelityError", m),
        crate::Error::Registration(m) => ("RegistrationError", m),
    };
    Python::attach(|py| match py.import("irfidelity.errors").and_then(|m| m.getattr(class)) {
        Ok(cls) => match cls.call1((msg.clone(),)) {
            Ok(inst) => PyErr::from_value(inst),
            Err(e) => e,
        },
        Err(_) => pyo3::exceptions::PyValueError::new_err(msg),
    })
}

/// `Result<T, crate::Error>` -> `PyResult<T>`.
pub(crate) trait IntoPy<T> {
    fn py_err(self) -> PyResult<T>;
}

impl<T> IntoPy<T> for crate::Result<T> {
    fn py_err(self) -> PyResult<T> {
        self.map_err(to_pyerr)
    }
}

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    stats::register(m)?;
    io::register(m)?;
    sequence::register(m)?;
    register::register(m)?;
    Ok(())
}
