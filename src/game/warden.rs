//! Game schedule, fixed step "gameplay": the wardens. Per step, after the player's light
//! gem is measured:
//! 1. `watch_for_player`: each warden looks (`sight::look`: its cones, rays from its eyes
//!    to the body points, the light gem) and its suspicion moves by
//!    `FILL_RATE` x visibility - `DRAIN` a second: it fills in about half a second close
//!    and lit, in several seconds far and dim, and drains when it sees nothing or too
//!    little to grow (visibility below `DRAIN / FILL_RATE`, which counts as not seeing);
//!    its state follows (below), and a warden reaching the player while alert catches
//!    them;
//! 2. `walk_wardens`: each moves as its state asks, turning at most `TURN_RATE`;
//! 3. `animate_wardens`: each plays the clip its state and motion call for (`walk`,
//!    `idle`, and `alert` once when it notices).
//!
//! States: patrol (walks its route, point after point, round again; a doused lamp it
//! sees is an errand: `lamps::relight_lamps`) -> suspicious
//! (suspicion reached `NOTICE`: stops and turns to where it glimpsed the player) ->
//! searching (`LOOK_TIME` without seeing them: walks to that place, finding its way on
//! the `NavGrid`, and looks around for `SEARCH_TIME`, then walks back to its route) ->
//! alert (suspicion full: chases at `CHASE_SPEED`, slower than a sprint, to where it last
//! saw the player; losing them drains it back to searching) -> caught (within
//! `CATCH_DISTANCE` of the player while alert: the attempt is over). Every time a warden
//! goes from not seeing the player to noticing them counts as one time seen.
//!
//! Each carries its lamp: a real spot light (a child entity with a `PunctualLight`) that
//! moves with it and lights the level, so its pool is what the player sees coming and
//! what raises the light gem. A warden faces its model's +Z, as glTF models do.

use bevy_ecs::prelude::*;
use glam::{Quat, Vec3};

use super::animation::{AnimationLibrary, Animator, BodyClips};
use super::exposure::{Exposure, body_points};
use super::goal::{Outcome, Progress};
use super::nav::NavGrid;
use super::player::Player;
use super::sight::{self, Sighting};
use super::world_query::WorldGeometry;
use super::{PunctualLight, SIMULATION_HZ, Transform};
use crate::profile::{GameplayPhase, StageTimes, since};
use crate::scene::animation::Playback;
use crate::scene::level::{WardenDef, WardenLamp};

/// The wardens' minds and legs, in one place (seconds, metres, 0..1 suspicion; the genre's
/// starting numbers, tuned by playing level 1).
pub mod tuning {
    /// Suspicion gained a second per unit of visibility: at visibility 1 (close, lit,
    /// every point in sight) full in about 0.55 s; at 0.25 (far and dim) in 3.3 s.
    pub const FILL_RATE: f32 = 2.0;
    /// Suspicion lost a second, whatever it sees: a player seen too little to outweigh it
    /// is being forgotten.
    pub const DRAIN: f32 = 0.2;
    /// Suspicion at which a patrolling warden stops to look.
    pub const NOTICE: f32 = 0.25;
    /// How long a suspicious warden stares at nothing before it goes to look.
    pub const LOOK_TIME: f32 = 2.0;
    /// How long a searching warden looks around where it last saw the player.
    pub const SEARCH_TIME: f32 = 12.0;
    /// How far it turns either way while looking around (degrees), and one sweep's time.
    pub const LOOK_AROUND_DEGREES: f32 = 75.0;
    pub const LOOK_AROUND_PERIOD: f32 = 4.0;
    /// Walking speed while searching, and running speed while alert (a sprint is 3.5).
    pub const SEARCH_SPEED: f32 = 1.5;
    pub const CHASE_SPEED: f32 = 3.0;
    /// An alert warden this close (horizontally, with the player's feet within a body's
    /// height of its own) catches the player.
    pub const CATCH_DISTANCE: f32 = 0.9;
    /// How fast a warden turns (radians a second).
    pub const TURN_RATE: f32 = std::f32::consts::PI;
    /// A chase plans its way again when the player has moved this far from its end.
    pub const REPLAN_DISTANCE: f32 = 0.75;
}

