//! Frame step `accel`, inside a BLAS: the 8-wide BVH that rays actually traverse.
//!
//! Built once per BLAS build by collapsing obvhs's SAH-built BVH2 (Wald, Benthin & Boulos
//! 2008, "Getting Rid of Packets: Efficient SIMD Single-Ray Traversal using Multi-branching
//! BVHs"): a wide node starts from a BVH2 node's two children and repeatedly opens the
//! inner child of largest surface area, the one a random ray is likeliest to enter, until it
//! has 8 children. Each BVH2 leaf, and each subtree of at most 8 triangles, becomes one
//! `TriangleBlock`, 8 triangles as SoA lanes (so a BVH2 built without obvhs's own leaf
//! collapse gives the same tree, sooner: `WideBvh::source_params`). A block names each
//! triangle by its index in the mesh.
//!
//! The build then orders each node's children for shadow rays: an any-hit walk goes on into
//! the highest hit lane first, so the build puts there the child likeliest to block a ray
//! for what its walk costs (`WideBvh::order_for_occlusion`).
//!
//! Per ray: one AVX2 slab test of a node's 8 child boxes, the hit children visited nearest
//! first (sorted by entry distance; an any-hit walk takes them in lane order, highest
//! first), and one AVX2 Moller-Trumbore test (Moller & Trumbore 1997) of a leaf's 8
//! triangles. Rays that start on a surface are offset off it by
//! `Ray::spawn` before they get here, so the test needs no epsilon: t must lie in
//! (t_min, t_max), and a ray in a triangle's plane (determinant zero) misses it.
//!
//! Every kernel has a portable twin written to do the same IEEE operations in the same order
//! (no FMA anywhere: Rust never contracts a * b + c, and the AVX2 code does not either), so
//! a machine without AVX2, or an aarch64 one, finds bit-identical hits.
//!
//! Deforming meshes refit the wide nodes in place, children before parents, the topology
//! unchanged (`refit`).

use std::mem::MaybeUninit;

use glam::Vec3A;
use obvhs::BvhBuildParams;
use obvhs::bvh2::Bvh2;
use obvhs::ray::Ray as ObvhsRay;
use obvhs::rt_triangle::RtTriangle;

use super::prefetch;

/// Children per node and triangles per block.
pub(crate) const WIDTH: usize = 8;

/// A child slot with nothing in it.
pub(super) const EMPTY: u32 = u32::MAX;
/// Set on a child reference that names a leaf (a range of triangle blocks).
pub(super) const LEAF: u32 = 1 << 31;
/// Leaf references: block index in the low bits, block count - 1 in these three.
const LEAF_COUNT_SHIFT: u32 = 28;
const MAX_LEAF_BLOCKS: usize = 8;

/// Entries on the traversal stack. A node pushes at most 7 (it continues into the 8th), so
/// this holds a tree 145 nodes deep; `WideBvh::build` refuses deeper trees (rule: every
/// tree built passes `depth * 7 + 1 <= STACK`, so the traversal never checks).
pub(super) const STACK: usize = 1024;

/// Far distances are widened by this factor so a box whose entry and exit round to the same
/// t, or a triangle lying on its box's face, is not missed (Ize 2013, "Robust BVH Ray
/// Traversal": 1 + 2 gamma(3)).
pub(super) const ROBUST_FAR: f32 = 1.0 + 2.0 * 3.0 * f32::EPSILON * 0.5;

/// Eight child boxes as lanes: `bounds[axis]` are the minima, `bounds[3 + axis]` the
/// maxima. Empty lanes hold an inverted box (+inf, -inf) that no ray enters.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
pub(crate) struct WideNode {
    pub(super) bounds: [[f32; WIDTH]; 6],
    pub(super) children: [u32; WIDTH],
}

impl WideNode {
    const EMPTY: WideNode = WideNode {
        bounds: [
            [f32::INFINITY; WIDTH],
            [f32::INFINITY; WIDTH],
            [f32::INFINITY; WIDTH],
            [f32::NEG_INFINITY; WIDTH],
            [f32::NEG_INFINITY; WIDTH],
            [f32::NEG_INFINITY; WIDTH],
        ],
        children: [EMPTY; WIDTH],
    };

    fn set_box(&mut self, lane: usize, min: Vec3A, max: Vec3A) {
        for axis in 0..3 {
            self.bounds[axis][lane] = min[axis];
            self.bounds[3 + axis][lane] = max[axis];
        }
    }

    /// The union of the node's children's boxes.
    fn union(&self) -> (Vec3A, Vec3A) {
        let mut min = Vec3A::INFINITY;
        let mut max = Vec3A::NEG_INFINITY;
        for lane in 0..WIDTH {
            if self.children[lane] != EMPTY {
                min = min.min(Vec3A::new(
                    self.bounds[0][lane],
                    self.bounds[1][lane],
                    self.bounds[2][lane],
                ));
                max = max.max(Vec3A::new(
                    self.bounds[3][lane],
                    self.bounds[4][lane],
                    self.bounds[5][lane],
                ));
            }
        }
        (min, max)
    }
}

/// Eight triangles as lanes, as obvhs's `RtTriangle` keeps one: base vertex v0, edges
/// e1 = v0 - v1 and e2 = v2 - v0, and the unnormalised normal ng = e1 x e2. The lane test
/// repeats `RtTriangle::intersect`'s arithmetic operation for operation, so the wide tree
/// finds the very hits (to the bit) of obvhs's BVH2 and of a brute-force loop over
/// `RtTriangle`s. Unused lanes hold NaN, which fails every comparison, so they never hit.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
pub(crate) struct TriangleBlock {
    /// v0 x, y, z, e1 x, y, z, e2 x, y, z, ng x, y, z.
    pub(super) planes: [[f32; WIDTH]; 12],
    /// Per lane, the triangle's index in the mesh the BVH2 was built over (its
    /// `primitive_indices` entry; `EMPTY` for unused lanes). The mesh's own index rather than
    /// the leaf order's: a hit then names its triangle without a lookup in a table as large
    /// as the mesh, a likely cache miss per incoherent ray (dream-apartment's bounces: 190
    /// against 176 ns a ray through that table, in one run).
    pub(super) ids: [u32; WIDTH],
}

impl TriangleBlock {
    const EMPTY: TriangleBlock = TriangleBlock {
        planes: [[f32::NAN; WIDTH]; 12],
        ids: [EMPTY; WIDTH],
    };

    fn set(&mut self, lane: usize, id: u32, triangle: &RtTriangle) {
        for axis in 0..3 {
            self.planes[axis][lane] = triangle.v0[axis];
            self.planes[3 + axis][lane] = triangle.e1[axis];
            self.planes[6 + axis][lane] = triangle.e2[axis];
            self.planes[9 + axis][lane] = triangle.ng[axis];
        }
        self.ids[lane] = id;
    }
}

/// Which kernels a traversal runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kernels {
    /// AVX2 where the CPU has it and `simd::kernels` allows it, else portable.
    Best,
    /// Plain Rust (what a CPU without AVX2, or aarch64, runs).
    Portable,
}

impl Kernels {
    pub(super) fn avx2(self) -> bool {
        self == Kernels::Best && crate::simd::avx2()
    }
}

/// An 8-wide BVH over a BLAS's triangles (blocks in the BVH2's leaf order, each triangle
/// named by its index in the mesh).
#[derive(Clone, Debug, Default)]
pub struct WideBvh {
    /// Node 0 is the root; every node comes before its children (so a reverse sweep refits).
    pub(super) nodes: Vec<WideNode>,
    pub(super) blocks: Vec<TriangleBlock>,
    /// Levels of nodes (the root is 1).
    depth: usize,
    /// Refit scratch, per block: its box and how many lanes it uses.
    block_bounds: Vec<(Vec3A, Vec3A, u32)>,
}

/// What an any-hit walk of a subtree comes to, for a ray that enters its box: how likely
/// it is blocked there, and the tests it takes on average (`WideBvh::order_for_occlusion`).
#[derive(Clone, Copy, Debug)]
struct Occlusion {
    blocked: f32,
    cost: f32,
}

impl Occlusion {
    const CLEAR: Occlusion = Occlusion {
        blocked: 0.0,
        cost: 0.0,
    };
    /// A node's test and a block's cost about the same: one 8-lane kernel each.
    const NODE_COST: f32 = 1.0;
    const BLOCK_COST: f32 = 1.0;
}

/// Half the surface area of a box (zero for an empty one).
fn half_area(min: Vec3A, max: Vec3A) -> f32 {
    let d = (max - min).max(Vec3A::ZERO);
    d.x * d.y + d.y * d.z + d.z * d.x
}

