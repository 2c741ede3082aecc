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
//! The moving lamp's pool is what survives of the light the mover's own lamp casts: a
//! second reference of the same instant with that lamp dark tells which pixels it lights
//! (more than half their luminance), and over those pixels each result's mean luminance is
//! set against the reference's (1 is the whole pool, lower is a pool gone dim) with its
//! RMSE there.

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
use crate::render::light::{Light, luminance};
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

/// A pixel is in the moving lamp's pool when that lamp gives more than this share of its
/// luminance in the reference.
const POOL_SHARE: f32 = 0.5;

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

/// What an image keeps of the moving lamp's pool of light.
#[derive(Clone, Copy, Debug, Default)]
struct Pool {
    /// Mean luminance over the pool's pixels against the reference's.
    kept: f64,
    /// RMSE over the pool's pixels, on display values.
    display: f64,
}

/// The pixels the moving lamp lights: in `reference`, more than `POOL_SHARE` of their
/// luminance is missing from `unlit` (the same instant and seed with that lamp dark).
fn pool_mask(reference: &Film, unlit: &Film) -> Vec<bool> {
    reference
        .pixels
        .iter()
        .zip(&unlit.pixels)
        .map(|(lit, dark)| {
            let (lit, dark) = (luminance(*lit), luminance(*dark));
            lit > 0.0 && lit - dark > POOL_SHARE * lit
        })
        .collect()
}

fn pool(image: &Film, reference: &Film, in_pool: &[bool]) -> Pool {
    let (mut image_sum, mut reference_sum, mut display, mut count) = (0.0, 0.0, 0.0, 0usize);
    for ((a, b), _) in image
        .pixels
        .iter()
        .zip(&reference.pixels)
        .zip(in_pool)
        .filter(|(_, inside)| **inside)
    {
        image_sum += f64::from(luminance(*a));
        reference_sum += f64::from(luminance(*b));
        display += (display_value(*a, 1.0) - display_value(*b, 1.0)).length_squared() as f64;
        count += 1;
    }
    Pool {
        kept: image_sum / reference_sum.max(f64::MIN_POSITIVE),
        display: (display / (3 * count.max(1)) as f64).sqrt(),
    }
}

