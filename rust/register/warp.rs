//! Resampling a frame through an affine map, with the mask of the pixels that could be
//! computed.
//!
//! `out(q) = src(W·q)` for every pixel `q` of the output grid, where `W` maps output (real)
//! coordinates to source (simulated) coordinates — the inverse of a registration's matrix.
//! An output pixel is valid when every source pixel with a non-zero interpolation weight
//! lies inside the source and is itself valid (finite, not masked): no value is invented
//! at the border and no NaN spreads. At an exactly integer position only the centre tap has
//! weight, so an integer shift copies values unchanged (no smoothing).

use super::affine::Affine;
use crate::kernel::Sample;

/// Interpolation kernel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interp {
    /// 2×2 taps, linear weights (`order=1`).
    Bilinear,
    /// 4×4 taps, Keys' cubic convolution with a = −0.5 (`order=3`): interpolating,
    /// third-order accurate, and it smooths noise less than bilinear (docs/registration.md).
    Bicubic,
}

impl Interp {
    pub fn from_order(order: u32) -> Option<Interp> {
        match order {
            1 => Some(Interp::Bilinear),
            3 => Some(Interp::Bicubic),
            _ => None,
        }
    }
}

/// Source coordinates within this distance of an integer are taken as that integer, so the
/// rounding of `W·q` cannot give a far tap a weight of 1e-13 (and invalidate the border of
/// an integer shift).
const SNAP: f64 = 1e-9;

/// A source frame: samples, shape and the optional mask of valid pixels.
pub struct Source<'a, T> {
    pub data: &'a [T],
    pub rows: usize,
    pub cols: usize,
    pub valid: Option<&'a [bool]>,
}

impl<T: Sample> Source<'_, T> {
    #[inline]
    fn tap(&self, r: isize, c: isize) -> Option<f64> {
        if r < 0 || c < 0 || r as usize >= self.rows || c as usize >= self.cols {
            return None;
        }
        let i = r as usize * self.cols + c as usize;
        if self.valid.is_some_and(|m| !m[i]) {
            return None;
        }
        let v = self.data[i].to_f64();
        v.is_finite().then_some(v)
    }
}

/// Weights of the taps at offsets −1, 0, 1, 2 from `floor(x)` for the fraction `t`.
#[inline]
fn cubic_weights(t: f64) -> [f64; 4] {
    // Keys (1981), a = −0.5.
    let t2 = t * t;
    let t3 = t2 * t;
    [-0.5 * t3 + t2 - 0.5 * t, 1.5 * t3 - 2.5 * t2 + 1.0, -1.5 * t3 + 2.0 * t2 + 0.5 * t, 0.5 * t3 - 0.5 * t2]
}

/// One interpolated value at source position `(x, y)`, or `None` if a weighted tap is
/// missing.
#[inline]
fn sample<T: Sample>(src: &Source<'_, T>, x: f64, y: f64, interp: Interp) -> Option<f64> {
    let snap = |v: f64| {
        let r = v.round();
        if (v - r).abs() < SNAP {
            r
        } else {
            v
        }
    };
    let (x, y) = (snap(x), snap(y));
    let (fx, fy) = (x.floor(), y.floor());
    let (tx, ty) = (x - fx, y - fy);
    let (ix, iy) = (fx as isize, fy as isize);
    match interp {
        Interp::Bilinear => {
            let wx = [1.0 - tx, tx];
            let wy = [1.0 - ty, ty];
            let mut acc = 0.0;
            for (j, &wyj) in wy.iter().enumerate() {
                if wyj == 0.0 {
                    continue;
                }
                for (i, &wxi) in wx.iter().enumerate() {
                    if wxi == 0.0 {
                        continue;
                    }
                    acc += wyj * wxi * src.tap(iy + j as isize, ix + i as isize)?;
                }
            }
            Some(acc)
        }
        Interp::Bicubic => {
            let wx = if tx == 0.0 { [0.0, 1.0, 0.0, 0.0] } else { cubic_weights(tx) };
            let wy = if ty == 0.0 { [0.0, 1.0, 0.0, 0.0] } else { cubic_weights(ty) };
            let mut acc = 0.0;
            for (j, &wyj) in wy.iter().enumerate() {
                if wyj == 0.0 {
                    continue;
                }
                let mut line = 0.0;
                for (i, &wxi) in wx.iter().enumerate() {
                    if wxi == 0.0 {
                        continue;
                    }
                    line += wxi * src.tap(iy + j as isize - 1, ix + i as isize - 1)?;
                }
                acc += wyj * line;
            }
            Some(acc)
        }
    }
}

