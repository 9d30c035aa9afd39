//! [`PairStats`]: sufficient statistics of a frame pair, the one value every image
//! metric is computed from. Mergeable (`a.merge(b)` = statistics of the union; exact
//! for integer frames) and serialisable, so chunks, the frames of a sequence and Dask
//! workers all combine through it. The pass that produces it is in [`crate::kernel`].
//!
//! Integer frames carry exact sums (i128/u128), so MSE, variances and covariance are
//! exact rationals rounded to f64 once. Float frames carry centred sums (means, M2,
//! co-moment) merged with Chan's update and a Neumaier-compensated SSE.

use crate::error::{Error, Result};
use crate::hist::{self, Entropies, HistSpec, Joint};

pub use crate::kernel::{pair_stats, HistRequest, Request, Sample};

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
    /// The real frame's min and max, when the pass's scan read every pixel of it (float
    /// frames with moments and a histogram, no mask, every value finite); neither merged nor
    /// encoded.
    pub real_range: Option<(f64, f64)>,
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

/// `a·b − c·d` exactly, as f64 (256-bit intermediate; i128 overflows for long u32 sequences).
pub(crate) fn det_f64(a: i128, b: i128, c: i128, d: i128) -> f64 {
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
    pub(crate) fn empty<T: Sample>(req: &Request) -> PairStats {
        PairStats {
            n: 0,
            masked: 0,
            nonfinite: 0,
            has_sse: req.sse,
            has_moments: req.moments,
            sums: if T::IS_INT { Sums::Int(IntSums::default()) } else { Sums::Float(FloatSums::default()) },
            hist: None,
            real_range: None,
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
            Sums::Float(s) => {
                Moments { mean_real: s.mr, mean_sim: s.ms, var_real: s.m2r / n, var_sim: s.m2s / n, cov: s.crs / n }
            }
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
                return Err(Error::Value("cannot merge statistics of integer frames with those of float frames".into()))
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
            real_range: None,
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
                    HistSpec::Each { bins, real, sim } => {
                        b.push(3);
                        b.extend_from_slice(&(*bins as u64).to_le_bytes());
                        for v in [real.0, real.1, sim.0, sim.1] {
                            b.extend_from_slice(&v.to_le_bytes());
                        }
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
                let spec = match tag {
                    1 => HistSpec::Levels,
                    2 => HistSpec::Binned { bins: rd.u64()? as usize, lo: rd.f64()?, width: rd.f64()? },
                    3 => HistSpec::Each {
                        bins: rd.u64()? as usize,
                        real: (rd.f64()?, rd.f64()?),
                        sim: (rd.f64()?, rd.f64()?),
                    },
                    _ => return Err(Reader::bad()),
                };
                let joint = match rd.u8()? {
                    0 => {
                        let (bins, offset) = (rd.u64()? as usize, rd.u64()?);
                        let len =
                            bins.checked_mul(bins).filter(|&l| l <= rd.remaining() / 8).ok_or_else(Reader::bad)?;
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
        let (has_sse, has_moments) = (flags & 1 != 0, flags & 2 != 0);
        Ok(PairStats { n, masked, nonfinite, has_sse, has_moments, sums, hist, real_range: None })
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

#[inline(always)]
pub(crate) fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let bb = s - a;
    (s, (a - (s - bb)) + (b - bb))
}

/// Neumaier-compensated running sum: `sum` plus the rounding errors collected in `comp`.
#[derive(Clone, Copy, Default)]
pub(crate) struct Neumaier {
    pub(crate) sum: f64,
    pub(crate) comp: f64,
}

impl Neumaier {
    #[inline(always)]
    pub(crate) fn add(&mut self, x: f64) {
        let (s, e) = two_sum(self.sum, x);
        self.sum = s;
        self.comp += e;
    }
    pub(crate) fn value(&self) -> f64 {
        self.sum + self.comp
    }
    /// Add another compensated total (both parts).
    pub(crate) fn merge(&mut self, other: &Neumaier) {
        self.add(other.sum);
        self.add(other.comp);
    }
}

/// Neumaier-compensated sum of a sequence.
pub(crate) fn compensated_sum(values: impl Iterator<Item = f64>) -> f64 {
    let mut acc = Neumaier::default();
    values.for_each(|v| acc.add(v));
    acc.value()
}

/// Chan et al.'s pairwise update of centred sums.
pub(crate) fn merge_float(a: &FloatSums, na: u64, b: &FloatSums, nb: u64) -> FloatSums {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn det_wide_path() {
        let big = i128::MAX / 3;
        let v = det_f64(big, 4, big, 2);
        assert!(((v - 2.0 * big as f64) / v).abs() < 1e-15);
        assert_eq!(det_f64(3, 4, 2, 5), 2.0);
    }
}
