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
//!
//! The lights are gathered every step as the renderer defines them (`render::light::
//! Light`, made by the same `extract::lights` code): the lit punctual lights in content
//! order, then the emissive triangles of the instances (their material's emission, with
//! the entity's overrides; none when switched off), and the level's sky.
//! `light_arriving` measures each with shadow rays through this copy of the level: a
//! punctual light along one ray, an emissive triangle at four fixed points, the sky along
//! eight fixed cosine-weighted directions above.

use std::collections::HashMap;
use std::sync::Arc;

use bevy_ecs::prelude::*;
use glam::{Affine3A, Vec2, Vec3, Vec3A};

use super::{instance_user_id, is_drawable, mesh_geometry};
use crate::accel::{AccelScene, Blas, Instance, InstanceMask, Opaque, Ray};
use crate::game::world_query::{Contact, RayHit, Surface, WorldGeometry, WorldQuery};
use crate::game::{
    AssetInstance, AssetLight, GlobalTransform, LevelInfo, MeshNode, PunctualLight, SwitchedOff,
};
use crate::profile::{GameplayPhase, Stage, StageTimes, since};
use crate::render::light::Light;
use crate::scene::AssetKey;
use crate::scene::model::Light as LightDef;
use crate::scene::model::luminance;

/// The simulation's copy of the level's rigid geometry.
pub struct StepWorld {
    accel: AccelScene,
    /// The BLAS of each asset mesh, by (asset, mesh).
    meshes: HashMap<(AssetKey, usize), u32>,
    /// The instance of each mesh node.
    instance_of: HashMap<Entity, u32>,
    /// Scratch for contacts in accel's terms.
    found: std::sync::Mutex<Vec<crate::accel::Contact>>,
    /// Every light as of this step: punctual lights, then emissive triangles.
    lights: Vec<Light>,
    /// Emitted radiance by `Light::Triangle::material` (an index into this table), and
    /// whether that material emits from both sides.
    emission: Vec<Vec3>,
    emission_sides: Vec<bool>,
    /// Per emitting instance, its emissive triangles (triangle, index into `emission`).
    emitters: Vec<(u32, Vec<(u32, u32)>)>,
    /// Radiance of the sky.
    sky: Vec3,
    /// Per mirroring instance, its mirror triangles (see `is_mirror`).
    mirror_triangles: Vec<(u32, Vec<u32>)>,
    /// Those triangles in world space as of this step, front faces by their winding.
    mirrors: Vec<[Vec3; 3]>,
    /// Per instance, how each of its asset's materials sounds (`Surface::of`).
    surfaces: Vec<Vec<Surface>>,
}

/// A material the game treats as a mirror that wardens and the player see each other in:
/// a perfect conductor (metallic 1, roughness 0, no texture to vary either), as the
/// renderer reflects it.
fn is_mirror(material: &crate::scene::model::Material) -> bool {
    material.metallic >= 0.99
        && material.roughness <= 0.01
        && material.metallic_roughness_texture.is_none()
}

