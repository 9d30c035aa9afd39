//! Radiometric FLIR files (FFF, SEQ and radiometric JPEGs, embedded PNG or TIFF raw images)
//! decoded, their calibration read and their counts converted to temperatures.
#![no_main]
libfuzzer_sys::fuzz_target!(init: irfidelity_fuzz::init(), |data: &[u8]| {
    if matches!(data.get(1..5), Some(b"FFF\0" | b"AFF\0")) || matches!(data.get(1..3), Some([0xFF, 0xD8])) {
        irfidelity_fuzz::temperatures(data);
    }
});
