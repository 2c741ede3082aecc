//! The renderer against analytic answers and against itself.
//!
//! Scenes are written as glTF by the project's own writer and loaded the way `gloam render`
//! loads them, so the whole path (import, extract, accel, render) is under test. Every
//! statistical check uses a fixed seed and states its tolerance.

mod common;

use std::path::PathBuf;

use glam::{Quat, Vec3, Vec4};
use gloam::render::{
    Camera, HdrImage, IntegratorKind, RadianceCache, RenderScene, RenderSettings, SamplerKind,
    render, render_guided,
};
use gloam::scene::gltf_export::{
    CameraData, GltfDocument, MaterialData, MeshData, NodeData, write_gltf,
};
use gloam::scene::world::Scene;

fn load(path: &std::path::Path) -> RenderScene {
    gloam::frame::render_scene(&Scene::load(path).unwrap_or_else(|e| panic!("{e}")))
}

fn settings(
    width: u32,
    height: u32,
    spp: u32,
    integrator: IntegratorKind,
    sampler: SamplerKind,
    max_depth: u32,
) -> RenderSettings {
    RenderSettings {
        width,
        height,
        spp,
        seed: 1,
        frame: 0,
        integrator,
        sampler,
        max_depth,
    }
}

fn run(scene: &RenderScene, settings: &RenderSettings) -> HdrImage {
    let camera = Camera::new(&scene.camera, settings.width, settings.height);
    let output = render(scene, &camera, settings, &|_| {});
    assert_eq!(output.invalid_samples, 0, "NaN or infinite samples");
    output.image
}

fn emitter(name: &str, albedo: Vec3, radiance: Vec3) -> MaterialData {
    MaterialData {
        emissive: radiance,
        double_sided: true,
        ..MaterialData::lambertian(name, albedo)
    }
}

/// A camera node at `position` with `rotation`, looking down its -Z.
fn add_camera(document: &mut GltfDocument, position: Vec3, rotation: Quat, yfov_degrees: f32) {
    document.cameras.push(CameraData {
        name: "camera".into(),
        yfov: yfov_degrees.to_radians(),
        znear: 0.01,
    });
    let mut node = NodeData::named("camera");
    node.translation = position;
    node.rotation = rotation;
    node.camera = Some(document.cameras.len() - 1);
    document.nodes.push(node);
    document.roots.push(document.nodes.len() - 1);
}

/// A 20 x 20 m floor at y = 0 facing up.
fn floor() -> MeshData {
    let corners = [(-10.0, 10.0), (10.0, 10.0), (10.0, -10.0), (-10.0, -10.0)]
        .map(|(x, z)| Vec3::new(x, 0.0, z));
    MeshData::quad("floor", corners, 0)
}

fn write(name: &str, document: &GltfDocument) -> PathBuf {
    let path = common::scratch_dir(name).join(format!("{name}.glb"));
    write_gltf(document, &path).unwrap();
    path
}

/// The furnace: inside a closed box whose walls all have albedo rho and emit Le (double
/// sided), every ray sees Le + rho Le + rho^2 Le + ... = Le / (1 - rho).
fn furnace(albedo: f32, emitted: f32) -> PathBuf {
    let mut document = GltfDocument::default();
    document.add_mesh_node(
        MeshData::cuboid("walls", Vec3::splat(-1.0), Vec3::splat(1.0), 0),
        emitter("glowing white", Vec3::splat(albedo), Vec3::splat(emitted)),
    );
    add_camera(
        &mut document,
        Vec3::new(0.1, -0.2, 0.3),
        Quat::from_rotation_y(0.4),
        100.0,
    );
    write("furnace", &document)
}

