//! Frame decoding: OpenEXR (`exr` crate), PNG (`image` crate) and TIFF (`tiff` crate),
//! as plain Rust with no Python types, so the sequence engine can decode frames from its
//! own threads.
//!
//! * [`decode_frame`] decodes one 2-D frame (one channel, one page) in the file's own
//!   sample type ([`FrameData`]); float16 stays float16.
//! * [`page_count`] counts the pages of a (multi-page) TIFF; 1 for other formats.
//! * [`list_channels`] lists the channels one may select.
//! * [`decode_bytes`] is the same decoder over an in-memory buffer (used by the fuzz target).
//!
//! Hostile input: every failure is an [`Error::Frame`] whose message starts with the path.
//! Headers that claim more than [`DecodeOptions::max_pixels`] pixels are refused before any
//! pixel buffer is allocated, and the whole decode runs under `catch_unwind`, so a panic in
//! a third-party decoder becomes a `FrameError("...: decoder failed: ...")` instead of
//! unwinding into the caller.

use std::fs::File;
use std::io::{BufRead, BufReader, Cursor, Seek};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;

use crate::{Error, Result};

mod exr;
mod piz;
mod raster;
mod zip;

/// Decoded samples of one frame, row-major, in the file's own sample type.
#[derive(Debug, Clone, PartialEq)]
pub enum FrameData {
    U8(Vec<u8>),
    U16(Vec<u16>),
    I16(Vec<i16>),
    U32(Vec<u32>),
    F16(Vec<half::f16>),
    F32(Vec<f32>),
    F64(Vec<f64>),
}

impl FrameData {
    /// Number of samples.
    pub fn len(&self) -> usize {
        match self {
            FrameData::U8(v) => v.len(),
            FrameData::U16(v) => v.len(),
            FrameData::I16(v) => v.len(),
            FrameData::U32(v) => v.len(),
            FrameData::F16(v) => v.len(),
            FrameData::F32(v) => v.len(),
            FrameData::F64(v) => v.len(),
        }
    }

    /// True when there are no samples.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// numpy-style name of the sample type ("uint16", "float16", ...).
    pub fn dtype_name(&self) -> &'static str {
        match self {
            FrameData::U8(_) => "uint8",
            FrameData::U16(_) => "uint16",
            FrameData::I16(_) => "int16",
            FrameData::U32(_) => "uint32",
            FrameData::F16(_) => "float16",
            FrameData::F32(_) => "float32",
            FrameData::F64(_) => "float64",
        }
    }
}

/// One decoded 2-D frame: `rows * cols` samples, row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    pub rows: usize,
    pub cols: usize,
    pub data: FrameData,
}

/// What to decode and how much to allow.
#[derive(Debug, Clone, PartialEq)]
pub struct DecodeOptions {
    /// Channel to decode: an EXR channel name ("Y", "R", "left.Y", or "part.channel" in
    /// multi-part files), or for PNG/TIFF one of "Y", "R", "G", "B", "A" or a channel
    /// index ("0", "1", ...). `None`: the only channel, or "Y" if present.
    pub channel: Option<String>,
    /// Refuse files whose header claims more pixels than this (checked before allocating).
    pub max_pixels: u64,
    /// Page of a multi-page TIFF (0-based). Must be 0 for other formats.
    pub page: usize,
}

/// Default pixel limit: one 16384 x 16384 frame.
pub const DEFAULT_MAX_PIXELS: u64 = 16384 * 16384;

impl Default for DecodeOptions {
    fn default() -> Self {
        DecodeOptions { channel: None, max_pixels: DEFAULT_MAX_PIXELS, page: 0 }
    }
}

/// File formats recognised by their magic bytes (never by extension).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Format {
    Exr,
    Png,
    Tiff,
}

