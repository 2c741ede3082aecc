//! The game: the simulation, and nothing else. ECS components and resources, the systems
//! of one fixed 60 Hz step, and the functions that put a level into a world and write it
//! back out.
//!
//! The world is the source of truth for everything in a level: `spawn::spawn_level` turns
//! a loaded `Scene` into entities (a root per level entity, its asset's node hierarchy
//! under it), and anything may be spawned, despawned or changed while the game runs
//! (`spawn::spawn`, `World::despawn`, editing a component); the frame driver's extract step
//! (`crate::extract`) sees the change in the next frame. `level_io::level_from_world`
//! writes the world back as a level.
//!
//! One fixed step (`fixed_step_schedules`, in `Stage::FIXED_STEP` order):
//! 1. `Stage::Input`: `remember_transforms` (where things were, for interpolated
//!    rendering), then `fly_camera` (levels played without a player);
//! 2. `Stage::Gameplay`: lamps doused and relit (`douse_lamps`), the player's body
//!    (`move_player`: look, walk, jump, crouch,
//!    collide with the level through `WorldGeometry`), the noise it makes (`make_noise`, `knock_over`),
//!    its light gem (`measure_exposure`), the goal (`collect_shards`, `reach_exit`), the
//!    wardens (`watch_for_player`: sight, suspicion, state; `hear_noises`, through
//!    `acoustics`, the rays the player's own ears use;
//!    `relight_lamps`; `walk_wardens`: their feet, on the `nav::NavGrid` built at load),
//!    then `patrol` movers, and last what the step sounded like (`hear_the_step`: the
//!    sound kit's files, where and by whom, in `SoundEvents`), and the lamps' fixtures
//!    take their lamps' switch (`switch_fixtures`);
//! 3. `Stage::Animation`: `animate_wardens` (each warden's clip for its state) and
//!    `animate_player_body` (the player's own body walks or idles), then
//!    `advance_animations` and `apply_animations` (glTF clips into node transforms and
//!    morph weights; deformer clocks);
//! 4. `Stage::Transforms`: `propagate_transforms`.
//!
//! This module imports none of render, accel, the film, winit or pixels: it sees input as a
//! resource and leaves drawing to the frame driver (`crate::frame`).

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
