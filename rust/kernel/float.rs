//! The float pass: values promoted to f64, summed relative to a pivot near each frame's
//! mean, in independent lanes folded into Neumaier-compensated totals. With the scan's means
//! as the common centre, every chunk's centred totals are added into compensated totals, in
//! chunk order; otherwise (mask, NaN/Inf) each chunk is centred on its own mean and the chunks
//! are merged with Chan's update, in chunk order. Either way the result does not depend on
//! how the chunks were shared out between threads.

use super::acc::{Acc, Bad};
use super::binning::{Binner, HistPlan};
use super::dispatch::Pass;
use super::parallel::{cost, map_chunks};
use super::request::Request;
use super::sample::Sample;
use crate::stats::{merge_float, two_sum, FloatSums, Neumaier};

/// On AVX2 CPUs, return `$call` with `$r`, `$s` bound to the runs as float32 or float64
/// slices (the explicit loops in `avx2`); other types and CPUs fall through to the portable
/// loop that follows.
macro_rules! avx2_floats {
    ($rr:expr, $sb:expr, |$r:ident, $s:ident| $call:expr) => {
        #[cfg(target_arch = "x86_64")]
        if super::dispatch::use_avx2() {
            // SAFETY (both): the CPU has AVX2 (`use_avx2`), the only requirement of the `avx2`
            // functions (their loads stay within the slices for any lengths).
            if let (Some($r), Some($s)) = (T::as_f32($rr), T::as_f32($sb)) {
                return unsafe { $call };
            }
            if let (Some($r), Some($s)) = (T::as_f64($rr), T::as_f64($sb)) {
                return unsafe { $call };
            }
        }
    };
}

/// Lanes of independent partial sums (vectorised; also a first level of pairwise summation)
/// and values per block before the lanes are folded into a compensated total.
const LANES: usize = 8;
/// The centred pass keeps six sums: four lanes each fit the SSE2 register file unspilled.
const LANES_C: usize = 4;
const SUB: usize = 256;

/// What one chunk of the float pass contributes; combined in chunk order by [`float_total`].
pub(super) enum ChunkFloat {
    /// Σdr, Σds, Σdr², Σds², Σdr·ds, Σ(x − y)² about the common centre (the scan's means).
    Centred([Neumaier; 6]),
    /// The chunk's own centred sums (`mr`, `ms` relative to the pivot), count and
    /// Σ(x − pivot), Σ(y − pivot) (mask, NaN/Inf, or the SSE-only plan).
    Own { n: u64, sums: FloatSums, sum_r: Neumaier, sum_s: Neumaier },
}

/// The pass's float sums over `n` counted pairs from its chunks' parts (`(first pixel,
/// part)`, in any order): parts are combined in chunk order, so the result does not depend on
/// the threads. `means` are the scan's means when every chunk was centred on them.
pub(super) fn float_total(
    mut parts: Vec<(usize, ChunkFloat)>,
    n: u64,
    pivot: (f64, f64),
    means: Option<(f64, f64)>,
) -> FloatSums {
    parts.sort_unstable_by_key(|p| p.0);
    if let Some((mr, ms)) = means {
        let mut t = [Neumaier::default(); 6];
        for (_, part) in &parts {
            if let ChunkFloat::Centred(c) = part {
                t.iter_mut().zip(c).for_each(|(t, c)| t.merge(c));
            }
        }
        let nf = n.max(1) as f64;
        let [dr, ds, m2r, m2s, crs, _] = t.map(|t| t.value());
        // corrected two-pass, once for the whole pass, for the second moments. The means are
        // the scan's, rounded once from its compensated sums (`offset_mean`): the residual
        // Σ(x − centre) is summed plainly within runs, and on ±3e38 data its rounding (1e-14 of
        // the mean) would outweigh the sub-ulp it corrects
        return FloatSums {
            mr,
            ms,
            m2r: m2r - dr * dr / nf,
            m2s: m2s - ds * ds / nf,
            crs: crs - dr * ds / nf,
            sse: t[5].sum,
            sse_c: t[5].comp,
        };
    }
    let (mut total, mut count) = (FloatSums::default(), 0u64);
    let (mut sum_r, mut sum_s) = (Neumaier::default(), Neumaier::default());
    for (_, part) in parts {
        if let ChunkFloat::Own { n: k, sums, sum_r: r, sum_s: s } = part {
            total = merge_float(&total, count, &sums, k);
            count += k;
            sum_r.merge(&r);
            sum_s.merge(&s);
        }
    }
    if count > 0 {
        // the means from the compensated sums, not from Chan's merges (whose δ between chunk
        // means costs digits when the data spread is much larger than the mean)
        total.mr = offset_mean(pivot.0, &sum_r, count as f64);
        total.ms = offset_mean(pivot.1, &sum_s, count as f64);
    }
    total
}

