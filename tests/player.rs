//! The player's body in the real level: it stands on the floor, walls stop it and it slides
//! along them, it steps up a kerb but not a wall, it jumps half a metre, a long fall never
//! passes through the floor, noclip flies through walls, and the same inputs give the same
//! walk at any frame rate.

mod common;

use bevy_ecs::prelude::*;
use glam::Vec3;
use gloam::frame::Engine;
use gloam::game::{Action, Input, Player, Transform, spawn, spawn_player};
use gloam::render::RenderSettings;
use gloam::scene::Scene;
use gloam::scene::level::{EntityDef, InstanceDef};

const STEP: f64 = 1.0 / 60.0;

/// Where first-light's player starts (facing -Z), in its south-west room.
const START: Vec3 = Vec3::new(-10.0, 0.0, 6.5);

/// first-light with the player at its start and its wardens off their beats (standing
/// where they start, seeing nothing), so only the body does what a test does.
fn level() -> (Engine, Entity) {
    let (mut engine, player) = level_with_wardens();
    common::pause_animation(&mut engine);
    (engine, player)
}

/// first-light as it plays, with the player at its start.
fn level_with_wardens() -> (Engine, Entity) {
    let scene = Scene::load(&common::repo().join("levels").join("first-light.ron")).unwrap();
    let mut engine = Engine::new(&scene, RenderSettings::real_time(8, 8));
    let player = spawn_player(&mut engine.world).expect("first-light has a player start");
    assert_eq!(feet(&engine, player), START);
    (engine, player)
}

fn feet(engine: &Engine, player: Entity) -> Vec3 {
    engine.world.get::<Transform>(player).unwrap().translation
}

/// Puts the player's feet at `at`.
fn place(engine: &mut Engine, player: Entity, at: Vec3) {
    engine
        .world
        .get_mut::<Transform>(player)
        .unwrap()
        .translation = at;
}

fn state(engine: &Engine, player: Entity) -> Player {
    engine.world.get::<Player>(player).unwrap().clone()
}

/// Runs `seconds` of fixed steps (no rendering) with `held` held.
fn hold(engine: &mut Engine, held: &[Action], seconds: f64) {
    engine.world.resource_mut::<Input>().held = held.iter().copied().collect();
    for _ in 0..(seconds / STEP).round() as usize {
        engine.prepare(STEP);
    }
    engine.world.resource_mut::<Input>().held.clear();
}

/// A 2 x 2 m block `height` tall whose near edge is 0.5 m ahead of the start.
fn block(engine: &mut Engine, height: f32) {
    let mut def = EntityDef::named(format!("block {height}"));
    def.transform.translation = START - Vec3::Z * 1.5;
    def.transform.scale = Vec3::new(2.0, height, 2.0);
    def.instance = Some(InstanceDef {
        asset: "../assets/kit/crate.glb".into(),
        material_overrides: Default::default(),
    });
    spawn(&mut engine.world, &def).unwrap();
}

#[test]
fn the_player_stands_on_the_floor_and_a_wall_stops_it() {
    let (mut engine, player) = level();
    hold(&mut engine, &[], 1.0);
    let standing = feet(&engine, player);
    assert!(standing.y.abs() < 0.01, "stands on the floor: {standing}");
    assert!(state(&engine, player).grounded);
    // Backwards (+Z) into the south wall, whose inner face is at z = 8.0.
    hold(&mut engine, &[Action::MoveBack], 3.0);
    let stopped = feet(&engine, player);
    assert!(
        (stopped.z - 7.7).abs() < 0.02,
        "the capsule (radius 0.3) stops at the wall: {stopped}"
    );
    assert!(stopped.y.abs() < 0.01, "{stopped}");
    // Back and to the right: it slides along the wall.
    hold(&mut engine, &[Action::MoveBack, Action::MoveRight], 1.0);
    let slid = feet(&engine, player);
    assert!(
        slid.x > stopped.x + 0.5,
        "slides along the wall: {stopped} -> {slid}"
    );
    assert!(slid.z < 7.71, "{slid}");
}

