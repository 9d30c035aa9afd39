//! PNG (`png` crate, row by row) and TIFF (`tiff` crate, strip by strip or tile by tile)
//! decoding.
//!
//! Both keep only the selected channel: the output frame is allocated once, and each row
//! (PNG) or chunk (TIFF) of all samples is decoded into a small buffer and the channel's
//! samples copied out (a single-channel row or full-width strip is decoded straight into
//! the frame). The peak memory is therefore the frame plus one row or chunk of all samples,
//! checked against the decoding budget (`max_bytes`) from the header before allocating; PNG
//! metadata chunks are either skipped (ICC profiles, text) or bounded.

use std::io::{BufRead, Read, Seek, SeekFrom};

use tiff::decoder::{ChunkType, Decoder as TiffDecoder, DecodingSampleType, Limits as TiffLimits};
use tiff::ColorType as TiffColor;

use super::tiff_pages::{self, FileKey};
use super::{check_budget, check_size, product, select_channel, DecodeOptions, Frame, FrameData, Reason};

// ----------------------------------------------------------------------------- sample bytes

/// Plain sample types: every bit pattern is a valid value and there is no padding, so a
/// slice of them may be viewed as bytes (the decoders write native-endian samples).
pub(super) trait Plain: Copy + Default + 'static {}
impl Plain for u8 {}
impl Plain for i8 {}
impl Plain for u16 {}
impl Plain for i16 {}
impl Plain for u32 {}
impl Plain for half::f16 {}
impl Plain for f32 {}
impl Plain for f64 {}

/// The bytes of a slice of plain samples.
fn bytes_mut<T: Plain>(v: &mut [T]) -> &mut [u8] {
    // SAFETY: `T: Plain` has no padding and every bit pattern is a valid `T` (sealed list
    // above), u8 has alignment 1, and the byte length is exactly `size_of_val(v)`; the
    // returned borrow keeps `v` borrowed mutably for as long as the bytes live.
    unsafe { std::slice::from_raw_parts_mut(v.as_mut_ptr().cast::<u8>(), std::mem::size_of_val(v)) }
}

// ----------------------------------------------------------------------------- PNG

/// Memory the `png` crate may use for metadata chunks it keeps (eXIf, palette, ...): ICC
/// profiles and text chunks are not read at all (their compressed forms inflate to GBs).
const PNG_METADATA_BYTES: u64 = 16 << 20;

fn png_err(e: png::DecodingError) -> Reason {
    use png::DecodingError as E;
    match e {
        E::LimitsExceeded => format!(
            "PNG metadata chunks need more memory than allowed ({PNG_METADATA_BYTES} bytes at most, within \
             the decoding budget, max_bytes)"
        ),
        E::IoError(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            "truncated PNG file (unexpected end of file)".to_string()
        }
        E::IoError(io) => format!("read error: {io}"),
        E::Format(f) => format!("corrupt or invalid PNG file: {f}"),
        other => format!("corrupt or unsupported PNG file: {other}"),
    }
}

fn png_names(colour: png::ColorType) -> Result<&'static [&'static str], Reason> {
    use png::ColorType as C;
    Ok(match colour {
        C::Grayscale => &["Y"],
        C::GrayscaleAlpha => &["Y", "A"],
        C::Rgb => &["R", "G", "B"],
        C::Rgba => &["R", "G", "B", "A"],
        other => return Err(format!("unsupported PNG colour type {other:?}")),
    })
}

/// An open PNG past its metadata, with the output (after palette and low-bit expansion)
/// described.
struct PngOpen<R: BufRead + Seek> {
    reader: png::Reader<R>,
    names: &'static [&'static str],
    sixteen: bool,
    /// 1-, 2- and 4-bit grey is expanded to 8 bits by scaling (x255, x85, x17): undone.
    low_grey_scale: Option<u8>,
}

