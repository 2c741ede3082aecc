//! The palette's thumbnails: each asset path traced alone by the game's own renderer, and
//! kept on disk so an asset is rendered once per version of its files.
//!
//! A thumbnail is the asset posed at time 0 (`frame::render_scene`), seen from three
//! quarters above and in front (the kit's pieces face +Z), framed so its bounding sphere
//! fills the square, under a uniform studio sky that lights every side (an asset's own
//! lamps add to it): `SIZE` pixels square, `SPP` stratified samples, tone mapped as the
//! window's view is.
//!
//! The cache file is named by a hash of everything the picture depends on: the setup
//! (`SETUP`, size, samples) and the bytes of the glTF and of every buffer and image file
//! it names. An edited asset gets a new name, so a stale picture is never shown; a cache
//! file that does not decode to the right size is rendered again and replaced. Folder:
//! `$GLOAM_CACHE_DIR`, else `gloam` in the platform's cache folder (`~/.cache/gloam`),
//! under `thumbnails/`.
//!
//! The editor renders the ones it lacks on a thread of its own with a one-thread pool
//! (`Thumbnails::start`), so the view keeps the other core; the palette shows a name until
//! its picture arrives.

use std::io::Cursor;
use std::path::{Path, PathBuf};
use std::sync::mpsc::{Receiver, TryRecvError};
use std::time::Instant;

use anyhow::{Context as _, anyhow};
use glam::{EulerRot, Mat4, Quat, Vec3};

use crate::render::{Camera, RenderSettings, SamplerKind, render};
use crate::scene::Scene;
use crate::scene::files::write_atomically;
use crate::scene::world::CameraPlacement;

/// Pixels on a side: the palette shows 48-point tiles, sharp on a 2x display.
pub const SIZE: u32 = 96;

/// Samples per pixel: at 64 the studio sky's soft shadows show no grain at this size.
pub const SPP: u32 = 64;

/// The picture's setup, in the cache key: change it with the camera, sky or tone mapping
/// here, so thumbnails made the old way are not shown as the new.
const SETUP: &str = "three-quarter view, sky 0.85 0.88 0.95, max depth 4, v1";

/// Radiance of the studio sky: a cool white, so warm wood and lamp light stand out.
const SKY: Vec3 = Vec3::new(0.85, 0.88, 0.95);

/// Where the camera looks from, relative to the asset's centre (front, right, above).
const VIEW_FROM: Vec3 = Vec3::new(0.55, 0.5, 1.0);

/// Vertical field of view, degrees: narrow enough that the kit's boxes keep their shape.
const FIELD_OF_VIEW: f32 = 30.0;

/// An 8-bit sRGB picture, row-major from the top-left, four bytes a pixel (opaque).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Thumbnail {
    pub width: u32,
    pub height: u32,
    pub rgba: Vec<u8>,
}

/// Renders the glTF file `asset` as its thumbnail.
pub fn render_thumbnail(asset: &Path) -> anyhow::Result<Thumbnail> {
    let scene = Scene::load(asset)?;
    let mut render_scene = crate::frame::render_scene(&scene);
    render_scene.sky = SKY;
    let bounds = render_scene.accel.bounds();
    let (min, max): (Vec3, Vec3) = (bounds.min.into(), bounds.max.into());
    if !(min.is_finite() && max.is_finite()) || min.cmpgt(max).any() {
        return Err(anyhow!(
            "{}: nothing to see (no triangles)",
            asset.display()
        ));
    }
    render_scene.camera = three_quarter_view(min, max);
    let camera = Camera::new(&render_scene.camera, SIZE, SIZE);
    let settings = RenderSettings {
        width: SIZE,
        height: SIZE,
        spp: SPP,
        sampler: SamplerKind::Stratified,
        max_depth: 4,
        ..RenderSettings::default()
    };
    let output = render(&render_scene, &camera, &settings, &|_| {});
    let mut rgba = vec![0; (SIZE * SIZE * 4) as usize];
    output.image.tone_map_into(&mut rgba, SIZE, SIZE, 1.0);
    Ok(Thumbnail {
        width: SIZE,
        height: SIZE,
        rgba,
    })
}