#[test]
fn it_steps_up_a_kerb_but_not_onto_a_crate() {
    let (mut engine, player) = level();
    block(&mut engine, 0.25);
    hold(&mut engine, &[], 0.5);
    hold(&mut engine, &[Action::MoveForward], 1.5);
    let on_kerb = feet(&engine, player);
    assert!(on_kerb.z < START.z - 1.0, "walked on: {on_kerb}");
    assert!(
        (on_kerb.y - 0.25).abs() < 0.02,
        "stepped up onto the kerb: {on_kerb}"
    );

    let (mut engine, player) = level();
    block(&mut engine, 0.5);
    hold(&mut engine, &[], 0.5);
    hold(&mut engine, &[Action::MoveForward], 1.5);
    let blocked = feet(&engine, player);
    assert!(
        blocked.y.abs() < 0.01,
        "a 0.5 m crate is no step: {blocked}"
    );
    assert!(
        (blocked.z - (START.z - 0.2)).abs() < 0.05,
        "stopped at its edge: {blocked}"
    );
}

#[test]
fn a_jump_rises_half_a_metre_and_lands() {
    let (mut engine, player) = level();
    hold(&mut engine, &[], 0.5);
    engine
        .world
        .resource_mut::<Input>()
        .pressed
        .insert(Action::MoveUp);
    let mut highest: f32 = 0.0;
    for _ in 0..90 {
        engine.prepare(STEP);
        highest = highest.max(feet(&engine, player).y);
    }
    assert!((highest - 0.5).abs() < 0.05, "apex {highest}");
    assert!(feet(&engine, player).y.abs() < 0.01);
    assert!(state(&engine, player).grounded);
}

#[test]
fn a_long_fall_never_passes_through_the_floor() {
    let (mut engine, player) = level();
    place(&mut engine, player, Vec3::new(1.0, 40.0, 1.0));
    hold(&mut engine, &[], 5.0);
    let landed = feet(&engine, player);
    assert!(landed.y.abs() < 0.01, "landed on the floor: {landed}");
}

#[test]
fn crouching_lowers_the_body_and_noclip_passes_walls() {
    let (mut engine, player) = level();
    hold(&mut engine, &[Action::MoveDown], 1.0);
    let crouched = state(&engine, player);
    assert!(
        crouched.crouched && (crouched.eye - 1.0).abs() < 0.01,
        "{crouched:?}"
    );
    hold(&mut engine, &[], 1.0);
    assert!(!state(&engine, player).crouched, "stands again");

    engine
        .world
        .resource_mut::<Input>()
        .pressed
        .insert(Action::Noclip);
    hold(&mut engine, &[Action::MoveBack], 1.5);
    assert!(feet(&engine, player).z > 8.5, "flew through the south wall");
}

#[test]
fn the_same_inputs_walk_the_same_way_at_any_frame_rate() {
    let script = [
        (&[Action::MoveForward][..], 0.5),
        (
            &[Action::MoveForward, Action::MoveLeft, Action::Sprint][..],
            1.0,
        ),
        (&[Action::MoveBack, Action::MoveDown][..], 0.5),
    ];
    let mut ends = Vec::new();
    for frame in [STEP, 2.0 * STEP, 0.5 * STEP] {
        let (mut engine, player) = level();
        for (held, seconds) in script {
            engine.world.resource_mut::<Input>().held = held.iter().copied().collect();
            let frames = (seconds / frame).round() as usize;
            for _ in 0..frames {
                engine.advance(frame);
            }
        }
        ends.push((feet(&engine, player), gem(&engine, player)));
    }
    assert!(ends.windows(2).all(|w| w[0] == w[1]), "{ends:?}");
}

/// Under the hall's north lamp (a spot light 2.58 m up, under its hanging lantern).
const HALL_LAMP_POOL: Vec3 = Vec3::new(0.0, 0.0, -4.0);

fn gem(engine: &Engine, player: Entity) -> f32 {
    engine
        .world
        .get::<gloam::game::Exposure>(player)
        .unwrap()
        .gem
}

