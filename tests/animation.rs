//! Animation and deformation, end to end: the game's posed meshes against an independent
//! per-vertex reference, renders of deformed poses against the same pose baked static,
//! and change detection deciding what to deform and refit.
//!
//! The reference reads the glTF JSON and buffers itself (serde_json and byte slicing, not
//! Gloam's importer or the gltf crate), samples the clips with its own f64 arithmetic, walks
//! the node hierarchy, and skins each vertex as the glTF specification writes it:
//! v' = sum_i w_i (J_i IBM_i) (v + sum_t m_t dv_t).

mod common;

use std::path::Path;

use glam::{DMat3, DMat4, DQuat, DVec3};
use gloam::extract::{DeformStats, RenderState};
use gloam::frame::Engine;
use gloam::render::{Camera, IntegratorKind, RenderSettings, SamplerKind, render};
use gloam::scene::world::Scene;
use serde_json::Value;

// ---- an independent glTF reader -----------------------------------------------------------

struct Document {
    json: Value,
    buffers: Vec<Vec<u8>>,
}

impl Document {
    fn open(path: &Path) -> Document {
        let bytes = std::fs::read(path).unwrap();
        let (json, blob) = if bytes.starts_with(b"glTF") {
            let word =
                |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
            let json_length = word(12);
            let json: Value = serde_json::from_slice(&bytes[20..20 + json_length]).unwrap();
            let bin_at = 20 + json_length;
            let blob = (bin_at < bytes.len())
                .then(|| bytes[bin_at + 8..bin_at + 8 + word(bin_at)].to_vec());
            (json, blob)
        } else {
            (serde_json::from_slice(&bytes).unwrap(), None)
        };
        let buffers = json["buffers"]
            .as_array()
            .map(|buffers| {
                buffers
                    .iter()
                    .map(|buffer| match buffer["uri"].as_str() {
                        Some(uri) if uri.starts_with("data:") => {
                            use base64::Engine as _;
                            let payload = uri.split_once(',').unwrap().1;
                            base64::engine::general_purpose::STANDARD
                                .decode(payload)
                                .unwrap()
                        }
                        Some(uri) => std::fs::read(path.parent().unwrap().join(uri)).unwrap(),
                        None => blob.clone().unwrap(),
                    })
                    .collect()
            })
            .unwrap_or_default();
        Document { json, buffers }
    }

    /// Accessor `index` as f64 elements of its component count (normalised integers mapped
    /// to [0, 1] when the accessor says so).
    fn read(&self, index: usize) -> Vec<Vec<f64>> {
        let accessor = &self.json["accessors"][index];
        assert!(
            accessor.get("sparse").is_none(),
            "reference reader has no sparse support"
        );
        let count = accessor["count"].as_u64().unwrap() as usize;
        let components = match accessor["type"].as_str().unwrap() {
            "SCALAR" => 1,
            "VEC2" => 2,
            "VEC3" => 3,
            "VEC4" => 4,
            "MAT4" => 16,
            other => panic!("type {other}"),
        };
        let component_type = accessor["componentType"].as_u64().unwrap();
        let size = match component_type {
            5120 | 5121 => 1,
            5122 | 5123 => 2,
            _ => 4,
        };
        let normalized = accessor["normalized"].as_bool().unwrap_or(false);
        let view = &self.json["bufferViews"][accessor["bufferView"].as_u64().unwrap() as usize];
        let buffer = &self.buffers[view["buffer"].as_u64().unwrap() as usize];
        let start = view["byteOffset"].as_u64().unwrap_or(0) as usize
            + accessor["byteOffset"].as_u64().unwrap_or(0) as usize;
        let stride = view["byteStride"]
            .as_u64()
            .map_or(components * size, |s| s as usize);
        (0..count)
            .map(|element| {
                (0..components)
                    .map(|c| {
                        let at = start + element * stride + c * size;
                        let b = &buffer[at..at + size];
                        match component_type {
                            5126 => f32::from_le_bytes(b.try_into().unwrap()) as f64,
                            5121 if normalized => b[0] as f64 / 255.0,
                            5121 => b[0] as f64,
                            5123 if normalized => {
                                u16::from_le_bytes(b.try_into().unwrap()) as f64 / 65535.0
                            }
                            5123 => u16::from_le_bytes(b.try_into().unwrap()) as f64,
                            5125 => u32::from_le_bytes(b.try_into().unwrap()) as f64,
                            other => panic!("component type {other}"),
                        }
                    })
                    .collect()
            })
            .collect()
    }

