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
