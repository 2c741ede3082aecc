//! Frame step `film`: what becomes of each rendered frame before it is shown. Every film
//! step lives here:
//! - `Accumulation`: still views add frames up into a converging image (a running sum of
//!   per-frame means), restarted by any change;
//! - the real-time chain (`denoise::FrameFilter`, used by the window and `bench`):
//!   `temporal` reprojection (`reproject` carries last frame's pixels through each
//!   instance's and the camera's motion), then the `atrous` wavelet filter, then
//!   remodulation by the surface's albedo, then (rendering below the shown resolution)
//!   `upscale`'s temporal upscaling to it;
//! - between the real-time frames, their radiance cache (render/cache.rs): the render reads
//!   it, and it learns the frame's samples on a pool thread while the next frame's
//!   simulation runs (`BackgroundCache`).
//!
//! The film never calls the renderer: it orders each frame (`Accumulation::order_frame`:
//! the view, the sample index, plain or for the filters), the frame driver has it
//! rendered, and the film develops the output (`Accumulation::develop`).
//!
//! The image itself (`render::HdrImage`), its tone mapper and its file writers and readers
//! are in `render::hdr`: render writes that buffer and everything downstream reads it.
//! Knows nothing of the ECS or windows.

pub mod atrous;
mod chain;
pub mod denoise;
mod reproject;
pub mod temporal;
pub mod upscale;

use std::sync::mpsc;

use glam::Vec3;

pub use denoise::{FilmPhaseTimes, FilterMode, FrameFilter};
pub use upscale::{UpscaleSettings, Upscaler, render_scale_for, render_size_for, scaled_size};

use crate::profile::{Stage, StageTimes, since};
use crate::render::cache::CacheSample;
use crate::render::scene::SceneChanges;
use crate::render::{Camera, HdrImage, RadianceCache, RenderOutput, RenderScene, RenderSettings};

/// The film: frames accumulated since the last change, as a running sum of per-frame
/// means, or (filter on) the last filtered frame.
pub struct Accumulation {
    pub settings: RenderSettings,
    sum: Vec<Vec3>,
    pub frames: u32,
    /// Frames rendered through the filter since the film began: their sample sequence's
    /// index. The filter's history carries on across changes, so its frames must go on
    /// drawing new samples (and new sub-pixel jitters, which the upscaler rebuilds the
    /// shown resolution from) where a restarted sum begins its sequence again.
    filtered_frames: u32,
    /// The real-time filter chain (`FilterMode::Off` unless the shell turns it on).
    pub filter: FrameFilter,
    /// The last frame through the filter.
    filtered: Option<HdrImage>,
    /// The last filtered frame's render, whose buffers the next one reuses.
    rendered: Option<RenderOutput>,
    /// The filtered frames' radiance cache (made with the first of them: render/cache.rs).
    cache: BackgroundCache,
    /// The resolution shown: the filtered frames are upscaled to it when the render's is
    /// lower (still frames summed without the filter are shown at the render's).
    pub shown: (u32, u32),
    pub upscaler: Upscaler,
    /// The last filtered frame at the render's resolution, before upscaling.
    filtered_render: HdrImage,
    /// Set when anything visible changed: the next frame starts a new sum.
    pub reset: bool,
    /// The view the sum was rendered from.
    view: Option<glam::Mat4>,
}

impl Accumulation {
    pub fn new(settings: RenderSettings) -> Accumulation {
        let pixels = (settings.width * settings.height) as usize;
        Accumulation {
            shown: (settings.width, settings.height),
            upscaler: Upscaler::new(UpscaleSettings::default()),
            filtered_render: HdrImage::new(0, 0),
            settings,
            sum: vec![Vec3::ZERO; pixels],
            frames: 0,
            filtered_frames: 0,
            filter: FrameFilter::new(FilterMode::Off),
            filtered: None,
            rendered: None,
            cache: BackgroundCache::default(),
            reset: true,
            view: None,
        }
    }

    /// Renders at `width` x `height` from the next frame on, starting the image and the
    /// filter's history again (the upscaler's, at the shown resolution, goes on).
    pub fn set_resolution(&mut self, width: u32, height: u32) {
        let (width, height) = (width.max(1), height.max(1));
        if (width, height) == (self.settings.width, self.settings.height) {
            return;
        }
        self.settings.width = width;
        self.settings.height = height;
        self.sum = vec![Vec3::ZERO; (width * height) as usize];
        self.frames = 0;
        self.reset = true;
        self.filter.reset();
        self.filtered = None;
        self.rendered = None;
    }

    /// Takes note of what extract changed: anything visible restarts the sum; instances
    /// numbered anew are renumbered in the filter's history, which names them by index; a
    /// new light set makes the radiance cache learn the lights afresh.
    pub fn scene_changed(&mut self, changes: &SceneChanges) {
        if changes.visible {
            self.reset = true;
        }
        if changes.relit
            && let Some(cache) = self.cache.settled()
        {
            cache.relit();
        }
        if let Some(new_index) = &changes.renumbered {
            self.filter.renumber_instances(new_index);
            self.upscaler.renumber_instances(new_index);
        }
    }

