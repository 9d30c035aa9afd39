//! The errors of simulated temperatures against real ones (`irfidelity.temperature.TemperatureErrors`):
//! one pass over the pixel pairs that count, those kept by the mask whose difference
//! `d = sim − real` is finite, giving their number, Σd, Σd², Σ|d| and how many |d| are within a
//! tolerance.
//!
//! Each chunk sums in independent lanes (vector registers), and the chunks' sums are
//! joined in chunk order by compensated addition, so the result does not depend on how the
//! chunks were shared out between threads.

use crate::kernel::map_chunks;
use crate::stats::Neumaier;
use crate::{Error, Result};

/// The sums over the pixel pairs that count.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ErrorSums {
    /// Pixel pairs counted.
    pub n: u64,
    /// Σd, Σd² and Σ|d|.
    pub sum: f64,
    pub squares: f64,
    pub magnitudes: f64,
    /// Pairs with |d| ≤ the tolerance.
    pub within: u64,
}

const LANES: usize = 8;
/// About the cost of one pair, in ns (decides threading).
const NS_PER_PX: f64 = 0.4;

/// [`ErrorSums`] of `sim − real` over the pairs `mask` keeps (all without one) whose difference is
/// finite; `tolerance` bounds the pairs counted as within.
pub fn error_sums(real: &[f64], sim: &[f64], mask: Option<&[bool]>, tolerance: f64) -> Result<ErrorSums> {
    if real.len() != sim.len() || mask.is_some_and(|m| m.len() != real.len()) {
        return Err(Error::Shape(format!(
            "the real ({}) and simulated ({}) temperatures and the mask must have as many values",
            real.len(),
            sim.len()
        )));
    }
    let Ok(parts) = map_chunks::<_, std::convert::Infallible>(real.len(), NS_PER_PX, |(a, b)| {
        Ok(chunk(&real[a..b], &sim[a..b], mask.map(|m| &m[a..b]), tolerance))
    });
    Ok(joined(&parts))
}

/// The chunks' sums joined in chunk order, by compensated addition (the chunks of
/// `crate::kernel::map_chunks`, whose bounds do not depend on the threads).
pub(crate) fn joined(parts: &[ErrorSums]) -> ErrorSums {
    let (mut sum, mut squares, mut magnitudes) = (Neumaier::default(), Neumaier::default(), Neumaier::default());
    let (mut n, mut within) = (0u64, 0u64);
    for part in parts {
        sum.add(part.sum);
        squares.add(part.squares);
        magnitudes.add(part.magnitudes);
        n += part.n;
        within += part.within;
    }
    ErrorSums { n, sum: sum.value(), squares: squares.value(), magnitudes: magnitudes.value(), within }
}

/// One chunk's sums, through explicit AVX2 when the CPU has it.
pub(crate) fn chunk(real: &[f64], sim: &[f64], mask: Option<&[bool]>, tolerance: f64) -> ErrorSums {
    #[cfg(target_arch = "x86_64")]
    if crate::kernel::use_avx2() {
        // SAFETY: `use_avx2` is true only when the CPU reports AVX2.
        return unsafe { avx2::chunk(real, sim, mask, tolerance) };
    }
    chunk_portable(real, sim, mask, tolerance)
}

