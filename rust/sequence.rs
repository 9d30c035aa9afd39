//! Sequence engine: score many (real, simulated) frame pairs read from files, in
//! parallel over pairs, with bounded memory.
//!
//! For every index `i`, both frames are decoded ([`crate::io::decode_frame`]), checked
//! for matching shape and sample type, and reduced to a [`PairStats`] by
//! [`crate::stats::pair_stats`]. A frame that cannot be read or scored becomes an error
//! *for that index only*; every other pair is still scored.
//!
//! Parallelism is across pairs: a rayon pool of `workers` threads runs `workers`
//! long-lived loops that each take the next index from a shared counter. So at most two
//! decoded frames are alive per loop whatever the sequence length (a loop blocked inside
//! the kernel may, through work stealing, run one more loop's pair: still bounded). The
//! kernel's own chunk-level `par_iter` runs on the same pool, where every thread is busy
//! with its own pair, so it stays on its thread (no oversubscription) and only spreads
//! out at the tail, when threads run out of pairs.
//!
//! Memory: each pair is planned against the per-pair budget (`max_bytes`, docs/design.md
//! §14) once its real frame is decoded ([`pair_plan`]): both frames, their float64 copies,
//! registration and resampling. A pair over budget is that pair's error; the simulated frame
//! is decoded within what the real one leaves.
//!
//! Outcomes reach the consumer through [`stream_pairs`]: a bounded queue of
//! [`QUEUE_PER_WORKER`] outcomes per worker, filled in completion order. A worker whose
//! outcome finds the queue full waits before decoding its next pair (back-pressure), so a
//! slow consumer bounds the memory held by finished pairs. A shared [`AtomicUsize`] counts
//! finished pairs; an [`AtomicBool`] (or dropping the stream) cancels the pairs not yet
//! started (Ctrl-C).

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, RecvTimeoutError, TryRecvError};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::budget::{self, Plan};
use crate::fingerprint::{self, Fingerprint};
use crate::hist::Entropies;
use crate::io::{self, DecodeOptions, Frame, FrameData};
use crate::kernel::Sample;
use crate::register::{self, Affine, Interp, Source as WarpSource};
use crate::stats::{self, HistRequest, PairStats, Request};
use crate::{Error, Result};

/// Where one frame lives: a file and (for multi-page TIFF) a page.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Source {
    pub path: PathBuf,
    pub page: usize,
}

impl Source {
    pub fn new(path: impl Into<PathBuf>, page: usize) -> Source {
        Source { path: path.into(), page }
    }

    fn label(&self) -> String {
        if self.page == 0 {
            self.path.display().to_string()
        } else {
            format!("{}[{}]", self.path.display(), self.page)
        }
    }
}

/// What to compute for every pair (the per-frame [`Request`] template) and how to decode.
#[derive(Clone, Debug)]
pub struct SeqRequest {
    pub sse: bool,
    pub moments: bool,
    pub hist: Option<HistRequest>,
    /// Integer frames: allowed values `[lo, hi]` (from `bits`); ignored for float frames.
    pub valid: Option<(i64, i64)>,
    /// Float frames: exclude NaN/Inf pairs instead of failing the pair.
    pub mask_nonfinite: bool,
    /// Channel to decode from the real / simulated frames (EXR channel name, or PNG/TIFF
    /// channel); `None` = the only one / "Y".
    pub real_channel: Option<String>,
    pub sim_channel: Option<String>,
    /// Report the real frame's (min, max) over its finite values (for a PSNR peak of the
    /// real frame's range).
    pub real_extent: bool,
    pub max_pixels: u64,
    /// The memory budget of one pair's work, in bytes (decoding both frames included);
    /// `None` = [`io::DEFAULT_MAX_BYTES`].
    pub max_bytes: Option<u64>,
    /// Registration: the simulated frame is resampled onto the real one and only the
    /// overlap is scored (both frames as float64).
    pub warp: Option<Warp>,
    /// Fingerprint both input files of every pair, in the same read as the decode
    /// ([`crate::fingerprint`]; [`PairOutcome::fingerprints`]).
    pub fingerprint: bool,
}

/// How pairs are registered before scoring.
#[derive(Clone, Debug)]
pub enum Warp {
    /// One registration, found beforehand, applied to every pair (fixed camera geometry).
    Fixed(FixedWarp),
    /// Every pair registered on its own, on its worker.
    Each(EachWarp),
}

/// What a registration of every pair searches for, and how the simulated frame is resampled.
#[derive(Clone, Debug)]
pub struct EachWarp {
    pub options: register::Options,
    pub interp: Interp,
}

/// A fixed registration: real → simulated pixel coordinates (the inverse of the
/// registration's matrix) and the interpolation.
#[derive(Clone, Debug)]
pub struct FixedWarp {
    pub to_source: Affine,
    pub interp: Interp,
}

impl FixedWarp {
    /// From a registration's matrix (simulated → real, 6 floats row-major) and an
    /// interpolation order (1 or 3).
    pub fn from_matrix(matrix: [f64; 6], order: u32) -> Result<FixedWarp> {
        let m = Affine([[matrix[0], matrix[1], matrix[2]], [matrix[3], matrix[4], matrix[5]]]);
        FixedWarp::new(&m, interp_of(order)?)
    }

    /// The warp that applies `matrix` (simulated → real), integer-snapped
    /// ([`Affine::snapped`]).
    pub fn new(matrix: &Affine, interp: Interp) -> Result<FixedWarp> {
        let to_source = matrix
            .snapped()
            .inverse()
            .filter(Affine::is_finite)
            .ok_or_else(|| Error::Value(format!("the registration matrix {:?} cannot be inverted", matrix.0)))?;
        Ok(FixedWarp { to_source, interp })
    }
}

fn interp_of(order: u32) -> Result<Interp> {
    Interp::from_order(order)
        .ok_or_else(|| Error::Value(format!("warp order must be 1 (bilinear) or 3 (bicubic), got {order}")))
}

impl EachWarp {
    pub fn new(options: register::Options, order: u32) -> Result<EachWarp> {
        Ok(EachWarp { options, interp: interp_of(order)? })
    }
}

/// A registered pair scored: what [`Warp::score_pair`] returns.
#[derive(Clone, Debug)]
pub struct Aligned {
    /// The pair's own registration ([`Warp::Each`]); None for a fixed one.
    pub registration: Option<register::Registration>,
    /// The statistics over the scored pixels, both frames as float64.
    pub stats: PairStats,
    /// The real frame's (min, max) over the scored pixels, when asked for (the PSNR peak
    /// "range" of what is scored).
    pub extent: Option<(f64, f64)>,
    /// The simulated frame resampled onto the real one (NaN where it does not cover it).
    pub sim: Vec<f64>,
    /// The scored pixels: the overlap, and the caller's mask when given.
    pub scored: Vec<bool>,
}

/// One frame pair in memory: samples of one type, `shape = (rows, cols)` row-major, and the
/// pixel positions that take part (`mask` false excludes a position in both frames).
#[derive(Clone, Copy, Debug)]
pub struct PairSlices<'a, T> {
    pub real: &'a [T],
    pub sim: &'a [T],
    pub shape: (usize, usize),
    pub mask: Option<&'a [bool]>,
}

