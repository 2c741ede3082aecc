//! The `gloam` binary as a user meets it: exit codes, one-line errors, no panics.

mod common;

use std::process::{Command, Output};

fn gloam(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_gloam"))
        .args(args)
        .current_dir(common::repo())
        .output()
        .expect("run gloam")
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

#[test]
fn check_accepts_the_shipped_levels() {
    for level in ["levels/cornell.ron", "levels/first-light.ron"] {
        let output = gloam(&["check", level]);
        assert!(
            output.status.success(),
            "{level}: {}{}",
            text(&output.stdout),
            text(&output.stderr)
        );
        assert!(
            text(&output.stdout).contains(": ok:"),
            "{}",
            text(&output.stdout)
        );
    }
}

#[test]
fn check_lists_problems_and_exits_1() {
    let dir = common::scratch_dir("cli-check");
    let level = common::write(
        &dir,
        "broken.ron",
        "(\n    version: 1,\n    entities: [\n        (name: \"a\", transform: (scale: (1.0, -1.0, 1.0))),\n    ],\n)\n",
    );
    let output = gloam(&["check", level.to_str().unwrap()]);
    assert_eq!(output.status.code(), Some(1));
    let stdout = text(&output.stdout);
    assert!(stdout.contains("broken.ron:4:"), "{stdout}");
    assert!(stdout.contains("scale must be positive"), "{stdout}");
    assert!(stdout.contains("no player spawn"), "{stdout}");
    assert!(!text(&output.stderr).contains("panicked"));
}

/// A command line clap refuses is a usage error: one line, exit 2 (clap's and sysexits'
/// convention); a command that runs and finds its input wrong is a failure: exit 1.
#[test]
fn bad_flags_are_one_line_usage_errors_and_failed_runs_exit_1() {
    for (args, code) in [
        (&["check"][..], 2),
        (&["--frobnicate"], 2),
        (&["check", "a", "b"], 2),
        (
            &[
                "generate",
                "stress",
                "--triangles",
                "many",
                "--out",
                "x.glb",
            ],
            2,
        ),
        (
            &[
                "play",
                "--replay",
                "tests/recordings/first-light-won.json",
                "--record",
                "x.json",
            ],
            2,
        ),
        (&["play", "levels/first-light.ron", "--json", "x.json"], 2),
        (&["play", "--replay", "x.json", "--threads", "2"], 2),
        (&["play", "--linger-seconds", "2"], 2),
        (&["flythrough", "--alpha-min", "0"], 2),
        (
            &[
                "exposure",
                "levels/first-light.ron",
                "--cell",
                "0",
                "--out",
                "x.png",
                "--json",
                "x.json",
            ],
            2,
        ),
        (&["exposure", "levels/first-light.ron", "--out", "x.png"], 2),
        (
            &["play", "--headless", "--replay", "no-such-replay.json"],
            1,
        ),
    ] {
        let output = gloam(args);
        assert_eq!(output.status.code(), Some(code), "{args:?}");
        let stderr = text(&output.stderr);
        assert_eq!(stderr.trim_end().lines().count(), 1, "{args:?}: {stderr}");
        assert!(stderr.starts_with("gloam: "), "{stderr}");
    }
    assert!(gloam(&["--help"]).status.success());
}

#[test]
fn a_missing_argument_is_named_with_the_help_to_read() {
    for (args, line) in [
        (
            &["render"][..],
            "gloam: render needs --out and a SCENE (see `gloam render --help`)",
        ),
        (
            &["exposure", "levels/first-light.ron", "--out", "x.png"],
            "gloam: exposure needs --json (see `gloam exposure --help`)",
        ),
        (
            &["check"],
            "gloam: check needs a SCENE (see `gloam check --help`)",
        ),
    ] {
        let output = gloam(args);
        assert_eq!(output.status.code(), Some(2), "{args:?}");
        assert_eq!(text(&output.stderr).trim_end(), line, "{args:?}");
    }
    // A bad value names its flag and points to its own command's help.
    let output = gloam(&[
        "generate",
        "stress",
        "--triangles",
        "many",
        "--out",
        "x.glb",
    ]);
    let stderr = text(&output.stderr);
    assert!(
        stderr.contains("'--triangles <TRIANGLES>'")
            && stderr
                .trim_end()
                .ends_with("(see `gloam generate stress --help`)"),
        "{stderr}"
    );
}

#[test]
fn numbers_out_of_range_name_the_flag_and_the_range() {
    for (args, flag, range) in [
        (
            &[
                "render",
                "levels/cornell.ron",
                "--out",
                "x.png",
                "--spp",
                "-3",
            ][..],
            "--spp",
            "1..=",
        ),
        (&["bench", "--width", "0"], "--width", "1..="),
        (&["play", "--target-ms", "-1"], "--target-ms", "above 0"),
        (
            &[
                "exposure",
                "levels/first-light.ron",
                "--threshold",
                "2",
                "--out",
                "x.png",
                "--json",
                "x.json",
            ],
            "--threshold",
            "between 0 and 1",
        ),
        (
            &["raybench", "levels/cornell.ron", "--threads", "0"],
            "--threads",
            "1..",
        ),
    ] {
        let output = gloam(args);
        assert_eq!(output.status.code(), Some(2), "{args:?}");
        let stderr = text(&output.stderr);
        assert_eq!(stderr.trim_end().lines().count(), 1, "{args:?}: {stderr}");
        assert!(
            stderr.contains(flag) && stderr.contains(range),
            "{args:?}: {stderr}"
        );
    }
}

#[test]
fn a_misspelt_command_is_named_as_neither_a_command_nor_a_level() {
    let output = gloam(&["rendr"]);
    assert_eq!(output.status.code(), Some(2));
    let stderr = text(&output.stderr);
    assert_eq!(
        stderr.trim_end(),
        "gloam: 'rendr' is neither a command nor a level file (see `gloam --help`)"
    );
}

#[cfg(unix)]
#[test]
fn output_into_a_closed_pipe_ends_quietly() {
    use std::os::unix::process::ExitStatusExt as _;
    let dir = common::scratch_dir("cli-pipe");
    // The reader is gone before the first line is written.
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_gloam"))
        .args(["generate", "assets", "--out"])
        .arg(&dir)
        .stdout(writer)
        .current_dir(common::repo())
        .output()
        .unwrap();
    let stderr = text(&output.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert_eq!(
        output.status.signal(),
        Some(13),
        "SIGPIPE, as any Unix tool"
    );
}

#[test]
fn stress_mesh_generates_and_checks() {
    let dir = common::scratch_dir("cli-stress");
    let out = dir.join("stress.glb");
    let output = gloam(&[
        "generate",
        "stress",
        "--triangles",
        "5000",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(output.status.success(), "{}", text(&output.stderr));
    let output = gloam(&["check", out.to_str().unwrap()]);
    assert!(output.status.success(), "{}", text(&output.stdout));
}

#[test]
fn unwritable_output_is_an_error_not_a_panic() {
    let output = gloam(&[
        "generate",
        "stress",
        "--triangles",
        "10",
        "--out",
        "/proc/gloam-cannot-write-here/x.glb",
    ]);
    assert_eq!(output.status.code(), Some(1));
    let stderr = text(&output.stderr);
    assert!(
        stderr.contains("x.glb") && !stderr.contains("panicked"),
        "{stderr}"
    );
}

#[test]
fn check_accepts_the_shared_samples() {
    let Some(samples) = common::shared("gltf-samples") else {
        return;
    };
    let Some(scenes) = common::shared("scenes") else {
        return;
    };
    let mut files = vec![scenes.join("dream-apartment.glb")];
    for model in std::fs::read_dir(samples)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_dir())
    {
        for variant in std::fs::read_dir(&model)
            .unwrap()
            .map(|e| e.unwrap().path())
        {
            files.extend(
                std::fs::read_dir(&variant)
                    .unwrap()
                    .map(|e| e.unwrap().path())
                    .filter(|p| p.extension().is_some_and(|e| e == "gltf" || e == "glb")),
            );
        }
    }
    assert!(files.len() >= 10);
    for file in files {
        let output = gloam(&["check", file.to_str().unwrap()]);
        assert!(
            output.status.success(),
            "{}: {}",
            file.display(),
            text(&output.stdout)
        );
    }
}

#[test]
fn convergence_prints_how_blue_whole_paths_are() {
    let output = gloam(&[
        "convergence",
        "levels/cornell.ron",
        "--width",
        "32",
        "--height",
        "32",
        "--reference-spp",
        "64",
        "--seeds",
        "2",
        "--max-depth",
        "64",
    ]);
    assert!(
        output.status.success(),
        "{}{}",
        text(&output.stdout),
        text(&output.stderr)
    );
    let stdout = text(&output.stdout);
    let line = stdout
        .lines()
        .find(|line| line.starts_with("blue noise over whole paths"))
        .unwrap_or_else(|| panic!("no whole-path line in: {stdout}"));
    let ratio: f64 = line
        .rsplit("= ")
        .next()
        .and_then(|ratio| ratio.trim().parse().ok())
        .unwrap_or_else(|| panic!("no ratio in: {line}"));
    // Blue noise puts less of its error at low frequencies than white noise (where the eye
    // and the filters see it): measured 0.735 here, with these two seeds.
    assert!(ratio > 0.0 && ratio < 0.9, "{line}");
}

#[test]
fn raybench_writes_the_documented_json() {
    let dir = common::scratch_dir("cli-raybench");
    let json = dir.join("nested/raybench.json");
    let output = gloam(&[
        "raybench",
        "levels/cornell.ron",
        "--size",
        "48",
        "--repeats",
        "1",
        "--threads",
        "2",
        "--instances",
        "20",
        "--deforming-triangles",
        "2000",
        "--json",
        json.to_str().unwrap(),
    ]);
    assert!(
        output.status.success(),
        "{}{}",
        text(&output.stdout),
        text(&output.stderr)
    );
    let stdout = text(&output.stdout);
    assert!(
        stdout.contains("gloam / obvhs flat"),
        "the table shows the ratios: {stdout}"
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    for key in [
        "primary_mrays_per_s",
        "shadow_mrays_per_s",
        "diffuse_mrays_per_s",
        "tlas_build_ms",
        "blas_refit_ms",
    ] {
        assert!(
            report[key].as_f64().is_some_and(|v| v > 0.0),
            "{key}: {}",
            report[key]
        );
    }
    assert_eq!(
        report["instances"], 21,
        "20 scene instances plus the deforming grid"
    );
    // The Cornell box places 8 meshes (32 triangles): 20 instances are 2.5 boxes.
    assert!(report["triangles"].as_u64().unwrap() >= 2 * 32 + 2000);
    for ray_type in ["primary", "shadow", "diffuse"] {
        let key = format!("{ray_type}_mrays_per_s");
        assert!(
            report["baseline_obvhs_bvh2"][&key]
                .as_f64()
                .is_some_and(|v| v > 0.0),
            "baseline {key}"
        );
        for layout in [
            "gloam_renderer",
            "gloam_packets",
            "gloam_packets_portable",
            "gloam_tlas_blas_wide8",
            "gloam_tlas_blas_wide8_portable",
            "gloam_tlas_blas_bvh2",
            "obvhs_bvh2_flat",
            "wide8_flat",
            "obvhs_cwbvh_flat",
        ] {
            for threads in ["threads_1", "threads_2"] {
                assert!(
                    report["layouts"][layout][threads][&key].as_f64().is_some(),
                    "{layout} {threads} {key}"
                );
            }
        }
    }
    // One shadow ray (to the box's light) and one bounce per primary hit; the classic
    // Cornell view's edge pixels look just past the box (half-angle 19.65 vs 19.16 degrees).
    assert_eq!(report["rays"]["primary"], 48 * 48);
    assert_eq!(report["rays"]["shadow"], report["rays"]["diffuse"]);
    assert!(report["rays"]["shadow"].as_u64().unwrap() > 48 * 48 * 9 / 10);
    assert_eq!(report["agreement_with_baseline"], 1.0);
    assert_eq!(report["deforming"]["frames"], 30);
}

#[test]
fn raybench_bad_input_is_one_line() {
    for (args, code) in [
        (&["raybench", "levels/nowhere.ron"][..], 1),
        (&["raybench", "levels/cornell.ron", "--size", "0"], 2),
    ] {
        let output = gloam(args);
        assert_eq!(output.status.code(), Some(code), "{args:?}");
        let stderr = text(&output.stderr);
        assert_eq!(stderr.trim_end().lines().count(), 1, "{stderr}");
        assert!(!stderr.contains("panicked"));
    }
}

#[test]
fn render_writes_png_and_exr_and_refuses_bad_output() {
    let dir = common::scratch_dir("cli-render");
    for name in ["cornell.png", "cornell.exr"] {
        let out = dir.join(name);
        let output = gloam(&[
            "render",
            "levels/cornell.ron",
            "--out",
            out.to_str().unwrap(),
            "--width",
            "32",
            "--height",
            "24",
            "--spp",
            "4",
        ]);
        assert!(
            output.status.success(),
            "{}{}",
            text(&output.stdout),
            text(&output.stderr)
        );
        let image = image::open(&out).unwrap();
        assert_eq!((image.width(), image.height()), (32, 24));
    }
    // The EXR holds linear radiance: the Cornell light (17, 12, 4) is seen directly near
    // the top centre, so some pixel is brighter than any PNG could store.
    let exr = image::open(dir.join("cornell.exr")).unwrap().into_rgb32f();
    assert!(
        exr.pixels().any(|p| p.0[0] > 2.0),
        "no super-white radiance in the EXR"
    );
    // Bad output names fail fast with one line, and nothing is written.
    let bad = dir.join("cornell.jpg");
    let output = gloam(&[
        "render",
        "levels/cornell.ron",
        "--out",
        bad.to_str().unwrap(),
    ]);
    assert_eq!(output.status.code(), Some(1));
    assert_eq!(
        text(&output.stderr).trim_end().lines().count(),
        1,
        "{}",
        text(&output.stderr)
    );
    assert!(!bad.exists());
    let output = gloam(&[
        "render",
        "levels/missing.ron",
        "--out",
        dir.join("x.png").to_str().unwrap(),
    ]);
    assert_eq!(output.status.code(), Some(1));
}

#[test]
fn generate_assets_reproduces_the_committed_assets() {
    let dir = common::scratch_dir("cli-generate");
    let output = gloam(&["generate", "assets", "--out", dir.to_str().unwrap()]);
    assert!(output.status.success(), "{}", text(&output.stderr));
    for relative in [
        "cornell/cornell-box.gltf",
        "cornell/cornell-box.bin",
        "kit/floor.glb",
        "kit/shard.glb",
    ] {
        let generated = std::fs::read(dir.join(relative)).unwrap();
        let committed = std::fs::read(common::repo().join("assets").join(relative)).unwrap();
        assert!(
            generated == committed,
            "{relative} differs from the committed asset"
        );
    }
}

/// `listen` writes a 48 kHz stereo WAV of the asked length and the documented report; a
/// place that is not X,Y,Z is one line naming the flag.
#[test]
fn listen_writes_a_stereo_wav_and_its_report() {
    let dir = common::scratch_dir("cli-listen");
    let (wav, json) = (dir.join("ears.wav"), dir.join("ears.json"));
    let output = gloam(&[
        "listen",
        "levels/first-light.ron",
        "--at",
        "0,1.6,0",
        "--seconds",
        "0.5",
        "--out",
        wav.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
    ]);
    assert!(output.status.success(), "{}", text(&output.stderr));
    let bytes = std::fs::read(&wav).unwrap();
    assert_eq!(&bytes[22..24], &2u16.to_le_bytes(), "stereo");
    assert_eq!(&bytes[24..28], &48_000u32.to_le_bytes());
    assert_eq!(bytes.len(), 44 + 24_000 * 4);
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert!(report["sources"].is_array());
    assert!(report["reverb"]["decay_s"].as_f64().unwrap() > 0.0);
    assert!(report["reverb"]["wet_db"].is_f64());
    let bad = gloam(&[
        "listen",
        "levels/first-light.ron",
        "--at",
        "0,1.6",
        "--out",
        "x.wav",
    ]);
    assert_eq!(bad.status.code(), Some(2), "a bad value is a usage error");
    let stderr = text(&bad.stderr);
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.contains("--at") && stderr.contains("X,Y,Z"),
        "{stderr}"
    );
}

/// `generate sounds` with no espeak-ng on the PATH still writes every synthesised sound,
/// keeps the voices already there, and says in one line what it could not do.
#[test]
fn generate_sounds_without_espeak_keeps_the_voices_and_says_so() {
    let dir = common::scratch_dir("cli-generate-sounds");
    let kept = b"the voice as it was";
    std::fs::write(dir.join("warden-alarm.wav"), kept).unwrap();
    let output = Command::new(env!("CARGO_BIN_EXE_gloam"))
        .args(["generate", "sounds", "--out", dir.to_str().unwrap()])
        .env("PATH", "")
        .output()
        .unwrap();
    assert_eq!(output.status.code(), Some(1));
    let stderr = text(&output.stderr);
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.contains("espeak-ng is not installed"), "{stderr}");
    assert_eq!(std::fs::read(dir.join("warden-alarm.wav")).unwrap(), kept);
    for name in ["step-stone-walk-1.wav", "lamp-hum.wav", "bottle-break.wav"] {
        let generated = std::fs::read(dir.join(name)).unwrap();
        let committed = std::fs::read(common::repo().join("assets/sounds").join(name)).unwrap();
        assert!(
            generated == committed,
            "{name} differs from the committed sound"
        );
    }
}

#[test]
fn a_replay_runs_headless_and_writes_its_report() {
    let dir = common::scratch_dir("cli-replay");
    let out = dir.join("report.json");
    let output = gloam(&[
        "play",
        "--headless",
        "--replay",
        "tests/recordings/first-light-won.json",
        "--json",
        out.to_str().unwrap(),
        "--threads",
        "1",
    ]);
    assert!(output.status.success(), "{}", text(&output.stderr));
    assert!(
        text(&output.stdout).contains("won after"),
        "{}",
        text(&output.stdout)
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    assert_eq!(report["outcome"], "won");
    assert_eq!(report["state_hash"].as_str().unwrap().len(), 16);
    // And bench profiles the same play-through.
    let output = gloam(&[
        "bench",
        "--replay",
        "tests/recordings/first-light-won.json",
        "--frames",
        "4",
        "--warmup",
        "1",
        "--width",
        "16",
        "--height",
        "16",
    ]);
    assert!(output.status.success(), "{}", text(&output.stderr));
    assert!(
        text(&output.stdout).contains("4 frames of"),
        "{}",
        text(&output.stdout)
    );
    let output = gloam(&[
        "bench",
        "levels/cornell.ron",
        "--replay",
        "tests/recordings/first-light-won.json",
    ]);
    assert_eq!(output.status.code(), Some(1));
    assert!(
        text(&output.stderr).contains("was recorded on"),
        "{}",
        text(&output.stderr)
    );
}

/// Every flag and argument of every command says what it is in `--help`, and a level
/// argument is called LEVEL (or SCENE where a glTF file is taken too).
#[test]
fn every_argument_has_help_and_a_conventional_name() {
    use clap::CommandFactory as _;
    fn walk(command: &clap::Command, path: &str, found: &mut Vec<String>, positionals: &mut usize) {
        for arg in command.get_arguments() {
            let id = arg.get_id().as_str();
            if matches!(id, "help" | "version") {
                continue;
            }
            if arg.get_help().is_none() && arg.get_long_help().is_none() {
                found.push(format!("{path}: {id} has no help text"));
            }
            if arg.is_positional() {
                let name = match arg.get_value_names() {
                    Some([name, ..]) => name.to_string(),
                    _ => id.to_uppercase(),
                };
                // `compare` takes two images; every other positional is a level or scene.
                let images = path == "gloam compare" && matches!(id, "image" | "reference");
                if !images && !matches!(name.as_str(), "LEVEL" | "SCENE") {
                    found.push(format!("{path}: <{name}> is neither LEVEL nor SCENE"));
                }
                if name == "LEVEL"
                    && arg
                        .get_help()
                        .is_some_and(|h| h.to_string().contains("glTF"))
                {
                    found.push(format!("{path}: <LEVEL> takes glTF too, so it is a SCENE"));
                }
                *positionals += 1;
            }
        }
        for sub in command.get_subcommands() {
            walk(
                sub,
                &format!("{path} {}", sub.get_name()),
                found,
                positionals,
            );
        }
    }
    let mut found = Vec::new();
    let mut positionals = 0;
    walk(
        &gloam::cli::Cli::command(),
        "gloam",
        &mut found,
        &mut positionals,
    );
    assert!(found.is_empty(), "{}", found.join("\n"));
    // The commands taking a level or scene today: the walk saw them all.
    assert!(positionals >= 13, "{positionals} positional arguments");
}

#[test]
fn edit_new_refuses_a_file_that_exists_in_one_line_before_asking_for_a_window() {
    let output = Command::new(env!("CARGO_BIN_EXE_gloam"))
        .args(["edit", "--new", "levels/first-light.ron"])
        .current_dir(common::repo())
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .expect("run gloam");
    let stderr = text(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
    assert!(
        stderr.contains("levels/first-light.ron already exists"),
        "{stderr}"
    );
}
