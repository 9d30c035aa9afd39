//! The frame sample types, listed once: every part of the crate that names a sample type
//! (decoding, the kernels' dispatch, the noise sums, the Python binding's
//! `_core.SUPPORTED_DTYPES` and its messages) takes the names from [`Dtype`].

/// A frame's sample type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dtype {
    U8,
    U16,
    I16,
    U32,
    F16,
    F32,
    F64,
}

impl Dtype {
    /// Every supported sample type, in the order of `_core.SUPPORTED_DTYPES` (and of the
    /// noise sums' serialised dtype byte).
    pub const ALL: [Dtype; 7] = [Dtype::U8, Dtype::U16, Dtype::I16, Dtype::U32, Dtype::F16, Dtype::F32, Dtype::F64];

    /// The numpy name of the sample type ("uint16", "float32", ...).
    pub fn name(self) -> &'static str {
        match self {
            Dtype::U8 => "uint8",
            Dtype::U16 => "uint16",
            Dtype::I16 => "int16",
            Dtype::U32 => "uint32",
            Dtype::F16 => "float16",
            Dtype::F32 => "float32",
            Dtype::F64 => "float64",
        }
    }

    pub fn from_name(name: &str) -> Option<Dtype> {
        Dtype::ALL.into_iter().find(|d| d.name() == name)
    }

    /// The names of every supported sample type, for messages: "uint8, uint16, ...".
    pub fn names() -> String {
        Dtype::ALL.map(Dtype::name).join(", ")
    }

    /// Bytes of one sample.
    pub fn size(self) -> usize {
        match self {
            Dtype::U8 => 1,
            Dtype::U16 | Dtype::I16 | Dtype::F16 => 2,
            Dtype::U32 | Dtype::F32 => 4,
            Dtype::F64 => 8,
        }
    }

    pub fn is_int(self) -> bool {
        matches!(self, Dtype::U8 | Dtype::U16 | Dtype::I16 | Dtype::U32)
    }

    /// Smallest and largest value of an integer type.
    pub fn int_range(self) -> Option<(i64, i64)> {
        Some(match self {
            Dtype::U8 => (0, u8::MAX as i64),
            Dtype::U16 => (0, u16::MAX as i64),
            Dtype::I16 => (i16::MIN as i64, i16::MAX as i64),
            Dtype::U32 => (0, u32::MAX as i64),
            _ => return None,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::Dtype;

    #[test]
    fn names_round_trip() {
        for d in Dtype::ALL {
            assert_eq!(Dtype::from_name(d.name()), Some(d));
        }
        assert_eq!(Dtype::from_name("int32"), None);
        assert_eq!(Dtype::names(), "uint8, uint16, int16, uint32, float16, float32, float64");
    }
}
