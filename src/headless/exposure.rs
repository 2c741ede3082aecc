//! The exposure map of a level as authored, at a time on the wardens' beats: what
//! `gloam exposure` writes and the editor's overlay draws. One computation for both.
//!
//! The level is loaded into its own `Engine` (never the editor's), its wardens walk their
//! beats for `time` seconds (no player, so none sees anyone), and the simulation's copy of
//! the level as it then stands answers `game::exposure_map`: the game's own body points,
//! lights and shadow rays.

use bevy_ecs::prelude::{With, World};
use glam::Vec3;

use crate::frame::Engine;
use crate::game::exposure::curve::HIDDEN;
use crate::game::exposure_map::{ExposureMap, Waypoints, exposure_map};
use crate::game::{Exit, PlayerStart, SIMULATION_HZ, Shard, Transform, Warden, WorldGeometry};
use crate::render::RenderSettings;
use crate::scene::Scene;

/// A map and what it was taken of.
#[derive(Clone, Debug)]
pub struct Exposure {
    pub map: ExposureMap,
    pub waypoints: Waypoints,
    /// Each warden where its beat has taken it: (feet, facing), facing level.
    pub wardens: Vec<(Vec3, Vec3)>,
    /// How long the map itself took (the flood, every cell's gem and the route), seconds.
    pub seconds: f64,
}

/// Why a level has no map.
#[derive(Debug, thiserror::Error)]
pub enum NoMap {
    #[error("the level has no player start to map from")]
    NoSpawn,
    #[error("the level has no geometry")]
    NoGeometry,
}

/// The exposure map of `scene` at `time` seconds, `cell`-metre cells, the route judged
/// against `threshold`.
pub fn compute(scene: &Scene, time: f64, cell: f32, threshold: f32) -> Result<Exposure, NoMap> {
    let mut engine = Engine::new(scene, RenderSettings::real_time(1, 1));
    for _ in 0..(time * SIMULATION_HZ).round() as u64 {
        engine.step();
    }
    engine.update_step_world();
    let waypoints = waypoints(&mut engine.world).ok_or(NoMap::NoSpawn)?;
    let wardens = engine
        .world
        .query_filtered::<&Transform, With<Warden>>()
        .iter(&engine.world)
        .map(|placed| {
            let facing = placed.rotation * Vec3::Z;
            (
                placed.translation,
                Vec3::new(facing.x, 0.0, facing.z).normalize_or_zero(),
            )
        })
        .collect();
    let geometry = &engine.world.resource::<WorldGeometry>().0;
    let bounds = geometry.bounds().ok_or(NoMap::NoGeometry)?;
    let start = std::time::Instant::now();
    let map = exposure_map(geometry.as_ref(), bounds, cell, &waypoints, threshold);
    Ok(Exposure {
        map,
        waypoints,
        wardens,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// The spawn, shards and exit of the world's level (None without a player start).
fn waypoints(world: &mut World) -> Option<Waypoints> {
    let spawn = world
        .query_filtered::<&Transform, With<PlayerStart>>()
        .iter(world)
        .next()?
        .translation;
    let shards = world
        .query::<(&Transform, &Shard)>()
        .iter(world)
        .map(|(t, shard)| (t.translation, shard.radius))
        .collect();
    let exit = world
        .query::<(&Transform, &Exit)>()
        .iter(world)
        .next()
        .map(|(t, exit)| (t.translation, exit.radius));
    Some(Waypoints {
        spawn,
        shards,
        exit,
    })
}

/// A cell's colour on the map: dark blue where hidden (no cell of the gem lit), warming to
/// yellow as the gem rises to the threshold, red above it.
pub fn colour(value: f32, threshold: f32) -> [u8; 3] {
    if value < HIDDEN {
        [20, 30, 70]
    } else if value > threshold {
        [200, 40, 30]
    } else {
        let t = ((value - HIDDEN) / (threshold - HIDDEN).max(1e-3)).clamp(0.0, 1.0);
        [
            (60.0 + 180.0 * t) as u8,
            (60.0 + 150.0 * t) as u8,
            (90.0 - 50.0 * t) as u8,
        ]
    }
}
