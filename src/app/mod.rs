//! The window shell: the only code that knows winit and pixels.
//!
//! Per displayed frame (winit 0.30 `ApplicationHandler`):
//! 1. window and device events -> the key-binding table -> the game's `Input` resource;
//! 2. `RedrawRequested`: the engine advances by the real time since the last frame (fixed
//!    60 Hz simulation, then extract -> accel -> render -> film accumulation);
//! 3. present: the accumulated image is tone mapped (the film's tone mapper) into pixels'
//!    frame buffer at the internal render resolution, the HUD is drawn over it (the light
//!    gem, the shards, each warden's state mark projected over its head, the end screen),
//!    and pixels scales it to the window;
//! 4. when a warden has caught the player, the level starts again at once from the loaded
//!    `Scene` (a watched recording stays on its last frame instead).
//!
//! Keys: W A S D walk, Shift sprints, Space jumps, C or Ctrl crouches, E douses or
//! relights the lamp looked at, N toggles noclip
//! (fly through walls: Space and C rise and sink), mouse looks once captured (click), Esc
//! pauses (and releases the mouse), Q quits, F11 toggles fullscreen, V toggles vsync, F3
//! the profiler overlay, F4 cycles the film's filters (temporal+spatial, temporal, raw). A
//! level without a player start is flown through with the same keys.

mod hud;
pub mod replay;
pub mod resolution;

