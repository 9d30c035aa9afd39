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
//!
//! Coarse to fine: the iterations run on the frames halved (while they stay at least
//! [`COARSE_MIN_SIDE`] pixels on their shorter side), where each costs a quarter, and end
//! at full resolution, where typically one or two remain.
//!
//! Robust: each iteration weighs the pixels by Huber's function of their residual (iteratively
//! reweighted least squares), with the scale from the median absolute residual. Pixels that
//! no transform of the model can match — a black border a simulator rendered, a burned-in
//! overlay, a hot object present on one side only — would otherwise pull the least-squares
//! optimum away (a 2-px zero border moved a translation by 0.7 px); with the weights they
//! count for little.

use super::affine::Affine;
use super::bands::map_bands;
use super::image::Plane;
use super::pool::Buffer;
use super::warp::{warp_into, Interp, Source};
use super::Model;

/// Iterations stop when an update moves no frame corner by more than this (pixels of the
/// level).
const CONVERGED: f64 = 1e-3;
const MAX_ITERATIONS: usize = 30;
/// Levels are halved while their shorter side stays at least this long.
const COARSE_MIN_SIDE: usize = 96;
/// Huber's tuning constant, in robust standard deviations of the residuals (95 % efficiency
/// for Gaussian residuals).
const HUBER: f64 = 1.345;
/// The standard deviation of a Gaussian over its median absolute deviation.
const MAD_TO_SIGMA: f64 = 1.482_6;
/// The median absolute residual is taken over every this-many-th pixel (a sample of tens of
/// thousands at the usual frame sizes: a scale, not a statistic reported).
const SCALE_STRIDE: usize = 5;

/// A refined transform.
#[derive(Clone, Debug, PartialEq)]
pub struct Refined {
    /// Simulated → real coordinates.
    pub matrix: Affine,
    /// `real ≈ gain·warped sim + offset` over the overlap.
    pub gain: f64,
    pub offset: f64,
    /// Root-mean-square residual of that fit at full resolution.
    pub rms: f64,
    /// Iterations at full resolution.
    pub iterations: usize,
}

/// Refine `start` (simulated → real) on the pixel values, through coarser levels first if
/// `coarse`; `None` when the frames give no usable system (no overlap, or flat within it).
pub fn refine(real: &Plane, sim: &Plane, start: &Affine, model: Model, coarse: bool) -> Option<Refined> {
    // halved copies, finest first; the full resolution is used as given
    let mut halved: Vec<(Plane, Plane)> = Vec::new();
    if coarse {
        loop {
            let (r, s) = halved.last().map_or((real, sim), |(r, s)| (r, s));
            if r.rows.min(r.cols) / 2 < COARSE_MIN_SIDE {
                break;
            }
            let next = (r.halved(), s.halved());
            halved.push(next);
        }
    }
    let levels: Vec<(&Plane, &Plane)> =
        std::iter::once((real, sim)).chain(halved.iter().map(|(r, s)| (r, s))).collect();
    let mut matrix = *start;
    let mut photometric = None;
    let mut last = None;
    for (k, &(r, s)) in levels.iter().enumerate().rev() {
        let factor = (1u32 << k) as f64;
        let fit = refine_level(r, s, &matrix.at_scale(factor), model, photometric)?;
        matrix = fit.matrix.at_scale(1.0 / factor);
        photometric = Some((fit.gain, fit.offset));
        last = Some(fit);
    }
    last.map(|fit| Refined { matrix, ..fit })
}

