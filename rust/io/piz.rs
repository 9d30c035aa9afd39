//! PIZ block decoding for one channel (OpenEXR's `ImfPizCompressor` + `ImfHuf` + `ImfWav`).
//!
//! Why our own: the `exr` crate decodes PIZ at about half OpenEXR's speed (a byte-at-a-time
//! Huffman reader over a 400 KB table of enums, rebuilt per block, and a list search per
//! long code) and wavelet-decodes and converts every channel. Here the Huffman stream is
//! read through a 64-bit window, up to four codes per window, with a 16 KB first-level
//! table that stays in L1 cache; longer codes are found from the canonical code bases by
//! length (as OpenEXR's `FastHufDecoder` does); tables are per thread and reused between
//! blocks; only the selected channel is wavelet-decoded and mapped back through the
//! value table.
//!
//! Every step follows OpenEXR's reference decoder, including its checks (a short code
//! that overlaps another in the table, run-lengths past the end, a wrong symbol count
//! are all errors); nothing here can index out of bounds on hostile input.

use std::cell::RefCell;

use half::f16;

use super::Reason;

const U16_RANGE: usize = 1 << 16;
const BITMAP_SIZE: usize = U16_RANGE >> 3;
const ENC_SIZE: usize = U16_RANGE + 1; // HUF_ENCSIZE: symbols 0..=65536
/// OpenEXR's HUF_DECBITS: the main decoding phase runs while this many bits remain.
const DEC_BITS: u32 = 14;
/// Bits of our first-level table: 4096 entries (16 KB) stay in L1 cache; longer codes
/// are found by length (`long_code`).
const TABLE_BITS: u32 = 12;
const DEC_SIZE: usize = 1 << TABLE_BITS;
const SHORT_ZEROCODE_RUN: u64 = 59;
const LONG_ZEROCODE_RUN: u64 = 63;
const SHORTEST_LONG_RUN: usize = 2 + (LONG_ZEROCODE_RUN - SHORT_ZEROCODE_RUN) as usize;
/// Decoding-table entry flag: the 14-bit prefix starts one or more long codes.
const LONG: u32 = 1 << 31;

fn corrupt(what: &str) -> Reason {
    format!("corrupt OpenEXR PIZ data: {what}")
}

/// Huffman tables: codes per symbol, the 14-bit decoding table, and the long codes
/// (> 14 bits) by length: canonical codes of one length are consecutive integers from
/// `base[l]`, given to symbols in increasing order, so a long code is found from the
/// lengths alone (as OpenEXR's `FastHufDecoder` does) instead of a list search.
struct Tables {
    hcode: Vec<u64>,
    /// Symbols with a code (length > 0), in increasing order; only their `hcode` is valid.
    used: Vec<u32>,
    dec: Vec<u32>,
    base: [u64; 59],
    /// `base`, or u64::MAX for lengths without codes (skipped by the search).
    search_base: [u64; 59],
    count: [u64; 59],
    first: [usize; 59],
    long_syms: Vec<u32>,
}

/// Per-thread buffers, kept between blocks (the encoding table alone is 512 KB).
struct Scratch {
    tables: Tables,
    lut: Vec<u16>,
    /// Entries of `lut` past this index are 0.
    lut_len: usize,
    input: Vec<u8>,
    tmp: Vec<u16>,
}

thread_local! {
    static SCRATCH: RefCell<Scratch> = RefCell::new(Scratch {
        tables: Tables {
            hcode: vec![0; ENC_SIZE],
            used: Vec::new(),
            dec: vec![0; DEC_SIZE],
            base: [0; 59],
            search_base: [0; 59],
            count: [0; 59],
            first: [0; 59],
            long_syms: Vec::new(),
        },
        lut: vec![0; U16_RANGE],
        lut_len: 0,
        input: Vec::new(),
        tmp: Vec::new(),
    });
}

/// A sample type stored as 16-bit words in PIZ data (low half first).
pub(super) trait FromWords: Sized {
    const WORDS: usize;
    fn from_words(lo: u16, hi: u16) -> Self;
}

