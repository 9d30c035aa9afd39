//! The crate's one error type. Kernels return `Result<_, Error>`; the binding maps each
//! kind to the matching Python exception class in one place (`rust/binding/mod.rs`).

use std::fmt;

#[derive(Debug, Clone, PartialEq)]
pub enum Error {
    /// Shapes, dtypes or masks that do not match (Python: `ShapeError`).
    Shape(String),
    /// Values outside the declared range, or non-finite values (Python: `RangeError`).
    Range(String),
    /// A frame file that cannot be read or is not supported (Python: `FrameError`).
    Frame(String),
    /// A frame pair that cannot be registered (Python: `RegistrationError`).
    Registration(String),
    /// Any other bad argument (Python: `FidelityError`, a `ValueError`).
    Value(String),
}

impl Error {
    /// The message, without the kind.
    pub fn message(&self) -> &str {
        match self {
            Error::Shape(m) | Error::Range(m) | Error::Frame(m) | Error::Registration(m) | Error::Value(m) => m,
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.message())
    }
}

impl std::error::Error for Error {}

pub type Result<T> = std::result::Result<T, Error>;
