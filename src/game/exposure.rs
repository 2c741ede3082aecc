//! Game schedule, fixed step "gameplay": how lit the player is, the light gem.
//!
//! Per step (`measure_exposure`, after the player has moved):
//! 1. the light arriving at eight body points (head, shoulders, hands, hips, feet; lower
//!    when crouched) from every light within reach, each found with shadow rays through
//!    the level as of this step (`WorldQuery::light_arriving`: the renderer's own light
//!    definitions), so a shadow the player can see is a shadow that hides them;
//! 2. each point's light, as luminance E, mapped to 0..1 by one curve,
//!    v = E / (E + E_HALF) (`curve::point_value`);
//! 3. the points combined as the mean of the brighter half (a face in the light counts,
//!    a hand in it alone does not), then smoothed over `curve::SMOOTHING` seconds so it
//!    does not flicker from step to step: the light gem, 0..1. The HUD shows it and the
//!    wardens read it, nothing else.

use bevy_ecs::prelude::*;
use glam::{Quat, Vec3};

use super::player::tuning::STANDING_HEIGHT;
use super::world_query::{WorldGeometry, WorldQuery};
use super::{Player, SIMULATION_HZ, Transform};
use crate::profile::{GameplayPhase, StageTimes, since};
use crate::scene::model::luminance;

/// The one curve from light to visibility, and its smoothing.
pub mod curve {
    /// The light (luminance of the arriving irradiance, W/m^2) at which a body point reads
    /// as half seen: a lamp's pool (a few W/m^2 and more) reads as seen, a night sky
    /// (0.1) as hidden.
    pub const E_HALF: f32 = 1.0;
    /// Time constant of the gem's smoothing, in seconds.
    pub const SMOOTHING: f32 = 0.1;
    /// Steps the HUD shows the gem in: few enough to read at a glance (Splinter Cell's
    /// meter has 3-5; the exact value is on the F3 overlay).
    pub const GEM_STEPS: usize = 5;
    /// Below this the gem lights no step: the player is hidden, and no warden sees them
    /// (`sight::lit`).
    pub const HIDDEN: f32 = 0.5 / GEM_STEPS as f32;

    /// How many of the HUD's `GEM_STEPS` a gem of `value` lights (the nearest step).
    pub fn gem_cells(value: f32) -> usize {
        (value.clamp(0.0, 1.0) * GEM_STEPS as f32).round() as usize
    }

    /// A body point's visibility, 0..1, from the light arriving there.
    pub fn point_value(light: f32) -> f32 {
        let light = light.max(0.0);
        light / (light + E_HALF)
    }

    /// The gem's target from the points' values: the mean of the brighter half.
    pub fn combine(values: &[f32]) -> f32 {
        let mut sorted = values.to_vec();
        sorted.sort_by(|a, b| b.total_cmp(a));
        let half = sorted.len().div_ceil(2).max(1);
        sorted[..half].iter().sum::<f32>() / half as f32
    }
}

/// Where the body points are on a standing body, relative to the feet (x right, y up, z
/// back, metres): head, shoulders, hands, hips, feet.
pub const BODY_POINTS: [(&str, Vec3); 8] = [
    ("head", Vec3::new(0.0, 1.65, 0.0)),
    ("left shoulder", Vec3::new(-0.2, 1.45, 0.0)),
    ("right shoulder", Vec3::new(0.2, 1.45, 0.0)),
    ("left hand", Vec3::new(-0.35, 0.95, -0.1)),
    ("right hand", Vec3::new(0.35, 0.95, -0.1)),
    ("left hip", Vec3::new(-0.12, 0.95, 0.0)),
    ("right hip", Vec3::new(0.12, 0.95, 0.0)),
    ("feet", Vec3::new(0.0, 0.1, 0.0)),
];

/// The player's exposure this step.
#[derive(Component, Clone, Debug, Default, PartialEq)]
pub struct Exposure {
    /// Each body point's light (luminance of the arriving irradiance), in `BODY_POINTS`
    /// order.
    pub light: [f32; BODY_POINTS.len()],
    /// Each body point's visibility, 0..1 (`curve::point_value`).
    pub values: [f32; BODY_POINTS.len()],
    /// The light gem: the points combined and smoothed, 0..1.
    pub gem: f32,
}

/// The world positions of the body points of a player standing at `feet`, facing `yaw`,
/// `height` tall (crouching lowers them in proportion).
pub fn body_points(feet: Vec3, yaw: f32, height: f32) -> [Vec3; BODY_POINTS.len()] {
    let facing = Quat::from_rotation_y(yaw);
    let squash = Vec3::new(1.0, height / STANDING_HEIGHT, 1.0);
    BODY_POINTS.map(|(_, offset)| feet + facing * (offset * squash))
}

/// Steps 1 and 2 of the module doc at `points`: each point's light and value (into
/// `light` and `values`), and their combination, the gem's target (what it settles at).
pub fn measure_points(
    world: &dyn WorldQuery,
    points: &[Vec3; BODY_POINTS.len()],
    light: &mut [f32; BODY_POINTS.len()],
    values: &mut [f32; BODY_POINTS.len()],
) -> f32 {
    for (index, point) in points.iter().enumerate() {
        light[index] = luminance(world.light_arriving(*point));
        values[index] = curve::point_value(light[index]);
    }
    curve::combine(values)
}

/// The gem a body `height` tall standing at `feet` settles at (the smoothing's end).
pub fn settled_gem(world: &dyn WorldQuery, feet: Vec3, height: f32) -> f32 {
    let points = body_points(feet, 0.0, height);
    let mut light = [0.0; BODY_POINTS.len()];
    let mut values = [0.0; BODY_POINTS.len()];
    measure_points(world, &points, &mut light, &mut values)
}

/// Fixed step: the player's exposure (see the module doc).
pub fn measure_exposure(
    geometry: Option<Res<WorldGeometry>>,
    mut players: Query<(&Player, &Transform, &mut Exposure)>,
    times: Option<ResMut<StageTimes>>,
) {
    let Some(geometry) = geometry else { return };
    let start = std::time::Instant::now();
    let smoothing = 1.0 - (-(1.0 / SIMULATION_HZ as f32) / curve::SMOOTHING).exp();
    for (player, transform, mut exposure) in &mut players {
        let points = body_points(transform.translation, player.yaw, player.height());
        let exposure = &mut *exposure;
        let target = measure_points(
            &*geometry.0,
            &points,
            &mut exposure.light,
            &mut exposure.values,
        );
        exposure.gem += (target - exposure.gem) * smoothing;
    }
    // For the profiler only: nothing in the simulation reads it.
    if let Some(mut times) = times {
        times.add_gameplay(GameplayPhase::Exposure, since(start));
    }
}
