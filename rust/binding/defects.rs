//! `error_profile`: where a frame pair's squared error sits (`crate::defects`), for
//! `irfidelity.defects.concentrated_error`; one pass with the GIL released.

use numpy::{
    IntoPyArray, PyArray1, PyArrayDescrMethods, PyArrayDyn, PyReadonlyArrayDyn, PyUntypedArray, PyUntypedArrayMethods,
};
use pyo3::prelude::*;

use super::detached;
use super::dtypes::{contiguous, mask_samples, pair_shape, unsupported_dtype};
use super::stats::readonly;
use crate::defects::{profile, Profile, Question};
use crate::kernel::Sample;

/// The `top` largest squares (largest first) and their flat indices.
type Top<'py> = (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<i64>>);

/// `(total, count, largest, (border total, border count, border box), top)`.
type ProfileTuple<'py> = (f64, u64, f64, (f64, u64, Option<[usize; 4]>), Option<Top<'py>>);

/// `error_profile(real, sim, mask=None, *, top_share, most, border)`: the squared error of a
/// pair (2-D, C-contiguous, one shape; `sim` of `real`'s dtype or float64), its border's
/// share, its largest square, and its `top_share` largest squares when two bounds cannot rule out that they carry
/// more than `most` of the total (see `crate::defects`).
#[pyfunction]
#[pyo3(signature = (real, sim, mask=None, *, top_share, most, border))]
fn error_profile<'py>(
    py: Python<'py>,
    real: &Bound<'py, PyUntypedArray>,
    sim: &Bound<'py, PyUntypedArray>,
    mask: Option<PyReadonlyArrayDyn<'py, bool>>,
    top_share: f64,
    most: f64,
    border: usize,
) -> PyResult<ProfileTuple<'py>> {
    let shape = pair_shape(real, sim)?;
    let mask = mask_samples(mask.as_ref(), shape)?;
    let question = Question { top_share, most, border };
    let dtype = real.dtype();
    let Profile { total, count, largest, border, top } =
        with_frame_dtype!(py, &dtype, |T| typed::<T>(py, (real, sim), mask, shape, question))
            .unwrap_or_else(|| Err(unsupported_dtype("real", &dtype).into()))?;
    let top = top.map(|squares| {
        let (values, index): (Vec<f64>, Vec<i64>) = squares.into_iter().map(|(v, i)| (v, i as i64)).unzip();
        (values.into_pyarray(py), index.into_pyarray(py))
    });
    Ok((total, count, largest, (border.total, border.count, border.bounds), top))
}

/// [`profile`] of a `T` frame against a `T` or float64 one (a registered pair's resampled
/// frame), without the GIL.
fn typed<T: numpy::Element + Sample>(
    py: Python<'_>,
    (real, sim): (&Bound<'_, PyUntypedArray>, &Bound<'_, PyUntypedArray>),
    mask: Option<&[bool]>,
    shape: (usize, usize),
    question: Question,
) -> PyResult<Profile> {
    let Ok(real_array) = real.cast::<PyArrayDyn<T>>() else {
        return Err(crate::Error::Value("internal: real frame dtype".into()).into());
    };
    let real_view = readonly(real_array)?;
    let r = contiguous(&real_view, "the real frame")?;
    if let Ok(sim) = sim.cast::<PyArrayDyn<T>>() {
        let sim = readonly(sim)?;
        let s = contiguous(&sim, "the simulated frame")?;
        return detached(py, || profile(r, s, mask, shape, question));
    }
    if let Ok(sim) = sim.cast::<PyArrayDyn<f64>>() {
        let sim = readonly(sim)?;
        let s = contiguous(&sim, "the simulated frame")?;
        return detached(py, || profile(r, s, mask, shape, question));
    }
    Err(crate::Error::Shape(format!(
        "sim: dtype {} with a {} real frame: expected the real frame's dtype or float64",
        sim.dtype(),
        real.dtype()
    ))
    .into())
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(error_profile, m)?)
}
