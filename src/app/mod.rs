//! The window shell: the only code that knows winit and pixels.
//!
//! Per displayed frame (winit 0.30 `ApplicationHandler`):
//! 1. window and device events -> the player's key bindings (`settings`) -> the game's
//!    `Input` resource, or, while a menu is open, -> the menu (`menu`), in `controls`;
//! 2. `RedrawRequested`: the engine advances by the real time since the last frame (fixed
//!    60 Hz simulation, then extract -> accel -> render -> film accumulation), unless a
//!    menu holds it;
//! 3. present (`present`): the film's image (with the filters on, upscaled by the film from
//!    a lowered internal resolution to the configured one) is tone mapped (the film's tone
//!    mapper, scaled by the brightness setting) into pixels' frame buffer at the configured
//!    resolution and pixels scales it to the window; over it, at the window's own
//!    resolution (`interface`), the HUD (`hud`: the light gem, the shards, each warden's
//!    state mark projected over its head, captions, prompts) or the open menu (`menu`);
//! 4. when a warden has caught the player, the level starts again at once from the loaded
//!    `Scene`; when the player gets out, the best time is kept and the end page opens (a
//!    watched recording stays on its last frame instead);
//! 5. hot reload: when the level file or one of its assets changes on disk
//!    (`scene::watch`), the level starts again from the files; one that does not load
//!    leaves the level playing with its `file:line:column: message` on screen until fixed.
//!
//! The configured resolution is 1280 x 720 unless `--width` and `--height` say otherwise
//! ([`DEFAULT_WIDTH`]); the render's starts at the game's rule for it (640 x 360,
//! `film::render_scale_for`) and adapts to hold the frame-time target (the setting, or
//! `--target-ms`), a step at a time down and up a ladder of scales ([`resolution`]). The
//! first run (no settings file yet) times its first frames at the full resolution and
//! keeps the frame-time target they choose (`resolution::first_run_target`), and says so
//! on screen.
//!
//! # Menus
//!
//! With no level named, the window opens on the main menu ([`menu`]) over the first level
//! seen from its own camera, its wardens walking their beats. Play starts the first level
//! not yet won; Choose a level lists every playable level in `levels/` in campaign order
//! with its best time; Settings sets the mouse, the view, brightness, the frame-time
//! target, the interface size, captions, the volumes, the keys and the gamepad buttons
//! ([`settings`]). Getting out opens the end page with the time, shards, times seen and
//! how it compares with the best; Next level goes on. A run with a level, a recording or a
//! frame count (`gloam LEVEL`, `gloam play LEVEL`, `--headless`, `--replay`, `--record`,
//! `--frames`) skips the menu. With no display, `gloam play` says so in one line and
//! points to the headless commands.
//!
//! # Keys
//!
//! Keys in play (the defaults; the keys page rebinds them): W A S D walk, Shift sprints,
//! Space jumps, C or Ctrl crouches, E douses or relights the lamp looked at, N toggles
//! noclip (fly through walls: Space and C rise and sink), mouse looks once captured
//! (click). A gamepad plays too ([`gamepad`]). Fixed: Esc pauses (the pause page: resume,
//! restart, settings, main menu, quit; losing the keyboard focus pauses the same way), F11
//! toggles fullscreen, V vsync (both remembered in the settings), F3 the profiler overlay
//! (`crate::profile::overlay`), F4 cycles the film's filters (temporal+spatial, temporal,
//! raw), F2 opens the level's file in the editor (`shell`), F12 writes a screenshot
//! ([`screenshot`]: the frame as PNG and the linear film as EXR). No single key quits. A
//! level without a player start is flown through with the same keys. Prompts name the key
//! the player bound, and the campaign's first level states its goal and, the first time
//! the player stands lit, the crouch key ([`hints`]).

mod captions;
mod controls;
pub mod editor;
pub mod gamepad;
pub mod hints;
mod hud;
pub(crate) mod interface;
pub mod menu;
mod options;
mod present;
pub mod resolution;
pub mod screenshot;
pub mod settings;
pub(crate) mod shell;
mod sound;

