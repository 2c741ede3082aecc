//! Frame step `film`, first filter (`temporal`), steps 2 and 3: reprojection. Owns the
//! record last frame is kept in for it (`LastPixel`) and finds, for a pixel of this frame,
//! the history under its first hit last frame:
//! 1. motion: the hit carried back through its instance's previous transform;
//! 2. projection with the previous camera, to a film point and a depth, a row at a time
//!    (the row's lanes at once: AVX2 where the CPU has it, the same code either way);
//! 3. the 2 x 2 bilinear taps there, each kept only if it saw the same surface (instance,
//!    depth within a tolerance, normal within a cone); none kept is a disocclusion.

use glam::{Affine3A, Vec2, Vec3, Vec3A};

use super::temporal::{History, TemporalSettings};
use crate::render::camera::Projection;
use crate::render::guides::{
    DEPTH, Guides, NO_INSTANCE, NORMAL_X, NORMAL_Y, NORMAL_Z, POSITION_X, POSITION_Y, POSITION_Z,
};

/// What the next frame's reprojection reads of a pixel that is not sky: its history and,
/// for validation, its first hit, in one 40-byte record, so a tap touches one place and a
/// pixel's two taps on a row are neighbours. (As planes, a tap's 11 values were 11 places
/// a row: the temporal pass took 4.4-6.0 ms against 4.0, and 4.1-4.2 with AVX2 gathers,
/// which cost as much as the scalar reads on this Zen 3.) Its instance is kept apart, in
/// a dense row of its own for every pixel, so the sky's records are neither written nor
/// fed back (first-light's view is about half sky: the temporal pass 1.15 -> 1.09 ms, the
/// remodulation and feedback 0.21 -> 0.18 ms, `gloam bench` on 2 cores). The illumination
/// stays in the record although the feedback rewrites it there each frame (0.23 of the
/// remodulation's 0.41 ms, one thread, first-light): kept instead in planes handed over
/// from the first a-trous pass, each tap read three more cache lines, and the temporal
/// pass took 2.35 ms against 1.93 (one thread).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C)]
pub(super) struct LastPixel {
    pub history: History,
    pub normal: Vec3,
    pub depth: f32,
}

/// A `LastPixel`'s fields in the order it keeps them (`keep_lanes` writes them so).
const FIELDS: usize = 10;
const _: () = assert!(size_of::<LastPixel>() == FIELDS * size_of::<f32>());
const _: () = assert!(std::mem::offset_of!(History, moments) == 3 * size_of::<f32>());
const _: () = assert!(std::mem::offset_of!(History, length) == 5 * size_of::<f32>());
const _: () = assert!(std::mem::offset_of!(LastPixel, normal) == 6 * size_of::<f32>());
const _: () = assert!(std::mem::offset_of!(LastPixel, depth) == 9 * size_of::<f32>());

impl LastPixel {
    /// From its fields in the order it keeps them: illumination, moments, length, normal,
    /// depth.
    #[inline(always)]
    fn from_fields(f: [f32; FIELDS]) -> LastPixel {
        LastPixel {
            history: History {
                illumination: Vec3::new(f[0], f[1], f[2]),
                moments: Vec2::new(f[3], f[4]),
                length: f[5],
            },
            normal: Vec3::new(f[6], f[7], f[8]),
            depth: f[9],
        }
    }
}

