//! The working image of registration: a frame converted once to float64, with a mask of
//! the pixels that take part (not masked by the caller, finite). Excluded pixels hold 0
//! and are skipped by every step, never propagated.

use super::bands;
use super::normal::Normalisation;
use super::pool::Buffer;
use crate::budget;
use crate::error::{Error, Result};
use crate::kernel::{all_finite, Sample};

/// A 2-D float64 image in row-major order with its valid-pixel mask.
#[derive(Clone, Debug)]
pub struct Plane {
    pub rows: usize,
    pub cols: usize,
    pub values: Buffer<f64>,
    pub valid: Buffer<bool>,
    pub n_valid: usize,
}

impl Plane {
    /// A plane from values and mask (`values[i]` is ignored where `valid[i]` is false).
    pub fn new(rows: usize, cols: usize, values: impl Into<Buffer<f64>>, valid: impl Into<Buffer<bool>>) -> Plane {
        let (mut values, valid) = (values.into(), valid.into());
        debug_assert!(values.len() == rows * cols && valid.len() == rows * cols);
        let mut n_valid = 0;
        for (v, &ok) in values.iter_mut().zip(&valid) {
            if ok {
                n_valid += 1;
            } else {
                *v = 0.0;
            }
        }
        Plane { rows, cols, values, valid, n_valid }
    }

    /// Convert a frame of any supported sample type; `mask` false and non-finite values are
    /// excluded. `what` names the frame in errors.
    pub fn from_samples<T: Sample>(
        data: &[T],
        rows: usize,
        cols: usize,
        mask: Option<&[bool]>,
        what: &str,
    ) -> Result<Plane> {
        check_shape(data.len(), rows, cols, mask, what)?;
        let n = data.len();
        let mut values = Buffer::collect_exact(n, data.iter().map(|v| v.to_f64()));
        if mask.is_none() && (T::IS_INT || all_finite(&values)) {
            // the common case, in vectorised passes
            return Ok(Plane::all_valid(rows, cols, values));
        }
        let valid = match mask {
            Some(m) => Buffer::collect_exact(n, values.iter().zip(m).map(|(v, &keep)| keep && v.is_finite())),
            None => Buffer::collect_exact(n, values.iter().map(|v| v.is_finite())),
        };
        let n_valid = valid.iter().filter(|&&ok| ok).count();
        values.iter_mut().zip(valid.iter()).filter(|(_, &ok)| !ok).for_each(|(v, _)| *v = 0.0);
        Ok(Plane { rows, cols, values, valid, n_valid })
    }

    /// A plane of `rows × cols` samples known to be all finite and unmasked, mapped to
    /// working values by `normal` as they are converted (one pass).
    pub fn from_clean<T: Sample>(data: &[T], rows: usize, cols: usize, normal: Normalisation) -> Plane {
        debug_assert_eq!(data.len(), rows * cols);
        Plane::all_valid(rows, cols, Buffer::collect_exact(data.len(), data.iter().map(|v| normal.apply(v.to_f64()))))
    }

    fn all_valid(rows: usize, cols: usize, values: Buffer<f64>) -> Plane {
        let n = values.len();
        Plane { rows, cols, values, valid: Buffer::filled(n, true), n_valid: n }
    }

    /// Mean of the valid pixels (0 if none).
    pub fn mean(&self) -> f64 {
        if self.n_valid == 0 {
            return 0.0;
        }
        // excluded pixels hold 0: the plain sum is that of the valid pixels
        lane_sum(&self.values) / self.n_valid as f64
    }

    /// Mean and population standard deviation of the valid pixels (two passes).
    pub fn mean_std(&self) -> (f64, f64) {
        if self.n_valid == 0 {
            return (0.0, 0.0);
        }
        let n = self.n_valid as f64;
        let mean = self.valid_values().sum::<f64>() / n;
        let var = self.valid_values().map(|v| (v - mean) * (v - mean)).sum::<f64>() / n;
        (mean, var.sqrt())
    }

    /// Smallest and largest valid value.
    pub fn range(&self) -> (f64, f64) {
        if self.n_valid == self.values.len() {
            return min_max(&self.values);
        }
        let (mut lo, mut hi) = ([f64::INFINITY; 4], [f64::NEG_INFINITY; 4]);
        let chunks = self.values.chunks_exact(4).zip(self.valid.chunks_exact(4));
        let tail = self.values.len() - self.values.len() % 4;
        for (v, ok) in chunks {
            for k in 0..4 {
                lo[k] = if ok[k] && v[k] < lo[k] { v[k] } else { lo[k] };
                hi[k] = if ok[k] && v[k] > hi[k] { v[k] } else { hi[k] };
            }
        }
        for i in tail..self.values.len() {
            if self.valid[i] {
                lo[0] = lo[0].min(self.values[i]);
                hi[0] = hi[0].max(self.values[i]);
            }
        }
        (lo.into_iter().fold(f64::INFINITY, f64::min), hi.into_iter().fold(f64::NEG_INFINITY, f64::max))
    }

