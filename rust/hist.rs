//! Joint grey-level histograms (shared edges, or each frame's own), and their Shannon entropies
//! (paper eqs. 7–8). One representation serves every dtype and binning mode:
//! a dense `bins × bins` table when that is small and a quarter full, otherwise a sorted run
//! list of packed `(row_bin << 32) | col_bin` keys. Marginals always come from the joint.

use crate::error::{Error, Result};

/// How the grey levels were mapped to bins: needed to decide whether two histograms
/// can be merged (same edges) and to report what was measured.
#[derive(Clone, Debug, PartialEq)]
pub enum HistSpec {
    /// `bins` uniform bins starting at `lo`, each `width` wide (integers for integer frames).
    Binned { bins: usize, lo: f64, width: f64 },
    /// `bins` uniform bins for each frame over its own range: `(lo, width)` of the real and
    /// of the simulated frame's bins.
    Each { bins: usize, real: (f64, f64), sim: (f64, f64) },
    /// Every grey level its own bin (integer frames only).
    Levels,
}

/// Joint counts of (real bin, simulated bin). Two joints are equal when they hold the same
/// counts, whichever form holds them.
#[derive(Clone, Debug)]
pub enum Joint {
    /// `counts[r * bins + s]`; `offset` is added to a bin index to make it a key in the
    /// sparse domain (non-zero only for `levels` stored densely).
    Dense { bins: usize, offset: u64, counts: Vec<u64> },
    /// Sorted `(key, count)` runs with `key = (r << 32) | s`, no zero counts.
    Sparse(Vec<(u64, u64)>),
}

/// Most uniform bins a histogram may have (exposed as `_core.MAX_HIST_BINS`; the Python
/// layer's one check of `bins` holds callers to it, `irfidelity.stats.bins_value`).
pub const MAX_BINS: usize = 1 << 20;

/// Largest `bins` stored densely: `bins²` u64 counters per worker must stay cache-sized.
pub const DENSE_MAX_BINS: usize = 512;

#[inline]
pub fn pack(r: u64, s: u64) -> u64 {
    (r << 32) | s
}

/// Entropies of a joint histogram, in bits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Entropies {
    pub h_real: f64,
    pub h_sim: f64,
    pub h_joint: f64,
}

/// Shannon entropy (bits) of a histogram given by its non-zero counts summing to `n`.
///
/// Uses `H = Σ p·log2(N/c)` with `log2(N/c) = ln_1p((N−c)/c)/ln 2`, all terms ≥ 0 and
/// `N − c` exact, so a nearly constant frame (H ≈ 1e-6 bit) keeps full relative precision —
/// `log2 N − Σc·log2 c / N` would cancel there.
pub fn entropy<I: IntoIterator<Item = u64>>(counts: I, n: u64) -> f64 {
    if n == 0 {
        return 0.0;
    }
    let nf = n as f64;
    let term = |c: u64| (c as f64 / nf) * (((n - c) as f64) / c as f64).ln_1p() / std::f64::consts::LN_2;
    // A joint histogram holds thousands of bins with the same small count: each count's
    // term (a log) is computed once per call. Same values, same order of additions.
    let mut memo = [f64::NAN; MEMO];
    let mut h = 0.0f64;
    let mut comp = 0.0f64; // Neumaier compensation: many small terms
    for c in counts {
        if c == 0 {
            continue;
        }
        let t = match memo.get_mut(c as usize) {
            Some(m) if !m.is_nan() => *m,
            Some(m) => {
                *m = term(c);
                *m
            }
            None => term(c),
        };
        let s = h + t;
        comp += if h.abs() >= t.abs() { (h - s) + t } else { (t - s) + h };
        h = s;
    }
    h + comp
}

/// Counts below this have their entropy term memoised (`entropy`).
const MEMO: usize = 512;

