//! The SSIM map's parameters and the checks of its input: shapes, and per band the pixels
//! (NaN/Inf, integer values outside the declared bit depth, magnitudes whose squares would
//! overflow float64). Each band checks its own output rows, so the first bad pixel of the
//! lowest failing band is the first of the frame, however the bands were shared out.

use crate::error::{Error, Result};
use crate::kernel::Sample;

/// Largest |value| accepted: squares and products of centred values stay below ~1e301.
const MAX_ABS: f64 = 1e150;

/// Parameters of the SSIM map (Wang et al. 2004).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SsimParams {
    /// Standard deviation of the Gaussian window, in pixels (1.5 in the paper).
    pub sigma: f64,
    /// Side of the square window, odd (11 in the paper); the Gaussian is truncated to it.
    pub win_size: usize,
    /// C1 = (k1·peak)², C2 = (k2·peak)².
    pub k1: f64,
    pub k2: f64,
    /// The data range L: 2^bits − 1 for integer frames, given for float frames.
    pub peak: f64,
}

impl SsimParams {
    /// The paper's parameters (σ = 1.5, 11 × 11, K1 = 0.01, K2 = 0.03) for data range `peak`.
    pub fn paper(peak: f64) -> SsimParams {
        SsimParams { sigma: 1.5, win_size: 11, k1: 0.01, k2: 0.03, peak }
    }

    pub(crate) fn radius(&self) -> usize {
        (self.win_size - 1) / 2
    }

    pub(crate) fn c1(&self) -> f64 {
        (self.k1 * self.peak).powi(2)
    }

    pub(crate) fn c2(&self) -> f64 {
        (self.k2 * self.peak).powi(2)
    }

    /// Every parameter in its domain, with an error naming the one that is not.
    pub fn check(&self) -> Result<()> {
        let bad = |m: String| Err(Error::Value(m));
        if !(self.sigma.is_finite() && self.sigma > 0.0) {
            return bad(format!("sigma must be a positive finite number of pixels, got {}", self.sigma));
        }
        if self.win_size % 2 == 0 {
            return bad(format!("win_size must be odd (a window centred on its pixel), got {}", self.win_size));
        }
        for (name, k) in [("k1", self.k1), ("k2", self.k2)] {
            if !(k.is_finite() && k > 0.0) {
                return bad(format!(
                    "{name} must be positive and finite (its constant keeps the map defined on flat regions; \
                     irf.stats.ssim gives the constant-free global SSIM), got {k}"
                ));
            }
        }
        if !(self.peak.is_finite() && self.peak > 0.0 && self.peak <= MAX_ABS) {
            return bad(format!(
                "peak (the data range) must be positive, finite and at most {MAX_ABS:e}, got {}",
                self.peak
            ));
        }
        if !(self.c1() > 0.0 && self.c2() > 0.0) {
            return bad(format!(
                "k1·peak and k2·peak are too small for float64 (C1 = {:e}, C2 = {:e}); rescale the frames and peak",
                self.c1(),
                self.c2()
            ));
        }
        Ok(())
    }
}

/// Shapes: both frames hold `rows × cols` values and the window fits inside them.
pub(crate) fn check_shape(len_real: usize, len_sim: usize, rows: usize, cols: usize, win_size: usize) -> Result<()> {
    let n = rows.checked_mul(cols);
    if n != Some(len_real) || n != Some(len_sim) {
        return Err(Error::Shape(format!(
            "real and sim frames must both hold {rows} × {cols} values, got {len_real} and {len_sim}"
        )));
    }
    if rows < win_size || cols < win_size {
        return Err(Error::Shape(format!(
            "frames of {rows} × {cols} pixels are smaller than the {win_size} × {win_size} SSIM window; \
             use a smaller win_size (and sigma)"
        )));
    }
    Ok(())
}

