//! The game: the simulation, and nothing else. ECS components and resources, the systems
//! of one fixed 60 Hz step, and the functions that put a level into a world and write it
//! back out. This page also holds the game's rules as a player meets them, where their
//! numbers live, and the campaign's levels.
//!
//! # One fixed step
//!
//! `fixed_step_schedules`, in `Stage::FIXED_STEP` order:
//! 1. `Stage::Input`: `remember_transforms` (where things were, for interpolated
//!    rendering), then `fly_camera` (levels played without a player);
//! 2. `Stage::Gameplay`: lamps doused and relit (`douse_lamps`), the player's body
//!    (`move_player`: look, walk, jump, crouch, collide with the level through
//!    `WorldGeometry`), the noise it makes (`make_noise`, `knock_over`), its light gem
//!    (`measure_exposure`), the goal (`collect_shards`, `reach_exit`), the wardens
//!    (`watch_for_player`: sight, suspicion, state; `hear_noises`, through `acoustics`, the
//!    rays the player's own ears use; `relight_lamps`; `walk_wardens`: their feet, on the
//!    `nav::NavGrid` built at load), then `patrol` movers, and last what the step sounded
//!    like (`hear_the_step`: the sound kit's files, where and by whom, in `SoundEvents`),
//!    and the lamps' fixtures take their lamps' switch (`switch_fixtures`);
//! 3. `Stage::Animation`: `animate_wardens` (each warden's clip for its state) and
//!    `animate_player_body` (the player's own body walks or idles), then
//!    `advance_animations` and `apply_animations` (glTF clips into node transforms and
//!    morph weights; deformer clocks);
//! 4. `Stage::Transforms`: `propagate_transforms`.
//!
//! This module imports none of render, accel, the film, winit or pixels: it sees input as a
//! resource and leaves drawing to the frame driver (`crate::frame`).
//!
//! # The rules
//!
//! The player takes every shard of a level (a glowing pickup whose light goes with it) and
//! then reaches the exit ([`goal`]); wardens walk their beats carrying lamps and catch a
//! player they see, which starts the level again at once. In play:
//!
//! - **The body** ([`player`]): walking 1.4 m/s, sprinting 3.5, crouching 0.9 with the eye
//!   at 1.0 m (for the default 1.6 m eye height), jumps 0.5 m high; a capsule of radius
//!   0.3 m, 1.8 m tall and 1.1 m crouched, that slides along walls and steps up ledges of up
//!   to 0.3 m.
//! - **Light is what gives you away** ([`exposure`]). The light gem (five cells on the HUD)
//!   is the light arriving at eight body points from every lamp, glowing surface and the
//!   sky, found with shadow rays through the level as it stands, so a shadow the player can
//!   see is a shadow that hides them. Each point's light E becomes v = E / (E + 1); the gem
//!   is the mean of the brighter half, smoothed over 0.1 s. It is the only thing about the
//!   player a warden reads: with no cell lit (gem below 0.1) no warden sees the player,
//!   however close, and each lit cell makes them easier to see. A warden's own lamp lights
//!   the player too.
//! - **What a warden sees** ([`sight`]): a wide near cone (60 degrees either side, 5 m) and
//!   a narrow far one (30 degrees either side, 18 m) from its eyes, and nothing behind it
//!   except within 0.8 m. Inside a cone, rays from its eyes to the eight body points say how
//!   much of the player is in sight (walls, pillars and crates hide; crouching lowers the
//!   points): visibility = share of points in sight x the gem (its darkest step taken off)
//!   x distance (1 out to 6 m, falling to 0.2 at 18 m).
//! - **Suspicion** ([`warden`]) moves by 2 a second times the visibility, less 0.2 a second:
//!   full in about half a second close and lit, several seconds far and dim; seen too
//!   little to outweigh the 0.2, or not at all, it drains, and the warden counts as not
//!   seeing. The bar over a warden's head shows it. At 0.25 the warden stops and turns to
//!   look (`?`); after 2 s without seeing the player it walks to where it saw them and
//!   looks around for 12 s (`?`), then walks back to its route. Full suspicion makes it
//!   alert (`!`, red): it runs (3 m/s, slower than a sprint) to where it last saw the
//!   player; losing them drains it back to searching. An alert warden within 0.9 m
//!   catches the player.
//! - **Noise** ([`noise`]): walking and crouching are silent. Sprinting is heard 8 m away
//!   in the open (a footfall every 0.35 s), a hard landing (falling faster than 4 m/s)
//!   12 m away. The level carries it as it carries every sound, by rays ([`acoustics`]): a
//!   wall between stops it, but round a corner or through a doorway it is heard from the
//!   opening, a little quieter for the way round. Walking into a standing bottle (a
//!   level's `knock` thing) knocks it over with a crash heard 10 m away; crouched, the
//!   player steps round it. A warden that hears turns to the place (`?`) and goes to
//!   search it; an alert one that has lost sight of the player runs there. The HUD draws
//!   each noise's reach as a fading ring on the floor, so the player knows who could have
//!   heard it.
//! - **Lamps are the player's to put out** ([`lamps`]): the interact action douses the lamp
//!   looked at (within 2.5 m of the eye and 15 degrees of the aim, nothing between) or
//!   relights a doused one. Its pool is gone for the player and the wardens alike;
//!   reaching it means stepping into its light first. A patrolling warden that sees a dark
//!   lamp walks over and lights it again (within 1 m of it), then goes back to its beat.
//! - **Mirrors carry sight, not light, both ways** ([`sight`]): a surface the renderer
//!   reflects perfectly (metallic 1, roughness 0, like the kit's `mirror.glb`) shows the
//!   player a warden round a corner, and shows the player to it, at the length of the
//!   reflected path. The gem's shadow rays, like the renderer's light sampling, stop at the
//!   first surface, so a mirror shows a lamp's reflection but throws none of its light.
//!   Glass (transmission) stops a warden's sight and the gem's light, though the renderer
//!   shows what is behind it, so the shipped levels keep glass out of sightlines.
//! - **Times seen**, on the end page, counts every time a warden went from not seeing the
//!   player to noticing them. `gloam play --record FILE` keeps an attempt and
//!   `gloam play --headless --replay FILE --json OUT` lists every step's gem and every
//!   warden's state and suspicion ([`crate::headless::replay`]), so a catch can always be
//!   explained.
//!
//! # Tuning
//!
//! The numbers live in one place each, and the rules above are read from them:
//! [`player::tuning`] (movement), [`sight::tuning`] (eyes), [`warden::tuning`] (minds and
//! legs), [`noise::tuning`] (ears and noises), [`exposure::curve`] (the gem), the reaches
//! in [`lamps`], [`acoustics::tuning`] (how the level carries sound) and
//! [`sound_events::tuning`] (what each event sounds like).
//!
//! # The campaign
//!
//! Three levels in `levels/`, played in order (each file's `campaign`); every one is
//! finishable unseen, and proven so by play: the player bot ([`crate::headless::autoplay`])
//! wins each without a warden noticing it, and its runs are the shipped recordings
//! `tests/recordings/<level>-won.json`.
//!
//! 1. `first-light.ron`: the player starts in the dark south-west cellar. Three shards:
//!    the cellar's far corner, the north end of the hall where warden 1 turns, and the
//!    store's south-east corner behind the crates; the way out is green-lit in the store's
//!    north wall. Warden 1 walks the hall's length through its two lamp pools, warden 2
//!    crosses the store.
//! 2. `the-gallery.ron` (20 x 16 m): the player starts at the south end of a west corridor.
//!    Shards: the north-west corner where the corridor meets the north hall, the reading
//!    table in the library (east, lit by a candle), and the vault in the library's
//!    south-east corner behind a portcullis that rises and falls on an 11 s cycle (shut
//!    4 s, rising 1.5 s, open 4 s, falling 1.5 s: `scene::kit::GATE_CYCLE`). The way out
//!    is the north hall's green-lit north-east corner. Warden 1 walks the north hall;
//!    warden 2 circles the pillared gallery between bracket lamps. The corridor's lamp pool
//!    is seen from the north hall only in the mirror hung across the north-west corner:
//!    cross it while warden 1 walks away from the mirror, and watch him in the glass.
//! 3. `the-keep.ron` (24 x 16 m, two storeys): the player starts in the gatehouse
//!    (south-west). Shards: the far corner of the dark armoury north of the gatehouse
//!    (its floor strewn with bottles), the table on the balcony 3 m above the great hall
//!    (lit by a candle; stairs climb to it from beside the armoury's door), and the east
//!    wing's south-east corner. The way out is the east wing's green-lit north-east corner.
//!    A lantern runs on a rail along the great hall's west wall (5.5 m either way every
//!    16 s), its pool sweeping the floor and the stairs; warden 1 circles the hall's south
//!    half, warden 2 crosses the east wing, and warden 3 keeps the balcony, looking down
//!    into the hall with his lamp.
//!
//! `levels/cornell.ron` is a showcase (`playable: false`), flown through.
//!
//! # The world at run time
//!
//! The ECS world is the source of truth for a running level. [`spawn_level`] puts a loaded
//! `Scene` into a world: each level entity becomes a root entity (`LevelEntity` for its
//! place in the file, `Name`, `Transform`) with one component per field the level format
//! has, and its asset's glTF nodes as children ([`mod@spawn`] lists them). While the game runs,
//! anything may change, and the frame driver's extract step (`crate::extract`) shows it in
//! the next frame:
//!
//! - [`spawn()`] adds a level entity (its asset imported once through the world's asset
//!   cache; the entity checked as a level's would be, with a one-line error naming the
//!   field); `World::despawn` on its root removes it with its nodes;
//! - editing `Transform`, `AssetInstance::material_overrides` or `PunctualLight` moves,
//!   re-materials or relights; inserting `SwitchedOff` on a root darkens its punctual light
//!   and its asset's emitters, removing it lights them again;
//! - [`level_from_world`] gives the level back (rotations in the file's degrees), and
//!   [`crate::scene::level::save_level`] writes it atomically: loading a shipped level and
//!   saving it with no change gives the same bytes.
//!
//! Extract assembles the render's instances in an order that depends only on content, so the
//! same world renders the same image however it came to be: `tests/world.rs` edits
//! first-light into another level and renders it bit-identically to that level loaded from
//! disk. Moved things are updated in place; the light set is rebuilt only when a light or
//! emitter is added, removed, switched or changes power; static batches whose members are
//! untouched survive a spawn, and batches re-form once the static instances have kept still
//! for 30 frames.

