//! Recordings replay exactly: the shipped play-through of first-light wins again, with the
//! same state hash on 1 and 2 threads; a recording made in code replays to the state the
//! play reached; a recording of another version of its level, or a broken one, is refused
//! in one line naming the file.

mod common;

use gloam::frame::Engine;
use gloam::game::replay::{Ended, Recorder, Recording};
use gloam::game::{Action, Input, Player, Transform, spawn_player};
use gloam::headless::replay::{read_recording, replay, write_recording};
use gloam::render::RenderSettings;
use gloam::scene::Scene;

fn shipped() -> std::path::PathBuf {
    common::repo()
        .join("tests")
        .join("recordings")
        .join("first-light-won.json")
}

#[test]
fn the_shipped_play_through_wins_on_any_thread_count() {
    let one = replay(&shipped(), 1).unwrap();
    let two = replay(&shipped(), 2).unwrap();
    assert_eq!(one["outcome"], "won");
    assert_eq!(one["state_hash"], two["state_hash"]);
    assert_eq!(one["steps"], two["steps"]);
    let steps = one["steps"].as_array().unwrap();
    let last = steps.last().unwrap();
    assert_eq!(last["shards_left"], 0);
    // Every step reports what the JSON promises.
    for step in steps {
        assert!(step["t"].is_f64() && step["exposure"].is_f64());
        assert_eq!(step["player"].as_array().unwrap().len(), 3);
        assert!(step["wardens"].is_array());
    }
    let gem = |step: &serde_json::Value| step["exposure"].as_f64().unwrap();
    assert!(steps.iter().all(|s| (0.0..=1.0).contains(&gem(s))));
}

#[test]
fn a_recording_replays_to_the_state_the_play_reached() {
    let level = common::repo().join("levels").join("first-light.ron");
    let scene = Scene::load(&level).unwrap();
    let mut engine = Engine::new(&scene, RenderSettings::real_time(8, 8));
    let player = spawn_player(&mut engine.world).unwrap();
    engine.recording = Some(Recorder::default());
    let script = [
        (vec![Action::MoveForward], 0.3f32),
        (
            vec![Action::MoveForward, Action::MoveRight, Action::Sprint],
            -0.2,
        ),
        (vec![Action::MoveDown, Action::MoveLeft], 0.1),
    ];
    for (held, turn) in &script {
        for frame in 0..20 {
            let mut input = engine.world.resource_mut::<Input>();
            input.held = held.iter().copied().collect();
            if frame == 0 {
                input.look.x += turn;
                input.pressed.insert(Action::MoveUp);
            }
            // Uneven frames: the recording keeps the steps, whatever the frames were.
            engine.advance(if frame % 3 == 0 {
                1.5 / 60.0
            } else {
                0.75 / 60.0
            });
        }
    }
    let played = *engine.world.get::<Transform>(player).unwrap();
    let yaw = engine.world.get::<Player>(player).unwrap().yaw;
    let recorded = engine.recording.take().unwrap();
    let steps = recorded.steps.clone();
    let dir = common::scratch_dir("record");
    let out = dir.join("recording.json");
    write_recording(&out, &level, recorded, Ended::Quit).unwrap();
    let (read, found) = read_recording(&out).unwrap();
    assert_eq!(read.steps, steps);
    assert_eq!(
        std::fs::canonicalize(found).unwrap(),
        std::fs::canonicalize(&level).unwrap()
    );
    let report = replay(&out, 2).unwrap();
    assert_eq!(
        report["outcome"], "quit",
        "it ended in a quit, still running"
    );
    let last = report["steps"].as_array().unwrap().last().unwrap().clone();
    let feet: Vec<f32> = last["player"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap() as f32)
        .collect();
    assert_eq!(feet, played.translation.to_array().to_vec());
    assert_ne!(yaw, 0.0, "the look was recorded too");
}

