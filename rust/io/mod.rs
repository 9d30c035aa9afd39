//! Frame decoding: OpenEXR (`exr` crate), PNG (`image` crate) and TIFF (`tiff` crate),
//! and the raw counts and calibration of radiometric FLIR files (FFF, SEQ, CSQ, radiometric
//! JPEG: `flir.rs`, `seq.rs`, `rjpeg.rs`, with CSQ's JPEG-LS in `jpegls/`), as plain Rust with
//! no Python types, so the sequence engine can decode frames from its own threads.
//!
//! * [`decode_frame`] decodes one 2-D frame (one channel, one page) in the file's own
//!   sample type ([`FrameData`]); float16 stays float16.
//! * [`page_chain`] finds the pages of a (multi-page) TIFF, and where a broken IFD chain
//!   breaks, or the frames of a FLIR SEQ; [`page_count`] counts them (1 for other formats).
//! * [`read_camera_info`] reads a radiometric file's calibration ([`CameraInfo`]).
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

use crate::dtype::Dtype;
use crate::{Error, Result};
use tiff_pages::FileKey;

mod calibrations;
mod exr;
mod flir;
#[cfg(feature = "fuzzing")]
pub mod fuzzing;
mod jpegls;
mod piz;
mod raster;
mod rjpeg;
mod seq;
mod tiff_pages;
mod unread;
mod zip;

pub use flir::CameraInfo;
pub use tiff_pages::ifds_read;

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

    /// The sample type.
    pub fn dtype(&self) -> Dtype {
        match self {
            FrameData::U8(_) => Dtype::U8,
            FrameData::U16(_) => Dtype::U16,
            FrameData::I16(_) => Dtype::I16,
            FrameData::U32(_) => Dtype::U32,
            FrameData::F16(_) => Dtype::F16,
            FrameData::F32(_) => Dtype::F32,
            FrameData::F64(_) => Dtype::F64,
        }
    }

    /// numpy-style name of the sample type ("uint16", "float16", ...).
    pub fn dtype_name(&self) -> &'static str {
        self.dtype().name()
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

/// Default pixel limit: one 8192 x 8192 frame (67 Mpx), 200 times a 640 x 512 thermal frame.
/// Like Pillow's, it keeps a small compressed file from expanding to gigabytes unless the
/// caller raises it (`max_pixels`, `--max-pixels`); a float64 frame of this size is 512 MiB.
pub const DEFAULT_MAX_PIXELS: u64 = 8192 * 8192;

