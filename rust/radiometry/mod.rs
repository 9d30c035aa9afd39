//! Raw counts to temperatures and back: the FLIR camera model as Thermimage's `raw2temp` and
//! `temp2raw` publish it.
//!
//! The factory calibration fits Planck's law to the camera's counts: a blackbody at `t`
//! kelvin gives the signal `U(t) = R1 / (R2 (exp(B / t) − F)) − O`. The camera sees the
//! object through the atmosphere (transmission τ, from the humidity, the air temperature and
//! half the object distance, on each side of a window) and an external window (transmission
//! W, emitting `1 − W`, reflecting nothing), so the counts are
//!
//! ```text
//! S = E τ W τ U(obj) + (1 − E) τ W τ U(refl) + (1 − τ) W τ U(atm) + (1 − W) τ U(win) + (1 − τ) U(atm)
//! ```
//!
//! with E the emissivity. [`Calibration::model`] reduces that to a gain and a background, so
//! one pixel costs a multiply-add, a division and a logarithm: `t = B / ln(R1 / (R2 (U + O)) + F)`
//! with `U = (S − background) / gain`; the inverse runs the same steps backwards.
//!
//! Counts outside the calibration's domain (no finite, positive absolute temperature: the
//! logarithm of a non-positive number, or of a number below 1) become NaN and are counted.
//! The pixel loops use branch-free `ln` and `exp` (`math.rs`) so they compile to SIMD code.

use rayon::prelude::*;
use std::mem::MaybeUninit;

use crate::{Error, Result};

pub(crate) mod errors;
mod math;

pub use errors::{error_sums, ErrorSums};

/// 0 °C in kelvin.
pub const ZERO_CELSIUS: f64 = 273.15;

/// The calibration and viewing conditions of a conversion. Temperatures in °C, relative
/// humidity in percent, distance in metres; field names are those of the Python `Radiometry`
/// (the binding reads them from it attribute by attribute, and returns a file's as a dict).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "python", derive(pyo3::FromPyObject, pyo3::IntoPyObject))]
pub struct Calibration {
    pub planck_r1: f64,
    pub planck_r2: f64,
    pub planck_b: f64,
    pub planck_f: f64,
    pub planck_o: f64,
    pub emissivity: f64,
    pub object_distance: f64,
    pub reflected_temperature: f64,
    pub atmospheric_temperature: f64,
    pub window_temperature: f64,
    pub window_transmission: f64,
    pub relative_humidity: f64,
    pub alpha1: f64,
    pub alpha2: f64,
    pub beta1: f64,
    pub beta2: f64,
    pub x: f64,
}

/// The temperature unit of a conversion.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Unit {
    Celsius,
    Kelvin,
}

impl Unit {
    /// What to add to a temperature in this unit to get kelvin.
    fn to_kelvin(self) -> f64 {
        match self {
            Unit::Celsius => ZERO_CELSIUS,
            Unit::Kelvin => 0.0,
        }
    }
}

/// One requirement on a field: `Ok` or the phrase that says what is wrong.
fn require(name: &str, value: f64, ok: bool, expected: &str) -> Result<()> {
    if ok && value.is_finite() {
        Ok(())
    } else {
        Err(Error::Value(format!("{name} = {value} is invalid: expected {expected}")))
    }
}

/// The per-pixel constants of the model.
#[derive(Debug, Clone, Copy)]
pub struct Model {
    /// R1 / R2
    ratio: f64,
    b: f64,
    f: f64,
    o: f64,
    /// counts per unit of object signal: E τ² W
    gain: f64,
    /// counts that do not come from the object
    background: f64,
}

