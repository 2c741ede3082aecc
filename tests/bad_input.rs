//! Bad input of every kind gets a diagnostic naming the file and the place, never a panic.
//!
//! Each case writes a broken file into a scratch folder, loads it the way `gloam check`
//! does, and asserts on the `file:line:column: message` text a user would see.

mod common;

use std::path::Path;

use base64::Engine as _;
use gloam::scene::Scene;

/// A valid one-triangle glTF whose buffer is embedded as a data URI; `edit` changes the
/// JSON value before it is written.
fn triangle_gltf(edit: impl FnOnce(&mut serde_json::Value)) -> String {
    let mut bytes = Vec::new();
    for v in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
        bytes.extend(v.to_le_bytes());
    }
    for i in [0u16, 1, 2, 0] {
        bytes.extend(i.to_le_bytes());
    }
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&bytes)
    );
    let mut json = serde_json::json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"name": "triangle", "mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}]}],
        "materials": [{"name": "white", "pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 1]}}],
        "buffers": [{"byteLength": 44, "uri": uri}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 36},
            {"buffer": 0, "byteOffset": 36, "byteLength": 6}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
            {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}
        ]
    });
    edit(&mut json);
    serde_json::to_string_pretty(&json).unwrap()
}

/// Loads `path`, expects failure, and returns every diagnostic line.
fn errors_of(path: &Path) -> Vec<String> {
    match Scene::load(path) {
        Ok(_) => panic!("{} loaded, but it is broken", path.display()),
        Err(error) => error.diagnostics.iter().map(ToString::to_string).collect(),
    }
}

/// Asserts some diagnostic names `file` with `line` (when given) and contains every needle.
fn assert_reported(path: &Path, file_name: &str, line: Option<usize>, needles: &[&str]) {
    let lines = errors_of(path);
    let found = lines.iter().any(|message| {
        let place = match line {
            Some(line) => message.contains(&format!("{file_name}:{line}:")),
            None => message.contains(&format!("{file_name}:")),
        };
        place && needles.iter().all(|needle| message.contains(needle))
    });
    assert!(
        found,
        "no diagnostic with {file_name}:{line:?} and {needles:?} in:\n{}",
        lines.join("\n")
    );
}

/// Line (1-based) of the first occurrence of `needle` in `text`.
fn line_of(text: &str, needle: &str) -> usize {
    text.lines()
        .position(|l| l.contains(needle))
        .expect("needle in text")
        + 1
}

#[test]
fn the_valid_triangle_loads() {
    let dir = common::scratch_dir("valid");
    let path = common::write(&dir, "ok.gltf", triangle_gltf(|_| {}));
    let scene = Scene::load(&path).unwrap();
    assert_eq!(scene.triangle_count(), 1);
}

#[test]
fn truncated_json_reports_line_and_column() {
    let dir = common::scratch_dir("truncated");
    let text = triangle_gltf(|_| {});
    let cut = &text[..text.len() / 2];
    let path = common::write(&dir, "truncated.gltf", cut);
    let last_line = cut.lines().count();
    assert_reported(
        &path,
        "truncated.gltf",
        Some(last_line),
        &["invalid glTF JSON", "EOF"],
    );
}

#[test]
fn missing_buffer_file_names_the_uri() {
    let dir = common::scratch_dir("missing-buffer");
    let text = triangle_gltf(|json| json["buffers"][0]["uri"] = "geometry.bin".into());
    let path = common::write(&dir, "missing-buffer.gltf", &text);
    assert_reported(
        &path,
        "missing-buffer.gltf",
        Some(line_of(&text, "geometry.bin")),
        &["/buffers/0/uri", "geometry.bin", "cannot read"],
    );
}

#[test]
fn bad_base64_names_the_buffer() {
    let dir = common::scratch_dir("base64");
    let text = triangle_gltf(|json| {
        json["buffers"][0]["uri"] = "data:application/octet-stream;base64,@@not base64@@".into()
    });
    let path = common::write(&dir, "bad-base64.gltf", &text);
    assert_reported(
        &path,
        "bad-base64.gltf",
        Some(line_of(&text, "@@not base64")),
        &["bad base64", "/buffers/0/uri"],
    );
}

