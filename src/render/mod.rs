//! Frame step `render`: camera rays, path tracing with next event estimation, samplers,
//! then hands its frame to `film`. Reads a `RenderScene` (built by `extract`) and writes a
//! `HdrImage`; knows nothing of the ECS or windows.
//!
//! Per call of `render`:
//! 1. split the image into 16 x 16 tiles and hand them to rayon;
//! 2. per tile and sample index, take all the tile's paths through the same phase before
//!    the next (a wavefront over the tile, so coherent rays are traced together and each
//!    phase has its own profiler scope and timer):
//!    - `primary`: a `PixelSampler` keyed by (seed, frame, pixel, sample), a jittered
//!      camera ray, and the closest hits of the tile's rays, traced in packets of 16 x 4
//!      (`AccelScene::intersect_coherent`; the same hits as one ray at a time), and their
//!      surfaces (a hit on the last hit's triangle reuses its `TriangleSurface`);
//!    - `shade`: the first vertex: emission, a light sample and a BSDF sample; rendering
//!      with guides (the real-time view), also the lamp that lights the vertex most,
//!      shaded in full and kept apart (`PathState::with_dominant_apart`), among the lamps
//!      that may reach the box around the tile's hits (`LightSet::reach`);
//!    - `shadow`: the first vertex's shadow rays (all towards the lights), traced as
//!      interleaved streams of single rays (`AccelScene::occluded_stream`; as packets
//!      they measured slower: see accel/packet.rs and accel/stream.rs);
//!    - `bounces`: every path onwards, a vertex at a time: each live path's bounce ray
//!      alone (incoherent: neither packets nor streams paid), then every hit's surface
//!      (its lines asked for ahead: `AccelScene::prefetch_triangle`), then every vertex
//!      shaded, then that vertex's shadow rays as one stream, until every path has ended;
//!      with a radiance cache (the real-time view's), a path whose second vertex's cell
//!      has learnt its light ends there with that light, unless it is one of the frame's
//!      teachers (`cache.rs`);
//! 3. average each pixel's samples in sample order (so the result does not depend on the
//!    thread count) and store the mean in the film (and the kept-apart lamp light's mean
//!    in the guides' `unfiltered` light, which the film's filters leave as it is);
//! 4. with a radiance cache, hand back the teachers' samples, tile by tile in image order,
//!    for the caller to fold into the cache before the next frame
//!    (`RenderOutput::cache_samples`; so the next frame's cache does not depend on the
//!    thread count either).
//!
//! The phases draw each pixel's sample dimensions in the order one path at a time
//! (`integrator::continue_path` from the camera ray) does, so the wavefront and the
//! one-path-at-a-time integrator give bit-identical images (checked by hashing renders),
//! and at the same speed as a per-pixel loop (first-light at 480 x 270, render p50 72.2
//! against 72.3 ms and 72.6 against 71.4 in one run); what the wavefront buys is the
//! batched work each phase can then do (packets, streams, `VertexDrawBatch`, prefetching).
//! In the bounces phase, asking for each incoherent hit's triangle as its ray is traced
//! and its corners' lines `SURFACE_AHEAD` hits before its surface is read took 5% off the
//! phase's time on first-light and the-gallery.
//!
//! # Tests
//!
//! A furnace (a closed box lit by its own walls: Le / (1 - rho), with both integrators),
//! direct light from a tilted polygonal light against Lambert's analytic formula, `path`
//! against `reference` on diffuse, mirror, glass and rough metal, thread-count determinism,
//! and the low-frequency power of the 1-spp error spectrum (blue noise against white).

pub mod bsdf;
pub mod cache;
pub mod camera;
pub mod guides;
pub mod hdr;
pub mod integrator;
pub mod light;
pub mod material;
pub mod planes;
pub mod sampler;
pub mod sampling;
pub mod scene;
pub mod spectrum;

use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use glam::{Vec2, Vec3};
use rayon::prelude::*;

pub use cache::RadianceCache;
pub use camera::Camera;
pub use guides::{GuidePixel, Guides};
pub use hdr::HdrImage;
pub use integrator::{IntegratorKind, RayCounts};
pub use sampler::SamplerKind;
pub use scene::RenderScene;

