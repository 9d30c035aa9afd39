//! Python wrappers of the frame decoders (`crate::io`): `load_frame`, `page_chain`,
//! `list_channels`, and the default limits. Decoding runs with the GIL released; the decoded `Vec` is handed to
//! numpy without a copy.

use std::path::PathBuf;

use numpy::ndarray::Array2;
use numpy::IntoPyArray;
use pyo3::prelude::*;

use super::{args, detached};
use crate::io::{self, DecodeOptions, Frame, FrameData};

fn to_array<'py>(py: Python<'py>, f: Frame, name: &str) -> PyResult<Bound<'py, PyAny>> {
    let shape = (f.rows, f.cols);
    macro_rules! arr {
        ($v:expr) => {
            Array2::from_shape_vec(shape, $v)
                .map_err(|e| crate::Error::Frame(format!("{name}: decoder returned a bad shape: {e}")))?
                .into_pyarray(py)
                .into_any()
        };
    }
    Ok(match f.data {
        FrameData::U8(v) => arr!(v),
        FrameData::U16(v) => arr!(v),
        FrameData::I16(v) => arr!(v),
        FrameData::U32(v) => arr!(v),
        FrameData::F16(v) => arr!(v),
        FrameData::F32(v) => arr!(v),
        FrameData::F64(v) => arr!(v),
    })
}

/// Decode one frame of an OpenEXR, PNG or TIFF file into a 2-D numpy array in the file's
/// own sample type. `max_bytes` is the decoding budget (peak memory of the decode, default
/// `default_max_bytes()`). Raises `irfidelity.errors.FrameError` naming the path and the reason.
#[pyfunction]
#[pyo3(signature = (path, channel=None, page=0, max_pixels=None, *, max_bytes=None))]
fn load_frame<'py>(
    py: Python<'py>,
    path: PathBuf,
    channel: Option<String>,
    #[pyo3(from_py_with = args::page)] page: usize,
    #[pyo3(from_py_with = args::max_pixels)] max_pixels: Option<u64>,
    #[pyo3(from_py_with = args::max_bytes)] max_bytes: Option<u64>,
) -> PyResult<Bound<'py, PyAny>> {
    let opts = DecodeOptions {
        channel,
        page,
        max_pixels: max_pixels.unwrap_or(io::DEFAULT_MAX_PIXELS),
        max_bytes: max_bytes.unwrap_or(io::DEFAULT_MAX_BYTES),
    };
    let frame = detached(py, || io::decode_frame(&path, &opts))?;
    to_array(py, frame, &path.display().to_string())
}

/// The pages of a frame file: `(pages found, why the TIFF's IFD chain breaks after them or
/// None)`; 1 page for EXR and PNG.
#[pyfunction]
fn page_chain(py: Python<'_>, path: PathBuf) -> PyResult<(usize, Option<String>)> {
    let chain = detached(py, || io::page_chain(&path))?;
    Ok((chain.pages, chain.broken))
}

/// How many TIFF IFDs the page-chain walk has read in this process (a test hook: a file's
/// pages cost one walk over its chain).
#[pyfunction]
fn tiff_ifds_read() -> u64 {
    io::ifds_read()
}

/// Selectable channel names of a frame file.
#[pyfunction]
fn list_channels(py: Python<'_>, path: PathBuf) -> PyResult<Vec<String>> {
    detached(py, || io::list_channels(&path))
}

/// The default pixel limit (8192 x 8192).
#[pyfunction]
fn default_max_pixels() -> u64 {
    io::DEFAULT_MAX_PIXELS
}

/// The default memory budget of a frame pair's work in bytes, decoding included
/// (`io::DEFAULT_MAX_BYTES`, docs/design.md §14).
#[pyfunction]
fn default_max_bytes() -> u64 {
    io::DEFAULT_MAX_BYTES
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(load_frame, m)?)?;
    m.add_function(wrap_pyfunction!(page_chain, m)?)?;
    m.add_function(wrap_pyfunction!(tiff_ifds_read, m)?)?;
    m.add_function(wrap_pyfunction!(list_channels, m)?)?;
    m.add_function(wrap_pyfunction!(default_max_pixels, m)?)?;
    m.add_function(wrap_pyfunction!(default_max_bytes, m)?)?;
    Ok(())
}