#[test]
fn furnace_returns_the_analytic_radiance_with_both_integrators() {
    let (albedo, emitted) = (0.5, 1.0);
    let expected = emitted / (1.0 - albedo);
    let scene = load(&furnace(albedo, emitted));
    for (integrator, spp) in [(IntegratorKind::Path, 64), (IntegratorKind::Reference, 64)] {
        let film = run(
            &scene,
            &settings(24, 24, spp, integrator, SamplerKind::White, 64),
        );
        let mean = film.mean();
        // 36,864 paths; the per-path spread is about 1 (geometric bounce count under
        // roulette), so the mean's standard error is ~0.005: 1% is over 3 sigma.
        for channel in mean.to_array() {
            assert!(
                (channel - expected).abs() < 0.01 * expected,
                "{integrator:?}: mean {mean}, expected {expected}"
            );
        }
        // No pixel strays far: every one is the same integral.
        let worst = film
            .pixels
            .iter()
            .map(|p| (p.x - expected).abs())
            .fold(0.0, f32::max);
        assert!(
            worst < 0.35 * expected,
            "{integrator:?}: a pixel is off by {worst}"
        );
    }
}

/// Irradiance at the origin from a planar polygon of radiance Le above it, with the
/// receiver facing +Y: Lambert's formula E = Le / 2 sum_i gamma_i cos(beta_i) (Arvo 1995,
/// "Applications of Irradiance Tensors to the Simulation of Non-Lambertian Phenomena").
fn polygon_irradiance(corners: &[Vec3], radiance: f32) -> f32 {
    let mut sum = 0.0;
    for i in 0..corners.len() {
        let (a, b) = (
            corners[i].normalize(),
            corners[(i + 1) % corners.len()].normalize(),
        );
        let gamma = a.dot(b).clamp(-1.0, 1.0).acos();
        let normal = a.cross(b).normalize();
        sum += gamma * normal.dot(Vec3::Y);
    }
    radiance * 0.5 * sum.abs()
}

#[test]
fn direct_light_from_a_small_area_light_matches_lamberts_formula() {
    let (albedo, radiance, height) = (0.5f32, 10.0f32, 2.0f32);
    // A 0.6 x 0.4 m light, off-centre and tilted 20 degrees, facing down.
    let tilt = Quat::from_rotation_z(20f32.to_radians());
    let corners: Vec<Vec3> = [(-0.3, -0.2), (-0.3, 0.2), (0.3, 0.2), (0.3, -0.2)]
        .iter()
        .map(|&(x, z)| Vec3::new(0.4, height, -0.3) + tilt * Vec3::new(x, 0.0, z))
        .collect();
    let mut document = GltfDocument::default();
    document.add_mesh_node(
        floor(),
        MaterialData::lambertian("grey", Vec3::splat(albedo)),
    );
    document.add_mesh_node(
        MeshData::quad("light", [corners[0], corners[1], corners[2], corners[3]], 0),
        emitter("light", Vec3::ZERO, Vec3::splat(radiance)),
    );
    // Looking straight down at the origin through a 0.2-degree field: the pixel footprint
    // is a few millimetres, over which the irradiance is constant to 1e-4.
    add_camera(
        &mut document,
        Vec3::new(0.0, 1.0, 0.0),
        Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2),
        0.2,
    );
    let scene = load(&write("area-light", &document));
    let expected = albedo / std::f32::consts::PI * polygon_irradiance(&corners, radiance);

    let path = run(
        &scene,
        &settings(4, 4, 1024, IntegratorKind::Path, SamplerKind::Stratified, 1),
    )
    .mean();
    // 16,384 light samples of a light that subtends a small solid angle: the estimate's
    // relative standard error is below 0.2%; allow 1%.
    assert!(
        (path.x - expected).abs() < 0.01 * expected,
        "path: {} vs analytic {expected}",
        path.x
    );
    // The reference finds the light only by chance (about 3% of cosine samples): 4%.
    let reference = run(
        &scene,
        &settings(
            4,
            4,
            16384,
            IntegratorKind::Reference,
            SamplerKind::White,
            1,
        ),
    )
    .mean();
    assert!(
        (reference.x - expected).abs() < 0.04 * expected,
        "reference: {} vs analytic {expected}",
        reference.x
    );
}

