//! The top-level BVH over instances, rebuilt every frame, and the ray queries through it.
//!
//! Frame step `accel`, second half. The TLAS is a PLOC-built BVH2 over the instances'
//! world-space boxes (Meister & Bittner 2018); the builder, the box list and the index list
//! are kept between frames so a rebuild allocates nothing once the instance count settles.
//! Rays walk it collapsed 8 wide (`WideTlas`, rebuilt from the BVH2 each frame) with the
//! same kernels as the BLASes; `Traversal::Bvh2` walks obvhs's BVH2 instead. A TLAS of a
//! single entry (a level that is all one static batch) is not walked: single rays and
//! packets go straight to the entry, whose own tree tests the box.

use glam::{Affine3A, Mat3A, Vec2, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;
use obvhs::ploc::{PlocBuilder, PlocSearchDistance, SortPrecision};
use obvhs::ray::{Ray as ObvhsRay, RayHit};

use super::batch::{StaticBatch, batch_statics};
use super::blas::{Blas, MeshGeometry, PendingHit, Traversal, interpolate_uv};
use super::packet::{PACKET, RayPacket, first_lanes, lanes_of};
use super::stream::{Job, occluded_jobs};
use super::wide::{Kernels, Portable, RayLanes, WideBvh, WideTlas};
use super::{AlphaTest, Hit, InstanceMask, Ray, SurfaceHit, prefetch};

/// How far from the world's origin an instance's box may reach (metres) and still go into
/// the TLAS; levels span tens of metres, a million kilometres is room to spare.
const MAX_WORLD_EXTENT: f32 = 1.0e9;

/// Whether an instance may move: `Static` ones are merged into world-space batches
/// (`batch`), which is only worth it for things that never move.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Mobility {
    /// Never moves (a wall): batched at load. Moving it anyway is correct, only slower: its
    /// batch dissolves.
    Static,
    /// May move or animate.
    #[default]
    Movable,
}

/// A placed copy of a BLAS.
#[derive(Clone, Debug)]
pub struct Instance {
    /// Index into `AccelScene::blases`.
    pub blas: u32,
    world_from_object: Affine3A,
    /// Cached inverse: rays are moved into object space once per instance visited.
    object_from_world: Affine3A,
    /// Inverse transpose of the linear part, for normals.
    normal_from_object: Mat3A,
    /// World and object space coincide: the world ray is used as is.
    is_identity: bool,
    /// log2 of how much the transform scales areas, (2/3) log2 |det|: exact for a
    /// rotation and a uniform scale, the mean for a non-uniform one (which only a texture's
    /// level of detail reads, `SurfaceHit::uv_density`).
    log2_area_scale: f32,
    /// -1 where the transform mirrors (negative determinant), else 1: it turns a UV
    /// layout's handedness.
    mirror: f32,
    pub mask: InstanceMask,
    /// The caller's id for this instance (the game's ECS entity).
    pub user_id: u64,
    pub mobility: Mobility,
}

impl Instance {
    /// `world_from_object` must be invertible (non-zero scale in every axis).
    pub fn new(
        blas: u32,
        world_from_object: Affine3A,
        mask: InstanceMask,
        user_id: u64,
    ) -> Instance {
        let mut instance = Instance {
            blas,
            world_from_object,
            object_from_world: Affine3A::IDENTITY,
            normal_from_object: Mat3A::IDENTITY,
            is_identity: true,
            log2_area_scale: 0.0,
            mirror: 1.0,
            mask,
            user_id,
            mobility: Mobility::Movable,
        };
        instance.set_transform(world_from_object);
        instance
    }

    /// The same instance with `mobility` (instances start `Movable`).
    pub fn with_mobility(mut self, mobility: Mobility) -> Instance {
        self.mobility = mobility;
        self
    }

    /// Moves the instance. Rule: rays need the inverse and the TLAS build asserts every box
    /// is a number, so a transform that is not finite or not invertible (an animation
    /// scaled past f32's range, a zero scale) leaves the instance where it was.
    pub fn set_transform(&mut self, world_from_object: Affine3A) {
        let object_from_world = world_from_object.inverse();
        if !(world_from_object.is_finite()
            && object_from_world.is_finite()
            && world_from_object.matrix3.determinant() != 0.0)
        {
            return;
        }
        self.world_from_object = world_from_object;
        self.object_from_world = object_from_world;
        self.normal_from_object = self.object_from_world.matrix3.transpose();
        self.is_identity = world_from_object == Affine3A::IDENTITY;
        let determinant = world_from_object.matrix3.determinant();
        self.log2_area_scale = 2.0 / 3.0 * determinant.abs().log2();
        self.mirror = if determinant < 0.0 { -1.0 } else { 1.0 };
    }

    pub fn world_from_object(&self) -> Affine3A {
        self.world_from_object
    }

    pub fn object_from_world(&self) -> Affine3A {
        self.object_from_world
    }

    /// A world-space ray's origin and direction in this instance's object space (same t).
    #[inline]
    fn object_origin_direction(&self, world: &Ray) -> (Vec3A, Vec3A) {
        if self.is_identity {
            return (world.origin, world.direction);
        }
        (
            self.object_from_world.transform_point3a(world.origin),
            self.object_from_world.transform_vector3a(world.direction),
        )
    }

