//! The binning plan: how each value becomes a histogram bin (exact integer edges, a lookup
//! table for ≤ 16-bit frames, float edges) and the joint table's layout, decided before the
//! pass from the request and (for `hist_range="data"`) the data range.

use super::parallel::map_units;
use super::range::{bulk, data_range, data_ranges, robust_range, Bulk};
use super::request::{HistRequest, Request};
use super::sample::Sample;
use super::scratch;
use crate::error::{Error, Result};
use crate::hist::{HistSpec, DENSE_MAX_BINS, MAX_BINS};

/// Integer bins, exact: the bin of `v` is `clamp(floor((v − lo) / width), 0, top)`, where
/// `top` is the bin holding the range's upper end, so values below the range land in bin 0
/// and values above it in the bin of `hi` (the edge bins), however few bins the range
/// needs. `top < bins` by construction ([`IntEdges::new`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum IntEdges {
    /// `|lo| ≤ 2^62` and `width ≤ 2^62`: `v − lo` fits i64 for every 32-bit value.
    Small { lo: i64, width: i64, top: i64 },
    /// Ranges beyond that (explicit `hist_range` up to ±2^100): i128 arithmetic.
    Wide { lo: i128, width: i128, top: i128 },
}

/// Largest magnitude of an explicit integer `hist_range` end: every whole f64 up to it is an
/// exact i128, and spans stay far from i128 overflow.
pub(crate) const INT_RANGE_LIMIT: f64 = 1.2676506002282294e30; // 2^100

impl IntEdges {
    /// `bins` bins of whole grey levels covering `lo..=hi` (`lo <= hi`, both within ±2^100):
    /// `width = ceil((hi − lo + 1) / bins)` levels each, starting at `lo`.
    pub(crate) fn new(bins: usize, lo: i128, hi: i128) -> IntEdges {
        assert!(bins >= 1 && lo <= hi && lo.abs() <= 1 << 100 && hi.abs() <= 1 << 100);
        let span = hi - lo + 1;
        let width = (span + bins as i128 - 1) / bins as i128;
        // hi − lo = span − 1 < bins · width, so top ≤ bins − 1
        let top = (hi - lo) / width;
        debug_assert!(top < bins as i128);
        let small = 1i128 << 62;
        if lo.abs() <= small && width <= small {
            IntEdges::Small { lo: lo as i64, width: width as i64, top: top as i64 }
        } else {
            IntEdges::Wide { lo, width, top }
        }
    }

    /// Bins of exactly one level each from `lo` (`count` levels, `count ≥ 1`).
    fn levels(lo: i64, count: usize) -> IntEdges {
        IntEdges::new(count, lo as i128, lo as i128 + count as i128 - 1)
    }

    #[inline(always)]
    fn bin(&self, v: i64) -> usize {
        match *self {
            IntEdges::Small { lo, width, top } => ((v - lo).max(0) / width).min(top) as usize,
            IntEdges::Wide { lo, width, top } => ((v as i128 - lo).max(0) / width).min(top) as usize,
        }
    }

    fn width(&self) -> f64 {
        match *self {
            IntEdges::Small { width, .. } => width as f64,
            IntEdges::Wide { width, .. } => width as f64,
        }
    }

    fn top(&self) -> usize {
        match *self {
            IntEdges::Small { top, .. } => top as usize,
            IntEdges::Wide { top, .. } => top as usize,
        }
    }

    /// The first level of bin `b`, clamped to i128's range.
    fn start(&self, b: usize) -> i128 {
        match *self {
            IntEdges::Small { lo, width, .. } => lo as i128 + b as i128 * width as i128,
            IntEdges::Wide { lo, width, .. } => lo.saturating_add((b as i128).saturating_mul(width)),
        }
    }
}

/// How a value of one frame becomes a bin index.
pub(crate) struct Binner {
    pub(super) bins: usize,
    /// float frames: bin = clamp(trunc((v − lo) · inv_width), 0, bins − 1)
    pub(super) lo: f64,
    pub(super) width: f64,
    pub(super) inv_width: f64,
    /// integer frames
    pub(super) edges: Option<IntEdges>,
    /// integer frames with ≤ 16-bit types: value − MIN → bin (every entry ≤ `edges.top()` <
    /// `bins`), when the bins fit u16; empty otherwise
    pub(super) lut: Vec<u16>,
}