impl Calibration {
    fn check(&self) -> Result<()> {
        let above_zero = |name, t: f64| require(name, t, t > -ZERO_CELSIUS, "a temperature above -273.15 °C");
        require("planck_r1", self.planck_r1, self.planck_r1 != 0.0, "a finite non-zero number")?;
        require("planck_r2", self.planck_r2, self.planck_r2 != 0.0, "a finite non-zero number")?;
        require("planck_b", self.planck_b, self.planck_b > 0.0, "a finite number above 0")?;
        require("planck_f", self.planck_f, true, "a finite number")?;
        require("planck_o", self.planck_o, true, "a finite number")?;
        let e = self.emissivity;
        require("emissivity", e, e > 0.0 && e <= 1.0, "a number in (0, 1]")?;
        require("object_distance", self.object_distance, self.object_distance >= 0.0, "a distance >= 0 m")?;
        above_zero("reflected_temperature", self.reflected_temperature)?;
        above_zero("atmospheric_temperature", self.atmospheric_temperature)?;
        above_zero("window_temperature", self.window_temperature)?;
        let w = self.window_transmission;
        require("window_transmission", w, w > 0.0 && w <= 1.0, "a number in (0, 1]")?;
        let h = self.relative_humidity;
        require("relative_humidity", h, (0.0..=100.0).contains(&h), "a percentage in [0, 100]")?;
        for (name, v) in [("alpha1", self.alpha1), ("alpha2", self.alpha2), ("beta1", self.beta1)] {
            require(name, v, true, "a finite number")?;
        }
        require("beta2", self.beta2, true, "a finite number")?;
        require("x", self.x, true, "a finite number")
    }

    /// Water vapour in the air (the humidity term of the transmission), from the relative
    /// humidity and the air temperature.
    fn water_vapour(&self) -> f64 {
        let t = self.atmospheric_temperature;
        let saturated = (1.5587 + 0.06939 * t - 0.00027816 * t * t + 0.00000068455 * t * t * t).exp();
        self.relative_humidity / 100.0 * saturated
    }

    /// Transmission of the atmosphere over half the object distance (one side of the window).
    pub fn transmission(&self) -> f64 {
        let root_h2o = self.water_vapour().sqrt();
        let path = (self.object_distance / 2.0).sqrt();
        let band = |alpha: f64, beta: f64| (-path * (alpha + beta * root_h2o)).exp();
        self.x * band(self.alpha1, self.beta1) + (1.0 - self.x) * band(self.alpha2, self.beta2)
    }

    /// The validated model; an `Error::Value` names the field that makes it meaningless.
    pub fn model(&self) -> Result<Model> {
        self.check()?;
        let tau = self.transmission();
        if !(tau > 0.0 && tau.is_finite()) {
            return Err(Error::Value(format!(
                "the atmospheric transmission is {tau} (from object_distance = {}, relative_humidity = {}, \
                 atmospheric_temperature = {} and alpha1, alpha2, beta1, beta2, x): expected a number above 0",
                self.object_distance, self.relative_humidity, self.atmospheric_temperature
            )));
        }
        let ratio = self.planck_r1 / self.planck_r2;
        let mut m = Model { ratio, b: self.planck_b, f: self.planck_f, o: self.planck_o, gain: 0.0, background: 0.0 };
        let signal = |name: &str, celsius: f64| {
            let u = m.signal(celsius + ZERO_CELSIUS);
            require(name, celsius, u.is_finite(), "a temperature whose calibrated signal is finite").map(|_| u)
        };
        let reflected = signal("reflected_temperature", self.reflected_temperature)?;
        let atmosphere = signal("atmospheric_temperature", self.atmospheric_temperature)?;
        let window = signal("window_temperature", self.window_temperature)?;
        let (e, w) = (self.emissivity, self.window_transmission);
        m.gain = e * tau * w * tau;
        m.background = (1.0 - e) * tau * w * tau * reflected
            + (1.0 - tau) * w * tau * atmosphere
            + (1.0 - w) * tau * window
            + (1.0 - tau) * atmosphere;
        Ok(m)
    }
}

impl Model {
    /// The calibrated signal of a blackbody at `kelvin`.
    #[inline(always)]
    fn signal(&self, kelvin: f64) -> f64 {
        self.ratio / (math::exp_non_negative(self.b / kelvin) - self.f) - self.o
    }

