//! Radiometric JPEGs (FLIR, and DJI Zenmuse XT2/XT-R, which write the same format): the
//! visible JPEG image carries one FLIR FFF frame split over APP1 segments, each starting with
//! `"FLIR\0"`, a version byte, the segment's index and the last index. The segments are read
//! from the markers before the image data (only their lengths are read for the others) and
//! joined in index order into the FFF frame, which `flir.rs` reads. A JPEG without them, or
//! whose FLIR segments hold no FFF frame, is checked for the thermal formats irfidelity does
//! not read (`unread.rs`), so that its refusal names the format.

use std::io::{BufRead, Seek, SeekFrom};

use super::flir::{CameraInfo, FffFrame};
use super::unread::{has_hikmicro_block, is_research_studio, segment_head_len, JpegSigns, Unread};
use super::{check_budget, DecodeOptions, Frame, Reason};

/// Bytes before a segment's share of the FFF frame: "FLIR\0", version, index, last index.
const SEGMENT_HEADER: usize = 8;
const APP1: u8 = 0xE1;
/// Start of scan (image data follows) and end of image: no FLIR segment after these.
const SOS: u8 = 0xDA;
const EOI: u8 = 0xD9;

/// One FLIR APP1 segment's share of the FFF frame.
struct Segment {
    index: u8,
    last: u8,
    data: Vec<u8>,
}

fn read_err(e: std::io::Error, at: u64) -> Reason {
    if e.kind() == std::io::ErrorKind::UnexpectedEof {
        format!("truncated JPEG file (ends inside the segment at byte {at})")
    } else {
        format!("read error: {e}")
    }
}

/// The next marker (after any fill bytes), or `None` at the end of the file.
fn next_marker<R: BufRead + Seek>(reader: &mut R, at: u64) -> Result<Option<u8>, Reason> {
    let mut byte = [0u8; 1];
    if reader.read(&mut byte).map_err(|e| read_err(e, at))? == 0 {
        return Ok(None);
    }
    if byte[0] != 0xFF {
        return Err(format!("corrupt JPEG file: expected a marker at byte {at}, found {:#04x}", byte[0]));
    }
    loop {
        reader.read_exact(&mut byte).map_err(|e| read_err(e, at))?;
        if byte[0] != 0xFF {
            return Ok(Some(byte[0]));
        }
    }
}

/// A marker segment with a length, as [`walk_segments`] meets it.
#[derive(Clone, Copy)]
struct Header {
    marker: u8,
    /// bytes of its body (after the length)
    body: u64,
    /// where the segment starts, for errors
    at: u64,
}

/// Walk a JPEG's marker segments up to its image data (start of scan) or its end, calling
/// `visit` at the start of each segment's body: `visit` reads what it wants of the body (at
/// most all of it) and returns how many bytes it read; the rest is skipped.
fn walk_segments<R: BufRead + Seek>(
    reader: &mut R,
    mut visit: impl FnMut(Header, &mut R) -> Result<u64, Reason>,
) -> Result<(), Reason> {
    let mut soi = [0u8; 2];
    reader.read_exact(&mut soi).map_err(|e| read_err(e, 0))?;
    if soi != [0xFF, 0xD8] {
        return Err("not a JPEG file".to_string());
    }
    let mut at = 2u64;
    while let Some(marker) = next_marker(reader, at)? {
        if marker == SOS || marker == EOI {
            break;
        }
        if (0xD0..=0xD8).contains(&marker) || marker == 0x01 {
            at = reader.stream_position().map_err(|e| read_err(e, at))?;
            continue; // markers without a length
        }
        let mut len = [0u8; 2];
        reader.read_exact(&mut len).map_err(|e| read_err(e, at))?;
        let body = u64::from(u16::from_be_bytes(len))
            .checked_sub(2)
            .ok_or_else(|| format!("corrupt JPEG file: the segment at byte {at} has a length below 2"))?;
        let read = visit(Header { marker, body, at }, reader)?;
        reader.seek(SeekFrom::Current((body - read) as i64)).map_err(|e| read_err(e, at))?;
        at = reader.stream_position().map_err(|e| read_err(e, at))?;
    }
    Ok(())
}

