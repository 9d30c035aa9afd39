//! Exact accumulation for integer frames and the exact ANOVA sums of squares.
//!
//! With `N = T·V·H`, frame totals `F_t`, row sums `R_tv`, column sums `C_th`, pixel sums
//! `P_vh`, their totals `Rv_v = Σ_t R_tv`, `Ch_h = Σ_t C_th` and the grand total `G`,
//! every part of the classical decomposition is an integer over `N`:
//!
//! ```text
//! N·N_t   = T·F_t − G                         N·N_tv = T·V·R_tv − T·F_t − V·Rv_v + G
//! N·N_v   = V·Rv_v − G                        N·N_th = T·H·C_th − T·F_t − H·Ch_h + G
//! N·N_h   = H·Ch_h − G                        N·N_vh = V·H·P_vh − V·Rv_v − H·Ch_h + G
//! ```
//!
//! so `N²·SS_x = w_x · Σ e_x²` with the integer residuals `e_x` above and the replication
//! weights `w = (V·H, T·H, T·V, H, V, T)`, and `N²·SS_total = N·(N·Σx² − G²)`. The
//! remaining part is `N²·SS_tvh = N²·SS_total − Σ others`: all exact, in 256 bits.

use super::wide::U256;
use super::{Decomposition, FrameSample, Region, Shape};
use crate::budget;
use crate::{Error, Result};

/// Per-pixel sums of squares: u64 while a square fits 32 bits (8/16-bit samples), u128
/// for 32-bit samples.
#[derive(Clone, Debug, PartialEq)]
pub enum PixelSq {
    Narrow(Vec<u64>),
    Wide(Vec<u128>),
}

/// Exact sums of an integer recording.
#[derive(Clone, Debug, PartialEq)]
pub struct IntAcc {
    /// Σₜ x per pixel (V·H).
    pub pixel_sum: Vec<i64>,
    /// Σₜ x² per pixel (V·H).
    pub pixel_sq: PixelSq,
    /// Σₕ x per frame and row (T·V).
    pub row_sums: Vec<i64>,
    /// Σᵥ x per frame and column (T·H).
    pub col_sums: Vec<i64>,
    /// Valid range; samples equal to a limit are counted.
    pub lo: i64,
    pub hi: i64,
    pub at_lo: u64,
    pub at_hi: u64,
    pub min: i64,
    pub max: i64,
}

impl IntAcc {
    pub fn new(pixels: usize, wide: bool, (lo, hi): (i64, i64)) -> IntAcc {
        IntAcc {
            pixel_sum: budget::filled(pixels, 0),
            pixel_sq: if wide {
                PixelSq::Wide(budget::filled(pixels, 0))
            } else {
                PixelSq::Narrow(budget::filled(pixels, 0))
            },
            row_sums: Vec::new(),
            col_sums: Vec::new(),
            lo,
            hi,
            at_lo: 0,
            at_hi: 0,
            min: i64::MAX,
            max: i64::MIN,
        }
    }

