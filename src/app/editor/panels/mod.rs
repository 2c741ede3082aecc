//! The editor's interface, built each frame: the menu and tool bar, the outline and
//! palette (left), the inspector (right), the status line, and the view in the middle with
//! its overlays (the selection's boxes, markers for what draws nothing, wardens' routes
//! with draggable waypoints, the gizmo). It reads a snapshot of the level (`FrameInput`)
//! and only queues `Command`s: the window runs them after. The inspector (`inspector`) and
//! the view with its overlays (`view`) each have their own file.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use egui::{Color32, Key, KeyboardShortcut, Modifiers, Pos2, Rect, Sense, Stroke, TextureId};
use glam::{DMat4, EulerRot, Quat, Vec2, Vec3};
use transform_gizmo_egui::config::GizmoModeKind;
use transform_gizmo_egui::math::Transform as GizmoTransform;
use transform_gizmo_egui::prelude::*;

use super::dialogs::DialogKind;
use super::{Command, Leave, view_ray};
use crate::edit::audibility::{Audibility, NoiseKind};
use crate::edit::camera::FlyCamera;
use crate::edit::palette::{Prefab, asset_files, asset_reference, assets_folder, sound_files};
use crate::edit::play_check::Checked;
use crate::edit::{Editor, LevelProperties, entity_bounds};
use crate::film::FilterMode;
use crate::frame::Engine;
use crate::game::Assets;
use crate::game::LevelEntity;
use crate::game::level_io::entity_defs;
use crate::headless::exposure::Exposure;
use crate::scene::level::{
    AmbienceDef, AnimationDef, CameraDef, DeformerDef, EntityDef, ExitDef, KnockDef, LightDef,
    MaterialOverride, MoverDef, Playback, PlayerSpawn, ShardDef, SoundDef, WardenDef,
};
use crate::scene::model::Material;

mod inspector;
mod view;

use inspector::euler_degrees;

/// What the interface reads of the level this frame.
pub struct FrameInput {
    pub defs: Vec<(LevelEntity, EntityDef)>,
    pub selection: Vec<LevelEntity>,
    /// The world box of each selected entity that draws something.
    pub bounds: Vec<(Vec3, Vec3)>,
    pub dirty: bool,
    pub can_undo: bool,
    pub can_redo: bool,
    /// The materials of the asset the one selected entity instances (for its overrides).
    pub materials: Vec<Material>,
    /// The animation clips of the asset the one selected entity instances.
    pub clips: Vec<String>,
    /// The level's own properties (name, campaign, sky, ambience).
    pub properties: LevelProperties,
}

impl FrameInput {
    pub fn gather(engine: &mut Engine, editor: &Editor) -> FrameInput {
        let bounds = editor
            .selection
            .iter()
            .filter_map(|&place| entity_bounds(engine, place))
            .collect();
        let defs = entity_defs(&mut engine.world);
        let asset = match editor.selection.as_slice() {
            [place] => defs
                .iter()
                .find(|(p, _)| p == place)
                .and_then(|(_, def)| def.instance.as_ref())
                .and_then(|instance| {
                    let mut assets = engine.world.get_resource_mut::<Assets>()?;
                    assets.0.load(&instance.asset).ok()
                }),
            _ => None,
        };
        let materials = asset
            .as_ref()
            .map_or_else(Vec::new, |asset| asset.materials.clone());
        let clips = asset.as_ref().map_or_else(Vec::new, |asset| {
            (0..asset.animations.len())
                .map(|index| asset.animation_label(index))
                .collect()
        });
        FrameInput {
            defs,
            materials,
            clips,
            properties: LevelProperties::of(&engine.world),
            selection: editor.selection.clone(),
            bounds,
            dirty: editor.is_dirty(),
            can_undo: editor.can_undo(),
            can_redo: editor.can_redo(),
        }
    }

    fn def(&self, place: LevelEntity) -> Option<&EntityDef> {
        self.defs
            .iter()
            .find(|(p, _)| *p == place)
            .map(|(_, def)| def)
    }
}

/// The view's film this frame.
pub struct ViewState {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub mode: FilterMode,
    pub texture: TextureId,
}

/// What the palette holds, ready to place with the next click in the view.
#[derive(Clone, Debug, PartialEq)]
pub enum PaletteItem {
    Prefab(Prefab),
    Asset(PathBuf),
}

/// The fly keys held this frame.
#[derive(Clone, Copy, Debug, Default)]
pub struct FlyKeys {
    forward: bool,
    back: bool,
    left: bool,
    right: bool,
    up: bool,
    down: bool,
    pub fast: bool,
}

impl FlyKeys {
    /// x right, y up, z forward; each -1, 0 or 1.
    pub fn direction(&self) -> Vec3 {
        let axis = |plus: bool, minus: bool| plus as i32 as f32 - minus as i32 as f32;
        Vec3::new(
            axis(self.right, self.left),
            axis(self.up, self.down),
            axis(self.forward, self.back),
        )
    }
}

/// How many camera bookmarks there are (keys 1 to 4).
const BOOKMARKS: usize = 4;