/// The column totals of sparse runs in column order (zeros where a column in between is
/// empty, which [`entropy`] skips): counted into a table when the columns span few more
/// than there are runs, else by sorting.
fn column_counts(runs: &[(u64, u64)]) -> Vec<u64> {
    let column = |k: u64| k & 0xFFFF_FFFF;
    let Some((lo, hi)) = runs
        .iter()
        .map(|&(k, _)| column(k))
        .fold(None, |span: Option<(u64, u64)>, s| Some(span.map_or((s, s), |(lo, hi)| (lo.min(s), hi.max(s)))))
    else {
        return Vec::new();
    };
    let span = (hi - lo) as usize + 1;
    if span <= 2 * runs.len().max(512) {
        let mut counts = vec![0u64; span];
        for &(k, c) in runs {
            counts[(column(k) - lo) as usize] += c;
        }
        return counts;
    }
    let mut cols: Vec<(u64, u64)> = runs.iter().map(|&(k, c)| (column(k), c)).collect();
    cols.sort_unstable_by_key(|&(s, _)| s);
    let mut counts: Vec<u64> = Vec::new();
    let mut last = u64::MAX;
    for (s, c) in cols {
        match counts.last_mut() {
            Some(total) if s == last => *total += c,
            _ => {
                counts.push(c);
                last = s;
            }
        }
    }
    counts
}

/// Sort `keys`, and append their run-length counts to a new sorted run list.
pub fn runs_from_keys(keys: &mut [u64]) -> Vec<(u64, u64)> {
    keys.sort_unstable();
    let mut runs: Vec<(u64, u64)> = Vec::new();
    for &k in keys.iter() {
        match runs.last_mut() {
            Some((lk, c)) if *lk == k => *c += 1,
            _ => runs.push((k, 1)),
        }
    }
    runs
}

/// Merge two sorted run lists, adding the counts of equal keys.
pub fn merge_runs(a: &[(u64, u64)], b: &[(u64, u64)]) -> Vec<(u64, u64)> {
    let mut out = Vec::with_capacity(a.len().max(b.len()));
    let (mut i, mut j) = (0, 0);
    while i < a.len() && j < b.len() {
        let (ka, ca) = a[i];
        let (kb, cb) = b[j];
        if ka < kb {
            out.push((ka, ca));
            i += 1;
        } else if kb < ka {
            out.push((kb, cb));
            j += 1;
        } else {
            out.push((ka, ca + cb));
            i += 1;
            j += 1;
        }
    }
    out.extend_from_slice(&a[i..]);
    out.extend_from_slice(&b[j..]);
    out
}

/// The occupied cells of one row of a pass's table (key row `row_key`, columns from
/// `offset`) appended to `runs` in column order, and zeroed.
fn take_row(line: &mut [u32], row_key: u64, offset: u64, runs: &mut Vec<(u64, u64)>) {
    #[cfg(target_arch = "x86_64")]
    if crate::kernel::use_avx2() {
        // SAFETY: `use_avx2` is true only when the CPU reports AVX2.
        return unsafe { take_row_avx2(line, row_key, offset, runs) };
    }
    take_cells_from(line, 0, row_key, offset, runs);
}

/// [`take_row`] from column `first` on, testing 16 cells at a time (most of a row is empty).
fn take_cells_from(line: &mut [u32], first: usize, row_key: u64, offset: u64, runs: &mut Vec<(u64, u64)>) {
    const BLOCK: usize = 16;
    for (block, cells) in line[first..].chunks_mut(BLOCK).enumerate() {
        if cells.iter().fold(0, |any, &c| any | c) == 0 {
            continue;
        }
        for (k, cell) in cells.iter_mut().enumerate() {
            if *cell > 0 {
                runs.push((pack(row_key, (first + block * BLOCK + k) as u64 + offset), *cell as u64));
                *cell = 0;
            }
        }
    }
}

/// [`take_row`] 32 cells per step: one test skips four empty groups of eight (most of a
/// row); in a block with counts, one compare per group finds its occupied cells, which are
/// visited bit by bit. The rest of the row (fewer than 32 cells) portably.
///
/// # Safety
/// The CPU supports AVX2 (every load and store stays within `line`).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn take_row_avx2(line: &mut [u32], row_key: u64, offset: u64, runs: &mut Vec<(u64, u64)>) {
    use std::arch::x86_64::*;
    const GROUP: usize = 8;
    const BLOCK: usize = 4 * GROUP;
    let zero = _mm256_setzero_si256();
    let blocks = line.len() / BLOCK;
    for (b, block) in line[..blocks * BLOCK].chunks_exact_mut(BLOCK).enumerate() {
        let at = block.as_mut_ptr() as *mut __m256i;
        // SAFETY: `at` points at the block's 32 u32 cells, four vectors (unaligned loads)
        let groups = unsafe {
            [
                _mm256_loadu_si256(at),
                _mm256_loadu_si256(at.add(1)),
                _mm256_loadu_si256(at.add(2)),
                _mm256_loadu_si256(at.add(3)),
            ]
        };
        let any = _mm256_or_si256(_mm256_or_si256(groups[0], groups[1]), _mm256_or_si256(groups[2], groups[3]));
        if _mm256_testz_si256(any, any) != 0 {
            continue;
        }
        for (g, &cells) in groups.iter().enumerate() {
            let empty = _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpeq_epi32(cells, zero))) as u32;
            let mut occupied = !empty & 0xff;
            if occupied == 0 {
                continue;
            }
            let mut values = [0u32; GROUP];
            // SAFETY: both point at eight u32 cells (the group's within the block)
            unsafe {
                _mm256_storeu_si256(values.as_mut_ptr() as *mut __m256i, cells);
                _mm256_storeu_si256(at.add(g), zero);
            }
            while occupied != 0 {
                let k = occupied.trailing_zeros() as usize;
                runs.push((pack(row_key, (b * BLOCK + g * GROUP + k) as u64 + offset), values[k] as u64));
                occupied &= occupied - 1;
            }
        }
    }
    take_cells_from(line, blocks * BLOCK, row_key, offset, runs);
}

