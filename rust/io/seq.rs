//! FLIR FFF and SEQ files: one FFF frame (`.fff`), or FFF frames one after another (`.seq`).
//! Frame `k` is page `k`.
//!
//! Each frame's length follows from its header and record directory (`flir::frame_len`), so
//! the frames are found by one pass over headers and directories only; the next frame must
//! start where the previous one ends. Where that fails (a recording cut short, a damaged
//! header) the frames before stay readable and the break is reported, as for a TIFF's
//! broken IFD chain ([`page_chain`]). That index is kept per file (process-wide, a few files),
//! so reading a sequence page by page costs one pass, not one per page. A frame is then read
//! whole into memory (checked against the decoding budget) and decoded by `flir.rs`.

use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::Path;
use std::sync::{Arc, Mutex};

use super::flir::{self, CameraInfo, FffFrame, Header};
use super::tiff_pages::FileKey;
use super::{check_budget, DecodeOptions, Frame, Reason};

/// Where one frame lies in the file.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Span {
    start: u64,
    len: u64,
}

fn read_err(e: std::io::Error, k: usize) -> Reason {
    if e.kind() == std::io::ErrorKind::UnexpectedEof {
        format!("truncated FLIR file (frame {k} ends early)")
    } else {
        format!("read error: {e}")
    }
}

/// The length of frame `k`, which starts at `start`, from its header and directory.
fn frame_span<R: Read + Seek>(reader: &mut R, start: u64, file_len: u64, k: usize) -> Result<Span, Reason> {
    let at = |reason: Reason| format!("frame {k} (at byte {start}): {reason}");
    let mut head = [0u8; flir::HEADER_LEN];
    reader.seek(SeekFrom::Start(start)).map_err(|e| read_err(e, k))?;
    let got = reader.by_ref().take(head.len() as u64).read(&mut head).map_err(|e| read_err(e, k))?;
    let header = Header::parse(&head[..got]).map_err(at)?;
    let (dir_start, dir_end) = header.directory_range();
    if start + dir_end > file_len {
        return Err(at(format!("its record directory ends at byte {}, past the end of the file", start + dir_end)));
    }
    let mut dir = vec![0u8; (dir_end - dir_start.min(dir_end)) as usize];
    reader.seek(SeekFrom::Start(start + dir_start)).map_err(|e| read_err(e, k))?;
    reader.read_exact(&mut dir).map_err(|e| read_err(e, k))?;
    let len = flir::frame_len(&header, &flir::parse_directory(&dir, &header));
    if start + len > file_len {
        return Err(at(format!(
            "truncated FLIR file: the frame's records end at byte {}, past the end of the file ({file_len} bytes)",
            start + len
        )));
    }
    Ok(Span { start, len })
}

/// The frames found in a file, and why the walk stopped before the end of the file when it
/// did (a recording cut short, a damaged header): the frames before stay readable.
#[derive(Debug, Clone, PartialEq)]
struct Index {
    spans: Vec<Span>,
    broken: Option<Reason>,
}

impl Index {
    /// Frame `page`'s span, or why there is none.
    fn span(&self, page: usize) -> Result<Span, Reason> {
        match (self.spans.get(page), &self.broken) {
            (Some(span), _) => Ok(*span),
            (None, Some(why)) => Err(why.clone()),
            (None, None) => Err(out_of_range(page, self.spans.len())),
        }
    }
}

/// The frames of the file, up to frame `last` (all of them when `None`). An error when not
/// even frame 0 is found.
fn index<R: Read + Seek>(reader: &mut R, last: Option<usize>) -> Result<Index, Reason> {
    let file_len = reader.seek(SeekFrom::End(0)).map_err(|e| read_err(e, 0))?;
    let mut spans: Vec<Span> = Vec::new();
    let mut start = 0;
    while start < file_len && last.is_none_or(|l| spans.len() <= l) {
        match frame_span(reader, start, file_len, spans.len()) {
            Ok(span) => {
                start += span.len;
                spans.push(span);
            }
            Err(why) if spans.is_empty() => return Err(why),
            Err(why) => return Ok(Index { spans, broken: Some(why) }),
        }
    }
    Ok(Index { spans, broken: None })
}

/// Frame `span` read into memory, within the budget.
fn read_frame<R: Read + Seek>(reader: &mut R, span: Span, k: usize, max_bytes: u64) -> Result<Vec<u8>, Reason> {
    check_budget(Some(span.len), || format!("frame {k}'s {} bytes of FLIR data", span.len), max_bytes)?;
    let mut bytes = vec![0u8; span.len as usize];
    reader.seek(SeekFrom::Start(span.start)).map_err(|e| read_err(e, k))?;
    reader.read_exact(&mut bytes).map_err(|e| read_err(e, k))?;
    Ok(bytes)
}

fn out_of_range(page: usize, frames: usize) -> Reason {
    format!("page {page} out of range ({frames} frame{})", if frames == 1 { "" } else { "s" })
}

/// Frame `page` of the file as FFF bytes, walking the headers from the start.
fn frame_bytes<R: Read + Seek>(mut reader: R, o: &DecodeOptions) -> Result<Vec<u8>, Reason> {
    let span = index(&mut reader, Some(o.page))?.span(o.page)?;
    read_frame(&mut reader, span, o.page, o.max_bytes)
}

