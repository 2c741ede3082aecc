//! The world lives in the ECS: what is spawned, despawned and changed while the game runs
//! reaches the render scene in the next frame, the same world renders the same image
//! however it came to be, and the world writes back as the level it was loaded from.

mod common;

use bevy_ecs::prelude::*;
use glam::{Quat, Vec3, Vec4};
use gloam::frame::Engine;
use gloam::game::{
    AssetInstance, LevelEntity, PunctualLight, SwitchedOff, Transform, level_from_world, spawn,
};
use gloam::render::{Camera, HdrImage, IntegratorKind, RenderSettings, SamplerKind, render};
use gloam::scene::Scene;
use gloam::scene::level::{
    EntityDef, InstanceDef, LightDef, MaterialOverride, TransformDef, level_to_string, parse_level,
    save_level,
};

fn settings() -> RenderSettings {
    RenderSettings {
        width: 48,
        height: 32,
        spp: 2,
        seed: 11,
        frame: 3,
        integrator: IntegratorKind::Path,
        sampler: SamplerKind::BlueNoise,
        max_depth: 4,
    }
}

fn first_light() -> std::path::PathBuf {
    common::repo().join("levels").join("first-light.ron")
}

/// The engine's scene rendered at `settings()` on `threads` threads.
fn image(engine: &Engine, threads: usize) -> HdrImage {
    let scene = engine.render_scene();
    let camera = Camera::new(&scene.camera, settings().width, settings().height);
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(|| render(scene, &camera, &settings(), &|_| {}).image)
}

/// The root entity of the level entity called `name`.
fn named(engine: &mut Engine, name: &str) -> Entity {
    let mut roots = engine.world.query::<(Entity, &Name, &LevelEntity)>();
    roots
        .iter(&engine.world)
        .find(|(_, n, _)| n.as_str() == name)
        .map(|(e, _, _)| e)
        .unwrap_or_else(|| panic!("no entity {name:?}"))
}

fn crate_def(name: &str, asset: &str, at: Vec3) -> EntityDef {
    let mut def = EntityDef::named(name);
    def.transform.translation = at;
    def.transform.rotation = Vec3::new(0.0, 30.0, 0.0);
    def.instance = Some(InstanceDef {
        asset: asset.to_owned(),
        material_overrides: Default::default(),
    });
    def
}

fn blue_lamp() -> EntityDef {
    let mut lamp = EntityDef::named("blue lamp");
    lamp.transform = TransformDef {
        translation: Vec3::new(-3.0, 2.2, 3.0),
        rotation: Vec3::new(-60.0, 0.0, 0.0),
        ..TransformDef::default()
    };
    lamp.light = Some(LightDef::Spot {
        color: Vec3::new(0.3, 0.5, 1.0),
        intensity: 80.0,
        inner_cone_degrees: 20.0,
        outer_cone_degrees: 35.0,
    });
    lamp
}

fn dark_wood() -> MaterialOverride {
    MaterialOverride {
        base_color: Some(Vec4::new(0.2, 0.1, 0.05, 1.0)),
        emissive: Some(Vec3::new(0.0, 0.4, 0.1)),
        ..MaterialOverride::default()
    }
}

