//! Game schedule, fixed step "gameplay": the player's body. Per step (`move_player`):
//! 1. look: mouse look turns the body (yaw) and the eye (pitch, within 89 degrees);
//! 2. stance: crouch while the crouch action is held, stand again when there is head room;
//! 3. walk: the wished direction at walking, sprinting or crouching speed (the genre's
//!    numbers: 1.4, 3.5 and 0.9 m/s), gravity and jumps (0.5 m high) on the vertical;
//! 4. move the capsule (radius 0.3 m, 1.8 m tall, 1.1 m crouched) through the level by
//!    collide and slide: in pieces shorter than half its radius (nothing is passed
//!    through between two tests at any speed), each followed by pushing the capsule's
//!    spheres out of every surface they reach, deepest first, and cancelling the velocity
//!    into it; a blocked walk is tried again up a 0.3 m step and down onto what is there
//!    (stairs, kerbs), and a grounded body follows the floor down slopes and steps;
//! 5. the eye follows the stance smoothly.
//!
//! The level is asked through `WorldGeometry` (the geometry as of this step), so the same
//! inputs move the player the same way on every machine and frame rate. With noclip on the
//! body flies where it looks and passes through everything.

use bevy_ecs::prelude::*;
use glam::{EulerRot, Quat, Vec3};

use super::input::FLY_SPEED;
use super::world_query::{Contact, WorldGeometry, WorldQuery};
use super::{
    Action, GlobalTransform, Input, PlayerStart, PreviousGlobalTransform, SIMULATION_HZ, Transform,
    ViewCamera,
};

/// The body's tuning, in one place (metres, seconds; the genre's starting numbers).
pub mod tuning {
    /// Walking speed (quiet).
    pub const WALK: f32 = 1.4;
    /// Sprinting speed (loud).
    pub const SPRINT: f32 = 3.5;
    /// Crouching speed (quieter).
    pub const CROUCH: f32 = 0.9;
    /// Capsule radius.
    pub const RADIUS: f32 = 0.3;
    /// Capsule height standing and crouched.
    pub const STANDING_HEIGHT: f32 = 1.8;
    pub const CROUCHED_HEIGHT: f32 = 1.1;
    /// Eye height crouched, for a standing eye height of 1.6 (scaled with it).
    pub const CROUCHED_EYE_RATIO: f32 = 1.0 / 1.6;
    /// The highest ledge a walk steps up onto.
    pub const STEP_HEIGHT: f32 = 0.3;
    /// Jump apex height.
    pub const JUMP_HEIGHT: f32 = 0.5;
    pub const GRAVITY: f32 = 9.81;
    /// Falling never gets faster than this (air resistance, and a bound on each step).
    pub const MAX_FALL_SPEED: f32 = 30.0;
    /// Surfaces whose normal is within this cosine of straight up are floors.
    pub const FLOOR_COSINE: f32 = 0.7;
    /// How fast the eye moves between standing and crouched heights (m/s).
    pub const EYE_SPEED: f32 = 4.0;
}

use tuning::*;

/// The player's body: where it stands is its `Transform` (the feet; yaw only).
#[derive(Component, Clone, Debug, PartialEq)]
pub struct Player {
    pub velocity: Vec3,
    /// Standing on a floor after the last step.
    pub grounded: bool,
    pub crouched: bool,
    /// Collision off: the body flies.
    pub noclip: bool,
    /// Running on the ground this step (the sprint action held, standing, moving): what
    /// makes a sprinting footfall's noise. The body's speed does not say it: a stumble
    /// down a stair edge turns falling into speed across the ground past a walk's.
    pub sprinting: bool,
    /// View angles in radians: yaw about +Y (0 looks down -Z), pitch up from the horizon.
    pub yaw: f32,
    pub pitch: f32,
    /// Eye height standing (the level's `player_spawn.eye_height`).
    pub eye_height: f32,
    /// The eye's height now (moves towards the stance's).
    pub eye: f32,
}

