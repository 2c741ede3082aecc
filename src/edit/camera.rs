//! The editor's own view: a free-flying camera that is not part of the level (it is never
//! saved), put into the world as the active `ViewCamera` so extract renders from it.
//!
//! Yaw turns about world +Y, pitch about the camera's own X; the camera looks down its
//! local -Z, as every Gloam camera does. Flying moves in the view's frame: forward along
//! the look direction, right along its X, up along world +Y.

use bevy_ecs::prelude::{Component, Name, With, World};
use glam::{EulerRot, Mat4, Quat, Vec2, Vec3};

use rayon::prelude::*;

use crate::accel::InstanceMask;
use crate::frame::Engine;
use crate::game::{ActiveCamera, GlobalTransform, PreviousGlobalTransform, Transform, ViewCamera};
use crate::scene::world::CameraPlacement;

/// Marks the editor's view entity (one per world).
#[derive(Component, Clone, Copy, Debug, Default)]
pub struct EditorView;

/// How far pitch may go from the horizon, short of straight up or down (where yaw is lost).
const PITCH_LIMIT: f32 = 1.55;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FlyCamera {
    pub position: Vec3,
    /// Radians about +Y; 0 looks down -Z.
    pub yaw: f32,
    /// Radians above the horizon.
    pub pitch: f32,
    /// Vertical field of view in radians.
    pub yfov: f32,
    pub znear: f32,
}

impl FlyCamera {
    /// Starts where the engine's view is now: the level's own camera, else the view that
    /// frames it.
    pub fn from_view(engine: &Engine) -> FlyCamera {
        let placement = &engine.render_scene().camera;
        let (_, rotation, position) = placement.world_from_camera.to_scale_rotation_translation();
        let forward = rotation * Vec3::NEG_Z;
        FlyCamera {
            position,
            yaw: (-forward.x).atan2(-forward.z),
            pitch: forward
                .y
                .clamp(-1.0, 1.0)
                .asin()
                .clamp(-PITCH_LIMIT, PITCH_LIMIT),
            yfov: placement.yfov,
            znear: placement.znear.min(0.05),
        }
    }

    pub fn rotation(&self) -> Quat {
        Quat::from_euler(EulerRot::YXZ, self.yaw, self.pitch, 0.0)
    }

    pub fn world_from_camera(&self) -> Mat4 {
        Mat4::from_rotation_translation(self.rotation(), self.position)
    }

    /// The view as the renderer's camera takes it (to cast a click's ray, to project).
    pub fn placement(&self) -> CameraPlacement {
        CameraPlacement {
            name: String::new(),
            yfov: self.yfov,
            znear: self.znear,
            world_from_camera: self.world_from_camera(),
        }
    }

    /// Turns the view by `radians` (x: right, y: up).
    pub fn turn(&mut self, radians: Vec2) {
        self.yaw -= radians.x;
        self.pitch = (self.pitch + radians.y).clamp(-PITCH_LIMIT, PITCH_LIMIT);
    }

    /// Moves by `local` metres: x right, y world up, z forward along the look direction.
    pub fn fly(&mut self, local: Vec3) {
        let rotation = self.rotation();
        self.position +=
            rotation * Vec3::X * local.x + Vec3::Y * local.y + rotation * Vec3::NEG_Z * local.z;
    }

    /// Backs off along the look direction until the box [min, max] fills the view (its
    /// bounding sphere touching the narrower side of the frustum at `aspect`, width over
    /// height), looking at its centre: the editor's F, frame the selection.
    pub fn frame(&mut self, min: Vec3, max: Vec3, aspect: f32) {
        let centre = (min + max) * 0.5;
        let radius = ((max - min).length() * 0.5).max(0.1);
        let half_vertical = self.yfov * 0.5;
        let half_horizontal = (half_vertical.tan() * aspect.max(1e-3)).atan();
        let distance = radius / half_vertical.min(half_horizontal).sin();
        let forward = self.rotation() * Vec3::NEG_Z;
        self.position = centre - forward * distance;
    }

    /// Makes this the view the next frame renders from (spawning the editor's view entity
    /// the first time). Only the view changes: the level is not touched.
    pub fn install(&self, world: &mut World) {
        let placed = Transform::from_matrix(self.world_from_camera());
        let global = placed.affine();
        let lens = ViewCamera {
            yfov: self.yfov,
            znear: self.znear,
        };
        let mut views = world.query_filtered::<(
            &mut Transform,
            &mut GlobalTransform,
            &mut PreviousGlobalTransform,
            &mut ViewCamera,
        ), With<EditorView>>();
        if let Some((mut transform, mut now, mut before, mut view)) = views.iter_mut(world).next() {
            *transform = placed;
            now.0 = global;
            // No motion between frames to blur or reproject: the view jumps.
            before.0 = global;
            *view = lens;
            return;
        }
        world.spawn((
            Name::new("editor view"),
            EditorView,
            ActiveCamera,
            lens,
            placed,
            GlobalTransform(global),
            PreviousGlobalTransform(global),
        ));
    }
}

/// How far the camera sees through each cell of a coarse grid over the view: what the
/// editor's overlays drawn in the world (the ground grid) test against, so the level hides
/// them as it hides itself.
#[derive(Clone, Debug)]
pub struct ViewDepth {
    /// The view it was taken from.
    pub camera: FlyCamera,
    /// That view's projection onto the cells.
    projection: crate::render::camera::Projection,
    pub width: u32,
    pub height: u32,
    /// Metres from the camera to the first surface a camera ray meets through each cell's
    /// centre (infinite where it meets nothing), row-major from the top-left.
    pub metres: Vec<f32>,
}

