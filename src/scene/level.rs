//! The level format, version 1: a [RON](https://github.com/ron-rs/ron) file in `levels/`
//! that places glTF assets, lights, cameras, the player spawn, and the game's things
//! (shards, the exit, wardens, knockable things, movers, sounds) in the world. Load time,
//! and the editor's save path.
//!
//! A level names its glTF assets by paths relative to itself and places entities: each has a
//! unique `name`, a `transform`, and optional components. `#![enable(implicit_some)]` lets
//! optional components be written without `Some(...)`. Unknown fields are errors, so a typo
//! never silently becomes a default. Units and conventions are the project's (the crate's
//! front page): glTF's space, metres, degrees in the file, linear colour, lights in the
//! units of `KHR_lights_punctual`.
//!
//! # Every field
//!
//! ```ron
//! #![enable(implicit_some)]
//! (
//!     version: 1,                       // required; this gloam reads version 1
//!     name: "First light",              // shown in menus and the editor
//!     playable: true,                   // default true: needs exactly one player_spawn;
//!                                       // false for showcase scenes such as the Cornell box
//!     campaign: 1,                      // optional: its place in the level select (levels
//!                                       // without one follow, by file name)
//!     environment: (
//!         sky: (0.02, 0.03, 0.05),      // radiance of the sky, linear RGB, W/(sr m^2)
//!         // A sound bed heard everywhere (optional; .wav, .flac, .ogg or .mp3, relative to
//!         // the level file; gain_db defaults to 0).
//!         ambience: (asset: "../assets/sounds/wind.wav", gain_db: -6.0),
//!     ),
//!     entities: [
//!         (
//!             name: "crate 3",
//!             transform: (
//!                 translation: (3.9, 1.0, -3.7),   // metres
//!                 rotation: (0.0, -12.0, 0.0),     // degrees: (pitch X, yaw Y, roll Z),
//!                                                  // applied yaw, then pitch, then roll
//!                 scale: (0.7, 0.7, 0.7),          // positive in every axis
//!             ),
//!             instance: (
//!                 asset: "../assets/kit/crate.glb",   // .gltf or .glb, relative to this file
//!                 material_overrides: {                // by material name; all optional
//!                     "wood": (
//!                         base_color: (0.35, 0.25, 0.15, 1.0),   // linear RGBA in [0, 1]
//!                         // metallic, roughness, transmission: [0, 1]
//!                         // emissive: (r, g, b) radiance; ior: >= 1; double_sided: bool
//!                     ),
//!                 },
//!             ),
//!         ),
//!         (
//!             name: "hanging lamp",
//!             transform: (translation: (0.0, 2.7, 0.0)),
//!             light: Point(color: (1.0, 0.85, 0.6), intensity: 30.0),      // W/sr
//!         ),
//!         (
//!             name: "warden lamp",
//!             transform: (translation: (4.0, 2.0, 4.0), rotation: (-20.0, 45.0, 0.0)),
//!             light: Spot(                   // shines down the entity's -Z
//!                 color: (0.8, 0.9, 1.0),
//!                 intensity: 120.0,          // W/sr
//!                 inner_cone_degrees: 15.0,
//!                 outer_cone_degrees: 25.0,  // 0 <= inner < outer <= 90
//!             ),
//!             // Directional(color: ..., intensity: ...) is irradiance in W/m^2.
//!         ),
//!         (
//!             name: "overview camera",       // the view `render` uses; looks down -Z
//!             transform: (translation: (0.0, 1.7, 5.5), rotation: (-10.0, 0.0, 0.0)),
//!             camera: (yfov_degrees: 70.0, znear: 0.05),   // znear defaults to 0.05
//!         ),
//!         (
//!             name: "player start",          // feet position; yaw gives the view direction
//!             transform: (translation: (0.0, 0.0, 5.0)),
//!             player_spawn: (
//!                 eye_height: 1.6,           // the default
//!                 // Optional: the player's own body (a model facing +Z with `walk` and
//!                 // `idle` clips, feet at its origin); their camera sees past it, it casts
//!                 // shadows and shows in reflections.
//!                 body: (asset: "../assets/kit/warden.glb", material_overrides: {}),
//!             ),
//!         ),
//!         (
//!             name: "shard 1",               // collected when the player's body comes within
//!             transform: (translation: (0.0, 0.0, -4.5)),   // `radius` (default 0.6 m)
//!             instance: (asset: "../assets/kit/shard.glb"),
//!             shard: (),                     // or shard: (radius: 0.8); taking it removes
//!         ),                                 // the entity, its glow with it
//!         (
//!             name: "way out",               // with every shard taken, reaching it wins;
//!             transform: (translation: (0.0, 0.0, 5.0)),    // a level with shards and no
//!             exit: (radius: 1.0),           // exit is won when the last shard is taken
//!         ),
//!         (
//!             name: "warden 1",
//!             transform: (translation: (2.0, 0.0, -3.0)),
//!             instance: (asset: "../assets/kit/warden.glb"),
//!             animation: (
//!                 clip: "walk",              // a glTF animation's name, or "#N" for the N-th
//!                 playback: Loop,            // default Loop; Once holds the last pose
//!                 speed: 1.0,                // default 1; 0 pauses, negative plays backwards
//!                 start: 0.25,               // seconds into the clip at level start (>= 0)
//!             ),
//!             warden: (                      // faces its model's +Z; plays its model's
//!                                            // walk, idle and alert clips by its state
//!                 route: [(-4.0, 0.0, -3.0), (2.0, 0.0, -3.0)],  // feet positions, walked in
//!                 speed: 1.2,                // order, round and round; m/s (default 1.2)
//!                 lamp: (                    // a spot light it carries; these are the
//!                     color: (1.0, 0.8, 0.55),   // defaults, and every field is optional
//!                     intensity: 40.0,       // W/sr
//!                     inner_cone_degrees: 20.0,
//!                     outer_cone_degrees: 32.0,
//!                     height: 1.3,           // above its feet
//!                     reach: 0.35,           // ahead of it
//!                     tilt_degrees: 40.0,    // below the horizon
//!                 ),
//!             ),
//!         ),
//!         (
//!             name: "flag",
//!             instance: (asset: "../assets/kit/banner.glb"),
//!             // Procedural deformation of every mesh of the instance, along rest normals,
//!             // in mesh space; shading normals are recomputed from the moved triangles.
//!             deformer: Wave(
//!                 amplitude: 0.05,           // metres
//!                 wavelength: 0.8,           // metres, > 0
//!                 period: 1.5,               // seconds, > 0
//!                 direction: (0.0, 1.0, 0.0),   // default (1, 0, 0)
//!             ),
//!             // or Wobble(amplitude: 0.02, period: 0.7): a breathing, rippling blob.
//!         ),
//!         (
//!             name: "bottle 1",
//!             transform: (translation: (-9.0, 0.0, 0.6)),
//!             instance: (asset: "../assets/kit/bottle.glb"),
//!             knock: (),                     // falls over with a crash when the player walks
//!                                            // into it standing: knock: (radius: 0.25,
//!                                            // noise: 10.0) are the defaults (metres)
//!         ),
//!         (
//!             name: "rail lantern light",
//!             transform: (translation: (-5.55, 2.33, 0.0), rotation: (-55.0, -90.0, 0.0)),
//!             light: Spot(color: (1.0, 0.75, 0.45), intensity: 22.0,
//!                         inner_cone_degrees: 30.0, outer_cone_degrees: 48.0),
//!             // Swings up to `offset` metres either side of its place, a sine over `period`
//!             // seconds by the simulation clock; entities with the same mover move as one.
//!             mover: (offset: (0.0, 0.0, 5.5), period: 16.0),
//!             // A sound it makes where it stands, moving with it; gain_db (default 0) at
//!             // 1 m; looping: true (the default) plays it round and round, false once as
//!             // the level starts.
//!             sound: (asset: "../assets/sounds/lamp-hum.wav", gain_db: -3.0),
//!             // The entity whose instance the light shines from (a lamp-bracket, a
//!             // hanging-lamp, a candle): its glow goes dark while the lamp is doused.
//!             fixture: "rail lantern",
//!         ),
//!     ],
//! )
//! ```
//!
//! A level without a camera entity renders from the first camera in its assets (the Cornell
//! box level does this), and without either from a view that frames the scene. A bare
//! `.gltf` or `.glb` given where a level is expected loads as a showcase level with one
//! entity at the origin. `levels/first-light.ron` is a complete level; the editor saves
//! levels in exactly the form the files in `levels/` are written in ([`level_to_string`]), so
//! an unchanged save changes nothing.
//!
//! # Validation
//!
//! Parsing gives typed data; [`validate_level`] then checks values and reports each problem
//! at its place in the text through [`crate::scene::source_map`], as `file:line:column: message (at
//! /json/pointer)`; `gloam check FILE` lists them all. Reported: RON syntax errors and
//! unknown fields, an unsupported `version`, non-finite numbers, non-positive scale, colours
//! out of range, ior below 1, bad spot cones or camera fields, empty or duplicate entity
//! names, missing or broken asset files (with the asset's own diagnostics), material
//! overrides naming a material the asset lacks, animation clips the asset lacks (listing
//! those it has), animations or deformers on an entity with no instance, non-positive
//! deformer wavelengths and periods, non-positive shard, exit and knock radii, a negative
//! knock noise, a mover with a non-positive period, a warden with no route, a non-positive
//! speed or a bad lamp, a fixture on an entity with no light, naming no entity or one that
//! draws nothing, and a playable level with no (or two) player spawns.

