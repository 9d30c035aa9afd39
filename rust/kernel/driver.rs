//! The driver: [`pair_stats`] checks its inputs, plans the pass (the float scan, the binning
//! plan, the pivot), folds the chunks over the calling thread and idle pool threads
//! (`parallel`, `dispatch::run_chunk`), and finishes the totals into a [`PairStats`].

use super::acc::{Acc, Bad};
use super::binning::{plan_hist, HistPlan};
use super::dispatch::{run_chunk, Pass};
use super::float::{float_pivot, float_scan, float_total, offset_mean, RunSums};
use super::parallel::{cost, fold_chunks};
use super::request::Request;
use super::sample::Sample;
use super::CHUNK;
use crate::error::{Error, Result};
use crate::hist::Joint;
use crate::stats::{FloatSums, PairStats, Sums};

/// Statistics of the frame pair `(r, s)` (same length, same pixel order).
///
/// Runs on the current rayon pool; call it inside `ThreadPool::install` to bound the
/// number of threads.
pub fn pair_stats<T: Sample>(r: &[T], s: &[T], req: &Request) -> Result<PairStats> {
    check_inputs(r, s, req)?;
    if let (Some(r16), Some(s16)) = (T::as_f16(r), T::as_f16(s)) {
        // float16 → f32 is exact: widen each frame once (F16C when the CPU has it) instead of
        // converting in software on every access of every pass. Costs 4 bytes per pixel.
        return pair_stats(&widen_f16(r16), &widen_f16(s16), req);
    }
    let plan = Plan::new(r, s, req)?;
    let (acc, nonfinite) = fold(r, s, req, &plan)?;
    finish::<T>(r.len(), req, plan, acc, nonfinite)
}

/// Equal lengths, a mask of the same length, and fewer than 2^32 pixels (the dense
/// histogram's per-worker counters are u32).
fn check_inputs<T>(r: &[T], s: &[T], req: &Request) -> Result<()> {
    if r.len() != s.len() {
        return Err(Error::Shape(format!(
            "real and simulated frames differ in size: {} vs {} pixels",
            r.len(),
            s.len()
        )));
    }
    if r.len() as u64 >= u32::MAX as u64 {
        return Err(Error::Value(format!("frames of {} pixels are too large (limit 2^32 - 1)", r.len())));
    }
    if let Some(m) = req.mask {
        if m.len() != r.len() {
            return Err(Error::Shape(format!("mask has {} elements, frames have {}", m.len(), r.len())));
        }
    }
    Ok(())
}

/// A float16 frame as float32 (exact), converted chunk by chunk like a pass.
fn widen_f16(x: &[half::f16]) -> Vec<f32> {
    use half::slice::HalfFloatSliceExt;
    let mut out = vec![0f32; x.len()];
    // each chunk's output slice behind its own (uncontended) lock, shared like a pass
    let parts: Vec<std::sync::Mutex<&mut [f32]>> = out.chunks_mut(CHUNK).map(std::sync::Mutex::new).collect();
    let Ok(()) = fold_chunks::<(), std::convert::Infallible>(
        x.len(),
        cost::RANGE,
        || (),
        |(), (a, b)| {
            let mut o = parts[a / CHUNK].lock().unwrap_or_else(|p| p.into_inner());
            x[a..b].convert_to_f32_slice(&mut o);
            Ok(())
        },
        |(), ()| (),
    );
    drop(parts);
    out
}

/// What is decided before the pass.
struct Plan {
    /// Float frames with moments and no mask: one compensated scan of both frames, giving
    /// the histogram range, each frame's mean, and (when finite) certifying every value finite.
    scan: Option<RunSums>,
    hist: Option<HistPlan>,
    /// Float frames: all sums are taken relative to a pivot near each frame's mean, so the
    /// final mean is the pivot plus a small, accurate correction and chunk merges see small
    /// offsets (a pivot far from the mean would cancel digits: ±3e38 data, mean 1e35).
    pivot: (f64, f64),
    /// Each frame's mean relative to the pivot, when the scan found every value finite: the
    /// common centre of every chunk's sums.
    centre: Option<(f64, f64)>,
}

impl Plan {
    fn new<T: Sample>(r: &[T], s: &[T], req: &Request) -> Result<Plan> {
        let scan = (!T::IS_INT && req.moments && req.mask.is_none() && !r.is_empty())
            .then(|| float_scan(r, s, req.hist.is_some()));
        let known = scan.as_ref().filter(|sc| sc.finite()).map(|sc| (sc.real_range, sc.sim_range));
        let hist = match &req.hist {
            Some(h) => Some(plan_hist(r, s, req, h, known)?),
            None => None,
        };
        let (pivot, centre) =
            if T::IS_INT || !req.moments { ((0.0, 0.0), None) } else { float_pivot(r, s, scan.as_ref()) };
        Ok(Plan { scan, hist, pivot, centre })
    }

