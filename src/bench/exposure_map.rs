//! `gloam exposure`: the exposure map of a level, headless, before anyone plays it.
//!
//! A measurement over the simulation, outside the frame: the level is loaded into an
//! `Engine`, its wardens walk their beats for `--time` seconds (no player, so no warden
//! sees anyone), and the simulation's copy of the level as it then stands answers
//! `game::exposure_map` (the game's own body points, lights and shadow rays). Writes the
//! map as JSON (the schema in the README, `gloam exposure`) and as a PNG, `PNG_SCALE`
//! pixels a cell, +x right and +z down.

use std::path::PathBuf;

use anyhow::Context as _;
use bevy_ecs::prelude::{With, World};
use serde_json::{Value, json};

use crate::frame::Engine;
use crate::game::exposure::curve::HIDDEN;
use crate::game::exposure_map::{ExposureMap, Storey, Waypoints, exposure_map};
use crate::game::{Exit, PlayerStart, SIMULATION_HZ, Shard, Transform, WorldGeometry};
use crate::render::RenderSettings;
use crate::scene::files::write_atomically;
use crate::scene::world::Scene;

/// Pixels a cell takes in the PNG, each way.
pub const PNG_SCALE: u32 = 8;

#[derive(Debug, clap::Args)]
pub struct Options {
    /// The level.
    pub level: PathBuf,
    /// Seconds of the wardens' beats before the map is taken (their lamps move with them).
    #[arg(long, default_value_t = 0.0, value_parser = crate::cli::values::non_negative)]
    pub time: f64,
    /// The side of a cell in metres.
    #[arg(long, default_value_t = crate::game::nav::CELL, value_parser = crate::cli::values::positive_f32)]
    pub cell: f32,
    /// The gem a route may not rise above.
    #[arg(long, default_value_t = 0.5, value_parser = crate::cli::values::unit)]
    pub threshold: f32,
    /// The map as a PNG.
    #[arg(long, value_name = "MAP.png")]
    pub out: PathBuf,
    /// The map as JSON.
    #[arg(long, value_name = "MAP.json")]
    pub json: PathBuf,
}

pub fn run(options: &Options) -> anyhow::Result<()> {
    if !(options.time.is_finite() && options.time >= 0.0 && options.time <= 3600.0) {
        anyhow::bail!("--time must be between 0 and 3600 seconds");
    }
    if !(options.cell.is_finite() && (0.05..=4.0).contains(&options.cell)) {
        anyhow::bail!("--cell must be between 0.05 and 4 metres");
    }
    if !(options.threshold.is_finite() && (0.0..=1.0).contains(&options.threshold)) {
        anyhow::bail!("--threshold must be between 0 and 1");
    }
    let scene = Scene::load(&options.level)?;
    let mut engine = Engine::new(&scene, RenderSettings::real_time(1, 1));
    for _ in 0..(options.time * SIMULATION_HZ).round() as u64 {
        engine.step();
    }
    engine.update_step_world();
    let waypoints = waypoints(&mut engine.world).with_context(|| {
        format!(
            "{}: the level has no player start to map from",
            options.level.display()
        )
    })?;
    let geometry = &engine.world.resource::<WorldGeometry>().0;
    let bounds = geometry
        .bounds()
        .with_context(|| format!("{}: the level has no geometry", options.level.display()))?;
    let start = std::time::Instant::now();
    let map = exposure_map(
        geometry.as_ref(),
        bounds,
        options.cell,
        &waypoints,
        options.threshold,
    );
    let seconds = start.elapsed().as_secs_f64();
    let reached: usize = map
        .storeys
        .iter()
        .map(|s| s.standing.iter().flatten().count())
        .sum();
    let route = match map.route.max_exposure {
        Some(max) => format!(
            "the darkest route peaks at {max:.3}: {}",
            if map.route.exists {
                format!("at or below {}", options.threshold)
            } else {
                format!("above {}", options.threshold)
            }
        ),
        None => "no walkable route reaches every shard and the exit".to_string(),
    };
    println!(
        "{} at {} s: {}x{} cells of {} m, {reached} the player reaches ({} storeys); {route}; computed in {:.0} ms",
        options.level.display(),
        options.time,
        map.width,
        map.depth,
        map.cell_size,
        map.storeys.len(),
        seconds * 1e3
    );
    let text = serde_json::to_string_pretty(&map_json(&map, options.threshold))
        .context("encoding the map")?;
    write_atomically(&options.json, text.as_bytes())?;
    write_atomically(&options.out, &map_png(&map, &waypoints, options.threshold)?)?;
    println!(
        "wrote {} and {}",
        options.json.display(),
        options.out.display()
    );
    Ok(())
}

