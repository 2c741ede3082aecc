//! What `gloam play` is asked (`PlayOptions`), the engine it builds from that, the per-stage
//! log it prints when it ends, and the same frame loop without a window (`--headless`).

use std::path::PathBuf;
use std::time::Duration;

use super::*;

/// What `gloam play` was asked: the level, the resolution, scripted frames, recordings.
pub struct PlayOptions {
    /// The level to play; None opens the main menu.
    pub level: Option<PathBuf>,
    /// Internal render resolution (pixels scales it to the window).
    pub width: u32,
    pub height: u32,
    /// Stop rendering after this many frames and keep showing the image (for tests and
    /// screenshots); print `ready` once shown.
    pub frames: Option<u32>,
    /// With `frames`: quit this long after the last frame.
    pub linger: Duration,
    /// Run the same frame loop without a window (`frames` frames, default 60) and print
    /// the stage times.
    pub headless: bool,
    /// Start with the profiler overlay (F3) shown.
    pub profiler: bool,
    /// The film's filters.
    pub filter: FilterMode,
    /// The frame time the internal resolution adapts to hold: `Some(None)` keeps it fixed,
    /// None takes the player's setting.
    pub target_ms: Option<Option<f64>>,
    /// Record every step's input of the attempt to this file.
    pub record: Option<PathBuf>,
    /// Watch this recording's inputs play instead of taking the keyboard's (its level is
    /// `level`); the attempt is not restarted when it ends.
    pub watch: Option<crate::game::replay::Recording>,
}

/// Per-frame stage times, for the table printed when a `--frames` run ends.
#[derive(Default)]
pub(super) struct StageLog {
    pub(super) profile: Profile,
    /// Frames kept (None: all, for the table a `--frames` run prints).
    keep: Option<usize>,
    /// Deforming meshes refit and rebuilt, summed over the frames.
    refits: u64,
    rebuilds: u64,
}

impl StageLog {
    pub(super) fn new(options: &PlayOptions) -> StageLog {
        StageLog {
            profile: Profile {
                scene: options
                    .level
                    .as_ref()
                    .map_or_else(|| "menu".to_string(), |level| level.display().to_string()),
                width: options.width,
                height: options.height,
                threads: rayon::current_num_threads(),
                ..Profile::default()
            },
            keep: options.frames.is_none().then_some(2 * overlay::HISTORY),
            ..StageLog::default()
        }
    }

    pub(super) fn push(
        &mut self,
        times: &StageTimes,
        deform: DeformStats,
        present: f64,
        frame: f64,
    ) {
        self.refits += deform.refits as u64;
        self.rebuilds += deform.rebuilds as u64;
        self.profile.frames.push(times.sample(present, frame));
        if let Some(keep) = self.keep
            && self.profile.frames.len() > keep
        {
            // Playing without end: keep what the overlay shows, not every frame.
            self.profile
                .frames
                .drain(..self.profile.frames.len() - keep / 2);
        }
    }

    /// The per-stage statistics, and the deforming meshes' refits and rebuilds.
    pub(super) fn print(&self, label: &str) {
        print!("{label}: {}", self.profile.table());
        if self.refits + self.rebuilds > 0 {
            println!(
                "deforming BLASes: {} refits, {} rebuilds",
                self.refits, self.rebuilds
            );
        }
    }
}

pub(super) fn frame_settings(options: &PlayOptions) -> RenderSettings {
    RenderSettings::real_time(options.width, options.height)
}

/// The engine as `play` runs it: the level, the real-time settings, the chosen filters.
pub(super) fn play_engine(scene: &Scene, options: &PlayOptions) -> Engine {
    let mut engine = Engine::new(scene, frame_settings(options));
    engine.film.filter.mode = options.filter;
    // Rendered by the game's rule for the configured size (native up to 640 x 360's
    // pixels); the resolution controller works down from there.
    let (width, height) = crate::film::render_size_for(options.width, options.height);
    engine.film.set_resolution(width, height);
    // A playable level is seen through the player's eyes; a showcase scene from its camera.
    if scene.level.playable {
        crate::game::spawn_player(&mut engine.world);
    }
    engine
}

/// Sets the player's eye to `degrees` of vertical field of view.
pub(super) fn set_field_of_view(engine: &mut Engine, degrees: f32) {
    use bevy_ecs::query::With;
    let mut eyes = engine
        .world
        .query_filtered::<&mut crate::game::ViewCamera, With<crate::game::PlayerEye>>();
    for mut eye in eyes.iter_mut(&mut engine.world) {
        eye.yfov = degrees.to_radians();
    }
}

/// Feeds a frame's time to the resolution controller and applies a change of step.
pub(super) fn adapt_resolution(
    controller: &mut Option<ResolutionController>,
    engine: &mut Engine,
    options: &PlayOptions,
    frame_ms: f64,
) {
    if let Some(controller) = controller
        && controller.observe(frame_ms).is_some()
    {
        let (width, height) = controller.size(options.width, options.height);
        engine.film.set_resolution(width, height);
    }
}

/// The same frame loop with no window: real time drives the simulation as in `play`, and
/// present costs nothing.
pub(super) fn play_headless(options: PlayOptions) -> anyhow::Result<()> {
    let level = options.level.clone().unwrap_or_else(default_level);
    let scene = Scene::load(&level)?;
    let mut engine = play_engine(&scene, &options);
    // Headless runs are measurements: the player's settings do not enter them.
    let target = options
        .target_ms
        .unwrap_or(Some(settings::DEFAULT_TARGET_MS));
    let mut controller = target.map(ResolutionController::new);
    let mut log = StageLog::new(&options);
    let mut last = Instant::now();
    for _ in 0..options.frames.unwrap_or(60) {
        let now = Instant::now();
        let elapsed = (now - last).as_secs_f64();
        adapt_resolution(&mut controller, &mut engine, &options, elapsed * 1e3);
        engine.advance(elapsed);
        last = now;
        log.push(
            &engine.stage_times(),
            engine.deform_stats(),
            0.0,
            now.elapsed().as_secs_f64() * 1e3,
        );
    }
    log.print("headless");
    let settings = &engine.film.settings;
    println!(
        "film: {}, internal resolution {}x{} at the end",
        options.filter.name(),
        settings.width,
        settings.height
    );
    Ok(())
}
