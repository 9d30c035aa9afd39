//! Grey levels brought to a working scale before anything is computed.
//!
//! A transform must not depend on the units of the frames: values of 1e36 or 1e-308 must
//! register as the same frame in counts does. Without a common scale they do not: float32
//! sums of 1e36 overflow (a 640×512 transform of such a frame is infinite), squares of 1e200
//! overflow float64, and differences of values near 1e-308 are lost to underflow. So each
//! frame's valid values are used as `v·factor − shift` ([`Normalisation`]): `factor` is a
//! power of two that brings their spread (largest − smallest) to [1, 2), `shift` their
//! scaled mean, so the working values are O(1) and centred.
//!
//! The map is increasing and affine, so it changes no step beyond rounding: phase
//! correlation (of mean-free frames, whitened), the correlations that judge aliases and
//! rivals (Pearson), the refinement (its gain and offset absorb the map: the gain keeps its
//! sign, which is what tells an inversion, and both are in working units), NMI (each frame
//! binned over its own range), the checks on overlap and confidence. Multiplying by a power
//! of two is exact (outside the subnormal range), and subtracting the shift is exact for
//! values within a factor of two of it, so no precision is lost to it either.

/// `v ↦ v·factor − shift`: a frame's values as the registration works on them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Normalisation {
    /// A power of two.
    pub factor: f64,
    pub shift: f64,
}

/// Valid values whose spread is at most this fraction of their magnitude are one level: the
/// frame is flat (constant up to rounding).
const FLAT: f64 = 1e-12;

impl Normalisation {
    pub const IDENTITY: Normalisation = Normalisation { factor: 1.0, shift: 0.0 };

    /// The normalisation of valid values in `[lo, hi]` whose mean, scaled by the factor, is
    /// `scaled_mean(factor)`.
    pub fn new(lo: f64, hi: f64, scaled_mean: impl FnOnce(f64) -> f64) -> Normalisation {
        let factor = unit_factor(lo, hi);
        Normalisation { factor, shift: scaled_mean(factor) }
    }

    /// The working value of `v`.
    #[inline(always)]
    pub fn apply(self, v: f64) -> f64 {
        v * self.factor - self.shift
    }
}

/// The power of two that brings the spread `hi − lo` to [1, 2), or, when there is none (a
/// flat frame), the magnitude; 1 when the values are empty, all zero or not finite. Its
/// exponent stays within float64's normal range: a spread of subnormal values comes to at
/// least 4e-16 (still far from underflow in every step), one beyond 2^1023 to at most 8.
pub fn unit_factor(lo: f64, hi: f64) -> f64 {
    let spread = hi - lo;
    // the spread of values near ±f64::MAX overflows: then its half (halving a subnormal
    // spread instead would lose it)
    let (size, halved) = if spread.is_finite() { (spread, 0) } else { (0.5 * hi - 0.5 * lo, 1) };
    let size = if size > 0.0 { size } else { lo.abs().max(hi.abs()) };
    if !(size > 0.0 && size.is_finite()) {
        return 1.0;
    }
    power_of_two(-(binary_exponent(size) + halved))
}

/// The common value of valid values in `[lo, hi]` if they are one level (their spread at
/// most [`FLAT`] of their magnitude), else None.
pub fn flat_level(lo: f64, hi: f64) -> Option<f64> {
    (lo <= hi && hi - lo <= FLAT * lo.abs().max(hi.abs())).then_some(lo)
}

/// `e` with `2^e ≤ x < 2^(e+1)`, for finite `x > 0` (subnormals included).
fn binary_exponent(x: f64) -> i32 {
    let bits = x.to_bits();
    let biased = ((bits >> 52) & 0x7ff) as i32;
    if biased == 0 {
        // subnormal: x = m·2^-1074 with m < 2^52
        let mantissa = bits & ((1u64 << 52) - 1);
        63 - mantissa.leading_zeros() as i32 - 1074
    } else {
        biased - 1023
    }
}

/// `2^e`, `e` clamped to float64's normal exponents.
fn power_of_two(e: i32) -> f64 {
    f64::from_bits(((e.clamp(-1022, 1023) + 1023) as u64) << 52)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn factors_are_powers_of_two_bringing_the_spread_to_one() {
        for (lo, hi) in [(2623.0, 2739.0), (-1e36, 3e36), (0.96e-300, 1e-300), (1e12, 1e12 + 1.5), (-5.0, -4.0)] {
            let f = unit_factor(lo, hi);
            assert_eq!(f, 2f64.powi(binary_exponent(f)), "{f}");
            let spread = hi * f - lo * f;
            assert!((1.0..2.0).contains(&spread), "{lo} {hi}: {spread}");
        }
        // exact powers of two at both ends of the range
        assert_eq!(unit_factor(0.0, 1.0), 1.0);
        assert_eq!(unit_factor(0.0, 4.0), 0.25);
        assert_eq!(binary_exponent(f64::MIN_POSITIVE), -1022);
        assert_eq!(binary_exponent(f64::MIN_POSITIVE / 8.0), -1025);
        assert_eq!(binary_exponent(5e-324), -1074);
        assert_eq!(binary_exponent(f64::MAX), 1023);
        // the widest finite spread does not overflow (the factor is clamped to a normal
        // number: the spread comes to 8); the narrowest is clamped, not infinite
        let widest = unit_factor(-f64::MAX, f64::MAX);
        assert_eq!(widest, f64::MIN_POSITIVE);
        assert!((1.0..=8.0).contains(&(f64::MAX * widest - -f64::MAX * widest)));
        let narrowest = unit_factor(0.0, 5e-324);
        assert_eq!(narrowest, 2f64.powi(1023));
        assert!(5e-324 * narrowest > 1e-16);
        // subnormal values whose spread is still near 1e-310: clamped too, to about 0.04
        let subnormal = unit_factor(0.96e-308, 1e-308);
        assert_eq!(subnormal, 2f64.powi(1023));
        assert!((0.01..1.0).contains(&(1e-308 * subnormal - 0.96e-308 * subnormal)));
        // flat frames: the magnitude; nothing to scale: 1
        assert_eq!(unit_factor(3.0, 3.0), 0.5);
        assert_eq!(unit_factor(0.0, 0.0), 1.0);
        assert_eq!(unit_factor(f64::INFINITY, f64::NEG_INFINITY), 1.0);
    }

    #[test]
    fn working_values_are_exact_images_of_the_values() {
        // a frame with a large offset: v·factor − shift loses nothing
        let values = [1e12 + 0.25, 1e12 - 0.5, 1e12 + 1.0];
        let n = Normalisation::new(1e12 - 0.5, 1e12 + 1.0, |f| 1e12 * f);
        assert_eq!(n.factor, 1.0);
        let working: Vec<f64> = values.iter().map(|&v| n.apply(v)).collect();
        assert_eq!(working, [0.25, -0.5, 1.0]);
        // float32-scale extremes: the same working values up to the power of two
        let big = Normalisation::new(-0.5 * 2f64.powi(120), 2f64.powi(120), |f| 0.0 * f);
        assert_eq!(big.apply(0.25 * 2f64.powi(120)), 0.25);
    }

    #[test]
    fn flat_levels() {
        assert_eq!(flat_level(3.5, 3.5), Some(3.5));
        assert_eq!(flat_level(1e300, 1e300 * (1.0 + 1e-15)), Some(1e300));
        assert_eq!(flat_level(0.0, 5e-324), None);
        assert_eq!(flat_level(-f64::MAX, f64::MAX), None);
        assert_eq!(flat_level(f64::INFINITY, f64::NEG_INFINITY), None);
    }
}
