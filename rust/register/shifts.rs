//! Integer shifts judged on the pixels themselves, where the two frames actually overlap.
//! A circular (FFT) correlation cannot tell a shift `d` from `d ± frame size` (settled by the
//! correlation of the values), and its apodisation window favours small shifts, which hides
//! how well a periodic pattern matches one period away (settled by the correlation of the
//! gradients, which — unlike that of the values — falls quickly with the shift on smooth
//! frames too).

use super::frame::Frame;
use super::image::Plane;

/// Pearson correlation of `real(p)` and `sim(p − d)` over the pixels valid in both, if at
/// least `min_pairs` are (and neither side is constant there).
pub fn shifted_correlation(real: &Plane, sim: &Plane, d: (isize, isize), min_pairs: usize) -> Option<f64> {
    let (rows, cols) = (real.rows as isize, real.cols as isize);
    let (r0, r1) = (d.0.max(0), (rows + d.0).min(rows));
    let (c0, c1) = (d.1.max(0), (cols + d.1).min(cols));
    if r1 <= r0 || c1 <= c0 || (((r1 - r0) * (c1 - c0)) as usize) < min_pairs.max(2) {
        return None;
    }
    // sums about a pivot (the first pair), so the second moments do not cancel
    let (mut pivot, mut n) = (None, 0usize);
    let (mut sa, mut sb, mut saa, mut sbb, mut sab) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for r in r0..r1 {
        let (ri, si) = ((r * cols) as usize, ((r - d.0) * cols) as usize);
        for c in c0..c1 {
            let (i, j) = (ri + c as usize, si + (c - d.1) as usize);
            if !(real.valid[i] && sim.valid[j]) {
                continue;
            }
            let (pa, pb) = *pivot.get_or_insert((real.values[i], sim.values[j]));
            let (x, y) = (real.values[i] - pa, sim.values[j] - pb);
            n += 1;
            sa += x;
            sb += y;
            saa += x * x;
            sbb += y * y;
            sab += x * y;
        }
    }
    if n < min_pairs.max(2) {
        return None;
    }
    let nf = n as f64;
    let (vaa, vbb, vab) = (saa - sa * sa / nf, sbb - sb * sb / nf, sab - sa * sb / nf);
    (vaa > 0.0 && vbb > 0.0).then(|| vab / (vaa * vbb).sqrt())
}

/// Correlation of the gradients of `real(p)` and `sim(p − d)`:
/// `Σ ∇r·∇s / sqrt(Σ|∇r|² Σ|∇s|²)` over the pixels where both central differences exist, if
/// at least `min_pairs` do.
pub fn shifted_gradient_correlation(real: &Plane, sim: &Plane, d: (isize, isize), min_pairs: usize) -> Option<f64> {
    let overlap = Overlap::interior(real.rows, real.cols, d);
    if overlap.y.1 <= overlap.y.0 || overlap.x.1 <= overlap.x.0 {
        return None;
    }
    let all_valid = |p: &Plane| p.n_valid == p.values.len();
    let sums = if all_valid(real) && all_valid(sim) {
        clean_gradient_sums(real, sim, overlap)
    } else {
        masked_gradient_sums(real, sim, overlap)
    };
    let GradientSums { n, rr, ss, rs } = sums;
    (n >= min_pairs.max(2) && rr > 0.0 && ss > 0.0).then(|| rs / (rr * ss).sqrt())
}

/// Where `real(p)` meets `sim(p − d)` with both frames' borders left out (a central
/// difference needs the neighbours): the real frame's rows `y` and columns `x`, half-open.
#[derive(Clone, Copy, Debug)]
struct Overlap {
    d: (isize, isize),
    y: (isize, isize),
    x: (isize, isize),
}

impl Overlap {
    fn interior(rows: usize, cols: usize, d: (isize, isize)) -> Overlap {
        let span = |n: usize, shift: isize| ((shift + 1).max(1), (n as isize - 1 + shift).min(n as isize - 1));
        Overlap { d, y: span(rows, d.0), x: span(cols, d.1) }
    }
}

/// `Σ|∇r|²`, `Σ|∇s|²`, `Σ ∇r·∇s` over `n` pixels (central differences, unscaled).
struct GradientSums {
    n: usize,
    rr: f64,
    ss: f64,
    rs: f64,
}

/// [`GradientSums`] over an overlap when every pixel of both frames is valid: whole row
/// slices, no per-pixel mask checks, four independent partial sums.
fn clean_gradient_sums(real: &Plane, sim: &Plane, overlap: Overlap) -> GradientSums {
    let Overlap { d, y: span_y, x: span_x } = overlap;
    const LANES: usize = 4;
    let width = (span_x.1 - span_x.0) as usize;
    // the row `r` of `p` from column `c − 1` to `c + width` (the neighbours included)
    fn row(p: &Plane, r: isize, c: isize, width: usize) -> &[f64] {
        &p.values[r as usize * p.cols + c as usize - 1..][..width + 2]
    }
    let mut lanes = [[0.0f64; LANES]; 3];
    let mut add = |lane: usize, a: (f64, f64), b: (f64, f64)| {
        lanes[0][lane] += a.0 * a.0 + a.1 * a.1;
        lanes[1][lane] += b.0 * b.0 + b.1 * b.1;
        lanes[2][lane] += a.0 * b.0 + a.1 * b.1;
    };
    for r in span_y.0..span_y.1 {
        let (s, cs) = (r - d.0, span_x.0 - d.1);
        let x = span_x.0;
        let (a_up, a, a_down) = (row(real, r - 1, x, width), row(real, r, x, width), row(real, r + 1, x, width));
        let (b_up, b, b_down) = (row(sim, s - 1, cs, width), row(sim, s, cs, width), row(sim, s + 1, cs, width));
        let gradient =
            |up: &[f64], centre: &[f64], down: &[f64], k: usize| (centre[k + 2] - centre[k], down[k + 1] - up[k + 1]);
        for k in 0..width {
            add(k % LANES, gradient(a_up, a, a_down, k), gradient(b_up, b, b_down, k));
        }
    }
    let total = |m: usize| lanes[m].iter().sum::<f64>();
    GradientSums { n: (span_y.1 - span_y.0) as usize * width, rr: total(0), ss: total(1), rs: total(2) }
}

