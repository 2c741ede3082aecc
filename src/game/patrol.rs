//! Game schedule, fixed step "gameplay": scripted movers. A `Patrol` swings its entity back
//! and forth along a line through its place, a sine by the simulation clock: a level's
//! `mover` (a lantern running on a rail), and the lamp-carrier `gloam flythrough` uses to
//! measure how the film copes with a moving light.

use bevy_ecs::prelude::*;
use glam::Vec3;

use super::{SIMULATION_HZ, Transform};

/// Moves the entity up to `offset` (world metres) either side of `origin`, a sine over
/// `period` seconds, by the simulation clock.
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub struct Patrol {
    /// Where the beat is centred (the entity's transform when the patrol was given).
    pub origin: Transform,
    pub offset: Vec3,
    /// Seconds for one round trip.
    pub period: f64,
    /// Seconds walked so far.
    pub elapsed: f64,
}

impl Patrol {
    /// A patrol centred on `origin`, starting there, `amplitude` metres either way along
    /// the origin's local +Z.
    pub fn new(origin: Transform, amplitude: f32, period: f64) -> Patrol {
        Patrol {
            origin,
            offset: origin.rotation * Vec3::Z * amplitude,
            period,
            elapsed: 0.0,
        }
    }

    /// Where the patrol puts its entity `seconds` in.
    pub fn at(&self, seconds: f64) -> Transform {
        let phase = std::f64::consts::TAU * seconds / self.period;
        Transform {
            translation: self.origin.translation + self.offset * phase.sin() as f32,
            ..self.origin
        }
    }
}

/// Fixed step: every patrol one step further on.
pub fn patrol(mut movers: Query<(&mut Patrol, &mut Transform)>) {
    for (mut patrol, mut transform) in &mut movers {
        patrol.elapsed += 1.0 / SIMULATION_HZ;
        let placed = patrol.at(patrol.elapsed);
        transform.set_if_neq(placed);
    }
}
