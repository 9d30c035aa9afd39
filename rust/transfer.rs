//! Cross-spectra of a frame pair, the input of the relative transfer function
//! (`irfidelity.transfer`, docs/interpretation.md "The pair as a system").
//!
//! A simulated frame of the scene a real camera saw is, to first order, the real frame
//! through a relative transfer function plus noise of its own. Its estimate needs the
//! spectra of both frames and their cross-spectrum, averaged over many windowed tiles
//! (Welch's method): [`tile_spectra`] computes them, kept apart in `groups` runs of
//! neighbouring tiles so the Python layer can give each estimate a jackknife uncertainty,
//! and, with a second real frame of the scene, the spectrum of the two real frames'
//! difference (twice the real camera's temporal noise). [`low_spectrum`] gives the
//! cross-spectrum of the whole frame reduced by block means, whose lowest frequencies fix
//! the gain (the transfer at zero frequency) more closely than a tile's.
//!
//! Tiles are Hann-windowed after their mean is removed (in float64) and transformed in
//! float32, two real tiles as one complex transform (the real frame as its real part, the
//! simulated one as its imaginary part, told apart by the symmetry of real spectra); the
//! products are summed in float64. The transforms' rounding, about 1e-7 of a tile's largest
//! coefficient, is far below the noise of any camera frame. A tile is used only when every
//! one of its pixels is scored (`mask`) and finite in every frame. Memory does not grow
//! with the frame: each worker holds one tile and one group's sums.

use std::sync::Arc;

use rayon::prelude::*;
use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};

use crate::budget;
use crate::kernel::{all_finite, Sample};
use crate::{Error, Result};

type C32 = Complex<f32>;
type C64 = Complex<f64>;

thread_local! {
    static PLANNER32: std::cell::RefCell<FftPlanner<f32>> = std::cell::RefCell::new(FftPlanner::new());
    static PLANNER64: std::cell::RefCell<FftPlanner<f64>> = std::cell::RefCell::new(FftPlanner::new());
}

/// The smallest tile side: below it a tile holds too few frequencies to be of use.
pub const MIN_TILE: usize = 8;
/// The largest tile side (a tile's working set stays in the cache).
pub const MAX_TILE: usize = 256;

/// The frames of a pair, row-major `rows × cols`: the real one, the simulated one, an optional
/// second real frame of the same scene, and the scored pixels.
pub struct Frames<'a, R, S> {
    pub real: &'a [R],
    pub sim: &'a [S],
    pub reference: Option<&'a [R]>,
    pub mask: Option<&'a [bool]>,
    pub shape: (usize, usize),
}

/// How a frame is cut into tiles: `tile × tile` squares every `step` pixels, in `groups` runs
/// of neighbouring tiles (raster order); `shift` is the pair's displacement `(dy, dx)`
/// (`sim(x) ≈ real(x − d)`), around which each tile's own is measured (see [`align`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tiling {
    pub tile: usize,
    pub step: usize,
    pub groups: usize,
    pub shift: (f64, f64),
}

/// A tile's own displacement is looked for within this many pixels of the pair's; beyond, the
/// tile keeps the pair's (its own cannot be told from noise).
pub const MAX_LOCAL_SHIFT: f64 = 1.5;

/// ... and only when its standard error (px) is below this: at 0.25 cy/px an alignment off by
/// this much lowers the ratio by 1 − cos(2π·0.25·0.05) ≈ 0.3 %.
pub const MAX_LOCAL_ERROR: f64 = 0.05;

/// ... and when it departs from the pair's by more than this many of its standard errors.
pub const SIGNIFICANT: f64 = 3.0;

/// Sums of periodograms over the tiles of each group, each `groups × tile × (tile/2 + 1)`
/// values (group, row frequency `ky` in FFT order, column frequency `kx` = 0..=tile/2).
#[derive(Clone, Debug, PartialEq)]
pub struct TileSpectra {
    pub tile: usize,
    pub groups: usize,
    /// Tiles summed in each group.
    pub tiles: Vec<u64>,
    /// Σ |R|².
    pub real: Vec<f64>,
    /// Σ |S|².
    pub sim: Vec<f64>,
    /// Σ conj(R)·S, real and imaginary parts.
    pub cross_re: Vec<f64>,
    pub cross_im: Vec<f64>,
    /// Σ |R − R′|² with a second real frame R′ (None without one).
    pub difference: Option<Vec<f64>>,
    /// Σ w² over a tile: a white noise of variance σ² has the expected periodogram σ²·Σ w².
    pub window_energy: f64,
    /// Tiles of the frame that could not be used (a pixel not scored or not finite).
    pub skipped: u64,
    /// Per group, over its tiles' own displacements weighted by their low-frequency cross
    /// power `w`: `[Σw, Σw·dy, Σw·dx, Σw·dy², Σw·dx²]`.
    pub shifts: Vec<[f64; 5]>,
    /// The whole-pixel displacement of the simulated tiles (the pair's, rounded); `shifts` are
    /// the rest, measured from it.
    pub offset: (i64, i64),
    /// Per group, the box its tiles cover: `[row0, row1, col0, col1]` (end excluded; empty
    /// when the group has no tile).
    pub boxes: Vec<[usize; 4]>,
}

/// The cross-spectrum of the block-mean frames (`factor × factor` blocks), one periodogram
/// of the whole (Hann-windowed) frame: `rows × (cols/2 + 1)` values each, row frequency in
/// FFT order. Frequencies are in cycles per block.
#[derive(Clone, Debug, PartialEq)]
pub struct LowSpectrum {
    pub rows: usize,
    pub cols: usize,
    pub factor: usize,
    pub real: Vec<f64>,
    pub sim: Vec<f64>,
    pub cross_re: Vec<f64>,
    pub cross_im: Vec<f64>,
    /// Blocks without a scored, finite pixel (they enter at the mean).
    pub empty: u64,
    /// Σ real, Σ sim and their count over the whole frame's pixels scored and finite in both.
    pub sum_real: f64,
    pub sum_sim: f64,
    pub pixels: u64,
}

/// A Hann window of length `n` without its zero end points, `sin²(π(i + 1)/(n + 1))`.
pub fn hann(n: usize) -> Vec<f64> {
    hann_moved(n, 0.0)
}