/// The spawn, shards and exit of the world's level (None without a player start).
fn waypoints(world: &mut World) -> Option<Waypoints> {
    let spawn = world
        .query_filtered::<&Transform, With<PlayerStart>>()
        .iter(world)
        .next()?
        .translation;
    let shards = world
        .query::<(&Transform, &Shard)>()
        .iter(world)
        .map(|(t, shard)| (t.translation, shard.radius))
        .collect();
    let exit = world
        .query::<(&Transform, &Exit)>()
        .iter(world)
        .next()
        .map(|(t, exit)| (t.translation, exit.radius));
    Some(Waypoints {
        spawn,
        shards,
        exit,
    })
}

/// `depth` rows of `width` values, null where the player cannot stand.
fn rows(map: &ExposureMap, values: &[Option<f32>]) -> Value {
    Value::Array(
        values
            .chunks(map.width.max(1))
            .map(|row| Value::Array(row.iter().map(|v| json!(v)).collect()))
            .collect(),
    )
}

/// The JSON report (the README's schema).
pub fn map_json(map: &ExposureMap, threshold: f32) -> Value {
    let empty = Storey {
        standing: vec![None; map.width * map.depth],
        crouching: vec![None; map.width * map.depth],
    };
    let ground = map.storeys.first().unwrap_or(&empty);
    let mut report = json!({
        "origin": [map.origin.0, map.origin.1],
        "cell_size": map.cell_size,
        "width": map.width,
        "depth": map.depth,
        "standing": rows(map, &ground.standing),
        "crouching": rows(map, &ground.crouching),
        "route": {
            "exists": map.route.exists,
            "max_exposure": map.route.max_exposure,
            "threshold": threshold,
        },
    });
    if map.storeys.len() > 1 {
        report["floors"] = Value::Array(
            map.storeys[1..]
                .iter()
                .enumerate()
                .map(|(above, storey)| {
                    json!({
                        "storey": above + 1,
                        "standing": rows(map, &storey.standing),
                        "crouching": rows(map, &storey.crouching),
                    })
                })
                .collect(),
        );
    }
    report
}

/// The ground storey standing, `PNG_SCALE` pixels a cell: black where the player cannot
/// stand, dark blue where hidden (no cell of the gem lit), warming to yellow as the gem
/// rises, red above the threshold; the spawn white, the shards cyan, the exit green.
fn map_png(map: &ExposureMap, waypoints: &Waypoints, threshold: f32) -> anyhow::Result<Vec<u8>> {
    let (width, height) = (map.width as u32 * PNG_SCALE, map.depth as u32 * PNG_SCALE);
    let mut image = image::RgbImage::new(width.max(1), height.max(1));
    let ground = map.storeys.first();
    let colour = |value: Option<f32>| -> [u8; 3] {
        match value {
            None => [12, 12, 14],
            Some(v) if v < HIDDEN => [20, 30, 70],
            Some(v) if v > threshold => [200, 40, 30],
            Some(v) => {
                let t = ((v - HIDDEN) / (threshold - HIDDEN).max(1e-3)).clamp(0.0, 1.0);
                [
                    (60.0 + 180.0 * t) as u8,
                    (60.0 + 150.0 * t) as u8,
                    (90.0 - 50.0 * t) as u8,
                ]
            }
        }
    };
    for row in 0..map.depth {
        for column in 0..map.width {
            let value = ground.and_then(|g| g.standing[row * map.width + column]);
            let rgb = colour(value);
            for y in 0..PNG_SCALE {
                for x in 0..PNG_SCALE {
                    image.put_pixel(
                        column as u32 * PNG_SCALE + x,
                        row as u32 * PNG_SCALE + y,
                        image::Rgb(rgb),
                    );
                }
            }
        }
    }
    let mut mark = |at: glam::Vec3, rgb: [u8; 3]| {
        let x = ((at.x - map.origin.0) / map.cell_size * PNG_SCALE as f32) as i64;
        let y = ((at.z - map.origin.1) / map.cell_size * PNG_SCALE as f32) as i64;
        for dy in -3..=3 {
            for dx in -3..=3 {
                let (px, py) = (x + dx, y + dy);
                if px >= 0 && py >= 0 && (px as u32) < width && (py as u32) < height {
                    image.put_pixel(px as u32, py as u32, image::Rgb(rgb));
                }
            }
        }
    };
    mark(waypoints.spawn, [255, 255, 255]);
    for &(shard, _) in &waypoints.shards {
        mark(shard, [80, 230, 255]);
    }
    if let Some((exit, _)) = waypoints.exit {
        mark(exit, [80, 240, 100]);
    }
    let mut bytes = std::io::Cursor::new(Vec::new());
    image::DynamicImage::ImageRgb8(image)
        .write_to(&mut bytes, image::ImageFormat::Png)
        .context("encoding the PNG")?;
    Ok(bytes.into_inner())
}
