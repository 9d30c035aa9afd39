//! SIMD dispatch: each chunk runs a copy of the loops compiled for AVX2 when the CPU has it
//! (the baseline x86-64 build assumes SSE2 only), the integer or float pass monomorphised
//! for the requested outputs.

use super::acc::{Acc, Bad};
use super::binning::HistPlan;
use super::float::float_chunk;
use super::int::int_chunk;
use super::request::Request;
use super::sample::Sample;

/// What every chunk of one call shares, read-only.
#[derive(Clone, Copy)]
pub(crate) struct Pass<'a, T> {
    pub(crate) r: &'a [T],
    pub(crate) s: &'a [T],
    pub(crate) req: &'a Request<'a>,
    pub(crate) plan: Option<&'a HistPlan>,
    /// float frames: the values the sums are taken relative to (see `float::float_pivot`)
    pub(crate) pivot: (f64, f64),
    /// float frames, all values finite, no mask: each frame's mean relative to the pivot,
    /// the centre of every chunk's sums
    pub(crate) centre: Option<(f64, f64)>,
}

avx2_copy! {
    /// One chunk, dispatched once per call to a copy of the loops compiled for AVX2 when the
    /// CPU has it (the baseline x86-64 build only assumes SSE2). Same code, same results.
    pub(super) fn run_chunk[T: Sample](
        pass: &Pass<'_, T>,
        range: (usize, usize),
        acc: &mut Acc,
        nf: &mut u64,
    ) -> std::result::Result<(), Bad>
    => run_chunk_avx2, run_chunk_impl
}

/// AVX2 when the CPU has it, unless `IRFIDELITY_NO_SIMD` is set (to compare both copies).
/// Every `unsafe` AVX2 call in the kernels is guarded by this being true.
#[cfg(target_arch = "x86_64")]
pub(crate) fn use_avx2() -> bool {
    #[cfg(test)]
    if tests::PORTABLE.with(|p| p.get()) {
        return false;
    }
    static USE: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *USE.get_or_init(|| std::arch::is_x86_feature_detected!("avx2") && std::env::var_os("IRFIDELITY_NO_SIMD").is_none())
}

