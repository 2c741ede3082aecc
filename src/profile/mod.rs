//! Profiling: what every stage of every frame cost, summarised and written as reports.
//!
//! Not a step of the frame but a witness to all of them. `Stage` names the frame's stages
//! once; the frame driver's `StageTimes` (filled by its timers and by the extract systems
//! that time their own parts) becomes one `FrameSample` per frame, and a `Profile` of them
//! is what `gloam bench` prints and writes:
//! - JSON (its schema: [`crate::headless::bench`]): per stage and per frame the mean, p50,
//!   p95, p99 and max milliseconds, Mrays/s, rays per frame;
//! - CSV (`--csv`), a row per frame and a column per stage and phase;
//! - a Chrome trace (`--trace`, the JSON "Trace Event Format"), which Perfetto
//!   (ui.perfetto.dev) and chrome://tracing open: a track of frames, a track of their
//!   stages with the phases nested inside, and a track per render thread holding the tiles
//!   it traced (the last `TRACE_TILE_FRAMES` frames' tiles, to keep the file loadable);
//! - a PNG chart (`--chart`, [`chart`]): the stages stacked per frame over time, the timed
//!   phases in shades of their stage's colour, the frame budget marked, over a histogram of
//!   frame times.
//!
//! [`overlay`] draws the same statistics live over the game's frame (F3).
//!
//! Depends on nothing above it: plain numbers in, files and pixels out.
//!
//! # Live profiling in Tracy or puffin
//!
//! The frame stages, the render phases (`render.primary`, `render.shade`, `render.shadow`,
//! `render.bounces`, per tile and thread) and obvhs's own build scopes are `profiling`
//! crate scopes, which compile to nothing in a normal build. Build with a feature to see
//! them live ([`start_live_profiler`]):
//!
//! ```sh
//! # then connect the Tracy profiler (v0.14, the protocol tracy-client 0.18 speaks)
//! cargo run --release --features profile-with-tracy
//! # then `puffin_viewer` (cargo install puffin_viewer), served on 127.0.0.1:8585
//! cargo run --release --features profile-with-puffin
//! ```
//!
//! Any command works with them, e.g. `cargo run --release --features profile-with-tracy --
//! bench --frames 600` for a long, steady capture.

use std::path::Path;

use anyhow::Context as _;
use serde_json::{Value, json};

use crate::scene::files::write_atomically;

pub mod chart;
pub mod overlay;

/// The live profiler a `profile-with-*` feature built in, running while this value lives.
/// Without those features there is none, and every `profiling::scope!` compiles to nothing.
pub struct LiveProfiler {
    #[cfg(feature = "profile-with-puffin")]
    _server: puffin_http::Server,
}

/// Where `profile-with-puffin` serves its scopes for puffin_viewer.
pub const PUFFIN_ADDRESS: &str = "127.0.0.1:8585";

/// Starts the live profiler, if one was built in: Tracy's client (the Tracy profiler then
/// connects to this process), or puffin's recorder and its server at `PUFFIN_ADDRESS`.
pub fn start_live_profiler() -> anyhow::Result<Option<LiveProfiler>> {
    #[cfg(feature = "profile-with-tracy")]
    {
        profiling::tracy_client::Client::start();
        eprintln!("gloam: Tracy client running; connect with the Tracy profiler");
        return Ok(Some(LiveProfiler {}));
    }
    #[cfg(feature = "profile-with-puffin")]
    {
        profiling::puffin::set_scopes_on(true);
        let server = puffin_http::Server::new(PUFFIN_ADDRESS).map_err(|error| {
            anyhow::anyhow!("starting the puffin server on {PUFFIN_ADDRESS}: {error}")
        })?;
        eprintln!("gloam: puffin scopes served on {PUFFIN_ADDRESS}; connect with puffin_viewer");
        return Ok(Some(LiveProfiler { _server: server }));
    }
    #[allow(unreachable_code)]
    Ok(None)
}

/// The stages of a frame, in the order they run: the one list the frame driver's schedules
/// and timers, `StageTimes`, every report (table, JSON, CSV, trace, chart) and the F3
/// overlay are indexed by. The frame line of the crate's front page, with `transforms` and
/// `extract` timed apart from their neighbours.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Stage {
    /// Input actions applied, last step's transforms remembered (fixed steps).
    Input,
    /// Gameplay systems (fixed steps).
    Gameplay,
    /// Clip and deformer clocks and sampling (fixed steps), plus the frame's skinning,
    /// morph targets and procedural deformers.
    Animation,
    /// Transform propagation down the hierarchy (fixed steps).
    Transforms,
    /// What the player's ears hear of each fixed step (`audio::Hearing`: sources, events
    /// and the room through the level's acoustics); 0 where nothing listens.
    Audio,
    /// The ECS made into the `RenderScene`: spawned, despawned, moved and changed things.
    Extract,
    /// Refitting (or rebuilding) the deformed meshes' BLASes.
    BlasRefit,
    /// Rebuilding the TLAS (and re-forming static batches), emitters following their
    /// instances.
    TlasBuild,
    Render,
    /// The film: accumulation, or the real-time filters.
    Film,
    /// Tone mapping into the window's buffer and presenting it (0 headless).
    Present,
}

impl Stage {
    pub const COUNT: usize = 11;
    pub const ALL: [Stage; Stage::COUNT] = [
        Stage::Input,
        Stage::Gameplay,
        Stage::Animation,
        Stage::Transforms,
        Stage::Audio,
        Stage::Extract,
        Stage::BlasRefit,
        Stage::TlasBuild,
        Stage::Render,
        Stage::Film,
        Stage::Present,
    ];
    /// The simulation's stages, run once per fixed step in this order.
    pub const FIXED_STEP: [Stage; 4] = [
        Stage::Input,
        Stage::Gameplay,
        Stage::Animation,
        Stage::Transforms,
    ];

