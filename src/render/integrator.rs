//! Frame step `render`: integrators, which estimate the radiance arriving along a camera ray.
//!
//! - `path`: unidirectional path tracing with next event estimation at every non-specular
//!   vertex, multiple importance sampling (power heuristic) between light and BSDF
//!   sampling, and Russian roulette (Veach 1997; pbrt-v4's `PathIntegrator`).
//! - `reference`: BSDF sampling only, no NEE, no MIS, no roulette. Slow and simple: every
//!   variance reduction in `path` must converge to the image this one converges to.
//!   (It cannot see punctual lights, which only light sampling can reach.)

use glam::{Vec2, Vec3, Vec3A};

use super::bsdf::Bsdf;
use super::sampler::PixelSampler;
use super::sampling::{Frame, power_heuristic};
use super::scene::{RenderScene, SceneAlpha};
use crate::accel::{Hit, InstanceMask, Ray, SurfaceHit};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IntegratorKind {
    Path,
    Reference,
}

/// Rays traced, for throughput figures.
#[derive(Clone, Copy, Debug, Default)]
pub struct RayCounts {
    pub camera: u64,
    pub bounce: u64,
    pub shadow: u64,
}

impl RayCounts {
    pub fn total(&self) -> u64 {
        self.camera + self.bounce + self.shadow
    }

    pub fn add(&mut self, other: &RayCounts) {
        self.camera += other.camera;
        self.bounce += other.bounce;
        self.shadow += other.shadow;
    }
}

/// Bounces after which Russian roulette may end a path.
const ROULETTE_START: u32 = 3;

/// A hit resolved for shading: the surface, its material's lobe, and the frame.
struct Vertex {
    surface: SurfaceHit,
    /// Geometric normal turned to the side `wo` is on.
    facing_normal: Vec3A,
    frame: Frame,
    bsdf: Bsdf,
    /// wo in the local frame.
    wo: Vec3A,
}

/// The next surface along a ray, and the light it emits back along the ray (zero unless
/// the material is emissive and the ray meets its emitting side).
struct NextHit {
    hit: Hit,
    surface: SurfaceHit,
    /// Unit direction back along the ray.
    wo_world: Vec3A,
    emitted: Vec3,
}

/// Both integrators' first step at every vertex: None when the ray leaves the scene.
fn next_hit(scene: &RenderScene, ray: &Ray, alpha: &SceneAlpha) -> Option<NextHit> {
    let hit = scene.accel.intersect(ray, InstanceMask::CAMERA, alpha)?;
    let surface = scene.accel.surface(&hit);
    let wo_world = -ray.direction.normalize();
    let material = scene.material(hit.instance, surface.material);
    let front = surface.geometric_normal.dot(wo_world) > 0.0;
    let emitted = if material.is_emissive() && (front || material.double_sided) {
        material.emission_at(&scene.textures, surface.uv)
    } else {
        Vec3::ZERO
    };
    Some(NextHit {
        hit,
        surface,
        wo_world,
        emitted,
    })
}

/// Shades the hit: picks the material lobe and builds the local frame, with the shading
/// normal turned to the side the ray came from (two-sided shading).
fn vertex(
    scene: &RenderScene,
    surface: SurfaceHit,
    wo_world: Vec3A,
    instance: u32,
    u_lobe: f32,
) -> Vertex {
    let material = scene.material(instance, surface.material);
    let front = surface.geometric_normal.dot(wo_world) >= 0.0;
    let facing_normal = if front {
        surface.geometric_normal
    } else {
        -surface.geometric_normal
    };
    let mut shading_normal = if front {
        surface.shading_normal
    } else {
        -surface.shading_normal
    };
    // Interpolated normals can tip below the horizon at grazing angles: fall back to flat.
    if shading_normal.dot(wo_world) <= 0.0 {
        shading_normal = facing_normal;
    }
    let frame = Frame::from_normal(shading_normal);
    Vertex {
        bsdf: material.bsdf_at(&scene.textures, surface.uv, u_lobe, front),
        wo: frame.to_local(wo_world),
        frame,
        facing_normal,
        surface,
    }
}

