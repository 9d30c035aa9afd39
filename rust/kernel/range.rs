//! The data range of a frame pair: plain min/max (vectorised) and the range over the counted,
//! finite pixels that a histogram over the data spans.

use super::parallel::{cost, fold_chunks};
use super::request::Request;
use super::sample::Sample;

/// Min and max of two runs of samples by plain compares, in the native width. `None` for
/// empty runs. NaN is not ordered: callers check finiteness. Integers: one running min/max,
/// which LLVM vectorises itself (pminuw & co.). Floats: sixteen independent lanes, since
/// LLVM may not reorder float compares and a single running min/max stays a scalar `maxss`
/// chain (2 ns per value); lanes vectorise to minps/maxps.
pub(crate) fn min_max<T: Sample>(r: &[T], s: &[T]) -> Option<(T, T)> {
    const L: usize = 16;
    let first = *r.first()?;
    if T::IS_INT {
        let (mut lo, mut hi) = (first, first);
        for part in [r, s] {
            for &v in part {
                lo = if v < lo { v } else { lo };
                hi = if v > hi { v } else { hi };
            }
        }
        return Some((lo, hi));
    }
    let (mut lo, mut hi) = ([first; L], [first; L]);
    for part in [r, s] {
        let lanes = part.chunks_exact(L);
        let rest = lanes.remainder();
        for c in lanes {
            for k in 0..L {
                lo[k] = if c[k] < lo[k] { c[k] } else { lo[k] };
                hi[k] = if c[k] > hi[k] { c[k] } else { hi[k] };
            }
        }
        for &v in rest {
            lo[0] = if v < lo[0] { v } else { lo[0] };
            hi[0] = if v > hi[0] { v } else { hi[0] };
        }
    }
    let fold = |a: [T; L], pick: fn(T, T) -> bool| a.into_iter().fold(first, |m, v| if pick(v, m) { v } else { m });
    Some((fold(lo, |v, m| v < m), fold(hi, |v, m| v > m)))
}

/// Min and max over the counted pixels of both frames (f64 for floats, exact for ints).
pub(super) fn data_range<T: Sample>(r: &[T], s: &[T], req: &Request) -> Option<(f64, f64)> {
    let fold = |(a, b): (usize, usize)| -> (f64, f64) {
        if req.mask.is_none() {
            // a branch-free loop the compiler vectorises; for floats it is kept only when both
            // ends are finite (a NaN or ±Inf anywhere falls through to the careful loop)
            match min_max(&r[a..b], &s[a..b]) {
                None => return (f64::INFINITY, f64::NEG_INFINITY),
                Some((lo, hi)) if T::IS_INT || (lo.to_f64().is_finite() && hi.to_f64().is_finite()) => {
                    return (lo.to_f64(), hi.to_f64())
                }
                Some(_) => {}
            }
        }
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for i in a..b {
            if req.mask.is_some_and(|m| !m[i]) {
                continue;
            }
            let (x, y) = (r[i].to_f64(), s[i].to_f64());
            if !(x.is_finite() && y.is_finite()) {
                continue;
            }
            lo = lo.min(x.min(y));
            hi = hi.max(x.max(y));
        }
        (lo, hi)
    };
    let both = |a: (f64, f64), b: (f64, f64)| (a.0.min(b.0), a.1.max(b.1));
    let Ok((lo, hi)) = fold_chunks::<_, std::convert::Infallible>(
        r.len(),
        cost::RANGE,
        || (f64::INFINITY, f64::NEG_INFINITY),
        |acc, range| Ok(both(acc, fold(range))),
        both,
    );
    (lo <= hi).then_some((lo, hi))
}
