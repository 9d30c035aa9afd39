//! Splitting one piece of work over the calling thread and idle pool threads.
//!
//! The work comes in units (the chunks of a pass, the blocks of an EXR file). The calling
//! thread works through them itself, one at a time from a shared counter, while helpers queued
//! on the rayon pool take units from the same counter when, and if, they start. A helper that
//! has not started by the time the units run out is cancelled, never waited for. A busy
//! machine (the other cores running something else) then costs the work the queuing of a job,
//! and it runs at single-thread speed. rayon's own splitting hands part of the work to a pool
//! thread and waits for it to finish, however late the scheduler runs it: 512 × 512 float SSIM
//! took 0.35–0.45 ms that way, against 0.28 ms on one thread, while other threads held the
//! second core.
//!
//! Entry points: [`fold_chunks`] and [`map_chunks`] (the chunks of a frame pair),
//! [`map_units`] (any indexed units). The helpers borrow the caller's data and closures
//! through a type-erased pointer (rayon's `spawn` needs `'static` jobs). The protocol that
//! makes this sound: a helper may touch the job only after moving its slot from `Pending` to
//! `Running`, and the caller returns (or unwinds) only after moving every slot from `Pending`
//! to `Closed` or seeing it `Done`.

use std::any::Any;
use std::panic::{self, AssertUnwindSafe};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};

use super::CHUNK;

/// Rough single-core cost of one pass, in nanoseconds per pixel pair (measured on 2-core
/// x86-64 VMs with AVX2): only the order of magnitude matters, it decides threading.
pub(crate) mod cost {
    /// min/max of both frames
    pub const RANGE: f64 = 0.15;
    /// compensated sums and range of both float frames
    pub const SCAN: f64 = 1.5;
    /// squared error only (PSNR/MSE plan)
    pub const SSE: f64 = 0.2;
    /// moments and/or histogram, integer frames
    pub const FULL_INT: f64 = 3.0;
    /// moments and/or histogram, float frames
    pub const FULL_FLOAT: f64 = 6.0;
}

/// Passes estimated below this many nanoseconds run on the calling thread alone: queuing a
/// helper costs the caller a few microseconds, and a helper needs 5–50 µs to wake (more in
/// VMs), so shorter passes would end before it helps.
const PARALLEL_MIN_NS: f64 = 30_000.0;

