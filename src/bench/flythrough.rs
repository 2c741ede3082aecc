//! `gloam flythrough`: how close the real-time filters bring one sample per pixel to the
//! converged image, frame by frame, along a scripted flight through a level.
//!
//! Per frame: the view follows `bench`'s camera path, one warden patrols back and forth
//! across the view (the moving object), one 60 Hz step runs, and one frame is rendered at
//! 1 spp with its guides. That same frame goes through three film steps: raw, temporal
//! only, and temporal + spatial (each with its own history). Every `--every` frames after
//! the warm-up, a converged reference of the same instant (`--reference-spp`, another seed)
//! is rendered and each result's RMSE against it printed, on display values (tone mapped,
//! sRGB-encoded, in [0, 1]: the error a player sees; linear radiance would be dominated by
//! the lamps) and on linear radiance. Ghosting is the RMSE over the warden's trail: pixels
//! it covered in the previous 8 frames and does not cover now, where stale history shows.

use std::collections::VecDeque;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context as _;
use bevy_ecs::hierarchy::Children;
use bevy_ecs::prelude::Entity;
use glam::Affine3A;
use serde_json::json;

use super::frames::camera_path;
use crate::film::denoise::{FilterMode, FrameFilter};
use crate::frame::Engine;
use crate::game::{Patrol, Transform, ViewCamera};
use crate::render::film::display_value;
use crate::render::{Film, Guides, RenderSettings, render, render_guided};
use crate::scene::files::write_atomically;
use crate::scene::world::Scene;

#[derive(Debug, clap::Args)]
pub struct Options {
    /// The level to fly through; levels/first-light.ron when omitted.
    pub level: Option<PathBuf>,
    /// Frames rendered (one 60 Hz step each).
    #[arg(long, default_value_t = 64, value_parser = crate::cli::values::count())]
    pub frames: u32,
    /// Frames before the first comparison (the histories fill).
    #[arg(long, default_value_t = 16, value_parser = crate::cli::values::count_or_zero())]
    pub warmup: u32,
    /// Compare against a reference every this many frames.
    #[arg(long, default_value_t = 8, value_parser = crate::cli::values::count())]
    pub every: u32,
    #[arg(long, default_value_t = 320, value_parser = crate::cli::values::count())]
    pub width: u32,
    #[arg(long, default_value_t = 180, value_parser = crate::cli::values::count())]
    pub height: u32,
    /// Samples per pixel of each reference.
    #[arg(long, default_value_t = 256, value_parser = crate::cli::values::count())]
    pub reference_spp: u32,
    /// The level entity that patrols across the view (by name); "warden 1" when omitted.
    #[arg(long)]
    pub mover: Option<String>,
    /// Write every figure here as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Write the last compared frame as raw, temporal, full and reference PNGs here.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Tuning: a-trous passes (the game's default when omitted).
    #[arg(long, value_parser = clap::value_parser!(u32).range(0..=8))]
    pub iterations: Option<u32>,
    /// Tuning: the newest frame's least weight in the temporal average, in (0, 1].
    #[arg(long, value_parser = crate::cli::values::unit)]
    pub alpha_min: Option<f32>,
    /// Tuning: the a-trous luminance edge's width, in standard deviations.
    #[arg(long, value_parser = crate::cli::values::positive_f32)]
    pub sigma_luminance: Option<f32>,
}

/// Trail length for the ghosting measure, in frames.
const TRAIL_FRAMES: usize = 8;

/// The RMSE of one image against the reference, on display values and linear radiance,
/// over all pixels and over the mover's trail.
#[derive(Clone, Copy, Debug, Default)]
struct Errors {
    display: f64,
    linear: f64,
    trail: f64,
}

fn errors(image: &Film, reference: &Film, trail: &[bool]) -> Errors {
    let (mut display, mut linear, mut trail_sum, mut trail_count) = (0.0, 0.0, 0.0, 0usize);
    for ((a, b), in_trail) in image.pixels.iter().zip(&reference.pixels).zip(trail) {
        let d = (display_value(*a, 1.0) - display_value(*b, 1.0)).length_squared() as f64;
        display += d;
        linear += (*a - *b).length_squared() as f64;
        if *in_trail {
            trail_sum += d;
            trail_count += 1;
        }
    }
    let n = (3 * image.pixels.len().max(1)) as f64;
    Errors {
        display: (display / n).sqrt(),
        linear: (linear / n).sqrt(),
        trail: (trail_sum / (3 * trail_count.max(1)) as f64).sqrt(),
    }
}

