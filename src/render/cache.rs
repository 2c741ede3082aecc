//! Frame step `render`: the real-time renderer's radiance cache, which ends at their
//! second vertex most of the paths whose second vertex it may stand in for (86-89% on the
//! three levels' play-throughs; the rest teach it or find a cell still learning). It owns
//! a world-space hash grid of the light diffuse surfaces reflect, learnt from the paths
//! that go on, frame after frame.
//!
//! After the method of NVIDIA's spatially hashed radiance cache (SHaRC, RTXGI 2024) and
//! Müller et al. 2021 ("Real-time Neural Radiance Caching for Path Tracing"): a few paths
//! (`trains`: one pixel in each 4 x 4 block, taking turns over 16 frames) are traced in
//! full, and what arrived back at their second vertex is averaged into that vertex's cell;
//! the others, at a second vertex whose cell has learnt enough, take the cell's light
//! instead of tracing on. That saves the vertex's shadow ray and everything after it.
//!
//! Per frame:
//! 1. the tiles read the cache as the last frame left it (read only, so the frame does not
//!    depend on the order the threads take the tiles in);
//! 2. each tile lists its full paths' samples (`CacheSample`), which the render hands back
//!    tile by tile in image order (`RenderOutput::cache_samples`);
//! 3. before the next frame's render, `learn` folds them in, in that order, into each
//!    cell's running mean (the game's film step does it on a pool thread while the frame
//!    goes on: film/mod.rs).
//!
//! When the light set is built anew (a lamp doused or lit), `relit` makes each cell's next
//! sample replace its light and one pixel in 4 teach for a few frames, so the light that
//! went out leaves the bounce light as fast as it left the direct light.
//!
//! A cell is a cube whose side doubles with the distance from the camera (about four
//! render pixels across wherever it is seen), keyed with the axis its surface faces, so the
//! two faces of a thin wall never share one. It stores what the surface reflects divided
//! by its albedo (the light arriving, in effect), which the vertex's own albedo multiplies
//! back: textures keep their detail across a cell.
//!
//! Only a second vertex on a diffuse surface, reached by a diffuse bounce from farther away
//! than its cell's side, takes the cache: a mirror would show the cells' blocks, and in a
//! corner the cell would reach past the corner into the other wall.
//!
//! What it bought, on the play-throughs at 640 x 360 rendered at half scale (`gloam bench
//! --replay`, medians of three alternated runs): it ends 62% of the-gallery's paths at their
//! second vertex, 48% of the-keep's and 38% of first-light's; frame p50 went from 38.9 to
//! 28.5 ms on the-gallery (render 32.4 to 22.1), from 35.8 to 29.5 on the-keep (render
//! 28.6 to 22.5) and from 22.8 to 20.7 on first-light (whose bounce rays mostly leave
//! through the sky); p99 from 46.9, 44.5 and 27.4 to 31.9, 39.4 and 24.1 ms. It also
//! lowers the error: `gloam flythrough` at 640 x 360 puts the player's view at 0.0195,
//! 0.0201 and 0.0226 (first-light, the-gallery, the-keep; from 0.0204, 0.0215 and 0.0231),
//! and the-gallery's moving lamp's pool at 0.0364 (from 0.0491). With every light of
//! first-light put out, `relit` takes the bounce light still there 4 to 12 frames later
//! from 6.9% of what went out to 0.0%, so a doused corner looks as dark as the wardens
//! find it. Folding the samples in at the render's end had taken 0.22 ms of a 9.3 ms
//! render on one core while the other waited, hence the pool thread.

use glam::{Vec3, Vec3A};

use super::Camera;
use super::material::floor;
use crate::accel::prefetch;

/// How large cells are where: from the camera's eye, `CELL_PIXELS` of its pixels across.
#[derive(Clone, Copy, Debug)]
pub struct CellSizing {
    pub eye: Vec3A,
    /// A cell's side a metre from the eye.
    pub side_per_metre: f32,
}

