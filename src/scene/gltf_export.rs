//! Load-time tooling: writes glTF 2.0 files (.gltf + .bin, or .glb) from simple mesh data;
//! used by the asset generators in `kit` and by tests that need glTF files.
//!
//! The data model is deliberately small: one triangle-list primitive per mesh (POSITION,
//! NORMAL, optional TEXCOORD_0, optional JOINTS_0 + WEIGHTS_0 for skinning, optional morph
//! targets with POSITION and NORMAL deltas, u32 indices; default morph weights as
//! `mesh.weights` and target names as `mesh.extras.targetNames`), metallic-roughness
//! materials with emission, transmission, ior and base-colour, metallic-roughness and normal
//! textures, PNG images (one texture per image, one trilinear/repeat sampler), perspective cameras, a TRS node tree, skins (joints, inverse bind
//! matrices, skeleton root) and animations (one sampler per channel: translation, rotation,
//! scale or morph weights with LINEAR, STEP or CUBICSPLINE interpolation). Everything is
//! validated before anything is written; the JSON is built from gltf-json's own types and the
//! GLB container by the gltf crate's binary writer, so every shipped asset passes the Khronos
//! glTF Validator (`tests/gltf_validator.rs`). Output is byte-for-byte deterministic and every
//! file is written atomically (temporary file in the same folder, then rename).
//! `MeshData` also carries the shape builders the generators use (quad, box, cylinder,
//! flat-shaded convex solid).

use std::borrow::Cow;
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use anyhow::{Context as _, bail, ensure};
use glam::{Mat4, Quat, Vec2, Vec3, Vec4};
use gltf::binary::Glb;
use gltf::json::accessor::{self, Accessor, ComponentType};
use gltf::json::validation::Checked::Valid;
use gltf::json::{self, Index, Root, animation, buffer, mesh, texture};
use serde_json::{Value, json};

pub use super::files::write_atomically;
use super::model::{AnimatedProperty, Interpolation};

/// One mesh with a single triangle-list primitive. Attribute vectors have equal length
/// (`uvs` may instead be empty); triangles are counter-clockwise seen from the front.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshData {
    pub name: String,
    pub positions: Vec<Vec3>,
    /// Unit normals, one per position.
    pub normals: Vec<Vec3>,
    /// TEXCOORD_0 (glTF convention: v grows downwards in the image), or empty.
    pub uvs: Vec<Vec2>,
    pub indices: Vec<[u32; 3]>,
    /// Index into `GltfDocument::materials`.
    pub material: usize,
    /// JOINTS_0: four indices into the joint list of the skin of every node showing this
    /// mesh, one set per vertex; empty when the mesh is not skinned.
    pub joints: Vec<[u16; 4]>,
    /// WEIGHTS_0: the weights of `joints`, one set per vertex (each >= 0, summing to 1);
    /// empty when the mesh is not skinned.
    pub weights: Vec<[f32; 4]>,
    /// Morph targets, all with one delta per vertex.
    pub morph_targets: Vec<MorphTargetData>,
    /// Default morph weights (glTF `mesh.weights`), one per morph target.
    pub morph_weights: Vec<f32>,
}

/// One morph target: displacements added to the mesh's attributes, scaled by its weight.
#[derive(Clone, Debug, PartialEq)]
pub struct MorphTargetData {
    /// Written to `mesh.extras.targetNames`.
    pub name: String,
    /// Position deltas, one per vertex.
    pub positions: Vec<Vec3>,
    /// Normal deltas, one per vertex, or empty.
    pub normals: Vec<Vec3>,
}

/// A metallic-roughness material.
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialData {
    pub name: String,
    /// Linear RGBA, each component in [0, 1].
    pub base_color: Vec4,
    /// Index into `GltfDocument::images` (sampled with TEXCOORD_0, sRGB-encoded).
    pub base_color_texture: Option<usize>,
    pub metallic: f32,
    pub roughness: f32,
    /// Index into `GltfDocument::images`: roughness in G and metalness in B (linear),
    /// multiplying `roughness` and `metallic`.
    pub metallic_roughness_texture: Option<usize>,
    /// Index into `GltfDocument::images`: tangent-space normals (linear, glTF's
    /// convention: x along +u, y along -v), written with scale 1.
    pub normal_texture: Option<usize>,
    /// Emitted radiance in W/(sr m^2); written as emissiveFactor x emissiveStrength.
    pub emissive: Vec3,
    /// KHR_materials_transmission factor (written only when not 0).
    pub transmission: f32,
    /// KHR_materials_ior (written only when not 1.5).
    pub ior: f32,
    pub double_sided: bool,
}

/// An image stored as PNG bytes inside the binary buffer.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageData {
    pub name: String,
    pub png: Vec<u8>,
}

/// A perspective camera with an infinite far plane and the film's aspect ratio.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraData {
    pub name: String,
    /// Vertical field of view in radians.
    pub yfov: f32,
    pub znear: f32,
}

/// A node with a translation-rotation-scale transform.
#[derive(Clone, Debug, PartialEq)]
pub struct NodeData {
    pub name: String,
    pub translation: Vec3,
    pub rotation: Quat,
    pub scale: Vec3,
    /// Index into `GltfDocument::meshes`.
    pub mesh: Option<usize>,
    /// Index into `GltfDocument::cameras`.
    pub camera: Option<usize>,
    /// Index into `GltfDocument::skins`; the node's mesh must then carry joints and weights.
    /// (glTF ignores the transform of a node showing a skinned mesh: make it a root with
    /// the identity transform.)
    pub skin: Option<usize>,
    /// Indices into `GltfDocument::nodes`.
    pub children: Vec<usize>,
}

/// A skin: the joint nodes that deform skinned meshes, with their inverse bind matrices.
#[derive(Clone, Debug, PartialEq)]
pub struct SkinData {
    pub name: String,
    /// Node index of each joint, no node twice; `MeshData::joints` index into this list.
    pub joints: Vec<usize>,
    /// One per joint: the inverse of the joint's world matrix in the bind pose. The fourth
    /// row must be exactly (0, 0, 0, 1) (invert an `Affine3A` to get that).
    pub inverse_bind_matrices: Vec<Mat4>,
    /// The common root of the joints, or an ancestor of it.
    pub skeleton: Option<usize>,
}

/// A named clip: channels played together, each with its own sampler.
#[derive(Clone, Debug, PartialEq)]
pub struct AnimationData {
    pub name: String,
    pub channels: Vec<ChannelData>,
}

/// One animated property of one node and its keyframes.
#[derive(Clone, Debug, PartialEq)]
pub struct ChannelData {
    /// Index into `GltfDocument::nodes`.
    pub node: usize,
    pub property: AnimatedProperty,
    pub interpolation: Interpolation,
    /// Keyframe times in seconds: finite, >= 0 and strictly increasing.
    pub times: Vec<f32>,
    /// Output values flattened exactly as `model::AnimationSampler::values` holds them:
    /// per keyframe 3 floats (translation, scale), 4 (rotation, x y z w; unit quaternions
    /// for LINEAR and STEP) or one per morph target (weights); CUBICSPLINE stores
    /// (in-tangent, value, out-tangent) per keyframe.
    pub values: Vec<f32>,
}

/// Everything one glTF file holds; indices refer into the sibling vectors.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GltfDocument {
    pub meshes: Vec<MeshData>,
    pub materials: Vec<MaterialData>,
    pub images: Vec<ImageData>,
    pub cameras: Vec<CameraData>,
    pub nodes: Vec<NodeData>,
    /// Root nodes of the file's single scene.
    pub roots: Vec<usize>,
    pub skins: Vec<SkinData>,
    pub animations: Vec<AnimationData>,
}

impl MaterialData {
    /// A Lambertian material (metallic 0, roughness 1, no emission, opaque).
    pub fn lambertian(name: &str, albedo: Vec3) -> Self {
        MaterialData {
            name: name.to_owned(),
            base_color: albedo.extend(1.0),
            base_color_texture: None,
            metallic: 0.0,
            roughness: 1.0,
            metallic_roughness_texture: None,
            normal_texture: None,
            emissive: Vec3::ZERO,
            transmission: 0.0,
            ior: 1.5,
            double_sided: false,
        }
    }
}

impl NodeData {
    /// A node with the identity transform and nothing attached.
    pub fn named(name: &str) -> Self {
        NodeData {
            name: name.to_owned(),
            translation: Vec3::ZERO,
            rotation: Quat::IDENTITY,
            scale: Vec3::ONE,
            mesh: None,
            camera: None,
            skin: None,
            children: Vec::new(),
        }
    }

