//! accel against brute force: every query on random instanced scenes (rotated, non-uniformly
//! scaled and mirrored instances; degenerate and huge triangles; axis-parallel rays; rays
//! leaving surfaces) must find what testing every triangle of every instance finds, before
//! and after refitting deforming meshes.
//!
//! Brute force moves the ray into each instance's space exactly as accel does and runs the
//! same triangle test, so closest-hit distances must agree bit for bit: any difference is a
//! traversal bug, not rounding. A separate check compares with world-space triangles under a
//! loose tolerance to cover the transforms themselves.

use glam::{Affine3A, Quat, Vec2, Vec3, Vec3A};
use gloam::accel::{
    AccelScene, Blas, BlasKind, Hit, Instance, InstanceMask, Kernels, MeshGeometry, Mobility,
    Opaque, Ray, RefitOutcome, Traversal,
};
use obvhs::ray::Ray as ObvhsRay;
use obvhs::rt_triangle::RtTriangle;

/// Every way rays go through: wide TLAS and BLASes with each kernel set, and obvhs's BVH2s.
const TRAVERSALS: [Traversal; 3] = [
    Traversal::Wide(Kernels::Best),
    Traversal::Wide(Kernels::Portable),
    Traversal::Bvh2,
];

/// A small deterministic generator (SplitMix64), so failures reproduce from the seed.
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    fn unit(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }
    fn range(&mut self, low: f32, high: f32) -> f32 {
        low + (high - low) * self.unit()
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }
    fn vec3(&mut self, low: f32, high: f32) -> Vec3 {
        Vec3::new(
            self.range(low, high),
            self.range(low, high),
            self.range(low, high),
        )
    }
    fn direction(&mut self) -> Vec3 {
        loop {
            let v = self.vec3(-1.0, 1.0);
            if v.length_squared() > 1e-4 && v.length_squared() <= 1.0 {
                return v.normalize();
            }
        }
    }
}

/// A triangle soup in the unit cube with some degenerate and some huge triangles.
fn random_mesh(rng: &mut Rng, triangles: usize) -> MeshGeometry {
    let mut geometry = MeshGeometry::default();
    for t in 0..triangles {
        let centre = rng.vec3(-1.0, 1.0);
        let size = if rng.unit() < 0.05 { 4.0 } else { 0.3 };
        let mut corners = [
            centre + rng.vec3(-size, size),
            centre + rng.vec3(-size, size),
            centre + rng.vec3(-size, size),
        ];
        match rng.below(20) {
            0 => corners[1] = corners[0], // two equal vertices
            1 => corners[2] = corners[0] + (corners[1] - corners[0]) * 0.5, // collinear
            _ => {}
        }
        let base = geometry.positions.len() as u32;
        geometry.positions.extend(corners);
        geometry.triangles.push([base, base + 1, base + 2]);
        geometry.materials.push(t as u32 % 3);
    }
    geometry
}

fn random_transform(rng: &mut Rng) -> Affine3A {
    let mut scale = rng.vec3(0.3, 2.5);
    if rng.unit() < 0.3 {
        scale.x = -scale.x; // mirrored
    }
    let rotation = Quat::from_axis_angle(rng.direction(), rng.range(0.0, std::f32::consts::TAU));
    Affine3A::from_scale_rotation_translation(scale, rotation, rng.vec3(-6.0, 6.0))
}

fn random_scene(seed: u64, kind: BlasKind) -> AccelScene {
    let mut rng = Rng(seed);
    let blases: Vec<Blas> = (0..4)
        .map(|_| {
            let triangles = 40 + rng.below(200);
            Blas::build(random_mesh(&mut rng, triangles), kind)
        })
        .collect();
    let instances = (0..30)
        .map(|i| {
            let mask = InstanceMask(1 << rng.below(3));
            Instance::new(
                rng.below(blases.len()) as u32,
                random_transform(&mut rng),
                mask,
                1000 + i,
            )
        })
        .collect();
    AccelScene::new(blases, instances)
}

fn object_ray(instance: &Instance, ray: &Ray) -> ObvhsRay {
    let to_object = instance.object_from_world();
    ObvhsRay::new(
        to_object.transform_point3a(ray.origin),
        to_object.transform_vector3a(ray.direction),
        ray.t_min,
        ray.t_max,
    )
}