/// Which handles the gizmo shows (W, E, R).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Tool {
    Move,
    Rotate,
    Scale,
}

/// The exposure overlay's controls.
#[derive(Clone, Debug, PartialEq)]
pub struct ExposureControls {
    pub on: bool,
    pub crouching: bool,
    /// Seconds into the wardens' beats.
    pub time: f32,
    /// The gem a route may not rise above.
    pub threshold: f32,
    /// What the map shows: where the player is seen (None), or where a noise would be
    /// heard (`edit::audibility`).
    pub heard: Option<NoiseKind>,
    /// What the last map says, or that one is being computed.
    pub status: String,
}

/// What the view draws over the level besides the selection: the exposure map, and the last
/// play-check with whether the level has been edited since.
#[derive(Clone, Copy, Default)]
pub struct Overlays<'a> {
    pub exposure: Option<&'a Exposure>,
    /// Where the chosen noise would be heard, when the map shows that.
    pub audibility: Option<&'a Audibility>,
    pub play_check: Option<(&'a Checked, bool)>,
    /// How far the camera sees through the view, for the ground grid to hide behind the
    /// level.
    pub depth: Option<&'a crate::edit::camera::ViewDepth>,
}

/// The longest time the exposure slider reaches, seconds.
const EXPOSURE_TIME_MAX: f32 = 60.0;

/// What a palette tile shows.
enum Picture<'a> {
    /// The thumbnail of this asset file, once it has arrived.
    Thumbnail(&'a Path),
    /// A symbol, for a prefab with no mesh of its own.
    Glyph(&'static str),
}

/// A prefab's symbol: what the palette shows for one with no mesh of its own to picture.
fn prefab_glyph(prefab: Prefab) -> &'static str {
    match prefab {
        Prefab::Lamp => "💡",
        Prefab::Shard => "◆",
        Prefab::Warden => "👤",
        Prefab::Door => "▯",
        Prefab::Exit => "🚪",
        Prefab::PlayerSpawn => "🚶",
    }
}

/// The side of a palette tile's picture, in points.
const THUMBNAIL_POINTS: f32 = 48.0;

/// Pixels within which a click takes a marker or a waypoint.
const HANDLE_RADIUS: f32 = 9.0;

pub struct Panels {
    /// The right button went down in the view and is still held: the camera flies.
    pub flying: bool,
    pub fly_keys: FlyKeys,
    /// The primary button is held (a drag in progress continues).
    pub primary_down: bool,
    /// Closing or opening another level with unsaved edits: ask first.
    pub leaving: Option<Leave>,
    /// The desktop can show file dialogs (Browse buttons beside the path field).
    pub dialogs: bool,
    /// A desktop file dialog is open (its Browse buttons wait).
    pub dialog_open: bool,
    /// The last thing the editor did or failed to do.
    pub notice: Option<(Instant, String)>,
    /// The level changed on disk while there are unsaved edits: ask which to keep.
    pub conflict: bool,
    /// The level's autosave, newer than the file, found on opening it: ask which to edit.
    pub autosave_offer: Option<PathBuf>,
    /// Level text for the system clipboard, handed to egui at the next frame (Ctrl+C).
    pub clipboard: Option<String>,
    /// The outline's search field.
    search: String,
    /// Entities hidden, and locked against clicks in the view, for this editing session.
    pub hidden: Vec<LevelEntity>,
    pub locked: Vec<LevelEntity>,
    /// Where a box select began in the view (a primary drag on nothing else).
    box_from: Option<Pos2>,
    /// The grid drawn over the ground plane at the snap size (G).
    show_grid: bool,
    /// Clicks in the view measure instead of selecting (M).
    measuring: bool,
    /// The points measured between: the first click's, then the second's.
    pub measured: Vec<Vec3>,
    /// Views kept with Ctrl+1..4 and gone back to with 1..4.
    bookmarks: [Option<FlyCamera>; BOOKMARKS],
    /// The level or an asset on disk does not load: its problems, shown over the view
    /// until a good version is loaded.
    pub file_error: Option<String>,
    pub exposure: ExposureControls,
    /// The play-check's state in a few words (playing, or its outcome), beside its button.
    pub play_check: String,
    tool: Tool,
    snapping: bool,
    /// Grid step for moving, metres.
    grid: f32,
    /// Angle step for rotating, degrees.
    angle: f32,
    armed: Option<PaletteItem>,
    assets_folder: PathBuf,
    assets: Vec<PathBuf>,
    /// `assets` as the level names them (an instance's choices).
    asset_names: Vec<String>,
    /// The sound files under the assets folder, as the level names them (the ambience's
    /// and sound components' choices).
    sounds: Vec<String>,
    /// Thumbnails arrived from `edit::thumbnails`, to become textures at the next frame.
    arrived: Vec<crate::edit::thumbnails::Arrived>,
    /// Each asset's thumbnail (by path), or why it has none.
    thumbnails: BTreeMap<PathBuf, Result<egui::TextureHandle, String>>,
    /// The path field for Open and Save as (always there, with or without a desktop file
    /// dialog).
    path_field: String,
    gizmo: Gizmo,
    /// The waypoint being dragged: (warden's name, index in its route).
    waypoint: Option<(String, usize)>,
}

