use super::*;

#[test]
fn default_thresholds_follow_the_standard() {
    // T.87 Table C.3's defaults for 8 bits, and the 16-bit ones (factor capped at 4095)
    assert_eq!(default_thresholds(255, 0), (3, 7, 21));
    assert_eq!(default_thresholds(65535, 0), (18, 67, 276));
    assert_eq!(default_thresholds(4095, 0), (18, 67, 276));
    assert_eq!(default_thresholds(255, 3), (12, 22, 42));
    assert_eq!(default_thresholds(15, 0), (2, 3, 4));
}
