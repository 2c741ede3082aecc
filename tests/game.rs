//! The headless game loop: the ECS places things where the static loader does, frames
//! accumulate into the same image a multi-sample render gives, and any change restarts it.

mod common;

use bevy_ecs::prelude::{Entity, With};
use glam::Vec3;
use gloam::extract::{RenderState, instance_entity};
use gloam::frame::Engine;
use gloam::game::{GlobalTransform, LevelEntity, MeshNode, PunctualLight, SwitchedOff, Transform};
use gloam::render::{Camera, IntegratorKind, RenderSettings, SamplerKind, render};
use gloam::scene::world::Scene;

fn settings(spp: u32) -> RenderSettings {
    RenderSettings {
        width: 24,
        height: 16,
        spp,
        seed: 3,
        frame: 0,
        integrator: IntegratorKind::Path,
        sampler: SamplerKind::White,
        max_depth: 4,
    }
}

fn level(name: &str) -> Scene {
    Scene::load(&common::repo().join("levels").join(name)).unwrap()
}

/// The level entity (index in the level file) whose asset an accel instance draws.
fn level_entity_of(engine: &Engine, user_id: u64) -> Option<usize> {
    let node = engine.world.get::<MeshNode>(instance_entity(user_id)?)?;
    engine.world.get::<LevelEntity>(node.root).map(|e| e.0)
}

/// Lifts the level entity `name` by a metre; returns its index in the level.
fn lift(engine: &mut Engine, scene: &Scene, name: &str) -> usize {
    let entity = scene
        .level
        .entities
        .iter()
        .position(|e| e.name == name)
        .unwrap();
    let mut roots = engine.world.query::<(&LevelEntity, &mut Transform)>();
    for (level_entity, mut transform) in roots.iter_mut(&mut engine.world) {
        if level_entity.0 == entity {
            transform.translation += Vec3::Y;
        }
    }
    entity
}

#[test]
fn propagated_transforms_match_the_static_placements() {
    for name in ["first-light.ron", "cornell.ron"] {
        let mut engine = Engine::new(&level(name), settings(1));
        let mut query = engine
            .world
            .query::<(Entity, &MeshNode, &GlobalTransform)>();
        let placed: Vec<(Entity, GlobalTransform)> =
            query.iter(&engine.world).map(|(e, _, g)| (e, *g)).collect();
        let state = engine.world.resource::<RenderState>();
        let placed: Vec<(u32, GlobalTransform)> = placed
            .into_iter()
            .map(|(entity, global)| (state.instance_of(entity).expect("drawn"), global))
            .collect();
        assert_eq!(
            placed.len(),
            state.scene.accel.instances().len(),
            "{name}: every instance has an entity"
        );
        for (instance, global) in placed {
            let expected = state.scene.accel.instances()[instance as usize].world_from_object();
            assert!(
                global.0.abs_diff_eq(expected, 1e-5),
                "{name}: instance {instance}: {global:?} vs {expected:?}"
            );
        }
    }
}

#[test]
fn still_frames_accumulate_into_the_multi_sample_image() {
    let scene = level("cornell.ron");
    let mut engine = Engine::new(&scene, settings(1));
    for _ in 0..4 {
        engine.advance(0.0);
    }
    assert_eq!(engine.film.frames, 4);
    // Four frames of one white-noise sample each are the four samples of a 4-spp render.
    let render_scene = gloam::frame::render_scene(&scene);
    let camera = Camera::new(&render_scene.camera, 24, 16);
    let four = render(&render_scene, &camera, &settings(4), &|_| {}).image;
    let accumulated = engine.image();
    let worst = four
        .pixels
        .iter()
        .zip(&accumulated.pixels)
        .map(|(a, b)| (*a - *b).abs().max_element())
        .fold(0.0, f32::max);
    // The view is rebuilt from the ECS transform, so rays differ in the last bits.
    assert!(
        worst < 1e-3,
        "accumulated frames differ from a 4-spp render by {worst}"
    );
}