    /// A node with the identity transform showing mesh `mesh`.
    pub fn with_mesh(name: &str, mesh: usize) -> Self {
        NodeData {
            mesh: Some(mesh),
            ..NodeData::named(name)
        }
    }
}

impl GltfDocument {
    /// Adds `mesh` (with its material) and a node showing it as a new root; returns the node.
    pub fn add_mesh_node(&mut self, mut mesh: MeshData, material: MaterialData) -> usize {
        mesh.material = self.materials.len();
        self.materials.push(material);
        let node = NodeData::with_mesh(&mesh.name, self.meshes.len());
        self.meshes.push(mesh);
        self.nodes.push(node);
        self.roots.push(self.nodes.len() - 1);
        self.nodes.len() - 1
    }

    /// Total triangle count over all meshes (not instanced).
    pub fn triangle_count(&self) -> usize {
        self.meshes.iter().map(|mesh| mesh.indices.len()).sum()
    }
}

// ---- mesh shapes --------------------------------------------------------------------------

impl MeshData {
    /// An empty mesh using material `material`.
    pub fn new(name: &str, material: usize) -> Self {
        MeshData {
            name: name.to_owned(),
            positions: Vec::new(),
            normals: Vec::new(),
            uvs: Vec::new(),
            indices: Vec::new(),
            material,
            joints: Vec::new(),
            weights: Vec::new(),
            morph_targets: Vec::new(),
            morph_weights: Vec::new(),
        }
    }

    /// Appends a flat-shaded convex planar polygon (fan-triangulated) given counter-clockwise
    /// as seen from the side its normal faces. UVs are the planar coordinates in metres:
    /// u along the first edge, v downwards (against the in-plane "up").
    pub fn push_polygon(&mut self, corners: &[Vec3]) {
        if corners.len() < 3 {
            return;
        }
        let normal = newell_normal(corners);
        let right = (corners[1] - corners[0]).normalize_or_zero();
        let up = normal.cross(right);
        let planar = |p: Vec3| Vec2::new((p - corners[0]).dot(right), (p - corners[0]).dot(up));
        let top = corners
            .iter()
            .map(|&p| planar(p).y)
            .fold(f32::NEG_INFINITY, f32::max);
        let first = self.positions.len() as u32;
        for &corner in corners {
            let uv = planar(corner);
            self.positions.push(corner);
            self.normals.push(normal);
            self.uvs.push(Vec2::new(uv.x, top - uv.y));
        }
        for i in 1..corners.len() as u32 - 1 {
            self.indices.push([first, first + i, first + i + 1]);
        }
    }

    /// One flat quad; `corners` are counter-clockwise as seen from the front.
    pub fn quad(name: &str, corners: [Vec3; 4], material: usize) -> Self {
        let mut mesh = MeshData::new(name, material);
        mesh.push_polygon(&corners);
        mesh
    }

    /// An axis-aligned box from `min` to `max` with outward per-face normals and UVs in
    /// metres, each face's UVs starting at 0 at its top-left corner seen from outside.
    pub fn cuboid(name: &str, min: Vec3, max: Vec3, material: usize) -> Self {
        let centre = (min + max) * 0.5;
        let half = (max - min) * 0.5;
        // (outward normal, right, up) as seen from outside; right x up = normal.
        let faces = [
            (Vec3::X, Vec3::NEG_Z, Vec3::Y),
            (Vec3::NEG_X, Vec3::Z, Vec3::Y),
            (Vec3::Y, Vec3::X, Vec3::NEG_Z),
            (Vec3::NEG_Y, Vec3::X, Vec3::Z),
            (Vec3::Z, Vec3::X, Vec3::Y),
            (Vec3::NEG_Z, Vec3::NEG_X, Vec3::Y),
        ];
        let mut mesh = MeshData::new(name, material);
        for (normal, right, up) in faces {
            let face_centre = centre + normal * half;
            let (r, u) = (right * half, up * half);
            mesh.push_polygon(&[
                face_centre - r - u,
                face_centre + r - u,
                face_centre + r + u,
                face_centre - r + u,
            ]);
        }
        mesh
    }

    /// A closed cylinder around +Y from y = 0 to `height`: smooth sides (the seam vertices
    /// are duplicated so u runs 0..circumference in metres) and flat fan-triangulated caps.
    pub fn cylinder(name: &str, radius: f32, height: f32, segments: u32, material: usize) -> Self {
        let segments = segments.max(3);
        let point = |i: u32| {
            // Trig in f64, rounded to f32: the same bits whether or not the optimiser folds it,
            // which keeps the committed assets byte-identical across build profiles.
            let angle = std::f64::consts::TAU * f64::from(i % segments) / f64::from(segments);
            Vec3::new(angle.sin() as f32, 0.0, angle.cos() as f32)
        };
        let mut mesh = MeshData::new(name, material);
        let circumference = std::f32::consts::TAU * radius;
        for i in 0..=segments {
            let direction = point(i);
            let u = circumference * i as f32 / segments as f32;
            for (y, v) in [(0.0, height), (height, 0.0)] {
                mesh.positions.push(direction * radius + Vec3::Y * y);
                mesh.normals.push(direction);
                mesh.uvs.push(Vec2::new(u, v));
            }
        }
        for i in 0..segments {
            // Columns i and i + 1, each (bottom, top); the angle grows to the right seen from outside.
            let (bottom_left, top_left, bottom_right, top_right) =
                (2 * i, 2 * i + 1, 2 * i + 2, 2 * i + 3);
            mesh.indices.push([bottom_left, bottom_right, top_right]);
            mesh.indices.push([bottom_left, top_right, top_left]);
        }
        let rim: Vec<Vec3> = (0..segments).map(|i| point(i) * radius).collect();
        let top: Vec<Vec3> = rim.iter().map(|&p| p + Vec3::Y * height).collect();
        let bottom: Vec<Vec3> = rim.iter().rev().copied().collect();
        mesh.push_polygon(&top);
        mesh.push_polygon(&bottom);
        mesh
    }

    /// A flat-shaded convex solid: each face lists indices into `vertices` and may be given
    /// in either winding; it is oriented away from the centroid of `vertices`. Faces may be
    /// omitted (e.g. a block's hidden bottom); the centroid must still lie inside.
    pub fn convex_solid(
        name: &str,
        vertices: &[Vec3],
        faces: &[&[usize]],
        material: usize,
    ) -> anyhow::Result<Self> {
        ensure!(
            !vertices.is_empty(),
            "convex solid '{name}' has no vertices"
        );
        let centroid = vertices.iter().copied().sum::<Vec3>() / vertices.len() as f32;
        let mut mesh = MeshData::new(name, material);
        for (face_index, face) in faces.iter().enumerate() {
            let mut corners = face
                .iter()
                .map(|&i| vertices.get(i).copied())
                .collect::<Option<Vec<Vec3>>>()
                .with_context(|| {
                    format!(
                        "face {face_index} of convex solid '{name}' names a vertex out of range"
                    )
                })?;
            ensure!(
                corners.len() >= 3,
                "face {face_index} of convex solid '{name}' has fewer than 3 corners"
            );
            let face_centre = corners.iter().copied().sum::<Vec3>() / corners.len() as f32;
            if newell_normal(&corners).dot(face_centre - centroid) < 0.0 {
                corners.reverse();
            }
            mesh.push_polygon(&corners);
        }
        Ok(mesh)
    }

    /// Multiplies every UV by `scale` (e.g. 0.25 so a 4 m face spans the texture once).
    pub fn scale_uvs(mut self, scale: f32) -> Self {
        self.uvs.iter_mut().for_each(|uv| *uv *= scale);
        self
    }
}