impl Panels {
    pub fn new(level: &Path) -> Panels {
        let folder = assets_folder(level);
        let assets = asset_files(&folder);
        Panels {
            flying: false,
            fly_keys: FlyKeys::default(),
            primary_down: false,
            leaving: None,
            dialogs: super::dialogs::available(),
            dialog_open: false,
            notice: None,
            conflict: false,
            autosave_offer: None,
            clipboard: None,
            search: String::new(),
            hidden: Vec::new(),
            locked: Vec::new(),
            box_from: None,
            show_grid: true,
            measuring: false,
            measured: Vec::new(),
            bookmarks: [None; BOOKMARKS],
            file_error: None,
            exposure: ExposureControls {
                on: false,
                crouching: false,
                time: 0.0,
                threshold: 0.5,
                heard: None,
                status: String::new(),
            },
            play_check: String::new(),
            tool: Tool::Move,
            snapping: true,
            grid: 0.25,
            angle: 15.0,
            armed: None,
            asset_names: assets
                .iter()
                .map(|asset| asset_reference(level, asset))
                .collect(),
            assets,
            sounds: sound_files(&folder)
                .iter()
                .map(|sound| asset_reference(level, sound))
                .collect(),
            assets_folder: folder,
            arrived: Vec::new(),
            thumbnails: BTreeMap::new(),
            path_field: level.display().to_string(),
            gizmo: Gizmo::default(),
            waypoint: None,
        }
    }

    /// Another level is being edited: what belonged to the last one goes (the palette's
    /// assets, the choice held, the path field, a file's error), the designer's tools stay,
    /// and so do the thumbnails when the new level's assets folder is the last one's.
    pub fn opened(&mut self, level: &Path) {
        let fresh = Panels::new(level);
        let same_assets = fresh.assets_folder == self.assets_folder;
        *self = Panels {
            thumbnails: if same_assets {
                std::mem::take(&mut self.thumbnails)
            } else {
                BTreeMap::new()
            },
            arrived: if same_assets {
                std::mem::take(&mut self.arrived)
            } else {
                Vec::new()
            },
            notice: self.notice.take(),
            exposure: ExposureControls {
                status: String::new(),
                ..self.exposure.clone()
            },
            tool: self.tool,
            snapping: self.snapping,
            grid: self.grid,
            show_grid: self.show_grid,
            angle: self.angle,
            dialogs: self.dialogs,
            ..fresh
        };
    }

    pub fn ui(
        &mut self,
        ui: &mut egui::Ui,
        frame: &FrameInput,
        view: &ViewState,
        camera: &FlyCamera,
        overlays: Overlays,
        out: &mut Vec<Command>,
    ) {
        let ctx = ui.ctx().clone();
        self.primary_down = ctx.input(|i| i.pointer.primary_down());
        self.upload_thumbnails(&ctx);
        if let Some(text) = self.clipboard.take() {
            ctx.copy_text(text);
        }
        self.shortcuts(&ctx, camera, out);
        egui::Panel::top("menu").show_inside(ui, |ui| self.menu_bar(ui, frame, view, out));
        egui::Panel::bottom("status").show_inside(ui, |ui| self.status(ui, frame, view));
        egui::Panel::left("outline")
            .resizable(true)
            .default_size(220.0)
            .show_inside(ui, |ui| self.outline_and_palette(ui, frame, out));
        egui::Panel::right("inspector")
            .resizable(true)
            .default_size(280.0)
            .show_inside(ui, |ui| self.inspector(ui, frame, out));
        egui::CentralPanel::default()
            .frame(egui::Frame::NONE.fill(Color32::from_gray(12)))
            .show_inside(ui, |ui| self.view(ui, frame, view, camera, overlays, out));
        if self.leaving.is_some() {
            self.leave_prompt(&ctx, out);
        } else if self.conflict {
            conflict_prompt(&ctx, out);
        } else if let Some(autosave) = &self.autosave_offer
            && let Some(command) = autosave_prompt(&ctx, autosave)
        {
            out.push(command);
            self.autosave_offer = None;
        }
    }

