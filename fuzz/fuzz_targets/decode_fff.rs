//! FLIR FFF and SEQ files (FFF frames one after another, either byte order) through
//! `irfidelity::io::decode_bytes` (first byte: options and page).
#![no_main]
libfuzzer_sys::fuzz_target!(init: irfidelity_fuzz::init(), |data: &[u8]| {
    if matches!(data.get(1..5), Some(b"FFF\0" | b"AFF\0")) {
        irfidelity_fuzz::decode(data);
    }
});