/// A closed room with an area light, a mirror cube and a glass cube.
fn mirror_and_glass_room() -> PathBuf {
    let mut document = GltfDocument::default();
    document.add_mesh_node(
        MeshData::cuboid(
            "room",
            Vec3::new(-1.0, 0.0, -1.0),
            Vec3::new(1.0, 2.0, 1.0),
            0,
        ),
        MaterialData::lambertian("walls", Vec3::new(0.7, 0.6, 0.5)),
    );
    document.add_mesh_node(
        MeshData::quad(
            "light",
            [
                Vec3::new(-0.3, 1.99, -0.3),
                Vec3::new(-0.3, 1.99, 0.3),
                Vec3::new(0.3, 1.99, 0.3),
                Vec3::new(0.3, 1.99, -0.3),
            ],
            0,
        ),
        emitter("light", Vec3::ZERO, Vec3::new(12.0, 10.0, 8.0)),
    );
    document.add_mesh_node(
        MeshData::cuboid(
            "mirror",
            Vec3::new(-0.7, 0.0, -0.6),
            Vec3::new(-0.2, 0.9, -0.1),
            0,
        ),
        MaterialData {
            metallic: 1.0,
            roughness: 0.0,
            ..MaterialData::lambertian("mirror", Vec3::splat(0.9))
        },
    );
    document.add_mesh_node(
        MeshData::cuboid(
            "glass",
            Vec3::new(0.1, 0.0, -0.3),
            Vec3::new(0.6, 0.5, 0.2),
            0,
        ),
        MaterialData {
            transmission: 1.0,
            ior: 1.5,
            ..MaterialData::lambertian("glass", Vec3::ONE)
        },
    );
    document.add_mesh_node(
        MeshData::cuboid(
            "rough metal",
            Vec3::new(-0.1, 0.0, 0.3),
            Vec3::new(0.3, 0.3, 0.7),
            0,
        ),
        MaterialData {
            metallic: 1.0,
            roughness: 0.5,
            base_color: Vec4::new(0.9, 0.7, 0.4, 1.0),
            ..MaterialData::lambertian("gold", Vec3::ONE)
        },
    );
    add_camera(
        &mut document,
        Vec3::new(0.0, 1.0, 0.95),
        Quat::from_rotation_x(-0.35),
        80.0,
    );
    write("mirror-glass", &document)
}

#[test]
fn path_and_reference_agree_on_diffuse_mirror_and_glass() {
    let scene = load(&mirror_and_glass_room());
    let (width, height) = (16, 16);
    let path = run(
        &scene,
        &settings(
            width,
            height,
            512,
            IntegratorKind::Path,
            SamplerKind::BlueNoise,
            8,
        ),
    );
    let reference = run(
        &scene,
        &settings(
            width,
            height,
            8192,
            IntegratorKind::Reference,
            SamplerKind::White,
            8,
        ),
    );
    // Whole image: both estimators' standard errors are well under 0.5% here; allow 2%.
    let (a, b) = (path.mean(), reference.mean());
    assert!(
        ((a - b).abs() / b).max_element() < 0.02,
        "path {a} vs reference {b}"
    );
    // Quadrants (each holds one of the special materials): reference noise from caustics
    // through the glass is a few percent per quadrant; allow 6%.
    for (qx, qy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
        let mean_of = |film: &HdrImage| {
            let mut sum = Vec3::ZERO;
            for y in qy * height / 2..(qy + 1) * height / 2 {
                for x in qx * width / 2..(qx + 1) * width / 2 {
                    sum += film.pixel(x, y);
                }
            }
            sum.element_sum()
        };
        let (p, r) = (mean_of(&path), mean_of(&reference));
        assert!(
            (p - r).abs() < 0.06 * r,
            "quadrant ({qx}, {qy}): path {p} vs reference {r}"
        );
    }
}

