//! `gloam autoplay`: a player bot that plays a level to its end, headless, through the
//! same input actions a player has, and records the run.
//!
//! Per fixed step of the run:
//! 1. watch: the bot reads what a player sees: its own body and light gem, the wardens
//!    (where they are, and the mark over each head: none, ? or !);
//! 2. replan when the world has gone another way than foreseen: a warden is no longer on
//!    its beat (suspicious, searching, alert), a warden stands elsewhere than foreseen, or
//!    the body has fallen behind its way. The new plan starts from a foresight engine that
//!    has replayed the run so far (`foresee`);
//! 3. steer: the move of the plan under way gives the cell to reach and the stance; the
//!    bot turns its view to it (the recording's look) and walks or crouches forward, or
//!    stands still when it is there early (`steer`);
//! 4. step the real simulation with that input, recorded.
//!
//! The plan (`plan`): from the spawn to each shard in turn, the earliest one reached
//! unseen first, then to the way out, each leg a sweep through space and time. The run
//! ends won, caught, with no unseen route (`no_route`, with the lit chokepoints), or at
//! `--max-seconds` of play (`timeout`); the report and the recording are written whatever
//! the ending.
//!
//! # What a run writes
//!
//! `gloam autoplay LEVEL --out REC.json --json REPORT.json` exits 0 when the bot won, 1
//! otherwise with one line why (`no unseen route: the way out cannot be reached on foot
//! from the spawn`, or where the way is watched and lit and from when). `REC.json` is an
//! ordinary recording ([`crate::game::replay`]; `gloam play --replay REC.json` watches it).
//! The report, for every outcome:
//!
//! ```text
//! {"level", "outcome": "won" | "caught" | "no_route" | "timeout", "seconds", "shards",
//!  "shards_total", "times_seen", "max_gem", "replans", "recording",
//!  "chokepoints": [{"x", "z", "time", "exposure"}]}
//! ```
//!
//! `--get-caught` is the scripted walk into the light instead ([`get_caught`]; exit 0 when
//! caught).
//!
//! # Making the recordings again
//!
//! The shipped recordings in `tests/recordings/` are the bot's runs, and `tests/autoplay.rs`
//! fails when a run is no longer its recording, step for step (after any change to the
//! rules, the levels or the bot). Make them again with one loop, from the repository root
//! after `cargo build --release`, then review what changed (`git diff --stat
//! tests/recordings`, then the tests: `tests/autoplay.rs` pins each recording's final
//! state hash, so a recording made again needs its new pin):
//!
//! ```sh
//! for level in first-light the-gallery the-keep; do
//!   target/release/gloam autoplay levels/$level.ron --out tests/recordings/$level-won.json
//!   target/release/gloam autoplay levels/$level.ron --get-caught \
//!     --out tests/recordings/$level-caught.json
//! done
//! ```
//!
//! The recordings, and what makes each:
//! - `<level>-won.json`: the loop's first command, the bot unseen with every shard;
//! - `<level>-caught.json`: the loop's second, standing in the nearest warden's lamp;
//! - `first-light-glimpsed.json`: by hand, a glimpse in the hall, searched for and given up
//!   (`tests/wardens.rs`);
//! - `the-gallery-mirror.json`: by hand, seen only in the corner mirror (`tests/levels.rs`).
//!
//! On the shipped recordings the bot wins first light in 1:09.8, the gallery in 1:15.0 and
//! the keep in 1:26.2 of play.

pub mod plan;

use std::path::PathBuf;

use anyhow::Context as _;
use bevy_ecs::prelude::{Name, With, World};
use glam::{Vec2, Vec3};
use serde_json::{Value, json};

