//! Game schedule, fixed step "gameplay": light as a verb. Before the player moves
//! (`douse_lamps`), the interact action (E) douses the level lamp the player looks at, or
//! relights a doused one: the lamp within `REACH` of the eye whose direction lies closest
//! to the view, within `AIM_DEGREES` of it, with nothing between (a ray through the level
//! as of this step). A doused lamp is a `SwitchedOff` lamp: its light leaves the renderer's
//! light set, the light gem and the wardens' sight with it. Wardens' own lamps are theirs.

use bevy_ecs::prelude::*;
use glam::{Quat, Vec3};

use super::world_query::WorldGeometry;
use super::{
    Action, GlobalTransform, Input, LevelEntity, Player, PlayerEye, PunctualLight, SwitchedOff,
};

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
        let from: Vec3 = eye.0.translation.into();
        let view =
            Quat::from_rotation_y(player.yaw) * Quat::from_rotation_x(player.pitch) * Vec3::NEG_Z;
        let aimed = lamps
            .iter()
            .filter_map(|(lamp, placed, doused)| {
                let to = Vec3::from(placed.0.translation) - from;
                let distance = to.length();
                let cosine = to.dot(view) / distance.max(1e-6);
                let in_reach = distance <= REACH && cosine >= AIM_DEGREES.to_radians().cos();
                let clear = in_reach
                    && geometry
                        .0
                        .raycast(from, to / distance, (distance - 0.05).max(0.0))
                        .is_none();
                clear.then_some((cosine, lamp, doused))
            })
            .max_by(|a, b| a.0.total_cmp(&b.0));
        if let Some((_, lamp, doused)) = aimed {
            if doused {
                commands.entity(lamp).remove::<SwitchedOff>();
            } else {
                commands.entity(lamp).insert(SwitchedOff);
            }
        }
    }
}