/// Why a BVH2 was not collapsed (the BLAS keeps tracing its BVH2).
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum CollapseError {
    #[error("the tree is {0} levels deep, more than the traversal stack holds")]
    TooDeep(usize),
    #[error("a leaf holds {0} triangles, more than 64")]
    LeafTooLarge(usize),
}

/// How many queued nodes ahead of the one being read a walk over a BVH2 fetches.
const PREFETCH_AHEAD: usize = 16;

/// The BVH2 being collapsed, with the triangle count under each of its nodes and the
/// triangles of each wide leaf it holds.
struct Source<'a> {
    bvh: &'a Bvh2,
    ordered: &'a [RtTriangle],
    triangles_below: Vec<u32>,
    /// The leaf-order slots of the triangles under each wide leaf (`is_wide_leaf` nodes
    /// whose parent is not one), each wide leaf's as one run.
    leaf_slots: Vec<u32>,
    /// Per such node, where its run in `leaf_slots` ends (it is `triangles_below` long).
    leaf_slots_end: Vec<u32>,
}

impl<'a> Source<'a> {
    fn new(bvh: &'a Bvh2, ordered: &'a [RtTriangle]) -> Source<'a> {
        let nodes = &bvh.nodes;
        // 1. Parents before children, breadth first: each node as (index, first child or
        //    first triangle slot, triangles in it for a leaf or INNER). Breadth first, the
        //    nodes to read next are already queued, so they are fetched ahead of use; a
        //    depth-first walk waits on every node's load in turn (after reinsertion the
        //    nodes lie scattered in memory), and took 60% of this function.
        const INNER: u32 = u32::MAX;
        let mut order: Vec<(u32, u32, u32)> = Vec::with_capacity(nodes.len());
        let mut queued: Vec<u32> = Vec::with_capacity(nodes.len());
        queued.push(0);
        let mut next = 0;
        while next < queued.len() {
            if let Some(&ahead) = queued.get(next + PREFETCH_AHEAD) {
                prefetch(&nodes[ahead as usize]);
            }
            let index = queued[next];
            next += 1;
            let node = &nodes[index as usize];
            if node.is_leaf() {
                order.push((index, node.first_index, node.prim_count));
            } else {
                order.push((index, node.first_index, INNER));
                queued.extend([node.first_index, node.first_index + 1]);
            }
        }
        // 2. Counted in reverse: children before parents.
        let mut triangles_below = vec![0u32; nodes.len()];
        for &(index, first, count) in order.iter().rev() {
            triangles_below[index as usize] = if count != INNER {
                count
            } else {
                triangles_below[first as usize] + triangles_below[first as usize + 1]
            };
        }
        // 3. Forward again, each wide leaf's triangles into one run: a node inside a wide
        //    leaf is owned by its top node, and a BVH2 leaf adds its slots to its owner's
        //    run. (Gathering them per wide leaf by a walk of its subtree, every load waiting
        //    on its parent's, took a quarter of the collapse.)
        const NONE: u32 = u32::MAX;
        let mut owner = vec![NONE; nodes.len()];
        let mut leaf_slots_end = vec![0u32; nodes.len()];
        let mut leaf_slots = vec![0u32; bvh.primitive_indices.len()];
        let mut runs_end = 0u32;
        for &(index, first, count) in &order {
            let (index, is_leaf) = (index as usize, count != INNER);
            let below = triangles_below[index];
            let mut own = owner[index];
            if own == NONE && (is_leaf || below as usize <= WIDTH) {
                // The top of a wide leaf: its run starts here.
                own = index as u32;
                leaf_slots_end[index] = runs_end;
                runs_end += below;
            }
            if is_leaf {
                if own != NONE {
                    let end = &mut leaf_slots_end[own as usize];
                    let start = *end as usize;
                    for (slot, id) in leaf_slots[start..start + count as usize]
                        .iter_mut()
                        .zip(first..)
                    {
                        *slot = id;
                    }
                    *end += count;
                }
            } else if own != NONE {
                owner[first as usize] = own;
                owner[first as usize + 1] = own;
            }
        }
        leaf_slots.truncate(runs_end as usize);
        Source {
            bvh,
            ordered,
            triangles_below,
            leaf_slots,
            leaf_slots_end,
        }
    }

    /// Whether BVH2 node `node` becomes one wide leaf: a BVH2 leaf, or a subtree small enough
    /// for one block (its 8 triangles cost one SIMD test, less than the nodes above them).
    fn is_wide_leaf(&self, node: usize) -> bool {
        self.bvh.nodes[node].is_leaf() || self.triangles_below[node] as usize <= WIDTH
    }

    /// The leaf-order slots of the triangles under `node`, the top of a wide leaf.
    fn wide_leaf_slots(&self, node: usize) -> &[u32] {
        let end = self.leaf_slots_end[node] as usize;
        &self.leaf_slots[end - self.triangles_below[node] as usize..end]
    }
}

/// What a collapse makes of a BVH2's leaves: triangle blocks (a BLAS) or instance ranges
/// (the TLAS).
trait LeafMaker {
    fn bvh(&self) -> &Bvh2;
    /// Whether BVH2 node `node` becomes one wide leaf.
    fn is_leaf(&self, node: usize) -> bool;
    /// The child reference of the leaf made of `node`.
    fn leaf(&mut self, node: usize) -> Result<u32, CollapseError>;
}

/// A BLAS's leaves: blocks of its triangles.
struct TriangleLeaves<'a, 'b> {
    source: &'b Source<'a>,
    blocks: &'b mut Vec<TriangleBlock>,
}

impl LeafMaker for TriangleLeaves<'_, '_> {
    fn bvh(&self) -> &Bvh2 {
        self.source.bvh
    }

    fn is_leaf(&self, node: usize) -> bool {
        self.source.is_wide_leaf(node)
    }

    /// Blocks for the triangles under BVH2 node `node`.
    fn leaf(&mut self, node: usize) -> Result<u32, CollapseError> {
        let ids = self.source.wide_leaf_slots(node);
        let block_count = ids.len().div_ceil(WIDTH).max(1);
        if block_count > MAX_LEAF_BLOCKS {
            return Err(CollapseError::LeafTooLarge(ids.len()));
        }
        let first_block = self.blocks.len();
        // Blocks are filled where they lie: built on the stack and pushed, each 416-byte
        // block was copied once more (with a fresh id list per leaf, 25% of the collapse).
        self.blocks
            .resize(first_block + block_count, TriangleBlock::EMPTY);
        for (block, block_ids) in self.blocks[first_block..].iter_mut().zip(ids.chunks(WIDTH)) {
            for (lane, &id) in block_ids.iter().enumerate() {
                let mesh_index = self.source.bvh.primitive_indices[id as usize];
                block.set(lane, mesh_index, &self.source.ordered[id as usize]);
            }
        }
        Ok(LEAF | ((block_count as u32 - 1) << LEAF_COUNT_SHIFT) | first_block as u32)
    }
}

/// Collapses `leaves.bvh()` into `nodes` (cleared first); returns the depth.
fn collapse_tree(
    nodes: &mut Vec<WideNode>,
    leaves: &mut impl LeafMaker,
) -> Result<usize, CollapseError> {
    nodes.clear();
    let Some(root) = leaves.bvh().nodes.first().copied() else {
        return Ok(0);
    };
    nodes.push(WideNode::EMPTY);
    if leaves.is_leaf(0) {
        // A one-leaf tree: a root with a single leaf child.
        nodes[0].children[0] = leaves.leaf(0)?;
        nodes[0].set_box(0, root.aabb.min, root.aabb.max);
        return Ok(1);
    }
    collapse_node(nodes, leaves, 0, 0, 1)
}

/// Fills wide node `target` from BVH2 inner node `node`; returns the depth below.
fn collapse_node(
    nodes: &mut Vec<WideNode>,
    leaves: &mut impl LeafMaker,
    node: usize,
    target: usize,
    depth: usize,
) -> Result<usize, CollapseError> {
    if depth * (WIDTH - 1) + 1 > STACK {
        return Err(CollapseError::TooDeep(depth));
    }
    // Open the largest child that is not a wide leaf until there are 8 (Wald et al.
    // 2008's greedy rule: the largest box is the one a ray is likeliest to enter).
    let first = leaves.bvh().nodes[node].first_index as usize;
    let mut children = [0usize; WIDTH];
    children[..2].copy_from_slice(&[first, first + 1]);
    let mut count = 2;
    while count < WIDTH {
        let bvh = leaves.bvh();
        let largest = (0..count)
            .filter(|&slot| !leaves.is_leaf(children[slot]))
            .max_by(|&a, &b| {
                let area = |slot: usize| bvh.nodes[children[slot]].aabb.half_area();
                area(a).total_cmp(&area(b))
            });
        let Some(slot) = largest else { break };
        let grand = bvh.nodes[children[slot]].first_index as usize;
        children[slot] = grand;
        children[count] = grand + 1;
        count += 1;
    }
    // Inner children are allocated together, so siblings sit side by side in memory.
    let mut deepest = depth;
    let mut inner = [(0usize, 0usize); WIDTH];
    let mut inner_count = 0;
    for (lane, &child) in children[..count].iter().enumerate() {
        let aabb = leaves.bvh().nodes[child].aabb;
        nodes[target].set_box(lane, aabb.min, aabb.max);
        if leaves.is_leaf(child) {
            nodes[target].children[lane] = leaves.leaf(child)?;
        } else {
            let index = nodes.len();
            nodes.push(WideNode::EMPTY);
            nodes[target].children[lane] = index as u32;
            inner[inner_count] = (child, index);
            inner_count += 1;
        }
    }
    for &(child, index) in &inner[..inner_count] {
        deepest = deepest.max(collapse_node(nodes, leaves, child, index, depth + 1)?);
    }
    Ok(deepest)
}

