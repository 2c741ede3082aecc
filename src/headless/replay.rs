//! Recordings and headless replays of play-throughs (`gloam play LEVEL --record FILE`,
//! `gloam play --headless --replay FILE --json OUT`, and the bot's runs).
//!
//! Recording: the frame driver keeps each fixed step's input and the trail of states
//! (`Engine::recording`); when the attempt is won or caught, or the player quits, it is
//! written (atomically) with the level's path relative to the recording and the level
//! file's hash (`game::replay::Recording`).
//!
//! Replay: the level the recording names is loaded (refused in one line if its file has
//! changed since), the player spawned, and every recorded step's input fed to one fixed
//! step of the simulation, with no rendering, until the inputs end or the attempt is won
//! or caught. After each step the whole state is read (`game::state::StateParts`); at
//! each mark of the recording's trail it is held to the mark, and the replay stops at the
//! first mark it departs from. A replay that ends at another step than the recording did
//! (won or caught sooner, or not at all) has departed too; the command then exits 1 with
//! one line naming the step and the first part of the state that differs
//! (`REC: diverged at step N (t = S s): player position`).
//!
//! The report (`--json OUT`) has every step, then the outcome, `state_hash` (the states of
//! every step chained, 16 hex digits: the same on any thread count and with either SIMD
//! kernels; the tests pin every shipped recording's) and `diverged`, null or where the
//! replay went another way:
//!
//! ```text
//! {"outcome": "won" | "caught" | "quit" | "running", "state_hash",
//!  "steps": [{"t", "player": [x, y, z] (feet), "exposure" (the light gem), "shards_left",
//!             "wardens": [{"name", "state", "suspicion"}],
//!             "sounds": [the sound kit's files the step's events played, e.g.
//!                        "step-stone-crouch-1", "warden-alarm"]}],
//!  "diverged": null | {"step", "t", "part"}}
//! ```
//!
//! Listening (`--audio OUT.wav`), the player's ears hear every step as they do in the
//! window (`audio::Hearing`) and the window's mixer mixes it, one step's samples at a
//! time: the run's sound, 48 kHz stereo, the same bytes on any thread count.

use std::path::{Path, PathBuf};

use anyhow::{Context as _, anyhow, bail};
use bevy_ecs::query::With;
use serde_json::{Value, json};

use crate::audio::{Hearing, Mixer, STEP_FRAMES, Stereo};
use crate::frame::Engine;
use crate::game::replay::{
    Ended, Fnv64, OLDEST_RECORDING_VERSION, RECORDING_VERSION, Recorder, Recording, level_hash,
};
use crate::game::state::StateParts;
use crate::game::{
    Exposure, Input, Outcome, Player, Progress, SIMULATION_HZ, Shard, Transform, Warden,
    spawn_player,
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
    recorded: Recorder,
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
        steps: recorded.steps,
        trail: recorded.trail,
    };
    let text = serde_json::to_string(&recording).context("encoding the recording")?;
    write_atomically(out, text.as_bytes())
}

/// Reads a recording and finds its level: (recording, level file).
pub fn read_recording(path: &Path) -> anyhow::Result<(Recording, PathBuf)> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read recording '{}'", path.display()))?;
    parse_recording(path, &text)
}

