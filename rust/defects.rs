//! Where a frame pair's squared error sits: its total, the share its largest values carry and
//! the share on the frame's border — the numbers `irfidelity.defects.concentrated_error`
//! judges (a dead cluster, stuck pixels, a hot border decide global SSIM and MSE).
//!
//! One pass gives the total, the scored pixels, the largest square, Σ v² (the squares'
//! squares) and the border's sums. The `top` largest squares are searched for only when three
//! bounds cannot rule out that they carry more than `limit` (see [`may_dominate`]). Squares are
//! float64 (exact for frames of ≤ 16-bit integers); each chunk's sums are combined in chunk
//! order, so a result does not depend on the threads that computed it.

use std::cmp::Ordering;

use crate::kernel::{fold_chunks, map_chunks, Sample};
use crate::radiometry::errors::{chunk as error_chunk, joined, ErrorSums};

/// What is asked: the share of the scored pixels whose largest squares are examined, the share
/// of the total they must carry to dominate, and the border's width in pixels; with a
/// `tolerance`, also the pair's temperature errors (float64 frames); with a `spread_step`, also
/// the spread of the differences sampled at that step ([`sampled_differences`]).
#[derive(Clone, Copy, Debug)]
pub struct Question {
    pub top_share: f64,
    pub most: f64,
    pub border: usize,
    pub tolerance: Option<f64>,
    pub spread_step: Option<usize>,
}

/// The border's squared error, scored pixels and their bounding box (row0, row1, col0, col1,
/// inclusive; None when no border pixel is scored).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Border {
    pub total: f64,
    pub count: u64,
    pub bounds: Option<[usize; 4]>,
}

/// The answer: totals over the scored pixels, the border's, and the `top` largest squares
/// (largest first, ties by the smaller flat index) when the bounds could not rule them out.
#[derive(Clone, Debug)]
pub struct Profile {
    pub total: f64,
    pub count: u64,
    /// The largest square.
    pub largest: f64,
    pub border: Border,
    pub top: Option<Vec<(f64, usize)>>,
    /// The temperature errors over the scored pixels, as `crate::radiometry::error_sums` gives
    /// them (the same chunks, joined the same way): when a tolerance was asked and both frames
    /// are float64.
    pub errors: Option<ErrorSums>,
    /// [`sample_spread`] of [`sampled_differences`] at the asked step, when asked.
    pub spread: Option<(usize, Option<Spread>)>,
}

/// Two frames of `rows × cols` samples (row-major) and the scored pixels (`mask`).
struct Pair<'a, A, B> {
    real: &'a [A],
    sim: &'a [B],
    mask: Option<&'a [bool]>,
}

/// One chunk's (or the frame's) sums: the squares, their squares (Σ v², for the
/// Cauchy–Schwarz bound), the scored pixels and the largest square.
#[derive(Clone, Copy, Debug, Default)]
struct Sums {
    total: f64,
    squares: f64,
    count: u64,
    largest: f64,
}

/// Σ v² may be summed in float32 steps (the uint16 AVX2 pass): this relative margin covers their
/// rounding (< 3.1e-5) in the Cauchy–Schwarz bound.
const FOURTH_MARGIN: f64 = 1.0 + 1e-4;

/// Chunk passes cost about this many ns per pixel (decides threading).
const NS_PER_PX: f64 = 0.5;
const LANES: usize = 8;

/// The squared difference of `x` and `y`, 0 where the pixel is not scored (`keep` false, or
/// either value not finite), and whether it is scored.
#[inline(always)]
fn square<A: Sample, B: Sample>(x: A, y: B, keep: bool) -> (f64, bool) {
    let (x, y) = (x.to_f64(), y.to_f64());
    let kept = keep && (A::IS_INT || x.is_finite()) && (B::IS_INT || y.is_finite());
    let d = y - x;
    (if kept { d * d } else { 0.0 }, kept)
}