#[test]
fn the_light_gem_rises_in_a_lamp_pool_and_falls_in_the_dark() {
    let (mut engine, player) = level();
    // The start, far from the lamps: dark (the night sky, little else), hidden.
    hold(&mut engine, &[], 1.0);
    let dark = gem(&engine, player);
    assert!(
        dark < gloam::game::exposure::curve::HIDDEN,
        "the start: {dark}"
    );
    // Under the hall's north lamp.
    place(&mut engine, player, HALL_LAMP_POOL);
    let mut last = dark;
    let mut steps = Vec::new();
    for _ in 0..60 {
        engine.prepare(STEP);
        let now = gem(&engine, player);
        steps.push(now - last);
        last = now;
    }
    assert!(last > 0.85, "the lamp's pool: {last}");
    // Smoothed: no step jumps more than a sixth of the way (time constant 0.1 s).
    assert!(steps.iter().all(|&d| (0.0..0.16).contains(&d)), "{steps:?}");
    // The lamp doused: mostly dark again (the other lamps and the shards still reach).
    let lamp = {
        let mut named = engine.world.query::<(Entity, &Name)>();
        named
            .iter(&engine.world)
            .find(|(_, n)| n.as_str() == "hall lamp north")
            .unwrap()
            .0
    };
    engine
        .world
        .entity_mut(lamp)
        .insert(gloam::game::SwitchedOff);
    hold(&mut engine, &[], 1.0);
    let doused = gem(&engine, player);
    assert!(doused < 0.4, "the lamp off: {doused}");
}

#[test]
fn a_shadow_the_player_can_see_hides_them() {
    let (mut engine, player) = level();
    place(&mut engine, player, HALL_LAMP_POOL);
    hold(&mut engine, &[], 1.0);
    let lit = gem(&engine, player);
    // A board hung between the lamp (2.58 m up) and the player.
    let mut board = EntityDef::named("board");
    board.transform.translation = HALL_LAMP_POOL + Vec3::Y * 2.4;
    board.transform.scale = Vec3::new(2.0, 0.05, 2.0);
    board.instance = Some(InstanceDef {
        asset: "../assets/kit/crate.glb".into(),
        material_overrides: Default::default(),
    });
    spawn(&mut engine.world, &board).unwrap();
    hold(&mut engine, &[], 1.0);
    let shaded = gem(&engine, player);
    assert!(
        shaded < lit - 0.3,
        "the board's shadow hides the player: {lit} -> {shaded}"
    );
}

#[test]
fn taking_every_shard_and_reaching_the_exit_wins() {
    use gloam::game::{Outcome, Progress, Shard};
    let (mut engine, player) = level();
    engine.advance(STEP);
    let shards = |engine: &mut Engine| {
        engine
            .world
            .query_filtered::<(), With<Shard>>()
            .iter(&engine.world)
            .count()
    };
    assert_eq!(shards(&mut engine), 3);
    let emitters = engine.render_scene().lights.lights.len();
    // The exit does nothing while shards are left.
    hold(&mut engine, &[], 0.2);
    assert_eq!(
        engine.world.resource::<Progress>().outcome,
        Outcome::Running
    );
    for (x, z) in [(-10.8, -6.8), (0.0, -7.3), (11.0, 7.0)] {
        place(&mut engine, player, Vec3::new(x, 0.0, z));
        hold(&mut engine, &[], 0.1);
    }
    assert_eq!(shards(&mut engine), 0, "every shard taken");
    assert_eq!(engine.world.resource::<Progress>().shards_taken, 3);
    engine.advance(STEP);
    assert!(
        engine.render_scene().lights.lights.len() < emitters,
        "their glow went with them"
    );
    // Back to the way out.
    place(&mut engine, player, Vec3::new(10.0, 0.0, -7.3));
    hold(&mut engine, &[], 0.1);
    let progress = engine.world.resource::<Progress>().clone();
    assert_eq!(progress.outcome, Outcome::Won);
    // Over: the body no longer takes input, and the clock has stopped.
    let at = feet(&engine, player);
    hold(&mut engine, &[Action::MoveForward], 0.5);
    assert_eq!(feet(&engine, player), at);
    assert_eq!(engine.world.resource::<Progress>().steps, progress.steps);
}

