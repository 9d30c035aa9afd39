//! The calibrations of the radiometric frames decoded last. Decoding a FLIR frame parses its
//! camera-info record beside its counts and keeps it here, keyed by the file (path, size,
//! times, inode) and the page, so that converting the counts to temperatures
//! ([`super::read_camera_info`] of the same file) does not read the file a second time.
//! A file that changed since has another key and is read again.

use std::path::Path;
use std::sync::Mutex;

use super::flir::CameraInfo;
use super::tiff_pages::FileKey;

/// The last calibrations decoded, newest first, shared by all threads.
static KEPT: Mutex<Vec<(FileKey, usize, CameraInfo)>> = Mutex::new(Vec::new());
/// How many are kept: a few files scored side by side (a real and a second real frame, a
/// simulator's radiometric files).
const KEPT_MAX: usize = 8;

fn kept() -> std::sync::MutexGuard<'static, Vec<(FileKey, usize, CameraInfo)>> {
    KEPT.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// Keeps the calibration of page `page` of the file `key` names.
pub(super) fn keep(key: &FileKey, page: usize, info: CameraInfo) {
    let mut kept = kept();
    kept.retain(|(k, p, _)| !(k == key && *p == page));
    kept.insert(0, (key.clone(), page, info));
    kept.truncate(KEPT_MAX);
}

/// The calibration of page `page` of the file at `path`, when it was kept since the file last
/// changed.
pub(super) fn find(path: &Path, page: usize) -> Option<CameraInfo> {
    let key = FileKey::of(path, &std::fs::metadata(path).ok()?);
    kept().iter().find(|(k, p, _)| *k == key && *p == page).map(|(_, _, info)| info.clone())
}
