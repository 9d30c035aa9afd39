//! Rotation and scale from log-polar magnitude spectra (Reddy & Chatterji 1996).
//!
//! The magnitude of a frame's spectrum ignores translation; rotating the frame rotates it
//! and scaling by `s` scales it by `1/s`. Resampled on a grid of angle × log-radius, both
//! become shifts, found by phase correlation ([`super::phase`]). The angle axis covers
//! [0°, 180°) (a magnitude spectrum is point-symmetric), so it is periodic and needs no
//! window, and a rotation is known modulo 180° — the caller tries both.

use std::cell::RefCell;
use std::rc::Rc;

use super::fft;

use super::image::Plane;
use super::phase::{correlate_tapered, Locate, Polarity};
use super::pool::Buffer;
use super::window::{tapered, tukey};

/// Samples of the angle axis over 180°: 0.35° per sample before subpixel refinement.
const ANGLES: usize = 512;
/// Samples of the log-radius axis.
const RADII: usize = 256;
/// Highest radius sampled, in cycles per pixel (below Nyquist, where aliasing lives).
const R_MAX: f64 = 0.45;
/// Lowest radius, in cycles per frame (the shorter side): the window dominates below it.
const R_MIN_CYCLES: f64 = 4.0;
/// Largest scale change searched (and its inverse).
const MAX_SCALE: f64 = 2.0;

/// Rotation and scale of the map from simulated to real coordinates.
#[derive(Clone, Debug, PartialEq)]
pub struct RotationScale {
    /// Degrees, OpenCV sense, in [−90, 90).
    pub angle_deg: f64,
    pub scale: f64,
    /// Distinctness of the log-polar correlation peak (see [`super::phase::Peak`]).
    pub confidence: f64,
}

/// Estimate the rotation (and, if `with_scale`, the scale) taking `sim` onto `real`.
pub fn rotation_scale(real: &Plane, sim: &Plane, with_scale: bool) -> RotationScale {
    let r_min = R_MIN_CYCLES / real.rows.min(real.cols) as f64;
    let step = (R_MAX / r_min).ln() / (RADII - 1) as f64;
    let (a, b) = log_polar_pair(real, sim, r_min, step);
    // log-radius is not periodic: Hann window along it; angle is periodic: no window
    let (w_angle, w_radius) = (vec![1.0; ANGLES], tukey(RADII, 1.0));
    let ta = tapered(&a, &w_angle, &w_radius);
    let tb = tapered(&b, &w_angle, &w_radius);
    let radius_limit = if with_scale { (MAX_SCALE.ln() / step).floor() as usize } else { 0 };
    let (peak, _) = correlate_tapered(
        &ta,
        &tb,
        ANGLES,
        RADII,
        (ANGLES / 2, radius_limit),
        Polarity::Positive,
        Locate::HalfWhitened,
    );
    // real's spectrum at angle φ equals sim's at φ − dy samples: the real frame is the
    // simulated one turned by −dy samples; likewise its radii are scaled by e^{dx·step}.
    let angle_deg = -peak.dy * 180.0 / ANGLES as f64;
    let scale = if with_scale { (-peak.dx * step).exp() } else { 1.0 };
    RotationScale { angle_deg, scale, confidence: peak.confidence }
}

/// The magnitude of the Hann-windowed frame's half spectrum (column-major, as [`fft::Spectrum`]).
fn magnitude(plane: &Plane) -> Vec<f64> {
    let windowed = tapered(plane, &tukey(plane.rows, 1.0), &tukey(plane.cols, 1.0));
    let spec = fft::forward(&windowed, plane.rows, plane.cols);
    let modulus = |z: &fft::C32| (z.re as f64 * z.re as f64 + z.im as f64 * z.im as f64).sqrt();
    crate::budget::collect(spec.data.len(), spec.data.iter().map(modulus))
}

/// Where one log-polar sample reads the half spectrum: the offsets of its four bilinear taps
/// (`kx·rows + ky`), their weights along x and y, and the high-pass emphasis there.
struct Tap {
    at: [usize; 4],
    tx: f64,
    ty: f64,
    emphasis: f64,
}

/// The `ANGLES × RADII` taps for a `rows × cols` frame: angle in [0, π), radius
/// `r_min·e^{j·step}` cycles/px.
fn grid(rows: usize, cols: usize, r_min: f64, step: f64) -> Vec<Tap> {
    let width = cols / 2 + 1;
    let radii: Vec<f64> = (0..RADII).map(|j| r_min * (j as f64 * step).exp()).collect();
    let pi = std::f64::consts::PI;
    let mut taps = Vec::with_capacity(ANGLES * RADII);
    for i in 0..ANGLES {
        let (sin, cos) = (pi * i as f64 / ANGLES as f64).sin_cos();
        for &r in &radii {
            // |F(−f)| = |F(f)|: fold onto the stored half (fx ≥ 0)
            let (mut fx, mut fy) = (r * cos, r * sin);
            if fx < 0.0 {
                fx = -fx;
                fy = -fy;
            }
            let (kx, ky) = (fx * cols as f64, (fy * rows as f64).rem_euclid(rows as f64));
            let (x0, y0) = (kx.floor(), ky.floor());
            let (tx, ty) = (kx - x0, ky - y0);
            let (x0, y0) = (x0 as usize, y0 as usize);
            // clamped at the highest stored column; rows wrap (`ky` may round up to `rows`)
            let (x0, x1) = (x0.min(width - 1), (x0 + 1).min(width - 1));
            let (y0, y1) = (y0 % rows, (y0 + 1) % rows);
            let offset = |x: usize, y: usize| x * rows + y;
            // Reddy & Chatterji's emphasis of high frequencies: H = (1 − X)(2 − X)
            let x = (pi * fx).cos() * (pi * fy).cos();
            taps.push(Tap {
                at: [offset(x0, y0), offset(x1, y0), offset(x0, y1), offset(x1, y1)],
                tx,
                ty,
                emphasis: (1.0 - x) * (2.0 - x),
            });
        }
    }
    taps
}