/// The FLIR segments of a JPEG, in file order; their data at most `max_bytes` in all. With
/// `lead`, only the first `lead` bytes of each segment's data are read (the rest skipped).
fn flir_segments<R: BufRead + Seek>(
    reader: &mut R,
    max_bytes: u64,
    lead: Option<usize>,
) -> Result<Vec<Segment>, Reason> {
    let (mut segments, mut held) = (Vec::new(), 0u64);
    // a skipped segment is not read: the file's length tells whether it is whole
    let file_len = match lead {
        Some(_) => {
            let start = reader.stream_position().map_err(|e| read_err(e, 0))?;
            let len = reader.seek(SeekFrom::End(0)).map_err(|e| read_err(e, 0))?;
            reader.seek(SeekFrom::Start(start)).map_err(|e| read_err(e, 0))?;
            Some(len)
        }
        None => None,
    };
    walk_segments(reader, |Header { marker, body, at }, reader| {
        if marker != APP1 || body < SEGMENT_HEADER as u64 {
            return Ok(0);
        }
        let mut head = [0u8; SEGMENT_HEADER];
        reader.read_exact(&mut head).map_err(|e| read_err(e, at))?;
        if !head.starts_with(b"FLIR\0") {
            return Ok(SEGMENT_HEADER as u64);
        }
        held += body;
        check_budget(Some(held), || format!("the FLIR segments ({held} bytes so far)"), max_bytes)?;
        let kept = lead.map_or(body as usize - SEGMENT_HEADER, |lead| lead.min(body as usize - SEGMENT_HEADER));
        let mut data = vec![0u8; kept];
        reader.read_exact(&mut data).map_err(|e| read_err(e, at))?;
        if let Some(len) = file_len {
            let end = reader.stream_position().map_err(|e| read_err(e, at))? + (body - (SEGMENT_HEADER + kept) as u64);
            if end > len {
                return Err(read_err(std::io::ErrorKind::UnexpectedEof.into(), at));
            }
        }
        segments.push(Segment { index: head[6], last: head[7], data });
        Ok((SEGMENT_HEADER + kept) as u64)
    })?;
    Ok(segments)
}

/// Why a JPEG without FLIR segments is refused: the thermal format its other segments (or the
/// data after its image) name, else that it is no radiometric JPEG.
fn not_flir<R: BufRead + Seek>(reader: &mut R) -> Reason {
    let mut signs = JpegSigns::default();
    let walked = reader.rewind().is_ok()
        && walk_segments(reader, |Header { marker, body, at }, reader| {
            let want = body.min(segment_head_len(marker) as u64);
            let mut head = vec![0u8; want as usize];
            reader.read_exact(&mut head).map_err(|e| read_err(e, at))?;
            signs.note(marker, &head);
            Ok(want)
        })
        .is_ok();
    let format = signs.format().or_else(|| (walked && has_hikmicro_block(reader)).then_some(Unread::HikmicroJpeg));
    match format {
        Some(format) => format.reason(),
        None => "a JPEG without FLIR segments: not a radiometric JPEG of the FLIR kind (FLIR, DJI Zenmuse \
                 XT2/XT-R), and irfidelity reads no other JPEG (its 8-bit colours are not camera counts)"
            .to_string(),
    }
}

/// The FFF frame the JPEG's FLIR segments hold, joined in index order.
pub(super) fn fff_frame<R: BufRead + Seek>(mut reader: R, max_bytes: u64) -> Result<Vec<u8>, Reason> {
    let segments = in_order(flir_segments(&mut reader, max_bytes, None)?, &mut reader)?;
    let mut data = Vec::with_capacity(segments.iter().map(|s| s.data.len()).sum());
    segments.iter().for_each(|s| data.extend_from_slice(&s.data)); // one copy a segment, not a byte at a time
    if is_research_studio(&data) {
        return Err(Unread::ResearchStudioJpeg.reason());
    }
    Ok(data)
}

