//! FLIR FFF frames: the header, the record directory, the raw-data record (the counts) and
//! the camera-info record (the calibration).
//!
//! An FFF frame is a 64-byte header, a directory of 32-byte entries, and records at the
//! offsets the entries give (from the start of the frame). The header and the directory are
//! in one byte order, told by the format version (100..199 when read the right way round);
//! each record tells its own by its first 16-bit word, 2. The raw-data record holds the
//! counts as raw 16-bit samples (in the record's byte order), as a PNG (whose 16-bit samples
//! FLIR writes in the record's byte order, not PNG's big-endian one), as a TIFF, or as
//! JPEG-LS (FLIR CSQ recordings; `jpegls/`). Radiometric JPEGs carry one such frame in APP1
//! segments (`rjpeg.rs`), SEQ files a run of them (`seq.rs`).
//!
//! The layout follows ExifTool's FLIR tables (`Image::ExifTool::FLIR`).

use std::io::Cursor;

use crate::radiometry::{Calibration, ZERO_CELSIUS};

use super::{check_budget, check_size, raster, select_channel, DecodeOptions, Frame, FrameData, Reason};

/// Bytes of the FFF header.
pub(super) const HEADER_LEN: usize = 64;
/// Bytes of one directory entry.
pub(super) const ENTRY_LEN: u64 = 32;
/// Most directory entries a frame may claim (real frames hold about a dozen).
pub(super) const MAX_ENTRIES: u64 = 4096;
/// Record types.
const RAW_DATA: u16 = 0x01;
const CAMERA_INFO: u16 = 0x20;
/// Bytes before the image in the raw-data record.
const RAW_HEADER_LEN: usize = 32;
/// The camera-info record up to the last calibration field (Planck R2 at 0x30c).
const CALIBRATION_LEN: usize = 0x310;

/// Whether `head` starts with an FFF (or AFF, an older SEQ) frame header.
pub(super) fn is_fff(head: &[u8]) -> bool {
    head.starts_with(b"FFF\0") || head.starts_with(b"AFF\0")
}

/// Numbers at byte offsets in one byte order; `None` past the end.
#[derive(Clone, Copy)]
struct Fields<'a> {
    bytes: &'a [u8],
    big: bool,
}

macro_rules! field_reader {
    ($name:ident, $t:ty) => {
        fn $name(&self, at: usize) -> Option<$t> {
            let raw = self.bytes.get(at..at.checked_add(size_of::<$t>())?)?.try_into().ok()?;
            Some(if self.big { <$t>::from_be_bytes(raw) } else { <$t>::from_le_bytes(raw) })
        }
    };
}

impl Fields<'_> {
    field_reader!(u16, u16);
    field_reader!(i16, i16);
    field_reader!(u32, u32);
    field_reader!(i32, i32);
    field_reader!(f32, f32);

    /// A NUL-terminated text field of `len` bytes; `None` when absent or empty.
    fn text(&self, at: usize, len: usize) -> Option<String> {
        let raw = self.bytes.get(at..at + len)?;
        let end = raw.iter().position(|&b| b == 0).unwrap_or(len);
        let text = String::from_utf8_lossy(&raw[..end]).trim().to_string();
        (!text.is_empty()).then_some(text)
    }
}

/// The frame header: byte order and where the record directory is.
#[derive(Debug, Clone, Copy)]
pub(super) struct Header {
    big: bool,
    directory: u64,
    entries: u64,
}

impl Header {
    pub(super) fn parse(head: &[u8]) -> Result<Header, Reason> {
        if head.len() < HEADER_LEN || !is_fff(head) {
            return Err("not a FLIR FFF frame (no FFF header)".to_string());
        }
        let version = |big| Fields { bytes: head, big }.u32(0x14).expect("header length checked");
        let big = match (version(true), version(false)) {
            (v, _) if (100..200).contains(&v) => true,
            (_, v) if (100..200).contains(&v) => false,
            (v, _) => return Err(format!("unsupported FLIR FFF version {v:#x} (expected 100..199)")),
        };
        let f = Fields { bytes: head, big };
        let header =
            Header { big, directory: f.u32(0x18).unwrap_or(0).into(), entries: f.u32(0x1c).unwrap_or(0).into() };
        if header.entries > MAX_ENTRIES {
            return Err(format!(
                "corrupt FLIR frame: the header claims {} records (at most {MAX_ENTRIES})",
                header.entries
            ));
        }
        Ok(header)
    }