/// Level A (first-light) edited in the ECS into level B, and level B written to disk by
/// hand (its entities in another order), render bit-identically on 1 and 2 threads.
#[test]
fn a_level_edited_into_another_renders_as_that_level_loaded() {
    // B on disk: first-light without "crate hall 2" and "cellar lamp", with "pillar 3" moved,
    // "crate cellar 3" re-materialed (and glowing), the hall's north lamp recoloured, and a new crate
    // and a blue spot lamp, written first in the file.
    let a_path = first_light();
    let a_scene = Scene::load(&a_path).unwrap();
    let kit = common::repo().join("assets").join("kit");
    let mut b_level = a_scene.level.clone();
    if let Some(bed) = &mut b_level.environment.ambience {
        bed.asset = in_repo(&bed.asset);
    }
    for entity in &mut b_level.entities {
        let body = entity.player_spawn.as_mut().and_then(|s| s.body.as_mut());
        for instance in entity.instance.iter_mut().chain(body) {
            instance.asset = kit
                .join(std::path::Path::new(&instance.asset).file_name().unwrap())
                .display()
                .to_string();
        }
        if let Some(sound) = &mut entity.sound {
            sound.asset = in_repo(&sound.asset);
        }
        match entity.name.as_str() {
            "pillar 3" => entity.transform.translation = Vec3::new(-2.5, 0.0, 2.5),
            "crate cellar 3" => {
                let instance = entity.instance.as_mut().unwrap();
                instance
                    .material_overrides
                    .insert("wood".to_owned(), dark_wood());
            }
            "hall lamp north" => {
                entity.light = Some(LightDef::Point {
                    color: Vec3::new(1.0, 0.5, 0.3),
                    intensity: 45.0,
                })
            }
            _ => {}
        }
    }
    b_level
        .entities
        .retain(|e| e.name != "crate hall 2" && e.name != "cellar lamp");
    let crate_file = kit.join("crate.glb").display().to_string();
    b_level.entities.insert(0, blue_lamp());
    b_level.entities.insert(
        5,
        crate_def("crate 4", &crate_file, Vec3::new(-4.0, 0.0, 1.0)),
    );
    let dir = common::scratch_dir("edit-into");
    let b_path = dir.join("b.ron");
    save_level(&b_level, &b_path).unwrap();
    let b_scene = Scene::load(&b_path).unwrap();

    // A, edited in the ECS.
    let mut edited = Engine::new(&a_scene, settings());
    let crate_2 = named(&mut edited, "crate hall 2");
    edited.world.despawn(crate_2);
    let warden_lamp = named(&mut edited, "cellar lamp");
    edited.world.despawn(warden_lamp);
    let pillar = named(&mut edited, "pillar 3");
    edited
        .world
        .get_mut::<Transform>(pillar)
        .unwrap()
        .translation = Vec3::new(-2.5, 0.0, 2.5);
    let crate_3 = named(&mut edited, "crate cellar 3");
    edited
        .world
        .get_mut::<AssetInstance>(crate_3)
        .unwrap()
        .material_overrides
        .insert("wood".to_owned(), dark_wood());
    let hanging = named(&mut edited, "hall lamp north");
    edited.world.get_mut::<PunctualLight>(hanging).unwrap().0 = LightDef::Point {
        color: Vec3::new(1.0, 0.5, 0.3),
        intensity: 45.0,
    };
    spawn(
        &mut edited.world,
        &crate_def(
            "crate 4",
            "../assets/kit/crate.glb",
            Vec3::new(-4.0, 0.0, 1.0),
        ),
    )
    .unwrap();
    spawn(&mut edited.world, &blue_lamp()).unwrap();
    // The clips' clocks back to level start (the pose B loads in), the batches re-formed.
    edited.pose_at(0.0);
    edited.render_state_mut().rebatch();

    let loaded = Engine::new(&b_scene, settings());
    for (what, engine) in [("edited", &edited), ("loaded", &loaded)] {
        let accel = &engine.render_scene().accel;
        assert!(
            accel.batched_instance_count() > accel.instances().len() / 2,
            "{what}: the statics are batched"
        );
    }
    assert_eq!(
        edited.render_scene().lights.lights.len(),
        loaded.render_scene().lights.lights.len()
    );
    for threads in [1, 2] {
        let (a, b) = (image(&edited, threads), image(&loaded, threads));
        assert!(
            a.pixels == b.pixels,
            "{threads} thread(s): the edited level renders differently from the loaded one"
        );
    }
    // And it is a different image from first-light's.
    let original = Engine::new(&a_scene, settings());
    assert!(image(&original, 2).pixels != image(&loaded, 2).pixels);
}