    /// The keys. None fires while a text field has the keyboard.
    fn shortcuts(&mut self, ctx: &egui::Context, camera: &FlyCamera, out: &mut Vec<Command>) {
        self.fly_keys = FlyKeys::default();
        if ctx.egui_wants_keyboard_input() {
            return;
        }
        let command = |key| KeyboardShortcut::new(Modifiers::COMMAND, key);
        let command_shift = |key| KeyboardShortcut::new(Modifiers::COMMAND | Modifiers::SHIFT, key);
        ctx.input_mut(|input| {
            // The clipboard's keys come as events (egui-winit reads the system clipboard
            // for a paste), not as key presses.
            for event in &input.events {
                match event {
                    egui::Event::Copy => out.push(Command::Copy),
                    egui::Event::Cut => out.push(Command::Cut),
                    egui::Event::Paste(text) => out.push(Command::Paste(text.clone())),
                    _ => {}
                }
            }
            // Ctrl+Shift+Z before Ctrl+Z, which would also match it.
            if input.consume_shortcut(&command_shift(Key::Z))
                || input.consume_shortcut(&command(Key::Y))
            {
                out.push(Command::Redo);
            }
            if input.consume_shortcut(&command(Key::Z)) {
                out.push(Command::Undo);
            }
            if input.consume_shortcut(&command(Key::S)) {
                out.push(Command::Save);
            }
            if input.consume_shortcut(&command(Key::D)) {
                out.push(Command::Duplicate);
            }
            if input.consume_key(Modifiers::NONE, Key::Delete) {
                out.push(Command::Delete);
            }
            if !self.flying && input.consume_key(Modifiers::NONE, Key::F) {
                out.push(Command::FrameSelection);
            }
            if !self.flying && input.consume_key(Modifiers::NONE, Key::G) {
                self.show_grid = !self.show_grid;
            }
            if !self.flying && input.consume_key(Modifiers::NONE, Key::M) {
                self.measuring = !self.measuring;
                self.measured.clear();
            }
            let keys = [Key::Num1, Key::Num2, Key::Num3, Key::Num4];
            for (slot, key) in keys.into_iter().enumerate() {
                if input.consume_shortcut(&command(key)) {
                    self.bookmarks[slot] = Some(*camera);
                    self.notice = Some((
                        Instant::now(),
                        format!("view kept as bookmark {}", slot + 1),
                    ));
                } else if input.consume_key(Modifiers::NONE, key) {
                    match self.bookmarks[slot] {
                        Some(kept) => out.push(Command::GoTo(kept)),
                        None => {
                            self.notice = Some((
                                Instant::now(),
                                format!(
                                    "no bookmark {} yet: Ctrl+{} keeps the view",
                                    slot + 1,
                                    slot + 1
                                ),
                            ))
                        }
                    }
                }
            }
            if input.consume_key(Modifiers::NONE, Key::F4) {
                out.push(Command::ToggleView);
            }
            if input.consume_key(Modifiers::NONE, Key::F5) {
                out.push(Command::PlayTest);
            }
            if input.consume_key(Modifiers::NONE, Key::F6) {
                out.push(Command::PlayCheck);
            }
            if !self.flying && input.consume_key(Modifiers::NONE, Key::X) {
                self.exposure.on = !self.exposure.on;
            }
            if input.consume_key(Modifiers::NONE, Key::Escape) && self.armed.take().is_none() {
                out.push(Command::ClearSelection);
            }
            if self.flying {
                self.fly_keys = FlyKeys {
                    forward: input.key_down(Key::W),
                    back: input.key_down(Key::S),
                    left: input.key_down(Key::A),
                    right: input.key_down(Key::D),
                    up: input.key_down(Key::E),
                    down: input.key_down(Key::Q),
                    fast: input.modifiers.shift,
                };
            } else {
                for (key, tool) in [
                    (Key::W, Tool::Move),
                    (Key::E, Tool::Rotate),
                    (Key::R, Tool::Scale),
                ] {
                    if input.consume_key(Modifiers::NONE, key) {
                        self.tool = tool;
                    }
                }
            }
        });
    }

