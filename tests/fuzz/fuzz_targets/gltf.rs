//! A glTF/GLB file, all the way: import -> scene -> BLAS and TLAS builds -> one tiny frame.
//! Any input must end in an error or an image, never a panic or a hang.
#![no_main]

use std::path::Path;

use gloam::frame::Engine;
use gloam::render::RenderSettings;
use gloam::scene::Scene;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    // GLB when it says so, JSON glTF otherwise (its buffers are data: URIs or missing).
    let name = if data.starts_with(b"glTF") { "fuzz.glb" } else { "fuzz.gltf" };
    let Ok(asset) = gloam::scene::gltf_import::import_gltf_bytes(Path::new(name), data) else {
        return;
    };
    let Ok(scene) = Scene::from_asset(asset) else {
        return;
    };
    let mut engine = Engine::new(&scene, RenderSettings::real_time(8, 8));
    engine.advance(1.0 / 60.0);
    let _ = engine.image();
});