use crate::accel::{Hit, InstanceMask, Ray};
use crate::profile::{TileSpan, since};
use cache::{CacheSample, CellSizing};
use camera::FilmPoints;
use guides::GuideRects;
use integrator::{
    CacheMark, CacheVertex, NextHit, PathState, RayCone, ShadowQuery, VertexOutcome, cache_vertex,
    camera_sample, end_at_cache, next_hit, next_hits, path_vertex, path_vertex_inlined,
    reference_radiance, surface_at,
};
use light::LightReach;
use planes::SharedRuns;
use sampler::{BlueNoise, PixelSampler, VertexDrawBatch};
use scene::SceneAlpha;

const TILE: u32 = 16;

/// How many bounce hits ahead of the one whose surface is read its corners' lines are
/// asked for (`AccelScene::prefetch_corners`).
const SURFACE_AHEAD: usize = 8;

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

/// Seconds of CPU time each phase of the tiles' work took, summed over the threads that
/// did it (so on two busy threads they add up to about twice the render's wall time).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PhaseTimes {
    /// Camera rays and their closest hits.
    pub primary: f64,
    /// The first vertex: emission, material, light and BSDF samples.
    pub shade: f64,
    /// The first vertex's shadow rays.
    pub shadow: f64,
    /// Every later vertex of every path, shadow rays included.
    pub bounces: f64,
}

impl PhaseTimes {
    /// The phases' names, in `as_array` order (the profiler's `render.*` rows).
    pub const NAMES: [&str; 4] = ["primary", "shade", "shadow", "bounces"];

    pub fn as_array(&self) -> [f64; 4] {
        [self.primary, self.shade, self.shadow, self.bounces]
    }

    pub fn total(&self) -> f64 {
        self.as_array().iter().sum()
    }

    /// `wall` (the render's wall time, any unit) split over the phases in proportion to
    /// their CPU time: what each phase cost the frame, adding up to `wall`.
    pub fn share_of(&self, wall: f64) -> [f64; 4] {
        let total = self.total();
        if total <= 0.0 {
            return [0.0; 4];
        }
        self.as_array().map(|phase| wall * phase / total)
    }

    fn add(&mut self, other: &PhaseTimes) {
        self.primary += other.primary;
        self.shade += other.shade;
        self.shadow += other.shadow;
        self.bounces += other.bounces;
    }
}

/// One tile's mean radiance per pixel (film index, value) and its ray counts.
struct TileResult {
    /// The tile's top-left pixel, and its width (less at the image's right edge).
    origin: (usize, usize),
    width: usize,
    /// What the tile's full paths teach the radiance cache, in pixel order.
    cache_samples: Vec<CacheSample>,
    counts: RayCounts,
    phases: PhaseTimes,
    invalid: u64,
    /// The thread that traced the tile, and when.
    span: TileSpan,
}

/// Sets a tile's `pixels` (row by row, `width` across, from `origin`) in the film
/// (`image_width` across) and its `guide_pixels` in `guides`.
///
/// # Safety
/// No other tile setting any of the same pixels may run at the same time.
unsafe fn set_tile_pixels(
    (origin, width): ((usize, usize), usize),
    (pixels, guide_pixels): (&[Vec3], &[GuidePixel]),
    film: &SharedRuns<Vec3>,
    guides: Option<&GuideRects>,
    image_width: usize,
) {
    let (x0, y0) = origin;
    for (row, values) in pixels.chunks(width.max(1)).enumerate() {
        // SAFETY: the tile's own run of this row (the caller's promise).
        unsafe { film.run((y0 + row) * image_width + x0, values.len()) }.copy_from_slice(values);
    }
    if let Some(guides) = guides {
        // SAFETY: the tile's own rectangle (the caller's promise).
        unsafe { guides.set_rect(origin, width, guide_pixels) };
    }
}

