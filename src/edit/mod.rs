//! The level editor's commands: plain functions on an `Engine`'s world, between frames, so
//! the editor's window and the tests drive the same code.
//!
//! The editor edits the level as authored. Each level entity (a `LevelEntity` root) is read
//! and written as its `EntityDef` (`game::level_io::entity_defs`), so a command is recorded
//! as, for every entity it touched, its definition before and after (`None`: absent), and
//! undo puts the befores back: a deleted entity returns with all its components at its old
//! place in the level. Per command:
//!
//! 1. read the touched entities' definitions;
//! 2. change the world: a change of transform alone moves the root, anything else despawns
//!    it and spawns the new definition at the same place (`game::spawn_entity`);
//! 3. pose the world at the editor's time and extract it (`Engine::pose_at`), so the next
//!    frame and the next pick see the change;
//! 4. push one step on the undo stack and clear the redo stack.
//!
//! Reloading compares the file's level with the world's and replaces the world only when
//! they differ. Saving writes `level_from_world`: a level loaded and saved with no edit is the file it
//! came from, byte for byte. The previous file is kept as `<file>.bak` (a name no reader
//! of `levels/*.ron` picks up) and the new one is written atomically, so a failed save
//! leaves the old file and the edits where they were.

pub mod audibility;
pub mod camera;
pub mod palette;
pub mod play_check;
pub mod template;
pub mod thumbnails;

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use bevy_ecs::prelude::{ChildOf, Entity, World};
use glam::Vec3;

use crate::accel::{InstanceMask, Ray};
use crate::extract::instance_entity;
use crate::frame::Engine;
use crate::game::level_io::entity_defs;
use crate::game::spawn::{Assets, spawn_entity};
use crate::game::{LevelEntity, LevelInfo, Transform, level_from_world};
use crate::scene::Scene;
use crate::scene::files::{absolute, write_atomically};
use crate::scene::level::{EntityDef, Environment, LEVEL_VERSION, Level, level_to_string};

/// One entity's definition before and after a step (`None`: it did not exist).
#[derive(Clone, Debug, PartialEq)]
struct Change {
    place: LevelEntity,
    before: Option<EntityDef>,
    after: Option<EntityDef>,
}

/// One undoable step: everything one command changed.
#[derive(Clone, Debug)]
struct Step {
    /// Numbers steps so the dirty marker can tell the saved state from an edited one.
    id: u64,
    changes: Vec<Change>,
    /// The level's own properties before and after, when the step changed them.
    properties: Option<Box<(LevelProperties, LevelProperties)>>,
}

/// What a level file says of the level as a whole, as a designer edits it: its name, its
/// place in the campaign, its sky and its ambience (`scene::level::Level`'s fields beside
/// the entities; the format's version and `playable` are not the designer's to change).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LevelProperties {
    pub name: String,
    pub campaign: Option<u32>,
    pub environment: Environment,
}

impl LevelProperties {
    /// The world's level properties (a world with no level has none yet: the defaults).
    pub fn of(world: &World) -> LevelProperties {
        world
            .get_resource::<LevelInfo>()
            .map(|info| LevelProperties {
                name: info.name.clone(),
                campaign: info.campaign,
                environment: info.environment.clone(),
            })
            .unwrap_or_default()
    }

    /// Makes these the world's level properties; the next frame's extraction reads the sky
    /// from there.
    fn install(&self, world: &mut World) {
        match world.get_resource_mut::<LevelInfo>() {
            Some(mut info) => {
                info.name = self.name.clone();
                info.campaign = self.campaign;
                info.environment = self.environment.clone();
            }
            None => world.insert_resource(LevelInfo {
                source: PathBuf::new(),
                version: LEVEL_VERSION,
                name: self.name.clone(),
                playable: true,
                campaign: self.campaign,
                environment: self.environment.clone(),
            }),
        }
    }
}

/// `Editor::saved` for a level never written: no step has this id (they count up from 1).
const NEVER_SAVED: u64 = u64::MAX;

/// The editor's state beside the world: the selection and the history.
#[derive(Debug, Default)]
pub struct Editor {
    /// The selected level entities, in the order they were picked.
    pub selection: Vec<LevelEntity>,
    /// The clock the world is posed at (clips, deformers, patrols scrubbed to it).
    pub time: f64,
    undo: Vec<Step>,
    redo: Vec<Step>,
    /// A drag under way: what it has changed so far, each entity from its state before
    /// the drag (recorded as one step when it ends).
    dragging: Vec<Change>,
    /// The level's properties before and after a drag of them under way.
    properties_dragging: Option<(LevelProperties, LevelProperties)>,
    next_id: u64,
    /// The id of the step on top of the undo stack when the file was last saved or loaded
    /// (0: the loaded state).
    saved: u64,
}

