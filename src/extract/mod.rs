//! Frame step `extract`, and the ECS side of `accel`: the ECS made into the `RenderScene`
//! that `accel` and `render` read. The only code that writes a `RenderScene`.
//!
//! The world is the source of truth; `RenderState` (a resource) holds the scene made from
//! it and the caches that keep each frame's work to what changed. Per frame, chained,
//! steps 1 and 2 are extract (`extract_schedule`) and step 3 accel (`accel_schedule`):
//! 1. `extract_scene` (`Stage::Extract`), from change detection:
//!    - a mesh node spawned or despawned, an `AssetInstance` changed (material
//!      overrides), a `SwitchedOff` marker added or removed: the instances are assembled
//!      again in content order (level entity name, then glTF node index), reusing each
//!      mesh's BLAS (one per distinct asset mesh that keeps its shape, one per deforming
//!      node), with the materials' override blocks rebuilt; accel keeps the static
//!      batches whose members are all unchanged; the light set is built anew only if an
//!      emitter was added, removed or changed its emission (else its entries are renumbered);
//!    - a punctual light added, removed or changed (colour, intensity, cone): the light
//!      set is rebuilt;
//!    - otherwise, only moved things: each instance whose entity moved gets its
//!      transform, interpolated between the last two simulation steps by how far real
//!      time has run into the next one, and moved punctual lights are moved in place;
//!    - the view camera, interpolated the same way;
//! 2. `deform::deform_meshes` (`Stage::Animation`): skinning, morph targets and
//!    procedural deformers for meshes whose pose changed, written into their BLASes;
//! 3. `update_acceleration` (`Stage::BlasRefit`, then `Stage::TlasBuild`): the deformed
//!    BLASes are refit, the TLAS is rebuilt when anything moved, emitters follow their instances (or the light set is built, when step 1
//!    asked for it: after deformation, so emitters are weighted by the shape they have),
//!    and static batches re-form once the static instances have kept still for
//!    `REBATCH_AFTER_FRAMES`.
//!
//! Since instances, override blocks and lights enter in an order that depends only on
//! content, the same world renders the same image however it came to be (loaded, or
//! edited into shape). The asset material tables keep the order assets were first seen
//! in; nothing the renderer computes depends on where a material sits.

pub mod deform;
mod lights;
mod materials;
pub mod step_world;

use std::collections::HashMap;
use std::sync::Arc;

use bevy_ecs::prelude::*;
use glam::{Affine3A, Vec3};
use rayon::prelude::*;

use crate::accel::{
    AccelScene, Blas, BlasKind, Instance, InstanceMask, MeshGeometry, Mobility, RefitOutcome,
};
use crate::game::{
    ActiveCamera, AnimationSource, Animator, AssetInstance, AssetLight, DeformerSource,
    GlobalTransform, LevelInfo, MeshNode, Patrol, PlayerBody, PlayerStart, PreviousGlobalTransform,
    PunctualLight, SimulationClock, SwitchedOff, ViewCamera, interpolate,
};
use crate::profile::{Stage, StageTimes, since};
use crate::render::light::LightSet;
pub use crate::render::scene::SceneChanges;
use crate::render::scene::{DEFAULT_MATERIAL, InstanceShading, RenderScene};
use crate::scene::AssetKey;
use crate::scene::model::{AlphaMode, Asset, Light as LightDef};
use crate::scene::world::CameraPlacement;

pub use deform::{DeformSource, DeformStats};
pub use lights::refresh_triangle_lights;
use materials::{DEFAULT_MATERIAL_INDEX, MaterialTable};

/// Frames the static instances must keep still (none spawned, despawned or moved) before
/// their batches re-form: an edit being dragged, or a run of spawns, re-forms once at its
/// end rather than every frame.
pub const REBATCH_AFTER_FRAMES: u32 = 30;

/// The accel `user_id` of the instance drawing mesh node `entity`: picking finds the
/// entity again by it.
pub fn instance_user_id(entity: Entity) -> u64 {
    entity.to_bits()
}