thread_local! {
    /// Set on a thread whose pool is already busy with independent work (the sequence
    /// engine's pair loops): splitting a pass there only adds stealing and wake-ups.
    static POOL_BUSY: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Run `f` with nested parallel passes turned off on this thread (see `POOL_BUSY`).
pub fn with_pool_busy<R>(busy: bool, f: impl FnOnce() -> R) -> R {
    let before = POOL_BUSY.with(|b| b.replace(busy));
    let out = f();
    POOL_BUSY.with(|b| b.set(before));
    out
}

/// Whether this thread's pool is busy with independent work (see `with_pool_busy`).
pub fn pool_busy() -> bool {
    POOL_BUSY.with(|b| b.get())
}

/// Whether a pass over `n` pixel pairs at `ns_per_px` is worth the thread pool.
fn worth_parallel(n: usize, ns_per_px: f64) -> bool {
    n as f64 * ns_per_px >= PARALLEL_MIN_NS && rayon::current_num_threads() > 1 && !pool_busy()
}

fn chunk_ranges(n: usize) -> Vec<(usize, usize)> {
    (0..n.div_ceil(CHUNK)).map(|c| (c * CHUNK, ((c + 1) * CHUNK).min(n))).collect()
}

/// Fold `step` over the chunks of a pair of `n`-pixel frames, starting each partial result
/// from `init`, and combine the partial results with `merge`: on the calling thread for cheap
/// passes (see `worth_parallel`), shared with idle pool threads otherwise.
///
/// Chunks are taken in order; a failing chunk stops the others from starting new ones, and
/// the error of the lowest failing chunk is returned, so errors do not depend on timing.
pub(crate) fn fold_chunks<A, E>(
    n: usize,
    ns_per_px: f64,
    init: impl Fn() -> A + Sync,
    step: impl Fn(A, (usize, usize)) -> Result<A, E> + Sync,
    merge: impl Fn(A, A) -> A,
) -> Result<A, E>
where
    A: Send,
    E: Send,
{
    let chunks = chunk_ranges(n);
    let helpers = if worth_parallel(n, ns_per_px) { helpers_for(chunks.len()) } else { 0 };
    share(chunks.len(), helpers, init, |acc, i| step(acc, chunks[i]), merge)
}

/// `f` of every chunk of a pair of `n`-pixel frames, in chunk order, computed like
/// [`fold_chunks`] (shared with idle pool threads when worth it). For float partial sums:
/// combined in chunk order afterwards, they do not depend on how the chunks were shared out.
pub(crate) fn map_chunks<R, E>(
    n: usize,
    ns_per_px: f64,
    f: impl Fn((usize, usize)) -> Result<R, E> + Sync,
) -> Result<Vec<R>, E>
where
    R: Send,
    E: Send,
{
    let chunks = chunk_ranges(n);
    let helpers = if worth_parallel(n, ns_per_px) { helpers_for(chunks.len()) } else { 0 };
    ordered(chunks.len(), helpers, |i| f(chunks[i]))
}

/// `f(0), f(1), …, f(units − 1)` in order, shared with idle pool threads when `parallel`
/// (and this thread's pool is not busy with other frames): units of work that are each worth
/// a wake-up, such as the compressed blocks of an EXR file.
pub fn map_units<R, E>(units: usize, parallel: bool, f: impl Fn(usize) -> Result<R, E> + Sync) -> Result<Vec<R>, E>
where
    R: Send,
    E: Send,
{
    let helpers = if parallel && !pool_busy() { helpers_for(units) } else { 0 };
    ordered(units, helpers, f)
}

/// Helpers worth queuing for `units` units: one per other pool thread, at most one per unit
/// beyond the caller's first.
fn helpers_for(units: usize) -> usize {
    (rayon::current_num_threads().max(1) - 1).min(units.saturating_sub(1))
}

/// `f` of every unit, in unit order (see `share`).
fn ordered<R: Send, E: Send>(
    units: usize,
    helpers: usize,
    f: impl Fn(usize) -> Result<R, E> + Sync,
) -> Result<Vec<R>, E> {
    let mut parts = share(
        units,
        helpers,
        Vec::new,
        |mut acc: Vec<(usize, R)>, i| {
            acc.push((i, f(i)?));
            Ok(acc)
        },
        |mut a, mut b| {
            a.append(&mut b);
            a
        },
    )?;
    parts.sort_unstable_by_key(|p| p.0);
    Ok(parts.into_iter().map(|p| p.1).collect())
}

/// The work sharing itself: units `0..units` taken in order from a shared counter by the
/// calling thread and up to `helpers` pool threads; each folds its units with `step` from
/// `init`, and the partial results are combined with `merge`. The error of the lowest
/// failing unit wins; a helper's panic resumes on the caller.
fn share<A, E>(
    units: usize,
    helpers: usize,
    init: impl Fn() -> A + Sync,
    step: impl Fn(A, usize) -> Result<A, E> + Sync,
    merge: impl Fn(A, A) -> A,
) -> Result<A, E>
where
    A: Send,
    E: Send,
{
    if helpers == 0 {
        return (0..units).try_fold(init(), step);
    }
    let job = Job {
        units,
        next: AtomicUsize::new(0),
        stop: AtomicBool::new(false),
        init: &init,
        step: &step,
        parts: Mutex::new(Vec::with_capacity(helpers)),
    };
    let mut parts = {
        let _helpers = Helpers::start(&job, helpers);
        let mine = job.run();
        drop(_helpers); // every helper has finished or will never touch `job`
        let mut parts = std::mem::take(&mut *lock(&job.parts));
        parts.push(Ok(mine));
        parts
    };
    // A helper's panic resumes here, on the caller (where the binding catches it).
    if let Some(pos) = parts.iter().position(|p| p.is_err()) {
        if let Err(payload) = parts.swap_remove(pos) {
            panic::resume_unwind(payload);
        }
    }
    let parts = parts.into_iter().filter_map(Result::ok);
    let mut first_err: Option<(usize, E)> = None;
    let mut total: Option<A> = None;
    for part in parts {
        match part {
            Part::Done(Some(a)) => {
                total = Some(match total.take() {
                    Some(t) => merge(t, a),
                    None => a,
                })
            }
            Part::Done(None) => {}
            Part::Failed(i, e) => {
                if first_err.as_ref().is_none_or(|(j, _)| i < *j) {
                    first_err = Some((i, e));
                }
            }
        }
    }
    match first_err {
        Some((_, e)) => Err(e),
        None => Ok(total.unwrap_or_else(init)),
    }
}

/// What one thread folded: its partial result (`None`: it took no chunk), or the first
/// chunk that failed and why.
enum Part<A, E> {
    Done(Option<A>),
    Failed(usize, E),
}

type Panic = Box<dyn Any + Send + 'static>;

/// The shared state of one pass; lives on the caller's stack.
struct Job<'a, A, E, I, S> {
    units: usize,
    /// Index of the next unit to take.
    next: AtomicUsize,
    /// Set when a unit failed: no new unit is started.
    stop: AtomicBool,
    init: &'a I,
    step: &'a S,
    /// The helpers' parts (or panics).
    parts: Mutex<Vec<Result<Part<A, E>, Panic>>>,
}

