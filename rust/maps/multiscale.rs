//! Multi-scale SSIM (Wang, Simoncelli & Bovik 2003):
//!
//! ```text
//! MS-SSIM = [SSIM_M]^β_M · Π_{j<M} [cs_j]^β_j
//! ```
//!
//! with `cs_j` the mean contrast-structure term and `SSIM_M` the mean SSIM at the coarsest of
//! M scales, each a 2×2 average of the one before (the reference implementation's
//! `imfilter(ones(2)/4, 'symmetric')` then every other pixel: an odd last row or column is
//! averaged with itself), and the paper's β = (0.0448, 0.2856, 0.3001, 0.2363, 0.1333).
//!
//! Small frames: M is capped at the largest number of scales whose smallest scale is still at
//! least `win_size` pixels on both sides (160 × 120 Lepton frames: 120, 60, 30, 15 → 4
//! scales), and the kept weights are divided by their sum. A term ≤ 0 (anti-correlated
//! structure at that scale) counts as 0, so MS-SSIM lies in [0, 1] and is never NaN.

use super::frame::{check_shape, SsimParams};
use super::ssim::{band_scratch_bytes, ssim_means};
use crate::budget::{self, Plan};
use crate::error::{Error, Result};
use crate::kernel::Sample;

/// The paper's scale weights β_1..β_5, finest first.
pub const MS_SSIM_WEIGHTS: [f64; 5] = [0.0448, 0.2856, 0.3001, 0.2363, 0.1333];

/// MS-SSIM and its parts.
#[derive(Clone, Debug, PartialEq)]
pub struct MsSsim {
    pub value: f64,
    /// The weights used (the paper's for the kept scales, divided by their sum).
    pub weights: Vec<f64>,
    /// Mean SSIM and mean contrast-structure of each scale, finest first.
    pub ssim: Vec<f64>,
    pub cs: Vec<f64>,
}

/// The largest number of scales (at most 5) whose smallest scale is at least `win_size`
/// pixels on both sides; 0 when the frame itself is smaller than the window.
pub fn max_scales(rows: usize, cols: usize, win_size: usize) -> usize {
    let (mut r, mut c, mut n) = (rows, cols, 0);
    while n < MS_SSIM_WEIGHTS.len() && r >= win_size && c >= win_size {
        n += 1;
        r = r.div_ceil(2);
        c = c.div_ceil(2);
    }
    n
}

/// MS-SSIM of two `rows × cols` row-major frames over `scales` scales (default: the cap of
/// [`max_scales`]). `valid` as for [`super::ssim_map`].
pub fn ms_ssim<T: Sample>(
    real: &[T],
    sim: &[T],
    rows: usize,
    cols: usize,
    params: &SsimParams,
    valid: Option<(i64, i64)>,
    scales: Option<usize>,
) -> Result<MsSsim> {
    params.check()?;
    check_shape(real.len(), sim.len(), rows, cols, params.win_size)?;
    let cap = max_scales(rows, cols, params.win_size);
    let count = match scales {
        None => cap,
        Some(n) if (1..=MS_SSIM_WEIGHTS.len()).contains(&n) && n <= cap => n,
        Some(n) if (1..=MS_SSIM_WEIGHTS.len()).contains(&n) => {
            return Err(Error::Value(format!(
                "scales={n}: frames of {rows} × {cols} pixels allow at most {cap} scales (the smallest scale must \
                 be at least win_size = {} pixels on both sides)",
                params.win_size
            )))
        }
        Some(n) => return Err(Error::Value(format!("scales must be between 1 and 5, got {n}"))),
    };
    let (mut ssim, mut cs) = (Vec::with_capacity(count), Vec::with_capacity(count));
    budget::guard("MS-SSIM", Error::Value, || {
        let first = ssim_means(real, sim, rows, cols, params, valid)?;
        ssim.push(first.0);
        cs.push(first.1);
        if count == 1 {
            return Ok(());
        }
        let (mut r, mut s, mut shape) =
            (halve(real, rows, cols)?, halve(sim, rows, cols)?, (rows.div_ceil(2), cols.div_ceil(2)));
        for k in 1..count {
            let (m, c) = ssim_means(&r, &s, shape.0, shape.1, params, None)?;
            ssim.push(m);
            cs.push(c);
            if k + 1 < count {
                (r, s) = (halve(&r, shape.0, shape.1)?, halve(&s, shape.0, shape.1)?);
                shape = (shape.0.div_ceil(2), shape.1.div_ceil(2));
            }
        }
        Ok(())
    })?;
    let total: f64 = MS_SSIM_WEIGHTS[..count].iter().sum();
    let weights: Vec<f64> = MS_SSIM_WEIGHTS[..count].iter().map(|w| w / total).collect();
    let terms = cs[..count - 1].iter().chain([&ssim[count - 1]]);
    let value = terms.zip(&weights).map(|(t, w)| t.max(0.0).powf(*w)).product();
    Ok(MsSsim { value, weights, ssim, cs })
}