use crate::frame::Engine;
use crate::game::replay::{Ended, Recorder, StepInput};
use crate::game::warden::wrap_angle;
use crate::game::{
    Action, Exit, Exposure, Input, Outcome, Player, Progress, SIMULATION_HZ, Shard, Transform,
    Warden, WardenState, spawn_player,
};
use crate::render::RenderSettings;
use crate::scene::files::write_atomically;
use crate::scene::world::Scene;
use plan::{Chokepoint, Map, PlanMove, SLICE_STEPS, Stance, Sweep, Targets, WardenPose};

/// Seconds of play a run may take before it ends as a timeout, unless told otherwise.
pub const DEFAULT_MAX_SECONDS: f64 = 600.0;

/// `gloam autoplay`'s flags.
#[derive(Debug, clap::Args)]
pub struct Options {
    /// The level.
    pub level: PathBuf,
    /// Write the run as a recording (`gloam play --replay` watches it).
    #[arg(long, value_name = "REC.json")]
    pub out: Option<PathBuf>,
    /// Write the report (outcome, time, shards, times seen, replans, chokepoints).
    #[arg(long, value_name = "REPORT.json")]
    pub json: Option<PathBuf>,
    /// Seconds of play after which the run ends as a timeout.
    #[arg(long, default_value_t = DEFAULT_MAX_SECONDS, value_parser = crate::headless::values::positive)]
    pub max_seconds: f64,
    /// Worker threads (the run is the same on any count).
    #[arg(long, value_parser = crate::headless::values::size())]
    pub threads: Option<usize>,
    /// Which vector kernels run: the CPU's best, or the portable ones a CPU without AVX2
    /// runs (the same bits, so the same run).
    #[arg(long, value_enum, default_value_t = crate::simd::Simd::Native)]
    pub simd: crate::simd::Simd,
    /// Instead of playing to win, walk standing into the nearest warden's lamp and stay
    /// there until caught (how the `-caught` recordings are made); exit 0 when caught.
    #[arg(long)]
    pub get_caught: bool,
}

/// How a run ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RunOutcome {
    Won,
    Caught,
    NoRoute,
    Timeout,
}

impl RunOutcome {
    pub fn name(self) -> &'static str {
        match self {
            RunOutcome::Won => "won",
            RunOutcome::Caught => "caught",
            RunOutcome::NoRoute => "no_route",
            RunOutcome::Timeout => "timeout",
        }
    }
}

/// What a run did (the report's fields).
#[derive(Clone, Debug)]
pub struct Run {
    pub level: String,
    pub outcome: RunOutcome,
    /// Seconds of play.
    pub seconds: f64,
    pub shards: u32,
    pub shards_total: u32,
    pub times_seen: u32,
    /// The light gem's highest value over the run.
    pub max_gem: f32,
    /// Plans made after the first.
    pub replans: u32,
    /// Where the recording was written.
    pub recording: Option<PathBuf>,
    pub chokepoints: Vec<Chokepoint>,
    /// Why the run ended, in one line.
    pub why: String,
    /// The feet, every step (to draw the route taken).
    pub route: Vec<Vec3>,
    /// Wall-clock seconds spent planning, and playing (stepping the simulation).
    pub planning_seconds: f64,
    pub playing_seconds: f64,
    /// The run's steps and trail, as recorded.
    pub recorded: Recorder,
    pub ended: Ended,
}

impl Run {
    /// The report (its schema: the module's documentation).
    pub fn report(&self) -> Value {
        json!({
            "level": self.level,
            "outcome": self.outcome.name(),
            "seconds": self.seconds,
            "shards": self.shards,
            "shards_total": self.shards_total,
            "times_seen": self.times_seen,
            "max_gem": self.max_gem,
            "replans": self.replans,
            "recording": self.recording.as_ref().map(|p| p.display().to_string()),
            "chokepoints": self.chokepoints.iter().map(|c| json!({
                "x": c.at.x,
                "z": c.at.z,
                "time": c.time,
                "exposure": c.exposure,
            })).collect::<Vec<_>>(),
        })
    }
}

