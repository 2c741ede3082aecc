//! Frame step `accel`, for coherent rays: packets of up to 64 rays (a 16 x 4 strip of a
//! render tile's camera rays) that walk the 8-wide trees together.
//!
//! Per packet:
//! 1. group the rays by direction octant (all of a group agree which face of a box is near);
//!    a ray whose reciprocal direction is not finite, a group too small to share a walk, or
//!    one whose directions spread wider than an 8-degree cone (`COHERENT_COS`) is traced a
//!    ray at a time;
//! 2. walk each group's tree once: an inner node's 8 child boxes are tested against the whole
//!    group at once by interval arithmetic over the rays' origins and reciprocal directions
//!    (Boulos et al. 2006, "Geometric and Arithmetic Culling Methods for Entire Ray Packets");
//!    children are visited nearest first by the group's earliest entry, and skipped once
//!    every ray has a hit nearer than that;
//! 3. at a leaf, each ray's own slab test against the leaf's box (8 rays per AVX2 test) picks
//!    the rays that go on to the single-ray triangle block test. Any-hit (shadow) walks take
//!    that per-ray test at every child the intervals admit and carry each subtree's rays
//!    down with it (`walk_packet`'s `MASKED`).
//!
//! What pays (dream-apartment, 512 x 512, one thread, `gloam raybench`, same runs): camera
//! rays 11.2 Mrays/s in packets against 5.5 alone (when both walked a TLAS; 16-17 against
//! 12-15 through the static batch). Shadow rays from a strip's hit points to points spread
//! over an area light gave 7.4 against 9.7 alone then, and 14.2-14.9 against 15-16 now:
//! their origins span the strip's visible depth and their directions the light, so the
//! intervals admit many boxes, and a group ends only when its last ray is blocked. The
//! renderer traces those as interleaved streams of single rays instead (accel/stream.rs;
//! `occluded_coherent` is here for rays that do converge, and for the comparison).
//!
//! Why no hit is lost: IEEE subtraction and multiplication round monotonically, so the
//! interval bound computed from the corners of `[origin] x [reciprocal]` is below (entry) or
//! above (exit) what any ray's own arithmetic gives, and the interval test passes every box
//! any one ray's test passes. Leaf boxes and triangles then get exactly the single-ray
//! tests, so every ray finds the hit distance it finds alone (the tests check it bit for
//! bit against brute force).

use std::mem::MaybeUninit;

use glam::Vec3A;
use obvhs::ray::Ray as ObvhsRay;

use super::Ray;

use super::wide::{
    Kernels, LEAF, Lanes, Portable, ROBUST_FAR, RayLanes, STACK, WIDTH, WideBvh, WideNode,
    WideTlas, leaf_blocks, max_dropping_nan, min_dropping_nan, slab_test,
};

/// Rays in a packet, one bit each in a `u64` mask.
pub const PACKET: usize = 64;

/// Octant groups smaller than this are traced ray by ray: a shared walk pays for its wider
/// node tests only when several rays share it.
const MIN_GROUP: u32 = 4;

/// Rays further than acos(0.99) = 8 degrees from their group's mean direction send the
/// group one ray at a time: the intervals of a wider cone admit so many boxes that a shared
/// walk costs more than single rays (random bounce directions in packets: 0.03 Mrays/s
/// against 3.5 alone, dream-apartment, `gloam raybench`). A 16 x 4 strip of camera rays
/// spans well under a degree.
const COHERENT_COS: f32 = 0.99;

/// The octant of a ray no packet takes (a direction or reciprocal that is not finite).
const LONE: usize = 8;

/// Up to 64 rays as lanes (structure of arrays), as the packet kernels read them.
#[derive(Clone)]
#[repr(C, align(32))]
pub struct RayPacket {
    origin: [[f32; PACKET]; 3],
    direction: [[f32; PACKET]; 3],
    /// 1 / direction, per axis (what the single-ray slab test multiplies by).
    inverse: [[f32; PACKET]; 3],
    t_min: [f32; PACKET],
    /// Bit `axis` set when the direction's component is negative; `LONE` for rays traced
    /// alone.
    octant: [u8; PACKET],
}

impl Default for RayPacket {
    fn default() -> Self {
        RayPacket {
            origin: [[0.0; PACKET]; 3],
            direction: [[0.0; PACKET]; 3],
            inverse: [[0.0; PACKET]; 3],
            t_min: [0.0; PACKET],
            octant: [LONE as u8; PACKET],
        }
    }
}

/// The lanes set in `mask`, lowest first.
#[inline(always)]
pub(crate) fn lanes_of(mut mask: u64) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        (mask != 0).then(|| {
            let lane = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            lane
        })
    })
}

/// A mask of the first `count` lanes.
#[inline]
pub fn first_lanes(count: usize) -> u64 {
    debug_assert!(count <= PACKET);
    if count >= PACKET {
        u64::MAX
    } else {
        (1u64 << count) - 1
    }
}

impl RayPacket {
    /// Up to 64 rays in lanes 0.., and each one's t_max (which the queries lower as they
    /// find hits).
    pub fn of_rays(rays: &[Ray]) -> (RayPacket, [f32; PACKET]) {
        debug_assert!(rays.len() <= PACKET);
        let mut packet = RayPacket::default();
        let mut t_max = [0.0; PACKET];
        for (lane, ray) in rays.iter().enumerate() {
            packet.place(lane, ray.origin, ray.direction, ray.t_min);
            t_max[lane] = ray.t_max;
        }
        packet.settle_lanes(rays.len());
        packet.settle_groups(first_lanes(rays.len()));
        (packet, t_max)
    }