pub fn run(options: &Options) -> anyhow::Result<()> {
    if options.width == 0 || options.height == 0 || options.frames == 0 {
        anyhow::bail!("--width, --height and --frames must be at least 1");
    }
    if let Some(alpha) = options.alpha_min {
        anyhow::ensure!(
            alpha > 0.0 && alpha <= 1.0,
            "--alpha-min {alpha}: must be in (0, 1]"
        );
    }
    if let Some(sigma) = options.sigma_luminance {
        anyhow::ensure!(
            sigma.is_finite() && sigma > 0.0,
            "--sigma-luminance {sigma}: must be positive"
        );
    }
    if options.every == 0 || options.reference_spp == 0 {
        anyhow::bail!("--every and --reference-spp must be at least 1");
    }
    if options.warmup >= options.frames {
        anyhow::bail!(
            "--warmup ({}) leaves no frame to compare out of --frames {}",
            options.warmup,
            options.frames
        );
    }
    let level = options
        .level
        .clone()
        .unwrap_or_else(crate::scene::files::default_level);
    let scene = Scene::load(&level)?;
    let (width, height) = (options.width, options.height);
    let mut engine = Engine::new(&scene, RenderSettings::real_time(width, height));

    // The view and the mover, by their level entities.
    let mut views = engine
        .world
        .query_filtered::<(Entity, &Transform), bevy_ecs::query::With<ViewCamera>>();
    let view = views
        .iter(&engine.world)
        .next()
        .map(|(e, t)| (e, *t))
        .context("the level has no view camera")?;
    let mover_name = options.mover.as_deref().unwrap_or("warden 1");
    let mut roots = engine
        .world
        .query::<(Entity, &bevy_ecs::prelude::Name, &Transform)>();
    let (mover, mover_start) = roots
        .iter(&engine.world)
        .find(|(_, name, _)| name.as_str() == mover_name)
        .map(|(e, _, t)| (e, *t))
        .with_context(|| format!("{}: no entity named {mover_name:?}", level.display()))?;
    // A 1.5 m beat either side of where it stands, a 4-second round trip.
    engine
        .world
        .entity_mut(mover)
        .insert(Patrol::new(mover_start, 1.5, 4.0));
    let mover_instances = instances_under(&mut engine, mover);
    if mover_instances.is_empty() {
        anyhow::bail!("{}: {mover_name:?} has no mesh to move", level.display());
    }

    let mut temporal = FrameFilter::new(FilterMode::Temporal);
    let mut full = FrameFilter::new(FilterMode::Full);
    for filter in [&mut temporal, &mut full] {
        if let Some(alpha) = options.alpha_min {
            filter.temporal.settings.alpha_min = alpha;
        }
        if let Some(iterations) = options.iterations {
            filter.atrous.iterations = iterations;
        }
        if let Some(sigma) = options.sigma_luminance {
            filter.atrous.sigma_luminance = sigma;
        }
    }
    let mut settings = RenderSettings::real_time(width, height);
    let mut trail_masks: VecDeque<Vec<bool>> = VecDeque::new();
    let mut rows = Vec::new();
    let (mut render_ms, mut temporal_ms, mut full_ms) = (Vec::new(), Vec::new(), Vec::new());
    let mut last_images = None;
    let step = 1.0 / crate::game::SIMULATION_HZ;
    println!(
        "{:>5}{:>10}{:>10}{:>10}{:>12}{:>12}{:>12}",
        "frame", "raw", "temporal", "full", "trail raw", "trail temp", "trail full"
    );
    let bar = super::progress::bar(u64::from(options.frames), "frames");
    for frame in 0..options.frames {
        bar.inc(1);
        let seconds = frame as f64 * step;
        if let Some(mut transform) = engine.world.get_mut::<Transform>(view.0) {
            *transform = camera_path(&view.1, seconds);
        }
        engine.simulate(step);
        let camera = engine.view_camera(width, height);
        settings.frame = frame;
        let started = Instant::now();
        let output = render_guided(engine.render_scene(), &camera, &settings);
        render_ms.push(started.elapsed().as_secs_f64() * 1e3);
        let guides = output.guides.as_ref().context("guides")?;
        let instances: Vec<Affine3A> = engine
            .render_scene()
            .accel
            .instances()
            .iter()
            .map(|i| i.world_from_object())
            .collect();
        let started = Instant::now();
        let temporal_image = temporal.apply(&output.film, guides, &camera, &instances);
        temporal_ms.push(started.elapsed().as_secs_f64() * 1e3);
        let started = Instant::now();
        let full_image = full.apply(&output.film, guides, &camera, &instances);
        full_ms.push(started.elapsed().as_secs_f64() * 1e3);

        let covered = mover_mask(guides, &mover_instances);
        let trail: Vec<bool> = (0..covered.len())
            .map(|i| !covered[i] && trail_masks.iter().any(|mask| mask[i]))
            .collect();
        trail_masks.push_back(covered);
        if trail_masks.len() > TRAIL_FRAMES {
            trail_masks.pop_front();
        }
        if frame < options.warmup || (frame - options.warmup) % options.every != 0 {
            continue;
        }
        let reference_settings = RenderSettings {
            spp: options.reference_spp,
            seed: 0x5eed,
            frame: 0,
            ..settings.clone()
        };
        let reference = render(engine.render_scene(), &camera, &reference_settings, &|_| {}).film;
        let raw = errors(&output.film, &reference, &trail);
        let temporal_errors = errors(&temporal_image, &reference, &trail);
        let full_errors = errors(&full_image, &reference, &trail);
        bar.suspend(|| {
            println!(
                "{frame:>5}{:>10.4}{:>10.4}{:>10.4}{:>12.4}{:>12.4}{:>12.4}",
                raw.display,
                temporal_errors.display,
                full_errors.display,
                raw.trail,
                temporal_errors.trail,
                full_errors.trail
            )
        });
        rows.push((frame, raw, temporal_errors, full_errors));
        last_images = Some((output.film, temporal_image, full_image, reference));
    }
    bar.finish_and_clear();

    let median = |values: Vec<f64>| {
        let mut sorted = values;
        sorted.sort_by(f64::total_cmp);
        sorted[sorted.len() / 2]
    };
    let column = |pick: &dyn Fn(&(u32, Errors, Errors, Errors)) -> f64| {
        median(rows.iter().map(pick).collect())
    };
    let raw = column(&|r| r.1.display);
    let temporal_rmse = column(&|r| r.2.display);
    let full_rmse = column(&|r| r.3.display);
    let render_median = median(render_ms.clone());
    let (temporal_median, full_median) = (median(temporal_ms.clone()), median(full_ms.clone()));
    println!(
        "median RMSE (display): raw {raw:.4}, temporal {temporal_rmse:.4} ({:.2}x raw), \
         temporal+spatial {full_rmse:.4} ({:.2}x raw)",
        temporal_rmse / raw,
        full_rmse / raw
    );
    println!(
        "median trail RMSE (ghosting): raw {:.4}, temporal {:.4}, temporal+spatial {:.4}",
        column(&|r| r.1.trail),
        column(&|r| r.2.trail),
        column(&|r| r.3.trail)
    );
    println!(
        "median ms per frame: render {render_median:.2}, temporal filter {temporal_median:.2}, \
         temporal+spatial filter {full_median:.2} ({:.1}% of render + filter)",
        100.0 * full_median / (render_median + full_median)
    );

    if let Some(path) = &options.json {
        let row_json =
            |e: &Errors| json!({"display": e.display, "linear": e.linear, "trail": e.trail});
        let report = json!({
            "level": level.display().to_string(),
            "width": width, "height": height, "frames": options.frames,
            "reference_spp": options.reference_spp,
            "median_rmse_display": {"raw": raw, "temporal": temporal_rmse, "full": full_rmse},
            "median_rmse_linear": {
                "raw": column(&|r| r.1.linear),
                "temporal": column(&|r| r.2.linear),
                "full": column(&|r| r.3.linear),
            },
            "median_trail_rmse": {
                "raw": column(&|r| r.1.trail),
                "temporal": column(&|r| r.2.trail),
                "full": column(&|r| r.3.trail),
            },
            "ratio_full_to_raw": full_rmse / raw,
            "ratio_temporal_to_raw": temporal_rmse / raw,
            "median_ms": {"render": render_median, "temporal": temporal_median, "full": full_median},
            "compared": rows.iter().map(|(frame, raw, temporal, full)| json!({
                "frame": frame, "raw": row_json(raw), "temporal": row_json(temporal),
                "full": row_json(full),
            })).collect::<Vec<_>>(),
        });
        write_atomically(path, serde_json::to_string_pretty(&report)?.as_bytes())
            .with_context(|| format!("writing {}", path.display()))?;
        println!("wrote {}", path.display());
    }
    if let (Some(dir), Some((raw, temporal, full, reference))) = (&options.out, last_images) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        for (name, image) in [
            ("raw", raw),
            ("temporal", temporal),
            ("full", full),
            ("reference", reference),
        ] {
            let path = dir.join(format!("{name}.png"));
            image.write(&path, 1.0)?;
        }
        println!(
            "wrote raw, temporal, full and reference PNGs to {}",
            dir.display()
        );
    }
    Ok(())
}

/// The accel instances of `root` and everything under it.
fn instances_under(engine: &mut Engine, root: Entity) -> Vec<u32> {
    let mut found = Vec::new();
    let mut stack = vec![root];
    while let Some(entity) = stack.pop() {
        if let Some(instance) = engine
            .world
            .resource::<crate::extract::RenderState>()
            .instance_of(entity)
        {
            found.push(instance);
        }
        if let Some(children) = engine.world.get::<Children>(entity) {
            stack.extend(children.iter());
        }
    }
    found
}

/// Pixels whose first hit is one of `instances`.
fn mover_mask(guides: &Guides, instances: &[u32]) -> Vec<bool> {
    guides
        .instances()
        .iter()
        .map(|instance| instances.contains(instance))
        .collect()
}