impl Player {
    /// A player standing (eye at 1.6 m) and moving at `velocity`, for unit tests: running
    /// (the sprint held) when that is faster than a walk.
    #[cfg(test)]
    pub(crate) fn moving(velocity: Vec3, grounded: bool) -> Player {
        Player {
            velocity,
            grounded,
            crouched: false,
            noclip: false,
            sprinting: grounded && Vec3::new(velocity.x, 0.0, velocity.z).length() > WALK + 0.1,
            yaw: 0.0,
            pitch: 0.0,
            eye_height: 1.6,
            eye: 1.6,
        }
    }

    pub fn height(&self) -> f32 {
        if self.crouched {
            CROUCHED_HEIGHT
        } else {
            STANDING_HEIGHT
        }
    }

    /// The eye height the stance asks for.
    pub fn stance_eye(&self) -> f32 {
        if self.crouched {
            self.eye_height * CROUCHED_EYE_RATIO
        } else {
            self.eye_height
        }
    }
}

/// The player's eye: the camera entity under the body.
#[derive(Component, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PlayerEye;

/// The view the frame renders from when several entities have a `ViewCamera`.
#[derive(Component, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ActiveCamera;

/// Puts the player at the level's `PlayerStart` (feet there, facing its yaw) with its eye
/// as the active view. None when the level has no player start.
pub fn spawn_player(world: &mut World) -> Option<Entity> {
    let mut starts = world.query::<(&PlayerStart, &Transform)>();
    let (start, placed) = starts
        .iter(world)
        .next()
        .map(|(start, transform)| (start.0.clone(), *transform))?;
    let (yaw, _, _) = placed.rotation.to_euler(EulerRot::YXZ);
    let yfov = {
        let mut views = world.query::<&ViewCamera>();
        views
            .iter(world)
            .next()
            .map_or(70f32.to_radians(), |v| v.yfov)
    };
    let body = Transform {
        translation: placed.translation,
        rotation: Quat::from_rotation_y(yaw),
        scale: Vec3::ONE,
    };
    let player = world
        .spawn((
            Name::new("player"),
            Player {
                velocity: Vec3::ZERO,
                grounded: false,
                crouched: false,
                noclip: false,
                sprinting: false,
                yaw,
                pitch: 0.0,
                eye_height: start.eye_height,
                eye: start.eye_height,
            },
            super::Exposure::default(),
            super::Footfalls::default(),
            body,
            GlobalTransform(body.affine()),
            PreviousGlobalTransform(body.affine()),
        ))
        .id();
    let eye = Transform {
        translation: Vec3::Y * start.eye_height,
        ..Transform::default()
    };
    let world_eye = body.affine() * eye.affine();
    world.spawn((
        Name::new("player eye"),
        PlayerEye,
        ActiveCamera,
        ViewCamera { yfov, znear: 0.05 },
        eye,
        GlobalTransform(world_eye),
        PreviousGlobalTransform(world_eye),
        ChildOf(player),
    ));
    if let Some(body) = &start.body {
        spawn_body(world, player, body);
    }
    world.init_resource::<WorldGeometry>();
    world.init_resource::<super::Noises>();
    Some(player)
}

/// The player's own body: the root of its model, a child of the `Player`. The player's
/// camera rays pass through it; it casts shadows and shows in reflections (extract gives
/// its meshes the shadow and bounce masks only).
#[derive(Component, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PlayerBody;

/// Puts the body's model under `player`, facing where the player looks (the model faces
/// +Z, the view -Z), playing its idle clip. The level loader has already imported the
/// asset, so this does not fail for a level that loaded; a body that cannot be had is left
/// out.
fn spawn_body(world: &mut World, player: Entity, body: &crate::scene::level::InstanceDef) {
    let Ok(asset) = world
        .get_resource_or_init::<super::Assets>()
        .0
        .load(&body.asset)
    else {
        return;
    };
    let mut def = crate::scene::level::EntityDef::named("player body");
    def.instance = Some(body.clone());
    // Not a level entity: it belongs to the player, and a saved level does not hold it.
    let spawned = super::spawn_entity(
        world,
        &def,
        super::LevelEntity(usize::MAX),
        Some(asset.clone()),
    );
    let local = Transform {
        rotation: Quat::from_rotation_y(std::f32::consts::PI),
        ..Transform::default()
    };
    let placed = world
        .get::<GlobalTransform>(player)
        .map_or(local.affine(), |parent| parent.0 * local.affine());
    let clips = super::BodyClips::of(
        &mut world.get_resource_or_init::<super::AnimationLibrary>(),
        &asset,
    );
    let mut root = world.entity_mut(spawned.root);
    root.remove::<super::LevelEntity>().insert((
        PlayerBody,
        local,
        GlobalTransform(placed),
        PreviousGlobalTransform(placed),
        ChildOf(player),
        clips,
    ));
    if let Some(animator) = clips.idle_animator(&spawned.nodes) {
        root.insert(animator);
    }
}

