//! The bits of one JPEG-LS scan (or restart interval), most significant first.
//!
//! JPEG-LS stuffs bits, not bytes (T.87 §9.1): after a 0xFF byte the encoder writes a 0 bit,
//! so the next byte carries 7 bits of data; a 0xFF followed by a byte with its high bit set is
//! a marker and ends the data. Past the end of the data the reader yields 0 bits and counts
//! them, so the hot loop reads without a bounds check per bit and the caller asks
//! [`Bits::overran`] once a line.

/// The reader: a left-aligned cache of up to 64 bits over the scan's bytes.
pub(super) struct Bits<'a> {
    data: &'a [u8],
    /// Next byte to load.
    pos: usize,
    /// First 0xFF at or after `pos` (`data.len()` when none): bytes before it load 8 at a time.
    next_ff: usize,
    /// Valid bits, from the top.
    cache: u64,
    valid: u32,
    /// The previous byte loaded was 0xFF: the next carries 7 bits.
    after_ff: bool,
    /// Zero bits appended past the end of the data (or at a marker).
    padding: u64,
}

/// Bits a fill guarantees (when data or padding remain): enough for any one read.
const FILLED: u32 = 56;

impl<'a> Bits<'a> {
    pub(super) fn new(data: &'a [u8]) -> Bits<'a> {
        let mut bits = Bits { data, pos: 0, next_ff: 0, cache: 0, valid: 0, after_ff: false, padding: 0 };
        bits.find_ff();
        bits.fill();
        bits
    }

    fn find_ff(&mut self) {
        self.next_ff = self.data[self.pos..].iter().position(|&b| b == 0xFF).map_or(self.data.len(), |i| self.pos + i);
    }

    /// Load bytes until at least `FILLED` bits are valid.
    fn fill(&mut self) {
        if !self.after_ff && self.pos + 8 <= self.next_ff {
            let word = u64::from_be_bytes(self.data[self.pos..self.pos + 8].try_into().expect("8 bytes"));
            let bytes = (64 - self.valid) / 8;
            self.cache |= word >> self.valid;
            self.valid += bytes * 8;
            self.pos += bytes as usize;
            if self.valid < 64 {
                self.cache &= !(u64::MAX >> self.valid); // drop the part of a byte not yet counted
            }
            return;
        }
        while self.valid <= FILLED {
            let Some(&byte) = self.data.get(self.pos).filter(|_| !self.at_marker()) else {
                self.padding += u64::from(64 - self.valid);
                self.valid = 64;
                return;
            };
            let (value, width) = if self.after_ff { (byte & 0x7F, 7) } else { (byte, 8) };
            self.cache |= u64::from(value) << (64 - self.valid - width);
            self.valid += width;
            self.after_ff = byte == 0xFF;
            self.pos += 1;
            if self.pos > self.next_ff {
                self.find_ff();
            }
        }
    }

    /// Whether the byte at `pos` starts a marker (0xFF, then a byte with its high bit set).
    fn at_marker(&self) -> bool {
        self.data[self.pos] == 0xFF && self.data.get(self.pos + 1).is_none_or(|&next| next & 0x80 != 0)
    }

    /// The next `n` bits (`n` ≤ 32) as a number.
    #[inline]
    pub(super) fn read(&mut self, n: u32) -> u32 {
        if n == 0 {
            return 0;
        }
        if self.valid < n {
            self.fill();
        }
        let value = (self.cache >> (64 - n)) as u32;
        self.skip(n);
        value
    }

    #[inline]
    pub(super) fn bit(&mut self) -> bool {
        self.read(1) == 1
    }

    #[inline]
    fn skip(&mut self, n: u32) {
        self.cache = if n < 64 { self.cache << n } else { 0 };
        self.valid -= n;
    }

    /// The number of 0 bits before the next 1, which is consumed; `None` when more than `most`
    /// zeros come first.
    #[inline]
    pub(super) fn zeros(&mut self, most: u32) -> Option<u32> {
        let mut count = 0;
        loop {
            if self.valid < 32 {
                self.fill();
            }
            let run = self.cache.leading_zeros().min(self.valid);
            if run < self.valid {
                count += run;
                if count > most {
                    return None;
                }
                self.skip(run + 1);
                return Some(count);
            }
            count += run;
            if count > most {
                return None;
            }
            self.skip(run);
        }
    }

    /// A Golomb code of order `k` (`k` ≤ 32) whose unary prefix is below `escape`, when the
    /// whole code is in the cache: `(prefix << k) | the k bits after it`. `None` otherwise
    /// (the caller reads it with [`Bits::zeros`] and [`Bits::read`]); nothing is consumed then.
    #[inline]
    pub(super) fn short_code(&mut self, k: u32, escape: u32) -> Option<u32> {
        if self.valid < 32 {
            self.fill();
        }
        let prefix = self.cache.leading_zeros();
        let len = prefix + 1 + k;
        if prefix >= escape || len > self.valid || len >= 64 {
            return None;
        }
        let suffix = ((self.cache << (prefix + 1)) >> 1 >> (63 - k)) as u32;
        self.skip(len);
        Some(prefix << k | suffix)
    }

    /// Whether reading went past the end of the data: the scan is truncated or corrupt.
    pub(super) fn overran(&self) -> bool {
        self.padding > u64::from(self.valid)
    }

    /// The byte after the last one loaded: the scan's data ends at or after it.
    pub(super) fn position(&self) -> usize {
        self.pos
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stuffed_byte_carries_seven_bits_and_a_marker_ends_the_data() {
        // 0xFF, then 0x7F with its stuffed 0 bit: 8 + 7 one-bits; then the marker 0xFF 0xD9
        let mut bits = Bits::new(&[0xFF, 0x7F, 0xFF, 0xD9, 0x12]);
        assert_eq!(bits.read(15), 0x7FFF);
        assert!(!bits.overran());
        assert_eq!(bits.read(8), 0, "the marker is not data");
        assert!(bits.overran());
        assert_eq!(bits.position(), 2);
    }

    #[test]
    fn long_reads_cross_the_fast_and_slow_paths_alike() {
        let data: Vec<u8> = (0..64u32).map(|i| (i * 37 + 11) as u8 & 0x7F | 0x01).collect();
        let mut fast = Bits::new(&data);
        let mut expected = data.iter().flat_map(|b| (0..8).rev().map(move |s| u32::from(b >> s & 1)));
        for n in [1, 7, 13, 3, 16, 9, 1, 2, 32, 5, 11] {
            let want = (0..n).fold(0u32, |acc, _| acc << 1 | expected.next().unwrap());
            assert_eq!(fast.read(n), want, "{n} bits");
        }
    }

    #[test]
    fn zeros_count_across_refills_and_stop_at_the_limit() {
        let mut data = vec![0u8; 12];
        data.push(0x80);
        let mut bits = Bits::new(&data);
        assert_eq!(bits.zeros(200), Some(96));
        assert_eq!(Bits::new(&data).zeros(50), None);
    }
}