impl Editor {
    pub fn new() -> Editor {
        Editor {
            next_id: 1,
            ..Editor::default()
        }
    }

    /// An editor for a level not yet on disk (`template::new_level`'s): dirty until saved,
    /// so the title marks it and leaving asks first.
    pub fn unsaved() -> Editor {
        Editor {
            saved: NEVER_SAVED,
            ..Editor::new()
        }
    }

    /// Whether the world differs from the file (the title's dirty marker).
    pub fn is_dirty(&self) -> bool {
        self.undo.last().map_or(0, |step| step.id) != self.saved
            || !self.dragging.is_empty()
            || self.properties_dragging.is_some()
    }

    /// Makes `place` the selection, or (with `add`) adds it or takes it out again: the
    /// outline list's click and Shift+click.
    pub fn select(&mut self, place: LevelEntity, add: bool) {
        if !add {
            self.selection = vec![place];
        } else if let Some(at) = self.selection.iter().position(|&p| p == place) {
            self.selection.remove(at);
        } else {
            self.selection.push(place);
        }
    }

    /// Makes `places` the selection, or (with `add`) adds those not in it: a box drawn in
    /// the view.
    pub fn select_many(&mut self, places: &[LevelEntity], add: bool) {
        if !add {
            self.selection.clear();
        }
        for place in places {
            if !self.selection.contains(place) {
                self.selection.push(*place);
            }
        }
    }

    pub fn can_undo(&self) -> bool {
        !self.undo.is_empty()
    }

    pub fn can_redo(&self) -> bool {
        !self.redo.is_empty()
    }

    /// Picks the level entity a ray hits first among pickable instances: it becomes the
    /// selection, or joins it (or leaves it, if already in) with `add` (Shift+click). A ray
    /// that hits nothing clears the selection unless `add`. Returns what was hit.
    pub fn select_by_ray(
        &mut self,
        engine: &mut Engine,
        ray: &Ray,
        add: bool,
    ) -> Option<LevelEntity> {
        let hit = {
            let scene = engine.render_scene();
            scene
                .accel
                .intersect(ray, InstanceMask::PICKABLE, &scene.alpha())
                .map(|hit| scene.accel.instances()[hit.instance as usize].user_id)
        };
        let picked = hit
            .and_then(instance_entity)
            .and_then(|entity| level_root(&engine.world, entity));
        match picked {
            Some(place) => self.select(place, add),
            None if !add => self.selection.clear(),
            None => {}
        }
        picked
    }

    /// Changes every selected entity's definition with `edit`, as one step (a whole drag of
    /// the gizmo, or one inspector field). Nothing is recorded when nothing changed.
    pub fn modify(
        &mut self,
        engine: &mut Engine,
        edit: impl FnMut(&mut EntityDef),
    ) -> anyhow::Result<()> {
        let changes = self.selection_changes(engine, edit);
        self.commit(engine, changes)
    }

    /// Changes the selection's definitions with `edit` as part of a drag: the world follows
    /// at once, and the whole drag becomes one step when `end_drag` is called (or any other
    /// command runs).
    pub fn drag(
        &mut self,
        engine: &mut Engine,
        edit: impl FnMut(&mut EntityDef),
    ) -> anyhow::Result<()> {
        let changes = self.selection_changes(engine, edit);
        if changes.is_empty() {
            return Ok(());
        }
        apply(engine, &changes, self.time)?;
        for change in changes {
            match self.dragging.iter_mut().find(|c| c.place == change.place) {
                Some(earlier) => earlier.after = change.after,
                None => self.dragging.push(change),
            }
        }
        Ok(())
    }

    /// Each selected entity's definition before and after `edit`, where it changed.
    fn selection_changes(
        &self,
        engine: &mut Engine,
        mut edit: impl FnMut(&mut EntityDef),
    ) -> Vec<Change> {
        let defs = entity_defs(&mut engine.world);
        self.selection
            .iter()
            .filter_map(|place| defs.iter().find(|(p, _)| p == place))
            .filter_map(|(place, before)| {
                let mut after = before.clone();
                edit(&mut after);
                (after != *before).then(|| Change {
                    place: *place,
                    before: Some(before.clone()),
                    after: Some(after),
                })
            })
            .collect()
    }

    /// Records the drag under way as one step (nothing when it ended where it began).
    pub fn end_drag(&mut self) {
        let changes: Vec<Change> = std::mem::take(&mut self.dragging)
            .into_iter()
            .filter(|change| change.before != change.after)
            .collect();
        let properties = self
            .properties_dragging
            .take()
            .filter(|(before, after)| before != after)
            .map(Box::new);
        if !changes.is_empty() || properties.is_some() {
            self.push_step(changes, properties);
        }
    }

