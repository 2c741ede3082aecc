//! Frame step `film`, first filter: temporal accumulation with reprojection, after SVGF
//! (Schied et al. 2017, "Spatiotemporal Variance-Guided Filtering: Real-Time
//! Reconstruction for Path-Traced Global Illumination") with the colour clamp of TAA
//! (Karis 2014, "High Quality Temporal Supersampling"; Salvi 2016's variance clipping).
//!
//! Owns last frame's history (demodulated illumination, luminance moments, history length)
//! and first hits (`reproject::LastPixel`), camera and instance transforms. Per frame, a
//! band of rows at a time, for every pixel (steps 2 and 3 are `reproject`'s):
//! 1. demodulate: illumination = (radiance - unfiltered) / albedo (`GuidePixel::demodulate`);
//! 2. motion: carry the first hit back through its instance's previous transform and
//!    project it with the previous camera; that film point is where history is read;
//! 3. validate the 2 x 2 bilinear taps there by instance, depth and normal; with no valid
//!    tap the pixel is disoccluded and its history starts again;
//! 4. clamp the history to the current 3 x 3 neighbourhood's mean +- `clamp_sigma`
//!    standard deviations (stale light is pulled towards what the frame shows now);
//! 5. blend: an exponential moving average whose weight is 1/length until it reaches
//!    `alpha_min`, for the illumination and its first two luminance moments, whose spread
//!    is the variance the spatial filter (`atrous`) steers by.

use glam::{Affine3A, Vec2, Vec3, Vec4};
use rayon::prelude::*;

use super::reproject::{LastPixel, LastTransforms, ProjectedRow, Reprojection, SurfaceRow};
use crate::render::camera::Camera;
use crate::render::film::Film;
use crate::render::guides::{
    ALBEDO_B, ALBEDO_FLOOR, ALBEDO_G, ALBEDO_R, Guides, NO_INSTANCE, UNFILTERED_B, UNFILTERED_G,
    UNFILTERED_R,
};
use crate::render::planes::{BAND_ROWS, BLUE, GREEN, RED, SIGNAL_PLANES, SignalPlanes, VARIANCE};

/// How the history is kept; the defaults are what `gloam flythrough` measured best.
#[derive(Clone, Debug, PartialEq)]
pub struct TemporalSettings {
    /// The newest frame's weight in the moving average never drops below this.
    pub alpha_min: f32,
    /// The same for the luminance moments (they need fewer frames to be useful).
    pub moments_alpha_min: f32,
    /// History is clamped to the neighbourhood mean +- this many standard deviations.
    pub clamp_sigma: f32,
    /// A tap is the same surface when its depth is within this fraction of the expected.
    pub depth_tolerance: f32,
    /// ... and its normal is within this cosine of the expected.
    pub normal_tolerance: f32,
}

impl Default for TemporalSettings {
    fn default() -> Self {
        TemporalSettings {
            // `gloam flythrough` (moving camera, 3 a-trous passes), RMSE of temporal +
            // spatial against raw: 0.05 -> 0.37x, 0.1 -> 0.32x, 0.15 -> 0.30x, 0.2 -> 0.29x,
            // 0.25 -> 0.285x. Lag outweighs noise once the spatial filter runs; 0.2 keeps a
            // still view's history about 9 frames long. Under the upscaler, which keeps a
            // history of its own at the shown resolution, 0.2 is best as well (player's
            // view RMSE, first-light 320x180 -> 640x360: 0.7 -> 0.0216, 0.5 -> 0.0210,
            // 0.3 -> 0.0205, 0.2 -> 0.0202, 0.1 -> 0.0201 with more ghosting).
            alpha_min: 0.2,
            moments_alpha_min: 0.2,
            clamp_sigma: 2.0,
            depth_tolerance: 0.05,
            normal_tolerance: 0.9,
        }
    }
}

