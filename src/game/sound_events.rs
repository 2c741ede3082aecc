//! Game schedule, fixed step "gameplay", last: what the step sounded like. `hear_the_step`
//! compares the world with how the last step left it and lists every sound a game event
//! made in `SoundEvents`: which file of the sound kit (`scene::sound_kit`), where, how loud
//! at 1 m, who made it and its caption. The audio, the captions and the wardens' hearing
//! read the list; nothing in the simulation depends on it, so it is not part of the state
//! hash and a replay makes the same list again.
//!
//! The events, per step:
//! - the player's footsteps: one per stride walked on the ground (0.55 m crouched, 0.8 m
//!   walking, 1.2 m sprinting), on the surface under the feet (a ray down through the
//!   level), the kit's two variants in turn; a landing from a fall faster than 2 m/s,
//!   louder the harder;
//! - a knocked thing toppling, and crashing as it lies flat;
//! - a lamp doused or lit;
//! - a shard taken;
//! - a thing the level animates starting to slide (the kit's gate, rising or falling on
//!   its chains): its animated nodes still last step and moving now;
//! - a warden's boots every 0.9 m walked, its armour every second step, and its voice on
//!   each change of mind: curious (suspicious), searching, the alarm (or the catch, when
//!   no alarm came first), giving up.

use std::collections::BTreeMap;

use bevy_ecs::prelude::*;
use glam::Vec3;

use super::noise::{Knockable, tuning::TOPPLE_SECONDS};
use super::player::Player;
use super::warden::{Warden, WardenState};
use super::world_query::{Surface, WorldGeometry};
use super::{
    AnimationSource, Animator, GlobalTransform, LevelEntity, PunctualLight, Shard, SwitchedOff,
    Transform,
};
use crate::scene::sound_kit::{Gait, STEP_VARIANTS, footstep_name};

/// Who made a sound.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum SoundMaker {
    Player,
    /// A warden, by name.
    Warden(String),
    /// A thing in the level (a lamp, a bottle, a shard), by name.
    Thing(String),
}

/// One sound a game event made this step.
#[derive(Clone, Debug, PartialEq)]
pub struct SoundEvent {
    /// The sound kit's file, by name (`assets/sounds/<sound>.wav`).
    pub sound: String,
    /// Where it was made.
    pub at: Vec3,
    /// Its level at 1 m against the file's own, decibels.
    pub gain_db: f32,
    pub by: SoundMaker,
    /// What a caption says of it, and how far away.
    pub caption: Caption,
}

/// A sound's caption: its words, and how far away a caption shows it, metres (0: never,
/// for the player's own footsteps and pickups, which go without saying). A distance in the
/// open, until the sound's propagation through the level says what is heard.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Caption {
    pub text: &'static str,
    pub within: f32,
}

const fn caption(text: &'static str, within: f32) -> Caption {
    Caption { text, within }
}

const FOOTSTEPS: Caption = caption("footsteps", 0.0);
const LANDING: Caption = caption("a landing", 0.0);
const SHARD: Caption = caption("a shard taken", 0.0);
const WARDEN_STEPS: Caption = caption("a warden's footsteps", 12.0);
/// Heard with the footsteps, so captioned by them.
const ARMOUR: Caption = caption("armour clinks", 0.0);
const CURIOUS: Caption = caption("a warden: \"Hm?\"", 25.0);
const SEARCHING: Caption = caption("a warden: \"Who's there?\"", 25.0);
const ALARM: Caption = caption("a warden: \"Intruder!\"", 25.0);
const GIVES_UP: Caption = caption("a warden gives up", 25.0);
const LAMP_OUT: Caption = caption("a lamp goes out", 12.0);
const LAMP_LIT: Caption = caption("a lamp is lit", 12.0);
const TOPPLES: Caption = caption("something topples", 20.0);
const BREAKS: Caption = caption("a bottle breaks", 20.0);
const CHAINS: Caption = caption("chains rattle", 30.0);

/// This step's sounds, and what the last step left, to tell what changed.
#[derive(Resource, Default, Debug)]
pub struct SoundEvents {
    pub events: Vec<SoundEvent>,
    /// Every step's events since a frame last took them (`take`): a frame may run several
    /// steps. Only the newest `PENDING_MAX` are kept for a reader that never comes.
    pending: std::collections::VecDeque<SoundEvent>,
    memory: Memory,
}

/// The most events kept for a frame to take.
const PENDING_MAX: usize = 256;

impl SoundEvents {
    /// The events of every step since the last call, oldest first.
    pub fn take(&mut self) -> Vec<SoundEvent> {
        self.pending.drain(..).collect()
    }
}