impl<A, E, I, S> Job<'_, A, E, I, S>
where
    I: Fn() -> A,
    S: Fn(A, usize) -> Result<A, E>,
{
    fn run(&self) -> Part<A, E> {
        let mut acc: Option<A> = None;
        while !self.stop.load(Ordering::Relaxed) {
            let i = self.next.fetch_add(1, Ordering::Relaxed);
            if i >= self.units {
                break;
            }
            match (self.step)(acc.take().unwrap_or_else(self.init), i) {
                Ok(a) => acc = Some(a),
                Err(e) => {
                    self.stop.store(true, Ordering::Relaxed);
                    return Part::Failed(i, e);
                }
            }
        }
        Part::Done(acc)
    }
}

/// The helper's entry point: run the job behind `p` and keep its part (or panic) in the job.
///
/// # Safety
/// `p` points to a live `Job<A, E, I, S>` (the `Helpers` protocol guarantees it while the
/// helper's slot is `Running`).
unsafe fn help<A, E, I, S>(p: *const ())
where
    I: Fn() -> A,
    S: Fn(A, usize) -> Result<A, E>,
{
    // SAFETY: the caller's guarantee
    let job = unsafe { &*p.cast::<Job<'_, A, E, I, S>>() };
    let part = panic::catch_unwind(AssertUnwindSafe(|| job.run()));
    lock(&job.parts).push(part);
}

#[derive(Clone, Copy, PartialEq)]
enum State {
    Pending,
    Running,
    Closed,
    Done,
}

struct Slot {
    state: Mutex<State>,
    done: Condvar,
}

/// A raw pointer sent to a helper; only dereferenced under the `Helpers` protocol.
struct JobPtr(*const ());
// SAFETY: the pointee (`Job`) is `Sync` for the types `share` accepts (atomics, a
// mutex of `Send` parts, `Sync` closures); the pointer itself is only an address.
unsafe impl Send for JobPtr {}

/// Helpers queued on the rayon pool for one job. Dropping it (also when unwinding) cancels
/// the helpers that have not started and waits for the ones running.
struct Helpers(Vec<Arc<Slot>>);

impl Helpers {
    fn start<A, E, I, S>(job: &Job<'_, A, E, I, S>, count: usize) -> Helpers
    where
        A: Send,
        E: Send,
        I: Fn() -> A + Sync,
        S: Fn(A, usize) -> Result<A, E> + Sync,
    {
        let entry: unsafe fn(*const ()) = help::<A, E, I, S>;
        let slots = (0..count)
            .map(|_| {
                let slot = Arc::new(Slot { state: Mutex::new(State::Pending), done: Condvar::new() });
                let (mine, ptr) = (Arc::clone(&slot), JobPtr((job as *const Job<'_, A, E, I, S>).cast()));
                rayon::spawn(move || {
                    let ptr = ptr; // the whole wrapper moves into the closure, not its field
                    {
                        let mut st = lock(&mine.state);
                        if *st != State::Pending {
                            return;
                        }
                        *st = State::Running;
                    }
                    // SAFETY: the slot is Running, so the caller waits (in `Helpers::drop`)
                    // until it is Done before `job` goes out of scope.
                    unsafe { entry(ptr.0) };
                    *lock(&mine.state) = State::Done;
                    mine.done.notify_all();
                });
                slot
            })
            .collect();
        Helpers(slots)
    }
}

impl Drop for Helpers {
    fn drop(&mut self) {
        for slot in &self.0 {
            let mut st = lock(&slot.state);
            if *st == State::Pending {
                *st = State::Closed;
                continue;
            }
            while *st != State::Done {
                st = slot.done.wait(st).unwrap_or_else(|p| p.into_inner());
            }
        }
    }
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// a + (a + 1) + ... + (b − 1)
    fn range_sum(a: usize, b: usize) -> u64 {
        (a + b).saturating_sub(1) as u64 * (b - a) as u64 / 2
    }

    fn sum_of(n: usize) -> Result<u64, usize> {
        fold_chunks(n, 1e6, || 0u64, |acc, (a, b)| Ok(acc + range_sum(a, b)), |a, b| a + b)
    }

    /// Rounds of the concurrent tests: fewer under Miri, which interprets every step of the
    /// protocol (and checks it for data races and use after free).
    const ROUNDS: u64 = if cfg!(miri) { 2 } else { 20 };

    #[test]
    fn every_chunk_is_counted_once() {
        for n in [0, 1, CHUNK - 1, CHUNK, CHUNK + 1, 5 * CHUNK + 7, 40 * CHUNK] {
            let n64 = n as u64;
            assert_eq!(sum_of(n), Ok(n64 * n64.saturating_sub(1) / 2), "n = {n}");
        }
    }

    #[test]
    fn the_lowest_failing_chunk_is_reported() {
        for _ in 0..ROUNDS * 2 + 10 {
            let got: Result<u64, usize> = fold_chunks(
                40 * CHUNK,
                1e6,
                || 0,
                |acc, (a, _)| if a / CHUNK >= 7 && (a / CHUNK) % 3 == 1 { Err(a / CHUNK) } else { Ok(acc + 1) },
                |a, b| a + b,
            );
            assert_eq!(got, Err(7));
        }
    }

    #[test]
    fn a_panicking_chunk_panics_on_the_caller() {
        for bad in [0, 3, 39] {
            let got = panic::catch_unwind(|| {
                fold_chunks::<u64, ()>(
                    40 * CHUNK,
                    1e6,
                    || 0,
                    |acc, (a, _)| {
                        std::thread::sleep(std::time::Duration::from_micros(50));
                        assert!(a / CHUNK != bad, "chunk {bad}");
                        Ok(acc + 1)
                    },
                    |a, b| a + b,
                )
            });
            assert!(got.is_err(), "chunk {bad}");
        }
    }

    #[test]
    fn many_callers_at_once_share_one_pool() {
        // Eight threads fold at once on the same pool, with uneven chunk times: helpers start
        // late, early or never; every result must still count each chunk once.
        let pool = rayon::ThreadPoolBuilder::new().num_threads(3).build().unwrap();
        std::thread::scope(|s| {
            for t in 0..if cfg!(miri) { 3 } else { 8u64 } {
                let pool = &pool;
                s.spawn(move || {
                    for round in 0..ROUNDS {
                        let n = (3 + (t + round) % 9) as usize * CHUNK + (round as usize * 37);
                        let got: Result<u64, ()> = pool.install(|| {
                            fold_chunks(
                                n,
                                1e6,
                                || 0,
                                |acc, (a, b)| {
                                    if (a / CHUNK + t as usize) % 4 == 0 {
                                        std::thread::sleep(std::time::Duration::from_micros(30));
                                    }
                                    Ok(acc + range_sum(a, b))
                                },
                                |a, b| a + b,
                            )
                        });
                        let n64 = n as u64;
                        assert_eq!(got, Ok(n64 * (n64 - 1) / 2), "thread {t} round {round}");
                    }
                });
            }
        });
    }

    #[test]
    fn a_busy_pool_does_not_hold_the_caller() {
        // The caller runs on one thread of a 3-thread pool whose two others are blocked: its
        // helpers never start, it finishes alone and cancels them (a wait would hang).
        let pool = rayon::ThreadPoolBuilder::new().num_threads(3).build().unwrap();
        let gate = Arc::new((Mutex::new(false), Condvar::new()));
        let blocked = Arc::new(AtomicUsize::new(0));
        for _ in 0..2 {
            let (g, b) = (Arc::clone(&gate), Arc::clone(&blocked));
            pool.spawn(move || {
                b.fetch_add(1, Ordering::SeqCst);
                let mut open = g.0.lock().unwrap();
                while !*open {
                    open = g.1.wait(open).unwrap();
                }
            });
        }
        while blocked.load(Ordering::SeqCst) < 2 {
            std::thread::yield_now();
        }
        let got = pool.install(|| {
            assert_eq!(rayon::current_num_threads(), 3);
            sum_of(8 * CHUNK)
        });
        let n = 8 * CHUNK as u64;
        assert_eq!(got, Ok(n * (n - 1) / 2));
        *gate.0.lock().unwrap() = true;
        gate.1.notify_all();
    }
}
