//! Every run with no window, which the command line and the window (the editor's
//! play-check) both call; nothing here knows either. Outside the frame: these drive the
//! frame driver's own steps (`frame::Engine`).
//! - `replay`: a recording replayed step by step, checked against its trail;
//! - `autoplay`: the player bot, which plays a level to its end and records the run;
//! - `exposure`: the exposure map of a level as authored, which `gloam exposure` writes
//!   and the editor's overlay draws;
//! - `listen`: what ears at a place hear, mixed offline;
//! - `bench`: the measurement tools (`bench`, `raybench`, `flythrough`, `convergence`
//!   and the exposure map), which time the engine's steps and write reports;
//! - `values`: the checks on the runs' option values (counts, sizes, ranges), which the
//!   command line's own flags share.

pub mod autoplay;
pub mod bench;
pub mod exposure;
pub mod listen;
pub mod replay;
pub mod values;
