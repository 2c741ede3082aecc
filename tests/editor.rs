//! The level editor's commands, headless, as the editor's window drives them: select by
//! ray, move, duplicate, delete, undo and redo, save (byte-identical with no edit, the old
//! file kept as .bak) and a failed save that loses nothing.

mod common;

use std::path::{Path, PathBuf};

use glam::{Vec3, Vec3A};
use gloam::accel::Ray;
use gloam::edit::{Editor, Reloaded, autosave_path, backup_path};
use gloam::frame::Engine;
use gloam::game::level_io::entity_defs;
use gloam::render::RenderSettings;
use gloam::scene::Scene;
use gloam::scene::level::{EntityDef, MaterialOverride};

/// first-light copied into a scratch `levels/` beside the real `assets/` (its asset paths
/// are relative), loaded into an engine.
fn open_first_light(test: &str) -> (PathBuf, String, Engine) {
    let dir = common::scratch_dir(test);
    let levels = dir.join("levels");
    std::fs::create_dir_all(&levels).unwrap();
    let original = std::fs::read_to_string(common::repo().join("levels/first-light.ron")).unwrap();
    let text = original.replace(
        "\"../assets/",
        &format!("\"{}/assets/", common::repo().display()),
    );
    let path = levels.join("first-light.ron");
    std::fs::write(&path, &text).unwrap();
    let scene = Scene::load(&path).unwrap();
    let engine = Engine::new(&scene, RenderSettings::real_time(32, 18));
    (path, text, engine)
}

fn defs(engine: &mut Engine) -> Vec<EntityDef> {
    entity_defs(&mut engine.world)
        .into_iter()
        .map(|(_, def)| def)
        .collect()
}

fn named(engine: &mut Engine, name: &str) -> Option<EntityDef> {
    defs(engine).into_iter().find(|def| def.name == name)
}

/// A ray straight down onto the point (x, z) from `height` metres.
fn down_onto(x: f32, z: f32, height: f32) -> Ray {
    Ray::new(Vec3A::new(x, height, z), Vec3A::NEG_Y)
}

fn saved_text(editor: &mut Editor, engine: &mut Engine, path: &Path) -> String {
    editor.save(engine, path).unwrap();
    std::fs::read_to_string(path).unwrap()
}

#[test]
fn select_move_duplicate_delete_and_undo_them_all() {
    let (path, text, mut engine) = open_first_light("editor-commands");
    let mut editor = Editor::new();
    assert!(!editor.is_dirty());

    // A click on "crate hall 1" (at -3.2, 0, -3.2) selects it.
    let crate_ray = down_onto(-3.2, -3.2, 2.0);
    let picked = editor.select_by_ray(&mut engine, &crate_ray, false);
    assert!(picked.is_some());
    assert_eq!(editor.selection.len(), 1);
    // Shift+click on "crate hall 2" adds it; Shift+click on it again takes it out.
    let other = editor.select_by_ray(&mut engine, &down_onto(3.2, 2.0, 2.0), true);
    assert!(other.is_some() && other != picked);
    assert_eq!(editor.selection, [picked.unwrap(), other.unwrap()]);
    editor.select_by_ray(&mut engine, &down_onto(3.2, 2.0, 2.0), true);
    assert_eq!(editor.selection, [picked.unwrap()]);
    let before = named(&mut engine, "crate hall 1").unwrap();

    // Move it one metre east: one step, dirty.
    editor.translate(&mut engine, Vec3::X).unwrap();
    let moved = named(&mut engine, "crate hall 1").unwrap();
    assert_eq!(
        moved.transform.translation,
        before.transform.translation + Vec3::X
    );
    assert!(editor.is_dirty());
    // The pick follows the crate: it is now under x = -2.2, not -3.2.
    let mut probe = Editor::new();
    assert_eq!(
        probe.select_by_ray(&mut engine, &down_onto(-2.2, -3.2, 2.0), false),
        picked
    );

    // Duplicate: a copy with every component under a new name, selected.
    editor.duplicate(&mut engine).unwrap();
    let copy = named(&mut engine, "crate hall 1 2").expect("the copy");
    assert_eq!(
        EntityDef {
            name: moved.name.clone(),
            ..copy.clone()
        },
        moved
    );
    assert_eq!(editor.selection.len(), 1);
    assert_ne!(Some(editor.selection[0]), picked);

    // Delete the copy, then the original.
    editor.delete(&mut engine).unwrap();
    assert!(named(&mut engine, "crate hall 1 2").is_none());
    editor.selection = vec![picked.unwrap()];
    editor.delete(&mut engine).unwrap();
    assert!(named(&mut engine, "crate hall 1").is_none());
    let under = editor.select_by_ray(&mut engine, &down_onto(-2.2, -3.2, 2.0), false);
    assert!(
        under.is_some() && under != picked,
        "the floor is hit there now"
    );
    editor.selection.clear();

    // Undo all four steps: the crate is back with all its components at its old place in
    // the level, and the level saves as the file it was.
    for _ in 0..4 {
        assert!(editor.undo(&mut engine).unwrap());
    }
    assert!(!editor.undo(&mut engine).unwrap(), "nothing more to undo");
    assert_eq!(named(&mut engine, "crate hall 1").unwrap(), before);
    assert!(!editor.is_dirty(), "back to the loaded state");
    assert_eq!(saved_text(&mut editor, &mut engine, &path), text);

    // Redo the move: the crate moves again, and the level is dirty again.
    assert!(editor.redo(&mut engine).unwrap());
    assert_eq!(named(&mut engine, "crate hall 1").unwrap(), moved);
    assert!(editor.is_dirty());
}