/// `gloam autoplay`: plays, writes what was asked, prints one line. Ok(true) when won.
pub fn run(options: &Options) -> anyhow::Result<bool> {
    let threads = options
        .threads
        .unwrap_or_else(crate::headless::bench::default_threads);
    if threads == 0 {
        anyhow::bail!("--threads must be at least 1");
    }
    if !(options.max_seconds.is_finite() && options.max_seconds > 0.0) {
        anyhow::bail!("--max-seconds must be a positive number of seconds");
    }
    crate::simd::use_kernels(options.simd);
    let scene = Scene::load(&options.level)?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .context("starting the worker threads")?;
    let mut run = pool.install(|| {
        if options.get_caught {
            get_caught(&scene, options.max_seconds)
        } else {
            autoplay(&scene, options.max_seconds)
        }
    })?;
    run.level = options.level.display().to_string();
    if let Some(out) = &options.out {
        crate::headless::replay::write_recording(
            out,
            &options.level,
            run.recorded.clone(),
            run.ended,
        )?;
        run.recording = Some(out.clone());
    }
    if let Some(json) = &options.json {
        let text = serde_json::to_string_pretty(&run.report()).context("encoding the report")?;
        write_atomically(json, text.as_bytes())?;
    }
    let line = format!(
        "{}: {} (planned in {:.1} s, played {} steps in {:.1} s: {:.0} steps/s)",
        options.level.display(),
        run.why,
        run.planning_seconds,
        run.recorded.steps.len(),
        run.playing_seconds,
        run.recorded.steps.len() as f64 / run.playing_seconds.max(1e-9),
    );
    if run.outcome == RunOutcome::Won || (options.get_caught && run.outcome == RunOutcome::Caught) {
        println!("{line}");
    } else {
        eprintln!("{line}");
    }
    let wanted = if options.get_caught {
        RunOutcome::Caught
    } else {
        RunOutcome::Won
    };
    Ok(run.outcome == wanted)
}

/// The level's shards (by name) and way out.
fn targets(world: &mut World) -> Option<Targets> {
    let mut shards: Vec<(String, Vec3, f32)> = world
        .query::<(&Name, &Shard, &Transform)>()
        .iter(world)
        .map(|(name, shard, placed)| (name.as_str().to_owned(), placed.translation, shard.radius))
        .collect();
    shards.sort_by(|a, b| a.0.cmp(&b.0));
    let exit = world
        .query::<(&Exit, &Transform)>()
        .iter(world)
        .next()
        .map(|(exit, placed)| (placed.translation, exit.radius))?;
    Some(Targets { shards, exit })
}

/// A plan: the moves of every leg, in steps of the run, and the wardens' poses foreseen
/// at each slice.
#[derive(Default)]
struct Plan {
    /// (depart step, arrive step, to, stance, a shard nudged towards in the move's first
    /// half, coming back to `to` in its second, the stance it waits in once there).
    moves: Vec<(u64, u64, Vec3, Stance, Option<Vec3>, Stance)>,
    /// (step, poses) at every slice of the plan.
    poses: Vec<(u64, Vec<WardenPose>)>,
}

/// Why a plan could not be made.
enum NoPlan {
    Unreachable(String),
    Watched(String, Vec<Chokepoint>),
    OutOfTime,
}

/// A foresight engine: the level run so far with `inputs`, then its player made one no
/// warden sees (noclip) standing still: the world as it goes on while the bot is hidden.
fn foresee(scene: &Scene, inputs: &[StepInput]) -> Engine {
    let mut engine = Engine::new(scene, RenderSettings::real_time(1, 1));
    spawn_player(&mut engine.world);
    engine.playback = Some(inputs.iter().copied().collect());
    for _ in 0..inputs.len() {
        engine.step();
    }
    engine.playback = None;
    *engine.world.resource_mut::<Input>() = Input::default();
    let mut players = engine.world.query::<&mut Player>();
    for mut player in players.iter_mut(&mut engine.world) {
        player.noclip = true;
    }
    engine
}

