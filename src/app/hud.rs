//! Frame step `present`: the heads-up text drawn into the frame buffer, with the Noto Sans
//! Mono bitmap font (crate noto-sans-mono-bitmap, SIL Open Font License; no font file).

pub use crate::profile::chart::draw_text;

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
