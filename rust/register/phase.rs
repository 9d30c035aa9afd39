//! Fourier phase correlation.
//!
//! The cross-power spectrum `X = F_real · conj(F_sim)` of the tapered frames encodes the
//! shift `d` of `real(p) = sim(p − d)` as the phase `e^{−i k·d}`. Two surfaces come from it:
//!
//! - the **fully whitened** surface `IFFT(X/|X|)` — a sharp peak over a flat floor — gives
//!   the integer peak (taken by absolute value: a negative peak means inverted grey levels)
//!   and the confidence: a rival peak elsewhere (a periodic pattern, an unrelated pair)
//!   shows as a second peak of comparable height.
//! - the **half-whitened** spectrum `X/|X|^½` gives the subpixel shift
//!   ([`super::subpixel`]); for log-polar spectra its surface also locates the peak. Half
//!   whitening weights frequencies between plain correlation (the lowest frequencies
//!   dominate: a broad peak) and phase correlation (noise at high frequencies weighted like
//!   signal); on real thermal frames with noise and blur it gave the smallest error
//!   (docs/registration.md).
//!
//! The apodisation window favours small shifts and the FFT cannot tell `d` from
//! `d ± frame size`; both are settled on the pixels ([`super::shifts`]).

use super::fft::{self, Spectrum, C32};
use super::frame::Frame;
use super::polarity;
use super::shifts::{resolve_alias, shifted_gradient_correlation};
use super::subpixel::newton_peak;
use super::window::{tukey, TUKEY_ALPHA};

/// Half width, in pixels, of the box around the peak that no rival may come from.
pub const EXCLUSION: isize = 3;

/// Rival peaks below this many standard deviations of the whitened surface are noise.
const NOISE_SIGMAS: f64 = 4.0;

/// Rivals at least this high (relative to the peak, on the whitened surface) are checked on
/// the pixels; at most this many of them.
const CREDIBLE_RIVAL: f64 = 0.2;
const RIVALS_CHECKED: usize = 4;

/// A peak outside the max_shift window this much higher than the best inside it means the
/// shift lies beyond max_shift.
const BEYOND_RATIO: f64 = 1.5;

/// The correlation peak between two frames.
#[derive(Clone, Debug, PartialEq)]
pub struct Peak {
    /// Subpixel shift `(dy, dx)`: `real(p) ≈ sim(p − d)`.
    pub dy: f64,
    pub dx: f64,
    /// +1, or −1 when the frames correlate negatively (inverted grey levels).
    pub sign: f64,
    /// Height of the whitened correlation surface at the peak, in (0, 1].
    pub height: f64,
    /// Distinctness of the peak in [0, 1] (see [`surface_confidence`] and [`correlate`]).
    pub confidence: f64,
    /// Integer shift `(dy, dx)` of the strongest rival.
    pub rival: (isize, isize),
    /// That rival matches with the other polarity ([`super::polarity`]).
    pub rival_flipped: bool,
    /// The best match lies outside the max_shift window: the in-window peak sits on its edge
    /// with the correlation still rising, or a far higher peak lies outside.
    pub beyond_limit: bool,
}

/// Which peaks may be taken.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Polarity {
    /// Only positive correlation (magnitude spectra, log-polar images).
    Positive,
    /// The larger of the positive and negative peaks.
    Either,
}

/// Largest integer shift searched along each axis: `(max_dy, max_dx)`.
pub fn search_limits(rows: usize, cols: usize, max_shift: Option<f64>) -> (usize, usize) {
    let cap = |n: usize| {
        let half = n / 2;
        match max_shift {
            Some(m) => (m.floor().max(0.0) as usize).min(half),
            None => half,
        }
    };
    (cap(rows), cap(cols))
}