impl Binner {
    #[inline(always)]
    pub(super) fn int_bin(&self, v: i64, min: i64) -> usize {
        if !self.lut.is_empty() {
            return self.lut[(v - min) as usize] as usize;
        }
        match &self.edges {
            Some(e) => e.bin(v),
            None => self.float_bin(v as f64),
        }
    }

    #[inline(always)]
    pub(super) fn float_bin(&self, v: f64) -> usize {
        // Truncation equals floor wherever the result is kept (negatives clamp to bin 0) and,
        // unlike floor(), is one instruction on baseline x86-64. The top edge goes in the last bin.
        let b = ((v - self.lo) * self.inv_width) as i64;
        b.clamp(0, self.bins as i64 - 1) as usize
    }
}

impl Drop for Binner {
    fn drop(&mut self) {
        scratch::give_back_lut(std::mem::take(&mut self.lut), self.bins);
    }
}

/// The histogram layout decided before the pass.
pub(crate) struct HistPlan {
    pub(super) spec: HistSpec,
    pub(super) binner: Option<Binner>, // None = levels keyed by value − MIN
    /// The simulated frame's binning when it has its own edges (`HistRequest::Each`); None:
    /// both frames share `binner`.
    pub(super) sim_binner: Option<Binner>,
    pub(super) dense_bins: Option<usize>,
    pub(super) offset: u64, // levels stored densely: key offset of bin 0
}

/// The histogram plan; `known` is each frame's data range (real, simulated) when a scan has
/// already found it.
pub(super) fn plan_hist<T: Sample>(
    r: &[T],
    s: &[T],
    req: &Request,
    hreq: &HistRequest,
    known: Option<((f64, f64), (f64, f64))>,
) -> Result<HistPlan> {
    match hreq {
        HistRequest::Levels => {
            if !T::IS_INT {
                // the Python layer refuses 'levels' for float frames (stats.hist_params)
                return Err(Error::Value("internal: one bin per level asked of float frames".into()));
            }
            // A small data span is stored densely (same counts, faster than sorting keys).
            let (lo, hi) = data_range(r, s, req).unwrap_or((0.0, 0.0));
            let span = (hi - lo) as usize + 1;
            let dense = span <= DENSE_MAX_BINS;
            let binner = dense.then(|| make_int_binner::<T>(span, IntEdges::levels(lo as i64, span), None));
            Ok(HistPlan {
                spec: HistSpec::Levels,
                binner,
                sim_binner: None,
                dense_bins: dense.then_some(span),
                offset: if dense { (lo as i64 - T::MIN) as u64 } else { 0 },
            })
        }
        HistRequest::Bins { bins, range } => {
            let bins = checked_bins(*bins)?;
            let (lo, hi) = match range {
                Some(range) => explicit_range::<T>(*range)?,
                None => known
                    .map(|(a, b)| (a.0.min(b.0), a.1.max(b.1)))
                    .or_else(|| data_range(r, s, req))
                    .unwrap_or((0.0, 0.0)),
            };
            let binner = uniform_binner::<T>(bins, lo, hi);
            let spec = HistSpec::Binned { bins, lo, width: binner.width };
            Ok(HistPlan {
                spec,
                binner: Some(binner),
                sim_binner: None,
                dense_bins: (bins <= DENSE_MAX_BINS).then_some(bins),
                offset: 0,
            })
        }
        HistRequest::Each { bins } => {
            let bins = checked_bins(*bins)?;
            let (real_full, sim_full) = known.or_else(|| data_ranges(r, s, req)).unwrap_or(((0.0, 0.0), (0.0, 0.0)));
            // a finite scan (`known`) certified every float pair finite
            let finite = T::IS_INT || known.is_some();
            // the two frames' bulks side by side (each sorts a sample of up to 16,384 values)
            let Ok(bulks) = map_units::<_, std::convert::Infallible>(2, r.len() >= PARALLEL_BULK_PIXELS, |k| {
                Ok(match k {
                    0 => bulk(r, (!finite).then_some(s), req, real_full),
                    _ => bulk(s, (!finite).then_some(r), req, sim_full),
                })
            });
            let (real_bulk, sim_bulk) = (bulks[0], bulks[1]);
            let (real, sim) = locked_binners::<T>(bins, (real_bulk, real_full), (sim_bulk, sim_full));
            let spec = HistSpec::Each { bins, real: (real.lo, real.width), sim: (sim.lo, sim.width) };
            Ok(HistPlan {
                spec,
                binner: Some(real),
                sim_binner: Some(sim),
                dense_bins: (bins <= DENSE_MAX_BINS).then_some(bins),
                offset: 0,
            })
        }
    }
}

