//! A frame as registration receives it: the caller's samples, of any supported type.
//!
//! Most steps work on a float64 [`Plane`] with its mask. Phase correlation needs less: the
//! frame's mean and its tapered rows, which it reads from the samples themselves. So a clean
//! frame (no mask, every value finite) becomes a plane only when a later step asks for one
//! (an alias or rival check, a refinement, a rotation search, NMI); a translation by phase
//! correlation usually never does. Masked frames and frames with NaN/Inf pixels are
//! converted at once, since their mask is needed from the start.

use std::borrow::Cow;
use std::cell::OnceCell;

use super::image::{check_shape, flat_level, lane_sum, Plane};
use super::window::taper_row;
use crate::error::Result;
use crate::kernel::Sample;

/// A frame to register: `rows × cols` pixels, `n_valid` of them taking part.
pub struct Frame<'a> {
    pub rows: usize,
    pub cols: usize,
    pub n_valid: usize,
    /// Mean of the valid pixels.
    pub mean: f64,
    pixels: Pixels<'a>,
}

enum Pixels<'a> {
    /// Converted already: a masked frame, one with NaN/Inf pixels, or a plane given as such.
    Plane(Cow<'a, Plane>),
    /// All valid: read directly, converted on first use.
    Samples { samples: Box<dyn Samples + 'a>, plane: OnceCell<Plane> },
}

/// What a frame's own samples can do, whatever their type.
trait Samples: Send + Sync {
    fn flat_level(&self) -> Option<f64>;
    fn taper_row(&self, r: usize, cols: usize, mean: f64, w_row: f64, w_cols: &[f64], line: &mut [f32]);
    fn plane(&self, rows: usize, cols: usize) -> Plane;
}

impl<T: Sample> Samples for &[T] {
    fn flat_level(&self) -> Option<f64> {
        flat_level(self.iter().map(|v| v.to_f64()))
    }

    fn taper_row(&self, r: usize, cols: usize, mean: f64, w_row: f64, w_cols: &[f64], line: &mut [f32]) {
        taper_row(&self[r * cols..(r + 1) * cols], None, mean, w_row, w_cols, line);
    }

    fn plane(&self, rows: usize, cols: usize) -> Plane {
        Plane::from_clean(self, rows, cols)
    }
}

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
        if mask.is_none() {
            // one pass: the sum is finite exactly when every value is (float64 values so
            // large that it overflows are rare enough to take the general path below)
            let sum = lane_sum(data);
            if sum.is_finite() {
                let n = data.len();
                let mean = if n == 0 { 0.0 } else { sum / n as f64 };
                let pixels = Pixels::Samples { samples: Box::new(data), plane: OnceCell::new() };
                return Ok(Frame { rows, cols, n_valid: n, mean, pixels });
            }
        }
        Ok(Plane::from_samples(data, rows, cols, mask, what)?.into())
    }

    /// The frame as a float64 plane with its mask (converted on the first call).
    pub fn plane(&self) -> &Plane {
        match &self.pixels {
            Pixels::Plane(plane) => plane,
            Pixels::Samples { samples, plane } => plane.get_or_init(|| samples.plane(self.rows, self.cols)),
        }
    }

    /// The valid-pixel mask, or None when every pixel is valid.
    pub fn valid(&self) -> Option<&[bool]> {
        match &self.pixels {
            Pixels::Plane(plane) if plane.n_valid < plane.values.len() => Some(&plane.valid),
            _ => None,
        }
    }

    /// The common value of the valid pixels if they are all equal (see [`flat_level`]).
    pub fn flat_level(&self) -> Option<f64> {
        match &self.pixels {
            Pixels::Plane(plane) => plane.flat_level(),
            Pixels::Samples { samples, .. } => samples.flat_level(),
        }
    }

    /// Row `r` of the tapered frame `(v − mean)·w_row·w_cols[c]` (0 at invalid pixels) into
    /// `line`, in float32: the input of a transform.
    pub fn taper_row(&self, r: usize, w_row: f64, w_cols: &[f64], line: &mut [f32]) {
        let cols = self.cols;
        match &self.pixels {
            Pixels::Plane(plane) => {
                let span = r * cols..(r + 1) * cols;
                let valid = self.valid().map(|v| &v[span.clone()]);
                taper_row(&plane.values[span], valid, self.mean, w_row, w_cols, line);
            }
            Pixels::Samples { samples, .. } => samples.taper_row(r, cols, self.mean, w_row, w_cols, line),
        }
    }
}

impl<'a> From<Cow<'a, Plane>> for Frame<'a> {
    fn from(plane: Cow<'a, Plane>) -> Frame<'a> {
        let (rows, cols, n_valid, mean) = (plane.rows, plane.cols, plane.n_valid, plane.mean());
        Frame { rows, cols, n_valid, mean, pixels: Pixels::Plane(plane) }
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

    /// A clean frame read from its samples and the same frame converted first agree on
    /// everything registration asks of them.
    #[test]
    fn samples_and_their_plane_agree() {
        let (rows, cols) = (5, 7);
        let data: Vec<u16> = (0..rows * cols).map(|i| ((i * 7919) % 1013) as u16).collect();
        let direct = Frame::new(&data, rows, cols, None, "real").unwrap();
        let converted = Frame::from(Plane::from_samples(&data, rows, cols, None, "real").unwrap());
        assert!(matches!(direct.pixels, Pixels::Samples { .. }));
        assert_eq!((direct.n_valid, direct.mean), (converted.n_valid, converted.mean));
        assert_eq!(direct.valid(), None);
        assert_eq!(converted.valid(), None);
        assert_eq!(direct.flat_level(), None);
        let w_cols: Vec<f64> = (0..cols).map(|c| 0.1 * c as f64).collect();
        for r in 0..rows {
            let (mut a, mut b) = (vec![0.0f32; cols], vec![0.0f32; cols]);
            direct.taper_row(r, 0.5, &w_cols, &mut a);
            converted.taper_row(r, 0.5, &w_cols, &mut b);
            assert_eq!(a, b);
        }
        assert_eq!(direct.plane().values, converted.plane().values);
        let flat = vec![3.5f32; rows * cols];
        assert_eq!(Frame::new(&flat, rows, cols, None, "sim").unwrap().flat_level(), Some(3.5));
    }

    /// NaN/Inf pixels or a mask make the frame a converted plane with its mask, and the mean
    /// is that of the valid pixels.
    #[test]
    fn excluded_pixels_are_converted_at_once() {
        let data = [1.0f32, f32::NAN, 3.0, 4.0, f32::INFINITY, 8.0];
        let frame = Frame::new(&data, 2, 3, None, "sim").unwrap();
        assert!(matches!(frame.pixels, Pixels::Plane(_)));
        assert_eq!((frame.n_valid, frame.mean), (4, 4.0));
        assert_eq!(frame.valid(), Some(&[true, false, true, true, false, true][..]));
        let mut line = [f32::NAN; 3];
        frame.taper_row(1, 1.0, &[1.0; 3], &mut line);
        assert_eq!(line, [0.0, 0.0, 4.0]);

        let mask = [true, true, true, false, true, true];
        let frame = Frame::new(&[1u8, 2, 3, 200, 4, 5], 2, 3, Some(&mask), "real").unwrap();
        assert_eq!((frame.n_valid, frame.mean), (5, 3.0));
        assert!(Frame::new(&data, 3, 3, None, "real").is_err());
        assert!(Frame::new(&data, 2, 3, Some(&mask[..4]), "real").is_err());
    }
}