    /// Adds `def` to the level as a new entity (renamed if its name is taken, as
    /// `duplicate` does) and selects it: the palette's placing.
    pub fn place(
        &mut self,
        engine: &mut Engine,
        mut def: EntityDef,
    ) -> anyhow::Result<LevelEntity> {
        let defs = entity_defs(&mut engine.world);
        let names: Vec<String> = defs.iter().map(|(_, def)| def.name.clone()).collect();
        if def.name.is_empty() || names.contains(&def.name) {
            def.name = unused_name(
                if def.name.is_empty() {
                    "entity"
                } else {
                    &def.name
                },
                &names,
            );
        }
        let place = LevelEntity(defs.iter().map(|(place, _)| place.0 + 1).max().unwrap_or(0));
        self.commit(
            engine,
            vec![Change {
                place,
                before: None,
                after: Some(def),
            }],
        )?;
        self.selection = vec![place];
        Ok(place)
    }

    /// Sets the level's own properties (name, campaign, sky, ambience) as part of a drag,
    /// as `drag` does for entities: the world follows at once, and the drag becomes one
    /// step when it ends (a name typed a letter at a time is one step). The ambience's file
    /// is the caller's to choose from the sounds that exist (the window offers only those).
    pub fn drag_properties(&mut self, engine: &mut Engine, properties: LevelProperties) {
        let before = match self.properties_dragging.take() {
            Some((before, _)) => before,
            None => LevelProperties::of(&engine.world),
        };
        properties.install(&mut engine.world);
        self.properties_dragging = Some((before, properties));
    }

    /// Moves the selection by `offset` metres (the gizmo's move handles, after snapping).
    pub fn translate(&mut self, engine: &mut Engine, offset: Vec3) -> anyhow::Result<()> {
        self.modify(engine, |def| def.transform.translation += offset)
    }

    /// Copies every selected entity with all its components, under a new unique name
    /// (`lamp` -> `lamp 2`), at the level's next places; the copies become the selection.
    pub fn duplicate(&mut self, engine: &mut Engine) -> anyhow::Result<()> {
        let defs = entity_defs(&mut engine.world);
        let mut names: Vec<String> = defs.iter().map(|(_, def)| def.name.clone()).collect();
        let mut next = defs.iter().map(|(place, _)| place.0 + 1).max().unwrap_or(0);
        let mut changes = Vec::new();
        for place in &self.selection {
            let Some((_, original)) = defs.iter().find(|(p, _)| p == place) else {
                continue;
            };
            let mut copy = original.clone();
            copy.name = unused_name(&original.name, &names);
            names.push(copy.name.clone());
            changes.push(Change {
                place: LevelEntity(next),
                before: None,
                after: Some(copy),
            });
            next += 1;
        }
        let copies = changes.iter().map(|change| change.place).collect();
        self.commit(engine, changes)?;
        self.selection = copies;
        Ok(())
    }

    /// The selected entities as level text, for the system clipboard: a level holding just
    /// them, every asset named by its absolute path, so the text pastes into a level in
    /// any folder (and loads as a level of its own). None when nothing is selected.
    pub fn copy(&self, engine: &mut Engine, level: &Path) -> Option<String> {
        let defs = entity_defs(&mut engine.world);
        let folder = level.parent().unwrap_or(Path::new("."));
        let entities: Vec<EntityDef> = self
            .selection
            .iter()
            .filter_map(|place| defs.iter().find(|(p, _)| p == place))
            .map(|(_, def)| {
                let mut def = def.clone();
                for asset in asset_paths(&mut def) {
                    *asset = absolute(&folder.join(&*asset))
                        .to_string_lossy()
                        .into_owned();
                }
                def
            })
            .collect();
        (!entities.is_empty()).then(|| {
            level_to_string(&Level {
                version: LEVEL_VERSION,
                name: "copied entities".to_owned(),
                playable: false,
                campaign: None,
                environment: Environment::default(),
                entities,
            })
        })
    }