/// `hist_range="each"`: bins of one width for both frames, each frame's covering its own
/// robust range, the simulated frame's edges locked to the real frame's by the offset between
/// their medians. The width is the wider robust span over `bins` (whole levels for integer
/// frames, the offset too), so an offset moves the edges with the levels, a few extreme pixels
/// land in the edge bins instead of stretching every bin, and a gain spreads the simulated
/// frame over more bins, as with shared edges.
fn locked_binners<T: Sample>(
    bins: usize,
    (real_bulk, real_full): (Option<Bulk>, (f64, f64)),
    (sim_bulk, sim_full): (Option<Bulk>, (f64, f64)),
) -> (Binner, Binner) {
    let (rlo, rhi) = robust_range::<T>(real_bulk, real_full);
    let (slo, shi) = robust_range::<T>(sim_bulk, sim_full);
    let span = (rhi - rlo).max(shi - slo);
    let mut offset = match (real_bulk, sim_bulk) {
        (Some(r), Some(s)) => s.median - r.median,
        _ => slo - rlo,
    };
    let width = if T::IS_INT {
        offset = offset.round();
        ((span + 1.0) / bins as f64).ceil().max(1.0)
    } else {
        span / bins as f64
    };
    // the simulated frame's first edge: the real frame's moved by the offset, then whole bins
    // down to its own range
    let anchor = rlo + offset;
    let sim_lo = if width > 0.0 { anchor + ((slo - anchor) / width).floor() * width } else { slo };
    (width_binner::<T>(bins, rlo, width, real_full), width_binner::<T>(bins, sim_lo, width, sim_full))
}

/// `bins` bins of `width` from `lo` (whole levels for integer frames), values beyond them in
/// the edge bins; `full` is the frame's min..max over the pixels the pass counts (an integer
/// frame's table is written for those levels only).
fn width_binner<T: Sample>(bins: usize, lo: f64, width: f64, full: (f64, f64)) -> Binner {
    if T::IS_INT {
        let edges = IntEdges::Small { lo: lo as i64, width: width as i64, top: bins as i64 - 1 };
        return make_int_binner::<T>(bins, edges, Some((full.0 as i64, full.1 as i64)));
    }
    let inv_width = if width > 0.0 { 1.0 / width } else { 0.0 };
    Binner { bins, lo, width, inv_width, edges: None, lut: Vec::new() }
}

/// Frames of at least this many pixels have their two bulks found on two threads (when the
/// pool is idle): each then takes about 0.1 ms, against a wake-up of a few microseconds.
const PARALLEL_BULK_PIXELS: usize = 1 << 14;

fn checked_bins(bins: usize) -> Result<usize> {
    if bins == 0 || bins > MAX_BINS {
        // the Python layer checks `bins` once (stats.bins_value)
        return Err(Error::Value(format!("internal: {bins} histogram bins asked, outside 1..={MAX_BINS}")));
    }
    Ok(bins)
}

/// An explicit `hist_range`, checked: finite, `lo <= hi`, whole levels within ±2^100 for
/// integer frames.
fn explicit_range<T: Sample>((lo, hi): (f64, f64)) -> Result<(f64, f64)> {
    if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
        return Err(Error::Value(format!("hist_range must be finite with lo <= hi, got ({lo}, {hi})")));
    }
    if T::IS_INT && (lo.fract() != 0.0 || hi.fract() != 0.0) {
        return Err(Error::Value(format!("hist_range for integer frames must be whole grey levels, got ({lo}, {hi})")));
    }
    if T::IS_INT && (lo.abs() > INT_RANGE_LIMIT || hi.abs() > INT_RANGE_LIMIT) {
        return Err(Error::Value(format!("hist_range for integer frames must lie within ±2^100, got ({lo}, {hi})")));
    }
    Ok((lo, hi))
}

