//! The level format round-trips: load, save, load gives equal levels, and saving is stable
//! text, so an editor save of an unchanged level changes nothing in git.

mod common;

use gloam::scene::Scene;
use gloam::scene::level::{Level, level_to_string, parse_level, save_level};

fn shipped_levels() -> Vec<std::path::PathBuf> {
    let levels = common::shipped_levels();
    assert!(
        levels.len() >= 2,
        "levels/ should hold cornell.ron and a first test level"
    );
    levels
}

#[test]
fn shipped_levels_load_with_their_assets() {
    for path in shipped_levels() {
        let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
        assert!(
            scene.triangle_count() > 0,
            "{} has no geometry",
            path.display()
        );
        assert!(scene.camera().is_some(), "{} has no camera", path.display());
    }
}

#[test]
fn shipped_levels_are_in_saved_form_and_round_trip() {
    for path in shipped_levels() {
        let text = std::fs::read_to_string(&path).unwrap();
        let level = parse_level(&path, &text).unwrap();
        let saved = level_to_string(&level);
        let reloaded: Level = parse_level(&path, &saved).unwrap();
        assert_eq!(
            reloaded,
            level,
            "{}: load-save-load changed the level",
            path.display()
        );
        assert_eq!(
            level_to_string(&reloaded),
            saved,
            "{}: saved text is not stable",
            path.display()
        );
        if let Some((line, (file, canonical))) = text
            .lines()
            .zip(saved.lines())
            .enumerate()
            .find(|(_, (a, b))| a != b)
        {
            panic!(
                "{}:{}: not in the form the editor saves:\n  file:  {file}\n  saved: {canonical}",
                path.display(),
                line + 1
            );
        }
        assert_eq!(
            text,
            saved,
            "{}: differs from its saved form in length",
            path.display()
        );
    }
}

#[test]
fn save_level_writes_atomically_and_reloads_equal() {
    let dir = common::scratch_dir("save");
    let source = common::repo().join("levels/first-light.ron");
    let mut level = parse_level(&source, &std::fs::read_to_string(&source).unwrap()).unwrap();
    level.entities[0].transform.translation.x += 0.25;
    let target = dir.join("edited.ron");
    save_level(&level, &target).unwrap();
    let again = parse_level(&target, &std::fs::read_to_string(&target).unwrap()).unwrap();
    assert_eq!(again, level);
    let leftovers: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(
        leftovers,
        vec![std::ffi::OsString::from("edited.ron")],
        "temporary files left behind"
    );
}

#[test]
fn first_light_is_a_complete_playable_level() {
    let scene = Scene::load(&common::repo().join("levels/first-light.ron")).unwrap();
    let (feet, eye_height) = scene.player_spawn().expect("spawn");
    assert_eq!(eye_height, 1.6);
    assert!(feet.is_finite());
    assert_eq!(scene.punctual_lights().len(), 5);
    // Every kit piece is used, and the crate override took effect.
    let names: Vec<_> = scene
        .assets
        .iter()
        .map(|a| a.source.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    for piece in [
        "floor.glb",
        "wall.glb",
        "pillar.glb",
        "crate.glb",
        "shard.glb",
    ] {
        assert!(
            names.iter().any(|n| n == piece),
            "{piece} not used: {names:?}"
        );
    }
    let dark_crate = scene
        .level
        .entities
        .iter()
        .position(|e| e.name == "crate cellar 3")
        .unwrap();
    let asset = &scene.assets[scene.entity_assets[dark_crate].unwrap()];
    let wood = asset.material_by_name("wood");
    let material = scene.resolved_material(dark_crate, asset, wood);
    assert_eq!(material.base_color, glam::Vec4::new(0.35, 0.25, 0.15, 1.0));
}

#[test]
fn cornell_level_uses_the_asset_camera() {
    let scene = Scene::load(&common::repo().join("levels/cornell.ron")).unwrap();
    let camera = scene.camera().unwrap();
    assert!((camera.yfov.to_degrees() - 39.3077).abs() < 1e-3);
    assert!(
        (camera.world_from_camera.w_axis.truncate() - glam::Vec3::new(0.278, 0.273, 0.8)).length()
            < 1e-5
    );
}

/// A level's sounds (an entity's `sound`, the environment's `ambience`) load, reach the
/// world as components, and are written back as they were, defaults left out.
#[test]
fn sounds_round_trip_through_the_world() {
    let dir = common::scratch_dir("sound-roundtrip");
    let sounds = common::repo().join("assets").join("sounds");
    let text = format!(
        r#"(
    version: 1,
    name: "sounds",
    environment: (
        ambience: (asset: "{wind}", gain_db: -6.0),
    ),
    entities: [
        (name: "start", player_spawn: (eye_height: 1.6)),
        (
            name: "lamp",
            transform: (translation: (1.0, 2.0, 0.0)),
            sound: (asset: "{hum}"),
        ),
        (
            name: "bell",
            sound: (asset: "{shard}", gain_db: 3.0, looping: false),
        ),
    ],
)
"#,
        wind = sounds.join("wind.wav").display(),
        hum = sounds.join("lamp-hum.wav").display(),
        shard = sounds.join("shard.wav").display(),
    );
    let path = common::write(&dir, "sounds.ron", &text);
    let scene = gloam::scene::Scene::load(&path).unwrap();
    let mut engine =
        gloam::frame::Engine::new(&scene, gloam::render::RenderSettings::real_time(8, 8));
    let mut sources = engine.world.query::<&gloam::game::SoundSource>();
    assert_eq!(sources.iter(&engine.world).count(), 2);
    let level = gloam::game::level_from_world(&mut engine.world);
    assert_eq!(level, scene.level);
    let saved = gloam::scene::level::level_to_string(&level);
    assert_eq!(saved, gloam::scene::level::level_to_string(&scene.level));
    assert_eq!(saved.matches("looping: false").count(), 1, "{saved}");
    assert!(!saved.contains("looping: true") && !saved.contains("gain_db: 0.0"));
    assert_eq!(parse_level(&path, &saved).unwrap(), level);
}