impl<A: Sample, B: Sample> Pair<'_, A, B> {
    /// The square at flat index `i` (see [`square`]).
    #[inline(always)]
    fn square(&self, i: usize) -> (f64, bool) {
        square(self.real[i], self.sim[i], self.mask.is_none_or(|m| m[i]))
    }

    /// `step(squares, scored)` over `[a, b)` in blocks of eight (the last padded with unscored
    /// zeros): fixed-size blocks the compiler keeps in vector registers.
    #[inline(always)]
    fn each(&self, (a, b): (usize, usize), mut step: impl FnMut(&[f64; LANES], &[bool; LANES])) {
        let (real, sim) = (&self.real[a..b], &self.sim[a..b]);
        let mask = self.mask.map(|m| &m[a..b]);
        let blocks = (b - a) / LANES;
        for block in 0..blocks {
            let at = block * LANES;
            let x: &[A; LANES] = real[at..at + LANES].try_into().expect("a block of eight");
            let y: &[B; LANES] = sim[at..at + LANES].try_into().expect("a block of eight");
            let (mut v, mut k) = ([0.0; LANES], [false; LANES]);
            match mask {
                None => (0..LANES).for_each(|l| (v[l], k[l]) = square(x[l], y[l], true)),
                Some(m) => {
                    let m: &[bool; LANES] = m[at..at + LANES].try_into().expect("a block of eight");
                    (0..LANES).for_each(|l| (v[l], k[l]) = square(x[l], y[l], m[l]));
                }
            }
            step(&v, &k);
        }
        let (mut v, mut k) = ([0.0; LANES], [false; LANES]);
        for (l, i) in (a + blocks * LANES..b).enumerate() {
            (v[l], k[l]) = self.square(i);
        }
        step(&v, &k);
    }

    /// [`Pair::sums`], through explicit AVX2 for the common cases: two unmasked uint16 frames
    /// (an unregistered pair), a uint16 frame against a float64 one over a mask (a registered
    /// pair's resampled frame over the overlap).
    #[inline(always)]
    fn chunk_sums(&self, (a, b): (usize, usize)) -> Sums {
        #[cfg(target_arch = "x86_64")]
        if crate::kernel::use_avx2() {
            let (real, sim, mask) = (&self.real[a..b], &self.sim[a..b], self.mask.map(|m| &m[a..b]));
            if let (Some(real), Some(sim), None) = (A::as_u16(real), B::as_u16(sim), mask) {
                // SAFETY: `use_avx2` is true only when the CPU reports AVX2.
                return unsafe { avx2::sums_u16(real, sim) };
            }
            if let (Some(real), Some(sim)) = (A::as_u16(real), B::as_f64(sim)) {
                // SAFETY: as above.
                return unsafe { avx2::sums_f64(real, sim, mask) };
            }
            if let (Some(real), Some(sim)) = (A::as_f64(real), B::as_f64(sim)) {
                // SAFETY: as above.
                return unsafe { avx2::sums_f64(real, sim, mask) };
            }
        }
        self.sums((a, b))
    }

    /// Total, sum of squares, scored pixels and largest square of `[a, b)`.
    #[inline(always)]
    fn sums(&self, range: (usize, usize)) -> Sums {
        let (mut total, mut squares, mut largest) = ([0.0; LANES], [0.0; LANES], [0.0f64; LANES]);
        let mut count = [0u64; LANES];
        self.each(range, |v, kept| {
            for l in 0..LANES {
                total[l] += v[l];
                squares[l] += v[l] * v[l];
                count[l] += kept[l] as u64;
                largest[l] = if v[l] > largest[l] { v[l] } else { largest[l] };
            }
        });
        Sums {
            total: total.iter().sum(),
            squares: squares.iter().sum(),
            count: count.iter().sum(),
            largest: largest.iter().fold(0.0, |m, &v| if v > m { v } else { m }),
        }
    }

    /// Sum and number of the squares above `tau` in `[a, b)`.
    #[inline(always)]
    fn above(&self, range: (usize, usize), tau: f64) -> (f64, u64) {
        let (mut total, mut count) = ([0.0; LANES], [0u64; LANES]);
        self.each(range, |v, _| {
            for l in 0..LANES {
                let over = v[l] > tau;
                total[l] += if over { v[l] } else { 0.0 };
                count[l] += over as u64;
            }
        });
        (total.iter().sum(), count.iter().sum())
    }

    /// The flat indices in `[a, b)`, ascending, of the scored pixels whose difference lies more
    /// than `threshold` from `median` (see [`far_pixels`]); None once there are more than `most`.
    fn far(
        &self,
        (a, b): (usize, usize),
        median: f64,
        threshold: f64,
        most: usize,
    ) -> crate::Result<Option<Vec<usize>>> {
        let mut found = Vec::new();
        let is_far = |i: usize| {
            let d = self.sim[i].to_f64() - self.real[i].to_f64();
            (d - median).abs() > threshold && self.mask.is_none_or(|m| m[i])
        };
        let mut start = a;
        while start < b {
            let end = (start + LANES).min(b);
            // a block of eight tested without a branch each: far pixels are rare
            if (start..end).fold(false, |any, i| any | is_far(i)) {
                for i in (start..end).filter(|&i| is_far(i)) {
                    if found.len() == most {
                        return Ok(None);
                    }
                    found.try_reserve(1).map_err(|_| {
                        crate::Error::Value(format!("not enough memory to list {} far pixels", found.len() + 1))
                    })?;
                    found.push(i);
                }
            }
            start = end;
        }
        Ok(Some(found))
    }

    /// Adds the squares of `[a, b)` that rank among the `top` largest so far to `found`.
    fn largest(&self, found: &mut Candidates, (a, b): (usize, usize), top: usize) -> crate::Result<()> {
        for i in a..b {
            let (v, _) = self.square(i);
            if v > found.threshold {
                found.push((v, i), top)?;
            }
        }
        Ok(())
    }
}

/// What one worker keeps of the largest squares: at most `2·top` (cut back to the `top`
/// first when full) and the value a square must exceed to enter (later equal values rank
/// lower: their indices are larger).
#[derive(Default)]
struct Candidates {
    kept: Vec<(f64, usize)>,
    threshold: f64,
}

impl Candidates {
    fn push(&mut self, candidate: (f64, usize), top: usize) -> crate::Result<()> {
        if self.kept.capacity() == 0 {
            self.kept.try_reserve_exact(2 * top + 1).map_err(|_| {
                crate::Error::Value(format!(
                    "not enough memory to search the {top} largest squared differences ({} bytes)",
                    (2 * top + 1) * std::mem::size_of::<(f64, usize)>()
                ))
            })?;
        }
        self.kept.push(candidate);
        if self.kept.len() > 2 * top {
            keep_largest(&mut self.kept, top);
            self.threshold = self.kept[top - 1].0;
        }
        Ok(())
    }

    /// Both workers' candidates, cut to the `top` first.
    fn merge(mut self, mut other: Candidates, top: usize) -> Candidates {
        keep_largest(&mut self.kept, top);
        keep_largest(&mut other.kept, top);
        if self.kept.capacity() < other.kept.capacity() {
            std::mem::swap(&mut self, &mut other);
        }
        self.kept.append(&mut other.kept); // within the 2·top + 1 reserved
        keep_largest(&mut self.kept, top);
        self
    }
}

