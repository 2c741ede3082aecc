//! The imported-asset model: what one glTF file holds once it is loaded and checked.
//!
//! Load time, before the frame loop: `gltf_import` fills these types, the level loader
//! instances them, and `extract` later turns the instanced data into a `RenderScene`.
//! Everything here is plain data in glTF's conventions (right-handed, +Y up, metres,
//! linear Rec.709 colour); nothing refers back to the file it came from except `source`.

use std::path::PathBuf;

use glam::{Affine2, Mat4, Quat, Vec2, Vec3, Vec4};

/// Luminance of linear Rec.709 RGB (ITU-R BT.709 weights): the one definition every
/// module uses (light power, the film's filters, the game's light gem).
pub fn luminance(c: Vec3) -> f32 {
    c.dot(Vec3::new(0.2126, 0.7152, 0.0722))
}

/// One glTF file, imported.
#[derive(Clone, Debug, Default)]
pub struct Asset {
    /// The file this asset was read from.
    pub source: PathBuf,
    pub meshes: Vec<Mesh>,
    pub materials: Vec<Material>,
    pub textures: Vec<Texture>,
    pub images: Vec<Image>,
    pub nodes: Vec<Node>,
    /// Root nodes of the asset's default scene (glTF `scene`, else the first scene, else
    /// every node that is nobody's child).
    pub roots: Vec<usize>,
    pub cameras: Vec<Camera>,
    pub lights: Vec<Light>,
    pub skins: Vec<Skin>,
    pub animations: Vec<Animation>,
}

impl Asset {
    /// Total triangle count over every primitive of every mesh (not instanced).
    pub fn triangle_count(&self) -> usize {
        self.meshes
            .iter()
            .flat_map(|mesh| &mesh.primitives)
            .map(|p| p.indices.len())
            .sum()
    }

    /// Index of the animation clip called `name`, or written `#N` for the N-th clip (many
    /// files leave clips unnamed).
    pub fn animation_by_name(&self, name: &str) -> Option<usize> {
        self.animations
            .iter()
            .position(|a| a.name == name)
            .or_else(|| {
                name.strip_prefix('#')
                    .and_then(|n| n.parse::<usize>().ok())
                    .filter(|&n| n < self.animations.len())
            })
    }

    /// How a level names clip `index`: its name, or `#index` when it has none.
    pub fn animation_label(&self, index: usize) -> String {
        match self.animations[index].name.as_str() {
            "" => format!("#{index}"),
            name => name.to_owned(),
        }
    }

    /// Index of the material called `name`, if any.
    pub fn material_by_name(&self, name: &str) -> Option<usize> {
        self.materials.iter().position(|m| m.name == name)
    }

    /// Calls `visit(node, world_from_node)` for every node reachable from the default
    /// scene's roots, parents before children, with `root_transform` applied above the roots.
    pub fn visit_nodes(&self, root_transform: Mat4, mut visit: impl FnMut(usize, Mat4)) {
        // Iterative walk: glTF hierarchies can be deep (skeletons), and import already
        // rejected cycles, so a plain stack is enough.
        let mut stack: Vec<(usize, Mat4)> = self
            .roots
            .iter()
            .rev()
            .map(|&root| (root, root_transform))
            .collect();
        while let Some((node_index, parent_world)) = stack.pop() {
            let node = &self.nodes[node_index];
            let world = parent_world * node.transform.matrix();
            visit(node_index, world);
            stack.extend(node.children.iter().rev().map(|&child| (child, world)));
        }
    }
}

/// A glTF mesh: a list of primitives drawn with the same node transform.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    pub name: String,
    pub primitives: Vec<Primitive>,
    /// glTF `mesh.weights`: default morph-target weights (empty when there are no targets).
    pub morph_weights: Vec<f32>,
}

/// A triangle list with per-vertex attributes, all of equal length.
///
/// Strips and fans are converted to lists at import. When the file has no normals, the
/// primitive is unwelded and given flat face normals, as the glTF spec requires.
#[derive(Clone, Debug, Default)]
pub struct Primitive {
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    /// TEXCOORD_0, or empty when absent.
    pub uv0: Vec<Vec2>,
    /// TEXCOORD_1, or empty when absent (only used by textures that ask for set 1).
    pub uv1: Vec<Vec2>,
    pub indices: Vec<[u32; 3]>,
    pub material: Option<usize>,
    /// JOINTS_n / WEIGHTS_n sets, in order; empty for unskinned primitives.
    pub skin_influences: Vec<SkinInfluenceSet>,
    pub morph_targets: Vec<MorphTarget>,
}

/// One JOINTS_n + WEIGHTS_n pair: four joint indices (into the skin's joint list) and weights.
#[derive(Clone, Debug, Default)]
pub struct SkinInfluenceSet {
    pub joints: Vec<[u16; 4]>,
    pub weights: Vec<[f32; 4]>,
}