#[test]
fn saving_keeps_the_old_file_and_a_failed_save_loses_nothing() {
    let (path, text, mut engine) = open_first_light("editor-save");
    let mut editor = Editor::new();

    // Load then save with no edit: the same bytes, the old file kept as .bak.
    assert_eq!(saved_text(&mut editor, &mut engine, &path), text);
    assert_eq!(
        backup_path(&path),
        path.with_file_name("first-light.ron.bak")
    );
    assert_eq!(std::fs::read_to_string(backup_path(&path)).unwrap(), text);

    // An edit, saved: the file has it, the .bak the version before.
    editor.selection = vec![entity_defs(&mut engine.world)[0].0];
    editor
        .translate(&mut engine, Vec3::new(0.0, 0.0, 0.5))
        .unwrap();
    assert!(editor.is_dirty());
    let edited = saved_text(&mut editor, &mut engine, &path);
    assert_ne!(edited, text);
    assert!(!editor.is_dirty());
    assert_eq!(std::fs::read_to_string(backup_path(&path)).unwrap(), text);
    // What was saved loads back as the same level.
    let reloaded = Scene::load(&path).unwrap();
    let mut again = Engine::new(&reloaded, RenderSettings::real_time(32, 18));
    assert_eq!(defs(&mut again), defs(&mut engine));

    // A save that cannot be written (a file stands where its folder should be) says why
    // and changes nothing: not the old file, not the world, not the dirty marker.
    editor
        .translate(&mut engine, Vec3::new(0.0, 0.0, 0.5))
        .unwrap();
    let blocked = path.parent().unwrap().join("blocked");
    std::fs::write(&blocked, "a file, not a folder").unwrap();
    let error = editor
        .save(&mut engine, &blocked.join("first-light.ron"))
        .unwrap_err();
    assert!(format!("{error:#}").contains("blocked"), "{error:#}");
    assert!(editor.is_dirty());
    assert_eq!(std::fs::read_to_string(&path).unwrap(), edited);
    assert_eq!(
        std::fs::read_to_string(&blocked).unwrap(),
        "a file, not a folder"
    );
    // The edits are still there to save elsewhere.
    let elsewhere = path.with_file_name("rescued.ron");
    let rescued = saved_text(&mut editor, &mut engine, &elsewhere);
    assert_ne!(rescued, edited);
    assert!(
        !backup_path(&elsewhere).exists(),
        "nothing was there to keep"
    );
}

#[test]
fn reloading_an_unchanged_file_keeps_everything_and_a_broken_one_changes_nothing() {
    let (path, text, mut engine) = open_first_light("editor-reload");
    let mut editor = Editor::new();
    // Unchanged on disk: the world, the selection and the history stay.
    editor.selection = vec![entity_defs(&mut engine.world)[0].0];
    editor.translate(&mut engine, Vec3::X).unwrap();
    editor.save(&mut engine, &path).unwrap();
    let saved = std::fs::read_to_string(&path).unwrap();
    assert_eq!(
        editor.reload(&mut engine, &path).unwrap(),
        Reloaded::Unchanged
    );
    assert!(editor.can_undo() && !editor.selection.is_empty());

    // Broken on disk: an error with the place, and the world as it was.
    let before = defs(&mut engine);
    std::fs::write(
        &path,
        saved.replacen("name: \"First light\"", "name: First light", 1),
    )
    .unwrap();
    let error = format!("{:#}", editor.reload(&mut engine, &path).unwrap_err());
    assert!(error.contains("first-light.ron:"), "{error}");
    assert_eq!(defs(&mut engine), before);

    // Changed on disk (the file as it first was): the world is the file's level now, with
    // a clean history, and saving it again gives the file back.
    std::fs::write(&path, &text).unwrap();
    assert_eq!(
        editor.reload(&mut engine, &path).unwrap(),
        Reloaded::Replaced
    );
    assert!(!editor.can_undo() && !editor.is_dirty() && editor.selection.is_empty());
    assert_eq!(saved_text(&mut editor, &mut engine, &path), text);
}

#[test]
fn autosave_writes_unsaved_edits_beside_the_file_and_leaves_it_alone() {
    let (path, text, mut engine) = open_first_light("editor-autosave");
    let mut editor = Editor::new();
    let autosave = autosave_path(&path);
    assert_eq!(autosave, path.with_file_name(".first-light.ron.autosave"));
    assert!(
        !editor.autosave(&mut engine, &path).unwrap(),
        "nothing unsaved"
    );
    assert!(!autosave.exists());

    editor.selection = vec![entity_defs(&mut engine.world)[0].0];
    editor.translate(&mut engine, Vec3::Z).unwrap();
    assert!(editor.autosave(&mut engine, &path).unwrap());
    assert_eq!(
        std::fs::read_to_string(&path).unwrap(),
        text,
        "the level file is untouched"
    );
    assert!(editor.is_dirty(), "an autosave is not a save");
    // The autosave is the edited level.
    let recovered = std::fs::read_to_string(&autosave).unwrap();
    let level = gloam::scene::level::parse_level(&autosave, &recovered).unwrap();
    assert_eq!(level, gloam::game::level_from_world(&mut engine.world));
}