    /// Byte range of the record directory within the frame.
    pub(super) fn directory_range(&self) -> (u64, u64) {
        (self.directory, self.directory + self.entries * ENTRY_LEN)
    }
}

/// One used directory entry: a record's type and byte range within the frame.
#[derive(Debug, Clone, Copy)]
pub(super) struct Entry {
    kind: u16,
    offset: u64,
    len: u64,
}

/// The used entries of a directory (type 0 marks a free entry).
pub(super) fn parse_directory(dir: &[u8], header: &Header) -> Vec<Entry> {
    dir.chunks_exact(ENTRY_LEN as usize)
        .map(|e| {
            let f = Fields { bytes: e, big: header.big };
            let word = |at| u64::from(f.u32(at).unwrap_or(0));
            Entry { kind: f.u16(0).unwrap_or(0), offset: word(0x0c), len: word(0x10) }
        })
        .filter(|e| e.kind != 0)
        .collect()
}

/// Bytes of the whole frame: up to the end of its last record or of its directory.
pub(super) fn frame_len(header: &Header, entries: &[Entry]) -> u64 {
    let start = (HEADER_LEN as u64).max(header.directory_range().1);
    entries.iter().map(|e| e.offset + e.len).fold(start, u64::max)
}

/// One FFF frame in memory.
pub(super) struct FffFrame<'a> {
    bytes: &'a [u8],
    entries: Vec<Entry>,
}

impl<'a> FffFrame<'a> {
    pub(super) fn parse(bytes: &'a [u8]) -> Result<FffFrame<'a>, Reason> {
        let header = Header::parse(bytes)?;
        let (start, end) = header.directory_range();
        let dir =
            usize::try_from(start).ok().zip(usize::try_from(end).ok()).and_then(|(s, e)| bytes.get(s..e)).ok_or_else(
                || {
                    format!(
                    "truncated or corrupt FLIR frame: its record directory (bytes {start}..{end}) lies past the end of \
                     the FLIR data ({} bytes)",
                    bytes.len()
                )
                },
            )?;
        Ok(FffFrame { bytes, entries: parse_directory(dir, &header) })
    }

    /// The first record of type `kind`.
    fn record(&self, kind: u16, what: &str) -> Result<&'a [u8], Reason> {
        let e = self
            .entries
            .iter()
            .find(|e| e.kind == kind)
            .ok_or_else(|| format!("the FLIR frame has no {what} record (record type {kind:#04x})"))?;
        usize::try_from(e.offset)
            .ok()
            .zip(usize::try_from(e.offset + e.len).ok())
            .and_then(|(s, end)| self.bytes.get(s..end))
            .ok_or_else(|| {
                format!(
                    "truncated FLIR data: the {what} record (bytes {}..{}) lies past its end ({} bytes)",
                    e.offset,
                    e.offset + e.len,
                    self.bytes.len()
                )
            })
    }