    fn vec3s(&self, index: usize) -> Vec<DVec3> {
        self.read(index)
            .iter()
            .map(|v| DVec3::new(v[0], v[1], v[2]))
            .collect()
    }

    fn nodes(&self) -> &Vec<Value> {
        self.json["nodes"].as_array().unwrap()
    }
}

/// Local TRS of every node (matrix nodes decomposed), with clip 0 applied at time `t`.
fn posed_locals(document: &Document, t: f64) -> Vec<(DVec3, DQuat, DVec3, Option<DMat4>)> {
    let mut locals: Vec<_> = document
        .nodes()
        .iter()
        .map(|node| {
            let v3 = |key: &str, default: DVec3| {
                node[key].as_array().map_or(default, |a| {
                    DVec3::new(
                        a[0].as_f64().unwrap(),
                        a[1].as_f64().unwrap(),
                        a[2].as_f64().unwrap(),
                    )
                })
            };
            let rotation = node["rotation"].as_array().map_or(DQuat::IDENTITY, |a| {
                let q: Vec<f64> = a.iter().map(|x| x.as_f64().unwrap()).collect();
                DQuat::from_xyzw(q[0], q[1], q[2], q[3]).normalize()
            });
            let matrix = node["matrix"].as_array().map(|m| {
                let m: Vec<f64> = m.iter().map(|x| x.as_f64().unwrap()).collect();
                DMat4::from_cols_slice(&m)
            });
            (
                v3("translation", DVec3::ZERO),
                rotation,
                v3("scale", DVec3::ONE),
                matrix,
            )
        })
        .collect();
    if let Some(animation) = document.json["animations"].get(0) {
        for channel in animation["channels"].as_array().unwrap() {
            let path = channel["target"]["path"].as_str().unwrap();
            if path == "weights" {
                continue;
            }
            let node = channel["target"]["node"].as_u64().unwrap() as usize;
            let value = sample_channel(document, animation, channel, t);
            let local = &mut locals[node];
            match path {
                "translation" => local.0 = DVec3::new(value[0], value[1], value[2]),
                "rotation" => {
                    local.1 = DQuat::from_xyzw(value[0], value[1], value[2], value[3]).normalize()
                }
                "scale" => local.2 = DVec3::new(value[0], value[1], value[2]),
                _ => {}
            }
        }
    }
    locals
}

/// glTF appendix C, written out in f64: clamp outside the keys, STEP holds, LINEAR lerps
/// (slerp for rotations, by its sine formula), CUBICSPLINE is the Hermite spline.
fn sample_channel(document: &Document, animation: &Value, channel: &Value, t: f64) -> Vec<f64> {
    let sampler = &animation["samplers"][channel["sampler"].as_u64().unwrap() as usize];
    let times: Vec<f64> = document
        .read(sampler["input"].as_u64().unwrap() as usize)
        .iter()
        .map(|v| v[0])
        .collect();
    let flat: Vec<f64> = document
        .read(sampler["output"].as_u64().unwrap() as usize)
        .concat();
    let interpolation = sampler["interpolation"].as_str().unwrap_or("LINEAR");
    let per_key = if interpolation == "CUBICSPLINE" { 3 } else { 1 };
    let width = flat.len() / (times.len() * per_key);
    let element = |k: usize, e: usize| {
        flat[(k * per_key + e) * width..(k * per_key + e + 1) * width].to_vec()
    };
    let value_of = |k: usize| element(k, if per_key == 3 { 1 } else { 0 });
    let n = times.len();
    if t <= times[0] || n == 1 {
        return value_of(0);
    }
    if t >= times[n - 1] {
        return value_of(n - 1);
    }
    let mut k = 0;
    while times[k + 1] <= t {
        k += 1;
    }
    let interval = times[k + 1] - times[k];
    let s = (t - times[k]) / interval;
    let is_rotation = channel["target"]["path"] == "rotation";
    match interpolation {
        "STEP" => value_of(k),
        "CUBICSPLINE" => {
            let (p0, m0, p1, m1) = (
                element(k, 1),
                element(k, 2),
                element(k + 1, 1),
                element(k + 1, 0),
            );
            let (s2, s3) = (s * s, s * s * s);
            let mut out: Vec<f64> = (0..width)
                .map(|c| {
                    (2.0 * s3 - 3.0 * s2 + 1.0) * p0[c]
                        + (s3 - 2.0 * s2 + s) * interval * m0[c]
                        + (-2.0 * s3 + 3.0 * s2) * p1[c]
                        + (s3 - s2) * interval * m1[c]
                })
                .collect();
            if is_rotation {
                let length = out.iter().map(|x| x * x).sum::<f64>().sqrt();
                out.iter_mut().for_each(|x| *x /= length);
            }
            out
        }
        _ if is_rotation => {
            let (a, mut b) = (value_of(k), value_of(k + 1));
            let mut dot: f64 = (0..4).map(|c| a[c] * b[c]).sum();
            if dot < 0.0 {
                b.iter_mut().for_each(|x| *x = -*x);
                dot = -dot;
            }
            if dot > 0.9995 {
                let mut out: Vec<f64> = (0..4).map(|c| a[c] + (b[c] - a[c]) * s).collect();
                let length = out.iter().map(|x| x * x).sum::<f64>().sqrt();
                out.iter_mut().for_each(|x| *x /= length);
                return out;
            }
            let angle = dot.clamp(-1.0, 1.0).acos();
            let (wa, wb) = (
                ((1.0 - s) * angle).sin() / angle.sin(),
                (s * angle).sin() / angle.sin(),
            );
            (0..4).map(|c| wa * a[c] + wb * b[c]).collect()
        }
        _ => {
            let (a, b) = (value_of(k), value_of(k + 1));
            (0..width).map(|c| a[c] + (b[c] - a[c]) * s).collect()
        }
    }
}

