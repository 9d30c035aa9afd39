//! SSIM per pixel (Wang et al. 2004, eq. 13, with the local moments of a Gaussian window),
//! the map and its means over the map without its `(win_size − 1) / 2` border.
//!
//! With local means μx, μy, variances σx², σy² and covariance σxy (population, window-weighted):
//!
//! ```text
//! SSIM = (2·μx·μy + C1)·(2·σxy + C2) / ((μx² + μy² + C1)·(σx² + σy² + C2)),   C_i = (k_i·L)²
//! cs   = (2·σxy + C2) / (σx² + σy² + C2)          (contrast-structure, for MS-SSIM)
//! ```
//!
//! C1, C2 > 0, so both are defined everywhere: flat windows of equal value give 1, of values
//! a and b give the luminance term (2ab + C1)/(a² + b² + C1). A sum of local variances that
//! rounding makes negative is taken as 0.

use std::cell::RefCell;
use std::sync::Mutex;

use super::filter::{Band, Scratch, Window, MOMENTS};
use super::frame::{check_shape, BandCheck, SsimParams};
use crate::budget::{self, Plan};
use crate::error::{Error, Result};
use crate::kernel::{map_units, Sample};
use crate::stats::Neumaier;

/// Output rows per band: a band's input (its rows and a window radius either side) as four
/// float64 moment images stays in L2 for frames up to ~1000 columns.
const BAND_ROWS: usize = 32;

/// Frames below this many pixels (about 0.1 ms of work) are computed on the calling thread
/// alone: a pool thread takes tens of microseconds to wake.
const PARALLEL_MIN_PIXELS: usize = 1 << 13;

/// A windowed SSIM map (or every `step`-th row and column of it) and its mean.
#[derive(Clone, Debug, PartialEq)]
pub struct SsimMap {
    /// Shape of `map`: `ceil(frame rows / step) × ceil(frame cols / step)`.
    pub rows: usize,
    pub cols: usize,
    /// SSIM per pixel, row-major: frame pixel `(step·i, step·j)` at `i·cols + j`.
    pub map: Vec<f64>,
    /// Mean SSIM over the whole map without its `(win_size − 1) / 2` border (scikit-image's
    /// mean), whatever the step.
    pub mean: f64,
}

/// The SSIM map of two `rows × cols` row-major frames, every `step`-th row and column of it
/// (1: the whole map; more: what a display of the map shows, the same values as
/// `map[::step, ::step]` of the whole map and the same mean, without holding the whole map).
/// `valid`: the allowed range of integer values (the declared bit depth); values outside
/// it, NaN or Inf are a range error naming the first of them.
pub fn ssim_map<T: Sample>(
    real: &[T],
    sim: &[T],
    rows: usize,
    cols: usize,
    params: &SsimParams,
    valid: Option<(i64, i64)>,
    step: usize,
) -> Result<SsimMap> {
    params.check()?;
    check_shape(real.len(), sim.len(), rows, cols, params.win_size)?;
    if step == 0 {
        return Err(Error::Value("step must be at least 1".into()));
    }
    let (out_rows, out_cols) = (rows.div_ceil(step), cols.div_ceil(step));
    budget::guard("SSIM map", Error::Value, || {
        let mut map = budget::try_filled(out_rows * out_cols, 0.0)?;
        let (mean, _) = run::<T, false>(real, sim, rows, cols, params, valid, Some((&mut map, step)))?;
        Ok(SsimMap { rows: out_rows, cols: out_cols, map, mean })
    })
}

/// Bytes of one pool thread's band buffers for frames `cols` wide (they stay with the
/// thread for its next map).
pub(crate) fn band_scratch_bytes(cols: usize, params: &SsimParams) -> u64 {
    let (cols, radius) = (cols as u64, params.radius() as u64);
    let in_rows = BAND_ROWS as u64 + 2 * radius;
    // moment images of the input rows and of the filtered output rows, a padded row, the
    // local moments, and a row of SSIM and of cs
    let moments = MOMENTS as u64 * (in_rows + BAND_ROWS as u64 + 1);
    let values = moments.saturating_mul(cols).saturating_add(3 * cols + 2 * radius);
    values.saturating_mul(std::mem::size_of::<f64>() as u64)
}

/// The peak of [`ssim_map`] besides the frames: the map kept and every pool
/// thread's band buffers.
pub fn ssim_map_plan(shape: (usize, usize), params: &SsimParams, step: usize) -> Plan {
    let step = step.max(1);
    let kept = budget::size_of_vec::<f64>(shape.0.div_ceil(step) * shape.1.div_ceil(step));
    let threads = rayon::current_num_threads() as u64;
    Plan::new("the SSIM map", shape, 0.0, kept.saturating_add(threads * band_scratch_bytes(shape.1, params)))
}

