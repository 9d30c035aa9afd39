//! 3-D noise: the sufficient statistics of a frame sequence for the directional-average
//! decomposition of D'Agostino & Webb (1991), accumulated one frame at a time.
//!
//! A recording is a cube of T frames × V rows × H columns. The seven parts of the model
//! (t, v, h, tv, th, vh, tvh) are functions of directional averages only, so a pass keeps
//!
//! * per pixel: the temporal sum Σₜx and sum of squares Σₜx² (V·H values each),
//! * per frame: the row sums Σₕx (V values) and column sums Σᵥx (H values),
//!
//! memory O(V·H + T·(V+H)), never the cube. [`NoiseSums`] is mergeable: the sums of two
//! disjoint frame ranges merged (`a.merge(&b)`: b's frames after a's) equal one pass over
//! both, exactly for integer frames, so a long recording can be spread over threads,
//! processes or Dask workers. [`NoiseSums::finish`] turns them into the seven sums of
//! squares of a balanced three-way ANOVA with one observation per cell.
//!
//! Integer frames (uint8, uint16, int16, uint32) are summed exactly (i64/u64/u128), and
//! the sums of squares are formed exactly as integers `N²·SS` (256 bits, [`wide::U256`]):
//! the seven parts add up to the total exactly. Float frames (float16/32/64) are promoted
//! to f64 and centred on a per-pixel pivot (the first frame) with compensated sums; see
//! `docs/noise.md` for the error analysis.

mod bytes;
mod engine;
mod exact;
mod float;
pub mod wide;

use crate::{Error, Result};

pub use engine::{noise_sums_from_array, noise_sums_from_paths, run_pass, FrameSource, PassOptions, Samples, Window};
pub use exact::IntAcc;
pub use float::FloatAcc;
pub use wide::U256;

/// The seven parts, in the order every array of this module uses.
pub const PARTS: [&str; 7] = ["t", "v", "h", "tv", "th", "vh", "tvh"];

/// Sample types of a recording: the crate's one list of frame sample types.
pub use crate::dtype::Dtype;

/// The accumulated sums, exact (integer frames) or compensated (float frames).
#[derive(Clone, Debug, PartialEq)]
pub enum Acc {
    Int(IntAcc),
    Float(FloatAcc),
}

/// Sufficient statistics of a T × V × H recording for the 3-D noise decomposition.
#[derive(Clone, Debug, PartialEq)]
pub struct NoiseSums {
    pub rows: usize,
    pub cols: usize,
    pub frames: usize,
    pub dtype: Dtype,
    pub acc: Acc,
}

/// Frames are counted in i64 sums of up to 2^32-valued samples: at most 2^31 − 1 frames.
pub const MAX_FRAMES: usize = (1 << 31) - 1;

impl NoiseSums {
    /// Empty sums for `rows × cols` frames of `dtype`. Integer frames: values must lie in
    /// `limits = (lo, hi)` (default: the type's range); values equal to `lo` or `hi` are
    /// counted as clipped.
    pub fn new(rows: usize, cols: usize, dtype: Dtype, limits: Option<(i64, i64)>) -> Result<NoiseSums> {
        if rows == 0 || cols == 0 {
            return Err(Error::Shape(format!("frames must have at least one row and column, got {rows} x {cols}")));
        }
        rows.checked_mul(cols).ok_or_else(|| Error::Shape("frame size overflows".into()))?;
        let acc = match dtype.int_range() {
            Some(range) => {
                let (lo, hi) = limits.unwrap_or(range);
                if lo > hi || lo < range.0 || hi > range.1 {
                    return Err(Error::Value(format!(
                        "valid range ({lo}, {hi}) does not fit the sample type {} ({} .. {})",
                        dtype.name(),
                        range.0,
                        range.1
                    )));
                }
                Acc::Int(IntAcc::new(rows * cols, dtype == Dtype::U32, (lo, hi)))
            }
            None => Acc::Float(FloatAcc::new()),
        };
        Ok(NoiseSums { rows, cols, frames: 0, dtype, acc })
    }

    /// Sums of a float pass whose per-pixel pivot is already known (the engine's chunks
    /// share the pivot of the pass's first frame, so their merges need no shift).
    pub(crate) fn with_pivot(rows: usize, cols: usize, dtype: Dtype, pivot: std::sync::Arc<Vec<f64>>) -> NoiseSums {
        NoiseSums { rows, cols, frames: 0, dtype, acc: Acc::Float(FloatAcc::with_pivot(pivot)) }
    }