impl CellSizing {
    pub fn of(camera: &Camera) -> CellSizing {
        CellSizing {
            eye: camera.position,
            side_per_metre: CELL_PIXELS * 2.0 * camera.tan_half_fov / camera.height.max(1) as f32,
        }
    }
}

/// The smallest cell's side, in metres.
const CELL_MIN: f32 = 0.05;
/// About how many render pixels a cell spans where the camera sees it.
const CELL_PIXELS: f32 = 4.0;
/// Slots in the table: 2^16 cells of 32 bytes, 2 MB.
const SLOTS: usize = 1 << 16;
/// Slots probed from a key's hash before a cell gives up its place.
const PROBES: usize = 8;
/// How many samples ahead of the one `learn` folds in it asks for the slots of.
const LEARN_AHEAD: usize = 4;
/// A cell's running mean weighs its newest samples at least this much (against all it has
/// learnt). A cell learns only every few frames, so its light trails a moving lamp's by
/// more frames than this suggests; 1/8 measured no better (`gloam flythrough` the-gallery,
/// player's view RMSE 0.0201 with either).
const NEWEST_WEIGHT: f32 = 1.0 / 16.0;
/// Samples a cell must have learnt before paths take its light.
const SAMPLES_TO_TRUST: f32 = 4.0;
/// Frames after the lights change in which one pixel in 4 teaches, not one in 16.
const EAGER_FRAMES: u32 = 8;
/// Frames after which a cell nothing has trained is forgotten.
const FRAMES_TO_FORGET: u32 = 32;

/// floor(log2(v)) for v >= 1, as `v.log2()` then truncated gives it (infinity and NaN:
/// u32::MAX and 0). Its binary exponent, read off its bits, except within 2^-16 below the
/// next power of two, where `log2f` may round up to it: only there is it called (it was
/// 0.6% of the-gallery's frame cycles, called for every cell: perf).
#[inline]
fn floor_log2_at_least_one(v: f32) -> u32 {
    let bits = v.to_bits();
    let exponent = (bits >> 23).wrapping_sub(127);
    let mantissa_top = (bits >> 7) & 0xffff;
    if v.is_finite() && mantissa_top != 0xffff {
        exponent
    } else {
        v.log2() as u32
    }
}

/// A cell's identity: its level, the axis its surface faces and its coordinates, packed.
/// 0 is no cell.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct CellKey(u64);

impl CellKey {
    /// The cell of a surface point `position` facing `normal`, and the cell's side: a
    /// power of two times `CELL_MIN`, at most the side `sizing` asks for there.
    pub fn at(position: Vec3A, normal: Vec3A, sizing: &CellSizing) -> (CellKey, f32) {
        let wanted = position.distance(sizing.eye) * sizing.side_per_metre;
        let level = u64::from(floor_log2_at_least_one((wanted / CELL_MIN).max(1.0)).min(15));
        let side = CELL_MIN * (1u32 << level) as f32;
        let axis = {
            let a = normal.abs();
            let (index, value) = if a.x >= a.y && a.x >= a.z {
                (0, normal.x)
            } else if a.y >= a.z {
                (1, normal.y)
            } else {
                (2, normal.z)
            };
            2 * index + (value < 0.0) as u64
        };
        // 17 bits a coordinate: +-65536 cells, 3.2 km at the smallest side.
        let coordinate = |value: f32| (floor(value / side) as i64 & 0x1ffff) as u64;
        let key = 1 << 63
            | level << 54
            | axis << 51
            | coordinate(position.x) << 34
            | coordinate(position.y) << 17
            | coordinate(position.z);
        (CellKey(key), side)
    }

    /// The slot probing starts from (a 64-bit finaliser: murmur3's fmix64).
    fn home(self) -> usize {
        let mut h = self.0;
        h ^= h >> 33;
        h = h.wrapping_mul(0xff51_afd7_ed55_8ccd);
        h ^= h >> 33;
        h = h.wrapping_mul(0xc4ce_b9fe_1a85_ec53);
        h ^= h >> 33;
        h as usize % SLOTS
    }
}

