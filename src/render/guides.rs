//! Frame step `render`, beside the image: the guides (a G-buffer) of every pixel's first
//! camera ray, which the `film` step's filters read: where the ray landed, the surface's
//! normal, distance, instance, albedo and emission.
//!
//! Filled in the primary phase from sample 0 of each pixel (the real-time view renders one
//! sample per pixel, so the guides describe exactly the sample the pixel holds).

use glam::{Vec3, Vec3A};

use super::integrator::NextHit;
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
    /// pixel's radiance minus `emission`, divided by this, is its demodulated illumination.
    pub albedo: Vec3,
    /// Radiance the hit itself sends to the camera (the sky's for escaping rays).
    pub emission: Vec3,
}

impl GuidePixel {
    pub const SKY: GuidePixel = GuidePixel {
        position: Vec3A::ZERO,
        normal: Vec3A::ZERO,
        depth: f32::INFINITY,
        instance: NO_INSTANCE,
        albedo: Vec3::ONE,
        emission: Vec3::ZERO,
    };

    /// The guides of a camera ray from `origin` that found `hit` (None: the sky).
    pub fn from_hit(scene: &RenderScene, origin: Vec3A, hit: Option<&NextHit>) -> GuidePixel {
        let Some(found) = hit else {
            return GuidePixel {
                emission: scene.sky,
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
            emission: found.emitted,
        }
    }

    pub fn is_sky(&self) -> bool {
        self.instance == NO_INSTANCE
    }

    /// Demodulates `radiance` (this pixel's) into illumination: (L - emission) / albedo,
    /// with albedo floored so black surfaces give zero rather than infinity.
    pub fn demodulate(&self, radiance: Vec3) -> Vec3 {
        if self.is_sky() {
            return Vec3::ZERO;
        }
        (radiance - self.emission).max(Vec3::ZERO) / self.albedo.max(Vec3::splat(ALBEDO_FLOOR))
    }

    /// `demodulate`'s inverse.
    pub fn modulate(&self, illumination: Vec3) -> Vec3 {
        if self.is_sky() {
            return self.emission;
        }
        illumination * self.albedo.max(Vec3::splat(ALBEDO_FLOOR)) + self.emission
    }
}

/// Below this albedo a channel is treated as this dark (no division by zero).
const ALBEDO_FLOOR: f32 = 1e-3;

/// The guides of a whole image, row-major from the top-left like `Film`.
#[derive(Clone, Debug, PartialEq)]
pub struct Guides {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<GuidePixel>,
}

impl Guides {
    pub fn new(width: u32, height: u32) -> Guides {
        Guides {
            width,
            height,
            pixels: vec![GuidePixel::SKY; (width * height) as usize],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn demodulation_round_trips_and_keeps_emission_out() {
        let pixel = GuidePixel {
            albedo: Vec3::new(0.5, 0.25, 0.0),
            emission: Vec3::new(1.0, 0.0, 0.0),
            instance: 3,
            ..GuidePixel::SKY
        };
        let radiance = Vec3::new(1.5, 0.5, 0.0);
        let illumination = pixel.demodulate(radiance);
        assert_eq!(illumination, Vec3::new(1.0, 2.0, 0.0));
        assert_eq!(pixel.modulate(illumination), radiance);
        let sky = GuidePixel {
            emission: Vec3::splat(0.2),
            ..GuidePixel::SKY
        };
        assert_eq!(sky.demodulate(Vec3::splat(0.2)), Vec3::ZERO);
        assert_eq!(sky.modulate(Vec3::splat(9.0)), Vec3::splat(0.2));
    }
}