pub use tuning::TURN_RATE;
use tuning::*;

/// What a warden is doing.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum WardenState {
    #[default]
    Patrol,
    Suspicious,
    Searching,
    Alert,
    Caught,
}

impl WardenState {
    /// As replays and the HUD name it.
    pub fn name(self) -> &'static str {
        match self {
            WardenState::Patrol => "patrol",
            WardenState::Suspicious => "suspicious",
            WardenState::Searching => "searching",
            WardenState::Alert => "alert",
            WardenState::Caught => "caught",
        }
    }
}

/// A warden (on its level entity's root).
#[derive(Component, Clone, Debug, PartialEq)]
pub struct Warden {
    /// As the level writes it.
    pub def: WardenDef,
    /// The route point it walks to.
    pub next: usize,
    /// Facing, radians about +Y (0 faces +Z).
    pub yaw: f32,
    pub state: WardenState,
    /// 0..1: how sure it is it has seen someone.
    pub suspicion: f32,
    /// What it saw of the player this step.
    pub sighting: Sighting,
    /// Where it last saw the player's feet, or heard them (`noise`): where it searches.
    pub last_seen: Option<Vec3>,
    /// Seconds in this state (suspicious, searching) or since it last saw the player
    /// (alert).
    pub timer: f32,
    /// Seconds since it last noticed the player (its `alert` clip plays then).
    pub since_noticed: f32,
    /// The points it walks through to where it is going (searching, chasing, returning).
    pub path: Vec<Vec3>,
    /// How far it moved this step (metres).
    pub moved: f32,
    /// The yaw it looks around from while searching.
    pub look_from: f32,
    /// A doused lamp it saw and is on its way to relight (`lamps::relight_lamps`).
    pub relight: Option<Entity>,
}

impl Warden {
    /// The way it faces (horizontal, unit).
    pub fn forward(&self) -> Vec3 {
        Vec3::new(self.yaw.sin(), 0.0, self.yaw.cos())
    }
}

/// A warden's lamp (the child entity carrying its light).
#[derive(Component, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct WardenLampLight;

/// The lamp's place relative to the warden's feet: `reach` ahead (+Z) at `height`,
/// shining ahead (a spot light shines down its -Z) and tilted down.
pub fn lamp_transform(lamp: &WardenLamp) -> Transform {
    Transform {
        translation: Vec3::new(0.0, lamp.height, lamp.reach),
        rotation: Quat::from_rotation_y(std::f32::consts::PI)
            * Quat::from_rotation_x(-lamp.tilt_degrees.to_radians()),
        scale: Vec3::ONE,
    }
}

/// The components a warden's root and lamp get at spawn: the warden facing `yaw`, and its
/// lamp's light and local placement.
pub fn warden_parts(def: &WardenDef, yaw: f32) -> (Warden, PunctualLight, Transform) {
    (
        Warden {
            def: def.clone(),
            next: 0,
            yaw,
            state: WardenState::Patrol,
            suspicion: 0.0,
            sighting: Sighting::default(),
            last_seen: None,
            timer: 0.0,
            since_noticed: f32::INFINITY,
            path: Vec::new(),
            moved: 0.0,
            look_from: yaw,
            relight: None,
        },
        PunctualLight(def.lamp.light()),
        lamp_transform(&def.lamp),
    )
}

const STEP: f32 = 1.0 / SIMULATION_HZ as f32;