    /// The valid values mapped to working values by `normal` (excluded pixels stay 0).
    pub fn normalise(&mut self, normal: Normalisation) {
        for (v, &ok) in self.values.iter_mut().zip(self.valid.iter()) {
            *v = if ok { normal.apply(*v) } else { 0.0 };
        }
    }

    fn valid_values(&self) -> impl Iterator<Item = f64> + '_ {
        self.values.iter().zip(&self.valid).filter(|(_, &ok)| ok).map(|(&v, _)| v)
    }

    /// Gaussian smoothing of standard deviation `sigma` px by normalised convolution: only
    /// valid pixels contribute, each output weighted by the valid part of its kernel (at the
    /// border too). The mask is unchanged.
    pub fn smoothed(&self, sigma: f64) -> Plane {
        let radius = (3.0 * sigma).ceil() as usize;
        let kernel: Vec<f64> = (0..=2 * radius)
            .map(|i| {
                let d = i as f64 - radius as f64;
                (-0.5 * d * d / (sigma * sigma)).exp()
            })
            .collect();
        let (rows, cols) = (self.rows, self.cols);
        // invalid pixels hold 0, so the numerator is a plain convolution of the values
        let mut values = convolve_separable(&self.values, rows, cols, &kernel);
        if self.n_valid == rows * cols {
            // all valid: the weight image is separable
            let along = |n: usize| convolve_separable(&vec![1.0; n], 1, n, &kernel);
            let (wr, wc) = (along(rows), along(cols));
            for (line, &w) in values.chunks_exact_mut(cols).zip(&wr) {
                line.iter_mut().zip(&wc).for_each(|(v, &u)| *v /= w * u);
            }
        } else {
            let weights: Buffer<f64> =
                Buffer::collect_exact(self.valid.len(), self.valid.iter().map(|&ok| if ok { 1.0 } else { 0.0 }));
            let den = convolve_separable(&weights, rows, cols, &kernel);
            for ((v, &d), &ok) in values.iter_mut().zip(&den).zip(&self.valid) {
                *v = if ok && d > 0.0 { *v / d } else { 0.0 };
            }
        }
        Plane { rows, cols, values, valid: self.valid.clone(), n_valid: self.n_valid }
    }

    /// Half the resolution: the mean of each 2×2 block whose four pixels are valid.
    pub fn halved(&self) -> Plane {
        let (rows, cols) = (self.rows / 2, self.cols / 2);
        let mut values = budget::filled(rows * cols, 0.0);
        let mut valid = budget::filled(rows * cols, false);
        for r in 0..rows {
            for c in 0..cols {
                let idx = [(2 * r) * self.cols + 2 * c, (2 * r) * self.cols + 2 * c + 1];
                let idx = [idx[0], idx[1], idx[0] + self.cols, idx[1] + self.cols];
                if idx.iter().all(|&i| self.valid[i]) {
                    values[r * cols + c] = idx.iter().map(|&i| self.values[i]).sum::<f64>() / 4.0;
                    valid[r * cols + c] = true;
                }
            }
        }
        Plane::new(rows, cols, values, valid)
    }

    /// Valid values mapped to [0, 1] between their `q`-th and `(1 − q)`-th quantiles,
    /// clamped: one scale for a joint histogram whatever the gain, offset and outliers.
    pub fn unit_range(&self, q: f64) -> Plane {
        let mut sorted: Vec<f64> = budget::collect(self.n_valid, self.valid_values());
        if sorted.is_empty() {
            return self.clone();
        }
        let at = |frac: f64| ((sorted.len() - 1) as f64 * frac).round() as usize;
        let (ilo, ihi) = (at(q), at(1.0 - q));
        let lo = *sorted.select_nth_unstable_by(ilo, f64::total_cmp).1;
        let hi = *sorted.select_nth_unstable_by(ihi, f64::total_cmp).1;
        let (lo, hi) = if hi > lo { (lo, hi) } else { self.range() };
        let scale = if hi > lo { 1.0 / (hi - lo) } else { 0.0 };
        let values =
            Buffer::collect_exact(self.values.len(), self.values.iter().map(|&v| ((v - lo) * scale).clamp(0.0, 1.0)));
        Plane::new(self.rows, self.cols, values, self.valid.clone())
    }

    /// Central-difference gradients `(d/dx, d/dy)` and their mask (a pixel and its four
    /// neighbours valid).
    pub fn gradient(&self) -> (Vec<f64>, Vec<f64>, Vec<bool>) {
        let (rows, cols) = (self.rows, self.cols);
        let mut gx = budget::filled(rows * cols, 0.0);
        let mut gy = budget::filled(rows * cols, 0.0);
        let mut ok = budget::filled(rows * cols, false);
        for r in 1..rows.saturating_sub(1) {
            for c in 1..cols.saturating_sub(1) {
                let i = r * cols + c;
                if self.valid[i]
                    && self.valid[i - 1]
                    && self.valid[i + 1]
                    && self.valid[i - cols]
                    && self.valid[i + cols]
                {
                    gx[i] = 0.5 * (self.values[i + 1] - self.values[i - 1]);
                    gy[i] = 0.5 * (self.values[i + cols] - self.values[i - cols]);
                    ok[i] = true;
                }
            }
        }
        (gx, gy, ok)
    }
}