/// Morph weights of node `node` at time `t`: animated, else the node's, else the mesh's.
fn morph_weights(document: &Document, node: usize, mesh: &Value, t: f64) -> Vec<f64> {
    if let Some(animation) = document.json["animations"].get(0) {
        for channel in animation["channels"].as_array().unwrap() {
            if channel["target"]["path"] == "weights" && channel["target"]["node"] == node {
                return sample_channel(document, animation, channel, t);
            }
        }
    }
    let from = |v: &Value| {
        v.as_array()
            .map(|w| w.iter().map(|x| x.as_f64().unwrap()).collect::<Vec<f64>>())
    };
    from(&document.nodes()[node]["weights"])
        .or_else(|| from(&mesh["weights"]))
        .unwrap_or_default()
}

/// World-space positions and normals of every vertex of node `node`'s mesh at time `t`,
/// in Gloam's vertex order (primitives concatenated; unwelded by index when the file has
/// no normals, as import does).
fn reference_vertices(document: &Document, node: usize, t: f64) -> Vec<(DVec3, Option<DVec3>)> {
    let nodes = document.nodes();
    let locals = posed_locals(document, t);
    let mut parent = vec![None; nodes.len()];
    for (index, n) in nodes.iter().enumerate() {
        for child in n["children"].as_array().into_iter().flatten() {
            parent[child.as_u64().unwrap() as usize] = Some(index);
        }
    }
    let world = |mut n: usize| {
        let mut matrix = DMat4::IDENTITY;
        loop {
            let (translation, rotation, scale, fixed) = locals[n];
            let local = fixed.unwrap_or_else(|| {
                DMat4::from_scale_rotation_translation(scale, rotation, translation)
            });
            matrix = local * matrix;
            match parent[n] {
                Some(p) => n = p,
                None => return matrix,
            }
        }
    };
    let mesh = &document.json["meshes"][nodes[node]["mesh"].as_u64().unwrap() as usize];
    let weights = morph_weights(document, node, mesh, t);
    let skin = nodes[node]["skin"]
        .as_u64()
        .map(|s| &document.json["skins"][s as usize]);
    let joint_matrices: Vec<DMat4> = skin
        .map(|skin| {
            let joints: Vec<usize> = skin["joints"]
                .as_array()
                .unwrap()
                .iter()
                .map(|j| j.as_u64().unwrap() as usize)
                .collect();
            let inverse_binds: Vec<DMat4> = match skin["inverseBindMatrices"].as_u64() {
                Some(accessor) => document
                    .read(accessor as usize)
                    .iter()
                    .map(|m| DMat4::from_cols_slice(m))
                    .collect(),
                None => vec![DMat4::IDENTITY; joints.len()],
            };
            joints
                .iter()
                .zip(&inverse_binds)
                .map(|(&j, ibm)| world(j) * *ibm)
                .collect()
        })
        .unwrap_or_default();
    let node_world = world(node);
    let mut out = Vec::new();
    for primitive in mesh["primitives"].as_array().unwrap() {
        let attributes = &primitive["attributes"];
        let positions = document.vec3s(attributes["POSITION"].as_u64().unwrap() as usize);
        let normals = attributes["NORMAL"]
            .as_u64()
            .map(|a| document.vec3s(a as usize));
        let mut morphed: Vec<(DVec3, Option<DVec3>)> = positions
            .iter()
            .enumerate()
            .map(|(v, &p)| (p, normals.as_ref().map(|n| n[v])))
            .collect();
        for (target, &w) in primitive["targets"]
            .as_array()
            .into_iter()
            .flatten()
            .zip(&weights)
        {
            if let Some(a) = target["POSITION"].as_u64() {
                for (vertex, delta) in morphed.iter_mut().zip(document.vec3s(a as usize)) {
                    vertex.0 += w * delta;
                }
            }
            if let Some(a) = target["NORMAL"].as_u64() {
                for (vertex, delta) in morphed.iter_mut().zip(document.vec3s(a as usize)) {
                    if let Some(n) = &mut vertex.1 {
                        *n += w * delta;
                    }
                }
            }
        }
        let mut sets = Vec::new();
        for set in 0.. {
            let (Some(j), Some(w)) = (
                attributes[format!("JOINTS_{set}")].as_u64(),
                attributes[format!("WEIGHTS_{set}")].as_u64(),
            ) else {
                break;
            };
            sets.push((document.read(j as usize), document.read(w as usize)));
        }
        let posed: Vec<(DVec3, Option<DVec3>)> = morphed
            .iter()
            .enumerate()
            .map(|(v, &(p, n))| {
                let matrix = if skin.is_some() {
                    let mut blended = DMat4::ZERO;
                    let mut total = 0.0;
                    for (joints, weights) in &sets {
                        for k in 0..4 {
                            blended += joint_matrices[joints[v][k] as usize] * weights[v][k];
                            total += weights[v][k];
                        }
                    }
                    blended * (1.0 / total)
                } else {
                    node_world
                };
                let normal_matrix = DMat3::from_mat4(matrix).inverse().transpose();
                (
                    matrix.transform_point3(p),
                    n.map(|n| (normal_matrix * n).normalize()),
                )
            })
            .collect();
        let order: Vec<usize> = match (primitive["indices"].as_u64(), normals.is_some()) {
            (Some(indices), false) => document
                .read(indices as usize)
                .iter()
                .map(|i| i[0] as usize)
                .collect(),
            (None, false) | (_, true) => (0..posed.len()).collect(),
        };
        out.extend(order.into_iter().map(|v| posed[v]));
    }
    out
}

