//! Gloam: a first-person stealth game path traced on the CPU, and the engine under it.
//!
//! The frame, left to right (see DESIGN.md): winit events -> input -> game schedule ->
//! extract -> accel -> render -> film -> present. This crate grows one module per step;
//! what exists today:
//! - `app`: the window (winit + pixels), input bindings, HUD, presenting.
//! - `game`: ECS components, transforms, clip playback, skinning/morphs/deformers with
//!   their BLAS refits, the fixed-step and frame schedules (headless).
//! - `scene`: load time — glTF import, the level format, validation, asset generators.
//! - `extract`: scene data to the `RenderScene`; emitters that follow moved instances.
//! - `accel`: BLAS per mesh (refit when deforming), TLAS rebuilt per frame, ray queries.
//! - `render`: camera, samplers, BSDFs, lights, path and reference integrators, film.
//! - `profile`: per-stage frame statistics and the bench reports (JSON, CSV, Chrome trace,
//!   PNG chart).
//! - `cli`: the `gloam` command line (`main.rs` only calls `cli::main`), with `raybench`,
//!   `convergence` and `bench`.

pub mod accel;
pub mod app;
pub mod cli;
pub mod extract;
pub mod game;
pub mod profile;
pub mod render;
pub mod scene;