    /// The scan, when it certified every value finite.
    fn finite_scan(&self) -> Option<&RunSums> {
        self.scan.as_ref().filter(|sc| sc.finite())
    }
}

/// The pass itself: every chunk folded into per-worker accumulators, merged; the lowest
/// failing chunk's error otherwise. Returns the accumulator and the non-finite pairs excluded.
fn fold<T: Sample>(r: &[T], s: &[T], req: &Request, plan: &Plan) -> Result<(Acc, u64)> {
    let hist = plan.hist.as_ref();
    let pass = Pass { r, s, req, plan: hist, pivot: plan.pivot, centre: plan.centre };
    let ns_per_px = match (req.moments || req.hist.is_some() || req.mask.is_some(), T::IS_INT) {
        (false, _) => cost::SSE,
        (true, true) => cost::FULL_INT,
        (true, false) => cost::FULL_FLOAT,
    };
    let result = fold_chunks(
        r.len(),
        ns_per_px,
        || (Acc::new(hist), 0u64),
        |(mut acc, mut nf), range| {
            run_chunk(&pass, range, &mut acc, &mut nf)?;
            if acc.keys.len() >= 1 << 20 {
                acc.flush_keys();
            }
            Ok((acc, nf))
        },
        |(a, na), (b, nb)| (a.merge(b, T::IS_INT), na + nb),
    );
    let (mut acc, nonfinite) = result.map_err(|bad| describe(bad, r, s, req))?;
    acc.flush_keys();
    Ok((acc, nonfinite))
}

/// The totals as a [`PairStats`] (`n` pixels per frame).
fn finish<T: Sample>(n: usize, req: &Request, plan: Plan, mut acc: Acc, nonfinite: u64) -> Result<PairStats> {
    let mut out = PairStats::empty::<T>(req);
    out.n = acc.n;
    out.masked = req.mask.map_or(0, |m| m.iter().filter(|&&k| !k).count() as u64);
    out.nonfinite = nonfinite;
    out.sums = if T::IS_INT { Sums::Int(acc.int) } else { Sums::Float(float_sums(n, &plan, &mut acc)?) };
    // the scan took each frame's range only for the histogram
    out.real_range = plan.finite_scan().filter(|_| req.hist.is_some()).map(|sc| sc.real_range);
    if let Some(p) = plan.hist {
        let joint = match p.dense_bins {
            Some(b) => acc.take_joint(b, p.offset),
            None => Joint::Sparse(std::mem::take(&mut acc.runs)),
        };
        out.hist = Some((p.spec, joint));
    }
    Ok(out)
}

/// The float pass's sums, combined in chunk order; an error when float64 cannot hold them
/// (every square underflows, or the sums overflow).
fn float_sums(n: usize, plan: &Plan, acc: &mut Acc) -> Result<FloatSums> {
    // every chunk was centred on the scan's means: they are the means
    let means = match (plan.finite_scan(), plan.centre) {
        (Some(sc), Some(_)) => {
            acc.max_abs = acc.max_abs.max(sc.max_abs);
            Some((offset_mean(0.0, &sc.r, n as f64), offset_mean(0.0, &sc.s, n as f64)))
        }
        _ => None,
    };
    let f = float_total(std::mem::take(&mut acc.floats), acc.n, plan.pivot, means);
    // below 2^-500 every square underflows: MSE 0 and equal-looking frames would be silent lies
    if acc.max_abs > 0.0 && acc.max_abs < 2f64.powi(-500) {
        return Err(Error::Range(format!(
            "float frames with magnitudes at most {:e} cannot be summed in float64 without underflow \
             (squares below 1e-300); rescale them, e.g. multiply both by 2**600",
            acc.max_abs
        )));
    }
    if ![f.mr, f.ms, f.m2r, f.m2s, f.crs, f.sse].iter().all(|v| v.is_finite()) {
        return Err(Error::Range(
            "frame values are too large for float64 statistics (sums overflow); rescale the frames".into(),
        ));
    }
    Ok(f)
}

