//! glTF 2.0 import (.gltf with embedded `data:` or external buffers, .glb) into the `Asset`
//! model.
//!
//! Load time, before the frame loop. Owns: reading buffers and images, bounds-checked
//! accessor decoding (every component type, normalized integers, sparse accessors, byte
//! strides), triangle-list conversion, flat normals where a file has none, materials,
//! cameras, lights, skins, morph targets and animations (parsed here, evaluated by the
//! animation step).
//!
//! # What it reads
//!
//! The node hierarchy (TRS or matrices); every triangle primitive (lists, strips and fans;
//! indexed or not; flat normals generated when a file has none, as the spec asks); UV sets
//! 0 and 1; metallic-roughness materials with their textures (sRGB decoding for colour,
//! linear for data; sampler filters and wrap modes) and normal textures; the emissive
//! factor and texture with `KHR_materials_emissive_strength`, `KHR_materials_transmission`,
//! `KHR_materials_ior`, `KHR_texture_transform`, `KHR_mesh_quantization`, alpha mode and
//! cutoff, double-sidedness; perspective and orthographic cameras; `KHR_lights_punctual`;
//! skins (every joint/weight set, inverse bind matrices); morph targets (positions,
//! normals); and animations (translation, rotation, scale and morph-weight channels;
//! linear, step and cubic-spline samplers, sparse accessors included). A file that
//! *requires* any other extension ([`SUPPORTED_REQUIRED_EXTENSIONS`]) is refused with an
//! error naming it.
//!
//! Conventions: glTF's space (right-handed, +Y up, metres, cameras look down -Z); linear
//! Rec.709 colour inside; an emissive surface's radiance is emissiveFactor x
//! emissiveStrength in W/(sr m^2); point and spot light intensity is radiant intensity in
//! W/sr, directional intensity is irradiance in W/m^2.
//!
//! # Errors
//!
//! Every failure is a `Diagnostic` naming the file, a line:column in its JSON (the GLB's
//! JSON chunk for binary files) and the JSON pointer of the offending element. Nothing a
//! file contains may panic this code: all offsets are checked before slicing.

use std::borrow::Cow;
use std::path::{Path, PathBuf};

use base64::Engine as _;
use glam::{Affine2, Mat2, Mat4, Quat, Vec2, Vec3, Vec4};
use gltf::accessor::{DataType, Dimensions};
use gltf::json::validation::Validate as _;
use rayon::prelude::*;

use super::diagnostic::{Diagnostic, LoadError, Pointer};
use super::model::*;

/// Required extensions this importer honours; any other in `extensionsRequired` is an error.
pub const SUPPORTED_REQUIRED_EXTENSIONS: &[&str] = &[
    "KHR_lights_punctual",
    "KHR_materials_emissive_strength",
    "KHR_materials_transmission",
    "KHR_materials_ior",
    "KHR_texture_transform",
    "KHR_mesh_quantization",
];

/// How far from its own origin a vertex may lie (metres): past it, f32 bounds arithmetic
/// in the BVH build overflows.
pub const MAX_COORDINATE: f32 = 1.0e6;

/// Imports the glTF or GLB file at `path`.
pub fn import_gltf(path: &Path) -> Result<Asset, LoadError> {
    let bytes = std::fs::read(path)
        .map_err(|error| Diagnostic::whole_file(path, format!("cannot read glTF file: {error}")))?;
    import_gltf_bytes(path, &bytes)
}

/// Imports glTF or GLB `bytes`; `path` names the file in diagnostics and anchors relative URIs.
///
/// Contained: the gltf crate's accessors `unwrap` what its validation is trusted to have
/// checked, and `validate_root` guards each case fuzzing has found; should a file still
/// reach a panic inside the import, it becomes this file's diagnostic (and the panic
/// message is not printed), never a crash of the game, the editor or `gloam check`.
pub fn import_gltf_bytes(path: &Path, bytes: &[u8]) -> Result<Asset, LoadError> {
    contained(path, || import_checked(path, bytes))
}

thread_local! {
    /// Set while this thread runs a contained import: its panics are reported as a
    /// diagnostic, not printed.
    static CONTAINED: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Runs `import`, turning a panic inside it into a diagnostic naming `path`.
fn contained(
    path: &Path,
    import: impl FnOnce() -> Result<Asset, LoadError>,
) -> Result<Asset, LoadError> {
    static QUIET_HOOK: std::sync::Once = std::sync::Once::new();
    QUIET_HOOK.call_once(|| {
        let earlier = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !CONTAINED.with(std::cell::Cell::get) {
                earlier(info);
            }
        }));
    });
    let was = CONTAINED.with(|contained| contained.replace(true));
    let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(import));
    CONTAINED.with(|contained| contained.set(was));
    outcome.unwrap_or_else(|panic| {
        let what = (panic.downcast_ref::<&str>().map(|s| s.to_string()))
            .or_else(|| panic.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "an unexpected value".to_string());
        Err(Diagnostic::whole_file(
            path,
            format!("the glTF reader failed on this file ({what}); it may be malformed"),
        )
        .into())
    })
}

fn import_checked(path: &Path, bytes: &[u8]) -> Result<Asset, LoadError> {
    // 1. Split a GLB into its JSON and BIN chunks; a .gltf is all JSON.
    let (json_bytes, glb_bin): (Cow<[u8]>, Option<Cow<[u8]>>) = if bytes.starts_with(b"glTF") {
        // gltf 1.4.1 subtracts the 12-byte header from the declared length unchecked: a
        // length below 12 overflows there (a panic wherever overflow checks are on).
        if let Some(length) = bytes.get(8..12)
            && let Ok(length) = <[u8; 4]>::try_from(length).map(u32::from_le_bytes)
            && length < 12
        {
            return Err(Diagnostic::whole_file(
                path,
                format!("not a valid GLB file: its header says {length} bytes, less than the 12-byte header itself"),
            )
            .into());
        }
        let glb = gltf::binary::Glb::from_slice(bytes).map_err(|error| {
            Diagnostic::whole_file(
                path,
                format!("not a valid GLB file: {}", describe_gltf_error(&error)),
            )
        })?;
        (glb.json, glb.bin)
    } else {
        (Cow::Borrowed(bytes), None)
    };
    let json_text = std::str::from_utf8(&json_bytes).map_err(|error| {
        let what = if glb_bin.is_some() || bytes.starts_with(b"glTF") {
            "the GLB's JSON chunk"
        } else {
            "the file"
        };
        Diagnostic::whole_file(
            path,
            format!("not a glTF file: {what} is not UTF-8 JSON ({error})"),
        )
    })?;

    // 2. Parse the JSON; serde reports syntax and type errors with their line and column.
    let root: gltf::json::Root = serde_json::from_str(json_text).map_err(|error| Diagnostic {
        file: path.to_owned(),
        line: error.line().max(1),
        column: error.column().max(1),
        message: format!(
            "invalid glTF JSON: {}",
            strip_serde_position(&error.to_string())
        ),
    })?;

    // 3. Validate references and required values, then our own extension list.
    let document_errors = validate_root(path, json_text, &root);
    if !document_errors.is_empty() {
        return Err(LoadError {
            diagnostics: document_errors,
        });
    }
    let document = gltf::Document::from_json_without_validation(root);
    let importer = Importer {
        path: path.to_owned(),
        json_text,
        document: &document,
        buffers: Vec::new(),
    };
    importer.run(glb_bin)
}

/// Removes serde_json's " at line L column C" suffix (we print the position ourselves).
fn strip_serde_position(message: &str) -> &str {
    message
        .rfind(" at line ")
        .map_or(message, |i| &message[..i])
}