/// One pixel's history.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct History {
    /// Demodulated illumination, averaged.
    pub illumination: Vec3,
    /// Mean luminance and mean squared luminance.
    pub moments: Vec2,
    /// Frames in the average (1 on a fresh or disoccluded pixel).
    pub length: f32,
}

/// What this frame's accumulation gives the spatial filter.
#[derive(Clone, Debug, Default)]
pub struct Accumulated {
    /// The averaged illumination, and its luminance variance per pixel (from the moments,
    /// or from the neighbourhood while the history is short), in the planes the a-trous
    /// passes read.
    pub signal: SignalPlanes,
}

/// History lengths below this use the neighbourhood's variance (SVGF's rule: the moments
/// of a few frames say little).
const SHORT_HISTORY: f32 = 4.0;

#[derive(Default)]
pub struct TemporalFilter {
    pub settings: TemporalSettings,
    width: u32,
    height: u32,
    /// Last frame's pixels: history, and first hits as much as validation reads.
    last: Vec<LastPixel>,
    camera: Option<Camera>,
    /// Last frame's world-from-object per instance.
    instances: LastTransforms,
    /// This frame's result; its buffers, like the others here, are reused frame to frame
    /// (fresh megabyte buffers each frame cost more in page faults than the blending).
    accumulated: Accumulated,
    next: Vec<LastPixel>,
}

pub use crate::scene::model::luminance;

impl TemporalFilter {
    pub fn new(settings: TemporalSettings) -> TemporalFilter {
        TemporalFilter {
            settings,
            ..TemporalFilter::default()
        }
    }

    /// Forgets everything (a new level, a new resolution): the next frame starts afresh.
    pub fn reset(&mut self) {
        self.last.clear();
        self.camera = None;
        self.instances.clear();
    }

    /// Accumulates this frame (`radiance` with its `guides`, seen by `camera`, with the
    /// instances at `instances`' world-from-object transforms) into the history.
    pub fn accumulate(
        &mut self,
        radiance: &Film,
        guides: &Guides,
        camera: &Camera,
        instance_transforms: &[Affine3A],
    ) -> &Accumulated {
        let (width, height) = (radiance.width, radiance.height);
        debug_assert_eq!((guides.width, guides.height), (width, height));
        if (width, height) != (self.width, self.height) {
            self.reset();
            self.width = width;
            self.height = height;
        }
        let count = (width * height) as usize;
        let band = width as usize * BAND_ROWS;
        self.next.resize(count, LastPixel::default());
        // 1-5 a band of rows at a time: demodulate (the band and a row either side, for the
        // neighbourhoods), project a row, then per pixel move, validate, clamp, blend; and
        // keep this frame's history and first hits for the next. (Demodulated in a pass of
        // its own, the image went through memory once more: 2 MB written and read again.)
        let motions = self.instances.motions(instance_transforms);
        let reprojection = self.camera.as_ref().map(|previous_camera| Reprojection {
            projection: previous_camera.projection(),
            last: &self.last,
            width: width as usize,
            height: height as usize,
            motions: &motions,
            settings: &self.settings,
            portable_only: false,
        });
        let accumulated = &mut self.accumulated;
        accumulated.signal.resize(width as usize, height as usize);
        let settings = &self.settings;
        let instances = guides.instances();
        let width = width as usize;
        self.next
            .par_chunks_mut(band)
            .zip(accumulated.signal.bands_mut())
            .for_each_init(
                || (NeighbourhoodRows::new(width), ProjectedRow::default()),
                |(rows, projected), (next, (first_row, signal))| {
                    let last_row = first_row + next.len() / width - 1;
                    rows.sum_band(radiance, guides, first_row as u32, last_row as u32);
                    for (row, (next, signal)) in next
                        .chunks_mut(width)
                        .zip(signal.chunks_mut(SIGNAL_PLANES * width))
                        .enumerate()
                    {
                        let y = first_row + row;
                        let instances = &instances[y * width..][..width];
                        let surfaces = SurfaceRow::new(guides, y);
                        if let Some(reprojection) = &reprojection {
                            reprojection.project_row(guides, y, projected);
                        }
                        for x in 0..width {
                            let (history, variance) = if instances[x] == NO_INSTANCE {
                                (History::default(), 0.0)
                            } else {
                                let before = reprojection.as_ref().and_then(|reprojection| {
                                    reprojection.history_at(
                                        guides,
                                        &surfaces,
                                        projected,
                                        x,
                                        y,
                                        instances[x],
                                    )
                                });
                                let around = rows.neighbourhood(x as u32, y as u32);
                                blend(rows.current(x as u32, y as u32), &around, before, settings)
                            };
                            next[x] = LastPixel::new(&surfaces, x, history);
                            signal[RED * width + x] = history.illumination.x;
                            signal[GREEN * width + x] = history.illumination.y;
                            signal[BLUE * width + x] = history.illumination.z;
                            signal[VARIANCE * width + x] = variance;
                        }
                    }
                },
            );
        std::mem::swap(&mut self.last, &mut self.next);
        self.camera = Some(camera.clone());
        self.instances.record(instance_transforms);
        &self.accumulated
    }

