//! Frame step `film`: the image a render produces, and the files it is written to.
//!
//! A film pixel holds the mean radiance over the pixel's area (box filter, uniform jitter),
//! in linear Rec.709 RGB, W/(sr m^2). `.exr` files store exactly that (no exposure, no tone
//! mapping) so they compare with any reference renderer. `.png` files and the window go
//! through the one tone mapper below.
//!
//! Tone mapper: radiance x exposure, then the ACES filmic curve fitted by Narkowicz 2015
//! ("ACES Filmic Tone Mapping Curve": (x (2.51 x + 0.03)) / (x (2.43 x + 0.59) + 0.14) per
//! channel, clamped to [0, 1]), then the sRGB transfer function, then 8 bits.

use std::io::Cursor;
use std::path::Path;

use anyhow::{Context as _, bail};
use glam::Vec3;

use crate::scene::files::write_atomically;

#[derive(Clone, Debug, PartialEq)]
pub struct Film {
    pub width: u32,
    pub height: u32,
    /// Mean radiance per pixel, row-major from the top-left.
    pub pixels: Vec<Vec3>,
}

impl Film {
    pub fn new(width: u32, height: u32) -> Film {
        Film {
            width,
            height,
            pixels: vec![Vec3::ZERO; (width * height) as usize],
        }
    }

    pub fn pixel(&self, x: u32, y: u32) -> Vec3 {
        self.pixels[(y * self.width + x) as usize]
    }

    /// Mean over every pixel.
    pub fn mean(&self) -> Vec3 {
        self.pixels.iter().copied().sum::<Vec3>() / self.pixels.len().max(1) as f32
    }

    /// Root-mean-square difference from `reference` over all pixels and channels.
    pub fn rmse(&self, reference: &Film) -> f32 {
        debug_assert_eq!(self.pixels.len(), reference.pixels.len());
        let sum: f64 = self
            .pixels
            .iter()
            .zip(&reference.pixels)
            .map(|(a, b)| (*a - *b).length_squared() as f64)
            .sum();
        (sum / (3 * self.pixels.len().max(1)) as f64).sqrt() as f32
    }

    /// Writes `.exr` (linear radiance) or `.png` (tone mapped with `exposure`), by extension.
    pub fn write(&self, path: &Path, exposure: f32) -> anyhow::Result<()> {
        let extension = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        let bytes = match extension.as_deref() {
            Some("exr") => self.exr_bytes()?,
            Some("png") => self.png_bytes(exposure)?,
            _ => bail!("{}: the output must end in .exr or .png", path.display()),
        };
        write_atomically(path, &bytes)
    }

    fn exr_bytes(&self) -> anyhow::Result<Vec<u8>> {
        let data: Vec<f32> = self.pixels.iter().flat_map(|p| p.to_array()).collect();
        let image =
            image::Rgb32FImage::from_raw(self.width, self.height, data).context("film size")?;
        let mut bytes = Cursor::new(Vec::new());
        image::DynamicImage::ImageRgb32F(image)
            .write_to(&mut bytes, image::ImageFormat::OpenExr)
            .context("encoding EXR")?;
        Ok(bytes.into_inner())
    }

    fn png_bytes(&self, exposure: f32) -> anyhow::Result<Vec<u8>> {
        let data: Vec<u8> = self
            .pixels
            .iter()
            .flat_map(|p| tone_map(*p, exposure))
            .collect();
        let image =
            image::RgbImage::from_raw(self.width, self.height, data).context("film size")?;
        let mut bytes = Cursor::new(Vec::new());
        image
            .write_to(&mut bytes, image::ImageFormat::Png)
            .context("encoding PNG")?;
        Ok(bytes.into_inner())
    }
}

/// Linear radiance to display sRGB bytes (see the module doc).
pub fn tone_map(radiance: Vec3, exposure: f32) -> [u8; 3] {
    let x = (radiance * exposure).max(Vec3::ZERO);
    let mapped = (x * (x * 2.51 + 0.03)) / (x * (x * 2.43 + 0.59) + 0.14);
    mapped
        .clamp(Vec3::ZERO, Vec3::ONE)
        .to_array()
        .map(|c| (srgb_encode(c) * 255.0 + 0.5) as u8)
}

/// The sRGB opto-electronic transfer function (IEC 61966-2-1).
pub fn srgb_encode(linear: f32) -> f32 {
    if linear <= 0.003_130_8 {
        linear * 12.92
    } else {
        1.055 * linear.powf(1.0 / 2.4) - 0.055
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tone_map_is_monotonic_and_bounded() {
        let mut last = 0u8;
        for i in 0..1000 {
            let [r, _, _] = tone_map(Vec3::splat(i as f32 * 0.02), 1.0);
            assert!(r >= last);
            last = r;
        }
        assert_eq!(tone_map(Vec3::ZERO, 1.0), [0, 0, 0]);
        assert_eq!(tone_map(Vec3::splat(1e6), 1.0), [255, 255, 255]);
    }

    #[test]
    fn exr_round_trips_radiance_exactly() {
        let mut film = Film::new(3, 2);
        film.pixels[4] = Vec3::new(17.0, 12.0, 4.0);
        film.pixels[1] = Vec3::new(1e-4, 0.5, 2.25);
        let bytes = film.exr_bytes().unwrap();
        let decoded = image::load_from_memory(&bytes).unwrap().into_rgb32f();
        let back: Vec<Vec3> = decoded.pixels().map(|p| Vec3::from_array(p.0)).collect();
        assert_eq!(back, film.pixels);
    }
}
