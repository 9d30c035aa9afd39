//! The EXR block decoders and the JPEG-LS decoder on their own, for the fuzz targets
//! (feature `fuzzing`, off in every normal build): fuzzing a block decoder through whole files
//! spends most runs on headers.

use half::f16;

use super::{piz, zip};

/// Decode one PIZ block of `w` x `h` pixels whose channels have `sizes[c]` bytes per sample
/// (2: half, 4: float/uint; file order), keeping channel `selected`. Returns the number
/// of samples decoded, or the decoder's reason for refusing the block.
pub fn piz_block(data: &[u8], sizes: &[usize], selected: usize, w: usize, h: usize) -> Result<usize, String> {
    let words: Vec<usize> = sizes.iter().map(|b| b / 2).collect();
    match sizes[selected] {
        2 => piz::decode_channel::<f16>(data, &words, selected, w, h).map(|v| v.len()),
        _ => piz::decode_channel::<f32>(data, &words, selected, w, h).map(|v| v.len()),
    }
}

/// Decode one ZIP block, as [`piz_block`].
pub fn zip_block(data: &[u8], sizes: &[usize], selected: usize, w: usize, h: usize) -> Result<usize, String> {
    let bytes_per_pixel = sizes.iter().sum();
    let offset = sizes[..selected].iter().sum();
    match sizes[selected] {
        2 => zip::decode_channel::<f16>(data, bytes_per_pixel, offset, w, h).map(|v| v.len()),
        _ => zip::decode_channel::<f32>(data, bytes_per_pixel, offset, w, h).map(|v| v.len()),
    }
}

/// Decode one JPEG-LS stream with irfidelity's own decoder (`rust/io/jpegls`), within
/// `max_pixels` and `max_bytes`. Returns (cols, rows, the samples decoded), or the decoder's
/// reason for refusing the stream.
pub fn jpegls(data: &[u8], max_pixels: u64, max_bytes: u64) -> Result<(usize, usize, usize), String> {
    super::jpegls::decode(data, max_pixels, max_bytes).map(|image| (image.cols, image.rows, image.samples.len()))
}
