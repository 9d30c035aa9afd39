//! One streamed pass over a recording: frames are read (decoded from files, or sliced
//! from an in-memory cube) and added to [`NoiseSums`] on `workers` threads.
//!
//! The first frame is read on the calling thread: it fixes the shape, the sample type and
//! (float frames) the per-pixel pivot. The remaining frames are cut into chunks of a
//! length that depends only on the frame count, and chunks are appended to the total
//! strictly in chunk order. A float chunk is summed into its own [`NoiseSums`], so the
//! result does not depend on the number of workers (bit-identical); an integer chunk adds
//! its pixels into its worker's accumulator (exact sums do not depend on the order) and
//! hands on only its per-frame sums. Memory stays bounded: a worker does not start a float
//! chunk more than `2·workers` chunks ahead of the last one appended (integer chunks hold
//! only per-frame sums, which the result keeps anyway).
//!
//! The pass is planned against the memory budget once the first frame has fixed the shape
//! ([`pass_plan`]): when the per-pixel sums of every worker and the frames in flight would
//! not fit, fewer workers run (float results do not depend on their number) and, for
//! integer frames read from files, fewer frames are decoded at once (integer sums do not
//! depend on it either); when one worker reading one frame at a time does not fit, the pass
//! is refused before it allocates its sums.

use std::ops::Range;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};

use super::{Acc, Dtype, NoiseSums};
use crate::budget::{self, Plan};
use crate::io::{self, DecodeOptions, FrameData};
use crate::{Error, Result};

/// A rectangular region of every frame (default: the whole frame).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Window {
    pub row0: usize,
    pub col0: usize,
    pub rows: usize,
    pub cols: usize,
}

/// How to run a pass.
#[derive(Clone, Debug, Default)]
pub struct PassOptions {
    /// Worker threads (0: all cores).
    pub workers: usize,
    /// Integer frames: the valid range `(lo, hi)` (default: the sample type's range).
    pub limits: Option<(i64, i64)>,
    /// Region to analyse (default: whole frames).
    pub window: Option<Window>,
    /// The memory budget of the pass in bytes (`None`: [`io::DEFAULT_MAX_BYTES`]); a cube
    /// given in memory is the caller's and not counted.
    pub max_bytes: Option<u64>,
}

