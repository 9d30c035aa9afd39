//! Subpixel position of a correlation peak: the exact maximiser of the band-limited
//! correlation `f(p) = Σ_k w_k Re(X_k e^{i k·p})` of a (partially whitened) cross-power
//! spectrum `X`, by Newton's method started near the integer peak and confined to ±1 px of
//! it.
//!
//! This is the function that the matrix-multiply DFT upsampling of Guizar-Sicairos,
//! Thurman & Fienup (2008) samples on a grid of step 1/upsample around the peak; Newton's
//! method with the analytic gradient and Hessian (both O(N) sums over the half spectrum)
//! reaches its maximum to machine precision in a few evaluations instead, and its accuracy
//! does not depend on an upsampling factor.

use super::fft::{Spectrum, C32, C64};
use super::phase::signed;

/// Value, gradient and Hessian of the band-limited correlation at `(py, px)`.
struct Interpolant<'a> {
    spec: &'a Spectrum,
    /// `2π·ky/rows` for signed ky; the Nyquist row (even rows) has weight 0.
    freq_y: Vec<f64>,
    weight_y: Vec<f64>,
}

struct Local {
    value: f64,
    grad: [f64; 2],
    hess: [[f64; 2]; 2],
}

impl<'a> Interpolant<'a> {
    fn new(spec: &'a Spectrum) -> Self {
        let rows = spec.rows;
        let tau = 2.0 * std::f64::consts::PI;
        let freq_y = (0..rows).map(|k| tau * signed(k, rows) as f64 / rows as f64).collect();
        let weight_y = (0..rows).map(|k| if rows % 2 == 0 && k == rows / 2 { 0.0 } else { 1.0 }).collect();
        Interpolant { spec, freq_y, weight_y }
    }

    fn eval(&self, py: f64, px: f64) -> Local {
        let (rows, cols) = (self.spec.rows, self.spec.cols);
        let width = self.spec.width();
        let tau = 2.0 * std::f64::consts::PI;
        let phasor_y: Vec<C64> =
            self.freq_y.iter().zip(&self.weight_y).map(|(&a, &w)| C64::from_polar(w, a * py)).collect();
        let (mut f, mut gy, mut gx, mut hyy, mut hxx, mut hxy) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        for kx in 0..width {
            // Full spectrum = this column and its conjugate mirror: weight 2, except the DC
            // column and the (even-width) Nyquist column, whose sign of frequency is ambiguous.
            let weight = if kx == 0 {
                1.0
            } else if cols % 2 == 0 && kx == cols / 2 {
                0.0
            } else {
                2.0
            };
            if weight == 0.0 {
                continue;
            }
            let column = &self.spec.data[kx * rows..(kx + 1) * rows];
            let [s0, s1, s2] = column_moments(column, &phasor_y, &self.freq_y);
            let ax = tau * kx as f64 / cols as f64;
            let rot = C64::from_polar(weight, ax * px);
            let (z0, z1, z2) = (s0 * rot, s1 * rot, s2 * rot);
            f += z0.re;
            gy -= z1.im;
            gx -= ax * z0.im;
            hyy -= z2.re;
            hxx -= ax * ax * z0.re;
            hxy -= ax * z1.re;
        }
        Local { value: f, grad: [gy, gx], hess: [[hyy, hxy], [hxy, hxx]] }
    }
}

/// `Σ x·p·a^m` for m = 0, 1, 2 over one column `x` of the spectrum, its phasors `p` and
/// frequencies `a`. Summed in four independent lanes, which the compiler can vectorise.
fn column_moments(column: &[C32], phasor: &[C64], freq: &[f64]) -> [C64; 3] {
    const LANES: usize = 4;
    // re and im of the three sums, one partial sum per lane
    let mut acc = [[0.0f64; LANES]; 6];
    let mut add = |lane: usize, x: &C32, p: &C64, a: f64| {
        let (xr, xi) = (x.re as f64, x.im as f64);
        let (tr, ti) = (xr * p.re - xi * p.im, xr * p.im + xi * p.re);
        let (ur, ui) = (tr * a, ti * a);
        acc[0][lane] += tr;
        acc[1][lane] += ti;
        acc[2][lane] += ur;
        acc[3][lane] += ui;
        acc[4][lane] += ur * a;
        acc[5][lane] += ui * a;
    };
    let (xs, ps, fs) = (column.chunks_exact(LANES), phasor.chunks_exact(LANES), freq.chunks_exact(LANES));
    let tail = (xs.remainder(), ps.remainder(), fs.remainder());
    for ((x, p), a) in xs.zip(ps).zip(fs) {
        for lane in 0..LANES {
            add(lane, &x[lane], &p[lane], a[lane]);
        }
    }
    for ((x, p), &a) in tail.0.iter().zip(tail.1).zip(tail.2) {
        add(0, x, p, a);
    }
    let sum = |k: usize| acc[k].iter().sum::<f64>();
    [C64::new(sum(0), sum(1)), C64::new(sum(2), sum(3)), C64::new(sum(4), sum(5))]
}

/// Maximise `sign·f` from `start`, staying within ±1 px of `centre` on each axis.
pub fn newton_peak(spec: &Spectrum, start: (f64, f64), centre: (f64, f64), sign: f64) -> (f64, f64) {
    /// Steps shorter than this (pixels) end the search: far below any other error.
    const TOLERANCE: f64 = 1e-6;
    let interp = Interpolant::new(spec);
    let clamp = |p: [f64; 2]| [p[0].clamp(centre.0 - 1.0, centre.0 + 1.0), p[1].clamp(centre.1 - 1.0, centre.1 + 1.0)];
    let mut p = [start.0, start.1];
    let mut here = interp.eval(p[0], p[1]);
    for _ in 0..20 {
        let g = [sign * here.grad[0], sign * here.grad[1]];
        let h = [[sign * here.hess[0][0], sign * here.hess[0][1]], [sign * here.hess[1][0], sign * here.hess[1][1]]];
        let det = h[0][0] * h[1][1] - h[0][1] * h[1][0];
        let concave = h[0][0] < 0.0 && det > 0.0;
        let mut step = if concave {
            [-(h[1][1] * g[0] - h[0][1] * g[1]) / det, -(h[0][0] * g[1] - h[1][0] * g[0]) / det]
        } else {
            let norm = g[0].hypot(g[1]);
            if norm == 0.0 {
                break;
            }
            [0.25 * g[0] / norm, 0.25 * g[1] / norm]
        };
        let len = step[0].hypot(step[1]);
        if len < TOLERANCE {
            break;
        }
        if len > 0.5 {
            step = [step[0] * 0.5 / len, step[1] * 0.5 / len];
        }
        if concave && len < 1e-3 {
            // quadratic convergence: take the step and stop (a value test would only see
            // rounding at this scale)
            p = clamp([p[0] + step[0], p[1] + step[1]]);
            break;
        }
        let mut accepted = None;
        for _ in 0..8 {
            let q = clamp([p[0] + step[0], p[1] + step[1]]);
            let there = interp.eval(q[0], q[1]);
            if sign * there.value >= sign * here.value {
                accepted = Some((q, there));
                break;
            }
            step = [step[0] * 0.5, step[1] * 0.5];
        }
        let Some((q, there)) = accepted else { break };
        let moved = (q[0] - p[0]).hypot(q[1] - p[1]);
        p = q;
        here = there;
        if moved < TOLERANCE {
            break;
        }
    }
    (p[0], p[1])
}
