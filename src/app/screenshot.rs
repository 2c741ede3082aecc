//! App step, on F12: writes what the window shows (a PNG at the window's size, HUD and
//! menus included, as the player saw it: `capture` draws the frame once more into a texture
//! it can read back) and the linear film under it (an EXR of radiance at the internal
//! resolution, for comparing lighting without the tone mapping), side by side and numbered
//! per level: `first-light-001.png` and `first-light-001.exr`.

use std::path::{Path, PathBuf};

use anyhow::Context as _;

use pixels::{Pixels, PixelsContext, wgpu};

use crate::render::hdr::HdrImage;
use crate::scene::files::write_atomically;

/// The files one screenshot wrote.
#[derive(Debug)]
pub struct Written {
    pub png: PathBuf,
    /// None when no level was on screen (nothing rendered to keep).
    pub exr: Option<PathBuf>,
}

/// Writes `rgba` (the window's frame, `width` x `height`) as PNG and `film` as EXR into
/// `folder`, under the first number neither file already has, so no screenshot replaces
/// another. Each file is written atomically; an error names the file.
pub fn save(
    folder: &Path,
    stem: &str,
    rgba: &[u8],
    (width, height): (u32, u32),
    film: Option<&HdrImage>,
) -> anyhow::Result<Written> {
    let name =
        |number: u32, extension: &str| folder.join(format!("{stem}-{number:03}.{extension}"));
    let number = (1..)
        .find(|&n| !name(n, "png").exists() && !name(n, "exr").exists())
        .context("no free screenshot number")?;
    let png = name(number, "png");
    let rgb: Vec<u8> = rgba
        .chunks_exact(4)
        .flat_map(|pixel| [pixel[0], pixel[1], pixel[2]])
        .collect();
    let image = image::RgbImage::from_raw(width, height, rgb)
        .context("the frame does not match the window's size")?;
    let mut bytes = std::io::Cursor::new(Vec::new());
    image
        .write_to(&mut bytes, image::ImageFormat::Png)
        .context("encoding the PNG")?;
    write_atomically(&png, bytes.get_ref())
        .with_context(|| format!("writing {}", png.display()))?;
    let exr = match film {
        Some(film) => {
            let exr = name(number, "exr");
            film.write(&exr, 1.0)
                .with_context(|| format!("writing {}", exr.display()))?;
            Some(exr)
        }
        None => None,
    };
    Ok(Written { png, exr })
}

/// Draws a frame with `draw` (given an encoder, a target the size of the window's surface,
/// and pixels' context) into a texture of `size`, reads it back and returns it as RGBA8.
/// `draw` is what presenting does: pixels' scaling pass, then the interface over it.
pub fn capture(
    pixels: &Pixels<'_>,
    (width, height): (u32, u32),
    draw: impl FnOnce(&mut wgpu::CommandEncoder, &wgpu::TextureView, &PixelsContext),
) -> anyhow::Result<Vec<u8>> {
    let format = pixels.render_texture_format();
    let bgra = match format {
        wgpu::TextureFormat::Bgra8Unorm | wgpu::TextureFormat::Bgra8UnormSrgb => true,
        wgpu::TextureFormat::Rgba8Unorm | wgpu::TextureFormat::Rgba8UnormSrgb => false,
        other => anyhow::bail!("the window's format {other:?} is not one a PNG can take"),
    };
    let device = pixels.device();
    let size = wgpu::Extent3d {
        width: width.max(1),
        height: height.max(1),
        depth_or_array_layers: 1,
    };
    let texture = device.create_texture(&wgpu::TextureDescriptor {
        label: Some("screenshot"),
        size,
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    });
    // Rows of a texture copy start on 256-byte boundaries.
    let row = (size.width * 4).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT)
        * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
    let buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("screenshot"),
        size: u64::from(row) * u64::from(size.height),
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
        label: Some("screenshot"),
    });
    let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
    draw(&mut encoder, &view, pixels.context());
    encoder.copy_texture_to_buffer(
        texture.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer: &buffer,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(row),
                rows_per_image: Some(size.height),
            },
        },
        size,
    );
    pixels.queue().submit(Some(encoder.finish()));
    let slice = buffer.slice(..);
    let (sender, receiver) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |mapped| {
        let _ = sender.send(mapped);
    });
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .context("waiting for the screenshot's copy")?;
    receiver
        .recv()
        .context("the screenshot's copy never finished")?
        .context("reading the screenshot back")?;
    let mapped = slice.get_mapped_range();
    let mut rgba = Vec::with_capacity((size.width * size.height * 4) as usize);
    for line in mapped.chunks_exact(row as usize) {
        for texel in line[..(size.width * 4) as usize].chunks_exact(4) {
            match bgra {
                true => rgba.extend_from_slice(&[texel[2], texel[1], texel[0], 255]),
                false => rgba.extend_from_slice(&[texel[0], texel[1], texel[2], 255]),
            }
        }
    }
    Ok(rgba)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn scratch(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("gloam-screenshot-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        dir
    }

    #[test]
    fn a_screenshot_writes_the_frame_and_the_linear_film_without_replacing_older_ones() {
        let folder = scratch("numbers");
        let rgba: Vec<u8> = (0..4 * 3 * 2).map(|i| i as u8 * 10).collect();
        let film = HdrImage {
            width: 3,
            height: 2,
            pixels: (0..6).map(|i| Vec3::splat(i as f32 * 2.5)).collect(),
        };
        let first = save(&folder, "first-light", &rgba, (3, 2), Some(&film)).unwrap();
        assert_eq!(first.png, folder.join("first-light-001.png"));
        let png = image::open(&first.png).unwrap().to_rgb8();
        assert_eq!(png.dimensions(), (3, 2));
        assert_eq!(
            png.get_pixel(1, 0).0,
            [40, 50, 60],
            "RGB of the frame, alpha dropped"
        );
        let exr = HdrImage::read_exr(first.exr.as_ref().unwrap()).unwrap();
        assert_eq!(
            exr.pixels, film.pixels,
            "the EXR holds radiance, not tone-mapped bytes"
        );

        let second = save(&folder, "first-light", &rgba, (3, 2), None).unwrap();
        assert_eq!(second.png, folder.join("first-light-002.png"));
        assert!(second.exr.is_none());
        assert!(first.png.exists(), "the first screenshot is kept");
        std::fs::remove_dir_all(&folder).unwrap();
    }

    #[test]
    fn an_unwritable_folder_is_an_error_naming_the_file() {
        let folder = scratch("unwritable");
        std::fs::create_dir_all(folder.parent().unwrap()).unwrap();
        // A file where the folder should be: nothing can be created under it.
        std::fs::write(&folder, b"in the way").unwrap();
        let error = save(&folder, "x", &[0; 4], (1, 1), None).unwrap_err();
        assert!(format!("{error:#}").contains("x-001.png"), "{error:#}");
        std::fs::remove_file(&folder).unwrap();
    }
}
