//! The Gaussian window and the separable filtering of one band of moment images.
//!
//! A band's input rows (its output rows and `radius` reflected rows either side) become the
//! four moment images x, y, x² + y², x·y, with x and y centred on the band's pivots. Each output
//! row is then filtered along columns (over its 2·radius + 1 input rows) and along its row,
//! with reflected borders: scipy.ndimage's `gaussian_filter(..., mode="reflect")`, the filter
//! of scikit-image's `structural_similarity(..., gaussian_weights=True)`, in the same order of
//! axes and of taps.

use crate::budget;
use crate::kernel::Sample;

/// Number of moment images: x, y, x² + y², x·y. SSIM needs the two variances only as their
/// sum, and filtering is linear: one image of x² + y² instead of two.
pub(crate) const MOMENTS: usize = 4;

/// Columns filtered together, in registers (four AVX2 vectors of float64).
const LANES: usize = 16;

/// A symmetric window: `taps[k]` weighs the pixels `k` away from the centre.
#[derive(Clone, Debug)]
pub(crate) struct Window {
    pub taps: Vec<f64>,
}

impl Window {
    /// Gaussian weights `exp(−x²/2σ²)` for `x = −radius..=radius`, divided by their sum
    /// (scipy.ndimage's kernel). Written `−(x/σ)²/2`, so a tiny σ gives the weights (1, 0, …)
    /// rather than 0·∞.
    pub fn gaussian(sigma: f64, radius: usize) -> Window {
        let r = radius as i64;
        let full: Vec<f64> = (-r..=r).map(|x| (-0.5 * (x as f64 / sigma).powi(2)).exp()).collect();
        let sum: f64 = full.iter().sum();
        Window { taps: full[radius..].iter().map(|w| w / sum).collect() }
    }

    pub fn radius(&self) -> usize {
        self.taps.len() - 1
    }
}

/// Index `i` reflected into `0..n` with the edge pixel repeated (scipy.ndimage `reflect`:
/// d c b a | a b c d | d c b a). Valid for `−n ≤ i < 2n`.
#[inline]
pub(crate) fn reflect(i: isize, n: usize) -> usize {
    let n = n as isize;
    (if i < 0 {
        -i - 1
    } else if i >= n {
        2 * n - i - 1
    } else {
        i
    }) as usize
}

/// Columns of a strip filtered along columns for every output row of a band before the next
/// strip: the strip's 2·radius + 1 input rows of one image stay in L1 from one output row to
/// the next.
const STRIP: usize = 256;

/// Per-thread buffers for one band.
#[derive(Default)]
pub(crate) struct Scratch {
    /// The moment images of the band's input rows: image `m`, input row `j` at
    /// `(m · in_rows + j) · cols`.
    products: Vec<f64>,
    /// The same images filtered along columns, for the band's output rows: image `m`, output
    /// row `i` at `(m · out_rows + i) · cols`.
    columns: Vec<f64>,
    out_rows: usize,
    /// One row of `columns` with `radius` reflected values either side.
    padded: Vec<f64>,
    /// The local (windowed) moments of one output row: moment `m` at `m · cols`.
    pub local: Vec<f64>,
}

/// A band of output rows `y0..y1` of a `rows × cols` frame pair.
pub(crate) struct Band<'a, T> {
    pub real: &'a [T],
    pub sim: &'a [T],
    pub rows: usize,
    pub cols: usize,
    pub y0: usize,
    pub y1: usize,
    /// Subtracted from every value of each frame (exact for integer and float32 samples).
    pub pivots: (f64, f64),
}