/// Resample `src` on an `out_rows × out_cols` grid: `out(q) = src(to_source·q)`. Invalid
/// output pixels hold `fill`.
pub fn warp<T: Sample>(
    src: &Source<'_, T>,
    to_source: &Affine,
    interp: Interp,
    out_rows: usize,
    out_cols: usize,
    fill: f64,
) -> (Vec<f64>, Vec<bool>) {
    let mut values = vec![fill; out_rows * out_cols];
    let mut valid = vec![false; out_rows * out_cols];
    let m = &to_source.0;
    for r in 0..out_rows {
        let (x0, y0) = (m[0][1] * r as f64 + m[0][2], m[1][1] * r as f64 + m[1][2]);
        let base = r * out_cols;
        for c in 0..out_cols {
            let (x, y) = (x0 + m[0][0] * c as f64, y0 + m[1][0] * c as f64);
            if let Some(v) = sample(src, x, y, interp) {
                values[base + c] = v;
                valid[base + c] = true;
            }
        }
    }
    (values, valid)
}

/// Which output pixels [`warp`] would compute, without interpolating: the overlap of the
/// warped source with the output grid.
pub fn coverage(
    src_rows: usize,
    src_cols: usize,
    src_valid: Option<&[bool]>,
    to_source: &Affine,
    interp: Interp,
    out_rows: usize,
    out_cols: usize,
) -> Vec<bool> {
    let ones = vec![0u8; src_rows * src_cols];
    let src = Source { data: &ones[..], rows: src_rows, cols: src_cols, valid: src_valid };
    warp(&src, to_source, interp, out_rows, out_cols, 0.0).1
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(rows: usize, cols: usize) -> Vec<f64> {
        (0..rows * cols).map(|i| (i / cols) as f64 * 10.0 + (i % cols) as f64).collect()
    }

    #[test]
    fn integer_shift_copies_exactly_and_masks_the_border() {
        let data: Vec<u16> = (0..30).map(|i| (i * 37 % 101) as u16).collect();
        let src = Source { data: &data[..], rows: 5, cols: 6, valid: None };
        for interp in [Interp::Bilinear, Interp::Bicubic] {
            // out(q) = src(q − (1, 2)): shift right by 2, down by 1
            let (v, ok) = warp(&src, &Affine::translation(-2.0, -1.0), interp, 5, 6, f64::NAN);
            for r in 0..5 {
                for c in 0..6 {
                    let inside = r >= 1 && c >= 2;
                    assert_eq!(ok[r * 6 + c], inside, "{interp:?} {r},{c}");
                    if inside {
                        assert_eq!(v[r * 6 + c], data[(r - 1) * 6 + c - 2] as f64);
                    } else {
                        assert!(v[r * 6 + c].is_nan());
                    }
                }
            }
        }
    }

    #[test]
    fn reproduces_linear_ramps_and_excludes_nan_taps() {
        let data = ramp(8, 9);
        let src = Source { data: &data[..], rows: 8, cols: 9, valid: None };
        let w = Affine::rotation_scale(7.0, 1.01, (4.0, 3.5)).compose(&Affine::translation(0.3, -0.2));
        for interp in [Interp::Bilinear, Interp::Bicubic] {
            let (v, ok) = warp(&src, &w, interp, 8, 9, 0.0);
            assert!(ok.iter().filter(|&&b| b).count() > 20);
            for r in 0..8 {
                for c in 0..9 {
                    if ok[r * 9 + c] {
                        let (x, y) = w.apply(c as f64, r as f64);
                        assert!((v[r * 9 + c] - (y * 10.0 + x)).abs() < 1e-9, "{interp:?}");
                    }
                }
            }
        }
        let mut nan = data.clone();
        nan[4 * 9 + 4] = f64::NAN;
        let src = Source { data: &nan[..], rows: 8, cols: 9, valid: None };
        let (_, ok) = warp(&src, &Affine::translation(0.5, 0.0), Interp::Bilinear, 8, 9, 0.0);
        // output (4, 3) and (4, 4) read source x = 3.5 and 4.5 on row 4: both touch x = 4
        assert!(!ok[4 * 9 + 3] && !ok[4 * 9 + 4] && ok[4 * 9 + 2] && ok[4 * 9 + 5]);
        let (_, ok) = warp(&src, &Affine::translation(0.5, 0.0), Interp::Bicubic, 8, 9, 0.0);
        assert!(!ok[4 * 9 + 2] && !ok[4 * 9 + 5] && ok[4 * 9 + 1] && ok[4 * 9 + 6]);
    }

    #[test]
    fn cubic_weights_partition_unity() {
        for t in [0.0, 0.1, 0.5, 0.9] {
            let w = cubic_weights(t);
            assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        }
        assert_eq!(cubic_weights(0.0), [0.0, 1.0, 0.0, 0.0]);
    }
}
