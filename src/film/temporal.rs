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

use glam::{Affine3A, Vec2, Vec3};
use std::sync::Mutex;

use rayon::prelude::*;

use super::reproject::{
    HistoryRow, LastPixel, LastTransforms, ProjectedRow, RecordLanes, Reprojection, SurfaceRow,
};
use crate::render::camera::Camera;
use crate::render::guides::{
    ALBEDO_B, ALBEDO_FLOOR, ALBEDO_G, ALBEDO_R, Guides, NO_INSTANCE, UNFILTERED_B, UNFILTERED_G,
    UNFILTERED_R,
};
use crate::render::hdr::HdrImage;
use crate::render::planes::{
    BAND_ROWS, BLUE, GREEN, PlaneRows, RED, SIGNAL_PLANES, SharedRuns, SignalPlanes, VARIANCE,
};

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

/// One pixel's history (its fields in this order: `LastPixel` is written as floats).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C)]
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

#[derive(Default)]
pub struct TemporalFilter {
    pub settings: TemporalSettings,
    width: u32,
    height: u32,
    /// Last frame's pixels: their instances (`NO_INSTANCE` for the sky), and for those
    /// that are not sky their history and as much of their first hits as validation reads
    /// (`LastPixel`: the sky's records are stale).
    last_instances: Vec<u32>,
    last: Vec<LastPixel>,
    camera: Option<Camera>,
    /// Last frame's world-from-object per instance.
    instances: LastTransforms,
    /// This frame's result; its buffers, like the others here, are reused frame to frame
    /// (fresh megabyte buffers each frame cost more in page faults than the blending).
    accumulated: Accumulated,
    next_instances: Vec<u32>,
    next: Vec<LastPixel>,
    /// The workers' rows, kept from frame to frame (`WorkspacePool`).
    workspaces: WorkspacePool,
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
        self.last_instances.clear();
        self.camera = None;
        self.instances.clear();
    }

    /// Accumulates this frame (`radiance` with its `guides`, seen by `camera`, with the
    /// instances at `instances`' world-from-object transforms) into the history.
    pub fn accumulate(
        &mut self,
        radiance: &HdrImage,
        guides: &Guides,
        camera: &Camera,
        instance_transforms: &[Affine3A],
    ) -> &Accumulated {
        self.accumulate_then(radiance, guides, camera, instance_transforms, |bands| {
            (0..bands.count()).into_par_iter().for_each(|band| {
                // SAFETY: each band once.
                unsafe { bands.run(band) }
            })
        });
        &self.accumulated
    }

    /// `accumulate` as bands of `BAND_ROWS` rows, which `then` runs, each once, from any
    /// threads (and may read as they are done: `AccumulationBands`); then the history
    /// moves on a frame. The spatial filter chains its passes after them (film/chain.rs).
    pub(super) fn accumulate_then<R>(
        &mut self,
        radiance: &HdrImage,
        guides: &Guides,
        camera: &Camera,
        instance_transforms: &[Affine3A],
        then: impl FnOnce(&AccumulationBands) -> R,
    ) -> R {
        let (width, height) = (radiance.width, radiance.height);
        debug_assert_eq!((guides.width, guides.height), (width, height));
        if (width, height) != (self.width, self.height) {
            self.reset();
            self.width = width;
            self.height = height;
        }
        let count = (width * height) as usize;
        self.next.resize(count, LastPixel::default());
        self.next_instances.resize(count, NO_INSTANCE);
        // 1-5 a band of rows at a time (`Band::accumulate`). (Demodulated in a pass of its
        // own, the image went through memory once more: 2 MB written and read again.)
        let motions = self.instances.motions(instance_transforms);
        let reprojection = self.camera.as_ref().map(|previous_camera| Reprojection {
            projection: previous_camera.projection(),
            last_instances: &self.last_instances,
            last: &self.last,
            width: width as usize,
            height: height as usize,
            motions: &motions,
            settings: &self.settings,
            portable_only: false,
        });
        let accumulated = &mut self.accumulated;
        accumulated.signal.resize(width as usize, height as usize);
        let result = then(&AccumulationBands {
            band: Band {
                radiance,
                guides,
                reprojection: reprojection.as_ref(),
                settings: &self.settings,
                record_lanes: RecordLanes::detect(),
            },
            width: width as usize,
            height: height as usize,
            #[cfg(target_arch = "x86_64")]
            avx2: crate::simd::avx2(),
            workspaces: &self.workspaces,
            next_instances: SharedRuns::new(&mut self.next_instances),
            next: SharedRuns::new(&mut self.next),
            signal: accumulated.signal.shared_runs(),
        });
        std::mem::swap(&mut self.last, &mut self.next);
        std::mem::swap(&mut self.last_instances, &mut self.next_instances);
        self.camera = Some(camera.clone());
        self.instances.record(instance_transforms);
        result
    }

    /// The instances were numbered anew (things spawned or despawned): `new_index[old]` is
    /// each old instance's new index (None: gone). The history follows its surfaces to
    /// their new numbers, so a spawn does not start every pixel's history again; a gone
    /// instance's pixels lose theirs, as a disocclusion would.
    pub fn renumber_instances(&mut self, new_index: &[Option<u32>]) {
        self.instances.renumber(new_index);
        for instance in &mut self.last_instances {
            if *instance != NO_INSTANCE {
                *instance = new_index
                    .get(*instance as usize)
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
        if self.last_instances[index] == NO_INSTANCE {
            return 0.0;
        }
        self.last[index].history.length
    }
}

/// A frame's accumulation as bands of `BAND_ROWS` rows (`TemporalFilter::accumulate_then`),
/// each writing its rows of the signal and of the next frame's history.
pub(super) struct AccumulationBands<'a> {
    band: Band<'a>,
    width: usize,
    height: usize,
    #[cfg(target_arch = "x86_64")]
    avx2: bool,
    workspaces: &'a WorkspacePool,
    next_instances: SharedRuns<'a, u32>,
    next: SharedRuns<'a, LastPixel>,
    signal: SharedRuns<'a, f32>,
}