/// Every hit (t, instance, triangle) of `ray` on instances in `mask`, by testing all. An
/// instance in a static batch is tested as the batch holds it: its triangles carried into
/// world space, against the world ray.
fn brute_hits(scene: &AccelScene, ray: &Ray, mask: InstanceMask) -> Vec<(f32, u32, u32)> {
    let mut hits = Vec::new();
    for (index, instance) in scene.instances().iter().enumerate() {
        if !instance.mask.intersects(mask) {
            continue;
        }
        let batched = scene.is_batched(index as u32);
        let local = if batched {
            ObvhsRay::new(ray.origin, ray.direction, ray.t_min, ray.t_max)
        } else {
            object_ray(instance, ray)
        };
        let geometry = &scene.blases[instance.blas as usize].geometry;
        for triangle in 0..geometry.triangles.len() {
            let [a, b, c] = if batched {
                geometry.triangles[triangle].map(|i| {
                    Vec3A::from(
                        instance
                            .world_from_object()
                            .transform_point3(geometry.positions[i as usize]),
                    )
                })
            } else {
                geometry.triangle_vertices(triangle)
            };
            let t = RtTriangle::new(a, b, c).intersect(&local);
            if t.is_finite() {
                hits.push((t, index as u32, triangle as u32));
            }
        }
    }
    hits
}

fn assert_matches_brute_force(scene: &AccelScene, ray: &Ray, mask: InstanceMask, context: &str) {
    let hits = brute_hits(scene, ray, mask);
    let found = scene.intersect(ray, mask, &Opaque);
    let nearest = hits.iter().map(|h| h.0).fold(f32::INFINITY, f32::min);
    match found {
        None => assert!(
            hits.is_empty(),
            "{context}: accel missed, brute force hit at t={nearest} ({ray:?})"
        ),
        Some(Hit {
            t,
            instance,
            primitive,
            barycentrics,
        }) => {
            assert_eq!(t, nearest, "{context}: closest t differs ({ray:?})");
            assert!(
                hits.iter()
                    .any(|&(ht, hi, hp)| ht == t && hi == instance && hp == primitive),
                "{context}: reported (instance {instance}, triangle {primitive}) is not a hit at t={t}"
            );
            assert!(
                barycentrics.is_finite() && t.is_finite(),
                "{context}: NaN in hit"
            );
        }
    }
    assert_eq!(
        scene.occluded(ray, mask, &Opaque),
        !hits.is_empty(),
        "{context}: occluded disagrees ({ray:?})"
    );
}

/// Random rays through the scene, plus axis-parallel ones.
/// 300 `test_rays` from `Rng(seed)`, numbered, each with one of three instance masks in turn
/// (all instances, mask 1, masks 2 and 4).
fn masked_test_rays(seed: u64) -> impl Iterator<Item = (usize, Ray, InstanceMask)> {
    let masks = [InstanceMask::ALL, InstanceMask(1), InstanceMask(2 | 4)];
    test_rays(&mut Rng(seed), 300)
        .into_iter()
        .enumerate()
        .map(move |(i, ray)| (i, ray, masks[i % 3]))
}

fn test_rays(rng: &mut Rng, count: usize) -> Vec<Ray> {
    let mut rays = Vec::with_capacity(count);
    for i in 0..count {
        let origin = Vec3A::from(rng.vec3(-12.0, 12.0));
        let direction = if i % 5 == 0 {
            let mut axis = Vec3A::ZERO;
            axis[rng.below(3)] = if rng.unit() < 0.5 { 1.0 } else { -1.0 };
            axis
        } else {
            // Aim near the scene so most rays hit something.
            (Vec3A::from(rng.vec3(-5.0, 5.0)) - origin).normalize()
        };
        let mut ray = Ray::new(origin, direction);
        if i % 7 == 0 {
            ray.t_max = rng.range(1.0, 20.0); // segments, as shadow rays are
        }
        rays.push(ray);
    }
    rays
}

#[test]
fn closest_and_any_hit_match_brute_force() {
    for traversal in TRAVERSALS {
        for seed in 0..6 {
            let mut scene = random_scene(seed, BlasKind::Static);
            scene.set_traversal(traversal);
            for (i, ray, mask) in masked_test_rays(seed + 100) {
                let context = format!("{traversal:?} seed {seed} ray {i}");
                assert_matches_brute_force(&scene, &ray, mask, &context);
            }
        }
    }
}

/// `random_scene` with two instances in three `Mobility::Static`: batched, one batch per
/// mask.
fn random_batched_scene(seed: u64) -> AccelScene {
    let scene = random_scene(seed, BlasKind::Static);
    let instances = scene
        .instances()
        .iter()
        .enumerate()
        .map(|(index, instance)| {
            let mobility = if index % 3 == 0 {
                Mobility::Movable
            } else {
                Mobility::Static
            };
            instance.clone().with_mobility(mobility)
        })
        .collect();
    AccelScene::new(scene.blases, instances)
}

#[test]
fn static_batches_find_exactly_their_members_hits() {
    for traversal in TRAVERSALS {
        for seed in 0..4 {
            let mut scene = random_batched_scene(seed);
            assert_eq!(scene.batched_instance_count(), 20, "seed {seed}");
            scene.set_traversal(traversal);
            for (i, ray, mask) in masked_test_rays(seed + 200) {
                let context = format!("batched, {traversal:?} seed {seed} ray {i}");
                assert_matches_brute_force(&scene, &ray, mask, &context);
                // The hit names the member's own triangle: its surface lies on the ray.
                if let Some(hit) = scene.intersect(&ray, mask, &Opaque) {
                    let surface = scene.surface(&hit);
                    assert!(
                        (surface.position - ray.at(hit.t)).length() <= 1e-3 * (1.0 + hit.t),
                        "{context}: surface off the ray"
                    );
                }
            }
        }
    }
}

