//! `gloam listen`: what ears at a place in a level hear of its looping sound sources, by
//! the level's own acoustics (`game::acoustics`), mixed offline (`audio`). No ambience bed
//! and no normalisation, so levels compare between runs and between levels: the test of
//! "a wall makes it quieter and duller" is two renders side by side.
//!
//! The level is loaded into its own `Engine`, its clock run on to `--time` (wardens walk,
//! gates lift), and the simulation's copy of the level then answers every ray. Sound files
//! are read as WAV (the sound kit's format); other formats are refused in one line.

use std::path::Path;

use anyhow::{Context as _, bail};
use bevy_ecs::prelude::Name;
use glam::Vec3;
use serde_json::{Value, json};

use crate::audio::{Stereo, add_reverb, add_source};
use crate::frame::Engine;
use crate::game::acoustics::{hear, reverb};
use crate::game::nav::{CELL, NavGrid};
use crate::game::{GlobalTransform, SIMULATION_HZ, SoundSource, WorldGeometry};
use crate::render::RenderSettings;
use crate::scene::Scene;
use crate::scene::sound_kit::{RATE, read_wav, resample};

/// Where the ears are and what they take in.
#[derive(Clone, Copy, Debug)]
pub struct Listening {
    /// The ears, world metres.
    pub at: Vec3,
    /// Which way they face, degrees about +Y (0 looks down -Z).
    pub facing_degrees: f32,
    /// Seconds into the level.
    pub time: f64,
    /// Seconds of sound.
    pub seconds: f64,
}

/// What the ears at `listening.at` hear of `scene`'s looping sources (the level file at
/// `level`, which their paths are relative to): the report (`sources`, `reverb`) and the
/// sound.
pub fn listen(
    scene: &Scene,
    level: &Path,
    listening: &Listening,
) -> anyhow::Result<(Value, Stereo)> {
    let mut engine = Engine::new(scene, RenderSettings::real_time(1, 1));
    for _ in 0..(listening.time * SIMULATION_HZ).round() as u64 {
        engine.step();
    }
    engine.update_step_world();
    let world = &mut engine.world;
    let mut found: Vec<(String, crate::scene::level::SoundDef, Vec3)> = world
        .query::<(&Name, &SoundSource, &GlobalTransform)>()
        .iter(world)
        .filter(|(_, source, _)| source.0.looping)
        .map(|(name, source, placed)| {
            (
                name.as_str().to_owned(),
                source.0.clone(),
                placed.0.translation.into(),
            )
        })
        .collect();
    found.sort_by(|a, b| a.0.cmp(&b.0));
    let geometry = &world.resource::<WorldGeometry>().0;
    let nav = geometry
        .bounds()
        .map(|bounds| NavGrid::build(geometry.as_ref(), bounds, CELL));
    let ears = (listening.at, listening.facing_degrees.to_radians());
    let frames = (listening.seconds * RATE as f64).round() as usize;
    let mut out = Stereo::silence(frames);
    let mut send = vec![0.0f32; frames];
    let mut reports = Vec::new();
    let base = level.parent().unwrap_or(Path::new("."));
    for (name, def, at) in found {
        let file = base.join(&def.asset);
        let bytes = std::fs::read(&file).with_context(|| {
            format!(
                "{}: cannot read sound '{}'",
                level.display(),
                file.display()
            )
        })?;
        let Ok((rate, samples)) = read_wav(&bytes) else {
            bail!(
                "{}: sound '{}' is not a 16-bit PCM WAV file (listen reads only those yet)",
                level.display(),
                file.display()
            );
        };
        let samples = if rate == RATE {
            samples
        } else {
            resample(&samples, rate, RATE)
        };
        let heard = hear(geometry.as_ref(), nav.as_ref(), at, listening.at);
        let dry = add_source(&mut out, &samples, true, &heard, def.gain_db, ears);
        for (s, d) in send.iter_mut().zip(&dry) {
            *s += d;
        }
        reports.push(json!({
            "name": name,
            "level_db": heard.level_db + def.gain_db,
            "occluded": heard.occluded,
            "path_length": heard.path_length,
            "arrival": [heard.arrival.x, heard.arrival.y, heard.arrival.z],
        }));
    }
    let room = reverb(geometry.as_ref(), listening.at);
    add_reverb(&mut out, &send, &room);
    let report = json!({
        "sources": reports,
        "reverb": {"decay_s": room.decay_s, "wet_db": room.wet_db},
    });
    Ok((report, out))
}
