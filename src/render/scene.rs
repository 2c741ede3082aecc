//! Frame step `render`: `RenderScene`, everything the integrators read for one frame.
//! Built by `extract`; render only reads it.

use glam::{Vec2, Vec3};

use super::light::LightSet;
use super::material::{RenderMaterial, Texture};
use crate::accel::{AccelScene, AlphaTest};
use crate::scene::world::CameraPlacement;

/// Material id carried by triangles that name no material (glTF's default material).
pub const DEFAULT_MATERIAL: u32 = u32::MAX;

/// How an instance's triangle material ids map into `RenderScene::materials`.
///
/// Triangle ids are the asset's materials numbered globally (`asset_offset` + the asset's
/// own index), which is what the alpha test reads; an instance whose level entity overrides
/// materials points `material_base` at its own resolved copy of the asset's table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct InstanceShading {
    pub material_base: u32,
    pub asset_offset: u32,
}

/// What changed in a `RenderScene` since the frame before (extract says; the film reads).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SceneChanges {
    /// Anything visible changed (moved, deformed, spawned, despawned, relit): an
    /// accumulated image must start again.
    pub visible: bool,
    /// The instances were numbered anew (things spawned or despawned): each earlier
    /// instance's new index, None for one that is gone. A history keyed by instance
    /// follows its surfaces through this.
    pub renumbered: Option<Vec<Option<u32>>>,
    /// The light set was built anew (a lamp lit or doused, a light spawned or despawned):
    /// light learnt from the old set is stale.
    pub relit: bool,
}

pub struct RenderScene {
    pub accel: AccelScene,
    /// The assets' materials (by global id), then per-entity override copies, then the
    /// default material.
    pub materials: Vec<RenderMaterial>,
    /// One per accel instance.
    pub instance_shading: Vec<InstanceShading>,
    pub default_material: u32,
    pub textures: Vec<Texture>,
    pub lights: LightSet,
    /// Radiance of rays that leave the scene.
    pub sky: Vec3,
    pub camera: CameraPlacement,
}

impl RenderScene {
    /// Index into `materials` of triangle material `id` on `instance`.
    #[inline]
    pub fn material_index(&self, instance: u32, id: u32) -> u32 {
        if id == DEFAULT_MATERIAL {
            return self.default_material;
        }
        let shading = self.instance_shading[instance as usize];
        shading.material_base + (id - shading.asset_offset)
    }

    #[inline]
    pub fn material(&self, instance: u32, id: u32) -> &RenderMaterial {
        &self.materials[self.material_index(instance, id) as usize]
    }

    /// The alpha test accel calls for alpha-masked triangles.
    pub fn alpha(&self) -> SceneAlpha<'_> {
        SceneAlpha(self)
    }
}

/// Alpha masks as authored in the assets (level overrides do not change coverage).
pub struct SceneAlpha<'a>(&'a RenderScene);

impl AlphaTest for SceneAlpha<'_> {
    fn is_opaque(&self, material: u32, uv: Vec2) -> bool {
        let scene = self.0;
        let index = if material == DEFAULT_MATERIAL {
            scene.default_material
        } else {
            material
        };
        scene.materials[index as usize].is_opaque_at(&scene.textures, uv)
    }
}
