//! `gloam bench`: a headless frame-time profile of a level along a fixed camera path.
//!
//! A measurement tool around the game's own frame loop. Loads the level into an `Engine`,
//! then for each frame: moves the view along a scripted path (a slow sway and dolly around
//! the level's camera), advances exactly one 60 Hz simulation step (so every run does the
//! same work: same poses, same rays), and records the stage times the schedules measured.
//! Warm-up frames are run first and dropped. After every `ACCEL_ROUND_FRAMES` measured
//! frames the level's accel alone traces a round of `raybench`'s rays on the same threads,
//! set beside the renderer's rays per second over those frames. The `profile` module
//! prints the table and writes the JSON, CSV, Chrome trace and PNG chart. With `--replay`,
//! the frames are a real play-through instead: the player fed one recorded step's input a
//! frame. With `--churn-instances` and `--churn-lights`, every other frame spawns things
//! into the world and the next despawns them, and extract + accel is reported per kind of
//! frame.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context as _;
use bevy_ecs::prelude::{Entity, With};
use glam::{Quat, Vec3};

use crate::frame::Engine;
use crate::game::replay::Recording;
use crate::game::{AssetInstance, Input, LevelEntity, Transform, ViewCamera, spawn, spawn_player};
use crate::profile::{AccelRound, Profile, Stage};
use crate::render::RenderSettings;
use crate::scene::level::{EntityDef, InstanceDef, LightDef};
use crate::scene::world::Scene;

#[derive(Debug, clap::Args)]
pub struct Options {
    /// The level (or glTF) to profile; levels/first-light.ron when omitted.
    #[arg(value_name = "SCENE")]
    pub level: Option<PathBuf>,
    /// Frames measured (after the warm-up).
    #[arg(long, default_value_t = 240, value_parser = crate::headless::values::count())]
    pub frames: u32,
    /// Frames run first and not measured (caches, page faults, the first BLAS refits).
    #[arg(long, default_value_t = 30, value_parser = crate::headless::values::count_or_zero())]
    pub warmup: u32,
    /// The render width, in pixels.
    #[arg(long, default_value_t = 480, value_parser = crate::headless::values::count())]
    pub width: u32,
    /// The render height, in pixels.
    #[arg(long, default_value_t = 270, value_parser = crate::headless::values::count())]
    pub height: u32,
    /// Worker threads (default: all cores), for scaling studies.
    #[arg(long, value_parser = crate::headless::values::size())]
    pub threads: Option<usize>,
    /// Which vector kernels run: the CPU's best, or the portable ones a CPU without AVX2
    /// runs (the same bits, timed).
    #[arg(long, value_enum, default_value_t = crate::simd::Simd::Native)]
    pub simd: crate::simd::Simd,
    /// Write the JSON report here (its fields: the `headless::bench` module's docs).
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Write a row per frame, a column per stage.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Write a Chrome trace (open it in Perfetto, ui.perfetto.dev, or chrome://tracing).
    #[arg(long)]
    pub trace: Option<PathBuf>,
    /// Write a PNG chart: stages stacked per frame, and a frame-time histogram.
    #[arg(long)]
    pub chart: Option<PathBuf>,
    /// Render at this scale of --width x --height per axis, and upscale the filtered
    /// frames to it (`film::upscale`), as the game does when its adaptive resolution
    /// lowers the render's; 1 renders at --width x --height.
    #[arg(long, default_value_t = 1.0, value_parser = crate::headless::values::share)]
    pub render_scale: f32,
    /// The film's filters, as in `play` (their cost is the `film` stage).
    #[arg(long, value_enum, default_value_t = crate::film::FilterMode::Full)]
    pub filter: crate::film::FilterMode,
    /// A world that changes while it runs: every other frame spawns this many instances
    /// of the level's first asset (in a grid on the floor) and the frame after despawns
    /// them; the table then splits extract + accel by spawning, despawning and quiet
    /// frames.
    #[arg(long, default_value_t = 0, value_parser = crate::headless::values::count_or_zero())]
    pub churn_instances: u32,
    /// ... and this many point lights with them.
    #[arg(long, default_value_t = 0, value_parser = crate::headless::values::count_or_zero())]
    pub churn_lights: u32,
    /// Profile a real play-through: the player at the recording's level start, fed one
    /// recorded step's input a frame, seen through its eyes (the measured frames end
    /// with the inputs). The recording names its level; LEVEL, if given, must be it.
    #[arg(long, value_name = "FILE")]
    pub replay: Option<PathBuf>,
}

/// What a measured frame did to the world (`--churn-*`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Churn {
    Quiet,
    Spawned,
    Despawned,
}