    /// Puts `ray` in lane `lane` (its t_max stays with the caller, per query). Callers
    /// that fill a packet this way settle its groups with `settle_groups` before use.
    #[inline]
    fn set(&mut self, lane: usize, ray: &ObvhsRay) {
        self.place(lane, ray.origin, ray.direction, ray.tmin);
        self.settle_lane(lane);
    }

    /// The ray from `origin` along `direction`, from `t_min` on, in lane `lane`, before its
    /// reciprocal and octant are worked out (`settle_lane`).
    #[inline(always)]
    fn place(&mut self, lane: usize, origin: Vec3A, direction: Vec3A, t_min: f32) {
        for axis in 0..3 {
            self.origin[axis][lane] = origin[axis];
            self.direction[axis][lane] = direction[axis];
        }
        self.t_min[lane] = t_min;
    }

    /// `settle_lane` for lanes 0..`count` at once, in AVX2 lanes where the CPU has them
    /// (the same IEEE operations, so the same bits). Worked out a lane at a time as each
    /// ray was set, with a branch per axis, this was 3.7% of first-light's render
    /// instructions (callgrind).
    fn settle_lanes(&mut self, count: usize) {
        #[cfg(target_arch = "x86_64")]
        if crate::simd::avx2() {
            #[target_feature(enable = "avx2")]
            fn settle_lanes_avx2(packet: &mut RayPacket, count: usize) {
                packet.settle_lanes_portable(count);
            }
            // SAFETY: the CPU has AVX2, the only feature `settle_lanes_avx2` enables.
            return unsafe { settle_lanes_avx2(self, count) };
        }
        self.settle_lanes_portable(count);
    }

    #[inline(always)]
    fn settle_lanes_portable(&mut self, count: usize) {
        for lane in 0..count.min(PACKET) {
            self.settle_lane(lane);
        }
    }

    /// Lane `lane`'s reciprocal direction (a true one, as the single-ray test takes it) and
    /// octant: the signs of its reciprocal, or `LONE` when any of its origin, direction or
    /// reciprocal is not finite.
    #[inline(always)]
    fn settle_lane(&mut self, lane: usize) {
        let mut finite = true;
        let mut octant = 0;
        for axis in 0..3 {
            let (origin, direction) = (self.origin[axis][lane], self.direction[axis][lane]);
            let inverse = 1.0 / direction;
            self.inverse[axis][lane] = inverse;
            finite &= inverse.is_finite() & direction.is_finite() & origin.is_finite();
            // Branch-free, so the lanes vectorise: the sign bit is `is_sign_negative`.
            octant |= (inverse.to_bits() >> 31) << axis;
        }
        self.octant[lane] = if finite { octant as u8 } else { LONE as u8 };
    }

    /// Lane `lane` as a single ray ending at `t_max`.
    #[inline]
    pub fn ray(&self, lane: usize, t_max: f32) -> ObvhsRay {
        let vector =
            |rows: &[[f32; PACKET]; 3]| Vec3A::new(rows[0][lane], rows[1][lane], rows[2][lane]);
        ObvhsRay::new(
            vector(&self.origin),
            vector(&self.direction),
            self.t_min[lane],
            t_max,
        )
    }

    /// The rays in `rays`, each passed through `map` (into an instance's object space).
    pub fn mapped(&self, rays: u64, map: impl Fn(&ObvhsRay) -> ObvhsRay) -> RayPacket {
        let mut packet = RayPacket::default();
        for lane in lanes_of(rays) {
            packet.set(lane, &map(&self.ray(lane, f32::INFINITY)));
        }
        packet.settle_groups(rays);
        packet
    }

    /// Marks the rays of every octant group in `rays` that will not share a walk (too few,
    /// or spread too wide) to go alone, once per packet: the TLAS and each BLAS it reaches
    /// then read the groups as they are. Part of a settled group is still one (its cone
    /// lies inside the group's), so only the count is checked again.
    fn settle_groups(&mut self, rays: u64) {
        for (octant, group) in self.groups(rays).into_iter().enumerate() {
            if octant != LONE
                && group != 0
                && (group.count_ones() < MIN_GROUP || !self.coherent(group))
            {
                for lane in lanes_of(group) {
                    self.octant[lane] = LONE as u8;
                }
            }
        }
    }

    /// Whether the rays in `rays` point close enough together for a shared walk to pay:
    /// every direction within the cone of half-angle acos(COHERENT_COS) about their mean.
    /// (Only the walk's cost rests on the answer, never a hit: a group traced ray by ray
    /// finds what it finds together.) In plain lane arithmetic over the packet, for the
    /// compiler to vectorise: normalising each direction twice, a ray at a time, was 2.8%
    /// of first-light's render instructions (callgrind).
    fn coherent(&self, rays: u64) -> bool {
        #[cfg(target_arch = "x86_64")]
        if crate::simd::avx2() {
            #[target_feature(enable = "avx2")]
            fn coherent_avx2(packet: &RayPacket, rays: u64) -> bool {
                packet.coherent_lanes(rays)
            }
            // SAFETY: the CPU has AVX2, the only feature `coherent_avx2` enables.
            return unsafe { coherent_avx2(self, rays) };
        }
        self.coherent_lanes(rays)
    }

