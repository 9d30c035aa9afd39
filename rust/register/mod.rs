//! Registration of a simulated frame onto a real one (paper §2.4: "if the position of the
//! target in the actual image does not perfectly accord with that in the simulated one,
//! image registration is required before the quality metrics").
//!
//! The result is the map `M` from simulated to real pixel coordinates (x = column,
//! y = row): `real(M·p) ≈ sim(p)`, OpenCV's `warpAffine(sim, M, (w, h)) ≈ real`. Data flow:
//!
//! - `frame`: each frame as the caller gave it ([`Frame`]); phase correlation reads clean
//!   frames' samples directly, every other step a float64 [`Plane`] (`image`) with its
//!   valid-pixel mask (caller's mask, finite values), converted once when first needed;
//!   excluded pixels take part in nothing.
//! - `phase` (method "phase"): Fourier phase correlation of Tukey-windowed frames
//!   (`window`, `fft`), subpixel peak by Newton's method on the band-limited correlation;
//!   for rotation and scale first `logpolar` (Reddy & Chatterji 1996), then the translation
//!   of the turned frame; then `refine`: Gauss–Newton on the pixel values with a grey-level
//!   gain and offset.
//! - `nmi` (method "nmi"): maximise normalised mutual information (joint histogram of the
//!   statistics kernel) — coarse exhaustive shift search, then Nelder–Mead.
//! - `warp`: bilinear or bicubic resampling with the mask of computable pixels, used by
//!   all of the above and to apply a registration.
//!
//! Every result is checked before it is returned: the overlap, `max_shift`, and how
//! distinct the match is (`confidence`); a pair that fails gets an
//! [`Error::Registration`] saying why — never a silent identity.

mod affine;
mod bands;
mod fft;
mod frame;
mod image;
mod logpolar;
mod nmi;
mod normal;
mod phase;
mod plan;
mod polarity;
mod pool;
mod refine;
mod shifts;
mod subpixel;
mod warp;
mod window;

pub use affine::{Affine, INTEGER_SNAP};
pub use frame::Frame;
pub use image::Plane;
pub use plan::{register_plan, warp_plan};
pub use warp::{coverage, warp, Interp, Source};

use crate::budget;
use crate::error::{Error, Result};
use crate::kernel::Sample;

/// The transforms a registration may find.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Model {
    /// Shift only.
    Translation,
    /// Shift and rotation.
    Rigid,
    /// Shift, rotation and uniform scale.
    Similarity,
}

impl Model {
    /// Every model, the one list of their names (exported as `_core.REGISTRATION_MODELS`).
    pub const ALL: [Model; 3] = [Model::Translation, Model::Rigid, Model::Similarity];

    pub fn parse(name: &str) -> Result<Model> {
        Model::ALL
            .into_iter()
            .find(|m| m.name() == name)
            .ok_or_else(|| unknown_name("model", &Model::ALL.map(Model::name), name))
    }

    pub fn name(self) -> &'static str {
        match self {
            Model::Translation => "translation",
            Model::Rigid => "rigid",
            Model::Similarity => "similarity",
        }
    }
}

/// How the transform is searched.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// Phase correlation; for rotation and scale log-polar spectra, refined on the pixel
    /// values.
    Phase,
    /// Maximum normalised mutual information.
    Nmi,
    /// Phase, refined on the pixel values (translations too); NMI as well when phase
    /// correlation is unsure, keeping the more distinct.
    Auto,
}

impl Method {
    /// Every method, the one list of their names (exported as `_core.REGISTRATION_METHODS`).
    pub const ALL: [Method; 3] = [Method::Auto, Method::Phase, Method::Nmi];

    pub fn parse(name: &str) -> Result<Method> {
        Method::ALL
            .into_iter()
            .find(|m| m.name() == name)
            .ok_or_else(|| unknown_name("method", &Method::ALL.map(Method::name), name))
    }

    pub fn name(self) -> &'static str {
        match self {
            Method::Phase => "phase",
            Method::Nmi => "nmi",
            Method::Auto => "auto",
        }
    }
}

/// The error for a `what` (model, method) that is none of `names`: "model must be one of
/// 'translation', 'rigid', 'similarity', got "affine"".
fn unknown_name(what: &str, names: &[&str], got: &str) -> Error {
    let quoted: Vec<String> = names.iter().map(|n| format!("'{n}'")).collect();
    Error::Value(format!("{what} must be one of {}, got {got:?}", quoted.join(", ")))
}

/// What to search for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Options {
    pub model: Model,
    pub method: Method,
    /// No frame corner may move by more than this many pixels along x or y.
    pub max_shift: Option<f64>,
}

