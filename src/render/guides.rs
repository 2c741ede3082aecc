//! Frame step `render`, beside the image: the guides (a G-buffer) of every pixel's first
//! camera ray, which the `film` step's filters read: where the ray landed, the surface's
//! normal, distance, instance, albedo and the light the filters leave alone (`unfiltered`).
//!
//! Filled in the primary phase from sample 0 of each pixel (the real-time view renders one
//! sample per pixel, so the guides describe exactly the sample the pixel holds); the light
//! of each first vertex's dominant lamp joins `unfiltered` once the paths are done.

use glam::{Vec3, Vec3A};

use super::integrator::{NextHit, RayCone};
use super::planes::{RowPlanes, SharedRuns};
use super::scene::RenderScene;

/// The instance of a pixel whose camera ray left the scene.
pub const NO_INSTANCE: u32 = u32::MAX;

/// One pixel's first hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GuidePixel {
    /// World-space hit point.
    pub position: Vec3A,
    /// Shading normal turned towards the camera (zero for the sky).
    pub normal: Vec3A,
    /// Distance from the camera to the hit, in metres (infinite for the sky).
    pub depth: f32,
    /// Index of the instance hit in the scene's accel (`NO_INSTANCE` for the sky).
    pub instance: u32,
    /// What the surface multiplies incoming light by (`RenderMaterial::albedo_at`): the
    /// pixel's radiance minus `unfiltered`, divided by this, is its demodulated
    /// illumination.
    pub albedo: Vec3,
    /// The pixel's light the film's filters leave as it is: the radiance the hit itself
    /// sends to the camera (the sky's for escaping rays) and, from the real-time renderer,
    /// the direct light of the lamp that lights the hit most, shaded in full
    /// (`PathState::with_dominant_apart`): noiseless, it is sharper unfiltered.
    pub unfiltered: Vec3,
}

impl GuidePixel {
    pub const SKY: GuidePixel = GuidePixel {
        position: Vec3A::ZERO,
        normal: Vec3A::ZERO,
        depth: f32::INFINITY,
        instance: NO_INSTANCE,
        albedo: Vec3::ONE,
        unfiltered: Vec3::ZERO,
    };

    /// The guides of a camera ray from `origin` that found `hit` (None: the sky). Inlined:
    /// returned through memory, each pixel's guides were read back before their stores
    /// had landed (the primary phase's p50 fell 3.36 -> 3.18 ms on first-light).
    #[inline(always)]
    pub fn from_hit(
        scene: &RenderScene,
        origin: Vec3A,
        cone: RayCone,
        hit: Option<&NextHit>,
    ) -> GuidePixel {
        let mut guide = GuidePixel::from_hit_but_albedo(scene, origin, hit);
        if let Some(found) = hit {
            guide.albedo = GuidePixel::albedo_of(scene, cone, found);
        }
        guide
    }

    /// The albedo guide of a camera ray's `found` hit, for a pixel's `cone`.
    #[inline(always)]
    pub fn albedo_of(scene: &RenderScene, cone: RayCone, found: &NextHit) -> Vec3 {
        let material = scene.material(found.hit.instance, found.surface.material);
        material.albedo_at(&scene.textures, found.surface.uv, cone.footprint_at(found))
    }

    /// `from_hit` with the albedo left at 1, for a render that sets it from the first
    /// vertex's shading (`VertexOutcome::albedo`).
    #[inline(always)]
    pub fn from_hit_but_albedo(
        scene: &RenderScene,
        origin: Vec3A,
        hit: Option<&NextHit>,
    ) -> GuidePixel {
        let Some(found) = hit else {
            return GuidePixel {
                unfiltered: scene.sky,
                ..GuidePixel::SKY
            };
        };
        let surface = &found.surface;
        let normal = if surface.shading_normal.dot(found.wo_world) >= 0.0 {
            surface.shading_normal
        } else {
            -surface.shading_normal
        };
        GuidePixel {
            position: surface.position,
            normal,
            depth: (surface.position - origin).length(),
            instance: found.hit.instance,
            albedo: Vec3::ONE,
            unfiltered: found.emitted,
        }
    }

    pub fn is_sky(&self) -> bool {
        self.instance == NO_INSTANCE
    }

    /// Demodulates `radiance` (this pixel's) into illumination: (L - unfiltered) / albedo,
    /// with albedo floored so black surfaces give zero rather than infinity.
    pub fn demodulate(&self, radiance: Vec3) -> Vec3 {
        if self.is_sky() {
            return Vec3::ZERO;
        }
        (radiance - self.unfiltered).max(Vec3::ZERO) / self.albedo.max(Vec3::splat(ALBEDO_FLOOR))
    }

