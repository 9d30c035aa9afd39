//! OpenEXR decoding with the `exr` crate's block-level API.
//!
//! Only the blocks of the selected part at the largest resolution level are read; each
//! block is decompressed (shared between the calling thread and idle pool threads, see
//! `kernel::map_units`) and only the selected channel's
//! samples are copied out, in the file's own sample type (f16 / f32 / u32). The output is
//! the data window (like OpenEXR's own readers), row-major. The decode's peak memory — the
//! frame, the blocks of a round and the blocks in flight, each of *all* channels — is planned
//! from the header against the decoding budget before any block is read (`plan`).

use std::collections::HashSet;
use std::io::{BufRead, Seek, SeekFrom};

use ::exr::block::chunk::{Chunk, CompressedBlock};
use ::exr::block::reader::ChunksReader;
use ::exr::block::UncompressedBlock;
use ::exr::compression::Compression;
use ::exr::math::Vec2;
use ::exr::meta::attribute::SampleType;
use ::exr::meta::header::Header;
use ::exr::meta::{BlockDescription, MetaData};
use half::f16;

use super::piz::{self, FromWords};
use super::zip;
use super::{check_budget, check_size, product, DecodeOptions, Frame, FrameData, Reason};

/// Map an `exr` crate error to a reason.
fn exr_err(e: ::exr::error::Error) -> Reason {
    use ::exr::error::Error as E;
    match e {
        E::NotSupported(m) if m.contains("deep") => {
            format!("unsupported: deep data ({m}); only flat OpenEXR images can be decoded")
        }
        E::NotSupported(m) if m.contains("compression") => format!("unsupported compression ({m})"),
        E::NotSupported(m) => format!("unsupported OpenEXR feature: {m}"),
        E::Invalid(m) => format!("corrupt or invalid OpenEXR file: {m}"),
        E::Io(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            "truncated OpenEXR file (unexpected end of file)".to_string()
        }
        E::Io(io) => format!("read error: {io}"),
        E::Aborted => "OpenEXR decoding aborted".to_string(),
    }
}

/// One selectable channel: part index, channel index in that part, display name,
/// bare channel name.
struct Entry {
    part: usize,
    channel: usize,
    name: String,
    bare: String,
}

fn part_label(index: usize, header: &Header) -> String {
    match &header.own_attributes.layer_name {
        Some(n) if !n.to_string().is_empty() => n.to_string(),
        _ => format!("part{index}"),
    }
}

fn entries(headers: &[Header]) -> Vec<Entry> {
    let multi = headers.len() > 1;
    let mut out = Vec::new();
    for (p, h) in headers.iter().enumerate() {
        let label = if multi { Some(part_label(p, h)) } else { None };
        for (c, ch) in h.channels.list.iter().enumerate() {
            let bare = ch.name.to_string();
            let name = match &label {
                Some(l) => format!("{l}.{bare}"),
                None => bare.clone(),
            };
            out.push(Entry { part: p, channel: c, name, bare });
        }
    }
    out
}

fn listing(names: impl Iterator<Item = String>) -> String {
    let all: Vec<String> = names.collect();
    if all.len() > 40 {
        format!("{}, ... ({} in all)", all[..40].join(", "), all.len())
    } else {
        all.join(", ")
    }
}

fn select(headers: &[Header], channel: Option<&str>) -> Result<(usize, usize), Reason> {
    let es = entries(headers);
    if es.is_empty() {
        return Err("corrupt or invalid OpenEXR file: no channels".to_string());
    }
    let all = || listing(es.iter().map(|e| e.name.clone()));
    let by_bare = |want: &str| -> Vec<&Entry> { es.iter().filter(|e| e.bare == want).collect() };
    match channel {
        Some(want) => {
            if let Some(e) = es.iter().find(|e| e.name == want) {
                return Ok((e.part, e.channel));
            }
            let m = by_bare(want);
            match m.len() {
                1 => Ok((m[0].part, m[0].channel)),
                0 => Err(format!("no channel {want:?}; channels are: {}", all())),
                _ => Err(format!(
                    "channel {want:?} is ambiguous (in several parts); choose one of: {}",
                    listing(m.iter().map(|e| e.name.clone()))
                )),
            }
        }
        None => {
            if es.len() == 1 {
                return Ok((es[0].part, es[0].channel));
            }
            let ys = by_bare("Y");
            if ys.len() == 1 {
                return Ok((ys[0].part, ys[0].channel));
            }
            Err(format!("several channels ({}); choose one with channel=...", all()))
        }
    }
}

