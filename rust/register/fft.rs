//! Two-dimensional FFTs of real images (`rustfft`). Along rows, two real rows go through
//! one complex transform, the first as its real part and the second as its imaginary part,
//! and are told apart by the symmetry of real spectra (`X(−k) = conj X(k)`): half as many
//! row transforms, and a separation pass cheaper than a real-to-complex transform's
//! post-processing (docs/performance.md, "Translation, third pass"). Along columns, complex
//! transforms. The half spectrum is stored column by column
//! (`data[kx * rows + ky]`, kx in `0..=cols/2`), so every column transform runs on
//! contiguous memory. Plans are cached per thread (the planner keeps them by length).
//!
//! The transforms run in float32, twice as many values per vector instruction as float64 and
//! half the memory traffic: their input is the tapered image in float32 (the frames stay
//! float64), their output a float32 spectrum or surface. Their relative
//! rounding (about 1e-7 of the largest coefficient) is far below the noise of any frame that
//! registration sees: exact shifts of noise-free patterns are still found to 1e-6 px (the
//! `phase` tests), and the worst errors of `benches/bench_register.py` agree with float64
//! transforms to 1e-4 px.

use std::cell::RefCell;
use std::sync::Arc;

use rustfft::num_complex::Complex;
use rustfft::{Fft, FftDirection, FftPlanner};

use super::pool::Buffer;

pub type C64 = Complex<f64>;
/// A coefficient of a [`Spectrum`].
pub type C32 = Complex<f32>;

/// The half spectrum of a real `rows × cols` image, column-major.
#[derive(Clone, Debug)]
pub struct Spectrum {
    pub rows: usize,
    pub cols: usize,
    pub data: Buffer<C32>,
}

impl Spectrum {
    /// Number of stored columns, `cols / 2 + 1`.
    pub fn width(&self) -> usize {
        self.cols / 2 + 1
    }
}

thread_local! {
    static PLANNER: RefCell<FftPlanner<f32>> = RefCell::new(FftPlanner::new());
}

/// The transforms of length `cols` (rows) and `rows` (columns) in one direction.
fn plans(rows: usize, cols: usize, direction: FftDirection) -> (Arc<dyn Fft<f32>>, Arc<dyn Fft<f32>>) {
    PLANNER.with(|p| {
        let mut p = p.borrow_mut();
        (p.plan_fft(cols, direction), p.plan_fft(rows, direction))
    })
}

/// Rows transformed together before their columns are scattered (keeps writes local); even,
/// so rows pair up within a block.
const ROW_BLOCK: usize = 16;

/// Forward transform of a `rows × cols` real image (row-major).
pub fn forward(values: &[f32], rows: usize, cols: usize) -> Spectrum {
    debug_assert_eq!(values.len(), rows * cols);
    forward_rows(rows, cols, |r, line| line.copy_from_slice(&values[r * cols..(r + 1) * cols]))
}

avx2_copy! {
    /// Forward transform of a `rows × cols` real image whose row `r` `fill_row(r, line)` writes
    /// into `line` (so an image computed row by row, such as a tapered frame, is never stored).
    /// The packing and scattering around the transforms run in a copy compiled for AVX2 when the
    /// CPU has it (same code, same results).
    pub fn forward_rows(rows: usize, cols: usize, fill_row: impl FnMut(usize, &mut [f32])) -> Spectrum
    => forward_rows_avx2, forward_rows_impl
}

#[inline(always)]
fn forward_rows_impl(rows: usize, cols: usize, mut fill_row: impl FnMut(usize, &mut [f32])) -> Spectrum {
    let (row_fft, col_fft) = plans(rows, cols, FftDirection::Forward);
    let width = cols / 2 + 1;
    let mut data = Buffer::scratch(width * rows); // every coefficient is written below
    let (mut first, mut second) = (vec![0.0f32; cols], vec![0.0f32; cols]);
    let mut packed = vec![C32::default(); cols];
    let mut block = vec![C32::default(); ROW_BLOCK * width];
    let mut scratch = vec![C32::default(); row_fft.get_inplace_scratch_len()];
    for r0 in (0..rows).step_by(ROW_BLOCK) {
        let n = ROW_BLOCK.min(rows - r0);
        for k in (0..n).step_by(2) {
            fill_row(r0 + k, &mut first);
            if k + 1 < n {
                fill_row(r0 + k + 1, &mut second);
            } else {
                second.fill(0.0); // an odd last row goes alone
            }
            packed.iter_mut().zip(&first).zip(&second).for_each(|((z, &re), &im)| *z = C32::new(re, im));
            row_fft.process_with_scratch(&mut packed, &mut scratch);
            let (half_first, half_second) = block[k * width..(k + 2) * width].split_at_mut(width);
            unpack_rows(&packed, half_first, half_second);
        }
        for kx in 0..width {
            let column = &mut data[kx * rows + r0..kx * rows + r0 + n];
            for (k, v) in column.iter_mut().enumerate() {
                *v = block[k * width + kx];
            }
        }
    }
    let mut col_scratch = vec![C32::default(); col_fft.get_inplace_scratch_len()];
    col_fft.process_with_scratch(&mut data, &mut col_scratch);
    Spectrum { rows, cols, data }
}

