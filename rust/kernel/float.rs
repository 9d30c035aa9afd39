//! The float pass: values promoted to f64, summed relative to a pivot near each frame's
//! mean, in independent lanes folded into Neumaier-compensated totals (two passes per
//! cache-sized chunk: mean, then centred sums), chunks merged with Chan's update.

use super::{cost, fold_chunks, Acc, Bad, HistPlan, Pass, Request, Sample};
use crate::stats::{merge_float, two_sum, FloatSums};

/// Neumaier-compensated running sum: totals of per-block lane sums.
#[derive(Clone, Copy, Default)]
pub(super) struct Neumaier {
    sum: f64,
    comp: f64,
}

impl Neumaier {
    #[inline(always)]
    fn add(&mut self, x: f64) {
        let (s, e) = two_sum(self.sum, x);
        self.sum = s;
        self.comp += e;
    }
    pub(super) fn value(&self) -> f64 {
        self.sum + self.comp
    }
    /// Add another compensated total (both parts).
    pub(super) fn merge(&mut self, other: &Neumaier) {
        self.add(other.sum);
        self.add(other.comp);
    }
}

/// Lanes of independent partial sums (vectorised; also a first level of pairwise summation)
/// and values per block before the lanes are folded into a compensated total.
const LANES: usize = 8;
/// The centred pass keeps six sums: four lanes each fit the SSE2 register file unspilled.
const LANES_C: usize = 4;
const SUB: usize = 64;

/// The float pass over `[a, b)`: mean first, then centred sums, on cache-resident data.
/// Values are shifted by a per-call `pivot` (≈ each frame's mean, see `float_pivot`) so
/// chunk means are small and Chan's merge does not lose digits to a large common offset.
#[inline(always)]
pub(super) fn float_chunk<T: Sample>(
    pass: &Pass<'_, T>,
    (a, b): (usize, usize),
    acc: &mut Acc,
    nonfinite: &mut u64,
) -> std::result::Result<(), Bad> {
    let Pass { r, s, req, plan, pivot, centre } = *pass;
    let (rr, sb) = (&r[a..b], &s[a..b]);
    if req.mask.is_none() && !req.moments && req.hist.is_none() {
        // PSNR-only plan: one pass, no means needed
        let (sse, max_abs) = float_sse(rr, sb);
        if sse.value().is_finite() {
            acc.max_abs = acc.max_abs.max(max_abs);
            let part = FloatSums { sse: sse.sum, sse_c: sse.comp, ..FloatSums::default() };
            acc.float = merge_float(&acc.float, acc.n, &part, rr.len() as u64);
            acc.n += rr.len() as u64;
            return Ok(());
        }
    }
    if let Some(c) = centre {
        // the scan found every value finite and gave each frame's mean: centre on it
        float_centred(rr, sb, c, req, plan, acc, pivot);
        return Ok(());
    }
    if req.mask.is_none() {
        let sums = float_sums(rr, sb, pivot);
        // a NaN/Inf anywhere makes the sums non-finite: only then look pixel by pixel
        if sums.finite() {
            acc.max_abs = acc.max_abs.max(sums.max_abs);
            acc.sum_r.add(sums.r);
            acc.sum_s.add(sums.s);
            let nf = rr.len() as f64;
            float_centred(rr, sb, (sums.r / nf, sums.s / nf), req, plan, acc, pivot);
            return Ok(());
        }
    }
    // General path: keep the counted pairs (mask, finiteness) as f64, then the same kernel.
    let (mut xs, mut ys) = (Vec::with_capacity(rr.len()), Vec::with_capacity(rr.len()));
    for (k, (&x, &y)) in rr.iter().zip(sb).enumerate() {
        if req.mask.is_some_and(|m| !m[a + k]) {
            continue;
        }
        let (x, y) = (x.to_f64(), y.to_f64());
        if !(x.is_finite() && y.is_finite()) {
            if req.mask_nonfinite {
                *nonfinite += 1;
                continue;
            }
            return Err(Bad::NonFinite { index: a + k });
        }
        xs.push(x);
        ys.push(y);
    }
    if !xs.is_empty() {
        let sums = float_sums(&xs, &ys, pivot);
        acc.max_abs = acc.max_abs.max(sums.max_abs);
        acc.sum_r.add(sums.r);
        acc.sum_s.add(sums.s);
        let nf = xs.len() as f64;
        float_centred(&xs, &ys, (sums.r / nf, sums.s / nf), req, plan, acc, pivot);
    }
    Ok(())
}

