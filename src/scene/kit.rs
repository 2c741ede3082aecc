//! Gloam's own assets, reproducible from code: the Cornell box (`cornell/cornell-box.gltf`
//! and its `.bin`), the level kit under `kit/` and the enemy (`kit/warden.glb`, a skinned,
//! animated guard), plus a wavy-grid stress mesh for import timing and a high-detail
//! warden for skinning benchmarks.
//!
//! The kit (one `.glb` each; the dimensions and origins are in each builder's doc):
//! - structure: `wall`, `wall-doorway` (framed) and `wall-window` (4 x 3 x 0.2 m, with a
//!   1.2 x 2.2 m doorway or a 1.2 x 1 m window), `floor` (4 x 4 m tile), `pillar`,
//!   `stairs` (15 steps, 3 m up over 5 m), `beam` (8 m, to rest on two walls' tops),
//!   `door` (fills the doorway) and `gate` (an iron portcullis);
//! - furniture: `crate`, `barrel`, `table`, `bookcase` (with books), `shelf` (with jars),
//!   `rug`, `bottle` (to knock over), `mirror` (its reflecting face is the z = 0.03 plane
//!   over x -0.6..0.6, y 0..2);
//! - lights: `lamp-bracket` (a wall lantern), `hanging-lamp` (the same lantern on a rod,
//!   to hang under a beam) and `candle`, whose emissive glass and flame are closed solids:
//!   their punctual lights go just outside them ([`LAMP_BRACKET_LIGHT`],
//!   [`HANGING_LAMP_LIGHT`], [`CANDLE_LIGHT`]);
//! - the collectable `shard` and the morphing cloth `banner`.
//!
//! Every kit piece but the banner is built from closed solids with outward faces.
//! Every material but the glows and the mirror carries the textures of one of
//! `kit_surfaces`' surfaces (base colour, metallic-roughness and normals; see `dress`), and
//! each `.glb` embeds the ones it uses.
//!
//! Load-time tooling, never run by the game itself. `gloam generate assets` calls
//! [`generate_assets`] to rewrite every file under `assets/`; a test checks that the
//! committed files are byte-identical to what this code writes, so edit the code, never
//! the files. Everything is in glTF space (right-handed, +Y up, metres) with linear colours
//! and emission given as radiance in W/(sr m^2). `assets/SOURCES.md` lists every file under
//! `assets/` and where it comes from (the sounds: `gloam generate sounds`, `sound_kit`).
//!
//! `gloam generate stress [--triangles N] --out FILE` writes the wavy grid of at least N
//! triangles (default 1,000,000), whose load time `gloam check FILE` reports; with
//! `--skinned`, a walking warden of at least N triangles, whose `animation` and
//! `blas_refit` stages `gloam play FILE --headless` reports.

use std::path::{Path, PathBuf};

use anyhow::ensure;
use glam::{Affine3A, Mat4, Vec2, Vec3};

use super::gltf_export::{
    AnimationData, CameraData, ChannelData, GltfDocument, ImageData, MaterialData, MeshData,
    MorphTargetData, NodeData, SkinData, write_gltf,
};
use super::kit_surfaces::{self, Surface};
use super::model::{AnimatedProperty, Interpolation};

