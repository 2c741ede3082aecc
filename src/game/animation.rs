//! Game schedule, fixed step "animation": glTF clip playback and procedural deformer clocks.
//!
//! Per fixed step, after gameplay and before transform propagation:
//! 1. `advance_animations`: every `Animator` and `Deformer` clock moves on by one step
//!    (times its speed);
//! 2. `apply_animations`: each animator samples its clip (`scene::animation`) at its clock
//!    and writes the channels into the node entities' `Transform`s and `MorphWeights`.
//!    Writes go through `set_if_neq`, so a component whose value did not change keeps its
//!    change tick: the frame's `deform_meshes` reads those ticks to skip meshes whose pose
//!    is unchanged (a clip playing `Once` that has ended, a paused animator).

use bevy_ecs::prelude::*;
use glam::Quat;

use super::Transform;
use crate::scene::animation::{Playback, clip_time};
use crate::scene::level::DeformerDef;
use crate::scene::model::{AnimatedProperty, Animation};

/// Plays one glTF clip over the node entities of one level entity's asset.
#[derive(Component, Clone, Debug)]
pub struct Animator {
    /// Index into `AnimationLibrary::clips`.
    pub clip: usize,
    /// Seconds of playback so far, already multiplied by `speed`; mapped into the clip by
    /// `playback`.
    pub elapsed: f64,
    /// Where `elapsed` stood at level start (the level's `start`, in clip seconds).
    pub start: f64,
    /// Playback rate (1 = authored speed; 0 pauses; negative plays backwards).
    pub speed: f32,
    pub playback: Playback,
    /// The ECS entity of each node of the asset (by glTF node index).
    pub nodes: Vec<Entity>,
}

impl Animator {
    /// The time within the clip this animator is at.
    pub fn clip_time(&self, library: &AnimationLibrary) -> f32 {
        clip_time(
            self.elapsed,
            library.clips[self.clip].duration(),
            self.playback,
        )
    }
}

/// Morph-target weights of a mesh entity (glTF node or mesh `weights`, then animated).
#[derive(Component, Clone, Debug, PartialEq)]
pub struct MorphWeights(pub Vec<f32>);

/// A procedural deformer on a mesh entity, with its own clock (seconds).
#[derive(Component, Clone, Debug, PartialEq)]
pub struct Deformer {
    pub kind: DeformerDef,
    pub time: f64,
}

/// The gait clips of a body's model (a warden's, the player's), as `AnimationLibrary`
/// indices, each if the model has it: `walk`, `idle`, and `alert` (played once when a
/// warden notices the player).
#[derive(Component, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BodyClips {
    pub walk: Option<usize>,
    pub idle: Option<usize>,
    pub alert: Option<usize>,
}

impl BodyClips {
    /// `asset`'s gait clips, copied into `library`.
    pub fn of(
        library: &mut AnimationLibrary,
        asset: &std::sync::Arc<crate::scene::model::Asset>,
    ) -> BodyClips {
        let mut named = |name: &str| {
            asset
                .animation_by_name(name)
                .map(|clip| library.clip(asset, clip))
        };
        BodyClips {
            walk: named("walk"),
            idle: named("idle"),
            alert: named("alert"),
        }
    }

    /// An animator playing the idle clip over `nodes`, if there is one.
    pub fn idle_animator(&self, nodes: &[Entity]) -> Option<Animator> {
        Some(Animator {
            clip: self.idle?,
            elapsed: 0.0,
            start: 0.0,
            speed: 1.0,
            playback: crate::scene::animation::Playback::Loop,
            nodes: nodes.to_vec(),
        })
    }

    /// Plays `clip` (restarting it when it is not already playing) at `rate`.
    pub fn play(
        animator: &mut Animator,
        clip: usize,
        playback: crate::scene::animation::Playback,
        rate: f32,
    ) {
        if animator.clip != clip {
            animator.clip = clip;
            animator.elapsed = 0.0;
            animator.playback = playback;
        }
        if animator.speed != rate {
            animator.speed = rate;
        }
    }
}

/// Every clip an animator in the world may play (copied out of the assets at spawn).
#[derive(Resource, Default)]
pub struct AnimationLibrary {
    pub clips: Vec<Animation>,
    /// Each clip's index in `clips` by (asset file, clip index in the asset).
    by_source: std::collections::HashMap<(crate::scene::AssetKey, usize), usize>,
}

impl AnimationLibrary {
    /// The index of `asset`'s clip `clip`, copied in on first use.
    pub fn clip(
        &mut self,
        asset: &std::sync::Arc<crate::scene::model::Asset>,
        clip: usize,
    ) -> usize {
        let clips = &mut self.clips;
        *self
            .by_source
            .entry((crate::scene::AssetKey(std::sync::Arc::clone(asset)), clip))
            .or_insert_with(|| {
                clips.push(asset.animations[clip].clone());
                clips.len() - 1
            })
    }
}

/// Fixed step: moves every animation and deformer clock on by `step` seconds.
pub fn advance_clocks(
    step: f64,
    animators: &mut Query<&mut Animator>,
    deformers: &mut Query<&mut Deformer>,
) {
    for mut animator in animators.iter_mut() {
        if animator.speed != 0.0 {
            let speed = animator.speed as f64;
            animator.elapsed += step * speed;
        }
    }
    for mut deformer in deformers.iter_mut() {
        deformer.time += step;
    }
}

/// Fixed step 1: clocks on by one simulation step.
pub fn advance_animations(
    mut animators: Query<&mut Animator>,
    mut deformers: Query<&mut Deformer>,
) {
    advance_clocks(1.0 / super::SIMULATION_HZ, &mut animators, &mut deformers);
}

/// Fixed step 2: every animator's clip sampled at its clock, written to its nodes.
pub fn apply_animations(
    animators: Query<&Animator>,
    library: Res<AnimationLibrary>,
    mut transforms: Query<&mut Transform>,
    mut weights: Query<&mut MorphWeights>,
) {
    let mut sampled = Vec::new();
    for animator in &animators {
        let clip = &library.clips[animator.clip];
        let t = animator.clip_time(&library);
        for channel in &clip.channels {
            let sampler = &clip.samplers[channel.sampler];
            let Some(&target) = animator.nodes.get(channel.node) else {
                continue;
            };
            if channel.property == AnimatedProperty::MorphWeights {
                let Ok(mut current) = weights.get_mut(target) else {
                    continue;
                };
                sampled.resize(sampler.components, 0.0);
                sampler.sample_into(t, &mut sampled);
                if current.0 != sampled {
                    current.0.clone_from(&sampled);
                }
                continue;
            }
            let Ok(mut transform) = transforms.get_mut(target) else {
                continue;
            };
            let mut posed = *transform;
            match channel.property {
                AnimatedProperty::Translation => posed.translation = sampler.sample_vec3(t),
                AnimatedProperty::Scale => posed.scale = sampler.sample_vec3(t),
                AnimatedProperty::Rotation => {
                    posed.rotation = sampler.sample_rotation(t);
                    if !posed.rotation.is_finite() {
                        posed.rotation = Quat::IDENTITY;
                    }
                }
                AnimatedProperty::MorphWeights => unreachable!("handled above"),
            }
            transform.set_if_neq(posed);
        }
    }
}