impl PartialEq for Joint {
    fn eq(&self, other: &Joint) -> bool {
        match (self, other) {
            (Joint::Dense { bins: b1, offset: o1, counts: c1 }, Joint::Dense { bins: b2, offset: o2, counts: c2 })
                if b1 == b2 && o1 == o2 =>
            {
                c1 == c2
            }
            (Joint::Sparse(a), Joint::Sparse(b)) => a == b,
            _ => self.to_runs() == other.to_runs(),
        }
    }
}

impl Joint {
    pub fn dense(bins: usize, offset: u64) -> Joint {
        Joint::Dense { bins, offset, counts: vec![0; bins * bins] }
    }

    /// A pass's `bins × bins` table of counts (row-major, `offset` as in [`Joint::Dense`]),
    /// kept dense when at least a quarter of its cells are occupied, else as runs of the
    /// occupied cells: a small frame fills few cells of a 256² table, and its runs take less
    /// memory and give its entropies without a walk over every cell. The table is left zeroed
    /// for the next pass, writing only the cells that held a count.
    pub fn take_counts(bins: usize, offset: u64, counts: &mut [u32]) -> Joint {
        let row_len = bins.max(1);
        let mut runs = Vec::new();
        for row in 0..counts.len() / row_len {
            take_row(&mut counts[row * row_len..(row + 1) * row_len], row as u64 + offset, offset, &mut runs);
            if runs.len() * 4 >= counts.len() {
                return Joint::dense_from(bins, offset, &runs, counts);
            }
        }
        Joint::Sparse(runs) // row-major order is key order
    }

    /// The dense joint of a table whose first rows were taken into `runs` (the rest still in
    /// `counts`, zeroed here).
    fn dense_from(bins: usize, offset: u64, runs: &[(u64, u64)], counts: &mut [u32]) -> Joint {
        let mut dense: Vec<u64> = counts.iter().map(|&c| c as u64).collect();
        for &(key, c) in runs {
            let (r, s) = ((key >> 32) - offset, (key & 0xffff_ffff) - offset);
            dense[r as usize * bins + s as usize] = c;
        }
        counts.fill(0);
        Joint::Dense { bins, offset, counts: dense }
    }

    /// Total count.
    pub fn total(&self) -> u64 {
        match self {
            Joint::Dense { counts, .. } => counts.iter().sum(),
            Joint::Sparse(runs) => runs.iter().map(|&(_, c)| c).sum(),
        }
    }

    /// The same counts as a sparse run list (keys in the absolute level/bin domain).
    pub fn to_runs(&self) -> Vec<(u64, u64)> {
        match self {
            Joint::Sparse(runs) => runs.clone(),
            Joint::Dense { bins, offset, counts } => {
                let mut runs = Vec::new();
                for (idx, &c) in counts.iter().enumerate() {
                    if c > 0 {
                        let (r, s) = ((idx / bins) as u64, (idx % bins) as u64);
                        runs.push((pack(r + offset, s + offset), c));
                    }
                }
                runs // row-major order of (r, s) is already key order
            }
        }
    }

    /// Add `other`'s counts. Both must share the same edges (checked by the caller via
    /// [`HistSpec`]); dense tables with the same layout add element-wise, anything else
    /// goes through the sparse domain.
    pub fn merge(&self, other: &Joint) -> Joint {
        match (self, other) {
            (Joint::Dense { bins: b1, offset: o1, counts: c1 }, Joint::Dense { bins: b2, offset: o2, counts: c2 })
                if b1 == b2 && o1 == o2 =>
            {
                let counts = c1.iter().zip(c2).map(|(a, b)| a + b).collect();
                Joint::Dense { bins: *b1, offset: *o1, counts }
            }
            _ => Joint::Sparse(merge_runs(&self.to_runs(), &other.to_runs())),
        }
    }