/// The means of the SSIM map and of the contrast-structure term (MS-SSIM's per-scale term)
/// over the map without its border, without keeping the map.
pub(crate) fn ssim_means<T: Sample>(
    real: &[T],
    sim: &[T],
    rows: usize,
    cols: usize,
    params: &SsimParams,
    valid: Option<(i64, i64)>,
) -> Result<(f64, f64)> {
    params.check()?;
    check_shape(real.len(), sim.len(), rows, cols, params.win_size)?;
    run::<T, true>(real, sim, rows, cols, params, valid, None)
}

/// What one band contributes: its pixel checks and its sums of SSIM and cs over the crop.
struct BandResult {
    check: BandCheck,
    ssim: Neumaier,
    cs: Neumaier,
}

thread_local! {
    static SCRATCH: RefCell<Scratch> = RefCell::new(Scratch::default());
}

/// Where a band writes its rows of the map: every `step`-th row and column of the frame
/// rows it covers.
pub(crate) struct Sink<'a> {
    pub rows: &'a mut [f64],
    pub step: usize,
}

/// Each band's part of a map holding every `step`-th row and column of a `rows × cols` map:
/// the sampled rows that fall in the band.
fn band_slots(map: &mut [f64], rows: usize, cols: usize, step: usize) -> Vec<Mutex<&mut [f64]>> {
    let out_cols = cols.div_ceil(step);
    let mut rest = map;
    let mut slots = Vec::with_capacity(rows.div_ceil(BAND_ROWS));
    for y0 in (0..rows).step_by(BAND_ROWS) {
        let y1 = (y0 + BAND_ROWS).min(rows);
        let kept = y1.div_ceil(step) - y0.div_ceil(step);
        let (mine, after) = std::mem::take(&mut rest).split_at_mut(kept * out_cols);
        slots.push(Mutex::new(mine));
        rest = after;
    }
    slots
}

/// The means of SSIM and (with `CS`) of cs over the crop, writing the map (every `step`-th
/// row and column) when given.
fn run<T: Sample, const CS: bool>(
    real: &[T],
    sim: &[T],
    rows: usize,
    cols: usize,
    params: &SsimParams,
    valid: Option<(i64, i64)>,
    map: Option<(&mut [f64], usize)>,
) -> Result<(f64, f64)> {
    let window = Window::gaussian(params.sigma, params.radius());
    let units = rows.div_ceil(BAND_ROWS);
    // each band writes its own rows of the map
    let step = map.as_ref().map_or(1, |m| m.1);
    let slots = map.map(|(m, step)| band_slots(m, rows, cols, step));
    let parallel = rows * cols >= PARALLEL_MIN_PIXELS;
    let bands = map_units(units, parallel, |b| -> std::result::Result<BandResult, std::convert::Infallible> {
        let (y0, y1) = (b * BAND_ROWS, ((b + 1) * BAND_ROWS).min(rows));
        let pivots = (pivot(&real[y0 * cols..(y0 + 1) * cols]), pivot(&sim[y0 * cols..(y0 + 1) * cols]));
        let band = Band { real, sim, rows, cols, y0, y1, pivots };
        let mut out = slots.as_ref().map(|s| s[b].lock().unwrap_or_else(|e| e.into_inner()));
        let (check, ssim, cs) = SCRATCH.with(|scratch| {
            let mut scratch = scratch.borrow_mut();
            let sink = out.as_deref_mut().map(|o| Sink { rows: o, step });
            band_sums::<T, CS>(&band, &window, params, valid, sink, &mut scratch)
        });
        Ok(BandResult { check, ssim, cs })
    });
    let Ok(bands) = bands;
    let check = bands.iter().fold(BandCheck::default(), |acc, b| acc.then(&b.check));
    check.result(cols, valid)?;
    let (mut ssim, mut cs) = (Neumaier::default(), Neumaier::default());
    for b in &bands {
        ssim.merge(&b.ssim);
        cs.merge(&b.cs);
    }
    let pad = params.radius();
    let count = ((rows - 2 * pad) * (cols - 2 * pad)) as f64;
    Ok((ssim.value() / count, cs.value() / count))
}

