//! The accumulator one worker folds its chunks into ([`Acc`]), and what a failing chunk
//! reports ([`Bad`]).

use super::binning::HistPlan;
use super::float::ChunkFloat;
use super::scratch;
use crate::hist;
use crate::stats::IntSums;

/// Per-worker accumulator.
pub(crate) struct Acc {
    pub(super) n: u64,
    pub(super) int: IntSums,
    pub(super) dense: Vec<u32>, // per-worker counts; frames are < 2^32 pixels (checked)
    dense_zeroed: bool,         // `dense` was taken (and zeroed) by `take_joint`
    pub(super) keys: Vec<u64>,
    pub(super) runs: Vec<(u64, u64)>,
    pub(super) max_abs: f64, // float frames: largest magnitude seen (underflow check)
    /// float frames: each chunk's sums, keyed by its first pixel (combined in chunk order)
    pub(super) floats: Vec<(usize, ChunkFloat)>,
}

impl Acc {
    pub(super) fn new(plan: Option<&HistPlan>) -> Acc {
        let dense = match plan.and_then(|p| p.dense_bins) {
            Some(b) => scratch::zeroed_counts(b * b),
            None => Vec::new(),
        };
        Acc {
            n: 0,
            int: IntSums::default(),
            dense,
            dense_zeroed: false,
            keys: Vec::new(),
            runs: Vec::new(),
            max_abs: 0.0,
            floats: Vec::new(),
        }
    }

    #[inline(always)]
    pub(super) fn count(&mut self, dense_bins: usize, br: usize, bs: usize) {
        if dense_bins > 0 {
            self.dense[br * dense_bins + bs] += 1;
        } else {
            self.keys.push(hist::pack(br as u64, bs as u64));
        }
    }

    /// The dense counts as a joint histogram, leaving the table zeroed for the next pass.
    pub(super) fn take_joint(&mut self, bins: usize, offset: u64) -> hist::Joint {
        self.dense_zeroed = true;
        hist::Joint::take_counts(bins, offset, &mut self.dense)
    }

    pub(super) fn flush_keys(&mut self) {
        if !self.keys.is_empty() {
            let runs = hist::runs_from_keys(&mut self.keys);
            self.runs = hist::merge_runs(&self.runs, &runs);
            self.keys.clear();
        }
    }

    pub(super) fn merge(mut self, mut other: Acc, is_int: bool) -> Acc {
        self.max_abs = self.max_abs.max(other.max_abs);
        if is_int {
            let (a, b) = (&mut self.int, &other.int);
            a.sr += b.sr;
            a.ss += b.ss;
            a.srr += b.srr;
            a.sss += b.sss;
            a.srs += b.srs;
            a.sse += b.sse;
        } else {
            self.floats.append(&mut other.floats);
        }
        self.n += other.n;
        for (a, b) in self.dense.iter_mut().zip(&other.dense) {
            *a += b;
        }
        self.flush_keys();
        other.flush_keys();
        if !other.runs.is_empty() {
            self.runs = hist::merge_runs(&self.runs, &other.runs);
        }
        self
    }
}

impl Drop for Acc {
    fn drop(&mut self) {
        let table = std::mem::take(&mut self.dense);
        if self.dense_zeroed {
            scratch::give_back_zeroed_counts(table);
        } else {
            scratch::give_back_counts(table);
        }
    }
}

/// A failure found inside a chunk: the flat index and what was wrong.
pub(crate) enum Bad {
    Range { frame: &'static str, value: i64, index: usize },
    NonFinite { index: usize },
}