/// Per-vertex glTF tangents (xyz unit and orthogonal to the vertex normal, w = +-1 so that
/// the bitangent normal x tangent x w runs along -v, glTF's "up" in a texture) for a mesh
/// with UVs: the area-weighted sum of its triangles' dP/du, made orthogonal to the normal.
/// The kit's flat faces have their own vertices, so there each vertex's tangent is its
/// face's, exactly what the renderer works out per triangle (`accel::SurfaceHit::tangent`).
pub fn vertex_tangents(mesh: &MeshData) -> Vec<Vec4> {
    let count = mesh.positions.len();
    let mut along_u = vec![Vec3::ZERO; count];
    let mut along_v = vec![Vec3::ZERO; count];
    for triangle in &mesh.indices {
        let [a, b, c] = triangle.map(|i| i as usize);
        let (e1, e2) = (
            mesh.positions[b] - mesh.positions[a],
            mesh.positions[c] - mesh.positions[a],
        );
        let (d1, d2) = (mesh.uvs[b] - mesh.uvs[a], mesh.uvs[c] - mesh.uvs[a]);
        // Unnormalised by the UV area's size, so each triangle weighs by its world area.
        let sign = d1.perp_dot(d2).signum();
        let dp_du = (e1 * d2.y - e2 * d1.y) * sign;
        let dp_dv = (e2 * d1.x - e1 * d2.x) * sign;
        for vertex in [a, b, c] {
            along_u[vertex] += dp_du;
            along_v[vertex] += dp_dv;
        }
    }
    (0..count)
        .map(|vertex| {
            let normal = mesh.normals[vertex].normalize_or(Vec3::Z);
            let tangent = along_u[vertex] - normal * normal.dot(along_u[vertex]);
            // A vertex on degenerate UVs only: any direction across the normal.
            let tangent = tangent
                .try_normalize()
                .unwrap_or_else(|| normal.any_orthonormal_vector());
            let w = if normal.cross(tangent).dot(-along_v[vertex]) >= 0.0 {
                1.0
            } else {
                -1.0
            };
            tangent.extend(w)
        })
        .collect()
}

/// Unit normal of a planar polygon by Newell's method (counter-clockwise = front).
fn newell_normal(corners: &[Vec3]) -> Vec3 {
    let mut normal = Vec3::ZERO;
    for (i, &a) in corners.iter().enumerate() {
        let b = corners[(i + 1) % corners.len()];
        normal += Vec3::new(
            (a.y - b.y) * (a.z + b.z),
            (a.z - b.z) * (a.x + b.x),
            (a.x - b.x) * (a.y + b.y),
        );
    }
    normal.normalize_or_zero()
}

// ---- writing ------------------------------------------------------------------------------

/// Writes `document` to `path`: a `.glb`, or a pretty-printed `.gltf` with a sibling
/// `<stem>.bin`. Parent folders are created; each file is replaced atomically.
pub fn write_gltf(document: &GltfDocument, path: &Path) -> anyhow::Result<()> {
    enum Container {
        Binary,
        Text,
    }
    let container = match path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .as_deref()
    {
        Some("glb") => Container::Binary,
        Some("gltf") => Container::Text,
        _ => bail!(
            "cannot write glTF to '{}': the file name must end in .gltf or .glb",
            path.display()
        ),
    };
    validate(document).with_context(|| format!("cannot write '{}'", path.display()))?;
    let (mut root, buffer) = build_root_and_buffer(document)?;
    let mut buffer_entry = |uri: Option<String>| {
        if !buffer.is_empty() {
            root.push(json::Buffer {
                byte_length: buffer.len().into(),
                name: None,
                uri,
                extensions: None,
                extras: None,
            });
        }
    };
    match container {
        Container::Binary => {
            buffer_entry(None);
            let glb = Glb {
                header: gltf::binary::Header {
                    magic: *b"glTF",
                    version: 2,
                    // Glb::to_writer computes the length from the chunks it pads.
                    length: 0,
                },
                json: Cow::Owned(root.to_vec()?),
                bin: (!buffer.is_empty()).then_some(Cow::Borrowed(&buffer[..])),
            };
            let bytes = glb.to_vec()?;
            // Glb::to_writer truncates the lengths it writes to u32.
            ensure!(
                u32::try_from(bytes.len()).is_ok(),
                "cannot write '{}': GLB files are limited to 4 GiB",
                path.display()
            );
            write_atomically(path, &bytes)
        }
        Container::Text => {
            let stem = path
                .file_stem()
                .and_then(|s| s.to_str())
                .unwrap_or("buffer");
            let bin_name = format!("{stem}.bin");
            if !buffer.is_empty() {
                write_atomically(&path.with_file_name(&bin_name), &buffer)?;
            }
            buffer_entry(Some(percent_encode(&bin_name)));
            let mut text = root.to_string_pretty()?;
            text.push('\n');
            write_atomically(path, text.as_bytes())
        }
    }
}

/// Checks every index and value the JSON would otherwise carry wrongly.
fn validate(document: &GltfDocument) -> anyhow::Result<()> {
    for mesh in &document.meshes {
        let name = &mesh.name;
        let vertex_count = mesh.positions.len();
        ensure!(
            vertex_count > 0 && !mesh.indices.is_empty(),
            "mesh '{name}' has no triangles"
        );
        ensure!(
            u32::try_from(vertex_count).is_ok(),
            "mesh '{name}' has more vertices than u32 indices can address"
        );
        ensure!(
            mesh.normals.len() == vertex_count,
            "mesh '{name}' has {} normals for {vertex_count} positions",
            mesh.normals.len()
        );
        ensure!(
            mesh.uvs.is_empty() || mesh.uvs.len() == vertex_count,
            "mesh '{name}' has {} UVs for {vertex_count} positions",
            mesh.uvs.len()
        );
        ensure!(
            mesh.positions
                .iter()
                .chain(&mesh.normals)
                .all(|v| v.is_finite()),
            "mesh '{name}' has a non-finite position or normal"
        );
        ensure!(
            mesh.uvs.iter().all(|uv| uv.is_finite()),
            "mesh '{name}' has a non-finite UV"
        );
        ensure!(
            mesh.indices
                .iter()
                .flatten()
                .all(|&i| (i as usize) < vertex_count),
            "mesh '{name}' has an index past its {vertex_count} vertices"
        );
        ensure!(
            mesh.material < document.materials.len(),
            "mesh '{name}' uses material {} which does not exist",
            mesh.material
        );
        validate_skinning(mesh)?;
        validate_morph_targets(mesh)?;
    }
    for material in &document.materials {
        let name = &material.name;
        let in_unit = |x: f32| (0.0..=1.0).contains(&x);
        ensure!(
            material.base_color.to_array().into_iter().all(in_unit),
            "material '{name}': base colour must lie in [0, 1]"
        );
        ensure!(
            in_unit(material.metallic)
                && in_unit(material.roughness)
                && in_unit(material.transmission),
            "material '{name}': metallic, roughness and transmission must lie in [0, 1]"
        );
        ensure!(
            material.emissive.is_finite() && material.emissive.min_element() >= 0.0,
            "material '{name}': emission must be finite and >= 0"
        );
        ensure!(
            material.ior.is_finite() && material.ior >= 1.0,
            "material '{name}': ior must be at least 1"
        );
        for image in [
            material.base_color_texture,
            material.metallic_roughness_texture,
            material.normal_texture,
        ]
        .into_iter()
        .flatten()
        {
            ensure!(
                image < document.images.len(),
                "material '{name}' uses image {image} which does not exist"
            );
        }
    }
    for image in &document.images {
        ensure!(
            image.png.starts_with(b"\x89PNG\r\n\x1a\n"),
            "image '{}' is not PNG data",
            image.name
        );
    }
    for camera in &document.cameras {
        ensure!(
            camera.yfov > 0.0
                && camera.yfov < std::f32::consts::PI
                && camera.znear > 0.0
                && camera.znear.is_finite(),
            "camera '{}': yfov must lie in (0, pi) and znear must be positive",
            camera.name
        );
    }
    for node in &document.nodes {
        let name = &node.name;
        ensure!(
            node.translation.is_finite() && node.rotation.is_finite() && node.scale.is_finite(),
            "node '{name}' has a non-finite transform"
        );
        ensure!(
            node.mesh.is_none_or(|m| m < document.meshes.len()),
            "node '{name}' shows a mesh that does not exist"
        );
        ensure!(
            node.camera.is_none_or(|c| c < document.cameras.len()),
            "node '{name}' holds a camera that does not exist"
        );
        ensure!(
            node.children.iter().all(|&c| c < document.nodes.len()),
            "node '{name}' has a child that does not exist"
        );
        let mesh = node.mesh.map(|m| &document.meshes[m]);
        match (node.skin, mesh) {
            (Some(skin), Some(mesh)) => {
                let skin = document.skins.get(skin).with_context(|| {
                    format!("node '{name}' uses skin {skin} which does not exist")
                })?;
                ensure!(
                    !mesh.joints.is_empty(),
                    "node '{name}' has skin '{}' but its mesh '{}' has no joints and weights",
                    skin.name,
                    mesh.name
                );
                if let Some(joint) = mesh
                    .joints
                    .iter()
                    .flatten()
                    .find(|&&j| usize::from(j) >= skin.joints.len())
                {
                    bail!(
                        "mesh '{}' (on node '{name}') names joint {joint} but skin '{}' has only {} joints",
                        mesh.name,
                        skin.name,
                        skin.joints.len()
                    );
                }
            }
            (Some(_), None) => bail!("node '{name}' has a skin but no mesh"),
            (None, Some(mesh)) => ensure!(
                mesh.joints.is_empty(),
                "node '{name}' shows the skinned mesh '{}' without a skin",
                mesh.name
            ),
            (None, None) => {}
        }
    }
    ensure!(
        document.roots.iter().all(|&r| r < document.nodes.len()),
        "a scene root names a node that does not exist"
    );
    validate_skins(document)?;
    for animation in &document.animations {
        validate_animation(document, animation)?;
    }
    Ok(())
}