    /// The instances were numbered anew (things spawned or despawned): `new_index[old]` is
    /// each old instance's new index (None: gone). The history follows its surfaces to
    /// their new numbers, so a spawn does not start every pixel's history again; a gone
    /// instance's pixels lose theirs, as a disocclusion would.
    pub fn renumber_instances(&mut self, new_index: &[Option<u32>]) {
        self.instances.renumber(new_index);
        for pixel in &mut self.last {
            if pixel.instance != NO_INSTANCE {
                pixel.instance = new_index
                    .get(pixel.instance as usize)
                    .copied()
                    .flatten()
                    .unwrap_or(NO_INSTANCE);
            }
        }
    }

    /// What the last `accumulate` gave.
    pub fn accumulated(&self) -> &Accumulated {
        &self.accumulated
    }

    /// Pixel `index`'s (row-major) history length after the last `accumulate`: 1 where
    /// its history started again.
    pub fn history_length(&self, index: usize) -> f32 {
        self.last[index].history.length
    }

    /// Replaces the history's illumination (SVGF keeps the first a-trous iteration's
    /// output as history: less noise carried forward).
    pub fn feed_back(&mut self, illumination: &SignalPlanes) {
        let width = illumination.width();
        if width * illumination.height() != self.last.len() || width == 0 {
            return;
        }
        self.last
            .par_chunks_mut(width)
            .enumerate()
            .for_each(|(y, last)| {
                let (red, green, blue) = (
                    illumination.row(y, RED),
                    illumination.row(y, GREEN),
                    illumination.row(y, BLUE),
                );
                for (x, last) in last.iter_mut().enumerate() {
                    last.history.illumination = Vec3::new(red[x], green[x], blue[x]);
                }
            });
    }
}

/// Step 1 for row `y`: each pixel demodulated (`GuidePixel::demodulate`, from the guide
/// planes), with its luminance in w (the neighbourhood's sums of c and c^2 then give the
/// colour and luminance moments in four lanes at once).
fn demodulate_row(radiance: &Film, guides: &Guides, y: usize, current: &mut [Vec4]) {
    let width = guides.width as usize;
    let start = y * width;
    let radiance = &radiance.pixels[start..start + width];
    let instances = &guides.instances()[start..start + width];
    let row = |plane| guides.row(y, plane);
    let (albedo_r, albedo_g, albedo_b) = (row(ALBEDO_R), row(ALBEDO_G), row(ALBEDO_B));
    let (unfiltered_r, unfiltered_g, unfiltered_b) =
        (row(UNFILTERED_R), row(UNFILTERED_G), row(UNFILTERED_B));
    for x in 0..width {
        let albedo = Vec3::new(albedo_r[x], albedo_g[x], albedo_b[x]);
        let unfiltered = Vec3::new(unfiltered_r[x], unfiltered_g[x], unfiltered_b[x]);
        let illumination = if instances[x] == NO_INSTANCE {
            Vec3::ZERO
        } else {
            (radiance[x] - unfiltered).max(Vec3::ZERO) / albedo.max(Vec3::splat(ALBEDO_FLOOR))
        };
        current[x] = illumination.extend(luminance(illumination));
    }
}