#[test]
fn moving_a_batched_instance_dissolves_its_batch() {
    let mut scene = random_batched_scene(5);
    let member = (0..30).find(|&i| scene.is_batched(i)).unwrap();
    let mask = scene.instances()[member as usize].mask;
    let moved = scene.instances()[member as usize].world_from_object()
        * Affine3A::from_translation(Vec3::new(0.5, -1.0, 2.0));
    scene.instances_mut()[member as usize].set_transform(moved);
    scene.rebuild_tlas();
    // Its batch (its mask's) is gone; the other masks' batches stay.
    for (index, instance) in scene.instances().iter().enumerate() {
        let same_batch = instance.mask == mask && instance.mobility == Mobility::Static;
        assert_eq!(
            scene.is_batched(index as u32),
            !same_batch && index % 3 != 0
        );
    }
    let mut rng = Rng(77);
    for (i, ray) in test_rays(&mut rng, 300).iter().enumerate() {
        assert_matches_brute_force(
            &scene,
            ray,
            InstanceMask::ALL,
            &format!("dissolved, ray {i}"),
        );
    }
    // Batching again takes the member where it now is.
    scene.rebatch();
    assert_eq!(scene.batched_instance_count(), 20);
    for (i, ray) in test_rays(&mut rng, 300).iter().enumerate() {
        assert_matches_brute_force(
            &scene,
            ray,
            InstanceMask::ALL,
            &format!("rebatched, ray {i}"),
        );
    }
}

#[test]
fn only_static_opaque_rigid_instances_are_batched() {
    let mut rng = Rng(9);
    let opaque = random_mesh(&mut rng, 50);
    let mut alpha_tested = random_mesh(&mut rng, 50);
    alpha_tested.uvs = vec![Vec2::ZERO; alpha_tested.positions.len()];
    alpha_tested.alpha_tested = vec![true; alpha_tested.triangles.len()];
    let blases = vec![
        Blas::build(opaque.clone(), BlasKind::Static),
        Blas::build(alpha_tested, BlasKind::Static),
        Blas::build(opaque, BlasKind::Deforming),
    ];
    let placed = |blas: u32, x: f32, mobility: Mobility| {
        Instance::new(
            blas,
            Affine3A::from_translation(Vec3::new(x, 0.0, 0.0)),
            InstanceMask::ALL,
            0,
        )
        .with_mobility(mobility)
    };
    let scene = AccelScene::new(
        blases,
        vec![
            placed(0, 0.0, Mobility::Static),
            placed(0, 3.0, Mobility::Static),
            placed(0, 6.0, Mobility::Movable),
            placed(1, 9.0, Mobility::Static),
            placed(1, 12.0, Mobility::Static),
            placed(2, 15.0, Mobility::Static),
        ],
    );
    let batched: Vec<bool> = (0..6).map(|i| scene.is_batched(i)).collect();
    assert_eq!(batched, [true, true, false, false, false, false]);
}

/// Bundles of rays as the renderer groups them, and worse: a pinhole's rays through a
/// narrow patch (one octant) or a wide one (straddling axes, so packets split by octant);
/// segments from nearby points to one target (shadow rays); rays leaving surfaces towards
/// one point; incoherent and axis-parallel rays mixed in; and sizes that are not a whole
/// packet (100 = 64 + 36) or smaller than a shared walk takes (3).
fn coherent_bundles(scene: &AccelScene, rng: &mut Rng) -> Vec<Vec<Ray>> {
    let mut bundles = Vec::new();
    for kind in 0..8 {
        let count = [64, 100, 3, 64, 64][kind % 5];
        let origin = Vec3A::from(rng.vec3(-12.0, 12.0));
        let target = Vec3A::from(rng.vec3(-4.0, 4.0));
        let spread = [0.04, 0.8][kind % 2];
        let forward = (target - origin).normalize();
        let side = forward.any_orthonormal_vector();
        let up = forward.cross(side);
        let rays: Vec<Ray> = (0..count)
            .map(|i| {
                let (x, y) = ((i % 16) as f32 / 16.0 - 0.5, (i / 16) as f32 / 4.0 - 0.5);
                match kind % 4 {
                    // Camera rays through a 16 x 4 grid.
                    0 | 1 => Ray::new(origin, (forward + (side * x + up * y) * spread).normalize()),
                    // Shadow-like segments: a patch of origins, one target.
                    2 => {
                        let from = target + forward * -6.0 + (side * x + up * y) * (spread * 4.0);
                        let mut ray = Ray::new(from, target - from);
                        ray.t_max = 0.999;
                        ray
                    }
                    // Incoherent, some axis-parallel.
                    _ => test_rays(rng, 1)[0],
                }
            })
            .collect();
        bundles.push(rays);
    }
    // Copies of one ray: the packet's intervals are exact, so its node test is as tight as
    // a single ray's (any less conservative packet test fails here).
    bundles.extend(test_rays(rng, 60).into_iter().map(|ray| vec![ray; 8]));
    // Rays leaving surfaces towards one point (next event estimation's shadow rays).
    let light = Vec3A::from(rng.vec3(-8.0, 8.0));
    let mut spawned = Vec::new();
    while spawned.len() < 64 {
        let ray = test_rays(rng, 1)[0];
        if let Some(hit) = scene.intersect(&ray, InstanceMask::ALL, &Opaque) {
            let surface = scene.surface(&hit);
            spawned.push(Ray::spawn_to(
                surface.position,
                surface.geometric_normal,
                light,
            ));
        } else if rng.unit() < 0.05 {
            spawned.push(Ray::spawn_to(ray.origin, Vec3A::Y, light));
        }
    }
    bundles.push(spawned);
    bundles
}