/// The entity an accel instance draws (the inverse of `instance_user_id`).
pub fn instance_entity(user_id: u64) -> Option<Entity> {
    Entity::try_from_bits(user_id)
}

/// All of a glTF mesh's primitives as one triangle soup; triangle material ids are
/// `material_offset` + the asset's material index (`DEFAULT_MATERIAL` for none).
pub fn mesh_geometry(asset: &Asset, mesh: usize, material_offset: u32) -> MeshGeometry {
    let mut geometry = MeshGeometry::default();
    let primitives = &asset.meshes[mesh].primitives;
    let has_uvs = primitives.iter().all(|p| !p.uv0.is_empty());
    for primitive in primitives {
        let base = geometry.positions.len() as u32;
        geometry.positions.extend_from_slice(&primitive.positions);
        geometry.normals.extend_from_slice(&primitive.normals);
        if has_uvs {
            geometry.uvs.extend_from_slice(&primitive.uv0);
        }
        geometry
            .triangles
            .extend(primitive.indices.iter().map(|t| t.map(|i| i + base)));
        let material = primitive
            .material
            .map_or(DEFAULT_MATERIAL, |m| material_offset + m as u32);
        let alpha_tested = primitive
            .material
            .is_some_and(|m| !matches!(asset.materials[m].alpha_mode, AlphaMode::Opaque));
        geometry
            .materials
            .extend(std::iter::repeat_n(material, primitive.indices.len()));
        geometry
            .alpha_tested
            .extend(std::iter::repeat_n(alpha_tested, primitive.indices.len()));
    }
    if !geometry.alpha_tested.contains(&true) {
        geometry.alpha_tested.clear();
    }
    geometry
}

/// The scene as the renderer reads it, and the caches extract keeps it with.
#[derive(Resource)]
pub struct RenderState {
    pub scene: RenderScene,
    /// What the last frame's extract changed.
    pub changes: SceneChanges,
    /// Light sets built so far (a new set is built only when a light or emitter is added,
    /// removed, switched or changes power).
    pub light_set_builds: u64,
    /// The TLAS must be rebuilt before the next query.
    tlas_stale: bool,
    /// BLASes whose geometry extract deformed this frame, for accel to refit.
    pub(crate) refit: Vec<u32>,
    /// Per accel instance: moved or deformed this frame (its emissive triangles follow).
    moved: Vec<bool>,
    /// Materials and textures (append-only base tables).
    materials: MaterialTable,
    /// The BLAS of each asset mesh that keeps its shape, by (asset file, mesh).
    mesh_blases: HashMap<(AssetKey, usize), u32>,
    /// The BLAS of each deforming mesh node.
    node_blases: HashMap<Entity, u32>,
    /// BLAS slots of despawned deforming nodes, emptied, for the next one.
    free_blases: Vec<u32>,
    /// The accel instance of each mesh node entity.
    instance_of: HashMap<Entity, u32>,
    /// Each lit punctual light's entity and its index in the light set.
    light_of: Vec<(Entity, u32)>,
    /// The light set is to be built anew this frame, with these punctual lights (lit
    /// ones, in content order, placed).
    pending_lights: Option<Vec<(Entity, LightDef, Affine3A)>>,
    /// Deformation sources and per-node state (`deform`).
    pub(crate) deform: deform::DeformCache,
    /// Each BLAS's distinct triangle material ids (which materials an instance can emit by).
    blas_materials: HashMap<u32, Vec<u32>>,
    /// A light set has been built (the first assembly always builds one).
    assembled_lights: bool,
    /// Frames since a static instance was last added, removed or moved.
    still_frames: u32,
    /// The first assembly builds batches at once (a level's load), later ones wait.
    assembled: bool,
}