impl WideBvh {
    /// obvhs's build `params` as they should be for a BVH2 that is to be collapsed 8 wide:
    /// without obvhs's leaf collapse (SAH-driven merging of subtrees into leaves of up to
    /// `max_prims_per_leaf`) when no reinsertion pass follows it. This collapse forms its
    /// own leaves (every subtree of at most 8 triangles, `Source::is_wide_leaf`), so the
    /// wide tree comes out the same: dream-apartment's 178k triangles, one thread, fast
    /// preset, fastest of 15 builds: SAH cost 19.23, 9,274 nodes and 32,165 blocks either
    /// way, in 45 against 59 ms (PLOC 21.7, reinsertion 8.4 and this collapse 14.1 ms over
    /// the uncollapsed tree, against obvhs's collapse 18.8 and this one 8.7 over its
    /// output). Presets that reinsert after obvhs's collapse (medium, slow) keep it: that
    /// pass moves whole 8-triangle leaves, and without it the slow preset's wide tree had
    /// the same SAH cost (18.50) but traced 4-10% slower rays (`gloam raybench
    /// --build-study`, three runs).
    pub fn source_params(params: BvhBuildParams) -> BvhBuildParams {
        if params.post_collapse_reinsertion_batch_ratio_multiplier > 0.0
            && params.reinsertion_batch_ratio > 0.0
        {
            return params;
        }
        BvhBuildParams {
            max_prims_per_leaf: 1,
            ..params
        }
    }

    /// Collapses `bvh` (over `ordered`, its triangles in leaf order) into 8-wide nodes.
    pub fn build(bvh: &Bvh2, ordered: &[RtTriangle]) -> Result<WideBvh, CollapseError> {
        let mut wide = WideBvh::default();
        if bvh.nodes.is_empty() {
            return Ok(wide);
        }
        let source = Source::new(bvh, ordered);
        // Room for blocks half full and a node per 7 BVH2 nodes, so the vectors do not grow
        // (and copy themselves) along the way on a typical tree.
        wide.blocks.reserve(ordered.len().div_ceil(WIDTH / 2));
        wide.nodes.reserve(bvh.nodes.len() / (WIDTH - 1) + 1);
        let mut leaves = TriangleLeaves {
            source: &source,
            blocks: &mut wide.blocks,
        };
        wide.depth = collapse_tree(&mut wide.nodes, &mut leaves)?;
        if !wide.nodes.is_empty() {
            wide.order_for_occlusion(0);
        }
        Ok(wide)
    }

    /// Orders node `index`'s children (and, first, every node below it) for any-hit walks,
    /// which go on into the highest lane first: the child likeliest to block a ray for what
    /// it costs to walk goes last (Ize & Hansen 2011, "RTSAH Traversal Order for Occlusion
    /// Rays"). Returns the subtree's figures for a ray that enters its box.
    fn order_for_occlusion(&mut self, index: usize) -> Occlusion {
        let node = self.nodes[index];
        let (min, max) = node.union();
        let area = half_area(min, max).max(f32::MIN_POSITIVE);
        let mut lanes = [(0usize, 0.0f32, Occlusion::CLEAR); WIDTH];
        let mut count = 0;
        for lane in 0..WIDTH {
            let child = node.children[lane];
            if child == EMPTY {
                continue;
            }
            let b = &node.bounds;
            let child_area = half_area(
                Vec3A::new(b[0][lane], b[1][lane], b[2][lane]),
                Vec3A::new(b[3][lane], b[4][lane], b[5][lane]),
            );
            let figures = if child & LEAF != 0 {
                self.leaf_occlusion(child, child_area)
            } else {
                self.order_for_occlusion(child as usize)
            };
            lanes[count] = (lane, (child_area / area).min(1.0), figures);
            count += 1;
        }
        let lanes = &mut lanes[..count];
        // Swapping two neighbours in the walk's order changes its expected cost by
        // q_a q_b (P_a C_b - P_b C_a), so the best order is by P / C: the lowest first here,
        // since the walk takes the highest lane first.
        lanes.sort_by(|a, b| (a.2.blocked * b.2.cost).total_cmp(&(b.2.blocked * a.2.cost)));
        let mut ordered = WideNode::EMPTY;
        for (slot, &(lane, _, _)) in lanes.iter().enumerate() {
            for plane in 0..6 {
                ordered.bounds[plane][slot] = node.bounds[plane][lane];
            }
            ordered.children[slot] = node.children[lane];
        }
        self.nodes[index] = ordered;
        let mut through = 1.0;
        let mut cost = Occlusion::NODE_COST;
        for &(_, entered, figures) in lanes.iter().rev() {
            cost += through * entered * figures.cost;
            through *= 1.0 - entered * figures.blocked;
        }
        Occlusion {
            blocked: 1.0 - through,
            cost,
        }
    }

    /// A leaf's figures: by Cauchy and Crofton, a random line through a convex box meets a
    /// convex body inside it with probability S_body / S_box, and a triangle's S is twice
    /// its area, |ng|; its triangles are taken as independent.
    fn leaf_occlusion(&self, leaf: u32, half_box_area: f32) -> Occlusion {
        let (first, count) = leaf_blocks(leaf);
        let box_area = 2.0 * half_box_area.max(f32::MIN_POSITIVE);
        let mut through = 1.0;
        let mut cost = 0.0;
        for block in &self.blocks[first..first + count] {
            cost += through * Occlusion::BLOCK_COST;
            for lane in 0..WIDTH {
                if block.ids[lane] != EMPTY {
                    let p = &block.planes;
                    let ng = Vec3A::new(p[9][lane], p[10][lane], p[11][lane]).length();
                    through *= 1.0 - (ng / box_area).min(1.0);
                }
            }
        }
        Occlusion {
            blocked: 1.0 - through,
            cost,
        }
    }

    /// The box around everything (empty for an empty tree).
    pub fn bounds(&self) -> (Vec3A, Vec3A) {
        self.nodes
            .first()
            .map_or((Vec3A::INFINITY, Vec3A::NEG_INFINITY), WideNode::union)
    }

    /// Bytes of nodes and triangle blocks (what a walk may read).
    pub fn bytes(&self) -> usize {
        self.nodes.len() * size_of::<WideNode>() + self.blocks.len() * size_of::<TriangleBlock>()
    }

    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    pub fn block_count(&self) -> usize {
        self.blocks.len()
    }

    /// Triangles in the tree (the used lanes of its blocks).
    pub fn triangle_count(&self) -> usize {
        self.blocks
            .iter()
            .map(|block| block.ids.iter().filter(|&&id| id != EMPTY).count())
            .sum()
    }

    /// Levels of nodes, the root's counted as 1.
    pub fn depth(&self) -> usize {
        self.depth
    }

