//! A frame as registration receives it: the caller's samples, of any supported type.
//!
//! Most steps work on a float64 [`Plane`] with its mask. Phase correlation needs less: the
//! frame's mean and its tapered rows, which it reads from the samples themselves. So a clean
//! frame (no mask, every value finite) becomes a plane only when a later step asks for one
//! (an alias or rival check, a refinement, a rotation search, NMI); a translation by phase
//! correlation usually never does. Masked frames and frames with NaN/Inf pixels are
//! converted at once, since their mask is needed from the start.
//!
//! Every step sees working values, `v·factor − shift` ([`Normalisation`]): O(1) and
//! centred, whatever the frame's units (docs/registration.md, "Any scale").

use std::borrow::Cow;
use std::cell::OnceCell;

use super::image::{check_shape, lane_sum_range, Plane};
use super::normal::{flat_level, Normalisation};
use super::window::taper_row;
use crate::error::Result;
use crate::kernel::Sample;

/// A frame to register: `rows × cols` pixels, `n_valid` of them taking part.
pub struct Frame<'a> {
    pub rows: usize,
    pub cols: usize,
    pub n_valid: usize,
    /// Mean of the valid pixels' working values (about 0).
    pub mean: f64,
    /// The valid pixels' smallest and largest value, as given (None: a plane of working
    /// values, whose extremes are found when asked for).
    extremes: Option<(f64, f64)>,
    pixels: Pixels<'a>,
}

enum Pixels<'a> {
    /// Converted already, to working values: a masked frame, one with NaN/Inf pixels, or a
    /// plane given as such.
    Plane(Cow<'a, Plane>),
    /// All valid: read directly and normalised on the fly, converted on first use.
    Samples { samples: Box<dyn Samples + 'a>, normal: Normalisation, plane: OnceCell<Plane> },
}

/// What a frame's own samples can do, whatever their type.
trait Samples: Send + Sync {
    fn taper_row(&self, r: usize, cols: usize, centring: Normalisation, w_row: f64, w_cols: &[f64], line: &mut [f32]);
    /// The samples as a plane of working values.
    fn plane(&self, rows: usize, cols: usize, normal: Normalisation) -> Plane;
    /// Σ working values (the second pass of an accurate mean).
    fn working_sum(&self, normal: Normalisation) -> f64;
}

impl<T: Sample> Samples for &[T] {
    fn taper_row(&self, r: usize, cols: usize, centring: Normalisation, w_row: f64, w_cols: &[f64], line: &mut [f32]) {
        taper_row(&self[r * cols..(r + 1) * cols], None, centring, w_row, w_cols, line);
    }

    fn plane(&self, rows: usize, cols: usize, normal: Normalisation) -> Plane {
        Plane::from_clean(self, rows, cols, normal)
    }

    fn working_sum(&self, normal: Normalisation) -> f64 {
        let mut lanes = [0.0f64; 8];
        let chunks = self.chunks_exact(8);
        let tail: f64 = chunks.remainder().iter().map(|v| normal.apply(v.to_f64())).sum();
        for chunk in chunks {
            lanes.iter_mut().zip(chunk).for_each(|(acc, v)| *acc += normal.apply(v.to_f64()));
        }
        lanes.iter().sum::<f64>() + tail
    }
}

/// A shift beyond this many units of the spread leaves the mean's rounding visible in the
/// working values: the mean is then summed again over them.
const LARGE_SHIFT: f64 = (1u64 << 20) as f64;

impl<'a> Frame<'a> {
    /// A frame of any supported sample type; `mask` false and non-finite values are
    /// excluded. `what` names the frame in errors.
    pub fn new<T: Sample>(
        data: &'a [T],
        rows: usize,
        cols: usize,
        mask: Option<&[bool]>,
        what: &str,
    ) -> Result<Frame<'a>> {
        check_shape(data.len(), rows, cols, mask, what)?;
        if mask.is_none() && !data.is_empty() {
            // one pass: the sum is finite exactly when every value is (float64 values so
            // large that it overflows are rare enough to take the general path below)
            let (sum, lo, hi) = lane_sum_range(data);
            if sum.is_finite() {
                let n = data.len();
                let samples: Box<dyn Samples + 'a> = Box::new(data);
                let normal = Normalisation::new(lo, hi, |factor| sum * factor / n as f64);
                // the sum's rounding, scaled, is all that separates the working mean from 0
                let mean = if normal.shift.abs() > LARGE_SHIFT { samples.working_sum(normal) / n as f64 } else { 0.0 };
                let pixels = Pixels::Samples { samples, normal, plane: OnceCell::new() };
                return Ok(Frame { rows, cols, n_valid: n, mean, extremes: Some((lo, hi)), pixels });
            }
        }
        Ok(Frame::normalised(Plane::from_samples(data, rows, cols, mask, what)?))
    }

    /// A frame of the plane's values as given: its valid values become working values.
    fn normalised(mut plane: Plane) -> Frame<'static> {
        let (lo, hi) = plane.range();
        // scaled first, so that the mean of values near ±f64::MAX cannot overflow
        plane.normalise(Normalisation::new(lo, hi, |_| 0.0));
        plane.normalise(Normalisation { factor: 1.0, shift: plane.mean() });
        Frame { extremes: Some((lo, hi)), ..Frame::from(plane) }
    }

    /// The frame as a float64 plane of working values with its mask (converted on the
    /// first call).
    pub fn plane(&self) -> &Plane {
        match &self.pixels {
            Pixels::Plane(plane) => plane,
            Pixels::Samples { samples, normal, plane } => {
                plane.get_or_init(|| samples.plane(self.rows, self.cols, *normal))
            }
        }
    }

    /// The valid-pixel mask, or None when every pixel is valid.
    pub fn valid(&self) -> Option<&[bool]> {
        match &self.pixels {
            Pixels::Plane(plane) if plane.n_valid < plane.values.len() => Some(&plane.valid),
            _ => None,
        }
    }

    /// The common value of the valid pixels (as given) if they are all equal (see
    /// [`flat_level`]).
    pub fn flat_level(&self) -> Option<f64> {
        let (lo, hi) = self.extremes.unwrap_or_else(|| self.plane().range());
        flat_level(lo, hi)
    }

    /// Row `r` of the tapered frame `(working value − mean)·w_row·w_cols[c]` (0 at invalid
    /// pixels) into `line`, in float32: the input of a transform.
    pub fn taper_row(&self, r: usize, w_row: f64, w_cols: &[f64], line: &mut [f32]) {
        let cols = self.cols;
        match &self.pixels {
            Pixels::Plane(plane) => {
                let span = r * cols..(r + 1) * cols;
                let valid = self.valid().map(|v| &v[span.clone()]);
                let centring = Normalisation { factor: 1.0, shift: self.mean };
                taper_row(&plane.values[span], valid, centring, w_row, w_cols, line);
            }
            Pixels::Samples { samples, normal, .. } => {
                let centring = Normalisation { shift: normal.shift + self.mean, ..*normal };
                samples.taper_row(r, cols, centring, w_row, w_cols, line)
            }
        }
    }
}