/// Steps 4 and 5 for a pixel (demodulated illumination `current`, luminance in w, amid
/// `around`), given its history `before` (None: disoccluded): the new history and the
/// variance the spatial filter reads.
fn blend(
    current: Vec4,
    around: &Neighbourhood,
    before: Option<History>,
    settings: &TemporalSettings,
) -> (History, f32) {
    let (c, lum) = (current.truncate(), current.w);
    let Neighbourhood {
        mean,
        sigma,
        luminance_variance: spatial_variance,
    } = *around;
    let fresh = Vec2::new(lum, lum * lum);
    let Some(before) = before else {
        let history = History {
            illumination: c,
            moments: fresh,
            length: 1.0,
        };
        return (history, spatial_variance);
    };
    let length = before.length + 1.0;
    let alpha = (1.0 / length).max(settings.alpha_min);
    let moments_alpha = (1.0 / length).max(settings.moments_alpha_min);
    let band = if settings.clamp_sigma.is_finite() {
        sigma * settings.clamp_sigma
    } else {
        Vec3::INFINITY
    };
    let clamped = before
        .illumination
        .clamp((mean - band).max(Vec3::ZERO), mean + band);
    let moments = before.moments.lerp(fresh, moments_alpha);
    let variance = if length < SHORT_HISTORY {
        spatial_variance
    } else {
        (moments.y - moments.x * moments.x).max(0.0)
    };
    let history = History {
        illumination: clamped.lerp(c, alpha),
        moments,
        length,
    };
    (history, variance)
}

/// The 3 x 3 neighbourhood's illumination over pixels that are not sky.
#[derive(Clone, Copy)]
struct Neighbourhood {
    mean: Vec3,
    /// Standard deviation per channel.
    sigma: Vec3,
    luminance_variance: f32,
}

/// The 3 x 3 neighbourhood sums of a band of rows, taken separably: each row's sums of
/// three across, then three of those down (6 additions a pixel instead of 9 taps: 13%
/// fewer instructions in the temporal pass, counted by callgrind at 480 x 270).
struct NeighbourhoodRows {
    width: usize,
    /// The first row summed (the band's first row, less one where there is one).
    first: u32,
    /// Per summed row, per pixel: the sum of c and of c^2 (colour and luminance in four
    /// lanes) over the pixel and its left and right neighbours that are not sky, ...
    sum: Vec<Vec4>,
    squares: Vec<Vec4>,
    /// ... and how many of them there are.
    count: Vec<f32>,
    /// The summed rows demodulated (`demodulate_row`).
    current: Vec<Vec4>,
    /// The band's last row summed.
    last: u32,
}

impl NeighbourhoodRows {
    fn new(width: usize) -> NeighbourhoodRows {
        NeighbourhoodRows {
            width,
            first: 0,
            last: 0,
            sum: Vec::new(),
            squares: Vec::new(),
            count: Vec::new(),
            current: Vec::new(),
        }
    }

