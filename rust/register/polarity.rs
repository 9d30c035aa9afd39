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

/// `c(peak + (dy, dx))` for dy, dx in −1..=1 (up to a common positive factor). Per column of
/// the half spectrum, `y = x·e^{iθ·peak.0}` (θ = 2π·ky/rows) summed plainly and weighted by
/// `cos θ` and `sin θ` gives the three row sums `Σ y·e^{iθ·dy}`; each is then turned by the
/// column's phase. The column sums run in float32 lanes (a screen needs no more), folded
/// into float64 per column.
fn neighbourhood(spec: &Spectrum, cross: impl Fn(C32) -> C32, peak: (isize, isize)) -> [[f64; 3]; 3] {
    let (rows, cols) = (spec.rows, spec.cols);
    let tau = 2.0 * std::f64::consts::PI;
    // at integer shifts every row (the Nyquist row too) counts once, whatever the sign of
    // its frequency
    let phasor = |ky: usize, shift: isize| {
        let turns = (ky as isize * shift).rem_euclid(rows as isize) as f64 / rows as f64;
        let (sin, cos) = (tau * turns).sin_cos();
        (cos as f32, sin as f32)
    };
    let (at_re, at_im): (Vec<f32>, Vec<f32>) = (0..rows).map(|ky| phasor(ky, peak.0)).unzip();
    let (step_cos, step_sin): (Vec<f32>, Vec<f32>) = (0..rows).map(|ky| phasor(ky, 1)).unzip();
    let (mut x_re, mut x_im) = (vec![0.0f32; rows], vec![0.0f32; rows]);
    let mut out = [[0.0f64; 3]; 3];
    for kx in 0..spec.width() {
        // the column as separate real and imaginary parts: the sums below then vectorise
        let column = &spec.data[kx * rows..(kx + 1) * rows];
        for ((re, im), &h) in x_re.iter_mut().zip(x_im.iter_mut()).zip(column) {
            let x = cross(h);
            (*re, *im) = (x.re, x.im);
        }
        let [yr, yi, yr_cos, yi_cos, yr_sin, yi_sin] =
            column_moments([&x_re, &x_im, &at_re, &at_im, &step_cos, &step_sin]);
        // Σ y·e^{iθ·dy} for dy = −1, 0, +1
        let sums =
            [C64::new(yr_cos + yi_sin, yi_cos - yr_sin), C64::new(yr, yi), C64::new(yr_cos - yi_sin, yi_cos + yr_sin)];
        // the rest of the spectrum is the conjugate mirror: weight 2, except the columns
        // that are their own mirror (DC, and Nyquist for even widths)
        let weight = if kx == 0 || (cols % 2 == 0 && kx == cols / 2) { 1.0 } else { 2.0 };
        for (dx, slot) in (-1isize..=1).zip(0..3) {
            let turns = (kx as isize * (peak.1 + dx)).rem_euclid(cols as isize) as f64 / cols as f64;
            let rot = C64::from_polar(weight, tau * turns);
            for (row, s) in out.iter_mut().zip(&sums) {
                row[slot] += (s * rot).re;
            }
        }
    }
    out
}

/// Lanes of the column sums (six accumulators of four lanes fit the vector registers).
const LANES: usize = 4;

/// For one column `x = (re, im)` and per-row `at = (re, im)`, `step = (cos, sin)`: with
/// `y = x·at`, the sums `Σ Re y, Σ Im y, Σ Re y·cos, Σ Im y·cos, Σ Re y·sin, Σ Im y·sin`.
fn column_moments([x_re, x_im, at_re, at_im, cos, sin]: [&[f32]; 6]) -> [f64; 6] {
    let n = x_re.len();
    let whole = n - n % LANES;
    let lanes = |s| whole_lanes(s, whole);
    let (mut s_re, mut s_im, mut c_re, mut c_im, mut n_re, mut n_im) =
        ([0.0f32; LANES], [0.0f32; LANES], [0.0f32; LANES], [0.0f32; LANES], [0.0f32; LANES], [0.0f32; LANES]);
    for (((((xr, xi), ar), ai), c), s) in
        lanes(x_re).zip(lanes(x_im)).zip(lanes(at_re)).zip(lanes(at_im)).zip(lanes(cos)).zip(lanes(sin))
    {
        for k in 0..LANES {
            let (yr, yi) = (xr[k] * ar[k] - xi[k] * ai[k], xr[k] * ai[k] + xi[k] * ar[k]);
            s_re[k] += yr;
            s_im[k] += yi;
            c_re[k] += yr * c[k];
            c_im[k] += yi * c[k];
            n_re[k] += yr * s[k];
            n_im[k] += yi * s[k];
        }
    }
    let mut out = [s_re, s_im, c_re, c_im, n_re, n_im].map(|acc| acc.iter().map(|&v| f64::from(v)).sum::<f64>());
    for i in whole..n {
        let (yr, yi) = (x_re[i] * at_re[i] - x_im[i] * at_im[i], x_re[i] * at_im[i] + x_im[i] * at_re[i]);
        let terms = [yr, yi, yr * cos[i], yi * cos[i], yr * sin[i], yi * sin[i]];
        out.iter_mut().zip(terms).for_each(|(o, t)| *o += f64::from(t));
    }
    out
}

/// The first `whole` values of `s` as arrays of [`LANES`].
fn whole_lanes(s: &[f32], whole: usize) -> impl Iterator<Item = [f32; LANES]> + '_ {
    s[..whole].chunks_exact(LANES).map(|c| <[f32; LANES]>::try_from(c).expect("a whole lane"))
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