/// Largest first, ties by the smaller index.
fn rank(a: &(f64, usize), b: &(f64, usize)) -> Ordering {
    b.0.total_cmp(&a.0).then(a.1.cmp(&b.1))
}

/// Cut `values` to its `top` first by [`rank`] (unordered but for the last, the `top`-th).
fn keep_largest(values: &mut Vec<(f64, usize)>, top: usize) {
    if values.len() > top {
        values.select_nth_unstable_by(top - 1, rank);
        values.truncate(top);
    }
}

/// A chunk's [`Pair::chunk_sums`], compiled on its own (the loops optimise there as they do
/// not inlined into the chunk scheduler's closure).
#[inline(never)]
fn chunk_sums<A: Sample, B: Sample>(pair: &Pair<'_, A, B>, range: (usize, usize)) -> Sums {
    pair.chunk_sums(range)
}

/// A chunk's [`Pair::above`], like [`chunk_sums`].
#[inline(never)]
fn chunk_above<A: Sample, B: Sample>(pair: &Pair<'_, A, B>, range: (usize, usize), tau: f64) -> (f64, u64) {
    pair.above(range, tau)
}

/// [`Pair::sums`] of two uint16 frames with explicit AVX2, sixteen pixels per step: |x − y| by
/// two saturating subtractions; its square summed exactly as bytes (as `kernel::int`'s
/// squared-error loop does), its largest by lane maxima, its fourth power in float32 lanes
/// joined in float64 every 2^8 steps (an upper bound's input: `FOURTH_MARGIN`).
#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::Sums;
    use crate::kernel::int_avx2::{abs_diff, kept_lanes, SquareSums, STEPS};
    use std::arch::x86_64::*;

    /// Steps per float32 partial sum of the fourth powers: each term is rounded once or twice
    /// (relative 2^-23 each) and 2^8 of them summed in float32 before joining the float64
    /// total, so the sum is within 2^8 · 2^-23 < 3.1e-5 of the exact one, relative
    /// (`FOURTH_MARGIN` covers it).
    const FOURTH_STEPS: usize = 1 << 8;

    /// The fourth powers of the sixteen u16 lanes of `d`, added to two float32 vectors.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn add_fourth(d: __m256i, fourth: &mut [__m256; 2]) {
        let halves = [_mm256_castsi256_si128(d), _mm256_extracti128_si256::<1>(d)];
        for (part, half) in fourth.iter_mut().zip(halves) {
            let f = _mm256_cvtepi32_ps(_mm256_cvtepu16_epi32(half)); // exact: < 2^16
            let f2 = _mm256_mul_ps(f, f);
            *part = _mm256_add_ps(*part, _mm256_mul_ps(f2, f2));
        }
    }

    /// The eight float32 lanes of both vectors, summed in float64.
    #[target_feature(enable = "avx2")]
    fn lanes_sum_f32(fourth: [__m256; 2]) -> f64 {
        let mut lanes = [0.0f32; 8];
        let mut total = 0.0;
        for part in fourth {
            // SAFETY: `lanes` is 32 bytes, the size of one unaligned 256-bit store.
            unsafe { _mm256_storeu_ps(lanes.as_mut_ptr(), part) };
            total += lanes.iter().map(|&x| x as f64).sum::<f64>();
        }
        total
    }

    /// Total, sum of squares, count and largest square of `(r − s)²` over the common length.
    ///
    /// # Safety
    /// The CPU supports AVX2 (the loads stay within both slices for any lengths).
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn sums_u16(r: &[u16], s: &[u16]) -> Sums {
        let n = r.len().min(s.len());
        let full = n / 16 * 16;
        let (mut total, mut largest, mut squares) = (0u128, _mm256_setzero_si256(), 0.0f64);
        let mut start = 0;
        while start < full {
            let end = (start + 16 * STEPS).min(full);
            let mut exact = SquareSums::new();
            let mut i = start;
            while i < end {
                let stop = (i + 16 * FOURTH_STEPS).min(end);
                let mut fourth = [_mm256_setzero_ps(); 2];
                while i < stop {
                    // SAFETY: unaligned 16 x u16 loads at i with i + 16 <= full <= the length of
                    // both slices (i steps by 16 from 0 up to stop <= full, a multiple of 16)
                    let x = _mm256_loadu_si256(r.as_ptr().add(i) as *const __m256i);
                    let y = _mm256_loadu_si256(s.as_ptr().add(i) as *const __m256i);
                    let d = abs_diff(x, y);
                    largest = _mm256_max_epu16(largest, d);
                    exact.add(d);
                    add_fourth(d, &mut fourth);
                    i += 16;
                }
                squares += lanes_sum_f32(fourth);
            }
            total += exact.total();
            start = end;
        }
        let mut lanes = [0u16; 16];
        // SAFETY: `lanes` is 32 bytes, the size of one unaligned 256-bit store.
        _mm256_storeu_si256(lanes.as_mut_ptr() as *mut __m256i, largest);
        let mut sums = Sums { count: n as u64, squares, ..Sums::default() };
        let mut top = lanes.iter().copied().max().unwrap_or(0);
        for (&x, &y) in r[full..n].iter().zip(&s[full..n]) {
            let d = x.abs_diff(y);
            total += (d as u128).pow(2);
            let square = (d as f64) * (d as f64);
            sums.squares += square * square;
            top = top.max(d);
        }
        sums.total = total as f64;
        sums.largest = top as f64 * top as f64; // exact (powi need not be)
        sums
    }

    /// Real frames [`sums_f64`] reads four values at a time, as float64.
    pub(super) trait RealLanes: crate::kernel::Sample {
        /// # Safety
        /// The CPU supports AVX2 and `p` points at four readable values.
        unsafe fn load4(p: *const Self) -> __m256d;
    }

    impl RealLanes for u16 {
        #[inline(always)]
        unsafe fn load4(p: *const u16) -> __m256d {
            // SAFETY: the caller's contract: four u16 (8 bytes) at p
            unsafe { _mm256_cvtepi32_pd(_mm_cvtepu16_epi32(_mm_loadl_epi64(p as *const __m128i))) }
        }
    }

    impl RealLanes for f64 {
        #[inline(always)]
        unsafe fn load4(p: *const f64) -> __m256d {
            // SAFETY: the caller's contract: four f64 at p
            unsafe { _mm256_loadu_pd(p) }
        }
    }

    /// [`Sums`](super::Sums) of a uint16 or float64 frame (a registered pair's real frame, a
    /// frame in temperature) against a float64 one over `mask` (all pixels when None), four
    /// pixels per step: a pixel counts when the mask keeps it and its float values are finite;
    /// the squares are those of [`super::square`].
    ///
    /// # Safety
    /// The CPU supports AVX2 (the loads stay within the slices for any lengths).
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn sums_f64<R: RealLanes>(r: &[R], s: &[f64], mask: Option<&[bool]>) -> Sums {
        let n = r.len().min(s.len()).min(mask.map_or(usize::MAX, <[bool]>::len));
        let full = n / 4 * 4;
        let (infinity, magnitude) = (_mm256_set1_pd(f64::INFINITY), _mm256_set1_pd(f64::from_bits(!(1u64 << 63))));
        let (mut total, mut squares, mut largest) = (_mm256_setzero_pd(), _mm256_setzero_pd(), _mm256_setzero_pd());
        let mut count = _mm256_setzero_si256();
        let mut i = 0;
        while i < full {
            // SAFETY: 4 x R, 4 x f64 and 4 x bool loads at i with i + 4 <= full <= every length
            let x = R::load4(r.as_ptr().add(i));
            let y = _mm256_loadu_pd(s.as_ptr().add(i));
            // |v| < ∞ is false for ±∞ and NaN
            let finite = |v: __m256d| _mm256_cmp_pd::<_CMP_LT_OQ>(_mm256_and_pd(v, magnitude), infinity);
            let mut keep = finite(y);
            if !R::IS_INT {
                keep = _mm256_and_pd(keep, finite(x));
            }
            if let Some(m) = mask {
                keep = _mm256_and_pd(keep, kept_lanes(m, i));
            }
            let d = _mm256_sub_pd(y, x);
            let v = _mm256_and_pd(_mm256_mul_pd(d, d), keep);
            total = _mm256_add_pd(total, v);
            squares = _mm256_add_pd(squares, _mm256_mul_pd(v, v));
            largest = _mm256_max_pd(largest, v);
            count = _mm256_sub_epi64(count, _mm256_castpd_si256(keep)); // a kept lane is -1
            i += 4;
        }
        let (mut t, mut q, mut l, mut c) = ([0.0f64; 4], [0.0f64; 4], [0.0f64; 4], [0i64; 4]);
        // SAFETY: each array is 32 bytes, the size of one unaligned 256-bit store.
        _mm256_storeu_pd(t.as_mut_ptr(), total);
        _mm256_storeu_pd(q.as_mut_ptr(), squares);
        _mm256_storeu_pd(l.as_mut_ptr(), largest);
        _mm256_storeu_si256(c.as_mut_ptr() as *mut __m256i, count);
        let mut sums = Sums {
            total: t.iter().sum(),
            squares: q.iter().sum(),
            count: c.iter().sum::<i64>() as u64,
            largest: l.iter().fold(0.0, |m, &v| if v > m { v } else { m }),
        };
        for j in full..n {
            let (v, kept) = super::square(r[j], s[j], mask.is_none_or(|m| m[j]));
            sums.total += v;
            sums.squares += v * v;
            sums.count += kept as u64;
            sums.largest = if v > sums.largest { v } else { sums.largest };
        }
        sums
    }
}

