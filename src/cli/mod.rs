//! The `gloam` command line: parses arguments and calls into the library. Outside the frame;
//! this is where user errors become one line on stderr: a command line clap refuses names
//! what is missing or wrong and the help to read, and exits 2; a command that runs and
//! fails exits 1.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Context as _;
use clap::{Parser, Subcommand};

use crate::film::FilterMode;
use crate::headless::bench::{convergence, exposure_map, flythrough, frames, raybench};
use crate::scene::files::default_level;
use crate::scene::world::Scene;

#[derive(Debug, Parser)]
#[command(
    name = "gloam",
    version,
    about = "A first-person stealth game path traced on the CPU, and its engine",
    args_conflicts_with_subcommands = true
)]
pub struct Cli {
    /// A level to play at once, as `gloam play LEVEL`.
    pub level: Option<PathBuf>,
    /// Without a command or a level, `gloam` is `gloam play`: the main menu.
    #[command(subcommand)]
    pub command: Option<Command>,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Play a level in a window; with no level, open the main menu (level select, settings,
    /// best times). Default keys: W A S D walk, Shift sprints, Space jumps, C crouches, E
    /// douses or relights the lamp you look at, N toggles noclip, mouse looks after a
    /// click; Esc pauses (resume, restart, settings, main menu, quit), F11 fullscreen, V
    /// vsync, F2 edit the level's file, F3 profiler, F4 film filters, F12 screenshot (PNG and EXR into the pictures
    /// folder's Gloam/, else ~/.local/share/gloam/screenshots). Settings and best times
    /// live in the user's config folder (~/.config/gloam, or $GLOAM_CONFIG_DIR).
    #[command(allow_negative_numbers = true)]
    Play {
        /// The level to play; the menu opens when omitted.
        level: Option<PathBuf>,
        /// The width shown, in pixels (the frame buffer the window scales). The render's
        /// is lower past 640 x 360's pixels and upscaled, and lowered further to hold the
        /// frame-time target.
        #[arg(long, default_value_t = crate::app::DEFAULT_WIDTH, value_parser = crate::headless::values::count())]
        width: u32,
        /// The height shown, in pixels.
        #[arg(long, default_value_t = crate::app::DEFAULT_HEIGHT, value_parser = crate::headless::values::count())]
        height: u32,
        /// Render this many frames, then keep showing the image and print `ready`.
        #[arg(long, value_parser = crate::headless::values::count())]
        frames: Option<u32>,
        /// With --frames: quit this many seconds after the last frame.
        #[arg(long, default_value_t = 0.0, value_parser = crate::headless::values::non_negative, requires = "frames")]
        linger_seconds: f64,
        /// The same frame loop without a window (for --frames frames, default 60); prints
        /// the per-stage table `bench` prints.
        #[arg(long)]
        headless: bool,
        /// Start with the profiler overlay (F3) shown.
        #[arg(long)]
        profiler: bool,
        /// The film's filters (F4 cycles them in the window).
        #[arg(long, value_enum, default_value_t = FilterMode::Full)]
        filter: FilterMode,
        /// Keep the internal resolution fixed instead of adapting it to --target-ms.
        #[arg(long)]
        fixed_resolution: bool,
        /// The frame time the adaptive resolution holds, in milliseconds (default: the
        /// settings' frame-time target, 33.3 until changed).
        #[arg(long, value_parser = crate::headless::values::positive)]
        target_ms: Option<f64>,
        /// Record every step's input of this attempt to FILE (JSON), written when it is
        /// won, caught or quit.
        #[arg(long, value_name = "FILE", conflicts_with = "replay")]
        record: Option<PathBuf>,
        /// Watch a recording play in the window (it names its level), or with --headless
        /// replay it without rendering.
        #[arg(long, value_name = "FILE")]
        replay: Option<PathBuf>,
        /// With --headless --replay: write the per-step report here (JSON).
        #[arg(long, value_name = "FILE", requires_all = ["headless", "replay"])]
        json: Option<PathBuf>,
        /// With --headless --replay: worker threads (the result is the same on any count).
        #[arg(long, value_parser = crate::headless::values::size(), requires_all = ["headless", "replay"])]
        threads: Option<usize>,
        /// With --headless --replay: write the run's sound, as the player heard it, here
        /// (48 kHz stereo 16-bit WAV; the same bytes on any thread count).
        #[arg(long, value_name = "OUT.wav", requires_all = ["headless", "replay"])]
        audio: Option<PathBuf>,
        /// Which vector kernels run: the CPU's best, or the portable ones a CPU without
        /// AVX2 runs (the same bits, so a replay ends at the same state hash).
        #[arg(long, value_enum, default_value_t = crate::simd::Simd::Native)]
        simd: crate::simd::Simd,
    },
    /// Edit a level in a window: the path-traced view with an outline, a palette of assets and
    /// prefabs, an inspector and a gizmo. Keys: click selects, Shift+click adds, a drag draws a
    /// box to select, right mouse + W A S D Q E flies (Shift: faster), W/E/R move/rotate/scale,
    /// F frames the selection, G shows the grid, M measures, Ctrl+1..4 keep the view and 1..4
    /// go back, Delete deletes, Ctrl+D duplicates, Ctrl+C / Ctrl+X / Ctrl+V copy, cut and paste
    /// through the system clipboard (as level text), Ctrl+Z undoes, Ctrl+Shift+Z or Ctrl+Y
    /// redoes, Ctrl+S saves (the previous file kept as LEVEL.bak), F4 switches between the
    /// converging view and the game's 1-spp filtered view, F5 play-tests the level as edited
    /// from the editor's camera (Esc comes back), F6 runs the player bot on the level as edited
    /// and draws how it went (play-check), Esc drops the palette's choice or the selection.
    /// Unsaved edits are autosaved to .LEVEL.autosave beside it every two minutes. `--new`
    /// starts LEVEL from a template instead (File > New level does so in the window).
    #[command(allow_negative_numbers = true)]
    Edit {
        /// The level file to edit.
        level: PathBuf,
        /// Start LEVEL, a file that does not exist yet, from the template (a floor, four
        /// walls, a player start, a way out and a lamp); Ctrl+S writes it.
        #[arg(long)]
        new: bool,
        /// The view's render width, in pixels.
        #[arg(long, default_value_t = crate::app::EDITOR_WIDTH, value_parser = crate::headless::values::count())]
        width: u32,
        /// The render height, in pixels.
        #[arg(long, default_value_t = crate::app::EDITOR_HEIGHT, value_parser = crate::headless::values::count())]
        height: u32,
        /// Quit after this many frames and print the frame times (idle, converging,
        /// dragging).
        #[arg(long, value_parser = crate::headless::values::count())]
        frames: Option<u32>,
    },
    /// Validate a level (.ron) or glTF file: prints `file:line:column: message` per problem,
    /// exit 1 when there are any; otherwise a summary and the load time.
    #[command(allow_negative_numbers = true)]
    Check {
        /// Level or glTF/GLB file.
        #[arg(value_name = "SCENE")]
        path: PathBuf,
    },
    /// Write generated files: the shipped assets, or a stress-test mesh.
    #[command(subcommand)]
    Generate(Generate),
    /// Render a level or glTF file to .exr (linear mean radiance per pixel) or .png (tone
    /// mapped), from the level's camera, the file's first camera, or a view framing it.
    #[command(allow_negative_numbers = true)]
    Render(RenderCommand),
    /// RMSE against a converged render at 1/4/16 spp for the white, stratified and blue
    /// samplers, and path against reference integrator at equal time.
    #[command(allow_negative_numbers = true)]
    Convergence(convergence::Options),
    /// Headless frame-time profile of a level as it is played (the player's view of its
    /// won recording; a scene without a player, a fixed camera path): per-stage mean, p50,
    /// p95, p99 and max; JSON, CSV, Chrome trace and PNG chart reports.
    #[command(allow_negative_numbers = true)]
    Bench(frames::Options),
    /// Fly through a level at 1 spp with a warden patrolling, and print each frame's RMSE
    /// against converged references for the raw frame, temporal filtering, and temporal +
    /// spatial filtering, plus a ghosting measure over the warden's trail.
    #[command(allow_negative_numbers = true)]
    Flythrough(flythrough::Options),
    /// The exposure map: the light gem a player would have standing and crouching on each
    /// floor cell (the game's own exposure rays, lights and wardens' lamps at --time), and
    /// whether a walkable route from the spawn through every shard to the exit stays at or
    /// below --threshold. Writes MAP.png and MAP.json.
    #[command(allow_negative_numbers = true)]
    Exposure(exposure_map::Options),
    /// A player bot plays the level headless, through the player's own input actions,
    /// unseen if it can: it plans through space and time from what a player can watch (the
    /// wardens' beats, the light), collects every shard and leaves. Exit 0 when it won;
    /// otherwise 1, with a line saying why (no unseen route and where it is watched and
    /// lit, caught, or out of time).
    #[command(allow_negative_numbers = true)]
    Autoplay(crate::headless::autoplay::Options),
    /// What ears at a place in a level hear of its looping sound sources, by the level's
    /// own acoustics: a 48 kHz stereo 16-bit WAV (no ambience, no normalisation, so levels
    /// compare between runs) and, with --json, each source's level, whether the way is
    /// blocked, the path's length and where it arrives from, and the room's reverb.
    #[command(allow_negative_numbers = true)]
    Listen {
        /// The level whose sounds are heard.
        level: PathBuf,
        /// Where the ears are, world metres.
        #[arg(long, value_name = "X,Y,Z", value_parser = crate::headless::values::point)]
        at: glam::Vec3,
        /// Which way the ears face, degrees about +Y (0 looks down -Z).
        #[arg(long, default_value_t = 0.0, value_parser = crate::headless::values::finite)]
        facing: f32,
        /// Seconds into the level (wardens walk, gates lift).
        #[arg(long, default_value_t = 0.0, value_parser = crate::headless::values::non_negative)]
        time: f64,
        /// Seconds of sound.
        #[arg(long, default_value_t = 4.0, value_parser = crate::headless::values::positive)]
        seconds: f64,
        /// The WAV file to write.
        #[arg(long, value_name = "OUT.wav")]
        out: PathBuf,
        /// Write the report here.
        #[arg(long, value_name = "OUT.json")]
        json: Option<PathBuf>,
    },
    /// Compare two .exr renders of the same size: mean radiance of each, RMSE, and the
    /// ratio of their means over a 4 x 4 grid of regions (a local bias shows there).
    #[command(allow_negative_numbers = true)]
    Compare {
        /// The image to judge.
        image: PathBuf,
        /// The reference (e.g. a long `--integrator reference` render).
        reference: PathBuf,
    },
    /// Ray throughput (primary, shadow, diffuse bounce) through gloam's TLAS -> BLAS and
    /// through obvhs's flat BVH2 and CWBVH on the same rays; BLAS, TLAS and refit times.
    #[command(allow_negative_numbers = true)]
    Raybench(raybench::Options),
}

#[derive(Debug, Subcommand)]
pub enum Generate {
    /// Regenerate every file under assets/ (src/scene/kit.rs).
    Assets {
        /// Output folder.
        #[arg(long, default_value = "assets")]
        out: PathBuf,
    },
    /// Regenerate every sound under assets/sounds/ (src/scene/sound_kit.rs); the wardens'
    /// voices need espeak-ng.
    Sounds {
        /// Output folder.
        #[arg(long, default_value = "assets/sounds")]
        out: PathBuf,
    },
    /// Write a wavy-grid mesh with at least N triangles, for import timing (or, with
    /// --skinned, a walking warden of at least N triangles, for skinning timing).
    #[command(allow_negative_numbers = true)]
    Stress {
        /// Minimum number of triangles.
        #[arg(long, default_value_t = 1_000_000, value_parser = crate::headless::values::size())]
        triangles: usize,
        /// A skinned, animated warden instead of a static grid.
        #[arg(long)]
        skinned: bool,
        /// Output .glb or .gltf file.
        #[arg(long)]
        out: PathBuf,
    },
}

/// The exit status of a command line clap cannot take (clap's and the BSD sysexits'
/// convention); a command that runs and fails exits 1.
const USAGE_ERROR: u8 = 2;

/// A command line clap refused, in one line that names what is wrong and where to read
/// more: `render needs a SCENE (see `gloam render --help`)`, or clap's own first line
/// (`invalid value 'abc' for '--spp <SPP>': ...`) with the same pointer.
fn usage_error_line(error: &clap::Error) -> String {
    use clap::error::{ContextKind, ContextValue, ErrorKind};
    // "Usage: gloam render [OPTIONS] <SCENE>": the command is the words before the first
    // option or argument.
    let usage = match error.get(ContextKind::Usage) {
        Some(ContextValue::StyledStr(usage)) => usage.to_string(),
        _ => String::new(),
    };
    let command: Vec<&str> = (usage.split_whitespace())
        .skip_while(|word| *word != "gloam")
        .take_while(|word| !word.starts_with(['[', '<', '-']))
        .collect();
    // Errors about a value carry no usage: the subcommands are the words of the command
    // line that name one, each inside the one before (`generate stress`).
    let named = || {
        let mut at = <Cli as clap::CommandFactory>::command();
        let mut path = vec!["gloam".to_string()];
        for word in std::env::args().skip(1) {
            if let Some(inner) = at.find_subcommand(&word).cloned() {
                path.push(word);
                at = inner;
            }
        }
        (path.len() > 1).then(|| path.join(" "))
    };
    let command = match command.is_empty() {
        false => command.join(" "),
        true => named().unwrap_or_else(|| "gloam".to_string()),
    };
    let help = format!("(see `{command} --help`)");
    if error.kind() == ErrorKind::MissingRequiredArgument
        && let Some(ContextValue::Strings(missing)) = error.get(ContextKind::InvalidArg)
    {
        // "<SCENE>" is a SCENE; "--out <OUT>" is --out.
        let named: Vec<String> = missing
            .iter()
            .map(|arg| match arg.strip_prefix('<') {
                Some(value) => format!("a {}", value.trim_end_matches('>')),
                None => arg.split_whitespace().next().unwrap_or(arg).to_string(),
            })
            .collect();
        let verb = command.strip_prefix("gloam ").unwrap_or(&command);
        return format!("{verb} needs {} {help}", named.join(" and "));
    }
    let rendered = error.render().to_string();
    let first_line = rendered.lines().next().unwrap_or("bad command line");
    format!("{} {help}", first_line.trim_start_matches("error: "))
}

/// Runs the command line; the binary's whole `main`.
pub fn main() -> ExitCode {
    // Output piped into a reader that stops early (`gloam check x.ron | head -1`) ends
    // the process quietly, as it does any Unix tool, instead of a panic in `println!`:
    // Rust ignores SIGPIPE by default, which turns the closed pipe into an error there.
    #[cfg(unix)]
    // SAFETY: called first, before any thread is started; SIG_DFL is always valid.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    // What wgpu and winit report (a missing Vulkan driver, a lost surface) goes to stderr:
    // warnings and errors unless RUST_LOG says otherwise (`RUST_LOG=info`, `RUST_LOG=wgpu=debug`).
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or("warn"))
        .format_timestamp(None)
        .init();
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(error) if !error.use_stderr() => {
            // --help and --version.
            let _ = error.print();
            return ExitCode::SUCCESS;
        }
        Err(error) => {
            eprintln!("gloam: {}", usage_error_line(&error));
            return ExitCode::from(USAGE_ERROR);
        }
    };
    // Bare `gloam` is `gloam play` and `gloam LEVEL` is `gloam play LEVEL`, with `play`'s
    // own defaults.
    let command = match (cli.command, cli.level) {
        (Some(command), _) => command,
        (None, level) => {
            let mut args = vec!["gloam".into(), "play".into()];
            if let Some(level) = level {
                if !level.is_file() {
                    eprintln!(
                        "gloam: '{}' is neither a command nor a level file (see `gloam --help`)",
                        level.display()
                    );
                    return ExitCode::from(USAGE_ERROR);
                }
                args.push(level.into_os_string());
            }
            match Cli::try_parse_from(args) {
                Ok(Cli {
                    command: Some(command),
                    ..
                }) => command,
                Ok(_) => return ExitCode::from(USAGE_ERROR),
                Err(error) => {
                    eprintln!("gloam: {}", usage_error_line(&error));
                    return ExitCode::from(USAGE_ERROR);
                }
            }
        }
    };
    match run(command) {
        Ok(code) => code,
        Err(error) => {
            eprintln!("gloam: {error:#}");
            ExitCode::FAILURE
        }
    }
}