/// A row of new histories, as the blend leaves them: a row per field.
pub(super) struct HistoryRow<'a> {
    pub illumination: [&'a [f32]; 3],
    pub moments: [&'a [f32]; 2],
    pub length: &'a [f32],
}

/// Proof that the CPU has what `keep_lanes` needs (AVX2): only `detect` makes one, once a
/// frame, and the temporal pass hands it down to its rows.
#[derive(Clone, Copy, Debug)]
pub(super) struct RecordLanes(());

impl RecordLanes {
    pub fn detect() -> Option<RecordLanes> {
        #[cfg(target_arch = "x86_64")]
        if crate::simd::avx2() {
            return Some(RecordLanes(()));
        }
        None
    }
}

/// `SurfaceRow::keep`'s records 8 pixels at a time: the ten fields' rows (`fields`, in
/// the record's order, each as long as `out`) transposed in registers into 8 records, each
/// written with one 32-byte and one 8-byte store. Written a field at a time, a record's 10
/// scalar stores were 15% of the temporal pass's samples; in lanes the pass runs 7% fewer
/// instructions (133.0 M against 123.9 M over 7 frames of first-light at 320 x 180) and
/// takes 3% less time on one thread, 2% on two. A run of 8 that is all sky is
/// skipped; one with some sky writes its sky records too, which is harmless: a tap reads a
/// record only under its own instance, and a sky record's history is zero. Returns how
/// many pixels it kept (whole runs of 8 from the first).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn keep_lanes(fields: &[&[f32]; FIELDS], instances: &[u32], out: &mut [LastPixel]) -> usize {
    use std::arch::x86_64::*;
    let width = out.len();
    assert!(instances.len() >= width && fields.iter().all(|field| field.len() >= width));
    let all_sky = _mm256_set1_epi32(NO_INSTANCE as i32);
    for x in (0..width / 8).map(|run| run * 8) {
        // SAFETY (every load and store below): x + 8 <= width, and every row is at least
        // `width` long (asserted); a run of 8 records is 80 floats.
        unsafe {
            let instances = _mm256_loadu_si256(instances.as_ptr().add(x).cast());
            let sky = _mm256_castsi256_ps(_mm256_cmpeq_epi32(instances, all_sky));
            if _mm256_movemask_ps(sky) == 0xff {
                continue;
            }
            let field = |f: usize| _mm256_loadu_ps(fields[f].as_ptr().add(x));
            // The first 8 fields: an 8 x 8 transpose, lane k of field f to field f of
            // record k.
            let [a0, a1, a2, a3, a4, a5, a6, a7] = std::array::from_fn(field);
            let (t0, t1) = (_mm256_unpacklo_ps(a0, a1), _mm256_unpackhi_ps(a0, a1));
            let (t2, t3) = (_mm256_unpacklo_ps(a2, a3), _mm256_unpackhi_ps(a2, a3));
            let (t4, t5) = (_mm256_unpacklo_ps(a4, a5), _mm256_unpackhi_ps(a4, a5));
            let (t6, t7) = (_mm256_unpacklo_ps(a6, a7), _mm256_unpackhi_ps(a6, a7));
            // Records k and k + 4 of the first and second four fields.
            let quads = [
                _mm256_shuffle_ps::<0x44>(t0, t2),
                _mm256_shuffle_ps::<0xee>(t0, t2),
                _mm256_shuffle_ps::<0x44>(t1, t3),
                _mm256_shuffle_ps::<0xee>(t1, t3),
            ];
            let highs = [
                _mm256_shuffle_ps::<0x44>(t4, t6),
                _mm256_shuffle_ps::<0xee>(t4, t6),
                _mm256_shuffle_ps::<0x44>(t5, t7),
                _mm256_shuffle_ps::<0xee>(t5, t7),
            ];
            let records: *mut f32 = out.as_mut_ptr().add(x).cast();
            for k in 0..4 {
                let (low, high) = (quads[k], highs[k]);
                let first = _mm256_permute2f128_ps::<0x20>(low, high);
                let fifth = _mm256_permute2f128_ps::<0x31>(low, high);
                _mm256_storeu_ps(records.add(k * FIELDS), first);
                _mm256_storeu_ps(records.add((k + 4) * FIELDS), fifth);
            }
            // The last 2 fields: pairs (f8, f9) of records 0, 1, 4, 5 and 2, 3, 6, 7.
            let (f8, f9) = (field(8), field(9));
            let pairs = [_mm256_unpacklo_ps(f8, f9), _mm256_unpackhi_ps(f8, f9)];
            for (half, pairs) in pairs.into_iter().enumerate() {
                for (lane, quad) in [
                    _mm256_castps256_ps128(pairs),
                    _mm256_extractf128_ps::<1>(pairs),
                ]
                .into_iter()
                .enumerate()
                {
                    let quad = _mm_castps_si128(quad);
                    let k = 4 * lane + 2 * half;
                    _mm_storeu_si64(records.add(k * FIELDS + 8).cast(), quad);
                    _mm_storeu_si64(
                        records.add((k + 1) * FIELDS + 8).cast(),
                        _mm_unpackhi_epi64(quad, quad),
                    );
                }
            }
        }
    }
    width / 8 * 8
}

/// A row of this frame's first hits as validation reads them, each plane's row cut once
/// (cut per pixel, the eight guide reads of a pixel were eight slicings with their bounds
/// checks).
pub(super) struct SurfaceRow<'a> {
    normal_x: &'a [f32],
    normal_y: &'a [f32],
    normal_z: &'a [f32],
    depth: &'a [f32],
    instances: &'a [u32],
}