impl FromWords for f16 {
    const WORDS: usize = 1;
    #[inline]
    fn from_words(lo: u16, _: u16) -> Self {
        f16::from_bits(lo)
    }
}

impl FromWords for f32 {
    const WORDS: usize = 2;
    #[inline]
    fn from_words(lo: u16, hi: u16) -> Self {
        f32::from_bits(lo as u32 | (hi as u32) << 16)
    }
}

impl FromWords for u32 {
    const WORDS: usize = 2;
    #[inline]
    fn from_words(lo: u16, hi: u16) -> Self {
        lo as u32 | (hi as u32) << 16
    }
}

/// Little-endian reader over the block bytes.
struct Bytes<'a>(&'a [u8]);

impl<'a> Bytes<'a> {
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], Reason> {
        if self.0.len() < n {
            return Err(corrupt(&format!("block ends inside the {what}")));
        }
        let (head, rest) = self.0.split_at(n);
        self.0 = rest;
        Ok(head)
    }
    fn u16(&mut self, what: &str) -> Result<u16, Reason> {
        let b = self.take(2, what)?;
        Ok(u16::from_le_bytes([b[0], b[1]]))
    }
    fn u32(&mut self, what: &str) -> Result<u32, Reason> {
        let b = self.take(4, what)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }
}

/// Decode the PIZ block `data` of `w` x `h` pixels whose channels have `words[c]` 16-bit
/// words per sample (1 for half, 2 for float/uint; file order), and return channel
/// `selected`'s samples, row-major.
pub(super) fn decode_channel<T: FromWords>(
    data: &[u8],
    words: &[usize],
    selected: usize,
    w: usize,
    h: usize,
) -> Result<Vec<T>, Reason> {
    debug_assert_eq!(words[selected], T::WORDS);
    SCRATCH.with(|s| {
        let s = &mut *s.borrow_mut();
        let out = decode_with(s, data, words, selected, w, h);
        // keep scratch between blocks, but not a huge one after a file with huge tiles
        if s.tmp.capacity() > KEEP_WORDS {
            s.tmp = Vec::new();
            s.input = Vec::new();
        }
        out
    })
}

/// Scratch sizes kept per thread between blocks (a 2048 x 2048 RGBA float tile and less).
const KEEP_WORDS: usize = 1 << 25;

fn decode_with<T: FromWords>(
    s: &mut Scratch,
    data: &[u8],
    words: &[usize],
    selected: usize,
    w: usize,
    h: usize,
) -> Result<Vec<T>, Reason> {
    let pixels = w.checked_mul(h).ok_or_else(|| corrupt("block size"))?;
    let total = pixels.checked_mul(words.iter().sum()).ok_or_else(|| corrupt("block size"))?;
    let start: usize = words[..selected].iter().map(|k| k * pixels).sum();
    let k = T::WORDS;

    let mut r = Bytes(data);
    let min_nz = r.u16("value bitmap")? as usize;
    let max_nz = r.u16("value bitmap")? as usize;
    if max_nz >= BITMAP_SIZE || min_nz >= BITMAP_SIZE {
        return Err(corrupt("value bitmap bounds"));
    }
    let mut bitmap = [0u8; BITMAP_SIZE];
    if min_nz <= max_nz {
        bitmap[min_nz..=max_nz].copy_from_slice(r.take(max_nz - min_nz + 1, "value bitmap")?);
    }
    let max_value = reverse_lut(&bitmap, min_nz, max_nz, &mut s.lut, &mut s.lut_len);

    let length = r.u32("Huffman length")? as i32;
    if length < 0 || length as usize > r.0.len() {
        return Err(corrupt("Huffman length exceeds the block"));
    }
    let huf = &r.0[..length as usize];

    // Every word is overwritten by the Huffman decoder (or it fails): no zeroing.
    s.tmp.resize(total, 0);
    huffman(s, huf)?;

    let region = &mut s.tmp[start..start + pixels * k];
    for j in 0..k {
        wavelet_decode(&mut region[j..], w, k, h, w * k, max_value);
    }
    let lut: &[u16; U16_RANGE] = s.lut[..].try_into().expect("lut has 2^16 entries");
    Ok(if k == 1 {
        region.iter().map(|&v| T::from_words(lut[v as usize], 0)).collect()
    } else {
        region.chunks_exact(2).map(|c| T::from_words(lut[c[0] as usize], lut[c[1] as usize])).collect()
    })
}