/// The counts of frame `o.page`, and its calibration when its camera-info record reads.
pub(super) fn decode<R: Read + Seek>(reader: R, o: &DecodeOptions) -> Result<(Frame, Option<CameraInfo>), Reason> {
    let bytes = frame_bytes(reader, o)?;
    counts_and_calibration(&bytes, o)
}

/// The counts of an FFF frame, and its calibration when its camera-info record reads (an
/// error in it is reported when the calibration is asked for).
fn counts_and_calibration(bytes: &[u8], o: &DecodeOptions) -> Result<(Frame, Option<CameraInfo>), Reason> {
    let frame = FffFrame::parse(bytes)?;
    let counts = frame.counts(o).map_err(|reason| in_frame(o.page, reason))?;
    Ok((counts, frame.camera_info().ok()))
}

/// The calibration of frame `o.page`.
pub(super) fn camera_info<R: Read + Seek>(reader: R, o: &DecodeOptions) -> Result<CameraInfo, Reason> {
    let bytes = frame_bytes(reader, o)?;
    FffFrame::parse(&bytes)?.camera_info().map_err(|reason| in_frame(o.page, reason))
}

fn in_frame(page: usize, reason: Reason) -> Reason {
    if page == 0 {
        reason
    } else {
        format!("frame {page}: {reason}")
    }
}

/// The number of whole frames before any break, and why the frames break when they do.
pub(super) fn page_chain<R: Read + Seek>(mut reader: R) -> Result<(usize, Option<Reason>), Reason> {
    let index = index(&mut reader, None)?;
    Ok((index.spans.len(), index.broken))
}

/// Indexes of recently read files, shared by all threads.
static INDEXES: Mutex<Vec<(FileKey, Arc<Index>)>> = Mutex::new(Vec::new());
const INDEXES_KEPT: usize = 8;

/// The frame index of the file at `path`, from the cache or by one pass.
fn cached_index(path: &Path, file: &mut BufReader<File>) -> Result<Arc<Index>, Reason> {
    let meta = file.get_ref().metadata().map_err(|e| format!("cannot stat: {e}"))?;
    let key = FileKey::of(path, &meta);
    let lock = || INDEXES.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
    if let Some((_, index)) = lock().iter().find(|(k, _)| *k == key) {
        return Ok(index.clone());
    }
    let index = Arc::new(index(file, None)?);
    let mut kept = lock();
    kept.retain(|(k, _)| *k != key);
    kept.insert(0, (key, index.clone()));
    kept.truncate(INDEXES_KEPT);
    Ok(index)
}

/// Decode frame `o.page` of the FLIR file at `path`, with the file's cached frame index.
pub(super) fn decode_cached(path: &Path, o: &DecodeOptions) -> Result<(Frame, Option<CameraInfo>), Reason> {
    let mut file = BufReader::with_capacity(1 << 16, super::open_regular(path)?);
    let span = cached_index(path, &mut file)?.span(o.page)?;
    let bytes = read_frame(&mut file, span, o.page, o.max_bytes)?;
    counts_and_calibration(&bytes, o)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Cursor;

    fn raw(cols: u16, rows: u16, fill: u16) -> Vec<u8> {
        let mut r = vec![0u8; 32];
        r[..2].copy_from_slice(&2u16.to_le_bytes());
        r[2..4].copy_from_slice(&cols.to_le_bytes());
        r[4..6].copy_from_slice(&rows.to_le_bytes());
        (0..cols as usize * rows as usize).for_each(|_| r.extend(fill.to_le_bytes()));
        r
    }

    #[test]
    fn frames_follow_one_another() {
        let one = flir::tests::frame(true, &[(1, raw(2, 2, 7))]);
        let two = flir::tests::frame(false, &[(1, raw(3, 1, 9))]);
        let seq = [one.clone(), two.clone(), one.clone()].concat();
        assert_eq!(page_chain(Cursor::new(&seq)).unwrap(), (3, None));
        let page = |k| decode(Cursor::new(&seq), &DecodeOptions { page: k, ..Default::default() });
        assert_eq!(page(1).unwrap().0.data, super::super::FrameData::U16(vec![9; 3]));
        assert_eq!(page(2).unwrap(), page(0).unwrap());
        assert!(page(3).unwrap_err().contains("page 3 out of range (3 frames)"));
        let mut cut = seq.clone();
        cut.truncate(seq.len() - 1);
        let (whole, why) = page_chain(Cursor::new(&cut)).unwrap();
        assert_eq!(whole, 2, "the frames before the cut stay readable");
        assert!(why.unwrap().contains("truncated FLIR file"));
        let cut_page = |k| decode(Cursor::new(&cut), &DecodeOptions { page: k, ..Default::default() });
        assert_eq!(cut_page(1).unwrap(), page(1).unwrap());
        assert!(cut_page(2).unwrap_err().contains("frame 2 (at byte"));
        assert!(page_chain(Cursor::new(&cut[..10])).is_err(), "not even frame 0: an error");
        let mut junk = seq.clone();
        junk.extend(b"trailing bytes that are no frame, long enough for a header: ..........................");
        let m = page_chain(Cursor::new(&junk)).unwrap().1.unwrap();
        assert!(m.contains("frame 3 (at byte") && m.contains("no FFF header"), "{m}");
    }
}
