//! The editor's palette: what a designer can place by clicking in the view. Every glTF
//! asset under the project's `assets/` folder, and the prefabs the game's components make
//! (a lamp, a shard, a warden with its lamp, a door, the exit, the player spawn). Each is
//! an `EntityDef` placed at the point clicked; asset paths are written relative to the
//! level file, as the level format wants them.

use std::path::{Component, Path, PathBuf};

use glam::Vec3;

use crate::scene::files::absolute;
pub use crate::scene::files::assets_folder;

use crate::scene::level::{EntityDef, ExitDef, InstanceDef, PlayerSpawn, ShardDef, WardenDef};

/// The game's ready-made entities.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Prefab {
    Lamp,
    Shard,
    Warden,
    Door,
    Exit,
    PlayerSpawn,
}

/// Metres a warden prefab's first beat runs out (and back), where the level has room
/// (`edit::prefab_def` fits it to the room: `edit::first_beat`).
pub const FIRST_BEAT: f32 = 4.0;

/// Height above the floor a lamp prefab hangs at (the kit's lamp brackets' height).
const LAMP_HEIGHT: f32 = 2.5;

impl Prefab {
    pub const ALL: [Prefab; 6] = [
        Prefab::Lamp,
        Prefab::Shard,
        Prefab::Warden,
        Prefab::Door,
        Prefab::Exit,
        Prefab::PlayerSpawn,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Prefab::Lamp => "lamp",
            Prefab::Shard => "shard",
            Prefab::Warden => "warden",
            Prefab::Door => "door",
            Prefab::Exit => "exit",
            Prefab::PlayerSpawn => "player start",
        }
    }

    /// The kit asset the prefab instances (under the assets folder), if it has a mesh.
    pub fn kit_asset(self) -> Option<&'static str> {
        match self {
            Prefab::Shard => Some("kit/shard.glb"),
            Prefab::Warden => Some("kit/warden.glb"),
            Prefab::Door => Some("kit/door.glb"),
            Prefab::Lamp | Prefab::Exit | Prefab::PlayerSpawn => None,
        }
    }

    /// The prefab standing on the floor point `at`, its assets found in `assets` and named
    /// relative to the level file `level`.
    pub fn def(self, at: Vec3, level: &Path, assets: &Path) -> EntityDef {
        let mut def = EntityDef::named(self.name());
        def.transform.translation = at;
        def.instance = self.kit_asset().map(|file| InstanceDef {
            asset: asset_reference(level, &assets.join(file)),
            material_overrides: Default::default(),
        });
        match self {
            Prefab::Lamp => {
                // A spot light pointing straight down from ceiling height.
                def.transform.translation.y += LAMP_HEIGHT;
                def.transform.rotation = Vec3::new(-90.0, 0.0, 0.0);
                def.light = Some(crate::scene::kit::LANTERN_SPOT);
            }
            Prefab::Shard => def.shard = Some(ShardDef::default()),
            Prefab::Warden => {
                // A first beat ahead and back; the inspector edits the route.
                def.warden = Some(WardenDef::walking(vec![at + Vec3::NEG_Z * FIRST_BEAT, at]));
            }
            Prefab::Door => {}
            Prefab::Exit => def.exit = Some(ExitDef::default()),
            Prefab::PlayerSpawn => def.player_spawn = Some(PlayerSpawn::default()),
        }
        def
    }
}

/// Every glTF file under `folder` (.gltf and .glb, any depth), sorted by path.
pub fn asset_files(folder: &Path) -> Vec<PathBuf> {
    files_with(folder, &["gltf", "glb"])
}

