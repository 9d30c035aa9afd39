//! What one pass computes and how it treats pixels: [`Request`], [`HistRequest`].

/// Which histogram to build.
#[derive(Clone, Debug, PartialEq)]
pub enum HistRequest {
    /// `bins` uniform bins over `range` (inclusive integer levels for integer frames);
    /// `None` = the data range of both frames.
    Bins { bins: usize, range: Option<(f64, f64)> },
    /// `bins` uniform bins over each frame's own data range: the real frame's edges span the
    /// real values, the simulated frame's the simulated ones, so a grey-level offset between
    /// the frames (or an outlier in one of them) does not move the other frame's edges.
    Each { bins: usize },
    /// Every grey level its own bin (integer frames only).
    Levels,
}

/// What to compute, and how to treat pixels.
#[derive(Clone, Debug)]
pub struct Request<'a> {
    pub sse: bool,
    pub moments: bool,
    pub hist: Option<HistRequest>,
    /// `false` entries exclude a pixel pair.
    pub mask: Option<&'a [bool]>,
    /// Integer frames: allowed values `[lo, hi]`; anything else is a range error.
    pub valid: Option<(i64, i64)>,
    /// Float frames: exclude non-finite pairs (`true`) or report them as an error.
    pub mask_nonfinite: bool,
    /// `(rows, cols)` and memory order, only to name positions in error messages.
    pub shape: (usize, usize),
    pub fortran: bool,
}

impl Default for Request<'_> {
    fn default() -> Self {
        Request {
            sse: true,
            moments: true,
            hist: Some(HistRequest::Bins { bins: 256, range: None }),
            mask: None,
            valid: None,
            mask_nonfinite: false,
            shape: (0, 0),
            fortran: false,
        }
    }
}

impl Request<'_> {
    /// `(row, col)` of flat pixel index `i`, for error messages.
    pub(crate) fn position(&self, i: usize) -> (usize, usize) {
        let (rows, cols) = (self.shape.0.max(1), self.shape.1.max(1));
        if self.fortran {
            (i % rows, i / rows)
        } else {
            (i / cols, i % cols)
        }
    }
}
