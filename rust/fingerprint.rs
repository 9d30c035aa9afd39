//! Content fingerprints of frame files (size, modification time, XXH3-64 of every byte), so
//! that a resumed sequence run scores again a frame whose file changed since its row was
//! written, even when the size and the modification time were kept.
//!
//! A fingerprint recorded with a frame's statistics must describe the bytes those statistics
//! were computed from; one taken after decoding could describe a newer file than the one
//! decoded. The sequence engine therefore fingerprints a frame file in one of two ways:
//!
//! * [`read_whole`] — the file read once into memory, hashed, and decoded from that buffer:
//!   the fingerprint is of exactly the bytes decoded. For files up to a share of the decoding
//!   budget.
//! * [`digest_before`] and [`unchanged`] — for the later pages of a multi-page TIFF (reading
//!   the whole file per page would be quadratic) and files too large to hold: the digest is
//!   taken *before* decoding (cached per thread and per file state), and the file's state
//!   ([`FileState`]: device, inode, size, modification and change times) is checked again
//!   after decoding; a fingerprint is given only when it did not change. So a recorded digest
//!   is never of content newer than the decoded one, and a file changed during the decode
//!   gets no fingerprint (its frame is not trusted by a resume). What remains is a file
//!   rewritten to other content and back to the hashed bytes, both within one tick of the
//!   filesystem's change-time clock, during a decode (Linux keeps the change time per inode
//!   and moves it on every write; since 6.13 a queried change time is always followed by a
//!   distinct one).

use std::cell::RefCell;
use std::fs::{File, Metadata};
use std::io::Read;
use std::path::{Path, PathBuf};
use std::time::UNIX_EPOCH;

use xxhash_rust::xxh3::{xxh3_64, Xxh3};

use crate::{Error, Result};

const BLOCK: usize = 1 << 20;

/// What a record trusts about one input file: its size, modification time (nanoseconds since
/// the Unix epoch) and the XXH3-64 of its bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Fingerprint {
    pub size: u64,
    pub mtime_ns: i64,
    pub digest: u64,
}

fn mtime_ns(meta: &Metadata) -> i64 {
    match meta.modified() {
        Ok(t) => match t.duration_since(UNIX_EPOCH) {
            Ok(d) => i64::try_from(d.as_nanos()).unwrap_or(i64::MAX),
            Err(before) => i64::try_from(before.duration().as_nanos()).map_or(i64::MIN, |ns| -ns),
        },
        Err(_) => 0,
    }
}

/// XXH3-64 of everything `file` still holds, read in blocks of at most 1 MiB.
fn digest_of(file: &mut File, len_hint: u64, name: &dyn std::fmt::Display) -> Result<u64> {
    let mut hasher = Xxh3::new();
    let mut block = vec![0u8; (len_hint as usize).saturating_add(1).clamp(1, BLOCK)];
    loop {
        match file.read(&mut block) {
            Ok(0) => return Ok(hasher.digest()),
            Ok(n) => hasher.update(&block[..n]),
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(Error::Frame(format!("{name}: read error: {e}"))),
        }
    }
}

/// XXH3-64 of the file's contents. Only regular files are read (a FIFO or a device would
/// block or never end).
pub fn file_digest(path: &Path) -> Result<u64> {
    let name = path.display();
    let mut file = crate::io::open_regular(path).map_err(|reason| Error::Frame(format!("{name}: {reason}")))?;
    let len = file.metadata().map(|m| m.len()).unwrap_or(0);
    digest_of(&mut file, len, &name)
}

/// The whole file in memory with its fingerprint, when it holds at most `limit` bytes (None
/// when it is larger, or grows beyond `limit` while being read).
pub fn read_whole(path: &Path, limit: u64) -> Result<Option<(Vec<u8>, Fingerprint)>> {
    let name = path.display();
    let err = |reason: String| Error::Frame(format!("{name}: {reason}"));
    let file = crate::io::open_regular(path).map_err(err)?;
    let len = file.metadata().map_err(|e| err(format!("cannot stat: {e}")))?.len();
    if len > limit {
        return Ok(None);
    }
    let mut bytes = Vec::new();
    bytes.try_reserve_exact(len as usize + 1).map_err(|_| err(format!("cannot hold its {len} bytes in memory")))?;
    let mut file = file;
    (&mut file).take(limit + 1).read_to_end(&mut bytes).map_err(|e| err(format!("cannot read: {e}")))?;
    if bytes.len() as u64 > limit {
        return Ok(None);
    }
    let meta = file.metadata().map_err(|e| err(format!("cannot stat: {e}")))?;
    let fingerprint = Fingerprint { size: bytes.len() as u64, mtime_ns: mtime_ns(&meta), digest: xxh3_64(&bytes) };
    Ok(Some((bytes, fingerprint)))
}

/// What identifies a file's content on disk between two looks: the same path may be replaced
/// by rename (a new inode) or rewritten in place (the change time moves on even when the
/// modification time is set back), and either may keep the length and modification time.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FileState {
    path: PathBuf,
    len: u64,
    mtime_ns: i64,
    #[cfg(unix)]
    unix: (u64, u64, i64, i64), // device, inode, change time (seconds, nanoseconds)
}