    /// A world-space ray carried into this instance's object space, ready for the wide
    /// kernels: `world` (that ray, prepared) itself for an untransformed instance, else
    /// `moved`, filled in. (Copied out for every instance, the 88-byte ray cost 8.7 ns of
    /// a 105 ns shadow ray on dream-apartment: the copy's loads wait on the stores that
    /// just wrote it.)
    #[inline]
    fn object_lanes<'a>(
        &self,
        ray: &Ray,
        world: &'a RayLanes,
        moved: &'a mut Option<RayLanes>,
    ) -> &'a RayLanes {
        if self.is_identity {
            return world;
        }
        let (origin, direction) = self.object_origin_direction(ray);
        moved.insert(RayLanes::from_parts(origin, direction, ray.t_min))
    }

    /// A world-space ray carried into this instance's object space (same t).
    #[inline]
    fn object_ray(&self, world: &ObvhsRay) -> ObvhsRay {
        if self.is_identity {
            return *world;
        }
        ObvhsRay::new(
            self.object_from_world.transform_point3a(world.origin),
            self.object_from_world.transform_vector3a(world.direction),
            world.tmin,
            world.tmax,
        )
    }
}

/// Set on a TLAS leaf's primitive index that names a static batch (`batches[index & !BATCH]`);
/// without it the index is an instance's.
const BATCH: u32 = 1 << 31;

/// BLASes, their instances and the TLAS over them: what the renderer and the game query.
pub struct AccelScene {
    pub blases: Vec<Blas>,
    instances: Vec<Instance>,
    /// Static instances merged into world-space BLASes (`batch`); the TLAS holds these in
    /// place of their members.
    batches: Vec<StaticBatch>,
    /// Per instance: is it a member of one of `batches`?
    batched: Vec<bool>,
    /// Its `primitive_indices` name instances, or batches with `BATCH` set (rewritten so
    /// after each build: a query looks up one table, as before batching).
    tlas: Bvh2,
    builder: PlocBuilder,
    /// The boxes of what the TLAS holds: unbatched instances, then batches...
    instance_boxes: Vec<Aabb>,
    /// ...and what each box stands for, as `tlas.primitive_indices` will name it.
    box_codes: Vec<u32>,
    /// `tlas` collapsed 8 wide (None: rays walk `tlas`).
    wide_tlas: Option<WideTlas>,
    /// How rays walk the TLAS (the BLASes keep their own, set with them by `set_traversal`).
    traversal: Traversal,
}

impl AccelScene {
    pub fn new(blases: Vec<Blas>, instances: Vec<Instance>) -> AccelScene {
        let mut scene = AccelScene {
            blases,
            instances,
            batches: Vec::new(),
            batched: Vec::new(),
            box_codes: Vec::new(),
            tlas: Bvh2::default(),
            builder: PlocBuilder::new(),
            instance_boxes: Vec::new(),
            wide_tlas: None,
            traversal: Traversal::Wide(Kernels::Best),
        };
        scene.rebatch();
        scene
    }

    /// Merges the static instances into batches anew (built with the static preset: about
    /// as long as building their meshes' BLASes), then rebuilds the TLAS. `new` does this
    /// at load; the editor, once an edit has settled.
    pub fn rebatch(&mut self) {
        self.batches = batch_statics(&self.blases, &self.instances);
        for batch in &mut self.batches {
            batch.blas.set_traversal(self.traversal);
        }
        self.rebuild_tlas();
    }

    /// The static batches' BLASes (`gloam raybench` traces the largest on its own).
    pub(crate) fn batch_blases(&self) -> impl Iterator<Item = &Blas> {
        self.batches.iter().map(|batch| &batch.blas)
    }

    /// Is `instance` traced through a static batch (its triangles in world space) rather
    /// than on its own?
    pub fn is_batched(&self, instance: u32) -> bool {
        self.batched
            .get(instance as usize)
            .copied()
            .unwrap_or(false)
    }

    /// Instances traced through a static batch rather than on their own.
    pub fn batched_instance_count(&self) -> usize {
        self.batched.iter().filter(|&&batched| batched).count()
    }

    /// What a TLAS leaf's primitive index names: the instance rays enter and its BLAS (for
    /// a batch, an untransformed stand-in and the batch's world-space BLAS).
    #[inline]
    fn traced(&self, code: u32) -> (&Instance, &Blas) {
        if code & BATCH == 0 {
            let instance = &self.instances[code as usize];
            (instance, &self.blases[instance.blas as usize])
        } else {
            let batch = &self.batches[(code & !BATCH) as usize];
            (&batch.instance, &batch.blas)
        }
    }

    pub fn instances(&self) -> &[Instance] {
        &self.instances
    }

    /// Change instances in place; call `rebuild_tlas` before the next query.
    pub fn instances_mut(&mut self) -> &mut [Instance] {
        &mut self.instances
    }

    /// Replaces the instance list (things spawned and despawned, a new order), then
    /// rebuilds the TLAS. A static batch stays, renumbered, while every member is still
    /// there (found by `user_id`) exactly as it was batched; the others dissolve.
    pub fn set_instances(&mut self, instances: Vec<Instance>) {
        let index_of: std::collections::HashMap<u64, u32> = instances
            .iter()
            .enumerate()
            .map(|(index, instance)| (instance.user_id, index as u32))
            .collect();
        for batch in &mut self.batches {
            batch.renumber(&index_of);
        }
        self.instances = instances;
        self.rebuild_tlas();
    }

