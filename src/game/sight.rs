//! Game schedule, fixed step "gameplay": what a warden sees of the player this step.
//!
//! A warden looks from its eyes along its facing with two cones (the starting numbers
//! of the stealth games players love, tuned by playing): a narrow far one (`FAR_HALF_ANGLE` either side, out
//! to `FAR_RANGE`) and a wide near one (`NEAR_HALF_ANGLE`, out to `NEAR_RANGE`); behind
//! it, nothing but what is within `TOUCH_RANGE`. For each of the player's body points
//! (`exposure::body_points`, the same ones the light gem is measured at) inside a cone, a
//! ray from the eyes through the level as of this step (`WorldQuery::raycast`) says
//! whether anything stands between. Then
//!
//!   visibility = share of points in sight x lit(gem) x falloff(distance)
//!
//! where `lit` is the light gem with its darkest step taken off (a gem that lights no
//! cell on the HUD hides the player from every warden) and `falloff` is 1 out to
//! `FULL_SIGHT` and falls linearly to `FAR_FALLOFF` at `FAR_RANGE`. A warden reads
//! nothing else of the player: the gem is on the HUD, the rest is geometry the player
//! sees too.
//!
//! Sight goes through mirrors, as the player's does: a point not seen straight may be
//! seen in a mirror triangle (`WorldQuery::mirrors`, the level's perfect-mirror surfaces),
//! along the reflected path, with the cones and the falloff taken at that path's length.
//! Light does not: the gem's shadow rays, like the renderer's light sampling, stop at the
//! first surface, so a mirror shows a lamp but throws none of its light.

use glam::Vec3;

use super::exposure::{BODY_POINTS, curve};
use super::world_query::WorldQuery;

/// The wardens' eyes, in one place (metres, degrees).
pub mod tuning {
    /// The wide near cone: half its angle, and how far it reaches.
    pub const NEAR_HALF_ANGLE: f32 = 60.0;
    pub const NEAR_RANGE: f32 = 5.0;
    /// The narrow far cone.
    pub const FAR_HALF_ANGLE: f32 = 30.0;
    pub const FAR_RANGE: f32 = 18.0;
    /// Within this distance a warden senses the player from any side.
    pub const TOUCH_RANGE: f32 = 0.8;
    /// Sight is undimmed out to this distance ...
    pub const FULL_SIGHT: f32 = 6.0;
    /// ... and falls off linearly to this factor at `FAR_RANGE`.
    pub const FAR_FALLOFF: f32 = 0.2;
    /// Where the eyes are above the feet, and ahead of the body's axis (outside the head).
    pub const EYE_HEIGHT: f32 = 1.6;
    pub const EYE_FORWARD: f32 = 0.15;
}

use tuning::*;

/// What one warden sees of the player in one step.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sighting {
    /// Share of the body points inside a cone with nothing in between, 0..1.
    pub share: f32,
    /// How well it sees the player, 0..1 (the module doc's product).
    pub visibility: f32,
    /// From the eyes to the body's middle, metres.
    pub distance: f32,
}

/// A warden's eyes standing at `feet` facing `forward` (horizontal, unit).
pub fn eye(feet: Vec3, forward: Vec3) -> Vec3 {
    feet + Vec3::Y * EYE_HEIGHT + forward * EYE_FORWARD
}

/// How much of the light gem counts: 0 below its darkest step, rising to 1 at full.
pub fn lit(gem: f32) -> f32 {
    ((gem - curve::HIDDEN) / (1.0 - curve::HIDDEN)).clamp(0.0, 1.0)
}

/// Sight's distance factor.
pub fn falloff(distance: f32) -> f32 {
    if distance <= FULL_SIGHT {
        return 1.0;
    }
    let beyond = ((distance - FULL_SIGHT) / (FAR_RANGE - FULL_SIGHT)).min(1.0);
    1.0 + (FAR_FALLOFF - 1.0) * beyond
}