    /// Moves the triangles to `triangle(id)` (id in the mesh) and refits every box, children
    /// before parents (the topology is kept: same nodes, same blocks). Returns the refit
    /// tree's `sah_cost`, summed on the way.
    pub fn refit(&mut self, triangle: impl Fn(usize) -> RtTriangle + Sync) -> f32 {
        use rayon::prelude::*;
        // 1. The blocks and their boxes, in parallel (most of the work: every triangle).
        self.block_bounds
            .resize(self.blocks.len(), (Vec3A::ZERO, Vec3A::ZERO, 0));
        self.blocks
            .par_iter_mut()
            .zip(self.block_bounds.par_iter_mut())
            .with_min_len(256)
            .for_each(|(block, bounds)| {
                let mut used = 0;
                let (mut min, mut max) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY);
                for lane in 0..WIDTH {
                    let id = block.ids[lane];
                    if id != EMPTY {
                        let triangle = triangle(id as usize);
                        block.set(lane, id, &triangle);
                        // The box of the corners the test sees (as `RtTriangle::aabb` finds them),
                        // taken here rather than by reading the block back.
                        for corner in [
                            triangle.v0,
                            triangle.v0 - triangle.e1,
                            triangle.v0 + triangle.e2,
                        ] {
                            min = min.min(corner);
                            max = max.max(corner);
                        }
                        used += 1;
                    }
                }
                *bounds = (min, max, used);
            });
        // 2. The nodes, last first: children come after their parents, so every child's
        //    box is final before its parent reads it.
        let mut cost = 0.0;
        for index in (0..self.nodes.len()).rev() {
            for lane in 0..WIDTH {
                let child = self.nodes[index].children[lane];
                if child == EMPTY {
                    continue;
                }
                let (min, max, triangles) = if child & LEAF != 0 {
                    let (first, count) = leaf_blocks(child);
                    self.block_bounds[first..first + count].iter().fold(
                        (Vec3A::INFINITY, Vec3A::NEG_INFINITY, 0),
                        |(min, max, used), &(lo, hi, n)| (min.min(lo), max.max(hi), used + n),
                    )
                } else {
                    let (min, max) = self.nodes[child as usize].union();
                    (min, max, 0)
                };
                self.nodes[index].set_box(lane, min, max);
                cost += half_area(min, max) * triangles.max(1) as f32;
            }
        }
        let (min, max) = self
            .nodes
            .first()
            .map_or((Vec3A::ZERO, Vec3A::ZERO), WideNode::union);
        let root_area = half_area(min, max).max(f32::MIN_POSITIVE);
        (root_area + cost) / root_area
    }

    /// SAH cost relative to the root's area (Goldsmith & Salmon 1987, as `Blas::sah_cost`):
    /// the root, each child box's area once per node entered, a leaf's area per triangle.
    pub fn sah_cost(&self) -> f32 {
        let Some(root) = self.nodes.first() else {
            return 0.0;
        };
        let (min, max) = root.union();
        let root_area = half_area(min, max).max(f32::MIN_POSITIVE);
        let mut cost = 0.0;
        for node in &self.nodes {
            for lane in 0..WIDTH {
                let child = node.children[lane];
                if child == EMPTY {
                    continue;
                }
                let triangles = if child & LEAF != 0 {
                    let (first, count) = leaf_blocks(child);
                    self.blocks[first..first + count]
                        .iter()
                        .map(|block| block.ids.iter().filter(|&&id| id != EMPTY).count())
                        .sum::<usize>()
                } else {
                    1
                };
                let b = &node.bounds;
                let area = half_area(
                    Vec3A::new(b[0][lane], b[1][lane], b[2][lane]),
                    Vec3A::new(b[3][lane], b[4][lane], b[5][lane]),
                );
                cost += area * triangles.max(1) as f32;
            }
        }
        (root_area + cost) / root_area
    }

    /// Closest hit within [t_min, t_max]: (t, triangle's index in the mesh).
    #[inline]
    pub fn intersect(&self, ray: &ObvhsRay, kernels: Kernels) -> Option<(f32, u32)> {
        self.intersect_triangle(ray, kernels)
            .map(|(t, id, _)| (t, id))
    }

    /// `intersect`, with the triangle as the tree holds it (what a deforming BLAS's
    /// barycentrics come from: its leaf-ordered copy is not updated while rays walk this).
    #[inline]
    pub fn intersect_triangle(
        &self,
        ray: &ObvhsRay,
        kernels: Kernels,
    ) -> Option<(f32, u32, RtTriangle)> {
        let (t, slot) = self.intersect_slot(ray, kernels)?;
        let (id, triangle) = self.triangle_at(slot);
        Some((t, id, triangle))
    }

    /// The triangle in `slot` (block * 8 + lane, as the queries report hits): its index in
    /// the mesh and its planes as the tree holds them.
    #[inline]
    pub fn triangle_at(&self, slot: u32) -> (u32, RtTriangle) {
        let block = &self.blocks[slot as usize / WIDTH];
        let lane = slot as usize % WIDTH;
        let p = &block.planes;
        let lane_vector =
            |first: usize| Vec3A::new(p[first][lane], p[first + 1][lane], p[first + 2][lane]);
        let triangle = RtTriangle {
            v0: lane_vector(0),
            e1: lane_vector(3),
            e2: lane_vector(6),
            ng: lane_vector(9),
        };
        (block.ids[lane], triangle)
    }

    /// Closest hit within [t_min, t_max]: (t, slot); `triangle_at(slot)` tells which.
    #[inline]
    pub fn intersect_slot(&self, ray: &ObvhsRay, kernels: Kernels) -> Option<(f32, u32)> {
        self.intersect_lanes(&RayLanes::new(ray), ray.tmax, kernels)
    }

    /// True when a triangle lies within (t_min, t_max) (stops at the first found).
    #[inline]
    pub fn occluded(&self, ray: &ObvhsRay, kernels: Kernels) -> bool {
        self.occluded_lanes(&RayLanes::new(ray), ray.tmax, kernels)
    }

    /// `intersect_slot` for a ray already prepared (the TLAS hands its own to BLASes that
    /// share its space, rather than working out the reciprocals again).
    #[inline]
    pub(crate) fn intersect_lanes(
        &self,
        ray: &RayLanes,
        t_max: f32,
        kernels: Kernels,
    ) -> Option<(f32, u32)> {
        if self.nodes.is_empty() {
            return None;
        }
        #[cfg(target_arch = "x86_64")]
        if kernels.avx2() {
            // SAFETY: the CPU has AVX2, the only feature the function enables.
            return unsafe { self.intersect_avx2(ray, t_max) };
        }
        let _ = kernels;
        self.traverse::<Portable, false>(ray, t_max)
    }

    /// `occluded` for a ray already prepared.
    #[inline]
    pub(crate) fn occluded_lanes(&self, ray: &RayLanes, t_max: f32, kernels: Kernels) -> bool {
        if self.nodes.is_empty() {
            return false;
        }
        #[cfg(target_arch = "x86_64")]
        if kernels.avx2() {
            // SAFETY: as in `intersect_lanes`.
            return unsafe { self.occluded_avx2(ray, t_max) };
        }
        let _ = kernels;
        self.traverse::<Portable, true>(ray, t_max).is_some()
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn intersect_avx2(&self, ray: &RayLanes, t_max: f32) -> Option<(f32, u32)> {
        self.traverse::<avx2::Avx2, false>(ray, t_max)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn occluded_avx2(&self, ray: &RayLanes, t_max: f32) -> bool {
        self.traverse::<avx2::Avx2, true>(ray, t_max).is_some()
    }

    /// The traversal both queries share: with `ANY`, the first hit ends it. Returns the
    /// hit's t and slot (block * WIDTH + lane).
    #[inline(always)]
    pub(super) fn traverse<K: Lanes, const ANY: bool>(
        &self,
        lanes: &RayLanes,
        t_max: f32,
    ) -> Option<(f32, u32)> {
        let mut found = None;
        walk::<K, ANY>(&self.nodes, lanes, t_max, |leaf, t_max| {
            let (first, count) = leaf_blocks(leaf);
            for (index, block) in self.blocks[first..first + count].iter().enumerate() {
                let (mut hits, t) = K::block(block, lanes, *t_max);
                while hits != 0 {
                    let lane = hits.trailing_zeros() as usize;
                    hits &= hits - 1;
                    let slot = ((first + index) * WIDTH + lane) as u32;
                    if ANY {
                        found = Some((t[lane], slot));
                        return true;
                    }
                    if t[lane] < *t_max {
                        *t_max = t[lane];
                        found = Some((t[lane], slot));
                    }
                }
            }
            false
        });
        found
    }
}

/// Walks `nodes` along the ray, nearest child first (with `ANY`, in any order), calling
/// `leaf(reference, t_max)` for each leaf the ray enters before `t_max`; `leaf` may lower
/// `t_max` (a closer hit), and returning true ends the walk.
#[inline(always)]
pub(super) fn walk<K: Lanes, const ANY: bool>(
    nodes: &[WideNode],
    lanes: &RayLanes,
    mut t_max: f32,
    mut leaf: impl FnMut(u32, &mut f32) -> bool,
) {
    if nodes.is_empty() {
        return;
    }
    // Uninitialised: zeroing 8 KB per ray cost more than the traversal of a short ray.
    // Rule: entries below `depth` are always written before they are read.
    let mut stack = [const { MaybeUninit::<(u32, f32)>::uninit() }; STACK];
    // SAFETY: `read` is only called at indices below `depth` (see the rule above).
    let read =
        |stack: &[MaybeUninit<(u32, f32)>; STACK], at: usize| unsafe { stack[at].assume_init() };
    let mut depth = 0usize;
    let mut current = 0u32;
    loop {
        if current & LEAF == 0 {
            let node = &nodes[current as usize];
            let (mut hits, entry) = K::node(node, lanes, t_max);
            if hits != 0 {
                if hits.count_ones() == 1 {
                    current = node.children[hits.trailing_zeros() as usize];
                    continue;
                }
                if ANY {
                    // Any hit ends the search, so no sorting: the highest lane, which the
                    // build made the likeliest to block for its cost, is popped first.
                    while hits != 0 {
                        let lane = hits.trailing_zeros() as usize;
                        hits &= hits - 1;
                        stack[depth].write((node.children[lane], entry[lane]));
                        depth += 1;
                    }
                    depth -= 1;
                    current = read(&stack, depth).0;
                    continue;
                }
                // Push the hit children farthest first, then carry on with the nearest
                // (insertion sort: two or three hits are the common case).
                let base = depth;
                while hits != 0 {
                    let lane = hits.trailing_zeros() as usize;
                    hits &= hits - 1;
                    let item = (node.children[lane], entry[lane]);
                    let mut at = depth;
                    while at > base && read(&stack, at - 1).1 < item.1 {
                        stack[at] = stack[at - 1];
                        at -= 1;
                    }
                    stack[at].write(item);
                    depth += 1;
                }
                depth -= 1;
                current = read(&stack, depth).0;
                continue;
            }
        } else if leaf(current, &mut t_max) {
            return;
        }
        // Next: the nearest pending child still nearer than the closest hit.
        loop {
            if depth == 0 {
                return;
            }
            depth -= 1;
            let (child, entry) = read(&stack, depth);
            if entry <= t_max {
                current = child;
                break;
            }
        }
    }
}

/// The TLAS as an 8-wide tree: obvhs's PLOC-built BVH2 over instance boxes, collapsed the
/// way a BLAS's is; a leaf names a range of that BVH2's `primitive_indices`.
#[derive(Clone, Debug, Default)]
pub struct WideTlas {
    pub(super) nodes: Vec<WideNode>,
    /// The tree holds a single entry (a level that is all one static batch): walks hand
    /// rays straight to it, and its BLAS's own walk tests the box. Skipping the one-node
    /// walk took dream-apartment's shadow rays from 11.0 to 16.2 Mrays/s and bounces from
    /// 4.6 to 5.4 (`gloam raybench`, one thread).
    pub(super) sole_entry: bool,
}

/// A TLAS's leaves: ranges of its BVH2's primitive slots (instances).
struct InstanceLeaves<'a> {
    bvh: &'a Bvh2,
}

