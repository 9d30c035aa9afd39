//! Compensated accumulation for float frames and the float ANOVA sums of squares.
//!
//! Every sample is promoted to f64 and used as `d = x − p`, with the per-pixel pivot `p`
//! the first frame (for float32 data `d` is exact). Per pixel, Σd and Σd² of a batch of
//! frames (a few) are added to two-sum compensated totals; rows are summed in lanes folded
//! every 128 values, and columns over blocks of 64 rows, into compensated totals. The
//! temporal parts (t, tv, th) do not depend on a per-pixel offset, so they come from the
//! row and column sums of `d`; the spatial parts (v, h, vh) from the pixel-mean map
//! `(p − c) + Σd/T`, centred on the pivot's mean `c` so that an offset common to all pixels
//! costs no precision; the within-pixel sum `W = Σ_vh (Σd² − (Σd)²/T)` gives
//! `SS_tvh = W − SS_t − SS_tv − SS_th`.

use std::sync::Arc;

use super::{Decomposition, FrameSample, Region, Shape};
use crate::budget;
use crate::stats::{compensated_sum, two_sum, Neumaier};
use crate::{Error, Result};

/// Compensated sums of a float recording.
#[derive(Clone, Debug, PartialEq)]
pub struct FloatAcc {
    /// Per-pixel pivot (V·H): the first frame; empty before it.
    pub pivot: Arc<Vec<f64>>,
    /// Σₜ d per pixel and its compensation.
    pub sum: Vec<f64>,
    pub sum_c: Vec<f64>,
    /// Σₜ d² per pixel and its compensation.
    pub sq: Vec<f64>,
    pub sq_c: Vec<f64>,
    /// Σₕ d per frame and row (T·V).
    pub row_sums: Vec<f64>,
    /// Σᵥ d per frame and column (T·H).
    pub col_sums: Vec<f64>,
    pub min: f64,
    pub max: f64,
    /// Largest |x| (underflow check).
    pub max_abs: f64,
}

/// Rows whose column sums are added plainly before being folded into compensated totals.
const COL_BLOCK: usize = 64;
/// |x| beyond this: squares of differences could overflow f64.
const TOO_LARGE: f64 = 1e150;
/// Largest |x| below this: every square underflows f64's normal range.
const TOO_SMALL: f64 = 1e-140;

impl Default for FloatAcc {
    fn default() -> Self {
        FloatAcc::new()
    }
}

impl FloatAcc {
    pub fn new() -> FloatAcc {
        FloatAcc::with_pivot(Arc::new(Vec::new()))
    }

    pub fn with_pivot(pivot: Arc<Vec<f64>>) -> FloatAcc {
        let n = pivot.len();
        FloatAcc {
            pivot,
            sum: budget::filled(n, 0.0),
            sum_c: budget::filled(n, 0.0),
            sq: budget::filled(n, 0.0),
            sq_c: budget::filled(n, 0.0),
            row_sums: Vec::new(),
            col_sums: Vec::new(),
            min: f64::INFINITY,
            max: f64::NEG_INFINITY,
            max_abs: 0.0,
        }
    }

    /// Add a batch of frames. Per row, the batch's deviations from the pivot are summed
    /// into scratch rows (at most a few values each), which are then added to the
    /// per-pixel sums with compensation: one pass over the per-pixel sums per batch.
    /// (Unlike the integer loops, these are not faster compiled for AVX2: measured slower.)
    pub(crate) fn add_frames<S: FrameSample>(
        &mut self,
        frames: &[&[S]],
        region: &Region,
        label: &dyn Fn(usize) -> String,
    ) -> Result<()> {
        let (rows, cols) = (region.rows, region.cols);
        for (k, data) in frames.iter().enumerate() {
            let (lo, hi) = extremes(data, region, &|| label(k))?;
            self.min = self.min.min(lo);
            self.max = self.max.max(hi);
            self.max_abs = self.max_abs.max(lo.abs()).max(hi.abs());
        }
        if frames.is_empty() {
            return Ok(());
        }
        if self.pivot.is_empty() {
            let samples = (0..rows).flat_map(|r| region.row(frames[0], r).iter().map(|v| v.to_f64()));
            let pivot: Vec<f64> = budget::collect(rows * cols, samples);
            *self = FloatAcc::with_pivot(Arc::new(pivot));
        }
        let base_rows = self.row_sums.len();
        budget::resize(&mut self.row_sums, base_rows + frames.len() * rows, 0.0);
        // column sums: plain over blocks of COL_BLOCK rows, folded into compensated totals
        let mut col = vec![Neumaier::default(); frames.len() * cols];
        let mut col_block = vec![0.0; frames.len() * cols];
        let (mut batch_sum, mut batch_sq) = (vec![0.0; cols], vec![0.0; cols]);
        for r in 0..rows {
            let span = r * cols..(r + 1) * cols;
            let pivot = &self.pivot[span.clone()];
            batch_sum.fill(0.0);
            batch_sq.fill(0.0);
            for (k, data) in frames.iter().enumerate() {
                let row = region.row(data, r);
                scan_row(row, pivot, &mut batch_sum, &mut batch_sq, &mut col_block[k * cols..(k + 1) * cols]);
                self.row_sums[base_rows + k * rows + r] = row_sum(row, pivot);
            }
            add_compensated(&mut self.sum[span.clone()], &mut self.sum_c[span.clone()], &batch_sum);
            add_compensated(&mut self.sq[span.clone()], &mut self.sq_c[span], &batch_sq);
            if (r + 1) % COL_BLOCK == 0 || r + 1 == rows {
                col.iter_mut().zip(col_block.iter_mut()).for_each(|(c, b)| {
                    c.add(*b);
                    *b = 0.0;
                });
            }
        }
        if self.max_abs > TOO_LARGE {
            return Err(Error::Range(format!(
                "{}: values up to {:e} are too large for float64 sums of squares; rescale the frames",
                label(0),
                self.max_abs
            )));
        }
        self.col_sums.extend(col.iter().map(|c| c.value()));
        Ok(())
    }

