//! Recordings and headless replays of play-throughs (`gloam play LEVEL --record FILE`,
//! `gloam play --headless --replay FILE --json OUT`).
//!
//! Recording: the frame driver keeps each fixed step's input (`Engine::recording`); when
//! the attempt is won or caught, or the player quits, it is written (atomically) with the
//! level's path relative to the recording and the level file's hash
//! (`game::replay::Recording`).
//!
//! Replay: the level the recording names is loaded (refused in one line if its file has
//! changed since), the player spawned, and every recorded step's input fed to one fixed
//! step of the simulation, with no rendering, until the inputs end or the attempt is won
//! or caught. The report, per 60 Hz step: the time, the player's feet, the light gem, the
//! shards left and the wardens; then the outcome and a hash of the simulation's state over
//! every step, which is the same on any thread count.

use std::path::{Path, PathBuf};

use anyhow::{Context as _, anyhow, bail};
use bevy_ecs::query::With;
use serde_json::{Value, json};

use crate::frame::Engine;
use crate::game::replay::{Ended, Fnv64, RECORDING_VERSION, Recording, StepInput, level_hash};
use crate::game::{
    Exposure, Input, Outcome, Player, Progress, Shard, Transform, Warden, spawn_player,
};
use crate::render::RenderSettings;
use crate::scene::files::write_atomically;
use crate::scene::world::Scene;

/// `to` relative to the folder `from` (both made absolute first), with `/` separators.
fn relative_path(from: &Path, to: &Path) -> anyhow::Result<String> {
    let from = std::fs::canonicalize(from)
        .with_context(|| format!("cannot resolve folder '{}'", from.display()))?;
    let to = std::fs::canonicalize(to)
        .with_context(|| format!("cannot resolve file '{}'", to.display()))?;
    let common = from
        .components()
        .zip(to.components())
        .take_while(|(a, b)| a == b)
        .count();
    let mut relative = PathBuf::new();
    for _ in from.components().skip(common) {
        relative.push("..");
    }
    for component in to.components().skip(common) {
        relative.push(component);
    }
    Ok(relative.to_string_lossy().replace('\\', "/"))
}

/// Writes the steps recorded while playing `level` to `out`.
pub fn write_recording(
    out: &Path,
    level: &Path,
    steps: Vec<StepInput>,
    ended: Ended,
) -> anyhow::Result<()> {
    let folder = match out.parent() {
        Some(parent) if !parent.as_os_str().is_empty() => parent.to_owned(),
        _ => PathBuf::from("."),
    };
    std::fs::create_dir_all(&folder)
        .with_context(|| format!("cannot create folder '{}'", folder.display()))?;
    let bytes =
        std::fs::read(level).with_context(|| format!("cannot read '{}'", level.display()))?;
    let recording = Recording {
        version: RECORDING_VERSION,
        level: relative_path(&folder, level)?,
        level_hash: level_hash(&bytes),
        ended,
        steps,
    };
    let text = serde_json::to_string(&recording).context("encoding the recording")?;
    write_atomically(out, text.as_bytes())
}

/// Reads a recording and finds its level: (recording, level file).
pub fn read_recording(path: &Path) -> anyhow::Result<(Recording, PathBuf)> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read recording '{}'", path.display()))?;
    let recording: Recording = serde_json::from_str(&text).map_err(|error| {
        anyhow!(
            "{}:{}:{}: not a Gloam recording: {error}",
            path.display(),
            error.line(),
            error.column()
        )
    })?;
    if recording.version != RECORDING_VERSION {
        bail!(
            "{}: recording version {} (this gloam reads version {RECORDING_VERSION})",
            path.display(),
            recording.version
        );
    }
    let folder = path.parent().unwrap_or(Path::new("."));
    let level = folder.join(&recording.level);
    let bytes = std::fs::read(&level).with_context(|| {
        format!(
            "{}: its level '{}' cannot be read",
            path.display(),
            level.display()
        )
    })?;
    let hash = level_hash(&bytes);
    if hash != recording.level_hash {
        bail!(
            "{}: recorded on another version of '{}' (level hash {}, the file now hashes {hash}); record it again",
            path.display(),
            level.display(),
            recording.level_hash
        );
    }
    Ok((recording, level))
}

/// Replays `path` headless on `threads` threads: the report (see the module doc).
pub fn replay(path: &Path, threads: usize) -> anyhow::Result<Value> {
    let (recording, level) = read_recording(path)?;
    let scene = Scene::load(&level)?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .context("starting the worker threads")?;
    pool.install(|| {
        let mut engine = Engine::new(&scene, RenderSettings::real_time(1, 1));
        spawn_player(&mut engine.world)
            .with_context(|| format!("{}: the level has no player start", level.display()))?;
        Ok(simulate(&mut engine, &recording))
    })
}

/// Feeds the recording's steps to the simulation and reports each.
fn simulate(engine: &mut Engine, recording: &Recording) -> Value {
    let mut hash = Fnv64::default();
    let mut steps = Vec::with_capacity(recording.steps.len());
    for (index, input) in recording.steps.iter().enumerate() {
        input.apply(&mut engine.world.resource_mut::<Input>());
        engine.step();
        let mut players = engine
            .world
            .query_filtered::<(&Transform, &Exposure), With<Player>>();
        let (feet, gem) = players
            .iter(&engine.world)
            .next()
            .map_or((glam::Vec3::ZERO, 0.0), |(t, e)| (t.translation, e.gem));
        let shards_left = engine
            .world
            .query_filtered::<(), With<Shard>>()
            .iter(&engine.world)
            .count() as u32;
        let outcome = engine.world.resource::<Progress>().outcome;
        let mut wardens: Vec<(String, &'static str, f32, glam::Vec3)> = engine
            .world
            .query::<(&bevy_ecs::name::Name, &Warden, &Transform)>()
            .iter(&engine.world)
            .map(|(name, warden, placed)| {
                (
                    name.as_str().to_owned(),
                    warden.state.name(),
                    warden.suspicion,
                    placed.translation,
                )
            })
            .collect();
        wardens.sort_by(|a, b| a.0.cmp(&b.0));
        for (name, state, suspicion, at) in &wardens {
            hash.write(name.as_bytes());
            hash.write(state.as_bytes());
            for value in [*suspicion, at.x, at.y, at.z] {
                hash.write(&value.to_bits().to_le_bytes());
            }
        }
        for value in [feet.x, feet.y, feet.z, gem] {
            hash.write(&value.to_bits().to_le_bytes());
        }
        hash.write(&shards_left.to_le_bytes());
        hash.write(&[outcome as u8]);
        steps.push(json!({
            "t": (index + 1) as f64 / crate::game::SIMULATION_HZ,
            "player": [feet.x, feet.y, feet.z],
            "exposure": gem,
            "shards_left": shards_left,
            "wardens": wardens
                .iter()
                .map(|(name, state, suspicion, _)| {
                    json!({"name": name, "state": state, "suspicion": suspicion})
                })
                .collect::<Vec<_>>(),
        }));
        if outcome != Outcome::Running {
            break;
        }
    }
    let outcome = match engine.world.resource::<Progress>().outcome {
        Outcome::Running if recording.ended == Ended::Quit => Outcome::Quit,
        outcome => outcome,
    };
    json!({
        "outcome": outcome.name(),
        "state_hash": hash.hex(),
        "steps": steps,
    })
}