#[test]
fn accessor_past_its_buffer_view_is_out_of_range() {
    let dir = common::scratch_dir("accessor");
    let text = triangle_gltf(|json| json["accessors"][0]["count"] = 300.into());
    let path = common::write(&dir, "accessor.gltf", &text);
    assert_reported(
        &path,
        "accessor.gltf",
        None,
        &["/accessors/0", "300 elements", "36 bytes"],
    );
}

#[test]
fn buffer_view_past_its_buffer_is_reported() {
    let dir = common::scratch_dir("view");
    let text = triangle_gltf(|json| json["bufferViews"][1]["byteOffset"] = 4000.into());
    let path = common::write(&dir, "view.gltf", &text);
    assert_reported(
        &path,
        "view.gltf",
        None,
        &["/bufferViews/1", "buffer 0 has only"],
    );
}

#[test]
fn index_beyond_the_vertices_is_reported() {
    let dir = common::scratch_dir("index");
    // Read the indices as u32 from the positions' bytes at 1.0f32 (0x3f800000): a huge index.
    let text = triangle_gltf(|json| {
        json["accessors"][1]["bufferView"] = 0.into();
        json["accessors"][1]["byteOffset"] = 12.into();
        json["accessors"][1]["componentType"] = 5125.into();
    });
    let path = common::write(&dir, "index.gltf", &text);
    assert_reported(
        &path,
        "index.gltf",
        None,
        &[
            "/meshes/0/primitives/0/indices",
            "out of range for 3 vertices",
        ],
    );
}

#[test]
fn dangling_reference_is_reported_by_path() {
    let dir = common::scratch_dir("reference");
    let text = triangle_gltf(|json| {
        json["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = 9.into()
    });
    let path = common::write(&dir, "reference.gltf", &text);
    assert_reported(
        &path,
        "reference.gltf",
        None,
        &[
            "index out of range",
            "/meshes/0/primitives/0/attributes/POSITION",
        ],
    );
}

#[test]
fn unknown_required_extension_is_named() {
    let dir = common::scratch_dir("extension");
    let text = triangle_gltf(|json| {
        json["extensionsUsed"] = serde_json::json!(["EXT_imaginary_compression"]);
        json["extensionsRequired"] = serde_json::json!(["EXT_imaginary_compression"]);
    });
    let path = common::write(&dir, "extension.gltf", &text);
    let line = line_of(&text, "\"extensionsRequired\"") + 1;
    assert_reported(
        &path,
        "extension.gltf",
        Some(line),
        &[
            "required extension 'EXT_imaginary_compression' is not supported",
            "/extensionsRequired/0",
        ],
    );
}

#[test]
fn negative_ior_in_gltf_is_reported() {
    let dir = common::scratch_dir("gltf-ior");
    let text = triangle_gltf(|json| {
        json["extensionsUsed"] = serde_json::json!(["KHR_materials_ior"]);
        json["materials"][0]["extensions"] =
            serde_json::json!({"KHR_materials_ior": {"ior": -1.5}});
    });
    let path = common::write(&dir, "ior.gltf", &text);
    assert_reported(
        &path,
        "ior.gltf",
        Some(line_of(&text, "-1.5")),
        &[
            "ior must be at least 1",
            "/materials/0/extensions/KHR_materials_ior/ior",
        ],
    );
}

#[test]
fn undecodable_image_is_reported() {
    let dir = common::scratch_dir("image");
    let text = triangle_gltf(|json| {
        json["images"] = serde_json::json!([{"uri": "data:image/png;base64,aGVsbG8="}]);
    });
    let path = common::write(&dir, "image.gltf", &text);
    assert_reported(
        &path,
        "image.gltf",
        None,
        &["/images/0", "cannot decode image"],
    );
}

#[test]
fn an_image_without_its_data_or_its_type_is_reported_not_a_panic() {
    let dir = common::scratch_dir("image-source");
    for (name, image, expected) in [
        (
            "nothing.gltf",
            serde_json::json!({"mimeType": "image/png"}),
            "an image needs a \"uri\" or a \"bufferView\"",
        ),
        (
            "untyped.gltf",
            serde_json::json!({"bufferView": 0}),
            "an image in a \"bufferView\" needs a \"mimeType\"",
        ),
    ] {
        let text = triangle_gltf(|json| json["images"] = serde_json::json!([image]));
        let path = common::write(&dir, name, &text);
        assert_reported(&path, name, None, &["/images/0", expected]);
    }
}

#[test]
fn truncated_and_garbage_glb_are_reported() {
    let dir = common::scratch_dir("glb");
    let mut glb = b"glTF".to_vec();
    glb.extend(2u32.to_le_bytes());
    glb.extend(4000u32.to_le_bytes()); // claims 4000 bytes
    glb.extend(b"short");
    let path = common::write(&dir, "short.glb", &glb);
    assert_reported(
        &path,
        "short.glb",
        Some(1),
        &["not a valid GLB", "truncated"],
    );

    let path = common::write(&dir, "noise.glb", [0xffu8, 0xfe, 0x00, 0x13]);
    assert_reported(&path, "noise.glb", Some(1), &["not a glTF file"]);
}

#[test]
fn unreadable_and_unknown_files_are_reported() {
    let dir = common::scratch_dir("missing-file");
    assert_reported(
        &dir.join("nowhere.ron"),
        "nowhere.ron",
        Some(1),
        &["cannot read level"],
    );
    assert_reported(
        &dir.join("nowhere.glb"),
        "nowhere.glb",
        Some(1),
        &["cannot read glTF file"],
    );
    let path = common::write(&dir, "notes.txt", "hello");
    assert_reported(&path, "notes.txt", Some(1), &["not a level"]);
}

// ---- levels ---------------------------------------------------------------------------------

/// A folder with a valid asset and a level whose text is `level`.
fn level_fixture(name: &str, level: &str) -> std::path::PathBuf {
    let dir = common::scratch_dir(name);
    common::write(&dir, "triangle.gltf", triangle_gltf(|_| {}));
    common::write(&dir, "level.ron", level)
}

const GOOD_LEVEL: &str = r#"(
    version: 1,
    name: "fixture",
    entities: [
        (
            name: "thing",
            transform: (translation: (1.0, 0.0, 0.0), scale: (1.0, 2.0, 1.0)),
            instance: (asset: "triangle.gltf", material_overrides: {"white": (roughness: 0.5)}),
        ),
        (name: "start", player_spawn: (eye_height: 1.6)),
    ],
)
"#;

