//! Two-dimensional real FFTs: real-to-complex along rows (`realfft`), complex along columns
//! (`rustfft`). The half spectrum is stored column by column (`data[kx * rows + ky]`, kx in
//! `0..=cols/2`), so every column transform runs on contiguous memory. Plans are cached per
//! thread (the planners keep them by length).
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

use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};
use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};

use super::pool::Buffer;
use crate::error::{Error, Result};

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

struct Planners {
    real: RealFftPlanner<f32>,
    complex: FftPlanner<f32>,
}

thread_local! {
    static PLANNERS: RefCell<Planners> =
        RefCell::new(Planners { real: RealFftPlanner::new(), complex: FftPlanner::new() });
}

fn fft_error(e: impl std::fmt::Display) -> Error {
    Error::Value(format!("internal FFT error: {e}"))
}

/// Rows transformed together before their columns are scattered (keeps writes local).
const ROW_BLOCK: usize = 16;

/// Forward transform of a `rows × cols` real image (row-major).
pub fn forward(values: &[f32], rows: usize, cols: usize) -> Result<Spectrum> {
    debug_assert_eq!(values.len(), rows * cols);
    forward_rows(rows, cols, |r, line| line.copy_from_slice(&values[r * cols..(r + 1) * cols]))
}

/// Forward transform of a `rows × cols` real image whose row `r` `fill_row(r, line)` writes
/// into `line` (so an image computed row by row, such as a tapered frame, is never stored).
pub fn forward_rows(rows: usize, cols: usize, mut fill_row: impl FnMut(usize, &mut [f32])) -> Result<Spectrum> {
    let (r2c, col_fft): (Arc<dyn RealToComplex<f32>>, Arc<dyn Fft<f32>>) = PLANNERS.with(|p| {
        let mut p = p.borrow_mut();
        (p.real.plan_fft_forward(cols), p.complex.plan_fft_forward(rows))
    });
    let width = cols / 2 + 1;
    let mut data = Buffer::scratch(width * rows); // every coefficient is written below
    let mut line = vec![0.0f32; cols];
    let mut block = vec![C32::default(); ROW_BLOCK * width];
    let mut scratch = r2c.make_scratch_vec();
    for r0 in (0..rows).step_by(ROW_BLOCK) {
        let n = ROW_BLOCK.min(rows - r0);
        for k in 0..n {
            fill_row(r0 + k, &mut line);
            r2c.process_with_scratch(&mut line, &mut block[k * width..(k + 1) * width], &mut scratch)
                .map_err(fft_error)?;
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
    Ok(Spectrum { rows, cols, data })
}

/// Inverse transform, normalised (`inverse(forward(x)) == x` up to rounding), in float32:
/// the precision the transforms carry. `spec` is consumed as scratch space.
pub fn inverse(mut spec: Spectrum) -> Result<Buffer<f32>> {
    let (rows, cols) = (spec.rows, spec.cols);
    let (c2r, col_ifft): (Arc<dyn ComplexToReal<f32>>, Arc<dyn Fft<f32>>) = PLANNERS.with(|p| {
        let mut p = p.borrow_mut();
        (p.real.plan_fft_inverse(cols), p.complex.plan_fft_inverse(rows))
    });
    let width = cols / 2 + 1;
    let mut col_scratch = vec![C32::default(); col_ifft.get_inplace_scratch_len()];
    col_ifft.process_with_scratch(&mut spec.data, &mut col_scratch);
    let norm = 1.0 / (rows * cols) as f32;
    let mut out = Buffer::scratch(rows * cols); // every row is written below
    let mut block = vec![C32::default(); ROW_BLOCK * width];
    let mut scratch = c2r.make_scratch_vec();
    for r0 in (0..rows).step_by(ROW_BLOCK) {
        let n = ROW_BLOCK.min(rows - r0);
        for kx in 0..width {
            for k in 0..n {
                block[k * width + kx] = spec.data[kx * rows + r0 + k];
            }
        }
        for k in 0..n {
            let half = &mut block[k * width..(k + 1) * width];
            // The DC column and (even widths) the Nyquist column of a real image's spectrum
            // are real after the column transform; drop the rounding residue.
            half[0].im = 0.0;
            if cols % 2 == 0 {
                half[width - 1].im = 0.0;
            }
            let row = &mut out[(r0 + k) * cols..(r0 + k + 1) * cols];
            c2r.process_with_scratch(half, row, &mut scratch).map_err(fft_error)?;
            row.iter_mut().for_each(|v| *v *= norm);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_a_direct_dft_and_round_trips() {
        let (rows, cols) = (6, 5);
        let values: Vec<f32> = (0..rows * cols).map(|i| ((i * 7919) % 13) as f32 - 6.0).collect();
        let spec = forward(&values, rows, cols).unwrap();
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
                assert!((C64::new(got.re as f64, got.im as f64) - want).norm() < 1e-4);
            }
        }
        // sizes in turn, so the later ones reuse the earlier ones' storage
        for (rows, cols) in [(6, 5), (8, 8), (1, 4), (17, 16), (6, 5)] {
            let values: Vec<f32> = (0..rows * cols).map(|i| ((i * 31) % 11) as f32).collect();
            let back = inverse(forward(&values, rows, cols).unwrap()).unwrap();
            assert!(back.iter().zip(&values).all(|(&a, b)| (a - b).abs() < 1e-5), "{rows}x{cols}");
        }
    }
}
