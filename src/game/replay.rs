//! Recordings: every fixed step's input of one attempt at a level, and the level it ran,
//! so a play-through can be replayed exactly (the simulation depends only on its inputs).
//!
//! A recording is JSON: `{"version": 1, "level": path relative to the recording,
//! "level_hash": FNV-1a 64 of the level file as 16 hex digits, "ended": "quit" | "won" |
//! "caught" | "inputs", "steps": [[held, pressed, look_x, look_y], ...]}`, one entry per
//! 60 Hz step: the actions held and pressed as bit sets (`Action::bit`), and the mouse look
//! applied in that step (radians). A recording of another version of the level is refused.

use serde::{Deserialize, Serialize};

use super::{Action, Input};

/// The recording format this build reads and writes.
pub const RECORDING_VERSION: u32 = 1;

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