/// Default memory budget of one frame pair's work, 2 GiB (docs/design.md §14): decoding
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
    /// FLIR FFF, or a FLIR SEQ (FFF frames one after another)
    Flir,
    /// JPEG: read only when radiometric (FLIR segments)
    Jpeg,
    /// Possibly an InfiRay IRG file, whose header (of this many bytes) is checked before it is
    /// refused (`unread.rs`)
    Irg(usize),
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
    } else if flir::is_fff(head) {
        Some(Format::Flir)
    } else if head.starts_with(&[0xFF, 0xD8, 0xFF]) {
        Some(Format::Jpeg)
    } else {
        unread::irg_header_len(head).map(Format::Irg)
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
    Radiometry(&'a DecodeOptions),
}

enum OpOut {
    Frame(Frame),
    /// Pages found, and why the chain breaks after them (if it does).
    Pages(usize, Option<Reason>),
    Channels(Vec<String>),
    Radiometry(Box<CameraInfo>),
}

/// Run `op` on a stream named `name`; `key` identifies the file it reads (the TIFF page
/// cache's key).
fn run_op<R: BufRead + Seek>(
    mut reader: R,
    name: &str,
    op: &Op<'_>,
    key: Option<&FileKey>,
) -> std::result::Result<OpOut, Reason> {
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
            unread::unknown_format(name)
        }
    })?;
    if let Format::Irg(header_len) = format {
        return Err(if unread::is_irg(&mut reader, header_len) {
            unread::Unread::InfiRayIrg.reason()
        } else {
            unread::unknown_format(name)
        });
    }
    if let Op::Decode(o) = op {
        if o.page != 0 && format != Format::Tiff && format != Format::Flir {
            return Err(format!("page {} out of range (only TIFF and FLIR SEQ files have several pages)", o.page));
        }
    }
    match (format, op) {
        (Format::Exr, Op::Decode(o)) => exr::decode(reader, o).map(OpOut::Frame),
        (Format::Exr, Op::Channels) => exr::channels(reader).map(OpOut::Channels),
        (Format::Exr, Op::Pages) => exr::channels(reader).map(|_| OpOut::Pages(1, None)),
        (Format::Png, Op::Decode(o)) => raster::decode_png(reader, o).map(OpOut::Frame),
        (Format::Png, Op::Channels) => raster::png_channels(reader).map(OpOut::Channels),
        (Format::Png, Op::Pages) => raster::png_channels(reader).map(|_| OpOut::Pages(1, None)),
        (Format::Tiff, Op::Decode(o)) => raster::decode_tiff(reader, o, key).map(OpOut::Frame),
        (Format::Tiff, Op::Channels) => raster::tiff_channels(reader, key).map(OpOut::Channels),
        (Format::Tiff, Op::Pages) => {
            raster::tiff_page_chain(reader, key).map(|(pages, broken)| OpOut::Pages(pages, broken))
        }
        (Format::Flir, Op::Decode(o)) => {
            seq::decode(reader, o).map(|decoded| OpOut::Frame(calibrated(decoded, key, o.page)))
        }
        (Format::Flir, Op::Channels) => seq::page_chain(reader).map(|_| OpOut::Channels(vec!["Y".to_string()])),
        (Format::Flir, Op::Pages) => seq::page_chain(reader).map(|(pages, broken)| OpOut::Pages(pages, broken)),
        (Format::Flir, Op::Radiometry(o)) => seq::camera_info(reader, o).map(|c| OpOut::Radiometry(Box::new(c))),
        (Format::Jpeg, Op::Decode(o)) => {
            rjpeg::decode(reader, o).map(|decoded| OpOut::Frame(calibrated(decoded, key, o.page)))
        }
        (Format::Jpeg, Op::Channels) => {
            rjpeg::has_fff_frame(reader, DEFAULT_MAX_BYTES).map(|_| OpOut::Channels(vec!["Y".to_string()]))
        }
        (Format::Jpeg, Op::Pages) => rjpeg::has_fff_frame(reader, DEFAULT_MAX_BYTES).map(|_| OpOut::Pages(1, None)),
        (Format::Jpeg, Op::Radiometry(o)) => rjpeg::camera_info(reader, o).map(|c| OpOut::Radiometry(Box::new(c))),
        (Format::Exr | Format::Png | Format::Tiff, Op::Radiometry(_)) => {
            Err("no radiometric calibration: only FLIR files (FFF, SEQ, CSQ, radiometric JPEG) carry one".to_string())
        }
        (Format::Irg(_), _) => unreachable!("an IRG file is refused above"),
    }
}

/// A decoded radiometric frame, its calibration kept for the file `key` names
/// (`calibrations`).
fn calibrated((frame, info): (Frame, Option<CameraInfo>), key: Option<&FileKey>, page: usize) -> Frame {
    if let (Some(key), Some(info)) = (key, info) {
        calibrations::keep(key, page, info);
    }
    frame
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

/// The file's format by its signature (errors are left to the full decode path).
fn sniff_path(path: &Path) -> Option<Format> {
    let mut head = [0u8; 8];
    let n = open_regular(path).ok().and_then(|mut f| std::io::Read::read(&mut f, &mut head).ok()).unwrap_or(0);
    sniff(&head[..n])
}

/// The read buffer for a file: small for a TIFF, whose decoder seeks to each directory and
/// chunk it reads (every seek refills the buffer, and large chunks bypass it), smaller still
/// to walk its `pages` (a few hundred bytes at each: an IFD and its next offset), larger for
/// the formats read front to back.
fn buffer_size(file: &File, pages: bool) -> usize {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileExt;
        let mut head = [0u8; 8];
        if let Ok(n) = file.read_at(&mut head, 0) {
            if sniff(&head[..n]) == Some(Format::Tiff) {
                return if pages { 1 << 9 } else { 1 << 13 };
            }
        }
    }
    1 << 16
}

fn run_on_path(path: &Path, op: Op<'_>) -> Result<OpOut> {
    let name = path.display().to_string();
    let file = open_regular(path).map_err(|reason| frame_err(&name, reason))?;
    let key = file.metadata().map(|meta| FileKey::of(path, &meta)).ok();
    let reader = BufReader::with_capacity(buffer_size(&file, matches!(op, Op::Pages)), file);
    guarded(&name, || run_op(reader, &name, &op, key.as_ref()))
}

