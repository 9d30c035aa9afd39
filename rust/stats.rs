//! Fused frame-pair statistics: one pass over two frames computes exactly what the
//! caller needs (SSE, moments, joint histogram) as a mergeable [`PairStats`].
//!
//! Integer frames are summed **exactly** (u64/i64 per block, u128/i128 totals), so
//! MSE, variances and covariance are exact rationals rounded to f64 once. Float frames
//! are promoted to f64 and summed per cache-sized chunk in two passes (mean, then
//! centred sums), chunks merged with Chan's update, SSE with Neumaier compensation.
//! Frames are split into chunks processed in parallel (rayon) and merged, which is the
//! same `merge` that pools the frames of a sequence or the results of Dask workers.

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::hist::{self, Entropies, HistSpec, Joint, DENSE_MAX_BINS};

/// Pixels per work unit: two chunks of u16/f32 fit in L2 with the histogram.
const CHUNK: usize = 1 << 16;

/// A pixel type the kernels accept. Implemented for u8, u16, i16, u32 (exact integer
/// path) and f16, f32, f64 (float path) by the macros below.
pub trait Sample: Copy + PartialOrd + Send + Sync + 'static {
    const IS_INT: bool;
    /// Smallest value of the type (integer types), used to make level keys non-negative.
    const MIN: i64;
    /// Size of a value → bin lookup table (0: compute bins arithmetically).
    const LUT: usize;
    /// Pixels per exact block: squares of this many values fit in u64.
    const BLOCK: usize;
    fn to_i64(self) -> i64;
    fn to_f64(self) -> f64;
}

macro_rules! int_sample {
    ($($t:ty => $lut:expr, $block:expr);* $(;)?) => {$(
        impl Sample for $t {
            const IS_INT: bool = true;
            const MIN: i64 = <$t>::MIN as i64;
            const LUT: usize = $lut;
            const BLOCK: usize = $block;
            #[inline(always)]
            fn to_i64(self) -> i64 { self as i64 }
            #[inline(always)]
            fn to_f64(self) -> f64 { self as f64 }
        }
    )*};
}
// |v| < 2^16: v² < 2^32, so 2^15 of them sum below 2^47 in u64. u32 squares fill a
// u64 on their own, so u32 blocks are one pixel long (rare dtype; exactness first).
int_sample!(u8 => 1 << 8, 1 << 15; u16 => 1 << 16, 1 << 15; i16 => 1 << 16, 1 << 15; u32 => 0, 1);

macro_rules! float_sample {
    ($($t:ty => $conv:expr);* $(;)?) => {$(
        impl Sample for $t {
            const IS_INT: bool = false;
            const MIN: i64 = 0;
            const LUT: usize = 0;
            const BLOCK: usize = CHUNK;
            #[inline(always)]
            fn to_i64(self) -> i64 { 0 }
            #[inline(always)]
            fn to_f64(self) -> f64 { $conv(self) }
        }
    )*};
}
float_sample!(f32 => |v: f32| v as f64; f64 => |v: f64| v; half::f16 => |v: half::f16| v.to_f64());

/// Which histogram to build.
#[derive(Clone, Debug, PartialEq)]
pub enum HistRequest {
    /// `bins` uniform bins over `range` (inclusive integer levels for integer frames);
    /// `None` = the data range of both frames.
    Bins { bins: usize, range: Option<(f64, f64)> },
    /// Every grey level its own bin (integer frames only).
    Levels,
}

/// What to compute, and how to treat pixels.
#[derive(Clone, Debug)]
pub struct Request<'a> {
    pub sse: bool,
    pub moments: bool,
    pub hist: Option<HistRequest>,
    /// `false` entries exclude a pixel pair.
    pub mask: Option<&'a [bool]>,
    /// Integer frames: allowed values `[lo, hi]`; anything else is a range error.
    pub valid: Option<(i64, i64)>,
    /// Float frames: exclude non-finite pairs (`true`) or report them as an error.
    pub mask_nonfinite: bool,
    /// `(rows, cols)` and memory order, only to name positions in error messages.
    pub shape: (usize, usize),
    pub fortran: bool,
}

impl Default for Request<'_> {
    fn default() -> Self {
        Request {
            sse: true,
            moments: true,
            hist: Some(HistRequest::Bins { bins: 256, range: None }),
            mask: None,
            valid: None,
            mask_nonfinite: false,
            shape: (0, 0),
            fortran: false,
        }
    }
}

/// Exact sums of an integer pair.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct IntSums {
    pub sr: i128,
    pub ss: i128,
    pub srr: u128,
    pub sss: u128,
    pub srs: i128,
    pub sse: u128,
}

