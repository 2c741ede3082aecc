//! `gloam flythrough`: how close the real-time filters bring one sample per pixel to the
//! converged image, frame by frame, along a scripted flight through a level or through the
//! player's eyes as the level is played.
//!
//! Per frame, along the camera path (`--view camera`, the default): the view follows
//! `bench`'s camera path, one warden patrols back and forth across the view (the moving
//! object), one 60 Hz step runs, and one frame is rendered at 1 spp with its guides. Through
//! the player's eyes (`--view player`): the level's won recording plays (or the bot's run,
//! as `bench` finds it), from `--from` seconds in, `PLAYER_FRAME_STEPS` steps a frame as at
//! the game's 30 fps target; the wardens keep their own beats, so no mover is added and the
//! trail and pool figures are left out (NaN, null in the JSON).
//!
//! That same frame goes through three film steps: raw, temporal only, and temporal +
//! spatial (each with its own history). Beside them, what the player sees: a second frame
//! rendered at `--render-scale` of the resolution, filtered (temporal + spatial) and
//! upscaled to it (`film::upscale`), as the game shows it. Every `--every` frames after the
//! warm-up, a converged reference of the same instant (`--reference-spp`, another seed)
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

use super::frames::{View, camera_path, play_through};
use crate::film::denoise::{FilterMode, FrameFilter};
use crate::film::upscale::{UpscaleSettings, Upscaler, render_scale_for, scaled_size};
use crate::frame::Engine;
use crate::game::{Patrol, Transform, ViewCamera, spawn_player};
use crate::render::hdr::display_value;
use crate::render::light::{Light, luminance};
use crate::render::{Guides, HdrImage, RadianceCache, RenderSettings, render, render_guided};
use crate::scene::files::write_atomically;
use crate::scene::world::Scene;

#[derive(Debug, clap::Args)]
pub struct Options {
    /// The level to fly through; levels/first-light.ron when omitted.
    pub level: Option<PathBuf>,
    /// Frames rendered (one 60 Hz step each).
    #[arg(long, default_value_t = 64, value_parser = crate::headless::values::count())]
    pub frames: u32,
    /// Frames before the first comparison (the histories fill).
    #[arg(long, default_value_t = 16, value_parser = crate::headless::values::count_or_zero())]
    pub warmup: u32,
    /// Compare against a reference every this many frames.
    #[arg(long, default_value_t = 8, value_parser = crate::headless::values::count())]
    pub every: u32,
    /// The render width, in pixels.
    #[arg(long, default_value_t = 320, value_parser = crate::headless::values::count())]
    pub width: u32,
    /// The render height, in pixels.
    #[arg(long, default_value_t = 180, value_parser = crate::headless::values::count())]
    pub height: u32,
    /// Samples per pixel of each reference.
    #[arg(long, default_value_t = 256, value_parser = crate::headless::values::count())]
    pub reference_spp: u32,
    /// The level entity that patrols across the camera path's view (by name); "warden 1"
    /// when omitted.
    #[arg(long)]
    pub mover: Option<String>,
    /// Whose eyes the frames are seen through: the level's camera along a scripted path
    /// (the default: a warden patrols across it for the ghosting figures), or the player's,
    /// playing the level's won recording (or the bot's run) as `bench` does.
    #[arg(long, value_enum, default_value_t = View::Camera)]
    pub view: View,
    /// With `--view player`: seconds of the play-through run before the first frame.
    #[arg(long, default_value_t = 0.0, value_parser = crate::headless::values::non_negative)]
    pub from: f64,
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
    #[arg(long, value_parser = crate::headless::values::share)]
    pub alpha_min: Option<f32>,
    /// The player's view renders at this scale of --width x --height per axis and is
    /// upscaled. Default: the game's rule for the size shown (`film::render_scale_for`:
    /// native up to 640 x 360's pixels).
    #[arg(long, value_parser = crate::headless::values::share)]
    pub render_scale: Option<f32>,
    /// Tuning: the upscaler's history cap, in samples.
    #[arg(long, value_parser = crate::headless::values::positive_f32)]
    pub max_history: Option<f32>,
    /// Tuning: the a-trous luminance edge's width, in standard deviations.
    #[arg(long, value_parser = crate::headless::values::positive_f32)]
    pub sigma_luminance: Option<f32>,
}

