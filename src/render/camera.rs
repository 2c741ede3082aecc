//! Frame step `render`, first: the camera and its primary rays.
//!
//! The pinhole model: pixel (u, v) from the top-left; ndc = (2u/W - 1, 1 - 2v/H);
//! camera-space direction (ndc.x tan(yfov/2) W/H, ndc.y tan(yfov/2), -1), rotated into the
//! world. An optional thin lens (Kolb et al. 1995 / pbrt's `PerspectiveCamera`) blurs what
//! is off the focus distance.

use glam::{Mat3A, Vec2, Vec3A};

use crate::accel::Ray;
use crate::scene::world::CameraPlacement;

/// Image-plane points for `Camera::pinhole_rays`, a plane per axis (so they load as lanes).
#[derive(Clone, Debug, Default)]
pub struct FilmPoints {
    x: Vec<f32>,
    y: Vec<f32>,
    /// Scratch: the rays' directions, a plane per axis.
    direction: [Vec<f32>; 3],
}

impl FilmPoints {
    pub fn clear(&mut self) {
        self.x.clear();
        self.y.clear();
    }

    pub fn push(&mut self, film: Vec2) {
        self.x.push(film.x);
        self.y.push(film.y);
    }
}

#[derive(Clone, Debug)]
pub struct Camera {
    pub position: Vec3A,
    /// World-from-camera rotation (no scale).
    pub rotation: Mat3A,
    /// tan(yfov / 2).
    pub tan_half_fov: f32,
    pub width: u32,
    pub height: u32,
    /// Thin-lens aperture radius in metres (0: pinhole).
    pub lens_radius: f32,
    /// Distance to the plane in focus, in metres along the view axis.
    pub focus_distance: f32,
}

impl Camera {
    pub fn new(placement: &CameraPlacement, width: u32, height: u32) -> Camera {
        let (_, rotation, translation) =
            placement.world_from_camera.to_scale_rotation_translation();
        Camera {
            position: translation.into(),
            rotation: Mat3A::from_quat(rotation),
            tan_half_fov: (placement.yfov * 0.5).tan(),
            width: width.max(1),
            height: height.max(1),
            lens_radius: 0.0,
            focus_distance: 1.0,
        }
    }

    /// Whether `ray` reads its lens position (a thin lens, not a pinhole).
    pub fn has_lens(&self) -> bool {
        self.lens_radius > 0.0
    }

    /// The ray through film point `film` (in pixels from the top-left, e.g. pixel + jitter);
    /// `lens` in [0, 1)^2 picks the point on the aperture.
    pub fn ray(&self, film: Vec2, lens: Vec2) -> Ray {
        let aspect = self.width as f32 / self.height as f32;
        let ndc = Vec2::new(
            2.0 * film.x / self.width as f32 - 1.0,
            1.0 - 2.0 * film.y / self.height as f32,
        );
        let direction = Vec3A::new(
            ndc.x * self.tan_half_fov * aspect,
            ndc.y * self.tan_half_fov,
            -1.0,
        );
        if !self.has_lens() {
            return Ray::new(self.position, (self.rotation * direction).normalize());
        }
        // Thin lens: aim from a point on the aperture at where the pinhole ray meets the
        // focus plane (z = -focus_distance in camera space).
        let focus = direction * self.focus_distance;
        let aperture = super::sampling::concentric_disk(lens) * self.lens_radius;
        let origin = Vec3A::new(aperture.x, aperture.y, 0.0);
        Ray::new(
            self.position + self.rotation * origin,
            (self.rotation * (focus - origin)).normalize(),
        )
    }

    /// A pinhole `ray`'s direction through `film`, in plain lane arithmetic without
    /// branches, so a row of them runs as vector lanes (`upscale`'s sky): ndc, the
    /// camera-space direction, the rotation and the normalisation, in glam's order of
    /// operations (`Mat3A * Vec3A` column by column, `normalize` a division by the length),
    /// so the same bits (a test holds the two together). `ray` keeps glam's own: one ray
    /// at a time it is the shorter (bench first-light, render 0.6% more instructions
    /// through this).
    #[inline(always)]
    pub fn pinhole_direction_lanes(&self, film: Vec2) -> [f32; 3] {
        let (width, height) = (self.width as f32, self.height as f32);
        let aspect = width / height;
        let (ndc_x, ndc_y) = (2.0 * film.x / width - 1.0, 1.0 - 2.0 * film.y / height);
        let (dx, dy, dz) = (
            ndc_x * self.tan_half_fov * aspect,
            ndc_y * self.tan_half_fov,
            -1.0,
        );
        let (x_axis, y_axis, z_axis) = (
            self.rotation.x_axis,
            self.rotation.y_axis,
            self.rotation.z_axis,
        );
        let rx = x_axis.x * dx + y_axis.x * dy + z_axis.x * dz;
        let ry = x_axis.y * dx + y_axis.y * dy + z_axis.y * dz;
        let rz = x_axis.z * dx + y_axis.z * dy + z_axis.z * dz;
        let length = (rx * rx + ry * ry + rz * rz).sqrt();
        [rx / length, ry / length, rz / length]
    }

