//! Python wrappers of the sequence engine (`crate::sequence`): `score_pairs` and
//! `merge_all`.
//!
//! `score_pairs` runs the engine on a background thread with the GIL released; the
//! calling thread waits for outcomes (a few at a time, at most 100 ms) and takes the GIL
//! only to hand them to Python, report progress and check for signals (Ctrl-C cancels the pairs
//! not yet started, waits for those in flight, then raises `KeyboardInterrupt`).

use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::sync::{Condvar, Mutex, MutexGuard};
use std::time::Duration;

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyList, PyTuple};

use super::stats::PyPairStats;
use super::IntoPy;
use crate::sequence::{self, PairOutcome, Progress, SeqRequest, Source};
use crate::stats::HistRequest;

const POLL: Duration = Duration::from_millis(100);

fn sources(paths: Vec<PathBuf>, pages: Option<Vec<usize>>, which: &str) -> PyResult<Vec<Source>> {
    let pages = pages.unwrap_or_else(|| vec![0; paths.len()]);
    if pages.len() != paths.len() {
        return Err(PyValueError::new_err(format!("{which}: {} paths but {} pages", paths.len(), pages.len())));
    }
    Ok(paths.into_iter().zip(pages).map(|(p, g)| Source::new(p, g)).collect())
}

/// Outcomes waiting for the calling thread, and whether the engine has finished.
struct Queue {
    items: Vec<PairOutcome>,
    finished: bool,
}

struct Shared {
    queue: Mutex<Queue>,
    /// Signalled when an outcome arrives or the engine finishes (the poller waits on it).
    ready: Condvar,
    /// Signalled when the poller drained the queue (workers wait on it when it is full).
    space: Condvar,
}

fn lock(m: &Mutex<Queue>) -> MutexGuard<'_, Queue> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

fn outcome_tuple<'py>(py: Python<'py>, o: PairOutcome) -> PyResult<Bound<'py, PyTuple>> {
    let (stats, err) = match o.stats {
        Ok(s) => (Some(Py::new(py, PyPairStats::with_entropies(s, o.entropies))?), None),
        Err(e) => (None, Some(e.to_string())),
    };
    (o.index, stats, err, o.shape, o.dtype).into_pyobject(py)
}

/// `score_pairs(real_paths, sim_paths, real_pages=None, sim_pages=None, *, channel=None,
/// sse=True, moments=True, bins=None, levels=False, hist_range=None, valid=None,
/// mask_nonfinite=False, max_pixels=None, workers=0, progress=None, on_result=None, max_bytes=None)`
///
/// Decode and score every pair `(real_paths[i] page real_pages[i], sim_paths[i] page
/// sim_pages[i])` on `workers` threads (0 = all cores) with the GIL released. Each
/// outcome is a tuple
/// `(index, PairStats | None, error_message | None, (rows, cols) | None, dtype_name | None)`;
/// a frame that cannot be read or scored gives an error message for its index only.
///
/// * `on_result=None`: returns the list of outcomes in index order.
/// * `on_result=callable`: outcomes are streamed as they finish (completion order), in
///   batches `on_result(list_of_tuples)` called from the calling thread; the function
///   returns None. At most a few outcomes per worker wait for the callback (workers
///   pause when it falls behind), so memory does not grow with the sequence length.
///
/// `progress(done)` is called from the calling thread whenever the count of finished
/// pairs changed (at most every 100 ms, and at the end). Ctrl-C (or an exception in a
/// callback) stops new pairs from starting, waits for the ones in flight and raises.
#[pyfunction]
#[pyo3(signature = (real_paths, sim_paths, real_pages=None, sim_pages=None, *, channel=None, sse=true,
                    moments=true, bins=None, levels=false, hist_range=None, valid=None,
                    mask_nonfinite=false, max_pixels=None, workers=0, progress=None, on_result=None,
                    max_bytes=None))]