    /// Append `other`'s frames (`nb` of them) after `self`'s (`na`). Different pivots are
    /// reconciled by moving `other`'s sums onto `self`'s pivot.
    pub fn append(&mut self, na: usize, other: &FloatAcc, nb: usize, rows: usize, cols: usize) {
        if nb == 0 || other.pivot.is_empty() {
            return;
        }
        if na == 0 || self.pivot.is_empty() {
            *self = other.clone();
            return;
        }
        let same = Arc::ptr_eq(&self.pivot, &other.pivot) || self.pivot == other.pivot;
        let nbf = nb as f64;
        for i in 0..self.pivot.len() {
            let (mut sb, mut sbc, mut qb, mut qbc) = (other.sum[i], other.sum_c[i], other.sq[i], other.sq_c[i]);
            if !same {
                // Σ(x−pa) = Σ(x−pb) + nb·δ; Σ(x−pa)² = Σ(x−pb)² + 2δ·Σ(x−pb) + nb·δ²
                let delta = other.pivot[i] - self.pivot[i];
                let s = sb + sbc;
                let (q1, e1) = two_sum(qb, 2.0 * delta * s);
                let (q2, e2) = two_sum(q1, nbf * delta * delta);
                (qb, qbc) = (q2, qbc + e1 + e2);
                let (s1, e3) = two_sum(sb, nbf * delta);
                (sb, sbc) = (s1, sbc + e3);
            }
            let (s, e) = two_sum(self.sum[i], sb);
            self.sum[i] = s;
            self.sum_c[i] += sbc + e;
            let (q, e) = two_sum(self.sq[i], qb);
            self.sq[i] = q;
            self.sq_c[i] += qbc + e;
        }
        let first_row = self.row_sums.len();
        let first_col = self.col_sums.len();
        self.row_sums.extend_from_slice(&other.row_sums);
        self.col_sums.extend_from_slice(&other.col_sums);
        if !same {
            let delta: Vec<f64> = other.pivot.iter().zip(self.pivot.iter()).map(|(b, a)| b - a).collect();
            let row_shift: Vec<f64> = delta.chunks_exact(cols).map(|r| compensated_sum(r.iter().copied())).collect();
            let col_shift: Vec<f64> =
                (0..cols).map(|c| compensated_sum((0..rows).map(|r| delta[r * cols + c]))).collect();
            for frame in self.row_sums[first_row..].chunks_exact_mut(rows) {
                frame.iter_mut().zip(&row_shift).for_each(|(s, d)| *s += d);
            }
            for frame in self.col_sums[first_col..].chunks_exact_mut(cols) {
                frame.iter_mut().zip(&col_shift).for_each(|(s, d)| *s += d);
            }
        }
        self.min = self.min.min(other.min);
        self.max = self.max.max(other.max);
        self.max_abs = self.max_abs.max(other.max_abs);
    }

    pub fn pixel_mean(&self, frames: usize) -> Vec<f64> {
        self.centred_pixel_mean(frames, 0.0)
    }

    /// The pixel means minus `centre`: `(p − centre) + Σd/T`, exact in its first term for
    /// pixels within a factor of two of the centre.
    fn centred_pixel_mean(&self, frames: usize, centre: f64) -> Vec<f64> {
        let t = frames as f64;
        budget::collect(
            self.pivot.len(),
            (0..self.pivot.len()).map(|i| (self.pivot[i] - centre) + (self.sum[i] + self.sum_c[i]) / t),
        )
    }

