//! Frame step `present`: the heads-up display drawn into the frame buffer: text, with the
//! Noto Sans Mono bitmap font (crate noto-sans-mono-bitmap, SIL Open Font License; no font
//! file), and the light gem.

pub use crate::profile::chart::{GLYPH_WIDTH, draw_text};

use crate::game::WardenState;
use crate::game::exposure::curve::{GEM_STEPS, gem_cells};

/// The light gem, bottom centre: `GEM_STEPS` cells lit up to `value` (0..1), dim grey to
/// warm white as they fill, in a dark frame.
pub fn draw_gem(frame: &mut [u8], width: u32, height: u32, value: f32) {
    let cell = (width / 40).max(4);
    let gap = (cell / 4).max(1);
    let total = GEM_STEPS as u32 * (cell + gap) + gap;
    if total + 4 > width || cell * 2 > height {
        return;
    }
    let left = (width - total) / 2;
    let top = height - cell - 3 * gap;
    let lit = gem_cells(value);
    let mut fill = |x0: u32, y0: u32, w: u32, h: u32, rgb: [u8; 3]| {
        for y in y0..(y0 + h).min(height) {
            for x in x0..(x0 + w).min(width) {
                let at = ((y * width + x) * 4) as usize;
                frame[at..at + 3].copy_from_slice(&rgb);
            }
        }
    };
    fill(
        left - gap,
        top - gap,
        total + 2 * gap,
        cell + 2 * gap,
        [12, 12, 16],
    );
    for step in 0..GEM_STEPS {
        let x = left + gap + step as u32 * (cell + gap);
        let rgb = if step < lit {
            let warmth = (step + 1) as f32 / GEM_STEPS as f32;
            [
                (120.0 + 135.0 * warmth) as u8,
                (110.0 + 120.0 * warmth) as u8,
                (90.0 + 80.0 * warmth) as u8,
            ]
        } else {
            [40, 40, 46]
        };
        fill(x, top, cell, cell, rgb);
    }
}

/// How far above a warden's feet its state mark floats (metres), and the farthest a
/// mark is drawn from.
pub const MARK_HEIGHT: f32 = 2.15;
pub const MARK_RANGE: f32 = 30.0;

/// A warden's state mark at film point `at`: `?` while suspicious or searching, `!` when
/// alert, `X` when it caught the player, over a bar filled to its suspicion (yellow, red
/// when alert). A patrolling warden with no suspicion shows nothing.
pub fn draw_warden_mark(
    frame: &mut [u8],
    width: u32,
    height: u32,
    at: (f32, f32),
    state: WardenState,
    suspicion: f32,
) {
    let glyph = match state {
        WardenState::Patrol if suspicion <= 0.0 => return,
        WardenState::Patrol => "",
        WardenState::Suspicious | WardenState::Searching => "?",
        WardenState::Alert => "!",
        WardenState::Caught => "X",
    };
    let (x, y) = (at.0.round() as i64, at.1.round() as i64);
    let bar = 24i64;
    let (left, top) = (x - bar / 2, y);
    let colour = if matches!(state, WardenState::Alert | WardenState::Caught) {
        [230, 50, 40]
    } else {
        [235, 200, 60]
    };
    let filled = (suspicion.clamp(0.0, 1.0) * bar as f32).round() as i64;
    for row in top..top + 4 {
        for column in left - 1..left + bar + 1 {
            if row < 0 || column < 0 || row >= height as i64 || column >= width as i64 {
                continue;
            }
            let i = ((row as u32 * width + column as u32) * 4) as usize;
            let inside = column >= left && column < left + filled && row > top && row < top + 3;
            let rgb = if inside { colour } else { [20, 20, 24] };
            frame[i..i + 3].copy_from_slice(&rgb);
        }
    }
    if !glyph.is_empty() && x >= 4 && y >= 20 {
        draw_text(frame, width, height, x as u32 - 4, y as u32 - 18, glyph);
    }
}

/// How many points a noise ring is drawn with.
pub const RING_POINTS: usize = 96;

/// Points on a noise ring (film points, None behind the camera) drawn as small dots
/// blended towards white by `strength` (1 new, fading to 0).
pub fn draw_noise_ring(
    frame: &mut [u8],
    width: u32,
    height: u32,
    points: impl Iterator<Item = Option<(f32, f32)>>,
    strength: f32,
) {
    let strength = strength.clamp(0.0, 1.0);
    for (x, y) in points.flatten() {
        let (x, y) = (x.round() as i64, y.round() as i64);
        for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            let (px, py) = (x + dx, y + dy);
            if px < 0 || py < 0 || px >= width as i64 || py >= height as i64 {
                continue;
            }
            let i = ((py as u32 * width + px as u32) * 4) as usize;
            for channel in &mut frame[i..i + 3] {
                *channel = (*channel as f32 + (235.0 - *channel as f32) * strength) as u8;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_gem_lights_as_many_cells_as_its_value_asks() {
        let (width, height) = (320, 180);
        let lit_cells = |value: f32| {
            let mut frame = vec![0u8; (width * height * 4) as usize];
            draw_gem(&mut frame, width, height, value);
            // Count bright pixels on the cells' row, in cell-sized runs.
            let row = (height - 10) as usize; // through the cells (top = height - 14)
            let bright = (0..width as usize)
                .filter(|x| frame[(row * width as usize + x) * 4] > 100)
                .count();
            bright / (width / 40) as usize
        };
        assert_eq!(lit_cells(0.0), 0);
        assert_eq!(lit_cells(0.4), 2);
        assert_eq!(lit_cells(1.0), GEM_STEPS);
    }

    #[test]
    fn text_lights_pixels_inside_its_box_and_clips_outside() {
        let (width, height) = (64, 20);
        let mut frame = vec![100u8; (width * height * 4) as usize];
        draw_text(
            &mut frame,
            width,
            height,
            2,
            2,
            "fps 60 and far too long to fit",
        );
        let lit = frame.chunks_exact(4).filter(|p| p[0] > 200).count();
        assert!(lit > 20, "glyphs drew {lit} bright pixels");
        // Outside the text box the frame is untouched.
        assert_eq!(&frame[0..4], &[100, 100, 100, 100]);
    }
}