impl<T: Sample> Band<'_, T> {
    /// The moment images of the band's input rows (reflected at the frame's edges), filtered
    /// along columns into `scratch.columns`.
    #[inline(always)]
    pub fn filter_columns(&self, window: &Window, scratch: &mut Scratch) {
        let (cols, r) = (self.cols, window.radius());
        let (out_rows, in_rows) = (self.y1 - self.y0, self.y1 - self.y0 + 2 * r);
        self.load(r, in_rows, &mut scratch.products);
        scratch.out_rows = out_rows;
        budget::resize(&mut scratch.columns, MOMENTS * out_rows * cols, 0.0);
        let (in_plane, out_plane) = (in_rows * cols, out_rows * cols);
        for s0 in (0..cols).step_by(STRIP) {
            let width = STRIP.min(cols - s0);
            for m in 0..MOMENTS {
                let image = &scratch.products[m * in_plane..(m + 1) * in_plane];
                for i in 0..out_rows {
                    let at = m * out_plane + i * cols + s0;
                    // input rows i..=i + 2r, centre i + r
                    symmetric_filter(
                        &window.taps,
                        image,
                        (i + r) * cols + s0,
                        cols,
                        &mut scratch.columns[at..at + width],
                    );
                }
            }
        }
    }

    /// The four moment images of input rows `y0 − radius .. y1 + radius` into `products`.
    #[inline(always)]
    fn load(&self, radius: usize, in_rows: usize, products: &mut Vec<f64>) {
        let cols = self.cols;
        let plane = in_rows * cols;
        budget::resize(products, MOMENTS * plane, 0.0);
        let (pr, ps) = self.pivots;
        let (x, rest) = products.split_at_mut(plane);
        let (y, rest) = rest.split_at_mut(plane);
        let (sq, xy) = rest.split_at_mut(plane);
        for j in 0..in_rows {
            let src = reflect(self.y0 as isize - radius as isize + j as isize, self.rows) * cols;
            let (real, sim) = (&self.real[src..src + cols], &self.sim[src..src + cols]);
            let at = j * cols..(j + 1) * cols;
            let (x, y) = (&mut x[at.clone()], &mut y[at.clone()]);
            let (sq, xy) = (&mut sq[at.clone()], &mut xy[at]);
            for c in 0..cols {
                let (a, b) = (real[c].to_f64() - pr, sim[c].to_f64() - ps);
                x[c] = a;
                y[c] = b;
                sq[c] = a * a + b * b;
                xy[c] = a * b;
            }
        }
    }

    /// The local moments of the band's output row `i` (0-based within the band) into
    /// `scratch.local`: its row of `scratch.columns` filtered along the row.
    #[inline(always)]
    pub fn local_moments(&self, window: &Window, i: usize, scratch: &mut Scratch) {
        let (cols, r) = (self.cols, window.radius());
        let plane = scratch.out_rows * cols;
        budget::resize(&mut scratch.padded, cols + 2 * r, 0.0);
        budget::resize(&mut scratch.local, MOMENTS * cols, 0.0);
        for m in 0..MOMENTS {
            let padded = &mut scratch.padded;
            padded[r..r + cols].copy_from_slice(&scratch.columns[m * plane + i * cols..][..cols]);
            for k in 0..r {
                padded[r - 1 - k] = padded[r + k];
                padded[r + cols + k] = padded[r + cols - 1 - k];
            }
            symmetric_filter(&window.taps, padded, r, 1, &mut scratch.local[m * cols..(m + 1) * cols]);
        }
    }
}

/// `out[c] = taps[0]·line(0)[c] + Σ_k taps[k]·(line(−k)[c] + line(k)[c])`, k from the window's
/// edge inwards (scipy.ndimage's order), with `line(d) = src[centre + d·stride..][..out.len()]`:
/// rows of an image (`stride` = its width) or shifts of one padded row (`stride` = 1).
///
/// Panics if a line falls outside `src` (callers lay the lines out inside it).
#[inline(always)]
fn symmetric_filter(taps: &[f64], src: &[f64], centre: usize, stride: usize, out: &mut [f64]) {
    let (r, n) = (taps.len() - 1, out.len());
    assert!(r * stride <= centre && centre + r * stride + n <= src.len(), "filter lines outside their source");
    // the paper's 11 × 11 window and its neighbours with the taps unrolled
    match r {
        1 => filter_lines::<1>(taps, src, centre, stride, out),
        2 => filter_lines::<2>(taps, src, centre, stride, out),
        3 => filter_lines::<3>(taps, src, centre, stride, out),
        4 => filter_lines::<4>(taps, src, centre, stride, out),
        5 => filter_lines::<5>(taps, src, centre, stride, out),
        6 => filter_lines::<6>(taps, src, centre, stride, out),
        7 => filter_lines::<7>(taps, src, centre, stride, out),
        _ => filter_lines::<0>(taps, src, centre, stride, out),
    }
}