fn sniff(head: &[u8]) -> Option<Format> {
    if head.starts_with(&[0x76, 0x2f, 0x31, 0x01]) {
        Some(Format::Exr)
    } else if head.starts_with(b"\x89PNG\r\n\x1a\n") {
        Some(Format::Png)
    } else if head.starts_with(b"II*\0")
        || head.starts_with(b"MM\0*")
        || head.starts_with(b"II+\0")
        || head.starts_with(b"MM\0+")
    {
        Some(Format::Tiff)
    } else {
        None
    }
}

/// A reason (without the path); turned into `Error::Frame("{path}: {reason}")` at the top.
pub(crate) type Reason = String;

fn frame_err(name: &str, reason: impl std::fmt::Display) -> Error {
    Error::Frame(format!("{name}: {reason}"))
}

fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    if let Some(s) = payload.downcast_ref::<&str>() {
        (*s).to_string()
    } else if let Some(s) = payload.downcast_ref::<String>() {
        s.clone()
    } else {
        "panic with a non-string payload".to_string()
    }
}

/// Run `f`, turning a panic into a FrameError (last line of defence against decoder bugs).
fn guarded<T>(name: &str, f: impl FnOnce() -> std::result::Result<T, Reason>) -> Result<T> {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(Ok(v)) => Ok(v),
        Ok(Err(reason)) => Err(frame_err(name, reason)),
        Err(payload) => Err(frame_err(name, format!("decoder failed: {}", panic_message(&*payload)))),
    }
}

/// What one operation does with an opened, sniffed stream.
enum Op<'a> {
    Decode(&'a DecodeOptions),
    Pages,
    Channels,
}

enum OpOut {
    Frame(Frame),
    Pages(usize),
    Channels(Vec<String>),
}

fn run_op<R: BufRead + Seek>(mut reader: R, op: &Op<'_>) -> std::result::Result<OpOut, Reason> {
    let mut head = [0u8; 8];
    let mut got = 0;
    while got < head.len() {
        match reader.read(&mut head[got..]) {
            Ok(0) => break,
            Ok(n) => got += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(format!("cannot read: {e}")),
        }
    }
    reader.rewind().map_err(|e| format!("cannot read: {e}"))?;
    let format = sniff(&head[..got]).ok_or_else(|| {
        if got == 0 {
            "empty file (not an EXR, PNG or TIFF image)".to_string()
        } else {
            "unsupported file format (not an OpenEXR, PNG or TIFF image by its magic bytes)".to_string()
        }
    })?;
    if let Op::Decode(o) = op {
        if o.page != 0 && format != Format::Tiff {
            return Err(format!("page {} out of range (only TIFF files have several pages)", o.page));
        }
    }
    match (format, op) {
        (Format::Exr, Op::Decode(o)) => exr::decode(reader, o).map(OpOut::Frame),
        (Format::Exr, Op::Channels) => exr::channels(reader).map(OpOut::Channels),
        (Format::Exr, Op::Pages) => exr::channels(reader).map(|_| OpOut::Pages(1)),
        (Format::Png, Op::Decode(o)) => raster::decode_png(reader, o).map(OpOut::Frame),
        (Format::Png, Op::Channels) => raster::png_channels(reader).map(OpOut::Channels),
        (Format::Png, Op::Pages) => raster::png_channels(reader).map(|_| OpOut::Pages(1)),
        (Format::Tiff, Op::Decode(o)) => raster::decode_tiff(reader, o).map(OpOut::Frame),
        (Format::Tiff, Op::Channels) => raster::tiff_channels(reader).map(OpOut::Channels),
        (Format::Tiff, Op::Pages) => raster::tiff_page_count(reader).map(OpOut::Pages),
    }
}

/// Whether the file starts with a TIFF signature (errors are left to the full decode path).
fn is_tiff(path: &Path) -> bool {
    let mut head = [0u8; 8];
    let n = File::open(path).and_then(|mut f| std::io::Read::read(&mut f, &mut head)).unwrap_or(0);
    sniff(&head[..n]) == Some(Format::Tiff)
}

