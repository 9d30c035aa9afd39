//! One JPEG-LS scan of one component decoded (T.87 Annex A): context modelling, the
//! regular mode (prediction, bias correction, Golomb codes) and the run mode.
//!
//! The names follow the standard's (Ra, Rb, Rc, Rd; A, B, C, N, Nn; RUNindex) so the code can
//! be read beside it. Lines are decoded into two buffers of `cols + 2` samples whose first and
//! last entries hold the edge values the standard defines; a restart interval starts as a scan
//! does, with the line above all zero and every context reset.

use std::cell::RefCell;
use std::rc::Rc;

use super::bits::Bits;
use super::Reason;

/// The coding parameters of a scan (T.87 §A.2.1, C.2.4.1.1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Coding {
    pub maxval: i32,
    pub near: i32,
    pub t1: i32,
    pub t2: i32,
    pub t3: i32,
    pub reset: i32,
}

impl Coding {
    /// RANGE: the number of quantised error values.
    fn range(&self) -> i32 {
        (self.maxval + 2 * self.near) / (2 * self.near + 1) + 1
    }

    /// The bits of a quantised error (qbpp) and the most bits of one code (LIMIT).
    fn code_sizes(&self) -> (u32, u32) {
        let bits_for = |n: i32| 32 - (n as u32 - 1).leading_zeros(); // ceil(log2(n)) for n >= 2
        let qbpp = bits_for(self.range());
        let bpp = bits_for(self.maxval + 1).max(2);
        (qbpp, 2 * (bpp + bpp.max(8)))
    }
}

/// Run lengths: a run-length code's order per RUNindex (T.87 §A.7.1.1, J).
const J: [u32; 32] =
    [0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2, 2, 3, 3, 3, 3, 4, 4, 5, 5, 6, 6, 7, 7, 8, 9, 10, 11, 12, 13, 14, 15];
const MIN_C: i32 = -128;
const MAX_C: i32 = 127;
/// Largest Golomb order accepted: beyond it A and N describe no valid stream.
const MAX_K: u32 = 24;
/// Largest |A| or |B| a context may reach: sums of at most RESET errors of at most 2^16.
const MAX_SUM: i32 = 1 << 24;

/// A regular-mode context (T.87 §A.2.1): error magnitudes A, bias B, correction C, count N.
#[derive(Clone, Copy)]
struct Context {
    a: i32,
    b: i32,
    c: i32,
    n: i32,
}

/// A run-interruption context: A, N, and Nn, the count of negative errors.
#[derive(Clone, Copy)]
struct RunContext {
    a: i32,
    n: i32,
    nn: i32,
}

/// Everything a scan's decoding carries from sample to sample.
struct Decoder<'a, 'b> {
    bits: Bits<'a>,
    coding: Coding,
    range: i32,
    qbpp: u32,
    limit: u32,
    /// Gradient quantisation Q(D) for D in -maxval..=maxval, at D + maxval.
    quantised: &'b [i8],
    contexts: [Context; 365],
    run_contexts: [RunContext; 2],
    run_index: usize,
}

fn corrupt(what: &str) -> Reason {
    format!("corrupt JPEG-LS data ({what})")
}

/// Why a scan's data is corrupt: a byte wide, so the per-sample results stay in a register.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Corrupt {
    LongCode,
    LargeOrder,
    BeyondRange,
    Overflow,
    LongRun,
}

impl Corrupt {
    fn reason(self) -> Reason {
        corrupt(match self {
            Corrupt::LongCode => "a code longer than LIMIT",
            Corrupt::LargeOrder => "a Golomb order beyond 24",
            Corrupt::BeyondRange => "an error beyond RANGE",
            Corrupt::Overflow => "a context's error sum overflows",
            Corrupt::LongRun => "a run past the end of its line",
        })
    }
}

