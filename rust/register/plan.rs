//! What registration and warping hold at their peak, estimated from the frame shape before
//! anything is allocated (docs/design.md §14).
//!
//! Registration's working memory, besides the two frames it is given, is a few float64
//! planes with their masks (9 bytes a pixel each: the frames converted, smoothed, their
//! gradients, a warped copy) and the float32 spectra and correlation surfaces of phase
//! correlation (4 bytes a pixel each). Which of them are alive at once depends on the model
//! and the method; the figures below are the measured peaks of every path (counted by the
//! allocator on 2048 × 2560 frames: translation by phase correlation 19 bytes a pixel, 28
//! with a mask; refined on the pixels 62; NMI 70; rotation and scale 70, by NMI 68) with
//! about 10 % to spare, and `Method::Auto` counts its NMI fallback. The fixed part covers the
//! log-polar grids, FFT plans, row buffers and the spare buffers each thread keeps
//! ([`super::pool::SPARE_BYTES`]).

use super::{Method, Model, Options};
use crate::budget::Plan;

/// Bytes a pixel of registration's working memory, besides the frames.
fn work_per_pixel(model: Model, method: Method) -> f64 {
    match (model, method) {
        (Model::Translation, Method::Phase) => 31.0,
        _ => 78.0,
    }
}

/// Fixed working memory of a registration, bytes.
const WORK_FIXED: u64 = 32 << 20;

/// The peak of registering `rows × cols` frames as `opts` says, besides the frames.
pub fn register_plan(shape: (usize, usize), opts: &Options) -> Plan {
    let operation = format!("registration ({}, method {})", opts.model.name(), opts.method.name());
    Plan::new(operation, shape, work_per_pixel(opts.model, opts.method), WORK_FIXED)
}

/// The peak of resampling a frame onto a `rows × cols` grid, besides the source: the
/// float64 values and the mask of the output.
pub fn warp_plan(shape: (usize, usize)) -> Plan {
    Plan::new("resampling (Registration.apply)", shape, 9.0, 0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plans_grow_with_the_frames_and_name_the_search() {
        let opts = Options { model: Model::Rigid, method: Method::Auto, max_shift: None };
        let small = register_plan((512, 640), &opts);
        let large = register_plan((8192, 8192), &opts);
        assert!(large.bytes > 4 << 30 && small.bytes < 64 << 20, "{} {}", small.bytes, large.bytes);
        assert!(large.operation.contains("rigid") && large.operation.contains("auto"));
        let err = large.check(2 << 30, crate::Error::Registration).unwrap_err();
        assert!(matches!(err, crate::Error::Registration(m) if m.contains("8192 x 8192")));
        assert_eq!(warp_plan((100, 10)).bytes, 9000);
    }
}
