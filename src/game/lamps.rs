//! Game schedule, fixed step "gameplay": light as a verb. Before the player moves
//! (`douse_lamps`), the interact action (E) douses the level lamp the player looks at, or
//! relights a doused one: the lamp within `REACH` of the eye whose direction lies closest
//! to the view, within `AIM_DEGREES` of it, with nothing between (a ray through the level
//! as of this step). A doused lamp is a `SwitchedOff` lamp: its light leaves the renderer's
//! light set, the light gem and the wardens' sight with it. Wardens' own lamps are theirs.
//!
//! After the wardens look (`relight_lamps`): a patrolling warden that sees a doused lamp
//! (inside its sight cones, nothing between its eyes and the lamp) walks to it on the
//! navigation grid and, within `RELIGHT_REACH` of it, lights it again, then walks back to
//! its route. A warden that notices the player drops the errand.
//!
//! Last in the step (`switch_fixtures`), a lamp's fixture (`EntityDef::fixture`, the
//! bracket or hanging lamp it shines from) is switched with it, so its glass glows only
//! while its light is lit.

use bevy_ecs::prelude::*;
use glam::{Quat, Vec3};

use super::nav::NavGrid;
use super::sight;
use super::warden::{Warden, WardenState, plan};
use super::world_query::{WorldGeometry, WorldQuery};
use super::{
    Action, AssetInstance, GlobalTransform, Input, LevelEntity, Player, PlayerEye, PunctualLight,
    SwitchedOff, Transform,
};

/// How close (across the ground) a warden gets to a lamp to light it again.
pub const RELIGHT_REACH: f32 = 1.0;

/// How far from the eye a lamp can be reached (metres), and how far off the view it may
/// lie (degrees).
pub const REACH: f32 = 2.5;
pub const AIM_DEGREES: f32 = 15.0;

/// Fixed step: the interact action douses or relights the lamp aimed at (see the module
/// doc).
pub fn douse_lamps(
    mut commands: Commands,
    input: Res<Input>,
    geometry: Option<Res<WorldGeometry>>,
    players: Query<(&Player, &Children)>,
    eyes: Query<&GlobalTransform, With<PlayerEye>>,
    lamps: Query<
        (Entity, &GlobalTransform, Has<SwitchedOff>),
        (With<PunctualLight>, With<LevelEntity>),
    >,
) {
    if !input.pressed.contains(&Action::Interact) {
        return;
    }
    let Some(geometry) = geometry else { return };
    for (player, children) in &players {
        let Some(eye) = children.iter().find_map(|child| eyes.get(child).ok()) else {
            continue;
        };
        let candidates = lamps
            .iter()
            .map(|(lamp, placed, doused)| (lamp, placed.0.translation.into(), doused));
        if let Some((lamp, doused)) = aimed_lamp(
            &*geometry.0,
            eye.0.translation.into(),
            view(player),
            candidates,
        ) {
            if doused {
                commands.entity(lamp).remove::<SwitchedOff>();
            } else {
                commands.entity(lamp).insert(SwitchedOff);
            }
        }
    }
}

/// The level entity, by name, whose instance a level lamp shines from
/// (`EntityDef::fixture`): it is switched off and on with the lamp, so its glow goes dark
/// with the light. Held by name, as the level writes it, so a fixture respawned by the
/// editor is found again.
#[derive(Component, Clone, Debug, PartialEq, Eq)]
pub struct LampFixture(pub String);

/// A level instance as `switch_fixtures` reads it: its name and its switch.
type FixtureData<'a> = (Entity, &'a Name, Has<SwitchedOff>);

/// Fixed step, after the lamps were doused and relit: each fixture takes its lamp's
/// switch, so the renderer draws its glass dark exactly while the light is out.
pub fn switch_fixtures(
    mut commands: Commands,
    lamps: Query<(&LampFixture, Has<SwitchedOff>), With<PunctualLight>>,
    fixtures: Query<FixtureData, (With<LevelEntity>, With<AssetInstance>)>,
) {
    // A few lamps, each looked up among the level's instances by name: a few microseconds
    // a step, and nothing to keep in step with spawns and renames.
    for (LampFixture(name), doused) in &lamps {
        let Some((fixture, _, dark)) = fixtures.iter().find(|(_, n, _)| n.as_str() == name) else {
            continue;
        };
        if dark != doused {
            if doused {
                commands.entity(fixture).insert(SwitchedOff);
            } else {
                commands.entity(fixture).remove::<SwitchedOff>();
            }
        }
    }
}