fn run(command: Command) -> anyhow::Result<ExitCode> {
    // Only with a profile-with-* feature; a profiler that cannot start is not fatal.
    let _live_profiler = crate::profile::start_live_profiler().unwrap_or_else(|error| {
        eprintln!("gloam: {error:#}; running without the live profiler");
        None
    });
    match command {
        Command::Play {
            level,
            width,
            height,
            frames,
            linger_seconds,
            headless,
            profiler,
            filter,
            fixed_resolution,
            target_ms,
            record,
            replay,
            json,
            threads,
            audio,
            simd,
        } => {
            crate::simd::use_kernels(simd);
            let mut watch = None;
            let mut level = level;
            if let Some(replay) = replay {
                if headless {
                    return replay_command(&replay, json.as_deref(), audio.as_deref(), threads);
                }
                let (recording, recorded_level) = crate::headless::replay::read_recording(&replay)?;
                if let Some(given) = &level
                    && std::fs::canonicalize(given).ok()
                        != std::fs::canonicalize(&recorded_level).ok()
                {
                    anyhow::bail!(
                        "{}: recorded on '{}', not '{}'",
                        replay.display(),
                        recorded_level.display(),
                        given.display()
                    );
                }
                level = Some(recorded_level);
                watch = Some(recording);
            }
            // Only a bare window opens on the menu: scripted runs play the default level.
            let menu = !headless && frames.is_none() && record.is_none();
            let level = match level {
                Some(level) => Some(level),
                None if menu => None,
                None => Some(default_level()),
            };
            crate::app::play(crate::app::PlayOptions {
                level,
                width,
                height,
                frames,
                linger: std::time::Duration::from_secs_f64(linger_seconds.max(0.0)),
                headless,
                profiler,
                filter,
                target_ms: if fixed_resolution {
                    Some(None)
                } else {
                    target_ms.map(Some)
                },
                record,
                watch,
            })?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Edit {
            level,
            new,
            width,
            height,
            frames,
        } => {
            if new {
                // Refused before a window is asked for, so it says so with no display too.
                crate::edit::template::new_scene(&level)?;
            }
            crate::app::editor::edit(crate::app::editor::EditOptions {
                level,
                width,
                height,
                frames,
                new,
            })?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Check { path } => Ok(check(&path)),
        Command::Generate(Generate::Assets { out }) => {
            let files = crate::scene::kit::generate_assets(&out)
                .with_context(|| format!("generating assets into {}", out.display()))?;
            Ok(said_written(&files))
        }
        Command::Generate(Generate::Sounds { out }) => {
            let files = crate::scene::sound_kit::generate_sounds(&out)
                .with_context(|| format!("generating sounds into {}", out.display()))?;
            Ok(said_written(&files))
        }
        Command::Render(command) => {
            render_command(command)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Convergence(options) => {
            convergence::run(&options)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Bench(options) => {
            frames::run(&options, &mut crate::app::HeadlessPresent::new())?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Flythrough(options) => {
            flythrough::run(&options)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Exposure(options) => {
            exposure_map::run(&options)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Listen {
            level,
            at,
            facing,
            time,
            seconds,
            out,
            json,
        } => {
            let scene = Scene::load(&level)?;
            let listening = crate::headless::listen::Listening {
                at,
                facing_degrees: facing,
                time,
                seconds,
            };
            let (report, sound) = crate::headless::listen::listen(&scene, &level, &listening)?;
            let (left, right) = sound.to_pcm();
            let bytes = crate::scene::sound_kit::stereo_wav_bytes(&left, &right);
            crate::scene::files::write_atomically(&out, &bytes)?;
            if let Some(json) = json {
                let text = serde_json::to_string_pretty(&report).context("encoding the report")?;
                crate::scene::files::write_atomically(&json, text.as_bytes())?;
            }
            println!(
                "wrote {} ({seconds} s, {} sources)",
                out.display(),
                report["sources"].as_array().map_or(0, Vec::len)
            );
            Ok(ExitCode::SUCCESS)
        }
        Command::Autoplay(options) => Ok(if crate::headless::autoplay::run(&options)? {
            ExitCode::SUCCESS
        } else {
            ExitCode::FAILURE
        }),
        Command::Compare { image, reference } => {
            compare(&image, &reference)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Raybench(options) => {
            raybench::run(&options)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Generate(Generate::Stress {
            triangles,
            skinned,
            out,
        }) => {
            let written = if skinned {
                crate::scene::kit::write_skinned_stress(&out, triangles)
            } else {
                crate::scene::kit::write_stress_mesh(&out, triangles)
            }
            .with_context(|| format!("writing stress mesh {}", out.display()))?;
            println!("wrote {} ({written} triangles)", out.display());
            Ok(ExitCode::SUCCESS)
        }
    }
}

/// A line for each file a generator wrote.
fn said_written(files: &[PathBuf]) -> ExitCode {
    for file in files {
        println!("wrote {}", file.display());
    }
    ExitCode::SUCCESS
}

/// `gloam play --headless --replay FILE [--json OUT] [--audio OUT.wav] [--threads N]`:
/// the outcome and state hash on stdout, the per-step report in OUT, the run's sound in
/// OUT.wav.
fn replay_command(
    path: &Path,
    json: Option<&Path>,
    audio: Option<&Path>,
    threads: Option<usize>,
) -> anyhow::Result<ExitCode> {
    let threads = threads.unwrap_or_else(crate::headless::bench::default_threads);
    if threads == 0 {
        anyhow::bail!("--threads must be at least 1");
    }
    let report = match audio {
        Some(out) => {
            let (report, sound) = crate::headless::replay::replay_with_sound(path, threads)?;
            let (left, right) = sound.to_pcm();
            let bytes = crate::scene::sound_kit::stereo_wav_bytes(&left, &right);
            crate::scene::files::write_atomically(out, &bytes)?;
            println!(
                "wrote {} ({:.1} s, {:.1} dBFS RMS)",
                out.display(),
                sound.left.len() as f64 / f64::from(crate::scene::sound_kit::RATE),
                sound.rms_dbfs()
            );
            report
        }
        None => crate::headless::replay::replay(path, threads)?,
    };
    if let Some(out) = json {
        let text = serde_json::to_string_pretty(&report).context("encoding the report")?;
        crate::scene::files::write_atomically(out, text.as_bytes())?;
    }
    if let Some(diverged) = crate::headless::replay::divergence(&report) {
        eprintln!("{}", diverged.line(path));
        return Ok(ExitCode::FAILURE);
    }
    println!(
        "{}: {} after {} steps, state hash {}",
        path.display(),
        report["outcome"].as_str().unwrap_or("?"),
        report["steps"].as_array().map_or(0, Vec::len),
        report["state_hash"].as_str().unwrap_or("?")
    );
    if let Some(out) = json {
        println!("wrote {}", out.display());
    }
    Ok(ExitCode::SUCCESS)
}

/// `gloam check`: every problem on its own line, or a one-line summary.
fn check(path: &Path) -> ExitCode {
    let start = Instant::now();
    match Scene::load(path) {
        Ok(scene) => {
            let elapsed_ms = start.elapsed().as_secs_f64() * 1e3;
            let camera = scene.camera().map_or_else(
                || "none (framed from bounds)".to_owned(),
                |c| format!("'{}'", c.name),
            );
            let spawn = scene
                .player_spawn()
                .map_or_else(|| "none".to_owned(), |(feet, _)| format!("{feet}"));
            println!(
                "{}: ok: {} entities, {} assets, {} triangles placed, {} materials, {} punctual lights, camera {camera}, player spawn {spawn}; loaded in {elapsed_ms:.1} ms",
                path.display(),
                scene.level.entities.len(),
                scene.assets.len(),
                scene.triangle_count(),
                scene
                    .assets
                    .iter()
                    .map(|a| a.materials.len())
                    .sum::<usize>(),
                scene.punctual_lights().len(),
            );
            let is_level = path
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("ron"));
            if is_level
                && scene.player_spawn().is_some()
                && !scene.level.entities.iter().any(|e| e.exit.is_some())
            {
                println!(
                    "{}: warning: no exit: the level is a free walk that never ends",
                    path.display()
                );
            }
            ExitCode::SUCCESS
        }
        Err(error) => {
            for diagnostic in &error.diagnostics {
                println!("{diagnostic}");
            }
            eprintln!(
                "gloam: {}: {} problem(s)",
                path.display(),
                error.diagnostics.len()
            );
            ExitCode::FAILURE
        }
    }
}

/// `gloam render`'s flags.
#[derive(Debug, clap::Args)]
pub struct RenderCommand {
    /// Level or glTF/GLB file.
    pub scene: PathBuf,
    /// Output .exr or .png.
    #[arg(long)]
    pub out: PathBuf,
    /// The render width, in pixels.
    #[arg(long, default_value_t = 640, value_parser = crate::headless::values::count())]
    pub width: u32,
    /// The render height, in pixels.
    #[arg(long, default_value_t = 360, value_parser = crate::headless::values::count())]
    pub height: u32,
    /// Samples per pixel.
    #[arg(long, default_value_t = 64, value_parser = crate::headless::values::count())]
    pub spp: u32,
    /// The sampler's seed: another seed draws other samples (the same image on any thread count).
    #[arg(long, default_value_t = 0, value_parser = crate::headless::values::count_or_zero())]
    pub seed: u32,
    /// The integrator.
    #[arg(long, value_enum, default_value_t = crate::render::IntegratorKind::Path)]
    pub integrator: crate::render::IntegratorKind,
    /// Stratified by default: at 4 spp and more it has the lowest RMSE of the three
    /// (`gloam convergence`); blue noise pays off at 1-2 spp, where its error is blue.
    #[arg(long, value_enum, default_value_t = crate::render::SamplerKind::Stratified)]
    pub sampler: crate::render::SamplerKind,
    /// Bounces at most (0: emitters only, 1: direct lighting, ...).
    #[arg(long, default_value_t = 8, value_parser = crate::headless::values::count_or_zero())]
    pub max_depth: u32,
    /// Exposure multiplier for .png output (ignored for .exr).
    #[arg(long, default_value_t = 1.0, value_parser = crate::headless::values::positive_f32)]
    pub exposure: f32,
    /// Seconds after level start: animation clips and deformers are posed there.
    #[arg(long, default_value_t = 0.0, value_parser = crate::headless::values::non_negative)]
    pub time: f64,
}

/// `gloam render`: load, extract, render with a progress bar on a terminal, write.
fn render_command(command: RenderCommand) -> anyhow::Result<()> {
    use crate::render::{Camera, RenderSettings, render};

    // Refuse a bad output name before spending minutes rendering.
    let extension = command
        .out
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    if !matches!(extension.as_deref(), Some("exr" | "png")) {
        anyhow::bail!(
            "{}: the output must end in .exr or .png",
            command.out.display()
        );
    }
    if !command.time.is_finite() {
        anyhow::bail!("--time must be a finite number of seconds");
    }
    let scene = Scene::load(&command.scene)?;
    let settings = RenderSettings {
        width: command.width,
        height: command.height,
        spp: command.spp,
        seed: command.seed,
        frame: 0,
        integrator: command.integrator,
        sampler: command.sampler,
        max_depth: command.max_depth,
    };
    // The game's own path to a posed scene: skinning, morphs and deformers at --time.
    let mut engine = crate::frame::Engine::new(&scene, RenderSettings::real_time(1, 1));
    engine.pose_at(command.time);
    let render_scene = engine.render_scene();
    let camera = Camera::new(&render_scene.camera, settings.width, settings.height);
    // Per mille of the image's samples.
    let bar = crate::headless::bench::progress::bar(1000, "rendering");
    let progress = |fraction: f32| bar.set_position((fraction * 1000.0) as u64);
    let output = render(render_scene, &camera, &settings, &progress);
    bar.finish_and_clear();
    output.image.write(&command.out, command.exposure)?;
    println!(
        "wrote {}: {}x{}, {} spp, {:?} integrator, {} sampler, camera '{}'; {:.2} s, {:.2} Mrays/s ({} camera, {} bounce, {} shadow rays){}",
        command.out.display(),
        settings.width,
        settings.height,
        settings.spp,
        settings.integrator,
        settings.sampler.name(),
        render_scene.camera.name,
        output.seconds,
        output.mrays_per_second(),
        output.rays.camera,
        output.rays.bounce,
        output.rays.shadow,
        if output.invalid_samples > 0 {
            format!("; {} NaN/inf samples dropped", output.invalid_samples)
        } else {
            String::new()
        },
    );
    Ok(())
}

/// `gloam compare`.
fn compare(image: &Path, reference: &Path) -> anyhow::Result<()> {
    let (a, b) = (
        crate::render::HdrImage::read_exr(image)?,
        crate::render::HdrImage::read_exr(reference)?,
    );
    let comparison = a
        .compare(&b)
        .with_context(|| format!("comparing {} with {}", image.display(), reference.display()))?;
    print!(
        "{}",
        comparison.report(
            &image.display().to_string(),
            &reference.display().to_string()
        )
    );
    Ok(())
}