/// Borrowed samples of one frame.
#[derive(Clone, Copy, Debug)]
pub enum Samples<'a> {
    U8(&'a [u8]),
    U16(&'a [u16]),
    I16(&'a [i16]),
    U32(&'a [u32]),
    F16(&'a [half::f16]),
    F32(&'a [f32]),
    F64(&'a [f64]),
}

impl Samples<'_> {
    fn dtype(&self) -> Dtype {
        match self {
            Samples::U8(_) => Dtype::U8,
            Samples::U16(_) => Dtype::U16,
            Samples::I16(_) => Dtype::I16,
            Samples::U32(_) => Dtype::U32,
            Samples::F16(_) => Dtype::F16,
            Samples::F32(_) => Dtype::F32,
            Samples::F64(_) => Dtype::F64,
        }
    }
}

/// One frame as read from a source.
#[derive(Clone, Copy, Debug)]
pub struct FrameRef<'a> {
    pub rows: usize,
    pub cols: usize,
    pub samples: Samples<'a>,
}

/// Frames a pass reads, by index.
pub trait FrameSource: Sync {
    fn len(&self) -> usize;
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Name of frame `i` in messages.
    fn label(&self, i: usize) -> String;
    /// Read frames `range` and hand them to `visit` together.
    fn with_frames(&self, range: Range<usize>, visit: &mut dyn FnMut(&[FrameRef<'_>]) -> Result<()>) -> Result<()>;
    /// Whether reading a frame allocates it (decoded from a file) rather than borrowing it.
    fn allocates(&self) -> bool {
        false
    }
}

/// Frames of files (a TIFF page each), decoded by [`crate::io::decode_frame`].
pub struct PathSource {
    pub frames: Vec<(PathBuf, usize)>,
    pub channel: Option<String>,
    pub max_pixels: u64,
    /// The decoding budget of one frame ([`DecodeOptions::max_bytes`]).
    pub max_bytes: u64,
}

impl FrameSource for PathSource {
    fn len(&self) -> usize {
        self.frames.len()
    }
    fn label(&self, i: usize) -> String {
        let (path, page) = &self.frames[i];
        if *page == 0 {
            path.display().to_string()
        } else {
            format!("{}[{page}]", path.display())
        }
    }
    fn allocates(&self) -> bool {
        true
    }
    fn with_frames(&self, range: Range<usize>, visit: &mut dyn FnMut(&[FrameRef<'_>]) -> Result<()>) -> Result<()> {
        let decoded: Vec<io::Frame> = range
            .map(|i| {
                let (path, page) = &self.frames[i];
                let opts = DecodeOptions {
                    channel: self.channel.clone(),
                    max_pixels: self.max_pixels,
                    max_bytes: self.max_bytes,
                    page: *page,
                };
                io::decode_frame(path, &opts)
            })
            .collect::<Result<_>>()?;
        let refs: Vec<FrameRef<'_>> = decoded
            .iter()
            .map(|frame| {
                let samples = match &frame.data {
                    FrameData::U8(v) => Samples::U8(v),
                    FrameData::U16(v) => Samples::U16(v),
                    FrameData::I16(v) => Samples::I16(v),
                    FrameData::U32(v) => Samples::U32(v),
                    FrameData::F16(v) => Samples::F16(v),
                    FrameData::F32(v) => Samples::F32(v),
                    FrameData::F64(v) => Samples::F64(v),
                };
                FrameRef { rows: frame.rows, cols: frame.cols, samples }
            })
            .collect();
        visit(&refs)
    }
}

/// Frames of a C-ordered `frames × rows × cols` cube in memory.
pub struct ArraySource<'a> {
    pub data: Samples<'a>,
    pub frames: usize,
    pub rows: usize,
    pub cols: usize,
}

impl FrameSource for ArraySource<'_> {
    fn len(&self) -> usize {
        self.frames
    }
    fn label(&self, i: usize) -> String {
        format!("frame {i}")
    }
    fn with_frames(&self, range: Range<usize>, visit: &mut dyn FnMut(&[FrameRef<'_>]) -> Result<()>) -> Result<()> {
        let size = self.rows * self.cols;
        let refs = range
            .map(|i| {
                let span = i * size..(i + 1) * size;
                macro_rules! cut {
                    ($($v:ident),*) => {
                        match self.data {
                            $(Samples::$v(d) => Samples::$v(d.get(span).ok_or_else(|| {
                                Error::Shape(format!("frame {i}: the array holds fewer than {} frames", self.frames))
                            })?),)*
                        }
                    };
                }
                Ok(FrameRef { rows: self.rows, cols: self.cols, samples: cut!(U8, U16, I16, U32, F16, F32, F64) })
            })
            .collect::<Result<Vec<_>>>()?;
        visit(&refs)
    }
}

/// Sums of a cube in memory (`data` holds `frames·rows·cols` samples, C order).
pub fn noise_sums_from_array(
    data: Samples<'_>,
    frames: usize,
    rows: usize,
    cols: usize,
    opts: &PassOptions,
) -> Result<NoiseSums> {
    run_pass(&ArraySource { data, frames, rows, cols }, opts)
}

/// Sums of frames read from files: `(path, page)` each, decoded as `decode` says (its
/// `page` is ignored).
pub fn noise_sums_from_paths(
    frames: Vec<(PathBuf, usize)>,
    decode: &DecodeOptions,
    opts: &PassOptions,
) -> Result<NoiseSums> {
    let source = PathSource {
        frames,
        channel: decode.channel.clone(),
        max_pixels: decode.max_pixels,
        max_bytes: decode.max_bytes,
    };
    run_pass(&source, opts)
}

/// What every frame must match: the first frame's shape and type, and the window.
#[derive(Clone, Copy)]
struct Layout {
    full: (usize, usize),
    dtype: Dtype,
    window: Window,
}

/// Add a batch of frames (checked against the layout) to `sums`; `label(k)` names frame k.
fn add_batch(
    sums: &mut NoiseSums,
    frames: &[FrameRef<'_>],
    layout: &Layout,
    label: &dyn Fn(usize) -> String,
) -> Result<()> {
    for (k, frame) in frames.iter().enumerate() {
        if (frame.rows, frame.cols) != layout.full {
            return Err(Error::Shape(format!(
                "{}: frame of {} x {} pixels (rows x cols), but the first frame is {} x {}; all frames must have one shape",
                label(k),
                frame.rows,
                frame.cols,
                layout.full.0,
                layout.full.1
            )));
        }
        if frame.samples.dtype() != layout.dtype {
            return Err(Error::Shape(format!(
                "{}: sample type {}, but the first frame is {}; all frames must have one sample type",
                label(k),
                frame.samples.dtype().name(),
                layout.dtype.name()
            )));
        }
    }
    let origin = (layout.window.row0, layout.window.col0);
    let stride = layout.full.1;
    macro_rules! typed {
        ($($v:ident),*) => {
            match frames.first().map(|f| f.samples) {
                None => Ok(()),
                $(Some(Samples::$v(_)) => {
                    let data: Vec<_> = frames
                        .iter()
                        .map(|f| match f.samples {
                            Samples::$v(d) => d,
                            _ => unreachable!("sample types were checked"),
                        })
                        .collect();
                    sums.add_frames(&data, stride, origin, label)
                })*
            }
        };
    }
    typed!(U8, U16, I16, U32, F16, F32, F64)
}

/// Frames per chunk: depends on the frame count only (so float results do not depend on
/// the number of workers); a multiple of [`BATCH`], long enough that a chunk's own per-pixel
/// sums (allocated, then appended to the total) cost little next to its frames.
fn chunk_len(frames: usize) -> usize {
    frames.div_ceil(16).clamp(4 * BATCH, 256).next_multiple_of(BATCH)
}

/// Frames added together (sharing one pass over the per-pixel sums).
const BATCH: usize = 8;

fn effective_workers(workers: usize) -> usize {
    if workers > 0 {
        workers
    } else {
        std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1)
    }
}

/// How a pass runs: worker threads, frames each reads at once, and frames per chunk.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Schedule {
    workers: usize,
    batch: usize,
    chunk: usize,
}

impl Schedule {
    /// `workers` (at most one per chunk) reading `batch` frames at once, in chunks of
    /// [`chunk_len`] frames for float frames (their result depends on it) and of one batch for
    /// integer frames.
    fn new(layout: &Layout, frames: usize, workers: usize, batch: usize) -> Schedule {
        let chunk = if layout.dtype.is_int() { batch } else { chunk_len(frames) };
        Schedule { workers: workers.clamp(1, Self::chunks(frames, chunk).max(1)), batch, chunk }
    }

    /// Chunks after the first frame (read on its own).
    fn chunks(frames: usize, chunk: usize) -> usize {
        frames.saturating_sub(1).div_ceil(chunk)
    }
}

/// The peak of a pass over `frames` frames of `layout` run as `schedule`, besides a cube
/// given in memory: the per-pixel sums of the total and of every worker (integer frames:
/// each worker's accumulator; float frames: the pivot, and the chunks being summed or
/// waiting to be appended, at most `2·workers` since no worker starts a chunk further
/// ahead), the per-frame row and column sums (of the
/// total and of the pieces handed on), and, when reading allocates frames, the first frame
/// and every worker's batch.
fn pass_plan(layout: &Layout, frames: usize, allocates: bool, schedule: Schedule) -> Plan {
    let (window, workers) = (layout.window, schedule.workers);
    let per_pixel = if layout.dtype.is_int() {
        let square = if layout.dtype == Dtype::U32 { 16.0 } else { 8.0 };
        (8.0 + square) * (1 + workers) as f64
    } else {
        let alive = (2 * workers).min(Schedule::chunks(frames, schedule.chunk));
        8.0 + 32.0 * (1 + alive) as f64
    };
    let line_sums = 2 * budget::size_of_vec::<f64>(frames.saturating_mul(window.rows + window.cols));
    let frame =
        if allocates { budget::size_of_vec::<u8>(layout.full.0 * layout.full.1 * layout.dtype.size()) } else { 0 };
    let in_flight = frame.saturating_mul((1 + workers * schedule.batch) as u64);
    let operation = format!(
        "the 3-D noise pass ({workers} worker{}, {} frame{} read at a time each)",
        if workers == 1 { "" } else { "s" },
        schedule.batch,
        if schedule.batch == 1 { "" } else { "s" }
    );
    Plan::new(operation, (window.rows, window.cols), per_pixel, line_sums.saturating_add(in_flight))
}

/// The most workers (up to `requested`) and, for integer frames read from files, the largest
/// batch that fit `max_bytes`; an error naming the smallest plan when none does.
fn schedule(layout: &Layout, frames: usize, allocates: bool, requested: usize, max_bytes: u64) -> Result<Schedule> {
    let batches: &[usize] = if allocates && layout.dtype.is_int() { &[BATCH, 4, 2, 1] } else { &[BATCH] };
    for workers in (1..=requested.max(1)).rev() {
        for &batch in batches {
            let s = Schedule::new(layout, frames, workers, batch);
            if pass_plan(layout, frames, allocates, s).bytes <= max_bytes {
                return Ok(s);
            }
        }
    }
    let least = Schedule::new(layout, frames, 1, *batches.last().expect("a batch"));
    pass_plan(layout, frames, allocates, least).check(max_bytes, Error::Value).map(|_| least)
}

/// A summed chunk of frames, waiting to be appended to the total in chunk order.
enum Piece {
    /// Float frames: the chunk's own sums.
    Sums(NoiseSums),
    /// Integer frames: only the chunk's per-frame sums; its per-pixel sums stay in the
    /// worker's accumulator (integer sums do not depend on the order they are added in).
    Frames { rows: Vec<i64>, cols: Vec<i64>, count: usize },
}

/// State shared by the workers of a pass.
struct Shared {
    total: NoiseSums,
    /// Finished chunks waiting for their predecessors.
    pending: std::collections::BTreeMap<usize, Piece>,
    /// Integer frames: the workers' per-pixel accumulators, added to the total at the end.
    locals: Vec<NoiseSums>,
    /// Next chunk to append.
    next: usize,
    /// First error, by frame index.
    error: Option<(usize, Error)>,
}

fn lock(m: &Mutex<Shared>) -> MutexGuard<'_, Shared> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// Run a pass over every frame of `source`, planned against `opts.max_bytes` (see the
/// module notes); memory the system refuses is an error too.
pub fn run_pass(source: &dyn FrameSource, opts: &PassOptions) -> Result<NoiseSums> {
    budget::guard("the 3-D noise pass", Error::Value, || planned_pass(source, opts))
}

fn planned_pass(source: &dyn FrameSource, opts: &PassOptions) -> Result<NoiseSums> {
    let n = source.len();
    if n == 0 {
        return Err(Error::Value("no frames to analyse".into()));
    }
    let max_bytes = opts.max_bytes.unwrap_or(io::DEFAULT_MAX_BYTES);
    let mut first: Option<NoiseSums> = None;
    let mut layout: Option<Layout> = None;
    let mut plan: Option<Schedule> = None;
    source.with_frames(0..1, &mut |frames| {
        let frame = frames[0];
        let full = (frame.rows, frame.cols);
        let window = opts.window.unwrap_or(Window { row0: 0, col0: 0, rows: full.0, cols: full.1 });
        if window.rows == 0
            || window.cols == 0
            || window.row0 + window.rows > full.0
            || window.col0 + window.cols > full.1
        {
            return Err(Error::Shape(format!(
                "{}: region rows {}..{}, columns {}..{} is empty or outside the {} x {} frame",
                source.label(0),
                window.row0,
                window.row0 + window.rows,
                window.col0,
                window.col0 + window.cols,
                full.0,
                full.1
            )));
        }
        let l = Layout { full, dtype: frame.samples.dtype(), window };
        plan = Some(schedule(&l, n, source.allocates(), effective_workers(opts.workers), max_bytes)?);
        let mut sums = NoiseSums::new(window.rows, window.cols, l.dtype, opts.limits)?;
        add_batch(&mut sums, frames, &l, &|_| source.label(0))?;
        layout = Some(l);
        first = Some(sums);
        Ok(())
    })?;
    let (first, layout) = (first.expect("first frame"), layout.expect("first frame"));
    let Schedule { workers, batch, chunk } = plan.expect("first frame");
    let pivot = match &first.acc {
        Acc::Float(a) => Some(Arc::clone(&a.pivot)),
        Acc::Int(_) => None,
    };
    // Integer chunks cost only their per-frame sums, so they are short (the workers share
    // the frames evenly whatever the machine's load) and may run any distance ahead.
    let chunks = Schedule::chunks(n, chunk);
    let ahead = if pivot.is_some() { 2 * workers } else { usize::MAX / 2 };
    let shared =
        Mutex::new(Shared { total: first, pending: Default::default(), locals: Vec::new(), next: 0, error: None });
    let appended = Condvar::new();
    let claim = AtomicUsize::new(0);
    let cancel = AtomicBool::new(false);

    // Float chunks get their own sums (so merges, and the result, do not depend on the
    // worker count); integer chunks add into the worker's accumulator and hand on only
    // their per-frame sums (no per-chunk per-pixel arrays to allocate and merge).
    let add_range = |sums: &mut NoiseSums, start: usize, stop: usize| -> std::result::Result<(), (usize, Error)> {
        for i in (start..stop).step_by(batch) {
            if cancel.load(Ordering::Relaxed) {
                break;
            }
            let batch = i..(i + batch).min(stop);
            let label = |k: usize| source.label(i + k);
            source.with_frames(batch, &mut |frames| add_batch(sums, frames, &layout, &label)).map_err(|e| (i, e))?;
        }
        Ok(())
    };
    let sum_chunk = |c: usize, local: &mut Option<NoiseSums>| -> std::result::Result<Piece, (usize, Error)> {
        let (start, stop) = (1 + c * chunk, (1 + (c + 1) * chunk).min(n));
        if let Some(p) = &pivot {
            let w = layout.window;
            let mut sums = NoiseSums::with_pivot(w.rows, w.cols, layout.dtype, Arc::clone(p));
            add_range(&mut sums, start, stop)?;
            return Ok(Piece::Sums(sums));
        }
        let sums = match local {
            Some(l) => l,
            None => local.insert(
                NoiseSums::new(layout.window.rows, layout.window.cols, layout.dtype, opts.limits)
                    .map_err(|e| (start, e))?,
            ),
        };
        let frames0 = sums.frames;
        let Acc::Int(a) = &sums.acc else { unreachable!("integer sums") };
        let (rows0, cols0) = (a.row_sums.len(), a.col_sums.len());
        add_range(sums, start, stop)?;
        let Acc::Int(a) = &mut sums.acc else { unreachable!("integer sums") };
        let (rows, cols) = a.split_frames(rows0, cols0);
        Ok(Piece::Frames { rows, cols, count: sums.frames - frames0 })
    };
    let worker = || {
        let mut local: Option<NoiseSums> = None;
        loop {
            let c = claim.fetch_add(1, Ordering::Relaxed);
            if c >= chunks {
                break;
            }
            {
                let mut st = lock(&shared);
                while c >= st.next + ahead && !cancel.load(Ordering::Relaxed) {
                    st = appended.wait(st).unwrap_or_else(|p| p.into_inner());
                }
            }
            if cancel.load(Ordering::Relaxed) {
                break;
            }
            let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| sum_chunk(c, &mut local)))
                .unwrap_or_else(|p| {
                    let err = budget::refused_error(&*p)
                        .unwrap_or_else(|| Error::Value("internal error while summing frames".into()));
                    Err((1 + c * chunk, err))
                });
            let mut st = lock(&shared);
            match result {
                Ok(piece) => {
                    st.pending.insert(c, piece);
                    loop {
                        let key = st.next;
                        let Some(next) = st.pending.remove(&key) else { break };
                        if let Err(e) = append_piece(&mut st.total, next) {
                            st.error.get_or_insert((0, e));
                            cancel.store(true, Ordering::Relaxed);
                        }
                        st.next += 1;
                    }
                }
                Err((i, e)) => {
                    if st.error.as_ref().is_none_or(|(j, _)| i < *j) {
                        st.error = Some((i, e));
                    }
                    cancel.store(true, Ordering::Relaxed);
                }
            }
            appended.notify_all();
        }
        if let Some(l) = local {
            lock(&shared).locals.push(l);
        }
    };
    if workers <= 1 {
        worker();
    } else {
        std::thread::scope(|scope| {
            for _ in 0..workers {
                scope.spawn(worker);
            }
        });
    }
    let mut st = shared.into_inner().unwrap_or_else(|p| p.into_inner());
    if let Some((_, e)) = st.error {
        return Err(e);
    }
    if st.next != chunks {
        return Err(Error::Value("internal: not every chunk of frames was summed".into()));
    }
    for local in std::mem::take(&mut st.locals) {
        match (&mut st.total.acc, &local.acc) {
            (Acc::Int(total), Acc::Int(l)) => total.add_pixels(l)?,
            _ => return Err(Error::Value("internal: a float pass kept worker sums".into())),
        }
    }
    Ok(st.total)
}

/// Append a chunk to the total.
fn append_piece(total: &mut NoiseSums, piece: Piece) -> Result<()> {
    match piece {
        Piece::Sums(sums) => total.append(&sums),
        Piece::Frames { rows, cols, count } => match &mut total.acc {
            Acc::Int(a) => {
                a.push_frames(&rows, &cols);
                total.frames += count;
                Ok(())
            }
            Acc::Float(_) => Err(Error::Value("internal: integer frame sums for a float pass".into())),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An in-memory cube read as if each frame were decoded (the plan counts the frames).
    struct Decoded<'a>(ArraySource<'a>);

    impl FrameSource for Decoded<'_> {
        fn len(&self) -> usize {
            self.0.len()
        }
        fn label(&self, i: usize) -> String {
            self.0.label(i)
        }
        fn with_frames(&self, range: Range<usize>, visit: &mut dyn FnMut(&[FrameRef<'_>]) -> Result<()>) -> Result<()> {
            self.0.with_frames(range, visit)
        }
        fn allocates(&self) -> bool {
            true
        }
    }

    fn frames(n: usize) -> Vec<u16> {
        (0..n).map(|i| (1000 + (i * 7919) % 97) as u16).collect()
    }

    #[test]
    fn a_tight_budget_runs_fewer_workers_reading_fewer_frames_with_the_same_sums() {
        let (t, v, h) = (21, 16, 24);
        let data = frames(t * v * h);
        let source = Decoded(ArraySource { data: Samples::U16(&data), frames: t, rows: v, cols: h });
        let opts = |max_bytes| PassOptions { workers: 3, max_bytes, ..Default::default() };
        let free = run_pass(&source, &opts(None)).unwrap();
        let layout = Layout { full: (v, h), dtype: Dtype::U16, window: Window { row0: 0, col0: 0, rows: v, cols: h } };
        let least = Schedule::new(&layout, t, 1, 1);
        let tight = pass_plan(&layout, t, true, least).bytes;
        assert_eq!(schedule(&layout, t, true, 3, tight).unwrap(), least);
        assert_eq!(schedule(&layout, t, true, 3, u64::MAX).unwrap(), Schedule::new(&layout, t, 3, BATCH));
        assert_eq!(run_pass(&source, &opts(Some(tight))).unwrap(), free);
        let err = run_pass(&source, &opts(Some(tight - 1))).unwrap_err();
        assert!(matches!(&err, Error::Value(m) if m.contains("the 3-D noise pass (1 worker, 1 frame read")), "{err:?}");
        // a cube in memory is not counted: only the sums
        let borrowed = ArraySource { data: Samples::U16(&data), frames: t, rows: v, cols: h };
        assert_eq!(run_pass(&borrowed, &opts(Some(tight))).unwrap(), free);
    }

    #[test]
    fn float_passes_run_fewer_workers_with_the_same_sums_bit_for_bit() {
        let (t, v, h) = (70, 8, 10);
        let data: Vec<f32> = frames(t * v * h).iter().map(|&x| x as f32 * 0.37).collect();
        let source = ArraySource { data: Samples::F32(&data), frames: t, rows: v, cols: h };
        let opts = |max_bytes| PassOptions { workers: 2, max_bytes, ..Default::default() };
        let layout = Layout { full: (v, h), dtype: Dtype::F32, window: Window { row0: 0, col0: 0, rows: v, cols: h } };
        let one = pass_plan(&layout, t, false, Schedule::new(&layout, t, 1, BATCH)).bytes;
        assert!(one < pass_plan(&layout, t, false, Schedule::new(&layout, t, 2, BATCH)).bytes);
        assert_eq!(run_pass(&source, &opts(Some(one))).unwrap(), run_pass(&source, &opts(None)).unwrap());
        assert!(run_pass(&source, &opts(Some(one - 1))).is_err());
    }
}
