//! The level editor's window (`gloam edit LEVEL`): egui panels around the path-traced
//! view of the level as authored, driving `edit::Editor`'s commands.
//!
//! Per displayed frame (winit 0.30 `ApplicationHandler`):
//! 1. window events go to egui first (`gui`); mouse motion while the right button is held
//!    turns the editor camera;
//! 2. `RedrawRequested`: a finished exposure map or play-check (`edit::play_check`, F6)
//!    and the palette's thumbnails made since (`edit::thumbnails`), each on a thread of
//!    its own, are taken up; the camera flies by the held
//!    keys; the interface is built (`panels`): the outline, palette, inspector, the view
//!    with its gizmo and overlays, and the shortcuts, which queue `Command`s rather than
//!    act;
//! 3. the commands run on the `Editor` and the `Engine` (a drag of the gizmo, a waypoint
//!    or an inspector field is one undo step, ended when the button is let go);
//! 4. the engine renders one frame of the still level (no simulation step runs): with the
//!    view still the film converges, and it stops at `CONVERGED_SPP`, after which the
//!    editor draws only on input or when a file changes on disk, a notice ends or an
//!    autosave is due (`about_to_wait`); F4 shows the game's 1-spp filtered view instead;
//! 5. present: the film is tone mapped into pixels' buffer, whose texture the interface
//!    draws as the view.
//!
//! # Using it
//!
//! `gloam edit levels/x.ron` opens the level as its file has it, path traced from a camera
//! of its own (it starts at the level's camera and is never saved). The view converges
//! while the camera and the level stand still, up to [`CONVERGED_SPP`] samples a pixel,
//! then rests; F4 switches to the game's own view (1 sample a pixel through the film's
//! filters), to see what the player will see. No key fires while a text field has the
//! keyboard.
//!
//! - **Look around:** hold the right mouse button in the view and fly with W A S D, E up
//!   and Q down (Shift: four times faster).
//! - **Select:** click in the view (the first thing the ray hits, up to its level entity)
//!   or a name in the outline on the left; Shift+click adds or removes. A drag in the view
//!   from empty space draws a box that selects every entity whose place lies inside it
//!   (Shift adds). The outline groups the entities by kind (player start, ways out,
//!   wardens, shards, lights, cameras, sounds), then by the asset they instance (`wall`,
//!   `floor`), and its search field keeps only the names that hold the text; beside each
//!   name, the eye hides the entity from the view and the lock lets clicks in the view pass
//!   through it (and keeps the gizmo off it), for this session only. Lights, the
//!   player start, the exit and cameras draw nothing, so they show as dots to click. The
//!   selection is outlined in orange; a selected warden's waypoints are squares to drag
//!   over the floor.
//! - **Move, rotate, scale:** W, E and R choose the gizmo's handles (axes and planes) when
//!   the camera is not flying. Snap (on by default) steps moves by the grid (0.25 m) and
//!   turns by the angle (15 degrees), both set in the tool bar; waypoints snap to the grid
//!   too. The grid is drawn over the ground plane at the snap size (G hides it), the X axis
//!   red and the Z axis blue, and the level hides it where it stands in front
//!   (`edit::camera::ViewDepth`).
//! - **Measure and come back:** M turns clicks into a measuring tape: two clicks, and the
//!   distance between the points they meet (with its run along each axis) is drawn between
//!   them. Ctrl+1 to Ctrl+4 keep the view as a bookmark; 1 to 4 go back to it.
//! - **Place:** choose a prefab (lamp, shard, warden with its lamp, door, exit, player
//!   start) or any glTF under `assets/` in the palette (`edit::palette`), each shown by a
//!   thumbnail the path tracer rendered (`edit::thumbnails`: the first opening renders them
//!   on one core, in about 4 s for the kit's 24; later ones read them from the cache in
//!   0.1 s), then click in the view: it lands where the click meets the level (the ground
//!   plane where it meets nothing; on the grid when snapping), under a unique name; a
//!   warden's first beat runs the roomiest way, short of any wall (`edit::first_beat`).
//!   Shift+click places another; Esc puts the choice back.
//! - **Start a level:** `gloam edit --new LEVEL`, or File > New level at this file, starts
//!   from a template (`edit::template`: an 8 x 8 m room, a player start, the way out under
//!   a lamp on its bracket) that the bot already wins; Ctrl+S writes it to LEVEL, which
//!   must not exist yet.
//! - **Inspect:** the panel on the right edits every component of the one selected entity:
//!   name, transform, the asset it instances (swapped among the project's, keeping the
//!   overrides and clip the new one has), material overrides, animation (clip, loop or
//!   once, speed, start), deformer (wobble or wave), sound (file, gain, loop), light
//!   (kind, colour, intensity, cones), warden (speed, route, lamp), shard, exit, player
//!   start, camera, knock, mover. A box beside each component adds or removes it. With
//!   nothing selected it edits the level's own properties: name, campaign number, sky and
//!   ambience. Under the asset, each of its named materials lists
//!   the values a level may replace for this one entity (base colour, metallic, roughness,
//!   transmission, ior, emissive, double sided): ticking one starts from the asset's value,
//!   and the file names only the values ticked.
//! - **Undo everything:** Ctrl+Z undoes, Ctrl+Shift+Z or Ctrl+Y redoes; a whole gizmo,
//!   waypoint or field drag is one step, and a deleted entity comes back with all its
//!   components at its old place in the file. Ctrl+D duplicates, Delete deletes, F frames
//!   the selection. Ctrl+C, Ctrl+X and Ctrl+V copy, cut and paste through the system
//!   clipboard as level text, so entities move between two open levels (their assets
//!   named again relative to the level pasted into).
//! - **Never lose work:** the title starts with `*` while there are unsaved edits. Ctrl+S
//!   writes the file atomically and keeps the previous one as `x.ron.bak`; a save that
//!   fails says why and leaves the old file and the edits as they were. The File menu's
//!   path field opens another level (Open this file) or saves this one under a new name
//!   (Save as this file); where the desktop has file dialogs (`dialogs`: the XDG desktop
//!   portal, or zenity, on Linux), Open... and Save as... show them too. Every two minutes
//!   unsaved edits go to `.x.ron.autosave` beside the level (the level file itself is
//!   untouched); neither name is a `*.ron`, so no level list picks them up. Opening a level
//!   whose autosave is newer than the file offers it back: load it (unsaved), or keep the
//!   file with the autosave moved aside to `.x.ron.autosave-N`. Closing, or
//!   opening another level, with unsaved edits asks first: save, don't save, or cancel;
//!   Enter takes the first answer, which loses nothing. A level loaded and saved with no
//!   edit is the same file, byte for byte.
//! - **Play-test:** F5 (or the tool bar's button) plays the level as it stands in the
//!   editor, unsaved edits and all, with the player standing on the floor under the
//!   editor's camera and facing its way (the level's own start when the camera is over no
//!   floor). Esc, or getting out, comes back to the editor exactly as it was left. In play,
//!   F2 does the opposite: it opens the level's file in the editor.
//! - **Play-check:** F6 (or the tool bar's button) runs the player bot on the level as it
//!   stands (`edit::play_check`), from the level's own start, on a thread of its own while
//!   the view stays live (first-light takes about 40 s). Beside the button it says how it
//!   went: won unseen in m:ss, with the route it walked drawn in green over the floor;
//!   caught, with the place ringed; or no unseen route, with the lit chokepoints ringed.
//!   An edit made since greys the answer out ("edited since"); F6 again checks anew.
//! - **Exposure and audibility maps:** X (or the tool bar's button) lays `gloam exposure`'s
//!   map over the floor (`headless::exposure`), computed by the rays the game uses: each cell
//!   the player can reach from the start in its colour (dark blue hidden, warming to yellow
//!   as the light gem rises, red above 0.5), standing or crouching. The darkest route from
//!   the start through every shard to the exit is drawn as a line, and where even that
//!   route has to cross light above 0.5 (no way round is darker) the crossing is ringed in
//!   red, "lit, no way round". The map can show instead where a noise the player makes
//!   would be heard by a warden (`edit::audibility`). The slider moves the wardens along
//!   their beats (red dots facing their way) and their lamps with them. The map follows
//!   every edit: it is computed on a thread of its own (about 0.3 s for the first level on
//!   two cores) while the view stays live, and again as soon as the level or the time has
//!   changed.
//! - **Hot reload:** the level file and every asset it uses are watched (`scene::watch`,
//!   `files`). When another program saves the level, the editor loads it; with unsaved
//!   edits it asks first: keep the edits (Enter), which the next save writes over the file,
//!   kept as `.bak`; or load the file, the edits written to the autosave file first. A
//!   changed asset is imported again and the entities that use it are respawned in place.
//!   A file that does not load leaves the level as it was and shows its
//!   `file:line:column: message` over the view until it is fixed. The editor's own saves
//!   are recognised by their bytes and not reloaded.