/// JOINTS_0 / WEIGHTS_0: one set per vertex (or none), weights normalised, no joint twice.
fn validate_skinning(mesh: &MeshData) -> anyhow::Result<()> {
    let name = &mesh.name;
    let vertex_count = mesh.positions.len();
    ensure!(
        mesh.joints.len() == mesh.weights.len()
            && (mesh.joints.is_empty() || mesh.joints.len() == vertex_count),
        "mesh '{name}' has {} joint sets and {} weight sets for {vertex_count} vertices (both must be empty or one per vertex)",
        mesh.joints.len(),
        mesh.weights.len()
    );
    for (vertex, (joints, weights)) in mesh.joints.iter().zip(&mesh.weights).enumerate() {
        ensure!(
            weights.iter().all(|w| w.is_finite() && *w >= 0.0),
            "mesh '{name}': vertex {vertex} has a negative or non-finite skin weight {weights:?}"
        );
        let sum: f32 = weights.iter().sum();
        ensure!(
            (sum - 1.0).abs() <= 1e-3,
            "mesh '{name}': the skin weights of vertex {vertex} sum to {sum}, not 1 (glTF requires normalised weights)"
        );
        for a in 0..4 {
            for b in a + 1..4 {
                ensure!(
                    !(joints[a] == joints[b] && weights[a] > 0.0 && weights[b] > 0.0),
                    "mesh '{name}': vertex {vertex} gives joint {} two non-zero weights",
                    joints[a]
                );
            }
        }
    }
    Ok(())
}

/// Morph targets: one delta per vertex, finite, one default weight per target.
fn validate_morph_targets(mesh: &MeshData) -> anyhow::Result<()> {
    let name = &mesh.name;
    let vertex_count = mesh.positions.len();
    ensure!(
        mesh.morph_weights.len() == mesh.morph_targets.len(),
        "mesh '{name}' has {} default morph weights for {} morph targets",
        mesh.morph_weights.len(),
        mesh.morph_targets.len()
    );
    ensure!(
        mesh.morph_weights.iter().all(|w| w.is_finite()),
        "mesh '{name}' has a non-finite default morph weight"
    );
    for target in &mesh.morph_targets {
        let target_name = &target.name;
        ensure!(
            target.positions.len() == vertex_count,
            "morph target '{target_name}' of mesh '{name}' has {} position deltas for {vertex_count} vertices",
            target.positions.len()
        );
        ensure!(
            target.normals.is_empty() || target.normals.len() == vertex_count,
            "morph target '{target_name}' of mesh '{name}' has {} normal deltas for {vertex_count} vertices",
            target.normals.len()
        );
        ensure!(
            target
                .positions
                .iter()
                .chain(&target.normals)
                .all(|v| v.is_finite()),
            "morph target '{target_name}' of mesh '{name}' has a non-finite delta"
        );
    }
    Ok(())
}

/// Skins: existing, distinct joints (in the scene when the skin is), one affine inverse
/// bind matrix each, and a skeleton root that is an ancestor (or itself) of every joint.
fn validate_skins(document: &GltfDocument) -> anyhow::Result<()> {
    let node_count = document.nodes.len();
    let mut parent = vec![None; node_count];
    for (index, node) in document.nodes.iter().enumerate() {
        for &child in &node.children {
            parent[child] = Some(index);
        }
    }
    // Nodes in the scene: reachable from the roots (visited once each, so cycles end).
    let mut in_scene = vec![false; node_count];
    let mut stack = document.roots.clone();
    while let Some(node) = stack.pop() {
        if !std::mem::replace(&mut in_scene[node], true) {
            stack.extend(&document.nodes[node].children);
        }
    }
    for (skin_index, skin) in document.skins.iter().enumerate() {
        let name = &skin.name;
        ensure!(!skin.joints.is_empty(), "skin '{name}' has no joints");
        let mut seen = BTreeSet::new();
        for &joint in &skin.joints {
            ensure!(
                joint < node_count,
                "skin '{name}' names joint node {joint} which does not exist"
            );
            ensure!(
                seen.insert(joint),
                "skin '{name}' lists node '{}' twice",
                document.nodes[joint].name
            );
        }
        ensure!(
            skin.inverse_bind_matrices.len() == skin.joints.len(),
            "skin '{name}' has {} inverse bind matrices for {} joints",
            skin.inverse_bind_matrices.len(),
            skin.joints.len()
        );
        for (index, matrix) in skin.inverse_bind_matrices.iter().enumerate() {
            ensure!(
                matrix.is_finite() && matrix.row(3) == Vec4::W,
                "skin '{name}': inverse bind matrix {index} is not finite or its fourth row is not exactly (0, 0, 0, 1)"
            );
        }
        let used_in_scene = document
            .nodes
            .iter()
            .zip(&in_scene)
            .any(|(node, &shown)| shown && node.skin == Some(skin_index));
        if used_in_scene && let Some(&joint) = skin.joints.iter().find(|&&j| !in_scene[j]) {
            bail!(
                "skin '{name}' is used in the scene but its joint '{}' is not in the scene (make the joints' root a scene root)",
                document.nodes[joint].name
            );
        }
        if let Some(skeleton) = skin.skeleton {
            ensure!(
                skeleton < node_count,
                "skin '{name}' names skeleton node {skeleton} which does not exist"
            );
            for &joint in &skin.joints {
                // Walk up at most node_count steps (a cycle must not hang the writer).
                let mut current = Some(joint);
                let mut steps = 0;
                while let Some(node) = current
                    && node != skeleton
                    && steps <= node_count
                {
                    current = parent[node];
                    steps += 1;
                }
                ensure!(
                    current == Some(skeleton),
                    "skin '{name}': joint '{}' is not under the skeleton root '{}'",
                    document.nodes[joint].name,
                    document.nodes[skeleton].name
                );
            }
        }
    }
    Ok(())
}

/// glTF's `target.path` for an animated property.
fn property_path(property: AnimatedProperty) -> &'static str {
    match property {
        AnimatedProperty::Translation => "translation",
        AnimatedProperty::Rotation => "rotation",
        AnimatedProperty::Scale => "scale",
        AnimatedProperty::MorphWeights => "weights",
    }
}

/// Floats per keyframe element of `channel` (3, 4, or the morph-target count of the
/// node's mesh); errors when a weights channel's node has no morph targets.
fn channel_components(document: &GltfDocument, channel: &ChannelData) -> anyhow::Result<usize> {
    Ok(match channel.property {
        AnimatedProperty::Translation | AnimatedProperty::Scale => 3,
        AnimatedProperty::Rotation => 4,
        AnimatedProperty::MorphWeights => {
            let node = &document.nodes[channel.node];
            let targets = node
                .mesh
                .map_or(0, |mesh| document.meshes[mesh].morph_targets.len());
            ensure!(
                targets > 0,
                "animates the morph weights of node '{}', whose mesh has no morph targets",
                node.name
            );
            targets
        }
    })
}

