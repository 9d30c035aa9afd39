//! Registration by maximising normalised mutual information (Pluim, Maintz & Viergever
//! 2003): for frames whose grey levels relate non-linearly or inversely, where a
//! correlation of the values may miss.
//!
//! NMI is `2·MI / (H(R) + H(S))` of the joint histogram built by the statistics kernel
//! ([`crate::stats::pair_stats`]) over the pixels both frames cover, with `BINS` bins over
//! each frame's own robust range (so gain and offset do not matter). Both frames are
//! smoothed first: bilinear interpolation smooths the resampled frame by an amount that
//! depends on the subpixel position, which makes raw NMI prefer half-pixel positions (Pluim
//! et al. 2000); a common smoothing makes that difference small.
//!
//! Search: every integer shift on a coarse level (frames halved until they are at most
//! [`COARSE_SIDE`] pixels wide) gives the NMI surface — its best shift starts the
//! refinement, and how distinct its maximum is gives the confidence — then Nelder–Mead
//! refines the model's parameters at the full resolution.

use super::affine::Affine;
use super::image::Plane;
use super::phase::EXCLUSION;
use super::warp::{warp, Interp, Source};
use super::Model;
use crate::budget;
use crate::error::Result;
use crate::stats::{pair_stats, HistRequest, Request};

/// Histogram bins per frame.
pub const BINS: usize = 32;
/// Largest side of the coarse level of the exhaustive shift search.
const COARSE_SIDE: usize = 96;
/// Standard deviation (pixels) of the smoothing applied to both frames.
const SMOOTHING: f64 = 1.0;
/// Quantile clipped at each end of a frame's range before binning.
const CLIP: f64 = 0.005;
/// Fewest pixels an overlap may have to be scored.
const MIN_PIXELS: usize = 64;

/// The result of an NMI search.
#[derive(Clone, Debug, PartialEq)]
pub struct NmiFit {
    /// Simulated → real coordinates.
    pub matrix: Affine,
    pub nmi: f64,
    /// Distinctness of the coarse NMI maximum, as for phase correlation:
    /// `(best − rival)/(best − median)` over the searched shifts, clamped to [0, 1].
    pub confidence: f64,
    /// Integer shift (full-resolution pixels) of the best coarse rival.
    pub rival: (isize, isize),
    /// The registered frames correlate negatively (measured on the coarse level).
    pub inverted: bool,
}

/// NMI of `real` and `sim` over the pixels valid in both (0 if fewer than [`MIN_PIXELS`]).
pub fn nmi(real: &[f64], sim: &[f64], valid: &[bool], shape: (usize, usize)) -> Result<f64> {
    if valid.iter().filter(|&&v| v).count() < MIN_PIXELS {
        return Ok(0.0);
    }
    let req = Request {
        sse: false,
        moments: false,
        hist: Some(HistRequest::Bins { bins: BINS, range: Some((0.0, 1.0)) }),
        mask: Some(valid),
        shape,
        ..Request::default()
    };
    let stats = pair_stats(real, sim, &req)?;
    Ok(match stats.entropies() {
        Some(e) if e.h_real + e.h_sim > 0.0 => (2.0 * (e.h_real + e.h_sim - e.h_joint) / (e.h_real + e.h_sim)).max(0.0),
        _ => 0.0,
    })
}

