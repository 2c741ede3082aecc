//! `gloam bench`: a headless frame-time profile of a level, seen as it is played.
//!
//! A measurement tool around the game's own frame loop. Loads the level into an `Engine`
//! and chooses whose eyes the frames are seen through (`View`): a level with a player start
//! is played through (`--replay FILE`, else the level's won recording in
//! `tests/recordings/`, else the bot's run: `PlayThrough`); a glTF, a level without one, or
//! `--view camera` has its camera moved along a scripted path instead. Per frame:
//! 1. the fixed steps the last frame's time owes run, as in play (a play-through feeds each
//!    its recorded input; the camera path runs exactly one 60 Hz step a frame, so every run
//!    does the same work);
//! 2. extract, accel, render and film (`Engine::advance`);
//! 3. present: the shell's own (`Present`), timed as `Stage::Present`.
//!
//! Warm-up frames are run first and dropped. After every `ACCEL_ROUND_FRAMES` measured
//! frames the level's accel alone traces a round of `raybench`'s rays on the same threads,
//! set beside the renderer's rays per second over those frames. The `profile` module
//! prints the table and writes the JSON, CSV, Chrome trace and PNG chart. With
//! `--churn-instances` and `--churn-lights`, every other frame spawns things into the world
//! and the next despawns them, and extract + accel is reported per kind of frame.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context as _;
use bevy_ecs::prelude::{Entity, With};
use glam::{Quat, Vec3};

use crate::frame::Engine;
use crate::game::replay::{Recording, StepInput};
use crate::game::{AssetInstance, LevelEntity, Transform, ViewCamera, spawn, spawn_player};
use crate::profile::{AccelRound, Profile, Stage};
use crate::render::RenderSettings;
use crate::scene::level::{EntityDef, InstanceDef, LightDef};
use crate::scene::world::Scene;

#[derive(Debug, clap::Args)]
pub struct Options {
    /// The level (or glTF) to profile; levels/first-light.ron when omitted.
    #[arg(value_name = "SCENE")]
    pub level: Option<PathBuf>,
    /// Frames measured (after the warm-up): a play-through's run to the end of its inputs,
    /// the camera path's 240.
    #[arg(long, value_parser = crate::headless::values::count())]
    pub frames: Option<u32>,
    /// Frames run first and not measured (caches, page faults, the first BLAS refits).
    #[arg(long, default_value_t = 30, value_parser = crate::headless::values::count_or_zero())]
    pub warmup: u32,
    /// The width shown, in pixels.
    #[arg(long, default_value_t = 480, value_parser = crate::headless::values::count())]
    pub width: u32,
    /// The height shown, in pixels.
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
    /// lowers the render's; 1 renders at --width x --height. Default: the game's own rule
    /// for the size shown (`film::render_scale_for`: native up to 640 x 360's pixels).
    #[arg(long, value_parser = crate::headless::values::share)]
    pub render_scale: Option<f32>,
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
    /// Whose eyes the frames are seen through: the player's, in a play-through of the
    /// level; or the level's camera, moved along a scripted path. Default: the player
    /// when the level has a player start.
    #[arg(long, value_enum)]
    pub view: Option<View>,
    /// The play-through to profile: this recording's inputs, step by step, rather than the
    /// level's won recording (`tests/recordings/<level>-won.json`) or the bot's run. The
    /// recording names its level; LEVEL, if given, must be it.
    #[arg(long, value_name = "FILE", conflicts_with = "view")]
    pub replay: Option<PathBuf>,
}

/// Whose eyes `gloam bench` sees through (`--view`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum View {
    /// The player's, playing the level through.
    Player,
    /// The level's camera, along the scripted path (`camera_path`).
    Camera,
}

impl View {
    pub fn name(self) -> &'static str {
        match self {
            View::Player => "player",
            View::Camera => "camera",
        }
    }
}

/// The inputs of a play-through, step by step, and where they came from (the report's
/// `replay`: the recording's path, or `autoplay`).
pub(super) struct PlayThrough {
    pub(super) steps: Vec<StepInput>,
    pub(super) source: String,
}

/// Seconds of play the bot is given when a level has no won recording.
const BOT_SECONDS: f64 = 300.0;