impl<'a> SurfaceRow<'a> {
    pub fn new(guides: &'a Guides, y: usize) -> SurfaceRow<'a> {
        let width = guides.width as usize;
        SurfaceRow {
            normal_x: guides.row(y, NORMAL_X),
            normal_y: guides.row(y, NORMAL_Y),
            normal_z: guides.row(y, NORMAL_Z),
            depth: guides.row(y, DEPTH),
            instances: &guides.instances()[y * width..(y + 1) * width],
        }
    }

    /// The row's instances, and each surface pixel's record with its new history
    /// (`history`), for the next frame (`out`, a row of each).
    #[inline(always)]
    pub fn keep(
        &self,
        (out_instances, out): (&mut [u32], &mut [LastPixel]),
        history: HistoryRow,
        lanes: Option<RecordLanes>,
    ) {
        let width = out.len();
        let instances = &self.instances[..width];
        out_instances[..width].copy_from_slice(instances);
        let HistoryRow {
            illumination: [red, green, blue],
            moments: [mean, square],
            length,
        } = history;
        // Each row cut to the width once, written out: `map`'s closure is a call the
        // optimiser may leave out of line in a function the size of the temporal pass.
        let fields = [
            &red[..width],
            &green[..width],
            &blue[..width],
            &mean[..width],
            &square[..width],
            &length[..width],
            &self.normal_x[..width],
            &self.normal_y[..width],
            &self.normal_z[..width],
            &self.depth[..width],
        ];
        let kept = match lanes {
            // SAFETY: the CPU has AVX2 (`RecordLanes`), the only feature `keep_lanes`
            // enables.
            #[cfg(target_arch = "x86_64")]
            Some(RecordLanes(())) => unsafe { keep_lanes(&fields, instances, out) },
            _ => 0,
        };
        for x in kept..width {
            // The sky's records are left as they were.
            if instances[x] != NO_INSTANCE {
                out[x] = LastPixel::from_fields(std::array::from_fn(|f| fields[f][x]));
            }
        }
    }

    #[inline(always)]
    fn normal(&self, x: usize) -> Vec3 {
        Vec3::new(self.normal_x[x], self.normal_y[x], self.normal_z[x])
    }
}

/// How an instance moved since last frame.
#[derive(Clone, Copy, Debug)]
pub(super) enum Motion {
    /// Not at all (most of a level): points were where they are.
    Still,
    /// Last frame's world-from-object times this frame's object-from-world.
    Moved(Affine3A),
    /// Not there last frame (spawned since): nothing of it to reproject.
    New,
}

/// Each instance's world-from-object transform last frame, by index (None: spawned
/// since), as the film's filters keep it to tell how everything moved.
#[derive(Clone, Debug, Default)]
pub(super) struct LastTransforms(Vec<Option<Affine3A>>);

impl LastTransforms {
    /// How each of this frame's instances (at `now`) moved since last frame.
    pub fn motions(&self, now: &[Affine3A]) -> Vec<Motion> {
        now.iter()
            .enumerate()
            .map(|(index, now)| match self.0.get(index).copied().flatten() {
                Some(before) if before == *now => Motion::Still,
                Some(before) => Motion::Moved(before * now.inverse()),
                None => Motion::New,
            })
            .collect()
    }

    /// Keeps `now` for the next frame.
    pub fn record(&mut self, now: &[Affine3A]) {
        self.0.clear();
        self.0.extend(now.iter().copied().map(Some));
    }

    pub fn clear(&mut self) {
        self.0.clear();
    }

    /// The instances were numbered anew: `new_index[old]` is each old instance's new
    /// index (None: gone).
    pub fn renumber(&mut self, new_index: &[Option<u32>]) {
        let count = new_index.iter().flatten().map(|&i| i as usize + 1).max();
        let mut renumbered = vec![None; count.unwrap_or(0)];
        for (old, new) in new_index.iter().enumerate() {
            if let (Some(new), Some(before)) = (new, self.0.get(old).copied().flatten()) {
                renumbered[*new as usize] = Some(before);
            }
        }
        self.0 = renumbered;
    }
}

/// Last frame, as this frame's pixels find it.
pub(super) struct Reprojection<'a> {
    /// Last frame's camera.
    pub projection: Projection,
    /// Last frame's pixels, row-major, `width` by `height`: their instances (`NO_INSTANCE`
    /// for the sky) and the records of those that are not sky.
    pub last_instances: &'a [u32],
    pub last: &'a [LastPixel],
    pub width: usize,
    pub height: usize,
    /// Per instance, last frame's world from this frame's.
    pub motions: &'a [Motion],
    pub settings: &'a TemporalSettings,
    /// Project rows with the portable code even where AVX2 is there (to compare the two).
    pub portable_only: bool,
}

