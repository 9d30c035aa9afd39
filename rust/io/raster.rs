//! PNG (`image` crate, png feature) and TIFF (`tiff` crate) decoding.
//!
//! Sizes are checked against `max_pixels` from the header before any pixel buffer is
//! allocated, and each decoder gets a memory limit sized from that check (not the crate's
//! default), so a legitimate 16k x 16k 16-bit frame decodes and a lying header does not
//! allocate.

use std::cell::RefCell;
use std::fs::File;
use std::io::{BufRead, BufReader, Seek};
use std::path::{Path, PathBuf};
use std::time::SystemTime;

use image::codecs::png::PngDecoder;
use image::{ColorType as PngColor, ImageDecoder};
use tiff::decoder::{Decoder as TiffDecoder, DecodingResult, Limits as TiffLimits};
use tiff::ColorType as TiffColor;

use super::{check_size, select_channel, DecodeOptions, Frame, FrameData, Reason};

// ----------------------------------------------------------------------------- PNG

fn png_err(e: image::ImageError) -> Reason {
    use image::ImageError as E;
    match e {
        E::Limits(l) => format!("PNG exceeds the decoder memory limit: {l}"),
        E::Unsupported(u) => format!("unsupported PNG: {u}"),
        E::IoError(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            "truncated PNG file (unexpected end of file)".to_string()
        }
        E::IoError(io) => format!("read error: {io}"),
        other => format!("corrupt or invalid PNG file: {other}"),
    }
}

fn png_names(c: PngColor) -> Result<Vec<String>, Reason> {
    let n: &[&str] = match c {
        PngColor::L8 | PngColor::L16 => &["Y"],
        PngColor::La8 | PngColor::La16 => &["Y", "A"],
        PngColor::Rgb8 | PngColor::Rgb16 => &["R", "G", "B"],
        PngColor::Rgba8 | PngColor::Rgba16 => &["R", "G", "B", "A"],
        other => return Err(format!("unsupported PNG colour type {other:?}")),
    };
    Ok(n.iter().map(|s| s.to_string()).collect())
}

fn png_open<R: BufRead + Seek>(reader: R, max_pixels: u64) -> Result<PngDecoder<R>, Reason> {
    let mut limits = image::Limits::default();
    // Deliberately raised from the crate default (512 MiB): room for a frame of
    // `max_pixels` pixels of 4 channels x 16 bits, plus decoder working memory.
    limits.max_alloc = Some(max_pixels.saturating_mul(8).saturating_add(64 << 20));
    PngDecoder::with_limits(reader, limits).map_err(png_err)
}

pub(super) fn png_channels<R: BufRead + Seek>(reader: R) -> Result<Vec<String>, Reason> {
    let dec = png_open(reader, u64::MAX / 16)?;
    png_names(dec.color_type())
}

/// Width, height, bit depth and colour type from the IHDR chunk of a PNG file.
fn png_ihdr<R: BufRead + Seek>(reader: &mut R) -> Option<(u32, u32, u8, u8)> {
    let mut head = [0u8; 26];
    let ok = reader.read_exact(&mut head).is_ok();
    reader.rewind().ok()?;
    let be = |i: usize| u32::from_be_bytes([head[i], head[i + 1], head[i + 2], head[i + 3]]);
    (ok && &head[12..16] == b"IHDR").then(|| (be(16), be(20), head[24], head[25]))
}