    /// Would `rebatch` batch an instance that is traced on its own now?
    pub fn can_rebatch(&self) -> bool {
        super::batch::unbatched_candidates(&self.blases, &self.instances, &self.batched) > 0
    }

    /// Calls `visit` for every instance and static batch whose world box the TLAS finds
    /// overlapping `query` (for box queries: `overlap`).
    pub(super) fn visit_boxes<'a>(
        &'a self,
        query: &Aabb,
        mut visit: impl FnMut(super::overlap::Entry<'a>),
    ) {
        self.tlas.aabb_traverse(*query, |tlas, node| {
            let node = &tlas.nodes[node as usize];
            let first = node.first_index as usize;
            for &code in &tlas.primitive_indices[first..first + node.prim_count as usize] {
                if code & BATCH == 0 {
                    visit(super::overlap::Entry::Instance(code));
                } else {
                    let batch = &self.batches[(code & !BATCH) as usize];
                    visit(super::overlap::Entry::Batch(&batch.blas, batch));
                }
            }
            true
        });
    }

    /// Adds an instance; call `rebuild_tlas` before the next query. Returns its index.
    pub fn push_instance(&mut self, instance: Instance) -> u32 {
        debug_assert!((instance.blas as usize) < self.blases.len());
        self.instances.push(instance);
        self.instances.len() as u32 - 1
    }

    /// Triangles over all instances.
    pub fn instanced_triangle_count(&self) -> usize {
        self.instances
            .iter()
            .map(|i| self.blases[i.blas as usize].triangle_count())
            .sum()
    }

    /// World-space bounds of every instance.
    pub fn bounds(&self) -> Aabb {
        self.tlas
            .nodes
            .first()
            .map_or(Aabb::empty(), |root| *root.aabb())
    }

    /// Rebuilds the TLAS over the instances' current world boxes.
    /// Batches a member of which has changed are dissolved first (their members are traced
    /// one by one from now on).
    pub fn rebuild_tlas(&mut self) {
        // 1. Dissolve what no longer matches the instances; mark who is batched.
        let instances = &self.instances;
        self.batches.retain(|batch| batch.is_current(instances));
        self.batched.clear();
        self.batched.resize(self.instances.len(), false);
        for batch in &self.batches {
            for &(index, _) in &batch.members {
                self.batched[index as usize] = true;
            }
        }
        // 2. The boxes of what the TLAS holds and the code of each.
        self.instance_boxes.clear();
        self.box_codes.clear();
        for (index, instance) in self.instances.iter().enumerate() {
            if !self.batched[index] {
                let world_box = transform_aabb(
                    &self.blases[instance.blas as usize].bounds(),
                    &instance.world_from_object,
                );
                // Rule: PLOC asserts its boxes are numbers and sorts their centres as
                // integers: a box out of f32's comfortable range (a finite transform
                // scaling a mesh a billion kilometres wide) is left out of the TLAS.
                let reachable = |v: Vec3A| v.abs().max_element() <= MAX_WORLD_EXTENT;
                if !(reachable(world_box.min) && reachable(world_box.max)) {
                    continue;
                }
                self.instance_boxes.push(world_box);
                self.box_codes.push(index as u32);
            }
        }
        for (index, batch) in self.batches.iter().enumerate() {
            self.instance_boxes.push(batch.blas.bounds());
            self.box_codes.push(index as u32 | BATCH);
        }
        if self.instance_boxes.is_empty() {
            self.tlas = Bvh2::default();
            self.wide_tlas = None;
            return;
        }
        // 3. PLOC over the boxes (their indices as labels, as its leaves require), reusing
        //    last frame's index allocation.
        let mut indices = std::mem::take(&mut self.tlas.primitive_indices);
        indices.clear();
        indices.extend(0..self.instance_boxes.len() as u32);
        // Low search distance: 1.7x faster to build than Medium (0.095 vs 0.165 ms for
        // 1,000 instances of levels/first-light.ron, 2 threads) with ray throughput within
        // run-to-run noise (`gloam raybench levels/first-light.ron --instances 1000`).
        self.builder.build_with_bvh(
            &mut self.tlas,
            PlocSearchDistance::Low,
            &self.instance_boxes,
            indices,
            SortPrecision::U64,
            1,
        );
        // Leaves name slots of `primitive_indices`, whose entries become the codes.
        for slot in &mut self.tlas.primitive_indices {
            *slot = self.box_codes[*slot as usize];
        }
        self.wide_tlas = match self.traversal {
            Traversal::Wide(_) => {
                let mut wide = self.wide_tlas.take().unwrap_or_default();
                // A tree too deep for the wide stack keeps the BVH2 walk.
                wide.rebuild(&self.tlas).is_ok().then_some(wide)
            }
            Traversal::Bvh2 => None,
        };
    }

    /// Chooses how rays walk the TLAS and every BLAS (`gloam raybench` compares them).
    pub fn set_traversal(&mut self, traversal: Traversal) {
        self.traversal = traversal;
        for blas in &mut self.blases {
            blas.set_traversal(traversal);
        }
        for batch in &mut self.batches {
            batch.blas.set_traversal(traversal);
        }
        self.rebuild_tlas();
    }