#[test]
fn a_drag_is_one_step_and_the_palette_places_where_the_click_meets_the_floor() {
    let (path, text, mut engine) = open_first_light("editor-drag");
    let mut editor = Editor::new();
    editor.select_by_ray(&mut engine, &down_onto(-3.2, -3.2, 2.0), false);
    let before = named(&mut engine, "crate hall 1").unwrap();

    // A gizmo drag: the world follows every frame of it, and letting go records one step.
    for step in 1..=5 {
        editor
            .drag(&mut engine, |def| {
                def.transform.translation =
                    before.transform.translation + Vec3::X * step as f32 * 0.25;
            })
            .unwrap();
        let now = named(&mut engine, "crate hall 1").unwrap();
        assert_eq!(
            now.transform.translation.x,
            before.transform.translation.x + step as f32 * 0.25
        );
        assert!(editor.is_dirty(), "a drag under way is unsaved");
        assert!(!editor.can_undo(), "nothing recorded until the drag ends");
    }
    editor.end_drag();
    assert!(editor.can_undo());
    assert!(editor.undo(&mut engine).unwrap());
    assert_eq!(
        named(&mut engine, "crate hall 1").unwrap(),
        before,
        "one undo undoes the drag"
    );
    assert!(!editor.can_undo());
    assert!(!editor.is_dirty());
    // A drag that ends where it began records nothing.
    editor.redo(&mut engine).unwrap();
    editor.undo(&mut engine).unwrap();
    editor.selection = vec![editor.selection[0]];
    editor
        .drag(&mut engine, |def| def.transform.translation += Vec3::Y)
        .unwrap();
    editor
        .drag(&mut engine, |def| def.transform.translation -= Vec3::Y)
        .unwrap();
    editor.end_drag();
    assert!(!editor.can_undo() && !editor.is_dirty());

    // The palette: a shard placed where a ray down at (1, 1) meets the level, under the
    // shard prefab's name made unique ("shard" is free in first-light; a second is
    // "shard 2"), selected; both undo away and the file saves as it was.
    let assets = gloam::edit::palette::assets_folder(&path);
    assert!(
        assets.join("kit/shard.glb").is_file(),
        "{}",
        assets.display()
    );
    for expected in ["shard", "shard 2"] {
        let at = gloam::edit::surface_point(&engine, &down_onto(1.0, 1.0, 2.5)).expect("the floor");
        assert!(
            (at.x - 1.0).abs() < 1e-4 && (at.z - 1.0).abs() < 1e-4 && at.y >= 0.0,
            "{at}"
        );
        let def = gloam::edit::palette::Prefab::Shard.def(at, &path, &assets);
        let place = editor.place(&mut engine, def).unwrap();
        assert_eq!(editor.selection, [place]);
        let placed = named(&mut engine, expected).expect("placed");
        assert!(placed.shard.is_some() && placed.instance.is_some());
    }
    // The level with the shards saves and loads (the asset path is relative to the level).
    let elsewhere = path.with_file_name("with-shards.ron");
    editor.save(&mut engine, &elsewhere).unwrap();
    let reloaded = Scene::load(&elsewhere).unwrap();
    assert_eq!(
        reloaded
            .level
            .entities
            .iter()
            .filter(|e| e.shard.is_some())
            .count(),
        5
    );
    editor.undo(&mut engine).unwrap();
    editor.undo(&mut engine).unwrap();
    assert_eq!(saved_text(&mut editor, &mut engine, &path), text);
}

#[test]
fn a_changed_asset_is_imported_again_in_place_and_a_broken_one_changes_nothing() {
    let (path, _, mut engine) = open_first_light("editor-assets");
    // The level's crates come from a copy of the kit's crate beside the scratch level.
    let scratch_crate = path.with_file_name("crate.glb");
    let kit_crate = common::repo().join("assets/kit/crate.glb");
    std::fs::copy(&kit_crate, &scratch_crate).unwrap();
    let mut editor = Editor::new();
    editor.select_by_ray(&mut engine, &down_onto(-3.2, -3.2, 2.0), false);
    editor
        .modify(&mut engine, |def| {
            def.instance.as_mut().unwrap().asset = "crate.glb".to_owned();
        })
        .unwrap();
    let steps_before = editor.can_undo();
    let crate_top = |engine: &Engine| {
        gloam::edit::surface_point(engine, &down_onto(-3.2, -3.2, 5.0))
            .unwrap()
            .y
    };
    let before = crate_top(&engine);

    // The file changes on disk into a taller asset (the kit's bookcase): the entity is
    // respawned from it where it stands, and the history is untouched.
    std::fs::copy(
        common::repo().join("assets/kit/bookcase.glb"),
        &scratch_crate,
    )
    .unwrap();
    let respawned = editor
        .reload_assets(&mut engine, std::slice::from_ref(&scratch_crate))
        .unwrap();
    assert_eq!(respawned, 1);
    let after = crate_top(&engine);
    assert!(after > before + 0.5, "{before} -> {after}");
    assert_eq!(editor.can_undo(), steps_before);
    assert_eq!(
        named(&mut engine, "crate hall 1")
            .unwrap()
            .instance
            .unwrap()
            .asset,
        "crate.glb"
    );

    // A broken file: an error naming it, and the world as it was.
    std::fs::write(&scratch_crate, b"glTF not really").unwrap();
    let error = editor
        .reload_assets(&mut engine, std::slice::from_ref(&scratch_crate))
        .unwrap_err();
    assert!(format!("{error:#}").contains("crate.glb"), "{error:#}");
    assert_eq!(crate_top(&engine), after);
}

/// The inspector's material overrides: one the level did not have is added to an instance
/// (a floor tile made to glow red), reaches the renderer's materials and its light set and
/// is written to the file; undo takes it away, and the level saves as the file it was.
#[test]
fn a_new_material_override_reaches_the_renderer_and_the_file_and_undoes() {
    let (path, text, mut engine) = open_first_light("editor-materials");
    let mut editor = Editor::new();
    let (tile, _) = entity_defs(&mut engine.world)
        .into_iter()
        .find(|(_, def)| def.name == "floor 22")
        .unwrap();
    editor.select(tile, false);
    let glow = Vec3::new(4.7, 0.0, 0.0);
    let glows = |engine: &Engine| {
        engine
            .render_scene()
            .materials
            .iter()
            .any(|material| material.emissive == glow)
    };
    let lights_before = engine.render_scene().lights.lights.len();
    assert!(!glows(&engine));

    editor
        .modify(&mut engine, |def| {
            let change = MaterialOverride {
                emissive: Some(glow),
                ..MaterialOverride::default()
            };
            let instance = def.instance.as_mut().unwrap();
            instance
                .material_overrides
                .insert("flagstones".to_owned(), change);
        })
        .unwrap();
    assert!(glows(&engine), "the renderer's materials have the override");
    assert!(
        engine.render_scene().lights.lights.len() > lights_before,
        "the glowing tile is a light"
    );
    let saved = saved_text(&mut editor, &mut engine, &path);
    assert!(saved.contains("\"flagstones\": (\n"), "{saved}");
    assert!(saved.contains("emissive: (4.7, 0.0, 0.0),"), "{saved}");

    assert!(editor.undo(&mut engine).unwrap());
    assert!(!glows(&engine));
    assert_eq!(saved_text(&mut editor, &mut engine, &path), text);
}

