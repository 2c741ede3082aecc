//! Extract: the material table. Each asset's materials enter once, under an offset that
//! never changes afterwards (its meshes' BLASes carry triangle material ids as that offset
//! plus the asset's own index, which is what the alpha test reads); each texture is decoded
//! once per colour encoding. Entities whose level overrides change materials, or that are
//! switched off (no emission), get their own resolved copy of their asset's table, rebuilt
//! whenever the instances are.

use std::collections::HashMap;
use std::sync::Arc;

use glam::Vec3;

use crate::render::material::{RenderMaterial, Texture, TextureSlot};
use crate::scene::AssetKey;
use crate::scene::level::MaterialOverride;
use crate::scene::model::{Asset, ColorEncoding, Material, TextureRef};

/// The materials and textures the render scene reads, as extract grows and rebuilds them.
#[derive(Default)]
pub struct MaterialTable {
    /// Base tables (the default material first, then each asset's materials at its
    /// offset); per-entity override blocks follow them in `RenderScene::materials`.
    pub base: Vec<RenderMaterial>,
    /// Each asset's offset into `base`, by its file.
    offsets: HashMap<AssetKey, u32>,
    /// Textures decoded so far, by (asset file, glTF texture, sRGB).
    texture_index: HashMap<(AssetKey, usize, bool), u32>,
    pub textures: Vec<Texture>,
}

/// Index of the default material (glTF's, for primitives that name none) in every table.
pub const DEFAULT_MATERIAL_INDEX: u32 = 0;

impl MaterialTable {
    pub fn new() -> MaterialTable {
        let mut table = MaterialTable::default();
        let default = table.material(&Arc::new(Asset::default()), &Material::default());
        table.base.push(default);
        table
    }

    /// The offset of `asset`'s materials, adding them on first use.
    pub fn offset(&mut self, asset: &Arc<Asset>) -> u32 {
        let key = AssetKey(Arc::clone(asset));
        if let Some(&offset) = self.offsets.get(&key) {
            return offset;
        }
        let offset = self.base.len() as u32;
        for material in &asset.materials {
            let converted = self.material(asset, material);
            self.base.push(converted);
        }
        self.offsets.insert(key, offset);
        offset
    }

    /// `asset`'s whole table with `overrides` applied (and no emission when `dark`).
    pub fn resolved_block(
        &mut self,
        asset: &Arc<Asset>,
        overrides: &std::collections::BTreeMap<String, MaterialOverride>,
        dark: bool,
    ) -> Vec<RenderMaterial> {
        asset
            .materials
            .iter()
            .map(|base| {
                let mut material = match overrides.get(&base.name) {
                    Some(change) => change.apply(base),
                    None => base.clone(),
                };
                if dark {
                    material.emissive = Vec3::ZERO;
                    material.emissive_texture = None;
                }
                self.material(asset, &material)
            })
            .collect()
    }

    fn slot(&mut self, asset: &Arc<Asset>, reference: &Option<TextureRef>) -> Option<TextureSlot> {
        let reference = reference.as_ref()?;
        let key = (
            AssetKey(Arc::clone(asset)),
            reference.texture,
            reference.encoding == ColorEncoding::Srgb,
        );
        let textures = &mut self.textures;
        let texture = *self.texture_index.entry(key).or_insert_with(|| {
            let gltf_texture = &asset.textures[reference.texture];
            let sampler = gltf_texture.sampler;
            textures.push(Texture::from_image(
                &asset.images[gltf_texture.image],
                reference.encoding,
                sampler.wrap_u,
                sampler.wrap_v,
                sampler.magnify,
            ));
            textures.len() as u32 - 1
        });
        Some(TextureSlot {
            texture,
            uv_transform: reference.uv_transform,
        })
    }

    fn material(&mut self, asset: &Arc<Asset>, material: &Material) -> RenderMaterial {
        let mut made = RenderMaterial {
            base_color: material.base_color,
            base_color_texture: self.slot(asset, &material.base_color_texture),
            metallic: material.metallic,
            roughness: material.roughness,
            metallic_roughness_texture: self.slot(asset, &material.metallic_roughness_texture),
            normal_texture: self.slot(asset, &material.normal_texture),
            normal_scale: material.normal_scale,
            emissive: material.emissive,
            emissive_texture: self.slot(asset, &material.emissive_texture),
            transmission: material.transmission,
            ior: material.ior,
            alpha_mode: material.alpha_mode,
            double_sided: material.double_sided,
            paired_tap: false,
        };
        made.paired_tap = made.pairs_taps(&self.textures);
        made
    }
}