/// The error for a failing chunk: the first out-of-range value, or the non-finite counts.
fn describe<T: Sample>(bad: Bad, r: &[T], s: &[T], req: &Request) -> Error {
    match bad {
        Bad::Range { frame, value, index } => {
            let (row, col) = req.position(index);
            let (lo, hi) = req.valid.unwrap_or((0, 0));
            Error::Range(format!(
                "{frame} frame: value {value} at (row {row}, col {col}) is outside the valid range [{lo}, {hi}] \
                 of the declared bit depth"
            ))
        }
        Bad::NonFinite { index } => {
            let keep = |i: usize| req.mask.is_none_or(|m| m[i]);
            let count_r = (0..r.len()).filter(|&i| keep(i) && !r[i].to_f64().is_finite()).count();
            let count_s = (0..s.len()).filter(|&i| keep(i) && !s[i].to_f64().is_finite()).count();
            let (row, col) = req.position(index);
            Error::Range(format!(
                "non-finite values (NaN/Inf): {count_r} in the real frame, {count_s} in the simulated frame; \
                 first at (row {row}, col {col}); pass nonfinite='mask' to exclude those pixel pairs"
            ))
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::kernel::HistRequest;

    /// Every output, 256 bins over the data.
    pub(crate) fn all() -> Request<'static> {
        Request { hist: Some(HistRequest::Bins { bins: 256, range: None }), ..Request::default() }
    }

    #[test]
    fn exact_u16_sums_and_merge() {
        let r: Vec<u16> = (0..200_000u32).map(|i| (65535 - (i % 7)) as u16).collect();
        let s: Vec<u16> = r.iter().enumerate().map(|(i, &v)| if i % 3 == 0 { v - 1 } else { v }).collect();
        let st = pair_stats(&r, &s, &all()).unwrap();
        let sse: u128 = r.iter().zip(&s).map(|(&a, &b)| ((a as i64 - b as i64).pow(2)) as u128).sum();
        let Sums::Int(sums) = st.sums else { panic!() };
        assert_eq!(sums.sse, sse);
        assert_eq!(sums.sr, r.iter().map(|&v| v as i128).sum::<i128>());
        assert_eq!(sums.srs, r.iter().zip(&s).map(|(&a, &b)| a as i128 * b as i128).sum::<i128>());
        // merge of halves equals the whole (shared explicit edges)
        let req = Request { hist: Some(HistRequest::Bins { bins: 256, range: Some((0.0, 65535.0)) }), ..all() };
        let whole = pair_stats(&r, &s, &req).unwrap();
        let a = pair_stats(&r[..70_001], &s[..70_001], &req).unwrap();
        let b = pair_stats(&r[70_001..], &s[70_001..], &req).unwrap();
        assert_eq!(a.merge(&b).unwrap(), whole);
    }

    #[test]
    fn range_and_nonfinite_errors() {
        let r = [1u16, 2, 300];
        let s = [1u16, 2, 3];
        let req = Request { valid: Some((0, 255)), shape: (1, 3), ..all() };
        let e = pair_stats(&r, &s, &req).unwrap_err();
        assert!(matches!(&e, Error::Range(m) if m.contains("300") && m.contains("col 2")), "{e}");
        let rf = [1.0f32, f32::NAN, 2.0];
        let sf = [1.0f32, 1.0, 2.0];
        let req = Request { shape: (1, 3), ..all() };
        assert!(matches!(pair_stats(&rf, &sf, &req), Err(Error::Range(_))));
        let req = Request { mask_nonfinite: true, ..req };
        let st = pair_stats(&rf, &sf, &req).unwrap();
        assert_eq!((st.n, st.nonfinite), (2, 1));
    }

    #[test]
    fn float_cancellation() {
        // 1e6 offset, tiny spread: centred sums keep the variance exact
        let r: Vec<f64> = (0..100_000).map(|i| 1e6 + ((i % 10) as f64) / 128.0).collect(); // exact in f64
        let s: Vec<f64> = r.iter().map(|v| v + 1.0 / 256.0).collect();
        let st = pair_stats(&r, &s, &Request { hist: None, ..all() }).unwrap();
        let m = st.moments().unwrap();
        let want = (0..10).map(|k| ((k as f64 - 4.5) / 128.0).powi(2)).sum::<f64>() / 10.0;
        assert!(((m.var_real - want) / want).abs() < 1e-9, "{} vs {want}", m.var_real);
        assert!(((m.cov - m.var_real) / want).abs() < 1e-9);
    }

    #[test]
    fn bytes_roundtrip() {
        let r: Vec<u16> = (0..5000u32).map(|i| (i * 7 % 4096) as u16).collect();
        let s: Vec<u16> = r.iter().map(|&v| v / 2).collect();
        for hist in [Some(HistRequest::Levels), Some(HistRequest::Bins { bins: 2048, range: None }), None] {
            let st = pair_stats(&r, &s, &Request { hist, ..all() }).unwrap();
            assert_eq!(PairStats::from_bytes(&st.to_bytes()).unwrap(), st);
        }
        let f: Vec<f32> = r.iter().map(|&v| v as f32 * 0.5).collect();
        let st = pair_stats(&f, &f, &all()).unwrap();
        assert_eq!(st.real_range, Some((0.0, 2047.5))); // the scan read every pixel
        let bytes = st.to_bytes();
        // the encoding keeps all but the pass's own real range
        assert_eq!(PairStats::from_bytes(&bytes).unwrap(), PairStats { real_range: None, ..st.clone() });
        assert!(PairStats::from_bytes(&bytes[..bytes.len() - 3]).is_err());
        assert!(PairStats::from_bytes(b"nope").is_err());
    }
}