/// Radiance along `ray` (a camera ray) with the path integrator.
pub fn path_radiance(
    scene: &RenderScene,
    camera_ray: Ray,
    sampler: &mut PixelSampler,
    max_depth: u32,
    counts: &mut RayCounts,
) -> Vec3 {
    let alpha = scene.alpha();
    let mut radiance = Vec3::ZERO;
    let mut beta = Vec3::ONE;
    let mut ray = camera_ray;
    // Whether the previous vertex was specular (or the camera): emission found by this
    // ray is then counted in full, since light sampling could not have produced it.
    let mut specular_bounce = true;
    let mut previous_bsdf_pdf = 0.0;
    let mut previous_position = ray.origin;
    counts.camera += 1;

    // `depth` counts scattering events so far (pbrt's definition: max_depth 0 is emission
    // only, 1 adds direct lighting).
    let mut depth = 0;
    loop {
        // 1. Find the next vertex; escaping rays see the sky.
        let Some(NextHit {
            hit,
            surface,
            wo_world,
            emitted,
        }) = next_hit(scene, &ray, &alpha)
        else {
            radiance += beta * scene.sky;
            break;
        };

        // 2. Emission at the hit: in full after the camera or a specular bounce, else
        //    weighted against the light-sampling strategy that could also have found it.
        if emitted != Vec3::ZERO {
            if specular_bounce {
                radiance += beta * emitted;
            } else if let Some(light) = scene.lights.triangle_light(hit.instance, hit.primitive) {
                let light_pdf = scene.lights.pdf(light, previous_position, surface.position);
                radiance += beta * emitted * power_heuristic(previous_bsdf_pdf, light_pdf);
            } else {
                radiance += beta * emitted;
            }
        }

        if depth == max_depth {
            break;
        }
        depth += 1;
        let v = vertex(scene, surface, wo_world, hit.instance, sampler.next_1d());

        // 3. Next event estimation: one light sample, one shadow ray.
        let u_pick = sampler.next_1d();
        let u_light = sampler.next_2d();
        if !v.bsdf.is_specular()
            && let Some(light) =
                scene
                    .lights
                    .sample(v.surface.position, u_pick, u_light, |material, uv| {
                        scene.materials[material as usize].emission_at(&scene.textures, uv)
                    })
        {
            let wi = v.frame.to_local(light.wi);
            let f = v.bsdf.f(v.wo, wi) * wi.z.abs();
            if f.max_element() > 0.0 && light.radiance.max_element() > 0.0 {
                counts.shadow += 1;
                let shadow = Ray::spawn_to(v.surface.position, v.facing_normal, light.point);
                if !scene.accel.occluded(&shadow, InstanceMask::SHADOW, &alpha) {
                    let weight = if light.is_delta {
                        1.0
                    } else {
                        power_heuristic(light.pdf, v.bsdf.pdf(v.wo, wi))
                    };
                    radiance += beta * f * light.radiance * (weight / light.pdf);
                }
            }
        }

        // 4. Continue the path by sampling the BSDF.
        let u_choice = sampler.next_1d();
        let u_direction = sampler.next_2d();
        let u_roulette = sampler.next_1d();
        let Some(sample) = v.bsdf.sample(v.wo, u_choice, u_direction) else {
            break;
        };
        beta *= sample.f * (sample.wi.z.abs() / sample.pdf);
        specular_bounce = sample.specular;
        previous_bsdf_pdf = sample.pdf;
        previous_position = v.surface.position;

        // 5. Russian roulette: survive with probability q, and divide by it.
        if depth >= ROULETTE_START {
            let q = beta.max_element().min(0.95);
            if u_roulette >= q {
                break;
            }
            beta /= q;
        }
        if !beta.is_finite() || beta == Vec3::ZERO {
            break;
        }
        let wi_world = v.frame.to_world(sample.wi);
        ray = Ray::spawn(v.surface.position, v.facing_normal, wi_world);
        counts.bounce += 1;
    }
    radiance
}

/// Radiance along `ray` with the reference integrator: BSDF sampling only.
pub fn reference_radiance(
    scene: &RenderScene,
    camera_ray: Ray,
    sampler: &mut PixelSampler,
    max_depth: u32,
    counts: &mut RayCounts,
) -> Vec3 {
    let alpha = scene.alpha();
    let mut radiance = Vec3::ZERO;
    let mut beta = Vec3::ONE;
    let mut ray = camera_ray;
    counts.camera += 1;
    let mut depth = 0;
    loop {
        let Some(NextHit {
            hit,
            surface,
            wo_world,
            emitted,
        }) = next_hit(scene, &ray, &alpha)
        else {
            radiance += beta * scene.sky;
            break;
        };
        radiance += beta * emitted;
        if depth == max_depth {
            break;
        }
        depth += 1;
        let v = vertex(scene, surface, wo_world, hit.instance, sampler.next_1d());
        let u_choice = sampler.next_1d();
        let u_direction = sampler.next_2d();
        let Some(sample) = v.bsdf.sample(v.wo, u_choice, u_direction) else {
            break;
        };
        beta *= sample.f * (sample.wi.z.abs() / sample.pdf);
        if !beta.is_finite() || beta == Vec3::ZERO {
            break;
        }
        ray = Ray::spawn(
            v.surface.position,
            v.facing_normal,
            v.frame.to_world(sample.wi),
        );
        counts.bounce += 1;
    }
    radiance
}

/// The camera's sample dimensions, drawn first by every integrator: 2D pixel jitter, then
/// 2D lens position.
pub fn camera_sample(sampler: &mut PixelSampler) -> (Vec2, Vec2) {
    (sampler.next_2d(), sampler.next_2d())
}