/// Per-thread buffers for a tile's paths, reused from tile to tile.
#[derive(Default)]
struct TileScratch<'a> {
    samplers: Vec<PixelSampler<'a>>,
    /// A vertex's sample values for every path there, drawn together.
    draws: VertexDrawBatch,
    paths: Vec<PathState>,
    /// Per path: traced in full to teach the radiance cache (`RadianceCache::trains`), and
    /// its mark at the second vertex when it will.
    trains: Vec<bool>,
    marks: Vec<Option<CacheMark>>,
    hits: Vec<Option<NextHit>>,
    /// A bounce's closest hits, before their surfaces are read.
    bounce_hits: Vec<Option<Hit>>,
    /// A bounce's hits, and for each second vertex the radiance cache may end, its cell.
    found: Vec<(Option<NextHit>, Option<CacheVertex>)>,
    /// The camera rays' film points (a pinhole's rays are made together), the rays, and
    /// what `intersect_coherent` found for them.
    films: FilmPoints,
    rays: Vec<Ray>,
    accel_hits: Vec<Option<Hit>>,
    /// A vertex's shadow queries (path index, query), their rays, and whether something
    /// blocks each.
    shadows: Vec<(usize, ShadowQuery)>,
    shadow_rays: Vec<Ray>,
    blocked: Vec<bool>,
    /// The paths still going (path index, next ray), this vertex's and the next's.
    live: Vec<(usize, Ray)>,
    next_live: Vec<(usize, Ray)>,
    sums: Vec<Vec3>,
    /// The tile's pixels and (sample 0's) guides, row by row, for `set_tile_pixels`.
    pixels: Vec<Vec3>,
    guides: Vec<GuidePixel>,
    /// Per pixel, the dominant lamp's light kept apart (`PathState::with_dominant_apart`).
    dominant_sums: Vec<Vec3>,
}

impl TileScratch<'_> {
    /// Traces the shadow rays of `shadows` as one stream (`AccelScene::occluded_stream`) and
    /// adds the light each lets through to its path.
    fn resolve_shadows(&mut self, scene: &RenderScene, alpha: &SceneAlpha) {
        self.shadow_rays.clear();
        self.shadow_rays
            .extend(self.shadows.iter().map(|(_, shadow)| shadow.ray));
        self.blocked.clear();
        self.blocked.resize(self.shadow_rays.len(), false);
        scene.accel.occluded_stream(
            &self.shadow_rays,
            InstanceMask::SHADOW,
            alpha,
            &mut self.blocked,
        );
        for ((index, shadow), &blocked) in self.shadows.iter().zip(&self.blocked) {
            shadow.arrive(blocked, &mut self.paths[*index]);
        }
    }
}

pub struct RenderOutput {
    pub image: HdrImage,
    pub rays: RayCounts,
    pub seconds: f64,
    /// Where the tiles' CPU time went.
    pub phases: PhaseTimes,
    /// Each pixel's first hit (`render_guided` only).
    pub guides: Option<Guides>,
    /// Samples whose estimate was NaN or infinite and were dropped (should be 0).
    pub invalid_samples: u64,
    /// Each tile's thread and time, in ms from the render's start (the profiler's tracks).
    pub tiles: Vec<TileSpan>,
    /// What the frame's full paths teach the radiance cache it read, tile by tile in image
    /// order: `RadianceCache::learn` takes them before the next frame's render (empty
    /// without a cache).
    pub cache_samples: Vec<CacheSample>,
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
    render_tiles(scene, camera, settings, progress, false, None, None)
}

/// `render`, plus each pixel's guides (its first hit) for the film step's filters; with a
/// radiance `cache`, paths whose second vertex it stands in for end there with its light,
/// and the frame's full paths list what they teach it in `RenderOutput::cache_samples`
/// (the real-time view's frames: render/cache.rs).
pub fn render_guided(
    scene: &RenderScene,
    camera: &Camera,
    settings: &RenderSettings,
    cache: Option<&RadianceCache>,
) -> RenderOutput {
    render_tiles(scene, camera, settings, &|_| {}, true, None, cache)
}

/// `render_guided` into the buffers of an earlier output (the real-time view's frame after
/// frame: fresh film and guide buffers cost 5 ms a frame in page faults at 480 x 270).
pub fn render_guided_reusing(
    scene: &RenderScene,
    camera: &Camera,
    settings: &RenderSettings,
    earlier: RenderOutput,
    cache: Option<&RadianceCache>,
) -> RenderOutput {
    render_tiles(scene, camera, settings, &|_| {}, true, Some(earlier), cache)
}