/// A registration: the transform and how far to trust it.
#[derive(Clone, Debug, PartialEq)]
pub struct Registration {
    /// Simulated → real pixel coordinates.
    pub matrix: Affine,
    pub model: Model,
    /// The method whose result was kept (`Phase` or `Nmi`).
    pub method: Method,
    /// Distinctness of the match in [0, 1]: 1 − (best rival)/(best), see `phase`.
    pub confidence: f64,
    /// Fraction of the real frame covered by the warped simulated frame.
    pub overlap: f64,
    /// The registered frames correlate negatively (inverted grey levels).
    pub inverted: bool,
}

/// Below this overlap a registration is refused.
pub const MIN_OVERLAP: f64 = 0.25;
/// Below this confidence a registration is refused as ambiguous.
pub const AMBIGUOUS: f64 = 0.1;
/// Below this confidence a registration is reported as unsure (a warning in Python), and
/// `Method::Auto` tries NMI as well.
pub const LOW_CONFIDENCE: f64 = 0.3;
/// A rotation candidate matched this distinctly is not doubted (the 180° alternative is
/// not tried).
const CONFIDENT: f64 = 0.5;
/// Smallest frame side registered.
const MIN_SIDE: usize = 8;
/// Fewest valid pixels a frame must have.
const MIN_VALID: usize = 64;
/// Smoothing (pixels) of both frames before the Gauss–Newton refinement: noise in the
/// gradients biases the solution; measured, σ = 1 halved the error on noisy real frames.
const REFINE_SMOOTHING: f64 = 1.0;
/// A refinement that moves a frame corner further than this from its phase-correlation
/// start has left the basin of the right answer; the start is kept.
const MAX_REFINE_MOVE: f64 = 3.0;

/// Register `sim` onto `real` (same shape `(rows, cols)`, any supported sample types).
/// `mask` false excludes a pixel position in both frames; NaN/Inf pixels are excluded.
pub fn register<T: Sample, U: Sample>(
    real: &[T],
    sim: &[U],
    shape: (usize, usize),
    mask: Option<&[bool]>,
    opts: &Options,
) -> Result<Registration> {
    let (rows, cols) = shape;
    budget::guard("registration", Error::Registration, || {
        let real = Frame::new(real, rows, cols, mask, "real")?;
        let sim = Frame::new(sim, rows, cols, mask, "simulated")?;
        register_frames(&real, &sim, opts)
    })
}

/// [`register`] on frames already wrapped. Memory the system refuses is an
/// `Error::Registration` (the caller checks [`register_plan`] against its budget first).
pub fn register_frames(real: &Frame, sim: &Frame, opts: &Options) -> Result<Registration> {
    budget::guard("registration", Error::Registration, || search(real, sim, opts))
}

fn search(real: &Frame, sim: &Frame, opts: &Options) -> Result<Registration> {
    if (real.rows, real.cols) != (sim.rows, sim.cols) {
        // every caller wraps both frames with one shape (the bindings check the arrays given)
        return Err(Error::Value(format!(
            "internal: registration of frames of two shapes, {}×{} and {}×{}",
            real.rows, real.cols, sim.rows, sim.cols
        )));
    }
    if real.rows < MIN_SIDE || real.cols < MIN_SIDE {
        return Err(Error::Registration(format!(
            "frames of {}×{} pixels are too small to register (need at least {MIN_SIDE}×{MIN_SIDE})",
            real.rows, real.cols
        )));
    }
    if let Some(m) = opts.max_shift {
        if !(m.is_finite() && m >= 0.0) {
            return Err(Error::Value(format!("max_shift must be a finite number >= 0, got {m}")));
        }
    }
    check_content(real, "real")?;
    check_content(sim, "simulated")?;
    let fit = match opts.method {
        Method::Phase => phase_fit(real, sim, opts)?,
        Method::Nmi => nmi_fit(real, sim, opts)?,
        Method::Auto => {
            let phase = phase_fit(real, sim, opts)?;
            if phase.confidence >= LOW_CONFIDENCE {
                phase
            } else {
                let nmi = nmi_fit(real, sim, opts)?;
                if nmi.confidence > phase.confidence {
                    nmi
                } else {
                    phase
                }
            }
        }
    };
    finish(real, sim, fit, opts)
}

/// A frame must have enough valid pixels and not be constant.
fn check_content(frame: &Frame, what: &str) -> Result<()> {
    if frame.n_valid < MIN_VALID {
        return Err(Error::Registration(format!(
            "cannot register: the {what} frame has {} valid pixels (the others are NaN/Inf or masked); \
             need at least {MIN_VALID}",
            frame.n_valid
        )));
    }
    if let Some(level) = frame.flat_level() {
        return Err(Error::Registration(format!(
            "cannot register: the {what} frame is flat (its {} valid pixels all equal {level}); \
             there is nothing to align",
            frame.n_valid
        )));
    }
    Ok(())
}