mod dialogs;
mod events;
mod files;
mod gui;
mod panels;

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context as _, anyhow};
use glam::Vec2;
use pixels::Pixels;
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::window::{CursorGrabMode, Window};

use crate::accel::Ray;
use crate::edit::audibility::{Audibility, CELL as AUDIBILITY_CELL, NoiseKind};
use crate::edit::camera::FlyCamera;
use crate::edit::camera::ViewDepth;
use crate::edit::palette::{asset_def, assets_folder};
use crate::edit::play_check::PlayCheck;
use crate::edit::thumbnails::Thumbnails;
use crate::edit::{Editor, Reloaded, surface_point};
use crate::film::FilterMode;
use crate::frame::Engine;
use crate::game::LevelEntity;
use crate::headless::exposure::Exposure;
use crate::render::RenderSettings;
use crate::scene::Scene;
use crate::scene::files::absolute;
use crate::scene::level::EntityDef;
use crate::scene::level::Level;
use crate::scene::watch::FileWatch;
use dialogs::{DialogKind, PendingDialog};
use panels::Panels;
use std::sync::mpsc::Receiver;

pub struct EditOptions {
    pub level: PathBuf,
    /// The view's render resolution (the window scales it into its panel).
    pub width: u32,
    pub height: u32,
    /// Quit after this many displayed frames (for tests), printing the frame times.
    pub frames: Option<u32>,
    /// `level` does not exist yet: start from the template (`edit::template`), written to
    /// `level` by the first save.
    pub new: bool,
}

/// Samples per pixel at which a still view stops rendering: past this the image no longer
/// visibly changes, and the editor leaves the cores to the designer.
pub const CONVERGED_SPP: u32 = 1024;

/// View pixels a side per cell of the depth the grid is hidden by (`ViewDepth`): 120 x 68
/// cells at 480 x 270, taken again only when the view or the level changes.
const VIEW_DEPTH_CELL: u32 = 4;