impl AccumulationBands<'_> {
    /// How many bands.
    pub(super) fn count(&self) -> usize {
        self.height.div_ceil(BAND_ROWS)
    }

    /// Steps 1-5 for band `band`.
    ///
    /// # Safety
    /// No other call for the same band may run at the same time, and no row of it may be
    /// read (`signal`, `history`) while it runs.
    pub(super) unsafe fn run(&self, band: usize) {
        let first_row = band * BAND_ROWS;
        let rows = first_row..(first_row + BAND_ROWS).min(self.height);
        let pixels = rows.start * self.width..rows.end * self.width;
        // SAFETY: the band's own runs, which nothing else holds meanwhile (the caller's
        // promise).
        let (next_instances, next, signal) = unsafe {
            (
                self.next_instances.run(pixels.start, pixels.len()),
                self.next.run(pixels.start, pixels.len()),
                (self.signal).run(pixels.start * SIGNAL_PLANES, pixels.len() * SIGNAL_PLANES),
            )
        };
        let mut workspace = self.workspaces.take(self.width);
        let workspace = &mut workspace.workspace;
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: the CPU has AVX2, the only feature `accumulate_avx2` enables.
            unsafe {
                (self.band).accumulate_avx2(workspace, first_row, (next_instances, next), signal)
            };
            return;
        }
        (self.band).accumulate(workspace, first_row, (next_instances, next), signal);
    }

    /// The accumulated signal (the spatial filter's input), row by row.
    ///
    /// # Safety
    /// While the rows live, a row is read only once its band has run, and not while any
    /// band runs that writes it.
    pub(super) unsafe fn signal(&self) -> PlaneRows<'_, SIGNAL_PLANES> {
        // SAFETY: the caller's promise.
        unsafe { self.signal.rows(self.width, self.height) }
    }

    /// The next frame's history, for `feed_back_row` to replace its illumination row by
    /// row (SVGF keeps the first a-trous iteration's output as history: less noise
    /// carried forward).
    pub(super) fn history(&self) -> HistoryRecords<'_> {
        HistoryRecords {
            width: self.width,
            instances: &self.next_instances,
            records: &self.next,
        }
    }
}