/// Gauss–Newton iterations on one level; `photometric` is the `(gain, offset)` to start
/// from (fitted by least squares when `None`).
fn refine_level(
    real: &Plane,
    sim: &Plane,
    start: &Affine,
    model: Model,
    photometric: Option<(f64, f64)>,
) -> Option<Refined> {
    let real_grad = real.gradient();
    let mut to_sim = start.inverse()?;
    let mut best: Option<Refined> = None;
    let mut gain_offset = photometric;
    let n = real.rows * real.cols;
    let mut warped = Plane::new(real.rows, real.cols, Buffer::filled(n, 0.0), Buffer::filled(n, false));
    let src = Source { data: &sim.values[..], rows: sim.rows, cols: sim.cols, valid: Some(&sim.valid[..]) };
    for iteration in 0..MAX_ITERATIONS {
        warp_into(&src, &to_sim, Interp::Bilinear, real.cols, 0.0, &mut warped.values, &mut warped.valid);
        let (gain, offset) = match gain_offset {
            Some(go) => go,
            None => fit_photometric(real, &warped)?,
        };
        let fit = Photometric { gain, offset, huber: huber_threshold(real, &warped, gain, offset) };
        let step = match model {
            Model::Translation => solve_step::<2>(real, &real_grad, &warped, &fit),
            Model::Rigid => solve_step::<3>(real, &real_grad, &warped, &fit),
            Model::Similarity => solve_step::<4>(real, &real_grad, &warped, &fit),
        }?;
        let matrix = to_sim.inverse()?;
        if best.as_ref().is_none_or(|b| step.rms <= b.rms) {
            best = Some(Refined { matrix, gain, offset, rms: step.rms, iterations: iteration });
        }
        gain_offset = Some((step.gain, step.offset));
        let delta = step.update(model, real.rows, real.cols);
        to_sim = to_sim.compose(&delta);
        if !to_sim.is_finite() || delta.max_displacement(real.rows, real.cols) < CONVERGED {
            break;
        }
    }
    best
}

/// Least-squares `real ≈ gain·warped + offset` over the pixels valid in both.
fn fit_photometric(real: &Plane, warped: &Plane) -> Option<(f64, f64)> {
    let both = || (0..real.values.len()).filter(|&i| real.valid[i] && warped.valid[i]);
    let n = both().count();
    if n < 16 {
        return None;
    }
    let mw = both().map(|i| warped.values[i]).sum::<f64>() / n as f64;
    let mr = both().map(|i| real.values[i]).sum::<f64>() / n as f64;
    let (sww, swr) = both().fold((0.0, 0.0), |(ww, wr), i| {
        let (w, r) = (warped.values[i] - mw, real.values[i] - mr);
        (ww + w * w, wr + w * r)
    });
    (sww > 0.0).then(|| (swr / sww, mr - swr / sww * mw))
}

/// `real ≈ gain·warped + offset`, and the residual beyond which a pixel's weight falls.
#[derive(Clone, Copy)]
struct Photometric {
    gain: f64,
    offset: f64,
    /// Huber threshold; infinite when the residuals have no spread (every weight 1).
    huber: f64,
}

/// [`HUBER`] robust standard deviations of the residuals `real − gain·warped − offset` over
/// the pixels valid in both (the median absolute residual of every [`SCALE_STRIDE`]-th pixel;
/// the offset centres them).
fn huber_threshold(real: &Plane, warped: &Plane, gain: f64, offset: f64) -> f64 {
    let mut residuals: Vec<f64> = crate::budget::with_capacity(real.values.len().div_ceil(SCALE_STRIDE));
    residuals.extend(
        (0..real.values.len())
            .step_by(SCALE_STRIDE)
            .filter(|&i| real.valid[i] && warped.valid[i])
            .map(|i| (real.values[i] - gain * warped.values[i] - offset).abs()),
    );
    if residuals.is_empty() {
        return f64::INFINITY;
    }
    let middle = residuals.len() / 2;
    let (_, median, _) = residuals.select_nth_unstable_by(middle, f64::total_cmp);
    let scale = HUBER * MAD_TO_SIGMA * *median;
    if scale > 0.0 {
        scale
    } else {
        f64::INFINITY
    }
}

/// Huber's weight of a residual and its loss (doubled, so that it is `e²` within the threshold).
#[inline(always)]
fn huber(e: f64, threshold: f64) -> (f64, f64) {
    let a = e.abs();
    if a <= threshold {
        (1.0, e * e)
    } else {
        (threshold / a, threshold * (2.0 * a - threshold))
    }
}

