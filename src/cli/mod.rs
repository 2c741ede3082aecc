//! The `gloam` command line: parses arguments and calls into the library. Outside the frame;
//! this is where user errors become one line on stderr and exit status 1.

mod raybench;

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Context as _;
use clap::{Parser, Subcommand};

use crate::scene::world::Scene;

#[derive(Debug, Parser)]
#[command(
    name = "gloam",
    version,
    about = "A first-person stealth game path traced on the CPU, and its engine"
)]
pub struct Cli {
    /// Without a command, `gloam` will play the default level once the real-time shell
    /// lands; today it prints this help.
    #[command(subcommand)]
    pub command: Option<Command>,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Validate a level (.ron) or glTF file: prints `file:line:column: message` per problem,
    /// exit 1 when there are any; otherwise a summary and the load time.
    Check {
        /// Level or glTF/GLB file.
        path: PathBuf,
    },
    /// Write generated files: the shipped assets, or a stress-test mesh.
    #[command(subcommand)]
    Generate(Generate),
    /// Ray throughput (primary, shadow, diffuse bounce) through gloam's TLAS -> BLAS and
    /// through obvhs's flat BVH2 and CWBVH on the same rays; BLAS, TLAS and refit times.
    Raybench {
        /// Level or glTF/GLB file (its camera; emissive triangles are the shadow-ray targets).
        scene: PathBuf,
        /// Repeat the scene's instances in a grid until there are N.
        #[arg(long)]
        instances: Option<usize>,
        /// Add a deforming grid of at least M triangles and time its per-frame refit.
        #[arg(long, default_value_t = 0)]
        deforming_triangles: usize,
        /// Threads for the multi-threaded measurement (one thread is always measured).
        #[arg(long, default_value_t = default_threads())]
        threads: usize,
        /// Primary rays per side (size x size).
        #[arg(long, default_value_t = 512)]
        size: u32,
        /// Timed runs per measurement; medians are reported.
        #[arg(long, default_value_t = 5)]
        repeats: usize,
        /// Write the report as JSON.
        #[arg(long)]
        json: Option<PathBuf>,
    },
}

fn default_threads() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

#[derive(Debug, Subcommand)]
pub enum Generate {
    /// Regenerate every file under assets/ from the code in src/scene/kit.rs.
    Assets {
        /// Output folder.
        #[arg(long, default_value = "assets")]
        out: PathBuf,
    },
    /// Write a wavy-grid mesh with at least N triangles, for import timing.
    Stress {
        /// Minimum number of triangles.
        #[arg(long, default_value_t = 1_000_000)]
        triangles: usize,
        /// Output .glb or .gltf file.
        #[arg(long)]
        out: PathBuf,
    },
}

/// Runs the command line; the binary's whole `main`.
pub fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(error) if !error.use_stderr() => {
            // --help and --version.
            let _ = error.print();
            return ExitCode::SUCCESS;
        }
        Err(error) => {
            let rendered = error.render().to_string();
            let first_line = rendered.lines().next().unwrap_or("bad command line");
            eprintln!(
                "gloam: {} (see `gloam --help`)",
                first_line.trim_start_matches("error: ")
            );
            return ExitCode::FAILURE;
        }
    };
    let Some(command) = cli.command else {
        use clap::CommandFactory as _;
        let _ = Cli::command().print_help();
        return ExitCode::SUCCESS;
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
    match command {
        Command::Check { path } => Ok(check(&path)),
        Command::Generate(Generate::Assets { out }) => {
            let files = crate::scene::kit::generate_assets(&out)
                .with_context(|| format!("generating assets into {}", out.display()))?;
            for file in &files {
                println!("wrote {}", file.display());
            }
            Ok(ExitCode::SUCCESS)
        }
        Command::Raybench {
            scene,
            instances,
            deforming_triangles,
            threads,
            size,
            repeats,
            json,
        } => {
            raybench::run(&raybench::Options {
                scene,
                instances,
                deforming_triangles,
                threads,
                size,
                repeats,
                json,
            })?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Generate(Generate::Stress { triangles, out }) => {
            let written = crate::scene::kit::write_stress_mesh(&out, triangles)
                .with_context(|| format!("writing stress mesh {}", out.display()))?;
            println!("wrote {} ({written} triangles)", out.display());
            Ok(ExitCode::SUCCESS)
        }
    }
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