    /// `demodulate`'s inverse.
    pub fn modulate(&self, illumination: Vec3) -> Vec3 {
        if self.is_sky() {
            return self.unfiltered;
        }
        illumination * self.albedo.max(Vec3::splat(ALBEDO_FLOOR)) + self.unfiltered
    }
}

/// Below this albedo a channel is treated as this dark (no division by zero).
pub(crate) const ALBEDO_FLOOR: f32 = 1e-3;

/// Guide planes (`Guides::row`): the ones the a-trous passes read first, so they are near.
pub const NORMAL_X: usize = 0;
pub const NORMAL_Y: usize = 1;
pub const NORMAL_Z: usize = 2;
pub const DEPTH: usize = 3;
pub const ALBEDO_R: usize = 4;
pub const ALBEDO_G: usize = 5;
pub const ALBEDO_B: usize = 6;
pub const POSITION_X: usize = 7;
pub const POSITION_Y: usize = 8;
pub const POSITION_Z: usize = 9;
pub const UNFILTERED_R: usize = 10;
pub const UNFILTERED_G: usize = 11;
pub const UNFILTERED_B: usize = 12;
pub const GUIDE_PLANES: usize = 13;

/// The guides of a whole image: each `GuidePixel` field a plane of floats a row at a time
/// (`planes::RowPlanes`), and the instances row-major. Every film pass reads only the
/// planes it needs, a row of lanes at a time (as 64-byte pixels, the four passes that read
/// them moved 33 MB a frame at 480 x 270).
#[derive(Clone, Debug, PartialEq)]
pub struct Guides {
    pub width: u32,
    pub height: u32,
    planes: RowPlanes<GUIDE_PLANES>,
    instances: Vec<u32>,
}

impl Guides {
    /// Guides with every pixel the sky.
    pub fn new(width: u32, height: u32) -> Guides {
        let mut planes = RowPlanes::default();
        planes.resize(width as usize, height as usize);
        let sky = GuidePixel::SKY;
        for y in 0..height as usize {
            for (plane, value) in pixel_planes(&sky).into_iter().enumerate() {
                planes.row_mut(y, plane).fill(value);
            }
        }
        Guides {
            width,
            height,
            planes,
            instances: vec![NO_INSTANCE; (width * height) as usize],
        }
    }

    /// Guides of `pixels` (row-major, `width` x `height` of them).
    pub fn from_pixels(width: u32, height: u32, pixels: &[GuidePixel]) -> Guides {
        let mut guides = Guides::new(width, height);
        for (index, pixel) in pixels.iter().enumerate() {
            guides.set(index, pixel);
        }
        guides
    }

    /// Pixel `index`'s (row-major) guides.
    pub fn pixel(&self, index: usize) -> GuidePixel {
        let (x, y) = (index % self.width as usize, index / self.width as usize);
        let values = self.planes.pixel(x, y);
        let triple = |first: usize| Vec3::new(values[first], values[first + 1], values[first + 2]);
        GuidePixel {
            position: triple(POSITION_X).into(),
            normal: triple(NORMAL_X).into(),
            depth: values[DEPTH],
            instance: self.instances[index],
            albedo: triple(ALBEDO_R),
            unfiltered: triple(UNFILTERED_R),
        }
    }

    /// Sets pixel `index`'s (row-major) guides.
    pub fn set(&mut self, index: usize, guide: &GuidePixel) {
        // 32-bit division: the render sets every pixel of a frame through here, serially.
        let (x, y) = (index as u32 % self.width, index as u32 / self.width);
        let (x, y) = (x as usize, y as usize);
        self.planes.set_pixel(x, y, pixel_planes(guide));
        self.instances[index] = guide.instance;
    }