/// Centred sums of a float pair: means, Σ(x−x̄)², Σ(r−r̄)(s−s̄), and a compensated Σ(r−s)².
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FloatSums {
    pub mr: f64,
    pub ms: f64,
    pub m2r: f64,
    pub m2s: f64,
    pub crs: f64,
    pub sse: f64,
    pub sse_c: f64,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Sums {
    Int(IntSums),
    Float(FloatSums),
}

/// Sufficient statistics of a frame pair; mergeable.
#[derive(Clone, Debug, PartialEq)]
pub struct PairStats {
    /// Pixel pairs counted.
    pub n: u64,
    /// Pairs excluded by the mask.
    pub masked: u64,
    /// Pairs excluded because a value was NaN/Inf (`mask_nonfinite`).
    pub nonfinite: u64,
    pub has_sse: bool,
    pub has_moments: bool,
    pub sums: Sums,
    pub hist: Option<(HistSpec, Joint)>,
}

/// Population moments (divided by N).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Moments {
    pub mean_real: f64,
    pub mean_sim: f64,
    pub var_real: f64,
    pub var_sim: f64,
    pub cov: f64,
}

fn position(i: usize, shape: (usize, usize), fortran: bool) -> (usize, usize) {
    let (rows, cols) = (shape.0.max(1), shape.1.max(1));
    if fortran {
        (i % rows, i / rows)
    } else {
        (i / cols, i % cols)
    }
}

/// `a·b − c·d` exactly, as f64 (256-bit intermediate; i128 overflows for long u32 sequences).
fn det_f64(a: i128, b: i128, c: i128, d: i128) -> f64 {
    if let (Some(p), Some(q)) = (a.checked_mul(b), c.checked_mul(d)) {
        if let Some(r) = p.checked_sub(q) {
            return r as f64;
        }
    }
    // Rare path: sign-magnitude 256-bit products.
    fn mul(a: u128, b: u128) -> (u128, u128) {
        let (a1, a0) = (a >> 64, a & u64::MAX as u128);
        let (b1, b0) = (b >> 64, b & u64::MAX as u128);
        let (p00, p01, p10, p11) = (a0 * b0, a0 * b1, a1 * b0, a1 * b1);
        let mid = (p00 >> 64) + (p01 & u64::MAX as u128) + (p10 & u64::MAX as u128);
        let lo = (p00 & u64::MAX as u128) | (mid << 64);
        let hi = p11 + (p01 >> 64) + (p10 >> 64) + (mid >> 64);
        (hi, lo)
    }
    let to_f = |(hi, lo): (u128, u128)| hi as f64 * 2f64.powi(128) + lo as f64;
    let p = mul(a.unsigned_abs(), b.unsigned_abs());
    let q = mul(c.unsigned_abs(), d.unsigned_abs());
    let (sp, sq) = ((a < 0) != (b < 0), (c < 0) != (d < 0));
    // value = ±p − ±q; subtract magnitudes when signs agree
    let sub = |x: (u128, u128), y: (u128, u128)| -> f64 {
        if x >= y {
            let (lo, borrow) = x.1.overflowing_sub(y.1);
            to_f((x.0 - y.0 - borrow as u128, lo))
        } else {
            let (lo, borrow) = y.1.overflowing_sub(x.1);
            -to_f((y.0 - x.0 - borrow as u128, lo))
        }
    };
    match (sp, sq) {
        (false, false) => sub(p, q),
        (true, true) => -sub(p, q),
        (false, true) => to_f(p) + to_f(q),
        (true, false) => -(to_f(p) + to_f(q)),
    }
}

impl PairStats {
    fn empty<T: Sample>(req: &Request) -> PairStats {
        PairStats {
            n: 0,
            masked: 0,
            nonfinite: 0,
            has_sse: req.sse,
            has_moments: req.moments,
            sums: if T::IS_INT { Sums::Int(IntSums::default()) } else { Sums::Float(FloatSums::default()) },
            hist: None,
        }
    }

    /// Σ(r−s)², exact for integer frames (rounded to f64 once).
    pub fn sse(&self) -> Option<f64> {
        if !self.has_sse {
            return None;
        }
        Some(match &self.sums {
            Sums::Int(s) => s.sse as f64,
            Sums::Float(s) => s.sse + s.sse_c,
        })
    }

    /// Mean squared error, paper eq. 5's E[(S−R)²].
    pub fn mse(&self) -> Option<f64> {
        if self.n == 0 {
            return None;
        }
        match &self.sums {
            // one rounding: the exact ratio of two integers
            Sums::Int(s) if self.has_sse => Some(ratio_u128(s.sse, self.n as u128)),
            _ => self.sse().map(|e| e / self.n as f64),
        }
    }

    /// Means, variances and covariance (population), exact-then-rounded for integer frames.
    pub fn moments(&self) -> Option<Moments> {
        if !self.has_moments || self.n == 0 {
            return None;
        }
        let n = self.n as f64;
        Some(match &self.sums {
            Sums::Int(s) => {
                let ni = self.n as i128;
                let nn = n * n;
                Moments {
                    mean_real: s.sr as f64 / n,
                    mean_sim: s.ss as f64 / n,
                    var_real: det_f64(ni, s.srr as i128, s.sr, s.sr) / nn,
                    var_sim: det_f64(ni, s.sss as i128, s.ss, s.ss) / nn,
                    cov: det_f64(ni, s.srs, s.sr, s.ss) / nn,
                }
            }
            Sums::Float(s) => Moments {
                mean_real: s.mr,
                mean_sim: s.ms,
                var_real: s.m2r / n,
                var_sim: s.m2s / n,
                cov: s.crs / n,
            },
        })
    }