fn describe_gltf_error(error: &gltf::Error) -> String {
    match error {
        gltf::Error::Binary(binary) => match binary {
            gltf::binary::Error::Length {
                length,
                length_read,
            } => {
                format!("header says {length} bytes but the file has {length_read} (truncated?)")
            }
            gltf::binary::Error::ChunkLength {
                ty,
                length,
                length_read,
            } => {
                format!(
                    "{ty:?} chunk says {length} bytes but only {length_read} remain (truncated?)"
                )
            }
            other => format!("{other:?}"),
        },
        other => other.to_string(),
    }
}

fn validate_root(path: &Path, json_text: &str, root: &gltf::json::Root) -> Vec<Diagnostic> {
    let mut diagnostics = Vec::new();
    // Guard: gltf-json 1.4.1's primitive hook indexes `root.accessors[POSITION]` without a
    // bounds check and panics on a dangling index, so those are caught before it runs.
    for (mesh_index, mesh) in root.meshes.iter().enumerate() {
        for (primitive_index, primitive) in mesh.primitives.iter().enumerate() {
            let position = primitive
                .attributes
                .get(&gltf::json::validation::Checked::Valid(
                    gltf::Semantic::Positions,
                ));
            if let Some(accessor) = position
                && accessor.value() >= root.accessors.len()
            {
                let pointer = Pointer::root()
                    .key("meshes")
                    .index(mesh_index)
                    .key("primitives")
                    .index(primitive_index)
                    .key("attributes")
                    .key("POSITION");
                diagnostics.push(Diagnostic::at_pointer(
                    path,
                    json_text,
                    &pointer,
                    format!(
                        "index out of range: accessor {} does not exist ({} accessors)",
                        accessor.value(),
                        root.accessors.len()
                    ),
                ));
            }
        }
    }
    // Guard: gltf-json 1.4.1 validates an animation's samplers and its channels' sampler
    // indices but not their targets, and the gltf crate unwraps a target's path and finds
    // its node by index: an unknown path or a dangling node would panic there.
    for (animation_index, animation) in root.animations.iter().enumerate() {
        for (channel_index, channel) in animation.channels.iter().enumerate() {
            let target = Pointer::root()
                .key("animations")
                .index(animation_index)
                .key("channels")
                .index(channel_index)
                .key("target");
            if !matches!(
                channel.target.path,
                gltf::json::validation::Checked::Valid(_)
            ) {
                diagnostics.push(Diagnostic::at_pointer(
                    path,
                    json_text,
                    &target.key("path"),
                    "invalid value: an animated property is \"translation\", \"rotation\", \"scale\" or \"weights\"".to_owned(),
                ));
            }
            let node = channel.target.node.value();
            if node >= root.nodes.len() {
                diagnostics.push(Diagnostic::at_pointer(
                    path,
                    json_text,
                    &target.key("node"),
                    format!(
                        "index out of range: node {node} does not exist ({} nodes)",
                        root.nodes.len()
                    ),
                ));
            }
        }
    }
    // Guard: the gltf crate's `Image::source` unwraps a `uri` when an image has no
    // `bufferView`, and a `mimeType` when it has one; glTF requires both of them there.
    for (index, image) in root.images.iter().enumerate() {
        let pointer = Pointer::root().key("images").index(index);
        let missing = match (&image.buffer_view, &image.uri, &image.mime_type) {
            (None, None, _) => Some("an image needs a \"uri\" or a \"bufferView\""),
            (Some(_), _, None) => Some("an image in a \"bufferView\" needs a \"mimeType\""),
            _ => None,
        };
        if let Some(message) = missing {
            diagnostics.push(Diagnostic::at_pointer(
                path,
                json_text,
                &pointer,
                format!("required value missing: {message}"),
            ));
        }
    }
    if !diagnostics.is_empty() {
        return diagnostics;
    }
    root.validate(root, gltf::json::Path::new, &mut |where_, error| {
        let pointer = Pointer::from_gltf_path(where_().as_str());
        // Required extensions are checked against our own list below.
        if matches!(pointer.0.first(), Some(super::diagnostic::Segment::Key(k)) if k == "extensionsRequired") {
            return;
        }
        let message = match error {
            gltf::json::validation::Error::IndexOutOfBounds => "index out of range",
            gltf::json::validation::Error::Invalid => "invalid value",
            gltf::json::validation::Error::Missing => "required value missing",
            gltf::json::validation::Error::Oversize => "size exceeds this platform's limits",
            gltf::json::validation::Error::Unsupported => "unsupported",
        };
        diagnostics.push(Diagnostic::at_pointer(path, json_text, &pointer, message));
    });
    for (index, extension) in root.extensions_required.iter().enumerate() {
        if !SUPPORTED_REQUIRED_EXTENSIONS.contains(&extension.as_str()) {
            diagnostics.push(Diagnostic::at_pointer(
                path,
                json_text,
                &Pointer::root().key("extensionsRequired").index(index),
                format!(
                    "required extension '{extension}' is not supported (gloam supports {})",
                    SUPPORTED_REQUIRED_EXTENSIONS.join(", ")
                ),
            ));
        }
    }
    diagnostics
}

struct Importer<'a> {
    path: PathBuf,
    json_text: &'a str,
    document: &'a gltf::Document,
    buffers: Vec<Vec<u8>>,
}

type Checked<T> = Result<T, Diagnostic>;

