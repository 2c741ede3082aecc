//! Frame step `film`: the real-time filter chain that makes one sample per pixel per frame
//! look like many. Per frame:
//! 1. `temporal`: demodulate, reproject last frame's history through each instance's motion
//!    and the camera's, validate it, clamp it, blend;
//! 2. `atrous`: edge-avoiding wavelet passes over the accumulated illumination, steered by
//!    its variance (SVGF);
//! 3. remodulate: illumination x albedo + the light left unfiltered (the hit's emission,
//!    its dominant lamp's direct light: `GuidePixel::unfiltered`), `Guides::modulate_row`.
//!    With the a-trous passes it runs in the last pass, a row at a time as the pass writes
//!    it, and the first pass's rows go back into the history (SVGF's feedback) as it
//!    writes them.
//!
//! Every step reads and writes images as rows of planes (`planes`, `Guides`), so each reads
//! only the channels it needs and one step's output is the next one's input as it stands.
//! Under the full chain, steps 1 to 3 run as one chain of bands of rows (film/chain.rs): a
//! band of the a-trous prepass starts as soon as the temporal bands it reads are done,
//! and so on down the passes, rather than every thread waiting at the end of each step.
//!
//! Reads a frame rendered with `render_guided`; knows nothing of the ECS.

use std::time::Instant;

use glam::{Affine3A, Vec3};
use rayon::prelude::*;

use super::atrous::{self, AtrousSettings, Input};
use super::temporal::{TemporalFilter, TemporalSettings, feed_back_row};
use crate::render::camera::Camera;
use crate::render::guides::Guides;
use crate::render::hdr::HdrImage;
use crate::render::planes::{BLUE, GREEN, RED, SharedRuns, SignalPlanes};

/// Which filters run (the command line's `--filter`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum FilterMode {
    /// The raw frame (still views accumulate progressively instead).
    #[default]
    #[value(name = "raw")]
    Off,
    /// Temporal reprojection only.
    Temporal,
    /// Temporal reprojection, then the a-trous spatial filter (SVGF).
    Full,
}

impl FilterMode {
    pub fn name(self) -> &'static str {
        match self {
            FilterMode::Off => "raw",
            FilterMode::Temporal => "temporal",
            FilterMode::Full => "temporal+spatial",
        }
    }

    /// The next mode in the window's cycle (F4).
    pub fn next(self) -> FilterMode {
        match self {
            FilterMode::Full => FilterMode::Temporal,
            FilterMode::Temporal => FilterMode::Off,
            FilterMode::Off => FilterMode::Full,
        }
    }
}

/// Wall-clock milliseconds of each step of the last `FrameFilter::apply`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FilmPhaseTimes {
    /// Step 1: demodulation, reprojection, validation, clamping, blending.
    pub temporal: f64,
    /// Step 2: the a-trous passes (with the depth slopes and prefiltered variance they
    /// read), and with them step 3 and the feedback, done in their rows. Under the full
    /// chain steps 1 and 2 run as one chain of bands, and their wall time is shared out
    /// between the two as their bands' CPU time was.
    pub spatial: f64,
    /// Step 3 on its own: remodulation where no a-trous pass runs (0 where one does).
    pub remodulate: f64,
    /// After the chain, rendering below the shown resolution: `upscale` (set by
    /// `Accumulation`, which runs it).
    pub upscale: f64,
}

impl FilmPhaseTimes {
    /// The steps' names, in `as_array` order (the profiler's `film.*` rows).
    pub const NAMES: [&str; 4] = ["temporal", "spatial", "remodulate", "upscale"];

    pub fn as_array(&self) -> [f64; 4] {
        [self.temporal, self.spatial, self.remodulate, self.upscale]
    }
}

/// The filter chain and its state across frames.
pub struct FrameFilter {
    pub mode: FilterMode,
    pub temporal: TemporalFilter,
    pub atrous: AtrousSettings,
    /// Keep the first a-trous pass as history (SVGF); off keeps the plain temporal average.
    pub feed_back: bool,
    /// The render's resolution per axis against the one shown (below 1 the upscaler
    /// follows): the a-trous passes are `AtrousSettings::iterations_at_scale` of it.
    pub render_scale: f32,
    /// The spatial filter's buffers, kept between frames.
    atrous_workspace: atrous::Workspace,
    /// How long each step of the last `apply` took.
    pub last_times: FilmPhaseTimes,
}

impl FrameFilter {
    pub fn new(mode: FilterMode) -> FrameFilter {
        FrameFilter {
            mode,
            temporal: TemporalFilter::new(TemporalSettings::default()),
            atrous: AtrousSettings::default(),
            feed_back: true,
            render_scale: 1.0,
            atrous_workspace: atrous::Workspace::default(),
            last_times: FilmPhaseTimes::default(),
        }
    }

    /// Forgets the history (new level, new resolution).
    pub fn reset(&mut self) {
        self.temporal.reset();
    }