    /// Adds the entities of `text` (level text, as `copy` makes it or any level file holds)
    /// to the level at `level` as one step, where they were, and selects them: assets are
    /// named relative to `level`, names taken already get a number, and a light's fixture
    /// follows its entity's new name (or is let go when it names nothing in this level).
    /// Text that is not a level changes nothing and says why. Returns how many.
    pub fn paste(
        &mut self,
        engine: &mut Engine,
        level: &Path,
        text: &str,
    ) -> anyhow::Result<usize> {
        let pasted = crate::scene::level::parse_level(Path::new("the clipboard"), text)
            .map_err(|error| anyhow::anyhow!("{error}"))?;
        let defs = entity_defs(&mut engine.world);
        let mut names: Vec<String> = defs.iter().map(|(_, def)| def.name.clone()).collect();
        let mut next = defs.iter().map(|(place, _)| place.0 + 1).max().unwrap_or(0);
        let folder = level.parent().unwrap_or(Path::new("."));
        let mut renamed = Vec::new();
        let mut entities = Vec::new();
        for mut def in pasted.entities {
            for asset in asset_paths(&mut def) {
                // Relative paths are taken as the level's own (text from a level file).
                *asset = palette::asset_reference(level, &folder.join(&*asset));
            }
            let name = if names.contains(&def.name) || def.name.is_empty() {
                unused_name(
                    if def.name.is_empty() {
                        "entity"
                    } else {
                        &def.name
                    },
                    &names,
                )
            } else {
                def.name.clone()
            };
            renamed.push((std::mem::replace(&mut def.name, name.clone()), name.clone()));
            names.push(name);
            entities.push(def);
        }
        for def in &mut entities {
            if let Some(fixture) = &def.fixture {
                def.fixture = match renamed.iter().find(|(old, _)| old == fixture) {
                    Some((_, new)) => Some(new.clone()),
                    None if defs.iter().any(|(_, other)| &other.name == fixture) => {
                        Some(fixture.clone())
                    }
                    None => None,
                };
            }
        }
        let changes: Vec<Change> = entities
            .into_iter()
            .map(|def| {
                let place = LevelEntity(next);
                next += 1;
                Change {
                    place,
                    before: None,
                    after: Some(def),
                }
            })
            .collect();
        let count = changes.len();
        let places = changes.iter().map(|change| change.place).collect();
        self.commit(engine, changes)?;
        self.selection = places;
        Ok(count)
    }

    /// Deletes the selected entities (their asset hierarchies with them).
    pub fn delete(&mut self, engine: &mut Engine) -> anyhow::Result<()> {
        let defs = entity_defs(&mut engine.world);
        let changes = self
            .selection
            .iter()
            .filter_map(|place| defs.iter().find(|(p, _)| p == place))
            .map(|(place, before)| Change {
                place: *place,
                before: Some(before.clone()),
                after: None,
            })
            .collect();
        self.commit(engine, changes)?;
        self.selection.clear();
        Ok(())
    }

    /// Undoes the last step; false when there is none.
    pub fn undo(&mut self, engine: &mut Engine) -> anyhow::Result<bool> {
        self.end_drag();
        let Some(step) = self.undo.pop() else {
            return Ok(false);
        };
        let reverse: Vec<Change> = step
            .changes
            .iter()
            .map(|change| Change {
                place: change.place,
                before: change.after.clone(),
                after: change.before.clone(),
            })
            .collect();
        if let Err(error) = apply(engine, &reverse, self.time) {
            self.undo.push(step);
            return Err(error);
        }
        if let Some(properties) = &step.properties {
            properties.0.install(&mut engine.world);
        }
        self.selection = present_after(&reverse);
        self.redo.push(step);
        Ok(true)
    }

    /// Redoes the last undone step; false when there is none.
    pub fn redo(&mut self, engine: &mut Engine) -> anyhow::Result<bool> {
        self.end_drag();
        let Some(step) = self.redo.pop() else {
            return Ok(false);
        };
        if let Err(error) = apply(engine, &step.changes, self.time) {
            self.redo.push(step);
            return Err(error);
        }
        if let Some(properties) = &step.properties {
            properties.1.install(&mut engine.world);
        }
        self.selection = present_after(&step.changes);
        self.undo.push(step);
        Ok(true)
    }

    /// Writes the world's level to `path`: the file there now is kept as `<path>.bak`, the
    /// new one written atomically. On failure the old file, the world and the history are
    /// as they were, and the error says why.
    pub fn save(&mut self, engine: &mut Engine, path: &Path) -> anyhow::Result<()> {
        self.end_drag();
        let text = level_to_string(&level_from_world(&mut engine.world));
        match std::fs::read(path) {
            Ok(previous) => write_atomically(&backup_path(path), &previous)
                .with_context(|| format!("keeping the previous {}", path.display()))?,
            Err(error) if error.kind() == std::io::ErrorKind::NotFound => {}
            Err(error) => {
                return Err(error).with_context(|| format!("reading {}", path.display()));
            }
        }
        write_atomically(path, text.as_bytes())?;
        self.saved = self.undo.last().map_or(0, |step| step.id);
        Ok(())
    }

    /// Reads `path` again (the file changed on disk, or the designer chose to revert): an
    /// unchanged level leaves everything as it is; a changed one replaces the world and
    /// starts a new history, clean. A file that does not load changes nothing and the error
    /// gives its `file:line:column: message` lines. Asking before dropping unsaved edits
    /// is the window's part.
    pub fn reload(&mut self, engine: &mut Engine, path: &Path) -> anyhow::Result<Reloaded> {
        let scene = Scene::load(path).map_err(|error| anyhow::anyhow!("{error}"))?;
        if scene.level == level_from_world(&mut engine.world) {
            return Ok(Reloaded::Unchanged);
        }
        let shown = engine.film.shown;
        *engine = Engine::new(&scene, engine.film.settings.clone());
        engine.film.shown = shown;
        engine.pose_at(self.time);
        let time = self.time;
        *self = Editor::new();
        self.time = time;
        Ok(Reloaded::Replaced)
    }