/// A full path's light back at its second vertex, over that vertex's albedo.
#[derive(Clone, Copy, Debug)]
pub struct CacheSample {
    pub cell: CellKey,
    pub light: Vec3,
}

/// Aligned to its 32 bytes, so two share a cache line and none straddles one.
#[derive(Clone, Copy, Debug, Default)]
#[repr(align(32))]
struct Cell {
    key: u64,
    light: Vec3,
    /// Samples learnt since the cell was made: paths take its light from
    /// `SAMPLES_TO_TRUST` on.
    samples: f32,
    /// Samples `light` is the mean of: as `samples`, but none again after `relit`, so the
    /// next one learnt replaces what the old lights gave.
    averaged: f32,
    /// The frame the cell last learnt in.
    trained: u32,
}

/// What `learn` gathers for a cell this frame before folding it in.
#[derive(Clone, Copy, Debug, Default)]
struct Gathered {
    sum: Vec3,
    count: u32,
}

/// The cache: a fixed table of cells, probed linearly from each key's hash.
pub struct RadianceCache {
    cells: Vec<Cell>,
    gathered: Vec<Gathered>,
    /// Slots gathered into this frame.
    touched: Vec<usize>,
    /// Frames learnt so far.
    frame: u32,
    /// Frames learnt so far at which teaching goes back from one pixel in 4 to one in 16
    /// (`relit`).
    eager_until: u32,
}

impl Default for RadianceCache {
    fn default() -> Self {
        RadianceCache::new()
    }
}

impl RadianceCache {
    pub fn new() -> RadianceCache {
        RadianceCache {
            cells: vec![Cell::default(); SLOTS],
            gathered: vec![Gathered::default(); SLOTS],
            touched: Vec::new(),
            frame: 0,
            eager_until: 0,
        }
    }

    /// Whether the pixel's path this frame (the sampler's `frame`) is traced in full to
    /// teach the cache: one in each 4 x 4 block, each pixel once in 16 frames, in the order
    /// of a Bayer matrix so the frames' teachers spread evenly over the block. One in four
    /// cost 5% more of the render's instructions than one in sixteen (the-gallery's
    /// play-through) for the same flythrough error, so one in four teach only for
    /// `EAGER_FRAMES` after the lights change.
    pub fn trains(&self, frame: u32, (x, y): (u32, u32)) -> bool {
        const BAYER: [[u32; 4]; 4] = [[0, 8, 2, 10], [12, 4, 14, 6], [3, 11, 1, 9], [15, 7, 13, 5]];
        let turn = BAYER[(y % 4) as usize][(x % 4) as usize];
        if self.frame < self.eager_until {
            turn % 4 == frame % 4
        } else {
            turn == frame % 16
        }
    }

    /// The light a cell has learnt, if it has learnt enough of it lately.
    pub fn light(&self, cell: CellKey) -> Option<Vec3> {
        let slot = self.find(cell)?;
        let found = &self.cells[slot];
        (found.samples >= SAMPLES_TO_TRUST && self.frame - found.trained <= FRAMES_TO_FORGET)
            .then_some(found.light)
    }

    /// Asks the CPU to bring the slots `light` will look for `cell` in into its cache (a
    /// hint: nothing changes but when the loads arrive). All `PROBES` of them: in
    /// the-keep's play-through the slot probed first held the cell in only about a third
    /// of the lookups that stalled (perf).
    #[inline(always)]
    pub fn prefetch(&self, cell: CellKey) {
        let home = cell.home();
        // Two 32-byte cells a 64-byte line: every other slot, and the last, touches every
        // line the probes read.
        for probe in (0..PROBES).step_by(2).chain([PROBES - 1]) {
            prefetch(&self.cells[(home + probe) % SLOTS]);
        }
    }

