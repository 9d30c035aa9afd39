//! The frame dtypes the bindings accept, listed once, and the one dispatch from a numpy
//! dtype to its Rust sample type (`with_frame_dtype!`, in scope in the modules declared
//! after this one).

/// Calls `$m!($args … list)` with the list of supported `Rust sample type => numpy dtype name`.
macro_rules! frame_dtypes {
    ($m:ident, $($args:tt)*) => {
        $m! {
            $($args)* u8 => "uint8", u16 => "uint16", i16 => "int16", u32 => "uint32",
            half::f16 => "float16", f32 => "float32", f64 => "float64"
        }
    };
}

macro_rules! dtype_names {
    ($($t:ty => $name:literal),*) => {
        /// The frame dtypes the kernels accept (exposed as `_core.SUPPORTED_DTYPES`).
        pub(crate) const SUPPORTED_DTYPES: &[&str] = &[$($name),*];
    };
}
frame_dtypes!(dtype_names,);

/// `Some($body)` evaluated with the type `$T` standing for the Rust sample type of the numpy
/// dtype `$dtype`, or `None` when the dtype is not supported.
macro_rules! with_frame_dtype {
    ($py:expr, $dtype:expr, |$T:ident| $body:expr) => {
        frame_dtypes!(with_frame_dtype, @each $py, $dtype, $T, $body;)
    };
    (@each $py:expr, $dtype:expr, $T:ident, $body:expr; $($t:ty => $name:literal),*) => {{
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

/// The one error for an array whose dtype no kernel takes (`what` names the array).
pub(crate) fn unsupported_dtype(what: &str, dtype: impl std::fmt::Display) -> crate::Error {
    crate::Error::Shape(format!(
        "{what}: unsupported frame dtype {dtype}: expected one of {}",
        SUPPORTED_DTYPES.join(", ")
    ))
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