/// One mask for every pair of a sequence: the pixel positions scored (`true`), row-major,
/// shared by the workers (never copied per pair).
#[derive(Clone, Debug)]
pub struct SeqMask {
    values: Arc<[bool]>,
    shape: (usize, usize),
}

impl SeqMask {
    /// A mask of `shape` (`values` row-major); an error when the lengths differ or no pixel
    /// is scored.
    pub fn new(values: Arc<[bool]>, shape: (usize, usize)) -> Result<SeqMask> {
        if values.len() != shape.0 * shape.1 {
            return Err(Error::Shape(format!("mask: {} values for a ({}, {}) mask", values.len(), shape.0, shape.1)));
        }
        if !values.iter().any(|&keep| keep) {
            return Err(Error::Value("mask: no pixel is scored (every value is false)".into()));
        }
        Ok(SeqMask { values, shape })
    }

    /// The mask's values for a pair of `shape` frames, or a shape error.
    fn for_shape(&self, shape: (usize, usize)) -> Result<&[bool]> {
        if shape != self.shape {
            return Err(Error::Shape(format!(
                "the mask has shape ({}, {}), the frames ({}, {})",
                self.shape.0, self.shape.1, shape.0, shape.1
            )));
        }
        Ok(&self.values)
    }
}

impl Warp {
    /// What scoring a `shape` pair through this registration holds besides the frames as
    /// given, and the kind of error over budget: the real frame as float64, the resampled
    /// frame, its overlap and the scored mask (18 bytes a pixel) or, when the pair is
    /// registered first, registration's working memory if that is more.
    pub fn plan(&self, shape: (usize, usize)) -> (Plan, budget::Kind) {
        let scoring = Plan::new("resampling and scoring a registered pair", shape, 18.0, 0);
        match self {
            Warp::Fixed(_) => (scoring, Error::Value),
            Warp::Each(each) => {
                let search = register::register_plan(shape, &each.options);
                (if search.bytes > scoring.bytes { search } else { scoring }, Error::Registration)
            }
        }
    }

    /// Score a pair through this registration, the one path of every registered pair (files
    /// of a sequence, arrays of a sequence, a single pair): integer levels checked against
    /// `kreq.valid`; with [`Warp::Each`] the pair registered (over `mask`); the simulated
    /// frame resampled onto the real one (masked simulated pixels unused); the statistics
    /// over the overlap ∩ `mask`, both frames as float64.
    pub fn score_pair<T: Sample>(
        &self,
        pair: &PairSlices<'_, T>,
        kreq: &Request,
        want_extent: bool,
    ) -> Result<Aligned> {
        let PairSlices { real, sim, shape: (rows, cols), mask } = *pair;
        if let Some(valid) = kreq.valid {
            check_levels(real, valid, "real")?;
            check_levels(sim, valid, "sim")?;
        }
        let (registration, fixed) = match self {
            Warp::Fixed(fixed) => (None, fixed.clone()),
            Warp::Each(each) => {
                let reg = register::register_frames(
                    &register::Frame::new(real, rows, cols, mask, "real")?,
                    &register::Frame::new(sim, rows, cols, mask, "simulated")?,
                    &each.options,
                )?;
                let fixed = FixedWarp::new(&reg.matrix, each.interp)?;
                (Some(reg), fixed)
            }
        };
        let src = WarpSource { data: sim, rows, cols, valid: mask };
        let (aligned, overlap) = register::warp(&src, &fixed.to_source, fixed.interp, rows, cols, f64::NAN);
        let scored = match mask {
            None => overlap,
            Some(mask) => overlap.iter().zip(mask).map(|(&covered, &keep)| covered && keep).collect(),
        };
        let real = budget::try_collect(real.len(), real.iter().map(|v| v.to_f64()))?;
        let (stats, extent) = overlap_stats(&real, &aligned, &scored, kreq, want_extent)?;
        Ok(Aligned { registration, stats, extent, sim: aligned, scored })
    }

    /// [`Warp::score_pair`] on two decoded frames (of one sample type, else a shape error)
    /// over `mask`.
    fn score_frames(
        &self,
        (r, s): (&Frame, &Frame),
        mask: Option<&[bool]>,
        kreq: &Request,
        want_extent: bool,
    ) -> Result<Aligned> {
        use FrameData::*;
        let shape = (r.rows, r.cols);
        macro_rules! pair {
            ($a:expr, $b:expr) => {
                self.score_pair(&PairSlices { real: $a, sim: $b, shape, mask }, kreq, want_extent)
            };
        }
        match (&r.data, &s.data) {
            (U8(a), U8(b)) => pair!(a, b),
            (U16(a), U16(b)) => pair!(a, b),
            (I16(a), I16(b)) => pair!(a, b),
            (U32(a), U32(b)) => pair!(a, b),
            (F16(a), F16(b)) => pair!(a, b),
            (F32(a), F32(b)) => pair!(a, b),
            (F64(a), F64(b)) => pair!(a, b),
            (a, b) => Err(dtype_mismatch(a, b)),
        }
    }
}

/// Integer samples within `[lo, hi]` (the kernel's check, made before a warp turns the
/// frames into floats); float samples pass.
fn check_levels<T: Sample>(data: &[T], (lo, hi): (i64, i64), which: &str) -> Result<()> {
    if !T::IS_INT {
        return Ok(());
    }
    let (min, max) = data.iter().fold((i64::MAX, i64::MIN), |(a, b), x| (a.min(x.to_i64()), b.max(x.to_i64())));
    match [min, max].into_iter().find(|&x| x < lo || x > hi) {
        Some(bad) => Err(Error::Range(format!(
            "{which} frame: value {bad} outside the valid range {lo} .. {hi} (set bits to the camera's bit depth, or \
             leave it unset)"
        ))),
        None => Ok(()),
    }
}

impl Default for SeqRequest {
    fn default() -> Self {
        SeqRequest {
            sse: true,
            moments: true,
            hist: Some(HistRequest::Bins { bins: 256, range: None }),
            valid: None,
            mask_nonfinite: false,
            real_channel: None,
            sim_channel: None,
            real_extent: false,
            max_pixels: io::DEFAULT_MAX_PIXELS,
            max_bytes: None,
            warp: None,
            fingerprint: false,
        }
    }
}

/// Result of one pair.
#[derive(Clone, Debug)]
pub struct PairOutcome {
    pub index: usize,
    pub stats: Result<PairStats>,
    /// `(rows, cols)` of the real frame, when it was decoded.
    pub shape: Option<(usize, usize)>,
    /// Sample type of the real frame ("uint16", "float32", ...), when it was decoded.
    pub dtype: Option<&'static str>,
    /// The histogram's entropies, computed on the worker (not on the thread that hands
    /// outcomes to Python, which all workers share).
    pub entropies: Option<Entropies>,
    /// The real frame's (min, max) over its finite scored values (the overlap, when
    /// registered), when asked for.
    pub real_extent: Option<(f64, f64)>,
    /// The pair's own registration ([`Warp::Each`]), when it was found.
    pub registration: Option<register::Registration>,
    /// With [`SeqRequest::fingerprint`]: the fingerprints of the real and the simulated file,
    /// of the bytes decoded; None when a file changed while it was decoded.
    pub fingerprints: Option<(Fingerprint, Fingerprint)>,
}

