//! Fuzz the frame decoders (OpenEXR, PNG, TIFF) through `irfidelity::io::decode_bytes`.
//!
//! Any input must give `Ok(frame)` or `Err(Error::Frame(..))`; a panic that escapes, an
//! abort, a hang or an allocation beyond libFuzzer's `-rss_limit_mb` is a bug. The first
//! byte picks the channel option so channel selection paths are fuzzed too.
#![no_main]

use irfidelity::io::{decode_bytes, DecodeOptions, FrameData};
use irfidelity::Error;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let (sel, bytes) = match data.split_first() {
        Some((s, rest)) => (*s, rest),
        None => return,
    };
    let channel = match sel % 6 {
        0 => None,
        1 => Some("Y"),
        2 => Some("R"),
        3 => Some("G"),
        4 => Some("A"),
        _ => Some("1"),
    };
    let opts = DecodeOptions {
        channel: channel.map(str::to_string),
        // keep the fuzzer's memory bounded: 4096 x 4096 pixels at most
        max_pixels: 1 << 24,
        page: (sel / 6 % 3) as usize,
    };
    match decode_bytes(bytes, "fuzz-input", &opts) {
        Ok(frame) => {
            assert_eq!(frame.data.len(), frame.rows * frame.cols);
            assert!(frame.rows * frame.cols <= 1 << 24);
            let _ = matches!(frame.data, FrameData::F16(_));
        }
        Err(Error::Frame(msg)) => assert!(msg.starts_with("fuzz-input: ")),
        Err(other) => panic!("non-Frame error: {other:?}"),
    }
});