/// Renders `settings` with punctual light `lamp` dark (its intensity zero for the one
/// render; the light set's picking is left as it is, so the estimate stays unbiased).
fn render_without(
    engine: &mut Engine,
    lamp: u32,
    camera: &crate::render::Camera,
    settings: &RenderSettings,
) -> anyhow::Result<Film> {
    let lit = {
        let mut state = engine.render_state_mut();
        let light = state
            .scene
            .lights
            .lights
            .get_mut(lamp as usize)
            .context("the lamp's light is gone")?;
        let lit = light.clone();
        match light {
            Light::Point { intensity, .. } | Light::Spot { intensity, .. } => {
                *intensity = glam::Vec3::ZERO;
            }
            Light::Directional { irradiance, .. } => *irradiance = glam::Vec3::ZERO,
            Light::Triangle { .. } => anyhow::bail!("the mover's lamp is not a punctual light"),
        }
        lit
    };
    let film = render(engine.render_scene(), camera, settings, &|_| {}).film;
    engine.render_state_mut().scene.lights.lights[lamp as usize] = lit;
    Ok(film)
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
    let mover_instances = instances_under(&engine, mover);
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
    // Per compared frame: the pool's size, and what raw, temporal and full keep of it.
    let (mut pool_pixels, mut pool_rows): (Vec<f64>, Vec<[Pool; 3]>) = (Vec::new(), Vec::new());
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
        // The mover's own lamp (a warden carries one): the first lit punctual light under
        // it, looked up each time as the light set may have been renumbered.
        let pools = match lamps_under(&engine, mover).first().copied() {
            Some(lamp) => {
                let unlit = render_without(&mut engine, lamp, &camera, &reference_settings)?;
                let in_pool = pool_mask(&reference, &unlit);
                pool_pixels.push(in_pool.iter().filter(|inside| **inside).count() as f64);
                Some([
                    pool(&output.film, &reference, &in_pool),
                    pool(&temporal_image, &reference, &in_pool),
                    pool(&full_image, &reference, &in_pool),
                ])
            }
            None => None,
        };
        pool_rows.extend(pools);
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

    let pool_summary = (!pool_rows.is_empty()).then(|| {
        let of = |index: usize, pick: fn(&Pool) -> f64| {
            median(pool_rows.iter().map(|row| pick(&row[index])).collect())
        };
        let kept = [0, 1, 2].map(|index| of(index, |p| p.kept));
        let display = [0, 1, 2].map(|index| of(index, |p| p.display));
        (median(pool_pixels.clone()), kept, display)
    });
    match &pool_summary {
        Some((pixels, kept, display)) => println!(
            "moving lamp's pool ({pixels:.0} pixels, median): luminance kept raw {:.2}, \
             temporal {:.2}, temporal+spatial {:.2}; RMSE (display) there raw {:.4}, \
             temporal {:.4}, temporal+spatial {:.4}",
            kept[0], kept[1], kept[2], display[0], display[1], display[2]
        ),
        None => println!("moving lamp's pool: {mover_name:?} carries no lamp"),
    }

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
            "moving_lamp_pool": pool_summary.map(|(pixels, kept, display)| json!({
                "pixels": pixels,
                "luminance_kept": {"raw": kept[0], "temporal": kept[1], "full": kept[2]},
                "rmse_display": {"raw": display[0], "temporal": display[1], "full": display[2]},
            })),
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

/// `root` and every entity under it.
fn family(engine: &Engine, root: Entity) -> Vec<Entity> {
    let mut found = Vec::new();
    let mut stack = vec![root];
    while let Some(entity) = stack.pop() {
        found.push(entity);
        if let Some(children) = engine.world.get::<Children>(entity) {
            stack.extend(children.iter());
        }
    }
    found
}

/// The accel instances of `root` and everything under it.
fn instances_under(engine: &Engine, root: Entity) -> Vec<u32> {
    let state = engine.world.resource::<crate::extract::RenderState>();
    family(engine, root)
        .into_iter()
        .filter_map(|entity| state.instance_of(entity))
        .collect()
}

/// The light-set indices of the lit punctual lights at `root` and under it.
fn lamps_under(engine: &Engine, root: Entity) -> Vec<u32> {
    let state = engine.world.resource::<crate::extract::RenderState>();
    family(engine, root)
        .into_iter()
        .filter_map(|entity| state.light_of(entity))
        .collect()
}

/// Pixels whose first hit is one of `instances`.
fn mover_mask(guides: &Guides, instances: &[u32]) -> Vec<bool> {
    guides
        .instances()
        .iter()
        .map(|instance| instances.contains(instance))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn film(pixels: &[f32]) -> Film {
        Film {
            width: pixels.len() as u32,
            height: 1,
            pixels: pixels.iter().map(|&v| Vec3::splat(v)).collect(),
        }
    }

    #[test]
    fn the_pool_is_where_the_lamp_gives_most_of_the_light_and_its_share_is_measured() {
        // Pixel 0: all from the lamp; 1: the lamp gives 0.6 of it; 2: only 0.4; 3: dark.
        let reference = film(&[2.0, 1.0, 1.0, 0.0]);
        let unlit = film(&[0.0, 0.4, 0.6, 0.0]);
        let mask = pool_mask(&reference, &unlit);
        assert_eq!(mask, [true, true, false, false]);

        let same = pool(&reference, &reference, &mask);
        assert!((same.kept - 1.0).abs() < 1e-9 && same.display == 0.0);
        // Half the pool's light gone, whatever happens outside it.
        let dim = pool(&film(&[1.0, 0.5, 9.0, 9.0]), &reference, &mask);
        assert!((dim.kept - 0.5).abs() < 1e-6, "{dim:?}");
        assert!(dim.display > 0.0);
    }
}
