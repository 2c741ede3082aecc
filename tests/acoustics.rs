//! Sound through the level, by rays through the simulation's copy of it
//! (`game::acoustics`): a source behind a wall is quieter and duller than in the open;
//! through a doorway it arrives from the doorway; a stone hall rings longer than a small
//! room.

mod common;

use glam::Vec3;
use gloam::frame::Engine;
use gloam::game::WorldGeometry;
use gloam::game::acoustics::{hear, reverb};
use gloam::game::nav::{CELL, NavGrid};
use gloam::render::RenderSettings;
use gloam::scene::Scene;

/// A kit piece at (x, z), turned `yaw` degrees.
fn piece(name: &str, asset: &str, (x, y, z): (f32, f32, f32), yaw: f32) -> String {
    let kit = common::repo().join("assets/kit");
    format!(
        "(name: \"{name}\", transform: (translation: ({x:.2}, {y:.2}, {z:.2}), rotation: (0.0, {yaw:.1}, 0.0)), instance: (asset: \"{}\")),\n",
        kit.join(asset).display()
    )
}

/// A level of floor tiles over x, z in [-half, half] (4 m tiles), the given pieces, and a
/// ceiling of tiles at 3 m when `roofed`; its engine with the geometry extracted.
fn level(test: &str, half: i32, roofed: bool, pieces: &[String]) -> Engine {
    let (scene, _) = level_file(test, half, roofed, pieces);
    let mut engine = Engine::new(&scene, RenderSettings::real_time(8, 8));
    engine.update_step_world();
    engine
}

/// `level`'s scene and file.
fn level_file(
    test: &str,
    half: i32,
    roofed: bool,
    pieces: &[String],
) -> (Scene, std::path::PathBuf) {
    let mut entities = String::new();
    let tiles = (-half..half).step_by(4).map(|c| c as f32 + 2.0);
    for (i, x) in tiles.clone().enumerate() {
        for (j, z) in tiles.clone().enumerate() {
            entities += &piece(&format!("floor {i} {j}"), "floor.glb", (x, 0.0, z), 0.0);
            if roofed {
                entities += &piece(&format!("roof {i} {j}"), "floor.glb", (x, 3.1, z), 0.0);
            }
        }
    }
    for entity in pieces {
        entities += entity;
    }
    let text = format!(
        "(version: 1, playable: false, entities: [\n{entities}(name: \"light\", light: Point(color: (1, 1, 1), intensity: 1)),\n])\n"
    );
    let dir = common::scratch_dir(test);
    let path = common::write(&dir, "level.ron", text);
    (Scene::load(&path).unwrap(), path)
}

fn nav(engine: &Engine) -> NavGrid {
    let world = &engine.world.resource::<WorldGeometry>().0;
    NavGrid::build(world.as_ref(), world.bounds().unwrap(), CELL)
}

#[test]
fn a_wall_between_makes_a_sound_quieter_and_duller() {
    let (source, ears) = (Vec3::new(0.0, 0.5, 3.0), Vec3::new(0.0, 1.6, -3.0));
    let open = level("acoustics-open", 8, false, &[]);
    let walled = level(
        "acoustics-wall",
        8,
        false,
        &[piece("wall", "wall.glb", (0.0, 0.0, 0.0), 0.0)],
    );
    fn world(engine: &Engine) -> &WorldGeometry {
        engine.world.resource::<WorldGeometry>()
    }
    let in_the_open = hear(world(&open).0.as_ref(), None, source, ears);
    assert!(!in_the_open.occluded);
    let grid = nav(&walled);
    let behind = hear(world(&walled).0.as_ref(), Some(&grid), source, ears);
    println!("open {in_the_open:?}\nbehind the wall {behind:?}");
    assert!(behind.occluded);
    assert!(behind.level_db <= in_the_open.level_db - 6.0);
    assert!(behind.cutoff_hz < in_the_open.cutoff_hz);
    // With no way round, only what comes through the wall: far quieter still.
    let through = hear(world(&walled).0.as_ref(), None, source, ears);
    assert!(through.level_db < behind.level_db - 20.0, "{through:?}");
    assert!(through.cutoff_hz < behind.cutoff_hz);
}

#[test]
fn through_a_doorway_a_sound_arrives_from_the_doorway() {
    let wall = [
        piece("doorway", "wall-doorway.glb", (0.0, 0.0, 0.0), 0.0),
        piece("left", "wall.glb", (-4.0, 0.0, 0.0), 0.0),
        piece("right", "wall.glb", (4.0, 0.0, 0.0), 0.0),
    ];
    let engine = level("acoustics-doorway", 8, false, &wall);
    let world = &engine.world.resource::<WorldGeometry>().0;
    let grid = nav(&engine);
    let heard = hear(
        world.as_ref(),
        Some(&grid),
        Vec3::new(3.0, 0.5, 3.0),
        Vec3::new(3.0, 1.6, -3.0),
    );
    println!("{heard:?}");
    assert!(heard.occluded);
    let arrival = heard.arrival;
    assert!(
        arrival.x.abs() < 1.0 && arrival.z.abs() < 1.5,
        "arrives from {arrival}"
    );
    assert!(
        heard.path_length > 6.5,
        "round, not straight: {}",
        heard.path_length
    );
}