/// Gloam's posed world-space vertices of the instance drawing asset node `node`.
fn engine_vertices(engine: &mut Engine, node: usize) -> Vec<(DVec3, DVec3)> {
    let index = engine
        .node_instance(0, node)
        .expect("an instance for the node");
    let state = engine.world.resource::<RenderState>();
    let accel = &state.scene.accel;
    let instance = &accel.instances()[index as usize];
    let to_world = instance.world_from_object();
    let normal_matrix = glam::Mat3::from(to_world.matrix3).inverse().transpose();
    let geometry = &accel.blases[instance.blas as usize].geometry;
    geometry
        .positions
        .iter()
        .zip(&geometry.normals)
        .map(|(&p, &n)| {
            (
                to_world.transform_point3(p).as_dvec3(),
                (normal_matrix * n).normalize().as_dvec3(),
            )
        })
        .collect()
}

fn settings(width: u32, height: u32, spp: u32) -> RenderSettings {
    RenderSettings {
        width,
        height,
        spp,
        seed: 7,
        frame: 0,
        integrator: IntegratorKind::Path,
        sampler: SamplerKind::Stratified,
        max_depth: 3,
    }
}

/// Poses `path` (a bare glTF: clip 0 plays) at several times, keyframes and between them,
/// and checks every deformed vertex and normal against the reference.
fn check_against_reference(path: &Path) {
    let document = Document::open(path);
    let scene = Scene::load(path).unwrap();
    let asset = &scene.assets[0];
    let duration = asset.animations.first().map_or(0.0, |a| a.duration()) as f64;
    let key_times: Vec<f64> = asset
        .animations
        .first()
        .map(|a| a.samplers[0].times.iter().map(|&t| t as f64).collect())
        .unwrap_or_default();
    // Keys (inside the clip: its last key wraps to 0 when looping) and points between them.
    let mut times = vec![0.0];
    for pair in key_times.windows(2).step_by((key_times.len() / 4).max(1)) {
        times.push(pair[0]);
        times.push(0.5 * (pair[0] + pair[1]));
        times.push(pair[0] + 0.3 * (pair[1] - pair[0]));
    }
    times.retain(|&t| t < duration || duration == 0.0);
    let deforming: Vec<usize> = document
        .nodes()
        .iter()
        .enumerate()
        .filter(|(_, n)| {
            n.get("mesh").is_some()
                && (n.get("skin").is_some() || {
                    let mesh = &document.json["meshes"][n["mesh"].as_u64().unwrap() as usize];
                    mesh["primitives"][0].get("targets").is_some()
                })
        })
        .map(|(i, _)| i)
        .collect();
    assert!(!deforming.is_empty(), "{}: nothing deforms", path.display());

    let mut engine = Engine::new(&scene, RenderSettings::real_time(4, 4));
    let mut checked = 0;
    for &t in &times {
        engine.pose_at(t);
        for &node in &deforming {
            let expected = reference_vertices(&document, node, t);
            let actual = engine_vertices(&mut engine, node);
            assert_eq!(
                expected.len(),
                actual.len(),
                "{}: node {node} vertex count",
                path.display()
            );
            let extent = expected
                .iter()
                .map(|v| v.0.abs().max_element())
                .fold(0.0, f64::max)
                .max(1e-3);
            for (v, (reference, gloam)) in expected.iter().zip(&actual).enumerate() {
                let error = (reference.0 - gloam.0).length();
                assert!(
                    error <= 2e-5 * extent,
                    "{} node {node} t {t}: vertex {v} at {} but the reference puts it at {} (extent {extent})",
                    path.display(),
                    gloam.0,
                    reference.0
                );
                if let Some(normal) = reference.1 {
                    assert!(
                        normal.dot(gloam.1) > 0.9999,
                        "{} node {node} t {t}: vertex {v} normal {} vs reference {normal}",
                        path.display(),
                        gloam.1
                    );
                }
                checked += 1;
            }
        }
    }
    println!(
        "{}: {checked} vertices at {} times match the reference",
        path.display(),
        times.len()
    );
}

