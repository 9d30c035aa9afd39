//! Compact little-endian encoding of [`NoiseSums`], for pickling and shipping partial
//! results between processes (Dask). Lengths are checked against the bytes present
//! before anything is allocated, so a corrupt or hostile buffer is an error, not an abort.

use std::sync::Arc;

use super::exact::{IntAcc, PixelSq};
use super::float::FloatAcc;
use super::{Acc, Dtype, NoiseSums, MAX_FRAMES};
use crate::{Error, Result};

const MAGIC: &[u8; 4] = b"IFN1";

fn bad() -> Error {
    Error::Value("not serialized 3-D noise sums (corrupt, or written by another version)".into())
}

struct Writer(Vec<u8>);

impl Writer {
    fn put(&mut self, b: &[u8]) {
        self.0.extend_from_slice(b);
    }
    fn u64(&mut self, v: u64) {
        self.put(&v.to_le_bytes());
    }
    fn i64s(&mut self, v: &[i64]) {
        v.iter().for_each(|x| self.put(&x.to_le_bytes()));
    }
    fn f64s(&mut self, v: &[f64]) {
        v.iter().for_each(|x| self.put(&x.to_le_bytes()));
    }
}

struct Reader<'a> {
    data: &'a [u8],
    pos: usize,
}

impl Reader<'_> {
    fn take(&mut self, k: usize) -> Result<&[u8]> {
        let end = self.pos.checked_add(k).ok_or_else(bad)?;
        let out = self.data.get(self.pos..end).ok_or_else(bad)?;
        self.pos = end;
        Ok(out)
    }
    fn arr<const K: usize>(&mut self) -> Result<[u8; K]> {
        Ok(self.take(K)?.try_into().expect("K bytes"))
    }
    fn u8(&mut self) -> Result<u8> {
        Ok(self.take(1)?[0])
    }
    fn u64(&mut self) -> Result<u64> {
        Ok(u64::from_le_bytes(self.arr()?))
    }
    fn usize(&mut self) -> Result<usize> {
        usize::try_from(self.u64()?).map_err(|_| bad())
    }
    fn i64(&mut self) -> Result<i64> {
        Ok(i64::from_le_bytes(self.arr()?))
    }
    fn f64(&mut self) -> Result<f64> {
        Ok(f64::from_le_bytes(self.arr()?))
    }
    /// Room for `count` values of `width` bytes, checked before allocating.
    fn room(&self, count: usize, width: usize) -> Result<()> {
        match count.checked_mul(width) {
            Some(b) if b <= self.data.len() - self.pos => Ok(()),
            _ => Err(bad()),
        }
    }
    fn i64s(&mut self, count: usize) -> Result<Vec<i64>> {
        self.room(count, 8)?;
        (0..count).map(|_| self.i64()).collect()
    }
    fn u64s(&mut self, count: usize) -> Result<Vec<u64>> {
        self.room(count, 8)?;
        (0..count).map(|_| self.u64()).collect()
    }
    fn u128s(&mut self, count: usize) -> Result<Vec<u128>> {
        self.room(count, 16)?;
        (0..count).map(|_| Ok(u128::from_le_bytes(self.arr()?))).collect()
    }
    fn f64s(&mut self, count: usize) -> Result<Vec<f64>> {
        self.room(count, 8)?;
        (0..count).map(|_| self.f64()).collect()
    }
}

