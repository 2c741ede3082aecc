//! The player's settings and best-times files, parsed and checked: `gloam::fuzz::settings`.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = gloam::fuzz::settings(data);
});