/// The view of the box [min, max] from `VIEW_FROM`, backed off until its bounding sphere
/// fits the square's height (and so its width).
fn three_quarter_view(min: Vec3, max: Vec3) -> CameraPlacement {
    let yfov = FIELD_OF_VIEW.to_radians();
    let centre = (min + max) * 0.5;
    let radius = ((max - min).length() * 0.5).max(1e-3);
    let distance = radius / (yfov * 0.5).sin();
    let eye = centre + VIEW_FROM.normalize() * distance;
    // The camera looks down its -Z: turned by yaw about Y, then tipped by pitch about X.
    let forward = -VIEW_FROM.normalize();
    let (yaw, pitch) = ((-forward.x).atan2(-forward.z), forward.y.asin());
    let rotation = Quat::from_euler(EulerRot::YXZ, yaw, pitch, 0.0);
    CameraPlacement {
        name: "thumbnail".to_owned(),
        yfov,
        znear: (distance - radius).max(1e-3) * 0.5,
        world_from_camera: Mat4::from_rotation_translation(rotation, eye),
    }
}

/// The folder thumbnails are kept in (None: the platform has no cache folder and no
/// `$GLOAM_CACHE_DIR` is set; thumbnails are then rendered each time).
pub fn cache_folder() -> Option<PathBuf> {
    let base = std::env::var_os("GLOAM_CACHE_DIR")
        .filter(|dir| !dir.is_empty())
        .map(PathBuf::from)
        .or_else(|| dirs::cache_dir().map(|base| base.join("gloam")))?;
    Some(base.join("thumbnails"))
}

/// The cache file's name for `asset` as its files are now: a hash of the setup and of the
/// bytes of the glTF and of each buffer and image file it names.
pub fn cache_name(asset: &Path) -> anyhow::Result<String> {
    let bytes = std::fs::read(asset).with_context(|| format!("reading {}", asset.display()))?;
    let mut hash = Fnv1a::default();
    hash.write(SETUP.as_bytes());
    hash.write(&SIZE.to_le_bytes());
    hash.write(&SPP.to_le_bytes());
    hash.write(&bytes);
    // A file the importer cannot read has no files of its own to hash: its render says why.
    if let Ok(document) = gltf::Gltf::from_slice(&bytes) {
        let buffers = document
            .buffers()
            .filter_map(|buffer| match buffer.source() {
                gltf::buffer::Source::Uri(uri) => Some(uri.to_owned()),
                gltf::buffer::Source::Bin => None,
            });
        let images = document.images().filter_map(|image| match image.source() {
            gltf::image::Source::Uri { uri, .. } => Some(uri.to_owned()),
            gltf::image::Source::View { .. } => None,
        });
        let folder = asset.parent().unwrap_or(Path::new("."));
        for uri in buffers
            .chain(images)
            .filter(|uri| !uri.starts_with("data:"))
        {
            hash.write(uri.as_bytes());
            // A missing file hashes as empty: the render then fails and says which.
            hash.write(&std::fs::read(folder.join(&uri)).unwrap_or_default());
        }
    }
    Ok(format!("{:016x}.png", hash.finish()))
}

/// FNV-1a, 64 bits (Fowler, Noll and Vo): stable across builds and platforms, unlike std's
/// hasher, so a cache outlives an upgrade; every field is written with its length so no two
/// sequences of fields hash the same bytes.
struct Fnv1a(u64);