    /// The stage's name in every report.
    pub const fn name(self) -> &'static str {
        match self {
            Stage::Input => "input",
            Stage::Gameplay => "gameplay",
            Stage::Animation => "animation",
            Stage::Transforms => "transforms",
            Stage::Audio => "audio",
            Stage::Extract => "extract",
            Stage::BlasRefit => "blas_refit",
            Stage::TlasBuild => "tlas_build",
            Stage::Render => "render",
            Stage::Film => "film",
            Stage::Present => "present",
        }
    }

    pub const fn index(self) -> usize {
        self as usize
    }
}

/// `Stage::ALL`'s names, in order.
pub const STAGES: [&str; Stage::COUNT] = {
    let mut names = [""; Stage::COUNT];
    let mut index = 0;
    while index < Stage::COUNT {
        names[index] = Stage::ALL[index].name();
        index += 1;
    }
    names
};

/// What each stage of the frame being run cost so far, and the rays it traced: the frame
/// driver clears it, the schedules' systems and the driver's timers add to it, and it
/// becomes the frame's `FrameSample`. A resource, so extract's systems can add the parts
/// they time themselves (deforming under `Animation`, refits under `BlasRefit`).
#[derive(bevy_ecs::resource::Resource, Clone, Copy, Debug, Default, PartialEq)]
pub struct StageTimes {
    /// Milliseconds per stage (`Stage::index`); the fixed steps' stages sum over every
    /// step the frame ran.
    pub ms: [f64; Stage::COUNT],
    /// The render's wall time split over its phases (`RENDER_PHASES`) in proportion to
    /// the CPU time each took on the tiles' threads.
    pub render_phases: [f64; RENDER_PHASES.len()],
    /// The film's wall time split over its steps (`FILM_PHASES`).
    pub film_phases: [f64; FILM_PHASES.len()],
    /// The gameplay stage's timed parts (`GameplayPhase`; `Rest` is filled in by `sample`).
    pub gameplay_phases: [f64; GAMEPLAY_PHASES.len()],
    /// Rays the render traced, by kind.
    pub rays: RayMix,
    /// Paths the radiance cache ended at their second vertex.
    pub cache_ended: u64,
    /// Milliseconds the radiance cache took to learn the frame before (in the background,
    /// off the frame's own stages: `film::Accumulation`).
    pub cache_learn_ms: f64,
    /// Fixed simulation steps the frame ran (the real time it simulated, in 1/60 s steps).
    pub steps: u32,
}

/// The rays a frame's render traced, by kind.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RayMix {
    pub camera: u64,
    pub shadow: u64,
    pub bounce: u64,
}

impl RayMix {
    pub fn total(&self) -> u64 {
        self.camera + self.shadow + self.bounce
    }
}

impl StageTimes {
    /// Adds `ms` to a timed part of the gameplay stage (the stage's total is timed apart).
    pub fn add_gameplay(&mut self, phase: GameplayPhase, ms: f64) {
        self.gameplay_phases[phase as usize] += ms;
    }

    pub fn add(&mut self, stage: Stage, ms: f64) {
        self.ms[stage.index()] += ms;
    }

    pub fn get(&self, stage: Stage) -> f64 {
        self.ms[stage.index()]
    }

    /// This frame as a profile sample, with the shell's own `present` and whole-frame times.
    pub fn sample(&self, present_ms: f64, frame_ms: f64) -> FrameSample {
        let mut stages = self.ms;
        stages[Stage::Present.index()] = present_ms;
        let mut gameplay_phases = self.gameplay_phases;
        let timed: f64 = gameplay_phases[..GameplayPhase::Rest as usize].iter().sum();
        gameplay_phases[GameplayPhase::Rest as usize] =
            (stages[Stage::Gameplay.index()] - timed).max(0.0);
        FrameSample {
            stages,
            render_phases: self.render_phases,
            film_phases: self.film_phases,
            gameplay_phases,
            frame_ms,
            rays: self.rays,
            cache_ended: self.cache_ended,
            cache_learn_ms: self.cache_learn_ms,
            steps: self.steps,
            tiles: Vec::new(),
        }
    }
}

/// Milliseconds since `start`.
pub fn since(start: std::time::Instant) -> f64 {
    start.elapsed().as_secs_f64() * 1e3
}

/// The parts of the gameplay stage timed apart, nested under it as `gameplay.<part>`:
/// bringing the simulation's copy of the level up to date, the light gem's shadow rays,
/// the wardens' sight (rays and minds), and everything else (the player's body, the goal,
/// the wardens' feet and paths).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GameplayPhase {
    World,
    Exposure,
    Sight,
    Rest,
}

impl GameplayPhase {
    pub const ALL: [GameplayPhase; 4] = [
        GameplayPhase::World,
        GameplayPhase::Exposure,
        GameplayPhase::Sight,
        GameplayPhase::Rest,
    ];

    pub const fn name(self) -> &'static str {
        match self {
            GameplayPhase::World => "world",
            GameplayPhase::Exposure => "exposure",
            GameplayPhase::Sight => "sight",
            GameplayPhase::Rest => "rest",
        }
    }
}

/// `GameplayPhase` names, in order.
pub const GAMEPLAY_PHASES: [&str; GameplayPhase::ALL.len()] = {
    let mut names = [""; GameplayPhase::ALL.len()];
    let mut index = 0;
    while index < names.len() {
        names[index] = GameplayPhase::ALL[index].name();
        index += 1;
    }
    names
};

/// The phases inside `render` (render/mod.rs's wavefront over each tile), nested under it
/// in every report as `render.<phase>`. The same names as `render::PhaseTimes::NAMES`
/// (a test holds them equal; the profiler depends on nothing above it).
pub const RENDER_PHASES: [&str; 4] = ["primary", "shade", "shadow", "bounces"];

/// The steps inside `film` (film/denoise.rs's filter chain), nested under it as
/// `film.<step>`: the same names as `render::FilmPhaseTimes::NAMES`.
pub const FILM_PHASES: [&str; 4] = ["temporal", "spatial", "remodulate", "upscale"];

/// A frame's phase times of a stage that has phases: `gameplay`'s, `render`'s or `film`'s.
type PhasesOf = fn(&FrameSample) -> &[f64];