/// A play-through of `level`: `--replay`'s recording, else the won recording shipped
/// beside the levels (`<levels>/../tests/recordings/<level>-won.json`), else the bot's run.
pub(super) fn play_through(
    level: &Path,
    scene: &Scene,
    replay: Option<(Recording, &Path)>,
) -> anyhow::Result<PlayThrough> {
    if let Some((recording, path)) = replay {
        return Ok(PlayThrough {
            steps: recording.steps,
            source: path.display().to_string(),
        });
    }
    match won_recording(level).map(|path| (crate::headless::replay::read_recording(&path), path)) {
        Some((Ok((recording, recorded_on)), path)) => {
            ensure_recorded_on(&path, &recorded_on, level)?;
            return Ok(PlayThrough {
                steps: recording.steps,
                source: path.display().to_string(),
            });
        }
        // A level edited since its recording was made: the bot plays it as it is now.
        Some((Err(error), _)) => println!("{error:#}; the bot plays the level first"),
        None => println!(
            "{}: no won recording beside it; the bot plays it first",
            level.display()
        ),
    }
    let run = crate::headless::autoplay::autoplay(scene, BOT_SECONDS)
        .with_context(|| format!("{}: the bot's run", level.display()))?;
    println!(
        "the bot's run: {} after {:.1} s",
        run.outcome.name(),
        run.seconds
    );
    Ok(PlayThrough {
        steps: run.recorded.steps,
        source: "autoplay".to_owned(),
    })
}

/// An error unless the recording at `path`, made on `recorded_on`, was made on `level`.
fn ensure_recorded_on(path: &Path, recorded_on: &Path, level: &Path) -> anyhow::Result<()> {
    let same = std::fs::canonicalize(recorded_on).ok() == std::fs::canonicalize(level).ok();
    anyhow::ensure!(
        same,
        "{} was recorded on '{}', not '{}'",
        path.display(),
        recorded_on.display(),
        level.display()
    );
    Ok(())
}

/// The won recording shipped for `level`, if there is one: in the repository's
/// `tests/recordings/`, beside the levels' folder (named relative to the working folder
/// when it is under it).
fn won_recording(level: &Path) -> Option<PathBuf> {
    let stem = level.file_stem()?.to_str()?;
    let root = crate::scene::files::absolute(level)
        .parent()?
        .parent()?
        .to_path_buf();
    let path = root
        .join("tests")
        .join("recordings")
        .join(format!("{stem}-won.json"));
    let here = std::env::current_dir()
        .ok()
        .map(|dir| crate::scene::files::absolute(&dir));
    let shown = here
        .and_then(|here| path.strip_prefix(here).ok().map(Path::to_path_buf))
        .unwrap_or_else(|| path.clone());
    path.is_file().then_some(shown)
}