    /// Add a batch of frames, with the loops compiled for AVX2 when the CPU has it (the
    /// baseline x86-64 build assumes only SSE2). Same code, same results.
    pub(crate) fn add_frames<S: FrameSample>(
        &mut self,
        frames: &[&[S]],
        region: &Region,
        label: &dyn Fn(usize) -> String,
    ) -> Result<()> {
        #[cfg(target_arch = "x86_64")]
        if crate::kernel::use_avx2() {
            // SAFETY: `use_avx2` is true only when the CPU reports AVX2.
            return unsafe { self.add_frames_avx2(frames, region, label) };
        }
        self.add_frames_impl(frames, region, label)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    pub(crate) fn add_frames_avx2<S: FrameSample>(
        &mut self,
        frames: &[&[S]],
        region: &Region,
        label: &dyn Fn(usize) -> String,
    ) -> Result<()> {
        self.add_frames_impl(frames, region, label)
    }

    /// The batch add without the dispatch (tests compare it with the AVX2 copy).
    #[cfg(test)]
    pub(crate) fn add_frames_baseline<S: FrameSample>(
        &mut self,
        frames: &[&[S]],
        region: &Region,
        label: &dyn Fn(usize) -> String,
    ) -> Result<()> {
        self.add_frames_impl(frames, region, label)
    }

    /// Add a batch of frames. Each frame's rows are scanned into its row and column sums
    /// and into per-row scratch sums; the per-pixel sums are updated once per row of the
    /// batch (their memory traffic is shared by the batch's frames).
    #[inline(always)]
    fn add_frames_impl<S: FrameSample>(
        &mut self,
        frames: &[&[S]],
        region: &Region,
        label: &dyn Fn(usize) -> String,
    ) -> Result<()> {
        let (base_rows, base_cols) = (self.row_sums.len(), self.col_sums.len());
        budget::resize(&mut self.row_sums, base_rows + frames.len() * region.rows, 0);
        budget::resize(&mut self.col_sums, base_cols + frames.len() * region.cols, 0);
        // 8/16-bit samples, at most 2^15 rows, columns and frames in the batch: every row,
        // column and batch sum fits i32, which halves the lanes' width
        let small = |n: usize| n <= 1 << 15;
        let narrow = matches!(self.pixel_sq, PixelSq::Narrow(_))
            && small(region.rows)
            && small(region.cols)
            && small(frames.len());
        let result = if narrow {
            self.add_narrow(frames, region, base_rows, base_cols, label)
        } else {
            self.add_general(frames, region, base_rows, base_cols, label)
        };
        if result.is_err() {
            self.row_sums.truncate(base_rows);
            self.col_sums.truncate(base_cols);
        }
        result
    }

    /// Range check and clipping counts of one row (counting only when a limit is reached).
    #[inline(always)]
    fn check_row<S: FrameSample>(&mut self, row: &[S], r: usize, label: &dyn Fn() -> String) -> Result<()> {
        let (lo, hi) = (self.lo, self.hi);
        let (min, max) = if S::NARROW {
            let (a, b) = row.iter().fold((i32::MAX, i32::MIN), |(a, b), v| (a.min(v.to_i32()), b.max(v.to_i32())));
            (a as i64, b as i64)
        } else {
            row.iter().fold((i64::MAX, i64::MIN), |(a, b), v| (a.min(v.to_i64()), b.max(v.to_i64())))
        };
        if min < lo || max > hi {
            let c = row.iter().position(|v| v.to_i64() < lo || v.to_i64() > hi).unwrap_or(0);
            return Err(Error::Range(format!(
                "{}: value at row {r}, column {c} outside the valid range {lo} .. {hi} (set bits to the camera's \
                 bit depth, or leave it unset)",
                label()
            )));
        }
        if min == lo {
            self.at_lo += row.iter().filter(|v| v.to_i64() == lo).count() as u64;
        }
        if max == hi {
            self.at_hi += row.iter().filter(|v| v.to_i64() == hi).count() as u64;
        }
        self.min = self.min.min(min);
        self.max = self.max.max(max);
        Ok(())
    }

    #[inline(always)]
    fn add_narrow<S: FrameSample>(
        &mut self,
        frames: &[&[S]],
        region: &Region,
        base_rows: usize,
        base_cols: usize,
        label: &dyn Fn(usize) -> String,
    ) -> Result<()> {
        let (rows, cols) = (region.rows, region.cols);
        let mut batch_sum = vec![0i32; cols];
        let mut batch_sq = vec![0u64; cols];
        let mut col_sums = vec![0i32; frames.len() * cols];
        for r in 0..rows {
            batch_sum.fill(0);
            batch_sq.fill(0);
            for (k, data) in frames.iter().enumerate() {
                let row = region.row(data, r);
                self.check_row(row, r, &|| label(k))?;
                let sum = scan_narrow(row, &mut batch_sum, &mut batch_sq, &mut col_sums[k * cols..(k + 1) * cols]);
                self.row_sums[base_rows + k * rows + r] = sum as i64;
            }
            let span = r * cols..(r + 1) * cols;
            self.pixel_sum[span.clone()].iter_mut().zip(&batch_sum).for_each(|(a, &b)| *a += b as i64);
            let PixelSq::Narrow(sq) = &mut self.pixel_sq else { unreachable!("narrow sums") };
            sq[span].iter_mut().zip(&batch_sq).for_each(|(a, b)| *a += b);
        }
        self.col_sums[base_cols..].iter_mut().zip(&col_sums).for_each(|(a, &b)| *a = b as i64);
        Ok(())
    }

    #[inline(always)]
    fn add_general<S: FrameSample>(
        &mut self,
        frames: &[&[S]],
        region: &Region,
        base_rows: usize,
        base_cols: usize,
        label: &dyn Fn(usize) -> String,
    ) -> Result<()> {
        let (rows, cols) = (region.rows, region.cols);
        let mut batch_sum = vec![0i64; cols];
        let mut batch_sq = vec![0u128; cols];
        for r in 0..rows {
            batch_sum.fill(0);
            batch_sq.fill(0);
            for (k, data) in frames.iter().enumerate() {
                let row = region.row(data, r);
                self.check_row(row, r, &|| label(k))?;
                let col_sums = &mut self.col_sums[base_cols + k * cols..base_cols + (k + 1) * cols];
                self.row_sums[base_rows + k * rows + r] = scan_general(row, &mut batch_sum, &mut batch_sq, col_sums);
            }
            let span = r * cols..(r + 1) * cols;
            self.pixel_sum[span.clone()].iter_mut().zip(&batch_sum).for_each(|(a, b)| *a += b);
            match &mut self.pixel_sq {
                PixelSq::Narrow(sq) => sq[span].iter_mut().zip(&batch_sq).for_each(|(a, &b)| *a += b as u64),
                PixelSq::Wide(sq) => sq[span].iter_mut().zip(&batch_sq).for_each(|(a, b)| *a += b),
            }
        }
        Ok(())
    }

    /// Append `other`'s frames after `self`'s.
    pub fn append(&mut self, other: &IntAcc) -> Result<()> {
        self.add_pixels(other)?;
        self.push_frames(&other.row_sums, &other.col_sums);
        Ok(())
    }

    /// Add `other`'s per-pixel sums and value statistics (not its per-frame sums).
    pub(crate) fn add_pixels(&mut self, other: &IntAcc) -> Result<()> {
        if (self.lo, self.hi) != (other.lo, other.hi) {
            return Err(Error::Value(format!(
                "cannot merge 3-D noise sums with valid ranges {} .. {} and {} .. {}",
                self.lo, self.hi, other.lo, other.hi
            )));
        }
        match (&mut self.pixel_sq, &other.pixel_sq) {
            (PixelSq::Narrow(a), PixelSq::Narrow(b)) => a.iter_mut().zip(b).for_each(|(x, y)| *x += y),
            (PixelSq::Wide(a), PixelSq::Wide(b)) => a.iter_mut().zip(b).for_each(|(x, y)| *x += y),
            _ => return Err(Error::Value("internal: narrow and wide 3-D noise sums".into())),
        }
        self.pixel_sum.iter_mut().zip(&other.pixel_sum).for_each(|(a, b)| *a += b);
        self.at_lo += other.at_lo;
        self.at_hi += other.at_hi;
        self.min = self.min.min(other.min);
        self.max = self.max.max(other.max);
        Ok(())
    }

    /// Append per-frame row and column sums (frames whose pixels were added elsewhere).
    pub(crate) fn push_frames(&mut self, row_sums: &[i64], col_sums: &[i64]) {
        self.row_sums.extend_from_slice(row_sums);
        self.col_sums.extend_from_slice(col_sums);
    }

    /// Remove and return the per-frame sums from the given lengths on.
    pub(crate) fn split_frames(&mut self, rows_from: usize, cols_from: usize) -> (Vec<i64>, Vec<i64>) {
        (self.row_sums.split_off(rows_from), self.col_sums.split_off(cols_from))
    }

    fn sum_sq_total(&self) -> u128 {
        match &self.pixel_sq {
            PixelSq::Narrow(q) => q.iter().map(|&v| v as u128).sum(),
            PixelSq::Wide(q) => q.iter().sum(),
        }
    }

    fn pixel_sq_at(&self, i: usize) -> u128 {
        match &self.pixel_sq {
            PixelSq::Narrow(q) => q[i] as u128,
            PixelSq::Wide(q) => q[i],
        }
    }

    pub fn pixel_mean(&self, frames: usize) -> Vec<f64> {
        budget::collect(self.pixel_sum.len(), self.pixel_sum.iter().map(|&s| s as f64 / frames as f64))
    }

    /// `(T·Σx² − (Σx)²) / T²` per pixel, the numerator exact in i128.
    pub fn pixel_var(&self, frames: usize) -> Vec<f64> {
        let t = frames as i128;
        let tt = (frames as f64) * (frames as f64);
        let var = |i: usize| {
            let s = self.pixel_sum[i] as i128;
            (t * self.pixel_sq_at(i) as i128 - s * s) as f64 / tt
        };
        budget::collect(self.pixel_sum.len(), (0..self.pixel_sum.len()).map(var))
    }

    /// The exact decomposition (see the module documentation for the formulas).
    pub fn finish(&self, shape: Shape) -> Result<Decomposition> {
        let Shape { frames, rows, cols } = shape;
        let (t, v, h) = (frames as i128, rows as i128, cols as i128);
        let n = shape.n();
        let frame_totals: Vec<i128> =
            self.row_sums.chunks_exact(rows).map(|r| r.iter().map(|&x| x as i128).sum()).collect();
        let mut row_totals = vec![0i128; rows];
        for frame in self.row_sums.chunks_exact(rows) {
            for (acc, &x) in row_totals.iter_mut().zip(frame) {
                *acc += x as i128;
            }
        }
        let mut col_totals = vec![0i128; cols];
        for frame in self.col_sums.chunks_exact(cols) {
            for (acc, &x) in col_totals.iter_mut().zip(frame) {
                *acc += x as i128;
            }
        }
        let g: i128 = frame_totals.iter().sum();

        let ss_t = sum_squares(frame_totals.iter().map(|&f| t * f - g))?;
        let ss_v = sum_squares(row_totals.iter().map(|&r| v * r - g))?;
        let ss_h = sum_squares(col_totals.iter().map(|&c| h * c - g))?;
        let ss_tv = sum_squares(self.row_sums.chunks_exact(rows).zip(&frame_totals).flat_map(|(frame, &f)| {
            frame.iter().zip(&row_totals).map(move |(&r, &rv)| t * v * r as i128 - t * f - v * rv + g)
        }))?;
        let ss_th = sum_squares(self.col_sums.chunks_exact(cols).zip(&frame_totals).flat_map(|(frame, &f)| {
            frame.iter().zip(&col_totals).map(move |(&c, &ch)| t * h * c as i128 - t * f - h * ch + g)
        }))?;
        // (the largest part: its per-row and per-column terms are formed once)
        let col_terms: Vec<i128> = col_totals.iter().map(|&ch| h * ch).collect();
        let vh = (v * h) as i64 as i128;
        let ss_vh = sum_squares(self.pixel_sum.chunks_exact(cols).zip(&row_totals).flat_map(|(row, &rv)| {
            let row_term = g - v * rv;
            row.iter().zip(&col_terms).map(move |(&p, &ct)| vh * p as i128 - ct + row_term)
        }))?;

        // N²·SS_x = w_x · Σ e_x²
        let weights = [(v * h) as u128, (t * h) as u128, (t * v) as u128, h as u128, v as u128, t as u128];
        let raw = [ss_t, ss_v, ss_h, ss_tv, ss_th, ss_vh];
        let mut exact = [U256::ZERO; 8];
        for k in 0..6 {
            exact[k] = raw[k].checked_mul(weights[k])?;
        }
        // N²·SS_total = N·(N·Σx² − G²)
        let n_sum_sq = U256::from_u128(self.sum_sq_total()).checked_mul(n)?;
        let total = n_sum_sq.checked_sub(U256::square(g))?.checked_mul(n)?;
        let mut rest = total;
        for part in &exact[..6] {
            rest = rest.checked_sub(*part)?;
        }
        exact[6] = rest;
        exact[7] = total;

        let nf = n as f64;
        let nn = nf * nf;
        let mut ss = [0.0; 7];
        for (k, s) in ss.iter_mut().enumerate() {
            *s = exact[k].to_f64() / nn;
        }
        Ok(Decomposition { shape, mean: ratio_i128(g, n), ss, ss_total: total.to_f64() / nn, exact: Some(exact) })
    }
}

/// Σ e² of exact integers, in 256 bits: squares below 2^128 (|e| < 2^64, the common case)
/// are added to a u128 whose carries are counted; larger ones go through [`U256::square`].
fn sum_squares(values: impl Iterator<Item = i128>) -> Result<U256> {
    let (mut low, mut carries) = (0u128, 0u128);
    let mut wide = U256::ZERO;
    for e in values {
        let m = e.unsigned_abs();
        if m >> 64 == 0 {
            let (sum, carry) = low.overflowing_add(m * m);
            low = sum;
            carries += carry as u128;
        } else {
            wide = wide.checked_add(U256::square(e))?;
        }
    }
    wide.checked_add(U256 { hi: carries, lo: low })
}

/// `a / b` rounded to f64 with a single rounding in the common case.
fn ratio_i128(a: i128, b: u128) -> f64 {
    let b = b as i128;
    let (q, r) = (a / b, a % b);
    q as f64 + r as f64 / b as f64
}

/// One row of 8/16-bit samples into the batch's scratch sums and the frame's column sums
/// (i32: the caller bounds the rows and columns); returns the row's sum. Squares fit u32
/// (|x| ≤ 65535) and are summed in u64.
#[inline(always)]
fn scan_narrow<S: FrameSample>(row: &[S], sums: &mut [i32], sq: &mut [u64], col_sums: &mut [i32]) -> i32 {
    let n = row.len();
    let (sums, sq, col_sums) = (&mut sums[..n], &mut sq[..n], &mut col_sums[..n]);
    let mut total = 0i32;
    for i in 0..n {
        let x = row[i].to_i32();
        let a = x.unsigned_abs() as u64;
        sums[i] += x;
        sq[i] += a * a;
        col_sums[i] += x;
        total += x;
    }
    total
}

/// One row of any integer samples (32-bit, or frames too large for i32 sums); returns its sum.
#[inline(always)]
fn scan_general<S: FrameSample>(row: &[S], sums: &mut [i64], sq: &mut [u128], col_sums: &mut [i64]) -> i64 {
    let n = row.len();
    let (sums, sq, col_sums) = (&mut sums[..n], &mut sq[..n], &mut col_sums[..n]);
    let mut total = 0i64;
    for i in 0..n {
        let x = row[i].to_i64();
        let a = x.unsigned_abs() as u128;
        sums[i] += x;
        sq[i] += a * a;
        col_sums[i] += x;
        total += x;
    }
    total
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sum_squares_counts_carries_and_takes_wide_values() {
        let big = 1i128 << 63;
        // four squares of 2^126 carry once out of the low 128 bits
        assert_eq!(sum_squares([big, -big, big, -big].into_iter()).unwrap(), U256 { hi: 1, lo: 0 });
        // 2^70 squared is 2^140 = 2^12 · 2^128 (the wide path), plus 3² in the low half
        assert_eq!(sum_squares([1i128 << 70, 3].into_iter()).unwrap(), U256 { hi: 1 << 12, lo: 9 });
        assert_eq!(sum_squares(std::iter::empty()).unwrap(), U256::ZERO);
    }
}