/// Displacements added to a primitive's attributes, scaled by the morph weight.
#[derive(Clone, Debug, Default)]
pub struct MorphTarget {
    /// Position deltas, or empty.
    pub positions: Vec<Vec3>,
    /// Normal deltas, or empty.
    pub normals: Vec<Vec3>,
}

/// glTF metallic-roughness material, with the extensions Gloam honours.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    pub name: String,
    /// Linear RGBA; rgb is the albedo, a the coverage used by `alpha_mode`.
    pub base_color: Vec4,
    pub base_color_texture: Option<TextureRef>,
    pub metallic: f32,
    pub roughness: f32,
    /// Roughness in G, metalness in B (linear).
    pub metallic_roughness_texture: Option<TextureRef>,
    /// Tangent-space normals (linear; x along +u, y along -v, z out of the surface), and
    /// glTF's `normalTexture.scale` on their x and y.
    pub normal_texture: Option<TextureRef>,
    pub normal_scale: f32,
    /// Emitted radiance in W/(sr m^2): emissiveFactor x KHR_materials_emissive_strength.
    pub emissive: Vec3,
    pub emissive_texture: Option<TextureRef>,
    /// KHR_materials_transmission factor (0 opaque, 1 fully transmissive dielectric).
    pub transmission: f32,
    /// KHR_materials_ior, 1.5 when absent.
    pub ior: f32,
    pub alpha_mode: AlphaMode,
    pub double_sided: bool,
}

impl Default for Material {
    /// glTF's default material: white, fully metallic, fully rough.
    fn default() -> Self {
        Material {
            name: String::new(),
            base_color: Vec4::ONE,
            base_color_texture: None,
            metallic: 1.0,
            roughness: 1.0,
            metallic_roughness_texture: None,
            normal_texture: None,
            normal_scale: 1.0,
            emissive: Vec3::ZERO,
            emissive_texture: None,
            transmission: 0.0,
            ior: 1.5,
            alpha_mode: AlphaMode::Opaque,
            double_sided: false,
        }
    }
}