/// Whether `y` is within `width` of the first or last of `n` rows (or columns).
fn near_edge(y: usize, n: usize, width: usize) -> bool {
    y < width || y + width >= n
}

/// The border's sums: the rows near the top and bottom edges, and in the other rows the
/// columns near the left and right edges (each pixel once).
fn border_sums<A: Sample, B: Sample>(pair: &Pair<'_, A, B>, (rows, cols): (usize, usize), width: usize) -> Border {
    let mut border = Border::default();
    let mut add = |y: usize, x: usize| {
        let (v, kept) = pair.square(y * cols + x);
        if kept {
            border.total += v;
            border.count += 1;
            let b = border.bounds.get_or_insert([y, y, x, x]);
            *b = [b[0].min(y), b[1].max(y), b[2].min(x), b[3].max(x)];
        }
    };
    let sides = (0..width.min(cols)).chain(width.max(cols.saturating_sub(width))..cols);
    for y in 0..rows {
        if near_edge(y, rows, width) {
            (0..cols).for_each(|x| add(y, x));
        } else {
            sides.clone().for_each(|x| add(y, x));
        }
    }
    border
}

/// The squared error of `real` against `sim` (`rows × cols`, row-major, over `mask`), and where
/// it sits (see the module's text).
pub fn profile<A: Sample, B: Sample>(
    real: &[A],
    sim: &[B],
    mask: Option<&[bool]>,
    shape: (usize, usize),
    question: Question,
) -> crate::Result<Profile> {
    let n = shape.0 * shape.1;
    if real.len() != n || sim.len() != n || mask.is_some_and(|m| m.len() != n) {
        return Err(crate::Error::Shape(format!("the frames and mask must have {n} samples ({shape:?})")));
    }
    let pair = Pair { real, sim, mask };
    // the temperature errors read each chunk while the profile's pass has it in cache
    let temperatures = question.tolerance.and_then(|t| Some((A::as_f64(real)?, B::as_f64(sim)?, t)));
    // ... and so does the sample of the defects' threshold
    if question.spread_step == Some(0) {
        return Err(crate::Error::Value("spread_step: expected at least 1 pixel".into()));
    }
    let parts = map_chunks(n, NS_PER_PX, |(a, b)| {
        let errors = temperatures.map(|(r, s, t)| error_chunk(&r[a..b], &s[a..b], mask.map(|m| &m[a..b]), t));
        let mut sample = Vec::new();
        if let Some(step) = question.spread_step {
            sample_into(&pair, shape.1, step, (a, b), &mut sample)?;
        }
        Ok::<_, crate::Error>((chunk_sums(&pair, (a, b)), errors, sample))
    })?;
    let errors = temperatures.map(|_| joined(&parts.iter().filter_map(|p| p.1).collect::<Vec<_>>()));
    let spread = match question.spread_step {
        Some(_) => {
            let mut sample: Vec<f64> = crate::budget::try_with_capacity(parts.iter().map(|p| p.2.len()).sum())?;
            parts.iter().for_each(|p| sample.extend_from_slice(&p.2));
            Some(sample_spread(&mut sample))
        }
        None => None,
    };
    let sums = parts.iter().map(|p| &p.0).fold(Sums::default(), |all, p| Sums {
        total: all.total + p.total,
        squares: all.squares + p.squares,
        count: all.count + p.count,
        largest: if p.largest > all.largest { p.largest } else { all.largest },
    });
    let border = border_sums(&pair, shape, question.border);
    let (total, count) = (sums.total, sums.count);
    let top = if count == 0 || total.is_nan() || total <= 0.0 {
        None
    } else {
        let top = ((question.top_share * count as f64).ceil() as usize).max(1);
        may_dominate(&pair, n, top, question.most * total, &sums).then(|| top_squares(&pair, n, top)).transpose()?
    };
    Ok(Profile { total, count, largest: sums.largest, border, top, errors, spread })
}