/// The view's offset from its start at `seconds` into the run: a +-20 degree sway and a
/// +-0.5 m dolly, periods 8 s and 5 s (a path that keeps moving, so nothing accumulates).
pub fn camera_path(start: &Transform, seconds: f64) -> Transform {
    use std::f64::consts::TAU;
    let yaw = 20f64.to_radians() * (TAU * seconds / 8.0).sin();
    let dolly = 0.5 * (TAU * seconds / 5.0).sin();
    let rotation = start.rotation * Quat::from_rotation_y(yaw as f32);
    Transform {
        translation: start.translation + rotation * Vec3::new(0.0, 0.0, -dolly as f32),
        rotation,
        scale: start.scale,
    }
}

/// The render's resolution: --width x --height at --render-scale.
fn render_size(options: &Options) -> (u32, u32) {
    let scaled = |n: u32| ((n as f32 * options.render_scale).round() as u32).max(1);
    (scaled(options.width), scaled(options.height))
}

pub fn run(options: &Options) -> anyhow::Result<()> {
    if options.width == 0 || options.height == 0 || options.frames == 0 {
        anyhow::bail!("--width, --height and --frames must be at least 1");
    }
    anyhow::ensure!(
        options.render_scale > 0.0,
        "--render-scale {}: must be above 0",
        options.render_scale
    );
    for path in [&options.json, &options.csv, &options.trace]
        .into_iter()
        .flatten()
    {
        if path.extension().and_then(|e| e.to_str()).is_none() {
            anyhow::bail!("{}: a report file needs an extension", path.display());
        }
    }
    if let Some(chart) = &options.chart
        && !chart
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| e.eq_ignore_ascii_case("png"))
    {
        anyhow::bail!("{}: the chart is a PNG; name it .png", chart.display());
    }
    let threads = options.threads.unwrap_or_else(super::default_threads);
    if threads == 0 {
        anyhow::bail!("--threads must be at least 1");
    }
    crate::simd::use_kernels(options.simd);
    let (recording, level) = match &options.replay {
        Some(path) => {
            let (recording, level) = crate::headless::replay::read_recording(path)?;
            if let Some(named) = &options.level {
                let same = std::fs::canonicalize(named).ok() == std::fs::canonicalize(&level).ok();
                if !same {
                    anyhow::bail!(
                        "{} was recorded on '{}', not '{}'",
                        path.display(),
                        level.display(),
                        named.display()
                    );
                }
            }
            (Some(recording), level)
        }
        None => (
            None,
            options
                .level
                .clone()
                .unwrap_or_else(crate::scene::files::default_level),
        ),
    };
    let scene = Scene::load(&level)?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .context("starting the worker threads")?;
    let (profile, churn) =
        pool.install(|| measure(&scene, &level, recording.as_ref(), threads, options))?;
    print!("{}", profile.table());
    // Extract + accel (extract, blas_refit, tlas_build) per kind of frame.
    let world_ms = |frame: &crate::profile::FrameSample| {
        [Stage::Extract, Stage::BlasRefit, Stage::TlasBuild]
            .iter()
            .map(|stage| frame.stages[stage.index()])
            .sum::<f64>()
    };
    for kind in [Churn::Quiet, Churn::Spawned, Churn::Despawned] {
        let (world, edits): (Vec<f64>, Vec<f64>) = profile
            .frames
            .iter()
            .zip(&churn)
            .filter(|(_, (k, _))| *k == kind)
            .map(|(frame, (_, edit_ms))| (world_ms(frame), *edit_ms))
            .unzip();
        if world.is_empty() {
            continue;
        }
        let (world, edits) = (
            crate::profile::Summary::of(&world),
            crate::profile::Summary::of(&edits),
        );
        let name = match kind {
            Churn::Quiet => "quiet",
            Churn::Spawned => "spawning",
            Churn::Despawned => "despawning",
        };
        print!(
            "extract+accel, {name} frames: p50 {:.3} ms, p99 {:.3} ms",
            world.p50, world.p99
        );
        if kind == Churn::Quiet {
            println!();
        } else {
            println!(
                "; the {name} calls before the frame: p50 {:.3} ms",
                edits.p50
            );
        }
    }
    profile.write_reports(
        options.json.as_deref(),
        options.csv.as_deref(),
        options.trace.as_deref(),
        options.chart.as_deref(),
    )?;
    for path in [&options.json, &options.csv, &options.trace, &options.chart]
        .into_iter()
        .flatten()
    {
        println!("wrote {}", path.display());
    }
    Ok(())
}