#[test]
fn moving_an_entity_restarts_accumulation_and_moves_its_geometry() {
    let scene = level("first-light.ron");
    let mut engine = Engine::new(&scene, settings(1));
    common::pause_animation(&mut engine);
    engine.advance(0.0);
    engine.advance(0.0);
    assert_eq!(engine.film.frames, 2);
    let before = engine.image();

    // Lift "pillar 1" (level entity) by a metre.
    let pillar = lift(&mut engine, &scene, "pillar 1");
    // Rendering interpolates between the last two steps: the step that moves the pillar
    // shows it where it was (alpha 0); the next one shows it lifted.
    engine.advance(1.0 / 60.0);
    assert_eq!(engine.film.frames, 3);
    engine.advance(1.0 / 60.0);
    assert_eq!(engine.film.frames, 1, "a change restarts accumulation");
    assert_ne!(engine.image(), before);

    // The pillar's instance moved with it, and the TLAS knows.
    let state = engine.world.resource::<RenderState>();
    let moved = state
        .scene
        .accel
        .instances()
        .iter()
        .find(|i| level_entity_of(&engine, i.user_id) == Some(pillar))
        .expect("pillar instance");
    assert!((moved.world_from_object().translation.y - 1.0).abs() < 1e-6);
    let ray = gloam::accel::Ray::new(glam::Vec3A::new(-2.0, 3.5, 5.0), glam::Vec3A::NEG_Z);
    let hit =
        state
            .scene
            .accel
            .intersect(&ray, gloam::accel::InstanceMask::ALL, &gloam::accel::Opaque);
    assert_eq!(
        hit.and_then(|h| {
            level_entity_of(
                &engine,
                state.scene.accel.instances()[h.instance as usize].user_id,
            )
        }),
        Some(pillar),
        "the lifted pillar now reaches y = 3.5"
    );
}

/// first-light, its animation paused, through the game's filter (as the window shows it).
fn filtered_first_light() -> (Scene, Engine) {
    let scene = level("first-light.ron");
    let mut engine = Engine::new(&scene, settings(1));
    common::pause_animation(&mut engine);
    engine.film.filter.mode = gloam::film::FilterMode::Full;
    (scene, engine)
}

#[test]
fn filtered_frames_draw_new_samples_while_the_world_moves_and_keep_a_radiance_cache() {
    let (scene, mut engine) = filtered_first_light();
    engine.advance(0.0);
    let mut seen = vec![engine.film.sample_frame()];
    // A change every frame restarts the sum each time, but the filter's frames must not
    // draw the same samples (and jitters) again.
    for _ in 0..3 {
        lift(&mut engine, &scene, "pillar 1");
        engine.advance(1.0 / 60.0);
        seen.push(engine.film.sample_frame());
    }
    assert!(engine.film.frames < 4, "the changes restarted the sum");
    assert_eq!(seen, [1, 2, 3, 4]);
    assert!(
        engine.film.radiance_cache().is_some(),
        "filtered frames keep a cache"
    );
    // Summing still frames, the sequence starts again with the sum.
    engine.film.filter.mode = gloam::film::FilterMode::Off;
    lift(&mut engine, &scene, "pillar 1");
    engine.advance(1.0 / 60.0);
    engine.advance(1.0 / 60.0);
    assert_eq!(engine.film.sample_frame(), engine.film.frames);
    assert!(engine.film.frames <= 1);
    // What the cache learnt would be stale when the filter comes back on.
    assert!(engine.film.radiance_cache().is_none());
}

/// The game's filtered frames, the radiance cache learning each frame in the background
/// (on the pool, while the next frame's simulation runs), are the same bits on one thread
/// as on two, and the cache ends paths once its cells have learnt.
#[test]
fn filtered_frames_with_the_cache_learning_in_the_background_are_the_same_on_any_thread_count() {
    let frames = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                let (_, mut engine) = filtered_first_light();
                let mut ended = 0;
                for _ in 0..40 {
                    engine.advance(1.0 / 60.0);
                    ended += engine.stage_times().cache_ended;
                }
                (engine.image().pixels, ended)
            })
    };
    let (one, ended) = frames(1);
    let (two, ended_on_two) = frames(2);
    assert!(one == two, "the 40th filtered frame differs on two threads");
    assert_eq!(ended, ended_on_two);
    assert!(ended > 0, "the cache ended no path in 40 frames");
}