/// Fixed step, animation: the player's body walks while the player moves (at the pace of
/// the movement), idles while they stand, and is squashed to the crouched height.
pub fn animate_player_body(
    players: Query<&Player>,
    mut bodies: Query<
        (
            &ChildOf,
            &mut Transform,
            &super::BodyClips,
            Option<&mut super::Animator>,
        ),
        With<PlayerBody>,
    >,
) {
    for (parent, mut transform, clips, animator) in &mut bodies {
        let Ok(player) = players.get(parent.parent()) else {
            continue;
        };
        let squash = player.height() / STANDING_HEIGHT;
        if transform.scale.y != squash {
            transform.scale.y = squash;
        }
        let Some(mut animator) = animator else {
            continue;
        };
        let speed = Vec3::new(player.velocity.x, 0.0, player.velocity.z).length();
        let playback = crate::scene::animation::Playback::Loop;
        match (speed > 0.05, clips.walk, clips.idle) {
            (true, Some(walk), _) => super::BodyClips::play(
                &mut animator,
                walk,
                playback,
                (speed / WALK).clamp(0.5, 2.5),
            ),
            (false, _, Some(idle)) => super::BodyClips::play(&mut animator, idle, playback, 1.0),
            _ => {}
        }
    }
}

/// Fixed step: the player looks, walks, jumps, crouches and collides (see the module doc).
pub fn move_player(
    mut input: ResMut<Input>,
    geometry: Option<Res<WorldGeometry>>,
    mut bodies: Query<(&mut Player, &mut Transform, &Children), Without<PlayerEye>>,
    mut eyes: Query<&mut Transform, With<PlayerEye>>,
    mut contacts: Local<Vec<Contact>>,
    progress: Option<ResMut<super::Progress>>,
) {
    let dt = 1.0 / SIMULATION_HZ as f32;
    let look = std::mem::take(&mut input.look);
    let pressed = std::mem::take(&mut input.pressed);
    // Once the attempt is over, the body stands still.
    let mut progress = progress;
    if progress
        .as_ref()
        .is_some_and(|p| p.outcome != super::Outcome::Running)
    {
        return;
    }
    let empty = super::world_query::EmptyWorld;
    let world: &dyn WorldQuery = geometry.as_ref().map_or(&empty, |g| g.0.as_ref());
    for (mut player, mut transform, children) in &mut bodies {
        let player = &mut *player;
        // 1. Look. Rule: the view angles stay finite whatever the input says (a corrupt
        // recording's turn of -2.4e57 rad became -inf and sent the eye's rays nowhere;
        // found by fuzzing): a turn that would leave them infinite is no turn.
        let limit = 89f32.to_radians();
        let (yaw, pitch) = (player.yaw - look.x, player.pitch + look.y);
        if yaw.is_finite() && pitch.is_finite() {
            player.yaw = yaw;
            player.pitch = pitch.clamp(-limit, limit);
        }
        if pressed.contains(&Action::Noclip) {
            player.noclip = !player.noclip;
            player.velocity = Vec3::ZERO;
            if player.noclip
                && let Some(progress) = progress.as_mut()
            {
                progress.noclip_used = true;
            }
        }
        let facing = Quat::from_rotation_y(player.yaw);
        let mut feet = transform.translation;
        let held = |action| input.held.contains(&action);
        let mut wish = Vec3::ZERO;
        for (action, direction) in [
            (Action::MoveForward, Vec3::NEG_Z),
            (Action::MoveBack, Vec3::Z),
            (Action::MoveLeft, Vec3::NEG_X),
            (Action::MoveRight, Vec3::X),
        ] {
            if held(action) {
                wish += direction;
            }
        }
        if player.noclip {
            player.sprinting = false;
            let view = facing * Quat::from_rotation_x(player.pitch);
            let mut motion = view * wish;
            if held(Action::MoveUp) {
                motion += Vec3::Y;
            }
            if held(Action::MoveDown) {
                motion -= Vec3::Y;
            }
            feet += motion.normalize_or_zero() * FLY_SPEED * dt;
        } else {
            // 2. Stance.
            let wants_crouch = held(Action::MoveDown);
            if wants_crouch {
                player.crouched = true;
            } else if player.crouched && head_room(world, feet, &mut contacts) {
                player.crouched = false;
            }
            // 3. Walk, jump, fall.
            let speed = if player.crouched {
                CROUCH
            } else if held(Action::Sprint) {
                SPRINT
            } else {
                WALK
            };
            let horizontal = facing * wish.normalize_or_zero() * speed;
            player.velocity.x = horizontal.x;
            player.velocity.z = horizontal.z;
            if player.grounded && pressed.contains(&Action::MoveUp) && !player.crouched {
                player.velocity.y = (2.0 * GRAVITY * JUMP_HEIGHT).sqrt();
                player.grounded = false;
            }
            if !player.grounded {
                player.velocity.y = (player.velocity.y - GRAVITY * dt).max(-MAX_FALL_SPEED);
            }
            // 4. Move through the level.
            let body = Body {
                world,
                height: player.height(),
                contacts: &mut contacts,
            };
            (feet, player.velocity, player.grounded) =
                body.step(feet, player.velocity, player.grounded, dt);
            player.sprinting = speed == SPRINT && wish != Vec3::ZERO && player.grounded;
        }
        transform.set_if_neq(Transform {
            translation: feet,
            rotation: facing,
            scale: Vec3::ONE,
        });
        // 5. The eye.
        let target = player.stance_eye();
        let change = (target - player.eye).clamp(-EYE_SPEED * dt, EYE_SPEED * dt);
        player.eye += change;
        for &child in children {
            if let Ok(mut eye) = eyes.get_mut(child) {
                eye.set_if_neq(Transform {
                    translation: Vec3::Y * player.eye,
                    rotation: Quat::from_rotation_x(player.pitch),
                    scale: Vec3::ONE,
                });
            }
        }
    }
}