    /// The variance numerators `N·Σx² − (Σx)²` etc. are what SSIM's c and s need; for
    /// integer frames they are exact, and their ratios need no N at all.
    /// Returns `(d_real, d_sim, d_cov)` in a common (arbitrary) scale.
    pub fn centred(&self) -> Option<(f64, f64, f64)> {
        if !self.has_moments || self.n == 0 {
            return None;
        }
        Some(match &self.sums {
            Sums::Int(s) => {
                let ni = self.n as i128;
                (
                    det_f64(ni, s.srr as i128, s.sr, s.sr),
                    det_f64(ni, s.sss as i128, s.ss, s.ss),
                    det_f64(ni, s.srs, s.sr, s.ss),
                )
            }
            Sums::Float(s) => (s.m2r, s.m2s, s.crs),
        })
    }

    pub fn entropies(&self) -> Option<Entropies> {
        self.hist.as_ref().map(|(_, j)| j.entropies())
    }

    /// Statistics of the union of both pixel sets. Exact for integer frames.
    pub fn merge(&self, other: &PairStats) -> Result<PairStats> {
        let sums = match (&self.sums, &other.sums) {
            (Sums::Int(a), Sums::Int(b)) => Sums::Int(IntSums {
                sr: a.sr + b.sr,
                ss: a.ss + b.ss,
                srr: a.srr + b.srr,
                sss: a.sss + b.sss,
                srs: a.srs + b.srs,
                sse: a.sse + b.sse,
            }),
            (Sums::Float(a), Sums::Float(b)) => Sums::Float(merge_float(a, self.n, b, other.n)),
            _ => {
                return Err(Error::Value(
                    "cannot merge statistics of integer frames with those of float frames".into(),
                ))
            }
        };
        let hist = match (&self.hist, &other.hist) {
            (Some((sa, ja)), Some((sb, jb))) => {
                hist::check_mergeable(sa, sb)?;
                Some((sa.clone(), ja.merge(jb)))
            }
            (None, None) => None,
            _ => return Err(Error::Value("cannot merge statistics with and without a histogram".into())),
        };
        Ok(PairStats {
            n: self.n + other.n,
            masked: self.masked + other.masked,
            nonfinite: self.nonfinite + other.nonfinite,
            has_sse: self.has_sse && other.has_sse,
            has_moments: self.has_moments && other.has_moments,
            sums,
            hist,
        })
    }
}

/// Compact little-endian encoding, for pickling and shipping between processes (Dask).
impl PairStats {
    const MAGIC: &'static [u8; 4] = b"IFS1";

    pub fn to_bytes(&self) -> Vec<u8> {
        let mut b = Vec::with_capacity(256);
        b.extend_from_slice(Self::MAGIC);
        for v in [self.n, self.masked, self.nonfinite] {
            b.extend_from_slice(&v.to_le_bytes());
        }
        b.push(self.has_sse as u8 | (self.has_moments as u8) << 1);
        match &self.sums {
            Sums::Int(s) => {
                b.push(0);
                for v in [s.sr, s.ss, s.srr as i128, s.sss as i128, s.srs, s.sse as i128] {
                    b.extend_from_slice(&v.to_le_bytes());
                }
            }
            Sums::Float(s) => {
                b.push(1);
                for v in [s.mr, s.ms, s.m2r, s.m2s, s.crs, s.sse, s.sse_c] {
                    b.extend_from_slice(&v.to_le_bytes());
                }
            }
        }
        match &self.hist {
            None => b.push(0),
            Some((spec, joint)) => {
                match spec {
                    HistSpec::Levels => b.push(1),
                    HistSpec::Binned { bins, lo, width } => {
                        b.push(2);
                        b.extend_from_slice(&(*bins as u64).to_le_bytes());
                        b.extend_from_slice(&lo.to_le_bytes());
                        b.extend_from_slice(&width.to_le_bytes());
                    }
                }
                match joint {
                    Joint::Dense { bins, offset, counts } => {
                        b.push(0);
                        b.extend_from_slice(&(*bins as u64).to_le_bytes());
                        b.extend_from_slice(&offset.to_le_bytes());
                        for c in counts {
                            b.extend_from_slice(&c.to_le_bytes());
                        }
                    }
                    Joint::Sparse(runs) => {
                        b.push(1);
                        b.extend_from_slice(&(runs.len() as u64).to_le_bytes());
                        for (k, c) in runs {
                            b.extend_from_slice(&k.to_le_bytes());
                            b.extend_from_slice(&c.to_le_bytes());
                        }
                    }
                }
            }
        }
        b
    }

