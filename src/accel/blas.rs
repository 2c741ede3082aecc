//! Bottom-level BVHs: one per mesh, in the mesh's object space.
//!
//! Frame step `accel`, first half: static meshes are built once at load; deforming meshes
//! are refit every frame (leaf boxes in parallel, then a single bottom-up sweep) and rebuilt
//! when refitting has let the tree decay (its SAH cost past [`REBUILD_RATIO`] times its
//! last build's). Built on obvhs's `Bvh2` (PLOC + reinsertion +
//! leaf collapse; Meister & Bittner 2018, "Parallel Locally-Ordered Clustering for Bounding
//! Volume Hierarchy Construction"). Opaque meshes collapse it into an 8-wide BVH (`wide`),
//! which `gloam raybench` measures at about twice the BVH2's throughput; a deforming mesh
//! refits that wide tree in place, straight from its vertices. Alpha-tested meshes (which
//! need the per-triangle `AlphaTest`) trace the BVH2.
//!
//! Triangles are stored in BVH leaf order as `RtTriangle` (base vertex, two edges, normal):
//! the traversal closure indexes them directly, with no `primitive_indices` indirection.

use glam::{Vec2, Vec3, Vec3A};
use obvhs::BvhBuildParams;
use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;
use obvhs::bvh2::leaf_collapser::collapse;
use obvhs::bvh2::node::Bvh2Node;
use obvhs::bvh2::reinsertion::ReinsertionOptimizer;
use obvhs::ploc::PlocBuilder;
use obvhs::ray::{Ray as ObvhsRay, RayHit};
use obvhs::rt_triangle::RtTriangle;
use rayon::prelude::*;

use super::wide::{Kernels, WideBvh};
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
        interpolate_uv(self.triangles[triangle].map(|i| self.uvs[i as usize]), b)
    }
}

/// The UV at barycentrics (b1, b2) between a triangle's corners' `uvs`.
#[inline]
pub fn interpolate_uv([a, c, d]: [Vec2; 3], b: Vec2) -> Vec2 {
    a * (1.0 - b.x - b.y) + c * b.x + d * b.y
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

/// A BLAS hit whose triangle and barycentrics are not worked out yet.
#[derive(Clone, Copy, Debug)]
pub(crate) enum PendingHit {
    /// A slot of the wide tree (`WideBvh::triangle_at`).
    Wide(u32),
    /// Known already: (triangle, barycentrics).
    Known(u32, Vec2),
}

/// How a BLAS's rays are traced (`gloam raybench` measures each).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Traversal {
    /// The 8-wide BVH collapsed from the BVH2 (`wide`), with these kernels.
    Wide(Kernels),
    /// obvhs's own BVH2 traversal.
    Bvh2,
}

/// Rayon tasks of at least this many elements in refits: a warden-sized mesh (5k
/// triangles) refits in one task (meshes themselves refit in parallel), a 100k-triangle one
/// spreads over the cores.
const MIN_TASK: usize = 4096;

/// A bottom-level BVH with its triangles in leaf order.
#[derive(Clone)]
pub struct Blas {
    pub kind: BlasKind,
    pub geometry: MeshGeometry,
    /// Which tree rays walk (`set_traversal`); the wide one when there is one.
    traversal: Traversal,
    pub(crate) bvh: Bvh2,
    /// The BVH2 collapsed to 8-wide nodes, for meshes without alpha-tested triangles (None
    /// for those: they trace the BVH2).
    pub(crate) wide: Option<WideBvh>,
    /// `ordered` and the BVH2's boxes lag the mesh: refits went to the wide tree only
    /// (rays walk it), and `set_traversal` brings them up to date before rays walk the
    /// BVH2 instead.
    bvh_stale: bool,
    /// The wide tree's SAH cost right after the last build.
    built_wide_cost: f32,
    /// Triangles in BVH leaf order (`bvh.primitive_indices` applied).
    pub(crate) ordered: Vec<RtTriangle>,
    /// Original triangle index of each entry of `ordered`.
    pub(crate) ordered_ids: Vec<u32>,
    /// Alpha-tested flag per entry of `ordered`, or empty when no triangle is.
    ordered_alpha: Vec<bool>,
    /// SAH cost right after the last build (the reference for the rebuild policy).
    built_cost: f32,
    /// Refit scratch: the box of each entry of `ordered` (reused from frame to frame).
    triangle_boxes: Vec<Aabb>,
    /// Node ranges that each hold exactly the descendants of one subtree root, disjoint and
    /// sorted: refit sweeps them in parallel (empty: one sequential sweep). Topology never
    /// changes on refit, so they are found once per build.
    subtree_ranges: Vec<std::ops::Range<usize>>,
    /// SAH cost as the last refit's sweep summed it.
    refit_cost: f32,
}

