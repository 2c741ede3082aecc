//! `gloam bench` as a user runs it: the reports it writes hold their schemas, the stages
//! account for the frame, and the same run does the same work every time.

mod common;

use std::path::Path;
use std::process::Command;

use serde_json::Value;

const STAGES: [&str; 9] = [
    "input",
    "gameplay",
    "animation",
    "audio",
    "blas_refit",
    "tlas_build",
    "render",
    "film",
    "present",
];

/// Runs a short bench of first-light (wardens walking, a banner in the wind) into `dir`.
fn bench(dir: &Path, name: &str, extra: &[&str]) -> (Value, String) {
    let path = |ext: &str| dir.join(format!("{name}.{ext}")).display().to_string();
    let (json, csv, trace, chart) = (path("json"), path("csv"), path("trace.json"), path("png"));
    let mut args = vec![
        "bench",
        "levels/first-light.ron",
        "--frames",
        "24",
        "--warmup",
        "4",
        "--width",
        "96",
        "--height",
        "54",
        "--json",
        &json,
        "--csv",
        &csv,
        "--trace",
        &trace,
        "--chart",
        &chart,
    ];
    args.extend_from_slice(extra);
    let output = Command::new(env!("CARGO_BIN_EXE_gloam"))
        .args(&args)
        .current_dir(common::repo())
        .output()
        .expect("run gloam bench");
    let stdout = String::from_utf8_lossy(&output.stdout).into_owned();
    assert!(
        output.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(
        stdout.contains("render") && stdout.contains("p99"),
        "{stdout}"
    );
    let report: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    (report, std::fs::read_to_string(&csv).unwrap())
}

#[test]
fn reports_hold_their_schemas_and_the_stages_add_up() {
    let dir = common::scratch_dir("bench");
    let (report, csv) = bench(&dir, "first", &["--threads", "2"]);

    // The JSON schema `headless::bench`'s docs give for `gloam bench --json`.
    assert_eq!(report["frames"], 24);
    assert_eq!(
        (report["width"].as_u64(), report["height"].as_u64()),
        (Some(96), Some(54))
    );
    let fields = ["mean_ms", "p50_ms", "p95_ms", "p99_ms", "max_ms"];
    for stage in STAGES {
        for field in fields {
            assert!(
                report["stages"][stage][field]
                    .as_f64()
                    .is_some_and(|v| v >= 0.0),
                "stages.{stage}.{field} in {report}"
            );
        }
        let s = &report["stages"][stage];
        assert!(
            s["p50_ms"].as_f64() <= s["p95_ms"].as_f64()
                && s["p95_ms"].as_f64() <= s["max_ms"].as_f64()
        );
    }
    for field in fields {
        assert!(report["frame"][field].as_f64().is_some_and(|v| v > 0.0));
    }
    assert!(report["mrays_per_s"].as_f64().is_some_and(|v| v > 0.0));
    // The accel alone, beside the renderer: three positive rates, their harmonic mean
    // between the slowest and the fastest, and the renderer's share of it.
    let accel = &report["accel_mrays_per_s"];
    let rates: Vec<f64> = ["camera", "shadow", "bounce"]
        .iter()
        .map(|kind| accel[kind].as_f64().unwrap_or(0.0))
        .collect();
    assert!(rates.iter().all(|&rate| rate > 0.0), "{accel}");
    let harmonic = accel["harmonic_mean"].as_f64().unwrap();
    let (slowest, fastest) = (
        rates.iter().copied().fold(f64::INFINITY, f64::min),
        rates.iter().copied().fold(0.0, f64::max),
    );
    assert!(slowest <= harmonic && harmonic <= fastest, "{accel}");
    // Each round of the accel alone is set beside the renderer's rays over the window of
    // frames before it; the ratio reported is the median of the windows' ratios.
    let rounds = report["accel_rounds"].as_array().unwrap();
    assert!(!rounds.is_empty());
    let mut ratios: Vec<f64> = rounds
        .iter()
        .map(|round| {
            round["renderer_mrays_per_s"].as_f64().unwrap()
                / round["harmonic_mean"].as_f64().unwrap()
        })
        .collect();
    ratios.sort_by(f64::total_cmp);
    let median = ratios[ratios.len().div_ceil(2) - 1];
    let ratio = report["renderer_vs_accel"].as_f64().unwrap();
    assert!(
        (ratio - median).abs() <= 1e-9 * median,
        "{ratio} against {median} of {ratios:?}"
    );
    // The render's mix of rays adds up to its rays a frame, and tracing it alone takes
    // part of the render's time.
    let tracing = &report["tracing"];
    let mix: f64 = ["camera_rays", "shadow_rays", "bounce_rays"]
        .iter()
        .map(|kind| tracing[kind].as_f64().unwrap())
        .sum();
    let per_frame = report["rays_per_frame"].as_array().unwrap();
    let mean = per_frame.iter().map(|r| r.as_f64().unwrap()).sum::<f64>() / per_frame.len() as f64;
    assert!(
        (mix - mean).abs() <= 1e-6 * mean,
        "{tracing} against {mean}"
    );
    let share = tracing["share_of_render"].as_f64().unwrap();
    assert!(
        share > 0.0 && tracing["ms"].as_f64().unwrap() > 0.0,
        "{tracing}"
    );
    let last = rounds.last().unwrap()["after_frames"].as_u64();
    assert_eq!(
        last,
        report["frames"].as_u64(),
        "the last window ends the run"
    );
    // The radiance cache ends some of the paths, never more than there are.
    let ended = report["cache_ended_share"].as_f64().unwrap();
    assert!(ended > 0.0 && ended < 1.0, "cache_ended_share {ended}");
    // It learns every frame's samples in the background, and the report times that.
    let learn = &report["cache_learn_ms"];
    assert!(
        learn["p50_ms"].as_f64().unwrap() > 0.0,
        "cache_learn_ms {learn}"
    );
    assert!(learn["p50_ms"].as_f64() <= learn["max_ms"].as_f64());
    // The film's share of the frames' time is its mean over the frame's (both summed over
    // the same frames); rendered at the size shown, none of it is the upscaler's.
    let share = &report["film_share"];
    let mean = |summary: &Value| summary["mean_ms"].as_f64().unwrap();
    let film_over_frame = mean(&report["stages"]["film"]) / mean(&report["frame"]);
    let film = share["film"].as_f64().unwrap();
    assert!(
        (film - film_over_frame).abs() <= 1e-9 && film > 0.0 && film < 1.0,
        "{share} against {film_over_frame}"
    );
    assert_eq!(share["upscale"].as_f64(), Some(0.0), "{share}");
    // Wardens walk in first-light: animation and refits take time every frame.
    assert!(report["stages"]["animation"]["mean_ms"].as_f64().unwrap() > 0.0);
    assert!(report["stages"]["blas_refit"]["mean_ms"].as_f64().unwrap() > 0.0);

    // The stages account for the frame: their means add up to the mean frame within 5%.
    let stage_sum: f64 = report["stages"]
        .as_object()
        .unwrap()
        .values()
        .map(|s| s["mean_ms"].as_f64().unwrap())
        .sum();
    let frame = report["frame"]["mean_ms"].as_f64().unwrap();
    assert!(
        (stage_sum - frame).abs() <= 0.05 * frame,
        "stages sum to {stage_sum:.3} ms, the frame is {frame:.3} ms"
    );

    // The render phases (primary, shade, shadow, bounces) share out the render stage.
    let phases = report["render_phases"].as_object().expect("render_phases");
    assert_eq!(phases.len(), 4);
    let phase_sum: f64 = phases
        .values()
        .map(|p| p["mean_ms"].as_f64().unwrap())
        .sum();
    let render = report["stages"]["render"]["mean_ms"].as_f64().unwrap();
    assert!(
        (phase_sum - render).abs() <= 1e-6 * render.max(1.0),
        "phases sum to {phase_sum} ms, render is {render} ms"
    );
    for phase in ["primary", "shade", "shadow", "bounces"] {
        assert!(
            phases[phase]["mean_ms"].as_f64().unwrap() > 0.0,
            "render.{phase} took no time"
        );
    }

    // The film's steps (temporal, spatial, remodulate, upscale) share out the film stage
    // the same way.
    let steps = report["film_phases"].as_object().expect("film_phases");
    let step_sum: f64 = steps.values().map(|p| p["mean_ms"].as_f64().unwrap()).sum();
    let film = report["stages"]["film"]["mean_ms"].as_f64().unwrap();
    assert!(
        (step_sum - film).abs() <= 1e-6 * film.max(1.0),
        "film steps sum to {step_sum} ms, film is {film} ms"
    );
    for step in ["temporal", "spatial"] {
        assert!(
            steps[step]["mean_ms"].as_f64().unwrap() > 0.0,
            "film.{step} took no time"
        );
    }
    // The full chain remodulates in the last a-trous pass's rows, inside `spatial`.
    assert_eq!(steps["remodulate"]["mean_ms"].as_f64(), Some(0.0));
    // Rendered at the size shown: nothing to upscale.
    assert_eq!(steps["upscale"]["mean_ms"].as_f64(), Some(0.0));
    assert_eq!(report["render_width"], report["width"]);

    // CSV: a header and a row per frame, a column per stage.
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines.len(), 25);
    let header: Vec<&str> = lines[0].split(',').collect();
    for stage in STAGES {
        assert!(
            header.contains(&format!("{stage}_ms").as_str()),
            "{}",
            lines[0]
        );
    }
    assert!(
        lines[1..]
            .iter()
            .all(|l| l.split(',').count() == header.len())
    );

    // Chrome trace: complete events with numeric microsecond times, every stage present,
    // stages inside their frame.
    let trace: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("first.trace.json")).unwrap())
            .unwrap();
    let all_events = trace["traceEvents"].as_array().expect("traceEvents");
    // Metadata events name the tracks: frames, stages, and one per render thread.
    let track_names: Vec<&str> = all_events
        .iter()
        .filter(|e| e["ph"] == "M" && e["name"] == "thread_name")
        .filter_map(|e| e["args"]["name"].as_str())
        .collect();
    assert_eq!(
        track_names,
        ["frames", "stages", "render thread 0", "render thread 1"]
    );
    let events: Vec<&Value> = all_events.iter().filter(|e| e["ph"] != "M").collect();
    assert!(events.iter().all(|e| e["ph"] == "X"
        && e["ts"].as_f64().is_some_and(|t| t >= 0.0)
        && e["dur"].as_f64().is_some_and(|d| d >= 0.0)
        && e["pid"].is_u64()
        && e["tid"].is_u64()
        && e["name"].is_string()));
    assert_eq!(events.iter().filter(|e| e["name"] == "frame").count(), 24);
    for stage in [
        "animation",
        "blas_refit",
        "render",
        "render.primary",
        "render.bounces",
    ] {
        assert!(
            events.iter().any(|e| e["name"] == stage),
            "no {stage} event"
        );
    }
    // Each render thread's track holds its tiles: every tile of every frame (96 x 54 is
    // 6 x 4 tiles of 16), each inside its frame's render stage.
    let renders: Vec<(f64, f64)> = events
        .iter()
        .filter(|e| e["name"] == "render")
        .map(|e| (e["ts"].as_f64().unwrap(), e["dur"].as_f64().unwrap()))
        .collect();
    let tiles: Vec<&&Value> = events.iter().filter(|e| e["cat"] == "tile").collect();
    assert_eq!(tiles.len(), 24 * 24);
    for tile in &tiles {
        let (ts, dur) = (tile["ts"].as_f64().unwrap(), tile["dur"].as_f64().unwrap());
        assert!(
            tile["tid"]
                .as_u64()
                .is_some_and(|tid| tid == 100 || tid == 101),
            "{tile}"
        );
        assert!(
            renders
                .iter()
                .any(|&(start, length)| ts >= start && ts + dur <= start + length + 1.0),
            "tile {tile} lies in no render"
        );
    }
    // The chart is a PNG.
    let chart = image::open(dir.join("first.png")).expect("chart decodes");
    assert_eq!((chart.width(), chart.height()), (1280, 720));
}

