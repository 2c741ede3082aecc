//! Frame step `render`: integrators, which estimate the radiance arriving along a camera ray.
//!
//! - `path`: unidirectional path tracing with next event estimation at every non-specular
//!   vertex, multiple importance sampling (power heuristic) between light and BSDF
//!   sampling, and Russian roulette (Veach 1997; pbrt-v4's `PathIntegrator`). The
//!   real-time render's paths (`PathState::with_dominant_apart`) shade the first vertex's
//!   dominant lamp in full and keep its light apart, sampling the other lights.
//! - `reference`: BSDF sampling only, no NEE, no MIS, no roulette. Slow and simple: every
//!   variance reduction in `path` must converge to the image this one converges to.
//!   (It cannot see punctual lights, which only light sampling can reach.)

use glam::{Vec2, Vec3, Vec3A};

use super::bsdf::Bsdf;
use super::cache::{CacheSample, CellKey, CellSizing};
use super::light::{LightReach, LightSample};
use super::sampler::{PixelSampler, VertexDraws};
use super::sampling::{Frame, power_heuristic};
use super::scene::{RenderScene, SceneAlpha};
use crate::accel::{Hit, InstanceMask, Ray, SurfaceHit, TriangleSurface};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IntegratorKind {
    Path,
    Reference,
}

/// Rays traced, for throughput figures, and the paths the radiance cache ended (which
/// are not rays: `total` leaves them out).
#[derive(Clone, Copy, Debug, Default)]
pub struct RayCounts {
    pub camera: u64,
    pub bounce: u64,
    pub shadow: u64,
    pub cache_ended: u64,
}

impl RayCounts {
    pub fn total(&self) -> u64 {
        self.camera + self.bounce + self.shadow
    }

