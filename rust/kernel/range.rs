//! The data range of a frame pair: plain min/max (vectorised) and the range over the counted,
//! finite pixels that a histogram over the data spans.

use super::parallel::{cost, fold_chunks};
use super::request::Request;
use super::sample::{all_finite, Sample};

avx2_copy! {
    /// Min and max of two runs of samples by plain compares, in the native width. `None` for
    /// empty runs. NaN is not ordered: callers check finiteness. Integers: one running min/max,
    /// which LLVM vectorises itself (pminuw & co.). Floats: sixteen independent lanes, since
    /// LLVM may not reorder float compares and a single running min/max stays a scalar `maxss`
    /// chain (2 ns per value); lanes vectorise to minps/maxps (whole AVX2 registers in the
    /// AVX2 copy).
    pub(crate) fn min_max[T: Sample](r: &[T], s: &[T]) -> Option<(T, T)>
    => min_max_avx2, min_max_portable
}

#[inline(always)]
fn min_max_portable<T: Sample>(r: &[T], s: &[T]) -> Option<(T, T)> {
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

/// [`min_max`] of a float64 run (temperatures, resampled frames), through explicit AVX2
/// `vminpd`/`vmaxpd` when the CPU has it (neither [`min_max`]'s generic compares nor
/// `f64::min` vectorise to them). A NaN or ±Inf anywhere makes both ends NaN, so the caller
/// takes its careful loop.
fn float64_ends(values: &[f64]) -> Option<(f64, f64)> {
    #[cfg(target_arch = "x86_64")]
    if super::use_avx2() {
        // SAFETY: `use_avx2` is true only when the CPU reports AVX2.
        return unsafe { float64_ends_avx2(values) };
    }
    float64_ends_portable(values)
}

fn float64_ends_portable(values: &[f64]) -> Option<(f64, f64)> {
    let first = *values.first()?;
    // v · 0 is 0 for a finite value and NaN for NaN or ±Inf, and a NaN stays in the sum
    let (lo, hi, probe) = values.iter().fold((first, first, 0.0), |(lo, hi, probe), &v| {
        (if v < lo { v } else { lo }, if v > hi { v } else { hi }, probe + v * 0.0)
    });
    Some(if probe.is_nan() { (f64::NAN, f64::NAN) } else { (lo, hi) })
}

/// [`float64_ends`] eight values per step (two vectors per end), the remainder portably.
///
/// # Safety
/// The CPU supports AVX2 (the loads stay within the slice for any length).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn float64_ends_avx2(values: &[f64]) -> Option<(f64, f64)> {
    use std::arch::x86_64::*;
    let first = *values.first()?;
    let full = values.len() / 8 * 8;
    let (zero, start) = (_mm256_setzero_pd(), _mm256_set1_pd(first));
    let (mut lo, mut hi, mut probe) = ([start; 2], [start; 2], [zero; 2]);
    for i in (0..full).step_by(8) {
        for h in 0..2 {
            // SAFETY: i + 4h + 4 <= i + 8 <= full <= values.len()
            let v = unsafe { _mm256_loadu_pd(values.as_ptr().add(i + 4 * h)) };
            lo[h] = _mm256_min_pd(lo[h], v);
            hi[h] = _mm256_max_pd(hi[h], v);
            probe[h] = _mm256_add_pd(probe[h], _mm256_mul_pd(v, zero));
        }
    }
    let lanes = |v: [__m256d; 2]| {
        let mut out = [0.0f64; 8];
        // SAFETY: `out` holds 8 doubles, two 4-lane stores at 0 and 4
        unsafe {
            _mm256_storeu_pd(out.as_mut_ptr(), v[0]);
            _mm256_storeu_pd(out.as_mut_ptr().add(4), v[1]);
        }
        out
    };
    let (lo, hi, probe) = (lanes(lo), lanes(hi), lanes(probe));
    let (rest_lo, rest_hi) = float64_ends_portable(&values[full..]).unwrap_or((first, first));
    if probe.iter().any(|p| p.is_nan()) || rest_lo.is_nan() {
        return Some((f64::NAN, f64::NAN));
    }
    Some((lo.iter().fold(rest_lo, |m, &v| m.min(v)), hi.iter().fold(rest_hi, |m, &v| m.max(v))))
}