use std::collections::BTreeMap;
use std::path::Path;

use glam::{EulerRot, Mat4, Quat, Vec3, Vec4};
use ron::extensions::Extensions;
use serde::{Deserialize, Serialize};

use super::diagnostic::{Diagnostic, LoadError, Pointer};
use super::model::Material;

pub use super::animation::Playback;

/// The level format version this build reads and writes.
pub const LEVEL_VERSION: u32 = 1;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Level {
    /// Format version; must be 1.
    pub version: u32,
    /// Shown in menus and the editor.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub name: String,
    /// A playable level needs exactly one player spawn; a showcase scene (the Cornell box)
    /// sets this to false.
    #[serde(default = "default_true", skip_serializing_if = "is_true")]
    pub playable: bool,
    /// Its place in the campaign: the level select lists levels by this number, then those
    /// without one by file name.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub campaign: Option<u32>,
    #[serde(default, skip_serializing_if = "Environment::is_default")]
    pub environment: Environment,
    #[serde(default)]
    pub entities: Vec<EntityDef>,
}

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Environment {
    /// Radiance of the sky seen by rays that leave the level, linear RGB in W/(sr m^2).
    #[serde(default)]
    pub sky: Vec3,
    /// A bed of sound heard everywhere in the level, the same in both ears (wind, a
    /// distant sea); none by default.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ambience: Option<AmbienceDef>,
}