    #[inline(always)]
    fn coherent_lanes(&self, rays: u64) -> bool {
        // Each ray's unit direction (zero outside `rays`, and for a direction too short
        // or too long to normalise), and their sum.
        let mut unit = [[0.0f32; PACKET]; 3];
        for lane in 0..PACKET {
            let [x, y, z] = [0, 1, 2].map(|axis| self.direction[axis][lane]);
            let scale = 1.0 / (x * x + y * y + z * z).sqrt();
            // Selected, not scaled by zero: another group's lanes may hold infinities.
            let take = rays >> lane & 1 != 0 && scale.is_finite();
            for (axis, value) in [x, y, z].into_iter().enumerate() {
                unit[axis][lane] = if take { value * scale } else { 0.0 };
            }
        }
        let sum = unit.map(|plane| plane.iter().sum::<f32>());
        let length = (sum[0] * sum[0] + sum[1] * sum[1] + sum[2] * sum[2]).sqrt();
        if !(length > 0.0 && length.is_finite()) {
            return false;
        }
        let mean = sum.map(|value| value / length);
        // Every ray of `rays` near the mean (a lane outside them has a zero unit: ignored).
        let mut wide = 0u64;
        for lane in 0..PACKET {
            let cos = unit[0][lane] * mean[0] + unit[1][lane] * mean[1] + unit[2][lane] * mean[2];
            wide |= u64::from(cos < COHERENT_COS) << lane;
        }
        wide & rays == 0
    }

    /// `rays` split by octant; index `LONE` holds the rays traced alone.
    fn groups(&self, rays: u64) -> [u64; LONE + 1] {
        let mut groups = [0u64; LONE + 1];
        for lane in lanes_of(rays) {
            groups[self.octant[lane] as usize] |= 1 << lane;
        }
        groups
    }

    /// Lane `lane` as a single ray for the single-ray walks.
    #[inline]
    fn single(&self, lane: usize) -> RayLanes {
        let vector =
            |rows: &[[f32; PACKET]; 3]| Vec3A::new(rows[0][lane], rows[1][lane], rows[2][lane]);
        RayLanes::from_parts(
            vector(&self.origin),
            vector(&self.direction),
            self.t_min[lane],
        )
    }

    /// Lane `lane` as the single-ray kernels read it.
    #[inline(always)]
    fn lanes(&self, lane: usize, near: [usize; 3], far: [usize; 3]) -> RayLanes {
        RayLanes {
            origin: [0, 1, 2].map(|axis| self.origin[axis][lane]),
            direction: [0, 1, 2].map(|axis| self.direction[axis][lane]),
            inverse: [0, 1, 2].map(|axis| self.inverse[axis][lane]),
            near,
            far,
            t_min: self.t_min[lane],
        }
    }
}

/// One octant group of a packet as intervals: what the node test reads.
pub(crate) struct PacketBounds {
    origin_low: [f32; 3],
    origin_high: [f32; 3],
    inverse_low: [f32; 3],
    inverse_high: [f32; 3],
    /// The earliest t_min of the group.
    t_min: f32,
    /// Index into `WideNode::bounds` of each axis's near and far planes (shared: one octant).
    near: [usize; 3],
    far: [usize; 3],
    octant: usize,
    /// How many rays the intervals were taken over.
    rays: u32,
}

impl PacketBounds {
    /// Rule: `rays` is non-empty and every ray in it has octant `octant` (finite values).
    /// Inlined into its callers, the packet kernels, to be compiled for their AVX2.
    #[inline(always)]
    fn new(packet: &RayPacket, rays: u64, octant: usize) -> PacketBounds {
        debug_assert!(rays != 0 && octant < LONE);
        // Eight lanes of running bounds, one per lane of a vector, taken over the packet a
        // vector at a time and folded at the end (minima and maxima are exact in any
        // order). A ray at a time, this loop was 2.1% of first-light's render
        // instructions (callgrind). A comparison and a select are one `minps` or `maxps`:
        // `f32::min` and `max` also handle NaN, which the rule above excludes.
        const LANES: usize = 8;
        let low = |low: f32, value: f32, inside: bool| {
            if inside && value < low { value } else { low }
        };
        let high = |high: f32, value: f32, inside: bool| {
            if inside && value > high { value } else { high }
        };
        let mut origin_low = [[f32::INFINITY; LANES]; 3];
        let mut origin_high = [[f32::NEG_INFINITY; LANES]; 3];
        let mut inverse_low = [[f32::INFINITY; LANES]; 3];
        let mut inverse_high = [[f32::NEG_INFINITY; LANES]; 3];
        let mut t_min = [f32::INFINITY; LANES];
        for chunk in 0..PACKET / LANES {
            let bits = (rays >> (chunk * LANES)) as u32;
            for lane in 0..LANES {
                let inside = bits >> lane & 1 != 0;
                let at = chunk * LANES + lane;
                for axis in 0..3 {
                    let origin = packet.origin[axis][at];
                    let inverse = packet.inverse[axis][at];
                    origin_low[axis][lane] = low(origin_low[axis][lane], origin, inside);
                    origin_high[axis][lane] = high(origin_high[axis][lane], origin, inside);
                    inverse_low[axis][lane] = low(inverse_low[axis][lane], inverse, inside);
                    inverse_high[axis][lane] = high(inverse_high[axis][lane], inverse, inside);
                }
                t_min[lane] = low(t_min[lane], packet.t_min[at], inside);
            }
        }
        let fold_low = |lanes: [f32; LANES]| {
            (lanes.into_iter()).fold(f32::INFINITY, |folded, value| low(folded, value, true))
        };
        let fold_high = |lanes: [f32; LANES]| {
            (lanes.into_iter()).fold(f32::NEG_INFINITY, |folded, value| high(folded, value, true))
        };
        PacketBounds {
            origin_low: origin_low.map(fold_low),
            origin_high: origin_high.map(fold_high),
            inverse_low: inverse_low.map(fold_low),
            inverse_high: inverse_high.map(fold_high),
            t_min: fold_low(t_min),
            near: [0, 1, 2].map(|axis| {
                if octant >> axis & 1 != 0 {
                    3 + axis
                } else {
                    axis
                }
            }),
            far: [0, 1, 2].map(|axis| {
                if octant >> axis & 1 != 0 {
                    axis
                } else {
                    3 + axis
                }
            }),
            octant,
            rays: rays.count_ones(),
        }
    }
}