/// Min and max over the counted pixels of both frames (f64 for floats, exact for ints).
pub(super) fn data_range<T: Sample>(r: &[T], s: &[T], req: &Request) -> Option<(f64, f64)> {
    data_ranges(r, s, req).map(|(a, b)| (a.0.min(b.0), a.1.max(b.1)))
}

/// Each frame's min and max over the counted pixels (a pixel pair counts when the mask keeps
/// it and, for floats, both values are finite): `(real range, simulated range)`.
pub(super) fn data_ranges<T: Sample>(r: &[T], s: &[T], req: &Request) -> Option<((f64, f64), (f64, f64))> {
    type Ranges = ((f64, f64), (f64, f64));
    const EMPTY: (f64, f64) = (f64::INFINITY, f64::NEG_INFINITY);
    let fold = |(a, b): (usize, usize)| -> Ranges {
        if req.mask.is_none() {
            // a branch-free loop the compiler vectorises; for floats it is kept only when all
            // ends are finite (a NaN or ±Inf anywhere falls through to the careful loop)
            let ends = |v: &[T]| match T::as_f64(v) {
                Some(v) => float64_ends(v),
                None => min_max(v, &[]).map(|(lo, hi)| (lo.to_f64(), hi.to_f64())),
            };
            match (ends(&r[a..b]), ends(&s[a..b])) {
                (None, _) | (_, None) => return (EMPTY, EMPTY),
                (Some(x), Some(y)) if T::IS_INT || [x.0, x.1, y.0, y.1].iter().all(|v| v.is_finite()) => return (x, y),
                _ => {}
            }
        }
        let (mut rr, mut ss) = (EMPTY, EMPTY);
        for i in a..b {
            if req.mask.is_some_and(|m| !m[i]) {
                continue;
            }
            let (x, y) = (r[i].to_f64(), s[i].to_f64());
            if !(x.is_finite() && y.is_finite()) {
                continue;
            }
            rr = (rr.0.min(x), rr.1.max(x));
            ss = (ss.0.min(y), ss.1.max(y));
        }
        (rr, ss)
    };
    let union = |a: (f64, f64), b: (f64, f64)| (a.0.min(b.0), a.1.max(b.1));
    let both = |a: Ranges, b: Ranges| (union(a.0, b.0), union(a.1, b.1));
    let Ok((rr, ss)) = fold_chunks::<_, std::convert::Infallible>(
        r.len(),
        cost::RANGE,
        || (EMPTY, EMPTY),
        |acc, range| Ok(both(acc, fold(range))),
        both,
    );
    (rr.0 <= rr.1 && ss.0 <= ss.1).then_some((rr, ss))
}

/// One frame's min and max over the pixels `mask` keeps whose values are finite (None when
/// there are none), and whether a kept pixel is not finite.
pub fn scored_range<T: Sample>(values: &[T], mask: Option<&[bool]>) -> (Option<(f64, f64)>, bool) {
    type Part = ((f64, f64), bool);
    const EMPTY: (f64, f64) = (f64::INFINITY, f64::NEG_INFINITY);
    let fold = |(a, b): (usize, usize)| -> Part {
        let run = &values[a..b];
        if mask.is_none() {
            // vectorised ends; a NaN or ±Inf makes them NaN, and the careful loop follows
            let ends = match T::as_f64(run) {
                Some(v) => float64_ends(v),
                None if all_finite(run) => min_max(run, &[]).map(|(lo, hi)| (lo.to_f64(), hi.to_f64())),
                None => Some((f64::NAN, f64::NAN)),
            };
            match ends {
                None => return (EMPTY, false),
                Some((lo, hi)) if lo.is_finite() && hi.is_finite() => return ((lo, hi), false),
                _ => {}
            }
        }
        let (mut range, mut bad) = (EMPTY, false);
        for (i, v) in (a..b).zip(run) {
            if mask.is_some_and(|m| !m[i]) {
                continue;
            }
            let v = v.to_f64();
            if v.is_finite() {
                range = (range.0.min(v), range.1.max(v));
            } else {
                bad = true;
            }
        }
        (range, bad)
    };
    let both = |(x, p): Part, (y, q): Part| ((x.0.min(y.0), x.1.max(y.1)), p || q);
    let Ok((range, bad)) = fold_chunks::<_, std::convert::Infallible>(
        values.len(),
        cost::RANGE,
        || (EMPTY, false),
        |acc, range| Ok(both(acc, fold(range))),
        both,
    );
    ((range.0 <= range.1).then_some(range), bad)
}