/// Search around `start` (simulated → real; its rotation and scale are kept as the coarse
/// guess) for the transform of `model` that maximises NMI. `max_shift` bounds the coarse
/// search (pixels); `None` searches a quarter of the frame each way.
pub fn register_nmi(real: &Plane, sim: &Plane, start: &Affine, model: Model, max_shift: Option<f64>) -> Result<NmiFit> {
    let real_u = real.smoothed(SMOOTHING).unit_range(CLIP);
    let sim_u = sim.smoothed(SMOOTHING).unit_range(CLIP);
    let (coarse_shift, confidence, rival) = coarse_search(&real_u, &sim_u, start, max_shift)?;
    let mut matrix = Affine::translation(coarse_shift.1, coarse_shift.0).compose(start);
    // Nelder–Mead first on a middle level (cheap, wide steps), then at full resolution.
    let mut levels = vec![(real_u.clone(), sim_u.clone(), 1.0)];
    while levels.last().is_some_and(|(r, _, _)| r.rows.max(r.cols) > 2 * 160) {
        let (r, s, f) = levels.last().unwrap();
        levels.push((r.halved(), s.halved(), f * 2.0));
    }
    let coarse_step = coarse_factor(real.rows, real.cols) as f64;
    let n_levels = levels.len();
    for (k, (r, s, factor)) in levels.iter().rev().enumerate() {
        let step = if k == 0 { coarse_step / factor } else { 0.5 };
        let tolerance = if k + 1 == n_levels { 0.005 } else { 0.05 };
        matrix = nelder_mead(r, s, &matrix.at_scale(*factor), model, step, tolerance)?;
        matrix = matrix.at_scale(1.0 / factor);
    }
    let value = nmi_at(&real_u, &sim_u, &matrix)?;
    let (r_top, s_top, f_top) = levels.last().expect("the full level");
    let inverted = correlation_at(r_top, s_top, &matrix.at_scale(*f_top)) < 0.0;
    Ok(NmiFit { matrix, nmi: value, confidence, rival, inverted })
}

/// Halvings to the coarse level, as a factor.
fn coarse_factor(rows: usize, cols: usize) -> usize {
    let mut f = 1;
    while rows.max(cols) / f > COARSE_SIDE && rows.min(cols) / (2 * f) >= 16 {
        f *= 2;
    }
    f
}

/// NMI of `real` and `sim` warped by `matrix` (simulated → real).
fn nmi_at(real: &Plane, sim: &Plane, matrix: &Affine) -> Result<f64> {
    let Some(to_sim) = matrix.inverse() else { return Ok(0.0) };
    let src = Source { data: &sim.values[..], rows: sim.rows, cols: sim.cols, valid: Some(&sim.valid[..]) };
    let (values, mut valid) = warp(&src, &to_sim, Interp::Bilinear, real.rows, real.cols, 0.0);
    for (v, &r) in valid.iter_mut().zip(&real.valid) {
        *v &= r;
    }
    nmi(&real.values, &values, &valid, (real.rows, real.cols))
}

/// Covariance of `real` and `sim` warped by `matrix` over the pixels valid in both.
fn correlation_at(real: &Plane, sim: &Plane, matrix: &Affine) -> f64 {
    let Some(to_sim) = matrix.inverse() else { return 0.0 };
    let src = Source { data: &sim.values[..], rows: sim.rows, cols: sim.cols, valid: Some(&sim.valid[..]) };
    let (values, valid) = warp(&src, &to_sim, Interp::Bilinear, real.rows, real.cols, 0.0);
    let mut both: Vec<usize> = budget::with_capacity(values.len());
    both.extend((0..values.len()).filter(|&i| valid[i] && real.valid[i]));
    if both.is_empty() {
        return 0.0;
    }
    let n = both.len() as f64;
    let (mr, ms) =
        (both.iter().map(|&i| real.values[i]).sum::<f64>() / n, both.iter().map(|&i| values[i]).sum::<f64>() / n);
    both.iter().map(|&i| (real.values[i] - mr) * (values[i] - ms)).sum::<f64>()
}

/// The coarse search's `((dy, dx)` in full-resolution pixels, confidence, rival shift`)`.
type CoarseShift = ((f64, f64), f64, (isize, isize));

