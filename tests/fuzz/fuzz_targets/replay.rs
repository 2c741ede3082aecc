//! A recording file, all the way: parse -> checks -> replayed headless on the level it
//! names (the shipped first-light, so the hash check passes when the input keeps it).
#![no_main]

use std::path::PathBuf;
use std::sync::OnceLock;

use libfuzzer_sys::fuzz_target;

fn recording_path() -> &'static PathBuf {
    static PATH: OnceLock<PathBuf> = OnceLock::new();
    PATH.get_or_init(|| {
        // Beside the shipped recordings, so `../../levels/first-light.ron` resolves.
        PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../recordings")
            .join(format!(".fuzz-{}.json", std::process::id()))
    })
}

fuzz_target!(|data: &[u8]| {
    let path = recording_path();
    if std::fs::write(path, data).is_err() {
        return;
    }
    let _ = gloam::headless::replay::replay(path, 1);
    let _ = std::fs::remove_file(path);
});
