//! Frame step `accel`, at level load: static batching.
//!
//! Instances the caller marks `Mobility::Static` (walls, floors, props: everything that never
//! moves) are merged, one batch per instance mask, into a single BLAS over their triangles
//! carried into world space. Rays then walk one deep tree where they walked a TLAS over many
//! shallow ones: every two-level query pays for the TLAS walk, for entering each
//! overlapping instance's tree and for the object-space ray, and on dream-apartment (the
//! room and its light quad, two instances) that was 40% of a shadow ray (`gloam raybench`:
//! the room's BLAS on its own traced 14.6 against 10.0 Mrays/s through the TLAS). Batched,
//! dream-apartment's shadow rays went from 11.2 to 16.7 Mrays/s and its diffuse bounces
//! from 4.7 to 5.4 (`gloam_renderer` against `gloam_renderer_unbatched` in one `gloam
//! raybench` run, one thread); first-light (a batch of 30 static pieces plus the wardens
//! and the banner) went from 17.1 to 22.0 Mrays/s for camera rays and from 8.9 to 9.7 for
//! bounces, while its shadow rays went from 8.8 to 8.4 (medians of four runs, one thread).
//! The same idea as the static batching of Unity and Unreal, applied to the BVH rather than
//! to draw calls.
//!
//! Hits are reported as the members' own: each member's triangles are a run of the batch's,
//! so a batch triangle maps back to (instance, triangle) by a search over the members' first
//! triangles, and its barycentrics are the member triangle's (an affine
//! map keeps them; they differ from the object-space ones by rounding only). The members'
//! BLASes stay, for shading and for the day the batch dissolves: `AccelScene::rebuild_tlas`
//! drops a batch as soon as any member's transform, mask, BLAS or mobility has changed (the
//! editor moving a wall) or a member is gone (`AccelScene::set_instances` finds members by
//! `user_id` in a new instance list), and its members are traced one by one again until
//! `AccelScene::rebatch` merges them anew.

use glam::{Vec2, Vec3A};
use rayon::prelude::*;

use super::blas::{Blas, BlasKind, MeshGeometry, PendingHit};
use super::tlas::{Instance, Mobility};

/// A batch holds at most this many triangles (about 200 bytes each with its trees): a level
/// that places one big mesh a thousand times keeps the copies beyond this instanced rather
/// than spend gigabytes on them.
pub const MAX_BATCH_TRIANGLES: usize = 1 << 21;

/// Static instances of one mask merged into one world-space BLAS.
#[derive(Clone)]
pub(super) struct StaticBatch {
    /// The members' triangles in world space, built as a static BLAS.
    pub(super) blas: Blas,
    /// Stands in for the members in the TLAS: untransformed, with their mask.
    pub(super) instance: Instance,
    /// Each member's index and its instance as it was batched (to see it change).
    pub(super) members: Vec<(u32, Instance)>,
    /// Per member (in `members`' order), the index of its first triangle in the batch
    /// mesh, ascending: a member's triangles are the run up to the next member's first.
    /// Searched, not a table per triangle: that table (8 bytes a triangle) missed the cache
    /// on most incoherent rays (dream-apartment's bounces through the TLAS: 190 ns a ray
    /// with it, 178 with the search, in one run).
    first_triangles: Vec<u32>,
}

impl StaticBatch {
    /// The member instance, its triangle and the barycentrics of a hit the batch's BLAS
    /// found (still pending) along the world-space ray from `origin` along `direction`.
    #[inline]
    pub(super) fn resolve(
        &self,
        pending: PendingHit,
        origin: Vec3A,
        direction: Vec3A,
    ) -> ((u32, u32), Vec2) {
        let (triangle, barycentrics) = self.blas.resolve(pending, origin, direction);
        (self.member_of(triangle), barycentrics)
    }

    /// True while every member is still as it was batched.
    pub(super) fn is_current(&self, instances: &[Instance]) -> bool {
        self.members.iter().all(|(index, batched)| {
            instances.get(*index as usize).is_some_and(|now| {
                now.mobility == Mobility::Static
                    && now.blas == batched.blas
                    && now.mask == batched.mask
                    && now.world_from_object() == batched.world_from_object()
            })
        })
    }
}

