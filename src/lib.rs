//! Gloam: a first-person stealth game path traced on the CPU, and the engine under it.
//!
//! The frame, left to right (see DESIGN.md): winit events -> input -> game schedule ->
//! extract -> accel -> render -> film -> present. This crate grows one module per step;
//! what exists today:
//! - `app`: the window (winit + pixels), input bindings, HUD, presenting.
//! - `game`: ECS components, transforms, the fixed-step and frame schedules (headless).
//! - `scene`: load time — glTF import, the level format, validation, asset generators.
//! - `extract`: scene data to the `RenderScene` (headless path today; the ECS path later).
//! - `accel`: BLAS per mesh (refit when deforming), TLAS rebuilt per frame, ray queries.
//! - `render`: camera, samplers, BSDFs, lights, path and reference integrators, film.
//! - `cli`: the `gloam` command line (`main.rs` only calls `cli::main`), with `raybench`
//!   and `convergence`.

pub mod accel;
pub mod app;
pub mod cli;
pub mod extract;
pub mod game;
pub mod render;
pub mod scene;