    /// The closest hit along `ray` among instances sharing a bit with `mask`.
    pub fn intersect<A: AlphaTest>(&self, ray: &Ray, mask: InstanceMask, alpha: &A) -> Option<Hit> {
        if self.tlas.nodes.is_empty() {
            return None;
        }
        // The closest so far: (t, instance, its BLAS's pending hit). Triangle id and
        // barycentrics are worked out once, for the last one.
        let mut closest: Option<(f32, u32, PendingHit)> = None;
        if let (Some(wide), Traversal::Wide(kernels)) = (&self.wide_tlas, self.traversal) {
            // The ray is prepared once, for the TLAS and every untransformed BLAS.
            let world = RayLanes::from_parts(ray.origin, ray.direction, ray.t_min);
            let visit = |slot: usize, t_max: f32| {
                let index = self.tlas.primitive_indices[slot];
                let (instance, blas) = self.traced(index);
                if !instance.mask.intersects(mask) {
                    return None;
                }
                // t_max is the closest hit so far: the BLAS prunes against it.
                let found = match blas.packet_tree() {
                    Some((tree, kernels)) => tree
                        .intersect_lanes(
                            instance.object_lanes(ray, &world, &mut None),
                            t_max,
                            kernels,
                        )
                        .map(|(t, slot)| (t, PendingHit::Wide(slot))),
                    None => {
                        let mut object_ray = instance.object_ray(&ray.to_obvhs());
                        object_ray.tmax = t_max;
                        blas.intersect_pending(&object_ray, alpha)
                    }
                };
                match found {
                    Some((t, pending)) if t < t_max => {
                        closest = Some((t, index, pending));
                        Some(t)
                    }
                    _ => None,
                }
            };
            wide.walk(&world, ray.t_max, kernels, false, visit);
        } else {
            let mut tlas_hit = RayHit::none();
            self.tlas
                .ray_traverse(ray.to_obvhs(), &mut tlas_hit, |world_ray, id| {
                    let index = self.tlas.primitive_indices[id];
                    let (instance, blas) = self.traced(index);
                    if !instance.mask.intersects(mask) {
                        return f32::INFINITY;
                    }
                    // world_ray.tmax is the closest hit so far: the BLAS prunes against it.
                    let object_ray = instance.object_ray(world_ray);
                    match blas.intersect_pending(&object_ray, alpha) {
                        // obvhs accepts only t < tmax; keep `closest` in step with it.
                        Some((t, pending)) if t < world_ray.tmax => {
                            closest = Some((t, index, pending));
                            t
                        }
                        _ => f32::INFINITY,
                    }
                });
        }
        let (t, index, pending) = closest?;
        Some(self.finish_hit(ray, t, index, pending))
    }

    /// The `Hit` for a BLAS's pending closest hit along a world ray; `index` is the TLAS
    /// leaf's (an instance, or a batch whose triangle is mapped back to its member's).
    #[inline]
    fn finish_hit(&self, ray: &Ray, t: f32, index: u32, pending: PendingHit) -> Hit {
        let ((instance, primitive), barycentrics) = if index & BATCH == 0 {
            let instance = &self.instances[index as usize];
            let (origin, direction) = instance.object_origin_direction(ray);
            let (primitive, barycentrics) =
                self.blases[instance.blas as usize].resolve(pending, origin, direction);
            ((index, primitive), barycentrics)
        } else {
            self.batches[(index & !BATCH) as usize].resolve(pending, ray.origin, ray.direction)
        };
        Hit {
            t,
            instance,
            primitive,
            barycentrics,
        }
    }

    /// `intersect` for many rays at once, `hits[i]` for `rays[i]`, each exactly what
    /// `intersect` finds. Rays that travel together (a tile's camera rays, in rows) are
    /// traced in packets of 64 (`packet`), which share their walks through the trees.
    pub fn intersect_coherent<A: AlphaTest>(
        &self,
        rays: &[Ray],
        mask: InstanceMask,
        alpha: &A,
        hits: &mut [Option<Hit>],
    ) {
        debug_assert_eq!(rays.len(), hits.len());
        let (Some(wide), Traversal::Wide(kernels)) = (&self.wide_tlas, self.traversal) else {
            for (ray, hit) in rays.iter().zip(hits.iter_mut()) {
                *hit = self.intersect(ray, mask, alpha);
            }
            return;
        };
        for (rays, hits) in rays.chunks(PACKET).zip(hits.chunks_mut(PACKET)) {
            let (packet, mut t_max) = RayPacket::of_rays(rays);
            // Per ray, the closest so far: its instance and the BLAS's pending hit.
            let mut closest = [(0u32, PendingHit::Wide(0)); PACKET];
            let mut slots = [0u32; PACKET];
            let found = wide.walk_packet(
                &packet,
                first_lanes(rays.len()),
                kernels,
                false,
                &mut t_max,
                |slot, lanes, t_max| {
                    let index = self.tlas.primitive_indices[slot];
                    let (instance, blas) = self.traced(index);
                    if !instance.mask.intersects(mask) {
                        return 0;
                    }
                    let hit = match blas.packet_tree() {
                        Some((tree, kernels)) if instance.is_identity => {
                            tree.intersect_packet(&packet, lanes, t_max, &mut slots, kernels)
                        }
                        Some((tree, kernels)) => {
                            let object = packet.mapped(lanes, |ray| instance.object_ray(ray));
                            tree.intersect_packet(&object, lanes, t_max, &mut slots, kernels)
                        }
                        None => {
                            // Alpha-tested or BVH2: one ray at a time.
                            let mut hit = 0;
                            for lane in lanes_of(lanes) {
                                let ray = packet.ray(lane, t_max[lane]);
                                let object_ray = instance.object_ray(&ray);
                                if let Some((t, pending)) =
                                    blas.intersect_pending(&object_ray, alpha)
                                    && t < t_max[lane]
                                {
                                    t_max[lane] = t;
                                    closest[lane] = (index, pending);
                                    hit |= 1 << lane;
                                }
                            }
                            return hit;
                        }
                    };
                    for lane in lanes_of(hit) {
                        closest[lane] = (index, PendingHit::Wide(slots[lane]));
                    }
                    hit
                },
            );
            for (lane, (ray, hit)) in rays.iter().zip(hits.iter_mut()).enumerate() {
                *hit = (found >> lane & 1 != 0).then(|| {
                    let (index, pending) = closest[lane];
                    self.finish_hit(ray, t_max[lane], index, pending)
                });
            }
        }
    }