/// Measured frames between two timings of the accel alone: 8 rounds in a default run,
/// each about 40 ms of tracing on two threads.
const ACCEL_ROUND_FRAMES: usize = 30;

/// Runs the warm-up and the measured frames; returns the profile of the measured ones and
/// what each did to the world, with the milliseconds the spawn or despawn calls took.
fn measure(
    scene: &Scene,
    level: &std::path::Path,
    recording: Option<&Recording>,
    threads: usize,
    options: &Options,
) -> anyhow::Result<(Profile, Vec<(Churn, f64)>)> {
    let mut engine = Engine::new(
        scene,
        RenderSettings::real_time(options.width, options.height),
    );
    engine.film.filter.mode = options.filter;
    // Ears, as in play (the player's, or the view's on the camera path): their cost is
    // the `audio` stage. The mixing runs on the device's thread, off the frame, so the
    // commands are dropped here.
    engine.hearing = Some(crate::audio::Hearing::for_level(level));
    let (render_width, render_height) = render_size(options);
    engine.film.set_resolution(render_width, render_height);
    // A replay is seen through the player's eyes; otherwise the view takes its path.
    let view = if recording.is_some() {
        spawn_player(&mut engine.world)
            .with_context(|| format!("{}: the level has no player start", level.display()))?;
        None
    } else {
        let mut views = engine
            .world
            .query_filtered::<(Entity, &Transform), With<ViewCamera>>();
        views.iter(&engine.world).next().map(|(e, t)| (e, *t))
    };
    let churn_asset = if options.churn_instances > 0 {
        let mut instances = engine.world.query::<(&LevelEntity, &AssetInstance)>();
        let mut found: Vec<(usize, String)> = instances
            .iter(&engine.world)
            .map(|(order, instance)| (order.0, instance.path.clone()))
            .collect();
        found.sort();
        Some(
            found
                .into_iter()
                .next()
                .map(|(_, path)| path)
                .context("--churn-instances: the level instances no asset to spawn")?,
        )
    } else {
        None
    };
    let mut profile = Profile {
        scene: level.display().to_string(),
        width: options.width,
        height: options.height,
        render_size: Some(render_size(options)),
        threads,
        frames: Vec::with_capacity(options.frames as usize),
        accel_rounds: Vec::new(),
    };
    // The level's accel alone, timed on the same threads in a round after every window of
    // `ACCEL_ROUND_FRAMES` measured frames (the two never share the cores, and each window
    // is set beside a round taken under the same load).
    let accel_alone = super::raybench::AccelAlone::new(scene);
    let accel_round = |profile: &mut Profile| {
        profile.accel_rounds.push(AccelRound {
            after_frames: profile.frames.len(),
            rays: accel_alone.round(),
        });
    };
    let mut churn: Vec<(Churn, f64)> = Vec::with_capacity(options.frames as usize);
    let mut spawned: Vec<Entity> = Vec::new();
    let step = 1.0 / crate::game::SIMULATION_HZ;
    let bar = super::progress::bar(u64::from(options.warmup + options.frames), "frames");
    for frame in 0..options.warmup + options.frames {
        bar.inc(1);
        if let Some(recording) = recording {
            let Some(input) = recording.steps.get(frame as usize) else {
                break; // the play-through ends here
            };
            input.apply(&mut engine.world.resource_mut::<Input>());
        }
        if let Some((entity, start)) = view {
            let placed = camera_path(&start, frame as f64 * step);
            if let Some(mut transform) = engine.world.get_mut::<Transform>(entity) {
                *transform = placed;
            }
        }
        let edit_started = Instant::now();
        let kind = if options.churn_instances + options.churn_lights == 0 {
            Churn::Quiet
        } else if spawned.is_empty() {
            spawned = spawn_churn(&mut engine, churn_asset.as_deref(), options)?;
            Churn::Spawned
        } else {
            for entity in spawned.drain(..) {
                engine.world.despawn(entity);
            }
            Churn::Despawned
        };
        let edit_ms = edit_started.elapsed().as_secs_f64() * 1e3;
        let started = Instant::now();
        engine.advance(step);
        let frame_ms = started.elapsed().as_secs_f64() * 1e3;
        if let Some(hearing) = &mut engine.hearing {
            drop(hearing.take());
        }
        if frame >= options.warmup {
            let mut sample = engine.stage_times().sample(0.0, frame_ms);
            sample.tiles = engine.tile_spans().to_vec();
            profile.frames.push(sample);
            churn.push((kind, edit_ms));
            if profile.frames.len() % ACCEL_ROUND_FRAMES == 0 {
                engine.film.finish_learning();
                accel_round(&mut profile);
            }
        }
    }
    // The last window (a replay may end early, or the count not divide evenly).
    if profile
        .accel_rounds
        .last()
        .map_or(0, |round| round.after_frames)
        < profile.frames.len()
    {
        engine.film.finish_learning();
        accel_round(&mut profile);
    }
    bar.finish_and_clear();
    Ok((profile, churn))
}