/// Fixed step: every warden looks, its suspicion and state follow, and an alert one
/// within reach catches the player (see the module doc).
pub fn watch_for_player(
    geometry: Option<Res<WorldGeometry>>,
    grid: Option<Res<NavGrid>>,
    progress: Option<ResMut<Progress>>,
    players: Query<(&Player, &Transform, &Exposure)>,
    mut wardens: Query<(&mut Warden, &Transform), Without<Player>>,
    times: Option<ResMut<StageTimes>>,
) {
    let Some(geometry) = geometry else { return };
    let Some(mut progress) = progress else { return };
    let start = std::time::Instant::now();
    // For the profiler only: nothing in the simulation reads it.
    let _timed = Timed(times, start);
    if progress.outcome != Outcome::Running {
        return;
    }
    let Some((player, body, exposure)) = players.iter().next() else {
        return;
    };
    let feet = body.translation;
    let points = body_points(feet, player.yaw, player.height());
    for (mut warden, placed) in &mut wardens {
        let warden = &mut *warden;
        let at = placed.translation;
        let seen = if player.noclip {
            Sighting::default()
        } else {
            sight::look(
                &*geometry.0,
                sight::eye(at, warden.forward()),
                warden.forward(),
                &points,
                exposure.gem,
            )
        };
        warden.sighting = seen;
        warden.since_noticed += STEP;
        warden.timer += STEP;
        let growth = FILL_RATE * seen.visibility - DRAIN;
        warden.suspicion = (warden.suspicion + growth * STEP).clamp(0.0, 1.0);
        // Seeing is seeing enough to grow more suspicious.
        let sees = growth > 0.0;
        if sees {
            warden.last_seen = Some(feet);
        }
        let before = warden.state;
        warden.state = match before {
            WardenState::Patrol | WardenState::Searching if sees && warden.suspicion >= 1.0 => {
                WardenState::Alert
            }
            WardenState::Patrol | WardenState::Searching if sees && warden.suspicion >= NOTICE => {
                WardenState::Suspicious
            }
            WardenState::Suspicious if warden.suspicion >= 1.0 => WardenState::Alert,
            WardenState::Suspicious if sees => WardenState::Suspicious,
            WardenState::Suspicious if warden.timer >= LOOK_TIME => WardenState::Searching,
            WardenState::Searching if warden.timer >= SEARCH_TIME => WardenState::Patrol,
            WardenState::Alert if !sees && warden.suspicion < 0.5 => WardenState::Searching,
            state => state,
        };
        if warden.state == WardenState::Alert {
            let across = (feet - at) * Vec3::new(1.0, 0.0, 1.0);
            let reached = across.length() <= CATCH_DISTANCE
                && (feet.y - at.y).abs() < super::player::tuning::STANDING_HEIGHT;
            if reached {
                warden.state = WardenState::Caught;
                progress.outcome = Outcome::Caught;
            }
        }
        // Timers count from the moment something new happened.
        if sees && matches!(warden.state, WardenState::Suspicious | WardenState::Alert) {
            warden.timer = 0.0;
        }
        if warden.state != before {
            warden.timer = 0.0;
            // Relighting is a patrol's errand: the player comes first.
            warden.relight = None;
            // The way to where the new state goes: the last place it saw the player, or
            // back to its route; a chase plans as it runs.
            warden.path = match (warden.state, warden.last_seen) {
                (WardenState::Searching, Some(target)) => plan(grid.as_deref(), at, target),
                (WardenState::Patrol, _) => match warden.def.route.get(warden.next) {
                    Some(&home) => plan(grid.as_deref(), at, home),
                    None => Vec::new(),
                },
                _ => Vec::new(),
            };
            warden.look_from = warden.yaw;
            if matches!(before, WardenState::Patrol | WardenState::Searching)
                && matches!(warden.state, WardenState::Suspicious | WardenState::Alert)
            {
                progress.times_seen += 1;
                warden.since_noticed = 0.0;
            }
            if warden.state == WardenState::Patrol {
                warden.suspicion = 0.0;
            }
        }
    }
}

/// Adds the time since its start to the gameplay stage's `Sight` part when dropped (every
/// way out of `watch_for_player`).
struct Timed<'w>(Option<ResMut<'w, StageTimes>>, std::time::Instant);