pub mod acoustics;
pub mod animation;
pub mod exposure;
pub mod exposure_map;
pub mod goal;
pub mod input;
pub mod lamps;
pub mod level_io;
pub mod nav;
pub mod noise;
pub mod patrol;
pub mod player;
pub mod replay;
pub mod sight;
pub mod sound_events;
pub mod spawn;
pub mod state;
pub mod status;
pub mod transform;
pub mod warden;
pub mod world_query;

use std::collections::BTreeMap;
use std::sync::Arc;

use bevy_ecs::prelude::*;
use glam::{Mat4, Vec3};

pub use animation::{
    AnimationLibrary, Animator, BodyClips, Deformer, MorphWeights, advance_animations,
    apply_animations,
};
pub use exposure::{Exposure, measure_exposure};
pub use goal::{Exit, Outcome, Progress, Shard, collect_shards, play_time, reach_exit};
pub use input::{Action, Input, fly_camera};
pub use lamps::{LampFixture, douse_lamps, relight_lamps, switch_fixtures};
pub use level_io::level_from_world;
pub use nav::NavGrid;
pub use noise::{Footfalls, Knockable, Noises, hear_noises, knock_over, make_noise};
pub use patrol::{Patrol, patrol};
pub use player::{
    ActiveCamera, Player, PlayerBody, PlayerEye, animate_player_body, move_player, spawn_player,
};
pub use sound_events::{SoundEvent, SoundEvents, SoundMaker, hear_the_step};
pub use spawn::{Assets, LevelInfo, spawn, spawn_entity, spawn_level};
pub use transform::{
    GlobalTransform, PreviousGlobalTransform, Transform, interpolate, propagate_transforms,
    remember_transforms,
};
pub use warden::{
    Warden, WardenLampLight, WardenState, animate_wardens, walk_wardens, watch_for_player,
};
pub use world_query::{WorldGeometry, WorldQuery};