/// A candidate transform before the checks.
struct Fit {
    matrix: Affine,
    method: Method,
    confidence: f64,
    /// Integer shift of the best rival match (for the ambiguity message).
    rival: (isize, isize),
    /// That rival matches with the other polarity.
    rival_flipped: bool,
    /// The correlation peak lay on the edge of the max_shift window and rose beyond it.
    beyond_limit: bool,
    /// The frames correlate negatively at this transform.
    inverted: bool,
}

/// The frame centre `(x, y)`.
fn centre(rows: usize, cols: usize) -> (f64, f64) {
    ((cols as f64 - 1.0) / 2.0, (rows as f64 - 1.0) / 2.0)
}

/// `out(q) = plane(to_source·q)`, bilinear, with its mask.
fn warp_plane(plane: &Plane, to_source: &Affine) -> Plane {
    let src = Source { data: &plane.values[..], rows: plane.rows, cols: plane.cols, valid: Some(&plane.valid[..]) };
    let (values, valid) = warp(&src, to_source, Interp::Bilinear, plane.rows, plane.cols, 0.0);
    Plane::new(plane.rows, plane.cols, values, valid)
}

fn phase_fit(real: &Frame, sim: &Frame, opts: &Options) -> Result<Fit> {
    let (start, peak) = match opts.model {
        Model::Translation => {
            let peak = phase::correlate(real, sim, opts.max_shift);
            (Affine::translation(peak.dx, peak.dy), peak)
        }
        Model::Rigid | Model::Similarity => {
            let turn = logpolar::rotation_scale(real.plane(), sim.plane(), opts.model == Model::Similarity);
            // a magnitude spectrum knows the angle modulo 180°: the other candidate is tried
            // unless the first gives a confident match, and the better kept
            let mut best: Option<(Affine, phase::Peak)> = None;
            for angle in [turn.angle_deg, turn.angle_deg + 180.0] {
                if best.as_ref().is_some_and(|(_, b)| b.confidence >= CONFIDENT) {
                    break;
                }
                let rotation = Affine::rotation_scale(angle, turn.scale, centre(real.rows, real.cols));
                let Some(back) = rotation.inverse() else { continue };
                let turned = Frame::from(warp_plane(sim.plane(), &back));
                if turned.n_valid < MIN_VALID {
                    continue;
                }
                let peak = phase::correlate(real, &turned, opts.max_shift);
                if best.as_ref().is_none_or(|(_, b)| peak.height > b.height) {
                    best = Some((Affine::translation(peak.dx, peak.dy).compose(&rotation), peak));
                }
            }
            best.ok_or_else(|| Error::Registration("cannot register: the rotation found leaves no overlap".into()))?
        }
    };
    // A translation from phase correlation is final for `Method::Phase` (accurate to a few
    // hundredths of a pixel, docs/registration.md); `Method::Auto` refines it on the pixel
    // values too (about 3× smaller error, twice the time), without coarse levels since it is
    // already within a fraction of a pixel. Rotation and scale from log-polar spectra are
    // always refined.
    let refine_it = opts.model != Model::Translation || opts.method == Method::Auto;
    let coarse = opts.model != Model::Translation;
    let refined = if refine_it {
        let smoothed = |frame: &Frame| frame.plane().smoothed(REFINE_SMOOTHING);
        refine::refine(&smoothed(real), &smoothed(sim), &start, opts.model, coarse)
    } else {
        None
    };
    let (matrix, inverted) = match refined {
        Some(r) if r.matrix.corner_distance(&start, real.rows, real.cols) <= MAX_REFINE_MOVE => {
            (r.matrix, r.gain < 0.0)
        }
        _ => (start, peak.sign < 0.0),
    };
    Ok(Fit {
        matrix,
        method: Method::Phase,
        confidence: peak.confidence,
        rival: peak.rival,
        rival_flipped: peak.rival_flipped,
        beyond_limit: peak.beyond_limit,
        inverted,
    })
}

fn nmi_fit(real: &Frame, sim: &Frame, opts: &Options) -> Result<Fit> {
    let (real_plane, sim_plane) = (real.plane(), sim.plane());
    let starts = match opts.model {
        Model::Translation => vec![Affine::IDENTITY],
        Model::Rigid | Model::Similarity => {
            let turn = logpolar::rotation_scale(real_plane, sim_plane, opts.model == Model::Similarity);
            [turn.angle_deg, turn.angle_deg + 180.0]
                .iter()
                .map(|&a| Affine::rotation_scale(a, turn.scale, centre(real.rows, real.cols)))
                .collect()
        }
    };
    let mut best: Option<nmi::NmiFit> = None;
    for start in &starts {
        let fit = nmi::register_nmi(real_plane, sim_plane, start, opts.model, opts.max_shift)?;
        if best.as_ref().is_none_or(|b| fit.nmi > b.nmi) {
            best = Some(fit);
        }
    }
    let fit = best.expect("at least one start");
    let (confidence, rival, rival_flipped) = match flipped_rival(real, sim, &fit.matrix) {
        Some((c, at)) if c < fit.confidence => (c, at, true),
        _ => (fit.confidence, fit.rival, false),
    };
    Ok(Fit {
        matrix: fit.matrix,
        method: Method::Nmi,
        confidence,
        rival,
        rival_flipped,
        beyond_limit: false,
        inverted: fit.inverted,
    })
}