    /// Add one frame: `rows × cols` samples read from `data`, a row-major image `stride`
    /// samples wide, starting at `(row0, col0)`. `label` names the frame in errors.
    pub fn add_frame<S: FrameSample>(
        &mut self,
        data: &[S],
        stride: usize,
        origin: (usize, usize),
        label: &dyn Fn() -> String,
    ) -> Result<()> {
        self.add_frames(&[data], stride, origin, &|_| label())
    }

    /// Add several frames (as [`NoiseSums::add_frame`]; `label(k)` names the k-th). The
    /// per-pixel sums are updated once per batch, not once per frame. After an error the
    /// sums are partly updated: discard them.
    pub fn add_frames<S: FrameSample>(
        &mut self,
        frames: &[&[S]],
        stride: usize,
        origin: (usize, usize),
        label: &dyn Fn(usize) -> String,
    ) -> Result<()> {
        if S::DTYPE != self.dtype {
            return Err(Error::Shape(format!(
                "{}: sample type {} differs from the recording's {}",
                label(0),
                S::DTYPE.name(),
                self.dtype.name()
            )));
        }
        if self.frames + frames.len() > MAX_FRAMES {
            return Err(Error::Value(format!("{}: more than {MAX_FRAMES} frames", label(0))));
        }
        let region = Region { stride, row0: origin.0, col0: origin.1, rows: self.rows, cols: self.cols };
        let needed = (region.row0 + self.rows - 1).checked_mul(stride).map(|v| v + region.col0 + self.cols);
        for (k, data) in frames.iter().enumerate() {
            if region.col0 + self.cols > stride || needed.is_none_or(|n| n > data.len()) {
                return Err(Error::Shape(format!(
                    "{}: frame too small for the {} x {} window",
                    label(k),
                    self.rows,
                    self.cols
                )));
            }
        }
        match &mut self.acc {
            Acc::Int(a) => a.add_frames(frames, &region, label)?,
            Acc::Float(a) => a.add_frames(frames, &region, label)?,
        }
        self.frames += frames.len();
        Ok(())
    }

    /// Sums of `self`'s frames followed by `other`'s (same window and sample type).
    pub fn merge(&self, other: &NoiseSums) -> Result<NoiseSums> {
        let mut out = self.clone();
        out.append(other)?;
        Ok(out)
    }

    /// Append `other`'s frames after `self`'s, in place.
    pub fn append(&mut self, other: &NoiseSums) -> Result<()> {
        if (self.rows, self.cols) != (other.rows, other.cols) {
            return Err(Error::Shape(format!(
                "cannot merge 3-D noise sums of {} x {} frames with those of {} x {} frames",
                self.rows, self.cols, other.rows, other.cols
            )));
        }
        if self.dtype != other.dtype {
            return Err(Error::Shape(format!(
                "cannot merge 3-D noise sums of {} frames with those of {} frames",
                self.dtype.name(),
                other.dtype.name()
            )));
        }
        if self.frames + other.frames > MAX_FRAMES {
            return Err(Error::Value(format!("more than {MAX_FRAMES} frames")));
        }
        match (&mut self.acc, &other.acc) {
            (Acc::Int(a), Acc::Int(b)) => a.append(b)?,
            (Acc::Float(a), Acc::Float(b)) => a.append(self.frames, b, other.frames, self.rows, self.cols),
            _ => return Err(Error::Value("internal: integer and float 3-D noise sums".into())),
        }
        self.frames += other.frames;
        Ok(())
    }

    /// The decomposition: sums of squares of the seven parts and the total.
    pub fn finish(&self) -> Result<Decomposition> {
        if self.frames == 0 {
            return Err(Error::Value("no frames were accumulated".into()));
        }
        let shape = Shape { frames: self.frames, rows: self.rows, cols: self.cols };
        match &self.acc {
            Acc::Int(a) => a.finish(shape),
            Acc::Float(a) => a.finish(shape),
        }
    }

    /// Per-pixel temporal mean (V·H, row-major).
    pub fn pixel_mean(&self) -> Vec<f64> {
        match &self.acc {
            Acc::Int(a) => a.pixel_mean(self.frames),
            Acc::Float(a) => a.pixel_mean(self.frames),
        }
    }

    /// Per-pixel temporal population variance (V·H, row-major).
    pub fn pixel_var(&self) -> Vec<f64> {
        match &self.acc {
            Acc::Int(a) => a.pixel_var(self.frames),
            Acc::Float(a) => a.pixel_var(self.frames),
        }
    }