impl Importer<'_> {
    fn error(&self, pointer: Pointer, message: impl Into<String>) -> Diagnostic {
        Diagnostic::at_pointer(&self.path, self.json_text, &pointer, message)
    }

    fn run(mut self, glb_bin: Option<Cow<[u8]>>) -> Result<Asset, LoadError> {
        self.buffers = self.load_buffers(glb_bin)?;
        let images = self.load_images()?;
        let mut asset = Asset {
            source: self.path.clone(),
            images,
            ..Asset::default()
        };
        let mut diagnostics = Vec::new();
        // Each part reports its first problem; all parts are tried so `check` lists them all.
        macro_rules! part {
            ($field:ident, $call:expr) => {
                match $call {
                    Ok(value) => asset.$field = value,
                    Err(diagnostic) => diagnostics.push(diagnostic),
                }
            };
        }
        part!(textures, self.textures());
        part!(materials, self.materials());
        part!(meshes, self.meshes());
        part!(nodes, self.nodes());
        part!(cameras, self.cameras());
        part!(lights, self.lights());
        part!(skins, self.skins());
        part!(animations, self.animations());
        if diagnostics.is_empty() {
            diagnostics.extend(self.check_deformation(&asset));
        }
        if diagnostics.is_empty() {
            match self.roots(&asset.nodes) {
                Ok(roots) => asset.roots = roots,
                Err(diagnostic) => diagnostics.push(diagnostic),
            }
        }
        if diagnostics.is_empty() {
            Ok(asset)
        } else {
            Err(LoadError { diagnostics })
        }
    }

    fn base_dir(&self) -> &Path {
        self.path.parent().unwrap_or(Path::new("."))
    }

    /// Bytes named by a URI: a `data:` URI (base64) or a file relative to the glTF.
    fn read_uri(&self, uri: &str, pointer: &Pointer) -> Checked<Vec<u8>> {
        if let Some(rest) = uri.strip_prefix("data:") {
            let Some((header, payload)) = rest.split_once(',') else {
                return Err(self.error(pointer.clone(), "data URI has no ',' before its payload"));
            };
            if !header.ends_with(";base64") {
                return Err(self.error(pointer.clone(), "data URI is not base64-encoded"));
            }
            return base64::engine::general_purpose::STANDARD
                .decode(payload)
                .map_err(|error| {
                    self.error(pointer.clone(), format!("bad base64 in data URI: {error}"))
                });
        }
        let relative = percent_decode(uri);
        let file = self.base_dir().join(&relative);
        std::fs::read(&file).map_err(|error| {
            self.error(
                pointer.clone(),
                format!("cannot read '{}': {error}", file.display()),
            )
        })
    }

    fn load_buffers(&self, mut glb_bin: Option<Cow<[u8]>>) -> Result<Vec<Vec<u8>>, LoadError> {
        let mut buffers = Vec::new();
        let mut diagnostics = Vec::new();
        for buffer in self.document.buffers() {
            let pointer = Pointer::root().key("buffers").index(buffer.index());
            let data = match buffer.source() {
                gltf::buffer::Source::Bin => match glb_bin.take() {
                    Some(bin) => Ok(bin.into_owned()),
                    None => Err(self.error(
                        pointer.clone(),
                        "buffer has no uri and the file has no GLB binary chunk",
                    )),
                },
                gltf::buffer::Source::Uri(uri) => self.read_uri(uri, &pointer.key("uri")),
            };
            match data {
                Ok(data) if data.len() < buffer.length() => diagnostics.push(self.error(
                    pointer.key("byteLength"),
                    format!(
                        "buffer declares {} bytes but its data has {}",
                        buffer.length(),
                        data.len()
                    ),
                )),
                Ok(data) => buffers.push(data),
                Err(diagnostic) => diagnostics.push(diagnostic),
            }
        }
        if diagnostics.is_empty() {
            Ok(buffers)
        } else {
            Err(LoadError { diagnostics })
        }
    }

    fn load_images(&self) -> Result<Vec<Image>, LoadError> {
        let encoded: Vec<Checked<(String, Cow<[u8]>)>> = self
            .document
            .images()
            .map(|image| {
                let pointer = Pointer::root().key("images").index(image.index());
                let bytes = match image.source() {
                    gltf::image::Source::View { view, .. } => {
                        Cow::Borrowed(self.view_bytes(&view)?)
                    }
                    gltf::image::Source::Uri { uri, .. } => {
                        Cow::Owned(self.read_uri(uri, &pointer.key("uri"))?)
                    }
                };
                Ok((image.name().unwrap_or_default().to_owned(), bytes))
            })
            .collect();
        // Decoding dominates texture-heavy imports; images are independent.
        let decoded: Vec<Checked<Image>> = encoded
            .into_par_iter()
            .enumerate()
            .map(|(index, entry)| {
                let (name, bytes) = entry?;
                let decoded = image::load_from_memory(&bytes).map_err(|error| {
                    self.error(
                        Pointer::root().key("images").index(index),
                        format!("cannot decode image: {error}"),
                    )
                })?;
                let rgba = decoded.into_rgba8();
                let (width, height) = rgba.dimensions();
                let rgba8 = rgba
                    .into_raw()
                    .chunks_exact(4)
                    .map(|t| [t[0], t[1], t[2], t[3]])
                    .collect();
                Ok(Image {
                    name,
                    width,
                    height,
                    rgba8,
                })
            })
            .collect();
        let mut images = Vec::new();
        let mut diagnostics = Vec::new();
        for result in decoded {
            match result {
                Ok(image) => images.push(image),
                Err(diagnostic) => diagnostics.push(diagnostic),
            }
        }
        if diagnostics.is_empty() {
            Ok(images)
        } else {
            Err(LoadError { diagnostics })
        }
    }

    /// The bytes of a buffer view, checked against its buffer.
    fn view_bytes(&self, view: &gltf::buffer::View) -> Checked<&[u8]> {
        let buffer = &self.buffers[view.buffer().index()];
        view.offset()
            .checked_add(view.length())
            .and_then(|end| buffer.get(view.offset()..end))
            .ok_or_else(|| {
                self.error(
                    Pointer::root().key("bufferViews").index(view.index()),
                    format!(
                        "buffer view covers bytes {}..{} but buffer {} has only {} bytes",
                        view.offset(),
                        view.offset().saturating_add(view.length()),
                        view.buffer().index(),
                        buffer.len()
                    ),
                )
            })
    }

    // ---- accessors ---------------------------------------------------------------------

    /// Reads every component of an accessor as `T`, applying sparse substitution.
    /// Returns the components flattened and the component count per element.
    fn read_accessor<T: Component>(&self, accessor: &gltf::Accessor) -> Checked<(Vec<T>, usize)> {
        let pointer = Pointer::root().key("accessors").index(accessor.index());
        let dims = accessor.dimensions().multiplicity();
        let data_type = accessor.data_type();
        if !T::accepts(data_type) {
            return Err(self.error(
                pointer,
                format!("component type {data_type:?} is not allowed here"),
            ));
        }
        let component_size = data_type.size();
        if matches!(
            accessor.dimensions(),
            Dimensions::Mat2 | Dimensions::Mat3 | Dimensions::Mat4
        ) && component_size < 4
        {
            return Err(self.error(
                pointer,
                "matrix accessors with 8- or 16-bit components are not supported",
            ));
        }
        let count = accessor.count();
        let total = count
            .checked_mul(dims)
            .filter(|&total| total <= (1 << 31))
            .ok_or_else(|| {
                self.error(
                    pointer.key("count"),
                    format!("accessor count {count} is too large"),
                )
            })?;
        let normalized = accessor.normalized();
        let mut out = Vec::with_capacity(total);
        match accessor.view() {
            None => out.resize(total, T::ZERO),
            Some(view) => {
                let bytes = self.view_bytes(&view)?;
                let element_size = component_size * dims;
                let stride = view.stride().unwrap_or(element_size);
                if stride < element_size {
                    return Err(self.error(
                        Pointer::root()
                            .key("bufferViews")
                            .index(view.index())
                            .key("byteStride"),
                        format!(
                            "byteStride {stride} is smaller than the {element_size}-byte element"
                        ),
                    ));
                }
                if count > 0 {
                    let end = (count - 1)
                        .checked_mul(stride)
                        .and_then(|x| x.checked_add(accessor.offset()))
                        .and_then(|x| x.checked_add(element_size));
                    if end.is_none_or(|end| end > bytes.len()) {
                        return Err(self.error(
                            pointer,
                            format!(
                                "accessor reads {count} elements of {element_size} bytes (stride {stride}) from offset {} but buffer view {} has only {} bytes",
                                accessor.offset(),
                                view.index(),
                                bytes.len()
                            ),
                        ));
                    }
                }
                let bytes = &bytes[accessor.offset()..];
                // Hot at import: 1M-triangle meshes read ~10M components here. The
                // component type is matched once per call, not per element.
                T::decode_strided(bytes, data_type, normalized, count, dims, stride, &mut out);
            }
        }
        if let Some(sparse) = accessor.sparse() {
            self.apply_sparse(
                &sparse, data_type, normalized, dims, count, &pointer, &mut out,
            )?;
        }
        Ok((out, dims))
    }

    #[allow(clippy::too_many_arguments)]
    fn apply_sparse<T: Component>(
        &self,
        sparse: &gltf::accessor::sparse::Sparse,
        data_type: DataType,
        normalized: bool,
        dims: usize,
        count: usize,
        pointer: &Pointer,
        out: &mut [T],
    ) -> Checked<()> {
        let pointer = pointer.key("sparse");
        let sparse_count = sparse.count();
        let indices = sparse.indices();
        let index_type = match indices.index_type() {
            gltf::accessor::sparse::IndexType::U8 => DataType::U8,
            gltf::accessor::sparse::IndexType::U16 => DataType::U16,
            gltf::accessor::sparse::IndexType::U32 => DataType::U32,
        };
        let index_bytes = self.view_bytes(&indices.view())?;
        let index_bytes = index_bytes.get(indices.offset()..).unwrap_or_default();
        if sparse_count
            .checked_mul(index_type.size())
            .is_none_or(|n| n > index_bytes.len())
        {
            return Err(self.error(
                pointer.key("indices"),
                "sparse indices run past their buffer view",
            ));
        }
        let mut sparse_indices = Vec::with_capacity(sparse_count);
        u32::decode_strided(
            index_bytes,
            index_type,
            false,
            sparse_count,
            1,
            index_type.size(),
            &mut sparse_indices,
        );

        let values = sparse.values();
        let element_size = data_type.size() * dims;
        let value_bytes = self.view_bytes(&values.view())?;
        let value_bytes = value_bytes.get(values.offset()..).unwrap_or_default();
        if sparse_count
            .checked_mul(element_size)
            .is_none_or(|n| n > value_bytes.len())
        {
            return Err(self.error(
                pointer.key("values"),
                "sparse values run past their buffer view",
            ));
        }
        let mut sparse_values = Vec::with_capacity(sparse_count * dims);
        T::decode_strided(
            value_bytes,
            data_type,
            normalized,
            sparse_count,
            dims,
            element_size,
            &mut sparse_values,
        );
        for (k, &index) in sparse_indices.iter().enumerate() {
            let index = index as usize;
            if index >= count {
                return Err(self.error(
                    pointer.key("indices"),
                    format!("sparse index {index} is out of range for {count} elements"),
                ));
            }
            out[index * dims..(index + 1) * dims]
                .copy_from_slice(&sparse_values[k * dims..(k + 1) * dims]);
        }
        Ok(())
    }

    fn read_f32_elements(
        &self,
        accessor: &gltf::Accessor,
        expected: Dimensions,
        what: &str,
    ) -> Checked<Vec<f32>> {
        if accessor.dimensions() != expected {
            return Err(self.error(
                Pointer::root()
                    .key("accessors")
                    .index(accessor.index())
                    .key("type"),
                format!(
                    "{what} must be {expected:?}, found {:?}",
                    accessor.dimensions()
                ),
            ));
        }
        let values = self.read_accessor::<f32>(accessor)?.0;
        // As the Khronos validator does (ACCESSOR_INVALID_FLOAT): a NaN or an infinity
        // would pass import and break the BVH build, the renderer or the simulation later.
        if let Some(at) = values.iter().position(|v| !v.is_finite()) {
            let components = expected.multiplicity();
            return Err(self.error(
                Pointer::root().key("accessors").index(accessor.index()),
                format!(
                    "{what} element {} holds {} (values must be finite)",
                    at / components,
                    values[at]
                ),
            ));
        }
        Ok(values)
    }

    fn read_vec3s(&self, accessor: &gltf::Accessor, what: &str) -> Checked<Vec<Vec3>> {
        let flat = self.read_f32_elements(accessor, Dimensions::Vec3, what)?;
        Ok(flat.chunks_exact(3).map(Vec3::from_slice).collect())
    }

    fn read_vec2s(&self, accessor: &gltf::Accessor, what: &str) -> Checked<Vec<Vec2>> {
        let flat = self.read_f32_elements(accessor, Dimensions::Vec2, what)?;
        Ok(flat.chunks_exact(2).map(Vec2::from_slice).collect())
    }

    // ---- meshes ------------------------------------------------------------------------

    fn meshes(&self) -> Checked<Vec<Mesh>> {
        self.document
            .meshes()
            .map(|mesh| {
                let primitives = mesh
                    .primitives()
                    .map(|primitive| self.primitive(&mesh, &primitive))
                    .filter_map(Result::transpose)
                    .collect::<Checked<Vec<_>>>()?;
                Ok(Mesh {
                    name: mesh.name().unwrap_or_default().to_owned(),
                    primitives,
                    morph_weights: mesh.weights().map(<[f32]>::to_vec).unwrap_or_default(),
                })
            })
            .collect()
    }

    /// One primitive as a triangle list, or None for point and line primitives.
    fn primitive(
        &self,
        mesh: &gltf::Mesh,
        primitive: &gltf::Primitive,
    ) -> Checked<Option<Primitive>> {
        use gltf::mesh::{Mode, Semantic};
        let pointer = Pointer::root()
            .key("meshes")
            .index(mesh.index())
            .key("primitives")
            .index(primitive.index());
        let mode = primitive.mode();
        if !matches!(
            mode,
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
        ) {
            return Ok(None);
        }
        let Some(position_accessor) = primitive.get(&Semantic::Positions) else {
            return Err(self.error(
                pointer.key("attributes"),
                "primitive has no POSITION attribute",
            ));
        };
        // A subnormal coordinate (under 1.2e-38 m) is the origin to any ray, but each sum and
        // product of them takes the CPU's slow path: a fuzzed GLB of 2,399 such vertices spent
        // 4 s in the BVH build. They are flushed to zero here, once.
        let positions: Vec<Vec3> = self
            .read_vec3s(&position_accessor, "POSITION")?
            .into_iter()
            .map(|p| Vec3::select(p.abs().cmplt(Vec3::splat(f32::MIN_POSITIVE)), Vec3::ZERO, p))
            .collect();
        // A finite but enormous coordinate (1e32 m) overflows the BVH's bounds arithmetic
        // in f32 and breaks its build; nothing a level needs is a thousand kilometres out.
        if let Some(at) = positions
            .iter()
            .position(|p| p.abs().max_element() > MAX_COORDINATE)
        {
            return Err(self.error(
                Pointer::root()
                    .key("accessors")
                    .index(position_accessor.index()),
                format!(
                    "POSITION element {at} is {} (coordinates must lie within {MAX_COORDINATE} m of the origin)",
                    positions[at]
                ),
            ));
        }
        let vertex_count = positions.len();
        let attribute_pointer = |name: &str| pointer.key("attributes").key(name);
        let check_count = |len: usize, name: &str| -> Checked<()> {
            if len == vertex_count {
                Ok(())
            } else {
                Err(self.error(
                    attribute_pointer(name),
                    format!("{name} has {len} elements but POSITION has {vertex_count}"),
                ))
            }
        };

        // Corner list: explicit indices, or 0..vertex_count.
        let corners: Vec<u32> = match primitive.indices() {
            Some(accessor) => {
                if accessor.dimensions() != Dimensions::Scalar {
                    return Err(self.error(pointer.key("indices"), "indices must be SCALAR"));
                }
                let (corners, _) = self.read_accessor::<u32>(&accessor)?;
                if let Some(bad) = corners.iter().find(|&&i| i as usize >= vertex_count) {
                    return Err(self.error(
                        pointer.key("indices"),
                        format!("index {bad} is out of range for {vertex_count} vertices"),
                    ));
                }
                corners
            }
            None => (0..vertex_count as u32).collect(),
        };
        let indices = triangulate(mode, &corners)
            .map_err(|message| self.error(pointer.key("mode"), message))?;

        let mut normals = match primitive.get(&Semantic::Normals) {
            Some(accessor) => {
                let normals = self.read_vec3s(&accessor, "NORMAL")?;
                check_count(normals.len(), "NORMAL")?;
                normals
                    .into_iter()
                    .map(|n| n.normalize_or(Vec3::Y))
                    .collect()
            }
            None => Vec::new(),
        };
        let read_uv = |set: u32| -> Checked<Vec<Vec2>> {
            match primitive.get(&Semantic::TexCoords(set)) {
                Some(accessor) => {
                    let name = format!("TEXCOORD_{set}");
                    let uvs = self.read_vec2s(&accessor, &name)?;
                    check_count(uvs.len(), &name)?;
                    Ok(uvs)
                }
                None => Ok(Vec::new()),
            }
        };
        let uv0 = read_uv(0)?;
        let uv1 = read_uv(1)?;

        let mut skin_influences = Vec::new();
        for set in 0.. {
            let (Some(joints), Some(weights)) = (
                primitive.get(&Semantic::Joints(set)),
                primitive.get(&Semantic::Weights(set)),
            ) else {
                break;
            };
            let joint_name = format!("JOINTS_{set}");
            let weight_name = format!("WEIGHTS_{set}");
            if joints.dimensions() != Dimensions::Vec4 {
                return Err(self.error(
                    attribute_pointer(&joint_name),
                    format!("{joint_name} must be VEC4"),
                ));
            }
            let (joint_values, _) = self.read_accessor::<u32>(&joints)?;
            if joint_values.iter().any(|&j| j > u16::MAX as u32) {
                return Err(self.error(
                    attribute_pointer(&joint_name),
                    format!("{joint_name} holds a joint index above 65535"),
                ));
            }
            let weight_values = self.read_f32_elements(&weights, Dimensions::Vec4, &weight_name)?;
            check_count(joint_values.len() / 4, &joint_name)?;
            check_count(weight_values.len() / 4, &weight_name)?;
            skin_influences.push(SkinInfluenceSet {
                joints: joint_values
                    .chunks_exact(4)
                    .map(|j| [j[0] as u16, j[1] as u16, j[2] as u16, j[3] as u16])
                    .collect(),
                weights: weight_values
                    .chunks_exact(4)
                    .map(|w| [w[0], w[1], w[2], w[3]])
                    .collect(),
            });
        }

        let mut morph_targets = Vec::new();
        for (target_index, target) in primitive.morph_targets().enumerate() {
            let target_pointer = pointer.key("targets").index(target_index);
            let read = |accessor: Option<gltf::Accessor>, name: &str| -> Checked<Vec<Vec3>> {
                let Some(accessor) = accessor else {
                    return Ok(Vec::new());
                };
                let deltas = self.read_vec3s(&accessor, name)?;
                if deltas.len() != vertex_count {
                    return Err(self.error(
                        target_pointer.key(name),
                        format!(
                            "morph target {name} has {} elements but POSITION has {vertex_count}",
                            deltas.len()
                        ),
                    ));
                }
                Ok(deltas)
            };
            morph_targets.push(MorphTarget {
                positions: read(target.positions(), "POSITION")?,
                normals: read(target.normals(), "NORMAL")?,
            });
        }

        let mut result = Primitive {
            positions,
            normals: Vec::new(),
            uv0,
            uv1,
            indices,
            material: primitive.material().index(),
            skin_influences,
            morph_targets,
        };
        if normals.is_empty() {
            unweld_with_flat_normals(&mut result);
        } else {
            result.normals = std::mem::take(&mut normals);
        }
        Ok(Some(result))
    }

    // ---- materials and textures ----------------------------------------------------------

    fn textures(&self) -> Checked<Vec<Texture>> {
        use gltf::texture::{MagFilter, MinFilter, WrappingMode};
        let wrap = |mode: WrappingMode| match mode {
            WrappingMode::Repeat => Wrap::Repeat,
            WrappingMode::MirroredRepeat => Wrap::MirroredRepeat,
            WrappingMode::ClampToEdge => Wrap::ClampToEdge,
        };
        self.document
            .textures()
            .map(|texture| {
                let sampler = texture.sampler();
                Ok(Texture {
                    image: texture.source().index(),
                    sampler: Sampler {
                        magnify: match sampler.mag_filter() {
                            Some(MagFilter::Nearest) => Filter::Nearest,
                            _ => Filter::Linear,
                        },
                        minify: match sampler.min_filter() {
                            Some(
                                MinFilter::Nearest
                                | MinFilter::NearestMipmapNearest
                                | MinFilter::NearestMipmapLinear,
                            ) => Filter::Nearest,
                            _ => Filter::Linear,
                        },
                        wrap_u: wrap(sampler.wrap_s()),
                        wrap_v: wrap(sampler.wrap_t()),
                    },
                })
            })
            .collect()
    }

    fn materials(&self) -> Checked<Vec<Material>> {
        self.document
            .materials()
            .map(|material| {
                let index = material.index().unwrap_or_default();
                let pointer = Pointer::root().key("materials").index(index);
                let pbr = material.pbr_metallic_roughness();
                let emissive_strength = material.emissive_strength().unwrap_or(1.0);
                let ior = material.ior().unwrap_or(1.5);
                let base_color = Vec4::from(pbr.base_color_factor());
                let checks: [(bool, Pointer, String); 4] = [
                    (
                        ior >= 1.0,
                        pointer
                            .key("extensions")
                            .key("KHR_materials_ior")
                            .key("ior"),
                        format!("ior must be at least 1 (found {ior})"),
                    ),
                    (
                        emissive_strength >= 0.0,
                        pointer
                            .key("extensions")
                            .key("KHR_materials_emissive_strength")
                            .key("emissiveStrength"),
                        format!(
                            "emissiveStrength must not be negative (found {emissive_strength})"
                        ),
                    ),
                    (
                        base_color.min_element() >= 0.0 && base_color.max_element() <= 1.0,
                        pointer.key("pbrMetallicRoughness").key("baseColorFactor"),
                        format!("baseColorFactor must lie in [0, 1] (found {base_color})"),
                    ),
                    (
                        (0.0..=1.0).contains(&pbr.metallic_factor())
                            && (0.0..=1.0).contains(&pbr.roughness_factor()),
                        pointer.key("pbrMetallicRoughness"),
                        "metallicFactor and roughnessFactor must lie in [0, 1]".to_owned(),
                    ),
                ];
                if let Some((_, pointer, message)) = checks.into_iter().find(|(ok, _, _)| !ok) {
                    return Err(self.error(pointer, message));
                }
                Ok(Material {
                    name: material.name().unwrap_or_default().to_owned(),
                    base_color,
                    base_color_texture: pbr
                        .base_color_texture()
                        .map(|info| texture_ref(&info, ColorEncoding::Srgb)),
                    metallic: pbr.metallic_factor(),
                    roughness: pbr.roughness_factor(),
                    metallic_roughness_texture: pbr
                        .metallic_roughness_texture()
                        .map(|info| texture_ref(&info, ColorEncoding::Linear)),
                    normal_texture: material.normal_texture().map(|normal| TextureRef {
                        texture: normal.texture().index(),
                        uv_set: normal.tex_coord(),
                        encoding: ColorEncoding::Linear,
                        uv_transform: Affine2::IDENTITY,
                    }),
                    normal_scale: material
                        .normal_texture()
                        .map_or(1.0, |normal| normal.scale()),
                    emissive: Vec3::from(material.emissive_factor()) * emissive_strength,
                    emissive_texture: material
                        .emissive_texture()
                        .map(|info| texture_ref(&info, ColorEncoding::Srgb)),
                    transmission: material
                        .transmission()
                        .map_or(0.0, |t| t.transmission_factor()),
                    ior,
                    alpha_mode: match material.alpha_mode() {
                        gltf::material::AlphaMode::Opaque => AlphaMode::Opaque,
                        gltf::material::AlphaMode::Mask => AlphaMode::Mask {
                            cutoff: material.alpha_cutoff().unwrap_or(0.5),
                        },
                        gltf::material::AlphaMode::Blend => AlphaMode::Blend,
                    },
                    double_sided: material.double_sided(),
                })
            })
            .collect()
    }

    // ---- nodes, cameras, lights ----------------------------------------------------------

    fn nodes(&self) -> Checked<Vec<Node>> {
        let nodes: Vec<Node> = self
            .document
            .nodes()
            .map(|node| Node {
                name: node.name().unwrap_or_default().to_owned(),
                transform: match node.transform() {
                    gltf::scene::Transform::Matrix { matrix } => {
                        NodeTransform::Matrix(Mat4::from_cols_array_2d(&matrix))
                    }
                    gltf::scene::Transform::Decomposed {
                        translation,
                        rotation,
                        scale,
                    } => NodeTransform::Trs {
                        translation: Vec3::from(translation),
                        rotation: Quat::from_array(rotation).normalize(),
                        scale: Vec3::from(scale),
                    },
                },
                children: node.children().map(|child| child.index()).collect(),
                mesh: node.mesh().map(|mesh| mesh.index()),
                camera: node.camera().map(|camera| camera.index()),
                light: node.light().map(|light| light.index()),
                skin: node.skin().map(|skin| skin.index()),
                morph_weights: node.weights().map(<[f32]>::to_vec),
            })
            .collect();
        // The hierarchy must be a forest: one parent at most, and no cycles.
        let mut parent = vec![None; nodes.len()];
        for (index, node) in nodes.iter().enumerate() {
            for &child in &node.children {
                if let Some(first) = parent[child].replace(index) {
                    return Err(self.error(
                        Pointer::root().key("nodes").index(index).key("children"),
                        format!("node {child} already has parent {first}; glTF nodes have one parent at most"),
                    ));
                }
            }
        }
        for start in 0..nodes.len() {
            let mut current = start;
            for _ in 0..=nodes.len() {
                match parent[current] {
                    Some(up) if up == start => {
                        return Err(self.error(
                            Pointer::root().key("nodes").index(start),
                            "node hierarchy has a cycle",
                        ));
                    }
                    Some(up) => current = up,
                    None => break,
                }
            }
        }
        Ok(nodes)
    }

    fn roots(&self, nodes: &[Node]) -> Checked<Vec<usize>> {
        let scene = self
            .document
            .default_scene()
            .or_else(|| self.document.scenes().next());
        Ok(match scene {
            Some(scene) => scene.nodes().map(|node| node.index()).collect(),
            None => {
                let mut has_parent = vec![false; nodes.len()];
                nodes
                    .iter()
                    .flat_map(|n| &n.children)
                    .for_each(|&c| has_parent[c] = true);
                (0..nodes.len()).filter(|&i| !has_parent[i]).collect()
            }
        })
    }

    fn cameras(&self) -> Checked<Vec<Camera>> {
        self.document
            .cameras()
            .map(|camera| {
                let projection = match camera.projection() {
                    gltf::camera::Projection::Perspective(p) => {
                        if !(p.yfov() > 0.0 && p.yfov() < std::f32::consts::PI) {
                            return Err(self.error(
                                Pointer::root()
                                    .key("cameras")
                                    .index(camera.index())
                                    .key("perspective")
                                    .key("yfov"),
                                format!("yfov must lie in (0, pi) radians (found {})", p.yfov()),
                            ));
                        }
                        Projection::Perspective {
                            yfov: p.yfov(),
                            aspect_ratio: p.aspect_ratio(),
                            znear: p.znear(),
                            zfar: p.zfar(),
                        }
                    }
                    gltf::camera::Projection::Orthographic(o) => Projection::Orthographic {
                        xmag: o.xmag(),
                        ymag: o.ymag(),
                        znear: o.znear(),
                        zfar: o.zfar(),
                    },
                };
                Ok(Camera {
                    name: camera.name().unwrap_or_default().to_owned(),
                    projection,
                })
            })
            .collect()
    }

    fn lights(&self) -> Checked<Vec<Light>> {
        let Some(lights) = self.document.lights() else {
            return Ok(Vec::new());
        };
        lights
            .map(|light| {
                let pointer = Pointer::root()
                    .key("extensions")
                    .key("KHR_lights_punctual")
                    .key("lights")
                    .index(light.index());
                if light.intensity() < 0.0 {
                    return Err(self.error(
                        pointer.key("intensity"),
                        "light intensity must not be negative",
                    ));
                }
                Ok(Light {
                    name: light.name().unwrap_or_default().to_owned(),
                    kind: match light.kind() {
                        gltf::khr_lights_punctual::Kind::Directional => LightKind::Directional,
                        gltf::khr_lights_punctual::Kind::Point => LightKind::Point,
                        gltf::khr_lights_punctual::Kind::Spot {
                            inner_cone_angle,
                            outer_cone_angle,
                        } => LightKind::Spot {
                            inner_cone_angle,
                            outer_cone_angle,
                        },
                    },
                    color: Vec3::from(light.color()),
                    intensity: light.intensity(),
                    range: light.range(),
                })
            })
            .collect()
    }

    // ---- skins and animations ------------------------------------------------------------

    fn skins(&self) -> Checked<Vec<Skin>> {
        self.document
            .skins()
            .map(|skin| {
                let joints: Vec<usize> = skin.joints().map(|joint| joint.index()).collect();
                let inverse_bind_matrices = match skin.inverse_bind_matrices() {
                    Some(accessor) => {
                        let flat = self.read_f32_elements(
                            &accessor,
                            Dimensions::Mat4,
                            "inverseBindMatrices",
                        )?;
                        if flat.len() / 16 != joints.len() {
                            return Err(self.error(
                                Pointer::root()
                                    .key("skins")
                                    .index(skin.index())
                                    .key("inverseBindMatrices"),
                                format!(
                                    "{} inverse bind matrices for {} joints",
                                    flat.len() / 16,
                                    joints.len()
                                ),
                            ));
                        }
                        flat.chunks_exact(16).map(Mat4::from_cols_slice).collect()
                    }
                    None => vec![Mat4::IDENTITY; joints.len()],
                };
                Ok(Skin {
                    name: skin.name().unwrap_or_default().to_owned(),
                    joints,
                    inverse_bind_matrices,
                    skeleton: skin.skeleton().map(|node| node.index()),
                })
            })
            .collect()
    }

    /// Cross-checks what skinning, morphing and animation will index, once every part has
    /// loaded: each is then safe to evaluate without further checks.
    fn check_deformation(&self, asset: &Asset) -> Option<Diagnostic> {
        for (node_index, node) in asset.nodes.iter().enumerate() {
            let Some(mesh_index) = node.mesh else {
                continue;
            };
            let mesh = &asset.meshes[mesh_index];
            let mesh_pointer = Pointer::root().key("meshes").index(mesh_index);
            let targets = mesh.primitives.first().map_or(0, |p| p.morph_targets.len());
            for (primitive_index, primitive) in mesh.primitives.iter().enumerate() {
                let pointer = mesh_pointer.key("primitives").index(primitive_index);
                if primitive.morph_targets.len() != targets {
                    return Some(self.error(
                        pointer.key("targets"),
                        format!(
                            "primitive has {} morph targets but the mesh's first has {targets} (glTF requires the same number)",
                            primitive.morph_targets.len()
                        ),
                    ));
                }
                let Some(skin) = node.skin.map(|s| &asset.skins[s]) else {
                    continue;
                };
                if primitive.skin_influences.is_empty() {
                    return Some(self.error(
                        pointer.key("attributes"),
                        format!("node {node_index} skins this mesh but the primitive has no JOINTS_0/WEIGHTS_0"),
                    ));
                }
                for (set, influences) in primitive.skin_influences.iter().enumerate() {
                    if let Some(joint) = influences
                        .joints
                        .iter()
                        .flatten()
                        .find(|&&j| j as usize >= skin.joints.len())
                    {
                        return Some(self.error(
                            pointer.key("attributes").key(&format!("JOINTS_{set}")),
                            format!(
                                "joint index {joint} is past the {} joints of skin '{}'",
                                skin.joints.len(),
                                skin.name
                            ),
                        ));
                    }
                }
            }
            for (weights, pointer) in [
                (Some(&mesh.morph_weights), mesh_pointer.key("weights")),
                (
                    node.morph_weights.as_ref(),
                    Pointer::root()
                        .key("nodes")
                        .index(node_index)
                        .key("weights"),
                ),
            ] {
                if let Some(weights) = weights.filter(|w| !w.is_empty() && w.len() != targets) {
                    return Some(self.error(
                        pointer,
                        format!("{} weights for {targets} morph targets", weights.len()),
                    ));
                }
            }
        }
        for (skin_index, skin) in asset.skins.iter().enumerate() {
            if skin.joints.is_empty() || skin.inverse_bind_matrices.len() != skin.joints.len() {
                return Some(self.error(
                    Pointer::root().key("skins").index(skin_index),
                    format!(
                        "skin has {} joints and {} inverse bind matrices",
                        skin.joints.len(),
                        skin.inverse_bind_matrices.len()
                    ),
                ));
            }
        }
        for (animation_index, animation) in asset.animations.iter().enumerate() {
            for (channel_index, channel) in animation.channels.iter().enumerate() {
                let sampler = &animation.samplers[channel.sampler];
                let expected = match channel.property {
                    AnimatedProperty::Translation | AnimatedProperty::Scale => 3,
                    AnimatedProperty::Rotation => 4,
                    AnimatedProperty::MorphWeights => asset.nodes[channel.node]
                        .mesh
                        .and_then(|m| asset.meshes[m].primitives.first())
                        .map_or(0, |p| p.morph_targets.len()),
                };
                if sampler.components != expected || expected == 0 {
                    return Some(self.error(
                        Pointer::root()
                            .key("animations")
                            .index(animation_index)
                            .key("channels")
                            .index(channel_index),
                        format!(
                            "{:?} channel's sampler gives {} values per key, but node {} needs {expected}",
                            channel.property, sampler.components, channel.node
                        ),
                    ));
                }
            }
        }
        None
    }

    fn animations(&self) -> Checked<Vec<Animation>> {
        use gltf::animation::{Interpolation as GltfInterpolation, Property};
        self.document
            .animations()
            .map(|animation| {
                let pointer = Pointer::root().key("animations").index(animation.index());
                let samplers = animation
                    .samplers()
                    .enumerate()
                    .map(|(sampler_index, sampler)| {
                        let sampler_pointer = pointer.key("samplers").index(sampler_index);
                        let times = self.read_f32_elements(
                            &sampler.input(),
                            Dimensions::Scalar,
                            "animation input",
                        )?;
                        if times.windows(2).any(|w| w[0] > w[1])
                            || times.iter().any(|t| !t.is_finite())
                        {
                            return Err(self.error(
                                sampler_pointer.key("input"),
                                "keyframe times must be finite and increasing",
                            ));
                        }
                        let interpolation = match sampler.interpolation() {
                            GltfInterpolation::Linear => Interpolation::Linear,
                            GltfInterpolation::Step => Interpolation::Step,
                            GltfInterpolation::CubicSpline => Interpolation::CubicSpline,
                        };
                        let (values, _) = self.read_accessor::<f32>(&sampler.output())?;
                        // Rule: a pose is built by multiplying these down the node tree; a
                        // value past MAX_COORDINATE (or not a number) overflows f32 there
                        // and breaks the BVH builds that follow.
                        if let Some(at) = values
                            .iter()
                            .position(|v| !(v.is_finite() && v.abs() <= MAX_COORDINATE))
                        {
                            return Err(self.error(
                                Pointer::root()
                                    .key("accessors")
                                    .index(sampler.output().index()),
                                format!(
                                    "animation output value {at} is {:e} (outputs must be finite and within {MAX_COORDINATE:e})",
                                    values[at]
                                ),
                            ));
                        }
                        let per_key = if interpolation == Interpolation::CubicSpline {
                            3
                        } else {
                            1
                        };
                        let elements = times.len() * per_key;
                        if elements == 0 || values.len() % elements != 0 {
                            return Err(self.error(
                                sampler_pointer.key("output"),
                                format!(
                                    "{} output values do not divide into {} keyframes",
                                    values.len(),
                                    times.len()
                                ),
                            ));
                        }
                        Ok(AnimationSampler {
                            interpolation,
                            components: values.len() / elements,
                            times,
                            values,
                        })
                    })
                    .collect::<Checked<Vec<_>>>()?;
                let channels = animation
                    .channels()
                    .map(|channel| AnimationChannel {
                        sampler: channel.sampler().index(),
                        node: channel.target().node().index(),
                        property: match channel.target().property() {
                            Property::Translation => AnimatedProperty::Translation,
                            Property::Rotation => AnimatedProperty::Rotation,
                            Property::Scale => AnimatedProperty::Scale,
                            Property::MorphTargetWeights => AnimatedProperty::MorphWeights,
                        },
                    })
                    .collect();
                Ok(Animation {
                    name: animation.name().unwrap_or_default().to_owned(),
                    channels,
                    samplers,
                })
            })
            .collect()
    }
}