impl Default for RenderState {
    fn default() -> Self {
        let materials = MaterialTable::new();
        RenderState {
            scene: RenderScene {
                accel: AccelScene::new(Vec::new(), Vec::new()),
                materials: materials.base.clone(),
                instance_shading: Vec::new(),
                default_material: DEFAULT_MATERIAL_INDEX,
                textures: Vec::new(),
                lights: LightSet::default(),
                sky: Vec3::ZERO,
                camera: CameraPlacement::framing(Vec3::ZERO, Vec3::ONE),
            },
            changes: SceneChanges::default(),
            light_set_builds: 0,
            tlas_stale: false,
            refit: Vec::new(),
            moved: Vec::new(),
            materials,
            mesh_blases: HashMap::new(),
            node_blases: HashMap::new(),
            free_blases: Vec::new(),
            instance_of: HashMap::new(),
            light_of: Vec::new(),
            pending_lights: None,
            deform: deform::DeformCache::default(),
            blas_materials: HashMap::new(),
            assembled_lights: false,
            still_frames: 0,
            assembled: false,
        }
    }
}

impl RenderState {
    /// The accel instance drawing mesh node `entity`, if it is drawn.
    pub fn instance_of(&self, entity: Entity) -> Option<u32> {
        self.instance_of.get(&entity).copied()
    }

    /// The light set's index of punctual light `entity`, while it is lit.
    pub fn light_of(&self, entity: Entity) -> Option<u32> {
        self.light_of
            .iter()
            .find(|(lit, _)| *lit == entity)
            .map(|&(_, index)| index)
    }

    /// Re-forms the static batches now, over the instances as they stand.
    pub fn rebatch(&mut self) {
        self.scene.accel.rebatch();
        self.still_frames = 0;
    }
}

/// The extract step's systems, chained, in one schedule: the scene from the ECS, then
/// the deformed meshes' geometry.
pub fn extract_schedule() -> Schedule {
    let mut schedule = Schedule::default();
    schedule.add_systems((extract_scene, deform::deform_meshes).chain());
    schedule
}

/// The accel step, in one schedule: the deformed BLASes refit, the TLAS rebuilt
/// (`update_acceleration`). The ECS side of accel lives here because `RenderState`, which
/// owns the accel scene, is extract's; accel itself never sees the ECS.
pub fn accel_schedule() -> Schedule {
    let mut schedule = Schedule::default();
    schedule.add_systems(update_acceleration);
    schedule
}

/// The transform to show for an entity: `alpha` of the way from the last step to this one.
fn shown(global: &GlobalTransform, previous: &PreviousGlobalTransform, alpha: f32) -> Affine3A {
    if previous.0 == global.0 {
        global.0
    } else {
        interpolate(previous.0, global.0, alpha)
    }
}

/// Zero-scale nodes (a common way to hide things in glTF) are invisible and singular.
fn is_drawable(transform: &Affine3A) -> bool {
    transform.matrix3.determinant().abs() > 1e-12
}

/// The editor's marks on a level entity's root (`edit::mark_entities`): never set by the
/// game, never saved. A hidden entity's meshes are not drawn at all; a locked one's are
/// drawn but the editor's picking rays pass through them.
#[derive(Component, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EditorMark {
    pub hidden: bool,
    pub locked: bool,
}

/// A level entity's root, as extract reads it.
type RootData<'a> = (
    &'a Name,
    Option<&'a AssetInstance>,
    Has<SwitchedOff>,
    Has<Animator>,
    Has<AnimationSource>,
    Has<DeformerSource>,
    Has<PlayerStart>,
    Has<Patrol>,
    Has<PlayerBody>,
    Option<&'a EditorMark>,
);

/// Mesh nodes as extract reads them.
type MeshData<'a> = (
    Entity,
    &'a MeshNode,
    &'a GlobalTransform,
    &'a PreviousGlobalTransform,
);

/// Cameras as extract reads them: name, placement, lens, and whether it is the active one.
type ViewData<'a> = (
    Option<&'a Name>,
    &'a GlobalTransform,
    &'a PreviousGlobalTransform,
    &'a ViewCamera,
    Has<ActiveCamera>,
);