use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use anyhow::anyhow;
use glam::Vec2;
use pixels::{Pixels, PixelsBuilder, SurfaceTexture};
use winit::application::ApplicationHandler;
use winit::dpi::LogicalSize;
use winit::event::{DeviceEvent, DeviceId, ElementState, MouseButton, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::keyboard::PhysicalKey;
use winit::window::{Fullscreen, Window, WindowId};

use crate::extract::DeformStats;
use crate::film::FilterMode;
use crate::frame::Engine;
use crate::game::{Action, Input};
use crate::profile::StageTimes;
use crate::profile::{Profile, overlay};
use crate::render::RenderSettings;
use crate::scene::files::default_level;
use crate::scene::watch::FileWatch;
use crate::scene::world::Scene;
use menu::{Finish, Menu, MenuCommand, MenuContext, MenuInput, Page};
pub use options::PlayOptions;
use options::{
    StageLog, adapt_resolution, frame_settings, play_engine, play_headless, set_field_of_view,
};
pub use present::HeadlessPresent;
use resolution::ResolutionController;
use settings::{BestTimes, PadButton, Settings};

/// Opens the window: plays `options.level`, or opens the main menu when none is named.
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
    // A level named on the command line that does not load is an error before any window.
    let first = match &options.level {
        Some(level) => Some((Scene::load(level)?, level.clone())),
        None => None,
    };
    let mut event_loop = EventLoop::new().map_err(|error| {
        anyhow!("cannot open a window ({error}); `gloam play --headless`, `gloam render` and `gloam bench` work without a display")
    })?;
    let mut app = App::new(options);
    match first {
        Some((scene, level)) => app.start(scene, level),
        None => app.open_main_menu(),
    }
    shell::run(&mut event_loop, shell::Mode::Play(Box::new(app)))
}

impl App {
    /// The window's state before any window exists: the player's settings and best times
    /// (a broken file named), the levels to choose from.
    fn new(options: PlayOptions) -> App {
        let mut notices = Vec::new();
        let config = settings::config_dir();
        // No settings file yet: the first frames choose the frame-time target, unless the
        // command line chose the resolution or runs a script of frames.
        let first_run = config
            .as_ref()
            .is_some_and(|dir| !dir.join(settings::SETTINGS_FILE).exists())
            && options.target_ms.is_none()
            && options.frames.is_none()
            && options.watch.is_none();
        let (player_settings, best) = match &config {
            Some(dir) => {
                let loaded = settings::load::<Settings>(&dir.join(settings::SETTINGS_FILE));
                let best = settings::load::<BestTimes>(&dir.join(settings::BEST_TIMES_FILE));
                notices.extend(loaded.warning);
                notices.extend(best.warning);
                (loaded.value, best.value)
            }
            None => {
                notices.push(
                    "no config folder (set HOME or GLOAM_CONFIG_DIR): settings and best times are not kept"
                        .to_string(),
                );
                (Settings::default(), BestTimes::default())
            }
        };
        let levels_folder = default_level()
            .parent()
            .map_or_else(|| PathBuf::from("levels"), Path::to_path_buf);
        let (levels, warnings) = menu::find_levels(&levels_folder);
        notices.extend(warnings);
        for notice in &notices {
            eprintln!("gloam: {notice}");
        }
        // Said on the terminal only: a machine without gamepads needs no notice on screen.
        let (gamepad, gamepad_warning) = gamepad::Gamepad::open();
        if let Some(warning) = gamepad_warning {
            eprintln!("gloam: warning: {warning}");
        }
        let log = StageLog::new(&options);
        let overlay = options.profiler;
        let player_settings_vsync = player_settings.vsync;
        let mut app = App {
            resolution: None,
            probe: first_run.then(resolution::FirstRunProbe::default),
            game: None,
            backdrop: None,
            menu: None,
            context: MenuContext {
                levels,
                best,
                settings: player_settings,
                playing: None,
                finish: None,
            },
            config,
            notice: notices.last().map(|line| (Instant::now(), line.clone())),
            watch: None,
            file_error: None,
            pointer: None,
            caught: None,
            captions: captions::Captions::default(),
            sound: sound::GameSound::default(),
            options,
            window: None,
            pixels: None,
            interface: None,
            last_frame: Instant::now(),
            frame_ms: Vec::new(),
            vsync: player_settings_vsync,
            overlay,
            screenshot: false,
            captured: false,
            rendered: 0,
            done_at: None,
            error: None,
            log,
            switch: None,
            play_test: false,
            focused: false,
            gamepad,
            device: hints::Device::Keyboard,
            keys_held: HashSet::new(),
        };
        app.apply_target();
        app
    }

    /// After its event loop has returned: the frame table of a `--frames` run, and the
    /// error that ended it, if one did.
    fn finish(&mut self) -> anyhow::Result<()> {
        if self.options.frames.is_some() {
            self.log.print("windowed");
        }
        match self.error.take() {
            Some(error) => Err(error),
            None => Ok(()),
        }
    }