fn texture_ref(info: &gltf::texture::Info, encoding: ColorEncoding) -> TextureRef {
    let (uv_set, uv_transform) = match info.texture_transform() {
        // KHR_texture_transform: uv' = T * R * S * uv, with R rotating by -rotation.
        Some(transform) => {
            let (sin, cos) = transform.rotation().sin_cos();
            let rotation = Mat2::from_cols(Vec2::new(cos, -sin), Vec2::new(sin, cos));
            let scale = Mat2::from_diagonal(Vec2::from(transform.scale()));
            (
                transform.tex_coord().unwrap_or(info.tex_coord()),
                Affine2::from_mat2_translation(rotation * scale, Vec2::from(transform.offset())),
            )
        }
        None => (info.tex_coord(), Affine2::IDENTITY),
    };
    TextureRef {
        texture: info.texture().index(),
        uv_set,
        encoding,
        uv_transform,
    }
}

/// Converts a corner list in `mode` to triangles.
fn triangulate(mode: gltf::mesh::Mode, corners: &[u32]) -> Result<Vec<[u32; 3]>, String> {
    use gltf::mesh::Mode;
    Ok(match mode {
        Mode::Triangles => {
            if corners.len() % 3 != 0 {
                return Err(format!(
                    "triangle list has {} indices, not a multiple of 3",
                    corners.len()
                ));
            }
            corners
                .chunks_exact(3)
                .map(|c| [c[0], c[1], c[2]])
                .collect()
        }
        // Strips alternate winding so every triangle keeps the first one's orientation.
        Mode::TriangleStrip => (0..corners.len().saturating_sub(2))
            .map(|i| {
                if i % 2 == 0 {
                    [corners[i], corners[i + 1], corners[i + 2]]
                } else {
                    [corners[i + 1], corners[i], corners[i + 2]]
                }
            })
            .collect(),
        Mode::TriangleFan => (1..corners.len().saturating_sub(1))
            .map(|i| [corners[0], corners[i], corners[i + 1]])
            .collect(),
        _ => Vec::new(),
    })
}