/// `bins` uniform bins over `lo..=hi`: for integer frames a bin is a whole number of grey
/// levels, width = ceil(span / bins) (whole f64 values within ±2^100, checked or data
/// values, are exact in i128); for floats width = (hi − lo) / bins.
fn uniform_binner<T: Sample>(bins: usize, lo: f64, hi: f64) -> Binner {
    if T::IS_INT {
        return make_int_binner::<T>(bins, IntEdges::new(bins, lo as i128, hi as i128), None);
    }
    let width = (hi - lo) / bins as f64;
    let inv_width = if width > 0.0 { 1.0 / width } else { 0.0 };
    Binner { bins, lo, width, inv_width, edges: None, lut: Vec::new() }
}

/// The integer binner of `edges`; with a `window` (the lowest and highest level the pass will
/// look up) only those levels' table entries are written.
fn make_int_binner<T: Sample>(bins: usize, edges: IntEdges, window: Option<(i64, i64)>) -> Binner {
    let lo = match edges {
        IntEdges::Small { lo, .. } => lo as f64,
        IntEdges::Wide { lo, .. } => lo as f64,
    };
    let width = edges.width();
    let inv_width = 1.0 / width;
    // value − MIN → bin for ≤ 16-bit types, filled run by run (a bin is `width` consecutive
    // levels): no division per entry. Bins above u16 (more than 65536 bins) use `IntEdges::bin`.
    // Entries outside the window keep what a kept table held: values below `bins` all the same
    // (`scratch::lut_below`), so no lookup can leave the dense table.
    let top = edges.top();
    let lut = if T::LUT > 0 && top <= u16::MAX as usize {
        let mut lut = scratch::lut_below(T::LUT, bins);
        let (first, end) = window.map_or((0, T::LUT), |(low, high)| {
            let entry = |level: i64| (level - T::MIN).clamp(0, T::LUT as i64 - 1) as usize;
            (entry(low), entry(high.max(low)) + 1)
        });
        let mut k = first;
        while k < end {
            let b = edges.bin(k as i64 + T::MIN);
            // the entries up to the next bin's first level share bin b (the last bin: all)
            let run_end = if b >= top {
                end
            } else {
                (edges.start(b + 1) - T::MIN as i128).clamp(k as i128 + 1, end as i128) as usize
            };
            lut[k..run_end].fill(b as u16);
            k = run_end;
        }
        lut
    } else {
        Vec::new()
    };
    Binner { bins, lo, width, inv_width, edges: Some(edges), lut }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernel::driver::tests::all;
    use crate::stats::pair_stats;

    #[test]
    fn lut_matches_the_binning_rule() {
        for (bins, lo, hi) in [(256usize, 2000i128, 14000i128), (10, -100, -31), (3, 65000, 65599), (512, 0, 511)] {
            let edges = IntEdges::new(bins, lo, hi);
            let bn = make_int_binner::<u16>(bins, edges, None);
            let width = (hi - lo + 1 + bins as i128 - 1) / bins as i128;
            let top = (hi - lo) / width;
            for v in [0i64, 1, 1999, 2000, 2046, 2047, 14000, 65000, 65535] {
                let want = ((v as i128 - lo).max(0) / width).min(top) as usize;
                assert_eq!(bn.int_bin(v, 0), want, "bins {bins} lo {lo} hi {hi} v {v}");
                assert_eq!(edges.bin(v), want);
            }
        }
        let bn = make_int_binner::<i16>(4, IntEdges::new(4, -10, 9), None);
        assert_eq!(
            (bn.int_bin(-32768, i16::MIN as i64), bn.int_bin(-6, i16::MIN as i64), bn.int_bin(9, i16::MIN as i64)),
            (0, 0, 3)
        );
    }

    /// A table written over a window holds the rule's bins there, and every entry (written or
    /// kept from an earlier pass) below `bins`: a table kept from a pass with more bins is not
    /// reused.
    #[test]
    fn a_windowed_table_holds_the_rule_in_its_window_and_stays_below_bins() {
        drop(make_int_binner::<u16>(512, IntEdges::Small { lo: 0, width: 1, top: 511 }, None));
        for (lo, width, window) in
            [(2600i64, 2i64, (2649i64, 2942i64)), (100, 3, (0, 65535)), (60000, 1, (65000, 65535))]
        {
            let edges = IntEdges::Small { lo, width, top: 255 };
            let bn = make_int_binner::<u16>(256, edges, Some(window));
            for v in window.0..=window.1 {
                assert_eq!(bn.lut[v as usize] as usize, edges.bin(v), "lo {lo} width {width} v {v}");
            }
            assert!(bn.lut.iter().all(|&b| b < 256), "lo {lo} width {width}");
        }
    }

    /// Every table entry is below `bins` (the bound the unchecked dense-table writes rely
    /// on), for ranges narrower than `bins`, wider than every type, and at the ±2^100 limit.
    #[test]
    fn int_bins_stay_below_bins_at_the_edges() {
        let limit = 1i128 << 100;
        let ranges = [
            (0, 0),
            (5, 5),
            (2, 5),
            (-3, 3),
            (250, 255),
            (-10_000_000_000_000_000_000, 1000),
            (-10_000_000_000_000_000_000, 10_000_000_000_000_000_000),
            (0, 10_000_000_000_000_000_000),
            (-9_300_000_000_000_000_000, -9_200_000_000_000_000_000),
            (-limit, limit),
            (limit - 7, limit),
            (-limit, -limit + 3),
            (i64::MIN as i128, i64::MAX as i128),
        ];
        for bins in [1usize, 2, 3, 255, 256, 512, 65536, 65537, MAX_BINS] {
            for &(lo, hi) in &ranges {
                let edges = IntEdges::new(bins, lo, hi);
                assert!(edges.top() < bins, "bins {bins} ({lo}, {hi})");
                for bn in [make_int_binner::<u8>(bins, edges, None), make_int_binner::<i16>(bins, edges, None)] {
                    assert!(bn.lut.iter().all(|&b| (b as usize) < bins), "bins {bins} ({lo}, {hi})");
                }
                for v in [i32::MIN as i64, -32768, -1, 0, 1, 255, 65535, u32::MAX as i64] {
                    let b = edges.bin(v);
                    assert!(b <= edges.top(), "bins {bins} ({lo}, {hi}) v {v}");
                    // the exact rule, in i128
                    let width = (hi - lo + 1 + bins as i128 - 1) / bins as i128;
                    assert_eq!(b as i128, ((v as i128 - lo).max(0) / width).min((hi - lo) / width));
                }
            }
        }
    }

    /// Integer frames at the extremes of their type through the whole pass, with the dense
    /// table (the unchecked writes), and explicit ranges beyond i64.
    #[test]
    fn extreme_levels_and_ranges_through_the_pass() {
        let r: Vec<u16> = vec![0, 65535, 1, 65534, 30000, 0, 65535, 7];
        let s: Vec<u16> = vec![65535, 0, 65534, 1, 30001, 0, 65535, 7];
        for range in [(0.0, 0.0), (-1e19, 1e3), (-1e19, 1e19), (65535.0, 65535.0), (-1.2676506002282294e30, 1e30)] {
            for bins in [1usize, 7, 256, 512, 513, 70_000] {
                let req = Request { hist: Some(HistRequest::Bins { bins, range: Some(range) }), ..all() };
                let st = pair_stats(&r, &s, &req).unwrap();
                let (_, joint) = st.hist.as_ref().unwrap();
                assert_eq!(joint.total(), r.len() as u64, "{range:?} bins {bins}");
            }
        }
        let req = Request { hist: Some(HistRequest::Bins { bins: 8, range: Some((-1e31, 0.0)) }), ..all() };
        assert!(matches!(pair_stats(&r, &s, &req), Err(Error::Value(m)) if m.contains("2^100")));
    }
}