    pub fn pixel_var(&self, frames: usize) -> Vec<f64> {
        let t = frames as f64;
        budget::collect(self.pivot.len(), (0..self.pivot.len()).map(|i| self.within_pixel(i, t) / t))
    }

    /// Σₜ (x − pixel mean)² of pixel `i` (never negative).
    fn within_pixel(&self, i: usize, t: f64) -> f64 {
        let s = self.sum[i] + self.sum_c[i];
        ((self.sq[i] + self.sq_c[i]) - s * s / t).max(0.0)
    }

    /// Means of the frames' rows (`by_row`) or columns, in frame units (pivot added back).
    pub fn frame_line_means(&self, sums: &[f64], rows: usize, cols: usize, count: f64, by_row: bool) -> Vec<f64> {
        let offsets: Vec<f64> = if by_row {
            self.pivot.chunks_exact(cols).map(|r| compensated_sum(r.iter().copied())).collect()
        } else {
            (0..cols).map(|c| compensated_sum((0..rows).map(|r| self.pivot[r * cols + c]))).collect()
        };
        let width = offsets.len();
        sums.iter().enumerate().map(|(i, s)| (s + offsets[i % width]) / count).collect()
    }

    pub fn finish(&self, shape: Shape) -> Result<Decomposition> {
        let Shape { frames, rows, cols } = shape;
        if self.max_abs > 0.0 && self.max_abs < TOO_SMALL {
            return Err(Error::Range(format!(
                "the largest |value| is {:e}: squares underflow float64; multiply the frames by a power of two",
                self.max_abs
            )));
        }
        let (t, v, h) = (frames as f64, rows as f64, cols as f64);
        let n = t * v * h;
        // temporal parts from the row and column sums of d (independent of the pivot)
        let frame_totals: Vec<f64> =
            self.row_sums.chunks_exact(rows).map(|f| compensated_sum(f.iter().copied())).collect();
        let grand = compensated_sum(frame_totals.iter().copied()) / n;
        let frame_means: Vec<f64> = frame_totals.iter().map(|f| f / (v * h)).collect();
        let row_over_t = column_means(&self.row_sums, rows, t * h);
        let col_over_t = column_means(&self.col_sums, cols, t * v);
        let ss_t = v * h * compensated_sum(frame_means.iter().map(|f| (f - grand) * (f - grand)));
        let ss_tv = h * compensated_sum(self.row_sums.chunks_exact(rows).zip(&frame_means).flat_map(|(frame, &f)| {
            frame.iter().zip(&row_over_t).map(move |(&r, &rv)| {
                let e = r / h - f - rv + grand;
                e * e
            })
        }));
        let ss_th = v * compensated_sum(self.col_sums.chunks_exact(cols).zip(&frame_means).flat_map(|(frame, &f)| {
            frame.iter().zip(&col_over_t).map(move |(&c, &ch)| {
                let e = c / v - f - ch + grand;
                e * e
            })
        }));
        // spatial parts from the pixel-mean map, centred: with an offset common to every
        // pixel (1e12, say) the map itself would round away their differences
        let centre = compensated_sum(self.pivot.iter().copied()) / (v * h);
        let mean_map = self.centred_pixel_mean(frames, centre);
        let row_means: Vec<f64> = mean_map.chunks_exact(cols).map(|r| compensated_sum(r.iter().copied()) / h).collect();
        let col_means: Vec<f64> =
            (0..cols).map(|c| compensated_sum((0..rows).map(|r| mean_map[r * cols + c])) / v).collect();
        let centred_mean = compensated_sum(row_means.iter().copied()) / v;
        let ss_v = t * h * compensated_sum(row_means.iter().map(|m| (m - centred_mean) * (m - centred_mean)));
        let ss_h = t * v * compensated_sum(col_means.iter().map(|m| (m - centred_mean) * (m - centred_mean)));
        let ss_vh = t * compensated_sum(mean_map.chunks_exact(cols).zip(&row_means).flat_map(|(row, &rm)| {
            row.iter().zip(&col_means).map(move |(&m, &cm)| {
                let e = m - rm - cm + centred_mean;
                e * e
            })
        }));
        let within = compensated_sum((0..self.pivot.len()).map(|i| self.within_pixel(i, t)));
        // the within-pixel sum is SS_t + SS_tv + SS_th + SS_tvh; only rounding can make the rest negative
        let ss_tvh = (within - ss_t - ss_tv - ss_th).max(0.0);
        let ss = [ss_t, ss_v, ss_h, ss_tv, ss_th, ss_vh, ss_tvh];
        let ss_total = within + ss_v + ss_h + ss_vh;
        Ok(Decomposition { shape, mean: centre + centred_mean, ss, ss_total, exact: None })
    }
}

