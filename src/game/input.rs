//! Game schedule, first fixed step: input as the game sees it, and the fly camera.
//!
//! The window shell translates devices into this resource through its key-binding table;
//! the game never sees winit. Held actions move the view at a fixed speed per step; mouse
//! look accumulated between steps is applied by the next step; actions pressed since the
//! last step (`Input::pressed`: a jump, the noclip toggle) are taken once. With a player in
//! the world the player moves (`player`), and the fly camera only serves levels without one.

use std::collections::HashSet;

use bevy_ecs::prelude::*;
use glam::{Quat, Vec2, Vec3};

use super::{SIMULATION_HZ, Transform, ViewCamera};

/// What a player can ask for, whatever key or button is bound to it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Action {
    MoveForward,
    MoveBack,
    MoveLeft,
    MoveRight,
    /// Jump; rise when flying.
    MoveUp,
    /// Crouch while held; sink when flying.
    MoveDown,
    /// Run (loud) while held.
    Sprint,
    /// Switch the player's collision off and on (fly through walls, for debugging).
    Noclip,
    /// Douse or relight the lamp the player looks at, within reach.
    Interact,
}

impl Action {
    /// Every action, in a fixed order (recordings store them as bits in this order).
    pub const ALL: [Action; 9] = [
        Action::MoveForward,
        Action::MoveBack,
        Action::MoveLeft,
        Action::MoveRight,
        Action::MoveUp,
        Action::MoveDown,
        Action::Sprint,
        Action::Noclip,
        Action::Interact,
    ];

    /// This action's bit in a recording's bit sets.
    pub fn bit(self) -> u16 {
        1 << Action::ALL.iter().position(|&a| a == self).unwrap_or(0)
    }
}

#[derive(Resource, Default, Debug)]
pub struct Input {
    /// Actions whose key is down.
    pub held: HashSet<Action>,
    /// Mouse look since the last fixed step, in radians: (yaw right, pitch up).
    pub look: Vec2,
    /// Actions pressed since the last fixed step (taken once by the step that reads them).
    pub pressed: HashSet<Action>,
}

/// Flying speed of the free camera, metres per second.
pub const FLY_SPEED: f32 = 3.0;

/// Moves and turns the view from `Input` (one fixed step). Yaw turns about the world's up,
/// pitch about the view's right and is kept within 89 degrees of the horizon.
pub fn fly_camera(
    mut input: ResMut<Input>,
    mut views: Query<&mut Transform, With<ViewCamera>>,
    players: Query<(), With<super::Player>>,
) {
    if !players.is_empty() || (input.held.is_empty() && input.look == Vec2::ZERO) {
        return; // leave the transform untouched: nothing moved, accumulation goes on
    }
    let look = std::mem::take(&mut input.look);
    input.pressed.clear();
    let step = FLY_SPEED / SIMULATION_HZ as f32;
    for mut transform in &mut views {
        let (yaw, pitch, _) = transform.rotation.to_euler(glam::EulerRot::YXZ);
        let limit = 89f32.to_radians();
        let (yaw, pitch) = (yaw - look.x, (pitch + look.y).clamp(-limit, limit));
        transform.rotation = Quat::from_euler(glam::EulerRot::YXZ, yaw, pitch, 0.0);
        let forward = transform.rotation * Vec3::NEG_Z;
        let right = transform.rotation * Vec3::X;
        let mut motion = Vec3::ZERO;
        for action in &input.held {
            motion += match action {
                Action::MoveForward => forward,
                Action::MoveBack => -forward,
                Action::MoveRight => right,
                Action::MoveLeft => -right,
                Action::MoveUp => Vec3::Y,
                Action::MoveDown => Vec3::NEG_Y,
                Action::Sprint | Action::Noclip | Action::Interact => Vec3::ZERO,
            };
        }
        transform.translation += motion.normalize_or_zero() * step;
    }
}
