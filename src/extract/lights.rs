//! Extract: the light set next event estimation samples. Emissive triangles (in world
//! space, in instance order) then punctual lights (in content order, as extract sorts
//! them), each weighted by its estimated power. Rebuilt only when a light or emitter is
//! added, removed, switched or changes power; moving ones are updated in place (their
//! selection weights stay as built: light picking remains unbiased, only less well
//! matched to power).

use glam::{Affine3A, Vec3, Vec3A};

use crate::accel::BlasKind;
use crate::render::light::{Light, LightSet, luminance};
use crate::render::scene::RenderScene;
use crate::scene::model::{Light as LightDef, LightKind};

/// An emissive triangle's front normal and area. The front side is the one the winding faces
/// in object space; a mirroring transform flips the world-space winding, so the normal is
/// flipped back.
pub(super) fn emitter_frame(vertices: &[Vec3A; 3], mirrored: bool) -> (Vec3A, f32) {
    let cross = (vertices[1] - vertices[0]).cross(vertices[2] - vertices[0]);
    let area = cross.length() * 0.5;
    if area <= 0.0 {
        return (Vec3A::Y, 0.0);
    }
    let normal = cross / (2.0 * area);
    (if mirrored { -normal } else { normal }, area)
}

/// Moves the emissive triangles of the instances flagged in `moved` (by instance index) to
/// where their instance's transform and BLAS vertices now put them.
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

/// A punctual light's position and direction (down -Z) under `world_from_light`.
fn placement(world_from_light: &Affine3A) -> (Vec3A, Vec3A) {
    let position = world_from_light.translation;
    let direction = world_from_light
        .transform_vector3a(Vec3A::NEG_Z)
        .normalize_or(Vec3A::NEG_Y);
    (position, direction)
}

/// Moves punctual light `light` of the set to `world_from_light` (no new weights).
pub fn move_punctual_light(lights: &mut LightSet, light: u32, world_from_light: &Affine3A) {
    let (new_position, new_direction) = placement(world_from_light);
    match &mut lights.lights[light as usize] {
        Light::Point { position, .. } => *position = new_position,
        Light::Spot {
            position,
            direction,
            ..
        } => {
            *position = new_position;
            *direction = new_direction;
        }
        Light::Directional { direction, .. } => *direction = new_direction,
        Light::Triangle { .. } => {}
    }
}

/// Every emitter of the scene's instances, then `punctual` (lit lights in content order with
/// their world transforms), weighted by estimated power. Returns the set; punctual light
/// `k` is entry `first_punctual + k` (`first_punctual` = the set's length minus
/// `punctual.len()`).
pub fn light_set(render: &RenderScene, punctual: &[(LightDef, Affine3A)]) -> LightSet {
    let bounds = render.accel.bounds();
    let scene_radius = (bounds.max - bounds.min).length() * 0.5;
    let mut lights = Vec::new();
    let mut weights = Vec::new();
    let mut keys = Vec::new();
    for (instance_index, instance) in render.accel.instances().iter().enumerate() {
        let blas = &render.accel.blases[instance.blas as usize];
        let geometry = &blas.geometry;
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
            if area <= 0.0 && blas.kind != BlasKind::Deforming {
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
    for (light, world_from_light) in punctual {
        let (light, power) = punctual_light(light, world_from_light, scene_radius);
        weights.push(power);
        lights.push(light);
    }
    LightSet::new(lights, &weights, keys)
}

/// A punctual light placed by `world_from_light`, as the renderer's `Light`, with its
/// estimated power (directional lights: over a disc of `scene_radius`).
pub fn punctual_light(
    light: &LightDef,
    world_from_light: &Affine3A,
    scene_radius: f32,
) -> (Light, f32) {
    let (position, direction) = placement(world_from_light);
    let intensity: Vec3 = light.color * light.intensity;
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
    (light, power)
}