/// `pivot + Σ/n` for a compensated sum `Σ` of values relative to `pivot`, without the
/// cancellation of a pivot far from the mean (the first finite value, with a mask: ±3e38
/// data whose mean is 1e35 lost ten digits of the mean). The quotient's remainder is exact
/// (fused multiply-add, once per pass) and the pivot is added as a two-sum.
pub(super) fn offset_mean(pivot: f64, sum: &Neumaier, n: f64) -> f64 {
    let q = sum.sum / n;
    let rem = (-q).mul_add(n, sum.sum); // sum.sum − q·n, exactly
    let (hi, lo) = two_sum(pivot, q);
    hi + (lo + (rem + sum.comp) / n)
}

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
        let sse = float_sse(rr, sb);
        if sse.value().is_finite() {
            acc.max_abs = acc.max_abs.max(sse_max_abs(rr, sb, sse.value()));
            let sums = FloatSums { sse: sse.sum, sse_c: sse.comp, ..FloatSums::default() };
            let n = rr.len() as u64;
            let zero = Neumaier::default();
            acc.floats.push((a, ChunkFloat::Own { n, sums, sum_r: zero, sum_s: zero }));
            acc.n += n;
            return Ok(());
        }
    }
    if let Some(c) = centre {
        // the scan found every value finite and gave each frame's mean: centre on it
        let tot = float_centred(rr, sb, c, req, plan, acc, pivot);
        acc.floats.push((a, ChunkFloat::Centred(tot)));
        acc.n += rr.len() as u64;
        return Ok(());
    }
    if req.mask.is_none() {
        let sums = float_sums::<T, false>(rr, sb, pivot);
        // a NaN/Inf anywhere makes the sums non-finite: only then look pixel by pixel
        if sums.finite() {
            acc.max_abs = acc.max_abs.max(sums.max_abs);
            own_part(rr, sb, a, sums, req, plan, acc, pivot);
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
        let sums = float_sums::<f64, false>(&xs, &ys, pivot);
        acc.max_abs = acc.max_abs.max(sums.max_abs);
        own_part(&xs, &ys, a, sums, req, plan, acc, pivot);
    }
    Ok(())
}