/// Running max of |x| and |y| for the underflow check. Plain compares (one `maxpd`), not
/// `f64::max`, whose NaN rules cost a blend per value: NaN is caught by the sums anyway.
/// Only float64 frames can be small enough to underflow, so other types skip it.
#[inline(always)]
fn bigger<T: Sample>(m: f64, x: f64, y: f64) -> f64 {
    if !T::MAY_UNDERFLOW {
        return m;
    }
    let (ax, ay) = (x.abs(), y.abs());
    let m = if ax > m { ax } else { m };
    if ay > m {
        ay
    } else {
        m
    }
}

/// Σ(x − y)² (compensated) and max |value| of a run of pixels: sixteen lanes, eight
/// values per lane per block of 128, lanes folded pairwise into a compensated total per
/// block; the rest of the run summed on its own. The explicit AVX2 loops (`avx2`) do the
/// same additions in the same order for float32/float64, so results are bit-identical.
#[inline(always)]
fn float_sse<T: Sample>(rr: &[T], sb: &[T]) -> (Neumaier, f64) {
    #[cfg(target_arch = "x86_64")]
    if super::use_avx2() {
        // SAFETY (both): the CPU has AVX2 (`use_avx2`).
        if let (Some(r), Some(s)) = (T::as_f32(rr), T::as_f32(sb)) {
            return unsafe { avx2::sse(r, s) };
        }
        if let (Some(r), Some(s)) = (T::as_f64(rr), T::as_f64(sb)) {
            return unsafe { avx2::sse(r, s) };
        }
    }
    let mut tot = Neumaier::default();
    let mut max_abs = 0.0f64;
    let full = rr.len() / SSE_BLOCK * SSE_BLOCK;
    for (cr, cs) in rr[..full].chunks_exact(SSE_BLOCK).zip(sb[..full].chunks_exact(SSE_BLOCK)) {
        let mut acc = [[0.0f64; 4]; 4]; // element 4k + m of each group of 16 -> acc[k][m]
        for (xr, xs) in cr.chunks_exact(16).zip(cs.chunks_exact(16)) {
            for k in 0..4 {
                for m in 0..4 {
                    let (x, y) = (xr[4 * k + m].to_f64(), xs[4 * k + m].to_f64());
                    let d = x - y;
                    acc[k][m] += d * d;
                    max_abs = bigger::<T>(max_abs, x, y);
                }
            }
        }
        let s: [f64; 4] = std::array::from_fn(|m| (acc[0][m] + acc[2][m]) + (acc[1][m] + acc[3][m]));
        tot.add((s[0] + s[2]) + (s[1] + s[3]));
    }
    let mut rest = 0.0f64;
    for (&x, &y) in rr[full..].iter().zip(&sb[full..]) {
        let (x, y) = (x.to_f64(), y.to_f64());
        rest += (x - y) * (x - y);
        max_abs = bigger::<T>(max_abs, x, y);
    }
    tot.add(rest);
    (tot, max_abs)
}

/// Values per block of the SSE-only pass (sixteen lanes of eight).
const SSE_BLOCK: usize = 128;