/// The level's ambience: a looping sound file and its gain.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AmbienceDef {
    /// Path to a sound file (WAV, FLAC, Ogg Vorbis or MP3), relative to the level file.
    pub asset: String,
    /// Gain in decibels (0: as the file is).
    #[serde(default, skip_serializing_if = "is_zero_db")]
    pub gain_db: f32,
}

/// A sound the entity makes where it stands, moving with it (a lamp's hum, a fountain).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SoundDef {
    /// Path to a sound file (WAV, FLAC, Ogg Vorbis or MP3), relative to the level file.
    pub asset: String,
    /// Gain in decibels at 1 m (0: as the file is).
    #[serde(default, skip_serializing_if = "is_zero_db")]
    pub gain_db: f32,
    /// Plays as a loop from the level's start (the default), or once as the level starts.
    #[serde(default = "default_true", skip_serializing_if = "is_true")]
    pub looping: bool,
}

/// The file extensions a sound asset may have.
pub const SOUND_EXTENSIONS: [&str; 4] = ["wav", "flac", "ogg", "mp3"];

fn is_zero_db(value: &f32) -> bool {
    *value == 0.0
}

impl Environment {
    fn is_default(&self) -> bool {
        *self == Environment::default()
    }
}

/// One thing in the level: a name, a transform, and optional components.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EntityDef {
    /// Unique within the level; gameplay and the editor refer to entities by name.
    pub name: String,
    #[serde(default, skip_serializing_if = "TransformDef::is_identity")]
    pub transform: TransformDef,
    /// Draw a glTF asset here.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub instance: Option<InstanceDef>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub light: Option<LightDef>,
    /// The level's view for `gloam render` and the editor's start view; looks down local -Z.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera: Option<CameraDef>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub player_spawn: Option<PlayerSpawn>,
    /// Play one of the instanced asset's glTF animation clips.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub animation: Option<AnimationDef>,
    /// Deform every mesh of the instance procedurally, every frame.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub deformer: Option<DeformerDef>,
    /// A shard the player collects (taking it removes the entity, its glow with it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shard: Option<ShardDef>,
    /// The way out: reached with every shard taken, the level is won.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub exit: Option<ExitDef>,
    /// A warden: walks its route, carrying a lamp.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub warden: Option<WardenDef>,
    /// Something that falls over, loudly, when the player walks into it standing.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub knock: Option<KnockDef>,
    /// Swing back and forth along a line through the entity's place (a lantern on a rail).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mover: Option<MoverDef>,
    /// A sound the entity makes where it stands.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sound: Option<SoundDef>,
    /// For a light: the entity (by name) whose instance is the lamp it shines from, a
    /// bracket or a hanging lamp. Its glow goes dark while the light is doused, so a lamp
    /// never looks lit when it is not.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fixture: Option<String>,
}

/// Moves the entity up to `offset` (world metres) either side of its place, a sine over
/// `period` seconds by the simulation clock: at the place at 0 s, at +offset a quarter
/// period in. Entities with the same mover move as one.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MoverDef {
    pub offset: Vec3,
    pub period: f32,
}

/// A thing that topples about its base, away from the player, and makes a noise when the
/// player's body comes within `radius` of its origin (horizontally) while standing;
/// crouched, the player steps round it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KnockDef {
    /// Metres from the entity's origin to the player's body surface.
    #[serde(
        default = "default_knock_radius",
        skip_serializing_if = "is_default_knock_radius"
    )]
    pub radius: f32,
    /// How far the crash carries in the open (metres).
    #[serde(
        default = "default_knock_noise",
        skip_serializing_if = "is_default_knock_noise"
    )]
    pub noise: f32,
}

impl Default for KnockDef {
    fn default() -> Self {
        KnockDef {
            radius: default_knock_radius(),
            noise: default_knock_noise(),
        }
    }
}

fn default_knock_radius() -> f32 {
    0.25
}
fn is_default_knock_radius(value: &f32) -> bool {
    *value == default_knock_radius()
}
fn default_knock_noise() -> f32 {
    10.0
}
fn is_default_knock_noise(value: &f32) -> bool {
    *value == default_knock_noise()
}

/// A warden's beat and the lamp it carries.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WardenDef {
    /// Where its feet go, in order, round and round (world positions; it starts at the
    /// entity's position and walks to the first).
    pub route: Vec<Vec3>,
    /// Walking speed in m/s.
    #[serde(
        default = "default_warden_speed",
        skip_serializing_if = "is_default_warden_speed"
    )]
    pub speed: f32,
    /// The lamp it carries: a spot light ahead of it, tilted down.
    #[serde(default, skip_serializing_if = "WardenLamp::is_default")]
    pub lamp: WardenLamp,
}

/// A warden's lamp, relative to the warden: `height` above its feet, `reach` ahead, tilted
/// `tilt_degrees` below the horizon.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct WardenLamp {
    pub color: Vec3,
    /// Radiant intensity in W/sr.
    pub intensity: f32,
    pub inner_cone_degrees: f32,
    pub outer_cone_degrees: f32,
    pub height: f32,
    pub reach: f32,
    pub tilt_degrees: f32,
}

