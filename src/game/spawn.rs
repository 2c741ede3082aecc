//! Putting things into the world: the one path by which a level's entities become ECS
//! entities, at load (`spawn_level`) and while the game runs (`spawn`).
//!
//! A level entity becomes a root entity (`LevelEntity`, `Name`, `Transform`) carrying its
//! components (`AssetInstance`, `PunctualLight`, `ViewCamera` + `LevelCamera`,
//! `PlayerStart`, `AnimationSource` + `Animator`, `DeformerSource`, `SoundSource`), and its asset's glTF
//! node hierarchy is spawned under it: every node an entity with its `Transform`, mesh
//! nodes with `MeshNode` (and `Skin`, `MorphWeights`, `Deformer` for meshes that change
//! shape), light nodes with `AssetLight`. Despawning the root (`World::despawn`) takes the
//! hierarchy with it. Extract notices both in the next frame.

use std::path::PathBuf;
use std::sync::Arc;

use bevy_ecs::prelude::*;
use glam::Affine3A;

use super::{
    AnimationLibrary, AnimationSource, Animator, AssetInstance, AssetLight, AuthoredRotation,
    BodyClips, Deformer, DeformerSource, GlobalTransform, Input, LevelCamera, LevelEntity,
    MeshNode, MorphWeights, PlayerStart, PreviousGlobalTransform, PunctualLight, SimulationClock,
    Skin, Transform, ViewCamera,
};
use crate::scene::level::{EntityDef, Environment};
use crate::scene::model::{Asset, NodeTransform, Projection};
use crate::scene::{AssetCache, LoadError, Scene};

/// The level as a whole: what its file says besides its entities.
#[derive(Resource, Clone, Debug, PartialEq)]
pub struct LevelInfo {
    /// The file the level was loaded from.
    pub source: PathBuf,
    pub version: u32,
    pub name: String,
    pub playable: bool,
    pub campaign: Option<u32>,
    pub environment: Environment,
}

/// The asset cache, as the world's resource: spawning at run time imports through it.
#[derive(Resource, Clone, Debug, Default)]
pub struct Assets(pub AssetCache);

/// A spawned level entity: its root and the entity of each of its asset's nodes (by glTF
/// node index; empty without an asset).
pub struct Spawned {
    pub root: Entity,
    pub nodes: Vec<Entity>,
}

/// Puts `scene` into `world`: the level's resources (and the simulation's own, when
/// missing), then every level entity in file order. With no camera entity, the first
/// perspective camera of an instanced asset becomes the view (as `Scene::camera` finds
/// it). Nothing is posed yet: the frame driver poses the world before the first frame.
pub fn spawn_level(world: &mut World, scene: &Scene) {
    let base = scene
        .source
        .parent()
        .map(|p| p.to_owned())
        .unwrap_or_default();
    let mut cache = AssetCache::new(base);
    for asset in &scene.assets {
        cache.insert(Arc::clone(asset));
    }
    world.insert_resource(Assets(cache));
    world.insert_resource(super::SoundEvents::default());
    world.insert_resource(LevelInfo {
        source: scene.source.clone(),
        version: scene.level.version,
        name: scene.level.name.clone(),
        playable: scene.level.playable,
        campaign: scene.level.campaign,
        environment: scene.level.environment.clone(),
    });
    world.init_resource::<Input>();
    world.init_resource::<SimulationClock>();
    world.init_resource::<AnimationLibrary>();
    world.insert_resource(super::Progress::default());

    let mut view = None;
    for (index, def) in scene.level.entities.iter().enumerate() {
        let asset = scene.entity_assets[index].map(|a| Arc::clone(&scene.assets[a]));
        let spawned = spawn_entity(world, def, LevelEntity(index), asset.clone());
        if view.is_none()
            && let Some(asset) = &asset
        {
            view = first_camera(asset).map(|node| spawned.nodes[node]);
        }
    }
    let has_level_camera = world
        .query_filtered::<(), With<LevelCamera>>()
        .iter(world)
        .next()
        .is_some();
    if !has_level_camera
        && let Some(node) = view
        && let Some(camera) = world.get::<AssetCamera>(node).copied()
    {
        world.entity_mut(node).insert(ViewCamera {
            yfov: camera.yfov,
            znear: camera.znear,
        });
    }
}

/// An asset node's perspective camera (not a view until chosen as one).
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub struct AssetCamera {
    pub yfov: f32,
    pub znear: f32,
}

/// The first perspective camera in the asset's default scene, in `Asset::visit_nodes`
/// order.
fn first_camera(asset: &Asset) -> Option<usize> {
    let mut found = None;
    asset.visit_nodes(glam::Mat4::IDENTITY, |node, _| {
        if found.is_none()
            && let Some(camera) = asset.nodes[node].camera
            && matches!(
                asset.cameras[camera].projection,
                Projection::Perspective { .. }
            )
        {
            found = Some(node);
        }
    });
    found
}