/// Whether a point `offset` from the eyes lies in a cone (or within touch).
pub fn in_view(offset: Vec3, forward: Vec3) -> bool {
    let distance = offset.length();
    if distance <= TOUCH_RANGE {
        return true;
    }
    let cosine = offset.dot(forward) / distance;
    (distance <= NEAR_RANGE && cosine >= NEAR_HALF_ANGLE.to_radians().cos())
        || (distance <= FAR_RANGE && cosine >= FAR_HALF_ANGLE.to_radians().cos())
}

/// What a warden with eyes at `eye` looking along `forward` sees of a body whose points
/// are `points`, lit as the gem says: straight, or in any mirror (`reflected_path`).
pub fn look(
    world: &dyn WorldQuery,
    eye: Vec3,
    forward: Vec3,
    points: &[Vec3; BODY_POINTS.len()],
    gem: f32,
) -> Sighting {
    let middle = points.iter().sum::<Vec3>() / points.len() as f32;
    let mirrors = world.mirrors();
    let mut seen = 0;
    // The shortest way the eyes reach a point they see, for the falloff.
    let mut nearest = f32::INFINITY;
    for &point in points {
        let offset = point - eye;
        let length = offset.length();
        if in_view(offset, forward)
            && (length < 1e-4 || world.raycast(eye, offset / length, length).is_none())
        {
            seen += 1;
            nearest = nearest.min(middle.distance(eye));
            continue;
        }
        let reflected = mirrors
            .iter()
            .filter_map(|mirror| reflected_path(world, eye, forward, point, mirror))
            .reduce(f32::min);
        if let Some(path) = reflected {
            seen += 1;
            nearest = nearest.min(path);
        }
    }
    let share = seen as f32 / points.len() as f32;
    let distance = if seen > 0 {
        nearest
    } else {
        middle.distance(eye)
    };
    Sighting {
        share,
        visibility: share * lit(gem) * falloff(distance),
        distance,
    }
}

/// The length of the path from `eye` to `point` by way of the front of the mirror
/// triangle `mirror`, when the eyes see the point there: both in front of its plane, the
/// reflection landing inside the triangle, the spot on the mirror in a cone at the path's
/// length, and nothing on either leg. The law of reflection makes that path the straight
/// line from the eye's image behind the mirror to the point.
pub fn reflected_path(
    world: &dyn WorldQuery,
    eye: Vec3,
    forward: Vec3,
    point: Vec3,
    mirror: &[Vec3; 3],
) -> Option<f32> {
    let [a, b, c] = *mirror;
    let normal = (b - a).cross(c - a).try_normalize()?;
    let (eye_height, point_height) = ((eye - a).dot(normal), (point - a).dot(normal));
    if eye_height <= 1e-3 || point_height <= 1e-3 {
        return None;
    }
    let image = eye - 2.0 * eye_height * normal;
    // Where the line from the point to the eye's image crosses the mirror's plane.
    let spot = point + (image - point) * (point_height / (point_height + eye_height));
    if !inside_triangle(spot, mirror, normal) {
        return None;
    }
    let path = point.distance(image);
    let to_spot = spot - eye;
    if !in_view(to_spot.normalize_or_zero() * path, forward) {
        return None;
    }
    // Both legs clear, short of the mirror itself.
    let clear = |from: Vec3, to: Vec3| {
        let leg = to - from;
        let length = leg.length();
        length <= 2e-3 || world.raycast(from, leg / length, length - 2e-3).is_none()
    };
    (clear(eye, spot) && clear(point, spot)).then_some(path)
}

