//! What every fuzz target checks, shared by the targets in `fuzz_targets/`.
//!
//! A decode must return a frame within its limits or a `FrameError` naming the input; a
//! panic in irfidelity's own code, an abort, a hang, or an allocation beyond libFuzzer's
//! `-rss_limit_mb` / `-malloc_limit_mb` is a finding. A panic inside a third-party decoder
//! (the `exr`, `png`, `tiff` crates) is caught by irfidelity and becomes a FrameError, as in
//! production; it is logged once per location (`third-party panic at ...`) instead of
//! stopping the run.

use std::collections::HashSet;
use std::sync::{Mutex, Once};

use irfidelity::io::{decode_bytes, read_camera_info_bytes, DecodeOptions, FrameData};
use irfidelity::radiometry::{temperatures as to_temperatures, Converted, Unit};
use irfidelity::Error;

/// The limits of a fuzzed decode: a header may claim anything, the decode allocates at most
/// this (so thousands of runs per second, far below the 1 GB limits), and every seed fits.
pub const MAX_PIXELS: u64 = 1 << 20;
pub const MAX_BYTES: u64 = 64 << 20;

/// Replace libFuzzer's abort-on-panic hook: a panic located in a registry crate is logged
/// once and left to irfidelity's `catch_unwind`; any other (irfidelity's own code, the
/// standard library) aborts, a finding.
pub fn init() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let default = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            let file = info.location().map(|l| l.file().to_string()).unwrap_or_default();
            if !(file.contains("/.cargo/registry/") || file.contains("/.cargo/git/")) {
                default(info);
                std::process::abort();
            }
            static SEEN: Mutex<Option<HashSet<String>>> = Mutex::new(None);
            let place = info.location().map(|l| format!("{}:{}", l.file(), l.line())).unwrap_or_default();
            let mut seen = SEEN.lock().unwrap_or_else(|p| p.into_inner());
            if seen.get_or_insert_with(HashSet::new).insert(place.clone()) {
                eprintln!("third-party panic at {place}: {info}");
            }
        }));
    });
}

/// Decode `data` (after one selector byte: channel, page and budget) and check the outcome.
pub fn decode(data: &[u8]) {
    let Some((&sel, bytes)) = data.split_first() else { return };
    let channel = match sel % 6 {
        0 => None,
        1 => Some("Y"),
        2 => Some("R"),
        3 => Some("G"),
        4 => Some("A"),
        _ => Some("1"),
    };
    // one input in eight under a tight budget, so refusals are fuzzed too
    let max_bytes = if sel / 18 % 8 == 7 { 1 << 16 } else { MAX_BYTES };
    let opts = DecodeOptions {
        channel: channel.map(str::to_string),
        max_pixels: MAX_PIXELS,
        max_bytes,
        page: (sel / 6 % 3) as usize,
    };
    match decode_bytes(bytes, "fuzz-input", &opts) {
        Ok(frame) => {
            assert_eq!(frame.data.len(), frame.rows * frame.cols);
            assert!((frame.rows * frame.cols) as u64 <= MAX_PIXELS);
            assert!(frame.rows > 0 && frame.cols > 0);
        }
        Err(Error::Frame(msg)) => assert!(msg.starts_with("fuzz-input: "), "{msg}"),
        Err(other) => panic!("not a FrameError: {other:?}"),
    }
}

/// A block decoder's arguments: the block's bytes, sample sizes, selected channel, w, h.
pub type Block<'a> = (&'a [u8], Vec<usize>, usize, usize, usize);

/// A block decoder's input: w (1..=512), h (1..=64), channels as sample sizes (1..=6
/// channels of 2 or 4 bytes), the selected channel, then the block's bytes.
pub fn block(data: &[u8]) -> Option<Block<'_>> {
    let (head, body) = data.split_at_checked(4)?;
    let w = (head[0] as usize | (head[1] as usize & 1) << 8) + 1;
    let h = (head[1] as usize >> 1 & 63) + 1;
    let n = (head[2] & 7) as usize % 6 + 1;
    let sizes: Vec<usize> = (0..n).map(|i| if head[2] >> (3 + i % 5) & 1 == 1 { 4 } else { 2 }).collect();
    let selected = head[3] as usize % n;
    Some((body, sizes, selected, w, h))
}

/// A radiometric file (FLIR FFF or SEQ, a radiometric JPEG; after one selector byte: page,
/// unit) decoded, its camera-info record read, and its counts converted to temperatures
/// (`radiometry::temperatures`): each step returns its result or an error naming the input (a
/// calibration no model can use is an `Error::Value`), and a conversion gives one temperature
/// per count.
pub fn temperatures(data: &[u8]) {
    let Some((&sel, bytes)) = data.split_first() else { return };
    let opts = DecodeOptions { channel: None, max_pixels: MAX_PIXELS, max_bytes: MAX_BYTES, page: (sel % 3) as usize };
    let Ok(frame) = decode_bytes(bytes, "fuzz-input", &opts) else { return }; // decode_fff's business
    let info = match read_camera_info_bytes(bytes, "fuzz-input", &opts) {
        Ok(info) => info,
        Err(Error::Frame(msg)) => return assert!(msg.starts_with("fuzz-input: "), "{msg}"),
        Err(other) => panic!("not a FrameError: {other:?}"),
    };
    let unit = if sel & 8 == 0 { Unit::Celsius } else { Unit::Kelvin };
    let converted = match &frame.data {
        FrameData::U8(v) => to_temperatures(v, &info.calibration, unit),
        FrameData::U16(v) => to_temperatures(v, &info.calibration, unit),
        FrameData::I16(v) => to_temperatures(v, &info.calibration, unit),
        FrameData::U32(v) => to_temperatures(v, &info.calibration, unit),
        FrameData::F16(v) => to_temperatures(v, &info.calibration, unit),
        FrameData::F32(v) => to_temperatures(v, &info.calibration, unit),
        FrameData::F64(v) => to_temperatures(v, &info.calibration, unit),
    };
    match converted {
        Ok(Converted { values, outside, nonfinite }) => {
            assert_eq!(values.len(), frame.rows * frame.cols);
            assert!(outside + nonfinite <= values.len());
        }
        Err(Error::Value(_)) => {}
        Err(other) => panic!("not a ValueError: {other:?}"),
    }
}