/// The gradient quantisation table for `coding`, kept per thread: a recording's frames share
/// their coding parameters, and the table (up to 128 KiB) costs more to build than a small
/// frame to decode.
fn quantisation(coding: &Coding) -> Rc<[i8]> {
    thread_local! {
        static KEPT: RefCell<Option<(Coding, Rc<[i8]>)>> = const { RefCell::new(None) };
    }
    KEPT.with_borrow_mut(|kept| match kept {
        Some((c, table)) if c == coding => table.clone(),
        _ => {
            let table: Rc<[i8]> = quantisation_table(coding).into();
            *kept = Some((*coding, table.clone()));
            table
        }
    })
}

/// The gradient quantisation table (T.87 §A.3.3) for `coding`: Q(D) at D + MAXVAL.
fn quantisation_table(coding: &Coding) -> Vec<i8> {
    let Coding { maxval, near, t1, t2, t3, .. } = *coding;
    let q = |d: i32| -> i8 {
        match d {
            _ if d <= -t3 => -4,
            _ if d <= -t2 => -3,
            _ if d <= -t1 => -2,
            _ if d < -near => -1,
            _ if d <= near => 0,
            _ if d < t1 => 1,
            _ if d < t2 => 2,
            _ if d < t3 => 3,
            _ => 4,
        }
    };
    (-maxval..=maxval).map(q).collect()
}

/// Decode the scan in `data` (from just after its SOS segment) into `out` (`rows` lines of
/// `cols` samples), with a restart marker every `restart` lines (0: none).
pub(super) fn decode(
    data: &[u8],
    (cols, rows): (usize, usize),
    coding: Coding,
    restart: usize,
    out: &mut [u16],
) -> Result<(), Reason> {
    let quantised = quantisation(&coding);
    let (qbpp, limit) = coding.code_sizes();
    let interval = if restart == 0 { rows } else { restart };
    let mut lines = [vec![0i32; cols + 2], vec![0i32; cols + 2]];
    let mut start = 0;
    for (k, first) in (0..rows).step_by(interval).enumerate() {
        if k > 0 {
            start = restart_marker(data, start, k)?;
            lines.iter_mut().for_each(|l| l.fill(0));
        }
        let mut decoder = Decoder::new(&data[start..], coding, &quantised, qbpp, limit);
        for row in first..rows.min(first + interval) {
            let [above, current] = &mut lines;
            let decoded = decoder.line(above, current);
            if decoder.bits.overran() {
                // zero bits read past the end make a corrupt-looking code: name the cause
                return Err(format!("truncated JPEG-LS data: it ends in line {row} of {rows}"));
            }
            decoded.map_err(Corrupt::reason)?;
            for (o, &v) in out[row * cols..(row + 1) * cols].iter_mut().zip(&current[1..=cols]) {
                *o = v as u16; // within 0..=maxval <= 65535
            }
            lines.swap(0, 1);
        }
        start += decoder.bits.position();
    }
    Ok(())
}

/// The offset just after the `k`-th restart marker (from 1; RST0 to RST7 in turn), the next
/// marker at or after `from`.
fn restart_marker(data: &[u8], from: usize, k: usize) -> Result<usize, Reason> {
    let at = super::next_marker(data, from)
        .ok_or_else(|| format!("truncated JPEG-LS data: restart marker {k} is missing"))?;
    let expected = 0xD0 + ((k - 1) % 8) as u8;
    match data[at + 1] {
        code if code == expected => Ok(at + 2),
        code => Err(corrupt(&format!("restart marker {k} is 0xFF{code:02X}, expected 0xFF{expected:02X}"))),
    }
}

impl<'a, 'b> Decoder<'a, 'b> {
    fn new(data: &'a [u8], coding: Coding, quantised: &'b [i8], qbpp: u32, limit: u32) -> Decoder<'a, 'b> {
        let range = coding.range();
        let a = ((range + 32) / 64).max(2);
        Decoder {
            bits: Bits::new(data),
            coding,
            range,
            qbpp,
            limit,
            quantised,
            contexts: [Context { a, b: 0, c: 0, n: 1 }; 365],
            run_contexts: [RunContext { a, n: 1, nn: 0 }; 2],
            run_index: 0,
        }
    }

    #[inline]
    fn quantise(&self, d: i32) -> i32 {
        i32::from(self.quantised[(d + self.coding.maxval) as usize])
    }

