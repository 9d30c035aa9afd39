//! Tables a thread reuses from one pass to the next: the dense joint counts and the ≤ 16-bit
//! lookup tables. A small frame pair (160 × 120) counts into a 256² table and bins through two
//! 64 Ki-entry lookup tables: allocating them afresh costs more page faults and zeroing than
//! the counting, and a sequence scores thousands of such pairs on each thread. A lookup table
//! is kept with a bound its every entry is below, so a pass can write only the levels it will
//! look up and still never index past its dense table.

use std::cell::RefCell;

use crate::hist::DENSE_MAX_BINS;

/// Spare tables of each kind a thread keeps.
const KEPT: usize = 2;

/// Largest table kept, in entries: the dense joint table of [`DENSE_MAX_BINS`] bins (1 MiB
/// of u32) and a 16-bit lookup table fit.
const MAX_KEPT_LEN: usize = DENSE_MAX_BINS * DENSE_MAX_BINS;

thread_local! {
    static ZEROED_COUNTS: RefCell<Vec<Vec<u32>>> = const { RefCell::new(Vec::new()) };
    /// each with a bound its every entry is below
    static SPARE_LUTS: RefCell<Vec<(Vec<u16>, usize)>> = const { RefCell::new(Vec::new()) };
}

/// Take a kept table that `fits`, if this thread has one.
fn take<E>(kept: &RefCell<Vec<E>>, fits: impl Fn(&E) -> bool) -> Option<E> {
    let mut kept = kept.borrow_mut();
    let at = kept.iter().position(fits)?;
    Some(kept.swap_remove(at))
}

/// Keep a table of `len` entries for a later pass on this thread (dropped when too large or
/// enough are kept).
fn keep<E>(kept: &RefCell<Vec<E>>, table: E, len: usize) {
    let mut kept = kept.borrow_mut();
    if len > 0 && len <= MAX_KEPT_LEN && kept.len() < KEPT {
        kept.push(table);
    }
}

/// `len` zero counts.
pub(super) fn zeroed_counts(len: usize) -> Vec<u32> {
    ZEROED_COUNTS.try_with(|k| take(k, |t| t.len() == len)).ok().flatten().unwrap_or_else(|| vec![0; len])
}

/// Give back a table of counts (zeroed here, so [`zeroed_counts`] hands it out as it is).
pub(super) fn give_back_counts(mut table: Vec<u32>) {
    if table.is_empty() || table.len() > MAX_KEPT_LEN {
        return;
    }
    table.fill(0);
    give_back_zeroed_counts(table);
}

/// Give back a table of counts that is already zeroed.
pub(super) fn give_back_zeroed_counts(table: Vec<u32>) {
    debug_assert!(table.iter().all(|&c| c == 0));
    let len = table.len();
    let _ = ZEROED_COUNTS.try_with(|k| keep(k, table, len)); // a thread being torn down keeps nothing
}

/// A lookup table of `len` entries, each below `bound`: a kept one whose entries are all
/// below it, else a new one of zeros. The caller writes the entries it reads.
pub(super) fn lut_below(len: usize, bound: usize) -> Vec<u16> {
    let kept = SPARE_LUTS.try_with(|k| take(k, |(t, below)| t.len() == len && *below <= bound));
    kept.ok().flatten().map_or_else(|| vec![0; len], |(table, _)| table)
}

/// Give back a lookup table whose every entry is below `bound`.
pub(super) fn give_back_lut(table: Vec<u16>, bound: usize) {
    let len = table.len();
    let _ = SPARE_LUTS.try_with(|k| keep(k, (table, bound), len));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_come_back_zeroed_and_only_at_their_length() {
        let mut table = zeroed_counts(16);
        assert!(table.iter().all(|&c| c == 0));
        table[3] = 7;
        let at = table.as_ptr();
        give_back_counts(table);
        let again = zeroed_counts(16);
        assert_eq!(again.as_ptr(), at, "the kept table is reused");
        assert!(again.iter().all(|&c| c == 0));
        assert_eq!(zeroed_counts(17).len(), 17);
        give_back_counts(again);
        give_back_counts(vec![1; MAX_KEPT_LEN + 1]); // too large: not kept
        assert_eq!(ZEROED_COUNTS.with(|k| k.borrow().iter().map(Vec::len).collect::<Vec<_>>()), vec![16]);
    }
}
