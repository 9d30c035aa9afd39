//! Integer shifts judged on the pixels themselves: the Pearson correlation of the
//! overlapping parts of two frames. A circular (FFT) correlation cannot tell a shift `d`
//! from `d ± frame size`, and the apodisation window favours small shifts; comparing the
//! frames where they actually overlap settles both.

use super::image::Plane;

/// Pearson correlation of `real(p)` and `sim(p − d)` over the pixels valid in both, if at
/// least `min_pairs` are (and neither side is constant there).
pub fn shifted_correlation(real: &Plane, sim: &Plane, d: (isize, isize), min_pairs: usize) -> Option<f64> {
    let (rows, cols) = (real.rows as isize, real.cols as isize);
    let (r0, r1) = (d.0.max(0), (rows + d.0).min(rows));
    let (c0, c1) = (d.1.max(0), (cols + d.1).min(cols));
    let pairs = || {
        (r0..r1).flat_map(move |r| (c0..c1).map(move |c| (r, c))).filter_map(|(r, c)| {
            let i = (r * cols + c) as usize;
            let j = ((r - d.0) * cols + (c - d.1)) as usize;
            (real.valid[i] && sim.valid[j]).then(|| (real.values[i], sim.values[j]))
        })
    };
    let n = pairs().count();
    if n < min_pairs.max(2) {
        return None;
    }
    let (sa, sb) = pairs().fold((0.0, 0.0), |(a, b), (x, y)| (a + x, b + y));
    let (ma, mb) = (sa / n as f64, sb / n as f64);
    let (saa, sbb, sab) = pairs().fold((0.0, 0.0, 0.0), |(aa, bb, ab), (x, y)| {
        let (x, y) = (x - ma, y - mb);
        (aa + x * x, bb + y * y, ab + x * y)
    });
    (saa > 0.0 && sbb > 0.0).then(|| sab / (saa * sbb).sqrt())
}

/// Of the shift `peak` and its aliases one frame away on each axis (those within
/// `max_shift`), the one whose overlap — at least an eighth of the frame — correlates best
/// with the sign `sign`.
pub fn resolve_alias(
    real: &Plane,
    sim: &Plane,
    peak: (isize, isize),
    sign: f64,
    max_shift: Option<f64>,
) -> (isize, isize) {
    let allowed = |d: isize| max_shift.is_none_or(|m| d.unsigned_abs() as f64 <= m);
    let aliases = |d: isize, n: usize| {
        let mut v = vec![d];
        let other = d - d.signum() * n as isize;
        if d != 0 && allowed(other) {
            v.push(other);
        }
        v
    };
    let min_pairs = real.rows * real.cols / 8;
    let mut best = (peak, f64::NEG_INFINITY);
    for &dy in &aliases(peak.0, real.rows) {
        for &dx in &aliases(peak.1, real.cols) {
            if let Some(r) = shifted_correlation(real, sim, (dy, dx), min_pairs) {
                if sign * r > best.1 {
                    best = ((dy, dx), sign * r);
                }
            }
        }
    }
    best.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn correlation_of_shifted_copies() {
        let (rows, cols) = (20, 30);
        let f = |r: isize, c: isize| ((r * 7 + c * 13) % 17) as f64 + 0.1 * (r * c) as f64;
        let real = Plane::new(
            rows,
            cols,
            (0..rows * cols).map(|i| f((i / cols) as isize, (i % cols) as isize)).collect(),
            vec![true; rows * cols],
        );
        // sim(p) = real(p + d) → real(p) = sim(p − d)
        let d = (3isize, -5isize);
        let sim = Plane::new(
            rows,
            cols,
            (0..rows * cols).map(|i| f((i / cols) as isize + d.0, (i % cols) as isize + d.1)).collect(),
            vec![true; rows * cols],
        );
        let r = shifted_correlation(&real, &sim, d, 10).unwrap();
        assert!((r - 1.0).abs() < 1e-12);
        assert!(shifted_correlation(&real, &sim, (0, 0), 10).unwrap() < 0.99);
        assert!(shifted_correlation(&real, &sim, (19, 29), 10).is_none());
        // the alias one frame away along x overlaps too little: the peak stays
        assert_eq!(resolve_alias(&real, &sim, d, 1.0, None), d);
    }
}