/// Exhaustive integer-shift search on the coarse level: `((dy, dx)` in full-resolution
/// pixels, confidence, rival shift`)`.
fn coarse_search(real: &Plane, sim: &Plane, start: &Affine, max_shift: Option<f64>) -> Result<CoarseShift> {
    let factor = coarse_factor(real.rows, real.cols);
    let (mut rc, mut sc) = (real.clone(), sim.clone());
    while rc.rows > real.rows / factor {
        rc = rc.halved();
        sc = sc.halved();
    }
    let f = factor as f64;
    // the simulated frame moved by `start` on the coarse grid, then shifted by whole pixels
    let Some(to_sim) = start.at_scale(f).inverse() else { return Ok(((0.0, 0.0), 0.0, (0, 0))) };
    let src = Source { data: &sc.values[..], rows: sc.rows, cols: sc.cols, valid: Some(&sc.valid[..]) };
    let (moved, moved_ok) = warp(&src, &to_sim, Interp::Bilinear, rc.rows, rc.cols, 0.0);
    let reach = |n: usize| {
        let quarter = (n / 4) as isize;
        match max_shift {
            Some(m) => ((m / f).ceil() as isize).min(quarter.max(1)),
            None => quarter,
        }
    };
    let (ry, rx) = (reach(rc.rows), reach(rc.cols));
    let (rows, cols) = (rc.rows, rc.cols);
    let mut shifted = budget::filled(rows * cols, 0.0);
    let mut valid = budget::filled(rows * cols, false);
    let mut surface = Vec::with_capacity(((2 * ry + 1) * (2 * rx + 1)) as usize);
    for dy in -ry..=ry {
        for dx in -rx..=rx {
            // pair real(q) with moved(q − d)
            for r in 0..rows as isize {
                for c in 0..cols as isize {
                    let i = (r * cols as isize + c) as usize;
                    let (sr, scol) = (r - dy, c - dx);
                    let inside = sr >= 0 && scol >= 0 && sr < rows as isize && scol < cols as isize;
                    let j = if inside { (sr * cols as isize + scol) as usize } else { 0 };
                    valid[i] = inside && moved_ok[j] && rc.valid[i];
                    shifted[i] = if valid[i] { moved[j] } else { 0.0 };
                }
            }
            surface.push(((dy, dx), nmi(&rc.values, &shifted, &valid, (rows, cols))?));
        }
    }
    let &((by, bx), best) = surface.iter().max_by(|a, b| a.1.total_cmp(&b.1)).expect("at least the zero shift");
    let mut values: Vec<f64> = surface.iter().map(|s| s.1).collect();
    let mid = values.len() / 2;
    let median = *values.select_nth_unstable_by(mid, f64::total_cmp).1;
    let rival = surface
        .iter()
        .filter(|((dy, dx), _)| (dy - by).abs() > EXCLUSION || (dx - bx).abs() > EXCLUSION)
        .max_by(|a, b| a.1.total_cmp(&b.1));
    let (confidence, rival_at) = match rival {
        Some(&((dy, dx), v)) if best > median => {
            (((best - v) / (best - median)).clamp(0.0, 1.0), (dy * factor as isize, dx * factor as isize))
        }
        Some(&((dy, dx), _)) => (0.0, (dy * factor as isize, dx * factor as isize)),
        None => (if best > median { 1.0 } else { 0.0 }, (0, 0)),
    };
    Ok(((by as f64 * f, bx as f64 * f), confidence, rival_at))
}

/// The transform of `model` near `start` from a parameter vector: translation (px), then
/// rotation and log-scale expressed as the displacement they cause at half the larger side.
fn params_to_matrix(start: &Affine, params: &[f64], model: Model, rows: usize, cols: usize) -> Affine {
    let (cx, cy) = ((cols as f64 - 1.0) / 2.0, (rows as f64 - 1.0) / 2.0);
    let half = rows.max(cols) as f64 / 2.0;
    let angle = if model == Model::Translation { 0.0 } else { (params[2] / half).to_degrees() };
    let scale = if model == Model::Similarity { (params[3] / half).exp() } else { 1.0 };
    Affine::translation(params[1], params[0]).compose(&Affine::rotation_scale(angle, scale, (cx, cy))).compose(start)
}