/// Writes every shipped asset under `out_dir` (normally `assets/`); returns the files written, sorted.
pub fn generate_assets(out_dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    let cornell = out_dir.join("cornell").join("cornell-box.gltf");
    write_gltf(&cornell_box()?, &cornell)?;
    let mut written = vec![cornell.with_extension("bin"), cornell];
    let mut kit: Vec<(&str, GltfDocument)> = vec![
        ("wall", wall()?),
        ("floor", floor()?),
        ("pillar", pillar()?),
        ("crate", crate_box()?),
        ("shard", shard()?),
        ("warden", warden_document(WARDEN_DETAIL)?),
        ("banner", banner()?),
    ];
    for (name, piece) in kit_pieces()? {
        let mut document = piece.document()?;
        if name == "gate" {
            document.animations.push(gate_lift());
        }
        kit.push((name, document));
    }
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

/// One mesh, one material, one root node named after the mesh; textured by `dress`.
fn single_mesh(mesh: MeshData, material: KitMaterial) -> anyhow::Result<GltfDocument> {
    let mut document = GltfDocument::default();
    document.add_mesh_node(mesh, material.data);
    dress(&mut document, &[material.surface])?;
    Ok(document)
}

/// A kit material: its glTF factors, and the surface whose textures it carries (none for
/// the glows and the mirror, whose look is their light or their reflection).
#[derive(Clone)]
struct KitMaterial {
    data: MaterialData,
    surface: Option<Surface>,
}

/// `data` carrying `surface`'s textures.
fn textured(surface: Surface, data: MaterialData) -> KitMaterial {
    KitMaterial {
        data,
        surface: Some(surface),
    }
}

/// `data` with no textures.
fn plain(data: MaterialData) -> KitMaterial {
    KitMaterial {
        data,
        surface: None,
    }
}

/// Gives `document`'s materials their surfaces' textures: material `i` carries
/// `surfaces[i]`'s three images (each surface's images embedded once, shared by every
/// material on it), its base colour factor becomes the colour it names divided by the
/// texture's mean (so the texture's mean is that colour), and the UVs of the meshes
/// using it, in metres, are divided by the surface's period.
fn dress(document: &mut GltfDocument, surfaces: &[Option<Surface>]) -> anyhow::Result<()> {
    ensure!(
        surfaces.len() == document.materials.len(),
        "{} surfaces for {} materials",
        surfaces.len(),
        document.materials.len()
    );
    let mut embedded: Vec<(Surface, usize, Vec3)> = Vec::new();
    for (material, surface) in document.materials.iter_mut().zip(surfaces) {
        let Some(surface) = *surface else { continue };
        let (first, mean) = match embedded.iter().find(|(s, ..)| *s == surface) {
            Some(&(_, first, mean)) => (first, mean),
            None => {
                let images = surface.images()?;
                let first = document.images.len();
                for (kind, png) in [
                    ("base colour", images.base_color),
                    ("metallic-roughness", images.metallic_roughness),
                    ("normals", images.normal),
                ] {
                    document.images.push(ImageData {
                        name: format!("{} {kind}", surface.name()),
                        png,
                    });
                }
                embedded.push((surface, first, images.mean_detail));
                (first, images.mean_detail)
            }
        };
        let colour = material.base_color.truncate();
        material.base_color = (colour / mean).min(Vec3::ONE).extend(material.base_color.w);
        material.base_color_texture = Some(first);
        material.metallic_roughness_texture = Some(first + 1);
        material.normal_texture = Some(first + 2);
    }
    for mesh in &mut document.meshes {
        if let Some(Some(surface)) = surfaces.get(mesh.material) {
            let scale = 1.0 / surface.period();
            mesh.uvs.iter_mut().for_each(|uv| *uv *= scale);
        }
    }
    Ok(())
}

/// 4 m wide (x) x 3 m high x 0.2 m thick (z), origin at the bottom centre.
fn wall() -> anyhow::Result<GltfDocument> {
    let mesh = MeshData::cuboid(
        "wall",
        Vec3::new(-2.0, 0.0, -0.1),
        Vec3::new(2.0, 3.0, 0.1),
        0,
    );
    single_mesh(mesh, ashlar())
}

/// A 4 x 4 m tile 0.1 m thick with its top at y = 0, paved with flagstones.
fn floor() -> anyhow::Result<GltfDocument> {
    let mesh = MeshData::cuboid(
        "floor",
        Vec3::new(-2.0, -0.1, -2.0),
        Vec3::new(2.0, 0.0, 2.0),
        0,
    );
    single_mesh(mesh, flagstones())
}

/// Radius 0.3 m, 3 m tall, 24 segments, base at y = 0.
fn pillar() -> anyhow::Result<GltfDocument> {
    single_mesh(MeshData::cylinder("pillar", 0.3, 3.0, 24, 0), stone())
}

/// A 1 m cube sitting on y = 0.
fn crate_box() -> anyhow::Result<GltfDocument> {
    let mesh = MeshData::cuboid(
        "crate",
        Vec3::new(-0.5, 0.0, -0.5),
        Vec3::new(0.5, 1.0, 0.5),
        0,
    );
    single_mesh(mesh, wood())
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
    single_mesh(mesh, plain(glow))
}

// ---- modular pieces: openings, doors, stairs, lamps and furniture --------------------------

/// `ashlar` (0.55, 0.52, 0.47) on the ashlar surface, roughness 0.9: the walls.
fn ashlar() -> KitMaterial {
    textured(
        Surface::Ashlar,
        MaterialData {
            roughness: 0.9,
            ..MaterialData::lambertian("ashlar", Vec3::new(0.55, 0.52, 0.47))
        },
    )
}

/// `flagstones` (0.3, 0.29, 0.27) on the flagstones surface, roughness 0.9: the floor.
fn flagstones() -> KitMaterial {
    textured(
        Surface::Flagstones,
        MaterialData {
            roughness: 0.9,
            ..MaterialData::lambertian("flagstones", Vec3::new(0.3, 0.29, 0.27))
        },
    )
}

/// `stone` (0.5, 0.5, 0.48) on dressed stone, Lambertian: the pillar and the stairs.
fn stone() -> KitMaterial {
    textured(
        Surface::DressedStone,
        MaterialData::lambertian("stone", Vec3::new(0.5, 0.5, 0.48)),
    )
}

/// `wood` (0.55, 0.38, 0.2) on planks, roughness 0.8: the crate and the table.
fn wood() -> KitMaterial {
    textured(
        Surface::Planks,
        MaterialData {
            roughness: 0.8,
            ..MaterialData::lambertian("wood", Vec3::new(0.55, 0.38, 0.2))
        },
    )
}

/// `dark wood` (0.3, 0.18, 0.1) on planks, roughness 0.7: the door, the window sill, the
/// bookcase and the mirror frame.
fn dark_wood() -> KitMaterial {
    textured(
        Surface::Planks,
        MaterialData {
            roughness: 0.7,
            ..MaterialData::lambertian("dark wood", Vec3::new(0.3, 0.18, 0.1))
        },
    )
}

/// `iron` (0.2, 0.2, 0.2) on hammered metal, metallic 1, roughness 0.5: the lamp bracket
/// and the gate.
fn iron() -> KitMaterial {
    textured(
        Surface::Metal,
        MaterialData {
            metallic: 1.0,
            roughness: 0.5,
            ..MaterialData::lambertian("iron", Vec3::splat(0.2))
        },
    )
}

/// `brass` (0.75, 0.56, 0.3) on hammered metal, metallic 1, roughness 0.4: the door
/// handles and the candle dish.
fn brass() -> KitMaterial {
    textured(
        Surface::Metal,
        MaterialData {
            metallic: 1.0,
            roughness: 0.4,
            ..MaterialData::lambertian("brass", Vec3::new(0.75, 0.56, 0.3))
        },
    )
}

/// A kit piece made of closed solids, each a `MeshData` whose `material` indexes
/// `materials`. [`Piece::document`] merges the solids that share a name into one mesh
/// (in order of first use), each shown by a root node of the same name.
struct Piece {
    materials: Vec<KitMaterial>,
    solids: Vec<MeshData>,
}

impl Piece {
    fn new(materials: Vec<KitMaterial>) -> Self {
        Piece {
            materials,
            solids: Vec::new(),
        }
    }

    /// Adds an axis-aligned box between the corners `a` and `b` (in any order).
    fn cuboid(&mut self, name: &str, a: Vec3, b: Vec3, material: usize) {
        self.solids
            .push(MeshData::cuboid(name, a.min(b), a.max(b), material));
    }

    fn document(&self) -> anyhow::Result<GltfDocument> {
        let mut meshes: Vec<MeshData> = Vec::new();
        for solid in &self.solids {
            ensure!(
                solid.material < self.materials.len(),
                "solid '{}' names material {} of {}",
                solid.name,
                solid.material,
                self.materials.len()
            );
            let mesh = match meshes.iter().position(|m| m.name == solid.name) {
                Some(index) => &mut meshes[index],
                None => {
                    meshes.push(MeshData::new(&solid.name, solid.material));
                    meshes.last_mut().expect("just pushed")
                }
            };
            ensure!(
                mesh.material == solid.material,
                "the solids of mesh '{}' use different materials",
                solid.name
            );
            let first = mesh.positions.len() as u32;
            mesh.positions.extend(&solid.positions);
            mesh.normals.extend(&solid.normals);
            mesh.uvs.extend(&solid.uvs);
            mesh.indices
                .extend(solid.indices.iter().map(|t| t.map(|i| first + i)));
        }
        let mut document = GltfDocument {
            nodes: meshes
                .iter()
                .enumerate()
                .map(|(i, mesh)| NodeData::with_mesh(&mesh.name, i))
                .collect(),
            roots: (0..meshes.len()).collect(),
            meshes,
            materials: self.materials.iter().map(|m| m.data.clone()).collect(),
            ..GltfDocument::default()
        };
        let surfaces: Vec<Option<Surface>> = self.materials.iter().map(|m| m.surface).collect();
        dress(&mut document, &surfaces)?;
        Ok(document)
    }
}

/// `mesh` moved by `offset`.
fn translated(mut mesh: MeshData, offset: Vec3) -> MeshData {
    mesh.positions.iter_mut().for_each(|p| *p += offset);
    mesh
}

/// A straight bar of square cross-section (`half_width` each side of its axis) from `from`
/// to `to`, its end faces square to the axis.
fn bar(
    name: &str,
    from: Vec3,
    to: Vec3,
    half_width: f32,
    material: usize,
) -> anyhow::Result<MeshData> {
    let axis = (to - from).normalize();
    let helper = if axis.x.abs() < 0.9 { Vec3::X } else { Vec3::Y };
    let u = axis.cross(helper).normalize() * half_width;
    let v = axis.cross(u);
    let corners = [-u - v, u - v, u + v, v - u];
    let vertices: Vec<Vec3> = corners
        .iter()
        .map(|&c| from + c)
        .chain(corners.iter().map(|&c| to + c))
        .collect();
    let faces: [&[usize]; 6] = [
        &[0, 1, 2, 3],
        &[4, 5, 6, 7],
        &[0, 1, 5, 4],
        &[1, 2, 6, 5],
        &[2, 3, 7, 6],
        &[3, 0, 4, 7],
    ];
    MeshData::convex_solid(name, &vertices, &faces, material)
}

/// A closed square pyramid: a horizontal base square `half_width` each side of
/// `base_centre`, and the apex.
fn pyramid(
    name: &str,
    base_centre: Vec3,
    half_width: f32,
    apex: Vec3,
    material: usize,
) -> anyhow::Result<MeshData> {
    let h = half_width;
    let vertices = [
        base_centre + Vec3::new(-h, 0.0, -h),
        base_centre + Vec3::new(h, 0.0, -h),
        base_centre + Vec3::new(h, 0.0, h),
        base_centre + Vec3::new(-h, 0.0, h),
        apex,
    ];
    let faces: [&[usize]; 5] = [
        &[0, 1, 2, 3],
        &[0, 1, 4],
        &[1, 2, 4],
        &[2, 3, 4],
        &[3, 0, 4],
    ];
    MeshData::convex_solid(name, &vertices, &faces, material)
}

/// Half the width and the height of the opening in `wall-doorway` (x -0.6..0.6, y 0..2.2),
/// which is also the size of `door`.
const DOORWAY_HALF_WIDTH: f32 = 0.6;
const DOORWAY_HEIGHT: f32 = 2.2;
/// How wide `wall-doorway`'s wooden frame is around the opening, and how far it stands
/// proud of each face of the wall.
const DOOR_FRAME_WIDTH: f32 = 0.1;
const DOOR_FRAME_PROUD: f32 = 0.02;

/// `wall-doorway`: `wall` (4 m wide (x) x 3 m high x 0.2 m thick (z), origin at the bottom
/// centre, `ashlar`) with a doorway 1.2 m wide x 2.2 m high at x -0.6..0.6 from the floor,
/// framed in `dark wood`. The stone is three boxes, the jambs x -2..-0.7 and 0.7..2 (full
/// height) and the lintel x -0.7..0.7, y 2.3..3; the frame fills the 0.1 m between them and
/// the opening (posts x 0.6..0.7 up to y 2.2 each side, a head x -0.7..0.7, y 2.2..2.3) and
/// stands 2 cm proud of both faces (z -0.12..0.12), so the opening reads as a door's even
/// where no door hangs in it. `door` placed at x = -0.6 fills the opening.
fn wall_doorway() -> Piece {
    let mut piece = Piece::new(vec![ashlar(), dark_wood()]);
    let v = Vec3::new;
    let (w, h, f) = (DOORWAY_HALF_WIDTH, DOORWAY_HEIGHT, DOOR_FRAME_WIDTH);
    let z = 0.1 + DOOR_FRAME_PROUD;
    for side in [-1.0, 1.0] {
        piece.cuboid(
            "wall-doorway",
            v(side * 2.0, 0.0, -0.1),
            v(side * (w + f), 3.0, 0.1),
            0,
        );
    }
    piece.cuboid(
        "wall-doorway",
        v(-w - f, h + f, -0.1),
        v(w + f, 3.0, 0.1),
        0,
    );
    for side in [-1.0, 1.0] {
        piece.cuboid(
            "door frame",
            v(side * w, 0.0, -z),
            v(side * (w + f), h, z),
            1,
        );
    }
    piece.cuboid("door frame", v(-w - f, h, -z), v(w + f, h + f, z), 1);
    piece
}

/// `wall-window`: `wall` (4 x 3 x 0.2 m, origin at the bottom centre, `ashlar`) with a
/// window opening 1.2 m wide x 1.0 m high, x -0.6..0.6, y 1.0..2.0: four ashlar boxes (the
/// sides x -2..-0.6 and 0.6..2 full height, the breast under the opening up to y 0.95 and
/// the head over it from y 2.0) and a `dark wood` sill x -0.7..0.7, y 0.95..1.0,
/// z -0.15..0.15 whose top is the opening's bottom, its ends let 0.1 m into the sides and
/// standing 5 cm proud of both faces.
fn wall_window() -> Piece {
    let mut piece = Piece::new(vec![ashlar(), dark_wood()]);
    let v = Vec3::new;
    for side in [-1.0, 1.0] {
        piece.cuboid(
            "wall-window",
            v(side * 2.0, 0.0, -0.1),
            v(side * 0.6, 3.0, 0.1),
            0,
        );
    }
    piece.cuboid("wall-window", v(-0.6, 0.0, -0.1), v(0.6, 0.95, 0.1), 0);
    piece.cuboid("wall-window", v(-0.6, 2.0, -0.1), v(0.6, 3.0, 0.1), 0);
    piece.cuboid("window sill", v(-0.7, 0.95, -0.15), v(0.7, 1.0, 0.15), 1);
    piece
}

/// `door`: a `dark wood` leaf 1.2 m wide x 2.2 m high x 0.08 m thick, origin at the bottom
/// of its hinge edge: x 0..1.2, y 0..2.2, z -0.04..0.04 (it turns about the y axis). A
/// `brass` lever handle on each face, centred at x = 1.05, y = 1.0: a 6 x 12 cm rose, a
/// stem and a 12.5 cm lever pointing back towards the hinge, 0.105 m out from the middle of
/// the leaf at most. Placed at x = -0.6 of `wall-doorway` it fills the opening.
fn door() -> Piece {
    let mut piece = Piece::new(vec![dark_wood(), brass()]);
    let v = Vec3::new;
    let (w, h) = (2.0 * DOORWAY_HALF_WIDTH, DOORWAY_HEIGHT);
    piece.cuboid("door", v(0.0, 0.0, -0.04), v(w, h, 0.04), 0);
    for side in [1.0, -1.0] {
        piece.cuboid(
            "door handles",
            v(1.02, 0.94, side * 0.04),
            v(1.08, 1.06, side * 0.048),
            1,
        );
        piece.cuboid(
            "door handles",
            v(1.04, 0.99, side * 0.048),
            v(1.06, 1.01, side * 0.09),
            1,
        );
        piece.cuboid(
            "door handles",
            v(0.94, 0.988, side * 0.09),
            v(1.065, 1.012, side * 0.105),
            1,
        );
    }
    piece
}

/// Steps in `stairs`.
const STAIR_STEPS: u32 = 15;

/// `stairs`: a straight flight 1.2 m wide (x -0.6..0.6) climbing 3 m over 5 m towards -Z:
/// 15 steps of rise 0.2 m and run 1/3 m, each a solid `stone` box down to y = 0 (step `i`,
/// from 0: z -(i + 1)/3..-i/3, top at y = 0.2 (i + 1)). Origin at the floor under the first
/// step's front edge (z = 0); the top step's back edge is the landing edge, y = 3 at z = -5.
fn stairs() -> Piece {
    let mut piece = Piece::new(vec![stone()]);
    for step in 0..STAIR_STEPS {
        let (near, far) = (step as f32, (step + 1) as f32);
        let steps = STAIR_STEPS as f32;
        piece.cuboid(
            "stairs",
            Vec3::new(-0.6, 0.0, -5.0 * far / steps),
            Vec3::new(0.6, 3.0 * far / steps, -5.0 * near / steps),
            0,
        );
    }
    piece
}

/// The centre of `lamp-bracket`'s lantern housing, relative to the mount point.
pub const LANTERN_CENTRE: Vec3 = Vec3::new(0.0, -0.15, 0.35);
/// Where a level puts `lamp-bracket`'s punctual light: 4 cm under the housing's base, on
/// its axis. Not at `LANTERN_CENTRE`: the glass is a closed opaque solid, so a light inside
/// it would be hidden from everything (the renderer's shadow rays and the game's rays to
/// a lamp alike).
pub const LAMP_BRACKET_LIGHT: Vec3 = Vec3::new(0.0, -0.27, 0.35);

/// The light a kit lantern casts, as a level writes it: a warm spot aimed straight down
/// (rotation -90 degrees about X) that lights a pool about 4 m across from bracket height.
/// The editor's template and its lamp prefab both hang this one.
pub const LANTERN_SPOT: super::level::LightDef = super::level::LightDef::Spot {
    color: Vec3::new(1.0, 0.8, 0.55),
    intensity: 24.0,
    inner_cone_degrees: 25.0,
    outer_cone_degrees: 40.0,
};

/// `lamp-bracket`: a wall-mounted `iron` bracket with a lantern. Origin at the mount point
/// on the wall, which is the z = 0 plane behind it; nothing lies behind z = 0. A back plate
/// (x -0.05..0.05, y -0.12..0.06, z 0..0.015), a 2.5 cm square arm along +Z at y = 0 out to
/// z = 0.38 with a diagonal brace under it, a hanger, and the lantern ([`lantern`])
/// centred at (0, -0.15, 0.35), x -0.08..0.08, y -0.23..-0.07, z 0.27..0.43. A level's
/// light goes at (0, -0.27, 0.35), 4 cm under the housing (see `LAMP_BRACKET_LIGHT`).
fn lamp_bracket() -> anyhow::Result<Piece> {
    let mut piece = Piece::new(vec![iron(), lantern_glass()]);
    let v = Vec3::new;
    let c = LANTERN_CENTRE;
    let name = "lamp bracket";
    piece.cuboid(name, v(-0.05, -0.12, 0.0), v(0.05, 0.06, 0.015), IRON);
    piece.cuboid(
        name,
        v(-0.0125, -0.0125, 0.015),
        v(0.0125, 0.0125, 0.38),
        IRON,
    );
    // The brace's ends are buried in the plate and the arm.
    piece.solids.push(bar(
        name,
        v(0.0, -0.1, 0.0075),
        v(0.0, 0.0, 0.2),
        0.008,
        IRON,
    )?);
    piece.cuboid(
        name,
        v(-0.006, -0.045, c.z - 0.006),
        v(0.006, 0.0, c.z + 0.006),
        IRON,
    );
    lantern(&mut piece, name, c)?;
    Ok(piece)
}

/// The lantern pieces' materials, by index: `iron` first, then `lantern glass`.
const IRON: usize = 0;
const GLASS: usize = 1;

/// `lantern glass`: base colour (0.9, 0.8, 0.6), radiance (6, 4, 1.5).
fn lantern_glass() -> KitMaterial {
    plain(MaterialData {
        emissive: Vec3::new(6.0, 4.0, 1.5),
        ..MaterialData::lambertian("lantern glass", Vec3::new(0.9, 0.8, 0.6))
    })
}

/// A lantern housing 0.16 m across centred at `c`, solids named `name` (and `lantern
/// glass`): an `IRON` pyramid roof from 8 cm over `c` peaking 11.5 cm over it, a cap and a
/// base, four corner posts, and round the emissive `GLASS` box (0.14 x 0.125 x 0.14 m)
/// between them. The housing spans `c` +- (0.08, 0.08, 0.08).
fn lantern(piece: &mut Piece, name: &str, c: Vec3) -> anyhow::Result<()> {
    let v = Vec3::new;
    piece.solids.push(pyramid(
        name,
        c + v(0.0, 0.08, 0.0),
        0.085,
        c + v(0.0, 0.115, 0.0),
        IRON,
    )?);
    piece.cuboid(
        name,
        c + v(-0.08, 0.065, -0.08),
        c + v(0.08, 0.08, 0.08),
        IRON,
    );
    piece.cuboid(
        name,
        c + v(-0.08, -0.08, -0.08),
        c + v(0.08, -0.06, 0.08),
        IRON,
    );
    for (x, z) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
        piece.cuboid(
            name,
            c + v(x * 0.065, -0.06, z * 0.065),
            c + v(x * 0.08, 0.065, z * 0.08),
            IRON,
        );
    }
    piece.cuboid(
        "lantern glass",
        c + v(-0.07, -0.06, -0.07),
        c + v(0.07, 0.065, 0.07),
        GLASS,
    );
    Ok(())
}