fn png_open<R: BufRead + Seek>(reader: R, o: &DecodeOptions) -> Result<PngOpen<R>, Reason> {
    let mut dec = png::Decoder::new_with_limits(reader, png::Limits { bytes: PNG_METADATA_BYTES as usize });
    dec.set_ignore_iccp_chunk(true);
    dec.set_ignore_text_chunk(true);
    dec.set_transformations(png::Transformations::EXPAND);
    let info = dec.read_header_info().map_err(png_err)?;
    let (w, h) = (info.width, info.height);
    check_size(w as u64, h as u64, o.max_pixels)?;
    let low_grey_scale = match (info.color_type, info.bit_depth as u8) {
        (png::ColorType::Grayscale | png::ColorType::GrayscaleAlpha, 1) => Some(255),
        (png::ColorType::Grayscale | png::ColorType::GrayscaleAlpha, 2) => Some(85),
        (png::ColorType::Grayscale | png::ColorType::GrayscaleAlpha, 4) => Some(17),
        _ => None,
    };
    // The decoder's rows (raw, unfiltered and expanded: at most 4 samples of 2 bytes) and
    // our row buffer; the frame itself is ours. Metadata chunks it keeps get what is left of
    // the budget, up to `PNG_METADATA_BYTES`.
    let row = product(&[w as u64, 8]).map(|b| b + 1);
    let rows = row.and_then(|r| r.checked_mul(5));
    let sample = if info.bit_depth as u8 == 16 { 2 } else { 1 };
    let frame = product(&[w as u64, h as u64, sample]);
    let need = frame.zip(rows).and_then(|(f, r)| f.checked_add(r));
    check_budget(need, || format!("a {w} x {h} PNG frame"), o.max_bytes)?;
    let (need, rows) = need.zip(rows).expect("checked above");
    let working = rows + PNG_METADATA_BYTES.min(o.max_bytes - need);
    dec.set_limits(png::Limits { bytes: usize::try_from(working).unwrap_or(usize::MAX) });
    let reader = dec.read_info().map_err(png_err)?;
    if let Some(palette) = &reader.info().palette {
        // the png crate indexes a palette in whole entries (it panics on a partial one)
        if palette.len() % 3 != 0 || palette.len() > 3 * 256 {
            return Err(format!(
                "corrupt PNG file: the PLTE chunk holds {} bytes (the PNG specification requires 3 per entry, at \
                 most 256 entries)",
                palette.len()
            ));
        }
    }
    let (colour, depth) = reader.output_color_type();
    let names = png_names(colour)?;
    Ok(PngOpen { reader, names, sixteen: depth == png::BitDepth::Sixteen, low_grey_scale })
}

pub(super) fn png_channels<R: BufRead + Seek>(reader: R) -> Result<Vec<String>, Reason> {
    let open = png_open(reader, &DecodeOptions::default())?;
    Ok(open.names.iter().map(|s| s.to_string()).collect())
}

/// Where the pixels of one decoded row go: frame row `y`, columns `x0, x0 + dx, ...`
/// (`count` of them). Non-interlaced rows in order; Adam7 pass rows in the order the
/// decoder returns them (passes with no pixels are skipped, as the `png` crate does).
#[derive(Clone, Copy, Debug, PartialEq)]
struct RowPlace {
    y: usize,
    x0: usize,
    dx: usize,
    count: usize,
}

fn row_places(w: usize, h: usize, interlaced: bool) -> Vec<RowPlace> {
    if !interlaced {
        return (0..h).map(|y| RowPlace { y, x0: 0, dx: 1, count: w }).collect();
    }
    // Adam7: (x offset, y offset, x step, y step) of passes 1..7
    const PASSES: [(usize, usize, usize, usize); 7] =
        [(0, 0, 8, 8), (4, 0, 8, 8), (0, 4, 4, 8), (2, 0, 4, 4), (0, 2, 2, 4), (1, 0, 2, 2), (0, 1, 1, 2)];
    let mut out = Vec::new();
    for (x0, y0, dx, dy) in PASSES {
        let count = w.saturating_sub(x0).div_ceil(dx);
        let lines = h.saturating_sub(y0).div_ceil(dy);
        if count > 0 {
            out.extend((0..lines).map(|line| RowPlace { y: y0 + line * dy, x0, dx, count }));
        }
    }
    out
}

/// A PNG sample in the frame: u8, or u16 from big-endian bytes.
trait PngSample: Plain {
    const SIZE: usize;
    fn from_be(b: &[u8]) -> Self;
    /// In place, the big-endian samples the decoder wrote into the frame.
    fn fix_order(v: &mut [Self]);
}

impl PngSample for u8 {
    const SIZE: usize = 1;
    #[inline]
    fn from_be(b: &[u8]) -> Self {
        b[0]
    }
    fn fix_order(_: &mut [Self]) {}
}

impl PngSample for u16 {
    const SIZE: usize = 2;
    #[inline]
    fn from_be(b: &[u8]) -> Self {
        u16::from_be_bytes([b[0], b[1]])
    }
    fn fix_order(v: &mut [Self]) {
        v.iter_mut().for_each(|x| *x = u16::from_be(*x));
    }
}

