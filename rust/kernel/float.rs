//! The float pass: values promoted to f64, summed relative to a pivot near each frame's
//! mean, in independent lanes folded into Neumaier-compensated totals (two passes per
//! cache-sized chunk: mean, then centred sums), chunks merged with Chan's update.

use super::{fold_chunks, Acc, Bad, HistPlan, Pass, Request, Sample};
use crate::stats::{merge_float, two_sum, FloatSums};

/// Neumaier-compensated running sum: totals of per-block lane sums.
#[derive(Clone, Copy, Default)]
pub(super) struct Neumaier {
    sum: f64,
    comp: f64,
}

impl Neumaier {
    #[inline(always)]
    fn add(&mut self, x: f64) {
        let (s, e) = two_sum(self.sum, x);
        self.sum = s;
        self.comp += e;
    }
    pub(super) fn value(&self) -> f64 {
        self.sum + self.comp
    }
    /// Add another compensated total (both parts).
    pub(super) fn merge(&mut self, other: &Neumaier) {
        self.add(other.sum);
        self.add(other.comp);
    }
}

/// Lanes of independent partial sums (vectorised; also a first level of pairwise summation)
/// and values per block before the lanes are folded into a compensated total.
const LANES: usize = 8;
/// The centred pass keeps six sums: four lanes each fit the SSE2 register file unspilled.
const LANES_C: usize = 4;
const SUB: usize = 64;

/// The float pass over `[a, b)`: mean first, then centred sums, on cache-resident data.
/// Values are shifted by a per-call `pivot` (≈ each frame's mean, see `float_pivot`) so
/// chunk means are small and Chan's merge does not lose digits to a large common offset.
#[inline(always)]
pub(super) fn float_chunk<T: Sample>(
    pass: &Pass<'_, T>,
    (a, b): (usize, usize),
    acc: &mut Acc,
    nonfinite: &mut u64,
) -> std::result::Result<(), Bad> {
    let Pass { r, s, req, plan, pivot } = *pass;
    let (rr, sb) = (&r[a..b], &s[a..b]);
    if req.mask.is_none() && !req.moments && req.hist.is_none() {
        // PSNR-only plan: one pass, no means needed
        let (sse, max_abs) = float_sse(rr, sb);
        if sse.value().is_finite() {
            acc.max_abs = acc.max_abs.max(max_abs);
            let part = FloatSums { sse: sse.sum, sse_c: sse.comp, ..FloatSums::default() };
            acc.float = merge_float(&acc.float, acc.n, &part, rr.len() as u64);
            acc.n += rr.len() as u64;
            return Ok(());
        }
    }
    if req.mask.is_none() {
        let (sum_r, sum_s, max_abs) = float_sums(rr, sb, pivot);
        // a NaN/Inf anywhere makes the sums non-finite: only then look pixel by pixel
        if sum_r.is_finite() && sum_s.is_finite() {
            acc.max_abs = acc.max_abs.max(max_abs);
            acc.sum_r.add(sum_r);
            acc.sum_s.add(sum_s);
            float_centred(rr, sb, sum_r, sum_s, req, plan, acc, pivot);
            return Ok(());
        }
    }
    // General path: keep the counted pairs (mask, finiteness) as f64, then the same kernel.
    let (mut xs, mut ys) = (Vec::with_capacity(rr.len()), Vec::with_capacity(rr.len()));
    for (k, (&x, &y)) in rr.iter().zip(sb).enumerate() {
        if req.mask.is_some_and(|m| !m[a + k]) {
            continue;
        }
        let (x, y) = (x.to_f64(), y.to_f64());
        if !(x.is_finite() && y.is_finite()) {
            if req.mask_nonfinite {
                *nonfinite += 1;
                continue;
            }
            return Err(Bad::NonFinite { index: a + k });
        }
        xs.push(x);
        ys.push(y);
    }
    if !xs.is_empty() {
        let (sum_r, sum_s, max_abs) = float_sums(&xs, &ys, pivot);
        acc.max_abs = acc.max_abs.max(max_abs);
        acc.sum_r.add(sum_r);
        acc.sum_s.add(sum_s);
        float_centred(&xs, &ys, sum_r, sum_s, req, plan, acc, pivot);
    }
    Ok(())
}

