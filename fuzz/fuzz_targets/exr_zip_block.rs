//! One OpenEXR ZIP block through irfidelity's own decoder (`rust/io/zip.rs`).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    if let Some((body, sizes, selected, w, h)) = irfidelity_fuzz::block(data) {
        if let Ok(n) = irfidelity::io::fuzzing::zip_block(body, &sizes, selected, w, h) {
            assert_eq!(n, w * h);
        }
    }
});