/// The history's records, whose rows `feed_back_row` replaces from many threads at once.
pub(super) struct HistoryRecords<'a> {
    width: usize,
    instances: &'a SharedRuns<'a, u32>,
    records: &'a SharedRuns<'a, LastPixel>,
}

/// Row `y` of the history given the red, green and blue `illumination` of its pixels (the
/// sky's records, never read, are left alone).
///
/// # Safety
/// No other call for the same row may run at the same time, and the row's band of the
/// accumulation (`AccumulationBands::run`) has run.
pub(super) unsafe fn feed_back_row(illumination: [&[f32]; 3], y: usize, history: &HistoryRecords) {
    let width = history.width;
    // SAFETY: the row's records and instances are this call's alone, written already (the
    // caller's promise).
    let (instances, records) = unsafe {
        (
            history.instances.read(y * width, width),
            history.records.run(y * width, width),
        )
    };
    let [red, green, blue] = illumination.map(|plane| &plane[..width]);
    for (x, last) in records.iter_mut().enumerate() {
        if instances[x] != NO_INSTANCE {
            last.history.illumination = Vec3::new(red[x], green[x], blue[x]);
        }
    }
}

/// What every band of a frame's accumulation reads.
struct Band<'a> {
    radiance: &'a HdrImage,
    guides: &'a Guides,
    /// Last frame, if there was one.
    reprojection: Option<&'a Reprojection<'a>>,
    settings: &'a TemporalSettings,
    /// Whether the records can be written in lanes.
    record_lanes: Option<RecordLanes>,
}

/// A worker's rows, kept from band to band.
#[derive(Default)]
struct Workspace {
    rows: NeighbourhoodRows,
    projected: ProjectedRow,
    blend: BlendRow,
}

impl Workspace {
    fn new(width: usize) -> Workspace {
        let mut blend = BlendRow::default();
        blend.resize(width);
        Workspace {
            rows: NeighbourhoodRows::new(width),
            projected: ProjectedRow::default(),
            blend,
        }
    }
}

/// Workspaces between bands: a fresh workspace allocates and zeroes 186 KB of rows at
/// 320 x 180, so each band (`AccumulationBands::run`, on whichever thread the chain or
/// rayon gives it) takes one from here and puts it back when it ends.
#[derive(Default)]
struct WorkspacePool(Mutex<Vec<Workspace>>);

impl WorkspacePool {
    /// A workspace for rows `width` wide, back in the pool when dropped.
    fn take(&self, width: usize) -> PooledWorkspace<'_> {
        let kept = self.lock().pop();
        let workspace = match kept {
            Some(mut workspace) => {
                workspace.blend.resize(width);
                workspace
            }
            None => Workspace::new(width),
        };
        PooledWorkspace {
            workspace,
            pool: self,
        }
    }

    /// The pool's list (a worker that panicked holding it left nothing half-done in it).
    fn lock(&self) -> std::sync::MutexGuard<'_, Vec<Workspace>> {
        self.0
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }
}

/// A workspace taken from a `WorkspacePool`.
struct PooledWorkspace<'a> {
    workspace: Workspace,
    pool: &'a WorkspacePool,
}

impl Drop for PooledWorkspace<'_> {
    fn drop(&mut self) {
        self.pool.lock().push(std::mem::take(&mut self.workspace));
    }
}

