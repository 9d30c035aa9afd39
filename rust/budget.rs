//! The memory budget (docs/design.md §14): every allocation proportional to a frame is
//! planned from the frame's shape before it happens, and large buffers are allocated
//! fallibly, so running out of memory is an [`Error`], never an abort.
//!
//! * [`Plan`]: the bytes an operation holds at its peak, estimated from the shape; checked
//!   against the budget (`max_bytes`) before anything is allocated. Over budget is an error
//!   naming the operation, the frame size, the bytes needed and the budget.
//! * [`try_filled`], [`try_with_capacity`]: vectors through `Vec::try_reserve_exact`, an
//!   error when the system refuses the memory.
//! * [`filled`], [`with_capacity`]: the same for code that cannot return an error (deep
//!   inside registration, where a plan already holds): a refused allocation unwinds to the
//!   operation's [`guard`], which returns it as the operation's error. `resume_unwind` runs
//!   no panic hook, so nothing is printed on the way.

use std::any::Any;
use std::panic::{catch_unwind, resume_unwind, AssertUnwindSafe};

use crate::{Error, Result};

/// How an error of an operation is made: `Error::Registration` for registration,
/// `Error::Frame` for decoding, `Error::Value` otherwise.
pub type Kind = fn(String) -> Error;

/// How the budget is raised, said in every over-budget message.
const RAISE: &str = "raise max_bytes (the memory budget of one frame pair's work; in a sequence run \
                     max_memory / --max-memory divided by the workers), or work on a region or a smaller copy";

/// `bytes` for a message: the exact count and a rounded size ("2147483648 bytes (2.00 GiB)").
pub fn describe(bytes: u64) -> String {
    const UNITS: [(&str, u64); 3] = [("GiB", 1 << 30), ("MiB", 1 << 20), ("KiB", 1 << 10)];
    match UNITS.iter().find(|(_, size)| bytes >= *size) {
        Some((unit, size)) => format!("{bytes} bytes ({:.2} {unit})", bytes as f64 / *size as f64),
        None => format!("{bytes} bytes"),
    }
}

/// The estimated peak of one operation on frames of one shape.
#[derive(Clone, Debug, PartialEq)]
pub struct Plan {
    /// What is done, e.g. "registration (translation, auto)".
    pub operation: String,
    /// `(rows, cols)` of the frames.
    pub shape: (usize, usize),
    /// Bytes held at the peak (saturating: a shape too large to count is too large to hold).
    pub bytes: u64,
}

impl Plan {
    /// `per_pixel` bytes for each pixel of a `rows × cols` frame plus `fixed` bytes.
    pub fn new(operation: impl Into<String>, shape: (usize, usize), per_pixel: f64, fixed: u64) -> Plan {
        let pixels = (shape.0 as f64) * (shape.1 as f64);
        Plan { operation: operation.into(), shape, bytes: bytes_of(pixels * per_pixel).saturating_add(fixed) }
    }

    /// This plan with `bytes` more held throughout (e.g. the frames it works on).
    pub fn holding(mut self, bytes: u64) -> Plan {
        self.bytes = self.bytes.saturating_add(bytes);
        self
    }

    /// Ok when the plan fits `max_bytes`; else the error `kind` makes of a message naming the
    /// operation, the frame size, the bytes needed, the budget and how to raise it.
    pub fn check(&self, max_bytes: u64, kind: Kind) -> Result<()> {
        if self.bytes <= max_bytes {
            return Ok(());
        }
        Err(kind(format!(
            "{} of {} x {} pixel frames needs about {} at its peak, more than the memory budget of {} (max_bytes); {RAISE}",
            self.operation,
            self.shape.0,
            self.shape.1,
            describe(self.bytes),
            describe(max_bytes)
        )))
    }
}

/// `x` bytes rounded up, saturating.
fn bytes_of(x: f64) -> u64 {
    if x.is_finite() && x < u64::MAX as f64 {
        x.max(0.0).ceil() as u64
    } else {
        u64::MAX
    }
}

/// Bytes of `len` values of `T` (saturating).
pub fn size_of_vec<T>(len: usize) -> u64 {
    (len as u64).saturating_mul(std::mem::size_of::<T>() as u64)
}

fn refused<T>(len: usize) -> Error {
    Error::Value(format!(
        "out of memory: the system refused {} for a buffer (an address-space limit, or other processes, left less \
         than the memory budget); lower max_bytes so the work is refused before it starts, or free memory",
        describe(size_of_vec::<T>(len))
    ))
}

/// An empty vector with room for exactly `len` values, or an error when the memory is refused.
pub fn try_with_capacity<T>(len: usize) -> Result<Vec<T>> {
    let mut v = Vec::new();
    v.try_reserve_exact(len).map_err(|_| refused::<T>(len))?;
    Ok(v)
}

/// `len` copies of `value`, or an error when the memory is refused.
pub fn try_filled<T: Clone>(len: usize, value: T) -> Result<Vec<T>> {
    let mut v = try_with_capacity(len)?;
    v.resize(len, value);
    Ok(v)
}

/// The `len` values `iter` yields, in storage reserved at once (an error when refused).
pub fn try_collect<T>(len: usize, iter: impl Iterator<Item = T>) -> Result<Vec<T>> {
    let mut v = try_with_capacity(len)?;
    v.extend(iter.take(len));
    Ok(v)
}

