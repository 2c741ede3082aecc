//! Gloam's own assets, reproducible from code: the Cornell box (`cornell/cornell-box.gltf`
//! and its `.bin`) and the level kit (`kit/wall.glb`, `floor.glb`, `pillar.glb`,
//! `crate.glb`, `shard.glb`), plus a wavy-grid stress mesh for import timing.
//!
//! Load-time tooling, never run by the game itself. `gloam generate assets` calls
//! [`generate_assets`] to rewrite every file under `assets/`; a test checks that the
//! committed files are byte-identical to what this code writes, so edit the code, never
//! the files. Everything is in glTF space (right-handed, +Y up, metres) with linear colours
//! and emission given as radiance in W/(sr m^2).

use std::path::{Path, PathBuf};

use anyhow::{Context as _, ensure};
use glam::{Vec2, Vec3};
use image::ImageEncoder as _;

use super::gltf_export::{
    CameraData, GltfDocument, ImageData, MaterialData, MeshData, NodeData, write_gltf,
};

/// Writes every shipped asset under `out_dir` (normally `assets/`); returns the files written, sorted.
pub fn generate_assets(out_dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    let cornell = out_dir.join("cornell").join("cornell-box.gltf");
    write_gltf(&cornell_box()?, &cornell)?;
    let mut written = vec![cornell.with_extension("bin"), cornell];
    let kit: [(&str, GltfDocument); 5] = [
        ("wall", wall()),
        ("floor", floor()?),
        ("pillar", pillar()),
        ("crate", crate_box()),
        ("shard", shard()?),
    ];
    for (name, document) in kit {
        let path = out_dir.join("kit").join(format!("{name}.glb"));
        write_gltf(&document, &path)?;
        written.push(path);
    }
    written.sort();
    Ok(written)
}

/// Writes a stress-test glTF/GLB with at least `triangles` triangles (a subdivided wavy grid with normals and UVs), for import timing.
pub fn write_stress_mesh(path: &Path, triangles: usize) -> anyhow::Result<usize> {
    let mut document = GltfDocument::default();
    document.add_mesh_node(
        stress_grid(triangles)?,
        MaterialData::lambertian("stress grey", Vec3::splat(0.5)),
    );
    write_gltf(&document, path)?;
    Ok(document.triangle_count())
}

/// A 10 x 10 m wavy height-field grid centred on the origin with at least `triangles`
/// triangles, normals and UVs (material 0): the stress mesh, and `raybench`'s deforming mesh.
pub fn stress_grid(triangles: usize) -> anyhow::Result<MeshData> {
    // An n x n grid of quads has 2 n^2 triangles.
    let mut cells = ((triangles as f64 / 2.0).sqrt().ceil() as usize).max(1);
    while 2 * cells * cells < triangles {
        cells += 1;
    }
    let side = cells + 1;
    ensure!(
        side.checked_mul(side)
            .is_some_and(|n| u32::try_from(n).is_ok()),
        "{triangles} triangles is too many for one mesh"
    );

    const SIZE: f32 = 10.0;
    const AMPLITUDE: f32 = 0.25;
    const FREQUENCY: Vec2 = Vec2::new(1.3, 0.9);
    let mut mesh = MeshData::new("stress grid", 0);
    mesh.positions.reserve(side * side);
    mesh.normals.reserve(side * side);
    mesh.uvs.reserve(side * side);
    for row in 0..side {
        for column in 0..side {
            let uv = Vec2::new(column as f32, row as f32) / cells as f32;
            let (x, z) = ((uv.x - 0.5) * SIZE, (uv.y - 0.5) * SIZE);
            let (sin_x, cos_x) = (FREQUENCY.x * x).sin_cos();
            let (sin_z, cos_z) = (FREQUENCY.y * z).sin_cos();
            let height = AMPLITUDE * sin_x * cos_z;
            // Height field y = f(x, z): the normal is (-df/dx, 1, -df/dz), normalised.
            let slope = Vec2::new(
                AMPLITUDE * FREQUENCY.x * cos_x * cos_z,
                -AMPLITUDE * FREQUENCY.y * sin_x * sin_z,
            );
            mesh.positions.push(Vec3::new(x, height, z));
            mesh.normals
                .push(Vec3::new(-slope.x, 1.0, -slope.y).normalize());
            mesh.uvs.push(uv);
        }
    }
    mesh.indices.reserve(2 * cells * cells);
    let vertex = |row: usize, column: usize| (row * side + column) as u32;
    for row in 0..cells {
        for column in 0..cells {
            // Counter-clockwise seen from above (+Z is "down" on screen there).
            let (v00, v01, v10, v11) = (
                vertex(row, column),
                vertex(row + 1, column),
                vertex(row, column + 1),
                vertex(row + 1, column + 1),
            );
            mesh.indices.push([v00, v01, v11]);
            mesh.indices.push([v00, v11, v10]);
        }
    }
    Ok(mesh)
}