/// A light component changed (added or edited).
type LightChanged = Or<(Changed<PunctualLight>, Changed<AssetLight>)>;

/// Level lights as extract reads them: whose, what, where, and switched off or not.
type PunctualData<'a> = (
    Entity,
    &'a Name,
    &'a PunctualLight,
    &'a GlobalTransform,
    &'a PreviousGlobalTransform,
    Has<SwitchedOff>,
);

/// A lit punctual light found this frame: its content key (root name, asset node), its
/// entity, the light and its placement.
type FoundLight<'a> = ((&'a str, Option<usize>), Entity, LightDef, Affine3A);

/// What, since the last frame, calls for assembling instances or lights anew.
#[derive(bevy_ecs::system::SystemParam)]
pub struct Structure<'w, 's> {
    meshes_added: Query<'w, 's, (), Added<MeshNode>>,
    meshes_removed: RemovedComponents<'w, 's, MeshNode>,
    instances_changed: Query<'w, 's, (), Changed<AssetInstance>>,
    switched: Query<'w, 's, (), Changed<SwitchedOff>>,
    unswitched: RemovedComponents<'w, 's, SwitchedOff>,
    lights_changed: Query<'w, 's, (), LightChanged>,
    punctual_removed: RemovedComponents<'w, 's, PunctualLight>,
    asset_lights_removed: RemovedComponents<'w, 's, AssetLight>,
    marks_changed: Query<'w, 's, (), Changed<EditorMark>>,
    marks_removed: RemovedComponents<'w, 's, EditorMark>,
}

impl Structure<'_, '_> {
    /// (instances must be assembled again, punctual lights must be gathered again).
    fn changes(&mut self) -> (bool, bool) {
        let switched = !self.switched.is_empty() || self.unswitched.read().next().is_some();
        let instances = !self.meshes_added.is_empty()
            || self.meshes_removed.read().next().is_some()
            || !self.instances_changed.is_empty()
            || !self.marks_changed.is_empty()
            || self.marks_removed.read().next().is_some()
            || switched;
        let lights = switched
            || !self.lights_changed.is_empty()
            || self.punctual_removed.read().next().is_some()
            || self.asset_lights_removed.read().next().is_some();
        // Drain every reader, whatever the first answered.
        self.meshes_removed.clear();
        self.marks_removed.clear();
        self.unswitched.clear();
        self.punctual_removed.clear();
        self.asset_lights_removed.clear();
        (instances, lights)
    }
}

