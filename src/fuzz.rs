//! The fuzz targets' bodies, as library functions. Outside the frame: each takes a file's
//! bytes down the path the game takes with that file (load, check, spawn, simulate,
//! render), and any input must end in an error or a result, never a panic or a hang.
//!
//! `tests/fuzz` holds one cargo-fuzz target per function here, each a single call; the
//! ordinary test suite (`tests/fuzz_seeds.rs`) runs the same functions over the seed
//! files, on stable, so a target cannot rot: when a body stops compiling, or stops
//! reaching the frame with a good file, the suite fails.
//!
//! What each body memoises, and why: the level and replay targets would otherwise import
//! the kit's assets (and load the recording's level) again for every input, hundreds of
//! milliseconds each, where a mutated level or recording takes microseconds to refuse.
//! The assets do not change between inputs, and their import is the gltf target's.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, LazyLock, Mutex};

use crate::frame::Engine;
use crate::render::RenderSettings;
use crate::scene::model::Asset;
use crate::scene::{AssetCache, Scene};

/// The recording steps the replay body plays, at most: 2 s of play. The bytes of a
/// recording reach its parsing, its checks and the steps its inputs drive, and what a bad
/// input value does to the simulation (a NaN look, a huge move) shows within a few steps.
/// At 600 steps the target ran 76 inputs a second; whole recordings, a minute or more
/// each, would put a million inputs out of reach.
pub const REPLAY_STEPS: usize = 120;

/// A glTF/GLB file (JSON glTF unless it starts with the GLB magic), all the way: import
/// -> scene -> BLAS and TLAS builds -> one 8x8 frame. `Err` is the first refusal.
pub fn gltf(data: &[u8]) -> Result<(), String> {
    let name = if data.starts_with(b"glTF") {
        "fuzz.glb"
    } else {
        "fuzz.gltf"
    };
    let asset = crate::scene::gltf_import::import_gltf_bytes(Path::new(name), data)
        .map_err(|error| error.to_string())?;
    let scene = Scene::from_asset(asset).map_err(|error| error.to_string())?;
    let mut engine = Engine::new(&scene, RenderSettings::real_time(8, 8));
    engine.advance(1.0 / 60.0);
    let _ = engine.image();
    Ok(())
}

/// A level file's text, as if read from `path` (its assets are named relative to
/// `path`'s folder), all the way: parse -> validation -> its assets -> spawn (with the
/// player, when playable) -> three simulated steps and one 8x8 frame.
pub fn level(path: &Path, data: &[u8]) -> Result<(), String> {
    let text = std::str::from_utf8(data).map_err(|error| error.to_string())?;
    let level = crate::scene::level::parse_level(path, text).map_err(|error| error.to_string())?;
    let scene = Scene::from_level_importing(level, path, &memoised_import)
        .map_err(|error| error.to_string())?;
    let mut engine = Engine::new(&scene, RenderSettings::real_time(8, 8));
    if scene.level.playable {
        let _ = crate::game::spawn_player(&mut engine.world);
    }
    for _ in 0..3 {
        engine.step();
    }
    engine.advance(1.0 / 60.0);
    Ok(())
}

/// A recording's text, as if read from `path` (its level is named relative to `path`'s
/// folder), all the way: parse -> version and level-hash checks -> the first
/// `REPLAY_STEPS` steps replayed headless on its level. `Ok` is the replay's report.
pub fn replay(path: &Path, data: &[u8]) -> Result<serde_json::Value, String> {
    let text = std::str::from_utf8(data).map_err(|error| error.to_string())?;
    let (recording, level) =
        crate::headless::replay::parse_recording(path, text).map_err(|error| error.to_string())?;
    let scene = memoised_scene(&level)?;
    crate::headless::replay::replay_loaded(&scene, &level, &recording, REPLAY_STEPS)
        .map_err(|error| error.to_string())
}

/// The player's settings and best-times files, parsed and checked as the window does at
/// start: `Ok` when the text is either.
pub fn settings(data: &[u8]) -> Result<(), String> {
    use crate::app::settings::{BestTimes, Settings, parse};
    let text = std::str::from_utf8(data).map_err(|error| error.to_string())?;
    let settings = parse::<Settings>(Path::new("settings.ron"), text).map(|_| ());
    let best = parse::<BestTimes>(Path::new("best-times.ron"), text).map(|_| ());
    settings.or(best).map_err(|error| error.to_string())
}

/// Each asset file imported once per process (the game's own `AssetCache`).
fn memoised_import(file: &Path) -> Result<Arc<Asset>, crate::scene::LoadError> {
    static ASSETS: LazyLock<Mutex<AssetCache>> =
        LazyLock::new(|| Mutex::new(AssetCache::new(PathBuf::new())));
    lock(&ASSETS).load_file(file)
}

/// Each level loaded once per process.
fn memoised_scene(level: &Path) -> Result<Arc<Scene>, String> {
    static SCENES: LazyLock<Mutex<HashMap<PathBuf, Arc<Scene>>>> = LazyLock::new(Default::default);
    if let Some(scene) = lock(&SCENES).get(level) {
        return Ok(Arc::clone(scene));
    }
    let scene = Arc::new(Scene::load(level).map_err(|error| error.to_string())?);
    lock(&SCENES).insert(level.to_owned(), Arc::clone(&scene));
    Ok(scene)
}

/// A memo's lock; one poisoned by a panic (which the fuzzer reports) still holds
/// whole entries, each inserted in one call.
fn lock<T>(memo: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    memo.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}
