//! irfidelity core: exact frame-pair statistics and frame decoding, as plain Rust over
//! slices. The PyO3 binding (`irfidelity._core`) is behind the `python` feature, so
//! `cargo test` needs no Python.

#[macro_use]
mod avx2_copy;

pub mod budget;
pub mod defects;
pub mod dtype;
pub mod error;
pub mod fingerprint;
pub mod hist;
pub mod io;
pub mod kernel;
pub mod maps;
pub mod noise;
pub mod radiometry;
pub mod register;
pub mod sequence;
pub mod stats;
pub mod transfer;

#[cfg(feature = "python")]
mod binding;

pub use error::{Error, Result};