    pub fn add(&mut self, other: &RayCounts) {
        self.camera += other.camera;
        self.bounce += other.bounce;
        self.shadow += other.shadow;
        self.cache_ended += other.cache_ended;
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
pub struct NextHit {
    pub hit: Hit,
    pub surface: SurfaceHit,
    /// Unit direction back along the ray.
    pub wo_world: Vec3A,
    pub emitted: Vec3,
}

/// Both integrators' first step at every vertex: None when the ray leaves the scene.
/// `mask` is `InstanceMask::CAMERA` for a camera ray, `InstanceMask::BOUNCE` after.
pub fn next_hit(
    scene: &RenderScene,
    ray: &Ray,
    mask: InstanceMask,
    alpha: &SceneAlpha,
) -> Option<NextHit> {
    let hit = scene.accel.intersect(ray, mask, alpha)?;
    Some(surface_at(scene, ray, hit))
}

/// `next_hit` for a tile's camera rays at once, traced in packets
/// (`AccelScene::intersect_coherent`): `found[i]` for `rays[i]`, exactly as `next_hit`
/// finds it. `hits` is scratch.
pub fn next_hits(
    scene: &RenderScene,
    rays: &[Ray],
    alpha: &SceneAlpha,
    hits: &mut Vec<Option<Hit>>,
    found: &mut Vec<Option<NextHit>>,
) {
    hits.clear();
    hits.resize(rays.len(), None);
    scene
        .accel
        .intersect_coherent(rays, InstanceMask::CAMERA, alpha, hits);
    // A tile's neighbouring camera rays mostly hit the same triangle: what its surface
    // reads and works out once per triangle is kept from one hit to the next (the primary
    // phase 12-14% faster on the three levels, one thread).
    let mut triangle: Option<TriangleSurface> = None;
    found.reserve(rays.len());
    for (ray, hit) in rays.iter().zip(hits.iter()) {
        found.push(hit.map(|hit| {
            let on = match triangle {
                Some(kept) if kept.holds(&hit) => kept,
                _ => *triangle.insert(scene.accel.triangle_surface(&hit)),
            };
            next_hit_at(scene, ray, hit, on.at(hit.barycentrics))
        }));
    }
}

/// What `ray` meets at `hit`: the surface, the way back and the light it emits that way.
pub fn surface_at(scene: &RenderScene, ray: &Ray, hit: Hit) -> NextHit {
    next_hit_at(scene, ray, hit, scene.accel.surface(&hit))
}

/// `surface_at` with the surface read.
#[inline(always)]
fn next_hit_at(scene: &RenderScene, ray: &Ray, hit: Hit, surface: SurfaceHit) -> NextHit {
    let wo_world = -ray.direction.normalize();
    let material = scene.material(hit.instance, surface.material);
    let front = surface.geometric_normal.dot(wo_world) > 0.0;
    let emitted = if material.is_emissive() && (front || material.double_sided) {
        material.emission_at(&scene.textures, surface.uv)
    } else {
        Vec3::ZERO
    };
    NextHit {
        hit,
        surface,
        wo_world,
        emitted,
    }
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

/// One path's running sums between vertices: pbrt's `PathIntegrator` locals, kept in a
/// struct so a tile can take all its paths through one vertex at a time (render/mod.rs)
/// as well as one path at a time (`continue_path`). Both orders draw each pixel's sample
/// dimensions in the same sequence, so they give bit-identical images.
#[derive(Clone, Copy, Debug)]
pub struct PathState {
    pub radiance: Vec3,
    /// Path throughput: the product of f cos / pdf (and roulette) so far.
    beta: Vec3,
    /// Whether the previous vertex was specular (or the camera): emission found by the
    /// next ray is then counted in full, since light sampling could not have produced it.
    specular_bounce: bool,
    previous_bsdf_pdf: f32,
    previous_position: Vec3A,
    /// Scattering events so far (pbrt's definition: max_depth 0 is emission only, 1 adds
    /// direct lighting).
    depth: u32,
    /// The real-time renderer's split (`PathState::with_dominant_apart`): at the first
    /// vertex the lamp that lights it most is shaded in full, its light summed here
    /// instead of in `radiance`, and next event estimation picks among the other lights.
    dominant_apart: bool,
    pub dominant_light: Vec3,
}

impl PathState {
    /// A path about to trace `camera_ray`.
    pub fn new(camera_ray: &Ray) -> PathState {
        PathState {
            radiance: Vec3::ZERO,
            beta: Vec3::ONE,
            specular_bounce: true,
            previous_bsdf_pdf: 0.0,
            previous_position: camera_ray.origin,
            depth: 0,
            dominant_apart: false,
            dominant_light: Vec3::ZERO,
        }
    }

    /// A path about to trace `camera_ray` whose first vertex's brightest lamp is shaded in
    /// full and kept apart in `dominant_light`: radiance + dominant_light estimates what
    /// `new`'s radiance does. A lamp's direct light is then free of the one-in-N light
    /// pick's noise, sharp where a filter would blur it (the real-time film leaves it out
    /// of its filters), for one shadow ray more at the first vertex.
    pub fn with_dominant_apart(camera_ray: &Ray) -> PathState {
        PathState {
            dominant_apart: true,
            ..PathState::new(camera_ray)
        }
    }
}

/// Next event estimation's shadow ray: `contribution` arrives unless something blocks it.
#[derive(Clone, Copy, Debug)]
pub struct ShadowQuery {
    pub ray: Ray,
    pub contribution: Vec3,
    /// The light arrives in `PathState::dominant_light` rather than `radiance`.
    pub dominant: bool,
}

impl ShadowQuery {
    /// Traces the shadow ray and adds the light it lets through.
    pub fn resolve(&self, scene: &RenderScene, alpha: &SceneAlpha, state: &mut PathState) {
        let blocked = scene.accel.occluded(&self.ray, InstanceMask::SHADOW, alpha);
        self.arrive(blocked, state);
    }

    /// Adds the light the shadow ray lets through, given whether something blocks it (for
    /// shadow rays traced together: `AccelScene::occluded_stream`).
    pub fn arrive(&self, blocked: bool, state: &mut PathState) {
        if blocked {
            return;
        }
        if self.dominant {
            state.dominant_light += self.contribution;
        } else {
            state.radiance += self.contribution;
        }
    }
}

/// What a vertex leaves to do: a shadow ray to trace, and the ray that continues the path.
#[derive(Clone, Copy, Debug, Default)]
pub struct VertexOutcome {
    pub shadow: Option<ShadowQuery>,
    /// The first vertex's brightest lamp, shaded in full (`PathState::with_dominant_apart`).
    pub dominant: Option<ShadowQuery>,
    pub next: Option<Ray>,
}

/// The path integrator at one vertex: `found` is what the path's last ray hit (None if it
/// left the scene). Adds emission to `state`, and returns the NEE shadow ray and the next
/// ray, using the vertex's `draws`.
pub fn path_vertex(
    scene: &RenderScene,
    state: &mut PathState,
    found: Option<&NextHit>,
    draws: &VertexDraws,
    max_depth: u32,
    counts: &mut RayCounts,
) -> VertexOutcome {
    path_vertex_inlined(
        scene,
        state,
        found,
        draws,
        LightReach::ALL,
        max_depth,
        counts,
    )
}

/// `path_vertex`, inlined into its caller: the render's first vertices, where the outcome
/// returned through memory was read back before its stores had landed, a stall a path
/// (perf); inlined there, the shade phase's p50 fell 2.60 -> 2.30 ms on first-light. The
/// bounces phase, where it was 2.6% slower inlined (one thread), calls `path_vertex`.
/// `reach`: the punctual lights that may light the vertex (`LightSet::reach`), which the
/// first vertex's pick beside the dominant lamp weighs.
#[inline(always)]
pub fn path_vertex_inlined(
    scene: &RenderScene,
    state: &mut PathState,
    found: Option<&NextHit>,
    draws: &VertexDraws,
    reach: LightReach,
    max_depth: u32,
    counts: &mut RayCounts,
) -> VertexOutcome {
    // 1. Escaping rays see the sky.
    let Some(&NextHit {
        hit,
        surface,
        wo_world,
        emitted,
    }) = found
    else {
        state.radiance += state.beta * scene.sky;
        return VertexOutcome::default();
    };

    // 2. Emission at the hit: in full after the camera or a specular bounce, else
    //    weighted against the light-sampling strategy that could also have found it.
    add_emission(scene, state, &hit, &surface, emitted);

    if state.depth == max_depth {
        return VertexOutcome::default();
    }
    state.depth += 1;
    let v = vertex(scene, surface, wo_world, hit.instance, draws.lobe);

    // 3. Next event estimation: one light sample, one shadow ray (traced by the caller).
    //    Kept apart, the first vertex's brightest lamp is shaded in full, with a shadow
    //    ray of its own, and the sample picks among the other lights.
    let mut outcome = VertexOutcome::default();
    let (u_pick, u_light) = (draws.pick, draws.light);
    let shadow_ray = |light: &LightSample, counts: &mut RayCounts, dominant: bool| {
        let wi = v.frame.to_local(light.wi);
        let f = v.bsdf.f(v.wo, wi) * wi.z.abs();
        if f.max_element() <= 0.0 || light.radiance.max_element() <= 0.0 {
            return None;
        }
        counts.shadow += 1;
        let weight = if light.is_delta {
            1.0
        } else {
            power_heuristic(light.pdf, v.bsdf.pdf(v.wo, wi))
        };
        Some(ShadowQuery {
            ray: Ray::spawn_to(v.surface.position, v.facing_normal, light.point),
            contribution: state.beta * f * light.radiance * (weight / light.pdf),
            dominant,
        })
    };
    if !v.bsdf.is_specular() {
        let emission =
            |material: u32, uv| scene.materials[material as usize].emission_at(&scene.textures, uv);
        let position = v.surface.position;
        let (dominant, sampled) = if state.dominant_apart && state.depth == 1 {
            (scene.lights).sample_beside_dominant(position, reach, u_pick, u_light, emission)
        } else {
            (
                None,
                scene.lights.sample(position, u_pick, u_light, emission),
            )
        };
        if let Some(light) = &dominant {
            outcome.dominant = shadow_ray(light, counts, true);
        }
        if let Some(light) = &sampled {
            outcome.shadow = shadow_ray(light, counts, false);
        }
    }

    // 4. Continue the path by sampling the BSDF.
    let Some(sample) = v.bsdf.sample(v.wo, draws.choice, draws.direction) else {
        return outcome;
    };
    state.beta *= sample.f * (sample.wi.z.abs() / sample.pdf);
    state.specular_bounce = sample.specular;
    state.previous_bsdf_pdf = sample.pdf;
    state.previous_position = v.surface.position;

    // 5. Russian roulette: survive with probability q, and divide by it.
    if state.depth >= ROULETTE_START {
        let q = state.beta.max_element().min(0.95);
        if draws.roulette >= q {
            return outcome;
        }
        state.beta /= q;
    }
    if !state.beta.is_finite() || state.beta == Vec3::ZERO {
        return outcome;
    }
    let wi_world = v.frame.to_world(sample.wi);
    outcome.next = Some(Ray::spawn(v.surface.position, v.facing_normal, wi_world));
    counts.bounce += 1;
    outcome
}

/// The light a path's last ray found emitted at `hit`: in full after the camera or a
/// specular bounce, else weighted against the light-sampling strategy that could also have
/// found it.
fn add_emission(
    scene: &RenderScene,
    state: &mut PathState,
    hit: &Hit,
    surface: &SurfaceHit,
    emitted: Vec3,
) {
    if emitted == Vec3::ZERO {
        return;
    }
    if state.specular_bounce {
        state.radiance += state.beta * emitted;
    } else if let Some(light) = scene.lights.triangle_light(hit.instance, hit.primitive) {
        let light_pdf = scene
            .lights
            .pdf(light, state.previous_position, surface.position);
        state.radiance +=
            state.beta * emitted * power_heuristic(state.previous_bsdf_pdf, light_pdf);
    } else {
        state.radiance += state.beta * emitted;
    }
}

/// Where a path's second vertex stands with the radiance cache (render/cache.rs): its cell,
/// and the albedo the cell's light is scaled by.
#[derive(Clone, Copy, Debug)]
pub struct CacheVertex {
    pub cell: CellKey,
    pub albedo: Vec3,
}

/// The radiance cache's view of the vertex a path's last ray found, if the cache may stand
/// in for the path from there: the path's second vertex, reached by a bounce light sampling
/// could also have taken, on a purely diffuse surface, farther from the first than the
/// cell is wide.
pub fn cache_vertex(
    scene: &RenderScene,
    state: &PathState,
    found: &NextHit,
    sizing: &CellSizing,
) -> Option<CacheVertex> {
    if state.depth != 1 || state.specular_bounce {
        return None;
    }
    let material = scene.material(found.hit.instance, found.surface.material);
    if material.metallic > 0.0 || material.transmission > 0.0 {
        return None;
    }
    let position = found.surface.position;
    let normal = found.surface.geometric_normal;
    let facing = if normal.dot(found.wo_world) >= 0.0 {
        normal
    } else {
        -normal
    };
    let (cell, side) = CellKey::at(position, facing, sizing);
    if position.distance(state.previous_position) < side {
        return None;
    }
    Some(CacheVertex {
        cell,
        albedo: material.albedo_at(&scene.textures, found.surface.uv),
    })
}

/// Ends a path at the vertex `found` with the cache's `light` there (its albedo already
/// applied) in place of everything the path would have gathered from that vertex on.
pub fn end_at_cache(scene: &RenderScene, state: &mut PathState, found: &NextHit, light: Vec3) {
    add_emission(scene, state, &found.hit, &found.surface, found.emitted);
    state.radiance += state.beta * light;
}

/// A full path's mark at its second vertex, from which `CacheMark::sample` reads what the
/// path gathered from there on, for the cache to learn.
#[derive(Clone, Copy, Debug)]
pub struct CacheMark {
    vertex: CacheVertex,
    /// Throughput on arrival, and radiance once the vertex's emission was added.
    beta: Vec3,
    radiance: Vec3,
}

impl CacheMark {
    /// Taken just before the path's second vertex is shaded (`path_vertex`).
    pub fn before(vertex: CacheVertex, state: &PathState) -> CacheMark {
        CacheMark {
            vertex,
            beta: state.beta,
            radiance: state.radiance,
        }
    }

    /// Once `path_vertex` has added the vertex's emission (and nothing after it).
    pub fn after_emission(&mut self, state: &PathState) {
        self.radiance = state.radiance;
    }

    /// What the path gathered from the vertex on (its state once it ended), over the
    /// throughput that carried it back and the vertex's albedo: the cell's light.
    pub fn sample(&self, ended: &PathState) -> CacheSample {
        let scale = self.beta * self.vertex.albedo;
        let gathered = ended.radiance - self.radiance;
        let light = Vec3::select(
            scale.cmpgt(Vec3::splat(1e-4)),
            gathered / scale.max(Vec3::splat(1e-4)),
            Vec3::ZERO,
        );
        CacheSample {
            cell: self.vertex.cell,
            light,
        }
    }
}

/// Follows a path from `ray` (already counted) to its end, one vertex at a time.
pub fn continue_path(
    scene: &RenderScene,
    alpha: &SceneAlpha,
    state: &mut PathState,
    mut ray: Ray,
    sampler: &mut PixelSampler,
    max_depth: u32,
    counts: &mut RayCounts,
) {
    let mut mask = InstanceMask::CAMERA;
    loop {
        let found = next_hit(scene, &ray, mask, alpha);
        mask = InstanceMask::BOUNCE;
        let draws = sampler.vertex_draws();
        let outcome = path_vertex(scene, state, found.as_ref(), &draws, max_depth, counts);
        for shadow in [outcome.dominant, outcome.shadow].into_iter().flatten() {
            shadow.resolve(scene, alpha, state);
        }
        match outcome.next {
            Some(next) => ray = next,
            None => break,
        }
    }
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
        }) = next_hit(
            scene,
            &ray,
            if depth == 0 {
                InstanceMask::CAMERA
            } else {
                InstanceMask::BOUNCE
            },
            &alpha,
        )
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
/// 2D lens position. A pinhole camera (`has_lens` false) reads no lens position: its
/// dimension is passed over undrawn (Vec2::ZERO stands for it), so the dimensions after it
/// are the same either way.
pub fn camera_sample(sampler: &mut PixelSampler, has_lens: bool) -> (Vec2, Vec2) {
    let jitter = sampler.next_2d();
    let lens = if has_lens {
        sampler.next_2d()
    } else {
        sampler.skip_2d();
        Vec2::ZERO
    };
    (jitter, lens)
}