#[test]
fn a_stone_hall_rings_longer_than_a_small_room() {
    let walls = |half: i32| -> Vec<String> {
        let mut walls = Vec::new();
        for (k, c) in (-half..half).step_by(4).map(|c| c as f32 + 2.0).enumerate() {
            let h = half as f32 + 0.1;
            walls.push(piece(&format!("n{k}"), "wall.glb", (c, 0.0, -h), 0.0));
            walls.push(piece(&format!("s{k}"), "wall.glb", (c, 0.0, h), 0.0));
            walls.push(piece(&format!("w{k}"), "wall.glb", (-h, 0.0, c), 90.0));
            walls.push(piece(&format!("e{k}"), "wall.glb", (h, 0.0, c), 90.0));
        }
        walls
    };
    let ears = Vec3::new(0.3, 1.6, 0.2);
    let small = level("acoustics-room", 2, true, &walls(2));
    let hall = level("acoustics-hall", 8, true, &walls(8));
    let ring = |engine: &Engine| reverb(engine.world.resource::<WorldGeometry>().0.as_ref(), ears);
    let (room, hall) = (ring(&small), ring(&hall));
    println!("room {room:?}\nhall {hall:?}");
    assert!(hall.decay_s > 1.5 * room.decay_s);
    assert!(hall.mean_free_path > room.mean_free_path);
    // Outdoors the sound never comes back: almost no decay.
    let open = level("acoustics-outdoors", 8, false, &[]);
    assert!(ring(&open).decay_s < room.decay_s);
}

/// `gloam listen`: the wind behind a kit wall is at least 6 dB quieter and duller (a lower
/// spectral centroid) than with the wall taken away, in the WAV itself.
#[test]
fn listening_behind_a_wall_is_quieter_and_duller_in_the_sound_itself() {
    use gloam::headless::listen::{Listening, listen};
    let wind = common::repo().join("assets/sounds/wind.wav");
    let source = format!(
        "(name: \"wind\", transform: (translation: (0.0, 1.0, 3.0)), sound: (asset: \"{}\")),\n",
        wind.display()
    );
    let wall = piece("wall", "wall.glb", (0.0, 0.0, 0.0), 0.0);
    let listening = Listening {
        at: Vec3::new(0.0, 1.6, -3.0),
        facing_degrees: 0.0,
        time: 0.0,
        seconds: 2.0,
    };
    let heard = |test: &str, pieces: &[String]| {
        let (scene, path) = level_file(test, 8, false, pieces);
        let (report, sound) = listen(&scene, &path, &listening).unwrap();
        assert_eq!(report["sources"].as_array().unwrap().len(), 1);
        let mono: Vec<f64> = sound
            .left
            .iter()
            .zip(&sound.right)
            .map(|(l, r)| f64::from(l + r) * 0.5)
            .collect();
        let power = mono.iter().map(|s| s * s).sum::<f64>() / mono.len() as f64;
        (report, 10.0 * power.log10(), centroid(&mono))
    };
    let (open, open_db, open_centroid) = heard("listen-open", &[source.clone()]);
    let (walled, walled_db, walled_centroid) = heard("listen-wall", &[source, wall]);
    println!(
        "open {open_db:.1} dB, {open_centroid:.0} Hz; walled {walled_db:.1} dB, {walled_centroid:.0} Hz"
    );
    assert_eq!(open["sources"][0]["occluded"], false);
    assert_eq!(walled["sources"][0]["occluded"], true);
    assert!(walled_db <= open_db - 6.0);
    assert!(walled_centroid < open_centroid);
    assert!(walled["reverb"]["decay_s"].as_f64().unwrap() > 0.0);
}

/// The power-weighted mean frequency of `signal` (48 kHz), from a DFT of its middle 4096
/// samples under a Hann window.
fn centroid(signal: &[f64]) -> f64 {
    let n = 4096;
    let start = (signal.len() - n) / 2;
    let window = &signal[start..start + n];
    let (mut weighted, mut total) = (0.0, 0.0);
    for bin in 1..n / 2 {
        let (mut re, mut im) = (0.0, 0.0);
        for (i, x) in window.iter().enumerate() {
            let hann = 0.5 - 0.5 * (std::f64::consts::TAU * i as f64 / n as f64).cos();
            let phase = std::f64::consts::TAU * (bin * i) as f64 / n as f64;
            re += x * hann * phase.cos();
            im -= x * hann * phase.sin();
        }
        let power = re * re + im * im;
        weighted += power * bin as f64 * 48_000.0 / n as f64;
        total += power;
    }
    weighted / total
}

/// The editor's audibility map asks the wardens' own hearing: on first-light a landing is
/// heard over more floor than a sprint, everything heard lies within the noise's reach of
/// a warden, and walls keep some of that reach quiet.
#[test]
fn the_audibility_map_hears_as_the_wardens_do() {
    use gloam::edit::audibility::{CELL, NoiseKind, compute};

    let scene = Scene::load(&common::repo().join("levels/first-light.ron")).unwrap();
    let area = |noise| {
        let map = compute(&scene, 0.0, noise).expect("first-light has wardens");
        for &(at, over_db, warden) in &map.heard {
            let feet = map.wardens[warden].1;
            assert!(
                at.distance(feet) <= map.radius + 2.0 && over_db >= 0.0,
                "{noise:?} heard at {at} by a warden at {feet}, {over_db} dB over"
            );
        }
        println!(
            "{}: heard over {:.0} m², kept quiet by walls over {:.0} m² ({:.0} ms)",
            noise.name(),
            map.heard.len() as f32 * CELL * CELL,
            map.muffled.len() as f32 * CELL * CELL,
            map.seconds * 1e3
        );
        (map.heard.len(), map.muffled.len())
    };
    let (sprint, _) = area(NoiseKind::Sprint);
    let (landing, landing_muffled) = area(NoiseKind::Landing);
    assert!(
        landing > sprint && sprint > 0,
        "landing {landing}, sprint {sprint}"
    );
    assert!(landing_muffled > 0, "no wall keeps a landing quiet");
}