/// Extract (see the module doc).
#[allow(clippy::too_many_arguments)]
pub fn extract_scene(
    mut structure: Structure,
    meshes: Query<MeshData>,
    roots: Query<RootData>,
    punctual: Query<PunctualData>,
    asset_lights: Query<(
        Entity,
        &AssetLight,
        &GlobalTransform,
        &PreviousGlobalTransform,
    )>,
    views: Query<ViewData>,
    level: Option<Res<LevelInfo>>,
    clock: Res<SimulationClock>,
    mut state: ResMut<RenderState>,
    mut times: ResMut<StageTimes>,
) {
    let start = std::time::Instant::now();
    profiling::scope!("extract");
    let state = &mut *state;
    state.changes = SceneChanges::default();
    let (instances_changed, punctual_changed) = structure.changes();
    let mut emitters_changed = false;
    if instances_changed {
        emitters_changed = assemble_instances(state, &meshes, &roots, clock.alpha);
    } else {
        move_instances(state, &meshes, clock.alpha);
    }
    let lights_changed = punctual_changed || emitters_changed;
    // The punctual lights, lit ones only, in content order: (root name, asset node).
    let lit = |switched: bool, root: Entity| !switched && !roots.get(root).is_ok_and(|r| r.2);
    if lights_changed {
        let mut found: Vec<FoundLight> = Vec::new();
        for (entity, name, light, global, previous, switched) in &punctual {
            if lit(switched, entity) {
                found.push((
                    (name.as_str(), None),
                    entity,
                    light.0.to_light(name.as_str()),
                    shown(global, previous, clock.alpha),
                ));
            }
        }
        for (entity, light, global, previous) in &asset_lights {
            let Ok(root) = roots.get(light.root) else {
                continue;
            };
            if lit(false, light.root) {
                found.push((
                    (root.0.as_str(), Some(light.node)),
                    entity,
                    light.light.clone(),
                    shown(global, previous, clock.alpha),
                ));
            }
        }
        found.sort_by(|a, b| a.0.cmp(&b.0));
        // Built in `update_acceleration`, once deformed emitters have their shape.
        state.pending_lights = Some(
            found
                .into_iter()
                .map(|(_, entity, light, transform)| (entity, light, transform))
                .collect(),
        );
        state.changes.visible = true;
    } else {
        for &(entity, light) in &state.light_of {
            let transform = punctual
                .get(entity)
                .map(|(_, _, _, g, p, _)| shown(g, p, clock.alpha))
                .or_else(|_| {
                    asset_lights
                        .get(entity)
                        .map(|(_, _, g, p)| shown(g, p, clock.alpha))
                });
            let Ok(transform) = transform else { continue };
            let before = state.scene.lights.lights[light as usize].clone();
            lights::move_punctual_light(&mut state.scene.lights, light, &transform);
            if !same_light(&before, &state.scene.lights.lights[light as usize]) {
                state.changes.visible = true;
            }
        }
    }
    state.scene.sky = level.map_or(Vec3::ZERO, |l| l.environment.sky);
    // The active view, else the first there is.
    let view = views
        .iter()
        .find(|(.., active)| *active)
        .or_else(|| views.iter().next());
    if let Some((name, global, previous, view, _)) = view {
        let placement = CameraPlacement {
            name: name.map_or_else(String::new, |n| n.as_str().to_owned()),
            yfov: view.yfov,
            znear: view.znear,
            world_from_camera: glam::Mat4::from(shown(global, previous, clock.alpha)),
        };
        if placement != state.scene.camera {
            state.scene.camera = placement;
        }
    }
    times.add(Stage::Extract, since(start));
}

fn same_light(a: &crate::render::light::Light, b: &crate::render::light::Light) -> bool {
    use crate::render::light::Light;
    match (a, b) {
        (Light::Point { position: p, .. }, Light::Point { position: q, .. }) => p == q,
        (
            Light::Spot {
                position: p,
                direction: d,
                ..
            },
            Light::Spot {
                position: q,
                direction: e,
                ..
            },
        ) => p == q && d == e,
        (Light::Directional { direction: d, .. }, Light::Directional { direction: e, .. }) => {
            d == e
        }
        _ => false,
    }
}

/// Moves the instances of moved mesh nodes; the TLAS is rebuilt after deformation.
fn move_instances(state: &mut RenderState, meshes: &Query<MeshData>, alpha: f32) {
    for (entity, _, global, previous) in meshes {
        let Some(&index) = state.instance_of.get(&entity) else {
            continue;
        };
        let transform = shown(global, previous, alpha);
        let target = &mut state.scene.accel.instances_mut()[index as usize];
        if target.world_from_object() != transform && is_drawable(&transform) {
            if target.mobility == Mobility::Static {
                state.still_frames = 0;
            }
            target.set_transform(transform);
            state.tlas_stale = true;
            state.moved[index as usize] = true;
        }
    }
}