/// Plans from `feet` at the present of `foresight` (step `foresight.steps` of the run),
/// the shards of `taken` already taken.
fn make_plan(
    map: &Map,
    foresight: &mut Engine,
    feet: Vec3,
    targets: &Targets,
    taken: u8,
    end_step: u64,
) -> Result<Plan, NoPlan> {
    let grid = &map.grid;
    let Some(at) = grid.node_near(feet) else {
        return Err(NoPlan::Unreachable(
            "no unseen route: the bot stands nowhere a body can walk".into(),
        ));
    };
    let start = foresight.steps;
    let max_slices = (end_step.saturating_sub(start) / SLICE_STEPS) as u32;
    let mut poses = Vec::new();
    let swept = plan::sweep(
        map, foresight, at, targets, taken, 0.0, max_slices, &mut poses,
    );
    let mut plan = Plan {
        moves: Vec::new(),
        poses: poses
            .into_iter()
            .enumerate()
            .map(|(slice, pose)| (start + slice as u64 * SLICE_STEPS, pose))
            .collect(),
    };
    let from = if start == 0 {
        "the spawn"
    } else {
        "where the bot stands"
    };
    match swept {
        Sweep::Won { moves } => {
            for PlanMove {
                to,
                depart,
                arrive,
                stance,
                nudge,
            } in moves
            {
                let cell = grid.position(to);
                let towards = nudge.map(|i| {
                    let shard = targets.shards[i].1;
                    Vec3::new(shard.x, cell.y, shard.z)
                });
                plan.moves.push((
                    start + depart as u64 * SLICE_STEPS,
                    start + arrive as u64 * SLICE_STEPS,
                    cell,
                    stance,
                    towards,
                    map.rest_stance(grid.index(to)),
                ));
            }
            Ok(plan)
        }
        Sweep::Unreachable { what } => Err(NoPlan::Unreachable(format!(
            "no unseen route: {what} cannot be reached on foot from {from}"
        ))),
        Sweep::Watched { what, chokepoints } => {
            let line = match chokepoints.first() {
                Some(c) => format!(
                    "no unseen route to {what}: the way is watched and lit at ({:.1}, {:.1}) from t = {:.1} s (gem {:.2}), with no way round",
                    c.at.x, c.at.z, c.time, c.exposure
                ),
                None => format!("no unseen route to {what}: every way there is watched"),
            };
            Err(NoPlan::Watched(line, chokepoints))
        }
        Sweep::OutOfTime => Err(NoPlan::OutOfTime),
    }
}

/// The input that steers the body along `plan` at step `step` (the step about to run).
fn steer(plan: &Plan, step: u64, player: &Player, feet: Vec3) -> StepInput {
    // The move under way: the last one departed.
    let index = plan.moves.partition_point(|&(depart, ..)| depart <= step);
    let Some(&(depart, arrive, cell, stance, towards, rest)) =
        index.checked_sub(1).and_then(|i| plan.moves.get(i))
    else {
        return StepInput(Action::MoveDown.bit(), 0, 0.0, 0.0);
    };
    let stance = if step >= arrive { rest } else { stance };
    let to = match towards {
        Some(shard) if step < depart + (arrive - depart) / 2 => shard,
        _ => cell,
    };
    let mut held = 0;
    if stance == Stance::Crouch {
        held |= Action::MoveDown.bit();
    }
    let across = Vec2::new(to.x - feet.x, to.z - feet.z);
    let reach = stance.speed() / SIMULATION_HZ as f32;
    if across.length() <= reach {
        return StepInput(held, 0, 0.0, 0.0);
    }
    // The view looks down -Z at yaw 0: face the cell, then walk forward.
    let wanted = (-across.x).atan2(-across.y);
    let turn = wrap_angle(player.yaw - wanted);
    StepInput(held | Action::MoveForward.bit(), 0, turn, -player.pitch)
}

