//! The crate's one error type. Kernels return `Result<_, Error>`; the binding maps each
//! kind to the matching Python exception class (DESIGN §5) in one place.

use std::fmt;

#[derive(Debug, Clone, PartialEq)]
pub enum Error {
    /// Shapes, dtypes or masks that do not match (Python: `ShapeError`).
    Shape(String),
    /// Values outside the declared range, or non-finite values (Python: `RangeError`).
    Range(String),
    /// A frame file that cannot be read or is not supported (Python: `FrameError`).
    Frame(String),
    /// Any other bad argument (Python: `FidelityError`, a `ValueError`).
    Value(String),
    /// A frame pair that cannot be registered (Python: `RegistrationError`).
    Registration(String),
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Shape(m) | Error::Range(m) | Error::Frame(m) | Error::Value(m) | Error::Registration(m) => {
                f.write_str(m)
            }
        }
    }
}

impl std::error::Error for Error {}

pub type Result<T> = std::result::Result<T, Error>;