/// (min, max) over the finite values; None when there are none.
fn finite_extent(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    values.filter(|x| x.is_finite()).fold(None, |acc, x| match acc {
        None => Some((x, x)),
        Some((lo, hi)) => Some((lo.min(x), hi.max(x))),
    })
}

/// (min, max) over the finite values of a frame (within `mask`); None when it has none.
fn extent(data: &FrameData, mask: Option<&[bool]>) -> Option<(f64, f64)> {
    fn fold<T: Copy>(v: &[T], mask: Option<&[bool]>, to_f64: impl Fn(T) -> f64) -> Option<(f64, f64)> {
        match mask {
            None => finite_extent(v.iter().map(|&x| to_f64(x))),
            Some(mask) => finite_extent(v.iter().zip(mask).filter(|&(_, &keep)| keep).map(|(&x, _)| to_f64(x))),
        }
    }
    /// An integer frame's ends compared as integers (vectorised), then as f64 (exact).
    fn int_fold<T: Copy + Ord + Into<f64>>(v: &[T], mask: Option<&[bool]>) -> Option<(f64, f64)> {
        if mask.is_some() {
            return fold(v, mask, Into::into);
        }
        let (&first, rest) = v.split_first()?;
        let (lo, hi) = rest.iter().fold((first, first), |(lo, hi), &x| (lo.min(x), hi.max(x)));
        Some((lo.into(), hi.into()))
    }
    match data {
        FrameData::U8(v) => int_fold(v, mask),
        FrameData::U16(v) => int_fold(v, mask),
        FrameData::I16(v) => int_fold(v, mask),
        FrameData::U32(v) => int_fold(v, mask),
        FrameData::F16(v) => fold(v, mask, f64::from),
        FrameData::F32(v) => fold(v, mask, f64::from),
        FrameData::F64(v) => fold(v, mask, |x| x),
    }
}

fn run_kernel(r: &FrameData, s: &FrameData, req: &Request) -> Result<PairStats> {
    use FrameData::*;
    match (r, s) {
        (U8(a), U8(b)) => stats::pair_stats(a, b, req),
        (U16(a), U16(b)) => stats::pair_stats(a, b, req),
        (I16(a), I16(b)) => stats::pair_stats(a, b, req),
        (U32(a), U32(b)) => stats::pair_stats(a, b, req),
        (F16(a), F16(b)) => stats::pair_stats(a, b, &Request { valid: None, ..req.clone() }),
        (F32(a), F32(b)) => stats::pair_stats(a, b, &Request { valid: None, ..req.clone() }),
        (F64(a), F64(b)) => stats::pair_stats(a, b, &Request { valid: None, ..req.clone() }),
        (a, b) => Err(dtype_mismatch(a, b)),
    }
}

fn dtype_mismatch(a: &FrameData, b: &FrameData) -> Error {
    Error::Shape(format!(
        "real and sim frames differ in dtype: {} vs {}; convert one so no silent rounding happens",
        a.dtype_name(),
        b.dtype_name()
    ))
}

fn prefix(err: Error, what: &str) -> Error {
    match err {
        Error::Shape(m) => Error::Shape(format!("{what}: {m}")),
        Error::Range(m) => Error::Range(format!("{what}: {m}")),
        Error::Registration(m) => Error::Registration(format!("{what}: {m}")),
        Error::Value(m) => Error::Value(format!("{what}: {m}")),
        // decode errors already start with the path
        Error::Frame(m) => Error::Frame(m),
    }
}

/// Files up to this share of the decoding budget are read whole, hashed and decoded from
/// memory when fingerprints are asked for (the buffer is held beside the decode).
const WHOLE_FILE_SHARE: u64 = 8;

/// Decode a frame and, with [`SeqRequest::fingerprint`], fingerprint the bytes decoded: a
/// first page held in memory is hashed as read; a later page of a stack, or a file beyond
/// the in-memory share, gets the digest taken before decoding if the file did not change
/// meanwhile (the module notes of [`crate::fingerprint`]). `max_bytes` bounds the decode,
/// the file's bytes held in memory included.
fn decode(
    src: &Source,
    channel: &Option<String>,
    req: &SeqRequest,
    max_bytes: u64,
) -> Result<(Frame, Option<Fingerprint>)> {
    let opts = DecodeOptions { channel: channel.clone(), max_pixels: req.max_pixels, max_bytes, page: src.page };
    if !req.fingerprint {
        return Ok((io::decode_frame(&src.path, &opts)?, None));
    }
    if src.page == 0 {
        if let Some((bytes, fp)) = fingerprint::read_whole(&src.path, opts.max_bytes / WHOLE_FILE_SHARE)? {
            let held = budget::size_of_vec::<u8>(bytes.len());
            let opts = DecodeOptions { max_bytes: max_bytes.saturating_sub(held), ..opts };
            let frame = io::decode_bytes(&bytes, &src.path.display().to_string(), &opts)?;
            return Ok((frame, Some(fp)));
        }
    }
    let before = fingerprint::digest_before(&src.path);
    let frame = io::decode_frame(&src.path, &opts)?;
    let fp = before.filter(|(state, _)| fingerprint::unchanged(&src.path, state)).map(|(_, fp)| fp);
    Ok((frame, fp))
}

/// Bytes of one sample of `data`.
fn sample_bytes(data: &FrameData) -> usize {
    match data {
        FrameData::U8(_) => 1,
        FrameData::U16(_) | FrameData::I16(_) | FrameData::F16(_) => 2,
        FrameData::U32(_) | FrameData::F32(_) => 4,
        FrameData::F64(_) => 8,
    }
}

/// What one pair of `shape` frames whose real frame is `real` holds at its peak under `req`
/// (both frames in their sample type throughout), and the kind of error over budget is:
/// - unregistered: the kernel's float32 copies of float16 frames;
/// - a fixed warp: the real frame as float64, the simulated one resampled and its overlap;
/// - registering each pair: both frames as float64, then registration's working memory
///   ([`register::register_plan`]) or the resampled frame and its overlap, whichever is more;
/// - with a sequence's mask (`masked`): the mask (1 byte a pixel, counted in every pair's
///   budget though the run holds it once) and, registered, the overlap within it (1 more).
pub fn pair_plan(shape: (usize, usize), real: &FrameData, req: &SeqRequest, masked: bool) -> (Plan, budget::Kind) {
    let frames = 2.0 * sample_bytes(real) as f64;
    let mask = match (masked, req.warp.is_some()) {
        (false, _) => 0.0,
        (true, false) => 1.0,
        (true, true) => 2.0,
    };
    match &req.warp {
        None => {
            let widened = if matches!(real, FrameData::F16(_)) { 8.0 } else { 0.0 };
            (Plan::new("scoring a frame pair", shape, frames + widened + mask, 0), Error::Value)
        }
        Some(Warp::Fixed(_)) => {
            (Plan::new("resampling and scoring a frame pair", shape, frames + 17.0 + mask, 0), Error::Value)
        }
        Some(Warp::Each(each)) => {
            let search = register::register_plan(shape, &each.options);
            let resampled = register::warp_plan(shape).bytes;
            let held = Plan::new("", shape, frames + 16.0 + mask, 0).bytes;
            let operation = format!("{} and scoring of a frame pair", search.operation);
            (Plan { operation, shape, bytes: search.bytes.max(resampled).saturating_add(held) }, Error::Registration)
        }
    }
}