impl ViewDepth {
    /// The depth of `engine`'s level seen from `camera`, `width` x `height` cells over an
    /// image of the same aspect.
    pub fn of(engine: &Engine, camera: &FlyCamera, width: u32, height: u32) -> ViewDepth {
        let (width, height) = (width.max(1), height.max(1));
        let lens = crate::render::Camera::new(&camera.placement(), width, height);
        let scene = engine.render_scene();
        let alpha = scene.alpha();
        let metres = (0..width * height)
            .into_par_iter()
            .map(|cell| {
                let pixel = Vec2::new((cell % width) as f32 + 0.5, (cell / width) as f32 + 0.5);
                let ray = lens.ray(pixel, Vec2::ZERO);
                scene
                    .accel
                    .intersect(&ray, InstanceMask::CAMERA, &alpha)
                    .map_or(f32::INFINITY, |hit| hit.t * ray.direction.length())
            })
            .collect();
        ViewDepth {
            camera: *camera,
            projection: lens.projection(),
            width,
            height,
            metres,
        }
    }

    /// Whether `point` is in front of the level from the camera: not behind the surface
    /// seen through its cell (with a margin, so a line on a floor shows on it). Points off
    /// the view count as seen.
    pub fn shows(&self, point: Vec3) -> bool {
        let Some(at) = self.projection.project(point.into()) else {
            return false;
        };
        let (x, y) = (at.x.floor(), at.y.floor());
        if x < 0.0 || y < 0.0 || x >= self.width as f32 || y >= self.height as f32 {
            return true;
        }
        let seen = self.metres[y as usize * self.width as usize + x as usize];
        let distance = point.distance(self.camera.position);
        seen >= distance - (0.05 + 0.02 * distance)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn yaw_and_pitch_give_the_look_direction_and_flying_follows_it() {
        let mut camera = FlyCamera {
            position: Vec3::ZERO,
            yaw: 0.0,
            pitch: 0.0,
            yfov: 1.0,
            znear: 0.05,
        };
        camera.fly(Vec3::new(0.0, 0.0, 2.0));
        assert!((camera.position - Vec3::new(0.0, 0.0, -2.0)).length() < 1e-6);
        // A quarter turn right looks down +X.
        camera.turn(Vec2::new(std::f32::consts::FRAC_PI_2, 0.0));
        camera.fly(Vec3::new(0.0, 1.0, 1.0));
        assert!((camera.position - Vec3::new(1.0, 1.0, -2.0)).length() < 1e-5);
        // Pitch stops short of the pole.
        camera.turn(Vec2::new(0.0, 10.0));
        assert_eq!(camera.pitch, PITCH_LIMIT);
    }

    /// From high over the template's room, its floor shows, the ground just behind its far
    /// wall is hidden by the wall, and a point in the air in front of everything shows.
    #[test]
    fn the_view_depth_hides_the_ground_behind_a_wall_and_shows_the_floor() {
        // Never written: the template's assets are named relative to it.
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("levels/room.ron");
        let level = crate::edit::template::new_level(&path);
        let scene = crate::scene::Scene::from_level(level, &path).expect("the template");
        let engine = Engine::new(&scene, crate::render::RenderSettings::real_time(16, 9));
        let camera = FlyCamera {
            position: Vec3::new(0.0, 9.0, 7.5),
            yaw: 0.0,
            pitch: -50f32.to_radians(),
            yfov: 65f32.to_radians(),
            znear: 0.05,
        };
        let depth = ViewDepth::of(&engine, &camera, 120, 68);
        assert!(depth.shows(Vec3::new(0.5, 0.0, 0.5)), "the room's floor");
        assert!(
            !depth.shows(Vec3::new(0.5, 0.0, -5.0)),
            "behind the north wall"
        );
        assert!(depth.shows(Vec3::new(0.5, 4.0, 0.5)), "above it all");
        assert!(!depth.shows(Vec3::new(0.5, 0.0, 20.0)), "behind the camera");
    }

    #[test]
    fn framing_a_box_looks_at_its_centre_from_where_it_just_fits() {
        let mut camera = FlyCamera {
            position: Vec3::new(50.0, 3.0, 9.0),
            yaw: 0.3,
            pitch: -0.4,
            yfov: 60f32.to_radians(),
            znear: 0.05,
        };
        let (yaw, pitch) = (camera.yaw, camera.pitch);
        let (min, max) = (Vec3::new(1.0, 0.0, -3.0), Vec3::new(3.0, 2.0, -1.0));
        camera.frame(min, max, 16.0 / 9.0);
        assert_eq!(
            (camera.yaw, camera.pitch),
            (yaw, pitch),
            "the view keeps its angle"
        );
        let centre = Vec3::new(2.0, 1.0, -2.0);
        let to_centre = centre - camera.position;
        let forward = camera.rotation() * Vec3::NEG_Z;
        assert!(
            to_centre.normalize().dot(forward) > 0.9999,
            "looks at the centre"
        );
        // The sphere around the box (radius sqrt 3) touches the 30-degree half angle.
        let radius = 3f32.sqrt();
        assert!((to_centre.length() - radius / 30f32.to_radians().sin()).abs() < 1e-4);
        // A tall, narrow view backs off further: the width is then the tighter side.
        let mut narrow = camera;
        narrow.frame(min, max, 0.5);
        assert!((narrow.position - centre).length() > to_centre.length() + 0.5);
    }
}
