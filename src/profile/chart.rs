//! The bench chart (a PNG) and the bitmap text it and the profiler overlay draw with.
//!
//! Top: each frame a column, its stages stacked bottom-up in `STAGES` order and the stages
//! timed in phases (gameplay, render, film) split into their phases in shades of the
//! stage's colour, on a millisecond axis with gridlines and the frame budget (`BUDGET_MS`,
//! the F3 overlay's) marked; the x axis counts frames. A legend names the colours. Bottom: a
//! histogram of frame times on a millisecond axis, the budget marked, bars counted in frames.

use image::{ImageEncoder as _, Rgba, RgbaImage};
use noto_sans_mono_bitmap::{FontWeight, RasterHeight, get_raster, get_raster_width};

use super::{BUDGET_MS, NESTED, Profile, STAGES};

const WIDTH: u32 = 1280;
const HEIGHT: u32 = 720;
/// Stacked-stage plot and histogram areas: (left, top, right, bottom).
const PLOT: (u32, u32, u32, u32) = (80, 36, 1250, 390);
const HISTOGRAM: (u32, u32, u32, u32) = (80, 530, 1250, 664);
/// The bitmap font's cell width (Noto Sans Mono, 16 px).
pub const GLYPH_WIDTH: u32 = get_raster_width(FontWeight::Regular, RasterHeight::Size16) as u32;
const GRID: [u8; 3] = [52, 52, 60];
const AXIS: [u8; 3] = [110, 110, 120];
const BUDGET: [u8; 3] = [255, 70, 70];

/// A colour per stage (Okabe-Ito-like, distinguishable by colour-blind readers).
pub(super) const COLOURS: [[u8; 3]; STAGES.len()] = [
    [230, 159, 0],
    [86, 180, 233],
    [0, 158, 115],
    [240, 228, 66],
    [255, 200, 210],
    [0, 114, 178],
    [213, 94, 0],
    [204, 121, 167],
    [120, 120, 220],
    [160, 160, 160],
    [90, 60, 40],
];

/// Phase `index` of `count` inside a stage drawn in `colour`: the first phase in the
/// stage's own colour, each later one darker, so the stage still reads as one block.
fn phase_shade(colour: [u8; 3], index: usize, count: usize) -> [u8; 3] {
    let darkness = 0.55 * index as f64 / count.max(1) as f64;
    colour.map(|c| (c as f64 * (1.0 - darkness)).round() as u8)
}

/// Tick spacing for an axis running from 0 to `top`: 1, 2 or 5 times a power of ten, giving
/// four to ten ticks.
fn tick_step(top: f64) -> f64 {
    let rough = top.max(1e-9) / 5.0;
    let power = 10f64.powf(rough.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * power)
        .find(|&step| top / step <= 10.0)
        .unwrap_or(10.0 * power)
}

/// A tick label: no decimals from 1 ms up, one below.
fn ms_label(ms: f64, step: f64) -> String {
    if step >= 1.0 {
        format!("{ms:.0}")
    } else {
        format!("{ms:.1}")
    }
}