/// The check of [`polarity`] for a transform found by NMI (which cannot tell the
/// polarities apart either): around its integer shift, the simulated frame turned first if
/// the transform rotates or scales.
fn flipped_rival(real: &Frame, sim: &Frame, matrix: &Affine) -> Option<(f64, (isize, isize))> {
    let [[a, b, tx], [c, d, ty]] = matrix.0;
    if [a, b, c, d] == [1.0, 0.0, 0.0, 1.0] {
        return polarity::check(real, sim, (ty.round() as isize, tx.round() as isize));
    }
    let turned = Frame::from(warp_plane(sim.plane(), &matrix.inverse()?));
    (turned.n_valid >= MIN_VALID).then(|| polarity::check(real, &turned, (0, 0)))?
}

/// Largest displacement of a frame corner along x or y.
fn max_axis_displacement(m: &Affine, rows: usize, cols: usize) -> f64 {
    let (xm, ym) = ((cols - 1) as f64, (rows - 1) as f64);
    [(0.0, 0.0), (xm, 0.0), (0.0, ym), (xm, ym)]
        .iter()
        .map(|&(x, y)| {
            let (u, v) = m.apply(x, y);
            (u - x).abs().max((v - y).abs())
        })
        .fold(0.0, f64::max)
}

/// Check a candidate (max_shift, overlap, confidence) and measure its overlap and polarity.
fn finish(real: &Frame, sim: &Frame, fit: Fit, opts: &Options) -> Result<Registration> {
    let (rows, cols) = (real.rows, real.cols);
    if !(0.0..=1.0).contains(&fit.confidence) {
        return Err(Error::Registration(format!(
            "cannot register: how distinct the match is could not be measured (confidence {}); the frames \
             may hold values that no step can use",
            fit.confidence
        )));
    }
    let to_sim = fit
        .matrix
        .inverse()
        .filter(|m| m.is_finite())
        .ok_or_else(|| Error::Registration(format!("cannot register: degenerate transform {:?}", fit.matrix.0)))?;
    if let Some(limit) = opts.max_shift {
        let moved = max_axis_displacement(&fit.matrix, rows, cols);
        if fit.beyond_limit || moved > limit + 1e-9 {
            return Err(Error::Registration(format!(
                "cannot register within max_shift={limit}: the best match {} (a frame corner moves {moved:.2} px); \
                 raise max_shift if so large a shift is plausible",
                if fit.beyond_limit { "lies beyond the search range" } else { "is outside it" }
            )));
        }
    }
    let covered = coverage((rows, cols), sim.valid(), &to_sim, Interp::Bilinear, (rows, cols));
    let overlap = covered as f64 / (rows * cols) as f64;
    if overlap < MIN_OVERLAP {
        return Err(Error::Registration(format!(
            "cannot register: no overlap — the best match leaves the frames overlapping on {:.1}% of the real \
             frame (need {:.0}%); they may show different scenes, or max_shift allows too large a shift",
            100.0 * overlap,
            100.0 * MIN_OVERLAP
        )));
    }
    if fit.confidence < AMBIGUOUS {
        let (dy, dx) = fit.rival;
        return Err(Error::Registration(if fit.rival_flipped {
            format!(
                "cannot register: ambiguous match (confidence {:.3} < {AMBIGUOUS}): a shift of (dy, dx) = ({dy}, {dx}) px \
                 with the opposite polarity (grey levels inverted relative to the best match) matches almost as well \
                 as the best. The pattern is periodic: shifted by a pixel it is its own negative (a checkerboard or \
                 one-pixel lines), so a shift cannot be told from an inversion; mask the pattern or register on a part \
                 of the scene without it",
                fit.confidence
            )
        } else {
            format!(
                "cannot register: ambiguous match (confidence {:.3} < {AMBIGUOUS}): a shift of (dy, dx) = ({dy}, {dx}) px \
                 matches almost as well as the best. Periodic patterns (bar targets), featureless, very noisy or \
                 unrelated frames do this; restrict max_shift below the pattern's period, or mask it",
                fit.confidence
            )
        }));
    }
    Ok(Registration {
        matrix: fit.matrix,
        model: opts.model,
        method: fit.method,
        confidence: fit.confidence,
        overlap,
        inverted: fit.inverted,
    })
}

#[cfg(test)]
mod tests;
