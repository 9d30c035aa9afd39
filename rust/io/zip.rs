//! ZIP / ZIPS block decoding for one channel (OpenEXR's `ImfZip`).
//!
//! A block is zlib data of the block's little-endian bytes after two transforms: the
//! bytes were split into even- and odd-indexed halves, then delta-coded (+128). Undoing
//! them needs the inflate and the running sum over every byte, but not the interleave of
//! every byte: the selected channel's samples are gathered straight from the two halves.
//! Inflate is zlib-rs (flate2), with the inflater and the buffer reused per thread;
//! against the `exr` crate's path (zune-inflate, then the full interleave, an endianness
//! pass and our copy of the channel) this is the cheaper half of EXR ZIP decoding.

use std::cell::RefCell;

use flate2::{Decompress, FlushDecompress, Status};

use super::piz::FromWords;
use super::Reason;

struct Scratch {
    inflater: Decompress,
    bytes: Vec<u8>,
}

thread_local! {
    static SCRATCH: RefCell<Scratch> = RefCell::new(Scratch { inflater: Decompress::new(true), bytes: Vec::new() });
}

fn corrupt(what: &str) -> Reason {
    format!("corrupt OpenEXR ZIP data: {what}")
}

/// Decode the ZIP block `data` of `w` x `h` pixels with `bytes_per_pixel` bytes over all
/// channels, and return the samples of the channel whose bytes start at
/// `offset_per_pixel` within each pixel's worth of a row (the channel's run in a
/// scan line starts at `w * offset_per_pixel`).
pub(super) fn decode_channel<T: FromWords>(
    data: &[u8],
    bytes_per_pixel: usize,
    offset_per_pixel: usize,
    w: usize,
    h: usize,
) -> Result<Vec<T>, Reason> {
    SCRATCH.with(|s| {
        let s = &mut *s.borrow_mut();
        let n = w.checked_mul(h).and_then(|p| p.checked_mul(bytes_per_pixel)).ok_or_else(|| corrupt("block size"))?;
        s.bytes.resize(n, 0);
        s.inflater.reset(true);
        match s.inflater.decompress(data, &mut s.bytes, FlushDecompress::Finish) {
            Ok(Status::StreamEnd) if s.inflater.total_out() == n as u64 => {}
            Ok(_) => return Err(corrupt(&format!("{} bytes inflated, {n} expected", s.inflater.total_out()))),
            Err(e) => return Err(corrupt(&format!("zlib: {e}"))),
        }
        undo_deltas(&mut s.bytes);
        let out = gather::<T>(&s.bytes, bytes_per_pixel, offset_per_pixel, w, h);
        // keep the buffer between blocks, but not a huge one after a file with huge tiles
        if s.bytes.capacity() > KEEP_BYTES {
            s.bytes = Vec::new();
        }
        Ok(out)
    })
}

/// Buffer size kept per thread between blocks (a 2048 x 2048 RGBA float tile and less).
const KEEP_BYTES: usize = 1 << 26;

/// t[i] = t[i-1] + t[i] - 128 (mod 256), eight bytes at a time: a byte-wise prefix sum
/// inside a u64 (three shifted byte-wise adds) plus the carried-in previous byte.
fn undo_deltas(t: &mut [u8]) {
    const LO7: u64 = 0x7f7f_7f7f_7f7f_7f7f;
    const HI: u64 = 0x8080_8080_8080_8080;
    #[inline(always)]
    fn add_bytes(a: u64, b: u64) -> u64 {
        ((a & LO7) + (b & LO7)) ^ ((a ^ b) & HI)
    }
    let Some(&first) = t.first() else { return };
    let mut prev = first; // t[0] is stored as is
    let rest = &mut t[1..];
    let mut chunks = rest.chunks_exact_mut(8);
    for c in &mut chunks {
        let mut x = u64::from_le_bytes((&*c).try_into().unwrap()) ^ HI; // d - 128 == d ^ 0x80 (mod 256)
        x = add_bytes(x, x << 8);
        x = add_bytes(x, x << 16);
        x = add_bytes(x, x << 32);
        x = add_bytes(x, u64::from(prev) * 0x0101_0101_0101_0101);
        c.copy_from_slice(&x.to_le_bytes());
        prev = (x >> 56) as u8;
    }
    for b in chunks.into_remainder() {
        prev = prev.wrapping_add(*b).wrapping_sub(128);
        *b = prev;
    }
}

/// The selected channel's samples from the de-delta'd halves: byte p of the block is
/// `t[p / 2]` for even p and `t[(n + 1) / 2 + p / 2]` for odd p. Sample starts are even
/// (every sample size is 2 or 4), so a sample's bytes alternate low half, high half.
fn gather<T: FromWords>(t: &[u8], bytes_per_pixel: usize, offset_per_pixel: usize, w: usize, h: usize) -> Vec<T> {
    let half = t.len().div_ceil(2);
    let (even, odd) = t.split_at(half);
    let row = w * bytes_per_pixel;
    let mut out = Vec::with_capacity(w * h);
    for r in 0..h {
        let start = (r * row + w * offset_per_pixel) / 2;
        let (e, o) = (&even[start..start + w * T::WORDS], &odd[start..start + w * T::WORDS]);
        if T::WORDS == 1 {
            out.extend(e.iter().zip(o).map(|(&lo, &hi)| T::from_words(u16::from_le_bytes([lo, hi]), 0)));
        } else {
            out.extend(
                e.chunks_exact(2)
                    .zip(o.chunks_exact(2))
                    .map(|(a, b)| T::from_words(u16::from_le_bytes([a[0], b[0]]), u16::from_le_bytes([a[1], b[1]]))),
            );
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::undo_deltas;

    #[test]
    fn undo_deltas_equals_the_running_sum() {
        let mut x: u64 = 12345;
        for n in [0usize, 1, 2, 8, 9, 17, 100, 1001] {
            let data: Vec<u8> = (0..n)
                .map(|_| {
                    x = x.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                    (x >> 56) as u8
                })
                .collect();
            let mut want = data.clone();
            for i in 1..n {
                want[i] = (want[i - 1] as i32 + want[i] as i32 - 128) as u8;
            }
            let mut got = data;
            undo_deltas(&mut got);
            assert_eq!(got, want, "n = {n}");
        }
    }
}