/// The Hann window of [`hann`] moved by `d` pixels (|d| ≤ ½): `sin²(π(i + 1 − d)/(n + 1))`.
/// Content displaced by `d` under the moved window is the displaced windowed content, so the
/// cross-spectrum's phase turns linearly with `d` (the same window on both would mix in
/// neighbouring bins of other phase, and read a fractional displacement about a fifth short).
fn hann_moved(n: usize, d: f64) -> Vec<f64> {
    (0..n).map(|i| (std::f64::consts::PI * ((i + 1) as f64 - d) / (n + 1) as f64).sin().powi(2)).collect()
}

/// The 2-D window of two 1-D ones, row-major.
fn outer(along_y: &[f64], along_x: &[f64]) -> Vec<f64> {
    along_y.iter().flat_map(|&wy| along_x.iter().map(move |&wx| wy * wx)).collect()
}

/// The top-left corners of the tiles along one axis of length `len`: every `step` pixels, the
/// grid centred so the uncovered margins are equal.
fn starts(len: usize, tile: usize, step: usize) -> Vec<usize> {
    if len < tile {
        return Vec::new();
    }
    let count = (len - tile) / step + 1;
    let margin = (len - tile - (count - 1) * step) / 2;
    (0..count).map(|i| margin + i * step).collect()
}

fn check_frames<R, S>(frames: &Frames<'_, R, S>, what: &str) -> Result<()> {
    let (rows, cols) = frames.shape;
    let n = rows.checked_mul(cols).ok_or_else(|| Error::Shape(format!("{what}: frame too large")))?;
    let lengths = [
        Some(frames.real.len()),
        Some(frames.sim.len()),
        frames.reference.map(<[R]>::len),
        frames.mask.map(<[bool]>::len),
    ];
    if lengths.iter().flatten().any(|&len| len != n) {
        return Err(Error::Shape(format!("{what}: the frames, reference and mask must all be {rows} x {cols}")));
    }
    Ok(())
}

/// Whether every pixel of the real frame's `tile × tile` square at `(y0, x0)` is scored and
/// finite, and of the simulated frame's at `at` (None: off the frame).
fn usable<R: Sample, S: Sample>(
    frames: &Frames<'_, R, S>,
    (y0, x0): (usize, usize),
    at: Option<(usize, usize)>,
    tile: usize,
) -> bool {
    let Some((sy, sx)) = at else { return false };
    let cols = frames.shape.1;
    (0..tile).all(|y| {
        let span = (y0 + y) * cols + x0..(y0 + y) * cols + x0 + tile;
        let moved = (sy + y) * cols + sx..(sy + y) * cols + sx + tile;
        frames.mask.is_none_or(|m| m[span.clone()].iter().all(|&k| k))
            && all_finite(&frames.real[span.clone()])
            && all_finite(&frames.sim[moved])
            && frames.reference.is_none_or(|r| all_finite(&r[span.clone()]))
    })
}

/// Where the simulated frame's tile lies for the real frame's at `(y0, x0)`: displaced by
/// `offset` whole pixels (the pair's displacement, rounded), None when that leaves the frame.
fn moved(
    (y0, x0): (usize, usize),
    offset: (i64, i64),
    (rows, cols): (usize, usize),
    tile: usize,
) -> Option<(usize, usize)> {
    let (y, x) = (y0 as i64 + offset.0, x0 as i64 + offset.1);
    (y >= 0 && x >= 0 && y as usize + tile <= rows && x as usize + tile <= cols).then_some((y as usize, x as usize))
}

/// The mean of a tile of `values`, summed in eight lanes (so the sum vectorises).
#[inline(always)]
fn tile_mean<T: Sample>(values: &[T], cols: usize, y0: usize, x0: usize, tile: usize) -> f64 {
    let mut lanes = [0.0f64; 8];
    for y in y0..y0 + tile {
        let row = &values[y * cols + x0..y * cols + x0 + tile];
        let mut chunks = row.chunks_exact(8);
        for chunk in &mut chunks {
            for (lane, v) in lanes.iter_mut().zip(chunk) {
                *lane += v.to_f64();
            }
        }
        for (lane, v) in lanes.iter_mut().zip(chunks.remainder()) {
            *lane += v.to_f64();
        }
    }
    lanes.iter().sum::<f64>() / (tile * tile) as f64
}

/// A square complex transform in place: rows, a transpose, rows again, so that the
/// coefficient of row frequency `ky` and column frequency `kx` is at `kx·n + ky`.
struct Square {
    n: usize,
    fft: Arc<dyn Fft<f32>>,
    scratch: Vec<C32>,
}

impl Square {
    fn new(fft: Arc<dyn Fft<f32>>) -> Square {
        let n = fft.len();
        Square { n, scratch: budget::filled(fft.get_inplace_scratch_len(), C32::default()), fft }
    }

    fn forward(&mut self, z: &mut [C32]) {
        self.fft.process_with_scratch(z, &mut self.scratch);
        let n = self.n;
        for y in 0..n {
            for x in y + 1..n {
                z.swap(y * n + x, x * n + y);
            }
        }
        self.fft.process_with_scratch(z, &mut self.scratch);
    }
}

/// Tiles summed in float32 before their sums join the float64 ones: the relative rounding of
/// a float32 sum of this many terms stays below 1e-6.
const FLUSH: u64 = 16;

/// One group's sums, stored column by column (`kx·n + ky`, the order of a [`Square`]
/// transform) while they are summed: the last tiles' in float32 (`pending`, eight values per
/// vector instruction), joined to the float64 totals every [`FLUSH`] tiles.
/// [`GroupSums::append_rows`] gives the layout of [`TileSpectra`].
struct GroupSums {
    tiles: u64,
    real: Vec<f64>,
    sim: Vec<f64>,
    cross_re: Vec<f64>,
    cross_im: Vec<f64>,
    difference: Option<Vec<f64>>,
    pending: [Vec<f32>; 4],
    pending_tiles: u64,
    /// The tile's cross-spectrum, before it is aligned and summed.
    cross: Vec<C32>,
    shifts: [f64; 5],
    /// What a power of the scaled tiles is multiplied by to be in frame units² (see [`scale_of`]).
    unscale: f64,
}

impl GroupSums {
    fn new(bins: usize, with_difference: bool, unscale: f64) -> GroupSums {
        GroupSums {
            unscale,
            tiles: 0,
            real: budget::filled(bins, 0.0),
            sim: budget::filled(bins, 0.0),
            cross_re: budget::filled(bins, 0.0),
            cross_im: budget::filled(bins, 0.0),
            difference: with_difference.then(|| budget::filled(bins, 0.0)),
            pending: std::array::from_fn(|_| budget::filled(bins, 0.0f32)),
            pending_tiles: 0,
            cross: budget::filled(bins, C32::default()),
            shifts: [0.0; 5],
        }
    }