#[test]
fn wardens_walk_their_routes_carrying_their_lamps() {
    use gloam::game::{Warden, WardenLampLight};
    let (mut engine, _) = level_with_wardens();
    let warden_1 = {
        let mut named = engine.world.query::<(Entity, &Name, &Warden)>();
        named
            .iter(&engine.world)
            .find(|(_, n, _)| n.as_str() == "warden 1")
            .unwrap()
            .0
    };
    let start = feet(&engine, warden_1);
    hold(&mut engine, &[], 1.0);
    let walked = feet(&engine, warden_1);
    // 1.2 m/s towards (0, 0, 5.2), south.
    assert!(
        (walked.z - (start.z + 1.2)).abs() < 0.02,
        "{start} -> {walked}"
    );
    assert!((walked.x - start.x).abs() < 1e-4);
    // Facing where it walks (+Z is a yaw of 0), from north turned at most 180 degrees a
    // second.
    let warden = engine.world.get::<Warden>(warden_1).unwrap().clone();
    assert!(warden.yaw.abs() < 0.05, "{}", warden.yaw);
    // Round the route: at (0, 0, 5.2), 11.2 m on, it turns back north.
    hold(&mut engine, &[], 9.0);
    assert_eq!(engine.world.get::<Warden>(warden_1).unwrap().next, 1);
    // Its lamp moves with it, in the renderer's light set too.
    engine.advance(STEP);
    let lamp = {
        let mut lamps = engine
            .world
            .query_filtered::<(&gloam::game::GlobalTransform, &ChildOf), With<WardenLampLight>>();
        lamps
            .iter(&engine.world)
            .find(|(_, parent)| parent.parent() == warden_1)
            .unwrap()
            .0
            .0
            .translation
    };
    let body = feet(&engine, warden_1);
    assert!(
        (Vec3::from(lamp) - body).length() < 1.5,
        "{lamp:?} near {body}"
    );
    let shown = engine.render_scene().lights.lights.iter().any(|light| {
        matches!(light, gloam::render::light::Light::Spot { position, .. }
            if (*position - lamp).length() < 0.1)
    });
    assert!(shown, "the lamp is a light the renderer draws");
}

#[test]
fn the_body_is_hidden_from_its_own_eyes_but_casts_a_shadow() {
    use gloam::accel::{InstanceMask, Opaque, Ray};
    let (mut engine, player) = level();
    place(&mut engine, player, HALL_LAMP_POOL);
    hold(&mut engine, &[], 0.5);
    engine.advance(STEP);
    // Its meshes are instances for shadow and bounce rays, not camera rays.
    let mut nodes = engine.world.query::<(Entity, &gloam::game::MeshNode)>();
    let body_nodes: Vec<Entity> = nodes
        .iter(&engine.world)
        .filter(|(_, node)| {
            engine
                .world
                .get::<gloam::game::PlayerBody>(node.root)
                .is_some()
        })
        .map(|(entity, _)| entity)
        .collect();
    assert!(
        !body_nodes.is_empty(),
        "first-light gives the player a body"
    );
    let accel = &engine.render_scene().accel;
    let masks: Vec<InstanceMask> = accel
        .instances()
        .iter()
        .filter(|i| {
            body_nodes
                .iter()
                .any(|&e| gloam::extract::instance_user_id(e) == i.user_id)
        })
        .map(|i| i.mask)
        .collect();
    assert_eq!(masks.len(), body_nodes.len());
    for mask in masks {
        assert!(!mask.intersects(InstanceMask::CAMERA), "{mask:?}");
        assert!(mask.intersects(InstanceMask::SHADOW) && mask.intersects(InstanceMask::BOUNCE));
    }
    // The floor at its feet is in its shadow from the lamp straight above ...
    let lamp = glam::Vec3A::new(0.0, 2.58, -4.0);
    let floor = glam::Vec3A::from(HALL_LAMP_POOL) + glam::Vec3A::new(0.05, 0.01, 0.0);
    let mut to_lamp = Ray::new(floor, lamp - floor);
    to_lamp.t_max = 1.0 - 1e-4;
    assert!(accel.occluded(&to_lamp, InstanceMask::SHADOW, &Opaque));
    assert!(!accel.occluded(&to_lamp, InstanceMask::CAMERA, &Opaque));
    // ... and its eye sees past its own head.
    let eye = glam::Vec3A::from(HALL_LAMP_POOL) + glam::Vec3A::Y * 1.6;
    let ahead = accel.intersect(
        &Ray::new(eye, glam::Vec3A::NEG_Z),
        InstanceMask::CAMERA,
        &Opaque,
    );
    assert!(ahead.is_some_and(|hit| hit.t > 0.5), "{ahead:?}");
    // A bounce ray coming at it from in front meets it.
    let towards = accel.intersect(
        &Ray::new(eye + glam::Vec3A::new(0.0, -0.5, -1.5), glam::Vec3A::Z),
        InstanceMask::BOUNCE,
        &Opaque,
    );
    assert!(towards.is_some_and(|hit| hit.t < 1.5), "{towards:?}");
}

