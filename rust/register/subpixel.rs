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
//!
//! Each column's products run in float32 (the precision of the spectrum itself) and are
//! summed in sixteen float64 lanes the compiler vectorises. Their rounding hides a rise of
//! the value over steps of about 1e-3 px, so steps that short near a concave peak are taken
//! without a value test; the `phase` tests recover exact shifts to 1e-6 px, also at grey
//! levels of 1e±30.

use super::fft::{Spectrum, C64};
use super::phase::signed;

/// Value, gradient and Hessian of the band-limited correlation at `(py, px)`.
struct Interpolant<'a> {
    spec: &'a Spectrum,
    /// `2π·ky/rows` for signed ky; the Nyquist row (even rows) has weight 0.
    freq_y: Vec<f64>,
    /// `freq_y` and its square in float32, the weights of the column sums.
    freq_y32: Vec<f32>,
    freq_y_sq: Vec<f32>,
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
        let freq_y: Vec<f64> = (0..rows).map(|k| tau * signed(k, rows) as f64 / rows as f64).collect();
        let weight_y = (0..rows).map(|k| if rows % 2 == 0 && k == rows / 2 { 0.0 } else { 1.0 }).collect();
        let freq_y32 = freq_y.iter().map(|&a| a as f32).collect();
        let freq_y_sq = freq_y.iter().map(|a| (a * a) as f32).collect();
        Interpolant { spec, freq_y, freq_y32, freq_y_sq, weight_y }
    }

    /// In a copy compiled for AVX2 when the CPU has it (same code, same results).
    fn eval(&self, py: f64, px: f64) -> Local {
        #[cfg(target_arch = "x86_64")]
        if crate::kernel::use_avx2() {
            // SAFETY: `use_avx2` is true only when the CPU reports AVX2.
            return unsafe { self.eval_avx2(py, px) };
        }
        self.eval_impl(py, px)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn eval_avx2(&self, py: f64, px: f64) -> Local {
        self.eval_impl(py, px)
    }

    #[inline(always)]
    fn eval_impl(&self, py: f64, px: f64) -> Local {
        let (rows, cols) = (self.spec.rows, self.spec.cols);
        let tau = 2.0 * std::f64::consts::PI;
        // the rows' phasors p = w·e^{i·ay·py}, parts apart
        let (p_re, p_im): (Vec<f32>, Vec<f32>) = self
            .freq_y
            .iter()
            .zip(&self.weight_y)
            .map(|(&ay, &w)| {
                let (sin, cos) = (ay * py).sin_cos();
                ((w * cos) as f32, (w * sin) as f32)
            })
            .unzip();
        let (mut t_re, mut t_im) = (vec![0.0f32; rows], vec![0.0f32; rows]);
        let (mut f, mut gy, mut gx, mut hyy, mut hxx, mut hxy) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        for kx in 0..self.spec.width() {
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
            // t = x·p, then its moments Σ t·ay^m (m = 0, 1, 2)
            for (((tr, ti), x), (&pr, &pi)) in
                t_re.iter_mut().zip(t_im.iter_mut()).zip(column).zip(p_re.iter().zip(&p_im))
            {
                let (xr, xi) = (x.re, x.im);
                *tr = xr * pr - xi * pi;
                *ti = xr * pi + xi * pr;
            }
            let s0 = C64::new(sum(&t_re), sum(&t_im));
            let s1 = C64::new(dot(&t_re, &self.freq_y32), dot(&t_im, &self.freq_y32));
            let s2 = C64::new(dot(&t_re, &self.freq_y_sq), dot(&t_im, &self.freq_y_sq));
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

/// Lanes of the sums below: independent float64 partial sums, which the compiler vectorises.
const LANES: usize = 16;

/// `Σ x`, in [`LANES`] partial sums.
#[inline(always)]
fn sum(x: &[f32]) -> f64 {
    let chunks = x.chunks_exact(LANES);
    let tail = chunks.remainder();
    let mut lanes = [0.0f64; LANES];
    for chunk in chunks {
        for (acc, &v) in lanes.iter_mut().zip(chunk) {
            *acc += f64::from(v);
        }
    }
    lanes.iter().sum::<f64>() + tail.iter().map(|&v| f64::from(v)).sum::<f64>()
}

/// `Σ x·y`, in [`LANES`] partial sums.
#[inline(always)]
fn dot(x: &[f32], y: &[f32]) -> f64 {
    let (xs, ys) = (x.chunks_exact(LANES), y[..x.len()].chunks_exact(LANES));
    let (x_tail, y_tail) = (xs.remainder(), ys.remainder());
    let mut lanes = [0.0f64; LANES];
    for (cx, cy) in xs.zip(ys) {
        for ((acc, &a), &b) in lanes.iter_mut().zip(cx).zip(cy) {
            *acc += f64::from(a * b);
        }
    }
    lanes.iter().sum::<f64>() + x_tail.iter().zip(y_tail).map(|(&a, &b)| f64::from(a * b)).sum::<f64>()
}

/// Maximise `sign·f` from `start`, staying within ±1 px of `centre` on each axis.
pub fn newton_peak(spec: &Spectrum, start: (f64, f64), centre: (f64, f64), sign: f64) -> (f64, f64) {
    /// Steps shorter than this (pixels) end the search: far below any other error.
    const TOLERANCE: f64 = 1e-6;
    /// Steps shorter than this (pixels) at a concave point are taken without a value test.
    const TRUSTED_STEP: f64 = 1e-2;
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
        if concave && len < TRUSTED_STEP {
            // Within a hundredth of a pixel of a concave peak Newton's steps are taken
            // without a value test, which at this scale sees the float32 sums' rounding
            // rather than the rise; below 1e-3 px the next step (quadratic convergence)
            // would be below the tolerance, so this one is the last.
            p = clamp([p[0] + step[0], p[1] + step[1]]);
            if len < 1e-3 {
                break;
            }
            here = interp.eval(p[0], p[1]);
            continue;
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