/// The lanes of one chunk: blocks of eight pairs, the last one padded with pairs that do not count.
fn chunk_portable(real: &[f64], sim: &[f64], mask: Option<&[bool]>, tolerance: f64) -> ErrorSums {
    let (mut sum, mut squares, mut magnitudes) = ([0.0; LANES], [0.0; LANES], [0.0; LANES]);
    let (mut n, mut within) = ([0u64; LANES], [0u64; LANES]);
    let mut add = |l: usize, r: f64, s: f64, keep: bool| {
        let d = s - r;
        let counts = keep && d.is_finite();
        let d = if counts { d } else { 0.0 };
        sum[l] += d;
        squares[l] += d * d;
        magnitudes[l] += d.abs();
        n[l] += counts as u64;
        within[l] += (counts && d.abs() <= tolerance) as u64;
    };
    let blocks = real.len() / LANES;
    for block in 0..blocks {
        let at = block * LANES;
        let r: &[f64; LANES] = real[at..at + LANES].try_into().expect("a block of eight");
        let s: &[f64; LANES] = sim[at..at + LANES].try_into().expect("a block of eight");
        match mask {
            None => (0..LANES).for_each(|l| add(l, r[l], s[l], true)),
            Some(m) => {
                let m: &[bool; LANES] = m[at..at + LANES].try_into().expect("a block of eight");
                (0..LANES).for_each(|l| add(l, r[l], s[l], m[l]));
            }
        }
    }
    for (l, i) in (blocks * LANES..real.len()).enumerate() {
        add(l, real[i], sim[i], mask.is_none_or(|m| m[i]));
    }
    ErrorSums {
        n: n.iter().sum(),
        sum: sum.iter().sum(),
        squares: squares.iter().sum(),
        magnitudes: magnitudes.iter().sum(),
        within: within.iter().sum(),
    }
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::{chunk_portable, ErrorSums};
    use crate::kernel::int_avx2::kept_lanes;
    use std::arch::x86_64::*;

    /// [`chunk_portable`] four pairs per step: a pair counts when the mask keeps it and its
    /// difference is finite; the remainder (fewer than four pairs) goes through
    /// [`chunk_portable`].
    ///
    /// # Safety
    /// The CPU supports AVX2 (the loads stay within the slices for any lengths).
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn chunk(real: &[f64], sim: &[f64], mask: Option<&[bool]>, tolerance: f64) -> ErrorSums {
        let n = real.len().min(sim.len()).min(mask.map_or(usize::MAX, <[bool]>::len));
        let full = n / 4 * 4;
        let (infinity, magnitude) = (_mm256_set1_pd(f64::INFINITY), _mm256_set1_pd(f64::from_bits(!(1u64 << 63))));
        let limit = _mm256_set1_pd(tolerance);
        let (mut sum, mut squares, mut magnitudes) = (_mm256_setzero_pd(), _mm256_setzero_pd(), _mm256_setzero_pd());
        let (mut count, mut within) = (_mm256_setzero_si256(), _mm256_setzero_si256());
        let mut i = 0;
        while i < full {
            // SAFETY: 4 x f64 (twice) and 4 x bool loads at i with i + 4 <= full <= every length
            let d = _mm256_sub_pd(_mm256_loadu_pd(sim.as_ptr().add(i)), _mm256_loadu_pd(real.as_ptr().add(i)));
            let size = _mm256_and_pd(d, magnitude);
            // |d| < ∞ is false for ±∞ and NaN
            let mut keep = _mm256_cmp_pd::<_CMP_LT_OQ>(size, infinity);
            if let Some(m) = mask {
                keep = _mm256_and_pd(keep, kept_lanes(m, i));
            }
            let d = _mm256_and_pd(d, keep);
            let size = _mm256_and_pd(size, keep);
            sum = _mm256_add_pd(sum, d);
            squares = _mm256_add_pd(squares, _mm256_mul_pd(d, d));
            magnitudes = _mm256_add_pd(magnitudes, size);
            let close = _mm256_and_pd(keep, _mm256_cmp_pd::<_CMP_LE_OQ>(size, limit));
            // a true lane is all ones, -1 as an integer
            count = _mm256_sub_epi64(count, _mm256_castpd_si256(keep));
            within = _mm256_sub_epi64(within, _mm256_castpd_si256(close));
            i += 4;
        }
        let (mut lanes, mut counts) = ([[0.0f64; 4]; 3], [[0i64; 4]; 2]);
        // SAFETY: each array is 32 bytes, the size of one unaligned 256-bit store.
        for (out, v) in lanes.iter_mut().zip([sum, squares, magnitudes]) {
            _mm256_storeu_pd(out.as_mut_ptr(), v);
        }
        for (out, v) in counts.iter_mut().zip([count, within]) {
            _mm256_storeu_si256(out.as_mut_ptr() as *mut __m256i, v);
        }
        let rest = chunk_portable(&real[full..n], &sim[full..n], mask.map(|m| &m[full..n]), tolerance);
        let total = |k: usize| lanes[k].iter().sum::<f64>();
        ErrorSums {
            n: counts[0].iter().sum::<i64>() as u64 + rest.n,
            sum: total(0) + rest.sum,
            squares: total(1) + rest.squares,
            magnitudes: total(2) + rest.magnitudes,
            within: counts[1].iter().sum::<i64>() as u64 + rest.within,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sums_count_the_kept_finite_pairs_only() {
        let real: Vec<f64> = (0..1003).map(|i| 300.0 + i as f64 * 0.01).collect();
        let mut sim: Vec<f64> = real.iter().enumerate().map(|(i, r)| r + ((i % 7) as f64 - 3.0) * 0.5).collect();
        sim[3] = f64::NAN;
        sim[10] = f64::INFINITY;
        let mask: Vec<bool> = (0..1003).map(|i| i % 5 != 0).collect();
        let got = error_sums(&real, &sim, Some(&mask), 1.0).unwrap();
        let kept: Vec<f64> =
            (0..1003).filter(|&i| mask[i]).map(|i| sim[i] - real[i]).filter(|d| d.is_finite()).collect();
        assert_eq!(got.n, kept.len() as u64);
        assert_eq!(got.within, kept.iter().filter(|d| d.abs() <= 1.0).count() as u64);
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b.abs().max(1.0);
        assert!(close(got.sum, kept.iter().sum()));
        assert!(close(got.squares, kept.iter().map(|d| d * d).sum()));
        assert!(close(got.magnitudes, kept.iter().map(|d| d.abs()).sum()));
        // the AVX2 lanes (when the CPU has them) count what the portable ones do
        let portable = chunk_portable(&real, &sim, Some(&mask), 1.0);
        assert_eq!((portable.n, portable.within), (got.n, got.within));
        assert!(close(portable.sum, got.sum) && close(portable.squares, got.squares));
        // an overflowing difference does not count; mismatched lengths are refused
        let far = error_sums(&[-1e308, 1.0], &[1e308, 2.0], None, 1.0).unwrap();
        assert_eq!((far.n, far.sum, far.within), (1, 1.0, 1));
        assert!(error_sums(&[1.0], &[1.0, 2.0], None, 1.0).is_err());
    }
}