#[test]
fn renders_are_identical_on_any_thread_count() {
    let scene = load(&mirror_and_glass_room());
    let settings = settings(24, 16, 4, IntegratorKind::Path, SamplerKind::BlueNoise, 6);
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(|| run(&scene, &settings));
    let two = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap()
        .install(|| run(&scene, &settings));
    assert_eq!(one, two);
    // And a different seed gives a different image.
    let mut reseeded = settings.clone();
    reseeded.seed = 2;
    assert_ne!(run(&scene, &reseeded), one);
}

/// The real-time view's frames with a radiance cache: `frames` of one sample each, and the
/// mean of each frame's image from `from` on (the cache learnt by then), with the paths
/// the cache ended.
fn cached_frames(scene: &RenderScene, frames: u32, from: u32) -> (HdrImage, Vec3, u64) {
    let settings = RenderSettings::real_time(64, 36);
    let camera = Camera::new(&scene.camera, settings.width, settings.height);
    let mut cache = RadianceCache::new();
    let (mut last, mut sum, mut ended) = (None, Vec3::ZERO, 0);
    for frame in 0..frames {
        let settings = RenderSettings {
            frame,
            ..settings.clone()
        };
        let output = render_guided(scene, &camera, &settings, Some(&cache));
        cache.learn(&output.cache_samples);
        assert_eq!(output.invalid_samples, 0, "NaN or infinite samples");
        if frame >= from {
            let pixels = &output.image.pixels;
            sum += pixels.iter().copied().sum::<Vec3>() / pixels.len() as f32;
            ended += output.rays.cache_ended;
        }
        last = Some(output.image);
    }
    (last.unwrap(), sum / (frames - from) as f32, ended)
}

#[test]
fn the_radiance_cache_keeps_the_image_and_is_the_same_on_any_thread_count() {
    let level = common::repo().join("levels/first-light.ron");
    let scene = gloam::frame::render_scene(&Scene::load(&level).unwrap());
    let on = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| cached_frames(&scene, 48, 16))
    };
    let (one, mean, ended) = on(1);
    let (two, _, _) = on(2);
    assert_eq!(
        one, two,
        "the cache learns in the same order on any thread count"
    );
    // Paths end at their second vertex once its cell has learnt (measured: 15% of all
    // paths at this size, where many bounce rays leave through the sky).
    let paths = 32 * 64 * 36;
    assert!(
        ended > paths as u64 / 10,
        "the cache ended {ended} of {paths} paths"
    );
    // Against the same frames with every path traced in full (the cache's light lags
    // and blurs over a cell, but must not lose or add light): measured 0.1% apart.
    let settings = RenderSettings::real_time(64, 36);
    let camera = Camera::new(&scene.camera, 64, 36);
    let mut full = Vec3::ZERO;
    for frame in 16..48 {
        let settings = RenderSettings {
            frame,
            ..settings.clone()
        };
        let pixels = render_guided(&scene, &camera, &settings, None).image.pixels;
        full += pixels.iter().copied().sum::<Vec3>() / pixels.len() as f32;
    }
    let full = full / 32.0;
    let apart = ((mean - full).abs() / full).max_element();
    assert!(apart < 0.02, "cached {mean} against full paths {full}");
}