/// Channel `c` of the PNG's rows into a `w` x `h` frame: a non-interlaced single-channel
/// row is read straight into its frame row, anything else through one row buffer.
fn png_rows<T: PngSample, R: BufRead + Seek>(
    reader: &mut png::Reader<R>,
    (w, h): (usize, usize),
    spp: usize,
    c: usize,
) -> Result<Vec<T>, Reason> {
    let interlaced = reader.info().interlaced;
    let mut out = super::frame_buffer(w * h, T::default())?;
    let truncated = || "truncated or corrupt PNG file (image data ends early)".to_string();
    if spp == 1 && !interlaced {
        for row in out.chunks_exact_mut(w) {
            reader.read_row(bytes_mut(row)).map_err(png_err)?.ok_or_else(truncated)?;
            T::fix_order(row);
        }
    } else {
        let mut line = vec![0u8; w * spp * T::SIZE];
        for p in row_places(w, h, interlaced) {
            reader.read_row(&mut line).map_err(png_err)?.ok_or_else(truncated)?;
            let dst = &mut out[p.y * w..(p.y + 1) * w];
            let pixels = line.chunks_exact(spp * T::SIZE).take(p.count);
            for (x, px) in (p.x0..).step_by(p.dx).zip(pixels) {
                dst[x] = T::from_be(&px[c * T::SIZE..]);
            }
        }
    }
    // the end of the image data (as the decoder's own frame reader checks it)
    reader.read_row(&mut []).map_err(png_err)?;
    Ok(out)
}

