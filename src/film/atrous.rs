//! Frame step `film`, second filter: the edge-avoiding a-trous wavelet filter of SVGF
//! (Dammertz et al. 2010, "Edge-Avoiding A-Trous Wavelet Transform for fast Global
//! Illumination Filtering"; Schied et al. 2017 for the variance-guided luminance weight),
//! on the demodulated illumination `temporal` accumulated.
//!
//! Each iteration i blurs with a 3 x 3 B-spline kernel (1/4, 1/2, 1/4 per axis) whose taps
//! are 2^i pixels apart, so `iterations` passes reach 2^(iterations+1) - 1 pixels across at
//! the cost of 9 taps each. A tap's kernel weight is multiplied by edge-stopping terms:
//! - normal: exp(-128 (1 - n_p . n_q)), SVGF's (n_p . n_q)^128 folded into the exponential;
//! - depth: exp(-|z_p - z_q| / (sigma_depth |grad z| |p - q| + eps)), the depth change
//!   the surface's own slope explains is free;
//! - luminance: exp(-|l_p - l_q| / (sigma_luminance sqrt(g3x3(variance_p)) + eps)), noise
//!   of the expected size is smoothed, real edges in the lighting are kept;
//! - albedo: exp(-|a_p - a_q|_1 / sigma_albedo), so light is not averaged across materials;
//! - instance: taps on another instance count zero.
//!
//! The variance is filtered alongside (weights squared), so later, wider iterations trust
//! the already-smoothed luminance more. Rows are filtered in bands of rows, the prepass and the
//! passes chained so that a band starts once the bands it reads are done (film/chain.rs).

use glam::Vec3;

use super::chain::run_chain;
use crate::render::guides::{
    ALBEDO_B, ALBEDO_G, ALBEDO_R, DEPTH, Guides, NO_INSTANCE, NORMAL_X, NORMAL_Y, NORMAL_Z,
};
use crate::render::planes::{
    BAND_ROWS, BLUE, GREEN, PlaneRows, RED, SIGNAL_PLANES, SharedRuns, SignalPlanes, VARIANCE,
};
use crate::scene::model::luminance;

#[derive(Clone, Debug, PartialEq)]
pub struct AtrousSettings {
    /// Passes, each with twice the tap spacing of the last (0 turns the filter off).
    pub iterations: u32,
    pub sigma_luminance: f32,
    pub sigma_depth: f32,
    pub sigma_albedo: f32,
}

impl Default for AtrousSettings {
    fn default() -> Self {
        AtrousSettings {
            // 3 passes (taps up to 4 apart, 15 pixels across): 4 and 5 measured no lower
            // RMSE on `gloam flythrough` (0.0554, 0.0565 against 0.0554) and more ghosting.
            iterations: 3,
            sigma_luminance: 4.0,
            sigma_depth: 1.0,
            sigma_albedo: 0.1,
        }
    }
}

impl AtrousSettings {
    /// The passes to run on a render at `render_scale` of the shown resolution per axis
    /// (1: `iterations`): one fewer for each halving of the scale, so the filter reaches
    /// about as far across the shown image (n passes reach 2^(n+1) - 1 render pixels,
    /// each 1 / `render_scale` shown pixels wide: 2 passes at half scale reach 14 shown
    /// pixels, 3 at full scale 15), never fewer than one. `gloam flythrough`'s player's
    /// view (first-light, 320x180 upscaled to 640x360) with 2 passes against 3: RMSE
    /// 0.0204 against 0.0202, less ghosting (trail 0.165 against 0.168), a third of the
    /// spatial filter's time saved.
    pub fn iterations_at_scale(&self, render_scale: f32) -> u32 {
        if self.iterations == 0 || !(render_scale > 0.0) || render_scale >= 1.0 {
            return self.iterations;
        }
        (self.iterations as f32 + render_scale.log2())
            .round()
            .max(1.0) as u32
    }
}

/// The filtered illumination, and the first iteration's (SVGF keeps it as history).
pub struct Filtered {
    pub illumination: Vec<Vec3>,
    pub first_iteration: Vec<Vec3>,
}

/// The same, left in the workspace's planes (the frame's filter reads them in place).
pub struct FilteredPlanes<'a> {
    pub illumination: &'a SignalPlanes,
    pub first_iteration: &'a SignalPlanes,
    /// CPU seconds the bands of a banded input (`Input::Banded`) took, and the filter's
    /// own (its prepass and passes), summed over the threads.
    pub input_seconds: f64,
    pub filter_seconds: f64,
}

/// What the passes filter.
#[derive(Clone, Copy)]
pub(crate) enum Input<'a> {
    /// An image already whole.
    Whole(&'a SignalPlanes),
    /// An image written a band of `BAND_ROWS` rows per call of `band` (each band once,
    /// from any thread), whose rows `rows` reads once their band is done: the filter runs
    /// its bands first in its chain (film/chain.rs), so its prepass starts on the first
    /// bands while the last are still being written.
    Banded {
        rows: PlaneRows<'a, SIGNAL_PLANES>,
        band: &'a (dyn Fn(usize) + Sync),
    },
}

/// B-spline weights of the 3-tap kernel (the variance prefilter's; the wavelet passes
/// spell out the products in `TAPS`).
const KERNEL: [f32; 3] = [0.25, 0.5, 0.25];

/// The 8 taps around the centre: offset in steps, kernel weight, diagonal.
const TAPS: [(isize, isize, f32, bool); 8] = [
    (-1, -1, 0.0625, true),
    (0, -1, 0.125, false),
    (1, -1, 0.0625, true),
    (-1, 0, 0.125, false),
    (1, 0, 0.125, false),
    (-1, 1, 0.0625, true),
    (0, 1, 0.125, false),
    (1, 1, 0.0625, true),
];

/// `out` = the luminance of the rows `red`, `green` and `blue`.
#[inline(always)]
fn luminance_row([red, green, blue]: [&[f32]; 3], out: &mut [f32]) {
    let width = out.len();
    let (red, green, blue) = (&red[..width], &green[..width], &blue[..width]);
    for x in 0..width {
        out[x] = luminance(Vec3::new(red[x], green[x], blue[x]));
    }
}

/// The filter's buffers, kept from frame to frame (`FrameFilter` owns one).
#[derive(Default)]
pub struct Workspace {
    /// How fast depth changes per pixel across its surface, row-major.
    depth_slope: Vec<f32>,
    /// The passes' outputs: the first pass writes `outputs[0]` (kept: it is the history's
    /// next illumination), later passes alternate between the other two.
    outputs: [SignalPlanes; 3],
    /// The variance under SVGF's 3 x 3 prefilter, row-major.
    blurred_variance: Vec<f32>,
    /// Each pass's input's luminance, row-major, written by the pass before (the first
    /// pass's by the prepass), so a tap reads it rather than weighing its colour again:
    /// pass i reads `luminance[i % 2]` and writes the other.
    luminance: [Vec<f32>; 2],
    /// A row of zero variance and a row of sky: what the variance prefilter reads past the
    /// film's top and bottom.
    past_edge: (Vec<f32>, Vec<u32>),
    /// Run the portable rows even where AVX2 is present (tests compare the two).
    portable_only: bool,
}