    /// Imports the asset `files` that changed on disk again and respawns, in place, every
    /// level entity that instances one (not an undo step: the asset changed, not the
    /// level). Every file is imported before anything changes, so one that no longer
    /// imports changes nothing and the error gives its problems. Returns how many
    /// entities were respawned.
    pub fn reload_assets(
        &mut self,
        engine: &mut Engine,
        files: &[PathBuf],
    ) -> anyhow::Result<usize> {
        self.end_drag();
        let changed: Vec<PathBuf> = files.iter().map(|file| absolute(file)).collect();
        let (cached, base) = {
            let cache = &engine.world.get_resource_or_init::<Assets>().0;
            let cached: Vec<PathBuf> = cache
                .files()
                .filter(|file| changed.contains(&absolute(file)))
                .map(Path::to_path_buf)
                .collect();
            (cached, cache.base.clone())
        };
        let fresh = cached
            .iter()
            .map(|file| crate::scene::gltf_import::import_gltf(file))
            .collect::<Result<Vec<_>, _>>()
            .map_err(|error| anyhow::anyhow!("{error}"))?;
        {
            let cache = &mut engine.world.resource_mut::<Assets>().0;
            for asset in fresh {
                cache.insert(std::sync::Arc::new(asset));
            }
        }
        let respawned: Vec<Change> = entity_defs(&mut engine.world)
            .into_iter()
            .filter(|(_, def)| {
                def.instance.as_ref().is_some_and(|instance| {
                    changed.contains(&absolute(&base.join(&instance.asset)))
                })
            })
            .map(|(place, def)| Change {
                place,
                // No `before`: the entity is spawned anew, not moved.
                before: None,
                after: Some(def),
            })
            .collect();
        apply(engine, &respawned, self.time)?;
        Ok(respawned.len())
    }

    /// Writes unsaved edits to `autosave_path(path)` (the window calls this every few
    /// minutes); the level file itself is not touched and the world stays dirty. Returns
    /// whether anything was written (nothing is when there are no unsaved edits).
    pub fn autosave(&self, engine: &mut Engine, path: &Path) -> anyhow::Result<bool> {
        if !self.is_dirty() {
            return Ok(false);
        }
        let text = level_to_string(&level_from_world(&mut engine.world));
        write_atomically(&autosave_path(path), text.as_bytes())?;
        Ok(true)
    }

    /// Applies `changes` to the world and records them as one step.
    fn commit(&mut self, engine: &mut Engine, changes: Vec<Change>) -> anyhow::Result<()> {
        self.end_drag();
        if changes.is_empty() {
            return Ok(());
        }
        apply(engine, &changes, self.time)?;
        self.push_step(changes, None);
        Ok(())
    }

    /// Records `changes` (and `properties`, before and after), already applied, as the
    /// newest step.
    fn push_step(
        &mut self,
        changes: Vec<Change>,
        properties: Option<Box<(LevelProperties, LevelProperties)>>,
    ) {
        self.undo.push(Step {
            id: self.next_id,
            changes,
            properties,
        });
        self.next_id += 1;
        self.redo.clear();
    }
}

/// What `Editor::reload` found on disk.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reloaded {
    /// The file holds the level the world holds: nothing changed.
    Unchanged,
    /// The file differed: the world is the file's level now.
    Replaced,
}

/// The entities `changes` leave in the world: what an undo or redo selects.
fn present_after(changes: &[Change]) -> Vec<LevelEntity> {
    changes
        .iter()
        .filter(|change| change.after.is_some())
        .map(|change| change.place)
        .collect()
}

/// Where unsaved edits to `path` are autosaved: `levels/x.ron` -> `levels/.x.ron.autosave`
/// (hidden, and not `*.ron`, so nothing reading `levels/*.ron` picks it up).
pub fn autosave_path(path: &Path) -> PathBuf {
    let mut name = std::ffi::OsString::from(".");
    name.push(path.file_name().unwrap_or_default());
    name.push(".autosave");
    path.with_file_name(name)
}