/// The centre of `hanging-lamp`'s lantern, under the point it hangs from.
pub const HANGING_LAMP_CENTRE: Vec3 = Vec3::new(0.0, -0.3, 0.0);
/// Where a level puts `hanging-lamp`'s punctual light: 4 cm under the housing, on its
/// axis (as `LAMP_BRACKET_LIGHT`).
pub const HANGING_LAMP_LIGHT: Vec3 = Vec3::new(0.0, -0.42, 0.0);

/// `hanging-lamp`: the lantern of `lamp-bracket` hung on an `iron` rod under a ceiling
/// plate. Origin at the point it hangs from, nothing above y = 0: a plate 0.12 m square
/// (y -0.02..0), a 1.2 cm rod down into the lantern's roof, and the lantern centred at
/// (0, -0.3, 0) (x and z -0.08..0.08, y -0.38..-0.22). Hang it under a `beam` (its
/// underside is the beam's origin); its light goes at (0, -0.42, 0) (`HANGING_LAMP_LIGHT`).
fn hanging_lamp() -> anyhow::Result<Piece> {
    let mut piece = Piece::new(vec![iron(), lantern_glass()]);
    let v = Vec3::new;
    let c = HANGING_LAMP_CENTRE;
    let name = "hanging lamp";
    piece.cuboid(name, v(-0.06, -0.02, -0.06), v(0.06, 0.0, 0.06), IRON);
    piece.cuboid(
        name,
        v(-0.006, c.y + 0.1, -0.006),
        v(0.006, -0.02, 0.006),
        IRON,
    );
    lantern(&mut piece, name, c)?;
    Ok(piece)
}

/// `beam`: a `dark wood` ceiling beam 8 m long (x -4..4), 0.2 m wide (z -0.1..0.1) and
/// 0.25 m deep, origin at the middle of its underside: set at y = 3 with its ends on the
/// centre lines of two walls 8 m apart, it rests on their tops and spans the room.
fn beam() -> Piece {
    let mut piece = Piece::new(vec![dark_wood()]);
    piece.cuboid(
        "beam",
        Vec3::new(-4.0, 0.0, -0.1),
        Vec3::new(4.0, 0.25, 0.1),
        0,
    );
    piece
}

/// Height of the middle of `candle`'s flame (y 0.17..0.22).
pub const CANDLE_FLAME_CENTRE: f32 = 0.195;
/// Where a level puts `candle`'s punctual light: 2 cm over the flame's tip, on its axis
/// (inside the closed flame it would be hidden, as for `LAMP_BRACKET_LIGHT`).
pub const CANDLE_LIGHT: Vec3 = Vec3::new(0.0, 0.24, 0.0);

/// `candle`: a candle on a dish, origin at the bottom centre. A `brass` dish (cylinder of
/// radius 0.06 m, 1.5 cm high, 16 segments), a `wax` candle (0.9, 0.85, 0.7), roughness
/// 0.6 (radius 0.02 m, 0.15 m tall, y 0.015..0.165, 12 segments) and a `candle flame` (base
/// colour (1, 0.9, 0.6), radiance (8, 5, 1.5)): a flat-shaded spindle 0.02 m across,
/// y 0.17..0.22, its widest ring (6 sides) at y 0.185; flame centre y = 0.195. A level's
/// light goes at (0, 0.24, 0), 2 cm over the tip (see `CANDLE_LIGHT`).
fn candle() -> anyhow::Result<Piece> {
    let wax = MaterialData {
        roughness: 0.6,
        ..MaterialData::lambertian("wax", Vec3::new(0.9, 0.85, 0.7))
    };
    let flame = MaterialData {
        emissive: Vec3::new(8.0, 5.0, 1.5),
        ..MaterialData::lambertian("candle flame", Vec3::new(1.0, 0.9, 0.6))
    };
    let mut piece = Piece::new(vec![brass(), textured(Surface::Wax, wax), plain(flame)]);
    piece
        .solids
        .push(MeshData::cylinder("candle dish", 0.06, 0.015, 16, 0));
    piece.solids.push(translated(
        MeshData::cylinder("candle", 0.02, 0.15, 12, 1),
        Vec3::new(0.0, 0.015, 0.0),
    ));
    let mut vertices = vec![Vec3::new(0.0, 0.17, 0.0), Vec3::new(0.0, 0.22, 0.0)];
    vertices.extend((0..6).map(|i| {
        let angle = std::f64::consts::TAU * f64::from(i) / 6.0;
        Vec3::new(
            (0.01 * angle.sin()) as f32,
            0.185,
            (0.01 * angle.cos()) as f32,
        )
    }));
    let faces: Vec<[usize; 3]> = (0..6)
        .flat_map(|i| [[0, 2 + i, 2 + (i + 1) % 6], [1, 2 + i, 2 + (i + 1) % 6]])
        .collect();
    let faces: Vec<&[usize]> = faces.iter().map(|face| face.as_slice()).collect();
    piece.solids.push(MeshData::convex_solid(
        "candle flame",
        &vertices,
        &faces,
        2,
    )?);
    Ok(piece)
}

/// `bottle`: a dark green bottle standing on its base at the origin: a body of radius
/// 0.07 m and 0.24 m tall, then a neck of radius 0.022 m to y = 0.34 (16 segments each).
/// Levels make it knockable: it topples about its base with a crash.
fn bottle() -> Piece {
    let glass = MaterialData {
        roughness: 0.25,
        ..MaterialData::lambertian("bottle green", Vec3::new(0.06, 0.16, 0.08))
    };
    let mut piece = Piece::new(vec![textured(Surface::Glass, glass)]);
    piece
        .solids
        .push(MeshData::cylinder("bottle", 0.07, 0.24, 16, 0));
    piece.solids.push(translated(
        MeshData::cylinder("bottle", 0.022, 0.1, 16, 0),
        Vec3::new(0.0, 0.24, 0.0),
    ));
    piece
}

/// `table`: a `wood` table (as `crate`), origin at the floor under its centre. Top 1.6 x
/// 0.8 m (x -0.8..0.8, z -0.4..0.4), 0.05 m thick, its top surface at y = 0.75; four legs
/// 0.07 m square, 5 cm in from the edges (x +-0.68..+-0.75, z +-0.28..+-0.35), and 0.1 m
/// aprons under the top between the legs.
fn table() -> Piece {
    let mut piece = Piece::new(vec![wood()]);
    let v = Vec3::new;
    piece.cuboid("table", v(-0.8, 0.7, -0.4), v(0.8, 0.75, 0.4), 0);
    for (x, z) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
        piece.cuboid(
            "table",
            v(x * 0.68, 0.0, z * 0.28),
            v(x * 0.75, 0.7, z * 0.35),
            0,
        );
    }
    for side in [-1.0, 1.0] {
        piece.cuboid(
            "table",
            v(-0.68, 0.6, side * 0.31),
            v(0.68, 0.7, side * 0.33),
            0,
        );
        piece.cuboid(
            "table",
            v(side * 0.71, 0.6, -0.28),
            v(side * 0.73, 0.7, 0.28),
            0,
        );
    }
    piece
}

/// `barrel`: a `wood` barrel 0.9 m tall of radius 0.3 m standing on its base at the origin
/// (16 staves' worth of sides), with two `iron` hoops 5 cm wide standing 1 cm proud (their
/// middles at y 0.15 and 0.75).
fn barrel() -> Piece {
    let mut piece = Piece::new(vec![wood(), iron()]);
    piece
        .solids
        .push(MeshData::cylinder("barrel", 0.3, 0.9, 16, 0));
    for middle in [0.15, 0.75] {
        piece.solids.push(translated(
            MeshData::cylinder("barrel hoops", 0.31, 0.05, 16, 1),
            Vec3::new(0.0, middle - 0.025, 0.0),
        ));
    }
    piece
}

/// `shelf`: open `wood` shelves 1.0 m wide x 1.8 m high x 0.35 m deep, origin at the bottom
/// centre of its back (x -0.5..0.5, y 0..1.8, z 0..0.35), to stand against a wall as
/// `bookcase` does. Two 2 cm sides and four 2.5 cm boards (tops at y 0.1, 0.65, 1.2 and
/// 1.8); on the lower three stand `earthenware` jars (0.42, 0.26, 0.16) on dressed stone,
/// 5..9 cm in radius and 0.14..0.26 m tall, placed by a fixed hash.
fn shelf() -> Piece {
    let earthenware = MaterialData {
        roughness: 0.7,
        ..MaterialData::lambertian("earthenware", Vec3::new(0.42, 0.26, 0.16))
    };
    let mut piece = Piece::new(vec![wood(), textured(Surface::DressedStone, earthenware)]);
    let v = Vec3::new;
    for side in [-1.0, 1.0] {
        piece.cuboid(
            "shelf",
            v(side * 0.5, 0.0, 0.0),
            v(side * 0.48, 1.8, 0.35),
            0,
        );
    }
    let boards = [0.1, 0.65, 1.2, 1.8];
    for top in boards {
        piece.cuboid("shelf", v(-0.48, top - 0.025, 0.0), v(0.48, top, 0.35), 0);
    }
    for (board, &floor) in boards[..3].iter().enumerate() {
        let mut x = -0.46;
        for jar in 0_u32.. {
            let r = kit_surfaces::hash(0x5e1f_0000 + 16 * board as u32 + jar);
            let radius = 0.05 + (r % 5) as f32 * 0.01;
            let gap = 0.02 + ((r >> 4) % 10) as f32 * 0.02;
            if x + gap + 2.0 * radius > 0.46 {
                break;
            }
            x += gap + radius;
            let height = 0.14 + ((r >> 8) % 7) as f32 * 0.02;
            let z = 0.17 + ((r >> 12) % 3) as f32 * 0.02;
            piece.solids.push(translated(
                MeshData::cylinder("jars", radius, height, 12, 1),
                v(x, floor, z),
            ));
            x += radius;
        }
    }
    piece
}

/// `rug`: a woven rug 2.4 x 1.6 m and 1 cm thick lying on the floor, origin at the middle
/// of its underside (x -1.2..1.2, z -0.8..0.8, y 0..0.01): a `rug red` (0.3, 0.05, 0.04)
/// field inside a 0.15 m `rug ochre` (0.45, 0.3, 0.1) border, both cloth, roughness 1.
/// Thinner than a step, so feet and the wardens' paths cross it as floor.
fn rug() -> Piece {
    let cloth = |name: &str, colour: Vec3| {
        textured(
            Surface::Cloth,
            MaterialData {
                roughness: 1.0,
                ..MaterialData::lambertian(name, colour)
            },
        )
    };
    let mut piece = Piece::new(vec![
        cloth("rug red", Vec3::new(0.3, 0.05, 0.04)),
        cloth("rug ochre", Vec3::new(0.45, 0.3, 0.1)),
    ]);
    let v = Vec3::new;
    let (x, z, border, top) = (1.2, 0.8, 0.15, 0.01);
    piece.cuboid(
        "rug",
        v(border - x, 0.0, border - z),
        v(x - border, top, z - border),
        0,
    );
    for side in [-1.0, 1.0] {
        piece.cuboid(
            "rug border",
            v(-x, 0.0, side * (z - border)),
            v(x, top, side * z),
            1,
        );
        piece.cuboid(
            "rug border",
            v(side * (x - border), 0.0, border - z),
            v(side * x, top, z - border),
            1,
        );
    }
    piece
}

/// The bookcase's book materials: (name, linear base colour); roughness 0.8.
const BOOK_COLOURS: [(&str, Vec3); 4] = [
    ("book red", Vec3::new(0.45, 0.07, 0.05)),
    ("book green", Vec3::new(0.1, 0.28, 0.14)),
    ("book blue", Vec3::new(0.1, 0.14, 0.35)),
    ("book ochre", Vec3::new(0.55, 0.4, 0.14)),
];

