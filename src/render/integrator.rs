//! Frame step `render`: integrators, which estimate the radiance arriving along a camera ray.
//!
//! - `path`: unidirectional path tracing with next event estimation at every non-specular
//!   vertex, multiple importance sampling (power heuristic) between light and BSDF
//!   sampling, and Russian roulette (Veach 1997; pbrt-v4's `PathIntegrator`). The
//!   real-time render's paths (`PathState::with_dominant_apart`) shade the first vertex's
//!   dominant lamp in full and keep its light apart, sampling the other lights. That light,
//!   noiseless, is what the film's filters leave as it is, so a lamp's pool stays whole and
//!   sharp under motion for one more shadow ray a pixel: in `gloam flythrough` on
//!   first-light the moving lamp's pool keeps 0.88 of its light natively and 0.83 in the
//!   player's view, against 0.54 and 0.46 with the lamp sampled like the others.
//! - `reference`: BSDF sampling only, no NEE, no MIS, no roulette. Slow and simple: every
//!   variance reduction in `path` must converge to the image this one converges to.
//!   (It cannot see punctual lights, which only light sampling can reach.)
//!
//! Both carry a ray cone along each path ([`RayCone`]) and read every texture at the level
//! of detail its footprint asks for, and both bend the shading normal by the material's
//! normal map ([`shading_frame`]).

use glam::{Vec2, Vec3, Vec3A};

use super::bsdf::Bsdf;
use super::cache::{CacheSample, CellKey, CellSizing};
use super::light::{LightReach, LightSample};
use super::material::FINEST;
use super::sampler::{PixelSampler, VertexDraws};
use super::sampling::{Frame, power_heuristic};
use super::scene::{RenderScene, SceneAlpha};
use crate::accel::{Hit, InstanceMask, Ray, SurfaceHit, TriangleSurface, approximate_log2};

/// Which integrator renders (the command line's `--integrator`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum IntegratorKind {
    /// The path tracer with next event estimation (the game's).
    Path,
    /// The unbiased reference the path tracer is checked against.
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

/// A ray cone for texture level of detail (Akenine-Moller et al. 2019, "Texture Level of
/// Detail Strategies for Real-Time Ray Tracing", Ray Tracing Gems ch. 20): the width of
/// the beam a path's ray stands for where it starts, and how fast it widens. A camera ray's
/// cone spans its pixel; at a hit, its width over the surface in UV units picks the mip
/// level (`Texture::sample`), so a texture far off is read as its mean instead of one texel
/// that changes with every frame's jitter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayCone {
    /// Metres across at the ray's origin.
    width: f32,
    /// Radians the cone widens by per metre travelled (small-angle: width grows by
    /// spread x distance).
    spread: f32,
}

/// What a rough bounce adds to a cone's spread. Past a diffuse or glossy bounce the paths
/// of neighbouring pixels part, and what the indirect light carries of a texture is its
/// mean over a wide patch: the cone opens by about a radian, so the second hit reads a
/// coarse level (which also spares the cache lines of the fine ones). A specular bounce,
/// off a flat mirror or glass, keeps the spread (the chapter's curvature term is left out:
/// the kit's mirrors and glass are flat).
const ROUGH_BOUNCE_SPREAD: f32 = 1.0;

/// The most a grazing view widens a footprint: 1 / |n . d| is held under 8 (three
/// levels), since an isotropic tap that wide would blur the across-view axis as well.
const MAX_GRAZING_STRETCH: f32 = 8.0;

impl RayCone {
    /// No cone: every texture is read at level 0 (light sampling, and tests that want
    /// the finest image).
    pub const NONE: RayCone = RayCone {
        width: 0.0,
        spread: 0.0,
    };

    /// The cone of a camera ray through one pixel of `height` rows spanning a vertical
    /// field of view with tan(fov / 2) = `tan_half_fov`: spread atan(2 tan(fov/2) / height)
    /// (the chapter's eq. 20.3), from a point.
    pub fn pixel(tan_half_fov: f32, height: u32) -> RayCone {
        RayCone {
            width: 0.0,
            spread: (2.0 * tan_half_fov / height.max(1) as f32).atan(),
        }
    }

    /// Metres across after `distance` metres.
    fn width_at(&self, distance: f32) -> f32 {
        self.width + self.spread * distance
    }

    /// log2 of the cone's width over `surface` in UV units, met `distance` metres along a
    /// ray leaving the surface along `wo`: `FINEST` for no cone or no UVs.
    fn footprint(&self, distance: f32, surface: &SurfaceHit, wo: Vec3A) -> f32 {
        let width = self.width_at(distance);
        if !(width > 0.0) {
            return FINEST;
        }
        let cosine = surface.geometric_normal.dot(wo).abs();
        let stretch = 1.0 / cosine.max(1.0 / MAX_GRAZING_STRETCH);
        approximate_log2(width * stretch) + surface.uv_density
    }

    /// `footprint` at `found`, the hit of a ray this cone stands for.
    pub fn footprint_at(&self, found: &NextHit) -> f32 {
        self.footprint(found.hit.t, &found.surface, found.wo_world)
    }

