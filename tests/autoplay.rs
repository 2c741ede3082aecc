//! The player bot and the recordings it makes: it wins every shipped level unseen with
//! every shard, and the run it makes is the shipped `<level>-won.json` step for step (a
//! rule change fails here until the recordings are made again, with the one command in
//! `headless::autoplay`'s docs); every shipped recording replays to its pinned state hash
//! on one and two threads, and with the portable kernels a CPU without AVX2 runs; an
//! edited recording is replayed and says at which step and in which part of the state it
//! went another way; a level whose way out cannot be walked to has no route.

mod common;

use gloam::app::menu::find_levels;
use gloam::headless::autoplay::{RunOutcome, autoplay};
use gloam::headless::replay::{divergence, read_recording, replay};
use gloam::scene::Scene;

fn recording(name: &str) -> std::path::PathBuf {
    common::repo().join("tests").join("recordings").join(name)
}

/// The bot on `stem`: won unseen with every shard, and the shipped recording is its run.
fn bot_wins(stem: &str) {
    let level = common::repo().join("levels").join(format!("{stem}.ron"));
    let scene = Scene::load(&level).unwrap();
    let run = autoplay(&scene, 600.0).unwrap();
    assert_eq!(run.outcome, RunOutcome::Won, "{stem}: {}", run.why);
    assert_eq!(run.times_seen, 0, "{stem}: seen");
    assert_eq!(run.shards, run.shards_total, "{stem}");
    assert!(run.shards_total >= 3, "{stem}");
    assert!(run.seconds < 300.0, "{stem}: {} s", run.seconds);
    let report = run.report();
    for key in [
        "level",
        "outcome",
        "seconds",
        "shards",
        "shards_total",
        "times_seen",
        "max_gem",
        "replans",
        "recording",
        "chokepoints",
    ] {
        assert!(report.get(key).is_some(), "{key}");
    }
    let (shipped, _) = read_recording(&recording(&format!("{stem}-won.json"))).unwrap();
    assert!(
        shipped.steps == run.recorded.steps && shipped.trail == run.recorded.trail,
        "{stem}: the bot's run is no longer tests/recordings/{stem}-won.json: make the recordings again (the docs of gloam::headless::autoplay, \"Making the recordings again\") and review what changed"
    );
}

#[test]
fn the_bot_wins_first_light_unseen_and_makes_its_recording_again() {
    bot_wins("first-light");
}

#[test]
fn the_bot_wins_the_gallery_unseen_and_makes_its_recording_again() {
    bot_wins("the-gallery");
}

#[test]
fn the_bot_wins_the_keep_unseen_and_makes_its_recording_again() {
    bot_wins("the-keep");
}

#[test]
fn every_campaign_level_has_a_won_and_a_caught_recording() {
    let (levels, _) = find_levels(&common::repo().join("levels"));
    for level in &levels {
        let stem = level.path.file_stem().unwrap().to_string_lossy();
        for ending in ["won", "caught"] {
            let path = recording(&format!("{stem}-{ending}.json"));
            let (read, _) = read_recording(&path).unwrap();
            assert_eq!(read.version, 2, "{}", path.display());
            assert!(!read.trail.is_empty(), "{}", path.display());
        }
    }
}

/// Every shipped recording and the state hash its replay ends at.
const PINNED: [(&str, &str); 8] = [
    ("first-light-won.json", "5ddff7ccb98b1d06"),
    ("first-light-caught.json", "fb58a06b4eaa922d"),
    ("first-light-glimpsed.json", "09e08d9214ca0a3a"),
    ("the-gallery-won.json", "9011e6ce9cdc1ddd"),
    ("the-gallery-caught.json", "56f78bae2d8dce5c"),
    ("the-gallery-mirror.json", "6a474f736aff7f43"),
    ("the-keep-won.json", "1989861cb5e7eeeb"),
    ("the-keep-caught.json", "3bb06ba89365c936"),
];

#[test]
fn every_shipped_recording_replays_to_its_pinned_hash_on_one_and_two_threads() {
    let shipped = std::fs::read_dir(common::repo().join("tests").join("recordings"))
        .unwrap()
        .count();
    assert_eq!(shipped, PINNED.len(), "pin every recording");
    for (name, hash) in PINNED {
        let one = replay(&recording(name), 1).unwrap();
        let two = replay(&recording(name), 2).unwrap();
        assert_eq!(divergence(&one), None, "{name}");
        assert_eq!(one["state_hash"], two["state_hash"], "{name}");
        assert_eq!(one["state_hash"], hash, "{name}");
    }
}

/// The portable kernels are a process-wide switch, so each portable replay is its own
/// `gloam` process: the other tests in this binary keep the native kernels.
#[test]
fn every_shipped_recording_replays_to_its_pinned_hash_with_the_portable_kernels() {
    for (name, hash) in PINNED {
        for threads in ["1", "2"] {
            let path = recording(name);
            let output = std::process::Command::new(env!("CARGO_BIN_EXE_gloam"))
                .args(["play", "--headless", "--replay"])
                .arg(&path)
                .args(["--threads", threads, "--simd", "portable"])
                .output()
                .unwrap();
            let stdout = String::from_utf8_lossy(&output.stdout);
            assert!(
                output.status.success(),
                "{name}: {}",
                String::from_utf8_lossy(&output.stderr)
            );
            assert!(
                stdout.trim_end().ends_with(&format!("state hash {hash}")),
                "{name} on {threads} threads, portable: {stdout}"
            );
        }
    }
}

#[test]
fn an_edited_recording_is_replayed_and_says_where_it_diverged() {
    let dir = common::scratch_dir("edited-recording");
    let text = std::fs::read_to_string(recording("first-light-won.json")).unwrap();
    let mut json: serde_json::Value = serde_json::from_str(&text).unwrap();
    json["level"] = common::repo()
        .join("levels")
        .join("first-light.ron")
        .display()
        .to_string()
        .into();
    // Turn a little more at step 301 (index 300): the trail's mark after step 360 differs.
    let look = json["steps"][300][2].as_f64().unwrap();
    json["steps"][300][2] = (look + 0.3).into();
    let edited = dir.join("edited.json");
    std::fs::write(&edited, serde_json::to_string(&json).unwrap()).unwrap();
    let report = replay(&edited, 2).unwrap();
    let diverged = divergence(&report).expect("it departs from its trail");
    assert_eq!(diverged.step, 360);
    assert!(diverged.part.starts_with("player"), "{}", diverged.part);
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_gloam"))
        .args(["play", "--headless", "--replay"])
        .arg(&edited)
        .output()
        .unwrap();
    assert_eq!(output.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.contains("edited.json: diverged at step 360 (t = 6.00 s): player"),
        "{stderr}"
    );
}

#[test]
fn a_level_whose_way_out_cannot_be_walked_to_has_no_route() {
    let mut scene = Scene::load(&common::repo().join("levels").join("first-light.ron")).unwrap();
    let exit = scene
        .level
        .entities
        .iter_mut()
        .find(|e| e.exit.is_some())
        .unwrap();
    exit.transform.translation = glam::Vec3::new(100.0, 0.0, 100.0);
    let run = autoplay(&scene, 600.0).unwrap();
    assert_eq!(run.outcome, RunOutcome::NoRoute);
    assert!(
        run.why.contains("the way out cannot be reached on foot"),
        "{}",
        run.why
    );
    assert_eq!(run.report()["outcome"], "no_route");
    assert_eq!(run.recorded.steps.len(), 0);
}
