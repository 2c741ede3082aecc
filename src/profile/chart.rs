//! The bench chart (a PNG) and the bitmap text both it and the in-game HUD draw with.
//!
//! Top: each frame a column, its stages stacked bottom-up in `STAGES` order, on a scale of
//! the slowest frame; a legend names the colours. Bottom: a histogram of frame times.

use image::{ImageEncoder as _, Rgba, RgbaImage};
use noto_sans_mono_bitmap::{FontWeight, RasterHeight, get_raster, get_raster_width};

use super::{Profile, STAGES};

const WIDTH: u32 = 960;
const HEIGHT: u32 = 540;
/// Stacked-stage plot and histogram areas: (left, top, right, bottom).
const PLOT: (u32, u32, u32, u32) = (60, 40, 940, 330);
const HISTOGRAM: (u32, u32, u32, u32) = (60, 380, 940, 520);

/// A colour per stage (Okabe-Ito-like, distinguishable by colour-blind readers).
pub(super) const COLOURS: [[u8; 3]; STAGES.len()] = [
    [230, 159, 0],
    [86, 180, 233],
    [0, 158, 115],
    [240, 228, 66],
    [0, 114, 178],
    [213, 94, 0],
    [204, 121, 167],
    [120, 120, 220],
    [160, 160, 160],
    [90, 60, 40],
];

/// The chart as PNG bytes.
pub fn png(profile: &Profile) -> anyhow::Result<Vec<u8>> {
    let mut image = RgbaImage::from_pixel(WIDTH, HEIGHT, Rgba([24, 24, 28, 255]));
    let frames = &profile.frames;
    let slowest = frames
        .iter()
        .map(|f| f.frame_ms.max(f.stages.iter().sum()))
        .fold(1e-3, f64::max);

    // Stacked stages per frame.
    let (left, top, right, bottom) = PLOT;
    let plot_width = right - left;
    let plot_height = (bottom - top) as f64;
    for (index, frame) in frames.iter().enumerate() {
        let x0 = left + (index as u64 * plot_width as u64 / frames.len().max(1) as u64) as u32;
        let x1 = (left
            + ((index as u64 + 1) * plot_width as u64 / frames.len().max(1) as u64) as u32)
            .max(x0 + 1);
        let mut level = 0.0;
        for (stage, ms) in frame.stages.iter().enumerate() {
            let y_low = bottom as f64 - level / slowest * plot_height;
            level += ms;
            let y_high = bottom as f64 - level / slowest * plot_height;
            fill(
                &mut image,
                x0,
                y_high.round() as u32,
                x1,
                y_low.round() as u32,
                COLOURS[stage],
            );
        }
    }
    frame_box(&mut image, PLOT);
    draw_text_rgba(
        &mut image,
        left,
        8,
        &format!(
            "{} {}x{}, {} frames: stages per frame (ms, top = {slowest:.1})",
            profile.scene,
            profile.width,
            profile.height,
            frames.len()
        ),
    );
    // Legend.
    let mut x = left;
    for (stage, name) in STAGES.iter().enumerate() {
        fill(
            &mut image,
            x,
            bottom + 14,
            x + 10,
            bottom + 24,
            COLOURS[stage],
        );
        draw_text_rgba(&mut image, x + 13, bottom + 11, name);
        x += 14 + 8 * name.len() as u32 + 12;
    }

    // Histogram of frame times, 40 bins from 0 to the slowest frame.
    let (left, top, right, bottom) = HISTOGRAM;
    const BINS: usize = 40;
    let mut counts = [0u32; BINS];
    for frame in frames {
        let bin = ((frame.frame_ms / slowest) * BINS as f64) as usize;
        counts[bin.min(BINS - 1)] += 1;
    }
    let tallest = counts.iter().copied().max().unwrap_or(1).max(1);
    let bin_width = (right - left) / BINS as u32;
    for (bin, &count) in counts.iter().enumerate() {
        let x0 = left + bin as u32 * bin_width;
        let height = (count as f64 / tallest as f64 * (bottom - top) as f64) as u32;
        fill(
            &mut image,
            x0 + 1,
            bottom - height,
            x0 + bin_width,
            bottom,
            [200, 200, 210],
        );
    }
    frame_box(&mut image, HISTOGRAM);
    draw_text_rgba(&mut image, left, bottom + 2, "0 ms");
    let top_label = format!("{slowest:.1} ms");
    draw_text_rgba(
        &mut image,
        right.saturating_sub(8 * top_label.len() as u32),
        bottom + 2,
        &top_label,
    );
    let summary = profile.frame();
    draw_text_rgba(
        &mut image,
        left,
        top - 20,
        &format!(
            "frame time histogram: p50 {:.2} ms, p95 {:.2}, p99 {:.2}, max {:.2}",
            summary.p50, summary.p95, summary.p99, summary.max
        ),
    );

    let mut bytes = Vec::new();
    image::codecs::png::PngEncoder::new(&mut bytes).write_image(
        image.as_raw(),
        WIDTH,
        HEIGHT,
        image::ExtendedColorType::Rgba8,
    )?;
    Ok(bytes)
}