/// Frame data of `len` samples (and the mask, if any) must fit a `rows × cols` frame.
pub fn check_shape(len: usize, rows: usize, cols: usize, mask: Option<&[bool]>, what: &str) -> Result<()> {
    if len != rows * cols {
        return Err(Error::Shape(format!("{what} frame has {len} pixels, expected {rows}×{cols}")));
    }
    match mask {
        Some(m) if m.len() != len => Err(Error::Shape(format!("mask has {} elements, frames have {len}", m.len()))),
        _ => Ok(()),
    }
}

/// Sum of the values in float64, in eight lanes (vectorised). Not finite if a value is not
/// (or, for float64 values beyond about 1e303, if the sum overflows).
pub fn lane_sum<T: Sample>(values: &[T]) -> f64 {
    let chunks = values.chunks_exact(8);
    let tail: f64 = chunks.remainder().iter().map(|v| v.to_f64()).sum();
    let mut lanes = [0.0f64; 8];
    for chunk in chunks {
        lanes.iter_mut().zip(chunk).for_each(|(acc, v)| *acc += v.to_f64());
    }
    lanes.iter().sum::<f64>() + tail
}

avx2_copy! {
    /// Sum, smallest and largest of the values in float64, in eight lanes (vectorised). The sum
    /// is not finite if a value is not (or, for float64 values beyond about 1e303, if it
    /// overflows); the extremes skip NaN.
    pub fn lane_sum_range[T: Sample](values: &[T]) -> (f64, f64, f64)
    => lane_sum_range_avx2, lane_sum_range_impl
}

#[inline(always)]
fn lane_sum_range_impl<T: Sample>(values: &[T]) -> (f64, f64, f64) {
    let chunks = values.chunks_exact(8);
    let tail = chunks.remainder();
    let (mut sum, mut lo, mut hi) = ([0.0f64; 8], [f64::INFINITY; 8], [f64::NEG_INFINITY; 8]);
    for chunk in chunks {
        for k in 0..8 {
            let v = chunk[k].to_f64();
            sum[k] += v;
            lo[k] = if v < lo[k] { v } else { lo[k] };
            hi[k] = if v > hi[k] { v } else { hi[k] };
        }
    }
    for v in tail.iter().map(|v| v.to_f64()) {
        sum[0] += v;
        lo[0] = if v < lo[0] { v } else { lo[0] };
        hi[0] = if v > hi[0] { v } else { hi[0] };
    }
    (sum.iter().sum(), lo.into_iter().fold(f64::INFINITY, f64::min), hi.into_iter().fold(f64::NEG_INFINITY, f64::max))
}

/// Smallest and largest of `values` (infinities when empty), in four lanes.
fn min_max(values: &[f64]) -> (f64, f64) {
    let (mut lo, mut hi) = ([f64::INFINITY; 4], [f64::NEG_INFINITY; 4]);
    let chunks = values.chunks_exact(4);
    let tail = chunks.remainder();
    for v in chunks {
        for k in 0..4 {
            lo[k] = if v[k] < lo[k] { v[k] } else { lo[k] };
            hi[k] = if v[k] > hi[k] { v[k] } else { hi[k] };
        }
    }
    let fold =
        |x: [f64; 4], f: fn(f64, f64) -> f64| x.into_iter().chain(tail.iter().copied()).reduce(f).unwrap_or(x[0]);
    (fold(lo, f64::min), fold(hi, f64::max))
}