impl Default for StepWorld {
    fn default() -> Self {
        StepWorld {
            accel: AccelScene::new(Vec::new(), Vec::new()),
            meshes: HashMap::new(),
            instance_of: HashMap::new(),
            found: std::sync::Mutex::new(Vec::new()),
            lights: Vec::new(),
            emission: Vec::new(),
            emission_sides: Vec::new(),
            emitters: Vec::new(),
            mirror_triangles: Vec::new(),
            mirrors: Vec::new(),
            surfaces: Vec::new(),
            sky: Vec3::ZERO,
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

    fn raycast(&self, origin: Vec3, direction: Vec3, max_distance: f32) -> Option<RayHit> {
        let mut ray = Ray::new(origin.into(), direction.into());
        ray.t_max = max_distance;
        let hit = self.accel.intersect(&ray, InstanceMask::ALL, &Opaque)?;
        let surface = self.accel.surface(&hit);
        let sounds = self
            .surfaces
            .get(hit.instance as usize)
            .and_then(|materials| materials.get(surface.material as usize));
        Some(RayHit {
            distance: hit.t,
            normal: surface.geometric_normal.into(),
            surface: sounds.copied().unwrap_or(Surface::Stone),
        })
    }

    fn mirrors(&self) -> &[[Vec3; 3]] {
        &self.mirrors
    }

    fn light_arriving(&self, point: Vec3) -> Vec3 {
        let point = Vec3A::from(point);
        let emission = |material: u32, _| self.emission[material as usize];
        let mut total = Vec3::ZERO;
        for (index, light) in self.lights.iter().enumerate() {
            let samples: &[Vec2] = match light {
                Light::Triangle { .. } => &TRIANGLE_POINTS,
                _ => &[Vec2::ZERO],
            };
            for &u in samples {
                let Some(sample) = light.sample(index as u32, 1.0, point, u, emission) else {
                    continue;
                };
                let arriving = sample.radiance / (sample.pdf * samples.len() as f32);
                if luminance(arriving) < REACH {
                    continue;
                }
                let ray = match light {
                    Light::Directional { .. } => Ray::new(point, sample.wi),
                    _ => {
                        let mut ray = Ray::new(point, sample.point - point);
                        ray.t_max = 1.0 - 1e-4;
                        ray
                    }
                };
                if !self.accel.occluded(&ray, InstanceMask::ALL, &Opaque) {
                    total += arriving;
                }
            }
        }
        if self.sky != Vec3::ZERO {
            let open = SKY_DIRECTIONS
                .iter()
                .filter(|&&direction| {
                    let ray = Ray::new(point, Vec3A::from(direction));
                    !self.accel.occluded(&ray, InstanceMask::ALL, &Opaque)
                })
                .count();
            // A uniform sky gives pi L on an open upward surface; each cosine-weighted
            // direction carries an equal share of it.
            total += self.sky * (std::f32::consts::PI * open as f32 / SKY_DIRECTIONS.len() as f32);
        }
        total
    }

    fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let bounds = self.accel.bounds();
        (bounds.min.x <= bounds.max.x).then(|| (bounds.min.into(), bounds.max.into()))
    }

    fn as_any_mut(&mut self) -> &mut dyn std::any::Any {
        self
    }
}

/// Below this luminance a light's share is not worth a shadow ray (W/m^2; the light gem's
/// half point is 1).
const REACH: f32 = 1e-4;

/// The fixed points an emissive triangle is measured at (square samples mapped onto it).
const TRIANGLE_POINTS: [Vec2; 4] = [
    Vec2::new(0.25, 0.25),
    Vec2::new(0.75, 0.25),
    Vec2::new(0.25, 0.75),
    Vec2::new(0.75, 0.75),
];

/// Eight directions above the horizon carrying equal shares of a uniform sky's light on
/// an upward surface (`sky_directions`).
const SKY_DIRECTIONS: [Vec3; 8] = sky_directions();

/// Directions at the centres of eight equal-cosine-weight cells: two rings of four,
/// at sin^2(theta) = 1/4 and 3/4 (theta 30 and 60 degrees), the rings turned 45 degrees.
const fn sky_directions() -> [Vec3; 8] {
    // sin and cos of 30 and 60 degrees; the azimuths' sines and cosines.
    const S30: f32 = 0.5;
    const C30: f32 = 0.866_025_4;
    const H: f32 = std::f32::consts::FRAC_1_SQRT_2;
    [
        Vec3::new(S30, C30, 0.0),
        Vec3::new(0.0, C30, S30),
        Vec3::new(-S30, C30, 0.0),
        Vec3::new(0.0, C30, -S30),
        Vec3::new(C30 * H, S30, C30 * H),
        Vec3::new(-C30 * H, S30, C30 * H),
        Vec3::new(-C30 * H, S30, -C30 * H),
        Vec3::new(C30 * H, S30, -C30 * H),
    ]
}

/// The schedule the frame driver runs at the start of every fixed step.
pub fn step_world_schedule() -> Schedule {
    let mut schedule = Schedule::default();
    schedule.add_systems(update_step_world);
    schedule
}

/// Roots as the step world reads them: their name, materials and switch.
type RootData<'a> = (&'a Name, Option<&'a AssetInstance>, Has<SwitchedOff>);

/// An entity's materials or switch changed.
type Rematerialed = Or<(Changed<AssetInstance>, Changed<SwitchedOff>)>;

/// Mesh nodes moved since the last step.
type MovedMeshes<'a> = (Entity, &'a GlobalTransform);
type MovedFilter = (With<MeshNode>, Changed<GlobalTransform>);