/// The play-check (F6): the bot plays the level as edited on a thread of its own and
/// answers whether it can be finished unseen; the answer belongs to the level it checked,
/// so an edit made since marks it out of date; a way out no one can walk to has no route.
#[test]
fn the_play_check_plays_the_level_as_edited_and_knows_when_it_is_out_of_date() {
    use gloam::edit::play_check::PlayCheck;
    use gloam::headless::autoplay::RunOutcome;

    let (path, _, mut engine) = open_first_light("play-check");
    let mut level = gloam::game::level_from_world(&mut engine.world);
    // Without its wardens the bot has nothing to wait for: a quick check.
    level.entities.retain(|entity| entity.warden.is_none());
    let mut check = PlayCheck::default();
    let started = check.start(level.clone(), &path);
    assert!(started.contains("playing the level as edited"), "{started}");
    assert!(check.status(&level).0.starts_with("playing..."));
    let again = check.start(level.clone(), &path);
    assert!(again.contains("already playing"), "{again}");
    let line = check.wait().expect("an answer");
    let checked = check.checked().expect("the bot ran");
    assert!(checked.proven(), "{line}");
    assert!(line.starts_with("play-check: won unseen in "), "{line}");
    assert!(checked.route.len() > 60, "a route walked: {line}");
    let (status, stale) = check.status(&level);
    assert!(status.starts_with("won unseen in "), "{status}");
    assert!(!stale);
    let mut edited = level.clone();
    edited.entities[0].transform.translation.x += 1.0;
    let (status, stale) = check.status(&edited);
    assert!(stale && status.ends_with("(edited since)"), "{status}");

    // The way out moved where no floor reaches.
    let exit = edited
        .entities
        .iter_mut()
        .find(|e| e.exit.is_some())
        .unwrap();
    exit.transform.translation = Vec3::new(100.0, 0.0, 100.0);
    check.start(edited.clone(), &path);
    let line = check.wait().expect("an answer");
    let checked = check.checked().expect("the bot ran");
    assert_eq!(checked.outcome, RunOutcome::NoRoute, "{line}");
    assert!(line.contains("cannot be reached on foot"), "{line}");
    assert!(check.status(&edited).0.starts_with("no unseen route"));

    // A level that does not load says why, and keeps nothing of the last answer.
    let mut broken = edited.clone();
    broken.entities[0].instance = Some(gloam::scene::level::InstanceDef {
        asset: "../assets/no-such-asset.glb".into(),
        material_overrides: Default::default(),
    });
    check.start(broken.clone(), &path);
    let line = check.wait().expect("an answer");
    assert!(line.contains("no-such-asset.glb"), "{line}");
    assert!(check.checked().is_none());
    assert!(check.status(&broken).0.starts_with("could not play: "));
}

/// `gloam edit --new` and File > New: the template is a level that loads, is unsaved until
/// the first save writes it where asked (its assets named relative to it), passes the same
/// load `gloam check` makes, and is won by the bot; an existing file or a missing folder is
/// refused, naming the path.
#[test]
fn a_new_level_starts_from_a_template_the_bot_wins_and_saves_where_it_was_asked() {
    use gloam::edit::template::new_scene;
    use gloam::headless::autoplay::{RunOutcome, autoplay};

    let dir = common::scratch_dir("new-level");
    let path = dir.join("cellar-2.ron");
    let scene = new_scene(&path).expect("a template for a new file");
    assert!(!path.exists(), "nothing is written before the first save");
    assert_eq!(scene.level.name, "Cellar 2");
    let kinds =
        |has: fn(&EntityDef) -> bool| scene.level.entities.iter().filter(|e| has(e)).count();
    assert_eq!(kinds(|e| e.player_spawn.is_some()), 1);
    assert_eq!(kinds(|e| e.exit.is_some()), 1);
    assert_eq!(kinds(|e| e.light.is_some()), 1);
    assert!(
        kinds(|e| e.instance.is_some()) >= 4 + 8,
        "floor tiles and walls"
    );

    let mut engine = Engine::new(&scene, RenderSettings::real_time(32, 18));
    let mut editor = Editor::unsaved();
    assert!(editor.is_dirty(), "a new level is unsaved until saved");
    let text = saved_text(&mut editor, &mut engine, &path);
    assert!(!editor.is_dirty());
    assert!(text.contains("kit/wall.glb\""), "{text}");
    assert!(
        !text.contains(&format!("\"{}", common::repo().display())),
        "assets are named relative to the level: {text}"
    );
    let loaded = Scene::load(&path).expect("the saved template loads as `gloam check` loads it");
    assert_eq!(loaded.level, scene.level);

    let run = autoplay(&loaded, 60.0).expect("the bot plays it");
    assert_eq!(run.outcome, RunOutcome::Won, "{}", run.why);
    assert_eq!(run.times_seen, 0);

    let refused = new_scene(&path)
        .expect_err("the file exists now")
        .to_string();
    assert!(
        refused.contains("cellar-2.ron") && refused.contains("already exists"),
        "{refused}"
    );
    let nowhere = dir.join("no-such-folder").join("x.ron");
    let refused = new_scene(&nowhere)
        .expect_err("no folder to save to")
        .to_string();
    assert!(
        refused.contains("no-such-folder") && refused.contains("does not exist"),
        "{refused}"
    );
}