/// A pivot for one band and frame: the median of up to 17 evenly spaced finite samples of the
/// band's first row (a sample value, so `x − pivot` is exact for integer and float32 frames).
fn pivot<T: Sample>(row: &[T]) -> f64 {
    let step = (row.len() / 16).max(1);
    let mut samples: Vec<f64> = row.iter().step_by(step).map(|v| v.to_f64()).filter(|v| v.is_finite()).collect();
    if samples.is_empty() {
        return 0.0; // the band's check reports the non-finite values
    }
    samples.sort_by(f64::total_cmp);
    samples[samples.len() / 2]
}

/// The checks of the band's own rows, SSIM of its rows written to `out` (the band's rows of
/// the map) when given, and its sums of SSIM and (with `CS`) cs over the cropped region.
fn band_sums<T: Sample, const CS: bool>(
    band: &Band<'_, T>,
    window: &Window,
    params: &SsimParams,
    valid: Option<(i64, i64)>,
    out: Option<Sink<'_>>,
    scratch: &mut Scratch,
) -> (BandCheck, Neumaier, Neumaier) {
    #[cfg(target_arch = "x86_64")]
    if crate::kernel::use_avx2() {
        // SAFETY: `use_avx2` is true only when the CPU reports AVX2.
        return unsafe { band_sums_avx2::<T, CS>(band, window, params, valid, out, scratch) };
    }
    band_sums_impl::<T, CS>(band, window, params, valid, out, scratch)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn band_sums_avx2<T: Sample, const CS: bool>(
    band: &Band<'_, T>,
    window: &Window,
    params: &SsimParams,
    valid: Option<(i64, i64)>,
    out: Option<Sink<'_>>,
    scratch: &mut Scratch,
) -> (BandCheck, Neumaier, Neumaier) {
    band_sums_impl::<T, CS>(band, window, params, valid, out, scratch)
}

#[inline(always)]
fn band_sums_impl<T: Sample, const CS: bool>(
    band: &Band<'_, T>,
    window: &Window,
    params: &SsimParams,
    valid: Option<(i64, i64)>,
    mut out: Option<Sink<'_>>,
    scratch: &mut Scratch,
) -> (BandCheck, Neumaier, Neumaier) {
    let (rows, cols, pad) = (band.rows, band.cols, window.radius());
    let check = BandCheck::rows(band.real, band.sim, cols, band.y0, band.y1, valid);
    let constants = (params.c1(), params.c2());
    let (mut ssim, mut cs) = (Neumaier::default(), Neumaier::default());
    let whole_rows = out.as_ref().is_some_and(|o| o.step == 1);
    let mut row_buf = budget::filled(if whole_rows { 0 } else { cols }, 0.0);
    let mut cs_row = budget::filled(if CS { cols } else { 0 }, 0.0);
    let mut kept = 0; // sampled rows written so far
    band.filter_columns(window, scratch);
    for i in 0..band.y1 - band.y0 {
        band.local_moments(window, i, scratch);
        let y = band.y0 + i;
        let line = match out.as_mut() {
            Some(o) if whole_rows => &mut o.rows[i * cols..(i + 1) * cols],
            _ => &mut row_buf[..],
        };
        ssim_row_of::<CS>(&scratch.local, cols, band.pivots, constants, line, &mut cs_row);
        if (pad..rows - pad).contains(&y) {
            ssim.add(line[pad..cols - pad].iter().sum());
            if CS {
                cs.add(cs_row[pad..cols - pad].iter().sum());
            }
        }
        if let Some(o) = out.as_mut().filter(|o| !whole_rows && y % o.step == 0) {
            let out_cols = cols.div_ceil(o.step);
            let dst = &mut o.rows[kept * out_cols..(kept + 1) * out_cols];
            dst.iter_mut().zip(row_buf.iter().step_by(o.step)).for_each(|(d, &v)| *d = v);
            kept += 1;
        }
    }
    (check, ssim, cs)
}

/// SSIM (and with `CS` the contrast-structure term) of one row from its local moments
/// (`local`: the rows of the centred moments x, y, x² + y², x·y).
#[inline(always)]
fn ssim_row_of<const CS: bool>(
    local: &[f64],
    cols: usize,
    (pivot_real, pivot_sim): (f64, f64),
    (c1, c2): (f64, f64),
    out: &mut [f64],
    cs_out: &mut [f64],
) {
    let (mx, rest) = local.split_at(cols);
    let (my, rest) = rest.split_at(cols);
    let (msq, mxy) = rest.split_at(cols);
    let (out, mx, my, msq, mxy) = (&mut out[..cols], &mx[..cols], &my[..cols], &msq[..cols], &mxy[..cols]);
    for c in 0..cols {
        let (ux, uy) = (pivot_real + mx[c], pivot_sim + my[c]);
        let var_sum = (msq[c] - mx[c] * mx[c] - my[c] * my[c]).max(0.0);
        let cov = mxy[c] - mx[c] * my[c];
        let a1 = 2.0 * ux * uy + c1;
        let a2 = 2.0 * cov + c2;
        let b1 = ux * ux + uy * uy + c1;
        let b2 = var_sum + c2;
        out[c] = (a1 * a2) / (b1 * b2);
        if CS {
            cs_out[c] = a2 / b2;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A direct evaluation: weighted window sums of raw products at every pixel (no bands,
    /// no centring, no separability).
    fn direct(real: &[f64], sim: &[f64], rows: usize, cols: usize, p: &SsimParams) -> Vec<f64> {
        let w = Window::gaussian(p.sigma, p.radius());
        let r = p.radius() as isize;
        let refl = super::super::filter::reflect;
        let mut out = vec![0.0; rows * cols];
        for y in 0..rows {
            for x in 0..cols {
                let mut m = [0.0f64; 5];
                for dy in -r..=r {
                    for dx in -r..=r {
                        let wt = w.taps[dy.unsigned_abs()] * w.taps[dx.unsigned_abs()];
                        let i = refl(y as isize + dy, rows) * cols + refl(x as isize + dx, cols);
                        let (a, b) = (real[i], sim[i]);
                        for (k, v) in [a, b, a * a, b * b, a * b].iter().enumerate() {
                            m[k] += wt * v;
                        }
                    }
                }
                let (vx, vy, vxy) = (m[2] - m[0] * m[0], m[3] - m[1] * m[1], m[4] - m[0] * m[1]);
                let (c1, c2) = (p.c1(), p.c2());
                out[y * cols + x] =
                    (2.0 * m[0] * m[1] + c1) * (2.0 * vxy + c2) / ((m[0] * m[0] + m[1] * m[1] + c1) * (vx + vy + c2));
            }
        }
        out
    }

    fn frames(rows: usize, cols: usize) -> (Vec<u16>, Vec<u16>) {
        let mut state = 12345u64;
        let mut next = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 33) % 1000
        };
        let real: Vec<u16> = (0..rows * cols).map(|i| (i % cols * 7 + i / cols * 3) as u16 + next() as u16).collect();
        let sim: Vec<u16> = real.iter().map(|&v| v / 2 + next() as u16).collect();
        (real, sim)
    }

    #[test]
    fn map_equals_direct_window_sums() {
        let (rows, cols) = (70, 45); // bands of 32 rows: a partial last band
        let (real, sim) = frames(rows, cols);
        let p = SsimParams::paper(4095.0);
        let got = ssim_map(&real, &sim, rows, cols, &p, Some((0, 4095)), 1).unwrap();
        let rf: Vec<f64> = real.iter().map(|&v| v as f64).collect();
        let sf: Vec<f64> = sim.iter().map(|&v| v as f64).collect();
        let want = direct(&rf, &sf, rows, cols, &p);
        for (g, w) in got.map.iter().zip(&want) {
            assert!((g - w).abs() < 1e-12, "{g} vs {w}");
        }
        let pad = p.radius();
        let mut sum = 0.0;
        for y in pad..rows - pad {
            sum += want[y * cols + pad..y * cols + cols - pad].iter().sum::<f64>();
        }
        let mean = sum / ((rows - 2 * pad) * (cols - 2 * pad)) as f64;
        assert!((got.mean - mean).abs() < 1e-13);
        let (m, _) = ssim_means(&real, &sim, rows, cols, &p, None).unwrap();
        assert_eq!(m, got.mean);
    }

    #[test]
    fn simd_and_portable_paths_agree_bitwise() {
        let (rows, cols) = (40, 37);
        let (real, sim) = frames(rows, cols);
        let p = SsimParams::paper(65535.0);
        let window = Window::gaussian(p.sigma, p.radius());
        let band = Band { real: &real, sim: &sim, rows, cols, y0: 0, y1: 32, pivots: (500.0, 300.0) };
        let mut a = vec![0.0; 32 * cols];
        let mut b = vec![0.0; 32 * cols];
        let sink = |rows| Some(Sink { rows, step: 1 });
        let sa = band_sums_impl::<u16, true>(&band, &window, &p, None, sink(&mut a), &mut Scratch::default());
        let sb = band_sums::<u16, true>(&band, &window, &p, None, sink(&mut b), &mut Scratch::default());
        assert_eq!(a, b);
        assert_eq!((sa.1.value(), sa.2.value()), (sb.1.value(), sb.2.value()));
    }

    #[test]
    fn flat_frames_have_documented_values() {
        let (rows, cols) = (12, 11);
        let p = SsimParams::paper(255.0);
        let same = ssim_map(&vec![7u8; rows * cols], &vec![7u8; rows * cols], rows, cols, &p, None, 1).unwrap();
        assert!(same.map.iter().all(|&v| v == 1.0) && same.mean == 1.0);
        let (a, b) = (200.0f64, 50.0f64);
        let want = (2.0 * a * b + p.c1()) / (a * a + b * b + p.c1());
        let diff = ssim_map(&vec![200u8; rows * cols], &vec![50u8; rows * cols], rows, cols, &p, None, 1).unwrap();
        assert!(diff.map.iter().all(|&v| (v - want).abs() < 1e-15));
        let (_, cs) = ssim_means(&vec![200u8; rows * cols], &vec![50u8; rows * cols], rows, cols, &p, None).unwrap();
        assert!((cs - 1.0).abs() < 1e-15);
        let zeros = ssim_map(&vec![0.0f32; rows * cols], &vec![0.0f32; rows * cols], rows, cols, &p, None, 1).unwrap();
        assert_eq!(zeros.mean, 1.0);
    }

    #[test]
    fn large_offset_does_not_cancel_local_variance() {
        // float64 frames at 2^30 and 2^31 with the same texture (binary fractions: exact at
        // both offsets) and data range 100: centring keeps cs equal to that at offset 0.
        let (rows, cols) = (33, 33);
        let (real, sim) = frames(rows, cols);
        let at = |off: f64| -> (Vec<f64>, Vec<f64>) {
            (
                real.iter().map(|&v| off + v as f64 / 64.0).collect(),
                sim.iter().map(|&v| off + v as f64 / 64.0).collect(),
            )
        };
        let p = SsimParams::paper(100.0);
        let cs = |off: f64| {
            let (r, s) = at(off);
            ssim_means(&r, &s, rows, cols, &p, None).unwrap().1
        };
        let base = cs(0.0);
        assert!((cs(2f64.powi(30)) - base).abs() < 1e-13, "{} vs {base}", cs(2f64.powi(30)));
        assert!((cs(2f64.powi(31)) - base).abs() < 1e-13);
    }

    #[test]
    fn sampled_maps_are_the_displayed_part_of_the_map() {
        let (rows, cols) = (70, 45);
        let (real, sim) = frames(rows, cols);
        let p = SsimParams::paper(4095.0);
        let whole = ssim_map(&real, &sim, rows, cols, &p, None, 1).unwrap();
        let map = &whole.map;
        for step in [2, 3, 31, 100] {
            let part = ssim_map(&real, &sim, rows, cols, &p, None, step).unwrap();
            assert_eq!((part.rows, part.cols), (rows.div_ceil(step), cols.div_ceil(step)));
            let at = |r: usize| (0..cols).step_by(step).map(move |c| map[r * cols + c]);
            assert_eq!(part.map, (0..rows).step_by(step).flat_map(at).collect::<Vec<f64>>(), "{step}");
            assert_eq!(part.mean, whole.mean);
        }
        assert!(ssim_map(&real, &sim, rows, cols, &p, None, 0).is_err());
        // the plan counts the map kept and the band buffers
        let (full, shown) = (ssim_map_plan((rows, cols), &p, 1), ssim_map_plan((rows, cols), &p, 3));
        assert_eq!(full.bytes - shown.bytes, 8 * (70 * 45 - 24 * 15));
    }

    #[test]
    fn bad_inputs_are_errors_not_panics() {
        let p = SsimParams::paper(255.0);
        assert!(ssim_map(&[0u8; 100], &[0u8; 100], 10, 10, &p, None, 1).is_err()); // 10 < 11
        assert!(ssim_map(&[0u8; 120], &[0u8; 121], 11, 11, &p, None, 1).is_err());
        let mut nan = vec![0.5f32; 144];
        nan[100] = f32::NAN;
        let e = ssim_map(&nan, &vec![0.5f32; 144], 12, 12, &p, None, 1).unwrap_err();
        assert!(format!("{e}").contains("(row 8, col 4)"), "{e}");
        let e = ssim_map(&[300u16; 144], &[0u16; 144], 12, 12, &p, Some((0, 255)), 1).unwrap_err();
        assert!(format!("{e}").contains("value 300 at (row 0, col 0)"), "{e}");
    }
}