    /// The raw counts of the raw-data record.
    pub(super) fn counts(&self, o: &DecodeOptions) -> Result<Frame, Reason> {
        select_channel(&["Y".to_string()], o.channel.as_deref())?;
        let rec = self.record(RAW_DATA, "raw-data")?;
        let big = record_order(rec, "raw-data")?;
        if rec.len() < RAW_HEADER_LEN {
            return Err(format!(
                "truncated raw-data record ({} bytes; its header alone is {RAW_HEADER_LEN})",
                rec.len()
            ));
        }
        let f = Fields { bytes: rec, big };
        let (cols, rows) = (f.u16(2).unwrap_or(0) as usize, f.u16(4).unwrap_or(0) as usize);
        check_size(cols as u64, rows as u64, o.max_pixels)?;
        let image = &rec[RAW_HEADER_LEN..];
        let held = self.bytes.len() as u64;
        let frame = if image.starts_with(b"\x89PNG\r\n\x1a\n") {
            let frame = embedded(raster::decode_png(Cursor::new(image), &inner(o, held)?), "PNG")?;
            // FLIR writes the PNG's 16-bit samples in the record's byte order
            if big {
                frame
            } else {
                swap_bytes(frame)
            }
        } else if image.starts_with(b"II*\0") || image.starts_with(b"MM\0*") {
            embedded(raster::decode_tiff(Cursor::new(image), &inner(o, held)?, None), "TIFF")?
        } else if super::jpegls::is_jpeg(image) {
            jpegls(image, held, o)?
        } else {
            raw16(image, (cols, rows), big, held, o)?
        };
        if (frame.cols, frame.rows) != (cols, rows) {
            return Err(format!(
                "corrupt raw-data record: its header says {cols} x {rows} pixels, its image holds {} x {}",
                frame.cols, frame.rows
            ));
        }
        Ok(frame)
    }

    /// The camera-info record: the calibration and the camera.
    pub(super) fn camera_info(&self) -> Result<CameraInfo, Reason> {
        let rec = self.record(CAMERA_INFO, "camera-info")?;
        let big = record_order(rec, "camera-info")?;
        if rec.len() < CALIBRATION_LEN {
            return Err(format!(
                "truncated camera-info record ({} bytes; the calibration needs {CALIBRATION_LEN})",
                rec.len()
            ));
        }
        Ok(CameraInfo::parse(Fields { bytes: rec, big }))
    }
}

/// A record's byte order from its first word (2 when read the right way round).
fn record_order(rec: &[u8], what: &str) -> Result<bool, Reason> {
    match rec.get(..2) {
        Some([2, 0]) => Ok(false),
        Some([0, 2]) => Ok(true),
        Some(&[a, b]) => Err(format!(
            "corrupt {what} record: its byte-order mark is {:#06x}, expected 2 (a zeroed or damaged record)",
            u16::from_le_bytes([a, b])
        )),
        _ => Err(format!("truncated {what} record ({} bytes)", rec.len())),
    }
}

/// Options for an image embedded in the FLIR data, which is held in memory alongside it.
fn inner(o: &DecodeOptions, held: u64) -> Result<DecodeOptions, Reason> {
    check_budget(Some(held), || format!("the {held} bytes of FLIR data"), o.max_bytes)?;
    Ok(DecodeOptions { channel: None, page: 0, max_pixels: o.max_pixels, max_bytes: o.max_bytes - held })
}

/// JPEG-LS coded counts (FLIR CSQ), decoded within the budget left beside the FLIR data.
fn jpegls(image: &[u8], held: u64, o: &DecodeOptions) -> Result<Frame, Reason> {
    let budget = inner(o, held)?;
    let decoded = super::jpegls::decode(image, budget.max_pixels, budget.max_bytes)
        .map_err(|reason| format!("the raw-data record's JPEG-LS image: {reason}"))?;
    Ok(Frame { rows: decoded.rows, cols: decoded.cols, data: FrameData::U16(decoded.samples) })
}

/// An embedded PNG or TIFF must be one 16-bit grey channel.
fn embedded(decoded: Result<Frame, Reason>, kind: &str) -> Result<Frame, Reason> {
    let frame = decoded.map_err(|reason| format!("the raw-data record's {kind} image: {reason}"))?;
    match frame.data {
        FrameData::U16(_) => Ok(frame),
        ref other => Err(format!(
            "the raw-data record's {kind} image holds {} samples, expected 16-bit counts",
            other.dtype_name()
        )),
    }
}

fn swap_bytes(mut frame: Frame) -> Frame {
    if let FrameData::U16(v) = &mut frame.data {
        v.iter_mut().for_each(|x| *x = x.swap_bytes());
    }
    frame
}