/// Decode one frame (one channel of one page) of an OpenEXR, PNG or TIFF file, or the raw counts of
/// a radiometric FLIR file (FFF, one frame of a SEQ, radiometric JPEG).
///
/// A page of a multi-page TIFF costs one IFD read, whatever its place: the file's chain of
/// pages is walked once and kept (`tiff_pages`). A page before the place where a broken
/// chain breaks (a truncated file, a loop) decodes; a page from there on is an error naming
/// why. Errors are `Error::Frame("{path}: {reason}")`.
pub fn decode_frame(path: &Path, opts: &DecodeOptions) -> Result<Frame> {
    if opts.page > 0 && sniff_path(path) == Some(Format::Flir) {
        // later frames of a SEQ: the file's frame index is kept
        let name = path.display().to_string();
        let decoded = guarded(&name, || seq::decode_cached(path, opts))?;
        let key = std::fs::metadata(path).map(|meta| FileKey::of(path, &meta)).ok();
        return Ok(calibrated(decoded, key.as_ref(), opts.page));
    }
    match run_on_path(path, Op::Decode(opts))? {
        OpOut::Frame(f) => Ok(f),
        _ => unreachable!("decode returns a frame"),
    }
}

/// Decode one frame from an in-memory file; `name` is used in error messages.
pub fn decode_bytes(bytes: &[u8], name: &str, opts: &DecodeOptions) -> Result<Frame> {
    match guarded(name, || run_op(Cursor::new(bytes), name, &Op::Decode(opts), None))? {
        OpOut::Frame(f) => Ok(f),
        _ => unreachable!("decode returns a frame"),
    }
}

/// The calibration of a radiometric FLIR file (frame `opts.page` of a SEQ): a FrameError for
/// files without one.
pub fn read_camera_info(path: &Path, opts: &DecodeOptions) -> Result<CameraInfo> {
    if let Some(info) = calibrations::find(path, opts.page) {
        return Ok(info); // decoded with the frame's counts, and the file has not changed since
    }
    match run_on_path(path, Op::Radiometry(opts))? {
        OpOut::Radiometry(c) => Ok(*c),
        _ => unreachable!("read_camera_info returns a calibration"),
    }
}

/// The calibration of a radiometric FLIR frame held in memory (`name` names it in errors), as
/// [`read_camera_info`] reads it from a file.
pub fn read_camera_info_bytes(bytes: &[u8], name: &str, opts: &DecodeOptions) -> Result<CameraInfo> {
    match guarded(name, || run_op(Cursor::new(bytes), name, &Op::Radiometry(opts), None))? {
        OpOut::Radiometry(c) => Ok(*c),
        _ => unreachable!("read_camera_info returns a calibration"),
    }
}

/// The pages of a frame file: how many can be read, and why the rest cannot.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PageChain {
    /// Pages found: the IFDs of a TIFF's chain up to its end or to where it breaks; 1 for
    /// EXR and PNG.
    pub pages: usize,
    /// When a TIFF's IFD chain breaks before its end, why (`"{path}: truncated at page k:
    /// ..."`, `"{path}: the IFD chain loops back at page k: ..."`): page `pages` and any
    /// after it cannot be read. None when the chain ends properly.
    pub broken: Option<String>,
}

/// The pages of a frame file, in one pass over a TIFF's IFD chain (kept for decoding its
/// pages) or a FLIR recording's frame headers, and where and why the chain breaks when it does.
/// An error when not even the first page can be found.
pub fn page_chain(path: &Path) -> Result<PageChain> {
    match run_on_path(path, Op::Pages)? {
        OpOut::Pages(pages, broken) => {
            Ok(PageChain { pages, broken: broken.map(|why| format!("{}: {why}", path.display())) })
        }
        _ => unreachable!("page_chain returns pages"),
    }
}

/// Number of pages: the IFD count of a TIFF, the frame count of a FLIR recording, 1 for EXR
/// and PNG. A chain that breaks before its end is an error naming where and why
/// ([`page_chain`] gives the pages before the break).
pub fn page_count(path: &Path) -> Result<usize> {
    let chain = page_chain(path)?;
    match chain.broken {
        Some(why) => Err(Error::Frame(why)),
        None => Ok(chain.pages),
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
        _ => Err(format!(
            "image of {cols} x {rows} pixels exceeds the limit of {max_pixels} pixels; raise max_pixels \
             (--max-pixels) to decode it"
        )),
    }
}

/// A frame's buffer of `len` copies of `value`, or the system's refusal as the decode's reason:
/// a budget within `max_bytes` can still exceed what the process may have (an address-space
/// limit, other processes), and that is an error, never an abort.
pub(crate) fn frame_buffer<T: Clone>(len: usize, value: T) -> std::result::Result<Vec<T>, Reason> {
    crate::budget::try_filled(len, value).map_err(|e| e.to_string())
}

/// The `len` values `iter` yields, in a frame's buffer reserved at once ([`frame_buffer`]).
pub(crate) fn frame_collect<T>(len: usize, iter: impl Iterator<Item = T>) -> std::result::Result<Vec<T>, Reason> {
    crate::budget::try_collect(len, iter).map_err(|e| e.to_string())
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