#[inline(always)]
fn run_chunk_impl<T: Sample>(
    pass: &Pass<'_, T>,
    range: (usize, usize),
    acc: &mut Acc,
    nf: &mut u64,
) -> std::result::Result<(), Bad> {
    if !T::IS_INT {
        return float_chunk(pass, range, acc, nf);
    }
    // Monomorphise the hot loop for each combination of requested outputs.
    match (pass.req.sse, pass.req.moments, pass.plan.is_some()) {
        (true, true, true) => int_chunk::<T, true, true, true>(pass, range, acc),
        (true, true, false) => int_chunk::<T, true, true, false>(pass, range, acc),
        (true, false, true) => int_chunk::<T, true, false, true>(pass, range, acc),
        (true, false, false) => int_chunk::<T, true, false, false>(pass, range, acc),
        (false, true, true) => int_chunk::<T, false, true, true>(pass, range, acc),
        (false, true, false) => int_chunk::<T, false, true, false>(pass, range, acc),
        (false, false, true) => int_chunk::<T, false, false, true>(pass, range, acc),
        (false, false, false) => int_chunk::<T, false, false, false>(pass, range, acc),
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::kernel::driver::tests::all;
    use crate::kernel::{with_pool_busy, HistRequest, CHUNK};
    use crate::stats::{pair_stats, IntSums, Sums};

    thread_local! {
        /// Set: this thread's passes take the portable loops even on an AVX2 CPU.
        pub(crate) static PORTABLE: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
    }

    /// `f` with the AVX2 copies (where the CPU has them) and with the portable loops, on
    /// this thread alone (no pool helpers, which would not see the switch).
    pub(crate) fn both_paths<R>(f: impl Fn() -> R) -> [R; 2] {
        with_pool_busy(true, || {
            let simd = f();
            PORTABLE.with(|p| p.set(true));
            let portable = f();
            PORTABLE.with(|p| p.set(false));
            [simd, portable]
        })
    }

    /// Run lengths around every step of the explicit loops (4, 8 and 16 lanes, blocks of
    /// 128 and 256, a chunk); under Miri, which interprets every step, a tail after each
    /// step up to 257 and one length without a tail.
    pub(crate) fn boundary_lengths() -> Vec<usize> {
        if cfg!(miri) {
            return vec![0, 1, 5, 9, 16, 17, 129, 257];
        }
        (0..=20)
            .chain([31, 32, 33, 127, 128, 129, 255, 256, 257, 511, 513, CHUNK - 1, CHUNK, CHUNK + 1, 2 * CHUNK + 3])
            .collect()
    }

    /// Histogram plans for the boundary tests: none, dense (≤ 512 bins) and sparse; under
    /// Miri, none and dense (the unchecked table writes; a pass costs Miri a fraction of a
    /// second).
    fn boundary_hists(explicit: (f64, f64)) -> Vec<Option<HistRequest>> {
        let mut plans = vec![None, Some(HistRequest::Bins { bins: 64, range: Some(explicit) })];
        if !cfg!(miri) {
            let half = ((explicit.0 / 2.0).floor(), (explicit.1 / 2.0).floor());
            plans.push(Some(HistRequest::Bins { bins: 700, range: Some(half) }));
            plans.push(Some(HistRequest::Bins { bins: 512, range: None }));
            plans.push(Some(HistRequest::Bins { bins: 3, range: Some((explicit.0 + 1.0, explicit.0 + 2.0)) }));
        }
        plans
    }

    /// (sse, moments) plans: the SSE-only pass, the full pass, moments alone (not under Miri).
    fn boundary_plans() -> &'static [(bool, bool)] {
        if cfg!(miri) {
            &[(true, false), (true, true)]
        } else {
            &[(true, false), (true, true), (false, true)]
        }
    }

    /// Float frames: the AVX2 loops (squared error, scan, centred sums, dense histogram)
    /// give bit-identical statistics to the portable ones at every boundary length, with
    /// values beyond the histogram range on both sides (the clamps before the unchecked
    /// table writes), and NaN/Inf masked.
    #[test]
    fn float_simd_equals_portable_at_the_boundaries() {
        let mut seed = 3u64;
        let mut next = move || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        for n in boundary_lengths() {
            let r: Vec<f64> = (0..n).map(|i| if i % 97 == 5 { 1e300 } else { next() * 300.0 - 100.0 }).collect();
            let s: Vec<f64> =
                r.iter().enumerate().map(|(i, v)| if i % 89 == 3 { -1e300 } else { v + next() }).collect();
            let r32: Vec<f32> = r.iter().map(|&v| v.clamp(-3e38, 3e38) as f32).collect();
            let s32: Vec<f32> = s.iter().map(|&v| v.clamp(-3e38, 3e38) as f32).collect();
            let mut rn = r.clone();
            if n > 2 {
                rn[n / 2] = f64::NAN;
                rn[1] = f64::INFINITY;
            }
            for hist in boundary_hists((0.0, 100.0)) {
                for &(sse, moments) in boundary_plans() {
                    let req = Request { sse, moments, hist: hist.clone(), ..all() };
                    let [a, b] = both_paths(|| pair_stats(&r, &s, &req));
                    assert_eq!(a, b, "f64 n {n} {req:?}");
                    let [a, b] = both_paths(|| pair_stats(&r32, &s32, &req));
                    assert_eq!(a, b, "f32 n {n} {req:?}");
                    let req = Request { mask_nonfinite: true, ..req };
                    let [a, b] = both_paths(|| pair_stats(&rn, &s, &req));
                    assert_eq!(a, b, "f64 with NaN/Inf n {n} {req:?}");
                }
            }
        }
    }

    /// Integer frames: the AVX2 squared error and the unchecked dense-table counts equal
    /// the portable loops and a naive count at every boundary length, levels at both ends
    /// of each type.
    #[test]
    fn int_simd_equals_portable_at_the_boundaries() {
        for n in boundary_lengths() {
            let r16: Vec<u16> = (0..n).map(|i| [0u16, 65535, 1, 65534, 30000][i % 5] ^ (i as u16 & 7)).collect();
            let s16: Vec<u16> = r16.iter().rev().copied().collect();
            let r8: Vec<u8> = r16.iter().map(|&v| (v >> 8) as u8).collect();
            let s8: Vec<u8> = s16.iter().map(|&v| v as u8).collect();
            let ri: Vec<i16> = r16.iter().map(|&v| v as i16).collect();
            let si: Vec<i16> = s16.iter().map(|&v| v as i16).collect();
            let mut hists = boundary_hists((-5.0, 40000.0));
            if !cfg!(miri) {
                hists.push(Some(HistRequest::Levels));
            }
            for hist in hists {
                for &(sse, moments) in boundary_plans() {
                    let req = Request { sse, moments, hist: hist.clone(), ..all() };
                    let [a, b] = both_paths(|| pair_stats(&r8, &s8, &req).unwrap());
                    assert_eq!(a, b, "u8 n {n} {req:?}");
                    // Under Miri, 16-bit frames at one length (each of their passes builds a
                    // 65536-entry table: seconds in Miri)
                    if cfg!(miri) && (n != 17 || !moments) {
                        continue;
                    }
                    let [a, b] = both_paths(|| pair_stats(&r16, &s16, &req).unwrap());
                    assert_eq!(a, b, "u16 n {n} {req:?}");
                    let want: u128 = r16.iter().zip(&s16).map(|(&x, &y)| (x.abs_diff(y) as u128).pow(2)).sum();
                    assert!(!sse || matches!(a.sums, Sums::Int(IntSums { sse, .. }) if sse == want));
                    if let Some((_, joint)) = &a.hist {
                        assert_eq!(joint.total(), n as u64);
                    }
                    let [a, b] = both_paths(|| pair_stats(&ri, &si, &req).unwrap());
                    assert_eq!(a, b, "i16 n {n} {req:?}");
                }
            }
        }
    }
}