use crate::profile::Stage;
use crate::scene::level::{AnimationDef, DeformerDef, LightDef, MaterialOverride, PlayerSpawn};
use crate::scene::model::{Asset, Light};

/// Simulation steps per second (fixed timestep, 60 Hz).
pub const SIMULATION_HZ: f64 = 60.0;

/// A level entity: its place in the level file (saving writes entities in this order; an
/// entity spawned at run time takes the next place). Every level entity's root has one,
/// with a `Name` and a `Transform`.
#[derive(Component, Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct LevelEntity(pub usize);

/// The rotation as the level wrote it (degrees, `TransformDef::rotation`): saving writes
/// these numbers back while the `Transform`'s rotation is still the one they make, so a
/// load and save with no edit gives the file it read.
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub struct AuthoredRotation(pub Vec3);

/// Draws a glTF asset: the asset's node hierarchy is spawned under this entity.
#[derive(Component, Clone, Debug)]
pub struct AssetInstance {
    /// The asset's path as the level writes it (relative to the level file).
    pub path: String,
    pub asset: Arc<Asset>,
    /// Per-instance changes to the asset's materials, keyed by material name.
    pub material_overrides: BTreeMap<String, MaterialOverride>,
}

/// An asset node that carries a mesh: extract gives it an accel instance.
#[derive(Component, Clone, Debug)]
pub struct MeshNode {
    /// The level entity whose `AssetInstance` this node belongs to.
    pub root: Entity,
    pub asset: Arc<Asset>,
    /// The asset's glTF node and mesh.
    pub node: usize,
    pub mesh: usize,
    /// The mesh changes shape (skinned, morph targets, or a level deformer): it gets its
    /// own refittable BLAS.
    pub deforms: bool,
}