impl Blas {
    pub fn build(geometry: MeshGeometry, kind: BlasKind) -> Blas {
        let params = match kind {
            // Static meshes are built once per level load and traced every frame: obvhs's
            // slow preset (PLOC search distance high, 20% of nodes reinserted; Meister &
            // Bittner 2018, "Parallel Reinsertion for Bounding Volume Hierarchy
            // Optimization") costs 298-337 against 151-172 ms for the 178k-triangle
            // apartment on one thread, and its wide tree traced 2-8% faster rays in three
            // runs (21-28% in a fourth; SAH cost 18.5 against 19.2; `gloam raybench
            // --build-study`): a few seconds of play repay it.
            BlasKind::Static => BvhBuildParams::slow_build(),
            // Refit trees keep their topology for many frames: the same quality preset,
            // but 1 triangle per leaf keeps refit boxes tight as triangles move apart.
            BlasKind::Deforming => BvhBuildParams {
                max_prims_per_leaf: 1,
                ..BvhBuildParams::medium_build()
            },
        };
        Self::build_with(geometry, kind, params)
    }

    /// A static BLAS built with obvhs's fast preset: for the few queries a fixed step asks
    /// (the simulation's copy of the level), where build time matters more than ray speed.
    pub fn build_for_queries(geometry: MeshGeometry) -> Blas {
        Self::build_with(geometry, BlasKind::Static, BvhBuildParams::fast_build())
    }

    fn build_with(geometry: MeshGeometry, kind: BlasKind, params: BvhBuildParams) -> Blas {
        let triangles: Vec<RtTriangle> = (0..geometry.triangles.len())
            .map(|t| {
                let [a, b, c] = geometry.triangle_vertices(t);
                RtTriangle::new(a, b, c)
            })
            .collect();
        // Rule: a triangle whose box is a point or an axis-aligned segment has no area, and
        // no ray hits it. PLOC pairs neighbours by the area of their union, and a long run of
        // ties at zero merges one pair per pass: a fuzzed GLB of 4,212 such triangles took
        // 2 s to build. Static trees leave them out; deforming ones keep every triangle,
        // since a refit may give one area.
        let (build_triangles, build_ids): (Vec<RtTriangle>, Vec<u32>) = triangles
            .iter()
            .zip(0u32..)
            .filter(|(triangle, _)| {
                kind == BlasKind::Deforming || triangle.aabb().half_area() > 0.0
            })
            .map(|(triangle, id)| (*triangle, id))
            .unzip();
        let mut bvh = if build_triangles.is_empty() {
            Bvh2::default()
        } else {
            build_bvh2(&build_triangles, &params)
        };
        // Rule: obvhs's PLOC makes each leaf's first index its primitive's id, which its
        // leaf collapse then reads as a place in `primitive_indices`: the two agree only for
        // ids 0..n. So the tree is built over the kept triangles' places, and their ids are
        // put in afterwards (ids given to PLOC sent a fuzzed GLB's collapse out of bounds).
        if build_ids.len() < triangles.len() {
            for id in &mut bvh.primitive_indices {
                *id = build_ids[*id as usize];
            }
        }
        if kind == BlasKind::Deforming {
            // Parents before children: `refit_all` then takes its single-sweep path (obvhs
            // measures it ~3x faster than the stack-ordered fallback).
            bvh.reorder_in_stack_traversal_order();
        }
        let ordered_ids = bvh.primitive_indices.clone();
        let ordered: Vec<RtTriangle> = ordered_ids.iter().map(|&i| triangles[i as usize]).collect();
        let ordered_alpha = if geometry.alpha_tested.iter().any(|&a| a) {
            ordered_ids
                .iter()
                .map(|&i| geometry.alpha_tested[i as usize])
                .collect()
        } else {
            Vec::new()
        };
        // Opaque meshes trace an 8-wide BVH; alpha-tested ones keep the BVH2, whose traversal
        // takes the per-triangle callback.
        let wide = ordered_alpha
            .is_empty()
            .then(|| WideBvh::build(&bvh, &ordered).ok())
            .flatten();
        let mut blas = Blas {
            kind,
            geometry,
            traversal: Traversal::Wide(Kernels::Best),
            built_wide_cost: wide.as_ref().map_or(0.0, WideBvh::sah_cost),
            wide,
            bvh_stale: false,
            bvh,
            ordered,
            ordered_ids,
            ordered_alpha,
            built_cost: 0.0,
            triangle_boxes: Vec::new(),
            subtree_ranges: Vec::new(),
            refit_cost: 0.0,
        };
        blas.built_cost = blas.bvh2_cost();
        blas
    }