/// For `values` laid out as `count`-wide records, the per-position sums divided by `divisor`.
fn column_means(values: &[f64], width: usize, divisor: f64) -> Vec<f64> {
    let mut acc = vec![Neumaier::default(); width];
    for rec in values.chunks_exact(width) {
        acc.iter_mut().zip(rec).for_each(|(a, &x)| a.add(x));
    }
    acc.iter().map(|a| a.value() / divisor).collect()
}

/// One frame's row: deviations from the pivot added to the batch's scratch rows and to the
/// frame's block of column sums.
#[inline(always)]
fn scan_row<S: FrameSample>(row: &[S], pivot: &[f64], batch_sum: &mut [f64], batch_sq: &mut [f64], col: &mut [f64]) {
    let n = row.len();
    let (pivot, batch_sum, batch_sq, col) = (&pivot[..n], &mut batch_sum[..n], &mut batch_sq[..n], &mut col[..n]);
    for i in 0..n {
        let d = row[i].to_f64() - pivot[i];
        batch_sum[i] += d;
        batch_sq[i] += d * d;
        col[i] += d;
    }
}

/// `sum += add` element-wise, two-sum compensated into `comp`.
#[inline(always)]
fn add_compensated(sum: &mut [f64], comp: &mut [f64], add: &[f64]) {
    let n = add.len();
    let (sum, comp) = (&mut sum[..n], &mut comp[..n]);
    for i in 0..n {
        let (s, e) = two_sum(sum[i], add[i]);
        sum[i] = s;
        comp[i] += e;
    }
}

/// Σ (x − p) over a row: eight lanes, folded every 128 values into a compensated total.
#[inline(always)]
fn row_sum<S: FrameSample>(row: &[S], pivot: &[f64]) -> f64 {
    let mut total = Neumaier::default();
    for (block, pblock) in row.chunks(128).zip(pivot.chunks(128)) {
        let mut lanes = [0.0f64; 8];
        let mut xs = block.chunks_exact(8);
        let mut ps = pblock.chunks_exact(8);
        for (x8, p8) in (&mut xs).zip(&mut ps) {
            for k in 0..8 {
                lanes[k] += x8[k].to_f64() - p8[k];
            }
        }
        for (x, p) in xs.remainder().iter().zip(ps.remainder()) {
            lanes[0] += x.to_f64() - p;
        }
        total.add(lanes.iter().sum());
    }
    total.value()
}

/// The smallest and largest value of a frame's window; NaN or ±Inf are an error with the
/// count and the first position.
fn extremes<S: FrameSample>(data: &[S], region: &Region, label: &dyn Fn() -> String) -> Result<(f64, f64)> {
    let (mut lo, mut hi) = ([f64::INFINITY; 4], [f64::NEG_INFINITY; 4]);
    let mut poisoned = false;
    for r in 0..region.rows {
        let row = region.row(data, r);
        // x·0 is 0 for finite x and NaN otherwise: a row summing to 0 holds no NaN or Inf
        let mut zero = [0.0f64; 4];
        let mut quads = row.chunks_exact(4);
        for q in &mut quads {
            for k in 0..4 {
                let x = q[k].to_f64();
                zero[k] += x * 0.0;
                lo[k] = if x < lo[k] { x } else { lo[k] };
                hi[k] = if x > hi[k] { x } else { hi[k] };
            }
        }
        for v in quads.remainder() {
            let x = v.to_f64();
            zero[0] += x * 0.0;
            lo[0] = if x < lo[0] { x } else { lo[0] };
            hi[0] = if x > hi[0] { x } else { hi[0] };
        }
        poisoned |= zero.iter().sum::<f64>() != 0.0;
    }
    if poisoned {
        let mut count = 0u64;
        let mut first = None;
        for r in 0..region.rows {
            for (c, v) in region.row(data, r).iter().enumerate() {
                if !v.to_f64().is_finite() {
                    count += 1;
                    first.get_or_insert((r, c));
                }
            }
        }
        let (r, c) = first.unwrap_or((0, 0));
        return Err(Error::Range(format!(
            "{}: {count} non-finite value(s) (NaN or Inf), the first at row {r}, column {c}; 3-D noise needs finite frames",
            label()
        )));
    }
    Ok((lo.iter().copied().fold(f64::INFINITY, f64::min), hi.iter().copied().fold(f64::NEG_INFINITY, f64::max)))
}