#[test]
fn skinned_and_morphed_samples_match_the_reference() {
    for sample in [
        "SimpleSkin/glTF/SimpleSkin.gltf",
        "RiggedSimple/glTF/RiggedSimple.gltf",
        "CesiumMan/glTF-Binary/CesiumMan.glb",
        "Fox/glTF-Binary/Fox.glb",
        "SimpleMorph/glTF/SimpleMorph.gltf",
        "AnimatedMorphCube/glTF/AnimatedMorphCube.gltf",
    ] {
        let Some(path) = common::shared(&format!("gltf-samples/{sample}")) else {
            continue;
        };
        check_against_reference(&path);
    }
}

#[test]
fn project_assets_match_the_reference() {
    for asset in ["kit/warden.glb", "kit/banner.glb"] {
        check_against_reference(&common::repo().join("assets").join(asset));
    }
}

/// The scene with every deforming mesh replaced by its pose at `t` as a plain static mesh:
/// vertices written into the asset, skins, morph targets and clips removed, skinned nodes
/// given the transform that cancels their parents' (their vertices are already in the
/// entity's space).
fn baked(scene: &Scene, engine: &mut Engine) -> Scene {
    let mut baked = scene.clone();
    let instances: Vec<Vec<(usize, u32)>> = (0..scene.level.entities.len())
        .map(|entity| engine.level_entity_instances(entity))
        .collect();
    let state = engine.world.resource::<RenderState>();
    let accel = &state.scene.accel;
    for entity in &mut baked.level.entities {
        entity.animation = None;
        entity.deformer = None;
    }
    for (entity_index, asset_index) in scene.entity_assets.iter().enumerate() {
        let Some(asset_index) = *asset_index else {
            continue;
        };
        // Entities share assets; each baked pose needs its own copy.
        let own = baked.assets.len();
        baked
            .assets
            .push(std::sync::Arc::new((*scene.assets[asset_index]).clone()));
        baked.entity_assets[entity_index] = Some(own);
        let asset = std::sync::Arc::make_mut(&mut baked.assets[own]);
        for node in 0..asset.nodes.len() {
            let Some(mesh) = asset.nodes[node].mesh else {
                continue;
            };
            let Some(&(_, index)) = instances[entity_index].iter().find(|(n, _)| *n == node) else {
                continue;
            };
            let instance = &accel.instances()[index as usize];
            let blas = &accel.blases[instance.blas as usize];
            if blas.kind != gloam::accel::BlasKind::Deforming {
                continue;
            }
            let geometry = &blas.geometry;
            let mut offset = 0;
            for primitive in &mut asset.meshes[mesh].primitives {
                let count = primitive.positions.len();
                primitive.positions = geometry.positions[offset..offset + count].to_vec();
                primitive.normals = geometry.normals[offset..offset + count].to_vec();
                primitive.morph_targets.clear();
                primitive.skin_influences.clear();
                offset += count;
            }
            if asset.nodes[node].skin.take().is_some() {
                // The vertices are in the entity's space: undo the parents' rest transforms
                // (the node keeps its place in the hierarchy, so instance order is kept).
                let mut world_from_node = glam::Mat4::IDENTITY;
                asset.visit_nodes(glam::Mat4::IDENTITY, |n, world| {
                    if n == node {
                        world_from_node = world;
                    }
                });
                let parent_world = world_from_node * asset.nodes[node].transform.matrix().inverse();
                asset.nodes[node].transform =
                    gloam::scene::model::NodeTransform::Matrix(parent_world.inverse());
            }
        }
        asset.animations.clear();
    }
    baked
}

