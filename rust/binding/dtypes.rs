//! The one dispatch from a numpy dtype to its Rust sample type (`with_frame_dtype!`, in
//! scope in the modules declared after this one; the names are `crate::dtype::Dtype`'s), and
//! the checks every binding makes of the frames it is given.

/// Calls `$m!($args … list)` with the list of supported `Rust sample type => Dtype variant`
/// (the names are `crate::dtype::Dtype`'s).
macro_rules! frame_dtypes {
    ($m:ident, $($args:tt)*) => {
        $m! {
            $($args)* u8 => U8, u16 => U16, i16 => I16, u32 => U32,
            half::f16 => F16, f32 => F32, f64 => F64
        }
    };
}

/// `Some($body)` evaluated with the type `$T` standing for the Rust sample type of the numpy
/// dtype `$dtype`, or `None` when the dtype is not supported.
macro_rules! with_frame_dtype {
    ($py:expr, $dtype:expr, |$T:ident| $body:expr) => {
        frame_dtypes!(with_frame_dtype, @each $py, $dtype, $T, $body;)
    };
    (@each $py:expr, $dtype:expr, $T:ident, $body:expr; $($t:ty => $variant:ident),*) => {{
        let dtype = $dtype;
        $(
            if dtype.is_equiv_to(&numpy::dtype::<$t>($py)) {
                type $T = $t;
                Some($body)
            } else
        )* {
            None
        }
    }};
}

/// The frame dtypes the kernels accept, by name (exposed as `_core.SUPPORTED_DTYPES`).
pub(crate) fn supported_dtypes() -> [&'static str; 7] {
    crate::dtype::Dtype::ALL.map(crate::dtype::Dtype::name)
}

/// The one error for an array whose dtype no kernel takes (`what` names the array).
pub(crate) fn unsupported_dtype(what: &str, dtype: impl std::fmt::Display) -> crate::Error {
    crate::Error::Shape(format!(
        "{what}: unsupported frame dtype {dtype}: expected one of {}",
        crate::dtype::Dtype::names()
    ))
}

/// `(rows, cols)` of the real frame when the simulated one has its shape: the one check of
/// a frame pair's shapes (both 2-D, one shape) for every binding that takes a pair.
pub(crate) fn pair_shape(
    real: &pyo3::Bound<'_, numpy::PyUntypedArray>,
    sim: &pyo3::Bound<'_, numpy::PyUntypedArray>,
) -> crate::Result<(usize, usize)> {
    use numpy::PyUntypedArrayMethods;
    for (what, frame) in [("real", real), ("sim", sim)] {
        if frame.ndim() != 2 {
            return Err(crate::Error::Shape(format!(
                "{what}: expected a 2-D frame, got shape {}",
                shape_text(frame.shape())
            )));
        }
    }
    if real.shape() != sim.shape() {
        return Err(crate::Error::Shape(format!(
            "real and sim frames differ in shape: {} vs {}",
            shape_text(real.shape()),
            shape_text(sim.shape())
        )));
    }
    Ok((real.shape()[0], real.shape()[1]))
}

/// A shape as numpy prints it: `(2, 3)`, `(5,)`.
pub(crate) fn shape_text(shape: &[usize]) -> String {
    let dims: Vec<String> = shape.iter().map(usize::to_string).collect();
    if dims.len() == 1 {
        format!("({},)", dims[0])
    } else {
        format!("({})", dims.join(", "))
    }
}

/// The contiguous samples of an array the Python layer laid out (C order), or an internal
/// error naming `what`.
pub(crate) fn contiguous<'a, T: numpy::Element>(
    array: &'a numpy::PyReadonlyArrayDyn<'_, T>,
    what: &str,
) -> crate::Result<&'a [T]> {
    array.as_slice().map_err(|_| crate::Error::Value(format!("internal: {what} must be C-contiguous")))
}

