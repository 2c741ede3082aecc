//! The exposure map (`gloam exposure`) of level 1: the JSON its docs promise
//! (`headless::bench`, "gloam exposure"), cells
//! that follow the lamps, a value that is the light gem the game itself gives a player
//! standing there, a route that is lit while warden 1 stands over a shard and dark once it
//! walks away, and no route to a shard nobody can reach.

mod common;

use glam::Vec3;
use gloam::frame::Engine;
use gloam::game::exposure::curve::HIDDEN;
use gloam::game::exposure_map::{Waypoints, exposure_map};
use gloam::game::{Exposure, Input, Transform, WorldGeometry, spawn_player};
use gloam::headless::bench::exposure_map::{Options, PNG_SCALE, run};
use gloam::render::RenderSettings;
use gloam::scene::Scene;
use serde_json::Value;

fn level_one() -> std::path::PathBuf {
    common::repo().join("levels").join("first-light.ron")
}

/// `gloam exposure` of level 1 at `time`: the JSON and the PNG's size.
fn map_at(time: f64) -> (Value, (u32, u32)) {
    let dir = common::scratch_dir("exposure-map");
    let options = Options {
        level: level_one(),
        time,
        cell: 0.25,
        threshold: 0.5,
        out: dir.join("map.png"),
        json: dir.join("map.json"),
    };
    run(&options).unwrap();
    let json = serde_json::from_str(&std::fs::read_to_string(&options.json).unwrap()).unwrap();
    let png = image::image_dimensions(&options.out).unwrap();
    (json, png)
}

/// The value of `map[key]` at (x, z), by the cell formula in its docs.
fn cell(map: &Value, key: &str, x: f32, z: f32) -> Option<f64> {
    let origin = map["origin"].as_array().unwrap();
    let size = map["cell_size"].as_f64().unwrap() as f32;
    let column = ((x - origin[0].as_f64().unwrap() as f32) / size).floor() as usize;
    let row = ((z - origin[1].as_f64().unwrap() as f32) / size).floor() as usize;
    map[key][row][column].as_f64()
}

#[test]
fn the_map_follows_the_lamps_and_the_json_is_as_promised() {
    let (map, png) = map_at(0.0);
    let (width, depth) = (
        map["width"].as_u64().unwrap() as usize,
        map["depth"].as_u64().unwrap() as usize,
    );
    assert_eq!(map["cell_size"].as_f64(), Some(0.25));
    for key in ["standing", "crouching"] {
        let rows = map[key].as_array().unwrap();
        assert_eq!(rows.len(), depth);
        assert!(
            rows.iter()
                .all(|row| row.as_array().unwrap().len() == width)
        );
    }
    assert_eq!(png, (width as u32 * PNG_SCALE, depth as u32 * PNG_SCALE));
    // Under the hall's north lamp: seen. The dark start: hidden. A crate and a wall: no
    // floor a player stands on.
    assert!(cell(&map, "standing", 0.0, -4.0).unwrap() > 0.6);
    assert!(cell(&map, "standing", -10.0, 6.5).unwrap() < HIDDEN as f64);
    assert_eq!(cell(&map, "standing", -9.0, 2.5), None);
    assert_eq!(cell(&map, "standing", -4.0, -6.0), None);
    // Both maps cover the same cells. Right under a lamp, crouching (points further from
    // it) is darker; at a pool's rim it can be brighter: the cone widens towards the floor.
    let cells = |key: &str| -> Vec<bool> {
        map[key]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|row| row.as_array().unwrap().iter().map(Value::is_null))
            .collect()
    };
    assert_eq!(cells("standing"), cells("crouching"));
    assert!(cell(&map, "crouching", 0.0, -4.0) < cell(&map, "standing", 0.0, -4.0));
    // At the start warden 1 stands at the hall's north end, its lamp on shard 2: no dark
    // route. A few seconds into its beat it has walked away and one exists.
    assert_eq!(map["route"]["exists"], false);
    assert!(map["route"]["max_exposure"].as_f64().unwrap() > 0.5);
    let (later, _) = map_at(6.0);
    assert_eq!(later["route"]["exists"], true);
    assert!(later["route"]["max_exposure"].as_f64().unwrap() <= 0.5);
    assert!(map.get("floors").is_none(), "level 1 has one storey");
}