#[test]
fn the_good_level_loads() {
    let path = level_fixture("good-level", GOOD_LEVEL);
    let scene = Scene::load(&path).unwrap();
    assert_eq!(scene.triangle_count(), 1);
    assert_eq!(scene.player_spawn().unwrap().1, 1.6);
}

fn broken_level(name: &str, from: &str, to: &str) -> (std::path::PathBuf, String) {
    assert!(GOOD_LEVEL.contains(from), "fixture lacks {from}");
    let text = GOOD_LEVEL.replacen(from, to, 1);
    (level_fixture(name, &text), text)
}

#[test]
fn ron_syntax_error_has_line_and_column() {
    let (path, text) = broken_level("syntax", "name: \"thing\",", "name: \"thing\" oops,");
    assert_reported(
        &path,
        "level.ron",
        Some(line_of(&text, "oops")),
        &["Expected"],
    );
}

#[test]
fn unknown_field_is_a_typo_not_a_default() {
    let (path, text) = broken_level("typo", "player_spawn:", "player_spwan:");
    assert_reported(
        &path,
        "level.ron",
        Some(line_of(&text, "player_spwan")),
        &["player_spwan"],
    );
}

#[test]
fn wrong_version_is_reported_at_the_version() {
    let (path, _) = broken_level("version", "version: 1", "version: 7");
    assert_reported(
        &path,
        "level.ron",
        Some(2),
        &["unsupported level version 7", "reads version 1"],
    );
}

