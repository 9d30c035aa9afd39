//! The fused pass: one sweep over two frames computes exactly what the caller needs
//! (SSE, moments, joint histogram) into a [`PairStats`](crate::stats::PairStats). Frames are
//! split into cache-sized chunks, shared between the calling thread and idle pool threads
//! (`parallel`) and merged. Integer frames are summed exactly (u64/i64 per block,
//! u128/i128 totals, `int`); float frames are promoted to f64 and summed about each frame's
//! mean from a compensated scan (`float`).
//!
//! * `sample`: the pixel types ([`Sample`]); `request`: what to compute ([`Request`]);
//! * `binning`: the histogram plan (bin edges, lookup tables, table layout); `range`: the
//!   data range it may need;
//! * `acc`: the per-worker accumulator (its table, and the lookup tables, reused per thread:
//!   `scratch`); `dispatch`: each chunk through the AVX2 or portable
//!   copy of the loops, monomorphised per requested output;
//! * `driver`: [`pair_stats`] — plan, fold the chunks, finish.

mod acc;
mod binning;
mod dispatch;
mod driver;
mod float;
mod int;
mod parallel;
mod range;
mod request;
mod sample;
mod scratch;

#[cfg(test)]
pub(crate) use dispatch::tests::both_paths;
pub(crate) use dispatch::use_avx2;
pub use driver::pair_stats;
#[cfg(target_arch = "x86_64")]
pub(crate) use int::avx2 as int_avx2;
pub(crate) use parallel::{fold_chunks, map_chunks};
pub use parallel::{map_units, pool_busy, with_pool_busy};
pub(crate) use range::min_max;
pub use range::scored_range;
pub use request::{HistRequest, Request};
pub use sample::{all_finite, Sample};

/// Pixels per work unit: two chunks of u16/f32 fit in L2 with the histogram.
pub(crate) const CHUNK: usize = 1 << 16;