#[test]
fn another_version_of_the_level_or_a_broken_file_is_refused_in_one_line() {
    let dir = common::scratch_dir("replay-refused");
    let levels = dir.join("levels");
    std::fs::create_dir_all(&levels).unwrap();
    let level = levels.join("first-light.ron");
    let text = std::fs::read_to_string(common::repo().join("levels").join("first-light.ron"))
        .unwrap()
        .replace(
            "../assets/",
            &format!("{}/", common::repo().join("assets").display()),
        );
    std::fs::write(&level, &text).unwrap();
    let out = dir.join("replay.json");
    write_recording(&out, &level, Recorder::default(), Ended::Inputs).unwrap();
    let report = replay(&out, 1).unwrap();
    assert_eq!(report["outcome"], "running", "no inputs: still running");

    std::fs::write(&level, text.replace("First light", "First light, changed")).unwrap();
    let error = format!("{:#}", replay(&out, 1).unwrap_err());
    assert!(
        error.contains("replay.json") && error.contains("another version") && !error.contains('\n'),
        "{error}"
    );

    let broken = dir.join("broken-replay.json");
    std::fs::write(&broken, "{\"version\": 1, \"level\": 7}").unwrap();
    let error = format!("{:#}", replay(&broken, 1).unwrap_err());
    assert!(
        error.contains("broken-replay.json:1:") && error.contains("not a Gloam recording"),
        "{error}"
    );
    let newer = Recording {
        version: 3,
        ..serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap()
    };
    let future = dir.join("future-replay.json");
    std::fs::write(&future, serde_json::to_string(&newer).unwrap()).unwrap();
    let error = format!("{:#}", replay(&future, 1).unwrap_err());
    assert!(error.contains("recording version 3"), "{error}");
}

/// The sounds a replay's steps made (`SoundEvents`), every one a file of the sound kit.
fn sounds_of(recording: &str) -> Vec<String> {
    let path = common::repo().join("tests/recordings").join(recording);
    let report = replay(&path, 2).unwrap();
    let kit: Vec<String> = gloam::scene::sound_kit::sounds()
        .into_iter()
        .map(|s| s.name)
        .collect();
    let mut heard = Vec::new();
    for step in report["steps"].as_array().unwrap() {
        for sound in step["sounds"].as_array().unwrap() {
            let sound = sound.as_str().unwrap().to_owned();
            assert!(
                kit.contains(&sound),
                "{recording}: {sound} is no file of the kit"
            );
            heard.push(sound);
        }
    }
    heard
}

/// Game events sound: the won play-through walks with quiet steps on the level's surfaces,
/// takes three shards and never hears an alarm; the caught one hears a warden's voice
/// raise the alarm; the gallery's gate runs on its chains; the glimpse is heard turn
/// curious and, after the search, give up.
#[test]
fn the_shipped_play_throughs_make_the_sounds_of_their_events() {
    let won = sounds_of("first-light-won.json");
    let count = |sounds: &[String], name: &str| sounds.iter().filter(|s| *s == name).count();
    let steps: Vec<&String> = won.iter().filter(|s| s.starts_with("step-")).collect();
    // 69.8 s of careful play: a footstep every 0.55-0.8 m.
    assert!(steps.len() > 40, "{} footsteps", steps.len());
    assert!(
        steps.iter().all(|s| !s.contains("-sprint-")),
        "the bot never sprints"
    );
    assert!(steps.iter().any(|s| s.contains("-crouch-")));
    assert_eq!(count(&won, "shard"), 3);
    assert_eq!(count(&won, "warden-alarm"), 0);
    assert!(count(&won, "warden-step-1") + count(&won, "warden-step-2") > 20);
    assert!(count(&won, "warden-armour") > 10);

    let caught = sounds_of("first-light-caught.json");
    assert!(count(&caught, "warden-alarm") >= 1, "{caught:?}");

    // The gallery's gate rises and falls every 11 s on its chains (kit::GATE_CYCLE).
    let gallery = sounds_of("the-gallery-won.json");
    let chains = count(&gallery, "gate-chains");
    assert!(
        (12..=14).contains(&chains),
        "{chains} runs of the chains in 75 s"
    );

    let glimpsed = sounds_of("first-light-glimpsed.json");
    assert!(count(&glimpsed, "warden-curious") >= 1, "{glimpsed:?}");
    assert!(count(&glimpsed, "warden-gives-up") >= 1, "{glimpsed:?}");
}
