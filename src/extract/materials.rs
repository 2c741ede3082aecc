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
use crate::scene::model::{Asset, ColorEncoding, Filter, Material, TextureRef, Wrap};

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
            let decoded = decoded_image(asset, gltf_texture.image, reference.encoding);
            textures.push(decoded.with_sampler(sampler.wrap_u, sampler.wrap_v, sampler.magnify));
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

/// Image `image` of `asset` decoded to linear texels with its mip pyramid, once per process
/// while the asset lives: every engine made over the same loaded assets (a level started
/// again, each replay a test or the fuzzer runs, the editor's play-tests) shares the
/// pyramids rather than decoding every image anew, which was over half the time of making
/// one (`perf`, a replay of first-light's first 120 steps). The cache holds a `Weak` to
/// each asset, which keeps its address from being reused, so an entry found by address
/// is that asset's; entries of assets that are gone are dropped as others are added.
fn decoded_image(asset: &Arc<Asset>, image: usize, encoding: ColorEncoding) -> Texture {
    use std::sync::{LazyLock, Mutex, Weak};
    type Key = (usize, usize, bool);
    static DECODED: LazyLock<Mutex<HashMap<Key, (Weak<Asset>, Texture)>>> =
        LazyLock::new(Default::default);
    let key = (
        Arc::as_ptr(asset) as usize,
        image,
        encoding == ColorEncoding::Srgb,
    );
    // A poisoned lock (a panic elsewhere while it was held) still holds whole entries.
    let lock = || {
        DECODED
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    };
    if let Some((_, texture)) = lock().get(&key) {
        return texture.clone();
    }
    // Decoded outside the lock: engines on other threads go on meanwhile.
    let texture = Texture::from_image(
        &asset.images[image],
        encoding,
        Wrap::Repeat,
        Wrap::Repeat,
        Filter::Linear,
    );
    let mut decoded = lock();
    decoded.retain(|_, (owner, _)| owner.strong_count() > 0);
    decoded.insert(key, (Arc::downgrade(asset), texture.clone()));
    texture
}

#[cfg(test)]
mod tests {
    use glam::{Affine2, Vec2, Vec4};

    use super::*;
    use crate::render::material::FINEST;
    use crate::scene::model::{Image, Sampler, Texture as GltfTexture};

    /// An asset of one material whose base colour is a 2 x 2 image of `grey`.
    fn asset_of_grey(grey: u8) -> Arc<Asset> {
        let mut asset = Asset::default();
        asset.images.push(Image {
            name: String::new(),
            width: 2,
            height: 2,
            rgba8: vec![[grey, grey, grey, 255]; 4],
        });
        asset.textures.push(GltfTexture {
            image: 0,
            sampler: Sampler::default(),
        });
        asset.materials.push(Material {
            base_color_texture: Some(TextureRef {
                texture: 0,
                uv_set: 0,
                encoding: ColorEncoding::Srgb,
                uv_transform: Affine2::IDENTITY,
            }),
            ..Material::default()
        });
        Arc::new(asset)
    }

    /// Two tables (two engines) over one loaded asset read one decoded pyramid; a new asset
    /// after the first is gone is decoded from its own image.
    #[test]
    fn tables_over_one_asset_share_its_decoded_images() {
        let white = asset_of_grey(255);
        let (mut first, mut second) = (MaterialTable::new(), MaterialTable::new());
        first.offset(&white);
        second.offset(&white);
        assert!(first.textures[0].shares_pyramid_with(&second.textures[0]));
        assert_eq!(
            first.textures[0].sample(Vec2::splat(0.5), FINEST),
            Vec4::ONE
        );
        drop((first, second, white));
        let black = asset_of_grey(0);
        let mut third = MaterialTable::new();
        third.offset(&black);
        assert_eq!(
            third.textures[0].sample(Vec2::splat(0.5), FINEST),
            Vec4::new(0.0, 0.0, 0.0, 1.0)
        );
    }
}