/// Whether [`fff_frame`] reads the JPEG (its one page), from the FLIR segments' headers and the
/// first one's leading bytes: the segments' data is joined only when it is no FFF frame, to tell
/// why.
pub(super) fn has_fff_frame<R: BufRead + Seek>(mut reader: R, max_bytes: u64) -> Result<(), Reason> {
    let segments = in_order(flir_segments(&mut reader, max_bytes, Some(4))?, &mut reader)?;
    if segments.first().is_some_and(|s| super::flir::is_fff(&s.data)) {
        return Ok(());
    }
    reader.rewind().map_err(|e| read_err(e, 0))?;
    fff_frame(reader, max_bytes).map(|_| ())
}

/// The FLIR segments in index order, each of `0..=last` once (the reason otherwise; `reader`
/// tells why a JPEG without any is refused).
fn in_order<R: BufRead + Seek>(mut segments: Vec<Segment>, reader: &mut R) -> Result<Vec<Segment>, Reason> {
    let Some(first) = segments.first() else {
        return Err(not_flir(reader));
    };
    let last = first.last;
    if let Some(s) = segments.iter().find(|s| s.last != last) {
        return Err(format!(
            "corrupt radiometric JPEG: FLIR segments disagree on their count ({} and {})",
            last as usize + 1,
            s.last as usize + 1
        ));
    }
    segments.sort_by_key(|s| s.index);
    let found: Vec<u8> = segments.iter().map(|s| s.index).collect();
    if !found.iter().copied().eq(0..=last) {
        return Err(format!(
            "corrupt or truncated radiometric JPEG: FLIR segments 0..={last} are each expected once, found {found:?}"
        ));
    }
    Ok(segments)
}

/// The raw counts of a radiometric JPEG, and its calibration when its camera-info record
/// reads (an error in it is reported when the calibration is asked for).
pub(super) fn decode<R: BufRead + Seek>(reader: R, o: &DecodeOptions) -> Result<(Frame, Option<CameraInfo>), Reason> {
    let fff = fff_frame(reader, o.max_bytes)?;
    let frame = FffFrame::parse(&fff)?;
    Ok((frame.counts(o)?, frame.camera_info().ok()))
}