    /// `occluded` for many rays at once, `occluded[i]` for `rays[i]`, in packets of 64 as
    /// `intersect_coherent` traces them (shadow rays of a tile towards the lights).
    pub fn occluded_coherent<A: AlphaTest>(
        &self,
        rays: &[Ray],
        mask: InstanceMask,
        alpha: &A,
        occluded: &mut [bool],
    ) {
        debug_assert_eq!(rays.len(), occluded.len());
        let (Some(wide), Traversal::Wide(kernels)) = (&self.wide_tlas, self.traversal) else {
            for (ray, blocked) in rays.iter().zip(occluded.iter_mut()) {
                *blocked = self.occluded(ray, mask, alpha);
            }
            return;
        };
        for (rays, occluded) in rays.chunks(PACKET).zip(occluded.chunks_mut(PACKET)) {
            let (packet, mut t_max) = RayPacket::of_rays(rays);
            let blocked = wide.walk_packet(
                &packet,
                first_lanes(rays.len()),
                kernels,
                true,
                &mut t_max,
                |slot, lanes, t_max| {
                    let (instance, blas) = self.traced(self.tlas.primitive_indices[slot]);
                    if !instance.mask.intersects(mask) {
                        return 0;
                    }
                    match blas.packet_tree() {
                        Some((tree, kernels)) if instance.is_identity => {
                            tree.occluded_packet(&packet, lanes, t_max, kernels)
                        }
                        Some((tree, kernels)) => {
                            let object = packet.mapped(lanes, |ray| instance.object_ray(ray));
                            tree.occluded_packet(&object, lanes, t_max, kernels)
                        }
                        None => lanes_of(lanes)
                            .filter(|&lane| {
                                let ray = packet.ray(lane, t_max[lane]);
                                blas.occluded(&instance.object_ray(&ray), alpha)
                            })
                            .fold(0, |hit, lane| hit | 1 << lane),
                    }
                },
            );
            for (lane, blocked_here) in occluded.iter_mut().enumerate() {
                *blocked_here = blocked >> lane & 1 != 0;
            }
        }
    }

