//! Extract, for the simulation: the level's geometry as of the current fixed step
//! (`StepWorld`), which answers the game's `WorldQuery` (the body's contacts, rays).
//!
//! The frame driver runs `update_step_world` at the start of every fixed step (timed under
//! `Stage::Gameplay`), so the step's systems see the world as the previous step left it:
//! every mesh node that keeps its shape, placed by its `GlobalTransform` (never the
//! render's interpolated transforms), in content order (level entity name, then glTF
//! node). Mesh nodes spawned or despawned since the last step assemble the instances
//! again; moved ones move their instance; the TLAS is rebuilt when anything changed.
//! Each asset mesh gets one BLAS of its own, built once with the fast preset. Meshes that
//! deform (wardens, banners) are left out: the game knows its wardens' bodies itself.

use std::collections::HashMap;
use std::sync::Arc;

use bevy_ecs::prelude::*;
use glam::{Affine3A, Vec3, Vec3A};

use super::{instance_user_id, is_drawable, mesh_geometry};
use crate::accel::{AccelScene, Blas, Instance, InstanceMask, Opaque, Ray};
use crate::game::world_query::{Contact, WorldGeometry, WorldQuery};
use crate::game::{GlobalTransform, MeshNode};
use crate::profile::{Stage, StageTimes, since};
use crate::scene::AssetKey;

/// The simulation's copy of the level's rigid geometry.
pub struct StepWorld {
    accel: AccelScene,
    /// The BLAS of each asset mesh, by (asset, mesh).
    meshes: HashMap<(AssetKey, usize), u32>,
    /// The instance of each mesh node.
    instance_of: HashMap<Entity, u32>,
    /// Scratch for contacts in accel's terms.
    found: std::sync::Mutex<Vec<crate::accel::Contact>>,
}

impl Default for StepWorld {
    fn default() -> Self {
        StepWorld {
            accel: AccelScene::new(Vec::new(), Vec::new()),
            meshes: HashMap::new(),
            instance_of: HashMap::new(),
            found: std::sync::Mutex::new(Vec::new()),
        }
    }
}

impl StepWorld {
    /// The instances the simulation collides with.
    pub fn accel(&self) -> &AccelScene {
        &self.accel
    }
}

impl WorldQuery for StepWorld {
    fn sphere_contacts(&self, center: Vec3, radius: f32, out: &mut Vec<Contact>) {
        // One step's queries run on one thread; the lock is never contended.
        let mut found = self
            .found
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        found.clear();
        self.accel
            .sphere_contacts(Vec3A::from(center), radius, InstanceMask::ALL, &mut found);
        out.extend(found.iter().map(|c| Contact {
            point: c.point.into(),
            normal: c.normal.into(),
            distance: c.distance,
        }));
    }

    fn raycast(&self, origin: Vec3, direction: Vec3, max_distance: f32) -> Option<f32> {
        let mut ray = Ray::new(origin.into(), direction.into());
        ray.t_max = max_distance;
        self.accel
            .intersect(&ray, InstanceMask::ALL, &Opaque)
            .map(|hit| hit.t)
    }

    fn as_any_mut(&mut self) -> &mut dyn std::any::Any {
        self
    }
}

/// The schedule the frame driver runs at the start of every fixed step.
pub fn step_world_schedule() -> Schedule {
    let mut schedule = Schedule::default();
    schedule.add_systems(update_step_world);
    schedule
}

/// Brings the `StepWorld` in `WorldGeometry` up to the world as it stands (see the module
/// doc). A `WorldGeometry` holding another answerer (a test's fake world) is left alone.
#[allow(clippy::type_complexity)]
pub fn update_step_world(
    added: Query<(), Added<MeshNode>>,
    mut removed: RemovedComponents<MeshNode>,
    moved: Query<(Entity, &GlobalTransform), (With<MeshNode>, Changed<GlobalTransform>)>,
    meshes: Query<(Entity, &MeshNode, &GlobalTransform)>,
    names: Query<&Name>,
    mut geometry: ResMut<WorldGeometry>,
    mut times: ResMut<StageTimes>,
) {
    let start = std::time::Instant::now();
    let Some(world) = geometry.0.as_any_mut().downcast_mut::<StepWorld>() else {
        return;
    };
    let structure = !added.is_empty() || removed.read().next().is_some();
    removed.clear();
    if structure {
        assemble(world, &meshes, &names);
    } else if !moved.is_empty() {
        let mut changed = false;
        for (entity, global) in &moved {
            if let Some(&index) = world.instance_of.get(&entity)
                && is_drawable(&global.0)
            {
                world.accel.instances_mut()[index as usize].set_transform(global.0);
                changed = true;
            }
        }
        if changed {
            world.accel.rebuild_tlas();
        }
    }
    times.add(Stage::Gameplay, since(start));
}

/// A mesh node to instance: its content key (root name, node, root), entity, node and
/// world transform.
type StepEntry<'a> = ((&'a str, usize, u64), Entity, &'a MeshNode, Affine3A);

/// The instances again, in content order, with a BLAS for each new asset mesh.
fn assemble(
    world: &mut StepWorld,
    meshes: &Query<(Entity, &MeshNode, &GlobalTransform)>,
    names: &Query<&Name>,
) {
    let mut entries: Vec<StepEntry> = meshes
        .iter()
        .filter(|(_, node, global)| !node.deforms && is_drawable(&global.0))
        .filter_map(|(entity, node, global)| {
            let name = names.get(node.root).ok()?;
            Some((
                (name.as_str(), node.node, node.root.to_bits()),
                entity,
                node,
                global.0,
            ))
        })
        .collect();
    entries.sort_by(|a, b| a.0.cmp(&b.0));
    let mut instances = Vec::with_capacity(entries.len());
    world.instance_of.clear();
    for (_, entity, node, transform) in entries {
        let key = (AssetKey(Arc::clone(&node.asset)), node.mesh);
        let blas = match world.meshes.get(&key) {
            Some(&blas) => blas,
            None => {
                let geometry = mesh_geometry(&node.asset, node.mesh, 0);
                world.accel.blases.push(Blas::build_for_queries(geometry));
                let blas = world.accel.blases.len() as u32 - 1;
                world.meshes.insert(key, blas);
                blas
            }
        };
        world.instance_of.insert(entity, instances.len() as u32);
        instances.push(Instance::new(
            blas,
            transform,
            InstanceMask::ALL,
            instance_user_id(entity),
        ));
    }
    world.accel.set_instances(instances);
}
