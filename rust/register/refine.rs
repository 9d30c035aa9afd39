//! Gauss–Newton refinement of a transform on the pixel values, with a grey-level gain and
//! offset: minimise `Σ (real(q) − g·sim(W(q)) − o)²` over the pixels both frames cover,
//! where `W` maps real to simulated coordinates within the model (translation, rigid or
//! similarity).
//!
//! Each iteration warps `sim` through the current `W`, linearises the composition
//! `W ∘ Δ` about the identity using the mean of the warped and the real gradients (the
//! efficient second-order minimisation of Benhimane & Malis 2004; same fixed point as
//! Lucas–Kanade, fewer iterations) and solves the normal equations for `Δ`, `Δg` and `Δo`
//! together. The gain may be negative: inverted grey levels register like any other. Only
//! pixels valid in both frames (and in their gradients) count, so masked and NaN pixels are
//! excluded exactly. This is the refinement of Evangelidis & Psarakis's ECC with the
//! photometric terms solved instead of normalised away.

use super::affine::Affine;
use super::image::Plane;
use super::warp::{warp, Interp, Source};
use super::Model;

/// Iterations stop when an update moves no frame corner by more than this (pixels).
const CONVERGED: f64 = 1e-3;
const MAX_ITERATIONS: usize = 50;

/// A refined transform.
#[derive(Clone, Debug, PartialEq)]
pub struct Refined {
    /// Simulated → real coordinates.
    pub matrix: Affine,
    /// `real ≈ gain·warped sim + offset` over the overlap.
    pub gain: f64,
    pub offset: f64,
    /// Root-mean-square residual of that fit.
    pub rms: f64,
    pub iterations: usize,
}

/// Refine `start` (simulated → real) on the pixel values; `None` when the frames give no
/// usable system (no overlap, or flat within it).
pub fn refine(real: &Plane, sim: &Plane, start: &Affine, model: Model) -> Option<Refined> {
    let real_grad = real.gradient();
    let mut to_sim = start.inverse()?;
    let mut best: Option<Refined> = None;
    for iteration in 0..MAX_ITERATIONS {
        let src = Source { data: &sim.values[..], rows: sim.rows, cols: sim.cols, valid: Some(&sim.valid[..]) };
        let (values, valid) = warp(&src, &to_sim, Interp::Bilinear, real.rows, real.cols, 0.0);
        let warped = Plane::new(real.rows, real.cols, values, valid);
        let step = solve_step(real, &real_grad, &warped, model)?;
        let matrix = to_sim.inverse()?;
        if best.as_ref().is_none_or(|b| step.rms <= b.rms) {
            best = Some(Refined { matrix, gain: step.gain, offset: step.offset, rms: step.rms, iterations: iteration });
        }
        let delta = step.update(model, real.rows, real.cols);
        to_sim = to_sim.compose(&delta);
        if !to_sim.is_finite() || delta.max_displacement(real.rows, real.cols) < CONVERGED {
            break;
        }
    }
    best
}

/// One linearised least-squares step.
struct Step {
    /// Parameter increments: tx, ty, then rotation and scale (scaled by the half size).
    params: [f64; 4],
    gain: f64,
    offset: f64,
    rms: f64,
}

impl Step {
    /// The increment `Δ` (real → real coordinates) to compose on the right of `W`.
    fn update(&self, model: Model, rows: usize, cols: usize) -> Affine {
        let (cx, cy, half) = centre(rows, cols);
        let [tx, ty, rot, dilate] = self.params;
        let theta = if model == Model::Translation { 0.0 } else { rot / half };
        let scale = if model == Model::Similarity { 1.0 + dilate / half } else { 1.0 };
        let (sin, cos) = theta.sin_cos();
        let (a, b) = (scale * cos, scale * sin);
        // q ↦ c + s·R(θ)(q − c) + t, R(θ) = [[cos, −sin], [sin, cos]]
        Affine([[a, -b, cx - a * cx + b * cy + tx], [b, a, cy - b * cx - a * cy + ty]])
    }
}

/// Frame centre and half the larger side (the unit of the rotation/scale parameters).
fn centre(rows: usize, cols: usize) -> (f64, f64, f64) {
    ((cols as f64 - 1.0) / 2.0, (rows as f64 - 1.0) / 2.0, rows.max(cols) as f64 / 2.0)
}

fn n_geometric(model: Model) -> usize {
    match model {
        Model::Translation => 2,
        Model::Rigid => 3,
        Model::Similarity => 4,
    }
}