/// A pixel is in the moving lamp's pool when that lamp gives more than this share of its
/// luminance in the reference.
const POOL_SHARE: f32 = 0.5;

/// The images compared, in the order every figure lists them: the native frame raw,
/// temporal only, temporal + spatial; the frame rendered at the render scale, filtered
/// and resized bilinearly (as the game showed a lowered resolution before `upscale`);
/// and the player's view, that frame filtered and upscaled.
const IMAGES: [&str; 5] = ["raw", "temporal", "full", "resized", "player"];

/// Trail length for the ghosting measure, in frames.
const TRAIL_FRAMES: usize = 8;

/// Fixed steps a frame through the player's eyes: two 60 Hz steps, the game's 30 fps
/// frame-time target (the camera path runs one).
const PLAYER_FRAME_STEPS: u32 = 2;

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
fn pool_mask(reference: &HdrImage, unlit: &HdrImage) -> Vec<bool> {
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

fn pool(image: &HdrImage, reference: &HdrImage, in_pool: &[bool]) -> Pool {
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
) -> anyhow::Result<HdrImage> {
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
    let film = render(engine.render_scene(), camera, settings, &|_| {}).image;
    engine.render_state_mut().scene.lights.lights[lamp as usize] = lit;
    Ok(film)
}

fn errors(image: &HdrImage, reference: &HdrImage, trail: &[bool]) -> Errors {
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
        // No trail (nothing moved out of view): no figure.
        trail: if trail_count == 0 {
            f64::NAN
        } else {
            (trail_sum / (3 * trail_count) as f64).sqrt()
        },
    }
}