/// Every file under `folder` (any depth) whose extension is one of `extensions` (in any
/// case), sorted by path.
fn files_with(folder: &Path, extensions: &[&str]) -> Vec<PathBuf> {
    let mut found = Vec::new();
    let mut pending = vec![folder.to_path_buf()];
    while let Some(dir) = pending.pop() {
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        for entry in entries.flatten() {
            let path = entry.path();
            if path.is_dir() {
                pending.push(path);
            } else if path
                .extension()
                .and_then(|e| e.to_str())
                .is_some_and(|extension| {
                    extensions.iter().any(|e| extension.eq_ignore_ascii_case(e))
                })
            {
                found.push(path);
            }
        }
    }
    found.sort();
    found
}

/// Every sound file under `folder` (the extensions a level's sounds may have, any depth),
/// sorted by path.
pub fn sound_files(folder: &Path) -> Vec<PathBuf> {
    files_with(folder, &crate::scene::level::SOUND_EXTENSIONS)
}

/// An entity instancing the glTF file `asset` at `at`, named after the file.
pub fn asset_def(asset: &Path, at: Vec3, level: &Path) -> EntityDef {
    let stem = asset
        .file_stem()
        .map_or_else(|| "asset".to_owned(), |s| s.to_string_lossy().into_owned());
    let mut def = EntityDef::named(stem);
    def.transform.translation = at;
    def.instance = Some(InstanceDef {
        asset: asset_reference(level, asset),
        material_overrides: Default::default(),
    });
    def
}

/// How the level file `level` names `asset`: relative to the level's folder with `/`
/// separators (`../assets/kit/crate.glb`), or absolute when no relative path exists (another
/// drive).
pub fn asset_reference(level: &Path, asset: &Path) -> String {
    let from = absolute(level.parent().unwrap_or(Path::new(".")));
    let to = absolute(asset);
    let from_parts: Vec<Component> = from.components().collect();
    let to_parts: Vec<Component> = to.components().collect();
    if from_parts.first() != to_parts.first() {
        return to.to_string_lossy().replace('\\', "/");
    }
    let common = from_parts
        .iter()
        .zip(&to_parts)
        .take_while(|(a, b)| a == b)
        .count();
    let mut parts: Vec<String> = vec!["..".to_owned(); from_parts.len() - common];
    parts.extend(
        to_parts[common..]
            .iter()
            .map(|part| part.as_os_str().to_string_lossy().into_owned()),
    );
    parts.join("/")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn assets_are_named_relative_to_the_level() {
        assert_eq!(
            asset_reference(
                Path::new("/game/levels/x.ron"),
                Path::new("/game/assets/kit/crate.glb")
            ),
            "../assets/kit/crate.glb"
        );
        assert_eq!(
            asset_reference(
                Path::new("/game/levels/./x.ron"),
                Path::new("/game/levels/../assets/a.glb")
            ),
            "../assets/a.glb"
        );
        assert_eq!(
            asset_reference(Path::new("/game/x.ron"), Path::new("/game/a.glb")),
            "a.glb"
        );
    }

    #[test]
    fn the_palette_lists_every_shipped_asset_and_each_prefab_is_valid() {
        let level = Path::new(env!("CARGO_MANIFEST_DIR")).join("levels/first-light.ron");
        let assets = assets_folder(&level);
        let files = asset_files(&assets);
        assert!(files.iter().any(|f| f.ends_with("kit/crate.glb")));
        assert!(
            files
                .iter()
                .any(|f| f.ends_with("cornell/cornell-box.gltf"))
        );
        assert!(files.iter().all(|f| !f.ends_with("wind.wav")));
        let sounds = sound_files(&assets);
        assert!(
            sounds.iter().any(|f| f.ends_with("sounds/wind.wav")),
            "{sounds:?}"
        );
        assert!(sounds.iter().all(|f| !f.ends_with(".glb")));
        for prefab in Prefab::ALL {
            let def = prefab.def(Vec3::new(1.0, 0.0, 2.0), &level, &assets);
            if let Some(instance) = &def.instance {
                assert!(
                    level.parent().unwrap().join(&instance.asset).is_file(),
                    "{}: {}",
                    prefab.name(),
                    instance.asset
                );
            }
        }
    }
}