/// One animation: existing nodes, each (node, property) once, valid keyframes and values.
fn validate_animation(document: &GltfDocument, animation: &AnimationData) -> anyhow::Result<()> {
    let name = &animation.name;
    ensure!(
        !animation.channels.is_empty(),
        "animation '{name}' has no channels"
    );
    let mut animated = BTreeSet::new();
    for (index, channel) in animation.channels.iter().enumerate() {
        let path = property_path(channel.property);
        let node = document.nodes.get(channel.node).with_context(|| {
            format!(
                "animation '{name}', channel {index}: node {} does not exist",
                channel.node
            )
        })?;
        let what = format!(
            "animation '{name}', channel {index} ({path} of node '{}')",
            node.name
        );
        ensure!(
            animated.insert((channel.node, path)),
            "{what}: the node's {path} is already animated by an earlier channel"
        );
        let components = channel_components(document, channel).with_context(|| what.clone())?;
        let keys = channel.times.len();
        let cubic = channel.interpolation == Interpolation::CubicSpline;
        ensure!(
            keys >= if cubic { 2 } else { 1 },
            "{what} has {keys} keyframes (at least {} needed)",
            if cubic { 2 } else { 1 }
        );
        ensure!(
            channel.times.iter().all(|t| t.is_finite() && *t >= 0.0)
                && channel.times.windows(2).all(|w| w[0] < w[1]),
            "{what}: keyframe times must be finite, >= 0 and strictly increasing"
        );
        let per_key = components * if cubic { 3 } else { 1 };
        ensure!(
            channel.values.len() == keys * per_key,
            "{what}: {} values for {keys} keyframes, expected {} ({per_key} per keyframe)",
            channel.values.len(),
            keys * per_key
        );
        ensure!(
            channel.values.iter().all(|v| v.is_finite()),
            "{what} has a non-finite value"
        );
        if channel.property == AnimatedProperty::Rotation && !cubic {
            for (key, quat) in channel.values.chunks_exact(4).enumerate() {
                let length = Vec4::from_slice(quat).length();
                ensure!(
                    (length - 1.0).abs() <= 1e-4,
                    "{what}: keyframe {key} is not a unit quaternion (length {length})"
                );
            }
        }
    }
    Ok(())
}

/// An accessor's `min`/`max`: serde_json widens an `f32` inside a `Value` to `f64`
/// (0.1 would be written 0.10000000149011612), so each bound goes through its shortest f32
/// decimal, which reads back as exactly the bound.
fn bound_values(values: &[f32]) -> Value {
    Value::Array(
        values
            .iter()
            .map(|x| {
                x.to_string()
                    .parse::<f64>()
                    .ok()
                    .and_then(serde_json::Number::from_f64)
                    .map_or(Value::Null, Value::Number)
            })
            .collect(),
    )
}

/// A glTF index for position `i` of one of the document's vectors.
fn index<T>(i: usize) -> Index<T> {
    // Rule: validate() has checked every reference against the length of a Vec in memory,
    // and no Vec of meshes, nodes or accessors comes near 2^32 entries.
    Index::new(u32::try_from(i).expect("a glTF index fits in u32"))
}

/// The document's JSON root under construction and the one binary buffer its buffer views
/// cut up.
struct Builder {
    root: Root,
    bytes: Vec<u8>,
}

impl Builder {
    /// Appends `data` at a 4-byte aligned offset as a new buffer view.
    fn push_view(&mut self, data: &[u8], target: Option<buffer::Target>) -> Index<buffer::View> {
        self.pad();
        let view = buffer::View {
            buffer: Index::new(0),
            byte_length: data.len().into(),
            byte_offset: Some(self.bytes.len().into()),
            byte_stride: None,
            name: None,
            target: target.map(Valid),
            extensions: None,
            extras: None,
        };
        self.bytes.extend_from_slice(data);
        self.root.push(view)
    }

    /// Appends `bytes` as a view and an accessor reading `count` elements of `type_` from it.
    fn push_accessor(
        &mut self,
        bytes: &[u8],
        count: usize,
        (component_type, type_): (ComponentType, accessor::Type),
        target: Option<buffer::Target>,
        bounds: Option<(Value, Value)>,
    ) -> Index<Accessor> {
        let view = self.push_view(bytes, target);
        let (min, max) = bounds.unzip();
        self.root.push(Accessor {
            buffer_view: Some(view),
            byte_offset: None,
            count: count.into(),
            component_type: Valid(accessor::GenericComponentType(component_type)),
            extensions: None,
            extras: None,
            type_: Valid(type_),
            min,
            max,
            name: None,
            normalized: false,
            sparse: None,
        })
    }

    /// Appends tightly packed floats, `components` per element (1 SCALAR, 2 VEC2, 3 VEC3,
    /// 4 VEC4, 16 MAT4), with per-component `min`/`max` when `bounds` is set.
    fn push_floats(
        &mut self,
        flat: &[f32],
        components: usize,
        target: Option<buffer::Target>,
        bounds: bool,
    ) -> Index<Accessor> {
        let type_ = match components {
            1 => accessor::Type::Scalar,
            2 => accessor::Type::Vec2,
            3 => accessor::Type::Vec3,
            4 => accessor::Type::Vec4,
            16 => accessor::Type::Mat4,
            _ => unreachable!("no glTF float accessor has {components} components"),
        };
        let bounds = bounds.then(|| {
            let mut min = vec![f32::INFINITY; components];
            let mut max = vec![f32::NEG_INFINITY; components];
            for element in flat.chunks_exact(components) {
                for (i, &x) in element.iter().enumerate() {
                    min[i] = min[i].min(x);
                    max[i] = max[i].max(x);
                }
            }
            (bound_values(&min), bound_values(&max))
        });
        let bytes: Vec<u8> = flat.iter().flat_map(|x| x.to_le_bytes()).collect();
        let count = flat.len() / components;
        self.push_accessor(&bytes, count, (ComponentType::F32, type_), target, bounds)
    }

    /// Appends a VEC3 vertex attribute (with bounds for POSITION, which glTF requires).
    fn push_vec3s(&mut self, vectors: &[Vec3], bounds: bool) -> Index<Accessor> {
        let flat: Vec<f32> = vectors.iter().flat_map(|v| v.to_array()).collect();
        self.push_floats(&flat, 3, Some(buffer::Target::ArrayBuffer), bounds)
    }

    fn pad(&mut self) {
        self.bytes.resize(self.bytes.len().next_multiple_of(4), 0);
    }
}

/// The glTF JSON root of `document` and its binary buffer (without a `buffers` entry: the
/// container decides where the buffer lives).
fn build_root_and_buffer(document: &GltfDocument) -> anyhow::Result<(Root, Vec<u8>)> {
    let mut builder = Builder {
        root: Root::default(),
        bytes: Vec::new(),
    };
    for mesh in &document.meshes {
        let normal_mapped = document
            .materials
            .get(mesh.material)
            .is_some_and(|material| material.normal_texture.is_some());
        let primitive = build_primitive(&mut builder, mesh, normal_mapped);
        let (weights, extras) = if mesh.morph_targets.is_empty() {
            (None, None)
        } else {
            // glTF has no field for target names; `extras.targetNames` is the convention
            // Blender and three.js read.
            let names: Vec<&str> = mesh.morph_targets.iter().map(|t| t.name.as_str()).collect();
            let extras = serde_json::value::to_raw_value(&json!({ "targetNames": names }))?;
            (Some(mesh.morph_weights.clone()), Some(extras))
        };
        builder.root.push(json::Mesh {
            extensions: None,
            extras,
            name: Some(mesh.name.clone()),
            primitives: vec![primitive],
            weights,
        });
    }

    for image in &document.images {
        let view = builder.push_view(&image.png, None);
        let image = builder.root.push(json::Image {
            buffer_view: Some(view),
            mime_type: Some(json::image::MimeType("image/png".into())),
            name: Some(image.name.clone()),
            uri: None,
            extensions: None,
            extras: None,
        });
        builder.root.push(json::Texture {
            name: None,
            sampler: Some(Index::new(0)),
            source: image,
            extensions: None,
            extras: None,
        });
    }
    if !document.images.is_empty() {
        builder.root.push(texture::Sampler {
            mag_filter: Some(Valid(texture::MagFilter::Linear)),
            min_filter: Some(Valid(texture::MinFilter::LinearMipmapLinear)),
            wrap_s: Valid(texture::WrappingMode::Repeat),
            wrap_t: Valid(texture::WrappingMode::Repeat),
            ..Default::default()
        });
    }

    for skin in &document.skins {
        let matrices: Vec<f32> = skin
            .inverse_bind_matrices
            .iter()
            .flat_map(|m| m.to_cols_array())
            .collect();
        let inverse_bind_matrices = builder.push_floats(&matrices, 16, None, false);
        builder.root.push(json::Skin {
            extensions: None,
            extras: None,
            inverse_bind_matrices: Some(inverse_bind_matrices),
            joints: skin.joints.iter().map(|&joint| index(joint)).collect(),
            name: Some(skin.name.clone()),
            skeleton: skin.skeleton.map(index),
        });
    }

    for animation in &document.animations {
        let mut channels = Vec::new();
        let mut samplers = Vec::new();
        for channel in &animation.channels {
            let input = builder.push_floats(&channel.times, 1, None, true);
            // Weights outputs are scalars (targets x keyframes of them); the rest are vectors.
            let components = match channel.property {
                AnimatedProperty::MorphWeights => 1,
                _ => channel_components(document, channel)?,
            };
            let output = builder.push_floats(&channel.values, components, None, false);
            channels.push(animation::Channel {
                sampler: index(samplers.len()),
                target: animation::Target {
                    extensions: None,
                    extras: None,
                    node: index(channel.node),
                    path: Valid(animation_property(channel.property)),
                },
                extensions: None,
                extras: None,
            });
            samplers.push(animation::Sampler {
                extensions: None,
                extras: None,
                input,
                interpolation: Valid(match channel.interpolation {
                    Interpolation::Linear => animation::Interpolation::Linear,
                    Interpolation::Step => animation::Interpolation::Step,
                    Interpolation::CubicSpline => animation::Interpolation::CubicSpline,
                }),
                output,
            });
        }
        builder.root.push(json::Animation {
            extensions: None,
            extras: None,
            channels,
            name: Some(animation.name.clone()),
            samplers,
        });
    }
    builder.pad();

    let mut extensions_used = BTreeSet::new();
    for material in &document.materials {
        let material = build_material(material, &mut extensions_used);
        builder.root.push(material);
    }
    for camera in &document.cameras {
        builder.root.push(json::Camera {
            name: Some(camera.name.clone()),
            orthographic: None,
            perspective: Some(json::camera::Perspective {
                aspect_ratio: None,
                yfov: camera.yfov,
                zfar: None,
                znear: camera.znear,
                extensions: None,
                extras: None,
            }),
            type_: Valid(json::camera::Type::Perspective),
            extensions: None,
            extras: None,
        });
    }
    for node in &document.nodes {
        builder.root.push(build_node(node));
    }

    let root = &mut builder.root;
    root.asset = json::Asset {
        generator: Some("gloam gltf_export".into()),
        ..Default::default()
    };
    root.extensions_used = extensions_used.into_iter().map(str::to_owned).collect();
    let scene = root.push(json::Scene {
        extensions: None,
        extras: None,
        name: None,
        nodes: document.roots.iter().map(|&node| index(node)).collect(),
    });
    root.scene = Some(scene);
    Ok((builder.root, builder.bytes))
}