impl StaticBatch {
    /// The member instance and its own triangle behind batch triangle `triangle`.
    pub(super) fn member_of(&self, triangle: u32) -> (u32, u32) {
        // The last member starting at or before `triangle` (the first starts at 0).
        let member = self
            .first_triangles
            .partition_point(|&first| first <= triangle)
            - 1;
        (
            self.members[member].0,
            triangle - self.first_triangles[member],
        )
    }

    /// The instance mask every member shares.
    pub(super) fn mask(&self) -> super::InstanceMask {
        self.instance.mask
    }

    /// Points each member at its index in a new instance list (by `user_id`); a member
    /// missing from it gets an index no list has, so the batch dissolves.
    pub(super) fn renumber(&mut self, index_of: &std::collections::HashMap<u64, u32>) {
        for (index, batched) in &mut self.members {
            *index = index_of.get(&batched.user_id).copied().unwrap_or(u32::MAX);
        }
    }
}

/// Instances that could join a batch but are traced on their own (`batched` per instance).
pub(super) fn unbatched_candidates(
    blases: &[Blas],
    instances: &[Instance],
    batched: &[bool],
) -> usize {
    instances
        .iter()
        .enumerate()
        .filter(|(index, instance)| {
            can_batch(instance, blases) && !batched.get(*index).copied().unwrap_or(false)
        })
        .count()
}

/// May `instance` join a batch? Static, over a mesh that keeps its shape and is opaque
/// (one with a wide tree: alpha-tested meshes need their per-triangle test, which batches,
/// having no materials, do not run).
fn can_batch(instance: &Instance, blases: &[Blas]) -> bool {
    let blas = &blases[instance.blas as usize];
    instance.mobility == Mobility::Static
        && blas.kind == BlasKind::Static
        && blas.triangle_count() > 0
        && blas.wide.is_some()
}

/// The batches for `instances`: per mask, the instances that may be batched, in index order
/// up to `MAX_BATCH_TRIANGLES`; a group of fewer than two members stays instanced (a lone
/// untransformed instance gains nothing, a lone transformed one little).
pub(super) fn batch_statics(blases: &[Blas], instances: &[Instance]) -> Vec<StaticBatch> {
    let mut groups: Vec<(u8, Vec<u32>, usize)> = Vec::new();
    for (index, instance) in instances.iter().enumerate() {
        if !can_batch(instance, blases) {
            continue;
        }
        let triangles = blases[instance.blas as usize].triangle_count();
        let group = match groups
            .iter()
            .position(|(mask, ..)| *mask == instance.mask.0)
        {
            Some(group) => group,
            None => {
                groups.push((instance.mask.0, Vec::new(), 0));
                groups.len() - 1
            }
        };
        let (_, members, count) = &mut groups[group];
        if *count + triangles <= MAX_BATCH_TRIANGLES {
            members.push(index as u32);
            *count += triangles;
        }
    }
    groups.retain(|(_, members, _)| members.len() >= 2);
    groups
        .into_par_iter()
        .map(|(_, members, _)| merge(blases, instances, &members))
        .collect()
}

/// One batch over `members`: their triangles in world space, built as a static BLAS.
fn merge(blases: &[Blas], instances: &[Instance], members: &[u32]) -> StaticBatch {
    let mut geometry = MeshGeometry::default();
    let mut first_triangles = Vec::with_capacity(members.len());
    for &index in members {
        let instance = &instances[index as usize];
        let mesh = &blases[instance.blas as usize].geometry;
        let to_world = instance.world_from_object();
        let base = geometry.positions.len() as u32;
        first_triangles.push(geometry.triangles.len() as u32);
        geometry
            .positions
            .extend(mesh.positions.iter().map(|&p| to_world.transform_point3(p)));
        // The vertex order is kept, so barycentrics (b1, b2) name the same point on the
        // member's triangle (a mirroring transform flips the winding, not the corners).
        geometry
            .triangles
            .extend(mesh.triangles.iter().map(|t| t.map(|i| i + base)));
    }
    let mask = instances[members[0] as usize].mask;
    StaticBatch {
        blas: Blas::build(geometry, BlasKind::Static),
        instance: Instance::new(u32::MAX, glam::Affine3A::IDENTITY, mask, u64::MAX),
        members: members
            .iter()
            .map(|&index| (index, instances[index as usize].clone()))
            .collect(),
        first_triangles,
    }
}
