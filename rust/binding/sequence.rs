//! Python wrappers of the sequence engine (`crate::sequence`): `score_pairs`, `score_shared`
//! and `merge_all`.
//!
//! `score_pairs` starts the engine ([`sequence::stream_pairs`], which owns the bounded queue
//! and the worker threads) and polls it: the calling thread waits for outcomes with the GIL
//! released (about one round of the workers, at most 100 ms) and takes the GIL only to hand
//! them to Python, report progress and check for signals (Ctrl-C cancels the pairs not yet
//! started, waits for those in flight, then raises `KeyboardInterrupt`).

use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::time::Duration;

use numpy::{PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyList, PyTuple};

use super::args::{self, SequenceRequest};
use super::dtypes::contiguous;
use super::stats::PyPairStats;
use crate::sequence::{self, Batch, PairOutcome, PairStream, SeqMask, Source};
use crate::Error;

const POLL: Duration = Duration::from_millis(100);

fn sources(paths: Vec<PathBuf>, pages: Option<Vec<usize>>, which: &str) -> crate::Result<Vec<Source>> {
    let pages = pages.unwrap_or_else(|| vec![0; paths.len()]);
    if pages.len() != paths.len() {
        return Err(Error::Value(format!("{which}: {} paths but {} pages", paths.len(), pages.len())));
    }
    Ok(paths.into_iter().zip(pages).map(|(p, g)| Source::new(p, g)).collect())
}

/// The sequence's `mask` argument (a 2-D bool array, C-contiguous) copied once, for every
/// pair and worker to share.
fn sequence_mask(mask: Option<PyReadonlyArrayDyn<'_, bool>>) -> crate::Result<Option<SeqMask>> {
    let Some(mask) = mask else { return Ok(None) };
    let &[rows, cols] = mask.shape() else {
        return Err(Error::Shape(format!(
            "mask must be 2-D (the frames' rows and columns), got shape {:?}",
            mask.shape()
        )));
    };
    SeqMask::new(contiguous(&mask, "the mask")?.into(), (rows, cols)).map(Some)
}

fn outcome_tuple<'py>(py: Python<'py>, o: PairOutcome) -> PyResult<Bound<'py, PyTuple>> {
    let (stats, err) = match o.stats {
        Ok(s) => (Some(Py::new(py, PyPairStats::with_entropies(s, o.entropies))?), None),
        Err(e) => (None, Some(e.to_string())),
    };
    let registration = o.registration.as_ref().map(super::register::registration_tuple);
    let fingerprints = o.fingerprints.map(|(r, s)| ((r.size, r.mtime_ns, r.digest), (s.size, s.mtime_ns, s.digest)));
    (o.index, stats, err, o.shape, o.dtype, o.real_extent, registration, fingerprints).into_pyobject(py)
}

/// Where outcomes go: a Python callback (streaming), or slots in index order (collecting).
enum Delivery<'py> {
    Stream(Bound<'py, PyAny>),
    Collect(Vec<Option<PairOutcome>>),
}

impl<'py> Delivery<'py> {
    fn deliver(&mut self, py: Python<'py>, outcomes: Vec<PairOutcome>) -> PyResult<()> {
        match self {
            Delivery::Stream(on_result) => {
                let items = PyList::empty(py);
                for o in outcomes {
                    items.append(outcome_tuple(py, o)?)?;
                }
                on_result.call1((items,))?;
            }
            Delivery::Collect(slots) => {
                for o in outcomes {
                    let i = o.index;
                    slots[i] = Some(o);
                }
            }
        }
        Ok(())
    }

    /// The collected outcomes as a list in index order (`None` when streaming).
    fn into_list(self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyList>>> {
        let Delivery::Collect(slots) = self else { return Ok(None) };
        let list = PyList::empty(py);
        for (i, o) in slots.into_iter().enumerate() {
            let o = o.ok_or_else(|| Error::Value(format!("internal error: frame pair {i} was not scored")))?;
            list.append(outcome_tuple(py, o)?)?;
        }
        Ok(Some(list))
    }
}

/// Hand every outcome of `stream` to `delivery` and the finished count to `progress`,
/// until the engine finishes or Python raises (a signal, or an exception in a callback).
fn poll<'py>(
    py: Python<'py>,
    stream: &mut PairStream,
    delivery: &mut Delivery<'py>,
    progress: Option<&Bound<'py, PyAny>>,
) -> PyResult<()> {
    // Wake about once per round of the workers, not per outcome: each wake takes the GIL
    // and runs Python on a core the workers need (below the queue's capacity: no stall).
    let wake_at = stream.workers();
    let mut reported = usize::MAX;
    loop {
        let Batch { outcomes, finished } = py.detach(|| stream.next_batch(wake_at, POLL));
        py.check_signals()?;
        if !outcomes.is_empty() {
            delivery.deliver(py, outcomes)?;
        }
        let done = stream.progress().done.load(Ordering::Acquire);
        if done != reported {
            if let Some(cb) = progress {
                cb.call1((done,))?;
            }
            reported = done;
        }
        if finished {
            return Ok(());
        }
    }
}