    fn menu_bar(
        &mut self,
        ui: &mut egui::Ui,
        frame: &FrameInput,
        view: &ViewState,
        out: &mut Vec<Command>,
    ) {
        egui::MenuBar::new().ui(ui, |ui| {
            // The File menu holds a text field: a click in it must not close the menu
            // (each command closes it itself).
            let file_menu = egui::containers::menu::MenuConfig::new()
                .close_behavior(egui::PopupCloseBehavior::CloseOnClickOutside);
            egui::containers::menu::MenuButton::new("File")
                .config(file_menu)
                .ui(ui, |ui| {
                    if ui.button("Save  (Ctrl+S)").clicked() {
                        out.push(Command::Save);
                        ui.close();
                    }
                    ui.separator();
                    ui.label("Level file:");
                    ui.text_edit_singleline(&mut self.path_field);
                    ui.horizontal(|ui| {
                        if ui.button("Open this file").clicked() {
                            let path = PathBuf::from(self.path_field.trim());
                            self.leave(Leave::Open(path), frame.dirty, out);
                            ui.close();
                        }
                        if ui.button("Save as this file").clicked() {
                            out.push(Command::SaveAs(PathBuf::from(self.path_field.trim())));
                            ui.close();
                        }
                        if ui.button("New level at this file").clicked() {
                            let path = PathBuf::from(self.path_field.trim());
                            self.leave(Leave::New(path), frame.dirty, out);
                            ui.close();
                        }
                    });
                    if self.dialogs {
                        ui.horizontal(|ui| {
                            for (label, kind) in [
                                ("Open...", DialogKind::Open),
                                ("Save as...", DialogKind::SaveAs),
                            ] {
                                let button = egui::Button::new(label);
                                if ui.add_enabled(!self.dialog_open, button).clicked() {
                                    out.push(Command::Browse(kind));
                                    ui.close();
                                }
                            }
                        });
                    }
                    ui.separator();
                    if ui
                        .add_enabled(frame.dirty, egui::Button::new("Revert to the file"))
                        .clicked()
                    {
                        out.push(Command::Revert);
                        ui.close();
                    }
                    if ui.button("Quit").clicked() {
                        self.leave(Leave::Quit, frame.dirty, out);
                        ui.close();
                    }
                });
            ui.menu_button("Edit", |ui| {
                let items = [
                    ("Undo  (Ctrl+Z)", frame.can_undo, Command::Undo),
                    (
                        "Redo  (Ctrl+Shift+Z, Ctrl+Y)",
                        frame.can_redo,
                        Command::Redo,
                    ),
                    (
                        "Duplicate  (Ctrl+D)",
                        !frame.selection.is_empty(),
                        Command::Duplicate,
                    ),
                    (
                        "Delete  (Del)",
                        !frame.selection.is_empty(),
                        Command::Delete,
                    ),
                ];
                for (label, enabled, command) in items {
                    if ui.add_enabled(enabled, egui::Button::new(label)).clicked() {
                        out.push(command);
                        ui.close();
                    }
                }
            });
            ui.separator();
            for (tool, label) in [
                (Tool::Move, "Move (W)"),
                (Tool::Rotate, "Rotate (E)"),
                (Tool::Scale, "Scale (R)"),
            ] {
                if ui.selectable_label(self.tool == tool, label).clicked() {
                    self.tool = tool;
                }
            }
            ui.separator();
            ui.checkbox(&mut self.show_grid, "Grid (G)");
            ui.checkbox(&mut self.snapping, "Snap");
            ui.add(
                egui::DragValue::new(&mut self.grid)
                    .range(0.01..=10.0)
                    .speed(0.01)
                    .suffix(" m"),
            );
            ui.add(
                egui::DragValue::new(&mut self.angle)
                    .range(1.0..=90.0)
                    .speed(0.5)
                    .suffix("°"),
            );
            ui.separator();
            let label = match view.mode {
                FilterMode::Off => "View: converging (F4)",
                _ => "View: game (F4)",
            };
            if ui.button(label).clicked() {
                out.push(Command::ToggleView);
            }
            if ui.button("Play-test (F5)").clicked() {
                out.push(Command::PlayTest);
            }
            if ui.button("Play-check (F6)").clicked() {
                out.push(Command::PlayCheck);
            }
            if !self.play_check.is_empty() {
                ui.label(&self.play_check);
            }
            ui.separator();
            ui.toggle_value(&mut self.exposure.on, "Exposure map (X)");
            if ui
                .toggle_value(&mut self.measuring, "Measure (M)")
                .changed()
            {
                self.measured.clear();
            }
        });
    }

    fn status(&mut self, ui: &mut egui::Ui, frame: &FrameInput, view: &ViewState) {
        ui.horizontal(|ui| {
            let film = match view.mode {
                FilterMode::Off => format!("{} spp", view.spp),
                _ => "game view".to_owned(),
            };
            ui.label(format!(
                "{}x{} {film}{}",
                view.width,
                view.height,
                if frame.dirty { "  | unsaved" } else { "" }
            ));
            ui.separator();
            if let Some(item) = &self.armed {
                let name = match item {
                    PaletteItem::Prefab(prefab) => prefab.name().to_owned(),
                    PaletteItem::Asset(path) => path.display().to_string(),
                };
                ui.colored_label(
                    Color32::LIGHT_YELLOW,
                    format!("click in the view to place {name}; Esc puts it back"),
                );
            } else if let Some((at, line)) = &self.notice
                && at.elapsed().as_secs_f32() < super::NOTICE_SECONDS
            {
                ui.label(line);
            } else {
                ui.weak("right mouse + W A S D Q E: fly   click: select   Shift+click: add");
            }
        });
    }