/// The stages timed in phases, with their phase names, in `STAGES` order.
pub(crate) const NESTED: [(&str, &[&str], PhasesOf); 3] = [
    ("gameplay", &GAMEPLAY_PHASES, |frame| &frame.gameplay_phases),
    ("render", &RENDER_PHASES, |frame| &frame.render_phases),
    ("film", &FILM_PHASES, |frame| &frame.film_phases),
];

/// `stage`'s phase names and how to read a frame's phase times, if it has phases.
fn phases_of(stage: &str) -> Option<(&'static [&'static str], PhasesOf)> {
    NESTED
        .iter()
        .find(|(name, _, _)| *name == stage)
        .map(|&(_, names, times)| (names, times))
}

/// The frame budget the F3 overlay and the bench chart mark, in ms (30 fps).
pub const BUDGET_MS: f64 = 1000.0 / 30.0;

/// The trace holds the tiles of this many frames at most (the last ones): at 640 x 360 a
/// frame has 900 tiles, and a trace of every frame of a long bench would not load.
pub const TRACE_TILE_FRAMES: usize = 120;

/// One tile of a render: the worker thread that traced it and when, in ms from the start of
/// the render (the trace's per-thread tracks).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TileSpan {
    pub thread: u16,
    pub start_ms: f32,
    pub end_ms: f32,
}

/// One frame: milliseconds per stage (in `STAGES` order), the whole frame, and rays traced.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameSample {
    pub stages: [f64; STAGES.len()],
    /// The render stage's milliseconds per phase (`RENDER_PHASES`), summing to it: the
    /// wall time shared out by each phase's CPU time over the threads.
    pub render_phases: [f64; RENDER_PHASES.len()],
    /// The film stage's milliseconds per step (`FILM_PHASES`), summing to it (zero when no
    /// filter ran).
    pub film_phases: [f64; FILM_PHASES.len()],
    /// The gameplay stage's milliseconds per part (`GAMEPLAY_PHASES`), summing to it.
    pub gameplay_phases: [f64; GAMEPLAY_PHASES.len()],
    pub frame_ms: f64,
    pub rays: RayMix,
    /// Paths the radiance cache ended at their second vertex.
    pub cache_ended: u64,
    /// Milliseconds the radiance cache took to learn the frame before, in the background.
    pub cache_learn_ms: f64,
    /// Fixed simulation steps the frame ran.
    pub steps: u32,
    /// The render's tiles, as `frame::Engine::tile_spans` gives them; `bench` keeps them,
    /// the window's running profile does not (they would grow by 900 a frame).
    pub tiles: Vec<TileSpan>,
}

/// Order statistics of one series, in milliseconds.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Summary {
    pub mean: f64,
    pub p50: f64,
    pub p95: f64,
    pub p99: f64,
    pub max: f64,
}

impl Summary {
    /// Nearest-rank percentiles (the smallest value with at least p% of the series at or
    /// below it), so every reported figure is a frame that happened.
    pub fn of(values: &[f64]) -> Summary {
        if values.is_empty() {
            return Summary::default();
        }
        let mut sorted = values.to_vec();
        sorted.sort_by(f64::total_cmp);
        let rank = |p: f64| {
            let index = ((p / 100.0) * sorted.len() as f64).ceil() as usize;
            sorted[index.clamp(1, sorted.len()) - 1]
        };
        Summary {
            mean: sorted.iter().sum::<f64>() / sorted.len() as f64,
            p50: rank(50.0),
            p95: rank(95.0),
            p99: rank(99.0),
            max: sorted[sorted.len() - 1],
        }
    }

    fn json(&self) -> Value {
        json!({
            "mean_ms": self.mean,
            "p50_ms": self.p50,
            "p95_ms": self.p95,
            "p99_ms": self.p99,
            "max_ms": self.max,
        })
    }
}

/// A run of frames and what it ran on.
#[derive(Clone, Debug, Default)]
pub struct Profile {
    pub scene: String,
    /// The resolution shown ...
    pub width: u32,
    pub height: u32,
    /// ... and rendered (below the shown, the film upscales; None: the same).
    pub render_size: Option<(u32, u32)>,
    pub threads: usize,
    pub frames: Vec<FrameSample>,
    /// What the level's accel alone traces on the same threads, set beside the
    /// renderer's rays per second: `gloam bench` times a round between windows of frames,
    /// so on a loaded machine both sides of each ratio see the same load.
    pub accel_rounds: Vec<AccelRound>,
    /// Whose eyes the frames were seen through (`gloam bench --view`: "player" or
    /// "camera"), when a bench run says.
    pub view: Option<String>,
    /// The play-through's inputs: a recording's path, or "autoplay" (the bot's run).
    pub replay: Option<String>,
}

/// How much of a run's time went to the film (`Profile::film_share`), as fractions of
/// the frames' time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FilmShare {
    /// The whole film stage: the filters and, rendering below the shown resolution, the
    /// upscaler.
    pub film: f64,
    /// The upscaler alone.
    pub upscale: f64,
}

/// The render's rays and what tracing them alone costs (`Profile::tracing`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tracing {
    /// Camera, shadow and bounce rays a frame, means over the frames.
    pub rays: [f64; 3],
    /// Milliseconds a frame the accel alone takes to trace them, and that as a share of the
    /// render's time: medians over the windows of frames beside the accel's rounds.
    pub ms: f64,
    pub share_of_render: f64,
}

/// One timing of the accel alone, after the window of frames it is set beside.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AccelRound {
    /// Measured frames before the round: its window is the frames since the last round.
    pub after_frames: usize,
    pub rays: AccelRays,
}

/// Millions of rays a second the accel traces of each kind, the renderer's way (camera
/// rays in packets, shadow rays in streams, bounce rays one at a time) but with no shading.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AccelRays {
    pub camera: f64,
    pub shadow: f64,
    pub bounce: f64,
}