    /// Leaves the event loop for another mode (`shell`), the window closed first: winit
    /// carries no window from one run of the loop to the next.
    fn switch_to(&mut self, event_loop: &ActiveEventLoop, switch: shell::Switch) {
        self.finish_recording(crate::game::replay::Ended::Quit);
        self.switch = Some(switch);
        self.pixels = None;
        self.window = None;
        self.captured = false;
        event_loop.exit();
    }
}

/// A level being played.
struct Game {
    engine: Engine,
    /// The level as loaded: a caught player starts it again from here.
    scene: Scene,
    level: PathBuf,
    /// The first level's hints (`hints`).
    hints: hints::Hints,
}

pub(crate) struct App {
    game: Option<Game>,
    /// The main menu's backdrop: the first level seen from its own camera, no player in
    /// it, the wardens walking their beats.
    backdrop: Option<Engine>,
    /// The open menu (None: playing).
    menu: Option<Menu>,
    context: MenuContext,
    /// Where the settings and best times are kept (None: nowhere to keep them).
    config: Option<PathBuf>,
    /// A line shown at the top for a few seconds (a broken settings file, a level that
    /// would not load).
    notice: Option<(Instant, String)>,
    /// The level being played and its assets, watched for changes on disk (hot reload).
    watch: Option<FileWatch>,
    /// The level or an asset changed on disk and no longer loads: its problems, shown
    /// until a version that loads replaces it (the level plays on meanwhile).
    file_error: Option<String>,
    /// The mouse pointer in the interface's points, while over the window.
    pointer: Option<egui::Pos2>,
    /// When the player was last caught, and by whom (shown over the new attempt).
    caught: Option<(Instant, String)>,
    /// Captions of the sounds heard lately (`captions`).
    captions: captions::Captions,
    /// The sound out (`sound`).
    sound: sound::GameSound,
    /// Adaptive internal resolution (None: fixed).
    resolution: Option<ResolutionController>,
    /// The first run's frames being timed at the full resolution, to choose the frame-time
    /// target (`resolution::first_run_target`); the resolution is fixed meanwhile.
    probe: Option<resolution::FirstRunProbe>,
    options: PlayOptions,
    window: Option<Arc<Window>>,
    pixels: Option<Pixels<'static>>,
    /// The HUD and the menus, drawn over the scaled frame (`interface`).
    interface: Option<interface::Interface>,
    last_frame: Instant,
    /// Recent frame times for the HUD.
    frame_ms: Vec<f32>,
    vsync: bool,
    /// The profiler overlay (F3) is shown.
    overlay: bool,
    /// F12 was pressed: the next frame shown is written to the screenshot folder.
    screenshot: bool,
    captured: bool,
    /// Frames rendered (not counting repeats of a held image).
    rendered: u32,
    /// With `--frames`: when to quit.
    done_at: Option<Instant>,
    error: Option<anyhow::Error>,
    log: StageLog,
    /// Set when the window closes for another mode: the editor (F2), or back to it.
    switch: Option<shell::Switch>,
    /// A play-test from the editor: Esc, closing the window and winning go back to the
    /// editor instead of the menus, and the level file is not watched (the editor holds
    /// the level being played).
    play_test: bool,
    /// Whether the window has the keyboard focus (losing it pauses an attempt).
    focused: bool,
    /// The gamepads, read once a frame (`read_gamepad`).
    gamepad: gamepad::Gamepad,
    /// The device the player last used: the prompts name its controls.
    device: hints::Device,
    /// The actions whose keys are down, so a pad letting go of one the keyboard also holds
    /// (or a key the pad also holds) does not let it go.
    keys_held: HashSet<Action>,
}

/// How long a notice stays on screen.
const NOTICE_SECONDS: f32 = 8.0;
/// How long "Caught by ..." stays over the attempt that starts again.
const CAUGHT_BANNER_SECONDS: f32 = 3.0;

impl App {
    fn fail(&mut self, event_loop: &ActiveEventLoop, error: anyhow::Error) {
        self.error = Some(error);
        event_loop.exit();
    }

    fn notify(&mut self, line: String) {
        eprintln!("gloam: {line}");
        self.notice = Some((Instant::now(), line));
    }