/// Raw 16-bit samples in the record's byte order.
fn raw16(image: &[u8], (cols, rows): (usize, usize), big: bool, held: u64, o: &DecodeOptions) -> Result<Frame, Reason> {
    let need = cols * rows * 2; // at most 65535² x 2: no overflow on 64-bit targets
    if image.len() < need {
        return Err(format!(
            "truncated or corrupt raw-data record: it holds {} bytes of samples, but its header claims {cols} x {rows} \
             pixels ({need} bytes)",
            image.len()
        ));
    }
    let what = || format!("a {cols} x {rows} FLIR frame and its {held} bytes of FLIR data");
    check_budget(held.checked_add(need as u64), what, o.max_bytes)?;
    let read = if big { u16::from_be_bytes } else { u16::from_le_bytes };
    let counts = super::frame_collect(need / 2, image[..need].chunks_exact(2).map(|b| read([b[0], b[1]])))?;
    Ok(Frame { rows, cols, data: FrameData::U16(counts) })
}

/// The camera-info record: the calibration (Planck constants, object parameters, atmosphere;
/// temperatures in °C, relative humidity in percent, distance in metres, as stored: the
/// conversion validates what it uses) and the camera.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraInfo {
    pub calibration: Calibration,
    pub camera_model: Option<String>,
    pub camera_serial: Option<String>,
    pub lens_model: Option<String>,
    /// When the frame was taken: seconds since 1970 (UTC), milliseconds, and the local time's
    /// offset east of UTC in minutes. `None` when absent (or zero).
    pub date: Option<(u32, u32, i32)>,
    /// Frames per second; `None` when absent or zero.
    pub frame_rate: Option<u32>,
}

impl CameraInfo {
    /// Parse a record at least `CALIBRATION_LEN` long (checked by the caller).
    fn parse(f: Fields<'_>) -> CameraInfo {
        let float = |at| f64::from(f.f32(at).expect("within the calibration's length"));
        let celsius = |at| float(at) - ZERO_CELSIUS;
        let humidity = float(0x3c);
        let calibration = Calibration {
            planck_r1: float(0x58),
            planck_r2: float(0x30c),
            planck_b: float(0x5c),
            planck_f: float(0x60),
            planck_o: f64::from(f.i32(0x308).expect("within the calibration's length")),
            emissivity: float(0x20),
            object_distance: float(0x24),
            reflected_temperature: celsius(0x28),
            atmospheric_temperature: celsius(0x2c),
            window_temperature: celsius(0x30),
            window_transmission: float(0x34),
            // stored as a fraction; some cameras store percent (a value above 2, as ExifTool reads it)
            relative_humidity: if humidity > 2.0 { humidity } else { humidity * 100.0 },
            alpha1: float(0x70),
            alpha2: float(0x74),
            beta1: float(0x78),
            beta2: float(0x7c),
            x: float(0x80),
        };
        CameraInfo {
            calibration,
            camera_model: f.text(0xd4, 32),
            camera_serial: f.text(0x104, 16),
            lens_model: f.text(0x170, 32),
            date: date(f),
            frame_rate: f.u16(0x464).filter(|&r| r > 0).map(u32::from),
        }
    }
}