/// Fits `def` to the asset it instances after a swap: material overrides the asset has no
/// material for, and an animation whose clip it lacks, are dropped (the level could not
/// load with them). The asset is imported through the world's cache, as spawning does; an
/// asset that does not import is the error, and `def` is left as it was.
pub fn fit_to_asset(engine: &mut Engine, def: &mut EntityDef) -> anyhow::Result<()> {
    let Some(instance) = &mut def.instance else {
        return Ok(());
    };
    let asset = engine
        .world
        .get_resource_or_init::<Assets>()
        .0
        .load(&instance.asset)
        .map_err(|error| anyhow::anyhow!("{error}"))?;
    instance
        .material_overrides
        .retain(|name, _| asset.material_by_name(name).is_some());
    if def
        .animation
        .as_ref()
        .is_some_and(|animation| asset.animation_by_name(&animation.clip).is_none())
    {
        def.animation = None;
    }
    Ok(())
}

/// The autosave of `path` when it is newer than the file (unsaved edits that never reached
/// it: the editor closed or crashed before a save), to be offered back on opening.
pub fn newer_autosave(path: &Path) -> Option<PathBuf> {
    let autosave = autosave_path(path);
    let modified = |file: &Path| std::fs::metadata(file).and_then(|m| m.modified()).ok();
    match (modified(&autosave)?, modified(path)) {
        (autosaved, Some(saved)) if autosaved <= saved => None,
        _ => Some(autosave),
    }
}

/// The level `path`'s autosave holds, loaded as if it were `path` (its assets are named
/// relative to the same folder): the edits it kept, to go on with unsaved.
pub fn load_autosave(path: &Path) -> anyhow::Result<Scene> {
    let autosave = autosave_path(path);
    let text = std::fs::read_to_string(&autosave)
        .with_context(|| format!("reading {}", autosave.display()))?;
    let level = crate::scene::level::parse_level(&autosave, &text)
        .map_err(|error| anyhow::anyhow!("{error}"))?;
    Scene::from_level(level, path).map_err(|error| anyhow::anyhow!("{error}"))
}

/// Moves `path`'s autosave aside, to the first free `.x.ron.autosave-N`, so the next
/// autosave does not write over the edits it holds; returns where it went.
pub fn keep_autosave_aside(path: &Path) -> anyhow::Result<PathBuf> {
    let autosave = autosave_path(path);
    let kept = (1..)
        .map(|n| {
            let mut name = autosave.file_name().unwrap_or_default().to_owned();
            name.push(format!("-{n}"));
            autosave.with_file_name(name)
        })
        .find(|kept| !kept.exists())
        .expect("some number is free");
    std::fs::rename(&autosave, &kept)
        .with_context(|| format!("moving {} to {}", autosave.display(), kept.display()))?;
    Ok(kept)
}

/// Where `path`'s previous contents are kept on save: `x.ron` -> `x.ron.bak`.
pub fn backup_path(path: &Path) -> PathBuf {
    let mut name = path.file_name().unwrap_or_default().to_owned();
    name.push(".bak");
    path.with_file_name(name)
}

/// `base` with the first number from 2 up that no name in `taken` has.
fn unused_name(base: &str, taken: &[String]) -> String {
    (2..)
        .map(|n| format!("{base} {n}"))
        .find(|name| !taken.contains(name))
        .unwrap_or_else(|| base.to_owned())
}

/// The outline's groups: the level's entities by what they are (the player start, ways
/// out, wardens, shards, lights, cameras and sounds, then the rest by the asset file they
/// instance, `wall` or `floor`), in that order and level order within each, keeping only
/// those whose name holds `search` (in any case). A level of a hundred walls and floors
/// reads as a few lines.
pub fn outline_groups<'a>(
    defs: &'a [(LevelEntity, EntityDef)],
    search: &str,
) -> Vec<(String, Vec<&'a (LevelEntity, EntityDef)>)> {
    const KINDS: [&str; 7] = [
        "player start",
        "ways out",
        "wardens",
        "shards",
        "lights",
        "cameras",
        "sounds",
    ];
    let kind = |def: &EntityDef| -> Result<usize, String> {
        let flags = [
            def.player_spawn.is_some(),
            def.exit.is_some(),
            def.warden.is_some(),
            def.shard.is_some(),
            def.light.is_some(),
            def.camera.is_some(),
            def.sound.is_some() && def.instance.is_none(),
        ];
        match flags.iter().position(|&flag| flag) {
            Some(index) => Ok(index),
            None => Err(def.instance.as_ref().map_or_else(
                || "other".to_owned(),
                |instance| {
                    Path::new(&instance.asset).file_stem().map_or_else(
                        || instance.asset.clone(),
                        |s| s.to_string_lossy().into_owned(),
                    )
                },
            )),
        }
    };
    let needle = search.trim().to_lowercase();
    let mut kinds: Vec<Vec<&(LevelEntity, EntityDef)>> = vec![Vec::new(); KINDS.len()];
    let mut by_asset: std::collections::BTreeMap<String, Vec<&(LevelEntity, EntityDef)>> =
        Default::default();
    for entry in defs
        .iter()
        .filter(|(_, def)| needle.is_empty() || def.name.to_lowercase().contains(&needle))
    {
        match kind(&entry.1) {
            Ok(index) => kinds[index].push(entry),
            Err(asset) => by_asset.entry(asset).or_default().push(entry),
        }
    }
    KINDS
        .iter()
        .map(|name| name.to_string())
        .zip(kinds)
        .chain(by_asset)
        .filter(|(_, members)| !members.is_empty())
        .collect()
}

