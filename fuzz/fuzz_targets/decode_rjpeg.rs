//! Radiometric JPEGs (FLIR APP1 segments joined into an FFF frame) through
//! `irfidelity::io::decode_bytes` (first byte: options and page).
#![no_main]
libfuzzer_sys::fuzz_target!(init: irfidelity_fuzz::init(), |data: &[u8]| {
    if matches!(data.get(1..4), Some([0xFF, 0xD8, 0xFF])) {
        irfidelity_fuzz::decode(data);
    }
});