impl AccelRays {
    /// The harmonic mean of the three: the rate of a frame tracing equally many of each.
    pub fn harmonic_mean(&self) -> f64 {
        let rates = [self.camera, self.shadow, self.bounce];
        if rates.iter().any(|&rate| rate <= 0.0) {
            return 0.0;
        }
        3.0 / rates.iter().map(|rate| 1.0 / rate).sum::<f64>()
    }
}

impl Profile {
    /// Summary of stage `index` over the frames.
    pub fn stage(&self, index: usize) -> Summary {
        let values: Vec<f64> = self.frames.iter().map(|f| f.stages[index]).collect();
        Summary::of(&values)
    }

    fn phase(&self, phases: PhasesOf, index: usize) -> Summary {
        let values: Vec<f64> = self.frames.iter().map(|f| phases(f)[index]).collect();
        Summary::of(&values)
    }

    /// Each stage with phases: its name and a summary per phase, by phase name.
    fn phase_summaries(&self) -> Vec<(&'static str, Vec<(&'static str, Summary)>)> {
        NESTED
            .iter()
            .map(|&(stage, names, times)| {
                let summaries = names
                    .iter()
                    .enumerate()
                    .map(|(index, name)| (*name, self.phase(times, index)))
                    .collect();
                (stage, summaries)
            })
            .collect()
    }

    pub fn frame(&self) -> Summary {
        self.series(|frame| frame.frame_ms)
    }

    /// The order statistics of one figure of every frame.
    fn series(&self, figure: impl Fn(&FrameSample) -> f64) -> Summary {
        let values: Vec<f64> = self.frames.iter().map(figure).collect();
        Summary::of(&values)
    }

    /// Rays traced per second of render stage, in millions.
    pub fn mrays_per_s(&self) -> f64 {
        Self::mrays_per_s_of(&self.frames)
    }

    fn mrays_per_s_of(frames: &[FrameSample]) -> f64 {
        let render = Stage::Render.index();
        let rays: u64 = frames.iter().map(|f| f.rays.total()).sum();
        let seconds: f64 = frames.iter().map(|f| f.stages[render]).sum::<f64>() / 1e3;
        rays as f64 / seconds.max(1e-9) / 1e6
    }

    /// Each accel round with its window of frames, the frames since the round before it
    /// (rounds with no frames before them are left out).
    fn windows(&self) -> Vec<(AccelRound, &[FrameSample])> {
        let mut start = 0;
        let mut windows = Vec::new();
        for round in &self.accel_rounds {
            let end = round.after_frames.min(self.frames.len());
            if end > start {
                windows.push((*round, &self.frames[start..end]));
                start = end;
            }
        }
        windows
    }

    /// Each accel round with the renderer's rays per second over its window of frames.
    fn accel_windows(&self) -> Vec<(AccelRound, f64)> {
        (self.windows().into_iter())
            .map(|(round, frames)| (round, Self::mrays_per_s_of(frames)))
            .collect()
    }

    /// The render's rays by kind, and how long the accel alone takes to trace them (each
    /// kind at its own rate from the round beside the frames) against the render's time:
    /// the render's time less the tracing is what shading the paths costs.
    pub fn tracing(&self) -> Option<Tracing> {
        let render = Stage::Render.index();
        let mut windows = Vec::new();
        for (round, frames) in self.windows() {
            let rates = round.rays;
            if [rates.camera, rates.shadow, rates.bounce]
                .iter()
                .any(|&rate| rate <= 0.0)
            {
                continue;
            }
            // Rays over Mrays/s are microseconds.
            let microseconds: f64 = (frames.iter())
                .map(|frame| {
                    let rays = frame.rays;
                    rays.camera as f64 / rates.camera
                        + rays.shadow as f64 / rates.shadow
                        + rays.bounce as f64 / rates.bounce
                })
                .sum();
            let ms = microseconds / 1e3 / frames.len() as f64;
            let render_ms =
                frames.iter().map(|f| f.stages[render]).sum::<f64>() / frames.len() as f64;
            if render_ms > 0.0 {
                windows.push((ms, ms / render_ms));
            }
        }
        if windows.is_empty() {
            return None;
        }
        let frames = self.frames.len() as f64;
        let mean = |kind: fn(&RayMix) -> u64| {
            self.frames
                .iter()
                .map(|f| kind(&f.rays) as f64)
                .sum::<f64>()
                / frames
        };
        let median = |part: fn(&(f64, f64)) -> f64| {
            Summary::of(&windows.iter().map(part).collect::<Vec<_>>()).p50
        };
        Some(Tracing {
            rays: [mean(|r| r.camera), mean(|r| r.shadow), mean(|r| r.bounce)],
            ms: median(|w| w.0),
            share_of_render: median(|w| w.1),
        })
    }

    /// The accel alone's rates, each the median over the rounds.
    pub fn accel_rays(&self) -> Option<AccelRays> {
        let median_of = |rate: fn(&AccelRays) -> f64| {
            let rates: Vec<f64> = self
                .accel_rounds
                .iter()
                .map(|round| rate(&round.rays))
                .collect();
            Summary::of(&rates).p50
        };
        (!self.accel_rounds.is_empty()).then(|| AccelRays {
            camera: median_of(|rays| rays.camera),
            shadow: median_of(|rays| rays.shadow),
            bounce: median_of(|rays| rays.bounce),
        })
    }

    /// The renderer's rays per second against the harmonic mean of what its accel alone
    /// traces: 1 would be a renderer that costs nothing but its rays. The median over the
    /// rounds of each window's ratio to its own round (a machine whose load changes during
    /// the run moves both sides of a pair together). It counts rays, not work: work saved
    /// together with the rays it would have cast (a path the radiance cache ends at its
    /// second vertex skips its shading and its rays alike) does not raise it, however far
    /// the render's milliseconds fall.
    pub fn renderer_vs_accel(&self) -> Option<f64> {
        let ratios: Vec<f64> = self
            .accel_windows()
            .into_iter()
            .filter_map(|(round, renderer)| {
                let accel = round.rays.harmonic_mean();
                (accel > 0.0).then(|| renderer / accel)
            })
            .collect();
        (!ratios.is_empty()).then(|| Summary::of(&ratios).p50)
    }

    /// The `bench --json` report (its schema: `headless::bench`), and the rays of each frame.
    pub fn to_json(&self) -> Value {
        let stages: serde_json::Map<String, Value> = STAGES
            .iter()
            .enumerate()
            .map(|(index, name)| (name.to_string(), self.stage(index).json()))
            .collect();
        let mut report = json!({
            "scene": self.scene,
            "frames": self.frames.len(),
            "width": self.width,
            "height": self.height,
            "render_width": self.render_size.map_or(self.width, |size| size.0),
            "render_height": self.render_size.map_or(self.height, |size| size.1),
            "threads": self.threads,
            "simd": crate::simd::kernels().name(),
            "stages": stages,
            "frame": self.frame().json(),
            "mrays_per_s": self.mrays_per_s(),
            "rays_per_frame": self.frames.iter().map(|f| f.rays.total()).collect::<Vec<_>>(),
            "cache_ended_share": self.cache_ended_share(),
            "cache_learn_ms": self.series(|frame| frame.cache_learn_ms).json(),
            "steps": self.frames.iter().map(|frame| u64::from(frame.steps)).sum::<u64>(),
        });
        if let Some(view) = &self.view {
            report["view"] = json!(view);
        }
        if let Some(replay) = &self.replay {
            report["replay"] = json!(replay);
        }
        if let Some(share) = self.film_share() {
            report["film_share"] = json!({ "film": share.film, "upscale": share.upscale });
        }
        if let Some(accel) = self.accel_rays() {
            report["accel_mrays_per_s"] = json!({
                "camera": accel.camera,
                "shadow": accel.shadow,
                "bounce": accel.bounce,
                "harmonic_mean": accel.harmonic_mean(),
            });
            report["renderer_vs_accel"] = json!(self.renderer_vs_accel());
            if let Some(tracing) = self.tracing() {
                let [camera, shadow, bounce] = tracing.rays;
                report["tracing"] = json!({
                    "camera_rays": camera,
                    "shadow_rays": shadow,
                    "bounce_rays": bounce,
                    "ms": tracing.ms,
                    "share_of_render": tracing.share_of_render,
                });
            }
            report["accel_rounds"] = self
                .accel_windows()
                .into_iter()
                .map(|(round, renderer)| {
                    json!({
                        "after_frames": round.after_frames,
                        "camera": round.rays.camera,
                        "shadow": round.rays.shadow,
                        "bounce": round.rays.bounce,
                        "harmonic_mean": round.rays.harmonic_mean(),
                        "renderer_mrays_per_s": renderer,
                    })
                })
                .collect();
        }
        // "gameplay_phases", "render_phases" and "film_phases": each phase's summary.
        for (stage, summaries) in self.phase_summaries() {
            let phases: serde_json::Map<String, Value> = summaries
                .into_iter()
                .map(|(name, summary)| (name.to_string(), summary.json()))
                .collect();
            report[format!("{stage}_phases")] = Value::Object(phases);
        }
        report
    }

    /// The share of the rendered paths (a pixel's a frame) the radiance cache ended at
    /// their second vertex.
    pub fn cache_ended_share(&self) -> f64 {
        let (width, height) = self.render_size.unwrap_or((self.width, self.height));
        let paths = u64::from(width) * u64::from(height) * self.frames.len() as u64;
        let ended: u64 = self.frames.iter().map(|frame| frame.cache_ended).sum();
        ended as f64 / paths.max(1) as f64
    }

    /// The film's share of the frames' time (its milliseconds summed over the frames, over
    /// theirs), and of that the upscaler's: None without frames or with no film run.
    pub fn film_share(&self) -> Option<FilmShare> {
        let total: f64 = self.frames.iter().map(|frame| frame.frame_ms).sum();
        let film: f64 = self
            .frames
            .iter()
            .map(|frame| frame.stages[Stage::Film.index()])
            .sum();
        let upscale_phase = FILM_PHASES.iter().position(|&name| name == "upscale")?;
        let upscale: f64 = self
            .frames
            .iter()
            .map(|frame| frame.film_phases[upscale_phase])
            .sum();
        (total > 0.0 && film > 0.0).then(|| FilmShare {
            film: film / total,
            upscale: upscale / total,
        })
    }

    /// The table `gloam bench` prints: a row per stage.
    pub fn table(&self) -> String {
        let rendered = match self.render_size {
            Some((width, height)) if (width, height) != (self.width, self.height) => {
                format!(" (rendered at {width}x{height}, upscaled)")
            }
            _ => String::new(),
        };
        let kernels = match crate::simd::kernels() {
            crate::simd::Simd::Native => "",
            crate::simd::Simd::Portable => " (portable kernels)",
        };
        let mut text = format!(
            "{} frames of {} at {}x{}{rendered} on {} threads{kernels}; {:.2} Mrays/s\n{:<12}{:>10}{:>10}{:>10}{:>10}{:>10}\n",
            self.frames.len(),
            self.scene,
            self.width,
            self.height,
            self.threads,
            self.mrays_per_s(),
            "stage (ms)",
            "mean",
            "p50",
            "p95",
            "p99",
            "max"
        );
        let phases = self.phase_summaries();
        let mut rows: Vec<(String, Summary)> = Vec::new();
        for (index, name) in STAGES.iter().enumerate() {
            rows.push((name.to_string(), self.stage(index)));
            let own = phases.iter().filter(|(stage, _)| stage == name);
            for (_, summaries) in own {
                rows.extend(
                    summaries
                        .iter()
                        .map(|(phase, summary)| (format!("  .{phase}"), *summary)),
                );
            }
        }
        rows.push(("frame".to_string(), self.frame()));
        for (name, s) in rows {
            text += &format!(
                "{name:<12}{:>10.3}{:>10.3}{:>10.3}{:>10.3}{:>10.3}\n",
                s.mean, s.p50, s.p95, s.p99, s.max
            );
        }
        if let (Some(accel), Some(ratio)) = (self.accel_rays(), self.renderer_vs_accel()) {
            text += &format!(
                "rays: the renderer {:.2} Mrays/s (rays traced / render time); its accel alone \
                 {:.2} (camera {:.2}, shadow {:.2}, bounce {:.2}; harmonic mean; medians of \
                 {} round{} between the frames): {:.2}x (median of each window's ratio to its \
                 round)\n",
                self.mrays_per_s(),
                accel.harmonic_mean(),
                accel.camera,
                accel.shadow,
                accel.bounce,
                self.accel_rounds.len(),
                if self.accel_rounds.len() == 1 {
                    ""
                } else {
                    "s"
                },
                ratio
            );
        }
        if let Some(tracing) = self.tracing() {
            let [camera, shadow, bounce] = tracing.rays;
            text += &format!(
                "tracing: {camera:.0} camera, {shadow:.0} shadow and {bounce:.0} bounce rays a \
                 frame, which the accel alone traces in {:.2} ms: {:.0}% of the render's time \
                 (the rest shades the paths)\n",
                tracing.ms,
                100.0 * tracing.share_of_render
            );
        }
        if let Some(share) = self.film_share() {
            text += &format!(
                "film: {:.1}% of the frames' time (the filters {:.1}%, the upscaler {:.1}%)\n",
                100.0 * share.film,
                100.0 * (share.film - share.upscale),
                100.0 * share.upscale
            );
        }
        if self.frames.iter().any(|frame| frame.cache_ended > 0) {
            text += &format!(
                "radiance cache: ended {:.0}% of the paths at their second vertex; learnt each \
                 frame's samples in {:.3} ms (p50), in the background\n",
                100.0 * self.cache_ended_share(),
                self.series(|frame| frame.cache_learn_ms).p50
            );
        }
        text
    }

    /// A row per frame: frame index, each stage, the frame, rays.
    pub fn to_csv(&self) -> String {
        let mut text = format!(
            "frame,{},{},frame_ms,rays\n",
            STAGES.map(|s| format!("{s}_ms")).join(","),
            NESTED
                .iter()
                .flat_map(|(stage, names, _)| names.iter().map(move |n| format!("{stage}.{n}_ms")))
                .collect::<Vec<_>>()
                .join(","),
        );
        for (index, frame) in self.frames.iter().enumerate() {
            let stages: Vec<String> = frame
                .stages
                .iter()
                .chain(NESTED.iter().flat_map(|(_, _, times)| times(frame)))
                .map(|ms| format!("{ms:.6}"))
                .collect();
            text += &format!(
                "{index},{},{:.6},{}\n",
                stages.join(","),
                frame.frame_ms,
                frame.rays.total()
            );
        }
        text
    }

    /// Chrome's Trace Event Format: each frame's stages as consecutive complete events on
    /// one track, frames end to end (with any untimed gap between stages left as a gap),
    /// and under them a track per render thread holding the tiles it traced (for the last
    /// `TRACE_TILE_FRAMES` frames that kept their tiles).
    pub fn to_trace(&self) -> Value {
        const FRAMES_TRACK: u64 = 1;
        const STAGES_TRACK: u64 = 2;
        const FIRST_THREAD_TRACK: u64 = 100;
        let track_name = |tid: u64, name: String| {
            [
                json!({ "name": "thread_name", "ph": "M", "pid": 1, "tid": tid, "args": { "name": name } }),
                json!({ "name": "thread_sort_index", "ph": "M", "pid": 1, "tid": tid, "args": { "sort_index": tid } }),
            ]
        };
        let mut events: Vec<Value> = [
            track_name(FRAMES_TRACK, "frames".into()),
            track_name(STAGES_TRACK, "stages".into()),
        ]
        .concat();
        let threads = self
            .frames
            .iter()
            .flat_map(|frame| &frame.tiles)
            .map(|tile| tile.thread + 1)
            .max()
            .unwrap_or(0);
        for thread in 0..threads {
            let tid = FIRST_THREAD_TRACK + thread as u64;
            events.extend(track_name(tid, format!("render thread {thread}")));
        }
        let tiles_from = self.frames.len().saturating_sub(TRACE_TILE_FRAMES);
        let mut frame_start_us = 0.0;
        for (index, frame) in self.frames.iter().enumerate() {
            events.push(json!({
                "name": "frame", "cat": "frame", "ph": "X", "pid": 1, "tid": 1,
                "ts": frame_start_us, "dur": frame.frame_ms * 1e3,
                "args": { "index": index, "rays": frame.rays.total() },
            }));
            let mut at = frame_start_us;
            for (name, ms) in STAGES.iter().zip(frame.stages) {
                if ms > 0.0 {
                    events.push(json!({
                        "name": name, "cat": "stage", "ph": "X", "pid": 1, "tid": 2,
                        "ts": at, "dur": ms * 1e3,
                    }));
                }
                if let Some((names, times)) = phases_of(name) {
                    // The phases nest inside their stage on the same track.
                    let mut phase_at = at;
                    for (phase, &phase_ms) in names.iter().zip(times(frame)) {
                        if phase_ms > 0.0 {
                            events.push(json!({
                                "name": format!("{name}.{phase}"), "cat": name,
                                "ph": "X", "pid": 1, "tid": 2,
                                "ts": phase_at, "dur": phase_ms * 1e3,
                            }));
                        }
                        phase_at += phase_ms * 1e3;
                    }
                }
                if *name == Stage::Render.name() && index >= tiles_from {
                    for tile in &frame.tiles {
                        events.push(json!({
                            "name": "tile", "cat": "tile", "ph": "X", "pid": 1,
                            "tid": FIRST_THREAD_TRACK + tile.thread as u64,
                            "ts": at + tile.start_ms as f64 * 1e3,
                            "dur": (tile.end_ms - tile.start_ms).max(0.0) as f64 * 1e3,
                        }));
                    }
                }
                at += ms * 1e3;
            }
            frame_start_us += (frame.frame_ms * 1e3).max(at - frame_start_us);
        }
        json!({
            "traceEvents": events,
            "displayTimeUnit": "ms",
            "otherData": { "scene": self.scene, "width": self.width, "height": self.height },
        })
    }

    /// Writes whichever reports have a path; each file is written whole or not at all.
    pub fn write_reports(
        &self,
        json_path: Option<&Path>,
        csv_path: Option<&Path>,
        trace_path: Option<&Path>,
        chart_path: Option<&Path>,
    ) -> anyhow::Result<()> {
        let write = |path: &Path, bytes: &[u8]| {
            write_atomically(path, bytes).with_context(|| format!("writing {}", path.display()))
        };
        if let Some(path) = json_path {
            write(
                path,
                serde_json::to_string_pretty(&self.to_json())?.as_bytes(),
            )?;
        }
        if let Some(path) = csv_path {
            write(path, self.to_csv().as_bytes())?;
        }
        if let Some(path) = trace_path {
            write(path, serde_json::to_string(&self.to_trace())?.as_bytes())?;
        }
        if let Some(path) = chart_path {
            write(path, &chart::png(self)?)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn accel_rays_average_harmonically() {
        let rays = AccelRays {
            camera: 10.0,
            shadow: 20.0,
            bounce: 40.0,
        };
        // Equal counts of each: 3 rays take 1/10 + 1/20 + 1/40 us.
        assert!((rays.harmonic_mean() - 3.0 / 0.175).abs() < 1e-12);
        let none = AccelRays {
            shadow: 0.0,
            ..rays
        };
        assert_eq!(none.harmonic_mean(), 0.0);
        let mut profile = Profile {
            frames: vec![FrameSample {
                rays: RayMix {
                    camera: 3_000,
                    ..RayMix::default()
                },
                ..FrameSample::default()
            }],
            accel_rounds: vec![AccelRound {
                after_frames: 1,
                rays,
            }],
            ..Profile::default()
        };
        profile.frames[0].stages[Stage::Render.index()] = 1.0;
        // 3,000 rays in 1 ms: 3 Mrays/s, against 17.14.
        let ratio = profile.renderer_vs_accel().unwrap();
        assert!((ratio - 3.0 / (3.0 / 0.175)).abs() < 1e-9, "{ratio}");
    }

    #[test]
    fn each_window_of_frames_is_set_beside_its_own_round() {
        // Three windows of two frames, each traced at 2 Mrays/s (2,000 rays in 1 ms) on a
        // machine whose load changed: the accel alone was slower in the second round.
        let frame = || {
            let mut frame = FrameSample {
                rays: RayMix {
                    bounce: 2_000,
                    ..RayMix::default()
                },
                ..FrameSample::default()
            };
            frame.stages[Stage::Render.index()] = 1.0;
            frame
        };
        let round = |after_frames, rate| AccelRound {
            after_frames,
            rays: AccelRays {
                camera: rate,
                shadow: rate,
                bounce: rate,
            },
        };
        let profile = Profile {
            frames: (0..6).map(|_| frame()).collect(),
            // A round before any frame has no window and counts in no ratio.
            accel_rounds: vec![round(0, 1.0), round(2, 8.0), round(4, 4.0), round(6, 5.0)],
            ..Profile::default()
        };
        // Ratios 0.25, 0.5, 0.4: their median, not the ratio of the medians (2 / 5).
        let ratio = profile.renderer_vs_accel().unwrap();
        assert!((ratio - 0.4).abs() < 1e-9, "{ratio}");
        assert_eq!(profile.accel_rays().map(|rays| rays.camera), Some(4.0));
        let report = profile.to_json();
        let rounds = report["accel_rounds"].as_array().unwrap();
        assert_eq!(rounds.len(), 3);
        assert_eq!(rounds[1]["after_frames"], 4);
        assert_eq!(rounds[1]["renderer_mrays_per_s"].as_f64(), Some(2.0));
        assert_eq!(Profile::default().renderer_vs_accel(), None);
    }

    #[test]
    fn tracing_takes_each_kind_of_ray_at_its_own_rate() {
        // 1,000 camera rays at 10 Mrays/s (100 us), 400 shadow at 20 (20 us) and 2,000
        // bounce at 40 (50 us): 0.17 ms of a 0.5 ms render.
        let frame = |render_ms: f64| {
            let mut frame = FrameSample {
                rays: RayMix {
                    camera: 1_000,
                    shadow: 400,
                    bounce: 2_000,
                },
                ..FrameSample::default()
            };
            frame.stages[Stage::Render.index()] = render_ms;
            frame
        };
        let rays = AccelRays {
            camera: 10.0,
            shadow: 20.0,
            bounce: 40.0,
        };
        let round = |after_frames, scale: f64| AccelRound {
            after_frames,
            rays: AccelRays {
                camera: rays.camera * scale,
                shadow: rays.shadow * scale,
                bounce: rays.bounce * scale,
            },
        };
        let profile = Profile {
            frames: vec![frame(0.5), frame(1.0), frame(0.5)],
            // The second window's round ran at half the rates (0.34 ms of its 1 ms render),
            // the third's at twice (0.085 ms of 0.5 ms).
            accel_rounds: vec![round(1, 1.0), round(2, 0.5), round(3, 2.0)],
            ..Profile::default()
        };
        let tracing = profile.tracing().unwrap();
        assert_eq!(tracing.rays, [1_000.0, 400.0, 2_000.0]);
        // Medians of the windows: of 0.17, 0.34 and 0.085 ms, and of 34%, 34% and 17%.
        assert!((tracing.ms - 0.17).abs() < 1e-12, "{tracing:?}");
        assert!(
            (tracing.share_of_render - 0.34).abs() < 1e-12,
            "{tracing:?}"
        );
        let report = profile.to_json();
        assert_eq!(report["tracing"]["shadow_rays"].as_f64(), Some(400.0));
        assert!(profile.table().contains(
            "tracing: 1000 camera, 400 shadow and 2000 bounce rays a frame, which the accel \
             alone traces in 0.17 ms: 34% of the render's time"
        ));
        assert_eq!(Profile::default().tracing(), None);
    }

    #[test]
    fn the_film_share_is_its_time_over_the_frames_time() {
        let frame = |film: f64, upscale: f64, frame_ms: f64| {
            let mut stages = [0.0; STAGES.len()];
            stages[Stage::Render.index()] = frame_ms - film;
            stages[Stage::Film.index()] = film;
            FrameSample {
                stages,
                film_phases: [film - upscale, 0.0, 0.0, upscale],
                frame_ms,
                ..FrameSample::default()
            }
        };
        let profile = Profile {
            frames: vec![frame(2.0, 1.0, 10.0), frame(4.0, 1.0, 30.0)],
            ..Profile::default()
        };
        let share = profile.film_share().unwrap();
        assert!((share.film - 0.15).abs() < 1e-12, "{share:?}");
        assert!((share.upscale - 0.05).abs() < 1e-12, "{share:?}");
        assert!(
            profile
                .table()
                .contains("film: 15.0% of the frames' time (the filters 10.0%, the upscaler 5.0%)")
        );
        assert_eq!(profile.to_json()["film_share"]["film"].as_f64(), Some(0.15));
        assert_eq!(Profile::default().film_share(), None);
    }

    #[test]
    fn percentiles_are_nearest_rank_frames_that_happened() {
        let values: Vec<f64> = (1..=100).map(f64::from).rev().collect();
        let s = Summary::of(&values);
        assert_eq!((s.p50, s.p95, s.p99, s.max), (50.0, 95.0, 99.0, 100.0));
        assert_eq!(s.mean, 50.5);
        let one = Summary::of(&[7.0]);
        assert_eq!((one.p50, one.p99, one.max, one.mean), (7.0, 7.0, 7.0, 7.0));
        assert_eq!(Summary::of(&[]), Summary::default());
    }

    #[test]
    fn render_phase_names_are_the_renderers() {
        assert_eq!(RENDER_PHASES, crate::render::PhaseTimes::NAMES);
        assert_eq!(FILM_PHASES, crate::film::FilmPhaseTimes::NAMES);
    }

    #[test]
    fn trace_events_lie_end_to_end_inside_their_frames() {
        let frame = |render: f64| FrameSample {
            stages: [0.1, 0.0, 0.2, 0.1, 0.0, 0.0, 0.3, 0.1, render, 0.2, 0.0],
            render_phases: [render * 0.4, render * 0.1, render * 0.2, render * 0.3],
            film_phases: [0.1, 0.05, 0.05, 0.0],
            gameplay_phases: [0.0, 0.0, 0.0, 0.0],
            frame_ms: render + 1.5,
            rays: RayMix {
                camera: 10,
                ..RayMix::default()
            },
            cache_ended: 0,
            cache_learn_ms: 0.0,
            steps: 1,
            tiles: vec![
                TileSpan {
                    thread: 0,
                    start_ms: 0.0,
                    end_ms: render as f32 * 0.5,
                },
                TileSpan {
                    thread: 1,
                    start_ms: 0.0,
                    end_ms: render as f32 * 0.9,
                },
                TileSpan {
                    thread: 0,
                    start_ms: render as f32 * 0.5,
                    end_ms: render as f32,
                },
            ],
        };
        let profile = Profile {
            frames: vec![frame(5.0), frame(7.0)],
            ..Profile::default()
        };
        let trace = profile.to_trace();
        let events = trace["traceEvents"].as_array().unwrap();
        let frames: Vec<&Value> = events.iter().filter(|e| e["name"] == "frame").collect();
        assert_eq!(frames[1]["ts"].as_f64(), Some(6500.0));
        for event in events.iter().filter(|e| e["cat"] == "stage") {
            let (ts, dur) = (
                event["ts"].as_f64().unwrap(),
                event["dur"].as_f64().unwrap(),
            );
            let inside = frames.iter().any(|f| {
                let (start, length) = (f["ts"].as_f64().unwrap(), f["dur"].as_f64().unwrap());
                ts >= start && ts + dur <= start + length + 1e-9
            });
            assert!(inside, "{event}");
        }
        // The render phases nest inside their frame's render event and fill it.
        let span = |e: &Value| (e["ts"].as_f64().unwrap(), e["dur"].as_f64().unwrap());
        let renders: Vec<(f64, f64)> = events
            .iter()
            .filter(|e| e["name"] == "render")
            .map(span)
            .collect();
        let phases: Vec<(f64, f64)> = events
            .iter()
            .filter(|e| e["cat"] == "render")
            .map(span)
            .collect();
        assert_eq!(phases.len(), 8);
        for (frame, &(start, length)) in renders.iter().enumerate() {
            let own = &phases[frame * 4..frame * 4 + 4];
            assert!(
                own.iter()
                    .all(|&(ts, dur)| ts >= start && ts + dur <= start + length + 1e-6)
            );
            assert!((own.iter().map(|p| p.1).sum::<f64>() - length).abs() < 1e-6);
        }
        // Each render thread has its own named track, holding its tiles inside the render.
        let track = |tid: u64| {
            events
                .iter()
                .find(|e| e["ph"] == "M" && e["name"] == "thread_name" && e["tid"] == tid)
                .map(|e| e["args"]["name"].clone())
        };
        assert_eq!(track(100), Some(json!("render thread 0")));
        assert_eq!(track(101), Some(json!("render thread 1")));
        assert_eq!(track(102), None);
        let tiles: Vec<&Value> = events.iter().filter(|e| e["cat"] == "tile").collect();
        assert_eq!(tiles.len(), 6);
        assert_eq!(tiles.iter().filter(|e| e["tid"] == 101).count(), 2);
        for (frame, &(start, length)) in renders.iter().enumerate() {
            let own = &tiles[frame * 3..frame * 3 + 3];
            assert!(own.iter().all(|e| {
                let (ts, dur) = span(e);
                ts >= start && ts + dur <= start + length + 1e-3
            }));
        }
        // Empty stages leave no event.
        assert!(!events.iter().any(|e| e["name"] == "gameplay"));
        assert!((profile.mrays_per_s() - 20.0 / 12.0 / 1e3).abs() < 1e-12);
    }
}