/// The level's own properties (the inspector with nothing selected): a run of edits is one
/// step, the render's sky follows at once, the file says what was set, and undo puts the
/// level back to its file byte for byte.
#[test]
fn the_level_properties_are_one_step_lit_by_the_new_sky_saved_and_undone() {
    use gloam::edit::LevelProperties;

    let (path, text, mut engine) = open_first_light("level-properties");
    let mut editor = Editor::new();
    let original = LevelProperties::of(&engine.world);
    assert_eq!(original.name, "First light");
    assert_eq!(original.campaign, Some(1));

    let mut edited = original.clone();
    for name in ["F", "Fi", "First dark"] {
        edited.name = name.to_owned();
        editor.drag_properties(&mut engine, edited.clone());
    }
    edited.campaign = Some(7);
    edited.environment.sky = Vec3::new(0.1, 0.2, 0.3);
    edited.environment.ambience = None;
    editor.drag_properties(&mut engine, edited.clone());
    assert!(editor.is_dirty());
    editor.end_drag();
    assert_eq!(LevelProperties::of(&engine.world), edited);
    engine.advance(0.0);
    assert_eq!(engine.render_scene().sky, Vec3::new(0.1, 0.2, 0.3));

    let saved = saved_text(&mut editor, &mut engine, &path);
    assert!(saved.contains("name: \"First dark\""), "{saved}");
    assert!(saved.contains("campaign: 7"), "{saved}");
    assert!(saved.contains("sky: (0.1, 0.2, 0.3)"), "{saved}");
    assert!(
        !saved.contains("wind.wav"),
        "the ambience was taken out: {saved}"
    );
    assert_eq!(Scene::load(&path).unwrap().level.name, "First dark");

    assert!(editor.undo(&mut engine).unwrap(), "the edits were one step");
    assert_eq!(LevelProperties::of(&engine.world), original);
    assert!(!editor.can_undo(), "the edits were one step");
    assert_eq!(saved_text(&mut editor, &mut engine, &path), text);
    assert!(editor.redo(&mut engine).unwrap());
    assert_eq!(LevelProperties::of(&engine.world), edited);
}

/// An autosave newer than its level (the editor closed before a save) is found on opening,
/// loads as the level it kept, and when the designer keeps the file instead it is moved
/// aside rather than left to be written over; one older than the file is not offered.
#[test]
fn an_autosave_newer_than_its_level_is_offered_back_and_neither_is_lost() {
    use gloam::edit::{keep_autosave_aside, load_autosave, newer_autosave};

    let (path, text, mut engine) = open_first_light("autosave-offer");
    assert_eq!(newer_autosave(&path), None, "no autosave yet");
    // The file, saved an hour ago.
    let hour_ago = std::time::SystemTime::now() - std::time::Duration::from_secs(3600);
    std::fs::File::options()
        .write(true)
        .open(&path)
        .unwrap()
        .set_modified(hour_ago)
        .unwrap();
    let mut editor = Editor::new();
    editor.select_by_ray(&mut engine, &down_onto(-10.0, -6.0, 5.0), false);
    editor
        .translate(&mut engine, Vec3::new(0.0, 0.0, 1.0))
        .unwrap();
    assert!(editor.autosave(&mut engine, &path).unwrap());
    let edited = gloam::game::level_from_world(&mut engine.world);

    let offered = newer_autosave(&path).expect("the autosave is newer than the file");
    assert_eq!(offered, autosave_path(&path));
    let scene = load_autosave(&path).unwrap();
    assert_eq!(
        scene.level, edited,
        "the autosave loads as the level it kept"
    );
    assert_eq!(
        std::fs::read_to_string(&path).unwrap(),
        text,
        "the file is untouched"
    );

    let kept = keep_autosave_aside(&path).unwrap();
    assert!(
        kept.to_string_lossy()
            .ends_with(".first-light.ron.autosave-1"),
        "{kept:?}"
    );
    assert!(load_autosave(&path).is_err(), "nothing left to load");
    assert_eq!(
        newer_autosave(&path),
        None,
        "moved aside, not offered again"
    );
    assert!(kept.is_file());
    // A second one goes beside the first.
    assert!(editor.autosave(&mut engine, &path).unwrap());
    assert!(
        keep_autosave_aside(&path)
            .unwrap()
            .to_string_lossy()
            .ends_with("autosave-2")
    );

    // Saved since: the autosave is older than the file and stays unoffered.
    assert!(editor.autosave(&mut engine, &path).unwrap());
    std::thread::sleep(std::time::Duration::from_millis(20));
    editor.save(&mut engine, &path).unwrap();
    assert_eq!(newer_autosave(&path), None);
}

