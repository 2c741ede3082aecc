//! Game schedule, fixed step "gameplay": noise, and the wardens who hear it.
//!
//! Per step:
//! 1. `make_noise` (after the player moves): sprinting on the ground (`Player::sprinting`:
//!    the sprint action held, not the body's speed) makes a footfall every
//!    `STRIDE` seconds, heard out to `SPRINT_RADIUS`; landing faster than `LANDING_SPEED`
//!    (a drop of about 0.8 m; a jump on the flat lands softer) is heard out to
//!    `LANDING_RADIUS`. Walking and crouching are quiet. Each noise is kept in `Noises`
//!    for `RING_SECONDS`, the time the HUD shows its ring.
//!    `knock_over` (after it): a standing player whose body walks into a knockable thing
//!    (the level's `knock`) topples it about its base, away from them, over
//!    `TOPPLE_SECONDS`, with a crash heard out to its `noise`; crouched, the player steps
//!    round it.
//! 2. `hear_noises` (after the wardens look): a warden hears a noise made this step when
//!    the noise's level at its ears is over the hearing threshold: its loudness (set so
//!    that in the open it carries its radius, `Noise::loudness_db`) less what the level
//!    takes on the way (`acoustics::hear`, the function the player's own ears use: a
//!    wall's transmission loss, or the way round through an opening). A warden that hears
//!    stops and turns to the place (suspicious), then goes to search it; a searching one
//!    goes there instead; an alert one runs there if it has lost sight of the player.
//!    Hearing is not seeing: it does not count as a time seen.
//!
//! The numbers are the genre's starting points, as the stealth games players love use them.
//! Fair by construction: every noise a warden hears is a ring on the HUD.

use bevy_ecs::prelude::*;
use glam::{Quat, Vec3};

use super::goal::{Outcome, Progress};
use super::nav::NavGrid;
use super::player::Player;
use super::warden::{Warden, WardenState, plan, tuning::NOTICE};
use super::world_query::WorldGeometry;
use super::{SIMULATION_HZ, Transform};

/// Noise, in one place (metres, seconds, m/s).
pub mod tuning {
    /// How far a sprinting footfall carries, and how often one falls.
    pub const SPRINT_RADIUS: f32 = 8.0;
    pub const STRIDE: f32 = 0.35;
    /// How far a hard landing carries, and the fall speed that makes one.
    pub const LANDING_RADIUS: f32 = 12.0;
    pub const LANDING_SPEED: f32 = 4.0;
    /// The quietest level a warden hears, decibels: a noise's loudness at 1 m is this
    /// plus 20 log10 of its radius, so in the open it carries exactly its radius.
    pub const HEARING_THRESHOLD_DB: f32 = 20.0;
    /// Where a warden's ears are above its feet.
    pub const EAR_HEIGHT: f32 = 1.6;
    /// How long the HUD shows a noise's ring.
    pub const RING_SECONDS: f32 = 1.0;
    /// How long a knocked thing takes to fall flat.
    pub const TOPPLE_SECONDS: f32 = 0.4;
}

use tuning::*;

/// A noise the player made.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Noise {
    /// Where (at the feet).
    pub at: Vec3,
    /// How far it carries in the open.
    pub radius: f32,
    /// Seconds since it was made.
    pub age: f32,
}

/// The noises of the last `RING_SECONDS` (the HUD draws them; wardens hear those of age 0).
#[derive(Resource, Clone, Debug, Default, PartialEq)]
pub struct Noises(pub Vec<Noise>);

/// The player's feet, as noise sees them: time to the next sprinting footfall, and how
/// fast the body was falling before this step.
#[derive(Component, Clone, Copy, Debug, Default, PartialEq)]
pub struct Footfalls {
    pub until_next: f32,
    pub falling: f32,
    pub grounded: bool,
}

const STEP: f32 = 1.0 / SIMULATION_HZ as f32;

/// A thing that falls over when walked into (the level's `knock`).
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub struct Knockable {
    pub radius: f32,
    pub noise: f32,
    /// Its rotation as placed.
    pub upright: Quat,
    /// Once knocked: seconds since, and the horizontal axis it falls about.
    pub fallen: Option<(f32, Vec3)>,
}

