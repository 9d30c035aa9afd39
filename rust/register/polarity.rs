//! A shift and an inversion that explain the frames equally well are rivals.
//!
//! A pattern that becomes its own negative when shifted by a pixel — a 1-px checkerboard
//! shifted by a column, lines one pixel wide — matches at one shift with inverted grey
//! levels and at the neighbouring shift with the original ones: nothing in the frames says
//! which. Phase correlation accepts either polarity (simulators may invert), so it takes
//! whichever its whitened surface favours, and that surface shows no rival there: the
//! neighbouring shifts lie in the box around the peak that the rival search leaves out (a
//! subpixel peak spreads over it).
//!
//! So the shifts next to the peak are judged with the other polarity, by the same rule as
//! rivals further away (`phase::correlate`): a rival that matches nearly as well as the
//! peak lowers the confidence to `1 − r_rival/r_peak`. First a screen on the cross-power
//! spectrum `X`: the circular correlation of the tapered frames, `c(p) = Σ_k Re(X_k e^{ik·p})`,
//! at the nine shifts around the peak; only where `−sign·c` reaches [`CREDIBLE`] of the
//! peak's `sign·c` are the pixels read: the Pearson correlation of the values over the
//! overlap. Values, not gradients: central differences of a 1-px checkerboard vanish; and,
//! unlike a rival of the same polarity, one of the other polarity gains nothing from a
//! frame's smoothness (neighbouring shifts of a smooth frame correlate with the *same* sign),
//! so on real scenes the screen stays far below the threshold and costs one pass over the
//! spectrum.

use super::fft::{Spectrum, C32, C64};
use super::frame::Frame;
use super::image::Plane;
use super::phase::tapered_spectrum;
use super::shifts::shifted_correlation;

/// A shift whose other-polarity correlation on the screen reaches this fraction of the
/// peak's is judged on the pixels (as `phase`'s credible rivals).
const CREDIBLE: f64 = 0.2;

/// The shifts `peak + δ`, δ one of the eight neighbours, where the other polarity than
/// `sign` correlates credibly on the spectrum `spec`, whose coefficients `cross` maps to
/// those of the plain cross-power spectrum `X = F_real·conj(F_sim)`.
pub fn screen(spec: &Spectrum, cross: impl Fn(C32) -> C32, peak: (isize, isize), sign: f64) -> Vec<(isize, isize)> {
    credible(&neighbourhood(spec, cross, peak), peak, sign)
}

/// [`screen`] and [`judge`] for frames matched at the integer shift `peak` by a method that
/// does not tell the polarities apart (NMI): the polarity is the sign of the correlation at
/// the peak. The lowest confidence a rival of the other polarity leaves, if one lowers it.
pub fn check(real: &Frame, sim: &Frame, peak: (isize, isize)) -> Option<(f64, (isize, isize))> {
    let mut cross = tapered_spectrum(real);
    let other = tapered_spectrum(sim);
    cross.data.iter_mut().zip(other.data.iter()).for_each(|(x, y)| *x *= y.conj());
    let c = neighbourhood(&cross, |x| x, peak);
    let sign = if c[1][1] < 0.0 { -1.0 } else { 1.0 };
    let candidates = credible(&c, peak, sign);
    judge(real.plane(), sim.plane(), peak, sign, &candidates, real.rows * real.cols / 8)
}

/// The neighbours whose correlation `c` (3 × 3 around `peak`) with the other polarity than
/// `sign` reaches [`CREDIBLE`] of the peak's.
fn credible(c: &[[f64; 3]; 3], peak: (isize, isize), sign: f64) -> Vec<(isize, isize)> {
    let height = sign * c[1][1];
    if height.is_nan() || height <= 0.0 {
        return Vec::new();
    }
    let mut out = Vec::new();
    for (dy, row) in (-1isize..=1).zip(c) {
        for (dx, &v) in (-1isize..=1).zip(row) {
            if (dy, dx) != (0, 0) && -sign * v >= CREDIBLE * height {
                out.push((peak.0 + dy, peak.1 + dx));
            }
        }
    }
    out
}

avx2_copy! {
    /// `c(peak + (dy, dx))` for dy, dx in −1..=1 (up to a common positive factor). With
    /// `e^{iθx·(peak.1 + dx)}` (θx = 2π·kx/cols) one complex number per column, the row sums
    /// `t_dx(ky) = Σ_kx x(kx, ky)·e^{iθx·(peak.1 + dx)}` accumulate column by column, element by
    /// element (three complex rows, vectorised, in float32: a screen needs no more); then
    /// `c = Σ_ky Re(t_dx(ky)·e^{iθy·(peak.0 + dy)})` in float64 (θy = 2π·ky/rows). In a copy
    /// compiled for AVX2 when the CPU has it (same code, same results).
    fn neighbourhood(spec: &Spectrum, cross: impl Fn(C32) -> C32, peak: (isize, isize)) -> [[f64; 3]; 3]
    => neighbourhood_avx2, neighbourhood_impl
}