impl NoiseSums {
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut w = Writer(Vec::new());
        w.put(MAGIC);
        w.u64(self.rows as u64);
        w.u64(self.cols as u64);
        w.u64(self.frames as u64);
        w.put(&[Dtype::ALL.iter().position(|&d| d == self.dtype).expect("known dtype") as u8]);
        match &self.acc {
            Acc::Int(a) => {
                w.i64s(&[a.lo, a.hi, a.min, a.max]);
                w.u64(a.at_lo);
                w.u64(a.at_hi);
                w.i64s(&a.pixel_sum);
                match &a.pixel_sq {
                    PixelSq::Narrow(q) => q.iter().for_each(|x| w.u64(*x)),
                    PixelSq::Wide(q) => q.iter().for_each(|x| w.put(&x.to_le_bytes())),
                }
                w.i64s(&a.row_sums);
                w.i64s(&a.col_sums);
            }
            Acc::Float(a) => {
                w.f64s(&[a.min, a.max, a.max_abs]);
                w.put(&[!a.pivot.is_empty() as u8]);
                if !a.pivot.is_empty() {
                    for v in [a.pivot.as_slice(), &a.sum, &a.sum_c, &a.sq, &a.sq_c] {
                        w.f64s(v);
                    }
                }
                w.f64s(&a.row_sums);
                w.f64s(&a.col_sums);
            }
        }
        w.0
    }

    pub fn from_bytes(data: &[u8]) -> Result<NoiseSums> {
        let mut rd = Reader { data, pos: 0 };
        if rd.take(4)? != MAGIC {
            return Err(bad());
        }
        let (rows, cols, frames) = (rd.usize()?, rd.usize()?, rd.usize()?);
        let dtype = *Dtype::ALL.get(rd.u8()? as usize).ok_or_else(bad)?;
        if rows == 0 || cols == 0 || frames > MAX_FRAMES {
            return Err(bad());
        }
        let pixels = rows.checked_mul(cols).ok_or_else(bad)?;
        let row_len = frames.checked_mul(rows).ok_or_else(bad)?;
        let col_len = frames.checked_mul(cols).ok_or_else(bad)?;
        let acc = if dtype.is_int() {
            let (lo, hi, min, max) = (rd.i64()?, rd.i64()?, rd.i64()?, rd.i64()?);
            let (at_lo, at_hi) = (rd.u64()?, rd.u64()?);
            let pixel_sum = rd.i64s(pixels)?;
            let pixel_sq =
                if dtype == Dtype::U32 { PixelSq::Wide(rd.u128s(pixels)?) } else { PixelSq::Narrow(rd.u64s(pixels)?) };
            let row_sums = rd.i64s(row_len)?;
            let col_sums = rd.i64s(col_len)?;
            // sums no pass over such frames could produce would overflow the exact arithmetic
            let (tmin, tmax) = dtype.int_range().ok_or_else(bad)?;
            let bound = tmin.unsigned_abs().max(tmax.unsigned_abs()) as u128;
            let within = |v: &[i64], count: usize| v.iter().all(|x| x.unsigned_abs() as u128 <= count as u128 * bound);
            let sq_ok = match &pixel_sq {
                PixelSq::Narrow(q) => q.iter().all(|&x| x as u128 <= frames as u128 * bound * bound),
                PixelSq::Wide(q) => q.iter().all(|&x| x <= frames as u128 * bound * bound),
            };
            if !(within(&pixel_sum, frames) && within(&row_sums, cols) && within(&col_sums, rows) && sq_ok)
                || lo < tmin
                || hi > tmax
                || lo > hi
            {
                return Err(bad());
            }
            Acc::Int(IntAcc { pixel_sum, pixel_sq, row_sums, col_sums, lo, hi, at_lo, at_hi, min, max })
        } else {
            let (min, max, max_abs) = (rd.f64()?, rd.f64()?, rd.f64()?);
            let has_pivot = rd.u8()? != 0;
            if has_pivot != (frames > 0) {
                return Err(bad());
            }
            let mut maps = Vec::new();
            if has_pivot {
                for _ in 0..5 {
                    maps.push(rd.f64s(pixels)?);
                }
            } else {
                maps.resize(5, Vec::new());
            }
            let mut maps = maps.into_iter();
            let mut next = || maps.next().expect("five maps");
            let pivot = Arc::new(next());
            let (sum, sum_c, sq, sq_c) = (next(), next(), next(), next());
            let row_sums = rd.f64s(row_len)?;
            let col_sums = rd.f64s(col_len)?;
            let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
            if !([&pivot[..], &sum, &sum_c, &sq, &sq_c, &row_sums, &col_sums].iter().all(|v| finite(v))
                && max_abs.is_finite())
            {
                return Err(bad());
            }
            Acc::Float(FloatAcc { pivot, sum, sum_c, sq, sq_c, row_sums, col_sums, min, max, max_abs })
        };
        if rd.pos != data.len() {
            return Err(bad());
        }
        Ok(NoiseSums { rows, cols, frames, dtype, acc })
    }
}
