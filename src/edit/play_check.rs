//! The play-check: the player bot (`headless::autoplay`) plays the level as edited, on a
//! thread of its own so the editor's view stays live, and answers whether the level can be
//! finished unseen: won in m:ss with the route it walked, caught and where, or no unseen
//! route with the lit chokepoints that block it. The editor's window starts one on F6 and
//! draws the answer over its view; a check belongs to the level it was asked of, so an
//! edit made since marks it as out of date rather than hiding it.

use std::path::{Path, PathBuf};
use std::sync::mpsc::{Receiver, TryRecvError};
use std::time::Instant;

use glam::Vec3;

use crate::headless::autoplay::{DEFAULT_MAX_SECONDS, RunOutcome, autoplay};
use crate::scene::Scene;
use crate::scene::level::Level;

/// What the bot did on one version of the level.
#[derive(Clone, Debug)]
pub struct Checked {
    /// The level as it was checked.
    pub level: Level,
    pub outcome: RunOutcome,
    /// Times the bot was seen (a won check with none was won unseen).
    pub times_seen: u32,
    /// The bot's one line: "won unseen in 1:09.8 ...", "caught at (x, z) ...", or why there
    /// is no unseen route.
    pub line: String,
    /// The feet, every step of the run (empty when it never set out).
    pub route: Vec<Vec3>,
    /// The lit places with no way round (a `no_route` outcome).
    pub chokepoints: Vec<Vec3>,
    /// Wall-clock seconds the check took.
    pub seconds: f64,
}

impl Checked {
    /// Won, unseen, with every shard: the level is proven fair.
    pub fn proven(&self) -> bool {
        self.outcome == RunOutcome::Won && self.times_seen == 0
    }

    /// The outcome in a few words, for a button's side.
    pub fn summary(&self) -> String {
        let seconds = self.route.len() as f64 / crate::game::SIMULATION_HZ;
        match self.outcome {
            RunOutcome::Won if self.times_seen == 0 => {
                format!("won unseen in {}", crate::game::play_time(seconds))
            }
            RunOutcome::Won => format!("won, but seen {} times", self.times_seen),
            RunOutcome::Caught => "caught (ringed)".into(),
            RunOutcome::NoRoute if self.chokepoints.is_empty() => "no unseen route".into(),
            RunOutcome::NoRoute => format!(
                "no unseen route: {} lit chokepoint(s) ringed",
                self.chokepoints.len()
            ),
            RunOutcome::Timeout => "timeout".into(),
        }
    }

    /// Where the bot was caught.
    pub fn caught_at(&self) -> Option<Vec3> {
        (self.outcome == RunOutcome::Caught)
            .then(|| self.route.last().copied())
            .flatten()
    }
}

/// A check under way or done, as the editor holds it.
#[derive(Default)]
pub struct PlayCheck {
    running: Option<(Receiver<Result<Checked, String>>, Instant)>,
    /// The last check's answer, or why it could not run (a level that does not load, no
    /// player start).
    pub last: Option<Result<Checked, String>>,
}

impl PlayCheck {
    /// Starts the bot on `level` (its asset paths relative to `path`'s folder) unless a
    /// check is running; says what happened in one line.
    pub fn start(&mut self, level: Level, path: &Path) -> String {
        if let Some((_, started)) = &self.running {
            return format!(
                "play-check: already playing ({:.0} s so far)",
                started.elapsed().as_secs_f64()
            );
        }
        let (sender, receiver) = std::sync::mpsc::channel();
        let path = path.to_path_buf();
        let spawned = std::thread::Builder::new()
            .name("play-check".into())
            .spawn(move || {
                let _ = sender.send(check(level, path));
            });
        match spawned {
            Ok(_) => {
                self.running = Some((receiver, Instant::now()));
                "play-check: the bot is playing the level as edited".into()
            }
            Err(error) => format!("play-check: cannot start its thread: {error}"),
        }
    }

    /// Seconds the running check has taken so far (None: none running).
    pub fn running_for(&self) -> Option<f64> {
        self.running
            .as_ref()
            .map(|(_, started)| started.elapsed().as_secs_f64())
    }

    /// Takes a finished check's answer (then kept as `last`) and returns its line, once.
    pub fn poll(&mut self) -> Option<String> {
        let (receiver, _) = self.running.as_ref()?;
        let answer = match receiver.try_recv() {
            Ok(answer) => answer,
            Err(TryRecvError::Empty) => return None,
            Err(TryRecvError::Disconnected) => Err("the bot stopped without an answer".into()),
        };
        self.running = None;
        let line = match &answer {
            Ok(checked) => format!("play-check: {} ({:.0} s)", checked.line, checked.seconds),
            Err(problem) => format!("play-check: {problem}"),
        };
        self.last = Some(answer);
        Some(line)
    }

    /// Waits for the running check (for tests and scripts); its line, as `poll`.
    pub fn wait(&mut self) -> Option<String> {
        while self.running.is_some() {
            if let Some(line) = self.poll() {
                return Some(line);
            }
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
        None
    }

    /// The last check's answer, when it ran.
    pub fn checked(&self) -> Option<&Checked> {
        self.last.as_ref().and_then(|answer| answer.as_ref().ok())
    }

    /// The check under way or the last one in a few words (empty: none yet), and whether
    /// the level has been edited since that one ran (`current`: the level as it stands).
    pub fn status(&self, current: &Level) -> (String, bool) {
        if let Some(seconds) = self.running_for() {
            return (format!("playing... {seconds:.0} s"), false);
        }
        match &self.last {
            None => (String::new(), false),
            Some(Err(problem)) => (format!("could not play: {problem}"), false),
            Some(Ok(checked)) if checked.level != *current => {
                (format!("{} (edited since)", checked.summary()), true)
            }
            Some(Ok(checked)) => (checked.summary(), false),
        }
    }
}

/// The bot on `level`, on one worker thread: the view keeps the others, and the run is the
/// same on any thread count.
fn check(level: Level, path: PathBuf) -> Result<Checked, String> {
    let started = Instant::now();
    let scene = Scene::from_level(level.clone(), &path).map_err(|error| error.to_string())?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .map_err(|error| format!("cannot start its worker: {error}"))?;
    let run = pool
        .install(|| autoplay(&scene, DEFAULT_MAX_SECONDS))
        .map_err(|error| format!("{error:#}"))?;
    Ok(Checked {
        level,
        outcome: run.outcome,
        times_seen: run.times_seen,
        line: run.why,
        route: run.route,
        chokepoints: run.chokepoints.iter().map(|c| c.at).collect(),
        seconds: started.elapsed().as_secs_f64(),
    })
}