    /// The guides to set from many threads at once, a rectangle each (the render's
    /// tiles set their own pixels as they finish).
    pub(crate) fn rects(&mut self) -> GuideRects<'_> {
        GuideRects {
            width: self.width as usize,
            planes: self.planes.shared_runs(),
            instances: SharedRuns::new(&mut self.instances),
        }
    }

    /// Row `y` of plane `plane` (`NORMAL_X` ... `UNFILTERED_B`).
    #[inline(always)]
    pub fn row(&self, y: usize, plane: usize) -> &[f32] {
        self.planes.row(y, plane)
    }

    /// Every pixel's instance, row-major (`NO_INSTANCE` for the sky).
    pub fn instances(&self) -> &[u32] {
        &self.instances
    }

    /// `GuidePixel::modulate` for row `y`, a row of lanes at a time: `illumination` (its
    /// red, green and blue rows) times albedo plus the unfiltered light, the sky its own.
    pub fn modulate_row(&self, y: usize, illumination: [&[f32]; 3], out: &mut [Vec3]) {
        let width = self.width as usize;
        let instances = &self.instances[y * width..(y + 1) * width];
        let out = &mut out[..width];
        let channels = [
            (ALBEDO_R, UNFILTERED_R),
            (ALBEDO_G, UNFILTERED_G),
            (ALBEDO_B, UNFILTERED_B),
        ];
        for (channel, ((albedo, unfiltered), illumination)) in
            channels.into_iter().zip(illumination).enumerate()
        {
            let (albedo, unfiltered) = (self.row(y, albedo), self.row(y, unfiltered));
            let illumination = &illumination[..width];
            for x in 0..width {
                let lit = illumination[x] * albedo[x].max(ALBEDO_FLOOR) + unfiltered[x];
                out[x][channel] = if instances[x] == NO_INSTANCE {
                    unfiltered[x]
                } else {
                    lit
                };
            }
        }
    }

    /// Pixel (x, y)'s hit point and normal.
    #[inline(always)]
    pub fn surface_at(&self, x: usize, y: usize) -> (Vec3A, Vec3A) {
        let at = |plane| self.planes.row(y, plane)[x];
        (
            Vec3A::new(at(POSITION_X), at(POSITION_Y), at(POSITION_Z)),
            Vec3A::new(at(NORMAL_X), at(NORMAL_Y), at(NORMAL_Z)),
        )
    }
}

/// `Guides` set a rectangle at a time from many threads (`Guides::rects`).
pub(crate) struct GuideRects<'a> {
    width: usize,
    planes: SharedRuns<'a, f32>,
    instances: SharedRuns<'a, u32>,
}

impl GuideRects<'_> {
    /// Sets the pixels of a rectangle `rect_width` wide whose top-left pixel is
    /// (`x0`, `y0`) from `guides`, row-major: a row at a time, through a slice per plane cut
    /// to the rectangle (one pixel at a time from its row-major index, with a division
    /// and 13 bounds-checked stores each, was 5% of a frame's CPU time on the-gallery).
    ///
    /// # Safety
    /// No other call setting any of the same pixels may run at the same time.
    pub(crate) unsafe fn set_rect(
        &self,
        (x0, y0): (usize, usize),
        rect_width: usize,
        guides: &[GuidePixel],
    ) {
        let width = self.width;
        assert!(
            x0 + rect_width <= width,
            "a rectangle past the guides' width"
        );
        for (row, pixels) in guides.chunks(rect_width.max(1)).enumerate() {
            let y = y0 + row;
            let first = y * GUIDE_PLANES * width + x0;
            // A plane at a time: a pixel at a time, the 13 runs' pointers spilled to the
            // stack and the stores went to 13 lines in turn (2.9% -> 1.7% of the frame's
            // CPU time, perf, first-light).
            // SAFETY: the rectangle's run in `plane`, which no other caller sets.
            let run =
                |plane: usize| unsafe { self.planes.run(first + plane * width, pixels.len()) };
            set_plane::<NORMAL_X>(&run, pixels);
            set_plane::<NORMAL_Y>(&run, pixels);
            set_plane::<NORMAL_Z>(&run, pixels);
            set_plane::<DEPTH>(&run, pixels);
            set_plane::<ALBEDO_R>(&run, pixels);
            set_plane::<ALBEDO_G>(&run, pixels);
            set_plane::<ALBEDO_B>(&run, pixels);
            set_plane::<POSITION_X>(&run, pixels);
            set_plane::<POSITION_Y>(&run, pixels);
            set_plane::<POSITION_Z>(&run, pixels);
            set_plane::<UNFILTERED_R>(&run, pixels);
            set_plane::<UNFILTERED_G>(&run, pixels);
            set_plane::<UNFILTERED_B>(&run, pixels);
            // SAFETY: as above.
            let instances = unsafe { self.instances.run(y * width + x0, pixels.len()) };
            for (slot, pixel) in instances.iter_mut().zip(pixels) {
                *slot = pixel.instance;
            }
        }
    }
}

/// Sets plane `PLANE`'s run (`run(PLANE)`) from its pixels.
#[inline(always)]
fn set_plane<'r, const PLANE: usize>(run: &impl Fn(usize) -> &'r mut [f32], pixels: &[GuidePixel]) {
    for (slot, pixel) in run(PLANE).iter_mut().zip(pixels) {
        *slot = pixel_planes(pixel)[PLANE];
    }
}