    /// Joins the pending float32 sums to the float64 totals.
    fn flush(&mut self) {
        let totals = [&mut self.real, &mut self.sim, &mut self.cross_re, &mut self.cross_im];
        for (total, pending) in totals.into_iter().zip(self.pending.iter_mut()) {
            for (t, p) in total.iter_mut().zip(pending.iter_mut()) {
                *t += *p as f64 * self.unscale;
                *p = 0.0;
            }
        }
        self.pending_tiles = 0;
    }

    /// Adds |D|² of a transform `z` of one real tile `d` (imaginary part zero).
    fn add_difference(&mut self, z: &[C32], n: usize) {
        let Some(difference) = self.difference.as_mut() else { return };
        for (sum, p) in difference.iter_mut().zip(&z[..(n / 2 + 1) * n]) {
            *sum += ((p.re as f64).powi(2) + (p.im as f64).powi(2)) * self.unscale;
        }
    }

    /// Each sum in the layout of [`TileSpectra`] (`ky·(n/2 + 1) + kx`), appended to `out`.
    fn append_rows(values: &[f64], n: usize, out: &mut Vec<f64>) {
        let width = n / 2 + 1;
        out.extend((0..n * width).map(|i| values[(i % width) * n + i / width]));
    }
}

avx2_copy! {
    /// Adds the periodograms of a transform `z` of `a + i·b` (two real `n × n` tiles) to
    /// `sums`: |A|², |B|² and conj(A)·B over the half plane `kx = 0..=n/2`, with
    /// `A(k) = (Z(k) + conj Z(−k))/2` and `B(k) = (Z(k) − conj Z(−k))/(2i)`, in float32 (see
    /// [`FLUSH`]); the cross-spectrum with the tile's own displacement taken out of its phase
    /// ([`Alignment::own`]). In a copy compiled for AVX2 when the CPU has it (same code, same results).
    fn add_pair(sums: &mut GroupSums, z: &[C32], alignment: &Alignment) => add_pair_avx2, add_pair_impl
}

#[inline(always)]
fn add_pair_impl(sums: &mut GroupSums, z: &[C32], alignment: &Alignment) {
    let n = alignment.n;
    let mut opposite = [C32::default(); MAX_TILE];
    let opposite = &mut opposite[..n];
    let [real, sim, _, _] = &mut sums.pending;
    for kx in 0..n / 2 + 1 {
        let column = &z[kx * n..(kx + 1) * n];
        let mirror = &z[((n - kx) % n) * n..((n - kx) % n + 1) * n];
        // Z(−ky): mirror[0] for ky = 0, else mirror[n − ky]
        opposite[0] = mirror[0];
        opposite[1..].iter_mut().zip(mirror[1..].iter().rev()).for_each(|(o, m)| *o = *m);
        let span = kx * n..(kx + 1) * n;
        let (real, sim, cross) = (&mut real[span.clone()], &mut sim[span.clone()], &mut sums.cross[span]);
        for (((real, sim), cross), (p, q)) in
            real.iter_mut().zip(sim.iter_mut()).zip(cross.iter_mut()).zip(column.iter().zip(opposite.iter()))
        {
            let (a_re, a_im) = (0.5 * (p.re + q.re), 0.5 * (p.im - q.im));
            let (b_re, b_im) = (0.5 * (p.im + q.im), -0.5 * (p.re - q.re));
            *real += a_re * a_re + a_im * a_im;
            *sim += b_re * b_re + b_im * b_im;
            *cross = C32::new(a_re * b_re + a_im * b_im, a_re * b_im - a_im * b_re);
        }
    }
    let (own, measured, weight) = alignment.own(&sums.cross);
    let weight = weight * sums.unscale; // in frame units², as the pair's other sums
    sums.shifts[0] += weight;
    sums.shifts[1] += weight * measured.0;
    sums.shifts[2] += weight * measured.1;
    sums.shifts[3] += weight * measured.0 * measured.0;
    sums.shifts[4] += weight * measured.1 * measured.1;
    if own == alignment.shift {
        add_turned(sums, &alignment.pair_turn);
    } else {
        add_turned(sums, &turns(n, own));
    }
    sums.pending_tiles += 1;
    if sums.pending_tiles == FLUSH {
        sums.flush();
    }
}

/// The bins a tile's displacement is read from: rings 3..=min(8, n/4) of the half plane (2..=4
/// in tiles under 32 px), `(ky, kx)` with ky signed. The lowest rings are left out: the window
/// mixes them with the mean's neighbourhood, whose phase does not turn with the displacement.
/// Within [`MAX_LOCAL_SHIFT`] of the pair's displacement, their phases do not wrap.
fn shift_bins(n: usize) -> impl Iterator<Item = (i64, usize)> {
    let (low, top) = if n >= 32 { (3.0, (n / 4).min(8) as f64) } else { (2.0, (n / 4) as f64) };
    let reach = top as i64;
    (-reach..=reach).flat_map(move |ky| (0..=reach as usize).map(move |kx| (ky, kx))).filter(move |&(ky, kx)| {
        let r = ((ky * ky) as f64 + (kx * kx) as f64).sqrt();
        (low..=top).contains(&r) && (kx > 0 || ky > 0)
    })
}

/// What aligning tiles needs, made once per pass: the bins a displacement is read from (their
/// flat index, phase gradients and the turn that takes the pair's displacement out), and the
/// turn of every bin for the pair's displacement (most tiles keep it).
struct Alignment {
    n: usize,
    shift: (f64, f64),
    bins: Vec<(usize, f64, f64, C64)>,
    pair_turn: Vec<C32>,
}

impl Alignment {
    fn new(n: usize, shift: (f64, f64)) -> Alignment {
        let tau = 2.0 * std::f64::consts::PI / n as f64;
        let bins = shift_bins(n)
            .map(|(ky, kx)| {
                let index = kx * n + ky.rem_euclid(n as i64) as usize;
                let turn = C64::from_polar(1.0, tau * (ky as f64 * shift.0 + kx as f64 * shift.1));
                (index, -tau * ky as f64, -tau * kx as f64, turn)
            })
            .collect();
        Alignment { n, shift, bins, pair_turn: turns(n, shift) }
    }