/// A hundred instances and twenty lights spawned in one frame show in it; despawned the
/// next, the image is the one before, bit for bit.
#[test]
fn a_hundred_spawns_despawned_leave_the_image_as_it_was() {
    let scene = Scene::load(&first_light()).unwrap();
    let mut engine = Engine::new(&scene, settings());
    common::pause_animation(&mut engine);
    engine.advance(1.0 / 60.0);
    let instances = engine.render_scene().accel.instances().len();
    let lights = engine.render_scene().lights.lights.len();
    let before = image(&engine, 2);

    let mut spawned = Vec::new();
    for i in 0..100 {
        let at = Vec3::new(-5.0 + (i % 10) as f32, 0.0, -5.0 + (i / 10) as f32);
        let def = crate_def(
            &format!("spawned crate {i:03}"),
            "../assets/kit/crate.glb",
            at,
        );
        spawned.push(spawn(&mut engine.world, &def).unwrap());
    }
    for i in 0..20 {
        let mut lamp = EntityDef::named(format!("spawned lamp {i:02}"));
        lamp.transform.translation = Vec3::new(-5.0 + i as f32 * 0.5, 1.5, 0.0);
        lamp.light = Some(LightDef::Point {
            color: Vec3::new(1.0, 0.8, 0.6),
            intensity: 2.0,
        });
        spawned.push(spawn(&mut engine.world, &lamp).unwrap());
    }
    engine.advance(1.0 / 60.0);
    assert!(engine.render_scene().accel.instances().len() >= instances + 100);
    assert_eq!(engine.render_scene().lights.lights.len(), lights + 20);
    assert!(image(&engine, 2).pixels != before.pixels, "the spawns show");

    for entity in spawned {
        engine.world.despawn(entity);
    }
    engine.advance(1.0 / 60.0);
    assert_eq!(engine.render_scene().accel.instances().len(), instances);
    assert_eq!(engine.render_scene().lights.lights.len(), lights);
    assert!(
        image(&engine, 2).pixels == before.pixels,
        "the image is back as it was"
    );
}

/// Switching a light off takes it out of the light set; an emitter switched off gives no
/// light and renders dark; both come back when switched on.
#[test]
fn lights_and_emitters_switch_off_and_on() {
    let scene = Scene::load(&first_light()).unwrap();
    let mut engine = Engine::new(&scene, settings());
    common::pause_animation(&mut engine);
    engine.advance(1.0 / 60.0);
    let lights = engine.render_scene().lights.lights.len();
    let before = image(&engine, 2);
    // Every lamp of the level (the wardens' lamps stay lit).
    let lamps: Vec<Entity> = engine
        .world
        .query_filtered::<Entity, (With<PunctualLight>, With<gloam::game::LevelEntity>)>()
        .iter(&engine.world)
        .collect();
    assert_eq!(lamps.len(), 5);
    let shard = named(&mut engine, "shard 1");
    for &lamp in &lamps {
        engine.world.entity_mut(lamp).insert(SwitchedOff);
    }
    engine.advance(1.0 / 60.0);
    // The lamps leave the light set, and so do their fixtures' glowing glass triangles.
    let out = engine.render_scene().lights.lights.len();
    assert!(
        out < lights - lamps.len(),
        "the lamps and their fixtures' glass left the light set ({lights} -> {out})"
    );
    engine.world.entity_mut(shard).insert(SwitchedOff);
    engine.advance(1.0 / 60.0);
    let dark = engine.render_scene().lights.lights.len();
    assert!(dark < out, "the shard's emitters left the light set");
    let darker = image(&engine, 2);
    let mean = |film: &HdrImage| film.mean().element_sum();
    assert!(mean(&darker) < mean(&before) * 0.9);
    for &lamp in &lamps {
        engine.world.entity_mut(lamp).remove::<SwitchedOff>();
    }
    engine.world.entity_mut(shard).remove::<SwitchedOff>();
    engine.advance(1.0 / 60.0);
    assert_eq!(engine.render_scene().lights.lights.len(), lights);
    assert!(image(&engine, 2).pixels == before.pixels);
}