/// `bookcase`: a `dark wood` bookcase 1.2 m wide x 2.0 m high x 0.4 m deep, origin at the
/// bottom centre of its back: x -0.6..0.6, y 0..2, z 0..0.4, so placed on a wall's face it
/// stands against it and reaches out along +Z. The carcass: a 2 cm back, 2 cm sides, a
/// plinth up to y = 0.1, a 2.5 cm top and three 2.5 cm shelves, leaving four shelves of
/// books (standing on y 0.1, 0.56875, 1.0375 and 1.50625). Each shelf holds a run of
/// upright books (boxes 2.5..5.5 cm thick, 0.2..0.32 m tall, 0.17..0.22 m deep, fronts
/// near z = 0.38) from one end, in four colours (`book red`, `book green`, `book blue`,
/// `book ochre`), all chosen by a fixed hash.
fn bookcase() -> Piece {
    let mut materials = vec![dark_wood()];
    materials.extend(BOOK_COLOURS.iter().map(|&(name, colour)| {
        textured(
            Surface::Leather,
            MaterialData {
                roughness: 0.8,
                ..MaterialData::lambertian(name, colour)
            },
        )
    }));
    let mut piece = Piece::new(materials);
    let v = Vec3::new;
    let (bottom, top) = (0.1, 1.975);
    piece.cuboid("bookcase", v(-0.6, 0.0, 0.0), v(0.6, 2.0, 0.02), 0);
    for side in [-1.0, 1.0] {
        piece.cuboid(
            "bookcase",
            v(side * 0.6, 0.0, 0.02),
            v(side * 0.58, 2.0, 0.4),
            0,
        );
    }
    piece.cuboid("bookcase", v(-0.58, 0.0, 0.02), v(0.58, bottom, 0.4), 0);
    piece.cuboid("bookcase", v(-0.58, top, 0.02), v(0.58, 2.0, 0.4), 0);
    let pitch = (top - bottom) / 4.0;
    for shelf in 1..4 {
        let y = bottom + shelf as f32 * pitch;
        piece.cuboid("bookcase", v(-0.58, y - 0.025, 0.02), v(0.58, y, 0.4), 0);
    }
    for shelf in 0..4_u32 {
        let floor = bottom + shelf as f32 * pitch;
        let seed = kit_surfaces::hash(0x0b00_c500 + shelf);
        let run = 0.45 + (seed % 36) as f32 * 0.01;
        let from_left = seed & 0x100 == 0;
        let mut filled = 0.0;
        for book in 0_u32.. {
            let r = kit_surfaces::hash(seed ^ book.wrapping_mul(0x9e37_79b9));
            let thickness = 0.025 + (r % 31) as f32 * 0.001;
            if filled + thickness > run {
                break;
            }
            let height = 0.2 + ((r >> 5) % 13) as f32 * 0.01;
            let depth = 0.17 + ((r >> 9) % 6) as f32 * 0.01;
            let front = 0.385 - ((r >> 13) % 3) as f32 * 0.005;
            let colour = ((r >> 16) % 4) as usize;
            let (left, right) = if from_left {
                (-0.575 + filled, -0.575 + filled + thickness)
            } else {
                (0.575 - filled - thickness, 0.575 - filled)
            };
            piece.cuboid(
                BOOK_COLOURS[colour].0,
                v(left, floor, front - depth),
                v(right, floor + height, front),
                1 + colour,
            );
            filled += thickness + 0.002;
        }
    }
    piece
}

/// `mirror`: a 1.2 m wide x 2.0 m high mirror facing +Z, origin at the bottom centre of the
/// glass's back. The glass is a box x -0.6..0.6, y 0..2, z 0..0.03, material `mirror` (0.9,
/// 0.9, 0.9), metallic 1, roughness 0: its reflecting face is the z = 0.03 plane over x
/// -0.6..0.6, y 0..2 (the rectangle the game uses for sight through mirrors). Around it a
/// 0.06 m `dark wood` frame (x -0.66..0.66, y -0.06..2.06, z 0..0.05) stands 2 cm proud of
/// the glass; it reaches 6 cm below the origin, so hang the mirror at y >= 0.06.
fn mirror() -> Piece {
    let glass = MaterialData {
        metallic: 1.0,
        roughness: 0.0,
        ..MaterialData::lambertian("mirror", Vec3::splat(0.9))
    };
    let mut piece = Piece::new(vec![plain(glass), dark_wood()]);
    let v = Vec3::new;
    piece.cuboid("mirror", v(-0.6, 0.0, 0.0), v(0.6, 2.0, 0.03), 0);
    for side in [-1.0, 1.0] {
        piece.cuboid(
            "mirror frame",
            v(side * 0.6, -0.06, 0.0),
            v(side * 0.66, 2.06, 0.05),
            1,
        );
    }
    piece.cuboid("mirror frame", v(-0.6, -0.06, 0.0), v(0.6, 0.0, 0.05), 1);
    piece.cuboid("mirror frame", v(-0.6, 2.0, 0.0), v(0.6, 2.06, 0.05), 1);
    piece
}

/// `gate`: an `iron` portcullis 2.0 m wide x 2.4 m high x 0.1 m deep, origin at the bottom
/// centre (x -1..1, y 0..2.4, z -0.05..0.05), to slide up and down. Ten vertical bars 0.05 m
/// square every 0.2 m (centres x = -0.9..0.9), each ending in a 0.1 m pyramid spike at
/// y = 0, and three full-width rails 0.06 m high and 0.1 m deep (tops at y 0.41, 1.31, 2.4).
fn gate() -> anyhow::Result<Piece> {
    let mut piece = Piece::new(vec![iron()]);
    let v = Vec3::new;
    for bar in 0..10 {
        let x = (2 * bar - 9) as f32 * 0.1;
        piece.cuboid(
            "gate",
            v(x - 0.025, 0.1, -0.025),
            v(x + 0.025, 2.37, 0.025),
            0,
        );
        piece
            .solids
            .push(pyramid("gate", v(x, 0.1, 0.0), 0.025, v(x, 0.0, 0.0), 0)?);
    }
    for top in [0.41, 1.31, 2.4] {
        piece.cuboid("gate", v(-1.0, top - 0.06, -0.05), v(1.0, top, 0.05), 0);
    }
    Ok(piece)
}

/// The gate's cycle, seconds: shut, rising, open, falling (then round again).
pub const GATE_CYCLE: [f32; 4] = [4.0, 1.5, 4.0, 1.5];
/// How far the open gate has risen, metres: its spikes clear a standing player's head.
pub const GATE_RISE: f32 = 2.3;

/// Clip `lift` of `gate.glb`: its node shut at y = 0 for `GATE_CYCLE[0]`, rising
/// `GATE_RISE` over `GATE_CYCLE[1]`, open for `GATE_CYCLE[2]`, falling over
/// `GATE_CYCLE[3]`; LINEAR translation, the last key equal to the first, so it loops.
fn gate_lift() -> AnimationData {
    let [shut, rising, open, falling] = GATE_CYCLE;
    let times = vec![
        0.0,
        shut,
        shut + rising,
        shut + rising + open,
        shut + rising + open + falling,
    ];
    let heights = [0.0, 0.0, GATE_RISE, GATE_RISE, 0.0];
    AnimationData {
        name: "lift".into(),
        channels: vec![ChannelData {
            node: 0,
            property: AnimatedProperty::Translation,
            interpolation: Interpolation::Linear,
            times,
            values: heights.iter().flat_map(|&y| [0.0, y, 0.0]).collect(),
        }],
    }
}

/// The kit pieces built from closed solids, by file stem.
fn kit_pieces() -> anyhow::Result<Vec<(&'static str, Piece)>> {
    Ok(vec![
        ("wall-doorway", wall_doorway()),
        ("wall-window", wall_window()),
        ("door", door()),
        ("stairs", stairs()),
        ("lamp-bracket", lamp_bracket()?),
        ("hanging-lamp", hanging_lamp()?),
        ("beam", beam()),
        ("candle", candle()?),
        ("bottle", bottle()),
        ("table", table()),
        ("bookcase", bookcase()),
        ("shelf", shelf()),
        ("barrel", barrel()),
        ("rug", rug()),
        ("mirror", mirror()),
        ("gate", gate()?),
    ])
}

// ---- the warden: the skinned, animated enemy -----------------------------------------------

/// The warden's joint names, in skin order; node `i` of [`warden_document`] is joint `i`.
/// ".L" is the warden's left (+X: it faces +Z), ".R" its right (-X).
pub const WARDEN_JOINTS: [&str; 11] = [
    "hips",
    "spine",
    "head",
    "upper_arm.L",
    "lower_arm.L",
    "upper_arm.R",
    "lower_arm.R",
    "upper_leg.L",
    "lower_leg.L",
    "upper_leg.R",
    "lower_leg.R",
];

const HIPS: usize = 0;
const SPINE: usize = 1;
const HEAD: usize = 2;
const UPPER_ARM_L: usize = 3;
const LOWER_ARM_L: usize = 4;
const UPPER_ARM_R: usize = 5;
const LOWER_ARM_R: usize = 6;
const UPPER_LEG_L: usize = 7;
const LOWER_LEG_L: usize = 8;
const UPPER_LEG_R: usize = 9;
const LOWER_LEG_R: usize = 10;

/// Bind pose of each joint: (parent, translation from the parent); no rotation or scale,
/// so every limb hangs straight down. World positions: hips (0, 0.95, 0), spine y 1.1,
/// head (neck) y 1.5, shoulders (+-0.25, 1.42), elbows y 1.13, hip joints (+-0.1, 0.92),
/// knees y 0.5.
const WARDEN_BIND: [(Option<usize>, Vec3); 11] = [
    (None, Vec3::new(0.0, 0.95, 0.0)),
    (Some(HIPS), Vec3::new(0.0, 0.15, 0.0)),
    (Some(SPINE), Vec3::new(0.0, 0.4, 0.0)),
    (Some(SPINE), Vec3::new(0.25, 0.32, 0.0)),
    (Some(UPPER_ARM_L), Vec3::new(0.0, -0.29, 0.0)),
    (Some(SPINE), Vec3::new(-0.25, 0.32, 0.0)),
    (Some(UPPER_ARM_R), Vec3::new(0.0, -0.29, 0.0)),
    (Some(HIPS), Vec3::new(0.1, -0.03, 0.0)),
    (Some(UPPER_LEG_L), Vec3::new(0.0, -0.42, 0.0)),
    (Some(HIPS), Vec3::new(-0.1, -0.03, 0.0)),
    (Some(UPPER_LEG_R), Vec3::new(0.0, -0.42, 0.0)),
];

/// Tessellation of the shipped `kit/warden.glb`.
const WARDEN_DETAIL: u32 = 3;

/// A body part: a closed surface of revolution around a vertical axis with elliptical
/// cross-sections, given bottom to top as (y, half-width in x, half-depth in z) with a
/// pole (zero radius) at each end; all y in the bind pose, in metres.
struct BodyPart {
    /// Axis position (x, z).
    axis: Vec2,
    profile: &'static [[f32; 3]],
    /// The bones the part follows, bottom to top.
    bones: &'static [usize],
    /// Between `bones[i]` and `bones[i + 1]`: (joint whose bind height is the seam,
    /// half-width of the blend zone in metres).
    seams: &'static [(usize, f32)],
}

/// Legs (left +X, right -X): foot stump to inside the pelvis, knee at 0.5.
const LEG_PROFILE: &[[f32; 3]] = &[
    [0.02, 0.0, 0.0],
    [0.03, 0.035, 0.04],
    [0.08, 0.045, 0.05],
    [0.3, 0.055, 0.06],
    [0.48, 0.05, 0.055],
    [0.7, 0.07, 0.075],
    [0.9, 0.08, 0.08],
    [0.98, 0.06, 0.06],
    [1.0, 0.0, 0.0],
];
/// Pelvis, waist, chest and shoulders, closing at the neck.
const TORSO_PROFILE: &[[f32; 3]] = &[
    [0.84, 0.0, 0.0],
    [0.86, 0.12, 0.09],
    [0.92, 0.17, 0.11],
    [1.05, 0.15, 0.1],
    [1.3, 0.19, 0.12],
    [1.42, 0.19, 0.11],
    [1.48, 0.12, 0.08],
    [1.52, 0.05, 0.05],
    [1.53, 0.0, 0.0],
];
/// Neck and head; the crown is the warden's highest point, y = 1.8.
const HEAD_PROFILE: &[[f32; 3]] = &[
    [1.46, 0.0, 0.0],
    [1.47, 0.04, 0.04],
    [1.56, 0.05, 0.05],
    [1.6, 0.08, 0.09],
    [1.68, 0.1, 0.11],
    [1.75, 0.09, 0.1],
    [1.79, 0.05, 0.055],
    [1.8, 0.0, 0.0],
];
/// Arms from the fist up to the shoulder cap; elbow at 1.13.
const ARM_PROFILE: &[[f32; 3]] = &[
    [0.74, 0.0, 0.0],
    [0.75, 0.03, 0.035],
    [0.8, 0.042, 0.045],
    [0.87, 0.035, 0.035],
    [1.12, 0.045, 0.045],
    [1.38, 0.055, 0.055],
    [1.45, 0.05, 0.05],
    [1.48, 0.0, 0.0],
];