impl LeafMaker for InstanceLeaves<'_> {
    fn bvh(&self) -> &Bvh2 {
        self.bvh
    }

    fn is_leaf(&self, node: usize) -> bool {
        self.bvh.nodes[node].is_leaf()
    }

    fn leaf(&mut self, node: usize) -> Result<u32, CollapseError> {
        let n = &self.bvh.nodes[node];
        if n.prim_count as usize > MAX_LEAF_BLOCKS {
            return Err(CollapseError::LeafTooLarge(n.prim_count as usize));
        }
        Ok(LEAF | ((n.prim_count.max(1) - 1) << LEAF_COUNT_SHIFT) | n.first_index)
    }
}

impl WideTlas {
    /// Rebuilds from `bvh` (every frame, after the BVH2 over the instances is rebuilt),
    /// keeping the allocation.
    pub fn rebuild(&mut self, bvh: &Bvh2) -> Result<(), CollapseError> {
        self.sole_entry = bvh.primitive_indices.len() == 1;
        collapse_tree(&mut self.nodes, &mut InstanceLeaves { bvh }).map(|_| ())
    }

    /// Calls `visit(slot, t_max)` for each primitive slot (index into the BVH2's
    /// `primitive_indices`) whose box `ray` enters before `t_max`, nearest first; `visit`
    /// returns the hit distance it found (lowering `t_max`), or None. With `any`, the first
    /// hit ends the walk. Returns whether anything was hit.
    #[inline]
    pub(crate) fn walk(
        &self,
        ray: &RayLanes,
        t_max: f32,
        kernels: Kernels,
        any: bool,
        mut visit: impl FnMut(usize, f32) -> Option<f32>,
    ) -> bool {
        // A one-entry tree is not walked (`sole_entry`); slot 0 is that entry.
        if self.sole_entry {
            return visit(0, t_max).is_some();
        }
        #[cfg(target_arch = "x86_64")]
        if kernels.avx2() {
            // SAFETY: the CPU has AVX2, the only feature the function enables.
            return unsafe { self.walk_avx2(ray, t_max, any, visit) };
        }
        let _ = kernels;
        self.walk_with::<Portable>(ray, t_max, any, visit)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn walk_avx2(
        &self,
        ray: &RayLanes,
        t_max: f32,
        any: bool,
        visit: impl FnMut(usize, f32) -> Option<f32>,
    ) -> bool {
        self.walk_with::<avx2::Avx2>(ray, t_max, any, visit)
    }

    #[inline(always)]
    pub(super) fn walk_with<K: Lanes>(
        &self,
        lanes: &RayLanes,
        t_max: f32,
        any: bool,
        mut visit: impl FnMut(usize, f32) -> Option<f32>,
    ) -> bool {
        let mut hit = false;
        let mut leaf = |reference: u32, t_max: &mut f32| {
            let (first, count) = leaf_blocks(reference);
            for slot in first..first + count {
                if let Some(t) = visit(slot, *t_max) {
                    hit = true;
                    if any {
                        return true;
                    }
                    *t_max = t_max.min(t);
                }
            }
            false
        };
        if any {
            walk::<K, true>(&self.nodes, lanes, t_max, &mut leaf);
        } else {
            walk::<K, false>(&self.nodes, lanes, t_max, &mut leaf);
        }
        hit
    }
}

/// (first block, block count) of a leaf reference.
#[inline(always)]
pub(super) fn leaf_blocks(child: u32) -> (usize, usize) {
    (
        (child & ((1 << LEAF_COUNT_SHIFT) - 1)) as usize,
        ((child & !LEAF) >> LEAF_COUNT_SHIFT) as usize + 1,
    )
}

/// A ray as the kernels read it: per axis, which bound is the near plane (by the sign of
/// the direction, so an empty lane's inverted box is entered at +inf and never hit).
#[derive(Clone, Copy, Debug)]
pub(crate) struct RayLanes {
    pub(super) origin: [f32; 3],
    pub(super) direction: [f32; 3],
    pub(super) inverse: [f32; 3],
    /// Index into `WideNode::bounds` of each axis's near and far planes.
    pub(super) near: [usize; 3],
    pub(super) far: [usize; 3],
    pub(super) t_min: f32,
}

impl RayLanes {
    #[inline(always)]
    pub(crate) fn new(ray: &ObvhsRay) -> RayLanes {
        RayLanes::from_parts(ray.origin, ray.direction, ray.tmin)
    }

    /// The ray from `origin` along `direction`, from `t_min` on.
    #[inline(always)]
    pub(crate) fn from_parts(origin: Vec3A, direction: Vec3A, t_min: f32) -> RayLanes {
        let direction = direction.to_array();
        // A true reciprocal: 1/0 is an infinity of the zero's sign, and the slab test drops
        // the NaN of 0 * inf (a ray in a slab's plane is inside that slab).
        let inverse = direction.map(|d| 1.0 / d);
        let near = [0, 1, 2].map(|axis| {
            if inverse[axis].is_sign_negative() {
                3 + axis
            } else {
                axis
            }
        });
        RayLanes {
            origin: origin.to_array(),
            direction,
            inverse,
            near,
            far: near.map(|plane| (plane + 3) % 6),
            t_min,
        }
    }
}

/// The two kernels, per implementation.
pub(crate) trait Lanes {
    /// Lanes whose box the ray enters before `t_max`, and each one's entry distance.
    fn node(node: &WideNode, ray: &RayLanes, t_max: f32) -> (u32, [f32; WIDTH]);
    /// Lanes whose triangle the ray crosses within (t_min, t_max), and the distances.
    fn block(block: &TriangleBlock, ray: &RayLanes, t_max: f32) -> (u32, [f32; WIDTH]);
    /// Writes the `children` named in `lanes` to the front of `slots`, lowest lane first,
    /// and returns how many (the other slots may be overwritten).
    fn push_children(
        children: &[u32; WIDTH],
        lanes: u32,
        slots: &mut [MaybeUninit<u32>; WIDTH],
    ) -> usize;
}

/// One ray against one box, portably: the entry distance, and whether the ray enters before
/// `t_max` (`planes(axis)` is the box's (near, far) plane on that axis for this ray). The
/// single-ray node test and the packets' per-ray leaf-box test both run this, so a packet's
/// ray admits exactly the boxes it admits alone.
#[inline(always)]
pub(super) fn slab_test(
    planes: impl Fn(usize) -> (f32, f32),
    origin: [f32; 3],
    inverse: [f32; 3],
    t_min: f32,
    t_max: f32,
) -> (f32, bool) {
    let (mut near, mut far) = (t_min, t_max);
    for axis in 0..3 {
        let (near_plane, far_plane) = planes(axis);
        near = max_dropping_nan((near_plane - origin[axis]) * inverse[axis], near);
        far = min_dropping_nan((far_plane - origin[axis]) * inverse[axis], far);
    }
    (near, near <= far * ROBUST_FAR)
}

/// x86's maxps: `a` when a > b, else `b` (so a NaN in `a` is dropped).
#[inline(always)]
pub(super) fn max_dropping_nan(a: f32, b: f32) -> f32 {
    if a > b { a } else { b }
}

/// x86's minps: `a` when a < b, else `b`.
#[inline(always)]
pub(super) fn min_dropping_nan(a: f32, b: f32) -> f32 {
    if a < b { a } else { b }
}

pub(super) struct Portable;

// Lane loops index several arrays by the lane, as the SIMD kernels do.
#[allow(clippy::needless_range_loop)]
impl Lanes for Portable {
    #[inline(always)]
    fn push_children(
        children: &[u32; WIDTH],
        mut lanes: u32,
        slots: &mut [MaybeUninit<u32>; WIDTH],
    ) -> usize {
        let mut count = 0;
        while lanes != 0 {
            let lane = lanes.trailing_zeros() as usize;
            lanes &= lanes - 1;
            slots[count % WIDTH].write(children[lane % WIDTH]);
            count += 1;
        }
        count
    }