/// Spawns a level entity at run time: its asset (if any) through the world's `Assets`
/// cache, at the level's next free place.
pub fn spawn(world: &mut World, def: &EntityDef) -> Result<Entity, LoadError> {
    let source = world
        .get_resource::<LevelInfo>()
        .map(|l| l.source.clone())
        .unwrap_or_default();
    // The level's own checks, on this entity alone.
    let alone = crate::scene::Level {
        version: crate::scene::level::LEVEL_VERSION,
        name: String::new(),
        playable: false,
        campaign: None,
        environment: Environment::default(),
        entities: vec![def.clone()],
    };
    let problems = crate::scene::level::validate_level(&alone);
    if !problems.is_empty() {
        return Err(LoadError {
            diagnostics: problems
                .into_iter()
                .map(|(pointer, message)| {
                    let place = pointer.to_string().replacen("/entities/0", "", 1);
                    crate::scene::Diagnostic::whole_file(
                        &source,
                        format!("spawning '{}': {place}: {message}", def.name),
                    )
                })
                .collect(),
        });
    }
    let asset = match &def.instance {
        Some(instance) => Some(
            world
                .get_resource_or_init::<Assets>()
                .0
                .load(&instance.asset)?,
        ),
        None => None,
    };
    let order = world
        .query::<&LevelEntity>()
        .iter(world)
        .map(|e| e.0 + 1)
        .max()
        .unwrap_or(0);
    Ok(spawn_entity(world, def, LevelEntity(order), asset).root)
}

/// Spawns level entity `def` at place `order`, instancing `asset` (the one its `instance`
/// names, already loaded). The one function every level entity goes through.
pub fn spawn_entity(
    world: &mut World,
    def: &EntityDef,
    order: LevelEntity,
    asset: Option<Arc<Asset>>,
) -> Spawned {
    let transform = Transform {
        translation: def.transform.translation,
        rotation: def.transform.rotation_quat(),
        scale: def.transform.scale,
    };
    // Placed from the start (not at the origin until the next propagation), with nothing
    // to interpolate from, so a thing spawned mid-game shows where it was put.
    let placed = transform.affine();
    let mut root = world.spawn((
        order,
        Name::new(def.name.clone()),
        transform,
        AuthoredRotation(def.transform.rotation),
        GlobalTransform(placed),
        PreviousGlobalTransform(placed),
    ));
    if let Some(light) = &def.light {
        root.insert(PunctualLight(light.clone()));
    }
    if let Some(camera) = &def.camera {
        root.insert((
            ViewCamera {
                yfov: camera.yfov_degrees.to_radians(),
                znear: camera.znear,
            },
            LevelCamera,
        ));
    }
    if let Some(spawn) = &def.player_spawn {
        root.insert(PlayerStart(spawn.clone()));
    }
    if let Some(deformer) = &def.deformer {
        root.insert(DeformerSource(deformer.clone()));
    }
    if let Some(animation) = &def.animation {
        root.insert(AnimationSource(animation.clone()));
    }
    if let Some(sound) = &def.sound {
        root.insert(super::SoundSource(sound.clone()));
    }
    if let Some(fixture) = &def.fixture {
        root.insert(super::LampFixture(fixture.clone()));
    }
    if let Some(shard) = &def.shard {
        root.insert(super::Shard {
            radius: shard.radius,
        });
    }
    if let Some(exit) = &def.exit {
        root.insert(super::Exit {
            radius: exit.radius,
        });
    }
    if let Some(mover) = &def.mover {
        root.insert(super::patrol::Patrol {
            origin: transform,
            offset: mover.offset,
            period: f64::from(mover.period),
            elapsed: 0.0,
        });
    }
    if let Some(knock) = &def.knock {
        root.insert(super::noise::Knockable {
            radius: knock.radius,
            noise: knock.noise,
            upright: transform.rotation,
            fallen: None,
        });
    }
    let root = root.id();
    if let Some(warden) = &def.warden {
        // The warden, and its lamp as a child light that moves with it.
        let (yaw, _, _) = transform.rotation.to_euler(glam::EulerRot::YXZ);
        let (parts, light, lamp) = super::warden::warden_parts(warden, yaw);
        world.entity_mut(root).insert(parts);
        let world_lamp = placed * lamp.affine();
        world.spawn((
            Name::new(format!("{} lamp", def.name)),
            super::WardenLampLight,
            light,
            lamp,
            GlobalTransform(world_lamp),
            PreviousGlobalTransform(world_lamp),
            ChildOf(root),
        ));
    }
    let (Some(asset), Some(instance)) = (asset, &def.instance) else {
        return Spawned {
            root,
            nodes: Vec::new(),
        };
    };
    world.entity_mut(root).insert(AssetInstance {
        path: instance.asset.clone(),
        asset: Arc::clone(&asset),
        material_overrides: instance.material_overrides.clone(),
    });
    let nodes = spawn_nodes(world, (root, placed), &asset, def);
    // A warden's model plays the clips its state calls for, whatever the level starts.
    let warden_clips = def.warden.as_ref().map(|_| {
        BodyClips::of(
            &mut world.get_resource_or_init::<AnimationLibrary>(),
            &asset,
        )
    });
    let authored = def
        .animation
        .as_ref()
        .and_then(|animation| Some((animation, asset.animation_by_name(&animation.clip)?)));
    let animator = match (
        authored,
        warden_clips.and_then(|clips| clips.idle_animator(&nodes)),
    ) {
        (Some((animation, clip)), _) => Some(Animator {
            clip: world
                .get_resource_or_init::<AnimationLibrary>()
                .clip(&asset, clip),
            elapsed: animation.start as f64,
            start: animation.start as f64,
            speed: animation.speed,
            playback: animation.playback,
            nodes: nodes.clone(),
        }),
        (None, idle) => idle,
    };
    if let Some(animator) = animator {
        world.entity_mut(root).insert(animator);
    }
    if let Some(clips) = warden_clips {
        world.entity_mut(root).insert(clips);
    }
    Spawned { root, nodes }
}