/// Assembles every instance again in content order (see the module doc). Returns whether
/// the emitters changed (one added, removed, re-materialed or switched): the light set must
/// then be built anew; otherwise its emissive triangles are only renumbered.
fn assemble_instances(
    state: &mut RenderState,
    meshes: &Query<MeshData>,
    roots: &Query<RootData>,
    alpha: f32,
) -> bool {
    profiling::scope!("extract.assemble");
    // The emitters as they were (before any BLAS slot is emptied or reused).
    let emitters_before = emitters(&state.scene, &mut state.blas_materials);
    let old_users: Vec<u64> = state
        .scene
        .accel
        .instances()
        .iter()
        .map(|i| i.user_id)
        .collect();
    // 1. The drawn mesh nodes, in content order.
    struct Entry<'a> {
        key: (&'a str, usize, u64),
        entity: Entity,
        node: &'a MeshNode,
        transform: Affine3A,
        mobility: Mobility,
        instance: Option<&'a AssetInstance>,
        dark: bool,
        mask: InstanceMask,
    }
    let mut entries: Vec<Entry> = Vec::new();
    for (entity, node, global, previous) in meshes {
        let Ok((
            name,
            instance,
            dark,
            animator,
            animation,
            deformer,
            spawn,
            patrol,
            own_body,
            mark,
        )) = roots.get(node.root)
        else {
            continue;
        };
        let mark = mark.copied().unwrap_or_default();
        if mark.hidden {
            continue;
        }
        let transform = shown(global, previous, alpha);
        if !is_drawable(&transform) {
            continue;
        }
        let moves = node.deforms || animator || animation || deformer || spawn || patrol;
        entries.push(Entry {
            key: (name.as_str(), node.node, node.root.to_bits()),
            entity,
            node,
            transform,
            mobility: if moves {
                Mobility::Movable
            } else {
                Mobility::Static
            },
            instance,
            dark,
            // The player's own body: not in their camera's view (the eye is inside it),
            // but in the light's way and in reflections.
            mask: match (own_body, mark.locked) {
                (true, _) => InstanceMask::SHADOW | InstanceMask::BOUNCE,
                (false, true) => InstanceMask(InstanceMask::ALL.0 & !InstanceMask::PICKABLE.0),
                (false, false) => InstanceMask::ALL,
            },
        });
    }
    entries.sort_by(|a, b| a.key.cmp(&b.key));

    // 2. The BLASes: each asset mesh that keeps its shape once, each deforming node its
    //    own; new ones are built in parallel.
    let present: std::collections::HashSet<Entity> = entries.iter().map(|e| e.entity).collect();
    let gone: Vec<Entity> = state
        .node_blases
        .keys()
        .filter(|entity| !present.contains(entity))
        .copied()
        .collect();
    for entity in gone {
        if let Some(slot) = state.node_blases.remove(&entity) {
            state.scene.accel.blases[slot as usize] =
                Blas::build(MeshGeometry::default(), BlasKind::Static);
            state.blas_materials.remove(&slot);
            state.free_blases.push(slot);
        }
        state.deform.forget(entity);
    }
    enum Needed {
        Mesh(AssetKey, usize),
        Node(Entity),
    }
    let mut needed: Vec<(Needed, Arc<Asset>, usize, BlasKind, u32)> = Vec::new();
    let mut queued_meshes = std::collections::HashSet::new();
    for entry in &entries {
        let asset = &entry.node.asset;
        let offset = state.materials.offset(asset);
        if entry.node.deforms {
            if !state.node_blases.contains_key(&entry.entity) {
                needed.push((
                    Needed::Node(entry.entity),
                    Arc::clone(asset),
                    entry.node.mesh,
                    BlasKind::Deforming,
                    offset,
                ));
            }
        } else {
            let key = (AssetKey(Arc::clone(asset)), entry.node.mesh);
            if !state.mesh_blases.contains_key(&key) && queued_meshes.insert(key.clone()) {
                needed.push((
                    Needed::Mesh(key.0, key.1),
                    Arc::clone(asset),
                    entry.node.mesh,
                    BlasKind::Static,
                    offset,
                ));
            }
        }
    }
    let built: Vec<Blas> = needed
        .par_iter()
        .map(|(_, asset, mesh, kind, offset)| {
            Blas::build(mesh_geometry(asset, *mesh, *offset), *kind)
        })
        .collect();
    for ((needed, ..), blas) in needed.into_iter().zip(built) {
        let slot = match state.free_blases.pop() {
            Some(slot) => {
                state.scene.accel.blases[slot as usize] = blas;
                slot
            }
            None => {
                state.scene.accel.blases.push(blas);
                state.scene.accel.blases.len() as u32 - 1
            }
        };
        state.blas_materials.remove(&slot);
        match needed {
            Needed::Mesh(asset, mesh) => {
                state.mesh_blases.insert((asset, mesh), slot);
            }
            Needed::Node(entity) => {
                state.node_blases.insert(entity, slot);
            }
        }
    }

    // 3. Materials: the base tables, then a resolved block per entity that changes its
    //    asset's materials (overrides, or switched off), in content order.
    let mut materials = state.materials.base.clone();
    let mut blocks: HashMap<Entity, u32> = HashMap::new();
    let mut instances = Vec::with_capacity(entries.len());
    let mut shading = Vec::with_capacity(entries.len());
    state.instance_of.clear();
    for entry in &entries {
        let asset = &entry.node.asset;
        let asset_offset = state.materials.offset(asset);
        let changes_materials = entry.dark
            || entry
                .instance
                .is_some_and(|i| !i.material_overrides.is_empty());
        let material_base = if changes_materials {
            *blocks.entry(entry.node.root).or_insert_with(|| {
                let base = materials.len() as u32;
                let empty = Default::default();
                let overrides = entry.instance.map_or(&empty, |i| &i.material_overrides);
                materials.extend(state.materials.resolved_block(asset, overrides, entry.dark));
                base
            })
        } else {
            asset_offset
        };
        shading.push(InstanceShading {
            material_base,
            asset_offset,
        });
        let blas = if entry.node.deforms {
            state.node_blases[&entry.entity]
        } else {
            state.mesh_blases[&(AssetKey(Arc::clone(asset)), entry.node.mesh)]
        };
        state
            .instance_of
            .insert(entry.entity, instances.len() as u32);
        instances.push(
            Instance::new(
                blas,
                entry.transform,
                entry.mask,
                instance_user_id(entry.entity),
            )
            .with_mobility(entry.mobility),
        );
    }
    for entry in entries.iter().filter(|e| e.node.deforms) {
        let blas = state.node_blases[&entry.entity];
        state
            .deform
            .track(entry.entity, &entry.node.asset, entry.node.mesh, blas);
    }

    // 4. Into the scene: accel keeps the batches whose members are all unchanged.
    let scene = &mut state.scene;
    scene.materials = materials;
    scene.textures = state.materials.textures.clone();
    scene.instance_shading = shading;
    scene.default_material = DEFAULT_MATERIAL_INDEX;
    let count = instances.len();
    scene.accel.set_instances(instances);
    if !state.assembled {
        scene.accel.rebatch();
        state.assembled = true;
    }
    state.moved = vec![false; count];
    state.tlas_stale = false;
    state.still_frames = 0;
    let new_index: Vec<Option<u32>> = old_users
        .iter()
        .map(|&user| instance_entity(user).and_then(|e| state.instance_of.get(&e).copied()))
        .collect();
    state.changes.visible = true;

    // 5. The light set: the same emitters keep their entries under their new numbers (and
    //    follow any move); others call for a new set.
    let emitters_after = emitters(&state.scene, &mut state.blas_materials);
    let same_emitters = emitters_before
        .iter()
        .map(|(_, signature)| signature)
        .eq(emitters_after.iter().map(|(_, signature)| signature));
    let rebuild = !same_emitters || !state.assembled_lights;
    if !rebuild {
        state.scene.lights.renumber_instances(&new_index);
        for (index, _) in &emitters_after {
            state.moved[*index as usize] = true;
        }
    }
    state.assembled_lights = true;
    state.changes.renumbered = Some(new_index);
    rebuild
}