/// Nelder–Mead maximisation of NMI over the model's parameters around `start`, initial
/// steps `step` pixels, stopping when the simplex spans less than `tolerance` pixels.
fn nelder_mead(real: &Plane, sim: &Plane, start: &Affine, model: Model, step: f64, tolerance: f64) -> Result<Affine> {
    let dim = match model {
        Model::Translation => 2,
        Model::Rigid => 3,
        Model::Similarity => 4,
    };
    let cost = |p: &[f64]| -> Result<f64> {
        Ok(-nmi_at(real, sim, &params_to_matrix(start, p, model, real.rows, real.cols))?)
    };
    let mut simplex: Vec<(Vec<f64>, f64)> = Vec::with_capacity(dim + 1);
    let origin = vec![0.0; dim];
    simplex.push((origin.clone(), cost(&origin)?));
    for k in 0..dim {
        let mut p = origin.clone();
        p[k] = step;
        let c = cost(&p)?;
        simplex.push((p, c));
    }
    let blend = |a: &[f64], b: &[f64], t: f64| -> Vec<f64> { a.iter().zip(b).map(|(x, y)| x + t * (y - x)).collect() };
    for _ in 0..60 * dim {
        simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
        let spread = simplex[1..]
            .iter()
            .map(|(p, _)| p.iter().zip(&simplex[0].0).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max))
            .fold(0.0, f64::max);
        if spread < tolerance {
            break;
        }
        let worst = simplex[dim].clone();
        let centroid: Vec<f64> =
            (0..dim).map(|k| simplex[..dim].iter().map(|(p, _)| p[k]).sum::<f64>() / dim as f64).collect();
        let reflected = blend(&centroid, &worst.0, -1.0);
        let fr = cost(&reflected)?;
        if fr < simplex[0].1 {
            let expanded = blend(&centroid, &worst.0, -2.0);
            let fe = cost(&expanded)?;
            simplex[dim] = if fe < fr { (expanded, fe) } else { (reflected, fr) };
        } else if fr < simplex[dim - 1].1 {
            simplex[dim] = (reflected, fr);
        } else {
            let toward = if fr < worst.1 { blend(&centroid, &reflected, 0.5) } else { blend(&centroid, &worst.0, 0.5) };
            let fc = cost(&toward)?;
            if fc < worst.1.min(fr) {
                simplex[dim] = (toward, fc);
            } else {
                let best = simplex[0].0.clone();
                for vertex in simplex.iter_mut().skip(1) {
                    vertex.0 = blend(&best, &vertex.0, 0.5);
                    vertex.1 = cost(&vertex.0)?;
                }
            }
        }
    }
    simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
    Ok(params_to_matrix(start, &simplex[0].0, model, real.rows, real.cols))
}

#[cfg(test)]
mod tests {
    use super::super::logpolar::tests::scene;
    use super::*;

    #[test]
    fn registers_an_inverted_non_linear_pair() {
        let (rows, cols) = (90, 120);
        let values = scene(rows, cols, 11);
        let real = Plane::new(rows, cols, values.clone(), vec![true; rows * cols]);
        let truth = Affine::translation(3.4, -2.3);
        let src = Source { data: &values[..], rows, cols, valid: None };
        let (warped, valid) = warp(&src, &truth, Interp::Bicubic, rows, cols, 0.0);
        // inverted and squashed: a monotone decreasing, non-linear grey-level relation
        let sim_values: Vec<f64> = warped.iter().map(|v| 1.0 / (1.5 + v)).collect();
        let sim = Plane::new(rows, cols, sim_values, valid);
        let fit = register_nmi(&real, &sim, &Affine::IDENTITY, Model::Translation, None).unwrap();
        let err = fit.matrix.corner_distance(&truth, rows, cols);
        assert!(err < 0.1, "{err} {fit:?}");
        assert!(fit.confidence > 0.3 && fit.nmi > 0.5, "{fit:?}");
    }

    #[test]
    fn nmi_of_a_frame_with_itself_and_its_negative_is_one() {
        let v: Vec<f64> = (0..400).map(|i| ((i % 32) as f64 + 0.5) / 32.0).collect();
        let neg: Vec<f64> = v.iter().map(|x| 1.0 - x).collect();
        let ok = vec![true; 400];
        assert!((nmi(&v, &v, &ok, (20, 20)).unwrap() - 1.0).abs() < 1e-12);
        assert!((nmi(&v, &neg, &ok, (20, 20)).unwrap() - 1.0).abs() < 1e-12);
        assert_eq!(nmi(&v, &v, &vec![false; 400], (20, 20)).unwrap(), 0.0);
    }
}