    /// Demodulates rows `first_row..=last_row` and the rows either side, and takes their
    /// row sums.
    fn sum_band(&mut self, radiance: &Film, guides: &Guides, first_row: u32, last_row: u32) {
        let (width, height) = (guides.width as usize, guides.height);
        self.first = first_row.saturating_sub(1);
        self.last = (last_row + 1).min(height - 1);
        let rows = (self.last - self.first + 1) as usize;
        self.sum.resize(rows * width, Vec4::ZERO);
        self.squares.resize(rows * width, Vec4::ZERO);
        self.count.resize(rows * width, 0.0);
        self.current.resize(rows * width, Vec4::ZERO);
        for row in 0..rows {
            let y = self.first as usize + row;
            let current = &mut self.current[row * width..][..width];
            demodulate_row(radiance, guides, y, current);
            let instances = &guides.instances()[y * width..(y + 1) * width];
            let (sum, squares, count) = (
                &mut self.sum[row * width..][..width],
                &mut self.squares[row * width..][..width],
                &mut self.count[row * width..][..width],
            );
            // A sky pixel's demodulated value is zero, so only its count needs masking.
            let seen = |x: usize| {
                if instances[x] == NO_INSTANCE {
                    0.0
                } else {
                    1.0
                }
            };
            for x in 0..width {
                let (mut s, mut q, mut n) = (current[x], current[x] * current[x], seen(x));
                if x > 0 {
                    s += current[x - 1];
                    q += current[x - 1] * current[x - 1];
                    n += seen(x - 1);
                }
                if x + 1 < width {
                    s += current[x + 1];
                    q += current[x + 1] * current[x + 1];
                    n += seen(x + 1);
                }
                sum[x] = s;
                squares[x] = q;
                count[x] = n;
            }
        }
        self.width = width;
    }

    /// Pixel (x, y)'s demodulated illumination and luminance (y within the band).
    fn current(&self, x: u32, y: u32) -> Vec4 {
        self.current[(y - self.first) as usize * self.width + x as usize]
    }