    fn find(&self, cell: CellKey) -> Option<usize> {
        let home = cell.home();
        (0..PROBES)
            .map(|probe| (home + probe) % SLOTS)
            .find(|&slot| self.cells[slot].key == cell.0)
    }

    /// The slot to gather `cell` in: its own, else an empty one or the longest untrained
    /// among those probed (cleared), never one already gathered into this frame.
    fn slot_for(&mut self, cell: CellKey) -> Option<usize> {
        if let Some(slot) = self.find(cell) {
            return Some(slot);
        }
        let home = cell.home();
        let slot = (0..PROBES)
            .map(|probe| (home + probe) % SLOTS)
            .filter(|&slot| self.gathered[slot].count == 0)
            .min_by_key(|&slot| {
                let found = &self.cells[slot];
                (found.key != 0, found.trained)
            })?;
        self.cells[slot] = Cell {
            key: cell.0,
            ..Cell::default()
        };
        Some(slot)
    }

    /// The lights changed (a lamp lit or doused): each cell's next sample replaces its light
    /// instead of joining a mean that would hold the old lights' for seconds (a cell learns
    /// only every few frames, so at `NEWEST_WEIGHT` a doused lamp's bounce light was still
    /// 5% there 64 frames on, first-light). Until that sample, paths still take the
    /// old light: forgetting it outright would trace every path in full for the frames
    /// the cells take to learn `SAMPLES_TO_TRUST` again.
    pub fn relit(&mut self) {
        for cell in &mut self.cells {
            cell.averaged = 0.0;
        }
        self.eager_until = self.frame + EAGER_FRAMES;
    }

    /// Whether the cache is still learning the lights after `relit` (teaching eagerly).
    pub fn relearning(&self) -> bool {
        self.frame < self.eager_until
    }

