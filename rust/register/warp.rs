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
use super::bands;
use super::image::lane_sum_range;
use crate::budget;
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
    /// The value at `(r, c)`, or `None` outside the frame, masked or not finite.
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

    /// For each source row, the longest run `[lo, hi)` of usable pixels (not masked and, for
    /// floats, finite): taps within it need no check beyond the bounds.
    fn clean_spans(&self) -> Vec<(usize, usize)> {
        if self.valid.is_none() && T::IS_INT {
            return vec![(0, self.cols); self.rows];
        }
        (0..self.rows)
            .map(|r| {
                // a row of finite values, unmasked (the common case), in one vectorised pass: the
                // sum of finite values is finite (rows near ±1e308 take the loop below)
                if self.valid.is_none() && lane_sum_range(&self.data[r * self.cols..(r + 1) * self.cols]).0.is_finite()
                {
                    return (0, self.cols);
                }
                let usable = |c: usize| {
                    let i = r * self.cols + c;
                    self.valid.is_none_or(|m| m[i]) && (T::IS_INT || self.data[i].to_f64().is_finite())
                };
                let (mut best, mut start) = ((0, 0), 0);
                for c in 0..=self.cols {
                    if c == self.cols || !usable(c) {
                        if c - start > best.1 - best.0 {
                            best = (start, c);
                        }
                        start = c + 1;
                    }
                }
                best
            })
            .collect()
    }
}

/// Whether the `n × n` block of taps at `(x0, y0)` lies in the clean spans of its rows.
#[inline(always)]
fn block_clean(spans: &[(usize, usize)], x0: isize, y0: isize, n: usize) -> bool {
    x0 >= 0
        && y0 >= 0
        && (y0 as usize + n) <= spans.len()
        && spans[y0 as usize..y0 as usize + n].iter().all(|&(lo, hi)| lo <= x0 as usize && x0 as usize + n <= hi)
}

/// Weights of the taps at offsets −1, 0, 1, 2 from `floor(x)` for the fraction `t`.
#[inline]
fn cubic_weights(t: f64) -> [f64; 4] {
    // Keys (1981), a = −0.5.
    let t2 = t * t;
    let t3 = t2 * t;
    [-0.5 * t3 + t2 - 0.5 * t, 1.5 * t3 - 2.5 * t2 + 1.0, -1.5 * t3 + 2.0 * t2 + 0.5 * t, 0.5 * t3 - 0.5 * t2]
}

/// `(floor(v), v − floor(v))` with the fraction snapped to 0 within [`SNAP`] of an integer.
/// (`as i64` truncates in one instruction; `f64::floor` is a library call on baseline x86-64.)
#[inline(always)]
fn split(v: f64) -> (isize, f64) {
    let mut i = v as i64;
    if (i as f64) > v {
        i -= 1;
    }
    let t = v - i as f64;
    if t < SNAP {
        (i as isize, 0.0)
    } else if t > 1.0 - SNAP {
        (i as isize + 1, 0.0)
    } else {
        (i as isize, t)
    }
}

/// Interpolation weights of one axis: the first tap's offset from `floor(x)` and the
/// weights of the `N` taps.
trait Kernel<const N: usize> {
    const FIRST: isize;
    fn weights(t: f64) -> [f64; N];
}

struct Linear;
impl Kernel<2> for Linear {
    const FIRST: isize = 0;
    #[inline(always)]
    fn weights(t: f64) -> [f64; 2] {
        [1.0 - t, t]
    }
}

struct Cubic;
impl Kernel<4> for Cubic {
    const FIRST: isize = -1;
    #[inline(always)]
    fn weights(t: f64) -> [f64; 4] {
        cubic_weights(t)
    }
}

/// `Σ_j wy[j] Σ_i wx[i]·src[start + j·cols + i]`: the taps of an N×N block whose top-left
/// sample is `start`, all inside the frame.
#[inline(always)]
fn block_sum<T: Sample, const N: usize>(src: &Source<'_, T>, start: usize, wx: &[f64; N], wy: &[f64; N]) -> f64 {
    let mut acc = 0.0;
    for (j, &w) in wy.iter().enumerate() {
        let row = &src.data[start + j * src.cols..start + j * src.cols + N];
        let mut line = 0.0;
        for (v, &u) in row.iter().zip(wx) {
            line += u * v.to_f64();
        }
        acc += w * line;
    }
    acc
}