    pub fn traversal(&self) -> Traversal {
        self.traversal
    }

    /// Chooses the tree rays walk (`gloam raybench` compares them); a BVH2 that refits left
    /// behind is brought up to date first.
    pub fn set_traversal(&mut self, traversal: Traversal) {
        self.traversal = traversal;
        if !self.uses_wide() && self.bvh_stale {
            self.refit_bvh2();
        }
    }

    /// Whether rays walk the wide tree.
    fn uses_wide(&self) -> bool {
        self.wide.is_some() && matches!(self.traversal, Traversal::Wide(_))
    }

    pub fn triangle_count(&self) -> usize {
        self.geometry.triangles.len()
    }

    /// Object-space bounds (empty for an empty mesh).
    pub fn bounds(&self) -> Aabb {
        match &self.wide {
            // The wide tree's: after a refit it is the one that is up to date.
            Some(wide) if self.uses_wide() && !self.bvh.nodes.is_empty() => {
                let (min, max) = wide.bounds();
                Aabb::new(min, max)
            }
            _ => self
                .bvh
                .nodes
                .first()
                .map_or(Aabb::empty(), |root| *root.aabb()),
        }
    }

    /// SAH cost of the tree relative to its root's area (Goldsmith & Salmon 1987;
    /// MacDonald & Booth 1990): sum of node areas times traversal cost (1) plus leaf areas
    /// times triangle count times intersection cost (1), over the root area.
    fn bvh2_cost(&self) -> f32 {
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

    /// SAH cost of the tree rays walk, relative to its root's area (`bvh2_cost`, or the
    /// wide tree's `WideBvh::sah_cost`).
    pub fn sah_cost(&self) -> f32 {
        match &self.wide {
            Some(wide) if self.uses_wide() => wide.sah_cost(),
            _ => self.bvh2_cost(),
        }
    }

    /// `sah_cost` right after the last build.
    fn built_cost(&self) -> f32 {
        if self.uses_wide() {
            self.built_wide_cost
        } else {
            self.built_cost
        }
    }

    /// Current cost over the cost right after the last build (1.0 = as good as built).
    pub fn quality_decay(&self) -> f32 {
        if self.built_cost() > 0.0 {
            self.sah_cost() / self.built_cost()
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
        // The triangles and boxes of the tree rays walk, its SAH cost summed on the way.
        let cost = match &mut self.wide {
            Some(wide) if matches!(self.traversal, Traversal::Wide(_)) => {
                // Straight from the mesh into the wide tree's blocks: the leaf-ordered copy
                // and the BVH2 wait until something needs them (`set_traversal`). Refit of
                // raybench's 100k-triangle grid on 2 threads: 1.31x the BVH2's refit time
                // through the copy, 1.14x like this (each pair timed in one run).
                // The blocks name each triangle by its index in the mesh.
                let (positions, triangles) = (&self.geometry.positions, &self.geometry.triangles);
                self.bvh_stale = true;
                let vertex = |i: u32| Vec3A::from(positions[i as usize]);
                wide.refit(|id| {
                    let [a, b, c] = triangles[id].map(vertex);
                    RtTriangle::new(a, b, c)
                })
            }
            _ => self.refit_bvh2(),
        };
        // 3. Rebuild when quality has decayed (same cost as `sah_cost`).
        self.refit_cost = cost;
        let built = self.built_cost();
        if built > 0.0 && cost / built > REBUILD_RATIO {
            let traversal = self.traversal;
            *self = Blas::build(std::mem::take(&mut self.geometry), self.kind);
            self.traversal = traversal;
            return RefitOutcome::Rebuilt;
        }
        RefitOutcome::Refit
    }

    /// Refits the BVH2 (and the leaf-ordered triangles it traces) to the mesh's positions;
    /// returns its `bvh2_cost`.
    fn refit_bvh2(&mut self) -> f32 {
        // 1. Leaf-ordered triangles and their boxes, one pass over the vertices (parallel).
        let geometry = &self.geometry;
        self.triangle_boxes
            .resize(self.ordered.len(), Aabb::empty());
        self.ordered
            .par_iter_mut()
            .zip(self.triangle_boxes.par_iter_mut())
            .zip(self.ordered_ids.par_iter())
            .with_min_len(MIN_TASK)
            .for_each(|((triangle, aabb), &id)| {
                let [a, b, c] = geometry.triangle_vertices(id as usize);
                *triangle = RtTriangle::new(a, b, c);
                *aabb = Aabb::new(a.min(b).min(c), a.max(b).max(c));
            });
        // 2. Every node's box in a reverse sweep (the build ordered every child after its
        //    parent), summing the SAH terms on the way, so the quality check costs no extra
        //    pass; leaves read their triangles' boxes from step 1.
        if !self.bvh.children_are_ordered_after_parents {
            // A static BLAS refit for the first time: put it in that order once.
            self.bvh.reorder_in_stack_traversal_order();
            self.subtree_ranges.clear();
        }
        if self.subtree_ranges.is_empty() && self.bvh.nodes.len() >= 8 * MIN_TASK {
            self.subtree_ranges = subtree_ranges(&self.bvh.nodes, 16);
        }
        // The subtrees below the top levels are swept in parallel, each range on its own
        // slice; then the few top nodes. Refit of raybench's 100k-triangle grid, 2 threads,
        // same run: 2.79 ms with obvhs's sequential `refit_all` plus separate leaf and SAH
        // passes, 1.43 ms like this.
        let boxes = &self.triangle_boxes;
        let nodes = &mut self.bvh.nodes;
        let mut pieces: Vec<(usize, &mut [Bvh2Node])> = Vec::new();
        let mut rest: &mut [Bvh2Node] = nodes;
        let mut consumed = 0;
        for range in &self.subtree_ranges {
            let (_, tail) = std::mem::take(&mut rest).split_at_mut(range.start - consumed);
            let (piece, tail) = tail.split_at_mut(range.len());
            pieces.push((range.start, piece));
            rest = tail;
            consumed = range.end;
        }
        let (mut leaf_cost, mut inner_cost) = pieces
            .par_iter_mut()
            .map(|(start, piece)| sweep(piece, *start, boxes, 0..piece.len(), &[]))
            .reduce(|| (0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
        let count = nodes.len();
        let top = sweep(nodes, 0, boxes, 0..count, &self.subtree_ranges);
        leaf_cost += top.0;
        inner_cost += top.1;
        self.bvh_stale = false;
        let root_area = nodes[0].aabb().half_area().max(f32::MIN_POSITIVE);
        (leaf_cost + inner_cost) / root_area
    }

    /// Closest hit of an object-space ray within [tmin, tmax]: (t, triangle, barycentrics).
    #[inline]
    pub fn intersect<A: AlphaTest>(&self, ray: &ObvhsRay, alpha: &A) -> Option<(f32, u32, Vec2)> {
        let (t, pending) = self.intersect_pending(ray, alpha)?;
        let (triangle, barycentrics) = self.resolve(pending, ray.origin, ray.direction);
        Some((t, triangle, barycentrics))
    }

    /// `intersect`, leaving the triangle's id and barycentrics for `resolve`: a ray through
    /// several instances needs them only for the last, closest hit.
    #[inline]
    pub(crate) fn intersect_pending<A: AlphaTest>(
        &self,
        ray: &ObvhsRay,
        alpha: &A,
    ) -> Option<(f32, PendingHit)> {
        if self.bvh.nodes.is_empty() {
            return None;
        }
        if let (Some(wide), Traversal::Wide(kernels)) = (&self.wide, self.traversal) {
            let (t, slot) = wide.intersect_slot(ray, kernels)?;
            return Some((t, PendingHit::Wide(slot)));
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
            PendingHit::Known(
                self.ordered_ids[id],
                barycentrics(&self.ordered[id], ray.origin, ray.direction),
            ),
        ))
    }

    /// The triangle and barycentrics of a hit `intersect_pending` (or a packet query) found
    /// for the object-space ray from `origin` along `direction`.
    #[inline]
    pub(crate) fn resolve(
        &self,
        pending: PendingHit,
        origin: Vec3A,
        direction: Vec3A,
    ) -> (u32, Vec2) {
        match (pending, &self.wide) {
            (PendingHit::Known(triangle, barycentrics), _) => (triangle, barycentrics),
            (PendingHit::Wide(slot), Some(wide)) => {
                let (id, triangle) = wide.triangle_at(slot);
                (id, barycentrics(&triangle, origin, direction))
            }
            (PendingHit::Wide(_), None) => unreachable!("a wide-tree hit from a BLAS without one"),
        }
    }

    /// The tree packets of rays walk, when rays walk the wide tree (alpha-tested BLASes and
    /// the BVH2 traversal take rays one at a time).
    #[inline]
    pub(crate) fn packet_tree(&self) -> Option<(&WideBvh, Kernels)> {
        match (&self.wide, self.traversal) {
            (Some(wide), Traversal::Wide(kernels)) => Some((wide, kernels)),
            _ => None,
        }
    }

    /// True when anything blocks the object-space ray within [tmin, tmax] (stops at the
    /// first hit found, not the closest).
    #[inline]
    pub fn occluded<A: AlphaTest>(&self, ray: &ObvhsRay, alpha: &A) -> bool {
        if self.bvh.nodes.is_empty() {
            return false;
        }
        if let (Some(wide), Traversal::Wide(kernels)) = (&self.wide, self.traversal) {
            return wide.occluded(ray, kernels);
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
        let uv = self.geometry.uv_at(
            triangle,
            barycentrics(&self.ordered[id], ray.origin, ray.direction),
        );
        if alpha.is_opaque(self.geometry.materials[triangle], uv) {
            t
        } else {
            f32::INFINITY
        }
    }
}

/// Bottom-up refit of `nodes[local]` for `local` in `within` (reversed), where `nodes` is the
/// slice starting at global index `offset`, skipping the global `skip` ranges (sorted; swept
/// already). Returns the SAH terms (leaf area x triangles, inner area) of the nodes swept.
fn sweep(
    nodes: &mut [Bvh2Node],
    offset: usize,
    boxes: &[Aabb],
    within: std::ops::Range<usize>,
    skip: &[std::ops::Range<usize>],
) -> (f32, f32) {
    let (mut leaf_cost, mut inner_cost) = (0.0f32, 0.0f32);
    let mut skip = skip.iter().rev().peekable();
    let mut local = within.end;
    while local > within.start {
        local -= 1;
        // Jump over a range already swept (children always sit after their parent, so a
        // range ending here holds no ancestor of what is left).
        if let Some(range) = skip.peek()
            && offset + local < range.end
            && offset + local >= range.start
        {
            local = range.start - offset;
            skip.next();
            continue;
        }
        let node = &nodes[local];
        let first = node.first_index as usize;
        let aabb = if node.is_leaf() {
            let count = node.prim_count as usize;
            let aabb = boxes[first..first + count]
                .iter()
                .fold(Aabb::empty(), |sum, b| sum.union(b));
            leaf_cost += aabb.half_area() * count as f32;
            aabb
        } else {
            let child = first - offset;
            let aabb = nodes[child].aabb().union(nodes[child + 1].aabb());
            inner_cost += aabb.half_area();
            aabb
        };
        nodes[local].set_aabb(aabb);
    }
    (leaf_cost, inner_cost)
}

/// Up to about `wanted` subtree roots below the root (breadth first), each as the range of
/// node indices holding exactly its descendants. Empty when the layout does not keep every
/// such subtree contiguous (then refit sweeps sequentially).
fn subtree_ranges(nodes: &[Bvh2Node], wanted: usize) -> Vec<std::ops::Range<usize>> {
    let mut frontier = vec![0usize];
    while frontier.len() < wanted {
        let next: Vec<usize> = frontier
            .iter()
            .flat_map(|&n| {
                let node = &nodes[n];
                if node.is_leaf() {
                    vec![n]
                } else {
                    vec![node.first_index as usize, node.first_index as usize + 1]
                }
            })
            .collect();
        if next.len() == frontier.len() {
            break;
        }
        frontier = next;
    }
    let mut ranges = Vec::new();
    for &root in &frontier {
        if nodes[root].is_leaf() {
            continue;
        }
        let (mut low, mut high, mut count) = (usize::MAX, 0usize, 0usize);
        let mut stack = vec![nodes[root].first_index as usize];
        while let Some(pair) = stack.pop() {
            for child in [pair, pair + 1] {
                low = low.min(child);
                high = high.max(child);
                count += 1;
                if !nodes[child].is_leaf() {
                    stack.push(nodes[child].first_index as usize);
                }
            }
        }
        if high + 1 - low != count || low <= root {
            return Vec::new();
        }
        ranges.push(low..high + 1);
    }
    ranges.sort_by_key(|r| r.start);
    if ranges.windows(2).any(|w| w[0].end > w[1].start) {
        return Vec::new();
    }
    ranges
}

/// obvhs's BVH2 build, its steps as its `build_bvh2` takes them (PLOC, reinsertion, leaf
/// collapse, reinsertion again; Meister & Bittner 2018), with the traversal stack sized for
/// the tree built. Rule: obvhs's traversals size their stacks by `Bvh2::max_depth` (96
/// levels unless told, and what its reinsertion finds while it runs), and a full stack
/// overwrites its top, dropping a subtree; a fuzzed GLB's mesh came out 106 levels deep
/// against the 104 obvhs had set, so `max_depth` is set from the tree built. (obvhs's own
/// helper asserts the depth instead, in builds with debug assertions: a panic on a bad
/// file.)
fn build_bvh2(triangles: &[RtTriangle], params: &BvhBuildParams) -> Bvh2 {
    let mut bvh = PlocBuilder::with_capacity(triangles.len()).build(
        params.ploc_search_distance,
        triangles,
        (0..triangles.len() as u32).collect(),
        params.sort_precision,
        params.search_depth_threshold,
    );
    let mut reinsertion = ReinsertionOptimizer::default();
    reinsertion.run(&mut bvh, params.reinsertion_batch_ratio, None);
    collapse(
        &mut bvh,
        params.max_prims_per_leaf.clamp(1, 255),
        params.collapse_traversal_cost,
    );
    reinsertion.run(
        &mut bvh,
        params.reinsertion_batch_ratio * params.post_collapse_reinsertion_batch_ratio_multiplier,
        None,
    );
    bvh.max_depth = bvh.max_depth.max(tree_depth(&bvh) + 1);
    bvh
}

/// Levels from the root to the deepest leaf (1 for a lone leaf), walked without recursion:
/// a degenerate tree can be as deep as it has primitives.
fn tree_depth(bvh: &Bvh2) -> usize {
    let Some(root) = bvh.nodes.first() else {
        return 0;
    };
    let mut deepest = 0;
    let mut pending = vec![(root, 1)];
    while let Some((node, depth)) = pending.pop() {
        deepest = deepest.max(depth);
        if !node.is_leaf() {
            let first = node.first_index as usize;
            pending.extend(
                [first, first + 1]
                    .iter()
                    .filter_map(|&child| bvh.nodes.get(child))
                    .map(|child| (child, depth + 1)),
            );
        }
    }
    deepest
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 2-triangles-per-cell height field of `cells` x `cells` cells with heights from `height`.
    fn grid(cells: u32, height: impl Fn(f32, f32) -> f32) -> MeshGeometry {
        let mut geometry = MeshGeometry::default();
        for row in 0..=cells {
            for column in 0..=cells {
                let (x, z) = (column as f32 * 0.1, row as f32 * 0.1);
                geometry.positions.push(Vec3::new(x, height(x, z), z));
            }
        }
        let at = |row: u32, column: u32| row * (cells + 1) + column;
        for row in 0..cells {
            for column in 0..cells {
                let (a, b, c, d) = (
                    at(row, column),
                    at(row, column + 1),
                    at(row + 1, column),
                    at(row + 1, column + 1),
                );
                geometry.triangles.push([a, c, b]);
                geometry.triangles.push([b, c, d]);
            }
        }
        geometry.materials = vec![0; geometry.triangles.len()];
        geometry
    }

    /// Every node's box recomputed from scratch, recursively.
    fn expected_box(blas: &Blas, node: usize) -> Aabb {
        let n = &blas.bvh.nodes[node];
        if n.is_leaf() {
            let first = n.first_index as usize;
            blas.ordered_ids[first..first + n.prim_count as usize]
                .iter()
                .map(|&t| {
                    let [a, b, c] = blas.geometry.triangle_vertices(t as usize);
                    Aabb::new(a.min(b).min(c), a.max(b).max(c))
                })
                .fold(Aabb::empty(), |sum, b| sum.union(&b))
        } else {
            let first = n.first_index as usize;
            expected_box(blas, first).union(&expected_box(blas, first + 1))
        }
    }

    /// Triangles nested like a telescope (each 1.25 times the one before, centred on the
    /// axis and farther off) build a tree deeper than obvhs's default 96-level traversal
    /// stack (136 levels): the stack is sized for the tree built (`build_bvh2`'s rule; a
    /// fuzzed file broke it by two levels, here the build's own reinsertion keeps it), and
    /// a ray down the axis still finds the smallest, nearest triangle through obvhs's BVH2
    /// walk.
    #[test]
    fn a_tree_deeper_than_the_default_stack_is_walked_whole() {
        let mut geometry = MeshGeometry::default();
        for i in 0..300 {
            let size = 1.25f32.powi(i);
            let z = -size;
            let base = geometry.positions.len() as u32;
            geometry.positions.extend([
                Vec3::new(-size, -size, z),
                Vec3::new(size, -size, z),
                Vec3::new(0.0, size, z),
            ]);
            geometry.triangles.push([base, base + 1, base + 2]);
        }
        geometry.materials = vec![0; geometry.triangles.len()];
        let mut blas = Blas::build(geometry, BlasKind::Static);
        let depth = tree_depth(&blas.bvh);
        assert!(depth > 96, "the tree is {depth} levels deep");
        assert!(blas.bvh.max_depth > depth, "{} levels", blas.bvh.max_depth);
        blas.set_traversal(Traversal::Bvh2);
        let ray = ObvhsRay::new_inf(Vec3A::ZERO, Vec3A::NEG_Z);
        let (t, triangle, _) = blas.intersect(&ray, &crate::accel::Opaque).unwrap();
        assert_eq!((t, triangle), (1.0, 0));
    }

    /// Triangles with no area (a point, a segment along an axis) stay out of static trees,
    /// which rays still find the one real triangle in; deforming trees keep them all.
    #[test]
    fn triangles_without_area_stay_out_of_static_trees() {
        let mut geometry = MeshGeometry::default();
        geometry.positions.extend([
            Vec3::new(-1.0, -1.0, -2.0),
            Vec3::new(1.0, -1.0, -2.0),
            Vec3::new(0.0, 1.0, -2.0),
            Vec3::new(0.5, 0.5, -1.0),
            Vec3::new(0.5, 0.5, -3.0),
        ]);
        geometry.triangles.push([0, 1, 2]);
        for i in 0..1000 {
            // Points, and segments along z through the real triangle's plane.
            geometry
                .triangles
                .push(if i % 2 == 0 { [3, 3, 3] } else { [3, 4, 3] });
        }
        geometry.materials = vec![0; geometry.triangles.len()];
        let deforming = Blas::build(geometry.clone(), BlasKind::Deforming);
        assert_eq!(deforming.ordered_ids.len(), 1001);
        let blas = Blas::build(geometry, BlasKind::Static);
        assert_eq!(blas.ordered_ids, [0]);
        assert_eq!(blas.triangle_count(), 1001);
        let ray = ObvhsRay::new_inf(Vec3A::new(0.0, 0.0, 0.0), Vec3A::NEG_Z);
        let (t, triangle, _) = blas.intersect(&ray, &crate::accel::Opaque).unwrap();
        assert_eq!((t, triangle), (2.0, 0));
    }

    /// Triangles with no area between real ones: every real triangle stays in the static
    /// tree under its own id, and a ray down onto its centre finds it, through both the
    /// BVH2 and the wide tree.
    #[test]
    fn triangles_without_area_between_real_ones_leave_every_real_one_found() {
        let flat = grid(10, |_, _| 0.0);
        let mut geometry = flat.clone();
        geometry.triangles.clear();
        let segment_start = geometry.positions.len() as u32;
        geometry
            .positions
            .extend([Vec3::new(0.05, 0.0, 0.05), Vec3::new(0.05, 0.0, 0.95)]);
        let mut real = Vec::new();
        for (i, triangle) in flat.triangles.iter().enumerate() {
            // A segment along z before each real triangle, and a point after every third.
            geometry
                .triangles
                .push([segment_start, segment_start + 1, segment_start]);
            real.push(geometry.triangles.len() as u32);
            geometry.triangles.push(*triangle);
            if i % 3 == 0 {
                geometry.triangles.push([triangle[2]; 3]);
            }
        }
        geometry.materials = vec![0; geometry.triangles.len()];
        let mut blas = Blas::build(geometry, BlasKind::Static);
        let mut kept = blas.ordered_ids.clone();
        kept.sort_unstable();
        assert_eq!(kept, real);
        for traversal in [Traversal::Bvh2, Traversal::Wide(Kernels::Best)] {
            blas.set_traversal(traversal);
            for &id in &real {
                let [a, b, c] = blas.geometry.triangle_vertices(id as usize);
                let centre = (a + b + c) / 3.0;
                let ray = ObvhsRay::new_inf(centre + Vec3A::Y, Vec3A::NEG_Y);
                let (t, triangle, _) = blas.intersect(&ray, &crate::accel::Opaque).unwrap();
                assert_eq!(triangle, id, "{traversal:?}");
                assert!((t - 1.0).abs() < 1e-6, "{traversal:?}: t = {t}");
            }
        }
    }

    #[test]
    fn parallel_subtree_refit_gives_every_node_its_exact_box() {
        // 2 x 150^2 = 45,000 triangles: enough nodes for the parallel sweep.
        let mut blas = Blas::build(
            grid(150, |x, z| (x * 7.0).sin() * (z * 5.0).cos() * 0.3),
            BlasKind::Deforming,
        );
        // This test is about the BVH2's refit; rays would walk the wide tree by default.
        blas.set_traversal(Traversal::Bvh2);
        let moved: Vec<Vec3> = blas
            .geometry
            .positions
            .iter()
            .map(|p| Vec3::new(p.x, (p.x * 7.0 + 0.4).sin() * (p.z * 5.0).cos() * 0.3, p.z))
            .collect();
        assert_eq!(blas.refit(&moved, None), RefitOutcome::Refit);
        assert!(
            blas.subtree_ranges.len() >= 8,
            "the parallel path ran ({} ranges)",
            blas.subtree_ranges.len()
        );
        for node in 0..blas.bvh.nodes.len() {
            let expected = expected_box(&blas, node);
            let actual = blas.bvh.nodes[node].aabb();
            assert!(
                actual.min == expected.min && actual.max == expected.max,
                "node {node}: {actual:?} vs {expected:?}"
            );
        }
        // The SAH cost the sweep summed is the one `sah_cost` computes.
        let fresh = blas.bvh2_cost();
        assert!(
            (blas.refit_cost - fresh).abs() <= 1e-4 * fresh,
            "{} vs {fresh}",
            blas.refit_cost
        );
    }
}