    /// The scene's instances were numbered anew (`TemporalFilter::renumber_instances`).
    pub fn renumber_instances(&mut self, new_index: &[Option<u32>]) {
        self.temporal.renumber_instances(new_index);
    }

    /// Filters this frame's `radiance` (rendered with `guides` from `camera`, the scene's
    /// instances at `instances`): the image to show.
    pub fn apply(
        &mut self,
        radiance: &HdrImage,
        guides: &Guides,
        camera: &Camera,
        instances: &[Affine3A],
    ) -> HdrImage {
        let mut image = HdrImage {
            width: radiance.width,
            height: radiance.height,
            pixels: Vec::new(),
        };
        self.apply_into(radiance, guides, camera, instances, &mut image);
        image
    }

    /// `apply`, into `image` (its buffer reused: the game keeps last frame's).
    pub fn apply_into(
        &mut self,
        radiance: &HdrImage,
        guides: &Guides,
        camera: &Camera,
        instances: &[Affine3A],
        image: &mut HdrImage,
    ) {
        let FrameFilter {
            mode,
            temporal,
            atrous: settings,
            feed_back,
            render_scale,
            atrous_workspace,
            last_times,
        } = self;
        *last_times = FilmPhaseTimes::default();
        if *mode == FilterMode::Off {
            image.clone_from(radiance);
            return;
        }
        let milliseconds_since = |start: Instant| start.elapsed().as_secs_f64() * 1e3;
        image.width = guides.width;
        image.height = guides.height;
        image
            .pixels
            .resize((guides.width * guides.height) as usize, Vec3::ZERO);
        let settings = &AtrousSettings {
            iterations: settings.iterations_at_scale(*render_scale),
            ..settings.clone()
        };
        if *mode == FilterMode::Full && settings.iterations > 0 {
            // 1, 2 and 3 as one chain of bands (film/chain.rs): the temporal filter's bands,
            // the a-trous prepass and passes, each band starting once the bands it reads
            // are done. The first pass's rows go back into the history and the last pass's
            // are remodulated as each is written, while they are in the cache. (A pass of
            // their own over first-light's 320 x 180 frame took 0.169 ms on two threads;
            // done in the a-trous rows they add 0.142.)
            let start = Instant::now();
            profiling::scope!("film.temporal+spatial");
            let width = guides.width as usize;
            let image = SharedRuns::new(&mut image.pixels);
            let (temporal_seconds, spatial_seconds) =
                temporal.accumulate_then(radiance, guides, camera, instances, |bands| {
                    let history = feed_back.then(|| bands.history());
                    // SAFETY: the chain runs each band once, and reads its rows only once
                    // it has run, while no band writes them.
                    let (signal, band) =
                        (unsafe { bands.signal() }, |band| unsafe { bands.run(band) });
                    let input = Input::Banded {
                        rows: signal,
                        band: &band,
                    };
                    let filtered =
                        atrous::filter_with(atrous_workspace, input, guides, settings, |row| {
                            if let (0, Some(history)) = (row.iteration, &history) {
                                // SAFETY: each pass hands over each row once, after the
                                // temporal band that wrote it.
                                unsafe { feed_back_row(row.illumination, row.y, history) };
                            }
                            if row.last {
                                // SAFETY: as above; only the last pass writes the image.
                                let pixels = unsafe { image.run(row.y * width, width) };
                                guides.modulate_row(row.y, row.illumination, pixels);
                            }
                        });
                    (filtered.input_seconds, filtered.filter_seconds)
                });
            // One wall time for both steps, shared out as their bands' CPU time was.
            let both = milliseconds_since(start);
            let busy = temporal_seconds + spatial_seconds;
            last_times.temporal = if busy > 0.0 {
                both * temporal_seconds / busy
            } else {
                both / 2.0
            };
            last_times.spatial = both - last_times.temporal;
        } else {
            // 1. Temporal accumulation.
            let start = Instant::now();
            {
                profiling::scope!("film.temporal");
                temporal.accumulate(radiance, guides, camera, instances);
            }
            last_times.temporal = milliseconds_since(start);
            // 3. Remodulate.
            let start = Instant::now();
            profiling::scope!("film.remodulate");
            remodulate(guides, &temporal.accumulated().signal, image);
            last_times.remodulate = milliseconds_since(start);
        }
    }
}

/// Step 3: `image` = `illumination` x albedo + the unfiltered light, pixel by pixel (sky:
/// its own radiance), a row at a time (`Guides::modulate_row`).
fn remodulate(guides: &Guides, illumination: &SignalPlanes, image: &mut HdrImage) {
    let width = guides.width as usize;
    image
        .pixels
        .par_chunks_mut(width.max(1))
        .enumerate()
        .for_each(|(y, pixels)| {
            let rows = [RED, GREEN, BLUE].map(|plane| illumination.row(y, plane));
            guides.modulate_row(y, rows, pixels);
        });
}
