//! The pages of a TIFF: where each page's IFD lies, found in one pass over the IFD chain and
//! kept per file, and a view of the file that shows the `tiff` crate a single page.
//!
//! The `tiff` crate reaches page k by walking the k IFDs before it, so reading a sequence page
//! by page would cost O(n²) directory reads. Here the chain is walked once per file
//! ([`scan`], which also finds where a broken chain breaks) and the offsets are kept in a
//! small process-wide cache keyed by the file's identity ([`FileKey`]), shared by every
//! thread. Page k is then decoded through [`OnePage`]: the file as if the header's first-IFD
//! offset were page k's and that IFD's next-IFD offset were 0, so the crate reads one
//! directory, whatever k.
//!
//! A chain that stops early keeps the pages found before the break, and [`Chain::broken`]
//! says why it stops at page k, the first page not found: the file is truncated (page k's
//! IFD lies beyond its end), the chain loops back (page k-1's next-IFD offset points to an
//! IFD already visited), an offset points into the header, or there are more than
//! [`MAX_PAGES`] pages. Decoding page k or later is an error with that reason.

use std::collections::HashSet;
use std::fs::Metadata;
use std::io::{self, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use super::Reason;

/// The most pages read from one TIFF; a longer chain is broken at this page.
pub(super) const MAX_PAGES: usize = 10_000_000;

/// Files whose chains the cache keeps (looked up one by one: a few files per sequence side).
const CACHED_FILES: usize = 16;

/// Pages whose offsets the cache keeps besides the newest file's (16 bytes a page).
const CACHED_PAGES: usize = 1 << 22;

/// Where one page's IFD lies, and where its next-IFD offset is stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Ifd {
    at: u64,
    next_field: u64,
}

/// The layout of a TIFF file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Layout {
    little: bool,
    big: bool,
}

impl Layout {
    /// Bytes of an offset (4, or 8 in BigTIFF).
    fn width(self) -> usize {
        if self.big {
            8
        } else {
            4
        }
    }
    fn header_len(self) -> u64 {
        if self.big {
            16
        } else {
            8
        }
    }
    /// Where the header stores the first IFD's offset.
    fn first_field(self) -> u64 {
        if self.big {
            8
        } else {
            4
        }
    }
    fn uint(self, b: &[u8]) -> u64 {
        let mut v = [0u8; 8];
        if self.little {
            v[..b.len()].copy_from_slice(b);
            u64::from_le_bytes(v)
        } else {
            v[8 - b.len()..].copy_from_slice(b);
            u64::from_be_bytes(v)
        }
    }
    fn bytes(self, value: u64) -> [u8; 8] {
        let (w, b) = (self.width(), if self.little { value.to_le_bytes() } else { value.to_be_bytes() });
        let mut out = [0u8; 8];
        if self.little {
            out[..w].copy_from_slice(&b[..w]);
        } else {
            out[..w].copy_from_slice(&b[8 - w..]);
        }
        out
    }
}

/// The pages of a TIFF file, in chain order.
#[derive(Debug)]
pub(super) struct Chain {
    layout: Layout,
    ifds: Vec<Ifd>,
    /// Why the chain stops before its proper end (a zero next-IFD offset); None when it does not.
    pub(super) broken: Option<Reason>,
}

impl Chain {
    /// Pages found (every page before the break, if any).
    pub(super) fn pages(&self) -> usize {
        self.ifds.len()
    }

    /// `reader` (the file) seen as a one-page TIFF of page `page`; an error naming why when the
    /// chain has no such page.
    pub(super) fn one_page<R: Read + Seek>(&self, mut reader: R, page: usize) -> Result<OnePage<R>, Reason> {
        let Some(ifd) = self.ifds.get(page) else {
            return Err(match &self.broken {
                Some(why) => why.clone(),
                None => match self.ifds.len() {
                    1 => format!("page {page} out of range (the file has one page)"),
                    n => format!("page {page} out of range (the file has {n} pages)"),
                },
            });
        };
        reader.rewind().map_err(|e| format!("read error: {e}"))?;
        let (layout, len) = (self.layout, self.layout.width());
        Ok(OnePage {
            inner: reader,
            pos: 0,
            patches: [
                Patch { at: layout.first_field(), bytes: layout.bytes(ifd.at), len },
                Patch { at: ifd.next_field, bytes: [0; 8], len },
            ],
        })
    }
}