    /// The cone after a bounce at `distance`: as wide as it arrived, opened by a rough lobe.
    fn bounced(&self, distance: f32, specular: bool) -> RayCone {
        RayCone {
            width: self.width_at(distance),
            spread: self.spread + if specular { 0.0 } else { ROUGH_BOUNCE_SPREAD },
        }
    }
}

/// The local shading frame at `surface` for a ray leaving along `wo_world`, with the shading
/// normal turned to the side the ray came from (two-sided shading) and bent by `mapped`,
/// the material's normal map there (`RenderMaterial::normal_at`): the tangent is dP/du
/// made orthogonal to the interpolated normal, the bitangent normal x tangent (by the
/// triangle's handedness), as glTF's sample viewer builds them when a mesh has no
/// tangents. Returns the frame, the geometric normal on `wo`'s side, and whether that is
/// the front.
pub fn shading_frame(
    surface: &SurfaceHit,
    wo_world: Vec3A,
    mapped: Option<Vec3>,
) -> (Frame, Vec3A, bool) {
    let front = surface.geometric_normal.dot(wo_world) >= 0.0;
    let facing_normal = if front {
        surface.geometric_normal
    } else {
        -surface.geometric_normal
    };
    let mut normal = surface.shading_normal;
    if let Some(mapped) = mapped {
        // Gram-Schmidt left unnormalised: the tangent and the bitangent (normal x tangent)
        // share one length, so the normal's part is scaled up by it instead, and the one
        // normalisation at the end does for all three (two square roots and three
        // divisions fewer a vertex).
        let tangent = surface.tangent - normal * normal.dot(surface.tangent);
        let length_squared = tangent.length_squared();
        if length_squared > 0.0 {
            let bitangent = normal.cross(tangent) * surface.handedness;
            let normal_part = normal * (mapped.z * length_squared.sqrt());
            normal = (tangent * mapped.x + bitangent * mapped.y + normal_part).normalize_or(normal);
        }
    }
    let mut shading_normal = if front { normal } else { -normal };
    // Interpolated or mapped normals can tip below the horizon at grazing angles: fall
    // back to flat.
    if shading_normal.dot(wo_world) <= 0.0 {
        shading_normal = facing_normal;
    }
    (Frame::from_normal(shading_normal), facing_normal, front)
}