/// The half spectra `a`, `b` of two real rows from the transform `z` of `a + i·b`:
/// `A(k) = (Z(k) + conj Z(−k))/2`, `B(k) = (Z(k) − conj Z(−k))/(2i)`.
#[inline(always)]
fn unpack_rows(z: &[C32], a: &mut [C32], b: &mut [C32]) {
    let n = z.len();
    a[0] = C32::new(z[0].re, 0.0);
    b[0] = C32::new(z[0].im, 0.0);
    for (k, (a, b)) in a.iter_mut().zip(b.iter_mut()).enumerate().skip(1) {
        let (p, q) = (z[k], z[n - k].conj());
        *a = (p + q) * 0.5;
        let d = (p - q) * 0.5;
        *b = C32::new(d.im, -d.re);
    }
}

/// The transform `z` of `a + i·b` from the half spectra `a`, `b` of two real rows (the
/// inverse of [`unpack_rows`]): `Z(k) = A(k) + i·B(k)`, with `A(−k) = conj A(k)`.
#[inline(always)]
fn pack_rows(a: &[C32], b: &[C32], z: &mut [C32]) {
    let n = z.len();
    let width = a.len();
    let join = |a: C32, b: C32| C32::new(a.re - b.im, a.im + b.re);
    for (k, z) in z[..width].iter_mut().enumerate() {
        *z = join(a[k], b[k]);
    }
    for (k, z) in z.iter_mut().enumerate().skip(width) {
        *z = join(a[n - k].conj(), b[n - k].conj());
    }
}

avx2_copy! {
    /// Inverse transform, normalised (`inverse(forward(x)) == x` up to rounding), in float32:
    /// the precision the transforms carry. `spec` is consumed as scratch space. Compiled for
    /// AVX2 when the CPU has it, as [`forward_rows`].
    pub fn inverse(spec: Spectrum) -> Buffer<f32>
    => inverse_avx2, inverse_impl
}

#[inline(always)]
fn inverse_impl(mut spec: Spectrum) -> Buffer<f32> {
    let (rows, cols) = (spec.rows, spec.cols);
    let (row_ifft, col_ifft) = plans(rows, cols, FftDirection::Inverse);
    let width = cols / 2 + 1;
    let mut col_scratch = vec![C32::default(); col_ifft.get_inplace_scratch_len()];
    col_ifft.process_with_scratch(&mut spec.data, &mut col_scratch);
    let norm = 1.0 / (rows * cols) as f32;
    let mut out = Buffer::scratch(rows * cols); // every row is written below
    let mut block = vec![C32::default(); ROW_BLOCK * width];
    let mut packed = vec![C32::default(); cols];
    let mut scratch = vec![C32::default(); row_ifft.get_inplace_scratch_len()];
    for r0 in (0..rows).step_by(ROW_BLOCK) {
        let n = ROW_BLOCK.min(rows - r0);
        for kx in 0..width {
            for k in 0..n {
                block[k * width + kx] = spec.data[kx * rows + r0 + k];
            }
        }
        for k in (0..n).step_by(2) {
            let (half_first, half_second) = block[k * width..(k + 2) * width].split_at_mut(width);
            if k + 1 == n {
                half_second.fill(C32::default()); // an odd last row goes alone
            }
            for half in [&mut *half_first, &mut *half_second] {
                // The DC column and (even widths) the Nyquist column of a real image's
                // spectrum are real after the column transform; drop the rounding residue,
                // which the packing would pass to the other row.
                half[0].im = 0.0;
                if cols % 2 == 0 {
                    half[width - 1].im = 0.0;
                }
            }
            pack_rows(half_first, half_second, &mut packed);
            row_ifft.process_with_scratch(&mut packed, &mut scratch);
            let rows_out = &mut out[(r0 + k) * cols..(r0 + (k + 2).min(n)) * cols];
            let (first, second) = rows_out.split_at_mut(cols);
            for (v, z) in first.iter_mut().zip(&packed) {
                *v = z.re * norm;
            }
            for (v, z) in second.iter_mut().zip(&packed) {
                *v = z.im * norm;
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_a_direct_dft_and_round_trips() {
        // odd and even row counts and widths: rows pair up, an odd last row goes alone
        for (rows, cols) in [(6, 5), (7, 8), (3, 1)] {
            let values: Vec<f32> = (0..rows * cols).map(|i| ((i * 7919) % 13) as f32 - 6.0).collect();
            let spec = forward(&values, rows, cols);
            for kx in 0..spec.width() {
                for ky in 0..rows {
                    let mut want = C64::default();
                    for r in 0..rows {
                        for c in 0..cols {
                            let phase = -2.0 * std::f64::consts::PI * (ky * r) as f64 / rows as f64
                                - 2.0 * std::f64::consts::PI * (kx * c) as f64 / cols as f64;
                            want += C64::from_polar(values[r * cols + c] as f64, phase);
                        }
                    }
                    let got = spec.data[kx * rows + ky];
                    assert!((C64::new(got.re as f64, got.im as f64) - want).norm() < 1e-4, "{rows}x{cols}");
                }
            }
        }
        // sizes in turn, so the later ones reuse the earlier ones' storage
        for (rows, cols) in [(6, 5), (8, 8), (1, 4), (17, 16), (7, 9), (6, 5)] {
            let values: Vec<f32> = (0..rows * cols).map(|i| ((i * 31) % 11) as f32).collect();
            let back = inverse(forward(&values, rows, cols));
            assert!(back.iter().zip(&values).all(|(&a, b)| (a - b).abs() < 1e-5), "{rows}x{cols}");
        }
    }
}
