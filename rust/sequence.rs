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
//! Progress: a shared [`AtomicUsize`] counts finished pairs (the Python binding polls
//! it), an optional callback is called after each pair, and an [`AtomicBool`] cancels
//! the pairs not yet started (Ctrl-C).

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::OnceLock;

use crate::hist::Entropies;
use crate::io::{self, DecodeOptions, Frame, FrameData};
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
    /// Channel to decode (EXR channel name, or PNG/TIFF channel); `None` = the only one / "Y".
    pub channel: Option<String>,
    pub max_pixels: u64,
}

impl Default for SeqRequest {
    fn default() -> Self {
        SeqRequest {
            sse: true,
            moments: true,
            hist: Some(HistRequest::Bins { bins: 256, range: None }),
            valid: None,
            mask_nonfinite: false,
            channel: None,
            max_pixels: io::DEFAULT_MAX_PIXELS,
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
}

fn run_kernel(r: FrameData, s: FrameData, req: &Request) -> Result<PairStats> {
    use FrameData::*;
    match (r, s) {
        (U8(a), U8(b)) => stats::pair_stats(&a, &b, req),
        (U16(a), U16(b)) => stats::pair_stats(&a, &b, req),
        (I16(a), I16(b)) => stats::pair_stats(&a, &b, req),
        (U32(a), U32(b)) => stats::pair_stats(&a, &b, req),
        (F16(a), F16(b)) => stats::pair_stats(&a, &b, &Request { valid: None, ..req.clone() }),
        (F32(a), F32(b)) => stats::pair_stats(&a, &b, &Request { valid: None, ..req.clone() }),
        (F64(a), F64(b)) => stats::pair_stats(&a, &b, &Request { valid: None, ..req.clone() }),
        (a, b) => Err(Error::Shape(format!(
            "real and sim frames differ in dtype: {} vs {}; convert one so no silent rounding happens",
            a.dtype_name(),
            b.dtype_name()
        ))),
    }
}

fn prefix(err: Error, what: &str) -> Error {
    match err {
        Error::Shape(m) => Error::Shape(format!("{what}: {m}")),
        Error::Range(m) => Error::Range(format!("{what}: {m}")),
        Error::Value(m) => Error::Value(format!("{what}: {m}")),
        Error::Registration(m) => Error::Registration(format!("{what}: {m}")),
        // decode errors already start with the path
        Error::Frame(m) => Error::Frame(m),
    }
}

fn decode(src: &Source, req: &SeqRequest) -> Result<Frame> {
    let opts = DecodeOptions { channel: req.channel.clone(), max_pixels: req.max_pixels, page: src.page };
    io::decode_frame(&src.path, &opts)
}

/// Decode and score one pair on the current thread (and the current rayon pool).
pub fn score_pair(index: usize, real: &Source, sim: &Source, req: &SeqRequest) -> PairOutcome {
    let mut out =
        PairOutcome { index, stats: Err(Error::Value(String::new())), shape: None, dtype: None, entropies: None };
    let body = || -> Result<PairStats> {
        let r = decode(real, req)?;
        out.shape = Some((r.rows, r.cols));
        out.dtype = Some(r.data.dtype_name());
        let s = decode(sim, req)?;
        let what = || format!("{} vs {}", real.label(), sim.label());
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
            mask: None,
            valid: req.valid,
            mask_nonfinite: req.mask_nonfinite,
            shape: (r.rows, r.cols),
            fortran: false,
        };
        let st = run_kernel(r.data, s.data, &kreq).map_err(|e| prefix(e, &what()))?;
        out.entropies = st.entropies();
        Ok(st)
    };
    let res = catch_unwind(AssertUnwindSafe(body));
    out.stats = match res {
        Ok(r) => r,
        Err(payload) => {
            let msg = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "panic".into());
            Err(Error::Value(format!("{} vs {}: internal error: {msg}", real.label(), sim.label())))
        }
    };
    out
}

/// Shared progress state: finished pairs, and a cancel flag for the pairs not started.
#[derive(Debug, Default)]
pub struct Progress {
    pub done: AtomicUsize,
    pub cancel: AtomicBool,
}