/// One interpolated value at source position `(x, y)`, or `None` if a tap with a non-zero
/// weight is missing. Taps within the clean spans of their rows need no other check.
#[inline(always)]
fn sample<T: Sample, K: Kernel<N>, const N: usize>(
    src: &Source<'_, T>,
    x: f64,
    y: f64,
    clean: &[(usize, usize)],
) -> Option<f64> {
    let ((ix, tx), (iy, ty)) = (split(x), split(y));
    let (wx, wy) = (K::weights(tx), K::weights(ty));
    let (x0, y0) = (ix + K::FIRST, iy + K::FIRST);
    if block_clean(clean, x0, y0, N) {
        // every tap present: no per-tap checks
        return Some(block_sum(src, y0 as usize * src.cols + x0 as usize, &wx, &wy));
    }
    let mut acc = 0.0;
    for (j, &w) in wy.iter().enumerate() {
        if w == 0.0 {
            continue;
        }
        let mut line = 0.0;
        for (i, &u) in wx.iter().enumerate() {
            if u != 0.0 {
                line += u * src.tap(y0 + j as isize, x0 + i as isize)?;
            }
        }
        acc += w * line;
    }
    Some(acc)
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
    let mut values = budget::filled(out_rows * out_cols, fill);
    let mut valid = budget::filled(out_rows * out_cols, false);
    warp_into(src, to_source, interp, out_cols, fill, &mut values, &mut valid);
    (values, valid)
}

/// [`warp`] into existing buffers (row-major, `out_cols` wide), every pixel written.
pub fn warp_into<T: Sample>(
    src: &Source<'_, T>,
    to_source: &Affine,
    interp: Interp,
    out_cols: usize,
    fill: f64,
    values: &mut [f64],
    valid: &mut [bool],
) {
    let clean = src.clean_spans();
    bands::fill_bands(values, valid, out_cols, |first, v, ok| match interp {
        Interp::Bilinear => rows_with::<T, Linear, 2>(src, to_source, first, out_cols, fill, &clean, v, ok),
        Interp::Bicubic => rows_with::<T, Cubic, 4>(src, to_source, first, out_cols, fill, &clean, v, ok),
    });
}

/// Output rows from `first` on (as many as `values` holds).
#[allow(clippy::too_many_arguments)]
fn rows_with<T: Sample, K: Kernel<N>, const N: usize>(
    src: &Source<'_, T>,
    to_source: &Affine,
    first: usize,
    out_cols: usize,
    fill: f64,
    clean: &[(usize, usize)],
    values: &mut [f64],
    valid: &mut [bool],
) {
    let m = &to_source.0;
    let shift_only = m[0][0] == 1.0 && m[0][1] == 0.0 && m[1][0] == 0.0 && m[1][1] == 1.0;
    let all_clean = clean.iter().all(|&span| span == (0, src.cols));
    let mut lines = shift_only.then(|| Lines::<N>::new::<K>(m[0][2], src.cols, out_cols));
    for (k, (out, ok)) in values.chunks_mut(out_cols.max(1)).zip(valid.chunks_mut(out_cols.max(1))).enumerate() {
        let r = first + k;
        let (x0, y0) = (m[0][1] * r as f64 + m[0][2], m[1][1] * r as f64 + m[1][2]);
        let interior = if let Some(lines) = lines.as_mut() {
            shifted_row::<T, K, N>(src, lines, y0, clean, out, ok)
        } else if all_clean {
            inside_row::<T, K, N>(src, (x0, y0), (m[0][0], m[1][0]), out, ok)
        } else {
            (0, 0)
        };
        for c in (0..interior.0).chain(interior.1.max(interior.0)..out.len()) {
            let (x, y) = (x0 + m[0][0] * c as f64, y0 + m[1][0] * c as f64);
            (out[c], ok[c]) = match sample::<T, K, N>(src, x, y, clean) {
                Some(s) => (s, true),
                None => (fill, false),
            };
        }
    }
}