    /// The image to show: the filtered frame with the filter on (borrowed), else the mean
    /// of the accumulated frames.
    pub fn image(&self) -> std::borrow::Cow<'_, HdrImage> {
        if self.filter.mode != FilterMode::Off
            && let Some(filtered) = &self.filtered
        {
            // Borrowed: a 1280 x 720 copy was 1.3 ms of every presented frame.
            return std::borrow::Cow::Borrowed(filtered);
        }
        let scale = 1.0 / self.frames.max(1) as f32;
        std::borrow::Cow::Owned(HdrImage {
            width: self.settings.width,
            height: self.settings.height,
            pixels: self.sum.iter().map(|p| *p * scale).collect(),
        })
    }

    /// The index of the sample sequence the next frame draws from: through the filter,
    /// every frame's is new (a moving view or warden resets the sum every frame, and
    /// frames drawing the same samples would leave the same noise and the same jitter
    /// for the filter and the upscaler to average); summing still frames, the sum's own
    /// count, so N frames are the sequence's first N samples.
    pub fn sample_frame(&self) -> u32 {
        if self.filter.mode != FilterMode::Off {
            self.filtered_frames
        } else {
            self.frames
        }
    }

    /// The filtered frames' radiance cache, while the filter is on (once it has learnt the
    /// last frame).
    pub fn radiance_cache(&mut self) -> Option<&RadianceCache> {
        self.cache.settled().map(|cache| &*cache)
    }

    /// Waits until the radiance cache has learnt the last frame (it learns in the
    /// background: `BackgroundCache`), so that nothing else timed shares the pool with it.
    pub fn finish_learning(&mut self) {
        self.cache.settled();
    }

    /// What the next frame renders, which the film decides (it knows the sum and the
    /// filter's history): the view, the settings with the frame's sample index, and how
    /// to render. A new view, or a change extract reported, starts the sum again.
    pub fn order_frame(&mut self, scene: &RenderScene, times: &mut StageTimes) -> FrameOrder {
        let view = scene.camera.world_from_camera;
        if self.view != Some(view) {
            self.view = Some(view);
            self.reset = true;
        }
        if self.reset {
            self.sum.iter_mut().for_each(|p| *p = Vec3::ZERO);
            self.frames = 0;
            self.reset = false;
        }
        let mut settings = self.settings.clone();
        settings.frame = self.sample_frame();
        let camera = Camera::new(&scene.camera, settings.width, settings.height);
        let kind = if self.filter.mode != FilterMode::Off {
            times.cache_learn_ms = self.cache.learnt_ms();
            FrameKind::Filtered {
                earlier: self.rendered.take(),
            }
        } else {
            // What the cache learnt goes stale while the filter is off (the editor's
            // converging view, where lamps and walls move): it starts afresh.
            self.cache = BackgroundCache::default();
            FrameKind::Summed
        };
        FrameOrder {
            camera,
            settings,
            kind,
        }
    }

    /// The radiance cache a filtered frame's render reads (made with the first of them).
    pub fn cache_for_render(&mut self) -> &RadianceCache {
        self.cache.settled_or_new()
    }

    /// The film step: the render's `output` of `order` goes into the running sum, or
    /// through the filter (and the upscaler, rendering below the shown resolution) into
    /// the image to show; the stage's time and its steps' go into `times`.
    pub fn develop(
        &mut self,
        order: &FrameOrder,
        mut output: RenderOutput,
        scene: &RenderScene,
        times: &mut StageTimes,
    ) {
        let start = std::time::Instant::now();
        profiling::scope!("film");
        let (camera, settings) = (&order.camera, &order.settings);
        if let Some(guides) = &output.guides {
            let instances: Vec<glam::Affine3A> = scene
                .accel
                .instances()
                .iter()
                .map(|instance| instance.world_from_object())
                .collect();
            // Last frame's image is overwritten (a fresh buffer a frame costs page faults).
            let mut image = self.filtered.take().unwrap_or_else(|| HdrImage::new(0, 0));
            let upscaling = self.shown != (settings.width, settings.height);
            self.filter.render_scale = if upscaling {
                (settings.width as f32 / self.shown.0.max(1) as f32)
                    .max(settings.height as f32 / self.shown.1.max(1) as f32)
            } else {
                1.0
            };
            let upscale_ms = if !upscaling {
                self.filter
                    .apply_into(&output.image, guides, camera, &instances, &mut image);
                0.0
            } else {
                let filtered = &mut self.filtered_render;
                self.filter
                    .apply_into(&output.image, guides, camera, &instances, filtered);
                let start = std::time::Instant::now();
                profiling::scope!("film.upscale");
                self.upscaler
                    .apply_into(filtered, guides, camera, &instances, self.shown, &mut image);
                since(start)
            };
            self.filtered = Some(image);
            self.cache.learn(std::mem::take(&mut output.cache_samples));
            self.rendered = Some(output);
            self.frames += 1;
            self.filtered_frames = self.filtered_frames.wrapping_add(1);
            let film_ms = since(start);
            times.add(Stage::Film, film_ms);
            // The steps' own times, with the little around them (the instances' transforms
            // gathered) shared out so they add up to the stage.
            let steps = FilmPhaseTimes {
                upscale: upscale_ms,
                ..self.filter.last_times
            }
            .as_array();
            let timed: f64 = steps.iter().sum();
            times.film_phases = if timed > 0.0 {
                steps.map(|step| film_ms * step / timed)
            } else {
                [0.0; FilmPhaseTimes::NAMES.len()]
            };
            return;
        }
        for (sum, pixel) in self.sum.iter_mut().zip(&output.image.pixels) {
            *sum += *pixel;
        }
        self.frames += 1;
        times.add(Stage::Film, since(start));
        times.film_phases = [0.0; FilmPhaseTimes::NAMES.len()];
    }
}

