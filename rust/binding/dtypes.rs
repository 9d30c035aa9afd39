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
