//! Fuzz the PLY reader (ASCII and binary): any byte string must give a mesh or an error,
//! never a panic. Run: `cargo +nightly fuzz run ply -- -max_total_time=600` from `fuzz/`.
#![no_main]

use libfuzzer_sys::fuzz_target;
use skin_core::mesh::{read_ply_from_reader, write_ply_to, PlyEncoding};

fuzz_target!(|data: &[u8]| {
    if let Ok(mesh) = read_ply_from_reader(data) {
        // Whatever was accepted must be a valid mesh that writes and reads back identically.
        assert!(mesh.validate().is_ok());
        let mut buf = Vec::new();
        if write_ply_to(&mut buf, &mesh, PlyEncoding::BinaryLittleEndian).is_ok() {
            let back = read_ply_from_reader(&buf[..]).expect("round trip of an accepted mesh");
            assert_eq!(back, mesh);
        }
    }
});