/// Gives every triangle its own three vertices and its face normal (glTF: "When normals
/// are not specified, client implementations MUST calculate flat normals").
fn unweld_with_flat_normals(primitive: &mut Primitive) {
    fn unweld<T: Copy>(values: &[T], indices: &[[u32; 3]]) -> Vec<T> {
        if values.is_empty() {
            return Vec::new();
        }
        indices
            .iter()
            .flatten()
            .map(|&i| values[i as usize])
            .collect()
    }
    let indices = std::mem::take(&mut primitive.indices);
    primitive.normals = indices
        .iter()
        .flat_map(|&[a, b, c]| {
            let [a, b, c] = [a, b, c].map(|i| primitive.positions[i as usize]);
            let normal = (b - a).cross(c - a).normalize_or(Vec3::Y);
            [normal; 3]
        })
        .collect();
    primitive.positions = unweld(&primitive.positions, &indices);
    primitive.uv0 = unweld(&primitive.uv0, &indices);
    primitive.uv1 = unweld(&primitive.uv1, &indices);
    for set in &mut primitive.skin_influences {
        set.joints = unweld(&set.joints, &indices);
        set.weights = unweld(&set.weights, &indices);
    }
    for target in &mut primitive.morph_targets {
        target.positions = unweld(&target.positions, &indices);
        target.normals = unweld(&target.normals, &indices);
    }
    primitive.indices = (0..indices.len() as u32)
        .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
        .collect();
}