/// Can a crouched body at `feet` stand up (nothing in the standing capsule's upper part)?
fn head_room(world: &dyn WorldQuery, feet: Vec3, contacts: &mut Vec<Contact>) -> bool {
    sphere_heights(STANDING_HEIGHT)
        .filter(|&height| height > CROUCHED_HEIGHT - RADIUS)
        .all(|height| {
            contacts.clear();
            world.sphere_contacts(feet + Vec3::Y * height, RADIUS - 0.01, contacts);
            contacts.is_empty()
        })
}

/// The centres' heights above the feet of the spheres that make a capsule `height` tall:
/// from the bottom sphere to the top one, at most a radius apart.
fn sphere_heights(height: f32) -> impl Iterator<Item = f32> {
    let span = (height - 2.0 * RADIUS).max(0.0);
    let gaps = (span / RADIUS).ceil().max(1.0) as usize;
    (0..=gaps).map(move |i| RADIUS + span * i as f32 / gaps as f32)
}

/// The capsule moving through the level.
struct Body<'a> {
    world: &'a dyn WorldQuery,
    height: f32,
    contacts: &'a mut Vec<Contact>,
}

/// The longest piece a move is cut into: half the radius, so a surface cannot be passed
/// between two overlap tests.
const PIECE: f32 = RADIUS * 0.5;