#[derive(Default, Debug)]
struct Memory {
    started: bool,
    player: Option<Feet>,
    wardens: BTreeMap<Entity, (Feet, WardenState)>,
    lamps: BTreeMap<Entity, bool>,
    shards: BTreeMap<Entity, (String, Vec3)>,
    knocked: BTreeMap<Entity, u8>,
    /// Per animated entity: where its nodes stood (summed), and whether they were moving.
    sliding: BTreeMap<Entity, (Vec3, bool)>,
}

/// A body's feet as the last step left them.
#[derive(Clone, Copy, Debug, Default)]
struct Feet {
    at: Vec3,
    grounded: bool,
    falling: f32,
    /// Metres walked since the last footstep.
    walked: f32,
    /// Footsteps so far (the variant and the armour follow it).
    steps: u32,
}

/// Footsteps and their captions, in one place (metres, m/s).
pub mod tuning {
    /// Metres between the player's footsteps, by gait.
    pub const STRIDE_CROUCH: f32 = 0.55;
    pub const STRIDE_WALK: f32 = 0.8;
    pub const STRIDE_SPRINT: f32 = 1.2;
    /// Metres between a warden's footsteps.
    pub const WARDEN_STRIDE: f32 = 0.9;
    /// The fall speed (m/s) from which a landing is heard; at the noise's `LANDING_SPEED`
    /// it is at the file's level, 6 dB up for each doubling.
    pub const LANDING_HEARD: f32 = 2.0;
}

use tuning::*;

/// A knocked thing's progress: standing, toppling, flat.
const TOPPLING: u8 = 1;
const FLAT: u8 = 2;

