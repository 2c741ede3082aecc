//! A level file, all the way to a few steps and one tiny frame: `gloam::fuzz::level`. The
//! input is read as `levels/fuzz.ron` in this repository (never written), so the kit it
//! names by `../assets/kit/...` resolves.
#![no_main]

use std::path::PathBuf;
use std::sync::LazyLock;

use libfuzzer_sys::fuzz_target;

static PATH: LazyLock<PathBuf> =
    LazyLock::new(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../levels/fuzz.ron"));

fuzz_target!(|data: &[u8]| {
    let _ = gloam::fuzz::level(&PATH, data);
});
