//! PNG files through `irfidelity::io::decode_bytes` (first byte: options).
#![no_main]
libfuzzer_sys::fuzz_target!(init: irfidelity_fuzz::init(), |data: &[u8]| {
    if data.get(1..9) == Some(&b"\x89PNG\r\n\x1a\n"[..]) {
        irfidelity_fuzz::decode(data);
    }
});