/// The bounce light of lights that went out, still in the cache's frames: per frame after
/// the lights went out, the cached image's mean less the full paths', as a share of the
/// light that went (first-light, every light out after 48 frames, `relit` told or not).
fn lingering_after_the_lights_go_out(relit: bool) -> Vec<f32> {
    let level = common::repo().join("levels/first-light.ron");
    let mut scene = gloam::frame::render_scene(&Scene::load(&level).unwrap());
    let settings = |frame| RenderSettings {
        frame,
        ..RenderSettings::real_time(96, 54)
    };
    let camera = Camera::new(&scene.camera, 96, 54);
    let mean = |film: &HdrImage| film.mean().y;
    let mut cache = RadianceCache::new();
    for frame in 0..48 {
        let output = render_guided(&scene, &camera, &settings(frame), Some(&cache));
        cache.learn(&output.cache_samples);
    }
    let lit = mean(&render_guided(&scene, &camera, &settings(47), None).image);
    scene.lights = gloam::render::light::LightSet::default();
    if relit {
        cache.relit();
    }
    (48..64)
        .map(|frame| {
            let cached = render_guided(&scene, &camera, &settings(frame), Some(&cache));
            cache.learn(&cached.cache_samples);
            let full = mean(&render_guided(&scene, &camera, &settings(frame), None).image);
            (mean(&cached.image) - full) / (lit - full)
        })
        .collect()
}

#[test]
fn light_that_went_out_leaves_the_radiance_cache_within_a_few_frames() {
    let window = |lingering: &[f32]| lingering[4..12].iter().sum::<f32>() / 8.0;
    // Told (`relit`, as the film is when the light set is built anew): measured 0.0% in
    // frames 4 to 12 after; untold, each cell's running mean still held 6.9%.
    let told = window(&lingering_after_the_lights_go_out(true));
    let untold = window(&lingering_after_the_lights_go_out(false));
    assert!(told < 0.02, "{told} of the light that went out lingers");
    assert!(untold > 2.0 * told, "untold {untold}, told {told}");
}

#[test]
fn one_sample_blue_noise_error_has_less_low_frequency_power_than_white() {
    // A floor lit by a large area light: at 1 spp the error comes from the light sample
    // and the pixel jitter, both driven by the sampler under test.
    let mut document = GltfDocument::default();
    document.add_mesh_node(floor(), MaterialData::lambertian("grey", Vec3::splat(0.5)));
    document.add_mesh_node(
        MeshData::quad(
            "light",
            [
                Vec3::new(-1.0, 1.5, -1.0),
                Vec3::new(-1.0, 1.5, 1.0),
                Vec3::new(1.0, 1.5, 1.0),
                Vec3::new(1.0, 1.5, -1.0),
            ],
            0,
        ),
        emitter("light", Vec3::ZERO, Vec3::splat(5.0)),
    );
    add_camera(
        &mut document,
        Vec3::new(0.0, 1.0, 0.0),
        Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2),
        90.0,
    );
    let scene = load(&write("blue-error", &document));
    let size = 64;
    let converged = run(
        &scene,
        &settings(
            size,
            size,
            4096,
            IntegratorKind::Path,
            SamplerKind::Stratified,
            1,
        ),
    );
    let luminance = |p: Vec3| p.dot(Vec3::new(0.2126, 0.7152, 0.0722));
    // The low band: radii up to a quarter of Nyquist, averaged over 8 seeds.
    let low_band = |sampler: SamplerKind| -> f32 {
        (0..8)
            .map(|seed| {
                let mut s = settings(size, size, 1, IntegratorKind::Path, sampler, 1);
                s.seed = seed;
                let film = run(&scene, &s);
                let error: Vec<f32> = film
                    .pixels
                    .iter()
                    .zip(&converged.pixels)
                    .map(|(a, b)| luminance(*a - *b))
                    .collect();
                gloam::render::spectrum::low_frequency_power(
                    &error,
                    size as usize,
                    size as usize,
                    0.25,
                )
            })
            .sum::<f32>()
            / 8.0
    };
    let (blue, white) = (
        low_band(SamplerKind::BlueNoise),
        low_band(SamplerKind::White),
    );
    println!(
        "low-band error power: blue {blue:.3e}, white {white:.3e}, ratio {:.3}",
        blue / white
    );
    assert!(blue <= 0.5 * white, "blue {blue} vs white {white}");
}