/// Decodes `%XX` escapes in a relative URI.
fn percent_decode(uri: &str) -> PathBuf {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%'
            && let Some(value) = uri
                .get(i + 1..i + 3)
                .and_then(|hex| u8::from_str_radix(hex, 16).ok())
        {
            out.push(value);
            i += 3;
            continue;
        }
        out.push(bytes[i]);
        i += 1;
    }
    PathBuf::from(String::from_utf8_lossy(&out).into_owned())
}

/// A value an accessor component can be decoded into.
trait Component: Copy + Send {
    const ZERO: Self;
    fn accepts(data_type: DataType) -> bool;
    /// Appends `count` elements of `dims` components, `stride` bytes apart, from `bytes`
    /// (already bounds-checked by the caller).
    fn decode_strided(
        bytes: &[u8],
        data_type: DataType,
        normalized: bool,
        count: usize,
        dims: usize,
        stride: usize,
        out: &mut Vec<Self>,
    );
}

macro_rules! decode_loop {
    ($bytes:expr, $count:expr, $dims:expr, $stride:expr, $out:expr, $size:expr, |$chunk:ident| $convert:expr) => {{
        for element in 0..$count {
            let base = element * $stride;
            for component in 0..$dims {
                let offset = base + component * $size;
                let $chunk: [u8; $size] = $bytes[offset..offset + $size]
                    .try_into()
                    .expect("checked size");
                $out.push($convert);
            }
        }
    }};
}