#[test]
fn nan_translation_is_reported() {
    let (path, text) = broken_level(
        "nan",
        "translation: (1.0, 0.0, 0.0)",
        "translation: (1.0, NaN, 0.0)",
    );
    assert_reported(
        &path,
        "level.ron",
        Some(line_of(&text, "NaN")),
        &[
            "translation must be finite",
            "/entities/0/transform/translation",
        ],
    );
}

#[test]
fn negative_scale_is_reported() {
    let (path, text) = broken_level("scale", "scale: (1.0, 2.0, 1.0)", "scale: (1.0, -2.0, 1.0)");
    assert_reported(
        &path,
        "level.ron",
        Some(line_of(&text, "-2.0")),
        &["scale must be positive", "/entities/0/transform/scale"],
    );
}

#[test]
fn negative_ior_override_is_reported() {
    let (path, text) = broken_level("ior", "roughness: 0.5", "ior: -1.33");
    assert_reported(
        &path,
        "level.ron",
        Some(line_of(&text, "-1.33")),
        &[
            "ior must be at least 1",
            "/entities/0/instance/material_overrides/white/ior",
        ],
    );
}

#[test]
fn missing_asset_is_reported_at_its_reference() {
    let (path, text) = broken_level("missing-asset", "\"triangle.gltf\"", "\"gone.glb\"");
    assert_reported(
        &path,
        "level.ron",
        Some(line_of(&text, "gone.glb")),
        &["missing asset", "gone.glb"],
    );
}

#[test]
fn broken_asset_reports_both_places() {
    let path = level_fixture("broken-asset", GOOD_LEVEL);
    let asset = path.with_file_name("triangle.gltf");
    std::fs::write(&asset, "{ \"asset\": ").unwrap();
    assert_reported(
        &path,
        "level.ron",
        Some(line_of(GOOD_LEVEL, "triangle.gltf")),
        &["failed to load"],
    );
    assert_reported(&path, "triangle.gltf", Some(1), &["invalid glTF JSON"]);
}

#[test]
fn unknown_material_override_is_reported() {
    let (path, text) = broken_level("override", "{\"white\":", "{\"whit\":");
    assert_reported(
        &path,
        "level.ron",
        Some(line_of(&text, "whit")),
        &["has no material 'whit'", "white"],
    );
}

#[test]
fn playable_level_without_spawn_is_reported() {
    let (path, _) = broken_level(
        "spawn",
        "(name: \"start\", player_spawn: (eye_height: 1.6)),",
        "",
    );
    assert_reported(&path, "level.ron", None, &["no player spawn"]);
    // The same level as a showcase is fine.
    let text = GOOD_LEVEL
        .replace("(name: \"start\", player_spawn: (eye_height: 1.6)),", "")
        .replace("name: \"fixture\",", "name: \"fixture\", playable: false,");
    let path = level_fixture("showcase", &text);
    assert!(Scene::load(&path).is_ok());
}

#[test]
fn duplicate_names_and_bad_lights_are_all_listed() {
    let (path, text) = broken_level(
        "many",
        "(name: \"start\", player_spawn: (eye_height: 1.6)),",
        "(name: \"start\", player_spawn: (eye_height: 1.6)),\n        (name: \"thing\", light: Spot(color: (1.0, 1.0, 1.0), intensity: -5.0, inner_cone_degrees: 30.0, outer_cone_degrees: 10.0)),",
    );
    let line = line_of(&text, "Spot(");
    assert_reported(
        &path,
        "level.ron",
        Some(line),
        &["duplicate entity name 'thing'"],
    );
    assert_reported(
        &path,
        "level.ron",
        Some(line),
        &["intensity must be finite and not negative"],
    );
    assert_reported(
        &path,
        "level.ron",
        Some(line),
        &["0 <= inner < outer <= 90"],
    );
}