/// A punctual light that moves is moved in place, without a new light set.
#[test]
fn a_moving_light_follows_its_entity() {
    let scene = Scene::load(&first_light()).unwrap();
    let mut engine = Engine::new(&scene, settings());
    let lamp = named(&mut engine, "cellar lamp");
    engine.world.get_mut::<Transform>(lamp).unwrap().translation = Vec3::new(1.0, 2.0, 1.0);
    engine.advance(1.0 / 60.0);
    engine.advance(1.0 / 60.0);
    let found = engine.render_scene().lights.lights.iter().any(|light| {
        matches!(light, gloam::render::light::Light::Spot { position, .. }
            if (glam::Vec3::from(*position) - Vec3::new(1.0, 2.0, 1.0)).length() < 1e-5)
    });
    assert!(found, "the spot light stands where its entity does");
}

/// Every shipped level, loaded and written back from the world with no change, is its file
/// byte for byte; an edited world saved and loaded again is the same world.
#[test]
fn the_world_writes_back_as_its_level() {
    let levels = common::shipped_levels();
    for path in &levels {
        let scene = Scene::load(path).unwrap();
        let mut engine = Engine::new(&scene, RenderSettings::real_time(4, 4));
        let saved = level_to_string(&level_from_world(&mut engine.world));
        let text = std::fs::read_to_string(path).unwrap();
        assert!(
            saved == text,
            "{}: saving the world changed the file:\n{saved}",
            path.display()
        );
    }

    // Edits: a rotation by a quaternion (saved as degrees), a spawn, a despawn, a light.
    let scene = Scene::load(&first_light()).unwrap();
    let mut engine = Engine::new(&scene, RenderSettings::real_time(4, 4));
    let pillar = named(&mut engine, "pillar 2");
    let turned = Quat::from_rotation_y(0.3) * Quat::from_rotation_x(-0.2);
    engine.world.get_mut::<Transform>(pillar).unwrap().rotation = turned;
    let crate_1 = named(&mut engine, "crate hall 1");
    engine.world.despawn(crate_1);
    spawn(&mut engine.world, &blue_lamp()).unwrap();
    let level = level_from_world(&mut engine.world);
    assert_eq!(level.entities.last().unwrap().name, "blue lamp");
    assert!(level.entities.iter().all(|e| e.name != "crate hall 1"));
    let dir = common::scratch_dir("write-back");
    let path = dir.join("edited.ron");
    // Saved beside the original's folder layout: asset paths stay relative.
    let mut relocated = level.clone();
    for entity in &mut relocated.entities {
        let body = entity.player_spawn.as_mut().and_then(|s| s.body.as_mut());
        for instance in entity.instance.iter_mut().chain(body) {
            instance.asset = in_repo(&instance.asset);
        }
        if let Some(sound) = &mut entity.sound {
            sound.asset = in_repo(&sound.asset);
        }
    }
    if let Some(bed) = &mut relocated.environment.ambience {
        bed.asset = in_repo(&bed.asset);
    }
    save_level(&relocated, &path).unwrap();
    let reloaded = parse_level(&path, &std::fs::read_to_string(&path).unwrap()).unwrap();
    let pillar_def = reloaded
        .entities
        .iter()
        .find(|e| e.name == "pillar 2")
        .unwrap();
    let angle = pillar_def.transform.rotation_quat().angle_between(turned);
    assert!(
        angle < 1e-5,
        "the saved degrees make the rotation ({angle} rad off)"
    );
    let scene = Scene::load(&path).unwrap();
    let mut again = Engine::new(&scene, RenderSettings::real_time(4, 4));
    let mut resaved = level_from_world(&mut again.world);
    for (entity, original) in resaved.entities.iter_mut().zip(&level.entities) {
        if let (Some(instance), Some(first)) = (&mut entity.instance, &original.instance) {
            instance.asset = first.asset.clone();
        }
        let body = entity.player_spawn.as_mut().and_then(|s| s.body.as_mut());
        let first = original.player_spawn.as_ref().and_then(|s| s.body.as_ref());
        if let (Some(body), Some(first)) = (body, first) {
            body.asset = first.asset.clone();
        }
        if let (Some(sound), Some(first)) = (&mut entity.sound, &original.sound) {
            sound.asset = first.asset.clone();
        }
    }
    resaved.environment.ambience = level.environment.ambience.clone();
    assert_eq!(resaved, level, "save, load, save gives the same level");
}

