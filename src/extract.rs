//! Frame step `extract`: turns scene data into the `RenderScene` that `accel` and `render`
//! consume.
//!
//! At load, a `Scene` (a level or a bare glTF) becomes one BLAS per distinct glTF mesh that
//! keeps its shape (shared by its instances), one refittable BLAS per placement of a mesh
//! that deforms (skinned, morphing, or under a level deformer), one instance per placement,
//! the materials with each entity's level overrides applied, textures decoded to linear
//! values, and the light set (emissive triangles and punctual lights). Placements that
//! nothing moves are marked `Mobility::Static`, and accel merges them into world-space
//! batches. Per frame, the game moves instances and deformed vertices in place and calls
//! `refresh_triangle_lights` so emitters follow them. `gloam render`, `raybench` and the
//! game all start here.

use std::collections::HashMap;

use glam::{Affine3A, Vec3, Vec3A};
use rayon::prelude::*;

use crate::accel::{AccelScene, Blas, BlasKind, Instance, InstanceMask, MeshGeometry, Mobility};
use crate::render::light::{Light, LightSet, luminance};
use crate::render::material::{RenderMaterial, Texture, TextureSlot};
use crate::render::scene::{DEFAULT_MATERIAL, InstanceShading, RenderScene};
use crate::scene::model::{AlphaMode, Asset, LightKind, Material, TextureRef};
use crate::scene::world::{CameraPlacement, MeshPlacement, Scene};

/// The accel `user_id` of the instance drawing asset node `node` of level entity `entity`:
/// the game finds its ECS entity's instance by it.
pub fn instance_user_id(entity: usize, node: usize) -> u64 {
    ((entity as u64) << 32) | node as u64
}

/// `Static` for a placement nothing in the level moves: its entity plays no animation, has
/// no deformer and is not the player, and its mesh keeps its shape. Accel batches those.
fn placement_mobility(scene: &Scene, placement: &MeshPlacement) -> Mobility {
    let entity = &scene.level.entities[placement.entity];
    let moves = placement.deforms
        || entity.animation.is_some()
        || entity.deformer.is_some()
        || entity.player_spawn.is_some();
    if moves {
        Mobility::Movable
    } else {
        Mobility::Static
    }
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

/// Textures decoded once per (asset, glTF texture, colour encoding) actually used.
struct TextureTable<'a> {
    scene: &'a Scene,
    index: HashMap<(usize, usize, bool), u32>,
    textures: Vec<Texture>,
}

impl TextureTable<'_> {
    fn slot(&mut self, asset: usize, reference: &Option<TextureRef>) -> Option<TextureSlot> {
        let reference = reference.as_ref()?;
        let key = (
            asset,
            reference.texture,
            reference.encoding == crate::scene::model::ColorEncoding::Srgb,
        );
        let texture = *self.index.entry(key).or_insert_with(|| {
            let source = &self.scene.assets[asset];
            let gltf_texture = &source.textures[reference.texture];
            let sampler = gltf_texture.sampler;
            self.textures.push(Texture::from_image(
                &source.images[gltf_texture.image],
                reference.encoding,
                sampler.wrap_u,
                sampler.wrap_v,
                sampler.magnify,
            ));
            self.textures.len() as u32 - 1
        });
        Some(TextureSlot {
            texture,
            uv_transform: reference.uv_transform,
        })
    }

    fn material(&mut self, asset: usize, material: &Material) -> RenderMaterial {
        RenderMaterial {
            base_color: material.base_color,
            base_color_texture: self.slot(asset, &material.base_color_texture),
            metallic: material.metallic,
            roughness: material.roughness,
            metallic_roughness_texture: self.slot(asset, &material.metallic_roughness_texture),
            emissive: material.emissive,
            emissive_texture: self.slot(asset, &material.emissive_texture),
            transmission: material.transmission,
            ior: material.ior,
            alpha_mode: material.alpha_mode,
            double_sided: material.double_sided,
        }
    }
}