impl Default for WardenLamp {
    fn default() -> Self {
        WardenLamp {
            color: Vec3::new(1.0, 0.8, 0.55),
            intensity: 40.0,
            inner_cone_degrees: 20.0,
            outer_cone_degrees: 32.0,
            height: 1.3,
            reach: 0.35,
            tilt_degrees: 40.0,
        }
    }
}

impl WardenLamp {
    fn is_default(&self) -> bool {
        *self == WardenLamp::default()
    }

    /// The lamp as a level light.
    pub fn light(&self) -> LightDef {
        LightDef::Spot {
            color: self.color,
            intensity: self.intensity,
            inner_cone_degrees: self.inner_cone_degrees,
            outer_cone_degrees: self.outer_cone_degrees,
        }
    }
}

/// A collectable shard at the entity's position.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShardDef {
    /// Taken when the player's body comes this close (metres, from the entity's origin to
    /// the body's axis, above the feet and below the head).
    #[serde(
        default = "default_pickup_radius",
        skip_serializing_if = "is_default_pickup_radius"
    )]
    pub radius: f32,
}

/// The level's exit at the entity's position.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExitDef {
    /// Reached when the player's feet come this close on the ground plane (metres).
    #[serde(
        default = "default_exit_radius",
        skip_serializing_if = "is_default_exit_radius"
    )]
    pub radius: f32,
}

impl Default for ShardDef {
    fn default() -> Self {
        ShardDef {
            radius: default_pickup_radius(),
        }
    }
}

impl Default for ExitDef {
    fn default() -> Self {
        ExitDef {
            radius: default_exit_radius(),
        }
    }
}

impl Default for PlayerSpawn {
    fn default() -> Self {
        PlayerSpawn {
            eye_height: default_eye_height(),
            body: None,
        }
    }
}

impl WardenDef {
    /// A warden walking `route` at the default speed, carrying the default lamp.
    pub fn walking(route: Vec<Vec3>) -> Self {
        WardenDef {
            route,
            speed: default_warden_speed(),
            lamp: WardenLamp::default(),
        }
    }
}

impl EntityDef {
    /// An entity with only a name and the identity transform.
    pub fn named(name: impl Into<String>) -> Self {
        EntityDef {
            name: name.into(),
            transform: TransformDef::default(),
            instance: None,
            light: None,
            camera: None,
            player_spawn: None,
            animation: None,
            deformer: None,
            shard: None,
            exit: None,
            warden: None,
            knock: None,
            mover: None,
            sound: None,
            fixture: None,
        }
    }
}

/// Placement relative to the world. Rotation is Euler angles in degrees, written
/// (pitch about X, yaw about Y, roll about Z) and applied yaw, then pitch, then roll
/// (`Quat::from_euler(YXZ, yaw, pitch, roll)`), the order a first-person view uses.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TransformDef {
    #[serde(default, skip_serializing_if = "is_zero")]
    pub translation: Vec3,
    #[serde(default, skip_serializing_if = "is_zero")]
    pub rotation: Vec3,
    #[serde(default = "one", skip_serializing_if = "is_one")]
    pub scale: Vec3,
}

impl Default for TransformDef {
    fn default() -> Self {
        TransformDef {
            translation: Vec3::ZERO,
            rotation: Vec3::ZERO,
            scale: Vec3::ONE,
        }
    }
}

impl TransformDef {
    pub fn is_identity(&self) -> bool {
        *self == TransformDef::default()
    }

    pub fn rotation_quat(&self) -> Quat {
        let radians = self.rotation * (std::f32::consts::PI / 180.0);
        Quat::from_euler(EulerRot::YXZ, radians.y, radians.x, radians.z)
    }

    /// World-from-entity matrix.
    pub fn matrix(&self) -> Mat4 {
        Mat4::from_scale_rotation_translation(self.scale, self.rotation_quat(), self.translation)
    }
}

/// An instance of a glTF asset (its default scene, under the entity's transform).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InstanceDef {
    /// Path to a .gltf or .glb file, relative to the level file.
    pub asset: String,
    /// Per-instance changes to the asset's materials, keyed by material name.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub material_overrides: BTreeMap<String, MaterialOverride>,
}

/// Replaces the named material's values for one instance; absent fields keep the asset's.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialOverride {
    /// Linear RGBA albedo and coverage, each in [0, 1].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base_color: Option<Vec4>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub metallic: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub roughness: Option<f32>,
    /// Emitted radiance in W/(sr m^2) (already multiplied by any strength).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub emissive: Option<Vec3>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub transmission: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ior: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub double_sided: Option<bool>,
}

impl MaterialOverride {
    /// `material` with this override's fields replaced.
    pub fn apply(&self, material: &Material) -> Material {
        let mut result = material.clone();
        if let Some(v) = self.base_color {
            result.base_color = v;
        }
        if let Some(v) = self.metallic {
            result.metallic = v;
        }
        if let Some(v) = self.roughness {
            result.roughness = v;
        }
        if let Some(v) = self.emissive {
            result.emissive = v;
        }
        if let Some(v) = self.transmission {
            result.transmission = v;
        }
        if let Some(v) = self.ior {
            result.ior = v;
        }
        if let Some(v) = self.double_sided {
            result.double_sided = v;
        }
        result
    }
}