/// The mesh's one triangle-list primitive, its attributes, indices and morph targets
/// appended to the buffer.
fn build_primitive(builder: &mut Builder, mesh: &MeshData, tangents: bool) -> mesh::Primitive {
    use mesh::Semantic;
    let vertex_data = Some(buffer::Target::ArrayBuffer);
    let mut attributes = BTreeMap::new();
    attributes.insert(
        Valid(Semantic::Positions),
        builder.push_vec3s(&mesh.positions, true),
    );
    attributes.insert(
        Valid(Semantic::Normals),
        builder.push_vec3s(&mesh.normals, false),
    );
    if !mesh.uvs.is_empty() {
        let uvs: Vec<f32> = mesh.uvs.iter().flat_map(|uv| uv.to_array()).collect();
        let accessor = builder.push_floats(&uvs, 2, vertex_data, false);
        attributes.insert(Valid(Semantic::TexCoords(0)), accessor);
        if tangents {
            let tangents: Vec<f32> = vertex_tangents(mesh)
                .iter()
                .flat_map(|t| t.to_array())
                .collect();
            let accessor = builder.push_floats(&tangents, 4, vertex_data, false);
            attributes.insert(Valid(Semantic::Tangents), accessor);
        }
    }
    if !mesh.joints.is_empty() {
        let bytes: Vec<u8> = mesh
            .joints
            .iter()
            .flatten()
            .flat_map(|j| j.to_le_bytes())
            .collect();
        let format = (ComponentType::U16, accessor::Type::Vec4);
        let joints = builder.push_accessor(&bytes, mesh.joints.len(), format, vertex_data, None);
        attributes.insert(Valid(Semantic::Joints(0)), joints);
        let weights: Vec<f32> = mesh.weights.iter().flatten().copied().collect();
        let weights = builder.push_floats(&weights, 4, vertex_data, false);
        attributes.insert(Valid(Semantic::Weights(0)), weights);
    }
    let bytes: Vec<u8> = mesh
        .indices
        .iter()
        .flatten()
        .flat_map(|i| i.to_le_bytes())
        .collect();
    let indices = builder.push_accessor(
        &bytes,
        mesh.indices.len() * 3,
        (ComponentType::U32, accessor::Type::Scalar),
        Some(buffer::Target::ElementArrayBuffer),
        None,
    );
    // Morph deltas are per-vertex data like the attributes, so their views are ARRAY_BUFFERs
    // too; a target's POSITION needs its bounds like the base attribute.
    let targets = (!mesh.morph_targets.is_empty()).then(|| {
        mesh.morph_targets
            .iter()
            .map(|target| mesh::MorphTarget {
                positions: Some(builder.push_vec3s(&target.positions, true)),
                normals: (!target.normals.is_empty())
                    .then(|| builder.push_vec3s(&target.normals, false)),
                tangents: None,
            })
            .collect()
    });
    mesh::Primitive {
        attributes,
        extensions: None,
        extras: None,
        indices: Some(indices),
        material: Some(index(mesh.material)),
        mode: Valid(mesh::Mode::Triangles),
        targets,
    }
}

/// A metallic-roughness material, with the KHR extensions it needs named in `extensions_used`.
fn build_material(
    material: &MaterialData,
    extensions_used: &mut BTreeSet<&'static str>,
) -> json::Material {
    use json::extensions::material as khr;
    use json::material::{EmissiveFactor, PbrBaseColorFactor, StrengthFactor};
    let mut extensions = khr::Material::default();
    let mut emissive_factor = [0.0; 3];
    let strength = material.emissive.max_element();
    if strength > 0.0 {
        // emissiveFactor must lie in [0, 1]; the brightest channel's radiance moves to the strength.
        emissive_factor = (material.emissive / strength).min(Vec3::ONE).to_array();
        if strength > 1.0 {
            extensions.emissive_strength = Some(khr::EmissiveStrength {
                emissive_strength: khr::EmissiveStrengthFactor(strength),
            });
            extensions_used.insert("KHR_materials_emissive_strength");
        }
    }
    if material.transmission != 0.0 {
        extensions.transmission = Some(khr::Transmission {
            transmission_factor: khr::TransmissionFactor(material.transmission),
            transmission_texture: None,
            extras: None,
        });
        extensions_used.insert("KHR_materials_transmission");
    }
    if material.ior != 1.5 {
        extensions.ior = Some(khr::Ior {
            ior: khr::IndexOfRefraction(material.ior),
            extras: None,
        });
        extensions_used.insert("KHR_materials_ior");
    }
    let info = |image: usize| texture::Info {
        index: index(image),
        tex_coord: 0,
        extensions: None,
        extras: None,
    };
    let any_extension = extensions.emissive_strength.is_some()
        || extensions.transmission.is_some()
        || extensions.ior.is_some();
    json::Material {
        name: Some(material.name.clone()),
        double_sided: material.double_sided,
        pbr_metallic_roughness: json::material::PbrMetallicRoughness {
            base_color_factor: PbrBaseColorFactor(material.base_color.to_array()),
            base_color_texture: material.base_color_texture.map(info),
            metallic_factor: StrengthFactor(material.metallic),
            roughness_factor: StrengthFactor(material.roughness),
            metallic_roughness_texture: material.metallic_roughness_texture.map(info),
            ..Default::default()
        },
        normal_texture: material
            .normal_texture
            .map(|image| json::material::NormalTexture {
                index: index(image),
                scale: 1.0,
                tex_coord: 0,
                extensions: None,
                extras: None,
            }),
        emissive_factor: EmissiveFactor(emissive_factor),
        extensions: any_extension.then_some(extensions),
        ..Default::default()
    }
}

fn build_node(node: &NodeData) -> json::Node {
    json::Node {
        name: Some(node.name.clone()),
        translation: (node.translation != Vec3::ZERO).then(|| node.translation.to_array()),
        rotation: (node.rotation != Quat::IDENTITY)
            .then(|| json::scene::UnitQuaternion(node.rotation.to_array())),
        scale: (node.scale != Vec3::ONE).then(|| node.scale.to_array()),
        mesh: node.mesh.map(index),
        camera: node.camera.map(index),
        skin: node.skin.map(index),
        children: (!node.children.is_empty())
            .then(|| node.children.iter().map(|&child| index(child)).collect()),
        ..Default::default()
    }
}