/// A guide pixel's plane values, in plane order (field by field, so that setting a row of
/// pixels compiles to stores: a table of getters was called through pointers, 17 us a
/// tile).
#[inline(always)]
fn pixel_planes(guide: &GuidePixel) -> [f32; GUIDE_PLANES] {
    let mut values = [0.0; GUIDE_PLANES];
    [values[NORMAL_X], values[NORMAL_Y], values[NORMAL_Z]] = guide.normal.to_array();
    [values[ALBEDO_R], values[ALBEDO_G], values[ALBEDO_B]] = guide.albedo.to_array();
    [values[POSITION_X], values[POSITION_Y], values[POSITION_Z]] = guide.position.to_array();
    [
        values[UNFILTERED_R],
        values[UNFILTERED_G],
        values[UNFILTERED_B],
    ] = guide.unfiltered.to_array();
    values[DEPTH] = guide.depth;
    values
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn demodulation_round_trips_and_keeps_the_unfiltered_light_out() {
        let pixel = GuidePixel {
            albedo: Vec3::new(0.5, 0.25, 0.0),
            unfiltered: Vec3::new(1.0, 0.0, 0.0),
            instance: 3,
            ..GuidePixel::SKY
        };
        let radiance = Vec3::new(1.5, 0.5, 0.0);
        let illumination = pixel.demodulate(radiance);
        assert_eq!(illumination, Vec3::new(1.0, 2.0, 0.0));
        assert_eq!(pixel.modulate(illumination), radiance);
        let sky = GuidePixel {
            unfiltered: Vec3::splat(0.2),
            ..GuidePixel::SKY
        };
        assert_eq!(sky.demodulate(Vec3::splat(0.2)), Vec3::ZERO);
        assert_eq!(sky.modulate(Vec3::splat(9.0)), Vec3::splat(0.2));
    }

    #[test]
    fn guides_keep_every_field_of_every_pixel() {
        let mut guides = Guides::new(5, 3);
        assert_eq!(guides.pixel(14), GuidePixel::SKY);
        let pixel = GuidePixel {
            position: Vec3A::new(1.0, 2.0, 3.0),
            normal: Vec3A::new(0.0, 0.6, 0.8),
            depth: 4.5,
            instance: 7,
            albedo: Vec3::new(0.1, 0.2, 0.3),
            unfiltered: Vec3::new(4.0, 5.0, 6.0),
        };
        guides.set(8, &pixel);
        assert_eq!(guides.pixel(8), pixel);
        assert_eq!(guides.pixel(7), GuidePixel::SKY);
        assert_eq!(guides.instances()[8], 7);
        assert_eq!(guides.row(1, DEPTH)[3], 4.5);
        assert_eq!(guides.row(1, UNFILTERED_G)[3], 5.0);
        assert_eq!(guides.surface_at(3, 1), (pixel.position, pixel.normal));
        // Set as rectangles, two at once from two threads: the same.
        let (mut whole, mut by_rect) = (Guides::new(5, 3), Guides::new(5, 3));
        let other = GuidePixel {
            depth: 9.0,
            instance: 2,
            ..pixel
        };
        let (left, right) = ([pixel, other, other, pixel], [other, pixel, pixel, pixel]);
        for (index, guide) in [(5, pixel), (6, other), (10, other), (11, pixel)] {
            whole.set(index, &guide);
        }
        for (index, guide) in [(7, other), (8, pixel), (12, pixel), (13, pixel)] {
            whole.set(index, &guide);
        }
        let rects = by_rect.rects();
        // SAFETY: the rectangles (0..2 and 2..4 across, rows 1 and 2) are disjoint.
        rayon::join(
            || unsafe { rects.set_rect((0, 1), 2, &left) },
            || unsafe { rects.set_rect((2, 1), 2, &right) },
        );
        assert_eq!(by_rect, whole);
        // A row modulated at once is each pixel modulated alone.
        let illumination = [[0.5f32; 5], [2.0; 5], [0.0; 5]];
        let mut row = [Vec3::ZERO; 5];
        guides.modulate_row(1, illumination.each_ref().map(|r| &r[..]), &mut row);
        for (x, value) in row.iter().enumerate() {
            let expected = guides.pixel(5 + x).modulate(Vec3::new(0.5, 2.0, 0.0));
            assert_eq!(*value, expected, "pixel {x}");
        }
    }
}