    /// `occluded` for many rays at once, `occluded[i]` for `rays[i]`: single-ray walks,
    /// several interleaved so that their latencies overlap (accel/stream.rs).
    pub fn occluded_stream<'a, A: AlphaTest>(
        &'a self,
        rays: &[Ray],
        mask: InstanceMask,
        alpha: &A,
        occluded: &mut [bool],
    ) {
        debug_assert_eq!(rays.len(), occluded.len());
        occluded.fill(false);
        let (Some(wide), Traversal::Wide(kernels)) = (&self.wide_tlas, self.traversal) else {
            for (ray, blocked) in rays.iter().zip(occluded.iter_mut()) {
                *blocked = self.occluded(ray, mask, alpha);
            }
            return;
        };
        let world = |ray: &Ray| RayLanes::from_parts(ray.origin, ray.direction, ray.t_min);
        // A one-entry TLAS of an untransformed wide BLAS (a level that is one static batch):
        // one job per ray, made as the walkers take them.
        if wide.sole_entry {
            let (instance, blas) = self.traced(self.tlas.primitive_indices[0]);
            if !instance.mask.intersects(mask) {
                return;
            }
            if let (true, Some((tree, _))) = (instance.is_identity, blas.packet_tree()) {
                if tree.nodes.is_empty() {
                    return;
                }
                let job = |index: usize| Job {
                    tree,
                    ray: world(&rays[index]),
                    t_max: rays[index].t_max,
                    index,
                };
                return run_jobs(kernels, rays.len(), job, occluded);
            }
        }
        // Else each ray walks the TLAS alone. A large wide BLAS it reaches becomes a job for
        // the stream; a small one (whose walk mostly hits the caches: a mover, a prop) and
        // one without a wide tree are tested there and then, and a block there cancels the
        // ray's jobs. `jobs` borrows the trees, so it cannot outlive the call as scratch;
        // it starts with room for a job a ray, one allocation a call (a tile's shadow rays
        // take at most 28 KB), where growing from empty took seven reallocations that
        // copied it: 1.5% of the-gallery's render instructions (callgrind).
        let mut jobs = Vec::with_capacity(rays.len());
        for (index, ray) in rays.iter().enumerate() {
            let lanes = world(ray);
            let first_job = jobs.len();
            let visit = |slot: usize, _| {
                let stream = |tree: &'a WideBvh, object: &RayLanes| {
                    // A tree this large has nodes (`Job::tree`'s rule).
                    let large = tree.bytes() >= STREAMED_TREE_BYTES;
                    if large {
                        let (ray, t_max) = (*object, ray.t_max);
                        jobs.push(Job {
                            tree,
                            ray,
                            t_max,
                            index,
                        });
                    }
                    large
                };
                // Any t inside the segment ends the walk; its value does not matter.
                (self.entry_blocks(slot, ray, &lanes, mask, alpha, stream)).then_some(ray.t_min)
            };
            if wide.walk(&lanes, ray.t_max, kernels, true, visit) {
                occluded[index] = true;
                jobs.truncate(first_job);
            }
        }
        let jobs = &jobs[..];
        run_jobs(kernels, jobs.len(), |at| jobs[at], occluded);
    }

    /// An any-hit walk's visit to TLAS slot `slot`: whether its instance or batch, if in
    /// `mask`, blocks `ray` (`world`: the ray prepared). `defer(tree, object ray)` may take a
    /// wide tree's walk away to be done later (returning true); the slot then counts as
    /// clear for now.
    #[inline(always)]
    fn entry_blocks<'a, A: AlphaTest>(
        &'a self,
        slot: usize,
        ray: &Ray,
        world: &RayLanes,
        mask: InstanceMask,
        alpha: &A,
        defer: impl FnOnce(&'a WideBvh, &RayLanes) -> bool,
    ) -> bool {
        let (instance, blas) = self.traced(self.tlas.primitive_indices[slot]);
        if !instance.mask.intersects(mask) {
            return false;
        }
        match blas.packet_tree() {
            Some((tree, kernels)) => {
                let mut moved = None;
                let object = instance.object_lanes(ray, world, &mut moved);
                !defer(tree, object) && tree.occluded_lanes(object, ray.t_max, kernels)
            }
            None => blas.occluded(&instance.object_ray(&ray.to_obvhs()), alpha),
        }
    }

    /// True when something in `mask` blocks `ray` between t_min and t_max (any hit).
    pub fn occluded<A: AlphaTest>(&self, ray: &Ray, mask: InstanceMask, alpha: &A) -> bool {
        if self.tlas.nodes.is_empty() {
            return false;
        }
        if let (Some(wide), Traversal::Wide(kernels)) = (&self.wide_tlas, self.traversal) {
            let world = RayLanes::from_parts(ray.origin, ray.direction, ray.t_min);
            let visit = |slot: usize, _| {
                let walk_now = |_: &WideBvh, _: &RayLanes| false;
                // Any t inside the segment ends the walk; its value does not matter.
                (self.entry_blocks(slot, ray, &world, mask, alpha, walk_now)).then_some(ray.t_min)
            };
            return wide.walk(&world, ray.t_max, kernels, true, visit);
        }
        !self
            .tlas
            .ray_traverse_miss(ray.to_obvhs(), |world_ray, id| {
                let (instance, blas) = self.traced(self.tlas.primitive_indices[id]);
                if !instance.mask.intersects(mask) {
                    return f32::INFINITY;
                }
                // Any t inside the segment ends traversal; its value does not matter.
                if blas.occluded(&instance.object_ray(world_ray), alpha) {
                    world_ray.tmin
                } else {
                    f32::INFINITY
                }
            })
    }

    /// Asks the CPU for the first lines `surface(hit)` will read: the triangle's corners
    /// and material (a hint: no effect on results). Then, once they have arrived,
    /// `prefetch_corners` asks for the lines those corners index.
    #[inline(always)]
    pub fn prefetch_triangle(&self, hit: &Hit) {
        let geometry = self.geometry_of(hit);
        let triangle = hit.primitive as usize;
        if let Some(corners) = geometry.triangles.get(triangle) {
            prefetch(corners);
        }
        if let Some(material) = geometry.materials.get(triangle) {
            prefetch(material);
        }
    }

    /// Asks the CPU for the corners' positions, normals and UVs `surface(hit)` will read
    /// (after `prefetch_triangle`: the corners' own line should be in the cache by now).
    #[inline(always)]
    pub fn prefetch_corners(&self, hit: &Hit) {
        let geometry = self.geometry_of(hit);
        let Some(corners) = geometry.triangles.get(hit.primitive as usize) else {
            return;
        };
        for &corner in corners {
            let corner = corner as usize;
            if let Some(position) = geometry.positions.get(corner) {
                prefetch(position);
            }
            if let Some(normal) = geometry.normals.get(corner) {
                prefetch(normal);
            }
            if let Some(uv) = geometry.uvs.get(corner) {
                prefetch(uv);
            }
        }
    }

    /// The mesh `hit` is on.
    #[inline(always)]
    fn geometry_of(&self, hit: &Hit) -> &MeshGeometry {
        &self.blases[self.instances[hit.instance as usize].blas as usize].geometry
    }

    /// The shading data at `hit` (found by `intersect` with `ray`).
    #[inline]
    pub fn surface(&self, hit: &Hit) -> SurfaceHit {
        self.triangle_surface(hit).at(hit.barycentrics)
    }

    /// What `surface` reads and works out once for `hit`'s triangle, wherever on it a hit
    /// lands.
    #[inline]
    pub fn triangle_surface(&self, hit: &Hit) -> TriangleSurface<'_> {
        let instance = &self.instances[hit.instance as usize];
        let geometry = &self.blases[instance.blas as usize].geometry;
        let triangle = hit.primitive as usize;
        let corners = geometry.triangles[triangle];
        let [v0, v1, v2] = geometry.triangle_vertices(triangle);
        // Normals go through the inverse transpose: under a mirroring transform this keeps
        // them on the same physical side, although the world-space winding flips.
        let object_normal = (v1 - v0).cross(v2 - v0);
        let geometric_normal = (instance.normal_from_object * object_normal).normalize_or(Vec3A::Y);
        let uvs = (!geometry.uvs.is_empty()).then(|| corners.map(|i| geometry.uvs[i as usize]));
        let texture_frame = uvs.map_or(TextureFrame::NONE, |uvs| {
            TextureFrame::of(
                instance,
                [v1 - v0, v2 - v0],
                [uvs[1] - uvs[0], uvs[2] - uvs[0]],
                object_normal,
            )
        });
        TriangleSurface {
            instance,
            of: (hit.instance, hit.primitive),
            vertices: [v0, v1, v2],
            normals: (!geometry.normals.is_empty())
                .then(|| corners.map(|i| Vec3A::from(geometry.normals[i as usize]))),
            uvs,
            texture_frame,
            geometric_normal,
            material: geometry.materials.get(triangle).copied().unwrap_or(0),
        }
    }
}