impl Default for Fnv1a {
    fn default() -> Fnv1a {
        Fnv1a(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv1a {
    fn write(&mut self, bytes: &[u8]) {
        for byte in (bytes.len() as u64).to_le_bytes().iter().chain(bytes) {
            self.0 = (self.0 ^ u64::from(*byte)).wrapping_mul(0x0000_0100_0000_01b3);
        }
    }

    fn finish(&self) -> u64 {
        self.0
    }
}

/// Where a thumbnail came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Origin {
    Cache,
    Rendered,
}

/// `asset`'s thumbnail from the cache in `folder` if it holds this version's, else
/// rendered and (when there is a folder) written there. A cache that cannot be written is
/// no error: the thumbnail is still shown.
pub fn thumbnail(asset: &Path, folder: Option<&Path>) -> anyhow::Result<(Thumbnail, Origin)> {
    let file = folder
        .map(|folder| cache_name(asset).map(|name| folder.join(name)))
        .transpose()?;
    if let Some(cached) = file.as_deref().and_then(read_cached) {
        return Ok((cached, Origin::Cache));
    }
    Ok((render_and_keep(asset, file.as_deref())?, Origin::Rendered))
}

/// `asset`'s thumbnail rendered, and written to the cache `file` when there is one (a
/// cache that cannot be written is no error: the thumbnail is still shown).
fn render_and_keep(asset: &Path, file: Option<&Path>) -> anyhow::Result<Thumbnail> {
    let rendered = render_thumbnail(asset)?;
    if let Some(file) = file {
        if let Some(folder) = file.parent() {
            let _ = std::fs::create_dir_all(folder);
        }
        if let Ok(bytes) = png_bytes(&rendered) {
            let _ = write_atomically(file, &bytes);
        }
    }
    Ok(rendered)
}

/// A cached thumbnail, if `file` decodes to one of this size.
fn read_cached(file: &Path) -> Option<Thumbnail> {
    let bytes = std::fs::read(file).ok()?;
    let image = image::load_from_memory_with_format(&bytes, image::ImageFormat::Png).ok()?;
    let image = image.to_rgba8();
    (image.dimensions() == (SIZE, SIZE)).then(|| Thumbnail {
        width: SIZE,
        height: SIZE,
        rgba: image.into_raw(),
    })
}

fn png_bytes(thumbnail: &Thumbnail) -> anyhow::Result<Vec<u8>> {
    let image =
        image::RgbaImage::from_raw(thumbnail.width, thumbnail.height, thumbnail.rgba.clone())
            .context("thumbnail size")?;
    let mut bytes = Cursor::new(Vec::new());
    image
        .write_to(&mut bytes, image::ImageFormat::Png)
        .context("encoding the thumbnail")?;
    Ok(bytes.into_inner())
}

/// One asset's thumbnail as the worker sends it (or the one line saying why there is none).
pub type Arrived = (PathBuf, Result<Thumbnail, String>);

/// The thumbnails of a palette's assets being made in the background, and what it cost.
pub struct Thumbnails {
    receiver: Receiver<(Arrived, Origin)>,
    started: Instant,
    wanted: usize,
    arrived: usize,
    rendered: usize,
    failed: usize,
    /// Seconds from the start until the last arrived (set when all have, or the worker
    /// stopped).
    pub finished_after: Option<f64>,
    /// Why no thumbnails will come, in one line.
    pub problem: Option<String>,
}

impl Thumbnails {
    /// Starts making the thumbnails of `assets`, cached in `folder`: the cached ones first
    /// (a file read each), then the renders, on one thread of a pool of one.
    pub fn start(assets: Vec<PathBuf>, folder: Option<PathBuf>) -> Thumbnails {
        let (sender, receiver) = std::sync::mpsc::channel();
        let wanted = assets.len();
        let worker = move || {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(1)
                .thread_name(|_| "thumbnails".into())
                .build();
            // Each asset hashed once: the cached ones go at once, the rest are rendered
            // after, into the files they were looked for in.
            let mut missing = Vec::new();
            for asset in assets {
                let file = folder
                    .as_ref()
                    .and_then(|folder| Some(folder.join(cache_name(&asset).ok()?)));
                match file.as_deref().and_then(read_cached) {
                    Some(cached) => {
                        if sender.send(((asset, Ok(cached)), Origin::Cache)).is_err() {
                            return;
                        }
                    }
                    None => missing.push((asset, file)),
                }
            }
            for (asset, file) in missing {
                let made = match &pool {
                    Ok(pool) => pool.install(|| render_and_keep(&asset, file.as_deref())),
                    Err(error) => Err(anyhow!("no thread to render on: {error}")),
                };
                let result = made.map_err(|error| format!("{error:#}"));
                // The palette went (another level, the window closed): stop.
                if sender.send(((asset, result), Origin::Rendered)).is_err() {
                    return;
                }
            }
        };
        let spawned = std::thread::Builder::new()
            .name("thumbnails".into())
            .spawn(worker);
        Thumbnails {
            receiver,
            started: Instant::now(),
            wanted,
            arrived: 0,
            rendered: 0,
            failed: 0,
            finished_after: None,
            problem: spawned.err().map(|error| {
                format!("the palette shows names only: no thread for thumbnails ({error})")
            }),
        }
    }

    /// The thumbnails that have arrived since the last call.
    pub fn poll(&mut self) -> Vec<Arrived> {
        let mut arrived = Vec::new();
        loop {
            match self.receiver.try_recv() {
                Ok((thumbnail, origin)) => {
                    self.arrived += 1;
                    if thumbnail.1.is_err() {
                        self.failed += 1;
                    } else if origin == Origin::Rendered {
                        self.rendered += 1;
                    }
                    arrived.push(thumbnail);
                }
                Err(TryRecvError::Empty) => break,
                Err(TryRecvError::Disconnected) => {
                    // Done, or the worker never started: no more will come.
                    self.wanted = self.arrived;
                    break;
                }
            }
        }
        if self.finished_after.is_none() && self.arrived == self.wanted {
            self.finished_after = Some(self.started.elapsed().as_secs_f64());
        }
        arrived
    }

    /// More are on their way.
    pub fn pending(&self) -> bool {
        self.finished_after.is_none()
    }

    /// What they cost, once all have arrived: "24 assets in 3.97 s (24 rendered, 0 from
    /// the cache)", and how many assets have none.
    pub fn summary(&self) -> Option<String> {
        let seconds = self.finished_after?;
        let failed = match self.failed {
            0 => String::new(),
            n => format!(", {n} without one"),
        };
        Some(format!(
            "{} assets in {seconds:.2} s ({} rendered, {} from the cache{failed})",
            self.wanted,
            self.rendered,
            self.wanted - self.rendered - self.failed
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kit(file: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("assets/kit")
            .join(file)
    }

    #[test]
    fn the_hash_counts_every_field_apart() {
        let hash = |fields: &[&[u8]]| {
            let mut hash = Fnv1a::default();
            fields.iter().for_each(|field| hash.write(field));
            hash.finish()
        };
        assert_ne!(hash(&[b"ab", b"c"]), hash(&[b"a", b"bc"]));
        assert_eq!(hash(&[b"ab", b"c"]), hash(&[b"ab", b"c"]));
    }

    /// The crate fills the middle of its picture and the studio sky its corners.
    #[test]
    fn a_thumbnail_frames_the_asset_against_the_sky() {
        let picture = render_thumbnail(&kit("crate.glb")).expect("the crate renders");
        assert_eq!((picture.width, picture.height), (SIZE, SIZE));
        let at = |x: u32, y: u32| {
            let i = ((y * SIZE + x) * 4) as usize;
            [picture.rgba[i], picture.rgba[i + 1], picture.rgba[i + 2]]
        };
        let sky = crate::render::hdr::tone_map(SKY, 1.0);
        assert_eq!(at(0, 0), sky, "the corner sees the sky");
        assert_ne!(at(SIZE / 2, SIZE / 2), sky, "the middle sees the crate");
        // The crate's wood is warmer than the cool sky.
        let middle = at(SIZE / 2, SIZE / 2);
        assert!(middle[0] > middle[2], "{middle:?}");
    }
}