    /// Kelvin from counts; NaN outside the calibration's domain.
    #[inline(always)]
    fn kelvin(&self, counts: f64) -> f64 {
        let object = (counts - self.background) / self.gain;
        let arg = self.ratio / (object + self.o) + self.f;
        let t = self.b / math::ln_at_least_one(arg);
        if arg > 1.0 && t.is_finite() {
            t
        } else {
            f64::NAN
        }
    }

    /// Counts from kelvin; NaN for temperatures that are not finite and above 0 K.
    #[inline(always)]
    fn counts(&self, kelvin: f64) -> f64 {
        let s = self.gain * self.signal(kelvin) + self.background;
        if kelvin > 0.0 && s.is_finite() {
            s
        } else {
            f64::NAN
        }
    }
}

/// A sample type the conversions accept.
pub trait Sample: crate::kernel::Sample {
    fn value(self) -> f64;
    /// The value as an integer, for integer sample types (they may use a table of values).
    fn integer(self) -> Option<i64>;
}

macro_rules! sample {
    (integer: $($t:ty),*) => {$(
        impl Sample for $t {
            #[inline]
            fn value(self) -> f64 { f64::from(self) }
            #[inline]
            fn integer(self) -> Option<i64> { Some(i64::from(self)) }
        }
    )*};
    (float: $($t:ty),*) => {$(
        impl Sample for $t {
            #[inline]
            fn value(self) -> f64 { f64::from(self) }
            #[inline]
            fn integer(self) -> Option<i64> { None }
        }
    )*};
}
sample!(integer: u8, u16, i16, u32);
sample!(float: half::f16, f32, f64);

/// The result of a conversion: one value per input, and how many became NaN.
#[derive(Debug, Clone, PartialEq)]
pub struct Converted {
    pub values: Vec<f64>,
    /// Finite inputs outside the calibration's domain (now NaN).
    pub outside: usize,
    /// Inputs that were NaN or infinite (now NaN).
    pub nonfinite: usize,
}

const CHUNK: usize = 1 << 14;

/// `f` of every input, in parallel; integer inputs spanning a range much smaller than their
/// count go through a table of `f` over that range (the same values, fewer logarithms).
fn convert<T: Sample>(input: &[T], f: impl Fn(f64) -> f64 + Sync + Copy) -> Result<Converted> {
    match integer_table(input, f) {
        Some((low, table)) => looked_up(input, low, &table),
        None => computed(input, f),
    }
}

/// `table[x − low]` of every integer input (the table spans their min..=max), each output
/// written once; the NaN entries (counts outside the calibration's domain) counted only when
/// the table has one.
fn looked_up<T: Sample>(input: &[T], low: i64, table: &[f64]) -> Result<Converted> {
    // refused as an error, not an abort, when the memory is not there
    let mut values: Vec<f64> = crate::budget::try_with_capacity(input.len())?;
    let unwritten = &mut values.spare_capacity_mut()[..input.len()];
    unwritten.par_chunks_mut(CHUNK).zip(input.par_chunks(CHUNK)).for_each(|(out, run)| look_up(run, low, table, out));
    // SAFETY: the chunks of `unwritten` cover its input.len() values, each written above
    unsafe { values.set_len(input.len()) };
    let outside = if table.iter().any(|v| v.is_nan()) {
        values.par_chunks(CHUNK).map(|run| run.iter().filter(|v| v.is_nan()).count()).sum()
    } else {
        0
    };
    Ok(Converted { values, outside, nonfinite: 0 })
}

avx2_copy! {
    /// `out[i] = table[inp[i] − low]` (NaN for an input the table does not span), without a
    /// branch per value (gathered in AVX2 code when the CPU has it).
    fn look_up[T: Sample](inp: &[T], low: i64, table: &[f64], out: &mut [MaybeUninit<f64>])
    => look_up_avx2, look_up_portable
}

