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
//! Two limits are checked from the headers before anything large is allocated: the pixel
//! count ([`DecodeOptions::max_pixels`]) and the decode's peak memory in bytes
//! ([`DecodeOptions::max_bytes`]: the frame, plus every block, strip or row of all channels
//! and the decompression scratch held at once). Only regular files are opened (a FIFO would
//! block forever). The whole decode runs under `catch_unwind`, so a panic in a third-party
//! decoder becomes a `FrameError("...: decoder failed: ...")` instead of unwinding into the
//! caller.

use std::fs::{File, Metadata, OpenOptions};
use std::io::{BufRead, BufReader, Cursor, Seek};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;

use crate::{Error, Result};

mod exr;
#[cfg(feature = "fuzzing")]
pub mod fuzzing;
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

    /// The samples as float64 (exact for every sample type).
    pub fn to_f64(&self) -> Vec<f64> {
        fn convert<T: Copy>(v: &[T], f: impl Fn(T) -> f64) -> Vec<f64> {
            v.iter().map(|&x| f(x)).collect()
        }
        match self {
            FrameData::U8(v) => convert(v, f64::from),
            FrameData::U16(v) => convert(v, f64::from),
            FrameData::I16(v) => convert(v, f64::from),
            FrameData::U32(v) => convert(v, f64::from),
            FrameData::F16(v) => convert(v, f64::from),
            FrameData::F32(v) => convert(v, f64::from),
            FrameData::F64(v) => v.clone(),
        }
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
    /// The decoding budget: the most memory one decode may hold at its peak, in bytes — the
    /// decoded frame (the selected channel) plus whatever the format needs alongside it:
    /// the compressed and decompressed blocks of *all* channels in flight (EXR), a strip or
    /// tile of all samples (TIFF), rows and metadata chunks (PNG), and decompression
    /// scratch. Computed from the headers and checked before allocating; a decode that
    /// would exceed it fails with a FrameError naming the budget.
    pub max_bytes: u64,
    /// Page of a multi-page TIFF (0-based). Must be 0 for other formats.
    pub page: usize,
}

/// Default pixel limit: one 16384 x 16384 frame.
pub const DEFAULT_MAX_PIXELS: u64 = 16384 * 16384;

/// Default memory budget of one frame pair's work, 2 GiB (docs/design.md §10): decoding
/// (this module checks its part), the float64 copies, registration, resampling, statistics
/// and maps. Registering a 4096 x 4096 16-bit pair by any model and method holds up to about
/// 1.8 GB at its peak (the two frames, their float64 copies and registration's planes,
/// spectra and gradients); 2 GiB lets that be done with room to spare, and still refuses an
/// 8192 x 8192 registration (about 5.6 GB) before it allocates. Decoding alone stays far
/// below it: the largest 16-bit frame the default pixel limit allows takes 512 MiB.
pub const DEFAULT_MAX_BYTES: u64 = 2 << 30;