/// `score_pairs(real_paths, sim_paths, real_pages=None, sim_pages=None, *, request,
/// workers=0, progress=None, on_result=None, fingerprints=False, mask=None)`
///
/// Decode and score every pair `(real_paths[i] page real_pages[i], sim_paths[i] page
/// sim_pages[i])` on `workers` threads (0 = all cores) with the GIL released, as
/// `request` (an `irfidelity.sequence.plan.SequenceRequest`) says. Each outcome is a tuple
/// `(index, PairStats | None, error_message | None, (rows, cols) | None, dtype_name | None,
/// real_extent | None, registration | None, fingerprints | None)`; a frame that cannot be
/// read or scored gives an error message for its index only. With `fingerprints`, the last
/// item is `((size, mtime_ns, xxh3), (size, mtime_ns, xxh3))` of the real and the simulated
/// file, of the bytes that were decoded (None when a file changed while it was decoded).
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
///
/// `mask` (a 2-D bool array of the frames' shape, copied once for the whole run): every
/// pair is scored over its `True` pixels (registered: over the overlap within it, the
/// registration searched over it); a pair of another shape is that pair's error.
#[pyfunction]
#[pyo3(signature = (real_paths, sim_paths, real_pages=None, sim_pages=None, *, request, workers=0,
                    progress=None, on_result=None, fingerprints=false, mask=None))]
#[allow(clippy::too_many_arguments)]
fn score_pairs<'py>(
    py: Python<'py>,
    real_paths: Vec<PathBuf>,
    sim_paths: Vec<PathBuf>,
    #[pyo3(from_py_with = args::real_pages)] real_pages: Option<Vec<usize>>,
    #[pyo3(from_py_with = args::sim_pages)] sim_pages: Option<Vec<usize>>,
    #[pyo3(from_py_with = args::sequence_request)] request: SequenceRequest,
    #[pyo3(from_py_with = args::workers)] workers: usize,
    progress: Option<Bound<'py, PyAny>>,
    on_result: Option<Bound<'py, PyAny>>,
    fingerprints: bool,
    mask: Option<PyReadonlyArrayDyn<'py, bool>>,
) -> PyResult<Option<Bound<'py, PyList>>> {
    let real = sources(real_paths, real_pages, "real")?;
    let sim = sources(sim_paths, sim_pages, "sim")?;
    let n = real.len();
    let req = sequence::SeqRequest { fingerprint: fingerprints, ..request.sequence_request()? };
    let stream = sequence::stream_pairs(real, sim, req, sequence_mask(mask)?, workers)?;
    drain(py, stream, n, progress, on_result)
}

/// Poll `stream` to its end, delivering its `n` outcomes to `on_result` or as a list.
fn drain<'py>(
    py: Python<'py>,
    mut stream: PairStream,
    n: usize,
    progress: Option<Bound<'py, PyAny>>,
    on_result: Option<Bound<'py, PyAny>>,
) -> PyResult<Option<Bound<'py, PyList>>> {
    let mut delivery = match on_result {
        Some(cb) => Delivery::Stream(cb),
        None => Delivery::Collect((0..n).map(|_| None).collect()),
    };
    let polled = poll(py, &mut stream, &mut delivery, progress.as_ref());
    if polled.is_err() {
        stream.cancel();
    }
    // waits for the pairs in flight (none are left when polling ended normally)
    let finished = py.detach(|| stream.finish());
    polled?;
    finished?;
    delivery.into_list(py)
}

/// `score_shared(real_paths, real_pages, sim_paths, sim_pages, owners, kinds, *, requests,
/// workers=0, progress=None, on_result=None, fingerprints=False, mask=None)`
///
/// Several simulators against one real sequence, each real frame decoded once: task `k`
/// scores `(sim_paths[k], sim_pages[k])` against real frame `owners[k]` with
/// `requests[kinds[k]]` (one `irfidelity.sequence.plan.SequenceRequest` per simulator; the
/// real frame is decoded with the decode options of its first task's request). The outcomes,
/// `progress`, `on_result`, `fingerprints` and `mask` (one for every task: it is on the real
/// frames' grid) are those of `score_pairs`, an outcome's index being its task.
#[pyfunction]
#[pyo3(signature = (real_paths, real_pages, sim_paths, sim_pages, owners, kinds, *, requests, workers=0,
                    progress=None, on_result=None, fingerprints=false, mask=None))]
#[allow(clippy::too_many_arguments)]
fn score_shared<'py>(
    py: Python<'py>,
    real_paths: Vec<PathBuf>,
    real_pages: Vec<usize>,
    sim_paths: Vec<PathBuf>,
    sim_pages: Vec<usize>,
    owners: Vec<usize>,
    kinds: Vec<usize>,
    requests: Vec<Bound<'py, PyAny>>,
    #[pyo3(from_py_with = args::workers)] workers: usize,
    progress: Option<Bound<'py, PyAny>>,
    on_result: Option<Bound<'py, PyAny>>,
    fingerprints: bool,
    mask: Option<PyReadonlyArrayDyn<'py, bool>>,
) -> PyResult<Option<Bound<'py, PyList>>> {
    let real = sources(real_paths, Some(real_pages), "real")?;
    let sims = sources(sim_paths, Some(sim_pages), "sim")?;
    let n = sims.len();
    let requests = requests
        .iter()
        .map(|r| -> PyResult<sequence::SeqRequest> {
            let req = args::sequence_request(r)?;
            Ok(sequence::SeqRequest { fingerprint: fingerprints, ..req.sequence_request()? })
        })
        .collect::<PyResult<Vec<_>>>()?;
    let tasks = sequence::SharedTasks { real, sims, owners, requests, kinds, mask: sequence_mask(mask)? };
    let stream = sequence::stream_shared(tasks, workers)?;
    drain(py, stream, n, progress, on_result)
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
    let merged = super::detached(py, || {
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
                    real_range: None,
                })
                .collect();
            sequence::merge_all(bare.iter())
        }
    })?;
    Ok(match merged {
        None => (None, false),
        Some((p, keep)) => (Some(PyPairStats::new(p)), keep),
    })
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(score_pairs, m)?)?;
    m.add_function(wrap_pyfunction!(score_shared, m)?)?;
    m.add_function(wrap_pyfunction!(merge_all, m)?)?;
    Ok(())
}