/// A row `out(c) = src(x0 + a·c, y0 + b·c)` of a source with every pixel usable: the
/// columns whose taps surely all lie inside the frame (a margin beyond the snapping of
/// [`split`]) are interpolated without per-tap checks. Returns that column range; the caller
/// does the others.
fn inside_row<T: Sample, K: Kernel<N>, const N: usize>(
    src: &Source<'_, T>,
    (x0, y0): (f64, f64),
    (a, b): (f64, f64),
    out: &mut [f64],
    ok: &mut [bool],
) -> (usize, usize) {
    const MARGIN: f64 = 1e-6;
    // floor(x) + FIRST ≥ 0 and floor(x) + FIRST + N ≤ cols, likewise for y
    let inside = |start: f64, step: f64, n: usize| {
        let lo = -(K::FIRST as f64) + MARGIN;
        let hi = n as f64 - N as f64 - K::FIRST as f64 + 1.0 - MARGIN;
        axis_range(start, step, lo, hi, out.len())
    };
    let (ax, bx) = inside(x0, a, src.cols);
    let (ay, by) = inside(y0, b, src.rows);
    let (lo, hi) = (ax.max(ay), bx.min(by));
    if lo >= hi {
        return (0, 0);
    }
    for (c, slot) in (lo..hi).zip(&mut out[lo..hi]) {
        let ((ix, tx), (iy, ty)) = (split(x0 + a * c as f64), split(y0 + b * c as f64));
        let (wx, wy) = (K::weights(tx), K::weights(ty));
        let start = (iy + K::FIRST) as usize * src.cols + (ix + K::FIRST) as usize;
        *slot = block_sum(src, start, &wx, &wy);
    }
    ok[lo..hi].iter_mut().for_each(|f| *f = true);
    (lo, hi)
}

/// The source rows of a pure translation filtered along x: `line(y)[c] = Σ_i wx[i]·src(y,
/// first_x + c + i)` for the columns `c` whose taps all lie inside the frame. A translation
/// has the same x weights on every row, so each source row is filtered once and shared by
/// the `N` output rows that read it (kept in a ring of `N` rows), and an output row is `N`
/// scaled filtered rows: `2N` multiply-adds per pixel instead of `N²`. The sums run in the
/// order of [`block_sum`], so a pixel has the same value on either path.
struct Lines<const N: usize> {
    first_x: isize,
    wx: [f64; N],
    /// Columns `[lo, hi)` with every tap inside the frame.
    cols: (usize, usize),
    /// Which source row each ring slot holds.
    held: [Option<usize>; N],
    data: Vec<f64>,
    width: usize,
}

impl<const N: usize> Lines<N> {
    fn new<K: Kernel<N>>(x0: f64, src_cols: usize, width: usize) -> Self {
        let (ix, tx) = split(x0);
        let first_x = ix + K::FIRST;
        let lo = (-first_x).clamp(0, width as isize) as usize;
        let hi = (src_cols as isize - N as isize + 1 - first_x).clamp(lo as isize, width as isize) as usize;
        let data = budget::filled(N * width, 0.0);
        Lines { first_x, wx: K::weights(tx), cols: (lo, hi), held: [None; N], data, width }
    }

    /// Filter source row `y` into its slot unless the slot holds it already.
    fn load<T: Sample>(&mut self, src: &Source<'_, T>, y: usize) {
        let slot = y % N;
        if self.held[slot] != Some(y) {
            let (lo, hi) = self.cols;
            let start = y * src.cols + (self.first_x + lo as isize) as usize;
            let taps = &src.data[start..start + (hi - lo) + N - 1];
            let wx = self.wx;
            filter_line(&mut self.line_mut(slot)[lo..hi], taps, &wx);
            self.held[slot] = Some(y);
        }
    }

    fn line_mut(&mut self, slot: usize) -> &mut [f64] {
        &mut self.data[slot * self.width..(slot + 1) * self.width]
    }

    /// Columns `[lo, hi)` of the filtered source row `y` (loaded before).
    fn line(&self, y: usize, (lo, hi): (usize, usize)) -> &[f64] {
        let slot = y % N;
        debug_assert_eq!(self.held[slot], Some(y));
        &self.data[slot * self.width + lo..slot * self.width + hi]
    }
}

avx2_copy! {
    /// `line[c] = Σ_i w[i]·taps[c + i]` (zero weights skipped).
    fn filter_line[T: Sample, const N: usize](line: &mut [f64], taps: &[T], w: &[f64; N])
    => filter_line_avx2, filter_line_impl
}

