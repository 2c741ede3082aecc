//! How the simulation asks the world questions: the surfaces a body touches, what a ray
//! meets, how much light reaches a point. The game defines the questions (`WorldQuery`) and holds the answerer as a
//! resource (`WorldGeometry`); the frame driver's extract step implements them over the
//! level's geometry as of the current fixed step (never the render's interpolated
//! transforms), so play, headless replays and any frame rate agree, and tests answer them
//! with a fake world.

use bevy_ecs::prelude::*;
use glam::Vec3;

/// A surface point within reach of a query sphere.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Contact {
    /// The closest point of the surface to the sphere's centre.
    pub point: Vec3,
    /// Unit direction from `point` to the centre: the way out.
    pub normal: Vec3,
    /// Distance from the centre to `point` (less than the radius).
    pub distance: f32,
}

/// Where a ray meets a surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayHit {
    /// Along the ray, from its origin.
    pub distance: f32,
    /// The surface's unit normal, on the side its triangle's winding makes the front
    /// (a floor's points up; the ray may have met its back).
    pub normal: Vec3,
    /// What it sounds like underfoot or struck (by its material).
    pub surface: Surface,
}

pub use crate::scene::sound_kit::Surface;

/// The questions the simulation asks of the level's geometry.
pub trait WorldQuery: Send + Sync + 'static {
    /// Every surface closer than `radius` to `center`, appended to `out`.
    fn sphere_contacts(&self, center: Vec3, radius: f32, out: &mut Vec<Contact>);

    /// The first surface along the unit `direction` from `origin`, if one is nearer than
    /// `max_distance`.
    fn raycast(&self, origin: Vec3, direction: Vec3, max_distance: f32) -> Option<RayHit>;

    /// The light arriving at `point` from every light within reach (linear RGB: irradiance
    /// from each direction summed, as a small sphere there would receive it), each light's
    /// share found with a shadow ray, with the renderer's own light definitions.
    fn light_arriving(&self, point: Vec3) -> Vec3;

    /// Every mirror triangle in the level (world space, front face by its winding): the
    /// surfaces the renderer reflects perfectly, through which wardens and the player see
    /// each other (`sight`).
    fn mirrors(&self) -> &[[Vec3; 3]] {
        &[]
    }

    /// The corners (min, max) of a box around all the geometry, if there is any.
    fn bounds(&self) -> Option<(Vec3, Vec3)> {
        None
    }

    /// The answerer as `Any`, so the code that keeps it current can reach its own type.
    fn as_any_mut(&mut self) -> &mut dyn std::any::Any;
}

/// The level's geometry as the simulation sees it.
#[derive(Resource)]
pub struct WorldGeometry(pub Box<dyn WorldQuery>);

/// A world with nothing in it (a level before its geometry is extracted).
pub struct EmptyWorld;

impl WorldQuery for EmptyWorld {
    fn sphere_contacts(&self, _: Vec3, _: f32, _: &mut Vec<Contact>) {}

    fn raycast(&self, _: Vec3, _: Vec3, _: f32) -> Option<RayHit> {
        None
    }

    fn light_arriving(&self, _: Vec3) -> Vec3 {
        Vec3::ZERO
    }

    fn as_any_mut(&mut self) -> &mut dyn std::any::Any {
        self
    }
}

impl Default for WorldGeometry {
    fn default() -> Self {
        WorldGeometry(Box::new(EmptyWorld))
    }
}

/// Test worlds shared by the game's unit tests.
#[cfg(test)]
pub(crate) mod fakes {
    use super::*;

    /// A wall between everything: every ray is stopped halfway.
    pub struct Walled;

    impl WorldQuery for Walled {
        fn sphere_contacts(&self, _: Vec3, _: f32, _: &mut Vec<Contact>) {}

        fn raycast(&self, _: Vec3, direction: Vec3, max_distance: f32) -> Option<RayHit> {
            Some(RayHit {
                surface: Surface::Stone,
                distance: max_distance * 0.5,
                normal: -direction,
            })
        }

        fn light_arriving(&self, _: Vec3) -> Vec3 {
            Vec3::ZERO
        }

        fn as_any_mut(&mut self) -> &mut dyn std::any::Any {
            self
        }
    }
}