    fn outline_and_palette(
        &mut self,
        ui: &mut egui::Ui,
        frame: &FrameInput,
        out: &mut Vec<Command>,
    ) {
        let shift = ui.input(|i| i.modifiers.shift);
        ui.heading("Level");
        ui.add(egui::TextEdit::singleline(&mut self.search).hint_text("search names"));
        let searching = !self.search.trim().is_empty();
        egui::ScrollArea::vertical()
            .id_salt("outline")
            .max_height(ui.available_height() * 0.55)
            .show(ui, |ui| {
                let groups = crate::edit::outline_groups(&frame.defs, &self.search);
                if groups.is_empty() {
                    ui.weak("no entity by that name");
                }
                for (group, members) in groups {
                    let holds_selection = members.iter().any(|(p, _)| frame.selection.contains(p));
                    let header =
                        egui::CollapsingHeader::new(format!("{group} ({})", members.len()))
                            .id_salt(("outline group", &group))
                            .default_open(members.len() <= 8);
                    // A search, or a selection made in the view, opens the groups it finds.
                    let header = if searching || holds_selection {
                        header.open(Some(true))
                    } else {
                        header
                    };
                    header.show(ui, |ui| {
                        for (place, def) in members {
                            ui.horizontal(|ui| {
                                for (marked, glyph, tip) in [
                                    (&mut self.hidden, "👁", "hidden in the editor (not saved)"),
                                    (
                                        &mut self.locked,
                                        "🔒",
                                        "locked: clicks in the view pass through",
                                    ),
                                ] {
                                    let on = marked.contains(place);
                                    if ui.selectable_label(on, glyph).on_hover_text(tip).clicked() {
                                        if on {
                                            marked.retain(|p| p != place);
                                        } else {
                                            marked.push(*place);
                                        }
                                    }
                                }
                                let selected = frame.selection.contains(place);
                                if ui.selectable_label(selected, &def.name).clicked() {
                                    out.push(Command::Select {
                                        place: *place,
                                        add: shift,
                                    });
                                }
                            });
                        }
                    });
                }
            });
        ui.separator();
        ui.heading("Palette");
        egui::ScrollArea::vertical()
            .id_salt("palette")
            .show(ui, |ui| {
                ui.label("Prefabs");
                ui.horizontal_wrapped(|ui| {
                    for prefab in Prefab::ALL {
                        let asset = prefab.kit_asset().map(|file| self.assets_folder.join(file));
                        let item = PaletteItem::Prefab(prefab);
                        let picture = match asset.as_deref() {
                            Some(asset) => Picture::Thumbnail(asset),
                            None => Picture::Glyph(prefab_glyph(prefab)),
                        };
                        self.palette_tile(ui, item, prefab.name(), picture);
                    }
                });
                ui.label("Assets");
                ui.horizontal_wrapped(|ui| {
                    // Taken out for the loop, as the tiles change `self` (which is armed).
                    let assets = std::mem::take(&mut self.assets);
                    for asset in &assets {
                        let name = asset
                            .file_stem()
                            .map_or_else(String::new, |stem| stem.to_string_lossy().into_owned());
                        let item = PaletteItem::Asset(asset.clone());
                        self.palette_tile(ui, item, &name, Picture::Thumbnail(asset));
                    }
                    self.assets = assets;
                });
            });
    }

    /// One tile of the palette: its picture over its name; a click arms it, a second
    /// disarms it.
    fn palette_tile(
        &mut self,
        ui: &mut egui::Ui,
        item: PaletteItem,
        name: &str,
        picture: Picture,
    ) -> egui::Response {
        let armed = self.armed.as_ref() == Some(&item);
        let side = egui::vec2(THUMBNAIL_POINTS, THUMBNAIL_POINTS);
        let glyph = |glyph: &str| {
            egui::Button::new(egui::RichText::new(glyph).size(THUMBNAIL_POINTS * 0.5))
                .min_size(side)
        };
        let (button, hover) = match picture {
            Picture::Glyph(symbol) => (glyph(symbol), name.to_owned()),
            Picture::Thumbnail(asset) => {
                let file = asset
                    .strip_prefix(&self.assets_folder)
                    .unwrap_or(asset)
                    .display()
                    .to_string();
                match self.thumbnails.get(asset) {
                    Some(Ok(texture)) => (
                        egui::Button::image(egui::Image::new(texture).fit_to_exact_size(side)),
                        file,
                    ),
                    Some(Err(problem)) => (glyph("⚠"), format!("{file}\nno thumbnail: {problem}")),
                    // Still rendering.
                    None => (glyph("…"), file),
                }
            }
        };
        let tile = egui::vec2(THUMBNAIL_POINTS + 8.0, THUMBNAIL_POINTS + 22.0);
        let response = ui
            .allocate_ui(tile, |ui| {
                ui.vertical_centered(|ui| {
                    let response = ui.add(button.selected(armed)).on_hover_text(&hover);
                    ui.add(egui::Label::new(egui::RichText::new(name).small()).truncate());
                    response
                })
                .inner
            })
            .inner;
        if response.clicked() {
            self.armed = (!armed).then_some(item);
        }
        response
    }

    /// The ground grid is on (G).
    pub fn shows_grid(&self) -> bool {
        self.show_grid
    }

    /// Thumbnails made since the last frame (`edit::thumbnails`), shown from the next.
    pub fn thumbnails_arrived(&mut self, arrived: Vec<crate::edit::thumbnails::Arrived>) {
        self.arrived.extend(arrived);
    }

    /// The thumbnails that arrived become egui textures (on the frame's context).
    fn upload_thumbnails(&mut self, ctx: &egui::Context) {
        for (asset, thumbnail) in self.arrived.drain(..) {
            let texture = thumbnail.map(|picture| {
                let size = [picture.width as usize, picture.height as usize];
                let image = egui::ColorImage::from_rgba_unmultiplied(size, &picture.rgba);
                let name = format!("thumbnail {}", asset.display());
                ctx.load_texture(name, image, egui::TextureOptions::LINEAR)
            });
            self.thumbnails.insert(asset, texture);
        }
    }

    /// Quits or opens another level now, or asks first if there are unsaved edits.
    pub fn leave(&mut self, leave: Leave, dirty: bool, out: &mut Vec<Command>) {
        if dirty {
            self.leaving = Some(leave);
        } else {
            out.push(Command::Leave(leave));
        }
    }