pub(super) fn decode_png<R: BufRead + Seek>(mut reader: R, o: &DecodeOptions) -> Result<Frame, Reason> {
    // The `image` crate expands 1/2/4-bit grey to 8 bits by scaling (x255, x85, x17);
    // undo that exactly so the frame holds the file's own sample values (like pypng).
    let ihdr = png_ihdr(&mut reader);
    if let Some((w, h, _, _)) = ihdr {
        // refuse a lying header before the decoder sizes any buffer from it
        check_size(w as u64, h as u64, o.max_pixels)?;
    }
    let low_grey_scale: Option<u8> = match ihdr {
        Some((_, _, 1, 0)) => Some(255),
        Some((_, _, 2, 0)) => Some(85),
        Some((_, _, 4, 0)) => Some(17),
        _ => None,
    };
    let dec = png_open(reader, o.max_pixels)?;
    let (w, h) = dec.dimensions();
    check_size(w as u64, h as u64, o.max_pixels)?;
    let color = dec.color_type();
    let names = png_names(color)?;
    let c = select_channel(&names, o.channel.as_deref())?;
    let spp = names.len();
    let (rows, cols) = (h as usize, w as usize);
    let n = rows * cols;
    let total = dec.total_bytes();
    let sixteen = matches!(color, PngColor::L16 | PngColor::La16 | PngColor::Rgb16 | PngColor::Rgba16);
    let expect = (n * spp * if sixteen { 2 } else { 1 }) as u64;
    if total != expect {
        return Err(format!("unsupported PNG layout ({total} bytes for {w} x {h} {color:?})"));
    }
    let data = if sixteen {
        let mut buf = vec![0u16; n * spp];
        dec.read_image(u16_bytes_mut(&mut buf)).map_err(png_err)?;
        FrameData::U16(pick(buf, spp, c, false))
    } else {
        let mut buf = vec![0u8; n * spp];
        dec.read_image(&mut buf).map_err(png_err)?;
        if let (Some(k), PngColor::L8) = (low_grey_scale, color) {
            buf.iter_mut().for_each(|v| *v /= k);
        }
        FrameData::U8(pick(buf, spp, c, false))
    };
    Ok(Frame { rows, cols, data })
}

/// View a `u16` buffer as bytes (the `image` crate writes native-endian samples).
fn u16_bytes_mut(v: &mut [u16]) -> &mut [u8] {
    // SAFETY: u8 has alignment 1 and every bit pattern is a valid u16, so the byte view
    // of the same memory (2 bytes per element) is sound; the borrow ties the lifetimes.
    unsafe { std::slice::from_raw_parts_mut(v.as_mut_ptr() as *mut u8, v.len() * 2) }
}

/// Channel `c` of `spp` interleaved (or planar) channels; no copy when there is one channel.
fn pick<T: Copy>(v: Vec<T>, spp: usize, c: usize, planar: bool) -> Vec<T> {
    if spp == 1 {
        return v;
    }
    if planar {
        let plane = v.len() / spp;
        v[c * plane..(c + 1) * plane].to_vec()
    } else {
        v.iter().skip(c).step_by(spp).copied().collect()
    }
}

// ---------------------------------------------------------------------------- TIFF

fn tiff_err(e: tiff::TiffError) -> Reason {
    use tiff::TiffError as E;
    match e {
        E::UnsupportedError(u) => format!("unsupported TIFF feature: {u}"),
        E::FormatError(f) => format!("corrupt or invalid TIFF file: {f}"),
        E::IoError(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            "truncated or corrupt TIFF file (unexpected end of file)".to_string()
        }
        E::IoError(io) => format!("read error: {io}"),
        E::LimitsExceeded => "TIFF exceeds the decoder memory limit".to_string(),
        E::IntSizeError => "TIFF sizes exceed platform limits".to_string(),
        other => format!("corrupt or unsupported TIFF file: {other}"),
    }
}