pub(super) fn channels<R: BufRead + Seek>(reader: R) -> Result<Vec<String>, Reason> {
    let r = ::exr::block::read(reader, false).map_err(exr_err)?;
    Ok(entries(r.headers()).into_iter().map(|e| e.name).collect())
}

/// A sample type as stored in an uncompressed (native-endian) block.
trait Sample: FromWords + Copy + Send + Sync + 'static {
    const ZERO: Self;
    const SIZE: usize;
    fn from_ne(b: &[u8]) -> Self;
}

impl Sample for f16 {
    const ZERO: Self = f16::ZERO;
    const SIZE: usize = 2;
    #[inline]
    fn from_ne(b: &[u8]) -> Self {
        f16::from_bits(u16::from_ne_bytes([b[0], b[1]]))
    }
}

impl Sample for f32 {
    const ZERO: Self = 0.0;
    const SIZE: usize = 4;
    #[inline]
    fn from_ne(b: &[u8]) -> Self {
        f32::from_ne_bytes([b[0], b[1], b[2], b[3]])
    }
}

impl Sample for u32 {
    const ZERO: Self = 0;
    const SIZE: usize = 4;
    #[inline]
    fn from_ne(b: &[u8]) -> Self {
        u32::from_ne_bytes([b[0], b[1], b[2], b[3]])
    }
}

/// Which decoder reads a part's blocks: our single-channel PIZ decoder (with the 16-bit
/// words per sample of every channel), our single-channel ZIP/ZIPS decoder, or the `exr`
/// crate for every other compression.
enum Codec {
    Piz(Vec<usize>),
    Zip,
    Crate,
}

/// Byte layout of one pixel row of a block: bytes per pixel over all channels, and the
/// offset (per pixel) of the selected channel's run within a row; the selected channel's
/// index, and the codec.
struct Layout {
    bytes_per_pixel: usize,
    channel_offset_per_pixel: usize,
    channel: usize,
    codec: Codec,
}

/// Samples of the selected channel from one decompressed block, with its placement.
struct Piece<T> {
    x: usize,
    y: usize,
    w: usize,
    h: usize,
    samples: Vec<T>,
}

fn extract<T: Sample>(block: &UncompressedBlock, layout: &Layout) -> Result<Piece<T>, Reason> {
    let Vec2(w, h) = block.index.pixel_size;
    let Vec2(x, y) = block.index.pixel_position;
    let row_bytes = w.checked_mul(layout.bytes_per_pixel).ok_or_else(|| "corrupt OpenEXR block size".to_string())?;
    let expected = row_bytes.checked_mul(h).ok_or_else(|| "corrupt OpenEXR block size".to_string())?;
    if block.data.len() != expected {
        return Err(format!(
            "corrupt OpenEXR block at ({x}, {y}): {} bytes decompressed, {expected} expected",
            block.data.len()
        ));
    }
    let mut samples = Vec::new();
    samples.try_reserve_exact(w * h).map_err(|_| format!("out of memory for a block of {w} x {h} samples"))?;
    let run = w * T::SIZE;
    for r in 0..h {
        let start = r * row_bytes + w * layout.channel_offset_per_pixel;
        let line = &block.data[start..start + run];
        samples.extend(line.chunks_exact(T::SIZE).map(T::from_ne));
    }
    Ok(Piece { x, y, w, h, samples })
}

