//! The exact integer pass: u64/i64 sums per block, i128/u128 totals, the joint histogram
//! through a value → bin lookup table. Monomorphised per requested output.

use super::acc::{Acc, Bad};
use super::dispatch::Pass;
use super::range::min_max;
use super::sample::Sample;

const LO32: u64 = 0xffff_ffff;

/// The exact integer pass over `[a, b)`.
#[inline(always)]
pub(super) fn int_chunk<T: Sample, const SSE: bool, const MOM: bool, const HIST: bool>(
    pass: &Pass<'_, T>,
    (a, b): (usize, usize),
    acc: &mut Acc,
) -> std::result::Result<(), Bad> {
    let Pass { r, s, req, plan, .. } = *pass;
    #[cfg(target_arch = "x86_64")]
    if SSE && !MOM && !HIST && req.mask.is_none() && super::dispatch::use_avx2() {
        if let (Some(r16), Some(s16)) = (T::as_u16(&r[a..b]), T::as_u16(&s[a..b])) {
            // values outside `valid` go to the general loop below, which names the first one
            let valid = req
                .valid
                .is_none_or(|(vlo, vhi)| min_max(r16, s16).is_none_or(|(lo, hi)| lo as i64 >= vlo && hi as i64 <= vhi));
            if valid {
                // SAFETY: the CPU has AVX2 (`use_avx2`).
                acc.int.sse += unsafe { avx2::sse_u16(r16, s16) };
                acc.n += (b - a) as u64;
                return Ok(());
            }
        }
    }
    let dense_bins = plan.and_then(|p| p.dense_bins).unwrap_or(0);
    let binner = plan.and_then(|p| p.binner.as_ref());
    // the simulated frame's bins: its own (`HistRequest::Each`) or the shared ones
    let sim_binner = plan.and_then(|p| p.sim_binner.as_ref()).or(binner);
    let mut start = a;
    while start < b {
        let end = (start + T::BLOCK).min(b);
        let (mut sr, mut ss, mut srs) = (0i64, 0i64, 0i64);
        let (mut srr, mut sss, mut sse) = (0u64, 0u64, 0u64);
        // 32-bit frames: sums of x, y and the high halves of x², y², x·y, (x − y)²
        let (mut wr, mut ws, mut wrs) = (0u64, 0u64, 0u64);
        let (mut hrr, mut hss, mut hrs, mut hse) = (0u64, 0u64, 0u64, 0u64);
        let mut n = 0u64;
        // Moments and SSE first (a branch-free loop the compiler vectorises), then the
        // histogram scatter over the same block while it is still in cache. The bodies
        // are macros, not closures, so they inline into both the masked and plain loops.
        macro_rules! moments {
            ($x:expr, $y:expr) => {{
                let (x, y): (i64, i64) = ($x, $y);
                n += 1;
                if SSE {
                    if T::WIDE {
                        // 32-bit values: |x − y| < 2^32, its square fits u64; halves summed apart
                        let d = x.abs_diff(y);
                        let d2 = d * d;
                        sse += d2 & LO32;
                        hse += d2 >> 32;
                    } else {
                        // ≤ 16-bit values: x − y fits i32, its square fits u64 (vpmuldq)
                        let d = (x - y) as i32 as i64;
                        sse += (d * d) as u64;
                    }
                }
                if MOM {
                    if T::WIDE {
                        // 32-bit values (unsigned): squares and products fit u64, halves apart
                        let (ux, uy) = (x as u64, y as u64);
                        let (xx, yy, xy) = (ux * ux, uy * uy, ux * uy);
                        wr += ux;
                        ws += uy;
                        srr += xx & LO32;
                        hrr += xx >> 32;
                        sss += yy & LO32;
                        hss += yy >> 32;
                        wrs += xy & LO32;
                        hrs += xy >> 32;
                    } else {
                        // |values| < 2^16: squares are u32 × u32 → u64 (pmuludq), products fit i64
                        let (ux, uy) = (x.unsigned_abs() as u32 as u64, y.unsigned_abs() as u32 as u64);
                        sr += x;
                        ss += y;
                        srr += ux * ux;
                        sss += uy * uy;
                        srs += (x as i32 as i64) * (y as i32 as i64);
                    }
                }
            }};
        }
        macro_rules! bin {
            ($x:expr, $y:expr) => {{
                let (x, y): (i64, i64) = ($x, $y);
                match (binner, sim_binner) {
                    (Some(rb), Some(sb)) => acc.count(dense_bins, rb.int_bin(x, T::MIN), sb.int_bin(y, T::MIN)),
                    _ => acc.count(0, (x - T::MIN) as usize, (y - T::MIN) as usize),
                }
            }};
        }
        let (rr, sb) = (&r[start..end], &s[start..end]);
        match req.mask {
            None => {
                if SSE || MOM || !HIST {
                    for (&x, &y) in rr.iter().zip(sb) {
                        moments!(x.to_i64(), y.to_i64());
                    }
                } else {
                    n += rr.len() as u64;
                }
                if HIST {
                    match (binner, sim_binner) {
                        (Some(rb), Some(sbn))
                            if dense_bins > 0 && rb.lut.len() == T::LUT && sbn.lut.len() == T::LUT && T::LUT > 0 =>
                        {
                            // The hot case (8/16-bit frames, dense table): LUT gather + increment.
                            let (lut, sim_lut, dense) = (&rb.lut[..], &sbn.lut[..], &mut acc.dense[..]);
                            assert!(rb.bins == dense_bins && sbn.bins == dense_bins);
                            assert!(dense.len() == dense_bins * dense_bins);
                            for (&x, &y) in rr.iter().zip(sb) {
                                let (i, j) = ((x.to_i64() - T::MIN) as usize, (y.to_i64() - T::MIN) as usize);
                                // SAFETY: each table has one entry per value of T (len == T::LUT,
                                // checked above), so `i, j` index them; every entry is below `bins`
                                // == dense_bins (asserted above): a written entry is at most the bin
                                // of its range's top, which `IntEdges::new` proves below `bins`, and
                                // an entry kept from an earlier pass is below the bound
                                // `scratch::lut_below` took it with (≤ bins); so `k < dense_bins² ==
                                // dense.len()`. Tested at the type's extreme levels and ranges by
                                // `kernel::tests::int_bins_stay_below_bins_at_the_edges` and, for
                                // kept entries, `a_windowed_table_holds_the_rule_in_its_window_and_stays_below_bins`.
                                unsafe {
                                    let k = *lut.get_unchecked(i) as usize * dense_bins
                                        + *sim_lut.get_unchecked(j) as usize;
                                    *dense.get_unchecked_mut(k) += 1;
                                }
                            }
                        }
                        _ => {
                            for (&x, &y) in rr.iter().zip(sb) {
                                bin!(x.to_i64(), y.to_i64());
                            }
                        }
                    }
                }
            }
            Some(m) => {
                for ((&x, &y), &keep) in rr.iter().zip(sb).zip(&m[start..end]) {
                    if keep {
                        moments!(x.to_i64(), y.to_i64());
                        if HIST {
                            bin!(x.to_i64(), y.to_i64());
                        }
                    }
                }
            }
        }
        if let Some((vlo, vhi)) = req.valid {
            // a vectorised min/max first; the scan for the message only on failure
            let outside = min_max(rr, sb).is_some_and(|(lo, hi)| lo.to_i64() < vlo || hi.to_i64() > vhi);
            for i in (start..end).filter(|_| outside) {
                if req.mask.is_some_and(|m| !m[i]) {
                    continue;
                }
                for (frame, v) in [("real", r[i].to_i64()), ("sim", s[i].to_i64())] {
                    if v < vlo || v > vhi {
                        return Err(Bad::Range { frame, value: v, index: i });
                    }
                }
            }
        }
        acc.n += n;
        let join = |lo: u64, hi: u64| lo as u128 + ((hi as u128) << 32);
        let t = &mut acc.int;
        t.sse += join(sse, hse);
        t.sr += sr as i128 + wr as i128;
        t.ss += ss as i128 + ws as i128;
        t.srr += join(srr, hrr);
        t.sss += join(sss, hss);
        t.srs += srs as i128 + join(wrs, hrs) as i128;
        start = end;
    }
    Ok(())
}