impl Band<'_> {
    /// The same code compiled for 8 lanes. No FMA, so both give the same bits.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn accumulate_avx2(
        &self,
        workspace: &mut Workspace,
        first_row: usize,
        next: (&mut [u32], &mut [LastPixel]),
        signal: &mut [f32],
    ) {
        self.accumulate(workspace, first_row, next, signal);
    }

    /// Steps 1-5 for the band of rows from `first_row` (`next`, its pixels' instances and
    /// records for the next frame, and `signal`, its planes): demodulate the band and a
    /// row either side (for the neighbourhoods), then a row at a time project, find the
    /// histories, clamp and blend, and keep this frame's history and first hits for the
    /// next.
    #[inline(always)]
    fn accumulate(
        &self,
        workspace: &mut Workspace,
        first_row: usize,
        (next_instances, next): (&mut [u32], &mut [LastPixel]),
        signal: &mut [f32],
    ) {
        let guides = self.guides;
        let width = guides.width as usize;
        let Workspace {
            rows,
            projected,
            blend,
        } = workspace;
        let last_row = first_row + next.len() / width - 1;
        rows.sum_band(self.radiance, guides, first_row as u32, last_row as u32);
        for (row, ((next_instances, next), signal)) in next_instances
            .chunks_mut(width)
            .zip(next.chunks_mut(width))
            .zip(signal.chunks_mut(SIGNAL_PLANES * width))
            .enumerate()
        {
            let y = first_row + row;
            let instances = &guides.instances()[y * width..][..width];
            let surfaces = SurfaceRow::new(guides, y);
            if let Some(reprojection) = self.reprojection {
                reprojection.project_row(guides, y, projected);
            }
            blend.find_histories(
                self.reprojection,
                guides,
                &surfaces,
                projected,
                y,
                instances,
            );
            blend.blend(rows, y as u32, instances, self.settings, signal);
            blend.keep(&surfaces, signal, (next_instances, next), self.record_lanes);
        }
    }
}

/// The channels a row's lanes keep for a pixel's demodulated illumination: its colour
/// and its luminance, whose first two moments the neighbourhood gives with the colour's.
const CHANNELS: usize = 4;
const LUMINANCE: usize = 3;

/// glam's `Vec3::max`, one lane: `a` where it is larger, else `b` (so NaN gives `b`).
#[inline(always)]
fn larger(a: f32, b: f32) -> f32 {
    if a > b { a } else { b }
}

/// glam's `Vec3::min`, one lane.
#[inline(always)]
fn smaller(a: f32, b: f32) -> f32 {
    if a < b { a } else { b }
}

/// Step 1 for row `y`: each pixel demodulated (`GuidePixel::demodulate`, from the guide
/// planes) into `current`'s red, green and blue rows, with its luminance in the fourth.
#[inline(always)]
fn demodulate_row(radiance: &HdrImage, guides: &Guides, y: usize, current: [&mut [f32]; CHANNELS]) {
    let width = guides.width as usize;
    let start = y * width;
    let radiance = &radiance.pixels[start..start + width];
    let instances = &guides.instances()[start..start + width];
    // Each row its own slice of `width` (as arrays of slices, the loop kept a bounds check
    // per read and branched around the division for the sky rather than vectorise).
    let (albedo_r, albedo_g, albedo_b) = (
        &guides.row(y, ALBEDO_R)[..width],
        &guides.row(y, ALBEDO_G)[..width],
        &guides.row(y, ALBEDO_B)[..width],
    );
    let (unfiltered_r, unfiltered_g, unfiltered_b) = (
        &guides.row(y, UNFILTERED_R)[..width],
        &guides.row(y, UNFILTERED_G)[..width],
        &guides.row(y, UNFILTERED_B)[..width],
    );
    let [red, green, blue, luminance_row] = current.map(|row| &mut row[..width]);
    for x in 0..width {
        let sky = instances[x] == NO_INSTANCE;
        let channel = |radiance: f32, unfiltered: f32, albedo: f32| {
            let illumination = larger(radiance - unfiltered, 0.0) / larger(albedo, ALBEDO_FLOOR);
            if sky { 0.0 } else { illumination }
        };
        let r = channel(radiance[x].x, unfiltered_r[x], albedo_r[x]);
        let g = channel(radiance[x].y, unfiltered_g[x], albedo_g[x]);
        let b = channel(radiance[x].z, unfiltered_b[x], albedo_b[x]);
        (red[x], green[x], blue[x]) = (r, g, b);
        luminance_row[x] = luminance(Vec3::new(r, g, b));
    }
}