/// Running max of |x| and |y| for the underflow check. Plain compares (one `maxpd`), not
/// `f64::max`, whose NaN rules cost a blend per value: NaN is caught by the sums anyway.
/// Only float64 frames can be small enough to underflow, so other types skip it.
#[inline(always)]
fn bigger<T: Sample>(m: f64, x: f64, y: f64) -> f64 {
    if !T::MAY_UNDERFLOW {
        return m;
    }
    let (ax, ay) = (x.abs(), y.abs());
    let m = if ax > m { ax } else { m };
    if ay > m {
        ay
    } else {
        m
    }
}

/// Σ(x − y)² (compensated) and max |value| of a run of pixels.
#[inline(always)]
fn float_sse<T: Sample>(rr: &[T], sb: &[T]) -> (Neumaier, f64) {
    let mut tot = Neumaier::default();
    let mut max_abs = [0.0f64; LANES];
    for (cr, cs) in rr.chunks(SUB).zip(sb.chunks(SUB)) {
        let mut l = [0.0f64; LANES];
        let (ir, is) = (cr.chunks_exact(LANES), cs.chunks_exact(LANES));
        let (rem_r, rem_s) = (ir.remainder(), is.remainder());
        for (xr, xs) in ir.zip(is) {
            for k in 0..LANES {
                let (x, y) = (xr[k].to_f64(), xs[k].to_f64());
                let d = x - y;
                l[k] += d * d;
                max_abs[k] = bigger::<T>(max_abs[k], x, y);
            }
        }
        for (&x, &y) in rem_r.iter().zip(rem_s) {
            let (x, y) = (x.to_f64(), y.to_f64());
            l[0] += (x - y) * (x - y);
            max_abs[0] = bigger::<T>(max_abs[0], x, y);
        }
        tot.add(l.iter().sum());
    }
    (tot, max_abs.iter().fold(0.0f64, |m, &v| m.max(v)))
}

/// Σ(x − pivot_r), Σ(y − pivot_s) and max |value| of a run of pixels. Each lane is a
/// compensated (two-sum) accumulator: the mean of wide-spread data (±3e38 around 1e35)
/// is the sum of large terms that cancel, so every addition's error is kept.
#[inline(always)]
fn float_sums<T: Sample>(rr: &[T], sb: &[T], (pr, ps): (f64, f64)) -> (f64, f64, f64) {
    let (mut lr, mut cr_) = ([0.0f64; LANES], [0.0f64; LANES]);
    let (mut ls, mut cs_) = ([0.0f64; LANES], [0.0f64; LANES]);
    let mut max_abs = [0.0f64; LANES];
    #[inline(always)]
    fn add(sum: &mut f64, comp: &mut f64, x: f64) {
        let (t, e) = two_sum(*sum, x);
        *sum = t;
        *comp += e;
    }
    let (ir, is) = (rr.chunks_exact(LANES), sb.chunks_exact(LANES));
    let (rem_r, rem_s) = (ir.remainder(), is.remainder());
    for (xr, xs) in ir.zip(is) {
        for k in 0..LANES {
            let (x, y) = (xr[k].to_f64(), xs[k].to_f64());
            add(&mut lr[k], &mut cr_[k], x - pr);
            add(&mut ls[k], &mut cs_[k], y - ps);
            max_abs[k] = bigger::<T>(max_abs[k], x, y);
        }
    }
    for (&x, &y) in rem_r.iter().zip(rem_s) {
        let (x, y) = (x.to_f64(), y.to_f64());
        add(&mut lr[0], &mut cr_[0], x - pr);
        add(&mut ls[0], &mut cs_[0], y - ps);
        max_abs[0] = bigger::<T>(max_abs[0], x, y);
    }
    let (mut tr, mut ts) = (Neumaier::default(), Neumaier::default());
    for k in 0..LANES {
        tr.add(lr[k]);
        tr.add(cr_[k]);
        ts.add(ls[k]);
        ts.add(cs_[k]);
    }
    (tr.value(), ts.value(), max_abs.iter().fold(0.0f64, |m, &v| m.max(v)))
}