/// Bytes that read differently from the file's: `bytes[..len]` at offset `at`.
#[derive(Clone, Copy, Debug)]
struct Patch {
    at: u64,
    bytes: [u8; 8],
    len: usize,
}

impl Patch {
    /// Overwrite the part of `buf` (the file's bytes from offset `start`) that the patch covers.
    fn apply(&self, start: u64, buf: &mut [u8]) {
        let end = start.saturating_add(buf.len() as u64);
        let (lo, hi) = (self.at.max(start), self.at.saturating_add(self.len as u64).min(end));
        for x in lo..hi {
            buf[(x - start) as usize] = self.bytes[(x - self.at) as usize];
        }
    }
}

/// A TIFF file as a one-page TIFF ([`Chain::one_page`]).
pub(super) struct OnePage<R> {
    inner: R,
    pos: u64,
    patches: [Patch; 2],
}

impl<R: Read> Read for OnePage<R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let n = self.inner.read(buf)?;
        for p in &self.patches {
            p.apply(self.pos, &mut buf[..n]);
        }
        self.pos += n as u64;
        Ok(n)
    }
}

impl<R: Seek> Seek for OnePage<R> {
    fn seek(&mut self, to: SeekFrom) -> io::Result<u64> {
        self.pos = self.inner.seek(to)?;
        Ok(self.pos)
    }
}

// ----------------------------------------------------------------------------- the walk

/// IFDs read by [`scan`] in this process: a test hook showing that a file's pages cost one
/// pass over its chain.
static IFDS_READ: AtomicU64 = AtomicU64::new(0);

/// How many IFDs the page-chain walk has read in this process.
pub fn ifds_read() -> u64 {
    IFDS_READ.load(Ordering::Relaxed)
}

/// Why an IFD cannot be read.
enum IfdError {
    /// It lies, or runs, past the end of the file.
    Truncated(String),
    Read(io::Error),
}

/// A reader that knows its position, so a short hop forward or back stays inside a
/// `BufReader`'s buffer instead of discarding it.
struct Walker<'a, R> {
    reader: &'a mut R,
    pos: u64,
    len: u64,
}

