//! Game schedule, last fixed step: transforms and their propagation down the hierarchy.
//!
//! bevy_ecs provides the hierarchy (`ChildOf` / `Children`) but no transforms; these are
//! written on glam 0.34 (the one obvhs uses) rather than pulling bevy_transform and a
//! second glam. `Transform` is the local placement an entity's systems edit;
//! `GlobalTransform` is world-from-entity, written only by `propagate_transforms`.

use bevy_ecs::prelude::*;
use glam::{Affine3A, Mat4, Quat, Vec3};

/// Local placement relative to the parent (or the world for a root).
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub struct Transform {
    pub translation: Vec3,
    pub rotation: Quat,
    pub scale: Vec3,
}

impl Default for Transform {
    fn default() -> Self {
        Transform {
            translation: Vec3::ZERO,
            rotation: Quat::IDENTITY,
            scale: Vec3::ONE,
        }
    }
}

impl Transform {
    /// From a matrix (glTF matrix nodes); shear, which TRS cannot hold, is dropped.
    pub fn from_matrix(matrix: Mat4) -> Transform {
        let (scale, rotation, translation) = matrix.to_scale_rotation_translation();
        Transform {
            translation,
            rotation,
            scale,
        }
    }

    pub fn affine(&self) -> Affine3A {
        Affine3A::from_scale_rotation_translation(self.scale, self.rotation, self.translation)
    }
}

/// World-from-entity, derived from the `Transform`s up the hierarchy.
#[derive(Component, Clone, Copy, Debug, PartialEq, Default)]
pub struct GlobalTransform(pub Affine3A);

/// `GlobalTransform` as of the previous simulation step, for interpolated rendering.
#[derive(Component, Clone, Copy, Debug, PartialEq, Default)]
pub struct PreviousGlobalTransform(pub Affine3A);

/// First fixed step: remember where everything was before this step moves it.
pub fn remember_transforms(mut query: Query<(&GlobalTransform, &mut PreviousGlobalTransform)>) {
    for (global, mut previous) in &mut query {
        previous.set_if_neq(PreviousGlobalTransform(global.0));
    }
}

/// The transform a fraction `t` (0..1) of the way from `from` to `to`: translation and
/// scale interpolated linearly, rotation spherically.
pub fn interpolate(from: Affine3A, to: Affine3A, t: f32) -> Affine3A {
    let (scale_a, rotation_a, translation_a) = from.to_scale_rotation_translation();
    let (scale_b, rotation_b, translation_b) = to.to_scale_rotation_translation();
    Affine3A::from_scale_rotation_translation(
        scale_a.lerp(scale_b, t),
        rotation_a.slerp(rotation_b, t),
        translation_a.lerp(translation_b, t),
    )
}

/// Recomputes every `GlobalTransform` from the roots down. Values are written only when
/// they change, so `Changed<GlobalTransform>` tells extract exactly what moved.
pub fn propagate_transforms(
    roots: Query<Entity, (With<Transform>, Without<ChildOf>)>,
    children: Query<&Children>,
    locals: Query<&Transform>,
    mut globals: Query<&mut GlobalTransform>,
) {
    let mut stack: Vec<(Entity, Affine3A)> = roots
        .iter()
        .map(|root| (root, Affine3A::IDENTITY))
        .collect();
    while let Some((entity, parent)) = stack.pop() {
        let local = locals
            .get(entity)
            .map(Transform::affine)
            .unwrap_or(Affine3A::IDENTITY);
        let global = parent * local;
        if let Ok(mut current) = globals.get_mut(entity) {
            current.set_if_neq(GlobalTransform(global));
        }
        if let Ok(kids) = children.get(entity) {
            stack.extend(kids.iter().map(|child| (child, global)));
        }
    }
}