/// Most pixels sampled to find a frame's bulk for [`robust_range`] ...
const BULK_SAMPLES: usize = 1 << 14;
/// ... in evenly spaced runs of this many consecutive pixels (a cache line of float32), so the
/// sample reads a sixteenth of a large frame's memory rather than a line per sampled pixel.
const BULK_RUN: usize = 16;
/// The bulk of a frame: its values between these quantiles of the sample.
const BULK_QUANTILE: f64 = 1e-3;
/// How far beyond its bulk a frame's bins reach, in bulk spans: values further out (a few
/// dead, hot or stuck pixels) land in the edge bins instead of stretching every bin.
const BULK_MARGIN: f64 = 1.0;

/// The pixels [`bulk`] samples from a frame of `len` that `keep`: runs of [`BULK_RUN`]
/// starting every `stride` pixels, at most [`BULK_SAMPLES`] in all (every pixel of a small
/// frame), as `value` gives them.
fn bulk_sample<K>(len: usize, keep: impl Fn(usize) -> bool, value: impl Fn(usize) -> K) -> Vec<K> {
    let mut out = Vec::with_capacity(BULK_SAMPLES.min(len));
    for start in (0..len).step_by(bulk_stride(len)) {
        for i in start..(start + BULK_RUN).min(len) {
            if keep(i) {
                out.push(value(i));
            }
        }
    }
    out
}

/// [`bulk_sample`] of a frame whose every pixel counts: the same pixels, copied run by run.
fn whole_sample<T: Sample, K>(values: &[T], value: impl Fn(T) -> K) -> Vec<K> {
    let len = values.len();
    let mut out = Vec::with_capacity(BULK_SAMPLES.min(len));
    for start in (0..len).step_by(bulk_stride(len)) {
        out.extend(values[start..(start + BULK_RUN).min(len)].iter().map(|&v| value(v)));
    }
    out
}

/// How far apart [`bulk_sample`]'s runs start in a frame of `len` pixels.
fn bulk_stride(len: usize) -> usize {
    len.div_ceil(BULK_SAMPLES / BULK_RUN).max(BULK_RUN)
}

/// A frame's bulk: the 0.1 %, 50 % and 99.9 % quantiles of [`bulk_sample`]'s pixels among
/// those that count (kept by the mask and, with `other` the other frame, finite in both;
/// `other` None: every pixel is known finite); None for fewer than two such pixels. `full` is
/// the frame's min..max over the counted pixels: integer samples within a span of 2^20 levels
/// are counted per level rather than selected.
pub(super) fn bulk<T: Sample>(values: &[T], other: Option<&[T]>, req: &Request, full: (f64, f64)) -> Option<Bulk> {
    let kept = |i: usize| req.mask.is_none_or(|m| m[i]);
    if T::IS_INT {
        let level = |v: T| v.to_f64() as i64;
        let (lo, span) = (full.0 as i64, (full.1 - full.0) as usize);
        let ranks = match req.mask {
            // every pixel counts, so every one lies within `full`: counted where it is read
            None if span < 1 << 20 => whole_counts(values, lo, span),
            None => quantiles(&mut whole_sample(values, level)),
            Some(_) => {
                let sample = bulk_sample(values.len(), kept, |i| level(values[i]));
                if span < 1 << 20 {
                    counted_quantiles(&sample, lo, span)
                } else {
                    quantiles(&mut { sample })
                }
            }
        };
        return ranks.map(|[a, m, b]| Bulk { low: a as f64, median: m as f64, high: b as f64 });
    }
    let finite = |i: usize| values[i].to_f64().is_finite() && other.is_none_or(|o| o[i].to_f64().is_finite());
    let sample = bulk_sample(values.len(), |i| kept(i) && finite(i), |i| values[i].to_f64());
    bucketed_quantiles(sample, full).map(|[low, median, high]| Bulk { low, median, high })
}

/// Buckets [`bucketed_quantiles`] sorts a float sample into first.
const BUCKETS: usize = 1024;

