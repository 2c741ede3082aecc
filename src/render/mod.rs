//! Frame step `render`: camera rays, path tracing with next event estimation, samplers,
//! then the `film` step. Reads a `RenderScene` (built by `extract`) and writes a `Film`;
//! knows nothing of the ECS or windows.
//!
//! Per call of `render`:
//! 1. split the image into 16 x 16 tiles and hand them to rayon;
//! 2. per pixel and sample: a `PixelSampler` keyed by (seed, frame, pixel, sample), a
//!    jittered camera ray, and the chosen integrator's radiance estimate;
//! 3. average each pixel's samples in sample order (so the result does not depend on the
//!    thread count) and store the mean in the film.

pub mod blue_noise;
pub mod bsdf;
pub mod camera;
pub mod film;
pub mod integrator;
pub mod light;
pub mod material;
pub mod sampler;
pub mod sampling;
pub mod scene;
pub mod spectrum;

use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use glam::{Vec2, Vec3};
use rayon::prelude::*;

pub use camera::Camera;
pub use film::Film;
pub use integrator::{IntegratorKind, RayCounts};
pub use sampler::SamplerKind;
pub use scene::RenderScene;

use integrator::{camera_sample, path_radiance, reference_radiance};
use sampler::PixelSampler;

const TILE: u32 = 16;

#[derive(Clone, Debug)]
pub struct RenderSettings {
    pub width: u32,
    pub height: u32,
    /// Samples per pixel.
    pub spp: u32,
    pub seed: u32,
    /// Frame index: successive frames continue each pixel's sample sequence.
    pub frame: u32,
    pub integrator: IntegratorKind,
    pub sampler: SamplerKind,
    /// Scattering events at most (pbrt's convention: 0 shows only emitters, 1 adds
    /// direct lighting, 2 one bounce of indirect light, ...).
    pub max_depth: u32,
}

impl RenderSettings {
    /// What the window renders each frame: one blue-noise sample per pixel, the path
    /// integrator, four bounces (frames accumulate while the view is still).
    pub fn real_time(width: u32, height: u32) -> RenderSettings {
        RenderSettings {
            width,
            height,
            spp: 1,
            seed: 0,
            frame: 0,
            integrator: IntegratorKind::Path,
            sampler: SamplerKind::BlueNoise,
            max_depth: 4,
        }
    }
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            width: 640,
            height: 360,
            spp: 16,
            seed: 0,
            frame: 0,
            integrator: IntegratorKind::Path,
            sampler: SamplerKind::BlueNoise,
            max_depth: 8,
        }
    }
}

/// One tile's mean radiance per pixel (film index, value) and its ray counts.
struct TileResult {
    pixels: Vec<(u32, Vec3)>,
    counts: RayCounts,
    invalid: u64,
}

pub struct RenderOutput {
    pub film: Film,
    pub rays: RayCounts,
    pub seconds: f64,
    /// Samples whose estimate was NaN or infinite and were dropped (should be 0).
    pub invalid_samples: u64,
}

impl RenderOutput {
    pub fn mrays_per_second(&self) -> f64 {
        self.rays.total() as f64 / self.seconds.max(1e-9) / 1e6
    }
}

/// Renders `scene` from `camera`; `progress(fraction)` is called as tiles finish.
pub fn render(
    scene: &RenderScene,
    camera: &Camera,
    settings: &RenderSettings,
    progress: &(dyn Fn(f32) + Sync),
) -> RenderOutput {
    let start = Instant::now();
    let (width, height) = (settings.width.max(1), settings.height.max(1));
    let tiles_x = width.div_ceil(TILE);
    let tiles: Vec<(u32, u32)> = (0..tiles_x * height.div_ceil(TILE))
        .map(|t| (t % tiles_x * TILE, t / tiles_x * TILE))
        .collect();
    let mask =
        (settings.sampler == SamplerKind::BlueNoise).then(blue_noise::BlueNoiseMask::shipped);
    let finished = AtomicUsize::new(0);

    let results: Vec<TileResult> = tiles
        .par_iter()
        .map(|&(x0, y0)| {
            let mut counts = RayCounts::default();
            let mut invalid = 0;
            let mut pixels = Vec::with_capacity((TILE * TILE) as usize);
            for y in y0..(y0 + TILE).min(height) {
                for x in x0..(x0 + TILE).min(width) {
                    let mut sum = Vec3::ZERO;
                    for s in 0..settings.spp {
                        let mut sampler = PixelSampler::new(
                            settings.sampler,
                            mask,
                            settings.seed,
                            settings.frame,
                            (x, y),
                            s,
                            settings.spp,
                        );
                        let (jitter, lens) = camera_sample(&mut sampler);
                        let ray = camera.ray(Vec2::new(x as f32, y as f32) + jitter, lens);
                        let radiance = match settings.integrator {
                            IntegratorKind::Path => path_radiance(
                                scene,
                                ray,
                                &mut sampler,
                                settings.max_depth,
                                &mut counts,
                            ),
                            IntegratorKind::Reference => reference_radiance(
                                scene,
                                ray,
                                &mut sampler,
                                settings.max_depth,
                                &mut counts,
                            ),
                        };
                        if radiance.is_finite() {
                            sum += radiance;
                        } else {
                            invalid += 1;
                        }
                    }
                    pixels.push((y * width + x, sum / settings.spp.max(1) as f32));
                }
            }
            let done = finished.fetch_add(1, Ordering::Relaxed) + 1;
            progress(done as f32 / tiles.len() as f32);
            TileResult {
                pixels,
                counts,
                invalid,
            }
        })
        .collect();

    let mut film = Film::new(width, height);
    let mut rays = RayCounts::default();
    let mut invalid_samples = 0;
    for tile in results {
        for (index, value) in tile.pixels {
            film.pixels[index as usize] = value;
        }
        rays.add(&tile.counts);
        invalid_samples += tile.invalid;
    }
    RenderOutput {
        film,
        rays,
        seconds: start.elapsed().as_secs_f64(),
        invalid_samples,
    }
}