#[test]
fn a_doused_lamp_sends_the_radiance_cache_back_to_learning_the_lights() {
    let (scene, mut engine) = filtered_first_light();
    // Things moving do not: only a new light set does.
    for _ in 0..3 {
        lift(&mut engine, &scene, "pillar 1");
        engine.advance(1.0 / 60.0);
    }
    let relearning = |engine: &mut Engine| {
        (engine.film.radiance_cache())
            .expect("filtered frames keep a cache")
            .relearning()
    };
    assert!(!relearning(&mut engine));
    let lamp = engine
        .world
        .query_filtered::<Entity, (With<PunctualLight>, With<LevelEntity>)>()
        .iter(&engine.world)
        .next()
        .expect("first-light has lamps");
    engine.world.entity_mut(lamp).insert(SwitchedOff);
    engine.advance(1.0 / 60.0);
    assert!(relearning(&mut engine));
}

#[test]
fn the_simulation_runs_at_a_fixed_sixty_hertz() {
    let mut engine = Engine::new(
        &level("cornell.ron"),
        RenderSettings {
            width: 4,
            height: 4,
            ..settings(1)
        },
    );
    engine.advance(0.05); // 3 steps owed
    assert_eq!(engine.steps, 3);
    engine.advance(0.01); // 0.01 carried: 0.6 of a step
    assert_eq!(engine.steps, 3);
    engine.advance(0.01); // 1.2 steps owed
    assert_eq!(engine.steps, 4);
    engine.advance(1.0);
    assert_eq!(engine.steps, 64);
}

#[test]
fn rendering_interpolates_between_simulation_steps() {
    let scene = level("first-light.ron");
    let mut engine = Engine::new(
        &scene,
        RenderSettings {
            width: 4,
            height: 4,
            ..settings(1)
        },
    );
    let pillar = scene
        .level
        .entities
        .iter()
        .position(|e| e.name == "pillar 2")
        .unwrap();
    let mut roots = engine.world.query::<(&LevelEntity, &mut Transform)>();
    for (level_entity, mut transform) in roots.iter_mut(&mut engine.world) {
        if level_entity.0 == pillar {
            transform.translation.y += 1.0;
        }
    }
    let height = |engine: &Engine| {
        let state = engine.world.resource::<RenderState>();
        state
            .scene
            .accel
            .instances()
            .iter()
            .find(|i| level_entity_of(engine, i.user_id) == Some(pillar))
            .unwrap()
            .world_from_object()
            .translation
            .y
    };
    engine.advance(1.0 / 60.0); // the step that moves it: shown where it was
    assert!(height(&engine).abs() < 1e-6);
    engine.advance(0.5 / 60.0); // half-way into the next step
    assert!((height(&engine) - 0.5).abs() < 1e-4, "{}", height(&engine));
    engine.advance(0.5 / 60.0); // the next step: where the simulation put it
    assert!((height(&engine) - 1.0).abs() < 1e-6);
}

#[test]
fn static_batches_last_through_play_and_dissolve_when_a_member_moves() {
    let scene = level("first-light.ron");
    let mut engine = Engine::new(&scene, settings(1));
    let batched = |engine: &Engine| {
        engine
            .world
            .resource::<RenderState>()
            .scene
            .accel
            .batched_instance_count()
    };
    let at_load = batched(&engine);
    let instances = engine
        .world
        .resource::<RenderState>()
        .scene
        .accel
        .instances()
        .len();
    assert!(
        at_load >= instances / 2,
        "walls, floors and pillars are batched ({at_load} of {instances})"
    );
    // The wardens walk; nothing static moves, so the batch stays.
    for _ in 0..6 {
        engine.advance(1.0 / 60.0);
    }
    assert_eq!(batched(&engine), at_load, "playing moved nothing static");

    // The editor drags a pillar: its batch dissolves and every member is traced alone.
    lift(&mut engine, &scene, "pillar 1");
    engine.advance(1.0 / 60.0);
    engine.advance(1.0 / 60.0);
    assert_eq!(batched(&engine), 0, "the moved pillar's batch is gone");
    // Batching again takes the pillar where it now stands.
    engine.render_state_mut().rebatch();
    assert_eq!(batched(&engine), at_load);
}