    /// Unsaved edits and the designer is leaving them: save, drop or stay. The answer
    /// that loses nothing has the keyboard, so Enter saves.
    fn leave_prompt(&mut self, ctx: &egui::Context, out: &mut Vec<Command>) {
        let Some(leave) = self.leaving.clone() else {
            return;
        };
        let (save, drop) = match leave {
            Leave::Quit => ("Save and quit", "Quit without saving"),
            Leave::Open(_) => ("Save and open", "Open without saving"),
            Leave::New(_) => ("Save and start it", "Start it without saving"),
        };
        egui::Modal::new(egui::Id::new("leave prompt")).show(ctx, |ui| {
            ui.heading("Unsaved changes");
            ui.label("The level has edits that are not saved.");
            let answer = prompt_answers(ui, &[save, drop, "Cancel"]);
            match answer {
                Some(0) => out.push(Command::SaveAndLeave(leave.clone())),
                Some(1) => out.push(Command::Leave(leave.clone())),
                _ => {}
            }
            if answer.is_some() {
                self.leaving = None;
            }
        });
    }
}

/// The level changed on disk while there are unsaved edits: which to keep. Neither is
/// dropped silently: keeping the edits means the next save replaces the file (kept as
/// `.bak`); taking the file writes the edits to the autosave file first.
fn conflict_prompt(ctx: &egui::Context, out: &mut Vec<Command>) {
    egui::Modal::new(egui::Id::new("changed on disk")).show(ctx, |ui| {
        ui.heading("The level changed on disk");
        ui.label("Someone else saved the level file while you have unsaved edits.");
        let answers = [
            "Keep my edits",
            "Load the file (my edits go to the autosave file)",
        ];
        match prompt_answers(ui, &answers) {
            Some(0) => out.push(Command::KeepEdits),
            Some(_) => out.push(Command::TakeFile),
            None => {}
        }
    });
}

/// The level opened has an autosave newer than the file: edit that, or the file. Neither
/// is lost: the file stays as it is on disk until a save, and an autosave not taken is
/// moved aside rather than written over by the next one.
fn autosave_prompt(ctx: &egui::Context, autosave: &Path) -> Option<Command> {
    egui::Modal::new(egui::Id::new("newer autosave"))
        .show(ctx, |ui| {
            ui.heading("An autosave is newer than the file");
            ui.label(format!(
                "{} holds edits made after the level was last saved.",
                autosave.display()
            ));
            let answers = [
                "Load the autosave (unsaved until Ctrl+S)",
                "Keep the file (the autosave is moved aside)",
            ];
            match prompt_answers(ui, &answers) {
                Some(0) => Some(Command::TakeAutosave),
                Some(_) => Some(Command::KeepFileOverAutosave),
                None => None,
            }
        })
        .inner
}

