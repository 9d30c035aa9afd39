//! `error_profile`: where a frame pair's squared error sits (`crate::defects`), for
//! `irfidelity.defects.concentrated_error`; `far_pixels`: the candidate defects of
//! `irfidelity.defects.find_defects`, and `robust_spread` their threshold. One pass each, with
//! the GIL released.

use numpy::{IntoPyArray, PyArray1, PyReadonlyArrayDyn, PyUntypedArray};
use pyo3::prelude::*;

use super::dtypes::{mask_samples, on_pair, pair_shape, PairWork};
use crate::defects::{
    far_pixels as far_pixels_of, profile, sample_spread, sampled_differences, Profile, Question, Spread,
};
use crate::kernel::Sample;

/// The `top` largest squares (largest first) and their flat indices.
type Top<'py> = (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<i64>>);

/// The temperature errors `(n, Σd, Σd², Σ|d|, within)`, as `temperature_errors` gives them.
type ErrorsTuple = (u64, f64, f64, f64, u64);

/// `(total, count, largest, (border total, border count, border box), top, errors, spread)`;
/// `spread` is `(sample size, Spread or None when empty)`.
type ProfileTuple<'py> = (
    f64,
    u64,
    f64,
    (f64, u64, Option<[usize; 4]>),
    Option<Top<'py>>,
    Option<ErrorsTuple>,
    Option<(usize, Option<Spread>)>,
);

/// `error_profile(real, sim, mask=None, *, top_share, most, border, tolerance=None,
/// spread_step=None)`: the squared error of a pair (2-D, C-contiguous, one shape; `sim` of
/// `real`'s dtype or float64), its border's share, its largest square, its `top_share` largest
/// squares when two bounds cannot rule out that they carry more than `most` of the total (see
/// `crate::defects`); with a `tolerance` on two float64 frames the temperature errors of the
/// same pass, with a `spread_step` the spread `robust_spread` gives, from the same pass.
#[pyfunction]
#[pyo3(signature = (real, sim, mask=None, *, top_share, most, border, tolerance=None, spread_step=None))]
#[allow(clippy::too_many_arguments)]
fn error_profile<'py>(
    py: Python<'py>,
    real: &Bound<'py, PyUntypedArray>,
    sim: &Bound<'py, PyUntypedArray>,
    mask: Option<PyReadonlyArrayDyn<'py, bool>>,
    top_share: f64,
    most: f64,
    border: usize,
    tolerance: Option<f64>,
    spread_step: Option<usize>,
) -> PyResult<ProfileTuple<'py>> {
    let shape = pair_shape(real, sim)?;
    let mask = mask_samples(mask.as_ref(), shape)?;
    let work = ErrorProfile { mask, shape, question: Question { top_share, most, border, tolerance, spread_step } };
    let Profile { total, count, largest, border, top, errors, spread } = on_pair(py, (real, sim, None), &work)?;
    let top = top.map(|squares| {
        let (values, index): (Vec<f64>, Vec<i64>) = squares.into_iter().map(|(v, i)| (v, i as i64)).unzip();
        (values.into_pyarray(py), index.into_pyarray(py))
    });
    let errors = errors.map(|e| (e.n, e.sum, e.squares, e.magnitudes, e.within));
    Ok((total, count, largest, (border.total, border.count, border.bounds), top, errors, spread))
}

/// `far_pixels(real, sim, mask=None, *, median, threshold, most)`: the flat indices (int64,
/// ascending) of the scored pixels with `|(sim − real) − median| > threshold`, or None when
/// there are more than `most` (`crate::defects::far_pixels`; frames as for `error_profile`).
#[pyfunction]
#[pyo3(signature = (real, sim, mask=None, *, median, threshold, most))]
fn far_pixels<'py>(
    py: Python<'py>,
    real: &Bound<'py, PyUntypedArray>,
    sim: &Bound<'py, PyUntypedArray>,
    mask: Option<PyReadonlyArrayDyn<'py, bool>>,
    median: f64,
    threshold: f64,
    most: usize,
) -> PyResult<Option<Bound<'py, PyArray1<i64>>>> {
    let shape = pair_shape(real, sim)?;
    let mask = mask_samples(mask.as_ref(), shape)?;
    let found = on_pair(py, (real, sim, None), &FarPixels { mask, median, threshold, most })?;
    Ok(found.map(|flat| flat.into_iter().map(|i| i as i64).collect::<Vec<_>>().into_pyarray(py)))
}

/// `robust_spread(real, sim, mask=None, *, step)` -> `(median, median absolute deviation, 99th
/// percentile of the absolute deviations, root mean square deviation)` of the differences
/// `sim − real` at every `step`-th pixel of every `step`-th row that is scored and finite
/// (`crate::defects::sampled_differences`; frames as for `error_profile`): the first three as
/// numpy's `median` and `quantile` give them; None when no such pixel.
#[pyfunction]
#[pyo3(signature = (real, sim, mask=None, *, step))]
fn robust_spread<'py>(
    py: Python<'py>,
    real: &Bound<'py, PyUntypedArray>,
    sim: &Bound<'py, PyUntypedArray>,
    mask: Option<PyReadonlyArrayDyn<'py, bool>>,
    step: usize,
) -> PyResult<Option<Spread>> {
    let shape = pair_shape(real, sim)?;
    let mask = mask_samples(mask.as_ref(), shape)?;
    on_pair(py, (real, sim, None), &ThresholdSample { mask, shape, step })
}

struct ErrorProfile<'a> {
    mask: Option<&'a [bool]>,
    shape: (usize, usize),
    question: Question,
}

impl PairWork for ErrorProfile<'_> {
    type Output = Profile;
    fn run<A: Sample, B: Sample>(&self, real: &[A], sim: &[B], _: Option<&[A]>) -> crate::Result<Profile> {
        profile(real, sim, self.mask, self.shape, self.question)
    }
}

struct FarPixels<'a> {
    mask: Option<&'a [bool]>,
    median: f64,
    threshold: f64,
    most: usize,
}

impl PairWork for FarPixels<'_> {
    type Output = Option<Vec<usize>>;
    fn run<A: Sample, B: Sample>(&self, real: &[A], sim: &[B], _: Option<&[A]>) -> crate::Result<Self::Output> {
        far_pixels_of(real, sim, self.mask, self.median, self.threshold, self.most)
    }
}

struct ThresholdSample<'a> {
    mask: Option<&'a [bool]>,
    shape: (usize, usize),
    step: usize,
}

impl PairWork for ThresholdSample<'_> {
    type Output = Option<Spread>;
    fn run<A: Sample, B: Sample>(&self, real: &[A], sim: &[B], _: Option<&[A]>) -> crate::Result<Self::Output> {
        let mut sample = sampled_differences(real, sim, self.mask, self.shape, self.step)?;
        Ok(sample_spread(&mut sample).1)
    }
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(error_profile, m)?)?;
    m.add_function(wrap_pyfunction!(far_pixels, m)?)?;
    m.add_function(wrap_pyfunction!(robust_spread, m)?)
}