    #[inline(always)]
    fn node(node: &WideNode, ray: &RayLanes, t_max: f32) -> (u32, [f32; WIDTH]) {
        let mut entry = [0.0; WIDTH];
        let mut hits = 0;
        for lane in 0..WIDTH {
            let (near, entered) = slab_test(
                |axis| {
                    (
                        node.bounds[ray.near[axis]][lane],
                        node.bounds[ray.far[axis]][lane],
                    )
                },
                ray.origin,
                ray.inverse,
                ray.t_min,
                t_max,
            );
            entry[lane] = near;
            hits |= (entered as u32) << lane;
        }
        (hits, entry)
    }

    #[inline(always)]
    fn block(block: &TriangleBlock, ray: &RayLanes, t_max: f32) -> (u32, [f32; WIDTH]) {
        let p = &block.planes;
        let [ox, oy, oz] = ray.origin;
        let [dx, dy, dz] = ray.direction;
        let mut distance = [0.0; WIDTH];
        let mut hits = 0;
        for lane in 0..WIDTH {
            let (e1x, e1y, e1z) = (p[3][lane], p[4][lane], p[5][lane]);
            let (e2x, e2y, e2z) = (p[6][lane], p[7][lane], p[8][lane]);
            let (nx, ny, nz) = (p[9][lane], p[10][lane], p[11][lane]);
            // c = v0 - o; r = d x c; 1 / det = 1 / (ng . d).
            let (cx, cy, cz) = (p[0][lane] - ox, p[1][lane] - oy, p[2][lane] - oz);
            let rx = dy * cz - dz * cy;
            let ry = dz * cx - dx * cz;
            let rz = dx * cy - dy * cx;
            let inverse_det = 1.0 / (nx * dx + ny * dy + nz * dz);
            // Barycentrics u = (r . e2) / det, v = (r . e1) / det, w = 1 - u - v: inside
            // when none has its sign bit set (so -0 is outside, as in obvhs).
            let u = (rx * e2x + ry * e2y + rz * e2z) * inverse_det;
            let v = (rx * e1x + ry * e1y + rz * e1z) * inverse_det;
            let w = 1.0 - u - v;
            let inside = (u.to_bits() | v.to_bits() | w.to_bits()) & 0x8000_0000 == 0;
            // t = (ng . c) / det, within [t_min, t_max].
            let t = (nx * cx + ny * cy + nz * cz) * inverse_det;
            distance[lane] = t;
            if inverse_det != 0.0 && inside && t >= ray.t_min && t <= t_max {
                hits |= 1 << lane;
            }
        }
        (hits, distance)
    }
}

#[cfg(target_arch = "x86_64")]
pub(super) mod avx2 {
    //! The kernels in AVX2 intrinsics: the portable ones' operations, lane for lane.

    use std::arch::x86_64::*;
    use std::mem::MaybeUninit;

    use super::{Lanes, ROBUST_FAR, RayLanes, TriangleBlock, WIDTH, WideNode};

    pub(crate) struct Avx2;

    // The trait's methods cannot carry `#[target_feature]`, so they call kernels that do:
    // the intrinsics are then compiled for AVX2 even where the optimiser does not inline
    // them into an AVX2 caller (a closure it left out-of-line once called every intrinsic
    // as a function: primary rays fell from 5.4 to 0.8 Mrays/s).
    impl Lanes for Avx2 {
        #[inline(always)]
        fn node(node: &WideNode, ray: &RayLanes, t_max: f32) -> (u32, [f32; WIDTH]) {
            // SAFETY: `Avx2` kernels run only where `Kernels::avx2` found AVX2.
            unsafe { Avx2::node_kernel(node, ray, t_max) }
        }

        #[inline(always)]
        fn block(block: &TriangleBlock, ray: &RayLanes, t_max: f32) -> (u32, [f32; WIDTH]) {
            // SAFETY: `Avx2` kernels run only where `Kernels::avx2` found AVX2.
            unsafe { Avx2::block_kernel(block, ray, t_max) }
        }

        #[inline(always)]
        fn push_children(
            children: &[u32; WIDTH],
            lanes: u32,
            slots: &mut [MaybeUninit<u32>; WIDTH],
        ) -> usize {
            // SAFETY: `Avx2` kernels run only where `Kernels::avx2` found AVX2.
            unsafe { Avx2::push_kernel(children, lanes, slots) }
        }
    }

    /// Per 8-bit lane mask, the set lanes' indices packed into the low bytes, lowest first:
    /// the permutation that compresses those lanes to the front of a vector; and in bits 3
    /// to 7 of the first byte, which the permutation ignores (it reads each index's low
    /// three bits), how many lanes are set. The baseline's AVX2 has no POPCNT instruction
    /// enabled, so `count_ones` was 17 instructions of arithmetic a push: read here, the
    /// shadow-ray stream takes 6.2% fewer instructions a ray (562 against 527, callgrind,
    /// dream-apartment), for 1-2% more rays a second (the walk waits on latency more than
    /// on instructions).
    static COMPRESS: [u64; 256] = {
        let mut table = [0u64; 256];
        let mut mask = 0;
        while mask < 256 {
            let (mut packed, mut count, mut lane) = (0u64, 0, 0);
            while lane < 8 {
                if mask >> lane & 1 != 0 {
                    packed |= (lane as u64) << (8 * count);
                    count += 1;
                }
                lane += 1;
            }
            table[mask] = packed | (count as u64) << 3;
            mask += 1;
        }
        table
    };

    /// The lanes a ray enters (entry `near` at most exit `far`, widened by `ROBUST_FAR`),
    /// and each lane's entry: the end of every node test, single-ray or packet.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(crate) fn entered(near: __m256, far: __m256) -> (u32, [f32; WIDTH]) {
        let far = _mm256_mul_ps(far, _mm256_set1_ps(ROBUST_FAR));
        let hit = _mm256_cmp_ps::<_CMP_LE_OQ>(near, far);
        let mut entry = [0.0f32; WIDTH];
        // SAFETY: `entry` holds 8 floats.
        unsafe { _mm256_storeu_ps(entry.as_mut_ptr(), near) };
        (_mm256_movemask_ps(hit) as u32, entry)
    }

    impl Avx2 {
        #[target_feature(enable = "avx2")]
        #[inline]
        fn node_kernel(node: &WideNode, ray: &RayLanes, t_max: f32) -> (u32, [f32; WIDTH]) {
            // SAFETY: only reached from `#[target_feature(enable = "avx2")]` functions;
            // `WideNode` is 32-byte aligned, so its rows are aligned loads.
            unsafe {
                let mut near = _mm256_set1_ps(ray.t_min);
                let mut far = _mm256_set1_ps(t_max);
                for axis in 0..3 {
                    let origin = _mm256_set1_ps(ray.origin[axis]);
                    let inverse = _mm256_set1_ps(ray.inverse[axis]);
                    let near_plane = _mm256_load_ps(node.bounds[ray.near[axis]].as_ptr());
                    let far_plane = _mm256_load_ps(node.bounds[ray.far[axis]].as_ptr());
                    let t_near = _mm256_mul_ps(_mm256_sub_ps(near_plane, origin), inverse);
                    let t_far = _mm256_mul_ps(_mm256_sub_ps(far_plane, origin), inverse);
                    // maxps(a, b) is b when either is NaN: as `max_dropping_nan`.
                    near = _mm256_max_ps(t_near, near);
                    far = _mm256_min_ps(t_far, far);
                }
                entered(near, far)
            }
        }

