//! Gloam: a first-person stealth game path traced on the CPU, and the engine under it.
//!
//! The frame, left to right (no step reaches back): winit events -> input -> game (fixed
//! 60 Hz simulation steps) -> extract (ECS -> `RenderScene`) -> accel (refit deformed
//! BLASes, rebuild the TLAS) -> render -> film -> present. One module per step:
//! - `app`: the window (winit + pixels), input bindings, HUD, presenting.
//! - `frame`: the frame driver, which runs the steps below in order and times each
//!   under its `profile::Stage`.
//! - `game`: the simulation: ECS components, input, gameplay, animation, transforms;
//!   spawning a level into the world and writing it back.
//! - `extract`: the ECS made into the `RenderScene` every frame from change detection;
//!   skinning, morphs and deformers with their BLAS refits.
//! - `accel`: BLAS per mesh (refit when deforming), TLAS rebuilt per frame, ray queries.
//! - `render`: camera, samplers, BSDFs, lights, path and reference integrators, the image.
//! - `film`: accumulation and the real-time filters (temporal, a-trous, remodulation).
//! - `scene`: load time: glTF import, the asset cache, the level format, validation,
//!   asset generators.
//! - `profile`: the `Stage` list, per-stage frame statistics and the bench reports (JSON,
//!   CSV, Chrome trace, PNG chart).
//! - `simd`: which vector kernels run (the CPU's best or the portable ones), for the whole
//!   process; accel, render and film ask it before every AVX2 build.
//! - `audio`: what the ears hear, mixed (the offline mixer of `gloam listen`).
//! - `headless`: runs with no window, which the command line and the window both call:
//!   replays of recordings and the player bot (`autoplay`).
//! - `bench`: the measurement tools behind `bench`, `raybench`, `flythrough` and
//!   `convergence`.
//! - `cli`: the `gloam` command line (`main.rs` only calls `cli::main`): it parses flags
//!   and calls the library.

pub mod accel;
pub mod app;
pub mod audio;
pub mod bench;
pub mod cli;
pub mod edit;
pub mod extract;
pub mod film;
pub mod frame;
pub mod game;
pub mod headless;
pub mod profile;
pub mod render;
pub mod scene;
pub mod simd;