    pub fn from_bytes(data: &[u8]) -> Result<PairStats> {
        let mut rd = Reader { data, pos: 0 };
        if rd.take(4)? != Self::MAGIC {
            return Err(Reader::bad());
        }
        let (n, masked, nonfinite) = (rd.u64()?, rd.u64()?, rd.u64()?);
        let flags = rd.u8()?;
        let sums = match rd.u8()? {
            0 => Sums::Int(IntSums {
                sr: rd.i128()?,
                ss: rd.i128()?,
                srr: rd.i128()? as u128,
                sss: rd.i128()? as u128,
                srs: rd.i128()?,
                sse: rd.i128()? as u128,
            }),
            1 => Sums::Float(FloatSums {
                mr: rd.f64()?,
                ms: rd.f64()?,
                m2r: rd.f64()?,
                m2s: rd.f64()?,
                crs: rd.f64()?,
                sse: rd.f64()?,
                sse_c: rd.f64()?,
            }),
            _ => return Err(Reader::bad()),
        };
        let hist = match rd.u8()? {
            0 => None,
            tag => {
                let spec = if tag == 1 {
                    HistSpec::Levels
                } else {
                    HistSpec::Binned { bins: rd.u64()? as usize, lo: rd.f64()?, width: rd.f64()? }
                };
                let joint = match rd.u8()? {
                    0 => {
                        let (bins, offset) = (rd.u64()? as usize, rd.u64()?);
                        let len = bins.checked_mul(bins).filter(|&l| l <= rd.remaining() / 8).ok_or_else(Reader::bad)?;
                        let counts = (0..len).map(|_| rd.u64()).collect::<Result<_>>()?;
                        Joint::Dense { bins, offset, counts }
                    }
                    1 => {
                        let len = rd.u64()? as usize;
                        if len > rd.remaining() / 16 {
                            return Err(Reader::bad());
                        }
                        Joint::Sparse((0..len).map(|_| Ok((rd.u64()?, rd.u64()?))).collect::<Result<_>>()?)
                    }
                    _ => return Err(Reader::bad()),
                };
                Some((spec, joint))
            }
        };
        Ok(PairStats { n, masked, nonfinite, has_sse: flags & 1 != 0, has_moments: flags & 2 != 0, sums, hist })
    }
}

struct Reader<'a> {
    data: &'a [u8],
    pos: usize,
}

impl Reader<'_> {
    fn bad() -> Error {
        Error::Value("not a serialized PairStats (corrupt, or written by another version)".into())
    }
    fn remaining(&self) -> usize {
        self.data.len() - self.pos
    }
    fn take(&mut self, k: usize) -> Result<&[u8]> {
        let out = self.data.get(self.pos..self.pos + k).ok_or_else(Self::bad)?;
        self.pos += k;
        Ok(out)
    }
    fn u8(&mut self) -> Result<u8> {
        Ok(self.take(1)?[0])
    }
    fn u64(&mut self) -> Result<u64> {
        Ok(u64::from_le_bytes(self.take(8)?.try_into().unwrap()))
    }
    fn f64(&mut self) -> Result<f64> {
        Ok(f64::from_le_bytes(self.take(8)?.try_into().unwrap()))
    }
    fn i128(&mut self) -> Result<i128> {
        Ok(i128::from_le_bytes(self.take(16)?.try_into().unwrap()))
    }
}

/// `a / b` for u128 rounded to f64 with a single rounding error in the common case.
fn ratio_u128(a: u128, b: u128) -> f64 {
    let q = a / b;
    let r = a % b;
    q as f64 + r as f64 / b as f64
}

fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let bb = s - a;
    (s, (a - (s - bb)) + (b - bb))
}

/// Chan et al.'s pairwise update of centred sums.
fn merge_float(a: &FloatSums, na: u64, b: &FloatSums, nb: u64) -> FloatSums {
    if na == 0 {
        return *b;
    }
    if nb == 0 {
        return *a;
    }
    let (fa, fb) = (na as f64, nb as f64);
    let n = fa + fb;
    let (dr, ds) = (b.mr - a.mr, b.ms - a.ms);
    let w = fa * fb / n;
    let (sse, e) = two_sum(a.sse, b.sse);
    FloatSums {
        mr: a.mr + dr * (fb / n),
        ms: a.ms + ds * (fb / n),
        m2r: a.m2r + b.m2r + dr * dr * w,
        m2s: a.m2s + b.m2s + ds * ds * w,
        crs: a.crs + b.crs + dr * ds * w,
        sse,
        sse_c: a.sse_c + b.sse_c + e,
    }
}

/// How a value becomes a bin index (shared edges for both frames).
struct Binner {
    bins: usize,
    lo: f64,
    width: f64,
    inv_width: f64,
    /// integer frames with ≤ 16-bit types: value − MIN → bin
    lut: Vec<u16>,
}