/// Puts the editor's marks on the level's roots: `hidden` ones draw nothing, `locked` ones
/// let picking rays through (`extract::EditorMark`). Edits respawn an entity without its
/// mark, so the window calls this every frame with the sets it keeps; returns whether any
/// mark changed (the converged view then starts again).
pub fn mark_entities(engine: &mut Engine, hidden: &[LevelEntity], locked: &[LevelEntity]) -> bool {
    let mut roots = engine
        .world
        .query::<(Entity, &LevelEntity, Option<&crate::extract::EditorMark>)>();
    let changes: Vec<(Entity, crate::extract::EditorMark)> = roots
        .iter(&engine.world)
        .filter_map(|(entity, place, mark)| {
            let wanted = crate::extract::EditorMark {
                hidden: hidden.contains(place),
                locked: locked.contains(place),
            };
            (mark.copied().unwrap_or_default() != wanted).then_some((entity, wanted))
        })
        .collect();
    for &(entity, wanted) in &changes {
        if wanted == crate::extract::EditorMark::default() {
            engine
                .world
                .entity_mut(entity)
                .remove::<crate::extract::EditorMark>();
        } else {
            engine.world.entity_mut(entity).insert(wanted);
        }
    }
    !changes.is_empty()
}

/// Every asset path an entity's definition holds (its instance, its player body, its
/// sound), to be renamed when it moves between folders.
fn asset_paths(def: &mut EntityDef) -> impl Iterator<Item = &mut String> {
    let instance = def.instance.as_mut().map(|instance| &mut instance.asset);
    let body = def
        .player_spawn
        .as_mut()
        .and_then(|spawn| spawn.body.as_mut())
        .map(|body| &mut body.asset);
    let sound = def.sound.as_mut().map(|sound| &mut sound.asset);
    instance.into_iter().chain(body).chain(sound)
}

/// The level entity whose hierarchy `entity` belongs to.
fn level_root(world: &World, mut entity: Entity) -> Option<LevelEntity> {
    loop {
        if let Some(place) = world.get::<LevelEntity>(entity) {
            return Some(*place);
        }
        entity = world.get::<ChildOf>(entity)?.parent();
    }
}

/// Puts each change's `after` into the world at its place, then poses the world at `time`.
/// Every asset is loaded before anything changes, so a missing asset changes nothing.
fn apply(engine: &mut Engine, changes: &[Change], time: f64) -> anyhow::Result<()> {
    let world = &mut engine.world;
    let mut assets = Vec::new();
    for change in changes {
        let asset = match change.after.as_ref().and_then(|def| def.instance.as_ref()) {
            Some(instance) => Some(
                world
                    .get_resource_or_init::<Assets>()
                    .0
                    .load(&instance.asset)
                    .map_err(|error| anyhow::anyhow!("{error}"))?,
            ),
            None => None,
        };
        assets.push(asset);
    }
    for (change, asset) in changes.iter().zip(assets) {
        let root = world
            .query::<(Entity, &LevelEntity)>()
            .iter(world)
            .find(|(_, place)| **place == change.place)
            .map(|(entity, _)| entity);
        // A mover's origin and a knockable's upright pose live in their own components:
        // those are respawned like any other change.
        let moved_only = match (&change.before, &change.after) {
            (Some(before), Some(after)) => {
                after.mover.is_none()
                    && after.knock.is_none()
                    && EntityDef {
                        transform: after.transform,
                        ..before.clone()
                    } == *after
            }
            _ => false,
        };
        match (root, &change.after) {
            (Some(root), Some(after)) if moved_only => {
                let transform = Transform {
                    translation: after.transform.translation,
                    rotation: after.transform.rotation_quat(),
                    scale: after.transform.scale,
                };
                world.entity_mut(root).insert((
                    transform,
                    crate::game::AuthoredRotation(after.transform.rotation),
                ));
            }
            (root, after) => {
                if let Some(root) = root {
                    world.despawn(root);
                }
                if let Some(after) = after {
                    spawn_entity(world, after, change.place, asset);
                }
            }
        }
    }
    engine.pose_at(time);
    Ok(())
}