/// Why the world calls for a new plan at `step`, if it does.
fn replan_reason(engine: &mut Engine, plan: &Plan, step: u64, feet: Vec3) -> Option<String> {
    let mut wardens = engine.world.query::<(&Name, &Warden)>();
    if let Some((name, warden)) = wardens
        .iter(&engine.world)
        .find(|(_, w)| w.state != WardenState::Patrol)
    {
        return Some(format!("{} is {}", name.as_str(), warden.state.name()));
    }
    if let Ok(index) = plan.poses.binary_search_by_key(&step, |(s, _)| *s) {
        let now = plan::warden_poses(engine);
        let foreseen = &plan.poses[index].1;
        let apart = now
            .iter()
            .zip(foreseen)
            .any(|(a, b)| a.at.distance(b.at) > 0.02 || (a.yaw - b.yaw).abs() > 0.02);
        if apart || now.len() != foreseen.len() {
            return Some("a warden is not where it was foreseen".into());
        }
    }
    // Fallen behind: a move that should have ended finds the body far from its cell.
    let index = plan
        .moves
        .partition_point(|&(_, arrive, ..)| arrive <= step);
    if let Some(&(_, arrive, to, ..)) = index.checked_sub(1).and_then(|i| plan.moves.get(i))
        && arrive == step
        && Vec2::new(to.x - feet.x, to.z - feet.z).length() > 0.3
    {
        return Some(format!(
            "the body fell behind its way ({feet} short of {to})"
        ));
    }
    None
}