    /// Starts playing `scene` (loaded from `level`), menus closed.
    fn start(&mut self, scene: Scene, level: PathBuf) {
        self.watch_level(&scene, &level);
        // The last level's sounds so far go out before its loops stop.
        self.sound
            .frame(self.game.as_mut().map(|game| &mut game.engine), false);
        let mut engine = play_engine(&scene, &self.options);
        set_field_of_view(&mut engine, self.context.settings.field_of_view);
        if let Some(warning) = self
            .sound
            .start(&mut engine, &level, self.context.settings.volume)
        {
            // Said once, on the terminal: a game without sound is still the game.
            eprintln!("gloam: warning: {warning}");
        }
        if self.options.record.is_some() {
            engine.recording = Some(crate::game::replay::Recorder::default());
        }
        if let Some(recording) = &self.options.watch {
            engine.playback = Some(recording.steps.iter().copied().collect());
        }
        let name = if scene.level.name.is_empty() {
            level.display().to_string()
        } else {
            scene.level.name.clone()
        };
        if let Some(window) = &self.window {
            window.set_title(&format!("Gloam - {name}"));
        }
        self.context.playing = Some(level.clone());
        self.context.finish = None;
        self.game = Some(Game {
            engine,
            scene,
            level,
            hints: hints::Hints::default(),
        });
        self.backdrop = None;
        self.menu = None;
        self.caught = None;
        self.captions.clear();
        self.apply_target();
    }

    /// Watches `level` and the assets of its `scene` for changes on disk.
    fn watch_level(&mut self, scene: &Scene, level: &Path) {
        if self.play_test {
            return;
        }
        let files = std::iter::once(level.to_path_buf())
            .chain(scene.assets.iter().map(|asset| asset.source.clone()));
        let result = match &mut self.watch {
            Some(watch) => watch.set_files(files),
            None => FileWatch::new(files).map(|watch| self.watch = Some(watch)),
        };
        if let Err(error) = result {
            self.notify(format!("{error:#} (changes on disk will not be noticed)"));
        }
    }

    /// Hot reload: when the level being played or one of its assets changed on disk, the
    /// level starts again from the files; one that does not load leaves the level playing
    /// and its problems on screen until it is fixed.
    fn reload_changed(&mut self) {
        let Some(watch) = &mut self.watch else { return };
        if watch.poll().is_empty() {
            return;
        }
        let Some(game) = &self.game else { return };
        let level = game.level.clone();
        match Scene::load(&level) {
            Ok(scene) => {
                let internal = (
                    game.engine.film.settings.width,
                    game.engine.film.settings.height,
                );
                self.finish_recording(crate::game::replay::Ended::Quit);
                let menu = self.menu.take();
                self.start(scene, level.clone());
                self.menu = menu;
                if let Some(game) = &mut self.game {
                    game.engine.film.set_resolution(internal.0, internal.1);
                }
                self.file_error = None;
                self.notify(format!("{} changed on disk: reloaded", level.display()));
            }
            Err(error) => {
                let text = format!("{error:#}");
                eprintln!("gloam: {text}");
                self.file_error = Some(text);
            }
        }
    }

    /// Loads and plays `level`; a level that does not load is named and the menu stays.
    fn start_level(&mut self, level: PathBuf) {
        match Scene::load(&level) {
            Ok(scene) => {
                self.start(scene, level);
                self.set_capture(true);
            }
            Err(error) => {
                let line = format!("{error:#}");
                self.notify(line.lines().next().unwrap_or_default().to_string());
            }
        }
    }

    /// The main menu, over the first level's backdrop.
    fn open_main_menu(&mut self) {
        self.finish_recording(crate::game::replay::Ended::Quit);
        self.game = None;
        self.sound.stop();
        self.context.playing = None;
        self.menu = Some(Menu::new(Page::Main));
        self.set_capture(false);
        if let Some(window) = &self.window {
            window.set_title("Gloam");
        }
        self.backdrop = self
            .context
            .levels
            .first()
            .and_then(|entry| Scene::load(&entry.path).ok())
            .map(|scene| {
                let mut engine = Engine::new(&scene, frame_settings(&self.options));
                engine.film.filter.mode = self.options.filter;
                engine
            });
        self.apply_target();
    }

    /// The adaptive resolution as the command line or the settings ask.
    fn apply_target(&mut self) {
        let target = match self.probe {
            Some(_) => None,
            None => (self.options.target_ms).unwrap_or(self.context.settings.frame_time_target_ms),
        };
        if self.resolution.as_ref().map(|c| c.target_ms) == target {
            return;
        }
        self.resolution = target.map(ResolutionController::new);
        // The game's rule for the configured size (native up to 640 x 360's pixels).
        let (width, height) = crate::film::render_size_for(self.options.width, self.options.height);
        if let Some(engine) = self.engine_mut() {
            engine.film.set_resolution(width, height);
        }
    }