const WARDEN_PARTS: [BodyPart; 6] = [
    BodyPart {
        axis: Vec2::new(0.1, 0.0),
        profile: LEG_PROFILE,
        bones: &[LOWER_LEG_L, UPPER_LEG_L, HIPS],
        seams: &[(LOWER_LEG_L, 0.06), (UPPER_LEG_L, 0.04)],
    },
    BodyPart {
        axis: Vec2::new(-0.1, 0.0),
        profile: LEG_PROFILE,
        bones: &[LOWER_LEG_R, UPPER_LEG_R, HIPS],
        seams: &[(LOWER_LEG_R, 0.06), (UPPER_LEG_R, 0.04)],
    },
    BodyPart {
        axis: Vec2::new(0.0, 0.0),
        profile: TORSO_PROFILE,
        bones: &[HIPS, SPINE, HEAD],
        seams: &[(SPINE, 0.08), (HEAD, 0.03)],
    },
    BodyPart {
        axis: Vec2::new(0.0, 0.01),
        profile: HEAD_PROFILE,
        bones: &[SPINE, HEAD],
        seams: &[(HEAD, 0.03)],
    },
    BodyPart {
        axis: Vec2::new(0.25, 0.0),
        profile: ARM_PROFILE,
        bones: &[LOWER_ARM_L, UPPER_ARM_L, SPINE],
        seams: &[(LOWER_ARM_L, 0.06), (UPPER_ARM_L, 0.04)],
    },
    BodyPart {
        axis: Vec2::new(-0.25, 0.0),
        profile: ARM_PROFILE,
        bones: &[LOWER_ARM_R, UPPER_ARM_R, SPINE],
        seams: &[(LOWER_ARM_R, 0.06), (UPPER_ARM_R, 0.04)],
    },
];

/// Each joint's bind-pose world transform (parents come before children in `WARDEN_BIND`).
fn warden_bind_world() -> [Affine3A; 11] {
    let mut world = [Affine3A::IDENTITY; 11];
    for (joint, &(parent, translation)) in WARDEN_BIND.iter().enumerate() {
        let parent_world = parent.map_or(Affine3A::IDENTITY, |p| world[p]);
        world[joint] = parent_world * Affine3A::from_translation(translation);
    }
    world
}

/// The skin influences of a vertex at bind height `y` on `part`: one bone away from the
/// seams, and a smoothstep blend of the two bones next to a seam within its zone.
fn part_influences(part: &BodyPart, seam_heights: &[f32], y: f32) -> ([u16; 4], [f32; 4]) {
    let single = |bone: usize| ([bone as u16, 0, 0, 0], [1.0, 0.0, 0.0, 0.0]);
    for (i, (&(_, half_width), &height)) in part.seams.iter().zip(seam_heights).enumerate() {
        if y >= height + half_width {
            continue;
        }
        let s = ((y - (height - half_width)) / (2.0 * half_width)).clamp(0.0, 1.0);
        let upper = s * s * (3.0 - 2.0 * s);
        return if upper <= 0.0 {
            single(part.bones[i])
        } else if upper >= 1.0 {
            single(part.bones[i + 1])
        } else {
            (
                [part.bones[i] as u16, part.bones[i + 1] as u16, 0, 0],
                [1.0 - upper, upper, 0.0, 0.0],
            )
        };
    }
    single(part.bones[part.bones.len() - 1])
}

/// Appends `part` to `mesh` as a closed, smooth-shaded surface of revolution: `segments`
/// vertices around each ring, rings about `spacing` metres apart along the profile, a
/// single vertex at each pole. Normals are the area-weighted face normals (outward: the
/// triangles are counter-clockwise seen from outside).
fn push_body_part(
    mesh: &mut MeshData,
    part: &BodyPart,
    seam_heights: &[f32],
    segments: u32,
    spacing: f32,
) -> anyhow::Result<()> {
    let profile = part.profile;
    ensure!(
        profile.len() >= 3
            && profile[0][1..] == [0.0, 0.0]
            && profile[profile.len() - 1][1..] == [0.0, 0.0]
            && profile[1..profile.len() - 1]
                .iter()
                .all(|p| p[1] > 0.0 && p[2] > 0.0),
        "a body part's profile must run from pole to pole through positive radii"
    );
    // Profile length in the (y, mean radius) plane, sampled evenly by arc length.
    let point = |p: &[f32; 3]| Vec2::new(p[0], 0.5 * (p[1] + p[2]));
    let lengths: Vec<f32> = profile
        .windows(2)
        .map(|w| point(&w[0]).distance(point(&w[1])))
        .collect();
    let total: f32 = lengths.iter().sum();
    let steps = ((total / spacing).ceil() as usize).max(3);
    let mut rings = Vec::with_capacity(steps - 1);
    let (mut segment, mut start) = (0, 0.0);
    for step in 1..steps {
        let at = total * step as f32 / steps as f32;
        while segment + 1 < lengths.len() && at > start + lengths[segment] {
            start += lengths[segment];
            segment += 1;
        }
        let t = ((at - start) / lengths[segment]).clamp(0.0, 1.0);
        let (a, b) = (profile[segment], profile[segment + 1]);
        rings.push([0, 1, 2].map(|i| a[i] + (b[i] - a[i]) * t));
    }

    let first = mesh.positions.len() as u32;
    let first_triangle = mesh.indices.len();
    let around: Vec<(f32, f32)> = (0..segments)
        .map(|j| {
            // Trig in f64, rounded to f32: the same bits in every build profile.
            let angle = std::f64::consts::TAU * f64::from(j) / f64::from(segments);
            (angle.sin() as f32, angle.cos() as f32)
        })
        .collect();
    let push_vertex = |mesh: &mut MeshData, position: Vec3| {
        let (joints, weights) = part_influences(part, seam_heights, position.y);
        mesh.uvs.push(planar_uv(position));
        mesh.positions.push(position);
        mesh.joints.push(joints);
        mesh.weights.push(weights);
    };
    let (bottom, top) = (profile[0][0], profile[profile.len() - 1][0]);
    push_vertex(mesh, Vec3::new(part.axis.x, bottom, part.axis.y));
    for &[y, half_width, half_depth] in &rings {
        for &(sin, cos) in &around {
            let position = Vec3::new(
                part.axis.x + half_width * sin,
                y,
                part.axis.y + half_depth * cos,
            );
            push_vertex(mesh, position);
        }
    }
    push_vertex(mesh, Vec3::new(part.axis.x, top, part.axis.y));

    // Vertex `j` of ring `r`; the angle grows to the right seen from outside.
    let ring = |r: usize, j: u32| first + 1 + r as u32 * segments + j % segments;
    let bottom_pole = first;
    let top_pole = ring(rings.len(), 0);
    for j in 0..segments {
        mesh.indices.push([bottom_pole, ring(0, j + 1), ring(0, j)]);
        for r in 0..rings.len() - 1 {
            let (bottom_left, bottom_right) = (ring(r, j), ring(r, j + 1));
            let (top_left, top_right) = (ring(r + 1, j), ring(r + 1, j + 1));
            mesh.indices.push([bottom_left, bottom_right, top_right]);
            mesh.indices.push([bottom_left, top_right, top_left]);
        }
        let last = rings.len() - 1;
        mesh.indices
            .push([ring(last, j), ring(last, j + 1), top_pole]);
    }

    let mut normals = vec![Vec3::ZERO; mesh.positions.len() - first as usize];
    for triangle in &mesh.indices[first_triangle..] {
        let [a, b, c] = triangle.map(|i| mesh.positions[i as usize]);
        let area_normal = (b - a).cross(c - a);
        for &i in triangle {
            normals[(i - first) as usize] += area_normal;
        }
    }
    mesh.normals
        .extend(normals.into_iter().map(Vec3::normalize_or_zero));
    Ok(())
}

/// The warden's UVs in metres: a planar projection, u along x - z and v down y, which a
/// body of revolution takes without a seam (the cloth's weave stretches a little where
/// the surface turns away from the projection, unseen on a figure in the dark).
fn planar_uv(position: Vec3) -> Vec2 {
    Vec2::new(
        (position.x - position.z) * std::f32::consts::FRAC_1_SQRT_2,
        -position.y,
    )
}

/// Appends a box (flat faces) rigidly bound to joint `bone`, with `planar_uv`'s UVs.
fn push_rigid_box(mesh: &mut MeshData, min: Vec3, max: Vec3, bone: usize) {
    let cuboid = MeshData::cuboid("", min, max, 0);
    let first = mesh.positions.len() as u32;
    mesh.uvs
        .extend(cuboid.positions.iter().map(|&p| planar_uv(p)));
    mesh.positions.extend(&cuboid.positions);
    mesh.normals.extend(&cuboid.normals);
    mesh.joints.extend(std::iter::repeat_n(
        [bone as u16, 0, 0, 0],
        cuboid.positions.len(),
    ));
    mesh.weights.extend(std::iter::repeat_n(
        [1.0, 0.0, 0.0, 0.0],
        cuboid.positions.len(),
    ));
    mesh.indices
        .extend(cuboid.indices.iter().map(|t| t.map(|i| first + i)));
}

/// A unit quaternion turning `angle` radians about the axis-aligned unit `axis`, from f64 trig.
fn axis_angle(axis: Vec3, angle: f64) -> [f32; 4] {
    let (sin, cos) = (0.5 * angle).sin_cos();
    [
        (f64::from(axis.x) * sin) as f32,
        (f64::from(axis.y) * sin) as f32,
        (f64::from(axis.z) * sin) as f32,
        cos as f32,
    ]
}

/// A rotation channel about the axis-aligned `axis` with keys at `times`, turning
/// `angle(key)` radians at each.
fn rotation_channel(
    node: usize,
    interpolation: Interpolation,
    times: &[f32],
    axis: Vec3,
    angle: impl Fn(usize) -> f64,
) -> ChannelData {
    ChannelData {
        node,
        property: AnimatedProperty::Rotation,
        interpolation,
        times: times.to_vec(),
        values: (0..times.len())
            .flat_map(|key| axis_angle(axis, angle(key)))
            .collect(),
    }
}

/// `walk`: a 1 s loop, 17 LINEAR keys (every 1/16 s, the last equal to the first): legs
/// swing +-0.45 rad about X in opposite phase with the knee bending up to 0.6 rad as each
/// leg passes forward, the left arm swings against the left leg (+-0.35 rad), the lantern
/// arm less (+-0.15 rad), elbows slightly bent, and the hips bob down 4 cm twice a cycle.
fn warden_walk() -> AnimationData {
    const KEYS: usize = 16;
    let times: Vec<f32> = (0..=KEYS).map(|k| k as f32 / KEYS as f32).collect();
    // Phase of key k; k % KEYS makes the last key exactly the first.
    let phase = |k: usize| std::f64::consts::TAU * (k % KEYS) as f64 / KEYS as f64;
    let knee = |phase: f64| {
        let swing = 0.5 * (1.0 + phase.cos());
        0.05 + 0.55 * swing * swing
    };
    let x = Vec3::X;
    let linear = Interpolation::Linear;
    let hips_rest = WARDEN_BIND[HIPS].1;
    let bob = ChannelData {
        node: HIPS,
        property: AnimatedProperty::Translation,
        interpolation: linear,
        times: times.clone(),
        values: (0..=KEYS)
            .flat_map(|k| {
                let drop = 0.02 * (1.0 - (2.0 * phase(k)).cos());
                [hips_rest.x, hips_rest.y - drop as f32, hips_rest.z]
            })
            .collect(),
    };
    AnimationData {
        name: "walk".into(),
        channels: vec![
            bob,
            rotation_channel(UPPER_LEG_L, linear, &times, x, |k| -0.45 * phase(k).sin()),
            rotation_channel(LOWER_LEG_L, linear, &times, x, |k| knee(phase(k))),
            rotation_channel(UPPER_LEG_R, linear, &times, x, |k| 0.45 * phase(k).sin()),
            rotation_channel(LOWER_LEG_R, linear, &times, x, |k| {
                knee(phase(k) + std::f64::consts::PI)
            }),
            rotation_channel(UPPER_ARM_L, linear, &times, x, |k| 0.35 * phase(k).sin()),
            rotation_channel(LOWER_ARM_L, linear, &times, x, |k| {
                -0.2 - 0.1 * phase(k).sin()
            }),
            rotation_channel(UPPER_ARM_R, linear, &times, x, |k| -0.15 * phase(k).sin()),
            rotation_channel(LOWER_ARM_R, linear, &times, x, |k| {
                -0.35 - 0.05 * phase(k).sin()
            }),
        ],
    }
}

