//! Where two frames differ: the windowed SSIM map of Wang et al. (2004) and multi-scale SSIM
//! (Wang, Simoncelli & Bovik 2003), over slices, in float64.
//!
//! The map is computed band by band (a band = a run of output rows): the four moment images
//! (x, y, x² + y², x·y) of the band's input rows are filtered along rows, then along columns,
//! with a Gaussian window and reflected borders (scipy.ndimage's `reflect` mode), and SSIM is
//! formed per pixel. Bands are shared with idle pool threads. Values are centred on a pivot
//! per band and frame (a sample of the band's first row), so a large common offset does not
//! cancel the digits of the local variances.
//!
//! - [`frame`]: the parameters, their checks, and the checks of each band's pixels (NaN/Inf,
//!   values outside the declared bit depth);
//! - [`filter`]: the window and the separable filtering of one band;
//! - [`ssim`]: SSIM per pixel, the map and its means;
//! - [`multiscale`]: 2×2 averaging and MS-SSIM.

mod filter;
mod frame;
mod multiscale;
mod ssim;

pub use frame::SsimParams;
pub use multiscale::{max_scales, ms_ssim, ms_ssim_plan, MsSsim, MS_SSIM_WEIGHTS};
pub use ssim::{ssim_map, ssim_map_plan, SsimMap};
