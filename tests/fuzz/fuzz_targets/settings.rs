//! The player's settings and best-times files: parse and check, as the window does at
//! start; a broken file must be a diagnostic, never a panic.
#![no_main]

use std::path::Path;

use gloam::app::settings::{BestTimes, Settings, parse};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let _ = parse::<Settings>(Path::new("settings.ron"), text);
    let _ = parse::<BestTimes>(Path::new("best-times.ron"), text);
});