/// Swapping an instance's asset (the inspector's asset choice) keeps what the new asset
/// has and drops the material overrides and animation it has not, so the level still loads.
#[test]
fn a_swapped_asset_keeps_only_the_overrides_and_clip_it_has_and_the_level_loads() {
    let (path, _, mut engine) = open_first_light("asset-swap");
    let mut editor = Editor::new();
    let mut def = named(&mut engine, "way out lamp bracket").expect("the bracket");
    let overrides = |def: &EntityDef| {
        def.instance
            .as_ref()
            .unwrap()
            .material_overrides
            .keys()
            .cloned()
            .collect::<Vec<_>>()
    };
    assert_eq!(overrides(&def), ["lantern glass"]);
    let kit = def
        .instance
        .as_ref()
        .unwrap()
        .asset
        .replace("lamp-bracket.glb", "");

    // Onto the warden: no lantern glass of that name, a walk clip to keep.
    def.instance.as_mut().unwrap().asset = format!("{kit}warden.glb");
    def.animation = Some(gloam::scene::level::AnimationDef {
        clip: "walk".into(),
        playback: Default::default(),
        speed: 1.0,
        start: 0.0,
    });
    gloam::edit::fit_to_asset(&mut engine, &mut def).unwrap();
    assert_eq!(overrides(&def), Vec::<String>::new());
    assert_eq!(
        def.animation.as_ref().map(|a| a.clip.as_str()),
        Some("walk")
    );
    // Onto a crate: no clips.
    def.instance.as_mut().unwrap().asset = format!("{kit}crate.glb");
    gloam::edit::fit_to_asset(&mut engine, &mut def).unwrap();
    assert_eq!(def.animation, None);
    // A file that is not there is the error, the definition untouched.
    let mut missing = def.clone();
    missing.instance.as_mut().unwrap().asset = format!("{kit}no-such.glb");
    let error = gloam::edit::fit_to_asset(&mut engine, &mut missing).unwrap_err();
    assert!(format!("{error:#}").contains("no-such.glb"), "{error:#}");
    assert_eq!(
        missing.instance.as_ref().unwrap().asset,
        format!("{kit}no-such.glb")
    );

    let place = entity_defs(&mut engine.world)
        .into_iter()
        .find(|(_, d)| d.name == "way out lamp bracket")
        .unwrap()
        .0;
    editor.select(place, false);
    editor
        .modify(&mut engine, |entity| *entity = def.clone())
        .unwrap();
    let saved = saved_text(&mut editor, &mut engine, &path);
    assert!(saved.contains("kit/crate.glb"), "{saved}");
    Scene::load(&path).expect("the level loads with the swapped asset");
}

/// Copy and paste between two levels in different folders, as the system clipboard carries
/// it (level text): the assets still resolve, a second paste numbers the names and the
/// pasted lamp's fixture follows its bracket's new name, and text that is no level changes
/// nothing.
#[test]
fn entities_copied_from_one_level_paste_into_another_and_still_load() {
    let (source, _, mut engine) = open_first_light("copy-paste");
    let mut editor = Editor::new();
    let places: Vec<_> = entity_defs(&mut engine.world)
        .into_iter()
        .filter(|(_, def)| def.name.starts_with("way out lamp"))
        .map(|(place, _)| place)
        .collect();
    assert_eq!(places.len(), 2, "the lamp and its bracket");
    for place in &places {
        editor.select(*place, true);
    }
    let text = editor
        .copy(&mut engine, &source)
        .expect("a selection to copy");
    assert!(text.contains("lamp-bracket.glb"), "{text}");

    let other = common::scratch_dir("copy-paste-target").join("attic.ron");
    let scene = gloam::edit::template::new_scene(&other).unwrap();
    let mut target = Engine::new(&scene, RenderSettings::real_time(32, 18));
    let mut pasting = Editor::unsaved();
    assert_eq!(pasting.paste(&mut target, &other, &text).unwrap(), 2);
    assert_eq!(pasting.selection.len(), 2);
    assert_eq!(pasting.paste(&mut target, &other, &text).unwrap(), 2);
    let lamp = named(&mut target, "way out lamp 2").expect("the second paste, renamed");
    assert_eq!(lamp.fixture.as_deref(), Some("way out lamp bracket 2"));
    assert_eq!(
        named(&mut target, "way out lamp")
            .unwrap()
            .fixture
            .as_deref(),
        Some("way out lamp bracket")
    );
    let saved = saved_text(&mut pasting, &mut target, &other);
    assert!(
        !saved.contains(&format!("\"{}", common::repo().display())),
        "relative: {saved}"
    );
    let loaded = Scene::load(&other).expect("the level with pasted entities loads");
    assert_eq!(loaded.level.entities.len(), scene.level.entities.len() + 4);

    let before = defs(&mut target);
    let error = pasting
        .paste(&mut target, &other, "not a level")
        .unwrap_err();
    assert!(format!("{error:#}").contains("the clipboard"), "{error:#}");
    assert_eq!(defs(&mut target), before);
    assert!(pasting.undo(&mut target).unwrap());
    assert_eq!(
        defs(&mut target).len(),
        before.len() - 2,
        "a paste is one step"
    );
}

/// The outline's groups (kinds first, then the asset each entity instances) and its search,
/// and a box's selection.
#[test]
fn the_outline_groups_by_kind_and_asset_and_its_search_filters_names() {
    use gloam::edit::outline_groups;

    let (_, _, mut engine) = open_first_light("outline");
    let defs = entity_defs(&mut engine.world);
    let groups = outline_groups(&defs, "");
    let names: Vec<&str> = groups.iter().map(|(name, _)| name.as_str()).collect();
    assert_eq!(
        &names[..5],
        ["player start", "ways out", "wardens", "shards", "lights"],
        "{names:?}"
    );
    assert!(
        names.contains(&"floor") && names.contains(&"wall"),
        "{names:?}"
    );
    let count: usize = groups.iter().map(|(_, members)| members.len()).sum();
    assert_eq!(count, defs.len(), "every entity once");
    let lights = &groups.iter().find(|(name, _)| name == "lights").unwrap().1;
    assert!(lights.iter().all(|(_, def)| def.light.is_some()));

    let found = outline_groups(&defs, "LAMP");
    assert!(!found.is_empty());
    for (_, members) in &found {
        assert!(
            members
                .iter()
                .all(|(_, def)| def.name.to_lowercase().contains("lamp"))
        );
    }
    assert!(outline_groups(&defs, "no such name").is_empty());

    let mut editor = Editor::new();
    let lamps: Vec<_> = lights.iter().map(|(place, _)| *place).collect();
    editor.select_many(&lamps[..2], false);
    editor.select_many(&lamps[1..], true);
    assert_eq!(
        editor.selection, lamps,
        "a box adds what is not in the selection yet"
    );
    editor.select_many(&lamps[..1], false);
    assert_eq!(editor.selection, lamps[..1]);
}