/// A triangle's shading data that does not depend on where on it a hit lands
/// (`AccelScene::triangle_surface`): kept while hits land on the same triangle, as most of
/// a tile's camera rays do, each hit then costs only its interpolation.
#[derive(Clone, Copy, Debug)]
pub struct TriangleSurface<'a> {
    instance: &'a Instance,
    /// (instance, primitive).
    of: (u32, u32),
    vertices: [Vec3A; 3],
    normals: Option<[Vec3A; 3]>,
    uvs: Option<[Vec2; 3]>,
    texture_frame: TextureFrame,
    geometric_normal: Vec3A,
    material: u32,
}

/// A triangle's texture-space facts (`SurfaceHit::tangent`, `handedness`, `uv_density`).
#[derive(Clone, Copy, Debug)]
struct TextureFrame {
    tangent: Vec3A,
    handedness: f32,
    uv_density: f32,
}

impl TextureFrame {
    const NONE: TextureFrame = TextureFrame {
        tangent: Vec3A::ZERO,
        handedness: 1.0,
        uv_density: f32::NEG_INFINITY,
    };

    /// From the triangle's two object-space edges from its first corner, the same edges
    /// in UV, and their cross product (`object_normal`, as long as twice the triangle's
    /// area), worked out in object space and carried to `instance`'s world: dP/du and
    /// dP/dv solve edge = dP/du du + dP/dv dv; the transform scales the area by
    /// 2^log2_area_scale and a mirror turns the handedness (the world frame built from the
    /// world edges is the same, `the_texture_frame_is_the_world_edges_frame`).
    #[inline]
    fn of(
        instance: &Instance,
        [e1, e2]: [Vec3A; 2],
        [d1, d2]: [Vec2; 2],
        object_normal: Vec3A,
    ) -> TextureFrame {
        let uv_area = d1.perp_dot(d2);
        let area_squared = object_normal.length_squared();
        if uv_area == 0.0 || !uv_area.is_finite() || !(area_squared > 0.0) {
            return TextureFrame::NONE;
        }
        let dp_du = (e1 * d2.y - e2 * d1.y) / uv_area;
        let dp_dv = (e2 * d1.x - e1 * d2.x) / uv_area;
        let turns = object_normal.cross(dp_du).dot(-dp_dv) >= 0.0;
        // log2 of the area as half log2 of its square: no square root.
        let log2_world_area =
            0.5 * super::approximate_log2(area_squared) + instance.log2_area_scale;
        TextureFrame {
            tangent: instance.world_from_object.transform_vector3a(dp_du),
            handedness: if turns {
                instance.mirror
            } else {
                -instance.mirror
            },
            uv_density: 0.5 * (super::approximate_log2(uv_area.abs()) - log2_world_area),
        }
    }
}

