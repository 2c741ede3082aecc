//! Bottom-level BVHs: one per mesh, in the mesh's object space.
//!
//! Frame step `accel`, first half: static meshes are built once at load; deforming meshes
//! are refit every frame (leaf boxes in parallel, then a single bottom-up sweep) and rebuilt
//! when refitting has let the tree decay. Built on obvhs's `Bvh2` (PLOC + reinsertion +
//! leaf collapse; Meister & Bittner 2018, "Parallel Locally-Ordered Clustering for Bounding
//! Volume Hierarchy Construction"). Measured on this machine, BVH2 traces faster than
//! obvhs's CWBVH (see `gloam raybench`'s layouts table), so both kinds use BVH2.
//!
//! Triangles are stored in BVH leaf order as `RtTriangle` (base vertex, two edges, normal):
//! the traversal closure indexes them directly, with no `primitive_indices` indirection.

use glam::{Vec2, Vec3, Vec3A};
use obvhs::BvhBuildParams;
use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;
use obvhs::bvh2::builder::build_bvh2;
use obvhs::ray::{Ray as ObvhsRay, RayHit};
use obvhs::rt_triangle::RtTriangle;
use rayon::prelude::*;

use super::{AlphaTest, barycentrics};

/// Triangle geometry handed to accel: object-space vertices and per-triangle data.
/// Accel knows materials only as opaque ids, passed back to the caller's `AlphaTest`.
#[derive(Clone, Debug, Default)]
pub struct MeshGeometry {
    pub positions: Vec<Vec3>,
    /// Per-vertex shading normals (may be empty: the geometric normal is used).
    pub normals: Vec<Vec3>,
    /// Per-vertex UVs (may be empty).
    pub uvs: Vec<Vec2>,
    pub triangles: Vec<[u32; 3]>,
    /// Material id per triangle.
    pub materials: Vec<u32>,
    /// Per triangle: does its material have alpha-masked holes? (empty: none do)
    pub alpha_tested: Vec<bool>,
}

impl MeshGeometry {
    pub fn triangle_vertices(&self, triangle: usize) -> [Vec3A; 3] {
        self.triangles[triangle].map(|i| Vec3A::from(self.positions[i as usize]))
    }

    /// UV at barycentrics (b1, b2) of `triangle` (zero when the mesh has no UVs).
    pub fn uv_at(&self, triangle: usize, b: Vec2) -> Vec2 {
        if self.uvs.is_empty() {
            return Vec2::ZERO;
        }
        let [a, c, d] = self.triangles[triangle].map(|i| self.uvs[i as usize]);
        a * (1.0 - b.x - b.y) + c * b.x + d * b.y
    }
}

/// How a BLAS will be used.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BlasKind {
    /// Built once with a thorough build.
    Static,
    /// Refit every frame; rebuilt when its SAH cost exceeds `REBUILD_RATIO` x the cost
    /// right after its last build.
    Deforming,
}

/// Rebuild a deforming BLAS when refitting has raised its SAH cost by this factor over its
/// last build. Refit trees of moderate deformation stay within ~1.2x (see the tests);
/// tearing and large motion blow past 2x. 1.5 rebuilds well before traversal suffers much.
pub const REBUILD_RATIO: f32 = 1.5;

/// What `Blas::refit` did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RefitOutcome {
    Refit,
    /// Quality had decayed past `REBUILD_RATIO`: rebuilt from scratch.
    Rebuilt,
}

/// A bottom-level BVH with its triangles in leaf order.
#[derive(Clone)]
pub struct Blas {
    pub kind: BlasKind,
    pub geometry: MeshGeometry,
    pub(crate) bvh: Bvh2,
    /// Triangles in BVH leaf order (`bvh.primitive_indices` applied).
    pub(crate) ordered: Vec<RtTriangle>,
    /// Original triangle index of each entry of `ordered`.
    pub(crate) ordered_ids: Vec<u32>,
    /// Alpha-tested flag per entry of `ordered`, or empty when no triangle is.
    ordered_alpha: Vec<bool>,
    /// SAH cost right after the last build (the reference for the rebuild policy).
    built_cost: f32,
}