/// The flat indices, ascending, of the pixels `mask` scores whose difference lies more than
/// `threshold` from `median`, `|(sim − real) − median| > threshold` in float64 (a NaN difference
/// is never far): the candidate defects of `irfidelity.defects.find_defects`, listed without a
/// frame-sized temporary. None when there are more than `most` (widespread error, no defects).
pub fn far_pixels<A: Sample, B: Sample>(
    real: &[A],
    sim: &[B],
    mask: Option<&[bool]>,
    median: f64,
    threshold: f64,
    most: usize,
) -> crate::Result<Option<Vec<usize>>> {
    let n = real.len();
    if sim.len() != n || mask.is_some_and(|m| m.len() != n) {
        return Err(crate::Error::Shape(format!("the frames and mask must have {n} samples")));
    }
    let pair = Pair { real, sim, mask };
    let parts = map_chunks(n, NS_PER_PX, |range| pair.far(range, median, threshold, most))?;
    let mut all: Vec<usize> = Vec::new();
    for part in parts {
        match part {
            Some(part) if all.len() + part.len() <= most => {
                all.try_reserve(part.len()).map_err(|_| {
                    crate::Error::Value(format!("not enough memory to list {} far pixels", all.len() + part.len()))
                })?;
                all.extend(part);
            }
            _ => return Ok(None),
        }
    }
    Ok(Some(all))
}

/// The differences `sim − real` the defects' threshold is drawn from: every `step`-th pixel of
/// every `step`-th row (`rows × cols`, row-major) that `mask` keeps and whose difference is
/// finite, row by row — numpy's `(sim[::step, ::step] − real[::step, ::step])[kept]` in float64.
pub fn sampled_differences<A: Sample, B: Sample>(
    real: &[A],
    sim: &[B],
    mask: Option<&[bool]>,
    (rows, cols): (usize, usize),
    step: usize,
) -> crate::Result<Vec<f64>> {
    if step == 0 {
        return Err(crate::Error::Value("step: expected at least 1 pixel".into()));
    }
    let n = rows.checked_mul(cols).filter(|&n| n == real.len() && n == sim.len());
    if n.is_none() || mask.is_some_and(|m| m.len() != real.len()) {
        return Err(crate::Error::Shape(format!("the frames and the mask must all be {rows} x {cols}")));
    }
    let mut out = crate::budget::try_with_capacity(rows.div_ceil(step) * cols.div_ceil(step))?;
    sample_into(&Pair { real, sim, mask }, cols, step, (0, rows * cols), &mut out)?;
    Ok(out)
}