    /// Pixel (x, y)'s `Neighbourhood`, over its 3 x 3 pixels that are not sky (y within
    /// the band last summed).
    fn neighbourhood(&self, x: u32, y: u32) -> Neighbourhood {
        let (mut sum, mut sum_squares, mut count) = (Vec4::ZERO, Vec4::ZERO, 0.0f32);
        for row in y.saturating_sub(1).max(self.first)..=(y + 1).min(self.last) {
            let index = (row - self.first) as usize * self.width + x as usize;
            sum += self.sum[index];
            sum_squares += self.squares[index];
            count += self.count[index];
        }
        let mean = sum / count;
        let spread = (sum_squares / count - mean * mean).max(Vec4::ZERO);
        let sigma = Vec3::new(spread.x.sqrt(), spread.y.sqrt(), spread.z.sqrt());
        Neighbourhood {
            mean: mean.truncate(),
            sigma,
            luminance_variance: spread.w,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::GuidePixel;
    use crate::scene::world::CameraPlacement;
    use glam::{Mat4, Vec3A};

    /// `guides` with `edit` applied to every pixel.
    fn edited(guides: &Guides, edit: impl Fn(&mut GuidePixel)) -> Guides {
        let pixels: Vec<GuidePixel> = (0..(guides.width * guides.height) as usize)
            .map(|index| {
                let mut pixel = guides.pixel(index);
                edit(&mut pixel);
                pixel
            })
            .collect();
        Guides::from_pixels(guides.width, guides.height, &pixels)
    }

    fn camera(x: f32) -> Camera {
        let placement = CameraPlacement {
            name: String::new(),
            yfov: 60f32.to_radians(),
            znear: 0.1,
            world_from_camera: Mat4::from_translation(glam::Vec3::new(x, 0.0, 0.0)),
        };
        Camera::new(&placement, 32, 16)
    }

    /// A wall at z = -5 facing the camera: instance 0, albedo 0.5.
    fn wall(camera: &Camera) -> Guides {
        let mut guides = Guides::new(32, 16);
        for y in 0..16 {
            for x in 0..32 {
                let ray = camera.ray(Vec2::new(x as f32 + 0.5, y as f32 + 0.5), Vec2::ZERO);
                let t = 5.0 / -ray.direction.z;
                let pixel = GuidePixel {
                    position: ray.origin + ray.direction * t,
                    normal: Vec3A::Z,
                    depth: t,
                    instance: 0,
                    albedo: Vec3::splat(0.5),
                    unfiltered: Vec3::ZERO,
                };
                guides.set((y * 32 + x) as usize, &pixel);
            }
        }
        guides
    }

    fn film(value: impl Fn(u32, u32) -> Vec3) -> Film {
        let mut film = Film::new(32, 16);
        for y in 0..16 {
            for x in 0..32 {
                film.pixels[(y * 32 + x) as usize] = value(x, y);
            }
        }
        film
    }

    #[test]
    fn a_still_view_averages_frames_and_grows_its_history() {
        let mut filter = TemporalFilter::new(TemporalSettings {
            clamp_sigma: f32::INFINITY,
            alpha_min: 0.1,
            ..TemporalSettings::default()
        });
        let camera = camera(0.0);
        let guides = wall(&camera);
        let identity = [Affine3A::IDENTITY];
        // Alternate 0.2 and 0.6 radiance: illumination 0.4 and 1.2, mean 0.8.
        let mut last = Accumulated::default();
        for frame in 0..10 {
            let value = if frame % 2 == 0 { 0.2 } else { 0.6 };
            last = filter
                .accumulate(
                    &film(|_, _| Vec3::splat(value)),
                    &guides,
                    &camera,
                    &identity,
                )
                .clone();
        }
        assert_eq!(filter.history_length(5 * 32 + 7), 10.0);
        // With weights 1/n (n <= 10 = 1/alpha_min) the average is the plain mean.
        assert!((last.signal.illumination(5 * 32 + 7).x - 0.8).abs() < 1e-5);
    }

    #[test]
    fn a_moving_camera_reads_history_where_the_surface_was() {
        let mut filter = TemporalFilter::new(TemporalSettings {
            clamp_sigma: f32::INFINITY,
            ..TemporalSettings::default()
        });
        let identity = [Affine3A::IDENTITY];
        // A pattern fixed on the wall: bright where world x > 0.
        let pattern = |camera: &Camera, guides: &Guides| {
            film(|x, y| {
                let p = guides.pixel((y * camera.width + x) as usize).position;
                Vec3::splat(if p.x > 0.0 { 0.5 } else { 0.05 })
            })
        };
        let first = camera(0.0);
        let guides = wall(&first);
        filter.accumulate(&pattern(&first, &guides), &guides, &first, &identity);
        // Move right by 1 m (2.8 pixels' worth of wall), and show black: where history
        // is found, the average is half the old pattern.
        let second = camera(1.0);
        let guides = wall(&second);
        let out = filter
            .accumulate(&film(|_, _| Vec3::ZERO), &guides, &second, &identity)
            .clone();
        for y in 2..14 {
            for x in 2..28 {
                let index = (y * 32 + x) as usize;
                let p = guides.pixel(index).position;
                if (p.x.abs()) < 0.5 {
                    continue; // the edge, blended by the bilinear taps
                }
                let expected = if p.x > 0.0 { 0.5 } else { 0.05 };
                assert!(
                    (out.signal.illumination(index).x - expected).abs() < 1e-3,
                    "({x}, {y}) at world x {}: {}",
                    p.x,
                    out.signal.illumination(index).x
                );
                assert_eq!(filter.history_length(index), 2.0);
            }
        }
        // The rightmost column came into view: no history.
        assert_eq!(filter.history_length(5 * 32 + 31), 1.0);
    }

    #[test]
    fn a_different_surface_is_a_disocclusion() {
        let mut filter = TemporalFilter::default();
        let camera = camera(0.0);
        let guides = wall(&camera);
        let identity = [Affine3A::IDENTITY, Affine3A::IDENTITY];
        filter.accumulate(&film(|_, _| Vec3::ONE), &guides, &camera, &identity);
        // Same place, but now another instance, then the same instance much nearer.
        let other = edited(&guides, |g| g.instance = 1);
        filter.accumulate(&film(|_, _| Vec3::ONE), &other, &camera, &identity);
        assert!((0..32 * 16).all(|index| filter.history_length(index) == 1.0));
        let nearer = edited(&other, |g| {
            g.depth *= 0.5;
            g.position = camera.position + (g.position - camera.position) * 0.5;
        });
        filter.accumulate(&film(|_, _| Vec3::ONE), &nearer, &camera, &identity);
        assert!((0..32 * 16).all(|index| filter.history_length(index) == 1.0));
        // Sky pixels carry nothing.
        let mut sky = nearer.clone();
        sky.set(
            0,
            &GuidePixel {
                instance: NO_INSTANCE,
                ..nearer.pixel(0)
            },
        );
        let out = filter.accumulate(&film(|_, _| Vec3::ONE), &sky, &camera, &identity);
        assert_eq!(out.signal.illumination(0), Vec3::ZERO);
    }

    #[test]
    fn a_moving_instance_carries_its_history_with_it() {
        let mut filter = TemporalFilter::new(TemporalSettings {
            clamp_sigma: f32::INFINITY,
            ..TemporalSettings::default()
        });
        let camera = camera(0.0);
        let guides = wall(&camera);
        // Frame 1: the wall at rest shows a ramp.
        let ramp = |guides: &Guides, shift: f32| {
            film(|x, y| {
                let p = guides.pixel((y * 32 + x) as usize).position;
                Vec3::splat(((p.x - shift) * 0.1 + 0.5).clamp(0.0, 1.0) * 0.5)
            })
        };
        filter.accumulate(&ramp(&guides, 0.0), &guides, &camera, &[Affine3A::IDENTITY]);
        // Frame 2: the wall (instance 0) moved 0.3 m right, its ramp with it.
        let moved = Affine3A::from_translation(glam::Vec3::new(0.3, 0.0, 0.0));
        let out = filter
            .accumulate(&ramp(&guides, 0.3), &guides, &camera, &[moved])
            .clone();
        // History came from the same point of the wall: the blend equals the ramp.
        let current = ramp(&guides, 0.3);
        for y in 2..14 {
            for x in 4..28 {
                let index = (y * 32 + x) as usize;
                assert_eq!(filter.history_length(index), 2.0);
                let expected = guides.pixel(index).demodulate(current.pixels[index]).x;
                assert!((out.signal.illumination(index).x - expected).abs() < 2e-3);
            }
        }
    }

    #[test]
    fn renumbered_instances_keep_their_history_and_gone_ones_lose_it() {
        let mut filter = TemporalFilter::new(TemporalSettings::default());
        let camera = camera(0.0);
        let guides = wall(&camera);
        let lit = film(|_, _| Vec3::splat(0.3));
        for _ in 0..3 {
            filter.accumulate(&lit, &guides, &camera, &[Affine3A::IDENTITY]);
        }
        // Something spawned before the wall: the wall is instance 1 now.
        filter.renumber_instances(&[Some(1)]);
        let mut renumbered = guides.clone();
        for index in 0..32 * 16 {
            let pixel = GuidePixel {
                instance: 1,
                ..renumbered.pixel(index)
            };
            renumbered.set(index, &pixel);
        }
        let moved_in = [
            Affine3A::from_translation(glam::Vec3::X),
            Affine3A::IDENTITY,
        ];
        filter.accumulate(&lit, &renumbered, &camera, &moved_in);
        assert_eq!(
            filter.history_length(5 * 32 + 7),
            4.0,
            "the wall's history went on"
        );
        // The wall despawned (and the same pixels show a new instance 0): history restarts.
        filter.renumber_instances(&[Some(0), None]);
        filter.accumulate(&lit, &guides, &camera, &[Affine3A::IDENTITY]);
        assert_eq!(filter.history_length(5 * 32 + 7), 1.0);
    }
}