impl Body<'_> {
    /// One step of `dt` with `velocity` from `feet`: returns the new feet, velocity and
    /// whether the body stands on a floor.
    fn step(mut self, start: Vec3, velocity: Vec3, grounded: bool, dt: f32) -> (Vec3, Vec3, bool) {
        let walk = Vec3::new(velocity.x, 0.0, velocity.z) * dt;
        // Horizontal: straight, and (on the ground) up a step, across and down, when that
        // gets further (a kerb or a stair the straight move stopped at).
        let mut velocity = velocity;
        let (mut feet, mut floor) = self.travel(start, walk, &mut velocity);
        let blocked = (feet - start).length() < walk.length() * 0.99;
        if grounded && blocked {
            let mut stepping = velocity;
            if let Some(stepped) = self.step_up(start, walk, &mut stepping) {
                let progress =
                    |end: Vec3| Vec3::new(end.x - start.x, 0.0, end.z - start.z).length();
                if progress(stepped) > progress(feet) + 1e-4 {
                    feet = stepped;
                    velocity = stepping;
                    floor = true;
                }
            }
        }
        // Vertical: jump or fall; on the ground, keep to the floor when walking down.
        let rise = Vec3::Y * velocity.y * dt;
        let (moved, landed) = self.travel(feet, rise, &mut velocity);
        feet = moved;
        floor |= landed;
        if grounded && velocity.y <= 0.0 && !floor {
            let (snapped, found) = self.probe_down(feet, STEP_HEIGHT + 0.05);
            feet = snapped;
            floor = found;
        }
        if floor && velocity.y < 0.0 {
            velocity.y = 0.0;
        }
        (feet, velocity, floor && velocity.y <= 0.0)
    }

    /// The horizontal move `walk` from `start` made up a step and down onto a floor: where
    /// it ends, if it ends on one.
    fn step_up(&mut self, start: Vec3, walk: Vec3, velocity: &mut Vec3) -> Option<Vec3> {
        let mut rising = Vec3::ZERO;
        let (raised, _) = self.travel(start, Vec3::Y * STEP_HEIGHT, &mut rising);
        let climbed = raised.y - start.y;
        if climbed <= 1e-4 {
            return None;
        }
        let (across, _) = self.travel(raised, walk, velocity);
        let (down, found) = self.probe_down(across, climbed + 0.05);
        found.then_some(down)
    }

    /// Moves down by at most `depth` until the body stands on a floor: the feet there,
    /// and whether a floor was found (else the feet as they were).
    fn probe_down(&mut self, feet: Vec3, depth: f32) -> (Vec3, bool) {
        let mut velocity = Vec3::NEG_Y;
        let (moved, floor) = self.travel(feet, Vec3::NEG_Y * depth, &mut velocity);
        if floor { (moved, true) } else { (feet, false) }
    }

    /// Moves the feet by `motion` in pieces, resolving contacts after each: the feet it
    /// ends at and whether a floor held it up. Velocity into surfaces is cancelled.
    fn travel(&mut self, feet: Vec3, motion: Vec3, velocity: &mut Vec3) -> (Vec3, bool) {
        let pieces = (motion.length() / PIECE).ceil().max(1.0) as usize;
        let piece = motion / pieces as f32;
        let mut feet = feet;
        let mut floor = false;
        for _ in 0..pieces {
            feet += piece;
            floor |= self.resolve(&mut feet, velocity);
        }
        (feet, floor)
    }

    /// Pushes the capsule out of what it overlaps, deepest contact first, a few times over;
    /// true when a floor pushed it up.
    fn resolve(&mut self, feet: &mut Vec3, velocity: &mut Vec3) -> bool {
        let mut floor = false;
        for _ in 0..8 {
            let mut deepest: Option<(f32, Vec3)> = None;
            for height in sphere_heights(self.height) {
                self.contacts.clear();
                self.world
                    .sphere_contacts(*feet + Vec3::Y * height, RADIUS, self.contacts);
                for contact in self.contacts.iter() {
                    let depth = RADIUS - contact.distance;
                    let deeper = deepest.is_none_or(|(d, n)| {
                        depth > d || (depth == d && contact.normal.to_array() < n.to_array())
                    });
                    if depth > 1e-5 && deeper {
                        deepest = Some((depth, contact.normal));
                    }
                }
            }
            let Some((depth, normal)) = deepest else {
                break;
            };
            if normal.y > FLOOR_COSINE {
                // Floors hold the body up: out straight up, so it does not slide down slopes.
                *feet += Vec3::Y * (depth / normal.y);
                floor = true;
            } else {
                *feet += normal * depth;
            }
            let into = velocity.dot(normal);
            if into < 0.0 {
                *velocity -= normal * into;
            }
        }
        floor
    }
}