/// The payload a refused allocation unwinds with, up to the operation's [`guard`].
struct Refused(Error);

/// Unwind with `err` to the nearest [`guard`] (no panic hook runs, nothing is printed).
pub fn raise(err: Error) -> ! {
    resume_unwind(Box::new(Refused(err)))
}

/// [`try_with_capacity`] where no error can be returned: a refusal unwinds to [`guard`].
pub fn with_capacity<T>(len: usize) -> Vec<T> {
    try_with_capacity(len).unwrap_or_else(|e| raise(e))
}

/// [`try_filled`] where no error can be returned: a refusal unwinds to [`guard`].
pub fn filled<T: Clone>(len: usize, value: T) -> Vec<T> {
    try_filled(len, value).unwrap_or_else(|e| raise(e))
}

/// `v.resize(len, value)` with any growth reserved fallibly: a refusal unwinds to [`guard`].
pub fn resize<T: Clone>(v: &mut Vec<T>, len: usize, value: T) {
    if len > v.capacity() {
        v.try_reserve_exact(len - v.len()).unwrap_or_else(|_| raise(refused::<T>(len)));
    }
    v.resize(len, value);
}

/// [`try_collect`] where no error can be returned: a refusal unwinds to [`guard`].
pub fn collect<T>(len: usize, iter: impl Iterator<Item = T>) -> Vec<T> {
    try_collect(len, iter).unwrap_or_else(|e| raise(e))
}

/// Run `f`; an allocation refused anywhere inside it (on this thread, or on a pool thread
/// whose panic resumes here) is returned as `kind` of the operation's error. Other panics
/// go on unwinding.
pub fn guard<T>(operation: &str, kind: Kind, f: impl FnOnce() -> Result<T>) -> Result<T> {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(result) => result,
        Err(payload) => match refused_error(&*payload) {
            Some(err) => Err(kind(format!("{operation}: {}", err.message()))),
            None => resume_unwind(payload),
        },
    }
}

/// The error of a caught panic payload when it is a refused allocation.
pub fn refused_error(payload: &(dyn Any + Send)) -> Option<Error> {
    payload.downcast_ref::<Refused>().map(|r| r.0.clone())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_plan_over_budget_is_the_operations_error() {
        let plan = Plan::new("registration (translation, auto)", (8192, 8192), 90.0, 1 << 20);
        assert_eq!(plan.bytes, 8192 * 8192 * 90 + (1 << 20));
        assert_eq!(plan.check(plan.bytes, Error::Registration), Ok(()));
        let err = plan.check(640 << 20, Error::Registration).unwrap_err();
        let Error::Registration(m) = &err else { panic!("{err:?}") };
        for part in [
            "registration (translation, auto)",
            "8192 x 8192",
            "6040846336 bytes (5.63 GiB)",
            "671088640 bytes",
            "max_bytes",
            "max_memory",
        ] {
            assert!(m.contains(part), "{part}: {m}");
        }
        let held = Plan::new("warp", (10, 10), 9.0, 0).holding(50);
        assert_eq!(held.bytes, 950);
        assert!(matches!(held.check(949, Error::Value), Err(Error::Value(_))));
        // shapes beyond counting saturate, and are refused
        assert_eq!(Plan::new("x", (usize::MAX, usize::MAX), 8.0, 1).bytes, u64::MAX);
        assert_eq!(describe(1536), "1536 bytes (1.50 KiB)");
        assert_eq!(describe(12), "12 bytes");
    }

    #[test]
    fn refused_allocations_are_errors() {
        let huge = usize::MAX / 4;
        let err = try_filled(huge, 0u64).unwrap_err();
        assert!(matches!(&err, Error::Value(m) if m.contains("out of memory")), "{err:?}");
        assert!(try_with_capacity::<f64>(huge).is_err());
        assert!(try_collect(huge, std::iter::repeat(1u8)).is_err());
        assert_eq!(try_filled(3, 7u8).unwrap(), vec![7, 7, 7]);
        assert_eq!(try_collect(2, 1..).unwrap(), vec![1, 2]);
    }

    #[test]
    fn a_refusal_deep_inside_unwinds_to_the_guard() {
        let deep = || -> Vec<f64> { filled(usize::MAX / 16, 0.0) };
        let err = guard("registration", Error::Registration, || Ok(deep().len())).unwrap_err();
        assert!(matches!(&err, Error::Registration(m) if m.starts_with("registration: out of memory")), "{err:?}");
        // through a pool thread too
        let err = guard("ssim map", Error::Value, || {
            let (a, b) =
                rayon::join(|| with_capacity::<u8>(4).capacity(), || collect::<u32>(usize::MAX / 8, 0..).len());
            Ok(a + b)
        })
        .unwrap_err();
        assert!(matches!(&err, Error::Value(m) if m.starts_with("ssim map: out of memory")), "{err:?}");
        assert_eq!(guard("fine", Error::Value, || Ok(filled(2, 1u8))), Ok(vec![1, 1]));
        // other panics are not swallowed
        let other = catch_unwind(|| guard("x", Error::Value, || -> Result<()> { panic!("a bug") }));
        assert!(other.is_err());
    }
}
