//! App step, on F12: writes what the window shows (a PNG, HUD and menus included, as the
//! player saw it) and the linear film under it (an EXR of radiance at the internal
//! resolution, for comparing lighting without the tone mapping), side by side and numbered
//! per level: `first-light-001.png` and `first-light-001.exr`.

use std::path::{Path, PathBuf};

use anyhow::Context as _;

use crate::render::film::Film;
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
    film: Option<&Film>,
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
        let film = Film {
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
        let exr = Film::read_exr(first.exr.as_ref().unwrap()).unwrap();
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
