//! Frame step `present`: the heads-up text drawn into the frame buffer, with the Noto Sans
//! Mono bitmap font (crate noto-sans-mono-bitmap, SIL Open Font License; no font file).

use noto_sans_mono_bitmap::{FontWeight, RasterHeight, get_raster, get_raster_width};

/// Draws `text` into an RGBA8 `frame` of `width` x `height` with its top-left at (x, y),
/// blending white glyphs over a darkened box so it reads on any image. Clipped at the edges.
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

#[cfg(test)]
mod tests {
    use super::*;

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
