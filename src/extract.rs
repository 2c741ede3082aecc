//! Frame step `extract`: turns scene data into what `accel` (and later `render`) consume.
//!
//! Today this is the headless path used by `gloam raybench`: a loaded `Scene` (a level or a
//! bare glTF) becomes one BLAS per distinct glTF mesh and one instance per placement. The
//! ECS path arrives with the real-time shell and will produce the same structures from
//! entities; both stay in this one module.

use std::collections::HashMap;

use glam::Affine3A;
use rayon::prelude::*;

use crate::accel::{AccelScene, Blas, BlasKind, Instance, InstanceMask, MeshGeometry};
use crate::scene::model::{AlphaMode, Asset};
use crate::scene::world::Scene;

/// Material id for triangles with no material (glTF's default material).
pub const DEFAULT_MATERIAL: u32 = u32::MAX;

/// Where an instance came from, by index parallel to `AccelScene::instances`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct InstanceSource {
    pub entity: usize,
    pub asset: usize,
    pub mesh: usize,
}

/// A static scene ready for ray queries.
pub struct ExtractedScene {
    pub accel: AccelScene,
    pub sources: Vec<InstanceSource>,
}

/// All of a glTF mesh's primitives as one triangle soup; material ids are the asset's
/// material indices (`DEFAULT_MATERIAL` for none).
pub fn mesh_geometry(asset: &Asset, mesh: usize) -> MeshGeometry {
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
        let material = primitive.material.map_or(DEFAULT_MATERIAL, |m| m as u32);
        let alpha_tested = primitive
            .material
            .is_some_and(|m| matches!(asset.materials[m].alpha_mode, AlphaMode::Mask { .. }));
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

/// Builds static BLASes for every mesh the scene places (each distinct mesh once, in
/// parallel) and an instance per placement, visible to every query.
pub fn extract_static(scene: &Scene) -> ExtractedScene {
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

    let mut blas_of: HashMap<(usize, usize), u32> = HashMap::new();
    let mut meshes: Vec<(usize, usize)> = Vec::new();
    for placement in &placements {
        let key = (asset_index(placement.asset), placement.mesh);
        blas_of.entry(key).or_insert_with(|| {
            meshes.push(key);
            meshes.len() as u32 - 1
        });
    }
    let blases: Vec<Blas> = meshes
        .par_iter()
        .map(|&(asset, mesh)| {
            Blas::build(mesh_geometry(&scene.assets[asset], mesh), BlasKind::Static)
        })
        .collect();

    let mut instances = Vec::with_capacity(placements.len());
    let mut sources = Vec::with_capacity(placements.len());
    for placement in &placements {
        let asset = asset_index(placement.asset);
        instances.push(Instance::new(
            blas_of[&(asset, placement.mesh)],
            Affine3A::from_mat4(placement.world_from_mesh),
            InstanceMask::ALL,
            placement.entity as u64,
        ));
        sources.push(InstanceSource {
            entity: placement.entity,
            asset,
            mesh: placement.mesh,
        });
    }
    ExtractedScene {
        accel: AccelScene::new(blases, instances),
        sources,
    }
}