/// History lengths below this use the neighbourhood's variance (SVGF's rule: the moments
/// of a few frames say little).
const SHORT_HISTORY: f32 = 4.0;

/// The 3 x 3 neighbourhood sums of a band of rows, taken separably: each row's sums of
/// three across, then three of those down (6 additions a pixel instead of 9 taps: 13%
/// fewer instructions in the temporal pass, counted by callgrind at 480 x 270). Kept as
/// rows of lanes, so each step runs over a row in vectors.
#[derive(Default)]
struct NeighbourhoodRows {
    width: usize,
    /// The first row summed (the band's first row, less one where there is one).
    first: u32,
    /// The band's last row summed.
    last: u32,
    /// Per channel (`CHANNELS`), the summed rows one after another: the demodulated
    /// illumination (`demodulate_row`), ...
    current: [Vec<f32>; CHANNELS],
    /// ... its sum and the sum of its squares over the pixel and its left and right
    /// neighbours that are not sky, ...
    sum: [Vec<f32>; CHANNELS],
    squares: [Vec<f32>; CHANNELS],
    /// ... and how many of them there are.
    count: Vec<f32>,
}

/// The sums across of one row (`NeighbourhoodRows`): `out[x]` = f(x) + f(x - 1) + f(x + 1)
/// over the neighbours there are, in that order.
#[inline(always)]
fn sum_across<T: Copy>(values: &[T], out: &mut [f32], f: impl Fn(T) -> f32) {
    let width = values.len();
    let out = &mut out[..width];
    match width {
        0 => {}
        1 => out[0] = f(values[0]),
        _ => {
            out[0] = f(values[0]) + f(values[1]);
            for x in 1..width - 1 {
                out[x] = f(values[x]) + f(values[x - 1]) + f(values[x + 1]);
            }
            out[width - 1] = f(values[width - 1]) + f(values[width - 2]);
        }
    }
}

impl NeighbourhoodRows {
    fn new(width: usize) -> NeighbourhoodRows {
        NeighbourhoodRows {
            width,
            first: 0,
            last: 0,
            current: Default::default(),
            sum: Default::default(),
            squares: Default::default(),
            count: Vec::new(),
        }
    }

    /// Demodulates rows `first_row..=last_row` and the rows either side, and takes their
    /// row sums.
    #[inline(always)]
    fn sum_band(&mut self, radiance: &HdrImage, guides: &Guides, first_row: u32, last_row: u32) {
        let (width, height) = (guides.width as usize, guides.height);
        self.width = width;
        self.first = first_row.saturating_sub(1);
        self.last = (last_row + 1).min(height - 1);
        let rows = (self.last - self.first + 1) as usize;
        for plane in self
            .current
            .iter_mut()
            .chain(&mut self.sum)
            .chain(&mut self.squares)
        {
            plane.resize(rows * width, 0.0);
        }
        self.count.resize(rows * width, 0.0);
        for row in 0..rows {
            let y = self.first as usize + row;
            let span = row * width..(row + 1) * width;
            let [r, g, b, l] = &mut self.current;
            demodulate_row(
                radiance,
                guides,
                y,
                [r, g, b, l].map(|plane| &mut plane[span.clone()]),
            );
            for c in 0..CHANNELS {
                let current = &self.current[c][span.clone()];
                sum_across(current, &mut self.sum[c][span.clone()], |v| v);
                sum_across(current, &mut self.squares[c][span.clone()], |v| v * v);
            }
            // A sky pixel's demodulated value is zero, so only its count needs masking.
            let instances = &guides.instances()[y * width..(y + 1) * width];
            let count = &mut self.count[span];
            sum_across(instances, count, |instance| {
                if instance == NO_INSTANCE { 0.0 } else { 1.0 }
            });
        }
    }
}