/// Per child lane in `hits`, the rays of `rays` whose own slab test enters that child's box
/// before their `t_max` (0 for the other lanes): a child box at a time, eight rays per test,
/// or, when few rays are left, a ray at a time against all eight boxes (the same
/// arithmetic either way).
#[inline(always)]
fn child_masks<K: PacketLanes>(
    node: &WideNode,
    hits: u32,
    packet: &RayPacket,
    bounds: &PacketBounds,
    rays: u64,
    t_max: &[f32; PACKET],
) -> [u64; WIDTH] {
    let mut masks = [0u64; WIDTH];
    if rays.count_ones() <= hits.count_ones() {
        for ray in lanes_of(rays) {
            let lanes = packet.lanes(ray, bounds.near, bounds.far);
            let (entered, _) = K::node(node, &lanes, t_max[ray]);
            let mut entered = entered & hits;
            while entered != 0 {
                let lane = entered.trailing_zeros() as usize;
                entered &= entered - 1;
                masks[lane] |= 1 << ray;
            }
        }
    } else {
        let mut remaining = hits;
        while remaining != 0 {
            let lane = remaining.trailing_zeros() as usize;
            remaining &= remaining - 1;
            masks[lane] = K::rays_in_box(node, lane, packet, bounds, rays, t_max);
        }
    }
    masks
}

/// The largest `t_max` among `rays` (-inf for none): a child entered later is of no use.
#[inline(always)]
fn farthest(t_max: &[f32; PACKET], rays: u64) -> f32 {
    // Eight running maxima, so the loop becomes one compare-and-select per 8 lanes.
    let mut partial = [f32::NEG_INFINITY; 8];
    for (chunk, values) in t_max.chunks_exact(8).enumerate() {
        for (lane, &value) in values.iter().enumerate() {
            let value = if rays >> (chunk * 8 + lane) & 1 != 0 {
                value
            } else {
                f32::NEG_INFINITY
            };
            partial[lane] = if value > partial[lane] {
                value
            } else {
                partial[lane]
            };
        }
    }
    partial.into_iter().fold(f32::NEG_INFINITY, f32::max)
}

/// The packet kernels, per implementation (beside the single-ray ones of `Lanes`).
pub(crate) trait PacketLanes: Lanes {
    /// Child lanes whose box some ray of the group may enter before `t_max`, and for each
    /// a lower bound of the rays' entry distances.
    fn packet_node(node: &WideNode, bounds: &PacketBounds, t_max: f32) -> (u32, [f32; WIDTH]);
    /// The rays in `rays` whose own slab test (`Lanes::node`'s arithmetic) enters child
    /// `lane` of `node` before their `t_max`.
    fn rays_in_box(
        node: &WideNode,
        lane: usize,
        packet: &RayPacket,
        bounds: &PacketBounds,
        rays: u64,
        t_max: &[f32; PACKET],
    ) -> u64;
}

impl PacketLanes for Portable {
    #[inline(always)]
    fn packet_node(node: &WideNode, bounds: &PacketBounds, t_max: f32) -> (u32, [f32; WIDTH]) {
        let mut entry = [0.0; WIDTH];
        let mut hits = 0;
        for lane in 0..WIDTH {
            let mut near = bounds.t_min;
            let mut far = t_max;
            for axis in 0..3 {
                let (low, high) = (bounds.inverse_low[axis], bounds.inverse_high[axis]);
                // (plane - origin) over the origins' interval, times the reciprocals': the
                // extremes lie at the corners.
                let near_plane = node.bounds[bounds.near[axis]][lane];
                let a = near_plane - bounds.origin_high[axis];
                let b = near_plane - bounds.origin_low[axis];
                let t_near = (a * low).min(a * high).min(b * low).min(b * high);
                let far_plane = node.bounds[bounds.far[axis]][lane];
                let c = far_plane - bounds.origin_high[axis];
                let d = far_plane - bounds.origin_low[axis];
                let t_far = (c * low).max(c * high).max(d * low).max(d * high);
                near = max_dropping_nan(t_near, near);
                far = min_dropping_nan(t_far, far);
            }
            entry[lane] = near;
            if near <= far * ROBUST_FAR {
                hits |= 1 << lane;
            }
        }
        (hits, entry)
    }

    #[inline(always)]
    fn rays_in_box(
        node: &WideNode,
        lane: usize,
        packet: &RayPacket,
        bounds: &PacketBounds,
        rays: u64,
        t_max: &[f32; PACKET],
    ) -> u64 {
        let mut inside = 0;
        for ray in lanes_of(rays) {
            let (_, entered) = slab_test(
                |axis| {
                    (
                        node.bounds[bounds.near[axis]][lane],
                        node.bounds[bounds.far[axis]][lane],
                    )
                },
                [0, 1, 2].map(|axis| packet.origin[axis][ray]),
                [0, 1, 2].map(|axis| packet.inverse[axis][ray]),
                packet.t_min[ray],
                t_max[ray],
            );
            inside |= (entered as u64) << ray;
        }
        inside
    }
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    //! The packet kernels in AVX2 intrinsics: eight child boxes per interval test, eight
    //! rays per leaf-box test.

    use std::arch::x86_64::*;

    use super::super::wide::avx2::{Avx2, entered};
    use super::{PACKET, PacketBounds, PacketLanes, ROBUST_FAR, RayPacket, WIDTH, WideNode};