/// What one band's own rows hold that makes the map impossible. "First" is in row-major
/// pixel order, the real frame before the simulated one at the same pixel.
#[derive(Clone, Debug, Default)]
pub(crate) struct BandCheck {
    /// Non-finite values (both frames).
    pub nonfinite: u64,
    /// The first of them: (flat index, frame).
    pub first_nonfinite: Option<(usize, &'static str)>,
    /// The first integer value outside the valid range: (flat index, frame, value).
    pub out_of_range: Option<(usize, &'static str, i64)>,
    /// Largest |value| of float frames (integer values are always small enough).
    pub max_abs: f64,
}

impl BandCheck {
    /// Check rows `y0..y1` of both frames; `valid` = the allowed integer range.
    #[inline(always)]
    pub fn rows<T: Sample>(
        real: &[T],
        sim: &[T],
        cols: usize,
        y0: usize,
        y1: usize,
        valid: Option<(i64, i64)>,
    ) -> Self {
        let mut out = BandCheck::default();
        for y in y0..y1 {
            let span = y * cols..(y + 1) * cols;
            for (frame, row) in [("real", &real[span.clone()]), ("sim", &sim[span])] {
                out.row(frame, row, y * cols, valid);
            }
        }
        out
    }

    #[inline(always)]
    fn row<T: Sample>(&mut self, frame: &'static str, row: &[T], start: usize, valid: Option<(i64, i64)>) {
        if T::IS_INT {
            // integer values are far below MAX_ABS: only the declared range needs a look
            let Some((vlo, vhi)) = valid else { return };
            let Some(&first) = row.first() else { return };
            let (lo, hi) = row
                .iter()
                .fold((first, first), |(lo, hi), &v| (if v < lo { v } else { lo }, if v > hi { v } else { hi }));
            if lo.to_i64() < vlo || hi.to_i64() > vhi {
                let at = row.iter().position(|v| !(vlo..=vhi).contains(&v.to_i64())).unwrap_or(0);
                if self.out_of_range.is_none_or(|(i, _, _)| start + at < i) {
                    self.out_of_range = Some((start + at, frame, row[at].to_i64()));
                }
            }
            return;
        }
        // one pass in eight lanes: x·0 is NaN exactly when x is NaN or ±Inf
        let (mut poison, mut big) = ([0.0f64; 8], [0.0f64; 8]);
        let chunks = row.chunks_exact(8);
        let rest = chunks.remainder();
        for chunk in chunks {
            for j in 0..8 {
                let x = chunk[j].to_f64();
                poison[j] += x * 0.0;
                let a = x.abs();
                big[j] = if a > big[j] { a } else { big[j] };
            }
        }
        for v in rest {
            let x = v.to_f64();
            poison[0] += x * 0.0;
            big[0] = big[0].max(x.abs());
        }
        self.max_abs = big.iter().fold(self.max_abs, |m, &b| m.max(b));
        if poison.iter().all(|p| !p.is_nan()) {
            return;
        }
        self.nonfinite += row.iter().filter(|v| !v.to_f64().is_finite()).count() as u64;
        let at = start + row.iter().position(|v| !v.to_f64().is_finite()).unwrap_or(0);
        if self.first_nonfinite.is_none_or(|(i, _)| at < i) {
            self.first_nonfinite = Some((at, frame));
        }
    }

    /// Combine with the check of the next band (in frame order).
    pub fn then(mut self, next: &BandCheck) -> BandCheck {
        self.nonfinite += next.nonfinite;
        self.first_nonfinite = self.first_nonfinite.or(next.first_nonfinite);
        self.out_of_range = self.out_of_range.or(next.out_of_range);
        self.max_abs = self.max_abs.max(next.max_abs);
        self
    }

    /// The error these checks found, if any.
    pub fn result(&self, cols: usize, valid: Option<(i64, i64)>) -> Result<()> {
        let at = |i: usize| (i / cols, i % cols);
        if let Some((i, frame, value)) = self.out_of_range {
            let (row, col) = at(i);
            let (lo, hi) = valid.unwrap_or((0, 0));
            return Err(Error::Range(format!(
                "{frame} frame: value {value} at (row {row}, col {col}) is outside the valid range [{lo}, {hi}] \
                 of the declared bit depth"
            )));
        }
        if let Some((i, frame)) = self.first_nonfinite {
            let (row, col) = at(i);
            return Err(Error::Range(format!(
                "{} non-finite value(s) (NaN/Inf) in the frames, the first in the {frame} frame at (row {row}, \
                 col {col}); the SSIM map needs finite values",
                self.nonfinite
            )));
        }
        if self.max_abs > MAX_ABS {
            return Err(Error::Range(format!(
                "frame values up to {:e} are too large for float64 SSIM (squares overflow); rescale the frames \
                 (and peak) below {MAX_ABS:e}",
                self.max_abs
            )));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn params_are_checked() {
        assert!(SsimParams::paper(255.0).check().is_ok());
        for p in [
            SsimParams { sigma: 0.0, ..SsimParams::paper(1.0) },
            SsimParams { sigma: f64::NAN, ..SsimParams::paper(1.0) },
            SsimParams { win_size: 10, ..SsimParams::paper(1.0) },
            SsimParams { k1: 0.0, ..SsimParams::paper(1.0) },
            SsimParams { k2: -0.03, ..SsimParams::paper(1.0) },
            SsimParams::paper(0.0),
            SsimParams::paper(f64::INFINITY),
            SsimParams::paper(1e-300),
        ] {
            assert!(matches!(p.check(), Err(Error::Value(_))), "{p:?}");
        }
    }

    #[test]
    fn first_bad_pixel_is_reported() {
        let mut real = vec![1.0f32; 12];
        let mut sim = vec![1.0f32; 12];
        sim[5] = f32::NAN;
        real[7] = f32::INFINITY;
        let c = BandCheck::rows(&real, &sim, 4, 0, 3, None);
        assert_eq!(c.nonfinite, 2);
        let msg = format!("{:?}", c.result(4, None));
        assert!(msg.contains("sim frame at (row 1, col 1)"), "{msg}");
        let ints = [0u16, 3, 4, 9];
        let c = BandCheck::rows(&ints, &ints, 2, 0, 2, Some((0, 7)));
        assert_eq!(c.out_of_range, Some((3, "real", 9)));
        assert!(BandCheck::rows(&ints, &ints, 2, 0, 2, Some((0, 9))).result(2, Some((0, 9))).is_ok());
    }
}