/// The editor's hide and lock: a hidden entity leaves the render (and picking) and comes
/// back, a locked one still draws but clicks in the view pass through it; neither reaches
/// the file, and an edit that respawns the entity gets its mark again on the next call.
#[test]
fn hidden_entities_leave_the_view_and_locked_ones_let_clicks_through_without_touching_the_file() {
    use gloam::edit::mark_entities;

    let (path, text, mut engine) = open_first_light("hide-lock");
    let mut editor = Editor::new();
    let ray = down_onto(-10.0, -6.0, 5.0);
    let floor = editor
        .select_by_ray(&mut engine, &ray, false)
        .expect("a floor tile");
    let instances = |engine: &mut Engine| engine.render_scene().accel.instances().len();
    let all = instances(&mut engine);

    assert!(mark_entities(&mut engine, &[floor], &[]));
    engine.advance(0.0);
    assert!(instances(&mut engine) < all, "the hidden tile is not drawn");
    assert_ne!(editor.select_by_ray(&mut engine, &ray, false), Some(floor));
    assert!(!mark_entities(&mut engine, &[floor], &[]), "already marked");

    assert!(mark_entities(&mut engine, &[], &[floor]));
    engine.advance(0.0);
    assert_eq!(instances(&mut engine), all, "a locked tile still draws");
    assert_ne!(
        editor.select_by_ray(&mut engine, &ray, false),
        Some(floor),
        "clicks pass through"
    );

    // An edit respawns the tile without its mark; marking again puts it back.
    editor.select(floor, false);
    editor
        .translate(&mut engine, Vec3::new(0.0, 0.0, 0.0))
        .unwrap();
    editor
        .translate(&mut engine, Vec3::new(0.0, 0.5, 0.0))
        .unwrap();
    mark_entities(&mut engine, &[], &[floor]);
    engine.advance(0.0);
    let lifted = down_onto(-10.0, -6.0, 5.0);
    assert_ne!(
        editor.select_by_ray(&mut engine, &lifted, false),
        Some(floor)
    );

    assert!(mark_entities(&mut engine, &[], &[]));
    engine.advance(0.0);
    assert_eq!(
        editor.select_by_ray(&mut engine, &lifted, false),
        Some(floor)
    );
    editor.undo(&mut engine).unwrap();
    assert_eq!(
        saved_text(&mut editor, &mut engine, &path),
        text,
        "no mark reaches the file"
    );
}

