//! The level a designer starts from (`gloam edit --new LEVEL`, and File > New in the
//! editor): an 8 x 8 m room of the kit's floor tiles and walls under a night sky, a player
//! start in one corner, the way out in the other under a humming lamp on its bracket, wind
//! for the ambience, and a camera over it all.
//! The bot wins it as it stands, so a designer builds on a level that is already proven.
//!
//! Asset paths are written relative to the new file, as the level format wants them, so the
//! template is the same level wherever it is saved.

use std::path::Path;

use anyhow::anyhow;
use glam::Vec3;

use super::palette::{Prefab, asset_def, asset_reference, assets_folder};
use crate::scene::Scene;
use crate::scene::kit::{LAMP_BRACKET_LIGHT, LANTERN_SPOT};
use crate::scene::level::{
    AmbienceDef, CameraDef, EntityDef, Environment, LEVEL_VERSION, Level, SoundDef,
};

/// Half the room's inside, in metres: the kit's 4 m floor tiles, two by two.
const HALF_ROOM: f32 = 4.0;
/// The kit's wall is 0.2 m thick with its origin at its middle: a wall's centre line
/// stands this far out, so its inner face is on the room's edge.
const WALL_CENTRE: f32 = HALF_ROOM + 0.1;
/// The lamp bracket's mount point above the floor (the height first-light's hang at).
const BRACKET_HEIGHT: f32 = 2.85;

/// The template level for the file `level` (which need not exist yet), its assets found in
/// the project's `assets/` folder and named relative to `level`.
pub fn new_level(level: &Path) -> Level {
    let assets = assets_folder(level);
    let kit = |file: &str| assets.join("kit").join(file);
    let mut entities = Vec::new();

    for x in [-2.0, 2.0] {
        for z in [-2.0, 2.0] {
            let mut tile = asset_def(&kit("floor.glb"), Vec3::new(x, 0.0, z), level);
            tile.name = format!("floor {x:+} {z:+}");
            entities.push(tile);
        }
    }
    // Two 4 m wall pieces a side, north and south across x, west and east across z.
    for (side, across, turned) in [
        ("north", Vec3::new(0.0, 0.0, -WALL_CENTRE), false),
        ("south", Vec3::new(0.0, 0.0, WALL_CENTRE), false),
        ("west", Vec3::new(-WALL_CENTRE, 0.0, 0.0), true),
        ("east", Vec3::new(WALL_CENTRE, 0.0, 0.0), true),
    ] {
        for along in [-2.0, 2.0] {
            let at = across
                + if turned {
                    Vec3::Z * along
                } else {
                    Vec3::X * along
                };
            let mut wall = asset_def(&kit("wall.glb"), at, level);
            wall.name = format!("{side} wall {along:+}");
            if turned {
                wall.transform.rotation = Vec3::new(0.0, 90.0, 0.0);
            }
            entities.push(wall);
        }
    }

    // The way out in the north-east corner, lit by the lamp on the north wall above it;
    // the player starts in the dark south-west corner.
    let way_out = Vec3::new(2.5, 0.0, -3.0);
    let mut exit = Prefab::Exit.def(way_out, level, &assets);
    exit.name = "way out".to_owned();
    entities.push(exit);

    let mount = Vec3::new(way_out.x, BRACKET_HEIGHT, -HALF_ROOM + 0.02);
    let mut bracket = asset_def(&kit("lamp-bracket.glb"), mount, level);
    bracket.name = "lamp bracket".to_owned();
    let mut lamp = EntityDef::named("lamp");
    lamp.transform.translation = mount + LAMP_BRACKET_LIGHT;
    lamp.transform.rotation = Vec3::new(-90.0, 0.0, 0.0);
    lamp.light = Some(LANTERN_SPOT);
    lamp.sound = Some(SoundDef {
        asset: asset_reference(level, &assets.join("sounds").join("lamp-hum.wav")),
        gain_db: 0.0,
        looping: true,
    });
    lamp.fixture = Some(bracket.name.clone());
    entities.push(bracket);
    entities.push(lamp);

    let mut start = Prefab::PlayerSpawn.def(Vec3::new(-2.5, 0.0, 2.5), level, &assets);
    start.name = "player start".to_owned();
    entities.push(start);

    let mut camera = EntityDef::named("overview camera");
    camera.transform.translation = Vec3::new(0.0, 9.0, 7.5);
    camera.transform.rotation = Vec3::new(-50.0, 0.0, 0.0);
    camera.camera = Some(CameraDef {
        yfov_degrees: 65.0,
        znear: 0.05,
    });
    entities.push(camera);

    Level {
        version: LEVEL_VERSION,
        name: title(level),
        playable: true,
        campaign: None,
        // A faint night sky over the roofless room, so its walls read in the dark, and
        // wind under everything (first-light's).
        environment: Environment {
            sky: Vec3::new(0.02, 0.03, 0.05),
            ambience: Some(AmbienceDef {
                asset: asset_reference(level, &assets.join("sounds").join("wind.wav")),
                gain_db: -6.0,
            }),
        },
        entities,
    }
}

/// The template level (`edit::template::new_level`) for `path`, which must not exist yet
/// and whose folder must: a new level never writes over a file, and its first save has
/// somewhere to go.
pub fn new_scene(path: &Path) -> anyhow::Result<Scene> {
    if path.exists() {
        return Err(anyhow!(
            "{} already exists: a new level needs a file name not in use (`gloam edit {}` opens it)",
            path.display(),
            path.display()
        ));
    }
    let folder = path
        .parent()
        .filter(|folder| !folder.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    if !folder.is_dir() {
        return Err(anyhow!(
            "{}: the folder {} does not exist",
            path.display(),
            folder.display()
        ));
    }
    let level = crate::edit::template::new_level(path);
    Scene::from_level(level, path).map_err(|error| anyhow!("{error}"))
}

/// A level's name from its file's: `cellar-2.ron` -> "Cellar 2".
fn title(level: &Path) -> String {
    let stem = level
        .file_stem()
        .map_or_else(String::new, |stem| stem.to_string_lossy().into_owned());
    let words = stem.replace(['-', '_'], " ");
    let mut letters = words.trim().chars();
    match letters.next() {
        Some(first) => first.to_uppercase().chain(letters).collect(),
        None => "New level".to_owned(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_level_is_named_after_its_file() {
        assert_eq!(title(Path::new("levels/cellar-2.ron")), "Cellar 2");
        assert_eq!(title(Path::new("/x/the_crypt.ron")), "The crypt");
        assert_eq!(title(Path::new("")), "New level");
    }
}