/// How often an idle editor looks for work that needs a frame (see `about_to_wait`).
const IDLE_FRAME: Duration = Duration::from_millis(250);

/// How often unsaved edits are written to the autosave file.
const AUTOSAVE_EVERY: Duration = Duration::from_secs(120);

/// How long a notice stays in the status bar.
const NOTICE_SECONDS: f32 = 8.0;

/// Flying speed in metres per second (Shift: four times that).
const FLY_SPEED: f32 = 4.0;

/// Radians of turn per pixel of mouse motion while flying.
const LOOK_PER_PIXEL: f32 = 0.003;

/// What the interface asks for; run after it is built, in order.
#[derive(Clone, Debug)]
pub enum Command {
    /// A click in the view: pick what the ray hits (`add`: Shift).
    Pick {
        ray: Ray,
        add: bool,
    },
    /// A box drawn in the view: what it holds becomes the selection (`add`: Shift).
    SelectMany {
        places: Vec<LevelEntity>,
        add: bool,
    },
    /// A click in the outline.
    Select {
        place: LevelEntity,
        add: bool,
    },
    ClearSelection,
    /// Place what the palette holds where a click's ray meets the level (on the grid of
    /// `snap` metres when snapping).
    Place {
        ray: Ray,
        item: panels::PaletteItem,
        snap: Option<f32>,
    },
    /// Part of a drag (gizmo, waypoint, inspector field): the entity named `name` becomes
    /// `def`.
    Edit {
        name: String,
        def: Box<EntityDef>,
    },
    /// Moves the view to frame the selection (F).
    FrameSelection,
    /// Moves the view to a bookmark (keys 1 to 4).
    GoTo(FlyCamera),
    /// A click with the measuring tool: the point it meets becomes a measured end.
    Measure(Ray),
    /// The selection to the system clipboard as level text (Ctrl+C).
    Copy,
    /// ... and then deleted (Ctrl+X).
    Cut,
    /// Level text from the system clipboard added to the level (Ctrl+V).
    Paste(String),
    /// Part of a drag of the level's own properties (inspector, nothing selected).
    Properties(Box<crate::edit::LevelProperties>),
    Duplicate,
    Delete,
    Undo,
    Redo,
    Save,
    /// Save to another file, which becomes the level being edited.
    SaveAs(PathBuf),
    /// Show the desktop's file dialog for Open or Save as.
    Browse(DialogKind),
    /// Read the file again, dropping unsaved edits.
    Revert,
    /// Converging view <-> the game's filtered view.
    ToggleView,
    /// Quit or open another level now, whatever is unsaved (asked first when there is).
    Leave(Leave),
    /// Save, then quit or open another level.
    SaveAndLeave(Leave),
    /// The file changed on disk while there were unsaved edits: keep the edits (a save
    /// will replace the file, which `.bak` then keeps).
    KeepEdits,
    /// ... or load the file (the edits go to the autosave file first).
    TakeFile,
    /// On opening, the autosave was newer than the file: edit the autosave's level, unsaved.
    TakeAutosave,
    /// ... or edit the file, the autosave moved aside (`edit::keep_autosave_aside`).
    KeepFileOverAutosave,
    /// Play the level as edited from the editor's camera (F5); Esc comes back.
    PlayTest,
    /// Run the player bot on the level as edited, in the background (F6).
    PlayCheck,
}

/// Where the editor goes when it leaves the level being edited.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Leave {
    /// Close the window.
    Quit,
    /// Edit this level file instead.
    Open(PathBuf),
    /// Start a new level from the template, to be saved to this file (which must not exist).
    New(PathBuf),
}

/// What a frame did, for the frame-time report.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum FrameKind {
    /// Nothing rendered: the view has converged.
    Idle,
    /// A frame added to the converging view.
    Converging,
    /// An edit under way this frame (the world changed).
    Dragging,
}

#[derive(Default)]
struct FrameLog {
    idle: Vec<f64>,
    converging: Vec<f64>,
    dragging: Vec<f64>,
}

impl FrameLog {
    fn push(&mut self, kind: FrameKind, ms: f64) {
        match kind {
            FrameKind::Idle => self.idle.push(ms),
            FrameKind::Converging => self.converging.push(ms),
            FrameKind::Dragging => self.dragging.push(ms),
        }
    }

    fn print(&self) {
        let median = |times: &[f64]| {
            let mut sorted = times.to_vec();
            sorted.sort_by(f64::total_cmp);
            sorted.get(sorted.len() / 2).copied()
        };
        for (label, times) in [
            ("idle", &self.idle),
            ("converging", &self.converging),
            ("dragging", &self.dragging),
        ] {
            if let Some(ms) = median(times) {
                println!(
                    "editor frames {label}: {} frames, median {ms:.2} ms",
                    times.len()
                );
            }
        }
    }
}

/// Opens the editor on `options.level`.
pub fn edit(options: EditOptions) -> anyhow::Result<()> {
    if cfg!(target_os = "linux")
        && std::env::var_os("DISPLAY").is_none()
        && std::env::var_os("WAYLAND_DISPLAY").is_none()
    {
        return Err(anyhow!(
            "no display to open the editor's window on (DISPLAY and WAYLAND_DISPLAY are unset)"
        ));
    }
    let mut event_loop =
        EventLoop::new().map_err(|error| anyhow!("cannot open the editor's window ({error})"))?;
    let editor = EditorApp::open(options)?;
    super::shell::run(&mut event_loop, super::shell::Mode::Edit(Box::new(editor)))
}