/// The selected channel of one chunk: PIZ and ZIP blocks through our single-channel
/// decoders (unless stored raw because compression did not pay), everything else through
/// the `exr` crate.
fn decompress<T: Sample>(c: Chunk, meta: &MetaData, layout: &Layout) -> Result<Piece<T>, Reason> {
    if !matches!(layout.codec, Codec::Crate) {
        let header = meta
            .headers
            .get(c.layer_index)
            .ok_or_else(|| "corrupt OpenEXR file: chunk names a missing part".to_string())?;
        let tile = header.get_block_data_indices(&c.compressed_block).map_err(exr_err)?;
        let bounds = header.get_absolute_block_pixel_coordinates(tile).map_err(exr_err)?;
        bounds.validate(Some(header.layer_size)).map_err(exr_err)?;
        let Vec2(x, y) = bounds.position.to_usize("block position").map_err(exr_err)?;
        let Vec2(w, h) = bounds.size;
        let bytes = match &c.compressed_block {
            CompressedBlock::ScanLine(b) => &b.compressed_pixels_le,
            CompressedBlock::Tile(b) => &b.compressed_pixels_le,
            _ => return Err("unsupported: deep data (only flat OpenEXR images can be decoded)".to_string()),
        };
        if Some(bytes.len()) != w.checked_mul(h).and_then(|n| n.checked_mul(layout.bytes_per_pixel)) {
            let samples = match &layout.codec {
                Codec::Piz(words) => piz::decode_channel::<T>(bytes, words, layout.channel, w, h)?,
                _ => zip::decode_channel::<T>(bytes, layout.bytes_per_pixel, layout.channel_offset_per_pixel, w, h)?,
            };
            return Ok(Piece { x, y, w, h, samples });
        }
    }
    let block = UncompressedBlock::decompress_chunk(c, meta, false).map_err(exr_err)?;
    extract::<T>(&block, layout)
}

/// Decompressed copies of a block (all channels) one block in flight may hold at once: the
/// decompressed block, and the decompressor's own intermediate buffers (the `exr` crate's
/// PXR24, RLE and B44 paths hold one or two more; ours, the inflated or Huffman-decoded
/// words). The extracted channel is counted apart.
const WORK_COPIES: u64 = 3;

/// Compressed bytes, and separately the extracted channel's bytes, held per round of
/// sharing (a round holds at least one block).
const BATCH_BYTES: u64 = 32 << 20;

/// How many blocks are decoded per round and whether in parallel, so that the decode's peak
/// memory stays within the budget: the frame; a round's extracted channel and compressed
/// bytes, plus the chunk being read (the `exr` crate allocates up to its header's largest
/// block, unclamped, for a chunk before reading it); the blocks in flight (one per thread)
/// with their scratch.
struct Plan {
    /// blocks per round
    batch: usize,
    parallel: bool,
}

/// The most a chunk of any part may claim to hold, as the `exr` crate bounds its read: the
/// header's bytes per pixel times the block's area (the tile as declared, or the lines per
/// block across the layer).
fn read_bound(headers: &[Header]) -> Option<u64> {
    headers.iter().try_fold(0u64, |most, h| {
        let area = match &h.blocks {
            BlockDescription::Tiles(t) => product(&[t.tile_size.0 as u64, t.tile_size.1 as u64]),
            BlockDescription::ScanLines => {
                product(&[h.compression.scan_lines_per_block() as u64, h.layer_size.0 as u64])
            }
        };
        Some(most.max(area?.checked_mul(h.channels.bytes_per_pixel as u64)?))
    })
}