/// Σ(x − y)² for float32/float64 runs with explicit AVX2: the PSNR/MSE plan is one sum,
/// and LLVM's vectorisation of the generic loop is fragile (a change in the block fold
/// turned it into gathers, 2-3x slower). Sixteen lanes (four vectors in flight), eight
/// values per lane per block of 128, lanes folded pairwise into a compensated total.
#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::Neumaier;
    use std::arch::x86_64::*;

    const BLOCK: usize = super::SSE_BLOCK;

    #[inline(always)]
    unsafe fn fold(acc: [__m256d; 4]) -> f64 {
        let s = _mm256_add_pd(_mm256_add_pd(acc[0], acc[2]), _mm256_add_pd(acc[1], acc[3]));
        let t = _mm_add_pd(_mm256_castpd256_pd128(s), _mm256_extractf128_pd::<1>(s));
        _mm_cvtsd_f64(_mm_add_sd(t, _mm_unpackhi_pd(t, t)))
    }

    /// Four values widened to float64 lanes.
    pub(super) trait Lanes: Copy + Into<f64> {
        /// float64 squares can underflow: track the largest |value| (see `bigger`)
        const TRACK_MAX: bool;
        unsafe fn load4(p: *const Self) -> __m256d;
    }

    impl Lanes for f32 {
        const TRACK_MAX: bool = false;
        #[inline(always)]
        unsafe fn load4(p: *const f32) -> __m256d {
            _mm256_cvtps_pd(_mm_loadu_ps(p))
        }
    }

    impl Lanes for f64 {
        const TRACK_MAX: bool = true;
        #[inline(always)]
        unsafe fn load4(p: *const f64) -> __m256d {
            _mm256_loadu_pd(p)
        }
    }

    /// Σ(x − y)² (and the largest |value| for float64, else 0).
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn sse<T: Lanes>(r: &[T], s: &[T]) -> (Neumaier, f64) {
        let n = r.len().min(s.len());
        let full = n / BLOCK * BLOCK;
        let (pr, ps) = (r.as_ptr(), s.as_ptr());
        let sign = _mm256_set1_pd(-0.0);
        let mut big = _mm256_setzero_pd();
        let mut tot = Neumaier::default();
        let mut i = 0;
        while i < full {
            let mut acc = [_mm256_setzero_pd(); 4];
            for j in (i..i + BLOCK).step_by(16) {
                for (k, a) in acc.iter_mut().enumerate() {
                    // SAFETY: j + 4k + 4 <= full <= len of both slices
                    let x = T::load4(pr.add(j + 4 * k));
                    let y = T::load4(ps.add(j + 4 * k));
                    let d = _mm256_sub_pd(x, y);
                    *a = _mm256_add_pd(*a, _mm256_mul_pd(d, d));
                    if T::TRACK_MAX {
                        big = _mm256_max_pd(big, _mm256_max_pd(_mm256_andnot_pd(sign, x), _mm256_andnot_pd(sign, y)));
                    }
                }
            }
            tot.add(fold(acc));
            i += BLOCK;
        }
        let mut lanes = [0.0f64; 4];
        _mm256_storeu_pd(lanes.as_mut_ptr(), big);
        let mut max_abs = lanes.iter().fold(0.0f64, |m, &v| m.max(v));
        let mut rest = 0.0f64;
        for (&x, &y) in r[full..n].iter().zip(&s[full..n]) {
            let (x, y): (f64, f64) = (x.into(), y.into());
            rest += (x - y) * (x - y);
            if T::TRACK_MAX {
                max_abs = max_abs.max(x.abs()).max(y.abs());
            }
        }
        tot.add(rest);
        (tot, max_abs)
    }
}

/// Σ(x − pivot_r), Σ(y − pivot_s), the range of both runs and max |value|.
pub(super) struct RunSums {
    pub(super) r: f64,
    pub(super) s: f64,
    pub(super) lo: f64,
    pub(super) hi: f64,
    pub(super) max_abs: f64,
}

impl RunSums {
    fn empty() -> Self {
        RunSums { r: 0.0, s: 0.0, lo: f64::INFINITY, hi: f64::NEG_INFINITY, max_abs: 0.0 }
    }
    fn merge(self, o: RunSums) -> RunSums {
        RunSums {
            r: self.r + o.r,
            s: self.s + o.s,
            lo: self.lo.min(o.lo),
            hi: self.hi.max(o.hi),
            max_abs: self.max_abs.max(o.max_abs),
        }
    }
    /// No NaN or ±Inf in the run: the sums stay finite (NaN and Inf propagate into them;
    /// values summing past f64's range are treated like non-finite ones, carefully).
    pub(super) fn finite(&self) -> bool {
        self.r.is_finite() && self.s.is_finite()
    }
}