impl Drop for Timed<'_> {
    fn drop(&mut self) {
        if let Some(times) = &mut self.0 {
            times.add_gameplay(GameplayPhase::Sight, since(self.1));
        }
    }
}

/// Fixed step: every warden moves as its state asks (see the module doc).
pub fn walk_wardens(
    grid: Option<Res<NavGrid>>,
    players: Query<&Transform, With<Player>>,
    mut wardens: Query<(&mut Warden, &mut Transform), Without<Player>>,
) {
    let player = players.iter().next().map(|body| body.translation);
    for (mut warden, mut transform) in &mut wardens {
        let warden = &mut *warden;
        let mut at = transform.translation;
        let start = at;
        match warden.state {
            WardenState::Patrol => {
                if !warden.path.is_empty() {
                    // To a lamp to relight, or back to its route after a search.
                    follow_path(warden, &mut at, warden.def.speed * STEP);
                } else {
                    walk_route(warden, &mut at);
                }
            }
            WardenState::Suspicious => {
                if let Some(target) = warden.last_seen {
                    turn_towards(warden, target - at);
                }
            }
            WardenState::Searching => {
                if !warden.path.is_empty() {
                    follow_path(warden, &mut at, SEARCH_SPEED * STEP);
                    // It looks around for `SEARCH_TIME` from when it gets there.
                    warden.timer = 0.0;
                    warden.look_from = warden.yaw;
                } else {
                    let phase = warden.timer / LOOK_AROUND_PERIOD * std::f32::consts::TAU;
                    let wanted = warden.look_from + LOOK_AROUND_DEGREES.to_radians() * phase.sin();
                    turn_towards(warden, Vec3::new(wanted.sin(), 0.0, wanted.cos()));
                }
            }
            WardenState::Alert => {
                let target = match (warden.sighting.visibility > 0.0, player) {
                    (true, Some(player)) => Some(player),
                    _ => warden.last_seen,
                };
                if let Some(target) = target {
                    let stale = warden
                        .path
                        .last()
                        .is_none_or(|end| end.distance(target) > REPLAN_DISTANCE);
                    if stale && at.distance(target) > CATCH_DISTANCE * 0.5 {
                        warden.path = plan(grid.as_deref(), at, target);
                    }
                    follow_path(warden, &mut at, CHASE_SPEED * STEP);
                    if warden.path.is_empty() {
                        turn_towards(warden, target - at);
                    }
                }
            }
            WardenState::Caught => {
                if let Some(player) = player {
                    turn_towards(warden, player - at);
                }
            }
        }
        warden.moved = at.distance(start);
        transform.set_if_neq(Transform {
            translation: at,
            rotation: Quat::from_rotation_y(warden.yaw),
            scale: transform.scale,
        });
    }
}

/// The way from `from` to `to` on the grid, or straight there without one.
pub fn plan(grid: Option<&NavGrid>, from: Vec3, to: Vec3) -> Vec<Vec3> {
    match grid {
        Some(grid) if grid.walkable_cells() > 0 => grid.path(from, to).unwrap_or_default(),
        _ => vec![to],
    }
}

/// Walks `budget` metres along the warden's route, past as many points as it reaches.
fn walk_route(warden: &mut Warden, at: &mut Vec3) {
    if warden.def.route.is_empty() {
        return;
    }
    let mut budget = warden.def.speed * STEP;
    let mut heading = None;
    for _ in 0..warden.def.route.len() {
        let target = warden.def.route[warden.next];
        let to = target - *at;
        let distance = to.length();
        if distance > 1e-6 {
            heading = Some(to);
        }
        if distance > budget {
            *at += to / distance * budget;
            break;
        }
        *at = target;
        budget -= distance;
        warden.next = (warden.next + 1) % warden.def.route.len();
    }
    if let Some(heading) = heading {
        turn_towards(warden, heading);
    }
}

