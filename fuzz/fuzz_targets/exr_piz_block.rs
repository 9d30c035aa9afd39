//! One OpenEXR PIZ block through irfidelity's own decoder (`rust/io/piz.rs`): any input is
//! decoded to the block's samples or refused, never a panic or an out-of-bounds access.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    if let Some((body, sizes, selected, w, h)) = irfidelity_fuzz::block(data) {
        if let Ok(n) = irfidelity::io::fuzzing::piz_block(body, &sizes, selected, w, h) {
            assert_eq!(n, w * h);
        }
    }
});
