//! A glTF/GLB file, all the way to one tiny frame: `gloam::fuzz::gltf`.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = gloam::fuzz::gltf(data);
});