impl FileState {
    /// The file's state now; None when it cannot be read (its decode then fails on its own).
    pub fn of(path: &Path) -> Option<FileState> {
        let meta = std::fs::metadata(path).ok().filter(Metadata::is_file)?;
        #[cfg(unix)]
        let unix = {
            use std::os::unix::fs::MetadataExt;
            (meta.dev(), meta.ino(), meta.ctime(), meta.ctime_nsec())
        };
        Some(FileState {
            path: path.to_path_buf(),
            len: meta.len(),
            mtime_ns: mtime_ns(&meta),
            #[cfg(unix)]
            unix,
        })
    }
}

/// Digests per thread: a real and a simulated stack (and a spare) are read together.
const DIGESTS_PER_THREAD: usize = 4;

thread_local! {
    static DIGESTS: RefCell<Vec<(FileState, Fingerprint)>> = const { RefCell::new(Vec::new()) };
}

/// The file's state and fingerprint before it is decoded: hashed once per thread and file
/// state (the pages of a stack share it). None when the file cannot be read or changed while
/// it was hashed.
pub fn digest_before(path: &Path) -> Option<(FileState, Fingerprint)> {
    let state = FileState::of(path)?;
    let cached = DIGESTS.with(|d| d.borrow().iter().find(|(s, _)| *s == state).map(|&(_, fp)| fp));
    let fingerprint = match cached {
        Some(fp) => fp,
        None => {
            let digest = file_digest(path).ok()?;
            if FileState::of(path).as_ref() != Some(&state) {
                return None;
            }
            let fp = Fingerprint { size: state.len, mtime_ns: state.mtime_ns, digest };
            DIGESTS.with(|d| {
                let mut v = d.borrow_mut();
                v.retain(|(s, _)| s.path != state.path);
                v.insert(0, (state.clone(), fp));
                v.truncate(DIGESTS_PER_THREAD);
            });
            fp
        }
    };
    Some((state, fingerprint))
}

/// Whether the file is still in `state` (checked after decoding it).
pub fn unchanged(path: &Path, state: &FileState) -> bool {
    FileState::of(path).as_ref() == Some(state)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(tag: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("irf_digest_{tag}_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn digest_follows_content_not_metadata() {
        let dir = scratch("content");
        let (a, b) = (dir.join("a.bin"), dir.join("b.bin"));
        let data: Vec<u8> = (0..3 * BLOCK + 17).map(|i| (i * 31 % 251) as u8).collect();
        std::fs::write(&a, &data).unwrap();
        std::fs::write(&b, &data).unwrap();
        assert_eq!(file_digest(&a).unwrap(), file_digest(&b).unwrap());
        assert_eq!(file_digest(&a).unwrap(), xxh3_64(&data));
        let mut changed = data.clone();
        changed[2 * BLOCK + 5] ^= 1; // one bit, deep inside the file
        std::fs::write(&b, &changed).unwrap();
        assert_ne!(file_digest(&a).unwrap(), file_digest(&b).unwrap());
        assert!(matches!(file_digest(&dir), Err(Error::Frame(m)) if m.contains("directory")));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_whole_read_fingerprints_the_bytes_it_returns() {
        let dir = scratch("whole");
        let path = dir.join("f.bin");
        let data: Vec<u8> = (0..5000u32).map(|i| (i % 253) as u8).collect();
        std::fs::write(&path, &data).unwrap();
        let (bytes, fp) = read_whole(&path, 5000).unwrap().unwrap();
        assert_eq!(bytes, data);
        assert_eq!((fp.size, fp.digest), (5000, file_digest(&path).unwrap()));
        assert_eq!(fp.mtime_ns, mtime_ns(&std::fs::metadata(&path).unwrap()));
        assert!(read_whole(&path, 4999).unwrap().is_none());
        assert!(matches!(read_whole(&dir.join("none"), 10), Err(Error::Frame(m)) if m.contains("none")));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_digest_before_is_cached_until_the_file_changes() {
        let dir = scratch("before");
        let path = dir.join("stack.bin");
        std::fs::write(&path, b"first content").unwrap();
        let (state, fp) = digest_before(&path).unwrap();
        assert_eq!(fp.digest, xxh3_64(b"first content"));
        assert!(unchanged(&path, &state));
        assert_eq!(digest_before(&path).unwrap().1, fp);
        // same length, new content, replaced by rename (a new inode): the state moves on
        std::fs::write(dir.join("new.bin"), b"other content").unwrap();
        std::fs::rename(dir.join("new.bin"), &path).unwrap();
        assert!(!unchanged(&path, &state));
        assert_eq!(digest_before(&path).unwrap().1.digest, xxh3_64(b"other content"));
        std::fs::remove_file(&path).unwrap();
        assert!(!unchanged(&path, &state) && digest_before(&path).is_none());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