    /// Decode one line into `current[1..=cols]`; `above` is the line above.
    fn line(&mut self, above: &mut [i32], current: &mut [i32]) -> Result<(), Corrupt> {
        let cols = current.len() - 2;
        above[cols + 1] = above[cols];
        current[0] = above[1];
        let mut x = 1;
        // Rc, Rb, Rd roll along the line above; Ra is the sample just decoded
        let (mut ra, mut rc, mut rb) = (current[0], above[0], above[1]);
        while x <= cols {
            let rd = above[x + 1];
            let q = (self.quantise(rd - rb) * 9 + self.quantise(rb - rc)) * 9 + self.quantise(rc - ra);
            if q != 0 {
                ra = self.regular(q, ra, rb, rc)?;
                current[x] = ra;
                x += 1;
                (rc, rb) = (rb, rd);
            } else {
                x = self.run(above, current, x)?;
                if x <= cols {
                    (ra, rc, rb) = (current[x - 1], above[x - 1], above[x]);
                }
            }
        }
        Ok(())
    }

    /// A Golomb-coded mapped error of order `k`, at most `limit` bits long (T.87 §A.5.3).
    #[inline(always)]
    fn mapped_error(&mut self, k: u32, limit: u32) -> Result<i32, Corrupt> {
        let escape = limit - self.qbpp - 1;
        if let Some(code) = self.bits.short_code(k, escape) {
            return Ok(code as i32);
        }
        let prefix = self.bits.zeros(escape).ok_or(Corrupt::LongCode)?;
        Ok(if prefix < escape {
            ((prefix << k) | self.bits.read(k)) as i32
        } else {
            self.bits.read(self.qbpp) as i32 + 1
        })
    }

    /// A sample in the regular mode (T.87 §A.4–A.6) in context `q` (signed).
    #[inline]
    fn regular(&mut self, q: i32, ra: i32, rb: i32, rc: i32) -> Result<i32, Corrupt> {
        let sign = if q < 0 { -1 } else { 1 };
        let index = q.unsigned_abs() as usize;
        let Context { a, b, c, n } = self.contexts[index];
        let predicted = (median_edge(ra, rb, rc) + sign * c).clamp(0, self.coding.maxval);
        let k = golomb_order(n, a).ok_or(Corrupt::LargeOrder)?;
        let mapped = self.mapped_error(k, self.limit)?;
        let mut error = (mapped >> 1) ^ -(mapped & 1);
        if self.coding.near == 0 && k == 0 && 2 * b <= -n {
            error = !error;
        }
        if error.abs() > self.range {
            return Err(Corrupt::BeyondRange);
        }
        self.update(index, error)?;
        Ok(self.reconstruct(predicted + sign * error * (2 * self.coding.near + 1)))
    }

    /// Context `index` after an error (T.87 §A.6.1, A.6.2).
    #[inline]
    fn update(&mut self, index: usize, error: i32) -> Result<(), Corrupt> {
        let (near, reset) = (self.coding.near, self.coding.reset);
        let ctx = &mut self.contexts[index];
        ctx.b += error * (2 * near + 1);
        ctx.a += error.abs();
        if ctx.a >= MAX_SUM || ctx.b.abs() >= MAX_SUM {
            return Err(Corrupt::Overflow);
        }
        if ctx.n == reset {
            ctx.a >>= 1;
            ctx.b >>= 1; // floor, as the standard's -((1 - B) >> 1) for negative B
            ctx.n >>= 1;
        }
        ctx.n += 1;
        if ctx.b <= -ctx.n {
            ctx.b = (ctx.b + ctx.n).max(-ctx.n + 1);
            ctx.c = (ctx.c - 1).max(MIN_C);
        } else if ctx.b > 0 {
            ctx.b = (ctx.b - ctx.n).min(0);
            ctx.c = (ctx.c + 1).min(MAX_C);
        }
        Ok(())
    }