/// The emissive materials of one instance, as (triangle material id, emitted radiance
/// bits, double-sided), in id order: what its emitters' power depends on.
type EmitterMaterials = Vec<(u32, [u32; 3], bool, Option<u32>)>;

/// Every instance that emits light, by `user_id`, with its BLAS and emissive materials,
/// sorted by `user_id` (as instance index, signature): equal lists mean the same emitters
/// with the same power. `blas_materials` caches each BLAS's distinct material ids.
fn emitters(
    scene: &RenderScene,
    blas_materials: &mut HashMap<u32, Vec<u32>>,
) -> Vec<(u32, (u64, u32, EmitterMaterials))> {
    let mut found = Vec::new();
    for (index, instance) in scene.accel.instances().iter().enumerate() {
        let ids = blas_materials.entry(instance.blas).or_insert_with(|| {
            let mut ids = scene.accel.blases[instance.blas as usize]
                .geometry
                .materials
                .clone();
            ids.sort_unstable();
            ids.dedup();
            ids
        });
        let emissive: EmitterMaterials = ids
            .iter()
            .filter_map(|&id| {
                let material = scene.material(index as u32, id);
                material.is_emissive().then(|| {
                    (
                        id,
                        material.emissive.to_array().map(f32::to_bits),
                        material.double_sided,
                        material.emissive_texture.map(|t| t.texture),
                    )
                })
            })
            .collect();
        if !emissive.is_empty() {
            found.push((index as u32, (instance.user_id, instance.blas, emissive)));
        }
    }
    found.sort_by_key(|(_, (user, ..))| *user);
    found
}

