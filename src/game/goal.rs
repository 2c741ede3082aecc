//! Game schedule, fixed step "gameplay": the level's goal. The player collects its shards
//! (`collect_shards`: a shard is taken when the body comes within its radius, and the
//! entity goes, its glow with it) and then reaches the exit (`reach_exit`): the level is
//! won. `Progress` keeps the count, the clock and the outcome; once the attempt is over
//! the player's body stops taking input (`move_player` reads it). A level with no exit is
//! a free walk with no end: nothing wins it (the HUD says so, and `gloam check` warns).

use bevy_ecs::prelude::*;
use glam::Vec2;

use super::player::tuning::STANDING_HEIGHT;
use super::{Player, Transform};

/// A shard the player collects (the level's `shard`).
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub struct Shard {
    pub radius: f32,
}

/// The way out (the level's `exit`).
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub struct Exit {
    pub radius: f32,
}

/// How an attempt ended, or that it has not.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Outcome {
    #[default]
    Running,
    Won,
    Caught,
    Quit,
}

impl Outcome {
    /// As the replay JSON writes it.
    pub fn name(self) -> &'static str {
        match self {
            Outcome::Running => "running",
            Outcome::Won => "won",
            Outcome::Caught => "caught",
            Outcome::Quit => "quit",
        }
    }
}

/// The attempt so far.
#[derive(Resource, Clone, Debug, Default, PartialEq)]
pub struct Progress {
    pub shards_taken: u32,
    /// Fixed steps since the attempt began (the clock: steps / 60 s).
    pub steps: u64,
    /// How many times a warden saw the player (the end screen's count).
    pub times_seen: u32,
    pub outcome: Outcome,
    /// Noclip was switched on during the attempt: it does not count for best times.
    pub noclip_used: bool,
}

impl Progress {
    pub fn seconds(&self) -> f64 {
        self.steps as f64 / super::SIMULATION_HZ
    }
}

/// A time of play as the end page, the best times and the bot say it: m:ss.s. Rounded to
/// the tenth before it is split, so 59.96 s reads 1:00.0, never 0:60.0.
pub fn play_time(seconds: f64) -> String {
    let tenths = (seconds.max(0.0) * 10.0).round() as u64;
    format!("{}:{:02}.{}", tenths / 600, tenths / 10 % 60, tenths % 10)
}

/// Fixed step: the clock, and shards the player's body reaches are taken.
pub fn collect_shards(
    mut commands: Commands,
    mut progress: ResMut<Progress>,
    players: Query<&Transform, With<Player>>,
    shards: Query<(Entity, &Shard, &Transform)>,
) {
    if progress.outcome != Outcome::Running {
        return;
    }
    let Some(player) = players.iter().next() else {
        return;
    };
    progress.steps += 1;
    let feet = player.translation;
    for (entity, shard, placed) in &shards {
        let at = placed.translation;
        let across = Vec2::new(at.x - feet.x, at.z - feet.z).length();
        let within_height = at.y >= feet.y - 0.5 && at.y <= feet.y + STANDING_HEIGHT;
        if across <= shard.radius && within_height {
            commands.entity(entity).despawn();
            progress.shards_taken += 1;
        }
    }
}

/// Fixed step: with every shard taken, the exit wins the level (a level without one is
/// never won).
pub fn reach_exit(
    mut progress: ResMut<Progress>,
    players: Query<&Transform, With<Player>>,
    shards: Query<(), With<Shard>>,
    exits: Query<(&Exit, &Transform)>,
) {
    if progress.outcome != Outcome::Running || !shards.is_empty() {
        return;
    }
    let Some(player) = players.iter().next() else {
        return;
    };
    let feet = player.translation;
    let reached = exits.iter().any(|(exit, placed)| {
        let at = placed.translation;
        Vec2::new(at.x - feet.x, at.z - feet.z).length() <= exit.radius
            && (at.y - feet.y).abs() < STANDING_HEIGHT
    });
    if reached {
        progress.outcome = Outcome::Won;
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn play_time_rounds_before_it_splits_minutes_and_seconds() {
        assert_eq!(super::play_time(0.0), "0:00.0");
        assert_eq!(super::play_time(69.8), "1:09.8");
        assert_eq!(super::play_time(59.96), "1:00.0");
        assert_eq!(super::play_time(-3.0), "0:00.0");
    }
}
