//! A recording file, parsed, checked and replayed headless for its first steps:
//! `gloam::fuzz::replay`. The input is read as `tests/recordings/fuzz.json` (never
//! written), beside the shipped recordings, so `../../levels/first-light.ron` resolves.
#![no_main]

use std::path::PathBuf;
use std::sync::LazyLock;

use libfuzzer_sys::fuzz_target;

static PATH: LazyLock<PathBuf> =
    LazyLock::new(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../recordings/fuzz.json"));

fuzz_target!(|data: &[u8]| {
    let _ = gloam::fuzz::replay(&PATH, data);
});