/// A grid and the frame shape `(rows, cols)` it was built for.
type ShapedGrid = ((usize, usize), Rc<Vec<Tap>>);

thread_local! {
    /// The last grid built on this thread: frames of one camera share it (sequences).
    static GRID: RefCell<Option<ShapedGrid>> = const { RefCell::new(None) };
}

/// [`grid`] for this frame shape, from the thread's cache when the shape repeats.
fn cached_grid(rows: usize, cols: usize, r_min: f64, step: f64) -> Rc<Vec<Tap>> {
    GRID.with(|cell| {
        let mut cache = cell.borrow_mut();
        match cache.as_ref() {
            Some((shape, taps)) if *shape == (rows, cols) => taps.clone(),
            _ => {
                let taps = Rc::new(grid(rows, cols, r_min, step));
                *cache = Some(((rows, cols), taps.clone()));
                taps
            }
        }
    })
}

/// Both frames' Hann-windowed magnitude spectra, high-pass emphasised, on the log-polar
/// [`grid`] (shared: the frames have one shape).
fn log_polar_pair(real: &Plane, sim: &Plane, r_min: f64, step: f64) -> (Plane, Plane) {
    let taps = cached_grid(real.rows, real.cols, r_min, step);
    let (ma, mb) = (magnitude(real), magnitude(sim));
    let sample = |m: &[f64], t: &Tap| {
        let v = |k: usize| m[t.at[k]];
        ((1.0 - t.ty) * ((1.0 - t.tx) * v(0) + t.tx * v(1)) + t.ty * ((1.0 - t.tx) * v(2) + t.tx * v(3))) * t.emphasis
    };
    let log_polar = |m: &[f64]| Buffer::collect_exact(taps.len(), taps.iter().map(|t| sample(m, t)));
    let (va, vb) = (log_polar(&ma), log_polar(&mb));
    let all = || Buffer::filled(ANGLES * RADII, true);
    (Plane::new(ANGLES, RADII, va, all()), Plane::new(ANGLES, RADII, vb, all()))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::super::affine::Affine;
    use super::super::warp::{warp, Interp, Source};
    use super::*;

    /// A smooth pseudo-random scene: a sum of Gaussian blobs.
    pub(crate) fn scene(rows: usize, cols: usize, seed: u64) -> Vec<f64> {
        let mut state = seed;
        let mut next = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let blobs: Vec<(f64, f64, f64, f64)> =
            (0..150).map(|_| (next() * rows as f64, next() * cols as f64, 1.0 + 3.0 * next(), next() - 0.3)).collect();
        let mut out = vec![0.0; rows * cols];
        for r in 0..rows {
            for c in 0..cols {
                out[r * cols + c] = blobs
                    .iter()
                    .map(|&(y, x, s, a)| a * (-((r as f64 - y).powi(2) + (c as f64 - x).powi(2)) / (2.0 * s * s)).exp())
                    .sum();
            }
        }
        out
    }

    #[test]
    fn finds_rotation_and_scale_signs() {
        let (rows, cols) = (128, 160);
        let real_values = scene(rows, cols, 7);
        let real = Plane::new(rows, cols, real_values.clone(), vec![true; rows * cols]);
        for &(angle, scale) in &[(4.0, 1.0), (-6.0, 1.0), (2.0, 1.03), (0.0, 0.97)] {
            // sim(p) = real(M p) with M the sim → real map
            let m = Affine::rotation_scale(angle, scale, ((cols - 1) as f64 / 2.0, (rows - 1) as f64 / 2.0));
            let src = Source { data: &real_values[..], rows, cols, valid: None };
            let (values, valid) = warp(&src, &m, Interp::Bicubic, rows, cols, 0.0);
            let sim = Plane::new(rows, cols, values, valid);
            let est = rotation_scale(&real, &sim, true);
            assert!((est.angle_deg - angle).abs() < 0.25, "{angle}: {est:?}");
            assert!((est.scale - scale).abs() < 0.005, "{scale}: {est:?}");
            let rigid = rotation_scale(&real, &sim, false);
            assert_eq!(rigid.scale, 1.0);
        }
    }
}
