//! The editor's interface, built each frame: the menu and tool bar, the outline and
//! palette (left), the inspector (right), the status line, and the view in the middle with
//! its overlays (the selection's boxes, markers for what draws nothing, wardens' routes
//! with draggable waypoints, the gizmo). It reads a snapshot of the level (`FrameInput`)
//! and only queues `Command`s: the window runs them after.

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
use crate::edit::exposure::Exposure;
use crate::edit::palette::{Prefab, asset_files, assets_folder};
use crate::edit::play_check::Checked;
use crate::edit::{Editor, entity_bounds};
use crate::film::FilterMode;
use crate::frame::Engine;
use crate::game::Assets;
use crate::game::LevelEntity;
use crate::game::level_io::entity_defs;
use crate::scene::level::{
    CameraDef, EntityDef, ExitDef, KnockDef, LightDef, MaterialOverride, MoverDef, PlayerSpawn,
    ShardDef, WardenDef,
};
use crate::scene::model::Material;

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
}

impl FrameInput {
    pub fn gather(engine: &mut Engine, editor: &Editor) -> FrameInput {
        let bounds = editor
            .selection
            .iter()
            .filter_map(|&place| entity_bounds(engine, place))
            .collect();
        let defs = entity_defs(&mut engine.world);
        let materials = match editor.selection.as_slice() {
            [place] => defs
                .iter()
                .find(|(p, _)| p == place)
                .and_then(|(_, def)| def.instance.as_ref())
                .and_then(|instance| {
                    let mut assets = engine.world.get_resource_mut::<Assets>()?;
                    assets.0.load(&instance.asset).ok()
                })
                .map_or_else(Vec::new, |asset| asset.materials.clone()),
            _ => Vec::new(),
        };
        FrameInput {
            defs,
            materials,
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
}

/// The longest time the exposure slider reaches, seconds.
const EXPOSURE_TIME_MAX: f32 = 60.0;

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
        Panels {
            flying: false,
            fly_keys: FlyKeys::default(),
            primary_down: false,
            leaving: None,
            dialogs: super::dialogs::available(),
            dialog_open: false,
            notice: None,
            conflict: false,
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
            assets: asset_files(&folder),
            assets_folder: folder,
            path_field: level.display().to_string(),
            gizmo: Gizmo::default(),
            waypoint: None,
        }
    }

    /// Another level is being edited: what belonged to the last one goes (the palette's
    /// assets, the choice held, the path field, a file's error), the designer's tools stay.
    pub fn opened(&mut self, level: &Path) {
        let fresh = Panels::new(level);
        *self = Panels {
            notice: self.notice.take(),
            exposure: ExposureControls {
                status: String::new(),
                ..self.exposure.clone()
            },
            tool: self.tool,
            snapping: self.snapping,
            grid: self.grid,
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
        self.shortcuts(&ctx, out);
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
        }
    }