/// [`GradientSums`] as [`clean_gradient_sums`], pixel by pixel, where a central difference
/// exists only if the four neighbours are valid.
fn masked_gradient_sums(real: &Plane, sim: &Plane, overlap: Overlap) -> GradientSums {
    let Overlap { d, y: span_y, x: span_x } = overlap;
    let cols = real.cols as isize;
    let grad = |p: &Plane, i: usize, stride: usize| -> Option<(f64, f64)> {
        let ok = p.valid[i - 1] && p.valid[i + 1] && p.valid[i - stride] && p.valid[i + stride];
        ok.then(|| (p.values[i + 1] - p.values[i - 1], p.values[i + stride] - p.values[i - stride]))
    };
    let mut sums = GradientSums { n: 0, rr: 0.0, ss: 0.0, rs: 0.0 };
    for r in span_y.0..span_y.1 {
        for c in span_x.0..span_x.1 {
            let i = (r * cols + c) as usize;
            let j = ((r - d.0) * cols + (c - d.1)) as usize;
            if let (Some(a), Some(b)) = (grad(real, i, cols as usize), grad(sim, j, cols as usize)) {
                sums.n += 1;
                sums.rr += a.0 * a.0 + a.1 * a.1;
                sums.ss += b.0 * b.0 + b.1 * b.1;
                sums.rs += a.0 * b.0 + a.1 * b.1;
            }
        }
    }
    sums
}

/// Of the shift `peak` and its aliases one frame away on each axis (those within
/// `max_shift` whose overlap is at least an eighth of the frame), the one whose overlap
/// correlates best with the sign `sign`.
pub fn resolve_alias(
    real: &Frame,
    sim: &Frame,
    peak: (isize, isize),
    sign: f64,
    max_shift: Option<f64>,
) -> (isize, isize) {
    let min_pairs = real.rows * real.cols / 8;
    let allowed = |d: isize| max_shift.is_none_or(|m| d.unsigned_abs() as f64 <= m);
    let aliases = |d: isize, n: usize| {
        let mut v = vec![d];
        let other = d - d.signum() * n as isize;
        if d != 0 && allowed(other) && other.unsigned_abs() < n {
            v.push(other);
        }
        v
    };
    let candidates: Vec<(isize, isize)> = aliases(peak.0, real.rows)
        .into_iter()
        .flat_map(|dy| aliases(peak.1, real.cols).into_iter().map(move |dx| (dy, dx)))
        .filter(|&(dy, dx)| (real.rows - dy.unsigned_abs()) * (real.cols - dx.unsigned_abs()) >= min_pairs)
        .collect();
    if candidates.len() < 2 {
        return peak;
    }
    let (real, sim) = (real.plane(), sim.plane());
    let mut best = (peak, f64::NEG_INFINITY);
    for d in candidates {
        if let Some(r) = shifted_correlation(real, sim, d, min_pairs) {
            if sign * r > best.1 {
                best = (d, sign * r);
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
            (0..rows * cols).map(|i| f((i / cols) as isize, (i % cols) as isize)).collect::<Vec<f64>>(),
            vec![true; rows * cols],
        );
        // sim(p) = real(p + d) → real(p) = sim(p − d)
        let d = (3isize, -5isize);
        let sim = Plane::new(
            rows,
            cols,
            (0..rows * cols).map(|i| f((i / cols) as isize + d.0, (i % cols) as isize + d.1)).collect::<Vec<f64>>(),
            vec![true; rows * cols],
        );
        let r = shifted_correlation(&real, &sim, d, 10).unwrap();
        assert!((r - 1.0).abs() < 1e-12);
        let g = shifted_gradient_correlation(&real, &sim, d, 10).unwrap();
        assert!((g - 1.0).abs() < 1e-12);
        assert!(shifted_gradient_correlation(&real, &sim, (0, 0), 10).unwrap() < 0.9);
        assert!(shifted_correlation(&real, &sim, (0, 0), 10).unwrap() < 0.99);
        assert!(shifted_correlation(&real, &sim, (19, 29), 10).is_none());
        // the row-slice path for fully valid frames gives the pixel-by-pixel sums
        for d in [(0, 0), (3, -5), (-4, 7), (18, 27), (-18, -27)] {
            let overlap = Overlap::interior(rows, cols, d);
            let fast = clean_gradient_sums(&real, &sim, overlap);
            let slow = masked_gradient_sums(&real, &sim, overlap);
            assert_eq!(fast.n, slow.n, "{d:?}");
            for (f, s) in [(fast.rr, slow.rr), (fast.ss, slow.ss), (fast.rs, slow.rs)] {
                assert!((f - s).abs() <= 1e-12 * s.abs().max(1.0), "{d:?}: {f} vs {s}");
            }
        }
        assert!(shifted_gradient_correlation(&real, &sim, (19, 0), 1).is_none());
        // the alias one frame away along x overlaps too little: the peak stays
        assert_eq!(resolve_alias(&(&real).into(), &(&sim).into(), d, 1.0, None), d);
    }
}