/// The calibration of a radiometric JPEG.
pub(super) fn camera_info<R: BufRead + Seek>(reader: R, o: &DecodeOptions) -> Result<CameraInfo, Reason> {
    let fff = fff_frame(reader, o.max_bytes)?;
    FffFrame::parse(&fff)?.camera_info()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Cursor;

    fn segment(index: u8, last: u8, data: &[u8]) -> Vec<u8> {
        let mut s = vec![0xFF, APP1];
        s.extend(((data.len() + SEGMENT_HEADER + 2) as u16).to_be_bytes());
        s.extend(b"FLIR\0\x01");
        s.extend([index, last]);
        s.extend(data);
        s
    }

    fn jpeg(parts: &[Vec<u8>]) -> Vec<u8> {
        let mut out = vec![0xFF, 0xD8, 0xFF, 0xE0, 0, 4, b'J', b'F'];
        parts.iter().for_each(|p| out.extend(p));
        out.extend([0xFF, SOS, 0, 2, 0xAB, 0xFF, EOI]);
        out
    }

    #[test]
    fn segments_are_joined_in_index_order() {
        let file = jpeg(&[segment(1, 2, b"cd"), segment(0, 2, b"ab"), segment(2, 2, b"e")]);
        assert_eq!(fff_frame(Cursor::new(file), 1 << 20).unwrap(), b"abcde");
    }

    #[test]
    fn missing_repeated_or_absent_segments_are_refused() {
        let gap = jpeg(&[segment(0, 2, b"ab"), segment(2, 2, b"e")]);
        assert!(fff_frame(Cursor::new(gap), 1 << 20).unwrap_err().contains("found [0, 2]"));
        let twice = jpeg(&[segment(0, 1, b"ab"), segment(1, 1, b"e"), segment(1, 1, b"e")]);
        assert!(fff_frame(Cursor::new(twice), 1 << 20).unwrap_err().contains("found [0, 1, 1]"));
        let none = jpeg(&[]);
        assert!(fff_frame(Cursor::new(none), 1 << 20).unwrap_err().contains("without FLIR segments"));
        let big = jpeg(&[segment(0, 0, &[7; 1000])]);
        assert!(fff_frame(Cursor::new(big), 100).unwrap_err().contains("max_bytes"));
        let mut cut = jpeg(&[segment(0, 0, &[7; 1000])]);
        cut.truncate(500);
        assert!(fff_frame(Cursor::new(cut), 1 << 20).unwrap_err().contains("truncated JPEG"));
    }

    /// A segment of any marker holding `body`.
    fn app(marker: u8, body: &[u8]) -> Vec<u8> {
        let mut s = vec![0xFF, marker];
        s.extend(((body.len() + 2) as u16).to_be_bytes());
        s.extend(body);
        s
    }

    fn refusal(file: Vec<u8>) -> String {
        fff_frame(Cursor::new(file), 1 << 20).unwrap_err()
    }

    #[test]
    fn jpegs_of_unread_thermal_formats_are_named() {
        let exif = app(APP1, &crate::io::unread::tests::exif_with_make("DJI", false));
        let mut params = vec![0u8; 128];
        params[..4].copy_from_slice(&[0xaa, 0x55, 0x12, 0x06]);
        let dji = jpeg(&[exif.clone(), app(0xE3, &[0x12; 300]), app(0xE4, &params)]);
        assert!(refusal(dji).starts_with("a DJI R-JPEG of the H20T"));
        let dji_without_params = jpeg(&[exif, app(0xE3, &[0x12; 300])]);
        assert!(refusal(dji_without_params).contains("without FLIR segments"));

        let infiray = jpeg(&[app(0xE2, b"\x01\x00\x00\x00IJPEG\0\0\0\0\0")]);
        assert!(refusal(infiray).starts_with("an InfiRay radiometric JPEG"));

        let mut hikmicro = jpeg(&[]);
        hikmicro.extend(b"\xFF\xD8\xFF\xE0\x00\x02\xFF\xD9HDRI");
        hikmicro.extend([0u8; 64]);
        assert!(refusal(hikmicro).starts_with("a HIKMICRO radiometric JPEG"));
        let mut hdri_not_after_eoi = jpeg(&[]);
        hdri_not_after_eoi.extend(b"\0HDRI");
        assert!(refusal(hdri_not_after_eoi).contains("without FLIR segments"));
    }

    #[test]
    fn the_page_check_answers_as_the_whole_read() {
        let fff = jpeg(&[segment(1, 2, &[5; 300]), segment(0, 2, b"FFF\0abcdefgh"), segment(2, 2, &[6; 200])]);
        let mut files = vec![
            fff.clone(),
            jpeg(&[segment(0, 1, b"FF"), segment(1, 1, b"F\0xyz")]), // FFF only once joined: read whole
            jpeg(&[segment(0, 2, b"FFF\0ab"), segment(2, 2, b"e")]),
            jpeg(&[]),
            jpeg(&[segment(0, 1, b"\0\0\0\x10FLIR ATS"), segment(1, 1, b"-US File\0\0FOV")]),
        ];
        // cut anywhere: inside a FLIR segment both are refused as truncated, after them both read
        files.extend((3..fff.len()).step_by(7).map(|cut| fff[..cut].to_vec()));
        for file in files {
            let whole = fff_frame(Cursor::new(file.clone()), 1 << 20).map(|_| ());
            assert_eq!(has_fff_frame(Cursor::new(file.clone()), 1 << 20), whole, "{} bytes", file.len());
        }
        assert!(has_fff_frame(Cursor::new(fff.clone()), 100).unwrap_err().contains("max_bytes"));
    }

    #[test]
    fn flir_segments_holding_a_research_studio_file_are_named() {
        let ats = jpeg(&[segment(0, 1, b"\0\0\0\x10FLIR ATS"), segment(1, 1, b"-US File\0\0FOV")]);
        assert!(refusal(ats).starts_with("a FLIR Research Studio radiometric JPEG"));
    }
}