impl EditOptions {
    /// The editor's defaults for `level` (as `gloam edit LEVEL` has them).
    pub fn for_level(level: PathBuf) -> EditOptions {
        EditOptions {
            level,
            width: super::EDITOR_WIDTH,
            height: super::EDITOR_HEIGHT,
            frames: None,
            new: false,
        }
    }
}

impl EditorApp {
    /// Loads the level and starts watching it; the window opens when the loop runs.
    pub fn open(options: EditOptions) -> anyhow::Result<EditorApp> {
        let (scene, disk, editor) = if options.new {
            let scene = crate::edit::template::new_scene(&options.level)?;
            (scene, Vec::new(), Editor::unsaved())
        } else {
            let scene = Scene::load(&options.level)?;
            let disk = std::fs::read(&options.level)
                .with_context(|| format!("reading {}", options.level.display()))?;
            (scene, disk, Editor::new())
        };
        let mut engine = editor_engine(&scene, &options);
        let camera = FlyCamera::from_view(&engine);
        camera.install(&mut engine.world);
        let options_level = options.level.clone();
        let mut app = EditorApp {
            path: options.level.clone(),
            panels: Panels::new(&options.level),
            engine,
            editor,
            camera,
            disk,
            options,
            window: None,
            pixels: None,
            gui: None,
            watch: None,
            look: Vec2::ZERO,
            grabbed: false,
            last_frame: Instant::now(),
            autosaved: Instant::now(),
            last_check: Instant::now(),
            shows_converged: false,
            shown: 0,
            log: FrameLog::default(),
            error: None,
            switch: None,
            exposure: None,
            audibility: None,
            exposure_job: None,
            exposure_for: None,
            play_check: PlayCheck::default(),
            play_check_stale: false,
            dialog: None,
            thumbnails: palette_thumbnails(&options_level),
            view_depth: None,
        };
        if !app.options.new {
            app.panels.autosave_offer = crate::edit::newer_autosave(&app.path);
        }
        match FileWatch::new([app.path.clone()]) {
            Ok(watch) => app.watch = Some(watch),
            Err(error) => app.notify(format!("{error:#} (changes on disk will not be noticed)")),
        }
        app.watch_files();
        Ok(app)
    }

    /// After the loop has returned for good: the frame times, and the error that ended it.
    pub fn finish(&mut self) -> anyhow::Result<()> {
        self.log.print();
        self.thumbnails.poll();
        match self.thumbnails.summary() {
            Some(summary) => println!("editor thumbnails: {summary}"),
            None => println!("editor thumbnails: still rendering when the editor closed"),
        }
        match self.error.take() {
            Some(error) => Err(error),
            None => Ok(()),
        }
    }

    /// Back from a play-test: the level as it was left, the film converging again.
    pub fn back_from_play_test(&mut self, ended: String) {
        self.engine.film.reset = true;
        self.last_frame = Instant::now();
        self.notify(ended);
    }

    /// Plays the level as edited (unsaved edits too) from where the editor's camera stands:
    /// the player start moves under the camera, facing its way.
    fn play_test(&mut self, event_loop: &ActiveEventLoop) -> anyhow::Result<Option<String>> {
        let mut level = crate::game::level_from_world(&mut self.engine.world);
        // The floor under the camera, if the camera is over the level: else the level's
        // own start is kept (a camera out in the void would drop the player into it).
        let down = Ray::new(self.camera.position.into(), glam::Vec3A::NEG_Y);
        let floor = crate::edit::level_point(&self.engine, &down);
        let has_start = level.entities.iter().any(|e| e.player_spawn.is_some());
        let from = match (floor, has_start) {
            (Some(feet), _) => {
                let start = match level.entities.iter().position(|e| e.player_spawn.is_some()) {
                    Some(index) => &mut level.entities[index],
                    None => {
                        let mut start = EntityDef::named("play-test start");
                        start.player_spawn = Some(Default::default());
                        level.entities.push(start);
                        level.entities.last_mut().expect("just pushed")
                    }
                };
                start.transform.translation = feet;
                start.transform.rotation = glam::Vec3::new(0.0, self.camera.yaw.to_degrees(), 0.0);
                "from the editor's camera"
            }
            (None, true) => "from the level's start (the camera is over no floor)",
            (None, false) => {
                return Ok(Some(
                    "no play-test: the level has no player start and the camera is over no floor"
                        .to_owned(),
                ));
            }
        };
        level.playable = true;
        let scene = Scene::from_level(level, &self.path).map_err(|error| anyhow!("{error}"))?;
        self.switch = Some(super::shell::Switch::PlayTest(Box::new(
            super::shell::PlayTest {
                scene,
                level: self.path.clone(),
            },
        )));
        self.close_window();
        event_loop.exit();
        Ok(Some(format!("play-test {from}: Esc comes back")))
    }

    /// The view is still and has all the samples it will take.
    fn converged(&self) -> bool {
        let film = &self.engine.film;
        film.filter.mode == FilterMode::Off && film.frames >= CONVERGED_SPP && !film.reset
    }

    /// Closes the window (before the loop is left for another mode).
    fn close_window(&mut self) {
        self.set_grab(false);
        self.panels.flying = false;
        self.gui = None;
        self.pixels = None;
        self.window = None;
    }
}