    /// Mean of each row of each frame (T·V, frame-major).
    pub fn row_means(&self) -> Vec<f64> {
        let h = self.cols as f64;
        match &self.acc {
            Acc::Int(a) => a.row_sums.iter().map(|&s| s as f64 / h).collect(),
            Acc::Float(a) => a.frame_line_means(&a.row_sums, self.rows, self.cols, h, true),
        }
    }

    /// Mean of each column of each frame (T·H, frame-major).
    pub fn col_means(&self) -> Vec<f64> {
        let v = self.rows as f64;
        match &self.acc {
            Acc::Int(a) => a.col_sums.iter().map(|&s| s as f64 / v).collect(),
            Acc::Float(a) => a.frame_line_means(&a.col_sums, self.rows, self.cols, v, false),
        }
    }

    /// Value range seen: `(min, max)`, and for integer frames the counts of samples at the
    /// lower and upper limit with the limits themselves.
    pub fn value_range(&self) -> ValueRange {
        match &self.acc {
            Acc::Int(a) => ValueRange {
                min: a.min as f64,
                max: a.max as f64,
                clipped: Some(Clipped { lo: a.lo, hi: a.hi, at_lo: a.at_lo, at_hi: a.at_hi }),
            },
            Acc::Float(a) => ValueRange { min: a.min, max: a.max, clipped: None },
        }
    }
}

/// Where the analysed window lies in a frame's row-major samples.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Region {
    pub stride: usize,
    pub row0: usize,
    pub col0: usize,
    pub rows: usize,
    pub cols: usize,
}

impl Region {
    /// Row `r` of the window (the caller checked that the frame holds the window).
    #[inline]
    pub fn row<'a, S>(&self, data: &'a [S], r: usize) -> &'a [S] {
        let start = (self.row0 + r) * self.stride + self.col0;
        &data[start..start + self.cols]
    }
}

/// Extent of the recording.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shape {
    pub frames: usize,
    pub rows: usize,
    pub cols: usize,
}

impl Shape {
    pub fn n(&self) -> u128 {
        self.frames as u128 * self.rows as u128 * self.cols as u128
    }
}

/// Samples at the limits of the valid range (saturated or clipped pixels).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Clipped {
    pub lo: i64,
    pub hi: i64,
    pub at_lo: u64,
    pub at_hi: u64,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ValueRange {
    pub min: f64,
    pub max: f64,
    pub clipped: Option<Clipped>,
}

/// The finished decomposition: with `N = T·V·H` and the parts `N_x` of the classical
/// decomposition, `ss[x] = Σ N_x²` summed over the whole cube (so `ss[x] / N` is the
/// classical variance of part x) and `ss_total = Σ (x − mean)²`.
#[derive(Clone, Debug, PartialEq)]
pub struct Decomposition {
    pub shape: Shape,
    pub mean: f64,
    pub ss: [f64; 7],
    pub ss_total: f64,
    /// Integer frames: `N²·SS` of the seven parts and of the total, exact.
    pub exact: Option<[U256; 8]>,
}

/// A sample type the accumulators read.
pub trait FrameSample: Copy + Send + Sync + 'static {
    const DTYPE: Dtype;
    fn to_i64(self) -> i64;
    fn to_f64(self) -> f64;
    /// A frame of this type as the pass's input.
    fn samples(data: &[Self]) -> Samples<'_>;
    /// 8- and 16-bit integer types: values fit i32 (and their squares u32).
    const NARROW: bool = false;
    /// The value as i32: exact for the `NARROW` types (the only ones it is used for).
    #[inline(always)]
    fn to_i32(self) -> i32 {
        self.to_i64() as i32
    }
}

macro_rules! frame_sample {
    ($($t:ty => $d:ident, $narrow:expr, |$v:ident| $int:expr, $flt:expr);* $(;)?) => {$(
        impl FrameSample for $t {
            const DTYPE: Dtype = Dtype::$d;
            const NARROW: bool = $narrow;
            #[inline(always)]
            fn to_i64(self) -> i64 { let $v = self; $int }
            #[inline(always)]
            fn to_f64(self) -> f64 { let $v = self; $flt }
            fn samples(data: &[Self]) -> Samples<'_> { Samples::$d(data) }
        }
    )*};
}

frame_sample!(
    u8 => U8, true, |v| v as i64, v as f64;
    u16 => U16, true, |v| v as i64, v as f64;
    i16 => I16, true, |v| v as i64, v as f64;
    u32 => U32, false, |v| v as i64, v as f64;
    half::f16 => F16, false, |v| v.to_f64() as i64, v.to_f64();
    f32 => F32, false, |v| v as i64, v as f64;
    f64 => F64, false, |v| v as i64, v;
);

#[cfg(test)]
mod tests;