impl TriangleSurface<'_> {
    /// Whether `hit` is on this triangle.
    #[inline]
    pub fn holds(&self, hit: &Hit) -> bool {
        self.of == (hit.instance, hit.primitive)
    }

    /// The shading data at barycentrics (b1, b2).
    #[inline]
    pub fn at(&self, barycentrics: Vec2) -> SurfaceHit {
        let Vec2 { x: b1, y: b2 } = barycentrics;
        let b0 = 1.0 - b1 - b2;
        let [v0, v1, v2] = self.vertices;
        let object_position = v0 * b0 + v1 * b1 + v2 * b2;
        let shading_normal = match self.normals {
            None => self.geometric_normal,
            Some([n0, n1, n2]) => (self.instance.normal_from_object
                * (n0 * b0 + n1 * b1 + n2 * b2))
                .normalize_or(self.geometric_normal),
        };
        SurfaceHit {
            position: (self.instance.world_from_object).transform_point3a(object_position),
            geometric_normal: self.geometric_normal,
            shading_normal,
            uv: self
                .uvs
                .map_or(Vec2::ZERO, |uvs| interpolate_uv(uvs, barycentrics)),
            material: self.material,
            tangent: self.texture_frame.tangent,
            handedness: self.texture_frame.handedness,
            uv_density: self.texture_frame.uv_density,
        }
    }
}

/// Trees at least this large (nodes and blocks) are walked in the stream; smaller ones
/// mostly hit the caches, so the rays walk them at once.
const STREAMED_TREE_BYTES: usize = 512 * 1024;

/// `occluded_jobs` with the kernels asked for: the TLAS's, which `set_traversal` keeps
/// the same as every BLAS's (so a streamed BLAS runs the kernels it would run alone).
#[inline]
fn run_jobs<'a>(
    kernels: Kernels,
    count: usize,
    job: impl Fn(usize) -> Job<'a>,
    occluded: &mut [bool],
) {
    #[cfg(target_arch = "x86_64")]
    if kernels.avx2() {
        // SAFETY: the CPU has AVX2, the only feature the function enables.
        return unsafe { run_jobs_avx2(count, job, occluded) };
    }
    let _ = kernels;
    occluded_jobs::<Portable>(count, job, occluded);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn run_jobs_avx2<'a>(count: usize, job: impl Fn(usize) -> Job<'a>, occluded: &mut [bool]) {
    occluded_jobs::<super::wide::avx2::Avx2>(count, job, occluded);
}

/// The world box of an object box under an affine transform (Arvo 1990, "Transforming
/// Axis-Aligned Bounding Boxes": centre moved, half-extent through |M|).
pub(crate) fn transform_aabb(aabb: &Aabb, transform: &Affine3A) -> Aabb {
    if !aabb.valid() {
        return Aabb::empty();
    }
    let centre = transform.transform_point3a(aabb.center());
    let half = aabb.diagonal() * 0.5;
    let m = transform.matrix3;
    let extent = m.x_axis.abs() * half.x + m.y_axis.abs() * half.y + m.z_axis.abs() * half.z;
    Aabb::new(centre - extent, centre + extent)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{Quat, Vec3};

    /// The texture frame worked out in object space and carried to the world is the one
    /// built from the world-space edges: the same tangent, the same handedness (mirrors
    /// included), and the same UV density to within the bit-level log2's error.
    #[test]
    fn the_texture_frame_is_the_world_edges_frame() {
        let corners = [
            Vec3A::new(0.1, 0.2, 0.3),
            Vec3A::new(1.3, 0.1, -0.2),
            Vec3A::new(0.4, 1.1, 0.5),
        ];
        let uvs = [
            Vec2::new(0.2, 0.9),
            Vec2::new(1.7, 0.8),
            Vec2::new(0.5, -0.4),
        ];
        let transforms = [
            Affine3A::IDENTITY,
            Affine3A::from_scale_rotation_translation(
                Vec3::splat(2.5),
                Quat::from_rotation_y(0.7) * Quat::from_rotation_x(-0.3),
                Vec3::new(4.0, -1.0, 2.0),
            ),
            Affine3A::from_scale_rotation_translation(
                Vec3::new(-1.0, 1.0, 1.0) * 0.5,
                Quat::from_rotation_z(1.1),
                Vec3::ZERO,
            ),
        ];
        for (flip, transform) in transforms.iter().enumerate() {
            let instance = Instance::new(0, *transform, InstanceMask::ALL, 0);
            for uvs in [uvs, [uvs[0], uvs[2], uvs[1]]] {
                let [e1, e2] = [corners[1] - corners[0], corners[2] - corners[0]];
                let [d1, d2] = [uvs[1] - uvs[0], uvs[2] - uvs[0]];
                let frame = TextureFrame::of(&instance, [e1, e2], [d1, d2], e1.cross(e2));
                // The same in world space.
                let [w1, w2] = [e1, e2].map(|e| transform.transform_vector3a(e));
                let uv_area = d1.perp_dot(d2);
                let dp_du = (w1 * d2.y - w2 * d1.y) / uv_area;
                let dp_dv = (w2 * d1.x - w1 * d2.x) / uv_area;
                let normal = (instance.normal_from_object * e1.cross(e2)).normalize();
                let handedness = if normal.cross(dp_du).dot(-dp_dv) >= 0.0 {
                    1.0
                } else {
                    -1.0
                };
                let density = 0.5 * (uv_area.abs() / w1.cross(w2).length()).log2();
                assert!(
                    (frame.tangent - dp_du).length() < 1e-4 * dp_du.length(),
                    "{flip}"
                );
                assert_eq!(frame.handedness, handedness, "transform {flip}");
                assert!((frame.uv_density - density).abs() < 0.1, "transform {flip}");
            }
        }
    }
}