fn plan(headers: &[Header], h: &Header, layout: &Layout, sample: u64, o: &DecodeOptions) -> Result<Plan, Reason> {
    let Vec2(cols, rows) = h.layer_size;
    let (bw, bh) = match &h.blocks {
        BlockDescription::Tiles(t) => (t.tile_size.0.min(cols), t.tile_size.1.min(rows)),
        BlockDescription::ScanLines => (cols, h.compression.scan_lines_per_block().min(rows)),
    };
    let (bw, bh, bpp) = (bw as u64, bh as u64, layout.bytes_per_pixel as u64);
    let block = product(&[bw, bh, bpp]); // all channels, uncompressed
    let piece = product(&[bw, bh, sample]); // the selected channel
    let frame = product(&[rows as u64, cols as u64, sample]);
    let threads = rayon::current_num_threads().max(1) as u64;
    let batch = piece.map_or(1, |p| (BATCH_BYTES / p.max(1)).clamp(1, (threads * 16).max(32)));
    let need = |in_flight: u64| -> Option<u64> {
        let held = frame?.checked_add(piece?.checked_mul(batch)?)?.checked_add(BATCH_BYTES)?;
        let reading = held.checked_add(read_bound(headers)?)?;
        reading.checked_add(block?.checked_mul(WORK_COPIES)?.checked_mul(in_flight)?)
    };
    let what = || {
        format!(
            "a {cols} x {rows} OpenEXR frame in blocks of {bw} x {bh} pixels of {} channels ({bpp} bytes per pixel)",
            h.channels.list.len()
        )
    };
    check_budget(need(1), what, o.max_bytes)?;
    let parallel = threads > 1 && need(threads).is_some_and(|n| n <= o.max_bytes);
    Ok(Plan { batch: batch as usize, parallel })
}

/// Bytes of a chunk's compressed data.
fn compressed_len(c: &Chunk) -> usize {
    match &c.compressed_block {
        CompressedBlock::ScanLine(b) => b.compressed_pixels_le.len(),
        CompressedBlock::Tile(b) => b.compressed_pixels_le.len(),
        CompressedBlock::DeepScanLine(b) => b.compressed_sample_data_le.len(),
        CompressedBlock::DeepTile(b) => b.compressed_sample_data_le.len(),
    }
}

fn assemble<T: Sample, C: ChunksReader>(
    mut chunks: C,
    layout: &Layout,
    plan: &Plan,
    rows: usize,
    cols: usize,
) -> Result<Vec<T>, Reason> {
    let meta = chunks.meta_data().clone();
    let mut out: Vec<T> = super::frame_buffer(rows * cols, T::ZERO)?;
    let mut seen: HashSet<(usize, usize)> = HashSet::new();
    let mut covered: usize = 0;
    // blocks per round of sharing: each round wakes a helper, and bounds the bytes held
    let batch = plan.batch;
    loop {
        let mut compressed: Vec<Chunk> = Vec::with_capacity(batch);
        let mut bytes = 0u64;
        while compressed.len() < batch && bytes < BATCH_BYTES {
            match chunks.next() {
                Some(c) => {
                    let c = c.map_err(exr_err)?;
                    bytes += compressed_len(&c) as u64;
                    compressed.push(c);
                }
                None => break,
            }
        }
        if compressed.is_empty() {
            break;
        }
        // blocks shared with idle pool threads (unless the pool is busy with other frames)
        let slots: Vec<std::sync::Mutex<Option<Chunk>>> =
            compressed.into_iter().map(|c| std::sync::Mutex::new(Some(c))).collect();
        let Ok(pieces) = crate::kernel::map_units::<_, std::convert::Infallible>(slots.len(), plan.parallel, |i| {
            // each unit is taken once (a shared counter), so its slot still holds the block
            let block = slots[i].lock().unwrap_or_else(|p| p.into_inner()).take();
            Ok(match block {
                Some(c) => decompress::<T>(c, &meta, layout),
                None => Err("internal error: an EXR block was decoded twice".to_string()),
            })
        });
        for piece in pieces {
            let p = piece?;
            if p.x.checked_add(p.w).is_none_or(|e| e > cols) || p.y.checked_add(p.h).is_none_or(|e| e > rows) {
                return Err(format!(
                    "corrupt OpenEXR file: block at ({}, {}) of {} x {} lies outside the data window",
                    p.x, p.y, p.w, p.h
                ));
            }
            if !seen.insert((p.x, p.y)) {
                return Err(format!("corrupt OpenEXR file: block at ({}, {}) appears twice", p.x, p.y));
            }
            for r in 0..p.h {
                let dst = (p.y + r) * cols + p.x;
                out[dst..dst + p.w].copy_from_slice(&p.samples[r * p.w..(r + 1) * p.w]);
            }
            covered += p.w * p.h;
        }
    }
    if covered != rows * cols {
        return Err(format!("truncated or corrupt OpenEXR file: its blocks cover {covered} of {} pixels", rows * cols));
    }
    Ok(out)
}