/// Starts making the thumbnails of the palette's assets for `level` (`edit::thumbnails`).
fn palette_thumbnails(level: &Path) -> Thumbnails {
    Thumbnails::start(
        crate::edit::palette::asset_files(&assets_folder(level)),
        crate::edit::thumbnails::cache_folder(),
    )
}

/// The level as the editor shows it: posed at time 0, nothing simulated, rendered from the
/// editor's camera, the film converging while the view is still.
fn editor_engine(scene: &Scene, options: &EditOptions) -> Engine {
    let mut settings = RenderSettings::real_time(options.width, options.height);
    settings.spp = 1;
    Engine::new(scene, settings)
}

pub struct EditorApp {
    /// The level file being edited.
    path: PathBuf,
    engine: Engine,
    editor: Editor,
    camera: FlyCamera,
    panels: Panels,
    /// The level file's bytes as last read or written by the editor (a change on disk
    /// that is not the editor's own).
    disk: Vec<u8>,
    options: EditOptions,
    window: Option<Arc<Window>>,
    pixels: Option<Pixels<'static>>,
    gui: Option<gui::Gui>,
    /// The level file and its assets, watched for changes on disk (None: watching failed,
    /// which was said).
    watch: Option<FileWatch>,
    /// Mouse motion gathered while flying, not yet turned into a turn.
    look: Vec2,
    /// The cursor is grabbed for flying.
    grabbed: bool,
    last_frame: Instant,
    /// When an idle editor last looked for work (`about_to_wait`).
    last_check: Instant,
    /// The last frame drawn showed the converged view (its status counts every sample).
    shows_converged: bool,
    autosaved: Instant,
    shown: u32,
    log: FrameLog,
    error: Option<anyhow::Error>,
    /// Set when the editor leaves the loop for a play-test.
    pub switch: Option<super::shell::Switch>,
    /// The exposure map on show, the one being computed (on a thread of its own, so the
    /// view stays live), and the level and time the last one was asked for.
    exposure: Option<Exposure>,
    /// Where the noise the map shows would be heard (with the exposure map, when the map
    /// shows a noise).
    audibility: Option<Audibility>,
    exposure_job: Option<Receiver<Result<(Exposure, Option<Audibility>), String>>>,
    exposure_for: Option<(Level, f32, Option<NoiseKind>)>,
    /// The player bot on the level (F6): the check under way, and the last answer.
    play_check: PlayCheck,
    /// The level has been edited since the last play-check ran.
    play_check_stale: bool,
    /// The desktop's file dialog, while it is open.
    dialog: Option<PendingDialog>,
    /// The palette's thumbnails on their way (`edit::thumbnails`).
    thumbnails: Thumbnails,
    /// What the camera sees through the view, for the grid (None: to be taken again).
    view_depth: Option<ViewDepth>,
}

impl EditorApp {
    fn title(&self) -> String {
        let name = self
            .path
            .file_name()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
        let dirty = if self.editor.is_dirty() { "*" } else { "" };
        format!("{dirty}{name} - Gloam editor")
    }

    fn notify(&mut self, line: String) {
        println!("{line}");
        self.panels.notice = Some((Instant::now(), line));
    }

    fn fail(&mut self, event_loop: &ActiveEventLoop, error: anyhow::Error) {
        self.error = Some(error);
        event_loop.exit();
    }