impl Blas {
    pub fn build(geometry: MeshGeometry, kind: BlasKind) -> Blas {
        let triangles: Vec<RtTriangle> = (0..geometry.triangles.len())
            .map(|t| {
                let [a, b, c] = geometry.triangle_vertices(t);
                RtTriangle::new(a, b, c)
            })
            .collect();
        let params = match kind {
            BlasKind::Static => BvhBuildParams::medium_build(),
            // Refit trees keep their topology for many frames: the same quality preset,
            // but 1 triangle per leaf keeps refit boxes tight as triangles move apart.
            BlasKind::Deforming => BvhBuildParams {
                max_prims_per_leaf: 1,
                ..BvhBuildParams::medium_build()
            },
        };
        let mut bvh = if triangles.is_empty() {
            Bvh2::default()
        } else {
            build_bvh2(&triangles, params, &mut Default::default())
        };
        if kind == BlasKind::Deforming {
            // Parents before children: `refit_all` then takes its single-sweep path (obvhs
            // measures it ~3x faster than the stack-ordered fallback).
            bvh.reorder_in_stack_traversal_order();
        }
        let ordered_ids = bvh.primitive_indices.clone();
        let ordered = ordered_ids.iter().map(|&i| triangles[i as usize]).collect();
        let ordered_alpha = if geometry.alpha_tested.iter().any(|&a| a) {
            ordered_ids
                .iter()
                .map(|&i| geometry.alpha_tested[i as usize])
                .collect()
        } else {
            Vec::new()
        };
        let mut blas = Blas {
            kind,
            geometry,
            bvh,
            ordered,
            ordered_ids,
            ordered_alpha,
            built_cost: 0.0,
        };
        blas.built_cost = blas.sah_cost();
        blas
    }

    pub fn triangle_count(&self) -> usize {
        self.geometry.triangles.len()
    }

    /// Object-space bounds (empty for an empty mesh).
    pub fn bounds(&self) -> Aabb {
        self.bvh
            .nodes
            .first()
            .map_or(Aabb::empty(), |root| *root.aabb())
    }

    /// SAH cost of the tree relative to its root's area (Goldsmith & Salmon 1987;
    /// MacDonald & Booth 1990): sum of node areas times traversal cost (1) plus leaf areas
    /// times triangle count times intersection cost (1), over the root area.
    pub fn sah_cost(&self) -> f32 {
        let Some(root) = self.bvh.nodes.first() else {
            return 0.0;
        };
        let root_area = root.aabb().half_area().max(f32::MIN_POSITIVE);
        let total: f32 = self
            .bvh
            .nodes
            .par_iter()
            .map(|node| {
                let area = node.aabb().half_area();
                if node.is_leaf() {
                    area * node.prim_count as f32
                } else {
                    area
                }
            })
            .sum();
        total / root_area
    }

    /// Current cost over the cost right after the last build (1.0 = as good as built).
    pub fn quality_decay(&self) -> f32 {
        if self.built_cost > 0.0 {
            self.sah_cost() / self.built_cost
        } else {
            1.0
        }
    }

    /// Moves the vertices (and, when given, the normals) and updates the tree: refit in
    /// place, or rebuild when the refit tree's SAH cost has decayed past `REBUILD_RATIO`.
    /// Topology (the triangle list) is unchanged; `positions` must match its length.
    pub fn refit(&mut self, positions: &[Vec3], normals: Option<&[Vec3]>) -> RefitOutcome {
        debug_assert_eq!(
            positions.len(),
            self.geometry.positions.len(),
            "refit keeps the vertex count"
        );
        self.geometry.positions.copy_from_slice(positions);
        if let Some(normals) = normals {
            self.geometry.normals.clear();
            self.geometry.normals.extend_from_slice(normals);
        }
        self.refit_geometry()
    }