#[inline(always)]
fn filter_line_impl<T: Sample, const N: usize>(line: &mut [f64], taps: &[T], w: &[f64; N]) {
    line.iter_mut().for_each(|v| *v = 0.0);
    for (i, &wi) in w.iter().enumerate() {
        if wi != 0.0 {
            for (o, s) in line.iter_mut().zip(&taps[i..]) {
                *o += wi * s.to_f64();
            }
        }
    }
}

avx2_copy! {
    /// `out[c] = Σ_j w[j]·lines[j][c]` (zero weights skipped).
    fn combine_lines[const N: usize](out: &mut [f64], lines: [&[f64]; N], w: &[f64; N])
    => combine_lines_avx2, combine_lines_impl
}

#[inline(always)]
fn combine_lines_impl<const N: usize>(out: &mut [f64], lines: [&[f64]; N], w: &[f64; N]) {
    out.iter_mut().for_each(|v| *v = 0.0);
    for (line, &wj) in lines.iter().zip(w) {
        if wj != 0.0 {
            for (o, &v) in out.iter_mut().zip(*line) {
                *o += wj * v;
            }
        }
    }
}

/// A row of a pure translation `out(c) = src(x0 + c, y0)`: the columns whose taps all lie
/// in the clean spans of their source rows are combined from the filtered rows of `lines`
/// (vectorised). Returns that column range; the caller does the others.
fn shifted_row<T: Sample, K: Kernel<N>, const N: usize>(
    src: &Source<'_, T>,
    lines: &mut Lines<N>,
    y0: f64,
    clean: &[(usize, usize)],
    out: &mut [f64],
    ok: &mut [bool],
) -> (usize, usize) {
    let (iy, ty) = split(y0);
    let first_y = iy + K::FIRST;
    if first_y < 0 || first_y + N as isize > src.rows as isize {
        return (0, 0);
    }
    let first_y = first_y as usize;
    // columns c whose taps first_x + c .. first_x + c + N lie in every source row's clean span
    let (mut lo, mut hi) = (lines.cols.0 as isize, lines.cols.1 as isize);
    for &(span_lo, span_hi) in &clean[first_y..first_y + N] {
        lo = lo.max(span_lo as isize - lines.first_x);
        hi = hi.min(span_hi as isize - N as isize - lines.first_x + 1);
    }
    if lo >= hi {
        return (0, 0);
    }
    let (lo, hi) = (lo as usize, hi as usize);
    let wy = K::weights(ty);
    // rows of zero weight are skipped by the sum; any loaded row stands in for them
    let weighted = |j: usize| if wy.iter().any(|&w| w != 0.0) { wy[j] != 0.0 } else { j == 0 };
    let first_weighted = (0..N).find(|&j| weighted(j)).unwrap_or(0);
    for j in (0..N).filter(|&j| weighted(j)) {
        lines.load(src, first_y + j);
    }
    let rows: [&[f64]; N] =
        std::array::from_fn(|j| lines.line(first_y + if weighted(j) { j } else { first_weighted }, (lo, hi)));
    combine_lines(&mut out[lo..hi], rows, &wy);
    ok[lo..hi].iter_mut().for_each(|f| *f = true);
    (lo, hi)
}

/// How many output pixels [`warp`] would compute (the overlap of the warped source with the
/// output grid), without interpolating or allocating an image.
/// `valid` is the source's mask (`None`: every pixel usable).
pub fn coverage(
    (rows, cols): (usize, usize),
    valid: Option<&[bool]>,
    to_source: &Affine,
    interp: Interp,
    (out_rows, out_cols): (usize, usize),
) -> usize {
    let zeros = budget::filled(rows * cols, 0u8); // any integer samples: only validity matters
    let src = Source { data: &zeros[..], rows, cols, valid };
    match interp {
        Interp::Bilinear => coverage_with::<Linear, 2>(&src, to_source, out_rows, out_cols),
        Interp::Bicubic => coverage_with::<Cubic, 4>(&src, to_source, out_rows, out_cols),
    }
}

