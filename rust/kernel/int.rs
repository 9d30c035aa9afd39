//! The exact integer pass: u64/i64 sums per block, i128/u128 totals, the joint histogram
//! through a value → bin lookup table. Monomorphised per requested output.

use super::{min_max, Acc, Bad, Pass, Sample};

const LO32: u64 = 0xffff_ffff;

/// The exact integer pass over `[a, b)`.
#[inline(always)]
pub(super) fn int_chunk<T: Sample, const SSE: bool, const MOM: bool, const HIST: bool>(
    pass: &Pass<'_, T>,
    (a, b): (usize, usize),
    acc: &mut Acc,
) -> std::result::Result<(), Bad> {
    let Pass { r, s, req, plan, .. } = *pass;
    let dense_bins = plan.and_then(|p| p.dense_bins).unwrap_or(0);
    let binner = plan.and_then(|p| p.binner.as_ref());
    let mut start = a;
    while start < b {
        let end = (start + T::BLOCK).min(b);
        let (mut sr, mut ss, mut srs) = (0i64, 0i64, 0i64);
        let (mut srr, mut sss, mut sse) = (0u64, 0u64, 0u64);
        // 32-bit frames: sums of x, y and the high halves of x², y², x·y, (x − y)²
        let (mut wr, mut ws, mut wrs) = (0u64, 0u64, 0u64);
        let (mut hrr, mut hss, mut hrs, mut hse) = (0u64, 0u64, 0u64, 0u64);
        let mut n = 0u64;
        // Moments and SSE first (a branch-free loop the compiler vectorises), then the
        // histogram scatter over the same block while it is still in cache. The bodies
        // are macros, not closures, so they inline into both the masked and plain loops.
        macro_rules! moments {
            ($x:expr, $y:expr) => {{
                let (x, y): (i64, i64) = ($x, $y);
                n += 1;
                if SSE {
                    if T::WIDE {
                        // 32-bit values: |x − y| < 2^32, its square fits u64; halves summed apart
                        let d = x.abs_diff(y);
                        let d2 = d * d;
                        sse += d2 & LO32;
                        hse += d2 >> 32;
                    } else {
                        // ≤ 16-bit values: x − y fits i32, its square fits u64 (vpmuldq)
                        let d = (x - y) as i32 as i64;
                        sse += (d * d) as u64;
                    }
                }
                if MOM {
                    if T::WIDE {
                        // 32-bit values (unsigned): squares and products fit u64, halves apart
                        let (ux, uy) = (x as u64, y as u64);
                        let (xx, yy, xy) = (ux * ux, uy * uy, ux * uy);
                        wr += ux;
                        ws += uy;
                        srr += xx & LO32;
                        hrr += xx >> 32;
                        sss += yy & LO32;
                        hss += yy >> 32;
                        wrs += xy & LO32;
                        hrs += xy >> 32;
                    } else {
                        // |values| < 2^16: squares are u32 × u32 → u64 (pmuludq), products fit i64
                        let (ux, uy) = (x.unsigned_abs() as u32 as u64, y.unsigned_abs() as u32 as u64);
                        sr += x;
                        ss += y;
                        srr += ux * ux;
                        sss += uy * uy;
                        srs += (x as i32 as i64) * (y as i32 as i64);
                    }
                }
            }};
        }
        macro_rules! bin {
            ($x:expr, $y:expr) => {{
                let (x, y): (i64, i64) = ($x, $y);
                match binner {
                    Some(bn) => acc.count(dense_bins, bn.int_bin(x, T::MIN), bn.int_bin(y, T::MIN)),
                    None => acc.count(0, (x - T::MIN) as usize, (y - T::MIN) as usize),
                }
            }};
        }
        let (rr, sb) = (&r[start..end], &s[start..end]);
        match req.mask {
            None => {
                if SSE || MOM || !HIST {
                    for (&x, &y) in rr.iter().zip(sb) {
                        moments!(x.to_i64(), y.to_i64());
                    }
                } else {
                    n += rr.len() as u64;
                }
                if HIST {
                    match binner {
                        Some(bn) if dense_bins > 0 && bn.lut.len() == T::LUT && T::LUT > 0 => {
                            // The hot case (8/16-bit frames, dense table): LUT gather + increment.
                            let (lut, dense) = (&bn.lut[..], &mut acc.dense[..]);
                            assert!(bn.bins == dense_bins && dense.len() == dense_bins * dense_bins);
                            for (&x, &y) in rr.iter().zip(sb) {
                                let (i, j) = ((x.to_i64() - T::MIN) as usize, (y.to_i64() - T::MIN) as usize);
                                // SAFETY: `lut` has one entry per value of T (len == T::LUT, checked
                                // above) and `make_int_binner` clamps every entry below bn.bins ==
                                // dense_bins, so both indices are in range.
                                unsafe {
                                    let k =
                                        *lut.get_unchecked(i) as usize * dense_bins + *lut.get_unchecked(j) as usize;
                                    *dense.get_unchecked_mut(k) += 1;
                                }
                            }
                        }
                        _ => {
                            for (&x, &y) in rr.iter().zip(sb) {
                                bin!(x.to_i64(), y.to_i64());
                            }
                        }
                    }
                }
            }
            Some(m) => {
                for ((&x, &y), &keep) in rr.iter().zip(sb).zip(&m[start..end]) {
                    if keep {
                        moments!(x.to_i64(), y.to_i64());
                        if HIST {
                            bin!(x.to_i64(), y.to_i64());
                        }
                    }
                }
            }
        }
        if let Some((vlo, vhi)) = req.valid {
            // a vectorised min/max first; the scan for the message only on failure
            let outside = min_max(rr, sb).is_some_and(|(lo, hi)| lo.to_i64() < vlo || hi.to_i64() > vhi);
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
        let join = |lo: u64, hi: u64| lo as u128 + ((hi as u128) << 32);
        let t = &mut acc.int;
        t.sse += join(sse, hse);
        t.sr += sr as i128 + wr as i128;
        t.ss += ss as i128 + ws as i128;
        t.srr += join(srr, hrr);
        t.sss += join(sss, hss);
        t.srs += srs as i128 + join(wrs, hrs) as i128;
        start = end;
    }
    Ok(())
}
