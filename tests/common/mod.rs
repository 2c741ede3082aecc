//! Helpers shared by the integration tests.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

/// The repository root (where Cargo.toml is).
pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// `../shared/<relative>` beside the repository, or None with a printed notice: a user's
/// clone has no ../shared, so tests that need it skip rather than fail.
pub fn shared(relative: &str) -> Option<PathBuf> {
    let path = repo().join("..").join("shared").join(relative);
    if path.exists() {
        Some(path)
    } else {
        println!(
            "notice: skipping, {} is absent (it exists only beside the development checkout)",
            path.display()
        );
        None
    }
}

/// A fresh empty folder for one test, under `gloam-test-<process>-...` in the temp dir.
/// Kept after the test (a failing test's files are there to look at); the first call in
/// each test process removes the folders of test processes that have ended.
pub fn scratch_dir(name: &str) -> PathBuf {
    static COUNTER: AtomicUsize = AtomicUsize::new(0);
    static SWEPT: std::sync::Once = std::sync::Once::new();
    SWEPT.call_once(remove_ended_processes_scratch);
    let dir = std::env::temp_dir().join(format!(
        "gloam-test-{}-{}-{name}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("create scratch dir");
    dir
}

/// Removes the scratch folders of test processes no longer running (`/proc/<pid>` gone;
/// where there is no /proc, none are removed).
fn remove_ended_processes_scratch() {
    let proc = Path::new("/proc");
    let Ok(entries) = std::fs::read_dir(std::env::temp_dir()) else {
        return;
    };
    if !proc.is_dir() {
        return;
    }
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(pid) = name
            .to_str()
            .and_then(|name| name.strip_prefix("gloam-test-"))
            .and_then(|rest| rest.split('-').next())
            .filter(|pid| !pid.is_empty() && pid.bytes().all(|b| b.is_ascii_digit()))
        else {
            continue;
        };
        if !proc.join(pid).exists() {
            let _ = std::fs::remove_dir_all(entry.path());
        }
    }
}

pub fn write(dir: &Path, name: &str, contents: impl AsRef<[u8]>) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, contents).expect("write test file");
    path
}

/// Every level shipped in levels/, sorted.
pub fn shipped_levels() -> Vec<PathBuf> {
    let mut levels: Vec<_> = std::fs::read_dir(repo().join("levels"))
        .expect("levels/ exists")
        .map(|entry| entry.expect("a readable folder entry").path())
        .filter(|path| path.extension().is_some_and(|e| e == "ron"))
        .collect();
    levels.sort();
    levels
}

/// Stops every clip and every warden's beat (first-light's wardens walk), so frames change
/// only what a test changes.
pub fn pause_animation(engine: &mut gloam::frame::Engine) {
    let mut animators = engine.world.query::<&mut gloam::game::Animator>();
    for mut animator in animators.iter_mut(&mut engine.world) {
        animator.speed = 0.0;
    }
    let mut wardens = engine
        .world
        .query_filtered::<bevy_ecs::prelude::Entity, bevy_ecs::prelude::With<gloam::game::Warden>>(
        );
    let wardens: Vec<_> = wardens.iter(&engine.world).collect();
    for warden in wardens {
        engine
            .world
            .entity_mut(warden)
            .remove::<gloam::game::Warden>();
    }
}