/// Score `real[i]` against `sim[i]` for every `i`, with `workers` threads (0 = all cores),
/// handing each outcome to `sink` as soon as it is ready (completion order, from the
/// worker threads). `sink` may block to apply back-pressure: the worker then waits before
/// decoding its next pair, so memory stays bounded.
///
/// Errors only for bad arguments (different lengths) or when the thread pool cannot be
/// built; frame problems are per-pair errors. Pairs not started when `progress.cancel`
/// is set are never given to `sink`.
pub fn score_pairs_with(
    real: &[Source],
    sim: &[Source],
    req: &SeqRequest,
    workers: usize,
    progress: &Progress,
    sink: &(dyn Fn(PairOutcome) + Sync),
) -> Result<()> {
    if real.len() != sim.len() {
        return Err(Error::Value(format!(
            "the real sequence has {} frames and the simulated sequence {}; they must have the same number",
            real.len(),
            sim.len()
        )));
    }
    let n = real.len();
    if n == 0 {
        return Ok(());
    }
    let workers = effective_workers(workers).min(n);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(workers)
        .thread_name(|i| format!("irfidelity-seq-{i}"))
        .build()
        .map_err(|e| Error::Value(format!("cannot start {workers} worker threads: {e}")))?;
    let next = AtomicUsize::new(0);
    let work = || loop {
        if progress.cancel.load(Ordering::Relaxed) {
            break;
        }
        let i = next.fetch_add(1, Ordering::Relaxed);
        if i >= n {
            break;
        }
        // While every worker has pairs left, each pair runs on its own thread; the last
        // pairs may split their passes over threads that ran out of work.
        let busy = workers > 1 && i + workers < n;
        let outcome = crate::kernel::with_pool_busy(busy, || score_pair(i, &real[i], &sim[i], req));
        progress.done.fetch_add(1, Ordering::AcqRel);
        sink(outcome);
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

/// [`score_pairs_with`] collecting the outcomes: one entry per index, in index order,
/// `None` for pairs skipped because `progress.cancel` was set. `on_done(count)` is called
/// after each pair.
pub fn score_pairs(
    real: &[Source],
    sim: &[Source],
    req: &SeqRequest,
    workers: usize,
    progress: &Progress,
    on_done: Option<&(dyn Fn(usize) + Sync)>,
) -> Result<Vec<Option<PairOutcome>>> {
    let slots: Vec<OnceLock<PairOutcome>> = (0..real.len().min(sim.len())).map(|_| OnceLock::new()).collect();
    let sink = |o: PairOutcome| {
        let i = o.index;
        let _ = slots[i].set(o);
        if let Some(cb) = on_done {
            cb(progress.done.load(Ordering::Acquire));
        }
    };
    score_pairs_with(real, sim, req, workers, progress, &sink)?;
    Ok(slots.into_iter().map(|s| s.into_inner()).collect())
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

    fn stack_sources(range: std::ops::Range<usize>) -> Vec<Source> {
        range.map(|p| Source::new(data(STACK), p)).collect()
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
        let req = SeqRequest::default();
        let prog = Progress::default();
        let out = score_pairs(&real, &sim, &req, 2, &prog, None).unwrap();
        assert_eq!(out.len(), 12);
        assert_eq!(prog.done.load(Ordering::SeqCst), 12);
        for (i, o) in out.iter().enumerate() {
            let o = o.as_ref().unwrap();
            assert_eq!(o.index, i);
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
        let a = score_pairs(&real, &sim, &req, 1, &Progress::default(), None).unwrap();
        let b = score_pairs(&real, &sim, &req, 3, &Progress::default(), None).unwrap();
        let sa: Vec<PairStats> = a.into_iter().map(|o| o.unwrap().stats.unwrap()).collect();
        let sb: Vec<PairStats> = b.into_iter().map(|o| o.unwrap().stats.unwrap()).collect();
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
        let out = score_pairs(&real, &sim, &SeqRequest::default(), 2, &Progress::default(), None).unwrap();
        let st: Vec<PairStats> = out.into_iter().map(|o| o.unwrap().stats.unwrap()).collect();
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
        let out = score_pairs(&real, &sim, &SeqRequest::default(), 2, &Progress::default(), None).unwrap();
        let out: Vec<PairOutcome> = out.into_iter().map(Option::unwrap).collect();
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
        let out = score_pairs(&real, &sim, &req, 2, &Progress::default(), None).unwrap();
        for o in out {
            let e = o.unwrap().stats.unwrap_err();
            assert!(matches!(&e, Error::Range(m) if m.contains("cptv_v2_all100frames_uint16.tif[")), "{e:?}");
        }
    }

    #[test]
    fn mismatched_lengths_and_cancel() {
        let real = stack_sources(0..3);
        let sim = stack_sources(0..2);
        let e = score_pairs(&real, &sim, &SeqRequest::default(), 1, &Progress::default(), None).unwrap_err();
        assert!(e.to_string().contains("3 frames") && e.to_string().contains(" 2;"));

        let real = stack_sources(0..30);
        let sim = stack_sources(30..60);
        let prog = Progress::default();
        let calls = AtomicUsize::new(0);
        let cb = |d: usize| {
            calls.fetch_add(1, Ordering::SeqCst);
            if d >= 3 {
                prog.cancel.store(true, Ordering::SeqCst);
            }
        };
        let out = score_pairs(&real, &sim, &SeqRequest::default(), 1, &prog, Some(&cb)).unwrap();
        let done = out.iter().filter(|o| o.is_some()).count();
        assert_eq!(done, 3);
        assert_eq!(calls.load(Ordering::SeqCst), 3);
        assert!(out[..3].iter().all(|o| o.is_some()));
    }

    #[test]
    fn plan_only_what_is_needed() {
        let real = stack_sources(0..2);
        let sim = stack_sources(2..4);
        let req = SeqRequest { moments: false, hist: None, ..Default::default() };
        let out = score_pairs(&real, &sim, &req, 2, &Progress::default(), None).unwrap();
        for o in out {
            let st = o.unwrap().stats.unwrap();
            assert!(st.has_sse && !st.has_moments && st.hist.is_none());
        }
    }
}