// ---- the Cornell box ----------------------------------------------------------------------

/// Box extent in glTF metres: x in [0, WIDTH], y in [0, HEIGHT], z in [-DEPTH, 0] (open front).
const CORNELL_WIDTH: f32 = 0.556;
const CORNELL_HEIGHT: f32 = 0.5488;
const CORNELL_DEPTH: f32 = 0.5592;

/// Maps the original Cornell data (x, y, z in millimetres, camera looking down +z) into
/// glTF space: a 180-degree turn about Y plus a shift, so winding (and facing) is kept.
fn from_cornell_mm(x: f64, y: f64, z: f64) -> Vec3 {
    Vec3::new(
        (0.556 - x / 1000.0) as f32,
        (y / 1000.0) as f32,
        (-z / 1000.0) as f32,
    )
}

/// A block from the measured top face (mm): four sides and the top, no hidden bottom.
fn cornell_block(name: &str, top_mm: [[f64; 3]; 4], material: usize) -> anyhow::Result<MeshData> {
    let top = top_mm.map(|[x, y, z]| from_cornell_mm(x, y, z));
    let vertices: Vec<Vec3> = top
        .iter()
        .copied()
        .chain(top.iter().map(|p| Vec3::new(p.x, 0.0, p.z)))
        .collect();
    let faces: [&[usize]; 5] = [
        &[0, 1, 2, 3],
        &[0, 1, 5, 4],
        &[1, 2, 6, 5],
        &[2, 3, 7, 6],
        &[3, 0, 4, 7],
    ];
    MeshData::convex_solid(name, &vertices, &faces, material)
}

/// The classic Cornell box (the room as its ideal rectangle, the blocks and the light from
/// the measured data), Lambertian materials, the light's radiance and the original camera.
fn cornell_box() -> anyhow::Result<GltfDocument> {
    let (w, h, d) = (CORNELL_WIDTH, CORNELL_HEIGHT, CORNELL_DEPTH);
    let v = Vec3::new;
    const WHITE: usize = 0;
    const RED: usize = 1;
    const GREEN: usize = 2;
    const LIGHT: usize = 3;
    let materials = vec![
        MaterialData::lambertian("white", v(0.725, 0.71, 0.68)),
        MaterialData::lambertian("red", v(0.63, 0.065, 0.05)),
        MaterialData::lambertian("green", v(0.14, 0.45, 0.091)),
        MaterialData {
            emissive: v(17.0, 12.0, 4.0),
            ..MaterialData::lambertian("light", Vec3::splat(0.78))
        },
    ];
    let light_mm = [
        [343.0, 548.7, 227.0],
        [343.0, 548.7, 332.0],
        [213.0, 548.7, 332.0],
        [213.0, 548.7, 227.0],
    ];
    // Quads are counter-clockwise seen from inside the box.
    let meshes = vec![
        MeshData::quad(
            "floor",
            [
                v(0.0, 0.0, 0.0),
                v(w, 0.0, 0.0),
                v(w, 0.0, -d),
                v(0.0, 0.0, -d),
            ],
            WHITE,
        ),
        MeshData::quad(
            "ceiling",
            [v(0.0, h, 0.0), v(0.0, h, -d), v(w, h, -d), v(w, h, 0.0)],
            WHITE,
        ),
        MeshData::quad(
            "back wall",
            [v(0.0, 0.0, -d), v(w, 0.0, -d), v(w, h, -d), v(0.0, h, -d)],
            WHITE,
        ),
        MeshData::quad(
            "left wall (red)",
            [
                v(0.0, 0.0, 0.0),
                v(0.0, 0.0, -d),
                v(0.0, h, -d),
                v(0.0, h, 0.0),
            ],
            RED,
        ),
        MeshData::quad(
            "right wall (green)",
            [v(w, 0.0, -d), v(w, 0.0, 0.0), v(w, h, 0.0), v(w, h, -d)],
            GREEN,
        ),
        cornell_block(
            "short block",
            [
                [130.0, 165.0, 65.0],
                [82.0, 165.0, 225.0],
                [240.0, 165.0, 272.0],
                [290.0, 165.0, 114.0],
            ],
            WHITE,
        )?,
        cornell_block(
            "tall block",
            [
                [423.0, 330.0, 247.0],
                [265.0, 330.0, 296.0],
                [314.0, 330.0, 456.0],
                [472.0, 330.0, 406.0],
            ],
            WHITE,
        )?,
        MeshData::quad(
            "light",
            light_mm.map(|[x, y, z]| from_cornell_mm(x, y, z)),
            LIGHT,
        ),
    ];
    let mut nodes: Vec<NodeData> = meshes
        .iter()
        .enumerate()
        .map(|(i, mesh)| NodeData::with_mesh(&mesh.name, i))
        .collect();
    nodes.push(NodeData {
        translation: v(0.278, 0.273, 0.8),
        camera: Some(0),
        ..NodeData::named("camera")
    });
    Ok(GltfDocument {
        roots: (0..nodes.len()).collect(),
        meshes,
        materials,
        images: Vec::new(),
        cameras: vec![CameraData {
            name: "camera".into(),
            yfov: 39.3077_f32.to_radians(),
            znear: 0.01,
        }],
        nodes,
        ..GltfDocument::default()
    })
}

