//! `gloam listen`: what ears at a place in a level hear of its looping sound sources, by
//! the level's own acoustics (`game::acoustics`), mixed offline (`audio`). No ambience bed
//! and no normalisation, so levels compare between runs and between levels: the test of
//! "a wall makes it quieter and duller" is two renders side by side.
//!
//! The level is loaded into its own `Engine`, its clock run on to `--time` (wardens walk,
//! gates lift), and the simulation's copy of the level then answers every ray. Sound files
//! are read as the game reads them (`audio::load_clip`: WAV, FLAC, Ogg Vorbis, MP3).
//!
//! `gloam listen LEVEL --at X,Y,Z --out OUT.wav` writes 48 kHz stereo 16-bit PCM; with
//! `--json OUT.json`, each source as heard and the room's reverb:
//!
//! ```text
//! {"sources": [{"name", "level_db", "occluded", "path_length", "arrival": [x, y, z]}],
//!  "reverb": {"decay_s", "wet_db"}}
//! ```

use std::path::Path;

use anyhow::Context as _;
use bevy_ecs::prelude::Name;
use glam::Vec3;
use serde_json::{Value, json};

use crate::audio::{Bus, Command, Mix, Mixer, Stereo, load_clip};
use crate::frame::Engine;
use crate::game::acoustics::{hear, reverb};
use crate::game::nav::{CELL, NavGrid};
use crate::game::{GlobalTransform, SIMULATION_HZ, SoundSource, WorldGeometry};
use crate::render::RenderSettings;
use crate::scene::Scene;
use crate::scene::sound_kit::RATE;

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
    // The engine's own grid when the level has wardens (it built one), else one for here.
    let built;
    let nav = match world.get_resource::<NavGrid>() {
        Some(grid) => Some(grid),
        None => {
            built = geometry
                .bounds()
                .map(|bounds| NavGrid::build(geometry.as_ref(), bounds, CELL));
            built.as_ref()
        }
    };
    let ears = (listening.at, listening.facing_degrees.to_radians());
    let mut mixer = Mixer::new();
    let mut reports = Vec::new();
    let base = level.parent().unwrap_or(Path::new("."));
    for (voice, (name, def, at)) in (1..).zip(found) {
        let file = base.join(&def.asset);
        let clip = load_clip(&file).with_context(|| format!("{}", level.display()))?;
        let heard = hear(geometry.as_ref(), nav, at, listening.at);
        mixer.apply(Command::Play {
            voice,
            clip,
            looping: true,
            bus: Bus::Effects,
            mix: Mix::heard(&heard, def.gain_db, ears),
        });
        reports.push(json!({
            "name": name,
            "level_db": heard.level_db + def.gain_db,
            "occluded": heard.occluded,
            "path_length": heard.path_length,
            "arrival": [heard.arrival.x, heard.arrival.y, heard.arrival.z],
        }));
    }
    let room = reverb(geometry.as_ref(), listening.at);
    mixer.apply(Command::Room(room));
    let mut out = Stereo::default();
    out.record(
        &mut mixer,
        (listening.seconds * RATE as f64).round() as usize,
    );
    let report = json!({
        "sources": reports,
        "reverb": {"decay_s": room.decay_s, "wet_db": room.wet_db},
    });
    Ok((report, out))
}