/// `idle`: a 2 s loop, 9 CUBICSPLINE keys (every 0.25 s, the last equal to the first) with
/// the exact derivative as both tangents: the spine sways 0.04 rad about Z and the head
/// turns 0.2 rad about Y, both sinusoids of period 2 s (phases chosen so no tangent is 0).
fn warden_idle() -> AnimationData {
    const KEYS: usize = 8;
    const PERIOD: f64 = 2.0;
    let times: Vec<f32> = (0..=KEYS).map(|k| k as f32 * 0.25).collect();
    // (joint, axis, amplitude, phase): angle(t) = amplitude * sin(2 pi t / PERIOD + phase).
    let sways = [
        (SPINE, Vec3::Z, 0.04, std::f64::consts::FRAC_PI_4),
        (HEAD, Vec3::Y, 0.2, 1.0),
    ];
    let channels = sways
        .into_iter()
        .map(|(joint, axis, amplitude, phase)| {
            let values = (0..=KEYS)
                .flat_map(|k| {
                    let t = PERIOD * (k % KEYS) as f64 / KEYS as f64;
                    let omega = std::f64::consts::TAU / PERIOD;
                    let angle = amplitude * (omega * t + phase).sin();
                    let rate = amplitude * omega * (omega * t + phase).cos();
                    // d/dt (axis sin(a/2), cos(a/2)) = a'/2 (axis cos(a/2), -sin(a/2)).
                    let (sin, cos) = (0.5 * angle).sin_cos();
                    let tangent = [
                        (f64::from(axis.x) * 0.5 * rate * cos) as f32,
                        (f64::from(axis.y) * 0.5 * rate * cos) as f32,
                        (f64::from(axis.z) * 0.5 * rate * cos) as f32,
                        (-0.5 * rate * sin) as f32,
                    ];
                    [tangent, axis_angle(axis, angle), tangent].concat()
                })
                .collect();
            ChannelData {
                node: joint,
                property: AnimatedProperty::Rotation,
                interpolation: Interpolation::CubicSpline,
                times: times.clone(),
                values,
            }
        })
        .collect();
    AnimationData {
        name: "idle".into(),
        channels,
    }
}

/// `alert`: 0.6 s, STEP: the head snaps left (0.7 rad about Y), right (-0.7), a little left
/// (0.35) and back to the front at 0, 0.15, 0.3, 0.45 and 0.6 s, while the lantern arm
/// snaps up to 1.1 rad forward at 0.15 s and holds it (a one-shot clip, not a loop).
fn warden_alert() -> AnimationData {
    let step = Interpolation::Step;
    let head_times = [0.0, 0.15, 0.3, 0.45, 0.6];
    let head_angles = [0.0, 0.7, -0.7, 0.35, 0.0];
    let arm_times = [0.0, 0.15, 0.6];
    let arm_angles = [0.0, -1.1, -1.1];
    AnimationData {
        name: "alert".into(),
        channels: vec![
            rotation_channel(HEAD, step, &head_times, Vec3::Y, |k| head_angles[k]),
            rotation_channel(UPPER_ARM_R, step, &arm_times, Vec3::X, |k| arm_angles[k]),
        ],
    }
}

/// The warden, Gloam's enemy: a skinned humanoid guard 1.8 m tall standing on y = 0 and
/// facing +Z, carrying a lantern in its right hand, with the clips `walk`, `idle` and
/// `alert`. `detail` (>= 1) scales the tessellation: 4 + 4 x detail segments around each
/// part and rings 1 / (8 x detail) m apart (detail 3, the shipped asset, gives a few
/// thousand triangles; the count grows with detail^2).
///
/// Nodes 0..11 are the joints ([`WARDEN_JOINTS`], hips the root and the skeleton), node 11
/// shows the body mesh (`cloak`) and node 12 the lantern mesh (`lantern glow`, emissive),
/// both roots with the identity transform and skinned by skin 0.
pub fn warden_document(detail: u32) -> anyhow::Result<GltfDocument> {
    ensure!(
        (1..=1000).contains(&detail),
        "warden detail must lie in 1..=1000 (got {detail})"
    );
    let world = warden_bind_world();
    let height_of = |joint: usize| world[joint].translation.y;
    let segments = 4 + 4 * detail;
    let spacing = 1.0 / (8.0 * detail as f32);

    let mut body = MeshData::new("warden", 0);
    for part in &WARDEN_PARTS {
        let seam_heights: Vec<f32> = part
            .seams
            .iter()
            .map(|&(joint, _)| height_of(joint))
            .collect();
        push_body_part(&mut body, part, &seam_heights, segments, spacing)?;
    }
    // Feet (pointing forward, +Z) and a hood brim over the face: boxes bound to one bone.
    for (x, bone) in [(0.1, LOWER_LEG_L), (-0.1, LOWER_LEG_R)] {
        push_rigid_box(
            &mut body,
            Vec3::new(x - 0.045, 0.0, -0.06),
            Vec3::new(x + 0.045, 0.07, 0.16),
            bone,
        );
    }
    push_rigid_box(
        &mut body,
        Vec3::new(-0.07, 1.69, 0.08),
        Vec3::new(0.07, 1.72, 0.15),
        HEAD,
    );
    let mut lantern = MeshData::new("lantern", 1);
    push_rigid_box(
        &mut lantern,
        Vec3::new(-0.31, 0.58, -0.06),
        Vec3::new(-0.19, 0.72, 0.06),
        LOWER_ARM_R,
    );

    let mut nodes: Vec<NodeData> = WARDEN_JOINTS
        .iter()
        .zip(&WARDEN_BIND)
        .map(|(&name, &(_, translation))| NodeData {
            translation,
            ..NodeData::named(name)
        })
        .collect();
    for (joint, &(parent, _)) in WARDEN_BIND.iter().enumerate() {
        if let Some(parent) = parent {
            nodes[parent].children.push(joint);
        }
    }
    for (mesh, name) in [(0, "warden"), (1, "lantern")] {
        nodes.push(NodeData {
            skin: Some(0),
            ..NodeData::with_mesh(name, mesh)
        });
    }
    let mut document = GltfDocument {
        meshes: vec![body, lantern],
        materials: vec![
            MaterialData {
                roughness: 0.7,
                ..MaterialData::lambertian("cloak", Vec3::new(0.08, 0.08, 0.1))
            },
            MaterialData {
                emissive: Vec3::new(6.0, 4.0, 1.5),
                ..MaterialData::lambertian("lantern glow", Vec3::new(0.9, 0.8, 0.6))
            },
        ],
        nodes,
        roots: vec![HIPS, WARDEN_JOINTS.len(), WARDEN_JOINTS.len() + 1],
        skins: vec![SkinData {
            name: "warden".into(),
            joints: (0..WARDEN_JOINTS.len()).collect(),
            inverse_bind_matrices: world.iter().map(|w| Mat4::from(w.inverse())).collect(),
            skeleton: Some(HIPS),
        }],
        animations: vec![warden_walk(), warden_idle(), warden_alert()],
        ..GltfDocument::default()
    };
    dress(&mut document, &[Some(Surface::Cloth), None])?;
    Ok(document)
}

/// Writes a warden (as [`warden_document`]) whose detail is raised until it has at least
/// `triangles` triangles, for skinning benchmarks; returns the triangle count (under about
/// twice the request once that exceeds the shipped asset's).
pub fn write_skinned_stress(path: &Path, triangles: usize) -> anyhow::Result<usize> {
    ensure!(
        triangles <= 50_000_000,
        "{triangles} triangles is too many for a skinned stress mesh (50 million at most)"
    );
    // The count grows with detail^2: start from the estimate, then step up.
    let base = warden_document(1)?.triangle_count();
    let mut detail = ((triangles as f64 / base as f64).sqrt().floor() as u32).max(1);
    let document = loop {
        let document = warden_document(detail)?;
        if document.triangle_count() >= triangles {
            break document;
        }
        detail += 1;
    };
    write_gltf(&document, path)?;
    Ok(document.triangle_count())
}

// ---- the banner: a morphing cloth ---------------------------------------------------------

/// Columns and rows of quads in the banner grid.
const BANNER_CELLS: (usize, usize) = (16, 32);

/// The banner's morph displacement at grid coordinates (u across, v down from the top
/// edge, both 0..1): `billow` pushes the lower cloth out from the wall (+Z, up to 0.15 m
/// at the bottom centre), `sway` swings the bottom sideways (+X, 0.12 m) with a ripple.
/// The top edge (v = 0) never moves.
fn banner_displacement(target: usize, u: f64, v: f64) -> Vec3 {
    use std::f64::consts::PI;
    match target {
        0 => Vec3::new(
            0.0,
            0.0,
            (0.15 * v * v * (0.6 + 0.4 * (PI * u).sin())) as f32,
        ),
        _ => Vec3::new(
            (0.12 * v * v) as f32,
            0.0,
            (0.05 * v * (2.0 * PI * u).sin()) as f32,
        ),
    }
}

/// Normals of a (columns + 1) x (rows + 1) grid of points, row-major from the top-left,
/// by central differences (one-sided at the edges): (right - left) x (up - down).
fn grid_normals(points: &[Vec3], columns: usize, rows: usize) -> Vec<Vec3> {
    let at = |column: usize, row: usize| points[row * (columns + 1) + column];
    let mut normals = Vec::with_capacity(points.len());
    for row in 0..=rows {
        for column in 0..=columns {
            let across = at((column + 1).min(columns), row) - at(column.saturating_sub(1), row);
            let up = at(column, row.saturating_sub(1)) - at(column, (row + 1).min(rows));
            normals.push(across.cross(up).normalize());
        }
    }
    normals
}