/// Σ(x − pivot_r), Σ(y − pivot_s), range and max |value| of a run of pixels. Each lane is a
/// compensated (two-sum) accumulator: the mean of wide-spread data (±3e38 around 1e35)
/// is the sum of large terms that cancel, so every addition's error is kept.
#[inline(always)]
fn float_sums<T: Sample>(rr: &[T], sb: &[T], (pr, ps): (f64, f64)) -> RunSums {
    let (mut lr, mut cr_) = ([0.0f64; LANES], [0.0f64; LANES]);
    let (mut ls, mut cs_) = ([0.0f64; LANES], [0.0f64; LANES]);
    let mut max_abs = [0.0f64; LANES];
    let (mut lo, mut hi) = ([f64::INFINITY; LANES], [f64::NEG_INFINITY; LANES]);
    #[inline(always)]
    fn add(sum: &mut f64, comp: &mut f64, x: f64) {
        let (t, e) = two_sum(*sum, x);
        *sum = t;
        *comp += e;
    }
    // plain compares (minpd/maxpd): a NaN is caught by the sums, not the range
    #[inline(always)]
    fn range(lo: &mut f64, hi: &mut f64, x: f64, y: f64) {
        let (a, b) = if x < y { (x, y) } else { (y, x) };
        *lo = if a < *lo { a } else { *lo };
        *hi = if b > *hi { b } else { *hi };
    }
    let (ir, is) = (rr.chunks_exact(LANES), sb.chunks_exact(LANES));
    let (rem_r, rem_s) = (ir.remainder(), is.remainder());
    for (xr, xs) in ir.zip(is) {
        for k in 0..LANES {
            let (x, y) = (xr[k].to_f64(), xs[k].to_f64());
            add(&mut lr[k], &mut cr_[k], x - pr);
            add(&mut ls[k], &mut cs_[k], y - ps);
            range(&mut lo[k], &mut hi[k], x, y);
            max_abs[k] = bigger::<T>(max_abs[k], x, y);
        }
    }
    for (&x, &y) in rem_r.iter().zip(rem_s) {
        let (x, y) = (x.to_f64(), y.to_f64());
        add(&mut lr[0], &mut cr_[0], x - pr);
        add(&mut ls[0], &mut cs_[0], y - ps);
        range(&mut lo[0], &mut hi[0], x, y);
        max_abs[0] = bigger::<T>(max_abs[0], x, y);
    }
    let (mut tr, mut ts) = (Neumaier::default(), Neumaier::default());
    for k in 0..LANES {
        tr.add(lr[k]);
        tr.add(cr_[k]);
        ts.add(ls[k]);
        ts.add(cs_[k]);
    }
    RunSums {
        r: tr.value(),
        s: ts.value(),
        lo: lo.iter().fold(f64::INFINITY, |m, &v| m.min(v)),
        hi: hi.iter().fold(f64::NEG_INFINITY, |m, &v| m.max(v)),
        max_abs: max_abs.iter().fold(0.0f64, |m, &v| m.max(v)),
    }
}

