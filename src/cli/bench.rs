//! `gloam bench`: a headless frame-time profile of a level along a fixed camera path.
//!
//! A measurement tool around the game's own frame loop. Loads the level into an `Engine`,
//! then for each frame: moves the view along a scripted path (a slow sway and dolly around
//! the level's camera), advances exactly one 60 Hz simulation step (so every run does the
//! same work: same poses, same rays), and records the stage times the schedules measured.
//! Warm-up frames are run first and dropped. The `profile` module prints the table and
//! writes the JSON, CSV, Chrome trace and PNG chart.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context as _;
use glam::{Quat, Vec3};

use crate::frame::Engine;
use crate::game::{Transform, ViewCamera};
use crate::profile::Profile;
use crate::render::RenderSettings;
use crate::scene::world::Scene;

#[derive(Debug, clap::Args)]
pub struct Options {
    /// The level (or glTF) to profile; levels/first-light.ron when omitted.
    pub level: Option<PathBuf>,
    /// Frames measured (after the warm-up).
    #[arg(long, default_value_t = 240)]
    pub frames: u32,
    /// Frames run first and not measured (caches, page faults, the first BLAS refits).
    #[arg(long, default_value_t = 30)]
    pub warmup: u32,
    #[arg(long, default_value_t = 480)]
    pub width: u32,
    #[arg(long, default_value_t = 270)]
    pub height: u32,
    /// Worker threads (default: all cores), for scaling studies.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Write DESIGN.md's JSON report here.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Write a row per frame, a column per stage.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Write a Chrome trace (open it in https://ui.perfetto.dev or chrome://tracing).
    #[arg(long)]
    pub trace: Option<PathBuf>,
    /// Write a PNG chart: stages stacked per frame, and a frame-time histogram.
    #[arg(long)]
    pub chart: Option<PathBuf>,
    /// The film's filters, as in `play` (their cost is the `film` stage).
    #[arg(long, value_enum, default_value_t = super::FilterArg::Full)]
    pub filter: super::FilterArg,
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

pub fn run(options: &Options) -> anyhow::Result<()> {
    if options.width == 0 || options.height == 0 || options.frames == 0 {
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
    let level = options.level.clone().unwrap_or_else(super::default_level);
    let scene = Scene::load(&level)?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .context("starting the worker threads")?;
    let profile = pool.install(|| measure(&scene, &level, threads, options));
    print!("{}", profile.table());
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

/// Runs the warm-up and the measured frames; returns the profile of the measured ones.
pub fn measure(
    scene: &Scene,
    level: &std::path::Path,
    threads: usize,
    options: &Options,
) -> Profile {
    let mut engine = Engine::new(
        scene,
        RenderSettings::real_time(options.width, options.height),
    );
    engine.film.filter.mode = options.filter.mode();
    let mut views = engine
        .world
        .query_filtered::<(bevy_ecs::entity::Entity, &Transform), bevy_ecs::query::With<ViewCamera>>();
    let view = views.iter(&engine.world).next().map(|(e, t)| (e, *t));
    let mut profile = Profile {
        scene: level.display().to_string(),
        width: options.width,
        height: options.height,
        threads,
        frames: Vec::with_capacity(options.frames as usize),
    };
    let step = 1.0 / crate::game::SIMULATION_HZ;
    for frame in 0..options.warmup + options.frames {
        if let Some((entity, start)) = view {
            let placed = camera_path(&start, frame as f64 * step);
            if let Some(mut transform) = engine.world.get_mut::<Transform>(entity) {
                *transform = placed;
            }
        }
        let started = Instant::now();
        engine.advance(step);
        let frame_ms = started.elapsed().as_secs_f64() * 1e3;
        if frame >= options.warmup {
            let times = engine.stage_times();
            profile.frames.push(times.sample(0.0, frame_ms));
        }
    }
    profile
}
