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

/// A fresh empty folder for one test.
pub fn scratch_dir(name: &str) -> PathBuf {
    static COUNTER: AtomicUsize = AtomicUsize::new(0);
    let dir = std::env::temp_dir().join(format!(
        "gloam-test-{}-{}-{name}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("create scratch dir");
    dir
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