fn solve_step(real: &Plane, real_grad: &(Vec<f64>, Vec<f64>, Vec<bool>), warped: &Plane, model: Model) -> Option<Step> {
    let (gxr, gyr, okr) = real_grad;
    let (gxw, gyw, okw) = warped.gradient();
    let used = |i: usize| real.valid[i] && okr[i] && okw[i];
    // grey-level fit at the current geometry: real ≈ gain·warped + offset
    let (mut n, mut sw, mut sr) = (0usize, 0.0, 0.0);
    for i in (0..real.values.len()).filter(|&i| used(i)) {
        n += 1;
        sw += warped.values[i];
        sr += real.values[i];
    }
    if n < 16 {
        return None;
    }
    let (mw, mr) = (sw / n as f64, sr / n as f64);
    let (mut sww, mut swr) = (0.0, 0.0);
    for i in (0..real.values.len()).filter(|&i| used(i)) {
        let (w, r) = (warped.values[i] - mw, real.values[i] - mr);
        sww += w * w;
        swr += w * r;
    }
    if sww <= 0.0 {
        return None;
    }
    let gain = swr / sww;
    let offset = mr - gain * mw;

    let geo = n_geometric(model);
    let k = geo + 2;
    let mut normal = [[0.0f64; 6]; 6];
    let mut rhs = [0.0f64; 6];
    let mut sse = 0.0;
    let (cx, cy, half) = centre(real.rows, real.cols);
    let mut jac = [0.0f64; 6];
    for r in 0..real.rows {
        let v = (r as f64 - cy) / half;
        for c in 0..real.cols {
            let i = r * real.cols + c;
            if !used(i) {
                continue;
            }
            let u = (c as f64 - cx) / half;
            let gx = 0.5 * (gain * gxw[i] + gxr[i]);
            let gy = 0.5 * (gain * gyw[i] + gyr[i]);
            jac[0] = gx;
            jac[1] = gy;
            if geo > 2 {
                jac[2] = -gx * v + gy * u;
            }
            if geo > 3 {
                jac[3] = gx * u + gy * v;
            }
            jac[geo] = warped.values[i] - mw; // centred: better conditioned, same solution
            jac[geo + 1] = 1.0;
            let e = real.values[i] - gain * warped.values[i] - offset;
            sse += e * e;
            for a in 0..k {
                rhs[a] += jac[a] * e;
                for b in 0..=a {
                    normal[a][b] += jac[a] * jac[b];
                }
            }
        }
    }
    for a in 0..k {
        for b in 0..a {
            normal[b][a] = normal[a][b];
        }
    }
    let delta = cholesky_solve(&normal, &rhs, k)?;
    let mut params = [0.0; 4];
    params[..geo].copy_from_slice(&delta[..geo]);
    let gain_step = delta[geo];
    Some(Step {
        params,
        gain: gain + gain_step,
        offset: offset + delta[geo + 1] - gain_step * mw,
        rms: (sse / n as f64).sqrt(),
    })
}

/// Solve the `k × k` symmetric positive definite system `a·x = b`; `None` if it is not.
fn cholesky_solve(a: &[[f64; 6]; 6], b: &[f64; 6], k: usize) -> Option<[f64; 6]> {
    let mut l = [[0.0f64; 6]; 6];
    for i in 0..k {
        for j in 0..=i {
            let s = a[i][j] - (0..j).map(|m| l[i][m] * l[j][m]).sum::<f64>();
            if i == j {
                if !(s > 1e-12 * a[i][i].abs()) || s <= 0.0 {
                    return None;
                }
                l[i][i] = s.sqrt();
            } else {
                l[i][j] = s / l[j][j];
            }
        }
    }
    let mut y = [0.0f64; 6];
    for i in 0..k {
        y[i] = (b[i] - (0..i).map(|m| l[i][m] * y[m]).sum::<f64>()) / l[i][i];
    }
    let mut x = [0.0f64; 6];
    for i in (0..k).rev() {
        x[i] = (y[i] - (i + 1..k).map(|m| l[m][i] * x[m]).sum::<f64>()) / l[i][i];
    }
    Some(x)
}

#[cfg(test)]
mod tests {
    use super::super::logpolar::tests::scene;
    use super::*;

    #[test]
    fn converges_from_a_pixel_off_with_gain_offset_and_inversion() {
        let (rows, cols) = (96, 120);
        let values = scene(rows, cols, 3);
        let real = Plane::new(rows, cols, values.clone(), vec![true; rows * cols]);
        let truth = Affine::rotation_scale(1.5, 1.01, (59.5, 47.5)).compose(&Affine::translation(0.7, -1.2));
        for (model, gain) in [(Model::Similarity, 2.5), (Model::Similarity, -0.8), (Model::Rigid, 1.0)] {
            let truth = if model == Model::Rigid { Affine::rotation_scale(1.5, 1.0, (59.5, 47.5)) } else { truth };
            let src = Source { data: &values[..], rows, cols, valid: None };
            let (warped, valid) = warp(&src, &truth, Interp::Bicubic, rows, cols, 0.0);
            let sim_values = warped.iter().map(|v| v / gain + 10.0).collect();
            let sim = Plane::new(rows, cols, sim_values, valid);
            let start = truth.compose(&Affine::translation(0.8, 0.6));
            let out = refine(&real.smoothed(1.0), &sim.smoothed(1.0), &start, model).unwrap();
            let err = out.matrix.corner_distance(&truth, rows, cols);
            assert!(err < 0.05, "{model:?} gain {gain}: {err} {out:?}");
            assert!((out.gain - gain).abs() < 0.05 * gain.abs(), "{out:?}");
        }
    }

    #[test]
    fn cholesky_rejects_singular_systems() {
        let mut a = [[0.0; 6]; 6];
        a[0][0] = 4.0;
        a[1][1] = 9.0;
        let x = cholesky_solve(&a, &[8.0, 9.0, 0.0, 0.0, 0.0, 0.0], 2).unwrap();
        assert_eq!(&x[..2], &[2.0, 1.0]);
        assert!(cholesky_solve(&a, &[1.0; 6], 3).is_none());
    }
}