/// Convolve rows then columns with a symmetric kernel; outside the image counts as 0.
fn convolve_separable(values: &[f64], rows: usize, cols: usize, kernel: &[f64]) -> Buffer<f64> {
    let radius = kernel.len() / 2;
    let mut tmp = Buffer::filled(rows * cols, 0.0);
    bands::fill_rows(&mut tmp, cols, |first, band| {
        for (k, out) in band.chunks_exact_mut(cols).enumerate() {
            let line = &values[(first + k) * cols..(first + k + 1) * cols];
            convolve_line(line, kernel, out);
        }
    });
    let mut out = Buffer::filled(rows * cols, 0.0);
    bands::fill_rows(&mut out, cols, |first, band| {
        for (k, dst) in band.chunks_exact_mut(cols).enumerate() {
            let r = first + k;
            let lo = r.saturating_sub(radius);
            let hi = (r + radius).min(rows - 1);
            for j in lo..=hi {
                let w = kernel[j + radius - r];
                for (d, s) in dst.iter_mut().zip(&tmp[j * cols..(j + 1) * cols]) {
                    *d += w * s;
                }
            }
        }
    });
    out
}

/// One row convolved with a symmetric kernel (outside the row counts as 0). The interior,
/// where the whole kernel fits, is summed tap by tap over the row (vectorised).
fn convolve_line(line: &[f64], kernel: &[f64], out: &mut [f64]) {
    let (cols, radius) = (line.len(), kernel.len() / 2);
    let edge = |c: usize| {
        let lo = c.saturating_sub(radius);
        let hi = (c + radius).min(cols - 1);
        (lo..=hi).map(|k| line[k] * kernel[k + radius - c]).sum()
    };
    if cols <= 2 * radius {
        out.iter_mut().enumerate().for_each(|(c, o)| *o = edge(c));
        return;
    }
    let inner = cols - 2 * radius;
    let interior = &mut out[radius..radius + inner];
    interior.iter_mut().for_each(|o| *o = 0.0);
    for (k, &w) in kernel.iter().enumerate() {
        interior.iter_mut().zip(&line[k..k + inner]).for_each(|(o, v)| *o += v * w);
    }
    for c in (0..radius).chain(cols - radius..cols) {
        out[c] = edge(c);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nonfinite_and_masked_pixels_are_excluded() {
        let data = [1.0f32, f32::NAN, 3.0, f32::INFINITY, 5.0, 6.0];
        let mask = [true, true, true, true, true, false];
        let p = Plane::from_samples(&data, 2, 3, Some(&mask), "real").unwrap();
        assert_eq!(&p.valid[..], &[true, false, true, false, true, false]);
        assert_eq!(p.n_valid, 3);
        assert_eq!(p.values[1], 0.0);
        let (mean, std) = p.mean_std();
        assert!((mean - 3.0).abs() < 1e-15 && (std - (8.0f64 / 3.0).sqrt()).abs() < 1e-15);
        assert!(Plane::from_samples(&data, 3, 3, None, "real").is_err());
    }

    #[test]
    fn smoothing_ignores_invalid_pixels_and_keeps_constants() {
        let mut values = vec![7.0; 100];
        let mut valid = vec![true; 100];
        values[55] = 1e9; // excluded: must not leak into its neighbours
        valid[55] = false;
        let p = Plane::new(10, 10, values, valid).smoothed(1.0);
        assert!(p.values.iter().zip(&p.valid).all(|(&v, &ok)| !ok || (v - 7.0).abs() < 1e-12));
        assert!(!p.valid[55]);
    }

    #[test]
    fn row_convolution_matches_the_direct_sum() {
        let kernel = [0.25, 0.5, 1.0, 0.5, 0.25];
        for cols in [1usize, 3, 4, 5, 9] {
            let line: Vec<f64> = (0..cols).map(|i| (i * i) as f64 - 3.0).collect();
            let mut out = vec![f64::NAN; cols];
            convolve_line(&line, &kernel, &mut out);
            for (c, &o) in out.iter().enumerate() {
                let want: f64 = (0..cols).filter(|&k| k.abs_diff(c) <= 2).map(|k| line[k] * kernel[k + 2 - c]).sum();
                assert!((o - want).abs() < 1e-12, "{cols} {c}");
            }
        }
    }

    #[test]
    fn unit_range_and_halving() {
        let values: Vec<f64> = (0..16).map(|i| i as f64).collect();
        let p = Plane::new(4, 4, values, vec![true; 16]);
        let u = p.unit_range(0.0);
        assert_eq!(u.values[0], 0.0);
        assert_eq!(u.values[15], 1.0);
        let h = p.halved();
        assert_eq!((h.rows, h.cols), (2, 2));
        assert_eq!(&h.values[..], &[2.5, 4.5, 10.5, 12.5]);
        let (gx, gy, ok) = p.gradient();
        assert!(ok[5] && !ok[0]);
        assert_eq!((gx[5], gy[5]), (1.0, 4.0));
    }
}