/// [`sampled_differences`]' pixels within `[a, b)` appended to `out`, in the same order: the
/// samples of consecutive ranges, joined, are the whole frame's.
fn sample_into<A: Sample, B: Sample>(
    pair: &Pair<'_, A, B>,
    cols: usize,
    step: usize,
    (a, b): (usize, usize),
    out: &mut Vec<f64>,
) -> crate::Result<()> {
    if a >= b || cols == 0 {
        return Ok(());
    }
    for row in (a / cols..=(b - 1) / cols).filter(|row| row % step == 0) {
        let (start, end) = ((row * cols).max(a), ((row + 1) * cols).min(b));
        let first = row * cols + (start - row * cols).div_ceil(step) * step;
        for at in (first..end).step_by(step) {
            let d = pair.sim[at].to_f64() - pair.real[at].to_f64();
            if d.is_finite() && pair.mask.is_none_or(|m| m[at]) {
                out.try_reserve(1).map_err(|_| {
                    crate::Error::Value(format!("not enough memory to sample {} differences", out.len() + 1))
                })?;
                out.push(d);
            }
        }
    }
    Ok(())
}

/// A sample's median, median absolute deviation, 99th percentile of the absolute deviations and
/// root mean square deviation.
pub type Spread = (f64, f64, f64, f64);

/// The defects' threshold statistics of a sample of differences: its size and, when it is not
/// empty, [`robust_spread`]'s median, median absolute deviation and 99th percentile with the
/// [`deviation`] (reorders `values`).
pub fn sample_spread(values: &mut [f64]) -> (usize, Option<Spread>) {
    let rms = deviation(values);
    (values.len(), robust_spread(values).map(|(median, mad, tail)| (median, mad, tail, rms)))
}

/// The root mean square deviation of `values` from their mean (numpy's `std`, to rounding);
/// 0 for an empty sample.
pub fn deviation(values: &[f64]) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    (values.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / n).sqrt()
}

/// The robust spread of a sample of differences (finite values): their median, the median of
/// their absolute deviations from it, and the 99th percentile of those deviations — numpy's
/// `median`, and `quantile` with its default linear interpolation, to the last bit, by
/// selection (`select_nth_unstable`, whose time does not depend on how the sample is
/// ordered). None for an empty sample. Reorders `values` and leaves the deviations in it.
pub fn robust_spread(values: &mut [f64]) -> Option<(f64, f64, f64)> {
    let median = median_of(values)?;
    values.iter_mut().for_each(|v| *v = (*v - median).abs());
    let deviation = median_of(values)?;
    Some((median, deviation, linear_quantile(values, 0.99)))
}

/// The `k`-th smallest value (`k < values.len()`), reordering `values` around it.
fn select(values: &mut [f64], k: usize) -> f64 {
    *values.select_nth_unstable_by(k, f64::total_cmp).1
}

/// numpy's median: the middle value, or the mean of the middle two, `(a + b) / 2`.
fn median_of(values: &mut [f64]) -> Option<f64> {
    let n = values.len();
    if n == 0 {
        return None;
    }
    let upper = select(values, n / 2);
    if n % 2 == 1 {
        return Some(upper);
    }
    // the lower middle value: the largest of those below the upper one after the selection
    let lower = values[..n / 2].iter().copied().fold(f64::NEG_INFINITY, f64::max);
    Some((lower + upper) / 2.0)
}

/// numpy's `quantile(values, q)` (method "linear"): the order statistics around `(n − 1)·q`,
/// `a + (b − a)·t`, or `b − (b − a)·(1 − t)` for `t ≥ ½`.
fn linear_quantile(values: &mut [f64], q: f64) -> f64 {
    let n = values.len();
    let at = (n - 1) as f64 * q;
    let below = at.floor();
    if at >= (n - 1) as f64 {
        return select(values, n - 1);
    }
    let k = below as usize;
    let a = select(values, k);
    let b = values[k + 1..].iter().copied().fold(f64::INFINITY, f64::min);
    let (t, step) = (at - below, b - a);
    if t >= 0.5 {
        b - step * (1.0 - t)
    } else {
        a + step * t
    }
}

/// Whether the `top` largest squares can sum to more than `limit`, by three bounds that need no
/// search (a relative margin of 1e-9 covers their own rounding): `top × largest`;
/// Cauchy–Schwarz, √(top · Σ v²); and, with τ = limit / (2·top), the sum of the squares above τ
/// plus τ for each of the `top` not above it (a second pass).
fn may_dominate<A: Sample, B: Sample>(pair: &Pair<'_, A, B>, n: usize, top: usize, limit: f64, sums: &Sums) -> bool {
    let margin = 1.0 + 1e-9;
    let top_f = top as f64;
    let squares = sums.squares * FOURTH_MARGIN;
    if (top_f * sums.largest).min((top_f * squares).sqrt()) * margin <= limit {
        return false;
    }
    let tau = limit / (2.0 * top_f);
    let Ok(parts) = map_chunks::<_, std::convert::Infallible>(n, NS_PER_PX, |range| Ok(chunk_above(pair, range, tau)));
    let above: f64 = parts.iter().map(|p| p.0).sum();
    let over: u64 = parts.iter().map(|p| p.1).sum();
    let bound = above + (top as u64).saturating_sub(over) as f64 * tau;
    bound * margin > limit
}

/// The `top` largest squares, largest first (ties: smaller index first); fewer when fewer
/// are positive. Each worker holds at most `2·top + 1` candidates (16 bytes each).
fn top_squares<A: Sample, B: Sample>(pair: &Pair<'_, A, B>, n: usize, top: usize) -> crate::Result<Vec<(f64, usize)>> {
    let found = fold_chunks(
        n,
        NS_PER_PX,
        Candidates::default,
        |mut found, range| pair.largest(&mut found, range, top).map(|()| found),
        |a, b| a.merge(b, top),
    )?;
    let mut all = found.kept;
    keep_largest(&mut all, top);
    all.sort_unstable_by(rank);
    Ok(all)
}