pub(super) fn decode<R: BufRead + Seek>(mut reader: R, o: &DecodeOptions) -> Result<Frame, Reason> {
    let file_len = reader.seek(SeekFrom::End(0)).map_err(|e| format!("read error: {e}"))?;
    reader.rewind().map_err(|e| format!("read error: {e}"))?;

    let r = ::exr::block::read(reader, false).map_err(exr_err)?;
    let headers = r.headers();
    let (part, ch) = select(headers, o.channel.as_deref())?;
    let h = &headers[part];
    let label = if headers.len() > 1 { format!(" (part {})", part_label(part, h)) } else { String::new() };
    if h.deep {
        return Err(format!("unsupported: deep data{label} (only flat OpenEXR images can be decoded)"));
    }
    let sub: Vec<String> = h
        .channels
        .list
        .iter()
        .filter(|c| c.sampling != Vec2(1, 1))
        .map(|c| format!("{} ({}x{})", c.name, c.sampling.0, c.sampling.1))
        .collect();
    if !sub.is_empty() {
        return Err(format!(
            "unsupported: subsampled channels{label}: {} (luminance/chroma images are not supported)",
            sub.join(", ")
        ));
    }
    let Vec2(cols, rows) = h.layer_size;
    check_size(cols as u64, rows as u64, o.max_pixels)?;

    // Every chunk has an 8-byte entry in the offset tables: a header that claims more
    // chunks than the file could hold is corrupt; refuse it before walking the tables.
    let mut total_chunks: u64 = 0;
    for hh in headers {
        total_chunks = total_chunks.saturating_add(hh.chunk_count as u64);
    }
    if total_chunks.saturating_mul(8) > file_len {
        return Err(format!(
            "truncated or corrupt OpenEXR file: headers claim {total_chunks} chunks but the file has only {file_len} bytes"
        ));
    }

    let sample_type = h.channels.list[ch].sample_type;
    let bytes: Vec<usize> = h.channels.list.iter().map(|c| c.sample_type.bytes_per_sample()).collect();
    let layout = Layout {
        bytes_per_pixel: bytes.iter().sum(),
        channel_offset_per_pixel: bytes[..ch].iter().sum(),
        channel: ch,
        codec: match h.compression {
            Compression::PIZ => Codec::Piz(bytes.iter().map(|b| b / 2).collect()),
            Compression::ZIP1 | Compression::ZIP16 => Codec::Zip,
            _ => Codec::Crate,
        },
    };

    let plan = plan(headers, h, &layout, sample_type.bytes_per_sample() as u64, o)?;

    let chunks = r
        .filter_chunks(false, |_, tile, block| block.layer == part && tile.level_index == Vec2(0, 0))
        .map_err(exr_err)?;
    let data = match sample_type {
        SampleType::F16 => FrameData::F16(assemble::<f16, _>(chunks, &layout, &plan, rows, cols)?),
        SampleType::F32 => FrameData::F32(assemble::<f32, _>(chunks, &layout, &plan, rows, cols)?),
        SampleType::U32 => FrameData::U32(assemble::<u32, _>(chunks, &layout, &plan, rows, cols)?),
    };
    Ok(Frame { rows, cols, data })
}