/// One row's steps 3 to 5 in lanes: the histories found (step 3, a pixel at a time), then
/// the neighbourhood, clamp and blend over the whole row at once. Kept per worker.
#[derive(Default)]
struct BlendRow {
    /// Whether a history was found under each pixel, and if so the history.
    found: Vec<bool>,
    before_illumination: [Vec<f32>; 3],
    before_moments: [Vec<f32>; 2],
    before_length: Vec<f32>,
    /// The neighbourhood's sums down the row's three rows.
    sum: [Vec<f32>; CHANNELS],
    squares: [Vec<f32>; CHANNELS],
    count: Vec<f32>,
    /// The new histories' moments and lengths (their illumination goes to the signal).
    moments: [Vec<f32>; 2],
    length: Vec<f32>,
}

impl BlendRow {
    fn resize(&mut self, width: usize) {
        self.found.resize(width, false);
        let planes = self
            .before_illumination
            .iter_mut()
            .chain(&mut self.before_moments);
        let planes = planes.chain(&mut self.sum).chain(&mut self.squares);
        for plane in planes.chain(&mut self.moments) {
            plane.resize(width, 0.0);
        }
        for plane in [&mut self.before_length, &mut self.count, &mut self.length] {
            plane.resize(width, 0.0);
        }
    }

    /// Steps 2 and 3 for row `y` (its first hits `surfaces`, projected as `projected`):
    /// the history under each pixel that is not sky, if any.
    #[inline(always)]
    fn find_histories(
        &mut self,
        reprojection: Option<&Reprojection>,
        guides: &Guides,
        surfaces: &SurfaceRow,
        projected: &ProjectedRow,
        y: usize,
        instances: &[u32],
    ) {
        let Some(reprojection) = reprojection else {
            self.found.fill(false);
            return;
        };
        for (x, &instance) in instances.iter().enumerate() {
            let before = if instance == NO_INSTANCE {
                None
            } else {
                reprojection.history_at(guides, surfaces, projected, x, y, instance)
            };
            self.found[x] = before.is_some();
            if let Some(before) = before {
                self.before_illumination[0][x] = before.illumination.x;
                self.before_illumination[1][x] = before.illumination.y;
                self.before_illumination[2][x] = before.illumination.z;
                self.before_moments[0][x] = before.moments.x;
                self.before_moments[1][x] = before.moments.y;
                self.before_length[x] = before.length;
            }
        }
    }