/// Filters with a workspace of its own (tests and one-off images; the game keeps one).
pub fn filter(
    illumination: &[Vec3],
    variance: &[f32],
    guides: &Guides,
    settings: &AtrousSettings,
) -> Filtered {
    let input = SignalPlanes::from_pixels(illumination, variance, guides.width as usize);
    let mut workspace = Workspace::default();
    let output = filter_with(
        &mut workspace,
        Input::Whole(&input),
        guides,
        settings,
        |_| {},
    );
    Filtered {
        illumination: output.illumination.colours(),
        first_iteration: output.first_iteration.colours(),
    }
}

/// A row a pass has just written, handed to `filter_with`'s `row_done` while it is still
/// in the worker's cache.
pub struct PassRow<'a> {
    /// The pass's number, from 0.
    pub iteration: u32,
    /// Whether it is the last pass (the first may be the last too).
    pub last: bool,
    pub y: usize,
    /// The row's red, green and blue illumination.
    pub illumination: [&'a [f32]; 3],
}

/// Filters `input` (demodulated illumination and its variance), seen with `guides`; the
/// result stays in `workspace`. With no iterations both outputs are a copy of the input.
/// Each pass hands every row it writes to `row_done` (from many threads, each row once),
/// so what the frame does with a pass's output next (SVGF's feedback, remodulation) reads
/// it from the cache, not in another pass over the image.
pub(crate) fn filter_with<'a>(
    workspace: &'a mut Workspace,
    input: Input,
    guides: &Guides,
    settings: &AtrousSettings,
    row_done: impl Fn(PassRow) + Sync,
) -> FilteredPlanes<'a> {
    let (width, height) = (guides.width as usize, guides.height as usize);
    let Workspace {
        depth_slope,
        outputs,
        blurred_variance,
        luminance,
        past_edge,
        portable_only,
    } = workspace;
    // SVGF prefilters the variance before every pass; here only before the first (later
    // passes read the variance the wavelet passes themselves filtered), a pass's cost less.
    // The prepass (the chain's first stage) takes the depth slopes, prefilters the variance
    // and weighs the first pass's input's luminance, a band at a time.
    depth_slope.resize(width * height, 0.0);
    blurred_variance.resize(width * height, 0.0);
    for plane in luminance.iter_mut() {
        plane.resize(width * height, 0.0);
    }
    let [first_luminance, second_luminance] = luminance;
    // What the variance prefilter reads past the film's top and bottom: sky.
    past_edge.0.resize(width, 0.0);
    past_edge.1.resize(width, NO_INSTANCE);
    let past_edge = (&past_edge.0[..], &past_edge.1[..]);
    // Pass i reads pass i - 1's output (the first reads `input`) and writes `outputs[0]`
    // (the first), then `outputs[1]`, `outputs[2]`, `outputs[1]`, ... .
    let output_of = |iteration: u32| match iteration {
        0 => 0,
        i => 1 + (i as usize - 1) % 2,
    };
    for iteration in 0..settings.iterations {
        outputs[output_of(iteration)].resize(width, height);
    }
    let bands = height.div_ceil(BAND_ROWS);
    let band_rows = |band: usize| band * BAND_ROWS..((band + 1) * BAND_ROWS).min(height);
    // The chain: the prepass, then the wavelet passes, each band of a pass after the bands
    // of the one before that it reads (film/chain.rs). A pass's taps reach `step` rows up
    // and down, and what it overwrites (a luminance plane, an output two passes old) was
    // read by the pass before within its own, shorter, reach: so it waits for the bands
    // within `step` rows of its own.
    let (input, producer) = match input {
        Input::Whole(planes) => (PlaneRows::of(planes), None),
        Input::Banded { rows, band } => (rows, Some(band)),
    };
    // The stages: a banded input's bands, the prepass and the passes (no prepass when
    // there is no pass). The prepass reads the input a row either side of its band.
    let first_filter_stage = usize::from(producer.is_some());
    let mut reach = vec![0; first_filter_stage];
    if settings.iterations > 0 {
        reach.push(1);
        reach.extend((0..settings.iterations).map(|i| (1usize << i).div_ceil(BAND_ROWS)));
    }
    let stage_seconds = {
        let output_runs = outputs.each_mut().map(|output| output.shared_runs());
        let slope_runs = SharedRuns::new(depth_slope);
        let blurred_runs = SharedRuns::new(blurred_variance);
        let luminance_runs =
            [first_luminance, second_luminance].map(|plane| SharedRuns::new(plane));
        // SAFETY (every view below): the chain runs a band of a pass only once the bands of
        // the pass before within its reach are done; a pass reads rows within its reach of
        // its band, which those bands (or bands before them) wrote, and which no band running
        // meanwhile writes (see `reach`).
        let rows = |runs| unsafe { SharedRuns::rows::<1>(runs, width, height) };
        let passes: Vec<Pass> = (0..settings.iterations)
            .map(|iteration| Pass {
                step: 1 << iteration,
                guides,
                depth_slope: rows(&slope_runs),
                input: match iteration {
                    0 => input,
                    // SAFETY: as above.
                    i => unsafe {
                        output_runs[output_of(i - 1)].rows::<SIGNAL_PLANES>(width, height)
                    },
                },
                steering_variance: (iteration == 0).then(|| rows(&blurred_runs)),
                luminance: rows(&luminance_runs[iteration as usize % 2]),
                settings,
                portable_only: *portable_only,
                carry_variance: iteration + 1 < settings.iterations,
            })
            .collect();
        let portable_only = *portable_only;
        run_chain(
            bands,
            &reach,
            || RowScratch::new(width),
            |scratch, stage, band| {
                let Some(stage) = stage.checked_sub(first_filter_stage) else {
                    if let Some(produce) = producer {
                        produce(band);
                    }
                    return;
                };
                let rows = band_rows(band);
                let band_pixels = rows.start * width..rows.end * width;
                // SAFETY: the band's own rows of each buffer it writes, which no other band
                // writes, and no band reads while this one runs (the chain's order).
                let run = |runs, planes: usize| unsafe {
                    SharedRuns::run(runs, band_pixels.start * planes, band_pixels.len() * planes)
                };
                if stage == 0 {
                    // The prepass: depth slopes, the prefiltered variance, the first pass's
                    // input's luminance.
                    let (slopes, blurred) = (run(&slope_runs, 1), run(&blurred_runs, 1));
                    let luminance = run(&luminance_runs[0], 1);
                    for (row, y) in rows.enumerate() {
                        let at = row * width..(row + 1) * width;
                        prepass_row(
                            portable_only,
                            &input,
                            guides,
                            y,
                            past_edge,
                            (&mut slopes[at.clone()], &mut blurred[at.clone()]),
                        );
                        luminance_row(
                            [RED, GREEN, BLUE].map(|plane| input.row(y, plane)),
                            &mut luminance[at],
                        );
                    }
                    return;
                }
                let iteration = stage as u32 - 1;
                let pass = &passes[iteration as usize];
                let out = run(&output_runs[output_of(iteration)], SIGNAL_PLANES);
                let luminance = run(&luminance_runs[(iteration as usize + 1) % 2], 1);
                for (row, y) in rows.enumerate() {
                    let out =
                        &mut out[row * width * SIGNAL_PLANES..(row + 1) * width * SIGNAL_PLANES];
                    pass.row(y, scratch, out);
                    let illumination =
                        [RED, GREEN, BLUE].map(|plane| &out[plane * width..(plane + 1) * width]);
                    // The next pass's taps read it; after the last, nothing does.
                    if pass.carry_variance {
                        luminance_row(illumination, &mut luminance[row * width..(row + 1) * width]);
                    }
                    row_done(PassRow {
                        iteration,
                        last: iteration + 1 == settings.iterations,
                        y,
                        illumination,
                    });
                }
            },
        )
    };
    if settings.iterations == 0 {
        // No pass: both outputs are the input as it stands.
        let output = &mut outputs[0];
        output.resize(width, height);
        for y in 0..height {
            for plane in 0..SIGNAL_PLANES {
                output
                    .row_mut(y, plane)
                    .copy_from_slice(input.row(y, plane));
            }
        }
    }
    let (produced, filtered) = stage_seconds.split_at(first_filter_stage);
    let (input_seconds, filter_seconds) = (produced.iter().sum(), filtered.iter().sum());
    FilteredPlanes {
        illumination: &outputs[output_of(settings.iterations.max(1) - 1)],
        first_iteration: &outputs[0],
        input_seconds,
        filter_seconds,
    }
}

