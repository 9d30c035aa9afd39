//! OpenEXR files through `irfidelity::io::decode_bytes` (first byte: options).
#![no_main]
libfuzzer_sys::fuzz_target!(init: irfidelity_fuzz::init(), |data: &[u8]| {
    if data.get(1..5) == Some(&[0x76, 0x2f, 0x31, 0x01][..]) {
        irfidelity_fuzz::decode(data);
    }
});