/// What the shell shows after the film each frame, timed as `Stage::Present`: the game
/// window's present without a window (the bench cannot see the window's shell, so the
/// command line hands it one).
pub trait Present {
    /// Shows `engine`'s developed frame at the size shown, `width` x `height`.
    fn present(&mut self, engine: &mut Engine, width: u32, height: u32);
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

/// The render's resolution: --width x --height at --render-scale (or the game's rule).
fn render_size(options: &Options) -> (u32, u32) {
    let scale = options
        .render_scale
        .unwrap_or_else(|| crate::film::render_scale_for(options.width, options.height));
    crate::film::scaled_size(options.width, options.height, scale)
}

/// Frames measured along the camera path when `--frames` is not given.
const CAMERA_PATH_FRAMES: u32 = 240;

pub fn run(options: &Options, present: &mut (dyn Present + Send)) -> anyhow::Result<()> {
    if options.width == 0 || options.height == 0 || options.frames == Some(0) {
        anyhow::bail!("--width, --height and --frames must be at least 1");
    }
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
    let (replay, level) = match &options.replay {
        Some(path) => {
            let (recording, level) = crate::headless::replay::read_recording(path)?;
            if let Some(named) = &options.level {
                ensure_recorded_on(path, &level, named)?;
            }
            (Some((recording, path.as_path())), level)
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
    let has_player = scene.player_spawn().is_some();
    let view = match options.view {
        Some(View::Player) if !has_player => {
            anyhow::bail!("--view player: {} has no player start", level.display())
        }
        Some(view) => view,
        None if has_player => View::Player,
        None => View::Camera,
    };
    let play = match view {
        View::Player => Some(play_through(&level, &scene, replay)?),
        View::Camera => None,
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .context("starting the worker threads")?;
    let (mut profile, churn) = pool.install(|| {
        measure(
            &scene,
            &level,
            play.as_ref().map(|play| play.steps.as_slice()),
            threads,
            options,
            present,
        )
    })?;
    profile.view = Some(view.name().to_owned());
    profile.replay = play.map(|play| play.source);
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

/// Runs the warm-up and the measured frames (a play-through's `steps`, or the camera
/// path); returns the profile of the measured ones and what each did to the world, with
/// the milliseconds the spawn or despawn calls took.
fn measure(
    scene: &Scene,
    level: &Path,
    steps: Option<&[StepInput]>,
    threads: usize,
    options: &Options,
    present: &mut (dyn Present + Send),
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
    // A play-through is seen through the player's eyes, each fixed step fed its recorded
    // input; otherwise the view takes its path.
    let camera = match steps {
        Some(steps) => {
            spawn_player(&mut engine.world)
                .with_context(|| format!("{}: the level has no player start", level.display()))?;
            engine.playback = Some(steps.iter().copied().collect());
            None
        }
        None => {
            let mut views = engine
                .world
                .query_filtered::<(Entity, &Transform), With<ViewCamera>>();
            views.iter(&engine.world).next().map(|(e, t)| (e, *t))
        }
    };
    let frames = match (options.frames, steps) {
        (Some(frames), _) => frames,
        // To the end of the inputs: never more frames than steps.
        (None, Some(steps)) => u32::try_from(steps.len()).unwrap_or(u32::MAX),
        (None, None) => CAMERA_PATH_FRAMES,
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
        frames: Vec::with_capacity(frames as usize),
        ..Profile::default()
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
    let mut churn: Vec<(Churn, f64)> = Vec::with_capacity(frames as usize);
    let mut spawned: Vec<Entity> = Vec::new();
    let step = 1.0 / crate::game::SIMULATION_HZ;
    // The real time the next frame simulates: as in play, the last frame's whole time (a
    // play-through), and at least one step's, as the game's default vsync holds frames to
    // a 60 Hz display's; one step a frame on the camera path, so every run does the same
    // work.
    let mut owed_seconds = step;
    let bar = super::progress::bar(u64::from(options.warmup + frames), "frames");
    for frame in 0..options.warmup + frames {
        if let Some(playback) = &engine.playback
            && playback.is_empty()
        {
            break; // the play-through ends here
        }
        bar.inc(1);
        if let Some((entity, start)) = camera {
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
        // Never past the end of the inputs (the engine's own remainder is under a step).
        if let Some(playback) = &engine.playback {
            owed_seconds = owed_seconds.min(playback.len() as f64 * step);
        }
        let started = Instant::now();
        engine.advance(owed_seconds);
        let presented = Instant::now();
        present.present(&mut engine, options.width, options.height);
        let present_ms = presented.elapsed().as_secs_f64() * 1e3;
        let frame_seconds = started.elapsed().as_secs_f64();
        if steps.is_some() {
            owed_seconds = frame_seconds.max(step);
        }
        if let Some(hearing) = &mut engine.hearing {
            drop(hearing.take());
        }
        if frame >= options.warmup {
            let mut sample = engine.stage_times().sample(present_ms, frame_seconds * 1e3);
            sample.tiles = engine.tile_spans().to_vec();
            profile.frames.push(sample);
            churn.push((kind, edit_ms));
            if profile.frames.len() % ACCEL_ROUND_FRAMES == 0 {
                engine.film.finish_learning();
                accel_round(&mut profile);
            }
        }
    }
    // The last window (a play-through may end early, or the count not divide evenly).
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
    anyhow::ensure!(
        !profile.frames.is_empty(),
        "{}: the play-through ended within the {} warm-up frames",
        level.display(),
        options.warmup
    );
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
