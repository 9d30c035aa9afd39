//! Apodisation windows and the tapered, mean-free image a Fourier correlation starts from.
//!
//! Phase correlation treats a frame as periodic; the jump between opposite edges would
//! correlate with itself at zero shift. A separable window brings the edges smoothly to
//! the mean. A Tukey window (cosine tapers over a quarter of each side, flat in the middle)
//! keeps more of the frame than a Hann window; measured on real thermal frames it also gave
//! the smaller subpixel error (docs/registration.md).

use super::image::Plane;
use super::normal::Normalisation;
use super::pool::Buffer;
use crate::kernel::Sample;

/// Fraction of each axis covered by the two cosine tapers of [`tukey`].
pub const TUKEY_ALPHA: f64 = 0.5;

/// Tukey (tapered cosine) window of length `n`: cosine tapers over `alpha·(n−1)/2` samples
/// at each end, 1 in between. `alpha = 1` is the Hann window.
pub fn tukey(n: usize, alpha: f64) -> Vec<f64> {
    if n < 2 {
        return vec![1.0; n];
    }
    let last = (n - 1) as f64;
    (0..n)
        .map(|i| {
            let x = i as f64 / last;
            let edge = x.min(1.0 - x); // distance to the nearer end, in [0, 0.5]
            if edge >= alpha / 2.0 {
                1.0
            } else {
                0.5 * (1.0 - (2.0 * std::f64::consts::PI * edge / alpha).cos())
            }
        })
        .collect()
}

/// `(v − mean)·w_rows[r]·w_cols[c]` at valid pixels, 0 elsewhere (the mean of the valid
/// pixels: an excluded pixel contributes nothing), in float32: the input of a transform.
pub fn tapered(plane: &Plane, w_rows: &[f64], w_cols: &[f64]) -> Buffer<f32> {
    let centring = Normalisation { factor: 1.0, shift: plane.mean() };
    let cols = plane.cols.max(1);
    let all_valid = plane.n_valid == plane.values.len();
    let mut out = Buffer::filled(plane.rows * plane.cols, 0.0);
    for (r, line) in out.chunks_exact_mut(cols).enumerate() {
        let span = r * cols..(r + 1) * cols;
        let valid = (!all_valid).then(|| &plane.valid[span.clone()]);
        taper_row(&plane.values[span], valid, centring, w_rows[r], w_cols, line);
    }
    out
}

avx2_copy! {
    /// One row of a tapered image: `centring(v)·w_row·w_cols[c]` into `line` (`centring` makes
    /// the values mean-free working values), 0 where `valid` (None: all valid) is false. In a
    /// copy compiled for AVX2 when the CPU has it (same code, same results).
    pub fn taper_row[T: Sample](
        values: &[T],
        valid: Option<&[bool]>,
        centring: Normalisation,
        w_row: f64,
        w_cols: &[f64],
        line: &mut [f32],
    )
    => taper_row_avx2, taper_row_impl
}

#[inline(always)]
fn taper_row_impl<T: Sample>(
    values: &[T],
    valid: Option<&[bool]>,
    centring: Normalisation,
    w_row: f64,
    w_cols: &[f64],
    line: &mut [f32],
) {
    let Some(valid) = valid else {
        for ((out, v), &wc) in line.iter_mut().zip(values).zip(w_cols) {
            *out = (centring.apply(v.to_f64()) * w_row * wc) as f32;
        }
        return;
    };
    for (((out, v), &ok), &wc) in line.iter_mut().zip(values).zip(valid).zip(w_cols) {
        *out = if ok { (centring.apply(v.to_f64()) * w_row * wc) as f32 } else { 0.0 };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tukey_shape() {
        let w = tukey(9, 0.5);
        assert_eq!(w[0], 0.0);
        assert_eq!(w[8], 0.0);
        assert_eq!(w[4], 1.0);
        assert!((w[1] - 0.5).abs() < 1e-12); // edge 1/8 of a 1/4 taper: half way
        assert!(w.iter().zip(w.iter().rev()).all(|(a, b)| (a - b).abs() < 1e-15));
        let hann = tukey(5, 1.0);
        assert!((hann[1] - 0.5).abs() < 1e-12 && (hann[2] - 1.0).abs() < 1e-12);
        assert_eq!(tukey(1, 0.5), vec![1.0]);
    }
}