/// glTF's `target.path` for an animated property.
fn animation_property(property: AnimatedProperty) -> animation::Property {
    match property {
        AnimatedProperty::Translation => animation::Property::Translation,
        AnimatedProperty::Rotation => animation::Property::Rotation,
        AnimatedProperty::Scale => animation::Property::Scale,
        AnimatedProperty::MorphWeights => animation::Property::MorphTargetWeights,
    }
}

/// Escapes everything but RFC 3986 unreserved characters, for a relative `uri`.
fn percent_encode(name: &str) -> String {
    name.bytes()
        .map(|b| {
            if b.is_ascii_alphanumeric() || b"-._~".contains(&b) {
                (b as char).to_string()
            } else {
                format!("%{b:02X}")
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::gltf_import::import_gltf;
    use std::path::PathBuf;

    fn unique_temp_dir(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("gloam-gltf-export-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        dir
    }

    /// A small document touching every feature the writer has.
    fn sample_document() -> GltfDocument {
        use image::ImageEncoder as _;
        let mut png = Vec::new();
        let rgba = [
            255, 0, 0, 255, 0, 255, 0, 255, 0, 0, 255, 255, 255, 255, 255, 255,
        ];
        image::codecs::png::PngEncoder::new(&mut png)
            .write_image(&rgba, 2, 2, image::ExtendedColorType::Rgba8)
            .unwrap();
        let glass = MaterialData {
            transmission: 1.0,
            ior: 1.33,
            roughness: 0.0,
            ..MaterialData::lambertian("glass", Vec3::ONE)
        };
        let lamp = MaterialData {
            emissive: Vec3::new(0.5, 8.0, 2.0),
            ..MaterialData::lambertian("lamp", Vec3::splat(0.5))
        };
        let textured = MaterialData {
            base_color_texture: Some(0),
            ..MaterialData::lambertian("textured", Vec3::ONE)
        };
        let mut document = GltfDocument::default();
        document.add_mesh_node(MeshData::cuboid("box", Vec3::ZERO, Vec3::ONE, 0), glass);
        document.add_mesh_node(MeshData::cylinder("can", 0.5, 2.0, 8, 0), lamp);
        document.add_mesh_node(
            MeshData::quad(
                "sign",
                [Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y],
                0,
            ),
            textured,
        );
        document.images.push(ImageData {
            name: "checker".into(),
            png,
        });
        document.cameras.push(CameraData {
            name: "eye".into(),
            yfov: 0.8,
            znear: 0.05,
        });
        document.nodes.push(NodeData {
            camera: Some(0),
            translation: Vec3::new(0.0, 1.0, 5.0),
            rotation: Quat::from_rotation_y(0.3),
            ..NodeData::named("eye")
        });
        document.nodes[0].children.push(3);
        document
    }

    #[test]
    fn writing_twice_gives_identical_bytes() {
        let dir = unique_temp_dir("determinism");
        let document = sample_document();
        for name in ["sample.gltf", "sample.glb"] {
            let path = dir.join(name);
            write_gltf(&document, &path).unwrap();
            let first = std::fs::read(&path).unwrap();
            let first_bin = std::fs::read(dir.join("sample.bin")).ok();
            write_gltf(&document, &path).unwrap();
            assert_eq!(
                first,
                std::fs::read(&path).unwrap(),
                "{name} changed between writes"
            );
            assert_eq!(first_bin, std::fs::read(dir.join("sample.bin")).ok());
        }
        // No temporary files are left behind.
        let leftovers: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(leftovers.len(), 3, "{leftovers:?}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn written_files_import_with_the_same_content() {
        let dir = unique_temp_dir("roundtrip");
        let document = sample_document();
        for name in ["sample.gltf", "sample.glb"] {
            write_gltf(&document, &dir.join(name)).unwrap();
            let asset = import_gltf(&dir.join(name)).unwrap();
            assert_eq!(asset.triangle_count(), document.triangle_count());
            assert_eq!(
                asset.meshes[1].primitives[0].positions,
                document.meshes[1].positions
            );
            assert_eq!(asset.meshes[1].primitives[0].uv0, document.meshes[1].uvs);
            let glass = &asset.materials[asset.material_by_name("glass").unwrap()];
            assert_eq!(
                (
                    glass.transmission,
                    glass.ior,
                    glass.metallic,
                    glass.roughness
                ),
                (1.0, 1.33, 0.0, 0.0)
            );
            let lamp = &asset.materials[asset.material_by_name("lamp").unwrap()];
            assert!(
                (lamp.emissive - Vec3::new(0.5, 8.0, 2.0))
                    .abs()
                    .max_element()
                    < 1e-6,
                "{}",
                lamp.emissive
            );
            let textured = &asset.materials[asset.material_by_name("textured").unwrap()];
            let texture = &asset.textures[textured.base_color_texture.as_ref().unwrap().texture];
            let image = &asset.images[texture.image];
            assert_eq!(
                (image.width, image.height, image.rgba8[1]),
                (2, 2, [0, 255, 0, 255])
            );
            assert_eq!(asset.cameras.len(), 1);
            assert_eq!(asset.nodes[3].name, "eye");
            assert_eq!(asset.nodes[0].children, vec![3]);
            assert_eq!(asset.roots, vec![0, 1, 2]);
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn bad_documents_and_extensions_are_errors_naming_the_path() {
        let dir = unique_temp_dir("errors");
        let error = write_gltf(&sample_document(), &dir.join("sample.obj")).unwrap_err();
        assert!(error.to_string().contains("sample.obj"), "{error}");
        let mut broken = sample_document();
        broken.meshes[0].material = 99;
        let error = write_gltf(&broken, &dir.join("broken.glb")).unwrap_err();
        assert!(
            format!("{error:#}").contains("broken.glb")
                && format!("{error:#}").contains("material 99"),
            "{error:#}"
        );
        assert!(!dir.join("broken.glb").exists());
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// A skinned two-joint tube with a translation/scale/rotation clip, and a morphing
    /// quad with a weights clip.
    fn animated_document() -> GltfDocument {
        let mut document = GltfDocument::default();
        // Nodes 0 and 1: the joints; 2: the skinned mesh; 3: the morphing quad.
        document.nodes.push(NodeData {
            translation: Vec3::new(0.0, 0.5, 0.0),
            children: vec![1],
            ..NodeData::named("root joint")
        });
        document.nodes.push(NodeData {
            translation: Vec3::new(0.0, 1.0, 0.0),
            ..NodeData::named("tip joint")
        });
        let mut tube = MeshData::cylinder("tube", 0.1, 2.0, 6, 0);
        for position in &tube.positions {
            let t = (position.y / 2.0).clamp(0.0, 1.0);
            // glTF: a joint index with zero weight should be 0.
            tube.joints.push([0, if t > 0.0 { 1 } else { 0 }, 0, 0]);
            tube.weights.push([1.0 - t, t, 0.0, 0.0]);
        }
        document.roots.push(0);
        let tube_node =
            document.add_mesh_node(tube, MaterialData::lambertian("grey", Vec3::splat(0.5)));
        document.nodes[tube_node].skin = Some(0);
        document.skins.push(SkinData {
            name: "tube skin".into(),
            joints: vec![0, 1],
            inverse_bind_matrices: vec![
                Mat4::from_translation(Vec3::new(0.0, -0.5, 0.0)),
                Mat4::from_translation(Vec3::new(0.0, -1.5, 0.0)),
            ],
            skeleton: Some(0),
        });
        let mut flag = MeshData::quad(
            "flag",
            [Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y],
            0,
        );
        flag.morph_targets = vec![
            MorphTargetData {
                name: "bulge".into(),
                positions: flag.positions.iter().map(|p| Vec3::Z * p.x * 0.3).collect(),
                normals: vec![Vec3::new(-0.1, 0.0, -0.005); 4],
            },
            MorphTargetData {
                name: "lift".into(),
                positions: vec![Vec3::new(0.0, 0.125, 0.0); 4],
                normals: Vec::new(),
            },
        ];
        flag.morph_weights = vec![0.25, 0.5];
        let flag_node = document.add_mesh_node(flag, MaterialData::lambertian("cloth", Vec3::ONE));
        let half_turn = Quat::from_rotation_z(0.7);
        document.animations = vec![
            AnimationData {
                name: "bend".into(),
                channels: vec![
                    ChannelData {
                        node: 0,
                        property: AnimatedProperty::Translation,
                        interpolation: Interpolation::Linear,
                        times: vec![0.0, 0.5, 1.0],
                        values: vec![0.0, 0.5, 0.0, 0.1, 0.6, 0.0, 0.0, 0.5, 0.0],
                    },
                    ChannelData {
                        node: 1,
                        property: AnimatedProperty::Scale,
                        interpolation: Interpolation::Step,
                        times: vec![0.0, 0.25],
                        values: vec![1.0, 1.0, 1.0, 1.5, 0.75, 1.5],
                    },
                    ChannelData {
                        node: 1,
                        property: AnimatedProperty::Rotation,
                        interpolation: Interpolation::CubicSpline,
                        times: vec![0.0, 1.0 / 3.0],
                        values: [
                            [0.0, 0.0, 0.1, 0.0],
                            Quat::IDENTITY.to_array(),
                            [0.0, 0.0, 0.2, -0.01],
                            [0.0, 0.0, 0.3, 0.0],
                            half_turn.to_array(),
                            [0.0, 0.0, -0.1, 0.05],
                        ]
                        .concat(),
                    },
                ],
            },
            AnimationData {
                name: "flutter".into(),
                channels: vec![ChannelData {
                    node: flag_node,
                    property: AnimatedProperty::MorphWeights,
                    interpolation: Interpolation::Linear,
                    times: vec![0.0, 1.0, 2.0],
                    values: vec![0.0, 0.0, 1.0, -0.5, 0.0, 0.0],
                }],
            },
        ];
        document
    }

    #[test]
    fn skins_morph_targets_and_animations_import_unchanged() {
        let dir = unique_temp_dir("animated");
        let document = animated_document();
        for name in ["animated.gltf", "animated.glb"] {
            let path = dir.join(name);
            write_gltf(&document, &path).unwrap();
            let first = std::fs::read(&path).unwrap();
            write_gltf(&document, &path).unwrap();
            assert_eq!(
                first,
                std::fs::read(&path).unwrap(),
                "{name} is not deterministic"
            );
            let asset = import_gltf(&path).unwrap_or_else(|error| panic!("{name}: {error}"));

            let tube = &document.meshes[0];
            let primitive = &asset.meshes[0].primitives[0];
            assert_eq!(primitive.skin_influences.len(), 1, "{name}");
            assert_eq!(primitive.skin_influences[0].joints, tube.joints, "{name}");
            assert_eq!(primitive.skin_influences[0].weights, tube.weights, "{name}");
            assert!(primitive.morph_targets.is_empty());
            assert_eq!(asset.nodes[2].skin, Some(0));
            assert_eq!(asset.skins.len(), 1);
            let (skin, expected) = (&asset.skins[0], &document.skins[0]);
            assert_eq!(
                (
                    &skin.name,
                    &skin.joints,
                    &skin.inverse_bind_matrices,
                    skin.skeleton
                ),
                (
                    &expected.name,
                    &expected.joints,
                    &expected.inverse_bind_matrices,
                    expected.skeleton
                ),
                "{name}"
            );

            let flag = &document.meshes[1];
            let mesh = &asset.meshes[1];
            assert_eq!(mesh.morph_weights, flag.morph_weights, "{name}");
            assert!(mesh.primitives[0].skin_influences.is_empty());
            let targets = &mesh.primitives[0].morph_targets;
            assert_eq!(targets.len(), 2, "{name}");
            for (imported, written) in targets.iter().zip(&flag.morph_targets) {
                assert_eq!(imported.positions, written.positions, "{name}");
                assert_eq!(imported.normals, written.normals, "{name}");
            }

            assert_eq!(asset.animations.len(), document.animations.len());
            for (imported, written) in asset.animations.iter().zip(&document.animations) {
                assert_eq!(imported.name, written.name);
                assert_eq!(imported.channels.len(), written.channels.len());
                for (channel, expected) in imported.channels.iter().zip(&written.channels) {
                    let sampler = &imported.samplers[channel.sampler];
                    assert_eq!(
                        (channel.node, channel.property, sampler.interpolation),
                        (expected.node, expected.property, expected.interpolation),
                        "{name}: {}",
                        written.name
                    );
                    assert_eq!(sampler.times, expected.times, "{name}: {}", written.name);
                    assert_eq!(sampler.values, expected.values, "{name}: {}", written.name);
                }
            }
            assert_eq!(asset.animations[0].duration(), 1.0);
            assert_eq!(asset.animations[1].samplers[0].components, 2);
        }
        // The text form names the morph targets in the mesh's extras.
        let json: Value =
            serde_json::from_slice(&std::fs::read(dir.join("animated.gltf")).unwrap()).unwrap();
        assert_eq!(
            json["meshes"][1]["extras"]["targetNames"],
            json!(["bulge", "lift"])
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn bad_skins_and_animations_are_errors_naming_the_mesh_or_animation() {
        let dir = unique_temp_dir("animated-errors");
        let path = dir.join("broken.glb");
        let expect_error = |document: &GltfDocument, needles: &[&str]| {
            let error = format!("{:#}", write_gltf(document, &path).unwrap_err());
            for needle in needles {
                assert!(error.contains(needle), "'{needle}' missing from: {error}");
            }
            assert!(!path.exists(), "a file was written despite: {error}");
        };

        let mut short_joints = animated_document();
        short_joints.meshes[0].joints.pop();
        expect_error(&short_joints, &["broken.glb", "mesh 'tube'", "joint sets"]);

        let mut unnormalised = animated_document();
        unnormalised.meshes[0].weights[3] = [0.5, 0.2, 0.0, 0.0];
        expect_error(&unnormalised, &["mesh 'tube'", "vertex 3", "sum to"]);

        let mut bad_joint = animated_document();
        bad_joint.meshes[0].joints[0] = [2, 1, 0, 0];
        expect_error(&bad_joint, &["mesh 'tube'", "joint 2", "skin 'tube skin'"]);

        let mut wrong_count = animated_document();
        wrong_count.animations[1].channels[0].values.pop();
        expect_error(
            &wrong_count,
            &["animation 'flutter'", "5 values", "expected 6"],
        );

        let mut no_targets = animated_document();
        no_targets.animations[1].channels[0].node = 0;
        expect_error(&no_targets, &["animation 'flutter'", "no morph targets"]);

        let mut unsorted = animated_document();
        unsorted.animations[0].channels[0].times = vec![0.0, 0.5, 0.5];
        expect_error(&unsorted, &["animation 'bend'", "strictly increasing"]);

        let mut not_unit = animated_document();
        not_unit.animations[0].channels[2].interpolation = Interpolation::Linear;
        not_unit.animations[0].channels[2].values.truncate(8);
        not_unit.animations[0].channels[2].values[3] = 0.5;
        expect_error(&not_unit, &["animation 'bend'", "not a unit quaternion"]);

        let mut missing_weights = animated_document();
        missing_weights.meshes[1].morph_weights.pop();
        expect_error(&missing_weights, &["mesh 'flag'", "morph weights"]);

        let mut joints_outside = animated_document();
        joints_outside.roots.retain(|&r| r != 0);
        expect_error(
            &joints_outside,
            &["skin 'tube skin'", "'root joint' is not in the scene"],
        );

        let mut not_affine = animated_document();
        not_affine.skins[0].inverse_bind_matrices[1].x_axis.w = 1e-7;
        expect_error(&not_affine, &["skin 'tube skin'", "fourth row"]);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn shapes_face_outwards_and_agree_with_their_winding() {
        let vertices = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
        let tetrahedron = MeshData::convex_solid(
            "tetrahedron",
            &vertices,
            &[&[0, 1, 2], &[0, 1, 3], &[0, 2, 3], &[1, 2, 3]],
            0,
        )
        .unwrap();
        let shapes = [
            (
                MeshData::cuboid(
                    "box",
                    Vec3::new(-1.0, 0.0, -2.0),
                    Vec3::new(1.0, 3.0, 2.0),
                    0,
                ),
                Vec3::new(0.0, 1.5, 0.0),
            ),
            (
                MeshData::cylinder("cylinder", 0.3, 3.0, 24, 0),
                Vec3::new(0.0, 1.5, 0.0),
            ),
            (tetrahedron, Vec3::splat(0.25)),
        ];
        for (mesh, centre) in shapes {
            for triangle in &mesh.indices {
                let [a, b, c] = triangle.map(|i| mesh.positions[i as usize]);
                let geometric = (b - a).cross(c - a).normalize();
                assert!(
                    geometric.dot((a + b + c) / 3.0 - centre) > 0.0,
                    "{} has an inward triangle",
                    mesh.name
                );
                for i in triangle {
                    assert!(
                        mesh.normals[*i as usize].dot(geometric) > 0.0,
                        "{} normal disagrees with winding",
                        mesh.name
                    );
                }
            }
        }
    }
}