/// A 1 x 2 m cloth banner hanging from its top edge (y = 3, x -0.5..0.5) in the z = 0
/// plane, front facing +Z, with the morph targets `billow` and `sway` (position and
/// normal deltas) and the looping clip `wind`.
fn banner() -> anyhow::Result<GltfDocument> {
    let (columns, rows) = BANNER_CELLS;
    let mut mesh = MeshData::new("banner", 0);
    for row in 0..=rows {
        for column in 0..=columns {
            let uv = Vec2::new(column as f32 / columns as f32, row as f32 / rows as f32);
            mesh.positions
                .push(Vec3::new(uv.x - 0.5, 3.0 - 2.0 * uv.y, 0.0));
            // In metres, as every kit UV is (`dress` scales them to the cloth's period).
            mesh.uvs.push(Vec2::new(uv.x, 2.0 * uv.y));
        }
    }
    mesh.normals = grid_normals(&mesh.positions, columns, rows);
    let vertex = |column: usize, row: usize| (row * (columns + 1) + column) as u32;
    for row in 0..rows {
        for column in 0..columns {
            // Counter-clockwise seen from the front (+Z); rows run downwards.
            let (top_left, top_right) = (vertex(column, row), vertex(column + 1, row));
            let (bottom_left, bottom_right) =
                (vertex(column, row + 1), vertex(column + 1, row + 1));
            mesh.indices.push([bottom_left, bottom_right, top_right]);
            mesh.indices.push([bottom_left, top_right, top_left]);
        }
    }
    for (target, name) in ["billow", "sway"].into_iter().enumerate() {
        let deltas: Vec<Vec3> = (0..=rows)
            .flat_map(|row| {
                (0..=columns).map(move |column| {
                    let (u, v) = (column as f64 / columns as f64, row as f64 / rows as f64);
                    banner_displacement(target, u, v)
                })
            })
            .collect();
        let displaced: Vec<Vec3> = mesh
            .positions
            .iter()
            .zip(&deltas)
            .map(|(&p, &d)| p + d)
            .collect();
        let normals = grid_normals(&displaced, columns, rows)
            .into_iter()
            .zip(&mesh.normals)
            .map(|(displaced, &rest)| displaced - rest)
            .collect();
        mesh.morph_targets.push(MorphTargetData {
            name: name.into(),
            positions: deltas,
            normals,
        });
    }
    mesh.morph_weights = vec![0.0, 0.0];

    // `wind`: 3 s loop, 13 LINEAR keys every 0.25 s, the last equal to the first.
    const KEYS: usize = 12;
    let times: Vec<f32> = (0..=KEYS).map(|k| k as f32 * 0.25).collect();
    let values = (0..=KEYS)
        .flat_map(|k| {
            let phase = std::f64::consts::TAU * (k % KEYS) as f64 / KEYS as f64;
            let billow = 0.45 + 0.35 * (phase + 0.5).sin();
            let sway = 0.6 * (2.0 * phase).sin();
            [billow as f32, sway as f32]
        })
        .collect();
    let mut document = GltfDocument::default();
    let node = document.add_mesh_node(
        mesh,
        MaterialData {
            double_sided: true,
            ..MaterialData::lambertian("banner cloth", Vec3::new(0.35, 0.05, 0.05))
        },
    );
    document.animations.push(AnimationData {
        name: "wind".into(),
        channels: vec![ChannelData {
            node,
            property: AnimatedProperty::MorphWeights,
            interpolation: Interpolation::Linear,
            times,
            values,
        }],
    });
    dress(&mut document, &[Some(Surface::Cloth)])?;
    Ok(document)
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
            "kit/banner.glb",
            "kit/barrel.glb",
            "kit/beam.glb",
            "kit/bookcase.glb",
            "kit/bottle.glb",
            "kit/candle.glb",
            "kit/crate.glb",
            "kit/door.glb",
            "kit/floor.glb",
            "kit/gate.glb",
            "kit/hanging-lamp.glb",
            "kit/lamp-bracket.glb",
            "kit/mirror.glb",
            "kit/pillar.glb",
            "kit/rug.glb",
            "kit/shard.glb",
            "kit/shelf.glb",
            "kit/stairs.glb",
            "kit/table.glb",
            "kit/wall-doorway.glb",
            "kit/wall-window.glb",
            "kit/wall.glb",
            "kit/warden.glb",
        ];
        assert_eq!(names, expected_files);

        let warden_triangles = warden_document(WARDEN_DETAIL).unwrap().triangle_count();
        assert!(
            (2000..=6000).contains(&warden_triangles),
            "the shipped warden has {warden_triangles} triangles"
        );
        // (file, triangles, material names)
        let expectations: [(&str, usize, &[&str]); 24] = [
            (
                "kit/warden.glb",
                warden_triangles,
                &["cloak", "lantern glow"],
            ),
            ("kit/banner.glb", 2 * 16 * 32, &["banner cloth"]),
            (
                "cornell/cornell-box.gltf",
                32,
                &["white", "red", "green", "light"],
            ),
            ("kit/wall.glb", 12, &["ashlar"]),
            ("kit/floor.glb", 12, &["flagstones"]),
            ("kit/pillar.glb", 24 * 2 + 2 * 22, &["stone"]),
            ("kit/crate.glb", 12, &["wood"]),
            ("kit/shard.glb", 8, &["shard glow"]),
            ("kit/wall-doorway.glb", 6 * 12, &["ashlar", "dark wood"]),
            ("kit/wall-window.glb", 5 * 12, &["ashlar", "dark wood"]),
            ("kit/door.glb", 7 * 12, &["dark wood", "brass"]),
            ("kit/stairs.glb", 15 * 12, &["stone"]),
            (
                "kit/lamp-bracket.glb",
                11 * 12 + 6,
                &["iron", "lantern glass"],
            ),
            // Dish and candle: 2 triangles per side segment, n - 2 per cap; flame 12.
            (
                "kit/candle.glb",
                (2 * 16 + 2 * 14) + (2 * 12 + 2 * 10) + 12,
                &["brass", "wax", "candle flame"],
            ),
            ("kit/bottle.glb", 2 * (2 * 16 + 2 * 14), &["bottle green"]),
            ("kit/table.glb", 9 * 12, &["wood"]),
            // Plate, rod, roof (6), cap, base, four posts and the glass.
            (
                "kit/hanging-lamp.glb",
                9 * 12 + 6,
                &["iron", "lantern glass"],
            ),
            ("kit/beam.glb", 12, &["dark wood"]),
            // A body and two hoops, each 2 triangles a segment and 14 a cap.
            ("kit/barrel.glb", 3 * (2 * 16 + 2 * 14), &["wood", "iron"]),
            // A field and four border strips.
            ("kit/rug.glb", 5 * 12, &["rug red", "rug ochre"]),
            // Two sides, four boards and nine jars (2 triangles a segment, 10 a cap).
            ("kit/shelf.glb", 6 * 12 + 9 * 44, &["wood", "earthenware"]),
            ("kit/mirror.glb", 5 * 12, &["mirror", "dark wood"]),
            ("kit/gate.glb", 10 * (12 + 6) + 3 * 12, &["iron"]),
            // Eight carcass boxes and 64 books.
            (
                "kit/bookcase.glb",
                72 * 12,
                &[
                    "dark wood",
                    "book red",
                    "book green",
                    "book blue",
                    "book ochre",
                ],
            ),
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
        assert_eq!((image.width, image.height), (256, 256));
        assert!(floor.materials[0].normal_texture.is_some());
        assert!(floor.materials[0].metallic_roughness_texture.is_some());
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
            (Vec2::ZERO, Vec2::splat(4.0)),
            "the flagstones repeat once a metre across the 4 m top"
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

    /// The axis-aligned bounds of `meshes`' positions.
    fn bounds<'a>(meshes: impl IntoIterator<Item = &'a MeshData>) -> (Vec3, Vec3) {
        meshes
            .into_iter()
            .flat_map(|mesh| &mesh.positions)
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| {
                (lo.min(p), hi.max(p))
            })
    }

    fn assert_near(actual: (Vec3, Vec3), expected: (Vec3, Vec3), what: &str) {
        assert!(
            actual.0.abs_diff_eq(expected.0, 1e-5) && actual.1.abs_diff_eq(expected.1, 1e-5),
            "{what}: bounds {actual:?}, expected {expected:?}"
        );
    }

    #[test]
    fn kit_pieces_are_closed_solids_facing_outwards() {
        for (name, piece) in kit_pieces().unwrap() {
            let document = piece.document().unwrap();
            let triangles = document.triangle_count();
            assert!(triangles < 2000, "{name} has {triangles} triangles");
            for (index, material) in piece.materials.iter().enumerate() {
                assert!(
                    document.meshes.iter().any(|m| m.material == index),
                    "{name}: material '{}' is unused",
                    material.data.name
                );
            }
            for solid in &piece.solids {
                // Closed: each edge (by position, to 0.01 mm) is crossed once each way.
                let key = |p: Vec3| (p * 1e5).round().as_ivec3().to_array();
                let mut edges = std::collections::BTreeMap::new();
                let mut volume = 0.0;
                for triangle in &solid.indices {
                    let [a, b, c] = triangle.map(|i| solid.positions[i as usize]);
                    for (from, to) in [(a, b), (b, c), (c, a)] {
                        *edges.entry((key(from), key(to))).or_insert(0) += 1;
                        *edges.entry((key(to), key(from))).or_insert(0) -= 1;
                    }
                    volume += a.dot(b.cross(c)) / 6.0;
                    let normal = (b - a).cross(c - a);
                    for &i in triangle {
                        assert!(
                            solid.normals[i as usize].dot(normal) > 0.0,
                            "{name}/{}: a vertex normal disagrees with the winding",
                            solid.name
                        );
                    }
                }
                assert!(
                    edges.values().all(|&count| count == 0),
                    "{name}/{}: not closed",
                    solid.name
                );
                assert!(volume > 0.0, "{name}/{}: faces inwards", solid.name);
            }
        }
    }

    #[test]
    fn kit_pieces_fit_their_documented_frames() {
        let v = Vec3::new;
        let pieces: std::collections::BTreeMap<&str, Piece> =
            kit_pieces().unwrap().into_iter().collect();
        let mesh_bounds = |piece: &str, mesh: &str| {
            bounds(pieces[piece].solids.iter().filter(|s| s.name == mesh))
        };
        let whole = |piece: &str| bounds(&pieces[piece].solids);
        // No solid reaches into the open box (lo, hi) by more than rounding.
        let clear = |piece: &str, lo: Vec3, hi: Vec3| {
            for solid in &pieces[piece].solids {
                let (min, max) = bounds([solid]);
                assert!(
                    max.cmple(lo + 1e-5).any() || min.cmpge(hi - 1e-5).any(),
                    "{piece}: '{}' ({min} .. {max}) is in the way",
                    solid.name
                );
            }
        };

        let wall = (v(-2.0, 0.0, -0.1), v(2.0, 3.0, 0.1));
        assert_near(
            mesh_bounds("wall-doorway", "wall-doorway"),
            wall,
            "wall-doorway",
        );
        clear("wall-doorway", v(-0.6, 0.0, -1.0), v(0.6, 2.2, 1.0));
        assert_near(
            mesh_bounds("wall-doorway", "door frame"),
            (v(-0.7, 0.0, -0.12), v(0.7, 2.3, 0.12)),
            "door frame",
        );
        assert_near(
            mesh_bounds("wall-window", "wall-window"),
            wall,
            "wall-window",
        );
        clear("wall-window", v(-0.6, 1.0, -1.0), v(0.6, 2.0, 1.0));
        assert_eq!(mesh_bounds("wall-window", "window sill").1.y, 1.0);

        // The door fills the doorway when placed at x = -0.6.
        let leaf = mesh_bounds("door", "door");
        assert_near(leaf, (v(0.0, 0.0, -0.04), v(1.2, 2.2, 0.04)), "door");
        let (lo, hi) = mesh_bounds("door", "door handles");
        assert!(
            lo.x > 0.9 && hi.x < 1.1 && lo.y > 0.9 && hi.y < 1.1,
            "{lo} .. {hi}"
        );
        assert!(lo.z < -0.1 && hi.z > 0.1);

        // Stairs: each step's top face lies at 0.2 (i + 1) over its run.
        assert_near(
            whole("stairs"),
            (v(-0.6, 0.0, -5.0), v(0.6, 3.0, 0.0)),
            "stairs",
        );
        let stairs = pieces["stairs"].document().unwrap();
        let mesh = &stairs.meshes[0];
        for step in 0..STAIR_STEPS {
            let z = -(step as f32 + 0.5) / 3.0;
            let top = mesh
                .indices
                .iter()
                .map(|t| t.map(|i| mesh.positions[i as usize]))
                .filter(|[a, b, c]| {
                    (b - a).cross(c - a).y > 0.0
                        && a.z.min(b.z).min(c.z) <= z
                        && a.z.max(b.z).max(c.z) >= z
                })
                .map(|[a, ..]| a.y)
                .fold(f32::NEG_INFINITY, f32::max);
            assert!(
                (top - 0.2 * (step + 1) as f32).abs() < 1e-5,
                "step {step}: {top}"
            );
        }

        // The lamp: nothing behind the wall, the housing around its centre, the light
        // outside every solid.
        let (lo, hi) = whole("lamp-bracket");
        assert!(lo.z == 0.0 && hi.z <= 0.435 + 1e-6, "{lo} .. {hi}");
        let (lo, hi) = mesh_bounds("lamp-bracket", "lantern glass");
        assert!(((lo + hi) * 0.5 - LANTERN_CENTRE).length() < 0.01);
        // The housing: cap, base, posts and glass (the solids after the roof).
        assert_near(
            bounds(pieces["lamp-bracket"].solids.iter().skip(5)),
            (v(-0.08, -0.23, 0.27), v(0.08, -0.07, 0.43)),
            "lantern housing",
        );
        let (lo, hi) = whole("hanging-lamp");
        assert!(hi.y == 0.0 && lo.y > HANGING_LAMP_LIGHT.y, "{lo} .. {hi}");
        let (lo, hi) = mesh_bounds("hanging-lamp", "lantern glass");
        assert!(((lo + hi) * 0.5 - HANGING_LAMP_CENTRE).length() < 0.01);
        assert_near(
            whole("beam"),
            (v(-4.0, 0.0, -0.1), v(4.0, 0.25, 0.1)),
            "beam",
        );
        for (piece, light) in [
            ("lamp-bracket", LAMP_BRACKET_LIGHT),
            ("hanging-lamp", HANGING_LAMP_LIGHT),
            ("candle", CANDLE_LIGHT),
        ] {
            for solid in &pieces[piece].solids {
                let (min, max) = bounds([solid]);
                assert!(
                    light.cmplt(min).any() || light.cmpgt(max).any(),
                    "{piece}: the light is inside '{}'",
                    solid.name
                );
            }
        }

        let (lo, hi) = mesh_bounds("candle", "candle flame");
        assert!(((lo.y + hi.y) * 0.5 - CANDLE_FLAME_CENTRE).abs() < 1e-5);
        assert!(hi.y < CANDLE_LIGHT.y && whole("candle").0.y == 0.0);

        assert_near(
            whole("table"),
            (v(-0.8, 0.0, -0.4), v(0.8, 0.75, 0.4)),
            "table",
        );
        assert_near(
            whole("bookcase"),
            (v(-0.6, 0.0, 0.0), v(0.6, 2.0, 0.4)),
            "bookcase",
        );
        assert!(pieces["bookcase"].solids.len() > 40, "too few books");
        assert_near(
            whole("shelf"),
            (v(-0.5, 0.0, 0.0), v(0.5, 1.8, 0.35)),
            "shelf",
        );
        let jars = pieces["shelf"].solids.iter().filter(|s| s.name == "jars");
        assert!(jars.count() >= 6, "too few jars");
        assert_near(
            whole("barrel"),
            (v(-0.31, 0.0, -0.31), v(0.31, 0.9, 0.31)),
            "barrel",
        );
        assert_near(whole("rug"), (v(-1.2, 0.0, -0.8), v(1.2, 0.01, 0.8)), "rug");

        let glass = mesh_bounds("mirror", "mirror");
        assert_near(
            glass,
            (v(-0.6, 0.0, 0.0), v(0.6, 2.0, 0.03)),
            "mirror glass",
        );
        assert_near(
            whole("mirror"),
            (v(-0.66, -0.06, 0.0), v(0.66, 2.06, 0.05)),
            "mirror",
        );
        assert_near(
            whole("gate"),
            (v(-1.0, 0.0, -0.05), v(1.0, 2.4, 0.05)),
            "gate",
        );
    }

    #[test]
    fn kit_solids_face_outwards() {
        for (document, name) in [
            (wall().unwrap(), "wall"),
            (floor().unwrap(), "floor"),
            (pillar().unwrap(), "pillar"),
            (crate_box().unwrap(), "crate"),
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

    /// Signed volume enclosed by `primitive`'s triangles: positive when they face outwards.
    fn signed_volume(primitive: &crate::scene::model::Primitive) -> f32 {
        primitive
            .indices
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| primitive.positions[i as usize]);
                a.dot(b.cross(c)) / 6.0
            })
            .sum()
    }

    #[test]
    fn warden_is_a_skinned_animated_guard() {
        use crate::scene::model::{AnimatedProperty, Interpolation};
        let dir = unique_temp_dir("warden");
        let path = dir.join("warden.glb");
        write_gltf(&warden_document(WARDEN_DETAIL).unwrap(), &path).unwrap();
        let asset = import_gltf(&path).unwrap();

        // The skin: joints named in order, hips the skeleton root, inverse bind matrices
        // undoing each joint's bind-pose world transform.
        assert_eq!(asset.skins.len(), 1);
        let skin = &asset.skins[0];
        let joint_names: Vec<&str> = skin
            .joints
            .iter()
            .map(|&j| asset.nodes[j].name.as_str())
            .collect();
        assert_eq!(joint_names, WARDEN_JOINTS);
        assert_eq!(skin.skeleton, Some(skin.joints[0]));
        let mut world = vec![glam::Mat4::IDENTITY; asset.nodes.len()];
        let mut parent = vec![None; asset.nodes.len()];
        asset.visit_nodes(glam::Mat4::IDENTITY, |node, matrix| world[node] = matrix);
        for (index, node) in asset.nodes.iter().enumerate() {
            node.children.iter().for_each(|&c| parent[c] = Some(index));
        }
        for (&joint, inverse_bind) in skin.joints.iter().zip(&skin.inverse_bind_matrices) {
            assert!(
                (world[joint] * *inverse_bind).abs_diff_eq(glam::Mat4::IDENTITY, 1e-6),
                "{}: inverse bind matrix does not undo the bind pose",
                asset.nodes[joint].name
            );
        }

        // Skinned meshes hang off identity root nodes; weights are normalised, reference
        // real joints, and blend only a joint with its parent.
        let mut blended = 0;
        for node in asset.nodes.iter().filter(|n| n.mesh.is_some()) {
            assert_eq!(node.skin, Some(0), "{}", node.name);
            assert_eq!(
                node.transform.matrix(),
                glam::Mat4::IDENTITY,
                "{}",
                node.name
            );
            let primitive = &asset.meshes[node.mesh.unwrap()].primitives[0];
            let influences = &primitive.skin_influences[0];
            assert_eq!(influences.joints.len(), primitive.positions.len());
            for (joints, weights) in influences.joints.iter().zip(&influences.weights) {
                let sum: f32 = weights.iter().sum();
                assert!((sum - 1.0).abs() < 1e-6, "weights {weights:?} sum to {sum}");
                assert!(joints.iter().all(|&j| (j as usize) < skin.joints.len()));
                assert!(weights.iter().all(|&w| w >= 0.0));
                let used: Vec<usize> = (0..4)
                    .filter(|&i| weights[i] > 0.0)
                    .map(|i| skin.joints[joints[i] as usize])
                    .collect();
                match used[..] {
                    [_] => {}
                    [a, b] => {
                        assert!(
                            parent[a] == Some(b) || parent[b] == Some(a),
                            "a vertex blends unrelated joints {} and {}",
                            asset.nodes[a].name,
                            asset.nodes[b].name
                        );
                        blended += 1;
                    }
                    _ => panic!("a vertex has {} influences", used.len()),
                }
            }
            triangles_of(&asset, &asset.meshes[node.mesh.unwrap()].name);
            assert!(
                signed_volume(primitive) > 0.0,
                "{} faces inwards",
                node.name
            );
        }
        assert!(blended > 100, "only {blended} vertices blend two bones");

        // Size and facing: 1.8 m tall on y = 0, feet and hood brim towards +Z, the lantern
        // (emissive, bound to the right forearm) on the right (-X).
        let body = &asset.meshes[0].primitives[0];
        let (min, max) = body
            .positions
            .iter()
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| {
                (lo.min(p), hi.max(p))
            });
        assert!(
            min.y.abs() < 1e-6 && (max.y - 1.8).abs() < 1e-3,
            "{min} .. {max}"
        );
        assert!(
            max.z > -min.z + 0.02,
            "the warden should face +Z: {min} .. {max}"
        );
        let lantern_material = asset.material_by_name("lantern glow").unwrap();
        assert_eq!(
            asset.materials[lantern_material].emissive,
            Vec3::new(6.0, 4.0, 1.5)
        );
        let lantern = &asset.meshes[1].primitives[0];
        assert_eq!(lantern.material, Some(lantern_material));
        assert!(lantern.positions.iter().all(|p| p.x < -0.15 && p.y < 0.75));
        let right_forearm = WARDEN_JOINTS
            .iter()
            .position(|&n| n == "lower_arm.R")
            .unwrap();
        assert!(
            lantern.skin_influences[0]
                .joints
                .iter()
                .zip(&lantern.skin_influences[0].weights)
                .all(|(j, w)| j[0] as usize == right_forearm && w[0] == 1.0)
        );

        // The clips: names, interpolation, durations; the loops end where they start.
        let clips: Vec<(&str, f32)> = asset
            .animations
            .iter()
            .map(|a| (a.name.as_str(), a.duration()))
            .collect();
        assert_eq!(clips, [("walk", 1.0), ("idle", 2.0), ("alert", 0.6)]);
        for (animation, interpolation) in asset.animations.iter().zip([
            Interpolation::Linear,
            Interpolation::CubicSpline,
            Interpolation::Step,
        ]) {
            assert!(
                animation
                    .samplers
                    .iter()
                    .all(|s| s.interpolation == interpolation),
                "{}",
                animation.name
            );
            for channel in &animation.channels {
                assert!(skin.joints.contains(&channel.node), "{}", animation.name);
            }
        }
        for animation in &asset.animations[..2] {
            for sampler in &animation.samplers {
                let per_key = sampler.values.len() / sampler.times.len();
                assert_eq!(
                    sampler.values[..per_key],
                    sampler.values[sampler.values.len() - per_key..],
                    "{} does not loop",
                    animation.name
                );
            }
        }
        let walk = &asset.animations[0];
        let walk_properties: Vec<AnimatedProperty> =
            walk.channels.iter().map(|c| c.property).collect();
        assert_eq!(walk_properties[0], AnimatedProperty::Translation);
        assert_eq!(asset.nodes[walk.channels[0].node].name, "hips");
        assert!(
            walk_properties[1..]
                .iter()
                .all(|&p| p == AnimatedProperty::Rotation)
        );
        let idle = &asset.animations[1];
        let idle_joints: Vec<&str> = idle
            .channels
            .iter()
            .map(|c| asset.nodes[c.node].name.as_str())
            .collect();
        assert_eq!(idle_joints, ["spine", "head"]);
        for sampler in &idle.samplers {
            // Every key's in- and out-tangent is non-zero.
            for key in sampler.values.chunks_exact(12) {
                assert!(key[..4].iter().any(|&x| x != 0.0) && key[8..].iter().any(|&x| x != 0.0));
            }
        }
        let alert = &asset.animations[2];
        assert!(alert.channels.iter().any(
            |c| asset.nodes[c.node].name == "head" && c.property == AnimatedProperty::Rotation
        ));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn warden_parts_face_away_from_their_axes() {
        let world = warden_bind_world();
        for (index, part) in WARDEN_PARTS.iter().enumerate() {
            let seams: Vec<f32> = part
                .seams
                .iter()
                .map(|&(joint, _)| world[joint].translation.y)
                .collect();
            let mut mesh = MeshData::new("part", 0);
            push_body_part(&mut mesh, part, &seams, 12, 0.05).unwrap();
            for triangle in &mesh.indices {
                let [a, b, c] = triangle.map(|i| mesh.positions[i as usize]);
                let normal = (b - a).cross(c - a);
                let centroid = (a + b + c) / 3.0;
                let outward = centroid - Vec3::new(part.axis.x, centroid.y, part.axis.y);
                assert!(
                    normal.dot(outward) > 0.0,
                    "part {index} has an inward triangle"
                );
                for &i in triangle {
                    assert!(
                        mesh.normals[i as usize].dot(normal) > 0.0,
                        "part {index}: a vertex normal disagrees with the winding"
                    );
                }
            }
        }
    }

    #[test]
    fn banner_has_two_morph_targets_and_a_looping_wind() {
        use crate::scene::model::{AnimatedProperty, Interpolation};
        let dir = unique_temp_dir("banner");
        let path = dir.join("banner.glb");
        write_gltf(&banner().unwrap(), &path).unwrap();
        let asset = import_gltf(&path).unwrap();
        let cloth = &asset.materials[0];
        assert_eq!(
            (cloth.name.as_str(), cloth.double_sided),
            ("banner cloth", true)
        );
        // The cloth's mean colour is the banner's red: the factor times the weave's mean.
        let mean = Surface::Cloth.images().unwrap().mean_detail;
        let colour = cloth.base_color.truncate() * mean;
        assert!((colour - Vec3::new(0.35, 0.05, 0.05)).abs().max_element() < 1e-5);
        assert!(cloth.normal_texture.is_some());
        let mesh = &asset.meshes[0];
        assert_eq!(mesh.morph_weights, [0.0, 0.0]);
        let primitive = &mesh.primitives[0];
        triangles_of(&asset, "banner")
            .iter()
            .for_each(|(_, normal)| assert!(normal.z > 0.999, "the banner faces +Z"));
        let (min, max) = primitive
            .positions
            .iter()
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| {
                (lo.min(p), hi.max(p))
            });
        assert_eq!(
            (min, max),
            (Vec3::new(-0.5, 1.0, 0.0), Vec3::new(0.5, 3.0, 0.0))
        );
        assert_eq!(primitive.morph_targets.len(), 2);
        for target in &primitive.morph_targets {
            assert_eq!(target.positions.len(), primitive.positions.len());
            assert_eq!(target.normals.len(), primitive.positions.len());
            assert!(target.positions.iter().any(|d| d.length() > 0.1));
            for ((position, delta), (normal, normal_delta)) in primitive
                .positions
                .iter()
                .zip(&target.positions)
                .zip(primitive.normals.iter().zip(&target.normals))
            {
                if position.y == 3.0 {
                    assert_eq!(*delta, Vec3::ZERO, "the top edge is fixed");
                }
                // Rest normal + delta is the displaced surface's unit normal, facing out.
                let displaced = *normal + *normal_delta;
                assert!((displaced.length() - 1.0).abs() < 1e-5 && displaced.z > 0.5);
            }
        }
        // Full weights keep the vertex normals consistent with the displaced winding.
        for target in &primitive.morph_targets {
            for triangle in &primitive.indices {
                let [a, b, c] = triangle
                    .map(|i| primitive.positions[i as usize] + target.positions[i as usize]);
                let normal = (b - a).cross(c - a);
                for &i in triangle {
                    let n = primitive.normals[i as usize] + target.normals[i as usize];
                    assert!(n.dot(normal) > 0.0);
                }
            }
        }
        assert_eq!(asset.animations.len(), 1);
        let wind = &asset.animations[0];
        assert_eq!((wind.name.as_str(), wind.duration()), ("wind", 3.0));
        assert_eq!(wind.channels.len(), 1);
        assert_eq!(wind.channels[0].property, AnimatedProperty::MorphWeights);
        let sampler = &wind.samplers[wind.channels[0].sampler];
        assert_eq!(
            (sampler.interpolation, sampler.components),
            (Interpolation::Linear, 2)
        );
        let values = &sampler.values;
        assert_eq!(
            values[..2],
            values[values.len() - 2..],
            "wind does not loop"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn skinned_stress_mesh_has_at_least_the_requested_triangles() {
        let dir = unique_temp_dir("skinned-stress");
        let path = dir.join("stress.glb");
        let written = write_skinned_stress(&path, 20_000).unwrap();
        assert!((20_000..40_000).contains(&written), "{written} triangles");
        let asset = import_gltf(&path).unwrap();
        assert_eq!(asset.triangle_count(), written);
        assert_eq!(asset.skins[0].joints.len(), WARDEN_JOINTS.len());
        assert_eq!(asset.animations.len(), 3);
        std::fs::remove_dir_all(&dir).unwrap();
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