    /// Steps 4 and 5 for row `y` of the band `rows` summed: each pixel's history blended
    /// with its demodulated illumination, clamped to its 3 x 3 neighbourhood (over pixels
    /// that are not sky); the illumination and the variance the spatial filter reads go
    /// into `signal`, the moments and lengths into `self`. Sky pixels keep nothing.
    #[inline(always)]
    fn blend(
        &mut self,
        rows: &NeighbourhoodRows,
        y: u32,
        instances: &[u32],
        settings: &TemporalSettings,
        signal: &mut [f32],
    ) {
        let width = rows.width;
        // The neighbourhood's sums down, from zero in row order (as the pixel's own were).
        let (top, bottom) = (y.saturating_sub(1).max(rows.first), (y + 1).min(rows.last));
        let summed = |plane: &[f32], total: &mut [f32]| {
            total.fill(0.0);
            for row in top..=bottom {
                let start = (row - rows.first) as usize * width;
                for (total, value) in total.iter_mut().zip(&plane[start..start + width]) {
                    *total += value;
                }
            }
        };
        for c in 0..CHANNELS {
            summed(&rows.sum[c], &mut self.sum[c]);
            summed(&rows.squares[c], &mut self.squares[c]);
        }
        summed(&rows.count, &mut self.count);
        let start = (y - rows.first) as usize * width;
        let current = rows
            .current
            .each_ref()
            .map(|plane| &plane[start..start + width]);
        let [sum_r, sum_g, sum_b, sum_l] = self.sum.each_ref().map(|plane| &plane[..width]);
        let [squares_r, squares_g, squares_b, squares_l] =
            self.squares.each_ref().map(|plane| &plane[..width]);
        let count = &self.count[..width];
        let found = &self.found[..width];
        let before = self
            .before_illumination
            .each_ref()
            .map(|plane| &plane[..width]);
        let [before_mean, before_square] = self.before_moments.each_ref().map(|p| &p[..width]);
        let before_length = &self.before_length[..width];
        let instances = &instances[..width];
        let reads = BlendReads {
            current,
            sum: [sum_r, sum_g, sum_b, sum_l],
            squares: [squares_r, squares_g, squares_b, squares_l],
            count,
            found,
            before,
            before_moments: [before_mean, before_square],
            before_length,
            instances,
        };
        let [moment_mean, moment_square] = self.moments.each_mut().map(|p| &mut p[..width]);
        // The signal's planes in the order `SignalPlanes` keeps them.
        const _: () = assert!(RED == 0 && GREEN == 1 && BLUE == 2 && VARIANCE == 3);
        let (colour, variance_out) = signal.split_at_mut(3 * width);
        let (red_out, colour) = colour.split_at_mut(width);
        let (green_out, blue_out) = colour.split_at_mut(width);
        blend_pixels(
            &reads,
            settings,
            red_out,
            green_out,
            blue_out,
            &mut variance_out[..width],
            moment_mean,
            moment_square,
            &mut self.length[..width],
        );
    }

    /// The row's instances and records for the next frame (`next`): each pixel's first
    /// hit (`surfaces`) and its new history, from `blend`'s row (its illumination from
    /// `signal`'s).
    #[inline(always)]
    fn keep(
        &self,
        surfaces: &SurfaceRow,
        signal: &[f32],
        next: (&mut [u32], &mut [LastPixel]),
        lanes: Option<RecordLanes>,
    ) {
        let width = next.1.len();
        let (red, green, blue) = (
            &signal[RED * width..][..width],
            &signal[GREEN * width..][..width],
            &signal[BLUE * width..][..width],
        );
        let (mean, square, length) = (
            &self.moments[0][..width],
            &self.moments[1][..width],
            &self.length[..width],
        );
        surfaces.keep(
            next,
            HistoryRow {
                illumination: [red, green, blue],
                moments: [mean, square],
                length,
            },
            lanes,
        );
    }
}

