//! Recordings: every fixed step's input of one attempt at a level, and the level it ran,
//! so a play-through can be replayed exactly (the simulation depends only on its inputs).
//!
//! A recording is JSON: `{"version": 2, "level": path relative to the recording,
//! "level_hash": FNV-1a 64 of the level file as 16 hex digits, "ended": "quit" | "won" |
//! "caught" | "inputs", "steps": [[held, pressed, look_x, look_y], ...], "trail":
//! [{"step": N, "hash": 16 hex digits, "parts": [[name, 16 hex digits], ...]}, ...]}`:
//! one entry in `steps` per 60 Hz step, the actions held and pressed as bit sets
//! (`Action::bit`) and the mouse look applied in that step (radians); one `trail` mark
//! every `TRAIL_EVERY` steps, the state after that step (`state::StateParts`), so a replay
//! finds the first step and part where it goes another way. Version 1 (no trail) still
//! reads. A recording of another version of the level is refused.

use serde::{Deserialize, Serialize};

use super::{Action, Input};

/// The recording format this build writes.
pub const RECORDING_VERSION: u32 = 2;

/// The oldest recording format this build still reads (version 1 has no trail).
pub const OLDEST_RECORDING_VERSION: u32 = 1;

/// Steps between two marks of a recording's trail (one a second).
pub const TRAIL_EVERY: usize = 60;

/// One step's input: held and pressed actions as bit sets, and the look applied.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct StepInput(pub u16, pub u16, pub f32, pub f32);

impl StepInput {
    /// The input a step is about to consume.
    pub fn of(input: &Input) -> StepInput {
        let bits = |set: &std::collections::HashSet<Action>| {
            set.iter().fold(0u16, |bits, action| bits | action.bit())
        };
        StepInput(
            bits(&input.held),
            bits(&input.pressed),
            input.look.x,
            input.look.y,
        )
    }

    /// Puts this step's input into `input` (replacing what was there).
    pub fn apply(&self, input: &mut Input) {
        let actions = |bits: u16| {
            Action::ALL
                .into_iter()
                .filter(|action| bits & action.bit() != 0)
                .collect()
        };
        input.held = actions(self.0);
        input.pressed = actions(self.1);
        input.look = glam::Vec2::new(self.2, self.3);
    }
}

/// How a recorded attempt ended.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Ended {
    /// The player quit.
    Quit,
    Won,
    Caught,
    /// The recording stopped (the window closed) with the attempt still going.
    #[default]
    Inputs,
}

/// One attempt at a level.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Recording {
    pub version: u32,
    /// The level, relative to the recording's folder.
    pub level: String,
    /// FNV-1a 64 of the level file's bytes, 16 hex digits.
    pub level_hash: String,
    pub ended: Ended,
    pub steps: Vec<StepInput>,
    /// The state every `TRAIL_EVERY` steps (empty in version 1).
    #[serde(default)]
    pub trail: Vec<TrailMark>,
}

/// The state after one step of a recording, whole and part by part.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrailMark {
    /// Steps run (the mark follows this many).
    pub step: usize,
    /// `StateParts::hash`, 16 hex digits.
    pub hash: String,
    /// Each part's name and hash (16 hex digits), in `StateParts` order.
    pub parts: Vec<(String, String)>,
}

impl TrailMark {
    pub fn new(step: usize, state: &super::state::StateParts) -> TrailMark {
        TrailMark {
            step,
            hash: format!("{:016x}", state.hash()),
            parts: state
                .0
                .iter()
                .map(|part| (part.name.clone(), format!("{:016x}", part.hash)))
                .collect(),
        }
    }

    /// The mark's parts as `StateParts` (a part whose hash does not parse counts as
    /// differing from anything).
    pub fn state(&self) -> super::state::StateParts {
        super::state::StateParts(
            self.parts
                .iter()
                .map(|(name, hash)| super::state::StatePart {
                    name: name.clone(),
                    hash: u64::from_str_radix(hash, 16).unwrap_or(u64::MAX),
                })
                .collect(),
        )
    }
}

/// What a run keeps while it is recorded: each step's input as the step found it, and the
/// trail.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Recorder {
    pub steps: Vec<StepInput>,
    pub trail: Vec<TrailMark>,
}

impl Recorder {
    /// Keeps the state after the step just recorded, when it is a trail mark's.
    pub fn after_step(&mut self, world: &mut bevy_ecs::world::World) {
        let step = self.steps.len();
        if step > 0 && step % TRAIL_EVERY == 0 {
            let state = super::state::StateParts::of(world);
            self.trail.push(TrailMark::new(step, &state));
        }
    }
}

/// FNV-1a, 64 bits (Fowler, Noll and Vo): a small, stable hash for file identity and
/// simulation states (not for security).
#[derive(Clone, Copy, Debug)]
pub struct Fnv64(pub u64);

impl Default for Fnv64 {
    fn default() -> Self {
        Fnv64(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv64 {
    pub fn write(&mut self, bytes: &[u8]) {
        for &byte in bytes {
            self.0 = (self.0 ^ byte as u64).wrapping_mul(0x0000_0100_0000_01b3);
        }
    }

    pub fn hex(&self) -> String {
        format!("{:016x}", self.0)
    }
}

/// The level hash a recording names its level by.
pub fn level_hash(bytes: &[u8]) -> String {
    let mut hash = Fnv64::default();
    hash.write(bytes);
    hash.hex()
}
