//! `cross_spectra` and `low_spectrum` (`crate::transfer`) for `irfidelity.transfer`: the
//! frames arrive 2-D and C-contiguous, the simulated one of the real one's dtype or float64
//! (a registered pair's resampled frame), a second real frame of the real one's dtype; the
//! passes run with the GIL released.

use numpy::ndarray::{Array2, Array3};
use numpy::{PyArray2, PyArray3, PyReadonlyArrayDyn, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use super::dtypes::{mask_samples, on_pair, pair_shape, PairArrays, PairWork};
use crate::kernel::Sample;
use crate::transfer::{self, Frames, LowSpectrum, TileSpectra, Tiling};
use crate::Error;

/// What a pass computes from the frames, whatever their sample types.
enum Pass {
    Tiles(Tiling),
    Low { factor: usize },
}

enum Output {
    Tiles(TileSpectra),
    Low(LowSpectrum),
}

/// A pass on the frames, scored pixels `mask`, of `shape`.
struct Work<'a> {
    mask: Option<&'a [bool]>,
    shape: (usize, usize),
    pass: Pass,
}

impl PairWork for Work<'_> {
    type Output = Output;
    fn run<R: Sample, S: Sample>(&self, real: &[R], sim: &[S], reference: Option<&[R]>) -> crate::Result<Output> {
        let frames = Frames { real, sim, reference, mask: self.mask, shape: self.shape };
        match self.pass {
            Pass::Tiles(tiling) => transfer::tile_spectra(&frames, tiling).map(Output::Tiles),
            Pass::Low { factor } => transfer::low_spectrum(&frames, factor).map(Output::Low),
        }
    }
}

fn dispatch(
    py: Python<'_>,
    frames: PairArrays<'_, '_>,
    mask: Option<PyReadonlyArrayDyn<'_, bool>>,
    pass: Pass,
) -> PyResult<Output> {
    let shape = pair_shape(frames.0, frames.1)?;
    if let Some(reference) = frames.2 {
        if reference.shape() != frames.0.shape() {
            return Err(Error::Shape("real_ref: expected the real frame's shape".into()).into());
        }
    }
    let mask = mask_samples(mask.as_ref(), shape)?;
    on_pair(py, frames, &Work { mask, shape, pass })
}

fn cube<'py>(py: Python<'py>, values: Vec<f64>, shape: (usize, usize, usize)) -> PyResult<Bound<'py, PyArray3<f64>>> {
    let array =
        Array3::from_shape_vec(shape, values).map_err(|e| Error::Value(format!("internal: spectra shape: {e}")))?;
    Ok(PyArray3::from_owned_array(py, array))
}

fn plane<'py>(py: Python<'py>, values: Vec<f64>, shape: (usize, usize)) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let array =
        Array2::from_shape_vec(shape, values).map_err(|e| Error::Value(format!("internal: spectrum shape: {e}")))?;
    Ok(PyArray2::from_owned_array(py, array))
}

/// `cross_spectra(real, sim, reference=None, mask=None, *, tile, step, groups, shift=(0, 0))` -> dict: the Welch
/// sums of `crate::transfer::tile_spectra` (`real`, `sim`, `cross_re`, `cross_im` — each tile
/// aligned on its own displacement, looked for around `shift` — and, with a reference,
/// `difference`: arrays `groups × tile × (tile/2 + 1)`; `tiles`, `shifts` and `boxes` per group,
/// `window_energy`, `skipped`).
#[pyfunction]
#[pyo3(signature = (real, sim, reference=None, mask=None, *, tile, step, groups, shift=(0.0, 0.0)))]
#[allow(clippy::too_many_arguments)] // the Python function's arguments, one parameter each
fn cross_spectra<'py>(
    py: Python<'py>,
    real: &Bound<'py, PyUntypedArray>,
    sim: &Bound<'py, PyUntypedArray>,
    reference: Option<&Bound<'py, PyUntypedArray>>,
    mask: Option<PyReadonlyArrayDyn<'py, bool>>,
    tile: usize,
    step: usize,
    groups: usize,
    shift: (f64, f64),
) -> PyResult<Bound<'py, PyDict>> {
    let tiling = Tiling { tile, step, groups, shift };
    let Output::Tiles(s) = dispatch(py, (real, sim, reference), mask, Pass::Tiles(tiling))? else {
        return Err(Error::Value("internal: pass".into()).into());
    };
    let shape = (s.groups, s.tile, s.tile / 2 + 1);
    let out = PyDict::new(py);
    out.set_item("tile", s.tile)?;
    out.set_item("step", step)?;
    out.set_item("tiles", s.tiles)?;
    out.set_item("window_energy", s.window_energy)?;
    out.set_item("skipped", s.skipped)?;
    out.set_item("shifts", s.shifts)?;
    out.set_item("boxes", s.boxes)?;
    out.set_item("offset", s.offset)?;
    out.set_item("real", cube(py, s.real, shape)?)?;
    out.set_item("sim", cube(py, s.sim, shape)?)?;
    out.set_item("cross_re", cube(py, s.cross_re, shape)?)?;
    out.set_item("cross_im", cube(py, s.cross_im, shape)?)?;
    if let Some(difference) = s.difference {
        out.set_item("difference", cube(py, difference, shape)?)?;
    }
    Ok(out)
}

/// `low_spectrum(real, sim, mask=None, *, factor)` -> dict: the whole-frame cross-spectrum of
/// the `factor × factor` block means (`crate::transfer::low_spectrum`): `real`, `sim`,
/// `cross_re`, `cross_im` (arrays `rows × (cols/2 + 1)`), `rows`, `cols`, `factor`, `empty`, and `sum_real`, `sum_sim`, `pixels` (the frames' sums over
/// the pixels scored and finite in both).
#[pyfunction]
#[pyo3(signature = (real, sim, mask=None, *, factor))]
fn low_spectrum<'py>(
    py: Python<'py>,
    real: &Bound<'py, PyUntypedArray>,
    sim: &Bound<'py, PyUntypedArray>,
    mask: Option<PyReadonlyArrayDyn<'py, bool>>,
    factor: usize,
) -> PyResult<Bound<'py, PyDict>> {
    let Output::Low(s) = dispatch(py, (real, sim, None), mask, Pass::Low { factor })? else {
        return Err(Error::Value("internal: pass".into()).into());
    };
    let shape = (s.rows, s.cols / 2 + 1);
    let out = PyDict::new(py);
    out.set_item("factor", s.factor)?;
    out.set_item("rows", s.rows)?;
    out.set_item("cols", s.cols)?;
    out.set_item("empty", s.empty)?;
    out.set_item("sum_real", s.sum_real)?;
    out.set_item("sum_sim", s.sum_sim)?;
    out.set_item("pixels", s.pixels)?;
    out.set_item("real", plane(py, s.real, shape)?)?;
    out.set_item("sim", plane(py, s.sim, shape)?)?;
    out.set_item("cross_re", plane(py, s.cross_re, shape)?)?;
    out.set_item("cross_im", plane(py, s.cross_im, shape)?)?;
    Ok(out)
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(cross_spectra, m)?)?;
    m.add_function(wrap_pyfunction!(low_spectrum, m)?)
}