/// The asset's nodes under `root`, parents before children. A skinned mesh's node hangs
/// straight off the root with no transform of its own: glTF places skinned vertices by
/// their joints alone.
fn spawn_nodes(
    world: &mut World,
    (root, world_from_root): (Entity, Affine3A),
    asset: &Arc<Asset>,
    def: &EntityDef,
) -> Vec<Entity> {
    let mut node_entities = vec![Entity::PLACEHOLDER; asset.nodes.len()];
    let mut parent_node = vec![None; asset.nodes.len()];
    let mut stack: Vec<(usize, Entity, Affine3A)> = asset
        .roots
        .iter()
        .rev()
        .map(|&node| (node, root, world_from_root))
        .collect();
    while let Some((node, parent, world_from_parent)) = stack.pop() {
        let gltf_node = &asset.nodes[node];
        let skinned_mesh = gltf_node.skin.is_some() && gltf_node.mesh.is_some();
        let transform = match gltf_node.transform {
            _ if skinned_mesh => Transform::default(),
            NodeTransform::Trs {
                translation,
                rotation,
                scale,
            } => Transform {
                translation,
                rotation,
                scale,
            },
            NodeTransform::Matrix(matrix) => Transform::from_matrix(matrix),
        };
        let world_from_node = if skinned_mesh {
            world_from_root
        } else {
            world_from_parent * transform.affine()
        };
        let mut spawned = world.spawn((
            transform,
            GlobalTransform(world_from_node),
            PreviousGlobalTransform(world_from_node),
            ChildOf(if skinned_mesh { root } else { parent }),
        ));
        if let Some(light) = gltf_node.light {
            spawned.insert(AssetLight {
                root,
                node,
                light: asset.lights[light].clone(),
            });
        }
        if let Some(camera) = gltf_node.camera
            && let Projection::Perspective { yfov, znear, .. } = asset.cameras[camera].projection
        {
            spawned.insert(AssetCamera { yfov, znear });
        }
        let id = spawned.id();
        node_entities[node] = id;
        for &child in &gltf_node.children {
            parent_node[child] = Some(node);
        }
        stack.extend(
            gltf_node
                .children
                .iter()
                .rev()
                .map(|&child| (child, id, world_from_node)),
        );
    }

    // Meshes: what extract instances, and what changes their shape.
    for (node_index, node) in asset.nodes.iter().enumerate() {
        let Some(mesh) = node.mesh else { continue };
        if node_entities[node_index] == Entity::PLACEHOLDER {
            continue; // not in the default scene
        }
        let primitives = &asset.meshes[mesh].primitives;
        let targets = primitives.first().map_or(0, |p| p.morph_targets.len());
        let skinned = node.skin.is_some();
        let deforms = skinned || targets > 0 || def.deformer.is_some();
        let mut entity = world.entity_mut(node_entities[node_index]);
        entity.insert(MeshNode {
            root,
            asset: Arc::clone(asset),
            node: node_index,
            mesh,
            deforms,
        });
        if let Some(skin) = node.skin {
            let skin = &asset.skins[skin];
            // Joints and their ancestors below the root: what moves the pose.
            let mut watched = Vec::new();
            for &joint in &skin.joints {
                let mut current = Some(joint);
                while let Some(n) = current {
                    if !watched.contains(&node_entities[n]) {
                        watched.push(node_entities[n]);
                    }
                    current = parent_node[n];
                }
            }
            entity.insert(Skin {
                root,
                joints: skin.joints.iter().map(|&j| node_entities[j]).collect(),
                inverse_bind_matrices: skin.inverse_bind_matrices.clone(),
                watched,
            });
        }
        if targets > 0 {
            let weights = node
                .morph_weights
                .clone()
                .or_else(|| {
                    let defaults = &asset.meshes[mesh].morph_weights;
                    (!defaults.is_empty()).then(|| defaults.clone())
                })
                .unwrap_or_else(|| vec![0.0; targets]);
            entity.insert(MorphWeights(weights));
        }
        if let Some(kind) = &def.deformer {
            entity.insert(Deformer {
                kind: kind.clone(),
                time: 0.0,
            });
        }
    }
    node_entities
}