/// Which clip of the instanced asset plays, and how.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AnimationDef {
    /// The glTF animation's name.
    pub clip: String,
    /// `Loop` (default) or `Once` (hold the last pose).
    #[serde(default, skip_serializing_if = "is_default_playback")]
    pub playback: Playback,
    /// Playback rate; 1 is the authored speed, negative plays backwards.
    #[serde(default = "default_speed", skip_serializing_if = "is_default_speed")]
    pub speed: f32,
    /// Seconds into the clip at level start (staggers a crowd of the same walk cycle).
    #[serde(default, skip_serializing_if = "is_zero_f32")]
    pub start: f32,
}

/// A procedural deformation of the entity's meshes, in each mesh's own space. Vertices move
/// along their rest normals; shading normals are recomputed from the moved triangles.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum DeformerDef {
    /// A travelling sine wave: offset = amplitude x sin(2 pi (d . p / wavelength - t / period)),
    /// with d the unit `direction` (mesh space).
    Wave {
        amplitude: f32,
        wavelength: f32,
        period: f32,
        #[serde(default = "default_wave_direction")]
        direction: Vec3,
    },
    /// A blob that breathes and ripples: offset = amplitude x sin(2 pi t / period + 3 (x + y + z)
    /// / size), where size is the mesh's bounding radius.
    Wobble { amplitude: f32, period: f32 },
}

/// A punctual light at the entity (same units as KHR_lights_punctual).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum LightDef {
    /// Radiant intensity `intensity` x `color` in W/sr, in every direction.
    Point { color: Vec3, intensity: f32 },
    /// As a point light, inside a cone down the entity's -Z; angles from the axis.
    Spot {
        color: Vec3,
        intensity: f32,
        inner_cone_degrees: f32,
        outer_cone_degrees: f32,
    },
    /// Irradiance `intensity` x `color` in W/m^2, travelling down the entity's -Z.
    Directional { color: Vec3, intensity: f32 },
}

