//! One scene model for levels and bare glTF files: the level description plus every asset it
//! instances, loaded and cross-checked. Load time; the game spawns ECS entities from a
//! `Scene`, and headless tools (render, raybench, check) read it directly.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{Mat4, Vec3};
use rayon::prelude::*;

use super::diagnostic::{Diagnostic, LoadError, Pointer};
use super::gltf_import::import_gltf;
use super::level::{
    AnimationDef, EntityDef, Environment, InstanceDef, LEVEL_VERSION, Level, Playback, load_level,
};
use super::model::{Asset, Camera, Light, Material, Projection};

/// A loaded level (or a glTF file seen as a one-entity level) with its assets.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The file the scene was loaded from.
    pub source: PathBuf,
    pub level: Level,
    /// Every distinct asset the level instances, in first-use order.
    pub assets: Vec<Arc<Asset>>,
    /// For each level entity, the index into `assets` of what it instances.
    pub entity_assets: Vec<Option<usize>>,
}

/// A mesh placed in the world, with its materials resolved (overrides applied).
#[derive(Clone, Debug)]
pub struct MeshPlacement<'a> {
    pub entity: usize,
    pub asset: &'a Asset,
    /// The asset node that carries the mesh.
    pub node: usize,
    pub mesh: usize,
    /// Where the mesh's vertices go in the world. For a skinned mesh this is the entity's
    /// transform: glTF places skinned vertices by their joints and ignores the mesh node's
    /// own transform.
    pub world_from_mesh: Mat4,
    /// The mesh changes shape at run time (skinned, morph targets, or a level deformer):
    /// it gets its own refittable BLAS instead of sharing one.
    pub deforms: bool,
}

/// A camera placed in the world.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraPlacement {
    pub name: String,
    /// Vertical field of view in radians.
    pub yfov: f32,
    pub znear: f32,
    /// World-from-camera; the camera looks down its local -Z.
    pub world_from_camera: Mat4,
}

impl CameraPlacement {
    /// A view down -Z that frames the box [min, max] (for scenes with no camera): 60 degrees
    /// vertical field of view, backed off until the bounding sphere fits.
    pub fn framing(min: Vec3, max: Vec3) -> CameraPlacement {
        let yfov = 60f32.to_radians();
        let centre = (min + max) * 0.5;
        let radius = ((max - min).length() * 0.5).max(1e-3);
        let distance = radius / (yfov * 0.5).sin();
        CameraPlacement {
            name: "framing".to_owned(),
            yfov,
            znear: (distance - radius).max(1e-3) * 0.5,
            world_from_camera: Mat4::from_translation(centre + Vec3::Z * distance),
        }
    }
}

impl Scene {
    /// Loads a level (.ron) or a glTF file (.gltf, .glb) and every asset it needs.
    pub fn load(path: &Path) -> Result<Scene, LoadError> {
        match path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .as_deref()
        {
            Some("ron") => Self::load_level(path),
            Some("gltf" | "glb") => Self::from_asset(import_gltf(path)?),
            _ => Err(
                Diagnostic::whole_file(path, "not a level (.ron) or glTF file (.gltf, .glb)")
                    .into(),
            ),
        }
    }

    /// A bare glTF seen as a level: one showcase entity instancing it at the origin.
    pub fn from_asset(asset: Asset) -> Result<Scene, LoadError> {
        let file_name = asset
            .source
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let stem = asset
            .source
            .file_stem()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let mut entity = EntityDef::named(stem.clone());
        entity.instance = Some(InstanceDef {
            asset: file_name,
            material_overrides: BTreeMap::new(),
        });
        // A bare animated file shows its first clip, looping.
        entity.animation = (!asset.animations.is_empty()).then(|| AnimationDef {
            clip: asset.animation_label(0),
            playback: Playback::Loop,
            speed: 1.0,
            start: 0.0,
        });
        let level = Level {
            version: LEVEL_VERSION,
            name: stem,
            playable: false,
            campaign: None,
            environment: Environment {
                // A file with no light of its own would render black: show it under a
                // uniform white sky instead.
                sky: if asset.lights.is_empty()
                    && asset.materials.iter().all(|m| m.emissive == Vec3::ZERO)
                {
                    Vec3::ONE
                } else {
                    Vec3::ZERO
                },
                ambience: None,
            },
            entities: vec![entity],
        };
        Ok(Scene {
            source: asset.source.clone(),
            level,
            assets: vec![Arc::new(asset)],
            entity_assets: vec![Some(0)],
        })
    }

