//! Frame step `present`: the heads-up display drawn into the frame buffer: text, with the
//! Noto Sans Mono bitmap font (crate noto-sans-mono-bitmap, SIL Open Font License; no font
//! file), and the light gem.

pub use crate::profile::chart::draw_text;

/// Steps the light gem is shown in: few enough to read at a glance (Splinter Cell's meter
/// has 3-5; the exact value is on the F3 overlay).
pub const GEM_STEPS: usize = 5;

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
    let lit = (value.clamp(0.0, 1.0) * GEM_STEPS as f32).round() as usize;
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
