//! The simulation's state, as replays compare it: after a fixed step, every part of the
//! world that the next step reads or the player sees, hashed part by part.
//!
//! `StateParts::of` reads the world and hashes each part on its own (FNV-1a 64 over the
//! exact bits of its numbers): the player (position, orientation, velocity, stance and
//! ground, light gem), every warden by name (position, facing, mind: state, suspicion,
//! timers, where it last saw or heard the player, its path and errand), the lamps on or
//! off, knocked things, movers, animation clocks, the shards left, the noises, and the
//! attempt's progress (steps, times seen, outcome). A replay that departs from its
//! recording is told by the first part whose hash differs, in this order, so the line
//! says what went another way, not only that something did.
//!
//! Nothing here depends on entity ids, thread counts or iteration order: parts are keyed
//! and sorted by names from the level.

use bevy_ecs::prelude::*;
use glam::Vec3;

use super::noise::{Footfalls, Knockable, Noises};
use super::replay::Fnv64;
use super::{
    Animator, Deformer, Exposure, LevelEntity, Patrol, Player, Progress, PunctualLight, Shard,
    SwitchedOff, Transform, Warden,
};

/// One part's hash, by the part's name.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StatePart {
    pub name: String,
    pub hash: u64,
}

/// The world's state after a step, part by part (see the module doc).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct StateParts(pub Vec<StatePart>);

/// Hashes a part's values.
#[derive(Default)]
struct Part(Fnv64);

impl Part {
    fn f32s(&mut self, values: &[f32]) -> &mut Self {
        for value in values {
            self.0.write(&value.to_bits().to_le_bytes());
        }
        self
    }

    fn f64s(&mut self, values: &[f64]) -> &mut Self {
        for value in values {
            self.0.write(&value.to_bits().to_le_bytes());
        }
        self
    }

    fn vec3(&mut self, value: Vec3) -> &mut Self {
        self.f32s(&value.to_array())
    }

    fn bytes(&mut self, bytes: &[u8]) -> &mut Self {
        // Length first, so two strings never run together into the same bytes.
        self.0.write(&(bytes.len() as u64).to_le_bytes());
        self.0.write(bytes);
        self
    }

    fn flags(&mut self, flags: &[bool]) -> &mut Self {
        let bits = flags
            .iter()
            .enumerate()
            .fold(0u64, |bits, (i, &flag)| bits | (flag as u64) << i);
        self.0.write(&bits.to_le_bytes());
        self
    }

    fn option(&mut self, value: Option<Vec3>) -> &mut Self {
        match value {
            Some(value) => self.flags(&[true]).vec3(value),
            None => self.flags(&[false]),
        }
    }
}