/// The frame the film asks the render for (`Accumulation::order_frame`).
pub struct FrameOrder {
    /// The view, at the render's resolution.
    pub camera: Camera,
    /// The render settings, with the frame's sample index.
    pub settings: RenderSettings,
    pub kind: FrameKind,
}

/// How a frame is rendered for the film.
pub enum FrameKind {
    /// A plain frame, added to the running sum of a still view.
    Summed,
    /// A frame for the real-time filters: with the guides they read and the radiance
    /// cache, reusing the buffers of the `earlier` frame's render when there is one.
    Filtered { earlier: Option<RenderOutput> },
}

/// The radiance cache between frames: at hand, or away on a pool thread folding in the
/// last frame's samples while the frame goes on (its film step's end, the next frame's
/// simulation). Learnt at the render's end, on one core while the other waited, it took
/// 0.2 ms of a 9.3 ms render (first-light, 640 x 360 at half scale, two threads). Now the
/// next render waits a median 0.5 us for it; in 4 to 6% of frames the learning has not
/// finished by then (its thread not yet woken) and the render waits out the rest, 0.2 to
/// 1.2 ms (first-light and the-keep, 270 frames each).
#[derive(Default)]
struct BackgroundCache {
    ready: Option<RadianceCache>,
    /// The cache coming back, with the milliseconds `learn` took.
    learning: Option<mpsc::Receiver<(RadianceCache, f64)>>,
    /// What the last learning to come back took, in ms (0 before any).
    learnt_ms: f64,
}

impl BackgroundCache {
    /// The cache once it has learnt what it was given: waits for that, running the pool's
    /// other jobs meanwhile when called on one of its threads (the one the learning may
    /// be queued on: `gloam bench` runs its frames inside its pool).
    fn settled(&mut self) -> Option<&mut RadianceCache> {
        if let Some(learning) = self.learning.take() {
            let settled = loop {
                match learning.try_recv() {
                    Ok(learnt) => break Some(learnt),
                    // The learning panicked (a bug; rayon aborts first by default): the
                    // next filtered frame starts a new cache.
                    Err(mpsc::TryRecvError::Disconnected) => break None,
                    Err(mpsc::TryRecvError::Empty) => match rayon::yield_now() {
                        Some(rayon::Yield::Executed) => {}
                        Some(rayon::Yield::Idle) => std::thread::yield_now(),
                        None => break learning.recv().ok(),
                    },
                }
            };
            self.learnt_ms = settled.as_ref().map_or(0.0, |&(_, ms)| ms);
            self.ready = settled.map(|(cache, _)| cache);
        }
        self.ready.as_mut()
    }

    /// How long the last learning took, in ms, once it is done (0 before any).
    fn learnt_ms(&mut self) -> f64 {
        self.settled();
        self.learnt_ms
    }

    fn settled_or_new(&mut self) -> &RadianceCache {
        self.settled();
        self.ready.get_or_insert_with(RadianceCache::new)
    }

    /// Folds `samples` in (`RadianceCache::learn`) on the current rayon pool, in the
    /// background: `settled` waits for it.
    fn learn(&mut self, samples: Vec<CacheSample>) {
        self.settled();
        let Some(mut cache) = self.ready.take() else {
            return;
        };
        let (sender, receiver) = mpsc::sync_channel(1);
        rayon::spawn(move || {
            profiling::scope!("film.cache_learn");
            let start = std::time::Instant::now();
            cache.learn(&samples);
            // The receiver is gone only if the film dropped its cache meanwhile.
            let _ = sender.send((cache, since(start)));
        });
        self.learning = Some(receiver);
    }
}
