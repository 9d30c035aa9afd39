//! `file_digests`: content fingerprints of many frame files, in parallel, GIL released.

use std::path::PathBuf;

use pyo3::prelude::*;
use rayon::prelude::*;

use crate::fingerprint::file_digest;

/// XXH3-64 of each file's bytes; None for a file that cannot be read (its frame fails
/// on its own when decoded).
#[pyfunction]
fn file_digests(py: Python<'_>, paths: Vec<PathBuf>) -> PyResult<Vec<Option<u64>>> {
    super::detached(py, || Ok(paths.par_iter().map(|p| file_digest(p).ok()).collect()))
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(file_digests, m)?)?;
    Ok(())
}