/// Where `player` looks (unit).
pub fn view(player: &Player) -> Vec3 {
    Quat::from_rotation_y(player.yaw) * Quat::from_rotation_x(player.pitch) * Vec3::NEG_Z
}

/// Of `lamps` (entity, position, doused), the one an eye at `eye` looking along `view`
/// reaches (see the module doc), and whether it is doused. The HUD asks the same question
/// to show the prompt.
pub fn aimed_lamp(
    world: &dyn WorldQuery,
    eye: Vec3,
    view: Vec3,
    lamps: impl Iterator<Item = (Entity, Vec3, bool)>,
) -> Option<(Entity, bool)> {
    lamps
        .filter_map(|(lamp, at, doused)| {
            let to = at - eye;
            let distance = to.length();
            let cosine = to.dot(view) / distance.max(1e-6);
            let in_reach = distance <= REACH && cosine >= AIM_DEGREES.to_radians().cos();
            let clear = in_reach
                && world
                    .raycast(eye, to / distance, (distance - 0.05).max(0.0))
                    .is_none();
            clear.then_some((cosine, lamp, doused))
        })
        .max_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, lamp, doused)| (lamp, doused))
}

/// Fixed step: patrolling wardens go to the doused lamps they see and light them again
/// (see the module doc).
pub fn relight_lamps(
    mut commands: Commands,
    geometry: Option<Res<WorldGeometry>>,
    grid: Option<Res<NavGrid>>,
    mut wardens: Query<(&mut Warden, &Transform)>,
    doused: Query<
        (Entity, &GlobalTransform),
        (With<SwitchedOff>, With<PunctualLight>, With<LevelEntity>),
    >,
) {
    let Some(geometry) = geometry else { return };
    for (mut warden, placed) in &mut wardens {
        let warden = &mut *warden;
        if warden.state != WardenState::Patrol {
            continue;
        }
        let at = placed.translation;
        match warden.relight {
            Some(lamp) => {
                let Ok((_, lamp_at)) = doused.get(lamp) else {
                    // Lit again (by the player): back to the route.
                    warden.relight = None;
                    warden.path = home(warden, at, grid.as_deref());
                    continue;
                };
                let lamp_at = Vec3::from(lamp_at.0.translation);
                let across = glam::Vec2::new(lamp_at.x - at.x, lamp_at.z - at.z).length();
                if across <= RELIGHT_REACH {
                    commands.entity(lamp).remove::<SwitchedOff>();
                } else if !warden.path.is_empty() {
                    continue; // still on its way
                }
                // Lit, or no way leads within reach of it: back to the route.
                warden.relight = None;
                warden.path = home(warden, at, grid.as_deref());
            }
            None => {
                let eye = sight::eye(at, warden.forward());
                let seen = doused.iter().find(|(_, lamp_at)| {
                    let offset = Vec3::from(lamp_at.0.translation) - eye;
                    let distance = offset.length();
                    sight::in_view(offset, warden.forward())
                        && distance > 1e-3
                        && geometry
                            .0
                            .raycast(eye, offset / distance, (distance - 0.05).max(0.0))
                            .is_none()
                });
                if let Some((lamp, lamp_at)) = seen {
                    let below = Vec3::new(lamp_at.0.translation.x, at.y, lamp_at.0.translation.z);
                    warden.relight = Some(lamp);
                    warden.path = plan(grid.as_deref(), at, below);
                }
            }
        }
    }
}

/// The way back to the warden's route.
fn home(warden: &Warden, at: Vec3, grid: Option<&NavGrid>) -> Vec<Vec3> {
    warden
        .def
        .route
        .get(warden.next)
        .map_or_else(Vec::new, |&point| plan(grid, at, point))
}