impl Material {
    /// True when the surface emits light.
    pub fn is_emissive(&self) -> bool {
        self.emissive.max_element() > 0.0
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AlphaMode {
    Opaque,
    /// Texels with coverage below `cutoff` are holes.
    Mask {
        cutoff: f32,
    },
    /// Treated as stochastic coverage by the renderer.
    Blend,
}

/// How a texel's stored bytes map to linear values.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ColorEncoding {
    /// Colour data (baseColor, emissive): decoded with the sRGB transfer function.
    Srgb,
    /// Non-colour data (metallic-roughness): bytes / 255.
    Linear,
}

/// A material's use of a texture.
#[derive(Clone, Debug, PartialEq)]
pub struct TextureRef {
    pub texture: usize,
    /// Which UV set (TEXCOORD_n) to read.
    pub uv_set: u32,
    /// Decoding for this slot (set by the slot, not the image).
    pub encoding: ColorEncoding,
    /// KHR_texture_transform, identity when absent.
    pub uv_transform: Affine2,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    pub image: usize,
    pub sampler: Sampler,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sampler {
    pub magnify: Filter,
    pub minify: Filter,
    pub wrap_u: Wrap,
    pub wrap_v: Wrap,
}

impl Default for Sampler {
    fn default() -> Self {
        Sampler {
            magnify: Filter::Linear,
            minify: Filter::Linear,
            wrap_u: Wrap::Repeat,
            wrap_v: Wrap::Repeat,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Filter {
    Nearest,
    Linear,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Wrap {
    Repeat,
    MirroredRepeat,
    ClampToEdge,
}

/// A decoded image, stored as the file's 8-bit RGBA bytes. Decoding to linear happens per
/// texel fetch through the owning `TextureRef`'s encoding, before filtering.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub name: String,
    pub width: u32,
    pub height: u32,
    pub rgba8: Vec<[u8; 4]>,
}

impl Image {
    /// The texel at (x, y), decoded to linear RGBA with `encoding` (alpha is always linear).
    pub fn texel_linear(&self, x: u32, y: u32, encoding: ColorEncoding) -> Vec4 {
        debug_assert!(
            x < self.width && y < self.height,
            "texel ({x}, {y}) outside {}x{}",
            self.width,
            self.height
        );
        let [r, g, b, a] = self.rgba8[(y * self.width + x) as usize];
        match encoding {
            ColorEncoding::Srgb => Vec4::new(
                srgb_to_linear(r),
                srgb_to_linear(g),
                srgb_to_linear(b),
                a as f32 / 255.0,
            ),
            ColorEncoding::Linear => Vec4::new(r as f32, g as f32, b as f32, a as f32) / 255.0,
        }
    }
}

/// The sRGB electro-optical transfer function (IEC 61966-2-1), for one 8-bit value. Read
/// from a table of the 256 answers: `powf` for every channel of every base colour texel
/// was a quarter of the instructions that decode the kit's textures (callgrind).
pub fn srgb_to_linear(encoded: u8) -> f32 {
    static TABLE: std::sync::LazyLock<[f32; 256]> = std::sync::LazyLock::new(|| {
        std::array::from_fn(|code| {
            let c = code as f32 / 255.0;
            if c <= 0.04045 {
                c / 12.92
            } else {
                ((c + 0.055) / 1.055).powf(2.4)
            }
        })
    });
    TABLE[usize::from(encoded)]
}

/// A node of the asset's hierarchy.
#[derive(Clone, Debug, Default)]
pub struct Node {
    pub name: String,
    pub transform: NodeTransform,
    pub children: Vec<usize>,
    pub mesh: Option<usize>,
    pub camera: Option<usize>,
    pub light: Option<usize>,
    pub skin: Option<usize>,
    /// Per-node morph weights overriding the mesh's defaults.
    pub morph_weights: Option<Vec<f32>>,
}

/// A node's local transform as the file gives it. Matrix nodes are kept as matrices
/// (they may hold shear, and glTF forbids animating them).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum NodeTransform {
    Trs {
        translation: Vec3,
        rotation: Quat,
        scale: Vec3,
    },
    Matrix(Mat4),
}

impl Default for NodeTransform {
    fn default() -> Self {
        NodeTransform::Trs {
            translation: Vec3::ZERO,
            rotation: Quat::IDENTITY,
            scale: Vec3::ONE,
        }
    }
}

impl NodeTransform {
    pub fn matrix(&self) -> Mat4 {
        match *self {
            NodeTransform::Trs {
                translation,
                rotation,
                scale,
            } => Mat4::from_scale_rotation_translation(scale, rotation, translation),
            NodeTransform::Matrix(matrix) => matrix,
        }
    }
}

/// A camera; it looks down its node's local -Z with +Y up.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    pub name: String,
    pub projection: Projection,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    Perspective {
        /// Vertical field of view in radians.
        yfov: f32,
        /// Width / height; None means "use the film's".
        aspect_ratio: Option<f32>,
        znear: f32,
        zfar: Option<f32>,
    },
    Orthographic {
        xmag: f32,
        ymag: f32,
        znear: f32,
        zfar: f32,
    },
}

/// KHR_lights_punctual light. Point and spot `intensity` is radiant intensity in W/sr
/// (radiance at distance d is intensity / d^2); directional `intensity` is irradiance in W/m^2.
#[derive(Clone, Debug, PartialEq)]
pub struct Light {
    pub name: String,
    pub kind: LightKind,
    /// Linear RGB colour, multiplied by `intensity`.
    pub color: Vec3,
    pub intensity: f32,
    pub range: Option<f32>,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightKind {
    /// Shines down the node's local -Z.
    Directional,
    Point,
    /// Shines down local -Z; cone angles in radians from the axis.
    Spot {
        inner_cone_angle: f32,
        outer_cone_angle: f32,
    },
}

#[derive(Clone, Debug, Default)]
pub struct Skin {
    pub name: String,
    /// Node index of each joint.
    pub joints: Vec<usize>,
    /// One per joint (identity when the file has none).
    pub inverse_bind_matrices: Vec<Mat4>,
    pub skeleton: Option<usize>,
}

#[derive(Clone, Debug, Default)]
pub struct Animation {
    pub name: String,
    pub channels: Vec<AnimationChannel>,
    pub samplers: Vec<AnimationSampler>,
}

impl Animation {
    /// Length of the clip in seconds (the last keyframe time over all samplers).
    pub fn duration(&self) -> f32 {
        self.samplers
            .iter()
            .filter_map(|s| s.times.last().copied())
            .fold(0.0, f32::max)
    }
}

#[derive(Clone, Debug)]
pub struct AnimationChannel {
    pub sampler: usize,
    pub node: usize,
    pub property: AnimatedProperty,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AnimatedProperty {
    Translation,
    Rotation,
    Scale,
    MorphWeights,
}

#[derive(Clone, Debug)]
pub struct AnimationSampler {
    pub interpolation: Interpolation,
    /// Keyframe times in seconds, increasing.
    pub times: Vec<f32>,
    /// Output values flattened: `components` floats per keyframe element, with
    /// (in-tangent, value, out-tangent) triples for cubic splines.
    pub values: Vec<f32>,
    /// Floats per element: 3 (translation, scale), 4 (rotation), or the morph-target count.
    pub components: usize,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interpolation {
    Linear,
    Step,
    CubicSpline,
}