    /// `ray` through each of `films`' points with no lens, into `rays`: the same bits,
    /// with the directions worked out together in vector lanes (`pinhole_direction_lanes`,
    /// eight to a register where the CPU has AVX2). One at a time, `ray`'s divisions and
    /// square root wait on each other: a tile's camera rays were 2.3% of a one-thread
    /// frame's cycles (perf, the-keep play-through at 640x360, half scale).
    pub fn pinhole_rays(&self, films: &mut FilmPoints, rays: &mut Vec<Ray>) {
        debug_assert!(!self.has_lens());
        let count = films.x.len();
        for plane in &mut films.direction {
            plane.resize(count, 0.0);
        }
        self.pinhole_directions(films);
        let [x, y, z] = &films.direction;
        rays.extend(
            (x.iter().zip(y).zip(z))
                .map(|((&x, &y), &z)| Ray::new(self.position, Vec3A::new(x, y, z))),
        );
    }

    /// `films`' ray directions into its direction planes, compiled for AVX2 where the CPU
    /// has it.
    fn pinhole_directions(&self, films: &mut FilmPoints) {
        #[cfg(target_arch = "x86_64")]
        if crate::simd::avx2() {
            #[target_feature(enable = "avx2")]
            fn pinhole_directions_avx2(camera: &Camera, films: &mut FilmPoints) {
                camera.pinhole_directions_lanes(films);
            }
            // SAFETY: the CPU has AVX2, the only feature `pinhole_directions_avx2` enables.
            return unsafe { pinhole_directions_avx2(self, films) };
        }
        self.pinhole_directions_lanes(films);
    }

    /// `pinhole_directions` as plain lane arithmetic, for the compiler to vectorise.
    #[inline(always)]
    fn pinhole_directions_lanes(&self, films: &mut FilmPoints) {
        let count = films.x.len();
        // Every slice cut to `count`: the loop runs without bounds checks, so it vectorises.
        let (film_x, film_y) = (&films.x[..count], &films.y[..count]);
        let [x, y, z] = &mut films.direction;
        let (x, y, z) = (&mut x[..count], &mut y[..count], &mut z[..count]);
        for i in 0..count {
            [x[i], y[i], z[i]] = self.pinhole_direction_lanes(Vec2::new(film_x[i], film_y[i]));
        }
    }

    /// The film point (pixels from the top-left, continuous) a world point projects to
    /// through the pinhole: `ray`'s inverse. None behind the camera.
    pub fn project(&self, point: Vec3A) -> Option<Vec2> {
        self.projection().project(point)
    }

    /// `project` with its per-camera terms worked out once, for projecting many points.
    pub fn projection(&self) -> Projection {
        let (width, height) = (self.width as f32, self.height as f32);
        let aspect = width / height;
        Projection {
            camera_from_world: self.rotation.transpose(),
            position: self.position,
            scale: Vec2::new(
                0.5 * width / (self.tan_half_fov * aspect),
                -0.5 * height / self.tan_half_fov,
            ),
            centre: Vec2::new(0.5 * width, 0.5 * height),
        }
    }
}

/// A camera's world-to-film projection.
#[derive(Clone, Debug)]
pub struct Projection {
    camera_from_world: Mat3A,
    position: Vec3A,
    /// Image-plane pixels per unit of x / -z and y / -z (y flipped: film rows run down).
    scale: Vec2,
    centre: Vec2,
}

/// A point as `Projection::project_lanes` finds it.
#[derive(Clone, Copy, Debug)]
pub struct FilmPoint {
    /// Where on the film (pixels; meaningless when not `in_front`).
    pub x: f32,
    pub y: f32,
    /// The point's distance from the camera.
    pub distance: f32,
    pub in_front: bool,
}

impl Projection {
    pub fn project(&self, point: Vec3A) -> Option<Vec2> {
        let projected = self.project_lanes(point);
        projected
            .in_front
            .then(|| Vec2::new(projected.x, projected.y))
    }

