//! Fuzz the OBJ reader: any byte string must give a mesh or an error, never a panic.
//! Run: `cargo +nightly fuzz run obj -- -max_total_time=600` from `fuzz/`.
#![no_main]

use libfuzzer_sys::fuzz_target;
use skin_core::mesh::ObjFile;

fuzz_target!(|data: &[u8]| {
    if let Ok(obj) = ObjFile::parse(data) {
        let _ = obj.to_mesh();
        // Exercise group selection on every group name the file defines, and a missing one.
        let names: Vec<String> = obj.group_names().iter().map(|s| s.to_string()).collect();
        for name in names.iter().take(8) {
            if let Ok(g) = obj.group_mesh(name) {
                assert_eq!(g.original_index.len(), g.mesh.vertex_count());
            }
        }
        let _ = obj.group_mesh("\u{0}no-such-group");
    }
});