#[test]
fn packets_find_exactly_what_single_rays_find() {
    // Every traversal (the BVH2 one falls back to single rays), random instanced scenes
    // with a third of the instances untransformed (their packets are not re-made in object
    // space) and the rest rotated, scaled and mirrored (they are).
    for traversal in TRAVERSALS {
        for seed in 0..6 {
            let mut scene = random_scene(seed + 20, BlasKind::Static);
            for (i, instance) in scene.instances_mut().iter_mut().enumerate() {
                if i % 3 == 0 {
                    instance.set_transform(Affine3A::IDENTITY);
                }
            }
            // Seeds 2-3: two instances in three in static batches; 4-5: every instance in
            // one batch, the TLAS's sole entry.
            if seed >= 2 {
                let instances = scene
                    .instances()
                    .iter()
                    .enumerate()
                    .map(|(i, instance)| {
                        let mut instance = instance.clone().with_mobility(Mobility::Static);
                        if seed >= 4 {
                            instance.mask = InstanceMask::ALL;
                        } else if i % 3 == 1 {
                            instance.mobility = Mobility::Movable;
                        }
                        instance
                    })
                    .collect();
                scene = AccelScene::new(scene.blases, instances);
                assert!(scene.batched_instance_count() >= 20);
            }
            scene.set_traversal(traversal);
            let mut rng = Rng(seed + 300);
            let mut hits_found = 0;
            for (b, bundle) in coherent_bundles(&scene, &mut rng).iter().enumerate() {
                let mask = [InstanceMask::ALL, InstanceMask(1 | 2), InstanceMask(4)][b % 3];
                let mut hits = vec![None; bundle.len()];
                let mut occluded = vec![false; bundle.len()];
                let mut streamed = vec![true; bundle.len()];
                scene.intersect_coherent(bundle, mask, &Opaque, &mut hits);
                scene.occluded_coherent(bundle, mask, &Opaque, &mut occluded);
                scene.occluded_stream(bundle, mask, &Opaque, &mut streamed);
                assert_eq!(streamed, occluded, "{traversal:?} seed {seed} bundle {b}");
                for (i, ray) in bundle.iter().enumerate() {
                    let context = format!("{traversal:?} seed {seed} bundle {b} ray {i}");
                    assert_eq!(
                        hits[i],
                        scene.intersect(ray, mask, &Opaque),
                        "{context}: packet and single ray differ ({ray:?})"
                    );
                    assert_eq!(
                        occluded[i],
                        scene.occluded(ray, mask, &Opaque),
                        "{context}: packet and single ray disagree on occlusion ({ray:?})"
                    );
                    assert_matches_brute_force(&scene, ray, mask, &context);
                    hits_found += hits[i].is_some() as usize;
                }
            }
            assert!(hits_found > 100, "too few hits to compare: {hits_found}");
        }
    }
}

