//! One JPEG-LS stream through irfidelity's own decoder (`rust/io/jpegls`): any input is
//! decoded to an image within the limits or refused, never a panic, a hang or an
//! out-of-bounds access.
#![no_main]
use irfidelity_fuzz::{MAX_BYTES, MAX_PIXELS};

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    if let Ok((cols, rows, samples)) = irfidelity::io::fuzzing::jpegls(data, MAX_PIXELS, MAX_BYTES) {
        assert_eq!(samples, cols * rows);
        assert!(cols > 0 && rows > 0 && samples as u64 <= MAX_PIXELS);
    }
});
