//! Gloam: a first-person stealth game path traced on the CPU, and the engine under it.
//!
//! This page is how Gloam is built: what a contributor needs to know before changing
//! anything. The README says how to build, play and test; each module's own page says what
//! it owns and how it works.
//!
//! # Conventions (one set, everywhere)
//!
//! - **Space:** glTF's. Right-handed, +Y up, metres; a camera looks down its local -Z; a
//!   warden or a player body faces its model's +Z.
//! - **Colour:** linear Rec.709 RGB floats inside; sRGB-encoded RGBA8 only at the very end
//!   (PNG files and the window, through one tone mapper, [`render::hdr::tone_map`]).
//! - **Radiometry:** an emissive surface's radiance is emissiveFactor x
//!   `KHR_materials_emissive_strength` (x emissiveTexture), in W/(sr m^2). Point and spot
//!   intensities are radiant intensity in W/sr (radiance at distance d is I/d^2);
//!   directional intensity is irradiance in W/m^2. No hidden scale factors: a white
//!   Lambertian furnace returns exactly the light it receives.
//! - **Materials:** glTF metallic-roughness ([`render::material`]). Base colour (x texture)
//!   is the albedo; metallic 0 and transmission 0 is Lambertian; metallic 1 is a conductor
//!   (a perfect mirror at roughness 0, GGX otherwise); transmission 1 is a dielectric with
//!   the glTF ior (default 1.5).
//! - **Pixel value:** `gloam render --out x.exr` writes mean radiance over the pixel's area
//!   (box filter, uniform jitter), no exposure and no tone mapping, so it compares with any
//!   reference renderer ([`render::hdr`]).
//! - **Determinism:** every random number derives from (seed, frame index, pixel, sample
//!   dimension); the simulation runs at a fixed 60 Hz step and depends only on its inputs
//!   and seed. The same inputs give bit-identical images and game states on any thread
//!   count and with either SIMD build ([`simd`]), so replays are tests.
//!
//! # The frame
//!
//! One line, left to right; no step reaches back, and the profiler times every arrow under
//! its [`profile::Stage`]:
//!
//! ```text
//! winit events -> Input resource -> simulate (fixed 60 Hz steps: input, gameplay,
//! animation, transforms; then what the player hears) -> extract (ECS -> RenderScene;
//! deformed meshes reshaped) -> accel (deformed BLASes refit, the TLAS rebuilt) -> render
//! (the frame the film orders; rayon over tiles: camera rays, path tracing with next
//! event estimation) -> film (accumulate, or reproject, filter and upscale) -> present
//! (tone map into pixels' frame buffer, the interface over it, to the window)
//! ```
//!
//! The frame driver, [`frame::Engine`], runs the five steps from simulate to film by name
//! and in order (`Engine::advance`) and times each; the window and every headless tool
//! drive it, and the window presents. Rendering is
//! interpolated between the last two simulation steps, so the frame rate and the
//! simulation's 60 Hz are independent.
//!
//! # Modules, and who may use whom
//!
//! One crate, `gloam` (this library plus a thin binary: `main.rs` only calls `cli::main`),
//! one module per step of the frame, and data runs one way through them: game (simulation)
//! -> extract -> accel -> render -> film -> app. [`render`] and [`accel`] never see the ECS
//! or a window, so they run headless in tests; [`game`] never sees render, accel, the film
//! or a window: it asks the world its questions (rays for exposure and sight, sphere
//! contacts for collision) through a trait it defines, [`game::WorldQuery`], and holds as a
//! resource, which extract answers over accel as of the current fixed step, and tests
//! answer with a fake world. The command line only parses flags and calls the library.
//!
//! - [`app`]: the window (winit + pixels): input bindings and gamepads, the HUD, the menus,
//!   settings files, F12 screenshots, presenting; and the editor's window
//!   ([`app::editor`]: egui drawn on pixels' wgpu device, the path-traced view an image
//!   inside it).
//! - [`frame`]: the frame driver, which runs the steps below in order and times each
//!   under its [`profile::Stage`].
//! - [`game`]: the simulation and nothing else: ECS components and resources, input as
//!   actions, the player, the wardens, the light gem, noise, the goal, clip playback and
//!   transforms, the fixed-step schedules (one per stage), putting a level into the world
//!   and writing it back. It imports none of render, accel, the film, winit or pixels.
//! - [`extract`]: the only code that writes the `RenderScene`, from the ECS, every frame,
//!   by change detection, with the materials, the light set and skinning, morph targets,
//!   deformers and their BLAS refits; and the simulation's own copy of the level's
//!   geometry, which answers the game's questions.
//! - [`accel`]: BLASes, instances, static batches, the TLAS and ray queries.
//! - [`render`]: the camera, samplers, BSDFs, lights, integrators, the real-time view's
//!   radiance cache, the guides and the image ([`render::hdr`]: the `HdrImage` buffer,
//!   tone mapper, EXR/PNG writers and reader, comparison).
//! - [`film`]: every film step: accumulation, temporal reprojection, the a-trous filter, the
//!   chain that runs them, and temporal upscaling.
//! - [`scene`]: load time: glTF import, the asset cache, the level format, one scene model
//!   for levels and bare glTF files, diagnostics, safe file writing, clip sampling, hot
//!   reload's file watching and the asset generators. The only code that touches asset and
//!   level files.
//! - [`profile`]: the `Stage` list, per-stage statistics, the bench reports (JSON, CSV,
//!   Chrome trace, PNG chart) and the F3 overlay; not a step but a witness to all of them.
//! - [`simd`]: which vector kernels run (the CPU's best or the portable ones), for the whole
//!   process; accel, render and film ask it before every AVX2 build.
//! - [`audio`]: what the player's ears hear of each step, mixed and played (or mixed
//!   offline, headless).
//! - [`edit`]: the level editor's commands, plain functions on an engine's world between
//!   frames (select by ray, change, drag as one step, place, duplicate, delete, undo and
//!   redo, save, reload, autosave), its free-flying camera, its palette and its overlays'
//!   maps. It reads and writes level entities as their `EntityDef`s, so every edit is undone
//!   by putting the definitions back. Tests drive the commands headless.
//! - [`headless`]: every run with no window, which the command line and the window both
//!   call: replays of recordings, the player bot ([`headless::autoplay`]), what a place
//!   hears (`listen`) and the measurement tools ([`headless::bench`]), with the checks on
//!   their options' values.
//! - [`fuzz`]: the fuzz targets' bodies, which the test suite runs over their seeds.
//! - [`cli`]: the `gloam` command line: it parses flags and calls the library.
//!
//! # Rules for code
//!
//! - **Hot loops** (per ray, per pixel, per triangle): no allocation, lock or `Result`;
//!   `debug_assert!` for invariants; data laid out for the traversal, not for convenience;
//!   parallel work through rayon over tiles with per-thread scratch. SIMD kernels use
//!   `std::arch` behind run-time feature detection ([`simd`]), each with a portable twin the
//!   tests hold it to. Every optimisation lands with the number it bought, measured by the
//!   project's own benchmark commands (`bench`, `raybench`, `flythrough`) in a release
//!   build, medians of alternated runs; the comment over the loop says why, with that
//!   number.
//! - **Errors:** typed errors inside, `anyhow` with context at file and command-line edges;
//!   no `unwrap` on anything a user controls. Bad input (a level, an asset, a flag, a
//!   replay, a settings file) is one line naming the file and the place, never a panic and
//!   never a half-written file ([`scene::files::write_atomically`]).
//! - **One definition** of each concept (a stage list, a default, a format, a tuning
//!   number); the rest derive from it. Each module opens with a `//!` saying which step of
//!   the frame it is and what it owns, and cites the paper an algorithm comes from. The
//!   design is documented there, in rustdoc, and `.ci/run` builds it with warnings as
//!   errors.
//!
//! # The command line
//!
//! `gloam` (the main menu), `gloam LEVEL` (play it), and the subcommands `gloam --help`
//! lists, each with its own `--help`. Run as `cargo run --release -- <command>` or
//! `target/release/gloam <command>`. The contract every command keeps:
//!
//! - exit status 0 on success, 2 on a command line it cannot take, 1 when it runs and
//!   fails (a bad file); either way one line on stderr names what is wrong and where, never
//!   a panic or a backtrace for bad input. A missing argument is named with the help to
//!   read (``gloam: render needs --out and a SCENE (see `gloam render --help`)``), a number
//!   out of range names its flag and the range ([`headless::values`]);
//! - reports are JSON with the fields the modules that write them document (the bench
//!   tools: [`headless::bench`]; replays: [`headless::replay`]; the bot:
//!   [`headless::autoplay`]);
//! - output piped into a reader that stops early (`| head`) ends the program quietly, as
//!   any Unix tool;
//! - a command that runs long (`render`, `bench`, `flythrough`, `convergence`,
//!   `raybench`) draws a progress bar with the elapsed time and an estimate of the time
//!   left, on stderr and only on a terminal, never into a pipe or a log;
//! - what wgpu and winit report (a missing Vulkan driver, a lost surface) is logged to
//!   stderr: warnings and errors by default, more with `RUST_LOG` (`RUST_LOG=info`,
//!   `RUST_LOG=wgpu_core=debug`).
//!
//! # Testing
//!
//! `cargo test --release` is the whole suite, exactly as CI runs it (`.ci/run`, which
//! first installs what the tests below need when run as root).
//!
//! - **Correctness first:** the naive reference path tracer stays; every variance reduction
//!   (next event estimation, MIS, stratification, blue noise, reprojection) must converge to
//!   the same image. Analytic checks with a tolerance (a furnace: a closed box lit by its own
//!   walls, Le / (1 - rho); Lambert's formula for a polygonal light) are preferred over
//!   golden images.
//! - **Statistical tests** use fixed seeds and say their tolerance and why.
//! - **The game** is tested by replays: each shipped level has a winning and a caught
//!   recording in `tests/recordings/`, replayed by `tests/levels.rs`, and
//!   `tests/autoplay.rs` holds the player bot's runs to the winning ones (how to make them
//!   again after a rule change: [`headless::autoplay`]).
//! - **Windows:** a test that needs one runs under Xvfb with Mesa's software Vulkan;
//!   `.ci/run` installs what it needs. So does the glTF Validator test
//!   (`tests/gltf_validator.rs`: Node and the npm package `gltf-validator`). Outside CI
//!   (where the `CI` variable is unset) such tests print a notice and skip when their tools
//!   are missing. Tests that need test data kept outside the repository (the Khronos glTF
//!   samples, the benchmark apartment) print a notice and skip when it is absent.
//! - `cargo test --release` stays under 15 minutes on 2 cores; long soaks and benchmarks
//!   are commands, not tests.
//!
//! # Fuzzing
//!
//! `tests/fuzz` holds four [cargo-fuzz](https://github.com/rust-fuzz/cargo-fuzz) targets,
//! each one call into [`fuzz`], whose bodies go past parsing into what a file feeds:
//! `gltf` (import -> scene -> BLAS and TLAS builds -> one 8x8 frame), `level` (parse ->
//! validation -> assets -> spawn -> three steps and a frame), `replay` (a recording's
//! checks, then its first `fuzz::REPLAY_STEPS` steps replayed headless) and `settings`
//! (the settings and best-times files). `tests/fuzz_seeds.rs` runs the same bodies over
//! the seed files in the ordinary suite. The targets need nightly Rust and
//! `cargo install cargo-fuzz`; CI neither builds nor runs them. Run one from the
//! repository root, seeded with the shipped files (libFuzzer writes new inputs to the
//! first folder and reads the others); `-a` keeps overflow checks on, and `-s none` skips
//! AddressSanitizer, which a panic does not need:
//!
//! ```sh
//! cargo +nightly fuzz run -a -s none --fuzz-dir tests/fuzz gltf tests/fuzz/corpus/gltf \
//!     assets/kit -- -runs=1000000
//! cargo +nightly fuzz run -a -s none --fuzz-dir tests/fuzz level tests/fuzz/corpus/level \
//!     levels -- -runs=1000000
//! cargo +nightly fuzz run -a -s none --fuzz-dir tests/fuzz replay \
//!     tests/fuzz/corpus/replay tests/recordings -- -runs=1000000
//! cargo +nightly fuzz run -a -s none --fuzz-dir tests/fuzz settings \
//!     tests/fuzz/corpus/settings -- -runs=1000000
//! ```
//!
//! A crash is saved under `tests/fuzz/artifacts/<target>/`; each one fixed gets a
//! regression test in the ordinary suite (on stable), as `tests/bad_input.rs` and the
//! source map's tests hold the ones found so far.

pub mod accel;
pub mod app;
pub mod audio;
pub mod cli;
pub mod edit;
pub mod extract;
pub mod film;
pub mod frame;
pub mod fuzz;
pub mod game;
pub mod headless;
pub mod profile;
pub mod render;
pub mod scene;
pub mod simd;