/// A chunk (starting at pixel `a`) centred on its own mean (`sums` from `float_sums`).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn own_part<T: Sample>(
    rr: &[T],
    sb: &[T],
    a: usize,
    sums: RunSums,
    req: &Request,
    plan: Option<&HistPlan>,
    acc: &mut Acc,
    pivot: (f64, f64),
) {
    let n = rr.len() as u64;
    let nf = n as f64;
    let (mr, ms) = (sums.r.value() / nf, sums.s.value() / nf);
    let tot = float_centred(rr, sb, (mr, ms), req, plan, acc, pivot);
    let [dr, ds, m2r, m2s, crs, _] = tot.map(|t| t.value());
    // corrected two-pass: remove the residual of the approximate mean
    let part = FloatSums {
        mr: mr + dr / nf,
        ms: ms + ds / nf,
        m2r: m2r - dr * dr / nf,
        m2s: m2s - ds * ds / nf,
        crs: crs - dr * ds / nf,
        sse: tot[5].sum,
        sse_c: tot[5].comp,
    };
    acc.floats.push((a, ChunkFloat::Own { n, sums: part, sum_r: sums.r, sum_s: sums.s }));
    acc.n += n;
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

/// For the underflow check of float64 frames (`pair_stats`), after the SSE-only pass:
/// the largest |value| of the run, or a lower bound of it that already passes the check.
/// Σ(x − y)² ≤ n·(2·max|v|)², so a sum of at least 2^-900 over n ≤ 2^32 values proves
/// max|v| ≥ 2^-467: only runs of (nearly) equal or tiny values need the extra look.
fn sse_max_abs<T: Sample>(rr: &[T], sb: &[T], sse: f64) -> f64 {
    if !T::MAY_UNDERFLOW || rr.is_empty() {
        return 0.0;
    }
    if sse >= 2f64.powi(-900) {
        return (sse / rr.len() as f64).sqrt() / 2.0;
    }
    rr.iter().zip(sb).fold(0.0, |m, (&x, &y)| bigger::<T>(m, x.to_f64(), y.to_f64()))
}

/// Σ(x − y)² (compensated) of a run of pixels: sixteen lanes, eight
/// values per lane per block of 128, lanes folded pairwise into a compensated total per
/// block; the rest of the run summed on its own. The explicit AVX2 loops (`avx2`) do the
/// same additions in the same order for float32/float64, so results are bit-identical.
#[inline(always)]
fn float_sse<T: Sample>(rr: &[T], sb: &[T]) -> Neumaier {
    avx2_floats!(rr, sb, |r, s| avx2::sse(r, s));
    let mut tot = Neumaier::default();
    let full = rr.len() / SSE_BLOCK * SSE_BLOCK;
    for (cr, cs) in rr[..full].chunks_exact(SSE_BLOCK).zip(sb[..full].chunks_exact(SSE_BLOCK)) {
        let mut acc = [[0.0f64; 4]; 4]; // element 4k + m of each group of 16 -> acc[k][m]
        for (xr, xs) in cr.chunks_exact(16).zip(cs.chunks_exact(16)) {
            for k in 0..4 {
                for m in 0..4 {
                    let (x, y) = (xr[4 * k + m].to_f64(), xs[4 * k + m].to_f64());
                    let d = x - y;
                    acc[k][m] += d * d;
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
    }
    tot.add(rest);
    tot
}

/// Values per block of the SSE-only pass (sixteen lanes of eight).
const SSE_BLOCK: usize = 128;

/// Explicit AVX2 copies of the float loops (float32/float64): the squared error, the scan,
/// the centred sums and the dense histogram. LLVM's vectorisation of the generic loops is
/// fragile (half-width vectors with spills, or gathers after a small change); each copy does
/// the same operations in the same order as its portable loop, so results are bit-identical.
#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::{Binner, Neumaier, RunSums, Sample, SumLanes, LANES, LANES_C, SUB};
    // one __m256d holds the four lanes of a centred sum, two the eight lanes of `sums`
    const _: () = assert!(LANES_C == 4 && LANES == 8);
    use std::arch::x86_64::*;

    const BLOCK: usize = super::SSE_BLOCK;

    /// The sum of the four vectors' lanes, in a fixed order.
    ///
    /// # Safety
    /// The CPU supports AVX2 (all functions of this module: callers check `use_avx2`).
    #[inline(always)]
    unsafe fn fold(acc: [__m256d; 4]) -> f64 {
        let s = _mm256_add_pd(_mm256_add_pd(acc[0], acc[2]), _mm256_add_pd(acc[1], acc[3]));
        let t = _mm_add_pd(_mm256_castpd256_pd128(s), _mm256_extractf128_pd::<1>(s));
        _mm_cvtsd_f64(_mm_add_sd(t, _mm_unpackhi_pd(t, t)))
    }

    /// Four values widened to float64 lanes.
    pub(super) trait Lanes: Sample + Into<f64> {
        /// The four values at `p`.
        ///
        /// # Safety
        /// The CPU supports AVX2, and `p .. p + 4` are readable values of `Self`.
        unsafe fn load4(p: *const Self) -> __m256d;
    }

    impl Lanes for f32 {
        #[inline(always)]
        unsafe fn load4(p: *const f32) -> __m256d {
            // SAFETY: the caller's guarantee: four readable f32 at p
            _mm256_cvtps_pd(_mm_loadu_ps(p))
        }
    }

    impl Lanes for f64 {
        #[inline(always)]
        unsafe fn load4(p: *const f64) -> __m256d {
            // SAFETY: the caller's guarantee: four readable f64 at p
            _mm256_loadu_pd(p)
        }
    }

    /// Σ(x − y)².
    ///
    /// # Safety
    /// The CPU supports AVX2 (the loads stay within both slices for any lengths).
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn sse<T: Lanes>(r: &[T], s: &[T]) -> Neumaier {
        let n = r.len().min(s.len());
        let full = n / BLOCK * BLOCK;
        let (pr, ps) = (r.as_ptr(), s.as_ptr());
        let mut tot = Neumaier::default();
        let mut i = 0;
        while i < full {
            let mut acc = [_mm256_setzero_pd(); 4];
            for j in (i..i + BLOCK).step_by(16) {
                for (k, a) in acc.iter_mut().enumerate() {
                    // SAFETY: j + 4k + 4 <= i + BLOCK <= full <= len of both slices (i steps by
                    // BLOCK up to full, a multiple of BLOCK; j + 16 <= i + BLOCK; k < 4)
                    let x = T::load4(pr.add(j + 4 * k));
                    let y = T::load4(ps.add(j + 4 * k));
                    let d = _mm256_sub_pd(x, y);
                    *a = _mm256_add_pd(*a, _mm256_mul_pd(d, d));
                }
            }
            tot.add(fold(acc));
            i += BLOCK;
        }
        let mut rest = 0.0f64;
        for (&x, &y) in r[full..n].iter().zip(&s[full..n]) {
            let (x, y): (f64, f64) = (x.into(), y.into());
            rest += (x - y) * (x - y);
        }
        tot.add(rest);
        tot
    }

    /// `float_sums` with explicit AVX2: lanes 0-3 and 4-7 in two vectors per sum.
    ///
    /// # Safety
    /// The CPU supports AVX2 (the loads stay within both slices for any lengths).
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn sums<T: Lanes, const RANGE: bool>(r: &[T], s: &[T], (pr, ps): (f64, f64)) -> RunSums {
        let n = r.len().min(s.len());
        let full = n / LANES * LANES;
        let (p_r, p_s) = (r.as_ptr(), s.as_ptr());
        let (vpr, vps) = (_mm256_set1_pd(pr), _mm256_set1_pd(ps));
        let sign = _mm256_set1_pd(-0.0);
        let zero = _mm256_setzero_pd();
        let (mut lr, mut cr, mut ls, mut cs) = ([zero; 2], [zero; 2], [zero; 2], [zero; 2]);
        // each frame's range in one vector per end (the two halves of a step compared first)
        let (mut big, mut lo, mut hi) =
            ([zero; 2], [_mm256_set1_pd(f64::INFINITY); 2], [_mm256_set1_pd(f64::NEG_INFINITY); 2]);
        /// # Safety
        /// The CPU supports AVX2.
        #[inline(always)]
        unsafe fn two_sum_into(sum: &mut __m256d, comp: &mut __m256d, x: __m256d) {
            // crate::stats::two_sum, four lanes at a time
            let t = _mm256_add_pd(*sum, x);
            let bb = _mm256_sub_pd(t, *sum);
            let e = _mm256_add_pd(_mm256_sub_pd(*sum, _mm256_sub_pd(t, bb)), _mm256_sub_pd(x, bb));
            *sum = t;
            *comp = _mm256_add_pd(*comp, e);
        }
        let mut i = 0;
        while i < full {
            // SAFETY: i + 4h + 4 <= i + LANES <= full <= len of both runs (i steps by LANES = 8
            // up to full, a multiple of 8; h < 2)
            let x = [T::load4(p_r.add(i)), T::load4(p_r.add(i + 4))];
            let y = [T::load4(p_s.add(i)), T::load4(p_s.add(i + 4))];
            for h in 0..2 {
                two_sum_into(&mut lr[h], &mut cr[h], _mm256_sub_pd(x[h], vpr));
                two_sum_into(&mut ls[h], &mut cs[h], _mm256_sub_pd(y[h], vps));
                if T::MAY_UNDERFLOW {
                    let (x, y) = (x[h], y[h]);
                    big[h] = _mm256_max_pd(_mm256_andnot_pd(sign, y), _mm256_max_pd(_mm256_andnot_pd(sign, x), big[h]));
                }
            }
            if RANGE {
                // lo[0], hi[0]: the real run's; lo[1], hi[1]: the simulated run's
                lo[0] = _mm256_min_pd(_mm256_min_pd(x[0], x[1]), lo[0]);
                hi[0] = _mm256_max_pd(_mm256_max_pd(x[0], x[1]), hi[0]);
                lo[1] = _mm256_min_pd(_mm256_min_pd(y[0], y[1]), lo[1]);
                hi[1] = _mm256_max_pd(_mm256_max_pd(y[0], y[1]), hi[1]);
            }
            i += LANES;
        }
        let mut st = SumLanes::new();
        // SAFETY (the stores): `dst` holds LANES = 8 doubles, two 4-lane stores at 0 and 4
        let store = |dst: &mut [f64; LANES], v: [__m256d; 2]| {
            _mm256_storeu_pd(dst.as_mut_ptr(), v[0]);
            _mm256_storeu_pd(dst.as_mut_ptr().add(4), v[1]);
        };
        store(&mut st.lr, lr);
        store(&mut st.cr, cr);
        store(&mut st.ls, ls);
        store(&mut st.cs, cs);
        store(&mut st.max_abs, big);
        // SAFETY (the range's stores): each lane array holds LANES = 8 doubles; the four
        // lanes not stored keep their empty-range start
        for (dst, v) in [(&mut st.lo_r, lo[0]), (&mut st.lo_s, lo[1]), (&mut st.hi_r, hi[0]), (&mut st.hi_s, hi[1])] {
            _mm256_storeu_pd(dst.as_mut_ptr(), v);
        }
        st.finish::<T, RANGE>(&r[full..n], &s[full..n], (pr, ps))
    }

    /// `float_hist` on a dense `bins × bins` table: bins of four pairs at a time, computed as
    /// `Binner::float_bin` does (`(v − lo)·(1/width)`, truncated, clamped to the edge bins; the
    /// clamp comes first here, in float64, so the truncation cannot overflow — same bins).
    ///
    /// # Safety
    /// The CPU supports AVX2 (loads and table writes stay in bounds for any lengths; the
    /// table's size is asserted).
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn hist_dense<T: Lanes>(r: &[T], s: &[T], (rb, sb): (&Binner, &Binner), dense: &mut [u32]) {
        let bins = rb.bins;
        assert!(sb.bins == bins && dense.len() == bins * bins && bins <= crate::hist::DENSE_MAX_BINS);
        let n = r.len().min(s.len());
        let full = n / 4 * 4;
        let (zero, top) = (_mm256_setzero_pd(), _mm256_set1_pd((bins - 1) as f64));
        let stride = _mm_set1_epi32(bins as i32);
        // maxpd returns its second operand for NaN, as `NaN as i64` gives 0: same bin 0
        let binner = |bn: &Binner| {
            let (lo, inv) = (_mm256_set1_pd(bn.lo), _mm256_set1_pd(bn.inv_width));
            move |v: __m256d| {
                _mm256_cvttpd_epi32(_mm256_min_pd(_mm256_max_pd(_mm256_mul_pd(_mm256_sub_pd(v, lo), inv), zero), top))
            }
        };
        let (real_bin, sim_bin) = (binner(rb), binner(sb));
        let mut idx = [0u32; 4];
        let mut j = 0;
        while j < full {
            // SAFETY: j + 4 <= full <= len of both runs (j steps by 4 up to full, a multiple of 4)
            let (x, y) = (T::load4(r.as_ptr().add(j)), T::load4(s.as_ptr().add(j)));
            let cell = _mm_add_epi32(_mm_mullo_epi32(real_bin(x), stride), sim_bin(y));
            _mm_storeu_si128(idx.as_mut_ptr().cast(), cell);
            for &c in &idx {
                // SAFETY: both bins are clamped to [0, bins − 1] in float64 before the conversion
                // (NaN becomes 0: maxpd returns its second operand), so c = bin_x · bins + bin_y
                // < bins² = dense.len() (asserted above; bins ≤ 512, no i32 overflow). Tested
                // with values beyond both ends by `float_simd_equals_portable_at_the_boundaries`.
                *dense.get_unchecked_mut(c as usize) += 1;
            }
            j += 4;
        }
        for (&x, &y) in r[full..n].iter().zip(&s[full..n]) {
            dense[rb.float_bin(x.to_f64()) * bins + sb.float_bin(y.to_f64())] += 1;
        }
    }

    /// `centred_totals` with explicit AVX2: one vector of four lanes per sum.
    ///
    /// # Safety
    /// The CPU supports AVX2 (the loads stay within both slices for any lengths).
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn centred<T: Lanes>(
        r: &[T],
        s: &[T],
        (pr, ps): (f64, f64),
        (mr, ms): (f64, f64),
    ) -> [Neumaier; 6] {
        let mut tot = [Neumaier::default(); 6];
        let (vpr, vps, vmr, vms) = (_mm256_set1_pd(pr), _mm256_set1_pd(ps), _mm256_set1_pd(mr), _mm256_set1_pd(ms));
        for (cr, cs) in r.chunks(SUB).zip(s.chunks(SUB)) {
            let n = cr.len().min(cs.len());
            let full = n / LANES_C * LANES_C;
            let (pr_, ps_) = (cr.as_ptr(), cs.as_ptr());
            let mut a = [_mm256_setzero_pd(); 6];
            let mut j = 0;
            while j < full {
                // SAFETY: j + 4 <= full <= len of both runs (j steps by LANES_C = 4 up to full,
                // a multiple of 4)
                let (x, y) = (T::load4(pr_.add(j)), T::load4(ps_.add(j)));
                let dr = _mm256_sub_pd(_mm256_sub_pd(x, vpr), vmr);
                let ds = _mm256_sub_pd(_mm256_sub_pd(y, vps), vms);
                let d = _mm256_sub_pd(x, y);
                a[0] = _mm256_add_pd(a[0], dr);
                a[1] = _mm256_add_pd(a[1], ds);
                a[2] = _mm256_add_pd(a[2], _mm256_mul_pd(dr, dr));
                a[3] = _mm256_add_pd(a[3], _mm256_mul_pd(ds, ds));
                a[4] = _mm256_add_pd(a[4], _mm256_mul_pd(dr, ds));
                a[5] = _mm256_add_pd(a[5], _mm256_mul_pd(d, d));
                j += LANES_C;
            }
            let mut l = [[0.0f64; LANES_C]; 6];
            for (lane, v) in l.iter_mut().zip(a) {
                // SAFETY: each lane array holds LANES_C = 4 doubles, one 4-lane store
                _mm256_storeu_pd(lane.as_mut_ptr(), v);
            }
            for (&x, &y) in cr[full..n].iter().zip(&cs[full..n]) {
                super::centred_add(&mut l, 0, x.into(), y.into(), (pr, ps), (mr, ms));
            }
            for (t, lane) in tot.iter_mut().zip(&l) {
                t.add(lane.iter().sum());
            }
        }
        tot
    }
}

/// Σ(x − pivot_r), Σ(y − pivot_s) (compensated: both parts kept, so merging runs loses
/// nothing), the range of each run and max |value|.
pub(super) struct RunSums {
    pub(super) r: Neumaier,
    pub(super) s: Neumaier,
    /// Min and max of the real run ...
    pub(super) real_range: (f64, f64),
    /// ... and of the simulated one.
    pub(super) sim_range: (f64, f64),
    pub(super) max_abs: f64,
}

impl RunSums {
    fn empty() -> Self {
        RunSums {
            r: Neumaier::default(),
            s: Neumaier::default(),
            real_range: EMPTY_RANGE,
            sim_range: EMPTY_RANGE,
            max_abs: 0.0,
        }
    }
    fn merge(mut self, o: RunSums) -> RunSums {
        self.r.merge(&o.r);
        self.s.merge(&o.s);
        let union = |a: (f64, f64), b: (f64, f64)| (a.0.min(b.0), a.1.max(b.1));
        RunSums {
            real_range: union(self.real_range, o.real_range),
            sim_range: union(self.sim_range, o.sim_range),
            max_abs: self.max_abs.max(o.max_abs),
            ..self
        }
    }
    /// No NaN or ±Inf in the run: the sums stay finite (NaN and Inf propagate into them;
    /// values summing past f64's range are treated like non-finite ones, carefully).
    pub(super) fn finite(&self) -> bool {
        self.r.value().is_finite() && self.s.value().is_finite()
    }
}

/// Σ(x − pivot_r), Σ(y − pivot_s), range (when `RANGE`) and max |value| of a run of
/// pixels. Each lane is a compensated (two-sum) accumulator: the mean of wide-spread data
/// (±3e38 around 1e35) is the sum of large terms that cancel, so every addition's error is
/// kept. The AVX2 copy (`avx2::sums`, float32/float64) does the same operations per lane.
#[inline(always)]
fn float_sums<T: Sample, const RANGE: bool>(rr: &[T], sb: &[T], pivot: (f64, f64)) -> RunSums {
    avx2_floats!(rr, sb, |r, s| avx2::sums::<_, RANGE>(r, s, pivot));
    let mut st = SumLanes::new();
    let (ir, is) = (rr.chunks_exact(LANES), sb.chunks_exact(LANES));
    let (rem_r, rem_s) = (ir.remainder(), is.remainder());
    for (xr, xs) in ir.zip(is) {
        for k in 0..LANES {
            st.add::<T, RANGE>(k, xr[k].to_f64(), xs[k].to_f64(), pivot);
        }
    }
    st.finish::<T, RANGE>(rem_r, rem_s, pivot)
}

/// The range of no value: any value's widens it.
const EMPTY_RANGE: (f64, f64) = (f64::INFINITY, f64::NEG_INFINITY);

fn fold_min(lanes: &[f64; LANES]) -> f64 {
    lanes.iter().fold(EMPTY_RANGE.0, |m, &v| m.min(v))
}

fn fold_max(lanes: &[f64; LANES]) -> f64 {
    lanes.iter().fold(EMPTY_RANGE.1, |m, &v| m.max(v))
}

/// The lanes of `float_sums`: element `k` of every group of `LANES` goes to lane `k`.
struct SumLanes {
    lr: [f64; LANES],
    cr: [f64; LANES],
    ls: [f64; LANES],
    cs: [f64; LANES],
    max_abs: [f64; LANES],
    lo_r: [f64; LANES],
    hi_r: [f64; LANES],
    lo_s: [f64; LANES],
    hi_s: [f64; LANES],
}

impl SumLanes {
    fn new() -> Self {
        SumLanes {
            lr: [0.0; LANES],
            cr: [0.0; LANES],
            ls: [0.0; LANES],
            cs: [0.0; LANES],
            max_abs: [0.0; LANES],
            lo_r: [EMPTY_RANGE.0; LANES],
            hi_r: [EMPTY_RANGE.1; LANES],
            lo_s: [EMPTY_RANGE.0; LANES],
            hi_s: [EMPTY_RANGE.1; LANES],
        }
    }

    #[inline(always)]
    fn add<T: Sample, const RANGE: bool>(&mut self, k: usize, x: f64, y: f64, (pr, ps): (f64, f64)) {
        let (t, e) = two_sum(self.lr[k], x - pr);
        self.lr[k] = t;
        self.cr[k] += e;
        let (t, e) = two_sum(self.ls[k], y - ps);
        self.ls[k] = t;
        self.cs[k] += e;
        if RANGE {
            // plain compares (minpd/maxpd): a NaN is caught by the sums, not the range
            self.lo_r[k] = if x < self.lo_r[k] { x } else { self.lo_r[k] };
            self.hi_r[k] = if x > self.hi_r[k] { x } else { self.hi_r[k] };
            self.lo_s[k] = if y < self.lo_s[k] { y } else { self.lo_s[k] };
            self.hi_s[k] = if y > self.hi_s[k] { y } else { self.hi_s[k] };
        }
        self.max_abs[k] = bigger::<T>(self.max_abs[k], x, y);
    }

    /// The run's remainder (fewer than `LANES` pairs) into lane 0, then the lanes folded.
    #[inline(always)]
    fn finish<T: Sample, const RANGE: bool>(mut self, rem_r: &[T], rem_s: &[T], pivot: (f64, f64)) -> RunSums {
        for (&x, &y) in rem_r.iter().zip(rem_s) {
            self.add::<T, RANGE>(0, x.to_f64(), y.to_f64(), pivot);
        }
        let (mut tr, mut ts) = (Neumaier::default(), Neumaier::default());
        for k in 0..LANES {
            tr.add(self.lr[k]);
            tr.add(self.cr[k]);
            ts.add(self.ls[k]);
            ts.add(self.cs[k]);
        }
        RunSums {
            r: tr,
            s: ts,
            real_range: (fold_min(&self.lo_r), fold_max(&self.hi_r)),
            sim_range: (fold_min(&self.lo_s), fold_max(&self.hi_s)),
            max_abs: self.max_abs.iter().fold(0.0f64, |m, &v| m.max(v)),
        }
    }
}

/// Six compensated totals of a run, centred on `(pr + mr, ps + ms)`: Σdr, Σds, Σdr², Σds²,
/// Σdr·ds and Σ(x − y)². Four lanes per sum, folded into the totals every `SUB` values. The
/// AVX2 copy (`avx2::centred`, float32/float64) does the same additions in the same order:
/// LLVM vectorised this loop into half-width vectors with spills.
#[inline(always)]
fn centred_totals<T: Sample>(rr: &[T], sb: &[T], (pr, ps): (f64, f64), (mr, ms): (f64, f64)) -> [Neumaier; 6] {
    avx2_floats!(rr, sb, |r, s| avx2::centred(r, s, (pr, ps), (mr, ms)));
    let mut tot = [Neumaier::default(); 6];
    for (cr, cs) in rr.chunks(SUB).zip(sb.chunks(SUB)) {
        let mut l = [[0.0f64; LANES_C]; 6];
        let (ir, is) = (cr.chunks_exact(LANES_C), cs.chunks_exact(LANES_C));
        let (rem_r, rem_s) = (ir.remainder(), is.remainder());
        for (xr, xs) in ir.zip(is) {
            for k in 0..LANES_C {
                centred_add(&mut l, k, xr[k].to_f64(), xs[k].to_f64(), (pr, ps), (mr, ms));
            }
        }
        for (&x, &y) in rem_r.iter().zip(rem_s) {
            centred_add(&mut l, 0, x.to_f64(), y.to_f64(), (pr, ps), (mr, ms));
        }
        for (t, lane) in tot.iter_mut().zip(&l) {
            t.add(lane.iter().sum());
        }
    }
    tot
}

/// One value pair into lane `k` of the six centred sums.
#[inline(always)]
fn centred_add(l: &mut [[f64; LANES_C]; 6], k: usize, x: f64, y: f64, (pr, ps): (f64, f64), (mr, ms): (f64, f64)) {
    let (dr, ds) = (x - pr - mr, y - ps - ms);
    let d = x - y;
    l[0][k] += dr;
    l[1][k] += ds;
    l[2][k] += dr * dr;
    l[3][k] += ds * ds;
    l[4][k] += dr * ds;
    l[5][k] += d * d;
}

/// Count the run's pairs into the joint histogram. On a dense table with AVX2 (float32 and
/// float64), four pairs are binned at a time (`avx2::hist_dense`): the same arithmetic as
/// `Binner::float_bin`, so the same bins; the scalar loop spent most of its time there.
#[inline(always)]
fn float_hist<T: Sample>(rr: &[T], sb: &[T], (rb, sbn): (&Binner, &Binner), dense_bins: usize, acc: &mut Acc) {
    if dense_bins > 0 {
        // the dense table holds dense_bins² counts (`Acc::new`); hist_dense asserts it
        avx2_floats!(rr, sb, |r, s| avx2::hist_dense(r, s, (rb, sbn), &mut acc.dense));
    }
    for (&x, &y) in rr.iter().zip(sb) {
        acc.count(dense_bins, rb.float_bin(x.to_f64()), sbn.float_bin(y.to_f64()));
    }
}

/// Centred totals of a run about `(mr, ms)` (relative to the pivot: the run's own mean, or
/// the frames' means) and its histogram counts into `acc`.
#[inline(always)]
fn float_centred<T: Sample>(
    rr: &[T],
    sb: &[T],
    (mr, ms): (f64, f64),
    req: &Request,
    plan: Option<&HistPlan>,
    acc: &mut Acc,
    pivot: (f64, f64),
) -> [Neumaier; 6] {
    if rr.is_empty() {
        return Default::default();
    }
    let mut tot = if req.moments || req.sse { centred_totals(rr, sb, pivot, (mr, ms)) } else { Default::default() };
    if let Some(p) = plan {
        if let Some(rb) = p.binner.as_ref() {
            let sbn = p.sim_binner.as_ref().unwrap_or(rb);
            float_hist(rr, sb, (rb, sbn), p.dense_bins.unwrap_or(0), acc);
        }
    }
    if !req.sse {
        tot[5] = Neumaier::default(); // Σ(x − y)² is not part of this plan
    }
    tot
}

/// One compensated pass over both whole frames (no mask): each frame's sum, the largest
/// magnitude and (`with_range`: for the histogram) the range of both. Gives the pivot and
/// the centre of the float pass, and certifies that no value is NaN or ±Inf.
pub(super) fn float_scan<T: Sample>(r: &[T], s: &[T], with_range: bool) -> RunSums {
    let sums = |(a, b): (usize, usize)| -> Result<RunSums, std::convert::Infallible> {
        Ok(match with_range {
            true => float_sums::<T, true>(&r[a..b], &s[a..b], (0.0, 0.0)),
            false => float_sums::<T, false>(&r[a..b], &s[a..b], (0.0, 0.0)),
        })
    };
    let Ok(parts) = map_chunks(r.len(), cost::SCAN, sums);
    // compensated, in chunk order: the means do not depend on the thread count
    parts.into_iter().fold(RunSums::empty(), RunSums::merge)
}

/// The pivot of the float pass and, when the scan certified every value finite, the
/// centre (each frame's mean relative to the pivot). The pivot is each frame's mean cut
/// to 24 significant bits, or (with a mask or non-finite values) the first finite value.
pub(super) fn float_pivot<T: Sample>(r: &[T], s: &[T], scan: Option<&RunSums>) -> ((f64, f64), Option<(f64, f64)>) {
    if let Some(sc) = scan.filter(|sc| sc.finite()) {
        let n = r.len() as f64;
        let (mr, ms) = (sc.r.value() / n, sc.s.value() / n);
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