/// Centred sums around the run's own mean (corrected two-pass), SSE and the histogram,
/// merged into `acc` (sums relative to the pivot).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn float_centred<T: Sample>(
    rr: &[T],
    sb: &[T],
    sum_r: f64,
    sum_s: f64,
    req: &Request,
    plan: Option<&HistPlan>,
    acc: &mut Acc,
    (pr, ps): (f64, f64),
) {
    let n = rr.len() as u64;
    if n == 0 {
        return;
    }
    let nf = n as f64;
    let (mr, ms) = (sum_r / nf, sum_s / nf); // relative to the pivot
                                             // six compensated totals: Σdr, Σds, Σdr², Σds², Σdr·ds, Σ(x−y)²
    let mut tot = [Neumaier::default(); 6];
    if req.moments || req.sse {
        for (cr, cs) in rr.chunks(SUB).zip(sb.chunks(SUB)) {
            let mut l = [[0.0f64; LANES_C]; 6];
            let (ir, is) = (cr.chunks_exact(LANES_C), cs.chunks_exact(LANES_C));
            let (rem_r, rem_s) = (ir.remainder(), is.remainder());
            macro_rules! body {
                ($k:expr, $x:expr, $y:expr) => {{
                    let (x, y): (f64, f64) = ($x, $y);
                    let (dr, ds) = (x - pr - mr, y - ps - ms);
                    let d = x - y;
                    l[0][$k] += dr;
                    l[1][$k] += ds;
                    l[2][$k] += dr * dr;
                    l[3][$k] += ds * ds;
                    l[4][$k] += dr * ds;
                    l[5][$k] += d * d;
                }};
            }
            for (xr, xs) in ir.zip(is) {
                for k in 0..LANES_C {
                    body!(k, xr[k].to_f64(), xs[k].to_f64());
                }
            }
            for (&x, &y) in rem_r.iter().zip(rem_s) {
                body!(0, x.to_f64(), y.to_f64());
            }
            for (t, lane) in tot.iter_mut().zip(&l) {
                t.add(lane.iter().sum());
            }
        }
    }
    if let Some(p) = plan {
        if let Some(bn) = p.binner.as_ref() {
            let dense_bins = p.dense_bins.unwrap_or(0);
            for (&x, &y) in rr.iter().zip(sb) {
                acc.count(dense_bins, bn.float_bin(x.to_f64()), bn.float_bin(y.to_f64()));
            }
        }
    }
    let [dr, ds, m2r, m2s, crs, _] = tot.map(|t| t.value());
    // corrected two-pass: remove the residual of the approximate mean
    let part = FloatSums {
        mr: mr + dr / nf,
        ms: ms + ds / nf,
        m2r: m2r - dr * dr / nf,
        m2s: m2s - ds * ds / nf,
        crs: crs - dr * ds / nf,
        sse: if req.sse { tot[5].sum } else { 0.0 },
        sse_c: if req.sse { tot[5].comp } else { 0.0 },
    };
    acc.float = merge_float(&acc.float, acc.n, &part, n);
    acc.n += n;
}

/// The pivot of the float pass: the mean of each frame from a parallel compensated prepass,
/// or (with a mask or non-finite values) the first finite value.
pub(super) fn float_pivot<T: Sample>(r: &[T], s: &[T], req: &Request) -> (f64, f64) {
    if req.mask.is_none() && !r.is_empty() {
        let add = |a: (f64, f64), b: (f64, f64)| (a.0 + b.0, a.1 + b.1);
        let Ok((sr, ss)) = fold_chunks::<T, _, std::convert::Infallible>(
            r.len(),
            || (0.0, 0.0),
            |acc, (a, b)| {
                let (x, y, _) = float_sums(&r[a..b], &s[a..b], (0.0, 0.0));
                Ok(add(acc, (x, y)))
            },
            add,
        );
        let n = r.len() as f64;
        // Keep 24 significant bits: x − pivot is then exact for every float32 value (and for
        // float64 values within 2^29 of the pivot's magnitude) — a 53-bit pivot would round
        // each difference, and identical values (e.g. clipped at ±3.4e38) round coherently.
        let short = |p: f64| f64::from_bits(p.to_bits() & !((1u64 << 29) - 1));
        if (sr / n).is_finite() && (ss / n).is_finite() {
            return (short(sr / n), short(ss / n));
        }
    }
    let pick = |v: &[T]| v.iter().map(|x| x.to_f64()).find(|x| x.is_finite()).unwrap_or(0.0);
    (pick(r), pick(s))
}