    /// The displacement a tile is aligned on, its own as measured, and the weight of that
    /// measurement (the cross power of the bins used; 0 when it was not kept). A tile's own:
    /// the phases of its cross-spectrum at [`shift_bins`], the pair's displacement taken out
    /// first, fitted by weighted least squares (`arg c(k) = −2π·k·d/n`); the pair's displacement
    /// instead (weight 0) when the tile's is beyond [`MAX_LOCAL_SHIFT`] of it or uncertain
    /// beyond [`MAX_LOCAL_ERROR`], and also (weight kept) when it departs from it by less than
    /// [`SIGNIFICANT`] standard errors. Distortion and moving objects displace tiles apart:
    /// aligning each tile keeps them out of the MTF ratio, which then measures resolution.
    fn own(&self, cross: &[C32]) -> ((f64, f64), (f64, f64), f64) {
        let mut phases = [(0.0f64, 0.0f64); 256];
        let (mut syy, mut syx, mut sxx, mut by, mut bx, mut total) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        for (slot, &(index, gy, gx, turn)) in phases.iter_mut().zip(&self.bins) {
            let c = C64::new(cross[index].re as f64, cross[index].im as f64) * turn;
            let (w, phase) = (c.norm(), c.arg());
            *slot = (w, phase);
            syy += w * gy * gy;
            syx += w * gy * gx;
            sxx += w * gx * gx;
            by += w * gy * phase;
            bx += w * gx * phase;
            total += w;
        }
        let det = syy * sxx - syx * syx;
        // NaN (a degenerate fit) is rejected with the non-positive
        if det.is_nan() || det <= 0.0 || total.is_nan() || total <= 0.0 {
            return (self.shift, self.shift, 0.0);
        }
        let (ry, rx) = ((by * sxx - bx * syx) / det, (bx * syy - by * syx) / det);
        if !(ry.abs() <= MAX_LOCAL_SHIFT && rx.abs() <= MAX_LOCAL_SHIFT) {
            return (self.shift, self.shift, 0.0);
        }
        // the fit's standard error from its residual phases
        let mut residual = 0.0f64;
        for (&(w, phase), &(_, gy, gx, _)) in phases.iter().zip(&self.bins) {
            let miss = phase - (gy * ry + gx * rx);
            let miss = (miss + std::f64::consts::PI).rem_euclid(2.0 * std::f64::consts::PI) - std::f64::consts::PI;
            residual += w * miss * miss;
        }
        let variance = residual / (self.bins.len() as f64 - 2.0).max(1.0) * (syy + sxx) / det;
        let error = variance.sqrt();
        if error.is_nan() || error > MAX_LOCAL_ERROR {
            return (self.shift, self.shift, 0.0);
        }
        let significant = (ry * ry + rx * rx) > SIGNIFICANT * SIGNIFICANT * variance;
        let measured = (self.shift.0 + ry, self.shift.1 + rx);
        (if significant { measured } else { self.shift }, measured, total)
    }
}

/// `e^{2πi·k·d/n}` for every bin of the half plane (`kx·n + ky`, ky signed).
fn turns(n: usize, d: (f64, f64)) -> Vec<C32> {
    let tau = 2.0 * std::f64::consts::PI / n as f64;
    let along_y: Vec<C64> = (0..n)
        .map(|ky| C64::from_polar(1.0, tau * (if ky <= n / 2 { ky as f64 } else { ky as f64 - n as f64 }) * d.0))
        .collect();
    (0..n / 2 + 1)
        .flat_map(|kx| {
            let along_x = C64::from_polar(1.0, tau * kx as f64 * d.1);
            along_y.iter().map(move |&t| {
                let t = t * along_x;
                C32::new(t.re as f32, t.im as f32)
            })
        })
        .collect()
}

/// Adds the tile's cross-spectrum (`sums.cross`) turned by `turn` (`c(k)·turn(k)`: its
/// displacement taken out of its phase) to the pending sums.
#[inline(always)]
fn add_turned(sums: &mut GroupSums, turn: &[C32]) {
    let [_, _, cross_re, cross_im] = &mut sums.pending;
    for (((re, im), c), t) in cross_re.iter_mut().zip(cross_im.iter_mut()).zip(&sums.cross).zip(turn) {
        let v = c * t;
        *re += v.re;
        *im += v.im;
    }
}

avx2_copy! {
    /// The windowed, mean-free tiles of `a` at the first corner (real part of `z`) and of `b` at
    /// the second (imaginary part); `windows` are their 2-D windows, row-major. In a copy compiled for AVX2 when the
    /// CPU has it (same code, same results).
    fn fill_pair[A: Sample, B: Sample](a: &[A], b: &[B], cols: usize, corners: ((usize, usize), (usize, usize)), windows: (&[f64], &[f64]), scale: f64, z: &mut [C32])
    => fill_pair_avx2, fill_pair_impl
}

#[inline(always)]
fn fill_pair_impl<A: Sample, B: Sample>(
    a: &[A],
    b: &[B],
    cols: usize,
    ((y0, x0), (sy, sx)): ((usize, usize), (usize, usize)),
    (window_a, window_b): (&[f64], &[f64]),
    scale: f64,
    z: &mut [C32],
) {
    let n = (window_a.len() as f64).sqrt() as usize;
    let (mean_a, mean_b) = (tile_mean(a, cols, y0, x0, n), tile_mean(b, cols, sy, sx, n));
    let rows = z.chunks_exact_mut(n).zip(window_a.chunks_exact(n).zip(window_b.chunks_exact(n)));
    for (y, (line, weights)) in rows.enumerate() {
        let (row, moved) = ((y0 + y) * cols + x0, (sy + y) * cols + sx);
        let values = a[row..row + n].iter().zip(&b[moved..moved + n]);
        if narrow::<A>() && narrow::<B>() {
            // values of 16 bits or fewer are exact in float32, and so are their differences from
            // the mean to float32's relative precision
            let (mean_a, mean_b) = (mean_a as f32, mean_b as f32);
            for ((out, (&wa, &wb)), (va, vb)) in line.iter_mut().zip(weights.0.iter().zip(weights.1)).zip(values) {
                *out = C32::new((va.to_f64() as f32 - mean_a) * wa as f32, (vb.to_f64() as f32 - mean_b) * wb as f32);
            }
        } else {
            for ((out, (&wa, &wb)), (va, vb)) in line.iter_mut().zip(weights.0.iter().zip(weights.1)).zip(values) {
                *out = C32::new(
                    ((va.to_f64() - mean_a) * wa * scale) as f32,
                    ((vb.to_f64() - mean_b) * wb * scale) as f32,
                );
            }
        }
    }
}

/// Integer samples of 16 bits or fewer: exact in float32.
#[inline(always)]
fn narrow<T: Sample>() -> bool {
    T::IS_INT && std::mem::size_of::<T>() <= 2
}