#[test]
fn shadow_streams_find_exactly_what_single_rays_find() {
    // A BLAS large enough to be walked in the stream (12,000 triangles fill at least 1,500
    // blocks of 416 bytes, over `STREAMED_TREE_BYTES`' 512 KB) under small ones tested
    // inline, instanced untransformed and transformed, in every traversal.
    for traversal in TRAVERSALS {
        let mut rng = Rng(77);
        let mut blases = vec![Blas::build(random_mesh(&mut rng, 12_000), BlasKind::Static)];
        blases.extend((0..3).map(|_| Blas::build(random_mesh(&mut rng, 60), BlasKind::Static)));
        let instances = (0..12)
            .map(|i| {
                let transform = if i % 8 == 0 {
                    Affine3A::IDENTITY
                } else {
                    random_transform(&mut rng)
                };
                let mask = InstanceMask(1 << (i % 3));
                Instance::new((i % 4) as u32, transform, mask, i as u64)
            })
            .collect();
        let mut scene = AccelScene::new(blases, instances);
        scene.set_traversal(traversal);
        for seed in 0..3 {
            let rays = test_rays(&mut Rng(seed + 500), 700);
            for mask in [InstanceMask::ALL, InstanceMask(1), InstanceMask(2 | 4)] {
                let mut streamed = vec![true; rays.len()];
                scene.occluded_stream(&rays, mask, &Opaque, &mut streamed);
                let single: Vec<bool> = rays
                    .iter()
                    .map(|ray| scene.occluded(ray, mask, &Opaque))
                    .collect();
                assert_eq!(streamed, single, "{traversal:?} seed {seed} mask {mask:?}");
                let blocked = single.iter().filter(|&&b| b).count();
                assert!(
                    blocked > 50 && blocked < rays.len() - 50,
                    "too one-sided to compare: {blocked} of {} blocked",
                    rays.len()
                );
            }
        }
    }
}

#[test]
fn hits_agree_with_world_space_triangles() {
    let scene = random_scene(42, BlasKind::Static);
    let mut rng = Rng(7);
    let mut checked = 0;
    for ray in test_rays(&mut rng, 400) {
        let Some(hit) = scene.intersect(&ray, InstanceMask::ALL, &Opaque) else {
            continue;
        };
        let instance = &scene.instances()[hit.instance as usize];
        let geometry = &scene.blases[instance.blas as usize].geometry;
        let world = geometry
            .triangle_vertices(hit.primitive as usize)
            .map(|v| instance.world_from_object().transform_point3a(v));
        let t_world = RtTriangle::new(world[0], world[1], world[2]).intersect(&ObvhsRay::new(
            ray.origin,
            ray.direction,
            0.0,
            f32::INFINITY,
        ));
        if t_world.is_finite() {
            assert!(
                (t_world - hit.t).abs() <= 1e-3 * (1.0 + hit.t),
                "object-space t {} vs world-space t {t_world}",
                hit.t
            );
            // The surface point lies on the ray.
            let surface = scene.surface(&hit);
            assert!((surface.position - ray.at(hit.t)).length() <= 1e-3 * (1.0 + hit.t));
            checked += 1;
        }
    }
    assert!(checked > 100, "too few hits checked: {checked}");
}

#[test]
fn rays_leaving_surfaces_do_not_hit_their_own_triangle() {
    let scene = random_scene(3, BlasKind::Static);
    let mut rng = Rng(11);
    let mut spawned = 0;
    for _ in 0..500 {
        // A random point on a random triangle of a random instance.
        let index = rng.below(scene.instances().len()) as u32;
        let instance = &scene.instances()[index as usize];
        let geometry = &scene.blases[instance.blas as usize].geometry;
        let primitive = rng.below(geometry.triangles.len()) as u32;
        let [a, b, c] = geometry.triangle_vertices(primitive as usize);
        if (b - a).cross(c - a).length() < 1e-4 {
            continue; // degenerate: no surface to leave
        }
        let (mut b1, mut b2) = (rng.unit(), rng.unit());
        if b1 + b2 > 1.0 {
            (b1, b2) = (1.0 - b1, 1.0 - b2);
        }
        let surface = scene.surface(&Hit {
            t: 0.0,
            instance: index,
            primitive,
            barycentrics: Vec2::new(b1, b2),
        });
        let ray = Ray::spawn(
            surface.position,
            surface.geometric_normal,
            Vec3A::from(rng.direction()),
        );
        if let Some(hit) = scene.intersect(&ray, InstanceMask::ALL, &Opaque) {
            assert!(
                !(hit.instance == index && hit.primitive == primitive),
                "ray hit the triangle it left at t={}",
                hit.t
            );
        }
        assert_matches_brute_force(&scene, &ray, InstanceMask::ALL, "spawned ray");
        spawned += 1;
    }
    assert!(spawned > 400);
}

/// A gently waved copy of `positions` (moderate deformation, as skinning produces).
fn waved(positions: &[Vec3], phase: f32, amplitude: f32) -> Vec<Vec3> {
    positions
        .iter()
        .map(|p| {
            *p + Vec3::new(
                (p.y * 3.0 + phase).sin(),
                (p.z * 3.0 + phase).cos(),
                (p.x * 3.0 + phase).sin(),
            ) * amplitude
        })
        .collect()
}