/// `reverseLutFromBitmap`: value k of the transformed data stands for the k-th value
/// present in the bitmap (0 is always present; bytes outside min..=max are 0), the
/// rest of the table is 0. Returns the largest k.
fn reverse_lut(bitmap: &[u8; BITMAP_SIZE], min: usize, max: usize, lut: &mut [u16], lut_len: &mut usize) -> u16 {
    lut[0] = 0;
    let mut k = 1usize;
    if min <= max {
        for (byte, &bits) in bitmap.iter().enumerate().take(max + 1).skip(min) {
            let mut b = bits;
            if byte == 0 {
                b &= !1; // value 0 is already entry 0
            }
            while b != 0 {
                lut[k] = (byte * 8 + b.trailing_zeros() as usize) as u16;
                k += 1;
                b &= b - 1;
            }
        }
    }
    if *lut_len > k {
        lut[k..*lut_len].fill(0);
    }
    *lut_len = k;
    (k - 1) as u16
}

/// `hufUncompress` into `s.tmp` (whose length is the expected symbol count).
fn huffman(s: &mut Scratch, data: &[u8]) -> Result<(), Reason> {
    if data.len() < 20 {
        return if s.tmp.is_empty() { Ok(()) } else { Err(corrupt("Huffman header too short")) };
    }
    let mut r = Bytes(data);
    let im = r.u32("Huffman header")? as usize;
    let i_max = r.u32("Huffman header")? as usize;
    let _table_len = r.u32("Huffman header")?;
    let n_bits = r.u32("Huffman header")? as usize;
    let _ = r.u32("Huffman header")?;
    if im >= ENC_SIZE || i_max >= ENC_SIZE {
        return Err(corrupt("Huffman table bounds"));
    }
    if n_bits.div_ceil(8) > r.0.len() {
        return Err(corrupt("Huffman bit count exceeds the block"));
    }
    let t = &mut s.tables;
    let rest = unpack_code_lengths(t, r.0, im, i_max)?;
    if n_bits > 8 * rest.len() {
        return Err(corrupt("Huffman bit count exceeds the block"));
    }
    canonical_codes(t);
    build_decoding_table(t)?;

    // The stream, padded so that 16-byte windows never run past the end.
    let n_bytes = n_bits.div_ceil(8);
    s.input.clear();
    s.input.extend_from_slice(&rest[..n_bytes]);
    s.input.resize(n_bytes + 16, 0);
    decode_symbols(&s.tables, &s.input, n_bits, i_max as u32, &mut s.tmp)
}

/// `hufUnpackEncTable`: 6-bit code lengths with zero-run codes, for symbols im..=i_max.
/// Returns the bytes after the table.
fn unpack_code_lengths<'a>(t: &mut Tables, data: &'a [u8], im: usize, i_max: usize) -> Result<&'a [u8], Reason> {
    t.used.clear();
    let mut bp = 0usize; // bits consumed
    let mut bits = |n: u32| -> Result<u64, Reason> {
        let i = bp >> 3;
        let v = if i + 8 <= data.len() {
            u64::from_be_bytes(data[i..i + 8].try_into().unwrap()) << (bp & 7)
        } else {
            if bp + n as usize > data.len() * 8 {
                return Err(corrupt("code table ends early"));
            }
            let mut b = [0u8; 8];
            b[..data.len() - i].copy_from_slice(&data[i..]);
            u64::from_be_bytes(b) << (bp & 7)
        };
        bp += n as usize;
        Ok(v >> (64 - n))
    };
    let mut i = im;
    while i <= i_max {
        let l = bits(6)?;
        let run = if l == LONG_ZEROCODE_RUN {
            bits(8)? as usize + SHORTEST_LONG_RUN
        } else if l >= SHORT_ZEROCODE_RUN {
            (l - SHORT_ZEROCODE_RUN) as usize + 2
        } else {
            if l > 0 {
                t.hcode[i] = l;
                t.used.push(i as u32);
            }
            i += 1;
            continue;
        };
        if i + run > i_max + 1 {
            return Err(corrupt("code table too long"));
        }
        i += run;
    }
    Ok(&data[bp.div_ceil(8)..])
}