#[inline(always)]
fn look_up_portable<T: Sample>(inp: &[T], low: i64, table: &[f64], out: &mut [MaybeUninit<f64>]) {
    let Some(last) = table.len().checked_sub(1) else {
        out.iter_mut().for_each(|value| _ = value.write(f64::NAN));
        return;
    };
    for (value, x) in out.iter_mut().zip(inp) {
        let at = x.integer().map_or(usize::MAX, |v| v.wrapping_sub(low) as usize);
        let found = table[at.min(last)];
        value.write(if at <= last { found } else { f64::NAN });
    }
}

/// `f` of every input, a chunk at a time in AVX2 code when the CPU has it.
fn computed<T: Sample>(input: &[T], f: impl Fn(f64) -> f64 + Sync + Copy) -> Result<Converted> {
    let mut values = crate::budget::try_filled(input.len(), 0.0)?;
    let (outside, nonfinite) = values
        .par_chunks_mut(CHUNK)
        .zip(input.par_chunks(CHUNK))
        .map(|(out, inp)| {
            apply(inp, out, f);
            count_nan(inp, out)
        })
        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    Ok(Converted { values, outside, nonfinite })
}

avx2_copy! {
    /// `out[i] = f(inp[i])`, in AVX2 code when the CPU has it.
    fn apply[T: Sample](inp: &[T], out: &mut [f64], f: impl Fn(f64) -> f64 + Copy)
    => apply_avx2, apply_portable
}

#[inline(always)]
fn apply_portable<T: Sample>(inp: &[T], out: &mut [f64], f: impl Fn(f64) -> f64 + Copy) {
    inp.iter().zip(out.iter_mut()).for_each(|(&x, o)| *o = f(x.value()));
}

/// NaN results from finite inputs (outside the domain), and from non-finite inputs.
fn count_nan<T: Sample>(inp: &[T], out: &[f64]) -> (usize, usize) {
    inp.iter().zip(out).fold((0, 0), |(outside, nonfinite), (&x, o)| {
        let nan = o.is_nan() as usize;
        let finite = x.value().is_finite() as usize;
        (outside + (nan & finite), nonfinite + (nan & (1 - finite)))
    })
}

/// Tables of fewer entries are computed on the calling thread (a few microseconds).
const PARALLEL_TABLE: usize = 1 << 12;

/// `f` over `min..=max` of integer inputs, when that range is under a quarter of their count.
fn integer_table<T: Sample>(input: &[T], f: impl Fn(f64) -> f64 + Sync) -> Option<(i64, Vec<f64>)> {
    input.first()?.integer()?; // float inputs: no table
                               // one thread: a vectorised pass over integers is shorter than waking the pool
    let (low, high) = crate::kernel::min_max(input, &[])?;
    let (low, high) = (crate::kernel::Sample::to_i64(low), crate::kernel::Sample::to_i64(high));
    let span = usize::try_from(high.checked_sub(low)?).ok()? + 1;
    if span > input.len() / 4 {
        return None;
    }
    let entry = |i: usize| f((low + i as i64) as f64);
    Some((
        low,
        if span < PARALLEL_TABLE {
            (0..span).map(entry).collect()
        } else {
            (0..span).into_par_iter().map(entry).collect()
        },
    ))
}

/// Temperatures (in `unit`) of raw counts.
pub fn temperatures<T: Sample>(counts: &[T], calibration: &Calibration, unit: Unit) -> Result<Converted> {
    let model = calibration.model()?;
    let shift = unit.to_kelvin();
    convert(counts, |s| model.kelvin(s) - shift)
}