#[test]
fn a_lamps_fixture_must_name_an_instance() {
    let lamp = |fixture: &str| {
        format!(
            "(name: \"start\", player_spawn: (eye_height: 1.6)),\n        (name: \"lamp\", light: Point(color: (1.0, 1.0, 1.0), intensity: 5.0), fixture: \"{fixture}\"),"
        )
    };
    let (path, text) = broken_level(
        "fixture-missing",
        "(name: \"start\", player_spawn: (eye_height: 1.6)),",
        &lamp("bracket"),
    );
    let line = line_of(&text, "fixture:");
    assert_reported(
        &path,
        "level.ron",
        Some(line),
        &["no entity is named 'bracket'"],
    );
    let (path, _) = broken_level(
        "fixture-bare",
        "(name: \"start\", player_spawn: (eye_height: 1.6)),",
        &lamp("start"),
    );
    assert_reported(
        &path,
        "level.ron",
        Some(line),
        &["the fixture 'start' draws no instance"],
    );
    let (path, _) = broken_level(
        "fixture-good",
        "(name: \"start\", player_spawn: (eye_height: 1.6)),",
        &lamp("thing"),
    );
    assert!(Scene::load(&path).is_ok());
}

#[test]
fn unknown_animation_clip_is_reported_with_the_clips_there_are() {
    let (path, text) = broken_level(
        "clip",
        "material_overrides: {\"white\": (roughness: 0.5)}),",
        "material_overrides: {\"white\": (roughness: 0.5)}),\n            animation: (clip: \"walk\"),",
    );
    assert_reported(
        &path,
        "level.ron",
        Some(line_of(&text, "clip:")),
        &["has no animation clip 'walk'", "it has no animations"],
    );
}

#[test]
fn bad_deformer_and_animation_values_are_all_listed() {
    let (path, text) = broken_level(
        "deformer",
        "material_overrides: {\"white\": (roughness: 0.5)}),",
        "material_overrides: {\"white\": (roughness: 0.5)}),\n            deformer: Wave(amplitude: 0.1,\n wavelength: -1.0,\n period: 0.0),",
    );
    assert_reported(
        &path,
        "level.ron",
        Some(line_of(&text, "wavelength")),
        &["wavelength must be positive"],
    );
    assert_reported(
        &path,
        "level.ron",
        Some(line_of(&text, "period")),
        &["period must be positive"],
    );
    let (path, text) = broken_level(
        "speed",
        "(name: \"start\", player_spawn: (eye_height: 1.6)),",
        "(name: \"start\", player_spawn: (eye_height: 1.6),\n animation: (clip: \"x\", start: -1.0)),",
    );
    assert_reported(
        &path,
        "level.ron",
        Some(line_of(&text, "animation")),
        &["needs an `instance`"],
    );
    assert_reported(
        &path,
        "level.ron",
        Some(line_of(&text, "start:")),
        &["start must be finite and >= 0"],
    );
}

/// The triangle given a one-joint skin and an animation channel; `edit` breaks it.
fn skinned_triangle(edit: impl FnOnce(&mut serde_json::Value)) -> String {
    let mut bytes = Vec::new();
    for v in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
        bytes.extend(v.to_le_bytes());
    }
    for i in [0u16, 1, 2, 0] {
        bytes.extend(i.to_le_bytes());
    }
    // JOINTS_0 (u16 x 4 per vertex), WEIGHTS_0 (f32 x 4), times, rotations.
    for _ in 0..3 {
        for j in [0u16, 0, 0, 0] {
            bytes.extend(j.to_le_bytes());
        }
    }
    for _ in 0..3 {
        for w in [1.0f32, 0.0, 0.0, 0.0] {
            bytes.extend(w.to_le_bytes());
        }
    }
    for t in [0.0f32, 1.0] {
        bytes.extend(t.to_le_bytes());
    }
    for q in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0] {
        bytes.extend(q.to_le_bytes());
    }
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&bytes)
    );
    let mut json = serde_json::json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0, 1]}],
        "nodes": [{"name": "body", "mesh": 0, "skin": 0}, {"name": "bone"}],
        "skins": [{"joints": [1]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "JOINTS_0": 2, "WEIGHTS_0": 3}, "indices": 1}]}],
        "animations": [{"name": "spin", "channels": [{"sampler": 0, "target": {"node": 1, "path": "rotation"}}],
                        "samplers": [{"input": 4, "output": 5}]}],
        "buffers": [{"byteLength": bytes.len(), "uri": uri}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 36},
            {"buffer": 0, "byteOffset": 36, "byteLength": 6},
            {"buffer": 0, "byteOffset": 44, "byteLength": 24},
            {"buffer": 0, "byteOffset": 68, "byteLength": 48},
            {"buffer": 0, "byteOffset": 116, "byteLength": 8},
            {"buffer": 0, "byteOffset": 124, "byteLength": 32}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
            {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"},
            {"bufferView": 2, "componentType": 5123, "count": 3, "type": "VEC4"},
            {"bufferView": 3, "componentType": 5126, "count": 3, "type": "VEC4"},
            {"bufferView": 4, "componentType": 5126, "count": 2, "type": "SCALAR", "min": [0], "max": [1]},
            {"bufferView": 5, "componentType": 5126, "count": 2, "type": "VEC4"}
        ]
    });
    edit(&mut json);
    serde_json::to_string_pretty(&json).unwrap()
}