/// Channel names for a TIFF colour type; "Y" only for grey images.
fn tiff_names(c: TiffColor) -> Result<Vec<String>, Reason> {
    let fixed: &[&str] = match c {
        TiffColor::Gray(_) => &["Y"],
        TiffColor::GrayA(_) => &["Y", "A"],
        TiffColor::RGB(_) => &["R", "G", "B"],
        TiffColor::RGBA(_) => &["R", "G", "B", "A"],
        TiffColor::Palette(_) => return Err("unsupported: palette (indexed colour) TIFF".to_string()),
        _ => &[],
    };
    if !fixed.is_empty() {
        return Ok(fixed.iter().map(|s| s.to_string()).collect());
    }
    let n = match c {
        TiffColor::CMYK(_) => 4,
        TiffColor::CMYKA(_) => 5,
        TiffColor::YCbCr(_) | TiffColor::Lab(_) => 3,
        TiffColor::Multiband { num_samples, .. } => num_samples as usize,
        other => return Err(format!("unsupported TIFF colour type {other:?}")),
    };
    if n == 0 || n > 64 {
        return Err(format!("unsupported TIFF with {n} samples per pixel"));
    }
    Ok((0..n).map(|i| i.to_string()).collect())
}

fn tiff_open<R: BufRead + Seek>(reader: R, max_pixels: u64) -> Result<TiffDecoder<R>, Reason> {
    let mut limits = TiffLimits::default();
    // Raised deliberately from the 256 MiB default: room for `max_pixels` pixels of up to
    // 4 float64 samples (the size itself is checked against max_pixels before reading).
    let cap = max_pixels.saturating_mul(32).min(usize::MAX as u64) as usize;
    limits.decoding_buffer_size = cap.max(limits.decoding_buffer_size);
    TiffDecoder::new(reader).map_err(tiff_err).map(|d| d.with_limits(limits))
}

pub(super) fn tiff_page_count<R: BufRead + Seek>(reader: R) -> Result<usize, Reason> {
    let mut dec = tiff_open(reader, super::DEFAULT_MAX_PIXELS)?;
    let mut n = 1usize;
    while dec.more_images() {
        dec.next_image().map_err(|e| format!("page {n}: {}", tiff_err(e)))?;
        n += 1;
        if n > 10_000_000 {
            return Err("corrupt TIFF file: more than 10 million pages".to_string());
        }
    }
    Ok(n)
}

pub(super) fn tiff_channels<R: BufRead + Seek>(reader: R) -> Result<Vec<String>, Reason> {
    let mut dec = tiff_open(reader, super::DEFAULT_MAX_PIXELS)?;
    tiff_names(dec.colortype().map_err(tiff_err)?)
}

pub(super) fn decode_tiff<R: BufRead + Seek>(reader: R, o: &DecodeOptions) -> Result<Frame, Reason> {
    let mut dec = tiff_open(reader, o.max_pixels)?;
    decode_tiff_page(&mut dec, o)
}

/// Decode page `o.page` with an open decoder (which remembers the IFD offsets it has seen).
fn decode_tiff_page<R: BufRead + Seek>(dec: &mut TiffDecoder<R>, o: &DecodeOptions) -> Result<Frame, Reason> {
    if o.page > 0 {
        dec.seek_to_image(o.page).map_err(|e| match e {
            tiff::TiffError::FormatError(tiff::TiffFormatError::ImageFileDirectoryNotFound) => {
                format!("page {} out of range", o.page)
            }
            other => format!("page {}: {}", o.page, tiff_err(other)),
        })?;
    }
    let (w, h) = dec.dimensions().map_err(tiff_err)?;
    check_size(w as u64, h as u64, o.max_pixels)?;
    let color = dec.colortype().map_err(tiff_err)?;
    let names = tiff_names(color)?;
    let c = select_channel(&names, o.channel.as_deref())?;
    let spp = names.len();
    let (rows, cols) = (h as usize, w as usize);
    let n = rows * cols;

    let mut result = DecodingResult::U8(Vec::new());
    let layout = dec.read_image_to_buffer(&mut result).map_err(tiff_err)?;
    let planar = layout.planes > 1;
    if planar && result.as_buffer(0).as_bytes().len() < layout.complete_len {
        return Err("planar TIFF too large to decode all planes".to_string());
    }
    let bits = color.bit_depth();
    macro_rules! take {
        ($v:expr, $variant:ident) => {{
            let v = $v;
            if v.len() < n * spp {
                return Err(format!(
                    "unsupported TIFF layout: {bits}-bit samples, {spp} per pixel ({} decoded for {w} x {h})",
                    v.len()
                ));
            }
            let mut v = v;
            v.truncate(n * spp);
            FrameData::$variant(pick(v, spp, c, planar))
        }};
    }
    let data = match result {
        DecodingResult::U8(v) => take!(v, U8),
        DecodingResult::U16(v) => take!(v, U16),
        DecodingResult::I16(v) => take!(v, I16),
        DecodingResult::U32(v) => take!(v, U32),
        DecodingResult::F16(v) => take!(v, F16),
        DecodingResult::F32(v) => take!(v, F32),
        DecodingResult::F64(v) => take!(v, F64),
        DecodingResult::I8(v) => take!(v.into_iter().map(i16::from).collect::<Vec<i16>>(), I16),
        DecodingResult::U64(_) => return Err("unsupported TIFF sample type uint64".to_string()),
        DecodingResult::I32(_) => return Err("unsupported TIFF sample type int32".to_string()),
        DecodingResult::I64(_) => return Err("unsupported TIFF sample type int64".to_string()),
    };
    Ok(Frame { rows, cols, data })
}