#[allow(clippy::too_many_arguments)]
fn score_pairs<'py>(
    py: Python<'py>,
    real_paths: Vec<PathBuf>,
    sim_paths: Vec<PathBuf>,
    real_pages: Option<Vec<usize>>,
    sim_pages: Option<Vec<usize>>,
    channel: Option<String>,
    sse: bool,
    moments: bool,
    bins: Option<usize>,
    levels: bool,
    hist_range: Option<(f64, f64)>,
    valid: Option<(i64, i64)>,
    mask_nonfinite: bool,
    max_pixels: Option<u64>,
    workers: usize,
    progress: Option<Bound<'py, PyAny>>,
    on_result: Option<Bound<'py, PyAny>>,
    max_bytes: Option<u64>,
) -> PyResult<Option<Bound<'py, PyList>>> {
    let real = sources(real_paths, real_pages, "real")?;
    let sim = sources(sim_paths, sim_pages, "sim")?;
    if real.len() != sim.len() {
        return Err(super::to_pyerr(crate::Error::Value(format!(
            "the real sequence has {} frames and the simulated sequence {}; they must have the same number",
            real.len(),
            sim.len()
        ))));
    }
    let hist =
        if levels { Some(HistRequest::Levels) } else { bins.map(|b| HistRequest::Bins { bins: b, range: hist_range }) };
    let req = SeqRequest {
        sse,
        moments,
        hist,
        valid,
        mask_nonfinite,
        channel,
        max_pixels: max_pixels.unwrap_or(crate::io::DEFAULT_MAX_PIXELS),
        max_bytes: max_bytes.unwrap_or(crate::io::DEFAULT_MAX_BYTES),
    };
    let n = real.len();
    let workers_n = sequence::effective_workers(workers).max(1);
    let cap = 4 * workers_n;
    // Wake the caller about once per round of the workers, not per outcome: each wake takes
    // the GIL and runs Python on a core the workers need (below `cap`: never a stall).
    let wake_at = workers_n;
    let state = Progress::default();
    let shared = Shared {
        queue: Mutex::new(Queue { items: Vec::new(), finished: false }),
        ready: Condvar::new(),
        space: Condvar::new(),
    };
    let mut pending_err: Option<PyErr> = None;
    let mut collected: Vec<Option<PairOutcome>> = Vec::new();
    if on_result.is_none() {
        collected.resize_with(n, || None);
    }
    let engine_result = std::thread::scope(|scope| {
        let handle = scope.spawn(|| {
            // Mark the queue finished even if the engine panics, so the poller always ends.
            struct Finish<'a>(&'a Shared);
            impl Drop for Finish<'_> {
                fn drop(&mut self) {
                    let mut q = lock(&self.0.queue);
                    q.finished = true;
                    self.0.ready.notify_all();
                }
            }
            let _finish = Finish(&shared);
            let sink = |o: PairOutcome| {
                let mut q = lock(&shared.queue);
                q.items.push(o);
                if q.items.len() >= wake_at {
                    shared.ready.notify_all();
                }
                // back-pressure: wait while the caller is behind (unless cancelled)
                while q.items.len() >= cap && !state.cancel.load(Ordering::Relaxed) {
                    q = shared.space.wait_timeout(q, POLL).unwrap_or_else(|p| p.into_inner()).0;
                }
            };
            sequence::score_pairs_with(&real, &sim, &req, workers, &state, &sink)
        });
        let mut reported = usize::MAX;
        loop {
            let (batch, finished) = py.detach(|| {
                let q = lock(&shared.queue);
                let mut q = shared
                    .ready
                    .wait_timeout_while(q, POLL, |q| q.items.is_empty() && !q.finished)
                    .unwrap_or_else(|p| p.into_inner())
                    .0;
                let batch = std::mem::take(&mut q.items);
                shared.space.notify_all();
                (batch, q.finished)
            });
            if pending_err.is_none() {
                if let Err(e) = py.check_signals() {
                    state.cancel.store(true, Ordering::SeqCst);
                    pending_err = Some(e);
                }
            }
            if !batch.is_empty() && pending_err.is_none() {
                match &on_result {
                    Some(cb) => {
                        let delivered = (|| -> PyResult<()> {
                            let items = PyList::empty(py);
                            for o in batch {
                                items.append(outcome_tuple(py, o)?)?;
                            }
                            cb.call1((items,))?;
                            Ok(())
                        })();
                        if let Err(e) = delivered {
                            state.cancel.store(true, Ordering::SeqCst);
                            pending_err = Some(e);
                        }
                    }
                    None => {
                        for o in batch {
                            let i = o.index;
                            collected[i] = Some(o);
                        }
                    }
                }
            }
            let done = state.done.load(Ordering::Acquire);
            if pending_err.is_none() && done != reported {
                if let Some(cb) = &progress {
                    if let Err(e) = cb.call1((done,)) {
                        state.cancel.store(true, Ordering::SeqCst);
                        pending_err = Some(e);
                    }
                }
                reported = done;
            }
            if finished {
                break;
            }
        }
        match handle.join() {
            Ok(r) => r.map_err(super::to_pyerr),
            Err(_) => Err(PyValueError::new_err("internal error: the sequence engine panicked")),
        }
    });
    if let Some(e) = pending_err {
        return Err(e);
    }
    engine_result?;
    if on_result.is_some() {
        return Ok(None);
    }
    let list = PyList::empty(py);
    for (i, o) in collected.into_iter().enumerate() {
        let o = o.ok_or_else(|| PyValueError::new_err(format!("internal error: frame pair {i} was not scored")))?;
        list.append(outcome_tuple(py, o)?)?;
    }
    Ok(Some(list))
}

/// `merge_all(stats, keep_hist=True) -> (PairStats | None, hist_merged)`: merge a list of
/// statistics (GIL released). Histograms are kept when `keep_hist` and all share the same
/// edges, otherwise dropped (`hist_merged` is then False). `None` for an empty list.
#[pyfunction]
#[pyo3(signature = (stats, keep_hist=true))]
fn merge_all(
    py: Python<'_>,
    stats: Vec<PyRef<'_, PyPairStats>>,
    keep_hist: bool,
) -> PyResult<(Option<PyPairStats>, bool)> {
    let inner: Vec<&crate::stats::PairStats> = stats.iter().map(|p| &p.inner).collect();
    let merged = py
        .detach(|| {
            if keep_hist {
                sequence::merge_all(inner.iter().copied())
            } else {
                let bare: Vec<crate::stats::PairStats> = inner
                    .iter()
                    .map(|p| crate::stats::PairStats {
                        n: p.n,
                        masked: p.masked,
                        nonfinite: p.nonfinite,
                        has_sse: p.has_sse,
                        has_moments: p.has_moments,
                        sums: p.sums,
                        hist: None,
                    })
                    .collect();
                sequence::merge_all(bare.iter())
            }
        })
        .py_err()?;
    Ok(match merged {
        None => (None, false),
        Some((p, keep)) => (Some(PyPairStats::new(p)), keep),
    })
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(score_pairs, m)?)?;
    m.add_function(wrap_pyfunction!(merge_all, m)?)?;
    Ok(())
}