/// [`symmetric_filter`] with radius `R` (0: any radius, `taps.len() − 1`), sixteen columns at a
/// time accumulated in registers. The caller has checked that every line lies inside `src`.
#[inline(always)]
fn filter_lines<const R: usize>(taps: &[f64], src: &[f64], centre: usize, stride: usize, out: &mut [f64]) {
    let r = if R > 0 { R } else { taps.len() - 1 };
    let n = out.len();
    let full = n - n % LANES;
    for c0 in (0..full).step_by(LANES) {
        let at = centre + c0;
        let mut acc = [0.0f64; LANES];
        for (j, a) in acc.iter_mut().enumerate() {
            // SAFETY: at + j < centre + n <= src.len() (checked by `symmetric_filter`)
            *a = taps[0] * unsafe { *src.get_unchecked(at + j) };
        }
        for k in (1..=r).rev() {
            let (lo, hi, w) = (at - k * stride, at + k * stride, taps[k]);
            for (j, a) in acc.iter_mut().enumerate() {
                // SAFETY: k <= r, r·stride <= centre and centre + r·stride + n <= src.len()
                // (checked by `symmetric_filter`), c0 + j < n: both indices lie inside `src`
                let pair = unsafe { *src.get_unchecked(lo + j) + *src.get_unchecked(hi + j) };
                *a += pair * w;
            }
        }
        out[c0..c0 + LANES].copy_from_slice(&acc);
    }
    for (c, o) in out.iter_mut().enumerate().skip(full) {
        let mut acc = taps[0] * src[centre + c];
        for k in (1..=r).rev() {
            acc += (src[centre + c - k * stride] + src[centre + c + k * stride]) * taps[k];
        }
        *o = acc;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gaussian_window_is_normalised_and_symmetric() {
        let w = Window::gaussian(1.5, 5);
        assert_eq!(w.radius(), 5);
        let total = w.taps[0] + 2.0 * w.taps[1..].iter().sum::<f64>();
        assert!((total - 1.0).abs() < 1e-15);
        assert!(w.taps.windows(2).all(|p| p[0] > p[1]));
        // exp(−1/(2·1.5²)) between neighbours at the centre
        assert!((w.taps[1] / w.taps[0] - (-1.0f64 / 4.5).exp()).abs() < 1e-15);
        let point = Window::gaussian(1e-300, 3);
        assert_eq!(point.taps, [1.0, 0.0, 0.0, 0.0]);
    }

    #[test]
    fn filters_equal_the_direct_sum_for_every_radius() {
        for radius in 1..=9 {
            let w = Window::gaussian(1.3, radius);
            let (cols, rows) = (37, 2 * radius + 1);
            let src: Vec<f64> = (0..rows * cols).map(|i| ((i * 37 % 101) as f64).sqrt() - 4.0).collect();
            // along columns (a full image row) and along a padded row (full and tail lanes)
            for (centre, stride, n) in [(radius * cols, cols, cols), (radius, 1, cols - 2 * radius)] {
                let mut got = vec![0.0; n];
                symmetric_filter(&w.taps, &src, centre, stride, &mut got);
                let mut general = vec![0.0; n];
                filter_lines::<0>(&w.taps, &src, centre, stride, &mut general);
                assert_eq!(got, general, "radius {radius}, stride {stride}");
                for (c, v) in got.iter().enumerate() {
                    let mut want = w.taps[0] * src[centre + c];
                    for k in (1..=radius).rev() {
                        want += (src[centre + c - k * stride] + src[centre + c + k * stride]) * w.taps[k];
                    }
                    assert_eq!(*v, want, "the direct sum in scipy's order");
                }
            }
        }
    }

    #[test]
    #[should_panic(expected = "outside their source")]
    fn filter_lines_outside_the_source_panic() {
        let w = Window::gaussian(1.5, 5);
        symmetric_filter(&w.taps, &[0.0; 20], 4, 1, &mut [0.0; 4]); // centre − 5 < 0
    }

    #[test]
    fn reflect_repeats_the_edge() {
        let got: Vec<usize> = (-3..7).map(|i| reflect(i, 4)).collect();
        assert_eq!(got, [2, 1, 0, 0, 1, 2, 3, 3, 2, 1]);
    }

    #[test]
    fn constant_frame_has_constant_local_moments() {
        let (rows, cols) = (7, 9);
        let real = vec![5u16; rows * cols];
        let sim = vec![3u16; rows * cols];
        let band = Band { real: &real, sim: &sim, rows, cols, y0: 0, y1: rows, pivots: (4.0, 4.0) };
        let window = Window::gaussian(1.5, 3);
        let mut scratch = Scratch::default();
        band.filter_columns(&window, &mut scratch);
        for i in 0..rows {
            band.local_moments(&window, i, &mut scratch);
            let want = [1.0, -1.0, 2.0, -1.0];
            for (m, w) in want.iter().enumerate() {
                for c in 0..cols {
                    assert!((scratch.local[m * cols + c] - w).abs() < 1e-15);
                }
            }
        }
    }
}