impl<R: Read + Seek> Walker<'_, R> {
    fn read_at(&mut self, at: u64, buf: &mut [u8]) -> io::Result<()> {
        if at != self.pos {
            // both lie within the file, whose length fits an i64
            self.reader.seek_relative(at as i64 - self.pos as i64)?;
        }
        self.reader.read_exact(buf)?;
        self.pos = at + buf.len() as u64;
        Ok(())
    }

    fn header(&mut self) -> Result<(Layout, u64), Reason> {
        let bad = || "corrupt TIFF file: invalid header".to_string();
        let mut head = [0u8; 16];
        let want = if self.len >= 16 { 16 } else { 8 };
        self.read_at(0, &mut head[..want]).map_err(|_| "truncated TIFF file (no complete header)".to_string())?;
        let little = match &head[..2] {
            b"II" => true,
            b"MM" => false,
            _ => return Err(bad()),
        };
        let probe = Layout { little, big: false };
        let layout = match probe.uint(&head[2..4]) {
            42 => probe,
            43 if want == 16 && probe.uint(&head[4..6]) == 8 && probe.uint(&head[6..8]) == 0 => {
                Layout { little, big: true }
            }
            _ => return Err(bad()),
        };
        let field = layout.first_field() as usize;
        Ok((layout, layout.uint(&head[field..field + layout.width()])))
    }

    /// The IFD at `at`: where it lies and the next IFD's offset; or why it cannot be read.
    fn ifd(&mut self, layout: Layout, at: u64) -> Result<(Ifd, u64), IfdError> {
        let len = self.len;
        if at >= len {
            return Err(IfdError::Truncated(format!(
                "its IFD at byte {at} lies beyond the end of the file ({len} bytes)"
            )));
        }
        let count_len: u64 = if layout.big { 8 } else { 2 };
        if at + count_len > len {
            return Err(IfdError::Truncated(format!(
                "its IFD at byte {at} runs past the end of the file ({len} bytes)"
            )));
        }
        let mut count = [0u8; 8];
        self.read_at(at, &mut count[..count_len as usize]).map_err(IfdError::Read)?;
        let entries = layout.uint(&count[..count_len as usize]);
        let entry_len: u64 = if layout.big { 20 } else { 12 };
        let width = layout.width() as u64;
        let next_field = entries.checked_mul(entry_len).and_then(|b| b.checked_add(at + count_len));
        let Some(next_field) = next_field.filter(|f| f.checked_add(width).is_some_and(|end| end <= len)) else {
            return Err(IfdError::Truncated(format!(
                "its IFD at byte {at} ({entries} entries) runs past the end of the file ({len} bytes)"
            )));
        };
        let mut next = [0u8; 8];
        self.read_at(next_field, &mut next[..width as usize]).map_err(IfdError::Read)?;
        IFDS_READ.fetch_add(1, Ordering::Relaxed);
        Ok((Ifd { at, next_field }, layout.uint(&next[..width as usize])))
    }
}

/// Walk the IFD chain of the TIFF `reader` holds, once, to its end or to where it breaks. An
/// error when not even the first page's IFD can be read.
pub(super) fn scan<R: Read + Seek>(reader: &mut R) -> Result<Chain, Reason> {
    let len = reader.seek(SeekFrom::End(0)).map_err(|e| format!("read error: {e}"))?;
    reader.rewind().map_err(|e| format!("read error: {e}"))?;
    let mut walk = Walker { reader, pos: 0, len };
    let (layout, mut next) = walk.header()?;
    let mut ifds: Vec<Ifd> = Vec::new();
    let mut seen: HashSet<u64> = HashSet::new();
    let broken = loop {
        let k = ifds.len();
        if next == 0 {
            break None;
        }
        if k == MAX_PAGES {
            break Some(format!("more than {MAX_PAGES} pages (the most read from one TIFF): page {k} is not read"));
        }
        if next < layout.header_len() {
            break Some(format!("corrupt TIFF file at page {k}: its IFD offset {next} points into the header"));
        }
        if !seen.insert(next) {
            let back = ifds.iter().position(|i| i.at == next).unwrap_or(0);
            break Some(format!(
                "the IFD chain loops back at page {k}: page {}'s next-IFD offset points back to page {back}'s IFD \
                 (byte {next})",
                k - 1
            ));
        }
        match walk.ifd(layout, next) {
            Ok((ifd, following)) => {
                ifds.push(ifd);
                next = following;
            }
            Err(IfdError::Truncated(why)) => break Some(format!("truncated at page {k}: {why}")),
            Err(IfdError::Read(e)) => break Some(format!("page {k}: read error: {e}")),
        }
    };
    let broken = broken.map(|why| match ifds.len() {
        0 => why,
        n => format!("{why}; the {n} page(s) before it are found"),
    });
    if ifds.is_empty() {
        return Err(broken.unwrap_or_else(|| "corrupt TIFF file: no image (the first IFD offset is 0)".to_string()));
    }
    Ok(Chain { layout, ifds, broken })
}

// ----------------------------------------------------------------------------- the cache