#[test]
fn e_douses_the_lamp_the_player_looks_at_and_relights_it() {
    use gloam::game::SwitchedOff;
    let (mut engine, player) = level();
    let lamp = {
        let mut named = engine.world.query::<(Entity, &Name)>();
        named
            .iter(&engine.world)
            .find(|(_, n)| n.as_str() == "cellar lamp")
            .unwrap()
            .0
    };
    // A metre west of the cellar lamp (2.58 m up at (-8, -2)), in its pool.
    place(&mut engine, player, Vec3::new(-9.0, 0.0, -2.0));
    let press = |engine: &mut Engine| {
        engine
            .world
            .resource_mut::<Input>()
            .pressed
            .insert(Action::Interact);
        hold(engine, &[], 0.1);
    };
    // Looking ahead (north), the lamp is out of aim: nothing happens.
    press(&mut engine);
    assert!(engine.world.get::<SwitchedOff>(lamp).is_none());
    // Looking up at it (east, 44 degrees up): doused, and the gem falls.
    {
        let mut body = engine.world.get_mut::<Player>(player).unwrap();
        body.yaw = -std::f32::consts::FRAC_PI_2;
        body.pitch = 0.98f32.atan2(1.0);
    }
    hold(&mut engine, &[], 1.0);
    let lit = gem(&engine, player);
    press(&mut engine);
    assert!(engine.world.get::<SwitchedOff>(lamp).is_some());
    hold(&mut engine, &[], 1.0);
    let doused = gem(&engine, player);
    assert!(doused < lit - 0.3, "{lit} -> {doused}");
    // Again: relit.
    press(&mut engine);
    assert!(engine.world.get::<SwitchedOff>(lamp).is_none());
    hold(&mut engine, &[], 1.0);
    assert!((gem(&engine, player) - lit).abs() < 0.02);
}

#[test]
fn a_warden_that_sees_a_doused_lamp_walks_over_and_lights_it_again() {
    use gloam::game::{SwitchedOff, Warden, WardenState};
    let (mut engine, _) = level_with_wardens();
    let named = |engine: &mut Engine, name: &str| {
        let mut named = engine.world.query::<(Entity, &Name)>();
        named
            .iter(&engine.world)
            .find(|(_, n)| n.as_str() == name)
            .unwrap()
            .0
    };
    // The hall's south lamp, on warden 1's beat, doused while it walks there.
    let lamp = named(&mut engine, "hall lamp south");
    let warden = named(&mut engine, "warden 1");
    engine.world.entity_mut(lamp).insert(SwitchedOff);
    let mut errand = false;
    for _ in 0..(30.0 / STEP) as usize {
        engine.step();
        let state = engine.world.get::<Warden>(warden).unwrap();
        assert_eq!(state.state, WardenState::Patrol, "no player to see");
        errand |= state.relight == Some(lamp);
        if engine.world.get::<SwitchedOff>(lamp).is_none() {
            break;
        }
    }
    assert!(errand, "it saw the dark lamp and went to it");
    assert!(
        engine.world.get::<SwitchedOff>(lamp).is_none(),
        "lit again within 30 s"
    );
    let lamp_at = engine.world.get::<Transform>(lamp).unwrap().translation;
    let at = engine.world.get::<Transform>(warden).unwrap().translation;
    assert!(
        Vec3::new(lamp_at.x - at.x, 0.0, lamp_at.z - at.z).length() <= 1.0 + 1e-3,
        "lit from beside it: {at} for {lamp_at}"
    );
}