    fn load_level(path: &Path) -> Result<Scene, LoadError> {
        Self::from_level(load_level(path)?, path)
    }

    /// A level already in memory (the editor's, unsaved edits and all) as if loaded from
    /// `path`: its assets are named relative to `path`'s folder and imported.
    pub fn from_level(level: Level, path: &Path) -> Result<Scene, LoadError> {
        Self::from_level_importing(level, path, &|file| import_gltf(file).map(Arc::new))
    }

    /// `from_level`, with each asset file imported by `import` (the fuzz targets' memo:
    /// their assets stay the same from one input to the next).
    pub fn from_level_importing(
        level: Level,
        path: &Path,
        import: &(dyn Fn(&Path) -> Result<Arc<Asset>, LoadError> + Sync),
    ) -> Result<Scene, LoadError> {
        // Positions for cross-file problems need the text again (only read on error).
        let text = || std::fs::read_to_string(path).unwrap_or_default();
        let base = path.parent().unwrap_or(Path::new("."));

        // Distinct asset files, in first-use order.
        let mut files: Vec<PathBuf> = Vec::new();
        // Where each file is first named (the place its load problems point to).
        let mut named_at: Vec<Pointer> = Vec::new();
        let mut entity_assets = Vec::with_capacity(level.entities.len());
        let mut use_file = |asset: &str, at: Pointer| {
            let file = base.join(asset);
            files.iter().position(|f| *f == file).unwrap_or_else(|| {
                files.push(file);
                named_at.push(at);
                files.len() - 1
            })
        };
        let mut body_assets = Vec::new();
        for (index, entity) in level.entities.iter().enumerate() {
            let at = Pointer::root().key("entities").index(index);
            entity_assets.push(
                entity
                    .instance
                    .as_ref()
                    .map(|instance| use_file(&instance.asset, at.key("instance").key("asset"))),
            );
            if let Some(body) = entity.player_spawn.as_ref().and_then(|s| s.body.as_ref()) {
                let at = at.key("player_spawn").key("body");
                body_assets.push((index, use_file(&body.asset, at.key("asset"))));
            }
        }
        // Assets import independently; rayon spreads them over the cores.
        let imported: Vec<Result<Arc<Asset>, LoadError>> =
            files.par_iter().map(|file| import(file)).collect();

        let mut diagnostics = Vec::new();
        let mut assets = Vec::new();
        for (asset_index, result) in imported.into_iter().enumerate() {
            match result {
                Ok(asset) => assets.push(asset),
                Err(error) => {
                    let pointer = named_at[asset_index].clone();
                    let file = &files[asset_index];
                    let message = if file.exists() {
                        format!(
                            "asset '{}' failed to load (problems follow)",
                            file.display()
                        )
                    } else {
                        format!("missing asset '{}' (no such file)", file.display())
                    };
                    diagnostics.push(Diagnostic::at_pointer(path, &text(), &pointer, message));
                    if file.exists() {
                        diagnostics.extend(error.diagnostics);
                    }
                }
            }
        }
        // Sound files are read when they play: here they need only be there.
        let ambience = level.environment.ambience.as_ref().map(|ambience| {
            let at = Pointer::root().key("environment").key("ambience");
            (at, &ambience.asset)
        });
        let sounds = level
            .entities
            .iter()
            .enumerate()
            .filter_map(|(index, entity)| {
                let at = Pointer::root().key("entities").index(index).key("sound");
                Some((at, &entity.sound.as_ref()?.asset))
            });
        for (at, asset) in ambience.into_iter().chain(sounds) {
            let file = base.join(asset);
            if !file.is_file() {
                diagnostics.push(Diagnostic::at_pointer(
                    path,
                    &text(),
                    &at.key("asset"),
                    format!("missing sound '{}' (no such file)", file.display()),
                ));
            }
        }
        if !diagnostics.is_empty() {
            return Err(LoadError { diagnostics });
        }

        // Material overrides must name materials the asset has.
        let instances = level
            .entities
            .iter()
            .enumerate()
            .filter_map(|(index, entity)| {
                let at = Pointer::root().key("entities").index(index).key("instance");
                Some((at, entity.instance.as_ref()?, entity_assets[index]?))
            });
        let bodies = body_assets.iter().filter_map(|&(index, asset)| {
            let spawn = level.entities[index].player_spawn.as_ref()?;
            let at = Pointer::root()
                .key("entities")
                .index(index)
                .key("player_spawn")
                .key("body");
            Some((at, spawn.body.as_ref()?, asset))
        });
        for (at, instance, asset) in instances.chain(bodies) {
            for name in instance.material_overrides.keys() {
                if assets[asset].material_by_name(name).is_none() {
                    let known: Vec<&str> = assets[asset]
                        .materials
                        .iter()
                        .map(|m| m.name.as_str())
                        .collect();
                    let pointer = at.key("material_overrides").key(name);
                    diagnostics.push(Diagnostic::at_pointer(
                        path,
                        &text(),
                        &pointer,
                        format!(
                            "asset '{}' has no material '{name}' (it has: {})",
                            instance.asset,
                            known.join(", ")
                        ),
                    ));
                }
            }
        }
        // Animation clips must be ones the asset has.
        for (index, entity) in level.entities.iter().enumerate() {
            let (Some(animation), Some(asset)) = (&entity.animation, entity_assets[index]) else {
                continue;
            };
            if assets[asset].animation_by_name(&animation.clip).is_none() {
                let known: Vec<String> = (0..assets[asset].animations.len())
                    .map(|i| format!("'{}'", assets[asset].animation_label(i)))
                    .collect();
                let pointer = Pointer::root()
                    .key("entities")
                    .index(index)
                    .key("animation")
                    .key("clip");
                let has = if known.is_empty() {
                    "it has no animations".to_owned()
                } else {
                    format!("it has: {}", known.join(", "))
                };
                diagnostics.push(Diagnostic::at_pointer(
                    path,
                    &text(),
                    &pointer,
                    format!(
                        "asset '{}' has no animation clip '{}' ({has})",
                        entity.instance.as_ref().map_or("", |i| i.asset.as_str()),
                        animation.clip
                    ),
                ));
            }
        }
        if !diagnostics.is_empty() {
            return Err(LoadError { diagnostics });
        }
        Ok(Scene {
            source: path.to_owned(),
            level,
            assets,
            entity_assets,
        })
    }

