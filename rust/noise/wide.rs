//! A 256-bit unsigned integer, just wide enough for the exact sums of squares of the 3-D
//! noise decomposition (`N²·SS` of a long 32-bit recording exceeds u128).

use crate::{Error, Result};

const LOW64: u128 = u64::MAX as u128;

/// Unsigned 256-bit integer `hi·2^128 + lo`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord)]
pub struct U256 {
    pub hi: u128,
    pub lo: u128,
}

fn overflow() -> Error {
    Error::Range("3-D noise sums exceed 256 bits (too many frames of 32-bit values); use fewer frames".into())
}

/// Full 256-bit product of two u128 values.
fn mul_wide(a: u128, b: u128) -> U256 {
    let (a1, a0) = (a >> 64, a & LOW64);
    let (b1, b0) = (b >> 64, b & LOW64);
    let (p00, p01, p10, p11) = (a0 * b0, a0 * b1, a1 * b0, a1 * b1);
    let mid = (p00 >> 64) + (p01 & LOW64) + (p10 & LOW64);
    U256 { hi: p11 + (p01 >> 64) + (p10 >> 64) + (mid >> 64), lo: (p00 & LOW64) | (mid << 64) }
}

impl U256 {
    pub const ZERO: U256 = U256 { hi: 0, lo: 0 };

    pub fn from_u128(v: u128) -> U256 {
        U256 { hi: 0, lo: v }
    }

    /// `v²` for any i128 (|v| < 2^127, so the square is below 2^254).
    pub fn square(v: i128) -> U256 {
        let m = v.unsigned_abs();
        if m <= LOW64 {
            U256::from_u128(m * m)
        } else {
            mul_wide(m, m)
        }
    }

    pub fn checked_add(self, o: U256) -> Result<U256> {
        let (lo, carry) = self.lo.overflowing_add(o.lo);
        let hi = self.hi.checked_add(o.hi).and_then(|h| h.checked_add(carry as u128)).ok_or_else(overflow)?;
        Ok(U256 { hi, lo })
    }

    /// `self − o`; an error if `o > self` (never for the identities it is used on).
    pub fn checked_sub(self, o: U256) -> Result<U256> {
        if o > self {
            return Err(Error::Value("internal: negative sum of squares in the 3-D noise decomposition".into()));
        }
        let (lo, borrow) = self.lo.overflowing_sub(o.lo);
        Ok(U256 { hi: self.hi - o.hi - borrow as u128, lo })
    }

    pub fn checked_mul(self, w: u128) -> Result<U256> {
        let low = mul_wide(self.lo, w);
        let high = mul_wide(self.hi, w);
        if high.hi != 0 {
            return Err(overflow());
        }
        let hi = low.hi.checked_add(high.lo).ok_or_else(overflow)?;
        Ok(U256 { hi, lo: low.lo })
    }

    /// Nearest f64 (within one rounding of each half: relative error below 2^-52).
    pub fn to_f64(self) -> f64 {
        if self.hi == 0 {
            self.lo as f64
        } else {
            self.hi as f64 * 2f64.powi(128) + self.lo as f64
        }
    }

    /// 32 little-endian bytes (the Python side reads them with `int.from_bytes`).
    pub fn to_le_bytes(self) -> [u8; 32] {
        let mut out = [0u8; 32];
        out[..16].copy_from_slice(&self.lo.to_le_bytes());
        out[16..].copy_from_slice(&self.hi.to_le_bytes());
        out
    }

    pub fn from_le_bytes(b: [u8; 32]) -> U256 {
        U256 {
            lo: u128::from_le_bytes(b[..16].try_into().expect("16 bytes")),
            hi: u128::from_le_bytes(b[16..].try_into().expect("16 bytes")),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn square_and_mul_match_u128_where_they_fit() {
        for v in [0i128, 1, -1, 12345, -(1 << 63), (1 << 64) - 1] {
            let s = U256::square(v);
            assert_eq!(s, U256::from_u128(v.unsigned_abs() * v.unsigned_abs()));
        }
        let a = U256::from_u128(u64::MAX as u128).checked_mul(u64::MAX as u128).unwrap();
        assert_eq!(a, U256::from_u128((u64::MAX as u128) * (u64::MAX as u128)));
    }

    #[test]
    fn wide_square_carries_into_the_high_half() {
        // (2^100)² = 2^200 = 2^72 · 2^128
        let s = U256::square(1i128 << 100);
        assert_eq!(s, U256 { hi: 1u128 << 72, lo: 0 });
        // (2^127 − 1)² = 2^254 − 2^128 + 1
        let m = i128::MAX;
        let s = U256::square(m);
        assert_eq!(s, U256 { hi: (1u128 << 126) - 1, lo: 1 });
        assert_eq!(U256::square(-m), s);
    }

    #[test]
    fn add_sub_mul_round_trip_and_overflow() {
        let a = U256 { hi: 3, lo: u128::MAX };
        let b = U256::from_u128(1);
        let c = a.checked_add(b).unwrap();
        assert_eq!(c, U256 { hi: 4, lo: 0 });
        assert_eq!(c.checked_sub(b).unwrap(), a);
        assert!(b.checked_sub(a).is_err());
        assert_eq!(U256 { hi: 1, lo: 0 }.checked_mul(1 << 10).unwrap(), U256 { hi: 1 << 10, lo: 0 });
        assert!(U256 { hi: 1 << 127, lo: 0 }.checked_mul(2).is_err());
        assert!(U256 { hi: u128::MAX, lo: 0 }.checked_add(U256 { hi: 1, lo: 0 }).is_err());
        let x = U256 { hi: 0x1234, lo: 0xdead_beef };
        assert_eq!(U256::from_le_bytes(x.to_le_bytes()), x);
        assert_eq!(U256 { hi: 1, lo: 0 }.to_f64(), 2f64.powi(128));
    }
}