fn rmse_over_mean(a: &gloam::render::HdrImage, b: &gloam::render::HdrImage) -> f64 {
    let mut squared = 0.0;
    let mut mean = 0.0;
    for (x, y) in a.pixels.iter().zip(&b.pixels) {
        squared += (*x - *y).length_squared() as f64;
        mean += y.length() as f64;
    }
    let n = a.pixels.len() as f64;
    (squared / n).sqrt() / (mean / n)
}

#[test]
fn a_deformed_pose_renders_like_the_same_pose_baked_static() {
    let level = common::repo().join("levels").join("first-light.ron");
    let mut cases = vec![(level, 1.3)];
    if let Some(path) = common::shared("gltf-samples/CesiumMan/glTF-Binary/CesiumMan.glb") {
        cases.push((path, 0.7));
    }
    for (path, t) in cases {
        let scene = Scene::load(&path).unwrap();
        let mut engine = Engine::new(&scene, RenderSettings::real_time(4, 4));
        engine.pose_at(t);
        assert!(
            engine.deform_stats().deformed > 0,
            "{}: nothing deformed",
            path.display()
        );
        let static_scene = baked(&scene, &mut engine);
        let static_engine = Engine::new(&static_scene, RenderSettings::real_time(4, 4));
        assert_eq!(
            static_engine.deform_stats(),
            DeformStats::default(),
            "the baked scene is static"
        );
        let deformed = engine.render_scene();
        let still = static_engine.render_scene();
        let camera = Camera::new(&deformed.camera, 96, 64);
        let a = render(deformed, &camera, &settings(96, 64, 8), &|_| {}).image;
        let b = render(still, &camera, &settings(96, 64, 8), &|_| {}).image;
        // Same triangles, same rays, same seeds: the images agree to rounding (measured
        // ~2e-8 on first-light, ~6e-7 on CesiumMan), except where a tie between triangles
        // sharing an edge resolves differently in the two trees (their layouts differ).
        let error = rmse_over_mean(&a, &b);
        println!(
            "{}: deformed vs baked RMSE/mean {error:.2e}",
            path.display()
        );
        assert!(
            error < 1e-4,
            "{}: deformed vs baked RMSE/mean {error}",
            path.display()
        );
    }
}