/// Phase correlation of two frames of the same shape, Tukey-windowed, peak searched within
/// `|dy|, |dx| ≤ max_shift`. The peak's alias one frame away is taken if its overlap
/// correlates better, and credible rivals are judged on the pixels too: a rival whose
/// gradients correlate nearly as well as the peak's (a periodic pattern) lowers the
/// confidence to `1 − r_rival/r_peak`, and so does a neighbouring shift that matches as well
/// with the other polarity ([`polarity`]).
pub fn correlate(real: &Frame, sim: &Frame, max_shift: Option<f64>) -> Peak {
    let (rows, cols) = (real.rows, real.cols);
    let (fa, fb) = (tapered_spectrum(real), tapered_spectrum(sim));
    let (mut peak, rivals) =
        correlate_spectra(fa, fb, search_limits(rows, cols, max_shift), Polarity::Either, Locate::Whitened);
    let canonical = (peak.dy.round() as isize, peak.dx.round() as isize);
    let chosen = resolve_alias(real, sim, canonical, peak.sign, max_shift);
    peak.dy += (chosen.0 - canonical.0) as f64;
    peak.dx += (chosen.1 - canonical.1) as f64;
    let min_pairs = rows * cols / 8;
    if rivals.far.is_empty() && rivals.flipped.is_empty() {
        return peak;
    }
    let (real, sim) = (real.plane(), sim.plane());
    if let Some(r_peak) = shifted_gradient_correlation(real, sim, chosen, min_pairs).map(|r| peak.sign * r) {
        for rival in rivals.far {
            if let Some(r) = shifted_gradient_correlation(real, sim, rival, min_pairs) {
                let c = if r_peak > 0.0 { (1.0 - peak.sign * r / r_peak).clamp(0.0, 1.0) } else { 0.0 };
                if c < peak.confidence {
                    (peak.confidence, peak.rival, peak.rival_flipped) = (c, rival, false);
                }
            }
        }
    }
    // the screen ran around the canonical peak; its neighbours move with the alias
    let moved = |d: (isize, isize)| (d.0 + chosen.0 - canonical.0, d.1 + chosen.1 - canonical.1);
    let flipped: Vec<(isize, isize)> = rivals.flipped.into_iter().map(moved).collect();
    if let Some((c, rival)) = polarity::judge(real, sim, chosen, peak.sign, &flipped, min_pairs) {
        if c < peak.confidence {
            (peak.confidence, peak.rival, peak.rival_flipped) = (c, rival, true);
        }
    }
    peak
}

/// The spectrum of the Tukey-windowed, mean-free frame.
pub fn tapered_spectrum(frame: &Frame) -> Spectrum {
    let (rows, cols) = (frame.rows, frame.cols);
    let (wr, wc) = (tukey(rows, TUKEY_ALPHA), tukey(cols, TUKEY_ALPHA));
    fft::forward_rows(rows, cols, |r, line| frame.taper_row(r, wr[r], &wc, line))
}

/// The shifts a peak's confidence is checked against on the pixels.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Rivals {
    /// Credible rivals on the whitened surface: local maxima outside the peak's box, at least
    /// [`CREDIBLE_RIVAL`] of its height.
    pub far: Vec<(isize, isize)>,
    /// Neighbours of the peak that correlate credibly with the other polarity
    /// ([`polarity::screen`]; only when both polarities are allowed).
    pub flipped: Vec<(isize, isize)>,
}

/// Which surface the integer peak is taken on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Locate {
    /// The fully whitened surface (sharp): frames, whose spectra are broad.
    Whitened,
    /// The half-whitened surface (smoother): log-polar spectra, whose fully whitened surface
    /// is too noisy to locate the peak reliably.
    HalfWhitened,
}

/// Phase correlation of two already tapered, mean-free images: the peak and its rivals.
pub fn correlate_tapered(
    a: &[f32],
    b: &[f32],
    rows: usize,
    cols: usize,
    limits: (usize, usize),
    polarity: Polarity,
    locate: Locate,
) -> (Peak, Rivals) {
    correlate_spectra(fft::forward(a, rows, cols), fft::forward(b, rows, cols), limits, polarity, locate)
}

