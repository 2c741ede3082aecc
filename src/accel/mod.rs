//! Frame step `accel`: ray queries over instanced meshes that move and deform every frame.
//!
//! At load, `AccelScene::new` merges the instances marked `Mobility::Static` into
//! world-space batches (`batch`). Per frame (driven by the caller; accel knows nothing of the
//! ECS, windows or materials):
//! 1. `Blas::refit` each deformed mesh (rebuilds it when its quality has decayed);
//! 2. `instances_mut` for moved instances, or `AccelScene::set_instances` for a new list
//!    (things spawned and despawned: batches whose members are all unchanged survive);
//! 3. `AccelScene::rebuild_tlas` over world-space instance and batch boxes (PLOC, builder
//!    reused), dissolving any batch a member of which has changed;
//! 4. `intersect` (closest hit) and `occluded` (any hit, early exit) from many threads, one
//!    ray at a time or, for rays that travel together, `intersect_coherent` /
//!    `occluded_coherent` in packets of 64 (`packet`), or, for many shadow rays at once,
//!    `occluded_stream` in interleaved single-ray walks (`stream`), with the very same
//!    results; and, for the simulation's character controller, `sphere_contacts`
//!    (`overlap`): every triangle within reach of a sphere.
//!
//! Rays are traced TLAS -> instance (ray moved into object space, direction not
//! renormalised, so t is the same in both spaces) or static batch (world space) -> BLAS (its
//! 8-wide BVH, `wide`, or its BVH2). Instance masks select what a query sees
//! (camera-visible, casts-shadow, pickable); materials with alpha-masked holes are honoured
//! through the caller's `AlphaTest` (accel knows materials only as ids).
//!
//! Rays that start on a surface: spawn them with `Ray::spawn`, which offsets the origin
//! along the geometric normal by an amount scaled to the position's magnitude (after
//! pbrt-v4's `OffsetRayOrigin`, simplified to a conservative relative epsilon).
//!
//! An [`Instance`] is a BLAS, an affine transform with its cached inverse, a mask
//! ([`InstanceMask::CAMERA`], [`InstanceMask::SHADOW`], [`InstanceMask::PICKABLE`]), the
//! caller's id (the game's entity) and a [`Mobility`]: `Static` for what never moves,
//! `Movable` otherwise. Extract marks a level's placements `Static` unless their entity
//! plays an animation, has a deformer, patrols or is the player. Queries return hits as t,
//! instance, triangle and barycentrics; `surface` makes a hit into world position,
//! geometric and shading normals, UV, material id and user id.
//!
//! # Tests
//!
//! The tests hold every query to brute force over all triangles of all instances, on random
//! scenes with rotated, non-uniformly scaled and mirrored instances, degenerate and huge
//! triangles, axis-parallel rays and rays leaving surfaces, before and after refits, with
//! and without static batches (a batched member is tested as the batch holds it, in world
//! space, so hits still agree to the bit), and before and after a batch dissolves.

mod batch;
mod blas;
pub mod overlap;
pub mod packet;
mod stream;
mod tlas;
pub mod wide;

pub use batch::MAX_BATCH_TRIANGLES;
pub use blas::{Blas, BlasKind, MeshGeometry, REBUILD_RATIO, RefitOutcome, Traversal};
pub use overlap::Contact;
pub use packet::{PACKET, RayPacket};
pub use tlas::{AccelScene, Instance, Mobility, TriangleSurface};
pub use wide::{Kernels, WideBvh, WideTlas};

use glam::{Vec2, Vec3A};
use obvhs::ray::Ray as ObvhsRay;
use obvhs::rt_triangle::RtTriangle;

/// Asks the CPU to fetch `value`'s cache line (a hint: no effect on results; nothing on
/// targets without one). Traversals fetch the nodes they will read next with it, and
/// `render` the lines a later pass over its paths will read.
#[inline(always)]
pub fn prefetch<T>(value: &T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch reads nothing architecturally and cannot fault; SSE is part of
    // x86-64's baseline.
    unsafe {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        _mm_prefetch::<_MM_HINT_T0>((value as *const T).cast());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = value;
}

/// A ray segment: points origin + t * direction for t in [t_min, t_max].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    pub origin: Vec3A,
    /// Need not be unit length; t is measured in multiples of it.
    pub direction: Vec3A,
    pub t_min: f32,
    pub t_max: f32,
}

impl Ray {
    pub fn new(origin: Vec3A, direction: Vec3A) -> Self {
        Ray {
            origin,
            direction,
            t_min: 0.0,
            t_max: f32::INFINITY,
        }
    }

    /// A ray leaving a surface point: the origin is pushed off the surface on the side
    /// `direction` goes, so the ray cannot hit the triangle it starts on.
    pub fn spawn(position: Vec3A, geometric_normal: Vec3A, direction: Vec3A) -> Self {
        let side = if geometric_normal.dot(direction) >= 0.0 {
            1.0
        } else {
            -1.0
        };
        Ray::new(
            position + geometric_normal * (side * surface_offset(position)),
            direction,
        )
    }

    /// A shadow ray from a surface point to a point `target` (on a light), stopping just
    /// short of it so the light's own surface does not count as a blocker.
    pub fn spawn_to(position: Vec3A, geometric_normal: Vec3A, target: Vec3A) -> Self {
        let mut ray = Ray::spawn(position, geometric_normal, target - position);
        let span = target - ray.origin;
        ray.direction = span;
        ray.t_max = 1.0 - surface_offset(target) / span.length().max(f32::MIN_POSITIVE);
        ray
    }