/// `--churn-instances` copies of `asset` in a grid 0.6 m apart on the floor around the
/// origin, and `--churn-lights` dim point lights above them.
fn spawn_churn(
    engine: &mut Engine,
    asset: Option<&str>,
    options: &Options,
) -> anyhow::Result<Vec<Entity>> {
    let mut spawned = Vec::new();
    let side = (options.churn_instances as f32).sqrt().ceil().max(1.0) as u32;
    let at = |index: u32, height: f32| {
        let (x, z) = ((index % side) as f32, (index / side) as f32);
        let half = (side as f32 - 1.0) * 0.5;
        Vec3::new((x - half) * 0.6, height, (z - half) * 0.6)
    };
    for index in 0..options.churn_instances {
        let mut def = EntityDef::named(format!("churn instance {index:05}"));
        def.transform.translation = at(index, 0.0);
        def.instance = asset.map(|asset| InstanceDef {
            asset: asset.to_owned(),
            material_overrides: Default::default(),
        });
        spawned.push(spawn(&mut engine.world, &def)?);
    }
    for index in 0..options.churn_lights {
        let mut def = EntityDef::named(format!("churn light {index:05}"));
        def.transform.translation = at(index, 1.5);
        def.light = Some(LightDef::Point {
            color: Vec3::ONE,
            intensity: 1.0,
        });
        spawned.push(spawn(&mut engine.world, &def)?);
    }
    Ok(spawned)
}