/// Walks `budget` metres along the warden's path, dropping the points it reaches.
fn follow_path(warden: &mut Warden, at: &mut Vec3, mut budget: f32) {
    while let Some(&target) = warden.path.first() {
        let to = target - *at;
        let distance = to.length();
        if distance > 1e-6 {
            turn_towards(warden, to);
        }
        if distance > budget {
            *at += to / distance * budget;
            return;
        }
        *at = target;
        budget -= distance;
        warden.path.remove(0);
    }
}

/// Turns the warden towards `direction` (its horizontal part), `TURN_RATE` at most.
fn turn_towards(warden: &mut Warden, direction: Vec3) {
    if Vec3::new(direction.x, 0.0, direction.z).length_squared() <= 1e-8 {
        return;
    }
    let wanted = direction.x.atan2(direction.z);
    let turn = wrap_angle(wanted - warden.yaw).clamp(-TURN_RATE * STEP, TURN_RATE * STEP);
    warden.yaw = wrap_angle(warden.yaw + turn);
}

/// Fixed step: each warden plays the clip its state and motion call for: `alert` once
/// when it notices the player, `walk` while it moves (faster for a faster gait), `idle`
/// while it stands.
pub fn animate_wardens(
    library: Option<Res<AnimationLibrary>>,
    mut wardens: Query<(&Warden, &BodyClips, &mut Animator)>,
) {
    let Some(library) = library else { return };
    for (warden, clips, mut animator) in &mut wardens {
        let alerting = clips
            .alert
            .filter(|&clip| warden.since_noticed < library.clips[clip].duration());
        let speed = warden.moved / STEP;
        let (clip, playback, rate) = match alerting {
            Some(clip) => (Some(clip), Playback::Once, 1.0),
            None if speed > 0.05 => (
                clips.walk,
                Playback::Loop,
                (speed / super::player::tuning::WALK).clamp(0.5, 2.5),
            ),
            None => (clips.idle, Playback::Loop, 1.0),
        };
        if let Some(clip) = clip {
            BodyClips::play(&mut animator, clip, playback, rate);
        }
    }
}