/// The windowed, mean-free difference of two real tiles, as the real part of `z`.
fn fill_difference<A: Sample>(
    real: &[A],
    reference: &[A],
    cols: usize,
    (y0, x0): (usize, usize),
    window: &[f64],
    scale: f64,
    z: &mut [C32],
) {
    let n = (window.len() as f64).sqrt() as usize;
    let mean = tile_mean(real, cols, y0, x0, n) - tile_mean(reference, cols, y0, x0, n);
    for (y, (line, weights)) in z.chunks_exact_mut(n).zip(window.chunks_exact(n)).enumerate() {
        let row = (y0 + y) * cols + x0;
        let values = real[row..row + n].iter().zip(&reference[row..row + n]);
        for ((out, &w), (r, q)) in line.iter_mut().zip(weights).zip(values) {
            *out = C32::new(((r.to_f64() - q.to_f64() - mean) * w * scale) as f32, 0.0);
        }
    }
}

/// The power of two the mean-free values of float frames are multiplied by before their tiles
/// are transformed in float32, so their spectra neither overflow (frames of 1e36) nor flush to
/// zero (frames of 1e-30): about 1 / the real frame's RMS deviation, from a regular subsample of
/// its finite values; 1 for integer frames of 16 bits or fewer (exact in float32 as they are).
/// A power of two scales exactly, and the sums are returned in frame units.
fn scale_of<R: Sample, S: Sample>(frames: &Frames<'_, R, S>) -> f64 {
    if narrow::<R>() && narrow::<S>() {
        return 1.0;
    }
    let stride = (frames.real.len() / SCALE_SAMPLES).max(1);
    let (mut count, mut sum, mut squares) = (0.0f64, 0.0f64, 0.0f64);
    let finite = frames.real.iter().step_by(stride).map(|v| v.to_f64()).filter(|v| v.is_finite());
    let values: Vec<f64> = finite.collect();
    for &v in &values {
        count += 1.0;
        sum += v;
    }
    let mean = sum / count.max(1.0);
    for &v in &values {
        squares += (v - mean) * (v - mean);
    }
    let rms = (squares / count.max(1.0)).sqrt();
    if !(rms > 0.0 && rms.is_finite()) {
        return 1.0;
    }
    2f64.powi((-rms.log2().round()).clamp(-500.0, 500.0) as i32)
}

/// Values of the real frame [`scale_of`] draws.
const SCALE_SAMPLES: usize = 1024;

/// Welch sums of a frame pair over the tiles of `tiling`, computed in parallel, one group per
/// task.
pub fn tile_spectra<R: Sample, S: Sample>(frames: &Frames<'_, R, S>, tiling: Tiling) -> Result<TileSpectra> {
    let Tiling { tile, step, groups, shift } = tiling;
    check_frames(frames, "cross-spectra")?;
    if !(MIN_TILE..=MAX_TILE).contains(&tile) || tile % 2 != 0 {
        return Err(Error::Value(format!(
            "tile: expected an even number of pixels in {MIN_TILE}..={MAX_TILE}, got {tile}"
        )));
    }
    if groups == 0 {
        return Err(Error::Value("groups: expected at least 1".into()));
    }
    if step == 0 || step > tile {
        return Err(Error::Value(format!("step: expected 1..={tile} pixels (the tile), got {step}")));
    }
    let (rows, cols) = frames.shape;
    let corners: Vec<(usize, usize)> = starts(rows, tile, step)
        .into_iter()
        .flat_map(|y| starts(cols, tile, step).into_iter().map(move |x| (y, x)))
        .collect();
    let taper = hann(tile);
    let window = outer(&taper, &taper);
    let fft = PLANNER32.with(|p| p.borrow_mut().plan_fft_forward(tile));
    // the simulated tiles are taken at the whole-pixel part of the pair's displacement, so the
    // two tiles of a pair hold the same content, under a window moved by the rest; the tiles
    // align on the rest
    let offset = (shift.0.round() as i64, shift.1.round() as i64);
    let rest = (shift.0 - offset.0 as f64, shift.1 - offset.1 as f64);
    let sim_window = outer(&hann_moved(tile, rest.0), &hann_moved(tile, rest.1));
    let alignment = Alignment::new(tile, rest);
    let scale = scale_of(frames);
    let bins = tile * (tile / 2 + 1);
    let with_difference = frames.reference.is_some();
    let total = corners.len();
    let sums: Vec<(GroupSums, u64)> = budget::guard("cross-spectra", Error::Value, || {
        Ok((0..groups)
            .into_par_iter()
            .map(|g| {
                let mut sums = GroupSums::new(bins, with_difference, 1.0 / (scale * scale));
                let mut skipped = 0;
                let mut square = Square::new(fft.clone());
                let mut z = budget::filled(tile * tile, C32::default());
                for &(y0, x0) in &corners[g * total / groups..(g + 1) * total / groups] {
                    let at = moved((y0, x0), offset, frames.shape, tile);
                    if !usable(frames, (y0, x0), at, tile) {
                        skipped += 1;
                        continue;
                    }
                    let at = at.unwrap_or((y0, x0));
                    fill_pair(frames.real, frames.sim, cols, ((y0, x0), at), (&window, &sim_window), scale, &mut z);
                    square.forward(&mut z);
                    add_pair(&mut sums, &z, &alignment);
                    if let Some(reference) = frames.reference {
                        fill_difference(frames.real, reference, cols, (y0, x0), &window, scale, &mut z);
                        square.forward(&mut z);
                        sums.add_difference(&z, tile);
                    }
                    sums.tiles += 1;
                }
                sums.flush();
                (sums, skipped)
            })
            .collect())
    })?;
    let mut out = TileSpectra {
        tile,
        groups,
        tiles: Vec::with_capacity(groups),
        real: budget::try_with_capacity(groups * bins)?,
        sim: budget::try_with_capacity(groups * bins)?,
        cross_re: budget::try_with_capacity(groups * bins)?,
        cross_im: budget::try_with_capacity(groups * bins)?,
        difference: if with_difference { Some(budget::try_with_capacity(groups * bins)?) } else { None },
        window_energy: window.iter().map(|w| w * w).sum::<f64>(),
        skipped: 0,
        shifts: Vec::with_capacity(groups),
        offset,
        boxes: (0..groups)
            .map(|g| {
                let mine = &corners[g * total / groups..(g + 1) * total / groups];
                mine.iter().fold([usize::MAX, 0, usize::MAX, 0], |[r0, r1, c0, c1], &(y, x)| {
                    [r0.min(y), r1.max(y + tile), c0.min(x), c1.max(x + tile)]
                })
            })
            .map(|b| if b[0] == usize::MAX { [0, 0, 0, 0] } else { b })
            .collect(),
    };
    for (group, skipped) in sums {
        out.tiles.push(group.tiles);
        out.shifts.push(group.shifts);
        out.skipped += skipped;
        GroupSums::append_rows(&group.real, tile, &mut out.real);
        GroupSums::append_rows(&group.sim, tile, &mut out.sim);
        GroupSums::append_rows(&group.cross_re, tile, &mut out.cross_re);
        GroupSums::append_rows(&group.cross_im, tile, &mut out.cross_im);
        if let (Some(all), Some(part)) = (out.difference.as_mut(), group.difference.as_ref()) {
            GroupSums::append_rows(part, tile, all);
        }
    }
    Ok(out)
}

