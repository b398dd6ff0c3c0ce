//! Fuzzes the OpenCV FileStorage YAML reader: it must never panic, and whatever it accepts must
//! survive a write/read round trip unchanged.
#![no_main]

use libfuzzer_sys::fuzz_target;
use skin_core::camera::OpenCvCalibration;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        if let Ok(calibration) = OpenCvCalibration::from_yaml_str(text) {
            let again = OpenCvCalibration::from_yaml_str(&calibration.to_yaml_string())
                .expect("written YAML must parse");
            assert_eq!(again, calibration);
        }
    }
});