/// Row y's depth slopes: per pixel, how fast depth changes per pixel across the surface,
/// the smaller of the forward and backward differences on each axis (so an edge beside the
/// pixel does not count; a neighbour on another instance is no difference), the larger
/// axis. Zero for the sky. Written as whole-row passes without branches so they vectorise
/// (pixel by pixel with a branch per neighbour it was 2 to 4% of a frame's CPU time at
/// 320 x 180).
#[inline(always)]
fn depth_slope_row(guides: &Guides, y: usize, out: &mut [f32]) {
    let (width, height) = (guides.width as usize, guides.height as usize);
    let instances = guides.instances();
    let row = |y: usize| (guides.row(y, DEPTH), &instances[y * width..(y + 1) * width]);
    let (depth, instance) = row(y);
    // The difference to a neighbour, or none (infinity) when it is another surface.
    #[inline(always)]
    fn difference(depth: f32, instance: u32, neighbour_depth: f32, neighbour_instance: u32) -> f32 {
        if neighbour_instance == instance {
            (neighbour_depth - depth).abs()
        } else {
            f32::INFINITY
        }
    }
    // An axis's slope: the smaller difference, zero where neither side is the surface.
    #[inline(always)]
    fn axis(a: f32, b: f32) -> f32 {
        let slope = a.min(b);
        if slope < f32::INFINITY { slope } else { 0.0 }
    }
    // Along the row: the film's first and last pixels have one neighbour.
    out.fill(f32::INFINITY);
    if width >= 2 {
        let left = (&depth[..width - 1], &instance[..width - 1]);
        let right = (&depth[1..], &instance[1..]);
        // out[x] = difference to the left neighbour, for x >= 1 ...
        for (slope, ((d, i), (nd, ni))) in out[1..]
            .iter_mut()
            .zip(right.0.iter().zip(right.1).zip(left.0.iter().zip(left.1)))
        {
            *slope = difference(*d, *i, *nd, *ni);
        }
        // ... and the axis with the right neighbour, for x < width - 1.
        for (slope, ((d, i), (nd, ni))) in out[..width - 1]
            .iter_mut()
            .zip(left.0.iter().zip(left.1).zip(right.0.iter().zip(right.1)))
        {
            *slope = axis(*slope, difference(*d, *i, *nd, *ni));
        }
        out[width - 1] = axis(out[width - 1], f32::INFINITY);
    } else {
        out.fill(0.0);
    }
    // Across rows: the larger axis.
    let up = (y > 0).then(|| row(y - 1));
    let down = (y + 1 < height).then(|| row(y + 1));
    match (up, down) {
        (Some(up), Some(down)) => {
            for (x, slope) in out.iter_mut().enumerate() {
                let vertical = axis(
                    difference(depth[x], instance[x], up.0[x], up.1[x]),
                    difference(depth[x], instance[x], down.0[x], down.1[x]),
                );
                *slope = slope.max(vertical);
            }
        }
        (Some(only), None) | (None, Some(only)) => {
            for (x, slope) in out.iter_mut().enumerate() {
                let vertical = axis(
                    difference(depth[x], instance[x], only.0[x], only.1[x]),
                    f32::INFINITY,
                );
                *slope = slope.max(vertical);
            }
        }
        (None, None) => {}
    }
    for (slope, instance) in out.iter_mut().zip(instance) {
        if *instance == NO_INSTANCE {
            *slope = 0.0;
        }
    }
}

/// Row y's depth slopes and prefiltered variance, compiled for 8 lanes where the CPU has
/// AVX2 (the two loops are plain float code: the same results either way).
fn prepass_row(
    portable_only: bool,
    input: &PlaneRows<'_, SIGNAL_PLANES>,
    guides: &Guides,
    y: usize,
    past_edge: (&[f32], &[u32]),
    (slopes, blurred): (&mut [f32], &mut [f32]),
) {
    #[cfg(target_arch = "x86_64")]
    if !portable_only && crate::simd::avx2() {
        #[target_feature(enable = "avx2")]
        fn prepass_row_avx2(
            input: &PlaneRows<'_, SIGNAL_PLANES>,
            guides: &Guides,
            y: usize,
            past_edge: (&[f32], &[u32]),
            slopes: &mut [f32],
            blurred: &mut [f32],
        ) {
            depth_slope_row(guides, y, slopes);
            blur_variance_row(input, guides, y, past_edge, blurred);
        }
        // SAFETY: the CPU has AVX2, the only feature `prepass_row_avx2` enables.
        unsafe { prepass_row_avx2(input, guides, y, past_edge, slopes, blurred) };
        return;
    }
    depth_slope_row(guides, y, slopes);
    blur_variance_row(input, guides, y, past_edge, blurred);
}

/// Per-row working arrays (one set per band, reused row after row).
struct RowScratch {
    luminance_scale: Vec<f32>,
    depth_straight: Vec<f32>,
    depth_diagonal: Vec<f32>,
    sum: [Vec<f32>; SIGNAL_PLANES],
    weights: Vec<f32>,
}

impl RowScratch {
    fn new(width: usize) -> RowScratch {
        let row = || vec![0.0f32; width];
        RowScratch {
            luminance_scale: row(),
            depth_straight: row(),
            depth_diagonal: row(),
            sum: [row(), row(), row(), row()],
            weights: row(),
        }
    }
}

/// One wavelet pass: `step` pixels between taps.
struct Pass<'a> {
    step: usize,
    guides: &'a Guides,
    depth_slope: PlaneRows<'a, 1>,
    input: PlaneRows<'a, SIGNAL_PLANES>,
    /// The prefiltered variance steering the luminance weight on the first pass; later
    /// passes steer by the variance they carry.
    steering_variance: Option<PlaneRows<'a, 1>>,
    /// The input's luminance.
    luminance: PlaneRows<'a, 1>,
    settings: &'a AtrousSettings,
    portable_only: bool,
    /// Whether the variance is filtered too: not on the last pass, where nothing reads it
    /// (its load and three operations are 5 of a tap's 40).
    carry_variance: bool,
}