/// [`quantiles`] of finite values within `full` (lo, hi): each value's bucket of `full` counted
/// first, then each quantile selected within its own bucket only.
fn bucketed_quantiles(mut sample: Vec<f64>, (lo, hi): (f64, f64)) -> Option<[f64; 3]> {
    let scale = BUCKETS as f64 / (hi - lo);
    if sample.len() < 2 || !(scale.is_finite() && scale > 0.0) || sample.iter().any(|v| !(lo..=hi).contains(v)) {
        return quantiles(&mut sample); // finite values: partial_cmp orders them all
    }
    let bucket = |v: f64| (((v - lo) * scale) as usize).min(BUCKETS - 1); // monotone in v
    let mut counts = [0usize; BUCKETS];
    for &v in &sample {
        counts[bucket(v)] += 1;
    }
    // each rank's bucket, and its rank within that bucket
    let found = ranks(sample.len()).map(|rank| {
        let (mut b, mut below) = (0usize, 0usize);
        while below + counts[b] <= rank {
            below += counts[b];
            b += 1;
        }
        (b, rank - below)
    });
    // the three buckets' values, gathered in one pass over the sample
    let mut inside = found.map(|(b, _)| Vec::with_capacity(counts[b]));
    for &v in &sample {
        let b = bucket(v);
        for (members, &(wanted, _)) in inside.iter_mut().zip(&found) {
            if b == wanted {
                members.push(v);
            }
        }
    }
    let mut out = [0.0; 3];
    for ((value, members), &(_, rank)) in out.iter_mut().zip(&mut inside).zip(&found) {
        let (_, &mut selected, _) = members.select_nth_unstable_by(rank, f64::total_cmp);
        *value = selected;
    }
    Some(out)
}

/// Where most of a frame's values lie: its 0.1 %, 50 % and 99.9 % quantiles ([`bulk`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Bulk {
    pub(super) low: f64,
    pub(super) median: f64,
    pub(super) high: f64,
}

/// The ranks [`quantiles`] picks in a sample of `n` (≥ 2): 0.1 %, 50 %, 99.9 %.
fn ranks(n: usize) -> [usize; 3] {
    let last = (n - 1) as f64;
    [BULK_QUANTILE, 0.5, 1.0 - BULK_QUANTILE].map(|q| (q * last).round() as usize)
}

/// [`quantiles`] of integer values within `lo..=lo + span`, by counting each level.
fn counted_quantiles(sample: &[i64], lo: i64, span: usize) -> Option<[i64; 3]> {
    if sample.len() < 2 {
        return None;
    }
    let mut counts = vec![0u32; span + 1];
    for &v in sample {
        let Some(count) = usize::try_from(v - lo).ok().and_then(|k| counts.get_mut(k)) else {
            return quantiles(&mut sample.to_vec()); // a value outside the range: select instead
        };
        *count += 1;
    }
    ranked_levels(&counts, lo, sample.len())
}

/// [`counted_quantiles`] of [`whole_sample`]'s pixels of an integer frame whose every value
/// lies within `lo..=lo + span`, counted as they are read (no sample is stored).
fn whole_counts<T: Sample>(values: &[T], lo: i64, span: usize) -> Option<[i64; 3]> {
    if span < COUNT_WAYS_MAX_LEVELS {
        whole_counts_in::<T, COUNT_WAYS>(values, lo, span + 1)
    } else {
        whole_counts_in::<T, 1>(values, lo, span + 1)
    }
}

/// Count tables [`whole_counts`] interleaves ...
const COUNT_WAYS: usize = 4;
/// ... for spans of fewer levels than this (larger tables would not stay in cache).
const COUNT_WAYS_MAX_LEVELS: usize = 1 << 14;

/// [`whole_counts`] over `WAYS` tables of `levels` counts, pixel `k` of a run counted in table
/// `k % WAYS`: neighbouring pixels often share a level, and in one table each addition would
/// wait for the last; the tables are summed before ranking.
fn whole_counts_in<T: Sample, const WAYS: usize>(values: &[T], lo: i64, levels: usize) -> Option<[i64; 3]> {
    let mut counts = vec![0u32; WAYS * levels];
    let mut sampled = 0;
    {
        let mut split = counts.chunks_exact_mut(levels);
        let mut tables: [&mut [u32]; WAYS] = std::array::from_fn(|_| split.next().unwrap_or_default());
        // within the range by the caller's contract; a value outside it (wrapping to a level
        // past the table) is left uncounted
        let mut add = |table: &mut [u32], v: &T| {
            if let Some(count) = table.get_mut((v.to_i64() - lo) as usize) {
                *count += 1;
                sampled += 1;
            }
        };
        for start in (0..values.len()).step_by(bulk_stride(values.len())) {
            let run = &values[start..(start + BULK_RUN).min(values.len())];
            let mut groups = run.chunks_exact(WAYS);
            for group in &mut groups {
                for (table, v) in tables.iter_mut().zip(group) {
                    add(table, v);
                }
            }
            for (table, v) in tables.iter_mut().zip(groups.remainder()) {
                add(table, v);
            }
        }
    }
    if sampled < 2 {
        return None;
    }
    let (first, rest) = counts.split_at_mut(levels);
    for table in rest.chunks_exact(levels) {
        first.iter_mut().zip(table).for_each(|(total, &c)| *total += c);
    }
    ranked_levels(first, lo, sampled)
}

