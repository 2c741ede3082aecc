//! Frame step `film`: the real-time filter chain that makes one sample per pixel per frame
//! look like many. Per frame:
//! 1. `temporal`: demodulate, reproject last frame's history through each instance's motion
//!    and the camera's, validate it, clamp it, blend;
//! 2. `atrous`: edge-avoiding wavelet passes over the accumulated illumination, steered by
//!    its variance (SVGF); the first pass's output goes back into the history;
//! 3. remodulate: illumination x albedo + emission.
//!
//! Reads a frame rendered with `render_guided`; knows nothing of the ECS.

use glam::Affine3A;
use rayon::prelude::*;

use super::atrous::{self, AtrousSettings};
use super::camera::Camera;
use super::film::Film;
use super::guides::Guides;
use super::temporal::{TemporalFilter, TemporalSettings};

/// Which filters run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FilterMode {
    /// The raw frame: still views accumulate progressively instead.
    #[default]
    Off,
    /// Temporal accumulation only.
    Temporal,
    /// Temporal, then spatial (SVGF).
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

/// The filter chain and its state across frames.
#[derive(Default)]
pub struct FrameFilter {
    pub mode: FilterMode,
    pub temporal: TemporalFilter,
    pub atrous: AtrousSettings,
    /// Keep the first a-trous pass as history (SVGF); off keeps the plain temporal average.
    pub feed_back: bool,
    /// The spatial filter's buffers, kept between frames.
    atrous_workspace: atrous::Workspace,
}

impl FrameFilter {
    pub fn new(mode: FilterMode) -> FrameFilter {
        FrameFilter {
            mode,
            temporal: TemporalFilter::new(TemporalSettings::default()),
            atrous: AtrousSettings::default(),
            feed_back: true,
            atrous_workspace: atrous::Workspace::default(),
        }
    }

    /// Forgets the history (new level, new resolution).
    pub fn reset(&mut self) {
        self.temporal.reset();
    }

    /// Filters this frame's `radiance` (rendered with `guides` from `camera`, the scene's
    /// instances at `instances`): the image to show.
    pub fn apply(
        &mut self,
        radiance: &Film,
        guides: &Guides,
        camera: &Camera,
        instances: &[Affine3A],
    ) -> Film {
        if self.mode == FilterMode::Off {
            return radiance.clone();
        }
        let accumulated = {
            profiling::scope!("film.temporal");
            self.temporal
                .accumulate(radiance, guides, camera, instances)
        };
        let mut first_iteration = None;
        let filtered;
        let illumination = if self.mode == FilterMode::Full && self.atrous.iterations > 0 {
            profiling::scope!("film.spatial");
            let output = atrous::filter_with(
                &mut self.atrous_workspace,
                &accumulated.illumination,
                &accumulated.variance,
                guides,
                &self.atrous,
            );
            first_iteration = Some(output.first_iteration);
            filtered = output.illumination;
            &filtered
        } else {
            &accumulated.illumination
        };
        // 3. Remodulate.
        profiling::scope!("film.remodulate");
        let pixels = guides
            .pixels
            .par_iter()
            .zip(illumination.par_iter())
            .map(|(g, i)| g.modulate(*i))
            .collect();
        if let Some(first_iteration) = first_iteration.filter(|_| self.feed_back) {
            self.temporal.feed_back(&first_iteration);
        }
        Film {
            width: radiance.width,
            height: radiance.height,
            pixels,
        }
    }
}