/// `hufCanonicalCodeTable` over the used symbols (every other has length 0): replace
/// each length l by (code << 6) | l, and keep each length's first code and count.
fn canonical_codes(t: &mut Tables) {
    let mut n = [0u64; 59];
    for &sym in &t.used {
        n[t.hcode[sym as usize] as usize] += 1;
    }
    t.count = n;
    let mut c = 0u64;
    for i in (1..=58).rev() {
        let nc = (c + n[i]) >> 1;
        n[i] = c;
        c = nc;
    }
    t.base = n;
    for &sym in &t.used {
        let code = &mut t.hcode[sym as usize];
        let l = *code as usize;
        *code = l as u64 | (n[l] << 6);
        n[l] += 1;
    }
}

#[inline]
fn code_len(e: u64) -> u32 {
    (e & 63) as u32
}

#[inline]
fn code_bits(e: u64) -> u64 {
    e >> 6
}

/// `hufBuildDecTable`: short codes (≤ 12 bits here, 14 in OpenEXR) fill all table slots
/// they prefix, as (symbol << 6) | length; a long code's 12-bit prefix is marked `LONG`
/// with the shortest length under it, and its symbol goes to `long_syms`, grouped by
/// length in symbol order.
fn build_decoding_table(t: &mut Tables) -> Result<(), Reason> {
    t.dec.fill(0);
    let mut total = 0usize;
    for l in (TABLE_BITS as usize + 1)..=58 {
        t.first[l] = total;
        total += t.count[l] as usize;
        t.search_base[l] = if t.count[l] > 0 { t.base[l] } else { u64::MAX };
    }
    let mut next = t.first;
    t.long_syms.clear();
    t.long_syms.resize(total, 0);
    for &sym in &t.used {
        let e = t.hcode[sym as usize];
        let (c, l) = (code_bits(e), code_len(e));
        if c >> l != 0 {
            return Err(corrupt("invalid code table entry"));
        }
        if l > TABLE_BITS {
            let prefix = (c >> (l - TABLE_BITS)) as usize;
            let slot = &mut t.dec[prefix];
            if *slot & 63 != 0 {
                return Err(corrupt("invalid code table entry"));
            }
            if *slot == 0 || (*slot >> 6) & 63 > l {
                *slot = LONG | l << 6;
            }
            t.long_syms[next[l as usize]] = sym;
            next[l as usize] += 1;
        } else if l != 0 {
            let first = (c << (TABLE_BITS - l)) as usize;
            let entry = (sym << 6) | l;
            for slot in &mut t.dec[first..first + (1 << (TABLE_BITS - l))] {
                if *slot != 0 {
                    return Err(corrupt("invalid code table entry"));
                }
                *slot = entry;
            }
        }
    }
    Ok(())
}

/// The 64 bits of the stream starting at bit `pos` (MSB first).
#[inline(always)]
fn window(input: &[u8], pos: usize) -> u64 {
    let i = pos >> 3;
    let b: [u8; 8] = input[i..i + 8].try_into().unwrap();
    u64::from_be_bytes(b) << (pos & 7)
}

/// The `l` ≤ 58 bits of the stream starting at bit `pos`.
#[inline]
fn bits_at(input: &[u8], pos: usize, l: u32) -> u64 {
    let i = pos >> 3;
    let b: [u8; 16] = input[i..i + 16].try_into().unwrap();
    let v = u128::from_be_bytes(b) << (pos & 7);
    (v >> (128 - l)) as u64
}