    /// The keys. None fires while a text field has the keyboard.
    fn shortcuts(&mut self, ctx: &egui::Context, out: &mut Vec<Command>) {
        self.fly_keys = FlyKeys::default();
        if ctx.egui_wants_keyboard_input() {
            return;
        }
        let command = |key| KeyboardShortcut::new(Modifiers::COMMAND, key);
        let command_shift = |key| KeyboardShortcut::new(Modifiers::COMMAND | Modifiers::SHIFT, key);
        ctx.input_mut(|input| {
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
        egui::ScrollArea::vertical()
            .id_salt("outline")
            .max_height(ui.available_height() * 0.55)
            .show(ui, |ui| {
                for (place, def) in &frame.defs {
                    let selected = frame.selection.contains(place);
                    if ui.selectable_label(selected, &def.name).clicked() {
                        out.push(Command::Select {
                            place: *place,
                            add: shift,
                        });
                    }
                }
            });
        ui.separator();
        ui.heading("Palette");
        egui::ScrollArea::vertical()
            .id_salt("palette")
            .show(ui, |ui| {
                ui.label("Prefabs");
                for prefab in Prefab::ALL {
                    let item = PaletteItem::Prefab(prefab);
                    let armed = self.armed.as_ref() == Some(&item);
                    if ui.selectable_label(armed, prefab.name()).clicked() {
                        self.armed = (!armed).then_some(item);
                    }
                }
                ui.label("Assets");
                for asset in &self.assets {
                    let label = asset
                        .strip_prefix(&self.assets_folder)
                        .unwrap_or(asset)
                        .display()
                        .to_string();
                    let item = PaletteItem::Asset(asset.clone());
                    let armed = self.armed.as_ref() == Some(&item);
                    if ui.selectable_label(armed, label).clicked() {
                        self.armed = (!armed).then_some(item);
                    }
                }
            });
    }

    fn inspector(&mut self, ui: &mut egui::Ui, frame: &FrameInput, out: &mut Vec<Command>) {
        ui.heading("Inspector");
        let selected: Vec<&EntityDef> = frame
            .selection
            .iter()
            .filter_map(|&p| frame.def(p))
            .collect();
        match selected.as_slice() {
            [] => {
                ui.weak("Nothing selected.");
            }
            [original] => {
                egui::ScrollArea::vertical().show(ui, |ui| {
                    let mut def = (*original).clone();
                    inspect(ui, &mut def, &frame.materials);
                    let taken = def.name != original.name
                        && frame.defs.iter().any(|(_, other)| other.name == def.name);
                    if taken || def.name.trim().is_empty() {
                        ui.colored_label(
                            Color32::LIGHT_RED,
                            "names must be unique and not empty: kept the old one",
                        );
                        def.name = original.name.clone();
                    }
                    if def != **original {
                        out.push(Command::Edit {
                            name: original.name.clone(),
                            def: Box::new(def),
                        });
                    }
                });
            }
            many => {
                ui.label(format!("{} selected", many.len()));
                for def in many {
                    ui.label(&def.name);
                }
            }
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

    /// The problems of a file on disk that does not load, over the top of the view.
    fn file_error(&self, painter: &egui::Painter, rect: Rect) {
        let Some(error) = &self.file_error else {
            return;
        };
        let text = painter.layout(
            error.clone(),
            egui::FontId::monospace(12.0),
            Color32::from_rgb(255, 120, 110),
            rect.width() - 16.0,
        );
        let at = rect.min + egui::vec2(8.0, 8.0);
        painter.rect_filled(
            Rect::from_min_size(at, text.size()).expand(4.0),
            3.0,
            Color32::from_black_alpha(200),
        );
        painter.galley(at, text, Color32::WHITE);
    }

    /// The path-traced view, its overlays, the gizmo, and what clicks in it do.
    fn view(
        &mut self,
        ui: &mut egui::Ui,
        frame: &FrameInput,
        view: &ViewState,
        camera: &FlyCamera,
        overlays: Overlays,
        out: &mut Vec<Command>,
    ) {
        let available = ui.available_rect_before_wrap();
        let aspect = view.width as f32 / view.height as f32;
        let mut size = available.size();
        if size.x / size.y.max(1.0) > aspect {
            size.x = size.y * aspect;
        } else {
            size.y = size.x / aspect;
        }
        let rect = Rect::from_center_size(available.center(), size);
        let response = ui.allocate_rect(rect, Sense::click_and_drag());
        let painter = ui.painter_at(rect);
        painter.image(
            view.texture,
            rect,
            Rect::from_min_max(Pos2::ZERO, Pos2::new(1.0, 1.0)),
            Color32::WHITE,
        );
        let (pressed_secondary, secondary_down) = ui.input(|i| {
            (
                i.pointer.button_pressed(egui::PointerButton::Secondary),
                i.pointer.secondary_down(),
            )
        });
        if response.hovered() && pressed_secondary {
            self.flying = true;
        }
        if !secondary_down {
            self.flying = false;
        }

        let projection = ViewProjection::new(camera, view, rect);
        if let Some((checked, stale)) = overlays.play_check {
            play_check_overlay(&painter, checked, stale, &projection);
        }
        if self.exposure.on {
            match (self.exposure.heard, overlays.audibility, overlays.exposure) {
                (Some(_), Some(heard), _) => audibility_overlay(&painter, heard, &projection),
                (None, _, Some(exposure)) => self.exposure_overlay(&painter, exposure, &projection),
                _ => {}
            }
            self.exposure_controls(ui, rect);
        }
        self.overlays(&painter, frame, &projection);
        self.file_error(&painter, rect);
        let gizmo_busy = self.gizmo(ui, frame, camera, rect, out);
        let waypoint_busy = self.waypoints(ui, &response, frame, &projection, camera, view, out);
        if response.clicked()
            && !gizmo_busy
            && !waypoint_busy
            && let Some(at) = response.interact_pointer_pos()
        {
            let add = ui.input(|i| i.modifiers.shift);
            let fraction = Vec2::new(
                (at.x - rect.min.x) / rect.width(),
                (at.y - rect.min.y) / rect.height(),
            );
            let ray = view_ray(camera, view.width, view.height, fraction);
            if let Some(item) = self.armed.clone() {
                out.push(Command::Place { ray, item });
                if !add {
                    self.armed = None;
                }
            } else if let Some(place) = marker_at(frame, &projection, at) {
                out.push(Command::Select { place, add });
            } else {
                out.push(Command::Pick { ray, add });
            }
        }
    }

    /// The exposure map over the floor: each cell the player reaches in its colour (standing
    /// or crouching), the darkest route from the spawn through the shards to the exit, its
    /// lit chokepoints, and the wardens where the time slider has put them.
    fn exposure_overlay(
        &self,
        painter: &egui::Painter,
        exposure: &Exposure,
        projection: &ViewProjection,
    ) {
        let map = &exposure.map;
        let threshold = self.exposure.threshold;
        let mut mesh = egui::Mesh::default();
        for storey in &map.storeys {
            let values = if self.exposure.crouching {
                &storey.crouching
            } else {
                &storey.standing
            };
            for (column, (value, floor)) in values.iter().zip(&storey.floor).enumerate() {
                let (Some(value), Some(floor)) = (value, floor) else {
                    continue;
                };
                let x = map.origin.0 + (column % map.width) as f32 * map.cell_size;
                let z = map.origin.1 + (column / map.width) as f32 * map.cell_size;
                let [r, g, b] = crate::edit::exposure::colour(*value, threshold);
                floor_cell(
                    &mut mesh,
                    projection,
                    Vec3::new(x, *floor, z),
                    map.cell_size,
                    Color32::from_rgba_unmultiplied(r, g, b, 120),
                );
            }
        }
        painter.add(mesh);
        let route: Vec<Pos2> = map
            .route
            .path
            .iter()
            .filter_map(|&p| projection.point(p + Vec3::Y * 0.05))
            .collect();
        painter.add(egui::Shape::line(
            route,
            Stroke::new(2.0_f32, Color32::from_rgb(120, 255, 200)),
        ));
        for &choke in &map.route.chokepoints {
            ring(painter, projection, choke, "lit, no way round", LIT);
        }
        for &(feet, facing) in &exposure.wardens {
            if let (Some(at), Some(ahead)) = (
                projection.point(feet + Vec3::Y * 0.05),
                projection.point(feet + Vec3::Y * 0.05 + facing * 0.8),
            ) {
                painter.circle_filled(at, 6.0, Color32::from_rgb(230, 60, 60));
                painter.line_segment(
                    [at, ahead],
                    Stroke::new(2.0_f32, Color32::from_rgb(230, 60, 60)),
                );
            }
        }
    }

    /// The overlay's controls, in a corner of the view.
    fn exposure_controls(&mut self, ui: &mut egui::Ui, rect: Rect) {
        // In front of the view it lies over.
        egui::Area::new(egui::Id::new("exposure controls"))
            .order(egui::Order::Foreground)
            .fixed_pos(Pos2::new(rect.min.x + 8.0, rect.max.y - 116.0))
            .show(ui.ctx(), |ui| {
                egui::Frame::popup(ui.style()).show(ui, |ui| {
                    ui.horizontal(|ui| {
                        ui.radio_value(&mut self.exposure.heard, None, "seen");
                        for noise in NoiseKind::ALL {
                            ui.radio_value(
                                &mut self.exposure.heard,
                                Some(noise),
                                format!("heard: {}", noise.name()),
                            );
                        }
                    });
                    if self.exposure.heard.is_none() {
                        ui.horizontal(|ui| {
                            ui.radio_value(&mut self.exposure.crouching, false, "standing");
                            ui.radio_value(&mut self.exposure.crouching, true, "crouching");
                        });
                    }
                    ui.add(
                        egui::Slider::new(&mut self.exposure.time, 0.0..=EXPOSURE_TIME_MAX)
                            .step_by(0.25)
                            .text("s into the beats"),
                    );
                    ui.label(&self.exposure.status);
                });
            });
    }

    /// The selection's boxes, a marker for each entity that draws nothing, and each
    /// warden's beat.
    fn overlays(&self, painter: &egui::Painter, frame: &FrameInput, projection: &ViewProjection) {
        let highlight = Color32::from_rgb(255, 170, 40);
        for (min, max) in &frame.bounds {
            draw_box(
                painter,
                projection,
                *min,
                *max,
                Stroke::new(1.5_f32, highlight),
            );
        }
        for (place, def) in &frame.defs {
            let selected = frame.selection.contains(place);
            if let Some(warden) = &def.warden {
                let colour = if selected {
                    highlight
                } else {
                    Color32::from_rgba_unmultiplied(200, 60, 60, 160)
                };
                let beat = beat_points(def, warden);
                for pair in beat.windows(2) {
                    if let (Some(a), Some(b)) =
                        (projection.point(pair[0]), projection.point(pair[1]))
                    {
                        painter.line_segment([a, b], Stroke::new(1.5_f32, colour));
                    }
                }
                for point in &warden.route {
                    if let Some(at) = projection.point(*point) {
                        painter.rect_filled(
                            Rect::from_center_size(at, egui::vec2(7.0, 7.0)),
                            1.0,
                            colour,
                        );
                    }
                }
            }
            if def.instance.is_some() {
                continue;
            }
            let Some(at) = projection.point(def.transform.translation) else {
                continue;
            };
            let (colour, label) = marker_style(def);
            painter.circle_filled(at, 5.0, colour);
            if selected {
                painter.circle_stroke(at, 8.0, Stroke::new(2.0_f32, highlight));
            }
            if selected || projection.rect.contains(at) && label != "light" {
                painter.text(
                    at + egui::vec2(8.0, -8.0),
                    egui::Align2::LEFT_BOTTOM,
                    &def.name,
                    egui::FontId::proportional(12.0),
                    Color32::from_gray(220),
                );
            }
        }
    }

    /// The gizmo on the selection; true while it has the pointer (hovered or dragged).
    fn gizmo(
        &mut self,
        ui: &mut egui::Ui,
        frame: &FrameInput,
        camera: &FlyCamera,
        rect: Rect,
        out: &mut Vec<Command>,
    ) -> bool {
        let selected: Vec<&EntityDef> = frame
            .selection
            .iter()
            .filter_map(|&p| frame.def(p))
            .collect();
        if selected.is_empty() || self.flying {
            return false;
        }
        let view = camera.world_from_camera().inverse().as_dmat4();
        let projection = perspective(
            camera.yfov as f64,
            (rect.width() / rect.height()) as f64,
            camera.znear as f64,
        );
        let kind = match self.tool {
            Tool::Move => GizmoModeKind::Translate,
            Tool::Rotate => GizmoModeKind::Rotate,
            Tool::Scale => GizmoModeKind::Scale,
        };
        self.gizmo.update_config(GizmoConfig {
            view_matrix: row_matrix(view),
            projection_matrix: row_matrix(projection),
            viewport: rect,
            modes: GizmoMode::all_from_kind(kind),
            orientation: GizmoOrientation::Global,
            snapping: self.snapping,
            snap_angle: self.angle.to_radians(),
            snap_distance: self.grid,
            snap_scale: 0.1,
            ..GizmoConfig::default()
        });
        let targets: Vec<GizmoTransform> = selected
            .iter()
            .map(|def| {
                let t = &def.transform;
                let q = t.rotation_quat();
                GizmoTransform::from_scale_rotation_translation(
                    mint::Vector3::from(t.scale.as_dvec3().to_array()),
                    mint::Quaternion::from([q.x as f64, q.y as f64, q.z as f64, q.w as f64]),
                    mint::Vector3::from(t.translation.as_dvec3().to_array()),
                )
            })
            .collect();
        if let Some((_, moved)) = self.gizmo.interact(ui, &targets) {
            for (def, transform) in selected.iter().zip(moved) {
                let mut changed = (*def).clone();
                let v = |m: mint::Vector3<f64>| Vec3::new(m.x as f32, m.y as f32, m.z as f32);
                changed.transform.translation = v(transform.translation);
                changed.transform.scale = v(transform.scale);
                let r = transform.rotation;
                let rotation =
                    Quat::from_xyzw(r.v.x as f32, r.v.y as f32, r.v.z as f32, r.s as f32);
                changed.transform.rotation = euler_degrees(rotation);
                if changed != **def {
                    out.push(Command::Edit {
                        name: def.name.clone(),
                        def: Box::new(changed),
                    });
                }
            }
        }
        self.gizmo.is_focused()
    }

    /// A selected warden's waypoints, dragged over the horizontal plane they stand on;
    /// true while one is held or under the pointer.
    #[allow(clippy::too_many_arguments)]
    fn waypoints(
        &mut self,
        ui: &egui::Ui,
        response: &egui::Response,
        frame: &FrameInput,
        projection: &ViewProjection,
        camera: &FlyCamera,
        view: &ViewState,
        out: &mut Vec<Command>,
    ) -> bool {
        let pointer = ui.input(|i| i.pointer.hover_pos());
        let wardens = frame
            .selection
            .iter()
            .filter_map(|&p| frame.def(p))
            .filter(|d| d.warden.is_some());
        let mut under = None;
        for def in wardens {
            let Some(warden) = &def.warden else { continue };
            for (index, point) in warden.route.iter().enumerate() {
                if let (Some(at), Some(pointer)) = (projection.point(*point), pointer)
                    && at.distance(pointer) < HANDLE_RADIUS
                {
                    under = Some((def.name.clone(), index));
                }
            }
        }
        if response.drag_started() && self.waypoint.is_none() {
            self.waypoint = under.clone();
        }
        if let Some((name, index)) = self.waypoint.clone() {
            if !self.primary_down {
                self.waypoint = None;
            } else if let (Some(pointer), Some(def)) = (
                pointer,
                frame.defs.iter().map(|(_, d)| d).find(|d| d.name == name),
            ) && let Some(warden) = &def.warden
                && let Some(old) = warden.route.get(index)
            {
                let fraction = Vec2::new(
                    (pointer.x - projection.rect.min.x) / projection.rect.width(),
                    (pointer.y - projection.rect.min.y) / projection.rect.height(),
                );
                let ray = view_ray(camera, view.width, view.height, fraction);
                let origin = Vec3::from(ray.origin);
                let direction = Vec3::from(ray.direction);
                if direction.y.abs() > 1e-5 {
                    let t = (old.y - origin.y) / direction.y;
                    if t > 0.0 {
                        let mut at = origin + direction * t;
                        if self.snapping {
                            at.x = (at.x / self.grid).round() * self.grid;
                            at.z = (at.z / self.grid).round() * self.grid;
                        }
                        at.y = old.y;
                        let mut changed = def.clone();
                        if let Some(route) = changed.warden.as_mut().map(|w| &mut w.route) {
                            route[index] = at;
                        }
                        if changed != *def {
                            out.push(Command::Edit {
                                name,
                                def: Box::new(changed),
                            });
                        }
                    }
                }
            }
        }
        self.waypoint.is_some() || under.is_some()
    }
}

/// Red: lit places with no way round, and where the bot was caught.
const LIT: Color32 = Color32::from_rgb(255, 60, 40);

/// A ring on the floor at `at` with a label beside it.
fn ring(
    painter: &egui::Painter,
    projection: &ViewProjection,
    at: Vec3,
    label: &str,
    colour: Color32,
) {
    if let Some(at) = projection.point(at + Vec3::Y * 0.05) {
        painter.circle_stroke(at, 9.0, Stroke::new(2.5_f32, colour));
        painter.text(
            at + egui::vec2(10.0, -10.0),
            egui::Align2::LEFT_BOTTOM,
            label,
            egui::FontId::proportional(12.0),
            colour,
        );
    }
}

/// The last play-check over the floor: the route the bot walked (green when won unseen,
/// orange otherwise), where it was caught, and the lit chokepoints that left it no route;
/// grey, and said so, when the level has been edited since.
fn play_check_overlay(
    painter: &egui::Painter,
    checked: &Checked,
    stale: bool,
    projection: &ViewProjection,
) {
    let grey = Color32::from_gray(150);
    let route_colour = match (stale, checked.proven()) {
        (true, _) => grey,
        (false, true) => Color32::from_rgb(90, 230, 120),
        (false, false) => Color32::from_rgb(255, 170, 40),
    };
    // A point every tenth of a second: the line looks the same and projects a sixth of
    // the points.
    let route: Vec<Pos2> = checked
        .route
        .iter()
        .step_by(6)
        .chain(checked.route.last())
        .filter_map(|&p| projection.point(p + Vec3::Y * 0.05))
        .collect();
    painter.add(egui::Shape::line(route, Stroke::new(2.0_f32, route_colour)));
    let marked = if stale { grey } else { LIT };
    let edited = if stale { " (before the last edit)" } else { "" };
    if let Some(at) = checked.caught_at() {
        ring(
            painter,
            projection,
            at,
            &format!("caught here{edited}"),
            marked,
        );
    }
    for &choke in &checked.chokepoints {
        ring(
            painter,
            projection,
            choke,
            &format!("lit, no way round{edited}"),
            marked,
        );
    }
}

/// Projects world points onto the view's rectangle on screen.
struct ViewProjection {
    projection: crate::render::camera::Projection,
    film: Vec2,
    rect: Rect,
}

impl ViewProjection {
    fn new(camera: &FlyCamera, view: &ViewState, rect: Rect) -> ViewProjection {
        ViewProjection {
            projection: crate::render::Camera::new(&camera.placement(), view.width, view.height)
                .projection(),
            film: Vec2::new(view.width as f32, view.height as f32),
            rect,
        }
    }

    fn point(&self, world: Vec3) -> Option<Pos2> {
        let film = self.projection.project(world.into())?;
        let fraction = film / self.film;
        Some(Pos2::new(
            self.rect.min.x + fraction.x * self.rect.width(),
            self.rect.min.y + fraction.y * self.rect.height(),
        ))
    }
}

/// The twelve edges of the box [min, max], as far as they are in front of the camera.
fn draw_box(
    painter: &egui::Painter,
    projection: &ViewProjection,
    min: Vec3,
    max: Vec3,
    stroke: Stroke,
) {
    let corner = |i: usize| {
        Vec3::new(
            if i & 1 == 0 { min.x } else { max.x },
            if i & 2 == 0 { min.y } else { max.y },
            if i & 4 == 0 { min.z } else { max.z },
        )
    };
    for a in 0..8usize {
        for bit in [1, 2, 4] {
            if a & bit == 0
                && let (Some(p), Some(q)) = (
                    projection.point(corner(a)),
                    projection.point(corner(a | bit)),
                )
            {
                painter.line_segment([p, q], stroke);
            }
        }
    }
}

/// A warden's beat as it walks it: from where it stands through its route, and round.
fn beat_points(def: &EntityDef, warden: &WardenDef) -> Vec<Vec3> {
    let mut points = vec![def.transform.translation];
    points.extend(&warden.route);
    if let Some(first) = warden.route.first() {
        points.push(*first);
    }
    points
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

/// The colour and kind of the marker drawn for an entity that draws nothing.
fn marker_style(def: &EntityDef) -> (Color32, &'static str) {
    if let Some(light) = &def.light {
        let colour = match light {
            LightDef::Point { color, .. }
            | LightDef::Spot { color, .. }
            | LightDef::Directional { color, .. } => *color,
        };
        let c = (colour / colour.max_element().max(1e-6) * 255.0).to_array();
        return (
            Color32::from_rgb(c[0] as u8, c[1] as u8, c[2] as u8),
            "light",
        );
    }
    if def.player_spawn.is_some() {
        return (Color32::from_rgb(60, 220, 90), "player start");
    }
    if def.exit.is_some() {
        return (Color32::from_rgb(80, 160, 255), "exit");
    }
    if def.camera.is_some() {
        return (Color32::from_gray(170), "camera");
    }
    (Color32::from_gray(120), "entity")
}

/// The marker entity (one that draws nothing) under the screen point `at`.
fn marker_at(frame: &FrameInput, projection: &ViewProjection, at: Pos2) -> Option<LevelEntity> {
    frame
        .defs
        .iter()
        .filter(|(_, def)| def.instance.is_none())
        .filter_map(|(place, def)| {
            let seen = projection.point(def.transform.translation)?;
            let distance = seen.distance(at);
            (distance < HANDLE_RADIUS).then_some((distance, *place))
        })
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, place)| place)
}

/// A right-handed perspective projection onto depth 0..1 (wgpu's), looking down -Z: what
/// the gizmo projects its handles with, matching the renderer's pinhole camera.
fn perspective(yfov: f64, aspect: f64, near: f64) -> DMat4 {
    const FAR: f64 = 1000.0;
    let f = 1.0 / (0.5 * yfov).tan();
    let depth = FAR / (near - FAR);
    DMat4::from_cols_array(&[
        f / aspect,
        0.0,
        0.0,
        0.0,
        0.0,
        f,
        0.0,
        0.0,
        0.0,
        0.0,
        depth,
        -1.0,
        0.0,
        0.0,
        near * depth,
        0.0,
    ])
}

fn row_matrix(m: DMat4) -> mint::RowMatrix4<f64> {
    mint::RowMatrix4::from([
        m.row(0).to_array(),
        m.row(1).to_array(),
        m.row(2).to_array(),
        m.row(3).to_array(),
    ])
}

/// A rotation as the level writes it: degrees about X, Y and Z, applied Y, X, Z
/// (`TransformDef::rotation_quat`'s inverse), rounded to a thousandth of a degree so a
/// round trip through the quaternion does not leave 89.99999 in the file.
pub fn euler_degrees(rotation: Quat) -> Vec3 {
    let (y, x, z) = rotation.to_euler(EulerRot::YXZ);
    let round = |radians: f32| {
        let degrees = (radians.to_degrees() * 1000.0).round() / 1000.0;
        if degrees == 0.0 { 0.0 } else { degrees }
    };
    Vec3::new(round(x), round(y), round(z))
}

/// The inspector's fields for one entity: every component it has, and a box to add each
/// one it has not.
fn inspect(ui: &mut egui::Ui, def: &mut EntityDef, materials: &[Material]) {
    ui.horizontal(|ui| {
        ui.label("Name");
        ui.text_edit_singleline(&mut def.name);
    });
    egui::CollapsingHeader::new("Transform")
        .default_open(true)
        .show(ui, |ui| {
            vec3_row(ui, "Position", &mut def.transform.translation, 0.01, " m");
            vec3_row(ui, "Rotation", &mut def.transform.rotation, 0.5, "°");
            vec3_row(ui, "Scale", &mut def.transform.scale, 0.01, "");
            let scale = &mut def.transform.scale;
            *scale = scale.max(Vec3::splat(0.001));
        });
    if let Some(instance) = &mut def.instance {
        egui::CollapsingHeader::new("Asset")
            .default_open(true)
            .show(ui, |ui| {
                ui.label(&instance.asset);
                material_overrides(ui, &mut instance.material_overrides, materials);
            });
    }
    component(
        ui,
        "Light",
        &mut def.light,
        || LightDef::Point {
            color: Vec3::ONE,
            intensity: 10.0,
        },
        |ui, light| {
            let (color, intensity) = match light {
                LightDef::Point { color, intensity }
                | LightDef::Directional { color, intensity }
                | LightDef::Spot {
                    color, intensity, ..
                } => (color, intensity),
            };
            let mut rgb = color.to_array();
            ui.horizontal(|ui| {
                ui.label("colour");
                ui.color_edit_button_rgb(&mut rgb);
            });
            *color = Vec3::from_array(rgb);
            number(ui, "intensity", intensity, 0.1, 0.0..=10_000.0, "");
            if let LightDef::Spot {
                inner_cone_degrees,
                outer_cone_degrees,
                ..
            } = light
            {
                number(ui, "inner cone", inner_cone_degrees, 0.5, 0.0..=90.0, "°");
                number(ui, "outer cone", outer_cone_degrees, 0.5, 0.0..=90.0, "°");
                *inner_cone_degrees = inner_cone_degrees.min(*outer_cone_degrees);
            }
            let kind = match light {
                LightDef::Point { .. } => 0,
                LightDef::Spot { .. } => 1,
                LightDef::Directional { .. } => 2,
            };
            let mut chosen = kind;
            ui.horizontal(|ui| {
                ui.radio_value(&mut chosen, 0, "point");
                ui.radio_value(&mut chosen, 1, "spot");
                ui.radio_value(&mut chosen, 2, "directional");
            });
            if chosen != kind {
                let (color, intensity) = match *light {
                    LightDef::Point { color, intensity }
                    | LightDef::Directional { color, intensity }
                    | LightDef::Spot {
                        color, intensity, ..
                    } => (color, intensity),
                };
                *light = match chosen {
                    0 => LightDef::Point { color, intensity },
                    1 => LightDef::Spot {
                        color,
                        intensity,
                        inner_cone_degrees: 25.0,
                        outer_cone_degrees: 38.0,
                    },
                    _ => LightDef::Directional { color, intensity },
                };
            }
        },
    );
    component(
        ui,
        "Warden",
        &mut def.warden,
        || WardenDef::walking(Vec::new()),
        |ui, warden| {
            number(ui, "speed", &mut warden.speed, 0.05, 0.1..=10.0, " m/s");
            ui.label("route (drag the squares in the view)");
            let mut remove = None;
            for (index, point) in warden.route.iter_mut().enumerate() {
                ui.horizontal(|ui| {
                    ui.label(format!("{}", index + 1));
                    for value in [&mut point.x, &mut point.y, &mut point.z] {
                        ui.add(egui::DragValue::new(value).speed(0.05));
                    }
                    if ui.small_button("x").clicked() {
                        remove = Some(index);
                    }
                });
            }
            if let Some(index) = remove {
                warden.route.remove(index);
            }
            if ui.button("add a waypoint").clicked() {
                let last = warden.route.last().copied().unwrap_or_default();
                warden.route.push(last + Vec3::new(1.0, 0.0, 0.0));
            }
            ui.label("lamp");
            let lamp = &mut warden.lamp;
            let mut rgb = lamp.color.to_array();
            ui.horizontal(|ui| {
                ui.label("colour");
                ui.color_edit_button_rgb(&mut rgb);
            });
            lamp.color = Vec3::from_array(rgb);
            number(
                ui,
                "intensity",
                &mut lamp.intensity,
                0.1,
                0.0..=10_000.0,
                "",
            );
            number(
                ui,
                "inner cone",
                &mut lamp.inner_cone_degrees,
                0.5,
                0.0..=90.0,
                "°",
            );
            number(
                ui,
                "outer cone",
                &mut lamp.outer_cone_degrees,
                0.5,
                0.0..=90.0,
                "°",
            );
            number(ui, "tilt", &mut lamp.tilt_degrees, 0.5, -90.0..=90.0, "°");
            number(ui, "height", &mut lamp.height, 0.01, 0.0..=5.0, " m");
        },
    );
    component(
        ui,
        "Shard",
        &mut def.shard,
        ShardDef::default,
        |ui, shard| {
            number(
                ui,
                "pickup radius",
                &mut shard.radius,
                0.01,
                0.05..=5.0,
                " m",
            );
        },
    );
    component(ui, "Exit", &mut def.exit, ExitDef::default, |ui, exit| {
        number(ui, "radius", &mut exit.radius, 0.01, 0.1..=10.0, " m");
    });
    component(
        ui,
        "Player start",
        &mut def.player_spawn,
        PlayerSpawn::default,
        |ui, spawn| {
            number(
                ui,
                "eye height",
                &mut spawn.eye_height,
                0.01,
                0.5..=2.5,
                " m",
            );
        },
    );
    component(
        ui,
        "Camera",
        &mut def.camera,
        || CameraDef {
            yfov_degrees: 60.0,
            znear: 0.05,
        },
        |ui, camera| {
            number(
                ui,
                "field of view",
                &mut camera.yfov_degrees,
                0.5,
                10.0..=150.0,
                "°",
            );
        },
    );
    component(
        ui,
        "Knocks over",
        &mut def.knock,
        KnockDef::default,
        |ui, knock| {
            number(ui, "radius", &mut knock.radius, 0.01, 0.05..=3.0, " m");
            number(ui, "noise reach", &mut knock.noise, 0.1, 0.0..=50.0, " m");
        },
    );
    component(
        ui,
        "Mover",
        &mut def.mover,
        || MoverDef {
            offset: Vec3::new(1.0, 0.0, 0.0),
            period: 4.0,
        },
        |ui, mover| {
            vec3_row(ui, "offset", &mut mover.offset, 0.01, " m");
            number(ui, "period", &mut mover.period, 0.05, 0.1..=120.0, " s");
        },
    );
}

/// A component's section: a box that adds or removes it, and its fields while present.
/// Each of the asset's materials, with a box per value the level may replace for this
/// instance; ticking one starts from the asset's value, and an override with no value
/// left is dropped, so the level file names only what differs.
fn material_overrides(
    ui: &mut egui::Ui,
    overrides: &mut BTreeMap<String, MaterialOverride>,
    materials: &[Material],
) {
    let mut shown = Vec::new();
    for material in materials {
        // Overrides are keyed by name: an unnamed material cannot be named by one, and a
        // name the asset repeats names all its materials at once.
        if material.name.is_empty() || shown.contains(&&material.name) {
            continue;
        }
        shown.push(&material.name);
        let mut change = overrides.get(&material.name).cloned().unwrap_or_default();
        let changed = if change == MaterialOverride::default() {
            ""
        } else {
            " (changed)"
        };
        egui::CollapsingHeader::new(format!("material '{}'{changed}", material.name))
            .id_salt(&material.name)
            .show(ui, |ui| material_fields(ui, &mut change, material));
        if change == MaterialOverride::default() {
            overrides.remove(&material.name);
        } else {
            overrides.insert(material.name.clone(), change);
        }
    }
    if shown.len() < materials.len() {
        ui.weak("(unnamed materials cannot be overridden)");
    }
}

fn material_fields(ui: &mut egui::Ui, change: &mut MaterialOverride, asset: &Material) {
    overridable(
        ui,
        "base colour",
        &mut change.base_color,
        asset.base_color,
        |ui, colour| {
            let mut rgb = colour.truncate().to_array();
            ui.color_edit_button_rgb(&mut rgb);
            *colour = Vec3::from_array(rgb).extend(colour.w);
        },
    );
    let unit = |ui: &mut egui::Ui, value: &mut f32| {
        ui.add(egui::Slider::new(value, 0.0..=1.0));
    };
    overridable(ui, "metallic", &mut change.metallic, asset.metallic, unit);
    overridable(
        ui,
        "roughness",
        &mut change.roughness,
        asset.roughness,
        unit,
    );
    overridable(
        ui,
        "transmission",
        &mut change.transmission,
        asset.transmission,
        unit,
    );
    overridable(ui, "ior", &mut change.ior, asset.ior, |ui, ior| {
        ui.add(egui::DragValue::new(ior).speed(0.01).range(1.0..=3.0));
    });
    overridable(
        ui,
        "emissive",
        &mut change.emissive,
        asset.emissive,
        |ui, radiance| {
            for channel in [&mut radiance.x, &mut radiance.y, &mut radiance.z] {
                ui.add(
                    egui::DragValue::new(channel)
                        .speed(0.05)
                        .range(0.0..=10_000.0),
                );
            }
        },
    );
    overridable(
        ui,
        "double sided",
        &mut change.double_sided,
        asset.double_sided,
        |ui, on| {
            ui.checkbox(on, "");
        },
    );
}

/// One value of a material override: ticked, the level's value (starting from the
/// asset's); not ticked, the asset's.
fn overridable<T>(
    ui: &mut egui::Ui,
    label: &str,
    value: &mut Option<T>,
    asset: T,
    edit: impl FnOnce(&mut egui::Ui, &mut T),
) {
    ui.horizontal(|ui| {
        let mut on = value.is_some();
        ui.checkbox(&mut on, label);
        match (on, value.is_some()) {
            (true, false) => *value = Some(asset),
            (false, true) => *value = None,
            _ => {}
        }
        match value {
            Some(value) => edit(ui, value),
            None => {
                ui.weak("as the asset");
            }
        }
    });
}

fn component<T>(
    ui: &mut egui::Ui,
    label: &str,
    value: &mut Option<T>,
    make: impl FnOnce() -> T,
    fields: impl FnOnce(&mut egui::Ui, &mut T),
) {
    let mut present = value.is_some();
    ui.separator();
    ui.checkbox(&mut present, label);
    match (present, value.is_some()) {
        (true, false) => *value = Some(make()),
        (false, true) => *value = None,
        _ => {}
    }
    if let Some(inner) = value {
        ui.indent(label, |ui| fields(ui, inner));
    }
}

fn vec3_row(ui: &mut egui::Ui, label: &str, value: &mut Vec3, speed: f64, suffix: &str) {
    ui.horizontal(|ui| {
        ui.label(label);
        for axis in [&mut value.x, &mut value.y, &mut value.z] {
            ui.add(egui::DragValue::new(axis).speed(speed).suffix(suffix));
        }
    });
}

fn number(
    ui: &mut egui::Ui,
    label: &str,
    value: &mut f32,
    speed: f64,
    range: std::ops::RangeInclusive<f32>,
    suffix: &str,
) {
    ui.horizontal(|ui| {
        ui.label(label);
        ui.add(
            egui::DragValue::new(value)
                .speed(speed)
                .range(range)
                .suffix(suffix),
        );
    });
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

/// The audibility map over the floor: each place a warden would hear the noise made there
/// in orange, brighter the further over the threshold (20 dB and more at full); places
/// within its reach in the open that a wall keeps quiet in blue; each warden with its name
/// and the noise's reach in the open around it.
fn audibility_overlay(painter: &egui::Painter, map: &Audibility, projection: &ViewProjection) {
    let size = crate::edit::audibility::CELL;
    let mut mesh = egui::Mesh::default();
    let mut cell = |at: Vec3, colour: Color32| {
        let corner = at - Vec3::new(size * 0.5, 0.0, size * 0.5);
        floor_cell(&mut mesh, projection, corner, size, colour);
    };
    for &at in &map.muffled {
        cell(at, Color32::from_rgba_unmultiplied(40, 70, 160, 90));
    }
    for &(at, over_db, _) in &map.heard {
        let t = (over_db / 20.0).clamp(0.0, 1.0);
        let colour = Color32::from_rgba_unmultiplied(
            230,
            (170.0 - 120.0 * t) as u8,
            40,
            (90.0 + 80.0 * t) as u8,
        );
        cell(at, colour);
    }
    painter.add(mesh);
    for (name, feet) in &map.wardens {
        let reach: Vec<Pos2> = (0..=48)
            .filter_map(|i| {
                let angle = i as f32 / 48.0 * std::f32::consts::TAU;
                projection.point(
                    *feet
                        + Vec3::new(angle.cos(), 0.05, angle.sin())
                            * Vec3::new(map.radius, 1.0, map.radius),
                )
            })
            .collect();
        painter.add(egui::Shape::line(
            reach,
            Stroke::new(1.0_f32, Color32::from_rgba_unmultiplied(230, 120, 40, 160)),
        ));
        if let Some(at) = projection.point(*feet + Vec3::Y * 0.05) {
            painter.circle_filled(at, 6.0, Color32::from_rgb(230, 60, 60));
            painter.text(
                at + egui::vec2(8.0, -8.0),
                egui::Align2::LEFT_BOTTOM,
                name,
                egui::FontId::proportional(13.0),
                Color32::WHITE,
            );
        }
    }
}

/// A map's cell on the floor: the square from `corner` (its minimum x and z, on the
/// floor) `size` metres along +x and +z, just above the floor, in `colour` (nothing when
/// a corner is behind the camera).
fn floor_cell(
    mesh: &mut egui::Mesh,
    projection: &ViewProjection,
    corner: Vec3,
    size: f32,
    colour: Color32,
) {
    let at = corner + Vec3::Y * 0.02;
    let corners = [
        at,
        at + Vec3::X * size,
        at + Vec3::new(size, 0.0, size),
        at + Vec3::Z * size,
    ];
    let Some(points) = corners
        .iter()
        .map(|&c| projection.point(c))
        .collect::<Option<Vec<Pos2>>>()
    else {
        return;
    };
    let first = mesh.vertices.len() as u32;
    for point in points {
        mesh.colored_vertex(point, colour);
    }
    mesh.add_triangle(first, first + 1, first + 2);
    mesh.add_triangle(first, first + 2, first + 3);
}
