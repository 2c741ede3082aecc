//! The audibility map of a level as authored, at a time on the wardens' beats: where on
//! the floor a noise the player can make (a sprinting footfall, a hard landing, a bottle
//! knocked over) would be heard by a warden. What the editor's overlay draws beside the
//! exposure map, by the wardens' own hearing (`game::noise::over_threshold_db`: the
//! noise's loudness, what the level takes on the way to the warden's ears through the
//! acoustics, against the hearing threshold), so the map and the game cannot disagree.
//!
//! The level is loaded into its own `Engine`, its wardens walk their beats for `time`
//! seconds, and every place on a `CELL`-metre lattice that the player can walk to from
//! the start (as the exposure map floods it) and that lies within the noise's reach of a
//! warden is asked, in parallel.

use bevy_ecs::prelude::With;
use glam::Vec3;
use rayon::prelude::*;

use crate::frame::Engine;
use crate::game::exposure_map::flood;
use crate::game::noise::tuning::{LANDING_RADIUS, SPRINT_RADIUS};
use crate::game::noise::{Noise, over_threshold_db};
use crate::game::{
    Knockable, NavGrid, PlayerStart, SIMULATION_HZ, Transform, Warden, WorldGeometry,
};
use crate::render::RenderSettings;
use crate::scene::Scene;

/// The map's cell, metres (twice the navigation grid's: a wall's thickness still shows).
pub const CELL: f32 = 0.5;

/// A noise the player can make.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum NoiseKind {
    Sprint,
    Landing,
    /// A knocked thing's crash: the loudest the level's knockable things make.
    Bottle,
}

impl NoiseKind {
    pub const ALL: [NoiseKind; 3] = [NoiseKind::Sprint, NoiseKind::Landing, NoiseKind::Bottle];

    pub fn name(self) -> &'static str {
        match self {
            NoiseKind::Sprint => "a sprint",
            NoiseKind::Landing => "a landing",
            NoiseKind::Bottle => "a bottle breaking",
        }
    }
}

/// Where a noise would be heard.
#[derive(Clone, Debug, PartialEq)]
pub struct Audibility {
    pub noise: NoiseKind,
    /// How far the noise carries in the open, metres.
    pub radius: f32,
    /// Every place asked that some warden hears: (the floor there, decibels over the
    /// threshold at the warden that hears it loudest, that warden's index in `wardens`).
    pub heard: Vec<(Vec3, f32, usize)>,
    /// Places asked that no warden hears, though within a warden's reach in the open (a
    /// wall between).
    pub muffled: Vec<Vec3>,
    /// Each warden's name and feet.
    pub wardens: Vec<(String, Vec3)>,
    /// How long the map took, seconds.
    pub seconds: f64,
}

/// Where `noise` would be heard in `scene` at `time` seconds into the wardens' beats
/// (`None`: the level has no wardens or nowhere to walk).
pub fn compute(scene: &Scene, time: f64, noise: NoiseKind) -> Option<Audibility> {
    let mut engine = Engine::new(scene, RenderSettings::real_time(1, 1));
    for _ in 0..(time * SIMULATION_HZ).round() as u64 {
        engine.step();
    }
    engine.update_step_world();
    let start = std::time::Instant::now();
    let world = &mut engine.world;
    let mut wardens: Vec<(String, Vec3)> = world
        .query_filtered::<(&bevy_ecs::name::Name, &Transform), With<Warden>>()
        .iter(world)
        .map(|(name, placed)| (name.as_str().to_owned(), placed.translation))
        .collect();
    wardens.sort_by(|a, b| a.0.cmp(&b.0));
    let radius = match noise {
        NoiseKind::Sprint => SPRINT_RADIUS,
        NoiseKind::Landing => LANDING_RADIUS,
        NoiseKind::Bottle => world
            .query::<&Knockable>()
            .iter(world)
            .map(|knock| knock.noise)
            .fold(None, |loudest: Option<f32>, r| {
                Some(loudest.map_or(r, |l| l.max(r)))
            })
            .unwrap_or(crate::scene::level::KnockDef::default().noise),
    };
    let spawn = world
        .query_filtered::<&Transform, With<PlayerStart>>()
        .iter(world)
        .next()
        .map(|placed| placed.translation);
    let grid = world.get_resource::<NavGrid>()?;
    let geometry = world.get_resource::<WorldGeometry>()?.0.as_ref();
    if wardens.is_empty() {
        return None;
    }
    // The places the player can walk to from the start (all walkable ones in a level
    // without a start): the top of a wall is floor to the grid, but no one sprints there.
    let spawn = spawn.and_then(|at| grid.node_near(at));
    let reachable: Option<Vec<bool>> = spawn.map(|spawn| {
        let mut reached = vec![false; grid.index_bound()];
        for node in flood(grid, spawn) {
            reached[grid.index(node)] = true;
        }
        reached
    });
    // The walkable places on the map's lattice within the noise's reach of a warden.
    let step = (CELL / grid.cell).round().max(1.0) as usize;
    let places: Vec<Vec3> = grid
        .nodes()
        .filter(|node| {
            reachable
                .as_ref()
                .is_none_or(|reached| reached[grid.index(*node)])
        })
        .filter(|node| {
            let (column, row) = (node.column % grid.width, node.column / grid.width);
            column % step == 0 && row % step == 0
        })
        .map(|node| grid.position(node))
        .filter(|at| {
            wardens
                .iter()
                .any(|(_, feet)| at.distance(*feet) <= radius + 2.0)
        })
        .collect();
    let answers: Vec<(Vec3, Option<(f32, usize)>)> = places
        .par_iter()
        .map(|&at| {
            let made = Noise {
                at,
                radius,
                age: 0.0,
            };
            let loudest = wardens
                .iter()
                .enumerate()
                .filter_map(|(index, (_, feet))| {
                    over_threshold_db(geometry, Some(grid), &made, *feet).map(|db| (db, index))
                })
                .max_by(|a, b| a.0.total_cmp(&b.0));
            (at, loudest)
        })
        .collect();
    let mut map = Audibility {
        noise,
        radius,
        heard: Vec::new(),
        muffled: Vec::new(),
        wardens,
        seconds: 0.0,
    };
    for (at, loudest) in answers {
        match loudest {
            Some((db, warden)) => map.heard.push((at, db, warden)),
            None if map
                .wardens
                .iter()
                .any(|(_, feet)| at.distance(*feet) <= radius) =>
            {
                map.muffled.push(at)
            }
            None => {}
        }
    }
    map.seconds = start.elapsed().as_secs_f64();
    Some(map)
}