#[cfg(test)]
mod tests {
    use super::*;

    const ASKED: Question = Question { top_share: 0.005, most: 0.5, border: 2, tolerance: None, spread_step: None };

    #[test]
    fn a_sample_drawn_chunk_by_chunk_is_the_whole_frames() {
        let (rows, cols) = (37, 29);
        let real = noise(rows * cols, 3);
        let mut sim = noise(rows * cols, 4);
        sim[40] = f64::NAN;
        let mask: Vec<bool> = (0..rows * cols).map(|i| i % 7 != 3).collect();
        let pair = Pair { real: &real[..], sim: &sim[..], mask: Some(&mask[..]) };
        for step in [1, 2, 3, 5, 40] {
            let whole = sampled_differences(&real, &sim, Some(&mask), (rows, cols), step).unwrap();
            for cut in [1, 10, 29, 64, 500] {
                let mut joined = Vec::new();
                for a in (0..rows * cols).step_by(cut) {
                    sample_into(&pair, cols, step, (a, (a + cut).min(rows * cols)), &mut joined).unwrap();
                }
                assert_eq!(joined, whole, "step {step}, chunks of {cut}");
            }
        }
    }

    fn noise(n: usize, seed: u64) -> Vec<f64> {
        let mut state = seed;
        (0..n)
            .map(|_| {
                state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 4.0
            })
            .collect()
    }

    /// A whole-frame reference: every square, sorted.
    fn reference(real: &[f64], sim: &[f64], mask: Option<&[bool]>) -> (f64, u64, Vec<(f64, usize)>) {
        let mut squares: Vec<(f64, usize)> = (0..real.len())
            .filter(|&i| real[i].is_finite() && sim[i].is_finite() && mask.is_none_or(|m| m[i]))
            .map(|i| ((sim[i] - real[i]) * (sim[i] - real[i]), i))
            .collect();
        let total = squares.iter().map(|s| s.0).sum();
        let count = squares.len() as u64;
        squares.sort_by(rank);
        (total, count, squares)
    }

    #[test]
    fn a_dead_cluster_across_chunks_is_the_top() {
        let (rows, cols) = (300, 500); // 150 000 pixels: three chunks
        let real: Vec<f64> = noise(rows * cols, 1).iter().map(|v| 3000.0 + v).collect();
        let mut sim: Vec<f64> = real.iter().zip(noise(rows * cols, 2)).map(|(r, e)| r + e).collect();
        for y in 120..140 {
            for x in 200..240 {
                sim[y * cols + x] = 0.0; // spans the first chunk boundary (row 131)
            }
        }
        let got = profile(&real, &sim, None, (rows, cols), ASKED).unwrap();
        let (total, count, squares) = reference(&real, &sim, None);
        assert_eq!(got.count, count);
        assert!((got.total - total).abs() <= 1e-12 * total);
        let top = got.top.expect("a dominating cluster is searched");
        assert_eq!(top.len(), 750);
        assert_eq!(top, squares[..750].to_vec());
    }

    #[test]
    fn far_pixels_are_those_a_plain_pass_finds_in_order() {
        let (rows, cols) = (300, 500); // three chunks
        let n = rows * cols;
        let real: Vec<u16> = noise(n, 5).iter().map(|v| (3000.0 + 100.0 * v) as u16).collect();
        let mut sim: Vec<f64> = real.iter().zip(noise(n, 6)).map(|(&r, e)| f64::from(r) + 2.0 + e).collect();
        let far_at = [7usize, 49_999, 50_000, 50_001, 100_003, n - 1];
        for &i in &far_at {
            sim[i] += if i % 2 == 0 { 40.0 } else { -40.0 };
        }
        sim[11] = f64::NAN; // never far
        sim[12] = f64::INFINITY; // always far
        let mask: Vec<bool> = (0..n).map(|i| i != 50_000).collect();
        let plain = |mask: Option<&[bool]>| -> Vec<usize> {
            (0..n)
                .filter(|&i| ((sim[i] - f64::from(real[i])) - 2.0).abs() > 10.0 && mask.is_none_or(|m| m[i]))
                .collect()
        };
        for m in [None, Some(&mask[..])] {
            let want = plain(m);
            assert_eq!(want.len(), if m.is_none() { 7 } else { 6 });
            assert_eq!(far_pixels(&real, &sim, m, 2.0, 10.0, 100).unwrap(), Some(want.clone()));
            assert_eq!(far_pixels(&real, &sim, m, 2.0, 10.0, want.len()).unwrap(), Some(want.clone()));
            assert_eq!(far_pixels(&real, &sim, m, 2.0, 10.0, want.len() - 1).unwrap(), None, "more than most");
        }
        assert!(far_pixels(&real, &sim[1..], None, 2.0, 10.0, 100).is_err());
    }

    #[test]
    fn spread_error_skips_the_search() {
        let (rows, cols) = (200, 300);
        let real = noise(rows * cols, 3);
        let sim = noise(rows * cols, 4);
        let got = profile(&real, &sim, None, (rows, cols), ASKED).unwrap();
        assert!(got.top.is_none());
    }

