//! `gloam exposure`: the exposure map of a level, headless, before anyone plays it.
//!
//! A measurement over the simulation, outside the frame (`headless::exposure::compute`, which
//! the editor's overlay shares): the level's wardens walk their beats for `--time` seconds
//! and the game's own body points, lights and shadow rays give each cell its gem. Writes the
//! map as JSON (its schema: `headless::bench`, `gloam exposure`) and as a PNG, `PNG_SCALE`
//! pixels a cell, +x right and +z down.

use std::path::PathBuf;

use anyhow::Context as _;
use serde_json::{Value, json};

use crate::game::exposure_map::{ExposureMap, Storey, Waypoints};
use crate::headless::exposure::{colour, compute};
use crate::scene::files::write_atomically;
use crate::scene::world::Scene;

/// Pixels a cell takes in the PNG, each way.
pub const PNG_SCALE: u32 = 8;

#[derive(Debug, clap::Args)]
pub struct Options {
    /// The level.
    pub level: PathBuf,
    /// Seconds of the wardens' beats before the map is taken (their lamps move with them).
    #[arg(long, default_value_t = 0.0, value_parser = crate::headless::values::non_negative)]
    pub time: f64,
    /// The side of a cell in metres.
    #[arg(long, default_value_t = crate::game::nav::CELL, value_parser = crate::headless::values::positive_f32)]
    pub cell: f32,
    /// The gem a route may not rise above.
    #[arg(long, default_value_t = 0.5, value_parser = crate::headless::values::unit)]
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
    let computed = compute(&scene, options.time, options.cell, options.threshold)
        .map_err(|problem| anyhow::anyhow!("{}: {problem}", options.level.display()))?;
    let (map, waypoints, seconds) = (computed.map, computed.waypoints, computed.seconds);
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

/// `depth` rows of `width` values, null where the player cannot stand.
fn rows(map: &ExposureMap, values: &[Option<f32>]) -> Value {
    Value::Array(
        values
            .chunks(map.width.max(1))
            .map(|row| Value::Array(row.iter().map(|v| json!(v)).collect()))
            .collect(),
    )
}

/// The JSON report (its schema: `headless::bench`).
pub fn map_json(map: &ExposureMap, threshold: f32) -> Value {
    let empty = Storey {
        standing: vec![None; map.width * map.depth],
        crouching: vec![None; map.width * map.depth],
        floor: vec![None; map.width * map.depth],
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
            "path": map.route.path.iter().map(|p| [p.x, p.y, p.z]).collect::<Vec<_>>(),
            "chokepoints": map.route.chokepoints.iter().map(|p| [p.x, p.y, p.z]).collect::<Vec<_>>(),
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
    let colour = |value: Option<f32>| match value {
        None => [12, 12, 14],
        Some(value) => colour(value, threshold),
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