    /// The engine on screen: the level played, else the menu's backdrop.
    fn engine_mut(&mut self) -> Option<&mut Engine> {
        match &mut self.game {
            Some(game) => Some(&mut game.engine),
            None => self.backdrop.as_mut(),
        }
    }

    /// Writes the settings after a change and applies them to the level being played.
    fn settings_changed(&mut self) {
        let fov = self.context.settings.field_of_view;
        if let Some(game) = &mut self.game {
            set_field_of_view(&mut game.engine, fov);
        }
        self.sound.set_volumes(self.context.settings.volume);
        self.apply_target();
        if let Some(dir) = &self.config
            && let Err(error) =
                settings::save(&dir.join(settings::SETTINGS_FILE), &self.context.settings)
        {
            self.notify(format!("{error:#}"));
        }
    }

    /// Carries out what the menu asked for.
    fn command(&mut self, event_loop: &ActiveEventLoop, command: MenuCommand) {
        match command {
            MenuCommand::Play(level) => {
                self.finish_recording(crate::game::replay::Ended::Quit);
                self.start_level(level);
            }
            MenuCommand::Resume => {
                self.menu = None;
                self.set_capture(true);
            }
            MenuCommand::Restart => {
                self.finish_recording(crate::game::replay::Ended::Quit);
                if let Some(game) = self.game.take() {
                    self.start(game.scene, game.level);
                    self.set_capture(true);
                }
            }
            MenuCommand::MainMenu => self.open_main_menu(),
            MenuCommand::Quit => {
                self.finish_recording(crate::game::replay::Ended::Quit);
                event_loop.exit();
            }
            MenuCommand::SettingsChanged => self.settings_changed(),
        }
    }

    /// Writes the recording, if one is being made, ended as `ended`; says where.
    fn finish_recording(&mut self, ended: crate::game::replay::Ended) {
        let Some(game) = &mut self.game else { return };
        let (Some(out), Some(recorded)) = (&self.options.record, game.engine.recording.take())
        else {
            return;
        };
        let count = recorded.steps.len();
        match crate::headless::replay::write_recording(out, &game.level, recorded, ended) {
            Ok(()) => println!("wrote {} ({count} steps, ended {ended:?})", out.display()),
            Err(error) => eprintln!("gloam: {error:#}"),
        }
    }

    /// Caught: the level starts again at once, and says who caught the player.
    fn restart_caught(&mut self) {
        let Some(game) = self.game.take() else { return };
        let mut engine = game.engine;
        let by = crate::game::status::caught_by(&mut engine.world);
        let internal = (engine.film.settings.width, engine.film.settings.height);
        self.start(game.scene, game.level);
        if let Some(game) = &mut self.game {
            game.engine.film.set_resolution(internal.0, internal.1);
        }
        self.caught = Some((Instant::now(), by));
    }

    /// Won: the finish is offered to the best times (kept when it beats them) and the end
    /// page opens.
    fn won(&mut self) {
        let Some(game) = &mut self.game else { return };
        let Some(progress) = game
            .engine
            .world
            .get_resource::<crate::game::Progress>()
            .cloned()
        else {
            return;
        };
        let finish = settings::Best {
            seconds: progress.seconds(),
            shards: progress.shards_taken,
            times_seen: progress.times_seen,
        };
        let level = game.level.clone();
        let previous = self.context.best.get(&level);
        // A watched recording is someone's run, not the player's; a run that flew through
        // walls with noclip is no run at all.
        let new_best = self.options.watch.is_none()
            && !progress.noclip_used
            && self.context.best.offer(&level, finish);
        if new_best
            && let Some(dir) = &self.config
            && let Err(error) =
                settings::save(&dir.join(settings::BEST_TIMES_FILE), &self.context.best)
        {
            self.notify(format!("{error:#}"));
        }
        self.context.finish = Some(Finish {
            noclip: progress.noclip_used,
            level,
            best: finish,
            new_best,
            previous,
        });
        self.menu = Some(Menu::new(Page::Won));
        self.set_capture(false);
    }

