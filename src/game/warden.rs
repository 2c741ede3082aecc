//! Game schedule, fixed step "gameplay": the wardens. Each walks its route, point after
//! point and round again, at its speed, turning towards where it goes (at most
//! `TURN_RATE`), and carries its lamp: a real spot light (a child entity with a
//! `PunctualLight`) that moves with it and lights the level, so its pool is what the
//! player sees coming and what raises the light gem.
//!
//! Seeing and the states beyond patrolling (suspicious, searching, alert, caught) come
//! next; every warden reports its state and suspicion already (replays write them).

use bevy_ecs::prelude::*;
use glam::{Quat, Vec3};

use super::{PunctualLight, SIMULATION_HZ, Transform};
use crate::scene::level::{WardenDef, WardenLamp};

/// How fast a warden turns to face where it walks (radians a second).
pub const TURN_RATE: f32 = std::f32::consts::PI;

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
    /// Facing, radians about +Y (0 looks down -Z).
    pub yaw: f32,
    pub state: WardenState,
    /// 0..1: how sure it is it has seen someone.
    pub suspicion: f32,
}

/// A warden's lamp (the child entity carrying its light).
#[derive(Component, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct WardenLampLight;

/// The lamp's place relative to the warden's feet.
pub fn lamp_transform(lamp: &WardenLamp) -> Transform {
    Transform {
        translation: Vec3::new(0.0, lamp.height, -lamp.reach),
        rotation: Quat::from_rotation_x(-lamp.tilt_degrees.to_radians()),
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
        },
        PunctualLight(def.lamp.light()),
        lamp_transform(&def.lamp),
    )
}

/// Fixed step: every warden walks on along its route.
pub fn walk_wardens(mut wardens: Query<(&mut Warden, &mut Transform)>) {
    let dt = 1.0 / SIMULATION_HZ as f32;
    for (mut warden, mut transform) in &mut wardens {
        let warden = &mut *warden;
        if warden.def.route.is_empty() || warden.state != WardenState::Patrol {
            continue;
        }
        let mut at = transform.translation;
        let mut budget = warden.def.speed * dt;
        let mut heading = None;
        // Walk the step's distance, past as many route points as it reaches.
        for _ in 0..warden.def.route.len() {
            let target = warden.def.route[warden.next];
            let to = target - at;
            let distance = to.length();
            if distance > 1e-6 {
                heading = Some(to);
            }
            if distance > budget {
                at += to / distance * budget;
                break;
            }
            at = target;
            budget -= distance;
            warden.next = (warden.next + 1) % warden.def.route.len();
        }
        if let Some(heading) = heading
            && Vec3::new(heading.x, 0.0, heading.z).length_squared() > 1e-8
        {
            let wanted = (-heading.x).atan2(-heading.z);
            let turn = wrap_angle(wanted - warden.yaw).clamp(-TURN_RATE * dt, TURN_RATE * dt);
            warden.yaw = wrap_angle(warden.yaw + turn);
        }
        transform.set_if_neq(Transform {
            translation: at,
            rotation: Quat::from_rotation_y(warden.yaw),
            scale: transform.scale,
        });
    }
}

/// `angle` in (-pi, pi].
fn wrap_angle(angle: f32) -> f32 {
    let tau = std::f32::consts::TAU;
    let wrapped = (angle + std::f32::consts::PI).rem_euclid(tau) - std::f32::consts::PI;
    if wrapped <= -std::f32::consts::PI {
        wrapped + tau
    } else {
        wrapped
    }
}