    #[test]
    fn border_counts_each_pixel_once_with_mask_and_nan() {
        let (rows, cols) = (7, 4);
        let real = vec![1.0; rows * cols];
        let mut sim = vec![3.0; rows * cols];
        sim[0] = f64::NAN;
        let mut mask = vec![true; rows * cols];
        mask[cols * 6 + 3] = false; // bottom-right corner
        let got = profile(&real, &sim, Some(&mask), (rows, cols), ASKED).unwrap();
        // every pixel of a 4-wide frame is within 2 of a side: all scored pixels are border
        assert_eq!(got.count, 26);
        assert_eq!(got.border.count, 26);
        assert_eq!(got.border.total, 26.0 * 4.0);
        assert_eq!(got.border.bounds, Some([0, 6, 0, 3]));
        let wide = profile(&[0u16; 6 * 9], &[1u16; 6 * 9], None, (6, 9), ASKED).unwrap();
        assert_eq!(wide.border.count, 6 * 9 - 2 * 5); // the 2 × 5 interior is not
    }

    #[test]
    fn ties_rank_by_index_and_threads_do_not_matter() {
        let (rows, cols) = (256, 1024);
        let real = vec![10u16; rows * cols];
        let mut sim = real.clone();
        for i in (0..rows * cols).step_by(150) {
            sim[i] = 1000; // equal squares everywhere: the first ones by index are the top
        }
        let got = profile(&real, &sim, None, (rows, cols), ASKED).unwrap();
        let top = got.top.unwrap();
        let want: Vec<usize> = (0..rows * cols).step_by(150).take(top.len()).collect();
        assert_eq!(top.iter().map(|t| t.1).collect::<Vec<_>>(), want);
        let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        let alone = pool.install(|| profile(&real, &sim, None, (rows, cols), ASKED).unwrap());
        assert_eq!((alone.total, alone.top), (got.total, Some(top)));
    }

    /// The uint16 AVX2 pass (where the CPU has it) equals the portable one: the total and the
    /// largest exactly, Σ v² within its float32 margin; at the extremes and off the 16-pixel step.
    #[test]
    fn uint16_pass_equals_the_portable_one() {
        let mut seed = 11u64;
        let mut next = move || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 48) as u16
        };
        let lengths: &[usize] = if cfg!(miri) { &[1, 15, 17, 33] } else { &[1, 15, 17, 4099, 70_001] };
        for &n in lengths {
            for kind in 0..3 {
                let (real, sim): (Vec<u16>, Vec<u16>) = (0..n)
                    .map(|i| match kind {
                        0 => (next(), next()),
                        1 => (if i % 2 == 0 { 0 } else { 65535 }, if i % 2 == 0 { 65535 } else { 0 }),
                        _ => (3000 + (next() % 9), 3000),
                    })
                    .unzip();
                let pair = Pair { real: &real[..], sim: &sim[..], mask: None };
                let (fast, portable) = (pair.chunk_sums((0, n)), pair.sums((0, n)));
                assert_eq!((fast.total, fast.count, fast.largest), (portable.total, portable.count, portable.largest));
                assert!((fast.squares - portable.squares).abs() <= 3.1e-5 * portable.squares, "n={n} kind={kind}");
            }
        }
    }

    /// The uint16- and float64-against-float64 AVX2 passes equal the portable one, with a mask,
    /// NaN and ±∞ (not scored) on either side, lengths off the 4-pixel step.
    #[test]
    fn uint16_against_float64_equals_the_portable_one() {
        let lengths: &[usize] = if cfg!(miri) { &[1, 3, 5, 9] } else { &[1, 3, 5, 4099] };
        for &n in lengths {
            let real: Vec<u16> = (0..n).map(|i| (i * 7919 % 65536) as u16).collect();
            let mut sim: Vec<f64> = noise(n, 9).iter().zip(&real).map(|(e, &r)| r as f64 + 300.0 * e).collect();
            for (i, bad) in [(0, f64::NAN), (n / 2, f64::INFINITY), (n - 1, f64::NEG_INFINITY)] {
                sim[i] = bad;
            }
            let mask: Vec<bool> = (0..n).map(|i| i % 7 != 3).collect();
            let mut real_f: Vec<f64> = real.iter().map(|&r| f64::from(r) + 0.25).collect();
            real_f[n / 3] = f64::NAN;
            for mask in [None, Some(&mask[..])] {
                let pair = Pair { real: &real[..], sim: &sim[..], mask };
                let (fast, portable) = (pair.chunk_sums((0, n)), pair.sums((0, n)));
                assert_eq!((fast.count, fast.largest), (portable.count, portable.largest), "n={n}");
                assert!((fast.total - portable.total).abs() <= 1e-12 * portable.total);
                assert!((fast.squares - portable.squares).abs() <= 1e-12 * portable.squares);
                let pair = Pair { real: &real_f[..], sim: &sim[..], mask };
                let (fast, portable) = (pair.chunk_sums((0, n)), pair.sums((0, n)));
                assert_eq!((fast.count, fast.largest), (portable.count, portable.largest), "float64, n={n}");
                assert!((fast.total - portable.total).abs() <= 1e-12 * portable.total);
                assert!((fast.squares - portable.squares).abs() <= 1e-12 * portable.squares);
            }
        }
    }

    #[test]
    fn nothing_scored_or_no_error() {
        let got = profile(&[1u8, 2], &[1u8, 2], None, (1, 2), ASKED).unwrap();
        assert_eq!((got.total, got.count, got.top.is_none()), (0.0, 2, true));
        let got = profile(&[1u8, 2], &[5u8, 6], Some(&[false, false]), (1, 2), ASKED).unwrap();
        assert_eq!((got.count, got.border.bounds), (0, None));
        assert!(profile(&[1u8, 2], &[1u8], None, (1, 2), ASKED).is_err());
    }
}