pub(super) fn decode_png<R: BufRead + Seek>(reader: R, o: &DecodeOptions) -> Result<Frame, Reason> {
    let PngOpen { mut reader, names, sixteen, low_grey_scale } = png_open(reader, o)?;
    let names: Vec<String> = names.iter().map(|s| s.to_string()).collect();
    let c = select_channel(&names, o.channel.as_deref())?;
    let (w, h) = (reader.info().width as usize, reader.info().height as usize);
    let data = if sixteen {
        FrameData::U16(png_rows::<u16, R>(&mut reader, (w, h), names.len(), c)?)
    } else {
        let mut v = png_rows::<u8, R>(&mut reader, (w, h), names.len(), c)?;
        if let (Some(k), "Y") = (low_grey_scale, names[c].as_str()) {
            v.iter_mut().for_each(|x| *x /= k);
        }
        FrameData::U8(v)
    };
    Ok(Frame { rows: h, cols: w, data })
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
        E::LimitsExceeded => {
            "corrupt TIFF file: a tag value or a chunk is larger than the decoder allows (or than the file)".to_string()
        }
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

fn tiff_open<R: Read + Seek>(mut reader: R) -> Result<TiffDecoder<R>, Reason> {
    let file_len = reader.seek(SeekFrom::End(0)).map_err(|e| format!("read error: {e}"))?;
    reader.rewind().map_err(|e| format!("read error: {e}"))?;
    let mut limits = TiffLimits::default();
    // We allocate every buffer ourselves (checked against the budget); the decoder only
    // reads a chunk's compressed bytes, which cannot be more than the file holds.
    limits.intermediate_buffer_size = usize::try_from(file_len).unwrap_or(usize::MAX);
    TiffDecoder::new(reader).map_err(tiff_err).map(|d| d.with_limits(limits))
}

/// The pages of the TIFF `reader` holds (`key`: the file's identity, for the page cache).
pub(super) fn tiff_page_chain<R: Read + Seek>(
    mut reader: R,
    key: Option<&FileKey>,
) -> Result<(usize, Option<Reason>), Reason> {
    let chain = tiff_pages::chain(&mut reader, key)?;
    Ok((chain.pages(), chain.broken.clone()))
}

/// The first page's channel names.
pub(super) fn tiff_channels<R: Read + Seek>(mut reader: R, key: Option<&FileKey>) -> Result<Vec<String>, Reason> {
    let chain = tiff_pages::chain(&mut reader, key)?;
    let mut dec = tiff_open(chain.one_page(reader, 0)?)?;
    tiff_names(dec.colortype().map_err(tiff_err)?)
}

/// Decode page `o.page`: the chain of pages from the cache (by `key`, the file's identity)
/// or walked once, then that page alone (whatever its place in the chain).
pub(super) fn decode_tiff<R: Read + Seek>(
    mut reader: R,
    o: &DecodeOptions,
    key: Option<&FileKey>,
) -> Result<Frame, Reason> {
    let chain = tiff_pages::chain(&mut reader, key)?;
    let view = chain.one_page(reader, o.page)?;
    // in a multi-page file, say which page failed
    let in_page = |e: Reason| if chain.pages() > 1 { format!("page {}: {e}", o.page) } else { e };
    let mut dec = tiff_open(view).map_err(in_page)?;
    decode_tiff_page(&mut dec, o).map_err(in_page)
}

/// How one page's samples are stored: chunks (strips or tiles) of `chunk` pixels in a grid
/// `across` wide, holding `per_chunk` samples per pixel (all of them, or one plane); the
/// selected channel is sample `offset` of each pixel of the chunks from `first` on.
struct ChunkGrid {
    width: usize,
    height: usize,
    chunk: (usize, usize),
    across: usize,
    per_chunk: usize,
    offset: usize,
    first: usize,
}

impl ChunkGrid {
    fn chunks(&self) -> usize {
        self.across * self.height.div_ceil(self.chunk.1)
    }
    /// Position and size (x, y, w, h) of chunk `k` (counted from `first`) in the frame.
    fn place(&self, k: usize) -> (usize, usize, usize, usize) {
        let (x, y) = (k % self.across * self.chunk.0, k / self.across * self.chunk.1);
        (x, y, self.chunk.0.min(self.width - x), self.chunk.1.min(self.height - y))
    }
    /// Whether chunks are decoded straight into the frame: one sample per pixel, full rows.
    fn direct(&self) -> bool {
        self.per_chunk == 1 && self.chunk.0 >= self.width
    }
    /// Samples of the largest chunk (the scratch buffer when not `direct`).
    fn scratch_len(&self) -> Option<u64> {
        product(&[self.chunk.0.min(self.width) as u64, self.chunk.1.min(self.height) as u64, self.per_chunk as u64])
    }
}

/// The page's chunk layout; checked before the decoder divides by a chunk size.
fn chunk_grid<R: Read + Seek>(dec: &mut TiffDecoder<R>, spp: usize, c: usize) -> Result<ChunkGrid, Reason> {
    let (w, h) = dec.dimensions().map_err(tiff_err)?;
    let (w, h) = (w as usize, h as usize);
    let (cw, ch) = match dec.get_chunk_type() {
        ChunkType::Strip => (w, dec.chunk_dimensions().1 as usize),
        ChunkType::Tile => {
            let (tw, th) = dec.chunk_dimensions();
            (tw as usize, th as usize)
        }
    };
    if cw == 0 || ch == 0 {
        return Err(format!("corrupt TIFF file: chunks of {cw} x {ch} pixels"));
    }
    let planar = dec.image_buffer_layout().map_err(tiff_err)?.planes > 1;
    let across = w.div_ceil(cw);
    let per_plane = across * h.div_ceil(ch);
    Ok(ChunkGrid {
        width: w,
        height: h,
        chunk: (cw, ch),
        across,
        per_chunk: if planar { 1 } else { spp },
        offset: if planar { 0 } else { c },
        first: if planar { c * per_plane } else { 0 },
    })
}

/// The selected channel of every chunk into a frame of `T`.
fn read_chunks<T: Plain, R: Read + Seek>(dec: &mut TiffDecoder<R>, g: &ChunkGrid) -> Result<Vec<T>, Reason> {
    let mut out = super::frame_buffer(g.width * g.height, T::default())?;
    let mut scratch: Vec<T> = Vec::new();
    for k in 0..g.chunks() {
        let index = u32::try_from(g.first + k).map_err(|_| "corrupt TIFF file: too many chunks".to_string())?;
        let (x, y, cw, ch) = g.place(k);
        let chunk_err = |e| format!("{} (in chunk {index})", tiff_err(e));
        if g.direct() {
            dec.read_chunk_bytes(index, bytes_mut(&mut out[y * g.width..])).map_err(chunk_err)?;
            continue;
        }
        let len = cw * ch * g.per_chunk;
        if len > scratch.len() {
            scratch = super::frame_buffer(len, T::default())?;
        }
        scratch.truncate(len);
        dec.read_chunk_bytes(index, bytes_mut(&mut scratch)).map_err(chunk_err)?;
        for (r, src) in scratch.chunks_exact(cw * g.per_chunk).enumerate() {
            let dst = &mut out[(y + r) * g.width + x..][..cw];
            for (d, px) in dst.iter_mut().zip(src.chunks_exact(g.per_chunk)) {
                *d = px[g.offset];
            }
        }
    }
    Ok(out)
}

/// Decode the decoder's current page.
fn decode_tiff_page<R: Read + Seek>(dec: &mut TiffDecoder<R>, o: &DecodeOptions) -> Result<Frame, Reason> {
    let (w, h) = dec.dimensions().map_err(tiff_err)?;
    check_size(w as u64, h as u64, o.max_pixels)?;
    let color = dec.colortype().map_err(tiff_err)?;
    let names = tiff_names(color)?;
    let c = select_channel(&names, o.channel.as_deref())?;
    let g = chunk_grid(dec, names.len(), c)?;
    let sample = dec.image_chunk_buffer_layout(0).map_err(tiff_err)?.sample_type;
    let bits = color.bit_depth();
    let size: u64 = match sample {
        Some(DecodingSampleType::U8 | DecodingSampleType::I8) if bits == 8 => 1,
        Some(DecodingSampleType::U16 | DecodingSampleType::I16 | DecodingSampleType::F16) if bits == 16 => 2,
        Some(DecodingSampleType::U32 | DecodingSampleType::F32) if bits == 32 => 4,
        Some(DecodingSampleType::F64) if bits == 64 => 8,
        Some(DecodingSampleType::U64) => return Err("unsupported TIFF sample type uint64".to_string()),
        Some(DecodingSampleType::I32) => return Err("unsupported TIFF sample type int32".to_string()),
        Some(DecodingSampleType::I64) => return Err("unsupported TIFF sample type int64".to_string()),
        _ => return Err(format!("unsupported TIFF colour type {color:?} ({bits}-bit samples are not decoded)")),
    };
    // the frame (int8 is widened to int16: both held a moment), plus one chunk of all samples
    let frame = product(&[w as u64, h as u64, if sample == Some(DecodingSampleType::I8) { 3 } else { size }]);
    let scratch = if g.direct() { Some(0) } else { g.scratch_len().and_then(|n| n.checked_mul(size)) };
    let need = frame.zip(scratch).and_then(|(f, s)| f.checked_add(s));
    let what = || format!("a {w} x {h} TIFF frame and one chunk of {} x {} pixels", g.chunk.0, g.chunk.1);
    check_budget(need, what, o.max_bytes)?;
    let data = match sample {
        Some(DecodingSampleType::U8) => FrameData::U8(read_chunks(dec, &g)?),
        Some(DecodingSampleType::I8) => {
            let narrow = read_chunks::<i8, R>(dec, &g)?;
            FrameData::I16(super::frame_collect(narrow.len(), narrow.into_iter().map(i16::from))?)
        }
        Some(DecodingSampleType::U16) => FrameData::U16(read_chunks(dec, &g)?),
        Some(DecodingSampleType::I16) => FrameData::I16(read_chunks(dec, &g)?),
        Some(DecodingSampleType::F16) => FrameData::F16(read_chunks(dec, &g)?),
        Some(DecodingSampleType::U32) => FrameData::U32(read_chunks(dec, &g)?),
        Some(DecodingSampleType::F32) => FrameData::F32(read_chunks(dec, &g)?),
        _ => FrameData::F64(read_chunks(dec, &g)?),
    };
    Ok(Frame { rows: h as usize, cols: w as usize, data })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn adam7_places_cover_every_pixel_once() {
        for (w, h) in [(1usize, 1usize), (2, 1), (1, 9), (5, 3), (8, 8), (9, 17), (33, 2)] {
            let mut seen = vec![0u8; w * h];
            for p in row_places(w, h, true) {
                for i in 0..p.count {
                    seen[p.y * w + p.x0 + i * p.dx] += 1;
                }
            }
            assert!(seen.iter().all(|&k| k == 1), "{w} x {h}");
        }
    }

    #[test]
    fn sample_bytes_are_native() {
        let mut v = [0x0102u16, 0xa0b0];
        let b = bytes_mut(&mut v);
        assert_eq!(b, [0x0102u16.to_ne_bytes(), 0xa0b0u16.to_ne_bytes()].concat());
        b[2..].copy_from_slice(&0xbeefu16.to_ne_bytes());
        assert_eq!(v, [0x0102, 0xbeef]);
        let mut odd = [1.5f64, -2.0, 3.25];
        assert_eq!(bytes_mut(&mut odd[1..]).len(), 16);
        let mut empty: [f64; 0] = [];
        assert!(bytes_mut(&mut empty).is_empty());
    }
}