impl StateParts {
    /// The state of `world` as it stands.
    pub fn of(world: &mut World) -> StateParts {
        let mut parts = Vec::new();
        let mut push = |name: String, part: &Part| {
            parts.push(StatePart {
                name,
                hash: part.0.0,
            })
        };
        let names = |world: &World, entity: Entity| {
            world
                .get::<Name>(entity)
                .map_or_else(String::new, |name| name.as_str().to_owned())
        };

        // The player.
        let mut players =
            world.query::<(&Player, &Transform, Option<&Exposure>, Option<&Footfalls>)>();
        if let Some((player, placed, exposure, feet)) = players.iter(world).next() {
            push(
                "player position".into(),
                Part::default().vec3(placed.translation),
            );
            push(
                "player orientation".into(),
                Part::default().f32s(&[player.yaw, player.pitch]),
            );
            push(
                "player velocity".into(),
                Part::default().vec3(player.velocity),
            );
            let mut stance = Part::default();
            stance
                .flags(&[
                    player.crouched,
                    player.grounded,
                    player.noclip,
                    player.sprinting,
                ])
                .f32s(&[player.eye]);
            if let Some(feet) = feet {
                stance
                    .f32s(&[feet.until_next, feet.falling])
                    .flags(&[feet.grounded]);
            }
            push("player stance".into(), &stance);
            push(
                "player gem".into(),
                Part::default().f32s(&[exposure.map_or(0.0, |e| e.gem)]),
            );
        }

        // The wardens, by name.
        let mut wardens: Vec<(String, Vec3, Warden)> = world
            .query::<(&Name, &Transform, &Warden)>()
            .iter(world)
            .map(|(name, placed, warden)| {
                (name.as_str().to_owned(), placed.translation, warden.clone())
            })
            .collect();
        wardens.sort_by(|a, b| a.0.cmp(&b.0));
        for (name, at, warden) in wardens {
            push(format!("{name} position"), Part::default().vec3(at));
            push(
                format!("{name} facing"),
                Part::default().f32s(&[warden.yaw]),
            );
            let mut mind = Part::default();
            mind.bytes(warden.state.name().as_bytes())
                .f32s(&[
                    warden.suspicion,
                    warden.timer,
                    warden.since_noticed,
                    warden.moved,
                    warden.look_from,
                    warden.sighting.share,
                    warden.sighting.visibility,
                    warden.sighting.distance,
                ])
                .option(warden.last_seen);
            mind.0.write(&(warden.next as u64).to_le_bytes());
            mind.0.write(&(warden.path.len() as u64).to_le_bytes());
            for point in &warden.path {
                mind.vec3(*point);
            }
            let errand = warden.relight.map(|lamp| names(world, lamp));
            mind.bytes(errand.as_deref().unwrap_or("").as_bytes());
            push(format!("{name} mind"), &mind);
        }

        // Level lamps on or off.
        let mut lamps: Vec<(String, bool)> = world
            .query_filtered::<(&Name, Has<SwitchedOff>), (With<PunctualLight>, With<LevelEntity>)>()
            .iter(world)
            .map(|(name, off)| (name.as_str().to_owned(), off))
            .collect();
        lamps.sort();
        let mut lamp_part = Part::default();
        for (name, off) in &lamps {
            lamp_part.bytes(name.as_bytes()).flags(&[*off]);
        }
        push("lamps".into(), &lamp_part);

        // Knocked things.
        let mut knocked: Vec<(String, Option<(f32, Vec3)>, [f32; 4])> = world
            .query::<(&Name, &Knockable, &Transform)>()
            .iter(world)
            .map(|(name, thing, placed)| {
                (
                    name.as_str().to_owned(),
                    thing.fallen,
                    placed.rotation.to_array(),
                )
            })
            .collect();
        knocked.sort_by(|a, b| a.0.cmp(&b.0));
        let mut knock_part = Part::default();
        for (name, fallen, rotation) in &knocked {
            knock_part.bytes(name.as_bytes()).f32s(rotation);
            match fallen {
                Some((seconds, axis)) => knock_part.flags(&[true]).f32s(&[*seconds]).vec3(*axis),
                None => knock_part.flags(&[false]),
            };
        }
        push("knocked things".into(), &knock_part);

        // Movers.
        let mut movers: Vec<(String, f64, Vec3)> = world
            .query::<(&Name, &Patrol, &Transform)>()
            .iter(world)
            .map(|(name, patrol, placed)| {
                (name.as_str().to_owned(), patrol.elapsed, placed.translation)
            })
            .collect();
        movers.sort_by(|a, b| a.0.cmp(&b.0));
        let mut mover_part = Part::default();
        for (name, elapsed, at) in &movers {
            mover_part
                .bytes(name.as_bytes())
                .f64s(&[*elapsed])
                .vec3(*at);
        }
        push("movers".into(), &mover_part);

        // Animation clocks: clips (by the entity's name) and deformers.
        let mut clips: Vec<(String, usize, f64, f32)> = world
            .query::<(Entity, &Animator)>()
            .iter(world)
            .map(|(entity, animator)| {
                (
                    names(world, entity),
                    animator.clip,
                    animator.elapsed,
                    animator.speed,
                )
            })
            .collect();
        clips.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.total_cmp(&b.2)));
        let mut deformers: Vec<(String, f64)> = world
            .query::<(Entity, &Deformer)>()
            .iter(world)
            .map(|(entity, deformer)| (names(world, entity), deformer.time))
            .collect();
        deformers.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)));
        let mut clock_part = Part::default();
        for (name, clip, elapsed, speed) in &clips {
            clock_part
                .bytes(name.as_bytes())
                .f64s(&[*elapsed])
                .f32s(&[*speed]);
            clock_part.0.write(&(*clip as u64).to_le_bytes());
        }
        for (name, time) in &deformers {
            clock_part.bytes(name.as_bytes()).f64s(&[*time]);
        }
        push("clips".into(), &clock_part);

        // Shards left.
        let mut shards: Vec<String> = world
            .query_filtered::<&Name, With<Shard>>()
            .iter(world)
            .map(|name| name.as_str().to_owned())
            .collect();
        shards.sort();
        let mut shard_part = Part::default();
        for name in &shards {
            shard_part.bytes(name.as_bytes());
        }
        push("shards left".into(), &shard_part);

        // Noises still ringing.
        let mut noise_part = Part::default();
        if let Some(noises) = world.get_resource::<Noises>() {
            for noise in &noises.0 {
                noise_part.vec3(noise.at).f32s(&[noise.radius, noise.age]);
            }
        }
        push("noises".into(), &noise_part);

        // The attempt.
        let mut progress_part = Part::default();
        if let Some(progress) = world.get_resource::<Progress>() {
            progress_part.0.write(&progress.steps.to_le_bytes());
            progress_part.0.write(&progress.shards_taken.to_le_bytes());
            progress_part.0.write(&progress.times_seen.to_le_bytes());
            progress_part.bytes(progress.outcome.name().as_bytes());
            progress_part.flags(&[progress.noclip_used]);
        }
        push("progress".into(), &progress_part);

        StateParts(parts)
    }

    /// The whole state's hash: every part's name and hash in order.
    pub fn hash(&self) -> u64 {
        let mut hash = Fnv64::default();
        for part in &self.0 {
            hash.write(part.name.as_bytes());
            hash.write(&part.hash.to_le_bytes());
        }
        hash.0
    }

    /// The first part (in order) whose hash differs from `other`'s, or that one of the two
    /// lacks; None when they agree.
    pub fn first_difference(&self, other: &StateParts) -> Option<String> {
        for part in &self.0 {
            match other.0.iter().find(|p| p.name == part.name) {
                Some(theirs) if theirs.hash == part.hash => {}
                Some(_) => return Some(part.name.clone()),
                None => return Some(format!("{} (not in the recording)", part.name)),
            }
        }
        other
            .0
            .iter()
            .find(|p| !self.0.iter().any(|mine| mine.name == p.name))
            .map(|p| format!("{} (no longer in the world)", p.name))
    }
}