fn render_tiles(
    scene: &RenderScene,
    camera: &Camera,
    settings: &RenderSettings,
    progress: &(dyn Fn(f32) + Sync),
    want_guides: bool,
    earlier: Option<RenderOutput>,
    cache: Option<&RadianceCache>,
) -> RenderOutput {
    let start = Instant::now();
    let (width, height) = (settings.width.max(1), settings.height.max(1));
    let tiles_x = width.div_ceil(TILE);
    let tiles: Vec<(u32, u32)> = (0..tiles_x * height.div_ceil(TILE))
        .map(|t| (t % tiles_x * TILE, t / tiles_x * TILE))
        .collect();
    let blue = (settings.sampler == SamplerKind::BlueNoise)
        .then(|| BlueNoise::new(settings.seed, settings.frame));
    let finished = AtomicUsize::new(0);

    // The film and guides: an earlier output's buffers where they fit (every pixel is
    // set by its tile, so nothing needs clearing).
    let (mut film, earlier_guides) = match earlier {
        Some(earlier) if (earlier.image.width, earlier.image.height) == (width, height) => {
            (earlier.image, earlier.guides)
        }
        _ => (HdrImage::new(width, height), None),
    };
    let mut guides = want_guides.then(|| {
        earlier_guides
            .filter(|g| (g.width, g.height) == (width, height))
            .unwrap_or_else(|| Guides::new(width, height))
    });
    // Each tile sets its own pixels as it finishes (copied in afterwards a band of tiles at
    // a time, the film's and guides' pixels took 0.40 ms of a 13.5 ms render on
    // first-light at 640 x 360, half scale, two threads).
    let film_runs = SharedRuns::new(&mut film.pixels);
    let guide_rects = guides.as_mut().map(Guides::rects);
    let results: Vec<TileResult> = tiles
        .par_iter()
        .map_init(TileScratch::default, |scratch, &origin| {
            let tile = Tile {
                scene,
                camera,
                settings,
                blue: blue.as_ref(),
                width,
                height,
                want_guides,
                cache,
            };
            let begun = since(start) as f32;
            let mut result = match settings.integrator {
                IntegratorKind::Path => tile.path_traced(origin, scratch),
                IntegratorKind::Reference => tile.reference(origin, scratch),
            };
            // SAFETY: the tiles do not overlap, and each sets only its own pixels.
            unsafe {
                set_tile_pixels(
                    (result.origin, result.width),
                    (&scratch.pixels, &scratch.guides),
                    &film_runs,
                    guide_rects.as_ref(),
                    width as usize,
                )
            };
            result.span = TileSpan {
                thread: rayon::current_thread_index().map_or(0, |thread| thread as u16),
                start_ms: begun,
                end_ms: since(start) as f32,
            };
            let done = finished.fetch_add(1, Ordering::Relaxed) + 1;
            progress(done as f32 / tiles.len() as f32);
            result
        })
        .collect();

    let cache_samples = (results.iter())
        .flat_map(|tile| &tile.cache_samples)
        .copied()
        .collect();
    let mut rays = RayCounts::default();
    let mut phases = PhaseTimes::default();
    let mut invalid_samples = 0;
    for tile in &results {
        rays.add(&tile.counts);
        phases.add(&tile.phases);
        invalid_samples += tile.invalid;
    }
    RenderOutput {
        image: film,
        rays,
        seconds: start.elapsed().as_secs_f64(),
        phases,
        guides,
        invalid_samples,
        tiles: results.iter().map(|tile| tile.span).collect(),
        cache_samples,
    }
}

/// What every tile of one render shares.
struct Tile<'a> {
    scene: &'a RenderScene,
    camera: &'a Camera,
    settings: &'a RenderSettings,
    blue: Option<&'a BlueNoise>,
    width: u32,
    height: u32,
    want_guides: bool,
    /// The radiance cache as the last frame left it (real-time renders only).
    cache: Option<&'a RadianceCache>,
}

impl<'a> Tile<'a> {
    /// The width of the tile at `origin` (less than TILE at the image's right edge).
    fn tile_width(&self, (x0, _): (u32, u32)) -> usize {
        ((x0 + TILE).min(self.width) - x0) as usize
    }

    /// The tile's pixels (x, y), row by row.
    fn pixels(&self, (x0, y0): (u32, u32)) -> impl Iterator<Item = (u32, u32)> + use<> {
        let (x1, y1) = ((x0 + TILE).min(self.width), (y0 + TILE).min(self.height));
        (y0..y1).flat_map(move |y| (x0..x1).map(move |x| (x, y)))
    }