/// [`correlate_tapered`] from the images' spectra.
fn correlate_spectra(
    mut fa: Spectrum,
    mut fb: Spectrum,
    limits: (usize, usize),
    polarity: Polarity,
    locate: Locate,
) -> (Peak, Rivals) {
    let (rows, cols) = (fa.rows, fa.cols);
    whiten(&mut fa.data, &mut fb.data);
    let (half, full) = (fa, fb);
    let surface = fft::inverse(full);
    let half_surface = match locate {
        Locate::Whitened => None,
        Locate::HalfWhitened => Some(fft::inverse(half.clone())),
    };
    let locate = half_surface.as_deref().unwrap_or(&surface);
    let (iy, ix, sign) = integer_peak(locate, rows, cols, limits, polarity);
    let at = |s: &[f32], y: isize, x: isize| sign * s[wrap(y, rows) * cols + wrap(x, cols)] as f64;
    let height = at(&surface, iy, ix);
    let (confidence, rival, far) = surface_confidence(&surface, rows, cols, (iy, ix), sign, limits, polarity);
    let outside = (rows / 2, cols / 2);
    let beyond_limit = limits != outside && {
        let (gy, gx, gsign) = integer_peak(locate, rows, cols, outside, polarity);
        let far = gy.unsigned_abs() > limits.0 || gx.unsigned_abs() > limits.1;
        (far && gsign * locate[wrap(gy, rows) * cols + wrap(gx, cols)] as f64 > BEYOND_RATIO * at(locate, iy, ix))
            || rises_beyond(locate, rows, cols, (iy, ix), sign, limits)
    };
    let start = parabolic_start(locate, rows, cols, (iy, ix), sign);
    let (dy, dx) = newton_peak(&half, start, (iy as f64, ix as f64), sign);
    // X/|X|^½ times |X|^½ is the plain cross-power spectrum
    let flipped = match polarity {
        Polarity::Either => polarity::screen(&half, |h| h * h.norm_sqr().sqrt(), (iy, ix), sign),
        Polarity::Positive => Vec::new(),
    };
    let peak = Peak { dy, dx, sign, height, confidence, rival, rival_flipped: false, beyond_limit };
    (peak, Rivals { far, flipped })
}

avx2_copy! {
    /// The cross-power spectrum `X = a·conj(b)` whitened in place: `a` becomes `X/|X|^½`, `b`
    /// becomes `X/|X|` (both 0 where `|X|` is below 1e-12 of the product of the spectra's
    /// largest parts, which bounds it: numerically zero).
    ///
    /// Computed in float32, eight coefficients per vector instruction (in a copy compiled for
    /// AVX2 when the CPU has it: same code, same results), in one pass over the coefficients
    /// after finding each spectrum's largest part (the passes are memory-bound).
    /// Each spectrum is first scaled by a power of two (exact) to a largest part in [0.5, 1),
    /// so `|X|²` can neither overflow nor, above the floor, underflow. The scale changes `X/|X|`
    /// not at all and `X/|X|^½` by a constant factor, which moves no peak.
    fn whiten(a: &mut [C32], b: &mut [C32])
    => whiten_avx2, whiten_impl
}

#[inline(always)]
fn whiten_impl(a: &mut [C32], b: &mut [C32]) {
    let (la, lb) = (largest_part(a), largest_part(b));
    let (sa, sb) = (unit_scale(la), unit_scale(lb));
    let floor = 1e-12 * (la * sa) * (lb * sb);
    let floor_sq = floor * floor;
    for (x, y) in a.iter_mut().zip(b.iter_mut()) {
        let z = C32::new(x.re * sa, x.im * sa) * C32::new(y.re * sb, -y.im * sb);
        let m_sq = z.norm_sqr();
        let root = m_sq.sqrt().sqrt(); // |X|^½
        let inv_root = if m_sq > floor_sq { 1.0 / root } else { 0.0 };
        *x = z * inv_root;
        *y = z * (inv_root * inv_root);
    }
}

/// The largest real or imaginary part of `z` in absolute value (0 if empty).
#[inline(always)]
fn largest_part(z: &[C32]) -> f32 {
    let mut lanes = [0.0f32; 8];
    let parts = z.chunks_exact(4);
    let tail = parts.remainder().iter().fold(0.0f32, |m, v| m.max(v.re.abs()).max(v.im.abs()));
    for chunk in parts {
        for (k, v) in chunk.iter().enumerate() {
            let (re, im) = (v.re.abs(), v.im.abs());
            lanes[2 * k] = if re > lanes[2 * k] { re } else { lanes[2 * k] };
            lanes[2 * k + 1] = if im > lanes[2 * k + 1] { im } else { lanes[2 * k + 1] };
        }
    }
    lanes.into_iter().fold(tail, f32::max)
}

/// The power of two that brings `largest` to [0.5, 1) (1 if it is 0 or not finite).
fn unit_scale(largest: f32) -> f32 {
    if largest > 0.0 && largest.is_finite() {
        (-(largest.log2().floor()) - 1.0).clamp(-126.0, 126.0).exp2()
    } else {
        1.0
    }
}