    /// Takes the sounds the steps since the last frame made and captions those that
    /// matter, as the player stands and faces (nothing when captions are off).
    fn hear_captions(&mut self) {
        let Some(game) = &mut self.game else { return };
        let world = &mut game.engine.world;
        let Some(events) = world
            .get_resource_mut::<crate::game::SoundEvents>()
            .map(|mut sounds| sounds.take())
        else {
            return;
        };
        if !self.context.settings.captions {
            return self.captions.clear();
        }
        let now = world
            .get_resource::<crate::game::Progress>()
            .map_or(0.0, |progress| progress.seconds());
        let mut eyes = world.query_filtered::<
            &crate::game::GlobalTransform,
            bevy_ecs::query::With<crate::game::PlayerEye>,
        >();
        let Some(ear) = eyes.iter(world).next().map(|eye| eye.0.translation.into()) else {
            return;
        };
        let mut players = world.query::<&crate::game::Player>();
        let yaw = players.iter(world).next().map_or(0.0, |player| player.yaw);
        let Some(geometry) = world.get_resource::<crate::game::WorldGeometry>() else {
            return;
        };
        let nav = world.get_resource::<crate::game::NavGrid>();
        let heard_db = |at: glam::Vec3| {
            let source = at + glam::Vec3::Y * crate::game::acoustics::tuning::SOURCE_LIFT;
            crate::game::acoustics::hear(geometry.0.as_ref(), nav, source, ear).level_db
        };
        self.captions.hear(&events, (ear, yaw), now, heard_db);
    }

    /// The pause menu over the level, which holds the simulation while it is open.
    fn pause(&mut self) {
        if let Some(game) = &mut self.game {
            game.engine.world.resource_mut::<Input>().held.clear();
        }
        // Key releases may never come while the window is elsewhere (losing the focus
        // pauses): keys count again from their next press.
        self.keys_held.clear();
        self.menu = Some(Menu::new(Page::Paused));
        self.set_capture(false);
    }

    /// Whether an attempt is under way in front of the player: a level with a player, not
    /// ended, no menu over it.
    fn attempt_running(&mut self) -> bool {
        if self.menu.is_some() {
            return false;
        }
        let Some(game) = &mut self.game else {
            return false;
        };
        let world = &mut game.engine.world;
        let running = world
            .get_resource::<crate::game::Progress>()
            .is_none_or(|progress| progress.outcome == crate::game::Outcome::Running);
        let mut players = world.query_filtered::<(), bevy_ecs::query::With<crate::game::Player>>();
        running && players.iter(world).next().is_some()
    }

    /// Times a first run's frame; once the probe has its answer, keeps the target it
    /// chooses in the settings and says so.
    fn time_first_run(&mut self, frame_ms: f64) {
        let Some(full_ms) = self
            .probe
            .as_mut()
            .and_then(|probe| probe.observe(frame_ms))
        else {
            return;
        };
        self.probe = None;
        let target = resolution::first_run_target(full_ms);
        self.context.settings.frame_time_target_ms = Some(target);
        self.settings_changed();
        self.notify(format!(
            "frame-time target {target} ms, from this machine's first frames ({full_ms:.1} ms at full resolution); Settings changes it"
        ));
    }

