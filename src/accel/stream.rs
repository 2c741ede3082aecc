//! Frame step `accel`, for shadow rays in bulk: streams of single-ray any-hit walks, several
//! interleaved on one thread.
//!
//! A shadow ray's walk is a chain of dependent steps (a node's test picks the child whose
//! node is loaded and tested next), so one walk leaves most of the core idle: on
//! dream-apartment a shadow ray tests about 5 nodes and 1 leaf, yet takes about 70 ns. So
//! `WALKERS` walks advance in turn, one node or leaf test each, and the out-of-order core
//! overlaps their latencies: memory-level parallelism by interleaving independent pointer
//! chases (Kocberber, Falsafi & Grot 2015, "Asynchronous Memory Access Chaining").
//!
//! Per stream:
//! 1. the caller turns each ray into jobs, one per large BLAS whose TLAS box the ray enters
//!    (`AccelScene::occluded_stream`; a one-entry TLAS makes one job per ray without a
//!    walk);
//! 2. `WALKERS` walkers take the jobs in order, each walking its job's wide BLAS as a
//!    single ray's any-hit walk does (children in any order, the first hit ends it); a job
//!    whose ray another job found blocked is skipped.
//!
//! Each ray takes exactly the single-ray tests, so it finds what `AccelScene::occluded`
//! finds. What it gains (dream-apartment's shadow rays, one thread, one process, 21 runs):
//! 72 ns a ray one at a time, 68 in a stream of one walker, 60 with two, 62 with three, 64
//! with four. A hit child's push is one compressing vector store (`Lanes::push_children`):
//! with a loop per child instead, two walkers took 70 ns.

use std::mem::MaybeUninit;

use super::wide::{LEAF, Lanes, RayLanes, STACK, WIDTH, WideBvh, WideNode, leaf_blocks};

/// One ray's walk of one BLAS.
#[derive(Clone, Copy)]
pub(super) struct Job<'a> {
    pub(super) tree: &'a WideBvh,
    /// The ray in the tree's space.
    pub(super) ray: RayLanes,
    pub(super) t_max: f32,
    /// The ray's index in the stream.
    pub(super) index: usize,
}

/// What one step of a walk came to.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Step {
    Walking,
    Blocked,
    Clear,
}

/// Walks the `count` jobs (`job(i)`), `WALKERS` at a time, and sets `occluded[index]` for
/// each ray a job finds blocked (jobs of rays already blocked are skipped).
#[inline(always)]
pub(super) fn occluded_jobs<'a, K: Lanes, const WALKERS: usize>(
    count: usize,
    job: impl Fn(usize) -> Job<'a>,
    occluded: &mut [bool],
) {
    if count == 0 {
        return;
    }
    // Per walker, its job's fields and walk as separate arrays, which the compiler keeps
    // in registers once it unrolls the walker loop. Walkers past the last job hold a copy
    // of the last job but are not `live`.
    let first: [Job; WALKERS] = std::array::from_fn(|walker| job(walker.min(count - 1)));
    let mut tree = first.map(|job| job.tree);
    let mut rays = first.map(|job| job.ray);
    let mut t_max = first.map(|job| job.t_max);
    let mut index = first.map(|job| job.index);
    let mut current = [0u32; WALKERS];
    let mut depth = [0usize; WALKERS];
    // Rule (`STACK`'s): on a node `level` levels down (the root's is 1) a stack holds at
    // most 7 * (level - 1) entries, so a push's 8 slots end by 7 * level + 1 <= STACK.
    let mut stacks = [[const { MaybeUninit::<u32>::uninit() }; STACK]; WALKERS];
    let mut next = WALKERS.min(count);
    let mut live: u32 = (1 << next) - 1;
    while live != 0 {
        for walker in 0..WALKERS {
            if live >> walker & 1 == 0 {
                continue;
            }
            let step = step::<K>(
                tree[walker],
                &rays[walker],
                t_max[walker],
                &mut current[walker],
                &mut depth[walker],
                &mut stacks[walker],
            );
            if step == Step::Walking {
                continue;
            }
            if step == Step::Blocked {
                occluded[index[walker]] = true;
            }
            // The next job whose ray is not blocked yet.
            loop {
                if next == count {
                    live &= !(1 << walker);
                    break;
                }
                let job = job(next);
                next += 1;
                if !occluded[job.index] {
                    (tree[walker], rays[walker]) = (job.tree, job.ray);
                    (t_max[walker], index[walker]) = (job.t_max, job.index);
                    (current[walker], depth[walker]) = (0, 0);
                    break;
                }
            }
        }
    }
}

/// One node or leaf test of an any-hit walk of `tree`: a node's hit children are pushed
/// bar the highest lane, which is tested next.
#[inline(always)]
fn step<K: Lanes>(
    tree: &WideBvh,
    ray: &RayLanes,
    t_max: f32,
    current: &mut u32,
    depth: &mut usize,
    stack: &mut [MaybeUninit<u32>; STACK],
) -> Step {
    if tree.nodes.is_empty() {
        return Step::Clear;
    }
    if *current & LEAF == 0 {
        let node = &tree.nodes[*current as usize];
        let (hits, _) = K::node(node, ray, t_max);
        if hits != 0 {
            let last = 31 - hits.leading_zeros();
            *depth += push::<K>(node, hits ^ (1 << last), stack, *depth);
            *current = node.children[last as usize];
            return Step::Walking;
        }
    } else {
        let (first, count) = leaf_blocks(*current);
        for block in &tree.blocks[first..first + count] {
            if K::block(block, ray, t_max).0 != 0 {
                return Step::Blocked;
            }
        }
    }
    if *depth == 0 {
        return Step::Clear;
    }
    *depth -= 1;
    // SAFETY: `push` wrote every entry below `depth`.
    *current = unsafe { stack.get_unchecked(*depth).assume_init() };
    Step::Walking
}

/// Pushes the children of `node` in `lanes` at `depth`; returns how many.
#[inline(always)]
fn push<K: Lanes>(
    node: &WideNode,
    lanes: u32,
    stack: &mut [MaybeUninit<u32>; STACK],
    depth: usize,
) -> usize {
    debug_assert!(depth + WIDTH <= STACK);
    // SAFETY: depth + WIDTH <= STACK by `STACK`'s rule (see `occluded_jobs`).
    let slots = unsafe {
        &mut *stack
            .as_mut_ptr()
            .add(depth)
            .cast::<[MaybeUninit<u32>; WIDTH]>()
    };
    K::push_children(&node.children, lanes, slots)
}