    /// `project` in plain lane arithmetic without branches, so a row of points projects
    /// as lanes (`reproject`), and with the point's distance.
    #[inline(always)]
    pub fn project_lanes(&self, point: Vec3A) -> FilmPoint {
        let rotation = &self.camera_from_world;
        let (px, py, pz) = (
            point.x - self.position.x,
            point.y - self.position.y,
            point.z - self.position.z,
        );
        // Camera space: the rotation's rows times the relative position.
        let local_x = rotation.x_axis.x * px + rotation.y_axis.x * py + rotation.z_axis.x * pz;
        let local_y = rotation.x_axis.y * px + rotation.y_axis.y * py + rotation.z_axis.y * pz;
        let local_z = rotation.x_axis.z * px + rotation.y_axis.z * py + rotation.z_axis.z * pz;
        let inverse_depth = 1.0 / -local_z;
        FilmPoint {
            x: local_x * inverse_depth * self.scale.x + self.centre.x,
            y: local_y * inverse_depth * self.scale.y + self.centre.y,
            distance: (px * px + py * py + pz * pz).sqrt(),
            in_front: local_z < -1e-6,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Mat4;

    #[test]
    fn centre_pixel_looks_down_minus_z_and_corners_span_the_fov() {
        let placement = CameraPlacement {
            name: String::new(),
            yfov: 90f32.to_radians(),
            znear: 0.1,
            world_from_camera: Mat4::IDENTITY,
        };
        let camera = Camera::new(&placement, 200, 100);
        let centre = camera.ray(Vec2::new(100.0, 50.0), Vec2::ZERO);
        assert!((centre.direction - Vec3A::NEG_Z).length() < 1e-6);
        // Top edge centre: 45 degrees up.
        let top = camera.ray(Vec2::new(100.0, 0.0), Vec2::ZERO);
        assert!((top.direction.y - top.direction.z.abs()).abs() < 1e-6 && top.direction.y > 0.0);
        // Left edge: x = -aspect * tan(45) = -2 at z = -1.
        let left = camera.ray(Vec2::new(0.0, 50.0), Vec2::ZERO);
        assert!((left.direction.x / left.direction.z - 2.0).abs() < 1e-5);
    }

    #[test]
    fn pinhole_directions_in_lanes_are_ray_directions_to_the_bit() {
        let placement = CameraPlacement {
            name: String::new(),
            yfov: 70f32.to_radians(),
            znear: 0.1,
            world_from_camera: Mat4::from_rotation_translation(
                glam::Quat::from_euler(glam::EulerRot::YXZ, 2.3, -0.4, 0.2),
                glam::Vec3::new(-4.0, 1.7, 9.0),
            ),
        };
        let camera = Camera::new(&placement, 333, 187);
        for i in 0..5000u32 {
            let jitter = Vec2::new((i * 37 % 101) as f32, (i * 59 % 97) as f32) / 101.0;
            let film = Vec2::new((i % 333) as f32, (i / 333 * 13 % 187) as f32) + jitter;
            let ray = camera.ray(film, Vec2::ZERO);
            assert_eq!(
                ray.direction.to_array().map(f32::to_bits),
                camera.pinhole_direction_lanes(film).map(f32::to_bits),
                "film point {film}"
            );
        }
    }

    #[test]
    fn pinhole_rays_together_are_rays_one_at_a_time_to_the_bit() {
        let placement = CameraPlacement {
            name: String::new(),
            yfov: 55f32.to_radians(),
            znear: 0.1,
            world_from_camera: Mat4::from_rotation_translation(
                glam::Quat::from_euler(glam::EulerRot::YXZ, -1.1, 0.3, -0.2),
                glam::Vec3::new(2.0, 1.6, -7.0),
            ),
        };
        let camera = Camera::new(&placement, 320, 180);
        // 259 points: whole registers of eight and a remainder.
        let films: Vec<Vec2> = (0..259u32)
            .map(|i| {
                Vec2::new((i * 41 % 320) as f32, (i * 7 % 180) as f32) + (i % 13) as f32 / 13.0
            })
            .collect();
        let mut points = FilmPoints::default();
        let mut rays = Vec::new();
        for round in 0..2 {
            // A second round reuses the scratch, as a tile's next sample does.
            points.clear();
            rays.clear();
            films[round..].iter().for_each(|&film| points.push(film));
            camera.pinhole_rays(&mut points, &mut rays);
            assert_eq!(rays.len(), films.len() - round);
            for (film, ray) in films[round..].iter().zip(&rays) {
                let one = camera.ray(*film, Vec2::ZERO);
                assert_eq!(
                    (
                        one.origin.to_array(),
                        one.direction.to_array().map(f32::to_bits)
                    ),
                    (
                        ray.origin.to_array(),
                        ray.direction.to_array().map(f32::to_bits)
                    ),
                    "film point {film}"
                );
                assert_eq!((one.t_min, one.t_max), (ray.t_min, ray.t_max));
            }
        }
    }

    #[test]
    fn project_inverts_ray() {
        let placement = CameraPlacement {
            name: String::new(),
            yfov: 60f32.to_radians(),
            znear: 0.1,
            world_from_camera: Mat4::from_rotation_translation(
                glam::Quat::from_euler(glam::EulerRot::YXZ, 0.7, -0.3, 0.1),
                glam::Vec3::new(1.0, 2.0, -3.0),
            ),
        };
        let camera = Camera::new(&placement, 320, 180);
        for film in [
            Vec2::new(0.5, 0.5),
            Vec2::new(160.0, 90.0),
            Vec2::new(311.2, 7.9),
        ] {
            let ray = camera.ray(film, Vec2::ZERO);
            let point = ray.origin + ray.direction * 4.5;
            let back = camera.project(point).unwrap();
            assert!((back - film).length() < 1e-3, "{film} -> {back}");
            assert!(camera.project(ray.origin - ray.direction).is_none());
        }
    }
}