    /// Runs one command; its error (a missing asset, a file that will not write) is shown
    /// and changes nothing.
    fn run(&mut self, event_loop: &ActiveEventLoop, command: Command) {
        let engine = &mut self.engine;
        let editor = &mut self.editor;
        let result: anyhow::Result<Option<String>> = match command {
            Command::Pick { ray, add } => {
                let picked = editor.select_by_ray(engine, &ray, add);
                Ok(picked.map(|place| format!("selected {}", entity_name(engine, place))))
            }
            Command::SelectMany { places, add } => {
                editor.select_many(&places, add);
                Ok(Some(format!("selected {}", editor.selection.len())))
            }
            Command::Select { place, add } => {
                editor.select(place, add);
                Ok(Some(format!("selected {}", entity_name(engine, place))))
            }
            Command::ClearSelection => {
                editor.selection.clear();
                Ok(None)
            }
            Command::Place { ray, item, snap } => {
                match crate::edit::placing_point(engine, &ray, snap) {
                    Some(at) => {
                        let def = match item {
                            panels::PaletteItem::Prefab(prefab) => {
                                crate::edit::prefab_def(engine, prefab, at, &self.path)
                            }
                            panels::PaletteItem::Asset(asset) => asset_def(&asset, at, &self.path),
                        };
                        editor
                            .place(engine, def)
                            .map(|place| Some(format!("placed {}", entity_name(engine, place))))
                    }
                    None => Ok(Some("nothing there to place on".to_owned())),
                }
            }
            Command::Edit { name, mut def } => {
                // Every edit leaves the entity fitted to the asset it instances: after a
                // swap, the overrides and clip the new asset lacks go; otherwise nothing
                // changes (the inspector offers only the asset's own).
                crate::edit::fit_to_asset(engine, &mut def)
                    .and_then(|()| {
                        editor.drag(engine, |entity| {
                            if entity.name == name {
                                *entity = (*def).clone();
                            }
                        })
                    })
                    .map(|()| None)
            }
            Command::Properties(properties) => {
                editor.drag_properties(engine, *properties);
                // The sky lights everything: the converged view starts again.
                engine.film.reset = true;
                Ok(None)
            }
            Command::FrameSelection => {
                let boxes: Vec<(glam::Vec3, glam::Vec3)> = editor
                    .selection
                    .iter()
                    .filter_map(|&place| crate::edit::entity_bounds(engine, place))
                    .collect();
                match boxes
                    .into_iter()
                    .reduce(|(a, b), (c, d)| (a.min(c), b.max(d)))
                {
                    Some((min, max)) => {
                        let aspect = self.options.width as f32 / self.options.height.max(1) as f32;
                        self.camera.frame(min, max, aspect);
                        Ok(None)
                    }
                    None => Ok(Some("nothing selected that draws, to frame".to_owned())),
                }
            }
            Command::GoTo(kept) => {
                self.camera = kept;
                Ok(None)
            }
            Command::Measure(ray) => match surface_point(engine, &ray) {
                Some(point) => {
                    self.panels.measured.push(point);
                    Ok(match self.panels.measured.as_slice() {
                        [a, b] => Some(format!("measured {:.2} m", (*b - *a).length())),
                        _ => Some("measuring from here: click the other end".to_owned()),
                    })
                }
                None => Ok(Some(
                    "the click meets neither the level nor the ground".to_owned(),
                )),
            },
            Command::Copy | Command::Cut => {
                let count = editor.selection.len();
                match editor.copy(engine, &self.path) {
                    Some(text) => {
                        self.panels.clipboard = Some(text);
                        if matches!(command, Command::Cut) {
                            editor
                                .delete(engine)
                                .map(|()| Some(format!("cut {count} to the clipboard")))
                        } else {
                            Ok(Some(format!("copied {count} to the clipboard")))
                        }
                    }
                    None => Ok(Some("nothing selected to copy".to_owned())),
                }
            }
            Command::Paste(text) => editor
                .paste(engine, &self.path, &text)
                .map(|count| Some(format!("pasted {count} from the clipboard")))
                .map_err(|error| error.context("the clipboard holds no level text")),
            Command::Duplicate => editor
                .duplicate(engine)
                .map(|()| Some(format!("duplicated: {} new", editor.selection.len()))),
            Command::Delete => {
                let count = editor.selection.len();
                editor
                    .delete(engine)
                    .map(|()| Some(format!("deleted {count}")))
            }
            Command::Undo => editor
                .undo(engine)
                .map(|done| Some(if done { "undone" } else { "nothing to undo" }.to_owned())),
            Command::Redo => editor
                .redo(engine)
                .map(|done| Some(if done { "redone" } else { "nothing to redo" }.to_owned())),
            Command::Save => self.save_to(self.path.clone()).map(Some),
            Command::SaveAndLeave(leave) => match self.save_to(self.path.clone()) {
                Ok(saved) => self.leave(event_loop, leave).map(|left| {
                    Some(match left {
                        Some(left) => format!("{saved}; {left}"),
                        None => saved,
                    })
                }),
                Err(error) => Err(error),
            },
            Command::Leave(leave) => self.leave(event_loop, leave),
            Command::SaveAs(path) => self.save_to(path).map(Some),
            Command::Browse(kind) => match &self.window {
                Some(window) => {
                    self.dialog = Some(PendingDialog::show(kind, window, &self.path));
                    self.panels.dialog_open = true;
                    Ok(None)
                }
                None => Ok(None),
            },
            Command::Revert => self.force_reload().map(|line| Some(line.to_owned())),
            Command::ToggleView => {
                let film = &mut self.engine.film;
                film.filter.mode = match film.filter.mode {
                    FilterMode::Off => FilterMode::Full,
                    _ => FilterMode::Off,
                };
                film.filter.reset();
                film.reset = true;
                Ok(Some(format!("view: {}", view_name(film.filter.mode))))
            }
            Command::PlayTest => self.play_test(event_loop),
            Command::PlayCheck => {
                let level = crate::game::level_from_world(&mut self.engine.world);
                Ok(Some(self.play_check.start(level, &self.path)))
            }
            Command::KeepEdits => {
                self.panels.conflict = false;
                // What is on disk now is the version the next save replaces (and keeps
                // as .bak): asking again about the same bytes would be noise.
                match std::fs::read(&self.path) {
                    Ok(bytes) => self.disk = bytes,
                    Err(error) => self.notify(format!("reading {}: {error}", self.path.display())),
                }
                Ok(Some(
                    "kept the edits; saving will replace the file on disk".to_owned(),
                ))
            }
            Command::TakeAutosave => self.take_autosave().map(Some),
            Command::KeepFileOverAutosave => {
                crate::edit::keep_autosave_aside(&self.path).map(|kept| {
                    Some(format!(
                        "kept the file; the autosave is now {}",
                        kept.display()
                    ))
                })
            }
            Command::TakeFile => {
                self.panels.conflict = false;
                match self.editor.autosave(&mut self.engine, &self.path) {
                    Ok(_) => {
                        let kept = crate::edit::autosave_path(&self.path);
                        self.force_reload().map(|line| {
                            Some(format!("{line}; the edits were kept in {}", kept.display()))
                        })
                    }
                    Err(error) => {
                        Err(error
                            .context("the edits could not be kept, so the file was not loaded"))
                    }
                }
            }
        };
        match result {
            Ok(Some(line)) => self.notify(line),
            Ok(None) => {}
            Err(error) => self.notify(format!("{error:#}")),
        }
    }

