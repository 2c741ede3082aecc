//! glTF import of every shipped asset and of the Khronos samples in ../shared (skipped with
//! a notice when absent), checked against counts known from the files' own documentation.

mod common;

use gloam::scene::import_gltf;
use gloam::scene::model::{Asset, Projection};

#[derive(Debug, PartialEq)]
struct Counts {
    triangles: usize,
    materials: usize,
    nodes: usize,
    skins: usize,
    animations: usize,
}

fn counts(asset: &Asset) -> Counts {
    Counts {
        triangles: asset.triangle_count(),
        materials: asset.materials.len(),
        nodes: asset.nodes.len(),
        skins: asset.skins.len(),
        animations: asset.animations.len(),
    }
}

fn import(path: &std::path::Path) -> Asset {
    import_gltf(path).unwrap_or_else(|error| panic!("{error}"))
}

/// Every primitive is consistent: attribute lengths agree, indices in range, unit normals.
fn assert_well_formed(asset: &Asset) {
    for mesh in &asset.meshes {
        for primitive in &mesh.primitives {
            let n = primitive.positions.len();
            assert_eq!(primitive.normals.len(), n, "{}: normals", mesh.name);
            assert!(primitive.uv0.is_empty() || primitive.uv0.len() == n);
            assert!(
                primitive
                    .indices
                    .iter()
                    .flatten()
                    .all(|&i| (i as usize) < n)
            );
            assert!(
                primitive
                    .normals
                    .iter()
                    .all(|v| (v.length() - 1.0).abs() < 1e-3),
                "{}: normals not unit",
                mesh.name
            );
            for set in &primitive.skin_influences {
                assert_eq!(set.joints.len(), n);
                assert_eq!(set.weights.len(), n);
            }
            for target in &primitive.morph_targets {
                assert!(target.positions.is_empty() || target.positions.len() == n);
            }
        }
    }
}

#[test]
fn khronos_samples_import_with_known_counts() {
    let Some(samples) = common::shared("gltf-samples") else {
        return;
    };
    // (file, triangles, materials, nodes, skins, animations); counts from the Khronos
    // sample descriptions and the files' JSON.
    let table = [
        ("Box/glTF/Box.gltf", 12, 1, 2, 0, 0),
        ("Box/glTF-Embedded/Box.gltf", 12, 1, 2, 0, 0),
        ("BoxTextured/glTF-Embedded/BoxTextured.gltf", 12, 1, 3, 0, 0),
        ("Duck/glTF-Binary/Duck.glb", 4212, 1, 3, 0, 0),
        ("CesiumMan/glTF-Binary/CesiumMan.glb", 4672, 1, 22, 1, 1),
        ("RiggedSimple/glTF/RiggedSimple.gltf", 188, 1, 5, 1, 1),
        ("SimpleSkin/glTF/SimpleSkin.gltf", 8, 0, 3, 1, 1),
        ("SimpleMorph/glTF/SimpleMorph.gltf", 1, 0, 1, 0, 1),
        (
            "AnimatedMorphCube/glTF/AnimatedMorphCube.gltf",
            12,
            1,
            1,
            0,
            1,
        ),
        ("Fox/glTF-Binary/Fox.glb", 576, 1, 26, 1, 3),
    ];
    for (file, triangles, materials, nodes, skins, animations) in table {
        let asset = import(&samples.join(file));
        assert_eq!(
            counts(&asset),
            Counts {
                triangles,
                materials,
                nodes,
                skins,
                animations
            },
            "{file}"
        );
        assert_well_formed(&asset);
    }
}

#[test]
fn khronos_samples_keep_their_details() {
    let Some(samples) = common::shared("gltf-samples") else {
        return;
    };
    // BoxTextured: one sRGB base-colour texture on UV set 0.
    let boxed = import(&samples.join("BoxTextured/glTF-Embedded/BoxTextured.gltf"));
    let texture = boxed.materials[0]
        .base_color_texture
        .as_ref()
        .expect("base colour texture");
    assert_eq!(texture.encoding, gloam::scene::model::ColorEncoding::Srgb);
    let image = &boxed.images[boxed.textures[texture.texture].image];
    assert!(image.width > 0 && image.rgba8.len() == (image.width * image.height) as usize);

    // Duck: a perspective camera.
    let duck = import(&samples.join("Duck/glTF-Binary/Duck.glb"));
    assert!(matches!(
        duck.cameras[0].projection,
        Projection::Perspective { .. }
    ));

    // Fox: 24 joints with one inverse bind matrix each; three clips (Survey, Walk, Run).
    let fox = import(&samples.join("Fox/glTF-Binary/Fox.glb"));
    assert_eq!(fox.skins[0].joints.len(), 24);
    assert_eq!(fox.skins[0].inverse_bind_matrices.len(), 24);
    let names: Vec<_> = fox.animations.iter().map(|a| a.name.as_str()).collect();
    assert_eq!(names, ["Survey", "Walk", "Run"]);
    let weights = &fox.meshes[0].primitives[0].skin_influences[0].weights;
    assert!(
        weights
            .iter()
            .all(|w| (w.iter().sum::<f32>() - 1.0).abs() < 0.01),
        "skin weights sum to 1"
    );

    // CesiumMan: 19 joints, 57 channels.
    let man = import(&samples.join("CesiumMan/glTF-Binary/CesiumMan.glb"));
    assert_eq!(man.skins[0].joints.len(), 19);
    assert_eq!(man.animations[0].channels.len(), 57);

    // Morph targets: two per primitive, with default weights and a weights channel.
    for file in [
        "SimpleMorph/glTF/SimpleMorph.gltf",
        "AnimatedMorphCube/glTF/AnimatedMorphCube.gltf",
    ] {
        let asset = import(&samples.join(file));
        assert_eq!(
            asset.meshes[0].primitives[0].morph_targets.len(),
            2,
            "{file}"
        );
        let channel = &asset.animations[0].channels[0];
        assert_eq!(
            channel.property,
            gloam::scene::model::AnimatedProperty::MorphWeights
        );
        assert_eq!(asset.animations[0].samplers[channel.sampler].components, 2);
    }

    // SimpleSkin: the animated joint's rotation keys are unit quaternions.
    let skin = import(&samples.join("SimpleSkin/glTF/SimpleSkin.gltf"));
    let sampler = &skin.animations[0].samplers[0];
    assert_eq!(sampler.components, 4);
    for q in sampler.values.chunks_exact(4) {
        assert!((glam::Vec4::from_slice(q).length() - 1.0).abs() < 1e-3);
    }
}

#[test]
fn benchmark_scene_imports() {
    let Some(scenes) = common::shared("scenes") else {
        return;
    };
    let asset = import(&scenes.join("dream-apartment.glb"));
    // SOURCES.md: 177,934 triangles of geometry plus the 2-triangle light quad.
    assert_eq!(asset.triangle_count(), 177_936);
    let light = asset
        .materials
        .iter()
        .find(|m| m.name == "light")
        .expect("light material");
    assert_eq!(light.emissive, glam::Vec3::splat(50.0));
    assert_eq!(asset.cameras.len(), 1);
    assert_well_formed(&asset);
}