    fn sampler(&self, (x, y): (u32, u32), sample: u32) -> PixelSampler<'a> {
        let settings = self.settings;
        PixelSampler::new(
            settings.sampler,
            self.blue,
            settings.seed,
            settings.frame,
            (x, y),
            sample,
            settings.spp,
        )
    }

    fn camera_ray(&self, pixel: (u32, u32), sampler: &mut PixelSampler) -> Ray {
        let (film, lens) = self.camera_sample(pixel, sampler);
        self.camera.ray(film, lens)
    }

    /// Where in `pixel` its camera ray goes through the film, and through the lens.
    #[inline(always)]
    /// The ray cone of one of this render's pixels (`RayCone::pixel`).
    fn pixel_cone(&self) -> RayCone {
        RayCone::pixel(self.camera.tan_half_fov, self.camera.height)
    }

    fn camera_sample(&self, (x, y): (u32, u32), sampler: &mut PixelSampler) -> (Vec2, Vec2) {
        let (jitter, lens) = camera_sample(sampler, self.camera.has_lens());
        (Vec2::new(x as f32, y as f32) + jitter, lens)
    }

    /// The path integrator over one tile, phase by phase (see the module doc).
    fn path_traced(&self, origin: (u32, u32), scratch: &mut TileScratch<'a>) -> TileResult {
        let (scene, settings) = (self.scene, self.settings);
        let alpha = scene.alpha();
        let mut counts = RayCounts::default();
        let mut phases = PhaseTimes::default();
        let mut invalid = 0;
        scratch.guides.clear();
        let mut cache_samples = Vec::new();
        let sizing = CellSizing::of(self.camera);
        let count = self.pixels(origin).count();
        scratch.sums.clear();
        scratch.sums.resize(count, Vec3::ZERO);
        scratch.dominant_sums.clear();
        scratch.dominant_sums.resize(count, Vec3::ZERO);

        for sample in 0..settings.spp {
            // Primary: camera rays and their closest hits.
            let mut clock = Instant::now();
            {
                profiling::scope!("render.primary");
                scratch.samplers.clear();
                scratch.paths.clear();
                scratch.hits.clear();
                scratch.rays.clear();
                scratch.trains.clear();
                scratch.marks.clear();
                scratch.marks.resize(count, None);
                scratch.films.clear();
                let has_lens = self.camera.has_lens();
                for pixel in self.pixels(origin) {
                    scratch.trains.push(
                        self.cache
                            .is_some_and(|cache| cache.trains(settings.frame, pixel)),
                    );
                    let mut sampler = self.sampler(pixel, sample);
                    let (film, lens) = self.camera_sample(pixel, &mut sampler);
                    if has_lens {
                        scratch.rays.push(self.camera.ray(film, lens));
                    } else {
                        scratch.films.push(film);
                    }
                    scratch.samplers.push(sampler);
                }
                if !has_lens {
                    self.camera
                        .pinhole_rays(&mut scratch.films, &mut scratch.rays);
                }
                // The real-time film leaves the dominant lamp's light out of its filters:
                // only renders with guides split it off.
                let cone = self.pixel_cone();
                scratch.paths.extend(scratch.rays.iter().map(|ray| {
                    if self.want_guides {
                        PathState::with_dominant_apart(ray, cone)
                    } else {
                        PathState::new(ray, cone)
                    }
                }));
                // The tile's rows in order: packets of 64 are 16 x 4 strips.
                next_hits(
                    scene,
                    &scratch.rays,
                    &alpha,
                    &mut scratch.accel_hits,
                    &mut scratch.hits,
                );
                counts.camera += count as u64;
                if self.want_guides && sample == 0 {
                    (scratch.guides).extend(scratch.hits.iter().map(|hit| {
                        GuidePixel::from_hit_but_albedo(scene, self.camera.position, hit.as_ref())
                    }));
                }
            }
            phases.primary += lap(&mut clock);

            // Shade: the first vertex of every path, queueing its shadow rays (the dominant
            // lamp's first) and the ray that continues it, in path order.
            {
                profiling::scope!("render.shade");
                scratch.shadows.clear();
                scratch.live.clear();
                // Only paths that keep their dominant lamp apart weigh the lamps per tile.
                let reach = if self.want_guides {
                    first_hits_reach(scene, &scratch.hits)
                } else {
                    LightReach::ALL
                };
                let draws = (scratch.draws).draw(&mut scratch.samplers, 0..count);
                for (index, ((path, hit), draws)) in
                    (scratch.paths.iter_mut().zip(&scratch.hits).zip(draws)).enumerate()
                {
                    // Taken apart here rather than kept: a kept outcome (192 bytes) was
                    // copied by a call to memmove, 1.2% of the render's time (perf).
                    let VertexOutcome {
                        shadow,
                        dominant,
                        next,
                        albedo,
                    } = path_vertex_inlined(
                        scene,
                        path,
                        hit.as_ref(),
                        draws,
                        reach,
                        settings.max_depth,
                        &mut counts,
                    );
                    for shadow in [dominant, shadow].into_iter().flatten() {
                        scratch.shadows.push((index, shadow));
                    }
                    if let Some(next) = next {
                        scratch.live.push((index, next));
                    }
                    // The guides' albedo is the first vertex's, as it was shaded (or, for a
                    // path that ends at its first hit, read here).
                    if self.want_guides && sample == 0 {
                        let albedo = albedo.or_else(|| {
                            let found = hit.as_ref()?;
                            Some(GuidePixel::albedo_of(scene, self.pixel_cone(), found))
                        });
                        if let Some(albedo) = albedo {
                            scratch.guides[index].albedo = albedo;
                        }
                    }
                }
            }
            phases.shade += lap(&mut clock);

            // Shadow: the first vertex's shadow rays, together, in interleaved streams.
            {
                profiling::scope!("render.shadow");
                scratch.resolve_shadows(scene, &alpha);
            }
            phases.shadow += lap(&mut clock);

            // Bounces: every path onwards, all of them a vertex at a time (so each vertex's
            // shadow rays are traced as one stream too), until every path has ended.
            {
                profiling::scope!("render.bounces");
                while !scratch.live.is_empty() {
                    scratch.shadows.clear();
                    scratch.next_live.clear();
                    let draws = (scratch.draws).draw(
                        &mut scratch.samplers,
                        scratch.live.iter().map(|&(index, _)| index),
                    );
                    // Every ray traced first, then every hit's surface read, then every
                    // vertex shaded, each pass asking for what a later one reads. The
                    // second vertices' cells are asked of the cache ahead (`prefetch`), so
                    // their slots of its 2 MB table arrive while the other surfaces are
                    // read. Looked up between one vertex's shading and the next's, the
                    // slot's load stalled the core: a third of the tile loop's own cycles
                    // (perf, the-keep); so arranged, the phase's p50 fell 12% (one thread,
                    // 6 alternated pairs). Likewise an incoherent hit's triangle, then its
                    // corners' positions, normals and UVs, were two misses in a row: the
                    // triangle's line is asked for as its ray is traced, its corners'
                    // `SURFACE_AHEAD` hits before its surface is read.
                    scratch.bounce_hits.clear();
                    for (_, ray) in &scratch.live {
                        let hit = scene.accel.intersect(ray, InstanceMask::BOUNCE, &alpha);
                        if let Some(hit) = &hit {
                            scene.accel.prefetch_triangle(hit);
                        }
                        scratch.bounce_hits.push(hit);
                    }
                    scratch.found.clear();
                    for (at, (&(index, ray), hit)) in
                        scratch.live.iter().zip(&scratch.bounce_hits).enumerate()
                    {
                        if let Some(Some(ahead)) = scratch.bounce_hits.get(at + SURFACE_AHEAD) {
                            scene.accel.prefetch_corners(ahead);
                        }
                        let found = hit.map(|hit| surface_at(scene, &ray, hit));
                        let vertex = match (self.cache, &found) {
                            (Some(cache), Some(hit)) => {
                                cache_vertex(scene, &scratch.paths[index], hit, &sizing)
                                    .inspect(|vertex| cache.prefetch(vertex.cell))
                            }
                            _ => None,
                        };
                        scratch.found.push((found, vertex));
                    }
                    for ((&(index, _), (found, vertex)), draws) in
                        (scratch.live.iter()).zip(&scratch.found).zip(draws)
                    {
                        let path = &mut scratch.paths[index];
                        // The radiance cache: at the second vertex, the cell's light ends
                        // the path, unless the path teaches the cache (or the cell has not
                        // learnt enough yet), when it goes on and is marked there.
                        let mut mark = None;
                        if let (Some(cache), Some(hit), Some(vertex)) = (self.cache, found, vertex)
                        {
                            if !scratch.trains[index]
                                && let Some(light) = cache.light(vertex.cell)
                            {
                                end_at_cache(scene, path, hit, light * vertex.albedo);
                                counts.cache_ended += 1;
                                continue;
                            }
                            mark = Some(CacheMark::before(*vertex, path));
                        }
                        let outcome = path_vertex(
                            scene,
                            path,
                            found.as_ref(),
                            draws,
                            settings.max_depth,
                            &mut counts,
                        );
                        if let Some(mut mark) = mark {
                            mark.after_emission(path);
                            scratch.marks[index] = Some(mark);
                        }
                        if let Some(shadow) = outcome.shadow {
                            scratch.shadows.push((index, shadow));
                        }
                        if let Some(next) = outcome.next {
                            scratch.next_live.push((index, next));
                        }
                    }
                    scratch.resolve_shadows(scene, &alpha);
                    std::mem::swap(&mut scratch.live, &mut scratch.next_live);
                }
                cache_samples.extend(
                    (scratch.marks.iter().zip(&scratch.paths))
                        .filter_map(|(mark, path)| Some(mark.as_ref()?.sample(path))),
                );
                for ((sum, dominant_sum), path) in (scratch.sums.iter_mut())
                    .zip(&mut scratch.dominant_sums)
                    .zip(&scratch.paths)
                {
                    let radiance = path.radiance + path.dominant_light;
                    if radiance.is_finite() {
                        *sum += radiance;
                        *dominant_sum += path.dominant_light;
                    } else {
                        invalid += 1;
                    }
                }
            }
            phases.bounces += lap(&mut clock);
        }

        let spp = settings.spp.max(1) as f32;
        // The dominant lamp's light is in the film's pixels and, for the film's filters to
        // leave it alone, in the guides' unfiltered light.
        for (guide, dominant_sum) in scratch.guides.iter_mut().zip(&scratch.dominant_sums) {
            guide.unfiltered += *dominant_sum / spp;
        }
        scratch.pixels.clear();
        (scratch.pixels).extend(scratch.sums.iter().map(|sum| *sum / spp));
        TileResult {
            origin: (origin.0 as usize, origin.1 as usize),
            width: self.tile_width(origin),
            cache_samples,
            counts,
            phases,
            invalid,
            span: TileSpan::default(),
        }
    }

    /// The reference integrator over one tile, one path at a time.
    fn reference(&self, origin: (u32, u32), scratch: &mut TileScratch) -> TileResult {
        let settings = self.settings;
        let mut counts = RayCounts::default();
        let mut invalid = 0;
        let clock = Instant::now();
        let alpha = self.scene.alpha();
        let (pixels, guides) = (&mut scratch.pixels, &mut scratch.guides);
        pixels.clear();
        guides.clear();
        for (x, y) in self.pixels(origin) {
            let mut sum = Vec3::ZERO;
            for sample in 0..settings.spp {
                let mut sampler = self.sampler((x, y), sample);
                let ray = self.camera_ray((x, y), &mut sampler);
                if self.want_guides && sample == 0 {
                    let hit = next_hit(self.scene, &ray, InstanceMask::CAMERA, &alpha);
                    guides.push(GuidePixel::from_hit(
                        self.scene,
                        ray.origin,
                        self.pixel_cone(),
                        hit.as_ref(),
                    ));
                }
                let radiance = reference_radiance(
                    self.scene,
                    ray,
                    self.pixel_cone(),
                    &mut sampler,
                    settings.max_depth,
                    &mut counts,
                );
                if radiance.is_finite() {
                    sum += radiance;
                } else {
                    invalid += 1;
                }
            }
            pixels.push(sum / settings.spp.max(1) as f32);
        }
        TileResult {
            origin: (origin.0 as usize, origin.1 as usize),
            width: self.tile_width(origin),
            cache_samples: Vec::new(),
            counts,
            phases: PhaseTimes {
                bounces: clock.elapsed().as_secs_f64(),
                ..PhaseTimes::default()
            },
            invalid,
            span: TileSpan::default(),
        }
    }
}