#[inline(always)]
fn neighbourhood_impl(spec: &Spectrum, cross: impl Fn(C32) -> C32, peak: (isize, isize)) -> [[f64; 3]; 3] {
    let (rows, cols) = (spec.rows, spec.cols);
    let tau = 2.0 * std::f64::consts::PI;
    // e^{2πi·m/n} for m in 0..n; e^{2πi·k·shift/n} is the entry k·shift modulo n (exact
    // for any shift)
    let unit = |n: usize| -> Vec<C64> { (0..n).map(|m| C64::from_polar(1.0, tau * (m as f64 / n as f64))).collect() };
    let (by_row, by_col) = (unit(rows), unit(cols));
    let phasor =
        |k: usize, shift: isize, table: &[C64]| table[(k as isize * shift).rem_euclid(table.len() as isize) as usize];
    let mut t_re: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0f32; rows]);
    let mut t_im: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0f32; rows]);
    for kx in 0..spec.width() {
        // the rest of the spectrum is the conjugate mirror: weight 2, except the columns
        // that are their own mirror (DC, and Nyquist for even widths)
        let weight = if kx == 0 || (cols % 2 == 0 && kx == cols / 2) { 1.0 } else { 2.0 };
        let turn = |dx: isize| {
            let b = weight * phasor(kx, peak.1 + dx, &by_col);
            (b.re as f32, b.im as f32)
        };
        let column = &spec.data[kx * rows..(kx + 1) * rows];
        accumulate_column(column, &cross, [turn(-1), turn(0), turn(1)], &mut t_re, &mut t_im);
    }
    let mut out = [[0.0f64; 3]; 3];
    for ky in 0..rows {
        for (dy, row) in (-1isize..=1).zip(out.iter_mut()) {
            // at integer shifts every row (the Nyquist row too) counts once, whatever the
            // sign of its frequency
            let a = phasor(ky, peak.0 + dy, &by_row);
            for (slot, (re, im)) in row.iter_mut().zip(t_re.iter().zip(&t_im)) {
                *slot += f64::from(re[ky]) * a.re - f64::from(im[ky]) * a.im;
            }
        }
    }
    out
}

/// `t_d += cross(h)·b_d` element by element over one column `h`, for the three column
/// phasors `b` (as `(re, im)`).
#[inline(always)]
fn accumulate_column(
    column: &[C32],
    cross: &impl Fn(C32) -> C32,
    b: [(f32, f32); 3],
    t_re: &mut [Vec<f32>; 3],
    t_im: &mut [Vec<f32>; 3],
) {
    let [r0, r1, r2] = t_re;
    let [i0, i1, i2] = t_im;
    let n = column.len();
    let (r0, r1, r2, i0, i1, i2) = (&mut r0[..n], &mut r1[..n], &mut r2[..n], &mut i0[..n], &mut i1[..n], &mut i2[..n]);
    for (i, &h) in column.iter().enumerate() {
        let x = cross(h);
        r0[i] += x.re * b[0].0 - x.im * b[0].1;
        i0[i] += x.re * b[0].1 + x.im * b[0].0;
        r1[i] += x.re * b[1].0 - x.im * b[1].1;
        i1[i] += x.re * b[1].1 + x.im * b[1].0;
        r2[i] += x.re * b[2].0 - x.im * b[2].1;
        i2[i] += x.re * b[2].1 + x.im * b[2].0;
    }
}

/// The lowest confidence `1 − r_rival/r_peak` over `candidates` judged on the pixels: `r` the
/// correlation of the values of `real(p)` and `sim(p − d)`, counted with polarity `sign` at
/// the peak and the other at a rival. None when no candidate lowers it below 1.
pub fn judge(
    real: &Plane,
    sim: &Plane,
    peak: (isize, isize),
    sign: f64,
    candidates: &[(isize, isize)],
    min_pairs: usize,
) -> Option<(f64, (isize, isize))> {
    if candidates.is_empty() {
        return None;
    }
    let r_peak = shifted_correlation(real, sim, peak, min_pairs).map_or(0.0, |r| sign * r);
    let mut lowest: Option<(f64, (isize, isize))> = None;
    for &rival in candidates {
        let Some(r) = shifted_correlation(real, sim, rival, min_pairs) else { continue };
        let c = if r_peak > 0.0 { (1.0 + sign * r / r_peak).clamp(0.0, 1.0) } else { 0.0 };
        if c < 1.0 && lowest.is_none_or(|(best, _)| c < best) {
            lowest = Some((c, rival));
        }
    }
    lowest
}

