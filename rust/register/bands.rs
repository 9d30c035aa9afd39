//! Row bands of an image, processed on the calling thread and idle pool threads
//! ([`crate::kernel::map_units`]: never waiting for a late pool thread, and on one thread
//! inside the sequence engine, whose pool is busy with other pairs). Bands have a fixed
//! height, so results combined band by band do not depend on the thread count.

use std::sync::Mutex;

use crate::kernel::map_units;

/// Rows per band.
const BAND_ROWS: usize = 32;
/// Images smaller than this stay on the calling thread.
const PARALLEL_MIN_PIXELS: usize = 1 << 16;

fn bands(rows: usize) -> usize {
    rows.div_ceil(BAND_ROWS).max(1)
}

/// Rows `[first, end)` of band `b`.
fn band_rows(b: usize, rows: usize) -> (usize, usize) {
    (b * BAND_ROWS, ((b + 1) * BAND_ROWS).min(rows))
}

/// One band of each of two outputs, taken (once) by the thread that fills it.
type BandPair<'a, A, B> = Mutex<Option<(&'a mut [A], &'a mut [B])>>;

/// `f(first_row, values, flags)` on each band of two row-major outputs of `cols` columns.
pub fn fill_bands<A: Send, B: Send>(
    a: &mut [A],
    b: &mut [B],
    cols: usize,
    f: impl Fn(usize, &mut [A], &mut [B]) + Sync,
) {
    let cols = cols.max(1);
    let rows = a.len() / cols;
    let parts: Vec<BandPair<'_, A, B>> =
        a.chunks_mut(BAND_ROWS * cols).zip(b.chunks_mut(BAND_ROWS * cols)).map(|p| Mutex::new(Some(p))).collect();
    let parallel = rows * cols >= PARALLEL_MIN_PIXELS;
    let _ = map_units::<(), std::convert::Infallible>(parts.len(), parallel, |i| {
        let taken = parts[i].lock().unwrap_or_else(|e| e.into_inner()).take();
        if let Some((x, y)) = taken {
            f(band_rows(i, rows).0, x, y);
        }
        Ok(())
    });
}

/// `f(first_row, values)` on each band of one row-major output of `cols` columns.
pub fn fill_rows<A: Send>(a: &mut [A], cols: usize, f: impl Fn(usize, &mut [A]) + Sync) {
    let mut units = vec![(); a.len()]; // zero-sized: no allocation
    fill_bands(a, &mut units, cols, |first, x, _| f(first, x));
}

/// `f(first_row, end_row)` of each band of an image of `rows × cols`, in band order.
pub fn map_bands<R: Send>(rows: usize, cols: usize, f: impl Fn(usize, usize) -> R + Sync) -> Vec<R> {
    let parallel = rows * cols >= PARALLEL_MIN_PIXELS;
    match map_units::<R, std::convert::Infallible>(bands(rows), parallel, |i| {
        let (lo, hi) = band_rows(i, rows);
        Ok(f(lo, hi))
    }) {
        Ok(v) => v,
        Err(never) => match never {},
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_row_once_in_order() {
        let (rows, cols) = (300, 250);
        let mut a = vec![0usize; rows * cols];
        let mut b = vec![false; rows * cols];
        fill_bands(&mut a, &mut b, cols, |first, x, y| {
            for (k, v) in x.iter_mut().enumerate() {
                *v = first * cols + k;
            }
            y.iter_mut().for_each(|f| *f = true);
        });
        assert!(a.iter().enumerate().all(|(i, &v)| v == i) && b.iter().all(|&f| f));
        let spans = map_bands(rows, cols, |lo, hi| (lo, hi));
        assert_eq!(spans.first(), Some(&(0, 32)));
        assert_eq!(spans.last(), Some(&(288, 300)));
        assert!(spans.windows(2).all(|w| w[0].1 == w[1].0));
    }
}