impl Binner {
    #[inline(always)]
    fn int_bin(&self, v: i64, min: i64) -> usize {
        if !self.lut.is_empty() {
            return self.lut[(v - min) as usize] as usize;
        }
        let b = ((v as f64 - self.lo) / self.width).floor();
        b.clamp(0.0, (self.bins - 1) as f64) as usize
    }

    #[inline(always)]
    fn float_bin(&self, v: f64) -> usize {
        let b = ((v - self.lo) * self.inv_width).floor();
        // NaN never reaches here (excluded or an error); clamp puts the top edge in the last bin
        if b <= 0.0 {
            0
        } else if b >= (self.bins - 1) as f64 {
            self.bins - 1
        } else {
            b as usize
        }
    }
}

/// The histogram layout decided before the pass.
struct HistPlan {
    spec: HistSpec,
    binner: Option<Binner>, // None = levels keyed by value − MIN
    dense_bins: Option<usize>,
    offset: u64, // levels stored densely: key offset of bin 0
}

/// Per-worker accumulator.
struct Acc {
    n: u64,
    int: IntSums,
    float: FloatSums,
    dense: Vec<u32>, // per-worker counts; frames are < 2^32 pixels (checked)
    keys: Vec<u64>,
    runs: Vec<(u64, u64)>,
}

impl Acc {
    fn new(plan: Option<&HistPlan>) -> Acc {
        let dense = match plan.and_then(|p| p.dense_bins) {
            Some(b) => vec![0; b * b],
            None => Vec::new(),
        };
        Acc { n: 0, int: IntSums::default(), float: FloatSums::default(), dense, keys: Vec::new(), runs: Vec::new() }
    }

    #[inline(always)]
    fn count(&mut self, dense_bins: usize, br: usize, bs: usize) {
        if dense_bins > 0 {
            self.dense[br * dense_bins + bs] += 1;
        } else {
            self.keys.push(hist::pack(br as u64, bs as u64));
        }
    }

    fn flush_keys(&mut self) {
        if !self.keys.is_empty() {
            let runs = hist::runs_from_keys(&mut self.keys);
            self.runs = hist::merge_runs(&self.runs, &runs);
            self.keys.clear();
        }
    }