    // The trait's methods cannot carry `#[target_feature]`, so they call kernels that do:
    // the intrinsics are then compiled for AVX2 even where the optimiser does not inline
    // them into an AVX2 caller (a closure it left out-of-line once called every intrinsic
    // as a function: primary rays fell from 5.4 to 0.8 Mrays/s).
    impl PacketLanes for Avx2 {
        #[inline(always)]
        fn packet_node(node: &WideNode, bounds: &PacketBounds, t_max: f32) -> (u32, [f32; WIDTH]) {
            // SAFETY: `Avx2` kernels run only where `Kernels::avx2` found AVX2.
            unsafe { Avx2::packet_node_kernel(node, bounds, t_max) }
        }

        #[inline(always)]
        fn rays_in_box(
            node: &WideNode,
            lane: usize,
            packet: &RayPacket,
            bounds: &PacketBounds,
            rays: u64,
            t_max: &[f32; PACKET],
        ) -> u64 {
            // SAFETY: `Avx2` kernels run only where `Kernels::avx2` found AVX2.
            unsafe { Avx2::rays_in_box_kernel(node, lane, packet, bounds, rays, t_max) }
        }
    }

    impl Avx2 {
        #[target_feature(enable = "avx2")]
        #[inline]
        fn packet_node_kernel(
            node: &WideNode,
            bounds: &PacketBounds,
            t_max: f32,
        ) -> (u32, [f32; WIDTH]) {
            // SAFETY: only reached from `#[target_feature(enable = "avx2")]` functions;
            // `WideNode` is 32-byte aligned.
            unsafe {
                let mut near = _mm256_set1_ps(bounds.t_min);
                let mut far = _mm256_set1_ps(t_max);
                for axis in 0..3 {
                    let low = _mm256_set1_ps(bounds.inverse_low[axis]);
                    let high = _mm256_set1_ps(bounds.inverse_high[axis]);
                    let origin_low = _mm256_set1_ps(bounds.origin_low[axis]);
                    let origin_high = _mm256_set1_ps(bounds.origin_high[axis]);
                    let near_plane = _mm256_load_ps(node.bounds[bounds.near[axis]].as_ptr());
                    let far_plane = _mm256_load_ps(node.bounds[bounds.far[axis]].as_ptr());
                    let a = _mm256_sub_ps(near_plane, origin_high);
                    let b = _mm256_sub_ps(near_plane, origin_low);
                    let t_near = _mm256_min_ps(
                        _mm256_min_ps(_mm256_mul_ps(a, low), _mm256_mul_ps(a, high)),
                        _mm256_min_ps(_mm256_mul_ps(b, low), _mm256_mul_ps(b, high)),
                    );
                    let c = _mm256_sub_ps(far_plane, origin_high);
                    let d = _mm256_sub_ps(far_plane, origin_low);
                    let t_far = _mm256_max_ps(
                        _mm256_max_ps(_mm256_mul_ps(c, low), _mm256_mul_ps(c, high)),
                        _mm256_max_ps(_mm256_mul_ps(d, low), _mm256_mul_ps(d, high)),
                    );
                    near = _mm256_max_ps(t_near, near);
                    far = _mm256_min_ps(t_far, far);
                }
                entered(near, far)
            }
        }

        #[target_feature(enable = "avx2")]
        #[inline]
        fn rays_in_box_kernel(
            node: &WideNode,
            lane: usize,
            packet: &RayPacket,
            bounds: &PacketBounds,
            rays: u64,
            t_max: &[f32; PACKET],
        ) -> u64 {
            let mut inside = 0u64;
            // SAFETY: as in `packet_node`; `RayPacket` is 32-byte aligned and its rows are
            // 64 floats, so every 8-lane group starts on a 32-byte boundary.
            unsafe {
                let planes = [0, 1, 2].map(|axis| {
                    (
                        _mm256_set1_ps(node.bounds[bounds.near[axis]][lane]),
                        _mm256_set1_ps(node.bounds[bounds.far[axis]][lane]),
                    )
                });
                let robust = _mm256_set1_ps(ROBUST_FAR);
                for group in 0..PACKET / 8 {
                    let wanted = (rays >> (group * 8)) & 0xff;
                    if wanted == 0 {
                        continue;
                    }
                    let at = group * 8;
                    let mut near = _mm256_load_ps(packet.t_min[at..].as_ptr());
                    let mut far = _mm256_loadu_ps(t_max[at..].as_ptr());
                    for (axis, &(near_plane, far_plane)) in planes.iter().enumerate() {
                        let origin = _mm256_load_ps(packet.origin[axis][at..].as_ptr());
                        let inverse = _mm256_load_ps(packet.inverse[axis][at..].as_ptr());
                        let t_near = _mm256_mul_ps(_mm256_sub_ps(near_plane, origin), inverse);
                        let t_far = _mm256_mul_ps(_mm256_sub_ps(far_plane, origin), inverse);
                        near = _mm256_max_ps(t_near, near);
                        far = _mm256_min_ps(t_far, far);
                    }
                    let hit = _mm256_cmp_ps::<_CMP_LE_OQ>(near, _mm256_mul_ps(far, robust));
                    inside |= ((_mm256_movemask_ps(hit) as u64) & wanted) << at;
                }
            }
            inside
        }
    }
}