/// A recording's `text`, as if read from `path`, checked, with its level found (relative
/// to `path`'s folder, and hashing as when it was recorded): (recording, level file).
pub fn parse_recording(path: &Path, text: &str) -> anyhow::Result<(Recording, PathBuf)> {
    let recording: Recording = serde_json::from_str(text).map_err(|error| {
        anyhow!(
            "{}:{}:{}: not a Gloam recording: {error}",
            path.display(),
            error.line(),
            error.column()
        )
    })?;
    if !(OLDEST_RECORDING_VERSION..=RECORDING_VERSION).contains(&recording.version) {
        bail!(
            "{}: recording version {} (this gloam reads versions {OLDEST_RECORDING_VERSION} to {RECORDING_VERSION})",
            path.display(),
            recording.version
        );
    }
    // A number past f32's range reads as infinite: no player's turn is that.
    if let Some(step) =
        (recording.steps.iter()).position(|input| !(input.2.is_finite() && input.3.is_finite()))
    {
        bail!(
            "{}: step {}: its look turn is not a finite number of radians",
            path.display(),
            step + 1
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

/// Where a replay went another way than its recording.
#[derive(Clone, Debug, PartialEq)]
pub struct Divergence {
    /// The step after which it was found (1 is the first step).
    pub step: usize,
    /// What differs: the first part of the state, or how the ending differs.
    pub part: String,
}

impl Divergence {
    /// The one line a replay that diverged ends with, naming the recording.
    pub fn line(&self, recording: &Path) -> String {
        format!(
            "{}: diverged at step {} (t = {:.2} s): {}",
            recording.display(),
            self.step,
            self.step as f64 / SIMULATION_HZ,
            self.part
        )
    }
}

/// Replays `path` headless on `threads` threads: the report (see the module doc).
pub fn replay(path: &Path, threads: usize) -> anyhow::Result<Value> {
    Ok(run(path, threads, false)?.0)
}

/// `replay`, listening: the report and the run's sound as the player heard it (the
/// window's mixer, `audio::Mixer`, fed each step's commands and mixing one step's samples
/// after each, and a second after the end for the last sounds to ring out), the same
/// samples on any thread count.
pub fn replay_with_sound(path: &Path, threads: usize) -> anyhow::Result<(Value, Stereo)> {
    let (report, sound) = run(path, threads, true)?;
    Ok((report, sound.unwrap_or_default()))
}

fn run(path: &Path, threads: usize, listen: bool) -> anyhow::Result<(Value, Option<Stereo>)> {
    let (recording, level) = read_recording(path)?;
    let scene = Scene::load(&level)?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .context("starting the worker threads")?;
    pool.install(|| play(&scene, &level, &recording, listen, recording.steps.len()))
}

/// Replays at most `max_steps` of `recording` on `scene`, loaded from `level`, in the
/// current thread pool: the report (the fuzz target's replay, on a scene loaded once).
pub fn replay_loaded(
    scene: &Scene,
    level: &Path,
    recording: &Recording,
    max_steps: usize,
) -> anyhow::Result<Value> {
    Ok(play(scene, level, recording, false, max_steps)?.0)
}

/// The replay itself, in the current thread pool.
fn play(
    scene: &Scene,
    level: &Path,
    recording: &Recording,
    listen: bool,
    max_steps: usize,
) -> anyhow::Result<(Value, Option<Stereo>)> {
    let mut engine = Engine::new(scene, RenderSettings::real_time(1, 1));
    spawn_player(&mut engine.world)
        .with_context(|| format!("{}: the level has no player start", level.display()))?;
    let mut sound = listen.then(|| {
        engine.hearing = Some(Hearing::for_level(level));
        (Mixer::new(), Stereo::default())
    });
    let report = simulate(&mut engine, recording, sound.as_mut(), max_steps);
    // The last sounds ring out.
    if let Some((mixer, stereo)) = &mut sound {
        stereo.record(mixer, crate::scene::sound_kit::RATE as usize);
    }
    if let Some(hearing) = &engine.hearing {
        for warning in &hearing.warnings {
            eprintln!("warning: {warning}");
        }
    }
    Ok((report, sound.map(|(_, stereo)| stereo)))
}

/// The divergence a replay report holds, if any.
pub fn divergence(report: &Value) -> Option<Divergence> {
    let diverged = report.get("diverged")?;
    Some(Divergence {
        step: diverged.get("step")?.as_u64()? as usize,
        part: diverged.get("part")?.as_str()?.to_owned(),
    })
}

/// Feeds the recording's steps (at most `max_steps`) to the simulation and reports each
/// (and mixes each step's sound into `sound`, when listening).
fn simulate(
    engine: &mut Engine,
    recording: &Recording,
    mut sound: Option<&mut (Mixer, Stereo)>,
    max_steps: usize,
) -> Value {
    let mut hash = Fnv64::default();
    let mut steps = Vec::with_capacity(recording.steps.len());
    let mut marks = recording.trail.iter().peekable();
    let mut diverged: Option<Divergence> = None;
    for (index, input) in recording.steps.iter().take(max_steps).enumerate() {
        input.apply(&mut engine.world.resource_mut::<Input>());
        engine.step();
        if let (Some((mixer, stereo)), Some(hearing)) = (&mut sound, &mut engine.hearing) {
            for command in hearing.take() {
                mixer.apply(command);
            }
            stereo.record(mixer, STEP_FRAMES);
        }
        let state = StateParts::of(&mut engine.world);
        hash.write(&state.hash().to_le_bytes());
        steps.push(step_report(engine, index + 1));
        while marks.next_if(|mark| mark.step < index + 1).is_some() {}
        if let Some(mark) = marks.next_if(|mark| mark.step == index + 1)
            && let Some(part) = state.first_difference(&mark.state())
        {
            diverged = Some(Divergence {
                step: index + 1,
                part,
            });
            break;
        }
        if engine.world.resource::<Progress>().outcome != Outcome::Running {
            break;
        }
    }
    let ran = steps.len();
    let outcome = engine.world.resource::<Progress>().outcome;
    if diverged.is_none() {
        diverged = ending_difference(recording, outcome, ran);
    }
    let outcome = match outcome {
        Outcome::Running if recording.ended == Ended::Quit => Outcome::Quit,
        outcome => outcome,
    };
    json!({
        "outcome": outcome.name(),
        "state_hash": hash.hex(),
        "steps": steps,
        "diverged": diverged.map(|d| json!({
            "step": d.step,
            "t": d.step as f64 / SIMULATION_HZ,
            "part": d.part,
        })),
    })
}

/// How the replay's end differs from the recording's: won or caught at another step, or
/// at all.
fn ending_difference(recording: &Recording, outcome: Outcome, ran: usize) -> Option<Divergence> {
    let recorded = recording.steps.len();
    let expected = match recording.ended {
        Ended::Won => Outcome::Won,
        Ended::Caught => Outcome::Caught,
        Ended::Quit | Ended::Inputs => Outcome::Running,
    };
    if outcome == expected && (ran == recorded || outcome == Outcome::Running) {
        return None;
    }
    let part = match (outcome, expected) {
        (Outcome::Running, _) => format!(
            "still running after the last step; the recording ended {}",
            expected.name()
        ),
        (_, Outcome::Running) => format!(
            "{} at step {ran}; the recording goes on to step {recorded}",
            outcome.name()
        ),
        _ if outcome == expected => format!(
            "{} at step {ran}; the recording ended at step {recorded}",
            outcome.name()
        ),
        _ => format!(
            "{} at step {ran}; the recording ended {} at step {recorded}",
            outcome.name(),
            expected.name()
        ),
    };
    Some(Divergence { step: ran, part })
}

/// One step's line of the report.
fn step_report(engine: &mut Engine, step: usize) -> Value {
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
    let mut wardens: Vec<(String, &'static str, f32)> = engine
        .world
        .query::<(&bevy_ecs::name::Name, &Warden)>()
        .iter(&engine.world)
        .map(|(name, warden)| {
            (
                name.as_str().to_owned(),
                warden.state.name(),
                warden.suspicion,
            )
        })
        .collect();
    wardens.sort_by(|a, b| a.0.cmp(&b.0));
    let sounds: Vec<&str> = engine
        .world
        .get_resource::<crate::game::SoundEvents>()
        .map(|sounds| sounds.events.iter().map(|e| e.sound.as_str()).collect())
        .unwrap_or_default();
    json!({
        "t": step as f64 / SIMULATION_HZ,
        "player": [feet.x, feet.y, feet.z],
        "exposure": gem,
        "shards_left": shards_left,
        "wardens": wardens
            .iter()
            .map(|(name, state, suspicion)| {
                json!({"name": name, "state": state, "suspicion": suspicion})
            })
            .collect::<Vec<_>>(),
        "sounds": sounds,
    })
}