#[test]
fn broken_skins_and_channels_are_reported_at_their_place() {
    let dir = common::scratch_dir("skins");
    let good = common::write(&dir, "good.gltf", skinned_triangle(|_| {}));
    let scene = Scene::load(&good).unwrap();
    assert_eq!(
        scene.level.entities[0].animation.as_ref().unwrap().clip,
        "spin"
    );
    // The engine poses it without complaint.
    let engine = gloam::frame::Engine::new(&scene, gloam::render::RenderSettings::real_time(4, 4));
    assert_eq!(engine.deform_stats().deformed, 1);

    // A skin with no joints, which the vertices' joint 0 then falls outside of.
    let path = common::write(
        &dir,
        "no-joints.gltf",
        skinned_triangle(|json| json["skins"][0]["joints"] = serde_json::json!([])),
    );
    assert_reported(
        &path,
        "no-joints.gltf",
        None,
        &["JOINTS_0", "joint index 0 is past the 0 joints"],
    );
    // A rotation channel whose sampler gives 3 values per key.
    let path = common::write(
        &dir,
        "channel.gltf",
        skinned_triangle(|json| {
            json["animations"][0]["channels"][0]["target"]["path"] = "translation".into()
        }),
    );
    assert_reported(
        &path,
        "channel.gltf",
        None,
        &[
            "/animations/0/channels/0",
            "gives 4 values per key",
            "needs 3",
        ],
    );
    // A skinned mesh without JOINTS_0.
    let path = common::write(
        &dir,
        "unjointed.gltf",
        skinned_triangle(|json| {
            json["meshes"][0]["primitives"][0]["attributes"]
                .as_object_mut()
                .unwrap()
                .retain(|k, _| k == "POSITION")
        }),
    );
    assert_reported(
        &path,
        "unjointed.gltf",
        None,
        &["skins this mesh", "JOINTS_0"],
    );
}

#[test]
fn bad_knock_and_mover_values_are_reported_at_their_place() {
    let (path, text) = broken_level(
        "knock",
        "instance: (asset: \"triangle.gltf\", material_overrides: {\"white\": (roughness: 0.5)}),",
        "instance: (asset: \"triangle.gltf\"), knock: (radius: 0.0, noise: -1.0), mover: (offset: (0.0, 1.0, 0.0), period: 0.0),",
    );
    let line = Some(line_of(&text, "knock:"));
    assert_reported(&path, "level.ron", line, &["knock radius must be positive"]);
    assert_reported(
        &path,
        "level.ron",
        line,
        &["knock noise must be a distance of 0 or more"],
    );
    assert_reported(
        &path,
        "level.ron",
        line,
        &["a mover's period must be positive"],
    );
}

#[test]
fn bad_sound_values_and_a_missing_sound_file_are_reported_at_their_place() {
    let (path, text) = broken_level(
        "sound",
        "(name: \"start\", player_spawn: (eye_height: 1.6)),",
        "(name: \"start\", player_spawn: (eye_height: 1.6), sound: (asset: \"hum.png\", gain_db: 99.0)),",
    );
    let line = Some(line_of(&text, "sound:"));
    assert_reported(&path, "level.ron", line, &["sound 'hum.png' is not a .wav"]);
    assert_reported(
        &path,
        "level.ron",
        line,
        &["gain must be between -60 and 60 dB"],
    );
    let (path, text) = broken_level(
        "sound-missing",
        "name: \"fixture\",",
        "name: \"fixture\", environment: (ambience: (asset: \"wind.ogg\")),",
    );
    let line = Some(line_of(&text, "ambience:"));
    assert_reported(
        &path,
        "level.ron",
        line,
        &["missing sound", "wind.ogg", "no such file"],
    );
}