    fn merge(mut self, mut other: Acc, is_int: bool) -> Acc {
        if is_int {
            let (a, b) = (&mut self.int, &other.int);
            a.sr += b.sr;
            a.ss += b.ss;
            a.srr += b.srr;
            a.sss += b.sss;
            a.srs += b.srs;
            a.sse += b.sse;
        } else {
            self.float = merge_float(&self.float, self.n, &other.float, other.n);
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

/// A failure found inside a chunk: the flat index and what was wrong.
enum Bad {
    Range { frame: &'static str, value: i64, index: usize },
    NonFinite { index: usize },
}

fn chunk_ranges(n: usize) -> Vec<(usize, usize)> {
    (0..n.div_ceil(CHUNK)).map(|c| (c * CHUNK, ((c + 1) * CHUNK).min(n))).collect()
}

/// Min and max over the counted pixels of both frames (f64 for floats, exact for ints).
fn data_range<T: Sample>(r: &[T], s: &[T], req: &Request) -> Option<(f64, f64)> {
    let chunks = chunk_ranges(r.len());
    let fold = |(a, b): (usize, usize)| -> (f64, f64) {
        if T::IS_INT && req.mask.is_none() {
            // integers: no finiteness test, a branch-free loop the compiler vectorises
            if a == b {
                return (f64::INFINITY, f64::NEG_INFINITY);
            }
            let (mut lo, mut hi) = (r[a], r[a]);
            for &v in r[a..b].iter().chain(&s[a..b]) {
                lo = if v < lo { v } else { lo };
                hi = if v > hi { v } else { hi };
            }
            return (lo.to_f64(), hi.to_f64());
        }
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for i in a..b {
            if req.mask.is_some_and(|m| !m[i]) {
                continue;
            }
            let (x, y) = (r[i].to_f64(), s[i].to_f64());
            if !(x.is_finite() && y.is_finite()) {
                continue;
            }
            lo = lo.min(x.min(y));
            hi = hi.max(x.max(y));
        }
        (lo, hi)
    };
    let (lo, hi) = chunks
        .into_par_iter()
        .map(fold)
        .reduce(|| (f64::INFINITY, f64::NEG_INFINITY), |a, b| (a.0.min(b.0), a.1.max(b.1)));
    (lo <= hi).then_some((lo, hi))
}

fn plan_hist<T: Sample>(r: &[T], s: &[T], req: &Request, hreq: &HistRequest) -> Result<HistPlan> {
    match hreq {
        HistRequest::Levels => {
            if !T::IS_INT {
                return Err(Error::Value("bins='levels' needs integer frames; use an integer bin count for float frames".into()));
            }
            // A small data span is stored densely (same counts, faster than sorting keys).
            let (lo, hi) = data_range(r, s, req).unwrap_or((0.0, 0.0));
            let span = (hi - lo) as usize + 1;
            let dense = span <= DENSE_MAX_BINS;
            let binner = dense.then(|| make_int_binner::<T>(span, lo as i64, 1));
            Ok(HistPlan {
                spec: HistSpec::Levels,
                binner,
                dense_bins: dense.then_some(span),
                offset: if dense { (lo as i64 - T::MIN) as u64 } else { 0 },
            })
        }
        HistRequest::Bins { bins, range } => {
            let bins = *bins;
            if bins == 0 || bins > (1 << 20) {
                return Err(Error::Value(format!("bins must be between 1 and 1048576, got {bins}")));
            }
            let (lo, hi) = match range {
                Some((lo, hi)) => {
                    if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
                        return Err(Error::Value(format!("hist_range must be finite with lo <= hi, got ({lo}, {hi})")));
                    }
                    if T::IS_INT && (lo.fract() != 0.0 || hi.fract() != 0.0) {
                        return Err(Error::Value(format!(
                            "hist_range for integer frames must be whole grey levels, got ({lo}, {hi})"
                        )));
                    }
                    (*lo, *hi)
                }
                None => data_range(r, s, req).unwrap_or((0.0, 0.0)),
            };
            let binner = if T::IS_INT {
                // a bin is a whole number of grey levels: width = ceil(span / bins)
                let span = (hi - lo) as u64 + 1;
                let width = span.div_ceil(bins as u64).max(1);
                make_int_binner::<T>(bins, lo as i64, width as i64)
            } else {
                let width = (hi - lo) / bins as f64;
                Binner {
                    bins,
                    lo,
                    width,
                    inv_width: if width > 0.0 { 1.0 / width } else { 0.0 },
                    lut: Vec::new(),
                }
            };
            let spec = HistSpec::Binned { bins, lo, width: binner.width };
            Ok(HistPlan { spec, binner: Some(binner), dense_bins: (bins <= DENSE_MAX_BINS).then_some(bins), offset: 0 })
        }
    }
}

fn make_int_binner<T: Sample>(bins: usize, lo: i64, width: i64) -> Binner {
    let bin_of = |v: i64| -> u16 { ((v - lo).max(0) / width).min(bins as i64 - 1) as u16 };
    let lut = (0..T::LUT).map(|k| bin_of(k as i64 + T::MIN)).collect();
    Binner { bins, lo: lo as f64, width: width as f64, inv_width: 1.0 / width as f64, lut }
}

/// The exact integer pass over `[a, b)`.
#[inline(always)]
fn int_chunk<T: Sample, const SSE: bool, const MOM: bool, const HIST: bool>(
    r: &[T],
    s: &[T],
    (a, b): (usize, usize),
    req: &Request,
    plan: Option<&HistPlan>,
    acc: &mut Acc,
) -> std::result::Result<(), Bad> {
    let dense_bins = plan.and_then(|p| p.dense_bins).unwrap_or(0);
    let binner = plan.and_then(|p| p.binner.as_ref());
    let mut start = a;
    while start < b {
        let end = (start + T::BLOCK).min(b);
        let (mut sr, mut ss, mut srs) = (0i64, 0i64, 0i64);
        let (mut srr, mut sss, mut sse) = (0u64, 0u64, 0u64);
        let mut n = 0u64;
        // Moments and SSE first (a branch-free loop the compiler vectorises), then the
        // histogram scatter over the same block while it is still in cache.
        let mut moments = |x: i64, y: i64, acc: &mut Acc| {
            n += 1;
            if SSE {
                let d = x.abs_diff(y);
                sse += d * d;
            }
            if MOM {
                if T::BLOCK == 1 {
                    // 32-bit values: products need 128 bits from the start
                    let t = &mut acc.int;
                    t.sr += x as i128;
                    t.ss += y as i128;
                    t.srr += (x as u128) * (x as u128);
                    t.sss += (y as u128) * (y as u128);
                    t.srs += (x as i128) * (y as i128);
                } else {
                    sr += x;
                    ss += y;
                    srr += x.unsigned_abs() * x.unsigned_abs();
                    sss += y.unsigned_abs() * y.unsigned_abs();
                    srs += x * y;
                }
            }
        };
        let (rr, sb) = (&r[start..end], &s[start..end]);
        match req.mask {
            None => {
                for (&x, &y) in rr.iter().zip(sb) {
                    moments(x.to_i64(), y.to_i64(), acc);
                }
            }
            Some(m) => {
                for ((&x, &y), &keep) in rr.iter().zip(sb).zip(&m[start..end]) {
                    if keep {
                        moments(x.to_i64(), y.to_i64(), acc);
                    }
                }
            }
        }
        if HIST {
            let mut bin = |x: i64, y: i64, acc: &mut Acc| match binner {
                Some(bn) => acc.count(dense_bins, bn.int_bin(x, T::MIN), bn.int_bin(y, T::MIN)),
                None => acc.count(0, (x - T::MIN) as usize, (y - T::MIN) as usize),
            };
            match req.mask {
                None => {
                    for (&x, &y) in rr.iter().zip(sb) {
                        bin(x.to_i64(), y.to_i64(), acc);
                    }
                }
                Some(m) => {
                    for ((&x, &y), &keep) in rr.iter().zip(sb).zip(&m[start..end]) {
                        if keep {
                            bin(x.to_i64(), y.to_i64(), acc);
                        }
                    }
                }
            }
        }
        if let Some((vlo, vhi)) = req.valid {
            // a vectorised min/max first; the scan for the message only on failure
            let (mut lo, mut hi) = (rr[0], rr[0]);
            for &v in rr.iter().chain(sb) {
                // native-width compares (vpminuw & co.), not i64
                lo = if v < lo { v } else { lo };
                hi = if v > hi { v } else { hi };
            }
            let outside = lo.to_i64() < vlo || hi.to_i64() > vhi;
            for i in (start..end).filter(|_| outside) {
                if req.mask.is_some_and(|m| !m[i]) {
                    continue;
                }
                for (frame, v) in [("real", r[i].to_i64()), ("sim", s[i].to_i64())] {
                    if v < vlo || v > vhi {
                        return Err(Bad::Range { frame, value: v, index: i });
                    }
                }
            }
        }
        acc.n += n;
        let t = &mut acc.int;
        t.sse += sse as u128;
        t.sr += sr as i128;
        t.ss += ss as i128;
        t.srr += srr as u128;
        t.sss += sss as u128;
        t.srs += srs as i128;
        start = end;
    }
    Ok(())
}

/// The float pass over `[a, b)`: mean first, then centred sums, on cache-resident data.
fn float_chunk<T: Sample>(
    r: &[T],
    s: &[T],
    (a, b): (usize, usize),
    req: &Request,
    plan: Option<&HistPlan>,
    acc: &mut Acc,
    nonfinite: &mut u64,
) -> std::result::Result<(), Bad> {
    let keep = |i: usize| req.mask.is_none_or(|m| m[i]);
    let (mut n, mut sum_r, mut sum_s) = (0u64, 0.0f64, 0.0f64);
    for i in a..b {
        if !keep(i) {
            continue;
        }
        let (x, y) = (r[i].to_f64(), s[i].to_f64());
        if !(x.is_finite() && y.is_finite()) {
            if req.mask_nonfinite {
                *nonfinite += 1;
                continue;
            }
            return Err(Bad::NonFinite { index: i });
        }
        n += 1;
        sum_r += x;
        sum_s += y;
    }
    if n == 0 {
        return Ok(());
    }
    let nf = n as f64;
    let (mr, ms) = (sum_r / nf, sum_s / nf);
    let (mut dr_sum, mut ds_sum, mut m2r, mut m2s, mut crs) = (0.0f64, 0.0f64, 0.0f64, 0.0f64, 0.0f64);
    let (mut sse, mut sse_c) = (0.0f64, 0.0f64);
    let dense_bins = plan.and_then(|p| p.dense_bins).unwrap_or(0);
    let binner = plan.and_then(|p| p.binner.as_ref());
    for i in a..b {
        if !keep(i) {
            continue;
        }
        let (x, y) = (r[i].to_f64(), s[i].to_f64());
        if !(x.is_finite() && y.is_finite()) {
            continue;
        }
        if req.moments {
            let (dr, ds) = (x - mr, y - ms);
            dr_sum += dr;
            ds_sum += ds;
            m2r += dr * dr;
            m2s += ds * ds;
            crs += dr * ds;
        }
        if req.sse {
            let d = x - y;
            let (t, e) = two_sum(sse, d * d);
            sse = t;
            sse_c += e;
        }
        if let Some(bn) = binner {
            acc.count(dense_bins, bn.float_bin(x), bn.float_bin(y));
        }
    }
    // corrected two-pass: remove the residual of the approximate mean
    let part = FloatSums {
        mr: mr + dr_sum / nf,
        ms: ms + ds_sum / nf,
        m2r: m2r - dr_sum * dr_sum / nf,
        m2s: m2s - ds_sum * ds_sum / nf,
        crs: crs - dr_sum * ds_sum / nf,
        sse,
        sse_c,
    };
    acc.float = merge_float(&acc.float, acc.n, &part, n);
    acc.n += n;
    Ok(())
}

fn run_chunk<T: Sample>(
    r: &[T],
    s: &[T],
    range: (usize, usize),
    req: &Request,
    plan: Option<&HistPlan>,
    acc: &mut Acc,
    nonfinite: &mut u64,
) -> std::result::Result<(), Bad> {
    if !T::IS_INT {
        return float_chunk(r, s, range, req, plan, acc, nonfinite);
    }
    // Monomorphise the hot loop for each combination of requested outputs.
    match (req.sse, req.moments, plan.is_some()) {
        (true, true, true) => int_chunk::<T, true, true, true>(r, s, range, req, plan, acc),
        (true, true, false) => int_chunk::<T, true, true, false>(r, s, range, req, plan, acc),
        (true, false, true) => int_chunk::<T, true, false, true>(r, s, range, req, plan, acc),
        (true, false, false) => int_chunk::<T, true, false, false>(r, s, range, req, plan, acc),
        (false, true, true) => int_chunk::<T, false, true, true>(r, s, range, req, plan, acc),
        (false, true, false) => int_chunk::<T, false, true, false>(r, s, range, req, plan, acc),
        (false, false, true) => int_chunk::<T, false, false, true>(r, s, range, req, plan, acc),
        (false, false, false) => int_chunk::<T, false, false, false>(r, s, range, req, plan, acc),
    }
}

/// Statistics of the frame pair `(r, s)` (same length, same pixel order).
///
/// Runs on the current rayon pool; call it inside `ThreadPool::install` to bound the
/// number of threads.
pub fn pair_stats<T: Sample>(r: &[T], s: &[T], req: &Request) -> Result<PairStats> {
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
    let plan = match &req.hist {
        Some(h) => Some(plan_hist(r, s, req, h)?),
        None => None,
    };
    let plan_ref = plan.as_ref();
    let chunks = chunk_ranges(r.len());
    let result = chunks
        .into_par_iter()
        .try_fold(
            || (Acc::new(plan_ref), 0u64),
            |(mut acc, mut nf), range| {
                run_chunk(r, s, range, req, plan_ref, &mut acc, &mut nf)?;
                if acc.keys.len() >= 1 << 20 {
                    acc.flush_keys();
                }
                Ok((acc, nf))
            },
        )
        .try_reduce(
            || (Acc::new(plan_ref), 0u64),
            |(a, na), (b, nb)| Ok((a.merge(b, T::IS_INT), na + nb)),
        );
    let (mut acc, nonfinite) = match result {
        Ok(v) => v,
        Err(bad) => return Err(describe(bad, r, s, req)),
    };
    acc.flush_keys();
    let masked = req.mask.map_or(0, |m| m.iter().filter(|&&k| !k).count() as u64);
    let mut out = PairStats::empty::<T>(req);
    out.n = acc.n;
    out.masked = masked;
    out.nonfinite = nonfinite;
    out.sums = if T::IS_INT { Sums::Int(acc.int) } else { Sums::Float(acc.float) };
    if let Sums::Float(f) = &out.sums {
        if ![f.mr, f.ms, f.m2r, f.m2s, f.crs, f.sse].iter().all(|v| v.is_finite()) {
            return Err(Error::Range(
                "frame values are too large for float64 statistics (sums overflow); rescale the frames".into(),
            ));
        }
    }
    if let Some(p) = plan {
        let joint = match p.dense_bins {
            Some(b) => Joint::Dense { bins: b, offset: p.offset, counts: acc.dense.iter().map(|&c| c as u64).collect() },
            None => Joint::Sparse(acc.runs),
        };
        out.hist = Some((p.spec, joint));
    }
    Ok(out)
}

fn describe<T: Sample>(bad: Bad, r: &[T], s: &[T], req: &Request) -> Error {
    match bad {
        Bad::Range { frame, value, index } => {
            let (row, col) = position(index, req.shape, req.fortran);
            let (lo, hi) = req.valid.unwrap_or((0, 0));
            Error::Range(format!(
                "{frame} frame: value {value} at (row {row}, col {col}) is outside the valid range [{lo}, {hi}] \
                 (check `bits`/`peak`)"
            ))
        }
        Bad::NonFinite { index } => {
            let keep = |i: usize| req.mask.is_none_or(|m| m[i]);
            let count_r = (0..r.len()).filter(|&i| keep(i) && !r[i].to_f64().is_finite()).count();
            let count_s = (0..s.len()).filter(|&i| keep(i) && !s[i].to_f64().is_finite()).count();
            let (row, col) = position(index, req.shape, req.fortran);
            Error::Range(format!(
                "non-finite values (NaN/Inf): {count_r} in the real frame, {count_s} in the simulated frame; \
                 first at (row {row}, col {col}); pass nonfinite='mask' to exclude those pixel pairs"
            ))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn all() -> Request<'static> {
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
        let bytes = st.to_bytes();
        assert_eq!(PairStats::from_bytes(&bytes).unwrap(), st);
        assert!(PairStats::from_bytes(&bytes[..bytes.len() - 3]).is_err());
        assert!(PairStats::from_bytes(b"nope").is_err());
    }

    #[test]
    fn det_wide_path() {
        let big = i128::MAX / 3;
        let v = det_f64(big, 4, big, 2);
        assert!(((v - 2.0 * big as f64) / v).abs() < 1e-15);
        assert_eq!(det_f64(3, 4, 2, 5), 2.0);
    }
}