/// `i` in `0..n` as a signed shift in `(−n/2, n/2]`.
pub(super) fn signed(i: usize, n: usize) -> isize {
    if i <= n / 2 {
        i as isize
    } else {
        i as isize - n as isize
    }
}

fn wrap(s: isize, n: usize) -> usize {
    s.rem_euclid(n as isize) as usize
}

/// The indices `0..n` whose signed shift is at most `limit` in magnitude, in increasing
/// order: `0..=limit` and the negative shifts at the end.
fn within_indices(n: usize, limit: usize) -> [std::ops::Range<usize>; 2] {
    let limit = limit.min(n / 2);
    [0..(limit + 1).min(n), (n - limit).max(n / 2 + 1)..n]
}

/// How a surface value scores as a peak: `sign·v`, or `|v|` when both polarities count.
#[derive(Clone, Copy)]
struct Score {
    sign: f32,
    absolute: bool,
}

impl Score {
    fn new(sign: f64, polarity: Polarity) -> Score {
        Score { sign: sign as f32, absolute: polarity == Polarity::Either }
    }

    #[inline(always)]
    fn of(self, v: f32) -> f32 {
        if self.absolute {
            v.abs()
        } else {
            self.sign * v
        }
    }

    /// The highest score over `line` (−∞ if empty), in eight lanes (vectorised; compiled for
    /// AVX2 when the CPU has it).
    fn top(self, line: &[f32]) -> f32 {
        #[cfg(target_arch = "x86_64")]
        if crate::kernel::use_avx2() {
            // SAFETY: `use_avx2` is true only when the CPU reports AVX2.
            return unsafe { self.top_avx2(line) };
        }
        self.top_impl(line)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn top_avx2(self, line: &[f32]) -> f32 {
        self.top_impl(line)
    }

    #[inline(always)]
    fn top_impl(self, line: &[f32]) -> f32 {
        let mut lanes = [f32::NEG_INFINITY; 8];
        let chunks = line.chunks_exact(8);
        let tail = chunks.remainder().iter().fold(f32::NEG_INFINITY, |m, &v| m.max(self.of(v)));
        for chunk in chunks {
            // a new array each step keeps the lanes in a register (updated in place, they
            // went through memory with a masked store)
            lanes = std::array::from_fn(|k| {
                let s = self.of(chunk[k]);
                if s > lanes[k] {
                    s
                } else {
                    lanes[k]
                }
            });
        }
        lanes.into_iter().fold(tail, f32::max)
    }

    /// Index of the first value of `line` scoring `top`.
    fn first_at(self, line: &[f32], top: f32) -> usize {
        line.iter().position(|&v| self.of(v) == top).unwrap_or(0)
    }
}

/// Integer shift of the highest peak within the limits (the first in row-major order of
/// equal ones), and its sign.
fn integer_peak(
    surface: &[f32],
    rows: usize,
    cols: usize,
    limits: (usize, usize),
    polarity: Polarity,
) -> (isize, isize, f64) {
    let score = Score::new(1.0, polarity);
    let mut best = (0usize, 0usize, f32::NEG_INFINITY);
    for r in within_indices(rows, limits.0).into_iter().flatten() {
        let line = &surface[r * cols..(r + 1) * cols];
        for span in within_indices(cols, limits.1) {
            let (first, part) = (span.start, &line[span]);
            let top = score.top(part);
            if top > best.2 {
                best = (r, first + score.first_at(part, top), top);
            }
        }
    }
    let sign = if polarity == Polarity::Either && surface[best.0 * cols + best.1] < 0.0 { -1.0 } else { 1.0 };
    (signed(best.0, rows), signed(best.1, cols), sign)
}

/// Distinctness of the peak on the whitened surface: `1 − max(rival, noise)/height`, where
/// `rival` is the highest value (either sign, if both polarities are allowed) within the
/// search limits but outside a ±[`EXCLUSION`] box around the peak, and `noise` is
/// [`NOISE_SIGMAS`] standard deviations of the surface outside that box (so a small search
/// window over noise cannot look distinct). Returns it with the rival's shift and the
/// credible rivals to check on the pixels.
fn surface_confidence(
    surface: &[f32],
    rows: usize,
    cols: usize,
    peak: (isize, isize),
    sign: f64,
    limits: (usize, usize),
    polarity: Polarity,
) -> (f64, (isize, isize), Vec<(isize, isize)>) {
    let score = Score::new(sign, polarity);
    let value = |r: usize, c: usize| score.of(surface[r * cols + c]) as f64;
    let height = sign * surface[wrap(peak.0, rows) * cols + wrap(peak.1, cols)] as f64;
    let near = |d: isize, n: usize| {
        let d = d.rem_euclid(n as isize);
        d.min(n as isize - d) <= EXCLUSION
    };
    let col_near: Vec<bool> = (0..cols).map(|c| near(signed(c, cols) - peak.1, cols)).collect();
    let row_near: Vec<bool> = (0..rows).map(|r| near(signed(r, rows) - peak.0, rows)).collect();
    let noise = NOISE_SIGMAS * rms_outside_box(surface, cols, &row_near, &col_near);
    let (mut rival, mut at) = (f64::NEG_INFINITY, (0isize, 0isize));
    let mut credible: Vec<(f64, (isize, isize))> = Vec::new();
    let threshold = CREDIBLE_RIVAL * height;
    for r in within_indices(rows, limits.0).into_iter().flatten() {
        for span in within_indices(cols, limits.1) {
            // Rows clear of the peak's box: their highest value first (vectorised); most
            // of them hold no credible rival, and their pixels need no closer look.
            let part = &surface[r * cols + span.start..r * cols + span.end];
            let top = if row_near[r] { f64::INFINITY } else { score.top(part) as f64 };
            if !row_near[r] && top > rival {
                (rival, at) = (top, (signed(r, rows), signed(span.start + score.first_at(part, top as f32), cols)));
            }
            if top < threshold {
                continue;
            }
            for c in span {
                if row_near[r] && col_near[c] {
                    continue;
                }
                let v = value(r, c);
                if row_near[r] && v > rival {
                    (rival, at) = (v, (signed(r, rows), signed(c, cols)));
                }
                if v >= threshold && is_local_max(&value, r, c, rows, cols) {
                    credible.push((v, (signed(r, rows), signed(c, cols))));
                }
            }
        }
    }
    credible.sort_by(|x, y| y.0.total_cmp(&x.0));
    let rivals = credible.into_iter().take(RIVALS_CHECKED).map(|(_, s)| s).collect();
    if !(height > 0.0 && rival.max(noise).is_finite()) {
        return (0.0, at, rivals);
    }
    ((1.0 - rival.max(noise) / height).clamp(0.0, 1.0), at, rivals)
}

avx2_copy! {
    /// Root mean square of the surface outside the box of rows `row_near` × columns `col_near`
    /// (0 if the box covers it all); compiled for AVX2 when the CPU has it.
    fn rms_outside_box(surface: &[f32], cols: usize, row_near: &[bool], col_near: &[bool]) -> f64
    => rms_outside_box_avx2, rms_outside_box_impl
}

#[inline(always)]
fn rms_outside_box_impl(surface: &[f32], cols: usize, row_near: &[bool], col_near: &[bool]) -> f64 {
    let square = |v: &f32| (*v as f64) * (*v as f64);
    let sum_sq = |line: &[f32]| {
        let mut lanes = [0.0f64; 8];
        let chunks = line.chunks_exact(8);
        let tail: f64 = chunks.remainder().iter().map(square).sum();
        for chunk in chunks {
            for (acc, v) in lanes.iter_mut().zip(chunk) {
                *acc += square(v);
            }
        }
        lanes.iter().sum::<f64>() + tail
    };
    let (mut total, mut count) = (0.0, 0usize);
    for (line, &near) in surface.chunks_exact(cols).zip(row_near) {
        total += sum_sq(line);
        count += cols;
        if near {
            for (v, _) in line.iter().zip(col_near).filter(|(_, &n)| n) {
                total -= square(v);
                count -= 1;
            }
        }
    }
    if count == 0 {
        0.0
    } else {
        (total.max(0.0) / count as f64).sqrt()
    }
}

fn is_local_max(value: &impl Fn(usize, usize) -> f64, r: usize, c: usize, rows: usize, cols: usize) -> bool {
    let v = value(r, c);
    (-1isize..=1).all(|dy| {
        (-1isize..=1)
            .all(|dx| (dy == 0 && dx == 0) || value(wrap(r as isize + dy, rows), wrap(c as isize + dx, cols)) <= v)
    })
}

/// Whether the peak sits on an edge of a window narrower than the frame with a higher value
/// just outside it.
fn rises_beyond(
    surface: &[f32],
    rows: usize,
    cols: usize,
    peak: (isize, isize),
    sign: f64,
    limits: (usize, usize),
) -> bool {
    let at = |y: isize, x: isize| sign * surface[wrap(y, rows) * cols + wrap(x, cols)] as f64;
    let here = at(peak.0, peak.1);
    let on_edge = |p: isize, limit: usize, n: usize| limit < n / 2 && p.unsigned_abs() == limit;
    let outward = |p: isize| -> [isize; 2] {
        match p.signum() {
            0 => [1, -1],
            s => [s, s],
        }
    };
    (on_edge(peak.0, limits.0, rows) && outward(peak.0).iter().any(|&o| at(peak.0 + o, peak.1) > here))
        || (on_edge(peak.1, limits.1, cols) && outward(peak.1).iter().any(|&o| at(peak.0, peak.1 + o) > here))
}

/// The integer peak moved by a parabola through it and its neighbours on each axis (at most
/// half a pixel): where Newton's method starts. A move below `ON_THE_INTEGER` is rounding
/// in the surface (float32 transforms are not exactly symmetric): Newton's method starts on
/// the integer, where the gradient of a symmetric peak (identical frames) is exactly zero.
fn parabolic_start(surface: &[f32], rows: usize, cols: usize, peak: (isize, isize), sign: f64) -> (f64, f64) {
    const ON_THE_INTEGER: f64 = 1e-6;
    let at = |dy: isize, dx: isize| sign * surface[wrap(peak.0 + dy, rows) * cols + wrap(peak.1 + dx, cols)] as f64;
    let vertex = |minus: f64, centre: f64, plus: f64| {
        let curvature = minus - 2.0 * centre + plus;
        let offset = if curvature < 0.0 { (0.5 * (minus - plus) / curvature).clamp(-0.5, 0.5) } else { 0.0 };
        if offset.abs() < ON_THE_INTEGER {
            0.0
        } else {
            offset
        }
    };
    let c = at(0, 0);
    let oy = if rows > 2 { vertex(at(-1, 0), c, at(1, 0)) } else { 0.0 };
    let ox = if cols > 2 { vertex(at(0, -1), c, at(0, 1)) } else { 0.0 };
    (peak.0 as f64 + oy, peak.1 as f64 + ox)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A smooth periodic test pattern shifted exactly by `(dy, dx)` (band-limited: a few
    /// low-frequency cosines), so the true shift is known to machine precision.
    fn pattern(rows: usize, cols: usize, dy: f64, dx: f64) -> Plane {
        let tau = 2.0 * std::f64::consts::PI;
        let waves = [(1.0, 2.0, 0.3, 1.0), (3.0, 1.0, 1.1, 0.7), (2.0, 5.0, 2.0, 0.5), (7.0, 3.0, 0.4, 0.3)];
        let mut values = vec![0.0; rows * cols];
        for r in 0..rows {
            for c in 0..cols {
                let (y, x) = (r as f64 - dy, c as f64 - dx);
                values[r * cols + c] = waves
                    .iter()
                    .map(|&(ky, kx, ph, amp)| amp * (tau * (ky * y / rows as f64 + kx * x / cols as f64) + ph).cos())
                    .sum();
            }
        }
        Plane::new(rows, cols, values, vec![true; rows * cols])
    }

    use super::super::image::Plane;
    use super::super::pool::Buffer;
    use super::super::window::tapered;

    fn untapered(p: &Plane) -> Buffer<f32> {
        tapered(p, &vec![1.0; p.rows], &vec![1.0; p.cols])
    }

    /// The peak of either polarity on the whitened surface of the untapered frames.
    fn whitened_peak(real: &Plane, sim: &Plane) -> Peak {
        let limits = search_limits(real.rows, real.cols, None);
        let (a, b) = (untapered(real), untapered(sim));
        correlate_tapered(&a, &b, real.rows, real.cols, limits, Polarity::Either, Locate::Whitened).0
    }

    #[test]
    fn recovers_exact_subpixel_shifts_of_periodic_patterns() {
        for &(rows, cols) in &[(64usize, 80usize), (45, 50)] {
            let real = pattern(rows, cols, 0.0, 0.0);
            for &(dy, dx) in &[(2.3, -1.7), (0.5, 0.5), (-3.25, 4.75), (0.0, 0.0)] {
                let sim = pattern(rows, cols, -dy, -dx); // real(p) = sim(p − d)
                let pk = whitened_peak(&real, &sim);
                assert!((pk.dy - dy).abs() < 1e-6 && (pk.dx - dx).abs() < 1e-6, "{rows}x{cols} {dy},{dx}: {pk:?}");
                assert_eq!(pk.sign, 1.0);
            }
        }
    }

    #[test]
    fn identical_frames_give_exactly_no_shift() {
        let frame = untapered(&pattern(48, 64, 0.3, -0.2));
        let limits = search_limits(48, 64, None);
        let (pk, _) = correlate_tapered(&frame, &frame, 48, 64, limits, Polarity::Either, Locate::Whitened);
        assert_eq!((pk.dy, pk.dx, pk.sign), (0.0, 0.0, 1.0));
    }

    #[test]
    fn inverted_frames_give_a_negative_peak() {
        let real = pattern(48, 64, 0.0, 0.0);
        let mut sim = pattern(48, 64, 1.5, -2.25);
        sim.values.iter_mut().for_each(|v| *v = 100.0 - 3.0 * *v);
        let limits = search_limits(48, 64, None);
        let (pk, _) =
            correlate_tapered(&untapered(&real), &untapered(&sim), 48, 64, limits, Polarity::Either, Locate::Whitened);
        assert_eq!(pk.sign, -1.0);
        assert!((pk.dy + 1.5).abs() < 1e-6 && (pk.dx - 2.25).abs() < 1e-6, "{pk:?}");
        let (pos, _) = correlate_tapered(
            &untapered(&real),
            &untapered(&sim),
            48,
            64,
            limits,
            Polarity::Positive,
            Locate::HalfWhitened,
        );
        assert_eq!(pos.sign, 1.0);
    }

    #[test]
    fn extreme_grey_levels_give_the_same_shift() {
        // whitening in float32 scales each spectrum first: 1e±30 grey levels neither
        // overflow nor underflow
        let (rows, cols) = (48, 64);
        let find = |scale: f64| {
            let scaled = |p: Plane| {
                let values: Vec<f64> = p.values.iter().map(|v| v * scale).collect();
                Plane::new(rows, cols, values, vec![true; rows * cols])
            };
            let (real, sim) = (scaled(pattern(rows, cols, 0.0, 0.0)), scaled(pattern(rows, cols, -1.25, 2.5)));
            let pk = whitened_peak(&real, &sim);
            (pk.dy, pk.dx, pk.height)
        };
        let reference = find(1.0);
        assert!((reference.0 - 1.25).abs() < 1e-6 && (reference.1 + 2.5).abs() < 1e-6, "{reference:?}");
        for scale in [1e-30, 1e30] {
            let (dy, dx, height) = find(scale);
            assert!((dy - reference.0).abs() < 1e-6 && (dx - reference.1).abs() < 1e-6, "{scale}: {dy} {dx}");
            assert!((height - reference.2).abs() < 1e-6, "{scale}: {height}");
        }
    }

    #[test]
    fn vectorised_scans_match_a_plain_scan() {
        // the highest score and its first position, ties included, for every polarity
        let line: Vec<f32> = (0..37).map(|i| (((i * 7919) % 23) as f32 - 11.0) * 0.5).collect();
        for (sign, polarity) in [(1.0, Polarity::Positive), (-1.0, Polarity::Positive), (1.0, Polarity::Either)] {
            let score = Score::new(sign, polarity);
            for len in [0usize, 1, 7, 8, 9, 16, 37] {
                let part = &line[..len];
                let plain = part.iter().map(|&v| score.of(v)).fold(f32::NEG_INFINITY, f32::max);
                assert_eq!(score.top(part), plain, "{len}");
                if len > 0 {
                    let first = part.iter().position(|&v| score.of(v) == plain).unwrap();
                    assert_eq!(score.first_at(part, plain), first);
                }
            }
        }
    }

    #[test]
    fn limits_confine_the_search() {
        assert_eq!(search_limits(120, 160, None), (60, 80));
        assert_eq!(search_limits(120, 160, Some(4.9)), (4, 4));
        assert_eq!(search_limits(10, 10, Some(99.0)), (5, 5));
    }
}