/// A triangle whose second vertex's x is `x`.
fn triangle_with_x(x: f32) -> String {
    triangle_gltf(|json| {
        let mut bytes = Vec::new();
        for v in [0.0f32, 0.0, 0.0, x, 0.0, 0.0, 0.0, 1.0, 0.0] {
            bytes.extend(v.to_le_bytes());
        }
        for i in [0u16, 1, 2, 0] {
            bytes.extend(i.to_le_bytes());
        }
        json["buffers"][0]["uri"] = serde_json::json!(format!(
            "data:application/octet-stream;base64,{}",
            base64::engine::general_purpose::STANDARD.encode(&bytes)
        ));
    })
}

/// Found by fuzzing import -> scene -> BLAS build: one NaN in a vertex passed `check` and
/// then panicked the BVH build. Non-finite floats are now refused at the accessor.
#[test]
fn a_nan_vertex_is_refused_at_its_accessor() {
    let dir = common::scratch_dir("gltf-nan");
    let path = common::write(&dir, "nan.gltf", triangle_with_x(f32::NAN));
    assert_reported(
        &path,
        "nan.gltf",
        None,
        &[
            "POSITION element 1 holds NaN (values must be finite)",
            "/accessors/0",
        ],
    );
}

/// Found by fuzzing: a finite but enormous coordinate (-4.8e32 m in a mutated mirror.glb)
/// passed `check` and panicked the wide BVH's traversal in `render`.
#[test]
fn an_enormous_vertex_is_refused_at_its_accessor() {
    let dir = common::scratch_dir("gltf-huge");
    let path = common::write(&dir, "huge.gltf", triangle_with_x(-4.8e32));
    assert_reported(
        &path,
        "huge.gltf",
        None,
        &[
            "POSITION element 1 is",
            "must lie within 1000000 m",
            "/accessors/0",
        ],
    );
}

/// Found by fuzzing: a GLB header declaring fewer bytes than the header itself overflowed
/// a subtraction inside the gltf crate (a panic in any build with overflow checks).
#[test]
fn a_glb_shorter_than_its_own_header_is_refused() {
    let dir = common::scratch_dir("glb-short");
    let mut bytes = b"glTF".to_vec();
    bytes.extend(2u32.to_le_bytes());
    bytes.extend(0u32.to_le_bytes());
    bytes.extend(b"\x10\x00\x00\x00JSON{}      ");
    let path = dir.join("short.glb");
    std::fs::write(&path, &bytes).unwrap();
    assert_reported(
        &path,
        "short.glb",
        Some(1),
        &["its header says 0 bytes, less than the 12-byte header itself"],
    );
}

/// The triangle with one translation clip of two keyframes, (0, 0, 0) then (0, `y`, 0),
/// on the channel `channel` (sampler 0).
fn triangle_with_clip(y: f32, channel: serde_json::Value) -> String {
    triangle_gltf(|json| {
        let mut bytes = Vec::new();
        for v in [0.0f32, 1.0, 0.0, 0.0, 0.0, 0.0, y, 0.0] {
            bytes.extend(v.to_le_bytes());
        }
        json["buffers"]
            .as_array_mut()
            .unwrap()
            .push(serde_json::json!({
                "byteLength": bytes.len(),
                "uri": format!(
                    "data:application/octet-stream;base64,{}",
                    base64::engine::general_purpose::STANDARD.encode(&bytes)
                ),
            }));
        let views = json["bufferViews"].as_array_mut().unwrap();
        views.push(serde_json::json!({"buffer": 1, "byteOffset": 0, "byteLength": 8}));
        views.push(serde_json::json!({"buffer": 1, "byteOffset": 8, "byteLength": 24}));
        let accessors = json["accessors"].as_array_mut().unwrap();
        accessors.push(serde_json::json!({"bufferView": 2, "componentType": 5126, "count": 2, "type": "SCALAR", "min": [0], "max": [1]}));
        accessors.push(
            serde_json::json!({"bufferView": 3, "componentType": 5126, "count": 2, "type": "VEC3"}),
        );
        json["animations"] = serde_json::json!([{
            "channels": [channel],
            "samplers": [{"input": 2, "output": 3}],
        }]);
    })
}