#[cfg(test)]
mod tests {
    use super::super::fft;
    use super::super::logpolar::tests::scene;
    use super::*;

    fn plane(rows: usize, cols: usize, f: impl Fn(usize, usize) -> f64) -> Plane {
        let values: Vec<f64> = (0..rows * cols).map(|i| f(i / cols, i % cols)).collect();
        Plane::new(rows, cols, values, vec![true; rows * cols])
    }

    /// The plain cross-power spectrum of two planes (mean-free, untapered).
    fn cross_power(real: &Plane, sim: &Plane) -> Spectrum {
        let centred = |p: &Plane| {
            let m = p.mean();
            p.values.iter().map(|v| (v - m) as f32).collect::<Vec<f32>>()
        };
        let (mut a, b) =
            (fft::forward(&centred(real), real.rows, real.cols), fft::forward(&centred(sim), sim.rows, sim.cols));
        a.data.iter_mut().zip(b.data.iter()).for_each(|(x, y)| *x *= y.conj());
        a
    }

    #[test]
    fn the_screen_is_the_circular_correlation() {
        let (rows, cols) = (12, 10);
        let real = plane(rows, cols, |r, c| ((r * 7 + c * 3) % 11) as f64 + 0.3 * (r * c) as f64);
        let sim = plane(rows, cols, |r, c| ((r * 5 + c * 9) % 7) as f64 - 0.1 * (r + c) as f64);
        let spec = cross_power(&real, &sim);
        for peak in [(0isize, 0isize), (2, -3), (-5, 4)] {
            let c = neighbourhood(&spec, |x| x, peak);
            for dy in -1isize..=1 {
                for dx in -1isize..=1 {
                    // Σ_q a(q)·b(q − d), circular, times rows·cols (the unnormalised inverse)
                    let d = (peak.0 + dy, peak.1 + dx);
                    let (ma, mb) = (real.mean(), sim.mean());
                    let mut want = 0.0;
                    for r in 0..rows as isize {
                        for col in 0..cols as isize {
                            let (sr, sc) = ((r - d.0).rem_euclid(rows as isize), (col - d.1).rem_euclid(cols as isize));
                            want += (real.values[(r * cols as isize + col) as usize] - ma)
                                * (sim.values[(sr * cols as isize + sc) as usize] - mb);
                        }
                    }
                    let got = c[(dy + 1) as usize][(dx + 1) as usize] / (rows * cols) as f64;
                    assert!((got - want).abs() < 1e-3 * want.abs().max(1.0), "{d:?}: {got} vs {want}");
                }
            }
        }
    }

    #[test]
    fn a_checkerboard_shifted_a_column_is_its_negative() {
        let (rows, cols) = (32, 40);
        let board = |shift: usize| plane(rows, cols, move |r, c| if (r + c + shift) % 2 == 0 { 7.0 } else { 3.0 });
        let (real, sim) = (board(0), board(1));
        let spec = cross_power(&real, &sim);
        // the peak taken as "no shift, inverted": every neighbour is a rival of the other
        // polarity, and the pixels agree that it matches as well
        let rivals = screen(&spec, |x| x, (0, 0), -1.0);
        assert!(rivals.contains(&(0, 1)) && rivals.contains(&(1, 0)), "{rivals:?}");
        let (confidence, _) = judge(&real, &sim, (0, 0), -1.0, &rivals, 64).unwrap();
        assert!(confidence < 1e-9, "{confidence}");
    }

    #[test]
    fn smooth_scenes_have_no_rival_of_the_other_polarity() {
        let (rows, cols) = (64, 80);
        let values = scene(rows, cols, 5);
        let real = plane(rows, cols, |r, c| values[r * cols + c]);
        for sign in [1.0, -1.0] {
            let sim = plane(rows, cols, |r, c| 100.0 + sign * 2.0 * values[r * cols + c]);
            let spec = cross_power(&real, &sim);
            assert!(screen(&spec, |x| x, (0, 0), sign).is_empty(), "{sign}");
            // and were one judged, it would not count
            assert_eq!(judge(&real, &sim, (0, 0), sign, &[(0, 1), (1, 1)], 64), None);
        }
    }
}