    /// The smallest and largest occupied keys of each axis, `((real_lo, real_hi), (sim_lo,
    /// sim_hi))`, or `None` when nothing was counted.
    pub fn occupied(&self) -> Option<((u64, u64), (u64, u64))> {
        let runs = self.to_runs();
        let (first, last) = (runs.first()?.0, runs.last()?.0);
        let (sim_lo, sim_hi) =
            runs.iter().fold((u64::MAX, 0), |(lo, hi), &(k, _)| (lo.min(k & 0xFFFF_FFFF), hi.max(k & 0xFFFF_FFFF)));
        Some(((first >> 32, last >> 32), (sim_lo, sim_hi)))
    }

    /// The counts as a dense row-major table: real keys `real_first..real_first + rows` down,
    /// simulated keys `sim_first..sim_first + cols` across. Counts of keys outside the table
    /// are not included (callers pass ranges that cover [`Joint::occupied`]).
    pub fn table(&self, real_first: u64, rows: usize, sim_first: u64, cols: usize) -> Vec<u64> {
        let mut out = vec![0u64; rows * cols];
        let mut put = |r: u64, s: u64, c: u64| {
            let (i, j) = (r.wrapping_sub(real_first) as usize, s.wrapping_sub(sim_first) as usize);
            if i < rows && j < cols {
                out[i * cols + j] += c;
            }
        };
        match self {
            Joint::Dense { bins, offset, counts } => {
                for (idx, &c) in counts.iter().enumerate().filter(|(_, &c)| c > 0) {
                    put((idx / bins) as u64 + offset, (idx % bins) as u64 + offset, c);
                }
            }
            Joint::Sparse(runs) => {
                for &(k, c) in runs {
                    put(k >> 32, k & 0xFFFF_FFFF, c);
                }
            }
        }
        out
    }

    /// Marginal and joint entropies (paper eqs. 7 and 8).
    pub fn entropies(&self) -> Entropies {
        let n = self.total();
        match self {
            Joint::Dense { bins, counts, .. } => {
                let b = *bins;
                // each row summed on its own, the columns by adding rows: two loops that vectorise
                let mut col = vec![0u64; b];
                let row: Vec<u64> = counts
                    .chunks_exact(b.max(1))
                    .map(|line| {
                        col.iter_mut().zip(line).for_each(|(total, &c)| *total += c);
                        line.iter().sum()
                    })
                    .collect();
                Entropies {
                    h_real: entropy(row, n),
                    h_sim: entropy(col, n),
                    h_joint: entropy(counts.iter().copied(), n),
                }
            }
            Joint::Sparse(runs) => {
                // Rows are contiguous in key order; columns need one sort.
                let mut row_counts = Vec::new();
                let mut cur: Option<(u64, u64)> = None;
                for &(k, c) in runs {
                    let r = k >> 32;
                    match cur.as_mut() {
                        Some((cr, cc)) if *cr == r => *cc += c,
                        _ => {
                            if let Some((_, cc)) = cur {
                                row_counts.push(cc);
                            }
                            cur = Some((r, c));
                        }
                    }
                }
                if let Some((_, cc)) = cur {
                    row_counts.push(cc);
                }
                Entropies {
                    h_real: entropy(row_counts, n),
                    h_sim: entropy(column_counts(runs), n),
                    h_joint: entropy(runs.iter().map(|&(_, c)| c), n),
                }
            }
        }
    }
}

/// A joint histogram laid out as a dense row-major table of `rows × cols` counts: real bins
/// (or levels) down, simulated across. Binned histograms cover every bin (`bins × bins`,
/// first key 0); `levels` histograms the occupied span of each axis, `real_first` and
/// `sim_first` being the level keys (value − the dtype's minimum) of the first row and column.
#[derive(Clone, Debug, PartialEq)]
pub struct JointTable {
    pub real_first: u64,
    pub sim_first: u64,
    pub rows: usize,
    pub cols: usize,
    pub counts: Vec<u64>,
}