/// Walks `nodes` with the rays of one octant group, nearest child first (with `ANY`, in any
/// order), calling `leaf(reference, rays, t_max)` with the rays whose own test enters each
/// leaf's box before their `t_max`; `leaf` lowers the `t_max` of rays it finds closer hits
/// for and returns which rays hit (with `ANY`, those rays then leave the walk). Returns every
/// ray `leaf` reported.
///
/// With `MASKED`, every child the group's interval test admits is also tested ray by ray
/// (`child_masks`), and the walk carries the rays inside each subtree: a child no ray
/// enters is skipped, and a leaf gets exactly its rays without a test of its own. That pays
/// for shadow rays, whose origins spread over a strip's visible depth so that the
/// intervals admit many boxes no ray enters: dream-apartment's shadow rays in packets went
/// from 13.0-13.6 to 14.2-14.9 Mrays/s (`gloam raybench`, one thread, two runs, both
/// walks in each run), while camera rays, whose intervals are tight, fell from 15.5-16.3 to 14.0-15.0;
/// so any-hit walks are masked and closest-hit walks are not. (Handing a subtree that only
/// one to four rays enter to single-ray walks, Benthin et al. 2012, measured no better.)
#[inline(always)]
fn walk_packet<K: PacketLanes, const ANY: bool, const MASKED: bool>(
    nodes: &[WideNode],
    packet: &RayPacket,
    mut bounds: PacketBounds,
    mut rays: u64,
    t_max: &mut [f32; PACKET],
    mut leaf: impl FnMut(u32, u64, &mut [f32; PACKET]) -> u64,
) -> u64 {
    let mut found = 0;
    if nodes.is_empty() || rays == 0 {
        return found;
    }
    // Rule: node indices fit in 29 bits (a tree that large would need 100 GB), so a child's
    // parent is kept as node * 8 + lane. Entries below `depth` are written before read.
    debug_assert!(nodes.len() < 1 << 29);
    let mut stack = [const { MaybeUninit::<(u32, f32, u32, u64)>::uninit() }; STACK];
    // SAFETY: `read` is only called at indices below `depth`.
    let read = |stack: &[MaybeUninit<(u32, f32, u32, u64)>; STACK], at: usize| unsafe {
        stack[at].assume_init()
    };
    let mut depth = 0usize;
    let mut current = 0u32;
    let mut parent = 0u32;
    // With `MASKED`: the rays whose own tests enter `current`'s box.
    let mut active = rays;
    let mut t_far = farthest(t_max, rays);
    loop {
        if current & LEAF == 0 {
            let node = &nodes[current as usize];
            let (mut hits, entry) = K::packet_node(node, &bounds, t_far);
            let mut masks = [0u64; WIDTH];
            if MASKED && hits != 0 {
                masks = child_masks::<K>(node, hits, packet, &bounds, active, t_max);
                for (lane, mask) in masks.iter().enumerate() {
                    if *mask == 0 {
                        hits &= !(1 << lane);
                    }
                }
            }
            if hits != 0 {
                let at = current << 3;
                if hits.count_ones() == 1 {
                    let lane = hits.trailing_zeros();
                    parent = at | lane;
                    current = node.children[lane as usize];
                    active = masks[lane as usize];
                    continue;
                }
                // Farthest first under the nearest, as the single-ray walk does.
                let base = depth;
                while hits != 0 {
                    let lane = hits.trailing_zeros();
                    hits &= hits - 1;
                    let item = (
                        node.children[lane as usize],
                        entry[lane as usize],
                        at | lane,
                        masks[lane as usize],
                    );
                    let mut slot = depth;
                    if !ANY {
                        while slot > base && read(&stack, slot - 1).1 < item.1 {
                            stack[slot] = stack[slot - 1];
                            slot -= 1;
                        }
                    }
                    stack[slot].write(item);
                    depth += 1;
                }
                depth -= 1;
                // (Masks are taken over `active`, which holds only rays still walking.)
                (current, _, parent, active) = read(&stack, depth);
                continue;
            }
        } else {
            let inside = if MASKED {
                active & rays
            } else {
                let node = &nodes[(parent >> 3) as usize];
                K::rays_in_box(node, (parent & 7) as usize, packet, &bounds, rays, t_max)
            };
            if inside != 0 {
                let hit = leaf(current, inside, t_max);
                if hit != 0 {
                    found |= hit;
                    if ANY {
                        rays &= !hit;
                        if rays == 0 {
                            return found;
                        }
                        // Blocked rays leave the walk: once half have, the intervals are
                        // taken again over the rest, tighter. (Boxes already on the stack
                        // were tested with the wider ones, which is conservative.)
                        if rays.count_ones() * 2 <= bounds.rays {
                            bounds = PacketBounds::new(packet, rays, bounds.octant);
                        }
                    }
                    t_far = farthest(t_max, rays);
                }
            }
        }
        // Next: the nearest pending child some ray may still need.
        loop {
            if depth == 0 {
                return found;
            }
            depth -= 1;
            let (child, entry, from, mask) = read(&stack, depth);
            if entry <= t_far && (!MASKED || mask & rays != 0) {
                current = child;
                parent = from;
                active = mask & rays;
                break;
            }
        }
    }
}

impl WideBvh {
    /// Closest hits of the rays in `rays` (any octants): for each ray that finds a hit nearer
    /// than its `t_max[lane]`, lowers `t_max[lane]` to it and sets `slots[lane]` (see
    /// `triangle_at`). Returns those rays. Each ray finds what `intersect_slot` finds.
    pub fn intersect_packet(
        &self,
        packet: &RayPacket,
        rays: u64,
        t_max: &mut [f32; PACKET],
        slots: &mut [u32; PACKET],
        kernels: Kernels,
    ) -> u64 {
        #[cfg(target_arch = "x86_64")]
        if kernels.avx2() {
            // SAFETY: the CPU has AVX2, the only feature the function enables.
            return unsafe { self.intersect_packet_avx2(packet, rays, t_max, slots) };
        }
        let _ = kernels;
        self.traverse_packet::<Portable, false>(packet, rays, t_max, slots)
    }