fn fill(image: &mut RgbaImage, x0: u32, y0: u32, x1: u32, y1: u32, [r, g, b]: [u8; 3]) {
    for y in y0.min(HEIGHT)..y1.min(HEIGHT) {
        for x in x0.min(WIDTH)..x1.min(WIDTH) {
            image.put_pixel(x, y, Rgba([r, g, b, 255]));
        }
    }
}

fn frame_box(image: &mut RgbaImage, (left, top, right, bottom): (u32, u32, u32, u32)) {
    let grey = [90, 90, 100];
    fill(image, left - 1, top, left, bottom + 1, grey);
    fill(image, left - 1, bottom, right, bottom + 1, grey);
}

fn draw_text_rgba(image: &mut RgbaImage, x: u32, y: u32, text: &str) {
    let (width, height) = image.dimensions();
    draw_text(image.as_mut(), width, height, x, y, text);
}

/// Draws `text` into an RGBA8 `frame` of `width` x `height` with its top-left at (x, y),
/// blending white glyphs over a darkened box so it reads on any image. Clipped at the
/// edges. Noto Sans Mono bitmaps (crate noto-sans-mono-bitmap, SIL Open Font License).
pub fn draw_text(frame: &mut [u8], width: u32, height: u32, x: u32, y: u32, text: &str) {
    let glyph_width = get_raster_width(FontWeight::Regular, RasterHeight::Size16) as u32;
    let glyph_height = RasterHeight::Size16.val() as u32;
    let columns = text.chars().count() as u32;
    // Darken the box behind the text.
    for row in y..(y + glyph_height).min(height) {
        for column in x..(x + columns * glyph_width).min(width) {
            let i = ((row * width + column) * 4) as usize;
            for channel in &mut frame[i..i + 3] {
                *channel /= 3;
            }
        }
    }
    for (index, character) in text.chars().enumerate() {
        let glyph = get_raster(character, FontWeight::Regular, RasterHeight::Size16)
            .or_else(|| get_raster('?', FontWeight::Regular, RasterHeight::Size16));
        let Some(glyph) = glyph else { continue };
        let left = x + index as u32 * glyph_width;
        for (dy, line) in glyph.raster().iter().enumerate() {
            for (dx, &coverage) in line.iter().enumerate() {
                let (px, py) = (left + dx as u32, y + dy as u32);
                if px >= width || py >= height || coverage == 0 {
                    continue;
                }
                let i = ((py * width + px) * 4) as usize;
                for channel in &mut frame[i..i + 3] {
                    *channel = ((*channel as u32 * (255 - coverage as u32) + 255 * coverage as u32)
                        / 255) as u8;
                }
            }
        }
    }
}