fn run_on_path(path: &Path, op: Op<'_>) -> Result<OpOut> {
    let name = path.display().to_string();
    let file = File::open(path).map_err(|e| frame_err(&name, format!("cannot open: {e}")))?;
    match file.metadata() {
        Ok(m) if m.is_dir() => return Err(frame_err(&name, "is a directory, not an image file")),
        Ok(_) => {}
        Err(e) => return Err(frame_err(&name, format!("cannot stat: {e}"))),
    }
    let reader = BufReader::with_capacity(1 << 16, file);
    guarded(&name, || run_op(reader, &op))
}

/// Decode one frame (one channel of one page) of an OpenEXR, PNG or TIFF file.
///
/// Errors are `Error::Frame("{path}: {reason}")`.
pub fn decode_frame(path: &Path, opts: &DecodeOptions) -> Result<Frame> {
    if opts.page > 0 && is_tiff(path) {
        // later pages of a multi-page TIFF: this thread's open decoder knows the IFD offsets
        let name = path.display().to_string();
        return guarded(&name, || raster::decode_tiff_page_cached(path, opts));
    }
    match run_on_path(path, Op::Decode(opts))? {
        OpOut::Frame(f) => Ok(f),
        _ => unreachable!("decode returns a frame"),
    }
}

/// Decode one frame from an in-memory file; `name` is used in error messages.
pub fn decode_bytes(bytes: &[u8], name: &str, opts: &DecodeOptions) -> Result<Frame> {
    match guarded(name, || run_op(Cursor::new(bytes), &Op::Decode(opts)))? {
        OpOut::Frame(f) => Ok(f),
        _ => unreachable!("decode returns a frame"),
    }
}

/// Number of pages: the IFD count of a TIFF, 1 for EXR and PNG.
pub fn page_count(path: &Path) -> Result<usize> {
    match run_on_path(path, Op::Pages)? {
        OpOut::Pages(n) => Ok(n),
        _ => unreachable!("page_count returns a count"),
    }
}

/// Channel names one may pass as `DecodeOptions::channel`: the EXR channel names
/// ("part.channel" in multi-part files), or e.g. `["Y"]`, `["Y","A"]`, `["R","G","B"]`
/// for PNG/TIFF.
pub fn list_channels(path: &Path) -> Result<Vec<String>> {
    match run_on_path(path, Op::Channels)? {
        OpOut::Channels(c) => Ok(c),
        _ => unreachable!("list_channels returns names"),
    }
}

/// Check a claimed `cols x rows` size against the limit before allocating.
pub(crate) fn check_size(cols: u64, rows: u64, max_pixels: u64) -> std::result::Result<(), Reason> {
    if cols == 0 || rows == 0 {
        return Err(format!("empty image ({cols} x {rows} pixels)"));
    }
    match cols.checked_mul(rows) {
        Some(n) if n <= max_pixels => Ok(()),
        _ => Err(format!("image of {cols} x {rows} pixels exceeds the limit of {max_pixels} pixels (max_pixels)")),
    }
}

/// Pick a channel index from `names` per the `channel` option (name or decimal index);
/// default: the only channel, or "Y" when present.
pub(crate) fn select_channel(names: &[String], channel: Option<&str>) -> std::result::Result<usize, Reason> {
    let listing = || names.join(", ");
    match channel {
        Some(want) => {
            if let Some(i) = names.iter().position(|n| n == want) {
                return Ok(i);
            }
            if let Ok(i) = want.parse::<usize>() {
                if i < names.len() {
                    return Ok(i);
                }
            }
            Err(format!("no channel {want:?}; channels are: {}", listing()))
        }
        None => {
            if names.len() == 1 {
                Ok(0)
            } else if let Some(i) = names.iter().position(|n| n == "Y") {
                Ok(i)
            } else {
                Err(format!("several channels ({}); choose one with channel=...", listing()))
            }
        }
    }
}

#[cfg(test)]
mod tests;