/// A prompt's answers in a row; which was clicked. The first, the one that loses nothing,
/// has the keyboard while nothing else does, so Enter (or Space) picks it as in the
/// desktop's own dialogs; once answered the keyboard is let go at once, so a shortcut
/// pressed straight after reaches the editor.
fn prompt_answers(ui: &mut egui::Ui, answers: &[&str]) -> Option<usize> {
    ui.horizontal(|ui| {
        let mut clicked = None;
        for (index, answer) in answers.iter().enumerate() {
            let button = ui.button(*answer);
            if index == 0 && ui.memory(|memory| memory.focused().is_none()) {
                button.request_focus();
            }
            if button.clicked() {
                clicked = Some(index);
                button.surrender_focus();
            }
        }
        clicked
    })
    .inner
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn euler_degrees_inverts_the_level_rotation() {
        for rotation in [
            Vec3::new(0.0, 90.0, 0.0),
            Vec3::new(-90.0, 0.0, 0.0),
            Vec3::new(10.0, -135.0, 30.0),
        ] {
            let def = crate::scene::level::TransformDef {
                rotation,
                ..Default::default()
            };
            let back = euler_degrees(def.rotation_quat());
            assert!(
                (back - rotation).abs().max_element() < 1e-2,
                "{rotation} -> {back}"
            );
        }
    }

    /// Arrived thumbnails become textures of their size (a failed one keeps its reason), a
    /// click on a tile arms its item and a second disarms it, and opening another level
    /// keeps the thumbnails only when it uses the same assets folder.
    #[test]
    fn thumbnails_become_tiles_that_arm_on_a_click_and_stay_for_the_same_assets() {
        use crate::edit::thumbnails::Thumbnail;

        let ctx = egui::Context::default();
        let level = Path::new(env!("CARGO_MANIFEST_DIR")).join("levels/first-light.ron");
        let mut panels = Panels::new(&level);
        let crate_asset = panels.assets_folder.join("kit/crate.glb");
        let broken = panels.assets_folder.join("kit/broken.glb");
        let picture = Thumbnail {
            width: 3,
            height: 2,
            rgba: vec![200; 3 * 2 * 4],
        };
        panels.thumbnails_arrived(vec![
            (crate_asset.clone(), Ok(picture)),
            (broken.clone(), Err("broken.glb: not a glTF file".into())),
        ]);
        let item = PaletteItem::Asset(crate_asset.clone());
        let frame = |panels: &mut Panels, events: Vec<egui::Event>| {
            let input = egui::RawInput {
                events,
                ..Default::default()
            };
            let mut rect = Rect::NOTHING;
            let _ = ctx.run_ui(input, |ui| {
                panels.upload_thumbnails(ui.ctx());
                let picture = Picture::Thumbnail(&crate_asset);
                rect = panels.palette_tile(ui, item.clone(), "crate", picture).rect;
            });
            rect
        };
        let rect = frame(&mut panels, Vec::new());
        match panels.thumbnails.get(&crate_asset) {
            Some(Ok(texture)) => assert_eq!(texture.size(), [3, 2]),
            Some(Err(problem)) => panic!("the crate has a picture: {problem}"),
            None => panic!("the crate's picture arrived"),
        }
        assert!(matches!(
            panels.thumbnails.get(&broken),
            Some(Err(problem)) if problem.contains("broken.glb")
        ));

        let click = |at: Pos2| {
            [true, false].map(|pressed| egui::Event::PointerButton {
                pos: at,
                button: egui::PointerButton::Primary,
                pressed,
                modifiers: Modifiers::NONE,
            })
        };
        let at = rect.center();
        frame(&mut panels, vec![egui::Event::PointerMoved(at)]);
        frame(&mut panels, click(at).to_vec());
        assert_eq!(panels.armed, Some(item.clone()), "a click arms the tile");
        frame(&mut panels, click(at).to_vec());
        assert_eq!(panels.armed, None, "a second click disarms it");

        panels.opened(&level.with_file_name("cellar.ron"));
        assert_eq!(
            panels.thumbnails.len(),
            2,
            "the same assets folder keeps them"
        );
        let project = std::env::temp_dir().join(format!("gloam-palette-{}", std::process::id()));
        std::fs::create_dir_all(project.join("assets")).expect("a scratch project");
        panels.opened(&project.join("levels/x.ron"));
        let _ = std::fs::remove_dir_all(&project);
        assert!(
            panels.thumbnails.is_empty(),
            "another assets folder drops them"
        );
    }

    /// The editor's keys as egui hands them over, run through `shortcuts` headless.
    #[test]
    fn keys_keep_and_recall_views_toggle_the_tools_and_the_clipboard_becomes_commands() {
        let ctx = egui::Context::default();
        let mut panels = Panels::new(Path::new("levels/first-light.ron"));
        let camera = FlyCamera {
            position: Vec3::new(1.0, 2.0, 3.0),
            yaw: 0.5,
            pitch: -0.2,
            yfov: 1.0,
            znear: 0.05,
        };
        let run = |panels: &mut Panels, events: Vec<egui::Event>| {
            let mut out = Vec::new();
            let input = egui::RawInput {
                events,
                ..Default::default()
            };
            let _ = ctx.run_ui(input, |ui| panels.shortcuts(ui.ctx(), &camera, &mut out));
            out
        };
        let key = |key, modifiers| egui::Event::Key {
            key,
            physical_key: None,
            pressed: true,
            repeat: false,
            modifiers,
        };
        let ctrl = Modifiers::CTRL | Modifiers::COMMAND;

        assert!(run(&mut panels, vec![key(Key::Num1, Modifiers::NONE)]).is_empty());
        assert!(
            panels
                .notice
                .as_ref()
                .is_some_and(|(_, n)| n.contains("no bookmark 1"))
        );
        assert!(run(&mut panels, vec![key(Key::Num1, ctrl)]).is_empty());
        match run(&mut panels, vec![key(Key::Num1, Modifiers::NONE)]).as_slice() {
            [Command::GoTo(kept)] => assert_eq!(*kept, camera),
            other => panic!("1 after Ctrl+1 goes back to the view kept: {other:?}"),
        }
        assert!(run(&mut panels, vec![key(Key::Num2, Modifiers::NONE)]).is_empty());

        assert!(panels.show_grid);
        run(&mut panels, vec![key(Key::G, Modifiers::NONE)]);
        assert!(!panels.show_grid, "G hides the grid");
        panels.measured.push(Vec3::ONE);
        run(&mut panels, vec![key(Key::M, Modifiers::NONE)]);
        assert!(
            panels.measuring && panels.measured.is_empty(),
            "M starts a fresh tape"
        );
        assert!(matches!(
            run(&mut panels, vec![key(Key::F, Modifiers::NONE)]).as_slice(),
            [Command::FrameSelection]
        ));

        let clipboard = run(
            &mut panels,
            vec![
                egui::Event::Copy,
                egui::Event::Cut,
                egui::Event::Paste("(version: 1)".into()),
            ],
        );
        assert!(
            matches!(
                clipboard.as_slice(),
                [Command::Copy, Command::Cut, Command::Paste(text)] if text == "(version: 1)"
            ),
            "{clipboard:?}"
        );
    }

    #[test]
    fn fly_keys_make_a_direction() {
        let keys = FlyKeys {
            forward: true,
            left: true,
            up: true,
            ..FlyKeys::default()
        };
        assert_eq!(keys.direction(), Vec3::new(-1.0, 1.0, 1.0));
    }
}