impl Default for DecodeOptions {
    fn default() -> Self {
        DecodeOptions { channel: None, max_pixels: DEFAULT_MAX_PIXELS, max_bytes: DEFAULT_MAX_BYTES, page: 0 }
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

thread_local! {
    /// While this thread runs a guarded decode: the location of a panic raised in it, which
    /// the panic hook records instead of printing (the panic becomes the decode's FrameError).
    static GUARDED_PANIC: std::cell::RefCell<Option<Option<String>>> = const { std::cell::RefCell::new(None) };
}

/// Wrap the process's panic hook, once: a panic inside a guarded decode on this thread is
/// recorded (file name and line) instead of printed, so a third-party decoder's bug reaches
/// the user once, as the FrameError naming the file. Every other panic goes to the previous
/// hook unchanged. Not under fuzzing, whose own hook must see every panic.
fn quiet_guarded_panics() {
    #[cfg(not(feature = "fuzzing"))]
    {
        static ONCE: std::sync::Once = std::sync::Once::new();
        ONCE.call_once(|| {
            let previous = std::panic::take_hook();
            std::panic::set_hook(Box::new(move |info| {
                let place = info.location().map(|l| {
                    let file = Path::new(l.file()).file_name().and_then(|f| f.to_str()).unwrap_or("?");
                    let krate = l.file().split("/src/").next().and_then(|d| d.rsplit('/').next()).unwrap_or("");
                    format!("{krate} {file}:{}", l.line())
                });
                let recorded = GUARDED_PANIC.with(|g| match &mut *g.borrow_mut() {
                    Some(slot) => {
                        *slot = place.clone();
                        true
                    }
                    None => false,
                });
                if !recorded {
                    previous(info);
                }
            }));
        });
    }
}

/// Run `f`, turning a panic into a FrameError (last line of defence against decoder bugs).
fn guarded<T>(name: &str, f: impl FnOnce() -> std::result::Result<T, Reason>) -> Result<T> {
    quiet_guarded_panics();
    let outer = GUARDED_PANIC.with(|g| g.replace(Some(None)));
    let result = catch_unwind(AssertUnwindSafe(f));
    let place = GUARDED_PANIC.with(|g| g.replace(outer)).flatten();
    match result {
        Ok(Ok(v)) => Ok(v),
        Ok(Err(reason)) => Err(frame_err(name, reason)),
        Err(payload) => {
            let at = place.map(|p| format!(" (a decoder bug at {p})")).unwrap_or_default();
            Err(frame_err(name, format!("decoder failed{at}: {}", panic_message(&*payload))))
        }
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

/// Refuse what is not a regular file: a directory, or a FIFO, socket or device (whose read
/// may block forever or never end).
fn regular(meta: &Metadata) -> std::result::Result<(), Reason> {
    if meta.is_dir() {
        Err("is a directory, not an image file".to_string())
    } else if !meta.is_file() {
        Err("not a regular file (a FIFO, socket or device); frames are read from regular files".to_string())
    } else {
        Ok(())
    }
}

/// Open a regular file for reading. The path is checked before opening (opening a FIFO for
/// reading blocks until a writer appears), opened non-blocking in case it was swapped for
/// one in between, and the open file checked again.
pub(crate) fn open_regular(path: &Path) -> std::result::Result<File, Reason> {
    regular(&std::fs::metadata(path).map_err(|e| format!("cannot open: {e}"))?)?;
    let mut options = OpenOptions::new();
    options.read(true);
    #[cfg(unix)]
    std::os::unix::fs::OpenOptionsExt::custom_flags(&mut options, libc::O_NONBLOCK);
    let file = options.open(path).map_err(|e| format!("cannot open: {e}"))?;
    regular(&file.metadata().map_err(|e| format!("cannot stat: {e}"))?)?;
    Ok(file)
}

/// Whether the file starts with a TIFF signature (errors are left to the full decode path).
fn is_tiff(path: &Path) -> bool {
    let mut head = [0u8; 8];
    let n = open_regular(path).ok().and_then(|mut f| std::io::Read::read(&mut f, &mut head).ok()).unwrap_or(0);
    sniff(&head[..n]) == Some(Format::Tiff)
}

fn run_on_path(path: &Path, op: Op<'_>) -> Result<OpOut> {
    let name = path.display().to_string();
    let file = open_regular(path).map_err(|reason| frame_err(&name, reason))?;
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

/// `a * b * ...` in u64, `None` on overflow.
pub(crate) fn product(factors: &[u64]) -> Option<u64> {
    factors.iter().try_fold(1u64, |acc, &f| acc.checked_mul(f))
}

/// Check that a decode whose peak memory is `need` bytes (`None`: beyond 2^64) fits the
/// budget; `what` says what needs it, e.g. "a 16384 x 16384 frame and one block of 300
/// channels".
pub(crate) fn check_budget(
    need: Option<u64>,
    what: impl FnOnce() -> String,
    max_bytes: u64,
) -> std::result::Result<(), Reason> {
    match need {
        Some(n) if n <= max_bytes => Ok(()),
        Some(n) => Err(format!(
            "decoding {} needs {n} bytes, which exceeds the decoding budget of {max_bytes} bytes (max_bytes)",
            what()
        )),
        None => Err(format!(
            "decoding {} needs more than 2^64 bytes, which exceeds the decoding budget of {max_bytes} bytes (max_bytes)",
            what()
        )),
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
