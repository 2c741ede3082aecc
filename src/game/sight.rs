//! Game schedule, fixed step "gameplay": what a warden sees of the player this step.
//!
//! A warden looks from its eyes along its facing with two cones (GAME.md's numbers from
//! the stealth games players love): a narrow far one (`FAR_HALF_ANGLE` either side, out
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
/// are `points`, lit as the gem says.
pub fn look(
    world: &dyn WorldQuery,
    eye: Vec3,
    forward: Vec3,
    points: &[Vec3; BODY_POINTS.len()],
    gem: f32,
) -> Sighting {
    let middle = points.iter().sum::<Vec3>() / points.len() as f32;
    let distance = middle.distance(eye);
    let mut seen = 0;
    for &point in points {
        let offset = point - eye;
        if !in_view(offset, forward) {
            continue;
        }
        let length = offset.length();
        if length < 1e-4 || world.raycast(eye, offset / length, length).is_none() {
            seen += 1;
        }
    }
    let share = seen as f32 / points.len() as f32;
    Sighting {
        share,
        visibility: share * lit(gem) * falloff(distance),
        distance,
    }
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
}
