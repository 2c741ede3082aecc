//! Every shipped glTF asset, and a document using every feature the asset writer has, passes
//! the Khronos glTF Validator (the npm package `gltf-validator`) with no error and no warning.
//!
//! `.ci/run` installs the package into `target/gltf-validator`; elsewhere the test looks there
//! or in `$GLTF_VALIDATOR` (a folder holding `node_modules/gltf-validator`), and skips with a
//! notice when Node or the package is missing, except under CI, where it fails.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use glam::{Quat, Vec2, Vec3, Vec4};
use gloam::scene::gltf_export::{
    CameraData, GltfDocument, ImageData, MaterialData, MeshData, NodeData, write_gltf,
};

/// Validates each file given after `--` and prints one JSON line per file: its path, the
/// numbers of errors and warnings, and the messages of both.
const VALIDATE_JS: &str = r#"
const fs = require('fs');
const path = require('path');
const validator = require(process.env.GLTF_VALIDATOR_MODULE);
(async () => {
  for (const file of process.argv.slice(1)) {
    const report = await validator.validateBytes(new Uint8Array(fs.readFileSync(file)), {
      uri: path.basename(file),
      maxIssues: 0,
      externalResourceFunction: (uri) => new Promise((resolve, reject) =>
        fs.readFile(path.resolve(path.dirname(file), decodeURIComponent(uri)),
          (error, data) => error ? reject(error.toString()) : resolve(new Uint8Array(data)))),
    });
    const issues = report.issues;
    console.log(JSON.stringify({
      file,
      errors: issues.numErrors,
      warnings: issues.numWarnings,
      messages: issues.messages.filter((m) => m.severity <= 1)
        .map((m) => `${m.code} at ${m.pointer || m.offset}: ${m.message}`),
    }));
  }
})().catch((error) => { console.error(String(error)); process.exit(1); });
"#;

/// The validator's module folder, or None (after a notice) when it or Node is missing
/// outside CI.
fn validator_module() -> Option<PathBuf> {
    let folder = std::env::var_os("GLTF_VALIDATOR")
        .map(PathBuf::from)
        .unwrap_or_else(|| common::repo().join("target/gltf-validator"));
    let module = folder.join("node_modules/gltf-validator");
    let node = Command::new("node").arg("--version").output().is_ok();
    if node && module.join("package.json").is_file() {
        return Some(module);
    }
    let missing = if node {
        format!(
            "the npm package gltf-validator (looked in {})",
            folder.display()
        )
    } else {
        "Node.js".to_owned()
    };
    assert!(
        std::env::var_os("CI").is_none(),
        "CI must install {missing} (.ci/run does)"
    );
    println!("notice: skipping the glTF Validator test, {missing} not installed");
    None
}

/// Runs the validator over `files` and fails naming every file with an error or warning.
fn assert_valid(module: &Path, files: &[PathBuf]) {
    let output = Command::new("node")
        .arg("-e")
        .arg(VALIDATE_JS)
        .arg("--")
        .args(files)
        .env("GLTF_VALIDATOR_MODULE", module)
        .output()
        .expect("node runs");
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        output.status.success(),
        "the validator failed: {}{stdout}",
        String::from_utf8_lossy(&output.stderr)
    );
    let reports: Vec<serde_json::Value> = stdout
        .lines()
        .map(|line| serde_json::from_str(line).expect("one JSON report a line"))
        .collect();
    assert_eq!(reports.len(), files.len(), "one report a file: {stdout}");
    let failures: Vec<String> = reports
        .iter()
        .filter(|report| report["errors"] != 0 || report["warnings"] != 0)
        .map(|report| format!("{}: {}", report["file"], report["messages"]))
        .collect();
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

fn gltf_files_under(dir: &Path, found: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            gltf_files_under(&path, found);
        } else if matches!(
            path.extension().and_then(|e| e.to_str()),
            Some("gltf" | "glb")
        ) {
            found.push(path);
        }
    }
}

#[test]
fn every_shipped_asset_passes_the_khronos_validator() {
    let Some(module) = validator_module() else {
        return;
    };
    let mut files = Vec::new();
    gltf_files_under(&common::repo().join("assets"), &mut files);
    files.sort();
    assert!(files.len() >= 19, "the kit and the Cornell box: {files:?}");
    assert_valid(&module, &files);
}

/// The features no shipped asset uses: a PNG texture and its sampler, transmission with an
/// index of refraction, emission above 1, a camera, a node tree with every transform part,
/// and a buffer whose file name needs percent-encoding.
fn every_feature_document() -> GltfDocument {
    let mut png = Vec::new();
    image::RgbImage::from_fn(4, 4, |x, y| {
        image::Rgb([(x * 60) as u8, (y * 60) as u8, 128])
    })
    .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
    .unwrap();
    let corners = [
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(1.0, 1.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
    ];
    let mut document = GltfDocument::default();
    let mut textured = MeshData::quad("textured", corners, 0);
    textured.uvs = vec![Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y];
    let quad = document.add_mesh_node(
        textured,
        MaterialData {
            base_color_texture: Some(0),
            ..MaterialData::lambertian("painted", Vec3::ONE)
        },
    );
    let glass = document.add_mesh_node(
        MeshData::cuboid("pane", Vec3::ZERO, Vec3::new(1.0, 1.0, 0.02), 0),
        MaterialData {
            base_color: Vec4::new(0.9, 0.95, 1.0, 1.0),
            roughness: 0.0,
            transmission: 1.0,
            ior: 1.52,
            double_sided: true,
            ..MaterialData::lambertian("glass", Vec3::ONE)
        },
    );
    document.add_mesh_node(
        MeshData::cylinder("flame", 0.02, 0.05, 8, 0),
        MaterialData {
            emissive: Vec3::new(40.0, 20.0, 5.0),
            ..MaterialData::lambertian("flame", Vec3::ONE)
        },
    );
    document.images.push(ImageData {
        name: "gradient".into(),
        png,
    });
    document.cameras.push(CameraData {
        name: "view".into(),
        yfov: 0.8,
        znear: 0.05,
    });
    document.nodes[glass] = NodeData {
        translation: Vec3::new(0.5, 1.0, -2.0),
        rotation: Quat::from_rotation_y(0.3),
        scale: Vec3::new(2.0, 1.0, 1.0),
        ..document.nodes[glass].clone()
    };
    document.nodes.push(NodeData {
        camera: Some(0),
        translation: Vec3::new(0.0, 1.6, 3.0),
        ..NodeData::named("camera")
    });
    let camera = document.nodes.len() - 1;
    document.nodes[quad].children.push(camera);
    document.roots.retain(|&root| root != camera);
    document
}

#[test]
fn a_document_with_every_writer_feature_passes_the_khronos_validator() {
    let Some(module) = validator_module() else {
        return;
    };
    let dir = common::scratch_dir("gltf_validator_every_feature");
    let document = every_feature_document();
    let binary = dir.join("every feature.glb");
    let text = dir.join("every feature.gltf");
    write_gltf(&document, &binary).unwrap();
    write_gltf(&document, &text).unwrap();
    assert!(dir.join("every feature.bin").is_file());
    assert_valid(&module, &[binary, text]);
}