/// A lit punctual light: its content key (root name, asset node), the light and where.
type PlacedLight<'a> = ((&'a str, Option<usize>), LightDef, Affine3A);

/// What, since the last step, calls for assembling the instances anew.
#[derive(bevy_ecs::system::SystemParam)]
pub struct StepStructure<'w, 's> {
    added: Query<'w, 's, (), Added<MeshNode>>,
    removed: RemovedComponents<'w, 's, MeshNode>,
    rematerialed: Query<'w, 's, (), Rematerialed>,
    unswitched: RemovedComponents<'w, 's, SwitchedOff>,
}

impl StepStructure<'_, '_> {
    fn changed(&mut self) -> bool {
        let changed = !self.added.is_empty()
            || !self.rematerialed.is_empty()
            || self.removed.read().next().is_some()
            || self.unswitched.read().next().is_some();
        self.removed.clear();
        self.unswitched.clear();
        changed
    }
}

/// Brings the `StepWorld` in `WorldGeometry` up to the world as it stands (see the module
/// doc). A `WorldGeometry` holding another answerer (a test's fake world) is left alone.
#[allow(clippy::too_many_arguments)]
pub fn update_step_world(
    mut structure: StepStructure,
    moved: Query<MovedMeshes, MovedFilter>,
    meshes: Query<(Entity, &MeshNode, &GlobalTransform)>,
    roots: Query<RootData>,
    punctual: Query<(&Name, &PunctualLight, &GlobalTransform, Has<SwitchedOff>)>,
    asset_lights: Query<(&AssetLight, &GlobalTransform)>,
    level: Option<Res<LevelInfo>>,
    mut geometry: ResMut<WorldGeometry>,
    mut times: ResMut<StageTimes>,
) {
    let start = std::time::Instant::now();
    let Some(world) = geometry.0.as_any_mut().downcast_mut::<StepWorld>() else {
        return;
    };
    if structure.changed() {
        assemble(world, &meshes, &roots);
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
    // The lights as of this step, in content order: punctual, then emitters.
    let mut placed: Vec<PlacedLight> = Vec::new();
    for (name, light, global, switched) in &punctual {
        if !switched {
            placed.push((
                (name.as_str(), None),
                light.0.to_light(name.as_str()),
                global.0,
            ));
        }
    }
    for (light, global) in &asset_lights {
        if let Ok((name, _, switched)) = roots.get(light.root)
            && !switched
        {
            placed.push((
                (name.as_str(), Some(light.node)),
                light.light.clone(),
                global.0,
            ));
        }
    }
    placed.sort_by(|a, b| a.0.cmp(&b.0));
    let bounds = world.accel.bounds();
    let radius = (bounds.max - bounds.min).length() * 0.5;
    world.lights.clear();
    for (_, light, transform) in &placed {
        world
            .lights
            .push(super::lights::punctual_light(light, transform, radius).0);
    }
    for (instance, triangles) in &world.emitters {
        let instance = &world.accel.instances()[*instance as usize];
        let to_world = instance.world_from_object();
        let mirrored = to_world.matrix3.determinant() < 0.0;
        let geometry = &world.accel.blases[instance.blas as usize].geometry;
        for &(triangle, material) in triangles {
            let vertices = geometry
                .triangle_vertices(triangle as usize)
                .map(|v| to_world.transform_point3a(v));
            let (normal, area) = super::lights::emitter_frame(&vertices, mirrored);
            if area > 0.0 {
                world.lights.push(Light::Triangle {
                    vertices,
                    uvs: [Vec2::ZERO; 3],
                    normal,
                    area,
                    material,
                    double_sided: world.emission_sides[material as usize],
                });
            }
        }
    }
    world.mirrors.clear();
    for (instance, triangles) in &world.mirror_triangles {
        let instance = &world.accel.instances()[*instance as usize];
        let to_world = instance.world_from_object();
        let mirrored = to_world.matrix3.determinant() < 0.0;
        let geometry = &world.accel.blases[instance.blas as usize].geometry;
        for &triangle in triangles {
            let [a, b, c] = geometry
                .triangle_vertices(triangle as usize)
                .map(|v| Vec3::from(to_world.transform_point3a(v)));
            // A mirrored placement turns the winding: keep the front the front.
            world
                .mirrors
                .push(if mirrored { [a, c, b] } else { [a, b, c] });
        }
    }
    world.sky = level.map_or(Vec3::ZERO, |l| l.environment.sky);
    let ms = since(start);
    times.add(Stage::Gameplay, ms);
    times.add_gameplay(GameplayPhase::World, ms);
}

/// A mesh node to instance: its content key (root name, node, root), entity, node and
/// world transform.
type StepEntry<'a> = ((&'a str, usize, u64), Entity, &'a MeshNode, Affine3A);