/// The punctual lights that may light some first hit of a tile: those of the box around
/// the hits. Dark tiles (outside every cone) then skip weighing the lamps at every pixel:
/// the shade phase fell 9% on first-light, 3% on the-gallery and 1% on the-keep (one
/// thread; their 11 lamps each, wardens' included, fill two groups of 8, each left out
/// only whole).
fn first_hits_reach(scene: &RenderScene, hits: &[Option<NextHit>]) -> LightReach {
    let mut positions = hits.iter().flatten().map(|hit| hit.surface.position);
    let Some(first) = positions.next() else {
        return LightReach::ALL;
    };
    let (low, high) = positions.fold((first, first), |(low, high), position| {
        (low.min(position), high.max(position))
    });
    scene.lights.reach(low, high)
}

/// Seconds since `clock`, which restarts.
fn lap(clock: &mut Instant) -> f64 {
    let now = Instant::now();
    let seconds = (now - *clock).as_secs_f64();
    *clock = now;
    seconds
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::integrator::continue_path;

    /// The game's first level as the renderer sees it.
    fn first_light() -> RenderScene {
        let level = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("levels/first-light.ron");
        let world = crate::scene::world::Scene::load(&level).unwrap_or_else(|e| panic!("{e}"));
        crate::frame::render_scene(&world)
    }

    /// The wavefront over each tile (its shadow rays in streams, each vertex's sample
    /// values drawn for all its paths at once) gives, bit for bit, the image one path at a
    /// time gives (`continue_path`, each shadow ray alone, each value drawn as needed).
    #[test]
    fn the_wavefront_renders_what_one_path_at_a_time_renders() {
        for sampler in [SamplerKind::Stratified, SamplerKind::BlueNoise] {
            wavefront_matches_one_path_at_a_time(sampler);
        }
    }

    fn wavefront_matches_one_path_at_a_time(sampler: SamplerKind) {
        let scene = first_light();
        let settings = RenderSettings {
            width: 40,
            height: 24,
            spp: 2,
            seed: 3,
            frame: 0,
            integrator: IntegratorKind::Path,
            sampler,
            max_depth: 5,
        };
        let camera = Camera::new(&scene.camera, settings.width, settings.height);
        let film = render(&scene, &camera, &settings, &|_| {}).image;
        let blue = BlueNoise::new(settings.seed, settings.frame);
        let tile = Tile {
            scene: &scene,
            camera: &camera,
            settings: &settings,
            blue: (sampler == SamplerKind::BlueNoise).then_some(&blue),
            width: settings.width,
            height: settings.height,
            want_guides: false,
            cache: None,
        };
        let alpha = scene.alpha();
        let mut counts = RayCounts::default();
        let mut lit = 0;
        for y in 0..settings.height {
            for x in 0..settings.width {
                let mut sum = Vec3::ZERO;
                for sample in 0..settings.spp {
                    let mut sampler = tile.sampler((x, y), sample);
                    let ray = tile.camera_ray((x, y), &mut sampler);
                    let mut path = PathState::new(&ray, tile.pixel_cone());
                    continue_path(&scene, &alpha, &mut path, ray, &mut sampler, 5, &mut counts);
                    sum += path.radiance;
                }
                let one_at_a_time = sum / settings.spp as f32;
                assert_eq!(
                    film.pixel(x, y),
                    one_at_a_time,
                    "pixel ({x}, {y}), {} sampler",
                    sampler.name()
                );
                lit += (one_at_a_time != Vec3::ZERO) as usize;
            }
        }
        assert!(lit > 500, "too few lit pixels to compare: {lit}");
    }

    /// The real-time render shades each first vertex's dominant lamp in full and samples
    /// the other lights: an estimate of the same image (its mean agrees with the plain
    /// path's), with that lamp's light in the guides' unfiltered light.
    #[test]
    fn the_dominant_lamp_apart_estimates_the_same_image() {
        let scene = first_light();
        let settings = RenderSettings {
            width: 64,
            height: 36,
            spp: 64,
            seed: 5,
            frame: 0,
            integrator: IntegratorKind::Path,
            sampler: SamplerKind::Stratified,
            max_depth: 1,
        };
        let camera = Camera::new(&scene.camera, settings.width, settings.height);
        let plain = render(&scene, &camera, &settings, &|_| {}).image;
        let split = render_guided(&scene, &camera, &settings, None);
        let guides = split.guides.expect("render_guided gives guides");
        let mean = |film: &HdrImage| {
            film.pixels
                .iter()
                .map(|p| p.as_dvec3())
                .sum::<glam::DVec3>()
                / film.pixels.len() as f64
        };
        let (plain_mean, split_mean) = (mean(&plain), mean(&split.image));
        let relative = (split_mean - plain_mean).abs() / plain_mean;
        assert!(
            relative.max_element() < 0.02,
            "{split_mean} against {plain_mean}"
        );
        // Lamps light the level: somewhere the kept-apart light is most of a pixel's.
        let apart = (0..guides.width * guides.height)
            .filter(|&index| {
                let pixel = guides.pixel(index as usize);
                let radiance = split.image.pixels[index as usize];
                !pixel.is_sky() && pixel.unfiltered.element_sum() > 0.5 * radiance.element_sum()
            })
            .count();
        assert!(
            apart > 100,
            "only {apart} pixels lit mostly by their dominant lamp"
        );
    }
}
