//! The in-game profiler overlay (F3): where the last 240 frames' milliseconds went.
//!
//! Drawn by the app into its frame buffer after the image, before present. At the bottom:
//! each recent frame a column of its stages stacked in `STAGES` colours (newest at the
//! right), under a line at the 33 ms budget (30 fps). Above it: frame p50/p95/p99, Mrays/s,
//! this frame's BLAS refits and rebuilds, and the three costliest stages' p50.

use super::chart::{COLOURS, draw_text};
use super::{BUDGET_MS, FrameSample, Profile, STAGES, Summary};

/// Frames the overlay shows.
pub const HISTORY: usize = 240;

/// Draws the overlay over an RGBA8 `frame` of `width` x `height` from `recent` (oldest
/// first; only the last `HISTORY` are shown) and this frame's refit and rebuild counts.
pub fn draw(
    frame: &mut [u8],
    width: u32,
    height: u32,
    recent: &[FrameSample],
    refits: u32,
    rebuilds: u32,
) {
    let shown = &recent[recent.len().saturating_sub(HISTORY)..];
    let graph_height = (height / 3).clamp(8, 120);
    let (left, right) = (2u32, width.saturating_sub(2).max(2));
    let bottom = height.saturating_sub(2);
    let top = bottom.saturating_sub(graph_height);
    let frames: Vec<f64> = shown.iter().map(|f| f.frame_ms).collect();
    let summary = Summary::of(&frames);
    let scale = summary.p99.max(BUDGET_MS * 1.2);
    let pixel = |frame: &mut [u8], x: u32, y: u32, rgb: [u8; 3]| {
        if x < width && y < height {
            let i = ((y * width + x) * 4) as usize;
            frame[i..i + 3].copy_from_slice(&rgb);
        }
    };
    // Darken the graph's background, then the stacked columns.
    for y in top..bottom {
        for x in left..right {
            let i = ((y * width + x) * 4) as usize;
            for channel in &mut frame[i..i + 3] {
                *channel /= 4;
            }
        }
    }
    let span = (right - left) as usize;
    for (index, sample) in shown.iter().enumerate() {
        // Newest at the right edge, one column per frame (or more when there is room).
        let x0 = left as usize + (HISTORY - shown.len() + index) * span / HISTORY;
        let x1 = (left as usize + (HISTORY - shown.len() + index + 1) * span / HISTORY).max(x0 + 1);
        let mut level = 0.0;
        for (stage, ms) in sample.stages.iter().enumerate() {
            let y_low = bottom as f64 - level / scale * graph_height as f64;
            level += ms;
            let y_high = (bottom as f64 - level / scale * graph_height as f64).max(top as f64);
            for y in y_high.round() as u32..y_low.round() as u32 {
                for x in x0 as u32..x1 as u32 {
                    pixel(frame, x, y, COLOURS[stage]);
                }
            }
        }
    }
    let budget_y = bottom as f64 - BUDGET_MS / scale * graph_height as f64;
    if budget_y >= top as f64 {
        for x in (left..right).step_by(2) {
            pixel(frame, x, budget_y as u32, [255, 60, 60]);
        }
    }

    // Text: frame statistics, throughput, refits; then the costliest stages.
    let profile = Profile {
        frames: shown.to_vec(),
        ..Profile::default()
    };
    let mut stages: Vec<(usize, f64)> = (0..STAGES.len())
        .map(|s| (s, profile.stage(s).p50))
        .collect();
    stages.sort_by(|a, b| b.1.total_cmp(&a.1));
    let costliest: Vec<String> = stages
        .iter()
        .take(3)
        .map(|&(s, ms)| format!("{} {ms:.1}", STAGES[s]))
        .collect();
    let lines = [
        format!(
            "frame p50 {:.1} p95 {:.1} p99 {:.1} ms",
            summary.p50, summary.p95, summary.p99
        ),
        format!(
            "{:.1} Mrays/s  refits {refits} rebuilds {rebuilds}",
            profile.mrays_per_s()
        ),
        format!("p50 {}", costliest.join("  ")),
    ];
    let line_height = 17;
    for (row, line) in lines.iter().enumerate() {
        let y = top.saturating_sub(line_height * (lines.len() - row) as u32 + 2);
        draw_text(frame, width, height, left, y, line);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::profile::RayMix;

    #[test]
    fn overlay_stacks_stage_colours_and_survives_tiny_frames() {
        let sample = FrameSample {
            stages: [0.5, 0.0, 1.0, 0.2, 0.0, 0.1, 2.0, 0.3, 20.0, 0.5, 3.0],
            frame_ms: 28.0,
            rays: RayMix {
                camera: 100_000,
                ..RayMix::default()
            },
            ..FrameSample::default()
        };
        let (width, height) = (480, 270);
        let mut frame = vec![128u8; (width * height * 4) as usize];
        draw(&mut frame, width, height, &vec![sample.clone(); 300], 2, 1);
        // The render stage's colour fills most of the newest column.
        let render = COLOURS[crate::profile::Stage::Render.index()];
        let column = width - 4;
        let render_pixels = (0..height)
            .filter(|&y| {
                let i = ((y * width + column) * 4) as usize;
                frame[i..i + 3] == render
            })
            .count();
        assert!(render_pixels > 30, "{render_pixels} render-coloured pixels");
        for (w, h) in [(1, 1), (16, 9), (3, 200)] {
            let mut small = vec![0u8; (w * h * 4) as usize];
            draw(&mut small, w, h, &[sample.clone()], 0, 0);
            draw(&mut small, w, h, &[], 0, 0);
        }
    }
}
