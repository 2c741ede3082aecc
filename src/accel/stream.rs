//! Frame step `accel`, for shadow rays in bulk: streams of single-ray any-hit walks, two
//! interleaved on one thread.
//!
//! A shadow ray's walk is a chain of dependent steps (a node's test picks the child whose
//! node is loaded and tested next), so one walk leaves most of the core idle: on
//! dream-apartment a shadow ray tests about 5 nodes and 1 leaf, yet takes about 70 ns. So
//! two walks advance in turn, one node or leaf test each, and the out-of-order core
//! overlaps their latencies: memory-level parallelism by interleaving independent pointer
//! chases (Kocberber, Falsafi & Grot 2015, "Asynchronous Memory Access Chaining").
//!
//! Per stream:
//! 1. the caller turns each ray into jobs, one per large BLAS whose TLAS box the ray enters
//!    (`AccelScene::occluded_stream`; a one-entry TLAS makes one job per ray without a
//!    walk);
//! 2. two walkers take the jobs in order, each walking its job's wide BLAS as a
//!    single ray's any-hit walk does (children in the order the build chose for occlusion,
//!    the first hit ends it); a job
//!    whose ray another job found blocked is skipped.
//!
//! Each ray takes exactly the single-ray tests, so it finds what `AccelScene::occluded`
//! finds. What it gains (dream-apartment's shadow rays, one thread, one process, 21 runs):
//! 72 ns a ray one at a time, 68 in a stream of one walker, 60 with two, 62 with three, 64
//! with four, all walkers in an array. Two walkers written out as variables take 7% less
//! again (`occluded_jobs`). A hit child's push is one compressing vector store
//! (`Lanes::push_children`): with a loop per child instead, two walkers took 70 ns.

use std::mem::MaybeUninit;

use super::wide::{LEAF, Lanes, RayLanes, STACK, WIDTH, WideBvh, WideNode, leaf_blocks};

/// One ray's walk of one BLAS.
#[derive(Clone, Copy)]
pub(super) struct Job<'a> {
    /// Rule: a tree with nodes (callers make no job for an empty one), so a step need not
    /// ask: asking at every step was 4.5% of a shadow ray's instructions (588 against 562
    /// a ray, dream-apartment, callgrind).
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

/// One walker's job and where its walk stands.
struct Walk<'a> {
    tree: &'a WideBvh,
    ray: RayLanes,
    t_max: f32,
    index: usize,
    current: u32,
    depth: usize,
}

impl<'a> Walk<'a> {
    #[inline(always)]
    fn new(job: Job<'a>) -> Walk<'a> {
        debug_assert!(!job.tree.nodes.is_empty(), "a job on an empty tree");
        Walk {
            tree: job.tree,
            ray: job.ray,
            t_max: job.t_max,
            index: job.index,
            current: 0,
            depth: 0,
        }
    }

    /// Forwards to the free `step`, whose walk state comes in as separate references: the
    /// same body written as this method measured 2-3% slower (16.6 against 17.0 and 16.2
    /// against 16.5 Mrays/s, dream-apartment's shadow rays, one thread, medians of 6 and 4
    /// alternated runs).
    #[inline(always)]
    fn step<K: Lanes>(&mut self, stack: &mut [MaybeUninit<u32>; STACK]) -> Step {
        step::<K>(
            self.tree,
            &self.ray,
            self.t_max,
            &mut self.current,
            &mut self.depth,
            stack,
        )
    }
}

/// Walks the `count` jobs (`job(i)`), two at a time, and sets `occluded[index]` for each
/// ray a job finds blocked (jobs of rays already blocked are skipped).
///
/// The two walkers are two named variables, not an array walked by a loop: the optimiser
/// keeps each one's walk (its node, depth and ray) in registers, where a loop over an array
/// of walkers kept them in memory and reloaded them every step: 18.4 against 19.7 Mrays/s
/// (54 against 51 ns a ray, dream-apartment's shadow rays, one thread, medians of 200 timings
/// in each of three alternated runs). A third walker written out added under 2%, within what
/// the machine's noise moves, for a third stack and walk: two stay.
#[inline(always)]
pub(super) fn occluded_jobs<'a, K: Lanes>(
    count: usize,
    job: impl Fn(usize) -> Job<'a>,
    occluded: &mut [bool],
) {
    let next_job = |next: &mut usize, occluded: &[bool]| {
        while *next < count {
            let job = job(*next);
            *next += 1;
            if !occluded[job.index] {
                return Some(job);
            }
        }
        None
    };
    let finish = |walk: &mut Walk, stack: &mut [MaybeUninit<u32>; STACK], occluded: &mut [bool]| loop {
        match walk.step::<K>(stack) {
            Step::Walking => continue,
            Step::Blocked => {
                occluded[walk.index] = true;
                return;
            }
            Step::Clear => return,
        }
    };
    // Rule (`STACK`'s): on a node `level` levels down (the root's is 1) a stack holds at
    // most 7 * (level - 1) entries, so a push's 8 slots end by 7 * level + 1 <= STACK.
    let mut stacks = [[const { MaybeUninit::<u32>::uninit() }; STACK]; 2];
    let [stack_a, stack_b] = &mut stacks;
    let mut next = 0;
    let Some(first) = next_job(&mut next, occluded) else {
        return;
    };
    let mut a = Walk::new(first);
    let Some(second) = next_job(&mut next, occluded) else {
        return finish(&mut a, stack_a, occluded);
    };
    let mut b = Walk::new(second);
    loop {
        let step_a = a.step::<K>(stack_a);
        let step_b = b.step::<K>(stack_b);
        if step_a != Step::Walking {
            if step_a == Step::Blocked {
                occluded[a.index] = true;
            }
            match next_job(&mut next, occluded) {
                Some(job) => a = Walk::new(job),
                None => {
                    match step_b {
                        Step::Walking => finish(&mut b, stack_b, occluded),
                        Step::Blocked => occluded[b.index] = true,
                        Step::Clear => {}
                    }
                    return;
                }
            }
        }
        if step_b != Step::Walking {
            if step_b == Step::Blocked {
                occluded[b.index] = true;
            }
            match next_job(&mut next, occluded) {
                Some(job) => b = Walk::new(job),
                None => return finish(&mut a, stack_a, occluded),
            }
        }
    }
}

/// One node or leaf test of an any-hit walk of `tree`: a node's hit children are pushed
/// bar the highest lane, which is tested next (the child the build judged likeliest to
/// block the ray for its cost: `WideBvh::order_for_occlusion`).
#[inline(always)]
fn step<K: Lanes>(
    tree: &WideBvh,
    ray: &RayLanes,
    t_max: f32,
    current: &mut u32,
    depth: &mut usize,
    stack: &mut [MaybeUninit<u32>; STACK],
) -> Step {
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