/// Whether `p`, on the plane of `triangle` (unit `normal`), lies inside it (edges
/// included).
fn inside_triangle(p: Vec3, triangle: &[Vec3; 3], normal: Vec3) -> bool {
    (0..3).all(|i| {
        let (from, to) = (triangle[i], triangle[(i + 1) % 3]);
        (to - from).cross(p - from).dot(normal) >= -1e-6
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::game::exposure::body_points;
    use crate::game::world_query::EmptyWorld;

    use crate::game::world_query::fakes::Walled;

    /// What a warden at the origin facing +Z sees of a standing body at `feet` lit `gem`.
    fn sees(world: &dyn WorldQuery, feet: Vec3, gem: f32) -> Sighting {
        let points = body_points(feet, 0.0, crate::game::player::tuning::STANDING_HEIGHT);
        look(world, eye(Vec3::ZERO, Vec3::Z), Vec3::Z, &points, gem)
    }

    #[test]
    fn a_lit_body_ahead_is_seen_whole_and_a_dark_one_not_at_all() {
        let ahead = sees(&EmptyWorld, Vec3::new(0.0, 0.0, 3.0), 1.0);
        assert_eq!(ahead.share, 1.0);
        assert!((ahead.visibility - 1.0).abs() < 1e-6, "{ahead:?}");
        // A gem that lights no step on the HUD hides the body from every warden.
        let dark = sees(&EmptyWorld, Vec3::new(0.0, 0.0, 3.0), curve::HIDDEN * 0.99);
        assert_eq!(dark.share, 1.0);
        assert_eq!(dark.visibility, 0.0);
    }

    #[test]
    fn the_cones_reach_as_far_as_their_angles_say() {
        let at = |degrees: f32, distance: f32| {
            let direction = Vec3::new(degrees.to_radians().sin(), 0.0, degrees.to_radians().cos());
            sees(&EmptyWorld, direction * distance, 1.0).visibility
        };
        // The wide near cone: 50 degrees off at 4 m is seen, 70 degrees off is not.
        assert!(at(50.0, 4.0) > 0.5);
        assert_eq!(at(70.0, 4.0), 0.0);
        // The narrow far cone: 20 degrees off at 12 m is seen, dimmer; 40 degrees off is not.
        let far = at(20.0, 12.0);
        assert!(far > 0.0 && far < at(20.0, 4.0), "{far}");
        assert_eq!(at(40.0, 12.0), 0.0);
        assert_eq!(at(0.0, FAR_RANGE + 2.0), 0.0);
        // Behind: nothing, except within touch.
        assert_eq!(at(180.0, 2.0), 0.0);
        assert!(at(180.0, 0.3) > 0.0);
    }

    #[test]
    fn a_wall_between_hides_a_lit_body() {
        let blocked = sees(&Walled, Vec3::new(0.0, 0.0, 3.0), 1.0);
        assert_eq!(blocked.share, 0.0);
        assert_eq!(blocked.visibility, 0.0);
    }

    #[test]
    fn falloff_is_one_near_and_the_floor_at_the_far_cone_s_end() {
        assert_eq!(falloff(0.5), 1.0);
        assert_eq!(falloff(FULL_SIGHT), 1.0);
        assert!((falloff(FAR_RANGE) - FAR_FALLOFF).abs() < 1e-6);
        assert!(falloff(12.0) < 1.0 && falloff(12.0) > FAR_FALLOFF);
    }

    /// A screen 0.5 m either side of the line ahead (the plane z = 2) hides the body at
    /// (0, 0, 6) from a warden at the origin; a mirror (the plane x = 1, facing the warden,
    /// z 0..10) shows it from the side. `with_mirror` false keeps the glass but not its
    /// reflection (a plain wall there).
    struct MirrorRoom {
        with_mirror: bool,
    }

    const MIRROR: [[Vec3; 3]; 2] = [
        [
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 10.0),
            Vec3::new(1.0, 3.0, 0.0),
        ],
        [
            Vec3::new(1.0, 3.0, 0.0),
            Vec3::new(1.0, 0.0, 10.0),
            Vec3::new(1.0, 3.0, 10.0),
        ],
    ];

    impl WorldQuery for MirrorRoom {
        fn sphere_contacts(&self, _: Vec3, _: f32, _: &mut Vec<crate::game::world_query::Contact>) {
        }

        fn raycast(
            &self,
            origin: Vec3,
            direction: Vec3,
            max_distance: f32,
        ) -> Option<crate::game::world_query::RayHit> {
            // (distance along the ray to the plane, whether the crossing is on the panel)
            let screen = (direction.z.abs() > 1e-6).then(|| {
                let t = (2.0 - origin.z) / direction.z;
                let at = origin + direction * t;
                (t, at.x.abs() < 0.5 && (0.0..3.0).contains(&at.y))
            });
            let glass = (direction.x.abs() > 1e-6).then(|| {
                let t = (1.0 - origin.x) / direction.x;
                let at = origin + direction * t;
                (t, (0.0..10.0).contains(&at.z) && (0.0..3.0).contains(&at.y))
            });
            [screen, glass]
                .into_iter()
                .flatten()
                .filter(|&(t, on)| on && t > 0.0 && t < max_distance)
                .map(|(t, _)| t)
                .reduce(f32::min)
                .map(|distance| crate::game::world_query::RayHit {
                    surface: crate::game::world_query::Surface::Stone,
                    distance,
                    normal: -direction,
                })
        }

        fn light_arriving(&self, _: Vec3) -> Vec3 {
            Vec3::ZERO
        }

        fn mirrors(&self) -> &[[Vec3; 3]] {
            if self.with_mirror { &MIRROR } else { &[] }
        }

        fn as_any_mut(&mut self) -> &mut dyn std::any::Any {
            self
        }
    }

    #[test]
    fn a_body_hidden_from_straight_sight_is_seen_in_a_mirror_at_the_reflected_distance() {
        let feet = Vec3::new(0.0, 0.0, 6.0);
        let plain = sees(&MirrorRoom { with_mirror: false }, feet, 1.0);
        assert_eq!(plain.share, 0.0, "the screen hides it: {plain:?}");
        let mirrored = sees(&MirrorRoom { with_mirror: true }, feet, 1.0);
        assert!(mirrored.share >= 0.5, "{mirrored:?}");
        // The path by the mirror is the straight line from the eye's image (x = 2).
        let image = eye(Vec3::ZERO, Vec3::Z) + Vec3::X * 2.0;
        let points = body_points(feet, 0.0, crate::game::player::tuning::STANDING_HEIGHT);
        let shortest = points
            .iter()
            .map(|point| point.distance(image))
            .fold(f32::INFINITY, f32::min);
        assert!(
            (mirrored.distance - shortest).abs() < 1e-4,
            "{mirrored:?} {shortest}"
        );
        assert!(mirrored.visibility > 0.0 && mirrored.visibility < 1.0);
    }

    #[test]
    fn a_mirror_shows_nothing_from_behind_or_outside_the_glass() {
        let points = body_points(
            Vec3::new(0.0, 0.0, 6.0),
            0.0,
            crate::game::player::tuning::STANDING_HEIGHT,
        );
        let room = MirrorRoom { with_mirror: true };
        // Eyes behind the glass (x > 1) see its back: no reflection.
        let behind = look(&room, Vec3::new(2.0, 1.6, 0.15), Vec3::Z, &points, 1.0);
        assert_eq!(behind.share, 0.0, "{behind:?}");
        // A body whose reflection would land past the glass's far end is not seen in it.
        let beyond = body_points(
            Vec3::new(0.0, 0.0, 30.0),
            0.0,
            crate::game::player::tuning::STANDING_HEIGHT,
        );
        let eye = eye(Vec3::ZERO, Vec3::Z);
        for point in beyond {
            for triangle in &MIRROR {
                assert_eq!(reflected_path(&room, eye, Vec3::Z, point, triangle), None);
            }
        }
    }
}