    /// Every mesh in the world: each instance entity's asset hierarchy under its transform.
    pub fn mesh_placements(&self) -> Vec<MeshPlacement<'_>> {
        let mut placements = Vec::new();
        for (entity_index, entity) in self.level.entities.iter().enumerate() {
            let Some(asset_index) = self.entity_assets[entity_index] else {
                continue;
            };
            let asset: &Asset = &self.assets[asset_index];
            let entity_world = entity.transform.matrix();
            asset.visit_nodes(entity_world, |node, world| {
                if let Some(mesh) = asset.nodes[node].mesh {
                    let skinned = asset.nodes[node].skin.is_some();
                    let morphs = asset.meshes[mesh]
                        .primitives
                        .iter()
                        .any(|p| !p.morph_targets.is_empty());
                    placements.push(MeshPlacement {
                        entity: entity_index,
                        asset,
                        node,
                        mesh,
                        world_from_mesh: if skinned { entity_world } else { world },
                        deforms: skinned || morphs || entity.deformer.is_some(),
                    });
                }
            });
        }
        placements
    }

    /// The material a placed primitive uses, with the entity's overrides applied
    /// (glTF's default material when the primitive names none).
    pub fn resolved_material(
        &self,
        entity: usize,
        asset: &Asset,
        material: Option<usize>,
    ) -> Material {
        let base = material
            .map(|m| asset.materials[m].clone())
            .unwrap_or_default();
        let overrides = self.level.entities[entity]
            .instance
            .as_ref()
            .map(|i| &i.material_overrides);
        match overrides.and_then(|o| o.get(&base.name)) {
            Some(change) => change.apply(&base),
            None => base,
        }
    }

    /// Triangles in the world, counting every instance.
    pub fn triangle_count(&self) -> usize {
        self.mesh_placements()
            .iter()
            .map(|p| {
                p.asset.meshes[p.mesh]
                    .primitives
                    .iter()
                    .map(|q| q.indices.len())
                    .sum::<usize>()
            })
            .sum()
    }

    /// The view to render from: the level's first camera entity, else the first perspective
    /// camera found in the instanced assets' hierarchies, else None (the renderer frames
    /// the scene's bounds).
    pub fn camera(&self) -> Option<CameraPlacement> {
        if let Some(entity) = self.level.entities.iter().find(|e| e.camera.is_some()) {
            let camera = entity.camera.as_ref()?;
            return Some(CameraPlacement {
                name: entity.name.clone(),
                yfov: camera.yfov_degrees.to_radians(),
                znear: camera.znear,
                world_from_camera: entity.transform.matrix(),
            });
        }
        let mut found = None;
        for (entity_index, entity) in self.level.entities.iter().enumerate() {
            let Some(asset_index) = self.entity_assets[entity_index] else {
                continue;
            };
            let asset: &Asset = &self.assets[asset_index];
            asset.visit_nodes(entity.transform.matrix(), |node, world| {
                let camera = asset.nodes[node].camera.map(|c| &asset.cameras[c]);
                if let (
                    None,
                    Some(Camera {
                        name,
                        projection: Projection::Perspective { yfov, znear, .. },
                    }),
                ) = (&found, camera)
                {
                    // Cameras are often unnamed in files; their node usually is not.
                    let name = if name.is_empty() {
                        &asset.nodes[node].name
                    } else {
                        name
                    };
                    found = Some(CameraPlacement {
                        name: name.clone(),
                        yfov: *yfov,
                        znear: *znear,
                        world_from_camera: world,
                    });
                }
            });
            if found.is_some() {
                break;
            }
        }
        found
    }

    /// Punctual lights in the world: the level's light entities and the assets' glTF lights.
    pub fn punctual_lights(&self) -> Vec<(Light, Mat4)> {
        let mut lights = Vec::new();
        for (entity_index, entity) in self.level.entities.iter().enumerate() {
            if let Some(light) = &entity.light {
                lights.push((light.to_light(&entity.name), entity.transform.matrix()));
            }
            let Some(asset_index) = self.entity_assets[entity_index] else {
                continue;
            };
            let asset: &Asset = &self.assets[asset_index];
            asset.visit_nodes(entity.transform.matrix(), |node, world| {
                if let Some(light) = asset.nodes[node].light {
                    lights.push((asset.lights[light].clone(), world));
                }
            });
        }
        lights
    }

    /// The player's start (feet position and eye height), if the level has one.
    pub fn player_spawn(&self) -> Option<(Vec3, f32)> {
        self.level.entities.iter().find_map(|e| {
            e.player_spawn
                .as_ref()
                .map(|spawn| (e.transform.translation, spawn.eye_height))
        })
    }
}