        /// `push_children` as one permute and one store of all 8 lanes: no loop whose
        /// length (the hit count) the branch predictor must guess.
        #[target_feature(enable = "avx2")]
        #[inline]
        fn push_kernel(
            children: &[u32; WIDTH],
            lanes: u32,
            slots: &mut [MaybeUninit<u32>; WIDTH],
        ) -> usize {
            let order = COMPRESS[(lanes & 0xff) as usize];
            // SAFETY: `children` and `slots` are 8 u32s each (unaligned loads and stores).
            unsafe {
                let order = _mm256_cvtepu8_epi32(_mm_cvtsi64_si128(order as i64));
                let children = _mm256_loadu_si256(children.as_ptr().cast());
                let packed = _mm256_permutevar8x32_epi32(children, order);
                _mm256_storeu_si256(slots.as_mut_ptr().cast(), packed);
            }
            (order as usize & 0xff) >> 3
        }

        #[target_feature(enable = "avx2")]
        #[inline]
        fn block_kernel(block: &TriangleBlock, ray: &RayLanes, t_max: f32) -> (u32, [f32; WIDTH]) {
            // SAFETY: as in `node`; `TriangleBlock` is 32-byte aligned.
            unsafe {
                let p = &block.planes;
                let load = |plane: usize| _mm256_load_ps(p[plane].as_ptr());
                let splat = |value: f32| _mm256_set1_ps(value);
                let (mul, sub, add) = (
                    |a, b| _mm256_mul_ps(a, b),
                    |a, b| _mm256_sub_ps(a, b),
                    |a, b| _mm256_add_ps(a, b),
                );
                let (dx, dy, dz) = (
                    splat(ray.direction[0]),
                    splat(ray.direction[1]),
                    splat(ray.direction[2]),
                );
                let cx = sub(load(0), splat(ray.origin[0]));
                let cy = sub(load(1), splat(ray.origin[1]));
                let cz = sub(load(2), splat(ray.origin[2]));
                let rx = sub(mul(dy, cz), mul(dz, cy));
                let ry = sub(mul(dz, cx), mul(dx, cz));
                let rz = sub(mul(dx, cy), mul(dy, cx));
                let (nx, ny, nz) = (load(9), load(10), load(11));
                let det = add(add(mul(nx, dx), mul(ny, dy)), mul(nz, dz));
                let inverse_det = _mm256_div_ps(splat(1.0), det);
                let u = mul(
                    add(add(mul(rx, load(6)), mul(ry, load(7))), mul(rz, load(8))),
                    inverse_det,
                );
                let v = mul(
                    add(add(mul(rx, load(3)), mul(ry, load(4))), mul(rz, load(5))),
                    inverse_det,
                );
                let w = sub(sub(splat(1.0), u), v);
                let t = mul(add(add(mul(nx, cx), mul(ny, cy)), mul(nz, cz)), inverse_det);
                // Sign bits of u | v | w: a lane is outside when any is set.
                let signs = _mm256_movemask_ps(_mm256_or_ps(_mm256_or_ps(u, v), w)) as u32;
                let zero = _mm256_setzero_ps();
                // NEQ_UQ: a NaN determinant's reciprocal counts as non-zero, as `!=` does.
                let mut hit = _mm256_cmp_ps::<_CMP_NEQ_UQ>(inverse_det, zero);
                hit = _mm256_and_ps(hit, _mm256_cmp_ps::<_CMP_GE_OQ>(t, splat(ray.t_min)));
                hit = _mm256_and_ps(hit, _mm256_cmp_ps::<_CMP_LE_OQ>(t, splat(t_max)));
                let mut distance = [0.0f32; WIDTH];
                _mm256_storeu_ps(distance.as_mut_ptr(), t);
                (_mm256_movemask_ps(hit) as u32 & !signs, distance)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::Ray;
    use obvhs::BvhBuildParams;
    use obvhs::bvh2::builder::build_bvh2;

    /// A small deterministic generator (xorshift32), so failures reproduce.
    struct Random(u32);

    impl Random {
        fn next(&mut self) -> f32 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 17;
            self.0 ^= self.0 << 5;
            (self.0 >> 8) as f32 / (1u32 << 24) as f32
        }

        fn range(&mut self, low: f32, high: f32) -> f32 {
            low + (high - low) * self.next()
        }

        fn point(&mut self, extent: f32) -> Vec3A {
            Vec3A::new(
                self.range(-extent, extent),
                self.range(-extent, extent),
                self.range(-extent, extent),
            )
        }
    }

    /// A triangle soup with the awkward cases mixed in: zero-area (repeated vertex and
    /// collinear), huge, axis-aligned (flat boxes) and tiny triangles.
    fn soup(random: &mut Random, count: usize) -> Vec<[Vec3A; 3]> {
        (0..count)
            .map(|i| {
                let centre = random.point(10.0);
                let size = match i % 10 {
                    0 => 100.0,
                    1 => 1e-3,
                    _ => random.range(0.05, 2.0),
                };
                let a = centre + random.point(size);
                let b = centre + random.point(size);
                let c = centre + random.point(size);
                match i % 13 {
                    3 => [a, a, c],
                    4 => [a, b, a + (b - a) * 0.5],
                    5 => [a, Vec3A::new(b.x, a.y, b.z), Vec3A::new(c.x, a.y, c.z)],
                    _ => [a, b, c],
                }
            })
            .collect()
    }

    /// The wide tree over `triangles`, and the triangles as `RtTriangle`s (mesh order).
    fn build(triangles: &[[Vec3A; 3]]) -> (WideBvh, Vec<RtTriangle>) {
        let rt: Vec<RtTriangle> = triangles
            .iter()
            .map(|&[a, b, c]| RtTriangle::new(a, b, c))
            .collect();
        let bvh = build_bvh2(&rt, BvhBuildParams::medium_build(), &mut Default::default());
        let ordered: Vec<RtTriangle> = bvh
            .primitive_indices
            .iter()
            .map(|&i| rt[i as usize])
            .collect();
        let wide = WideBvh::build(&bvh, &ordered).expect("collapse");
        (wide, rt)
    }

    /// Every triangle through the same portable lane arithmetic, one at a time: the closest
    /// (t, index in `mesh`) and whether any lies in (t_min, t_max).
    fn brute_force(mesh: &[RtTriangle], ray: &ObvhsRay) -> (Option<(f32, u32)>, bool) {
        let lanes = RayLanes::new(ray);
        let mut closest: Option<(f32, u32)> = None;
        for (id, triangle) in mesh.iter().enumerate() {
            let mut block = TriangleBlock::EMPTY;
            block.set(0, id as u32, triangle);
            let (hits, t) = Portable::block(&block, &lanes, ray.tmax);
            if hits & 1 != 0 && closest.is_none_or(|(best, _)| t[0] < best) {
                closest = Some((t[0], id as u32));
            }
        }
        (closest, closest.is_some())
    }

    fn rays(random: &mut Random, triangles: &[[Vec3A; 3]], count: usize) -> Vec<ObvhsRay> {
        let axes = [
            Vec3A::X,
            Vec3A::NEG_X,
            Vec3A::Y,
            Vec3A::NEG_Y,
            Vec3A::Z,
            Vec3A::NEG_Z,
        ];
        (0..count)
            .map(|i| {
                let ray = match i % 4 {
                    // From anywhere, anywhere.
                    0 => Ray::new(random.point(15.0), random.point(1.0)),
                    // Axis-parallel (zero direction components: infinite reciprocals).
                    1 => Ray::new(random.point(12.0), axes[i / 4 % 6]),
                    // Leaving a surface, as bounce and shadow rays do.
                    2 => {
                        let [a, b, c] = triangles[i / 4 % triangles.len()];
                        let (u, v) = (random.next() * 0.5, random.next() * 0.5);
                        let point = a + (b - a) * u + (c - a) * v;
                        let normal = (b - a).cross(c - a).normalize_or_zero();
                        Ray::spawn(point, normal, random.point(1.0))
                    }
                    // A short segment, as a shadow ray to a nearby light.
                    _ => {
                        let origin = random.point(12.0);
                        let mut ray = Ray::new(origin, random.point(3.0));
                        ray.t_max = random.range(0.1, 2.0);
                        ray
                    }
                };
                ray.to_obvhs()
            })
            .collect()
    }

    #[test]
    fn every_kernel_finds_exactly_the_brute_force_hit() {
        let mut random = Random(0x1234_5678);
        let mut avx2_checked = false;
        for count in [1, 7, 9, 100, 3000] {
            let triangles = soup(&mut random, count);
            let (wide, mesh) = build(&triangles);
            for ray in rays(&mut random, &triangles, 2000) {
                if !ray.direction.is_finite() || ray.direction == Vec3A::ZERO {
                    continue;
                }
                let (expected, blocked) = brute_force(&mesh, &ray);
                for kernels in [Kernels::Portable, Kernels::Best] {
                    avx2_checked |= kernels.avx2();
                    let found = wide.intersect(&ray, kernels);
                    // The same t to the bit; the same triangle unless two tie.
                    match (found, expected) {
                        (None, None) => {}
                        (Some((t, id)), Some((t_expected, id_expected))) => {
                            assert!(!t.is_nan());
                            assert_eq!(t.to_bits(), t_expected.to_bits(), "{ray:?} {kernels:?}");
                            if id != id_expected {
                                let lanes = RayLanes::new(&ray);
                                let mut block = TriangleBlock::EMPTY;
                                block.set(0, id, &mesh[id as usize]);
                                let (_, other) = Portable::block(&block, &lanes, f32::INFINITY);
                                assert_eq!(other[0], t_expected);
                            }
                        }
                        _ => panic!(
                            "{count} triangles, {kernels:?}: {found:?} against {expected:?} for {ray:?}"
                        ),
                    }
                    assert_eq!(wide.occluded(&ray, kernels), blocked, "{ray:?}");
                }
            }
        }
        if !avx2_checked {
            println!("(this CPU has no AVX2: only the portable kernels were checked)");
        }
    }

    /// The vector push (one permute, its count read from the table) packs and counts the
    /// children of every lane mask exactly as the portable loop does.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn every_lane_mask_pushes_the_same_children_on_every_kernel() {
        if !Kernels::Best.avx2() {
            println!("(this CPU has no AVX2: only the portable kernels run)");
            return;
        }
        let children: [u32; WIDTH] = std::array::from_fn(|lane| 100 + lane as u32);
        for lanes in 0..256u32 {
            let mut portable = [const { MaybeUninit::<u32>::uninit() }; WIDTH];
            let mut vector = [const { MaybeUninit::<u32>::uninit() }; WIDTH];
            let count = Portable::push_children(&children, lanes, &mut portable);
            assert_eq!(count, lanes.count_ones() as usize);
            assert_eq!(
                avx2::Avx2::push_children(&children, lanes, &mut vector),
                count,
                "{lanes:08b}"
            );
            // SAFETY: both pushes wrote their first `count` slots.
            let written = |slots: &[MaybeUninit<u32>; WIDTH]| -> Vec<u32> {
                slots[..count]
                    .iter()
                    .map(|slot| unsafe { slot.assume_init() })
                    .collect()
            };
            assert_eq!(written(&vector), written(&portable), "{lanes:08b}");
        }
    }