/// Plays `scene` to its end (see the module doc), for at most `max_seconds` of play.
pub fn autoplay(scene: &Scene, max_seconds: f64) -> anyhow::Result<Run> {
    let planning_start = std::time::Instant::now();
    let mut engine = Engine::new(scene, RenderSettings::real_time(1, 1));
    let player = spawn_player(&mut engine.world).context("the level has no player start")?;
    engine.recording = Some(Recorder::default());
    let targets = targets(&mut engine.world);
    let shards_total = targets.as_ref().map_or(0, |t| t.shards.len() as u32);
    let end_step = (max_seconds * SIMULATION_HZ).ceil() as u64;
    let mut map_engine = Engine::new(scene, RenderSettings::real_time(1, 1));
    let map = Map::build(&mut map_engine).context("the level has no geometry")?;
    drop(map_engine);
    let mut planning = planning_start.elapsed().as_secs_f64();

    let mut run = Run {
        level: String::new(),
        outcome: RunOutcome::Timeout,
        seconds: 0.0,
        shards: 0,
        shards_total,
        times_seen: 0,
        max_gem: 0.0,
        replans: 0,
        recording: None,
        chokepoints: Vec::new(),
        why: String::new(),
        route: Vec::new(),
        planning_seconds: 0.0,
        playing_seconds: 0.0,
        recorded: Recorder::default(),
        ended: Ended::Inputs,
    };
    let Some(targets) = targets else {
        run.outcome = RunOutcome::NoRoute;
        run.why =
            "no unseen route: the level has no way out (it is a free walk with no end)".into();
        run.planning_seconds = planning;
        return Ok(run);
    };
    if targets.shards.len() > plan::MAX_SHARDS {
        anyhow::bail!(
            "the bot plays levels of at most {} shards; this one has {}",
            plan::MAX_SHARDS,
            targets.shards.len()
        );
    }

    let mut plan: Option<Plan> = None;
    let mut playing = 0.0;
    loop {
        let step = engine.steps;
        let feet = engine
            .world
            .get::<Transform>(player)
            .map_or(Vec3::ZERO, |t| t.translation);
        let progress = engine.world.resource::<Progress>().clone();
        match progress.outcome {
            Outcome::Won => {
                run.outcome = RunOutcome::Won;
                break;
            }
            Outcome::Caught => {
                run.outcome = RunOutcome::Caught;
                break;
            }
            _ => {}
        }
        if step >= end_step {
            run.outcome = RunOutcome::Timeout;
            break;
        }
        // 2. Replan when the world went another way (or there is no plan yet).
        let reason = match &plan {
            None => Some(String::new()),
            Some(plan) => replan_reason(&mut engine, plan, step, feet).or_else(|| {
                let last = plan.moves.last().map_or(0, |m| m.1);
                (step > last + SIMULATION_HZ as u64)
                    .then(|| "the plan ended short of the goal".into())
            }),
        };
        if let Some(reason) = reason {
            if plan.is_some() {
                run.replans += 1;
                if run.replans > 50 {
                    run.outcome = RunOutcome::NoRoute;
                    run.why = format!(
                        "no unseen route: gave up after {} replans (the last: {reason})",
                        run.replans
                    );
                    break;
                }
            }
            let start = std::time::Instant::now();
            let inputs = engine.recording.as_ref().map_or(&[][..], |r| &r.steps[..]);
            let mut foresight = foresee(scene, inputs);
            let present: Vec<&str> = engine
                .world
                .query_filtered::<&Name, With<Shard>>()
                .iter(&engine.world)
                .map(|n| n.as_str())
                .collect();
            let taken = targets
                .shards
                .iter()
                .enumerate()
                .filter(|(_, (name, ..))| !present.contains(&name.as_str()))
                .fold(0u8, |bits, (i, _)| bits | 1 << i);
            let made = make_plan(&map, &mut foresight, feet, &targets, taken, end_step);
            planning += start.elapsed().as_secs_f64();
            match made {
                Ok(made) => plan = Some(made),
                Err(NoPlan::Unreachable(why)) => {
                    run.outcome = RunOutcome::NoRoute;
                    run.why = why;
                    break;
                }
                Err(NoPlan::Watched(why, chokepoints)) => {
                    run.outcome = RunOutcome::NoRoute;
                    run.why = why;
                    run.chokepoints = chokepoints;
                    break;
                }
                Err(NoPlan::OutOfTime) => {
                    run.outcome = RunOutcome::Timeout;
                    break;
                }
            }
        }
        // 3. Steer, 4. step.
        let start = std::time::Instant::now();
        let input = match (&plan, engine.world.get::<Player>(player)) {
            (Some(plan), Some(body)) => steer(plan, step, body, feet),
            _ => StepInput::default(),
        };
        input.apply(&mut engine.world.resource_mut::<Input>());
        engine.step();
        playing += start.elapsed().as_secs_f64();
        if let Some(exposure) = engine.world.get::<Exposure>(player) {
            run.max_gem = run.max_gem.max(exposure.gem);
        }
        run.route.push(feet);
    }
    let progress = engine.world.resource::<Progress>().clone();
    run.seconds = engine.steps as f64 / SIMULATION_HZ;
    run.shards = progress.shards_taken;
    run.times_seen = progress.times_seen;
    run.planning_seconds = planning;
    run.playing_seconds = playing;
    run.recorded = engine.recording.take().unwrap_or_default();
    run.ended = match run.outcome {
        RunOutcome::Won => Ended::Won,
        RunOutcome::Caught => Ended::Caught,
        _ => Ended::Quit,
    };
    match run.outcome {
        RunOutcome::Won => {
            run.why = format!(
                "won{} in {} with {} of {} shards, {} replans",
                if run.times_seen == 0 {
                    " unseen".to_owned()
                } else {
                    format!(", seen {} times,", run.times_seen)
                },
                crate::game::play_time(run.seconds),
                run.shards,
                run.shards_total,
                run.replans
            );
        }
        RunOutcome::Caught => {
            let at = run.route.last().copied().unwrap_or_default();
            run.why = format!(
                "caught at ({:.1}, {:.1}) after {} of play and {} replans",
                at.x,
                at.z,
                crate::game::play_time(run.seconds),
                run.replans
            );
        }
        RunOutcome::Timeout => {
            run.why = format!(
                "timeout: not won after {} of play ({} of {} shards)",
                crate::game::play_time(run.seconds),
                run.shards,
                run.shards_total
            );
        }
        RunOutcome::NoRoute => {}
    }
    Ok(run)
}

