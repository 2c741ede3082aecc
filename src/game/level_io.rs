//! Writing the world back as a level: every level entity (`LevelEntity`) with every
//! component the level format has, in level order. The editor saves through this, and a
//! level loaded and written back with no change is byte-for-byte the file it came from
//! (`scene::level::level_to_string` is stable, and rotations go back to the degrees the
//! file wrote: `AuthoredRotation`).

use bevy_ecs::prelude::*;
use glam::{EulerRot, Quat, Vec3};

use super::{
    AnimationSource, AssetInstance, AuthoredRotation, DeformerSource, Exit, LevelCamera,
    LevelEntity, LevelInfo, PlayerStart, PunctualLight, Shard, Transform, ViewCamera, Warden,
};
use crate::scene::level::{
    CameraDef, EntityDef, ExitDef, InstanceDef, LEVEL_VERSION, Level, ShardDef, TransformDef,
};

/// The level the world holds now.
pub fn level_from_world(world: &mut World) -> Level {
    let info = world.get_resource::<LevelInfo>().cloned();
    let entities = entity_defs(world);
    let info = info.unwrap_or(LevelInfo {
        source: Default::default(),
        version: LEVEL_VERSION,
        name: String::new(),
        playable: true,
        campaign: None,
        environment: Default::default(),
    });
    Level {
        version: info.version,
        name: info.name,
        playable: info.playable,
        campaign: info.campaign,
        environment: info.environment,
        entities: entities.into_iter().map(|(_, def)| def).collect(),
    }
}

/// Every level entity's place in the level and its definition as the world holds it now,
/// in level order.
pub fn entity_defs(world: &mut World) -> Vec<(LevelEntity, EntityDef)> {
    let mut query = world.query::<(
        &LevelEntity,
        &Name,
        &Transform,
        Option<&AuthoredRotation>,
        Option<&AssetInstance>,
        Option<&PunctualLight>,
        Option<(&ViewCamera, &LevelCamera)>,
        Option<&PlayerStart>,
        Option<&AnimationSource>,
        Option<&DeformerSource>,
        (
            Option<&Shard>,
            Option<&Exit>,
            Option<&Warden>,
            Option<&super::noise::Knockable>,
            Option<&super::patrol::Patrol>,
            Option<&super::SoundSource>,
            Option<&super::LampFixture>,
        ),
    )>();
    let mut entities: Vec<(LevelEntity, EntityDef)> = query
        .iter(world)
        .map(
            |(
                order,
                name,
                transform,
                authored,
                instance,
                light,
                camera,
                spawn,
                animation,
                deformer,
                (shard, exit, warden, knock, mover, sound, fixture),
            )| {
                // A mover is saved at its place, not where its swing has taken it.
                let transform = mover.map_or(*transform, |m| m.origin);
                // A knocked thing is saved standing.
                let transform = knock.map_or(transform, |k| Transform {
                    rotation: k.upright,
                    ..transform
                });
                let def = EntityDef {
                    name: name.as_str().to_owned(),
                    transform: TransformDef {
                        translation: transform.translation,
                        rotation: degrees_of(transform.rotation, authored),
                        scale: transform.scale,
                    },
                    instance: instance.map(|instance| InstanceDef {
                        asset: instance.path.clone(),
                        material_overrides: instance.material_overrides.clone(),
                    }),
                    light: light.map(|l| l.0.clone()),
                    camera: camera.map(|(view, _)| CameraDef {
                        yfov_degrees: round_degrees(view.yfov.to_degrees()),
                        znear: view.znear,
                    }),
                    player_spawn: spawn.map(|s| s.0.clone()),
                    animation: animation.map(|a| a.0.clone()),
                    deformer: deformer.map(|d| d.0.clone()),
                    shard: shard.map(|s| ShardDef { radius: s.radius }),
                    exit: exit.map(|e| ExitDef { radius: e.radius }),
                    warden: warden.map(|w| w.def.clone()),
                    knock: knock.map(|k| crate::scene::level::KnockDef {
                        radius: k.radius,
                        noise: k.noise,
                    }),
                    mover: mover.map(|m| crate::scene::level::MoverDef {
                        offset: m.offset,
                        period: m.period as f32,
                    }),
                    sound: sound.map(|s| s.0.clone()),
                    fixture: fixture.map(|f| f.0.clone()),
                };
                (*order, def)
            },
        )
        .collect();
    entities.sort_by(|(a, x), (b, y)| a.cmp(b).then_with(|| x.name.cmp(&y.name)));
    entities
}

/// The rotation in the level's degrees: the authored numbers while they still make
/// `rotation` exactly, else Euler angles (pitch X, yaw Y, roll Z, applied yaw-pitch-roll as
/// `TransformDef::rotation_quat`) rounded to 1/10000 of a degree, which removes the float
/// noise of the round trip and keeps far finer than any editor's snapping.
fn degrees_of(rotation: Quat, authored: Option<&AuthoredRotation>) -> Vec3 {
    if let Some(authored) = authored {
        let def = TransformDef {
            rotation: authored.0,
            ..TransformDef::default()
        };
        if def.rotation_quat() == rotation {
            return authored.0;
        }
    }
    let (yaw, pitch, roll) = rotation.to_euler(EulerRot::YXZ);
    Vec3::new(
        round_degrees(pitch.to_degrees()),
        round_degrees(yaw.to_degrees()),
        round_degrees(roll.to_degrees()),
    )
}

/// `degrees` to 1/10000 of a degree, with -0 written as 0.
fn round_degrees(degrees: f32) -> f32 {
    let rounded = ((degrees as f64 * 1e4).round() / 1e4) as f32;
    if rounded == 0.0 { 0.0 } else { rounded }
}