/// The peak of [`ms_ssim`] besides the frames: two consecutive scales of both frames as
/// float64 (the next is made while the last is held) and every pool thread's band buffers.
pub fn ms_ssim_plan(shape: (usize, usize), params: &SsimParams) -> Plan {
    let scales = max_scales(shape.0, shape.1, params.win_size).max(1);
    let mut sizes = Vec::new();
    let (mut r, mut c) = shape;
    for _ in 1..scales {
        (r, c) = (r.div_ceil(2), c.div_ceil(2));
        sizes.push(2 * budget::size_of_vec::<f64>(r * c));
    }
    let halves = sizes.windows(2).map(|w| w[0] + w[1]).chain(sizes.first().copied()).max().unwrap_or(0);
    let threads = rayon::current_num_threads() as u64;
    Plan::new("MS-SSIM", shape, 0.0, halves.saturating_add(threads * band_scratch_bytes(shape.1, params)))
}

/// 2×2 averages of a `rows × cols` frame, `ceil(rows/2) × ceil(cols/2)`; an odd last row or
/// column is averaged with itself.
fn halve<T: Sample>(src: &[T], rows: usize, cols: usize) -> Result<Vec<f64>> {
    let (out_rows, out_cols) = (rows.div_ceil(2), cols.div_ceil(2));
    let mut out = budget::try_with_capacity(out_rows * out_cols)?;
    for i in 0..out_rows {
        let (a, b) = (&src[2 * i * cols..(2 * i + 1) * cols], &src[(2 * i + 1).min(rows - 1) * cols..][..cols]);
        for j in 0..out_cols {
            let (j0, j1) = (2 * j, (2 * j + 1).min(cols - 1));
            out.push(0.25 * (a[j0].to_f64() + a[j1].to_f64() + b[j0].to_f64() + b[j1].to_f64()));
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scale_cap_rule() {
        assert_eq!(max_scales(120, 160, 11), 4); // 120, 60, 30, 15 (8 < 11)
        assert_eq!(max_scales(512, 640, 11), 5);
        assert_eq!(max_scales(11, 11, 11), 1);
        assert_eq!(max_scales(10, 100, 11), 0);
        assert_eq!(max_scales(21, 21, 11), 2); // 21 -> 11 -> 6
    }

    #[test]
    fn halving_averages_blocks_and_repeats_an_odd_edge() {
        let src = [1u8, 3, 5, 7, 9, 11]; // 2 × 3
        assert_eq!(halve(&src, 2, 3).unwrap(), vec![5.0, 8.0]);
        let src = [1u8, 3, 5]; // 1 × 3
        assert_eq!(halve(&src, 1, 3).unwrap(), vec![2.0, 5.0]);
    }

    #[test]
    fn ms_ssim_of_lepton_sized_frames() {
        let (rows, cols) = (120, 160);
        let real: Vec<u16> = (0..rows * cols).map(|i| ((i % cols) * 20 + (i / cols) * 13 % 97) as u16).collect();
        let sim: Vec<u16> = real.iter().enumerate().map(|(i, &v)| v + (i * 7 % 13) as u16).collect();
        let p = SsimParams::paper(16383.0);
        let got = ms_ssim(&real, &sim, rows, cols, &p, None, None).unwrap();
        assert_eq!(got.weights.len(), 4);
        assert!((got.weights.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        assert!(got.value > 0.0 && got.value <= 1.0);
        let same = ms_ssim(&real, &real, rows, cols, &p, None, None).unwrap();
        assert!((same.value - 1.0).abs() < 1e-15);
        let one = ms_ssim(&real, &sim, rows, cols, &p, None, Some(1)).unwrap();
        assert_eq!(one.value, got.ssim[0].max(0.0));
        assert!(ms_ssim(&real, &sim, rows, cols, &p, None, Some(5)).is_err());
        assert!(ms_ssim(&real, &sim, rows, cols, &p, None, Some(0)).is_err());
    }

    #[test]
    fn anti_correlated_frames_give_zero_not_nan() {
        let (rows, cols) = (64, 64);
        let real: Vec<f64> =
            (0..rows * cols).map(|i| ((i % cols) as f64 * 0.7).sin() + ((i / cols) as f64 * 0.3).cos()).collect();
        let sim: Vec<f64> = real.iter().map(|v| -v).collect();
        let got = ms_ssim(&real, &sim, rows, cols, &SsimParams::paper(4.0), None, None).unwrap();
        assert!(got.cs[0] < 0.0);
        assert_eq!(got.value, 0.0);
    }
}