/// The chart as PNG bytes.
pub fn png(profile: &Profile) -> anyhow::Result<Vec<u8>> {
    let mut image = RgbaImage::from_pixel(WIDTH, HEIGHT, Rgba([24, 24, 28, 255]));
    let frames = &profile.frames;
    let slowest = frames
        .iter()
        .map(|f| f.frame_ms.max(f.stages.iter().sum()))
        .fold(1e-3, f64::max);
    // The budget line stays on the chart even when every frame is well inside it.
    let scale_top = slowest.max(BUDGET_MS * 1.1);
    let step = tick_step(scale_top);
    let scale_top = (scale_top / step).ceil() * step;

    // Millisecond axis with gridlines, drawn under the columns.
    let (left, top, right, bottom) = PLOT;
    let plot_height = (bottom - top) as f64;
    let y_of = |ms: f64| (bottom as f64 - ms / scale_top * plot_height).round() as u32;
    let mut tick = 0.0;
    while tick <= scale_top + 1e-9 {
        let y = y_of(tick);
        fill(&mut image, left, y, right, y + 1, GRID);
        fill(&mut image, left - 5, y, left, y + 1, AXIS);
        let label = ms_label(tick, step);
        draw_label_right_aligned(&mut image, left - 8, y.saturating_sub(8), &label);
        tick += step;
    }
    draw_text_rgba(&mut image, 4, top.saturating_sub(28), "ms");

    // Stacked stages per frame, the phased stages split into their phases.
    let plot_width = right - left;
    let count = frames.len().max(1) as u64;
    for (index, frame) in frames.iter().enumerate() {
        let x0 = left + (index as u64 * plot_width as u64 / count) as u32;
        let x1 = (left + ((index as u64 + 1) * plot_width as u64 / count) as u32).max(x0 + 1);
        let mut level = 0.0;
        for (stage, (name, &ms)) in STAGES.iter().zip(&frame.stages).enumerate() {
            let parts: Vec<(f64, [u8; 3])> = match NESTED.iter().find(|(n, _, _)| n == name) {
                Some((_, names, times)) if times(frame).iter().sum::<f64>() > 0.0 => times(frame)
                    .iter()
                    .enumerate()
                    .map(|(i, &phase_ms)| (phase_ms, phase_shade(COLOURS[stage], i, names.len())))
                    .collect(),
                _ => vec![(ms, COLOURS[stage])],
            };
            for (part_ms, colour) in parts {
                let (y_low, y_high) = (y_of(level), y_of(level + part_ms));
                fill(&mut image, x0, y_high, x1, y_low, colour);
                level += part_ms;
            }
        }
    }
    // The budget, dashed over the columns.
    let budget_y = y_of(BUDGET_MS);
    for x in (left..right).step_by(6) {
        fill(&mut image, x, budget_y, x + 3, budget_y + 2, BUDGET);
    }
    let budget_label = format!("{BUDGET_MS:.1} ms budget (30 fps)");
    draw_label_right_aligned(
        &mut image,
        right,
        budget_y.saturating_sub(18),
        &budget_label,
    );
    axes(&mut image, PLOT);
    // Frame numbers along the bottom.
    let frame_step = tick_step(frames.len().max(1) as f64).max(1.0) as usize;
    for frame in (0..=frames.len()).step_by(frame_step) {
        let x = left + (frame as u64 * plot_width as u64 / count) as u32;
        fill(&mut image, x, bottom, x + 1, bottom + 5, AXIS);
        let label = frame.to_string();
        let half = GLYPH_WIDTH * label.len() as u32 / 2;
        draw_text_rgba(&mut image, x.saturating_sub(half), bottom + 6, &label);
    }
    draw_label_right_aligned(&mut image, right, bottom + 24, "frame");
    draw_text_rgba(
        &mut image,
        left,
        8,
        &format!(
            "{} {}x{}, {} threads, {} frames: milliseconds per stage, phases shaded",
            profile.scene,
            profile.width,
            profile.height,
            profile.threads,
            frames.len()
        ),
    );

    // Legend: the stages, then each phased stage's phases in their shades.
    let mut x = left;
    let legend_y = bottom + 48;
    for (stage, name) in STAGES.iter().enumerate() {
        x = swatch(&mut image, x, legend_y, COLOURS[stage], name);
    }
    let mut x = left;
    for (name, phases, _) in NESTED {
        let stage = STAGES.iter().position(|s| *s == name).unwrap_or(0);
        draw_text_rgba(&mut image, x, legend_y + 22, &format!("{name}:"));
        x += GLYPH_WIDTH * (name.len() as u32 + 2);
        for (i, phase) in phases.iter().enumerate() {
            let shade = phase_shade(COLOURS[stage], i, phases.len());
            x = swatch(&mut image, x, legend_y + 22, shade, phase);
        }
        x += 16;
    }

    // Histogram of frame times: bins of a tick's fraction, from 0 to the axis' top.
    let (left, top, right, bottom) = HISTOGRAM;
    let hist_step = tick_step(scale_top);
    let bins = ((scale_top / hist_step).round() as usize * 4).clamp(8, 80);
    let mut counts = vec![0u32; bins];
    for frame in frames {
        let bin = (frame.frame_ms / scale_top * bins as f64) as usize;
        counts[bin.min(bins - 1)] += 1;
    }
    let tallest = counts.iter().copied().max().unwrap_or(1).max(1);
    let count_step = tick_step(tallest as f64).max(1.0);
    let count_top = (tallest as f64 / count_step).ceil() * count_step;
    let hist_height = (bottom - top) as f64;
    let mut tick = 0.0;
    while tick <= count_top + 1e-9 {
        let y = (bottom as f64 - tick / count_top * hist_height).round() as u32;
        fill(&mut image, left, y, right, y + 1, GRID);
        fill(&mut image, left - 5, y, left, y + 1, AXIS);
        draw_label_right_aligned(
            &mut image,
            left - 8,
            y.saturating_sub(8),
            &format!("{tick:.0}"),
        );
        tick += count_step;
    }
    let hist_width = (right - left) as f64;
    let x_of = |ms: f64| left + (ms / scale_top * hist_width).round() as u32;
    for (bin, &n) in counts.iter().enumerate() {
        let x0 = x_of(bin as f64 * scale_top / bins as f64);
        let x1 = x_of((bin + 1) as f64 * scale_top / bins as f64);
        let height = (n as f64 / count_top * hist_height).round() as u32;
        fill(
            &mut image,
            x0 + 1,
            bottom - height,
            x1,
            bottom,
            [200, 200, 210],
        );
    }
    let budget_x = x_of(BUDGET_MS);
    for y in (top..bottom).step_by(6) {
        fill(&mut image, budget_x, y, budget_x + 2, y + 3, BUDGET);
    }
    axes(&mut image, HISTOGRAM);
    let mut tick = 0.0;
    while tick <= scale_top + 1e-9 {
        let x = x_of(tick);
        fill(&mut image, x, bottom, x + 1, bottom + 5, AXIS);
        let label = ms_label(tick, hist_step);
        let half = GLYPH_WIDTH * label.len() as u32 / 2;
        draw_text_rgba(&mut image, x.saturating_sub(half), bottom + 6, &label);
        tick += hist_step;
    }
    draw_label_right_aligned(&mut image, right, bottom + 24, "frame time (ms)");
    draw_text_rgba(&mut image, 4, top.saturating_sub(24), "frames");
    let summary = profile.frame();
    draw_text_rgba(
        &mut image,
        left,
        top - 24,
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

/// A legend entry at (x, y): a colour square and its name; returns where the next goes.
fn swatch(image: &mut RgbaImage, x: u32, y: u32, colour: [u8; 3], name: &str) -> u32 {
    fill(image, x, y + 3, x + 10, y + 13, colour);
    draw_text_rgba(image, x + 13, y, name);
    x + 13 + GLYPH_WIDTH * name.len() as u32 + 12
}

/// `text` ending at x (a tick label left of its axis, a note at a plot's right edge).
fn draw_label_right_aligned(image: &mut RgbaImage, x: u32, y: u32, text: &str) {
    let width = GLYPH_WIDTH * text.chars().count() as u32;
    draw_text_rgba(image, x.saturating_sub(width), y, text);
}

fn fill(image: &mut RgbaImage, x0: u32, y0: u32, x1: u32, y1: u32, [r, g, b]: [u8; 3]) {
    for y in y0.min(HEIGHT)..y1.min(HEIGHT) {
        for x in x0.min(WIDTH)..x1.min(WIDTH) {
            image.put_pixel(x, y, Rgba([r, g, b, 255]));
        }
    }
}

/// A plot's y axis (left) and x axis (bottom).
fn axes(image: &mut RgbaImage, (left, top, right, bottom): (u32, u32, u32, u32)) {
    fill(image, left - 1, top, left, bottom + 1, AXIS);
    fill(image, left - 1, bottom, right, bottom + 1, AXIS);
}

fn draw_text_rgba(image: &mut RgbaImage, x: u32, y: u32, text: &str) {
    let (width, height) = image.dimensions();
    draw_text(image.as_mut(), width, height, x, y, text);
}

/// Draws `text` into an RGBA8 `frame` of `width` x `height` with its top-left at (x, y),
/// blending white glyphs over a darkened box so it reads on any image. Clipped at the
/// edges. Noto Sans Mono bitmaps (crate noto-sans-mono-bitmap, SIL Open Font License).
pub fn draw_text(frame: &mut [u8], width: u32, height: u32, x: u32, y: u32, text: &str) {
    let glyph_width = GLYPH_WIDTH;
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::profile::{FrameSample, Stage};

    #[test]
    fn ticks_are_one_two_or_five_times_a_power_of_ten() {
        assert_eq!(tick_step(120.0), 20.0);
        assert_eq!(tick_step(36.7), 5.0);
        assert_eq!(tick_step(4.0), 0.5);
        assert_eq!(tick_step(1000.0), 100.0);
    }

    /// Frames of 20 ms of render (four phases of 5 ms) and 2 ms of film: the render's
    /// column holds its phases in their shades, and the budget line crosses the plot
    /// at 33.3 ms.
    #[test]
    fn the_chart_stacks_phases_in_their_stage_and_marks_the_budget() {
        let mut frame = FrameSample {
            frame_ms: 22.0,
            render_phases: [5.0; 4],
            film_phases: [1.0, 0.5, 0.5, 0.0],
            ..FrameSample::default()
        };
        frame.stages[Stage::Render.index()] = 20.0;
        frame.stages[Stage::Film.index()] = 2.0;
        let profile = Profile {
            frames: vec![frame; 10],
            ..Profile::default()
        };
        let image = image::load_from_memory(&png(&profile).unwrap())
            .unwrap()
            .into_rgb8();
        assert_eq!(image.dimensions(), (WIDTH, HEIGHT));
        // Axis to 40 ms (33.3 x 1.1 = 36.7, ticks of 5).
        let (left, top, _, bottom) = PLOT;
        let y_of = |ms: f64| bottom as f64 - ms / 40.0 * (bottom - top) as f64;
        let x = left + 60;
        let render = Stage::Render.index();
        let at = |ms: f64| image.get_pixel(x, y_of(ms).round() as u32).0;
        assert_eq!(
            at(2.5),
            phase_shade(COLOURS[render], 0, 4),
            "render.primary"
        );
        assert_eq!(
            at(17.5),
            phase_shade(COLOURS[render], 3, 4),
            "render.bounces"
        );
        assert_ne!(at(2.5), at(17.5));
        assert_eq!(
            at(20.5),
            phase_shade(COLOURS[Stage::Film.index()], 0, 3),
            "film.temporal"
        );
        let budget_row = y_of(BUDGET_MS).round() as u32;
        let red = (left..left + 60)
            .filter(|&x| image.get_pixel(x, budget_row).0 == BUDGET)
            .count();
        assert!(
            red >= 20,
            "the budget line is dashed across the plot ({red} px)"
        );
    }
}