/// A pair's statistics, and the real frame's (min, max) over the pixels scored when asked.
type Scored = (PairStats, Option<(f64, f64)>);

/// The statistics of a registered pair over its overlap and, when `want_extent`, the real
/// frame's (min, max) over the same pixels (the PSNR peak "range" of what is scored, as
/// `evaluate` takes it).
fn overlap_stats(real: &[f64], aligned: &[f64], overlap: &[bool], kreq: &Request, want_extent: bool) -> Result<Scored> {
    let st = stats::pair_stats(real, aligned, &Request { mask: Some(overlap), valid: None, ..kreq.clone() })?;
    let extent = if want_extent {
        finite_extent(real.iter().zip(overlap).filter(|&(_, &keep)| keep).map(|(&v, _)| v))
    } else {
        None
    };
    Ok((st, extent))
}

/// A decoded real frame and its file's fingerprint (with [`SeqRequest::fingerprint`]).
pub type Decoded = (Frame, Option<Fingerprint>);

/// Decode a real frame once, for every simulated frame scored against it (a panic of the
/// decoder becomes that frame's error).
pub fn decode_real(real: &Source, req: &SeqRequest) -> Result<Decoded> {
    let max_bytes = req.max_bytes.unwrap_or(io::DEFAULT_MAX_BYTES);
    catch_unwind(AssertUnwindSafe(|| decode(real, &req.real_channel, req, max_bytes)))
        .unwrap_or_else(|payload| Err(caught(payload.as_ref(), &real.label())))
}

/// The error of a caught panic of `what`'s work: an allocation the budget refused as that
/// error, anything else as an internal error.
fn caught(payload: &(dyn std::any::Any + Send), what: &str) -> Error {
    match budget::refused_error(payload) {
        Some(err) => prefix(err, what),
        None => Error::Value(format!("{what}: internal error: {}", panic_message(payload))),
    }
}

fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "panic".into())
}

/// Decode and score one pair on the current thread (and the current rayon pool), over `mask`
/// when given.
pub fn score_pair(index: usize, real: &Source, sim: &Source, req: &SeqRequest, mask: Option<&SeqMask>) -> PairOutcome {
    score_against(index, real, &decode_real(real, req), sim, req, mask)
}

/// Score a simulated frame against a real frame decoded beforehand ([`decode_real`]; its
/// error is this pair's error), over `mask` when given (a mask of another shape than the
/// frames is this pair's error).
pub fn score_against(
    index: usize,
    real: &Source,
    decoded: &Result<Decoded>,
    sim: &Source,
    req: &SeqRequest,
    mask: Option<&SeqMask>,
) -> PairOutcome {
    let mut out = PairOutcome {
        index,
        stats: Err(Error::Value(String::new())),
        shape: None,
        dtype: None,
        entropies: None,
        real_extent: None,
        registration: None,
        fingerprints: None,
    };
    let body = || -> Result<PairStats> {
        let what = || format!("{} vs {}", real.label(), sim.label());
        let max_bytes = req.max_bytes.unwrap_or(io::DEFAULT_MAX_BYTES);
        let (r, real_fp) = decoded.as_ref().map_err(Clone::clone)?;
        out.shape = Some((r.rows, r.cols));
        out.dtype = Some(r.data.dtype_name());
        let mask = mask.map(|m| m.for_shape((r.rows, r.cols))).transpose().map_err(|e| prefix(e, &what()))?;
        let (plan, kind) = pair_plan((r.rows, r.cols), &r.data, req, mask.is_some());
        plan.check(max_bytes, kind).map_err(|e| prefix(e, &what()))?;
        if req.real_extent && req.warp.is_none() {
            out.real_extent = extent(&r.data, mask);
        }
        let held = budget::size_of_vec::<u8>(r.data.len() * sample_bytes(&r.data));
        let (s, sim_fp) = decode(sim, &req.sim_channel, req, max_bytes.saturating_sub(held))?;
        out.fingerprints = real_fp.zip(sim_fp);
        if (r.rows, r.cols) != (s.rows, s.cols) {
            return Err(Error::Shape(format!(
                "{}: real and sim frames differ in shape: ({}, {}) vs ({}, {})",
                what(),
                r.rows,
                r.cols,
                s.rows,
                s.cols
            )));
        }
        let kreq = Request {
            sse: req.sse,
            moments: req.moments,
            hist: req.hist.clone(),
            mask,
            valid: req.valid,
            mask_nonfinite: req.mask_nonfinite,
            shape: (r.rows, r.cols),
            fortran: false,
        };
        let st = match &req.warp {
            None => run_kernel(&r.data, &s.data, &kreq),
            Some(warp) => warp.score_frames((r, &s), mask, &kreq, req.real_extent).map(|aligned| {
                out.registration = aligned.registration;
                out.real_extent = aligned.extent;
                aligned.stats
            }),
        }
        .map_err(|e| prefix(e, &what()))?;
        out.entropies = st.entropies();
        Ok(st)
    };
    let res = catch_unwind(AssertUnwindSafe(body));
    out.stats = match res {
        Ok(r) => r,
        Err(payload) => Err(caught(payload.as_ref(), &format!("{} vs {}", real.label(), sim.label()))),
    };
    out
}

/// Shared progress state: finished pairs, and a cancel flag for the pairs not started.
#[derive(Debug, Default)]
pub struct Progress {
    pub done: AtomicUsize,
    pub cancel: AtomicBool,
}

fn check_lengths(real: &[Source], sim: &[Source]) -> Result<()> {
    if real.len() != sim.len() {
        return Err(Error::Value(format!(
            "the real sequence has {} frames and the simulated sequence {}; they must have the same number",
            real.len(),
            sim.len()
        )));
    }
    Ok(())
}

/// One unit of work: score job `i`, handing each of its outcomes to the sink as it finishes.
type Job = dyn Fn(usize, &dyn Fn(PairOutcome)) + Send + Sync;