/// Block sums of both frames over the pixels scored and finite in both (`factor × factor`
/// blocks; the last partial row and column of blocks dropped), their counts, and the frames'
/// sums over all such pixels (partial blocks included): one pass, block rows in parallel.
struct Blocks {
    real: Vec<f64>,
    sim: Vec<f64>,
    counts: Vec<u32>,
    sum_real: f64,
    sum_sim: f64,
    pixels: u64,
}

/// The exact sum of integer samples.
#[inline(always)]
fn sum_of<T: Sample>(values: &[T]) -> i64 {
    values.iter().map(|v| v.to_i64()).sum()
}

/// One frame row's pixels into its block row's sums (`real`, `sim`, `counts`, one entry per
/// block) and into the totals (the row's pixels beyond the last whole block too).
#[inline(always)]
fn add_row<R: Sample, S: Sample>(
    (real, sim): (&[R], &[S]),
    keep: Option<&[bool]>,
    factor: usize,
    blocks: (&mut [f64], &mut [f64], &mut [u32]),
    totals: &mut (f64, f64, u64),
) {
    let whole = blocks.0.len() * factor;
    if keep.is_none() && R::IS_INT && S::IS_INT {
        // every pixel counts: exact integer sums per block, which vectorise
        let chunks = real[..whole].chunks_exact(factor).zip(sim[..whole].chunks_exact(factor));
        for (j, (r, s)) in chunks.enumerate() {
            let (r, s) = (sum_of(r) as f64, sum_of(s) as f64);
            blocks.0[j] += r;
            blocks.1[j] += s;
            blocks.2[j] += factor as u32;
        }
        totals.0 += sum_of(real) as f64;
        totals.1 += sum_of(sim) as f64;
        totals.2 += real.len() as u64;
        return;
    }
    if keep.is_none() && all_finite(real) && all_finite(sim) {
        // every pixel counts: plain sums per block, in the order of the general loop below
        let chunks = real[..whole].chunks_exact(factor).zip(sim[..whole].chunks_exact(factor));
        for (j, (r, s)) in chunks.enumerate() {
            let r = r.iter().fold(0.0, |sum, v| sum + v.to_f64());
            let s = s.iter().fold(0.0, |sum, v| sum + v.to_f64());
            blocks.0[j] += r;
            blocks.1[j] += s;
            blocks.2[j] += factor as u32;
            *totals = (totals.0 + r, totals.1 + s, totals.2 + factor as u64);
        }
        for (r, s) in real[whole..].iter().zip(&sim[whole..]) {
            *totals = (totals.0 + r.to_f64(), totals.1 + s.to_f64(), totals.2 + 1);
        }
        return;
    }
    // a pixel's values, 0 where it is not scored, and whether it is: no branch per pixel
    let scored = |i: usize| {
        let (r, s) = (real[i].to_f64(), sim[i].to_f64());
        let kept = keep.is_none_or(|k| k[i]) & (R::IS_INT || r.is_finite()) & (S::IS_INT || s.is_finite());
        if kept {
            (r, s, 1)
        } else {
            (0.0, 0.0, 0)
        }
    };
    for j in 0..blocks.0.len() {
        let (mut r, mut s, mut n) = (0.0, 0.0, 0u32);
        for i in j * factor..(j + 1) * factor {
            let (x, y, k) = scored(i);
            (r, s, n) = (r + x, s + y, n + k);
        }
        blocks.0[j] += r;
        blocks.1[j] += s;
        blocks.2[j] += n;
        *totals = (totals.0 + r, totals.1 + s, totals.2 + u64::from(n));
    }
    for i in whole..real.len() {
        let (x, y, k) = scored(i);
        *totals = (totals.0 + x, totals.1 + y, totals.2 + u64::from(k));
    }
}

/// The [`Blocks`] of a frame pair.
fn blocks<R: Sample, S: Sample>(frames: &Frames<'_, R, S>, factor: usize) -> Blocks {
    let (rows, cols) = frames.shape;
    let (out_rows, out_cols) = (rows / factor, cols / factor);
    // block row b takes frame rows b·factor.. (the last one also the rows below the last whole block)
    let block_row = |b: usize| {
        let (mut real, mut sim, mut counts) = (vec![0.0; out_cols], vec![0.0; out_cols], vec![0u32; out_cols]);
        let mut totals = (0.0, 0.0, 0u64);
        let end = if b + 1 == out_rows { rows } else { (b + 1) * factor };
        for y in b * factor..end {
            let span = y * cols..(y + 1) * cols;
            let keep = frames.mask.map(|m| &m[span.clone()]);
            let pair = (&frames.real[span.clone()], &frames.sim[span]);
            if y < out_rows * factor {
                add_row(pair, keep, factor, (&mut real, &mut sim, &mut counts), &mut totals);
            } else {
                add_row(pair, keep, factor, (&mut [], &mut [], &mut []), &mut totals);
            }
        }
        (real, sim, counts, totals)
    };
    let parts: Vec<_> = (0..out_rows).into_par_iter().map(block_row).collect();
    let mut out =
        Blocks { real: Vec::new(), sim: Vec::new(), counts: Vec::new(), sum_real: 0.0, sum_sim: 0.0, pixels: 0 };
    for (real, sim, counts, totals) in parts {
        out.real.extend(real);
        out.sim.extend(sim);
        out.counts.extend(counts);
        out.sum_real += totals.0;
        out.sum_sim += totals.1;
        out.pixels += totals.2;
    }
    out
}