/// Σ(x − y)² of uint16 frames with explicit AVX2, sixteen pixels per step: |x − y| by two
/// saturating subtractions, split into bytes h and l, then `vpmaddwd` gives the pair sums of
/// h², h·l and l² in i32 lanes, d² = 2^16·h² + 2^9·h·l + l² summed exactly. The generic loop
/// widens every value to 64 bits (four per vector); this keeps sixteen per vector.
#[cfg(target_arch = "x86_64")]
pub(crate) mod avx2 {
    use std::arch::x86_64::*;

    /// Steps (of sixteen pixels) per block of [`SquareSums`]: each adds < 2^17 to every i32
    /// lane, so 2^14 steps stay below 2^31.
    pub(crate) const STEPS: usize = 1 << 14;

    /// The eight u32 lanes of `v`, summed.
    ///
    /// # Safety
    /// The CPU supports AVX2.
    #[target_feature(enable = "avx2")]
    unsafe fn lanes_sum(v: __m256i) -> u128 {
        let mut lanes = [0u32; 8];
        // SAFETY: `lanes` is 32 bytes, the size of one unaligned 256-bit store.
        _mm256_storeu_si256(lanes.as_mut_ptr() as *mut __m256i, v);
        lanes.iter().map(|&x| x as u128).sum()
    }

    /// Four mask values from `at` as float64 lanes: all ones where the mask keeps the pixel,
    /// zero where it does not (to `and` into a lane mask).
    ///
    /// # Safety
    /// `at + 4 <= mask.len()`.
    #[inline]
    #[target_feature(enable = "avx2")]
    pub(crate) unsafe fn kept_lanes(mask: &[bool], at: usize) -> __m256d {
        // SAFETY: four bools (4 bytes) at `at`, within the mask by the caller's contract
        let bytes = unsafe { (mask.as_ptr().add(at) as *const u32).read_unaligned() };
        let kept = _mm256_cmpgt_epi64(_mm256_cvtepu8_epi64(_mm_cvtsi32_si128(bytes as i32)), _mm256_setzero_si256());
        _mm256_castsi256_pd(kept)
    }