pub fn run(options: &Options) -> anyhow::Result<()> {
    if options.width == 0 || options.height == 0 || options.frames == 0 {
        anyhow::bail!("--width, --height and --frames must be at least 1");
    }
    if let Some(sigma) = options.sigma_luminance {
        anyhow::ensure!(
            sigma.is_finite() && sigma > 0.0,
            "--sigma-luminance {sigma}: must be positive"
        );
    }
    let render_scale = options
        .render_scale
        .unwrap_or_else(|| render_scale_for(options.width, options.height));
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

    // Camera path: the view and the mover, by their level entities. Player: the player,
    // fed the play-through's inputs step by step.
    let mover_name = options.mover.as_deref().unwrap_or("warden 1");
    let (flight, mover) = match options.view {
        View::Camera => {
            anyhow::ensure!(
                options.from == 0.0,
                "--from {}: only the player's view (--view player) plays through a level",
                options.from
            );
            let mut views = engine
                .world
                .query_filtered::<(Entity, &Transform), bevy_ecs::query::With<ViewCamera>>();
            let view = views
                .iter(&engine.world)
                .next()
                .map(|(e, t)| (e, *t))
                .context("the level has no view camera")?;
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
            (Some(view), Some((mover, mover_instances)))
        }
        View::Player => {
            anyhow::ensure!(
                options.mover.is_none(),
                "--mover: the player's view has the wardens' own beats, no mover"
            );
            let play = play_through(&level, &scene, None)?;
            spawn_player(&mut engine.world)
                .with_context(|| format!("{}: the level has no player start", level.display()))?;
            let steps = play.steps.len() as f64 / crate::game::SIMULATION_HZ;
            anyhow::ensure!(
                options.from < steps,
                "--from {}: the play-through ({}) lasts {steps:.1} s",
                options.from,
                play.source
            );
            engine.playback = Some(play.steps.iter().copied().collect());
            println!(
                "the player's view: {}, from {:.1} s",
                play.source, options.from
            );
            engine.prepare(options.from);
            (None, None)
        }
    };

    let mut temporal = FrameFilter::new(FilterMode::Temporal);
    let mut full = FrameFilter::new(FilterMode::Full);
    let mut player_filter = FrameFilter::new(FilterMode::Full);
    let mut resized_filter = FrameFilter::new(FilterMode::Full);
    let mut upscaler = Upscaler::new(UpscaleSettings::default());
    if let Some(max_history) = options.max_history {
        upscaler.settings.max_history = max_history;
    }
    let render_size = scaled_size(width, height, render_scale);
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
    // The player's filter is the game's, with its defaults (the tuning flags are for the
    // native filters).
    player_filter.render_scale = render_scale;
    let mut settings = RenderSettings::real_time(width, height);
    let mut player_settings = RenderSettings::real_time(render_size.0, render_size.1);
    let (mut player_render, mut player_image) = (HdrImage::new(0, 0), HdrImage::new(0, 0));
    // Each view's radiance cache, as the game keeps one for its view.
    let (mut cache, mut player_cache) = (RadianceCache::new(), RadianceCache::new());
    let mut resized_render = HdrImage::new(0, 0);
    let mut trail_masks: VecDeque<Vec<bool>> = VecDeque::new();
    let mut rows = Vec::new();
    let (mut render_ms, mut temporal_ms, mut full_ms) = (Vec::new(), Vec::new(), Vec::new());
    let (mut player_render_ms, mut player_film_ms, mut upscale_ms) =
        (Vec::new(), Vec::new(), Vec::new());
    let mut last_images = None;
    // Per compared frame: the pool's size, and what each image (`IMAGES`) keeps of it.
    let (mut pool_pixels, mut pool_rows): (Vec<f64>, Vec<[Pool; IMAGES.len()]>) =
        (Vec::new(), Vec::new());
    let step = 1.0 / crate::game::SIMULATION_HZ;
    let frame_seconds = match options.view {
        View::Camera => step,
        View::Player => f64::from(PLAYER_FRAME_STEPS) * step,
    };
    println!(
        "player's view: {}x{} rendered, upscaled to {width}x{height}",
        render_size.0, render_size.1
    );
    println!(
        "{:>5}{}{}",
        "frame",
        IMAGES.map(|name| format!("{name:>10}")).concat(),
        IMAGES
            .map(|name| format!(" {:>13}", format!("trail {name}")))
            .concat()
    );
    let bar = super::progress::bar(u64::from(options.frames), "frames");
    for frame in 0..options.frames {
        bar.inc(1);
        if let Some((view, start)) = &flight
            && let Some(mut transform) = engine.world.get_mut::<Transform>(*view)
        {
            *transform = camera_path(start, frame as f64 * step);
        }
        engine.prepare(frame_seconds);
        let camera = engine.view_camera(width, height);
        settings.frame = frame;
        let started = Instant::now();
        let output = render_guided(engine.render_scene(), &camera, &settings, Some(&cache));
        render_ms.push(started.elapsed().as_secs_f64() * 1e3);
        cache.learn(&output.cache_samples);
        let guides = output.guides.as_ref().context("guides")?;
        let instances: Vec<Affine3A> = engine
            .render_scene()
            .accel
            .instances()
            .iter()
            .map(|i| i.world_from_object())
            .collect();
        let started = Instant::now();
        let temporal_image = temporal.apply(&output.image, guides, &camera, &instances);
        temporal_ms.push(started.elapsed().as_secs_f64() * 1e3);
        let started = Instant::now();
        let full_image = full.apply(&output.image, guides, &camera, &instances);
        full_ms.push(started.elapsed().as_secs_f64() * 1e3);

        // The player's view: rendered smaller, filtered, upscaled.
        let player_camera = engine.view_camera(render_size.0, render_size.1);
        player_settings.frame = frame;
        let started = Instant::now();
        let player_output = render_guided(
            engine.render_scene(),
            &player_camera,
            &player_settings,
            Some(&player_cache),
        );
        player_render_ms.push(started.elapsed().as_secs_f64() * 1e3);
        player_cache.learn(&player_output.cache_samples);
        let player_guides = player_output.guides.as_ref().context("guides")?;
        let started = Instant::now();
        player_filter.apply_into(
            &player_output.image,
            player_guides,
            &player_camera,
            &instances,
            &mut player_render,
        );
        let filtered_at = Instant::now();
        upscaler.apply_into(
            &player_render,
            player_guides,
            &player_camera,
            &instances,
            (width, height),
            &mut player_image,
        );
        player_film_ms.push(started.elapsed().as_secs_f64() * 1e3);
        upscale_ms.push(filtered_at.elapsed().as_secs_f64() * 1e3);
        // The same small frame as the game showed it before it had the upscaler: filtered
        // as at full resolution, then resized bilinearly.
        resized_filter.apply_into(
            &player_output.image,
            player_guides,
            &player_camera,
            &instances,
            &mut resized_render,
        );
        let resized_image = resized_render.resized(width, height);

        let covered = mover_mask(guides, mover.as_ref().map_or(&[], |(_, m)| m.as_slice()));
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
        let reference = render(engine.render_scene(), &camera, &reference_settings, &|_| {}).image;
        let images = [
            &output.image,
            &temporal_image,
            &full_image,
            &resized_image,
            &player_image,
        ];
        let compared = images.map(|image| errors(image, &reference, &trail));
        // The mover's own lamp (a warden carries one): the first lit punctual light under
        // it, looked up each time as the light set may have been renumbered.
        let lamp =
            (mover.as_ref()).and_then(|(mover, _)| lamps_under(&engine, *mover).first().copied());
        let pools = match lamp {
            Some(lamp) => {
                let unlit = render_without(&mut engine, lamp, &camera, &reference_settings)?;
                let in_pool = pool_mask(&reference, &unlit);
                pool_pixels.push(in_pool.iter().filter(|inside| **inside).count() as f64);
                Some(images.map(|image| pool(image, &reference, &in_pool)))
            }
            None => None,
        };
        pool_rows.extend(pools);
        bar.suspend(|| {
            let display = compared.map(|e| format!("{:>10.4}", e.display)).concat();
            let trail = compared.map(|e| format!("{:>14.4}", e.trail)).concat();
            println!("{frame:>5}{display}{trail}")
        });
        rows.push((frame, compared));
        last_images = Some((
            [
                output.image,
                temporal_image,
                full_image,
                resized_image,
                player_image.clone(),
            ],
            reference,
        ));
    }
    bar.finish_and_clear();

    let median = |values: Vec<f64>| {
        let mut sorted = values;
        sorted.sort_by(f64::total_cmp);
        sorted[sorted.len() / 2]
    };
    // Per image (`IMAGES`), the median over the compared frames of one figure.
    let column = |pick: fn(&Errors) -> f64| {
        std::array::from_fn::<f64, { IMAGES.len() }, _>(|image| {
            median(
                rows.iter()
                    .map(|(_, errors)| pick(&errors[image]))
                    .collect(),
            )
        })
    };
    let (display, linear, trail) = (
        column(|e| e.display),
        column(|e| e.linear),
        column(|e| e.trail),
    );
    let [raw, temporal_rmse, full_rmse, resized_rmse, player_rmse] = display;
    let render_median = median(render_ms.clone());
    let (temporal_median, full_median) = (median(temporal_ms.clone()), median(full_ms.clone()));
    let (player_render_median, player_film_median) = (
        median(player_render_ms.clone()),
        median(player_film_ms.clone()),
    );
    println!(
        "median RMSE (display): raw {raw:.4}, temporal {temporal_rmse:.4} ({:.2}x raw), \
         temporal+spatial {full_rmse:.4} ({:.2}x raw)",
        temporal_rmse / raw,
        full_rmse / raw
    );
    println!(
        "player's view ({}x{} upscaled) against the native pipeline (temporal+spatial): \
         {player_rmse:.4} / {full_rmse:.4} = {:.2}x; against the same frame resized \
         bilinearly: {player_rmse:.4} / {resized_rmse:.4} = {:.2}x",
        render_size.0,
        render_size.1,
        player_rmse / full_rmse,
        player_rmse / resized_rmse
    );
    let listed = |values: &[f64; IMAGES.len()], precision: usize| {
        IMAGES
            .iter()
            .zip(values)
            .map(|(name, value)| format!("{name} {value:.precision$}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    println!("median trail RMSE (ghosting): {}", listed(&trail, 4));
    println!(
        "median ms per frame: render {render_median:.2}, temporal filter {temporal_median:.2}, \
         temporal+spatial filter {full_median:.2} ({:.1}% of render + filter); player's view: \
         render {player_render_median:.2}, filter + upscale {player_film_median:.2} (upscale \
         {:.2})",
        100.0 * full_median / (render_median + full_median),
        median(upscale_ms.clone())
    );

    let pool_summary = (!pool_rows.is_empty()).then(|| {
        let of = |index: usize, pick: fn(&Pool) -> f64| {
            median(pool_rows.iter().map(|row| pick(&row[index])).collect())
        };
        let kept: [f64; IMAGES.len()] = std::array::from_fn(|index| of(index, |p| p.kept));
        let display: [f64; IMAGES.len()] = std::array::from_fn(|index| of(index, |p| p.display));
        (median(pool_pixels.clone()), kept, display)
    });
    match &pool_summary {
        Some((pixels, kept, display)) => println!(
            "moving lamp's pool ({pixels:.0} pixels, median): luminance kept {}; RMSE (display) \
             there {}",
            listed(kept, 2),
            listed(display, 4)
        ),
        None if mover.is_none() => println!("moving lamp's pool: no mover in the player's view"),
        None => println!("moving lamp's pool: {mover_name:?} carries no lamp"),
    }

    if let Some(path) = &options.json {
        let by_image = |values: &[f64; IMAGES.len()]| {
            serde_json::Value::Object(
                IMAGES
                    .iter()
                    .zip(values)
                    .map(|(name, value)| (name.to_string(), json!(value)))
                    .collect(),
            )
        };
        let row_json =
            |e: &Errors| json!({"display": e.display, "linear": e.linear, "trail": e.trail});
        let report = json!({
            "level": level.display().to_string(),
            "view": options.view.name(),
            "width": width, "height": height, "frames": options.frames,
            "render_scale": render_scale,
            "player_render_size": [render_size.0, render_size.1],
            "reference_spp": options.reference_spp,
            "median_rmse_display": by_image(&display),
            "median_rmse_linear": by_image(&linear),
            "median_trail_rmse": by_image(&trail),
            "ratio_full_to_raw": full_rmse / raw,
            "ratio_player_to_full": player_rmse / full_rmse,
            "ratio_player_to_resized": player_rmse / resized_rmse,
            "moving_lamp_pool": pool_summary.map(|(pixels, kept, display)| json!({
                "pixels": pixels,
                "luminance_kept": by_image(&kept),
                "rmse_display": by_image(&display),
            })),
            "ratio_temporal_to_raw": temporal_rmse / raw,
            "median_ms": {
                "render": render_median, "temporal": temporal_median, "full": full_median,
                "player_render": player_render_median, "player_film": player_film_median,
            },
            "compared": rows.iter().map(|(frame, errors)| {
                let mut row = serde_json::Map::new();
                row.insert("frame".into(), json!(frame));
                for (name, errors) in IMAGES.iter().zip(errors) {
                    row.insert(name.to_string(), row_json(errors));
                }
                serde_json::Value::Object(row)
            }).collect::<Vec<_>>(),
        });
        write_atomically(path, serde_json::to_string_pretty(&report)?.as_bytes())
            .with_context(|| format!("writing {}", path.display()))?;
        println!("wrote {}", path.display());
    }
    if let (Some(dir), Some((images, reference))) = (&options.out, last_images) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        for (name, image) in IMAGES
            .iter()
            .zip(&images)
            .chain([("reference", &reference)].iter().map(|(n, i)| (n, *i)))
        {
            let path = dir.join(format!("{name}.png"));
            image.write(&path, 1.0)?;
        }
        println!(
            "wrote {} and reference PNGs to {}",
            IMAGES.join(", "),
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

    fn film(pixels: &[f32]) -> HdrImage {
        HdrImage {
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
