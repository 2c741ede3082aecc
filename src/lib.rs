//! Gloam: a first-person stealth game path traced on the CPU, and the engine under it.
//!
//! The frame, left to right (see DESIGN.md): winit events -> input -> game schedule ->
//! extract -> accel -> render -> film -> present. This crate grows one module per step;
//! what exists today:
//! - `scene`: load time — glTF import, the level format, validation, asset generators.
//! - `cli`: the `gloam` command line (`main.rs` only calls `cli::main`).

pub mod cli;
pub mod scene;