/// Builds everything `render` reads from a loaded scene: BLASes for every placed mesh (each
/// distinct mesh once, in parallel), instances, materials, textures, lights and the camera.
pub fn render_scene(scene: &Scene) -> RenderScene {
    // Zero-scale nodes (a common way to hide things in glTF) are invisible and singular.
    let placements: Vec<_> = scene
        .mesh_placements()
        .into_iter()
        .filter(|p| p.world_from_mesh.determinant().abs() > 1e-12)
        .collect();
    let asset_index = |asset: &Asset| {
        scene
            .assets
            .iter()
            .position(|a| std::ptr::eq(a, asset))
            .unwrap_or(0)
    };

    // 1. Materials: every asset's table under a global offset, then the default material.
    let mut textures = TextureTable {
        scene,
        index: HashMap::new(),
        textures: Vec::new(),
    };
    let mut materials = Vec::new();
    let mut asset_offsets = Vec::with_capacity(scene.assets.len());
    for (index, asset) in scene.assets.iter().enumerate() {
        asset_offsets.push(materials.len() as u32);
        for material in &asset.materials {
            materials.push(textures.material(index, material));
        }
    }

    // 2. One BLAS per distinct (asset, mesh) that keeps its shape; each deforming placement
    //    gets its own, refit as it moves.
    let mut blas_of: HashMap<(usize, usize, Option<usize>), u32> = HashMap::new();
    let mut meshes: Vec<(usize, usize, BlasKind)> = Vec::new();
    let blas_key = |index: usize, placement: &MeshPlacement| {
        (
            asset_index(placement.asset),
            placement.mesh,
            placement.deforms.then_some(index),
        )
    };
    for (index, placement) in placements.iter().enumerate() {
        let key = blas_key(index, placement);
        blas_of.entry(key).or_insert_with(|| {
            let kind = if placement.deforms {
                BlasKind::Deforming
            } else {
                BlasKind::Static
            };
            meshes.push((key.0, key.1, kind));
            meshes.len() as u32 - 1
        });
    }
    let blases: Vec<Blas> = meshes
        .par_iter()
        .map(|&(asset, mesh, kind)| {
            Blas::build(
                mesh_geometry(&scene.assets[asset], mesh, asset_offsets[asset]),
                kind,
            )
        })
        .collect();

    // 3. Instances, with a resolved material block for entities that override materials.
    let mut override_blocks: HashMap<(usize, usize), u32> = HashMap::new();
    let mut instances = Vec::with_capacity(placements.len());
    let mut instance_shading = Vec::with_capacity(placements.len());
    for (index, placement) in placements.iter().enumerate() {
        let asset = asset_index(placement.asset);
        let overrides = scene.level.entities[placement.entity]
            .instance
            .as_ref()
            .is_some_and(|i| !i.material_overrides.is_empty());
        let material_base = if overrides {
            *override_blocks
                .entry((placement.entity, asset))
                .or_insert_with(|| {
                    let base = materials.len() as u32;
                    for local in 0..scene.assets[asset].materials.len() {
                        let resolved = scene.resolved_material(
                            placement.entity,
                            &scene.assets[asset],
                            Some(local),
                        );
                        materials.push(textures.material(asset, &resolved));
                    }
                    base
                })
        } else {
            asset_offsets[asset]
        };
        instance_shading.push(InstanceShading {
            material_base,
            asset_offset: asset_offsets[asset],
        });
        instances.push(
            Instance::new(
                blas_of[&blas_key(index, placement)],
                Affine3A::from_mat4(placement.world_from_mesh),
                InstanceMask::ALL,
                instance_user_id(placement.entity, placement.node),
            )
            .with_mobility(placement_mobility(scene, placement)),
        );
    }
    let default_material = materials.len() as u32;
    materials.push(textures.material(0, &Material::default()));
    let accel = AccelScene::new(blases, instances);

    let mut render = RenderScene {
        accel,
        materials,
        instance_shading,
        default_material,
        textures: textures.textures,
        lights: LightSet::default(),
        sky: scene.level.environment.sky,
        camera: CameraPlacement::framing(Vec3::ZERO, Vec3::ONE),
    };
    let bounds = render.accel.bounds();
    render.camera = scene
        .camera()
        .unwrap_or_else(|| CameraPlacement::framing(bounds.min.into(), bounds.max.into()));
    render.lights = light_set(scene, &render, (bounds.max - bounds.min).length() * 0.5);
    render
}

/// An emissive triangle's front normal and area. The front side is the one the winding faces
/// in object space; a mirroring transform flips the world-space winding, so the normal is
/// flipped back.
fn emitter_frame(vertices: &[Vec3A; 3], mirrored: bool) -> (Vec3A, f32) {
    let cross = (vertices[1] - vertices[0]).cross(vertices[2] - vertices[0]);
    let area = cross.length() * 0.5;
    if area <= 0.0 {
        return (Vec3A::Y, 0.0);
    }
    let normal = cross / (2.0 * area);
    (if mirrored { -normal } else { normal }, area)
}