/// Centred sums around `(mr, ms)` (relative to the pivot: the run's own mean, or the
/// frames' means; corrected two-pass, so an approximate centre costs no accuracy), SSE
/// and the histogram, merged into `acc` (sums relative to the pivot).
#[inline(always)]
fn float_centred<T: Sample>(
    rr: &[T],
    sb: &[T],
    (mr, ms): (f64, f64),
    req: &Request,
    plan: Option<&HistPlan>,
    acc: &mut Acc,
    (pr, ps): (f64, f64),
) {
    let n = rr.len() as u64;
    if n == 0 {
        return;
    }
    let nf = n as f64;
    // six compensated totals: Σdr, Σds, Σdr², Σds², Σdr·ds, Σ(x−y)²
    let mut tot = [Neumaier::default(); 6];
    if req.moments || req.sse {
        for (cr, cs) in rr.chunks(SUB).zip(sb.chunks(SUB)) {
            let mut l = [[0.0f64; LANES_C]; 6];
            let (ir, is) = (cr.chunks_exact(LANES_C), cs.chunks_exact(LANES_C));
            let (rem_r, rem_s) = (ir.remainder(), is.remainder());
            macro_rules! body {
                ($k:expr, $x:expr, $y:expr) => {{
                    let (x, y): (f64, f64) = ($x, $y);
                    let (dr, ds) = (x - pr - mr, y - ps - ms);
                    let d = x - y;
                    l[0][$k] += dr;
                    l[1][$k] += ds;
                    l[2][$k] += dr * dr;
                    l[3][$k] += ds * ds;
                    l[4][$k] += dr * ds;
                    l[5][$k] += d * d;
                }};
            }
            for (xr, xs) in ir.zip(is) {
                for k in 0..LANES_C {
                    body!(k, xr[k].to_f64(), xs[k].to_f64());
                }
            }
            for (&x, &y) in rem_r.iter().zip(rem_s) {
                body!(0, x.to_f64(), y.to_f64());
            }
            for (t, lane) in tot.iter_mut().zip(&l) {
                t.add(lane.iter().sum());
            }
        }
    }
    if let Some(p) = plan {
        if let Some(bn) = p.binner.as_ref() {
            let dense_bins = p.dense_bins.unwrap_or(0);
            for (&x, &y) in rr.iter().zip(sb) {
                acc.count(dense_bins, bn.float_bin(x.to_f64()), bn.float_bin(y.to_f64()));
            }
        }
    }
    let [dr, ds, m2r, m2s, crs, _] = tot.map(|t| t.value());
    // corrected two-pass: remove the residual of the approximate mean
    let part = FloatSums {
        mr: mr + dr / nf,
        ms: ms + ds / nf,
        m2r: m2r - dr * dr / nf,
        m2s: m2s - ds * ds / nf,
        crs: crs - dr * ds / nf,
        sse: if req.sse { tot[5].sum } else { 0.0 },
        sse_c: if req.sse { tot[5].comp } else { 0.0 },
    };
    acc.float = merge_float(&acc.float, acc.n, &part, n);
    acc.n += n;
}

/// One compensated pass over both whole frames (no mask): each frame's sum, the range of
/// both and the largest magnitude. Gives the histogram range, the pivot and the centre
/// of the float pass at once, and certifies that no value is NaN or ±Inf.
pub(super) fn float_scan<T: Sample>(r: &[T], s: &[T]) -> RunSums {
    let Ok(sums) = fold_chunks::<_, std::convert::Infallible>(
        r.len(),
        cost::SCAN,
        RunSums::empty,
        |acc, (a, b)| Ok(acc.merge(float_sums_dispatch(&r[a..b], &s[a..b]))),
        RunSums::merge,
    );
    sums
}

/// `float_sums` from zero, in the AVX2 copy when the CPU has it (as `run_chunk` does).
fn float_sums_dispatch<T: Sample>(r: &[T], s: &[T]) -> RunSums {
    #[cfg(target_arch = "x86_64")]
    if super::use_avx2() {
        #[target_feature(enable = "avx2")]
        fn sums_avx2<T: Sample>(r: &[T], s: &[T]) -> RunSums {
            float_sums(r, s, (0.0, 0.0))
        }
        // SAFETY: the CPU has AVX2 (`use_avx2`).
        return unsafe { sums_avx2(r, s) };
    }
    float_sums(r, s, (0.0, 0.0))
}

/// The pivot of the float pass and, when the scan certified every value finite, the
/// centre (each frame's mean relative to the pivot). The pivot is each frame's mean cut
/// to 24 significant bits, or (with a mask or non-finite values) the first finite value.
pub(super) fn float_pivot<T: Sample>(r: &[T], s: &[T], scan: Option<&RunSums>) -> ((f64, f64), Option<(f64, f64)>) {
    if let Some(sc) = scan.filter(|sc| sc.finite()) {
        let n = r.len() as f64;
        let (mr, ms) = (sc.r / n, sc.s / n);
        // Keep 24 significant bits: x − pivot is then exact for every float32 value (and for
        // float64 values within 2^29 of the pivot's magnitude) — a 53-bit pivot would round
        // each difference, and identical values (e.g. clipped at ±3.4e38) round coherently.
        let short = |p: f64| f64::from_bits(p.to_bits() & !((1u64 << 29) - 1));
        let pivot = (short(mr), short(ms));
        return (pivot, Some((mr - pivot.0, ms - pivot.1)));
    }
    let pick = |v: &[T]| v.iter().map(|x| x.to_f64()).find(|x| x.is_finite()).unwrap_or(0.0);
    ((pick(r), pick(s)), None)
}