/// One linearised least-squares step.
struct Step {
    /// Parameter increments: tx, ty, then rotation and scale (scaled by the half size).
    params: [f64; 4],
    gain: f64,
    offset: f64,
    /// Root-mean-square residual before the step (Huber's loss in place of the square).
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

/// Weighted sums of one band of rows for the normal equations.
#[derive(Clone, Copy, Default)]
struct Sums {
    normal: [[f64; 6]; 6],
    rhs: [f64; 6],
    /// Σ Huber loss (doubled).
    loss: f64,
    n: usize,
    /// Σ weight · warped value (the weighted mean of the gain column is this over Σ weight).
    sum_w: f64,
}

/// Normal equations of `G` geometric parameters (2: translation, 3: + rotation, 4: + scale)
/// plus gain and offset, and their solution. The warped frame's gradient is taken by central
/// differences on the fly. Bands of rows are summed apart and added in order.
// the matrix loops index (row, column) as the formulas do; mirroring needs both at once
#[allow(clippy::needless_range_loop)]
fn solve_step<const G: usize>(
    real: &Plane,
    real_grad: &(Vec<f64>, Vec<f64>, Vec<bool>),
    warped: &Plane,
    fit: &Photometric,
) -> Option<Step> {
    let (rows, cols) = (real.rows, real.cols);
    let parts = map_bands(rows, cols, |lo, hi| band_sums::<G>(real, real_grad, warped, fit, (lo, hi)));
    let mut total = Sums::default();
    for p in parts {
        for a in 0..G + 2 {
            total.rhs[a] += p.rhs[a];
            for b in 0..=a {
                total.normal[a][b] += p.normal[a][b];
            }
        }
        total.loss += p.loss;
        total.n += p.n;
        total.sum_w += p.sum_w;
    }
    let Sums { mut normal, mut rhs, loss, n, sum_w } = total;
    if n < 16 {
        return None;
    }
    // The gain column is centred (w − w̄, weighted mean) before solving: same solution,
    // better conditioned. The offset column is all ones: its diagonal is Σ weight.
    let mean_w = sum_w / normal[G + 1][G + 1];
    centre_column(&mut normal, &mut rhs, G, G + 1, mean_w);
    for a in 0..G + 2 {
        for b in 0..a {
            normal[b][a] = normal[a][b];
        }
    }
    let delta = cholesky_solve(&normal, &rhs, G + 2)?;
    let mut params = [0.0; 4];
    params[..G].copy_from_slice(&delta[..G]);
    let gain_step = delta[G];
    Some(Step {
        params,
        gain: fit.gain + gain_step,
        offset: fit.offset + delta[G + 1] - gain_step * mean_w,
        rms: (loss / n as f64).sqrt(),
    })
}

/// [`Sums`] over rows `[lo, hi)` (the first and last rows of the frame have no gradient).
fn band_sums<const G: usize>(
    real: &Plane,
    real_grad: &(Vec<f64>, Vec<f64>, Vec<bool>),
    warped: &Plane,
    fit: &Photometric,
    (lo, hi): (usize, usize),
) -> Sums {
    let Photometric { gain, offset, huber: threshold } = *fit;
    let (gxr, gyr, okr) = real_grad;
    let (rows, cols) = (real.rows, real.cols);
    let (cx, cy, half) = centre(rows, cols);
    let (w, ok) = (&warped.values, &warped.valid);
    let mut s = Sums::default();
    for r in lo.max(1)..hi.min(rows.saturating_sub(1)) {
        let v = (r as f64 - cy) / half;
        for c in 1..cols - 1 {
            let i = r * cols + c;
            if !(okr[i] && ok[i] && ok[i - 1] && ok[i + 1] && ok[i - cols] && ok[i + cols]) {
                continue;
            }
            let u = (c as f64 - cx) / half;
            let gx = 0.5 * (gain * 0.5 * (w[i + 1] - w[i - 1]) + gxr[i]);
            let gy = 0.5 * (gain * 0.5 * (w[i + cols] - w[i - cols]) + gyr[i]);
            let mut jac = [0.0f64; 6];
            jac[0] = gx;
            jac[1] = gy;
            if G > 2 {
                jac[2] = -gx * v + gy * u;
            }
            if G > 3 {
                jac[3] = gx * u + gy * v;
            }
            jac[G] = w[i];
            jac[G + 1] = 1.0;
            let e = real.values[i] - gain * w[i] - offset;
            let (weight, loss) = huber(e, threshold);
            s.loss += loss;
            s.n += 1;
            s.sum_w += weight * w[i];
            for a in 0..G + 2 {
                let wa = weight * jac[a];
                s.rhs[a] += wa * e;
                for (n, &j) in s.normal[a][..=a].iter_mut().zip(&jac) {
                    *n += wa * j;
                }
            }
        }
    }
    s
}

/// Replace column/row `col` of the lower-triangular normal matrix (and `rhs`) by those of
/// `col − mean·ones`, where `ones` is column `ones` (all 1).
// `a` is the column index of the formula below; the rows `col` and `ones` are both read
#[allow(clippy::needless_range_loop)]
fn centre_column(normal: &mut [[f64; 6]; 6], rhs: &mut [f64; 6], col: usize, ones: usize, mean: f64) {
    let n = normal[ones][ones];
    // Σ(w − m)² = Σw² − 2mΣw + m²n, with Σw = m·n
    normal[col][col] -= mean * mean * n;
    for a in 0..col {
        // Σ j_a (w − m) = Σ j_a w − m Σ j_a
        normal[col][a] -= mean * normal[ones][a];
    }
    // Σ 1·(w − m) = 0
    normal[ones][col] = 0.0;
    rhs[col] -= mean * rhs[ones];
}

/// Solve the `k × k` symmetric positive definite system `a·x = b`; `None` if it is not.
fn cholesky_solve(a: &[[f64; 6]; 6], b: &[f64; 6], k: usize) -> Option<[f64; 6]> {
    let mut l = [[0.0f64; 6]; 6];
    for i in 0..k {
        for j in 0..=i {
            let s = a[i][j] - (0..j).map(|m| l[i][m] * l[j][m]).sum::<f64>();
            if i == j {
                // deliberate NaN handling: a NaN pivot (or diagonal) is not positive definite either
                #[allow(clippy::neg_cmp_op_on_partial_ord)]
                let not_positive = !(s > 1e-12 * a[i][i].abs());
                if not_positive {
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
    use super::super::warp::warp;
    use super::*;

    #[test]
    fn converges_from_a_pixel_off_with_gain_offset_and_inversion() {
        let (rows, cols) = (200, 240);
        let values = scene(rows, cols, 3);
        let real = Plane::new(rows, cols, values.clone(), vec![true; rows * cols]);
        let c = ((cols - 1) as f64 / 2.0, (rows - 1) as f64 / 2.0);
        for (model, gain) in [(Model::Similarity, 2.5), (Model::Similarity, -0.8), (Model::Rigid, 1.0)] {
            let scale = if model == Model::Rigid { 1.0 } else { 1.01 };
            let truth = Affine::rotation_scale(1.5, scale, c).compose(&Affine::translation(0.7, -1.2));
            let src = Source { data: &values[..], rows, cols, valid: None };
            let (warped, valid) = warp(&src, &truth, Interp::Bicubic, rows, cols, 0.0);
            let sim_values: Vec<f64> = warped.iter().map(|v| v / gain + 10.0).collect();
            let sim = Plane::new(rows, cols, sim_values, valid);
            let start = truth.compose(&Affine::translation(0.8, 0.6));
            let out = refine(&real.smoothed(1.0), &sim.smoothed(1.0), &start, model, true).unwrap();
            let err = out.matrix.corner_distance(&truth, rows, cols);
            assert!(err < 0.05, "{model:?} gain {gain}: {err} {out:?}");
            assert!((out.gain - gain).abs() < 0.05 * gain.abs(), "{out:?}");
        }
    }

    #[test]
    #[allow(clippy::needless_range_loop)] // the normal matrix built and mirrored as in `solve_step`
    fn centring_the_gain_column_keeps_the_solution() {
        // 3 unknowns: one geometric, gain (column 1), offset (column 2)
        let rows: Vec<[f64; 3]> = (0..20).map(|i| [((i * 7) % 5) as f64 - 2.0, 100.0 + (i % 4) as f64, 1.0]).collect();
        let target: Vec<f64> = rows.iter().map(|j| 0.5 * j[0] + 2.0 * j[1] - 3.0).collect();
        let (mut normal, mut rhs) = ([[0.0; 6]; 6], [0.0; 6]);
        for (j, &t) in rows.iter().zip(&target) {
            for a in 0..3 {
                rhs[a] += j[a] * t;
                for b in 0..=a {
                    normal[a][b] += j[a] * j[b];
                }
            }
        }
        let mean = rows.iter().map(|j| j[1]).sum::<f64>() / 20.0;
        centre_column(&mut normal, &mut rhs, 1, 2, mean);
        for a in 0..3 {
            for b in 0..a {
                normal[b][a] = normal[a][b];
            }
        }
        let x = cholesky_solve(&normal, &rhs, 3).unwrap();
        // centred model: 0.5·g + 2·(w − m) + (2m − 3)
        assert!(
            (x[0] - 0.5).abs() < 1e-9 && (x[1] - 2.0).abs() < 1e-9 && (x[2] - (2.0 * mean - 3.0)).abs() < 1e-6,
            "{x:?}"
        );
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