// ----------------------------------------------------------------------------- TIFF pages in order

/// An open decoder of a multi-page TIFF, kept per thread between calls. Reading page k
/// from a fresh decoder walks the k earlier IFDs; a sequence read page by page would
/// cost O(n²) header reads. The decoder remembers every IFD offset it has walked.
struct PageCursor {
    key: (PathBuf, u64, Option<SystemTime>, u64), // path, length, mtime, max_pixels
    dec: TiffDecoder<BufReader<File>>,
    /// Highest page decoded so far: every IFD up to it is known to the decoder.
    max_page: usize,
}

/// Cursors per thread: a real and a simulated sequence (and a spare) stay open together.
const CURSORS_PER_THREAD: usize = 4;

thread_local! {
    static CURSORS: RefCell<Vec<PageCursor>> = const { RefCell::new(Vec::new()) };
}

/// Decode page `o.page` (> 0) of the TIFF at `path`, reusing this thread's open decoder of
/// that file when it has one. A file changed on disk (length or mtime) gets a new decoder.
pub(super) fn decode_tiff_page_cached(path: &Path, o: &DecodeOptions) -> Result<Frame, Reason> {
    let meta = std::fs::metadata(path).map_err(|e| format!("cannot stat: {e}"))?;
    let key = (path.to_path_buf(), meta.len(), meta.modified().ok(), o.max_pixels);
    // Take the cursor out while decoding: a decoder error or a panic (caught further up)
    // then simply drops it instead of leaving a half-moved decoder behind.
    let cached = CURSORS.with(|c| {
        let mut v = c.borrow_mut();
        v.iter().position(|cur| cur.key == key).map(|i| v.remove(i))
    });
    let mut cur = match cached {
        Some(cur) => cur,
        None => {
            let file = File::open(path).map_err(|e| format!("cannot open: {e}"))?;
            let dec = tiff_open(BufReader::with_capacity(1 << 16, file), o.max_pixels)?;
            PageCursor { key, dec, max_page: 0 }
        }
    };
    if o.page > cur.max_page {
        // The decoder extends its IFD list only when walking on from the last known IFD:
        // stand on it first (an O(1) seek), then walk forward.
        cur.dec.seek_to_image(cur.max_page).map_err(|e| format!("page {}: {}", cur.max_page, tiff_err(e)))?;
    }
    let frame = decode_tiff_page(&mut cur.dec, o)?;
    cur.max_page = cur.max_page.max(o.page);
    CURSORS.with(|c| {
        let mut v = c.borrow_mut();
        v.insert(0, cur);
        v.truncate(CURSORS_PER_THREAD);
    });
    Ok(frame)
}
