//! `ln` and `exp` for the conversions' pixel loops, without branches or calls, so a loop over
//! a frame compiles to SIMD code (the C library's `log` and `exp` are calls, one value each).
//! Both are accurate to a few units in the last place over the arguments the conversions
//! use; outside those (stated per function) the result is unspecified and the caller masks it.

/// 2^52 + 2^51: adding it to a float below 2^51 in magnitude rounds to an integer held in the
/// low mantissa bits.
const SHIFTER: f64 = 6_755_399_441_055_744.0;
/// ln 2 in two parts; `k * LN2_HI` is exact for |k| < 2^11.
const LN2_HI: f64 = f64::from_bits(0x3FE6_2E42_FEE0_0000);
const LN2_LO: f64 = f64::from_bits(0x3DEA_39EF_3579_3C76);
const SQRT_HALF_BITS: u64 = 0x3FE6_A09E_667F_3BCD;
const MANTISSA: u64 = (1 << 52) - 1;

/// Natural logarithm of `x` >= 1, finite (other arguments: unspecified, no panic).
///
/// `x = 2^k m` with `m` in [√½, √2); `ln m = 2 atanh f` with `f = (m − 1) / (m + 1)`, |f| <
/// 0.172, summed as `2f + f s P(s)` (s = f², the series to s^11, well below an ulp).
#[inline(always)]
pub(super) fn ln_at_least_one(x: f64) -> f64 {
    let shifted = x.to_bits().wrapping_sub(SQRT_HALF_BITS);
    let k = f64::from_bits((shifted >> 52) | 0x4330_0000_0000_0000) - 4_503_599_627_370_496.0;
    let m = f64::from_bits((shifted & MANTISSA).wrapping_add(SQRT_HALF_BITS));
    let f = (m - 1.0) / (m + 1.0);
    let s = f * f;
    // 2 / (2j + 1), j = 1..=11
    let mut p = 2.0 / 23.0;
    for c in [2.0 / 21.0, 2.0 / 19.0, 2.0 / 17.0, 2.0 / 15.0, 2.0 / 13.0, 2.0 / 11.0, 2.0 / 9.0, 2.0 / 7.0, 2.0 / 5.0] {
        p = p * s + c;
    }
    p = p * s + 2.0 / 3.0;
    k * LN2_HI + (k * LN2_LO + (2.0 * f + f * s * p))
}

/// e^y for y >= 0: infinity above ln(f64::MAX) and for +inf; NaN for NaN; unspecified below 0.
///
/// `y = n ln 2 + r`, |r| <= ln 2 / 2, `e^r` by its Taylor series to r^13, times 2^n.
#[inline(always)]
pub(super) fn exp_non_negative(y: f64) -> f64 {
    const MAX: f64 = 709.782_712_893_384;
    let clamped = y.clamp(0.0, MAX); // NaN stays NaN
    let shifted = clamped * std::f64::consts::LOG2_E + SHIFTER;
    let n = shifted - SHIFTER;
    let r = (clamped - n * LN2_HI) - n * LN2_LO;
    // 1 / j!, j = 13 down to 2
    let mut p = 1.0 / 6_227_020_800.0;
    for c in [
        1.0 / 479_001_600.0,
        1.0 / 39_916_800.0,
        1.0 / 3_628_800.0,
        1.0 / 362_880.0,
        1.0 / 40_320.0,
        1.0 / 5_040.0,
        1.0 / 720.0,
        1.0 / 120.0,
        1.0 / 24.0,
        1.0 / 6.0,
        0.5,
        1.0,
        1.0,
    ] {
        p = p * r + c;
    }
    // 2^(n − 1) (n <= 1024 keeps the exponent field below all ones), then times 2
    let half_scale = f64::from_bits(shifted.to_bits().wrapping_add(1022) << 52);
    let e = p * half_scale * 2.0;
    if y > MAX {
        f64::INFINITY
    } else {
        e
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ulps(a: f64, b: f64) -> u64 {
        a.to_bits().abs_diff(b.to_bits())
    }

    #[test]
    #[allow(clippy::approx_constant)] // 1.4142135 is meant: just below √2, the reduction's boundary
    fn ln_matches_the_c_library() {
        let mut worst = 0;
        let mut x = 1.0f64;
        while x < 1e300 {
            for y in [x, x * 1.000_000_1, x * 1.414, x * 1.4142135, x * 1.9999] {
                worst = worst.max(ulps(ln_at_least_one(y), y.ln()));
            }
            x *= 1.37;
        }
        for y in [1.0, 1.0 + f64::EPSILON, 1.000_001, 1.5, 2.0, std::f64::consts::E, f64::MAX] {
            worst = worst.max(ulps(ln_at_least_one(y), y.ln()));
        }
        assert!(worst <= 2, "{worst} ulps");
        assert_eq!(ln_at_least_one(1.0), 0.0);
    }

    #[test]
    fn exp_matches_the_c_library() {
        let mut worst = 0;
        let mut y = 0.0f64;
        while y < 709.7 {
            worst = worst.max(ulps(exp_non_negative(y), y.exp()));
            y += 0.013_7;
        }
        for y in [0.0, 1e-300, 1e-10, 0.5, 1.0, 708.0, 709.78] {
            worst = worst.max(ulps(exp_non_negative(y), y.exp()));
        }
        assert!(worst <= 2, "{worst} ulps");
        assert_eq!(exp_non_negative(709.8), f64::INFINITY);
        assert_eq!(exp_non_negative(f64::INFINITY), f64::INFINITY);
        assert!(exp_non_negative(f64::NAN).is_nan());
    }
}
