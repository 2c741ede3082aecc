//! Audio, beside the frame line after the simulation: what the player's ears hear of
//! each fixed step, by the level's own acoustics (`game::acoustics`: the rays the
//! wardens' hearing uses too), mixed and played.
//!
//! - `hearing`: after each fixed step (`Stage::Audio`), the step's sources, events, room
//!   and tension as the mixer's commands;
//! - `mixer`: the commands made into 48 kHz stereo, the same bytes on any machine;
//! - `device`: the mixer played live on the audio device (kira, cpal), or silence where
//!   there is none.
//!
//! Headless, the same mixer renders a replay's sound (`gloam play --headless --replay
//! REC --audio OUT.wav`) and what ears at one place hear (`gloam listen`).

pub mod device;
pub mod hearing;
pub mod mixer;

pub use device::Device;
pub use hearing::{Hearing, load_clip};
pub use mixer::{Bus, Clip, Command, Mix, Mixer, STEP_FRAMES, Stereo, Volumes};