/// Raw counts (unrounded) of temperatures in `unit`: the inverse of [`temperatures`].
pub fn counts<T: Sample>(temperatures: &[T], calibration: &Calibration, unit: Unit) -> Result<Converted> {
    let model = calibration.model()?;
    let shift = unit.to_kelvin();
    convert(temperatures, |t| model.counts(t + shift))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Thermimage's README example: raw 17994.06 with its SC660 calibration is 23.31223 °C.
    fn readme() -> Calibration {
        Calibration {
            planck_r1: 21106.77,
            planck_r2: 0.012545258,
            planck_b: 1501.0,
            planck_f: 1.0,
            planck_o: -7340.0,
            emissivity: 0.95,
            object_distance: 1.0,
            reflected_temperature: 20.0,
            atmospheric_temperature: 20.0,
            window_temperature: 20.0,
            window_transmission: 0.96,
            relative_humidity: 50.0,
            alpha1: 0.006569,
            alpha2: 0.01262,
            beta1: -0.002276,
            beta2: -0.00667,
            x: 1.9,
        }
    }

    #[test]
    fn worked_value_and_inverse() {
        let t = temperatures(&[17994.06f64], &readme(), Unit::Celsius).unwrap();
        assert!((t.values[0] - 23.31223).abs() < 5e-6, "{}", t.values[0]);
        let k = temperatures(&[17994.06f64], &readme(), Unit::Kelvin).unwrap();
        assert!((k.values[0] - t.values[0] - ZERO_CELSIUS).abs() < 1e-9);
        let back = counts(&t.values, &readme(), Unit::Celsius).unwrap();
        assert!((back.values[0] - 17994.06).abs() < 1e-7, "{}", back.values[0]);
    }

    #[test]
    fn table_and_direct_paths_agree_and_count_the_domain() {
        let raw: Vec<u16> = (0..40_000u32).map(|i| (i % 9000) as u16).collect();
        let via_table = temperatures(&raw, &readme(), Unit::Kelvin).unwrap();
        let as_float: Vec<f64> = raw.iter().map(|&r| f64::from(r)).collect();
        let direct = temperatures(&as_float, &readme(), Unit::Kelvin).unwrap();
        assert_eq!(via_table.values.len(), raw.len());
        for (a, b) in via_table.values.iter().zip(&direct.values) {
            assert!(a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()));
        }
        assert!(via_table.outside > 0 && via_table.outside == direct.outside && via_table.nonfinite == 0);
        let odd = temperatures(&[f64::NAN, f64::INFINITY, 17994.06], &readme(), Unit::Kelvin).unwrap();
        assert_eq!((odd.outside, odd.nonfinite), (0, 2));
    }

    #[test]
    fn a_table_look_up_writes_every_value_once() {
        // small enough for Miri, which checks the writes into the unfilled output: 96 counts
        // over 24 levels go through the table, each value equal to the direct conversion
        // (Miri's logarithms are a few ulps off, and differ between the two paths)
        let raw: Vec<u16> = (0..96u16).map(|i| 17_000 + (i * 7) % 24).collect();
        let via_table = temperatures(&raw, &readme(), Unit::Kelvin).unwrap();
        let direct: Vec<f64> =
            raw.iter().map(|&r| temperatures(&[f64::from(r)], &readme(), Unit::Kelvin).unwrap().values[0]).collect();
        assert_eq!(via_table.values.len(), raw.len());
        for (a, b) in via_table.values.iter().zip(&direct) {
            assert!(if cfg!(miri) { (a - b).abs() <= 1e-12 * b.abs() } else { a.to_bits() == b.to_bits() }, "{a} {b}");
        }
        assert_eq!((via_table.outside, via_table.nonfinite), (0, 0));
    }

    #[test]
    fn invalid_fields_are_named() {
        let bad = |c: Calibration| temperatures(&[1u16], &c, Unit::Celsius).unwrap_err().to_string();
        assert!(bad(Calibration { planck_r2: 0.0, ..readme() }).starts_with("planck_r2 = 0"));
        assert!(bad(Calibration { planck_b: -1.0, ..readme() }).starts_with("planck_b = -1"));
        assert!(bad(Calibration { emissivity: 1.5, ..readme() }).contains("emissivity = 1.5 is invalid"));
        assert!(bad(Calibration { object_distance: -2.0, ..readme() }).starts_with("object_distance"));
        assert!(bad(Calibration { relative_humidity: 101.0, ..readme() }).starts_with("relative_humidity"));
        assert!(bad(Calibration { window_temperature: f64::NAN, ..readme() }).starts_with("window_temperature"));
        assert!(bad(Calibration { object_distance: 1e12, ..readme() }).contains("atmospheric transmission"));
    }
}