    /// Quits, or opens another level (on an error the level shown stays).
    fn leave(
        &mut self,
        event_loop: &ActiveEventLoop,
        leave: Leave,
    ) -> anyhow::Result<Option<String>> {
        match leave {
            Leave::Quit => {
                event_loop.exit();
                Ok(None)
            }
            Leave::Open(path) => self.open_level(path).map(Some),
            Leave::New(path) => self.new_level(path).map(Some),
        }
    }

    /// The desktop's file dialog has closed: what was chosen is opened or saved to.
    fn dialog_answered(&mut self, event_loop: &ActiveEventLoop) {
        let Some(answer) = self.dialog.as_ref().and_then(PendingDialog::poll) else {
            return;
        };
        let kind = self.dialog.take().map(|dialog| dialog.kind);
        self.panels.dialog_open = false;
        match (kind, answer) {
            (_, None) => self.notify("no file chosen".to_owned()),
            (Some(DialogKind::SaveAs), Some(path)) => self.run(event_loop, Command::SaveAs(path)),
            (Some(DialogKind::Open), Some(path)) => {
                let mut commands = Vec::new();
                let dirty = self.editor.is_dirty();
                self.panels.leave(Leave::Open(path), dirty, &mut commands);
                for command in commands {
                    self.run(event_loop, command);
                }
            }
            (None, Some(_)) => {}
        }
    }

    /// Keeps the exposure overlay's map up to date while it is shown: a finished
    /// computation is shown, and when the level or the time has changed since the last
    /// request and none is running, the next starts (so during a drag the map follows as
    /// fast as it is computed).
    fn update_exposure(&mut self) {
        if let Some(job) = &self.exposure_job {
            match job.try_recv() {
                Ok(Ok((exposure, audibility))) => {
                    let route = &exposure.map.route;
                    self.panels.exposure.status = match route.max_exposure {
                        None => "no walkable route through every shard to the exit".to_owned(),
                        Some(max) if route.exists => format!(
                            "darkest route peaks at {max:.2} ({:.0} ms)",
                            exposure.seconds * 1e3
                        ),
                        Some(max) => format!(
                            "darkest route peaks at {max:.2}: {} lit chokepoint(s) ({:.0} ms)",
                            route.chokepoints.len(),
                            exposure.seconds * 1e3
                        ),
                    };
                    if let Some(heard) = &audibility {
                        self.panels.exposure.status = format!(
                            "{} carries {:.0} m: heard from {:.0} m² of floor, kept quiet by walls on {:.0} m² ({:.0} ms)",
                            heard.noise.name(),
                            heard.radius,
                            heard.heard.len() as f32 * AUDIBILITY_CELL * AUDIBILITY_CELL,
                            heard.muffled.len() as f32 * AUDIBILITY_CELL * AUDIBILITY_CELL,
                            heard.seconds * 1e3
                        );
                    }
                    println!(
                        "exposure map at {} s: {}",
                        self.panels.exposure.time, self.panels.exposure.status
                    );
                    self.exposure = Some(exposure);
                    self.audibility = audibility;
                    self.exposure_job = None;
                }
                Ok(Err(problem)) => {
                    self.panels.exposure.status = problem;
                    self.exposure = None;
                    self.exposure_job = None;
                }
                Err(std::sync::mpsc::TryRecvError::Empty) => {}
                Err(std::sync::mpsc::TryRecvError::Disconnected) => self.exposure_job = None,
            }
        }
        if !self.panels.exposure.on || self.exposure_job.is_some() {
            return;
        }
        let wanted = (
            crate::game::level_from_world(&mut self.engine.world),
            self.panels.exposure.time,
            self.panels.exposure.heard,
        );
        if self.exposure_for.as_ref() == Some(&wanted) {
            return;
        }
        let (sender, receiver) = std::sync::mpsc::channel();
        let (level, time, heard) = wanted.clone();
        let path = self.path.clone();
        let threshold = self.panels.exposure.threshold;
        std::thread::spawn(move || {
            let result = Scene::from_level(level, &path)
                .map_err(|error| format!("{error}"))
                .and_then(|scene| {
                    let exposure = crate::headless::exposure::compute(
                        &scene,
                        time as f64,
                        crate::game::nav::CELL,
                        threshold,
                    )
                    .map_err(|problem| problem.to_string())?;
                    let audibility = heard.and_then(|noise| {
                        crate::edit::audibility::compute(&scene, time as f64, noise)
                    });
                    Ok((exposure, audibility))
                });
            let _ = sender.send(result);
        });
        if self.exposure.is_none() {
            self.panels.exposure.status = "computing...".to_owned();
        }
        self.exposure_job = Some(receiver);
        self.exposure_for = Some(wanted);
    }

    /// Says a finished play-check's outcome, and keeps its few words beside the button and
    /// whether the level has changed since it ran.
    fn update_play_check(&mut self) {
        if let Some(line) = self.play_check.poll() {
            self.notify(line);
        }
        if self.play_check.last.is_none() && self.play_check.running_for().is_none() {
            return;
        }
        let current = crate::game::level_from_world(&mut self.engine.world);
        (self.panels.play_check, self.play_check_stale) = self.play_check.status(&current);
    }

    fn set_grab(&mut self, grab: bool) {
        if grab == self.grabbed {
            return;
        }
        let Some(window) = &self.window else { return };
        if grab {
            let _ = window
                .set_cursor_grab(CursorGrabMode::Locked)
                .or_else(|_| window.set_cursor_grab(CursorGrabMode::Confined));
        } else {
            let _ = window.set_cursor_grab(CursorGrabMode::None);
        }
        window.set_cursor_visible(!grab);
        self.grabbed = grab;
    }