use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context as _, anyhow};
use glam::Vec2;
use pixels::{Pixels, PixelsBuilder, SurfaceTexture};
use winit::application::ApplicationHandler;
use winit::dpi::LogicalSize;
use winit::event::{DeviceEvent, DeviceId, ElementState, MouseButton, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::{CursorGrabMode, Fullscreen, Window, WindowId};

use crate::extract::DeformStats;
use crate::film::FilterMode;
use crate::frame::Engine;
use crate::game::{Action, Input};
use crate::profile::StageTimes;
use crate::profile::{Profile, overlay};
use crate::render::RenderSettings;
use crate::render::film::tone_map;
use crate::scene::world::Scene;
use resolution::ResolutionController;

pub struct PlayOptions {
    pub level: PathBuf,
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
    /// Adapt the internal resolution to hold this frame time (None: fixed).
    pub target_ms: Option<f64>,
    /// Record every step's input of the attempt to this file.
    pub record: Option<PathBuf>,
    /// Watch this recording's inputs play instead of taking the keyboard's (its level is
    /// `level`); the attempt is not restarted when it ends.
    pub watch: Option<crate::game::replay::Recording>,
}

/// Per-frame stage times, for the table printed when a `--frames` run ends.
#[derive(Default)]
struct StageLog {
    profile: Profile,
    /// Frames kept (None: all, for the table a `--frames` run prints).
    keep: Option<usize>,
    /// Deforming meshes refit and rebuilt, summed over the frames.
    refits: u64,
    rebuilds: u64,
}

impl StageLog {
    fn new(options: &PlayOptions) -> StageLog {
        StageLog {
            profile: Profile {
                scene: options.level.display().to_string(),
                width: options.width,
                height: options.height,
                threads: rayon::current_num_threads(),
                frames: Vec::new(),
            },
            keep: options.frames.is_none().then_some(2 * overlay::HISTORY),
            ..StageLog::default()
        }
    }

    fn push(&mut self, times: &StageTimes, deform: DeformStats, present: f64, frame: f64) {
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
    fn print(&self, label: &str) {
        print!("{label}: {}", self.profile.table());
        if self.refits + self.rebuilds > 0 {
            println!(
                "deforming BLASes: {} refits, {} rebuilds",
                self.refits, self.rebuilds
            );
        }
    }
}

/// What a key does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Binding {
    Game(Action),
    Pause,
    Quit,
    Fullscreen,
    Profiler,
    Filter,
    Vsync,
}

/// The one key-binding table.
const BINDINGS: &[(KeyCode, Binding)] = &[
    (KeyCode::KeyW, Binding::Game(Action::MoveForward)),
    (KeyCode::KeyS, Binding::Game(Action::MoveBack)),
    (KeyCode::KeyA, Binding::Game(Action::MoveLeft)),
    (KeyCode::KeyD, Binding::Game(Action::MoveRight)),
    (KeyCode::Space, Binding::Game(Action::MoveUp)),
    (KeyCode::KeyC, Binding::Game(Action::MoveDown)),
    (KeyCode::ControlLeft, Binding::Game(Action::MoveDown)),
    (KeyCode::ShiftLeft, Binding::Game(Action::Sprint)),
    (KeyCode::KeyN, Binding::Game(Action::Noclip)),
    (KeyCode::KeyE, Binding::Game(Action::Interact)),
    (KeyCode::Escape, Binding::Pause),
    (KeyCode::KeyQ, Binding::Quit),
    (KeyCode::F11, Binding::Fullscreen),
    (KeyCode::F3, Binding::Profiler),
    (KeyCode::F4, Binding::Filter),
    (KeyCode::KeyV, Binding::Vsync),
];

/// Radians of view turn per pixel of mouse motion.
const MOUSE_SENSITIVITY: f32 = 0.0025;

/// Opens the window and plays `options.level` until the player quits.
pub fn play(options: PlayOptions) -> anyhow::Result<()> {
    if options.headless {
        return play_headless(options);
    }
    if cfg!(target_os = "linux")
        && std::env::var_os("DISPLAY").is_none()
        && std::env::var_os("WAYLAND_DISPLAY").is_none()
    {
        return Err(anyhow!(
            "no display to open a window on (DISPLAY and WAYLAND_DISPLAY are unset); `gloam play --headless` (and `--replay FILE`), `gloam render` and `gloam bench` work without one"
        ));
    }
    let scene = Scene::load(&options.level)?;
    let title = format!(
        "Gloam - {}",
        if scene.level.name.is_empty() {
            options.level.display().to_string()
        } else {
            scene.level.name.clone()
        }
    );
    let event_loop = EventLoop::new().map_err(|error| {
        anyhow!("cannot open a window ({error}); `gloam play --headless`, `gloam render` and `gloam bench` work without a display")
    })?;
    let log = StageLog::new(&options);
    let overlay = options.profiler;
    let mut engine = play_engine(&scene, &options);
    if options.record.is_some() {
        engine.recording = Some(Vec::new());
    }
    if let Some(recording) = &options.watch {
        engine.playback = Some(recording.steps.iter().copied().collect());
    }
    let mut app = App {
        resolution: options.target_ms.map(ResolutionController::new),
        engine,
        scene,
        caught: None,
        options,
        title,
        window: None,
        pixels: None,
        last_frame: Instant::now(),
        frame_ms: Vec::new(),
        paused: false,
        vsync: true,
        overlay,
        captured: false,
        rendered: 0,
        done_at: None,
        error: None,
        log,
    };
    event_loop
        .run_app(&mut app)
        .context("running the window's event loop")?;
    if app.options.frames.is_some() {
        app.log.print("windowed");
    }
    match app.error {
        Some(error) => Err(error),
        None => Ok(()),
    }
}

fn frame_settings(options: &PlayOptions) -> RenderSettings {
    RenderSettings::real_time(options.width, options.height)
}

/// The engine as `play` runs it: the level, the real-time settings, the chosen filters.
fn play_engine(scene: &Scene, options: &PlayOptions) -> Engine {
    let mut engine = Engine::new(scene, frame_settings(options));
    engine.film.filter.mode = options.filter;
    // A playable level is seen through the player's eyes; a showcase scene from its camera.
    if scene.level.playable {
        crate::game::spawn_player(&mut engine.world);
    }
    engine
}

/// Feeds a frame's time to the resolution controller and applies a change of step.
fn adapt_resolution(
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
fn play_headless(options: PlayOptions) -> anyhow::Result<()> {
    let scene = Scene::load(&options.level)?;
    let mut engine = play_engine(&scene, &options);
    let mut controller = options.target_ms.map(ResolutionController::new);
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

/// "E  douse the lamp" or "E  light the lamp" when a lamp is within reach of the player's
/// aim (`game::lamps::aimed_lamp`, the question E's press asks).
fn lamp_prompt(world: &mut bevy_ecs::world::World) -> Option<&'static str> {
    use crate::game::{
        GlobalTransform, LevelEntity, Player, PlayerEye, PunctualLight, SwitchedOff, WorldGeometry,
    };
    use bevy_ecs::query::With;
    let (player, eye) = {
        let mut players = world.query::<&Player>();
        let player = players.iter(world).next()?.clone();
        let mut eyes = world.query_filtered::<&GlobalTransform, With<PlayerEye>>();
        let eye: glam::Vec3 = eyes.iter(world).next()?.0.translation.into();
        (player, eye)
    };
    let mut lamps = world.query_filtered::<(
        bevy_ecs::entity::Entity,
        &GlobalTransform,
        bevy_ecs::query::Has<SwitchedOff>,
    ), (With<PunctualLight>, With<LevelEntity>)>();
    let candidates: Vec<_> = lamps
        .iter(world)
        .map(|(lamp, placed, doused)| (lamp, placed.0.translation.into(), doused))
        .collect();
    let geometry = world.get_resource::<WorldGeometry>()?;
    let view = crate::game::lamps::view(&player);
    let (_, doused) =
        crate::game::lamps::aimed_lamp(&*geometry.0, eye, view, candidates.into_iter())?;
    Some(if doused {
        "E  light the lamp"
    } else {
        "E  douse the lamp"
    })
}

/// The name of the warden that caught the player.
fn caught_by(world: &mut bevy_ecs::world::World) -> String {
    let mut wardens = world.query::<(&crate::game::Warden, &bevy_ecs::name::Name)>();
    wardens
        .iter(world)
        .find(|(warden, _)| warden.state == crate::game::WardenState::Caught)
        .map_or_else(|| "a warden".to_string(), |(_, name)| name.to_string())
}

struct App {
    engine: Engine,
    /// The level as loaded: a caught player starts it again from here.
    scene: Scene,
    /// When the player was last caught, and by whom (shown over the new attempt).
    caught: Option<(Instant, String)>,
    /// Adaptive internal resolution (None: fixed).
    resolution: Option<ResolutionController>,
    options: PlayOptions,
    title: String,
    window: Option<Arc<Window>>,
    pixels: Option<Pixels<'static>>,
    last_frame: Instant,
    /// Recent frame times for the HUD.
    frame_ms: Vec<f32>,
    paused: bool,
    vsync: bool,
    /// The profiler overlay (F3) is shown.
    overlay: bool,
    captured: bool,
    /// Frames rendered (not counting repeats of a held image).
    rendered: u32,
    /// With `--frames`: when to quit.
    done_at: Option<Instant>,
    error: Option<anyhow::Error>,
    log: StageLog,
}

impl App {
    fn fail(&mut self, event_loop: &ActiveEventLoop, error: anyhow::Error) {
        self.error = Some(error);
        event_loop.exit();
    }

    /// Writes the recording, if one is being made, ended as `ended`; says where.
    fn finish_recording(&mut self, ended: crate::game::replay::Ended) {
        let (Some(out), Some(steps)) = (&self.options.record, self.engine.recording.take()) else {
            return;
        };
        let count = steps.len();
        match replay::write_recording(out, &self.options.level, steps, ended) {
            Ok(()) => println!("wrote {} ({count} steps, ended {ended:?})", out.display()),
            Err(error) => eprintln!("gloam: {error:#}"),
        }
    }

    /// Caught: the level starts again at once, and says who caught the player.
    fn restart_caught(&mut self) {
        let by = caught_by(&mut self.engine.world);
        let internal = (
            self.engine.film.settings.width,
            self.engine.film.settings.height,
        );
        self.engine = play_engine(&self.scene, &self.options);
        self.engine.film.set_resolution(internal.0, internal.1);
        self.caught = Some((Instant::now(), by));
    }

    fn set_capture(&mut self, capture: bool) {
        let Some(window) = &self.window else { return };
        if capture {
            let grabbed = window
                .set_cursor_grab(CursorGrabMode::Locked)
                .or_else(|_| window.set_cursor_grab(CursorGrabMode::Confined));
            self.captured = grabbed.is_ok();
        } else {
            let _ = window.set_cursor_grab(CursorGrabMode::None);
            self.captured = false;
        }
        window.set_cursor_visible(!self.captured);
    }

    fn key(&mut self, event_loop: &ActiveEventLoop, code: KeyCode, state: ElementState) {
        let Some(&(_, binding)) = BINDINGS.iter().find(|(key, _)| *key == code) else {
            return;
        };
        let pressed = state == ElementState::Pressed;
        match binding {
            // A recording being watched plays its own input.
            Binding::Game(_) if self.options.watch.is_some() => {}
            Binding::Game(action) => {
                let mut input = self.engine.world.resource_mut::<Input>();
                if pressed && !self.paused {
                    input.held.insert(action);
                    input.pressed.insert(action);
                } else {
                    input.held.remove(&action);
                }
            }
            Binding::Pause if pressed => {
                self.paused = !self.paused;
                self.engine.world.resource_mut::<Input>().held.clear();
                self.set_capture(false);
            }
            Binding::Quit if pressed => {
                self.finish_recording(crate::game::replay::Ended::Quit);
                event_loop.exit();
            }
            Binding::Fullscreen if pressed => {
                if let Some(window) = &self.window {
                    let fullscreen = window
                        .fullscreen()
                        .is_none()
                        .then_some(Fullscreen::Borderless(None));
                    window.set_fullscreen(fullscreen);
                }
            }
            Binding::Profiler if pressed => self.overlay = !self.overlay,
            Binding::Filter if pressed => {
                let accumulation = &mut self.engine.film;
                accumulation.filter.mode = accumulation.filter.mode.next();
                accumulation.filter.reset();
                accumulation.reset = true;
            }
            Binding::Vsync if pressed => {
                self.vsync = !self.vsync;
                if let Some(pixels) = &mut self.pixels {
                    pixels.enable_vsync(self.vsync);
                }
            }
            _ => {}
        }
    }

    fn redraw(&mut self, event_loop: &ActiveEventLoop) {
        let now = Instant::now();
        let elapsed = now - self.last_frame;
        self.last_frame = now;
        let holding = self
            .options
            .frames
            .is_some_and(|limit| self.rendered >= limit);
        let advanced = !self.paused && !holding;
        if advanced {
            adapt_resolution(
                &mut self.resolution,
                &mut self.engine,
                &self.options,
                elapsed.as_secs_f64() * 1e3,
            );
            self.engine.advance(elapsed.as_secs_f64());
            // A recording holds one attempt: it ends when the attempt does.
            let outcome = self
                .engine
                .world
                .get_resource::<crate::game::Progress>()
                .map(|p| p.outcome);
            match outcome {
                Some(crate::game::Outcome::Won) => {
                    self.finish_recording(crate::game::replay::Ended::Won)
                }
                Some(crate::game::Outcome::Caught) if self.options.watch.is_none() => {
                    self.finish_recording(crate::game::replay::Ended::Caught);
                    self.restart_caught();
                }
                _ => {}
            }
            self.rendered += 1;
            self.frame_ms.push(elapsed.as_secs_f32() * 1e3);
            if self.frame_ms.len() > 60 {
                self.frame_ms.remove(0);
            }
        }
        let present_start = Instant::now();
        profiling::scope!("present");
        let Some(pixels) = &mut self.pixels else {
            return;
        };
        let accumulation = &self.engine.film;
        let internal = (accumulation.settings.width, accumulation.settings.height);
        // The buffer keeps the configured size; a lowered internal resolution is scaled up.
        let (width, height) = (self.options.width, self.options.height);
        let image = accumulation.image().resized(width, height);
        let frame = pixels.frame_mut();
        for (rgba, radiance) in frame.chunks_exact_mut(4).zip(&image.pixels) {
            let [r, g, b] = tone_map(*radiance, 1.0);
            rgba.copy_from_slice(&[r, g, b, 255]);
        }
        let mean_ms = self.frame_ms.iter().sum::<f32>() / self.frame_ms.len().max(1) as f32;
        let film = match accumulation.filter.mode {
            FilterMode::Off => format!("{} spp", accumulation.frames),
            mode => mode.name().to_string(),
        };
        let status = format!(
            "{:.1} fps {:.1} ms {}x{}{} {film}{}",
            1000.0 / mean_ms.max(1e-3),
            mean_ms,
            internal.0,
            internal.1,
            match &self.resolution {
                Some(controller) => format!(" ({:.0}%)", controller.scale() * 100.0),
                None => String::new(),
            },
            if self.vsync { "" } else { " novsync" }
        );
        // The light gem (the player's exposure), and its exact value with the overlay.
        let gem = self
            .engine
            .world
            .query::<&crate::game::Exposure>()
            .iter(&self.engine.world)
            .next()
            .map(|exposure| exposure.gem);
        hud::draw_text(frame, width, height, 2, 2, &status);
        if let Some(gem) = gem
            && self.overlay
        {
            hud::draw_text(frame, width, height, 2, 22, &format!("light gem {gem:.3}"));
        }
        if self.paused {
            hud::draw_text(frame, width, height, 2, 42, "PAUSED  Esc resume  Q quit");
        }
        if self.overlay {
            let frames = &self.log.profile.frames;
            let recent = &frames[frames.len().saturating_sub(overlay::HISTORY)..];
            let deform = self.engine.deform_stats();
            overlay::draw(frame, width, height, recent, deform.refits, deform.rebuilds);
        }
        if let Some(gem) = gem {
            hud::draw_gem(frame, width, height, gem);
        }
        // Each warden's state above its head: what it knows, the player knows.
        let projection = self.engine.view_camera(width, height).projection();
        let mut wardens = self
            .engine
            .world
            .query::<(&crate::game::Warden, &crate::game::GlobalTransform)>();
        for (warden, placed) in wardens.iter(&self.engine.world) {
            let head = placed.0.translation + glam::Vec3A::Y * hud::MARK_HEIGHT;
            let seen = projection.project_lanes(head);
            if seen.in_front && seen.distance < hud::MARK_RANGE {
                hud::draw_warden_mark(
                    frame,
                    width,
                    height,
                    (seen.x, seen.y),
                    warden.state,
                    warden.suspicion,
                );
            }
        }
        // The lamp within reach of the player's aim, and what E would do to it.
        if let Some(prompt) = lamp_prompt(&mut self.engine.world) {
            let x = (width / 2).saturating_sub(prompt.len() as u32 * 4);
            hud::draw_text(frame, width, height, x, height.saturating_sub(44), prompt);
        }
        // Each noise the player made, as a ring of its reach on the floor, fading.
        if let Some(noises) = self.engine.world.get_resource::<crate::game::Noises>() {
            for noise in &noises.0 {
                let points = (0..hud::RING_POINTS).map(|i| {
                    let angle = i as f32 / hud::RING_POINTS as f32 * std::f32::consts::TAU;
                    let at = noise.at
                        + glam::Vec3::new(
                            angle.cos() * noise.radius,
                            0.05,
                            angle.sin() * noise.radius,
                        );
                    let seen = projection.project_lanes(at.into());
                    seen.in_front.then_some((seen.x, seen.y))
                });
                let fade = 1.0 - noise.age / crate::game::noise::tuning::RING_SECONDS;
                hud::draw_noise_ring(frame, width, height, points, fade);
            }
        }
        if let Some((at, by)) = &self.caught {
            if at.elapsed().as_secs_f32() < 3.0 {
                let line = format!("Caught by {by}. The level starts again.");
                let x = (width / 2).saturating_sub(line.len() as u32 * 4);
                hud::draw_text(frame, width, height, x, height / 3, &line);
            }
        }
        // The goal: shards so far, and the end screen once the attempt is over.
        if let Some(progress) = self.engine.world.get_resource::<crate::game::Progress>() {
            let progress = progress.clone();
            let left = self
                .engine
                .world
                .query_filtered::<(), bevy_ecs::query::With<crate::game::Shard>>()
                .iter(&self.engine.world)
                .count() as u32;
            let total = progress.shards_taken + left;
            if total > 0 {
                let line = format!("shards {}/{total}", progress.shards_taken);
                hud::draw_text(frame, width, height, 2, height.saturating_sub(18), &line);
            }
            if progress.outcome == crate::game::Outcome::Caught {
                // Only a watched recording shows this: in play the level has restarted.
                let line = format!("Caught by {}.  Q quits", caught_by(&mut self.engine.world));
                let x = (width / 2).saturating_sub(line.len() as u32 * 4);
                hud::draw_text(frame, width, height, x, height / 3, &line);
            }
            if progress.outcome == crate::game::Outcome::Won {
                let seconds = progress.seconds();
                let lines = [
                    "You got out.".to_string(),
                    format!(
                        "time {}:{:04.1}  shards {}/{total}  seen {} times",
                        (seconds / 60.0) as u32,
                        seconds % 60.0,
                        progress.shards_taken,
                        progress.times_seen
                    ),
                    "Q quits".to_string(),
                ];
                for (row, line) in lines.iter().enumerate() {
                    let x = (width / 2).saturating_sub(line.len() as u32 * 4);
                    let y = height / 2 - 30 + row as u32 * 20;
                    hud::draw_text(frame, width, height, x, y, line);
                }
            }
        }
        if let Err(error) = pixels.render() {
            return self.fail(event_loop, anyhow!("presenting the frame: {error}"));
        }
        if advanced {
            let times = self.engine.stage_times();
            let present = present_start.elapsed().as_secs_f64() * 1e3;
            self.log.push(
                &times,
                self.engine.deform_stats(),
                present,
                now.elapsed().as_secs_f64() * 1e3,
            );
        }
        if holding && self.done_at.is_none() {
            println!("ready: {} frames shown", self.rendered);
            self.done_at = Some(now + self.options.linger);
        }
        if self.done_at.is_some_and(|at| now >= at) {
            event_loop.exit();
        }
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.window.is_some() {
            return;
        }
        let (width, height) = (self.options.width, self.options.height);
        let attributes = Window::default_attributes()
            .with_title(self.title.clone())
            .with_inner_size(LogicalSize::new(width * 2, height * 2));
        let window = match event_loop.create_window(attributes) {
            Ok(window) => Arc::new(window),
            Err(error) => {
                return self.fail(event_loop, anyhow!("cannot create the window: {error}"));
            }
        };
        let size = window.inner_size();
        let surface =
            SurfaceTexture::new(size.width.max(1), size.height.max(1), Arc::clone(&window));
        match PixelsBuilder::new(width, height, surface)
            .enable_vsync(self.vsync)
            .build()
        {
            Ok(pixels) => self.pixels = Some(pixels),
            Err(error) => {
                return self.fail(
                    event_loop,
                    anyhow!("cannot start the renderer's window surface: {error}"),
                );
            }
        }
        self.window = Some(window);
        self.last_frame = Instant::now();
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _: WindowId, event: WindowEvent) {
        match event {
            WindowEvent::CloseRequested => {
                self.finish_recording(crate::game::replay::Ended::Quit);
                event_loop.exit();
            }
            WindowEvent::Resized(size) => {
                if let Some(pixels) = &mut self.pixels
                    && size.width > 0
                    && size.height > 0
                    && let Err(error) = pixels.resize_surface(size.width, size.height)
                {
                    self.fail(event_loop, anyhow!("resizing the window surface: {error}"));
                }
            }
            WindowEvent::KeyboardInput { event, .. } => {
                if let PhysicalKey::Code(code) = event.physical_key
                    && !event.repeat
                {
                    self.key(event_loop, code, event.state);
                }
            }
            WindowEvent::MouseInput {
                state: ElementState::Pressed,
                button: MouseButton::Left,
                ..
            } if !self.paused => {
                self.set_capture(true);
            }
            WindowEvent::Focused(false) => self.set_capture(false),
            WindowEvent::RedrawRequested => self.redraw(event_loop),
            _ => {}
        }
    }

    fn device_event(&mut self, _: &ActiveEventLoop, _: DeviceId, event: DeviceEvent) {
        if let DeviceEvent::MouseMotion { delta } = event
            && self.captured
            && !self.paused
        {
            self.engine.world.resource_mut::<Input>().look +=
                Vec2::new(delta.0 as f32, delta.1 as f32)
                    * MOUSE_SENSITIVITY
                    * Vec2::new(1.0, -1.0);
        }
    }

    fn about_to_wait(&mut self, _: &ActiveEventLoop) {
        if let Some(window) = &self.window {
            window.request_redraw();
        }
    }
}