/// Moves the emissive triangles of the instances flagged in `moved` (by instance index) to
/// where their instance's transform and BLAS vertices now put them. Selection weights stay
/// as built: light picking remains unbiased, only less well matched to power.
pub fn refresh_triangle_lights(render: &mut RenderScene, moved: &[bool]) {
    let RenderScene { accel, lights, .. } = render;
    for ((instance_index, triangle), light) in lights.triangle_lights() {
        if !moved.get(instance_index as usize).copied().unwrap_or(false) {
            continue;
        }
        let instance = &accel.instances()[instance_index as usize];
        let to_world = instance.world_from_object();
        let mirrored = to_world.matrix3.determinant() < 0.0;
        let new_vertices = accel.blases[instance.blas as usize]
            .geometry
            .triangle_vertices(triangle as usize)
            .map(|v| to_world.transform_point3a(v));
        if let Light::Triangle {
            vertices,
            normal,
            area,
            ..
        } = &mut lights.lights[light as usize]
        {
            *vertices = new_vertices;
            (*normal, *area) = emitter_frame(&new_vertices, mirrored);
        }
    }
}

/// Emissive triangles (in world space) and punctual lights, weighted by estimated power.
fn light_set(scene: &Scene, render: &RenderScene, scene_radius: f32) -> LightSet {
    let mut lights = Vec::new();
    let mut weights = Vec::new();
    let mut keys = Vec::new();
    for (instance_index, instance) in render.accel.instances().iter().enumerate() {
        let geometry = &render.accel.blases[instance.blas as usize].geometry;
        let to_world = instance.world_from_object();
        let mirrored = to_world.matrix3.determinant() < 0.0;
        for (triangle, &id) in geometry.materials.iter().enumerate() {
            let material_index = render.material_index(instance_index as u32, id);
            let material = &render.materials[material_index as usize];
            if !material.is_emissive() {
                continue;
            }
            let vertices = geometry
                .triangle_vertices(triangle)
                .map(|v| to_world.transform_point3a(v));
            let (normal, area) = emitter_frame(&vertices, mirrored);
            // Degenerate emitters are kept only on meshes that deform (they may open up).
            let deforming = render.accel.blases[instance.blas as usize].kind
                == crate::accel::BlasKind::Deforming;
            if area <= 0.0 && !deforming {
                continue;
            }
            let uvs = if geometry.uvs.is_empty() {
                [glam::Vec2::ZERO; 3]
            } else {
                geometry.triangles[triangle].map(|i| geometry.uvs[i as usize])
            };
            let sides = if material.double_sided { 2.0 } else { 1.0 };
            keys.push((
                (instance_index as u32, triangle as u32),
                lights.len() as u32,
            ));
            weights.push(luminance(material.emissive) * area * std::f32::consts::PI * sides);
            lights.push(Light::Triangle {
                vertices,
                uvs,
                normal,
                area,
                material: material_index,
                double_sided: material.double_sided,
            });
        }
    }
    for (light, transform) in scene.punctual_lights() {
        let position = Vec3A::from(transform.w_axis.truncate());
        let direction =
            Vec3A::from(transform.transform_vector3(Vec3::NEG_Z)).normalize_or(Vec3A::NEG_Y);
        let intensity = light.color * light.intensity;
        let (light, power) = match light.kind {
            LightKind::Point => (
                Light::Point {
                    position,
                    intensity,
                },
                4.0 * std::f32::consts::PI * luminance(intensity),
            ),
            LightKind::Spot {
                inner_cone_angle,
                outer_cone_angle,
            } => {
                let (cos_inner, cos_outer) = (inner_cone_angle.cos(), outer_cone_angle.cos());
                let solid_angle = std::f32::consts::TAU * (1.0 - 0.5 * (cos_inner + cos_outer));
                (
                    Light::Spot {
                        position,
                        direction,
                        intensity,
                        cos_inner,
                        cos_outer,
                    },
                    solid_angle * luminance(intensity),
                )
            }
            LightKind::Directional => (
                Light::Directional {
                    direction,
                    irradiance: intensity,
                },
                std::f32::consts::PI * scene_radius * scene_radius * luminance(intensity),
            ),
        };
        weights.push(power);
        lights.push(light);
    }
    LightSet::new(lights, &weights, keys)
}