/// Fixed step, last of "gameplay": this step's sounds (see the module doc).
#[allow(clippy::type_complexity)]
pub fn hear_the_step(
    sounds: Option<ResMut<SoundEvents>>,
    geometry: Option<Res<WorldGeometry>>,
    players: Query<(&Player, &Transform)>,
    wardens: Query<(Entity, &Name, &Warden, &Transform)>,
    lamps: Query<
        (Entity, &Name, &GlobalTransform, Has<SwitchedOff>),
        (With<PunctualLight>, With<LevelEntity>),
    >,
    shards: Query<(Entity, &Name, &Transform), With<Shard>>,
    knockables: Query<(Entity, &Name, &Knockable, &Transform)>,
    animated: Query<(Entity, &Name, &Animator, &Transform), With<AnimationSource>>,
    nodes: Query<&Transform>,
) {
    let Some(mut sounds) = sounds else { return };
    let SoundEvents {
        events,
        pending,
        memory,
    } = &mut *sounds;
    events.clear();
    let first = !std::mem::replace(&mut memory.started, true);
    let mut event = |sound: String, at: Vec3, gain_db: f32, by: SoundMaker, caption| {
        if !first {
            events.push(SoundEvent {
                sound,
                at,
                gain_db,
                by,
                caption,
            });
        }
    };

    // The player's feet.
    if let Some((player, body)) = players.iter().next() {
        let at = body.translation;
        let mut feet = memory.player.unwrap_or(Feet {
            at,
            grounded: player.grounded,
            ..Feet::default()
        });
        if player.noclip {
            feet.walked = 0.0;
        } else if player.grounded {
            if !feet.grounded && feet.falling > LANDING_HEARD {
                let gain = 20.0 * (feet.falling / super::noise::tuning::LANDING_SPEED).log10();
                event(
                    "landing".into(),
                    at,
                    gain.clamp(-12.0, 6.0),
                    SoundMaker::Player,
                    LANDING,
                );
            }
            feet.walked += horizontal(at - feet.at);
            let gait = if player.sprinting {
                Gait::Sprint
            } else if player.crouched {
                Gait::Crouch
            } else {
                Gait::Walk
            };
            let stride = match gait {
                Gait::Crouch => STRIDE_CROUCH,
                Gait::Walk => STRIDE_WALK,
                Gait::Sprint => STRIDE_SPRINT,
            };
            if feet.walked >= stride {
                feet.walked -= stride;
                feet.steps += 1;
                let surface = geometry
                    .as_ref()
                    .and_then(|g| g.0.raycast(at + Vec3::Y * 0.2, Vec3::NEG_Y, 0.6))
                    .map_or(Surface::Stone, |hit| hit.surface);
                let variant = feet.steps % STEP_VARIANTS + 1;
                event(
                    footstep_name(surface, gait, variant),
                    at,
                    0.0,
                    SoundMaker::Player,
                    FOOTSTEPS,
                );
            }
        } else {
            feet.walked = 0.0;
        }
        feet.at = at;
        feet.grounded = player.grounded;
        feet.falling = -player.velocity.y;
        memory.player = Some(feet);
    }

    // The wardens: boots, armour and voice.
    for (entity, name, warden, body) in &wardens {
        let at = body.translation;
        let (mut feet, before) = memory.wardens.get(&entity).copied().unwrap_or((
            Feet {
                at,
                ..Feet::default()
            },
            warden.state,
        ));
        let by = || SoundMaker::Warden(name.as_str().to_owned());
        feet.walked += horizontal(at - feet.at);
        if feet.walked >= WARDEN_STRIDE {
            feet.walked -= WARDEN_STRIDE;
            feet.steps += 1;
            let variant = feet.steps % 2 + 1;
            event(
                format!("warden-step-{variant}"),
                at,
                0.0,
                by(),
                WARDEN_STEPS,
            );
            if feet.steps % 2 == 0 {
                event("warden-armour".into(), at, 0.0, by(), ARMOUR);
            }
        }
        let voice = at + Vec3::Y * super::noise::tuning::EAR_HEIGHT;
        let cue = match (before, warden.state) {
            (a, b) if a == b => None,
            (_, WardenState::Suspicious) => Some(("warden-curious", CURIOUS)),
            (_, WardenState::Searching) => Some(("warden-searching", SEARCHING)),
            // A catch with no alarm before it (seen close enough to be caught at once)
            // is called out as one.
            (WardenState::Alert, WardenState::Caught) => None,
            (_, WardenState::Alert | WardenState::Caught) => Some(("warden-alarm", ALARM)),
            (WardenState::Suspicious | WardenState::Searching, WardenState::Patrol) => {
                Some(("warden-gives-up", GIVES_UP))
            }
            _ => None,
        };
        if let Some((sound, caption)) = cue {
            event(sound.into(), voice, 0.0, by(), caption);
        }
        feet.at = at;
        memory.wardens.insert(entity, (feet, warden.state));
    }

    // Lamps doused and lit.
    for (entity, name, placed, off) in &lamps {
        let was_off = memory.lamps.insert(entity, off);
        if was_off.is_some_and(|was| was != off) {
            let (sound, caption) = if off {
                ("lamp-douse", LAMP_OUT)
            } else {
                ("lamp-light", LAMP_LIT)
            };
            let at = placed.0.translation.into();
            event(
                sound.into(),
                at,
                0.0,
                SoundMaker::Thing(name.as_str().to_owned()),
                caption,
            );
        }
    }

    // Shards taken: there last step, gone now. A shard is remembered once, when first
    // seen, so a quiet step allocates nothing.
    let taken: Vec<Entity> = memory
        .shards
        .keys()
        .copied()
        .filter(|&entity| !shards.contains(entity))
        .collect();
    for entity in taken {
        if let Some((name, at)) = memory.shards.remove(&entity) {
            event("shard".into(), at, 0.0, SoundMaker::Thing(name), SHARD);
        }
    }
    for (entity, name, placed) in &shards {
        memory
            .shards
            .entry(entity)
            .or_insert_with(|| (name.as_str().to_owned(), placed.translation));
    }

    // Knocked things: the topple, then the crash as they lie flat.
    for (entity, name, thing, placed) in &knockables {
        let now = match thing.fallen {
            None => 0,
            Some((seconds, _)) if seconds < TOPPLE_SECONDS => TOPPLING,
            Some(_) => FLAT,
        };
        let before = memory.knocked.insert(entity, now).unwrap_or(now);
        let by = || SoundMaker::Thing(name.as_str().to_owned());
        let at = placed.translation;
        if before == 0 && now >= TOPPLING {
            event("bottle-topple".into(), at, 0.0, by(), TOPPLES);
        }
        if before < FLAT && now == FLAT {
            event("bottle-break".into(), at, 0.0, by(), BREAKS);
        }
    }

    // Animated things that start to slide.
    for (entity, name, animator, placed) in &animated {
        let stood: Vec3 = animator
            .nodes
            .iter()
            .filter_map(|&node| nodes.get(node).ok())
            .map(|node| node.translation)
            .sum();
        let (before, was_moving) = memory
            .sliding
            .get(&entity)
            .copied()
            .unwrap_or((stood, true));
        let moving = (stood - before).length() > SLIDING;
        if moving && !was_moving {
            event(
                "gate-chains".into(),
                placed.translation,
                0.0,
                SoundMaker::Thing(name.as_str().to_owned()),
                CHAINS,
            );
        }
        memory.sliding.insert(entity, (stood, moving));
    }

    pending.extend(events.iter().cloned());
    while pending.len() > PENDING_MAX {
        pending.pop_front();
    }
}

/// Metres a node must move in a step to count as moving (a gate's chains run at about
/// 1.5 m/s, 25 mm a step).
const SLIDING: f32 = 1e-4;

fn horizontal(v: Vec3) -> f32 {
    Vec3::new(v.x, 0.0, v.z).length()
}