impl<'a> From<Cow<'a, Plane>> for Frame<'a> {
    /// A plane of working values (made by registration from frames that were normalised,
    /// such as a turned simulated frame), used as it is.
    fn from(plane: Cow<'a, Plane>) -> Frame<'a> {
        let (rows, cols, n_valid, mean) = (plane.rows, plane.cols, plane.n_valid, plane.mean());
        Frame { rows, cols, n_valid, mean, extremes: None, pixels: Pixels::Plane(plane) }
    }
}

impl From<Plane> for Frame<'static> {
    fn from(plane: Plane) -> Frame<'static> {
        Cow::<Plane>::Owned(plane).into()
    }
}

impl<'a> From<&'a Plane> for Frame<'a> {
    fn from(plane: &'a Plane) -> Frame<'a> {
        Cow::Borrowed(plane).into()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tapered_rows(frame: &Frame, w_cols: &[f64]) -> Vec<f32> {
        let mut out = vec![0.0f32; frame.rows * frame.cols];
        for (r, line) in out.chunks_exact_mut(frame.cols).enumerate() {
            frame.taper_row(r, 0.5, w_cols, line);
        }
        out
    }

    /// Equal up to the rounding of a mean (the sums' order differs between the paths).
    fn close(a: &[f64], b: &[f64]) -> bool {
        a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-14)
    }

    /// Values over their spread.
    fn unit_spread(values: &[f64]) -> Vec<f64> {
        let (lo, hi) = values.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| (l.min(v), h.max(v)));
        values.iter().map(|v| v / (hi - lo)).collect()
    }

    /// A clean frame read from its samples and the same frame converted first agree on
    /// everything registration asks of them.
    #[test]
    fn samples_and_their_plane_agree() {
        let (rows, cols) = (5, 7);
        let data: Vec<u16> = (0..rows * cols).map(|i| ((i * 7919) % 1013) as u16).collect();
        let direct = Frame::new(&data, rows, cols, None, "real").unwrap();
        let converted = Frame::normalised(Plane::from_samples(&data, rows, cols, None, "real").unwrap());
        assert!(matches!(direct.pixels, Pixels::Samples { .. }));
        assert_eq!(direct.n_valid, converted.n_valid);
        assert!(direct.mean.abs() < 1e-15 && converted.mean.abs() < 1e-15);
        assert_eq!(direct.valid(), None);
        assert_eq!(converted.valid(), None);
        assert_eq!(direct.flat_level(), None);
        let w_cols: Vec<f64> = (0..cols).map(|c| 0.1 * c as f64).collect();
        let (a, b) = (tapered_rows(&direct, &w_cols), tapered_rows(&converted, &w_cols));
        assert!(a.iter().zip(&b).all(|(x, y)| (x - y).abs() <= 1e-6), "{a:?} {b:?}");
        assert!(direct.plane().values.iter().zip(converted.plane().values.iter()).all(|(x, y)| (x - y).abs() < 1e-14));
        let flat = vec![3.5f32; rows * cols];
        assert_eq!(Frame::new(&flat, rows, cols, None, "sim").unwrap().flat_level(), Some(3.5));
    }

    /// The working values are `(v − mean)·factor`, the factor a power of two bringing the
    /// spread to [1, 2): the same for a frame in counts and the frame in any other units.
    #[test]
    fn working_values_do_not_depend_on_the_scale() {
        let (rows, cols) = (6, 8);
        let counts: Vec<f64> = (0..rows * cols).map(|i| 2600.0 + ((i * 7919) % 113) as f64).collect();
        let frame = Frame::new(&counts, rows, cols, None, "real").unwrap();
        let mean = counts.iter().sum::<f64>() / counts.len() as f64;
        let (lo, hi) = counts.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| (l.min(v), h.max(v)));
        let factor = super::super::normal::unit_factor(lo, hi);
        assert!((1.0..2.0).contains(&((hi - lo) * factor)));
        for (w, v) in frame.plane().values.iter().zip(&counts) {
            assert!((w - (v - mean) * factor).abs() < 1e-12, "{w} {v}");
        }
        let w_cols = vec![1.0; cols];
        let reference = tapered_rows(&frame, &w_cols);
        // a power of two: bit-identical working values, through either path
        for scale in [2f64.powi(-1000), 2f64.powi(-900), 2f64.powi(110), 2f64.powi(990)] {
            let scaled: Vec<f64> = counts.iter().map(|v| v * scale).collect();
            let direct = Frame::new(&scaled, rows, cols, None, "real").unwrap();
            assert_eq!(direct.plane().values, frame.plane().values, "{scale:e}");
            assert_eq!(tapered_rows(&direct, &w_cols), reference, "{scale:e}");
            let mask = vec![true; rows * cols];
            let converted = Frame::new(&scaled, rows, cols, Some(&mask), "real").unwrap();
            assert!(matches!(converted.pixels, Pixels::Plane(_)));
            assert!(close(&converted.plane().values, &frame.plane().values), "{scale:e}");
        }
        // any other scale, in float32 up to its largest values: equal up to its rounding
        for scale in [1e-30f64, 1e30, 1e35, 1.2e35] {
            let scaled: Vec<f32> = counts.iter().map(|v| (v * scale) as f32).collect();
            let direct = Frame::new(&scaled, rows, cols, None, "real").unwrap();
            let (a, b) = (unit_spread(&direct.plane().values), unit_spread(&frame.plane().values));
            assert!(a.iter().zip(&b).all(|(x, y)| (x - y).abs() < 1e-5), "{scale:e}");
        }
        // subnormal float64: working values of order 1e-6 at least, equal up to the values'
        // own rounding
        let tiny: Vec<f64> = counts.iter().map(|v| v * 1e-315).collect();
        let direct = Frame::new(&tiny, rows, cols, None, "real").unwrap();
        let (a, b) = (unit_spread(&direct.plane().values), unit_spread(&frame.plane().values));
        assert!(a.iter().zip(&b).all(|(x, y)| (x - y).abs() < 1e-5));
        assert!(direct.plane().values.iter().fold(0.0f64, |m, v| m.max(v.abs())) > 1e-6);
        // float64 so large that the sum overflows: the general path, the same working values
        let huge: Vec<f64> = counts.iter().map(|v| v * 2f64.powi(1012)).collect();
        let direct = Frame::new(&huge, rows, cols, None, "real").unwrap();
        assert!(matches!(direct.pixels, Pixels::Plane(_)));
        assert!(close(&direct.plane().values, &frame.plane().values));
        assert!(direct.mean.abs() < 1e-12, "{}", direct.mean);
    }

    /// NaN/Inf pixels or a mask make the frame a converted plane with its mask, and the mean
    /// is that of the valid pixels.
    #[test]
    fn excluded_pixels_are_converted_at_once() {
        let data = [1.0f32, f32::NAN, 3.0, 4.0, f32::INFINITY, 8.0];
        let frame = Frame::new(&data, 2, 3, None, "sim").unwrap();
        assert!(matches!(frame.pixels, Pixels::Plane(_)));
        // valid 1, 3, 4, 8: mean 4, spread 7 → factor 1/4
        assert_eq!((frame.n_valid, frame.mean), (4, 0.0));
        assert_eq!(frame.valid(), Some(&[true, false, true, true, false, true][..]));
        assert_eq!(&frame.plane().values[..], &[-0.75, 0.0, -0.25, 0.0, 0.0, 1.0]);
        let mut line = [f32::NAN; 3];
        frame.taper_row(1, 1.0, &[1.0; 3], &mut line);
        assert_eq!(line, [0.0, 0.0, 1.0]);
        assert_eq!(frame.flat_level(), None);

        let mask = [true, true, true, false, true, true];
        let frame = Frame::new(&[1u8, 2, 3, 200, 4, 5], 2, 3, Some(&mask), "real").unwrap();
        assert_eq!((frame.n_valid, frame.mean), (5, 0.0));
        assert_eq!(frame.extremes, Some((1.0, 5.0)));
        assert!(Frame::new(&data, 3, 3, None, "real").is_err());
        assert!(Frame::new(&data, 2, 3, Some(&mask[..4]), "real").is_err());
    }
}