fn coverage_with<K: Kernel<N>, const N: usize>(
    src: &Source<'_, u8>,
    m: &Affine,
    out_rows: usize,
    out_cols: usize,
) -> usize {
    let clean = src.clean_spans();
    let m = &m.0;
    let covered = |x: f64, y: f64| {
        let ((ix, tx), (iy, ty)) = (split(x), split(y));
        let (x0, y0) = (ix + K::FIRST, iy + K::FIRST);
        if block_clean(&clean, x0, y0, N) {
            return true;
        }
        let (wx, wy) = (K::weights(tx), K::weights(ty));
        wy.iter().enumerate().all(|(j, &w)| {
            w == 0.0
                || wx.iter().enumerate().all(|(i, &u)| u == 0.0 || src.tap(y0 + j as isize, x0 + i as isize).is_some())
        })
    };
    let all_valid = src.valid.is_none();
    let counts = bands::map_bands(out_rows, out_cols, |lo, hi| {
        let mut n = 0usize;
        for r in lo..hi {
            let (x0, y0) = (m[0][1] * r as f64 + m[0][2], m[1][1] * r as f64 + m[1][2]);
            let at = |c: usize| covered(x0 + m[0][0] * c as f64, y0 + m[1][0] * c as f64);
            if !all_valid {
                n += (0..out_cols).filter(|&c| at(c)).count();
                continue;
            }
            // A fully valid source covers a convex set: every pixel whose position lies
            // a tap's reach inside the frame (`inner`) is covered; only those between that
            // and the frame's edge (`outer`) need the exact test.
            let line = |lo: f64, hi: f64| {
                let (ax, bx) = axis_range(x0, m[0][0], lo, src.cols as f64 - 1.0 - lo + hi, out_cols);
                let (ay, by) = axis_range(y0, m[1][0], lo, src.rows as f64 - 1.0 - lo + hi, out_cols);
                (ax.max(ay), bx.min(by))
            };
            let reach = (N / 2) as f64 - 1.0; // taps beyond the centre pixel: 0 bilinear, 1 bicubic
            let (inner_lo, inner_hi) = line(reach + 1e-6, -1e-6);
            let (outer_lo, outer_hi) = line(-1e-6, 1e-6 + 1.0);
            if inner_lo < inner_hi {
                n += inner_hi - inner_lo;
                n += (outer_lo..inner_lo.max(outer_lo)).filter(|&c| at(c)).count();
                n += (inner_hi.min(outer_hi)..outer_hi).filter(|&c| at(c)).count();
            } else {
                n += (outer_lo..outer_hi).filter(|&c| at(c)).count();
            }
        }
        n
    });
    counts.iter().sum()
}