    /// Folds a frame's samples in, in the order given (the tiles' image order), and moves on
    /// to the next frame.
    pub fn learn<'a>(
        &mut self,
        samples: impl IntoIterator<Item = &'a CacheSample, IntoIter: Clone>,
    ) {
        self.frame += 1;
        let samples = samples.into_iter();
        // Each sample's cell is a slot anywhere in the 2 MB table: one after another, every
        // lookup waited for its line. The slots `LEARN_AHEAD` samples on are asked for
        // first, so the misses overlap.
        let mut ahead = samples.clone().skip(LEARN_AHEAD);
        for sample in samples {
            if let Some(later) = ahead.next() {
                let home = later.cell.home();
                prefetch(&self.cells[home]);
                prefetch(&self.gathered[home]);
            }
            if !sample.light.is_finite() {
                continue;
            }
            let Some(slot) = self.slot_for(sample.cell) else {
                continue;
            };
            let gathered = &mut self.gathered[slot];
            if gathered.count == 0 {
                self.touched.push(slot);
            }
            gathered.sum += sample.light;
            gathered.count += 1;
        }
        for at in 0..self.touched.len() {
            if let Some(&later) = self.touched.get(at + LEARN_AHEAD) {
                prefetch(&self.gathered[later]);
                prefetch(&self.cells[later]);
            }
            let slot = self.touched[at];
            let Gathered { sum, count } = std::mem::take(&mut self.gathered[slot]);
            let cell = &mut self.cells[slot];
            let count = count as f32;
            let weight = (count / (cell.averaged + count)).max(NEWEST_WEIGHT);
            cell.light = cell.light.lerp(sum / count, weight);
            cell.samples += count;
            cell.averaged += count;
            cell.trained = self.frame;
        }
        self.touched.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Cells a metre from an eye at the origin are 0.02 m wide, so the smallest.
    const SIZING: CellSizing = CellSizing {
        eye: Vec3A::ZERO,
        side_per_metre: 0.02,
    };

    #[test]
    fn the_cells_level_is_log2_floored_as_libm_gives_it() {
        let mut values: Vec<f32> = (0..=16)
            .flat_map(|e| {
                let power = 2f32.powi(e);
                // Each power of two, and the floats just below it.
                (0..300).map(move |k| f32::from_bits(power.to_bits() - k))
            })
            .filter(|&v| v >= 1.0)
            .collect();
        values.extend((0..100_000).map(|i| 1.0 + i as f32 * 0.0137));
        values.extend([f32::MAX, f32::INFINITY, f32::NAN]);
        for v in values {
            let expected = v.max(1.0).log2() as u32;
            assert_eq!(floor_log2_at_least_one(v.max(1.0)), expected, "{v:e}");
        }
    }

    #[test]
    fn cells_grow_with_distance_and_keep_the_faces_of_a_wall_apart() {
        let up = Vec3A::Y;
        let (near, near_side) = CellKey::at(Vec3A::new(1.01, 0.0, 0.0), up, &SIZING);
        assert_eq!(near_side, CELL_MIN);
        assert_eq!(near, CellKey::at(Vec3A::new(1.04, 0.0, 0.0), up, &SIZING).0);
        assert_ne!(near, CellKey::at(Vec3A::new(1.06, 0.0, 0.0), up, &SIZING).0);
        // 40 m away 0.8 m is wanted: 0.05 m doubled four times.
        let (_, far_side) = CellKey::at(Vec3A::new(0.0, 0.0, -40.0), up, &SIZING);
        assert_eq!(far_side, 0.8);
        // A camera with fewer pixels asks for larger cells.
        let placement = crate::scene::world::CameraPlacement {
            name: String::new(),
            yfov: std::f32::consts::FRAC_PI_2,
            znear: 0.1,
            world_from_camera: glam::Mat4::IDENTITY,
        };
        let camera = Camera::new(&placement, 160, 90);
        let sizing = CellSizing::of(&camera);
        assert!((sizing.side_per_metre - 4.0 * 2.0 / 90.0).abs() < 1e-6);
        // The same point seen from either side of a thin wall.
        let point = Vec3A::new(5.0, 0.0, 0.0);
        let (front, _) = CellKey::at(point, Vec3A::X, &SIZING);
        let (back, _) = CellKey::at(point, -Vec3A::X, &SIZING);
        assert_ne!(front, back);
        // Negative coordinates are cells of their own, not folded onto positive ones.
        let (negative, _) = CellKey::at(Vec3A::new(1.0, -0.01, -0.01), up, &SIZING);
        let (positive, _) = CellKey::at(Vec3A::new(1.0, 0.01, 0.01), up, &SIZING);
        assert_ne!(negative, positive);
    }

    #[test]
    fn one_pixel_of_each_block_trains_a_frame_and_each_in_turn() {
        let mut cache = RadianceCache::new();
        for frame in 0..16 {
            let teachers: Vec<(u32, u32)> = (0..8)
                .flat_map(|y| (0..8).map(move |x| (x, y)))
                .filter(|&pixel| cache.trains(frame, pixel))
                .collect();
            assert_eq!(teachers.len(), 4, "frame {frame}: one in each 4 x 4 block");
        }
        for (x, y) in [(0, 0), (5, 2), (7, 9)] {
            let frames: Vec<u32> = (0..32).filter(|&f| cache.trains(f, (x, y))).collect();
            assert_eq!(frames.len(), 2, "({x}, {y})");
            assert_eq!(frames[1] - frames[0], 16);
        }
        // After the lights change, one in each 2 x 2 block, for `EAGER_FRAMES` frames.
        let teachers = |cache: &RadianceCache, frame| {
            (0..8)
                .flat_map(|y| (0..8).map(move |x| (x, y)))
                .filter(|&pixel| cache.trains(frame, pixel))
                .count()
        };
        cache.relit();
        for frame in 0..EAGER_FRAMES {
            assert_eq!(teachers(&cache, frame), 16, "eager frame {frame}");
            cache.learn(&[]);
        }
        assert_eq!(teachers(&cache, EAGER_FRAMES), 4);
    }

    #[test]
    fn after_the_lights_change_a_cells_next_sample_replaces_its_light() {
        let mut cache = RadianceCache::new();
        let (cell, _) = CellKey::at(Vec3A::new(2.0, 0.0, 1.0), Vec3A::Y, &SIZING);
        for _ in 0..32 {
            cache.learn(&[CacheSample {
                cell,
                light: Vec3::ONE,
            }]);
        }
        cache.relit();
        assert_eq!(std::mem::size_of::<Cell>(), 32);
        // Still trusted with the old light until the cell learns again ...
        assert_eq!(cache.light(cell), Some(Vec3::ONE));
        let doused = Vec3::splat(0.25);
        cache.learn(&[CacheSample {
            cell,
            light: doused,
        }]);
        // ... then the new light alone, not a sixteenth of it.
        assert_eq!(cache.light(cell), Some(doused));
    }

    #[test]
    fn a_cell_is_trusted_after_enough_samples_and_follows_a_change() {
        let mut cache = RadianceCache::new();
        let (cell, _) = CellKey::at(Vec3A::new(2.0, 0.0, 1.0), Vec3A::Y, &SIZING);
        let sample = |light| CacheSample { cell, light };
        cache.learn(&[sample(Vec3::ONE), sample(Vec3::ONE)]);
        assert_eq!(cache.light(cell), None, "two samples are too few");
        cache.learn(&[sample(Vec3::splat(3.0)), sample(Vec3::splat(3.0))]);
        assert_eq!(
            cache.light(cell),
            Some(Vec3::splat(2.0)),
            "the mean of four"
        );
        // The lamp goes out: the newest frames weigh at least NEWEST_WEIGHT each.
        for _ in 0..48 {
            cache.learn(&[sample(Vec3::ZERO)]);
        }
        let left = cache.light(cell).unwrap().x;
        assert!(left < 2.0 * (1.0 - NEWEST_WEIGHT).powi(48) + 1e-6, "{left}");
        // Untrained for long, it is forgotten.
        for _ in 0..FRAMES_TO_FORGET + 1 {
            cache.learn(&[]);
        }
        assert_eq!(cache.light(cell), None);
    }

    #[test]
    fn a_full_neighbourhood_gives_up_its_stalest_cell() {
        let mut cache = RadianceCache::new();
        // Cells whose probes start at the same slot, more of them than PROBES, all of the
        // smallest side.
        const SIZING: CellSizing = CellSizing {
            eye: Vec3A::ZERO,
            side_per_metre: 0.0,
        };
        let (first, _) = CellKey::at(Vec3A::ZERO, Vec3A::Y, &SIZING);
        let home = first.home();
        let crowd: Vec<CellKey> = (0..2_000_000)
            .map(|i| {
                let (x, z) = ((i % 2000) as f32, (i / 2000) as f32);
                let position = Vec3A::new(x * 0.05 + 0.025, 0.0, z * 0.05 + 0.025);
                CellKey::at(position, Vec3A::Y, &SIZING).0
            })
            .filter(|cell| cell.home() == home)
            .take(PROBES + 1)
            .collect();
        assert_eq!(crowd.len(), PROBES + 1, "not enough colliding cells found");
        for (frame, &cell) in crowd.iter().take(PROBES).enumerate() {
            let samples = vec![
                CacheSample {
                    cell,
                    light: Vec3::splat(frame as f32)
                };
                4
            ];
            cache.learn(&samples);
        }
        for &cell in &crowd[..PROBES] {
            assert!(cache.light(cell).is_some());
        }
        let newcomer = crowd[PROBES];
        cache.learn(
            &[CacheSample {
                cell: newcomer,
                light: Vec3::ONE,
            }; 4],
        );
        assert_eq!(cache.light(newcomer), Some(Vec3::ONE));
        assert_eq!(cache.light(crowd[0]), None, "the stalest cell made room");
        assert!(cache.light(crowd[1]).is_some());
    }
}
