//! Any bytes through the C3D reader: errors are fine, panics and hangs are
//! not. Run with `cargo +nightly fuzz run c3d` from the repository root.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use treemocap::format::c3d::{C3dOptions, C3dReader};

fuzz_target!(|data: &[u8]| {
    if let Ok(reader) = C3dReader::from_bytes(Path::new("fuzz.c3d"), data.to_vec(), &C3dOptions::default()) {
        // Zero-byte frames can be declared up to 65535 times; bound the work.
        for frame in reader.take(1 << 16) {
            if frame.is_err() {
                break;
            }
        }
    }
});