/// The long code at bit `pos` whose first-table entry is `e` (flag `LONG`, the shortest
/// code length under that prefix in bits 6..): the shortest length l whose first code
/// is ≤ the next l bits (canonical codes of greater length lie below). `wdw` is
/// `window(input, pos)`. Returns (symbol, length).
#[inline]
fn long_code(t: &Tables, e: u32, wdw: u64, input: &[u8], pos: usize) -> Option<(u32, u32)> {
    let mut l = (e >> 6) & 63;
    while l <= 58 {
        let li = l as usize;
        // The window holds ≥ 57 valid bits; 58-bit codes read further.
        let v = if l <= 57 { wdw >> (64 - l) } else { bits_at(input, pos, l) };
        if v >= t.search_base[li] {
            let k = v - t.base[li];
            return (k < t.count[li]).then(|| (t.long_syms[t.first[li] + k as usize], l));
        }
        l += 1;
    }
    None
}

/// `hufDecode`: symbols into `out` (exactly `out.len()` of them); `rlc` is the
/// run-length symbol, followed by an 8-bit repeat count of the previous value.
fn decode_symbols(t: &Tables, input: &[u8], n_bits: usize, rlc: u32, out: &mut [u16]) -> Result<(), Reason> {
    let end = (input.len() - 16) * 8; // all bits of the bytes holding the stream
    let mut pos = 0usize;
    let mut n = 0usize;

    // Main phase (OpenEXR reads whole bytes): while 14 bits remain in those bytes.
    while end - pos >= DEC_BITS as usize {
        // Fast path: one 64-bit window (≥ 57 valid bits) serves up to four short codes
        // (≤ 56 bits), so the serial chain per symbol is one table load and one shift.
        // A long code, a run or a full output goes to the general step below.
        if end - pos >= 64 {
            let mut wdw = window(input, pos);
            let mut k = 0;
            while k < 4 {
                let e = t.dec[(wdw >> (64 - TABLE_BITS)) as usize];
                let l = e & 63;
                if l == 0 || e >> 6 == rlc || n >= out.len() {
                    break;
                }
                out[n] = (e >> 6) as u16;
                n += 1;
                pos += l as usize;
                wdw <<= l;
                k += 1;
            }
            if k == 4 {
                continue;
            }
        }
        let wdw = window(input, pos);
        let e = t.dec[(wdw >> (64 - TABLE_BITS)) as usize];
        let l = e & 63;
        let sym = if l != 0 {
            pos += l as usize;
            e >> 6
        } else if e & LONG != 0 {
            match long_code(t, e, wdw, input, pos) {
                Some((sym, cl)) if end - pos >= cl as usize => {
                    pos += cl as usize;
                    sym
                }
                _ => return Err(corrupt("invalid Huffman code")),
            }
        } else {
            return Err(corrupt("invalid Huffman code"));
        };
        if sym != rlc && n < out.len() {
            out[n] = sym as u16;
            n += 1;
        } else {
            n = emit_slow(sym, rlc, input, &mut pos, end, out, n)?;
        }
    }

    // The last bits: fewer than 14 remain, the final byte's padding excluded.
    if pos > n_bits {
        return Err(corrupt("Huffman stream overruns its bit count"));
    }
    while pos < n_bits {
        let lc = (n_bits - pos) as u32;
        // The table index sees the remaining bits followed by zeros, as OpenEXR's does.
        let padded = (window(input, pos) >> (64 - lc)) << (64 - lc);
        let e = t.dec[(padded >> (64 - TABLE_BITS)) as usize];
        let (sym, l) = if e & 63 != 0 {
            (e >> 6, e & 63)
        } else if e & LONG != 0 {
            long_code(t, e, window(input, pos), input, pos).ok_or_else(|| corrupt("invalid Huffman code"))?
        } else {
            return Err(corrupt("invalid Huffman code"));
        };
        if l > lc {
            return Err(corrupt("invalid Huffman code"));
        }
        pos += l as usize;
        n = emit_slow(sym, rlc, input, &mut pos, n_bits, out, n)?;
    }
    if n != out.len() {
        return Err(corrupt("decoded data are shorter than expected"));
    }
    Ok(())
}