/// Fixed step: a standing player walking into a knockable thing topples it and makes a
/// noise there; fallen things go on falling until flat (see the module doc).
pub fn knock_over(
    noises: Option<ResMut<Noises>>,
    players: Query<(&Player, &Transform), Without<Knockable>>,
    mut things: Query<(&mut Knockable, &mut Transform)>,
) {
    let Some(mut noises) = noises else { return };
    let player = players.iter().next();
    for (mut thing, mut placed) in &mut things {
        if thing.fallen.is_none()
            && let Some((player, body)) = player
            && !player.crouched
            && !player.noclip
        {
            let away = (placed.translation - body.translation) * Vec3::new(1.0, 0.0, 1.0);
            let reach = thing.radius + super::player::tuning::RADIUS;
            let moving = Vec3::new(player.velocity.x, 0.0, player.velocity.z).length() > 0.1;
            let beside = (placed.translation.y - body.translation.y).abs()
                < super::player::tuning::STANDING_HEIGHT;
            if moving && beside && away.length() < reach {
                let facing = Vec3::new(-player.yaw.sin(), 0.0, -player.yaw.cos());
                let away = away.try_normalize().unwrap_or(facing);
                thing.fallen = Some((0.0, Vec3::Y.cross(away).normalize()));
                noises.0.push(Noise {
                    at: placed.translation,
                    radius: thing.noise,
                    age: 0.0,
                });
            }
        }
        // A thing lying flat is left alone: its transform unchanged, nothing to rebuild.
        if let Some((since, axis)) = &mut thing.fallen
            && *since < TOPPLE_SECONDS
        {
            *since = (*since + STEP).min(TOPPLE_SECONDS);
            // Falling faster as it goes, as a thing tipping over its edge does.
            let share = (*since / TOPPLE_SECONDS).powi(2);
            let angle = share * std::f32::consts::FRAC_PI_2;
            placed.rotation = Quat::from_axis_angle(*axis, angle) * thing.upright;
        }
    }
}

/// Fixed step: the player's sprinting footfalls and hard landings become noises, and old
/// noises fade (see the module doc).
pub fn make_noise(
    noises: Option<ResMut<Noises>>,
    progress: Option<Res<Progress>>,
    mut players: Query<(&Player, &Transform, &mut Footfalls)>,
) {
    let Some(mut noises) = noises else { return };
    for noise in &mut noises.0 {
        noise.age += STEP;
    }
    noises.0.retain(|noise| noise.age < RING_SECONDS);
    if progress.is_some_and(|p| p.outcome != Outcome::Running) {
        return;
    }
    for (player, body, mut feet) in &mut players {
        let landed = player.grounded && !feet.grounded;
        if landed && feet.falling > LANDING_SPEED && !player.noclip {
            noises.0.push(Noise {
                at: body.translation,
                radius: LANDING_RADIUS,
                age: 0.0,
            });
        }
        if player.sprinting && !player.noclip {
            feet.until_next -= STEP;
            if feet.until_next <= 0.0 {
                noises.0.push(Noise {
                    at: body.translation,
                    radius: SPRINT_RADIUS,
                    age: 0.0,
                });
                feet.until_next += STRIDE;
            }
        } else {
            // The first sprinting step is heard at once.
            feet.until_next = 0.0;
        }
        feet.falling = -player.velocity.y;
        feet.grounded = player.grounded;
    }
}

impl Noise {
    /// Its level at 1 m, decibels over the same scale as `HEARING_THRESHOLD_DB`.
    pub fn loudness_db(&self) -> f32 {
        HEARING_THRESHOLD_DB + 20.0 * self.radius.max(1.0).log10()
    }
}

/// Fixed step: wardens within earshot of this step's noises go to look (see the module
/// doc).
pub fn hear_noises(
    noises: Option<Res<Noises>>,
    geometry: Option<Res<WorldGeometry>>,
    grid: Option<Res<NavGrid>>,
    mut wardens: Query<(&mut Warden, &Transform)>,
) {
    let (Some(noises), Some(geometry)) = (noises, geometry) else {
        return;
    };
    for noise in noises.0.iter().filter(|noise| noise.age == 0.0) {
        for (mut warden, placed) in &mut wardens {
            let world = geometry.0.as_ref();
            if over_threshold_db(world, grid.as_deref(), noise, placed.translation).is_some() {
                heard(&mut warden, placed.translation, noise.at, grid.as_deref());
            }
        }
    }
}