/// The cross-spectrum of the block-mean frames: each reduced by `factor × factor` block means
/// over the pixels scored and finite in both (a block without one enters at the mean, i.e. as
/// zero after centring), centred,
/// Hann-windowed and transformed whole, in float64.
pub fn low_spectrum<R: Sample, S: Sample>(frames: &Frames<'_, R, S>, factor: usize) -> Result<LowSpectrum> {
    check_frames(frames, "low-frequency spectrum")?;
    let (rows, cols) = (frames.shape.0 / factor.max(1), frames.shape.1 / factor.max(1));
    if factor == 0 || rows < 4 || cols < 4 {
        return Err(Error::Value(format!(
            "low-frequency spectrum: blocks of {factor} px leave {rows} x {cols} of a {} x {} frame; expected at least 4 x 4",
            frames.shape.0, frames.shape.1
        )));
    }
    let Blocks { real, sim, counts, sum_real, sum_sim, pixels } = blocks(frames, factor);
    let empty = counts.iter().filter(|&&c| c == 0).count() as u64;
    if empty as usize == counts.len() {
        return Err(Error::Value("low-frequency spectrum: no scored, finite pixel".into()));
    }
    let used = (counts.len() - empty as usize) as f64;
    let mean =
        |v: &[f64]| v.iter().zip(&counts).filter(|(_, &c)| c > 0).map(|(x, &c)| x / c as f64).sum::<f64>() / used;
    let (mean_real, mean_sim) = (mean(&real), mean(&sim));
    let (w_rows, w_cols) = (hann(rows), hann(cols));
    let mut z: Vec<C64> = budget::try_collect(
        rows * cols,
        (0..rows * cols).map(|i| {
            let w = w_rows[i / cols] * w_cols[i % cols];
            if counts[i] > 0 {
                let c = counts[i] as f64;
                C64::new((real[i] / c - mean_real) * w, (sim[i] / c - mean_sim) * w)
            } else {
                C64::default()
            }
        }),
    )?;
    let (along_rows, along_cols) = PLANNER64.with(|p| {
        let mut planner = p.borrow_mut();
        (planner.plan_fft_forward(cols), planner.plan_fft_forward(rows))
    });
    along_rows.process(&mut z);
    let mut columns: Vec<C64> = budget::try_filled(rows * cols, C64::default())?;
    for y in 0..rows {
        for x in 0..cols {
            columns[x * rows + y] = z[y * cols + x];
        }
    }
    along_cols.process(&mut columns);
    let width = cols / 2 + 1;
    let mut out = LowSpectrum {
        rows,
        cols,
        factor,
        real: budget::try_filled(rows * width, 0.0)?,
        sim: budget::try_filled(rows * width, 0.0)?,
        cross_re: budget::try_filled(rows * width, 0.0)?,
        cross_im: budget::try_filled(rows * width, 0.0)?,
        empty,
        sum_real,
        sum_sim,
        pixels,
    };
    for kx in 0..width {
        for ky in 0..rows {
            let p = columns[kx * rows + ky];
            let q = columns[((cols - kx) % cols) * rows + (rows - ky) % rows].conj();
            let a = (p + q) * 0.5;
            let d = (p - q) * 0.5;
            let b = C64::new(d.im, -d.re);
            let cross = a.conj() * b;
            let i = ky * width + kx;
            out.real[i] = a.norm_sqr();
            out.sim[i] = b.norm_sqr();
            out.cross_re[i] = cross.re;
            out.cross_im[i] = cross.im;
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A seeded standard normal sequence (Box–Muller over a xorshift generator).
    fn normal(n: usize, seed: u64) -> Vec<f64> {
        let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
        let mut uniform = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        (0..n).map(|_| (-2.0 * uniform().ln()).sqrt() * (2.0 * std::f64::consts::PI * uniform()).cos()).collect()
    }

    /// A direct DFT of a windowed, mean-free tile at one frequency.
    fn dft(values: &[f64], cols: usize, (y0, x0): (usize, usize), tile: usize, (ky, kx): (usize, usize)) -> C64 {
        let window = hann(tile);
        let mean: f64 = (0..tile)
            .flat_map(|y| (0..tile).map(move |x| (y, x)))
            .map(|(y, x)| values[(y0 + y) * cols + x0 + x])
            .sum::<f64>()
            / (tile * tile) as f64;
        let mut sum = C64::default();
        for y in 0..tile {
            for x in 0..tile {
                let phase = -2.0 * std::f64::consts::PI * ((ky * y) as f64 + (kx * x) as f64) / tile as f64;
                sum += C64::from_polar((values[(y0 + y) * cols + x0 + x] - mean) * window[y] * window[x], phase);
            }
        }
        sum
    }

    #[test]
    fn one_tile_equals_a_direct_transform() {
        let (rows, cols, tile) = (16, 16, 16);
        let real = normal(rows * cols, 1);
        let sim: Vec<f64> = normal(rows * cols, 2).iter().zip(&real).map(|(n, r)| 0.5 * r + n).collect();
        let reference = normal(rows * cols, 3);
        let frames = Frames { real: &real, sim: &sim, reference: Some(&reference), mask: None, shape: (rows, cols) };
        let spectra = tile_spectra(&frames, Tiling { tile, step: tile / 2, groups: 1, shift: (0.0, 0.0) }).unwrap();
        assert_eq!(spectra.tiles, vec![1]);
        let width = tile / 2 + 1;
        let difference: Vec<f64> = real.iter().zip(&reference).map(|(a, b)| a - b).collect();
        for (ky, kx) in [(0, 0), (1, 0), (0, 3), (5, 2), (15, 8), (9, 7)] {
            let (a, b) = (dft(&real, cols, (0, 0), tile, (ky, kx)), dft(&sim, cols, (0, 0), tile, (ky, kx)));
            let d = dft(&difference, cols, (0, 0), tile, (ky, kx));
            let i = ky * width + kx;
            let close = |got: f64, want: f64| (got - want).abs() <= 1e-4 * (1.0 + want.abs());
            assert!(close(spectra.real[i], a.norm_sqr()), "{ky},{kx}: {} vs {}", spectra.real[i], a.norm_sqr());
            assert!(close(spectra.sim[i], b.norm_sqr()));
            // the cross-spectrum is turned by the tile's own displacement: its size is kept
            let turned = C64::new(spectra.cross_re[i], spectra.cross_im[i]);
            assert!(close(turned.norm(), (a.conj() * b).norm()));
            assert!(close(spectra.difference.as_ref().unwrap()[i], d.norm_sqr()));
        }
    }

    #[test]
    fn each_tile_is_aligned_on_its_own_displacement() {
        // a smooth random scene, the simulated frame displaced by (0.7, −1.3) px: aligned, the
        // cross-spectrum is real and positive at low frequencies, and the shifts say where it was
        let (rows, cols, tile) = (128, 128, 32);
        let noise = normal(rows * cols, 11);
        let smooth = |y: f64, x: f64| -> f64 {
            (0..60).map(|i| noise[i] * (1.2 * (y * noise[60 + i] + x * noise[120 + i]) + noise[180 + i]).sin()).sum()
        };
        let real: Vec<f64> = (0..rows * cols).map(|i| smooth((i / cols) as f64, (i % cols) as f64)).collect();
        let sim: Vec<f64> =
            (0..rows * cols).map(|i| smooth((i / cols) as f64 - 0.7, (i % cols) as f64 + 1.3)).collect();
        let frames = Frames::<f64, f64> { real: &real, sim: &sim, reference: None, mask: None, shape: (rows, cols) };
        // the pair's displacement known to 0.3 px: each tile finds the rest
        let spectra = tile_spectra(&frames, Tiling { tile, step: tile / 2, groups: 1, shift: (0.5, -1.0) }).unwrap();
        let [w, wy, wx, _, _] = spectra.shifts[0];
        let (oy, ox) = (spectra.offset.0 as f64, spectra.offset.1 as f64);
        assert_eq!(spectra.offset, (1, -1)); // the whole-pixel part of (0.5, −1.0)
        assert!((oy + wy / w - 0.7).abs() < 0.03 && (ox + wx / w + 1.3).abs() < 0.03, "{} {}", wy / w, wx / w);
        let width = tile / 2 + 1;
        for (ky, kx) in [(3, 0), (0, 3), (2, 3), (4, 4)] {
            let i = ky * width + kx;
            let (re, im) = (spectra.cross_re[i], spectra.cross_im[i]);
            assert!(re > 0.0 && im.abs() < 0.3 * re, "{ky},{kx}: {re} {im}");
        }
    }

    #[test]
    fn white_noise_has_a_flat_spectrum_and_groups_are_disjoint() {
        let (rows, cols, tile) = (256, 192, 32);
        let real = normal(rows * cols, 7);
        let sim: Vec<f64> = real.iter().map(|v| 2.0 * v).collect();
        let frames = Frames::<f64, f64> { real: &real, sim: &sim, reference: None, mask: None, shape: (rows, cols) };
        let spectra = tile_spectra(&frames, Tiling { tile, step: tile / 2, groups: 4, shift: (0.0, 0.0) }).unwrap();
        let per_axis = |len: usize| (len - tile) / (tile / 2) + 1;
        assert_eq!(spectra.tiles.iter().sum::<u64>() as usize, per_axis(rows) * per_axis(cols));
        let bins = tile * (tile / 2 + 1);
        let tiles: f64 = spectra.tiles.iter().sum::<u64>() as f64;
        // away from DC (where the mean was removed), E|R|² = σ²·Σw²
        let mean: f64 = (0..spectra.groups)
            .flat_map(|g| (bins / 4..bins).map(move |i| g * bins + i))
            .map(|i| spectra.real[i])
            .sum::<f64>()
            / (tiles * (bins - bins / 4) as f64);
        assert!((mean / spectra.window_energy - 1.0).abs() < 0.03, "{}", mean / spectra.window_energy);
        // S = 2R: |S|² = 4|R|², conj(R)S = 2|R|², exactly up to float32 rounding
        for i in 0..spectra.real.len() {
            assert!((spectra.sim[i] - 4.0 * spectra.real[i]).abs() <= 1e-4 * spectra.sim[i] + 1e-9);
            assert!((spectra.cross_re[i] - 2.0 * spectra.real[i]).abs() <= 1e-4 * spectra.sim[i] + 1e-9);
        }
    }

    #[test]
    fn masked_and_nonfinite_tiles_are_skipped() {
        let (rows, cols, tile) = (64, 64, 16);
        let real: Vec<u16> = (0..rows * cols).map(|i| (i % 97) as u16).collect();
        let mut sim: Vec<f32> = real.iter().map(|&v| v as f32).collect();
        sim[5] = f32::NAN; // in the first tile only
        let mut mask = vec![true; rows * cols];
        mask[rows * cols - 1] = false; // in the last tile only
        let frames = Frames { real: &real, sim: &sim, reference: None, mask: Some(&mask), shape: (rows, cols) };
        let spectra = tile_spectra(&frames, Tiling { tile, step: tile / 2, groups: 3, shift: (0.0, 0.0) }).unwrap();
        assert_eq!(spectra.skipped, 2);
        assert_eq!(spectra.tiles.iter().sum::<u64>(), 7 * 7 - 2);
        assert!(spectra.real.iter().chain(&spectra.cross_re).all(|v| v.is_finite()));
        let small =
            Frames::<u16, f32> { real: &real[..64], sim: &sim[..64], reference: None, mask: None, shape: (8, 8) };
        assert_eq!(
            tile_spectra(&small, Tiling { tile: 16, step: 8, groups: 2, shift: (0.0, 0.0) }).unwrap().tiles,
            vec![0, 0]
        );
        assert!(tile_spectra(&frames, Tiling { tile: 7, step: 3, groups: 2, shift: (0.0, 0.0) }).is_err());
        let wrong =
            Frames::<u16, f32> { real: &real, sim: &sim[..10], reference: None, mask: None, shape: (rows, cols) };
        assert!(matches!(
            tile_spectra(&wrong, Tiling { tile: 16, step: 8, groups: 2, shift: (0.0, 0.0) }),
            Err(Error::Shape(_))
        ));
    }

    #[test]
    fn the_low_spectrum_sees_a_gain() {
        let (rows, cols) = (96, 128);
        let real: Vec<f64> =
            (0..rows * cols).map(|i| ((i / cols) as f64 / 9.0).sin() * 50.0 + (i % cols) as f64).collect();
        let sim: Vec<f64> = real.iter().map(|v| 1.5 * v + 7.0).collect();
        let frames = Frames::<f64, f64> { real: &real, sim: &sim, reference: None, mask: None, shape: (rows, cols) };
        let low = low_spectrum(&frames, 4).unwrap();
        assert_eq!((low.rows, low.cols, low.empty), (24, 32, 0));
        for i in 0..low.real.len() {
            assert!((low.cross_re[i] - 1.5 * low.real[i]).abs() <= 1e-9 * (1.0 + low.real[i]));
            assert!(low.cross_im[i].abs() <= 1e-9 * (1.0 + low.real[i]));
        }
        assert!(low_spectrum(&frames, 40).is_err());
    }
}