    #[test]
    fn the_wide_tree_finds_what_obvhs_triangles_find_to_the_bit() {
        // An independent reference: obvhs's own `RtTriangle::intersect` over every triangle
        // (the lanes repeat its arithmetic, so even the rounding agrees).
        let mut random = Random(0x9e37_79b9);
        let triangles = soup(&mut random, 500);
        let (wide, mesh) = build(&triangles);
        let rays = rays(&mut random, &triangles, 4000);
        let mut hits = 0;
        for ray in &rays {
            let reference = mesh
                .iter()
                .map(|t| t.intersect(ray))
                .filter(|t| t.is_finite())
                .min_by(f32::total_cmp);
            for kernels in [Kernels::Portable, Kernels::Best] {
                let found = wide.intersect(ray, kernels).map(|(t, _)| t);
                assert_eq!(found, reference, "{ray:?} {kernels:?}");
            }
            hits += reference.is_some() as usize;
        }
        assert!(
            hits > rays.len() / 10,
            "the rays must hit something: {hits}"
        );
    }

    /// Leaf tests an any-hit walk of `tree` takes for each ray, and whether it is blocked.
    fn any_hit_leaf_tests(tree: &WideBvh, rays: &[ObvhsRay]) -> Vec<(usize, bool)> {
        rays.iter()
            .map(|ray| {
                let (mut tests, mut blocked) = (0, false);
                walk::<Portable, true>(
                    &tree.nodes,
                    &RayLanes::new(ray),
                    ray.tmax,
                    |leaf, t_max| {
                        tests += 1;
                        let (first, count) = leaf_blocks(leaf);
                        blocked = tree.blocks[first..first + count].iter().any(|block| {
                            Portable::block(block, &RayLanes::new(ray), *t_max).0 != 0
                        });
                        blocked
                    },
                );
                (tests, blocked)
            })
            .collect()
    }

    #[test]
    fn the_occlusion_order_finds_blockers_sooner_than_its_reverse() {
        let mut random = Random(0x0cc1_0de5);
        let triangles = soup(&mut random, 3000);
        let (tree, _) = build(&triangles);
        // The same tree with every node's children the other way round.
        let mut reversed = tree.clone();
        for node in &mut reversed.nodes {
            let used = node
                .children
                .iter()
                .filter(|&&child| child != EMPTY)
                .count();
            assert!(
                node.children[used..].iter().all(|&child| child == EMPTY),
                "a node's children fill its first lanes"
            );
            node.children[..used].reverse();
            for plane in &mut node.bounds {
                plane[..used].reverse();
            }
        }
        let rays = rays(&mut random, &triangles, 8000);
        let ordered = any_hit_leaf_tests(&tree, &rays);
        let backwards = any_hit_leaf_tests(&reversed, &rays);
        let blocked_tests = |walks: &[(usize, bool)]| {
            walks
                .iter()
                .filter(|walk| walk.1)
                .map(|walk| walk.0)
                .sum::<usize>()
        };
        let (sooner, later) = (blocked_tests(&ordered), blocked_tests(&backwards));
        let blocked = ordered.iter().filter(|walk| walk.1).count();
        assert!(blocked > 1000, "{blocked} of 8000 rays blocked");
        assert!(
            ordered.iter().zip(&backwards).all(|(a, b)| a.1 == b.1),
            "both orders block the same rays"
        );
        println!("leaf tests of the {blocked} blocked rays: {sooner} in order, {later} reversed");
        assert!(
            (sooner as f64) < 0.8 * later as f64,
            "{sooner} leaf tests in order against {later} reversed"
        );
    }

    #[test]
    fn a_refit_tree_finds_what_a_rebuilt_one_finds() {
        let mut random = Random(42);
        // A 40 x 40 height field, then the same grid waved.
        let grid = |phase: f32| -> Vec<[Vec3A; 3]> {
            let height = |x: f32, z: f32| 0.5 * (x * 0.7 + phase).sin() * (z * 0.4 - phase).cos();
            let mut triangles = Vec::new();
            for i in 0..40 {
                for j in 0..40 {
                    let p = |a: i32, b: i32| {
                        let (x, z) = ((i + a) as f32 * 0.5 - 10.0, (j + b) as f32 * 0.5 - 10.0);
                        Vec3A::new(x, height(x, z), z)
                    };
                    triangles.push([p(0, 0), p(1, 0), p(1, 1)]);
                    triangles.push([p(0, 0), p(1, 1), p(0, 1)]);
                }
            }
            triangles
        };
        let (mut wide, _) = build(&grid(0.0));
        let moved = grid(1.3);
        let refit_cost = wide.refit(|id| {
            let [a, b, c] = moved[id];
            RtTriangle::new(a, b, c)
        });
        // The cost summed during the refit is the refit tree's.
        assert!((refit_cost - wide.sah_cost()).abs() <= 1e-4 * refit_cost);
        let (rebuilt, rebuilt_mesh) = build(&moved);
        for ray in rays(&mut random, &moved, 3000) {
            let refit_hit = wide.intersect(&ray, Kernels::Best);
            let rebuilt_hit = rebuilt.intersect(&ray, Kernels::Best);
            assert_eq!(
                refit_hit.map(|(t, _)| t.to_bits()),
                rebuilt_hit.map(|(t, _)| t.to_bits()),
                "{ray:?}"
            );
            // The same triangle, or one at the same distance.
            if let (Some((_, a)), Some((t, b))) = (refit_hit, rebuilt_hit)
                && a != b
            {
                let (expected, _) = brute_force(&rebuilt_mesh, &ray);
                assert_eq!(expected.map(|e| e.0), Some(t));
            }
            assert_eq!(
                wide.occluded(&ray, Kernels::Best),
                rebuilt.occluded(&ray, Kernels::Best)
            );
        }
        assert!(wide.sah_cost() > 0.0);
    }
}