/// Accel: each BLAS extract deformed is refit in parallel (`Stage::BlasRefit`; or rebuilt,
/// when refitting has let its tree decay); when any instance moved or deformed, the TLAS
/// is rebuilt over the new instance boxes and its emissive triangles follow it (or the
/// light set is built anew, when extract asked for it); static batches re-form once the
/// static instances have kept still for `REBATCH_AFTER_FRAMES` (`Stage::TlasBuild`).
pub fn update_acceleration(
    mut state: ResMut<RenderState>,
    mut stats: ResMut<DeformStats>,
    mut times: ResMut<StageTimes>,
) {
    let state = &mut *state;
    if !state.refit.is_empty() {
        let start = std::time::Instant::now();
        profiling::scope!("blas_refit");
        let mut refit = std::mem::take(&mut state.refit);
        refit.sort_unstable();
        let outcomes: Vec<RefitOutcome> = (state.scene.accel.blases.iter_mut().enumerate())
            .filter(|(index, _)| refit.binary_search(&(*index as u32)).is_ok())
            .collect::<Vec<_>>()
            .into_par_iter()
            .map(|(_, blas)| blas.refit_geometry())
            .collect();
        stats.rebuilds = outcomes
            .iter()
            .filter(|&&o| o == RefitOutcome::Rebuilt)
            .count() as u32;
        stats.refits = outcomes.len() as u32 - stats.rebuilds;
        times.add(Stage::BlasRefit, since(start));
    }
    let start = std::time::Instant::now();
    profiling::scope!("tlas_build");
    if state.tlas_stale {
        state.scene.accel.rebuild_tlas();
        state.tlas_stale = false;
        state.changes.visible = true;
    }
    if let Some(punctual) = state.pending_lights.take() {
        // A new set, weighted by the emitters' current shapes (the same world gives the
        // same weights however it came to be).
        let placed: Vec<(LightDef, Affine3A)> =
            punctual.iter().map(|(_, l, t)| (l.clone(), *t)).collect();
        state.scene.lights = lights::light_set(&state.scene, &placed);
        state.light_set_builds += 1;
        state.changes.relit = true;
        let first = (state.scene.lights.lights.len() - placed.len()) as u32;
        state.light_of = punctual
            .iter()
            .enumerate()
            .map(|(k, (entity, _, _))| (*entity, first + k as u32))
            .collect();
    } else if state.moved.contains(&true) {
        refresh_triangle_lights(&mut state.scene, &state.moved);
    }
    state.moved.fill(false);
    state.still_frames = state.still_frames.saturating_add(1);
    if state.still_frames == REBATCH_AFTER_FRAMES && state.scene.accel.can_rebatch() {
        state.scene.accel.rebatch();
    }
    times.add(Stage::TlasBuild, since(start));
}