#[test]
fn the_same_bench_does_the_same_work_every_run() {
    let dir = common::scratch_dir("bench-repeat");
    // The camera path runs one step a frame; a play-through runs the steps each frame's
    // time owes, which a loaded machine changes.
    let (first, _) = bench(&dir, "one", &["--threads", "1", "--view", "camera"]);
    let (second, _) = bench(&dir, "two", &["--threads", "2", "--view", "camera"]);
    let rays = |report: &Value| report["rays_per_frame"].as_array().unwrap().clone();
    assert_eq!(rays(&first).len(), 24);
    assert!(rays(&first).iter().all(|r| r.as_u64().unwrap() > 0));
    assert_eq!(
        rays(&first),
        rays(&second),
        "same path, same poses, same rays"
    );
    assert_eq!(
        first["cache_ended_share"], second["cache_ended_share"],
        "the radiance cache learns the same on any thread count"
    );
    // The portable kernels give the same bits, so the same paths and the same rays.
    let portable_flags = ["--threads", "2", "--simd", "portable", "--view", "camera"];
    let (portable, _) = bench(&dir, "portable", &portable_flags);
    assert_eq!(
        (&first["simd"], &portable["simd"]),
        (&"native".into(), &"portable".into())
    );
    assert_eq!(rays(&first), rays(&portable), "portable kernels, same rays");
    assert_eq!(first["cache_ended_share"], portable["cache_ended_share"]);
}