// ---- the level kit --------------------------------------------------------------------------

/// One mesh, one material, one root node named after the mesh.
fn single_mesh(mesh: MeshData, material: MaterialData) -> GltfDocument {
    let mut document = GltfDocument::default();
    document.add_mesh_node(mesh, material);
    document
}

/// 4 m wide (x) x 3 m high x 0.2 m thick (z), origin at the bottom centre.
fn wall() -> GltfDocument {
    let mesh = MeshData::cuboid(
        "wall",
        Vec3::new(-2.0, 0.0, -0.1),
        Vec3::new(2.0, 3.0, 0.1),
        0,
    );
    single_mesh(
        mesh,
        MaterialData {
            roughness: 0.9,
            ..MaterialData::lambertian("plaster", Vec3::new(0.62, 0.6, 0.56))
        },
    )
}

/// A 4 x 4 m tile 0.1 m thick with its top at y = 0, textured once across.
fn floor() -> anyhow::Result<GltfDocument> {
    let mesh = MeshData::cuboid(
        "floor",
        Vec3::new(-2.0, -0.1, -2.0),
        Vec3::new(2.0, 0.0, 2.0),
        0,
    )
    .scale_uvs(0.25);
    let mut document = single_mesh(
        mesh,
        MaterialData {
            base_color_texture: Some(0),
            ..MaterialData::lambertian("floor tiles", Vec3::ONE)
        },
    );
    document.images.push(ImageData {
        name: "floor tiles".into(),
        png: floor_tiles_png()?,
    });
    Ok(document)
}

/// Side of the floor texture in texels.
const FLOOR_TEXTURE_SIZE: u32 = 64;

/// 64x64 sRGB PNG: four stone tiles with a little per-texel variation and darker grout.
fn floor_tiles_png() -> anyhow::Result<Vec<u8>> {
    /// A small integer hash (deterministic noise).
    fn hash(mut x: u32) -> u32 {
        x ^= x >> 16;
        x = x.wrapping_mul(0x7feb_352d);
        x ^= x >> 15;
        x = x.wrapping_mul(0x846c_a68b);
        x ^ (x >> 16)
    }
    const TILE: u32 = FLOOR_TEXTURE_SIZE / 2;
    const STONE: [[i32; 3]; 4] = [
        [150, 146, 138],
        [140, 137, 131],
        [146, 141, 132],
        [136, 134, 130],
    ];
    const GROUT: [i32; 3] = [72, 68, 62];
    let mut rgb = Vec::with_capacity((FLOOR_TEXTURE_SIZE * FLOOR_TEXTURE_SIZE * 3) as usize);
    for y in 0..FLOOR_TEXTURE_SIZE {
        for x in 0..FLOOR_TEXTURE_SIZE {
            let (local_x, local_y) = (x % TILE, y % TILE);
            // One texel of grout on each tile edge: two where tiles meet (also across the wrap).
            let is_grout =
                local_x == 0 || local_y == 0 || local_x == TILE - 1 || local_y == TILE - 1;
            let base = if is_grout {
                GROUT
            } else {
                STONE[(y / TILE * 2 + x / TILE) as usize]
            };
            let noise = (hash(y * FLOOR_TEXTURE_SIZE + x) % 13) as i32 - 6;
            rgb.extend(base.map(|channel| (channel + noise).clamp(0, 255) as u8));
        }
    }
    let mut png = Vec::new();
    image::codecs::png::PngEncoder::new(&mut png)
        .write_image(
            &rgb,
            FLOOR_TEXTURE_SIZE,
            FLOOR_TEXTURE_SIZE,
            image::ExtendedColorType::Rgb8,
        )
        .context("encoding the floor texture")?;
    Ok(png)
}