    /// A reconstructed value brought back into 0..=maxval (T.87 §A.4.5, modulo RANGE).
    #[inline]
    fn reconstruct(&self, value: i32) -> i32 {
        let Coding { maxval, near, .. } = self.coding;
        let span = self.range * (2 * near + 1);
        let value = if value < -near {
            value + span
        } else if value > maxval + near {
            value - span
        } else {
            value
        };
        value.clamp(0, maxval)
    }

    /// The run mode from `x` (T.87 §A.7): a run of Ra, then, unless the line ends, a run
    /// interruption sample. Returns the next x.
    fn run(&mut self, above: &[i32], current: &mut [i32], x: usize) -> Result<usize, Corrupt> {
        let cols = current.len() - 2;
        let ra = current[x - 1];
        let remaining = cols + 1 - x;
        let length = self.run_length(remaining)?;
        current[x..x + length].fill(ra);
        let end = x + length;
        if end > cols {
            return Ok(end);
        }
        current[end] = self.interruption(ra, above[end])?;
        self.run_index = self.run_index.saturating_sub(1);
        Ok(end + 1)
    }

    /// The length of a run, at most `remaining` (T.87 §A.7.1.2).
    fn run_length(&mut self, remaining: usize) -> Result<usize, Corrupt> {
        let mut length = 0;
        while self.bits.bit() {
            let full = 1usize << J[self.run_index];
            let count = full.min(remaining - length);
            length += count;
            if count == full {
                self.run_index = (self.run_index + 1).min(31);
            }
            if length == remaining {
                return Ok(length);
            }
        }
        length += self.bits.read(J[self.run_index]) as usize;
        if length > remaining {
            return Err(Corrupt::LongRun);
        }
        Ok(length)
    }

    /// The sample interrupting a run (T.87 §A.7.2); `ra` is the run's value, `rb` the sample above.
    fn interruption(&mut self, ra: i32, rb: i32) -> Result<i32, Corrupt> {
        let near = self.coding.near;
        let kind = i32::from((ra - rb).abs() <= near);
        let (predicted, sign) = if kind == 1 { (ra, 1) } else { (rb, if rb >= ra { 1 } else { -1 }) };
        let RunContext { a, n, nn } = self.run_contexts[kind as usize];
        let temp = a + (n >> 1) * kind;
        let k = golomb_order(n, temp).ok_or(Corrupt::LargeOrder)?;
        let mapped = self.mapped_error(k, self.limit - J[self.run_index] - 1)?;
        let t = mapped + kind;
        let map = t & 1;
        let magnitude = (t + map) / 2;
        let error = if (k != 0 || 2 * nn >= n) == (map == 1) { -magnitude } else { magnitude };
        if magnitude > self.range {
            return Err(Corrupt::BeyondRange);
        }
        let ctx = &mut self.run_contexts[kind as usize];
        if error < 0 {
            ctx.nn += 1;
        }
        ctx.a += (mapped + 1 - kind) >> 1;
        if ctx.a >= MAX_SUM {
            return Err(Corrupt::Overflow);
        }
        if ctx.n == self.coding.reset {
            ctx.a >>= 1;
            ctx.n >>= 1;
            ctx.nn >>= 1;
        }
        ctx.n += 1;
        Ok(self.reconstruct(predicted + sign * error * (2 * near + 1)))
    }
}

/// The Golomb order k: the least with N·2^k ≥ A (T.87 §A.5.1); `None` beyond `MAX_K`.
#[inline]
fn golomb_order(n: i32, a: i32) -> Option<u32> {
    let (n, a) = (n as u32, a as u32); // N ≥ 1, 0 < A < MAX_SUM
    if n >= a {
        return Some(0);
    }
    let k = n.leading_zeros() - a.leading_zeros(); // N·2^k has A's top bit; below 2^25, no overflow
    let k = if n << k < a { k + 1 } else { k };
    (k <= MAX_K).then_some(k)
}

/// The median edge detector (T.87 §A.4.1).
#[inline]
fn median_edge(ra: i32, rb: i32, rc: i32) -> i32 {
    if rc >= ra.max(rb) {
        ra.min(rb)
    } else if rc <= ra.min(rb) {
        ra.max(rb)
    } else {
        ra + rb - rc
    }
}