/// What identifies a file's content for the cache: the same path may be replaced by rename
/// (a new inode) or rewritten in place (same inode, new change time even when the
/// modification time is set back), and either may keep the length and mtime.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct FileKey {
    path: PathBuf,
    len: u64,
    modified: Option<std::time::SystemTime>,
    #[cfg(unix)]
    unix: (u64, u64, i64, i64), // device, inode, ctime seconds, ctime nanoseconds
}

impl FileKey {
    /// The key of the file at `path`, from the metadata of the open file.
    pub(super) fn of(path: &Path, meta: &Metadata) -> FileKey {
        #[cfg(unix)]
        let unix = {
            use std::os::unix::fs::MetadataExt;
            (meta.dev(), meta.ino(), meta.ctime(), meta.ctime_nsec())
        };
        FileKey {
            path: path.to_path_buf(),
            len: meta.len(),
            modified: meta.modified().ok(),
            #[cfg(unix)]
            unix,
        }
    }
}

/// Chains of recently read files, newest first.
static CHAINS: Mutex<Vec<(FileKey, Arc<Chain>)>> = Mutex::new(Vec::new());

fn cached(key: &FileKey) -> Option<Arc<Chain>> {
    let mut chains = CHAINS.lock().unwrap_or_else(|e| e.into_inner());
    let i = chains.iter().position(|(k, _)| k == key)?;
    let hit = chains.remove(i);
    let chain = hit.1.clone();
    chains.insert(0, hit);
    Some(chain)
}

fn remember(key: FileKey, chain: Arc<Chain>) {
    let mut chains = CHAINS.lock().unwrap_or_else(|e| e.into_inner());
    chains.retain(|(k, _)| k.path != key.path);
    chains.insert(0, (key, chain));
    // keep the newest, and older chains while they hold at most CACHED_PAGES pages in all
    let mut kept = 0usize;
    let mut keep = 1;
    for (_, c) in chains.iter().skip(1).take(CACHED_FILES - 1) {
        kept += c.pages();
        if kept > CACHED_PAGES {
            break;
        }
        keep += 1;
    }
    chains.truncate(keep);
}

/// The page chain of the TIFF `reader` holds: from the cache when `key` (the file's
/// identity) is there, else walked and, with a key, kept.
pub(super) fn chain<R: Read + Seek>(reader: &mut R, key: Option<&FileKey>) -> Result<Arc<Chain>, Reason> {
    if let Some(found) = key.and_then(cached) {
        return Ok(found);
    }
    let chain = Arc::new(scan(reader)?);
    if let Some(key) = key {
        remember(key.clone(), chain.clone());
    }
    Ok(chain)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Cursor;

    #[test]
    fn patches_cover_exactly_their_bytes_whatever_the_read() {
        let file: Vec<u8> = (0..64u8).collect();
        let p = Patch { at: 10, bytes: [0xa0, 0xa1, 0xa2, 0xa3, 0, 0, 0, 0], len: 4 };
        let mut want = file.clone();
        want[10..14].copy_from_slice(&[0xa0, 0xa1, 0xa2, 0xa3]);
        for step in [1usize, 3, 5, 11, 64] {
            let mut view = OnePage { inner: Cursor::new(&file), pos: 0, patches: [p, Patch { len: 0, ..p }] };
            let mut got = vec![0u8; 64];
            for chunk in got.chunks_mut(step) {
                view.read_exact(chunk).unwrap();
            }
            assert_eq!(got, want, "reads of {step}");
        }
    }

    #[test]
    fn offsets_are_written_in_the_file_byte_order() {
        let le = Layout { little: true, big: false };
        let be = Layout { little: false, big: true };
        assert_eq!(le.bytes(0x0102_0304), [4, 3, 2, 1, 0, 0, 0, 0]);
        assert_eq!(be.bytes(0x0102_0304), [0, 0, 0, 0, 1, 2, 3, 4]);
        assert_eq!(le.uint(&le.bytes(77)[..4]), 77);
        assert_eq!(be.uint(&be.bytes(1 << 40)), 1 << 40);
    }
}