impl LightDef {
    /// The light in the asset model's terms (radians, one kind enum), named `name`.
    pub fn to_light(&self, name: &str) -> super::model::Light {
        use super::model::LightKind;
        let (kind, color, intensity) = match *self {
            LightDef::Point { color, intensity } => (LightKind::Point, color, intensity),
            LightDef::Spot {
                color,
                intensity,
                inner_cone_degrees,
                outer_cone_degrees,
            } => (
                LightKind::Spot {
                    inner_cone_angle: inner_cone_degrees.to_radians(),
                    outer_cone_angle: outer_cone_degrees.to_radians(),
                },
                color,
                intensity,
            ),
            LightDef::Directional { color, intensity } => {
                (LightKind::Directional, color, intensity)
            }
        };
        super::model::Light {
            name: name.to_owned(),
            kind,
            color,
            intensity,
            range: None,
        }
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraDef {
    /// Vertical field of view in degrees.
    pub yfov_degrees: f32,
    #[serde(default = "default_znear")]
    pub znear: f32,
}

/// Where the player starts: the entity's position is the feet, its yaw the view direction.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlayerSpawn {
    /// Eye height above the spawn point in metres.
    #[serde(default = "default_eye_height")]
    pub eye_height: f32,
    /// The player's body (a glTF asset facing +Z with `walk` and `idle` clips, feet at its
    /// origin): hidden from the player's own camera rays, it casts shadows and shows in
    /// reflections. None: no body.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub body: Option<InstanceDef>,
}

fn default_speed() -> f32 {
    1.0
}
fn is_default_speed(value: &f32) -> bool {
    *value == 1.0
}
fn is_zero_f32(value: &f32) -> bool {
    *value == 0.0
}
fn is_default_playback(value: &Playback) -> bool {
    *value == Playback::Loop
}
fn default_wave_direction() -> Vec3 {
    Vec3::X
}
fn default_true() -> bool {
    true
}
fn is_true(value: &bool) -> bool {
    *value
}
fn one() -> Vec3 {
    Vec3::ONE
}
fn is_one(value: &Vec3) -> bool {
    *value == Vec3::ONE
}
fn is_zero(value: &Vec3) -> bool {
    *value == Vec3::ZERO
}
fn default_znear() -> f32 {
    0.05
}
fn default_eye_height() -> f32 {
    1.6
}
fn default_warden_speed() -> f32 {
    1.2
}
fn is_default_warden_speed(value: &f32) -> bool {
    *value == default_warden_speed()
}
fn default_pickup_radius() -> f32 {
    0.6
}
fn is_default_pickup_radius(value: &f32) -> bool {
    *value == default_pickup_radius()
}
fn default_exit_radius() -> f32 {
    1.0
}
fn is_default_exit_radius(value: &f32) -> bool {
    *value == default_exit_radius()
}

fn ron_options() -> ron::Options {
    // `implicit_some` lets a level write `light: Point(...)` instead of `Some(Point(...))`.
    ron::Options::default().with_default_extension(Extensions::IMPLICIT_SOME)
}

/// Parses and validates level text. `path` names the file in diagnostics.
pub fn parse_level(path: &Path, text: &str) -> Result<Level, LoadError> {
    // The version decides how to read the rest, so it is checked before the schema: a
    // version-2 file should say "version 2", not "unknown field".
    #[derive(Deserialize)]
    struct VersionProbe {
        version: u32,
    }
    if let Ok(probe) = ron_options().from_str::<VersionProbe>(text)
        && probe.version != LEVEL_VERSION
    {
        return Err(Diagnostic::at_pointer(
            path,
            text,
            &Pointer::root().key("version"),
            format!(
                "unsupported level version {} (this gloam reads version {LEVEL_VERSION})",
                probe.version
            ),
        )
        .into());
    }
    let level: Level = ron_options().from_str(text).map_err(|error| Diagnostic {
        file: path.to_owned(),
        line: error.span.start.line.max(1),
        column: error.span.start.col.max(1),
        message: error.code.to_string(),
    })?;
    let problems = validate_level(&level);
    if problems.is_empty() {
        Ok(level)
    } else {
        Err(LoadError {
            diagnostics: problems
                .into_iter()
                .map(|(pointer, message)| Diagnostic::at_pointer(path, text, &pointer, message))
                .collect(),
        })
    }
}

/// Reads and validates the level file at `path`.
pub fn load_level(path: &Path) -> Result<Level, LoadError> {
    let text = std::fs::read_to_string(path)
        .map_err(|error| Diagnostic::whole_file(path, format!("cannot read level: {error}")))?;
    parse_level(path, &text)
}

/// The level as RON text, stable: saving what was loaded from saved text gives the same text.
pub fn level_to_string(level: &Level) -> String {
    let config = ron::ser::PrettyConfig::new()
        .extensions(Extensions::IMPLICIT_SOME)
        .indentor("    ".to_owned())
        .new_line("\n".to_owned());
    // Serializing plain data with derived impls cannot fail.
    ron::ser::to_string_pretty(level, config).expect("level serializes") + "\n"
}

/// Writes the level to `path` atomically (a temporary file renamed over the target), so a
/// failed save never leaves a half-written level.
pub fn save_level(level: &Level, path: &Path) -> anyhow::Result<()> {
    super::files::write_atomically(path, level_to_string(level).as_bytes())
}

/// Checks every value a parse cannot: returns (place, problem) pairs, empty when valid.
pub fn validate_level(level: &Level) -> Vec<(Pointer, String)> {
    let mut problems = Vec::new();
    let mut report = |pointer: Pointer, message: String| problems.push((pointer, message));

    check_colour(
        &mut report,
        Pointer::root().key("environment").key("sky"),
        level.environment.sky,
        "sky radiance",
        None,
    );
    if let Some(ambience) = &level.environment.ambience {
        check_sound(
            &mut report,
            Pointer::root().key("environment").key("ambience"),
            &ambience.asset,
            ambience.gain_db,
        );
    }

    let mut first_use: BTreeMap<&str, usize> = BTreeMap::new();
    let mut spawns = Vec::new();
    for (index, entity) in level.entities.iter().enumerate() {
        let at = Pointer::root().key("entities").index(index);
        if entity.name.trim().is_empty() {
            report(at.key("name"), "entity name is empty".into());
        } else if let Some(first) = first_use.insert(&entity.name, index) {
            report(
                at.key("name"),
                format!(
                    "duplicate entity name '{}' (entity {first} has it too)",
                    entity.name
                ),
            );
            first_use.insert(&entity.name, first);
        }

        let transform = at.key("transform");
        check_finite3(
            &mut report,
            transform.key("translation"),
            entity.transform.translation,
            "translation",
        );
        check_finite3(
            &mut report,
            transform.key("rotation"),
            entity.transform.rotation,
            "rotation",
        );
        let scale = entity.transform.scale;
        if !(scale.is_finite() && scale.min_element() > 0.0) {
            report(
                transform.key("scale"),
                format!("scale must be positive and finite in every axis (found {scale})"),
            );
        }

        if let Some(instance) = &entity.instance {
            let asset = &instance.asset;
            if !(asset.ends_with(".gltf") || asset.ends_with(".glb")) {
                report(
                    at.key("instance").key("asset"),
                    format!("asset '{asset}' is not a .gltf or .glb file"),
                );
            }
            for (material, change) in &instance.material_overrides {
                check_override(
                    &mut report,
                    at.key("instance").key("material_overrides").key(material),
                    change,
                );
            }
        }

        if let Some(sound) = &entity.sound {
            check_sound(&mut report, at.key("sound"), &sound.asset, sound.gain_db);
        }

        if let Some(animation) = &entity.animation {
            let animation_at = at.key("animation");
            if entity.instance.is_none() {
                report(
                    animation_at.clone(),
                    "an animation needs an `instance` to animate".into(),
                );
            }
            if !animation.speed.is_finite() {
                report(
                    animation_at.key("speed"),
                    format!("speed must be finite (found {})", animation.speed),
                );
            }
            if !(animation.start.is_finite() && animation.start >= 0.0) {
                report(
                    animation_at.key("start"),
                    format!("start must be finite and >= 0 (found {})", animation.start),
                );
            }
        }

        if let Some(deformer) = &entity.deformer {
            let deformer_at = at.key("deformer");
            if entity.instance.is_none() {
                report(
                    deformer_at.clone(),
                    "a deformer needs an `instance` to deform".into(),
                );
            }
            let (amplitude, period) = match *deformer {
                DeformerDef::Wave {
                    amplitude,
                    wavelength,
                    period,
                    direction,
                } => {
                    if !(wavelength.is_finite() && wavelength > 0.0) {
                        report(
                            deformer_at.key("wavelength"),
                            format!("wavelength must be positive (found {wavelength})"),
                        );
                    }
                    if !(direction.is_finite() && direction.length() > 1e-6) {
                        report(
                            deformer_at.key("direction"),
                            format!("direction must be a non-zero vector (found {direction})"),
                        );
                    }
                    (amplitude, period)
                }
                DeformerDef::Wobble { amplitude, period } => (amplitude, period),
            };
            if !amplitude.is_finite() {
                report(
                    deformer_at.key("amplitude"),
                    format!("amplitude must be finite (found {amplitude})"),
                );
            }
            if !(period.is_finite() && period > 0.0) {
                report(
                    deformer_at.key("period"),
                    format!("period must be positive (found {period})"),
                );
            }
        }

        if let Some(light) = &entity.light {
            let light_at = at.key("light");
            let (LightDef::Point { color, intensity }
            | LightDef::Spot {
                color, intensity, ..
            }
            | LightDef::Directional { color, intensity }) = light;
            check_colour(
                &mut report,
                light_at.key("color"),
                *color,
                "light colour",
                None,
            );
            if !(intensity.is_finite() && *intensity >= 0.0) {
                report(
                    light_at.key("intensity"),
                    format!("light intensity must be finite and not negative (found {intensity})"),
                );
            }
            if let LightDef::Spot {
                inner_cone_degrees: inner,
                outer_cone_degrees: outer,
                ..
            } = light
                && !(0.0 <= *inner && inner < outer && *outer <= 90.0)
            {
                report(
                    light_at.key("outer_cone_degrees"),
                    format!(
                        "spot cone angles need 0 <= inner < outer <= 90 degrees (found {inner} and {outer})"
                    ),
                );
            }
        }

        if let Some(camera) = &entity.camera {
            if !(camera.yfov_degrees > 0.0 && camera.yfov_degrees < 180.0) {
                report(
                    at.key("camera").key("yfov_degrees"),
                    format!(
                        "yfov_degrees must lie in (0, 180) (found {})",
                        camera.yfov_degrees
                    ),
                );
            }
            if !(camera.znear > 0.0 && camera.znear.is_finite()) {
                report(
                    at.key("camera").key("znear"),
                    format!("znear must be positive (found {})", camera.znear),
                );
            }
        }

        for (field, radius) in [
            ("shard", entity.shard.as_ref().map(|s| s.radius)),
            ("exit", entity.exit.as_ref().map(|e| e.radius)),
            ("knock", entity.knock.as_ref().map(|k| k.radius)),
        ] {
            if let Some(radius) = radius
                && !(radius.is_finite() && radius > 0.0)
            {
                report(
                    at.key(field).key("radius"),
                    format!("{field} radius must be positive (found {radius})"),
                );
            }
        }

        if let Some(mover) = &entity.mover {
            if !(mover.period.is_finite() && mover.period > 0.0) {
                report(
                    at.key("mover").key("period"),
                    format!(
                        "a mover's period must be positive seconds (found {})",
                        mover.period
                    ),
                );
            }
            if !mover.offset.is_finite() {
                report(
                    at.key("mover").key("offset"),
                    "a mover's offset must be finite".into(),
                );
            }
        }

        if let Some(knock) = &entity.knock
            && !(knock.noise.is_finite() && knock.noise >= 0.0)
        {
            report(
                at.key("knock").key("noise"),
                format!(
                    "knock noise must be a distance of 0 or more (found {})",
                    knock.noise
                ),
            );
        }

        if let Some(warden) = &entity.warden {
            let warden_at = at.key("warden");
            if warden.route.is_empty() {
                report(
                    warden_at.key("route"),
                    "a warden's route needs at least one point".into(),
                );
            }
            for (point_index, point) in warden.route.iter().enumerate() {
                check_finite3(
                    &mut report,
                    warden_at.key("route").index(point_index),
                    *point,
                    "route point",
                );
            }
            if !(warden.speed.is_finite() && warden.speed > 0.0) {
                report(
                    warden_at.key("speed"),
                    format!("speed must be positive (found {})", warden.speed),
                );
            }
            let lamp = &warden.lamp;
            check_colour(
                &mut report,
                warden_at.key("lamp").key("color"),
                lamp.color,
                "lamp colour",
                None,
            );
            if !(lamp.intensity.is_finite() && lamp.intensity >= 0.0) {
                report(
                    warden_at.key("lamp").key("intensity"),
                    format!(
                        "lamp intensity must be finite and not negative (found {})",
                        lamp.intensity
                    ),
                );
            }
            let (inner, outer) = (lamp.inner_cone_degrees, lamp.outer_cone_degrees);
            if !(0.0 <= inner && inner < outer && outer <= 90.0) {
                report(
                    warden_at.key("lamp").key("outer_cone_degrees"),
                    format!(
                        "lamp cone angles need 0 <= inner < outer <= 90 degrees (found {inner} and {outer})"
                    ),
                );
            }
            for (name, value) in [
                ("height", lamp.height),
                ("reach", lamp.reach),
                ("tilt_degrees", lamp.tilt_degrees),
            ] {
                if !value.is_finite() {
                    report(
                        warden_at.key("lamp").key(name),
                        format!("lamp {name} must be finite (found {value})"),
                    );
                }
            }
        }

        if let Some(fixture) = &entity.fixture {
            let named = level.entities.iter().find(|other| &other.name == fixture);
            let problem = if entity.light.is_none() {
                Some("only a light has a fixture".to_string())
            } else if fixture == &entity.name {
                Some("a light cannot be its own fixture".to_string())
            } else {
                match named {
                    None => Some(format!("no entity is named '{fixture}'")),
                    Some(other) if other.instance.is_none() => {
                        Some(format!("the fixture '{fixture}' draws no instance"))
                    }
                    Some(_) => None,
                }
            };
            if let Some(problem) = problem {
                report(at.key("fixture"), problem);
            }
        }

        if let Some(spawn) = &entity.player_spawn {
            spawns.push(index);
            if !(spawn.eye_height > 0.0 && spawn.eye_height.is_finite()) {
                report(
                    at.key("player_spawn").key("eye_height"),
                    format!("eye_height must be positive (found {})", spawn.eye_height),
                );
            }
        }
    }

    if level.playable {
        match spawns.as_slice() {
            [] => report(
                Pointer::root().key("entities"),
                "playable level has no player spawn (add an entity with `player_spawn: (eye_height: 1.6)`, or set `playable: false`)".into(),
            ),
            [_] => {}
            [_, extra @ ..] => {
                for &index in extra {
                    report(
                        Pointer::root().key("entities").index(index).key("player_spawn"),
                        format!("a second player spawn (entity {} has the first)", spawns[0]),
                    );
                }
            }
        }
    }
    problems
}

fn check_finite3(report: &mut impl FnMut(Pointer, String), at: Pointer, value: Vec3, what: &str) {
    if !value.is_finite() {
        report(at, format!("{what} must be finite (found {value})"));
    }
}

/// Colours are finite and not negative; `max` bounds reflectances to 1.
fn check_colour(
    report: &mut impl FnMut(Pointer, String),
    at: Pointer,
    value: Vec3,
    what: &str,
    max: Option<f32>,
) {
    let in_range = value.is_finite()
        && value.min_element() >= 0.0
        && max.is_none_or(|max| value.max_element() <= max);
    if !in_range {
        let range = match max {
            Some(max) => format!("in [0, {max}]"),
            None => "finite and not negative".to_owned(),
        };
        report(at, format!("{what} must be {range} (found {value})"));
    }
}

/// A sound's file is one of `SOUND_EXTENSIONS` and its gain a finite number of decibels
/// within +-60.
fn check_sound(report: &mut impl FnMut(Pointer, String), at: Pointer, asset: &str, gain_db: f32) {
    let extension = Path::new(asset)
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    if !extension.is_some_and(|e| SOUND_EXTENSIONS.contains(&e.as_str())) {
        report(
            at.key("asset"),
            format!(
                "sound '{asset}' is not a {} file",
                SOUND_EXTENSIONS.map(|e| format!(".{e}")).join(", ")
            ),
        );
    }
    if !(gain_db.is_finite() && gain_db.abs() <= 60.0) {
        report(
            at.key("gain_db"),
            format!("gain must be between -60 and 60 dB (found {gain_db})"),
        );
    }
}

fn check_override(
    report: &mut impl FnMut(Pointer, String),
    at: Pointer,
    change: &MaterialOverride,
) {
    if let Some(base) = change.base_color {
        let in_range = base.is_finite() && base.min_element() >= 0.0 && base.max_element() <= 1.0;
        if !in_range {
            report(
                at.key("base_color"),
                format!("base_color must be in [0, 1] (found {base})"),
            );
        }
    }
    for (name, value) in [
        ("metallic", change.metallic),
        ("roughness", change.roughness),
        ("transmission", change.transmission),
    ] {
        if let Some(value) = value
            && !(0.0..=1.0).contains(&value)
        {
            report(
                at.key(name),
                format!("{name} must be in [0, 1] (found {value})"),
            );
        }
    }
    if let Some(emissive) = change.emissive {
        check_colour(
            report,
            at.key("emissive"),
            emissive,
            "emissive radiance",
            None,
        );
    }
    if let Some(ior) = change.ior
        && !(ior >= 1.0 && ior.is_finite())
    {
        report(
            at.key("ior"),
            format!("ior must be at least 1 (found {ior})"),
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn euler_order_is_yaw_then_pitch() {
        let transform = TransformDef {
            rotation: Vec3::new(0.0, 90.0, 0.0),
            ..Default::default()
        };
        // Yaw 90 degrees turns the forward view (-Z) to -X.
        let forward = transform.rotation_quat() * Vec3::NEG_Z;
        assert!((forward - Vec3::NEG_X).length() < 1e-6, "{forward}");
    }

    #[test]
    fn override_replaces_only_given_fields() {
        let base = Material {
            name: "m".into(),
            roughness: 0.3,
            ..Material::default()
        };
        let changed = MaterialOverride {
            ior: Some(1.33),
            ..Default::default()
        }
        .apply(&base);
        assert_eq!(changed.ior, 1.33);
        assert_eq!(changed.roughness, 0.3);
    }

    #[test]
    fn minimal_level_parses_with_defaults() {
        let text = "(version: 1, playable: false, entities: [(name: \"a\", light: Point(color: (1, 1, 1), intensity: 2))])";
        let level = parse_level(Path::new("x.ron"), text).unwrap();
        assert_eq!(level.entities[0].transform, TransformDef::default());
        assert_eq!(
            level.entities[0].light,
            Some(LightDef::Point {
                color: Vec3::ONE,
                intensity: 2.0
            })
        );
    }
}