impl Component for f32 {
    const ZERO: Self = 0.0;

    fn accepts(_: DataType) -> bool {
        true
    }

    fn decode_strided(
        bytes: &[u8],
        data_type: DataType,
        normalized: bool,
        count: usize,
        dims: usize,
        stride: usize,
        out: &mut Vec<f32>,
    ) {
        // glTF 2.0 spec 3.11: normalized integers map to [0, 1] or [-1, 1].
        match (data_type, normalized) {
            (DataType::F32, _) => {
                decode_loop!(bytes, count, dims, stride, out, 4, |c| f32::from_le_bytes(
                    c
                ))
            }
            (DataType::I8, true) => decode_loop!(bytes, count, dims, stride, out, 1, |c| {
                (i8::from_le_bytes(c) as f32 / 127.0).max(-1.0)
            }),
            (DataType::U8, true) => {
                decode_loop!(bytes, count, dims, stride, out, 1, |c| c[0] as f32 / 255.0)
            }
            (DataType::I16, true) => decode_loop!(bytes, count, dims, stride, out, 2, |c| {
                (i16::from_le_bytes(c) as f32 / 32767.0).max(-1.0)
            }),
            (DataType::U16, true) => {
                decode_loop!(
                    bytes,
                    count,
                    dims,
                    stride,
                    out,
                    2,
                    |c| u16::from_le_bytes(c) as f32 / 65535.0
                )
            }
            (DataType::U32, true) => {
                decode_loop!(
                    bytes,
                    count,
                    dims,
                    stride,
                    out,
                    4,
                    |c| u32::from_le_bytes(c) as f32 / u32::MAX as f32
                )
            }
            (DataType::I8, false) => {
                decode_loop!(bytes, count, dims, stride, out, 1, |c| i8::from_le_bytes(c)
                    as f32)
            }
            (DataType::U8, false) => {
                decode_loop!(bytes, count, dims, stride, out, 1, |c| c[0] as f32)
            }
            (DataType::I16, false) => {
                decode_loop!(
                    bytes,
                    count,
                    dims,
                    stride,
                    out,
                    2,
                    |c| i16::from_le_bytes(c) as f32
                )
            }
            (DataType::U16, false) => {
                decode_loop!(
                    bytes,
                    count,
                    dims,
                    stride,
                    out,
                    2,
                    |c| u16::from_le_bytes(c) as f32
                )
            }
            (DataType::U32, false) => {
                decode_loop!(
                    bytes,
                    count,
                    dims,
                    stride,
                    out,
                    4,
                    |c| u32::from_le_bytes(c) as f32
                )
            }
        }
    }
}