impl Pass<'_> {
    /// Filters row `y` into `out` (the row's four signal planes).
    fn row(&self, y: usize, scratch: &mut RowScratch, out: &mut [f32]) {
        #[cfg(target_arch = "x86_64")]
        if !self.portable_only && crate::simd::avx2() {
            // SAFETY: the CPU has AVX2, the only feature `row_avx2` enables.
            unsafe {
                if self.carry_variance {
                    self.row_avx2::<true>(y, scratch, out)
                } else {
                    self.row_avx2::<false>(y, scratch, out)
                }
            };
            return;
        }
        if self.carry_variance {
            self.row_portable::<true>(y, scratch, out);
        } else {
            self.row_portable::<false>(y, scratch, out);
        }
    }

    /// The same code compiled for 8 lanes. No FMA: the two give identical results.
    /// (Written out in intrinsics with each run of 8 pixels' sums kept in registers across
    /// its 8 taps, the pass measured slower: 8.4 against 5.8 ms a frame, `gloam bench`.)
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn row_avx2<const CARRY_VARIANCE: bool>(
        &self,
        y: usize,
        scratch: &mut RowScratch,
        out: &mut [f32],
    ) {
        self.row_portable::<CARRY_VARIANCE>(y, scratch, out);
    }

    /// `CARRY_VARIANCE`: `carry_variance`, as a constant so the tap loop has no branch.
    #[inline(always)]
    fn row_portable<const CARRY_VARIANCE: bool>(
        &self,
        y: usize,
        scratch: &mut RowScratch,
        out: &mut [f32],
    ) {
        self.centre(y, scratch);
        self.taps::<CARRY_VARIANCE>(y, scratch, 0, self.input.width());
        self.normalise::<CARRY_VARIANCE>(y, scratch, out);
    }

    /// Row `y`'s per-pixel scales (divisions hoisted out of the taps) and its sums started
    /// with the centre tap.
    #[inline(always)]
    fn centre(&self, y: usize, scratch: &mut RowScratch) {
        let width = self.input.width();
        let (guides, input, settings) = (self.guides, &self.input, self.settings);
        let step = self.step;

        // The centre: per-pixel scales (divisions hoisted out of the taps) and the centre
        // tap itself, kernel 1/2 x 1/2 with every edge term 1.
        let steering = match &self.steering_variance {
            Some(variance) => variance.row(y, 0),
            None => input.row(y, VARIANCE),
        };
        let (red, green, blue) = (input.row(y, RED), input.row(y, GREEN), input.row(y, BLUE));
        let depth = guides.row(y, DEPTH);
        let slope = self.depth_slope.row(y, 0);
        let variance = input.row(y, VARIANCE);
        for x in 0..width {
            scratch.luminance_scale[x] =
                1.0 / (settings.sigma_luminance * steering[x].max(0.0).sqrt() + 1e-6);
            let depth_epsilon = 1e-3 * depth[x] + 1e-4;
            let depth_slope_step = settings.sigma_depth * slope[x] * step as f32;
            scratch.depth_straight[x] = 1.0 / (depth_slope_step + depth_epsilon);
            scratch.depth_diagonal[x] =
                1.0 / (depth_slope_step * std::f32::consts::SQRT_2 + depth_epsilon);
            scratch.sum[RED][x] = red[x] * 0.25;
            scratch.sum[GREEN][x] = green[x] * 0.25;
            scratch.sum[BLUE][x] = blue[x] * 0.25;
            scratch.sum[VARIANCE][x] = variance[x] * 0.0625;
            scratch.weights[x] = 0.25;
        }
    }

    /// Adds the 8 taps of pixels `range_start..range_end` of row `y` into its sums, a run of
    /// `chunk_length` pixels at a time, leaving out the sky at either end of each run.
    #[inline(always)]
    fn taps<const CARRY_VARIANCE: bool>(
        &self,
        y: usize,
        scratch: &mut RowScratch,
        range_start: usize,
        range_end: usize,
    ) {
        let (width, height) = (self.input.width(), self.input.height());
        let (guides, input, settings) = (self.guides, &self.input, self.settings);
        let step = self.step;
        let albedo_scale = 1.0 / settings.sigma_albedo;
        let chunk = chunk_length(range_end - range_start);
        let instances = self.guides.instances();
        for chunk_start in (range_start..range_end).step_by(chunk) {
            let chunk_end = (chunk_start + chunk).min(range_end);
            // Only the run from the chunk's first surface pixel to its last: the sky keeps
            // its own value (`normalise`), so its sums are never read. About half of `gloam
            // bench`'s overview is sky; leaving it out took the passes from 81 M to 52 M
            // instructions (the-gallery, 3 frames at 320 x 180).
            let centres = &instances[y * width..][chunk_start..chunk_end];
            let Some(first_surface) = centres.iter().position(|&i| i != NO_INSTANCE) else {
                continue;
            };
            let end_of_surfaces = centres.iter().rposition(|&i| i != NO_INSTANCE).unwrap_or(0) + 1;
            let surfaces = (chunk_start + first_surface, chunk_start + end_of_surfaces);
            for (dx, dy, kernel, diagonal) in TAPS {
                let tap_y = y as isize + dy * step as isize;
                if tap_y < 0 || tap_y >= height as isize {
                    continue;
                }
                let tap_y = tap_y as usize;
                // The surface's centres whose tap lies inside the row, ...
                let shift = dx * step as isize;
                let (in_row_first, in_row_end) = (
                    (-shift).max(0) as usize,
                    (width as isize - shift).max(0) as usize,
                );
                let first = in_row_first.max(surfaces.0);
                let end = in_row_end.min(surfaces.1);
                if end <= first {
                    continue;
                }
                // ... and the chunk's sky beside them as far as whole vectors take it (its
                // sums are never read, and a run's last partial vector is done a lane at a
                // time, at about 100 instructions a lane).
                let (first, end) = whole_vectors(
                    (first, end),
                    (in_row_first.max(chunk_start), in_row_end.min(chunk_end)),
                );
                let len = end - first;
                let tap_first = (first as isize + shift) as usize;
                // Every slice cut to `len` (`TapRun::add` runs without bounds checks).
                let centre = |plane| &guides.row(y, plane)[first..end];
                let tap = |plane| &guides.row(tap_y, plane)[tap_first..tap_first + len];
                let tap_signal = |plane| &input.row(tap_y, plane)[tap_first..tap_first + len];
                let taps = TapRun {
                    kernel,
                    albedo_scale,
                    centre_normal: [NORMAL_X, NORMAL_Y, NORMAL_Z].map(centre),
                    tap_normal: [NORMAL_X, NORMAL_Y, NORMAL_Z].map(tap),
                    centre_depth: centre(DEPTH),
                    tap_depth: tap(DEPTH),
                    centre_albedo: [ALBEDO_R, ALBEDO_G, ALBEDO_B].map(centre),
                    tap_albedo: [ALBEDO_R, ALBEDO_G, ALBEDO_B].map(tap),
                    centre_instance: &instances[y * width + first..][..len],
                    tap_instance: &instances[tap_y * width + tap_first..][..len],
                    tap_signal: [RED, GREEN, BLUE, VARIANCE].map(tap_signal),
                    centre_luminance: &self.luminance.row(y, 0)[first..end],
                    tap_luminance: &self.luminance.row(tap_y, 0)[tap_first..][..len],
                    luminance_scale: &scratch.luminance_scale[first..end],
                    depth_scale: if diagonal {
                        &scratch.depth_diagonal[first..end]
                    } else {
                        &scratch.depth_straight[first..end]
                    },
                };
                let [sum_red, sum_green, sum_blue, sum_variance] = &mut scratch.sum;
                taps.add::<CARRY_VARIANCE>(
                    &mut sum_red[first..end],
                    &mut sum_green[first..end],
                    &mut sum_blue[first..end],
                    &mut sum_variance[first..end],
                    &mut scratch.weights[first..end],
                );
            }
        }
    }

    /// Row `y`'s output: its sums over its weights.
    #[inline(always)]
    fn normalise<const CARRY_VARIANCE: bool>(
        &self,
        y: usize,
        scratch: &RowScratch,
        out: &mut [f32],
    ) {
        let (width, input) = (self.input.width(), &self.input);
        let variance = input.row(y, VARIANCE);
        // Normalise; the sky keeps its value. Slices cut to `width` so the loops vectorise
        // (indexed by x they were scalar with a bounds check per store: 7% of a pass).
        let centre_instance = &self.guides.instances()[y * width..(y + 1) * width];
        let weights = &scratch.weights[..width];
        let (out_colour, out_variance) = out.split_at_mut(3 * width);
        for plane in [RED, GREEN, BLUE] {
            let (sums, row) = (&scratch.sum[plane][..width], input.row(y, plane));
            let out_plane = &mut out_colour[plane * width..(plane + 1) * width];
            for x in 0..width {
                out_plane[x] = if centre_instance[x] == NO_INSTANCE {
                    row[x]
                } else {
                    sums[x] / weights[x]
                };
            }
        }
        let (sums, out_variance) = (&scratch.sum[VARIANCE][..width], &mut out_variance[..width]);
        if !CARRY_VARIANCE {
            // Nothing reads it; the input's is kept rather than a half-summed one.
            out_variance.copy_from_slice(&variance[..width]);
            return;
        }
        for x in 0..width {
            let w = weights[x];
            out_variance[x] = if centre_instance[x] == NO_INSTANCE {
                variance[x]
            } else {
                sums[x] / (w * w)
            };
        }
    }
}