/// The instances again, in content order, with a BLAS for each new asset mesh.
fn assemble(
    world: &mut StepWorld,
    meshes: &Query<(Entity, &MeshNode, &GlobalTransform)>,
    roots: &Query<RootData>,
) {
    let mut entries: Vec<StepEntry> = meshes
        .iter()
        .filter(|(_, node, global)| !node.deforms && is_drawable(&global.0))
        .filter_map(|(entity, node, global)| {
            let (name, ..) = roots.get(node.root).ok()?;
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
    world.emitters.clear();
    world.emission.clear();
    world.emission_sides.clear();
    world.mirror_triangles.clear();
    world.surfaces.clear();
    for (_, entity, node, transform) in entries {
        world
            .surfaces
            .push(node.asset.materials.iter().map(Surface::of).collect());
        let mut mirror = Vec::new();
        let mut triangle = 0u32;
        for primitive in &node.asset.meshes[node.mesh].primitives {
            let count = primitive.indices.len() as u32;
            if primitive
                .material
                .is_some_and(|material| is_mirror(&node.asset.materials[material]))
            {
                mirror.extend(triangle..triangle + count);
            }
            triangle += count;
        }
        if !mirror.is_empty() {
            world
                .mirror_triangles
                .push((instances.len() as u32, mirror));
        }
        // Its emissive triangles, by the materials as the entity has them.
        if let Ok((_, asset_instance, switched)) = roots.get(node.root)
            && !switched
        {
            let first = world.emission.len() as u32;
            for material in &node.asset.materials {
                let resolved =
                    match asset_instance.and_then(|i| i.material_overrides.get(&material.name)) {
                        Some(change) => change.apply(material),
                        None => material.clone(),
                    };
                world.emission.push(resolved.emissive);
                world.emission_sides.push(resolved.double_sided);
            }
            let mut triangles = Vec::new();
            let mut triangle = 0u32;
            for primitive in &node.asset.meshes[node.mesh].primitives {
                let count = primitive.indices.len() as u32;
                if let Some(material) = primitive.material
                    && world.emission[(first + material as u32) as usize] != Vec3::ZERO
                {
                    triangles
                        .extend((triangle..triangle + count).map(|t| (t, first + material as u32)));
                }
                triangle += count;
            }
            if triangles.is_empty() {
                world.emission.truncate(first as usize);
                world.emission_sides.truncate(first as usize);
            } else {
                world.emitters.push((instances.len() as u32, triangles));
            }
        }
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