impl JointTable {
    /// The table of `joint` (binned as `spec`), refused when it would hold more than
    /// `max_cells` counts.
    pub fn of(spec: &HistSpec, joint: &Joint, max_cells: usize) -> Result<JointTable> {
        let ((real_first, rows), (sim_first, cols)) = match spec {
            HistSpec::Binned { bins, .. } | HistSpec::Each { bins, .. } => ((0, *bins), (0, *bins)),
            HistSpec::Levels => match joint.occupied() {
                Some(((rl, rh), (sl, sh))) => ((rl, (rh - rl + 1) as usize), (sl, (sh - sl + 1) as usize)),
                None => ((0, 0), (0, 0)),
            },
        };
        let cells = rows.checked_mul(cols).filter(|&c| c <= max_cells).ok_or_else(|| {
            Error::Value(format!(
                "the joint histogram would be a {rows} × {cols} table, more than max_cells = {max_cells} counts; \
                 compute the statistics with fewer bins (e.g. bins=256) or raise max_cells"
            ))
        })?;
        let counts = joint.table(real_first, rows, sim_first, cols);
        debug_assert_eq!(counts.len(), cells);
        Ok(JointTable { real_first, sim_first, rows, cols, counts })
    }
}

/// Check that two histogram specs share edges, so their counts may be added.
pub fn check_mergeable(a: &HistSpec, b: &HistSpec) -> Result<()> {
    if a == b {
        Ok(())
    } else {
        Err(Error::Value(format!(
            "cannot merge histograms with different edges ({} vs {}); \
             use hist_range='full' or an explicit (lo, hi), or bins='levels', to pool NMI",
            edges_text(a),
            edges_text(b)
        )))
    }
}