/// The palette's thumbnails: rendered once and then read from the cache; an edit to the
/// glTF or to a buffer it names is a new picture; a cache file that does not decode is
/// rendered again and replaced; a broken asset says why, and the background worker sends
/// every asset's answer and says what they cost.
#[test]
fn thumbnails_are_rendered_once_cached_by_content_and_a_broken_asset_says_why() {
    use gloam::edit::thumbnails::{Origin, SIZE, Thumbnails, cache_name, thumbnail};

    let dir = common::scratch_dir("thumbnails");
    let cache = dir.join("cache");
    let kit = common::repo().join("assets/kit");
    let asset = dir.join("piece.glb");
    std::fs::copy(kit.join("crate.glb"), &asset).unwrap();

    let (first, origin) = thumbnail(&asset, Some(&cache)).expect("the crate renders");
    assert_eq!(origin, Origin::Rendered);
    assert_eq!((first.width, first.height), (SIZE, SIZE));
    let file = cache.join(cache_name(&asset).unwrap());
    assert!(file.exists(), "kept in the cache");
    let (again, origin) = thumbnail(&asset, Some(&cache)).unwrap();
    assert_eq!(origin, Origin::Cache);
    assert_eq!(again, first, "the cache gives back the very picture");

    // Another asset under the same name: a new key, a new picture.
    std::fs::copy(kit.join("barrel.glb"), &asset).unwrap();
    assert_ne!(cache.join(cache_name(&asset).unwrap()), file);
    let (barrel, origin) = thumbnail(&asset, Some(&cache)).unwrap();
    assert_eq!(origin, Origin::Rendered);
    assert_ne!(barrel, first);

    // A cache file that is not a picture is rendered again and replaced.
    let barrel_file = cache.join(cache_name(&asset).unwrap());
    std::fs::write(&barrel_file, b"not a png").unwrap();
    let (mended, origin) = thumbnail(&asset, Some(&cache)).unwrap();
    assert_eq!((origin, &mended), (Origin::Rendered, &barrel));
    assert_eq!(thumbnail(&asset, Some(&cache)).unwrap().1, Origin::Cache);

    // A .gltf's key covers the buffer file it names.
    let cornell = dir.join("cornell");
    std::fs::create_dir_all(&cornell).unwrap();
    for file in ["cornell-box.gltf", "cornell-box.bin"] {
        std::fs::copy(
            common::repo().join("assets/cornell").join(file),
            cornell.join(file),
        )
        .unwrap();
    }
    let gltf = cornell.join("cornell-box.gltf");
    let before = cache_name(&gltf).unwrap();
    let mut buffer = std::fs::read(cornell.join("cornell-box.bin")).unwrap();
    buffer[0] ^= 1;
    std::fs::write(cornell.join("cornell-box.bin"), buffer).unwrap();
    assert_ne!(
        cache_name(&gltf).unwrap(),
        before,
        "the buffer is part of the key"
    );

    let broken = common::write(&dir, "broken.glb", b"glTF but not really");
    let problem = thumbnail(&broken, Some(&cache)).expect_err("nothing to picture");
    assert!(format!("{problem:#}").contains("broken.glb"), "{problem:#}");

    // The worker: every asset's answer, the cached first, then what it cost.
    let mut worker = Thumbnails::start(vec![broken.clone(), asset.clone()], Some(cache.clone()));
    let mut arrived = Vec::new();
    let started = std::time::Instant::now();
    while worker.pending() && started.elapsed().as_secs() < 60 {
        arrived.extend(worker.poll());
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    assert_eq!(arrived.len(), 2);
    assert_eq!(arrived[0].0, asset, "the cached one comes first");
    assert_eq!(arrived[0].1.as_ref().ok(), Some(&barrel));
    assert!(matches!(&arrived[1].1, Err(problem) if problem.contains("broken.glb")));
    let summary = worker.summary().expect("all arrived");
    assert!(summary.starts_with("2 assets in "), "{summary}");
    assert!(
        summary.ends_with("(0 rendered, 1 from the cache, 1 without one)"),
        "{summary}"
    );
}

/// A designer's whole day, headless, as the window's commands run it: a new level from the
/// template; a warden from the palette, placed on the snap grid, whose first beat stops
/// short of the wall it was placed against, and a shard in the dark corner; the audibility
/// overlay hears a sprint near the warden and not across the room, and only on floor the
/// player reaches; the play-check proves the level can be finished unseen; the save is the
/// level that reopens.
#[test]
fn a_whole_day_from_a_new_file_to_a_level_proven_fair() {
    use gloam::edit::audibility::{NoiseKind, compute};
    use gloam::edit::palette::Prefab;
    use gloam::edit::play_check::PlayCheck;
    use gloam::edit::template::new_scene;
    use gloam::edit::{first_beat, level_point, placing_point, prefab_def};

    let dir = common::scratch_dir("whole-day");
    let path = dir.join("levels").join("vault.ron");
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    let scene = new_scene(&path).expect("a new level");
    let mut engine = Engine::new(&scene, RenderSettings::real_time(32, 18));
    let mut editor = Editor::unsaved();

    // A click from above lands on the floor; the warden's beat is fitted to the room.
    let mut place = |engine: &mut Engine, prefab: Prefab, x: f32, z: f32| {
        // Snapping is on: the click lands on the 0.25 m grid.
        let at = placing_point(engine, &down_onto(x, z, 10.0), Some(0.25)).expect("the floor");
        assert!(at.y.abs() < 0.05, "on the floor: {at}");
        for (on, clicked) in [(at.x, x), (at.z, z)] {
            assert!((on * 4.0 - (on * 4.0).round()).abs() < 1e-4 && (on - clicked).abs() <= 0.125);
        }
        editor
            .place(engine, prefab_def(engine, prefab, at, &path))
            .expect("placed");
        at
    };
    // Against the north wall (its face at z = -4): no room to the north, so the beat runs
    // south, the whole 4 m.
    let at = place(&mut engine, Prefab::Warden, 2.45, -3.17);
    let warden = named(&mut engine, "warden")
        .expect("the warden")
        .warden
        .unwrap();
    assert_eq!(warden.route.len(), 2);
    assert!(
        (warden.route[0] - (at + Vec3::new(0.0, 0.0, 4.0))).length() < 1e-3,
        "{:?}",
        warden.route
    );
    // No beat runs through a wall: from the feet to each end, nothing at chest height.
    for end in &warden.route {
        let reach = *end - at;
        if reach.length() > 0.0 {
            // Past the warden's own body.
            let mut ray = Ray::new(Vec3A::from(at + Vec3::Y), Vec3A::from(reach.normalize()));
            ray.t_min = 0.5;
            let free =
                level_point(&engine, &ray).map_or(f32::INFINITY, |hit| hit.distance(at + Vec3::Y));
            assert!(free > reach.length(), "{end} is behind a wall");
        }
    }
    // In the middle of the room no way has the whole beat: the roomiest stops 0.6 m short
    // of the wall 4 m off.
    let middle = first_beat(&engine, Vec3::ZERO);
    assert!((middle[0].length() - 3.4).abs() < 0.05, "{middle:?}");
    place(&mut engine, Prefab::Shard, -2.43, -2.47);

    // The audibility overlay: a sprint beside the warden is heard, one in the far corner
    // behind the start is not.
    let level = gloam::game::level_from_world(&mut engine.world);
    let edited = Scene::from_level(level.clone(), &path).expect("the edited level loads");
    let heard = compute(&edited, 0.0, NoiseKind::Sprint).expect("a warden to hear");
    assert_eq!(heard.wardens.len(), 1);
    let near = |place: Vec3, to: Vec3| (place - to).with_y(0.0).length() < 1.0;
    assert!(heard.heard.iter().any(|(place, _, _)| near(*place, at)));
    let far = Vec3::new(-3.5, 0.0, 3.5);
    assert!(!heard.heard.iter().any(|(place, _, _)| near(*place, far)));
    // Only where the player can walk: the room's floor, not the tops of its 3 m walls.
    assert!(heard.heard.iter().all(|(place, _, _)| place.y.abs() < 0.5));

    // The play-check: won unseen, with the shard.
    let mut check = PlayCheck::default();
    check.start(level.clone(), &path);
    let line = check.wait().expect("an answer");
    assert!(check.checked().expect("the bot ran").proven(), "{line}");

    // Save, reopen: the level as edited.
    let text = saved_text(&mut editor, &mut engine, &path);
    assert!(
        text.contains("\"warden\"") && text.contains("\"shard\""),
        "{text}"
    );
    let reopened = Scene::load(&path).expect("the saved level loads");
    assert_eq!(reopened.level, level);
}