    fn redraw(&mut self, event_loop: &ActiveEventLoop) {
        let start = Instant::now();
        let seconds = (start - self.last_frame).as_secs_f32().min(0.25);
        self.last_frame = start;
        self.update_exposure();
        self.update_play_check();
        self.panels.thumbnails_arrived(self.thumbnails.poll());
        self.dialog_answered(event_loop);
        let (Some(window), Some(gui)) = (self.window.clone(), self.gui.as_mut()) else {
            return;
        };

        // 2. Fly by the held keys, then build the interface.
        let mut commands = Vec::new();
        let view = {
            let film = &self.engine.film;
            panels::ViewState {
                width: film.settings.width,
                height: film.settings.height,
                spp: film.frames,
                mode: film.filter.mode,
                texture: gui.view,
            }
        };
        let frame = panels::FrameInput::gather(&mut self.engine, &self.editor);
        let camera_before = self.camera;
        if self.panels.shows_grid()
            && self
                .view_depth
                .as_ref()
                .is_none_or(|depth| depth.camera != self.camera)
        {
            let (width, height) = (view.width / VIEW_DEPTH_CELL, view.height / VIEW_DEPTH_CELL);
            self.view_depth = Some(ViewDepth::of(&self.engine, &self.camera, width, height));
        }
        let overlays = panels::Overlays {
            depth: self.view_depth.as_ref(),
            exposure: self.exposure.as_ref(),
            audibility: self.audibility.as_ref(),
            play_check: self
                .play_check
                .checked()
                .map(|checked| (checked, self.play_check_stale)),
        };
        gui.run(&window, |ui| {
            self.panels
                .ui(ui, &frame, &view, &self.camera, overlays, &mut commands)
        });
        let flying = self.panels.flying;
        if flying {
            let held = &self.panels.fly_keys;
            let speed = if held.fast {
                4.0 * FLY_SPEED
            } else {
                FLY_SPEED
            };
            self.camera
                .turn(std::mem::take(&mut self.look) * LOOK_PER_PIXEL);
            self.camera.fly(held.direction() * speed * seconds);
        } else {
            self.look = Vec2::ZERO;
        }
        self.set_grab(flying);

        // 3. Run what the interface asked for, then what changed on disk.
        let edited = commands
            .iter()
            .any(|c| matches!(c, Command::Edit { .. } | Command::Properties(_)));
        let ran = !commands.is_empty();
        for command in commands {
            self.run(event_loop, command);
        }
        if ran {
            self.watch_files();
            // The level may have changed under the view.
            self.view_depth = None;
        }
        self.files_changed();
        if !self.panels.primary_down {
            self.editor.end_drag();
        }
        if self.camera != camera_before {
            self.camera.install(&mut self.engine.world);
        }
        if crate::edit::mark_entities(&mut self.engine, &self.panels.hidden, &self.panels.locked) {
            self.engine.film.reset = true;
            self.view_depth = None;
        }
        window.set_title(&self.title());

        // 4. Render unless the view has converged.
        let converged = self.converged();
        let kind = if edited {
            FrameKind::Dragging
        } else if converged {
            FrameKind::Idle
        } else {
            FrameKind::Converging
        };
        self.shows_converged = converged;
        if !converged || self.engine.film.reset {
            self.engine.advance(0.0);
        }
        if self.autosaved.elapsed() >= AUTOSAVE_EVERY {
            self.autosaved = Instant::now();
            match self.editor.autosave(&mut self.engine, &self.path) {
                Ok(true) => self.notify(format!(
                    "autosaved to {}",
                    crate::edit::autosave_path(&self.path).display()
                )),
                Ok(false) => {}
                Err(error) => self.notify(format!("autosave failed: {error:#}")),
            }
        }

        // 5. Present.
        let Some(pixels) = &mut self.pixels else {
            return;
        };
        (self.engine.film.image()).tone_map_into(pixels.frame_mut(), view.width, view.height, 1.0);
        let Some(gui) = self.gui.as_mut() else { return };
        let presented = pixels.render_with(|encoder, target, context| {
            gui.paint(encoder, target, context);
            Ok(())
        });
        if let Err(error) = presented {
            return self.fail(
                event_loop,
                anyhow!("presenting the editor's frame: {error}"),
            );
        }
        self.log.push(kind, start.elapsed().as_secs_f64() * 1e3);
        self.shown += 1;
        if self.options.frames.is_some_and(|limit| self.shown >= limit) {
            event_loop.exit();
        }
    }
}

/// The view's name in the status bar.
fn view_name(mode: FilterMode) -> &'static str {
    match mode {
        FilterMode::Off => "converging",
        _ => "game (1 spp, filtered)",
    }
}

/// Where a click at `at` (0..1 across the view, from the top-left) looks into the level.
pub fn view_ray(camera: &FlyCamera, width: u32, height: u32, at: Vec2) -> Ray {
    let film = crate::render::Camera::new(&camera.placement(), width, height);
    film.ray(at * Vec2::new(width as f32, height as f32), Vec2::ZERO)
}

/// The name of level entity `place` in the engine's world.
fn entity_name(engine: &mut Engine, place: LevelEntity) -> String {
    crate::game::level_io::entity_defs(&mut engine.world)
        .into_iter()
        .find(|(p, _)| *p == place)
        .map_or_else(String::new, |(_, def)| def.name)
}