/// What `blend_pixels` reads of a row, each cut to the row.
struct BlendReads<'a> {
    current: [&'a [f32]; CHANNELS],
    sum: [&'a [f32]; CHANNELS],
    squares: [&'a [f32]; CHANNELS],
    count: &'a [f32],
    found: &'a [bool],
    before: [&'a [f32]; 3],
    before_moments: [&'a [f32]; 2],
    before_length: &'a [f32],
    instances: &'a [u32],
}

/// `BlendRow::blend`'s pixels. The seven rows written are arguments of their own, so the
/// compiler knows they alias none of the rows read and vectorises the loop without checks
/// at run time, whatever it is inlined into. (Written through the row's fields it needed
/// those checks, and a change elsewhere in the temporal pass, an extra call in its row
/// loop, was enough for it to give up: the pass went from 1.75 to 2.3 ms, one thread.)
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn blend_pixels(
    reads: &BlendReads,
    settings: &TemporalSettings,
    red_out: &mut [f32],
    green_out: &mut [f32],
    blue_out: &mut [f32],
    variance_out: &mut [f32],
    moment_mean: &mut [f32],
    moment_square: &mut [f32],
    length_out: &mut [f32],
) {
    let width = reads.instances.len();
    let current = reads.current.map(|plane| &plane[..width]);
    let [sum_r, sum_g, sum_b, sum_l] = reads.sum.map(|plane| &plane[..width]);
    let [squares_r, squares_g, squares_b, squares_l] = reads.squares.map(|plane| &plane[..width]);
    let (count, found, instances) = (
        &reads.count[..width],
        &reads.found[..width],
        reads.instances,
    );
    let before = reads.before.map(|plane| &plane[..width]);
    let [before_mean, before_square] = reads.before_moments.map(|plane| &plane[..width]);
    let before_length = &reads.before_length[..width];
    let (red_out, green_out, blue_out, variance_out) = (
        &mut red_out[..width],
        &mut green_out[..width],
        &mut blue_out[..width],
        &mut variance_out[..width],
    );
    let (moment_mean, moment_square, length_out) = (
        &mut moment_mean[..width],
        &mut moment_square[..width],
        &mut length_out[..width],
    );
    let clamp_sigma = settings.clamp_sigma;
    let band_of = |sigma: f32| {
        if clamp_sigma.is_finite() {
            sigma * clamp_sigma
        } else {
            f32::INFINITY
        }
    };
    for x in 0..width {
        // The neighbourhood (SVGF's spatial estimate, and the clamp's box).
        let n = count[x];
        let mean = [sum_r[x] / n, sum_g[x] / n, sum_b[x] / n, sum_l[x] / n];
        let spread = |square: f32, mean: f32| larger(square / n - mean * mean, 0.0);
        let sigma = [
            spread(squares_r[x], mean[0]).sqrt(),
            spread(squares_g[x], mean[1]).sqrt(),
            spread(squares_b[x], mean[2]).sqrt(),
        ];
        let spatial_variance = spread(squares_l[x], mean[3]);
        let c = [current[0][x], current[1][x], current[2][x]];
        let lum = current[LUMINANCE][x];
        let fresh = [lum, lum * lum];
        // Blended with the history found: weights 1/length down to their floors.
        let length = before_length[x] + 1.0;
        let alpha = (1.0 / length).max(settings.alpha_min);
        let moments_alpha = (1.0 / length).max(settings.moments_alpha_min);
        let blended = |channel: usize| {
            let band = band_of(sigma[channel]);
            let (low, high) = (larger(mean[channel] - band, 0.0), mean[channel] + band);
            let clamped = smaller(larger(before[channel][x], low), high);
            clamped * (1.0 - alpha) + c[channel] * alpha
        };
        let illumination = [blended(0), blended(1), blended(2)];
        let moments = [
            before_mean[x] * (1.0 - moments_alpha) + fresh[0] * moments_alpha,
            before_square[x] * (1.0 - moments_alpha) + fresh[1] * moments_alpha,
        ];
        let variance = if length < SHORT_HISTORY {
            spatial_variance
        } else {
            (moments[1] - moments[0] * moments[0]).max(0.0)
        };
        // Or none found: the history starts here, with the neighbourhood's variance.
        let (illumination, moments, length, variance) = if found[x] {
            (illumination, moments, length, variance)
        } else {
            (c, fresh, 1.0, spatial_variance)
        };
        // The sky keeps nothing.
        let sky = instances[x] == NO_INSTANCE;
        let kept = |value: f32| if sky { 0.0 } else { value };
        red_out[x] = kept(illumination[0]);
        green_out[x] = kept(illumination[1]);
        blue_out[x] = kept(illumination[2]);
        variance_out[x] = kept(variance);
        moment_mean[x] = kept(moments[0]);
        moment_square[x] = kept(moments[1]);
        length_out[x] = kept(length);
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

    fn film(value: impl Fn(u32, u32) -> Vec3) -> HdrImage {
        let mut film = HdrImage::new(32, 16);
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
