//! Content fingerprints of frame files (XXH3-64 of every byte), so that a resumed sequence run
//! scores again a frame whose file changed since its row was written, even when the size and
//! the modification time were kept.

use std::fs::File;
use std::io::Read;
use std::path::Path;

use xxhash_rust::xxh3::Xxh3;

use crate::{Error, Result};

const BLOCK: usize = 1 << 20;

/// XXH3-64 of the file's contents, read in 1 MiB blocks. Only regular files are read (a FIFO
/// or a device would block or never end).
pub fn file_digest(path: &Path) -> Result<u64> {
    let name = path.display();
    let meta = std::fs::metadata(path).map_err(|e| Error::Frame(format!("{name}: cannot stat: {e}")))?;
    if !meta.is_file() {
        return Err(Error::Frame(format!("{name}: not a regular file")));
    }
    let mut file = File::open(path).map_err(|e| Error::Frame(format!("{name}: cannot open: {e}")))?;
    let mut hasher = Xxh3::new();
    let mut block = vec![0u8; BLOCK];
    loop {
        match file.read(&mut block) {
            Ok(0) => return Ok(hasher.digest()),
            Ok(n) => hasher.update(&block[..n]),
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(Error::Frame(format!("{name}: read error: {e}"))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn digest_follows_content_not_metadata() {
        let dir = std::env::temp_dir().join(format!("irf_digest_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (a, b) = (dir.join("a.bin"), dir.join("b.bin"));
        let data: Vec<u8> = (0..3 * BLOCK + 17).map(|i| (i * 31 % 251) as u8).collect();
        std::fs::write(&a, &data).unwrap();
        std::fs::write(&b, &data).unwrap();
        assert_eq!(file_digest(&a).unwrap(), file_digest(&b).unwrap());
        assert_eq!(file_digest(&a).unwrap(), xxhash_rust::xxh3::xxh3_64(&data));
        let mut changed = data.clone();
        changed[2 * BLOCK + 5] ^= 1; // one bit, deep inside the file
        std::fs::write(&b, &changed).unwrap();
        assert_ne!(file_digest(&a).unwrap(), file_digest(&b).unwrap());
        assert!(matches!(file_digest(&dir), Err(Error::Frame(m)) if m.contains("not a regular file")));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
