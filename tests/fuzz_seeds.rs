//! The fuzz targets' bodies (`gloam::fuzz`, one per target in tests/fuzz) over their seed
//! files, on stable: each good seed goes all the way (a frame rendered, a replay reported),
//! so a body that no longer reaches what it fuzzes fails here, and the seeds the fuzzers
//! start from are known good.

mod common;

use std::path::{Path, PathBuf};

use common::{repo, scratch_dir, shared};

fn files_in(dir: &Path, extensions: &[&str]) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap_or_else(|error| panic!("{}: {error}", dir.display()))
        .map(|entry| entry.expect("a readable folder entry").path())
        .filter(|path| {
            path.extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| extensions.contains(&e))
        })
        .collect();
    files.sort();
    files
}

#[test]
fn the_gltf_body_renders_every_kit_asset_and_every_self_contained_sample() {
    let kit = files_in(&repo().join("assets/kit"), &["glb"]);
    assert!(kit.len() >= 20, "{} kit assets", kit.len());
    for file in &kit {
        let bytes = std::fs::read(file).expect("a kit asset");
        if let Err(error) = gloam::fuzz::gltf(&bytes) {
            panic!("{}: {error}", file.display());
        }
    }
    // The Khronos samples: a GLB or an embedded glTF carries everything, so it renders; a
    // glTF whose buffers are beside it is refused (the body reads one file's bytes), and
    // must be refused cleanly.
    let Some(samples) = shared("gltf-samples") else {
        return;
    };
    let mut rendered = 0;
    for model in files_in_tree(&samples) {
        let bytes = std::fs::read(&model).expect("a sample");
        let self_contained = model.extension().is_some_and(|e| e == "glb")
            || model
                .parent()
                .is_some_and(|dir| dir.ends_with("glTF-Embedded"));
        match gloam::fuzz::gltf(&bytes) {
            Ok(()) => rendered += 1,
            Err(error) if self_contained => panic!("{}: {error}", model.display()),
            Err(_) => {}
        }
    }
    assert!(rendered >= 5, "{rendered} samples rendered");
}

fn files_in_tree(dir: &Path) -> Vec<PathBuf> {
    let mut found = Vec::new();
    for entry in std::fs::read_dir(dir).expect("a readable folder").flatten() {
        let path = entry.path();
        if path.is_dir() {
            found.extend(files_in_tree(&path));
        } else if path.extension().is_some_and(|e| e == "glb" || e == "gltf") {
            found.push(path);
        }
    }
    found.sort();
    found
}

#[test]
fn the_level_body_plays_every_shipped_level_and_refuses_a_broken_one() {
    // As the level target reads its inputs: `levels/fuzz.ron`, never written.
    let path = repo().join("levels/fuzz.ron");
    for level in common::shipped_levels() {
        let bytes = std::fs::read(&level).expect("a shipped level");
        if let Err(error) = gloam::fuzz::level(&path, &bytes) {
            panic!("{}: {error}", level.display());
        }
    }
    let error = gloam::fuzz::level(&path, b"(version: 1, entities: [(name: ")
        .expect_err("a level cut short");
    assert!(error.contains("fuzz.ron:1:"), "{error}");
    assert!(!path.exists());
}

#[test]
fn the_replay_body_replays_every_shipped_recording_and_refuses_a_broken_one() {
    // As the replay target reads its inputs: beside the shipped recordings, never written.
    let path = repo().join("tests/recordings/fuzz.json");
    let recordings = files_in(&repo().join("tests/recordings"), &["json"]);
    assert!(recordings.len() >= 6, "{} recordings", recordings.len());
    for recording in &recordings {
        let bytes = std::fs::read(recording).expect("a shipped recording");
        let report = gloam::fuzz::replay(&path, &bytes)
            .unwrap_or_else(|error| panic!("{}: {error}", recording.display()));
        let steps = report["steps"].as_array().map_or(0, Vec::len);
        let recorded = serde_json::from_slice::<serde_json::Value>(&bytes).expect("JSON")["steps"]
            .as_array()
            .map_or(0, Vec::len);
        // Every step the body plays is reported, up to its cap or the end of play.
        assert!(
            steps > 0 && steps <= gloam::fuzz::REPLAY_STEPS.min(recorded),
            "{}: {steps} of {recorded} steps reported",
            recording.display()
        );
        // Cut short, a replay may differ only in how it ends: every state on the way
        // matches the recording's trail.
        let diverged = &report["diverged"];
        assert!(
            diverged.is_null()
                || diverged["part"]
                    .as_str()
                    .is_some_and(|part| part.starts_with("still running")),
            "{}: {diverged}",
            recording.display()
        );
    }
    let error = gloam::fuzz::replay(&path, b"{\"version\": 1").expect_err("a cut recording");
    assert!(error.contains("fuzz.json:1:"), "{error}");
    assert!(!path.exists());
}

#[test]
fn the_settings_body_reads_what_the_game_writes_and_refuses_a_broken_file() {
    use gloam::app::settings::{Best, BestTimes, Settings, save};
    let dir = scratch_dir("fuzz-settings");
    let mut best = BestTimes::default();
    best.offer(
        Path::new("levels/first-light.ron"),
        Best {
            seconds: 69.8,
            shards: 3,
            times_seen: 0,
        },
    );
    save(&dir.join("settings.ron"), &Settings::default()).expect("write settings");
    save(&dir.join("best-times.ron"), &best).expect("write best times");
    for file in ["settings.ron", "best-times.ron"] {
        let bytes = std::fs::read(dir.join(file)).expect("written");
        if let Err(error) = gloam::fuzz::settings(&bytes) {
            panic!("{file}: {error}");
        }
    }
    let error = gloam::fuzz::settings(b"(mouse_sensitivity: ").expect_err("a cut file");
    assert!(error.contains(".ron:1:"), "{error}");
}