/// The 0.1 %, 50 % and 99.9 % quantiles of `n` values counted per level from `lo`.
fn ranked_levels(counts: &[u32], lo: i64, n: usize) -> Option<[i64; 3]> {
    // the value of rank k (0-based) is the first level whose running count exceeds k
    let wanted = ranks(n);
    let (mut out, mut next, mut seen) = ([0i64; 3], 0usize, 0usize);
    for (level, &c) in counts.iter().enumerate() {
        seen += c as usize;
        while next < 3 && seen > wanted[next] {
            out[next] = lo + level as i64;
            next += 1;
        }
        if next == 3 {
            return Some(out);
        }
    }
    None
}

/// The 0.1 %, 50 % and 99.9 % quantiles of a sample (reordered); None for fewer than two
/// values.
fn quantiles<K: Copy + PartialOrd>(sample: &mut [K]) -> Option<[K; 3]> {
    if sample.len() < 2 {
        return None;
    }
    let [lo_at, mid_at, hi_at] = ranks(sample.len());
    let order = |a: &K, b: &K| a.partial_cmp(b).unwrap_or(std::cmp::Ordering::Equal);
    let (_, &mut hi, _) = sample.select_nth_unstable_by(hi_at, order);
    let (_, &mut mid, _) = sample[..=hi_at].select_nth_unstable_by(mid_at, order);
    let (_, &mut lo, _) = sample[..=mid_at].select_nth_unstable_by(lo_at, order);
    Some([lo, mid, hi])
}