#[test]
fn a_cell_s_value_is_the_gem_the_game_gives_a_player_standing_there() {
    let (map, _) = map_at(0.0);
    let scene = Scene::load(&level_one()).unwrap();
    let mut engine = Engine::new(&scene, RenderSettings::real_time(8, 8));
    common::pause_animation(&mut engine);
    let player = spawn_player(&mut engine.world).unwrap();
    // The cells in the cellar's lamp pool, at its edge and in the dark, at their centres.
    let origin = map["origin"].as_array().unwrap();
    let centre = |at: f32, origin: &Value| {
        let origin = origin.as_f64().unwrap() as f32;
        origin + (((at - origin) / 0.25).floor() + 0.5) * 0.25
    };
    for (x, z) in [(-8.0, -2.0), (-9.9, -2.0), (-10.9, 4.0)] {
        let (x, z) = (centre(x, &origin[0]), centre(z, &origin[1]));
        engine
            .world
            .get_mut::<Transform>(player)
            .unwrap()
            .translation = Vec3::new(x, 0.0, z);
        engine.world.resource_mut::<Input>().held.clear();
        for _ in 0..90 {
            engine.step();
        }
        let gem = engine.world.get::<Exposure>(player).unwrap().gem as f64;
        let mapped = cell(&map, "standing", x, z).unwrap();
        assert!(
            (gem - mapped).abs() < 0.01,
            "({x}, {z}): game {gem}, map {mapped}"
        );
    }
}

#[test]
fn a_shard_nobody_can_reach_leaves_no_route() {
    let scene = Scene::load(&level_one()).unwrap();
    let mut engine = Engine::new(&scene, RenderSettings::real_time(8, 8));
    engine.update_step_world();
    let geometry = &engine.world.resource::<WorldGeometry>().0;
    let bounds = geometry.bounds().unwrap();
    let spawn = Vec3::new(-10.0, 0.0, 6.5);
    let reachable = Waypoints {
        spawn,
        shards: vec![(Vec3::new(-10.8, 0.0, -6.8), 0.6)],
        exit: Some((Vec3::new(-10.0, 0.0, 4.0), 1.0)),
    };
    let map = exposure_map(geometry.as_ref(), bounds, 0.25, &reachable, 0.5);
    assert!(map.route.exists, "{:?}", map.route);
    // The same, with a shard on top of a stacked crate (1.7 m up: no step reaches it).
    let mut on_crate = reachable.clone();
    on_crate.shards.push((Vec3::new(-9.0, 1.7, 2.6), 0.6));
    let map = exposure_map(geometry.as_ref(), bounds, 0.25, &on_crate, 0.5);
    assert_eq!(map.route.max_exposure, None);
    assert!(!map.route.exists);
}

/// The route drawn: a walk of neighbouring cells from the spawn past every shard to the
/// exit whose brightest cell is the route's `max_exposure`; while warden 1 stands over a
/// shard the lit crossings it cannot avoid are chokepoints, and once it has walked away
/// there are none.
#[test]
fn the_drawn_route_walks_through_every_target_and_its_lit_crossings_are_chokepoints() {
    for (time, lit) in [(0.0, true), (4.0, false)] {
        let (map, _) = map_at(time);
        let route = &map["route"];
        let point = |p: &Value| {
            let p = p.as_array().unwrap();
            Vec3::new(
                p[0].as_f64().unwrap() as f32,
                p[1].as_f64().unwrap() as f32,
                p[2].as_f64().unwrap() as f32,
            )
        };
        let path: Vec<Vec3> = route["path"]
            .as_array()
            .unwrap()
            .iter()
            .map(point)
            .collect();
        assert!(!path.is_empty());
        for pair in path.windows(2) {
            let across = glam::Vec2::new(pair[1].x - pair[0].x, pair[1].z - pair[0].z).length();
            assert!(across > 0.0 && across < 0.36, "{} -> {}", pair[0], pair[1]);
        }
        let scene = Scene::load(&level_one()).unwrap();
        let spawn = scene.player_spawn().unwrap().0;
        assert!(
            path[0].distance(Vec3::new(spawn.x, path[0].y, spawn.z)) < 0.4,
            "{}",
            path[0]
        );
        for entity in &scene.level.entities {
            let radius = match (&entity.shard, &entity.exit) {
                (Some(shard), _) => shard.radius,
                (_, Some(exit)) => exit.radius,
                _ => continue,
            };
            let at = entity.transform.translation;
            assert!(
                path.iter()
                    .any(|p| glam::Vec2::new(p.x - at.x, p.z - at.z).length()
                        <= radius.max(0.125) + 1e-4),
                "{} is passed by",
                entity.name
            );
        }
        let value = |p: Vec3| {
            let standing = cell(&map, "standing", p.x, p.z).unwrap();
            let crouching = cell(&map, "crouching", p.x, p.z).unwrap();
            standing.min(crouching)
        };
        let brightest = path.iter().map(|&p| value(p)).fold(0.0, f64::max);
        let max = route["max_exposure"].as_f64().unwrap();
        assert!((brightest - max).abs() < 1e-5, "{brightest} against {max}");
        let chokepoints: Vec<Vec3> = route["chokepoints"]
            .as_array()
            .unwrap()
            .iter()
            .map(point)
            .collect();
        assert_eq!(!chokepoints.is_empty(), lit, "at {time} s: {chokepoints:?}");
        for choke in chokepoints {
            assert!(value(choke) > 0.5, "{choke} is lit");
            assert!(path.contains(&choke));
        }
    }
}
