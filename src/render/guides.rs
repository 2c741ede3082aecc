//! Frame step `render`, beside the image: the guides (a G-buffer) of every pixel's first
//! camera ray, which the `film` step's filters read: where the ray landed, the surface's
//! normal, distance, instance, albedo and the light the filters leave alone (`unfiltered`).
//!
//! Filled in the primary phase from sample 0 of each pixel (the real-time view renders one
//! sample per pixel, so the guides describe exactly the sample the pixel holds); the light
//! of each first vertex's dominant lamp joins `unfiltered` once the paths are done.

use glam::{Vec3, Vec3A};

use super::integrator::NextHit;
use rayon::prelude::*;

use super::planes::RowPlanes;
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

    /// The guides of a camera ray from `origin` that found `hit` (None: the sky).
    pub fn from_hit(scene: &RenderScene, origin: Vec3A, hit: Option<&NextHit>) -> GuidePixel {
        let Some(found) = hit else {
            return GuidePixel {
                unfiltered: scene.sky,
                ..GuidePixel::SKY
            };
        };
        let surface = &found.surface;
        let material = scene.material(found.hit.instance, surface.material);
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
            albedo: material.albedo_at(&scene.textures, surface.uv),
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

    /// Bands of `rows` rows, to set in parallel (the render assembles its tiles' guides
    /// a row of tiles per job).
    pub fn bands_mut(&mut self, rows: usize) -> impl IndexedParallelIterator<Item = GuideBand<'_>> {
        let width = self.width as usize;
        self.planes
            .bands_of_mut(rows)
            .zip(self.instances.par_chunks_mut((width * rows).max(1)))
            .map(move |((first_row, planes), instances)| GuideBand {
                width,
                first_index: first_row * width,
                planes,
                instances,
            })
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

/// Consecutive rows of `Guides`, to set (`Guides::bands_mut`).
pub struct GuideBand<'a> {
    width: usize,
    /// The row-major index of the band's first pixel.
    first_index: usize,
    planes: &'a mut [f32],
    instances: &'a mut [u32],
}

impl GuideBand<'_> {
    /// Sets the pixels of a rectangle `rect_width` wide whose top-left pixel is
    /// (`x0`, `y0`) (in the whole image; the rectangle must lie in the band) from
    /// `guides`, row-major. Row by row and plane by plane, each a run of stores through
    /// slices cut to the run (pixel by pixel, 13 bounds-checked stores each, this was 2.8%
    /// of a frame's CPU time on the-gallery at half scale; one pixel at a time from its
    /// row-major index, two 64-bit divisions each, 5%).
    pub fn set_rect(&mut self, (x0, y0): (usize, usize), rect_width: usize, guides: &[GuidePixel]) {
        let width = self.width;
        let first_row = self.first_index / width;
        for (row, pixels) in guides.chunks(rect_width.max(1)).enumerate() {
            let local_row = y0 + row - first_row;
            let planes =
                &mut self.planes[local_row * GUIDE_PLANES * width..][..GUIDE_PLANES * width];
            for (plane, value) in PLANE_VALUES {
                let run = &mut planes[plane * width + x0..][..pixels.len()];
                for (stored, pixel) in run.iter_mut().zip(pixels) {
                    *stored = value(pixel);
                }
            }
            let instances = &mut self.instances[local_row * width + x0..][..pixels.len()];
            for (stored, pixel) in instances.iter_mut().zip(pixels) {
                *stored = pixel.instance;
            }
        }
    }
}

/// A guide pixel's plane values, in plane order.
fn pixel_planes(guide: &GuidePixel) -> [f32; GUIDE_PLANES] {
    let mut values = [0.0; GUIDE_PLANES];
    for (plane, value) in PLANE_VALUES {
        values[plane] = value(guide);
    }
    values
}

/// Each guide plane and the value of a pixel it holds.
const PLANE_VALUES: [(usize, fn(&GuidePixel) -> f32); GUIDE_PLANES] = [
    (NORMAL_X, |pixel| pixel.normal.x),
    (NORMAL_Y, |pixel| pixel.normal.y),
    (NORMAL_Z, |pixel| pixel.normal.z),
    (ALBEDO_R, |pixel| pixel.albedo.x),
    (ALBEDO_G, |pixel| pixel.albedo.y),
    (ALBEDO_B, |pixel| pixel.albedo.z),
    (POSITION_X, |pixel| pixel.position.x),
    (POSITION_Y, |pixel| pixel.position.y),
    (POSITION_Z, |pixel| pixel.position.z),
    (UNFILTERED_R, |pixel| pixel.unfiltered.x),
    (UNFILTERED_G, |pixel| pixel.unfiltered.y),
    (UNFILTERED_B, |pixel| pixel.unfiltered.z),
    (DEPTH, |pixel| pixel.depth),
];

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
        // Set through bands of rows (pixel 8, (3, 1), is in the first, rows 0 and 1): the
        // same.
        let mut banded = Guides::new(5, 3);
        banded.bands_mut(2).for_each(|mut band| {
            if band.first_index == 0 {
                band.set_rect((3, 1), 1, &[pixel]);
            }
        });
        assert_eq!(banded, guides);
        // A 2 x 2 rectangle across two bands of one row each, set band by band.
        let (mut whole, mut by_band) = (Guides::new(5, 3), Guides::new(5, 3));
        let other = GuidePixel {
            depth: 9.0,
            instance: 2,
            ..pixel
        };
        let rect = [pixel, other, other, pixel];
        for (index, guide) in [(6, pixel), (7, other), (11, other), (12, pixel)] {
            whole.set(index, &guide);
        }
        by_band
            .bands_mut(1)
            .for_each(|mut band| match band.first_index / 5 {
                1 => band.set_rect((1, 1), 2, &rect[..2]),
                2 => band.set_rect((1, 2), 2, &rect[2..]),
                _ => {}
            });
        assert_eq!(by_band, whole);
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