/// `angle` in (-pi, pi].
pub fn wrap_angle(angle: f32) -> f32 {
    let tau = std::f32::consts::TAU;
    let wrapped = (angle + std::f32::consts::PI).rem_euclid(tau) - std::f32::consts::PI;
    if wrapped <= -std::f32::consts::PI {
        wrapped + tau
    } else {
        wrapped
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::game::world_query::EmptyWorld;

    /// A world with one warden at the origin facing +Z on a beat, and a player standing at
    /// `feet` whose light gem holds at `gem`; no walls.
    fn world_with(feet: Vec3, gem: f32) -> (World, Schedule, Entity) {
        let mut world = World::new();
        world.insert_resource(WorldGeometry(Box::new(EmptyWorld)));
        world.insert_resource(Progress::default());
        let player = crate::game::Player::moving(Vec3::ZERO, true);
        let exposure = Exposure {
            gem,
            ..Exposure::default()
        };
        world.spawn((
            player,
            exposure,
            Transform {
                translation: feet,
                ..Transform::default()
            },
        ));
        let def = WardenDef {
            route: vec![Vec3::ZERO],
            speed: 1.2,
            lamp: WardenLamp::default(),
        };
        let (warden, _, _) = warden_parts(&def, 0.0);
        let warden = world.spawn((warden, Transform::default())).id();
        let mut schedule = Schedule::default();
        schedule.add_systems((watch_for_player, walk_wardens).chain());
        (world, schedule, warden)
    }

    /// Steps until the warden is in `state`: the seconds it took (None within `limit` s).
    fn seconds_until(
        world: &mut World,
        schedule: &mut Schedule,
        warden: Entity,
        state: WardenState,
        limit: f32,
    ) -> Option<f32> {
        for step in 1..=(limit * SIMULATION_HZ as f32) as usize {
            schedule.run(world);
            if world.get::<Warden>(warden)?.state == state {
                return Some(step as f32 * STEP);
            }
        }
        None
    }

    #[test]
    fn close_and_lit_is_noticed_in_half_a_second_far_and_dim_takes_seconds() {
        let (mut world, mut schedule, warden) = world_with(Vec3::new(0.0, 0.0, 3.0), 1.0);
        let close = seconds_until(&mut world, &mut schedule, warden, WardenState::Alert, 5.0)
            .expect("a lit player 3 m ahead alarms the warden");
        assert!((0.3..=0.7).contains(&close), "{close} s");
        let (mut world, mut schedule, warden) = world_with(Vec3::new(0.0, 0.0, 10.0), 0.4);
        let far = seconds_until(
            &mut world,
            &mut schedule,
            warden,
            WardenState::Suspicious,
            30.0,
        )
        .expect("a dim player 10 m ahead is noticed in the end");
        assert!(far >= 0.6, "noticed after {far} s");
        // Full alert takes several seconds.
        let alert = seconds_until(&mut world, &mut schedule, warden, WardenState::Alert, 30.0)
            .map(|more| far + more)
            .expect("and alarms it in the end");
        assert!(alert >= 3.0, "{alert} s");
        assert_eq!(world.resource::<Progress>().times_seen, 1);
        // Seen so little that the drain outweighs it: never noticed.
        let (mut world, mut schedule, warden) = world_with(Vec3::new(0.0, 0.0, 14.0), 0.25);
        assert_eq!(
            seconds_until(
                &mut world,
                &mut schedule,
                warden,
                WardenState::Suspicious,
                30.0
            ),
            None
        );
    }

    #[test]
    fn a_player_in_the_dark_is_never_seen() {
        let (mut world, mut schedule, warden) = world_with(Vec3::new(0.0, 0.0, 2.0), 0.09);
        assert_eq!(
            seconds_until(
                &mut world,
                &mut schedule,
                warden,
                WardenState::Suspicious,
                20.0
            ),
            None
        );
        assert_eq!(world.get::<Warden>(warden).unwrap().suspicion, 0.0);
    }

    #[test]
    fn a_glimpse_is_searched_for_then_forgotten() {
        let glimpsed = Vec3::new(0.0, 0.0, 6.0);
        let (mut world, mut schedule, warden) = world_with(glimpsed, 1.0);
        seconds_until(
            &mut world,
            &mut schedule,
            warden,
            WardenState::Suspicious,
            2.0,
        )
        .expect("noticed");
        // The player steps into the dark: the warden stares, then goes to look.
        let mut players = world.query_filtered::<&mut Exposure, With<Player>>();
        players.single_mut(&mut world).unwrap().gem = 0.0;
        let looked = seconds_until(
            &mut world,
            &mut schedule,
            warden,
            WardenState::Searching,
            10.0,
        )
        .expect("it goes to search");
        assert!(
            (LOOK_TIME - 0.1..LOOK_TIME + 0.1).contains(&looked),
            "{looked}"
        );
        let back = seconds_until(&mut world, &mut schedule, warden, WardenState::Patrol, 60.0)
            .expect("it gives up and patrols again");
        // It walked to the place (6 m at SEARCH_SPEED), then looked around for SEARCH_TIME.
        let walk = glimpsed.length() / SEARCH_SPEED;
        assert!(back >= SEARCH_TIME + walk - 0.5, "{back} s");
        let state = world.get::<Warden>(warden).unwrap();
        assert_eq!(state.suspicion, 0.0);
        assert_eq!(world.resource::<Progress>().outcome, Outcome::Running);
    }

    #[test]
    fn an_alert_warden_runs_the_player_down() {
        let (mut world, mut schedule, warden) = world_with(Vec3::new(0.0, 0.0, 5.0), 1.0);
        let caught = seconds_until(&mut world, &mut schedule, warden, WardenState::Caught, 10.0)
            .expect("caught");
        // Alarmed in about half a second, then about 4 m at CHASE_SPEED.
        assert!(caught < 0.7 + 4.5 / CHASE_SPEED, "{caught} s");
        assert_eq!(world.resource::<Progress>().outcome, Outcome::Caught);
    }
}