#[test]
fn refit_keeps_queries_exact_and_matches_a_rebuild() {
    // Every tree a BLAS can trace: the wide one with each kernel set, and the BVH2.
    for traversal in TRAVERSALS {
        let mut scene = random_scene(9, BlasKind::Deforming);
        scene.set_traversal(traversal);
        let mut rng = Rng(99);
        let rays = test_rays(&mut rng, 250);
        for frame in 1..=4 {
            for blas in &mut scene.blases {
                // Waved, and carried upwards out of the box it was built in (the TLAS must
                // see the refit bounds).
                let moved: Vec<Vec3> = waved(&blas.geometry.positions, frame as f32, 0.1)
                    .into_iter()
                    .map(|p| p + Vec3::Y * 0.4)
                    .collect();
                assert_eq!(
                    blas.refit(&moved, None),
                    RefitOutcome::Refit,
                    "moderate motion should refit, not rebuild"
                );
            }
            scene.rebuild_tlas();
            // A fresh build of the same deformed meshes answers every query identically.
            let rebuilt = AccelScene::new(
                scene
                    .blases
                    .iter()
                    .map(|b| Blas::build(b.geometry.clone(), BlasKind::Deforming))
                    .collect(),
                scene.instances().to_vec(),
            );
            for (i, ray) in rays.iter().enumerate() {
                assert_matches_brute_force(
                    &scene,
                    ray,
                    InstanceMask::ALL,
                    &format!("{traversal:?} frame {frame} ray {i}"),
                );
                let (a, b) = (
                    scene.intersect(ray, InstanceMask::ALL, &Opaque),
                    rebuilt.intersect(ray, InstanceMask::ALL, &Opaque),
                );
                assert_eq!(
                    a.map(|h| h.t),
                    b.map(|h| h.t),
                    "{traversal:?}: refit and rebuild disagree on ray {i}"
                );
            }
        }
    }
}

#[test]
fn quality_decay_triggers_a_rebuild() {
    let mut rng = Rng(5);
    // A regular grid: a realistic deforming surface.
    let mut geometry = MeshGeometry::default();
    let n = 40;
    for z in 0..=n {
        for x in 0..=n {
            geometry
                .positions
                .push(Vec3::new(x as f32 / n as f32, 0.0, z as f32 / n as f32));
        }
    }
    for z in 0..n {
        for x in 0..n {
            let i = (z * (n + 1) + x) as u32;
            let row = (n + 1) as u32;
            geometry.triangles.push([i, i + row, i + 1]);
            geometry.triangles.push([i + 1, i + row, i + row + 1]);
        }
    }
    let mut blas = Blas::build(geometry, BlasKind::Deforming);
    let rest = blas.geometry.positions.clone();
    // A wave of a few percent of the size: the refit tree stays close to a fresh build.
    let gentle = waved(&rest, 0.5, 0.03);
    assert_eq!(blas.refit(&gentle, None), RefitOutcome::Refit);
    let decay = blas.quality_decay();
    let fresh = Blas::build(blas.geometry.clone(), BlasKind::Deforming);
    assert!(decay < 1.2, "gentle wave decayed the tree by {decay}x");
    assert!(
        blas.sah_cost() <= 1.2 * fresh.sah_cost(),
        "refit {} vs fresh {}",
        blas.sah_cost(),
        fresh.sah_cost()
    );
    // Scrambling the vertices (an explosion) ruins the refit tree: it must rebuild.
    let scrambled: Vec<Vec3> = rest.iter().map(|_| rng.vec3(-1.0, 1.0)).collect();
    assert_eq!(blas.refit(&scrambled, None), RefitOutcome::Rebuilt);
    assert!(
        blas.quality_decay() <= 1.0 + 1e-4,
        "a rebuilt tree is its own reference"
    );
}

#[test]
fn alpha_masked_triangles_have_holes() {
    // A unit quad at z = 0 facing +Z, UVs across it; texels with u < 0.5 are holes.
    let geometry = MeshGeometry {
        positions: vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        ],
        normals: Vec::new(),
        uvs: vec![
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(0.0, 1.0),
        ],
        triangles: vec![[0, 1, 2], [0, 2, 3]],
        materials: vec![7, 7],
        alpha_tested: vec![true, true],
    };
    let scene = AccelScene::new(
        vec![Blas::build(geometry, BlasKind::Static)],
        vec![Instance::new(0, Affine3A::IDENTITY, InstanceMask::ALL, 0)],
    );
    let holes = |material: u32, uv: Vec2| {
        assert_eq!(material, 7);
        uv.x >= 0.5
    };
    let through_hole = Ray::new(Vec3A::new(0.25, 0.5, 1.0), Vec3A::NEG_Z);
    let through_solid = Ray::new(Vec3A::new(0.75, 0.5, 1.0), Vec3A::NEG_Z);
    assert!(
        scene
            .intersect(&through_hole, InstanceMask::ALL, &holes)
            .is_none()
    );
    assert!(!scene.occluded(&through_hole, InstanceMask::ALL, &holes));
    assert!(
        scene
            .intersect(&through_solid, InstanceMask::ALL, &holes)
            .is_some()
    );
    assert!(scene.occluded(&through_solid, InstanceMask::ALL, &holes));
    // Packets take alpha-tested meshes one ray at a time, with the same holes.
    let rays = [
        through_hole,
        through_solid,
        through_hole,
        through_solid,
        through_solid,
    ];
    let mut hits = [None; 5];
    let mut occluded = [false; 5];
    scene.intersect_coherent(&rays, InstanceMask::ALL, &holes, &mut hits);
    scene.occluded_coherent(&rays, InstanceMask::ALL, &holes, &mut occluded);
    assert_eq!(hits.map(|h| h.is_some()), [false, true, false, true, true]);
    assert_eq!(occluded, [false, true, false, true, true]);
    // So do streams of shadow rays.
    let mut occluded = [false; 5];
    scene.occluded_stream(&rays, InstanceMask::ALL, &holes, &mut occluded);
    assert_eq!(occluded, [false, true, false, true, true]);
    // Without the alpha test both rays hit.
    assert!(
        scene
            .intersect(&through_hole, InstanceMask::ALL, &Opaque)
            .is_some()
    );
}