/// Run-time spawns are checked as a level's entities are.
#[test]
fn a_bad_spawn_is_refused_with_its_place() {
    let scene = Scene::load(&first_light()).unwrap();
    let mut engine = Engine::new(&scene, RenderSettings::real_time(4, 4));
    let mut def = crate_def("bad", "../assets/kit/crate.glb", Vec3::ZERO);
    def.transform.scale = Vec3::new(1.0, 0.0, 1.0);
    let error = spawn(&mut engine.world, &def).unwrap_err().to_string();
    assert!(
        error.contains("spawning 'bad'") && error.contains("/transform/scale"),
        "{error}"
    );
    let missing = crate_def("missing", "../assets/kit/no-such.glb", Vec3::ZERO);
    let error = spawn(&mut engine.world, &missing).unwrap_err().to_string();
    assert!(error.contains("no-such.glb"), "{error}");
}

/// The light set is built anew only when a light or emitter is added, removed, switched or
/// changes power: not for a spawned prop, a moved lamp or a moved emitter.
#[test]
fn the_light_set_is_rebuilt_only_when_the_lights_change() {
    let scene = Scene::load(&first_light()).unwrap();
    let mut engine = Engine::new(&scene, settings());
    common::pause_animation(&mut engine);
    engine.advance(1.0 / 60.0);
    let builds = |engine: &Engine| {
        engine
            .world
            .resource::<gloam::extract::RenderState>()
            .light_set_builds
    };
    let at_load = builds(&engine);
    let crate_4 = spawn(
        &mut engine.world,
        &crate_def(
            "crate 4",
            "../assets/kit/crate.glb",
            Vec3::new(-4.0, 0.0, 1.0),
        ),
    )
    .unwrap();
    engine.advance(1.0 / 60.0);
    let shard = named(&mut engine, "shard 2");
    engine
        .world
        .get_mut::<Transform>(shard)
        .unwrap()
        .translation
        .y += 0.5;
    let lamp = named(&mut engine, "hall lamp north");
    engine
        .world
        .get_mut::<Transform>(lamp)
        .unwrap()
        .translation
        .x += 0.5;
    engine.advance(1.0 / 60.0);
    engine.world.despawn(crate_4);
    engine.advance(1.0 / 60.0);
    assert_eq!(builds(&engine), at_load, "a prop and moves keep the set");
    // The moved shard's emitters went with it, as a new set would have them.
    let kept = engine.render_scene().lights.lights.clone();
    engine.render_state_mut().rebatch();
    let lamp_light = engine.world.get::<PunctualLight>(lamp).unwrap().0.clone();
    engine.world.get_mut::<PunctualLight>(lamp).unwrap().0 = lamp_light;
    engine.advance(1.0 / 60.0);
    assert_eq!(builds(&engine), at_load + 1, "a touched light builds a set");
    assert_eq!(
        format!("{kept:?}"),
        format!("{:?}", engine.render_scene().lights.lights),
        "the kept set had every light where a new one puts it"
    );
    spawn(&mut engine.world, &blue_lamp()).unwrap();
    engine.advance(1.0 / 60.0);
    assert_eq!(builds(&engine), at_load + 2, "a new lamp builds a set");
}

/// A shipped level's path (relative to levels/) made absolute, for a copy saved
/// elsewhere.
fn in_repo(asset: &str) -> String {
    common::repo()
        .join("levels")
        .join(asset)
        .display()
        .to_string()
}