    /// |x − y| of sixteen u16 lanes (two saturating subtractions).
    #[inline]
    #[target_feature(enable = "avx2")]
    pub(crate) fn abs_diff(x: __m256i, y: __m256i) -> __m256i {
        _mm256_or_si256(_mm256_subs_epu16(x, y), _mm256_subs_epu16(y, x))
    }

    /// Σ d² of u16 lanes over at most [`STEPS`] steps, exactly: the pair sums of h², h·l and l²
    /// of d's bytes in i32 lanes.
    #[derive(Clone, Copy)]
    pub(crate) struct SquareSums {
        hh: __m256i,
        hl: __m256i,
        ll: __m256i,
    }

    impl SquareSums {
        #[inline]
        #[target_feature(enable = "avx2")]
        pub(crate) fn new() -> SquareSums {
            SquareSums { hh: _mm256_setzero_si256(), hl: _mm256_setzero_si256(), ll: _mm256_setzero_si256() }
        }

        /// Adds the squares of the sixteen lanes of `d`.
        #[inline]
        #[target_feature(enable = "avx2")]
        pub(crate) fn add(&mut self, d: __m256i) {
            let (h, l) = (_mm256_srli_epi16::<8>(d), _mm256_and_si256(d, _mm256_set1_epi16(0xff)));
            self.hh = _mm256_add_epi32(self.hh, _mm256_madd_epi16(h, h));
            self.hl = _mm256_add_epi32(self.hl, _mm256_madd_epi16(h, l));
            self.ll = _mm256_add_epi32(self.ll, _mm256_madd_epi16(l, l));
        }

        /// Σ d² = 2^16·Σh² + 2^9·Σh·l + Σl².
        #[target_feature(enable = "avx2")]
        pub(crate) fn total(self) -> u128 {
            // SAFETY: this function's own target feature (AVX2) is what `lanes_sum` needs.
            unsafe { (lanes_sum(self.hh) << 16) + (lanes_sum(self.hl) << 9) + lanes_sum(self.ll) }
        }
    }

    /// Σ(r − s)² over the common length, exactly.
    ///
    /// # Safety
    /// The CPU supports AVX2 (the loads stay within both slices for any lengths).
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn sse_u16(r: &[u16], s: &[u16]) -> u128 {
        let n = r.len().min(s.len());
        let full = n / 16 * 16;
        let mut total: u128 = 0;
        let mut start = 0;
        while start < full {
            let end = (start + 16 * STEPS).min(full);
            let mut sums = SquareSums::new();
            let mut i = start;
            while i < end {
                // SAFETY: unaligned 16 x u16 loads at i with i + 16 <= full <= the length of both
                // slices (i steps by 16 from 0 up to end <= full, a multiple of 16)
                let x = _mm256_loadu_si256(r.as_ptr().add(i) as *const __m256i);
                let y = _mm256_loadu_si256(s.as_ptr().add(i) as *const __m256i);
                sums.add(abs_diff(x, y));
                i += 16;
            }
            total += sums.total();
            start = end;
        }
        total + r[full..n].iter().zip(&s[full..n]).map(|(&x, &y)| (x.abs_diff(y) as u64).pow(2) as u128).sum::<u128>()
    }
}

#[cfg(test)]
mod tests {
    use crate::stats::{pair_stats, Request, Sums};

    /// The SSE-only pass (the AVX2 loop where available) equals a naive u128 sum, with
    /// saturated differences, lengths off the 16-pixel step and more than one block.
    #[test]
    fn uint16_squared_error_is_exact() {
        let mut seed = 7u64;
        let mut next = move || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 48) as u16
        };
        let lengths: &[usize] = if cfg!(miri) { &[1, 15, 16, 17, 33] } else { &[1, 15, 16, 17, 1000, 300_001] };
        for &n in lengths {
            for kind in 0..3 {
                let (r, s): (Vec<u16>, Vec<u16>) = (0..n)
                    .map(|i| match kind {
                        0 => (next(), next()),
                        1 => (if i % 2 == 0 { 0 } else { 65535 }, if i % 2 == 0 { 65535 } else { 0 }),
                        _ => (40000 + (i % 7) as u16, 40000),
                    })
                    .unzip();
                let want: u128 = r.iter().zip(&s).map(|(&x, &y)| (x.abs_diff(y) as u128).pow(2)).sum();
                let req = Request { sse: true, moments: false, hist: None, ..Request::default() };
                let st = pair_stats(&r, &s, &req).unwrap();
                let Sums::Int(sums) = &st.sums else { panic!("integer sums expected") };
                assert_eq!(sums.sse, want, "n={n} kind={kind}");
            }
        }
    }
}