/// `getCode` for a run-length symbol or a full output: returns the new output count.
#[inline(never)]
fn emit_slow(
    sym: u32,
    rlc: u32,
    input: &[u8],
    pos: &mut usize,
    end: usize,
    out: &mut [u16],
    n: usize,
) -> Result<usize, Reason> {
    if sym != rlc {
        return if n < out.len() {
            out[n] = sym as u16;
            Ok(n + 1)
        } else {
            Err(corrupt("decoded data are longer than expected"))
        };
    }
    if end < *pos + 8 {
        return Err(corrupt("run length past the end of the stream"));
    }
    let run = (window(input, *pos) >> 56) as usize;
    *pos += 8;
    if n + run > out.len() {
        return Err(corrupt("decoded data are longer than expected"));
    }
    if n == 0 {
        return Err(corrupt("run length before any value"));
    }
    let v = out[n - 1];
    out[n..n + run].fill(v);
    Ok(n + run)
}

/// `wav2Decode`: inverse of the 2-D Haar-like wavelet over `nx` x `ny` words at
/// strides `ox`, `oy`, in place. 14-bit arithmetic when every value < 2^14.
fn wavelet_decode(buf: &mut [u16], nx: usize, ox: usize, ny: usize, oy: usize, max_value: u16) {
    if max_value < (1 << 14) {
        wavelet_levels(buf, nx, ox, ny, oy, wdec14);
    } else {
        wavelet_levels(buf, nx, ox, ny, oy, wdec16);
    }
}

#[inline(always)]
fn wdec14(l: u16, h: u16) -> (u16, u16) {
    let ls = l as i16 as i32;
    let hs = h as i16 as i32;
    let ai = ls + (hs & 1) + (hs >> 1);
    (ai as i16 as u16, (ai - hs) as i16 as u16)
}

const A_OFFSET: i32 = 1 << 15;
const MOD_MASK: i32 = (1 << 16) - 1;

#[inline(always)]
fn wdec16(l: u16, h: u16) -> (u16, u16) {
    let (m, d) = (l as i32, h as i32);
    let bb = (m - (d >> 1)) & MOD_MASK;
    let aa = (d + bb - A_OFFSET) & MOD_MASK;
    (aa as u16, bb as u16)
}

#[inline(always)]
fn wavelet_levels<F: Fn(u16, u16) -> (u16, u16)>(buf: &mut [u16], nx: usize, ox: usize, ny: usize, oy: usize, dec: F) {
    let n = nx.min(ny);
    let mut p = 1usize;
    while p <= n {
        p <<= 1;
    }
    p >>= 1;
    let mut p2 = p;
    p >>= 1;
    while p >= 1 {
        let (ox1, oy1, ox2, oy2) = (ox * p, oy * p, ox * p2, oy * p2);
        let ey = oy * (ny - p2);
        let mut py = 0usize;
        while py <= ey {
            let mut px = py;
            let ex = py + ox * (nx - p2);
            while px <= ex {
                let p01 = px + ox1;
                let p10 = px + oy1;
                let p11 = p10 + ox1;
                let (i00, i10) = dec(buf[px], buf[p10]);
                let (i01, i11) = dec(buf[p01], buf[p11]);
                let (a, b) = dec(i00, i01);
                buf[px] = a;
                buf[p01] = b;
                let (a, b) = dec(i10, i11);
                buf[p10] = a;
                buf[p11] = b;
                px += ox2;
            }
            if nx & p != 0 {
                let p10 = px + oy1;
                let (a, b) = dec(buf[px], buf[p10]);
                buf[px] = a;
                buf[p10] = b;
            }
            py += oy2;
        }
        if ny & p != 0 {
            let mut px = py;
            let ex = py + ox * (nx - p2);
            while px <= ex {
                let p01 = px + ox1;
                let (a, b) = dec(buf[px], buf[p01]);
                buf[px] = a;
                buf[p01] = b;
                px += ox2;
            }
        }
        p2 = p;
        p >>= 1;
    }
}