/// One tap of a run of centre pixels: the rows it reads, each cut to the run.
struct TapRun<'a> {
    kernel: f32,
    albedo_scale: f32,
    centre_normal: [&'a [f32]; 3],
    tap_normal: [&'a [f32]; 3],
    centre_depth: &'a [f32],
    tap_depth: &'a [f32],
    centre_albedo: [&'a [f32]; 3],
    tap_albedo: [&'a [f32]; 3],
    centre_instance: &'a [u32],
    tap_instance: &'a [u32],
    /// The tap's red, green, blue and variance.
    tap_signal: [&'a [f32]; SIGNAL_PLANES],
    centre_luminance: &'a [f32],
    tap_luminance: &'a [f32],
    luminance_scale: &'a [f32],
    depth_scale: &'a [f32],
}

impl TapRun<'_> {
    /// Adds the tap, weighted by its kernel weight and edge terms, into the run's sums.
    /// The sums are arguments of their own, not fields, so the compiler knows they alias
    /// none of the rows read (as fields of one struct it checked the 5 written against
    /// the 20 read before every run: about 850 instructions a tap and run).
    #[inline(always)]
    fn add<const CARRY_VARIANCE: bool>(
        &self,
        sum_red: &mut [f32],
        sum_green: &mut [f32],
        sum_blue: &mut [f32],
        sum_variance: &mut [f32],
        weights: &mut [f32],
    ) {
        let len = weights.len();
        let [centre_nx, centre_ny, centre_nz] = self.centre_normal.map(|row| &row[..len]);
        let [tap_nx, tap_ny, tap_nz] = self.tap_normal.map(|row| &row[..len]);
        let [centre_ar, centre_ag, centre_ab] = self.centre_albedo.map(|row| &row[..len]);
        let [tap_ar, tap_ag, tap_ab] = self.tap_albedo.map(|row| &row[..len]);
        let [tap_red, tap_green, tap_blue, tap_variance] = self.tap_signal.map(|row| &row[..len]);
        let (centre_depth, tap_depth) = (&self.centre_depth[..len], &self.tap_depth[..len]);
        let (centre_instance, tap_instance) =
            (&self.centre_instance[..len], &self.tap_instance[..len]);
        let (centre_luminance, tap_luminance, luminance_scale, depth_scale) = (
            &self.centre_luminance[..len],
            &self.tap_luminance[..len],
            &self.luminance_scale[..len],
            &self.depth_scale[..len],
        );
        let (sum_red, sum_green, sum_blue, sum_variance) = (
            &mut sum_red[..len],
            &mut sum_green[..len],
            &mut sum_blue[..len],
            &mut sum_variance[..len],
        );
        let (kernel, albedo_scale) = (self.kernel, self.albedo_scale);
        for i in 0..len {
            let same_instance = if centre_instance[i] == tap_instance[i] {
                1.0
            } else {
                0.0
            };
            let cosine =
                centre_nx[i] * tap_nx[i] + centre_ny[i] * tap_ny[i] + centre_nz[i] * tap_nz[i];
            let albedo_distance = (centre_ar[i] - tap_ar[i]).abs()
                + (centre_ag[i] - tap_ag[i]).abs()
                + (centre_ab[i] - tap_ab[i]).abs();
            let exponent = (centre_depth[i] - tap_depth[i]).abs() * depth_scale[i]
                + (centre_luminance[i] - tap_luminance[i]).abs() * luminance_scale[i]
                + albedo_distance * albedo_scale
                + NORMAL_SHARPNESS * (1.0 - cosine);
            let weight = kernel * same_instance * fast_exp(-exponent);
            sum_red[i] += tap_red[i] * weight;
            sum_green[i] += tap_green[i] * weight;
            sum_blue[i] += tap_blue[i] * weight;
            if CARRY_VARIANCE {
                sum_variance[i] += tap_variance[i] * weight * weight;
            }
            weights[i] += weight;
        }
    }
}

/// The run `first..end` grown, within `bounds`, towards a whole number of vectors of 8
/// lanes: at its end first, then at its start.
fn whole_vectors((first, end): (usize, usize), bounds: (usize, usize)) -> (usize, usize) {
    let short = (8 - (end - first) % 8) % 8;
    let after = short.min(bounds.1.saturating_sub(end));
    let before = (short - after).min(first.saturating_sub(bounds.0));
    (first - before, end + after)
}

/// The longest run of pixels `Pass::taps` takes all 8 taps of before the next run's: the
/// run's centre terms, sums and tap rows stay in L1 across its taps (whole 480-pixel rows
/// spilled to L2 each tap: 5.8 ns a tap against 3.4).
const MAX_CHUNK: usize = 192;

/// The run `Pass::taps` cuts a row of `length` pixels into: equal runs of at most
/// `MAX_CHUNK`, each whole vectors of 8 lanes but the last. Each tap of a run pays its set-up
/// (two dozen slices cut) and a vector's tail done lane by lane, so a short run is dear:
/// 320-pixel rows (640 x 360 at half scale) cut 160 + 160 rather than 128 + 128 + 64 took
/// the spatial filter's p50 from 1.53 to 1.31 ms on first-light, 1.73 to 1.50 on
/// the-gallery and 1.66 to 1.44 on the-keep (`gloam bench`, medians of 3 alternated runs).
fn chunk_length(length: usize) -> usize {
    let chunks = length.div_ceil(MAX_CHUNK).max(1);
    length.div_ceil(chunks).next_multiple_of(8).max(8)
}

/// The normal term's exponent: exp(-128 (1 - n_p . n_q)) is SVGF's (n_p . n_q)^128 to
/// within 1% where the weight matters (at a cosine of 0.99: 0.278 against 0.276; 1 - x <=
/// -ln x, so only already-negligible weights come out larger), and it folds into the one
/// exponential every tap already takes (the seven squarings were 8 of its 111 instructions).
const NORMAL_SHARPNESS: f32 = 128.0;

/// e^x for x <= 0 to about 5e-5 relative: 2^(x log2 e), the whole part put into the
/// exponent bits and a quartic (Taylor) for the fraction in [-1/2, 1/2]. Rounding by
/// adding 1.5 x 2^23 keeps it to plain float and integer lanes, so it vectorises (floor()
/// is a libm call on baseline x86-64, and libm's expf was a third of the filter's time).
#[inline(always)]
fn fast_exp(x: f32) -> f32 {
    const ROUND: f32 = 12_582_912.0;
    let y = (x * std::f32::consts::LOG2_E).clamp(-126.0, 0.0);
    let shifted = y + ROUND;
    let whole = shifted.to_bits() as i32 - ROUND.to_bits() as i32;
    let f = y - (shifted - ROUND);
    let fraction = 1.0
        + f * (std::f32::consts::LN_2 + f * (0.240_226_5 + f * (0.055_504_1 + f * 0.009_618_1)));
    f32::from_bits((fraction.to_bits() as i32 + (whole << 23)) as u32)
}

/// Row `y` of the variance under a 3 x 3 Gaussian (1/4, 1/2, 1/4 per axis), over non-sky pixels:
/// SVGF's prefilter, so one noisy variance estimate does not decide a weight. Each pixel
/// sums its nine taps in registers, row by row and left to right, with a row past the
/// film's top or bottom read as `past_edge` (zero variance, sky): that adds +0 to sums that
/// are never -0, the bits of leaving the row out. (As nine passes over the row, each
/// reading and writing the row's sums and weights, the spatial filter ran 1% more
/// instructions: 131.8 M against 130.5 M over 7 frames of first-light at 320 x 180.)
#[inline(always)]
fn blur_variance_row(
    input: &PlaneRows<'_, SIGNAL_PLANES>,
    guides: &Guides,
    y: usize,
    past_edge: (&[f32], &[u32]),
    out: &mut [f32],
) {
    let (width, height) = (guides.width as usize, guides.height as usize);
    let instances = guides.instances();
    let out = &mut out[..width];
    // wrapping_sub turns -1 into usize::MAX, which fails the bound.
    let row = |tap_y: usize| -> (&[f32], &[u32]) {
        match tap_y < height {
            true => (
                &input.row(tap_y, VARIANCE)[..width],
                &instances[tap_y * width..][..width],
            ),
            false => (&past_edge.0[..width], &past_edge.1[..width]),
        }
    };
    let rows = [row(y.wrapping_sub(1)), row(y), row(y + 1)];
    let weight_of = |instance: u32, kernel: f32| {
        if instance == NO_INSTANCE { 0.0 } else { kernel }
    };
    let normalised = |sum: f32, weight: f32| if weight > 0.0 { sum / weight } else { 0.0 };
    // The film's first and last pixels, their taps off the row left out.
    for x in [0, width.saturating_sub(1)].into_iter().take(width.min(2)) {
        let (mut sum, mut weight) = (0.0f32, 0.0f32);
        for (ky, (variance, instance)) in rows.iter().enumerate() {
            for (kx, tap) in [x.wrapping_sub(1), x, x + 1].into_iter().enumerate() {
                if tap < width {
                    let w = weight_of(instance[tap], KERNEL[kx] * KERNEL[ky]);
                    sum += variance[tap] * w;
                    weight += w;
                }
            }
        }
        out[x] = normalised(sum, weight);
    }
    // The rest, every tap inside the row: each tap's rows cut to line up with the centres
    // (no index arithmetic in the loop, so it vectorises).
    if width < 3 {
        return;
    }
    let inner = width - 2;
    let taps = rows.map(|(variance, instance)| {
        [0, 1, 2].map(|kx| (&variance[kx..kx + inner], &instance[kx..kx + inner]))
    });
    let out = &mut out[1..1 + inner];
    for x in 0..inner {
        let (mut sum, mut weight) = (0.0f32, 0.0f32);
        for (ky, row) in taps.iter().enumerate() {
            for (kx, (variance, instance)) in row.iter().enumerate() {
                let w = weight_of(instance[x], KERNEL[kx] * KERNEL[ky]);
                sum += variance[x] * w;
                weight += w;
            }
        }
        out[x] = normalised(sum, weight);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::guides::GuidePixel;
    use glam::Vec3A;

    fn flat_guides(width: u32, height: u32) -> Guides {
        Guides::from_pixels(width, height, &flat_pixels(width, height))
    }

    fn flat_pixels(width: u32, height: u32) -> Vec<GuidePixel> {
        let mut pixels = vec![GuidePixel::SKY; (width * height) as usize];
        for g in &mut pixels {
            *g = GuidePixel {
                position: Vec3A::ZERO,
                normal: Vec3A::Z,
                depth: 3.0,
                instance: 0,
                albedo: Vec3::splat(0.5),
                unfiltered: Vec3::ZERO,
            };
        }
        pixels
    }

    /// A fixed pseudo-random sequence in [0, 1).
    fn noise(i: usize) -> f32 {
        let mut h = (i as u32).wrapping_mul(0x9e37_79b9) ^ 0x5bd1_e995;
        h ^= h >> 15;
        h = h.wrapping_mul(0x2c1b_3c6d);
        h ^= h >> 12;
        (h >> 8) as f32 / (1u32 << 24) as f32
    }

    #[test]
    fn the_variance_prefilter_gives_the_bits_of_adding_its_taps_a_pass_each() {
        // The prefilter as nine passes over the row, each tap added into the row's sums
        // where it lies inside the film (the definition the one pass must match).
        fn tap_by_tap(input: &SignalPlanes, guides: &Guides, y: usize) -> Vec<f32> {
            let (width, height) = (guides.width as usize, guides.height as usize);
            let (mut sums, mut weights) = (vec![0.0f32; width], vec![0.0f32; width]);
            for (ky, tap_y) in [y.wrapping_sub(1), y, y + 1].into_iter().enumerate() {
                if tap_y >= height {
                    continue;
                }
                for (kx, shift) in [-1isize, 0, 1].into_iter().enumerate() {
                    for x in 0..width {
                        let tap_x = x as isize + shift;
                        if tap_x < 0 || tap_x >= width as isize {
                            continue;
                        }
                        let tap = tap_y * width + tap_x as usize;
                        let w = match guides.instances()[tap] {
                            NO_INSTANCE => 0.0,
                            _ => KERNEL[kx] * KERNEL[ky],
                        };
                        sums[x] += input.row(tap_y, VARIANCE)[tap_x as usize] * w;
                        weights[x] += w;
                    }
                }
            }
            (0..width)
                .map(|x| match weights[x] > 0.0 {
                    true => sums[x] / weights[x],
                    false => 0.0,
                })
                .collect()
        }
        for (width, height) in [(1u32, 1u32), (2, 3), (3, 2), (37, 5)] {
            let mut pixels = flat_pixels(width, height);
            for (p, g) in pixels.iter_mut().enumerate() {
                if p % 7 == 3 || p % 11 == 0 {
                    *g = GuidePixel::SKY;
                }
            }
            let guides = Guides::from_pixels(width, height, &pixels);
            let count = (width * height) as usize;
            let variance: Vec<f32> = (0..count)
                .map(|i| match pixels[i].instance {
                    NO_INSTANCE => 0.0,
                    _ => noise(i) * 4.0,
                })
                .collect();
            let input =
                SignalPlanes::from_pixels(&vec![Vec3::ONE; count], &variance, width as usize);
            let past_edge = (vec![0.0; width as usize], vec![NO_INSTANCE; width as usize]);
            for y in 0..height as usize {
                let mut one_pass = vec![f32::NAN; width as usize];
                let edge = (&past_edge.0[..], &past_edge.1[..]);
                blur_variance_row(&PlaneRows::of(&input), &guides, y, edge, &mut one_pass);
                let expected = tap_by_tap(&input, &guides, y);
                assert_eq!(
                    one_pass.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                    expected.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                    "{width} x {height}, row {y}"
                );
            }
        }
    }

    #[test]
    fn a_lower_render_scale_runs_fewer_passes_that_reach_as_far_on_screen() {
        let settings = AtrousSettings::default();
        assert_eq!(settings.iterations, 3);
        // Reach on screen, 2^(n+1) - 1 render pixels of 1 / scale shown pixels each.
        let reach =
            |scale: f32| ((1u32 << (settings.iterations_at_scale(scale) + 1)) - 1) as f32 / scale;
        for (scale, passes) in [(1.0, 3), (1.5, 3), (0.75, 3), (0.7, 2), (0.5, 2), (0.4, 2)] {
            assert_eq!(settings.iterations_at_scale(scale), passes, "scale {scale}");
        }
        assert!((reach(0.5) - reach(1.0)).abs() <= 1.0);
        // Never fewer than one pass, and none stays none.
        assert_eq!(settings.iterations_at_scale(0.1), 1);
        let off = AtrousSettings {
            iterations: 0,
            ..AtrousSettings::default()
        };
        assert_eq!(off.iterations_at_scale(0.5), 0);
        assert_eq!(settings.iterations_at_scale(f32::NAN), 3);
    }

    #[test]
    fn rows_are_cut_into_equal_runs_of_whole_vectors() {
        for (length, expected) in [(320, 160), (480, 160), (640, 160), (256, 128), (384, 192)] {
            assert_eq!(chunk_length(length), expected, "{length} pixels");
        }
        for length in 0..2000 {
            let chunk = chunk_length(length);
            assert!(chunk % 8 == 0 && chunk <= MAX_CHUNK, "{length}: {chunk}");
            // No more runs than the fewest that fit, so none is needlessly short.
            assert_eq!(
                length.div_ceil(chunk),
                length.div_ceil(MAX_CHUNK),
                "{length}"
            );
        }
    }

    #[test]
    fn a_run_grows_over_its_bounds_to_whole_vectors() {
        // Room after the run: it grows there.
        assert_eq!(whole_vectors((10, 21), (0, 160)), (10, 26));
        // Only three lanes of room after: the other two before.
        assert_eq!(whole_vectors((10, 21), (0, 24)), (8, 24));
        // Already whole, or no room at all: unchanged.
        assert_eq!(whole_vectors((8, 24), (0, 160)), (8, 24));
        assert_eq!(whole_vectors((1, 160), (1, 160)), (1, 160));
        for first in 0..20 {
            for end in first + 1..40 {
                for (low, high) in [(0, 40), (first, 40), (0, end), (first / 2, end + 3)] {
                    let (grown_first, grown_end) = whole_vectors((first, end), (low, high));
                    assert!(grown_first <= first && end <= grown_end, "contains the run");
                    assert!(low <= grown_first && grown_end <= high, "within the bounds");
                    let room = high - low;
                    let whole = (grown_end - grown_first) % 8 == 0;
                    assert!(
                        whole || grown_end - grown_first == room,
                        "whole unless bounded"
                    );
                }
            }
        }
    }

    #[test]
    fn fast_exp_is_close_to_exp() {
        for i in 0..2000 {
            let x = -(i as f32) * 0.01;
            let (fast, exact) = (fast_exp(x), x.exp());
            assert!(
                (fast - exact).abs() <= 2e-4 * exact + 1e-30,
                "{x}: {fast} vs {exact}"
            );
        }
        assert_eq!(fast_exp(-1e9), fast_exp(-126.0 / std::f32::consts::LOG2_E));
    }

    #[test]
    fn noise_on_a_flat_wall_is_smoothed_and_its_mean_kept() {
        let guides = flat_guides(64, 64);
        let illumination: Vec<Vec3> = (0..64 * 64).map(|i| Vec3::splat(noise(i))).collect();
        let variance = vec![1.0 / 12.0; 64 * 64];
        let out = filter(
            &illumination,
            &variance,
            &guides,
            &AtrousSettings::default(),
        );
        let mean = |v: &[Vec3]| v.iter().map(|c| c.x).sum::<f32>() / v.len() as f32;
        let spread = |v: &[Vec3]| {
            let m = mean(v);
            (v.iter().map(|c| (c.x - m).powi(2)).sum::<f32>() / v.len() as f32).sqrt()
        };
        assert!((mean(&out.illumination) - mean(&illumination)).abs() < 0.01);
        // Uniform noise has a deviation of 0.29; the passes take it well below a third.
        assert!(
            spread(&out.illumination) < spread(&illumination) / 3.0,
            "{} -> {}",
            spread(&illumination),
            spread(&out.illumination)
        );
    }

    /// Guides with edges of every kind (depth, normal, albedo, instance) and some sky, and
    /// noisy illumination and variance over them.
    fn edged_scene(width: u32, height: u32) -> (Guides, Vec<Vec3>, Vec<f32>) {
        let mut pixels = flat_pixels(width, height);
        for (p, g) in pixels.iter_mut().enumerate() {
            let x = p as u32 % width;
            g.depth = 2.0 + noise(p + 7) + x as f32 * 0.1;
            g.normal = Vec3A::new(noise(p + 3) - 0.5, 0.3, 1.0).normalize();
            g.albedo = Vec3::new(noise(p + 11), 0.5, 0.25);
            g.instance = (x / 9) % 3;
            if p % 29 == 0 {
                *g = GuidePixel::SKY;
            }
        }
        let count = (width * height) as usize;
        let illumination = (0..count)
            .map(|i| Vec3::new(noise(i), noise(i + 1), noise(i + 2)) * 3.0)
            .collect();
        let variance = (0..count).map(|i| noise(i + 5)).collect();
        (
            Guides::from_pixels(width, height, &pixels),
            illumination,
            variance,
        )
    }

    /// The passes run as a chain of bands (film/chain.rs) give, on any thread count, the
    /// bits they give on one thread, where the chain runs them a pass at a time: the
    /// outputs, and every row each pass hands on. Five passes, so the widest taps reach
    /// two bands away and the outputs' and luminance buffers are written again while the
    /// image is taller than the threads' segments.
    #[test]
    fn chained_passes_give_the_same_bits_on_any_thread_count() {
        let (width, height) = (67u32, 61u32);
        let (guides, illumination, variance) = edged_scene(width, height);
        let input = SignalPlanes::from_pixels(&illumination, &variance, width as usize);
        let settings = AtrousSettings {
            iterations: 5,
            ..AtrousSettings::default()
        };
        let on = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("a thread pool");
            let handed = std::sync::Mutex::new(Vec::new());
            let mut workspace = Workspace::default();
            let (filtered, first) = pool.install(|| {
                let output = filter_with(
                    &mut workspace,
                    Input::Whole(&input),
                    &guides,
                    &settings,
                    |row| {
                        let rows = row.illumination.map(<[f32]>::to_vec);
                        (handed.lock().expect("no panics")).push((row.iteration, row.y, rows));
                    },
                );
                (
                    output.illumination.colours(),
                    output.first_iteration.colours(),
                )
            });
            let mut handed = handed.into_inner().expect("no panics");
            handed.sort_by_key(|&(iteration, y, _)| (iteration, y));
            (filtered, first, handed)
        };
        let one = on(1);
        assert_eq!(
            one.2.len(),
            5 * height as usize,
            "every pass hands on every row"
        );
        for threads in [2, 3, 4] {
            assert!(on(threads) == one, "{threads} threads");
        }
    }

    #[test]
    fn portable_and_avx2_rows_give_identical_images() {
        // Edges of every kind, noise, sky and odd widths (partial lanes at row ends; at 37
        // the wider passes' taps leave the row for most pixels, at 101 for few).
        for width in [37u32, 101] {
            let height = 23u32;
            let (guides, illumination, variance) = edged_scene(width, height);
            let settings = AtrousSettings {
                iterations: 5,
                ..AtrousSettings::default()
            };
            let mut portable = Workspace {
                portable_only: true,
                ..Workspace::default()
            };
            let input = SignalPlanes::from_pixels(&illumination, &variance, width as usize);
            let a = filter_with(
                &mut portable,
                Input::Whole(&input),
                &guides,
                &settings,
                |_| {},
            );
            let (a_illumination, a_first) = (a.illumination.colours(), a.first_iteration.colours());
            let b = filter(&illumination, &variance, &guides, &settings);
            assert!(a_illumination.iter().all(|c| c.is_finite()));
            assert_eq!(a_illumination, b.illumination, "{width} wide");
            assert_eq!(a_first, b.first_iteration, "{width} wide");
            // The iterations' outputs are rotated through three buffers: the first is kept.
            let first_only = filter(
                &illumination,
                &variance,
                &guides,
                &AtrousSettings {
                    iterations: 1,
                    ..settings.clone()
                },
            );
            assert_eq!(first_only.illumination, b.first_iteration);
            assert_ne!(b.illumination, b.first_iteration);
        }
    }

    #[test]
    fn skipping_the_sky_leaves_every_surface_pixel_as_filtering_it_would() {
        // Runs of surface between sky, across the tap loop's 128-pixel chunks, and whole
        // rows of sky. Against the same image with another instance where the sky was:
        // taps there weigh zero either way, so a surface pixel the skip missed would differ.
        let (width, height) = (300u32, 20u32);
        let is_surface = |x: u32, y: u32| {
            y >= 4 && ((40..200).contains(&x) || (250..261).contains(&x) || x == 299)
        };
        let mut with_sky = flat_pixels(width, height);
        let mut with_wall = flat_pixels(width, height);
        for (p, (sky, wall)) in with_sky.iter_mut().zip(&mut with_wall).enumerate() {
            let (x, y) = (p as u32 % width, p as u32 / width);
            for g in [&mut *sky, &mut *wall] {
                g.depth = 2.0 + 0.5 * noise(p + 7);
            }
            if !is_surface(x, y) {
                *sky = GuidePixel::SKY;
                wall.instance = 1;
            }
        }
        let count = (width * height) as usize;
        let illumination: Vec<Vec3> = (0..count)
            .map(|i| Vec3::new(noise(i), noise(i + 1), noise(i + 2)))
            .collect();
        // One variance everywhere (a power of two, so its 3 x 3 prefilter gives it back
        // exactly): the prefilter skips the sky but not another instance.
        let variance = vec![0.25; count];
        let filtered = |pixels: &[GuidePixel]| {
            let guides = Guides::from_pixels(width, height, pixels);
            filter(
                &illumination,
                &variance,
                &guides,
                &AtrousSettings::default(),
            )
        };
        let (sky, wall) = (filtered(&with_sky), filtered(&with_wall));
        for p in 0..count {
            let (x, y) = (p as u32 % width, p as u32 / width);
            if is_surface(x, y) {
                assert_eq!(sky.illumination[p], wall.illumination[p], "({x}, {y})");
                assert_eq!(
                    sky.first_iteration[p], wall.first_iteration[p],
                    "({x}, {y})"
                );
                assert_ne!(
                    sky.illumination[p], illumination[p],
                    "({x}, {y}) unfiltered"
                );
            } else {
                assert_eq!(
                    sky.illumination[p], illumination[p],
                    "the sky keeps its value"
                );
            }
        }
    }

    #[test]
    fn edges_in_normal_depth_albedo_and_instance_are_kept() {
        for edge in ["normal", "depth", "albedo", "instance"] {
            let mut pixels = flat_pixels(32, 32);
            let mut illumination = vec![Vec3::splat(0.2); 32 * 32];
            for p in 0..32 * 32 {
                if p % 32 >= 16 {
                    illumination[p] = Vec3::splat(1.0);
                    let g = &mut pixels[p];
                    match edge {
                        "normal" => g.normal = Vec3A::X,
                        "depth" => g.depth = 6.0,
                        "albedo" => g.albedo = Vec3::splat(0.9),
                        _ => g.instance = 1,
                    }
                }
            }
            let guides = Guides::from_pixels(32, 32, &pixels);
            let out = filter(
                &illumination,
                &vec![100.0; 32 * 32],
                &guides,
                &AtrousSettings::default(),
            );
            // Next to the edge, on either side, the other side does not leak in.
            assert!(
                (out.illumination[10 * 32 + 15].x - 0.2).abs() < 0.01,
                "{edge}"
            );
            assert!(
                (out.illumination[10 * 32 + 16].x - 1.0).abs() < 0.01,
                "{edge}"
            );
        }
    }
}