/// The date field: seconds (UTC), a word whose low 16 bits are milliseconds, and the zone as
/// minutes west of UTC.
fn date(f: Fields<'_>) -> Option<(u32, u32, i32)> {
    let seconds = f.u32(0x384).filter(|&s| s > 0)?;
    let millis = f.u32(0x388)? & 0xffff;
    let west = f.i16(0x38c)?;
    Some((seconds, millis.min(999), -i32::from(west)))
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    /// A little frame: header, a directory of the given entries, the records after it.
    pub(crate) fn frame(big: bool, records: &[(u16, Vec<u8>)]) -> Vec<u8> {
        let put32 = |v: u32| if big { v.to_be_bytes() } else { v.to_le_bytes() };
        let mut out = b"FFF\0".to_vec();
        out.resize(HEADER_LEN, 0);
        out[0x14..0x18].copy_from_slice(&put32(100));
        out[0x18..0x1c].copy_from_slice(&put32(HEADER_LEN as u32));
        out[0x1c..0x20].copy_from_slice(&put32(records.len() as u32));
        let mut offset = HEADER_LEN + records.len() * ENTRY_LEN as usize;
        for (kind, body) in records {
            let mut e = vec![0u8; ENTRY_LEN as usize];
            e[..2].copy_from_slice(&if big { kind.to_be_bytes() } else { kind.to_le_bytes() });
            e[0x0c..0x10].copy_from_slice(&put32(offset as u32));
            e[0x10..0x14].copy_from_slice(&put32(body.len() as u32));
            out.extend(e);
            offset += body.len();
        }
        records.iter().for_each(|(_, body)| out.extend(body));
        out
    }

    fn raw_record(cols: u16, rows: u16, samples: &[u16]) -> Vec<u8> {
        let mut r = vec![0u8; RAW_HEADER_LEN];
        r[..2].copy_from_slice(&2u16.to_le_bytes());
        r[2..4].copy_from_slice(&cols.to_le_bytes());
        r[4..6].copy_from_slice(&rows.to_le_bytes());
        samples.iter().for_each(|s| r.extend(s.to_le_bytes()));
        r
    }

    #[test]
    fn raw_counts_in_both_directory_orders() {
        for big in [false, true] {
            let bytes = frame(big, &[(RAW_DATA, raw_record(3, 2, &[1, 2, 3, 400, 500, 65535]))]);
            let f = FffFrame::parse(&bytes).unwrap().counts(&DecodeOptions::default()).unwrap();
            assert_eq!((f.rows, f.cols), (2, 3));
            assert_eq!(f.data, FrameData::U16(vec![1, 2, 3, 400, 500, 65535]));
        }
    }

    #[test]
    fn lying_sizes_are_refused_before_allocating() {
        let bytes = frame(false, &[(RAW_DATA, raw_record(8000, 8000, &[1, 2]))]);
        let m = FffFrame::parse(&bytes).unwrap().counts(&DecodeOptions::default()).unwrap_err();
        assert!(m.contains("claims 8000 x 8000") && m.contains("truncated or corrupt raw-data record"), "{m}");
        let bytes = frame(false, &[(RAW_DATA, raw_record(65535, 65535, &[1, 2]))]);
        let m = FffFrame::parse(&bytes).unwrap().counts(&DecodeOptions::default()).unwrap_err();
        assert!(m.contains("max_pixels"), "{m}");
        let mut zeroed = raw_record(2, 1, &[1, 2]);
        zeroed[..2].fill(0);
        let bytes = frame(false, &[(RAW_DATA, zeroed)]);
        let m = FffFrame::parse(&bytes).unwrap().counts(&DecodeOptions::default()).unwrap_err();
        assert!(m.contains("byte-order mark"), "{m}");
        let mut cut = frame(false, &[(RAW_DATA, raw_record(2, 1, &[1, 2]))]);
        cut.truncate(cut.len() - 1);
        let m = FffFrame::parse(&cut).unwrap().counts(&DecodeOptions::default()).unwrap_err();
        assert!(m.contains("lies past its end"), "{m}");
    }

    #[test]
    fn missing_records_are_named() {
        let bytes = frame(true, &[]);
        let fff = FffFrame::parse(&bytes).unwrap();
        assert!(fff.camera_info().unwrap_err().contains("no camera-info record"));
        assert!(fff.counts(&DecodeOptions::default()).unwrap_err().contains("no raw-data record"));
        let short = frame(false, &[(CAMERA_INFO, vec![2, 0, 0, 0])]);
        let m = FffFrame::parse(&short).unwrap().camera_info().unwrap_err();
        assert!(m.contains("truncated camera-info record"), "{m}");
    }
}