/// Found by fuzzing (a mutated CesiumMan): keyframe translations of 2e36 m passed `check`,
/// overflowed f32 when the skin's joints were multiplied down the tree, and the NaN pose
/// panicked the deformed mesh's BVH rebuild. Animation outputs beyond 1e6 (or not numbers)
/// are now refused at their accessor.
#[test]
fn an_animation_output_out_of_range_is_refused_at_its_accessor() {
    let dir = common::scratch_dir("gltf-animation-huge");
    let channel = serde_json::json!({"sampler": 0, "target": {"node": 0, "path": "translation"}});
    let path = common::write(&dir, "thrown.gltf", triangle_with_clip(2.0e36, channel));
    assert_reported(
        &path,
        "thrown.gltf",
        None,
        &[
            "animation output value 4 is 2e36",
            "within 1e6",
            "/accessors/3",
        ],
    );
}

/// Found by fuzzing: gltf-json does not validate an animation channel's target, and the
/// gltf crate unwraps its path and indexes its node: `check` itself panicked on a path of
/// "s&ale". Both are now diagnostics at the channel.
#[test]
fn an_animation_channel_with_an_unknown_path_or_node_is_refused() {
    let dir = common::scratch_dir("gltf-animation-target");
    let bad_path = serde_json::json!({"sampler": 0, "target": {"node": 0, "path": "s&ale"}});
    let path = common::write(&dir, "path.gltf", triangle_with_clip(1.0, bad_path));
    assert_reported(
        &path,
        "path.gltf",
        None,
        &["invalid value", "/animations/0/channels/0/target/path"],
    );
    let bad_node = serde_json::json!({"sampler": 0, "target": {"node": 7, "path": "scale"}});
    let path = common::write(&dir, "node.gltf", triangle_with_clip(1.0, bad_node));
    assert_reported(
        &path,
        "node.gltf",
        None,
        &[
            "node 7 does not exist",
            "/animations/0/channels/0/target/node",
        ],
    );
}

/// Found by fuzzing the replay target: a recorded turn past f32's range (-2.4e57 rad)
/// read as -inf, and the player's rays went nowhere, into an index out of bounds in the
/// TLAS walk. The recording is refused at the step; the game ignores such a turn.
#[test]
fn a_recording_with_an_infinite_turn_is_refused_at_its_step() {
    let shipped = common::repo().join("tests/recordings/first-light-won.json");
    let mut recording: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&shipped).unwrap()).unwrap();
    recording["steps"][21][2] = serde_json::json!(-2.3841858e57);
    let text = serde_json::to_string(&recording).unwrap();
    // Beside the shipped recordings, so its level resolves (the file is never written).
    let path = common::repo().join("tests/recordings/infinite-turn.json");
    let error = gloam::headless::replay::parse_recording(&path, &text)
        .unwrap_err()
        .to_string();
    assert!(
        error.ends_with(
            "infinite-turn.json: step 22: its look turn is not a finite number of radians"
        ),
        "{error}"
    );

    let scene = gloam::scene::Scene::load(&common::repo().join("levels/first-light.ron")).unwrap();
    let mut engine =
        gloam::frame::Engine::new(&scene, gloam::render::RenderSettings::real_time(1, 1));
    gloam::game::spawn_player(&mut engine.world).unwrap();
    engine.world.resource_mut::<gloam::game::Input>().look =
        glam::Vec2::new(f32::NEG_INFINITY, f32::NAN);
    engine.step();
    let mut players = engine.world.query::<&gloam::game::Player>();
    let player = players.iter(&engine.world).next().unwrap();
    assert!(player.yaw.is_finite() && player.pitch.is_finite());
}