#[test]
fn a_lowered_render_is_upscaled_to_the_size_asked_for() {
    let dir = common::scratch_dir("bench-upscaled");
    let (report, _) = bench(&dir, "half", &["--render-scale", "0.5"]);
    assert_eq!(
        (report["width"].as_u64(), report["height"].as_u64()),
        (Some(96), Some(54))
    );
    assert_eq!(
        (
            report["render_width"].as_u64(),
            report["render_height"].as_u64()
        ),
        (Some(48), Some(27))
    );
    let upscale = report["film_phases"]["upscale"]["mean_ms"]
        .as_f64()
        .unwrap();
    assert!(upscale > 0.0, "film.upscale took no time");
}

/// Runs `gloam bench` with `args` from the repository, writing its JSON report; the report.
fn bench_json(dir: &Path, name: &str, args: &[&str]) -> Value {
    let json = dir.join(format!("{name}.json"));
    let output = Command::new(env!("CARGO_BIN_EXE_gloam"))
        .arg("bench")
        .args(args)
        .args(["--json", json.to_str().unwrap()])
        .current_dir(common::repo())
        .output()
        .expect("run gloam bench");
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap()
}

#[test]
fn bench_sees_a_level_through_the_players_eyes_and_plays_it_to_the_end() {
    let dir = common::scratch_dir("bench-view");
    let small = ["--width", "32", "--height", "18", "--warmup", "1"];
    // A level with a player start: its won recording, played from the start, every frame
    // running at least one step.
    let mut args = vec!["levels/first-light.ron", "--frames", "3"];
    args.extend_from_slice(&small);
    let played = bench_json(&dir, "player", &args);
    assert_eq!(played["view"], "player");
    assert_eq!(played["replay"], "tests/recordings/first-light-won.json");
    assert_eq!(played["frames"], 3);
    assert!(played["steps"].as_u64().unwrap() >= 3, "{played}");
    // Present (the film tone mapped into a frame buffer, the HUD laid out) is timed.
    let present = played["stages"]["present"]["p50_ms"].as_f64().unwrap();
    assert!(present > 0.0, "{played}");
    // Asked for, or with no player to see through, the camera path: one step a frame.
    args.extend_from_slice(&["--view", "camera"]);
    let camera = bench_json(&dir, "camera", &args);
    assert_eq!(camera["view"], "camera");
    assert!(camera.get("replay").is_none(), "{camera}");
    assert_eq!(camera["steps"], 3);
    let mut args = vec!["levels/cornell.ron", "--frames", "2"];
    args.extend_from_slice(&small);
    assert_eq!(bench_json(&dir, "cornell", &args)["view"], "camera");
    // A recording with no --frames runs to the end of its inputs, and no further.
    let recording = "tests/recordings/first-light-caught.json";
    let text = std::fs::read_to_string(common::repo().join(recording)).unwrap();
    let steps = serde_json::from_str::<Value>(&text).unwrap()["steps"]
        .as_array()
        .unwrap()
        .len() as u64;
    let args = [
        "--replay", recording, "--width", "8", "--height", "8", "--warmup", "0",
    ];
    let whole = bench_json(&dir, "whole", &args);
    let (frames, ran) = (
        whole["frames"].as_u64().unwrap(),
        whole["steps"].as_u64().unwrap(),
    );
    assert_eq!(whole["replay"], recording);
    assert!((steps..=steps + 1).contains(&ran), "{ran} steps of {steps}");
    assert!(
        frames >= 1 && frames <= steps,
        "{frames} frames for {steps} steps"
    );
    // No player to play as: a one-line error naming the level.
    let output = Command::new(env!("CARGO_BIN_EXE_gloam"))
        .args(["bench", "levels/cornell.ron", "--view", "player"])
        .current_dir(common::repo())
        .output()
        .unwrap();
    assert_eq!(output.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("cornell.ron") && stderr.contains("no player start"),
        "{stderr}"
    );
}

#[test]
fn bad_bench_flags_are_one_line_errors() {
    // A value clap refuses is a usage error (2); a chart the command cannot write, a
    // failure (1).
    for (flag, value, code) in [("--render-scale", "0", 2), ("--chart", "chart.jpg", 1)] {
        let output = Command::new(env!("CARGO_BIN_EXE_gloam"))
            .args(["bench", "levels/first-light.ron", flag, value])
            .current_dir(common::repo())
            .output()
            .unwrap();
        assert_eq!(output.status.code(), Some(code), "{flag} {value}");
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(
            stderr.contains(value) && stderr.lines().count() == 1,
            "{stderr}"
        );
    }
    let output = Command::new(env!("CARGO_BIN_EXE_gloam"))
        .args(["bench", "levels/missing.ron"])
        .current_dir(common::repo())
        .output()
        .unwrap();
    assert_eq!(output.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&output.stderr).contains("missing.ron"));
}