/// A bool mask of `rows × cols` samples, contiguous, or None.
pub(crate) fn mask_samples<'a>(
    mask: Option<&'a numpy::PyReadonlyArrayDyn<'_, bool>>,
    (rows, cols): (usize, usize),
) -> crate::Result<Option<&'a [bool]>> {
    let Some(mask) = mask else { return Ok(None) };
    let samples = contiguous(mask, "the mask")?;
    if samples.len() != rows * cols {
        return Err(crate::Error::Shape(format!("mask must have the frames' shape ({rows}, {cols})")));
    }
    Ok(Some(samples))
}

/// A computation on a frame pair whose real frame (and second real frame, when there is one)
/// has one supported sample type `A` and whose simulated frame has `A` or float64 (a registered
/// pair's resampled frame): what [`on_pair`] runs once the sample types are known.
pub(crate) trait PairWork: Sync {
    type Output: Send;
    fn run<A: crate::kernel::Sample, B: crate::kernel::Sample>(
        &self,
        real: &[A],
        sim: &[B],
        reference: Option<&[A]>,
    ) -> crate::Result<Self::Output>;
}

/// Frames as a binding receives them: the real one, the simulated one, a second real one.
pub(crate) type PairArrays<'a, 'py> = (
    &'a pyo3::Bound<'py, numpy::PyUntypedArray>,
    &'a pyo3::Bound<'py, numpy::PyUntypedArray>,
    Option<&'a pyo3::Bound<'py, numpy::PyUntypedArray>>,
);

/// `work` on C-contiguous frames (shapes checked by the caller) with the GIL released: the one
/// dispatch of a pair's sample types, naming a simulated or second real frame of another dtype.
pub(crate) fn on_pair<W: PairWork>(
    py: pyo3::Python<'_>,
    frames: PairArrays<'_, '_>,
    work: &W,
) -> pyo3::PyResult<W::Output> {
    use numpy::{PyArrayDescrMethods, PyUntypedArrayMethods};
    let dtype = frames.0.dtype();
    with_frame_dtype!(py, &dtype, |T| typed::<T, W>(py, frames, work))
        .unwrap_or_else(|| Err(unsupported_dtype("real", &dtype).into()))
}

fn typed<R: numpy::Element + crate::kernel::Sample, W: PairWork>(
    py: pyo3::Python<'_>,
    (real, sim, reference): PairArrays<'_, '_>,
    work: &W,
) -> pyo3::PyResult<W::Output> {
    use numpy::{PyArrayDyn, PyUntypedArrayMethods};
    let Ok(real) = real.cast::<PyArrayDyn<R>>() else {
        return Err(crate::Error::Value("internal: real frame dtype".into()).into());
    };
    let real_view = super::stats::readonly(real)?;
    let real = contiguous(&real_view, "the real frame")?;
    let reference_view = match reference {
        None => None,
        Some(r) => Some(super::stats::readonly(r.cast::<PyArrayDyn<R>>().map_err(|_| {
            crate::Error::Shape(format!(
                "real_ref: dtype {} with a {} real frame: expected the same dtype",
                r.dtype(),
                real_view.dtype()
            ))
        })?)?),
    };
    let reference = reference_view.as_ref().map(|view| contiguous(view, "the second real frame")).transpose()?;
    if let Ok(sim) = sim.cast::<PyArrayDyn<R>>() {
        let view = super::stats::readonly(sim)?;
        let sim = contiguous(&view, "the simulated frame")?;
        return super::detached(py, || work.run(real, sim, reference));
    }
    if let Ok(sim) = sim.cast::<PyArrayDyn<f64>>() {
        let view = super::stats::readonly(sim)?;
        let sim = contiguous(&view, "the simulated frame")?;
        return super::detached(py, || work.run(real, sim, reference));
    }
    Err(crate::Error::Shape(format!(
        "sim: dtype {} with a {} real frame: expected the real frame's dtype or float64",
        sim.dtype(),
        real_view.dtype()
    ))
    .into())
}