/// How far over the hearing threshold a warden standing at `feet` hears `noise`,
/// decibels, or `None` when it does not: the noise's loudness less what the level takes
/// on the way to the warden's ears (`acoustics::hear`). The wardens' hearing and the
/// editor's audibility map ask this one question.
pub fn over_threshold_db(
    world: &dyn super::world_query::WorldQuery,
    grid: Option<&NavGrid>,
    noise: &Noise,
    feet: Vec3,
) -> Option<f32> {
    let ears = feet + Vec3::Y * EAR_HEIGHT;
    let from = noise.at + Vec3::Y * super::acoustics::tuning::SOURCE_LIFT;
    // Nothing in the level carries a sound further than the open air does.
    if from.distance(ears) > noise.radius {
        return None;
    }
    let through = super::acoustics::hear(world, grid, from, ears);
    let over = noise.loudness_db() + through.level_db - HEARING_THRESHOLD_DB;
    (over >= 0.0).then_some(over)
}

/// A warden at `at` heard something at `place`.
fn heard(warden: &mut Warden, at: Vec3, place: Vec3, grid: Option<&NavGrid>) {
    match warden.state {
        WardenState::Patrol | WardenState::Suspicious => {
            warden.state = WardenState::Suspicious;
            warden.timer = 0.0;
            warden.path.clear();
            warden.suspicion = warden.suspicion.max(NOTICE);
            warden.last_seen = Some(place);
            if warden.since_noticed > 1.0 {
                warden.since_noticed = 0.0;
            }
        }
        WardenState::Searching => {
            warden.last_seen = Some(place);
            warden.path = plan(grid, at, place);
            warden.timer = 0.0;
        }
        WardenState::Alert if warden.sighting.visibility <= 0.0 => {
            warden.last_seen = Some(place);
        }
        WardenState::Alert | WardenState::Caught => {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::game::warden::warden_parts;
    use crate::game::world_query::{EmptyWorld, WorldQuery};
    use crate::scene::level::{WardenDef, WardenLamp};

    use crate::game::world_query::fakes::Walled;

    /// A world with the player at the origin moving at `velocity`, a warden standing
    /// `distance` m away along +Z facing away (it cannot see), and `world` as geometry.
    fn world_with(
        velocity: Vec3,
        distance: f32,
        world: Box<dyn WorldQuery>,
    ) -> (World, Entity, Entity) {
        let mut ecs = World::new();
        ecs.insert_resource(WorldGeometry(world));
        ecs.init_resource::<Noises>();
        let body = ecs
            .spawn((
                Player::moving(velocity, true),
                Transform::default(),
                Footfalls {
                    grounded: true,
                    ..Footfalls::default()
                },
            ))
            .id();
        let def = WardenDef {
            route: vec![Vec3::new(0.0, 0.0, distance)],
            speed: 1.2,
            lamp: WardenLamp::default(),
        };
        let (warden, _, _) = warden_parts(&def, 0.0);
        let placed = Transform {
            translation: Vec3::new(0.0, 0.0, distance),
            ..Transform::default()
        };
        let warden = ecs.spawn((warden, placed)).id();
        (ecs, body, warden)
    }

    fn run_steps(world: &mut World, steps: usize) {
        let mut schedule = Schedule::default();
        schedule.add_systems((make_noise, hear_noises).chain());
        for _ in 0..steps {
            schedule.run(world);
        }
    }

    #[test]
    fn sprinting_is_heard_every_stride_and_walking_not_at_all() {
        let (mut world, _, _) = world_with(Vec3::new(0.0, 0.0, -3.5), 30.0, Box::new(EmptyWorld));
        run_steps(&mut world, 60);
        // One second of sprinting: a footfall at once, then every 0.35 s (three in all),
        // each kept a second.
        assert_eq!(world.resource::<Noises>().0.len(), 3);
        assert!(
            world
                .resource::<Noises>()
                .0
                .iter()
                .all(|n| n.radius == SPRINT_RADIUS)
        );
        let (mut world, _, _) = world_with(Vec3::new(0.0, 0.0, -1.4), 30.0, Box::new(EmptyWorld));
        run_steps(&mut world, 60);
        assert!(world.resource::<Noises>().0.is_empty());
    }

    #[test]
    fn a_hard_landing_is_heard_and_a_hop_is_not() {
        for (falling, loud) in [(6.0, true), (3.1, false)] {
            let (mut world, body, _) = world_with(Vec3::ZERO, 30.0, Box::new(EmptyWorld));
            *world.get_mut::<Footfalls>(body).unwrap() = Footfalls {
                until_next: 0.0,
                falling,
                grounded: false,
            };
            run_steps(&mut world, 1);
            let landings = world
                .resource::<Noises>()
                .0
                .iter()
                .filter(|n| n.radius == LANDING_RADIUS)
                .count();
            assert_eq!(landings, usize::from(loud), "falling at {falling} m/s");
        }
    }

    #[test]
    fn a_warden_in_earshot_turns_to_the_noise_and_a_wall_stops_it() {
        let sprint = Vec3::new(0.0, 0.0, -3.5);
        // A noise behind a wall (and no way round: this world has no floor to walk) is
        // not heard where the same noise in the open is.
        for (distance, walled, hears) in [
            (6.0, false, true),
            (7.5, false, true),
            (9.0, false, false),
            (6.0, true, false),
            (3.0, true, false),
        ] {
            let geometry: Box<dyn WorldQuery> = if walled {
                Box::new(Walled)
            } else {
                Box::new(EmptyWorld)
            };
            let (mut world, _, warden) = world_with(sprint, distance, geometry);
            run_steps(&mut world, 1);
            let warden = world.get::<Warden>(warden).unwrap();
            let heard = warden.state == WardenState::Suspicious;
            assert_eq!(heard, hears, "{distance} m, walled {walled}");
            if hears {
                assert_eq!(warden.last_seen, Some(Vec3::ZERO));
                assert!(warden.suspicion >= NOTICE);
            }
        }
    }

    #[test]
    fn walking_into_a_bottle_knocks_it_over_loudly_and_a_crouched_player_steps_round() {
        for (crouched, knocked) in [(false, true), (true, false)] {
            let (mut world, body, warden) =
                world_with(Vec3::new(0.0, 0.0, -1.4), 6.0, Box::new(EmptyWorld));
            world.get_mut::<Player>(body).unwrap().crouched = crouched;
            let bottle = world
                .spawn((
                    Knockable {
                        radius: 0.25,
                        noise: 10.0,
                        upright: Quat::IDENTITY,
                        fallen: None,
                    },
                    Transform {
                        translation: Vec3::new(0.0, 0.0, -0.4),
                        ..Transform::default()
                    },
                ))
                .id();
            let mut schedule = Schedule::default();
            schedule.add_systems((make_noise, knock_over, hear_noises).chain());
            schedule.run(&mut world);
            let heard = world.get::<Warden>(warden).unwrap().state;
            if knocked {
                assert_eq!(world.resource::<Noises>().0.len(), 1);
                assert_eq!(world.resource::<Noises>().0[0].radius, 10.0);
                assert_eq!(heard, WardenState::Suspicious, "6 m off, within 10 m");
            } else {
                assert!(world.resource::<Noises>().0.is_empty());
                assert_eq!(heard, WardenState::Patrol);
            }
            // It falls flat, away from the player (towards -Z), in TOPPLE_SECONDS.
            for _ in 0..(TOPPLE_SECONDS * SIMULATION_HZ as f32) as usize + 2 {
                schedule.run(&mut world);
            }
            let up = world.get::<Transform>(bottle).unwrap().rotation * Vec3::Y;
            if knocked {
                assert!(up.dot(Vec3::NEG_Z) > 0.999, "{up}");
            } else {
                assert_eq!(up, Vec3::Y);
            }
        }
    }
}
