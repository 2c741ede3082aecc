//! A level file, all the way: parse -> validation -> load its assets -> spawn -> a few
//! simulated steps and one tiny frame. Levels name the shipped kit by `../assets/kit/...`,
//! so each input is written as `levels/fuzz.ron` in a scratch folder whose `assets` links
//! to the repository's.
#![no_main]

use std::path::PathBuf;
use std::sync::OnceLock;

use gloam::frame::Engine;
use gloam::render::RenderSettings;
use gloam::scene::Scene;
use libfuzzer_sys::fuzz_target;

fn level_path() -> &'static PathBuf {
    static PATH: OnceLock<PathBuf> = OnceLock::new();
    PATH.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("gloam-fuzz-level-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("levels")).expect("scratch folder");
        let assets = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../assets");
        let link = dir.join("assets");
        if !link.exists() {
            #[cfg(unix)]
            std::os::unix::fs::symlink(assets, &link).expect("link the assets");
        }
        dir.join("levels").join("fuzz.ron")
    })
}

fuzz_target!(|data: &[u8]| {
    let path = level_path();
    if std::fs::write(path, data).is_err() {
        return;
    }
    let Ok(scene) = Scene::load(path) else {
        return;
    };
    let mut engine = Engine::new(&scene, RenderSettings::real_time(8, 8));
    if scene.level.playable {
        gloam::game::spawn_player(&mut engine.world);
    }
    for _ in 0..3 {
        engine.step();
    }
    engine.advance(1.0 / 60.0);
});