/// Radius 0.3 m, 3 m tall, 24 segments, base at y = 0.
fn pillar() -> GltfDocument {
    single_mesh(
        MeshData::cylinder("pillar", 0.3, 3.0, 24, 0),
        MaterialData::lambertian("stone", Vec3::new(0.5, 0.5, 0.48)),
    )
}

/// A 1 m cube sitting on y = 0.
fn crate_box() -> GltfDocument {
    let mesh = MeshData::cuboid(
        "crate",
        Vec3::new(-0.5, 0.0, -0.5),
        Vec3::new(0.5, 1.0, 0.5),
        0,
    );
    single_mesh(
        mesh,
        MaterialData {
            roughness: 0.8,
            ..MaterialData::lambertian("wood", Vec3::new(0.55, 0.38, 0.2))
        },
    )
}

/// The collectable light shard: an elongated octahedron 0.15 m across and 0.5 m tall,
/// centred at y = 0.5, glowing cyan.
fn shard() -> anyhow::Result<GltfDocument> {
    let (half_width, half_height, centre) = (0.075, 0.25, 0.5);
    let vertices = [
        Vec3::new(0.0, centre + half_height, 0.0),
        Vec3::new(0.0, centre - half_height, 0.0),
        Vec3::new(half_width, centre, 0.0),
        Vec3::new(0.0, centre, -half_width),
        Vec3::new(-half_width, centre, 0.0),
        Vec3::new(0.0, centre, half_width),
    ];
    let faces: Vec<[usize; 3]> = (0..4)
        .flat_map(|i| [[0, 2 + i, 2 + (i + 1) % 4], [1, 2 + i, 2 + (i + 1) % 4]])
        .collect();
    let faces: Vec<&[usize]> = faces.iter().map(|face| face.as_slice()).collect();
    let mesh = MeshData::convex_solid("shard", &vertices, &faces, 0)?;
    let glow = MaterialData {
        emissive: Vec3::new(1.5, 4.0, 5.0),
        ..MaterialData::lambertian("shard glow", Vec3::new(0.1, 0.2, 0.25))
    };
    Ok(single_mesh(mesh, glow))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::gltf_import::import_gltf;
    use crate::scene::model::{Asset, Projection};

    /// A fresh folder under the system temp dir, unique to this process and test.
    fn unique_temp_dir(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("gloam-kit-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        dir
    }

    fn material_names(asset: &Asset) -> Vec<&str> {
        asset.materials.iter().map(|m| m.name.as_str()).collect()
    }

    /// Every triangle's (centroid, geometric normal) for mesh `name`, checking on the way
    /// that the stored vertex normals agree with the winding.
    fn triangles_of(asset: &Asset, name: &str) -> Vec<(Vec3, Vec3)> {
        let mesh = asset
            .meshes
            .iter()
            .find(|m| m.name == name)
            .unwrap_or_else(|| panic!("no mesh '{name}'"));
        let mut triangles = Vec::new();
        for primitive in &mesh.primitives {
            for triangle in &primitive.indices {
                let [a, b, c] = triangle.map(|i| primitive.positions[i as usize]);
                let normal = (b - a).cross(c - a).normalize();
                for &i in triangle {
                    assert!(
                        primitive.normals[i as usize].dot(normal) > 0.0,
                        "{name}: vertex normal disagrees with winding"
                    );
                }
                triangles.push(((a + b + c) / 3.0, normal));
            }
        }
        triangles
    }

    #[test]
    fn committed_assets_match_the_generator() {
        let dir = unique_temp_dir("committed");
        let committed = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets");
        for file in generate_assets(&dir).unwrap() {
            let relative = file.strip_prefix(&dir).unwrap();
            let expected = std::fs::read(committed.join(relative)).unwrap_or_else(|error| {
                panic!(
                    "assets/{} is missing ({error}); run `gloam generate assets`",
                    relative.display()
                )
            });
            assert!(
                std::fs::read(&file).unwrap() == expected,
                "assets/{} differs from the generator's output",
                relative.display()
            );
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn sources_lists_every_generated_file() {
        let dir = unique_temp_dir("sources");
        let sources = std::fs::read_to_string(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/SOURCES.md"),
        )
        .unwrap();
        for file in generate_assets(&dir).unwrap() {
            let relative = file
                .strip_prefix(&dir)
                .unwrap()
                .to_str()
                .unwrap()
                .replace('\\', "/");
            assert!(
                sources.contains(&format!("`{relative}`")),
                "assets/SOURCES.md does not list {relative}"
            );
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn generated_assets_import_with_the_expected_content() {
        let dir = unique_temp_dir("import");
        let files = generate_assets(&dir).unwrap();
        let names: Vec<String> = files
            .iter()
            .map(|f| {
                f.strip_prefix(&dir)
                    .unwrap()
                    .to_str()
                    .unwrap()
                    .replace('\\', "/")
            })
            .collect();
        let expected_files = [
            "cornell/cornell-box.bin",
            "cornell/cornell-box.gltf",
            "kit/crate.glb",
            "kit/floor.glb",
            "kit/pillar.glb",
            "kit/shard.glb",
            "kit/wall.glb",
        ];
        assert_eq!(names, expected_files);

        // (file, triangles, material names)
        let expectations: [(&str, usize, &[&str]); 6] = [
            (
                "cornell/cornell-box.gltf",
                32,
                &["white", "red", "green", "light"],
            ),
            ("kit/wall.glb", 12, &["plaster"]),
            ("kit/floor.glb", 12, &["floor tiles"]),
            ("kit/pillar.glb", 24 * 2 + 2 * 22, &["stone"]),
            ("kit/crate.glb", 12, &["wood"]),
            ("kit/shard.glb", 8, &["shard glow"]),
        ];
        for (file, triangles, materials) in expectations {
            let asset =
                import_gltf(&dir.join(file)).unwrap_or_else(|error| panic!("{file}: {error}"));
            assert_eq!(asset.triangle_count(), triangles, "{file}");
            assert_eq!(material_names(&asset), materials, "{file}");
            assert!(
                asset.nodes.iter().all(|n| !n.name.is_empty()),
                "{file}: unnamed node"
            );
            assert!(
                asset.meshes.iter().all(|m| !m.name.is_empty()),
                "{file}: unnamed mesh"
            );
        }

        let cornell = import_gltf(&dir.join("cornell/cornell-box.gltf")).unwrap();
        let light = &cornell.materials[cornell.material_by_name("light").unwrap()];
        assert!(
            (light.emissive - Vec3::new(17.0, 12.0, 4.0))
                .abs()
                .max_element()
                < 1e-4,
            "{}",
            light.emissive
        );
        assert_eq!(
            (light.base_color.truncate(), light.metallic, light.roughness),
            (Vec3::splat(0.78), 0.0, 1.0)
        );
        assert_eq!(cornell.cameras.len(), 1);
        let Projection::Perspective { yfov, znear, .. } = cornell.cameras[0].projection else {
            panic!("orthographic camera")
        };
        assert!(
            (yfov.to_degrees() - 39.3077).abs() < 1e-4 && znear == 0.01,
            "yfov {yfov}, znear {znear}"
        );
        let camera_node = cornell.nodes.iter().find(|n| n.camera == Some(0)).unwrap();
        assert_eq!(camera_node.name, "camera");
        assert_eq!(
            camera_node.transform.matrix(),
            glam::Mat4::from_translation(Vec3::new(0.278, 0.273, 0.8))
        );
        let mut mesh_names: Vec<&str> = cornell.meshes.iter().map(|m| m.name.as_str()).collect();
        mesh_names.sort_unstable();
        let expected_meshes = [
            "back wall",
            "ceiling",
            "floor",
            "left wall (red)",
            "light",
            "right wall (green)",
            "short block",
            "tall block",
        ];
        assert_eq!(mesh_names, expected_meshes);

        let floor = import_gltf(&dir.join("kit/floor.glb")).unwrap();
        let texture = floor.materials[0]
            .base_color_texture
            .as_ref()
            .expect("floor has a base-colour texture");
        let image = &floor.images[floor.textures[texture.texture].image];
        assert_eq!((image.width, image.height), (64, 64));
        let primitive = &floor.meshes[0].primitives[0];
        let top_uvs: Vec<Vec2> = primitive
            .normals
            .iter()
            .zip(&primitive.uv0)
            .filter(|(normal, _)| normal.y > 0.99)
            .map(|(_, &uv)| uv)
            .collect();
        let (uv_min, uv_max) = top_uvs
            .iter()
            .fold((Vec2::INFINITY, Vec2::NEG_INFINITY), |(lo, hi), &uv| {
                (lo.min(uv), hi.max(uv))
            });
        assert_eq!(
            (uv_min, uv_max),
            (Vec2::ZERO, Vec2::ONE),
            "the texture covers the top once"
        );

        let shard = import_gltf(&dir.join("kit/shard.glb")).unwrap();
        assert_eq!(shard.materials[0].emissive, Vec3::new(1.5, 4.0, 5.0));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn cornell_box_normals_face_into_the_room_and_out_of_the_blocks() {
        let dir = unique_temp_dir("cornell-normals");
        let path = dir.join("cornell-box.gltf");
        write_gltf(&cornell_box().unwrap(), &path).unwrap();
        let asset = import_gltf(&path).unwrap();
        let room_centre = Vec3::new(CORNELL_WIDTH, CORNELL_HEIGHT, -CORNELL_DEPTH) * 0.5;
        for name in [
            "floor",
            "ceiling",
            "back wall",
            "left wall (red)",
            "right wall (green)",
            "light",
        ] {
            for (centroid, normal) in triangles_of(&asset, name) {
                assert!(
                    normal.dot(room_centre - centroid) > 0.0,
                    "{name} faces out of the room"
                );
            }
        }
        for (_, normal) in triangles_of(&asset, "light") {
            assert!(normal.y < -0.999, "the light must face down");
        }
        let red = triangles_of(&asset, "left wall (red)");
        assert!(
            red.iter().all(|(centroid, _)| centroid.x == 0.0),
            "red wall at x = 0"
        );
        for name in ["short block", "tall block"] {
            let triangles = triangles_of(&asset, name);
            let mesh = asset.meshes.iter().find(|m| m.name == name).unwrap();
            let positions = &mesh.primitives[0].positions;
            let block_centre = positions.iter().copied().sum::<Vec3>() / positions.len() as f32;
            assert_eq!(triangles.len(), 10);
            for (centroid, normal) in triangles {
                assert!(
                    normal.dot(centroid - block_centre) > 0.0,
                    "{name} has a face pointing inwards"
                );
            }
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn kit_solids_face_outwards() {
        for (document, name) in [
            (wall(), "wall"),
            (floor().unwrap(), "floor"),
            (pillar(), "pillar"),
            (crate_box(), "crate"),
            (shard().unwrap(), "shard"),
        ] {
            let mesh = &document.meshes[0];
            let min = mesh
                .positions
                .iter()
                .copied()
                .fold(Vec3::INFINITY, Vec3::min);
            let max = mesh
                .positions
                .iter()
                .copied()
                .fold(Vec3::NEG_INFINITY, Vec3::max);
            let centre = (min + max) * 0.5;
            for triangle in &mesh.indices {
                let [a, b, c] = triangle.map(|i| mesh.positions[i as usize]);
                let normal = (b - a).cross(c - a);
                assert!(
                    normal.dot((a + b + c) / 3.0 - centre) > 0.0,
                    "{name} has an inward triangle"
                );
            }
        }
    }

    #[test]
    fn stress_mesh_has_at_least_the_requested_triangles() {
        let dir = unique_temp_dir("stress");
        for file in ["stress.glb", "stress.gltf"] {
            let path = dir.join(file);
            let written = write_stress_mesh(&path, 1000).unwrap();
            assert!(written >= 1000);
            let asset = import_gltf(&path).unwrap();
            assert_eq!(asset.triangle_count(), written);
            let primitive = &asset.meshes[0].primitives[0];
            assert_eq!(primitive.uv0.len(), primitive.positions.len());
            triangles_of(&asset, "stress grid")
                .iter()
                .for_each(|(_, normal)| assert!(normal.y > 0.0));
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