/// A row's first hits where last frame's camera saw them, as if nothing moved (step 2):
/// per pixel the film point less half a pixel (NaN behind the camera) and the distance.
#[derive(Default)]
pub(super) struct ProjectedRow {
    corner_x: Vec<f32>,
    corner_y: Vec<f32>,
    depth: Vec<f32>,
}

/// Histories below this total bilinear weight count as not found (a sliver of one tap).
const MIN_WEIGHT: f32 = 1e-2;

impl Reprojection<'_> {
    /// Step 2 for row `y` of this frame's `guides` (the same size as last frame).
    pub fn project_row(&self, guides: &Guides, y: usize, out: &mut ProjectedRow) {
        debug_assert_eq!(
            (guides.width as usize, guides.height as usize),
            (self.width, self.height)
        );
        for lane in [&mut out.corner_x, &mut out.corner_y, &mut out.depth] {
            lane.resize(self.width, 0.0);
        }
        #[cfg(target_arch = "x86_64")]
        if !self.portable_only && crate::simd::avx2() {
            // SAFETY: the CPU has AVX2, the only feature `project_row_avx2` enables.
            unsafe { self.project_row_avx2(guides, y, out) };
            return;
        }
        self.project_row_portable(guides, y, out);
    }

    /// The same code compiled for 8 lanes. No FMA, so both give the same bits. (Projected
    /// a pixel at a time, with the casts and checks of the taps between, the projection
    /// was 1.5 of the pass's 4.0 ms at 480 x 270; the taps, 0.85.)
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn project_row_avx2(&self, guides: &Guides, y: usize, out: &mut ProjectedRow) {
        self.project_row_portable(guides, y, out);
    }

    #[inline(always)]
    fn project_row_portable(&self, guides: &Guides, y: usize, out: &mut ProjectedRow) {
        let width = self.width;
        // Slices cut to `width`: the loop runs without bounds checks, so it vectorises.
        let (position_x, position_y, position_z) = (
            &guides.row(y, POSITION_X)[..width],
            &guides.row(y, POSITION_Y)[..width],
            &guides.row(y, POSITION_Z)[..width],
        );
        let (corner_x, corner_y, depth) = (
            &mut out.corner_x[..width],
            &mut out.corner_y[..width],
            &mut out.depth[..width],
        );
        for x in 0..width {
            let position = Vec3A::new(position_x[x], position_y[x], position_z[x]);
            (corner_x[x], corner_y[x], depth[x]) = self.project(position);
        }
    }

    /// Step 2 for a point: its film point less half a pixel (the top-left tap's corner;
    /// NaN behind the camera) and its distance from last frame's camera. In plain lane
    /// arithmetic, so a row of it vectorises.
    #[inline(always)]
    fn project(&self, position: Vec3A) -> (f32, f32, f32) {
        let point = self.projection.project_lanes(position);
        (
            if point.in_front {
                point.x - 0.5
            } else {
                f32::NAN
            },
            point.y - 0.5,
            point.distance,
        )
    }

    /// The history under pixel (x, y)'s first hit (on `instance`; `projected` is its row
    /// from `project_row`) last frame, bilinearly weighted over the taps that saw the same
    /// surface; None when none did (disocclusion).
    ///
    /// About 40% of the temporal pass (first-light), paced by its taps' loads (11 a tap),
    /// not its arithmetic: eight pixels at a time in AVX2 lanes, the taps gathered, it ran
    /// 44% fewer instructions and took as long (temporal p50 1.12 against 1.09 ms on two
    /// cores); its taps' records asked for 8 pixels ahead did not help either.
    #[inline(always)]
    pub fn history_at(
        &self,
        guides: &Guides,
        row: &SurfaceRow,
        projected: &ProjectedRow,
        x: usize,
        y: usize,
        instance: u32,
    ) -> Option<History> {
        // 1. Motion: where this point of the instance was last frame, and its normal then.
        let normal = Vec3A::from(row.normal(x));
        let (corner_x, corner_y, depth, normal) = match self.motions.get(instance as usize)? {
            Motion::Still => (
                projected.corner_x[x],
                projected.corner_y[x],
                projected.depth[x],
                normal,
            ),
            Motion::Moved(before_from_now) => {
                let (position, _) = guides.surface_at(x, y);
                let (corner_x, corner_y, depth) =
                    self.project(before_from_now.transform_point3a(position));
                let normal = (before_from_now.matrix3 * normal).normalize_or_zero();
                (corner_x, corner_y, depth, normal)
            }
            Motion::New => return None,
        };
        // Left of or above the first pixel's centre by a pixel or more, or right of or
        // below the last's, or behind the camera (NaN): no tap is inside (and the casts
        // below stay in range).
        let (width, height) = (self.width as i32, self.height as i32);
        if !(corner_x >= -1.0
            && corner_y >= -1.0
            && corner_x < width as f32
            && corner_y < height as f32)
        {
            return None;
        }
        // 3. The taps. floor() is a libm call on baseline x86-64; shifted to >= 0,
        // truncation is floor.
        let (x0, y0) = ((corner_x + 1.0) as i32 - 1, (corner_y + 1.0) as i32 - 1);
        let (fx, fy) = (corner_x - x0 as f32, corner_y - y0 as f32);
        let (depth_tolerance, normal_tolerance) = (
            self.settings.depth_tolerance * depth,
            self.settings.normal_tolerance,
        );
        let normal = Vec3::from(normal);
        // The taps' records and bilinear weights, zero for a tap off the film or on
        // another surface.
        let mut taps = [(&self.last[0], 0.0f32); 4];
        for (tap, (dx, dy, weight)) in taps.iter_mut().zip([
            (0, 0, (1.0 - fx) * (1.0 - fy)),
            (1, 0, fx * (1.0 - fy)),
            (0, 1, (1.0 - fx) * fy),
            (1, 1, fx * fy),
        ]) {
            let (x, y) = (x0 + dx, y0 + dy);
            if x < 0 || y < 0 || x >= width || y >= height {
                continue;
            }
            let index = y as usize * self.width + x as usize;
            if self.last_instances[index] != instance {
                continue;
            }
            let then = &self.last[index];
            let same_surface = (then.depth - depth).abs() <= depth_tolerance
                && then.normal.dot(normal) >= normal_tolerance;
            if same_surface {
                *tap = (then, weight);
            }
        }
        let weight_sum: f32 = taps.iter().map(|(_, weight)| weight).sum();
        if weight_sum <= MIN_WEIGHT {
            return None;
        }
        let mut sum = History::default();
        for (then, weight) in taps {
            let h = &then.history;
            sum.illumination += h.illumination * weight;
            sum.moments += h.moments * weight;
            sum.length += h.length * weight;
        }
        let normalise = 1.0 / weight_sum;
        Some(History {
            illumination: sum.illumination * normalise,
            moments: sum.moments * normalise,
            length: sum.length * normalise,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::GuidePixel;
    use crate::render::camera::Camera;
    use crate::scene::world::CameraPlacement;
    use glam::Mat4;

    /// Hits scattered in front of, beside and behind a turned camera, on a film 37 wide
    /// (four runs of eight lanes and a tail).
    fn scattered(width: u32, height: u32) -> Guides {
        let mut guides = Guides::new(width, height);
        let mut state = 0x9e37_79b9u32;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state as f32 / u32::MAX as f32 * 40.0 - 20.0
        };
        for index in 0..(width * height) as usize {
            let pixel = GuidePixel {
                position: Vec3A::new(next(), next(), next()),
                normal: Vec3A::Y,
                depth: 1.0,
                instance: 0,
                albedo: Vec3::ONE,
                unfiltered: Vec3::ZERO,
            };
            guides.set(index, &pixel);
        }
        guides
    }

    #[test]
    fn vector_and_portable_projections_agree_to_the_bit() {
        let (width, height) = (37, 5);
        let placement = CameraPlacement {
            name: String::new(),
            yfov: 70f32.to_radians(),
            znear: 0.1,
            world_from_camera: Mat4::from_rotation_translation(
                glam::Quat::from_euler(glam::EulerRot::YXZ, 0.7, -0.3, 0.1),
                glam::Vec3::new(1.0, 2.0, -3.0),
            ),
        };
        let camera = Camera::new(&placement, width, height);
        let guides = scattered(width, height);
        let last = vec![LastPixel::default(); (width * height) as usize];
        let last_instances = vec![0; (width * height) as usize];
        let settings = TemporalSettings::default();
        let reprojection = |portable_only| Reprojection {
            projection: camera.projection(),
            last_instances: &last_instances,
            last: &last,
            width: width as usize,
            height: height as usize,
            motions: &[Motion::Still],
            settings: &settings,
            portable_only,
        };
        let (vector, portable) = (reprojection(false), reprojection(true));
        let (mut a, mut b) = (ProjectedRow::default(), ProjectedRow::default());
        let mut behind = 0;
        for y in 0..height as usize {
            vector.project_row(&guides, y, &mut a);
            portable.project_row(&guides, y, &mut b);
            for x in 0..width as usize {
                let lanes = |row: &ProjectedRow| {
                    [row.corner_x[x], row.corner_y[x], row.depth[x]].map(f32::to_bits)
                };
                assert_eq!(lanes(&a), lanes(&b), "pixel ({x}, {y})");
                // And the same as one point at a time, which the moved instances take.
                let (position, _) = guides.surface_at(x, y);
                let (corner_x, corner_y, depth) = portable.project(position);
                assert_eq!(lanes(&a), [corner_x, corner_y, depth].map(f32::to_bits));
                behind += a.corner_x[x].is_nan() as usize;
            }
        }
        // Both sides of the camera were tried.
        assert!(behind > 10 && behind < 37 * 5 - 10, "{behind} behind");
    }

    #[test]
    fn records_kept_in_lanes_are_the_records_kept_one_at_a_time() {
        let Some(lanes) = RecordLanes::detect() else {
            println!("skipped: this CPU has no AVX2, so the records are never kept in lanes");
            return;
        };
        // 37 wide: four runs of eight and a tail. Sky at both ends of a run, a run of
        // surface only, a run of sky only (pixels 16..24), and sky in the tail.
        let width = 37u32;
        let sky = |x: usize| x < 3 || x == 13 || (16..24).contains(&x) || x == 35;
        let pixels: Vec<GuidePixel> = (0..width as usize)
            .map(|x| {
                if sky(x) {
                    return GuidePixel::SKY;
                }
                let f = x as f32;
                GuidePixel {
                    position: Vec3A::ZERO,
                    normal: Vec3A::new(0.1 * f, 1.0, -0.2 * f).normalize(),
                    depth: 1.0 + 0.5 * f,
                    instance: x as u32 % 3,
                    albedo: Vec3::ONE,
                    unfiltered: Vec3::ZERO,
                }
            })
            .collect();
        let guides = Guides::from_pixels(width, 1, &pixels);
        let field = |offset: f32| -> Vec<f32> {
            (0..width as usize)
                .map(|x| if sky(x) { 0.0 } else { offset + x as f32 })
                .collect()
        };
        let planes: Vec<Vec<f32>> = (0..6).map(|f| field(100.0 * f as f32)).collect();
        let history = || HistoryRow {
            illumination: [&planes[0][..], &planes[1], &planes[2]],
            moments: [&planes[3][..], &planes[4]],
            length: &planes[5],
        };
        let untouched = LastPixel {
            depth: -7.0,
            ..LastPixel::default()
        };
        let keep = |lanes| {
            let mut instances = vec![0; width as usize];
            let mut records = vec![untouched; width as usize];
            SurfaceRow::new(&guides, 0).keep((&mut instances, &mut records), history(), lanes);
            (instances, records)
        };
        let (in_lanes, one_at_a_time) = (keep(Some(lanes)), keep(None));
        assert_eq!(in_lanes.0, one_at_a_time.0);
        for x in 0..width as usize {
            let (a, b) = (in_lanes.1[x], one_at_a_time.1[x]);
            if sky(x) {
                // Left alone where the whole run is sky; a sky record is never read.
                assert_eq!(b, untouched, "pixel {x}");
                if (16..24).contains(&x) || x == 35 {
                    assert_eq!(a, untouched, "pixel {x}");
                }
                continue;
            }
            assert_eq!(a, b, "pixel {x}");
            assert_eq!(a.history.moments.y, 400.0 + x as f32, "pixel {x}");
            assert_eq!(a.depth, 1.0 + 0.5 * x as f32, "pixel {x}");
        }
    }
}