    fn redraw(&mut self, event_loop: &ActiveEventLoop) {
        self.reload_changed();
        let now = Instant::now();
        let elapsed = now - self.last_frame;
        self.last_frame = now;
        let holding = self
            .options
            .frames
            .is_some_and(|limit| self.rendered >= limit);
        self.read_gamepad(event_loop, elapsed.as_secs_f32());
        if self.switch.is_some() {
            return; // a menu row chosen on the pad left this window's level
        }
        // A menu holds the level; the main menu's backdrop goes on living behind it.
        let held = self.menu.is_some() && self.game.is_some();
        let advanced = !held && !holding && (self.game.is_some() || self.backdrop.is_some());
        if advanced {
            let (options, resolution) = (&self.options, &mut self.resolution);
            let engine = match &mut self.game {
                Some(game) => &mut game.engine,
                None => self.backdrop.as_mut().expect("advanced needs an engine"),
            };
            adapt_resolution(resolution, engine, options, elapsed.as_secs_f64() * 1e3);
            engine.advance(elapsed.as_secs_f64());
            self.time_first_run(elapsed.as_secs_f64() * 1e3);
            self.hear_captions();
            if let Some(game) = &self.game {
                // A recording holds one attempt: it ends when the attempt does.
                let outcome = game
                    .engine
                    .world
                    .get_resource::<crate::game::Progress>()
                    .map(|p| p.outcome);
                match outcome {
                    Some(crate::game::Outcome::Won) if self.play_test => {
                        let seconds = game
                            .engine
                            .world
                            .get_resource::<crate::game::Progress>()
                            .map_or(0.0, |progress| progress.seconds());
                        let line = format!("play-test won in {seconds:.1} s");
                        return self.switch_to(event_loop, shell::Switch::BackToEditor(line));
                    }
                    Some(crate::game::Outcome::Won) => {
                        self.finish_recording(crate::game::replay::Ended::Won);
                        self.won();
                    }
                    Some(crate::game::Outcome::Caught) if self.options.watch.is_none() => {
                        self.finish_recording(crate::game::replay::Ended::Caught);
                        self.restart_caught();
                    }
                    _ => {}
                }
            }
            self.rendered += 1;
            self.frame_ms.push(elapsed.as_secs_f32() * 1e3);
            if self.frame_ms.len() > 60 {
                self.frame_ms.remove(0);
            }
        }
        let paused = self.menu.is_some();
        self.sound
            .frame(self.game.as_mut().map(|game| &mut game.engine), paused);
        let present_start = Instant::now();
        if !self.present(event_loop) {
            return;
        }
        if advanced && let Some(engine) = self.engine_mut() {
            let times = engine.stage_times();
            let deform = engine.deform_stats();
            let present = present_start.elapsed().as_secs_f64() * 1e3;
            self.log
                .push(&times, deform, present, now.elapsed().as_secs_f64() * 1e3);
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

/// The game's resolution shown when none is asked for (`play`, play-tests): the frame
/// buffer the window scales. The render's own follows from it by the game's rule
/// (`film::render_scale_for`: 640 x 360 here, upscaled), lowered further by the adaptive
/// resolution (`resolution`) to hold the frame-time target.
pub const DEFAULT_WIDTH: u32 = 1280;
pub const DEFAULT_HEIGHT: u32 = 720;

/// The editor's view, rendered at this size when none is asked for (`edit`): its image
/// converges while nothing moves, so it is not upscaled.
pub const EDITOR_WIDTH: u32 = 480;
pub const EDITOR_HEIGHT: u32 = 270;

/// The window's size for a frame buffer of `width` x `height`: doubled when narrower than
/// 960 pixels (a 480 x 270 buffer in a 960 x 540 window), else the buffer's own (1280 x
/// 720).
fn window_size(width: u32, height: u32) -> LogicalSize<u32> {
    let scale = if width < 960 { 2 } else { 1 };
    LogicalSize::new(width * scale, height * scale)
}

/// Opens a window of `size` titled `title`, with a pixels surface over it holding a
/// `buffer` (width, height) frame buffer.
fn open_window(
    event_loop: &ActiveEventLoop,
    title: String,
    size: LogicalSize<u32>,
    (width, height): (u32, u32),
    vsync: bool,
) -> anyhow::Result<(Arc<Window>, Pixels<'static>)> {
    let attributes = Window::default_attributes()
        .with_title(title)
        .with_inner_size(size);
    let window = Arc::new(
        event_loop
            .create_window(attributes)
            .map_err(|error| anyhow!("cannot create the window: {error}"))?,
    );
    let inner = window.inner_size();
    let surface = SurfaceTexture::new(inner.width.max(1), inner.height.max(1), Arc::clone(&window));
    let pixels = PixelsBuilder::new(width, height, surface)
        .enable_vsync(vsync)
        .build()
        .map_err(|error| anyhow!("cannot start the renderer's window surface: {error}"))?;
    Ok((window, pixels))
}

/// Follows a resized window with pixels' surface (a minimised window, 0 x 0, is left).
fn resize_surface(
    pixels: &mut Option<Pixels<'static>>,
    size: winit::dpi::PhysicalSize<u32>,
) -> anyhow::Result<()> {
    match pixels {
        Some(pixels) if size.width > 0 && size.height > 0 => pixels
            .resize_surface(size.width, size.height)
            .map_err(|error| anyhow!("resizing the window surface: {error}")),
        _ => Ok(()),
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.window.is_some() {
            return;
        }
        let (width, height) = (self.options.width, self.options.height);
        let title = match &self.game {
            Some(game) if !game.scene.level.name.is_empty() => {
                format!("Gloam - {}", game.scene.level.name)
            }
            Some(game) => format!("Gloam - {}", game.level.display()),
            None => "Gloam".to_string(),
        };
        let size = window_size(width, height);
        match open_window(event_loop, title, size, (width, height), self.vsync) {
            Ok((window, pixels)) => {
                if self.context.settings.fullscreen {
                    window.set_fullscreen(Some(Fullscreen::Borderless(None)));
                }
                self.interface = Some(interface::Interface::new(&pixels));
                self.pixels = Some(pixels);
                self.window = Some(window);
            }
            Err(error) => return self.fail(event_loop, error),
        }
        self.last_frame = Instant::now();
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _: WindowId, event: WindowEvent) {
        match event {
            WindowEvent::CloseRequested if self.play_test => {
                let back = shell::Switch::BackToEditor("play-test closed".to_owned());
                self.switch_to(event_loop, back);
            }
            WindowEvent::CloseRequested => {
                self.finish_recording(crate::game::replay::Ended::Quit);
                event_loop.exit();
            }
            WindowEvent::Resized(size) => {
                if let Err(error) = resize_surface(&mut self.pixels, size) {
                    self.fail(event_loop, error);
                }
            }
            WindowEvent::KeyboardInput {
                event,
                is_synthetic,
                ..
            } => {
                // A window that takes the focus gets a made-up press for every key held at
                // that moment: a press the player made elsewhere (or the one whose release
                // is still on its way) must not move a menu or choose its row. Made-up
                // releases stay, so no key sticks when the focus leaves.
                let made_up_press = is_synthetic && event.state == ElementState::Pressed;
                if let PhysicalKey::Code(code) = event.physical_key
                    && !event.repeat
                    && !made_up_press
                {
                    self.key(event_loop, code, event.state);
                }
            }
            WindowEvent::CursorMoved { position, .. } => {
                let Some(screen) = self.screen() else { return };
                let before = self.pointer;
                self.pointer = Some(screen.window_point((position.x, position.y)));
                // A window that opens under a resting pointer is told where it is, as if it
                // had moved there: only a move from a known place points at a row, or a
                // pointer left where Quit appears would choose Quit for the keyboard.
                let moved = before.is_some() && before != self.pointer;
                if moved && let (Some(menu), Some(at)) = (&self.menu, self.pointer) {
                    let view = menu.view(&self.context);
                    if let Some(row) = menu::row_at(&view, screen.rect, at) {
                        self.menu_input(event_loop, MenuInput::Point(row));
                    }
                }
            }
            WindowEvent::CursorLeft { .. } => self.pointer = None,
            WindowEvent::MouseInput {
                state: ElementState::Pressed,
                button: MouseButton::Left,
                ..
            } => {
                if let Some(menu) = &self.menu {
                    // A click chooses the row under the pointer.
                    let view = menu.view(&self.context);
                    if let (Some(at), Some(screen)) = (self.pointer, self.screen())
                        && let Some(row) = menu::row_at(&view, screen.rect, at)
                    {
                        self.menu_input(event_loop, MenuInput::Point(row));
                        self.menu_input(event_loop, MenuInput::Activate);
                    }
                } else {
                    self.set_capture(true);
                }
            }
            WindowEvent::Focused(true) => self.focused = true,
            WindowEvent::Focused(false) => {
                self.set_capture(false);
                // Away from the window the player cannot see the wardens, so they must
                // not walk on: the level waits under the pause menu, as Esc leaves it.
                // Only a focus the window had is lost: winit says "unfocused" once as a
                // window opens, before the window manager gives it the focus.
                if std::mem::take(&mut self.focused) && self.attempt_running() {
                    self.pause();
                }
            }
            WindowEvent::RedrawRequested => self.redraw(event_loop),
            _ => {}
        }
    }

    fn device_event(&mut self, _: &ActiveEventLoop, _: DeviceId, event: DeviceEvent) {
        if let DeviceEvent::MouseMotion { delta } = event
            && self.captured
            && self.menu.is_none()
            && let Some(game) = &mut self.game
        {
            let settings = &self.context.settings;
            let pitch = if settings.invert_y { 1.0 } else { -1.0 };
            game.engine.world.resource_mut::<Input>().look +=
                Vec2::new(delta.0 as f32, delta.1 as f32)
                    * controls::MOUSE_SENSITIVITY
                    * settings.mouse_sensitivity
                    * Vec2::new(1.0, pitch);
        }
    }

    fn about_to_wait(&mut self, _: &ActiveEventLoop) {
        if let Some(window) = &self.window {
            window.request_redraw();
        }
    }
}