/// The world box around everything level entity `place` draws (the selection's outline);
/// None when it draws nothing (a light, the player start).
pub fn entity_bounds(engine: &mut Engine, place: LevelEntity) -> Option<(Vec3, Vec3)> {
    let instances = engine.level_entity_instances(place.0);
    let accel = &engine.render_scene().accel;
    let mut bounds: Option<(Vec3, Vec3)> = None;
    for (_, index) in instances {
        let instance = &accel.instances()[index as usize];
        let local = accel.blases[instance.blas as usize].bounds();
        let transform = instance.world_from_object();
        for corner in 0..8 {
            let pick = |bit: usize, min: f32, max: f32| if corner & bit == 0 { min } else { max };
            let point = Vec3::new(
                pick(1, local.min.x, local.max.x),
                pick(2, local.min.y, local.max.y),
                pick(4, local.min.z, local.max.z),
            );
            let world = transform.transform_point3(point);
            bounds = Some(match bounds {
                Some((min, max)) => (min.min(world), max.max(world)),
                None => (world, world),
            });
        }
    }
    bounds
}

/// Where `ray` first meets the level's pickable geometry.
pub fn level_point(engine: &Engine, ray: &Ray) -> Option<Vec3> {
    let scene = engine.render_scene();
    let hit = scene
        .accel
        .intersect(ray, InstanceMask::PICKABLE, &scene.alpha())?;
    Some((ray.origin + ray.direction * hit.t).into())
}

/// Where the palette places what it holds for a click whose ray is `ray`: the point the ray
/// meets (`surface_point`), with x and z snapped to the grid of `step` metres when there is
/// one, standing on whatever is under the snapped point (found from half a metre above the
/// clicked one, so a snap across a table's edge lands on the floor beside it).
pub fn placing_point(engine: &Engine, ray: &Ray, step: Option<f32>) -> Option<Vec3> {
    let clicked = surface_point(engine, ray)?;
    let Some(step) = step.filter(|step| *step > 0.0) else {
        return Some(clicked);
    };
    let snapped = Vec3::new(
        (clicked.x / step).round() * step,
        clicked.y,
        (clicked.z / step).round() * step,
    );
    let down = Ray::new((snapped + Vec3::Y * 0.5).into(), glam::Vec3A::NEG_Y);
    Some(surface_point(engine, &down).unwrap_or(snapped))
}

/// How far short of what it would meet a first beat stops: a warden's half-width, and room
/// to turn.
const BEAT_CLEARANCE: f32 = 0.6;

/// `prefab` standing at `at` in `engine`'s level, its assets named relative to the level
/// file `level` (`palette::Prefab::def`), with a warden's first beat fitted to the room it
/// stands in (`first_beat`): what the palette places.
pub fn prefab_def(engine: &Engine, prefab: palette::Prefab, at: Vec3, level: &Path) -> EntityDef {
    let mut def = prefab.def(at, level, &palette::assets_folder(level));
    if let Some(warden) = &mut def.warden {
        warden.route = first_beat(engine, at);
    }
    def
}

/// The first beat of a warden placed at `at`: out and back along whichever of -Z, +Z, -X
/// and +X has the most room for a warden's body, at most `FIRST_BEAT` and stopping
/// `BEAT_CLEARANCE` short of anything in the way, so it never runs through a wall. The
/// inspector and the waypoints in the view edit it from there.
pub fn first_beat(engine: &Engine, at: Vec3) -> Vec<Vec3> {
    use palette::FIRST_BEAT;
    let room = |direction: Vec3| {
        // A body's width of rays at knee and chest height: one ray down the middle slips
        // through the seam between two wall pieces, or under a table.
        let across = Vec3::Y.cross(direction);
        let mut free = f32::INFINITY;
        for height in [0.4, 1.2] {
            for side in [-0.3, 0.0, 0.3] {
                let from = at + Vec3::Y * height + across * side;
                let ray = Ray::new(from.into(), direction.into());
                if let Some(hit) = level_point(engine, &ray) {
                    free = free.min(hit.distance(from));
                }
            }
        }
        (free - BEAT_CLEARANCE).min(FIRST_BEAT)
    };
    let (direction, length) = [Vec3::NEG_Z, Vec3::Z, Vec3::NEG_X, Vec3::X]
        .into_iter()
        .map(|direction| (direction, room(direction)))
        // The first direction with the full beat's room, else the roomiest.
        .fold((Vec3::NEG_Z, f32::NEG_INFINITY), |best, next| {
            if best.1 >= FIRST_BEAT || next.1 <= best.1 {
                best
            } else {
                next
            }
        });
    vec![at + direction * length.max(0.0), at]
}

/// Where `ray` first meets the level's pickable geometry, else the ground plane y = 0
/// (where the palette places what it holds).
pub fn surface_point(engine: &Engine, ray: &Ray) -> Option<Vec3> {
    level_point(engine, ray).or_else(|| {
        (ray.direction.y < -1e-6)
            .then(|| (ray.origin + ray.direction * (-ray.origin.y / ray.direction.y)).into())
    })
}