#[test]
fn change_detection_decides_what_deforms() {
    let path = common::repo().join("assets").join("kit").join("warden.glb");
    let scene = Scene::load(&path).unwrap();
    let mut engine = Engine::new(&scene, RenderSettings::real_time(8, 8));
    // Playing: every frame with a simulation step re-poses and refits.
    engine.advance(1.0 / 60.0);
    let playing = engine.deform_stats();
    assert!(
        playing.deformed >= 1 && playing.refits + playing.rebuilds == playing.deformed,
        "{playing:?}"
    );
    // A frame with no simulation step changes nothing: skipped.
    engine.advance(0.0);
    let idle = engine.deform_stats();
    assert_eq!(
        (idle.deformed, idle.skipped),
        (0, playing.deformed),
        "{idle:?}"
    );
    // Paused animators leave the pose alone, even as steps run.
    let mut animators = engine.world.query::<&mut gloam::game::Animator>();
    for mut animator in animators.iter_mut(&mut engine.world) {
        animator.speed = 0.0;
    }
    engine.advance(1.0 / 60.0);
    engine.advance(1.0 / 60.0);
    assert_eq!(
        engine.deform_stats().deformed,
        0,
        "{:?}",
        engine.deform_stats()
    );
    // Moving the whole warden moves its instance, not its vertices.
    let mut roots = engine
        .world
        .query::<(&gloam::game::LevelEntity, &mut gloam::game::Transform)>();
    for (_, mut transform) in roots.iter_mut(&mut engine.world) {
        transform.translation.x += 1.0;
    }
    engine.advance(1.0 / 60.0);
    assert_eq!(
        engine.deform_stats().deformed,
        0,
        "{:?}",
        engine.deform_stats()
    );

    // A static level has nothing to deform at all.
    let level = Scene::load(&common::repo().join("levels").join("cornell.ron")).unwrap();
    let mut still = Engine::new(&level, RenderSettings::real_time(8, 8));
    still.advance(1.0 / 60.0);
    assert_eq!(still.deform_stats(), DeformStats::default());
}

#[test]
fn a_deformer_refits_every_step_and_rebuilds_when_the_tree_decays() {
    let dir = common::scratch_dir("deformer");
    let grid = dir.join("grid.glb");
    gloam::scene::kit::write_stress_mesh(&grid, 20_000).unwrap();
    let crate_asset = common::repo().join("assets").join("kit").join("crate.glb");
    let level = |name: &str, amplitude: f32, wavelength: f32| {
        let text = format!(
            r#"(
    version: 1,
    playable: false,
    entities: [
        (name: "blob", instance: (asset: "{}"), deformer: Wobble(amplitude: 0.05, period: 0.5)),
        (name: "sea", instance: (asset: "grid.glb"), deformer: Wave(amplitude: {amplitude}, wavelength: {wavelength}, period: 0.25, direction: (1.0, 0.0, 1.0))),
    ],
)"#,
            crate_asset.display()
        );
        Scene::load(&common::write(&dir, name, text)).unwrap()
    };

    // Gentle waves: refit in place every step.
    let mut engine = Engine::new(
        &level("gentle.ron", 0.05, 2.0),
        RenderSettings::real_time(8, 8),
    );
    for _ in 0..3 {
        engine.advance(1.0 / 60.0);
        let stats = engine.deform_stats();
        assert_eq!(
            (stats.deformed, stats.refits, stats.rebuilds),
            (2, 2, 0),
            "{stats:?}"
        );
    }
    // The sea's vertices really moved off the grid's rest heights (|y| <= 0.25).
    let (_, sea) = engine.level_entity_instances(1)[0];
    let state = engine.world.resource::<RenderState>();
    let accel = &state.scene.accel;
    let sea = &accel.instances()[sea as usize];
    let geometry = &accel.blases[sea.blas as usize].geometry;
    let rest = gloam::scene::import_gltf(&grid).unwrap();
    let moved = geometry
        .positions
        .iter()
        .zip(&rest.meshes[0].primitives[0].positions)
        .filter(|(a, b)| (**a - **b).length() > 1e-3)
        .count();
    assert!(
        moved > geometry.positions.len() / 2,
        "{moved} of {} vertices moved",
        geometry.positions.len()
    );

    // The editor turns the sea violent: short, tall waves stretch the refit tree until the
    // policy rebuilds it (from then on the new shape is the reference).
    let mut deformers = engine.world.query::<&mut gloam::game::Deformer>();
    for mut deformer in deformers.iter_mut(&mut engine.world) {
        if let gloam::scene::level::DeformerDef::Wave {
            amplitude,
            wavelength,
            ..
        } = &mut deformer.kind
        {
            (*amplitude, *wavelength) = (1.5, 0.2);
        }
    }
    let mut rebuilds = 0;
    for _ in 0..3 {
        engine.advance(1.0 / 60.0);
        rebuilds += engine.deform_stats().rebuilds;
    }
    assert_eq!(
        rebuilds, 1,
        "one rebuild when the waves turn violent, then refits"
    );
}