impl Component for u32 {
    const ZERO: Self = 0;

    fn accepts(data_type: DataType) -> bool {
        matches!(data_type, DataType::U8 | DataType::U16 | DataType::U32)
    }

    fn decode_strided(
        bytes: &[u8],
        data_type: DataType,
        _: bool,
        count: usize,
        dims: usize,
        stride: usize,
        out: &mut Vec<u32>,
    ) {
        match data_type {
            DataType::U8 => decode_loop!(bytes, count, dims, stride, out, 1, |c| c[0] as u32),
            DataType::U16 => decode_loop!(
                bytes,
                count,
                dims,
                stride,
                out,
                2,
                |c| u16::from_le_bytes(c) as u32
            ),
            DataType::U32 => {
                decode_loop!(bytes, count, dims, stride, out, 4, |c| u32::from_le_bytes(
                    c
                ))
            }
            _ => debug_assert!(
                false,
                "u32 decode of {data_type:?} was refused by accepts()"
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A panic inside the import (in a dependency's accessor, say) is the file's
    /// diagnostic, and the thread goes on importing: the next file is read as usual.
    #[test]
    fn a_panic_inside_an_import_is_a_diagnostic_naming_the_file() {
        let path = Path::new("broken.glb");
        let error = contained(path, || panic!("index out of bounds")).unwrap_err();
        let line = error.to_string();
        assert!(line.starts_with("broken.glb"), "{line}");
        assert!(line.contains("index out of bounds"), "{line}");
        assert!(!CONTAINED.with(std::cell::Cell::get));
        let text = br#"{"asset": {"version": "2.0"}}"#;
        assert!(import_gltf_bytes(Path::new("empty.gltf"), text).is_ok());
    }

    /// Subnormal coordinates arrive as zero; normal ones, however small, as they are.
    #[test]
    fn subnormal_positions_are_flushed_to_zero() {
        let values = [1.0e-40_f32, 2.0, -3.0e-39, 1.0e-37, 0.0, 5.0, 1.0, 1.0, 1.0];
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        let text = format!(
            r#"{{"asset": {{"version": "2.0"}},
                "buffers": [{{"byteLength": 36, "uri": "data:application/octet-stream;base64,{}"}}],
                "bufferViews": [{{"buffer": 0, "byteLength": 36}}],
                "accessors": [{{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                                "min": [0, 0, -3e-39], "max": [1, 5, 1]}}],
                "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}}}]}}]}}"#,
            base64::engine::general_purpose::STANDARD.encode(&bytes)
        );
        let asset = import_gltf_bytes(Path::new("tiny.gltf"), text.as_bytes()).unwrap();
        assert_eq!(
            asset.meshes[0].primitives[0].positions,
            [
                Vec3::new(0.0, 2.0, 0.0),
                Vec3::new(1.0e-37, 0.0, 5.0),
                Vec3::ONE
            ]
        );
    }

    #[test]
    fn strips_and_fans_keep_orientation() {
        use gltf::mesh::Mode;
        assert_eq!(
            triangulate(Mode::TriangleStrip, &[0, 1, 2, 3]).unwrap(),
            vec![[0, 1, 2], [2, 1, 3]]
        );
        assert_eq!(
            triangulate(Mode::TriangleFan, &[0, 1, 2, 3]).unwrap(),
            vec![[0, 1, 2], [0, 2, 3]]
        );
        assert!(triangulate(Mode::Triangles, &[0, 1]).is_err());
    }

    #[test]
    fn normalized_integers_follow_the_spec() {
        let mut out = Vec::new();
        f32::decode_strided(&[0x80, 0x81, 0x7f], DataType::I8, true, 3, 1, 1, &mut out);
        assert_eq!(out, vec![-1.0, -1.0, 1.0]);
    }

    #[test]
    fn percent_escapes_decode() {
        assert_eq!(percent_decode("a%20b.bin"), PathBuf::from("a b.bin"));
        assert_eq!(percent_decode("bad%zz"), PathBuf::from("bad%zz"));
    }
}