/// A frame's histogram range that a few extreme pixels cannot stretch: its `full` min..max,
/// cut to its `bulk` widened by one bulk span on each side. A frame whose values all lie that
/// close to their bulk keeps its whole range; a flat bulk (span 0) keeps it too. Integer
/// frames get whole levels.
pub(super) fn robust_range<T: Sample>(bulk: Option<Bulk>, full: (f64, f64)) -> (f64, f64) {
    let Some(Bulk { low, high, .. }) = bulk else { return full };
    let span = high - low;
    if span.is_nan() || span <= 0.0 {
        return full;
    }
    let (mut lo, mut hi) = (full.0.max(low - BULK_MARGIN * span), full.1.min(high + BULK_MARGIN * span));
    if T::IS_INT {
        (lo, hi) = (lo.floor(), hi.ceil());
    }
    (lo, hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn float64_ends_match_plain_extremes_and_flag_non_finite_values() {
        let values: Vec<f64> = (0..1037).map(|i| ((i * 7919) % 1013) as f64 * 0.5 - 100.0).collect();
        let (lo, hi) = values.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| (a.min(v), b.max(v)));
        assert_eq!(float64_ends(&values), Some((lo, hi)));
        assert_eq!(float64_ends(&[]), None);
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            for at in [0, 5, 1036] {
                let mut with_bad = values.clone();
                with_bad[at] = bad;
                let (a, b) = float64_ends(&with_bad).unwrap();
                assert!(a.is_nan() && b.is_nan(), "{bad} at {at}");
            }
        }
    }

    #[test]
    fn a_scored_range_leaves_out_masked_and_non_finite_pixels_and_says_whether_one_was_kept() {
        let values: Vec<f32> = (0..70_000).map(|i| ((i * 7919) % 1013) as f32 - 500.0).collect();
        assert_eq!(scored_range(&values, None), (Some((-500.0, 512.0)), false));
        let mut bad = values.clone();
        bad[66_000] = f32::NAN;
        bad[3] = 8_589_934_592.0; // 2^33, exact in float32
        bad[4] = f32::NEG_INFINITY;
        assert_eq!(scored_range(&bad, None), (Some((-500.0, 8_589_934_592.0)), true));
        let mut mask = vec![true; values.len()];
        mask[3] = false;
        mask[4] = false;
        mask[66_000] = false;
        assert_eq!(scored_range(&bad, Some(&mask)), (Some((-500.0, 512.0)), false));
        let doubles: Vec<f64> = bad.iter().map(|&v| f64::from(v)).collect();
        assert_eq!(scored_range(&doubles, None), (Some((-500.0, 8_589_934_592.0)), true));
        assert_eq!(scored_range(&[7u16, 3, 65535], None), (Some((3.0, 65535.0)), false));
        assert_eq!(scored_range(&[1u8, 2], Some(&[false, false])), (None, false));
        assert_eq!(scored_range::<f64>(&[], None), (None, false));
        assert_eq!(scored_range(&[f64::NAN], None), (None, true));
    }

    #[test]
    fn the_bulk_range_keeps_a_clean_frame_and_cuts_a_few_extremes() {
        let req = Request::default();
        let clean: Vec<u16> = (0..10_000u32).map(|i| 3000 + (i * 7919 % 1600) as u16).collect();
        let full = (3000.0, 4599.0);
        let found = bulk(&clean, Some(&clean), &req, full).unwrap();
        let mut sorted = clean.clone();
        sorted.sort_unstable();
        let at = |k: usize| sorted[ranks(sorted.len())[k]] as f64;
        assert_eq!((found.low, found.median, found.high), (at(0), at(1), at(2)));
        assert_eq!(robust_range::<u16>(Some(found), full), full);
        let mut dead = clean.clone();
        for k in 0..5 {
            dead[k * 1000] = if k % 2 == 0 { 0 } else { 65535 };
        }
        let (lo, hi) = robust_range::<u16>(bulk(&dead, Some(&clean), &req, (0.0, 65535.0)), (0.0, 65535.0));
        assert!(lo > 1000.0 && lo < 3000.0 && hi > 4599.0 && hi < 7000.0, "{lo} {hi}");
        // a flat bulk keeps the whole range; a masked-out or non-finite pair does not count
        let flat = [5u16; 100];
        assert_eq!(robust_range::<u16>(bulk(&flat, Some(&flat), &req, (5.0, 5.0)), (5.0, 5.0)), (5.0, 5.0));
        let values = [1.0f64, f64::NAN, 3.0, 1e30];
        let other = [0.0f64, 0.0, f64::NAN, 0.0];
        let mask = [true, true, true, false];
        let masked = Request { mask: Some(&mask), ..Request::default() };
        assert_eq!(bulk(&values, Some(&other), &masked, (1.0, 3.0)), None);
        // counting per level gives the selected quantiles, also with values outside the range
        let mut state = 7u64;
        let sample: Vec<i64> = (0..5000)
            .map(|_| {
                state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                (state >> 40) as i64 % 900 - 300
            })
            .collect();
        let selected = quantiles(&mut sample.clone());
        assert_eq!(counted_quantiles(&sample, -300, 899), selected);
        // counting a whole frame as it is read gives the same as counting its sample
        let frame: Vec<i16> = sample.iter().map(|&v| v as i16).collect();
        let whole = whole_sample(&frame, |v: i16| i64::from(v));
        assert_eq!(whole_counts(&frame, -300, 899), counted_quantiles(&whole, -300, 899));
        // ... with one table per level span too wide to interleave
        let wide = COUNT_WAYS_MAX_LEVELS + 10;
        assert_eq!(whole_counts(&frame, -300, wide), counted_quantiles(&whole, -300, wide));
        assert_eq!(counted_quantiles(&sample, 0, 10), selected);
        assert_eq!(counted_quantiles(&sample[..1], -300, 899), None);
        // so does bucketing floats, clustered or spread, and with a value outside the range
        let floats: Vec<f64> = sample.iter().map(|&v| (v as f64 * 0.37).powi(3)).collect();
        let (lo, hi) = floats.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| (a.min(v), b.max(v)));
        let selected = quantiles(&mut floats.clone());
        assert_eq!(bucketed_quantiles(floats.clone(), (lo, hi)), selected);
        assert_eq!(bucketed_quantiles(floats.clone(), (lo, 0.0)), selected);
        assert_eq!(bucketed_quantiles(vec![2.5; 50], (2.5, 2.5)), Some([2.5; 3]));
    }
}