    /// The rays in `rays` that something blocks within `(t_min, t_max[lane])` (any hit).
    pub fn occluded_packet(
        &self,
        packet: &RayPacket,
        rays: u64,
        t_max: &[f32; PACKET],
        kernels: Kernels,
    ) -> u64 {
        let mut t_max = *t_max;
        let mut slots = [0; PACKET];
        #[cfg(target_arch = "x86_64")]
        if kernels.avx2() {
            // SAFETY: as in `intersect_packet`.
            return unsafe { self.occluded_packet_avx2(packet, rays, &mut t_max, &mut slots) };
        }
        let _ = kernels;
        self.traverse_packet::<Portable, true>(packet, rays, &mut t_max, &mut slots)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn intersect_packet_avx2(
        &self,
        packet: &RayPacket,
        rays: u64,
        t_max: &mut [f32; PACKET],
        slots: &mut [u32; PACKET],
    ) -> u64 {
        self.traverse_packet::<Avx2, false>(packet, rays, t_max, slots)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn occluded_packet_avx2(
        &self,
        packet: &RayPacket,
        rays: u64,
        t_max: &mut [f32; PACKET],
        slots: &mut [u32; PACKET],
    ) -> u64 {
        self.traverse_packet::<Avx2, true>(packet, rays, t_max, slots)
    }

    #[inline(always)]
    fn traverse_packet<K: PacketLanes, const ANY: bool>(
        &self,
        packet: &RayPacket,
        rays: u64,
        t_max: &mut [f32; PACKET],
        slots: &mut [u32; PACKET],
    ) -> u64 {
        let mut found = 0;
        if self.nodes.is_empty() {
            return found;
        }
        for (octant, group) in packet.groups(rays).into_iter().enumerate() {
            if group == 0 {
                continue;
            }
            if octant == LONE || group.count_ones() < MIN_GROUP {
                for lane in lanes_of(group) {
                    if let Some((t, slot)) =
                        self.traverse::<K, ANY>(&packet.single(lane), t_max[lane])
                    {
                        found |= 1 << lane;
                        if !ANY {
                            t_max[lane] = t;
                            slots[lane] = slot;
                        }
                    }
                }
                continue;
            }
            let bounds = PacketBounds::new(packet, group, octant);
            let (near, far) = (bounds.near, bounds.far);
            let leaf = |leaf, inside, t_max: &mut [f32; PACKET]| {
                let (first, count) = leaf_blocks(leaf);
                let blocks = &self.blocks[first..first + count];
                let mut hit = 0;
                for lane in lanes_of(inside) {
                    let ray = packet.lanes(lane, near, far);
                    for (index, block) in blocks.iter().enumerate() {
                        let (mut hits, t) = K::block(block, &ray, t_max[lane]);
                        if ANY {
                            if hits != 0 {
                                hit |= 1 << lane;
                                break;
                            }
                            continue;
                        }
                        // As the single-ray walk: strictly nearer replaces.
                        while hits != 0 {
                            let triangle = hits.trailing_zeros() as usize;
                            hits &= hits - 1;
                            if t[triangle] < t_max[lane] {
                                t_max[lane] = t[triangle];
                                slots[lane] = ((first + index) * WIDTH + triangle) as u32;
                                hit |= 1 << lane;
                            }
                        }
                    }
                }
                hit
            };
            // Any-hit walks carry per-ray masks (`walk_packet`), closest-hit walks do not.
            found |= walk_packet::<K, ANY, ANY>(&self.nodes, packet, bounds, group, t_max, leaf);
        }
        found
    }
}

#[cfg(target_arch = "x86_64")]
use super::wide::avx2::Avx2;

impl WideTlas {
    /// Walks the TLAS with the rays in `rays`, calling `visit(slot, rays, t_max)` for each
    /// primitive slot (index into the BVH2's `primitive_indices`) with the rays whose test
    /// enters its leaf's box before their `t_max`; `visit` lowers `t_max` for the rays it
    /// finds nearer hits for and returns which rays hit. With `any`, a ray that hit leaves
    /// the walk. Returns every ray that hit.
    pub fn walk_packet(
        &self,
        packet: &RayPacket,
        rays: u64,
        kernels: Kernels,
        any: bool,
        t_max: &mut [f32; PACKET],
        mut visit: impl FnMut(usize, u64, &mut [f32; PACKET]) -> u64,
    ) -> u64 {
        // A one-entry tree is not walked (`sole_entry`): every ray goes to slot 0.
        if self.sole_entry {
            return visit(0, rays, t_max);
        }
        #[cfg(target_arch = "x86_64")]
        if kernels.avx2() {
            // SAFETY: the CPU has AVX2, the only feature the function enables.
            return unsafe { self.walk_packet_avx2(packet, rays, any, t_max, visit) };
        }
        let _ = kernels;
        self.walk_packet_with::<Portable>(packet, rays, any, t_max, visit)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn walk_packet_avx2(
        &self,
        packet: &RayPacket,
        rays: u64,
        any: bool,
        t_max: &mut [f32; PACKET],
        visit: impl FnMut(usize, u64, &mut [f32; PACKET]) -> u64,
    ) -> u64 {
        self.walk_packet_with::<Avx2>(packet, rays, any, t_max, visit)
    }

    #[inline(always)]
    fn walk_packet_with<K: PacketLanes>(
        &self,
        packet: &RayPacket,
        rays: u64,
        any: bool,
        t_max: &mut [f32; PACKET],
        mut visit: impl FnMut(usize, u64, &mut [f32; PACKET]) -> u64,
    ) -> u64 {
        let mut found = 0;
        for (octant, group) in packet.groups(rays).into_iter().enumerate() {
            if group == 0 {
                continue;
            }
            if octant == LONE || group.count_ones() < MIN_GROUP {
                for lane in lanes_of(group) {
                    let ray = packet.single(lane);
                    let ray_t_max = t_max[lane];
                    let t_max = &mut *t_max;
                    let hit = self.walk_with::<K>(&ray, ray_t_max, any, |slot, _| {
                        (visit(slot, 1 << lane, t_max) != 0).then_some(t_max[lane])
                    });
                    if hit {
                        found |= 1 << lane;
                    }
                }
                continue;
            }
            let bounds = PacketBounds::new(packet, group, octant);
            let mut leaf = |reference: u32, inside: u64, t_max: &mut [f32; PACKET]| {
                let (first, count) = leaf_blocks(reference);
                let mut remaining = inside;
                let mut hit = 0;
                for slot in first..first + count {
                    let found = visit(slot, remaining, t_max);
                    hit |= found;
                    if any {
                        remaining &= !found;
                        if remaining == 0 {
                            break;
                        }
                    }
                }
                hit
            };
            found |= if any {
                walk_packet::<K, true, true>(&self.nodes, packet, bounds, group, t_max, &mut leaf)
            } else {
                walk_packet::<K, false, false>(&self.nodes, packet, bounds, group, t_max, &mut leaf)
            };
        }
        found
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn farthest_reads_only_the_rays_asked_for() {
        let mut t_max = [0.0; PACKET];
        for (lane, t) in t_max.iter_mut().enumerate() {
            *t = lane as f32;
        }
        assert_eq!(farthest(&t_max, u64::MAX), 63.0);
        assert_eq!(farthest(&t_max, 1 << 17 | 1 << 3), 17.0);
        assert_eq!(farthest(&t_max, 0), f32::NEG_INFINITY);
    }

    #[test]
    fn axis_parallel_and_non_finite_rays_are_traced_alone() {
        let mut packet = RayPacket::default();
        let origin = glam::Vec3A::ZERO;
        packet.set(
            0,
            &ObvhsRay::new(origin, Vec3A::new(1.0, -2.0, 3.0), 0.0, 1.0),
        );
        packet.set(
            1,
            &ObvhsRay::new(origin, Vec3A::new(1.0, 0.0, 3.0), 0.0, 1.0),
        );
        packet.set(
            2,
            &ObvhsRay::new(origin, Vec3A::new(-1.0, -2.0, -3.0), 0.0, 1.0),
        );
        let groups = packet.groups(0b111);
        assert_eq!(groups[0b010], 0b001);
        assert_eq!(groups[LONE], 0b010);
        assert_eq!(groups[0b111], 0b100);
    }

    fn ray(origin: Vec3A, direction: Vec3A) -> Ray {
        Ray {
            origin,
            direction,
            t_min: 0.0,
            t_max: 1.0,
        }
    }

    #[test]
    fn a_packet_of_rays_settles_each_lane_as_setting_it_alone_does() {
        let directions = [
            Vec3A::new(1.0, -2.0, 3.0),
            Vec3A::new(1.0, 0.0, 3.0),
            Vec3A::new(-1.0, -2.0, -3.0),
            Vec3A::new(-0.0, 1.0, 1.0),
            Vec3A::new(f32::NAN, 1.0, 1.0),
            Vec3A::new(1e-39, 1.0, 1.0),
            Vec3A::new(f32::INFINITY, 1.0, 1.0),
            Vec3A::new(0.3, 0.2, -0.9),
        ];
        let rays: Vec<Ray> = directions
            .iter()
            .map(|&direction| ray(Vec3A::new(0.5, 1.0, -2.0), direction))
            .chain([ray(Vec3A::new(f32::NAN, 0.0, 0.0), Vec3A::ONE)])
            .collect();
        // Before `of_rays` settles the octant groups, which sends small ones alone.
        let mut packet = RayPacket::default();
        for (lane, ray) in rays.iter().enumerate() {
            packet.place(lane, ray.origin, ray.direction, ray.t_min);
        }
        packet.settle_lanes(rays.len());
        for (lane, ray) in rays.iter().enumerate() {
            let mut alone = RayPacket::default();
            alone.set(0, &ray.to_obvhs());
            assert_eq!(packet.octant[lane], alone.octant[0], "lane {lane}");
            for axis in 0..3 {
                let (inverse, expected) = (packet.inverse[axis][lane], alone.inverse[axis][0]);
                assert_eq!(inverse.to_bits(), expected.to_bits(), "lane {lane}");
            }
        }
        assert!(packet.octant[rays.len()..].iter().all(|&o| o == LONE as u8));
    }

    #[test]
    fn a_group_is_coherent_while_its_directions_stay_in_the_cone() {
        let strip = |spread: f32, stray: Option<Vec3A>| {
            let mut rays: Vec<Ray> = (0..16)
                .map(|i| ray(Vec3A::ZERO, Vec3A::new(1.0 + spread * i as f32, 0.5, 0.25)))
                .collect();
            rays.extend(stray.map(|direction| ray(Vec3A::ZERO, direction)));
            RayPacket::of_rays(&rays).0
        };
        let narrow = strip(0.001, None);
        assert!(narrow.coherent(first_lanes(16)));
        // A ray of another octant's group (here one traced alone) does not count.
        let with_lone = strip(0.001, Some(Vec3A::new(f32::INFINITY, 1.0, 1.0)));
        assert!(with_lone.coherent(first_lanes(16)));
        assert!(!with_lone.coherent(first_lanes(17)));
        // Directions 23 degrees apart (x from 1 to 5.5) are not.
        assert!(!strip(0.3, None).coherent(first_lanes(16)));
        // Nor is a group with a direction that cannot be normalised.
        let tiny = strip(0.001, Some(Vec3A::splat(1e-30)));
        assert!(!tiny.coherent(first_lanes(17)));
    }
}
