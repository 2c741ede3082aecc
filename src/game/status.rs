//! Frame step `simulate`, read between frames: what the player is told of the game's
//! state, as queries on the world that change nothing. The window's HUD, its first-level
//! hints and its end pages ask these; they lay out what they are told and know no rule.

use bevy_ecs::prelude::*;

use super::{
    Exit, Exposure, GlobalTransform, LevelEntity, Outcome, Player, PlayerEye, Progress,
    PunctualLight, SIMULATION_HZ, Shard, SwitchedOff, Warden, WardenState, WorldGeometry,
};

/// The light gem's reading, 0 (unseen) to 1, while there is a player to read.
pub fn gem(world: &mut World) -> Option<f32> {
    let mut exposures = world.query::<&Exposure>();
    exposures.iter(world).next().map(|exposure| exposure.gem)
}

/// The level's shards: taken so far, and in all.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shards {
    pub taken: u32,
    pub total: u32,
}

/// The shards, while an attempt is under way.
pub fn shards(world: &mut World) -> Option<Shards> {
    let taken = world.get_resource::<Progress>()?.shards_taken;
    let left = (world.query_filtered::<(), With<Shard>>().iter(world)).count() as u32;
    Some(Shards {
        taken,
        total: taken + left,
    })
}

/// A level with a player and no way out is a free walk (a scene without a player is only
/// a view).
pub fn is_free_walk(world: &mut World) -> bool {
    let exits = (world.query_filtered::<(), With<Exit>>().iter(world)).count();
    let players = (world.query_filtered::<(), With<Player>>().iter(world)).count();
    exits == 0 && players > 0
}

/// How the attempt stands.
pub fn outcome(world: &World) -> Option<Outcome> {
    world
        .get_resource::<Progress>()
        .map(|progress| progress.outcome)
}

/// The lamp within reach of the player's aim, if any: whether it is doused (the question
/// the interact key's press asks, `lamps::aimed_lamp`).
pub fn lamp_in_reach(world: &mut World) -> Option<LampInReach> {
    let (player, eye) = {
        let mut players = world.query::<&Player>();
        let player = players.iter(world).next()?.clone();
        let mut eyes = world.query_filtered::<&GlobalTransform, With<PlayerEye>>();
        let eye: glam::Vec3 = eyes.iter(world).next()?.0.translation.into();
        (player, eye)
    };
    let mut lamps = world.query_filtered::<
        (Entity, &GlobalTransform, Has<SwitchedOff>),
        (With<PunctualLight>, With<LevelEntity>),
    >();
    let candidates: Vec<_> = lamps
        .iter(world)
        .map(|(lamp, placed, doused)| (lamp, placed.0.translation.into(), doused))
        .collect();
    let geometry = world.get_resource::<WorldGeometry>()?;
    let view = super::lamps::view(&player);
    let (_, doused) = super::lamps::aimed_lamp(&*geometry.0, eye, view, candidates.into_iter())?;
    Some(if doused {
        LampInReach::Doused
    } else {
        LampInReach::Lit
    })
}

/// A lamp within reach, as the interact key finds it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LampInReach {
    /// Lit: the key douses it.
    Lit,
    /// Doused: the key lights it again.
    Doused,
}

/// The name of the warden that caught the player ("a warden" when none holds it).
pub fn caught_by(world: &mut World) -> String {
    let mut wardens = world.query::<(&Warden, &Name)>();
    wardens
        .iter(world)
        .find(|(warden, _)| warden.state == WardenState::Caught)
        .map_or_else(|| "a warden".to_string(), |(_, name)| name.to_string())
}

/// Each warden's head (where a mark over it goes, `head_height` above its feet) and what
/// it knows of the player.
pub fn warden_heads(world: &mut World, head_height: f32) -> Vec<WardenHead> {
    let mut wardens = world.query::<(&Warden, &GlobalTransform)>();
    wardens
        .iter(world)
        .map(|(warden, placed)| WardenHead {
            head: (placed.0.translation + glam::Vec3A::Y * head_height).into(),
            state: warden.state,
            suspicion: warden.suspicion,
        })
        .collect()
}

/// A warden's head and what it knows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WardenHead {
    pub head: glam::Vec3,
    pub state: WardenState,
    pub suspicion: f32,
}

/// What the player is doing now: the attempt's clock, the light gem, the crouch, the
/// shards in all (what the first level's hints read).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Moment {
    /// Seconds since the attempt began.
    pub seconds: f32,
    /// The light gem's reading.
    pub gem: f32,
    pub crouched: bool,
    /// The level's shards in all.
    pub shards: u32,
}

/// The player's moment, while an attempt with a player is under way.
pub fn moment(world: &mut World) -> Option<Moment> {
    let steps = world.get_resource::<Progress>()?.steps;
    let gem = gem(world)?;
    let crouched = world.query::<&Player>().iter(world).next()?.crouched;
    Some(Moment {
        seconds: (steps as f64 / SIMULATION_HZ) as f32,
        gem,
        crouched,
        shards: shards(world)?.total,
    })
}