    pub fn at(&self, t: f32) -> Vec3A {
        self.origin + self.direction * t
    }

    pub(crate) fn to_obvhs(self) -> ObvhsRay {
        ObvhsRay::new(self.origin, self.direction, self.t_min, self.t_max)
    }
}

/// Distance to push a ray origin off a surface at `position`: relative to the coordinates'
/// magnitude, since f32 spacing grows with it (2^-14 relative, about 60 ulps).
fn surface_offset(position: Vec3A) -> f32 {
    (1.0 + position.abs().max_element()) * (1.0 / 16384.0)
}

/// Which queries see an instance; a query passes a mask and sees instances sharing a bit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct InstanceMask(pub u8);

impl InstanceMask {
    /// Seen by camera rays (a path's first segment).
    pub const CAMERA: InstanceMask = InstanceMask(1);
    /// Blocks shadow rays.
    pub const SHADOW: InstanceMask = InstanceMask(2);
    /// Found by the editor's picking rays.
    pub const PICKABLE: InstanceMask = InstanceMask(4);
    /// Seen by bounce rays (every segment after the first: reflections, indirect light).
    pub const BOUNCE: InstanceMask = InstanceMask(8);
    pub const ALL: InstanceMask = InstanceMask(0xff);

    pub fn intersects(self, other: InstanceMask) -> bool {
        self.0 & other.0 != 0
    }
}

impl std::ops::BitOr for InstanceMask {
    type Output = InstanceMask;
    fn bitor(self, other: InstanceMask) -> InstanceMask {
        InstanceMask(self.0 | other.0)
    }
}

/// Decides whether a point on an alpha-masked material is solid. Called only for
/// triangles whose `MeshGeometry::alpha_tested` flag is set.
pub trait AlphaTest: Sync {
    fn is_opaque(&self, material: u32, uv: Vec2) -> bool;
}

/// For scenes with no alpha-masked materials: everything is solid.
pub struct Opaque;

impl AlphaTest for Opaque {
    #[inline]
    fn is_opaque(&self, _: u32, _: Vec2) -> bool {
        true
    }
}

impl<F: Fn(u32, Vec2) -> bool + Sync> AlphaTest for F {
    fn is_opaque(&self, material: u32, uv: Vec2) -> bool {
        self(material, uv)
    }
}

/// The closest hit of a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub t: f32,
    /// Index into `AccelScene::instances`.
    pub instance: u32,
    /// Triangle index in the instance's mesh.
    pub primitive: u32,
    /// (b1, b2): the hit is (1 - b1 - b2) v0 + b1 v1 + b2 v2.
    pub barycentrics: Vec2,
}

/// Everything about a hit point a shader needs, in world space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceHit {
    pub position: Vec3A,
    /// Unit normal of the triangle's plane, oriented by its winding (v0, v1, v2 counter-
    /// clockwise seen from the front), and kept correct under mirroring transforms.
    pub geometric_normal: Vec3A,
    /// Interpolated vertex normal (the geometric normal when the mesh has none).
    pub shading_normal: Vec3A,
    pub uv: Vec2,
    pub material: u32,
    /// The triangle's tangent frame for normal maps: dP/du in world space (zero where the
    /// triangle's UVs are degenerate or missing), and +1 or -1 for whether the bitangent,
    /// normal x tangent, runs along -v (glTF's "up" in a texture) or along +v (a mirrored
    /// UV layout).
    pub tangent: Vec3A,
    pub handedness: f32,
    /// 0.5 log2(UV area / world area) of the triangle: a ray cone `w` metres wide covers
    /// 2^(log2 w + this) UV units (Akenine-Moller et al. 2019, "Texture Level of Detail
    /// Strategies for Real-Time Ray Tracing", eq. 20.4's triangle term); -inf without UVs.
    pub uv_density: f32,
}

/// log2(x) for x > 0 read off its bits: exact at powers of two and linear between them
/// (at most 0.086 low), continuous and increasing, which is all a texture's level of
/// detail needs (`SurfaceHit::uv_density`, the render's ray cones). libm's `log2f` per hit
/// was 1.6% of first-light's frame (perf).
#[inline]
pub fn approximate_log2(x: f32) -> f32 {
    x.to_bits() as f32 * (1.0 / 8_388_608.0) - 127.0
}

/// Barycentrics (b1, b2) of the ray's crossing of the triangle's plane (Moller & Trumbore
/// 1997, "Fast, Minimum Storage Ray/Triangle Intersection"), for a ray known to hit it.
/// Works on obvhs's `RtTriangle` (v0, e1 = v0 - v1, e2 = v2 - v0), which the traversal has
/// just read: fetching the mesh's own vertices instead cost 20% of primary-ray throughput on
/// the 178k-triangle apartment (`gloam raybench`).
#[inline]
pub(crate) fn barycentrics(triangle: &RtTriangle, origin: Vec3A, direction: Vec3A) -> Vec2 {
    let edge1 = -triangle.e1;
    let edge2 = triangle.e2;
    let p = direction.cross(edge2);
    let determinant = edge1.dot(p);
    if determinant == 0.0 {
        return Vec2::ZERO;
    }
    let inverse = 1.0 / determinant;
    let s = origin - triangle.v0;
    let q = s.cross(edge1);
    Vec2::new(s.dot(p) * inverse, direction.dot(q) * inverse)
}