/// A spec's edges in words, for messages.
fn edges_text(spec: &HistSpec) -> String {
    match spec {
        HistSpec::Binned { bins, lo, width } => format!("{bins} bins of {width} from {lo}"),
        HistSpec::Each { bins, real, sim } => format!(
            "each frame's own {bins} bins (hist_range='each'): the real frame's of {} from {}, the simulated \
             frame's of {} from {}",
            real.1, real.0, sim.1, sim.0
        ),
        HistSpec::Levels => "one bin per grey level".into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernel::both_paths;

    #[test]
    fn entropy_of_uniform_and_constant() {
        assert!((entropy([1, 1, 1, 1], 4) - 2.0).abs() < 1e-15);
        assert_eq!(entropy([7], 7), 0.0);
        assert_eq!(entropy([], 0), 0.0);
        // one odd pixel in a million: H = p log2(1/p) + q log2(1/q), no cancellation
        let n = 1_000_000u64;
        let p = 1.0 / n as f64;
        let want = p * (n as f64).log2() - (1.0 - p) * (-p).ln_1p() / std::f64::consts::LN_2;
        let got = entropy([1, n - 1], n);
        assert!(((got - want) / want).abs() < 1e-13, "{got} vs {want}");
    }

    #[test]
    fn joint_table_layouts() {
        let binned = HistSpec::Binned { bins: 3, lo: 0.0, width: 1.0 };
        let joint = Joint::Sparse(vec![(pack(0, 2), 4), (pack(2, 1), 1)]);
        let t = JointTable::of(&binned, &joint, 100).unwrap();
        assert_eq!((t.rows, t.cols, t.counts.iter().sum::<u64>()), (3, 3, 5));
        assert_eq!(t.counts, [0, 0, 4, 0, 0, 0, 0, 1, 0]);
        // levels: the occupied span of each axis (real 100..=102, sim 7..=9)
        let joint = Joint::Sparse(vec![(pack(100, 9), 2), (pack(102, 7), 3)]);
        let t = JointTable::of(&HistSpec::Levels, &joint, 100).unwrap();
        assert_eq!((t.real_first, t.rows, t.sim_first, t.cols), (100, 3, 7, 3));
        assert_eq!(t.counts, [0, 0, 2, 0, 0, 0, 3, 0, 0]);
        assert!(JointTable::of(&HistSpec::Levels, &joint, 8).is_err());
        let huge = HistSpec::Binned { bins: 1 << 20, lo: 0.0, width: 1.0 };
        assert!(JointTable::of(&huge, &Joint::Sparse(vec![]), 1 << 24).is_err());
    }

    #[test]
    fn dense_and_sparse_agree_and_merge() {
        let mut d = Joint::dense(4, 0);
        let pairs = [(0u64, 0u64), (1, 1), (1, 2), (3, 3), (3, 3), (2, 0)];
        let mut keys = Vec::new();
        if let Joint::Dense { counts, .. } = &mut d {
            for &(r, s) in &pairs {
                counts[(r * 4 + s) as usize] += 1;
                keys.push(pack(r, s));
            }
        }
        let sp = Joint::Sparse(runs_from_keys(&mut keys));
        assert_eq!(d.to_runs(), sp.to_runs());
        let (e1, e2) = (d.entropies(), sp.entropies());
        assert!((e1.h_real - e2.h_real).abs() < 1e-15);
        assert!((e1.h_sim - e2.h_sim).abs() < 1e-15);
        assert!((e1.h_joint - e2.h_joint).abs() < 1e-15);
        assert_eq!(d.occupied(), Some(((0, 3), (0, 3))));
        assert_eq!(sp.occupied(), d.occupied());
        let table = d.table(0, 4, 0, 4);
        assert_eq!(table, sp.table(0, 4, 0, 4));
        assert_eq!(table, [1, 0, 0, 0, 0, 1, 1, 0, 1, 0, 0, 0, 0, 0, 0, 2]);
        assert_eq!(sp.table(1, 2, 1, 3), [1, 1, 0, 0, 0, 0]); // rows 1..3, cols 1..4
        assert_eq!(Joint::Sparse(vec![]).occupied(), None);
        let m = d.merge(&sp);
        assert_eq!(m.total(), 12);
        assert_eq!(m.merge(&Joint::Sparse(vec![])).total(), 12);
        assert_eq!(d, sp, "equal counts are equal joints, whichever form holds them");
        assert_ne!(d, Joint::Sparse(vec![(pack(0, 0), 1)]));
    }

    #[test]
    fn a_pass_table_is_kept_sparse_when_mostly_empty_with_the_same_entropies() {
        // a band about the diagonal (sparse), then every cell filled (dense); rows of one
        // block of 32 cells and of two, each with a tail
        for bins in [40usize, 75] {
            let mut state = 11u64;
            let mut next = || {
                state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                (state >> 33) as u32
            };
            let mut band = vec![0u32; bins * bins];
            for r in 0..bins {
                for s in r.saturating_sub(1)..(r + 2).min(bins) {
                    band[r * bins + s] = 1 + next() % 50;
                }
            }
            band[5 * bins + bins - 1] = 3; // a lone cell past a block of empty ones
            let full: Vec<u32> = (0..bins * bins).map(|_| 1 + next() % 50).collect();
            // full from its fourth row on: dense after some rows were taken as runs
            let mut late = band.clone();
            late[4 * bins..].iter_mut().for_each(|c| *c = 1 + next() % 50);
            for (counts, offset, sparse) in
                [(&band, 0u64, true), (&band, 7, true), (&full, 0, false), (&late, 3, false)]
            {
                let dense = Joint::Dense { bins, offset, counts: counts.iter().map(|&c| c as u64).collect() };
                let [kept, portable] = both_paths(|| {
                    let mut table = counts.clone();
                    let kept = Joint::take_counts(bins, offset, &mut table);
                    assert!(table.iter().all(|&c| c == 0), "the table is left zeroed");
                    kept
                });
                assert_eq!(kept, portable);
                assert_eq!(matches!(kept, Joint::Sparse(_)), sparse);
                assert_eq!(kept.to_runs(), dense.to_runs());
                assert_eq!(kept, dense);
                let (taken, counted) = (kept.entropies(), dense.entropies());
                if cfg!(miri) {
                    // Miri gives each logarithm a few ulps of random error (a libm's freedom):
                    // the same terms agree to rounding there, exactly everywhere else
                    let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * a.abs().max(b.abs());
                    assert!(close(taken.h_real, counted.h_real) && close(taken.h_sim, counted.h_sim));
                    assert!(close(taken.h_joint, counted.h_joint), "{taken:?} against {counted:?}");
                } else {
                    assert_eq!(taken, counted, "the same terms in the same order");
                }
            }
        }
        // columns spread far apart are counted by sorting, with the same result
        let spread =
            Joint::Sparse(vec![(pack(0, 0), 2), (pack(0, 1 << 30), 3), (pack(1, 5), 1), (pack(2, 1 << 30), 4)]);
        assert_eq!(
            column_counts(match &spread {
                Joint::Sparse(r) => r,
                _ => unreachable!(),
            }),
            vec![2, 1, 7]
        );
        assert_eq!(Joint::take_counts(2, 0, &mut [0, 0, 0, 0]), Joint::Sparse(vec![]));
    }
}