/// A hit resolved for shading: the surface, its material's lobe, and the frame.
struct Vertex {
    surface: SurfaceHit,
    /// `RenderMaterial::albedo_at` here.
    albedo: Vec3,
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

/// Shades `hit`: picks the material lobe, read where `cone` (the cone of the ray that found
/// it) meets the surface, and builds the local frame (`shading_frame`).
fn vertex(
    scene: &RenderScene,
    surface: SurfaceHit,
    wo_world: Vec3A,
    hit: &Hit,
    cone: &RayCone,
    u_lobe: f32,
) -> Vertex {
    let footprint = cone.footprint(hit.t, &surface, wo_world);
    let material = scene.material(hit.instance, surface.material);
    let textures = &scene.textures;
    let (base, mapped) = material.base_and_normal_at(textures, surface.uv, footprint);
    let base = base.truncate();
    let (frame, facing_normal, front) = shading_frame(&surface, wo_world, mapped);
    Vertex {
        bsdf: material.bsdf_with_base(base, textures, surface.uv, footprint, u_lobe, front),
        albedo: material.albedo_of(base),
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
    /// The cone of the ray the path traces next.
    cone: RayCone,
}

impl PathState {
    /// A path about to trace `camera_ray`, whose pixel's cone is `cone`.
    pub fn new(camera_ray: &Ray, cone: RayCone) -> PathState {
        PathState {
            radiance: Vec3::ZERO,
            beta: Vec3::ONE,
            specular_bounce: true,
            previous_bsdf_pdf: 0.0,
            previous_position: camera_ray.origin,
            depth: 0,
            dominant_apart: false,
            dominant_light: Vec3::ZERO,
            cone,
        }
    }

    /// The ray cone's footprint (`RayCone::footprint`) at `found`, the hit of the ray
    /// the path traced last.
    pub fn footprint(&self, found: &NextHit) -> f32 {
        self.cone.footprint_at(found)
    }

    /// A path about to trace `camera_ray` whose first vertex's brightest lamp is shaded in
    /// full and kept apart in `dominant_light`: radiance + dominant_light estimates what
    /// `new`'s radiance does. A lamp's direct light is then free of the one-in-N light
    /// pick's noise, sharp where a filter would blur it (the real-time film leaves it out
    /// of its filters), for one shadow ray more at the first vertex.
    pub fn with_dominant_apart(camera_ray: &Ray, cone: RayCone) -> PathState {
        PathState {
            dominant_apart: true,
            ..PathState::new(camera_ray, cone)
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
    /// The vertex's albedo (`RenderMaterial::albedo_at` at the cone's footprint), when it
    /// was shaded: the guides' demodulation reads the first vertex's instead of another
    /// texture tap.
    pub albedo: Option<Vec3>,
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
    let v = vertex(scene, surface, wo_world, &hit, &state.cone, draws.lobe);
    let mut outcome = VertexOutcome {
        albedo: Some(v.albedo),
        ..VertexOutcome::default()
    };

    // 3. Next event estimation: one light sample, one shadow ray (traced by the caller).
    //    Kept apart, the first vertex's brightest lamp is shaded in full, with a shadow
    //    ray of its own, and the sample picks among the other lights.
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
    state.cone = state.cone.bounced(hit.t, sample.specular);

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
        albedo: material.albedo_at(&scene.textures, found.surface.uv, state.footprint(found)),
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
    mut cone: RayCone,
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
        let v = vertex(scene, surface, wo_world, &hit, &cone, sampler.next_1d());
        let u_choice = sampler.next_1d();
        let u_direction = sampler.next_2d();
        let Some(sample) = v.bsdf.sample(v.wo, u_choice, u_direction) else {
            break;
        };
        beta *= sample.f * (sample.wi.z.abs() / sample.pdf);
        if !beta.is_finite() || beta == Vec3::ZERO {
            break;
        }
        cone = cone.bounced(hit.t, sample.specular);
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A flat surface facing +Z whose u runs along +X: glTF's normal-map convention
    /// (x along +u, y along -v, that is "up" in the texture) bends the shading normal
    /// towards +X for x > 0 and, where the bitangent runs along -v (handedness +1, here
    /// +Y), towards +Y for y > 0; a mirrored layout (handedness -1) turns y the other way.
    #[test]
    fn normal_maps_bend_the_shading_normal_in_gltfs_convention() {
        let surface = |handedness: f32| SurfaceHit {
            position: Vec3A::ZERO,
            geometric_normal: Vec3A::Z,
            shading_normal: Vec3A::Z,
            uv: Vec2::ZERO,
            material: 0,
            tangent: Vec3A::new(2.0, 0.0, 0.3),
            handedness,
            uv_density: 0.0,
        };
        let (s, c) = (0.5f32, 0.75f32.sqrt());
        let wo = Vec3A::new(0.0, 0.0, 1.0);
        let bent = |handedness: f32, mapped: Vec3| {
            shading_frame(&surface(handedness), wo, Some(mapped))
                .0
                .normal
        };
        let close = |a: Vec3A, b: Vec3A| (a - b).length() < 1e-5;
        assert!(close(
            bent(1.0, Vec3::new(s, 0.0, c)),
            Vec3A::new(s, 0.0, c)
        ));
        assert!(close(
            bent(1.0, Vec3::new(0.0, s, c)),
            Vec3A::new(0.0, s, c)
        ));
        assert!(close(
            bent(-1.0, Vec3::new(0.0, s, c)),
            Vec3A::new(0.0, -s, c)
        ));
        // A short filtered normal is normalised; no map leaves the normal as it is.
        assert!(close(bent(1.0, Vec3::new(0.0, 0.0, 0.3)), Vec3A::Z));
        assert!(close(
            shading_frame(&surface(1.0), wo, None).0.normal,
            Vec3A::Z
        ));
        // Seen from behind, the bent normal turns with the surface.
        let (frame, facing, front) = shading_frame(
            &surface(1.0),
            Vec3A::new(0.0, 0.0, -1.0),
            Some(Vec3::new(s, 0.0, c)),
        );
        assert!(!front && facing == -Vec3A::Z);
        assert!(close(frame.normal, -Vec3A::new(s, 0.0, c)));
    }

    /// A camera ray's cone spans its pixel, and widens by a radian at a rough bounce but
    /// not at a specular one; the footprint over a surface grows with distance and at
    /// grazing angles, and a ray with no cone reads level 0.
    #[test]
    fn ray_cones_widen_with_distance_slant_and_rough_bounces() {
        let cone = RayCone::pixel(1.0, 100);
        assert!((cone.spread - 0.02f32.atan()).abs() < 1e-7);
        let surface = SurfaceHit {
            position: Vec3A::ZERO,
            geometric_normal: Vec3A::Z,
            shading_normal: Vec3A::Z,
            uv: Vec2::ZERO,
            material: 0,
            tangent: Vec3A::X,
            handedness: 1.0,
            uv_density: 0.0,
        };
        let head_on = cone.footprint(10.0, &surface, Vec3A::Z);
        let farther = cone.footprint(20.0, &surface, Vec3A::Z);
        assert!(
            (farther - head_on - 1.0).abs() < 0.1,
            "twice as far, a level up"
        );
        let slanted = cone.footprint(10.0, &surface, Vec3A::new(0.0, 0.866, 0.5));
        assert!(
            (slanted - head_on - 1.0).abs() < 0.1,
            "at 60 degrees, a level up"
        );
        assert_eq!(RayCone::NONE.footprint(10.0, &surface, Vec3A::Z), FINEST);
        assert_eq!(cone.bounced(10.0, true).spread, cone.spread);
        assert_eq!(
            cone.bounced(10.0, false).spread,
            cone.spread + ROUGH_BOUNCE_SPREAD
        );
        assert!((cone.bounced(10.0, true).width - cone.spread * 10.0).abs() < 1e-6);
    }
}