/// Integer `c` in `[0, n)` with `lo ≤ start + step·c ≤ hi`, as a half-open range (empty:
/// `lo ≥ hi`).
fn axis_range(start: f64, step: f64, lo: f64, hi: f64, n: usize) -> (usize, usize) {
    if step == 0.0 {
        return if (lo..=hi).contains(&start) { (0, n) } else { (0, 0) };
    }
    let (a, b) = ((lo - start) / step, (hi - start) / step);
    let (a, b) = if a <= b { (a, b) } else { (b, a) };
    let first = a.ceil().max(0.0);
    let last = b.floor().min(n as f64 - 1.0);
    if last < first {
        (0, 0)
    } else {
        (first as usize, last as usize + 1)
    }
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
    fn coverage_counts_the_valid_pixels_of_a_warp() {
        let data = ramp(40, 50);
        let mut mask = vec![true; 40 * 50];
        mask[20 * 50 + 20] = false;
        for valid in [None, Some(&mask[..])] {
            let src = Source { data: &data[..], rows: 40, cols: 50, valid };
            for m in [
                Affine::translation(3.0, -2.0),
                Affine::translation(0.37, 5.5),
                Affine::rotation_scale(7.0, 1.05, (20.0, 25.0)).compose(&Affine::translation(1.2, -0.4)),
                Affine::rotation_scale(-90.0, 1.0, (24.5, 19.5)),
            ] {
                for interp in [Interp::Bilinear, Interp::Bicubic] {
                    let (_, ok) = warp(&src, &m, interp, 40, 50, 0.0);
                    let want = ok.iter().filter(|&&v| v).count();
                    assert_eq!(coverage((40, 50), valid, &m, interp, (40, 50)), want, "{m:?} {interp:?}");
                }
            }
        }
    }

    #[test]
    fn unchecked_interior_matches_the_checked_taps() {
        let (rows, cols) = (30, 40);
        let data: Vec<f64> = (0..rows * cols).map(|i| ((i * 7919) % 97) as f64).collect();
        // one masked corner pixel sends every row through the checked path
        let mut mask = vec![true; rows * cols];
        mask[0] = false;
        let w = Affine::rotation_scale(-5.0, 0.97, (19.5, 14.5)).compose(&Affine::translation(0.4, 1.3));
        for interp in [Interp::Bilinear, Interp::Bicubic] {
            let fast = warp(&Source { data: &data[..], rows, cols, valid: None }, &w, interp, rows, cols, 0.0);
            let checked =
                warp(&Source { data: &data[..], rows, cols, valid: Some(&mask) }, &w, interp, rows, cols, 0.0);
            for i in 0..rows * cols {
                if checked.1[i] {
                    assert!(fast.1[i] && fast.0[i] == checked.0[i], "{interp:?} pixel {i}");
                }
            }
            let extra = (0..rows * cols).filter(|&i| fast.1[i] && !checked.1[i]).count();
            assert!(extra <= 16, "{interp:?}: only pixels reading the masked corner differ");
        }
    }

    /// What a translation's output pixel `(r, c)` must hold: the direct `N × N` sum with the
    /// row's weights where every tap is clean, `sample` elsewhere.
    fn direct<T: Sample, K: Kernel<N>, const N: usize>(
        src: &Source<'_, T>,
        m: &Affine,
        r: usize,
        c: usize,
    ) -> Option<f64> {
        let clean = src.clean_spans();
        let (x0, y0) = (m.0[0][2], r as f64 + m.0[1][2]);
        let ((ix, tx), (iy, ty)) = (split(x0), split(y0));
        let (first_x, first_y) = (ix + K::FIRST + c as isize, iy + K::FIRST);
        if block_clean(&clean, first_x, first_y, N) {
            let start = first_y as usize * src.cols + first_x as usize;
            return Some(block_sum(src, start, &K::weights(tx), &K::weights(ty)));
        }
        sample::<T, K, N>(src, x0 + c as f64, y0, &clean)
    }

    #[test]
    fn translation_rows_match_the_direct_sum() {
        // the filtered-row path of a translation gives every pixel the value (bit for bit)
        // and validity of the direct sum: integer and float sources, NaN and masked taps
        let (rows, cols) = (70, 45); // more than one band of rows
        let ints: Vec<u16> = (0..rows * cols).map(|i| ((i * 7919 + 13) % 4093) as u16).collect();
        let mut floats: Vec<f64> = ints.iter().map(|&v| v as f64 * 0.37 - 50.0).collect();
        floats[10 * cols + 20] = f64::NAN;
        floats[40 * cols] = f64::INFINITY;
        let mut mask = vec![true; rows * cols];
        mask[33 * cols + 7] = false;
        let shifts = [(0.3, -1.7), (-2.0, 3.0), (12.6, 0.45), (-0.5, -0.5), (1e-10, 2.0 - 1e-10), (44.2, 3.1)];
        fn compare<T: Sample>(src: &Source<'_, T>, m: &Affine, interp: Interp) {
            let (values, valid) = warp(src, m, interp, src.rows, src.cols, -1.0);
            for r in 0..src.rows {
                for c in 0..src.cols {
                    let want = match interp {
                        Interp::Bilinear => direct::<T, Linear, 2>(src, m, r, c),
                        Interp::Bicubic => direct::<T, Cubic, 4>(src, m, r, c),
                    };
                    let got = valid[r * src.cols + c].then_some(values[r * src.cols + c]);
                    assert_eq!(got.map(f64::to_bits), want.map(f64::to_bits), "{interp:?} {m:?} at ({r}, {c})");
                }
            }
        }
        for (dx, dy) in shifts {
            for interp in [Interp::Bilinear, Interp::Bicubic] {
                let m = Affine::translation(dx, dy);
                compare(&Source { data: &ints[..], rows, cols, valid: Some(&mask) }, &m, interp);
                compare(&Source { data: &floats[..], rows, cols, valid: None }, &m, interp);
            }
        }
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