/// Run jobs `0..n` on `workers` threads, handing each outcome to `sink` from the worker that
/// produced it (completion order). `sink` may block to apply back-pressure: the worker then
/// waits before decoding its next frame. Jobs not started when `progress.cancel` is set are
/// skipped. Errors only when the thread pool cannot be built; frame problems are per-pair
/// errors.
fn run_jobs(
    n: usize,
    job: &Job,
    workers: usize,
    progress: &Progress,
    sink: &(dyn Fn(PairOutcome) + Sync),
) -> Result<()> {
    if n == 0 {
        return Ok(());
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(workers)
        .thread_name(|i| format!("irfidelity-seq-{i}"))
        .build()
        .map_err(|e| Error::Value(format!("cannot start {workers} worker threads: {e}")))?;
    let next = AtomicUsize::new(0);
    let deliver = |outcome: PairOutcome| {
        progress.done.fetch_add(1, Ordering::AcqRel);
        sink(outcome);
    };
    let work = || loop {
        if progress.cancel.load(Ordering::Relaxed) {
            break;
        }
        let i = next.fetch_add(1, Ordering::Relaxed);
        if i >= n {
            break;
        }
        // While every worker has jobs left, each job runs on its own thread; the last jobs
        // may split their passes over threads that ran out of work.
        let busy = workers > 1 && i + workers < n;
        crate::kernel::with_pool_busy(busy, || job(i, &deliver));
    };
    pool.scope(|s| {
        for _ in 0..workers {
            s.spawn(|_| work());
        }
    });
    Ok(())
}

/// `workers`, or the number of cores when 0.
pub fn effective_workers(workers: usize) -> usize {
    if workers == 0 {
        std::thread::available_parallelism().map_or(1, |p| p.get())
    } else {
        workers
    }
}

/// Finished outcomes that may wait in a [`PairStream`]'s queue, per worker: enough for the
/// workers to go on while Python turns a batch into report rows, which on small frames takes
/// about as long as scoring them (docs/performance.md, many small frames). An outcome holds
/// statistics, not frames: its joint histogram at most (512 KiB for 256 bins, less when
/// mostly empty).
pub const QUEUE_PER_WORKER: usize = 16;

/// A sequence being scored on background threads (see [`stream_pairs`]). Iterating it
/// blocks for the next outcome; [`PairStream::next_batch`] waits with a timeout. Dropping it
/// cancels the pairs not yet started and waits for those in flight.
pub struct PairStream {
    outcomes: Option<Receiver<PairOutcome>>,
    progress: Arc<Progress>,
    engine: Option<JoinHandle<Result<()>>>,
    workers: usize,
    capacity: usize,
}

/// Outcomes taken from a [`PairStream`] at once.
#[derive(Debug, Default)]
pub struct Batch {
    pub outcomes: Vec<PairOutcome>,
    /// Every outcome has been delivered (this batch holds the last ones, if any).
    pub finished: bool,
}

/// Start scoring `real[i]` against `sim[i]` for every `i` with `workers` threads (0 = all
/// cores, never more than pairs) and return at once. Outcomes arrive in completion order
/// through a queue of [`QUEUE_PER_WORKER`] per worker: at most `capacity() + workers()`
/// finished outcomes are ever waiting for the consumer, whatever the sequence length.
///
/// With `mask`, every pair is scored over it (the workers share it).
///
/// Errors for different lengths or when the engine thread cannot start.
pub fn stream_pairs(
    real: Vec<Source>,
    sim: Vec<Source>,
    req: SeqRequest,
    mask: Option<SeqMask>,
    workers: usize,
) -> Result<PairStream> {
    check_lengths(&real, &sim)?;
    let n = real.len();
    let job =
        move |i: usize, deliver: &dyn Fn(PairOutcome)| deliver(score_pair(i, &real[i], &sim[i], &req, mask.as_ref()));
    stream_jobs(n, Box::new(job), workers)
}

/// Simulated frames scored against shared real frames: task `k` scores `sims[k]` against
/// `real[owners[k]]` with `requests[kinds[k]]`, over `mask` when given (one mask: it is on
/// the real frames' grid).
#[derive(Clone, Debug)]
pub struct SharedTasks {
    pub real: Vec<Source>,
    pub sims: Vec<Source>,
    pub owners: Vec<usize>,
    pub requests: Vec<SeqRequest>,
    pub kinds: Vec<usize>,
    pub mask: Option<SeqMask>,
}

impl SharedTasks {
    fn check(&self) -> Result<()> {
        let k = self.sims.len();
        if self.owners.len() != k || self.kinds.len() != k {
            return Err(Error::Value(format!(
                "{k} simulated frames but {} owners and {} kinds; give one of each per simulated frame",
                self.owners.len(),
                self.kinds.len()
            )));
        }
        if let Some(&bad) = self.owners.iter().find(|&&o| o >= self.real.len()) {
            return Err(Error::Value(format!("owner {bad} is not a real frame (there are {})", self.real.len())));
        }
        if let Some(&bad) = self.kinds.iter().find(|&&q| q >= self.requests.len()) {
            return Err(Error::Value(format!("kind {bad} is not a request (there are {})", self.requests.len())));
        }
        Ok(())
    }

    /// The tasks of every real frame that has any, in order: one job each.
    fn groups(&self) -> Vec<(usize, Vec<usize>)> {
        let mut by_real: Vec<Vec<usize>> = vec![Vec::new(); self.real.len()];
        for (k, &owner) in self.owners.iter().enumerate() {
            by_real[owner].push(k);
        }
        by_real.into_iter().enumerate().filter(|(_, tasks)| !tasks.is_empty()).collect()
    }
}

/// Start scoring every task of `tasks` with `workers` threads, as [`stream_pairs`] does, but
/// decoding each real frame once for all the simulated frames scored against it (one job per
/// real frame: decode it, then decode and score its simulated frames one after another on
/// the same worker). The real frame is decoded with the decode options of its first task's
/// request (every request is expected to share them). An outcome's `index` is its task.
pub fn stream_shared(tasks: SharedTasks, workers: usize) -> Result<PairStream> {
    tasks.check()?;
    let groups = tasks.groups();
    let n = groups.len();
    let job = move |i: usize, deliver: &dyn Fn(PairOutcome)| {
        let (owner, members) = &groups[i];
        let real = &tasks.real[*owner];
        let decoded = decode_real(real, &tasks.requests[tasks.kinds[members[0]]]);
        for &k in members {
            let req = &tasks.requests[tasks.kinds[k]];
            deliver(score_against(k, real, &decoded, &tasks.sims[k], req, tasks.mask.as_ref()));
        }
    };
    stream_jobs(n, Box::new(job), workers)
}

/// Start `n` jobs on background threads; their outcomes come through the returned stream.
fn stream_jobs(n: usize, job: Box<Job>, workers: usize) -> Result<PairStream> {
    let workers = effective_workers(workers).min(n).max(1);
    let capacity = QUEUE_PER_WORKER * workers;
    let (sender, receiver) = sync_channel(capacity);
    let progress = Arc::new(Progress::default());
    let engine_progress = Arc::clone(&progress);
    let engine = std::thread::Builder::new()
        .name("irfidelity-seq".into())
        .spawn(move || {
            let sink = |o: PairOutcome| {
                if sender.send(o).is_err() {
                    // the consumer is gone: start no new pair
                    engine_progress.cancel.store(true, Ordering::Relaxed);
                }
            };
            run_jobs(n, job.as_ref(), workers, &engine_progress, &sink)
        })
        .map_err(|e| Error::Value(format!("cannot start the sequence engine thread: {e}")))?;
    Ok(PairStream { outcomes: Some(receiver), progress, engine: Some(engine), workers, capacity })
}

impl PairStream {
    /// Finished-pair count and cancel flag, shared with the workers.
    pub fn progress(&self) -> &Arc<Progress> {
        &self.progress
    }

    /// Worker threads in use.
    pub fn workers(&self) -> usize {
        self.workers
    }

    /// Outcomes the queue holds before workers wait.
    pub fn capacity(&self) -> usize {
        self.capacity
    }

    /// Start no new pair; the pairs in flight still finish and are delivered.
    pub fn cancel(&self) {
        self.progress.cancel.store(true, Ordering::SeqCst);
    }

    /// Wait until `min` outcomes (at least one) have arrived, the engine has finished, or
    /// `timeout` has passed; then take them with every other outcome already queued.
    pub fn next_batch(&mut self, min: usize, timeout: Duration) -> Batch {
        let mut batch = Batch::default();
        let Some(rx) = &self.outcomes else {
            batch.finished = true;
            return batch;
        };
        let deadline = Instant::now() + timeout;
        while batch.outcomes.len() < min.max(1) {
            match rx.recv_timeout(deadline.saturating_duration_since(Instant::now())) {
                Ok(o) => batch.outcomes.push(o),
                Err(RecvTimeoutError::Timeout) => break,
                Err(RecvTimeoutError::Disconnected) => {
                    batch.finished = true;
                    return batch;
                }
            }
        }
        loop {
            match rx.try_recv() {
                Ok(o) => batch.outcomes.push(o),
                Err(TryRecvError::Empty) => return batch,
                Err(TryRecvError::Disconnected) => {
                    batch.finished = true;
                    return batch;
                }
            }
        }
    }

    /// Stop receiving (a worker waiting on the full queue gives up and starts no new pair),
    /// wait for the engine, and return its error: only a thread pool that could not be
    /// built, or an internal panic.
    pub fn finish(mut self) -> Result<()> {
        self.stop()
    }

    fn stop(&mut self) -> Result<()> {
        self.outcomes = None;
        match self.engine.take() {
            None => Ok(()),
            Some(engine) => engine
                .join()
                .unwrap_or_else(|_| Err(Error::Value("internal error: the sequence engine panicked".into()))),
        }
    }
}

impl Iterator for PairStream {
    type Item = PairOutcome;

    /// The next outcome (blocking), or `None` when every pair has been delivered.
    fn next(&mut self) -> Option<PairOutcome> {
        self.outcomes.as_ref()?.recv().ok()
    }
}

impl Drop for PairStream {
    fn drop(&mut self) {
        self.cancel();
        let _ = self.stop();
    }
}

/// Merge statistics (e.g. of all frames of a sequence). Histograms are merged when all
/// share the same edges; otherwise they are dropped and the second value is `false`.
/// Returns `None` for an empty list.
pub fn merge_all<'a, I>(items: I) -> Result<Option<(PairStats, bool)>>
where
    I: IntoIterator<Item = &'a PairStats>,
    I::IntoIter: Clone,
{
    let it = items.into_iter();
    let mut specs = it.clone().map(|p| p.hist.as_ref().map(|(s, _)| s));
    let first = match specs.next() {
        None => return Ok(None),
        Some(f) => f,
    };
    let same = specs.all(|s| s == first);
    let keep_hist = same && first.is_some();
    let mut acc: Option<PairStats> = None;
    for p in it {
        let p_owned;
        let p = if keep_hist || p.hist.is_none() {
            p
        } else {
            p_owned = PairStats { hist: None, ..p.clone() };
            &p_owned
        };
        acc = Some(match acc {
            None => p.clone(),
            Some(a) => a.merge(p)?,
        });
    }
    Ok(acc.map(|a| (a, keep_hist)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn data(rel: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data").join(rel)
    }

    const STACK: &str = "thermal/cptv_v2_all100frames_uint16.tif";

    /// An integer frame's extent compared as integers equals the f64 fold, with and without a
    /// mask, at the type's ends.
    #[test]
    fn integer_extent_equals_the_float_fold() {
        let u16s: Vec<u16> = (0..1003u32).map(|i| (i * 7919 % 65536) as u16).collect();
        let i16s: Vec<i16> = u16s.iter().map(|&v| v as i16).collect();
        let mask: Vec<bool> = (0..1003).map(|i| i % 3 != 0).collect();
        for m in [None, Some(&mask[..])] {
            let want = |v: Vec<f64>| match m {
                None => finite_extent(v.into_iter()),
                Some(m) => finite_extent(v.into_iter().zip(m).filter(|&(_, &k)| k).map(|(x, _)| x)),
            };
            let (a, b) = (u16s.clone(), i16s.clone());
            assert_eq!(extent(&FrameData::U16(a), m), want(u16s.iter().map(|&v| v.into()).collect()));
            assert_eq!(extent(&FrameData::I16(b), m), want(i16s.iter().map(|&v| v.into()).collect()));
        }
        assert_eq!(extent(&FrameData::U16(Vec::new()), None), None);
    }

    fn stack_sources(range: std::ops::Range<usize>) -> Vec<Source> {
        range.map(|p| Source::new(data(STACK), p)).collect()
    }

    /// Every outcome of a stream, in index order; checks each index arrives exactly once.
    fn collect(real: &[Source], sim: &[Source], req: &SeqRequest, workers: usize) -> Vec<PairOutcome> {
        let mut stream = stream_pairs(real.to_vec(), sim.to_vec(), req.clone(), None, workers).unwrap();
        let mut out: Vec<PairOutcome> = stream.by_ref().collect();
        assert_eq!(stream.progress().done.load(Ordering::SeqCst), real.len());
        stream.finish().unwrap();
        out.sort_by_key(|o| o.index);
        assert_eq!(out.iter().map(|o| o.index).collect::<Vec<_>>(), (0..real.len()).collect::<Vec<_>>());
        out
    }

    fn u16_frame(src: &Source) -> Vec<u16> {
        let opts = DecodeOptions { page: src.page, ..Default::default() };
        match io::decode_frame(&src.path, &opts).unwrap().data {
            FrameData::U16(v) => v,
            other => panic!("expected u16, got {}", other.dtype_name()),
        }
    }

    #[test]
    fn matches_single_pair_kernel_and_is_in_order() {
        // real = pages 0..12, sim = pages 1..13 (consecutive Lepton frames)
        let real = stack_sources(0..12);
        let sim = stack_sources(1..13);
        let out = collect(&real, &sim, &SeqRequest::default(), 2);
        assert_eq!(out.len(), 12);
        for (i, o) in out.iter().enumerate() {
            assert_eq!(o.shape, Some((120, 160)));
            assert_eq!(o.dtype, Some("uint16"));
            let got = o.stats.as_ref().unwrap();
            let (r, s) = (u16_frame(&real[i]), u16_frame(&sim[i]));
            let kreq = Request { shape: (120, 160), ..Request::default() };
            let want = stats::pair_stats(&r, &s, &kreq).unwrap();
            assert_eq!(got, &want, "frame {i}");
        }
    }

    #[test]
    fn one_and_many_workers_agree_and_merge_is_exact() {
        let real = stack_sources(0..20);
        let sim = stack_sources(80..100);
        let req = SeqRequest {
            hist: Some(HistRequest::Bins { bins: 256, range: Some((0.0, 65535.0)) }),
            ..Default::default()
        };
        let sa: Vec<PairStats> = collect(&real, &sim, &req, 1).into_iter().map(|o| o.stats.unwrap()).collect();
        let sb: Vec<PairStats> = collect(&real, &sim, &req, 3).into_iter().map(|o| o.stats.unwrap()).collect();
        assert_eq!(sa, sb);
        let (pooled, hist_ok) = merge_all(&sa).unwrap().unwrap();
        assert!(hist_ok);
        assert_eq!(pooled.n, 20 * 120 * 160);
        // ΣSSE over frames equals the pooled exact SSE
        let total: u128 = sa
            .iter()
            .map(|p| match p.sums {
                stats::Sums::Int(s) => s.sse,
                _ => unreachable!(),
            })
            .sum();
        match pooled.sums {
            stats::Sums::Int(s) => assert_eq!(s.sse, total),
            _ => panic!("integer sums expected"),
        }
    }

    #[test]
    fn data_range_histograms_are_dropped_when_pooling() {
        let real = stack_sources(0..4);
        let sim = stack_sources(50..54);
        let out = collect(&real, &sim, &SeqRequest::default(), 2);
        let st: Vec<PairStats> = out.into_iter().map(|o| o.stats.unwrap()).collect();
        let (pooled, hist_ok) = merge_all(&st).unwrap().unwrap();
        assert!(!hist_ok);
        assert!(pooled.hist.is_none());
        assert!(pooled.has_sse && pooled.has_moments);
        assert!(merge_all(std::iter::empty::<&PairStats>()).unwrap().is_none());
    }

    #[test]
    fn bad_frames_fail_alone() {
        let tmp = std::env::temp_dir().join(format!("irf_seq_test_{}", std::process::id()));
        std::fs::create_dir_all(&tmp).unwrap();
        let good = data("thermal/cptv_v2_frame000.png");
        let bytes = std::fs::read(&good).unwrap();
        let truncated = tmp.join("truncated.png");
        std::fs::write(&truncated, &bytes[..bytes.len() / 2]).unwrap();
        let real = vec![
            Source::new(&good, 0),
            Source::new(&truncated, 0),
            Source::new(data("thermal/cptv_v2_frame001.png"), 0),
            Source::new(tmp.join("missing.png"), 0),
            Source::new(&good, 0),
            Source::new(&good, 0),
        ];
        let sim = vec![
            Source::new(data("thermal/cptv_v2_frame001.png"), 0),
            Source::new(&good, 0),
            Source::new(&good, 0),
            Source::new(&good, 0),
            // shape mismatch: 75x68 PTW frame
            Source::new(data("thermal/ptw_lwir_frame000.png"), 0),
            // dtype mismatch: float32 EXR of the same frame
            Source::new(data("thermal/cptv_v2_frame000_counts_f32_zip.exr"), 0),
        ];
        let out = collect(&real, &sim, &SeqRequest::default(), 2);
        assert!(out[0].stats.is_ok());
        assert!(out[2].stats.is_ok());
        let err = |i: usize| out[i].stats.clone().unwrap_err();
        assert!(matches!(err(1), Error::Frame(m) if m.contains("truncated.png")));
        assert!(matches!(err(3), Error::Frame(m) if m.contains("missing.png")));
        assert!(matches!(err(4), Error::Shape(m) if m.contains("shape") && m.contains("ptw_lwir_frame000.png")));
        assert!(matches!(err(5), Error::Shape(m) if m.contains("uint16 vs float32")));
        std::fs::remove_dir_all(&tmp).ok();
    }

    #[test]
    fn range_errors_name_the_frame() {
        let real = stack_sources(0..3);
        let sim = stack_sources(3..6);
        let req = SeqRequest { valid: Some((0, 2047)), ..Default::default() };
        for o in collect(&real, &sim, &req, 2) {
            let e = o.stats.unwrap_err();
            assert!(matches!(&e, Error::Range(m) if m.contains("cptv_v2_all100frames_uint16.tif[")), "{e:?}");
        }
    }

    /// A cheap request (SSE only), so the engine outruns a slow consumer.
    fn sse_only() -> SeqRequest {
        SeqRequest { moments: false, hist: None, ..Default::default() }
    }

    fn wait_for(what: &str, cond: impl Fn() -> bool) {
        let deadline = Instant::now() + Duration::from_secs(60);
        while !cond() {
            assert!(Instant::now() < deadline, "timed out waiting for {what}");
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    #[test]
    fn mismatched_lengths_fail_before_any_work() {
        let e = stream_pairs(stack_sources(0..3), stack_sources(0..2), SeqRequest::default(), None, 1).err().unwrap();
        assert!(e.to_string().contains("3 frames") && e.to_string().contains(" 2;"));
        let mut empty = stream_pairs(vec![], vec![], SeqRequest::default(), None, 0).unwrap();
        assert!(empty.next().is_none());
        empty.finish().unwrap();
    }

    #[test]
    fn a_slow_consumer_bounds_the_queue() {
        let n = 100;
        let mut stream = stream_pairs(stack_sources(0..n), stack_sources(0..n), sse_only(), None, 2).unwrap();
        let (workers, capacity) = (stream.workers(), stream.capacity());
        assert_eq!((workers, capacity), (2, 2 * QUEUE_PER_WORKER));
        // finished but not received: the queue, plus one outcome per worker waiting to enter it
        let bound = capacity + workers;
        let progress = Arc::clone(stream.progress());
        let done = || progress.done.load(Ordering::SeqCst);
        // nothing received: the workers fill the queue, then wait
        wait_for("a full queue", || done() >= bound);
        std::thread::sleep(Duration::from_millis(200));
        assert_eq!(done(), bound, "workers went on past a full queue");
        // a slow consumer never sees more than the bound finished ahead of it
        let mut received = Vec::new();
        for o in stream.by_ref() {
            received.push(o.index);
            assert!(done() - received.len() <= bound, "{} finished, {} received", done(), received.len());
            if received.len() % 10 == 0 {
                std::thread::sleep(Duration::from_millis(20));
            }
        }
        stream.finish().unwrap();
        received.sort_unstable();
        assert_eq!(received, (0..n).collect::<Vec<_>>());
    }

    #[test]
    fn cancel_stops_new_pairs_and_delivers_those_in_flight() {
        let n = 100;
        let mut stream = stream_pairs(stack_sources(0..n), stack_sources(0..n), sse_only(), None, 2).unwrap();
        let first: Vec<PairOutcome> = stream.by_ref().take(3).collect();
        stream.cancel();
        let rest: Vec<PairOutcome> = stream.by_ref().collect();
        let delivered = first.len() + rest.len();
        let done = stream.progress().done.load(Ordering::SeqCst);
        stream.finish().unwrap();
        // every finished pair is delivered; at most the queue, the waiting and the in-flight
        // outcomes come after the cancel
        assert_eq!(delivered, done);
        assert!(delivered <= 3 + 2 * QUEUE_PER_WORKER + 2 * 2, "{delivered} pairs after a cancel at 3");
        let mut idx: Vec<usize> = first.iter().chain(&rest).map(|o| o.index).collect();
        idx.sort_unstable();
        idx.dedup();
        assert_eq!(idx.len(), delivered);
    }

    #[test]
    fn dropping_the_stream_stops_the_workers() {
        let n = 100;
        let mut stream = stream_pairs(stack_sources(0..n), stack_sources(0..n), sse_only(), None, 2).unwrap();
        let progress = Arc::clone(stream.progress());
        assert!(stream.next().is_some());
        wait_for("a full queue", || progress.done.load(Ordering::SeqCst) > stream.capacity());
        let t = Instant::now();
        drop(stream); // joins the engine: returns only once every worker has exited
        assert!(t.elapsed() < Duration::from_secs(30));
        let done = progress.done.load(Ordering::SeqCst);
        assert!(done < n, "all {n} pairs were scored after the consumer left");
        std::thread::sleep(Duration::from_millis(50));
        assert_eq!(progress.done.load(Ordering::SeqCst), done, "a worker still runs");
    }

    #[test]
    fn batches_wait_for_a_round_and_end_with_finished() {
        let n = 20;
        let mut stream = stream_pairs(stack_sources(0..n), stack_sources(0..n), sse_only(), None, 2).unwrap();
        let first = stream.next_batch(5, Duration::from_secs(60));
        assert!(first.outcomes.len() >= 5 && !first.finished);
        let mut idx: Vec<usize> = first.outcomes.iter().map(|o| o.index).collect();
        loop {
            let batch = stream.next_batch(2, Duration::from_millis(100));
            idx.extend(batch.outcomes.iter().map(|o| o.index));
            if batch.finished {
                break;
            }
        }
        assert!(stream.next_batch(1, Duration::ZERO).finished);
        stream.finish().unwrap();
        idx.sort_unstable();
        assert_eq!(idx, (0..n).collect::<Vec<_>>());
    }

    #[test]
    fn fingerprints_are_of_the_files_decoded() {
        // a first page read whole, and later pages of a stack hashed before decoding
        let png = |i: usize| Source::new(data(&format!("thermal/cptv_v2_frame{i:03}.png")), 0);
        let real = vec![png(0), Source::new(data(STACK), 0), Source::new(data(STACK), 7)];
        let sim = vec![png(1), Source::new(data(STACK), 3), Source::new(data(STACK), 9)];
        let req = SeqRequest { fingerprint: true, ..sse_only() };
        for o in collect(&real, &sim, &req, 2) {
            let (r, s) = o.fingerprints.expect("both files fingerprinted");
            for (fp, src) in [(r, &real[o.index]), (s, &sim[o.index])] {
                assert_eq!(fp.digest, fingerprint::file_digest(&src.path).unwrap());
                assert_eq!(fp.size, std::fs::metadata(&src.path).unwrap().len());
            }
        }
        assert!(collect(&real, &sim, &sse_only(), 1).iter().all(|o| o.fingerprints.is_none()));
    }

    #[test]
    fn shared_real_frames_score_as_separate_pairs() {
        // three "simulators" of pages 0..6: pages shifted by 1, 2 and 3, the second with SSE only
        let real = stack_sources(0..6);
        let sims: Vec<Source> = (1..4).flat_map(|shift| stack_sources(shift..shift + 6)).collect();
        let owners: Vec<usize> = (0..3).flat_map(|_| 0..6).collect();
        let kinds: Vec<usize> = (0..3).flat_map(|sim| [usize::from(sim == 1); 6]).collect();
        let requests = vec![SeqRequest::default(), sse_only()];
        let mask = Some(band_mask());
        let tasks = SharedTasks { real: real.clone(), sims: sims.clone(), owners, requests, kinds, mask };
        let mut stream = stream_shared(tasks.clone(), 2).unwrap();
        let mut out: Vec<PairOutcome> = stream.by_ref().collect();
        assert_eq!(stream.progress().done.load(Ordering::SeqCst), 18);
        stream.finish().unwrap();
        out.sort_by_key(|o| o.index);
        assert_eq!(out.iter().map(|o| o.index).collect::<Vec<_>>(), (0..18).collect::<Vec<_>>());
        for o in &out {
            let k = o.index;
            let alone = score_pair(k, &real[k % 6], &sims[k], &tasks.requests[tasks.kinds[k]], tasks.mask.as_ref());
            assert_eq!(o.stats, alone.stats, "task {k}");
            assert_eq!(o.stats.as_ref().unwrap().n, 70 * 140);
            assert_eq!(o.shape, Some((120, 160)));
        }
        let bad = SharedTasks { owners: vec![6; 18], ..tasks };
        assert!(stream_shared(bad, 1).err().unwrap().to_string().contains("owner 6"));
    }

    #[test]
    fn an_unreadable_real_frame_fails_each_of_its_pairs() {
        let real = vec![Source::new(data("thermal/missing.png"), 0)];
        let sims = stack_sources(0..2);
        let tasks = SharedTasks {
            real,
            sims,
            owners: vec![0, 0],
            requests: vec![SeqRequest::default()],
            kinds: vec![0, 0],
            mask: None,
        };
        let out: Vec<PairOutcome> = stream_shared(tasks, 1).unwrap().collect();
        assert_eq!(out.len(), 2);
        assert!(out.iter().all(|o| matches!(&o.stats, Err(Error::Frame(m)) if m.contains("missing.png"))));
    }

    #[test]
    fn plan_only_what_is_needed() {
        let real = stack_sources(0..2);
        let sim = stack_sources(2..4);
        let req = SeqRequest { moments: false, hist: None, ..Default::default() };
        for o in collect(&real, &sim, &req, 2) {
            let st = o.stats.unwrap();
            assert!(st.has_sse && !st.has_moments && st.hist.is_none());
        }
    }

    /// A mask of the stack's (120, 160) frames: a band of rows and a block cut out of it.
    fn band_mask() -> SeqMask {
        let values: Vec<bool> =
            (0..120 * 160).map(|i| (20..90).contains(&(i / 160)) && !(40..60).contains(&(i % 160))).collect();
        SeqMask::new(values.into(), (120, 160)).unwrap()
    }

    #[test]
    fn a_mask_scores_its_pixels_in_every_pair() {
        let (real, sim) = (stack_sources(0..4), stack_sources(10..14));
        let mask = band_mask();
        let req = SeqRequest { real_extent: true, ..Default::default() };
        let mut stream = stream_pairs(real.clone(), sim.clone(), req, Some(mask.clone()), 2).unwrap();
        let mut out: Vec<PairOutcome> = stream.by_ref().collect();
        stream.finish().unwrap();
        out.sort_by_key(|o| o.index);
        for (i, o) in out.iter().enumerate() {
            let (r, s) = (u16_frame(&real[i]), u16_frame(&sim[i]));
            let kreq = Request { shape: (120, 160), mask: Some(&mask.values), ..Request::default() };
            assert_eq!(o.stats.as_ref().unwrap(), &stats::pair_stats(&r, &s, &kreq).unwrap(), "frame {i}");
            let inside = r.iter().zip(mask.values.iter()).filter(|&(_, &keep)| keep).map(|(&v, _)| f64::from(v));
            assert_eq!(o.real_extent, finite_extent(inside));
        }
    }

    #[test]
    fn a_mask_of_another_shape_fails_each_pair_and_an_empty_one_is_refused() {
        let mask = SeqMask::new(vec![true; 12].into(), (3, 4)).unwrap();
        let mut stream = stream_pairs(stack_sources(0..2), stack_sources(2..4), sse_only(), Some(mask), 1).unwrap();
        let out: Vec<PairOutcome> = stream.by_ref().collect();
        stream.finish().unwrap();
        assert!(out.iter().all(|o| matches!(&o.stats, Err(Error::Shape(m)) if m.contains("mask has shape (3, 4)"))));
        assert!(SeqMask::new(vec![false; 12].into(), (3, 4)).is_err());
        assert!(SeqMask::new(vec![true; 11].into(), (3, 4)).is_err());
    }

    #[test]
    fn a_mask_costs_its_bytes_in_the_pair_plan() {
        let frame = FrameData::U16(vec![0; 4]);
        for warp in [None, Some(Warp::Fixed(FixedWarp::from_matrix([1.0, 0.0, 0.0, 0.0, 1.0, 0.0], 1).unwrap()))] {
            let req = SeqRequest { warp, ..Default::default() };
            let bare = pair_plan((100, 100), &frame, &req, false).0.bytes;
            let masked = pair_plan((100, 100), &frame, &req, true).0.bytes;
            assert!(masked >= bare + 10_000, "{masked} vs {bare}");
        }
    }
}