    /// As `refit`, for a caller that has already written the new vertices into
    /// `geometry.positions` (and normals) in place: the deformers write straight into the
    /// BLAS, saving a copy of every vertex per frame.
    pub fn refit_geometry(&mut self) -> RefitOutcome {
        if self.bvh.nodes.is_empty() {
            return RefitOutcome::Refit;
        }
        // Rayon tasks of at least this many elements: a warden-sized mesh (5k triangles)
        // refits in one task (meshes themselves refit in parallel), a 100k-triangle one
        // spreads over the cores.
        const MIN_TASK: usize = 4096;
        // 1. Leaf-ordered triangles from the new positions.
        let geometry = &self.geometry;
        self.ordered
            .par_iter_mut()
            .zip(self.ordered_ids.par_iter())
            .with_min_len(MIN_TASK)
            .for_each(|(triangle, &id)| {
                let [a, b, c] = geometry.triangle_vertices(id as usize);
                *triangle = RtTriangle::new(a, b, c);
            });
        // 2. Leaf boxes, summing their SAH terms (area x triangles) on the way.
        let ordered = &self.ordered;
        let leaf_cost: f32 = self
            .bvh
            .nodes
            .par_iter_mut()
            .with_min_len(MIN_TASK)
            .filter(|node| node.is_leaf())
            .map(|leaf| {
                let first = leaf.first_index as usize;
                let mut aabb = Aabb::empty();
                for triangle in &ordered[first..first + leaf.prim_count as usize] {
                    aabb = aabb.union(&triangle.aabb());
                }
                leaf.set_aabb(aabb);
                aabb.half_area() * leaf.prim_count as f32
            })
            .sum();
        // 3. Inner boxes in one reverse sweep (the build ordered every child after its
        //    parent), summing their SAH terms: the quality check costs no extra pass.
        if !self.bvh.children_are_ordered_after_parents {
            // A static BLAS refit for the first time: put it in that order once.
            self.bvh.reorder_in_stack_traversal_order();
        }
        let nodes = &mut self.bvh.nodes;
        let mut inner_cost = 0.0f32;
        for index in (0..nodes.len()).rev() {
            let node = &nodes[index];
            if !node.is_leaf() {
                let first = node.first_index as usize;
                let aabb = nodes[first].aabb().union(nodes[first + 1].aabb());
                inner_cost += aabb.half_area();
                nodes[index].set_aabb(aabb);
            }
        }
        // 4. Rebuild when quality has decayed (same cost as `sah_cost`).
        let root_area = nodes[0].aabb().half_area().max(f32::MIN_POSITIVE);
        let cost = (leaf_cost + inner_cost) / root_area;
        if self.built_cost > 0.0 && cost / self.built_cost > REBUILD_RATIO {
            *self = Blas::build(std::mem::take(&mut self.geometry), self.kind);
            return RefitOutcome::Rebuilt;
        }
        RefitOutcome::Refit
    }

    /// Closest hit of an object-space ray within [tmin, tmax]: (t, triangle, barycentrics).
    #[inline]
    pub fn intersect<A: AlphaTest>(&self, ray: &ObvhsRay, alpha: &A) -> Option<(f32, u32, Vec2)> {
        if self.bvh.nodes.is_empty() {
            return None;
        }
        let mut hit = RayHit::none();
        let found = if self.ordered_alpha.is_empty() {
            self.bvh
                .ray_traverse(*ray, &mut hit, |ray, id| self.ordered[id].intersect(ray))
        } else {
            self.bvh.ray_traverse(*ray, &mut hit, |ray, id| {
                self.intersect_alpha(ray, id, alpha)
            })
        };
        if !found {
            return None;
        }
        let id = hit.primitive_id as usize;
        Some((
            hit.t,
            self.ordered_ids[id],
            barycentrics(&self.ordered[id], ray),
        ))
    }

    /// True when anything blocks the object-space ray within [tmin, tmax] (stops at the
    /// first hit found, not the closest).
    #[inline]
    pub fn occluded<A: AlphaTest>(&self, ray: &ObvhsRay, alpha: &A) -> bool {
        if self.bvh.nodes.is_empty() {
            return false;
        }
        let missed = if self.ordered_alpha.is_empty() {
            self.bvh
                .ray_traverse_miss(*ray, |ray, id| self.ordered[id].intersect(ray))
        } else {
            self.bvh
                .ray_traverse_miss(*ray, |ray, id| self.intersect_alpha(ray, id, alpha))
        };
        !missed
    }

    /// Triangle test that treats alpha-masked texels as holes.
    #[inline]
    fn intersect_alpha<A: AlphaTest>(&self, ray: &ObvhsRay, id: usize, alpha: &A) -> f32 {
        let t = self.ordered[id].intersect(ray);
        if t == f32::INFINITY || !self.ordered_alpha[id] {
            return t;
        }
        let triangle = self.ordered_ids[id] as usize;
        let uv = self
            .geometry
            .uv_at(triangle, barycentrics(&self.ordered[id], ray));
        if alpha.is_opaque(self.geometry.materials[triangle], uv) {
            t
        } else {
            f32::INFINITY
        }
    }
}