/// The scripted walk into the light: standing, the body walks the grid's way to the pool
/// of the nearest warden's lamp, a few metres ahead of it (asked again every half second,
/// as the wardens move), and stays in its light until it is caught, or `max_seconds` run
/// out.
pub fn get_caught(scene: &Scene, max_seconds: f64) -> anyhow::Result<Run> {
    let started = std::time::Instant::now();
    let mut engine = Engine::new(scene, RenderSettings::real_time(1, 1));
    let player = spawn_player(&mut engine.world).context("the level has no player start")?;
    engine.recording = Some(Recorder::default());
    let grid = engine
        .world
        .get_resource::<crate::game::NavGrid>()
        .cloned()
        .context("the level has no wardens to be caught by")?;
    let end_step = (max_seconds * SIMULATION_HZ).ceil() as u64;
    let mut way: Vec<Vec3> = Vec::new();
    let mut max_gem = 0.0f32;
    let mut route = Vec::new();
    while engine.world.resource::<Progress>().outcome == Outcome::Running && engine.steps < end_step
    {
        let feet = engine
            .world
            .get::<Transform>(player)
            .map_or(Vec3::ZERO, |t| t.translation);
        if engine.steps % 30 == 0 {
            let nearest = engine
                .world
                .query::<(&Transform, &Warden)>()
                .iter(&engine.world)
                .map(|(t, warden)| t.translation + warden.forward() * 2.5)
                .min_by(|a, b| a.distance(feet).total_cmp(&b.distance(feet)));
            way = nearest
                .and_then(|warden| grid.path(feet, warden))
                .unwrap_or_default();
        }
        while way
            .first()
            .is_some_and(|p| Vec2::new(p.x - feet.x, p.z - feet.z).length() < 0.3)
        {
            way.remove(0);
        }
        let input = match (way.first(), engine.world.get::<Player>(player)) {
            (Some(&to), Some(body)) => {
                let across = Vec2::new(to.x - feet.x, to.z - feet.z);
                let wanted = (-across.x).atan2(-across.y);
                StepInput(
                    Action::MoveForward.bit(),
                    0,
                    wrap_angle(body.yaw - wanted),
                    -body.pitch,
                )
            }
            _ => StepInput::default(),
        };
        input.apply(&mut engine.world.resource_mut::<Input>());
        engine.step();
        if let Some(exposure) = engine.world.get::<Exposure>(player) {
            max_gem = max_gem.max(exposure.gem);
        }
        route.push(feet);
    }
    let progress = engine.world.resource::<Progress>().clone();
    let caught = progress.outcome == Outcome::Caught;
    let seconds = engine.steps as f64 / SIMULATION_HZ;
    Ok(Run {
        level: String::new(),
        outcome: if caught {
            RunOutcome::Caught
        } else {
            RunOutcome::Timeout
        },
        seconds,
        shards: progress.shards_taken,
        shards_total: engine
            .world
            .query_filtered::<(), With<Shard>>()
            .iter(&engine.world)
            .count() as u32
            + progress.shards_taken,
        times_seen: progress.times_seen,
        max_gem,
        replans: 0,
        recording: None,
        chokepoints: Vec::new(),
        why: if caught {
            format!("caught, as asked, at {}", crate::game::play_time(seconds))
        } else {
            format!(
                "timeout: not caught after {}",
                crate::game::play_time(seconds)
            )
        },
        route,
        planning_seconds: 0.0,
        playing_seconds: started.elapsed().as_secs_f64(),
        recorded: engine.recording.take().unwrap_or_default(),
        ended: if caught { Ended::Caught } else { Ended::Quit },
    })
}