/// A punctual light at a level entity (the level's `light`).
#[derive(Component, Clone, Debug, PartialEq)]
pub struct PunctualLight(pub LightDef);

/// A glTF light (KHR_lights_punctual) on an asset node.
#[derive(Component, Clone, Debug, PartialEq)]
pub struct AssetLight {
    /// The level entity the asset is instanced by.
    pub root: Entity,
    pub node: usize,
    pub light: Light,
}

/// On a level entity: its punctual light and the emissive surfaces of its asset give no
/// light (a doused lamp, a taken shard's glow) until the marker is removed.
#[derive(Component, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SwitchedOff;

/// The entity whose `GlobalTransform` is the view (looks down its -Z).
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub struct ViewCamera {
    /// Vertical field of view in radians.
    pub yfov: f32,
    /// Near clipping distance in metres.
    pub znear: f32,
}

/// A level entity's `camera`: this view is the level's own (saved with it).
#[derive(Component, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LevelCamera;

/// Where the player starts (the level's `player_spawn`).
#[derive(Component, Clone, Debug, PartialEq)]
pub struct PlayerStart(pub PlayerSpawn);

/// The clip a level entity plays, as the level writes it (`Animator` plays it).
#[derive(Component, Clone, Debug, PartialEq)]
pub struct AnimationSource(pub AnimationDef);

/// A level entity's procedural deformer, as the level writes it (each deforming mesh
/// node gets a `Deformer` with its own clock).
#[derive(Component, Clone, Debug, PartialEq)]
pub struct DeformerSource(pub DeformerDef);

/// A sound a level entity makes where it stands, as the level writes it (its path is
/// relative to the level file, `LevelInfo::source`).
#[derive(Component, Clone, Debug, PartialEq)]
pub struct SoundSource(pub crate::scene::level::SoundDef);

/// A skinned mesh node's joints as entities (glTF skin).
#[derive(Component, Clone, Debug)]
pub struct Skin {
    /// The level entity whose space the skinned vertices are computed in.
    pub root: Entity,
    /// The entity of each joint, in skin order.
    pub joints: Vec<Entity>,
    pub inverse_bind_matrices: Vec<Mat4>,
    /// Joints and every node between them and `root`: a change to any of their
    /// `Transform`s changes the pose.
    pub watched: Vec<Entity>,
}

/// How far real time has run past the last simulation step, in steps (0..1): rendering
/// interpolates between the previous and the current step by this much.
#[derive(Resource, Default, Clone, Copy, Debug)]
pub struct SimulationClock {
    pub alpha: f32,
}

/// The schedules of one fixed step, one per stage of `Stage::FIXED_STEP`, in order.
pub fn fixed_step_schedules() -> Vec<(Stage, Schedule)> {
    Stage::FIXED_STEP
        .into_iter()
        .map(|stage| {
            let mut schedule = Schedule::default();
            match stage {
                Stage::Input => {
                    schedule.add_systems((remember_transforms, fly_camera).chain());
                }
                Stage::Gameplay => {
                    schedule.add_systems(
                        (
                            douse_lamps,
                            move_player,
                            make_noise,
                            knock_over,
                            measure_exposure,
                            collect_shards,
                            reach_exit,
                            watch_for_player,
                            hear_noises,
                            relight_lamps,
                            walk_wardens,
                            patrol,
                            hear_the_step,
                            switch_fixtures,
                        )
                            .chain(),
                    );
                }
                Stage::Animation => {
                    schedule.add_systems(
                        (
                            animate_wardens,
                            animate_player_body,
                            advance_animations,
                            apply_animations,
                        )
                            .chain(),
                    );
                }
                Stage::Transforms => {
                    schedule.add_systems(propagate_transforms);
                }
                _ => unreachable!("Stage::FIXED_STEP holds the simulation's stages only"),
            }
            (stage, schedule)
        })
        .collect()
}

/// Poses the world as it stands, moving no clock: clips applied, transforms propagated.
pub fn pose_schedule() -> Schedule {
    let mut pose = Schedule::default();
    pose.add_systems((apply_animations, propagate_transforms).chain());
    pose
}