#[test]
fn normals_face_outward_under_mirroring() {
    // A closed cube with outward winding, drawn mirrored: the geometric normal at a hit
    // from outside must still face the incoming ray.
    let mut geometry = MeshGeometry::default();
    let corners: Vec<Vec3> = (0..8)
        .map(|i| {
            Vec3::new((i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32) * 2.0 - 1.0
        })
        .collect();
    geometry.positions = corners;
    // Faces as quads (outward, counter-clockwise seen from outside).
    for [a, b, c, d] in [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ] {
        geometry.triangles.push([a, b, c]);
        geometry.triangles.push([a, c, d]);
    }
    let mirrored = Affine3A::from_scale(Vec3::new(-1.0, 2.0, 1.0));
    let scene = AccelScene::new(
        vec![Blas::build(geometry, BlasKind::Static)],
        vec![Instance::new(0, mirrored, InstanceMask::ALL, 0)],
    );
    let mut rng = Rng(3);
    for _ in 0..200 {
        let origin = Vec3A::from(rng.direction() * 10.0);
        let ray = Ray::new(
            origin,
            (Vec3A::from(rng.vec3(-0.5, 0.5)) - origin).normalize(),
        );
        let hit = scene
            .intersect(&ray, InstanceMask::ALL, &Opaque)
            .expect("aimed at the cube");
        let surface = scene.surface(&hit);
        assert!(
            surface.geometric_normal.dot(ray.direction) < 0.0,
            "normal faces inward under mirroring"
        );
        assert!((surface.geometric_normal.length() - 1.0).abs() < 1e-5);
    }
}

#[test]
fn empty_and_single_instance_scenes_work() {
    let empty = AccelScene::new(Vec::new(), Vec::new());
    let ray = Ray::new(Vec3A::ZERO, Vec3A::X);
    assert!(empty.intersect(&ray, InstanceMask::ALL, &Opaque).is_none());
    assert!(!empty.occluded(&ray, InstanceMask::ALL, &Opaque));

    let mut rng = Rng(1);
    let one = AccelScene::new(
        vec![Blas::build(random_mesh(&mut rng, 50), BlasKind::Static)],
        vec![Instance::new(0, Affine3A::IDENTITY, InstanceMask::ALL, 9)],
    );
    for ray in test_rays(&mut rng, 100) {
        assert_matches_brute_force(&one, &ray, InstanceMask::ALL, "single instance");
    }
}

/// Every (instance, triangle) within `radius` of `center`, with its distance, by testing
/// every triangle of every instance in world space.
fn brute_contacts(
    scene: &AccelScene,
    center: Vec3A,
    radius: f32,
    mask: InstanceMask,
) -> Vec<(u32, u32, f32)> {
    let mut found = Vec::new();
    for (index, instance) in scene.instances().iter().enumerate() {
        if !instance.mask.intersects(mask) {
            continue;
        }
        let geometry = &scene.blases[instance.blas as usize].geometry;
        for triangle in 0..geometry.triangles.len() {
            let [a, b, c] = geometry
                .triangle_vertices(triangle)
                .map(|v| instance.world_from_object().transform_point3a(v));
            let point = gloam::accel::overlap::closest_point_on_triangle(center, a, b, c);
            let distance = (center - point).length();
            if distance < radius {
                found.push((index as u32, triangle as u32, distance));
            }
        }
    }
    found.sort_by_key(|x| (x.0, x.1));
    found
}

#[test]
fn sphere_contacts_find_exactly_the_triangles_in_reach() {
    for (seed, scene) in [
        (31, random_scene(31, BlasKind::Static)),
        (32, random_scene(32, BlasKind::Deforming)),
        (33, random_batched_scene(33)),
    ] {
        let mut rng = Rng(seed * 7);
        let mut found = Vec::new();
        let mut total = 0;
        for query in 0..300 {
            let center = Vec3A::from(rng.vec3(-8.0, 8.0));
            let radius = rng.range(0.05, 1.5);
            let mask = InstanceMask([1, 2, 4, 7][query % 4]);
            found.clear();
            scene.sphere_contacts(center, radius, mask, &mut found);
            let mut got: Vec<(u32, u32, f32)> = found
                .iter()
                .map(|c| (c.instance, c.triangle, c.distance))
                .collect();
            got.sort_by_key(|x| (x.0, x.1));
            let expected = brute_contacts(&scene, center, radius, mask);
            let key = |v: &[(u32, u32, f32)]| v.iter().map(|c| (c.0, c.1)).collect::<Vec<_>>();
            assert_eq!(key(&got), key(&expected), "seed {seed} query {query}");
            for (a, b) in got.iter().zip(&expected) {
                // Batched members are tested as the batch holds them (world space).
                assert!(
                    (a.2 - b.2).abs() < 1e-4,
                    "seed {seed}: distance {a:?} vs {b:?}"
                );
            }
            for contact in &found {
                assert!((contact.normal.length() - 1.0).abs() < 1e-4);
                assert!(
                    ((center - contact.point).length() - contact.distance).abs() < 1e-4,
                    "the contact point is `distance` from the centre"
                );
            }
            total += expected.len();
        }
        assert!(
            total > 100,
            "seed {seed}: too few contacts to compare ({total})"
        );
    }
}

#[test]
fn a_sphere_resting_on_a_floor_touches_it_from_above() {
    // A 2 x 2 floor quad at y = 0, as two triangles, and a sphere of radius 0.3 sunk 0.1.
    let floor = MeshGeometry {
        positions: vec![
            Vec3::new(-1.0, 0.0, -1.0),
            Vec3::new(1.0, 0.0, -1.0),
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(-1.0, 0.0, 1.0),
        ],
        triangles: vec![[0, 2, 1], [0, 3, 2]],
        materials: vec![0, 0],
        ..MeshGeometry::default()
    };
    let scene = AccelScene::new(
        vec![Blas::build(floor, BlasKind::Static)],
        vec![Instance::new(0, Affine3A::IDENTITY, InstanceMask::ALL, 0)],
    );
    let mut found = Vec::new();
    scene.sphere_contacts(
        Vec3A::new(0.2, 0.2, 0.1),
        0.3,
        InstanceMask::ALL,
        &mut found,
    );
    // The triangle under the centre, straight below; its neighbour by the diagonal edge.
    assert_eq!(found.len(), 2, "{found:?}");
    let nearest = found
        .iter()
        .min_by(|a, b| a.distance.total_cmp(&b.distance))
        .unwrap();
    assert!((nearest.normal - Vec3A::Y).length() < 1e-5, "{nearest:?}");
    assert!((nearest.distance - 0.2).abs() < 1e-6);
    found.clear();
    scene.sphere_contacts(
        Vec3A::new(0.0, 0.31, 0.0),
        0.3,
        InstanceMask::ALL,
        &mut found,
    );
    assert!(found.is_empty(), "out of reach");
}

/// Found by fuzzing: a pose out of f32's range reached the TLAS build as NaN boxes, which
/// it asserts against. A transform that is not finite or not invertible leaves the instance
/// where it was; one that is finite but flings a mesh past a million kilometres leaves it
/// out of the TLAS; the rest of the scene is traced as before.
#[test]
fn instances_moved_out_of_range_neither_panic_nor_disturb_the_rest() {
    let mut scene = random_scene(7, BlasKind::Static);
    let rays = test_rays(&mut Rng(3), 200);
    let before: Vec<Option<(f32, u32)>> = rays
        .iter()
        .map(|ray| {
            scene
                .intersect(ray, InstanceMask::ALL, &Opaque)
                .map(|hit| (hit.t, hit.instance))
        })
        .collect();
    let kept = scene.instances()[0].world_from_object();
    scene.instances_mut()[0].set_transform(Affine3A::from_scale(Vec3::splat(f32::NAN)));
    scene.instances_mut()[0].set_transform(Affine3A::from_scale(Vec3::ZERO));
    assert_eq!(scene.instances()[0].world_from_object(), kept);
    let flung = 1;
    // Scaled 1e30 the inverse overflows: refused like NaN. Moved 1e20 m it is invertible.
    let before_fling = scene.instances()[1].world_from_object();
    scene.instances_mut()[1].set_transform(Affine3A::from_scale(Vec3::splat(1.0e30)));
    assert_eq!(scene.instances()[1].world_from_object(), before_fling);
    scene.instances_mut()[1].set_transform(Affine3A::from_translation(Vec3::splat(1.0e20)));
    scene.rebuild_tlas();
    for (ray, before) in rays.iter().zip(before) {
        let after = scene
            .intersect(ray, InstanceMask::ALL, &Opaque)
            .map(|hit| (hit.t, hit.instance));
        assert_ne!(
            after.map(|(_, id)| id),
            Some(flung),
            "the flung instance is out"
        );
        if before.is_some_and(|(_, id)| id != flung) {
            assert_eq!(after, before, "the rest of the scene is traced as before");
        }
    }
}
